//! Golden vectors: checked-in blobs and the exact output bits they must produce.
//!
//! Regenerate (only when the format or the kernels change on purpose, and say why in the
//! commit):
//!
//! ```sh
//! INFER_CORE_REGEN_GOLDEN=1 cargo test -p infer-core --release --test golden
//! ```

mod common;

use std::fmt::Write as _;
use std::path::PathBuf;

use common::{Rng, blob_act, blob_latent};
use infer_core::{Dims, FloatModel, Model, ModelKind, Quant, write_blob};

const DIMS: Dims = Dims {
    obs: 4,
    act: 2,
    r: 8,
    z: 4,
    hidden: 16,
};

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

fn name(q: Quant) -> &'static str {
    match q {
        Quant::F32 => "f32",
        Quant::W8A32 => "w8a32",
        Quant::W8A8 => "w8a8",
    }
}

fn hex(v: &[f32]) -> String {
    v.iter()
        .map(|x| format!("{:08x}", x.to_bits()))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Outputs of a blob on the fixed inputs, one line per output vector.
fn outputs(bytes: &[u8], float: &FloatModel) -> String {
    let model = Model::from_bytes(bytes).expect("golden blob loads");
    let mut rng = Rng(2024);
    let mut out = String::new();
    for n in 1..=3 {
        let ctx = common::context(&mut rng, float, n);
        let z = blob_latent(&model, &ctx);
        writeln!(out, "z{n} {}", hex(&z)).unwrap();
        for k in 0..3 {
            let obs = rng.vec(DIMS.obs, 2.0);
            writeln!(out, "a{n}.{k} {}", hex(&blob_act(&model, &obs, &z))).unwrap();
        }
    }
    out
}

#[test]
fn golden_blobs_and_outputs_are_bit_exact() {
    let float = FloatModel::random(ModelKind::StateAction, DIMS, 42);
    let calib = common::calibration(&mut Rng(77), &float);
    let regen = std::env::var_os("INFER_CORE_REGEN_GOLDEN").is_some();
    for quant in [Quant::F32, Quant::W8A32, Quant::W8A8] {
        let blob_path = dir().join(format!("{}.blob", name(quant)));
        let out_path = dir().join(format!("{}.expected", name(quant)));
        let written = write_blob(&float, quant, &calib).unwrap();
        if regen {
            std::fs::write(&blob_path, &written).unwrap();
            std::fs::write(&out_path, outputs(&written, &float)).unwrap();
        }
        let golden = std::fs::read(&blob_path)
            .expect("golden blob missing: see the module docs to regenerate");
        assert_eq!(
            written, golden,
            "{quant:?}: the writer no longer produces the golden blob bytes"
        );
        let expected = std::fs::read_to_string(&out_path).unwrap();
        assert_eq!(
            outputs(&golden, &float),
            expected,
            "{quant:?}: outputs differ from the golden bits"
        );
    }
}
