//! Environment steps per second per family and physics backend, one core. Episodes of the
//! default horizon with a fixed open-loop action pattern; the reset at each episode end is
//! included in the cost. Rapier's ids are the family names (as before the MuJoCo backend);
//! MuJoCo's (with `--features mujoco`) end in `-mujoco`.

use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use sim::{EnvConfig, Family, Physics, make_env};

fn env_steps(c: &mut Criterion) {
    let mut group = c.benchmark_group("env_step");
    group.throughput(Throughput::Elements(1));
    group.measurement_time(Duration::from_secs(4));
    group.warm_up_time(Duration::from_secs(1));
    let plants = Physics::ALL.into_iter().filter(|p| p.is_available());
    let cases = plants.flat_map(|p| Family::BUILTIN.into_iter().map(move |f| (p, f)));
    for (physics, family) in cases {
        if physics == Physics::Mujoco && family == Family::POINT_GOAL {
            continue;
        }
        let config = EnvConfig {
            healthy_termination: false,
            physics,
            ..EnvConfig::default()
        };
        let mut env = make_env(family, config).expect("every family builds");
        let id = match physics {
            Physics::Rapier => family.name().to_string(),
            other => format!("{family}-{other}"),
        };
        let task = family.train_tasks()[1];
        env.reset(&task, 0).expect("reset");
        let mut step = 0usize;
        let mut episode = 0u64;
        group.bench_function(id, |b| {
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
