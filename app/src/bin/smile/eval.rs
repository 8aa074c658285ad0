//! `smile eval`: meta-policies on a split's tasks with the paper's protocol.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::ProgressBar;
use sim::{Family, Split};
use trainer::MetaPolicy;
use trainer::eval::norm::References;
use trainer::eval::{self, EvalReport, Protocol};

/// Arguments of `smile eval`.
#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Trained run directories (or meta_policy.safetensors files); one line per method.
    #[arg(long, required = true, num_args = 1..)]
    policy: Vec<PathBuf>,
    /// Task family: point-goal, cheetah-vel, walker-dyn, ant-goal or ant-linclass.
    #[arg(long, default_value = "point-goal")]
    env: Family,
    /// Which tasks to evaluate on.
    #[arg(long, default_value = "test")]
    split: Split,
    /// Demos of those tasks, the contexts (`smile demos --split test`).
    #[arg(long)]
    contexts: PathBuf,
    /// Output directory for eval.json, eval.md and eval.svg.
    #[arg(short, long, default_value = "eval")]
    out: PathBuf,
    /// Override the protocol's rollouts per context draw (at least 1).
    #[arg(long, value_parser = crate::positive)]
    rollouts: Option<usize>,
    /// Override the protocol's context sizes (demos per context), e.g. `1,2,4`.
    #[arg(long, value_delimiter = ',', value_parser = clap::value_parser!(u32).range(1..))]
    context_sizes: Vec<u32>,
    /// Episode length override (at least 1).
    #[arg(long, value_parser = crate::positive)]
    horizon: Option<usize>,
    /// Standard deviation of Gaussian noise added to every action before the plant clips it
    /// (a compounding-error probe; seeded per episode). 0 is the paper's protocol.
    #[arg(long, default_value_t = 0.0, value_parser = parse_noise)]
    action_noise: f32,
    /// walker-dyn evaluation protocol: `falls-end` (this project's: a fall ends the episode)
    /// or `authors` (the SMILe authors' `terminal = False`: every episode runs the whole
    /// horizon and the alive bonus keeps accruing after a fall; returns compare with the
    /// paper's). The report records which.
    #[arg(long, value_enum, default_value_t = WalkerProtocol::FallsEnd)]
    walker_protocol: WalkerProtocol,
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
    /// Evaluate a policy whose training did not finish (killed or still running), with a
    /// warning, instead of refusing it.
    #[arg(long)]
    allow_unfinished: bool,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// `--walker-protocol`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum WalkerProtocol {
    /// A fall ends the episode (this project's protocol).
    FallsEnd,
    /// Episodes run through falls, alive bonus included (the SMILe authors' walker evaluation).
    Authors,
}

fn bar(tasks: usize, quiet: bool, message: String) -> ProgressBar {
    let pb = trainer::progress_bar(tasks as u64, quiet, "tasks");
    pb.set_message(message);
    pb
}

/// Run `smile eval`.
pub fn run(a: EvalArgs) -> Result<()> {
    let family = a.env;
    let ctx = crate::read_demos(&a.contexts, "--contexts", family)?;
    if ctx.split != a.split {
        bail!(
            "--contexts {} holds {} demos but --split is {}; pass --split {} or the {} demos",
            a.contexts.display(),
            ctx.split,
            a.split,
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
    protocol.action_noise = a.action_noise;
    if a.walker_protocol == WalkerProtocol::Authors {
        if family != Family::WalkerDyn {
            bail!("--walker-protocol authors is walker-dyn's evaluation, not {family}'s");
        }
        protocol.run_through_falls = true;
        eprintln!("walker protocol: {}", protocol.label());
    }
    // Everything is loaded and checked before any rollout, so a wrong policy, context file,
    // base or expert fails fast.
    let mut policies = Vec::with_capacity(a.policy.len());
    for p in &a.policy {
        let mp = MetaPolicy::load(p).with_context(|| format!("loading {}", p.display()))?;
        MetaPolicy::ensure_finished(p, a.allow_unfinished)?;
        if mp.family != family {
            bail!(
                "{} was trained on {}, not {family} (--env); pass --env {}",
                p.display(),
                mp.family,
                mp.family
            );
        }
        policies.push((p, mp));
    }
    // The episodes run on the plant the policies were trained on; all of them the same one.
    if let Some((first, mp)) = policies.first() {
        protocol.physics = mp.physics;
        if let Some((p, other)) = policies.iter().find(|(_, m)| m.physics != mp.physics) {
            bail!(
                "{} was trained on the {} plant, {} on {}: evaluate each plant's policies apart",
                first.display(),
                mp.physics,
                p.display(),
                other.physics
            );
        }
    }
    ctx.ensure_physics(protocol.physics)
        .with_context(|| format!("--contexts {}", a.contexts.display()))?;
    eval::contexts_for(&ctx, family, &family.tasks(a.split))
        .with_context(|| format!("--contexts {}", a.contexts.display()))?;
    let references = match &a.base {
        Some(base) => Some(References::load(family, base, &a.expert)?),
        None => None,
    };
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("creating the output directory {}", a.out.display()))?;
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
                protocol.env_config(),
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
    // eval.json last: a sweep counts a cell done by it, so it must mean the rest was written.
    let md = report.markdown();
    trainer::checkpoint::write_atomic(&a.out.join("eval.md"), md.as_bytes())?;
    report.plot_svg(&a.out.join("eval.svg"))?;
    trainer::checkpoint::write_atomic(
        &a.out.join("eval.json"),
        serde_json::to_string_pretty(&report)?.as_bytes(),
    )?;
    println!("{md}");
    eprintln!("wrote {}/eval.json, eval.md, eval.svg", a.out.display());
    Ok(())
}

/// `--action-noise`: a finite standard deviation in [0, 10].
fn parse_noise(text: &str) -> std::result::Result<f32, String> {
    let sigma: f32 = text
        .parse()
        .map_err(|e| format!("`{text}` is not a number: {e}"))?;
    if sigma.is_finite() && (0.0..=10.0).contains(&sigma) {
        Ok(sigma)
    } else {
        Err(format!(
            "{text}: expected a standard deviation from 0 to 10"
        ))
    }
}
