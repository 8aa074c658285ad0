//! Every shipped meta-policy (`assets/policies/*/`, issue 59): its blob is the one its report
//! describes, acts as its float policy within a stated bound on fixed inputs, and runs on the
//! simulated device against its plant. Each check can fail: a retrained policy without a new
//! blob, a blob of another policy, or a broken device path.

use std::path::{Path, PathBuf};

use firmware_sim::{SessionConfig, run_session};
use sim::{DemoDataset, EnvConfig, ExportReport, Family};
use trainer::MetaPolicy;
use trainer::eval::ConditionedActor;
use trainer::export::{self, BlobActor};

/// Mean |action difference| allowed between the w8a8 blob and its float policy on the test
/// demos' states (measured: 0.024-0.040 on the cheetah-vel policies; int8 of actions in
/// [-1, 1] with a tanh after the last layer).
const MEAN_ACTION_BOUND: f32 = 0.06;

fn shipped() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/policies");
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(&root)
        .unwrap_or_else(|e| panic!("{}: {e}", root.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("deploy.toml").exists())
        .collect();
    dirs.sort();
    assert!(
        !dirs.is_empty(),
        "no shipped policy under {}",
        root.display()
    );
    dirs
}

/// The test contexts a policy's manifest names.
fn contexts(dir: &Path) -> DemoDataset {
    let manifest = smile_app::device_table::DeployManifest::read(dir).unwrap();
    DemoDataset::read(dir.join(manifest.contexts)).unwrap()
}

#[test]
fn each_shipped_blob_is_its_policys_and_acts_like_it() {
    for dir in shipped() {
        let blob = std::fs::read(dir.join("policy.blob")).unwrap();
        let report = ExportReport::read(&dir.join("policy.blob.json")).unwrap();
        assert_eq!(
            report.blob_sha256,
            sim::sha256_hex(&blob),
            "{}",
            dir.display()
        );
        let mut mp = MetaPolicy::load(&dir).unwrap();
        MetaPolicy::ensure_finished(&dir, false).unwrap();
        assert_eq!((report.env, report.physics), (mp.family, mp.physics));
        let model = export::load_blob(&blob).unwrap();
        let mut actor = BlobActor::new(&model).unwrap();
        let test = contexts(&dir);
        let (od, ad) = (test.obs_dim, test.act_dim);
        let (mut sum, mut n) = (0.0f32, 0usize);
        for td in test.tasks.iter().take(5) {
            let demo = &td.trajectories[0];
            let z_float = mp.latent(&[demo]).unwrap();
            let z_blob = actor.latent(&[demo]).unwrap();
            let (mut a, mut b) = (vec![0.0; ad], vec![0.0; ad]);
            for obs in demo.obs.chunks_exact(od) {
                ConditionedActor::act(&mut mp, obs, &z_float, &mut a).unwrap();
                actor.act(obs, &z_blob, &mut b).unwrap();
                sum += a.iter().zip(&b).map(|(x, y)| (x - y).abs()).sum::<f32>();
                n += ad;
            }
        }
        let mean = sum / n as f32;
        assert!(
            mean <= MEAN_ACTION_BOUND,
            "{}: mean |blob - float| {mean} over {n} actions",
            dir.display()
        );
    }
}

/// Each shipped blob on the simulated device against its plant: the Rapier ones in every
/// build, the MuJoCo ones in the `mujoco` build (CI's MuJoCo step runs this file with it).
#[test]
fn each_shipped_blob_runs_on_the_device_against_its_plant() {
    let mut ran = 0;
    for dir in shipped() {
        let blob = std::fs::read(dir.join("policy.blob")).unwrap();
        let report = ExportReport::read(&dir.join("policy.blob.json")).unwrap();
        if report.physics == sim::Physics::Mujoco && !cfg!(feature = "mujoco") {
            continue;
        }
        ran += 1;
        let family: Family = report.env;
        let test = contexts(&dir);
        let task = family.test_tasks()[3];
        let demos = test.tasks.iter().find(|t| t.task == task).unwrap();
        let config = SessionConfig {
            plant: EnvConfig {
                physics: report.physics,
                ..EnvConfig::default()
            },
            // One whole episode of the plant.
            control: firmware_sim::LoopConfig {
                budget_us: 1e6,
                ..firmware_sim::LoopConfig::default()
            },
            ..SessionConfig::default()
        };
        let model = infer_core::Model::from_bytes(&blob).unwrap();
        let fits = blob.len() <= config.device.flash_bytes
            && firmware_sim::check_fits(&model, config.device).is_ok();
        let run = run_session(&blob, &task, &[&demos.trajectories[0]], &config);
        if !fits {
            // A policy too large or too wide for the device (its README says so) is refused
            // by the device, never run in part.
            assert!(
                run.is_err(),
                "{}: a blob that does not fit ran",
                dir.display()
            );
            continue;
        }
        let session = run.unwrap();
        assert!(session.report.records.len() >= 10, "{}", dir.display());
        assert_eq!(session.report.faults, 0, "{}", dir.display());
        assert!(session.report.metric.is_finite(), "{}", dir.display());
        assert!(session.z.iter().all(|v| v.is_finite()));
    }
    assert!(ran > 0, "no shipped policy of this build's plants ran");
}

/// Every folder of shipped files under `assets/` that lists checksums (issue 72, item 5).
fn checksum_lists() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.file_name() == Some(std::ffi::OsStr::new(sim::SUMS_FILE)) {
                out.push(p);
            }
        }
    }
    let mut lists = Vec::new();
    walk(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets"),
        &mut lists,
    );
    lists
}

#[test]
fn every_shipped_file_is_the_one_its_folder_lists() {
    let lists = checksum_lists();
    // Each expert, each policy, and assets/policies' own demo files.
    assert!(lists.len() >= 30, "{lists:?}");
    let mut files = 0;
    for list in &lists {
        let dir = list.parent().unwrap();
        for line in std::fs::read_to_string(list).unwrap().lines() {
            let name = line.split_once("  ").unwrap().1;
            assert!(
                sim::check_shipped(&dir.join(name)).unwrap(),
                "{}: {name} not checked",
                list.display()
            );
            files += 1;
        }
    }
    assert!(files > 200, "{files} files listed");
    for dir in shipped() {
        for f in ["meta_policy.safetensors", "policy.blob", "deploy.toml"] {
            assert!(
                sim::shipped_sha256(&dir.join(f)).unwrap().is_some(),
                "{}: {f} is not in its {}",
                dir.display(),
                sim::SUMS_FILE
            );
        }
    }
}

#[test]
fn a_changed_byte_in_a_shipped_file_is_refused_on_load_naming_the_file() {
    let src = &shipped()[0];
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("policy");
    std::fs::create_dir(&dir).unwrap();
    for e in std::fs::read_dir(src).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, dir.join(p.file_name().unwrap())).unwrap();
    }
    // As shipped, the copy loads.
    MetaPolicy::load(&dir).unwrap();
    let file = dir.join("meta_policy.safetensors");
    let mut bytes = std::fs::read(&file).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0x01; // a weight's lowest bit: a valid file, another policy
    std::fs::write(&file, &bytes).unwrap();
    let e = MetaPolicy::load(&dir).unwrap_err().to_string();
    assert!(
        e.contains("meta_policy.safetensors") && e.contains(sim::SUMS_FILE),
        "{e}"
    );
    // Demo files are checked the same way on read.
    let demos = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/policies");
    let name = "point-goal-demos-test.safetensors";
    let copy = tmp.path().join(name);
    std::fs::copy(demos.join(name), &copy).unwrap();
    std::fs::copy(demos.join(sim::SUMS_FILE), tmp.path().join(sim::SUMS_FILE)).unwrap();
    DemoDataset::read(&copy).unwrap();
    let mut bytes = std::fs::read(&copy).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0x01;
    std::fs::write(&copy, &bytes).unwrap();
    let e = DemoDataset::read(&copy).unwrap_err().to_string();
    assert!(e.contains(name) && e.contains(sim::SUMS_FILE), "{e}");
}
