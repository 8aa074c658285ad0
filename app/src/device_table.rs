//! The deployment table (`smile device-table`, issue 59): a shipped meta-policy measured from
//! float on the host, through its f32 / w8a32 / w8a8 blobs on the host, to the w8a8 blob in
//! firmware-sim's fixed-rate loop, taught one test demo over the link, under the effects a
//! device has: ideal full sensing, sensor noise with a 12-bit ADC, position-only sensing with
//! the on-board estimator, and a lossy link.
//!
//! Every column is the family's metric on the meta-test tasks, one-demo contexts: draw `d`
//! teaches the demo [`trainer::eval::context_draw`] picks, rollout `r` starts from reset seed
//! [`trainer::eval::episode_seed`]`(d, r)`, on the host and on the device alike, so the ideal
//! device column checks the loop against the host's evaluation of the same blob. A policy is
//! a directory with `meta_policy.safetensors` and its [`DeployManifest`] (`deploy.toml`).

use std::path::{Path, PathBuf};

use firmware_sim::link::LinkConfig;
use firmware_sim::{DeviceConfig, LoopConfig, Sensing, SessionConfig, ram_needed, run_session};
use serde::{Deserialize, Serialize};
use sim::{DemoDataset, EnvConfig, Family, Task};
use trainer::eval::{self, Protocol};
use trainer::export::{self, BlobActor};
use trainer::{Error, MetaPolicy, Result};

/// File naming what a shipped policy was trained and is measured on.
pub const MANIFEST_FILE: &str = "deploy.toml";

/// `deploy.toml` beside a shipped `meta_policy.safetensors`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeployManifest {
    /// The method as the results tables name it ("SMILe + BC", "Meta-BC").
    pub method: String,
    /// Meta-train demos (w8a8 calibration), relative to the manifest.
    pub demos: PathBuf,
    /// Meta-test demos: the one-demo contexts, relative to the manifest.
    pub contexts: PathBuf,
    /// Episode length (the family's when absent).
    #[serde(default)]
    pub horizon: Option<usize>,
    /// Adam steps of a quantization-aware fine-tune before the int8 blobs are written
    /// (`smile export --qat-steps`; none: the trained weights quantized as they are). The float
    /// column and the f32 blob stay the policy as trained.
    #[serde(default)]
    pub qat_steps: Option<usize>,
    /// The full scale of the sensor column's 12-bit ADC, +-this (firmware-sim's `--adc-range`;
    /// default 10). A real converter is scaled to its channel's signal: the cheetah's joint
    /// velocities reach 20-27 rad/s on Rapier, and clipped at +-10 cost its SMILe + BC +23% of
    /// the +27% the sensor column lost (docs/DEVICE.md, "which entries").
    #[serde(default)]
    pub adc_range: Option<f32>,
}

impl DeployManifest {
    /// Reads `dir/deploy.toml`; errors name the file.
    pub fn read(dir: &Path) -> Result<Self> {
        let path = dir.join(MANIFEST_FILE);
        let text = std::fs::read_to_string(&path).map_err(|e| Error::Io {
            path: path.clone(),
            source: e,
        })?;
        let manifest: Self = toml::from_str(&text)
            .map_err(|e| Error::Config(format!("{}: {}", path.display(), e.message())))?;
        if let Some(range) = manifest.adc_range
            && !(range.is_finite() && range > 0.0)
        {
            return Err(Error::Config(format!(
                "{}: adc_range = {range}: expected a finite full scale > 0",
                path.display()
            )));
        }
        Ok(manifest)
    }

    /// The sensor column's ADC full scale.
    pub fn adc_range(&self) -> f32 {
        self.adc_range
            .unwrap_or(firmware_sim::LoopConfig::default().adc_range)
    }
}

/// How much to measure, and on which tasks.
#[derive(Debug, Clone, PartialEq)]
pub struct TableConfig {
    /// Context draws per task (demo `d` of the task teaches draw `d`).
    pub draws: usize,
    /// Rollouts per draw.
    pub rollouts: usize,
    /// Demos of new tasks (`smile demos --task-params`): measure on the tasks this file holds,
    /// its demos the contexts, instead of the test split with the manifest's contexts. A
    /// family's test split is small (16-32 tasks); where int8 moves single tasks apart, only
    /// more tasks narrow the standard error.
    pub new_tasks: Option<PathBuf>,
}

impl Default for TableConfig {
    fn default() -> Self {
        Self {
            draws: 3,
            rollouts: 1,
            new_tasks: None,
        }
    }
}

/// One measured column: the metric, and its degradation against float (positive: worse).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Cell {
    /// Mean over the test tasks.
    pub metric: f32,
    /// `(worse - float) / |float|` in percent, the sign making a loss positive whichever way
    /// the metric points.
    pub degradation_pct: f32,
    /// The standard error of `degradation_pct`, paired by task: the sample standard deviation
    /// of the per-task differences against float, over the square root of the task count, in
    /// percent of |float| (NaN with one task). Every column runs the same episodes as float,
    /// so this is what says whether a table's episodes can resolve a 1% bar at all.
    pub stderr_pct: f32,
}

/// A device column: the cell and the loop's per-tick compute.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DeviceCell {
    /// Metric and degradation.
    pub cell: Cell,
    /// Per-tick compute of `act`, median and p99, microseconds (host time).
    pub tick_us: (f64, f64),
    /// Frames resent on the link (flash and teach) over all episodes.
    pub link_retries: u64,
}

/// One row of the table: one shipped policy.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Row {
    /// The policy directory.
    pub policy: PathBuf,
    /// Family.
    pub family: Family,
    /// Plant.
    pub physics: sim::Physics,
    /// Method.
    pub method: String,
    /// Adam steps of the quantization-aware fine-tune behind the int8 blobs, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub qat_steps: Option<usize>,
    /// The sensor column's ADC full scale (+-, volts-free units of the observation).
    pub adc_range: f32,
    /// Metric name.
    pub metric: String,
    /// Tasks measured: the test split's, or those of `new_tasks`.
    pub tasks: usize,
    /// The demo file of new tasks measured instead of the test split, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub new_tasks: Option<PathBuf>,
    /// Episodes per task per column (draws x rollouts).
    pub episodes_per_task: usize,
    /// Float policy on the host.
    pub float: f32,
    /// The blobs of [`BLOB_COLUMNS`] on the host.
    pub blobs: [Cell; 4],
    /// The deployed blob's bytes (w8a8 with w8a32 edges and context encoder; the others in `blob_bytes_all`).
    pub blob_bytes: usize,
    /// Bytes of the blobs of [`BLOB_COLUMNS`].
    pub blob_bytes_all: [usize; 4],
    /// The device's RAM for the application.
    pub ram_bytes: usize,
    /// Whether the w8a8 blob and its runners fit 64 KiB of flash and 16 KiB of RAM.
    pub fits: bool,
    /// w8a8 on the device: ideal full sensing, noise 0.01 + 12-bit ADC, position-only
    /// sensing with the estimator, 5% of frames corrupted or dropped; `None` when the blob
    /// does not fit the device (`does_not_fit` says why).
    pub device: Option<[DeviceCell; 4]>,
    /// Why the w8a8 blob cannot run on the 64 KiB / 16 KiB device, and by how much.
    pub does_not_fit: Option<String>,
}

/// The blobs measured on the host, in the table's order; the last is the one deployed.
pub const BLOB_COLUMNS: [&str; 4] = [
    "f32",
    "w8a32",
    "w8a8 (int8 throughout)",
    "w8a8, w8a32 edges and context",
];

/// The device conditions, in the table's order.
pub const DEVICE_COLUMNS: [&str; 4] = [
    "ideal",
    "noise 0.01 + 12-bit ADC",
    "positions + estimator",
    "lossy link (5%)",
];

/// How much worse `x` is than `float`, in the metric's units (positive: worse).
fn worse(family: Family, float: f64, x: f64) -> f64 {
    match family.metric_kind().lower_is_better() {
        true => x - float,
        false => float - x,
    }
}

/// The column whose per-task metrics are `tasks` against float's `float_tasks` (the same tasks,
/// in the same order, on the same episodes). The means are [`eval::mean_std`]'s, so a column
/// reads as the host's evaluation of the same episodes does, to the last bit.
fn cell(family: Family, float_tasks: &[f32], tasks: &[f32]) -> Cell {
    assert_eq!(float_tasks.len(), tasks.len(), "columns over other tasks");
    let float = eval::mean_std(float_tasks).0;
    let metric = eval::mean_std(tasks).0;
    let scale = 100.0 / (float.abs() as f64).max(1e-9);
    let diffs: Vec<f64> = float_tasks
        .iter()
        .zip(tasks)
        .map(|(&f, &x)| worse(family, f as f64, x as f64))
        .collect();
    let n = diffs.len() as f64;
    let mean = diffs.iter().sum::<f64>() / n;
    // Sample variance (n - 1): the tasks are a sample of the family's.
    let var = diffs.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / (n - 1.0);
    Cell {
        metric,
        degradation_pct: (scale * worse(family, float as f64, metric as f64)) as f32,
        stderr_pct: match diffs.len() {
            0 | 1 => f32::NAN,
            _ => (scale * (var / n).sqrt()) as f32,
        },
    }
}

/// Reads the demo file given as `input` in the manifest (relative to its directory).
fn demos_at(dir: &Path, file: &Path, input: trainer::Input) -> Result<DemoDataset> {
    let path = dir.join(file);
    trainer::read_demos(&path, input).map_err(|e| {
        Error::Data(format!(
            "{e} (named in {})",
            dir.join(MANIFEST_FILE).display()
        ))
    })
}

/// The tasks a row measures and the demos that teach them: the family's test split with the
/// manifest's contexts, or every task of `config.new_tasks`, which must be of the policy's
/// family (checked here) and plant (checked where the tasks are evaluated) and hold at least
/// one task.
fn tasks_measured(
    dir: &Path,
    manifest: &DeployManifest,
    config: &TableConfig,
    family: Family,
) -> Result<(DemoDataset, Vec<Task>)> {
    let Some(path) = &config.new_tasks else {
        let test = demos_at(dir, &manifest.contexts, trainer::Input::Contexts)?;
        return Ok((test, family.test_tasks()));
    };
    // As `demos_at`: a data error naming the file, where an input error would point the
    // user at a flag this table does not have.
    let demos = trainer::read_demos_of(path, trainer::Input::Contexts, family)
        .map_err(|e| Error::Data(format!("{e} (the demos of the new tasks to measure on)")))?;
    if demos.tasks.is_empty() {
        return Err(Error::Data(format!(
            "the new tasks' demos {} hold no task",
            path.display()
        )));
    }
    // Tasks the policy was meta-trained on are not new: measured there, a row would report
    // its training fit as generalisation.
    let trained = family.train_tasks();
    if let Some(t) = demos.tasks.iter().find(|t| trained.contains(&t.task)) {
        return Err(Error::Data(format!(
            "the new tasks' demos {} hold {}, a meta-train task of {family}: new tasks must be \
             ones the policy never trained on (`smile demos --task-params`)",
            path.display(),
            t.task.label()
        )));
    }
    let tasks = demos.tasks.iter().map(|t| t.task).collect();
    Ok((demos, tasks))
}

/// `mp` fine-tuned through its int8 rounding when the manifest asks (`qat_steps`).
fn fine_tuned(
    mp: &MetaPolicy,
    train: &DemoDataset,
    manifest: &DeployManifest,
    on: &mut dyn FnMut(String),
) -> Result<Option<MetaPolicy>> {
    let Some(steps) = manifest.qat_steps else {
        return Ok(None);
    };
    let env = sim::EnvConfig {
        horizon: manifest.horizon,
        physics: mp.physics,
        ..sim::EnvConfig::default()
    };
    let (tuned, r) = export::quantization_aware(mp, train, &export::QatConfig::new(steps, env))?;
    on(format!(
        "  quantization-aware fine-tune ({steps} steps): int8 actor's mean |action - float| \
         {:.3e} -> {:.3e}",
        r.action_mean_abs_diff_before, r.action_mean_abs_diff_after
    ));
    Ok(Some(tuned))
}

/// Measures the shipped policy in `dir`.
pub fn measure(dir: &Path, config: &TableConfig, on: &mut dyn FnMut(String)) -> Result<Row> {
    let manifest = DeployManifest::read(dir)?;
    let mut mp = MetaPolicy::load(dir)?;
    MetaPolicy::ensure_finished(dir, false)?;
    let shipped = shipped_blob(dir, &mp)?;
    let family = mp.family;
    let train = demos_at(dir, &manifest.demos, trainer::Input::Demos)?;
    if train.split != sim::Split::Train {
        // As `smile export --demos` refuses: int8 scales calibrated on the tasks the table
        // then measures would fit the test.
        return Err(Error::Data(format!(
            "{} names {} as the calibration demos (`demos`), but they hold {} demos: give the \
             policy's meta-train demos",
            dir.join(MANIFEST_FILE).display(),
            manifest.demos.display(),
            train.split
        )));
    }
    let (test, tasks) = tasks_measured(dir, &manifest, config, family)?;
    let mut protocol = Protocol::for_family(family);
    protocol.context_sizes = vec![1];
    protocol.draws = config.draws;
    protocol.rollouts = config.rollouts;
    protocol.horizon = manifest.horizon;
    protocol.physics = mp.physics;
    // Per-task metrics, in the order of `tasks`.
    let host = |actor: &mut dyn eval::ConditionedActor, name: &str| {
        eval::evaluate_tasks(
            actor,
            name,
            family,
            &tasks,
            &test,
            &protocol,
            &mut |_, _| {},
        )
        .map(|r| r.tasks.iter().map(|t| t.metric).collect::<Vec<f32>>())
    };
    let float_tasks = host(&mut mp, "float")?;
    let float = eval::mean_std(&float_tasks).0;
    on(format!("{}: float {float:.4}", dir.display()));
    let tuned = fine_tuned(&mp, &train, &manifest, on)?;
    let blobs = blob_columns(
        (&mp, tuned.as_ref()),
        &shipped,
        &train,
        &mut |actor| Ok(cell(family, &float_tasks, &host(actor, "blob")?)),
        on,
    )?;
    let w8a8 = &blobs[3].0;
    let does_not_fit = misfit(w8a8)?;
    let device = match &does_not_fit {
        Some(why) => {
            on(format!("  device: {why}"));
            None
        }
        None => {
            let cells = DEVICE_COLUMNS
                .iter()
                .enumerate()
                .map(|(c, name)| {
                    let d = device_column(
                        w8a8,
                        c,
                        (&tasks, &test),
                        &protocol,
                        family,
                        &float_tasks,
                        manifest.adc_range(),
                    )?;
                    on(format!("  device, {name}: {:.4}", d.cell.metric));
                    Ok(d)
                })
                .collect::<Result<Vec<_>>>()?;
            Some([cells[0], cells[1], cells[2], cells[3]])
        }
    };
    let ram = ram_needed();
    Ok(Row {
        policy: dir.to_path_buf(),
        family,
        physics: mp.physics,
        adc_range: manifest.adc_range(),
        method: manifest.method,
        qat_steps: manifest.qat_steps,
        metric: eval::metric_name(family.metric_kind()).into(),
        tasks: tasks.len(),
        new_tasks: config.new_tasks.clone(),
        episodes_per_task: config.draws * config.rollouts,
        float,
        blobs: [blobs[0].1, blobs[1].1, blobs[2].1, blobs[3].1],
        blob_bytes: blobs[3].0.len(),
        blob_bytes_all: [0, 1, 2, 3].map(|i| blobs[i].0.len()),
        ram_bytes: ram,
        fits: does_not_fit.is_none(),
        device,
        does_not_fit,
    })
}

/// The shipped blob beside a shipped policy (`dir/policy.blob`), the one the table's deployed
/// column measures: read, checked against the folder's `SHA256SUMS`, loaded, and of the
/// policy's shape; refused otherwise, naming the file.
fn shipped_blob(dir: &Path, mp: &MetaPolicy) -> Result<Vec<u8>> {
    let path = dir.join(BLOB_FILE);
    let blob = std::fs::read(&path).map_err(|e| {
        Error::Usage(format!(
            "{}: {e}; a shipped policy's table measures its shipped blob (make it with `smile \
             export --policy {} --quant w8a8 --demos <meta-train demos> -o {}`)",
            path.display(),
            dir.display(),
            path.display()
        ))
    })?;
    sim::check_shipped_bytes(&path, &blob)?;
    let bad = |why: String| Error::Usage(format!("{}: {why}", path.display()));
    let h = *export::load_blob(&blob)
        .map_err(|e| bad(e.to_string()))?
        .header();
    let family = mp.family;
    if (h.obs_dim as usize, h.act_dim as usize) != (family.obs_dim(), family.act_dim()) {
        return Err(bad(format!(
            "a blob of observation {} and action {} values, not of this {family} policy ({} \
             and {})",
            h.obs_dim,
            h.act_dim,
            family.obs_dim(),
            family.act_dim()
        )));
    }
    Ok(blob)
}

/// The shipped blob's file name in a shipped policy's folder.
const BLOB_FILE: &str = "policy.blob";

/// The blobs of [`BLOB_COLUMNS`], each with its column as `score` measures it; the int8 ones
/// from `tuned` when the manifest fine-tunes, the f32 blob always from `mp` as trained, and
/// the deployed one the `shipped` blob (a fresh export that differs from it is said).
fn blob_columns(
    (mp, tuned): (&MetaPolicy, Option<&MetaPolicy>),
    shipped: &[u8],
    train: &DemoDataset,
    score: &mut dyn FnMut(&mut dyn eval::ConditionedActor) -> Result<Cell>,
    on: &mut dyn FnMut(String),
) -> Result<Vec<(Vec<u8>, Cell)>> {
    // The deployed blob is the last: w8a8 with its first and last layers, and its context
    // encoder, in w8a32 (`smile export`'s defaults).
    use infer_core::Quant::{F32, W8A8, W8A32};
    let variants = [(F32, F32), (W8A32, W8A32), (W8A8, W8A8), (W8A8, W8A32)];
    let mut blobs = Vec::new();
    for (i, (quant, edges)) in variants.into_iter().enumerate() {
        let options = infer_core::WriteOptions {
            edges: Some(edges),
            context: (edges != quant).then_some(edges),
            ..Default::default()
        };
        let source = match (quant, tuned) {
            (W8A32 | W8A8, Some(tuned)) => tuned,
            _ => mp,
        };
        let mut blob = export::export_blob_with(source, quant, Some(train), None, &options)?;
        if i == BLOB_COLUMNS.len() - 1 {
            if blob != shipped {
                on(format!(
                    "  note: the shipped {BLOB_FILE} ({} B) is not a fresh export of the policy \
                     ({} B, this build's exporter); the table measures the shipped one",
                    shipped.len(),
                    blob.len()
                ));
            }
            blob = shipped.to_vec();
        }
        let column = score(&mut BlobActor::new(&export::load_blob(&blob)?)?)?;
        on(format!(
            "  {} blob ({} B): {:.4} ({:+.1}% +- {:.1})",
            BLOB_COLUMNS[i],
            blob.len(),
            column.metric,
            column.degradation_pct,
            column.stderr_pct
        ));
        blobs.push((blob, column));
    }
    Ok(blobs)
}

/// Why `blob` cannot run on the default device (64 KiB flash, 16 KiB RAM, layers at most
/// [`firmware_sim::CAPACITY`] wide), with the numbers; `None` when it fits.
fn misfit(blob: &[u8]) -> Result<Option<String>> {
    let config = DeviceConfig::default();
    let model = export::load_blob(blob)?;
    let mut why = Vec::new();
    if blob.len() > config.flash_bytes {
        why.push(format!(
            "{} B of flash, {} over the {} B",
            blob.len(),
            blob.len() - config.flash_bytes,
            config.flash_bytes
        ));
    }
    if model.max_width() > firmware_sim::CAPACITY {
        why.push(format!(
            "layers {} wide, the firmware's runners {} (a 2 x {} policy would fit)",
            model.max_width(),
            firmware_sim::CAPACITY,
            firmware_sim::CAPACITY
        ));
    }
    if why.is_empty()
        && let Err(e) = firmware_sim::check_fits(&model, config)
    {
        why.push(e.to_string());
    }
    Ok((!why.is_empty()).then(|| format!("does not fit: {}", why.join("; "))))
}

/// The session settings of device column `column` for episode seed `seed`.
fn session(column: usize, seed: u64, plant: EnvConfig, adc_range: f32) -> SessionConfig {
    let mut control = LoopConfig {
        seed,
        // A generous budget: the host is not the device; overruns are not the question here.
        budget_us: 1e6,
        ..LoopConfig::default()
    };
    let mut link = LinkConfig {
        seed,
        ..LinkConfig::default()
    };
    match column {
        1 => {
            control.noise_std = 0.01;
            control.adc_bits = Some(12);
            control.adc_range = adc_range;
        }
        2 => control.sensing = Sensing::POSITIONS,
        3 => {
            link.corrupt_probability = 0.025;
            link.drop_probability = 0.025;
            link.max_retries = 20;
        }
        _ => {}
    }
    SessionConfig {
        device: DeviceConfig::default(),
        link,
        control,
        plant,
    }
}

/// The w8a8 blob on the device under condition `column`, over every task of `measured` (the
/// tasks and their contexts), draw and rollout of `protocol`.
fn device_column(
    blob: &[u8],
    column: usize,
    measured: (&[Task], &DemoDataset),
    protocol: &Protocol,
    family: Family,
    float_tasks: &[f32],
    adc_range: f32,
) -> Result<DeviceCell> {
    let (tasks, test) = measured;
    let contexts = eval::contexts_for(test, family, tasks)?;
    let plant = EnvConfig {
        horizon: protocol.horizon,
        physics: protocol.physics,
        ..EnvConfig::default()
    };
    let (mut per_task, mut ticks, mut retries) = (Vec::new(), Vec::new(), 0);
    for (i, (task, demos)) in tasks.iter().zip(&contexts).enumerate() {
        let trajs: Vec<&sim::Trajectory> = demos
            .trajectories
            .iter()
            .filter(|t| !t.is_empty())
            .collect();
        let mut metrics = Vec::new();
        for d in 0..protocol.draws {
            // The host evaluation's draw: the same demo teaches the device.
            let context = eval::context_draw(&trajs, i, 1, d);
            for r in 0..protocol.rollouts {
                let config = session(column, eval::episode_seed(d, r), plant, adc_range);
                let s = run_session(blob, task, &context, &config)
                    .map_err(|e| Error::Device(e.to_string()))?;
                metrics.push(s.report.metric);
                ticks.extend(s.report.compute_ns.iter().map(|&n| n as f64 / 1e3));
                retries += s.link.retries;
            }
        }
        // Averaged as the host's evaluation averages, so that the same episodes give the
        // same number to the last bit.
        per_task.push(eval::mean_std(&metrics).0);
    }
    ticks.sort_by(f64::total_cmp);
    let at = |q: f64| ticks[((ticks.len() - 1) as f64 * q).round() as usize];
    Ok(DeviceCell {
        cell: cell(family, float_tasks, &per_task),
        tick_us: (at(0.5), at(0.99)),
        link_retries: retries,
    })
}

/// The row's method, with what its deployment changes from the defaults.
fn method_label(r: &Row) -> String {
    let mut label = r.method.clone();
    if let Some(n) = r.qat_steps {
        label.push_str(&format!(" (int8 fine-tuned {n} steps)"));
    }
    if r.adc_range != firmware_sim::LoopConfig::default().adc_range {
        label.push_str(&format!(" [ADC +-{}]", r.adc_range));
    }
    label
}

/// The table in markdown: one row per policy.
pub fn markdown(rows: &[Row]) -> String {
    let mut md = String::from(
        "| family, plant | method | metric | float | f32 blob (% worse than float +- its paired s.e.) | w8a32 blob | w8a8 blob (int8 \
         throughout) | w8a8 blob, w8a32 edges and context | device: ideal | noise + ADC | positions + \
         estimator | lossy link | blob B | RAM B | fits | tick us (median / p99) | tasks x \
         episodes |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let pct = |c: &Cell| {
        format!(
            "{:.4} ({:+.1}% +- {:.1})",
            c.metric, c.degradation_pct, c.stderr_pct
        )
    };
    for r in rows {
        // A metric's name may hold a pipe (`mean |v - v*|`): escaped, it stays one cell.
        let metric = r.metric.replace('|', "\\|");
        let device: Vec<String> = match &r.device {
            Some(d) => d.iter().map(|c| pct(&c.cell)).collect(),
            None => vec![
                r.does_not_fit.clone().unwrap_or_default(),
                "-".into(),
                "-".into(),
                "-".into(),
            ],
        };
        let tick = r.device.map_or("-".into(), |d| {
            format!("{:.1} / {:.1}", d[0].tick_us.0, d[0].tick_us.1)
        });
        md.push_str(&format!(
            "| {}, {} | {} | {} | {:.4} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} x {} |\n",
            r.family,
            r.physics,
            method_label(r),
            metric,
            r.float,
            pct(&r.blobs[0]),
            pct(&r.blobs[1]),
            pct(&r.blobs[2]),
            pct(&r.blobs[3]),
            device[0],
            device[1],
            device[2],
            device[3],
            r.blob_bytes,
            r.ram_bytes,
            if r.fits { "yes" } else { "no" },
            tick,
            match r.new_tasks {
                Some(_) => format!("{} new", r.tasks),
                None => r.tasks.to_string(),
            },
            r.episodes_per_task,
        ));
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;
    use infer_core::{Calibration, Dims, FloatModel, ModelKind, Quant};

    fn blob(hidden: usize) -> Vec<u8> {
        let dims = Dims {
            obs: 17,
            act: 6,
            r: 32,
            z: 16,
            hidden,
        };
        let model = FloatModel::random(ModelKind::StateAction, dims, 3);
        infer_core::write_blob(&model, Quant::W8A32, &Calibration::default()).unwrap()
    }

    /// A column's degradation is read from the means, with the metric's direction; its
    /// standard error from the per-task differences, so a column that moves every task alike
    /// is resolved however much the tasks differ, and one that moves them apart is not.
    #[test]
    fn a_column_is_paired_with_float_task_by_task() {
        let float = [10.0, 20.0, 30.0, 40.0];
        // A return, higher is better: every task 1 lower is 4% worse, with no spread.
        let c = cell(Family::WALKER_DYN, &float, &[9.0, 19.0, 29.0, 39.0]);
        assert!((c.degradation_pct - 4.0).abs() < 1e-5, "{c:?}");
        assert!(c.stderr_pct.abs() < 1e-6, "{c:?}");
        // The same mean from per-task losses 3, -1, 3, -1: sample variance 16 / 3, s.e.
        // sqrt(16 / 3 / 4), in percent of the float mean 25.
        let c = cell(Family::WALKER_DYN, &float, &[7.0, 21.0, 27.0, 41.0]);
        assert!((c.degradation_pct - 4.0).abs() < 1e-5, "{c:?}");
        let se = (16.0f64 / 3.0 / 4.0).sqrt() / 25.0 * 100.0;
        assert!(
            (c.stderr_pct as f64 - se).abs() < 1e-5,
            "{c:?} against {se}"
        );
        // A distance, lower is better: larger is worse.
        let c = cell(Family::POINT_GOAL, &[0.1, 0.3], &[0.2, 0.4]);
        assert!((c.degradation_pct - 50.0).abs() < 1e-4, "{c:?}");
        // One task has no spread to measure.
        assert!(cell(Family::POINT_GOAL, &[0.1], &[0.2]).stderr_pct.is_nan());
    }

    /// A blob the device can hold is not flagged; one with 256-wide layers is, with the width,
    /// the runners' capacity and the width that would fit; a 256-wide f32 blob also says by
    /// how many bytes it overflows the flash.
    #[test]
    fn a_blob_too_wide_or_too_large_for_the_device_says_by_how_much() {
        assert_eq!(misfit(&blob(64)).unwrap(), None);
        let why = misfit(&blob(256)).unwrap().unwrap();
        assert!(
            why.contains("layers 256 wide") && why.contains("2 x 128 policy would fit"),
            "{why}"
        );
        let dims = Dims {
            obs: 17,
            act: 6,
            r: 32,
            z: 16,
            hidden: 256,
        };
        let model = FloatModel::random(ModelKind::StateAction, dims, 3);
        let f32_blob = infer_core::write_blob(&model, Quant::F32, &Calibration::default()).unwrap();
        let why = misfit(&f32_blob).unwrap().unwrap();
        assert!(
            why.contains("B of flash") && why.contains("over the 65536 B"),
            "{why}"
        );
    }
}
