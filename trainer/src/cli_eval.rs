//! `smile eval` and `smile export`.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::ProgressBar;
use sim::{DemoDataset, EnvConfig, Family, Split};
use trainer::eval::{self, EvalReport, Protocol};
use trainer::eval_norm::References;
use trainer::export;
use trainer::meta_policy::MetaPolicy;

/// Arguments of `smile eval`.
#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Trained run directories (or meta_policy.safetensors files); one line per method.
    #[arg(long, required = true, num_args = 1..)]
    policy: Vec<PathBuf>,
    /// Task family.
    #[arg(long, default_value = "point-goal")]
    env: String,
    /// Which tasks to evaluate on.
    #[arg(long, default_value = "test")]
    split: Split,
    /// Demos of those tasks, the contexts (`smile demos --split test`).
    #[arg(long)]
    contexts: PathBuf,
    /// Output directory for eval.json, eval.md and eval.svg.
    #[arg(short, long, default_value = "eval")]
    out: PathBuf,
    /// Override the protocol's rollouts per context draw.
    #[arg(long)]
    rollouts: Option<usize>,
    /// Override the protocol's context sizes (demos per context), e.g. `1,2,4`.
    #[arg(long, value_delimiter = ',', value_parser = clap::value_parser!(u32).range(1..))]
    context_sizes: Vec<u32>,
    /// Episode length override.
    #[arg(long)]
    horizon: Option<usize>,
    /// Also save one animated SVG episode per method (first task, first context trajectory).
    #[arg(long)]
    render: bool,
    /// walker-dyn normalised metric: the base policy, trained on the unmodified dynamics
    /// (`smile expert --env walker-dyn --nominal`). Needs --expert.
    #[arg(long, requires = "expert")]
    base: Option<PathBuf>,
    /// walker-dyn normalised metric: the experts, as for `smile demos --expert` (per-task
    /// experts, comma separated, each task uses its own; or one general expert). Needs --base.
    #[arg(long, requires = "base", num_args = 1.., value_delimiter = ',')]
    expert: Vec<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

fn env_cfg(horizon: Option<usize>) -> EnvConfig {
    EnvConfig {
        horizon,
        ..EnvConfig::default()
    }
}

fn bar(tasks: usize, quiet: bool, message: String) -> ProgressBar {
    let pb = trainer::progress::bar(tasks as u64, quiet, "tasks");
    pb.set_message(message);
    pb
}

/// Run `smile eval`.
pub fn run_eval(a: EvalArgs) -> Result<()> {
    let family: Family = a.env.parse().map_err(|e| anyhow::anyhow!("{e}"))?;
    let ctx = DemoDataset::read(&a.contexts)
        .with_context(|| format!("reading {}", a.contexts.display()))?;
    if ctx.split != a.split {
        bail!(
            "{} holds {} demos but --split is {}",
            a.contexts.display(),
            ctx.split,
            a.split
        );
    }
    let mut protocol = Protocol::for_family(family);
    if let Some(r) = a.rollouts {
        protocol.rollouts = r;
    }
    if !a.context_sizes.is_empty() {
        protocol.context_sizes = a.context_sizes.iter().map(|&k| k as usize).collect();
    }
    protocol.horizon = a.horizon;
    // Everything is loaded and checked before any rollout, so a wrong policy, context file,
    // base or expert fails fast.
    let mut policies = Vec::with_capacity(a.policy.len());
    for p in &a.policy {
        let mp = MetaPolicy::load(p).with_context(|| format!("loading {}", p.display()))?;
        if mp.family != family {
            bail!("{} was trained on {}, not {family}", p.display(), mp.family);
        }
        policies.push((p, mp));
    }
    eval::contexts_for(&ctx, family, &family.tasks(a.split))?;
    let references = match &a.base {
        Some(base) => Some(References::load(family, base, &a.expert)?),
        None => None,
    };
    std::fs::create_dir_all(&a.out)?;
    let reference = match &references {
        Some(refs) => {
            let pb = bar(family.tasks(a.split).len(), a.quiet, "base + expert".into());
            let r = refs.returns(a.split, &protocol, &mut |i, _| pb.set_position(i as u64))?;
            pb.finish_and_clear();
            eprintln!(
                "base {}: mean return {:.4}; expert {}: mean return {:.4}",
                r.base,
                r.base_mean(),
                r.expert,
                r.expert_mean()
            );
            Some(r)
        }
        None => None,
    };
    let mut methods = Vec::new();
    for (idx, (p, mut mp)) in policies.into_iter().enumerate() {
        let name = eval::display_name(&mp.algo, p);
        let pb = bar(family.tasks(a.split).len(), a.quiet, name.clone());
        let r = eval::evaluate(
            &mut mp,
            &name,
            family,
            a.split,
            &ctx,
            &protocol,
            &mut |i, _| pb.set_position(i as u64),
        )?;
        pb.finish_and_clear();
        eprintln!(
            "{name}: mean {:.4} +- {:.4} over tasks",
            r.mean, r.std_over_tasks
        );
        if a.render {
            let task = family.tasks(a.split)[0];
            let tds = eval::contexts_for(&ctx, family, &[task])?;
            let path = a.out.join(format!("episode-{idx}-{}.svg", mp.algo));
            let m = eval::render_episode(
                &mut mp,
                family,
                &task,
                &[&tds[0].trajectories[0]],
                env_cfg(a.horizon),
                &path,
            )?;
            eprintln!("rendered {} (metric {m:.3})", path.display());
        }
        methods.push(r);
    }
    let mut report = EvalReport::new(family, a.split, protocol, methods);
    if let Some(r) = reference {
        report = report.with_reference(r)?;
        for m in &report.methods {
            if let Some(n) = &m.normalised {
                let score = n.score.map_or("none".into(), |x| format!("{x:.4}"));
                eprintln!(
                    "{}: normalised score {score} over {} tasks ({} skipped: expert not better \
                     than base)",
                    m.name, n.tasks_used, n.tasks_skipped
                );
            }
        }
    }
    std::fs::write(
        a.out.join("eval.json"),
        serde_json::to_string_pretty(&report)?,
    )?;
    let md = report.markdown();
    std::fs::write(a.out.join("eval.md"), &md)?;
    report.plot_svg(&a.out.join("eval.svg"))?;
    println!("{md}");
    eprintln!("wrote {}/eval.json, eval.md, eval.svg", a.out.display());
    Ok(())
}

/// Arguments of `smile export`.
#[derive(Args, Debug)]
pub struct ExportArgs {
    /// Trained run directory (or meta_policy.safetensors).
    #[arg(long)]
    policy: PathBuf,
    /// Quantization: f32, w8a32 or w8a8.
    #[arg(long, default_value = "w8a8")]
    quant: String,
    /// Output blob file; a JSON report is written next to it (`<blob>.json`).
    #[arg(short, long)]
    out: PathBuf,
    /// Meta-train demos: calibration inputs for w8a8.
    #[arg(long)]
    demos: PathBuf,
    /// Held-out contexts (e.g. the meta-test demos) for the parity check and the metric.
    #[arg(long)]
    contexts: PathBuf,
    /// Override the protocol's rollouts per context draw in the metric check.
    #[arg(long)]
    rollouts: Option<usize>,
    /// Episode length override.
    #[arg(long)]
    horizon: Option<usize>,
}

/// Run `smile export`.
pub fn run_export(a: ExportArgs) -> Result<()> {
    let quant = export::parse_quant(&a.quant)?;
    let mp =
        MetaPolicy::load(&a.policy).with_context(|| format!("loading {}", a.policy.display()))?;
    let family = mp.family;
    let demos =
        DemoDataset::read(&a.demos).with_context(|| format!("reading {}", a.demos.display()))?;
    if demos.split != Split::Train {
        bail!(
            "--demos must be meta-train demos (calibration); {} is {}",
            a.demos.display(),
            demos.split
        );
    }
    let ctx = DemoDataset::read(&a.contexts)
        .with_context(|| format!("reading {}", a.contexts.display()))?;
    let blob = export::export_blob(&mp, quant, &demos)?;
    if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    trainer::checkpoint::write_atomic(&a.out, &blob)?;
    eprintln!(
        "wrote {} ({} bytes, {})",
        a.out.display(),
        blob.len(),
        a.quant
    );
    let mut protocol = Protocol::for_family(family);
    if let Some(r) = a.rollouts {
        protocol.rollouts = r;
    }
    protocol.horizon = a.horizon;
    let report = export::verify(&mp, &blob, &a.quant, &ctx, &protocol)?;
    let p = &report.parity;
    eprintln!(
        "parity on {} held-out contexts, {} actions: action max |diff| {:.3e}, mean {:.3e}; z max |diff| {:.3e}",
        p.contexts, p.actions, p.action_max_abs_diff, p.action_mean_abs_diff, p.z_max_abs_diff
    );
    eprintln!(
        "{} on {} {} tasks: blob {:.4}, candle {:.4} (relative difference {:+.2}%)",
        report.metric,
        family,
        report.split,
        report.metric_blob,
        report.metric_candle,
        100.0 * report.metric_relative_difference
    );
    let json = a.out.with_extension(format!(
        "{}.json",
        a.out.extension().and_then(|e| e.to_str()).unwrap_or("blob")
    ));
    std::fs::write(&json, serde_json::to_string_pretty(&report)?)?;
    eprintln!("wrote {}", json.display());
    Ok(())
}
