//! Latency of `Policy::act` and `ContextEncoder::push` at the default sizes (obs 20, act 6,
//! r 32, z 16) for hidden 64 and 128 and each quantization scheme.
//!
//! ```sh
//! cargo bench -p infer-core --bench infer
//! ```

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use infer_core::{
    Calibration, ContextEncoder, Dims, FloatModel, Model, ModelKind, Policy, Quant, write_blob,
};

fn inputs(n: usize, seed: u32) -> Vec<f32> {
    (0..n)
        .map(|i| {
            ((i as u32).wrapping_mul(2_654_435_761).wrapping_add(seed) % 2000) as f32 / 1000.0 - 1.0
        })
        .collect()
}

fn calibration(float: &FloatModel) -> Calibration {
    let t = 2 * float.obs_dim + float.act_dim;
    Calibration {
        contexts: (0..4)
            .map(|c| vec![(0..20).map(|s| inputs(t, c * 100 + s)).collect()])
            .collect(),
        observations: (0..32).map(|s| inputs(float.obs_dim, 1000 + s)).collect(),
    }
}

fn bench(c: &mut Criterion) {
    for hidden in [64, 128] {
        let float =
            FloatModel::random(ModelKind::StateAction, Dims::default_with_hidden(hidden), 1);
        let calib = calibration(&float);
        for quant in [Quant::F32, Quant::W8A32, Quant::W8A8] {
            let blob = write_blob(&float, quant, &calib).unwrap();
            let model = Model::from_bytes(&blob).unwrap();
            let (obs, next, act, z) = (inputs(20, 1), inputs(20, 2), inputs(6, 3), inputs(16, 4));
            let mut policy = Policy::<128>::new(&model).unwrap();
            let mut action = [0.0f32; 6];
            c.bench_function(&format!("act/h{hidden}/{quant:?}"), |b| {
                b.iter(|| {
                    policy
                        .act(black_box(&obs), black_box(&z), &mut action)
                        .unwrap()
                })
            });
            let mut encoder = ContextEncoder::<128>::new(&model).unwrap();
            c.bench_function(&format!("push/h{hidden}/{quant:?}"), |b| {
                b.iter(|| {
                    encoder
                        .push(black_box(&obs), black_box(&act), black_box(&next))
                        .unwrap()
                })
            });
        }
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
