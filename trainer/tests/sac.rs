//! SAC learns and is deterministic (tiny, in-test tasks; a few seconds in release).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use trainer::ReplayBuffer;
use trainer::sac::{Sac, SacConfig};

fn small_cfg() -> SacConfig {
    SacConfig {
        hidden: vec![32, 32],
        batch_size: 64,
        actor_lr: 1e-3,
        critic_lr: 1e-3,
        alpha_lr: 1e-3,
        ..Default::default()
    }
}

/// Contextual bandit: s ~ U(-1, 1), reward -(a - 0.5 s)^2, every step terminal. The optimal
/// deterministic action is 0.5 s.
#[test]
fn sac_learns_contextual_bandit() {
    trainer::threads::set_compute_threads(1);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut sac = Sac::new(1, 1, small_cfg(), &mut rng).unwrap();
    let mut rb = ReplayBuffer::new(1, 1, 10_000).unwrap();
    let t0 = std::time::Instant::now();
    for step in 0..1500 {
        let s = rng.random_range(-1.0f32..1.0);
        let a = if step < 200 {
            vec![rng.random_range(-1.0f32..1.0)]
        } else {
            sac.actor.act(&[s], false, &mut rng).unwrap()
        };
        let r = -(a[0] - 0.5 * s).powi(2);
        rb.push(&[s], &a, r, &[0.0], true, None).unwrap();
        if step >= 200 {
            let b = rb.sample(64, &mut rng).unwrap();
            sac.update(&b, &mut rng).unwrap();
        }
    }
    let mut err = 0.0f32;
    for s in [-0.8f32, -0.4, 0.0, 0.4, 0.8] {
        let a = sac.actor.act(&[s], true, &mut rng).unwrap()[0];
        err = err.max((a - 0.5 * s).abs());
    }
    eprintln!("bandit: max |a - a*| = {err:.3} in {:?}", t0.elapsed());
    assert!(err < 0.1, "max action error {err}");
}

/// 1-D point: x' = clip(x + 0.2 a), reward -|x' - 0.5|, 15-step episodes from x ~ U(-1, 1);
/// needs bootstrapping through the discount to move toward the goal.
#[test]
fn sac_learns_point_1d() {
    trainer::threads::set_compute_threads(1);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let cfg = SacConfig {
        gamma: 0.9,
        ..small_cfg()
    };
    let mut sac = Sac::new(1, 1, cfg, &mut rng).unwrap();
    let mut rb = ReplayBuffer::new(1, 1, 20_000).unwrap();
    let step_env = |x: f32, a: f32| (x + 0.2 * a).clamp(-1.0, 1.0);
    let mut x = 0.0f32;
    for t in 0..3000 {
        if t % 15 == 0 {
            x = rng.random_range(-1.0f32..1.0);
        }
        let a = if t < 300 {
            vec![rng.random_range(-1.0f32..1.0)]
        } else {
            sac.actor.act(&[x], false, &mut rng).unwrap()
        };
        let nx = step_env(x, a[0]);
        rb.push(&[x], &a, -(nx - 0.5).abs(), &[nx], false, None)
            .unwrap();
        x = nx;
        if t >= 300 {
            let b = rb.sample(64, &mut rng).unwrap();
            sac.update(&b, &mut rng).unwrap();
        }
    }
    let mut worst = 0.0f32;
    for x0 in [-1.0f32, -0.5, 0.0, 0.9] {
        let mut x = x0;
        for _ in 0..15 {
            x = step_env(x, sac.actor.act(&[x], true, &mut rng).unwrap()[0]);
        }
        worst = worst.max((x - 0.5).abs());
    }
    eprintln!("point-1d: worst final distance {worst:.3}");
    assert!(worst < 0.1, "final distance {worst}");
}

#[test]
fn same_seed_same_update() {
    trainer::threads::set_compute_threads(1);
    let run = || {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut sac = Sac::new(5, 2, small_cfg(), &mut rng).unwrap();
        let mut rb = ReplayBuffer::new(5, 2, 100).unwrap();
        for _ in 0..100 {
            let o: Vec<f32> = (0..5).map(|_| rng.random_range(-1.0..1.0)).collect();
            let a: Vec<f32> = (0..2).map(|_| rng.random_range(-1.0..1.0)).collect();
            rb.push(&o, &a, rng.random(), &o, false, None).unwrap();
        }
        let mut stats = Vec::new();
        for _ in 0..3 {
            let b = rb.sample(32, &mut rng).unwrap();
            stats.push(sac.update(&b, &mut rng).unwrap());
        }
        let (tensors, _) = sac.state_tensors().unwrap();
        let flat: Vec<Vec<f32>> = tensors
            .iter()
            .map(|(_, t)| t.flatten_all().unwrap().to_vec1().unwrap())
            .collect();
        (stats, flat)
    };
    assert_eq!(run(), run());
}

/// SAC v1 style (the authors' SMILe): a fixed temperature, with the reward scale acting as the
/// inverse temperature. On the contextual bandit, scale 24 makes a much sharper policy than
/// scale 1 under the same fixed alpha = 1, and alpha does not move.
#[test]
fn with_a_fixed_temperature_the_reward_scale_sets_the_entropy() {
    trainer::threads::set_compute_threads(1);
    let entropy_at = |scale: f32| {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let cfg = SacConfig {
            learn_alpha: false,
            init_alpha: 1.0,
            reward_scale: scale,
            policy_reg: 1e-3,
            ..small_cfg()
        };
        let mut sac = Sac::new(1, 1, cfg, &mut rng).unwrap();
        let mut rb = ReplayBuffer::new(1, 1, 10_000).unwrap();
        let mut entropy = Vec::new();
        for step in 0..1200 {
            let s = rng.random_range(-1.0f32..1.0);
            let a = sac.actor.act(&[s], false, &mut rng).unwrap();
            rb.push(&[s], &a, -(a[0] - 0.5 * s).powi(2), &[0.0], true, None)
                .unwrap();
            if step >= 100 {
                let b = rb.sample(64, &mut rng).unwrap();
                let st = sac.update(&b, &mut rng).unwrap();
                assert_eq!(st.alpha, 1.0, "a fixed temperature moved");
                if step >= 1100 {
                    entropy.push(st.entropy);
                }
            }
        }
        entropy.iter().sum::<f32>() / entropy.len() as f32
    };
    let (h1, h24) = (entropy_at(1.0), entropy_at(24.0));
    eprintln!("fixed alpha 1: entropy {h1:.3} at reward scale 1, {h24:.3} at 24");
    assert!(h24 < h1 - 0.5, "entropy {h1} at scale 1, {h24} at scale 24");
}
