//! A sweep plan (TOML) and its expansion into cells.
//!
//! ```toml
//! env = "point-goal"                      # task family
//! out = "runs/pg-3seeds"                  # sweep directory (default: runs/<plan file stem>)
//! demos = ["runs/pg-train.safetensors"]   # axis: meta-train demo files (one or more)
//! seeds = [0, 1, 2]                       # axis: seeds
//!
//! [algo.smile]                            # axis: one table per method
//! algo = "smile"                          # smile | smile-state-only | meta-bc | meta-dagger
//! config = "docs/configs/cv-smile.toml"   # optional base config (paths relative to the plan)
//! set = { total_updates = 30000 }         # config keys set for every cell of this method
//! axes = { gp_weight = [0.1, 1.0] }       # config keys swept for this method
//! expert = "runs/pg-expert"               # meta-dagger's relabelling expert
//!
//! [eval]                                  # the evaluation run after training
//! contexts = "runs/pg-test.safetensors"
//! horizon = 1000                          # optional episode length
//! context_sizes = [1, 2, 3, 4]            # optional (default: the family's protocol)
//! # walker-dyn only, optional: the normalised metric's base policy and experts (smile eval
//! # --base/--expert)
//! # base = "runs/walker/base"
//! # experts = ["runs/walker/expert-10000", "runs/walker/expert-10001"]
//! ```
//!
//! Cells are the product of methods x demo files x each method's config axes x seeds, in that
//! order (seeds vary fastest); a cell's index is its position. Every cell's configuration is
//! checked against its algorithm's config type (unknown keys, invalid values) and every file
//! is checked to exist before anything runs.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sim::Family;

use trainer::Algo;
use trainer::{Error, Result};

/// A sweep plan as written.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Plan {
    /// Task family.
    pub env: Family,
    /// Sweep directory; relative paths are relative to the current directory. Default
    /// `runs/<plan file stem>`.
    #[serde(default)]
    pub out: Option<PathBuf>,
    /// Meta-train demo files (an axis).
    pub demos: Vec<PathBuf>,
    /// Seeds (an axis).
    pub seeds: Vec<u64>,
    /// Methods (an axis), by name.
    pub algo: BTreeMap<String, Method>,
    /// The evaluation after training.
    pub eval: EvalPlan,
}

/// One method of a plan.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Method {
    /// `smile train --algo` (default: the table's name).
    #[serde(default)]
    pub algo: Option<String>,
    /// Base config file (SMILe or Meta-BC TOML), relative to the plan file.
    #[serde(default)]
    pub config: Option<PathBuf>,
    /// Config keys set in every cell of this method (dotted keys for sections).
    #[serde(default)]
    pub set: toml::Table,
    /// Config keys swept for this method: key -> values.
    #[serde(default)]
    pub axes: BTreeMap<String, Vec<toml::Value>>,
    /// Meta-DAgger's expert (a `smile expert` run), relative to the plan file.
    #[serde(default)]
    pub expert: Option<PathBuf>,
}

/// The evaluation of every cell (`smile eval` on the test split).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct EvalPlan {
    /// Context demos of the evaluation tasks (meta-test demos).
    pub contexts: PathBuf,
    /// Episode length override.
    #[serde(default)]
    pub horizon: Option<usize>,
    /// Context sizes override.
    #[serde(default)]
    pub context_sizes: Vec<usize>,
    /// Rollouts per context draw override.
    #[serde(default)]
    pub rollouts: Option<usize>,
    /// walker-dyn normalised metric: the base policy (`smile eval --base`). Needs `experts`.
    #[serde(default)]
    pub base: Option<PathBuf>,
    /// walker-dyn normalised metric: the experts (`smile eval --expert`: per-task experts
    /// and/or one general expert). Needs `base`.
    #[serde(default)]
    pub experts: Vec<PathBuf>,
}

/// One cell: a training run and its evaluation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Cell {
    /// Position in the sweep (the Slurm array index).
    pub index: usize,
    /// Directory name inside the sweep directory.
    pub name: String,
    /// The method's table name (what the report groups by).
    pub method: String,
    /// `smile train --algo`.
    pub algo: String,
    /// The demo file.
    #[serde(with = "trainer::os_path")]
    pub demos: PathBuf,
    /// The seed.
    pub seed: u64,
    /// The swept config keys of this cell (key -> value as TOML).
    pub params: BTreeMap<String, String>,
    /// The full config given to `smile train --config` (base file + set + params + seed).
    pub config: String,
    /// Meta-DAgger's expert.
    #[serde(with = "trainer::os_path::option", default)]
    pub expert: Option<PathBuf>,
    /// What the training depends on (algorithm, full config, demo and expert paths), hashed:
    /// a cell directory trained for another key is stale, and two cells with one key are one
    /// training listed twice.
    #[serde(default)]
    pub key: String,
}

impl Cell {
    /// [`Cell::key`] from the cell's fields.
    pub fn training_key(&self) -> String {
        let text = format!(
            "algo {}\ndemos {}\nexpert {:?}\nconfig\n{}",
            self.algo,
            self.demos.display(),
            self.expert,
            self.config
        );
        trainer::checkpoint::sha256_hex(text.as_bytes())[..16].to_string()
    }

    /// The setting this cell belongs to, without the seed: what the report averages over.
    pub fn setting(&self) -> String {
        let mut s = self.demos_label();
        for (k, v) in &self.params {
            s.push_str(&format!(", {k}={v}"));
        }
        s
    }

    /// The cores this cell's training keeps busy: SMILe's `learner_threads`, else 1. The
    /// config was checked at load, so a value that does not parse counts as 1.
    pub fn cpus(&self) -> usize {
        self.config
            .parse::<toml::Table>()
            .ok()
            .and_then(|t| t.get("learner_threads")?.as_integer())
            .map_or(1, |n| {
                n.clamp(1, trainer::threads::MAX_LEARNER_THREADS as i64) as usize
            })
    }

    /// The demo file's stem.
    pub fn demos_label(&self) -> String {
        self.demos
            .file_stem()
            .map_or("demos".into(), |s| s.to_string_lossy().into_owned())
    }
}

/// A plan read from a file, with its cells.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// The plan file.
    pub path: PathBuf,
    /// The plan (its file paths resolved against the plan's directory).
    pub plan: Plan,
    /// The family.
    pub family: Family,
    /// The sweep directory.
    pub out: PathBuf,
    /// The cells, by index.
    pub cells: Vec<Cell>,
}

fn plan_err(path: &Path, text: &str, needle: Option<&str>, msg: String) -> Error {
    // The first line that names it outside a comment (a plan's header often quotes its files).
    let line = needle.and_then(|n| {
        text.lines()
            .position(|l| l.split('#').next().is_some_and(|code| code.contains(n)))
            .map(|i| format!(" (line {})", i + 1))
    });
    Error::Config(format!(
        "plan {}{}: {msg}",
        path.display(),
        line.unwrap_or_default()
    ))
}

/// The cartesian product of `axes` (key -> values), in key order, last key fastest.
fn product(axes: &BTreeMap<String, Vec<toml::Value>>) -> Vec<Vec<(String, toml::Value)>> {
    let mut out = vec![Vec::new()];
    for (k, vs) in axes {
        out = out
            .into_iter()
            .flat_map(|prefix| {
                vs.iter().map(move |v| {
                    let mut p = prefix.clone();
                    p.push((k.clone(), v.clone()));
                    p
                })
            })
            .collect();
    }
    out
}

fn short(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        other => other.to_string().replace([' ', '[', ']', '"'], ""),
    }
}

impl Sweep {
    /// The most cores any one cell keeps busy ([`Cell::cpus`]): a Slurm task's
    /// `--cpus-per-task`, and what divides the cores into local jobs.
    pub fn cpus_per_cell(&self) -> usize {
        self.cells.iter().map(Cell::cpus).max().unwrap_or(1)
    }

    /// How many cells to run at once on `cores` cores when the user does not say: one per
    /// `cpus_per_cell` cores, at least one (two-thread cells on two cores run one at a time,
    /// not two oversubscribed).
    pub fn default_jobs(&self, cores: usize) -> usize {
        (cores / self.cpus_per_cell()).max(1)
    }

    /// Reads, checks and expands the plan at `path`. Refuses unknown keys, empty axes, unknown
    /// algorithms, missing files and configs their algorithm rejects, naming the plan line.
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_with(path, true)
    }

    /// As [`Sweep::load`], but demo and context files need not exist yet (plans whose data is
    /// recorded by a documented command, not shipped): checks everything else.
    pub fn load_unchecked(path: &Path) -> Result<Self> {
        Self::load_with(path, false)
    }

    fn load_with(path: &Path, require_data: bool) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
            path: path.to_path_buf(),
            source: e,
        })?;
        let plan: Plan = toml::from_str(&text)
            .map_err(|e| Error::Config(format!("plan {}: {e}", path.display())))?;
        let at = PlanText {
            path,
            text: &text,
            base: path.parent().unwrap_or(Path::new(".")),
        };
        at.check_axes_and_files(&plan, require_data)?;
        let out = plan.out.clone().unwrap_or_else(|| {
            let stem = path
                .file_stem()
                .map_or("sweep".into(), |s| s.to_string_lossy());
            PathBuf::from("runs").join(stem.as_ref())
        });
        let mut cells = Vec::new();
        for (name, m) in &plan.algo {
            at.expand(&plan, name, m, &mut cells)?;
        }
        at.key_cells(&mut cells)?;
        let family = plan.env;
        let mut plan = plan;
        plan.eval.contexts = at.rel(&plan.eval.contexts);
        plan.eval.base = plan.eval.base.as_deref().map(|p| at.rel(p));
        plan.eval.experts = plan.eval.experts.iter().map(|p| at.rel(p)).collect();
        Ok(Self {
            path: path.to_path_buf(),
            plan,
            family,
            out,
            cells,
        })
    }

    /// The directory of cell `i`.
    pub fn cell_dir(&self, cell: &Cell) -> PathBuf {
        self.out.join(&cell.name)
    }
}

/// A plan file being read: its path and text (errors point at the plan line), and the
/// folder its relative paths start from.
struct PlanText<'a> {
    path: &'a Path,
    text: &'a str,
    base: &'a Path,
}

impl PlanText<'_> {
    /// `p` relative to the plan's folder (absolute paths as they are).
    fn rel(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.base.join(p)
        }
    }

    /// An error naming the plan line that holds `needle`.
    fn err(&self, needle: Option<&str>, msg: String) -> Error {
        plan_err(self.path, self.text, needle, msg)
    }

    /// Refuses empty axes, a base without experts (or the reverse), a base for a family
    /// without a normalised metric, and files that do not exist (demos and contexts only
    /// when `require_data`).
    fn check_axes_and_files(&self, plan: &Plan, require_data: bool) -> Result<()> {
        let family = plan.env;
        for (axis, empty) in [
            ("demos", plan.demos.is_empty()),
            ("seeds", plan.seeds.is_empty()),
            ("algo", plan.algo.is_empty()),
        ] {
            if empty {
                return Err(self.err(Some(axis), format!("the axis `{axis}` is empty")));
            }
        }
        let mut files: Vec<(&str, PathBuf)> =
            plan.demos.iter().map(|d| ("demos", self.rel(d))).collect();
        files.push(("contexts", self.rel(&plan.eval.contexts)));
        if plan.eval.base.is_some() == plan.eval.experts.is_empty() {
            let key = if plan.eval.base.is_some() {
                "base"
            } else {
                "experts"
            };
            return Err(self.err(
                Some(key),
                "[eval] `base` and `experts` go together (the walker-dyn normalised metric)".into(),
            ));
        }
        if plan.eval.base.is_some() && family.nominal_task().is_none() {
            return Err(self.err(
                Some("base"),
                format!(
                    "[eval] `base` is for a normalised metric (walker-dyn's); {family} has none"
                ),
            ));
        }
        for p in plan.eval.base.iter().chain(&plan.eval.experts) {
            files.push(("expert", self.rel(p)));
        }
        for (name, m) in &plan.algo {
            if let Some(c) = &m.config {
                files.push(("config", self.rel(c)));
            }
            if let Some(e) = &m.expert {
                files.push(("expert", self.rel(e)));
            }
            if let Some((k, _)) = m.axes.iter().find(|(_, v)| v.is_empty()) {
                return Err(self.err(Some(k), format!("the axis `{k}` of [algo.{name}] is empty")));
            }
        }
        for (what, f) in &files {
            let data = matches!(*what, "demos" | "contexts");
            if !f.exists() && (require_data || !data) {
                let needle = f.file_name().map(|n| n.to_string_lossy().into_owned());
                return Err(self.err(
                    needle.as_deref(),
                    format!("{what} file {} does not exist", f.display()),
                ));
            }
        }
        Ok(())
    }

    /// The algorithm of `[algo.name]`, with its expert checked: only Meta-DAgger takes one,
    /// and needs one except on point-goal (whose scripted PD controller relabels).
    fn algo_of(&self, family: Family, name: &str, m: &Method) -> Result<(String, Algo)> {
        let algo = m.algo.clone().unwrap_or_else(|| name.to_string());
        let at = format!("[algo.{name}]");
        let kind: Algo = algo.parse().map_err(|e| self.err(Some(&at), message(e)))?;
        if !kind.needs_expert() && m.expert.is_some() {
            return Err(self.err(
                Some(&at),
                format!("{algo} takes no `expert` (only meta-dagger relabels with one)"),
            ));
        }
        if kind.needs_expert() && m.expert.is_none() && family != Family::POINT_GOAL {
            return Err(self.err(Some(&at), format!("meta-dagger on {family} needs `expert`")));
        }
        Ok((algo, kind))
    }

    /// The method's config file (if any) with its `set` keys applied.
    fn method_table(&self, m: &Method) -> Result<toml::Table> {
        let mut table = match &m.config {
            Some(c) => {
                let p = self.rel(c);
                let s = std::fs::read_to_string(&p).map_err(|e| Error::Io {
                    path: p.clone(),
                    source: e,
                })?;
                toml::from_str::<toml::Table>(&s)
                    .map_err(|e| self.err(Some("config"), format!("{}: {e}", p.display())))?
            }
            None => toml::Table::new(),
        };
        for (k, v) in &m.set {
            trainer::set_config_key(&mut table, k, v.clone()).map_err(|e| self.err(Some(k), e))?;
        }
        Ok(table)
    }

    /// Appends the cells of `[algo.name]`: every demo file x axis point x seed, each config
    /// checked by its algorithm.
    fn expand(&self, plan: &Plan, name: &str, m: &Method, cells: &mut Vec<Cell>) -> Result<()> {
        let family = plan.env;
        let (algo, kind) = self.algo_of(family, name, m)?;
        let table = self.method_table(m)?;
        for demos in &plan.demos {
            for point in product(&m.axes) {
                for &seed in &plan.seeds {
                    let mut t = table.clone();
                    for (k, v) in &point {
                        trainer::set_config_key(&mut t, k, v.clone())
                            .map_err(|e| self.err(Some(k), e))?;
                    }
                    t.insert("seed".into(), toml::Value::Integer(seed as i64));
                    t.insert("env".into(), toml::Value::String(family.name().into()));
                    check_config(kind, &t, family).map_err(|e| {
                        let key = point
                            .iter()
                            .map(|(k, _)| k.as_str())
                            .chain(m.set.keys().map(String::as_str));
                        let needle = key.into_iter().find(|k| e.contains(k)).map(str::to_string);
                        self.err(
                            Some(needle.as_deref().unwrap_or(&format!("[algo.{name}]"))),
                            format!("[algo.{name}]: {e}"),
                        )
                    })?;
                    let params: BTreeMap<String, String> =
                        point.iter().map(|(k, v)| (k.clone(), short(v))).collect();
                    let mut cell_name = name.to_string();
                    if plan.demos.len() > 1 {
                        cell_name.push_str(&format!("-{}", stem(demos)));
                    }
                    for (k, v) in &params {
                        cell_name.push_str(&format!("-{k}={v}"));
                    }
                    cell_name.push_str(&format!("-s{seed}"));
                    cells.push(Cell {
                        index: cells.len(),
                        name: cell_name.replace(['/', ' '], "_"),
                        method: name.to_string(),
                        algo: algo.clone(),
                        demos: self.rel(demos),
                        seed,
                        params,
                        config: toml::to_string(&t).map_err(|e| Error::Serialise {
                            what: "cell config",
                            reason: e.to_string(),
                        })?,
                        expert: m.expert.as_ref().map(|e| self.rel(e)),
                        key: String::new(),
                    });
                }
            }
        }
        Ok(())
    }

    /// Keys: one training listed twice is refused; cells whose names collide (the same demo
    /// file name in two folders) get their key's first 8 digits appended.
    fn key_cells(&self, cells: &mut [Cell]) -> Result<()> {
        for c in cells.iter_mut() {
            c.key = c.training_key();
        }
        for (i, c) in cells.iter().enumerate() {
            if let Some(d) = cells[..i].iter().find(|d| d.key == c.key) {
                return Err(self.err(
                    Some("seeds"),
                    format!(
                        "cells {} and {} are the same training ({}, seed {}, demos {}): a \
                         repeated seed or demo file would be counted as two seeds",
                        d.index,
                        c.index,
                        c.method,
                        c.seed,
                        c.demos.display()
                    ),
                ));
            }
        }
        let names: Vec<String> = cells.iter().map(|c| c.name.clone()).collect();
        for c in cells.iter_mut() {
            if names.iter().filter(|n| **n == c.name).count() > 1 {
                c.name = format!("{}-{}", c.name, &c.key[..8]);
            }
        }
        Ok(())
    }
}

fn stem(p: &Path) -> String {
    p.file_stem()
        .map_or("demos".into(), |s| s.to_string_lossy().into_owned())
}

fn message(e: Error) -> String {
    match e {
        Error::Config(m) => m,
        other => other.to_string(),
    }
}

/// Deserialises `t` into the algorithm's config type and validates it.
fn check_config(algo: Algo, t: &toml::Table, family: Family) -> std::result::Result<(), String> {
    let s = toml::to_string(t).map_err(|e| e.to_string())?;
    algo.check_config(&s, family).map_err(message)
}
