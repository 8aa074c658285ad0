//! `smile eval`: meta-policies on a split's tasks with the paper's protocol.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use indicatif::ProgressBar;
use sim::{Family, Split};
use trainer::eval::{self, EvalEvent, EvalRequest};

/// Arguments of `smile eval`.
#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Trained run directories (or meta_policy.safetensors files); one line per method.
    #[arg(long, required = true, num_args = 1..)]
    policy: Vec<PathBuf>,
    /// Task family: point-goal, cheetah-vel, walker-dyn, ant-goal or ant-linclass [default:
    /// the --contexts file's; the policies must be of it].
    #[arg(long)]
    env: Option<Family>,
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
    #[arg(long, value_parser = crate::horizon)]
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
    /// Score the tasks the --contexts file holds instead of a split's: new tasks recorded with
    /// `smile demos --task-params` (what a few-shot learner is for).
    #[arg(long)]
    contexts_tasks: bool,
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

/// Run `smile eval`.
pub fn run(a: EvalArgs) -> Result<()> {
    // As `smile train` does: the family is the demo file's unless --env names one (which the
    // file must then hold; the library checks it and the policies against it).
    let env = match a.env {
        Some(env) => env,
        None => trainer::read_demos(&a.contexts, trainer::Input::Contexts)?.family,
    };
    let mut req = EvalRequest::new(
        a.policy.clone(),
        env,
        a.split,
        a.contexts.clone(),
        a.out.clone(),
    );
    req.rollouts = a.rollouts;
    req.context_sizes = a.context_sizes.iter().map(|&k| k as usize).collect();
    req.horizon = a.horizon;
    req.action_noise = a.action_noise;
    req.run_through_falls = a.walker_protocol == WalkerProtocol::Authors;
    req.render = a.render;
    req.base = a.base.clone();
    req.experts = a.expert.clone();
    req.allow_unfinished = a.allow_unfinished;
    req.contexts_tasks = a.contexts_tasks;
    let mut pb: Option<ProgressBar> = None;
    let report = eval::evaluate_to_dir(&req, &mut |e| match e {
        EvalEvent::Note(text) => eprintln!("{text}"),
        EvalEvent::Method { name, tasks } => {
            let bar = smile_app::progress::bar(tasks as u64, a.quiet, "tasks");
            bar.set_message(name);
            pb = Some(bar);
        }
        EvalEvent::Task(i) => {
            if let Some(bar) = &pb {
                bar.set_position(i as u64);
            }
        }
        EvalEvent::MethodDone => {
            if let Some(bar) = pb.take() {
                bar.finish_and_clear();
            }
        }
    })?;
    println!("{}", report.markdown());
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
