//! The validator against crafted blobs: the writer makes a valid blob, one field of its
//! decoded payload is changed, the payload is re-encoded behind a fresh envelope (length and
//! CRC recomputed, so the envelope checks pass) and the loader must name that exact fault.

extern crate alloc;

use alloc::vec::Vec;

use serde::Serialize;

use super::*;
use crate::format::Bytes;
use crate::{Calibration, Dims, FloatModel, ModelKind, write_blob};

const DIMS: Dims = Dims {
    obs: 4,
    act: 2,
    r: 8,
    z: 4,
    hidden: 8,
};

fn float() -> FloatModel {
    FloatModel::random(ModelKind::StateAction, DIMS, 11)
}

fn calibration() -> Calibration {
    let row = |n: usize, k: usize| -> Vec<f32> {
        (0..n)
            .map(|i| ((i * 5 + k * 3) % 7) as f32 / 3.5 - 1.0)
            .collect()
    };
    Calibration {
        contexts: (0..3)
            .map(|c| alloc::vec![(0..4).map(|t| row(10, c * 4 + t)).collect()])
            .collect(),
        observations: (0..8).map(|k| row(4, k)).collect(),
    }
}

fn blob(model: &FloatModel, quant: Quant) -> Vec<u8> {
    write_blob(model, quant, &calibration()).unwrap()
}

fn decode(blob: &[u8]) -> Payload<'_> {
    Model::from_bytes(blob).unwrap().payload
}

/// The payload bytes behind a valid envelope (version, length and CRC of these bytes).
fn seal(body: &[u8]) -> Vec<u8> {
    let mut out = MAGIC.to_vec();
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&(body.len() as u32).to_le_bytes());
    out.extend_from_slice(&format::crc32(body).to_le_bytes());
    out.extend_from_slice(body);
    out
}

/// Re-encodes `payload` as a blob and loads it.
fn reload(payload: &impl Serialize) -> Result<()> {
    let bytes = seal(&postcard::to_allocvec(payload).unwrap());
    Model::from_bytes(&bytes).map(|_| ())
}

fn f32_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

#[test]
fn a_decoded_payload_re_encodes_to_the_same_valid_blob() {
    for quant in [Quant::F32, Quant::W8A32, Quant::W8A8] {
        let good = blob(&float(), quant);
        let body = postcard::to_allocvec(&decode(&good)).unwrap();
        assert_eq!(seal(&body), good, "{quant:?}");
    }
}

#[test]
fn non_finite_values_are_refused_naming_the_part() {
    let nan = f32_bytes(&[f32::NAN; 4]);
    let inf_pair = f32_bytes(&[1.0, f32::INFINITY]);
    let good = blob(&float(), Quant::F32);
    let q8 = blob(&float(), Quant::W8A32);
    {
        let mut p = decode(&good);
        p.obs_mean = Bytes(&nan);
        assert_eq!(reload(&p), Err(Error::NonFinite { part: "obs_mean" }));
    }
    {
        let mut p = decode(&good);
        p.act_offset = Bytes(&inf_pair);
        assert_eq!(reload(&p), Err(Error::NonFinite { part: "act_offset" }));
    }
    let mut weights = decode(&good).encoder[1].weights.0.to_vec();
    weights[4..8].copy_from_slice(&f32::NAN.to_le_bytes());
    {
        let mut p = decode(&good);
        p.encoder[1].weights = Bytes(&weights);
        assert_eq!(reload(&p), Err(Error::NonFinite { part: "encoder" }));
    }
    {
        let mut p = decode(&good);
        p.policy[2].bias = Bytes(&inf_pair);
        assert_eq!(reload(&p), Err(Error::NonFinite { part: "policy" }));
    }
    // z_head: one r -> z layer, so its weight scales are `z` floats.
    {
        let mut p = decode(&q8);
        p.z_head[0].weight_scale = Bytes(&nan);
        assert_eq!(reload(&p), Err(Error::NonFinite { part: "z_head" }));
    }
}

#[test]
fn non_positive_scales_are_refused_naming_the_part() {
    let zero_std = f32_bytes(&[1.0, 0.0, 1.0, 1.0]);
    let negative_std = f32_bytes(&[1.0, 1.0, 1.0, -0.5]);
    let good = blob(&float(), Quant::F32);
    for std in [&zero_std, &negative_std] {
        let mut p = decode(&good);
        p.obs_std = Bytes(std);
        assert_eq!(reload(&p), Err(Error::NonPositiveScale { part: "obs_std" }));
    }
    let q8 = blob(&float(), Quant::W8A32);
    let mut scales = decode(&q8).encoder[0].weight_scale.0.to_vec();
    scales[..4].copy_from_slice(&0.0f32.to_le_bytes());
    {
        let mut p = decode(&q8);
        p.encoder[0].weight_scale = Bytes(&scales);
        assert_eq!(reload(&p), Err(Error::NonPositiveScale { part: "encoder" }));
    }
    let a8 = blob(&float(), Quant::W8A8);
    // The policy's first layer has one scale per input, its hidden layer a single one.
    let in_dim = decode(&a8).policy[0].in_dim as usize;
    assert_eq!(decode(&a8).policy[0].input_scale.0.len(), 4 * in_dim);
    assert_eq!(decode(&a8).policy[1].input_scale.0.len(), 4);
    for (bad, want) in [
        (0.0, Error::NonPositiveScale { part: "policy" }),
        (-1.0, Error::NonPositiveScale { part: "policy" }),
        (f32::NAN, Error::NonFinite { part: "policy" }),
    ] {
        let mut scales = decode(&a8).policy[0].input_scale.0.to_vec();
        scales[4 * (in_dim - 1)..].copy_from_slice(&bad.to_le_bytes());
        let mut p = decode(&a8);
        p.policy[0].input_scale = Bytes(&scales);
        assert_eq!(reload(&p), Err(want), "input scale {bad}");
    }
    // One input scale per input channel or a single one; any other count is refused.
    let two = f32_bytes(&[0.1, 0.2]);
    let mut p = decode(&a8);
    p.policy[0].input_scale = Bytes(&two);
    let first_in = decode(&a8).policy[0].in_dim as usize;
    assert_eq!(
        reload(&p),
        Err(Error::TensorLength {
            part: "policy",
            expected: 4 * first_in,
            found: 8
        })
    );
    // Unsigned inputs exist only in w8a8 blobs.
    let mut p = decode(&q8);
    p.policy[1].unsigned_input = true;
    assert!(matches!(
        reload(&p),
        Err(Error::TensorLength { part: "policy", .. })
    ));
}

#[test]
fn tensor_lengths_that_disagree_with_the_shape_are_refused() {
    let good = blob(&float(), Quant::F32);
    let short_mean = f32_bytes(&[0.0; 3]);
    {
        let mut p = decode(&good);
        p.obs_mean = Bytes(&short_mean);
        assert_eq!(
            reload(&p),
            Err(Error::TensorLength {
                part: "obs_mean",
                expected: 16,
                found: 12
            })
        );
    }
    let stray_scale = f32_bytes(&[1.0]);
    {
        let mut p = decode(&good);
        p.z_head[0].weight_scale = Bytes(&stray_scale);
        assert_eq!(
            reload(&p),
            Err(Error::TensorLength {
                part: "z_head",
                expected: 0,
                found: 4
            })
        );
    }
    // w8a32 encoder layer 0: 8 outputs x 10 inputs, one byte each.
    let q8 = blob(&float(), Quant::W8A32);
    let long_weights = alloc::vec![1u8; 81];
    {
        let mut p = decode(&q8);
        p.encoder[0].weights = Bytes(&long_weights);
        assert_eq!(
            reload(&p),
            Err(Error::TensorLength {
                part: "encoder",
                expected: 80,
                found: 81
            })
        );
    }
    let short_bias = f32_bytes(&[0.0]);
    {
        let mut p = decode(&q8);
        p.policy[2].bias = Bytes(&short_bias);
        assert_eq!(
            reload(&p),
            Err(Error::TensorLength {
                part: "policy",
                expected: 8,
                found: 4
            })
        );
    }
}

/// The payload with plain lists of layers, so a test can store more than `MAX_LAYERS`
/// (postcard encodes a `heapless::Vec` and a `Vec` alike: a length, then the items).
#[derive(Serialize)]
struct LongPayload<'a> {
    header: Header,
    obs_mean: Bytes<'a>,
    obs_std: Bytes<'a>,
    act_scale: Bytes<'a>,
    act_offset: Bytes<'a>,
    encoder: Vec<LayerRecord<'a>>,
    z_head: Vec<LayerRecord<'a>>,
    policy: Vec<LayerRecord<'a>>,
}

impl<'a> LongPayload<'a> {
    fn of(p: &Payload<'a>) -> Self {
        Self {
            header: p.header,
            obs_mean: p.obs_mean,
            obs_std: p.obs_std,
            act_scale: p.act_scale,
            act_offset: p.act_offset,
            encoder: p.encoder.to_vec(),
            z_head: p.z_head.to_vec(),
            policy: p.policy.to_vec(),
        }
    }
}

#[test]
fn more_layers_than_the_format_allows_are_refused_by_name() {
    // The z head as MAX_LAYERS chained r -> r ... -> z layers: the limit itself loads.
    let mut model = float();
    let square = |n: usize| crate::FloatLayer {
        in_dim: n,
        out_dim: n,
        weights: (0..n * n)
            .map(|i| if i % (n + 1) == 0 { 1.0 } else { 0.0 })
            .collect(),
        bias: alloc::vec![0.0; n],
        activation: Activation::Identity,
    };
    let last = model.z_head.pop().unwrap();
    model.z_head = (1..MAX_LAYERS).map(|_| square(DIMS.r)).collect();
    model.z_head.push(last);
    let at_limit = blob(&model, Quant::F32);
    let payload = decode(&at_limit);
    assert_eq!(payload.z_head.len(), MAX_LAYERS);
    assert_eq!(reload(&LongPayload::of(&payload)), Ok(()));

    // One more layer: the writer refuses it, and a crafted blob is refused by the loader.
    model.z_head.insert(0, square(DIMS.r));
    assert_eq!(
        write_blob(&model, Quant::F32, &calibration()),
        Err(crate::Error::TooManyLayers {
            part: "z_head",
            found: MAX_LAYERS + 1
        })
    );
    let mut long = LongPayload::of(&payload);
    long.z_head.insert(0, long.z_head[0]);
    assert_eq!(
        reload(&long),
        Err(Error::TooManyLayers {
            part: "z_head",
            found: MAX_LAYERS + 1
        })
    );
    let mut long = LongPayload::of(&payload);
    let extra = long.encoder[1];
    long.encoder.insert(1, extra);
    long.encoder.insert(1, extra);
    assert_eq!(
        reload(&long),
        Err(Error::TooManyLayers {
            part: "encoder",
            found: 5
        })
    );
}

#[test]
fn edge_layers_take_their_own_precision_and_none_is_coarser_than_the_header() {
    let options = crate::WriteOptions {
        edges: Some(Quant::W8A32),
        ..Default::default()
    };
    let mixed = crate::write_blob_with(&float(), Quant::W8A8, &calibration(), &options).unwrap();
    let p = decode(&mixed);
    assert_eq!(p.header.quant, Quant::W8A8);
    for (part, layers) in [
        ("encoder", &p.encoder),
        ("z_head", &p.z_head),
        ("policy", &p.policy),
    ] {
        let last = layers.len() - 1;
        for (i, l) in layers.iter().enumerate() {
            let want = if i == 0 || i == last {
                Quant::W8A32
            } else {
                Quant::W8A8
            };
            assert_eq!(l.quant, want, "{part} layer {i}");
        }
    }
    // The edges' precision is their own: the same layers of a whole-w8a32 blob, byte for byte.
    let w8a32 = blob(&float(), Quant::W8A32);
    assert_eq!(p.policy[0], decode(&w8a32).policy[0]);
    // A layer coarser than the header is refused by name, before it runs.
    let plain = blob(&float(), Quant::W8A32);
    let a8 = blob(&float(), Quant::W8A8);
    let mut p = decode(&plain);
    p.policy[1] = decode(&a8).policy[1];
    assert_eq!(
        reload(&p),
        Err(Error::LayerBelowHeader {
            part: "policy",
            layer: Quant::W8A8,
            header: Quant::W8A32
        })
    );
    // The context encoder and z head kept finer throughout (they run once per teaching): every
    // one of their layers, the policy's hidden layers still int8.
    let context = crate::WriteOptions {
        edges: Some(Quant::W8A32),
        context: Some(Quant::W8A32),
        ..Default::default()
    };
    let ctx = crate::write_blob_with(&float(), Quant::W8A8, &calibration(), &context).unwrap();
    let model = Model::from_bytes(&ctx).unwrap();
    for mlp in [crate::Mlp::Encoder, crate::Mlp::ZHead] {
        assert!(
            model.layer_quants(mlp).all(|q| q == Quant::W8A32),
            "{mlp:?}"
        );
    }
    let policy: Vec<Quant> = model.layer_quants(crate::Mlp::Policy).collect();
    assert_eq!(policy, [Quant::W8A32, Quant::W8A8, Quant::W8A32]);
    // The writer refuses edges coarser than the blob.
    let coarse = crate::WriteOptions {
        edges: Some(Quant::W8A8),
        ..Default::default()
    };
    assert_eq!(
        crate::write_blob_with(&float(), Quant::W8A32, &calibration(), &coarse),
        Err(crate::Error::FinerBelowQuant {
            asked: Quant::W8A8,
            quant: Quant::W8A32
        })
    );
}
