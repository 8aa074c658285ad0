//! `smile demos`: deterministic expert demonstrations in sim's dataset format.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;
use sim::{EnvConfig, Family, Split, Task};
use trainer::expert::ExpertSet;
use trainer::{DemoSpec, record_demos_with};

/// Arguments of `smile demos`.
#[derive(Args, Debug)]
pub struct DemosArgs {
    /// Task family: point-goal, cheetah-vel, walker-dyn, ant-goal or ant-linclass.
    #[arg(long)]
    env: Family,
    /// Which task list to record (also the split label stored in the file).
    #[arg(long, default_value = "train")]
    split: String,
    /// Explicit task parameters instead of the split's tasks: goal angles (rad), target
    /// velocities (m/s) or dynamics seeds, comma separated.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    task_params: Option<Vec<f64>>,
    /// Trajectories per task (at least 1).
    #[arg(long, default_value_t = 4, value_parser = crate::positive)]
    per_task: usize,
    /// Subsampling factor k, at least 1 (keep step t when t mod k equals a per-trajectory
    /// random offset; 1 keeps every step).
    #[arg(long, default_value_t = 1, value_parser = crate::positive)]
    subsample: usize,
    /// Expert: a run directory of `smile expert` or its policy.safetensors. Repeat (or give
    /// several, comma separated) for per-task experts: each task uses the expert trained on it
    /// (`smile expert --task-value`), else the one general expert.
    #[arg(long, required = true, num_args = 1.., value_delimiter = ',')]
    expert: Vec<PathBuf>,
    /// Base reset seed (trajectory j uses seed + j; also seeds the subsampling offsets).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Reset each task's demos from seeds no other task uses (trajectory j of task i:
    /// seed + i * per_task + j), not the same seeds in every task. Where tasks share their
    /// goals (ant-linclass' two targets) the file then holds tasks x per_task starts instead of
    /// per_task.
    #[arg(long)]
    distinct_starts: bool,
    /// Physics backend to record on [default: the expert's, from its policy file]; an
    /// expert trained on another plant is refused.
    #[arg(long)]
    physics: Option<sim::Physics>,
    /// Episode length override (at least 1).
    #[arg(long, value_parser = crate::horizon)]
    horizon: Option<usize>,
    /// Output dataset file.
    #[arg(short, long)]
    out: PathBuf,
}

/// The task a `--task-params` value names (sim's tolerant lookup: a split's task when the value
/// is within the family's tolerance of it, else a new task), saying which when it matched one.
fn named_task(family: Family, value: f64) -> Result<Task> {
    let task = family.task_named(value)?;
    if let Some(split) = [Split::Train, Split::Test]
        .into_iter()
        .find(|s| family.tasks(*s).contains(&task))
    {
        eprintln!(
            "--task-params {value}: the {split} task {} (value {})",
            task.label(),
            task.value()
        );
    }
    Ok(task)
}

/// Run `smile demos`.
pub fn run(a: DemosArgs) -> Result<()> {
    let family = a.env;
    let split: Split = a.split.parse().map_err(anyhow::Error::msg)?;
    let ex = ExpertSet::load(&a.expert)?;
    if ex.family() != family {
        bail!("the expert is for {}, not {}", ex.family(), family);
    }
    let tasks = match &a.task_params {
        Some(vs) => vs
            .iter()
            .map(|&v| named_task(family, v))
            .collect::<Result<Vec<_>>>()?,
        None => family.tasks(split),
    };
    // Which expert acts in each task, when there is a choice (per-task experts); a task no
    // expert covers fails here, before any recording.
    for task in &tasks {
        let choice = ex.describe_choice(task)?;
        if a.expert.len() > 1 {
            eprintln!("{}: expert {choice}", task.label());
        }
    }
    let spec = DemoSpec {
        tasks,
        split,
        per_task: a.per_task,
        subsample: a.subsample,
        seed: a.seed,
        distinct_starts: a.distinct_starts,
        env: EnvConfig {
            horizon: a.horizon,
            physics: a.physics.unwrap_or(ex.physics()),
            ..EnvConfig::default()
        },
    };
    let ds = record_demos_with(&ex, &spec)?;
    if let Some(parent) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .map_err(|e| anyhow::anyhow!("creating {}: {e}", parent.display()))?;
    }
    // Atomic: a kill or a full disk leaves the previous file whole.
    ds.write(&a.out)?;
    println!(
        "wrote {}: {} tasks x {} trajectories, {} transitions (subsample {}), {} plant, expert {}",
        a.out.display(),
        ds.tasks.len(),
        a.per_task,
        ds.transition_count(),
        ds.subsample_factor,
        ds.physics,
        ds.expert
    );
    Ok(())
}
