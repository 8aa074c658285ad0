//! The simulated device end to end: link, flash, teach, control loop, faults.

mod common;
use common::pd_demo as demo;

use firmware_sim::link::{HostMessage, LinkConfig, LinkError, Refusal, SimLink};
use firmware_sim::{
    Controller, Device, DeviceConfig, DeviceError, LoopConfig, LoopError, host, reference, run,
};
use infer_core::{Calibration, FloatModel, Model, ModelKind, Quant, write_blob};
use sim::{EnvConfig, Family, Task, Trajectory, make_env};

fn blob(quant: Quant, demo: &Trajectory) -> Vec<u8> {
    reference::pd_point_goal_blob(quant, &[demo]).unwrap()
}

fn flashed(blob: &[u8], link: LinkConfig) -> (Device, SimLink) {
    let mut device = firmware_sim::erased(DeviceConfig::default());
    let mut link = SimLink::new(link);
    host::upload_blob(&mut link, &mut device, blob).unwrap();
    (device, link)
}

fn run_task(blob: &[u8], task: &Task, config: &LoopConfig) -> firmware_sim::RunReport {
    let (device, mut link) = flashed(blob, LinkConfig::default());
    let model = Model::from_bytes(device.blob().unwrap()).unwrap();
    let mut controller = Controller::new(&model, device.config()).unwrap();
    let d = demo(task, 100);
    host::teach(&mut link, &mut controller, &[&d], 4, 2).unwrap();
    let mut plant = make_env(Family::POINT_GOAL, EnvConfig::default()).unwrap();
    run(&mut controller, plant.as_mut(), task, config).unwrap()
}

#[test]
fn a_taught_device_reaches_held_out_goals_over_a_lossy_link() {
    let tasks = Family::POINT_GOAL.test_tasks();
    for task in tasks.iter().step_by(5) {
        let d = demo(task, 7);
        let bytes = blob(Quant::W8A8, &d);
        let lossy = LinkConfig {
            corrupt_probability: 0.05,
            drop_probability: 0.05,
            max_retries: 20,
            seed: 3,
        };
        let (device, mut link) = flashed(&bytes, lossy);
        assert_eq!(device.blob().unwrap(), &bytes[..]);
        let model = Model::from_bytes(device.blob().unwrap()).unwrap();
        let mut controller = Controller::new(&model, device.config()).unwrap();
        host::teach(&mut link, &mut controller, &[&d], 4, 2).unwrap();
        assert!(
            link.stats.retries > 0,
            "a 5% lossy link should have needed retries"
        );
        let mut plant = make_env(Family::POINT_GOAL, EnvConfig::default()).unwrap();
        let report = run(
            &mut controller,
            plant.as_mut(),
            task,
            &LoopConfig {
                seed: 11,
                ..LoopConfig::default()
            },
        )
        .unwrap();
        assert_eq!(report.faults, 0);
        assert!(
            report.metric < 0.15,
            "{}: min distance {}",
            task.label(),
            report.metric
        );
    }
}

#[test]
fn corrupted_frames_are_detected_and_resent() {
    // A full-size blob (about 100 frames) so that corruption hits many of them.
    let float = FloatModel::random(
        ModelKind::StateAction,
        infer_core::Dims::default_with_hidden(64),
        1,
    );
    let bytes = write_blob(&float, Quant::W8A32, &Calibration::default()).unwrap();
    let noisy = LinkConfig {
        corrupt_probability: 0.3,
        drop_probability: 0.0,
        max_retries: 30,
        seed: 9,
    };
    let (device, link) = flashed(&bytes, noisy);
    assert!(link.stats.corrupted > 10, "{:?}", link.stats);
    assert!(
        link.stats.retries >= link.stats.corrupted / 2,
        "{:?}",
        link.stats
    );
    assert_eq!(
        device.blob().unwrap(),
        &bytes[..],
        "corruption must never reach flash"
    );
}

#[test]
fn a_dead_link_fails_cleanly_and_nothing_partial_runs() {
    let d = demo(&Family::POINT_GOAL.test_tasks()[0], 1);
    let bytes = blob(Quant::F32, &d);
    let mut device = firmware_sim::erased(DeviceConfig::default());
    let dead = LinkConfig {
        drop_probability: 1.0,
        max_retries: 3,
        ..LinkConfig::default()
    };
    let err = host::upload_blob(&mut SimLink::new(dead), &mut device, &bytes).unwrap_err();
    assert!(
        matches!(err, LinkError::RetriesExhausted { attempts: 4, .. }),
        "{err}"
    );
    assert_eq!(device.blob().err(), Some(DeviceError::NoBlob));

    // Half a blob, then silence: still nothing to run.
    let mut link = SimLink::new(LinkConfig::default());
    let crc = infer_core::crc32(&bytes);
    link.send(
        &mut device,
        &HostMessage::BlobBegin {
            len: bytes.len() as u32,
            crc,
        },
    )
    .unwrap();
    link.send(
        &mut device,
        &HostMessage::BlobChunk {
            offset: 0,
            data: &bytes[..100],
        },
    )
    .unwrap();
    assert_eq!(device.blob().err(), Some(DeviceError::NoBlob));
    let err = link.send(&mut device, &HostMessage::BlobEnd).unwrap_err();
    assert_eq!(
        err,
        LinkError::Refused {
            seq: 3,
            reason: Refusal::BadBlob
        }
    );
    assert_eq!(device.blob().err(), Some(DeviceError::NoBlob));
}

#[test]
fn oversize_blobs_and_budgets_are_refused_before_the_loop() {
    let d = demo(&Family::POINT_GOAL.test_tasks()[0], 1);
    let bytes = blob(Quant::F32, &d);
    let mut small = firmware_sim::erased(DeviceConfig {
        flash_bytes: 256,
        ram_bytes: 16 * 1024,
    });
    let err = host::upload_blob(&mut SimLink::new(LinkConfig::default()), &mut small, &bytes)
        .unwrap_err();
    assert_eq!(
        err,
        LinkError::Refused {
            seq: 1,
            reason: Refusal::BlobTooLarge
        }
    );
    let model = Model::from_bytes(&bytes).unwrap();
    let err = Controller::new(
        &model,
        DeviceConfig {
            flash_bytes: 65536,
            ram_bytes: 1024,
        },
    )
    .unwrap_err();
    assert!(
        matches!(err, DeviceError::RamBudget { budget: 1024, .. }),
        "{err}"
    );
    // Teaching nothing and running is refused too.
    let mut controller = Controller::new(&model, DeviceConfig::default()).unwrap();
    let mut plant = make_env(Family::POINT_GOAL, EnvConfig::default()).unwrap();
    let task = Family::POINT_GOAL.test_tasks()[0];
    let err = run(
        &mut controller,
        plant.as_mut(),
        &task,
        &LoopConfig::default(),
    )
    .unwrap_err();
    assert!(
        matches!(err, LoopError::Device(DeviceError::NotTaught)),
        "{err}"
    );
}

#[test]
fn loop_settings_the_plant_cannot_honour_are_named_errors() {
    let d = demo(&Family::POINT_GOAL.test_tasks()[0], 1);
    let bytes = blob(Quant::F32, &d);
    let model = Model::from_bytes(&bytes).unwrap();
    let mut controller = Controller::new(&model, DeviceConfig::default()).unwrap();
    let mut plant = make_env(Family::POINT_GOAL, EnvConfig::default()).unwrap();
    let task = Family::POINT_GOAL.test_tasks()[0];
    let plant_rate = 1.0 / plant.control_dt();
    let mut loop_run =
        |config: LoopConfig| run(&mut controller, plant.as_mut(), &task, &config).unwrap_err();
    let err = loop_run(LoopConfig {
        rate_hz: Some(plant_rate * 0.7),
        ..LoopConfig::default()
    });
    assert!(matches!(err, LoopError::Rate { .. }), "{err}");
    let err = loop_run(LoopConfig {
        noise_std: -1.0,
        ..LoopConfig::default()
    });
    assert!(matches!(err, LoopError::Noise(n) if n == -1.0), "{err}");
}

#[test]
fn a_nan_sensor_reading_gives_the_safe_action_and_a_fault() {
    let task = Family::POINT_GOAL.test_tasks()[2];
    let bytes = blob(Quant::W8A8, &demo(&task, 1));
    let report = run_task(
        &bytes,
        &task,
        &LoopConfig {
            nan_ticks: vec![3, 40],
            ..LoopConfig::default()
        },
    );
    assert_eq!(report.faults, 2);
    for r in &report.records {
        assert!(r.applied.iter().all(|a| a.is_finite()));
        if r.tick == 3 || r.tick == 40 {
            assert!(r.fault);
            assert_eq!(
                r.applied,
                vec![0.0, 0.0],
                "safe action = centre of the action range"
            );
        } else {
            assert!(!r.fault);
        }
    }
}

#[test]
fn each_tick_senses_acts_and_actuates_and_latency_shifts_by_exactly_one_tick() {
    let task = Family::POINT_GOAL.test_tasks()[4];
    let bytes = blob(Quant::W8A8, &demo(&task, 2));
    let now = run_task(&bytes, &task, &LoopConfig::default());
    assert_eq!(now.records.len(), 100);
    for r in &now.records {
        assert_eq!(r.applied, r.computed);
    }
    // The sensed observation of tick t+1 is the plant state after tick t's action.
    for pair in now.records.windows(2) {
        assert_eq!(pair[1].sensed, pair[0].plant_obs);
    }
    let late = run_task(
        &bytes,
        &task,
        &LoopConfig {
            latency: true,
            ..LoopConfig::default()
        },
    );
    assert_eq!(late.records[0].applied, vec![0.0, 0.0]);
    for pair in late.records.windows(2) {
        assert_eq!(pair[1].applied, pair[0].computed);
    }
    assert!(
        late.metric < 0.3,
        "one tick of latency should still reach: {}",
        late.metric
    );
}

#[test]
fn control_rate_holds_actions_over_plant_steps() {
    let task = Family::POINT_GOAL.test_tasks()[1];
    let bytes = blob(Quant::W8A8, &demo(&task, 3));
    let slow = run_task(
        &bytes,
        &task,
        &LoopConfig {
            rate_hz: Some(5.0),
            ..LoopConfig::default()
        },
    );
    assert_eq!(slow.steps_per_tick, 2);
    assert_eq!(slow.records.len(), 50);
    assert!((slow.records[1].time - 0.2).abs() < 1e-6);
    let (device, mut link) = flashed(&bytes, LinkConfig::default());
    let model = Model::from_bytes(device.blob().unwrap()).unwrap();
    let mut controller = Controller::new(&model, device.config()).unwrap();
    host::teach(&mut link, &mut controller, &[&demo(&task, 3)], 4, 2).unwrap();
    let mut plant = make_env(Family::POINT_GOAL, EnvConfig::default()).unwrap();
    let err = run(
        &mut controller,
        plant.as_mut(),
        &task,
        &LoopConfig {
            rate_hz: Some(3.0),
            ..LoopConfig::default()
        },
    );
    assert!(err.is_err());
}

#[test]
fn same_seed_blob_and_context_give_a_bit_identical_trace() {
    let task = Family::POINT_GOAL.test_tasks()[6];
    let bytes = blob(Quant::W8A8, &demo(&task, 4));
    let config = LoopConfig {
        noise_std: 0.01,
        adc_bits: Some(12),
        adc_range: 4.0,
        seed: 5,
        ..LoopConfig::default()
    };
    let a = run_task(&bytes, &task, &config);
    let b = run_task(&bytes, &task, &config);
    assert_eq!(a.records, b.records);
    let c = run_task(&bytes, &task, &LoopConfig { seed: 6, ..config });
    assert_ne!(
        a.records, c.records,
        "another seed must change the sensor noise"
    );
}

#[test]
fn a_session_runs_end_to_end_and_refuses_a_blob_for_another_plant() {
    let task = Family::POINT_GOAL.test_tasks()[5];
    let d = demo(&task, 8);
    let session = firmware_sim::run_session(
        &blob(Quant::W8A8, &d),
        &task,
        &[&d],
        &firmware_sim::SessionConfig::default(),
    )
    .unwrap();
    assert!(session.report.metric < 0.15, "{}", session.report.metric);
    assert_eq!(session.z.len(), 2);
    // A cheetah-sized blob on the point-goal plant: refused before the loop, with the dims.
    let cheetah = FloatModel::random(
        ModelKind::StateAction,
        infer_core::Dims {
            obs: 17,
            act: 6,
            r: 8,
            z: 4,
            hidden: 16,
        },
        2,
    );
    let bytes = write_blob(&cheetah, Quant::F32, &Calibration::default()).unwrap();
    let err = firmware_sim::run_session(
        &bytes,
        &task,
        &[&d],
        &firmware_sim::SessionConfig::default(),
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            firmware_sim::SessionError::Dims {
                blob_obs: 17,
                plant_obs: 4,
                ..
            }
        ),
        "{err}"
    );
}

#[test]
fn re_teaching_mid_run_switches_the_task() {
    let tasks = Family::POINT_GOAL.test_tasks();
    let (a, b) = (tasks[1], tasks[9]);
    let (demo_a, demo_b) = (demo(&a, 1), demo(&b, 2));
    let bytes = blob(Quant::W8A8, &demo_a);
    let (device, mut link) = flashed(&bytes, LinkConfig::default());
    let model = Model::from_bytes(device.blob().unwrap()).unwrap();

    let mut fresh = Controller::new(&model, device.config()).unwrap();
    host::teach(&mut link, &mut fresh, &[&demo_b], 4, 2).unwrap();
    let z_b = fresh.z().unwrap().to_vec();

    let mut controller = Controller::new(&model, device.config()).unwrap();
    host::teach(&mut link, &mut controller, &[&demo_a], 4, 2).unwrap();
    let z_a = controller.z().unwrap().to_vec();
    let mut plant = make_env(Family::POINT_GOAL, EnvConfig::default()).unwrap();
    let first = run(
        &mut controller,
        plant.as_mut(),
        &a,
        &LoopConfig {
            ticks: Some(30),
            ..LoopConfig::default()
        },
    )
    .unwrap();
    assert_eq!(first.records.len(), 30);
    // A new demo arrives while the device is running: the old context is forgotten.
    host::teach(&mut link, &mut controller, &[&demo_b], 4, 2).unwrap();
    assert_eq!(controller.z().unwrap(), &z_b[..]);
    assert_ne!(z_a, z_b);
    let second = run(&mut controller, plant.as_mut(), &b, &LoopConfig::default()).unwrap();
    assert!(second.metric < 0.15, "after re-teaching: {}", second.metric);
}
