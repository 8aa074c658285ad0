//! The fixed-rate control loop: a simulated clock ticks at the control rate; each tick reads
//! the sensors, runs the policy, and writes the actuators, while the plant (a sim family)
//! steps its physics in between.

use std::time::Instant;

use sim::{Environment, EpisodeMetric, PositionSensing, Sensor, SensorModelError, Task};

pub use crate::config::{LoopConfig, LoopError};
use crate::device::Controller;
use crate::estimation::sensor_path;

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

/// The loop's timing: the control rate, plant steps per tick, and ticks to run.
struct Timing {
    rate: f32,
    steps_per_tick: usize,
    ticks: usize,
}

impl Timing {
    /// Checks the configured rate against the plant's (a whole number of plant steps per
    /// tick) and the tick count against the episode.
    fn of(plant: &dyn Environment, config: &LoopConfig) -> Result<Self, LoopError> {
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
        Ok(Self {
            rate,
            steps_per_tick,
            ticks,
        })
    }
}

/// The sensors between the plant and the brain: noise and the ADC on every reading (`sim`'s
/// sensor model, the one training reads through), and with position-only sensing the device's
/// estimator.
struct Sensors<'c> {
    config: &'c LoopConfig,
    sensor: Sensor,
    estimated: Option<PositionSensing>,
}

impl<'c> Sensors<'c> {
    fn new(config: &'c LoopConfig, task: &Task, rate: f32) -> Result<Self, LoopError> {
        let sensor = Sensor::new(config.sensor_model(), config.seed).map_err(|e| match e {
            SensorModelError::Adc { bits, range } => LoopError::Adc { bits, range },
            _ => LoopError::Noise(config.noise_std),
        })?;
        Ok(Self {
            config,
            sensor,
            estimated: sensor_path(config, task.family(), rate)?,
        })
    }

    /// Reads the plant's true observation at `tick`: into `sensed` with full sensing, into
    /// the estimator's readings otherwise (a configured NaN tick corrupts the first reading).
    fn read(&mut self, tick: usize, truth: &[f32], sensed: &mut [f32]) {
        let nan = self.config.nan_ticks.contains(&tick);
        let sensor = &mut self.sensor;
        match self.estimated.as_mut() {
            Some(path) => {
                path.read(truth, |x| sensor.read(x));
                if nan {
                    path.readings[0] = f32::NAN;
                }
            }
            None => {
                sensor.read_all(truth, sensed);
                if nan {
                    sensed[0] = f32::NAN;
                }
            }
        }
    }

    /// The brain's action for this tick into `computed`, and whether a sensor faulted. With
    /// position-only sensing and no estimate yet, the safe action.
    fn decide(
        &mut self,
        brain: &mut dyn Brain,
        tick: usize,
        sensed: &mut [f32],
        computed: &mut [f32],
        safe: &[f32],
    ) -> Result<(Outcome, bool), LoopError> {
        let Some(path) = self.estimated.as_mut() else {
            return Ok((brain.act(tick, sensed, computed)?, false));
        };
        match path.estimate(sensed)? {
            Some(rejected) => Ok((brain.act(tick, sensed, computed)?, rejected)),
            None => {
                computed.copy_from_slice(safe);
                let on_time = Outcome {
                    fault: false,
                    late: None,
                };
                Ok((on_time, true))
            }
        }
    }

    /// The raw readings the estimator got (empty with full sensing).
    fn measured(&self) -> Vec<f32> {
        self.estimated
            .as_ref()
            .map_or_else(Vec::new, |p| p.readings.clone())
    }
}

/// The actuators: the action applied this tick, given the fresh one (or, when it came late,
/// the last applied); with latency the bus delivers the previous tick's action. Fixed
/// buffers: no allocation per tick.
struct Actuators {
    latency: bool,
    pending: Vec<f32>,
    applied: Vec<f32>,
    last_applied: Vec<f32>,
}

impl Actuators {
    fn new(latency: bool, safe: &[f32]) -> Self {
        Self {
            latency,
            pending: safe.to_vec(),
            applied: safe.to_vec(),
            last_applied: safe.to_vec(),
        }
    }

    fn apply(&mut self, computed: &[f32], late: bool) {
        let fresh = if late { &self.last_applied } else { computed };
        if self.latency {
            self.applied.copy_from_slice(&self.pending);
            self.pending.copy_from_slice(fresh);
        } else {
            self.applied.copy_from_slice(fresh);
        }
    }
}

/// Steps the plant `steps` times with `action`: the tick's summed reward, the last step's
/// info, and whether the episode ended.
fn step_plant(
    plant: &mut dyn Environment,
    action: &[f32],
    steps: usize,
    metric: &mut EpisodeMetric,
) -> Result<(f32, sim::StepInfo, bool), LoopError> {
    let mut reward = 0.0;
    let mut info = sim::StepInfo::default();
    for _ in 0..steps {
        let t = plant.step(action)?;
        reward += t.reward;
        info = t.info;
        metric.record(&t.info);
        if t.done {
            return Ok((reward, info, true));
        }
    }
    Ok((reward, info, false))
}

/// Runs `controller` against `plant` on `task`: each tick reads the sensors, computes the
/// action (timed against the budget), applies it, steps the plant and records the tick.
pub fn run(
    controller: &mut dyn Brain,
    plant: &mut dyn Environment,
    task: &Task,
    config: &LoopConfig,
) -> Result<RunReport, LoopError> {
    let timing = Timing::of(plant, config)?;
    let mut sensors = Sensors::new(config, task, timing.rate)?;
    let mut metric = EpisodeMetric::new(task.family());
    let mut safe = vec![0.0; plant.act_dim()];
    controller.safe_action(&mut safe);
    let mut actuators = Actuators::new(config.latency, &safe);
    let mut sensed = plant.reset(task, config.seed)?.to_vec();
    let mut computed = vec![0.0; safe.len()];
    let (mut records, mut compute_ns) = (
        Vec::with_capacity(timing.ticks),
        Vec::with_capacity(timing.ticks),
    );
    let (mut overruns, mut faults) = (0, 0);
    for tick in 0..timing.ticks {
        controller.start_tick(tick);
        sensors.read(tick, plant.observation(), &mut sensed);
        let start = Instant::now();
        let (outcome, sensor_fault) =
            sensors.decide(controller, tick, &mut sensed, &mut computed, &safe)?;
        let ns = start.elapsed().as_nanos() as u64;
        compute_ns.push(ns);
        let fault = outcome.fault || sensor_fault;
        faults += fault as usize;
        let overrun = outcome.late.unwrap_or(ns as f64 > config.budget_us * 1e3);
        overruns += overrun as usize;
        actuators.apply(&computed, overrun);
        let (reward, info, done) = step_plant(
            plant,
            &actuators.applied,
            timing.steps_per_tick,
            &mut metric,
        )?;
        // The trace is the host's view of the run, not part of the device.
        records.push(TickRecord {
            tick,
            time: tick as f32 / timing.rate,
            sensed: sensed.clone(),
            measured: sensors.measured(),
            computed: computed.clone(),
            applied: actuators.applied.clone(),
            reward,
            metric_sample: info.metric_sample,
            forward_velocity: info.forward_velocity,
            plant_obs: plant.observation().to_vec(),
            fault,
            overrun,
        });
        actuators.last_applied.copy_from_slice(&actuators.applied);
        if done {
            break;
        }
    }
    Ok(RunReport {
        records,
        metric: metric.value(),
        overruns,
        faults,
        compute_ns,
        steps_per_tick: timing.steps_per_tick,
        task: *task,
    })
}
