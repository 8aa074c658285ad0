//! The one fit loop (`trainer::fit`) driving a learner whose work is a counter: when it
//! evaluates, keeps, checkpoints and stops, what it logs and reports, with no network in the
//! way. The real learners' runs (smile.rs, meta_bc.rs, expert.rs) check what they do inside it.

use std::cell::RefCell;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use serde::{Deserialize, Serialize};
use trainer::{Cadence, Evaluation, Fields, Learner, MetricsLog, Progress, Result, Score, Unit};

/// The counter's budget and cadence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Plan {
    total: u64,
    /// Units per `advance`: 150 passes the multiples of 100 and 300 unevenly.
    stride: u64,
    eval_every: u64,
    /// Also evaluate when training ends (SMILe and Meta-BC do; an expert does not).
    eval_at_end: bool,
    checkpoint_every: u64,
    /// The metric of each evaluation in turn (higher is better).
    metrics: Vec<f32>,
    /// Its stopping rule: finished after this many evaluations (as Meta-BC's patience).
    stop_after: Option<usize>,
}

/// What the loop asked of the counter.
#[derive(Default)]
struct Counter {
    plan: Option<Plan>,
    done: u64,
    evals: usize,
    best: f32,
    /// Where the loop saved the kept policy.
    kept: RefCell<Vec<u64>>,
    finished_at: Option<u64>,
}

impl Learner for Counter {
    type Config = Plan;
    type Inputs = u64;
    const UNIT: Unit = Unit {
        plural: "units",
        word: "unit",
    };

    /// `done`: where a resumed run's checkpoint left it.
    fn start(plan: Plan, done: u64) -> Result<Self> {
        let best = f32::NEG_INFINITY;
        Ok(Self {
            plan: Some(plan),
            done,
            best,
            ..Self::default()
        })
    }

    fn resume(_dir: &Path, done: u64, wanted: &Plan) -> Result<Self> {
        Self::start(wanted.clone(), done)
    }

    fn config(&self) -> &Plan {
        self.plan.as_ref().expect("started")
    }

    fn done(&self) -> u64 {
        self.done
    }

    fn cadence(&self) -> Cadence {
        let p = self.config();
        Cadence {
            total: p.total,
            eval_every: p.eval_every,
            eval_at_end: p.eval_at_end,
            checkpoint_every: p.checkpoint_every,
            cpu_budget_s: 0.0,
        }
    }

    fn finished(&self) -> bool {
        let stopped = self.config().stop_after.is_some_and(|n| self.evals >= n);
        self.done >= self.config().total || stopped
    }

    fn advance(&mut self, on: &mut dyn FnMut(Progress)) -> Result<Fields> {
        self.done += self.config().stride;
        on(Progress::Steps(self.done));
        Ok(vec![("count", self.done as f64)])
    }

    fn evaluate(&mut self) -> Result<Option<Evaluation>> {
        let metric = self.config().metrics[self.evals];
        self.evals += 1;
        let keep = metric > self.best;
        self.best = self.best.max(metric);
        Ok(Some(Evaluation {
            keep,
            fields: vec![("eval/metric", metric as f64)],
            score: Score {
                what: "count",
                metric,
                best: self.best,
                val_mse: None,
            },
        }))
    }

    fn save_checkpoint(&self, _dir: &Path) -> Result<()> {
        Ok(())
    }

    fn save_kept(&self, _dir: &Path) -> Result<()> {
        self.kept.borrow_mut().push(self.done);
        Ok(())
    }

    fn finish(&mut self, _dir: &Path, _log: &mut MetricsLog) -> Result<()> {
        self.finished_at = Some(self.done);
        Ok(())
    }
}

/// Fits `run` in a fresh directory; returns what it reported (`Steps` left out) and the
/// metrics log's lines.
fn fit(run: &mut Counter) -> (Vec<Progress>, Vec<serde_json::Value>) {
    static RUNS: AtomicUsize = AtomicUsize::new(0);
    let n = RUNS.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("fit-counter-{}-{n}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut seen = Vec::new();
    trainer::fit(run, &dir, &mut |p| {
        if !matches!(p, Progress::Steps(_)) {
            seen.push(p);
        }
    })
    .unwrap();
    let log = std::fs::read_to_string(dir.join(trainer::METRICS_FILE)).unwrap();
    let lines = log
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    std::fs::remove_dir_all(&dir).unwrap();
    (seen, lines)
}

fn plan(metrics: &[f32]) -> Plan {
    Plan {
        total: 1000,
        stride: 150,
        eval_every: 300,
        eval_at_end: true,
        checkpoint_every: 500,
        metrics: metrics.to_vec(),
        stop_after: None,
    }
}

fn evals(seen: &[Progress]) -> Vec<(u64, f32)> {
    let at = |p: &Progress| match p {
        Progress::Eval { step, score } => Some((*step, score.best)),
        _ => None,
    };
    seen.iter().filter_map(at).collect()
}

fn checkpoints(seen: &[Progress]) -> Vec<u64> {
    let at = |p: &Progress| match p {
        Progress::Checkpoint(s) => Some(*s),
        _ => None,
    };
    seen.iter().filter_map(at).collect()
}

#[test]
fn evaluations_and_checkpoints_fall_once_per_multiple_and_at_the_end() {
    let mut run = Counter::start(plan(&[0.1, 0.3, 0.2, 0.5]), 0).unwrap();
    let (seen, log) = fit(&mut run);
    // Work done: 150, 300, ..., 1050. 900 passes no multiple of 300 twice; 1050 ends it.
    let best = [(300, 0.1), (600, 0.3), (900, 0.3), (1050, 0.5)];
    assert_eq!(evals(&seen), best);
    assert_eq!(*run.kept.borrow(), [300, 600, 1050]);
    assert_eq!(checkpoints(&seen), [600, 1050]);
    assert!(!seen.iter().any(|p| matches!(p, Progress::Stopped(_))));
    assert_eq!(run.finished_at, Some(1050));
    // One log line per unit of work (with its rate) and one per evaluation.
    assert_eq!(log.len(), 7 + 4);
    assert!(log.iter().all(|l| l["step"].as_u64().unwrap() % 150 == 0));
    assert_eq!(
        log.iter().filter(|l| l.get("charts/sps").is_some()).count(),
        7
    );
    assert_eq!(log.last().unwrap()["eval/metric"], 0.5);
}

#[test]
fn the_learners_stopping_rule_ends_the_run_after_the_evaluation_that_decided_it() {
    // Checkpoints every 2000: the one at 600 is the end's, due whatever the cadence.
    let stops = Plan {
        stop_after: Some(2),
        checkpoint_every: 2000,
        ..plan(&[0.4, 0.1, 0.9])
    };
    let mut run = Counter::start(stops, 0).unwrap();
    let (seen, _) = fit(&mut run);
    // No unit of work, evaluation or second stop after it.
    let eval = |step, metric, best| Progress::Eval {
        step,
        score: Score {
            what: "count",
            metric,
            best,
            val_mse: None,
        },
    };
    let want = [
        eval(300, 0.4, 0.4),
        eval(600, 0.1, 0.4),
        Progress::Stopped(600),
        Progress::Checkpoint(600),
    ];
    assert_eq!(seen, want);
    assert_eq!((run.done, run.finished_at), (600, Some(600)));
}

#[test]
fn a_resumed_run_continues_its_schedules_and_the_end_is_evaluated_only_when_asked() {
    // Resumed at a multiple: the next one is due, not the one it stands on.
    let mut run = Counter::resume(Path::new("."), 300, &plan(&[0.1, 0.2, 0.3])).unwrap();
    let (seen, _) = fit(&mut run);
    assert_eq!(evals(&seen), [(600, 0.1), (900, 0.2), (1050, 0.3)]);
    let never = Plan {
        eval_every: 0,
        ..plan(&[])
    };
    let mut run = Counter::start(never, 0).unwrap();
    let (seen, _) = fit(&mut run);
    assert!(evals(&seen).is_empty(), "{seen:?}");
    // An expert's cadence: no evaluation at the end unless it falls on a multiple.
    let no_end = Plan {
        eval_at_end: false,
        ..plan(&[0.1, 0.2, 0.3, 0.4])
    };
    let mut run = Counter::start(no_end, 0).unwrap();
    let (seen, _) = fit(&mut run);
    assert_eq!(evals(&seen), [(300, 0.1), (600, 0.2), (900, 0.3)]);
    // A finished run does no work, and still writes its files.
    let mut done = Counter::start(plan(&[]), 1000).unwrap();
    let (seen, log) = fit(&mut done);
    assert!(seen.is_empty() && log.is_empty(), "{seen:?} {log:?}");
    assert_eq!(done.finished_at, Some(1000));
}
