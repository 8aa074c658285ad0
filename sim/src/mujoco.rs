//! The MuJoCo backend (cargo feature `mujoco`): the robots as Gymnasium v5 defines them,
//! loaded from Gymnasium's XMLs (vendored in `sim/mujoco/`, MIT, Farama Foundation) and
//! stepped by MuJoCo 3.17.0 through `mujoco-rs`.
//!
//! Per robot, as Gymnasium's `half_cheetah_v5.py`, `walker2d_v5.py` and `ant_v5.py`: frame
//! skip 5; reset `qpos = qpos0 + U(-r, r)` and `qvel = r N(0, 1)` (cheetah, ant: r = 0.1) or
//! `U(-r, r)` (walker: r = 5e-3), then `mj_forward`; observations `qpos[1:] ++ qvel` for the
//! planar robots (the root x never observed) and `qpos[2:] ++ qvel ++ qpos[0:2]` for the ant (the
//! ant families observe the torso's x, y; Gymnasium's contact forces are not observed). The
//! walker is the original gym `walker2d.xml` (left foot friction 1.9), the SMILe authors' walker,
//! stepped 5 x 0.002 s as their rand_param_envs walker. walker-dyn's dynamics scale the model's
//! `body_mass`, `body_inertia`, `dof_damping` and `geom_friction` as rand_param_envs does, then
//! `mj_setConst` recomputes what MuJoCo derives from them.
//!
//! The noise is drawn from ChaCha8 (not NumPy), so a seed gives a different start than
//! Gymnasium's; from the same state and actions the trajectory is Python MuJoCo's to the last
//! bit (`sim/tests/mujoco_golden.rs`).

use mujoco_rs::mujoco_c::{mj_version, mjVERSION_HEADER, mjtWarning};
use mujoco_rs::prelude::{
    MjData, MjLogMessage, MjModel, MjtGeomBase, MjtLogLevel, set_log_handler,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::dynamics::WalkerDynamics;
use crate::error::SimError;
use crate::kinds::Physics;
use crate::plant::{Plant, Robot, TorsoPose};
use crate::render::{Role, Shape};

const HALF_CHEETAH_XML: &str = include_str!("../mujoco/half_cheetah.xml");
const WALKER2D_XML: &str = include_str!("../mujoco/walker2d.xml");
const ANT_XML: &str = include_str!("../mujoco/ant.xml");

/// How one robot is loaded, reset and observed.
#[derive(Debug, Clone, Copy)]
struct Spec {
    xml: &'static str,
    /// Physics steps per control step.
    frame_skip: usize,
    /// Reset: `qpos0 + U(-position_noise, position_noise)`.
    position_noise: f64,
    /// Reset: `velocity_noise * N(0, 1)`, or `U(-velocity_noise, velocity_noise)` if
    /// `uniform_velocity_noise`.
    velocity_noise: f64,
    uniform_velocity_noise: bool,
    /// Observation and action sizes, checked against the compiled model.
    nq: usize,
    nv: usize,
    nu: usize,
}

fn spec(robot: Robot) -> Spec {
    match robot {
        Robot::HalfCheetah => Spec {
            xml: HALF_CHEETAH_XML,
            frame_skip: 5,
            position_noise: 0.1,
            velocity_noise: 0.1,
            uniform_velocity_noise: false,
            nq: 9,
            nv: 9,
            nu: 6,
        },
        Robot::Walker2d => Spec {
            xml: WALKER2D_XML,
            frame_skip: 5,
            position_noise: 5e-3,
            velocity_noise: 5e-3,
            uniform_velocity_noise: true,
            nq: 9,
            nv: 9,
            nu: 6,
        },
        Robot::Ant => Spec {
            xml: ANT_XML,
            frame_skip: 5,
            position_noise: 0.1,
            velocity_noise: 0.1,
            uniform_velocity_noise: false,
            nq: 15,
            nv: 14,
            nu: 8,
        },
    }
}

/// The model values walker-dyn scales, as compiled.
#[derive(Debug, Clone)]
struct Nominal {
    body_mass: Vec<f64>,
    body_inertia: Vec<[f64; 3]>,
    dof_damping: Vec<f64>,
    geom_friction: Vec<[f64; 3]>,
}

/// One robot in its own MuJoCo model and data.
pub struct MjPlant {
    robot: Robot,
    spec: Spec,
    data: MjData<Box<MjModel>>,
    nominal: Nominal,
    /// The dynamics the model holds now (`None`: nominal).
    dynamics: Option<WalkerDynamics>,
    /// The torso body's rest height minus the rootz coordinate's rest value: the torso's height
    /// is this plus `qpos[1]` (the cheetah's rootz is 0 at rest, the walker's 1.25).
    planar_z_offset: f64,
}

fn unavailable(how: String) -> SimError {
    SimError::PhysicsUnavailable {
        physics: Physics::Mujoco,
        how,
    }
}

/// Checks that the loaded libmujoco is the version the bindings were made for (mujoco-rs
/// would panic on a mismatch).
fn check_library() -> Result<(), SimError> {
    // SAFETY: mj_version only reads a constant of the loaded library.
    let linked = unsafe { mj_version() } as u32;
    if linked == mjVERSION_HEADER {
        Ok(())
    } else {
        Err(unavailable(format!(
            "the loaded libmujoco is version {linked}, this build needs {mjVERSION_HEADER} \
             (MuJoCo {}); run scripts/fetch-mujoco.sh and rebuild",
            crate::physics::MUJOCO_VERSION
        )))
    }
}

/// MuJoCo's warnings and errors to stderr, prefixed, instead of its default handler's stdout
/// and a `MUJOCO_LOG.TXT` in the working directory; its debug and info messages (compile
/// timings) are dropped, and so is the one warning every cheetah load gives (`settotalmass is
/// deprecated`, about the vendored XML as Gymnasium ships it).
fn mujoco_log(message: &MjLogMessage) {
    let subject = message.subject();
    let level = message.level();
    let quiet = matches!(level, MjtLogLevel::mjLOG_DEBUG | MjtLogLevel::mjLOG_INFO);
    if !quiet && !subject.contains("settotalmass") {
        eprintln!("MuJoCo: {subject} {}", message.body().unwrap_or_default());
    }
}

static LOG_HANDLER: std::sync::Once = std::sync::Once::new();

/// The vendored XML of `robot`, as Gymnasium ships it.
pub fn xml(robot: Robot) -> &'static str {
    spec(robot).xml
}

impl MjPlant {
    /// Loads `robot`'s XML, reset with seed 0 and nominal dynamics.
    pub fn new(robot: Robot) -> Result<Self, SimError> {
        Self::load(robot, spec(robot).xml, true)
    }

    /// `robot` from another XML (an edited copy of its own, e.g. with the root joints removed
    /// for the fidelity probe's welded torso): the sizes are not checked, the state starts at
    /// `qpos0` with zero velocity, and only [`Self::set_state`], [`Self::step_f32`] and the
    /// accessors may be used.
    pub fn from_xml(robot: Robot, xml: &str) -> Result<Self, SimError> {
        let mut plant = Self::load(robot, xml, false)?;
        let qpos = plant.data.model().qpos0().to_vec();
        let qvel = vec![0.0; plant.qvel().len()];
        plant.set_state(&qpos, &qvel)?;
        Ok(plant)
    }

    fn load(robot: Robot, xml: &str, check_sizes: bool) -> Result<Self, SimError> {
        check_library()?;
        // Every use of MuJoCo in this crate starts here, so the first call runs before any
        // other thread touches MuJoCo; later calls wait for it.
        // SAFETY: see above; the handler is thread-safe (eprintln) and never logs an error.
        LOG_HANDLER.call_once(|| unsafe { set_log_handler(mujoco_log) });
        let mut spec = spec(robot);
        let model = MjModel::from_xml_string(xml)
            .map_err(|e| unavailable(format!("{} did not load: {e}", robot.name())))?;
        let sizes = (model.ffi().nq, model.ffi().nv, model.ffi().nu);
        if !check_sizes {
            (spec.nq, spec.nv, spec.nu) = (sizes.0 as usize, sizes.1 as usize, sizes.2 as usize);
        } else if sizes != (spec.nq as i64, spec.nv as i64, spec.nu as i64) {
            return Err(unavailable(format!(
                "{} compiled with (nq, nv, nu) = {sizes:?}, expected ({}, {}, {})",
                robot.name(),
                spec.nq,
                spec.nv,
                spec.nu
            )));
        }
        let nominal = Nominal {
            body_mass: model.body_mass().to_vec(),
            body_inertia: model.body_inertia().to_vec(),
            dof_damping: model.dof_damping().to_vec(),
            geom_friction: model.geom_friction().to_vec(),
        };
        let planar_z_offset = match robot {
            Robot::HalfCheetah | Robot::Walker2d if check_sizes => {
                model.body_pos()[1][2] - model.qpos0()[1]
            }
            _ => 0.0,
        };
        let data = MjData::try_new(Box::new(model))
            .map_err(|e| unavailable(format!("no memory for MuJoCo's data: {e}")))?;
        let mut plant = Self {
            robot,
            spec,
            data,
            nominal,
            dynamics: None,
            planar_z_offset,
        };
        if check_sizes {
            plant.reset(0, None);
        }
        Ok(plant)
    }

    /// `mj_forward`: the derived quantities (body poses, contacts) for the state reached, which
    /// `mj_step` leaves one physics step behind (it computes them before integrating).
    pub fn forward(&mut self) {
        self.data.forward();
    }

    /// The compiled model (joint ranges, actuator transmissions, custom numerics).
    pub fn model(&self) -> &MjModel {
        self.data.model()
    }

    /// The deepest penetration (m) of any contact with the floor (geom 0) now, 0 if none:
    /// `max(0, -dist)` over the contacts, as the fidelity probe's MuJoCo script measures it.
    pub fn ground_penetration(&self) -> f64 {
        self.data
            .contact()
            .iter()
            .filter(|c| c.geom[0] == 0 || c.geom[1] == 0)
            .map(|c| -c.dist)
            .fold(0.0, f64::max)
    }

    /// The robot.
    pub fn robot(&self) -> Robot {
        self.robot
    }

    /// Generalised positions (MuJoCo's `qpos`).
    pub fn qpos(&self) -> &[f64] {
        self.data.qpos()
    }

    /// Generalised velocities (MuJoCo's `qvel`).
    pub fn qvel(&self) -> &[f64] {
        self.data.qvel()
    }

    /// Sets the state exactly (`mj_resetData`, then `qpos`, `qvel`, then `mj_forward`: what
    /// Gymnasium's `set_state` does). Errors on a length mismatch.
    pub fn set_state(&mut self, qpos: &[f64], qvel: &[f64]) -> Result<(), SimError> {
        if qpos.len() != self.spec.nq || qvel.len() != self.spec.nv {
            return Err(SimError::BufferLength {
                expected: self.spec.nq + self.spec.nv,
                got: qpos.len() + qvel.len(),
            });
        }
        self.data.reset();
        self.data.qpos_mut().copy_from_slice(qpos);
        self.data.qvel_mut().copy_from_slice(qvel);
        self.data.forward();
        Ok(())
    }

    /// One control step: `ctrl = action` (each entry clipped to [-1, 1] by the model's
    /// ctrlrange), then `frame_skip` calls of `mj_step`.
    pub fn step_ctrl(&mut self, action: &[f64]) {
        for (ctrl, &a) in self.data.ctrl_mut().iter_mut().zip(action) {
            *ctrl = a;
        }
        for _ in 0..self.spec.frame_skip {
            self.data.step();
        }
    }

    /// One control step of an f32 action, as the environments take it (widened to f64).
    pub fn step_f32(&mut self, action: &[f32]) {
        let mut ctrl = [0.0f64; 8];
        for (c, &a) in ctrl.iter_mut().zip(action) {
            *c = a as f64;
        }
        self.step_ctrl(&ctrl[..self.spec.nu.min(ctrl.len())]);
    }

    /// Writes walker-dyn's factors into the model (nominal x factor, then `mj_setConst`), if
    /// they changed; the other robots ignore them. `None` restores the nominal model.
    pub fn set_dynamics(&mut self, dynamics: Option<&WalkerDynamics>) {
        if self.robot != Robot::Walker2d || self.dynamics.as_ref() == dynamics {
            return;
        }
        let d = dynamics.copied().unwrap_or_else(WalkerDynamics::nominal);
        let n = &self.nominal;
        // SAFETY: only values change (no size, index or address), as rand_param_envs does, and
        // mj_setConst below recomputes the derived constants.
        let model = unsafe { self.data.model_mut() };
        // Bodies 1..=7 are torso, thigh, leg, foot, thigh_left, leg_left, foot_left: the order
        // of WalkerDynamics' per-body factors; body 0 is the world.
        for b in 1..model.body_mass().len() {
            let k = (b - 1).min(d.mass.len() - 1);
            model.body_mass_mut()[b] = n.body_mass[b] * d.mass[k] as f64;
            for (axis, value) in model.body_inertia_mut()[b].iter_mut().enumerate() {
                *value = n.body_inertia[b][axis] * d.inertia[k] as f64;
            }
        }
        // Dofs 0..3 are the root (undamped); 3..9 the six joints.
        for j in 0..d.damping.len() {
            model.dof_damping_mut()[3 + j] = n.dof_damping[3 + j] * d.damping[j] as f64;
        }
        let bodies: Vec<i32> = model.geom_bodyid().to_vec();
        for (g, &body) in bodies.iter().enumerate() {
            if body >= 1 {
                let k = (body as usize - 1).min(d.friction.len() - 1);
                for (axis, value) in model.geom_friction_mut()[g].iter_mut().enumerate() {
                    *value = n.geom_friction[g][axis] * d.friction[k] as f64;
                }
            }
        }
        self.data.set_const();
        self.dynamics = dynamics.copied();
    }
}

impl Plant for MjPlant {
    fn control_dt(&self) -> f32 {
        (self.data.model().opt().timestep * self.spec.frame_skip as f64) as f32
    }

    fn reset(&mut self, seed: u64, dynamics: Option<&WalkerDynamics>) {
        self.set_dynamics(dynamics);
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x4d55_4a4f_434f_5253); // "MUJOCORS"
        let s = self.spec;
        let qpos: Vec<f64> = self
            .data
            .model()
            .qpos0()
            .iter()
            .map(|q| q + rng.random_range(-s.position_noise..=s.position_noise))
            .collect();
        let qvel: Vec<f64> = (0..s.nv)
            .map(|_| {
                if s.uniform_velocity_noise {
                    rng.random_range(-s.velocity_noise..=s.velocity_noise)
                } else {
                    let n: f64 = StandardNormal.sample(&mut rng);
                    s.velocity_noise * n
                }
            })
            .collect();
        // Lengths are the model's own: this cannot fail.
        let _ = self.set_state(&qpos, &qvel);
    }

    fn step(&mut self, action: &[f32]) {
        self.step_f32(action);
    }

    fn diverged(&self) -> bool {
        // MuJoCo resets the data itself when the state goes bad and counts a warning.
        let warnings = &self.data.ffi().warning;
        let bad = [
            mjtWarning::mjWARN_BADQPOS,
            mjtWarning::mjWARN_BADQVEL,
            mjtWarning::mjWARN_BADQACC,
        ]
        .iter()
        .any(|&w| warnings[w as usize].number > 0);
        bad || !self.qpos().iter().chain(self.qvel()).all(|v| v.is_finite())
    }

    fn observe(&self, out: &mut [f32], velocity_clip: f32) {
        // Written in place: this runs at every step of every rollout.
        let clip = velocity_clip as f64;
        let (qpos, qvel) = (self.qpos(), self.qvel());
        let skip = match self.robot {
            Robot::HalfCheetah | Robot::Walker2d => 1,
            Robot::Ant => 2,
        };
        let positions = qpos[skip..].iter().copied();
        let velocities = qvel.iter().map(|v| v.clamp(-clip, clip));
        let xy = qpos[..skip]
            .iter()
            .copied()
            .filter(|_| self.robot == Robot::Ant);
        for (o, v) in out.iter_mut().zip(positions.chain(velocities).chain(xy)) {
            *o = v as f32;
        }
    }

    fn torso(&self) -> TorsoPose {
        let q = self.qpos();
        match self.robot {
            Robot::HalfCheetah | Robot::Walker2d => TorsoPose {
                position: [q[0] as f32, 0.0, (self.planar_z_offset + q[1]) as f32],
                pitch: q[2] as f32,
            },
            Robot::Ant => TorsoPose {
                position: [q[0] as f32, q[1] as f32, q[2] as f32],
                pitch: 0.0,
            },
        }
    }

    fn shapes(&self) -> Vec<Shape> {
        let model = self.data.model();
        let top_view = self.robot == Robot::Ant;
        let project = |p: [f64; 3]| {
            if top_view {
                [p[0] as f32, p[1] as f32]
            } else {
                [p[0] as f32, p[2] as f32]
            }
        };
        let mut shapes = Vec::new();
        for (g, kind) in model.geom_type().iter().enumerate() {
            let center = self.data.geom_xpos()[g];
            let size = model.geom_size()[g];
            match kind {
                MjtGeomBase::mjGEOM_CAPSULE => {
                    let m = self.data.geom_xmat()[g];
                    // The capsule's axis is its frame's z axis: the third column.
                    let axis = [m[2], m[5], m[8]];
                    let end = |sign: f64| [0, 1, 2].map(|i| center[i] + sign * size[1] * axis[i]);
                    shapes.push(Shape::Capsule {
                        a: project(end(-1.0)),
                        b: project(end(1.0)),
                        radius: size[0] as f32,
                        role: Role::Robot,
                    });
                }
                MjtGeomBase::mjGEOM_SPHERE => shapes.push(Shape::Circle {
                    center: project(center),
                    radius: size[0] as f32,
                    role: Role::Robot,
                }),
                _ => {}
            }
        }
        shapes
    }
}
