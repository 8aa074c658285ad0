//! The host's side of the link: flashing a blob and teaching a demo, over any link that
//! carries one message and waits for its acknowledgement (the in-process [`SimLink`], or a
//! serial port: [`crate::serial::SerialLink`]).

use sim::Trajectory;

use crate::link::{CHUNK_BYTES, Endpoint, Floats, HostMessage, LinkError, SimLink};

/// Sends one message and waits until the device acknowledged it.
pub type Send<'s> = dyn FnMut(&HostMessage<'_>) -> Result<(), LinkError> + 's;

/// Sends `blob` to the device's bootloader in chunks; the device commits it only after
/// every chunk arrived and the whole blob verified.
pub fn upload_blob(
    link: &mut SimLink,
    device: &mut dyn Endpoint,
    blob: &[u8],
) -> Result<(), LinkError> {
    upload_with(&mut |m| link.send(device, m), blob)
}

/// [`upload_blob`] over any link.
pub fn upload_with(send: &mut Send<'_>, blob: &[u8]) -> Result<(), LinkError> {
    let len = u32::try_from(blob.len()).map_err(|_| LinkError::FrameTooLarge)?;
    send(&HostMessage::BlobBegin {
        len,
        crc: infer_core::crc32(blob),
    })?;
    for (i, chunk) in blob.chunks(CHUNK_BYTES).enumerate() {
        send(&HostMessage::BlobChunk {
            offset: (i * CHUNK_BYTES) as u32,
            data: chunk,
        })?;
    }
    send(&HostMessage::BlobEnd)
}

/// A vector of floats as one message carries it.
pub(crate) fn floats(values: &[f32]) -> Result<Floats, LinkError> {
    Floats::from_slice(values).map_err(|_| LinkError::FrameTooLarge)
}

/// Streams demo trajectories to the device, one transition per message; the device folds
/// each into its encoder as it arrives and fixes z at the end.
pub fn teach(
    link: &mut SimLink,
    device: &mut dyn Endpoint,
    trajectories: &[&Trajectory],
    obs_dim: usize,
    act_dim: usize,
) -> Result<(), LinkError> {
    teach_with(
        &mut |m| link.send(device, m),
        trajectories,
        obs_dim,
        act_dim,
    )
}

/// [`teach`] over any link.
pub fn teach_with(
    send: &mut Send<'_>,
    trajectories: &[&Trajectory],
    obs_dim: usize,
    act_dim: usize,
) -> Result<(), LinkError> {
    send(&HostMessage::TeachBegin)?;
    for trajectory in trajectories {
        for t in (0..trajectory.len()).filter_map(|i| trajectory.transition(i, obs_dim, act_dim)) {
            let message = HostMessage::Transition {
                obs: floats(t.obs)?,
                action: floats(t.action)?,
                next_obs: floats(t.next_obs)?,
            };
            send(&message)?;
        }
        send(&HostMessage::EndTrajectory)?;
    }
    send(&HostMessage::TeachEnd)
}
