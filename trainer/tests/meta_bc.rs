//! Meta-BC and Meta-DAgger on tiny networks.

mod common;

use sim::{DemoDataset, Family};
use trainer::MetaData;
use trainer::MetaPolicy;
use trainer::expert::Expert;
use trainer::meta_bc::{self, MetaBc, MetaBcConfig};
use trainer::{Progress, Score};

fn demos(tasks: usize, per_task: usize, horizon: usize) -> DemoDataset {
    common::train_demos(tasks, per_task, horizon)
}

fn tiny(dagger: bool) -> MetaBcConfig {
    let mut cfg = MetaBcConfig {
        policy_hidden: vec![32, 32],
        lr: 3e-3,
        tasks_per_batch: 4,
        per_task: 32,
        total_steps: 300,
        holdout_every: 4,
        eval_every: 50,
        patience: 0,
        eval_episodes: 1,
        dagger,
        dagger_every: 50,
        dagger_rollouts: 1,
        horizon: Some(30),
        seed: 1,
        ..MetaBcConfig::default()
    };
    cfg.context.enc_hidden = vec![16];
    cfg.context.r_dim = 8;
    cfg.context.z_dim = 4;
    cfg
}

#[test]
fn meta_bc_fits_and_saves_a_loadable_policy_and_a_resumable_run() {
    trainer::threads::set_compute_threads(1);
    let dir = std::env::temp_dir().join(format!("smile-bc-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let data = MetaData::from_dataset(&demos(8, 2, 30), Family::POINT_GOAL, 4).unwrap();
    let mut run = MetaBc::new(tiny(false), data, None).unwrap();
    let v0 = run.val_mse().unwrap();
    let mut vals = Vec::new();
    trainer::fit(&mut run, &dir, &mut |e| {
        if let Progress::Eval {
            score: Score {
                val_mse: Some(m), ..
            },
            ..
        } = e
        {
            vals.push(m);
        }
    })
    .unwrap();
    assert_eq!(vals.len(), 6);
    let best = vals.iter().cloned().fold(f32::INFINITY, f32::min);
    assert!(best < 0.5 * v0, "validation MSE {v0} -> {vals:?}");
    // A policy and a checkpoint are saved (that the policy is the best-validation one is
    // meta_bc_keeps_the_weights_of_its_best_validation_step's claim).
    let mp = MetaPolicy::load(&dir).unwrap();
    assert_eq!(mp.algo, "meta-bc");
    let saved = MetaBc::resume(&dir, run_data(), None, None).unwrap();
    assert_eq!(saved.steps(), 300);
    std::fs::remove_dir_all(&dir).unwrap();
}

fn run_data() -> MetaData {
    MetaData::from_dataset(&demos(8, 2, 30), Family::POINT_GOAL, 4).unwrap()
}

#[test]
fn early_stopping_and_dagger_relabelling() {
    trainer::threads::set_compute_threads(1);
    let dir = std::env::temp_dir().join(format!("smile-dagger-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut cfg = tiny(true);
    cfg.patience = 1;
    cfg.lr = 0.3; // diverging steps: the validation MSE stops improving quickly
    cfg.total_steps = 2000;
    let expert = Expert::ScriptedPd(sim::PointGoalPdExpert::default());
    let mut run = MetaBc::new(cfg, run_data(), Some(expert.into())).unwrap();
    let before = run.dataset_size();
    let (mut stopped, mut evals) = (Vec::new(), Vec::new());
    trainer::fit(&mut run, &dir, &mut |e| match e {
        Progress::Stopped(s) => stopped.push(s),
        Progress::Eval { step, .. } => evals.push(step),
        _ => {}
    })
    .unwrap();
    // Stopped once, at the evaluation that ran out of patience: no step, rollout or
    // evaluation after it.
    let [s] = stopped[..] else {
        panic!("one early stop, got {stopped:?}")
    };
    assert!(
        s < 2000 && run.steps() == s,
        "stopped at {s}, ran {}",
        run.steps()
    );
    assert_eq!(evals.last(), Some(&s), "{evals:?}");
    // One 30-step relabelled rollout every 50 steps.
    assert_eq!(run.dataset_size(), before + 30 * (s as usize).div_ceil(50));
    let err = MetaBc::new(tiny(true), run_data(), None).err().unwrap();
    assert!(
        matches!(&err, trainer::Error::Config(m) if m.contains("meta-dagger needs a relabelling expert")),
        "{err:?}"
    );
    // Meta-BC refuses an expert it would not use, as SMILe does: not ignored.
    let pd = Expert::ScriptedPd(sim::PointGoalPdExpert::default());
    let err = MetaBc::new(tiny(false), run_data(), Some(pd.into()))
        .err()
        .unwrap();
    assert!(
        matches!(&err, trainer::Error::Input { problem, .. } if problem.contains("meta-bc learns from the demos alone")),
        "{err:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn rollout_selection_keeps_the_best_held_out_rollouts() {
    trainer::threads::set_compute_threads(1);
    let dir = std::env::temp_dir().join(format!("smile-bc-rollouts-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let cfg = MetaBcConfig {
        select_by: meta_bc::Selection::Rollouts,
        ..tiny(false)
    };
    let (env_cfg, held_out) = (cfg.env_config(), cfg.held_out());
    let mut run = MetaBc::new(cfg, run_data(), None).unwrap();
    let mut metrics = Vec::new();
    trainer::fit(&mut run, &dir, &mut |e| {
        if let Progress::Eval { score, .. } = e {
            metrics.push(score.metric);
        }
    })
    .unwrap();
    // Min distance: lower is better. The kept policy reproduces the best held-out value.
    let best = metrics.iter().cloned().fold(f32::INFINITY, f32::min);
    let kept = MetaPolicy::load(&dir).unwrap();
    let again = trainer::quick_eval(&kept, &run_data().val, held_out, env_cfg).unwrap();
    assert_eq!(again, best, "kept {again}, evaluations {metrics:?}");
    // It is not simply the last evaluation (otherwise the test proves nothing).
    assert_ne!(best, *metrics.last().unwrap(), "{metrics:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn dagger_relabels_the_visited_states_with_the_experts_actions() {
    trainer::threads::set_compute_threads(1);
    let data = run_data();
    let pd = sim::PointGoalPdExpert::default();
    let mut run = MetaBc::new(
        tiny(true),
        data.clone(),
        Some(Expert::ScriptedPd(sim::PointGoalPdExpert::default()).into()),
    )
    .unwrap();
    let (od, ad) = (4, 2);
    let before: Vec<(Vec<f32>, Vec<f32>)> = (0..data.train.len())
        .map(|ti| {
            let (o, a) = run.aggregate(ti);
            (o.to_vec(), a.to_vec())
        })
        .collect();
    run.dagger_rollouts(3).unwrap();
    let (mut relabelled, mut moved) = (0, 0.0f32);
    for (ti, (obs0, act0)) in before.iter().enumerate() {
        let (obs, act) = run.aggregate(ti);
        // The demos stay first, unchanged.
        assert_eq!(
            (&obs[..obs0.len()], &act[..act0.len()]),
            (&obs0[..], &act0[..])
        );
        let mut oracle = [0.0f32; 6];
        data.train[ti]
            .task
            .write_parameter(&mut oracle[od..])
            .unwrap();
        for (o, a) in obs[obs0.len()..]
            .chunks_exact(od)
            .zip(act[act0.len()..].chunks_exact(ad))
        {
            oracle[..od].copy_from_slice(o);
            let mut want = [0.0f32; 2];
            pd.act(&oracle, &mut want).unwrap();
            assert_eq!(
                a, want,
                "task {ti}: state {o:?} labelled {a:?}, expert says {want:?}"
            );
            relabelled += 1;
            moved = moved.max(o[0].hypot(o[1]));
        }
    }
    // Three 30-step rollouts, every visited state relabelled.
    assert_eq!(relabelled, 3 * 30);
    // The states are the untrained policy's (it barely leaves the start), not the expert's: an
    // expert rollout would have travelled most of the way to a goal 2 away.
    assert!(moved < 1.0, "farthest relabelled state at {moved}");
}

#[test]
fn meta_bc_keeps_the_weights_of_its_best_validation_step() {
    trainer::threads::set_compute_threads(1);
    let root = std::env::temp_dir().join(format!("smile-bc-best-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let cfg = MetaBcConfig {
        lr: 3e-2, // noisy validation: the best step is not the last one
        total_steps: 200,
        eval_every: 20,
        ..tiny(false)
    };
    let (full, cut) = (root.join("full"), root.join("cut"));
    let mut run = MetaBc::new(cfg.clone(), run_data(), None).unwrap();
    let mut vals = Vec::new();
    trainer::fit(&mut run, &full, &mut |e| {
        if let Progress::Eval {
            step,
            score: Score {
                val_mse: Some(m), ..
            },
        } = e
        {
            vals.push((step, m));
        }
    })
    .unwrap();
    let &(best_step, best) = vals.iter().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
    assert_ne!(
        best_step,
        vals.last().unwrap().0,
        "the last evaluation is the best: this test could not tell best from last ({vals:?})"
    );
    // The same seed stopped at the best step: its final weights are the weights of that step.
    let mut again = MetaBc::new(
        MetaBcConfig {
            total_steps: best_step,
            ..cfg
        },
        run_data(),
        None,
    )
    .unwrap();
    trainer::fit(&mut again, &cut, &mut |_| {}).unwrap();
    assert_eq!(again.val_mse().unwrap(), best);
    // The weights are equal; the files' training marks differ (step 200 of 200 against
    // step 160 of 160), so compare tensors, not bytes.
    let kept = trainer::checkpoint::load(&full.join(trainer::META_POLICY_FILE)).unwrap();
    let at_best =
        trainer::checkpoint::load(&cut.join("last").join(trainer::META_POLICY_FILE)).unwrap();
    for name in [
        "phi.0", "phi.1", "head.0", "policy.0", "policy.1", "policy.2",
    ] {
        let (a, b) = (kept.get(name).unwrap(), at_best.get(name).unwrap());
        assert!(
            a.flatten_all().unwrap().to_vec1::<f32>().unwrap()
                == b.flatten_all().unwrap().to_vec1::<f32>().unwrap(),
            "{name}: the kept policy is not the step-{best_step} one (validation {vals:?})"
        );
    }
    let mark = trainer::MetaPolicy::training_mark(&full).unwrap().unwrap();
    assert!(mark.finished && mark.updates == best_step, "{mark:?}");
    std::fs::remove_dir_all(&root).ok();
}

/// `pre_tanh_loss` (the original code's loss, kept for issue 46's comparison) regresses the
/// pre-tanh mean: the same seed then learns other weights, its executed actions (tanh of a mean
/// fitted to the demo actions) are squashed, and a default config is written without the key.
#[test]
fn the_pre_tanh_loss_is_the_original_codes_and_off_by_default() {
    trainer::threads::set_compute_threads(1);
    let data = || MetaData::from_dataset(&demos(8, 2, 30), Family::POINT_GOAL, 4).unwrap();
    let cfg = MetaBcConfig {
        total_steps: 40,
        eval_every: 0,
        ..tiny(false)
    };
    let text = toml::to_string(&cfg).unwrap();
    assert!(!text.contains("pre_tanh_loss"), "{text}");
    let mut ours = MetaBc::new(cfg.clone(), data(), None).unwrap();
    let original_cfg = MetaBcConfig {
        pre_tanh_loss: true,
        ..cfg
    };
    assert!(
        toml::to_string(&original_cfg)
            .unwrap()
            .contains("pre_tanh_loss = true")
    );
    let mut original = MetaBc::new(original_cfg, data(), None).unwrap();
    // The same initial weights (one seed); the first step's losses already differ.
    let (a, b) = (ours.step().unwrap(), original.step().unwrap());
    assert!(a.is_finite() && b.is_finite() && a != b, "{a} vs {b}");
    for _ in 0..20 {
        ours.step().unwrap();
        original.step().unwrap();
    }
    let (p, q) = (ours.meta_policy(), original.meta_policy());
    let w = |m: &MetaPolicy| {
        m.policy.net().vars()[0]
            .flatten_all()
            .unwrap()
            .to_vec1::<f32>()
            .unwrap()
    };
    assert_ne!(w(&p), w(&q));
}

#[test]
fn early_weight_draws_the_first_steps_rows_that_many_times_more_often() {
    let data = run_data();
    let early = meta_bc::EarlyWeight {
        steps: 3,
        weight: 4,
    };
    let cfg = MetaBcConfig {
        early: Some(early),
        ..tiny(false)
    };
    let plain = MetaBc::new(tiny(false), data.clone(), None).unwrap();
    let weighted = MetaBc::new(cfg.clone(), data.clone(), None).unwrap();
    let (od, ad) = (4, 2);
    for (ti, td) in data.train.iter().enumerate() {
        let (po, pa) = plain.aggregate(ti);
        let (wo, wa) = weighted.aggregate(ti);
        // Every demo row, each of the first 3 steps' 4 times, in order.
        let (mut want_o, mut want_a) = (Vec::new(), Vec::new());
        let mut row = 0;
        for t in &td.trajectories {
            for &step in &t.time_steps {
                let copies = if step < 3 { 4 } else { 1 };
                for _ in 0..copies {
                    want_o.extend_from_slice(&po[row * od..(row + 1) * od]);
                    want_a.extend_from_slice(&pa[row * ad..(row + 1) * ad]);
                }
                row += 1;
            }
        }
        assert_eq!(row * ad, pa.len(), "task {ti}: every row read");
        assert!(wa.len() > pa.len(), "task {ti}: no row weighted");
        assert_eq!((wo, wa), (&want_o[..], &want_a[..]), "task {ti}");
    }
    for (steps, weight) in [(0, 4), (3, 0)] {
        let bad = MetaBcConfig {
            early: Some(meta_bc::EarlyWeight { steps, weight }),
            ..tiny(false)
        };
        let err = MetaBc::new(bad, data.clone(), None)
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("early."), "{err}");
    }
}
