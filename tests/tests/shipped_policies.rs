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
