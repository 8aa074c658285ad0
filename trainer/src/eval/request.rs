//! An evaluation of trained runs into a directory, as `smile eval` and a sweep's cells make
//! it: the policies, contexts, plant and references checked before any rollout, every method
//! evaluated with the family's protocol (overrides applied), then `eval.md`, `eval.svg` and,
//! last, `eval.json` written (a sweep counts a cell done by that file).

use std::path::{Path, PathBuf};

use sim::{Family, Split, Task};

use super::norm::References;
use super::{EvalReport, MethodResult, Protocol, ReferenceReturns};
use crate::error::{Error, Input, Result};
use crate::model::MetaPolicy;

/// What to evaluate, where, and the protocol's overrides.
#[derive(Debug, Clone)]
pub struct EvalRequest {
    /// Trained run directories (or `meta_policy.safetensors` files); one method each.
    pub policies: Vec<PathBuf>,
    /// The family.
    pub family: Family,
    /// Which tasks to evaluate on.
    pub split: Split,
    /// Demos of those tasks, the contexts (`smile demos --split test`).
    pub contexts: PathBuf,
    /// Output directory for `eval.json`, `eval.md` and `eval.svg`.
    pub out: PathBuf,
    /// The protocol's rollouts per context draw; `None`: the family's.
    pub rollouts: Option<usize>,
    /// The protocol's context sizes; empty: the family's.
    pub context_sizes: Vec<usize>,
    /// Episode length override.
    pub horizon: Option<usize>,
    /// Gaussian action noise (0: the paper's protocol).
    pub action_noise: f32,
    /// walker-dyn: the authors' evaluation (episodes run through falls).
    pub run_through_falls: bool,
    /// Also save one animated SVG episode per method (first task, first context trajectory).
    pub render: bool,
    /// walker-dyn's normalised metric: the base policy (needs `experts`).
    pub base: Option<PathBuf>,
    /// walker-dyn's normalised metric: per-task experts and/or one general expert.
    pub experts: Vec<PathBuf>,
    /// Evaluate a policy whose training did not finish (with a note) instead of refusing it.
    pub allow_unfinished: bool,
    /// Score the tasks the contexts file holds (new tasks recorded with `smile demos
    /// --task-params`: what a few-shot learner is for) instead of `split`'s.
    pub contexts_tasks: bool,
}

impl EvalRequest {
    /// A request with the family's protocol and no references: `policies` on `split`'s
    /// tasks with `contexts`, into `out`.
    pub fn new(
        policies: Vec<PathBuf>,
        family: Family,
        split: Split,
        contexts: PathBuf,
        out: PathBuf,
    ) -> Self {
        Self {
            policies,
            family,
            split,
            contexts,
            out,
            rollouts: None,
            context_sizes: Vec::new(),
            horizon: None,
            action_noise: 0.0,
            run_through_falls: false,
            render: false,
            base: None,
            experts: Vec::new(),
            allow_unfinished: false,
            contexts_tasks: false,
        }
    }
}

/// What [`evaluate_to_dir`] reports.
#[derive(Debug, Clone, PartialEq)]
pub enum EvalEvent {
    /// A line for the person watching.
    Note(String),
    /// A method (or the base + expert references) starts: `name`, over `tasks` tasks.
    Method {
        /// Its display name.
        name: String,
        /// Tasks to evaluate.
        tasks: usize,
    },
    /// Tasks done of the current method.
    Task(usize),
    /// The current method is done.
    MethodDone,
}

/// Evaluates `req` and writes its report files; returns the report. Everything is loaded and
/// checked before any rollout, so a wrong policy, context file, base or expert fails fast.
pub fn evaluate_to_dir(req: &EvalRequest, on: &mut dyn FnMut(EvalEvent)) -> Result<EvalReport> {
    let family = req.family;
    let ctx = crate::data::read_demos_of(&req.contexts, Input::Contexts, family)?;
    check_contexts(req, &ctx)?;
    let mut protocol = protocol_of(req, on)?;
    let policies = load_policies(req, on)?;
    // The episodes run on the plant the policies were trained on.
    if let Some((_, mp)) = policies.first() {
        protocol.physics = mp.physics;
    }
    let in_contexts = |e: &dyn std::fmt::Display| {
        Error::input(
            Input::Contexts,
            format!("the contexts {}: {e}", req.contexts.display()),
        )
    };
    ctx.ensure_physics(protocol.physics)
        .map_err(|e| in_contexts(&e))?;
    let tasks = match req.contexts_tasks {
        true => ctx.tasks.iter().map(|t| t.task).collect(),
        false => family.tasks(req.split),
    };
    let demos = super::contexts_for(&ctx, family, &tasks).map_err(|e| in_contexts(&e))?;
    let fewest = demos
        .iter()
        .map(|td| td.trajectories.len())
        .min()
        .unwrap_or(0);
    fit_context_sizes(
        &mut protocol,
        fewest,
        !req.context_sizes.is_empty(),
        req,
        on,
    )?;
    let references = match &req.base {
        Some(base) => Some(References::load(family, base, &req.experts)?),
        None => None,
    };
    std::fs::create_dir_all(&req.out).map_err(Error::io(&req.out))?;
    let reference = match &references {
        Some(refs) => Some(reference_returns(
            refs,
            req.split,
            &protocol,
            tasks.len(),
            on,
        )?),
        None => None,
    };
    let mut methods = Vec::new();
    for (idx, (p, mut mp)) in policies.into_iter().enumerate() {
        let run = Method {
            req,
            ctx: &ctx,
            tasks: &tasks,
            protocol: &protocol,
        };
        methods.push(run.evaluate(idx, p, &mut mp, on)?);
    }
    let mut report = EvalReport::new(family, req.split, protocol, methods);
    if req.contexts_tasks {
        report.split = "the contexts' own tasks".into();
    }
    if let Some(r) = reference {
        report = report.with_reference(r)?;
        note_normalised(&report, on);
    }
    write_report(&report, &req.out)?;
    Ok(report)
}

/// Refuses contexts that cannot serve the request: a split other than the one asked for, or
/// the contexts' own tasks with a base (which normalises over a split's tasks).
fn check_contexts(req: &EvalRequest, ctx: &sim::DemoDataset) -> Result<()> {
    if req.contexts_tasks && req.base.is_some() {
        return Err(Error::input(
            Input::Base,
            "the base normalises over a split's tasks; the contexts' own tasks have no base and \
             expert returns (drop the base, or evaluate on a split)",
        ));
    }
    if !req.contexts_tasks && ctx.split != req.split {
        return Err(Error::input(
            Input::Split,
            format!(
                "the contexts {} hold {} demos, but the split is {}; evaluate the {} split or give \
             the {} demos",
                req.contexts.display(),
                ctx.split,
                req.split,
                ctx.split,
                req.split
            ),
        ));
    }
    Ok(())
}

/// The context sizes measured are the ones recorded: a size given (`given`) beyond the
/// `fewest` demos a task has in the contexts file is refused, naming both; the family's
/// default sizes beyond it are left out, with a note (a context draws without repeats, so a
/// size-50 context of 3 demos would be a size-3 one recorded as 50).
fn fit_context_sizes(
    protocol: &mut Protocol,
    fewest: usize,
    given: bool,
    req: &EvalRequest,
    on: &mut dyn FnMut(EvalEvent),
) -> Result<()> {
    let beyond: Vec<usize> = (protocol.context_sizes.iter())
        .copied()
        .filter(|&k| k > fewest)
        .collect();
    if beyond.is_empty() {
        return Ok(());
    }
    let file = req.contexts.display();
    if given {
        return Err(Error::input(
            Input::ContextSizes,
            format!(
                "context size {} is more demos than the contexts {file} hold for some task                  ({fewest}); give sizes up to {fewest}, or contexts with more demos per task",
                beyond[0]
            ),
        ));
    }
    protocol.context_sizes.retain(|&k| k <= fewest);
    if protocol.context_sizes.is_empty() {
        protocol.context_sizes.push(fewest.max(1));
    }
    on(EvalEvent::Note(format!(
        "the contexts {file} hold {fewest} demos for some task: context sizes {beyond:?} of \
         the family's protocol left out, measuring {:?}",
        protocol.context_sizes
    )));
    Ok(())
}

/// The family's protocol with the request's overrides.
fn protocol_of(req: &EvalRequest, on: &mut dyn FnMut(EvalEvent)) -> Result<Protocol> {
    let family = req.family;
    let mut protocol = Protocol::for_family(family);
    if let Some(r) = req.rollouts {
        protocol.rollouts = r;
    }
    if !req.context_sizes.is_empty() {
        protocol.context_sizes = req.context_sizes.clone();
    }
    protocol.horizon = req.horizon;
    protocol.action_noise = req.action_noise;
    if req.run_through_falls {
        if !family.spec().eval.falls_end_episodes {
            return Err(Error::input(
                Input::WalkerProtocol,
                format!(
                    "the walker authors' protocol runs episodes through falls; {family}'s \
                     episodes have no falls to run through"
                ),
            ));
        }
        protocol.run_through_falls = true;
        on(EvalEvent::Note(format!(
            "walker protocol: {}",
            protocol.label()
        )));
    }
    Ok(protocol)
}

/// The request's policies, each finished (unless allowed) and of the request's family, all
/// trained on one plant.
fn load_policies<'r>(
    req: &'r EvalRequest,
    on: &mut dyn FnMut(EvalEvent),
) -> Result<Vec<(&'r PathBuf, MetaPolicy)>> {
    let family = req.family;
    let mut policies = Vec::with_capacity(req.policies.len());
    for p in &req.policies {
        let mp = MetaPolicy::load(p)
            .map_err(|e| Error::Usage(format!("loading {}: {e}", p.display())))?;
        if let Some(warning) = MetaPolicy::ensure_finished(p, req.allow_unfinished)? {
            on(EvalEvent::Note(warning));
        }
        if mp.family != family {
            return Err(Error::input(
                Input::Family,
                format!(
                    "{} was trained on {}, not {family}; evaluate it on {}",
                    p.display(),
                    mp.family,
                    mp.family
                ),
            ));
        }
        policies.push((p, mp));
    }
    if let Some((first, mp)) = policies.first()
        && let Some((p, other)) = policies.iter().find(|(_, m)| m.physics != mp.physics)
    {
        return Err(Error::Usage(format!(
            "{} was trained on the {} plant, {} on {}: evaluate each plant's policies apart",
            first.display(),
            mp.physics,
            p.display(),
            other.physics
        )));
    }
    Ok(policies)
}

/// The base's and the experts' returns on the split's tasks (the normalised metric's ends).
fn reference_returns(
    refs: &References,
    split: Split,
    protocol: &Protocol,
    tasks: usize,
    on: &mut dyn FnMut(EvalEvent),
) -> Result<ReferenceReturns> {
    on(EvalEvent::Method {
        name: "base + expert".into(),
        tasks,
    });
    let r = refs.returns(split, protocol, &mut |i, _| on(EvalEvent::Task(i)))?;
    on(EvalEvent::MethodDone);
    on(EvalEvent::Note(format!(
        "base {}: mean return {:.4}; expert {}: mean return {:.4}",
        r.base,
        r.base_mean(),
        r.expert,
        r.expert_mean()
    )));
    Ok(r)
}

/// What every method of one request is evaluated on.
struct Method<'r> {
    req: &'r EvalRequest,
    ctx: &'r sim::DemoDataset,
    tasks: &'r [Task],
    protocol: &'r Protocol,
}

impl Method<'_> {
    /// The metric of policy number `idx` (at `path`) on every task, and with `--render` its
    /// first task's episode as an SVG.
    fn evaluate(
        &self,
        idx: usize,
        path: &Path,
        mp: &mut MetaPolicy,
        on: &mut dyn FnMut(EvalEvent),
    ) -> Result<MethodResult> {
        let (family, tasks) = (self.req.family, self.tasks);
        let name = super::display_name(&mp.algo, path);
        on(EvalEvent::Method {
            name: name.clone(),
            tasks: tasks.len(),
        });
        let r = super::evaluate_tasks(
            mp,
            &name,
            family,
            tasks,
            self.ctx,
            self.protocol,
            &mut |i, _| on(EvalEvent::Task(i)),
        )?;
        on(EvalEvent::MethodDone);
        on(EvalEvent::Note(format!(
            "{name}: mean {:.4} +- {:.4} over tasks",
            r.mean, r.std_over_tasks
        )));
        if self.req.render {
            let task = tasks[0];
            let tds = super::contexts_for(self.ctx, family, &[task])?;
            let svg = self.req.out.join(format!("episode-{idx}-{}.svg", mp.algo));
            let m = super::render_episode(
                mp,
                family,
                &task,
                &[&tds[0].trajectories[0]],
                self.protocol.env_config(),
                &svg,
            )?;
            on(EvalEvent::Note(format!(
                "rendered {} (metric {m:.3})",
                svg.display()
            )));
        }
        Ok(r)
    }
}

/// One line per method with a normalised score.
fn note_normalised(report: &EvalReport, on: &mut dyn FnMut(EvalEvent)) {
    for m in &report.methods {
        if let Some(n) = &m.normalised {
            let score = n.score.map_or("none".into(), |x| format!("{x:.4}"));
            on(EvalEvent::Note(format!(
                "{}: normalised score {score} over {} tasks ({} skipped: expert not better \
                 than base)",
                m.name, n.tasks_used, n.tasks_skipped
            )));
        }
    }
}

/// The files of an evaluation, `eval.json` last: a sweep counts a cell done by it, and `smile
/// report` reads it, so it must mean the rest was written.
pub(crate) const REPORT_FILES: [&str; 3] = ["eval.md", "eval.svg", "eval.json"];

/// Writes `eval.md`, `eval.svg` and `eval.json` to `out`, replacing an earlier evaluation's
/// without ever leaving the old `eval.json` beside new files: all three are staged first (a
/// full disk fails here, the old evaluation untouched and the staged files removed), then the
/// old `eval.json` goes, then the new files land, `eval.json` last. A kill part way leaves no
/// `eval.json` (no numbers to report), never the old numbers beside the new pictures.
pub fn write_report(report: &EvalReport, out: &Path) -> Result<()> {
    let staged = |name: &str| out.join(format!(".{name}.staged"));
    let stage = || -> Result<()> {
        let write = crate::io::checkpoint::write_atomic;
        write(&staged("eval.md"), report.markdown().as_bytes())?;
        report.plot_svg(&staged("eval.svg"))?;
        let json = serde_json::to_string_pretty(report).map_err(|e| Error::Serialise {
            what: "eval.json",
            reason: e.to_string(),
        })?;
        write(&staged("eval.json"), json.as_bytes())
    };
    if let Err(e) = stage() {
        for name in REPORT_FILES {
            let _ = std::fs::remove_file(staged(name));
        }
        return Err(e);
    }
    let json = out.join("eval.json");
    match std::fs::remove_file(&json) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(Error::io(&json)(e)),
        _ => {}
    }
    for name in REPORT_FILES {
        let to = out.join(name);
        std::fs::rename(staged(name), &to).map_err(Error::io(&to))?;
    }
    Ok(())
}
