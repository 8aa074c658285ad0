//! The device on the MuJoCo plant: a policy trained (briefly) on MuJoCo cheetah-vel demos is
//! exported as a blob and run by firmware-sim's fixed-rate loop against the MuJoCo plant, with
//! its trace and plot; the same blob on the Rapier plant runs another trajectory.
#![cfg(feature = "mujoco")]

use firmware_sim::{SessionConfig, run_session, trace};
use sim::{DemoDataset, EnvConfig, Family, Physics, Split, TaskDemos, make_env};
use trainer::MetaData;
use trainer::meta_bc::{MetaBc, MetaBcConfig};

const HORIZON: usize = 40;

fn mujoco() -> EnvConfig {
    EnvConfig {
        horizon: Some(HORIZON),
        physics: Physics::Mujoco,
        ..EnvConfig::default()
    }
}

/// Demos of a velocity-dependent trot on MuJoCo's cheetah.
fn demos(split: Split, tasks: Vec<sim::Task>) -> DemoDataset {
    let mut env = make_env(Family::CHEETAH_VEL, mujoco()).unwrap();
    let mut ds = DemoDataset::new(Family::CHEETAH_VEL, split, "trot");
    ds.physics = Physics::Mujoco;
    for task in tasks {
        let mut step = 0usize;
        let tr = sim::record_trajectory(env.as_mut(), &task, 3, |oracle, a| {
            let v = oracle[oracle.len() - 1];
            for (j, out) in a.iter_mut().enumerate() {
                *out = (0.3 + 0.2 * v) * (0.6 * step as f32 + j as f32).sin();
            }
            step += 1;
        })
        .unwrap();
        ds.tasks.push(TaskDemos {
            task,
            trajectories: vec![tr],
        });
    }
    ds
}

#[test]
fn a_blob_trained_on_mujoco_runs_on_the_device_against_the_mujoco_plant() {
    let dir = tempfile::tempdir().unwrap();
    let fam = Family::CHEETAH_VEL;
    let train = demos(Split::Train, fam.train_tasks()[..6].to_vec());
    let test = demos(Split::Test, fam.test_tasks()[..1].to_vec());
    let cfg = MetaBcConfig {
        env: fam,
        physics: Physics::Mujoco,
        policy_hidden: vec![16, 16],
        total_steps: 40,
        eval_every: 0,
        horizon: Some(HORIZON),
        ..MetaBcConfig::default()
    };
    let data = MetaData::from_dataset(&train, fam, 0).unwrap();
    assert_eq!(data.physics, Physics::Mujoco);
    let mut learner = MetaBc::new(cfg, data, None).unwrap();
    trainer::fit(&mut learner, dir.path(), &mut |_| {}).unwrap();
    let mp = learner.meta_policy();
    assert_eq!(mp.physics, Physics::Mujoco);
    let blob = trainer::export::export_blob(&mp, infer_core::Quant::W8A32, None).unwrap();

    let task = test.tasks[0].task;
    let context = [&test.tasks[0].trajectories[0]];
    let run_on = |physics| {
        let config = SessionConfig {
            plant: EnvConfig {
                physics,
                ..mujoco()
            },
            ..SessionConfig::default()
        };
        run_session(&blob, &task, &context, &config).unwrap()
    };
    let session = run_on(Physics::Mujoco);
    let report = &session.report;
    assert_eq!(report.records.len(), HORIZON);
    assert!(report.metric.is_finite() && report.faults == 0);
    trace::write_csv(&dir.path().join("trace.csv"), report, &session.z).unwrap();
    trace::write_plot(&dir.path().join("plot.svg"), report).unwrap();
    let csv = std::fs::read_to_string(dir.path().join("trace.csv")).unwrap();
    assert!(
        csv.lines().count() > HORIZON,
        "trace has {} lines",
        csv.lines().count()
    );
    assert!(
        std::fs::metadata(dir.path().join("plot.svg"))
            .unwrap()
            .len()
            > 1000
    );

    // The plant is really the one asked for: the same blob and context on Rapier's cheetah
    // senses other observations (its rootz is absolute, MuJoCo's relative to the rest pose).
    let rapier = run_on(Physics::Rapier);
    assert_ne!(
        rapier.report.records[0].sensed, report.records[0].sensed,
        "the two plants gave the same first observation"
    );
}
