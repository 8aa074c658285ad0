//! The device metric with position-only sensing (on-device estimator) vs full-state sensing,
//! at sensor noise 0, 0.01 and 0.05 (12-bit ADC over +-4, as the quickstart's device stage),
//! over the test tasks that have a demo in the contexts file and a few reset seeds; then the
//! estimator's own cost per tick.
//!
//! ```sh
//! cargo run -p firmware-sim --release --example pd_blob -- runs/pd
//! cargo run -p firmware-sim --release --example sensing_compare -- point-goal runs/pd/pd.blob runs/pd/demos.safetensors 3
//! ```
//!
//! Arguments: family, blob, contexts, seeds per task (default 3), and optionally the
//! estimator's acceleration std (default: the family's).

use std::time::Instant;

use firmware_sim::{LoopConfig, Sensing, SessionConfig, run_session};
use infer_core::{Channel, Estimator, EstimatorConfig};
use sim::{DemoDataset, EnvConfig, Family};

fn mean_std(v: &[f32]) -> (f32, f32) {
    let n = v.len().max(1) as f32;
    let mean = v.iter().sum::<f32>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / n;
    (mean, var.sqrt())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        return Err("usage: sensing_compare FAMILY BLOB CONTEXTS [SEEDS] [ACCEL_STD]".into());
    }
    let family: Family = args[0].parse()?;
    let blob = std::fs::read(&args[1])?;
    let demos = DemoDataset::read(&args[2])?;
    demos.ensure_family(family)?;
    let seeds: u64 = args.get(3).map_or(Ok(3), |s| s.parse())?;
    let accel_std: Option<f32> = args.get(4).map(|s| s.parse()).transpose()?;
    let tasks: Vec<_> = family
        .test_tasks()
        .into_iter()
        .filter_map(|task| {
            let demo = demos
                .tasks
                .iter()
                .find(|t| t.task == task && !t.trajectories.is_empty())?;
            Some((task, &demo.trajectories[0]))
        })
        .collect();
    println!(
        "{family}: {} test tasks x {seeds} seeds, accel_std {}",
        tasks.len(),
        accel_std.unwrap_or_else(|| firmware_sim::estimation::default_accel_std(family))
    );
    println!(
        "| noise | full sensing | positions + estimator | difference | faults | median tick us (full / positions) |"
    );
    println!("|---|---|---|---|---|---|");
    for noise_std in [0.0f32, 0.01, 0.05] {
        let mut metrics = [Vec::new(), Vec::new()];
        let mut ticks_ns = [Vec::new(), Vec::new()];
        let mut faults = 0;
        for (task, demo) in &tasks {
            for seed in 0..seeds {
                for (k, sensing) in [
                    Sensing::Full,
                    Sensing::Positions {
                        accel_std,
                        meas_std: None,
                    },
                ]
                .into_iter()
                .enumerate()
                {
                    let config = SessionConfig {
                        control: LoopConfig {
                            noise_std,
                            adc_bits: Some(12),
                            adc_range: 4.0,
                            seed,
                            sensing,
                            ..LoopConfig::default()
                        },
                        plant: EnvConfig::default(),
                        ..SessionConfig::default()
                    };
                    let session = run_session(&blob, task, &[demo], &config)?;
                    metrics[k].push(session.report.metric);
                    ticks_ns[k].extend_from_slice(&session.report.compute_ns);
                    if k == 1 {
                        faults += session.report.faults;
                    }
                }
            }
        }
        let (full, full_std) = mean_std(&metrics[0]);
        let (pos, pos_std) = mean_std(&metrics[1]);
        let median = |v: &mut Vec<u64>| {
            v.sort_unstable();
            v.get(v.len() / 2).copied().unwrap_or(0) as f64 / 1e3
        };
        println!(
            "| {noise_std} | {full:.4} +- {full_std:.4} | {pos:.4} +- {pos_std:.4} | {:+.1}% | {faults} | {:.2} / {:.2} |",
            100.0 * (pos - full) / full.abs().max(1e-9),
            median(&mut ticks_ns[0]),
            median(&mut ticks_ns[1]),
        );
    }
    estimator_cost(family)
}

/// The estimator alone, per tick, on this family's layout: best of 5 timed passes.
fn estimator_cost(family: Family) -> Result<(), Box<dyn std::error::Error>> {
    let channels: &[Channel] = family.obs_components();
    let config = EstimatorConfig {
        dt: 0.05,
        accel_std: 2.0,
        meas_std: 0.01,
        limit: 10.0,
        initial_rate_std: 1.0,
    };
    let mut estimator = Estimator::<64>::new(channels, config)?;
    let readings: Vec<f32> = (0..estimator.readings_len())
        .map(|i| 0.1 * i as f32)
        .collect();
    let mut obs = vec![0.0f32; estimator.obs_len()];
    let mut readings_t = readings.clone();
    let n = 200_000;
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let start = Instant::now();
        for t in 0..n {
            readings_t[0] = readings[0] + 1e-6 * (t % 100) as f32;
            std::hint::black_box(estimator.step(std::hint::black_box(&readings_t), &mut obs)?);
        }
        best = best.min(start.elapsed().as_nanos() as f64 / n as f64);
    }
    println!(
        "estimator step ({} readings -> {} obs, capacity 64): {best:.0} ns per tick (best of 5 x {n}); size {} B",
        estimator.readings_len(),
        estimator.obs_len(),
        std::mem::size_of::<Estimator<64>>()
    );
    Ok(())
}
