//! The expert policies a run exports and demos, evaluation and Meta-DAgger load: a SAC actor on
//! the oracle observation, or a scripted controller (point-goal's PD, ant-linclass's classifier
//! over an ant-goal actor), each one `policy.safetensors` file.

use std::path::Path;

use candle_core::Tensor;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sim::{Family, Physics, PointGoalPdExpert};

use crate::error::{Error, Result};
use crate::io::checkpoint;
use crate::io::checkpoint::POLICY_FILE;
use crate::model::TanhGaussianPolicy;

pub(super) fn write_policy(
    dir: &Path,
    file: &str,
    tensors: &[(String, Tensor)],
    meta: &serde_json::Value,
) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(Error::io(dir))?;
    // One atomic file write: nothing half-written, no temporary folder left on failure.
    checkpoint::save_file(&dir.join(file), tensors, meta).map(|_| ())
}

/// Write a scripted point-goal PD expert descriptor to `dir/policy.safetensors`.
pub fn export_scripted_pd(dir: &Path) -> Result<()> {
    let pd = PointGoalPdExpert::default();
    let meta = serde_json::json!({
        "kind": "expert-policy", "expert": "scripted-pd", "env": Family::POINT_GOAL.name(),
        "kp": pd.kp, "kd": pd.kd,
    });
    write_policy(dir, POLICY_FILE, &[], &meta)
}

/// Write the scripted ant-linclass expert to `dir/policy.safetensors`: the ant-goal SAC
/// expert at `goal_expert` (a run directory or policy file, copied in) walking to the target
/// that [`sim::ant_linclass::scripted_target`] picks with the true hyperplane, as the paper
/// drove two of its Ant-goal experts, aimed `aim_scale` times as far as the target
/// ([`sim::ant_linclass::AIM_SCALE`] by default; stored in the file).
pub fn export_scripted_linclass(goal_expert: &Path, aim_scale: f32, dir: &Path) -> Result<()> {
    if !(aim_scale.is_finite() && aim_scale > 0.0) {
        return Err(Error::Usage(format!(
            "the aim scale must be a finite number > 0, not {aim_scale}"
        )));
    }
    let file = if goal_expert.is_dir() {
        goal_expert.join(POLICY_FILE)
    } else {
        goal_expert.to_path_buf()
    };
    let ck = checkpoint::load(&file)?;
    let is_goal_sac = ck.meta.get("expert").and_then(|k| k.as_str()) == Some("sac-oracle")
        && ck.meta.get("env").and_then(|k| k.as_str()) == Some(Family::ANT_GOAL.name());
    if ck.meta.get("kind").and_then(|k| k.as_str()) != Some("expert-policy") || !is_goal_sac {
        return Err(Error::Checkpoint {
            path: file,
            reason: "the scripted ant-linclass expert drives an ant-goal SAC expert (an \
                     ant-goal expert run); this file is not one"
                .into(),
        });
    }
    // Loads as the actor it will be (input and output widths checked) before anything is written.
    let goal = Family::ANT_GOAL;
    let bad = |r: &str| Error::Checkpoint {
        path: file.clone(),
        reason: r.to_string(),
    };
    load_actor(&ck, goal.oracle_obs_dim(), goal.act_dim(), &bad)?;
    let widths: Vec<usize> = ck.meta_field("widths")?;
    let bounds: (f32, f32) = ck.meta_field("log_std_bounds")?;
    let tensors = (0..2 * (widths.len() - 1))
        .map(|i| Ok((format!("actor.{i}"), ck.get(&format!("actor.{i}"))?)))
        .collect::<Result<Vec<_>>>()?;
    let meta = serde_json::json!({
        "kind": "expert-policy", "expert": "scripted-linclass",
        "env": Family::ANT_LINCLASS.name(), "widths": widths, "log_std_bounds": bounds,
        "physics": policy_physics(&ck, &file)?.name(),
        "goal_expert": file.display().to_string(), "aim_scale": aim_scale,
    });
    write_policy(dir, POLICY_FILE, &tensors, &meta)
}

/// The SAC actor stored as `actor.{i}` in a policy file, whose input width must be `input`.
fn load_actor(
    ck: &checkpoint::Loaded,
    input: usize,
    act_dim: usize,
    bad: &dyn Fn(&str) -> Error,
) -> Result<TanhGaussianPolicy> {
    let widths: Vec<usize> = ck.meta_field("widths")?;
    let bounds: (f32, f32) = ck.meta_field("log_std_bounds")?;
    if widths.len() < 2 || widths[0] != input {
        return Err(bad("policy input width does not match the family"));
    }
    let hidden = &widths[1..widths.len() - 1];
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let policy = TanhGaussianPolicy::new(widths[0], act_dim, hidden, bounds, &mut rng)?;
    let n = policy.net().vars().len();
    let ts = (0..n)
        .map(|i| ck.get(&format!("actor.{i}")))
        .collect::<Result<Vec<_>>>()?;
    policy.net().load_from(&ts)?;
    Ok(policy)
}

/// An expert that acts on oracle observations.
#[derive(Debug, Clone)]
pub enum Expert {
    /// A SAC policy trained on the oracle observation; acts with `tanh(mu)`.
    Sac {
        /// The family it was trained for.
        family: Family,
        /// The plant it was trained on.
        physics: Physics,
        /// The policy.
        policy: TanhGaussianPolicy,
    },
    /// The scripted point-goal PD controller from `sim`.
    ScriptedPd(PointGoalPdExpert),
    /// ant-linclass: classifies with the true hyperplane and drives an ant-goal SAC expert
    /// (`policy`, on the ant's observation + the chosen target) to the chosen target.
    ScriptedLinClass {
        /// The ant-goal expert's actor.
        policy: TanhGaussianPolicy,
        /// The plant the ant-goal expert was trained on.
        physics: Physics,
        /// How far beyond the target it aims the ant-goal expert (the file's `aim_scale`;
        /// [`sim::ant_linclass::AIM_SCALE`] for files from before it was stored).
        aim_scale: f32,
    },
}

/// The plant a policy file's expert was trained on: its `physics` entry; for files written
/// before the MuJoCo backend, the `physics` of the run's `config.toml` beside it (a run
/// directory or an `assets/experts/` folder), else Rapier.
fn policy_physics(ck: &checkpoint::Loaded, file: &Path) -> Result<Physics> {
    let bad = |reason: String| Error::Checkpoint {
        path: file.to_path_buf(),
        reason,
    };
    if let Some(name) = ck.meta.get("physics").and_then(|p| p.as_str()) {
        return name.parse().map_err(|e: sim::SimError| bad(e.to_string()));
    }
    let config = file.with_file_name("config.toml");
    let Ok(text) = std::fs::read_to_string(&config) else {
        return Ok(Physics::Rapier);
    };
    let table: toml::Table = text
        .parse()
        .map_err(|e| bad(format!("{}: {e}", config.display())))?;
    Physics::from_name_or_default(table.get("physics").and_then(|p| p.as_str()))
        .map_err(|e| bad(format!("{}: {e}", config.display())))
}

impl Expert {
    /// Load an expert from a run directory or a `policy.safetensors` file.
    pub fn load(path: &Path) -> Result<Self> {
        let file = if path.is_dir() {
            path.join(POLICY_FILE)
        } else {
            path.to_path_buf()
        };
        if path.is_dir() && !file.exists() && path.join(checkpoint::CHECKPOINT_FILE).exists() {
            return Err(Error::input(
                crate::error::Input::Resume,
                format!(
                    "{} holds an unfinished expert run (a checkpoint, no {POLICY_FILE} yet); \
                     resume its training to finish it",
                    path.display()
                ),
            ));
        }
        let ck = checkpoint::load(&file)?;
        let bad = |r: &str| Error::Checkpoint {
            path: file.clone(),
            reason: r.to_string(),
        };
        if ck.meta.get("kind").and_then(|k| k.as_str()) != Some("expert-policy") {
            return Err(bad("not an expert policy file"));
        }
        let family: Family = ck.meta_field("env")?;
        match ck.meta_field::<String>("expert")?.as_str() {
            "scripted-pd" => Ok(Expert::ScriptedPd(PointGoalPdExpert {
                kp: ck.meta_field("kp")?,
                kd: ck.meta_field("kd")?,
            })),
            "sac-oracle" => {
                let policy = load_actor(&ck, family.oracle_obs_dim(), family.act_dim(), &bad)?;
                let physics = policy_physics(&ck, &file)?;
                Ok(Expert::Sac {
                    family,
                    physics,
                    policy,
                })
            }
            "scripted-linclass" if family == Family::ANT_LINCLASS => {
                let goal = Family::ANT_GOAL;
                let policy = load_actor(&ck, goal.oracle_obs_dim(), goal.act_dim(), &bad)?;
                let physics = policy_physics(&ck, &file)?;
                let aim_scale = match ck.meta.get("aim_scale") {
                    None => sim::ant_linclass::AIM_SCALE,
                    Some(_) => ck.meta_field("aim_scale")?,
                };
                Ok(Expert::ScriptedLinClass {
                    policy,
                    physics,
                    aim_scale,
                })
            }
            other => Err(bad(&format!("unknown expert kind {other:?}"))),
        }
    }

    /// Short name stored in datasets (`sac-oracle`, `scripted-pd`).
    pub fn name(&self) -> &'static str {
        match self {
            Expert::Sac { .. } => "sac-oracle",
            Expert::ScriptedPd(_) => "scripted-pd",
            Expert::ScriptedLinClass { .. } => "scripted-linclass",
        }
    }

    /// The family this expert acts in.
    pub fn family(&self) -> Family {
        match self {
            Expert::Sac { family, .. } => *family,
            Expert::ScriptedPd(_) => Family::POINT_GOAL,
            Expert::ScriptedLinClass { .. } => Family::ANT_LINCLASS,
        }
    }

    /// The plant this expert acts on.
    pub fn physics(&self) -> Physics {
        match self {
            Expert::Sac { physics, .. } | Expert::ScriptedLinClass { physics, .. } => *physics,
            Expert::ScriptedPd(_) => Physics::Rapier,
        }
    }

    /// Deterministic action for an oracle observation.
    pub fn act(&self, oracle_obs: &[f32], action: &mut [f32]) -> Result<()> {
        match self {
            Expert::Sac { policy, .. } => {
                let mut rng = ChaCha8Rng::seed_from_u64(0); // unused: deterministic action
                action.copy_from_slice(&policy.act(oracle_obs, true, &mut rng)?);
                Ok(())
            }
            Expert::ScriptedPd(pd) => Ok(pd.act(oracle_obs, action)?),
            Expert::ScriptedLinClass {
                policy, aim_scale, ..
            } => {
                let mut goal_input = [0.0f32; sim::ant::OBS_DIM + 2];
                sim::ant_linclass::goal_expert_input(oracle_obs, *aim_scale, &mut goal_input)?;
                let mut rng = ChaCha8Rng::seed_from_u64(0); // unused: deterministic action
                action.copy_from_slice(&policy.act(&goal_input, true, &mut rng)?);
                Ok(())
            }
        }
    }
}
