//! The learner's update steps through the public API, one core: a SAC-v2 update and SMILe's
//! discriminator + encoder update at the PyTorch anchors' reference shapes
//! (`docs/bench/pytorch/torch_reference.py`: batch 256, obs 20 + z 16, act 6, two hidden
//! layers of width 64 or 256). `smile bench` times the same fixtures with its own harness and
//! sets them beside the PyTorch figures (`docs/BENCHMARKS.md`).
//!
//!   RAYON_NUM_THREADS=1 cargo bench -p smile-app --bench learner

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use smile_app::bench::{DiscBenchShape, DiscFixture, SacBenchShape, sac_fixture};

fn updates(c: &mut Criterion) {
    // One compute thread, as the learner runs (the previous setting is of no use here).
    let _previous = trainer::threads::set_compute_threads(1);
    let mut group = c.benchmark_group("update");
    group.measurement_time(Duration::from_secs(5));
    group.warm_up_time(Duration::from_secs(1));
    for hidden in [64, 256] {
        let (mut sac, batch, mut rng) =
            sac_fixture(SacBenchShape::reference(hidden), 0).expect("the SAC fixture builds");
        group.bench_function(format!("sac/h{hidden}"), |b| {
            b.iter(|| sac.update(&batch, &mut rng).expect("a SAC update"))
        });
        let mut disc = DiscFixture::new(&DiscBenchShape::reference(hidden), 0)
            .expect("the discriminator fixture builds");
        group.bench_function(format!("disc/h{hidden}"), |b| {
            b.iter(|| disc.step().expect("a discriminator update"))
        });
    }
    group.finish();
}

criterion_group!(benches, updates);
criterion_main!(benches);
