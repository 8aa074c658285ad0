//! The optimiser: Adam (Kingma & Ba 2015, no weight decay) whose per-parameter update is one
//! fused in-place pass over the parameter, both moments and the gradient (candle has no
//! in-place Adam; its `AdamW` allocates about eight temporaries per parameter per step).

use std::cell::RefCell;

use candle_core::{DType, Device, Tensor, Var};

use crate::error::Result;
use crate::model::{OnSlices, SliceUpdate, TensorLookup, check_shapes};

/// Hyper-parameters of [`Adam`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdamConfig {
    /// Learning rate.
    pub lr: f32,
    /// First-moment decay.
    pub beta1: f32,
    /// Second-moment decay.
    pub beta2: f32,
    /// Denominator epsilon (added after the square root, as PyTorch does).
    pub eps: f32,
}

impl AdamConfig {
    /// PyTorch's `torch.optim.Adam` defaults with the given learning rate.
    pub fn with_lr(lr: f32) -> Self {
        Self {
            lr,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
        }
    }
}

/// Adam without weight decay over a fixed list of variables. Moments are plain `Vec<f32>`s so
/// they can be checkpointed and restored exactly.
#[derive(Debug, Clone)]
pub struct Adam {
    cfg: AdamConfig,
    vars: Vec<Var>,
    m: Vec<Vec<f32>>,
    v: Vec<Vec<f32>>,
    t: u64,
}

/// The fused Adam update for one parameter; `m` and `v` are borrowed for the call.
struct AdamStep<'a> {
    m: RefCell<&'a mut [f32]>,
    v: RefCell<&'a mut [f32]>,
    lr_t: f32,
    b1: f32,
    b2: f32,
    eps_t: f32,
}

impl SliceUpdate for AdamStep<'_> {
    const NAME: &'static str = "adam";

    fn apply(&self, p: &mut [f32], g: &[f32]) -> candle_core::Result<()> {
        let mut m = self.m.borrow_mut();
        let mut v = self.v.borrow_mut();
        if p.len() != g.len() || m.len() != p.len() {
            return Err(candle_core::Error::Msg("adam: length mismatch".into()));
        }
        let (b1, b2, c1, c2) = (self.b1, self.b2, 1.0 - self.b1, 1.0 - self.b2);
        let (lr_t, eps_t) = (self.lr_t, self.eps_t);
        let (m, v): (&mut [f32], &mut [f32]) = (&mut m, &mut v);
        let step = |p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32]| {
            for (((p, g), m), v) in p.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
                *m = b1 * *m + c1 * g;
                *v = b2 * *v + c2 * g * g;
                *p -= lr_t * *m / (v.sqrt() + eps_t);
            }
        };
        // Inside a learner pool a large parameter is updated in blocks that free threads
        // steal (every element's update is independent, so the result is the same bit for
        // bit): the discriminator's optimiser step follows the join of a SMILe pair, where
        // one thread would otherwise work alone.
        if crate::threads::in_pool() && p.len() >= PARALLEL_MIN_PARAMS {
            use rayon::prelude::*;
            let block = p.len().div_ceil(rayon::current_num_threads());
            p.par_chunks_mut(block)
                .zip(g.par_chunks(block))
                .zip(m.par_chunks_mut(block))
                .zip(v.par_chunks_mut(block))
                .for_each(|(((p, g), m), v)| step(p, g, m, v));
        } else {
            step(p, g, m, v);
        }
        Ok(())
    }
}

/// Parameters with fewer elements than this are updated on one thread (a block handed to
/// another core costs a few microseconds; 64k elements take about 30 us).
const PARALLEL_MIN_PARAMS: usize = 1 << 16;

impl Adam {
    /// A new optimiser for `vars` with zeroed moments.
    pub fn new(vars: Vec<Var>, cfg: AdamConfig) -> Self {
        let m: Vec<Vec<f32>> = vars.iter().map(|v| vec![0.0; v.elem_count()]).collect();
        let v = m.clone();
        Self {
            cfg,
            vars,
            m,
            v,
            t: 0,
        }
    }

    /// Sets the learning rate of the next steps (a schedule).
    pub fn set_lr(&mut self, lr: f32) {
        self.cfg.lr = lr;
    }

    /// Number of steps taken.
    pub fn steps(&self) -> u64 {
        self.t
    }

    /// One Adam step from the gradients of `loss` (runs `loss.backward()`).
    ///
    /// `theta <- theta - lr * m_hat / (sqrt(v_hat) + eps)`, with the bias corrections folded into
    /// the step size and epsilon (algebraically identical to PyTorch's formulation).
    pub fn backward_step(&mut self, loss: &Tensor) -> Result<()> {
        let grads = loss.backward()?;
        self.step(&grads)
    }

    /// One Adam step from already computed gradients (several optimisers can share one
    /// `backward()`, e.g. SMILe's discriminator and encoder with different betas).
    pub fn step(&mut self, grads: &candle_core::backprop::GradStore) -> Result<()> {
        self.t += 1;
        let t = self.t as i32;
        let bc1 = 1.0 - self.cfg.beta1.powi(t);
        let bc2 = 1.0 - self.cfg.beta2.powi(t);
        // lr * (m / bc1) / (sqrt(v / bc2) + eps) = (lr sqrt(bc2) / bc1) m / (sqrt(v) + eps sqrt(bc2))
        let lr_t = self.cfg.lr * bc2.sqrt() / bc1;
        let eps_t = self.cfg.eps * bc2.sqrt();
        for (i, var) in self.vars.iter().enumerate() {
            let Some(g) = grads.get(var.as_tensor()) else {
                // The loss does not depend on this variable: skip it, as PyTorch does for a
                // parameter whose `.grad` is None.
                continue;
            };
            let g = g.contiguous()?;
            let op = OnSlices(AdamStep {
                m: RefCell::new(&mut self.m[i]),
                v: RefCell::new(&mut self.v[i]),
                lr_t,
                b1: self.cfg.beta1,
                b2: self.cfg.beta2,
                eps_t,
            });
            var.as_tensor().inplace_op2(&g, &op)?;
        }
        Ok(())
    }

    /// The moments as tensors `(m_i, v_i)` shaped like the variables, and the step count.
    pub fn state(&self) -> Result<(Vec<Tensor>, Vec<Tensor>, u64)> {
        let to_t = |xs: &[Vec<f32>]| -> Result<Vec<Tensor>> {
            xs.iter()
                .zip(&self.vars)
                .map(|(x, var)| Ok(Tensor::from_slice(x, var.shape(), &Device::Cpu)?))
                .collect()
        };
        Ok((to_t(&self.m)?, to_t(&self.v)?, self.t))
    }

    /// Appends the moments to a checkpoint's tensors as `{name}.m.{i}` and `{name}.v.{i}`
    /// (every learner's optimisers are saved this one way) and returns the step count, which
    /// the checkpoint keeps with its counters.
    pub fn save_into(&self, name: &str, out: &mut Vec<(String, Tensor)>) -> Result<u64> {
        let (m, v, t) = self.state()?;
        for (i, x) in m.into_iter().enumerate() {
            out.push((format!("{name}.m.{i}"), x));
        }
        for (i, x) in v.into_iter().enumerate() {
            out.push((format!("{name}.v.{i}"), x));
        }
        Ok(t)
    }

    /// Restores what [`Adam::save_into`] wrote under `name` (`get` looks a checkpoint tensor up
    /// by name) with the step count `t`; shapes must match this optimiser's variables.
    pub fn load_from(&mut self, name: &str, get: TensorLookup, t: u64) -> Result<()> {
        let n = self.vars.len();
        let many = |moment: &str| -> Result<Vec<Tensor>> {
            (0..n)
                .map(|i| get(&format!("{name}.{moment}.{i}")))
                .collect()
        };
        self.set_state(&many("m")?, &many("v")?, t)
    }

    /// Restore moments and step count saved by [`Adam::state`].
    pub fn set_state(&mut self, m: &[Tensor], v: &[Tensor], t: u64) -> Result<()> {
        let vars: Vec<Tensor> = self.vars.iter().map(|v| v.as_tensor().clone()).collect();
        check_shapes(&vars, m)?;
        check_shapes(&vars, v)?;
        let flat = |xs: &[Tensor]| -> Result<Vec<Vec<f32>>> {
            xs.iter()
                .map(|x| Ok(x.to_dtype(DType::F32)?.flatten_all()?.to_vec1::<f32>()?))
                .collect()
        };
        self.m = flat(m)?;
        self.v = flat(v)?;
        self.t = t;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adam_saves_and_loads_itself_exactly() {
        let dev = &Device::Cpu;
        let vars: Vec<Var> = [vec![0.5f32, -1.0, 2.0], vec![3.0f32]]
            .iter()
            .map(|x| Var::from_tensor(&Tensor::new(x.as_slice(), dev).unwrap()).unwrap())
            .collect();
        let mut a = Adam::new(vars.clone(), AdamConfig::with_lr(0.1));
        for _ in 0..3 {
            let loss = (vars[0].as_tensor().sqr().unwrap().sum_all().unwrap()
                + vars[1].as_tensor().sum_all().unwrap())
            .unwrap();
            a.backward_step(&loss).unwrap();
        }
        let mut ts = Vec::new();
        let t = a.save_into("opt", &mut ts).unwrap();
        assert_eq!(t, 3);
        let names: Vec<&str> = ts.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["opt.m.0", "opt.m.1", "opt.v.0", "opt.v.1"]);
        let get = |n: &str| -> Result<Tensor> {
            ts.iter()
                .find(|(k, _)| k == n)
                .map(|(_, t)| t.clone())
                .ok_or_else(|| crate::error::Error::Shape(n.into()))
        };
        let mut b = Adam::new(vars.clone(), AdamConfig::with_lr(0.1));
        b.load_from("opt", &get, t).unwrap();
        assert_eq!(
            (b.m.clone(), b.v.clone(), b.t),
            (a.m.clone(), a.v.clone(), a.t)
        );
        // A checkpoint of other shapes is refused, not half loaded.
        let other = Var::from_tensor(&Tensor::new(&[1.0f32, 2.0], dev).unwrap()).unwrap();
        let mut c = Adam::new(vec![other, vars[1].clone()], AdamConfig::with_lr(0.1));
        assert!(c.load_from("opt", &get, t).is_err());
        assert!(b.load_from("missing", &get, t).is_err());
    }

    #[test]
    fn adam_matches_reference_formula() {
        // One scalar parameter, loss = 0.5 * p^2 -> grad = p. Compare with textbook Adam.
        let var = Var::from_tensor(&Tensor::new(&[1.5f32], &Device::Cpu).unwrap()).unwrap();
        let cfg = AdamConfig::with_lr(0.1);
        let mut opt = Adam::new(vec![var.clone()], cfg);
        let (mut p, mut m, mut v) = (1.5f64, 0.0f64, 0.0f64);
        for t in 1..=5 {
            let loss = (var.as_tensor().sqr().unwrap() * 0.5)
                .unwrap()
                .sum_all()
                .unwrap();
            opt.backward_step(&loss).unwrap();
            let g = p;
            m = 0.9 * m + 0.1 * g;
            v = 0.999 * v + 0.001 * g * g;
            let mh = m / (1.0 - 0.9f64.powi(t));
            let vh = v / (1.0 - 0.999f64.powi(t));
            p -= 0.1 * mh / (vh.sqrt() + 1e-8);
            let got = var.as_tensor().to_vec1::<f32>().unwrap()[0] as f64;
            assert!((got - p).abs() < 1e-5, "step {t}: {got} vs {p}");
        }
    }
}
