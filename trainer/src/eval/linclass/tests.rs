use super::*;
use sim::{TaskDemos, TransitionRef};

const OBS: usize = sim::ant_linclass::OBS_DIM;

/// A two-transition demo of the pair (first, second) whose torso ends at `x`.
fn demo(first: &[f32; POINT_DIM], second: &[f32; POINT_DIM], x: f32, seed: u64) -> Trajectory {
    let mut obs = [0.0f32; OBS];
    obs[FIRST_POINT..SECOND_POINT].copy_from_slice(first);
    obs[SECOND_POINT..].copy_from_slice(second);
    let mut next = obs;
    let mut tr = Trajectory::new(seed);
    for (t, xt) in [(0u32, 0.0f32), (25, x)] {
        next[TORSO_X] = xt;
        tr.push(
            t,
            TransitionRef {
                obs: &obs,
                action: &[0.0; 8],
                reward: 0.0,
                next_obs: &next,
                done: false,
            },
        );
    }
    tr
}

/// Test-split contexts of 16 demos per task by a perfect expert (ends at x = +-1.5); the
/// first `flip` demos of every task walk the other way.
fn contexts(flip: usize) -> DemoDataset {
    let mut ds = DemoDataset::new(Family::ANT_LINCLASS, Split::Test, "synthetic");
    for task in Family::ANT_LINCLASS.test_tasks() {
        let (hseed, normal) = hyperplane(&task).unwrap();
        let trajectories = (0..16u64)
            .map(|j| {
                let (a, b, first_positive) = draw_pair(&normal, hseed, 500 + j);
                let right = if first_positive { 1.5 } else { -1.5 };
                demo(
                    &a,
                    &b,
                    if (j as usize) < flip { -right } else { right },
                    500 + j,
                )
            })
            .collect();
        ds.tasks.push(TaskDemos { task, trajectories });
    }
    ds
}

#[test]
fn a_demo_shows_the_side_it_walked_to_and_the_truth() {
    let task = Family::ANT_LINCLASS.test_tasks()[0];
    let (hseed, normal) = hyperplane(&task).unwrap();
    let (a, b, first_positive) = draw_pair(&normal, hseed, 3);
    let walked = demo(&a, &b, if first_positive { 1.4 } else { -1.4 }, 3);
    let label = demo_label(&walked, &normal, OBS).unwrap();
    assert_eq!(label.first_positive, first_positive);
    assert_eq!(label.shown, Some(first_positive));
    assert_eq!(label.first, a.map(f64::from));
    let pts = label.labelled_points();
    assert_eq!(pts.len(), 2);
    // Both labelled points lie on their label's side of the true hyperplane.
    let w = normal.map(f64::from);
    assert!(pts.iter().all(|(p, y)| y * dot(&w, p) > 0.0));
    // A demo that stayed near the start shows nothing.
    let stayed = demo(&a, &b, 0.1, 3);
    assert_eq!(demo_label(&stayed, &normal, OBS).unwrap().shown, None);
    assert!(
        demo_label(&stayed, &normal, OBS)
            .unwrap()
            .labelled_points()
            .is_empty()
    );
    // Wrong widths and empty demos are errors, not panics.
    assert!(demo_label(&stayed, &normal, OBS - 1).is_err());
    assert!(demo_label(&Trajectory::new(0), &normal, OBS).is_err());
}

#[test]
fn the_rules_separate_what_is_separable() {
    let w: Point = [0.5, -0.5, 0.5, 0.5];
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let pts: Vec<(Point, f64)> = (0..60)
        .map(|_| {
            let p: Point = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
            let y = if dot(&w, &p) > 0.0 { 1.0 } else { -1.0 };
            (p, y)
        })
        .collect();
    let svm = svm_normal(&pts);
    assert!(pts.iter().all(|(p, y)| y * dot(&svm, p) > 0.0), "{svm:?}");
    let cos = |v: &Point| dot(v, &w) / dot(v, v).sqrt();
    assert!(cos(&svm) > 0.95, "{}", cos(&svm));
    assert!(cos(&centroid_normal(&pts)) > 0.8);
    let prior = PriorSamples::new(20_000, 1);
    let posterior = prior.consistent(&pts);
    assert!(!posterior.is_empty() && posterior.len() < 2_000);
    assert!(posterior.iter().all(|v| cos(v) > 0.8));
    // No points: an SVM of zeros (every pair a tie) and the whole prior.
    assert_eq!(svm_normal(&[]), [0.0; POINT_DIM]);
    assert_eq!(prior.consistent(&[]).len(), 20_000);
    let (a, b) = ([1.0, 0.0, 0.0, 0.0], [-1.0, 0.0, 0.0, 0.0]);
    assert_eq!(linear_score(&[0.0; POINT_DIM], &a, &b, true), 0.5);
    assert_eq!(linear_score(&[1.0, 0.0, 0.0, 0.0], &a, &b, true), 1.0);
    assert_eq!(linear_score(&[1.0, 0.0, 0.0, 0.0], &a, &b, false), 0.0);
    assert_eq!(bayes_first_positive(&[], &a, &b), None);
    assert_eq!(bayes_score(&[], &a, &b, true), 0.5);
    assert_eq!(
        bayes_first_positive(&[[1.0, 0.0, 0.0, 0.0]], &a, &b),
        Some(1.0)
    );
}

#[test]
fn the_bound_grows_with_the_context_and_counts_what_the_demos_hide() {
    let setup = BoundSetup {
        sizes: vec![1, 16],
        draws: 2,
        rollouts: 5,
        fresh_pairs: 20,
    };
    let prior = PriorSamples::new(50_000, 2);
    let rows = information_bound(&contexts(0), Split::Test, &setup, &prior).unwrap();
    assert_eq!(rows.len(), 2);
    let (one, all) = (&rows[0], &rows[1]);
    assert_eq!(
        (one.contexts, one.eval_pairs.pairs, one.fresh_pairs.pairs),
        (64, 320, 1280)
    );
    assert_eq!((all.demos_without_side, all.demos_mislabelled), (0, 0));
    assert!(
        one.fresh_pairs.bayes > 0.55 && one.fresh_pairs.bayes < 0.9,
        "{one:?}"
    );
    assert!(all.fresh_pairs.bayes > 0.9, "{all:?}");
    assert!(
        all.fresh_pairs.svm > 0.85 && all.fresh_pairs.centroid > 0.8,
        "{all:?}"
    );
    // At 16 demos a context's posterior is a small cap of the sphere (the shipped run's
    // smallest held 37 of 2^20 prior samples): 50k samples leave some contexts none, most not.
    assert!(all.median_posterior_samples > 0, "{all:?}");
    assert!(one.min_posterior_samples > 0, "{one:?}");
    // Demos that walk the wrong way are counted (and can empty the posterior: a tie).
    let noisy = information_bound(&contexts(2), Split::Test, &setup, &prior).unwrap();
    assert_eq!(noisy[1].demos_mislabelled, 2 * 32 * 2);
    // Other families' data are refused.
    let other = DemoDataset::new(Family::POINT_GOAL, Split::Test, "x");
    assert!(information_bound(&other, Split::Test, &setup, &prior).is_err());
    assert!(visibility(&other).is_err());
}

#[test]
fn visibility_reads_the_side_per_time_step() {
    let (rows, clear) = visibility(&contexts(0)).unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!((rows[0].time_step, rows[1].time_step), (0, 25));
    assert_eq!(rows[0].x_clearly_correct, 0.0);
    assert_eq!(rows[1].x_on_correct_side, 1.0);
    assert!((rows[1].median_signed_x - 1.5).abs() < 1e-6);
    assert!((clear - 0.5).abs() < 1e-9);
    // The synthetic demos' actions are all zero: they tell nothing apart.
    assert_eq!(rows[0].action_gap, 0.0);
    assert!(rows[0].action_side_accuracy < 0.6);
}

#[test]
fn the_nearest_centroid_tells_separated_actions_apart() {
    let (a, b, c, d) = ([1.0f32, 0.0], [0.9f32, 0.1], [-1.0f32, 0.0], [-0.8f32, 0.0]);
    let rows = [
        (true, &a[..]),
        (true, &b[..]),
        (false, &c[..]),
        (false, &d[..]),
    ];
    let (accuracy, gap) = nearest_centroid(&rows);
    assert_eq!(accuracy, 1.0);
    assert!((gap - (0.95f64 + 0.9).hypot(0.05)).abs() < 1e-6, "{gap}");
    assert!(nearest_centroid(&rows[..3]).0.is_nan());
    assert!(nearest_centroid(&[]).0.is_nan());
}

#[test]
fn the_probe_scores_decisions_from_a_latent_that_is_the_normal() {
    let rows_of = |noise: bool| -> Vec<LatentRow> {
        Family::ANT_LINCLASS
            .test_tasks()
            .iter()
            .flat_map(|task| {
                let (_, normal) = hyperplane(task).unwrap();
                (0..2).map(move |d| LatentRow {
                    task: task.label(),
                    value: task.value(),
                    context_size: 4,
                    draw: d,
                    parameter: normal.to_vec(),
                    z: if noise {
                        let s = task.value() as f32 * 0.37 + d as f32;
                        vec![s.sin(), (2.0 * s).cos(), (3.0 * s).sin()]
                    } else {
                        vec![normal[0], normal[1], normal[2], normal[3], 0.3]
                    },
                })
            })
            .collect()
    };
    let coded = probe_decisions(&rows_of(false), 5).unwrap();
    assert_eq!(coded.len(), 1);
    assert_eq!(coded[0].rows, 64);
    assert!(
        coded[0].pair_accuracy > 0.9 && coded[0].mean_cosine > 0.9,
        "{coded:?}"
    );
    let noise = probe_decisions(&rows_of(true), 5).unwrap();
    assert!(
        noise[0].pair_accuracy < 0.75 && noise[0].mean_r2 < 0.3,
        "{noise:?}"
    );
    assert!(probe_decisions(&[], 5).unwrap().is_empty());
}

#[test]
fn timing_sorts_episodes_by_their_first_commitment() {
    let trace = |correct_side: i8, decision: i8, x: Vec<f32>| EpisodeTrace {
        task: 0,
        context_size: 1,
        draw: 0,
        rollout: 0,
        correct_side,
        decision,
        x,
    };
    let traces = vec![
        // Right from the start, decided right.
        trace(1, 1, vec![0.1, 0.3, 0.9, 1.4]),
        // Wrong from the start, decided wrong.
        trace(1, -1, vec![-0.1, -0.3, -0.9, -1.4]),
        // Right first, then drifted to the wrong target.
        trace(-1, -1, vec![-0.3, -0.1, 0.5, 1.4]),
        // Wrong first, recovered.
        trace(-1, 1, vec![0.3, 0.0, -0.9, -1.4]),
        // Never committed.
        trace(1, 0, vec![0.1, -0.1, 0.2, 0.0]),
    ];
    assert_eq!(traces[0].commit(COMMIT_X), Some((2, 1)));
    assert_eq!(traces[0].side_at(1, COMMIT_X), 0);
    assert_eq!(traces[2].side_at(4, COMMIT_X), -1);
    assert_eq!(traces[2].side_at(9, COMMIT_X), 0);
    let rows = timing_summary(&traces, &[2, 4]);
    assert_eq!(rows.len(), 2); // the one size and all sizes
    let all = &rows[1];
    assert_eq!((all.context_size, all.episodes), (None, 5));
    assert!((all.success - 0.4).abs() < 1e-12 && (all.no_op - 0.2).abs() < 1e-12);
    assert!((all.decided_accuracy - 0.5).abs() < 1e-12);
    assert!((all.committed_right - 0.4).abs() < 1e-12);
    assert!((all.committed_wrong - 0.4).abs() < 1e-12);
    assert!((all.never_committed - 0.2).abs() < 1e-12);
    assert!((all.wrong_from_start - 0.2).abs() < 1e-12);
    assert!((all.drifted - 0.2).abs() < 1e-12);
    assert!((all.recovered - 0.2).abs() < 1e-12);
    assert_eq!(all.side_at[1], (4, 0.4, 0.4));
    assert_eq!(all.median_commit_step, 2.0);
    // Commitments: +x in episodes 0 and 3, -x in 1 and 2 (of 4 committed).
    assert!((all.commits_to_first_target - 0.5).abs() < 1e-12);
    // Correct side +x (episodes 0, 1, 4): 1 of 2 committed right; -x (2, 3): 1 of 2.
    assert!((all.balanced_commit_accuracy - 0.5).abs() < 1e-12);
    // Decided: +x side episodes 0 (right) and 1 (wrong); -x side 2 (wrong) and 3 (right).
    assert!((all.balanced_decided_accuracy - 0.5).abs() < 1e-12);
    // A policy that always walks to x > 0 is right half the time, balanced 0.5 whatever the mix.
    let always: Vec<EpisodeTrace> = [1i8, 1, 1, -1]
        .iter()
        .map(|&c| trace(c, c, vec![0.5, 1.4]))
        .collect();
    let row = &timing_summary(&always, &[1])[1];
    assert!((row.decided_accuracy - 0.75).abs() < 1e-12);
    assert_eq!(row.commits_to_first_target, 1.0);
    assert!((row.balanced_commit_accuracy - 0.5).abs() < 1e-12);
}
