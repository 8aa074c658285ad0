//! Environment steps per second per family, one core. Episodes of the default horizon with a
//! fixed open-loop action pattern; the reset at each episode end is included in the cost.

use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use sim::{EnvConfig, Family, make_env};

fn env_steps(c: &mut Criterion) {
    let mut group = c.benchmark_group("env_step");
    group.throughput(Throughput::Elements(1));
    group.measurement_time(Duration::from_secs(4));
    group.warm_up_time(Duration::from_secs(1));
    for family in Family::ALL {
        let config = EnvConfig {
            healthy_termination: false,
            ..EnvConfig::default()
        };
        let mut env = make_env(family, config).expect("every family builds");
        let task = family.train_tasks()[1];
        env.reset(&task, 0).expect("reset");
        let mut step = 0usize;
        let mut episode = 0u64;
        group.bench_function(family.name(), |b| {
            b.iter(|| {
                step += 1;
                let phase = step as f32 * 0.3;
                let action: Vec<f32> = (0..env.act_dim())
                    .map(|j| 0.6 * (phase + j as f32).sin())
                    .collect();
                let done = env.step(&action).expect("step").done;
                if done {
                    episode += 1;
                    env.reset(&task, episode).expect("reset");
                }
            })
        });
    }
    group.finish();
}

criterion_group!(benches, env_steps);
criterion_main!(benches);
