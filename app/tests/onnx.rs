//! ONNX export parity with a real runtime: tract loads `encoder.onnx` and `policy.onnx` and its
//! z and actions are held against the trainer's (max abs difference <= 1e-5), on every family's
//! shipped test demos and for each algorithm's encoder / policy shape (random weights: the
//! graph is what is under test, not what was learned); then `smile export --format onnx` end to
//! end and its refusals (no policy, demos of another family, an unwritable output), each one
//! line with nothing left behind.

mod common;
use common::s;

use std::path::{Path, PathBuf};

use rand::SeedableRng;
use sim::{DemoDataset, Family, Split};
use tract_onnx::prelude::*;
use trainer::onnx::{self, Reference};
use trainer::{ContextConfig, ContextEncoder, MetaPolicy, ObsNorm, TanhGaussianPolicy};

/// The largest difference allowed between tract and the trainer.
const TOL: f32 = 1e-5;

fn tmp(name: &str) -> PathBuf {
    common::fresh_dir("smile-onnx", name)
}

fn assets() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/experts")
}

/// The shipped test demos of `fam`, its first `tasks` tasks.
fn test_demos(fam: Family, tasks: usize) -> DemoDataset {
    let dir = assets().join(fam.name());
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("demos-test-") && n.ends_with(".safetensors"))
        })
        .collect();
    files.sort();
    // The smallest file: the subsampled demos.
    files.sort_by_key(|p| std::fs::metadata(p).unwrap().len());
    let mut ds = DemoDataset::read(&files[0]).unwrap();
    ds.tasks.truncate(tasks);
    ds
}

/// A meta-policy of `fam` with random weights, shaped like `algo`'s (state-only encoder,
/// linear or deeper head, policy widths).
fn random_policy(fam: Family, algo: &str, norm: ObsNorm, seed: u64) -> MetaPolicy {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let (od, ad) = (fam.obs_dim(), fam.act_dim());
    let (ctx, hidden) = match algo {
        "smile" => (ContextConfig::default(), vec![64, 64]),
        "smile-state-only" => (
            ContextConfig {
                state_only: true,
                ..ContextConfig::default()
            },
            vec![64, 64],
        ),
        "meta-bc" => (
            ContextConfig {
                enc_hidden: vec![32],
                head_hidden: vec![],
                r_dim: 8,
                z_dim: 4,
                ..ContextConfig::default()
            },
            vec![32, 32],
        ),
        "meta-dagger" => (
            ContextConfig {
                head_hidden: vec![64],
                ..ContextConfig::default()
            },
            vec![128, 128, 128],
        ),
        other => panic!("{other}"),
    };
    let encoder = ContextEncoder::new(od, ad, ctx, &mut rng).unwrap();
    let policy =
        TanhGaussianPolicy::new(od + encoder.z_dim(), ad, &hidden, (-20.0, 2.0), &mut rng).unwrap();
    MetaPolicy {
        family: fam,
        physics: sim::Physics::Rapier,
        algo: algo.into(),
        norm,
        encoder,
        policy,
    }
}

/// Max abs differences (z, actions end to end, actions given the trainer's z) between tract
/// running the export in `dir` and the trainer's reference, and the largest |z| seen.
#[derive(Debug, Default)]
struct Diffs {
    z: f32,
    action: f32,
    action_same_z: f32,
    z_abs: f32,
    contexts: usize,
    actions: usize,
}

fn load(path: &Path) -> Arc<TypedRunnableModel> {
    tract_onnx::onnx()
        .model_for_path(path)
        .unwrap_or_else(|e| panic!("tract cannot load {}: {e:?}", path.display()))
        .into_optimized()
        .unwrap()
        .into_runnable()
        .unwrap()
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()))
}

fn tract_parity(dir: &Path, r: &Reference) -> Diffs {
    let enc = load(&dir.join(onnx::ENCODER_FILE));
    let pol = load(&dir.join(onnx::POLICY_FILE));
    let mut d = Diffs::default();
    for c in &r.contexts {
        let [n, st, td] = c.shape;
        let ctx = Tensor::from_shape(&[n, st, td], &c.context).unwrap();
        let mask = Tensor::from_shape(&[n, st], &c.mask).unwrap();
        let out = enc.run(tvec![ctx.into(), mask.into()]).unwrap();
        let view = out[0].to_plain_array_view::<f32>().unwrap();
        assert_eq!(view.shape(), &[1, r.z_dim]);
        let z: Vec<f32> = view.iter().copied().collect();
        d.z = d.z.max(max_diff(&z, &c.z));
        d.z_abs = c.z.iter().fold(d.z_abs, |m, v| m.max(v.abs()));
        let rows = c.observations.len() / r.obs_dim;
        let obs = Tensor::from_shape(&[rows, r.obs_dim], &c.observations).unwrap();
        for (zz, same) in [(&z, false), (&c.z, true)] {
            let zb: Vec<f32> = (0..rows).flat_map(|_| zz.iter().copied()).collect();
            let zt = Tensor::from_shape(&[rows, r.z_dim], &zb).unwrap();
            let out = pol.run(tvec![obs.clone().into(), zt.into()]).unwrap();
            let view = out[0].to_plain_array_view::<f32>().unwrap();
            assert_eq!(view.shape(), &[rows, r.act_dim]);
            let a: Vec<f32> = view.iter().copied().collect();
            let m = max_diff(&a, &c.actions);
            if same {
                d.action_same_z = d.action_same_z.max(m);
            } else {
                d.action = d.action.max(m);
            }
        }
        d.contexts += 1;
        d.actions += rows;
    }
    d
}

#[test]
fn tract_matches_the_trainer_on_every_family_and_algorithm() {
    trainer::threads::set_compute_threads(1);
    let root = tmp("families");
    let families = [
        Family::POINT_GOAL,
        Family::CHEETAH_VEL,
        Family::WALKER_DYN,
        Family::ANT_GOAL,
        Family::ANT_LINCLASS,
    ];
    let algos = ["smile", "smile-state-only", "meta-bc", "meta-dagger"];
    let mut worst = 0.0f32;
    for (f, fam) in families.into_iter().enumerate() {
        // Two tasks: contexts of one trajectory and of every trajectory (4 or 16), padded.
        let demos = test_demos(fam, 2);
        let norm = ObsNorm::from_demos(&demos).unwrap();
        for (k, algo) in algos.iter().enumerate() {
            let mp = random_policy(fam, algo, norm.clone(), (10 * f + k) as u64);
            let ex = onnx::export(&mp).unwrap();
            assert_eq!(ex.meta.family, fam.name());
            assert_eq!(ex.meta.opset, onnx::OPSET);
            let reference = onnx::reference(&mp, &demos).unwrap();
            let dir = root.join(format!("{}-{algo}", fam.name()));
            onnx::write_dir(&dir, &ex, Some((&reference, "test demos"))).unwrap();
            let d = tract_parity(&dir, &reference);
            eprintln!(
                "tract parity {:<12} {:<16} contexts {:>2} actions {:>4}: z max |diff| {:.2e} \
                 (max |z| {:.2}), action max |diff| {:.2e} end to end, {:.2e} on the trainer's z",
                fam.name(),
                algo,
                d.contexts,
                d.actions,
                d.z,
                d.z_abs,
                d.action,
                d.action_same_z
            );
            assert!(
                d.z <= TOL && d.action <= TOL && d.action_same_z <= TOL,
                "{} {algo}: {d:?}",
                fam.name()
            );
            worst = worst.max(d.z).max(d.action);
        }
    }
    eprintln!("tract parity: worst max |diff| {worst:.2e} over 5 families x 4 algorithms");
    std::fs::remove_dir_all(&root).ok();
}

/// Runs `smile` as a user would, without `RUST_BACKTRACE` (which adds the error chain).
fn smile(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_smile"))
        .args(args)
        .env_remove("RUST_BACKTRACE")
        .output()
        .expect("run smile")
}

/// Lines of a failed run's stderr; asserts a clean error exit.
fn one_line_error(out: &std::process::Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "not a clean error exit: {err}");
    assert!(!err.contains("panicked"), "{err}");
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "not one line: {err}");
    err
}

/// Entries of `dir` (names), sorted.
fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn smile_export_format_onnx_writes_a_runnable_directory_and_refuses_bad_input() {
    let dir = tmp("cli");
    let fam = Family::POINT_GOAL;
    let test = dir.join("test.safetensors");
    let demos = test_demos(fam, 16);
    demos.write(&test).unwrap();
    let norm = ObsNorm::from_demos(&demos).unwrap();
    let run = dir.join("run");
    std::fs::create_dir_all(&run).unwrap();
    random_policy(fam, "smile", norm, 99).save(&run).unwrap();
    let out = dir.join("onnx");
    // `smile export --format onnx` of `policy` on `contexts` into `o`, then `extra`.
    let export_onnx = |policy: &Path, contexts: &Path, o: &Path, extra: &[&str]| {
        let mut args = vec![
            "export",
            "--policy",
            s(policy),
            "--format",
            "onnx",
            "--contexts",
            s(contexts),
            "-o",
            s(o),
        ];
        args.extend_from_slice(extra);
        smile(&args)
    };
    let export = |o: &Path, extra: &[&str]| export_onnx(&run, &test, o, extra);
    let err = common::ok(&export(&out, &[]));
    assert!(err.contains("ONNX opset 17"), "{err}");
    assert_eq!(
        entries(&out),
        [
            "encoder.onnx",
            "onnx.json",
            "policy.onnx",
            "reference.safetensors"
        ]
    );
    let meta: onnx::OnnxMeta =
        serde_json::from_slice(&std::fs::read(out.join(onnx::META_FILE)).unwrap()).unwrap();
    assert_eq!(meta.family, "point-goal");
    assert_eq!(meta.transition_dim, 2 * fam.obs_dim() + fam.act_dim());
    assert_eq!(meta.encoder.inputs[0].shape[0], "trajectories");
    assert_eq!(meta.normalisation.obs_mean.len(), fam.obs_dim());
    assert_eq!(meta.reference.as_ref().unwrap().contexts, 32);
    // The files on disk, through tract, against the reference the CLI stored.
    let r = read_reference(&out.join(onnx::REFERENCE_FILE), &meta);
    let d = tract_parity(&out, &r);
    assert!(d.z <= TOL && d.action <= TOL, "{d:?}");
    // Exporting again replaces the directory; nothing is left beside it.
    common::ok(&export(&out, &[]));
    assert_eq!(entries(&dir), ["onnx", "run", "test.safetensors"]);

    // A run directory without a policy.
    let empty = dir.join("empty-run");
    std::fs::create_dir_all(&empty).unwrap();
    let o = export_onnx(&empty, &test, &dir.join("x"), &[]);
    let err = one_line_error(&o);
    assert!(err.contains("meta_policy.safetensors"), "{err}");
    // Contexts and demos of another family.
    let cheetah = dir.join("cheetah.safetensors");
    test_demos(Family::CHEETAH_VEL, 1).write(&cheetah).unwrap();
    let x = dir.join("x");
    for o in [
        export_onnx(&run, &cheetah, &x, &[]),
        export(&x, &["--demos", s(&cheetah)]),
    ] {
        let err = one_line_error(&o);
        assert!(
            err.contains("family cheetah-vel, expected point-goal"),
            "{err}"
        );
    }
    // Unwritable outputs: below a file, a file, a directory of something else.
    let file = dir.join("a-file");
    std::fs::write(&file, b"keep").unwrap();
    let err = one_line_error(&export(&file.join("onnx"), &[]));
    assert!(err.contains("cannot write"), "{err}");
    let err = one_line_error(&export(&file, &[]));
    assert!(err.contains("it is a file"), "{err}");
    assert_eq!(std::fs::read(&file).unwrap(), b"keep");
    let other = dir.join("other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("notes.txt"), b"mine").unwrap();
    let err = one_line_error(&export(&other, &[]));
    assert!(err.contains("other files"), "{err}");
    assert_eq!(entries(&other), ["notes.txt"]);
    // Nothing half-written anywhere.
    assert_eq!(
        entries(&dir),
        [
            "a-file",
            "cheetah.safetensors",
            "empty-run",
            "onnx",
            "other",
            "run",
            "test.safetensors"
        ]
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Reads the CLI's `reference.safetensors` back into a [`Reference`].
fn read_reference(path: &Path, meta: &onnx::OnnxMeta) -> Reference {
    let bytes = std::fs::read(path).unwrap();
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let f32s = |name: &str| -> (Vec<usize>, Vec<f32>) {
        let t = st.tensor(name).unwrap();
        let v = t
            .data()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        (t.shape().to_vec(), v)
    };
    let n = meta.reference.as_ref().unwrap().contexts;
    let contexts = (0..n)
        .map(|i| {
            let (shape, context) = f32s(&format!("{i}.context"));
            onnx::ReferenceContext {
                task: i / 2,
                shape: [shape[0], shape[1], shape[2]],
                context,
                mask: f32s(&format!("{i}.mask")).1,
                z: f32s(&format!("{i}.z")).1,
                observations: f32s(&format!("{i}.observation")).1,
                actions: f32s(&format!("{i}.action")).1,
            }
        })
        .collect();
    Reference {
        obs_dim: meta.obs_dim,
        act_dim: meta.act_dim,
        z_dim: meta.z_dim,
        physics: meta.physics,
        contexts,
    }
}

#[test]
fn the_export_is_deterministic() {
    // The same policy gives the same bytes (no timestamps, no map-order in the graphs).
    let fam = Family::POINT_GOAL;
    let demos = test_demos(fam, 2);
    assert_eq!(demos.split, Split::Test);
    let mp = random_policy(fam, "meta-bc", ObsNorm::from_demos(&demos).unwrap(), 5);
    let (a, b) = (onnx::export(&mp).unwrap(), onnx::export(&mp).unwrap());
    assert_eq!(a.encoder, b.encoder);
    assert_eq!(a.policy, b.policy);
}

/// tract on directories written by `smile export --format onnx` (trained policies), against
/// the reference each one holds: the figures of the guide's "Deploy with ONNX" (docs/GUIDE.md).
/// `SMILE_ONNX_DIRS=dir1:dir2 cargo test --release -p smile-app --test onnx -- --ignored --nocapture`
#[test]
#[ignore = "needs SMILE_ONNX_DIRS: export directories of trained policies"]
fn tract_on_exported_directories() {
    let dirs = std::env::var("SMILE_ONNX_DIRS").expect("SMILE_ONNX_DIRS");
    for dir in dirs.split(':').filter(|d| !d.is_empty()).map(PathBuf::from) {
        let meta: onnx::OnnxMeta =
            serde_json::from_slice(&std::fs::read(dir.join(onnx::META_FILE)).unwrap()).unwrap();
        let r = read_reference(&dir.join(onnx::REFERENCE_FILE), &meta);
        let d = tract_parity(&dir, &r);
        eprintln!(
            "tract {:<12} {:<16} contexts {:>3} actions {:>6}: z max |diff| {:.2e} (max |z| \
             {:.2}), action max |diff| {:.2e} end to end, {:.2e} on the trainer's z",
            meta.family, meta.algo, d.contexts, d.actions, d.z, d.z_abs, d.action, d.action_same_z
        );
        assert!(d.z <= TOL && d.action <= TOL, "{}: {d:?}", dir.display());
    }
}
