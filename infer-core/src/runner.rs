//! The two stateful runners: [`ContextEncoder`] turns a demo into `z`, [`Policy`] turns
//! `(obs, z)` into an action. Both own fixed-size buffers of capacity `W` (the widest layer
//! they can run), so nothing allocates and memory does not grow with the context length.

use crate::error::{Error, Result};
use crate::format::{LayerRecord, ModelKind};
use crate::kernels;
use crate::model::Model;

/// The buffers an MLP runs in, `W` wide: its input is written to `a`, the layers ping-pong
/// between `a` and `b` (with `q` for the int8 activations) and [`Scratch::run`] returns the
/// one holding the output.
#[derive(Debug)]
struct Scratch<const W: usize> {
    a: [f32; W],
    b: [f32; W],
    q: [u8; W],
}

impl<const W: usize> Scratch<W> {
    const fn new() -> Self {
        Self {
            a: [0.0; W],
            b: [0.0; W],
            q: [0; W],
        }
    }

    /// Runs `layers` on the input in `a`; the buffer holding the output.
    fn run(&mut self, layers: &[LayerRecord<'_>]) -> &[f32] {
        let in_b = kernels::mlp(layers, &mut self.a, &mut self.b, &mut self.q);
        if in_b { &self.b } else { &self.a }
    }
}

fn check_capacity<const W: usize>(model: &Model<'_>) -> Result<()> {
    let needed = model.max_width();
    if needed > W {
        return Err(Error::CapacityExceeded {
            needed,
            capacity: W,
        });
    }
    Ok(())
}

fn check_input(input: &'static str, x: &[f32], expected: usize) -> Result<()> {
    if x.len() != expected {
        return Err(Error::WrongLength {
            input,
            expected,
            found: x.len(),
        });
    }
    if x.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFiniteInput { input });
    }
    Ok(())
}

/// Writes `(x - mean) / std` for each observation component into `out`.
fn normalise(model: &Model<'_>, x: &[f32], out: &mut [f32]) {
    let (mean, std) = (model.obs_mean(), model.obs_std());
    for (i, (o, &v)) in out.iter_mut().zip(x).enumerate() {
        *o = (v - mean.get(i)) / std.get(i);
    }
}

/// The conditioned policy: `action = tanh(pi([norm(obs), z])) * scale + offset`.
///
/// ```
/// # use infer_core::{Model, Policy};
/// # fn run(blob: &[u8], obs: &[f32], z: &[f32]) -> Result<(), Box<dyn core::error::Error>> {
/// let model = Model::from_bytes(blob)?;
/// let mut policy = Policy::<64>::new(&model)?;
/// let mut action = [0.0f32; 6];
/// policy.act(obs, z, &mut action)?;
/// # Ok(()) }
/// ```
#[derive(Debug)]
pub struct Policy<'m, 'a, const W: usize> {
    model: &'m Model<'a>,
    scratch: Scratch<W>,
}

impl<'m, 'a, const W: usize> Policy<'m, 'a, W> {
    /// A policy runner for `model`; fails if a layer is wider than `W`.
    pub fn new(model: &'m Model<'a>) -> Result<Self> {
        check_capacity::<W>(model)?;
        Ok(Self {
            model,
            scratch: Scratch::new(),
        })
    }

    /// The action used when inference cannot be trusted: the centre of the action range
    /// (`offset`), which for the usual symmetric range is zero torque/force.
    pub fn safe_action(&self, action: &mut [f32]) {
        for (i, a) in action
            .iter_mut()
            .enumerate()
            .take(self.model.act_offset().len())
        {
            *a = self.model.act_offset().get(i);
        }
    }

    /// Computes the deterministic action for `obs` under task latent `z`.
    ///
    /// On a non-finite input or output, writes [`safe_action`](Self::safe_action) and returns
    /// the error, so a caller that ignores it still never sends NaN to an actuator.
    pub fn act(&mut self, obs: &[f32], z: &[f32], action: &mut [f32]) -> Result<()> {
        let h = *self.model.header();
        let (obs_dim, z_dim, act_dim) = (h.obs_dim as usize, h.z_dim as usize, h.act_dim as usize);
        if action.len() != act_dim {
            return Err(Error::WrongLength {
                input: "action",
                expected: act_dim,
                found: action.len(),
            });
        }
        if let Err(e) = check_input("obs", obs, obs_dim).and_then(|()| check_input("z", z, z_dim)) {
            self.safe_action(action);
            return Err(e);
        }
        normalise(self.model, obs, &mut self.scratch.a[..obs_dim]);
        self.scratch.a[obs_dim..obs_dim + z_dim].copy_from_slice(z);
        let mean = self.scratch.run(&self.model.payload.policy);
        let (scale, offset) = (self.model.act_scale(), self.model.act_offset());
        for (i, a) in action.iter_mut().enumerate() {
            *a = libm::tanhf(mean[i]) * scale.get(i) + offset.get(i);
        }
        if action.iter().any(|a| !a.is_finite()) {
            self.safe_action(action);
            return Err(Error::NonFiniteOutput);
        }
        Ok(())
    }
}

/// Streaming, permutation-invariant context encoder.
///
/// Each pushed transition goes through the per-transition MLP to `r`; `r` is averaged over
/// the steps of a trajectory and the averages are summed over trajectories; the head maps
/// that sum to the posterior mean of `z`. Only two running sums are kept, so memory is
/// constant however long the demo is.
#[derive(Debug)]
pub struct ContextEncoder<'m, 'a, const W: usize> {
    model: &'m Model<'a>,
    scratch: Scratch<W>,
    trajectory_sum: [f32; W],
    trajectory_steps: u32,
    context_sum: [f32; W],
    trajectories: u32,
}

impl<'m, 'a, const W: usize> ContextEncoder<'m, 'a, W> {
    /// An empty encoder for `model`; fails if a layer is wider than `W`.
    pub fn new(model: &'m Model<'a>) -> Result<Self> {
        check_capacity::<W>(model)?;
        Ok(Self {
            model,
            scratch: Scratch::new(),
            trajectory_sum: [0.0; W],
            trajectory_steps: 0,
            context_sum: [0.0; W],
            trajectories: 0,
        })
    }

    /// Forgets the whole context (to teach a new task).
    pub fn reset(&mut self) {
        self.trajectory_sum = [0.0; W];
        self.trajectory_steps = 0;
        self.context_sum = [0.0; W];
        self.trajectories = 0;
    }

    /// Completed trajectories so far.
    pub fn trajectories(&self) -> u32 {
        self.trajectories
    }

    /// Steps pushed into the open trajectory.
    pub fn open_steps(&self) -> u32 {
        self.trajectory_steps
    }

    /// Adds one transition of the current trajectory. State-only models ignore `action`
    /// (pass `&[]`). A transition with a wrong length or a non-finite value is refused and
    /// leaves the encoder unchanged.
    pub fn push(&mut self, obs: &[f32], action: &[f32], next_obs: &[f32]) -> Result<()> {
        let h = *self.model.header();
        let (obs_dim, act_dim) = (h.obs_dim as usize, h.act_dim as usize);
        check_input("obs", obs, obs_dim)?;
        check_input("next_obs", next_obs, obs_dim)?;
        let x = &mut self.scratch.a;
        normalise(self.model, obs, &mut x[..obs_dim]);
        let mut at = obs_dim;
        if h.kind == ModelKind::StateAction {
            check_input("action", action, act_dim)?;
            x[at..at + act_dim].copy_from_slice(action);
            at += act_dim;
        }
        normalise(self.model, next_obs, &mut x[at..at + obs_dim]);
        let r = self.scratch.run(&self.model.payload.encoder);
        let r_dim = h.r_dim as usize;
        for (s, &v) in self.trajectory_sum[..r_dim].iter_mut().zip(&r[..r_dim]) {
            *s += v;
        }
        self.trajectory_steps += 1;
        Ok(())
    }

    /// Closes the current trajectory: its mean `r` joins the context sum. Closing an empty
    /// trajectory does nothing.
    pub fn end_trajectory(&mut self) {
        if self.trajectory_steps == 0 {
            return;
        }
        let r_dim = self.model.header().r_dim as usize;
        let n = self.trajectory_steps as f32;
        for (c, t) in self.context_sum[..r_dim]
            .iter_mut()
            .zip(&mut self.trajectory_sum[..r_dim])
        {
            *c += *t / n;
            *t = 0.0;
        }
        self.trajectory_steps = 0;
        self.trajectories += 1;
    }

    /// Writes the posterior mean of `z` for the context so far into `z`. An open trajectory
    /// counts as if it had been closed (without closing it).
    pub fn latent(&mut self, z: &mut [f32]) -> Result<()> {
        let h = *self.model.header();
        let (r_dim, z_dim) = (h.r_dim as usize, h.z_dim as usize);
        if z.len() != z_dim {
            return Err(Error::WrongLength {
                input: "z",
                expected: z_dim,
                found: z.len(),
            });
        }
        if self.trajectories == 0 && self.trajectory_steps == 0 {
            return Err(Error::EmptyContext);
        }
        let n = self.trajectory_steps as f32;
        for i in 0..r_dim {
            let open = if self.trajectory_steps > 0 {
                self.trajectory_sum[i] / n
            } else {
                0.0
            };
            self.scratch.a[i] = self.context_sum[i] + open;
        }
        let out = self.scratch.run(&self.model.payload.z_head);
        z.copy_from_slice(&out[..z_dim]);
        if z.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFiniteOutput);
        }
        Ok(())
    }
}
