//! ant-goal physics statistics over 30 seeded 100-step episodes per action pattern (random,
//! sine, zero): flips, peak and final torso height, distance travelled, cost per step. The
//! numbers quoted in `sim::ant`'s physics settings come from this (`cargo run --release -p sim
//! --example ant_fidelity`).

use rand::{Rng, SeedableRng};
use sim::{EnvConfig, Family, make_env};
use std::time::Instant;

fn main() {
    let mut env = make_env(Family::ANT_GOAL, EnvConfig::default()).unwrap();
    let task = Family::ANT_GOAL.train_tasks()[0];
    for mode in ["random", "sine", "zero"] {
        let (mut flips, mut maxz, mut disp, mut n, mut zend) = (0, 0.0f32, 0.0f32, 0, 0.0f32);
        let t0 = Instant::now();
        let mut steps = 0;
        for seed in 0..30u64 {
            env.reset(&task, seed).unwrap();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed + 100);
            let mut mz = 0.0f32;
            let freq = 0.2 + 0.05 * (seed % 5) as f32;
            for s in 0..100 {
                let a: Vec<f32> = (0..8)
                    .map(|j| match mode {
                        "zero" => 0.0,
                        "sine" => (freq * s as f32 + j as f32 * 1.3 + seed as f32).sin(),
                        _ => rng.random_range(-1.0..=1.0),
                    })
                    .collect();
                let t = env.step(&a).unwrap();
                mz = mz.max(t.obs[0]);
                steps += 1;
            }
            let o = env.observation();
            // torso up vector z component: 1 - 2(x^2 + y^2)
            let up = 1.0 - 2.0 * (o[2] * o[2] + o[3] * o[3]);
            if up < 0.0 {
                flips += 1;
            }
            maxz += mz;
            zend += o[0];
            disp += (o[27] * o[27] + o[28] * o[28]).sqrt();
            n += 1;
        }
        let us = t0.elapsed().as_secs_f64() * 1e6 / steps as f64;
        println!(
            "{mode:7} flips {flips:2}/{n} mean max z {:.3} mean end z {:.3} mean |xy| {:.3}  {us:.0} us/step",
            maxz / n as f32,
            zend / n as f32,
            disp / n as f32
        );
    }
}
