//! Position-only sensing on the device: `sim`'s [`PositionSensing`] (the one implementation the
//! learners train through too), configured from the loop's settings.

use infer_core::EstimatorConfig;
use sim::{EstimatorTuning, Family, PositionSensing};

pub use crate::config::Sensing;
use crate::config::{LoopConfig, LoopError};

// The device's largest observation fits the filter bank.
const _: () = assert!(sim::ESTIMATOR_CAPACITY >= crate::link::MAX_DIM);

/// The filter's default acceleration std for `family` (units/s^2): its spec's
/// ([`sim::FamilySpec::estimator_accel_std`], from the sweep in `docs/ESTIMATOR.md`).
pub fn default_accel_std(family: Family) -> f32 {
    family.spec().estimator_accel_std
}

/// The filter configuration the loop uses for `family` at `rate_hz` under `config`'s sensor
/// model ([`sim::estimator_config`]); `None` with full sensing.
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
    let tuning = EstimatorTuning {
        accel_std,
        meas_std,
    };
    Some(sim::estimator_config(
        family,
        &config.sensor_model(),
        rate_hz,
        tuning,
    ))
}

/// The device side of position-only sensing; `None` with full sensing.
pub(crate) fn sensor_path(
    config: &LoopConfig,
    family: Family,
    rate_hz: f32,
) -> Result<Option<PositionSensing>, LoopError> {
    let Some(filter) = estimator_config(config, family, rate_hz) else {
        return Ok(None);
    };
    Ok(Some(PositionSensing::new(family, filter)?))
}
