//! Distilling a meta-policy through the device's senses (issue 73): the policy as trained, on
//! true states (the teacher), teaches a copy of its actor (the student) to act from what the
//! device reads (`[sensing]`: noise and the ADC, or position-only sensing with the on-board
//! estimator) as the teacher acts from the truth. The privileged-teacher recipe of robot
//! learning (Chen et al. 2019, "Learning by Cheating"; Lee et al. 2020), with DAgger's data
//! (Ross et al. 2011): the states come from the student's own closed loop through the sensors,
//! so it learns to act where its own mistakes take it.
//!
//! `L = E_(s, o, z) || tanh(mu_student(o, z)) - tanh(mu_teacher(s, z)) ||^2`
//!
//! where `s` is the plant's true state, `o` the device's reading of it in the same tick
//! ([`sensed_episode`]: the readings firmware-sim's loop makes), `z` the task's latent from its
//! demos. The set also holds every demo state read perfectly (`o = s`), so the student keeps the
//! teacher's action on clean readings. Round `r` of `rounds`: the student (round 0: the teacher)
//! runs `episodes` episodes on each meta-train task through the sensors; their `(s, o)` pairs
//! join the set; then `steps / rounds` Adam steps on it. The context encoder is the teacher's:
//! the device is taught demos recorded on the host.

use candle_core::{Device, Tensor};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim::{DemoDataset, EnvConfig};

use crate::data::{Sensing, sensed_episode};
use crate::error::{Error, Result};
use crate::model::MetaPolicy;
use crate::optim::{Adam, AdamConfig};

/// How the distillation runs.
#[derive(Debug, Clone, PartialEq)]
pub struct DistillConfig {
    /// What the device reads (the `[sensing]` section; its `fraction` is unused: every closed
    /// loop reads through it, and the demos' clean rows keep the truth in the set).
    pub sensing: Sensing,
    /// Further sensors the same student must act through: round `r` reads through
    /// `[sensing, also...][r % n]`, so one blob serves each (empty: `sensing` alone).
    pub also: Vec<Sensing>,
    /// Adam steps in all (at least 1).
    pub steps: usize,
    /// DAgger rounds: closed loops of the current student, then `steps / rounds` steps.
    pub rounds: usize,
    /// Episodes per meta-train task and round.
    pub episodes: usize,
    /// Adam's learning rate at the first step, decaying linearly to zero at the last.
    pub lr: f32,
    /// Rows per step.
    pub batch: usize,
    /// Seed of the episodes' resets and sensors, and of the batch sampling.
    pub seed: u64,
    /// The plant the closed loops run on.
    pub env: EnvConfig,
}

impl DistillConfig {
    /// `steps` steps through `sensing` on `env`, with the defaults: 4 rounds of one episode per
    /// task, Adam from 3e-4, 256 rows per step, seed 0.
    pub fn new(sensing: Sensing, steps: usize, env: EnvConfig) -> Self {
        Self {
            sensing,
            also: Vec::new(),
            steps,
            rounds: 4,
            episodes: 1,
            lr: 3e-4,
            batch: 256,
            seed: 0,
            env,
        }
    }

    fn check(&self) -> Result<()> {
        self.sensing.check()?;
        for s in &self.also {
            s.check()?;
        }
        let counts = [
            ("steps", self.steps),
            ("rounds", self.rounds),
            ("episodes", self.episodes),
            ("batch", self.batch),
        ];
        if let Some((name, _)) = counts.iter().find(|(_, n)| *n == 0) {
            return Err(Error::Config(format!(
                "distillation through the sensors: {name} must be at least 1"
            )));
        }
        if !(self.lr.is_finite() && self.lr > 0.0) || self.rounds > self.steps {
            return Err(Error::Config(format!(
                "distillation through the sensors: learning rate {} must be > 0 and rounds {} \
                 at most the steps {}",
                self.lr, self.rounds, self.steps
            )));
        }
        Ok(())
    }
}

impl DistillConfig {
    /// The sensor round `round`'s closed loops read through.
    fn round_sensing(&self, round: usize) -> &Sensing {
        match round % (1 + self.also.len()) {
            0 => &self.sensing,
            k => &self.also[k - 1],
        }
    }
}

/// What the distillation did.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DistillReport {
    /// Rows in the final set: demo states read perfectly, and closed-loop ticks.
    pub rows: usize,
    /// Closed-loop ticks among them.
    pub closed_loop_ticks: usize,
    /// Adam steps taken.
    pub steps: usize,
    /// Mean `|a_student(o) - a_teacher(s)|` over the final set's rows and action dimensions,
    /// of the teacher itself (the sensors' cost to the policy as trained) ...
    pub action_gap_before: f32,
    /// ... and of the student.
    pub action_gap_after: f32,
}

/// The growing set: student inputs `[norm(o), z]` and teacher inputs `[norm(s), z]`, row by row.
#[derive(Default)]
struct Pairs {
    student: Vec<f32>,
    teacher: Vec<f32>,
}

impl Pairs {
    fn push(&mut self, mp: &MetaPolicy, read: &[f32], truth: &[f32], z: &[f32]) {
        mp.norm.push(read, &mut self.student);
        self.student.extend_from_slice(z);
        mp.norm.push(truth, &mut self.teacher);
        self.teacher.extend_from_slice(z);
    }

    fn tensors(&self, width: usize) -> Result<(Tensor, Tensor)> {
        let n = self.student.len() / width;
        Ok((
            Tensor::from_slice(&self.student, (n, width), &Device::Cpu)?,
            Tensor::from_slice(&self.teacher, (n, width), &Device::Cpu)?,
        ))
    }
}

/// `mp` with its actor distilled to act through `cfg.sensing` as it acts on true states (the
/// module doc); `demos` are meta-train demos of its family and plant (each task's latent and
/// the clean rows). Deterministic for a seed and thread count.
pub fn distill_through_sensing(
    mp: &MetaPolicy,
    demos: &DemoDataset,
    cfg: &DistillConfig,
) -> Result<(MetaPolicy, DistillReport)> {
    cfg.check()?;
    crate::io::export::check_demos_fit(mp, demos, "the distillation's demos")?;
    let (od, act_dim) = (demos.obs_dim, mp.policy.act_dim());
    let width = od + mp.z_dim();
    let latents = demos
        .tasks
        .iter()
        .map(|td| mp.latent(&td.trajectories.iter().collect::<Vec<_>>()))
        .collect::<Result<Vec<_>>>()?;
    let mut pairs = Pairs::default();
    for (td, z) in demos.tasks.iter().zip(&latents) {
        for s in td
            .trajectories
            .iter()
            .flat_map(|tr| tr.obs.chunks_exact(od))
        {
            pairs.push(mp, s, s, z);
        }
    }
    let clean = pairs.student.len() / width;
    let student = MetaPolicy {
        policy: mp.policy.deep_copy()?,
        ..mp.clone()
    };
    let teacher = mp.policy.net();
    let mean = |net: &crate::model::Mlp, x: &Tensor| -> Result<Tensor> {
        Ok(net.forward(x)?.narrow(1, 0, act_dim)?.tanh()?)
    };
    let mut adam = Adam::new(
        student.policy.net().vars().to_vec(),
        AdamConfig::with_lr(cfg.lr),
    );
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let mut env = sim::make_env(mp.family, cfg.env)?;
    let mut step = 0;
    for round in 0..cfg.rounds {
        // Round 0's loop is the teacher's own: the student starts as its copy.
        closed_loops(
            &student,
            demos,
            &latents,
            env.as_mut(),
            cfg,
            round,
            &mut pairs,
        )?;
        let (x, t) = pairs.tensors(width)?;
        let target = mean(teacher, &t)?.detach();
        let n = x.dim(0)?;
        let until = cfg.steps * (round + 1) / cfg.rounds;
        while step < until {
            step += 1;
            let idx: Vec<u32> = (0..cfg.batch)
                .map(|_| rng.random_range(0..n as u32))
                .collect();
            let idx = Tensor::from_vec(idx, cfg.batch, &Device::Cpu)?;
            let a = mean(student.policy.net(), &x.index_select(&idx, 0)?)?;
            // L = E || tanh(mu_student(o, z)) - tanh(mu_teacher(s, z)) ||^2
            let loss = (a - target.index_select(&idx, 0)?)?.sqr()?.mean_all()?;
            adam.set_lr(cfg.lr * (1.0 - (step - 1) as f32 / cfg.steps as f32));
            adam.backward_step(&loss)?;
        }
    }
    let (x, t) = pairs.tensors(width)?;
    let target = mean(teacher, &t)?;
    let gap = |net: &crate::model::Mlp| -> Result<f32> {
        let d = (mean(net, &x)? - &target)?.abs()?.mean_all()?;
        Ok(d.to_scalar::<f32>()?)
    };
    let report = DistillReport {
        rows: x.dim(0)?,
        closed_loop_ticks: x.dim(0)? - clean,
        steps: cfg.steps,
        action_gap_before: gap(teacher)?,
        action_gap_after: gap(student.policy.net())?,
    };
    Ok((student, report))
}

/// `cfg.episodes` deterministic episodes of `student` on each meta-train task through the
/// sensors, every tick's (reading, truth) pair into `pairs`. Round `round` picks the reset
/// seeds (and with them the sensors' noise streams).
fn closed_loops(
    student: &MetaPolicy,
    demos: &DemoDataset,
    latents: &[Vec<f32>],
    env: &mut dyn sim::Environment,
    cfg: &DistillConfig,
    round: usize,
    pairs: &mut Pairs,
) -> Result<()> {
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    for (t, (td, z)) in demos.tasks.iter().zip(latents).enumerate() {
        for e in 0..cfg.episodes {
            let episode = (round * demos.tasks.len() + t) * cfg.episodes + e;
            let seed = cfg
                .seed
                .wrapping_mul(sim::seeds::TRAINING_SEED_STRIDE)
                .wrapping_add(episode as u64);
            // The policy's input of the tick, kept for the step's pair (one buffer, reused).
            let read = std::cell::RefCell::new(Vec::new());
            sensed_episode(
                env,
                &td.task,
                seed,
                Some(cfg.round_sensing(round)),
                &mut |o, a| {
                    let mut r = read.borrow_mut();
                    r.clear();
                    r.extend_from_slice(o);
                    a.copy_from_slice(&student.act(o, z, true, &mut rng)?);
                    Ok(())
                },
                &mut |st| {
                    // Position-only sensing names the reading itself (a tick without an
                    // estimate acts safely and reads as the truth); else the policy's input.
                    match st.sensed {
                        Some((o, _)) => pairs.push(student, o, st.obs, z),
                        None => pairs.push(student, &read.borrow(), st.obs, z),
                    }
                    Ok(())
                },
            )?;
        }
    }
    Ok(())
}
