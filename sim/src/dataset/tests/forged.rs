//! The reader against forged files: a valid file is written, then one header field or one
//! stored element is changed, and the reader must name that exact fault.

use super::super::*;
use super::point_goal_demos;
use serde_json::{Map, Value};

/// Two tasks of two trajectories of five steps: trajectory 3 (task 1) owns rows 15..20.
fn file() -> Vec<u8> {
    point_goal_demos(2, 2, 5).to_bytes().unwrap()
}

/// End of the JSON header (= start of the tensor data).
fn header_end(bytes: &[u8]) -> usize {
    8 + u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize
}

fn header(bytes: &[u8]) -> Map<String, Value> {
    match serde_json::from_slice(&bytes[8..header_end(bytes)]).unwrap() {
        Value::Object(map) => map,
        other => panic!("header is not an object: {other}"),
    }
}

/// The same tensor data under a header changed by `edit`.
fn with_header(bytes: &[u8], edit: impl FnOnce(&mut Map<String, Value>)) -> Vec<u8> {
    let mut map = header(bytes);
    edit(&mut map);
    let text = Value::Object(map).to_string();
    let mut out = (text.len() as u64).to_le_bytes().to_vec();
    out.extend_from_slice(text.as_bytes());
    out.extend_from_slice(&bytes[header_end(bytes)..]);
    out
}

/// Sets (or, with `None`, removes) one metadata key.
fn with_metadata(bytes: &[u8], key: &str, value: Option<&str>) -> Vec<u8> {
    with_header(bytes, |map| {
        let Some(Value::Object(meta)) = map.get_mut("__metadata__") else {
            panic!("no metadata");
        };
        match value {
            Some(value) => meta.insert(key.into(), value.into()),
            None => meta.remove(key),
        };
    })
}

/// Overwrites element `index` of tensor `name` with `element` (its little-endian bytes).
fn patch(bytes: &[u8], name: &str, index: usize, element: &[u8]) -> Vec<u8> {
    let begin = header(bytes)[name]["data_offsets"][0].as_u64().unwrap() as usize;
    let at = header_end(bytes) + begin + index * element.len();
    let mut out = bytes.to_vec();
    out[at..at + element.len()].copy_from_slice(element);
    out
}

fn read(bytes: &[u8]) -> DatasetError {
    DemoDataset::from_bytes(bytes).expect_err("the forged file was accepted")
}

#[test]
fn the_forging_helpers_keep_an_untouched_file_valid() {
    let bytes = file();
    let same = with_header(&bytes, |_| {});
    assert_eq!(
        DemoDataset::from_bytes(&same).unwrap(),
        point_goal_demos(2, 2, 5)
    );
    let rewritten = patch(&bytes, "rewards", 17, &0.25f32.to_le_bytes());
    let dataset = DemoDataset::from_bytes(&rewritten).unwrap();
    assert_eq!(dataset.tasks[1].trajectories[1].rewards[2], 0.25);
}

#[test]
fn non_finite_trajectory_values_are_refused_naming_tensor_task_and_trajectory() {
    let bytes = file();
    // Row 17 is step 2 of trajectory 3 (task 1); obs_dim 4, act_dim 2.
    let cases = [
        ("obs", 17 * 4 + 1, f32::NAN),
        ("actions", 17 * 2, f32::INFINITY),
        ("rewards", 17, f32::NEG_INFINITY),
        ("next_obs", 17 * 4 + 3, f32::NAN),
    ];
    for (name, index, bad) in cases {
        let err = read(&patch(&bytes, name, index, &bad.to_le_bytes()));
        assert!(
            matches!(
                err,
                DatasetError::NonFinite { tensor, task: 1, trajectory: Some(3), value }
                    if tensor == name && !value.is_finite()
            ),
            "{name}: {err:?}"
        );
    }
    // The first row of the file is trajectory 0 of task 0.
    let err = read(&patch(&bytes, "obs", 0, &f32::NAN.to_le_bytes()));
    assert!(
        matches!(
            err,
            DatasetError::NonFinite {
                tensor: "obs",
                task: 0,
                trajectory: Some(0),
                ..
            }
        ),
        "{err:?}"
    );
}

#[test]
fn non_finite_task_values_and_parameters_are_refused_naming_the_task() {
    let bytes = file();
    let err = read(&patch(&bytes, "task_values", 1, &f64::NAN.to_le_bytes()));
    assert!(
        matches!(
            err,
            DatasetError::NonFinite {
                tensor: "task_values",
                task: 1,
                trajectory: None,
                ..
            }
        ),
        "{err:?}"
    );
    // task_dim 2: element 3 is task 1's goal y.
    let err = read(&patch(
        &bytes,
        "task_parameters",
        3,
        &f32::INFINITY.to_le_bytes(),
    ));
    assert!(
        matches!(
            err,
            DatasetError::NonFinite {
                tensor: "task_parameters",
                task: 1,
                trajectory: None,
                ..
            }
        ),
        "{err:?}"
    );
}

#[test]
fn the_writer_refuses_what_the_reader_would_refuse() {
    let mut dataset = point_goal_demos(2, 2, 5);
    dataset.tasks[1].trajectories[0].rewards[4] = f32::NAN;
    let err = dataset.to_bytes().unwrap_err();
    assert!(
        matches!(
            err,
            DatasetError::NonFinite {
                tensor: "rewards",
                task: 1,
                trajectory: Some(2),
                ..
            }
        ),
        "{err:?}"
    );
}

#[test]
fn other_format_versions_are_refused_as_unsupported() {
    let bytes = file();
    for version in [0u32, 2, 99] {
        let err = read(&with_metadata(
            &bytes,
            "format_version",
            Some(&version.to_string()),
        ));
        assert!(
            matches!(
                err,
                DatasetError::UnsupportedVersion { found, supported: FORMAT_VERSION }
                    if found == version
            ),
            "version {version}: {err:?}"
        );
    }
    let err = read(&with_metadata(&bytes, "format", Some("other-demos")));
    assert!(matches!(err, DatasetError::NotADemoFile(_)), "{err:?}");
}

#[test]
fn bad_metadata_is_refused_naming_the_key() {
    let bytes = file();
    let cases: [(&str, Option<&str>); 8] = [
        ("format_version", Some("one")),
        ("format_version", None),
        ("family", Some("dog")),
        ("split", None),
        ("obs_dim", Some("-1")),
        ("subsample_factor", Some("0")),
        ("subsample_factor", Some("")),
        ("expert", None),
    ];
    for (key, value) in cases {
        let err = read(&with_metadata(&bytes, key, value));
        assert!(
            matches!(err, DatasetError::BadMetadata { key: k, .. } if k == key),
            "{key} = {value:?}: {err:?}"
        );
    }
}

#[test]
fn bad_tensors_are_refused_naming_the_tensor() {
    let bytes = file();
    let renamed = with_header(&bytes, |map| {
        let dones = map.remove("dones").unwrap();
        map.insert("dones_v0".into(), dones);
    });
    let retyped = with_header(&bytes, |map| map["obs"]["dtype"] = "I32".into());
    let reshaped = with_header(&bytes, |map| map["actions"]["shape"] = vec![40, 1].into());
    let negative = patch(&bytes, "time_steps", 6, &(-1i64).to_le_bytes());
    let too_late = patch(&bytes, "time_steps", 6, &(1i64 << 32).to_le_bytes());
    let negative_offset = patch(&bytes, "traj_offsets", 1, &(-5i64).to_le_bytes());
    let cases = [
        ("dones", renamed),
        ("obs", retyped),
        ("actions", reshaped),
        ("time_steps", negative),
        ("time_steps", too_late),
        ("traj_offsets", negative_offset),
    ];
    for (tensor, forged) in cases {
        let err = read(&forged);
        assert!(
            matches!(err, DatasetError::BadTensor { name, .. } if name == tensor),
            "{tensor}: {err:?}"
        );
    }
}

#[test]
fn inconsistent_offsets_are_refused() {
    let bytes = file();
    // traj_offsets = [0, 5, 10, 15, 20], task_traj_offsets = [0, 2, 4].
    let cases = [
        ("traj_offsets", 2, 3i64, "traj_offsets"),
        ("traj_offsets", 4, 19, "traj_offsets"),
        ("traj_offsets", 0, 1, "traj_offsets"),
        ("task_traj_offsets", 1, 5, "task_traj_offsets"),
        ("task_traj_offsets", 2, 3, "task_traj_offsets"),
        ("traj_subsample_offsets", 1, 1, "subsample offset"),
    ];
    for (tensor, index, value, named) in cases {
        let err = read(&patch(&bytes, tensor, index, &value.to_le_bytes()));
        assert!(
            matches!(&err, DatasetError::Inconsistent(reason) if reason.contains(named)),
            "{tensor}[{index}] = {value}: {err:?}"
        );
    }
}
