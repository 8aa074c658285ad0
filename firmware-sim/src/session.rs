//! One device session end to end: flash a blob, teach a context, run the loop. What the CLI's
//! `run` and `compare` are built from.

use sim::{EnvConfig, Task, Trajectory, make_env};

use crate::control::{LoopConfig, RunReport};
use crate::device::{Controller, DeviceConfig, DeviceError};
use crate::host;
use crate::link::{LinkConfig, LinkError, Refusal, SimLink};

/// Why a session failed.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// Flashing or teaching over the link failed.
    #[error("link: {0}")]
    Link(#[from] LinkError),
    /// The device refused the blob or cannot run.
    #[error(transparent)]
    Device(#[from] DeviceError),
    /// The control loop failed.
    #[error(transparent)]
    Loop(#[from] crate::control::LoopError),
    /// The plant could not be built.
    #[error("plant: {0}")]
    Plant(#[from] sim::SimError),
    /// The blob's dimensions are not the plant's.
    #[error("{}", dims_message(*blob_obs, *blob_act, *plant_obs, *plant_act))]
    Dims {
        /// Blob observation dimension.
        blob_obs: usize,
        /// Blob action dimension.
        blob_act: usize,
        /// Plant observation dimension.
        plant_obs: usize,
        /// Plant action dimension.
        plant_act: usize,
    },
}

/// Everything one session needs besides the blob, task and context.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SessionConfig {
    /// Memory budgets.
    pub device: DeviceConfig,
    /// Link faults.
    pub link: LinkConfig,
    /// Loop effects.
    pub control: LoopConfig,
    /// Plant options (episode length).
    pub plant: EnvConfig,
}

/// A finished session.
#[derive(Debug, Clone)]
pub struct Session {
    /// The control loop's report.
    pub report: RunReport,
    /// The latent the device fixed from the context.
    pub z: Vec<f32>,
    /// Link counters (flash + teach).
    pub link: crate::link::LinkStats,
}

/// Flashes `blob`, teaches `context` and runs `task` once.
pub fn run_session(
    blob: &[u8],
    task: &Task,
    context: &[&Trajectory],
    config: &SessionConfig,
) -> Result<Session, SessionError> {
    let family = task.family();
    let mut device = crate::device::erased(config.device);
    let mut link = SimLink::new(config.link);
    let uploaded = host::upload_blob(&mut link, &mut device, blob);
    if let Err(LinkError::Refused {
        reason: Refusal::DoesNotFit,
        ..
    }) = uploaded
    {
        // The device only says "does not fit"; the same check on the host names the reason.
        let model = infer_core::Model::from_bytes(blob).map_err(DeviceError::from)?;
        crate::device::check_fits(&model, config.device)?;
    }
    uploaded?;
    let model = infer_core::Model::from_bytes(device.blob()?).map_err(DeviceError::from)?;
    let h = *model.header();
    let (obs, act) = (h.obs_dim as usize, h.act_dim as usize);
    if obs != family.obs_dim() || act != family.act_dim() {
        return Err(SessionError::Dims {
            blob_obs: obs,
            blob_act: act,
            plant_obs: family.obs_dim(),
            plant_act: family.act_dim(),
        });
    }
    let mut controller = Controller::new(&model, config.device)?;
    host::teach(&mut link, &mut controller, context, obs, act)?;
    let z = controller.z().map(<[f32]>::to_vec).unwrap_or_default();
    let mut plant = make_env(family, config.plant)?;
    let report = crate::control::run(&mut controller, plant.as_mut(), task, &config.control)?;
    Ok(Session {
        report,
        z,
        link: link.stats,
    })
}

/// The dimension mismatch in words, naming the families the blob fits (`--env` to pass).
fn dims_message(blob_obs: usize, blob_act: usize, plant_obs: usize, plant_act: usize) -> String {
    let fits: Vec<&str> = sim::Family::BUILTIN
        .iter()
        .filter(|f| f.obs_dim() == blob_obs && f.act_dim() == blob_act)
        .map(|f| f.name())
        .collect();
    let hint = match fits.as_slice() {
        [] => "no task family has those dimensions".to_string(),
        names => format!(
            "it is a policy of another family: pass --env {}",
            names.join(" or --env ")
        ),
    };
    format!(
        "the blob is for obs {blob_obs} / act {blob_act} but the plant has obs {plant_obs} / act \
         {plant_act}; {hint}"
    )
}
