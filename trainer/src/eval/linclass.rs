//! ant-linclass, diagnosed (issue 70, item 2): what the context demos carry about a task's
//! hyperplane, what a learner's z carries, and when its episodes commit to a side.
//!
//! - **What a demo shows** ([`demo_label`], [`visibility`]): a demo's first observation holds
//!   its pair of points (every observation does); the target it walked to is the side of the
//!   torso's x at its last transition (`TARGETS[0]` is at x > 0). [`visibility`] says, per time
//!   step, how often the torso's x already shows that side, and how well the expert's action
//!   alone tells the two targets apart: which of a subsampled demo's transitions carry the
//!   choice, and where a cloned policy's action depends on it.
//! - **The information bound** ([`information_bound`]): for every context the evaluation draws
//!   (the same draws, [`super::context_draw`]), the demos' pairs labelled with the side they
//!   walked to, and three classifiers fitted on them, scored on the pairs of the evaluation's
//!   own episodes (reset seeds [`super::episode_seed`]) and on fresh pairs of the same task:
//!   the **Bayes** rule (the task's prior is uniform on the sphere and a pair's likelihood is
//!   constant on the hyperplanes that separate it, so the posterior is the prior restricted to
//!   the hyperplanes consistent with every labelled pair; its vote is estimated from a fixed
//!   set of normals drawn from the prior, [`PriorSamples`]), a hard-margin linear **SVM**
//!   through the origin ([`svm_normal`]), and the **centroid** `sum y (p1 - p2)`
//!   ([`centroid_normal`]), what a mean-pooling encoder computes with a per-step feature
//!   `y (p1 - p2)`. No learner seeing these contexts can beat the Bayes rule on average.
//! - **The latent's probe** ([`probe_decisions`]): the leave-one-task-out ridge from z to the
//!   normal ([`super::latents::probe_predictions`]), scored by how often the predicted normal
//!   classifies the evaluation's pairs.
//! - **Where the decision is made** ([`trace_episodes`], [`timing_summary`]): the evaluation's
//!   episodes (same contexts, seeds and deterministic actions), each with the torso's x per
//!   step; an episode *commits* at the first step where |x| reaches [`COMMIT_X`], and is then
//!   sorted into wrong from the start, drifted (committed to the right side, decided wrong or
//!   ended on the wrong side), or never committed.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;
use sim::ant_linclass::{FIRST_POINT, POINT_DIM, SECOND_POINT, draw_pair};
use sim::{DemoDataset, EnvConfig, Family, Split, Task, Trajectory};

use super::latents::{LatentRow, probe_predictions};
use super::{ConditionedActor, context_draw, contexts_for, episode_seed};
use crate::data::run_episode;
use crate::error::{Error, Result};

/// A point (or normal) of the classification, in f64.
pub type Point = [f64; POINT_DIM];

/// Index of the torso's x in the ant-linclass observation.
const TORSO_X: usize = sim::ant::obs::XY;

/// A demo shows a side when the torso's |x| at its last transition is at least this (m); the
/// targets are at |x| = 1.41.
pub const SHOWN_X: f32 = 0.25;

/// An episode commits to a side at the first step its torso's |x| reaches this (m): past the
/// start's jitter (the scripted expert's median |x| at step 5 is about 0.1), far short of the
/// targets' 1.41.
pub const COMMIT_X: f32 = 0.25;

/// Reset seeds of the fresh pairs the bound is also scored on start here, far from the
/// evaluation's ([`episode_seed`]) and the demos' seeds.
const FRESH_SEED_BASE: u64 = 1 << 40;

fn dot(a: &Point, b: &Point) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn to_point(xs: &[f32]) -> Result<Point> {
    if xs.len() != POINT_DIM {
        return Err(Error::Shape(format!(
            "a point has {POINT_DIM} entries, got {}",
            xs.len()
        )));
    }
    Ok(std::array::from_fn(|i| xs[i] as f64))
}

fn sub(a: &Point, b: &Point) -> Point {
    std::array::from_fn(|i| a[i] - b[i])
}

/// The ant-linclass task's hyperplane seed and normal; an error for any other task.
fn hyperplane(task: &Task) -> Result<(u64, [f32; POINT_DIM])> {
    match (task.hyperplane_seed(), task.linclass_normal()) {
        (Some(hyperplane_seed), Some(normal)) => Ok((hyperplane_seed, normal)),
        _ => Err(Error::Data(format!(
            "{} is not an ant-linclass task",
            task.label()
        ))),
    }
}

/// What one demo shows: its pair, the truth, and the side it walked to.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DemoLabel {
    /// The first point of the demo's pair.
    pub first: Point,
    /// The second point.
    pub second: Point,
    /// The truth: the first point is on the hyperplane's positive side.
    pub first_positive: bool,
    /// What the demo shows: `Some(true)` when it walked to `TARGETS[0]` (the first point is
    /// positive), `Some(false)` to `TARGETS[1]`, `None` when its last |x| is under
    /// [`SHOWN_X`].
    pub shown: Option<bool>,
}

impl DemoLabel {
    /// The labelled points a learner can read from this demo: `(p, +1)` for the point it
    /// walked as positive, `(p, -1)` for the other; none when it shows no side.
    pub fn labelled_points(&self) -> Vec<(Point, f64)> {
        match self.shown {
            Some(first_positive) => {
                let y = if first_positive { 1.0 } else { -1.0 };
                vec![(self.first, y), (self.second, -y)]
            }
            None => Vec::new(),
        }
    }
}

/// The label of demo `tr` of a task with unit normal `normal`, in a dataset of `obs_dim`.
pub fn demo_label(tr: &Trajectory, normal: &[f32; POINT_DIM], obs_dim: usize) -> Result<DemoLabel> {
    if obs_dim != Family::ANT_LINCLASS.obs_dim() {
        return Err(Error::Shape(format!(
            "ant-linclass observations have {} entries, the demos {obs_dim}",
            Family::ANT_LINCLASS.obs_dim()
        )));
    }
    let n = tr.len();
    let (Some(first_obs), Some(last)) = (tr.obs.get(..obs_dim), n.checked_sub(1)) else {
        return Err(Error::Data("an empty demo shows nothing".into()));
    };
    let first = to_point(&first_obs[FIRST_POINT..SECOND_POINT])?;
    let second = to_point(&first_obs[SECOND_POINT..SECOND_POINT + POINT_DIM])?;
    let normal = normal.map(|x| x as f64);
    let x = tr
        .next_obs
        .get(last * obs_dim + TORSO_X)
        .copied()
        .ok_or_else(|| Error::Shape("a demo's next observations are short".into()))?;
    Ok(DemoLabel {
        first,
        second,
        first_positive: dot(&normal, &first) > 0.0,
        shown: (x.abs() >= SHOWN_X).then_some(x > 0.0),
    })
}

/// Every demo's label, per task of `ds` (in its order).
pub fn dataset_labels(ds: &DemoDataset) -> Result<Vec<Vec<DemoLabel>>> {
    ds.ensure_family(Family::ANT_LINCLASS)?;
    ds.tasks
        .iter()
        .map(|td| {
            let (_, normal) = hyperplane(&td.task)?;
            td.trajectories
                .iter()
                .filter(|t| !t.is_empty())
                .map(|t| demo_label(t, &normal, ds.obs_dim))
                .collect()
        })
        .collect()
}

/// How often the torso's x shows the right side at one time step, over a dataset's demos.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepVisibility {
    /// The time step of the transitions (their s' is the state after it).
    pub time_step: u32,
    /// Transitions kept at this step.
    pub transitions: usize,
    /// Fraction whose s' has its torso's x on the correct target's side (x > 0 for
    /// `TARGETS[0]`).
    pub x_on_correct_side: f64,
    /// Fraction whose s' has |x| >= [`COMMIT_X`] on the correct side: the side shown clearly.
    pub x_clearly_correct: f64,
    /// Median of x times the correct side's sign (m).
    pub median_signed_x: f64,
    /// How well the expert's action alone tells the two targets apart: leave-one-out
    /// nearest-centroid accuracy of the correct side from the action (NaN with fewer than 2
    /// demos of either side).
    pub action_side_accuracy: f64,
    /// Distance between the mean actions of the demos walking to either target.
    pub action_gap: f64,
}

/// Leave-one-out nearest-centroid accuracy of labels `y` (true / false) from vectors `xs`,
/// and the distance between the two centroids; NaN for fewer than 2 of either label.
fn nearest_centroid(rows: &[(bool, &[f32])]) -> (f64, f64) {
    let dim = rows.first().map_or(0, |(_, x)| x.len());
    let mut sum = [vec![0.0f64; dim], vec![0.0f64; dim]];
    let mut count = [0usize; 2];
    for (y, x) in rows {
        count[usize::from(*y)] += 1;
        for (s, v) in sum[usize::from(*y)].iter_mut().zip(x.iter()) {
            *s += *v as f64;
        }
    }
    if count.iter().any(|&c| c < 2) {
        return (f64::NAN, f64::NAN);
    }
    let centroid = |label: usize, without: Option<&[f32]>| -> Vec<f64> {
        let n = count[label] - usize::from(without.is_some());
        sum[label]
            .iter()
            .enumerate()
            .map(|(i, s)| (s - without.map_or(0.0, |x| x[i] as f64)) / n as f64)
            .collect()
    };
    let distance = |a: &[f64], b: &[f64]| -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let right = rows
        .iter()
        .filter(|(y, x)| {
            let own = usize::from(*y);
            let x64: Vec<f64> = x.iter().map(|&v| v as f64).collect();
            let to_own = distance(&x64, &centroid(own, Some(*x)));
            let to_other = distance(&x64, &centroid(1 - own, None));
            to_own < to_other
        })
        .count();
    (
        right as f64 / rows.len() as f64,
        distance(&centroid(1, None), &centroid(0, None)),
    )
}

/// Per time step, how visible the correct side is in `ds`'s demos, and the fraction of all
/// kept transitions that show it clearly.
pub fn visibility(ds: &DemoDataset) -> Result<(Vec<StepVisibility>, f64)> {
    ds.ensure_family(Family::ANT_LINCLASS)?;
    let d = ds.obs_dim;
    let a = ds.act_dim;
    let mut by_step: std::collections::BTreeMap<u32, Vec<f64>> = Default::default();
    let mut actions: std::collections::BTreeMap<u32, Vec<(bool, &[f32])>> = Default::default();
    for td in &ds.tasks {
        let (_, normal) = hyperplane(&td.task)?;
        for tr in td.trajectories.iter().filter(|t| !t.is_empty()) {
            let label = demo_label(tr, &normal, d)?;
            let sign = if label.first_positive { 1.0 } else { -1.0 };
            for (i, &t) in tr.time_steps.iter().enumerate() {
                let x =
                    tr.next_obs.get(i * d + TORSO_X).copied().ok_or_else(|| {
                        Error::Shape("a demo's next observations are short".into())
                    })?;
                by_step.entry(t).or_default().push(sign * x as f64);
                let action = tr
                    .actions
                    .get(i * a..(i + 1) * a)
                    .ok_or_else(|| Error::Shape("a demo's actions are short".into()))?;
                actions
                    .entry(t)
                    .or_default()
                    .push((label.first_positive, action));
            }
        }
    }
    let (mut clear, mut all) = (0usize, 0usize);
    let rows = by_step
        .into_iter()
        .map(|(time_step, mut xs)| {
            let n = xs.len();
            let clearly = xs.iter().filter(|&&x| x >= COMMIT_X as f64).count();
            clear += clearly;
            all += n;
            let right = xs.iter().filter(|&&x| x > 0.0).count();
            xs.sort_by(f64::total_cmp);
            let (action_side_accuracy, action_gap) =
                nearest_centroid(actions.get(&time_step).map_or(&[][..], Vec::as_slice));
            StepVisibility {
                time_step,
                transitions: n,
                x_on_correct_side: right as f64 / n as f64,
                x_clearly_correct: clearly as f64 / n as f64,
                median_signed_x: xs[n / 2],
                action_side_accuracy,
                action_gap,
            }
        })
        .collect();
    Ok((rows, clear as f64 / all.max(1) as f64))
}

/// Normals drawn from the tasks' prior (uniform on the sphere), for the Bayes rule.
#[derive(Debug, Clone)]
pub struct PriorSamples(Vec<Point>);

impl PriorSamples {
    /// `n` normals from a stream seeded by `seed`.
    pub fn new(n: usize, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            let w: Point = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
            let norm = dot(&w, &w).sqrt();
            if norm > 1e-6 {
                out.push(w.map(|x| x / norm));
            }
        }
        Self(out)
    }

    /// The samples consistent with every labelled point (`y (w . p) > 0`): the posterior's.
    pub fn consistent(&self, points: &[(Point, f64)]) -> Vec<Point> {
        self.0
            .iter()
            .filter(|w| points.iter().all(|(p, y)| y * dot(w, p) > 0.0))
            .copied()
            .collect()
    }
}

/// The Bayes rule's probability that `first` is the positive point of a pair known to lie on
/// both sides, from the posterior's samples: the fraction of those separating the pair that
/// put `first` on the positive side; `None` when none separates it.
pub fn bayes_first_positive(posterior: &[Point], first: &Point, second: &Point) -> Option<f64> {
    let (mut yes, mut no) = (0usize, 0usize);
    for w in posterior {
        let (a, b) = (dot(w, first), dot(w, second));
        if a > 0.0 && b < 0.0 {
            yes += 1;
        } else if a < 0.0 && b > 0.0 {
            no += 1;
        }
    }
    (yes + no > 0).then(|| yes as f64 / (yes + no) as f64)
}

/// The centroid normal `sum_i y_i p_i` of labelled points (for a demo's two points,
/// `y (p1 - p2)`).
pub fn centroid_normal(points: &[(Point, f64)]) -> Point {
    let mut w = [0.0; POINT_DIM];
    for (p, y) in points {
        for (wi, pi) in w.iter_mut().zip(p) {
            *wi += y * pi;
        }
    }
    w
}

/// The (nearly) hard-margin linear SVM through the origin on labelled points: the L1-loss dual
/// solved by coordinate descent (Hsieh et al. 2008) with box `C = 1e4`, points in a fixed
/// order, until the projected gradient is under 1e-9 or after 10,000 sweeps. Zero for no
/// points.
pub fn svm_normal(points: &[(Point, f64)]) -> Point {
    const C: f64 = 1e4;
    let mut alpha = vec![0.0f64; points.len()];
    let mut w = [0.0f64; POINT_DIM];
    for _ in 0..10_000 {
        let mut worst = 0.0f64;
        for ((p, y), a) in points.iter().zip(alpha.iter_mut()) {
            let q = dot(p, p);
            if q <= 0.0 {
                continue;
            }
            let g = y * dot(&w, p) - 1.0;
            let projected = if *a <= 0.0 {
                g.min(0.0)
            } else if *a >= C {
                g.max(0.0)
            } else {
                g
            };
            worst = worst.max(projected.abs());
            if projected != 0.0 {
                let new = (*a - g / q).clamp(0.0, C);
                for (wi, pi) in w.iter_mut().zip(p) {
                    *wi += (new - *a) * y * pi;
                }
                *a = new;
            }
        }
        if worst < 1e-9 {
            break;
        }
    }
    w
}

/// Score of a linear rule on a pair known to lie on both sides: the first point is called
/// positive when it is further on `w`'s positive side than the second; 1 right, 0 wrong, 0.5
/// for a tie (no information).
pub fn linear_score(w: &Point, first: &Point, second: &Point, first_positive: bool) -> f64 {
    let margin = dot(w, &sub(first, second));
    if margin == 0.0 {
        0.5
    } else if (margin > 0.0) == first_positive {
        1.0
    } else {
        0.0
    }
}

/// Score of the Bayes rule on a pair: its vote, 0.5 for a tie or no vote.
pub fn bayes_score(
    posterior: &[Point],
    first: &Point,
    second: &Point,
    first_positive: bool,
) -> f64 {
    match bayes_first_positive(posterior, first, second) {
        Some(p) if p > 0.5 => f64::from(u8::from(first_positive)),
        Some(p) if p < 0.5 => f64::from(u8::from(!first_positive)),
        _ => 0.5,
    }
}

/// The bound at one context size.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BoundRow {
    /// Demos per context.
    pub context_size: usize,
    /// Contexts scored (tasks x draws).
    pub contexts: usize,
    /// Demos in those contexts that showed no side (carry no label).
    pub demos_without_side: usize,
    /// Demos whose shown side is not the truth.
    pub demos_mislabelled: usize,
    /// Accuracy on the evaluation's episode pairs: Bayes, SVM, centroid.
    pub eval_pairs: RuleScores,
    /// Accuracy on the fresh pairs.
    pub fresh_pairs: RuleScores,
    /// Smallest number of prior samples left consistent with a context.
    pub min_posterior_samples: usize,
    /// Median of that number.
    pub median_posterior_samples: usize,
}

/// One accuracy per rule.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RuleScores {
    /// Pairs scored.
    pub pairs: usize,
    /// The Bayes rule.
    pub bayes: f64,
    /// The hard-margin SVM through the origin.
    pub svm: f64,
    /// The centroid `sum y (p1 - p2)`.
    pub centroid: f64,
}

/// How the bound draws its contexts and scores them.
#[derive(Debug, Clone, PartialEq)]
pub struct BoundSetup {
    /// Context sizes.
    pub sizes: Vec<usize>,
    /// Context draws per task and size (the evaluation's draws).
    pub draws: usize,
    /// Episodes per draw (the evaluation's rollouts): their pairs are scored.
    pub rollouts: usize,
    /// Fresh pairs scored per context.
    pub fresh_pairs: usize,
}

/// The information bound of `split`'s tasks with contexts from `contexts`, per context size.
pub fn information_bound(
    contexts: &DemoDataset,
    split: Split,
    setup: &BoundSetup,
    prior: &PriorSamples,
) -> Result<Vec<BoundRow>> {
    let family = Family::ANT_LINCLASS;
    let tasks = family.tasks(split);
    let demos = contexts_for(contexts, family, &tasks)?;
    let mut rows = Vec::with_capacity(setup.sizes.len());
    for &k in &setup.sizes {
        let (mut without, mut wrong, mut n_contexts) = (0usize, 0usize, 0usize);
        let mut eval_scores = [Vec::new(), Vec::new(), Vec::new()];
        let mut fresh_scores = [Vec::new(), Vec::new(), Vec::new()];
        let mut kept = Vec::new();
        for (i, (task, td)) in tasks.iter().zip(&demos).enumerate() {
            let (hseed, normal) = hyperplane(task)?;
            let trajs: Vec<&Trajectory> =
                td.trajectories.iter().filter(|t| !t.is_empty()).collect();
            for d in 0..setup.draws {
                let context = context_draw(&trajs, i, k, d);
                let mut points = Vec::new();
                for tr in &context {
                    let label = demo_label(tr, &normal, contexts.obs_dim)?;
                    match label.shown {
                        None => without += 1,
                        Some(s) if s != label.first_positive => wrong += 1,
                        Some(_) => {}
                    }
                    points.extend(label.labelled_points());
                }
                let posterior = prior.consistent(&points);
                kept.push(posterior.len());
                let (svm, centroid) = (svm_normal(&points), centroid_normal(&points));
                let score = |seed: u64, out: &mut [Vec<f64>; 3]| {
                    let (a, b, first_positive) = draw_pair(&normal, hseed, seed);
                    let (a, b) = (a.map(f64::from), b.map(f64::from));
                    out[0].push(bayes_score(&posterior, &a, &b, first_positive));
                    out[1].push(linear_score(&svm, &a, &b, first_positive));
                    out[2].push(linear_score(&centroid, &a, &b, first_positive));
                };
                for r in 0..setup.rollouts {
                    score(episode_seed(d, r), &mut eval_scores);
                }
                for j in 0..setup.fresh_pairs {
                    score(FRESH_SEED_BASE + j as u64, &mut fresh_scores);
                }
                n_contexts += 1;
            }
        }
        kept.sort_unstable();
        let mean = |xs: &Vec<f64>| xs.iter().sum::<f64>() / xs.len().max(1) as f64;
        let scores = |s: &[Vec<f64>; 3]| RuleScores {
            pairs: s[0].len(),
            bayes: mean(&s[0]),
            svm: mean(&s[1]),
            centroid: mean(&s[2]),
        };
        rows.push(BoundRow {
            context_size: k,
            contexts: n_contexts,
            demos_without_side: without,
            demos_mislabelled: wrong,
            eval_pairs: scores(&eval_scores),
            fresh_pairs: scores(&fresh_scores),
            min_posterior_samples: kept.first().copied().unwrap_or(0),
            median_posterior_samples: kept.get(kept.len() / 2).copied().unwrap_or(0),
        });
    }
    Ok(rows)
}

/// The latent's decision probe at one context size.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProbeRow {
    /// Demos per context.
    pub context_size: usize,
    /// Rows (tasks x draws).
    pub rows: usize,
    /// Leave-one-task-out R^2 per component of the normal.
    pub r2: Vec<f64>,
    /// Their mean.
    pub mean_r2: f64,
    /// Mean cosine between the predicted and the true normal.
    pub mean_cosine: f64,
    /// Accuracy of the predicted normal on the evaluation's episode pairs of each row's draw
    /// ([`linear_score`]).
    pub pair_accuracy: f64,
}

/// The decision probe of latents `rows` (one policy, one split), per context size in `rows`;
/// each row's pairs are those of `rollouts` episodes of its draw.
pub fn probe_decisions(rows: &[LatentRow], rollouts: usize) -> Result<Vec<ProbeRow>> {
    let mut sizes: Vec<usize> = rows.iter().map(|r| r.context_size).collect();
    sizes.sort_unstable();
    sizes.dedup();
    let mut out = Vec::with_capacity(sizes.len());
    for k in sizes {
        let of_size: Vec<LatentRow> = rows
            .iter()
            .filter(|r| r.context_size == k)
            .cloned()
            .collect();
        let predicted = probe_predictions(&of_size)?;
        let pd = of_size.first().map_or(0, |r| r.parameter.len());
        let n = of_size.len() as f64;
        let r2: Vec<f64> = (0..pd)
            .map(|p| {
                let m = of_size.iter().map(|r| r.parameter[p] as f64).sum::<f64>() / n;
                let (mut sse, mut sst) = (0.0, 0.0);
                for (r, guess) in of_size.iter().zip(&predicted) {
                    sse += (r.parameter[p] as f64 - guess[p]).powi(2);
                    sst += (r.parameter[p] as f64 - m).powi(2);
                }
                if sst > 0.0 { 1.0 - sse / sst } else { f64::NAN }
            })
            .collect();
        let (mut cosines, mut scores) = (Vec::new(), Vec::new());
        for (r, guess) in of_size.iter().zip(&predicted) {
            let truth = to_point(&r.parameter)?;
            let guess = to_point(&guess.iter().map(|&x| x as f32).collect::<Vec<_>>())?;
            let norm = dot(&guess, &guess).sqrt() * dot(&truth, &truth).sqrt();
            cosines.push(if norm > 0.0 {
                dot(&guess, &truth) / norm
            } else {
                0.0
            });
            let task = Family::ANT_LINCLASS
                .task_from_value(r.value)
                .map_err(|e| Error::Data(format!("latent row of task {}: {e}", r.task)))?;
            let (hseed, normal) = hyperplane(&task)?;
            for j in 0..rollouts {
                let (a, b, first_positive) = draw_pair(&normal, hseed, episode_seed(r.draw, j));
                scores.push(linear_score(
                    &guess,
                    &a.map(f64::from),
                    &b.map(f64::from),
                    first_positive,
                ));
            }
        }
        let finite: Vec<f64> = r2.iter().copied().filter(|x| x.is_finite()).collect();
        let mean = |xs: &[f64]| xs.iter().sum::<f64>() / xs.len().max(1) as f64;
        out.push(ProbeRow {
            context_size: k,
            rows: of_size.len(),
            mean_r2: mean(&finite),
            r2,
            mean_cosine: mean(&cosines),
            pair_accuracy: mean(&scores),
        });
    }
    Ok(out)
}

/// One evaluation episode's path across the decision.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EpisodeTrace {
    /// Task index in the split.
    pub task: usize,
    /// Demos in the context.
    pub context_size: usize,
    /// Context draw.
    pub draw: usize,
    /// Rollout of that draw.
    pub rollout: usize,
    /// The correct target's side: +1 for `TARGETS[0]` (x > 0), -1 for `TARGETS[1]`.
    pub correct_side: i8,
    /// 1 the correct target reached first, -1 the wrong one, 0 none.
    pub decision: i8,
    /// The torso's x after each step (m).
    pub x: Vec<f32>,
}

impl EpisodeTrace {
    /// The first step (1-based: after that many steps) whose |x| reaches `commit_x`, and the
    /// side (+1 or -1) it was on.
    pub fn commit(&self, commit_x: f32) -> Option<(usize, i8)> {
        self.x
            .iter()
            .position(|x| x.abs() >= commit_x)
            .map(|i| (i + 1, if self.x[i] > 0.0 { 1 } else { -1 }))
    }

    /// The side after `step` steps (1-based) relative to the correct one: 1 on it, -1 on the
    /// other, 0 within `commit_x` of the middle or past the episode's end.
    pub fn side_at(&self, step: usize, commit_x: f32) -> i8 {
        match step.checked_sub(1).and_then(|i| self.x.get(i)) {
            Some(x) if x.abs() >= commit_x => {
                if (*x > 0.0) == (self.correct_side > 0) {
                    1
                } else {
                    -1
                }
            }
            _ => 0,
        }
    }
}

/// The evaluation's episodes of `actor` on `split`'s tasks with contexts from `contexts`:
/// the same context draws, reset seeds and deterministic actions as [`super::evaluate`], with
/// the torso's x recorded per step.
pub fn trace_episodes(
    actor: &mut dyn ConditionedActor,
    contexts: &DemoDataset,
    split: Split,
    setup: &BoundSetup,
    env_config: EnvConfig,
) -> Result<Vec<EpisodeTrace>> {
    let family = Family::ANT_LINCLASS;
    let tasks = family.tasks(split);
    let demos = contexts_for(contexts, family, &tasks)?;
    let mut env = sim::make_env(family, env_config)?;
    let mut out = Vec::new();
    for (i, (task, td)) in tasks.iter().zip(&demos).enumerate() {
        let (hseed, normal) = hyperplane(task)?;
        let trajs: Vec<&Trajectory> = td.trajectories.iter().filter(|t| !t.is_empty()).collect();
        for &k in &setup.sizes {
            for d in 0..setup.draws {
                let z = actor.latent(&context_draw(&trajs, i, k, d))?;
                for r in 0..setup.rollouts {
                    let seed = episode_seed(d, r);
                    let (_, _, first_positive) = draw_pair(&normal, hseed, seed);
                    let mut x = Vec::new();
                    let ep = run_episode(
                        env.as_mut(),
                        task,
                        seed,
                        &mut |o, a| actor.act(o, &z, a),
                        &mut |step| {
                            let xt = step.next_obs.get(TORSO_X).copied().ok_or_else(|| {
                                Error::Shape("an observation without the torso's x".into())
                            })?;
                            x.push(xt);
                            Ok(())
                        },
                    )?;
                    let decision = match (ep.no_op, ep.metric > 0.5) {
                        (Some(true), _) => 0,
                        (_, true) => 1,
                        (_, false) => -1,
                    };
                    out.push(EpisodeTrace {
                        task: i,
                        context_size: k,
                        draw: d,
                        rollout: r,
                        correct_side: if first_positive { 1 } else { -1 },
                        decision,
                        x,
                    });
                }
            }
        }
    }
    Ok(out)
}

/// Where a set of episodes decided, as fractions of all of them.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TimingRow {
    /// Demos per context (None: every size together).
    pub context_size: Option<usize>,
    /// Episodes.
    pub episodes: usize,
    /// Correct target reached first.
    pub success: f64,
    /// No target reached.
    pub no_op: f64,
    /// success / (1 - no_op).
    pub decided_accuracy: f64,
    /// Per checkpoint step: (step, on the correct side, on the wrong side), |x| >= [`COMMIT_X`].
    pub side_at: Vec<(usize, f64, f64)>,
    /// Committed (|x| reached [`COMMIT_X`]) first on the correct side.
    pub committed_right: f64,
    /// Committed first on the wrong side: wrong from the first steps.
    pub committed_wrong: f64,
    /// Never committed.
    pub never_committed: f64,
    /// Accuracy of the first commitment among the committed episodes.
    pub commit_accuracy: f64,
    /// Median step of the commitment.
    pub median_commit_step: f64,
    /// Decided wrong after committing wrong (wrong from the first steps).
    pub wrong_from_start: f64,
    /// Decided wrong, or ended on the wrong side undecided, after committing to the right side
    /// (drifted later).
    pub drifted: f64,
    /// Decided right after committing wrong (recovered).
    pub recovered: f64,
    /// Share of the first commitments that went to `TARGETS[0]` (x > 0); the correct side is
    /// `TARGETS[0]` in about half the episodes.
    pub commits_to_first_target: f64,
    /// The first commitment's accuracy averaged over the two correct sides (bias-free: a
    /// policy that always walks to one target scores 0.5).
    pub balanced_commit_accuracy: f64,
    /// The same for the decisions.
    pub balanced_decided_accuracy: f64,
}

/// Timing of `traces` with sides read at `checkpoints` (steps), per context size and for all.
pub fn timing_summary(traces: &[EpisodeTrace], checkpoints: &[usize]) -> Vec<TimingRow> {
    let mut sizes: Vec<usize> = traces.iter().map(|t| t.context_size).collect();
    sizes.sort_unstable();
    sizes.dedup();
    let mut groups: Vec<Option<usize>> = sizes.into_iter().map(Some).collect();
    groups.push(None);
    groups
        .into_iter()
        .map(|group| {
            let eps: Vec<&EpisodeTrace> = traces
                .iter()
                .filter(|t| group.is_none_or(|k| t.context_size == k))
                .collect();
            let n = eps.len().max(1) as f64;
            let frac =
                |f: &dyn Fn(&EpisodeTrace) -> bool| eps.iter().filter(|t| f(t)).count() as f64 / n;
            let success = frac(&|t| t.decision == 1);
            let no_op = frac(&|t| t.decision == 0);
            let committed = |t: &EpisodeTrace| t.commit(COMMIT_X).map(|(_, s)| s == t.correct_side);
            let last_side = |t: &EpisodeTrace| t.side_at(t.x.len(), COMMIT_X);
            let mut steps: Vec<f64> = eps
                .iter()
                .filter_map(|t| t.commit(COMMIT_X).map(|(s, _)| s as f64))
                .collect();
            steps.sort_by(f64::total_cmp);
            // Accuracy of `hit` among the episodes where `seen` holds, averaged over the two
            // correct sides.
            let balanced = |seen: &dyn Fn(&EpisodeTrace) -> bool,
                            hit: &dyn Fn(&EpisodeTrace) -> bool| {
                let per_side: Vec<f64> = [1i8, -1]
                    .iter()
                    .filter_map(|&side| {
                        let of: Vec<&&EpisodeTrace> = eps
                            .iter()
                            .filter(|t| t.correct_side == side && seen(t))
                            .collect();
                        (!of.is_empty())
                            .then(|| of.iter().filter(|t| hit(t)).count() as f64 / of.len() as f64)
                    })
                    .collect();
                if per_side.len() == 2 {
                    (per_side[0] + per_side[1]) / 2.0
                } else {
                    f64::NAN
                }
            };
            let commits: Vec<i8> = eps
                .iter()
                .filter_map(|t| t.commit(COMMIT_X).map(|(_, s)| s))
                .collect();
            let right = frac(&|t| committed(t) == Some(true));
            let wrong = frac(&|t| committed(t) == Some(false));
            TimingRow {
                context_size: group,
                episodes: eps.len(),
                success,
                no_op,
                decided_accuracy: if no_op < 1.0 {
                    success / (1.0 - no_op)
                } else {
                    f64::NAN
                },
                side_at: checkpoints
                    .iter()
                    .map(|&s| {
                        (
                            s,
                            frac(&|t| t.side_at(s, COMMIT_X) == 1),
                            frac(&|t| t.side_at(s, COMMIT_X) == -1),
                        )
                    })
                    .collect(),
                committed_right: right,
                committed_wrong: wrong,
                never_committed: frac(&|t| committed(t).is_none()),
                commit_accuracy: if right + wrong > 0.0 {
                    right / (right + wrong)
                } else {
                    f64::NAN
                },
                median_commit_step: steps.get(steps.len() / 2).copied().unwrap_or(f64::NAN),
                wrong_from_start: frac(&|t| committed(t) == Some(false) && t.decision == -1),
                drifted: frac(&|t| {
                    committed(t) == Some(true)
                        && (t.decision == -1 || (t.decision == 0 && last_side(t) == -1))
                }),
                recovered: frac(&|t| committed(t) == Some(false) && t.decision == 1),
                commits_to_first_target: if commits.is_empty() {
                    f64::NAN
                } else {
                    commits.iter().filter(|&&s| s > 0).count() as f64 / commits.len() as f64
                },
                balanced_commit_accuracy: balanced(&|t| committed(t).is_some(), &|t| {
                    committed(t) == Some(true)
                }),
                balanced_decided_accuracy: balanced(&|t| t.decision != 0, &|t| t.decision == 1),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests;
