//! Position-only sensing: the device's sensors deliver the plant's measured entries (positions,
//! angles, directly measured values; see [`sim::Family::obs_components`]) and infer-core's
//! [`Estimator`] rebuilds the observation the policy was trained on.

use infer_core::{Channel, Estimator, EstimatorConfig};
use sim::{Family, ObsComponent};

pub use crate::config::Sensing;
use crate::config::{LoopConfig, LoopError};
use crate::link::MAX_DIM;

/// The filter's default acceleration std for `family` (units/s^2): its spec's
/// ([`sim::FamilySpec::estimator_accel_std`], from the sweep in `docs/ESTIMATOR.md`).
pub fn default_accel_std(family: Family) -> f32 {
    family.spec().estimator_accel_std
}

/// The estimator's channel for a family's observation component.
pub fn channel(component: ObsComponent) -> Channel {
    match component {
        ObsComponent::Position => Channel::Position,
        ObsComponent::Angle => Channel::Angle,
        ObsComponent::Rate { of, scale } => Channel::Rate { of, scale },
        ObsComponent::Direct => Channel::Direct,
    }
}

/// The filter configuration the loop uses for `family` at `rate_hz` under `config`'s sensor
/// model. A reading at or beyond the sensor's full scale (`adc_range`) is out of range.
pub fn estimator_config(
    config: &LoopConfig,
    family: Family,
    rate_hz: f32,
) -> Option<EstimatorConfig> {
    let Sensing::Positions {
        accel_std,
        meas_std,
    } = config.sensing
    else {
        return None;
    };
    let lsb = config.sensor_model().lsb().unwrap_or(0.0);
    Some(EstimatorConfig {
        dt: 1.0 / rate_hz,
        accel_std: accel_std.unwrap_or_else(|| default_accel_std(family)),
        meas_std: meas_std
            .unwrap_or_else(|| (config.noise_std * config.noise_std + lsb * lsb / 12.0).sqrt()),
        limit: config.adc_range,
        initial_rate_std: 1.0,
    })
}

/// The device side of position-only sensing: its reading buffer and its estimator.
pub(crate) struct SensorPath {
    /// This tick's readings: the measured entries, in observation order.
    pub readings: Vec<f32>,
    measured: Vec<usize>,
    estimator: Estimator<MAX_DIM>,
}

impl SensorPath {
    /// `None` with full sensing.
    pub fn new(
        config: &LoopConfig,
        family: Family,
        rate_hz: f32,
    ) -> Result<Option<Self>, LoopError> {
        let Some(filter) = estimator_config(config, family, rate_hz) else {
            return Ok(None);
        };
        let components = family.obs_components();
        let channels: Vec<Channel> = components.iter().copied().map(channel).collect();
        let estimator = Estimator::new(&channels, filter)?;
        let measured: Vec<usize> = (0..components.len())
            .filter(|&i| components[i].is_measured())
            .collect();
        Ok(Some(Self {
            readings: vec![0.0; measured.len()],
            measured,
            estimator,
        }))
    }

    /// Reads the measured entries of the plant's true observation through `sense`.
    pub fn read(&mut self, truth: &[f32], mut sense: impl FnMut(f32) -> f32) {
        for (reading, &i) in self.readings.iter_mut().zip(&self.measured) {
            *reading = sense(truth[i]);
        }
    }

    /// Runs the estimator on this tick's readings into `obs`. `Some(fault)` when `obs` holds
    /// an estimate (`fault`: a reading was rejected), `None` when there is none yet.
    pub fn estimate(&mut self, obs: &mut [f32]) -> Result<Option<bool>, LoopError> {
        match self.estimator.step(&self.readings, obs) {
            Ok(report) => Ok(Some(report.rejected > 0)),
            Err(infer_core::Error::NotReady { .. }) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }
}
