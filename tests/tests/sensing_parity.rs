//! Training through the device's senses (issue 73): a training rollout with a `[sensing]`
//! section reads the plant exactly as firmware-sim's loop does for the same seed, tick by tick
//! and bit for bit, so a policy trained so meets on the device the observations it trained on.

use firmware_sim::{Brain, LoopConfig, LoopError, Outcome};
use sim::{EnvConfig, Family, make_env};
use trainer::{Sensing, sensed_episode};

/// A policy that depends on every entry it reads (so a different reading shows in the
/// trajectory), and that records what it read.
fn policy(sensed: &[f32], action: &mut [f32]) {
    for (i, a) in action.iter_mut().enumerate() {
        *a = (-0.7 * sensed[i % sensed.len()] + 0.3 * sensed[(i + 1) % sensed.len()]).tanh();
    }
}

struct Recording(Vec<Vec<f32>>);

impl Brain for Recording {
    fn safe_action(&self, action: &mut [f32]) {
        action.fill(0.0);
    }

    fn act(&mut self, _t: usize, sensed: &[f32], action: &mut [f32]) -> Result<Outcome, LoopError> {
        self.0.push(sensed.to_vec());
        policy(sensed, action);
        Ok(Outcome {
            fault: false,
            late: None,
        })
    }
}

/// Runs one episode of `family` on the device (firmware-sim's loop under `config`) and as a
/// training rollout through `sensing`, and checks that they read the plant alike, tick by tick
/// and bit for bit; with position-only sensing also that the rollout's steps carry the views
/// the policy acted on.
fn device_and_training_read_alike(
    family: Family,
    config: &LoopConfig,
    sensing: &Sensing,
    training_seed: u64,
) {
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let task = family.test_tasks()[1];
    let mut plant = make_env(family, EnvConfig::default()).unwrap();
    let mut device = Recording(Vec::new());
    let report = firmware_sim::run(&mut device, plant.as_mut(), &task, config).unwrap();

    let mut env = make_env(family, EnvConfig::default()).unwrap();
    let (mut read, mut truth, mut views) = (Vec::new(), Vec::new(), Vec::new());
    sensed_episode(
        env.as_mut(),
        &task,
        training_seed,
        Some(sensing),
        &mut |o, a| {
            read.push(o.to_vec());
            policy(o, a);
            Ok(())
        },
        &mut |st| {
            truth.push(st.next_obs.to_vec());
            views.push(st.sensed.map(|(v, v2)| (v.to_vec(), v2.to_vec())));
            Ok(())
        },
    )
    .unwrap();

    let ticks = report.records.len();
    assert!(ticks >= 50, "{family}: {ticks} ticks");
    for (t, r) in report.records.iter().enumerate() {
        assert_eq!(
            bits(&read[t]),
            bits(&device.0[t]),
            "{family} tick {t}: the reading"
        );
        assert_eq!(bits(&r.sensed), bits(&read[t]), "{family} tick {t}");
        assert_eq!(
            bits(&truth[t]),
            bits(&r.plant_obs),
            "{family} tick {t}: the plant"
        );
        // The sensors did something: a reading is not the true state it read.
        if t > 0 {
            let differs = read[t].iter().zip(&truth[t - 1]).any(|(s, p)| s != p);
            assert!(differs, "{family} tick {t}: the reading is the truth");
        }
        match &views[t] {
            Some((v, v2)) => {
                assert!(sensing.positions);
                assert_eq!(bits(v), bits(&read[t]), "{family} tick {t}: the view kept");
                if t + 1 < ticks {
                    assert_eq!(
                        bits(v2),
                        bits(&read[t + 1]),
                        "{family} tick {t}: the next view"
                    );
                }
            }
            None => assert!(!sensing.positions, "{family} tick {t}: no view kept"),
        }
    }
}

#[test]
fn a_training_rollout_reads_the_plant_as_the_device_does() {
    for (family, adc_range) in [(Family::POINT_GOAL, 4.0), (Family::CHEETAH_VEL, 10.0)] {
        let config = LoopConfig {
            noise_std: 0.01,
            adc_bits: Some(12),
            adc_range,
            seed: 11,
            ticks: Some(60),
            budget_us: 1e9,
            ..LoopConfig::default()
        };
        let sensing = Sensing {
            noise_std: config.noise_std,
            adc_bits: config.adc_bits,
            adc_range,
            ..Sensing::default()
        };
        device_and_training_read_alike(family, &config, &sensing, config.seed);
    }
}

/// Position-only sensing: the device's estimator (one implementation, `sim::PositionSensing`)
/// rebuilds the same states in training as on the device, and the rollout keeps them.
#[test]
fn a_training_rollout_estimates_the_state_as_the_device_does() {
    for (family, adc_range, noise_std) in [
        (Family::POINT_GOAL, 4.0, 0.01),
        (Family::CHEETAH_VEL, 10.0, 0.0),
        (Family::ANT_GOAL, 30.0, 0.01),
    ] {
        let config = LoopConfig {
            noise_std,
            adc_bits: Some(12),
            adc_range,
            seed: 5,
            ticks: Some(60),
            budget_us: 1e9,
            sensing: firmware_sim::Sensing::POSITIONS,
            ..LoopConfig::default()
        };
        let sensing = Sensing {
            noise_std,
            adc_bits: config.adc_bits,
            adc_range,
            positions: true,
            ..Sensing::default()
        };
        device_and_training_read_alike(family, &config, &sensing, config.seed);
    }
}

/// The comparison can fail: a rollout seeded otherwise reads the plant otherwise.
#[test]
#[should_panic(expected = "the reading")]
fn another_seed_reads_otherwise() {
    let config = LoopConfig {
        noise_std: 0.01,
        adc_bits: Some(12),
        adc_range: 4.0,
        seed: 11,
        ticks: Some(60),
        budget_us: 1e9,
        sensing: firmware_sim::Sensing::POSITIONS,
        ..LoopConfig::default()
    };
    let sensing = Sensing {
        noise_std: 0.01,
        adc_bits: Some(12),
        adc_range: 4.0,
        positions: true,
        ..Sensing::default()
    };
    device_and_training_read_alike(Family::POINT_GOAL, &config, &sensing, 12);
}
