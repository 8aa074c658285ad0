//! Position-only sensing: the device gets positions, estimates velocities on board, and
//! controls about as well as with full-state sensing; bad readings never reach the policy.

mod common;
use common::pd_demo as demo;

use firmware_sim::link::{LinkConfig, SimLink};
use firmware_sim::{Controller, DeviceConfig, LoopConfig, RunReport, Sensing, host, run};
use infer_core::{Model, Quant};
use sim::{EnvConfig, Family, Task, make_env};

/// The hand-built PD policy (w8a8) taught one demo of `task`, run once under `config`.
fn run_task(task: &Task, config: &LoopConfig) -> RunReport {
    let d = demo(task, 100);
    let blob = firmware_sim::reference::pd_point_goal_blob(Quant::W8A8, &[&d]).unwrap();
    let mut device = firmware_sim::erased(DeviceConfig::default());
    let mut link = SimLink::new(LinkConfig::default());
    host::upload_blob(&mut link, &mut device, &blob).unwrap();
    let model = Model::from_bytes(device.blob().unwrap()).unwrap();
    let mut controller = Controller::new(&model, device.config()).unwrap();
    host::teach(&mut link, &mut controller, &[&d], 4, 2).unwrap();
    let mut plant = make_env(Family::POINT_GOAL, EnvConfig::default()).unwrap();
    run(&mut controller, plant.as_mut(), task, config).unwrap()
}

fn positions(config: LoopConfig) -> LoopConfig {
    LoopConfig {
        sensing: Sensing::POSITIONS,
        ..config
    }
}

#[test]
fn position_sensing_controls_as_well_as_full_sensing() {
    // Measured mean |v est - v|: 0.006, 0.063 and 0.12 (differentiating positions amplifies
    // their noise); an estimator stuck at v = 0 would give about 0.15 at every noise level.
    for (noise_std, bound) in [(0.0, 0.02), (0.01, 0.1), (0.05, 0.2)] {
        for task in Family::POINT_GOAL.test_tasks().iter().step_by(5) {
            let config = LoopConfig {
                noise_std,
                adc_bits: Some(12),
                adc_range: 4.0,
                seed: 5,
                ..LoopConfig::default()
            };
            let full = run_task(task, &config);
            let estimated = run_task(task, &positions(config));
            assert_eq!(estimated.faults, 0);
            assert!(
                (estimated.metric - full.metric).abs() < 0.03 && estimated.metric < 0.15,
                "{} noise {noise_std}: positions {} vs full {}",
                task.label(),
                estimated.metric,
                full.metric
            );
            // The device only received positions; the velocities the policy saw were
            // estimated, and track the plant's (sensed at tick t = plant after tick t-1).
            let mut error = 0.0;
            for pair in estimated.records.windows(2) {
                assert_eq!(pair[1].measured.len(), 2);
                assert_eq!(pair[1].sensed.len(), 4);
                error += (pair[1].sensed[2] - pair[0].plant_obs[2]).abs()
                    + (pair[1].sensed[3] - pair[0].plant_obs[3]).abs();
            }
            let mean = error / (2.0 * (estimated.records.len() - 1) as f32);
            assert!(
                mean < bound,
                "{} noise {noise_std}: mean |v est - v| {mean} >= {bound}",
                task.label()
            );
            assert!(full.records.iter().all(|r| r.measured.is_empty()));
        }
    }
}

#[test]
fn a_nan_position_reading_is_held_by_the_estimator_and_counted_as_a_fault() {
    let task = Family::POINT_GOAL.test_tasks()[2];
    let report = run_task(
        &task,
        &positions(LoopConfig {
            nan_ticks: vec![3, 40],
            ..LoopConfig::default()
        }),
    );
    assert_eq!(report.faults, 2);
    for r in &report.records {
        let bad = r.tick == 3 || r.tick == 40;
        assert_eq!(r.fault, bad, "tick {}", r.tick);
        assert_eq!(r.measured[0].is_nan(), bad);
        // The policy saw the prediction, never the NaN, and acted on it.
        assert!(r.sensed.iter().all(|x| x.is_finite()), "tick {}", r.tick);
        assert!(r.applied.iter().all(|a| a.is_finite()));
    }
    assert!(report.metric < 0.15, "min distance {}", report.metric);
}

#[test]
fn out_of_range_readings_never_reach_the_policy() {
    // A sensor whose full scale is +-1.5 m, on goals 2 m away: near the goal, readings leave
    // the range, are rejected, and the estimator coasts on its prediction.
    let task = Family::POINT_GOAL.test_tasks()[0];
    let report = run_task(
        &task,
        &positions(LoopConfig {
            adc_range: 1.5,
            ..LoopConfig::default()
        }),
    );
    let rejected = report.records.iter().filter(|r| r.fault).count();
    assert!(rejected > 0, "no reading was rejected");
    assert_eq!(report.faults, rejected);
    for (i, r) in report.records.iter().enumerate() {
        let out = r.measured.iter().any(|y| y.abs() >= 1.5);
        assert_eq!(r.fault, out, "tick {}: {:?}", r.tick, r.measured);
        assert!(r.sensed.iter().all(|x| x.is_finite()));
        if out {
            // Each rejected position the policy saw is the previous estimate moved on by its rate
            // (point-goal's observed rate is 1/1.1 of the position's derivative).
            let previous = &report.records[i - 1].sensed;
            for axis in (0..2).filter(|&a| r.measured[a].abs() >= 1.5) {
                let predicted = previous[axis] + 0.1 * previous[axis + 2] * 1.1;
                assert!(
                    (r.sensed[axis] - predicted).abs() < 1e-4,
                    "tick {}: {} vs predicted {predicted}",
                    r.tick,
                    r.sensed[axis]
                );
            }
        }
    }
}

/// The device reads its plant through `sim`'s sensor model, the one the learners train through
/// (issue 73): every tick's sensed observation is `sim::Sensor` (seeded with the run's seed)
/// applied to the plant's true observation, bit for bit.
#[test]
fn the_device_reads_through_the_sensor_model_training_uses() {
    let task = Family::POINT_GOAL.test_tasks()[1];
    let config = LoopConfig {
        noise_std: 0.01,
        adc_bits: Some(12),
        adc_range: 4.0,
        seed: 9,
        ..LoopConfig::default()
    };
    let report = run_task(&task, &config);
    let mut plant = make_env(Family::POINT_GOAL, EnvConfig::default()).unwrap();
    let mut truth = plant.reset(&task, config.seed).unwrap().to_vec();
    let mut sensor = sim::Sensor::new(config.sensor_model(), config.seed).unwrap();
    let mut expected = vec![0.0; truth.len()];
    for r in &report.records {
        sensor.read_all(&truth, &mut expected);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&r.sensed), bits(&expected), "tick {}", r.tick);
        assert!(r.sensed.iter().zip(&truth).any(|(s, t)| s != t));
        truth.clone_from(&r.plant_obs);
    }
    assert!(report.records.len() > 10);
}
