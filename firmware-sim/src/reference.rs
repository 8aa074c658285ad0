//! A hand-built reference policy, for tests and demos of the device path before (or beside)
//! a trained one: written through infer-core's real writer, so it exercises the real format
//! and quantization. It is not learned and never stands in for a trained policy's results.

use infer_core::{Activation, FloatLayer, FloatModel, ModelKind};

/// A hand-built, expert-quality context-conditioned point-goal policy, written through the
/// blob writer (so it exercises the real format and quantization):
/// - encoder: r = s'_xy - s_xy (per-step displacement), mean over the demo's 100 steps;
/// - head: z = 100 * r = the demo's total displacement = goal - demo start (about the goal);
/// - policy: pre-tanh action = kp (z - p) - kd v, the PD expert with z as its goal.
///
/// point-goal only (obs 4, act 2, horizon 100). The 100 assumes unsubsampled 100-step demos.
pub fn pd_point_goal_model() -> FloatModel {
    let (kp, kd) = (2.0, 1.0);
    let layer = |in_dim: usize, out_dim: usize, weights: Vec<f32>| FloatLayer {
        in_dim,
        out_dim,
        weights,
        bias: vec![0.0; out_dim],
        activation: Activation::Identity,
    };
    #[rustfmt::skip]
    let encoder = layer(10, 2, vec![
        -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0,
        0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0,
    ]);
    #[rustfmt::skip]
    let policy = layer(6, 2, vec![
        -kp, 0.0, -kd, 0.0, kp, 0.0,
        0.0, -kp, 0.0, -kd, 0.0, kp,
    ]);
    FloatModel {
        kind: ModelKind::StateAction,
        obs_dim: 4,
        act_dim: 2,
        r_dim: 2,
        z_dim: 2,
        obs_mean: vec![0.0; 4],
        obs_std: vec![1.0; 4],
        act_scale: vec![1.0; 2],
        act_offset: vec![0.0; 2],
        encoder: vec![encoder],
        z_head: vec![layer(2, 2, vec![100.0, 0.0, 0.0, 100.0])],
        policy: vec![policy],
    }
}

/// w8a8 calibration data from point-goal demos: each demo is one single-trajectory context
/// of raw `[s, a, s']` rows, and its states are the observations.
pub fn point_goal_calibration(demos: &[&sim::Trajectory]) -> infer_core::Calibration {
    let mut calibration = infer_core::Calibration::default();
    for demo in demos {
        let rows = (0..demo.len())
            .filter_map(|i| demo.transition(i, 4, 2))
            .map(|t| [t.obs, t.action, t.next_obs].concat());
        calibration.contexts.push(vec![rows.collect()]);
        calibration
            .observations
            .extend(demo.obs.chunks(4).map(<[f32]>::to_vec));
    }
    calibration
}

/// The reference policy as blob bytes, calibrated on `demos`.
pub fn pd_point_goal_blob(
    quant: infer_core::Quant,
    demos: &[&sim::Trajectory],
) -> Result<Vec<u8>, infer_core::Error> {
    infer_core::write_blob(
        &pd_point_goal_model(),
        quant,
        &point_goal_calibration(demos),
    )
}

/// The `firmware-sim run` arguments that run `blob` on the device, taught the demo of point-goal
/// test task 3 from `demos`, writing to `out` (what `examples/pd_blob.rs` prints; paths are
/// shown as given, so they must not contain spaces).
pub fn pd_run_args(
    blob: &std::path::Path,
    demos: &std::path::Path,
    out: &std::path::Path,
) -> Vec<String> {
    [
        "run",
        "--blob",
        &blob.display().to_string(),
        "--env",
        "point-goal",
        "--task",
        "3",
        "--context",
        &demos.display().to_string(),
        "-o",
        &out.display().to_string(),
    ]
    .map(String::from)
    .to_vec()
}
