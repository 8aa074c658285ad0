//! The 3-D quadruped of the Ant families: Gymnasium's `ant.xml` as a Rapier 3-D multibody
//! (reduced coordinates: no joint drift), declared in one function, `ant`.
//!
//! Torques are applied as in [`crate::planar`] (and Rapier's MJCF loader): a force-based
//! velocity motor aimed at +-1e9 with gain 0 and `max_force = |torque|`. Joint damping and
//! armature are the multibody's implicit per-dof terms; the free root has neither (as the
//! `root` joint of ant.xml). The world is z-up.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rapier3d::prelude::*;

// The 3-D build of what the Rapier robots share (`multibody.rs` says why it is compiled twice).
use rapier3d as rapier;
#[allow(clippy::duplicate_mod)] // once per dimension, on purpose
#[path = "multibody.rs"]
mod multibody;

use crate::dynamics::WalkerDynamics;
use crate::planar::Start;
use crate::plant::TorsoPose;
use crate::rapier_plant::RapierRobot;
use crate::render::{Role, Shape};
use crate::sensing::{ObsComponent, rate};

mod episode;
pub(crate) use episode::AntEpisode;
pub use episode::VELOCITY_CLIP;

/// Eight torque-controlled joints: per leg, a hip (about z) then an ankle.
pub const ACT_DIM: usize = 8;
/// Observation: torso height z (1), orientation quaternion w, x, y, z (4), joint angles (8),
/// torso linear velocity in the world frame (3), torso angular velocity in the torso frame (3),
/// joint velocities (8), torso (x, y) (2). See [`obs`] for the indices.
pub const OBS_DIM: usize = 29;
/// Legs of the ant.
pub(crate) const LEGS: usize = 4;
/// Actuated joints (two per leg), in ant.xml's qpos order: hip_1, ankle_1, hip_2, ...
pub(crate) const JOINTS: usize = 2 * LEGS;
/// Generalised dofs of the floating torso: translation x, y, z, then rotation (world axes).
const ROOT_DOFS: usize = 6;
/// Index of a revolute joint's angle in a Rapier 3-D joint's coordinates (its free AngX).
const HINGE_COORD: usize = 3;

/// Where each quantity sits in the ant observation.
pub mod obs {
    /// Torso height z (m).
    pub const Z: usize = 0;
    /// Torso orientation quaternion (w, x, y, z), sign chosen so that w >= 0: 4 entries.
    pub const QUATERNION: usize = 1;
    /// The 8 joint angles (rad), hip_1, ankle_1, ..., hip_4, ankle_4.
    pub const JOINT_ANGLES: usize = 5;
    /// Torso linear velocity (vx, vy, vz), world frame, m/s: 3 entries.
    pub const LINEAR_VELOCITY: usize = 13;
    /// Torso angular velocity, torso frame (what a gyro reads), rad/s: 3 entries.
    pub const ANGULAR_VELOCITY: usize = 16;
    /// The 8 joint velocities (rad/s), same order as the angles.
    pub const JOINT_VELOCITIES: usize = 19;
    /// Torso (x, y) position (m): 2 entries.
    pub const XY: usize = 27;
}

/// What each observation entry is ([`obs`]): torso z, orientation quaternion (an IMU's attitude:
/// direct), eight joint angles, torso linear velocity (world frame: the rates of x, y, z),
/// angular velocity (a gyro's: direct, not the derivative of the quaternion entries), eight
/// joint velocities, torso x and y.
pub(crate) const OBS_COMPONENTS: [ObsComponent; OBS_DIM] = [
    ObsComponent::Position,
    ObsComponent::Direct,
    ObsComponent::Direct,
    ObsComponent::Direct,
    ObsComponent::Direct,
    ObsComponent::Angle,
    ObsComponent::Angle,
    ObsComponent::Angle,
    ObsComponent::Angle,
    ObsComponent::Angle,
    ObsComponent::Angle,
    ObsComponent::Angle,
    ObsComponent::Angle,
    rate(27),
    rate(28),
    rate(0),
    ObsComponent::Direct,
    ObsComponent::Direct,
    ObsComponent::Direct,
    rate(5),
    rate(6),
    rate(7),
    rate(8),
    rate(9),
    rate(10),
    rate(11),
    rate(12),
    ObsComponent::Position,
    ObsComponent::Position,
];

/// One leg as ant.xml declares it, in the torso frame at rest (joint angles 0: the leg lies
/// flat, pointing outwards).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Leg {
    /// End of the torso's auxiliary capsule = position of the hip joint (x, y).
    pub hip: [f32; 2],
    /// Thigh capsule from the hip to the ankle joint, relative to the hip (x, y).
    pub thigh: [f32; 2],
    /// Shin capsule from the ankle to the foot, relative to the ankle (x, y).
    pub shin: [f32; 2],
    /// Ankle hinge axis (torso frame); a positive angle turns the shin about it.
    pub ankle_axis: [f32; 3],
    /// Ankle range (rad).
    pub ankle_range: [f32; 2],
    /// Ankle angle of the rest pose the episodes start from (ant.xml's `init_qpos`).
    pub ankle_rest: f32,
}

/// The ant: geometry, joints and physics settings.
#[derive(Debug, Clone)]
pub(crate) struct AntSpec {
    pub torso_radius: f32,
    /// Radius of every capsule (auxiliary, thigh, shin).
    pub limb_radius: f32,
    /// Mass density of every geometry (kg/m^3): masses follow from the volumes.
    pub density: f32,
    /// Torso height of the rest pose (m).
    pub rest_height: f32,
    pub legs: [Leg; LEGS],
    /// Hip range (rad), the same for every leg.
    pub hip_range: [f32; 2],
    /// Torque (N m) of an action of 1, every joint.
    pub gear: f32,
    pub joint_damping: f32,
    pub joint_armature: f32,
    pub friction: f32,
    /// Softness of the ground contact (natural frequency Hz, damping ratio).
    pub contact_softness: [f32; 2],
    pub physics_dt: f32,
    pub substeps: usize,
    pub solver_iterations: usize,
    /// Initial generalised positions get U(-x, x) noise (rad for the rotations).
    pub position_noise: f32,
    /// Initial generalised velocities get x * N(0, 1) noise.
    pub velocity_noise: f32,
}

const fn deg(degrees: f32) -> f32 {
    degrees * std::f32::consts::PI / 180.0
}

/// Gymnasium's Ant (`ant.xml`): torso sphere of radius 0.25 with four auxiliary capsules to
/// the hips, four legs of a thigh and a shin (capsules of radius 0.08), hips about z in
/// +-30 deg, ankles in 30..70 deg (pointing down), gear 150, joint damping 1, armature 1,
/// friction 1, MuJoCo's default density 5 (so torso 0.486 kg with its capsules, thigh 0.039 kg,
/// shin 0.068 kg; 0.91 kg in all). Episodes start from ant.xml's `init_qpos` pose: torso at
/// 0.55 m, ankles at +-1 rad, feet on the ground.
///
/// Control step 0.05 s as in Gymnasium (5 x 0.01 s), here as 2 physics steps of 0.025 s with 2
/// solver iterations. Rapier's solver iterations are substeps, each recomputing the 14-dof
/// multibody mass matrix (most of the cost), so a control step is 4 solver substeps of
/// 12.5 ms: about 250 us on one core (EPYC). Measured (30 seeded 100-step episodes each):
/// zero, constant and random actions over 2000-step runs never diverged; zero action stands at
/// z 0.55; random actions flip the ant in 8 of 30 episodes, mean peak z 0.98 m, mean final
/// |xy| 1.4 m, the same as with 8 iterations x 2 steps (6/30, 0.91 m, 1.35 m) at 4x the cost,
/// and less lively than MuJoCo on ant.xml (18/30, 1.21 m, 2.0 m). The armature 1 makes the legs
/// heavy in joint space, which is what lets so large a step stay stable.
pub(crate) fn ant() -> AntSpec {
    let flat = |x: f32, y: f32, ankle_axis: [f32; 3], ankle_range: [f32; 2], ankle_rest| Leg {
        hip: [0.2 * x, 0.2 * y],
        thigh: [0.2 * x, 0.2 * y],
        shin: [0.4 * x, 0.4 * y],
        ankle_axis,
        ankle_range,
        ankle_rest,
    };
    let down = [deg(30.0), deg(70.0)];
    let down_mirrored = [deg(-70.0), deg(-30.0)];
    AntSpec {
        torso_radius: 0.25,
        limb_radius: 0.08,
        density: 5.0,
        rest_height: 0.55,
        legs: [
            flat(1.0, 1.0, [-1.0, 1.0, 0.0], down, 1.0),
            flat(-1.0, 1.0, [1.0, 1.0, 0.0], down_mirrored, -1.0),
            flat(-1.0, -1.0, [-1.0, 1.0, 0.0], down_mirrored, -1.0),
            flat(1.0, -1.0, [1.0, 1.0, 0.0], down, 1.0),
        ],
        hip_range: [deg(-30.0), deg(30.0)],
        gear: 150.0,
        joint_damping: 1.0,
        joint_armature: 1.0,
        friction: 1.0,
        contact_softness: ANT_CONTACT_SOFTNESS,
        physics_dt: 0.025,
        substeps: 2,
        solver_iterations: 2,
        position_noise: 0.1,
        velocity_noise: 0.1,
    }
}

/// The ant's ground-contact softness (natural frequency Hz, damping ratio), calibrated on
/// the fidelity probe's drop test against MuJoCo's (`docs/FIDELITY.md`).
pub(crate) const ANT_CONTACT_SOFTNESS: [f32; 2] = [60.0, 10.0];

fn flat(p: [f32; 2]) -> Vector {
    Vector::new(p[0], p[1], 0.0)
}

/// A built ant in its own physics world.
pub(crate) struct AntRobot {
    world: PhysicsWorld,
    torso: RigidBodyHandle,
    /// Link bodies in joint order: thigh_1, shin_1, thigh_2, ...
    links: [RigidBodyHandle; JOINTS],
    gear: f32,
    ground: ColliderHandle,
    substeps: usize,
}

impl AntRobot {
    /// Builds the ant as `start` says.
    pub fn build_with(spec: &AntSpec, start: Start) -> Self {
        let (mut world, ground) = multibody::world_on_ground(
            spec.physics_dt,
            spec.solver_iterations,
            spec.contact_softness,
            multibody::mujoco_friction(ColliderBuilder::cuboid(1.0e3, 1.0e3, 0.5), spec.friction),
            Vector::new(0.0, 0.0, -0.5),
        );
        world.gravity = Vector::new(0.0, 0.0, -9.81);
        let lift = match start {
            Start::Welded(height) => height,
            _ => 0.0,
        };
        // Built with every joint at 0 (legs flat); the rest pose is applied as a displacement.
        let origin = Vector::new(0.0, 0.0, spec.rest_height + lift);
        let r = spec.limb_radius;
        let capsule = |a: Vector, b: Vector| {
            let collider = ColliderBuilder::capsule_from_endpoints(a, b, r).density(spec.density);
            multibody::mujoco_friction(collider, spec.friction)
        };
        let root = if lift > 0.0 {
            RigidBodyBuilder::fixed()
        } else {
            RigidBodyBuilder::dynamic()
        };
        let torso = world.insert_body(root.translation(origin).can_sleep(false));
        let ball = ColliderBuilder::ball(spec.torso_radius).density(spec.density);
        world.insert_collider(multibody::mujoco_friction(ball, spec.friction), Some(torso));
        let mut links = [torso; JOINTS];
        for (leg_index, leg) in spec.legs.iter().enumerate() {
            let hip = flat(leg.hip);
            let ankle = hip + flat(leg.thigh);
            world.insert_collider(capsule(Vector::ZERO, hip), Some(torso));
            let thigh = world.insert_body(
                RigidBodyBuilder::dynamic()
                    .translation(origin + hip)
                    .can_sleep(false),
            );
            world.insert_collider(capsule(Vector::ZERO, flat(leg.thigh)), Some(thigh));
            let shin = world.insert_body(
                RigidBodyBuilder::dynamic()
                    .translation(origin + ankle)
                    .can_sleep(false),
            );
            world.insert_collider(capsule(Vector::ZERO, flat(leg.shin)), Some(shin));
            let hinge = |axis: Vector, anchor: Vector, range: [f32; 2]| {
                multibody::motor_hinge(RevoluteJointBuilder::new(axis.normalize()), anchor, range)
            };
            world.insert_multibody_joint(torso, thigh, hinge(Vector::Z, hip, spec.hip_range));
            let ankle_axis = Vector::from_array(leg.ankle_axis);
            let ankle_joint = hinge(ankle_axis, flat(leg.thigh), leg.ankle_range);
            world.insert_multibody_joint(thigh, shin, ankle_joint);
            links[2 * leg_index] = thigh;
            links[2 * leg_index + 1] = shin;
        }
        let mut robot = Self {
            world,
            torso,
            links,
            gear: spec.gear,
            ground,
            substeps: spec.substeps,
        };
        robot.configure_joints(spec);
        robot.place(spec, start);
        robot
    }

    fn multibody_mut(&mut self) -> Option<&mut Multibody> {
        multibody::multibody_mut(&mut self.world.multibody_joints, self.links[0])
    }

    fn configure_joints(&mut self, spec: &AntSpec) {
        let links = self.links;
        let Some(multibody) = self.multibody_mut() else {
            return;
        };
        let root_dofs = multibody::undamped_root(multibody, JOINTS);
        for (joint, &body) in links.iter().enumerate() {
            multibody.damping_mut()[root_dofs + joint] = spec.joint_damping;
            multibody.armature_mut()[root_dofs + joint] = spec.joint_armature;
            debug_assert_eq!(
                multibody.link(joint + 1).map(|l| l.rigid_body_handle()),
                Some(body)
            );
        }
    }

    /// Moves the flat-built ant to the rest pose, for [`Start::Noise`] plus U(-q, q) on every
    /// generalised position and qd * N(0, 1) on every generalised velocity (Gymnasium's reset
    /// noise).
    fn place(&mut self, spec: &AntSpec, start: Start) {
        let world = &mut self.world;
        let Some(multibody) = multibody::multibody_mut(&mut world.multibody_joints, self.links[0])
        else {
            return;
        };
        // Also settles the root's type: a welded (fixed) root loses its six dofs here.
        multibody.forward_kinematics(&world.bodies, true);
        let ndofs = multibody.generalized_velocity().len();
        let root_dofs = ndofs.saturating_sub(JOINTS);
        let (mut displacement, velocity): (Vec<f32>, Vec<f32>) = match start {
            Start::Noise(seed) => {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                let q = spec.position_noise;
                let displacement = (0..ndofs).map(|_| rng.random_range(-q..=q)).collect();
                let velocity = (0..ndofs)
                    .map(|_| {
                        let n: f32 = StandardNormal.sample(&mut rng);
                        spec.velocity_noise * n
                    })
                    .collect();
                (displacement, velocity)
            }
            Start::Rest | Start::Welded(_) => (vec![0.0; ndofs], vec![0.0; ndofs]),
        };
        for (leg, pair) in spec
            .legs
            .iter()
            .zip(displacement[root_dofs..].chunks_mut(2))
        {
            pair[1] += leg.ankle_rest;
        }
        multibody::displace(multibody, &mut world.bodies, &displacement, &velocity);
    }

    /// Sets the joint torques `action[i] * gear` (action already clipped).
    fn set_torques(&mut self, action: &[f32]) {
        let gear = self.gear;
        let Some(multibody) = self.multibody_mut() else {
            return;
        };
        for (joint, &a) in action.iter().enumerate().take(JOINTS) {
            let torque = a * gear;
            if let Some(link) = multibody.link_mut(joint + 1) {
                multibody::drive(link, torque);
            }
        }
    }

    /// Torso position (x, y, z).
    pub fn torso_position(&self) -> [f32; 3] {
        self.world.bodies[self.torso].translation().to_array()
    }

    /// The deepest penetration (m) of any ant collider into the ground right now (0 if none).
    pub fn ground_penetration(&self) -> f32 {
        multibody::deepest_penetration(&self.world, self.ground)
    }
}

impl RapierRobot for AntRobot {
    type Spec = AntSpec;
    const OBS_DIM: usize = OBS_DIM;

    /// The ant's dynamics are not randomised: `dynamics` is ignored.
    fn build(spec: &AntSpec, seed: u64, _dynamics: Option<&WalkerDynamics>) -> Self {
        Self::build_with(spec, Start::Noise(seed))
    }

    fn control_dt(spec: &AntSpec) -> f32 {
        spec.physics_dt * spec.substeps as f32
    }

    fn step(&mut self, action: &[f32]) {
        self.set_torques(action);
        multibody::advance(&mut self.world, self.substeps);
    }

    fn diverged(&self) -> bool {
        multibody::diverged(&self.world)
    }

    /// The 29-D observation (layout: [`obs`]).
    fn observe(&self, out: &mut [f32], velocity_clip: f32) {
        let body = &self.world.bodies[self.torso];
        let p = body.translation();
        let rotation = *body.rotation();
        // q and -q are the same orientation: the one with w >= 0 keeps the entries continuous
        // while the torso stays within 180 degrees of upright.
        let sign = if rotation.w < 0.0 { -1.0 } else { 1.0 };
        out[obs::Z] = p.z;
        out[obs::QUATERNION..obs::QUATERNION + 4]
            .copy_from_slice(&[rotation.w, rotation.x, rotation.y, rotation.z].map(|c| sign * c));
        out[obs::XY] = p.x;
        out[obs::XY + 1] = p.y;
        let Some(multibody) = multibody::multibody(&self.world.multibody_joints, self.links[0])
        else {
            return;
        };
        for joint in 0..JOINTS {
            if let Some(link) = multibody.link(joint + 1) {
                out[obs::JOINT_ANGLES + joint] = link.joint.coords()[HINGE_COORD];
            }
        }
        let velocity = multibody.generalized_velocity();
        let clip = |v: f32| v.clamp(-velocity_clip, velocity_clip);
        let root = multibody.ndofs() - JOINTS;
        if root == ROOT_DOFS {
            // The free root's generalised velocity: linear then angular, both in world axes.
            let angular = Vector::new(velocity[3], velocity[4], velocity[5]);
            let local = rotation.inverse() * angular;
            for axis in 0..3 {
                out[obs::LINEAR_VELOCITY + axis] = clip(velocity[axis]);
                out[obs::ANGULAR_VELOCITY + axis] = clip(local[axis]);
            }
        }
        for joint in 0..JOINTS {
            out[obs::JOINT_VELOCITIES + joint] = clip(velocity[root + joint]);
        }
    }

    fn torso(&self) -> TorsoPose {
        TorsoPose {
            position: self.torso_position(),
            pitch: 0.0,
        }
    }

    /// The torso disc and every capsule projected on the x-y plane, for a top view.
    fn shapes(&self) -> Vec<Shape> {
        let mut shapes = Vec::new();
        for (_, collider) in self.world.colliders.iter() {
            // From the bodies, not the colliders' own poses: those follow the bodies only at
            // the next physics step, so right after a reset they would show the built pose.
            let pose = &match (collider.parent(), collider.position_wrt_parent()) {
                (Some(body), Some(local)) => *self.world.bodies[body].position() * *local,
                _ => *collider.position(),
            };
            if let Some(ball) = collider.shape().as_ball() {
                let c = pose.translation;
                shapes.push(Shape::Circle {
                    center: [c.x, c.y],
                    radius: ball.radius,
                    role: Role::Robot,
                });
            } else if let Some(capsule) = collider.shape().as_capsule() {
                shapes.push(multibody::capsule_shape(pose, capsule));
            }
        }
        shapes
    }
}
