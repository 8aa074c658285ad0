//! Training through the device's senses (issue 73): a learner's `[sensing]` section, the
//! device's sensor model (`sim::SensorModel`, the one firmware-sim's loop reads its plant
//! through) applied to what the policy reads while it trains. The discriminator, the critics
//! and the context encoder read the states as recorded: the device is taught demos recorded on
//! the host, and only the policy runs on it.

use rand::Rng;
use serde::{Deserialize, Serialize};
use sim::{Environment, SensorModel, Task};

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
        Ok(())
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
