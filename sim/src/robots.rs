//! The two planar legged robots, one declarative function each. Dimensions, masses, ranges,
//! gears, damping and springs follow Gymnasium's `half_cheetah.xml` and `walker2d.xml`;
//! MuJoCo's joint angles are about +y (clockwise in the x-z plane), ours counter-clockwise,
//! so ranges are mirrored.

use crate::planar::{Capsule, LimbSpec, RobotSpec};

fn capsule(a: [f32; 2], b: [f32; 2], radius: f32) -> Capsule {
    Capsule { a, b, radius }
}

/// A limb from `joint` to `end` hanging from `parent` (None = torso), every value named;
/// `.into()` turns it into the [`LimbSpec`] the builder takes.
struct Limb {
    parent: Option<usize>,
    joint: [f32; 2],
    end: [f32; 2],
    radius: f32,
    mass: f32,
    /// MuJoCo's joint range (about +y, clockwise); mirrored into ours.
    mujoco_range: [f32; 2],
    gear: f32,
    damping: f32,
    stiffness: f32,
    armature: f32,
    friction: f32,
}

impl From<Limb> for LimbSpec {
    fn from(l: Limb) -> Self {
        LimbSpec {
            parent: l.parent,
            joint: l.joint,
            capsule: capsule(l.joint, l.end, l.radius),
            mass: l.mass,
            range: [-l.mujoco_range[1], -l.mujoco_range[0]],
            gear: l.gear,
            damping: l.damping,
            stiffness: l.stiffness,
            armature: l.armature,
            friction: l.friction,
        }
    }
}

/// HalfCheetah: torso with head, back leg (thigh, shin, foot) and front leg; control dt 0.05
/// as in Gymnasium, but as 2 physics steps of 0.025 s (Gymnasium: 5 of 0.01) because the
/// multibody mass-matrix update dominates the cost; friction 0.4.
pub(crate) fn half_cheetah() -> RobotSpec {
    let r = 0.046;
    let f = 0.4;
    RobotSpec {
        torso: vec![
            capsule([-0.5, 0.0], [0.5, 0.0], r),
            capsule([0.485, 0.003], [0.715, 0.197], r),
        ],
        torso_mass: 6.36,
        torso_friction: f,
        origin: [0.0, 0.7],
        limbs: [
            Limb {
                parent: None,
                joint: [-0.5, 0.0],
                end: [-0.34, -0.25],
                radius: r,
                mass: 1.54,
                mujoco_range: [-0.52, 1.05],
                gear: 120.0,
                damping: 6.0,
                stiffness: 240.0,
                armature: 0.1,
                friction: f,
            }
            .into(),
            Limb {
                parent: Some(0),
                joint: [-0.34, -0.25],
                end: [-0.62, -0.39],
                radius: r,
                mass: 1.59,
                mujoco_range: [-0.785, 0.785],
                gear: 90.0,
                damping: 4.5,
                stiffness: 180.0,
                armature: 0.1,
                friction: f,
            }
            .into(),
            Limb {
                parent: Some(1),
                joint: [-0.62, -0.39],
                end: [-0.56, -0.58],
                radius: r,
                mass: 1.07,
                mujoco_range: [-0.4, 0.785],
                gear: 60.0,
                damping: 3.0,
                stiffness: 120.0,
                armature: 0.1,
                friction: f,
            }
            .into(),
            Limb {
                parent: None,
                joint: [0.5, 0.0],
                end: [0.36, -0.24],
                radius: r,
                mass: 1.43,
                mujoco_range: [-1.0, 0.7],
                gear: 120.0,
                damping: 4.5,
                stiffness: 180.0,
                armature: 0.1,
                friction: f,
            }
            .into(),
            Limb {
                parent: Some(3),
                joint: [0.36, -0.24],
                end: [0.49, -0.42],
                radius: r,
                mass: 1.18,
                mujoco_range: [-1.2, 0.87],
                gear: 60.0,
                damping: 3.0,
                stiffness: 120.0,
                armature: 0.1,
                friction: f,
            }
            .into(),
            Limb {
                parent: Some(4),
                joint: [0.49, -0.42],
                end: [0.58, -0.56],
                radius: r,
                mass: 0.85,
                mujoco_range: [-0.5, 0.5],
                gear: 30.0,
                damping: 1.5,
                stiffness: 60.0,
                armature: 0.1,
                friction: f,
            }
            .into(),
        ],
        physics_dt: 0.025,
        substeps: 2,
        solver_iterations: 2,
        position_noise: 0.1,
        velocity_noise: 0.1,
        uniform_velocity_noise: false,
    }
}

/// Walker2d: vertical torso, two legs (thigh, leg, foot); control dt 0.008 as in Gymnasium,
/// as one physics step (Gymnasium: 4 of 0.002); friction 0.9, gears 100.
pub(crate) fn walker() -> RobotSpec {
    let f = 0.9;
    let bend = [-2.618, 0.0];
    let ankle = [-0.785, 0.785];
    let leg = |hip_parent: Option<usize>, first: usize| {
        [
            Limb {
                parent: hip_parent,
                joint: [0.0, -0.2],
                end: [0.0, -0.65],
                radius: 0.05,
                mass: 3.93,
                mujoco_range: bend,
                gear: 100.0,
                damping: 0.1,
                stiffness: 0.0,
                armature: 0.01,
                friction: f,
            }
            .into(),
            Limb {
                parent: Some(first),
                joint: [0.0, -0.65],
                end: [0.0, -1.15],
                radius: 0.04,
                mass: 2.71,
                mujoco_range: bend,
                gear: 100.0,
                damping: 0.1,
                stiffness: 0.0,
                armature: 0.01,
                friction: f,
            }
            .into(),
            Limb {
                parent: Some(first + 1),
                joint: [0.0, -1.15],
                end: [0.2, -1.15],
                radius: 0.06,
                mass: 2.94,
                mujoco_range: ankle,
                gear: 100.0,
                damping: 0.1,
                stiffness: 0.0,
                armature: 0.01,
                friction: f,
            }
            .into(),
        ]
    };
    let [r0, r1, r2] = leg(None, 0);
    let [l0, l1, l2] = leg(None, 3);
    RobotSpec {
        torso: vec![capsule([0.0, 0.2], [0.0, -0.2], 0.05)],
        torso_mass: 3.53,
        torso_friction: f,
        origin: [0.0, 1.25],
        limbs: [r0, r1, r2, l0, l1, l2],
        physics_dt: 0.008,
        substeps: 1,
        solver_iterations: 4,
        position_noise: 5e-3,
        velocity_noise: 5e-3,
        uniform_velocity_noise: true,
    }
}
