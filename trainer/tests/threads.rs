//! Learner threads: an expert and a Meta-BC run on a pool of several threads (their large
//! products split across it) train the same weights, bit for bit, as on one thread.

mod common;

use sim::Family;
use trainer::MetaData;
use trainer::expert::{ExpertConfig, ExpertTrainer};
use trainer::meta_bc::{MetaBc, MetaBcConfig};
use trainer::sac::SacConfig;

fn bits(vars: &[candle_core::Var]) -> Vec<u32> {
    common::flat_values(vars)
        .into_iter()
        .map(f32::to_bits)
        .collect()
}

#[test]
fn an_expert_trains_the_same_weights_on_one_and_on_three_threads() {
    trainer::threads::set_compute_threads(1);
    let weights = |threads: usize| {
        // batch 256 through 128 x 128: each hidden product is 8 MFLOP, above the split size
        let cfg = ExpertConfig {
            total_steps: 90,
            learning_starts: 60,
            horizon: Some(30),
            eval_every: 0,
            learner_threads: threads,
            sac: SacConfig {
                hidden: vec![128, 128],
                batch_size: 256,
                ..Default::default()
            },
            ..Default::default()
        };
        let mut run = ExpertTrainer::new(cfg).unwrap();
        while run.env_steps() < 90 {
            run.run_episode(&mut |_| {}).unwrap();
        }
        let mut w = bits(run.sac.actor.net().vars());
        w.extend(bits(run.sac.q1.vars()));
        w.extend(bits(run.sac.q2.vars()));
        w
    };
    let one = weights(1);
    assert_eq!(one, weights(3), "one and three learner threads");
    let bad = ExpertConfig {
        learner_threads: 0,
        ..Default::default()
    };
    let e = ExpertTrainer::new(bad).err().unwrap().to_string();
    assert!(e.contains("learner_threads must be 1 to 256, not 0"), "{e}");
}

#[test]
fn meta_bc_trains_the_same_weights_on_one_and_on_two_threads() {
    trainer::threads::set_compute_threads(1);
    let data =
        MetaData::from_dataset(&common::train_demos(8, 2, 30), Family::POINT_GOAL, 4).unwrap();
    let weights = |threads: usize| {
        // 4 tasks x 64 rows through 256 x 256: 33 MFLOP products
        let mut cfg = MetaBcConfig {
            policy_hidden: vec![256, 256],
            tasks_per_batch: 4,
            per_task: 64,
            holdout_every: 4,
            horizon: Some(30),
            seed: 2,
            learner_threads: threads,
            ..MetaBcConfig::default()
        };
        cfg.context.enc_hidden = vec![16];
        cfg.context.r_dim = 8;
        cfg.context.z_dim = 4;
        let mut run = MetaBc::new(cfg, data.clone(), None).unwrap();
        let losses: Vec<u32> = (0..6).map(|_| run.step().unwrap().to_bits()).collect();
        let mut w = bits(run.policy.net().vars());
        w.extend(bits(&run.encoder.vars()));
        (w, losses)
    };
    let (one, l1) = weights(1);
    let (two, l2) = weights(2);
    assert_eq!(l1, l2);
    assert_eq!(one, two, "one and two learner threads");
}
