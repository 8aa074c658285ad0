//! `smile linclass-diagnose`: why a learner does or does not read ant-linclass's hyperplane
//! (issue 70, item 2): what the context demos show and the best accuracy they allow, what
//! each policy's z carries, and when its episodes commit to a side (`trainer::eval::linclass`).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use serde::Serialize;
use sim::{DemoDataset, Family, Split};
use trainer::MetaPolicy;
use trainer::eval::linclass::{
    self, BoundRow, BoundSetup, COMMIT_X, EpisodeTrace, PriorSamples, ProbeRow, SHOWN_X,
    StepVisibility, TimingRow,
};
use trainer::eval::{Protocol, latents};

/// Arguments of `smile linclass-diagnose`.
#[derive(Args, Debug)]
pub struct LinclassArgs {
    /// Demos of the meta-test tasks: the evaluation's contexts.
    #[arg(long)]
    contexts: PathBuf,
    /// Demos of the meta-train tasks: adds their visibility and each policy's probe on them.
    #[arg(long)]
    train_demos: Option<PathBuf>,
    /// A trained policy as `LABEL=DIR` (a run directory or its meta_policy.safetensors);
    /// repeat for several.
    #[arg(long = "policy", value_parser = parse_policy)]
    policies: Vec<(String, PathBuf)>,
    /// Context sizes (demos per context).
    #[arg(long, value_delimiter = ',', default_value = "1,2,4,8,16", value_parser = clap::value_parser!(u32).range(1..))]
    context_sizes: Vec<u32>,
    /// Context draws per task and size (the evaluation's).
    #[arg(long, default_value_t = 3, value_parser = crate::positive)]
    draws: usize,
    /// Episodes per draw (the evaluation's): their pairs score the bound and the probes.
    #[arg(long, default_value_t = 5, value_parser = crate::positive)]
    rollouts: usize,
    /// Fresh pairs per context the bound is also scored on.
    #[arg(long, default_value_t = 100)]
    fresh_pairs: usize,
    /// Normals drawn from the prior for the Bayes rule.
    #[arg(long, default_value_t = 1 << 20, value_parser = crate::positive)]
    prior_samples: usize,
    /// Skip the policies' episodes (probes only).
    #[arg(long)]
    no_rollouts: bool,
    /// Also roll each policy out on the meta-train tasks, contexts from `--train-demos` (all 64
    /// tasks: the runs held every eighth out for validation and trained on the rest).
    #[arg(long, requires = "train_demos", conflicts_with = "no_rollouts")]
    rollouts_on_train: bool,
    /// Use policies whose training did not finish, with a warning, instead of refusing them.
    #[arg(long)]
    allow_unfinished: bool,
    /// Output directory: diagnosis.json, and per policy latents-{test,train}-LABEL.csv and
    /// episodes-{test,train}-LABEL.csv.
    #[arg(short, long)]
    out: PathBuf,
}

fn parse_policy(text: &str) -> std::result::Result<(String, PathBuf), String> {
    match text.split_once('=') {
        Some((label, path))
            if !label.is_empty()
                && !path.is_empty()
                && label
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_') =>
        {
            Ok((label.to_string(), PathBuf::from(path)))
        }
        _ => Err(format!(
            "`{text}`: expected LABEL=DIR with a label of letters, digits, - and _"
        )),
    }
}

/// What one policy shows.
#[derive(Debug, Serialize)]
struct PolicyDiagnosis {
    label: String,
    path: String,
    algo: String,
    probe_test: Vec<ProbeRow>,
    probe_train: Option<Vec<ProbeRow>>,
    timing: Option<Vec<TimingRow>>,
    timing_train: Option<Vec<TimingRow>>,
}

/// The whole diagnosis.
#[derive(Debug, Serialize)]
struct Diagnosis {
    contexts: String,
    train_demos: Option<String>,
    physics: String,
    context_sizes: Vec<usize>,
    draws: usize,
    rollouts: usize,
    fresh_pairs: usize,
    prior_samples: usize,
    shown_x: f32,
    commit_x: f32,
    visibility_test: Vec<StepVisibility>,
    clear_fraction_test: f64,
    visibility_train: Option<Vec<StepVisibility>>,
    clear_fraction_train: Option<f64>,
    bound: Vec<BoundRow>,
    policies: Vec<PolicyDiagnosis>,
}

/// The side checkpoints the timing reads (steps of the 50-step episode).
const CHECKPOINTS: [usize; 5] = [5, 10, 15, 25, 50];

fn read(path: &Path, input: trainer::Input, split: Split) -> Result<DemoDataset> {
    let ds = trainer::read_demos_of(path, input, Family::ANT_LINCLASS)?;
    if ds.split != split {
        bail!(
            "{} holds {} demos, expected {split}",
            path.display(),
            ds.split
        );
    }
    Ok(ds)
}

/// Run `smile linclass-diagnose`.
pub fn run(a: LinclassArgs) -> Result<()> {
    let ctx = read(&a.contexts, trainer::Input::Contexts, Split::Test)?;
    let train = a
        .train_demos
        .as_deref()
        .map(|p| read(p, trainer::Input::Demos, Split::Train))
        .transpose()?;
    if let Some(t) = &train {
        t.ensure_physics(ctx.physics)
            .context("--train-demos and --contexts come from different plants")?;
    }
    let sizes: Vec<usize> = a.context_sizes.iter().map(|&k| k as usize).collect();
    let setup = BoundSetup {
        sizes: sizes.clone(),
        draws: a.draws,
        rollouts: a.rollouts,
        fresh_pairs: a.fresh_pairs,
    };
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;

    let (visibility_test, clear_test) = linclass::visibility(&ctx)?;
    let train_vis = train.as_ref().map(linclass::visibility).transpose()?;
    print_visibility(
        ctx.physics,
        &visibility_test,
        clear_test,
        train_vis.as_ref(),
    );

    let prior = PriorSamples::new(a.prior_samples, 0x0050_5249_4f52); // "PRIOR"
    let bound = linclass::information_bound(&ctx, Split::Test, &setup, &prior)?;
    print_bound(&bound);

    let mut policies = Vec::new();
    for (label, path) in &a.policies {
        policies.push(
            diagnose_policy(&a, label, path, &ctx, train.as_ref(), &setup)
                .with_context(|| format!("--policy {label}={}", path.display()))?,
        );
    }

    let diagnosis = Diagnosis {
        contexts: a.contexts.display().to_string(),
        train_demos: a.train_demos.as_ref().map(|p| p.display().to_string()),
        physics: ctx.physics.to_string(),
        context_sizes: sizes,
        draws: a.draws,
        rollouts: a.rollouts,
        fresh_pairs: a.fresh_pairs,
        prior_samples: a.prior_samples,
        shown_x: SHOWN_X,
        commit_x: COMMIT_X,
        visibility_test,
        clear_fraction_test: clear_test,
        clear_fraction_train: train_vis.as_ref().map(|(_, c)| *c),
        visibility_train: train_vis.map(|(rows, _)| rows),
        bound,
        policies,
    };
    let path = a.out.join("diagnosis.json");
    let text = serde_json::to_string_pretty(&diagnosis)?;
    trainer::checkpoint::write_atomic(&path, text.as_bytes())?;
    println!("wrote {}", path.display());
    Ok(())
}

/// What the demos show, per time step (every step up to 15, then every fifth; all in the
/// JSON), test demos beside the train demos' where given.
fn print_visibility(
    physics: sim::Physics,
    visibility_test: &[linclass::StepVisibility],
    clear_test: f64,
    train_vis: Option<&(Vec<linclass::StepVisibility>, f64)>,
) {
    println!(
        "what the demos show ({} plant): the torso's x on the correct side per time step, test \
         demos{}",
        physics,
        if train_vis.is_some() {
            " (train demos)"
        } else {
            ""
        }
    );
    // Every step up to 15 (where the side appears), then every fifth; all in the JSON.
    for v in visibility_test
        .iter()
        .filter(|v| v.time_step <= 15 || v.time_step % 5 == 4)
    {
        let tr = train_vis
            .and_then(|(rows, _)| rows.iter().find(|t| t.time_step == v.time_step))
            .map_or(String::new(), |t| {
                format!(
                    " ({:.3}, clearly {:.3})",
                    t.x_on_correct_side, t.x_clearly_correct
                )
            });
        println!(
            "  step {:2}: {:4} transitions, x on the correct side {:.3}, clearly (|x| >= \
             {COMMIT_X}) {:.3}, median signed x {:+.3}; side from the action {:.3} (gap \
             {:.2}){tr}",
            v.time_step,
            v.transitions,
            v.x_on_correct_side,
            v.x_clearly_correct,
            v.median_signed_x,
            v.action_side_accuracy,
            v.action_gap
        );
    }
    println!(
        "  kept transitions showing the side clearly: test {clear_test:.3}{}",
        train_vis.map_or(String::new(), |(_, c)| format!(", train {c:.3}"))
    );
}

/// The information bound, a line per context size.
fn print_bound(bound: &[linclass::BoundRow]) {
    println!(
        "information bound on the test tasks (accuracy on the evaluation's pairs; on fresh pairs):"
    );
    for b in bound {
        println!(
            "  {:2} demos: Bayes {:.3} ({:.3}), SVM {:.3} ({:.3}), centroid {:.3} ({:.3}); demos \
             without a side {}, mislabelled {}; posterior samples min {} median {}",
            b.context_size,
            b.eval_pairs.bayes,
            b.fresh_pairs.bayes,
            b.eval_pairs.svm,
            b.fresh_pairs.svm,
            b.eval_pairs.centroid,
            b.fresh_pairs.centroid,
            b.demos_without_side,
            b.demos_mislabelled,
            b.min_posterior_samples,
            b.median_posterior_samples
        );
    }
}

fn diagnose_policy(
    a: &LinclassArgs,
    label: &str,
    path: &Path,
    ctx: &DemoDataset,
    train: Option<&DemoDataset>,
    setup: &BoundSetup,
) -> Result<PolicyDiagnosis> {
    let mut policy = MetaPolicy::load(path)?;
    if let Some(warning) = MetaPolicy::ensure_finished(path, a.allow_unfinished)? {
        eprintln!("{warning}");
    }
    if policy.family != Family::ANT_LINCLASS {
        bail!("a {} policy, not an ant-linclass one", policy.family);
    }
    ctx.ensure_physics(policy.physics)
        .context("the contexts and the policy come from different plants")?;
    let mut probe = |ds: &DemoDataset, split: Split| -> Result<Vec<ProbeRow>> {
        let rows = latents::latents(
            &mut policy,
            Family::ANT_LINCLASS,
            split,
            ds,
            &setup.sizes,
            setup.draws,
        )?;
        latents::write_csv(&rows, &a.out.join(format!("latents-{split}-{label}.csv")))?;
        Ok(linclass::probe_decisions(&rows, setup.rollouts)?)
    };
    let probe_test = probe(ctx, Split::Test)?;
    let probe_train = train.map(|t| probe(t, Split::Train)).transpose()?;
    println!(
        "{label} ({}, {}): the probe z -> normal",
        policy.algo,
        path.display()
    );
    for (i, p) in probe_test.iter().enumerate() {
        let tr = probe_train
            .as_ref()
            .and_then(|rows| rows.get(i))
            .map_or(String::new(), |t| {
                format!(
                    "; train tasks R^2 {:.3}, cosine {:.3}, pair accuracy {:.3}",
                    t.mean_r2, t.mean_cosine, t.pair_accuracy
                )
            });
        println!(
            "  {:2} demos: test tasks R^2 {:.3}, cosine {:.3}, pair accuracy {:.3}{tr}",
            p.context_size, p.mean_r2, p.mean_cosine, p.pair_accuracy
        );
    }
    let protocol = Protocol {
        physics: policy.physics,
        ..Protocol::for_family(Family::ANT_LINCLASS)
    };
    let mut timing_of = |ds: &DemoDataset, split: Split| -> Result<Vec<TimingRow>> {
        let traces =
            linclass::trace_episodes(&mut policy, ds, split, setup, protocol.env_config())?;
        write_traces(
            &traces,
            &a.out.join(format!("episodes-{split}-{label}.csv")),
        )?;
        let rows = linclass::timing_summary(&traces, &CHECKPOINTS);
        print_timing(split, &rows);
        Ok(rows)
    };
    let timing = (!a.no_rollouts)
        .then(|| timing_of(ctx, Split::Test))
        .transpose()?;
    let timing_train = match (a.rollouts_on_train, train) {
        (true, Some(t)) => Some(timing_of(t, Split::Train)?),
        _ => None,
    };
    Ok(PolicyDiagnosis {
        label: label.into(),
        path: path.display().to_string(),
        algo: policy.algo.clone(),
        probe_test,
        probe_train,
        timing,
        timing_train,
    })
}

fn print_timing(split: Split, rows: &[TimingRow]) {
    println!("  episodes on the {split} tasks (committed: |x| >= {COMMIT_X} m):");
    for r in rows {
        let sides: Vec<String> = r
            .side_at
            .iter()
            .map(|(s, right, wrong)| format!("{s}: {right:.2}/{wrong:.2}"))
            .collect();
        println!(
            "  {:>3} demos: success {:.3}, no-op {:.3}, decided accuracy {:.3} (balanced {:.3}); \
             first commitment right {:.3} wrong {:.3} none {:.3} (accuracy {:.3}, balanced {:.3}, \
             to x > 0 {:.3}, median step {}); wrong from the start {:.3}, drifted {:.3}, \
             recovered {:.3}; right/wrong side at step {}",
            r.context_size.map_or("all".into(), |k| k.to_string()),
            r.success,
            r.no_op,
            r.decided_accuracy,
            r.balanced_decided_accuracy,
            r.committed_right,
            r.committed_wrong,
            r.never_committed,
            r.commit_accuracy,
            r.balanced_commit_accuracy,
            r.commits_to_first_target,
            r.median_commit_step,
            r.wrong_from_start,
            r.drifted,
            r.recovered,
            sides.join(", ")
        );
    }
}

/// One line per episode: where it was at the checkpoints, when and where it committed.
fn write_traces(traces: &[EpisodeTrace], path: &Path) -> Result<()> {
    let mut text = String::from(
        "task,context_size,draw,rollout,correct_side,decision,commit_step,commit_side",
    );
    for s in CHECKPOINTS {
        text.push_str(&format!(",x_{s}"));
    }
    text.push('\n');
    for t in traces {
        let (step, side) = t
            .commit(COMMIT_X)
            .map_or((String::new(), String::new()), |(s, d)| {
                (s.to_string(), d.to_string())
            });
        text.push_str(&format!(
            "{},{},{},{},{},{},{step},{side}",
            t.task, t.context_size, t.draw, t.rollout, t.correct_side, t.decision
        ));
        for s in CHECKPOINTS {
            let x = t.x.get(s - 1).map_or(String::new(), |x| format!("{x:.4}"));
            text.push_str(&format!(",{x}"));
        }
        text.push('\n');
    }
    trainer::checkpoint::write_atomic(path, text.as_bytes())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn policies_are_label_equals_path() {
        assert_eq!(
            parse_policy("meta-bc=assets/policies/x").unwrap(),
            ("meta-bc".to_string(), PathBuf::from("assets/policies/x"))
        );
        for bad in ["nolabel", "=dir", "label=", "a b=dir", "x/y=dir"] {
            assert!(parse_policy(bad).is_err(), "{bad}");
        }
    }
}
