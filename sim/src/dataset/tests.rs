use super::*;
use crate::env::make_env;
use crate::family::EnvConfig;
use crate::point_goal::PointGoalPdExpert;
use proptest::prelude::*;

pub(super) fn point_goal_demos(tasks: usize, per_task: usize, horizon: usize) -> DemoDataset {
    let config = EnvConfig {
        horizon: Some(horizon),
        ..EnvConfig::default()
    };
    let mut env = make_env(Family::POINT_GOAL, config).unwrap();
    let expert = PointGoalPdExpert::default();
    let mut dataset = DemoDataset::new(Family::POINT_GOAL, Split::Train, "scripted-pd");
    for task in Family::POINT_GOAL.train_tasks().into_iter().take(tasks) {
        let trajectories = (0..per_task as u64)
            .map(|seed| {
                record_trajectory(env.as_mut(), &task, seed, |oracle, action| {
                    expert.act(oracle, action).unwrap()
                })
                .unwrap()
            })
            .collect();
        dataset.tasks.push(TaskDemos { task, trajectories });
    }
    dataset
}

#[test]
fn recorded_transitions_chain_and_hide_the_task() {
    let dataset = point_goal_demos(1, 1, 20);
    let trajectory = &dataset.tasks[0].trajectories[0];
    assert_eq!(trajectory.len(), 20);
    assert_eq!(trajectory.obs.len(), 20 * 4);
    for i in 0..19 {
        let now = trajectory.transition(i, 4, 2).unwrap();
        let next = trajectory.transition(i + 1, 4, 2).unwrap();
        assert_eq!(now.next_obs, next.obs);
    }
    assert!(
        trajectory.dones.iter().all(|d| !d),
        "the horizon is not a terminal"
    );
}

#[test]
fn bytes_and_file_round_trip_exactly() {
    let dataset = point_goal_demos(3, 2, 15).subsample(4, 9).unwrap();
    let bytes = dataset.to_bytes().unwrap();
    assert_eq!(DemoDataset::from_bytes(&bytes).unwrap(), dataset);
    let path = std::env::temp_dir().join(format!("sim-demos-{}.safetensors", std::process::id()));
    dataset.write(&path).unwrap();
    let back = DemoDataset::read(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(back, dataset);
    assert_eq!(back.trajectory_count(), 6);
}

#[test]
fn subsampling_keeps_steps_at_the_offset_with_their_true_next_state() {
    let full = point_goal_demos(2, 4, 40);
    let sub = full.subsample(10, 3).unwrap();
    assert_eq!(sub.subsample_factor, 10);
    let mut offsets = Vec::new();
    for (full_task, sub_task) in full.tasks.iter().zip(&sub.tasks) {
        for (original, kept) in full_task.trajectories.iter().zip(&sub_task.trajectories) {
            assert_eq!(kept.len(), 4);
            offsets.push(kept.subsample_offset);
            for (i, &t) in kept.time_steps.iter().enumerate() {
                assert_eq!(t as usize % 10, kept.subsample_offset);
                let expected = original.transition(t as usize, 4, 2).unwrap();
                assert_eq!(kept.transition(i, 4, 2).unwrap(), expected);
            }
        }
    }
    offsets.dedup();
    assert!(offsets.len() > 1, "offsets are drawn per trajectory");
    assert!(matches!(
        sub.subsample(2, 0),
        Err(DatasetError::Subsample(_))
    ));
    assert!(matches!(
        full.subsample(0, 0),
        Err(DatasetError::Subsample(_))
    ));
}

#[test]
fn truncated_files_are_reported_as_truncated() {
    let bytes = point_goal_demos(1, 1, 10).to_bytes().unwrap();
    for cut in [0, 5, 8, 40, bytes.len() / 2, bytes.len() - 1] {
        match DemoDataset::from_bytes(&bytes[..cut]) {
            Err(DatasetError::Truncated { expected, got }) => {
                assert_eq!(got, cut);
                assert!(expected > cut);
            }
            other => panic!("cut at {cut}: {other:?}"),
        }
    }
}

#[test]
fn corrupt_and_foreign_files_give_named_errors() {
    let bytes = point_goal_demos(1, 1, 10).to_bytes().unwrap();
    let mut garbled = bytes.clone();
    garbled[9] = b'#';
    assert!(matches!(
        DemoDataset::from_bytes(&garbled),
        Err(DatasetError::Corrupt(_))
    ));
    let mut trailing = bytes.clone();
    trailing.extend_from_slice(&[0; 8]);
    assert!(matches!(
        DemoDataset::from_bytes(&trailing),
        Err(DatasetError::Corrupt(_))
    ));
    let weights = TensorView::new(Dtype::F32, vec![1], &[0, 0, 0, 0]).unwrap();
    let foreign = safetensors::serialize([("w", weights)], None).unwrap();
    assert!(matches!(
        DemoDataset::from_bytes(&foreign),
        Err(DatasetError::NotADemoFile(_))
    ));
}

#[test]
fn mismatched_metadata_and_families_are_rejected() {
    let dataset = point_goal_demos(1, 1, 10);
    assert!(matches!(
        dataset.ensure_family(Family::CHEETAH_VEL),
        Err(DatasetError::FamilyMismatch { .. })
    ));
    // Rewrite the header claiming another family: its dimensions no longer match.
    let bytes = dataset.to_bytes().unwrap();
    let header_len = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let header = std::str::from_utf8(&bytes[8..8 + header_len]).unwrap();
    let relabelled = header.replace("\"point-goal\"", "\"cheetah-vel\"");
    assert_eq!(relabelled.len(), header.len() + 1);
    let mut forged = ((header_len + 1) as u64).to_le_bytes().to_vec();
    forged.extend_from_slice(relabelled.as_bytes());
    forged.extend_from_slice(&bytes[8 + header_len..]);
    assert!(matches!(
        DemoDataset::from_bytes(&forged),
        Err(DatasetError::DimensionMismatch { .. })
    ));
    let mut bad = dataset.clone();
    bad.tasks[0].trajectories[0].actions.pop();
    assert!(matches!(
        bad.to_bytes(),
        Err(DatasetError::DimensionMismatch { .. })
    ));
}

/// Issue 57, item 10: a `dones` flag other than 0 or 1, and a task listed twice, are refused by
/// name, not read as "done" or drawn twice as often.
#[test]
fn done_flags_other_than_zero_or_one_and_repeated_tasks_are_refused() {
    let dataset = point_goal_demos(2, 1, 10);
    let bytes = dataset.to_bytes().unwrap();
    let header_len = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let header: serde_json::Value = serde_json::from_slice(&bytes[8..8 + header_len]).unwrap();
    let start = header[names::DONES]["data_offsets"][0].as_u64().unwrap() as usize;
    let mut seven = bytes.clone();
    seven[8 + header_len + start] = 7;
    let e = DemoDataset::from_bytes(&seven).unwrap_err();
    assert!(
        matches!(&e, DatasetError::Inconsistent(m) if m.contains("dones") && m.contains('7')),
        "{e}"
    );
    let mut twice = dataset.clone();
    twice.tasks.push(dataset.tasks[0].clone());
    let e = twice.to_bytes().unwrap_err();
    assert!(
        matches!(&e, DatasetError::Inconsistent(m) if m.contains("appears twice")),
        "{e}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Any byte changed anywhere is an `Ok` or a `DatasetError`, never a panic.
    #[test]
    fn arbitrary_damage_never_panics(position in any::<prop::sample::Index>(), value in any::<u8>()) {
        let bytes = point_goal_demos(1, 1, 5).to_bytes().unwrap();
        let mut damaged = bytes.clone();
        damaged[position.index(bytes.len())] = value;
        let _ = DemoDataset::from_bytes(&damaged);
    }

    /// Every strict prefix of a file, cut anywhere from 0 to one byte short, is `Truncated`
    /// with the length actually present.
    #[test]
    fn every_prefix_is_reported_as_truncated(cut in any::<prop::sample::Index>()) {
        let bytes = point_goal_demos(1, 1, 5).to_bytes().unwrap();
        let cut = cut.index(bytes.len());
        match DemoDataset::from_bytes(&bytes[..cut]) {
            Err(DatasetError::Truncated { expected, got }) => {
                prop_assert_eq!(got, cut);
                prop_assert!(expected > cut && expected <= bytes.len());
            }
            other => prop_assert!(false, "cut at {} of {}: {:?}", cut, bytes.len(), other),
        }
    }
}

mod forged;

/// The writer's bytes are pinned: a shipped demo file read and written again hashes to the
/// value this writer gave when its function was split (2026-12-05), so a change that moves one
/// byte of the format fails here (update the hash only with a format change, in DATASET.md).
#[test]
fn a_shipped_demo_file_is_written_to_the_pinned_bytes() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/experts/point-goal/demos-test-4x-sub20.safetensors");
    let ds = DemoDataset::read(&path).unwrap();
    let bytes = ds.to_bytes().unwrap();
    assert_eq!(
        DemoDataset::from_bytes(&bytes).unwrap().to_bytes().unwrap(),
        bytes
    );
    assert_eq!(
        crate::fsio::sha256_hex(&bytes),
        PINNED,
        "{}",
        path.display()
    );
}

const PINNED: &str = "f87fa7c3ac76e538c3c98cc2354cd8fa60cd7378828407812362a09ee8ec01de";
