//! The loop's configuration, its errors and what the sensors deliver: the settings both the
//! control loop ([`crate::control`]) and the on-device estimation ([`crate::estimation`])
//! read, kept below both so that neither imports the other's.

use std::fmt;
use std::str::FromStr;

use crate::device::DeviceError;

/// Sensor, actuator and timing effects of the loop.
#[derive(Debug, Clone, PartialEq)]
pub struct LoopConfig {
    /// Control rate in Hz; `None` uses the plant's own rate (1 / control dt). Must divide the
    /// plant rate: each tick holds its action for `plant rate / rate` plant steps.
    pub rate_hz: Option<f32>,
    /// Ticks to run; `None` runs one episode of the plant.
    pub ticks: Option<usize>,
    /// Std of Gaussian sensor noise added to every observation component.
    pub noise_std: f32,
    /// ADC resolution in bits (e.g. 12); `None` for ideal sensors.
    pub adc_bits: Option<u8>,
    /// ADC full scale: readings are clipped to +-this before quantisation.
    pub adc_range: f32,
    /// Apply each action one tick late (the actuator bus is one tick behind).
    pub latency: bool,
    /// Compute budget per tick in microseconds; a late action is discarded and the last
    /// applied one held.
    pub budget_us: f64,
    /// Seed of the plant's reset noise and the sensor noise.
    pub seed: u64,
    /// Ticks whose sensor reading is replaced by NaN (fault injection).
    pub nan_ticks: Vec<usize>,
    /// What the sensors deliver: the whole observation, or positions only with an
    /// on-device estimator rebuilding the rest.
    pub sensing: Sensing,
}

impl LoopConfig {
    /// The sensors' model: the noise and the ADC every reading goes through (`sim`'s, the one
    /// the learners train through).
    pub fn sensor_model(&self) -> sim::SensorModel {
        sim::SensorModel {
            noise_std: self.noise_std,
            adc_bits: self.adc_bits,
            adc_range: self.adc_range,
        }
    }
}

impl Default for LoopConfig {
    fn default() -> Self {
        Self {
            rate_hz: None,
            ticks: None,
            noise_std: 0.0,
            adc_bits: None,
            adc_range: 10.0,
            latency: false,
            budget_us: 1000.0,
            seed: 0,
            nan_ticks: Vec::new(),
            sensing: Sensing::Full,
        }
    }
}

/// Errors of the loop itself.
#[derive(Debug, thiserror::Error)]
pub enum LoopError {
    /// The device cannot run.
    #[error(transparent)]
    Device(#[from] DeviceError),
    /// The plant refused something (a bug if it happens: actions are always finite).
    #[error("plant: {0}")]
    Plant(#[from] sim::SimError),
    /// The serial link to a device in another process failed for good.
    #[error("link: {0}")]
    Link(#[from] crate::link::LinkError),
    /// The estimator cannot be built for this plant and configuration.
    #[error("estimator: {0}")]
    Estimator(#[from] infer_core::Error),
    /// The sensor noise std is negative or not finite.
    #[error("sensor noise std must be finite and >= 0, got {0}")]
    Noise(f32),
    /// The ADC settings cannot quantise (the library check behind the CLI's).
    #[error("ADC: {bits} bits over +-{range} (bits must be 1 to 24, the range finite and > 0)")]
    Adc {
        /// Requested resolution.
        bits: u8,
        /// Requested full scale.
        range: f32,
    },
    /// More ticks were asked than one plant episode lasts (it would stop early, silently).
    #[error(
        "{ticks} ticks asked but a plant episode lasts {most} ticks at this rate; pass --ticks 1..={most} or a longer --horizon"
    )]
    Ticks {
        /// Requested ticks.
        ticks: usize,
        /// Ticks in one episode.
        most: usize,
    },
    /// The requested rate is not a divisor of the plant's rate.
    #[error("control rate {rate} Hz must divide the plant rate {plant} Hz")]
    Rate {
        /// Requested rate.
        rate: f32,
        /// The plant's rate.
        plant: f32,
    },
}

/// What the device's sensors deliver.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Sensing {
    /// Every observation entry (positions and velocities): today's default.
    #[default]
    Full,
    /// Positions, angles and directly measured entries only; the device estimates the
    /// velocities with a constant-velocity Kalman filter per position.
    Positions {
        /// Std of the unmodelled acceleration (filter tuning); `None`: the family's
        /// [`default_accel_std`](crate::estimation::default_accel_std).
        accel_std: Option<f32>,
        /// Std of a reading's noise as the filter assumes it; `None`: the loop's sensor
        /// noise and ADC step, `sqrt(noise^2 + lsb^2 / 12)`.
        meas_std: Option<f32>,
    },
}

impl Sensing {
    /// Position-only sensing with the default tuning.
    pub const POSITIONS: Sensing = Sensing::Positions {
        accel_std: None,
        meas_std: None,
    };
}

impl fmt::Display for Sensing {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Sensing::Full => "full",
            Sensing::Positions { .. } => "positions",
        })
    }
}

impl FromStr for Sensing {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "full" => Ok(Sensing::Full),
            "positions" => Ok(Sensing::POSITIONS),
            other => Err(format!(
                "unknown sensing {other:?}; expected full or positions"
            )),
        }
    }
}
