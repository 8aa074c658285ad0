//! The writer's answer to inputs that do not fit the model: a named `Error` saying
//! what was expected and what came, never a panic (a user once got "range end index 17 out
//! of range for slice of length 10" from the (since removed) equaliser for point-goal calibration rows given
//! to a cheetah-sized model).

use infer_core::{
    Activation, Calibration, Dims, Error, FloatLayer, FloatModel, ModelKind, Quant, write_blob,
};
use proptest::prelude::*;

/// Cheetah-sized observations and actions, small hidden layers.
const DIMS: Dims = Dims {
    obs: 17,
    act: 6,
    r: 8,
    z: 4,
    hidden: 8,
};

fn model(kind: ModelKind) -> FloatModel {
    FloatModel::random(kind, DIMS, 4)
}

fn transition_dim(kind: ModelKind) -> usize {
    match kind {
        ModelKind::StateAction => 2 * DIMS.obs + DIMS.act,
        ModelKind::StateOnly => 2 * DIMS.obs,
    }
}

fn row(n: usize, k: usize) -> Vec<f32> {
    (0..n)
        .map(|i| ((i * 3 + k * 5) % 9) as f32 / 4.0 - 1.0)
        .collect()
}

/// Three contexts of two trajectories of four transitions of `t_dim`; eight observations of
/// `obs_dim`.
fn calibration(t_dim: usize, obs_dim: usize) -> Calibration {
    Calibration {
        contexts: (0..3)
            .map(|c| {
                (0..2)
                    .map(|j| (0..4).map(|t| row(t_dim, c * 8 + j * 4 + t)).collect())
                    .collect()
            })
            .collect(),
        observations: (0..8).map(|k| row(obs_dim, k)).collect(),
    }
}

fn good(kind: ModelKind) -> Calibration {
    calibration(transition_dim(kind), DIMS.obs)
}

#[test]
fn the_good_calibration_writes() {
    for kind in [ModelKind::StateAction, ModelKind::StateOnly] {
        assert!(write_blob(&model(kind), Quant::W8A8, &good(kind)).is_ok());
    }
}

#[test]
fn observation_rows_of_another_dimension_are_named_not_a_panic() {
    for kind in [ModelKind::StateAction, ModelKind::StateOnly] {
        let mut short = good(kind);
        short.observations[0] = row(10, 0);
        let err = write_blob(&model(kind), Quant::W8A8, &short).unwrap_err();
        assert_eq!(
            err,
            Error::CalibrationLength {
                what: "observation",
                index: 0,
                expected: 17,
                got: 10
            }
        );
        assert_eq!(
            err.to_string(),
            "calibration observation 0: length 10, the model needs 17"
        );
        let mut long = good(kind);
        long.observations[5] = row(18, 5);
        assert_eq!(
            write_blob(&model(kind), Quant::W8A8, &long),
            Err(Error::CalibrationLength {
                what: "observation",
                index: 5,
                expected: 17,
                got: 18
            })
        );
    }
}

#[test]
fn context_transitions_of_another_width_are_named_not_a_panic() {
    let (sa, so) = (ModelKind::StateAction, ModelKind::StateOnly);
    let transition = |index, expected, got| Error::CalibrationLength {
        what: "context transition",
        index,
        expected,
        got,
    };
    // The reported case: point-goal transitions (4 + 2 + 4) for a 17-dimensional model.
    let point_goal = calibration(10, DIMS.obs);
    let err = write_blob(&model(sa), Quant::W8A8, &point_goal).unwrap_err();
    assert_eq!(err, transition(0, 40, 10));
    assert_eq!(
        err.to_string(),
        "calibration context transition in context 0: length 10, the model needs 40"
    );
    // State-only rows for a state-action model and the other way round.
    assert_eq!(
        write_blob(&model(sa), Quant::W8A8, &good(so)),
        Err(transition(0, 40, 34))
    );
    assert_eq!(
        write_blob(&model(so), Quant::W8A8, &good(sa)),
        Err(transition(0, 34, 40))
    );
    // One action one component short, deep in the third context.
    let mut one_bad = good(sa);
    one_bad.contexts[2][1][3] = row(2 * DIMS.obs + DIMS.act - 1, 0);
    assert_eq!(
        write_blob(&model(sa), Quant::W8A8, &one_bad),
        Err(transition(2, 40, 39))
    );
}

#[test]
fn non_finite_calibration_values_are_refused() {
    let kind = ModelKind::StateAction;
    let mut bad = good(kind);
    bad.observations[3][2] = f32::NAN;
    assert_eq!(
        write_blob(&model(kind), Quant::W8A8, &bad),
        Err(Error::NonFinite {
            part: "calibration observations"
        })
    );
    let mut bad = good(kind);
    bad.contexts[1][0][2][7] = f32::INFINITY;
    assert_eq!(
        write_blob(&model(kind), Quant::W8A8, &bad),
        Err(Error::NonFinite {
            part: "calibration contexts"
        })
    );
}

#[test]
fn calibration_is_only_checked_where_it_is_used() {
    let kind = ModelKind::StateAction;
    let wrong = calibration(10, 4);
    for quant in [Quant::F32, Quant::W8A32] {
        assert!(write_blob(&model(kind), quant, &wrong).is_ok(), "{quant:?}");
    }
}

fn square(n: usize) -> FloatLayer {
    FloatLayer {
        in_dim: n,
        out_dim: n,
        weights: vec![0.1; n * n],
        bias: vec![0.0; n],
        activation: Activation::Relu,
    }
}

#[test]
fn layers_that_do_not_chain_are_named_not_a_panic() {
    let kind = ModelKind::StateAction;
    let calib = good(kind);
    let width = |part, layer, side, expected, got| Error::LayerWidth {
        part,
        layer,
        side,
        expected,
        got,
    };
    for quant in [Quant::F32, Quant::W8A8] {
        let mut m = model(kind);
        m.encoder[1] = FloatLayer {
            in_dim: 9,
            ..square(9)
        };
        m.encoder[1].out_dim = 8;
        m.encoder[1].weights.truncate(72);
        m.encoder[1].bias.truncate(8);
        assert_eq!(
            write_blob(&m, quant, &calib),
            Err(width("encoder", 1, "input", 8, 9))
        );
        let mut m = model(kind);
        m.policy[0] = FloatLayer {
            in_dim: DIMS.obs,
            out_dim: 8,
            weights: vec![0.1; DIMS.obs * 8],
            bias: vec![0.0; 8],
            activation: Activation::Relu,
        };
        assert_eq!(
            write_blob(&m, quant, &calib),
            Err(width("policy", 0, "input", 21, 17))
        );
        let mut m = model(kind);
        m.z_head = vec![square(DIMS.r)];
        assert_eq!(
            write_blob(&m, quant, &calib),
            Err(width("z_head", 0, "output", 4, 8))
        );
        // A zero-wide hidden layer (the next layer reading width 0 would chain).
        let mut m = model(kind);
        m.encoder[0].out_dim = 0;
        m.encoder[0].weights.clear();
        m.encoder[0].bias.clear();
        m.encoder[1] = FloatLayer {
            in_dim: 0,
            weights: vec![],
            ..square(8)
        };
        assert_eq!(
            write_blob(&m, quant, &calib),
            Err(width("encoder", 0, "output", 1, 0))
        );
        let mut m = model(kind);
        m.policy.clear();
        assert_eq!(
            write_blob(&m, quant, &calib),
            Err(Error::EmptyMlp { part: "policy" })
        );
        let mut m = model(kind);
        m.z_dim = 0;
        assert!(matches!(
            write_blob(&m, quant, &calib),
            Err(Error::Shape(_))
        ));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any mix of row lengths gives a blob exactly when every row fits, and otherwise the
    /// named length error, never a panic.
    #[test]
    fn any_row_lengths_give_a_blob_or_a_length_error(
        state_only in any::<bool>(),
        obs_len in prop::collection::vec(prop_oneof![Just(17usize), 0usize..48], 1..6),
        t_len in prop::collection::vec(prop_oneof![Just(40usize), Just(34usize), 0usize..48], 1..6),
    ) {
        let kind = if state_only { ModelKind::StateOnly } else { ModelKind::StateAction };
        let t_dim = transition_dim(kind);
        let calib = Calibration {
            contexts: t_len.iter().enumerate().map(|(k, &n)| vec![vec![row(n, k)]]).collect(),
            observations: obs_len.iter().enumerate().map(|(k, &n)| row(n, k)).collect(),
        };
        let fits = obs_len.iter().all(|&n| n == DIMS.obs) && t_len.iter().all(|&n| n == t_dim);
        match write_blob(&model(kind), Quant::W8A8, &calib) {
            Ok(_) => prop_assert!(fits),
            Err(Error::CalibrationLength { expected, got, .. }) => {
                prop_assert!(!fits);
                prop_assert_ne!(expected, got);
            }
            Err(other) => prop_assert!(false, "unexpected {:?}", other),
        }
    }
}

/// Issue 57, item 9: a network with a parameter of 3e38 (finite, but beyond what the blob's
/// scales and sums can hold) is refused by name, for every scheme, instead of writing a blob
/// that fails to load back.
#[test]
fn a_parameter_too_large_for_the_blob_is_refused_by_layer() {
    for quant in [Quant::F32, Quant::W8A32, Quant::W8A8] {
        let mut m = model(ModelKind::StateAction);
        m.policy[1].weights[3] = 3e38;
        let e = write_blob(&m, quant, &good(ModelKind::StateAction)).unwrap_err();
        assert!(
            matches!(
                e,
                Error::OutOfRange {
                    part: "policy",
                    layer: 1,
                    ..
                }
            ),
            "{quant:?}: {e}"
        );
        assert!(e.to_string().contains("policy layer 1"), "{e}");
    }
}
