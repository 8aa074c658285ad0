//! Evaluation outputs and blob export parity on a tiny Meta-BC policy.

mod common;

use sim::{Family, Split};
use trainer::MetaData;
use trainer::eval::{self, EvalReport, Protocol};
use trainer::export::{self, BlobActor};
use trainer::meta_bc::{self, MetaBc, MetaBcConfig};

use common::pd_demos as demos;

#[test]
fn eval_report_and_blob_parity() {
    trainer::threads::set_compute_threads(1);
    let fam = Family::PointGoal;
    let dir = std::env::temp_dir().join(format!("smile-evalexp-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let train = demos(Split::Train, fam.train_tasks()[..8].to_vec(), 2, 20);
    let test = demos(Split::Test, fam.test_tasks(), 2, 20);
    let mut cfg = MetaBcConfig {
        policy_hidden: vec![32, 32],
        tasks_per_batch: 4,
        per_task: 32,
        total_steps: 100,
        holdout_every: 4,
        eval_every: 50,
        eval_episodes: 1,
        horizon: Some(20),
        ..MetaBcConfig::default()
    };
    cfg.context.enc_hidden = vec![16];
    cfg.context.z_dim = 4;
    cfg.context.r_dim = 8;
    let mut run = MetaBc::new(cfg, MetaData::from_dataset(&train, fam, 4).unwrap(), None).unwrap();
    meta_bc::train(&mut run, &dir, &mut |_| {}).unwrap();
    let mut mp = trainer::MetaPolicy::load(&dir).unwrap();

    // Evaluation protocol, report files.
    let proto = Protocol {
        context_sizes: vec![1, 2],
        draws: 2,
        rollouts: 1,
        horizon: Some(20),
    };
    let r = eval::evaluate(
        &mut mp,
        "meta-bc",
        fam,
        Split::Test,
        &test,
        &proto,
        &mut |_, _| {},
    )
    .unwrap();
    assert_eq!(r.tasks.len(), 16);
    assert_eq!(r.by_context_size.len(), 2);
    assert!(r.mean.is_finite() && r.tasks.iter().all(|t| t.metric >= 0.0));
    // Same contexts and seeds: the evaluation is deterministic.
    let r2 = eval::evaluate(
        &mut mp,
        "meta-bc",
        fam,
        Split::Test,
        &test,
        &proto,
        &mut |_, _| {},
    )
    .unwrap();
    assert_eq!(r, r2);
    let report = EvalReport {
        env: "point-goal".into(),
        split: "test".into(),
        metric: "min distance to goal".into(),
        lower_is_better: true,
        protocol: proto.clone(),
        methods: vec![r.clone(), r2],
        reference: None,
    };
    let md = report.markdown();
    assert!(md.contains("goal_angle=0.0982") && md.contains(&format!("{:.3}", r.mean)));
    report.plot_svg(&dir.join("eval.svg")).unwrap();
    assert!(
        std::fs::read_to_string(dir.join("eval.svg"))
            .unwrap()
            .starts_with("<svg")
    );
    // Contexts of another split's tasks are refused.
    assert!(
        eval::evaluate(
            &mut mp,
            "x",
            fam,
            Split::Test,
            &train,
            &proto,
            &mut |_, _| {}
        )
        .is_err()
    );

    // Export: f32 is exact up to float association; int8 schemes stay close.
    for (q, tol, tol_mean) in [
        ("f32", 1e-4f32, 1e-5f32),
        ("w8a32", 0.1, 0.02),
        ("w8a8", 0.5, 0.1),
    ] {
        let blob = export::export_blob(&mp, export::parse_quant(q).unwrap(), Some(&train)).unwrap();
        let model = export::load_blob(&blob).unwrap();
        let mut actor = BlobActor::new(&model).unwrap();
        let p = export::parity(&mp, &mut actor, &test).unwrap();
        assert_eq!(p.contexts, 16);
        assert!(
            p.action_max_abs_diff <= tol && p.action_mean_abs_diff <= tol_mean,
            "{q}: {p:?}"
        );
        if q == "w8a8" {
            let rep = export::verify(&mp, &blob, q, &test, &proto).unwrap();
            assert_eq!(rep.parity, p);
            assert_eq!(rep.bytes, blob.len());
            assert!((rep.metric_candle - r.mean).abs() < 1e-6);
            let (b, c) = (rep.metric_blob, rep.metric_candle);
            assert!((b - c).abs() < 0.25 * c.max(0.1), "blob {b} vs candle {c}");
        }
    }
    assert!(export::parse_quant("w4").is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}
