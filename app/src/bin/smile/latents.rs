//! `smile latents`: z of a meta-policy's encoder for every task's context draws (CSV), and how
//! well a linear probe reads the task parameter back from z.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use sim::{Family, Split};
use trainer::MetaPolicy;
use trainer::eval::latents;

/// Arguments of `smile latents`.
#[derive(Args, Debug)]
pub struct LatentsArgs {
    /// A trained run directory (or its meta_policy.safetensors).
    #[arg(long)]
    policy: PathBuf,
    /// Task family: point-goal, cheetah-vel, walker-dyn, ant-goal or ant-linclass.
    #[arg(long)]
    env: Family,
    /// Which tasks.
    #[arg(long, default_value = "test")]
    split: Split,
    /// Demos of those tasks, the contexts.
    #[arg(long)]
    contexts: PathBuf,
    /// Context sizes (demos per context), e.g. `1,2,4,8`.
    #[arg(long, value_delimiter = ',', default_value = "1", value_parser = clap::value_parser!(u32).range(1..))]
    context_sizes: Vec<u32>,
    /// Context draws per task and size (the evaluation's draws: the same contexts; at least 1).
    #[arg(long, default_value_t = 3, value_parser = crate::positive)]
    draws: usize,
    /// Use a policy whose training did not finish, with a warning, instead of refusing it.
    #[arg(long)]
    allow_unfinished: bool,
    /// Output CSV (task_value, context_size, draw, param_*, z_*).
    #[arg(short, long)]
    out: PathBuf,
}

/// Run `smile latents`.
pub fn run(a: LatentsArgs) -> Result<()> {
    let family = a.env;
    let ctx = trainer::read_demos_of(&a.contexts, trainer::Input::Contexts, family)?;
    if ctx.split != a.split {
        bail!(
            "--contexts {} holds {} demos but --split is {}",
            a.contexts.display(),
            ctx.split,
            a.split
        );
    }
    let mut policy =
        MetaPolicy::load(&a.policy).with_context(|| format!("--policy {}", a.policy.display()))?;
    if let Some(warning) = MetaPolicy::ensure_finished(&a.policy, a.allow_unfinished)? {
        eprintln!("{warning}");
    }
    if policy.family != family {
        bail!(
            "--policy {} is a {} policy but --env is {family}",
            a.policy.display(),
            policy.family
        );
    }
    // The contexts' states come from a plant; a policy of the other plant would encode them
    // into latents that mean nothing (eval, export and the device refuse the same mix).
    ctx.ensure_physics(policy.physics).map_err(|e| {
        anyhow::anyhow!(
            "--contexts {} for --policy {} (trained on the {} plant): {e}",
            a.contexts.display(),
            a.policy.display(),
            policy.physics
        )
    })?;
    let sizes: Vec<usize> = a.context_sizes.iter().map(|&k| k as usize).collect();
    let fewest = ctx
        .tasks
        .iter()
        .map(|t| t.trajectories.iter().filter(|tr| !tr.is_empty()).count())
        .min()
        .unwrap_or(0);
    if let Some(k) = sizes.iter().find(|&&k| k > fewest) {
        eprintln!(
            "note: --contexts has only {fewest} demos for some task: contexts of {k} use all of \
             them (rows still say {k})"
        );
    }
    let rows = latents::latents(&mut policy, family, a.split, &ctx, &sizes, a.draws)?;
    if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    latents::write_csv(&rows, &a.out)?;
    println!(
        "wrote {}: {} rows ({} tasks x {} sizes x {} draws)",
        a.out.display(),
        rows.len(),
        family.tasks(a.split).len(),
        sizes.len(),
        a.draws
    );
    println!(
        "linear probe of the task parameter from z, leave-one-task-out R^2 per parameter \
         dimension (1: z encodes it linearly; 0 or below: no linear trace):"
    );
    for k in sizes {
        let of_size: Vec<_> = rows
            .iter()
            .filter(|r| r.context_size == k)
            .cloned()
            .collect();
        let r2 = latents::probe_r2(&of_size)?;
        let cells: Vec<String> = r2.iter().map(|x| format!("{x:.3}")).collect();
        let mean = r2.iter().filter(|x| x.is_finite()).sum::<f64>()
            / r2.iter().filter(|x| x.is_finite()).count().max(1) as f64;
        println!("  {k} context demos: mean {mean:.3} [{}]", cells.join(", "));
    }
    Ok(())
}
