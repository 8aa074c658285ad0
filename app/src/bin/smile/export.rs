//! `smile export`: a meta-policy as an infer-core blob, verified against the float policy, or
//! (`--format onnx`) as two ONNX graphs with a description and a parity reference.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use sim::{DemoDataset, Split};
use trainer::eval::Protocol;
use trainer::export;
use trainer::{Input, MetaPolicy};

/// Arguments of `smile export`.
#[derive(Args, Debug)]
pub struct ExportArgs {
    /// Trained run directory (or meta_policy.safetensors).
    #[arg(long)]
    policy: PathBuf,
    /// What to write: an infer-core blob, or ONNX graphs (encoder.onnx, policy.onnx, onnx.json
    /// and reference.safetensors in the directory -o).
    #[arg(long, value_enum, default_value_t = Format::Blob)]
    format: Format,
    /// Quantization: f32, w8a32 or w8a8 (blob only; ONNX is float32) [default: w8a8].
    #[arg(long)]
    quant: Option<String>,
    /// Output blob file, with a JSON report next to it (`<blob>.json`); with --format onnx, the
    /// output directory.
    #[arg(short, long)]
    out: PathBuf,
    /// What calibrates w8a8's activation scales: `demos` (the --demos states and contexts) or
    /// `closed-loop` (those plus the states the float policy itself visits on the --demos
    /// tasks, one episode each: ranges it meets off the demos are not clipped).
    #[arg(long, value_enum, default_value_t = Calibrate::Demos)]
    calibrate: Calibrate,
    /// w8a8: cap each layer's activation range at this quantile of |input| on the
    /// calibration, 0.5 to 1 (1: the largest value seen; below 1 trades the rarest values,
    /// clipped, for a finer step on all the others).
    #[arg(long, default_value_t = 1.0, value_parser = quantile)]
    range_quantile: f32,
    /// The precision of the first and last layer of each MLP (encoder, z head, policy): raw
    /// observations, actions and latents go in there and the action mean comes out, where
    /// int8 activations cost most. `f32`, `w8a32` or the blob's own quantization (every layer
    /// alike) [default: w8a32 for a w8a8 blob, the same flash; otherwise the blob's own].
    #[arg(long)]
    edges: Option<String>,
    /// The precision of every layer of the context encoder and z head, which run once per
    /// teaching and not per control tick: `f32`, `w8a32` or the blob's own (as the policy,
    /// with its edges) [default: w8a32 for a w8a8 blob, the same flash; otherwise the blob's
    /// own].
    #[arg(long)]
    context_quant: Option<String>,
    /// Fine-tune the actor through its int8 rounding for this many Adam steps before writing
    /// an int8 blob (quantization-aware, straight-through; on the --demos states and one
    /// closed-loop episode per meta-train task, so it needs --demos). The blob's float metric
    /// and parity stay those of the policy as trained.
    #[arg(long, value_parser = crate::positive)]
    qat_steps: Option<usize>,
    /// Meta-train demos: calibration inputs, required for w8a8 (unused by f32 and w8a32).
    #[arg(long)]
    demos: Option<PathBuf>,
    /// Held-out contexts (e.g. the meta-test demos) for the parity check and the metric.
    #[arg(long)]
    contexts: PathBuf,
    /// Override the protocol's rollouts per context draw in the metric check (at least 1).
    #[arg(long, value_parser = crate::positive)]
    rollouts: Option<usize>,
    /// Episode length override (at least 1).
    #[arg(long, value_parser = crate::horizon)]
    horizon: Option<usize>,
    /// Export a policy whose training did not finish, with a warning, instead of refusing it.
    #[arg(long)]
    allow_unfinished: bool,
}

/// The export formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Format {
    /// The infer-core blob (quantized or f32), verified on the held-out contexts.
    Blob,
    /// ONNX opset 17: the context encoder and the conditioned policy, normalisation inside.
    Onnx,
}

/// Reads the demo file given as `input` and checks that it fits the policy (one-line errors).
fn read_demos(path: &Path, input: Input, mp: &MetaPolicy) -> Result<DemoDataset> {
    let demos = trainer::read_demos(path, input)?;
    export::check_demos_fit(mp, &demos, &format!("{} {}", input.noun(), path.display()))?;
    Ok(demos)
}

/// `--range-quantile`: a number from 0.5 to 1.
fn quantile(text: &str) -> std::result::Result<f32, String> {
    match text.parse::<f32>() {
        Ok(q) if (0.5..=1.0).contains(&q) => Ok(q),
        Ok(q) => Err(format!("{q}: expected a quantile from 0.5 to 1")),
        Err(e) => Err(format!("`{text}` is not a number: {e}")),
    }
}

/// `--calibrate`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Calibrate {
    /// The demos' states and contexts.
    Demos,
    /// The demos and the float policy's own closed loop on their tasks.
    ClosedLoop,
}

/// `--format onnx`: the graphs, their description and the trainer's z and actions on the
/// contexts, written to the directory `a.out` in one rename.
fn run_onnx(a: &ExportArgs, mp: &MetaPolicy) -> Result<()> {
    if let Some(q) = a.quant.as_deref().filter(|q| *q != "f32") {
        bail!(
            "--quant {q} quantizes a blob; the ONNX graphs are float32 (drop --quant, or \
             --format blob for a {q} blob)"
        );
    }
    if let Some(e) = &a.edges {
        bail!(
            "--edges {e} sets a blob's layer precision; the ONNX graphs are float32 (drop --edges)"
        );
    }
    if let Some(path) = &a.demos {
        read_demos(path, Input::Demos, mp)?;
    }
    let ctx = read_demos(&a.contexts, Input::Contexts, mp)?;
    let ex = trainer::onnx::export(mp)?;
    let reference = trainer::onnx::reference(mp, &ctx)?;
    let source = a.contexts.display().to_string();
    let files = trainer::onnx::write_dir(&a.out, &ex, Some((&reference, &source)))?;
    eprintln!(
        "wrote {} (ONNX opset {}, {} {}: encoder {} bytes, policy {} bytes; trainer z and \
         actions on {} contexts for the parity check)",
        a.out.display(),
        trainer::onnx::OPSET,
        mp.algo,
        mp.family,
        ex.encoder.len(),
        ex.policy.len(),
        reference.contexts.len()
    );
    for f in files {
        eprintln!("  {}", f.display());
    }
    eprintln!(
        "check with onnxruntime: python3 docs/scripts/onnx_parity.py {}",
        a.out.display()
    );
    Ok(())
}

/// Run `smile export`.
pub fn run(a: ExportArgs) -> Result<()> {
    let mp =
        MetaPolicy::load(&a.policy).with_context(|| format!("loading {}", a.policy.display()))?;
    if let Some(warning) = MetaPolicy::ensure_finished(&a.policy, a.allow_unfinished)? {
        eprintln!("{warning}");
    }
    if a.format == Format::Onnx {
        return run_onnx(&a, &mp);
    }
    let quant_name = a.quant.as_deref().unwrap_or("w8a8");
    let quant = export::parse_quant(quant_name)?;
    let family = mp.family;
    let demos = calibration_demos(&a, &mp, quant)?;
    let ctx = read_demos(&a.contexts, Input::Contexts, &mp)?;
    let closed_loop = (a.calibrate == Calibrate::ClosedLoop).then(|| {
        let env = sim::EnvConfig {
            horizon: a.horizon,
            physics: mp.physics,
            ..sim::EnvConfig::default()
        };
        (env, 1)
    });
    let edges = match a.edges.as_deref() {
        Some(e) => Some(export::parse_quant(e)?),
        None => export::default_edges(quant),
    };
    let options = infer_core::WriteOptions {
        range_quantile: a.range_quantile,
        edges,
        context: match a.context_quant.as_deref() {
            Some(c) => Some(export::parse_quant(c)?),
            None => export::default_context(quant),
        },
    };
    let tuned = match (a.qat_steps, &demos) {
        (None, _) => None,
        (Some(_), _) if quant == infer_core::Quant::F32 => {
            bail!("--qat-steps fine-tunes for an int8 blob; --quant f32 has no rounding to learn")
        }
        (Some(_), None) => bail!("--qat-steps needs --demos (meta-train demos: its states)"),
        (Some(steps), Some(demos)) => Some(fine_tune(&mp, demos, steps, a.horizon)?),
    };
    let blob = export::export_blob_with(
        tuned.as_ref().unwrap_or(&mp),
        quant,
        demos.as_ref(),
        closed_loop,
        &options,
    )?;
    if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let mut protocol = Protocol::for_family(family);
    if let Some(r) = a.rollouts {
        protocol.rollouts = r;
    }
    protocol.horizon = a.horizon;
    protocol.physics = mp.physics;
    let mut report = export::verify(&mp, &blob, quant_name, &ctx, &protocol)?;
    report.qat_steps = a.qat_steps;
    let p = &report.parity;
    eprintln!(
        "parity on {} held-out contexts, {} actions: action max |diff| {:.3e}, mean {:.3e}; z max |diff| {:.3e}; mean with the float z {:.3e}",
        p.contexts,
        p.actions,
        p.action_max_abs_diff,
        p.action_mean_abs_diff,
        p.z_max_abs_diff,
        p.action_mean_abs_diff_same_z
    );
    eprintln!(
        "{} on {} {} tasks: blob {:.4}, candle {:.4} (relative difference {:+.2}%)",
        report.metric,
        family,
        report.split,
        report.metric_blob,
        report.metric_candle,
        100.0 * report.metric_relative_difference
    );
    // `<blob>.json`, where firmware-sim looks (one definition: a blob named without an
    // extension once got its report at `<blob>.blob.json`, which the device never found).
    let json = export::ExportReport::path_beside(&a.out);
    land_blob_and_report(&a.out, &blob, &json, &report)?;
    let mut edges = report
        .edges
        .as_deref()
        .map_or(String::new(), |e| format!(", first and last layers {e}"));
    if let Some(c) = &report.context {
        edges.push_str(&format!(", context encoder {c}"));
    }
    eprintln!(
        "wrote {} ({} bytes, {quant_name}{edges}) and {}",
        a.out.display(),
        blob.len(),
        json.display()
    );
    Ok(())
}

/// `--demos` for a blob: meta-train demos, required by w8a8.
fn calibration_demos(
    a: &ExportArgs,
    mp: &MetaPolicy,
    quant: infer_core::Quant,
) -> Result<Option<DemoDataset>> {
    Ok(match &a.demos {
        Some(path) => {
            let demos = read_demos(path, Input::Demos, mp)?;
            if demos.split != Split::Train {
                bail!(
                    "--demos must be meta-train demos (calibration); {} is {}",
                    path.display(),
                    demos.split
                );
            }
            Some(demos)
        }
        None if quant == infer_core::Quant::W8A8 => bail!(
            "--quant w8a8 needs --demos (meta-train demos of {}) to calibrate its activation scales",
            mp.family
        ),
        None => None,
    })
}

/// `--qat-steps`: the policy fine-tuned through its int8 rounding, with what it bought.
fn fine_tune(
    mp: &MetaPolicy,
    demos: &DemoDataset,
    steps: usize,
    horizon: Option<usize>,
) -> Result<MetaPolicy> {
    let env = sim::EnvConfig {
        horizon,
        physics: mp.physics,
        ..sim::EnvConfig::default()
    };
    let (tuned, r) = export::quantization_aware(mp, demos, &export::QatConfig::new(steps, env))?;
    eprintln!(
        "quantization-aware fine-tune, {} Adam steps on {} states: int8 actor's mean |action \
         - float action| {:.3e} -> {:.3e}",
        r.steps, r.states, r.action_mean_abs_diff_before, r.action_mean_abs_diff_after
    );
    Ok(tuned)
}

/// Replaces a previous export by the verified `blob` and its `report`, so that no instant
/// loses the old pair without the new one in place: the report is staged first (a full disk
/// fails here, the old blob and report untouched), then the blob lands, then the report. A
/// kill between the last two leaves the new blob beside the old report, whose SHA-256 names
/// the old blob: firmware-sim refuses that pair and says to export again.
fn land_blob_and_report(
    out: &Path,
    blob: &[u8],
    json: &Path,
    report: &export::ExportReport,
) -> Result<()> {
    let mut staged = json.as_os_str().to_owned();
    staged.push(".staged");
    let staged = std::path::PathBuf::from(staged);
    report.write(&staged)?;
    if let Err(e) = trainer::checkpoint::write_atomic(out, blob) {
        let _ = std::fs::remove_file(&staged);
        return Err(e.into());
    }
    std::fs::rename(&staged, json)
        .with_context(|| format!("moving {} to {}", staged.display(), json.display()))
}
