//! Quantization error of w8a32 and w8a8 against the f32 blob on random networks, reported
//! (run with `--nocapture` to see the table) and bounded.

mod common;

use common::{Rng, blob_act, blob_latent, calibration, context, model};
use infer_core::{Calibration, Model, ModelKind, Quant, WriteOptions, write_blob, write_blob_with};

struct Stats {
    max: f32,
    sum: f64,
    n: usize,
}

fn errors(kind: ModelKind, hidden: usize, quant: Quant, edges: Option<Quant>) -> (Stats, Stats) {
    let float = model(kind, hidden, 21);
    let mut rng = Rng(99);
    let calib = calibration(&mut rng, &float);
    let reference = write_blob(&float, Quant::F32, &Calibration::default()).unwrap();
    let options = WriteOptions {
        edges,
        ..WriteOptions::default()
    };
    let quantized = write_blob_with(&float, quant, &calib, &options).unwrap();
    let (r, q) = (
        Model::from_bytes(&reference).unwrap(),
        Model::from_bytes(&quantized).unwrap(),
    );
    let (mut z_err, mut a_err) = (
        Stats {
            max: 0.0,
            sum: 0.0,
            n: 0,
        },
        Stats {
            max: 0.0,
            sum: 0.0,
            n: 0,
        },
    );
    // Held-out inputs: a different seed from the calibration data.
    let mut rng = Rng(1234);
    for i in 0..40 {
        let ctx = context(&mut rng, &float, 1 + i % 4);
        let (zr, zq) = (blob_latent(&r, &ctx), blob_latent(&q, &ctx));
        for (a, b) in zr.iter().zip(&zq) {
            let e = (a - b).abs();
            z_err.max = z_err.max.max(e);
            z_err.sum += e as f64;
            z_err.n += 1;
        }
        for _ in 0..8 {
            let obs = rng.vec(20, 1.5);
            // The quantized policy runs on its own z: the error is the whole pipeline's.
            for (a, b) in blob_act(&r, &obs, &zr).iter().zip(&blob_act(&q, &obs, &zq)) {
                let e = (a - b).abs();
                a_err.max = a_err.max.max(e);
                a_err.sum += e as f64;
                a_err.n += 1;
            }
        }
    }
    (z_err, a_err)
}

#[test]
fn quantization_error_is_reported_and_bounded() {
    println!("| kind | hidden | quant | z max | z mean | action max | action mean |");
    println!("|---|---|---|---|---|---|---|");
    for kind in [ModelKind::StateAction, ModelKind::StateOnly] {
        for hidden in [64, 128] {
            for (quant, max_bound, mean_bound) in
                [(Quant::W8A32, 0.01, 0.002), (Quant::W8A8, 0.05, 0.005)]
            {
                let (z, a) = errors(kind, hidden, quant, None);
                let mean = (a.sum / a.n as f64) as f32;
                println!(
                    "| {kind:?} | {hidden} | {quant:?} | {:.4} | {:.5} | {:.4} | {:.5} |",
                    z.max,
                    z.sum / z.n as f64,
                    a.max,
                    mean
                );
                assert!(
                    a.max < max_bound,
                    "{kind:?} {hidden} {quant:?}: max action error {}",
                    a.max
                );
                assert!(
                    mean < mean_bound,
                    "{kind:?} {hidden} {quant:?}: mean action error {mean}"
                );
                assert!(
                    a.max > 0.0,
                    "quantization that changes nothing is suspicious"
                );
            }
        }
    }
}

/// `write_blob_with` at quantile 1 is `write_blob` byte for byte; a lower quantile caps the
/// activation ranges (finer steps, the rarest values clipped), so the blob differs and still
/// loads and acts close to the float model.
#[test]
fn a_range_quantile_below_one_caps_the_scales_and_one_is_the_maximum() {
    let at = |range_quantile| WriteOptions {
        range_quantile,
        ..WriteOptions::default()
    };
    let float = model(ModelKind::StateAction, 32, 21);
    let mut rng = Rng(99);
    let calib = calibration(&mut rng, &float);
    let plain = write_blob(&float, Quant::W8A8, &calib).unwrap();
    assert_eq!(
        write_blob_with(&float, Quant::W8A8, &calib, &at(1.0)).unwrap(),
        plain
    );
    let capped = write_blob_with(&float, Quant::W8A8, &calib, &at(0.99)).unwrap();
    assert_ne!(capped, plain);
    let (p, c) = (
        Model::from_bytes(&plain).unwrap(),
        Model::from_bytes(&capped).unwrap(),
    );
    let mut rng = Rng(1234);
    let ctx = context(&mut rng, &float, 2);
    let obs = rng.vec(20, 1.5);
    let (zp, zc) = (blob_latent(&p, &ctx), blob_latent(&c, &ctx));
    for (a, b) in blob_act(&p, &obs, &zp).iter().zip(&blob_act(&c, &obs, &zc)) {
        assert!((a - b).abs() < 0.2, "{a} vs {b}");
    }
}

/// w8a8 with its first and last layers in w8a32 (format v3's per-layer precision) errs less
/// than plain w8a8 on every network here, and no more than whole-w8a32 bounds allow for the
/// layers it keeps in int8.
#[test]
fn higher_precision_edges_cut_the_w8a8_error() {
    println!("| kind | hidden | w8a8 action mean | edges w8a32 action mean | w8a32 action mean |");
    println!("|---|---|---|---|---|");
    for kind in [ModelKind::StateAction, ModelKind::StateOnly] {
        for hidden in [64, 128] {
            let mean = |s: &Stats| (s.sum / s.n as f64) as f32;
            let plain = mean(&errors(kind, hidden, Quant::W8A8, None).1);
            let edges = mean(&errors(kind, hidden, Quant::W8A8, Some(Quant::W8A32)).1);
            let whole = mean(&errors(kind, hidden, Quant::W8A32, None).1);
            println!("| {kind:?} | {hidden} | {plain:.5} | {edges:.5} | {whole:.5} |");
            assert!(
                edges < plain,
                "{kind:?} {hidden}: edges {edges} vs w8a8 {plain}"
            );
            assert!(
                edges > whole * 0.5,
                "{kind:?} {hidden}: edges {edges} vs w8a32 {whole}"
            );
        }
    }
}
