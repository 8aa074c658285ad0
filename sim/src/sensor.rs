//! The device's sensor model, one implementation for training and the device: each reading is
//! the true value plus Gaussian noise, then an ADC (clipped to its full scale, rounded to its
//! levels). firmware-sim's loop reads its plant through it; the learners read their training
//! observations through it (a `[sensing]` section in their configs), so the two cannot drift.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// Salt of a sensor's noise stream: a sensor seeded with a run's seed draws a stream apart
/// from the plant's reset noise drawn from the same seed.
const NOISE_SALT: u64 = 0x005E_ED0F_5E45;

/// What a sensor does to a reading.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorModel {
    /// Std of the Gaussian noise added to every reading (0: none).
    #[serde(default)]
    pub noise_std: f32,
    /// ADC resolution in bits, 1 to 24 (`None`: an ideal converter).
    #[serde(default)]
    pub adc_bits: Option<u8>,
    /// ADC full scale: readings are clipped to +-this before quantisation.
    #[serde(default = "default_range")]
    pub adc_range: f32,
}

fn default_range() -> f32 {
    10.0
}

impl Default for SensorModel {
    fn default() -> Self {
        Self {
            noise_std: 0.0,
            adc_bits: None,
            adc_range: default_range(),
        }
    }
}

/// A sensor model no reading can go through.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum SensorModelError {
    /// The noise std is negative or not finite.
    #[error("sensor noise std {0} is not a finite number >= 0")]
    Noise(f32),
    /// The ADC's bits or range cannot quantise.
    #[error("ADC of {bits} bits over +-{range}: expected 1 to 24 bits and a finite range > 0")]
    Adc {
        /// The bits given.
        bits: u8,
        /// The range given.
        range: f32,
    },
}

impl SensorModel {
    /// Checks the model can read.
    pub fn check(&self) -> Result<(), SensorModelError> {
        if !(self.noise_std.is_finite() && self.noise_std >= 0.0) {
            return Err(SensorModelError::Noise(self.noise_std));
        }
        if let Some(bits) = self.adc_bits
            && !((1..=24).contains(&bits) && self.adc_range.is_finite() && self.adc_range > 0.0)
        {
            return Err(SensorModelError::Adc {
                bits,
                range: self.adc_range,
            });
        }
        Ok(())
    }

    /// Whether readings are the true values.
    pub fn is_ideal(&self) -> bool {
        self.noise_std == 0.0 && self.adc_bits.is_none()
    }

    /// The ADC's step, if there is an ADC.
    pub fn lsb(&self) -> Option<f32> {
        self.adc_bits.map(|bits| adc_lsb(bits, self.adc_range))
    }

    /// The ADC's reading of `x` (no noise): clipped and rounded to the converter's levels.
    pub fn quantise(&self, x: f32) -> f32 {
        match self.adc_bits {
            Some(bits) => {
                let (lsb, range) = (adc_lsb(bits, self.adc_range), self.adc_range);
                ((x.clamp(-range, range) + range) / lsb).round() * lsb - range
            }
            None => x,
        }
    }

    /// One reading of the true value `x`: noise drawn from `rng` (none drawn without noise),
    /// then the ADC.
    pub fn read(&self, x: f32, rng: &mut impl Rng) -> f32 {
        let noisy = if self.noise_std > 0.0 {
            // Checked by `check`; a model that fails it reads without noise.
            let normal = Normal::new(0.0f32, self.noise_std).ok();
            x + normal.map_or(0.0, |n| n.sample(rng))
        } else {
            x
        };
        self.quantise(noisy)
    }
}

/// The step of a `bits`-bit converter over +-`range`.
pub fn adc_lsb(bits: u8, range: f32) -> f32 {
    let levels = ((1u32 << bits.min(24)) - 1) as f32;
    2.0 * range / levels
}

/// A sensor: a model and its own noise stream, seeded from a run's seed.
#[derive(Debug, Clone)]
pub struct Sensor {
    model: SensorModel,
    rng: ChaCha8Rng,
}

impl Sensor {
    /// A sensor reading through `model`, its noise stream seeded from `seed`.
    pub fn new(model: SensorModel, seed: u64) -> Result<Self, SensorModelError> {
        model.check()?;
        Ok(Self {
            model,
            rng: ChaCha8Rng::seed_from_u64(seed ^ NOISE_SALT),
        })
    }

    /// The model.
    pub fn model(&self) -> &SensorModel {
        &self.model
    }

    /// One reading of the true value `x`.
    pub fn read(&mut self, x: f32) -> f32 {
        self.model.read(x, &mut self.rng)
    }

    /// Reads every entry of `truth` into `out`, in order.
    pub fn read_all(&mut self, truth: &[f32], out: &mut [f32]) {
        for (o, &x) in out.iter_mut().zip(truth) {
            *o = self.read(x);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reading_is_noise_then_the_adc() {
        let model = SensorModel {
            noise_std: 0.01,
            adc_bits: Some(12),
            adc_range: 10.0,
        };
        let lsb = model.lsb().unwrap();
        assert!((lsb - 20.0 / 4095.0).abs() < 1e-9);
        let mut sensor = Sensor::new(model, 3).unwrap();
        let mut out = [0.0; 64];
        sensor.read_all(&[0.3; 64], &mut out);
        // Every reading lies on the converter's grid and near the truth; not all equal.
        for &r in &out {
            let k = (r + 10.0) / lsb;
            assert!(
                (k - k.round()).abs() < 1e-3 && (r - 0.3).abs() < 0.06,
                "{r}"
            );
        }
        assert!(out.iter().any(|&r| r != out[0]));
        assert_eq!(model.quantise(99.0), 10.0);
        let bad = SensorModel {
            adc_bits: Some(0),
            ..model
        };
        assert!(Sensor::new(bad, 0).is_err());
    }
}
