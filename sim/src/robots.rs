//! The two planar legged robots, one declarative function each. Dimensions, masses (as
//! MuJoCo 4.0 compiles them), ranges, gears, damping and springs follow Gymnasium's
//! `half_cheetah.xml` and `walker2d.xml`. Rapier's angles are counter-clockwise in the x-z
//! plane; a MuJoCo hinge about +y (the cheetah's) turns clockwise, one about -y (the
//! walker's) counter-clockwise, so each limb names its hinge axis and the robot converts:
//! observations and actions are in MuJoCo's joint coordinates. Measured against MuJoCo
//! itself in `docs/FIDELITY.md`.

use crate::planar::{Capsule, LimbSpec, RobotSpec};

/// The cheetah's ground-contact softness (natural frequency Hz, damping ratio), calibrated on
/// the fidelity probe's drop test against MuJoCo's penetration (12 mm; solref 0.02 s, solimp
/// 0 / 0.8 / 0.01): Rapier's default (60 Hz, 10) let it sink 42 mm (`docs/FIDELITY.md`).
const CHEETAH_CONTACT_SOFTNESS: [f32; 2] = [120.0, 1.0];
/// The walker's: Rapier's default, which no setting tried (30-240 Hz, ratio 1-10, 1-4
/// substeps) brought closer to MuJoCo's drop and divergence figures (`docs/FIDELITY.md`).
const WALKER_CONTACT_SOFTNESS: [f32; 2] = [60.0, 10.0];

fn capsule(a: [f32; 2], b: [f32; 2], radius: f32) -> Capsule {
    Capsule { a, b, radius }
}

/// A limb from `joint` to `end` hanging from `parent` (None = torso), every value named;
/// `LimbSpec::from` turns it into the [`LimbSpec`] the builder takes. Copy, so that a limb can
/// state only what differs from another (`Limb { mass, ..thigh }`).
#[derive(Clone, Copy)]
struct Limb {
    parent: Option<usize>,
    joint: [f32; 2],
    end: [f32; 2],
    radius: f32,
    mass: f32,
    /// The y component of MuJoCo's hinge axis: +1 (`axis="0 1 0"`) or -1 (`"0 -1 0"`).
    mujoco_axis_y: f32,
    /// MuJoCo's joint range, about that axis.
    mujoco_range: [f32; 2],
    gear: f32,
    damping: f32,
    stiffness: f32,
    armature: f32,
    friction: f32,
}

impl From<Limb> for LimbSpec {
    fn from(l: Limb) -> Self {
        // About +y MuJoCo's angle is clockwise: minus ours, and its range mirrored.
        let sign = -l.mujoco_axis_y;
        let [low, high] = l.mujoco_range.map(|a| sign * a);
        LimbSpec {
            parent: l.parent,
            joint: l.joint,
            capsule: capsule(l.joint, l.end, l.radius),
            mass: l.mass,
            range: [low.min(high), low.max(high)],
            sign,
            mujoco_range: l.mujoco_range,
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
// A robot is one declaration where every body, joint and value is named beside its source in
// half_cheetah.xml (the rapier examples' style), not a procedure.
pub(crate) fn half_cheetah() -> RobotSpec {
    // half_cheetah.xml's hinges turn about +y.
    const AXIS_Y: f32 = 1.0;
    let r = 0.046;
    let f = 0.4;
    // Every limb has bthigh's radius, hinge axis, armature and friction (the default class's);
    // the others state their own place (parent, joint position, end), mass, range, gear,
    // damping and stiffness.
    let bthigh = Limb {
        parent: None,
        joint: [-0.5, 0.0],
        end: [-0.34, -0.25],
        radius: r,
        mass: 1.544,
        mujoco_axis_y: AXIS_Y,
        mujoco_range: [-0.52, 1.05],
        gear: 120.0,
        damping: 6.0,
        stiffness: 240.0,
        armature: 0.1,
        friction: f,
    };
    let bshin = Limb {
        parent: Some(0),
        joint: [-0.34, -0.25],
        end: [-0.62, -0.39],
        mass: 1.587,
        mujoco_range: [-0.785, 0.785],
        gear: 90.0,
        damping: 4.5,
        stiffness: 180.0,
        ..bthigh
    };
    let bfoot = Limb {
        parent: Some(1),
        joint: [-0.62, -0.39],
        end: [-0.56, -0.58],
        mass: 1.095,
        mujoco_range: [-0.4, 0.785],
        gear: 60.0,
        damping: 3.0,
        stiffness: 120.0,
        ..bthigh
    };
    let fthigh = Limb {
        parent: None,
        joint: [0.5, 0.0],
        end: [0.36, -0.24],
        mass: 1.438,
        mujoco_range: [-1.0, 0.7],
        gear: 120.0,
        damping: 4.5,
        stiffness: 180.0,
        ..bthigh
    };
    let fshin = Limb {
        parent: Some(3),
        joint: [0.36, -0.24],
        end: [0.49, -0.42],
        mass: 1.201,
        mujoco_range: [-1.2, 0.87],
        gear: 60.0,
        damping: 3.0,
        stiffness: 120.0,
        ..bthigh
    };
    let ffoot = Limb {
        parent: Some(4),
        joint: [0.49, -0.42],
        end: [0.58, -0.56],
        mass: 0.885,
        mujoco_range: [-0.5, 0.5],
        gear: 30.0,
        damping: 1.5,
        stiffness: 60.0,
        ..bthigh
    };
    RobotSpec {
        torso: vec![
            capsule([-0.5, 0.0], [0.5, 0.0], r),
            capsule([0.485, 0.003], [0.715, 0.197], r),
        ],
        torso_mass: 6.25,
        torso_friction: f,
        // The floor takes the default class's friction too.
        ground_friction: f,
        contact_softness: CHEETAH_CONTACT_SOFTNESS,
        origin: [0.0, 0.7],
        limbs: [bthigh, bshin, bfoot, fthigh, fshin, ffoot].map(LimbSpec::from),
        physics_dt: 0.025,
        substeps: 2,
        solver_iterations: 2,
        position_noise: 0.1,
        velocity_noise: 0.1,
        uniform_velocity_noise: false,
    }
}

/// Walker2d as the original gym's `walker2d.xml` (the SMILe authors' walker): vertical torso,
/// two legs (thigh, leg, foot), hinges about -y (knees fold backwards), masses from density
/// 1000, friction 0.9 but 1.9 on the left foot (as that file has it; the floor 0.7), gears 100;
/// control dt 0.01 as the authors' walker (frame skip 5 of 0.002 s; Gymnasium's v5 takes 4),
/// here one physics step of 4 solver substeps.
pub(crate) fn walker() -> RobotSpec {
    // walker2d.xml's hinges turn about -y.
    const AXIS_Y: f32 = -1.0;
    let f = 0.9;
    let left_foot = 1.9;
    let bend = [-2.618, 0.0];
    let ankle = [-0.785, 0.785];
    let leg = |hip_parent: Option<usize>, first: usize, foot_friction: f32| {
        // The leg and foot have the thigh's hinge (axis, range, gear, damping, stiffness,
        // armature) and friction; they state their own place, radius and mass, the foot its
        // range and friction.
        let thigh = Limb {
            parent: hip_parent,
            joint: [0.0, -0.2],
            end: [0.0, -0.65],
            radius: 0.05,
            mass: 4.058,
            mujoco_axis_y: AXIS_Y,
            mujoco_range: bend,
            gear: 100.0,
            damping: 0.1,
            stiffness: 0.0,
            armature: 0.01,
            friction: f,
        };
        let leg = Limb {
            parent: Some(first),
            joint: [0.0, -0.65],
            end: [0.0, -1.15],
            radius: 0.04,
            mass: 2.781,
            ..thigh
        };
        let foot = Limb {
            parent: Some(first + 1),
            joint: [0.0, -1.15],
            end: [0.2, -1.15],
            radius: 0.06,
            mass: 3.167,
            mujoco_range: ankle,
            friction: foot_friction,
            ..thigh
        };
        [thigh, leg, foot].map(LimbSpec::from)
    };
    let [r0, r1, r2] = leg(None, 0, f);
    let [l0, l1, l2] = leg(None, 3, left_foot);
    RobotSpec {
        torso: vec![capsule([0.0, 0.2], [0.0, -0.2], 0.05)],
        torso_mass: 3.665,
        torso_friction: f,
        ground_friction: 0.7,
        contact_softness: WALKER_CONTACT_SOFTNESS,
        origin: [0.0, 1.25],
        limbs: [r0, r1, r2, l0, l1, l2],
        physics_dt: 0.01,
        substeps: 1,
        solver_iterations: 4,
        position_noise: 5e-3,
        velocity_noise: 5e-3,
        uniform_velocity_noise: true,
    }
}
