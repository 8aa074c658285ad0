//! Meta-BC and Meta-DAgger (reference §3): the same context encoder and policy as SMILe,
//! trained jointly by supervised regression of expert actions.
//!
//! ```text
//! z ~ q(z | c_task)      c_task: k in 1..=4 demos of the task
//! a_hat = tanh(mu_pi([norm(s), z]))          (the action the policy actually outputs)
//! L = mean over tasks and rows of || a_hat - a_E ||^2 / act_dim      (MSE)
//! ```
//! on `tasks_per_batch` tasks x `per_task` expert pairs `(s, a_E)` per step (with `[early]`,
//! pairs recorded in an episode's first steps are drawn `weight` times as often: a weighted
//! mean). The original regressed the pre-tanh mean while evaluating `tanh(mean)`; this
//! regresses what is executed.
//!
//! **Stopping rule** (Meta-BC overfits the few subsampled demos, reference §7): every
//! `eval_every` steps the MSE on the held-out *train* tasks' demos (context = their first demo,
//! z = posterior mean) is measured; the weights with the lowest validation MSE are kept
//! (`meta_policy.safetensors`) and training stops after `patience` evaluations without
//! improvement. The meta-test tasks are never read.
//!
//! **Meta-DAgger**: per-task aggregate datasets start with the demos; every `dagger_every`
//! steps, `dagger_rollouts` rollouts of the current policy (a random training task and
//! context, deterministic actions) are stored with the expert's action for every visited
//! state; training samples the aggregate.

use std::path::Path;

use candle_core::{Device, Tensor};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim::{Environment, TaskDemos};

use crate::algo::expert::ExpertSet;
use crate::algo::fit::{Cadence, Evaluation, Fields, Progress, Score};
use crate::algo::learner::{Learner, MetaInputs, Unit};
use crate::data::{MetaData, better, distinct_tasks, quick_eval, sample_context, sensed_episode};
use crate::error::{Error, Result};
use crate::io::checkpoint::rng_state;
use crate::io::{MetricsLog, checkpoint};
use crate::model::{
    ContextEncoder, ContextSpec, MetaPolicy, TanhGaussianPolicy, TrainingMark, mlp_load,
    mlp_tensors, scalar,
};
use crate::optim::{Adam, AdamConfig};
use crate::threads::LearnerPool;

mod config;

pub use crate::data::EarlyWeight;
pub use config::{MetaBcConfig, Selection};

/// Per-task `(s, a)` pairs: the demos, plus relabelled visits for Meta-DAgger.
#[derive(Debug, Clone, Default)]
struct Pairs {
    obs: Vec<f32>,
    act: Vec<f32>,
}

/// A Meta-BC / Meta-DAgger run.
pub struct MetaBc {
    cfg: MetaBcConfig,
    data: MetaData,
    expert: Option<ExpertSet>,
    env: Box<dyn Environment>,
    /// The context encoder.
    pub encoder: ContextEncoder,
    /// The policy on `[norm(s), z]`.
    pub policy: TanhGaussianPolicy,
    opt: Adam,
    pairs: Vec<Pairs>,
    rng: ChaCha8Rng,
    steps: u64,
    episodes: u64,
    best_mse: f32,
    best_metric: f32,
    bad_evals: u32,
    /// The learner threads of `learner_threads > 1`, started at the first step.
    pool: Option<LearnerPool>,
    stopped: bool,
}

impl MetaBc {
    /// A fresh run; Meta-DAgger needs `expert` (one expert, or per-task experts covering the
    /// meta-train tasks: `Some(expert.into())` for one).
    pub fn new(cfg: MetaBcConfig, data: MetaData, expert: Option<ExpertSet>) -> Result<Self> {
        let family = cfg.env;
        data.ensure_fits(family, cfg.physics)?;
        match (&expert, cfg.dagger) {
            (None, true) => {
                return Err(Error::Config(format!(
                    "meta-dagger needs a relabelling expert for {family}"
                )));
            }
            (Some(e), true) if e.family() != family => {
                return Err(Error::Config(format!(
                    "meta-dagger on {family} demos needs a {family} expert; the expert given \
                     ({}) is a {} expert",
                    e.name(),
                    e.family()
                )));
            }
            (Some(_), false) => return Err(Error::takes_no_expert("meta-bc", None)),
            _ => {}
        }
        // Only Meta-DAgger holds one here: the match above refused it to Meta-BC.
        if let Some(set) = &expert {
            let what = || "meta-dagger's relabelling expert".into();
            Error::same_plant(what, set.physics(), cfg.physics)?;
            // Every meta-train task needs its relabelling expert: fail now, not mid-run.
            for t in &data.train {
                set.for_task(&t.task)?;
            }
        }
        cfg.validate()?;
        let env = sim::make_env(family, cfg.env_config())?;
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let (od, ad) = (family.obs_dim(), family.act_dim());
        let encoder = ContextEncoder::new(od, ad, cfg.context.clone(), &mut rng)?;
        let policy = TanhGaussianPolicy::new(
            od + cfg.context.z_dim,
            ad,
            &cfg.policy_hidden,
            (-20.0, 2.0),
            &mut rng,
        )?;
        let vars = [encoder.vars(), policy.net().vars().to_vec()].concat();
        let opt = Adam::new(vars, AdamConfig::with_lr(cfg.lr));
        let pairs = data
            .train
            .iter()
            .map(|td| {
                let mut p = Pairs::default();
                for t in &td.trajectories {
                    for i in 0..t.actions.len() / ad {
                        let step = t.time_steps.get(i).copied().unwrap_or(u32::MAX);
                        let copies = cfg.early.map_or(1, |e| e.copies(step));
                        for _ in 0..copies {
                            p.obs.extend_from_slice(&t.obs[i * od..(i + 1) * od]);
                            p.act.extend_from_slice(&t.actions[i * ad..(i + 1) * ad]);
                        }
                    }
                }
                p
            })
            .collect();
        Ok(Self {
            cfg,
            data,
            expert,
            env,
            encoder,
            policy,
            opt,
            pairs,
            rng,
            steps: 0,
            episodes: 0,
            best_mse: f32::INFINITY,
            best_metric: f32::NAN,
            bad_evals: 0,
            stopped: false,
            pool: None,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &MetaBcConfig {
        &self.cfg
    }

    /// Gradient steps done.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Pairs in the aggregate dataset of every training task (demos + relabelled visits).
    pub fn dataset_size(&self) -> usize {
        self.pairs.iter().map(|p| p.act.len()).sum::<usize>() / self.data.family.act_dim()
    }

    /// Training task `ti`'s aggregate dataset as row-major `(observations, actions)`: its demo
    /// pairs first, then (Meta-DAgger) the visited states with the expert's actions.
    pub fn aggregate(&self, ti: usize) -> (&[f32], &[f32]) {
        let p = &self.pairs[ti];
        (&p.obs, &p.act)
    }

    /// The training mark of a policy saved now.
    fn mark(&self, finished: bool) -> TrainingMark {
        TrainingMark {
            updates: self.steps,
            total_updates: self.cfg.total_steps,
            finished,
        }
    }

    /// The current policy as a [`MetaPolicy`] (shares the live weights).
    pub fn meta_policy(&self) -> MetaPolicy {
        let cfg = &self.cfg;
        self.data
            .meta_policy(cfg.physics, cfg.algo_name(), &self.encoder, &self.policy)
    }

    /// `mean ||tanh(mu([norm(s), z])) - a||^2 / act_dim` with one z per context.
    fn mse(&self, z: &Tensor, obs: &[Vec<f32>], act: &[Vec<f32>]) -> Result<Tensor> {
        let (od, ad) = (self.data.family.obs_dim(), self.data.family.act_dim());
        // Rows of context c use z[c]: broadcast with a one-hot matrix so gradients reach z.
        let rows: usize = act.iter().map(|a| a.len() / ad).sum();
        let mut onehot = vec![0.0f32; rows * obs.len()];
        let (mut o_all, mut a_all) = (Vec::with_capacity(rows * od), Vec::with_capacity(rows * ad));
        let mut r = 0;
        for (c, (o, a)) in obs.iter().zip(act).enumerate() {
            for _ in 0..a.len() / ad {
                onehot[r * obs.len() + c] = 1.0;
                r += 1;
            }
            for row in o.chunks_exact(od) {
                self.data.norm.push(row, &mut o_all);
            }
            a_all.extend_from_slice(a);
        }
        let dev = &Device::Cpu;
        let z_rows = Tensor::from_vec(onehot, (rows, obs.len()), dev)?.matmul(z)?;
        let x_obs = Tensor::from_vec(o_all, (rows, od), dev)?;
        let x = Tensor::cat(&[&x_obs, &z_rows], 1)?;
        let (mean, _) = self.policy.heads(&x)?;
        let target = Tensor::from_vec(a_all, (rows, ad), dev)?;
        // The original code regressed the pre-tanh mean (`pre_tanh_loss`, for comparison only).
        let output = if self.cfg.pre_tanh_loss {
            mean
        } else {
            mean.tanh()?
        };
        Ok((output - target)?.sqr()?.mean_all()?)
    }

    /// One gradient step; returns the training MSE. With `learner_threads` > 1 it runs in the
    /// run's thread pool (started at the first step), its large products split.
    pub fn step(&mut self) -> Result<f32> {
        if self.cfg.learner_threads < 2 {
            return self.step_here();
        }
        let pool = match self.pool.take() {
            Some(p) => p,
            None => LearnerPool::new(self.cfg.learner_threads)?,
        };
        let out = pool.install(|| self.step_here());
        self.pool = Some(pool);
        out
    }

    /// [`Self::step`] on the calling thread.
    fn step_here(&mut self) -> Result<f32> {
        let (od, ad) = (self.data.family.obs_dim(), self.data.family.act_dim());
        let tasks = distinct_tasks(
            self.data.train.len(),
            self.cfg.tasks_per_batch,
            &mut self.rng,
        );
        let mut specs: Vec<ContextSpec<'_>> = Vec::new();
        let (mut obs, mut act) = (Vec::new(), Vec::new());
        for &ti in &tasks {
            specs.push(sample_context(
                &self.data.train[ti],
                self.cfg.context_draw(),
                &mut self.rng,
            ));
            let p = &self.pairs[ti];
            let n = p.act.len() / ad;
            let (mut o, mut a) = (Vec::new(), Vec::new());
            for _ in 0..self.cfg.per_task {
                let i = self.rng.random_range(0..n);
                o.extend_from_slice(&p.obs[i * od..(i + 1) * od]);
                a.extend_from_slice(&p.act[i * ad..(i + 1) * ad]);
            }
            // Through the device's senses: the policy learns the demo's action from the state
            // as the device would read it (noise injection; the context stays as recorded).
            if let Some(sensing) = &self.cfg.sensing {
                sensing.read_rows(&mut o, od, &mut self.rng);
            }
            obs.push(o);
            act.push(a);
        }
        let b = self.encoder.batch(&self.data.norm, &specs)?;
        let z = self.encoder.z(&b, true, &mut self.rng)?;
        let loss = self.mse(&z, &obs, &act)?;
        let v = scalar(&loss)?;
        if !v.is_finite() {
            return Err(Error::NonFinite {
                what: "losses/bc_mse",
                value: v,
                update: self.steps + 1,
            });
        }
        self.opt.backward_step(&loss)?;
        self.steps += 1;
        Ok(v)
    }

    /// Validation MSE on held-out train tasks: context = first demo, z = posterior mean,
    /// targets = all of the task's demo pairs.
    pub fn val_mse(&self) -> Result<f32> {
        val_mse_on(self, &self.data.val)
    }

    /// Meta-DAgger: `n` deterministic rollouts relabelled by the expert.
    pub fn dagger_rollouts(&mut self, n: usize) -> Result<()> {
        let Some(expert) = self.expert.clone() else {
            return Err(Error::input(
                crate::error::Input::Expert,
                "meta-dagger relabels its rollouts with an expert (an expert run); none was given",
            ));
        };
        let mp = self.meta_policy();
        for _ in 0..n {
            let ti = self.rng.random_range(0..self.data.train.len());
            let spec = sample_context(&self.data.train[ti], self.cfg.context_draw(), &mut self.rng);
            let ctx: Vec<_> = spec.trajectories[..spec.k].to_vec();
            let z = mp.latent(&ctx)?;
            let task = self.data.train[ti].task;
            let expert = expert.for_task(&task)?;
            let seed = sim::seeds::DAGGER_SEED + self.episodes;
            let (rng, pairs) = (&mut self.rng, &mut self.pairs[ti]);
            let mut a_exp = vec![0.0f32; self.data.family.act_dim()];
            // Through the device's senses where configured: the learner acts on what the
            // device would read, the expert labels the true state (DART's noise where the
            // learner acts).
            sensed_episode(
                self.env.as_mut(),
                &task,
                seed,
                self.cfg.sensing.as_ref(),
                &mut |o, a| {
                    a.copy_from_slice(&mp.act(o, &z, true, rng)?);
                    Ok(())
                },
                &mut |st| {
                    expert.act(st.oracle, &mut a_exp)?;
                    pairs.obs.extend_from_slice(st.obs);
                    pairs.act.extend(a_exp.iter().map(|v| v.clamp(-1.0, 1.0)));
                    Ok(())
                },
            )?;
            self.episodes += 1;
        }
        Ok(())
    }

    /// Writes the checkpoint to `dir`.
    pub fn save_checkpoint(&self, dir: &Path) -> Result<()> {
        let mut ts: Vec<(String, Tensor)> = Vec::new();
        mlp_tensors("phi", &self.encoder.phi, &mut ts);
        mlp_tensors("head", &self.encoder.head, &mut ts);
        mlp_tensors("policy", self.policy.net(), &mut ts);
        let t = self.opt.save_into("opt", &mut ts)?;
        let (od, ad) = (self.data.family.obs_dim(), self.data.family.act_dim());
        for (i, p) in self.pairs.iter().enumerate() {
            let n = p.act.len() / ad;
            ts.push((
                format!("pairs.{i}.obs"),
                Tensor::from_slice(&p.obs, (n, od), &Device::Cpu)?,
            ));
            ts.push((
                format!("pairs.{i}.act"),
                Tensor::from_slice(&p.act, (n, ad), &Device::Cpu)?,
            ));
        }
        let meta = serde_json::json!({
            "kind": "meta-bc-run",
            "config": self.cfg,
            "adam_steps": t,
            "steps": self.steps,
            "episodes": self.episodes,
            "best_mse": if self.best_mse.is_finite() { serde_json::Value::from(self.best_mse) } else { serde_json::Value::Null },
            "best_metric": if self.best_metric.is_finite() { serde_json::Value::from(self.best_metric) } else { serde_json::Value::Null },
            "bad_evals": self.bad_evals,
            "stopped": self.stopped,
            "rng": rng_state(&self.rng),
        });
        checkpoint::save(dir, &ts, &meta)?;
        Ok(())
    }

    /// Resumes the run checkpointed in `dir`; `total_steps` overrides the saved target.
    pub fn resume(
        dir: &Path,
        data: MetaData,
        expert: Option<ExpertSet>,
        total_steps: Option<u64>,
    ) -> Result<Self> {
        let ck = checkpoint::load(dir)?;
        if ck.meta.get("kind").and_then(|k| k.as_str()) != Some("meta-bc-run") {
            return Err(Error::Checkpoint {
                path: ck.path().into(),
                reason: "not a Meta-BC run".into(),
            });
        }
        let mut cfg: MetaBcConfig = ck.meta_field("config")?;
        if let Some(t) = total_steps {
            cfg.total_steps = t;
        }
        let mut run = Self::new(cfg, data, expert)?;
        let get = |n: &str| ck.get(n);
        mlp_load("phi", &run.encoder.phi, &get)?;
        mlp_load("head", &run.encoder.head, &get)?;
        mlp_load("policy", run.policy.net(), &get)?;
        run.opt
            .load_from("opt", &get, ck.meta_field("adam_steps")?)?;
        for (i, p) in run.pairs.iter_mut().enumerate() {
            p.obs = get(&format!("pairs.{i}.obs"))?
                .flatten_all()?
                .to_vec1::<f32>()?;
            p.act = get(&format!("pairs.{i}.act"))?
                .flatten_all()?
                .to_vec1::<f32>()?;
        }
        run.steps = ck.meta_field("steps")?;
        run.episodes = ck.meta_field("episodes")?;
        run.best_mse = ck
            .meta_field::<Option<f32>>("best_mse")?
            .unwrap_or(f32::INFINITY);
        // Absent from checkpoints written before rollout selection existed.
        run.best_metric = ck
            .meta
            .get("best_metric")
            .and_then(|v| v.as_f64())
            .map_or(f32::NAN, |v| v as f32);
        run.bad_evals = ck.meta_field("bad_evals")?;
        run.stopped = ck.meta_field("stopped")?;
        run.rng = ck.meta_rng("rng")?;
        Ok(run)
    }
}

// The run in the one fit loop: a gradient step (after DAgger's rollouts when due) is its unit
// of work, the held-out evaluation with the patience rule its evaluation.
impl Learner for MetaBc {
    type Config = MetaBcConfig;
    type Inputs = MetaInputs;
    const UNIT: Unit = Unit {
        plural: "steps",
        word: "step",
    };

    fn start(cfg: MetaBcConfig, inputs: MetaInputs) -> Result<Self> {
        MetaBc::new(cfg, inputs.data, inputs.expert)
    }

    fn resume(dir: &Path, inputs: MetaInputs, wanted: &MetaBcConfig) -> Result<Self> {
        MetaBc::resume(dir, inputs.data, inputs.expert, Some(wanted.total_steps))
    }

    fn config(&self) -> &MetaBcConfig {
        &self.cfg
    }

    fn done(&self) -> u64 {
        self.steps
    }

    fn cadence(&self) -> Cadence {
        Cadence {
            total: self.cfg.total_steps,
            eval_every: self.cfg.eval_every,
            eval_at_end: true,
            checkpoint_every: self.cfg.checkpoint_every,
            cpu_budget_s: 0.0,
        }
    }

    fn finished(&self) -> bool {
        self.steps >= self.cfg.total_steps || self.stopped
    }

    fn advance(&mut self, on: &mut dyn FnMut(Progress)) -> Result<Fields> {
        let cfg = &self.cfg;
        if cfg.dagger && self.steps.is_multiple_of(cfg.dagger_every.max(1)) {
            self.dagger_rollouts(cfg.dagger_rollouts)?;
        }
        let mse = self.step()?;
        on(Progress::Steps(self.steps));
        if !self.steps.is_multiple_of(50) {
            return Ok(Vec::new());
        }
        Ok(vec![
            ("losses/bc_mse", mse as f64),
            ("charts/dataset_size", self.dataset_size() as f64),
        ])
    }

    fn evaluate(&mut self) -> Result<Option<Evaluation>> {
        let at_end = self.steps >= self.cfg.total_steps;
        let cfg = &self.cfg;
        let val_mse = self.val_mse()?;
        let val_metric = quick_eval(
            &self.meta_policy(),
            &self.data.val,
            cfg.held_out(),
            cfg.env_config(),
        )?;
        let improved = match cfg.select_by {
            Selection::Mse => val_mse < self.best_mse,
            Selection::Rollouts => {
                better(self.data.family.metric_kind(), val_metric, self.best_metric)
            }
        };
        // Without held-out tasks the last policy is the one kept.
        let keep = improved || (self.data.val.is_empty() && at_end);
        if keep {
            (self.best_mse, self.best_metric) = (val_mse, val_metric);
            self.bad_evals = 0;
        } else {
            self.bad_evals += 1;
            if cfg.patience > 0 && self.bad_evals >= cfg.patience {
                // The stopping rule: `finished` now tells the loop.
                self.stopped = true;
            }
        }
        Ok(Some(Evaluation {
            keep,
            fields: vec![
                ("eval/val_mse", val_mse as f64),
                ("eval/val_metric", val_metric as f64),
                ("eval/val_best_mse", self.best_mse as f64),
                ("eval/val_best_metric", self.best_metric as f64),
            ],
            score: Score {
                what: "held-out metric",
                metric: val_metric,
                best: self.best_metric,
                val_mse: Some(val_mse),
            },
        }))
    }

    fn save_checkpoint(&self, dir: &Path) -> Result<()> {
        MetaBc::save_checkpoint(self, dir)
    }

    fn save_kept(&self, dir: &Path) -> Result<()> {
        self.meta_policy().save_marked(dir, Some(self.mark(false)))
    }

    fn finish(&mut self, dir: &Path, _log: &mut MetricsLog) -> Result<()> {
        self.meta_policy().save_final(dir, self.mark(true), false)
    }
}

fn val_mse_on(run: &MetaBc, tasks: &[TaskDemos]) -> Result<f32> {
    if tasks.is_empty() {
        return Ok(f32::NAN);
    }
    let specs: Vec<ContextSpec<'_>> = tasks
        .iter()
        .map(|td| ContextSpec::all(vec![&td.trajectories[0]]))
        .collect();
    let b = run.encoder.batch(&run.data.norm, &specs)?;
    let (mu, _) = run.encoder.posterior(&b)?;
    let obs: Vec<Vec<f32>> = tasks
        .iter()
        .map(|td| td.trajectories.iter().flat_map(|t| t.obs.clone()).collect())
        .collect();
    let act: Vec<Vec<f32>> = tasks
        .iter()
        .map(|td| {
            td.trajectories
                .iter()
                .flat_map(|t| t.actions.clone())
                .collect()
        })
        .collect();
    scalar(&run.mse(&mu.detach(), &obs, &act)?)
}
