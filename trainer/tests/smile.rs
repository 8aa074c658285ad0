//! SMILe on tiny networks: the discriminator learns to separate expert from policy
//! transitions, the state-only variant has the right shapes, and a short run checkpoints,
//! resumes and exports.

mod common;

use sim::{DemoDataset, Family};
use trainer::MetaData;
use trainer::MetaPolicy;
use trainer::Progress;
use trainer::sac::SacConfig;
use trainer::smile::{Smile, SmileConfig};

fn demos(tasks: usize, per_task: usize, horizon: usize) -> DemoDataset {
    common::train_demos(tasks, per_task, horizon)
}

fn tiny(state_only: bool) -> SmileConfig {
    let mut cfg = SmileConfig {
        disc_hidden: vec![32, 32],
        sac: SacConfig {
            hidden: vec![32, 32],
            reward_scale: 8.0,
            ..SacConfig::default()
        },
        tasks_per_batch: 4,
        disc_per_task: 32,
        sac_per_task: 16,
        rollouts_per_iter: 2,
        updates_per_iter: 10,
        total_updates: 20,
        replay_per_task: 2000,
        holdout_every: 4,
        eval_every: 10,
        eval_episodes: 1,
        checkpoint_every: 10,
        horizon: Some(30),
        seed: 3,
        ..SmileConfig::default()
    };
    cfg.context.state_only = state_only;
    cfg.context.enc_hidden = vec![16];
    cfg.context.r_dim = 8;
    cfg.context.z_dim = 4;
    cfg.context.head_hidden = vec![16];
    cfg
}

#[test]
fn discriminator_separates_expert_from_random_policy() {
    trainer::threads::set_compute_threads(1);
    for state_only in [false, true] {
        let ds = demos(8, 2, 30);
        let data = MetaData::from_dataset(&ds, Family::POINT_GOAL, 4).unwrap();
        let mut run = Smile::new(tiny(state_only), data).unwrap();
        // State-only: the discriminator reads [norm(s), norm(s'), z] = 4 + 4 + 4.
        let want = if state_only { 12 } else { 10 };
        assert_eq!(run.disc.net().widths()[0], want);
        assert_eq!(run.encoder.input_dim(), if state_only { 8 } else { 10 });
        run.warm_start().unwrap();
        for _ in 0..2 {
            for ti in 0..run.data().train.len() {
                run.rollout(ti).unwrap();
            }
        }
        let first = run.disc_step().unwrap();
        let (mut acc_e, mut acc_p) = (0.0, 0.0);
        // Measured at 400 steps (seeded, one thread): state-action acc 0.90 / 0.97, bce
        // 0.71 -> 0.31; state-only 0.93 / 1.00, 0.71 -> 0.19.
        for i in 0..400 {
            let s = run.disc_step().unwrap();
            if i >= 380 {
                acc_e += s.acc_expert / 20.0;
                acc_p += s.acc_policy / 20.0;
            }
        }
        let last = run.disc_step().unwrap();
        assert!(
            acc_e > 0.85 && acc_p > 0.85 && last.bce < 0.5 * first.bce,
            "state_only={state_only}: acc expert {acc_e:.2} policy {acc_p:.2}, bce {} -> {}",
            first.bce,
            last.bce
        );
    }
}

#[test]
fn short_run_checkpoints_resumes_and_exports() {
    trainer::threads::set_compute_threads(1);
    let dir = std::env::temp_dir().join(format!("smile-run-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let ds = demos(8, 2, 30);
    let data = MetaData::from_dataset(&ds, Family::POINT_GOAL, 4).unwrap();
    let mut run = Smile::new(tiny(false), data.clone()).unwrap();
    let mut evals = 0;
    trainer::fit(&mut run, &dir, &mut |e| {
        if let Progress::Eval { .. } = e {
            evals += 1;
        }
    })
    .unwrap();
    assert_eq!(run.updates(), 20);
    assert_eq!(evals, 2);
    let mp = MetaPolicy::load(&dir).unwrap();
    assert_eq!(mp.algo, "smile");
    MetaPolicy::load(&dir.join("last")).unwrap();
    let log = std::fs::read_to_string(dir.join("metrics.jsonl")).unwrap();
    assert!(log.contains("losses/disc_bce") && log.contains("eval/val_metric"));
    // Resume to 30 updates: continues from the saved counters and replay.
    let env_steps = run.env_steps();
    let mut resumed = Smile::resume(&dir, data, Some(30)).unwrap();
    assert_eq!((resumed.updates(), resumed.env_steps()), (20, env_steps));
    trainer::fit(&mut resumed, &dir, &mut |_| {}).unwrap();
    assert_eq!(resumed.updates(), 30);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_cpu_budget_stops_the_run_at_an_iteration_end_and_it_resumes() {
    trainer::threads::set_compute_threads(1);
    let dir = std::env::temp_dir().join(format!("smile-budget-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let ds = demos(8, 2, 30);
    let data = MetaData::from_dataset(&ds, Family::POINT_GOAL, 4).unwrap();
    let cfg = SmileConfig {
        total_updates: 1_000_000,
        eval_every: 1000,
        checkpoint_every: 1000,
        // Any work at all exceeds it: the run stops after its first iteration (10 pairs).
        cpu_budget_s: 1e-9,
        ..tiny(false)
    };
    let mut bad = cfg.clone();
    bad.cpu_budget_s = f64::NAN;
    assert!(
        Smile::new(bad, data.clone()).is_err(),
        "a NaN budget is refused"
    );
    let mut run = Smile::new(cfg, data.clone()).unwrap();
    let mut evals = 0;
    trainer::fit(&mut run, &dir, &mut |e| {
        if let Progress::Eval { .. } = e {
            evals += 1;
        }
    })
    .unwrap();
    assert_eq!(run.updates(), 10, "stopped at the first iteration end");
    assert_eq!(evals, 1, "a stopped run evaluates as a finished one does");
    let log = std::fs::read_to_string(dir.join("metrics.jsonl")).unwrap();
    let cpu: f64 = log
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter_map(|v| v["charts/cpu_s"].as_f64())
        .next_back()
        .expect("charts/cpu_s logged");
    assert!(cpu > 0.0);
    MetaPolicy::load(&dir).unwrap();
    MetaPolicy::load(&dir.join("last")).unwrap();
    // The budget counts the whole run: resumed under the same one, it stops again at once.
    let mut again = Smile::resume(&dir, data.clone(), Some(1_000_000)).unwrap();
    trainer::fit(&mut again, &dir, &mut |_| {}).unwrap();
    assert_eq!(
        again.updates(),
        20,
        "one iteration, then the spent budget stops it"
    );
    // Resumed without a budget, it runs to its (new) total; the CPU count carries on.
    let mut resumed = Smile::resume(&dir, data, Some(30)).unwrap();
    assert_eq!(resumed.updates(), 20);
    assert!(resumed.set_cpu_budget(-1.0).is_err());
    resumed.set_cpu_budget(0.0).unwrap();
    trainer::fit(&mut resumed, &dir, &mut |_| {}).unwrap();
    assert_eq!(resumed.updates(), 30);
    let cpus: Vec<f64> = std::fs::read_to_string(dir.join("metrics.jsonl"))
        .unwrap()
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter_map(|v| v["charts/cpu_s"].as_f64())
        .collect();
    assert!(
        cpus.windows(2).all(|w| w[1] >= w[0]) && cpus.len() == 3,
        "charts/cpu_s over the three processes: {cpus:?}"
    );
    // A damaged count is refused, not silently reset to zero.
    std::fs::write(dir.join("compute.json"), "{\"cpu_s\": \"lots\"}").unwrap();
    let data = MetaData::from_dataset(&demos(8, 2, 30), Family::POINT_GOAL, 4).unwrap();
    let Err(e) = Smile::resume(&dir, data, Some(40)) else {
        panic!("a damaged compute.json was accepted")
    };
    assert!(e.to_string().contains("compute.json"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn demos_of_another_family_are_a_typed_error() {
    let data = MetaData::from_dataset(&demos(8, 2, 30), Family::POINT_GOAL, 4).unwrap();
    let cfg = SmileConfig {
        env: Family::CHEETAH_VEL,
        ..tiny(false)
    };
    let Err(e) = Smile::new(cfg, data) else {
        panic!("point-goal demos under a cheetah-vel config were accepted")
    };
    assert!(
        matches!(
            e,
            trainer::Error::WrongFamily { found, expected, .. }
                if found == Family::POINT_GOAL && expected == Family::CHEETAH_VEL
        ),
        "{e}"
    );
    assert!(
        e.to_string()
            .contains("family point-goal, expected cheetah-vel"),
        "{e}"
    );
    // An expert given through the library is refused, not ignored (SMILe learns from the demos
    // alone; the run driver refuses one before this).
    let data = MetaData::from_dataset(&demos(8, 2, 30), Family::POINT_GOAL, 4).unwrap();
    let pd = trainer::expert::Expert::ScriptedPd(sim::PointGoalPdExpert::default());
    let inputs = trainer::MetaInputs {
        data,
        expert: Some(pd.into()),
    };
    let Err(e) = <Smile as trainer::Learner>::start(tiny(true), inputs) else {
        panic!("an expert given to SMILe was ignored")
    };
    assert!(
        e.to_string()
            .contains("smile-state-only learns from the demos alone"),
        "{e}"
    );
}

#[test]
fn learner_threads_are_deterministic_on_any_count_and_use_the_older_reward() {
    trainer::threads::set_compute_threads(1);
    let ds = demos(8, 2, 30);
    let data = MetaData::from_dataset(&ds, Family::POINT_GOAL, 4).unwrap();
    let weights = |threads: usize| {
        // Widths and batches at which the pool splits products (>= 4 MFLOP each): the
        // discriminator's 2 x 4 x 32 rows through 192 x 192, SAC's 4 x 64 rows through 128 x 128.
        // Whole iterations (3 rollouts, then 5 pairs): with two or more threads the rollouts
        // run on the pool beside the pairs.
        let mut cfg = SmileConfig {
            learner_threads: threads,
            disc_hidden: vec![192, 192],
            sac_per_task: 64,
            rollouts_per_iter: 3,
            updates_per_iter: 5,
            total_updates: 1000,
            ..tiny(false)
        };
        cfg.sac.hidden = vec![128, 128];
        let mut run = Smile::new(cfg, data.clone()).unwrap();
        run.warm_start().unwrap();
        let mut rewards = Vec::new();
        for _ in 0..3 {
            let (ds, _, r) = run.iteration(&mut |_| {}).unwrap().last.unwrap();
            assert!(ds.bce.is_finite() && r.is_finite());
            rewards.push(r);
        }
        // Every rollout's steps arrived (warm start: one per task; then 3 per iteration, each
        // the horizon's 30 steps).
        assert_eq!(
            run.env_steps(),
            30 * (run.data().train.len() as u64 + 9),
            "{threads} threads"
        );
        let mut w = Vec::new();
        for net in [run.disc.net(), run.sac.actor.net()] {
            for v in net.vars() {
                w.extend(
                    v.as_tensor()
                        .flatten_all()
                        .unwrap()
                        .to_vec1::<f32>()
                        .unwrap(),
                );
            }
        }
        (w, rewards)
    };
    let (a, ra) = weights(2);
    let (b, rb) = weights(2);
    assert_eq!(a, b, "same seed, two threads: bit-identical weights");
    assert_eq!(ra, rb);
    // Three threads split every large product into three blocks, not two: the same sums.
    let (c, rc) = weights(3);
    assert_eq!(a, c, "two and three learner threads: bit-identical weights");
    assert_eq!(ra, rc);
    let (serial, rs) = weights(1);
    assert_eq!(a.len(), serial.len());
    // A different (still deterministic) run: SAC's reward reads the discriminator one update
    // older, and the draws come in another order.
    assert_ne!(ra, rs);
    assert_ne!(a, serial);
    let bad = SmileConfig {
        learner_threads: 0,
        ..tiny(false)
    };
    let e = Smile::new(bad, data).err().unwrap().to_string();
    assert!(e.contains("learner_threads must be 1 to 256, not 0"), "{e}");
}

#[test]
fn walker_training_rollouts_run_to_the_horizon_unless_termination_is_asked_for() {
    trainer::threads::set_compute_threads(1);
    let tasks: Vec<_> = Family::WALKER_DYN
        .train_tasks()
        .into_iter()
        .take(4)
        .collect();
    let ds = common::open_loop_demos(Family::WALKER_DYN, sim::Split::Train, tasks, 60);
    let data = MetaData::from_dataset(&ds, Family::WALKER_DYN, 0).unwrap();
    let steps = |rollout_termination: bool| {
        let cfg = SmileConfig {
            env: Family::WALKER_DYN,
            rollout_termination,
            horizon: Some(300),
            ..tiny(false)
        };
        let mut run = Smile::new(cfg, data.clone()).unwrap();
        run.warm_start().unwrap(); // one rollout per task with the untrained policy
        run.env_steps()
    };
    // The untrained walker falls within a few dozen steps (healthy height 0.8 m).
    assert_eq!(steps(false), 4 * 300);
    let terminated = steps(true);
    assert!(terminated < 4 * 300 / 2, "{terminated} steps");
}

/// The deterministic actor's squared action error on every expert transition of the training
/// tasks, each task conditioned on its own whole context (posterior mean z).
fn clone_error(run: &Smile) -> f32 {
    let mp = run.meta_policy();
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(0);
    let (mut sum, mut rows) = (0.0f32, 0usize);
    let (od, ad) = (Family::POINT_GOAL.obs_dim(), Family::POINT_GOAL.act_dim());
    for td in &run.data().train {
        let ctx: Vec<_> = td.trajectories.iter().collect();
        let z = mp.latent(&ctx).unwrap();
        for tr in &td.trajectories {
            for k in 0..tr.len() {
                let a = mp
                    .act(&tr.obs[k * od..(k + 1) * od], &z, true, &mut rng)
                    .unwrap();
                let e = &tr.actions[k * ad..(k + 1) * ad];
                sum += a.iter().zip(e).map(|(x, y)| (x - y) * (x - y)).sum::<f32>();
                rows += 1;
            }
        }
    }
    sum / rows as f32
}

/// SMILe + BC (issue 29): the cloning term pulls the actor toward the demos, weight 0 is SMILe
/// bit for bit (the term's machinery draws nothing), and a decayed weight reaches 0.
#[test]
fn bc_term_pulls_the_policy_toward_the_demos_and_weight_zero_is_smile() {
    trainer::threads::set_compute_threads(1);
    let ds = demos(8, 2, 30);
    let data = MetaData::from_dataset(&ds, Family::POINT_GOAL, 4).unwrap();
    let train = |bc_weight: f32, bc_decay_updates: u64, pairs: usize| {
        let cfg = SmileConfig {
            bc_weight,
            bc_decay_updates,
            ..tiny(false)
        };
        let mut run = Smile::new(cfg, data.clone()).unwrap();
        run.warm_start().unwrap();
        let before = clone_error(&run);
        let mut bc_losses = Vec::new();
        for _ in 0..pairs {
            let (_, ss, _) = run.update_pair().unwrap();
            bc_losses.push(ss.bc_loss);
        }
        (run, before, bc_losses)
    };
    let (plain, before, plain_bc) = train(0.0, 0, 150);
    let (cloned, before_bc, bc) = train(4.0, 0, 150);
    assert_eq!(before, before_bc, "same seed, same initial policy");
    assert!(plain_bc.iter().all(Option::is_none));
    assert!(bc.iter().all(Option::is_some));
    let (e_plain, e_bc) = (clone_error(&plain), clone_error(&cloned));
    eprintln!("action error: before {before:.3}, SMILe {e_plain:.3}, SMILe + BC {e_bc:.3}");
    // Measured (seed 3, one thread, 150 pairs, w 4): before 0.550, SMILe 0.555, SMILe + BC 0.224.
    assert!(
        e_bc < 0.5 * e_plain && e_bc < 0.5 * before,
        "action error on the demos: before {before:.3}, SMILe {e_plain:.3}, SMILe + BC {e_bc:.3}"
    );

    // Weight 0 with a decay set is still SMILe: identical weights after the same pairs.
    let (zero, _, _) = train(0.0, 50, 150);
    let w = |r: &Smile| common::flat_values(r.sac.actor.net().vars());
    assert_eq!(w(&zero), w(&plain), "weight 0 must be SMILe bit for bit");

    // Decayed over 40 pairs: the term acts before, and the run is plain SMILe after.
    let cfg = SmileConfig {
        bc_weight: 2.0,
        bc_decay_updates: 40,
        ..tiny(false)
    };
    assert_eq!(cfg.bc_weight_at(0), 2.0);
    assert_eq!(cfg.bc_weight_at(20), 1.0);
    assert_eq!(cfg.bc_weight_at(40), 0.0);
    assert_eq!(cfg.bc_weight_at(1000), 0.0);
    let dir = std::env::temp_dir().join(format!("smile-bc-decay-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut run = Smile::new(
        SmileConfig {
            total_updates: 60,
            ..cfg
        },
        data.clone(),
    )
    .unwrap();
    trainer::fit(&mut run, &dir, &mut |_| {}).unwrap();
    let log = std::fs::read_to_string(dir.join("metrics.jsonl")).unwrap();
    let rows: Vec<serde_json::Value> = log
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .filter(|r: &serde_json::Value| r.get("charts/bc_weight").is_some())
        .collect();
    assert_eq!(rows.len(), 6, "one row per iteration of 10 pairs: {log}");
    for r in &rows {
        let (step, w) = (
            r["step"].as_u64().unwrap(),
            r["charts/bc_weight"].as_f64().unwrap(),
        );
        // The weight of the iteration's last pair, step - 1.
        let want = (2.0 * (1.0 - (step - 1) as f64 / 40.0)).max(0.0);
        assert!(
            (w - want).abs() < 1e-6,
            "step {step}: weight {w}, want {want}"
        );
        assert_eq!(r.get("losses/bc").is_some(), step <= 40, "step {step}: {r}");
    }
    std::fs::remove_dir_all(&dir).ok();

    // State-only has no expert actions to clone.
    let mut so = SmileConfig {
        bc_weight: 1.0,
        ..tiny(true)
    };
    so.context.state_only = true;
    let e = Smile::new(so, data).err().expect("refused").to_string();
    assert!(e.contains("bc_weight") && e.contains("state-only"), "{e}");
}

/// Training through the device's senses (issue 73): an ideal sensor (no noise, no ADC) is
/// SMILe bit for bit (the actor's view path draws nothing and reads the truth), a noisy one
/// trains another policy, and a sensed run is deterministic for its seed.
#[test]
fn sensing_is_deterministic_and_an_ideal_sensor_is_smile() {
    trainer::threads::set_compute_threads(1);
    let ds = demos(8, 2, 30);
    let data = MetaData::from_dataset(&ds, Family::POINT_GOAL, 4).unwrap();
    let train = |sensing: Option<trainer::Sensing>| {
        let cfg = SmileConfig {
            bc_weight: 2.0,
            sensing,
            ..tiny(false)
        };
        let mut run = Smile::new(cfg, data.clone()).unwrap();
        run.warm_start().unwrap();
        for _ in 0..40 {
            run.update_pair().unwrap();
        }
        run.rollout(0).unwrap();
        (clone_error(&run), run.env_steps())
    };
    let sensor = |noise_std: f32, adc_bits: Option<u8>| trainer::Sensing {
        noise_std,
        adc_bits,
        adc_range: 4.0,
        ..trainer::Sensing::default()
    };
    let plain = train(None);
    assert_eq!(train(Some(sensor(0.0, None))), plain, "an ideal sensor");
    let noisy = train(Some(sensor(0.05, Some(8))));
    assert_eq!(train(Some(sensor(0.05, Some(8)))), noisy, "same seed");
    assert_ne!(
        noisy.0, plain.0,
        "the sensors change what the actor trains on"
    );
    let half = train(Some(trainer::Sensing {
        fraction: 0.5,
        ..sensor(0.05, Some(8))
    }));
    assert_ne!(half.0, noisy.0);
    // A section no sensor can read is refused before anything runs.
    let bad = SmileConfig {
        sensing: Some(sensor(-0.1, None)),
        ..tiny(false)
    };
    let e = Smile::new(bad, data).err().unwrap().to_string();
    assert!(e.contains("[sensing]"), "{e}");
}

/// Position-only sensing (issue 73): the rollouts act on the device's estimator, the replay
/// keeps what the policy read beside the truth (in its checkpoint too: the run resumes), the
/// actor trains on those views (another policy than full sensing's), the run is deterministic
/// on one and on two learner threads, and Meta-BC, whose demos are subsampled, refuses it.
#[test]
fn position_sensing_trains_on_the_estimators_views_and_resumes() {
    trainer::threads::set_compute_threads(1);
    let ds = demos(8, 2, 30);
    let data = MetaData::from_dataset(&ds, Family::POINT_GOAL, 4).unwrap();
    let positions = trainer::Sensing {
        noise_std: 0.01,
        adc_bits: Some(12),
        adc_range: 4.0,
        fraction: 0.5,
        positions: true,
        ..trainer::Sensing::default()
    };
    let run_in = |name: &str, cfg: SmileConfig| {
        let dir = std::env::temp_dir().join(format!("smile-pos-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let mut run = Smile::new(cfg, data.clone()).unwrap();
        trainer::fit(&mut run, &dir, &mut |_| {}).unwrap();
        (dir, clone_error(&run))
    };
    let cfg = SmileConfig {
        bc_weight: 2.0,
        sensing: Some(positions),
        ..tiny(false)
    };
    let (dir, first) = run_in("a", cfg.clone());
    let (again, second) = run_in("b", cfg.clone());
    assert_eq!(first, second, "same seed, same policy");
    let full = SmileConfig {
        sensing: Some(trainer::Sensing {
            positions: false,
            ..positions
        }),
        ..cfg.clone()
    };
    let (full_dir, full_error) = run_in("c", full);
    assert_ne!(
        first, full_error,
        "the estimator's views are what the actor trains on"
    );
    let mut resumed = Smile::resume(&dir, data.clone(), Some(30)).unwrap();
    trainer::fit(&mut resumed, &dir, &mut |_| {}).unwrap();
    assert_eq!(resumed.updates(), 30);
    let two = SmileConfig {
        learner_threads: 2,
        ..cfg.clone()
    };
    let (two_a, e_a) = run_in("d", two.clone());
    let (two_b, e_b) = run_in("e", two);
    assert_eq!(e_a, e_b, "two learner threads, same seed");
    for d in [dir, again, full_dir, two_a, two_b] {
        std::fs::remove_dir_all(d).unwrap();
    }
    let bc = trainer::meta_bc::MetaBcConfig {
        sensing: Some(positions),
        ..trainer::meta_bc::MetaBcConfig::default()
    };
    let e = bc.validate().unwrap_err().to_string();
    assert!(e.contains("positions") && e.contains("subsampled"), "{e}");
    // The estimator's tuning without position-only sensing is refused, naming the key.
    let stray = trainer::Sensing {
        accel_std: Some(2.0),
        ..trainer::Sensing::default()
    };
    let e = stray.check().unwrap_err().to_string();
    assert!(
        e.contains("accel_std") && e.contains("positions = true"),
        "{e}"
    );
}

/// Distilling a trained policy through the device's senses (issue 73): the student's action on
/// what the device reads comes closer to the teacher's on the truth, over the student's own
/// closed loops through the estimator; the run is deterministic, and a zero budget is refused.
#[test]
fn distilling_through_the_sensors_closes_the_action_gap() {
    trainer::threads::set_compute_threads(1);
    let ds = demos(8, 2, 30);
    let data = MetaData::from_dataset(&ds, Family::POINT_GOAL, 4).unwrap();
    let mut run = Smile::new(tiny(false), data).unwrap();
    run.warm_start().unwrap();
    for _ in 0..20 {
        run.update_pair().unwrap();
    }
    let teacher = run.meta_policy();
    let sensing = trainer::Sensing {
        noise_std: 0.05,
        adc_range: 4.0,
        positions: true,
        ..trainer::Sensing::default()
    };
    let env = sim::EnvConfig {
        horizon: Some(30),
        ..sim::EnvConfig::default()
    };
    let cfg = trainer::DistillConfig {
        rounds: 2,
        ..trainer::DistillConfig::new(sensing, 300, env)
    };
    let (student, report) = trainer::distill_through_sensing(&teacher, &ds, &cfg).unwrap();
    assert_eq!(
        report.closed_loop_ticks,
        2 * ds.tasks.len() * 30,
        "{report:?}"
    );
    assert!(
        report.action_gap_after < 0.8 * report.action_gap_before,
        "{report:?}"
    );
    let (_, again) = trainer::distill_through_sensing(&teacher, &ds, &cfg).unwrap();
    assert_eq!(again, report, "same seed, same distillation");
    // The student is another actor; the encoder is the teacher's.
    let ctx: Vec<_> = ds.tasks[0].trajectories.iter().collect();
    assert_eq!(student.latent(&ctx).unwrap(), teacher.latent(&ctx).unwrap());
    // One student through two sensors: the second round reads through the noise alone.
    let both = trainer::DistillConfig {
        also: vec![trainer::Sensing {
            positions: false,
            ..sensing
        }],
        ..cfg.clone()
    };
    let (_, two) = trainer::distill_through_sensing(&teacher, &ds, &both).unwrap();
    assert_eq!(two.closed_loop_ticks, report.closed_loop_ticks);
    assert_ne!(two, report, "the second round read through another sensor");
    let zero = trainer::DistillConfig { steps: 0, ..cfg };
    let e = trainer::distill_through_sensing(&teacher, &ds, &zero).unwrap_err();
    assert!(e.to_string().contains("steps"), "{e}");
}
