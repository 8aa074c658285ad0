//! Where the scripted ant-linclass classifier's episodes end. Its evaluations (`smile expert
//! --kind scripted-linclass`) show that it (nearly) never reaches the wrong target: a failure
//! is a no-op, the torso never entering the correct target's decision radius within the 50
//! steps (`docs/results/ant-goal-mujoco-3m/README.md`). They do not show why. This example replays
//! the same episodes (the scripted expert written as that command writes it, the 32 meta-test
//! hyperplanes, reset seeds `EXPERT_EVAL_SEED + k`) and follows the torso's distance to the
//! correct target at every step: a failure still closing in at the end was too slow; one
//! whose closest approach came earlier stopped short of or beside the target, or went past or
//! around it.
//!
//! ```sh
//! cargo run --release --features mujoco -p trainer --example linclass_walk_end -- \
//!   --goal-expert docs/results/ant-goal-mujoco-3m/at-5m/policy.safetensors \
//!   --physics mujoco --aims 0.9,1.0,1.1,1.2 --episodes 10
//! ```
//!
//! `--distinct-starts` gives every task's episodes reset seeds of their own: the evaluation's
//! 320 episodes are 20 distinct walks (two targets times ten seeds), since the scripted expert
//! sees the hyperplane only through the target it picks.
//!
//! Prints a markdown table per aim (its success counts the evaluation's successes: 282 of 320
//! prints 0.8813 here and 0.8812 in `eval.json`, which averages per-task means in f32),
//! then every failure: its closest approach, the step of it, and where it ended. `--scripted
//! DIR` replays a scripted expert already written (`assets/experts/ant-linclass`, say) instead
//! of writing one per aim.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use sim::ant_linclass::{AntLinClassEnv, DECISION_RADIUS};
use sim::{EnvConfig, Environment, Family, Physics};
use trainer::expert::{Expert, eval_seed, export_scripted_linclass};

/// Which scripted experts to replay.
enum Source {
    /// One written from this ant-goal expert per aim.
    Goal(PathBuf, Vec<f32>),
    /// One already written.
    Scripted(PathBuf),
}

struct Args {
    source: Source,
    /// The plant, when given: it must be the expert's (default: the expert's).
    physics: Option<Physics>,
    episodes: u64,
    /// Reset seeds of their own per task (`trainer::expert::eval_seed`), as demos'
    /// `--distinct-starts`: the evaluation's seeds repeat across tasks, so its episodes are
    /// only as many distinct walks as targets times episodes.
    distinct_starts: bool,
}

fn parse() -> Result<Args, String> {
    let mut it = std::env::args().skip(1);
    let (mut goal_expert, mut scripted, mut physics) = (None, None, None);
    let (mut aims, mut episodes) = (vec![sim::ant_linclass::AIM_SCALE], 10u64);
    let mut distinct_starts = false;
    while let Some(flag) = it.next() {
        if flag == "--distinct-starts" {
            distinct_starts = true;
            continue;
        }
        let value = it.next().ok_or(format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--goal-expert" => goal_expert = Some(PathBuf::from(value)),
            "--scripted" => scripted = Some(PathBuf::from(value)),
            "--physics" => {
                physics = Some(value.parse().map_err(|e| format!("--physics: {e}"))?);
            }
            "--aims" => {
                let parse = |a: &str| a.parse::<f32>().map_err(|e| format!("--aims {a}: {e}"));
                aims = value.split(',').map(parse).collect::<Result<_, _>>()?;
            }
            "--episodes" => {
                episodes = value.parse().map_err(|e| format!("--episodes: {e}"))?;
                if episodes == 0 {
                    return Err("--episodes must be at least 1".into());
                }
            }
            other => return Err(format!("unknown flag {other}")),
        }
    }
    let source = match (goal_expert, scripted) {
        (Some(g), None) => Source::Goal(g, aims),
        (None, Some(s)) => Source::Scripted(s),
        _ => return Err("give one of --goal-expert and --scripted".into()),
    };
    Ok(Args {
        source,
        physics,
        episodes,
        distinct_starts,
    })
}

/// One episode: its decision, and the torso's distance to the correct target after each step.
struct Walk {
    target: [f32; 2],
    episode: u64,
    /// The latched decision at the end: 1 the correct target, -1 the wrong one, 0 none.
    decision: f32,
    distance: Vec<f32>,
}

impl Walk {
    /// The closest approach and the step (1-based) it came at.
    fn closest(&self) -> (f32, usize) {
        let (i, d) = self
            .distance
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .map_or((0, f32::INFINITY), |(i, d)| (i, *d));
        (d, i + 1)
    }

    /// The first step (1-based) inside the decision radius.
    fn entered(&self) -> Option<usize> {
        self.distance
            .iter()
            .position(|d| *d <= DECISION_RADIUS)
            .map(|i| i + 1)
    }
}

/// The scripted expert driving `goal_expert` aimed `aim` times as far as the target, as
/// `smile expert --kind scripted-linclass` writes it.
fn scripted(goal_expert: &Path, aim: f32) -> Result<Expert, Box<dyn std::error::Error>> {
    let dir = std::env::temp_dir().join(format!("linclass-walk-end-{}", std::process::id()));
    export_scripted_linclass(goal_expert, aim, &dir)?;
    let expert = Expert::load(&dir);
    std::fs::remove_dir_all(&dir).ok();
    Ok(expert?)
}

/// Every episode of `expert` on the meta-test hyperplanes.
fn walks(args: &Args, expert: &Expert) -> Result<Vec<Walk>, Box<dyn std::error::Error>> {
    let family = Family::ANT_LINCLASS;
    let physics = expert.physics();
    if let Some(p) = args.physics.filter(|p| *p != physics) {
        return Err(format!("--physics {p}: the expert was trained on the {physics} plant").into());
    }
    let mut env = AntLinClassEnv::new(EnvConfig::new(None, physics))?;
    let (mut oracle, mut action) = (
        vec![0.0; family.oracle_obs_dim()],
        vec![0.0; family.act_dim()],
    );
    let mut out = Vec::new();
    let episodes = args.episodes as usize;
    for (i, task) in family.test_tasks().into_iter().enumerate() {
        for k in 0..episodes {
            env.reset(&task, eval_seed(i, k, episodes, args.distinct_starts))?;
            let mut walk = Walk {
                target: env.correct_target(),
                episode: k as u64,
                decision: 0.0,
                distance: Vec::new(),
            };
            loop {
                env.oracle_observation(&mut oracle)?;
                expert.act(&oracle, &mut action)?;
                let tr = env.step(&action)?;
                let done = tr.done;
                walk.decision = tr.info.metric_sample;
                let ([x, y], [tx, ty]) = (env.torso_xy(), env.correct_target());
                walk.distance.push((x - tx).hypot(y - ty));
                if done {
                    break;
                }
            }
            out.push(walk);
        }
    }
    Ok(out)
}

/// The median of `v` (of an even count, the upper of the middle two; NaN when empty).
fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f32::NAN)
}

/// Prints the markdown tables of one expert's walks under the heading `what`.
fn report(what: &str, walks: &[Walk]) {
    let n = walks.len();
    // The scripted expert sees the hyperplane only through the target it picks, so an episode
    // is its target and reset seed: tasks that pick the same target walk the same walks.
    let mut distinct: Vec<(&Walk, usize)> = Vec::new();
    for w in walks {
        match distinct.iter_mut().find(|(d, _)| d.distance == w.distance) {
            Some((_, count)) => *count += 1,
            None => distinct.push((w, 1)),
        }
    }
    let (ok, failed): (Vec<&Walk>, Vec<&Walk>) = walks.iter().partition(|w| w.decision > 0.0);
    let wrong = failed.iter().filter(|w| w.decision < 0.0).count();
    // A no-op's kind: still closing in at the end (too slow); its closest approach earlier and
    // the end within STALLED of it (it stopped short or beside); or further (past, around).
    const STALLED: f32 = 0.1;
    let kind = |w: &Walk| {
        let (closest, step) = w.closest();
        let end = w.distance.last().copied().unwrap_or(f32::NAN);
        match (
            w.decision < 0.0,
            step == w.distance.len(),
            end - closest < STALLED,
        ) {
            (true, _, _) => 3,
            (false, true, _) => 0,
            (false, false, true) => 1,
            (false, false, false) => 2,
        }
    };
    let count = |k| failed.iter().filter(|w| kind(w) == k).count();
    let closest = median(failed.iter().map(|w| w.closest().0).collect());
    let entered: Vec<f32> = ok
        .iter()
        .filter_map(|w| w.entered())
        .map(|s| s as f32)
        .collect();
    let late = entered.iter().filter(|s| **s > 40.0).count();
    println!("### {what}\n");
    println!(
        "| episodes | distinct walks | success | failed: the wrong target | still closing in at \
         the end | stopped short or beside (ends within {STALLED} m of its closest) | past or \
         around | failures' closest approach, median (m) | successes' entry step, median | \
         successes entering after step 40 |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    println!(
        "| {n} | {} | {:.4} | {wrong} | {} | {} | {} | {closest:.3} | {} | {late} |\n",
        distinct.len(),
        ok.len() as f32 / n as f32,
        count(0),
        count(1),
        count(2),
        median(entered)
    );
    println!("Failed walks, each once (episodes: how many of the {n} walked it):\n");
    println!(
        "| target | episode k | episodes | decided | closest to the target (m) | at step | at the \
         end (m) |"
    );
    println!("|---|---|---|---|---|---|---|");
    for (w, count) in distinct.iter().filter(|(w, _)| w.decision <= 0.0) {
        let (d, step) = w.closest();
        let end = w.distance.last().copied().unwrap_or(f32::NAN);
        let [x, y] = w.target;
        println!(
            "| ({x}, {y}) | {} | {count} | {} | {d:.3} | {step} | {end:.3} |",
            w.episode,
            if w.decision < 0.0 { "wrong" } else { "none" }
        );
    }
    println!();
}

fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("linclass_walk_end: {e}");
            return ExitCode::from(2);
        }
    };
    trainer::threads::set_compute_threads(1);
    let runs: Vec<(String, Result<Expert, _>)> = match &args.source {
        Source::Goal(g, aims) => aims
            .iter()
            .map(|&aim| (format!("aim {aim}"), scripted(g, aim)))
            .collect(),
        Source::Scripted(s) => vec![(s.display().to_string(), Expert::load(s).map_err(Into::into))],
    };
    for (what, expert) in runs {
        match expert.and_then(|e| walks(&args, &e)) {
            Ok(w) => report(&what, &w),
            Err(e) => {
                eprintln!("linclass_walk_end: {what}: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    ExitCode::SUCCESS
}
