//! The position-only state estimator against known trajectories, and its fault handling.

use infer_core::{Channel, Error, Estimator, EstimatorConfig};

const PV: [Channel; 2] = [Channel::Position, Channel::Rate { of: 0, scale: 1.0 }];

fn config(dt: f32, accel_std: f32, meas_std: f32) -> EstimatorConfig {
    EstimatorConfig {
        dt,
        accel_std,
        meas_std,
        limit: 100.0,
        initial_rate_std: 2.0,
    }
}

/// Deterministic standard normal samples (xorshift64* + Box-Muller).
struct Gauss(u64);

impl Gauss {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn sample(&mut self) -> f32 {
        let (u, v) = (self.uniform(), self.uniform());
        ((-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()) as f32
    }
}

/// Feeds `position(t)` (plus noise of std `noise`) for `ticks` ticks; returns the estimated
/// (position, rate) after each tick.
fn track(
    estimator: &mut Estimator<4>,
    ticks: usize,
    dt: f32,
    noise: f32,
    position: impl Fn(f32) -> f32,
) -> Vec<(f32, f32)> {
    let mut gauss = Gauss(0x9E37_79B9_7F4A_7C15);
    let mut obs = [0.0f32; 2];
    (0..ticks)
        .map(|k| {
            let y = position(k as f32 * dt) + noise * gauss.sample();
            let report = estimator.step(&[y], &mut obs).unwrap();
            assert_eq!(report.rejected, 0);
            (obs[0], obs[1])
        })
        .collect()
}

#[test]
fn constant_velocity_is_recovered_exactly_without_noise() {
    let dt = 0.1;
    let mut estimator = Estimator::<4>::new(&PV, config(dt, 1.0, 0.0)).unwrap();
    let estimates = track(&mut estimator, 40, dt, 0.0, |t| 0.3 + 1.5 * t);
    // Starts at rate 0; a noise-free sensor makes the filter converge within a few ticks.
    for (k, &(p, v)) in estimates.iter().enumerate().skip(5) {
        let t = k as f32 * dt;
        assert!((v - 1.5).abs() < 1e-3, "tick {k}: rate {v}");
        assert!((p - (0.3 + 1.5 * t)).abs() < 1e-4, "tick {k}: position {p}");
    }
}

#[test]
fn a_sinusoid_is_tracked_with_a_bounded_lag() {
    // 1 Hz-ish motion sampled at 100 Hz: amplitude 1, omega 2 rad/s, peak acceleration 4.
    let (dt, omega) = (0.01f32, 2.0f32);
    let mut estimator = Estimator::<4>::new(&PV, config(dt, 4.0, 1e-4)).unwrap();
    let estimates = track(&mut estimator, 700, dt, 0.0, |t| (omega * t).sin());
    let worst = estimates
        .iter()
        .enumerate()
        .skip(100)
        .map(|(k, &(_, v))| (v - omega * (omega * k as f32 * dt).cos()).abs())
        .fold(0.0f32, f32::max);
    // The rate amplitude is 2: the worst error after 1 s is under 1.5% of it (measured 0.018).
    assert!(worst < 0.03, "worst rate error {worst}");
}

#[test]
fn noisy_readings_give_a_bounded_rate_error_well_below_finite_differences() {
    let (dt, noise) = (0.1f32, 0.01f32);
    let mut estimator = Estimator::<4>::new(&PV, config(dt, 0.5, noise)).unwrap();
    let truth = |t: f32| -0.5 + 0.8 * t;
    let estimates = track(&mut estimator, 500, dt, noise, truth);
    let settled = &estimates[50..];
    let rms = (settled.iter().map(|&(_, v)| (v - 0.8).powi(2)).sum::<f32>() / settled.len() as f32)
        .sqrt();
    let worst = settled
        .iter()
        .map(|&(_, v)| (v - 0.8).abs())
        .fold(0.0f32, f32::max);
    // A finite difference of two readings has rate noise sqrt(2) * 0.01 / 0.1 = 0.14.
    assert!(rms < 0.05, "rms rate error {rms}");
    assert!(worst < 0.15, "worst rate error {worst}");
    let position_rms = (settled
        .iter()
        .enumerate()
        .map(|(k, &(p, _))| (p - truth((k + 50) as f32 * dt)).powi(2))
        .sum::<f32>()
        / settled.len() as f32)
        .sqrt();
    assert!(position_rms < noise, "position rms {position_rms}");
}

#[test]
fn an_angle_crossing_pi_keeps_its_rate() {
    let dt = 0.05;
    let channels = [Channel::Angle, Channel::Rate { of: 0, scale: 1.0 }];
    let mut estimator = Estimator::<4>::new(&channels, config(dt, 1.0, 0.0)).unwrap();
    let wrap = |a: f32| {
        (a + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU) - std::f32::consts::PI
    };
    // 3 rad/s from 2.5 rad: crosses +pi after about 0.2 s and wraps to -pi.
    let estimates = track(&mut estimator, 60, dt, 0.0, |t| wrap(2.5 + 3.0 * t));
    for (k, &(a, v)) in estimates.iter().enumerate().skip(5) {
        assert!((v - 3.0).abs() < 1e-2, "tick {k}: rate {v}");
        assert!(
            a.abs() <= std::f32::consts::PI + 1e-6,
            "tick {k}: angle {a}"
        );
    }
    // Resting at pi with noisy readings that fall on both sides of the wrap: the rate stays
    // near 0 (an unwrapped innovation would be 2 pi).
    let mut estimator = Estimator::<4>::new(&channels, config(dt, 1.0, 0.02)).unwrap();
    let estimates = track(&mut estimator, 200, dt, 0.02, |_| std::f32::consts::PI);
    for (k, &(a, v)) in estimates.iter().enumerate() {
        assert!(v.abs() < 0.5, "tick {k}: rate {v}");
        assert!(a.abs() > 3.0, "tick {k}: angle {a}");
    }
}

#[test]
fn rates_are_scaled_and_direct_channels_pass_through() {
    let dt = 0.1;
    let channels = [
        Channel::Position,
        Channel::Direct,
        Channel::Rate { of: 0, scale: 0.5 },
    ];
    let mut estimator = Estimator::<4>::new(&channels, config(dt, 1.0, 0.0)).unwrap();
    assert_eq!((estimator.obs_len(), estimator.readings_len()), (3, 2));
    let mut obs = [0.0f32; 3];
    for k in 0..20 {
        let t = k as f32 * dt;
        estimator.step(&[2.0 * t, 7.0 + t], &mut obs).unwrap();
    }
    assert_eq!(obs[1], 7.0 + 19.0 * dt, "direct channel passed through");
    assert!((obs[2] - 1.0).abs() < 1e-3, "half of rate 2: {}", obs[2]);
}

/// A converged position/rate filter at 1 m/s, and its last estimate.
fn converged() -> (Estimator<4>, [f32; 2]) {
    let dt = 0.1;
    let mut estimator = Estimator::<4>::new(&PV, config(dt, 1.0, 0.001)).unwrap();
    let mut obs = [0.0f32; 2];
    for k in 0..30 {
        estimator.step(&[k as f32 * dt], &mut obs).unwrap();
    }
    (estimator, obs)
}

#[test]
fn nan_infinite_and_out_of_range_readings_are_rejected_and_the_prediction_held() {
    for bad in [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        100.0,
        -250.0,
        1e30,
    ] {
        let (mut estimator, before) = converged();
        let mut obs = [0.0f32; 2];
        let report = estimator.step(&[bad], &mut obs).unwrap();
        assert_eq!(report.rejected, 1, "{bad}");
        assert_eq!(report.first_rejected, Some(0), "{bad}");
        assert!(
            obs.iter().all(|x| x.is_finite()),
            "{bad} reached the estimate: {obs:?}"
        );
        // The prediction: one step further at the estimated rate, rate unchanged.
        assert!(
            (obs[0] - (before[0] + 0.1 * before[1])).abs() < 1e-5,
            "{bad}: {obs:?}"
        );
        assert_eq!(obs[1], before[1], "{bad}");
        // The next good reading is taken again.
        let report = estimator.step(&[3.1], &mut obs).unwrap();
        assert_eq!(report.rejected, 0);
        assert!(
            (obs[0] - 3.1).abs() < 1e-3 && (obs[1] - 1.0).abs() < 1e-2,
            "{obs:?}"
        );
    }
}

#[test]
fn a_bad_direct_reading_holds_the_last_valid_one() {
    let channels = [Channel::Position, Channel::Direct];
    let mut estimator = Estimator::<4>::new(&channels, config(0.1, 1.0, 0.0)).unwrap();
    let mut obs = [0.0f32; 2];
    estimator.step(&[0.0, 4.0], &mut obs).unwrap();
    let report = estimator.step(&[0.1, f32::NAN], &mut obs).unwrap();
    assert_eq!((report.rejected, report.first_rejected), (1, Some(1)));
    assert_eq!(obs[1], 4.0);
}

#[test]
fn no_estimate_is_given_before_a_valid_reading() {
    let mut estimator = Estimator::<4>::new(&PV, config(0.1, 1.0, 0.0)).unwrap();
    let mut obs = [-9.0f32; 2];
    assert_eq!(
        estimator.step(&[f32::NAN], &mut obs),
        Err(Error::NotReady { index: 0 })
    );
    assert_eq!(obs, [-9.0, -9.0], "nothing written without an estimate");
    estimator.step(&[0.5], &mut obs).unwrap();
    assert_eq!(obs, [0.5, 0.0]);
    estimator.reset();
    assert!(estimator.step(&[f32::NAN], &mut obs).is_err());
}

#[test]
fn bad_layouts_configs_and_lengths_are_typed_errors() {
    let ok = config(0.1, 1.0, 0.0);
    let rate_of_rate = [
        Channel::Position,
        Channel::Rate { of: 0, scale: 1.0 },
        Channel::Rate { of: 1, scale: 1.0 },
    ];
    assert_eq!(
        Estimator::<4>::new(&rate_of_rate, ok).err(),
        Some(Error::BadRate { index: 2, of: 1 })
    );
    let dangling = [Channel::Rate { of: 5, scale: 1.0 }];
    assert!(matches!(
        Estimator::<4>::new(&dangling, ok),
        Err(Error::BadRate { index: 0, of: 5 })
    ));
    let nan_scale = [
        Channel::Position,
        Channel::Rate {
            of: 0,
            scale: f32::NAN,
        },
    ];
    assert!(Estimator::<4>::new(&nan_scale, ok).is_err());
    assert_eq!(
        Estimator::<1>::new(&PV, ok).err(),
        Some(Error::ChannelCount {
            found: 2,
            capacity: 1
        })
    );
    assert!(Estimator::<4>::new(&[], ok).is_err());
    for (field, bad) in [
        ("dt", EstimatorConfig { dt: 0.0, ..ok }),
        ("dt", EstimatorConfig { dt: f32::NAN, ..ok }),
        (
            "accel_std",
            EstimatorConfig {
                accel_std: -1.0,
                ..ok
            },
        ),
        (
            "meas_std",
            EstimatorConfig {
                meas_std: f32::INFINITY,
                ..ok
            },
        ),
        ("limit", EstimatorConfig { limit: 0.0, ..ok }),
        (
            "initial_rate_std",
            EstimatorConfig {
                initial_rate_std: 0.0,
                ..ok
            },
        ),
    ] {
        assert_eq!(
            Estimator::<4>::new(&PV, bad).err(),
            Some(Error::BadConfig { field })
        );
    }
    let mut estimator = Estimator::<4>::new(&PV, ok).unwrap();
    let mut obs = [0.0f32; 2];
    assert!(matches!(
        estimator.step(&[0.0, 0.0], &mut obs),
        Err(Error::WrongLength {
            input: "readings",
            expected: 1,
            found: 2
        })
    ));
    assert!(matches!(
        estimator.step(&[0.0], &mut obs[..1]),
        Err(Error::WrongLength {
            input: "obs",
            expected: 2,
            found: 1
        })
    ));
}
