//! Position-only sensing, one implementation for training and the device: the sensors deliver
//! the plant's measured entries (positions, angles, directly measured values; see
//! [`ObsComponent`]), each read through the sensor model, and infer-core's [`Estimator`]
//! rebuilds the observation the policy reads. firmware-sim's loop runs it between its plant
//! and its brain (`--sensing positions`); the learners' `[sensing]` with `positions = true`
//! runs it between their training rollouts and their policy.

use infer_core::{Estimator, EstimatorConfig};

use crate::family::Family;
use crate::sensor::SensorModel;

/// The most observation entries the estimator holds (the device link's largest observation).
pub const ESTIMATOR_CAPACITY: usize = 64;

/// How the on-board filter is tuned; `None` fields take the defaults.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EstimatorTuning {
    /// Std of the unmodelled acceleration (units/s^2); `None`: the family's
    /// ([`crate::FamilySpec::estimator_accel_std`], from the sweep in `docs/ESTIMATOR.md`).
    pub accel_std: Option<f32>,
    /// Std of a reading's noise as the filter assumes it; `None`: the sensor model's noise
    /// and ADC step, `sqrt(noise^2 + lsb^2 / 12)`.
    pub meas_std: Option<f32>,
}

/// The filter configuration for `family` at `rate_hz` behind sensors of `model`. A reading at
/// or beyond the sensor's full scale (`adc_range`) is out of range.
pub fn estimator_config(
    family: Family,
    model: &SensorModel,
    rate_hz: f32,
    tuning: EstimatorTuning,
) -> EstimatorConfig {
    let lsb = model.lsb().unwrap_or(0.0);
    let noise = model.noise_std;
    EstimatorConfig {
        dt: 1.0 / rate_hz,
        accel_std: tuning
            .accel_std
            .unwrap_or_else(|| family.spec().estimator_accel_std),
        meas_std: tuning
            .meas_std
            .unwrap_or_else(|| (noise * noise + lsb * lsb / 12.0).sqrt()),
        limit: model.adc_range,
        initial_rate_std: 1.0,
    }
}

/// The device side of position-only sensing: this tick's readings and the estimator.
#[derive(Debug, Clone)]
pub struct PositionSensing {
    /// This tick's readings: the measured entries, in observation order.
    pub readings: Vec<f32>,
    measured: Vec<usize>,
    estimator: Estimator<ESTIMATOR_CAPACITY>,
}

impl PositionSensing {
    /// The filter bank for `family`'s observation under `config`.
    pub fn new(family: Family, config: EstimatorConfig) -> Result<Self, infer_core::Error> {
        let components = family.obs_components();
        let estimator = Estimator::new(components, config)?;
        let measured: Vec<usize> = (0..components.len())
            .filter(|&i| components[i].is_measured())
            .collect();
        Ok(Self {
            readings: vec![0.0; measured.len()],
            measured,
            estimator,
        })
    }

    /// Reads the measured entries of the plant's true observation through `sense`, in
    /// observation order (the order the sensor's noise stream is drawn in).
    pub fn read(&mut self, truth: &[f32], mut sense: impl FnMut(f32) -> f32) {
        for (reading, &i) in self.readings.iter_mut().zip(&self.measured) {
            *reading = sense(truth[i]);
        }
    }

    /// Runs the estimator on this tick's readings into `obs`. `Ok(Some(fault))` when `obs`
    /// holds an estimate (`fault`: a reading was rejected), `Ok(None)` when there is none yet
    /// (a channel has had no valid reading).
    pub fn estimate(&mut self, obs: &mut [f32]) -> Result<Option<bool>, infer_core::Error> {
        match self.estimator.step(&self.readings, obs) {
            Ok(report) => Ok(Some(report.rejected > 0)),
            Err(infer_core::Error::NotReady { .. }) => Ok(None),
            Err(e) => Err(e),
        }
    }
}
