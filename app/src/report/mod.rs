//! `smile report`: `smile eval` results of many runs aggregated into a paper-shaped table
//! (methods x settings, mean +- std over seeds, the number of seeds), as markdown and JSON,
//! with plots: the metric per test task with a band over seeds (the paper's Figure 2) and the
//! metric against the number of context demos.
//!
//! Inputs are sweep directories (their `manifest.json` names each cell's method, setting and
//! seed) or evaluation directories / `eval.json` files (each method in them is one seed of the
//! algorithm named before " (" in its name, in the setting "-").

mod files;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::sweep::{MANIFEST_FILE, Manifest};
use trainer::eval::{EvalReport, MethodResult, mean_std};
use trainer::{Error, Result};

/// One seed of one method in one setting.
#[derive(Debug, Clone)]
struct Entry {
    method: String,
    setting: String,
    seed: String,
    result: MethodResult,
}

/// A method in a setting, over seeds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// The method (plan table name or algorithm).
    pub method: String,
    /// The setting (demo file and swept keys), "-" for plain evaluations.
    pub setting: String,
    /// The seeds (labels) aggregated.
    pub seeds: Vec<String>,
    /// Each seed's mean over tasks.
    pub per_seed: Vec<f32>,
    /// Mean over seeds.
    pub mean: f32,
    /// Sample standard deviation over seeds (0 for one seed).
    pub std: f32,
    /// Mean over seeds per context size.
    pub by_context_size: Vec<f32>,
    /// Task labels.
    pub tasks: Vec<String>,
    /// Task parameters (the plot's x axis).
    pub task_values: Vec<f64>,
    /// Per task: mean over seeds.
    pub task_mean: Vec<f32>,
    /// Per task: sample std over seeds.
    pub task_std: Vec<f32>,
    /// walker-dyn's normalised score per seed, when every seed's evaluation has it (`smile
    /// eval --base --expert`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normalised: Option<NormalisedRow>,
    /// Classification families: the no-op rate over seeds, when every seed's evaluation has it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub no_op: Option<NoOpRow>,
}

/// The no-op rate (episodes without a decision) of a row over its seeds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoOpRow {
    /// Each seed's no-op rate.
    pub per_seed: Vec<f32>,
    /// Mean over seeds.
    pub mean: f32,
    /// Sample standard deviation over seeds.
    pub std: f32,
    /// Mean over seeds per context size.
    pub by_context_size: Vec<f32>,
}

/// The normalised score of a row over its seeds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NormalisedRow {
    /// Each seed's score.
    pub per_seed: Vec<f32>,
    /// Mean over seeds.
    pub mean: f32,
    /// Sample standard deviation over seeds.
    pub std: f32,
    /// Tasks used (R_expert > R_base) by the first seed's evaluation.
    pub tasks_used: usize,
}

/// The aggregated report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// The family.
    pub env: sim::Family,
    /// Metric name.
    pub metric: String,
    /// True if lower is better.
    pub lower_is_better: bool,
    /// Context sizes of the protocol.
    pub context_sizes: Vec<usize>,
    /// One row per (method, setting).
    pub rows: Vec<Row>,
    /// Sweep cells left out, each with why (not evaluated yet, unreadable evaluation): a row
    /// with fewer seeds than planned says so here, not silently.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub left_out: Vec<String>,
}

fn read_eval(path: &Path) -> Result<EvalReport> {
    let file = if path.is_dir() {
        path.join("eval.json")
    } else {
        path.to_path_buf()
    };
    let text = std::fs::read_to_string(&file).map_err(|e| Error::Io {
        path: file.clone(),
        source: e,
    })?;
    serde_json::from_str(&text).map_err(|e| {
        Error::Data(format!(
            "{} is not a `smile eval` report: {e}",
            file.display()
        ))
    })
}

/// Sample standard deviation (n - 1), 0 for fewer than two values.
fn sample_std(xs: &[f32]) -> f32 {
    if xs.len() < 2 {
        return 0.0;
    }
    let m = xs.iter().map(|&x| x as f64).sum::<f64>() / xs.len() as f64;
    let v = xs.iter().map(|&x| (x as f64 - m).powi(2)).sum::<f64>() / (xs.len() - 1) as f64;
    v.sqrt() as f32
}

/// The evaluations read so far, for [`Report::from_inputs`].
#[derive(Default)]
struct Gather {
    entries: Vec<Entry>,
    left_out: Vec<String>,
    /// The first evaluation: the others must be of its family, metric and protocol.
    head: Option<EvalReport>,
    /// Each evaluation counts once: the same file given twice (or a copy of it) would count as
    /// two seeds with a std of 0.
    seen: BTreeMap<String, PathBuf>,
}

impl Gather {
    /// The methods of `rep`, read from `origin`, once it is checked against the first.
    fn take(&mut self, rep: EvalReport, origin: &Path) -> Result<Vec<MethodResult>> {
        let file = if origin.is_dir() {
            origin.join("eval.json")
        } else {
            origin.to_path_buf()
        };
        let sha = trainer::checkpoint::sha256_file(&file)?;
        if let Some(first) = self.seen.insert(sha, origin.to_path_buf()) {
            return Err(Error::Data(format!(
                "{} and {} are the same evaluation (the same eval.json, byte for byte): each \
                 seed counts once; give each evaluation one time",
                first.display(),
                origin.display()
            )));
        }
        let Some(h) = &self.head else {
            self.head = Some(rep.clone());
            return Ok(rep.methods);
        };
        if h.protocol.run_through_falls != rep.protocol.run_through_falls {
            return Err(Error::Data(format!(
                "{} was evaluated with the walker protocol \"{}\", the first with \"{}\": \
                 returns of the two are not comparable",
                origin.display(),
                rep.protocol.label(),
                h.protocol.label()
            )));
        }
        if (h.env, h.metric.as_str(), &h.protocol.context_sizes)
            != (rep.env, rep.metric.as_str(), &rep.protocol.context_sizes)
        {
            return Err(Error::Data(format!(
                "{} is a {} evaluation ({}, context sizes {:?}); the first was {} ({}, {:?})",
                origin.display(),
                rep.env,
                rep.metric,
                rep.protocol.context_sizes,
                h.env,
                h.metric,
                h.protocol.context_sizes
            )));
        }
        Ok(rep.methods)
    }

    /// Every evaluated cell of the sweep in `input`; a cell not evaluated yet is left out.
    fn sweep(&mut self, input: &Path) -> Result<()> {
        let manifest = input.join(MANIFEST_FILE);
        let text = std::fs::read_to_string(&manifest).map_err(|e| Error::Io {
            path: manifest.clone(),
            source: e,
        })?;
        let m: Manifest = serde_json::from_str(&text).map_err(|e| {
            Error::Data(format!(
                "{} is not a sweep manifest: {e}",
                manifest.display()
            ))
        })?;
        // A cell listed twice (a hand-edited or merged manifest) would count as two seeds.
        let mut seen = std::collections::HashSet::new();
        for c in &m.cells {
            // (The name, not method + setting + seed: two demo files of one label are two cells.)
            if !seen.insert(c.cell.name.as_str()) {
                return Err(Error::Data(format!(
                    "{} lists {} (seed {} of {}, {}) twice: one cell is one seed; remove the \
                     repeated entry, or run `smile sweep` on the plan to write the manifest again",
                    manifest.display(),
                    c.cell.name,
                    c.cell.seed,
                    c.cell.method,
                    c.cell.setting()
                )));
            }
        }
        for c in &m.cells {
            let eval = input.join(&c.cell.name).join("eval");
            if !eval.join("eval.json").exists() {
                self.left_out.push(format!(
                    "{} (seed {} of {}, {}): not evaluated yet ({:?} in the manifest)",
                    c.cell.name,
                    c.cell.seed,
                    c.cell.method,
                    c.cell.setting(),
                    c.status
                ));
                continue;
            }
            let rep = match read_eval(&eval) {
                Ok(rep) => rep,
                Err(e) => {
                    self.left_out.push(format!("{}: {e}", c.cell.name));
                    continue;
                }
            };
            for r in self.take(rep, &eval)? {
                self.entries.push(Entry {
                    method: c.cell.method.clone(),
                    setting: c.cell.setting(),
                    seed: c.cell.seed.to_string(),
                    result: r,
                });
            }
        }
        Ok(())
    }

    /// The methods of one evaluation (a directory or its `eval.json`).
    fn evaluation(&mut self, input: &Path) -> Result<()> {
        if input.is_dir() && !input.join("eval.json").exists() {
            return Err(Error::Data(format!(
                "{}: neither a sweep directory (no {MANIFEST_FILE}) nor an evaluation (no \
                 eval.json); a sweep's manifest is written when it starts, by `--slurm` and \
                 after each `smile sweep run-cell`",
                input.display()
            )));
        }
        for r in self.take(read_eval(input)?, input)? {
            let method = r.name.split(" (").next().unwrap_or(&r.name).to_string();
            self.entries.push(Entry {
                method,
                setting: "-".into(),
                seed: r.name.clone(),
                result: r,
            });
        }
        Ok(())
    }
}

impl Report {
    /// Aggregates the evaluations found in `inputs` (sweep directories, evaluation
    /// directories or `eval.json` files). Cells without an evaluation yet are left out; all
    /// evaluations must be of one family, metric and protocol.
    pub fn from_inputs(inputs: &[PathBuf]) -> Result<Self> {
        let mut g = Gather::default();
        for input in inputs {
            if input.join(MANIFEST_FILE).exists() {
                g.sweep(input)?;
            } else {
                g.evaluation(input)?;
            }
        }
        let head = g.head.ok_or_else(|| {
            Error::Data(
                "no evaluation found in the inputs (no eval.json; cells not evaluated yet?)".into(),
            )
        })?;
        let mut groups: BTreeMap<(String, String), Vec<Entry>> = BTreeMap::new();
        let mut order: Vec<(String, String)> = Vec::new();
        for e in g.entries {
            let key = (e.method.clone(), e.setting.clone());
            if !groups.contains_key(&key) {
                order.push(key.clone());
            }
            groups.entry(key).or_default().push(e);
        }
        let rows = order
            .into_iter()
            .map(|key| row(&key.0, &key.1, &groups[&key]))
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            env: head.env,
            metric: head.metric,
            lower_is_better: head.lower_is_better,
            context_sizes: head.protocol.context_sizes,
            rows,
            left_out: g.left_out,
        })
    }

    /// The markdown table.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "# {}: {} ({} is better), mean +- std over seeds\n\n",
            self.env,
            self.metric,
            if self.lower_is_better {
                "lower"
            } else {
                "higher"
            }
        );
        let sizes: Vec<String> = self.context_sizes.iter().map(usize::to_string).collect();
        let (mut norm_head, mut norm_rule) = if self.rows.iter().any(|r| r.normalised.is_some()) {
            (" normalised score (mean +- std) |".to_string(), "---|")
        } else {
            (String::new(), "")
        };
        if self.rows.iter().any(|r| r.no_op.is_some()) {
            norm_head = format!(
                " no-op rate (mean +- std) | no-op by context size ({}) |",
                sizes.join(" / ")
            );
            norm_rule = "---|---|";
        }
        s.push_str(&format!(
            "| method | setting | seeds | per seed | mean +- std | by context size ({}) |{norm_head}\n|---|---|---|---|---|---|{norm_rule}\n",
            sizes.join(" / ")
        ));
        for r in &self.rows {
            let per: Vec<String> = r.per_seed.iter().map(|x| format!("{x:.3}")).collect();
            let mut normalised = r.normalised.as_ref().map_or(String::new(), |n| {
                format!(" {:.3} +- {:.3} ({} tasks) |", n.mean, n.std, n.tasks_used)
            });
            if let Some(n) = &r.no_op {
                let by: Vec<String> = n
                    .by_context_size
                    .iter()
                    .map(|x| format!("{x:.3}"))
                    .collect();
                normalised = format!(" {:.3} +- {:.3} | {} |", n.mean, n.std, by.join(" / "));
            } else if norm_rule == "---|---|" {
                // A row without no-op data (an evaluation by an older binary) keeps the columns.
                normalised = " - | - |".into();
            }
            let by: Vec<String> = r
                .by_context_size
                .iter()
                .map(|x| format!("{x:.3}"))
                .collect();
            s.push_str(&format!(
                "| {} | {} | {} | {} | **{:.3} +- {:.3}** | {} |{normalised}\n",
                r.method,
                r.setting,
                r.seeds.len(),
                per.join(", "),
                r.mean,
                r.std,
                by.join(" / ")
            ));
        }
        if !self.left_out.is_empty() {
            s.push_str(&format!(
                "\n**{} cell(s) left out** (rows above have fewer seeds than planned):\n\n",
                self.left_out.len()
            ));
            for l in &self.left_out {
                s.push_str(&format!("- {l}\n"));
            }
        }
        s
    }
}

fn row(method: &str, setting: &str, entries: &[Entry]) -> Result<Row> {
    let first = &entries[0].result;
    for e in entries {
        if e.result.tasks.len() != first.tasks.len() {
            return Err(Error::Data(format!(
                "{method} ({setting}): seed {} has {} tasks, seed {} has {}",
                e.seed,
                e.result.tasks.len(),
                entries[0].seed,
                first.tasks.len()
            )));
        }
    }
    let per_seed: Vec<f32> = entries.iter().map(|e| e.result.mean).collect();
    let (mean, _) = mean_std(&per_seed);
    let by_context_size = (0..first.by_context_size.len())
        .map(|k| {
            let xs: Vec<f32> = entries
                .iter()
                .map(|e| e.result.by_context_size[k])
                .collect();
            mean_std(&xs).0
        })
        .collect();
    let (mut task_mean, mut task_std) = (Vec::new(), Vec::new());
    for t in 0..first.tasks.len() {
        let xs: Vec<f32> = entries.iter().map(|e| e.result.tasks[t].metric).collect();
        task_mean.push(mean_std(&xs).0);
        task_std.push(sample_std(&xs));
    }
    let scores: Option<Vec<f32>> = entries
        .iter()
        .map(|e| e.result.normalised.as_ref().and_then(|n| n.score))
        .collect();
    let normalised = scores.map(|per_seed| NormalisedRow {
        mean: mean_std(&per_seed).0,
        std: sample_std(&per_seed),
        tasks_used: first.normalised.as_ref().map_or(0, |n| n.tasks_used),
        per_seed,
    });
    let no_op_seeds: Option<Vec<f32>> = entries.iter().map(|e| e.result.no_op_rate).collect();
    let no_op_sizes: Option<Vec<&Vec<f32>>> = entries
        .iter()
        .map(|e| e.result.no_op_by_context_size.as_ref())
        .collect();
    let no_op = no_op_seeds.map(|per_seed| NoOpRow {
        mean: mean_std(&per_seed).0,
        std: sample_std(&per_seed),
        by_context_size: no_op_sizes.map_or_else(Vec::new, |rows| {
            (0..rows.first().map_or(0, |r| r.len()))
                .map(|k| {
                    let xs: Vec<f32> = rows.iter().filter_map(|r| r.get(k).copied()).collect();
                    mean_std(&xs).0
                })
                .collect()
        }),
        per_seed,
    });
    Ok(Row {
        no_op,
        normalised,
        method: method.into(),
        setting: setting.into(),
        seeds: entries.iter().map(|e| e.seed.clone()).collect(),
        std: sample_std(&per_seed),
        per_seed,
        mean,
        by_context_size,
        tasks: first.tasks.iter().map(|t| t.task.clone()).collect(),
        task_values: first.tasks.iter().map(|t| t.value).collect(),
        task_mean,
        task_std,
    })
}
