//! The two ONNX graphs, node by node, from the blob's float structure.

use onnx_protobuf::attribute_proto::AttributeType;
use onnx_protobuf::tensor_proto::DataType;
use onnx_protobuf::tensor_shape_proto::{Dimension, dimension};
use onnx_protobuf::type_proto;
use onnx_protobuf::{
    AttributeProto, GraphProto, Message, ModelProto, NodeProto, OperatorSetIdProto,
    StringStringEntryProto, TensorProto, TensorShapeProto, TypeProto, ValueInfoProto,
};
use protobuf::{EnumOrUnknown, MessageField};

use super::{
    ENCODER_FILE, GraphInfo, IR_VERSION, Normalisation, OPSET, OnnxExport, OnnxMeta, POLICY_FILE,
    TensorInfo, names,
};
use crate::error::{Error, Result};
use crate::model::MetaPolicy;

fn dims_i64(dims: &[usize]) -> Vec<i64> {
    dims.iter().map(|&d| d as i64).collect()
}

/// One axis of a graph input or output: a size or a symbolic name.
#[derive(Clone, Copy)]
enum Axis {
    Fixed(usize),
    Named(&'static str),
}

fn value_info(name: &str, shape: &[Axis]) -> ValueInfoProto {
    let dim = shape
        .iter()
        .map(|a| Dimension {
            value: Some(match a {
                Axis::Fixed(n) => dimension::Value::DimValue(*n as i64),
                Axis::Named(s) => dimension::Value::DimParam((*s).into()),
            }),
            ..Default::default()
        })
        .collect();
    let tensor = type_proto::Tensor {
        elem_type: DataType::FLOAT as i32,
        shape: MessageField::some(TensorShapeProto {
            dim,
            ..Default::default()
        }),
        ..Default::default()
    };
    ValueInfoProto {
        name: name.into(),
        type_: MessageField::some(TypeProto {
            value: Some(type_proto::Value::TensorType(tensor)),
            ..Default::default()
        }),
        ..Default::default()
    }
}

fn tensor_info(name: &str, shape: &[Axis]) -> TensorInfo {
    TensorInfo {
        name: name.into(),
        dtype: "float32".into(),
        shape: shape
            .iter()
            .map(|a| match a {
                Axis::Fixed(n) => serde_json::json!(n),
                Axis::Named(s) => serde_json::json!(s),
            })
            .collect(),
    }
}

fn int_attr(name: &str, v: i64) -> AttributeProto {
    AttributeProto {
        name: name.into(),
        type_: EnumOrUnknown::new(AttributeType::INT),
        i: v,
        ..Default::default()
    }
}

/// A graph under construction: nodes in topological order and their initializers.
struct Builder {
    prefix: &'static str,
    nodes: Vec<NodeProto>,
    initializers: Vec<TensorProto>,
    count: usize,
}

impl Builder {
    fn new(prefix: &'static str) -> Self {
        Self {
            prefix,
            nodes: Vec::new(),
            initializers: Vec::new(),
            count: 0,
        }
    }

    fn fresh(&mut self, what: &str) -> String {
        self.count += 1;
        format!("{}/{what}_{}", self.prefix, self.count)
    }

    /// A float constant of shape `dims` (row-major `data`).
    fn constant(&mut self, what: &str, dims: &[usize], data: &[f32]) -> String {
        let name = self.fresh(what);
        self.initializers.push(TensorProto {
            name: name.clone(),
            dims: dims_i64(dims),
            data_type: DataType::FLOAT as i32,
            raw_data: data.iter().flat_map(|v| v.to_le_bytes()).collect(),
            ..Default::default()
        });
        name
    }

    /// An int64 constant (reduction and unsqueeze axes).
    fn axes(&mut self, axes: &[i64]) -> String {
        let name = self.fresh("axes");
        self.initializers.push(TensorProto {
            name: name.clone(),
            dims: vec![axes.len() as i64],
            data_type: DataType::INT64 as i32,
            raw_data: axes.iter().flat_map(|v| v.to_le_bytes()).collect(),
            ..Default::default()
        });
        name
    }

    /// Appends `op(inputs)` with `attrs`; its output is `out`, or a fresh name.
    fn op(
        &mut self,
        op: &str,
        inputs: &[&str],
        attrs: Vec<AttributeProto>,
        out: Option<&str>,
    ) -> String {
        let output = match out {
            Some(o) => o.to_string(),
            None => self.fresh(&op.to_lowercase()),
        };
        self.nodes.push(NodeProto {
            name: format!("{}/{op}_{}", self.prefix, self.nodes.len()),
            op_type: op.into(),
            input: inputs.iter().map(|s| s.to_string()).collect(),
            output: vec![output.clone()],
            attribute: attrs,
            ..Default::default()
        });
        output
    }

    /// A stack of dense layers on `x` (any leading axes): `MatMul`, `Add`, then the layer's
    /// activation. The last layer's output is named `out` when given.
    fn dense(
        &mut self,
        what: &str,
        x: &str,
        layers: &[infer_core::FloatLayer],
        out: Option<&str>,
    ) -> Result<String> {
        let mut h = x.to_string();
        for (l, layer) in layers.iter().enumerate() {
            let (i, o) = (layer.in_dim, layer.out_dim);
            if layer.weights.len() != i * o || layer.bias.len() != o {
                return Err(Error::Shape(format!(
                    "{what} layer {l}: {} weights and {} biases for {i} -> {o}",
                    layer.weights.len(),
                    layer.bias.len()
                )));
            }
            // FloatLayer weights are [out][in]; MatMul wants [in, out].
            let mut w = vec![0.0f32; i * o];
            for r in 0..o {
                for c in 0..i {
                    w[c * o + r] = layer.weights[r * i + c];
                }
            }
            let w = self.constant(&format!("{what}{l}_w"), &[i, o], &w);
            let b = self.constant(&format!("{what}{l}_b"), &[o], &layer.bias);
            let last = l + 1 == layers.len();
            let act = layer.activation;
            let name_at = |is_end: bool| if last && is_end { out } else { None };
            let mm = self.op("MatMul", &[&h, &w], vec![], None);
            let identity = act == infer_core::Activation::Identity;
            h = self.op("Add", &[&mm, &b], vec![], name_at(identity));
            match act {
                infer_core::Activation::Identity => {}
                infer_core::Activation::Relu => {
                    h = self.op("Relu", &[&h], vec![], name_at(true));
                }
                infer_core::Activation::Tanh => {
                    h = self.op("Tanh", &[&h], vec![], name_at(true));
                }
            }
        }
        if layers.is_empty() {
            return Err(Error::Shape(format!("{what}: no layers")));
        }
        Ok(h)
    }

    /// `(x - mean) / std` with `mean`, `std` broadcast on the last axis.
    fn normalise(&mut self, x: &str, mean: &[f32], std: &[f32]) -> String {
        let m = self.constant("mean", &[mean.len()], mean);
        let s = self.constant("std", &[std.len()], std);
        let centred = self.op("Sub", &[x, &m], vec![], None);
        self.op("Div", &[&centred, &s], vec![], None)
    }

    fn model(
        self,
        name: &str,
        doc: &str,
        inputs: Vec<ValueInfoProto>,
        outputs: Vec<ValueInfoProto>,
        props: &[(&str, &str)],
    ) -> Result<Vec<u8>> {
        let graph = GraphProto {
            name: name.into(),
            doc_string: doc.into(),
            node: self.nodes,
            initializer: self.initializers,
            input: inputs,
            output: outputs,
            ..Default::default()
        };
        let model = ModelProto {
            ir_version: IR_VERSION,
            opset_import: vec![OperatorSetIdProto {
                domain: String::new(),
                version: OPSET,
                ..Default::default()
            }],
            producer_name: "smile".into(),
            producer_version: env!("CARGO_PKG_VERSION").into(),
            doc_string: doc.into(),
            graph: MessageField::some(graph),
            metadata_props: props
                .iter()
                .map(|(k, v)| StringStringEntryProto {
                    key: (*k).into(),
                    value: (*v).into(),
                    ..Default::default()
                })
                .collect(),
            ..Default::default()
        };
        model.write_to_bytes().map_err(|e| Error::Serialise {
            what: "the ONNX model",
            reason: e.to_string(),
        })
    }
}

/// The graphs' inputs and outputs: named axes are dynamic (`trajectories`, `steps`, `batch`).
struct Shapes {
    context: [Axis; 3],
    mask: [Axis; 2],
    z: [Axis; 2],
    observation: [Axis; 2],
    policy_z: [Axis; 2],
    action: [Axis; 2],
}

impl Shapes {
    fn of(fm: &infer_core::FloatModel, transition_dim: usize) -> Shapes {
        let (traj, steps, batch) = (
            Axis::Named("trajectories"),
            Axis::Named("steps"),
            Axis::Named("batch"),
        );
        Shapes {
            context: [traj, steps, Axis::Fixed(transition_dim)],
            mask: [traj, steps],
            z: [Axis::Fixed(1), Axis::Fixed(fm.z_dim)],
            observation: [batch, Axis::Fixed(fm.obs_dim)],
            policy_z: [batch, Axis::Fixed(fm.z_dim)],
            action: [batch, Axis::Fixed(fm.act_dim)],
        }
    }
}

/// The two graphs of `mp` and their description (nothing is written).
pub fn export(mp: &MetaPolicy) -> Result<OnnxExport> {
    let fm = mp.to_float_model()?;
    let state_only = fm.kind == infer_core::ModelKind::StateOnly;
    let (od, ad) = (fm.obs_dim, fm.act_dim);
    let td = if state_only { 2 * od } else { 2 * od + ad };
    let shapes = Shapes::of(&fm, td);
    let props = [("family", mp.family.name()), ("algo", mp.algo.as_str())];
    Ok(OnnxExport {
        encoder: encoder_graph(&fm, state_only, &shapes, &props)?,
        policy: policy_graph(&fm, &shapes, &props)?,
        meta: describe(mp, &fm, td, &shapes),
    })
}

/// The context encoder's graph: normalised transitions through phi, masked means over each
/// trajectory's steps, their sum over trajectories, the z head.
fn encoder_graph(
    fm: &infer_core::FloatModel,
    state_only: bool,
    shapes: &Shapes,
    props: &[(&str, &str)],
) -> Result<Vec<u8>> {
    // s and s' are normalised, a is not: mean 0 and std 1 leave it exactly as it is.
    let (mut m, mut s) = (fm.obs_mean.clone(), fm.obs_std.clone());
    if !state_only {
        m.extend(std::iter::repeat_n(0.0, fm.act_dim));
        s.extend(std::iter::repeat_n(1.0, fm.act_dim));
    }
    m.extend_from_slice(&fm.obs_mean);
    s.extend_from_slice(&fm.obs_std);
    let mut g = Builder::new("encoder");
    let x = g.normalise(names::CONTEXT, &m, &s);
    let r = g.dense("phi", &x, &fm.encoder, None)?;
    let last_axis = g.axes(&[2]);
    let mask3 = g.op("Unsqueeze", &[names::MASK, &last_axis], vec![], None);
    let masked = g.op("Mul", &[&r, &mask3], vec![], None);
    let steps_axis = g.axes(&[1]);
    let sums = g.op(
        "ReduceSum",
        &[&masked, &steps_axis],
        vec![int_attr("keepdims", 0)],
        None,
    );
    let counts = g.op(
        "ReduceSum",
        &[names::MASK, &steps_axis],
        vec![int_attr("keepdims", 1)],
        None,
    );
    let one = g.constant("one", &[], &[1.0]);
    let counts = g.op("Max", &[&counts, &one], vec![], None);
    let means = g.op("Div", &[&sums, &counts], vec![], None);
    let traj_axis = g.axes(&[0]);
    let total = g.op(
        "ReduceSum",
        &[&means, &traj_axis],
        vec![int_attr("keepdims", 1)],
        None,
    );
    g.dense("head", &total, &fm.z_head, Some(names::Z))?;
    g.model(
        "smile_context_encoder",
        "SMILe context encoder: raw transitions [trajectories, steps, transition] and their \
         mask -> the posterior mean of z [1, z_dim]",
        vec![
            value_info(names::CONTEXT, &shapes.context),
            value_info(names::MASK, &shapes.mask),
        ],
        vec![value_info(names::Z, &shapes.z)],
        props,
    )
}

/// The policy's graph: the normalised observation beside z, the MLP, tanh of its mean.
fn policy_graph(
    fm: &infer_core::FloatModel,
    shapes: &Shapes,
    props: &[(&str, &str)],
) -> Result<Vec<u8>> {
    // MetaPolicy::to_float_model bakes unit scaling (sim's actions lie in [-1, 1]).
    if fm.act_scale.iter().any(|v| *v != 1.0) || fm.act_offset.iter().any(|v| *v != 0.0) {
        return Err(Error::Shape(
            "the ONNX export takes unit action scaling only (action = tanh(mu))".into(),
        ));
    }
    let mut g = Builder::new("policy");
    let on = g.normalise(names::OBSERVATION, &fm.obs_mean, &fm.obs_std);
    let x = g.op("Concat", &[&on, names::Z], vec![int_attr("axis", 1)], None);
    let mu = g.dense("pi", &x, &fm.policy, None)?;
    g.op("Tanh", &[&mu], vec![], Some(names::ACTION));
    g.model(
        "smile_policy",
        "SMILe conditioned policy: raw observations [batch, obs_dim] and z [batch, z_dim] -> \
         the deterministic action tanh(mu) [batch, act_dim]",
        vec![
            value_info(names::OBSERVATION, &shapes.observation),
            value_info(names::Z, &shapes.policy_z),
        ],
        vec![value_info(names::ACTION, &shapes.action)],
        props,
    )
}

/// What `meta.json` says about the two graphs.
fn describe(mp: &MetaPolicy, fm: &infer_core::FloatModel, td: usize, shapes: &Shapes) -> OnnxMeta {
    let state_only = fm.kind == infer_core::ModelKind::StateOnly;
    OnnxMeta {
        format: "smile-meta-policy-onnx".into(),
        opset: OPSET,
        ir_version: IR_VERSION,
        family: mp.family.name().into(),
        algo: mp.algo.clone(),
        physics: mp.physics,
        kind: if state_only {
            "state-only"
        } else {
            "state-action"
        }
        .into(),
        transition: if state_only { "[s, s']" } else { "[s, a, s']" }.into(),
        obs_dim: fm.obs_dim,
        act_dim: fm.act_dim,
        transition_dim: td,
        r_dim: fm.r_dim,
        z_dim: fm.z_dim,
        encoder: GraphInfo {
            file: ENCODER_FILE.into(),
            inputs: vec![
                tensor_info(names::CONTEXT, &shapes.context),
                tensor_info(names::MASK, &shapes.mask),
            ],
            outputs: vec![tensor_info(names::Z, &shapes.z)],
        },
        policy: GraphInfo {
            file: POLICY_FILE.into(),
            inputs: vec![
                tensor_info(names::OBSERVATION, &shapes.observation),
                tensor_info(names::Z, &shapes.policy_z),
            ],
            outputs: vec![tensor_info(names::ACTION, &shapes.action)],
        },
        normalisation: Normalisation {
            applied_to: "inside both graphs: s and s' of every context transition, and the \
                         policy's observation, as (x - obs_mean) / obs_std; feed raw values"
                .into(),
            obs_mean: fm.obs_mean.clone(),
            obs_std: fm.obs_std.clone(),
        },
        action: "the deterministic tanh(mu) of the policy's Gaussian head, in (-1, 1) as the \
                 plants take it"
            .into(),
        aggregation: "r = phi(transition); the mean of r over each trajectory's steps where \
                      mask = 1; the sum of those means over the trajectories with any step \
                      (not their mean); z = the mu rows of head(sum)"
            .into(),
        reference: None,
    }
}
