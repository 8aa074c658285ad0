//! Shared machinery of the planar legged robots (cheetah, walker): a declarative robot
//! description, its Rapier multibody (reduced coordinates: no joint drift), torque motors,
//! and the 17-D observation.
//!
//! Torques are applied the way Rapier's MJCF loader does it: a force-based velocity motor
//! aimed at +-1e9 with gain 0 and `max_force = |torque|`, so the motor always saturates at
//! exactly the commanded torque. Joint damping, armature and springs use the multibody's
//! implicit per-dof terms.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rapier2d::prelude::*;

// The 2-D build of what the Rapier robots share (`multibody.rs` says why it is compiled twice).
use rapier2d as rapier;
#[allow(clippy::duplicate_mod)] // once per dimension, on purpose
#[path = "multibody.rs"]
mod multibody;

use crate::dynamics::WalkerDynamics;
use crate::plant::TorsoPose;
use crate::rapier_plant::RapierRobot;
use crate::render::Shape;
use crate::sensing::{ObsComponent, rate};

/// Both planar legged robots have six torque-controlled joints.
pub const ACT_DIM: usize = 6;
/// Observation of both planar legged robots: torso height and angle, six joint angles, torso
/// (vx, vz, angular velocity), six joint velocities. The torso x is never observed.
pub const OBS_DIM: usize = 17;

/// What each observation entry is (cheetah-vel and walker-dyn): torso height, torso angle, six joint angles, torso (vx, vz,
/// angular velocity), six joint velocities. vx is the derivative of the unobserved torso x.
pub(crate) const OBS_COMPONENTS: [ObsComponent; OBS_DIM] = [
    ObsComponent::Position,
    ObsComponent::Angle,
    ObsComponent::Angle,
    ObsComponent::Angle,
    ObsComponent::Angle,
    ObsComponent::Angle,
    ObsComponent::Angle,
    ObsComponent::Angle,
    ObsComponent::Direct,
    rate(0),
    rate(1),
    rate(2),
    rate(3),
    rate(4),
    rate(5),
    rate(6),
    rate(7),
];
/// Number of limbs (each hangs from one actuated joint).
pub(crate) const LIMBS: usize = 6;
/// Generalised dofs of the floating torso (x, z, angle).
const ROOT_DOFS: usize = 3;
/// Index of the angular axis in a 2-D joint's spatial layout.
const ANGULAR_AXIS: usize = 2;

/// A capsule from `a` to `b` (rest pose, robot frame, metres).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Capsule {
    pub a: [f32; 2],
    pub b: [f32; 2],
    pub radius: f32,
}

/// One limb: a capsule hanging from a revolute joint on its parent.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LimbSpec {
    /// Index of the parent limb, or `None` for the torso.
    pub parent: Option<usize>,
    /// Joint position at rest (robot frame).
    pub joint: [f32; 2],
    /// The limb's capsule at rest (robot frame).
    pub capsule: Capsule,
    pub mass: f32,
    /// Joint range (radians, counter-clockwise positive).
    pub range: [f32; 2],
    /// +1 if MuJoCo's hinge turns about -y (its angle is counter-clockwise, as ours), -1 if
    /// about +y: observed angles, velocities and applied torques are multiplied by it, so the
    /// robot reads and takes exactly MuJoCo's joint coordinates and actions.
    pub sign: f32,
    /// The range in MuJoCo's coordinates (what the fidelity probe's controller tracks).
    pub mujoco_range: [f32; 2],
    /// Torque (N m) of an action of 1.
    pub gear: f32,
    pub damping: f32,
    pub stiffness: f32,
    pub armature: f32,
    pub friction: f32,
}

/// A planar legged robot: torso capsules, six limbs, and the physics settings.
#[derive(Debug, Clone)]
pub(crate) struct RobotSpec {
    pub torso: Vec<Capsule>,
    pub torso_mass: f32,
    pub torso_friction: f32,
    /// The ground's friction; contacts take the larger of the two, as MuJoCo does.
    pub ground_friction: f32,
    /// Softness of the ground contact (natural frequency Hz, damping ratio): Rapier's default
    /// (60 Hz, 10) is stiffer than MuJoCo's soft contacts (solref 0.02 s).
    pub contact_softness: [f32; 2],
    /// Rest position of the torso origin above the ground.
    pub origin: [f32; 2],
    pub limbs: [LimbSpec; LIMBS],
    pub physics_dt: f32,
    pub substeps: usize,
    pub solver_iterations: usize,
    /// Initial generalised positions get U(-x, x) noise.
    pub position_noise: f32,
    /// Initial generalised velocities get this times N(0, 1) (`uniform_velocity_noise` false)
    /// or U(-x, x) noise.
    pub velocity_noise: f32,
    pub uniform_velocity_noise: bool,
}

/// Per-body multipliers (torso first, then limbs) applied when building: mass, inertia,
/// friction; and per-joint damping multipliers.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Scaling {
    pub mass: [f32; LIMBS + 1],
    pub inertia: [f32; LIMBS + 1],
    pub friction: [f32; LIMBS + 1],
    pub damping: [f32; LIMBS],
}

impl Scaling {
    pub const NOMINAL: Scaling = Scaling {
        mass: [1.0; LIMBS + 1],
        inertia: [1.0; LIMBS + 1],
        friction: [1.0; LIMBS + 1],
        damping: [1.0; LIMBS],
    };
}

fn v(p: [f32; 2]) -> Vector {
    Vector::new(p[0], p[1])
}

/// Mass properties of `capsules` (body frame) scaled to `mass` and then inertia x `inertia`.
fn scaled_mass(capsules: &[Capsule], offset: Vector, mass: f32, inertia: f32) -> MassProperties {
    let unit: MassProperties = capsules
        .iter()
        .map(|c| MassProperties::from_capsule(1.0, v(c.a) - offset, v(c.b) - offset, c.radius))
        .sum();
    let ratio = mass / unit.mass();
    MassProperties::new(
        unit.local_com,
        mass,
        unit.principal_inertia() * ratio * inertia,
    )
}

/// How a robot starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Start {
    /// The rest pose plus the seeded reset noise (the episodes' start).
    Noise(u64),
    /// The rest pose exactly, zero velocity.
    Rest,
    /// The rest pose with the torso welded to the world this far (m) above its rest height:
    /// the fidelity probe's joint responses without contact.
    Welded(f32),
}

/// A built robot in its own physics world.
pub(crate) struct PlanarRobot {
    pub world: PhysicsWorld,
    torso: RigidBodyHandle,
    limbs: [RigidBodyHandle; LIMBS],
    gears: [f32; LIMBS],
    signs: [f32; LIMBS],
    ground: ColliderHandle,
    substeps: usize,
}

impl PlanarRobot {
    /// Builds the robot as `start` says.
    pub fn build_with(spec: &RobotSpec, scaling: &Scaling, start: Start) -> Self {
        let (mut world, ground) = Self::world(spec);
        let lift = match start {
            Start::Welded(height) => height,
            _ => 0.0,
        };
        let origin = v(spec.origin) + Vector::new(0.0, lift);
        let root = if lift > 0.0 {
            RigidBodyBuilder::fixed()
        } else {
            RigidBodyBuilder::dynamic()
        };
        let torso = world.insert_body(
            root.translation(origin)
                .additional_mass_properties(scaled_mass(
                    &spec.torso,
                    Vector::ZERO,
                    spec.torso_mass * scaling.mass[0],
                    scaling.inertia[0],
                ))
                .can_sleep(false),
        );
        for capsule in &spec.torso {
            let collider =
                ColliderBuilder::capsule_from_endpoints(v(capsule.a), v(capsule.b), capsule.radius)
                    .density(0.0);
            let friction = spec.torso_friction * scaling.friction[0];
            world.insert_collider(multibody::mujoco_friction(collider, friction), Some(torso));
        }
        let mut limbs = [torso; LIMBS];
        let mut gears = [0.0; LIMBS];
        let mut signs = [1.0; LIMBS];
        for (i, limb) in spec.limbs.iter().enumerate() {
            let joint = v(limb.joint);
            let body = world.insert_body(
                RigidBodyBuilder::dynamic()
                    .translation(origin + joint)
                    .additional_mass_properties(scaled_mass(
                        &[limb.capsule],
                        joint,
                        limb.mass * scaling.mass[i + 1],
                        scaling.inertia[i + 1],
                    ))
                    .can_sleep(false),
            );
            let collider = ColliderBuilder::capsule_from_endpoints(
                v(limb.capsule.a) - joint,
                v(limb.capsule.b) - joint,
                limb.capsule.radius,
            )
            .density(0.0);
            let friction = limb.friction * scaling.friction[i + 1];
            world.insert_collider(multibody::mujoco_friction(collider, friction), Some(body));
            let (parent, parent_origin) = match limb.parent {
                Some(p) => (limbs[p], v(spec.limbs[p].joint)),
                None => (torso, Vector::ZERO),
            };
            let hinge = multibody::motor_hinge(
                RevoluteJointBuilder::new(),
                joint - parent_origin,
                limb.range,
            );
            world.insert_multibody_joint(parent, body, hinge);
            limbs[i] = body;
            gears[i] = limb.gear;
            signs[i] = limb.sign;
        }
        let mut robot = Self {
            world,
            torso,
            limbs,
            gears,
            signs,
            ground,
            substeps: spec.substeps,
        };
        robot.configure_joints(spec, scaling);
        if let Start::Noise(seed) = start {
            robot.add_initial_noise(spec, seed);
        }
        robot
    }

    /// The robot's world: its integration parameters and the ground, with the ground's
    /// collider.
    fn world(spec: &RobotSpec) -> (PhysicsWorld, ColliderHandle) {
        multibody::world_on_ground(
            spec.physics_dt,
            spec.solver_iterations,
            spec.contact_softness,
            multibody::mujoco_friction(ColliderBuilder::cuboid(1.0e4, 0.5), spec.ground_friction),
            Vector::new(0.0, -0.5),
        )
    }

    fn multibody_mut(&mut self) -> Option<&mut Multibody> {
        multibody::multibody_mut(&mut self.world.multibody_joints, self.limbs[0])
    }

    fn configure_joints(&mut self, spec: &RobotSpec, scaling: &Scaling) {
        let limbs = self.limbs;
        let Some(multibody) = self.multibody_mut() else {
            return;
        };
        let root_dofs = multibody::undamped_root(multibody, LIMBS);
        // Rapier integrates a joint spring implicitly, -k (q + h v) over a solver substep h:
        // an extra damping k h that MuJoCo's (explicit) spring does not have. Take it off the
        // declared damping, so the joint's total damping is MuJoCo's.
        let substep = spec.physics_dt / spec.solver_iterations as f32;
        for (i, limb) in spec.limbs.iter().enumerate() {
            let dof = root_dofs + i;
            let spring_damping = limb.stiffness * substep;
            multibody.damping_mut()[dof] =
                (limb.damping * scaling.damping[i] - spring_damping).max(0.0);
            multibody.armature_mut()[dof] = limb.armature;
            if let Some(link) = multibody.link_mut(i + 1) {
                debug_assert_eq!(link.rigid_body_handle(), limbs[i]);
                link.joint.set_spring(ANGULAR_AXIS, limb.stiffness, 0.0);
            }
        }
    }

    fn add_initial_noise(&mut self, spec: &RobotSpec, seed: u64) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let ndofs = ROOT_DOFS + LIMBS;
        let q = spec.position_noise;
        let displacement: Vec<f32> = (0..ndofs).map(|_| rng.random_range(-q..=q)).collect();
        let velocity: Vec<f32> = (0..ndofs)
            .map(|_| {
                let qd = spec.velocity_noise;
                if spec.uniform_velocity_noise {
                    rng.random_range(-qd..=qd)
                } else {
                    let n: f32 = StandardNormal.sample(&mut rng);
                    qd * n
                }
            })
            .collect();
        let world = &mut self.world;
        if let Some(multibody) =
            multibody::multibody_mut(&mut world.multibody_joints, self.limbs[0])
        {
            multibody.forward_kinematics(&world.bodies, true);
            multibody::displace(multibody, &mut world.bodies, &displacement, &velocity);
        }
    }

    /// Sets the joint torques `action[i] * gear[i]` (action already clipped).
    fn set_torques(&mut self, action: &[f32]) {
        let gears = self.gears;
        let signs = self.signs;
        let Some(multibody) = self.multibody_mut() else {
            return;
        };
        for (i, (&a, gear)) in action.iter().zip(gears).enumerate() {
            let torque = signs[i] * a * gear;
            if let Some(link) = multibody.link_mut(i + 1) {
                multibody::drive(link, torque);
            }
        }
    }

    /// Torso origin (x, z) and pitch (MuJoCo's rooty: about +y, so clockwise positive).
    pub fn torso_pose(&self) -> (f32, f32, f32) {
        let body = &self.world.bodies[self.torso];
        let p = body.translation();
        (p.x, p.y, -body.rotation().angle())
    }

    /// The deepest penetration (m) of any robot collider into the ground right now (0 if
    /// none): what the fidelity probe compares with MuJoCo's contact distances.
    pub fn ground_penetration(&self) -> f32 {
        multibody::deepest_penetration(&self.world, self.ground)
    }
}

impl RapierRobot for PlanarRobot {
    type Spec = RobotSpec;
    const OBS_DIM: usize = OBS_DIM;

    fn build(spec: &RobotSpec, seed: u64, dynamics: Option<&WalkerDynamics>) -> Self {
        Self::build_with(spec, &Scaling::of(dynamics), Start::Noise(seed))
    }

    fn control_dt(spec: &RobotSpec) -> f32 {
        spec.physics_dt * spec.substeps as f32
    }

    fn step(&mut self, action: &[f32]) {
        self.set_torques(action);
        multibody::advance(&mut self.world, self.substeps);
    }

    fn diverged(&self) -> bool {
        multibody::diverged(&self.world)
    }

    /// The 17-D observation in MuJoCo's coordinates (Gymnasium's layout, the torso height
    /// absolute).
    fn observe(&self, obs: &mut [f32], velocity_clip: f32) {
        let (_, z, pitch) = self.torso_pose();
        obs[0] = z;
        obs[1] = pitch;
        let angle_of = |h: RigidBodyHandle| self.world.bodies[h].rotation().angle();
        let parent_of = |i: usize| match i {
            0 | 3 => self.torso,
            i => self.limbs[i - 1],
        };
        for i in 0..LIMBS {
            let relative = angle_of(self.limbs[i]) - angle_of(parent_of(i));
            obs[2 + i] = self.signs[i] * wrap_angle(relative);
        }
        let clip = |value: f32| value.clamp(-velocity_clip, velocity_clip);
        if let Some(multibody) = multibody::multibody(&self.world.multibody_joints, self.limbs[0]) {
            let velocity = multibody.generalized_velocity();
            let root = multibody.ndofs() - LIMBS;
            if root == ROOT_DOFS {
                obs[8] = clip(velocity[0]);
                obs[9] = clip(velocity[1]);
                obs[10] = clip(-velocity[ANGULAR_AXIS]);
            } else {
                obs[8..11].fill(0.0);
            }
            for i in 0..LIMBS {
                obs[11 + i] = clip(self.signs[i] * velocity[root + i]);
            }
        }
    }

    fn torso(&self) -> TorsoPose {
        let (x, z, pitch) = self.torso_pose();
        TorsoPose {
            position: [x, 0.0, z],
            pitch,
        }
    }

    /// The robot's capsules in world coordinates (side view).
    fn shapes(&self) -> Vec<Shape> {
        let mut shapes = Vec::new();
        for (_, collider) in self.world.colliders.iter() {
            if let Some(capsule) = collider.shape().as_capsule() {
                shapes.push(multibody::capsule_shape(collider.position(), capsule));
            }
        }
        shapes
    }
}

impl Scaling {
    /// walker-dyn's factors as the builder takes them (`None`: nominal).
    pub fn of(dynamics: Option<&WalkerDynamics>) -> Scaling {
        match dynamics {
            Some(d) => Scaling {
                mass: d.mass,
                inertia: d.inertia,
                friction: d.friction,
                damping: d.damping,
            },
            None => Scaling::NOMINAL,
        }
    }
}

/// Wraps an angle to (-pi, pi].
fn wrap_angle(angle: f32) -> f32 {
    use std::f32::consts::{PI, TAU};
    let wrapped = (angle + PI).rem_euclid(TAU) - PI;
    if wrapped <= -PI {
        wrapped + TAU
    } else {
        wrapped
    }
}
