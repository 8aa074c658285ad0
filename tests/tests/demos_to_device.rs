//! Across crates: the trainer records demos with an expert into sim's dataset file; the file
//! is read back and streamed over the simulated link into a device running an infer-core blob,
//! which must then reach the held-out goals it was taught.

use firmware_sim::link::{LinkConfig, SimLink};
use firmware_sim::{Controller, DeviceConfig, LoopConfig, host, reference, run};
use infer_core::{Model, Quant};
use sim::{DemoDataset, EnvConfig, Family, Split, make_env};
use trainer::expert::{Expert, export_scripted_pd};
use trainer::{DemoSpec, record_demos as record};

#[test]
fn demos_from_the_trainer_teach_a_device_through_a_file() {
    let dir = tempfile::tempdir().unwrap();
    export_scripted_pd(dir.path()).unwrap();
    let expert = Expert::load(dir.path()).unwrap();
    let tasks: Vec<_> = Family::POINT_GOAL
        .test_tasks()
        .into_iter()
        .step_by(4)
        .collect();
    let spec = DemoSpec {
        tasks: tasks.clone(),
        split: Split::Test,
        per_task: 1,
        subsample: 1,
        seed: 40,
        distinct_starts: false,
        env: EnvConfig::default(),
    };
    let path = dir.path().join("demos.safetensors");
    record(&expert, &spec).unwrap().write(&path).unwrap();
    let demos = DemoDataset::read(&path).unwrap();
    assert_eq!(demos.tasks.len(), tasks.len());

    // Calibrate the w8a8 blob on the recorded demos, as the exporter does.
    let recorded: Vec<_> = demos.tasks.iter().map(|t| &t.trajectories[0]).collect();
    let blob = reference::pd_point_goal_blob(Quant::W8A8, &recorded).unwrap();

    for task_demos in &demos.tasks {
        let mut device = firmware_sim::erased(DeviceConfig::default());
        let mut link = SimLink::new(LinkConfig {
            corrupt_probability: 0.02,
            seed: 1,
            ..LinkConfig::default()
        });
        host::upload_blob(&mut link, &mut device, &blob).unwrap();
        let model = Model::from_bytes(device.blob().unwrap()).unwrap();
        let mut controller = Controller::new(&model, device.config()).unwrap();
        host::teach(
            &mut link,
            &mut controller,
            &[&task_demos.trajectories[0]],
            4,
            2,
        )
        .unwrap();
        let mut plant = make_env(Family::POINT_GOAL, EnvConfig::default()).unwrap();
        let report = run(
            &mut controller,
            plant.as_mut(),
            &task_demos.task,
            &LoopConfig {
                seed: 99,
                ..LoopConfig::default()
            },
        )
        .unwrap();
        assert!(
            report.metric < 0.15,
            "{}: {}",
            task_demos.task.label(),
            report.metric
        );
    }
}
