//! Which observation entries carry a policy's cost of the device's sensors (issue 73): the float
//! meta-policy on the meta-test tasks with the sensor model (noise, then the ADC: `sim::Sensor`,
//! the device's) on every entry, then on one entry at a time, the others read as they are.
//!
//! ```sh
//! cargo run --release -p trainer --example sensor_entries -- \
//!   --policy assets/policies/cheetah-vel-rapier-smile-bc \
//!   --contexts assets/experts/cheetah-vel/demos-test-4x-sub20.safetensors \
//!   --noise 0.01 --adc-bits 12 --draws 2
//! ```
//!
//! One-demo contexts (draw d teaches demo d), one deterministic episode per task and draw, the
//! same reset seeds and sensor seeds in every column, so the columns differ by the sensed entries
//! alone. Prints a markdown table: each entry's metric, its change against clean readings, the
//! entry's std over the demos' states (the scale the noise meets) and the share of those states
//! beyond the ADC's full scale (what the converter clips).

use std::path::PathBuf;
use std::process::ExitCode;

use sim::{DemoDataset, EnvConfig, SensorModel};
use trainer::{MetaPolicy, run_episode};

struct Args {
    policy: PathBuf,
    contexts: PathBuf,
    model: SensorModel,
    draws: usize,
}

fn parse() -> Result<Args, String> {
    let mut it = std::env::args().skip(1);
    let (mut policy, mut contexts) = (None, None);
    let (mut model, mut draws) = (SensorModel::default(), 2usize);
    while let Some(flag) = it.next() {
        let value = it.next().ok_or(format!("{flag} needs a value"))?;
        let number = |what: &str| {
            value
                .parse::<f32>()
                .map_err(|e| format!("{what} {value}: {e}"))
        };
        match flag.as_str() {
            "--policy" => policy = Some(PathBuf::from(&value)),
            "--contexts" => contexts = Some(PathBuf::from(&value)),
            "--noise" => model.noise_std = number("--noise")?,
            "--adc-range" => model.adc_range = number("--adc-range")?,
            "--adc-bits" => {
                model.adc_bits = Some(value.parse().map_err(|e| format!("--adc-bits: {e}"))?)
            }
            "--draws" => {
                draws = value
                    .parse()
                    .ok()
                    .filter(|d| (1..=64).contains(d))
                    .ok_or(format!("--draws {value}: expected 1 to 64"))?
            }
            other => return Err(format!("unknown flag {other}")),
        }
    }
    model.check().map_err(|e| e.to_string())?;
    Ok(Args {
        policy: policy.ok_or("--policy is required")?,
        contexts: contexts.ok_or("--contexts is required")?,
        model,
        draws,
    })
}

/// The policy's mean metric over the tasks and draws with the sensors on the entries `sensed`
/// selects (sensor seeded per episode as the device's loop seeds it with its run's).
fn metric(mp: &MetaPolicy, demos: &DemoDataset, a: &Args, sensed: &dyn Fn(usize) -> bool) -> f32 {
    let mut env = sim::make_env(mp.family, EnvConfig::new(None, mp.physics)).expect("plant");
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(0);
    let (mut sum, mut n) = (0.0f64, 0usize);
    for td in &demos.tasks {
        for d in 0..a.draws {
            let demo = &td.trajectories[d % td.trajectories.len()];
            let z = mp.latent(&[demo]).expect("latent");
            let seed = sim::seeds::EVALUATION_SEED + d as u64;
            let mut sensor = sim::Sensor::new(a.model, seed).expect("checked model");
            let mut read = Vec::new();
            let ep = run_episode(
                env.as_mut(),
                &td.task,
                seed,
                &mut |o, act| {
                    read.clear();
                    for (i, &x) in o.iter().enumerate() {
                        // Every entry draws its reading, so the noise an entry gets is the same
                        // in every column that senses it.
                        let r = sensor.read(x);
                        read.push(if sensed(i) { r } else { x });
                    }
                    act.copy_from_slice(&mp.act(&read, &z, true, &mut rng)?);
                    Ok(())
                },
                &mut |_| Ok(()),
            )
            .expect("episode");
            sum += ep.metric as f64;
            n += 1;
        }
    }
    (sum / n as f64) as f32
}

fn main() -> ExitCode {
    let a = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let mp = match MetaPolicy::load(&a.policy) {
        Ok(mp) => mp,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let demos = match DemoDataset::read(&a.contexts) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let od = demos.obs_dim;
    let states: Vec<&[f32]> = demos
        .tasks
        .iter()
        .flat_map(|t| &t.trajectories)
        .flat_map(|tr| tr.obs.chunks_exact(od))
        .collect();
    let clipped = |i: usize| {
        let range = a
            .model
            .adc_bits
            .map_or(f32::INFINITY, |_| a.model.adc_range);
        states.iter().filter(|s| s[i].abs() > range).count() as f64 / states.len() as f64
    };
    let std = |i: usize| {
        let m = states.iter().map(|s| s[i] as f64).sum::<f64>() / states.len() as f64;
        let v = states
            .iter()
            .map(|s| (s[i] as f64 - m).powi(2))
            .sum::<f64>()
            / states.len() as f64;
        v.sqrt()
    };
    let clean = metric(&mp, &demos, &a, &|_| false);
    let all = metric(&mp, &demos, &a, &|_| true);
    println!(
        "{} on {} tasks x {} draws, sensors {:?}\n",
        a.policy.display(),
        demos.tasks.len(),
        a.draws,
        a.model
    );
    println!("| sensed | metric | change against clean | entry's demo std | demo states clipped |");
    println!("|---|---|---|---|---|");
    println!("| none | {clean:.4} | | | |");
    let pct = |m: f32| 100.0 * (m - clean) / clean;
    println!("| every entry | {all:.4} | {:+.1}% | | |", pct(all));
    for i in 0..od {
        let m = metric(&mp, &demos, &a, &|j| j == i);
        let share = 100.0 * clipped(i);
        println!(
            "| entry {i} | {m:.4} | {:+.1}% | {:.4} | {share:.1}% |",
            pct(m),
            std(i)
        );
    }
    ExitCode::SUCCESS
}
