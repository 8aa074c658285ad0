//! Training through the device's senses (issue 73): a learner's `[sensing]` section, the
//! device's sensor model (`sim::SensorModel`, the one firmware-sim's loop reads its plant
//! through) applied to what the policy reads while it trains. The discriminator, the critics
//! and the context encoder read the states as recorded: the device is taught demos recorded on
//! the host, and only the policy runs on it.

use std::cell::RefCell;

use rand::Rng;
use serde::{Deserialize, Serialize};
use sim::{Environment, PositionSensing, SensorModel, Task};

use super::rollout::{ActFn, Episode, Step, run_episode};
use crate::error::{Error, Result};

/// A learner's `[sensing]` section: the sensor model and the share of training rows read
/// through it. Preset: `docs/configs/sensing-noise01-adc12.toml`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensing {
    /// Std of the Gaussian noise on every reading, in the observation's own units (source: the
    /// device table's noise column, 0.01).
    #[serde(default)]
    pub noise_std: f32,
    /// ADC resolution in bits, 1 to 24; absent: an ideal converter (source: the device
    /// table's 12-bit column).
    #[serde(default)]
    pub adc_bits: Option<u8>,
    /// ADC full scale: readings are clipped to +-this before quantisation (firmware-sim's
    /// `--adc-range`, default 10).
    #[serde(default = "default_range")]
    pub adc_range: f32,
    /// Share of a training batch's rows whose states are read through the sensors, the others
    /// as recorded, in (0, 1]; default 1. Below 1 both the clean and the sensed states stay in
    /// the policy's training distribution (the first robust Meta-BC, trained on sensed states
    /// only, was much worse on clean ones: docs/DEVICE.md). Rollouts always read through it.
    #[serde(default = "default_fraction")]
    pub fraction: f32,
    /// Position-only sensing (firmware-sim's `--sensing positions`; default false): the
    /// sensors deliver the measured entries (positions, angles, direct values) through the
    /// model above and the device's estimator rebuilds the velocities (`sim::PositionSensing`,
    /// the loop's own). The estimate depends on the episode's history, so it cannot be
    /// redrawn for a batch row: the replay keeps the states as the policy read them and the
    /// actor's sensed rows are those. SMILe only; its cloning rows read the demos as recorded
    /// (a subsampled demo keeps one tick in k; the filter needs every tick).
    #[serde(default)]
    pub positions: bool,
    /// With `positions`: the filter's acceleration std (units/s^2); absent: the family's, as
    /// firmware-sim's `--accel-std`.
    #[serde(default)]
    pub accel_std: Option<f32>,
    /// With `positions`: the reading noise std the filter assumes; absent: the model's noise
    /// and ADC step, as firmware-sim's `--meas-std`.
    #[serde(default)]
    pub meas_std: Option<f32>,
}

impl Default for Sensing {
    /// An ideal sensor delivering every entry, all rows through it.
    fn default() -> Self {
        Self {
            noise_std: 0.0,
            adc_bits: None,
            adc_range: default_range(),
            fraction: default_fraction(),
            positions: false,
            accel_std: None,
            meas_std: None,
        }
    }
}

fn default_range() -> f32 {
    SensorModel::default().adc_range
}

fn default_fraction() -> f32 {
    1.0
}

impl Sensing {
    /// The device's sensor model this section names.
    pub fn model(&self) -> SensorModel {
        SensorModel {
            noise_std: self.noise_std,
            adc_bits: self.adc_bits,
            adc_range: self.adc_range,
        }
    }

    /// Checks the model and the fraction, naming the section's key.
    pub fn check(&self) -> Result<()> {
        self.model()
            .check()
            .map_err(|e| Error::Config(format!("[sensing]: {e}")))?;
        if !(self.fraction > 0.0 && self.fraction <= 1.0) {
            return Err(Error::Config(format!(
                "[sensing] fraction = {}: expected a share in (0, 1]",
                self.fraction
            )));
        }
        // The filter needs accel_std > 0; meas_std may be 0 (it floors the variance).
        for (key, value, zero_ok) in [
            ("accel_std", self.accel_std, false),
            ("meas_std", self.meas_std, true),
        ] {
            let Some(v) = value else { continue };
            if !self.positions {
                return Err(Error::Config(format!(
                    "[sensing] {key} tunes the estimator of position-only sensing: it needs \
                     positions = true"
                )));
            }
            if !(v.is_finite() && (v > 0.0 || zero_ok && v == 0.0)) {
                let bound = if zero_ok { ">= 0" } else { "> 0" };
                return Err(Error::Config(format!(
                    "[sensing] {key} = {v}: expected a finite std {bound}"
                )));
            }
        }
        Ok(())
    }

    /// The estimator's tuning (position-only sensing).
    pub fn tuning(&self) -> sim::EstimatorTuning {
        sim::EstimatorTuning {
            accel_std: self.accel_std,
            meas_std: self.meas_std,
        }
    }

    /// Reads the `dim`-wide rows of `rows` through the sensor model in place, each row with
    /// probability `fraction` (no draw for the choice when it is 1), every random draw from
    /// `rng` in row order.
    pub fn read_rows(&self, rows: &mut [f32], dim: usize, rng: &mut impl Rng) {
        let model = self.model();
        for row in rows.chunks_exact_mut(dim) {
            if self.picks(rng) {
                for x in row {
                    *x = model.read(*x, rng);
                }
            }
        }
    }

    /// Whether the next row is read through the sensors: with probability `fraction`, and
    /// no draw when it is 1.
    fn picks(&self, rng: &mut impl Rng) -> bool {
        self.fraction >= 1.0 || rng.random::<f32>() < self.fraction
    }

    /// Position-only sensing's [`Self::read_row_pairs`]: each row pair of `a` and `b` is
    /// replaced with probability `fraction` by the policy's views of it, `va` and `vb` (kept by
    /// the replay when the episode ran).
    pub fn take_views(
        &self,
        a: &mut [f32],
        b: &mut [f32],
        va: &[f32],
        vb: &[f32],
        dim: usize,
        rng: &mut impl Rng,
    ) {
        let rows = a.chunks_exact_mut(dim).zip(b.chunks_exact_mut(dim));
        let views = va.chunks_exact(dim).zip(vb.chunks_exact(dim));
        for ((ra, rb), (wa, wb)) in rows.zip(views) {
            if self.picks(rng) {
                ra.copy_from_slice(wa);
                rb.copy_from_slice(wb);
            }
        }
    }

    /// [`Self::read_rows`] on two row sets of one batch (states and next states), where a row
    /// is read in both or in neither: the actor sees one device, not two.
    pub fn read_row_pairs(&self, a: &mut [f32], b: &mut [f32], dim: usize, rng: &mut impl Rng) {
        let model = self.model();
        for (ra, rb) in a.chunks_exact_mut(dim).zip(b.chunks_exact_mut(dim)) {
            if self.picks(rng) {
                for x in ra.iter_mut().chain(rb.iter_mut()) {
                    *x = model.read(*x, rng);
                }
            }
        }
    }
}

/// [`run_episode`] with the policy reading the plant through the device's sensors: `act`
/// gets each observation as `sim::Sensor` reads it, its noise stream seeded with the episode's
/// reset seed (as firmware-sim's loop seeds it with the run's), while `on_step` sees the true
/// transitions. Without `sensing`, `run_episode` itself.
pub fn sensed_episode(
    env: &mut dyn Environment,
    task: &Task,
    seed: u64,
    sensing: Option<&Sensing>,
    act: &mut ActFn<'_>,
    on_step: &mut dyn FnMut(&Step<'_>) -> Result<()>,
) -> Result<Episode> {
    let Some(sensing) = sensing else {
        return run_episode(env, task, seed, act, on_step);
    };
    if sensing.positions {
        return estimated_episode(env, task, seed, sensing, act, on_step);
    }
    let mut sensor = sim::Sensor::new(sensing.model(), seed)
        .map_err(|e| Error::Config(format!("[sensing]: {e}")))?;
    let mut sensed = vec![0.0f32; env.obs_dim()];
    run_episode(
        env,
        task,
        seed,
        &mut |o, a| {
            sensor.read_all(o, &mut sensed);
            act(&sensed, a)
        },
        on_step,
    )
}

/// What [`estimated_episode`] keeps between the policy's calls and the steps.
struct Readings {
    sensor: sim::Sensor,
    path: PositionSensing,
    /// The state as the policy reads it this tick, and whether the estimator had one.
    now: Vec<f32>,
    now_ready: bool,
    /// The next state's reading, made when the step landed; `next_ready` is `Some` until the
    /// next tick takes it. The two buffers swap: nothing is allocated per tick.
    next: Vec<f32>,
    next_ready: Option<bool>,
}

/// One tick of the device's senses on the true state `truth`: the measured entries through
/// the sensor, the estimator into `view`. Without an estimate yet (a channel had no valid
/// reading) the estimator writes nothing, the view stays the truth, and `false`: the device
/// holds its safe action.
fn sense(
    sensor: &mut sim::Sensor,
    path: &mut PositionSensing,
    truth: &[f32],
    view: &mut Vec<f32>,
) -> Result<bool> {
    path.read(truth, |x| sensor.read(x));
    view.clear();
    view.extend_from_slice(truth);
    let ready = path
        .estimate(view)
        .map_err(|e| Error::Config(format!("[sensing] positions: {e}")))?;
    Ok(ready.is_some())
}

/// [`sensed_episode`] with position-only sensing: each tick the sensor reads the measured
/// entries and the device's estimator (`sim::PositionSensing`, firmware-sim's loop's own)
/// rebuilds the state the policy acts on; without an estimate the action is the safe one
/// (zeros, the action range's centre), as the device's. The next state is read as soon as
/// the step lands (the device's next tick, in the same draw order), so `on_step` gets both
/// views in [`Step::sensed`].
fn estimated_episode(
    env: &mut dyn Environment,
    task: &Task,
    seed: u64,
    sensing: &Sensing,
    act: &mut ActFn<'_>,
    on_step: &mut dyn FnMut(&Step<'_>) -> Result<()>,
) -> Result<Episode> {
    let family = task.family();
    let filter = sim::estimator_config(
        family,
        &sensing.model(),
        1.0 / env.control_dt(),
        sensing.tuning(),
    );
    let readings = RefCell::new(Readings {
        sensor: sim::Sensor::new(sensing.model(), seed)
            .map_err(|e| Error::Config(format!("[sensing]: {e}")))?,
        path: PositionSensing::new(family, filter)
            .map_err(|e| Error::Config(format!("[sensing] positions: {e}")))?,
        now: Vec::new(),
        now_ready: false,
        next: Vec::new(),
        next_ready: None,
    });
    run_episode(
        env,
        task,
        seed,
        &mut |o, a| {
            let r = &mut *readings.borrow_mut();
            match r.next_ready.take() {
                Some(ready) => {
                    std::mem::swap(&mut r.now, &mut r.next);
                    r.now_ready = ready;
                }
                None => r.now_ready = sense(&mut r.sensor, &mut r.path, o, &mut r.now)?,
            }
            if r.now_ready {
                act(&r.now, a)
            } else {
                a.fill(0.0);
                Ok(())
            }
        },
        &mut |st| {
            let r = &mut *readings.borrow_mut();
            let ready = sense(&mut r.sensor, &mut r.path, st.next_obs, &mut r.next)?;
            let out = on_step(&Step {
                sensed: Some((&r.now, &r.next)),
                ..*st
            });
            r.next_ready = Some(ready);
            out
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn preset(fraction: f32) -> Sensing {
        Sensing {
            noise_std: 0.01,
            adc_bits: Some(12),
            adc_range: 10.0,
            fraction,
            ..Sensing::default()
        }
    }

    #[test]
    fn a_fraction_reads_that_share_of_rows_and_pairs_move_together() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let (mut a, mut b) = (vec![0.3f32; 2000 * 3], vec![0.3f32; 2000 * 3]);
        preset(0.25).read_row_pairs(&mut a, &mut b, 3, &mut rng);
        let touched = |v: &[f32]| v.chunks(3).map(|r| r.iter().any(|&x| x != 0.3)).collect();
        let (ta, tb): (Vec<bool>, Vec<bool>) = (touched(&a), touched(&b));
        assert_eq!(ta, tb);
        let share = ta.iter().filter(|&&t| t).count() as f32 / 2000.0;
        assert!((share - 0.25).abs() < 0.04, "{share}");
        let mut all = vec![0.3f32; 300];
        preset(1.0).read_rows(&mut all, 3, &mut rng);
        assert!(all.chunks(3).all(|r| r.iter().any(|&x| x != 0.3)));
    }

    #[test]
    fn bad_sections_are_refused_naming_the_key() {
        for bad in [preset(0.0), preset(1.5), preset(f32::NAN)] {
            let e = bad.check().unwrap_err().to_string();
            assert!(e.contains("fraction"), "{e}");
        }
        let noisy = Sensing {
            noise_std: -1.0,
            ..preset(1.0)
        };
        assert!(noisy.check().unwrap_err().to_string().contains("[sensing]"));
        // The first robust policy's section, without a fraction, still reads.
        let old: Sensing =
            toml::from_str("noise_std = 0.01\nadc_bits = 12\nadc_range = 10.0").expect("parses");
        assert_eq!(old, preset(1.0));
    }
}
