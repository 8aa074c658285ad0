//! The discriminator's loss against its reference: one graph, one backward.

use super::*;
use crate::model::{ContextConfig, ContextSpec, DiscInput, ObsNorm};
use crate::threads::LearnerPool;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// A small encoder, discriminator and batch of random rows (3 tasks x 8 rows).
fn setup() -> (ContextEncoder, Discriminator, DiscBatch) {
    let (od, ad, tasks, per_task) = (5, 2, 3, 8);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let cfg = ContextConfig {
        enc_hidden: vec![16],
        r_dim: 8,
        z_dim: 4,
        head_hidden: vec![],
        stochastic_z: false,
        ..ContextConfig::default()
    };
    let encoder = ContextEncoder::new(od, ad, cfg, &mut rng).unwrap();
    let disc =
        Discriminator::new(od, ad, 4, &[32, 32], DiscInput::StateAction, 10.0, &mut rng).unwrap();
    let mut normal = |n: usize| -> Vec<f32> {
        (0..n)
            .map(|_| rng.sample::<f32, _>(rand_distr::StandardNormal))
            .collect()
    };
    let trajs: Vec<sim::Trajectory> = (0..tasks * 2)
        .map(|_| {
            let mut t = sim::Trajectory::new(0);
            for i in 0..4 {
                let (o, a, n) = (normal(od), normal(ad), normal(od));
                let tr = sim::TransitionRef {
                    obs: &o,
                    action: &a,
                    reward: 0.0,
                    next_obs: &n,
                    done: false,
                };
                t.push(i, tr);
            }
            t
        })
        .collect();
    let (xe, xp) = (
        normal(tasks * per_task * (od + ad)),
        normal(tasks * per_task * (od + ad)),
    );
    let specs: Vec<ContextSpec<'_>> = trajs
        .chunks(2)
        .map(|c| ContextSpec::all(c.iter().collect()))
        .collect();
    let context = encoder.batch(&ObsNorm::identity(od), &specs).unwrap();
    let batch = DiscBatch::new(context, xe, xp, tasks, per_task).unwrap();
    (encoder, disc, batch)
}

/// Every variable's gradient in `g`, flattened, in the networks' order.
fn flat(g: &GradStore, enc: &ContextEncoder, disc: &Discriminator) -> Vec<Vec<f32>> {
    enc.vars()
        .iter()
        .chain(disc.vars().iter())
        .map(|v| {
            g.get(v.as_tensor())
                .expect("every variable has a gradient")
                .flatten_all()
                .unwrap()
                .to_vec1::<f32>()
                .unwrap()
        })
        .collect()
}

#[test]
fn split_gradients_are_one_backward_of_the_sum_and_repeat_per_thread_count() {
    let (enc, disc, batch) = setup();
    let gp_w = 10.0;
    let grads = |threads: usize| {
        let pool = LearnerPool::new(threads).unwrap();
        pool.install(|| {
            let mut rng = ChaCha8Rng::seed_from_u64(3);
            let (g, s) = disc_loss(&enc, &disc, gp_w, &batch, 1, &mut rng).unwrap();
            (flat(&g, &enc, &disc), s)
        })
    };
    let (g1, s1) = grads(1);
    // Two learner threads: the halves run as joins (the penalty in two pieces); the same
    // bits every time.
    let (g2, s2) = grads(2);
    assert_eq!(g2, grads(2).0);
    assert_eq!(g1, grads(1).0);
    assert!(s1.gp > 0.0 && s1.bce > 0.0);
    assert_eq!(s1.bce, s2.bce);
    assert!((s1.gp - s2.gp).abs() <= 1e-5 * s1.gp);

    // The reference: L_D = L_bce + lambda L_gp in one graph, one backward, the same draws
    // (z first, then u).
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let rows = batch.tasks * batch.per_task;
    let z_rows = batch
        .z_rows(&enc.z(&batch.context, true, &mut rng).unwrap())
        .unwrap();
    let u: Vec<f32> = (0..rows).map(|_| rng.random::<f32>()).collect();
    let u = Tensor::from_vec(u, (rows, 1), &Device::Cpu).unwrap();
    let inp = Tensor::cat(
        &[
            &Tensor::cat(&[&batch.x_expert, &z_rows], 1).unwrap(),
            &Tensor::cat(&[&batch.x_policy, &z_rows], 1).unwrap(),
        ],
        0,
    )
    .unwrap();
    let logits = disc.logits(Input::from(&inp)).unwrap();
    let labels = Tensor::cat(
        &[
            Tensor::ones((rows, 1), DType::F32, &Device::Cpu).unwrap(),
            Tensor::zeros((rows, 1), DType::F32, &Device::Cpu).unwrap(),
        ],
        0,
    )
    .unwrap();
    let bce = bce_with_logits(&logits, &labels).unwrap();
    let gp = disc
        .gradient_penalty(&batch.x_expert, &batch.x_policy, &z_rows, &u, None)
        .unwrap();
    assert!((scalar(&gp).unwrap() - s1.gp).abs() <= 1e-5 * s1.gp);
    let reference = (bce + (gp * gp_w as f64).unwrap())
        .unwrap()
        .backward()
        .unwrap();
    let reference = flat(&reference, &enc, &disc);
    for g in [&g1, &g2] {
        for (a, b) in g.iter().flatten().zip(reference.iter().flatten()) {
            assert!((a - b).abs() <= 1e-4 * (1.0 + b.abs()), "{a} vs {b}");
        }
    }
}
