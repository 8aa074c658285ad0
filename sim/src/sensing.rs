//! What each observation component physically is, for a device that measures positions only
//! and estimates the rest (firmware-sim's `--sensing positions`).
//!
//! The families own this knowledge (each declares its table in its spec, the robots' shared
//! layouts sit with the robots: `planar::OBS_COMPONENTS`, `ant::OBS_COMPONENTS`): a velocity entry is the time derivative of a position or
//! angle entry of the same observation, and a position-sensing device (encoders, a tracker)
//! can reconstruct it by filtering that position over the control step. An entry that is the
//! derivative of something the observation does not contain (the cheetah's and walker's
//! torso forward velocity: the torso x is never observed) cannot be reconstructed from the
//! observation's positions; such entries are [`ObsComponent::Direct`]: measured directly (a
//! ground-speed or optical-flow sensor) and passed through with the same noise and ADC as the
//! positions.

use infer_core::Channel;

/// The physical meaning of one observation entry: the device estimator's own [`Channel`] (a
/// measured position or angle, the rate of another entry, or a quantity measured directly), so
/// a family's table is what the filter reads, with no translation between them. For
/// point-goal a rate's `scale` is `1 / (1 + LINEAR_DAMPING * CONTROL_DT)`: its observed
/// velocity is the one after the step's damping, not the one that moved the point.
pub type ObsComponent = Channel;

/// `ObsComponent::Rate { of, scale: 1.0 }`: the rate of entry `of` at the control step's scale.
pub(crate) const fn rate(of: usize) -> ObsComponent {
    ObsComponent::Rate { of, scale: 1.0 }
}

#[cfg(test)]
mod tests {
    use crate::env::make_env;
    use crate::family::EnvConfig;
    use crate::family::Family;
    use crate::family::Task;
    use infer_core::Channel::{Angle, Position, Rate};
    use std::f32::consts::{PI, TAU};

    #[test]
    fn every_rate_names_a_measured_position_of_the_same_observation() {
        for family in Family::BUILTIN {
            let components = family.obs_components();
            assert_eq!(components.len(), family.obs_dim(), "{family}");
            for (i, c) in components.iter().enumerate() {
                if let Rate { of, .. } = *c {
                    assert!(
                        matches!(components.get(of), Some(Position | Angle)),
                        "{family}: entry {i} is the rate of {of}, not a position"
                    );
                }
            }
        }
    }

    /// Rolls `family` out with a deterministic excitation and returns, per rate entry, the
    /// mean |scale * finite difference of its position - declared rate| divided by the mean
    /// |declared rate|. Steps that start or end with a clipped velocity (walker: +-10) are
    /// left out: the finite difference is not clipped.
    fn rate_mismatch(family: Family, task: &Task, steps: usize) -> Vec<(usize, f32)> {
        let mut env = make_env(
            family,
            EnvConfig {
                physics: Default::default(),
                horizon: Some(steps),
                healthy_termination: false,
            },
        )
        .unwrap();
        let dt = env.control_dt();
        let components = family.obs_components();
        let mut previous = env.reset(task, 3).unwrap().to_vec();
        let mut sums = vec![(0.0f64, 0.0f64); components.len()];
        for step in 0..steps {
            let action: Vec<f32> = (0..family.act_dim())
                .map(|j| 0.8 * (0.3 * step as f32 + j as f32).sin())
                .collect();
            let t = env.step(&action).unwrap();
            for (i, c) in components.iter().enumerate() {
                let Rate { of, scale } = *c else { continue };
                let rate = t.obs[i];
                if rate.abs().max(previous[i].abs()) >= 9.99 {
                    continue;
                }
                let mut delta = t.obs[of] - previous[of];
                if components[of] == Angle {
                    delta = (delta + PI).rem_euclid(TAU) - PI;
                }
                sums[i].0 += f64::from((scale * delta / dt - rate).abs());
                sums[i].1 += f64::from(rate.abs());
            }
            previous.copy_from_slice(t.obs);
        }
        sums.iter()
            .enumerate()
            .filter(|(_, s)| s.1 > 0.0)
            .map(|(i, s)| (i, (s.0 / s.1) as f32))
            .collect()
    }

    #[test]
    fn declared_rates_are_the_derivatives_of_their_positions() {
        // Point-goal integrates once per control step: exact. The legged robots integrate
        // over substeps with contacts and implicit joint damping: the finite difference over
        // the control step is the step's mean velocity, not the final one (measured 0.07 to
        // 0.44 relative; an entry paired with the wrong position is above 1).
        for (family, task, bound) in [
            (Family::POINT_GOAL, Task::point_goal(0.5), 1e-3),
            (Family::CHEETAH_VEL, Task::cheetah_vel(1.0), 0.5),
            (Family::WALKER_DYN, Family::WALKER_DYN.test_tasks()[0], 0.5),
            (Family::ANT_GOAL, Family::ANT_GOAL.test_tasks()[0], 0.5),
            (
                Family::ANT_LINCLASS,
                Family::ANT_LINCLASS.test_tasks()[0],
                0.5,
            ),
        ] {
            let mismatch = rate_mismatch(family, &task, 200);
            assert_eq!(
                mismatch.len(),
                family
                    .obs_components()
                    .iter()
                    .filter(|c| !c.is_measured())
                    .count()
            );
            for (i, m) in mismatch {
                assert!(m < bound, "{family} entry {i}: relative mismatch {m}");
            }
        }
    }
}
