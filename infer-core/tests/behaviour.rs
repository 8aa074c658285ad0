//! What the runners do with good and bad inputs.

mod common;

use common::{Rng, blob_act, blob_latent, context, model};
use infer_core::{Calibration, ContextEncoder, Error, Model, ModelKind, Policy, Quant, write_blob};

fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

#[test]
fn f32_blob_matches_the_float_reference() {
    for kind in [ModelKind::StateAction, ModelKind::StateOnly] {
        let float = model(kind, 64, 1);
        let blob = write_blob(&float, Quant::F32, &Calibration::default()).unwrap();
        let m = Model::from_bytes(&blob).unwrap();
        let mut rng = Rng(7);
        for n in 1..=4 {
            let ctx = context(&mut rng, &float, n);
            let z = blob_latent(&m, &ctx);
            assert!(
                max_abs_diff(&z, &float.latent(&ctx)) < 1e-4,
                "{kind:?} z with {n} trajectories"
            );
            let obs = rng.vec(20, 1.5);
            assert!(max_abs_diff(&blob_act(&m, &obs, &z), &float.act(&obs, &z)) < 1e-5);
        }
    }
}

#[test]
fn encoder_is_permutation_invariant() {
    let float = model(ModelKind::StateAction, 64, 2);
    let blob = write_blob(&float, Quant::F32, &Calibration::default()).unwrap();
    let m = Model::from_bytes(&blob).unwrap();
    let mut rng = Rng(3);
    let ctx = context(&mut rng, &float, 4);
    let z = blob_latent(&m, &ctx);
    let mut shuffled: Vec<Vec<Vec<f32>>> = ctx.iter().rev().cloned().collect();
    shuffled.swap(0, 2);
    for trajectory in &mut shuffled {
        trajectory.reverse();
    }
    let z_shuffled = blob_latent(&m, &shuffled);
    // Equal up to float re-association only.
    assert!(max_abs_diff(&z, &z_shuffled) < 1e-4);
    assert_ne!(
        z,
        blob_latent(&m, &ctx[..2]),
        "a different context must give a different z"
    );
}

#[test]
fn open_trajectory_counts_like_a_closed_one_and_reset_forgets() {
    let float = model(ModelKind::StateAction, 64, 4);
    let blob = write_blob(&float, Quant::W8A32, &Calibration::default()).unwrap();
    let m = Model::from_bytes(&blob).unwrap();
    let ctx = context(&mut Rng(5), &float, 1);
    let closed = blob_latent(&m, &ctx);
    let mut enc = ContextEncoder::<64>::new(&m).unwrap();
    let mut z = vec![0.0; 16];
    assert_eq!(enc.latent(&mut z), Err(Error::EmptyContext));
    for t in &ctx[0] {
        enc.push(&t[..20], &t[20..26], &t[26..]).unwrap();
    }
    enc.latent(&mut z).unwrap();
    assert_eq!(z, closed);
    assert_eq!(enc.trajectories(), 0);
    enc.reset();
    assert_eq!(enc.latent(&mut z), Err(Error::EmptyContext));
}

#[test]
fn bad_inputs_give_errors_and_a_safe_action() {
    let mut float = model(ModelKind::StateAction, 64, 6);
    float.act_offset = vec![0.25; 6];
    let blob = write_blob(&float, Quant::F32, &Calibration::default()).unwrap();
    let m = Model::from_bytes(&blob).unwrap();
    let mut policy = Policy::<64>::new(&m).unwrap();
    let z = vec![0.1; 16];
    let mut action = [9.0f32; 6];
    let mut obs = vec![0.0; 20];
    obs[3] = f32::NAN;
    assert_eq!(
        policy.act(&obs, &z, &mut action),
        Err(Error::NonFiniteInput { input: "obs" })
    );
    assert_eq!(action, [0.25; 6]);
    obs[3] = f32::INFINITY;
    action = [9.0; 6];
    assert!(policy.act(&obs, &z, &mut action).is_err());
    assert_eq!(action, [0.25; 6]);
    assert!(matches!(
        policy.act(&obs[..19], &z, &mut action),
        Err(Error::WrongLength { input: "obs", .. })
    ));
    assert!(matches!(
        policy.act(&[0.0; 20], &z, &mut [0.0; 5]),
        Err(Error::WrongLength {
            input: "action",
            ..
        })
    ));
    let mut enc = ContextEncoder::<64>::new(&m).unwrap();
    assert!(enc.push(&obs, &[0.0; 6], &[0.0; 20]).is_err());
    assert!(matches!(
        enc.push(&[0.0; 20], &[0.0; 5], &[0.0; 20]),
        Err(Error::WrongLength {
            input: "action",
            ..
        })
    ));
    assert_eq!(
        enc.open_steps(),
        0,
        "refused transitions must not be accumulated"
    );
}

#[test]
fn runner_capacity_is_checked_before_running() {
    let float = model(ModelKind::StateAction, 128, 8);
    let blob = write_blob(
        &float,
        Quant::W8A8,
        &common::calibration(&mut Rng(1), &float),
    )
    .unwrap();
    let m = Model::from_bytes(&blob).unwrap();
    assert_eq!(m.max_width(), 128);
    assert_eq!(
        Policy::<64>::new(&m).err(),
        Some(Error::CapacityExceeded {
            needed: 128,
            capacity: 64
        })
    );
    assert!(ContextEncoder::<64>::new(&m).is_err());
    assert!(Policy::<128>::new(&m).is_ok());
}

#[test]
fn same_inputs_give_identical_bits() {
    let float = model(ModelKind::StateOnly, 64, 9);
    for quant in [Quant::F32, Quant::W8A32, Quant::W8A8] {
        let blob = write_blob(&float, quant, &common::calibration(&mut Rng(2), &float)).unwrap();
        assert_eq!(
            blob,
            write_blob(&float, quant, &common::calibration(&mut Rng(2), &float)).unwrap()
        );
        let m = Model::from_bytes(&blob).unwrap();
        let ctx = context(&mut Rng(11), &float, 3);
        let z1 = blob_latent(&m, &ctx);
        let z2 = blob_latent(&m, &ctx);
        assert_eq!(
            z1.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            z2.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
        let obs = Rng(12).vec(20, 1.0);
        let (a1, a2) = (blob_act(&m, &obs, &z1), blob_act(&m, &obs, &z2));
        assert_eq!(
            a1.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            a2.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
    }
}

#[test]
fn writer_refuses_bad_models() {
    let mut float = model(ModelKind::StateAction, 32, 10);
    assert_eq!(
        write_blob(&float, Quant::W8A8, &Calibration::default()),
        Err(infer_core::Error::MissingCalibration)
    );
    float.policy[0].weights[0] = f32::NAN;
    assert!(matches!(
        write_blob(&float, Quant::F32, &Calibration::default()),
        Err(infer_core::Error::NonFinite { .. })
    ));
    let mut float = model(ModelKind::StateAction, 32, 10);
    float.obs_std[0] = 0.0;
    assert!(write_blob(&float, Quant::F32, &Calibration::default()).is_err());
}
