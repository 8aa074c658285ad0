//! The host's side of the link: flashing a blob and teaching a demo.

use sim::Trajectory;

use crate::link::{CHUNK_BYTES, Endpoint, Floats, HostMessage, LinkError, SimLink};

/// Sends `blob` to the device's bootloader in chunks; the device commits it only after
/// every chunk arrived and the whole blob verified.
pub fn upload_blob(
    link: &mut SimLink,
    device: &mut dyn Endpoint,
    blob: &[u8],
) -> Result<(), LinkError> {
    let len = u32::try_from(blob.len()).map_err(|_| LinkError::FrameTooLarge)?;
    link.send(
        device,
        &HostMessage::BlobBegin {
            len,
            crc: infer_core::format::crc32(blob),
        },
    )?;
    for (i, chunk) in blob.chunks(CHUNK_BYTES).enumerate() {
        link.send(
            device,
            &HostMessage::BlobChunk {
                offset: (i * CHUNK_BYTES) as u32,
                data: chunk,
            },
        )?;
    }
    link.send(device, &HostMessage::BlobEnd)
}

fn floats(values: &[f32]) -> Result<Floats, LinkError> {
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
    link.send(device, &HostMessage::TeachBegin)?;
    for trajectory in trajectories {
        for t in (0..trajectory.len()).filter_map(|i| trajectory.transition(i, obs_dim, act_dim)) {
            let message = HostMessage::Transition {
                obs: floats(t.obs)?,
                action: floats(t.action)?,
                next_obs: floats(t.next_obs)?,
            };
            link.send(device, &message)?;
        }
        link.send(device, &HostMessage::EndTrajectory)?;
    }
    link.send(device, &HostMessage::TeachEnd)
}
