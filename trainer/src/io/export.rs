//! Export of a trained [`MetaPolicy`](crate::model::MetaPolicy) to an infer-core blob (its verification, which
//! evaluates the blob, is `eval::blob`; both under `trainer::export`).
//!
//! The blob is written only through `infer_core::write_blob` (the one definition of the
//! format), from [`MetaPolicy::to_float_model`](crate::model::MetaPolicy::to_float_model): observation normalisation and action scaling
//! are baked in. `w8a8` activation scales are calibrated on the meta-train demos (contexts =
//! every training task's demos, observations = their states).

use sim::{DemoDataset, Trajectory};

use crate::error::{Error, Result};
use crate::model::MetaPolicy;

/// Widest layer the blob runners here accept.
pub const BLOB_CAPACITY: usize = 512;

/// Parses `f32`, `w8a32` or `w8a8`.
pub fn parse_quant(s: &str) -> Result<infer_core::Quant> {
    match s {
        "f32" => Ok(infer_core::Quant::F32),
        "w8a32" => Ok(infer_core::Quant::W8A32),
        "w8a8" => Ok(infer_core::Quant::W8A8),
        other => Err(Error::Usage(format!(
            "unknown quantization {other:?}; expected f32, w8a32 or w8a8"
        ))),
    }
}

/// The name of `quant` on the command line and in reports: `f32`, `w8a32` or `w8a8`.
pub fn quant_name(quant: infer_core::Quant) -> String {
    match quant {
        infer_core::Quant::F32 => "f32",
        infer_core::Quant::W8A32 => "w8a32",
        infer_core::Quant::W8A8 => "w8a8",
    }
    .into()
}

/// Raw transitions of a trajectory in the blob's context layout: `[s, a, s']` or `[s, s']`.
pub fn raw_transitions(
    t: &Trajectory,
    obs_dim: usize,
    act_dim: usize,
    state_only: bool,
) -> Vec<Vec<f32>> {
    (0..t.len())
        .map(|i| {
            let mut v = t.obs[i * obs_dim..(i + 1) * obs_dim].to_vec();
            if !state_only {
                v.extend_from_slice(&t.actions[i * act_dim..(i + 1) * act_dim]);
            }
            v.extend_from_slice(&t.next_obs[i * obs_dim..(i + 1) * obs_dim]);
            v
        })
        .collect()
}

/// Calibration inputs from demos: one context per task (all its trajectories) and every
/// demo state as an observation.
pub fn calibration(mp: &MetaPolicy, demos: &DemoDataset) -> infer_core::Calibration {
    let od = demos.obs_dim;
    let observations = demos
        .tasks
        .iter()
        .flat_map(|td| &td.trajectories)
        .flat_map(|t| t.obs.chunks_exact(od).map(<[f32]>::to_vec))
        .collect();
    infer_core::Calibration {
        contexts: calibration_contexts(mp, demos),
        observations,
    }
}

/// One calibration context per task of `demos`: all its trajectories, in the blob's layout.
fn calibration_contexts(mp: &MetaPolicy, demos: &DemoDataset) -> Vec<Vec<Vec<Vec<f32>>>> {
    let (od, ad) = (demos.obs_dim, demos.act_dim);
    let so = mp.encoder.config().state_only;
    demos
        .tasks
        .iter()
        .map(|td| {
            td.trajectories
                .iter()
                .map(|t| raw_transitions(t, od, ad, so))
                .collect()
        })
        .collect()
}

/// Calibration inputs from demos and from the float policy's own closed loop (issue 59): for
/// each task of `demos`, `episodes` episodes acted by `mp` deterministically, conditioned on
/// all of the task's demos, on `env`'s plant; every state it visits joins the demos' states.
/// A policy leaves the demos' state distribution (its errors compound), and an activation
/// range calibrated on the demos alone clips what it then meets. Each state is paired with its
/// own task's latent (infer-core pairs observation `i` with context `i % n`: the states are
/// interleaved task by task, each task contributing as many as the one with fewest).
pub fn closed_loop_calibration(
    mp: &MetaPolicy,
    demos: &DemoDataset,
    env: sim::EnvConfig,
    episodes: usize,
) -> Result<infer_core::Calibration> {
    let od = demos.obs_dim;
    let mut plant = sim::make_env(mp.family, env)?;
    let mut per_task: Vec<Vec<Vec<f32>>> = Vec::with_capacity(demos.tasks.len());
    for (t, td) in demos.tasks.iter().enumerate() {
        let mut states: Vec<Vec<f32>> = td
            .trajectories
            .iter()
            .flat_map(|tr| tr.obs.chunks_exact(od).map(<[f32]>::to_vec))
            .collect();
        let context: Vec<&Trajectory> = td.trajectories.iter().collect();
        let z = mp.latent(&context)?;
        states.extend(closed_loop_states(
            mp,
            plant.as_mut(),
            t,
            &td.task,
            &z,
            episodes,
        )?);
        per_task.push(states);
    }
    let fewest = per_task.iter().map(Vec::len).min().unwrap_or(0);
    let observations = (0..fewest)
        .flat_map(|i| per_task.iter().map(move |states| states[i].clone()))
        .collect();
    Ok(infer_core::Calibration {
        contexts: calibration_contexts(mp, demos),
        observations,
    })
}

/// The raw observations `mp` visits in `episodes` deterministic episodes on `task` (the `t`-th
/// of its dataset, which picks the reset seeds), conditioned on `z`: the states a policy meets
/// off its demos, for calibration and the quantization-aware fine-tune alike.
pub(crate) fn closed_loop_states(
    mp: &MetaPolicy,
    plant: &mut dyn sim::Environment,
    t: usize,
    task: &sim::Task,
    z: &[f32],
    episodes: usize,
) -> Result<Vec<Vec<f32>>> {
    let mut states = Vec::new();
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(0);
    for e in 0..episodes {
        let seed = sim::seeds::EVALUATION_SEED + (t * episodes + e) as u64;
        let mut obs = plant.reset(task, seed)?.to_vec();
        loop {
            let action = mp.act(&obs, z, true, &mut rng)?;
            states.push(obs);
            let done = plant.step(&action)?.done;
            obs = plant.observation().to_vec();
            if done {
                break;
            }
        }
    }
    Ok(states)
}

/// Refuses demos (calibration or contexts) that are not of `mp`'s family and dimensions, with
/// one line naming what differs.
pub fn check_demos_fit(mp: &MetaPolicy, demos: &DemoDataset, what: &str) -> Result<()> {
    if demos.family != mp.family {
        return Err(Error::WrongFamily {
            what: format!("{what}, for this policy"),
            found: demos.family,
            expected: mp.family,
        });
    }
    let whose = || format!("{what}, for this policy");
    Error::same_plant(whose, demos.physics, mp.physics)?;
    let (od, ad) = (mp.family.obs_dim(), mp.family.act_dim());
    if (demos.obs_dim, demos.act_dim) != (od, ad) {
        return Err(Error::Data(format!(
            "{what} have obs/act dimensions {}/{}, the policy {od}/{ad}",
            demos.obs_dim, demos.act_dim
        )));
    }
    Ok(())
}

/// The precision of the first and last layer of each MLP that a `quant` blob is deployed
/// with: a `w8a8` blob keeps them in `w8a32` (int8 weights, so the same flash; float
/// activations where the raw observations, actions and latents come in and the action mean
/// goes out). Measured on the shipped policies (docs/DEVICE.md): the cheetah's SMILe + BC
/// from +4.8% to -1.2% against float, point-goal's SMILe from +4.6% to -0.1%.
pub fn default_edges(quant: infer_core::Quant) -> Option<infer_core::Quant> {
    (quant == infer_core::Quant::W8A8).then_some(infer_core::Quant::W8A32)
}

/// The precision of the context encoder and z head that a `quant` blob is deployed with: a
/// `w8a8` blob keeps them in `w8a32` throughout (int8 weights, the same flash). They run once
/// per teaching, not per control tick, so float activations there cost nothing at run time;
/// measured on the shipped walker-dyn SMILe + BC (docs/DEVICE.md): its latent's error 0.43
/// -> 0.06, its return -13.7% -> -1.6% against float.
pub fn default_context(quant: infer_core::Quant) -> Option<infer_core::Quant> {
    (quant == infer_core::Quant::W8A8).then_some(infer_core::Quant::W8A32)
}

/// The blob bytes of `mp` with `quant`, its [`default_edges`] and [`default_context`]. `calib_demos` (meta-train
/// demos) calibrate the activation scales of `w8a8` and are required for it; the other
/// formats ignore them.
pub fn export_blob(
    mp: &MetaPolicy,
    quant: infer_core::Quant,
    calib_demos: Option<&DemoDataset>,
) -> Result<Vec<u8>> {
    let options = infer_core::WriteOptions {
        edges: default_edges(quant),
        context: default_context(quant),
        ..Default::default()
    };
    export_blob_with(mp, quant, calib_demos, None, &options)
}

/// [`export_blob`], calibrating w8a8 on the policy's closed loop too when `closed_loop` gives
/// the episodes' plant and count ([`closed_loop_calibration`]).
pub fn export_blob_with(
    mp: &MetaPolicy,
    quant: infer_core::Quant,
    calib_demos: Option<&DemoDataset>,
    closed_loop: Option<(sim::EnvConfig, usize)>,
    options: &infer_core::WriteOptions,
) -> Result<Vec<u8>> {
    let calib = match (quant, calib_demos) {
        (_, Some(demos)) => {
            check_demos_fit(mp, demos, "the calibration demos")?;
            match closed_loop {
                Some((env, episodes)) if quant == infer_core::Quant::W8A8 => {
                    closed_loop_calibration(mp, demos, env, episodes)?
                }
                _ => calibration(mp, demos),
            }
        }
        (infer_core::Quant::W8A8, None) => {
            return Err(Error::Usage(
                "w8a8 needs calibration demos (meta-train demos of the policy's family)".into(),
            ));
        }
        (_, None) => infer_core::Calibration {
            contexts: Vec::new(),
            observations: Vec::new(),
        },
    };
    let fm = mp.to_float_model()?;
    Ok(infer_core::write_blob_with(&fm, quant, &calib, options)?)
}

/// Loads (and fully validates) `blob` with infer-core, refusing layers wider than the
/// runners' capacity [`BLOB_CAPACITY`].
pub fn load_blob(blob: &[u8]) -> Result<infer_core::Model<'_>> {
    let model = infer_core::Model::from_bytes(blob)?;
    if model.max_width() > BLOB_CAPACITY {
        return Err(Error::Shape(format!(
            "blob layer width {} exceeds {BLOB_CAPACITY}",
            model.max_width()
        )));
    }
    Ok(model)
}
