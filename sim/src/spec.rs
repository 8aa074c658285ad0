//! The helpers the built-in families' declarations share (the goal families' angles, seeds
//! from numbers, the legged robots' filter default). A declaration itself is a
//! [`crate::FamilySpec`] (`family.rs`) written in the family's own module (`point_goal.rs`,
//! `cheetah_vel.rs`, `walker_dyn.rs`, `ant_goal.rs`, `ant_linclass.rs`); every other crate reads
//! its fields instead of matching on family names.

use std::f32::consts::PI;

use crate::family::Task;

const GOAL_TRAIN: usize = 32;
const GOAL_TEST: usize = 16;

/// Goal angles of the meta-train split: k pi/16.
pub(crate) fn goal_train_angles() -> impl Iterator<Item = f32> {
    (0..GOAL_TRAIN).map(|k| k as f32 * PI / 16.0)
}

/// Goal angles of the meta-test split: 2n pi/16 + pi/32.
pub(crate) fn goal_test_angles() -> impl Iterator<Item = f32> {
    (0..GOAL_TEST).map(|n| 2.0 * n as f32 * PI / 16.0 + PI / 32.0)
}

/// The goal families' task parameter: the goal's (x, y).
pub(crate) fn write_goal(task: &Task, out: &mut [f32]) {
    out.copy_from_slice(&task.goal().unwrap_or_default());
}

/// A seed from a number: a non-negative integer within `u32`.
pub(crate) fn seed_of(value: f64) -> Option<u64> {
    (value >= 0.0 && value.fract() == 0.0 && value <= u32::MAX as f64).then_some(value as u64)
}

/// The legged robots' filter default: joints accelerate fast.
pub(crate) const LEGGED_ACCEL_STD: f32 = 50.0;
