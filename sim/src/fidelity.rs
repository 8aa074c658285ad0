//! The plant-fidelity probe of `docs/FIDELITY.md`: the same measurements, with the same
//! action sequences, as its MuJoCo twin `docs/scripts/fidelity_mujoco.py` runs on Gymnasium's
//! XMLs, so a Rapier robot can be held against MuJoCo's (`sim/tests/fidelity.rs`).
//!
//! [`probe`] returns the JSON document both programs write (keys in FIDELITY.md);
//! `compare` scores one against the other within the band.

use std::f32::consts::{PI, TAU};
use std::str::FromStr;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde_json::{Value, json};

use crate::ant::{self, AntRobot, AntSpec};
use crate::planar::{self, PlanarRobot, RobotSpec, Scaling, Start};
use crate::rapier_plant::RapierRobot;
use crate::robots;

/// The robots the probe knows, each with a MuJoCo twin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Robot {
    /// HalfCheetah (`half_cheetah.xml`), the cheetah-vel plant.
    Cheetah,
    /// Walker2d (gym's `walker2d.xml`), the walker-dyn plant at its nominal dynamics.
    Walker,
    /// Ant (`ant.xml`), the plant of ant-goal and ant-linclass.
    Ant,
}

impl Robot {
    /// The name in the JSON and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Robot::Cheetah => "cheetah",
            Robot::Walker => "walker",
            Robot::Ant => "ant",
        }
    }
}

impl FromStr for Robot {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "cheetah" => Ok(Robot::Cheetah),
            "walker" => Ok(Robot::Walker),
            "ant" => Ok(Robot::Ant),
            other => Err(format!(
                "unknown robot `{other}` (expected cheetah, walker or ant)"
            )),
        }
    }
}

/// How much of the probe to run.
#[derive(Debug, Clone, Copy)]
pub struct ProbeConfig {
    /// Seeds of the statistical measurements (FIDELITY.md: 30).
    pub seeds: usize,
    /// Control steps of each open- and closed-loop rollout (FIDELITY.md: 200).
    pub steps: usize,
}

impl Default for ProbeConfig {
    fn default() -> Self {
        Self {
            seeds: 30,
            steps: 200,
        }
    }
}

/// The twin's action offset at step 0.
const NUDGE: f32 = 1e-3;
/// Noise levels of the closed-loop measurement.
const SIGMAS: [(&str, f32); 3] = [("0", 0.0), ("0.1", 0.1), ("0.3", 0.3)];
/// Seed offset of the closed loop's action noise (the MuJoCo script's too).
const NOISE_SEED_OFFSET: u64 = 1_000_000;

/// A robot as the probe drives it: actions in MuJoCo's joint order and coordinates, the
/// state vector of FIDELITY.md.
trait Plant {
    fn step(&mut self, action: &[f32]);
    /// The state vector s (velocities unclipped).
    fn state(&self) -> Vec<f32>;
    fn x(&self) -> f32;
    fn height(&self) -> f32;
    /// Planar: the pitch; ant: the tilt of its z axis from vertical.
    fn tilt(&self) -> f32;
    fn upside_down(&self) -> bool;
    /// Gymnasium's walker health test (true for the others).
    fn healthy(&self) -> bool;
    fn penetration(&self) -> f32;
}

/// What the probe needs to know of a robot beside its plant.
struct Layout {
    dt: f32,
    /// Joint ranges in MuJoCo's coordinates, joint order.
    ranges: Vec<[f32; 2]>,
    /// Index of joint 0's angle and velocity in the state vector.
    angle_at: usize,
    velocity_at: usize,
    /// The trot's period (s) and per-joint phases.
    period: f32,
    phases: Vec<f32>,
}

impl Layout {
    fn joints(&self) -> usize {
        self.ranges.len()
    }

    fn steps_per_second(&self, seconds: f32) -> usize {
        (seconds / self.dt).round() as usize
    }

    fn trot(&self, step: usize) -> Vec<f32> {
        let t = step as f32 * self.dt;
        self.phases
            .iter()
            .map(|phase| 0.6 * (TAU * t / self.period + phase).sin())
            .collect()
    }
}

struct PlanarPlant {
    robot: PlanarRobot,
    walker: bool,
}

impl Plant for PlanarPlant {
    fn step(&mut self, action: &[f32]) {
        let clipped: Vec<f32> = action.iter().map(|a| a.clamp(-1.0, 1.0)).collect();
        self.robot.step(&clipped);
    }
    fn state(&self) -> Vec<f32> {
        let mut obs = [0.0; planar::OBS_DIM];
        self.robot.observe(&mut obs, f32::INFINITY);
        obs.to_vec()
    }
    fn x(&self) -> f32 {
        self.robot.torso_pose().0
    }
    fn height(&self) -> f32 {
        self.robot.torso_pose().1
    }
    fn tilt(&self) -> f32 {
        self.robot.torso_pose().2
    }
    fn upside_down(&self) -> bool {
        self.tilt().abs() > PI / 2.0
    }
    fn healthy(&self) -> bool {
        if !self.walker {
            return true;
        }
        let (_, z, pitch) = self.robot.torso_pose();
        z > 0.8 && z < 2.0 && pitch.abs() < 1.0
    }
    fn penetration(&self) -> f32 {
        self.robot.ground_penetration()
    }
}

struct AntPlant {
    robot: AntRobot,
}

impl AntPlant {
    fn up_z(&self) -> f32 {
        let mut obs = [0.0; ant::OBS_DIM];
        self.robot.observe(&mut obs, f32::INFINITY);
        let q = &obs[ant::obs::QUATERNION..ant::obs::QUATERNION + 4];
        1.0 - 2.0 * (q[1] * q[1] + q[2] * q[2])
    }
}

impl Plant for AntPlant {
    fn step(&mut self, action: &[f32]) {
        let clipped: Vec<f32> = action.iter().map(|a| a.clamp(-1.0, 1.0)).collect();
        self.robot.step(&clipped);
    }
    fn state(&self) -> Vec<f32> {
        let mut obs = [0.0; ant::OBS_DIM];
        self.robot.observe(&mut obs, f32::INFINITY);
        obs[..ant::obs::XY].to_vec()
    }
    fn x(&self) -> f32 {
        self.robot.torso_position()[0]
    }
    fn height(&self) -> f32 {
        self.robot.torso_position()[2]
    }
    fn tilt(&self) -> f32 {
        self.up_z().clamp(-1.0, 1.0).acos()
    }
    fn upside_down(&self) -> bool {
        self.up_z() < 0.0
    }
    fn healthy(&self) -> bool {
        true
    }
    fn penetration(&self) -> f32 {
        self.robot.ground_penetration()
    }
}

/// A robot's specification, built into plants on demand.
enum Spec {
    Planar {
        spec: Box<RobotSpec>,
        walker: bool,
    },
    Ant(Box<AntSpec>),
    /// The same robot on the MuJoCo backend (Gymnasium's XML), driven as
    /// `docs/scripts/fidelity_mujoco.py` drives Python MuJoCo; its layout is the Rapier spec's
    /// (the same ranges, dt and trot).
    #[cfg(feature = "mujoco")]
    Mujoco {
        robot: Robot,
        layout_of: Box<Spec>,
    },
}

#[cfg(feature = "mujoco")]
mod on_mujoco;

impl Spec {
    fn of(robot: Robot) -> Self {
        match robot {
            Robot::Cheetah => Spec::Planar {
                spec: Box::new(robots::half_cheetah()),
                walker: false,
            },
            Robot::Walker => Spec::Planar {
                spec: Box::new(robots::walker()),
                walker: true,
            },
            Robot::Ant => Spec::Ant(Box::new(ant::ant())),
        }
    }

    fn build(&self, start: Start) -> Box<dyn Plant> {
        match self {
            #[cfg(feature = "mujoco")]
            Spec::Mujoco { robot, .. } => Box::new(on_mujoco::MjProbe::build(*robot, start)),
            Spec::Planar { spec, walker } => Box::new(PlanarPlant {
                robot: PlanarRobot::build_with(spec, &Scaling::NOMINAL, start),
                walker: *walker,
            }),
            Spec::Ant(spec) => Box::new(AntPlant {
                robot: AntRobot::build_with(spec, start),
            }),
        }
    }

    fn layout(&self, robot: Robot) -> Layout {
        match self {
            #[cfg(feature = "mujoco")]
            Spec::Mujoco { layout_of, .. } => layout_of.layout(robot),
            Spec::Planar { spec, .. } => {
                let (period, phases) = match robot {
                    // The back leg (joints 0..3) leads by half a period.
                    Robot::Cheetah => (0.5, vec![PI, PI, PI, 0.0, 0.0, 0.0]),
                    _ => (0.8, vec![0.0, 0.0, 0.0, PI, PI, PI]),
                };
                Layout {
                    dt: spec.physics_dt * spec.substeps as f32,
                    ranges: spec.limbs.iter().map(|l| l.mujoco_range).collect(),
                    angle_at: 2,
                    velocity_at: 11,
                    period,
                    phases,
                }
            }
            Spec::Ant(spec) => {
                let mut ranges = Vec::new();
                let mut phases = Vec::new();
                for (leg, l) in spec.legs.iter().enumerate() {
                    let hip_phase = if leg % 2 == 0 { 0.0 } else { PI };
                    ranges.push(spec.hip_range);
                    ranges.push(l.ankle_range);
                    phases.push(hip_phase);
                    phases.push(hip_phase + PI / 2.0);
                }
                Layout {
                    dt: spec.physics_dt * spec.substeps as f32,
                    ranges,
                    angle_at: ant::obs::JOINT_ANGLES,
                    velocity_at: ant::obs::JOINT_VELOCITIES,
                    period: 0.5,
                    phases,
                }
            }
        }
    }
}

/// numpy's median (the mean of the middle two of an even count); NaN for none.
fn median(values: &mut [f32]) -> f32 {
    if values.is_empty() {
        return f32::NAN;
    }
    values.sort_by(f32::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

fn random_actions(seed: u64, steps: usize, joints: usize) -> Vec<Vec<f32>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..steps)
        .map(|_| (0..joints).map(|_| rng.random_range(-1.0..1.0)).collect())
        .collect()
}

/// The twin-divergence figures of one seed: steps to 0.1, steps to 1, the rate.
fn twin(spec: &Spec, layout: &Layout, seed: u64, actions: &[Vec<f32>]) -> (f32, f32, f32) {
    let mut a = spec.build(Start::Noise(seed));
    let mut b = spec.build(Start::Noise(seed));
    let never = (actions.len() + 1) as f32;
    let (mut to_small, mut to_large) = (never, never);
    let horizon = layout.steps_per_second(1.0);
    let (mut d1, mut dk) = (f32::NAN, f32::NAN);
    for (k, action) in actions.iter().enumerate() {
        a.step(action);
        let nudged: Vec<f32> = if k == 0 {
            action.iter().map(|x| x + NUDGE).collect()
        } else {
            action.clone()
        };
        b.step(&nudged);
        let (sa, sb) = (a.state(), b.state());
        let gap = sa.iter().zip(&sb).map(|(x, y)| (x - y).abs());
        let max = gap.clone().fold(0.0, f32::max);
        let norm = gap.map(|g| g * g).sum::<f32>().sqrt();
        let step = (k + 1) as f32;
        if max > 0.1 && to_small == never {
            to_small = step;
        }
        if max > 1.0 && to_large == never {
            to_large = step;
        }
        if k == 0 {
            d1 = norm;
        }
        if k + 1 == horizon {
            dk = norm;
        }
    }
    let rate = (dk / d1).ln() / ((horizon - 1) as f32 * layout.dt);
    (to_small, to_large, rate)
}

/// One open-loop rollout's statistics.
struct OpenLoop {
    speed: f32,
    flipped: bool,
    fell_at: Option<usize>,
    overshoot: f32,
    penetration: f32,
}

fn open_loop(spec: &Spec, layout: &Layout, seed: u64, actions: &[Vec<f32>]) -> OpenLoop {
    let mut plant = spec.build(Start::Noise(seed));
    let x0 = plant.x();
    let mut result = OpenLoop {
        speed: 0.0,
        flipped: false,
        fell_at: None,
        overshoot: 0.0,
        penetration: 0.0,
    };
    for (k, action) in actions.iter().enumerate() {
        plant.step(action);
        result.flipped |= plant.upside_down();
        if result.fell_at.is_none() && !plant.healthy() {
            result.fell_at = Some(k + 1);
        }
        let state = plant.state();
        for (j, range) in layout.ranges.iter().enumerate() {
            let q = state[layout.angle_at + j];
            result.overshoot = result.overshoot.max(range[0] - q).max(q - range[1]);
        }
        result.penetration = result.penetration.max(plant.penetration());
    }
    result.speed = (plant.x() - x0) / (actions.len() as f32 * layout.dt);
    result
}

/// The closed-loop PD of FIDELITY.md under action noise `sigma`: speed, RMS tilt, RMS
/// tracking error.
fn closed_loop(
    spec: &Spec,
    layout: &Layout,
    seed: u64,
    steps: usize,
    sigma: f32,
) -> (f32, f32, f32) {
    let mut plant = spec.build(Start::Noise(seed));
    let mut rng = ChaCha8Rng::seed_from_u64(NOISE_SEED_OFFSET + seed);
    let x0 = plant.x();
    let (mut tilt2, mut track2) = (0.0f64, 0.0f64);
    let joints = layout.joints();
    for k in 0..steps {
        let t = k as f32 * layout.dt;
        let state = plant.state();
        let action: Vec<f32> = (0..joints)
            .map(|j| {
                let [lo, hi] = layout.ranges[j];
                let (mid, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
                let target = mid + 0.5 * half * (TAU * t / layout.period + layout.phases[j]).sin();
                let q = state[layout.angle_at + j];
                let qd = state[layout.velocity_at + j];
                track2 += f64::from((q - target).powi(2));
                let pd = (2.0 * (target - q) / half - 0.1 * qd).clamp(-1.0, 1.0);
                let noise: f32 = StandardNormal.sample(&mut rng);
                (pd + sigma * noise).clamp(-1.0, 1.0)
            })
            .collect();
        plant.step(&action);
        tilt2 += f64::from(plant.tilt().powi(2));
    }
    let speed = (plant.x() - x0) / (steps as f32 * layout.dt);
    let tilt = (tilt2 / steps as f64).sqrt() as f32;
    let track = (track2 / (steps * joints) as f64).sqrt() as f32;
    (speed, tilt, track)
}

/// The joint-pulse curves with the torso welded 1 m up: one per joint.
fn pulses(spec: &Spec, layout: &Layout) -> Vec<Vec<f32>> {
    let steps = layout.steps_per_second(1.0);
    (0..layout.joints())
        .map(|j| {
            let mut plant = spec.build(Start::Welded(1.0));
            let [lo, hi] = layout.ranges[j];
            let sign = if lo + hi >= 0.0 { 1.0 } else { -1.0 };
            (0..steps)
                .map(|k| {
                    let mut action = vec![0.0; layout.joints()];
                    if k == 0 {
                        action[j] = sign;
                    }
                    plant.step(&action);
                    plant.state()[layout.angle_at + j]
                })
                .collect()
        })
        .collect()
}

/// Runs the whole probe of FIDELITY.md on `robot`'s Rapier plant: the JSON document of its keys.
pub fn probe(robot: Robot, config: &ProbeConfig) -> Value {
    probe_spec(
        robot,
        Spec::of(robot),
        "rapier (this project's sim crate",
        config,
    )
}

/// [`probe`] on the MuJoCo backend (feature `mujoco`): Gymnasium's XML through
/// `sim::mujoco`, the same measurements as the Python script's on the same XML.
#[cfg(feature = "mujoco")]
pub fn probe_mujoco(robot: Robot, config: &ProbeConfig) -> Value {
    let spec = Spec::Mujoco {
        robot,
        layout_of: Box::new(Spec::of(robot)),
    };
    probe_spec(
        robot,
        spec,
        "mujoco 3.17.0 through this project's sim crate",
        config,
    )
}

fn probe_spec(robot: Robot, spec: Spec, source: &str, config: &ProbeConfig) -> Value {
    let layout = spec.layout(robot);
    let seeds: Vec<u64> = (0..config.seeds as u64).collect();
    let steps = config.steps;
    let trot: Vec<Vec<f32>> = (0..steps).map(|k| layout.trot(k)).collect();
    json!({
        "family": robot.name(),
        "source": format!("{source}, {})", robot.name()),
        "dt": layout.dt,
        "seeds": config.seeds,
        "steps": steps,
        "divergence": divergence(&spec, &layout, &seeds, &trot),
        "open_loop": open_loop_stats(robot, &spec, &layout, &seeds, &trot),
        "pulse": pulses(&spec, &layout),
        "drop": drop_test(&spec, &layout),
        "closed_loop": closed_loops(&spec, &layout, &seeds, steps),
    })
}

/// Twin divergence per action sequence (zero, trot, random): medians over the seeds.
fn divergence(spec: &Spec, layout: &Layout, seeds: &[u64], trot: &[Vec<f32>]) -> Value {
    let (steps, joints) = (trot.len(), layout.joints());
    let zero = vec![vec![0.0; joints]; steps];
    let mut divergence = serde_json::Map::new();
    for (name, actions) in [("zero", None), ("trot", Some(trot)), ("random", None)] {
        let (mut small, mut large, mut rates) = (Vec::new(), Vec::new(), Vec::new());
        for &seed in seeds {
            let random;
            let actions = match (name, actions) {
                ("random", _) => {
                    random = random_actions(seed, steps, joints);
                    &random
                }
                (_, Some(actions)) => actions,
                _ => &zero,
            };
            let (s, l, r) = twin(spec, layout, seed, actions);
            small.push(s);
            large.push(l);
            if r.is_finite() {
                rates.push(r);
            }
        }
        divergence.insert(
            name.into(),
            json!({"steps_0_1": median(&mut small), "steps_1": median(&mut large),
                   "rate": median(&mut rates)}),
        );
    }
    Value::Object(divergence)
}

/// Open-loop runs under the trot and random actions: speeds, flips, falls, limits, contact.
fn open_loop_stats(
    robot: Robot,
    spec: &Spec,
    layout: &Layout,
    seeds: &[u64],
    trot: &[Vec<f32>],
) -> Value {
    let (steps, joints) = (trot.len(), layout.joints());
    let trots: Vec<OpenLoop> = seeds
        .iter()
        .map(|&s| open_loop(spec, layout, s, trot))
        .collect();
    let randoms: Vec<OpenLoop> = seeds
        .iter()
        .map(|&s| open_loop(spec, layout, s, &random_actions(s, steps, joints)))
        .collect();
    let pick = |runs: &[OpenLoop], f: fn(&OpenLoop) -> f32| {
        let mut values: Vec<f32> = runs.iter().map(f).collect();
        median(&mut values)
    };
    let walker = robot == Robot::Walker;
    let falls = randoms.iter().filter(|r| r.fell_at.is_some()).count();
    let mut fall_steps: Vec<f32> = randoms
        .iter()
        .map(|r| r.fell_at.unwrap_or(steps + 1) as f32)
        .collect();
    let fall_step = median(&mut fall_steps);
    json!({
        "trot_speed": pick(&trots, |r| r.speed),
        "random_speed": pick(&randoms, |r| r.speed),
        "flips": randoms.iter().filter(|r| r.flipped).count(),
        "falls": if walker { json!(falls) } else { Value::Null },
        "fall_step": if walker { json!(fall_step) } else { Value::Null },
        "limit_overshoot": pick(&randoms, |r| r.overshoot.max(0.0)),
        "max_penetration": pick(&randoms, |r| r.penetration),
        "trot_penetration": pick(&trots, |r| r.penetration),
    })
}

/// The robot dropped from rest with zero torque for 2 s: its height curve and contact.
fn drop_test(spec: &Spec, layout: &Layout) -> Value {
    let joints = layout.joints();
    let drop_steps = layout.steps_per_second(2.0);
    let mut plant = spec.build(Start::Rest);
    let mut curve = Vec::with_capacity(drop_steps);
    let mut penetration = 0.0f32;
    for _ in 0..drop_steps {
        plant.step(&vec![0.0; joints]);
        curve.push(plant.height());
        penetration = penetration.max(plant.penetration());
    }
    let tail = layout.steps_per_second(0.5).max(1);
    let final_height = curve[drop_steps - tail..].iter().sum::<f32>() / tail as f32;
    json!({
        "curve": curve,
        "min": curve.iter().copied().fold(f32::INFINITY, f32::min),
        "final": final_height,
        "penetration": penetration,
    })
}

/// The closed-loop tracking runs, one per action-noise level.
fn closed_loops(spec: &Spec, layout: &Layout, seeds: &[u64], steps: usize) -> Value {
    let mut closed = serde_json::Map::new();
    for (name, sigma) in SIGMAS {
        let runs: Vec<(f32, f32, f32)> = seeds
            .iter()
            .map(|&s| closed_loop(spec, layout, s, steps, sigma))
            .collect();
        let mut speeds: Vec<f32> = runs.iter().map(|r| r.0).collect();
        let mean = speeds.iter().sum::<f32>() / speeds.len().max(1) as f32;
        let spread = (speeds.iter().map(|s| (s - mean).powi(2)).sum::<f32>()
            / speeds.len().max(1) as f32)
            .sqrt();
        let mut tilts: Vec<f32> = runs.iter().map(|r| r.1).collect();
        let mut tracks: Vec<f32> = runs.iter().map(|r| r.2).collect();
        closed.insert(
            name.into(),
            json!({"speed": median(&mut speeds), "speed_spread": spread,
                   "pitch_rms": median(&mut tilts), "track_rms": median(&mut tracks)}),
        );
    }
    Value::Object(closed)
}
