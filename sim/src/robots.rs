//! The two planar legged robots, one declarative function each. Dimensions, masses, ranges,
//! gears, damping and springs follow Gymnasium's `half_cheetah.xml` and `walker2d.xml`;
//! MuJoCo's joint angles are about +y (clockwise in the x-z plane), ours counter-clockwise,
//! so ranges are mirrored.

use crate::planar::{Capsule, LimbSpec, RobotSpec};

fn capsule(a: [f32; 2], b: [f32; 2], radius: f32) -> Capsule {
    Capsule { a, b, radius }
}

/// A limb from `joint` to `end` hanging from `parent` (None = torso).
#[allow(clippy::too_many_arguments)]
fn limb(
    parent: Option<usize>,
    joint: [f32; 2],
    end: [f32; 2],
    radius: f32,
    mass: f32,
    mujoco_range: [f32; 2],
    gear: f32,
    damping: f32,
    stiffness: f32,
    armature: f32,
    friction: f32,
) -> LimbSpec {
    LimbSpec {
        parent,
        joint,
        capsule: capsule(joint, end, radius),
        mass,
        range: [-mujoco_range[1], -mujoco_range[0]],
        gear,
        damping,
        stiffness,
        armature,
        friction,
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
            limb(
                None,
                [-0.5, 0.0],
                [-0.34, -0.25],
                r,
                1.54,
                [-0.52, 1.05],
                120.0,
                6.0,
                240.0,
                0.1,
                f,
            ),
            limb(
                Some(0),
                [-0.34, -0.25],
                [-0.62, -0.39],
                r,
                1.59,
                [-0.785, 0.785],
                90.0,
                4.5,
                180.0,
                0.1,
                f,
            ),
            limb(
                Some(1),
                [-0.62, -0.39],
                [-0.56, -0.58],
                r,
                1.07,
                [-0.4, 0.785],
                60.0,
                3.0,
                120.0,
                0.1,
                f,
            ),
            limb(
                None,
                [0.5, 0.0],
                [0.36, -0.24],
                r,
                1.43,
                [-1.0, 0.7],
                120.0,
                4.5,
                180.0,
                0.1,
                f,
            ),
            limb(
                Some(3),
                [0.36, -0.24],
                [0.49, -0.42],
                r,
                1.18,
                [-1.2, 0.87],
                60.0,
                3.0,
                120.0,
                0.1,
                f,
            ),
            limb(
                Some(4),
                [0.49, -0.42],
                [0.58, -0.56],
                r,
                0.85,
                [-0.5, 0.5],
                30.0,
                1.5,
                60.0,
                0.1,
                f,
            ),
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
            limb(
                hip_parent,
                [0.0, -0.2],
                [0.0, -0.65],
                0.05,
                3.93,
                bend,
                100.0,
                0.1,
                0.0,
                0.01,
                f,
            ),
            limb(
                Some(first),
                [0.0, -0.65],
                [0.0, -1.15],
                0.04,
                2.71,
                bend,
                100.0,
                0.1,
                0.0,
                0.01,
                f,
            ),
            limb(
                Some(first + 1),
                [0.0, -1.15],
                [0.2, -1.15],
                0.06,
                2.94,
                ankle,
                100.0,
                0.1,
                0.0,
                0.01,
                f,
            ),
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
