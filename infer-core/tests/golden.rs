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
use infer_core::{Dims, FloatModel, Model, ModelKind, Quant, WriteOptions, write_blob_with};

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

/// The golden blobs: the three schemes, and w8a8 with its first and last layers in w8a32.
const CASES: [(&str, Quant, Option<Quant>); 4] = [
    ("f32", Quant::F32, None),
    ("w8a32", Quant::W8A32, None),
    ("w8a8", Quant::W8A8, None),
    ("w8a8-edges-w8a32", Quant::W8A8, Some(Quant::W8A32)),
];

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
    for (name, quant, edges) in CASES {
        let blob_path = dir().join(format!("{name}.blob"));
        let out_path = dir().join(format!("{name}.expected"));
        let options = WriteOptions {
            edges,
            ..WriteOptions::default()
        };
        let written = write_blob_with(&float, quant, &calib, &options).unwrap();
        if regen {
            std::fs::write(&blob_path, &written).unwrap();
            std::fs::write(&out_path, outputs(&written, &float)).unwrap();
        }
        let golden = std::fs::read(&blob_path)
            .expect("golden blob missing: see the module docs to regenerate");
        assert_eq!(
            written, golden,
            "{name}: the writer no longer produces the golden blob bytes"
        );
        let expected = std::fs::read_to_string(&out_path).unwrap();
        assert_eq!(
            outputs(&golden, &float),
            expected,
            "{name}: outputs differ from the golden bits"
        );
    }
}
