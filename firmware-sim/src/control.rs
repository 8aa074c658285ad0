//! The fixed-rate control loop: a simulated clock ticks at the control rate; each tick reads
//! the sensors, runs the policy, and writes the actuators, while the plant (a sim family)
//! steps its physics in between.

use std::time::Instant;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use sim::{Environment, EpisodeMetric, Task};

use crate::config::adc_lsb;
pub use crate::config::{LoopConfig, LoopError};
use crate::device::Controller;
use crate::estimation::SensorPath;

/// What the loop saw and did at one tick. Deterministic: no wall-clock values in here.
#[derive(Debug, Clone, PartialEq)]
pub struct TickRecord {
    /// Tick index.
    pub tick: usize,
    /// Simulated time at the tick, seconds.
    pub time: f32,
    /// The observation the policy received: the sensor reading (full sensing) or the
    /// estimator's output (position-only sensing).
    pub sensed: Vec<f32>,
    /// Position-only sensing: the raw readings (the measured entries, in observation order)
    /// the estimator got. Empty with full sensing.
    pub measured: Vec<f32>,
    /// The action the policy computed this tick.
    pub computed: Vec<f32>,
    /// The action the actuators applied this tick.
    pub applied: Vec<f32>,
    /// Reward summed over the plant steps of this tick.
    pub reward: f32,
    /// The family's metric sample after the tick (distance, |v - v*|, reward).
    pub metric_sample: f32,
    /// Forward velocity of the robot after the tick (0 for point-goal).
    pub forward_velocity: f32,
    /// The plant's true observation after the tick (what ideal sensors would read).
    pub plant_obs: Vec<f32>,
    /// A non-finite reading or output was replaced by the safe action, or (position-only
    /// sensing) the estimator rejected a NaN or out-of-range reading.
    pub fault: bool,
    /// The computation overran its budget.
    pub overrun: bool,
}

/// The outcome of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunReport {
    /// Every tick.
    pub records: Vec<TickRecord>,
    /// The family's metric over the run.
    pub metric: f32,
    /// Ticks whose compute time exceeded the budget.
    pub overruns: usize,
    /// Ticks with a non-finite reading or output.
    pub faults: usize,
    /// Compute time of each tick's `act`, host nanoseconds (not deterministic; kept apart).
    pub compute_ns: Vec<u64>,
    /// Plant steps per tick.
    pub steps_per_tick: usize,
    /// The task run.
    pub task: Task,
}

impl RunReport {
    /// (min, median, p99, max) compute time in nanoseconds.
    pub fn compute_percentiles(&self) -> (u64, u64, u64, u64) {
        let mut v = self.compute_ns.clone();
        v.sort_unstable();
        if v.is_empty() {
            return (0, 0, 0, 0);
        }
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        (v[0], at(0.5), at(0.99), v[v.len() - 1])
    }
}

fn quantise(x: f32, bits: u8, range: f32) -> f32 {
    let lsb = adc_lsb(bits, range);
    ((x.clamp(-range, range) + range) / lsb).round() * lsb - range
}

/// One sensor reading of the true value `x`: Gaussian noise, then the ADC.
fn sense(x: f32, config: &LoopConfig, noise: &Normal<f32>, rng: &mut ChaCha8Rng) -> f32 {
    let mut v = x + if config.noise_std > 0.0 {
        noise.sample(rng)
    } else {
        0.0
    };
    if let Some(bits) = config.adc_bits {
        v = quantise(v, bits, config.adc_range);
    }
    v
}

/// What computes each tick's action: the controller in this process, or a device behind a
/// serial port ([`crate::serial::RemoteDevice`]). The loop around it (sensors, actuators,
/// plant, trace) is the same for both, so a run over a port can be compared tick by tick with
/// one in process.
pub trait Brain {
    /// The action sent when nothing better is known.
    fn safe_action(&self, action: &mut [f32]);

    /// Called at the start of tick `tick`, before the sensors are read: a real-time brain
    /// waits here for the tick's wall-clock time. Default: nothing.
    fn start_tick(&mut self, _tick: usize) {}

    /// The action for the observation `sensed` at `tick`, written into `action`.
    fn act(
        &mut self,
        tick: usize,
        sensed: &[f32],
        action: &mut [f32],
    ) -> Result<Outcome, LoopError>;
}

/// How one tick's computation went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Outcome {
    /// A non-finite reading or output was replaced by the safe action.
    pub fault: bool,
    /// Whether the action came too late to apply: `None` lets the loop judge by its compute
    /// budget (in process); a remote device's deadline is judged by the brain itself.
    pub late: Option<bool>,
}

impl Brain for Controller<'_, '_> {
    fn safe_action(&self, action: &mut [f32]) {
        Controller::safe_action(self, action);
    }

    fn act(
        &mut self,
        _tick: usize,
        sensed: &[f32],
        action: &mut [f32],
    ) -> Result<Outcome, LoopError> {
        let fault = Controller::act(self, sensed, action)?.is_err();
        Ok(Outcome { fault, late: None })
    }
}

/// Runs `controller` against `plant` on `task`.
pub fn run(
    controller: &mut dyn Brain,
    plant: &mut dyn Environment,
    task: &Task,
    config: &LoopConfig,
) -> Result<RunReport, LoopError> {
    let plant_rate = 1.0 / plant.control_dt();
    let rate = config.rate_hz.unwrap_or(plant_rate);
    let ratio = plant_rate / rate;
    let steps_per_tick = ratio.round() as usize;
    if steps_per_tick == 0 || (ratio - steps_per_tick as f32).abs() > 1e-3 {
        return Err(LoopError::Rate {
            rate,
            plant: plant_rate,
        });
    }
    let most = plant.horizon().div_ceil(steps_per_tick);
    let ticks = config.ticks.unwrap_or(most);
    if ticks == 0 || ticks > most {
        return Err(LoopError::Ticks { ticks, most });
    }
    if let Some(bits) = config.adc_bits
        && !((1..=24).contains(&bits) && config.adc_range.is_finite() && config.adc_range > 0.0)
    {
        return Err(LoopError::Adc {
            bits,
            range: config.adc_range,
        });
    }
    let mut noise_rng = ChaCha8Rng::seed_from_u64(config.seed ^ 0x005E_ED0F_5E45);
    if !(config.noise_std.is_finite() && config.noise_std >= 0.0) {
        return Err(LoopError::Noise(config.noise_std));
    }
    let noise =
        Normal::new(0.0f32, config.noise_std).map_err(|_| LoopError::Noise(config.noise_std))?;
    let act_dim = plant.act_dim();
    let mut metric = EpisodeMetric::new(task.family());
    let mut safe = vec![0.0; act_dim];
    controller.safe_action(&mut safe);
    let mut last_applied = safe.clone();
    let mut pending = safe.clone();
    let mut applied = safe.clone();
    let mut sensed = plant.reset(task, config.seed)?.to_vec();
    let mut estimated = SensorPath::new(config, task.family(), rate)?;
    let (mut records, mut compute_ns) = (Vec::with_capacity(ticks), Vec::with_capacity(ticks));
    let (mut overruns, mut faults) = (0, 0);
    let mut computed = vec![0.0; act_dim];
    let mut plant_done = false;
    for tick in 0..ticks {
        if plant_done {
            break;
        }
        controller.start_tick(tick);
        // Sensors.
        if let Some(path) = estimated.as_mut() {
            // Position-only sensing: the device gets the measured entries and estimates the
            // observation the policy needs; a bad reading never reaches it.
            path.read(plant.observation(), |x| {
                sense(x, config, &noise, &mut noise_rng)
            });
            if config.nan_ticks.contains(&tick) {
                path.readings[0] = f32::NAN;
            }
        } else {
            for (s, &x) in sensed.iter_mut().zip(plant.observation()) {
                *s = sense(x, config, &noise, &mut noise_rng);
            }
            if config.nan_ticks.contains(&tick) {
                sensed[0] = f32::NAN;
            }
        }
        // Compute.
        let start = Instant::now();
        let (outcome, sensor_fault) = match estimated.as_mut() {
            None => (controller.act(tick, &sensed, &mut computed)?, false),
            Some(path) => match path.estimate(&mut sensed)? {
                Some(rejected) => (controller.act(tick, &sensed, &mut computed)?, rejected),
                None => {
                    // No estimate yet: the safe action.
                    computed.copy_from_slice(&safe);
                    let on_time = Outcome {
                        fault: false,
                        late: None,
                    };
                    (on_time, true)
                }
            },
        };
        let ns = start.elapsed().as_nanos() as u64;
        compute_ns.push(ns);
        let fault = outcome.fault || sensor_fault;
        faults += fault as usize;
        let overrun = outcome.late.unwrap_or(ns as f64 > config.budget_us * 1e3);
        overruns += overrun as usize;
        // Actuators. A late action is dropped (hold the last one); with latency the bus
        // delivers the previous tick's action. Fixed buffers: no allocation per tick here.
        let fresh = if overrun { &last_applied } else { &computed };
        if config.latency {
            applied.copy_from_slice(&pending);
            pending.copy_from_slice(fresh);
        } else {
            applied.copy_from_slice(fresh);
        }
        let mut reward = 0.0;
        let mut info = sim::StepInfo::default();
        for _ in 0..steps_per_tick {
            let t = plant.step(&applied)?;
            reward += t.reward;
            info = t.info;
            metric.record(&t.info);
            if t.done {
                plant_done = true;
                break;
            }
        }
        // The trace is the host's view of the run, not part of the device.
        records.push(TickRecord {
            tick,
            time: tick as f32 / rate,
            sensed: sensed.clone(),
            measured: estimated
                .as_ref()
                .map_or_else(Vec::new, |p| p.readings.clone()),
            computed: computed.clone(),
            applied: applied.clone(),
            reward,
            metric_sample: info.metric_sample,
            forward_velocity: info.forward_velocity,
            plant_obs: plant.observation().to_vec(),
            fault,
            overrun,
        });
        last_applied.copy_from_slice(&applied);
    }
    Ok(RunReport {
        records,
        metric: metric.value(),
        overruns,
        faults,
        compute_ns,
        steps_per_tick,
        task: *task,
    })
}
