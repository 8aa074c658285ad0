//! What the Rapier robots do the same way in 2-D and 3-D: their world and ground, the motors'
//! torque, the initial displacement, stepping, divergence, ground penetration and drawing a
//! capsule. rapier2d and rapier3d are one source built twice, with distinct types, so no
//! generic function spans both: this file is compiled twice in the same way, as a child module
//! of `planar.rs` (over rapier2d) and of `ant.rs` (over rapier3d), each naming its crate
//! `rapier` for it. It is declared nowhere else.

use super::rapier::prelude::*;

use crate::render::{Role, Shape};

/// A fresh world stepping `dt` seconds with `solver_iterations` solver substeps and ground
/// contacts of `contact_softness` (natural frequency Hz, damping ratio), holding the fixed
/// `ground` collider with its body at `ground_at`; returns the ground's collider too.
pub(super) fn world_on_ground(
    dt: f32,
    solver_iterations: usize,
    contact_softness: [f32; 2],
    ground: ColliderBuilder,
    ground_at: Vector,
) -> (PhysicsWorld, ColliderHandle) {
    let mut world = PhysicsWorld::new();
    world.integration_parameters.dt = dt;
    world.integration_parameters.num_solver_iterations = solver_iterations;
    let [frequency, damping_ratio] = contact_softness;
    let softness = SpringCoefficients::new(frequency, damping_ratio);
    world.integration_parameters.contact_softness = softness;
    world.integration_parameters.static_contact_softness = softness;
    let (_, ground) = world.insert(RigidBodyBuilder::fixed().translation(ground_at), ground);
    (world, ground)
}

/// `collider` with `friction`, combined with the other collider's by taking the larger, as
/// MuJoCo combines frictions.
pub(super) fn mujoco_friction(collider: ColliderBuilder, friction: f32) -> ColliderBuilder {
    collider
        .friction(friction)
        .friction_combine_rule(CoefficientCombineRule::Max)
}

/// A torque-driven hinge about `axis`'s joint builder with `range`, anchored at `anchor` on
/// the parent and the child's origin, its motor idle (a force-based velocity motor, gain 0,
/// no force yet: [`drive`] sets the torque).
pub(super) fn motor_hinge(
    hinge: RevoluteJointBuilder,
    anchor: Vector,
    range: [f32; 2],
) -> RevoluteJointBuilder {
    hinge
        .local_anchor1(anchor)
        .local_anchor2(Vector::ZERO)
        .limits(range)
        .motor_model(MotorModel::ForceBased)
        .motor_velocity(0.0, 0.0)
        .motor_max_force(0.0)
}

/// The multibody every joint of the robot whose first link is `first_link` belongs to.
pub(super) fn multibody(
    joints: &MultibodyJointSet,
    first_link: RigidBodyHandle,
) -> Option<&Multibody> {
    joints
        .get(MultibodyJointHandle(first_link.0))
        .map(|(mb, _)| mb)
}

/// [`multibody`], to change.
pub(super) fn multibody_mut(
    joints: &mut MultibodyJointSet,
    first_link: RigidBodyHandle,
) -> Option<&mut Multibody> {
    joints
        .get_mut(MultibodyJointHandle(first_link.0))
        .map(|(mb, _)| mb)
}

/// Turns the multibody's self-contacts off and takes Rapier's damping off its root's dofs
/// (MuJoCo's root joints have none; Rapier gives a free angular dof 0.1); returns how many
/// dofs the root has, the `joints` actuated ones following them.
pub(super) fn undamped_root(multibody: &mut Multibody, joints: usize) -> usize {
    // A welded root turns fixed (0 dofs) only at the first step: count what is there now.
    let root_dofs = multibody.ndofs() - joints;
    multibody.set_self_contacts_enabled(false);
    for dof in 0..root_dofs {
        multibody.damping_mut()[dof] = 0.0;
    }
    root_dofs
}

/// Sets `link`'s joint motor to exactly `torque`: aimed at +-1e9 with gain 0, the motor always
/// saturates at its maximum force `|torque|` (the way Rapier's MJCF loader applies torques).
pub(super) fn drive(link: &mut MultibodyLink, torque: f32) {
    let target = if torque >= 0.0 { 1.0e9 } else { -1.0e9 };
    link.joint
        .data
        .set_motor_velocity(JointAxis::AngX, target, 0.0)
        .set_motor_max_force(JointAxis::AngX, torque.abs());
}

/// Moves `multibody` by the generalised `displacement` from its current pose, gives it the
/// generalised `velocity`, and moves its bodies there.
pub(super) fn displace(
    multibody: &mut Multibody,
    bodies: &mut RigidBodySet,
    displacement: &[f32],
    velocity: &[f32],
) {
    multibody.apply_displacements(displacement);
    multibody
        .generalized_velocity_mut()
        .copy_from_slice(velocity);
    multibody.forward_kinematics(bodies, false);
    multibody.update_rigid_bodies(bodies, true);
}

/// Advances one control step: `substeps` physics steps.
pub(super) fn advance(world: &mut PhysicsWorld, substeps: usize) {
    for _ in 0..substeps {
        world.step();
    }
}

/// True if any body's position or velocity is non-finite.
pub(super) fn diverged(world: &PhysicsWorld) -> bool {
    world.bodies.iter().any(|(_, body)| {
        !(body.translation().is_finite() && body.linvel().is_finite() && body.angvel().is_finite())
    })
}

/// The deepest penetration (m) of any collider into collider `ground` over its current
/// contact manifolds (0 if none): what the fidelity probe compares with MuJoCo's contact
/// distances.
pub(super) fn deepest_penetration(world: &PhysicsWorld, ground: ColliderHandle) -> f32 {
    world
        .narrow_phase
        .contact_pairs_with(ground)
        .flat_map(|pair| pair.manifolds().iter())
        .flat_map(|manifold| manifold.points.iter())
        .map(|point| -point.dist)
        .fold(0.0, f32::max)
}

/// `capsule` placed at `pose`, drawn in the plane of the world's first two axes (the planar
/// robots' side view, the ant's top view).
pub(super) fn capsule_shape(pose: &Pose, capsule: &Capsule) -> Shape {
    let a = *pose * capsule.segment.a;
    let b = *pose * capsule.segment.b;
    Shape::Capsule {
        a: [a.x, a.y],
        b: [b.x, b.y],
        radius: capsule.radius,
        role: Role::Robot,
    }
}
