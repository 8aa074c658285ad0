//! The reference policies of walker-dyn's normalised metric (reference §5, Table 2 left):
//! the *base*, a policy trained on the unmodified dynamics (`smile expert --env walker-dyn
//! --nominal`), and the *expert* of each test task (per-task experts picked as `smile demos
//! --expert` picks them, or one general expert). Both are rolled out deterministically on every
//! task with the methods' episode seeds ([`eval::episode_seed`]) and horizon, so R_base,
//! R_expert and R_pi come from the same initial states; [`eval::normalised_score`] then scores
//! each method.
//!
//! The base sees the *nominal* task parameter (all zeros) in its oracle observation, not the
//! test task's: it was trained on that parameter only, so it stands for "a policy that knows
//! nothing of the dynamics change", which is what the metric normalises against. Feeding it the
//! test factors would instead measure how it reacts to inputs it never saw. The expert sees its
//! task's own parameter, as in training and in the demos.

use std::path::Path;

use sim::{Environment, Family, Split, Task};

use crate::algo::expert::{Expert, ExpertSet, trained_task_value};
use crate::data::run_episode;
use crate::error::{Error, Result};
use crate::eval::{self, Protocol, ReferenceReturns};

/// The base policy and the experts of the normalised metric, checked against the family.
#[derive(Debug, Clone)]
pub struct References {
    family: Family,
    nominal: Task,
    base: Expert,
    base_name: String,
    experts: ExpertSet,
    expert_name: String,
}

impl References {
    /// Loads the base (a run directory or policy file of `smile expert --nominal`) and the
    /// experts (as `smile demos --expert`). Errors: a family without the metric (only
    /// walker-dyn has it), a policy of another family or with the wrong observation width, a
    /// base not trained on the unmodified dynamics.
    pub fn load(family: Family, base: &Path, experts: &[impl AsRef<Path>]) -> Result<Self> {
        let Some(nominal) = family.nominal_task() else {
            return Err(Error::input(
                crate::error::Input::Base,
                format!(
                    "the normalised metric (a base and experts) is defined for walker-dyn only, \
                     not {family}"
                ),
            ));
        };
        let wrong_family = |path: &Path, found: Family| Error::WrongFamily {
            what: format!("the policy {}", path.display()),
            found,
            expected: family,
        };
        let base_expert = Expert::load(base)?;
        if base_expert.family() != family {
            return Err(wrong_family(base, base_expert.family()));
        }
        match trained_task_value(base)? {
            Some(v) if nominal.is_named_by(v) => {}
            trained => {
                let on = trained.map_or("all meta-train tasks".into(), |v| format!("task {v}"));
                return Err(Error::input(
                    crate::error::Input::Base,
                    format!(
                        "the base {} was trained on {on}, not the unmodified dynamics; train a \
                         {family} expert on the nominal task",
                        base.display()
                    ),
                ));
            }
        }
        let set = ExpertSet::load(experts)?;
        if set.family() != family {
            let first = experts.first().map_or(Path::new(""), |p| p.as_ref());
            return Err(wrong_family(first, set.family()));
        }
        let expert_name = match experts {
            [one] => eval::display_name(&set.name(), one.as_ref()),
            many => format!("{} ({} runs)", set.name(), many.len()),
        };
        Ok(Self {
            family,
            nominal,
            base_name: eval::display_name(base_expert.name(), base),
            base: base_expert,
            experts: set,
            expert_name,
        })
    }

    /// R_base and R_expert on every task of `split`: the mean return over the protocol's
    /// draws x rollouts episode seeds (context sizes reuse the same seeds and these policies
    /// take no context). Fails before any rollout if a task has no expert.
    pub fn returns(
        &self,
        split: Split,
        protocol: &Protocol,
        on_task: &mut dyn FnMut(usize, usize),
    ) -> Result<ReferenceReturns> {
        let tasks = self.family.tasks(split);
        let experts = tasks
            .iter()
            .map(|t| self.experts.for_task(t))
            .collect::<Result<Vec<_>>>()?;
        let env_cfg = protocol.env_config();
        let mut env = sim::make_env(self.family, env_cfg)?;
        let nominal = self.nominal.parameter();
        let (mut base_returns, mut expert_returns) = (Vec::new(), Vec::new());
        let (mut base_steps, mut expert_steps) = (Vec::new(), Vec::new());
        for (i, (task, expert)) in tasks.iter().zip(experts).enumerate() {
            let mean = |env: &mut dyn Environment, policy: &Expert, parameter: &[f32]| {
                mean_return(env, policy, task, parameter, protocol)
            };
            let (r, n) = mean(env.as_mut(), &self.base, &nominal)?;
            base_returns.push(r);
            base_steps.push(n);
            let (r, n) = mean(env.as_mut(), expert, &task.parameter())?;
            expert_returns.push(r);
            expert_steps.push(n);
            on_task(i + 1, tasks.len());
        }
        Ok(ReferenceReturns {
            base: self.base_name.clone(),
            expert: self.expert_name.clone(),
            base_returns,
            expert_returns,
            task_values: tasks.iter().map(|t| t.value()).collect(),
            base_steps,
            expert_steps,
        })
    }
}

/// Mean episode return and length of `policy` acting on the observation followed by
/// `parameter`.
fn mean_return(
    env: &mut dyn Environment,
    policy: &Expert,
    task: &Task,
    parameter: &[f32],
    protocol: &Protocol,
) -> Result<(f32, f32)> {
    let od = env.obs_dim();
    let mut input = vec![0.0f32; od + parameter.len()];
    input[od..].copy_from_slice(parameter);
    let mut returns = Vec::with_capacity(protocol.draws * protocol.rollouts);
    let mut steps = Vec::with_capacity(returns.capacity());
    for d in 0..protocol.draws {
        for r in 0..protocol.rollouts {
            let mut act = |obs: &[f32], action: &mut [f32]| {
                input[..od].copy_from_slice(obs);
                policy.act(&input, action)
            };
            let ep = run_episode(env, task, eval::episode_seed(d, r), &mut act, &mut |_| {
                Ok(())
            })?;
            // The family's metric, exactly what the methods' R_pi is (the return here).
            returns.push(ep.metric);
            steps.push(ep.steps as f32);
        }
    }
    Ok((eval::mean_std(&returns).0, eval::mean_std(&steps).0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algo::expert::{ExpertConfig, ExpertTrainer};
    use crate::algo::sac::SacConfig;

    fn tmp(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("smile-evalnorm-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// An untrained walker policy exported as a run of `smile expert` (no training needed to
    /// test loading rules).
    fn walker_policy(dir: &Path, task_value: Option<f64>) {
        let cfg = ExpertConfig {
            env: sim::Family::WALKER_DYN,
            task_value,
            buffer_capacity: 10,
            sac: SacConfig {
                hidden: vec![8],
                ..SacConfig::default()
            },
            ..ExpertConfig::default()
        };
        std::fs::create_dir_all(dir).unwrap();
        ExpertTrainer::new(cfg).unwrap().export_policy(dir).unwrap();
    }

    #[test]
    fn base_and_experts_of_the_wrong_kind_are_typed_errors() {
        let d = tmp("load");
        let (base, general) = (d.join("base"), d.join("general"));
        walker_policy(&base, Some(sim::WALKER_NOMINAL_SEED as f64));
        walker_policy(&general, None);
        let refs = References::load(Family::WALKER_DYN, &base, &[&general]).unwrap();
        assert!(refs.base_name.contains("base") && refs.expert_name.contains("general"));
        let config_err = |r: Result<References>, needle: &str| match r {
            Err(Error::Data(m) | Error::Input { problem: m, .. }) => {
                assert!(m.contains(needle), "{m}")
            }
            other => panic!("expected a data error with {needle:?}, got {other:?}"),
        };
        // Only walker-dyn has the metric.
        config_err(
            References::load(Family::CHEETAH_VEL, &base, &[&general]),
            "walker-dyn only",
        );
        // A base trained on all train tasks, or on a test task, is not the base.
        config_err(
            References::load(Family::WALKER_DYN, &general, &[&general]),
            "nominal task",
        );
        let seeded = d.join("seeded");
        walker_policy(&seeded, Some(sim::WALKER_TEST_SEED_BASE as f64));
        config_err(
            References::load(Family::WALKER_DYN, &seeded, &[&general]),
            "task 10000",
        );
        // Another family's policy, as base or as expert.
        let pd = d.join("pd");
        std::fs::create_dir_all(&pd).unwrap();
        crate::algo::expert::export_scripted_pd(&pd).unwrap();
        for r in [
            References::load(Family::WALKER_DYN, &pd, &[&general]),
            References::load(Family::WALKER_DYN, &base, &[&pd]),
        ] {
            match r {
                Err(
                    e @ Error::WrongFamily {
                        found, expected, ..
                    },
                ) => {
                    assert_eq!((found, expected), (Family::POINT_GOAL, Family::WALKER_DYN));
                    assert!(
                        e.to_string()
                            .contains("pd: family point-goal, expected walker-dyn"),
                        "{e}"
                    );
                }
                other => panic!("expected a wrong-family error, got {other:?}"),
            }
        }
        // A walker policy file whose input width is not walker-dyn's oracle observation.
        let narrow = d.join("narrow");
        let meta = serde_json::json!({
            "kind": "expert-policy", "expert": "sac-oracle", "env": "walker-dyn",
            "widths": [5, 8, 6], "log_std_bounds": [-20.0, 2.0],
            "task_value": sim::WALKER_NOMINAL_SEED as f64,
        });
        crate::io::checkpoint::save(&narrow, &[], &meta).unwrap();
        let narrow_file = narrow.join(crate::io::checkpoint::CHECKPOINT_FILE);
        assert!(matches!(
            References::load(Family::WALKER_DYN, &narrow_file, &[&general]),
            Err(Error::Checkpoint { .. })
        ));
        // A per-task expert set that misses a test task fails before any rollout.
        let only_one = References::load(Family::WALKER_DYN, &base, &[&seeded]).unwrap();
        let protocol = Protocol::for_family(Family::WALKER_DYN);
        assert!(matches!(
            only_one.returns(Split::Test, &protocol, &mut |_, _| {}),
            Err(Error::Input { input: crate::error::Input::Expert, problem })
                if problem.contains("no expert for task")
        ));
        std::fs::remove_dir_all(&d).ok();
    }
}
