//! Task experts: SAC on the *oracle* observation (observation followed by the task parameter)
//! across a family's meta-train tasks (or one task, for per-task experts), as the SMILe
//! reference does (§4 "Experts"); and the scripted point-goal PD controller from `sim` as an
//! explicitly selected expert kind.
//!
//! Training loop (one process, one thread: the environment step is microseconds, the update
//! milliseconds, so a separate rollout thread would buy nothing for one update per step):
//! each episode draws a train task uniformly and resets with a seed derived from the episode
//! index; the first `learning_starts` steps act uniformly at random; after that every env step
//! is followed by `updates_per_step` SAC updates. Checkpoints are taken at episode ends, so a
//! resumed run continues exactly like an uninterrupted one.

use std::path::Path;

use candle_core::Tensor;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use sim::{EnvConfig, Environment, EpisodeMetric, Family, Physics, Task};

use crate::algo::fit::{Cadence, Evaluation, Fields, Progress, Score};
use crate::algo::learner::{Learner, Unit};
use crate::algo::sac::{Sac, SacConfig, SacCounters, SacStats};
use crate::data::{ReplayBuffer, better};
mod demos;
pub(crate) mod set;
use crate::error::{Error, Result};
use crate::io::checkpoint::{POLICY_FILE, rng_state};
use crate::io::{MetricsLog, checkpoint};
use crate::threads::LearnerPool;
pub use demos::{DemoSpec, record, record_with};
pub use set::{
    EvalReport, ExpertSet, SCRIPTED_PD, eval_seed, evaluate, evaluate_distinct,
    evaluate_under_noise, trained_task_value,
};

mod policy;
use policy::write_policy;
pub use policy::{Expert, export_scripted_linclass, export_scripted_pd};

/// Expert training configuration (TOML section names match the field names).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExpertConfig {
    /// Task family, written by its name (`point-goal`, `cheetah-vel`, `walker-dyn`, `ant-goal`,
    /// `ant-linclass`). Default `point-goal`.
    pub env: Family,
    /// Physics backend of the plant, `rapier` (default) or `mujoco` (the `mujoco` build).
    /// A config written before the MuJoCo backend existed reads as Rapier.
    pub physics: Physics,
    /// Train on this one meta-train task index only (per-task expert). Default: all tasks.
    pub task_index: Option<usize>,
    /// Train on this one task given by its parameter instead (goal angle in rad, target
    /// velocity in m/s, dynamics seed), e.g. a meta-test task: per-task experts for demos;
    /// `sim::WALKER_NOMINAL_SEED` is the unmodified walker (the normalised metric's base).
    /// Default: None.
    pub task_value: Option<f64>,
    /// Environment steps in total. Default 30 000 (point-goal; cheetah needs ~160k, ref §7).
    pub total_steps: u64,
    /// Uniform-random-action steps before learning starts. Default 2 000 (CleanRL uses 5 000).
    pub learning_starts: u64,
    /// SAC updates per environment step. Default 1 (SAC-v2).
    pub updates_per_step: usize,
    /// Replay capacity in transitions. Default 300 000.
    pub buffer_capacity: usize,
    /// Checkpoint at the first episode end after every this many env steps. Default 10 000.
    pub checkpoint_every: u64,
    /// Deterministic evaluation on the meta-test tasks (or the expert's own task) at the first
    /// episode end after every this many env steps, logged as `eval/metric` and
    /// `eval/final_sample`; 0 = never. Default 10 000.
    pub eval_every: u64,
    /// Episodes per task in those evaluations. Default 1.
    pub eval_episodes: usize,
    /// Warm start: begin from the SAC state (actor, critics, target critics, temperature and
    /// their optimisers) of this expert run's checkpoint, e.g. per-task walker experts
    /// fine-tuned from the walker trained on the unmodified dynamics. The replay buffer starts
    /// empty and the first `learning_starts` steps act with the loaded policy (sampled), not at
    /// random. Same family and widths required. Default None (from scratch).
    pub init_from: Option<std::path::PathBuf>,
    /// Ship the best-evaluated weights, not the last: every evaluation that beats the best so
    /// far writes `policy-best.safetensors`, and at the end `policy.safetensors` is whichever
    /// of it and the final weights evaluates better (SAC oscillates: a walker that walked at
    /// 150k steps can fall at 300k). Needs `eval_every` > 0. Default false.
    pub keep_best: bool,
    /// Episode length override; `None` uses the family's horizon. Default None.
    pub horizon: Option<usize>,
    /// Seed of everything (weights, task draws, noise, reset seeds). Default 0.
    pub seed: u64,
    /// Learner threads: the SAC updates run in a pool of this many threads that splits their
    /// large matrix products (`crate::threads`); the same weights on any count (a split
    /// product equals an unsplit one). Default 1.
    #[serde(skip_serializing_if = "crate::threads::is_one")]
    pub learner_threads: usize,
    /// SAC hyper-parameters.
    pub sac: SacConfig,
}

impl Default for ExpertConfig {
    fn default() -> Self {
        Self {
            env: Family::default(),
            physics: Physics::Rapier,
            task_index: None,
            task_value: None,
            total_steps: 30_000,
            learning_starts: 2_000,
            updates_per_step: 1,
            buffer_capacity: 300_000,
            checkpoint_every: 10_000,
            eval_every: 10_000,
            eval_episodes: 1,
            init_from: None,
            keep_best: false,
            horizon: None,
            seed: 0,
            learner_threads: 1,
            sac: SacConfig::default(),
        }
    }
}

impl ExpertConfig {
    /// Rejects values that cannot train: a positive step budget, replay, update rate and
    /// evaluation, an episode of at least one step, valid SAC settings and thread count.
    pub fn validate(&self) -> Result<()> {
        crate::io::require_run(
            ("total_steps", self.total_steps),
            &[
                ("updates_per_step", self.updates_per_step),
                ("buffer_capacity", self.buffer_capacity),
                ("eval_episodes", self.eval_episodes),
            ],
            self.horizon,
            self.learner_threads,
        )?;
        if self.learning_starts >= self.total_steps && self.init_from.is_none() {
            // Every step would act at random and no update would run: a run that trains
            // nothing and still writes an expert (issue 72, item 4).
            return Err(Error::Config(format!(
                "learning_starts ({}) must be below total_steps ({}): no update would run",
                self.learning_starts, self.total_steps
            )));
        }
        self.sac.validate()
    }

    fn env_config(&self) -> EnvConfig {
        EnvConfig::new(self.horizon, self.physics)
    }

    /// The tasks this expert trains on.
    pub fn tasks(&self) -> Result<Vec<Task>> {
        let family = self.env;
        if let Some(v) = self.task_value {
            if self.task_index.is_some() {
                return Err(Error::Config(
                    "give task_index or task_value, not both".into(),
                ));
            }
            return Ok(vec![family.task_named(v)?]);
        }
        let all = family.train_tasks();
        match self.task_index {
            None => Ok(all),
            Some(i) if i < all.len() => Ok(vec![all[i]]),
            Some(i) => Err(Error::Config(format!(
                "task_index {i} >= {} train tasks",
                all.len()
            ))),
        }
    }
}

/// What one finished episode reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpisodeReport {
    /// Env steps so far (after this episode).
    pub env_steps: u64,
    /// Episodes so far.
    pub episodes: u64,
    /// Undiscounted return of the episode.
    pub episodic_return: f32,
    /// The family's metric for the episode (min distance, mean |v - v*|, return).
    pub metric: f32,
    /// Stats of the last SAC update in the episode, if any.
    pub last_update: Option<SacStats>,
}

/// The state of an expert training run: everything a checkpoint must hold.
pub struct ExpertTrainer {
    cfg: ExpertConfig,
    family: Family,
    tasks: Vec<Task>,
    env: Box<dyn Environment>,
    /// The SAC agent.
    pub sac: Sac,
    replay: ReplayBuffer,
    rng: ChaCha8Rng,
    env_steps: u64,
    episodes: u64,
    /// The best periodic evaluation so far (with `keep_best`).
    best: Option<BestEval>,
    /// Where the updates run (`learner_threads`).
    pool: LearnerPool,
}

/// The best evaluation of a run with `keep_best`: its metric and when it was taken; the
/// weights are in `policy-best.safetensors`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BestEval {
    /// The family's metric, mean over the evaluation tasks.
    pub metric: f32,
    /// Env steps at the evaluation.
    pub env_steps: u64,
}

pub use crate::io::checkpoint::BEST_POLICY_FILE;

/// Loads the checkpoint of another expert run that `cfg` warm-starts from (see
/// `ExpertConfig::init_from`), refusing one of another family, width or physics backend.
fn warm_start_source(dir: &Path, cfg: &ExpertConfig) -> Result<checkpoint::Loaded> {
    let ck = checkpoint::load(dir)?;
    let foreign = |reason: String| Error::CheckpointState {
        path: ck.path().to_path_buf(),
        reason,
    };
    if ck.meta.get("kind").and_then(|k| k.as_str()) != Some("expert-run") {
        return Err(foreign(
            "the starting checkpoint must be an expert training run's checkpoint".into(),
        ));
    }
    let source: ExpertConfig = ck.meta_field("config")?;
    if source.env != cfg.env
        || source.sac.hidden != cfg.sac.hidden
        || source.sac.actor_hidden != cfg.sac.actor_hidden
    {
        return Err(foreign(format!(
            "a {} expert with hidden {:?} cannot start a {} expert with hidden {:?}",
            source.env, source.sac.hidden, cfg.env, cfg.sac.hidden
        )));
    }
    if source.physics != cfg.physics {
        // Its critics value another plant's states: fine-tuning would silently start from a
        // policy of the wrong robot (e.g. a MuJoCo base for experts that forgot `--physics`).
        return Err(foreign(format!(
            "an expert trained on {} cannot start one on {} (set the same physics backend)",
            source.physics.name(),
            cfg.physics.name()
        )));
    }
    Ok(ck)
}

impl ExpertTrainer {
    /// A fresh run (warm-started from `cfg.init_from` if set).
    pub fn new(cfg: ExpertConfig) -> Result<Self> {
        // The warm start's source is checked before anything is built, so a mismatch (another
        // family, width or plant) is refused at once, by name.
        let source = cfg
            .init_from
            .as_deref()
            .map(|dir| warm_start_source(dir, &cfg))
            .transpose()?;
        let mut run = Self::build(cfg)?;
        if let Some(ck) = source {
            let counters: SacCounters = ck.meta_field("sac_counters")?;
            let path = ck.path().to_path_buf();
            run.sac
                .load_state(&|n| ck.get(n), counters)
                .map_err(|e| Error::CheckpointState {
                    path,
                    reason: format!("does not match this configuration: {e}"),
                })?;
        }
        Ok(run)
    }

    fn build(cfg: ExpertConfig) -> Result<Self> {
        cfg.validate()?;
        let pool = LearnerPool::new(cfg.learner_threads)?;
        let family = cfg.env;
        let tasks = cfg.tasks()?;
        let env = sim::make_env(family, cfg.env_config())?;
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let (od, ad) = (family.oracle_obs_dim(), family.act_dim());
        let sac = Sac::new(od, ad, cfg.sac.clone(), &mut rng)?;
        let replay = ReplayBuffer::new(od, ad, cfg.buffer_capacity)?;
        Ok(Self {
            cfg,
            family,
            tasks,
            env,
            sac,
            replay,
            rng,
            env_steps: 0,
            episodes: 0,
            best: None,
            pool,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &ExpertConfig {
        &self.cfg
    }

    /// Environment steps taken.
    pub fn env_steps(&self) -> u64 {
        self.env_steps
    }

    /// Run one episode (acting, storing, updating). `on_step` is called after every env step
    /// with the env step count (for progress bars).
    pub fn run_episode(&mut self, on_step: &mut dyn FnMut(u64)) -> Result<EpisodeReport> {
        let task = self.tasks[self.rng.random_range(0..self.tasks.len())];
        let reset_seed = self
            .cfg
            .seed
            .wrapping_mul(sim::seeds::TRAINING_SEED_STRIDE)
            .wrapping_add(self.episodes);
        self.env.reset(&task, reset_seed)?;
        let (od, ad) = (self.family.oracle_obs_dim(), self.family.act_dim());
        let (mut obs, mut next) = (vec![0.0f32; od], vec![0.0f32; od]);
        self.env.oracle_observation(&mut obs)?;
        let mut metric = EpisodeMetric::new(self.family);
        let (mut ret, mut last_update) = (0.0f32, None);
        loop {
            let explore = self.cfg.init_from.is_none() && self.env_steps < self.cfg.learning_starts;
            let action: Vec<f32> = if explore {
                (0..ad)
                    .map(|_| self.rng.random_range(-1.0f32..1.0))
                    .collect()
            } else {
                self.sac.actor.act(&obs, false, &mut self.rng)?
            };
            let tr = self.env.step(&action)?;
            let (reward, done, info) = (tr.reward, tr.done, tr.info);
            self.env.oracle_observation(&mut next)?;
            self.replay
                .push(&obs, &action, reward, &next, info.terminated, None)?;
            metric.record(&info);
            ret += reward;
            self.env_steps += 1;
            if self.env_steps > self.cfg.learning_starts {
                for _ in 0..self.cfg.updates_per_step {
                    let batch = self.replay.sample(self.cfg.sac.batch_size, &mut self.rng)?;
                    let (sac, rng) = (&mut self.sac, &mut self.rng);
                    last_update = Some(self.pool.install(|| sac.update(&batch, rng))?);
                }
            }
            on_step(self.env_steps);
            std::mem::swap(&mut obs, &mut next);
            if done {
                break;
            }
        }
        self.episodes += 1;
        Ok(EpisodeReport {
            env_steps: self.env_steps,
            episodes: self.episodes,
            episodic_return: ret,
            metric: metric.value(),
            last_update,
        })
    }

    /// Write a checkpoint of the whole run to `dir` (atomic).
    pub fn save_checkpoint(&self, dir: &Path) -> Result<()> {
        let (mut tensors, counters) = self.sac.state_tensors()?;
        tensors.extend(self.replay.to_tensors("replay")?);
        let meta = serde_json::json!({
            "kind": "expert-run",
            "config": self.cfg,
            "sac_counters": counters,
            "env_steps": self.env_steps,
            "episodes": self.episodes,
            "rng": rng_state(&self.rng),
            "best_eval": self.best,
        });
        checkpoint::save(dir, &tensors, &meta)?;
        Ok(())
    }

    /// Restore a run from the checkpoint in `dir`. The saved configuration is used, except
    /// `total_steps`, which may be raised by `total_steps` to train longer.
    pub fn resume(dir: &Path, total_steps: Option<u64>) -> Result<Self> {
        let ck = checkpoint::load(dir)?;
        if ck.meta.get("kind").and_then(|k| k.as_str()) != Some("expert-run") {
            return Err(Error::Checkpoint {
                path: ck.path().to_path_buf(),
                reason: "not an expert training checkpoint".into(),
            });
        }
        let mut cfg: ExpertConfig = ck.meta_field("config")?;
        if let Some(t) = total_steps {
            cfg.total_steps = t;
        }
        // Not `new`: the warm start, if any, is already in the checkpoint.
        let mut run = Self::build(cfg)?;
        let counters: SacCounters = ck.meta_field("sac_counters")?;
        let wrap = |e: Error| Error::CheckpointState {
            path: ck.path().to_path_buf(),
            reason: format!("does not match this configuration: {e}"),
        };
        run.sac.load_state(&|n| ck.get(n), counters).map_err(wrap)?;
        run.replay
            .load_tensors("replay", &|n| ck.get(n))
            .map_err(wrap)?;
        run.env_steps = ck.meta_field("env_steps")?;
        run.episodes = ck.meta_field("episodes")?;
        run.rng = ck.meta_rng("rng")?;
        // Checkpoints written before `keep_best` existed have no entry.
        run.best = match ck.meta.get("best_eval") {
            Some(v) if !v.is_null() => ck.meta_field("best_eval")?,
            _ => None,
        };
        Ok(run)
    }

    /// The best periodic evaluation so far (runs with `keep_best`).
    pub fn best_eval(&self) -> Option<BestEval> {
        self.best
    }

    /// Export the deterministic policy (actor weights + metadata) to `dir/policy.safetensors`.
    pub fn export_policy(&self, dir: &Path) -> Result<()> {
        self.export_policy_as(dir, POLICY_FILE)
    }

    /// Export the deterministic policy to `dir/file` (atomic).
    fn export_policy_as(&self, dir: &Path, file: &str) -> Result<()> {
        let net = self.sac.actor.net();
        let tensors: Vec<(String, Tensor)> = net
            .vars()
            .iter()
            .enumerate()
            .map(|(i, v)| (format!("actor.{i}"), v.as_tensor().detach()))
            .collect();
        let meta = serde_json::json!({
            "kind": "expert-policy",
            "expert": "sac-oracle",
            "env": self.family.name(),
            "physics": self.cfg.physics.name(),
            "widths": net.widths(),
            "log_std_bounds": [self.cfg.sac.log_std_min, self.cfg.sac.log_std_max],
            "env_steps": self.env_steps,
            "task_value": (self.tasks.len() == 1).then(|| self.tasks[0].value()),
        });
        write_policy(dir, file, &tensors, &meta)
    }
}

impl ExpertTrainer {
    /// The current actor as an [`Expert`] (for evaluation during training).
    pub fn expert(&self) -> Expert {
        Expert::Sac {
            family: self.family,
            physics: self.cfg.physics,
            policy: self.sac.actor.clone(),
        }
    }
}

impl ExpertTrainer {
    /// The current actor, deterministic, on the evaluation tasks: the meta-test tasks, or the
    /// expert's own task.
    fn evaluate_now(&self) -> Result<EvalReport> {
        let cfg = &self.cfg;
        let eval_tasks = match (cfg.task_index, cfg.task_value) {
            (None, None) => self.family.test_tasks(),
            _ => self.tasks.clone(),
        };
        evaluate(
            &self.expert(),
            &eval_tasks,
            cfg.eval_episodes,
            cfg.env_config(),
        )
    }
}

impl Learner for ExpertTrainer {
    type Config = ExpertConfig;
    type Inputs = ();
    const UNIT: Unit = Unit {
        plural: "env steps",
        word: "env step",
    };

    fn start(cfg: ExpertConfig, (): ()) -> Result<Self> {
        ExpertTrainer::new(cfg)
    }

    fn resume(dir: &Path, (): (), wanted: &ExpertConfig) -> Result<Self> {
        ExpertTrainer::resume(dir, Some(wanted.total_steps))
    }

    fn config(&self) -> &ExpertConfig {
        &self.cfg
    }

    fn done(&self) -> u64 {
        self.env_steps
    }

    fn cadence(&self) -> Cadence {
        Cadence {
            total: self.cfg.total_steps,
            eval_every: self.cfg.eval_every,
            eval_at_end: false,
            checkpoint_every: self.cfg.checkpoint_every,
            cpu_budget_s: 0.0,
        }
    }

    fn advance(&mut self, on: &mut dyn FnMut(Progress)) -> Result<Fields> {
        let rep = self.run_episode(&mut |s| on(Progress::Steps(s)))?;
        let mut fields = vec![
            ("charts/episodic_return", rep.episodic_return as f64),
            ("charts/metric", rep.metric as f64),
            ("charts/updates", self.sac.updates() as f64),
        ];
        if let Some(s) = &rep.last_update {
            fields.extend(s.fields());
        }
        on(Progress::Episode {
            step: rep.env_steps,
            episodic_return: rep.episodic_return,
            metric: rep.metric,
        });
        Ok(fields)
    }

    // Deterministic, on its own environment: does not touch the run's state or RNG.
    fn evaluate(&mut self) -> Result<Option<Evaluation>> {
        let ev = self.evaluate_now()?;
        let keep = self.cfg.keep_best
            && self
                .best
                .is_none_or(|b| better(self.family.metric_kind(), ev.mean, b.metric));
        if keep {
            self.best = Some(BestEval {
                metric: ev.mean,
                env_steps: self.env_steps,
            });
        }
        Ok(Some(Evaluation {
            keep,
            fields: vec![
                ("eval/metric", ev.mean as f64),
                ("eval/final_sample", ev.final_sample_mean as f64),
            ],
            score: Score {
                what: "deterministic evaluation",
                metric: ev.mean,
                best: self.best.map_or(ev.mean, |b| b.metric),
                val_mse: None,
            },
        }))
    }

    fn save_checkpoint(&self, dir: &Path) -> Result<()> {
        ExpertTrainer::save_checkpoint(self, dir)
    }

    fn save_kept(&self, dir: &Path) -> Result<()> {
        self.export_policy_as(dir, BEST_POLICY_FILE)
    }

    /// `policy.safetensors`: the final weights, or with `keep_best` the best-evaluated ones
    /// if the final weights evaluate worse (the same tasks and episodes as the periodic
    /// evaluations).
    fn finish(&mut self, dir: &Path, log: &mut MetricsLog) -> Result<()> {
        let best_file = dir.join(BEST_POLICY_FILE);
        let best = match self.best {
            Some(b) if self.cfg.keep_best && best_file.exists() => b,
            _ => return self.export_policy(dir),
        };
        let last = self.evaluate_now()?;
        log.log(self.env_steps, &[("eval/metric", last.mean as f64)])?;
        if better(self.family.metric_kind(), best.metric, last.mean) {
            let bytes = std::fs::read(&best_file).map_err(Error::io(&best_file))?;
            crate::io::checkpoint::write_atomic(&dir.join(POLICY_FILE), &bytes)
        } else {
            self.export_policy(dir)
        }
    }
}
