//! `smile distill`: a trained meta-policy distilled to act through the device's senses
//! (`trainer::distill_through_sensing`): its actor, taught by itself on true states, learns to
//! act from what the device reads. Writes a policy folder that `smile eval`, `smile export` and
//! `docs/scripts/robust-ship.sh` take as any other.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use trainer::{DistillConfig, MetaPolicy};

/// Arguments of `smile distill`.
#[derive(Args, Debug)]
pub struct DistillArgs {
    /// The trained policy: a run directory or a shipped policy folder.
    #[arg(long)]
    policy: PathBuf,
    /// Its meta-train demos: each task's latent and the demo states read perfectly.
    #[arg(long)]
    demos: PathBuf,
    /// A TOML file whose `[sensing]` section is what the device reads (presets:
    /// docs/configs/sensing-noise01-adc12.toml, sensing-positions.toml). Several (comma or
    /// repeated): one student for each sensor, the rounds taking them in turn.
    #[arg(long, value_delimiter = ',', required = true)]
    sensing: Vec<PathBuf>,
    /// Adam steps in all.
    #[arg(long, default_value_t = 4000, value_parser = crate::positive)]
    steps: usize,
    /// DAgger rounds: the student's closed loops through the sensors, then steps / rounds steps.
    #[arg(long, default_value_t = 4, value_parser = crate::positive)]
    rounds: usize,
    /// Episode length of the closed loops, control steps (default: the family's).
    #[arg(long, value_parser = crate::horizon)]
    horizon: Option<usize>,
    /// Seed of the closed loops' resets and sensors and of the batches.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output folder: meta_policy.safetensors, the source's config.toml and run.json, and
    /// distill.json (what the distillation did).
    #[arg(short, long)]
    out: PathBuf,
}

/// Run `smile distill`.
pub fn run(a: DistillArgs) -> Result<()> {
    let teacher =
        MetaPolicy::load(&a.policy).with_context(|| format!("--policy {}", a.policy.display()))?;
    let demos = trainer::read_demos_of(&a.demos, trainer::Input::Demos, teacher.family)?;
    let sensings = a
        .sensing
        .iter()
        .map(|p| crate::train::sensing_preset(p))
        .collect::<Result<Vec<_>>>()?;
    let (sensing, also) = (sensings[0], sensings[1..].to_vec());
    let env = sim::EnvConfig {
        horizon: a.horizon,
        physics: teacher.physics,
        ..sim::EnvConfig::default()
    };
    let cfg = DistillConfig {
        rounds: a.rounds,
        seed: a.seed,
        also,
        ..DistillConfig::new(sensing, a.steps, env)
    };
    let (student, report) = trainer::distill_through_sensing(&teacher, &demos, &cfg)?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mark = MetaPolicy::training_mark(&a.policy)?;
    student.save_marked(&a.out, mark)?;
    for file in ["config.toml", "run.json"] {
        let from = if a.policy.is_dir() {
            a.policy.join(file)
        } else {
            a.policy.with_file_name(file)
        };
        if from.is_file() {
            std::fs::copy(&from, a.out.join(file))
                .with_context(|| format!("copying {}", from.display()))?;
        }
    }
    let json = serde_json::json!({
        "source": a.policy,
        "sensing": sensings,
        "steps": cfg.steps,
        "rounds": cfg.rounds,
        "episodes_per_task_and_round": cfg.episodes,
        "lr": cfg.lr,
        "batch": cfg.batch,
        "seed": cfg.seed,
        "horizon": a.horizon,
        "report": report,
    });
    trainer::checkpoint::write_atomic(
        &a.out.join("distill.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
    )?;
    println!(
        "distilled {} through the sensors: {} rows ({} closed-loop ticks), {} steps; the action \
         gap |a(read) - a(truth)| {:.4} -> {:.4}; wrote {}",
        a.policy.display(),
        report.rows,
        report.closed_loop_ticks,
        report.steps,
        report.action_gap_before,
        report.action_gap_after,
        a.out.display()
    );
    Ok(())
}
