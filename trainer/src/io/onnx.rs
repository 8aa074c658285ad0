//! Export of a trained [`MetaPolicy`] as ONNX, for runtimes other than infer-core.
//!
//! Two graphs and a description, in one directory (`smile export --format onnx -o DIR`):
//!
//! * [`ENCODER_FILE`]: raw context transitions -> the posterior mean of z. Inputs
//!   `context` `[trajectories, steps, transition]` (`[s, a, s']` or, state-only, `[s, s']`,
//!   raw) and `mask` `[trajectories, steps]` (1 for a real step, 0 for padding; a trajectory
//!   whose mask is all 0 does not count); output `z` `[1, z_dim]`. The graph is the trainer's
//!   encoder op for op:
//!
//!   ```text
//!   x = (context - M) / S                    M, S: the demo-state mean / std on s and s', 0 / 1 on a
//!   r = phi(x)                               MatMul, Add, Relu per layer: [trajectories, steps, r]
//!   rbar_j = sum_t mask_jt r_jt / max(sum_t mask_jt, 1)      Mul, ReduceSum, Max, Div
//!   s = sum_j rbar_j                         ReduceSum: the sum (not the mean) over trajectories
//!   z = head(s)[:z_dim]                      the head's mu rows only (as in the blob)
//!   ```
//! * [`POLICY_FILE`]: `observation` `[batch, obs_dim]` (raw) and `z` `[batch, z_dim]` ->
//!   `action` `[batch, act_dim]`, the deterministic `tanh(mu)` on `[(obs - mean) / std, z]`.
//! * [`META_FILE`]: the family, the algorithm, the opset, every input and output with its shape,
//!   the normalisation (the graphs apply it: feed raw observations).
//!
//! The weights and statistics come from [`MetaPolicy::to_float_model`], the structure the blob
//! is written from, so the two exports cannot drift apart. The trajectory, step and batch axes
//! are symbolic (`dim_param`). [`reference`] computes the trainer's z and actions on held-out
//! contexts (padded and masked the way a runtime would get them), which `smile export` stores
//! as [`REFERENCE_FILE`] for `docs/scripts/onnx_parity.py`; `trainer/tests/onnx.rs` runs the
//! graphs with tract against the same values.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use onnx_protobuf::attribute_proto::AttributeType;
use onnx_protobuf::tensor_proto::DataType;
use onnx_protobuf::tensor_shape_proto::{Dimension, dimension};
use onnx_protobuf::type_proto;
use onnx_protobuf::{
    AttributeProto, GraphProto, Message, ModelProto, NodeProto, OperatorSetIdProto,
    StringStringEntryProto, TensorProto, TensorShapeProto, TypeProto, ValueInfoProto,
};
use protobuf::{EnumOrUnknown, MessageField};
use serde::{Deserialize, Serialize};
use sim::{DemoDataset, Trajectory};

use crate::eval::ConditionedActor;
use crate::io::checkpoint;
use crate::io::export::{check_demos_fit, raw_transitions};
use crate::model::MetaPolicy;
use crate::{Error, Result};

/// The ONNX operator set the graphs are written for (default domain).
pub const OPSET: i64 = 17;
/// The ONNX IR version that goes with [`OPSET`].
pub const IR_VERSION: i64 = 8;
/// The encoder graph's file name inside the export directory.
pub const ENCODER_FILE: &str = "encoder.onnx";
/// The policy graph's file name inside the export directory.
pub const POLICY_FILE: &str = "policy.onnx";
/// The description's file name inside the export directory.
pub const META_FILE: &str = "onnx.json";
/// The parity reference's file name inside the export directory (safetensors).
pub const REFERENCE_FILE: &str = "reference.safetensors";

/// Input and output names of the two graphs (static: a runtime can hard-code them).
pub mod names {
    /// Encoder input: raw transitions `[trajectories, steps, transition]`.
    pub const CONTEXT: &str = "context";
    /// Encoder input: `[trajectories, steps]`, 1 for a real step, 0 for padding.
    pub const MASK: &str = "mask";
    /// Encoder output `[1, z_dim]`, and policy input `[batch, z_dim]`.
    pub const Z: &str = "z";
    /// Policy input: raw observations `[batch, obs_dim]`.
    pub const OBSERVATION: &str = "observation";
    /// Policy output: `[batch, act_dim]`.
    pub const ACTION: &str = "action";
}

/// One graph input or output as [`META_FILE`] describes it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TensorInfo {
    /// Its name in the graph.
    pub name: String,
    /// Always `float32`.
    pub dtype: String,
    /// Each dimension: a number, or the name of a symbolic axis.
    pub shape: Vec<serde_json::Value>,
}

/// One graph of the export.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GraphInfo {
    /// File name inside the export directory.
    pub file: String,
    /// Inputs, in order.
    pub inputs: Vec<TensorInfo>,
    /// Outputs, in order.
    pub outputs: Vec<TensorInfo>,
}

/// The normalisation the graphs apply (feed them raw observations).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Normalisation {
    /// What it is applied to.
    pub applied_to: String,
    /// Per-component mean of the meta-train demo states.
    pub obs_mean: Vec<f32>,
    /// Per-component std of the meta-train demo states.
    pub obs_std: Vec<f32>,
}

/// What [`META_FILE`] holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OnnxMeta {
    /// `smile-meta-policy-onnx`.
    pub format: String,
    /// ONNX operator set (default domain).
    pub opset: i64,
    /// ONNX IR version.
    pub ir_version: i64,
    /// Task family.
    pub family: String,
    /// Algorithm that trained the policy.
    pub algo: String,
    /// `state-action` (`[s, a, s']` transitions) or `state-only` (`[s, s']`).
    pub kind: String,
    /// The layout of one context transition.
    pub transition: String,
    /// Observation width.
    pub obs_dim: usize,
    /// Action width.
    pub act_dim: usize,
    /// Transition width (the context's last axis).
    pub transition_dim: usize,
    /// Per-transition representation width.
    pub r_dim: usize,
    /// Latent width.
    pub z_dim: usize,
    /// The context encoder.
    pub encoder: GraphInfo,
    /// The conditioned policy.
    pub policy: GraphInfo,
    /// The observation normalisation inside both graphs.
    pub normalisation: Normalisation,
    /// What the policy's output is, in words.
    pub action: String,
    /// How the encoder aggregates, in words.
    pub aggregation: String,
    /// The parity reference file, when one was written.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<ReferenceInfo>,
}

/// What [`META_FILE`] says of [`REFERENCE_FILE`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReferenceInfo {
    /// File name inside the export directory.
    pub file: String,
    /// The demo file the contexts and observations come from.
    pub source: String,
    /// Contexts stored.
    pub contexts: usize,
    /// Observations stored (over all contexts).
    pub observations: usize,
}

/// The serialised graphs and their description.
#[derive(Debug, Clone)]
pub struct OnnxExport {
    /// `encoder.onnx` bytes.
    pub encoder: Vec<u8>,
    /// `policy.onnx` bytes.
    pub policy: Vec<u8>,
    /// The description.
    pub meta: OnnxMeta,
}

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
        model
            .write_to_bytes()
            .map_err(|e| Error::Data(format!("ONNX serialisation: {e}")))
    }
}

/// The two graphs of `mp` and their description (nothing is written).
pub fn export(mp: &MetaPolicy) -> Result<OnnxExport> {
    let fm = mp.to_float_model()?;
    let (od, ad, zd) = (fm.obs_dim, fm.act_dim, fm.z_dim);
    let state_only = fm.kind == infer_core::ModelKind::StateOnly;
    let td = if state_only { 2 * od } else { 2 * od + ad };
    // s and s' are normalised, a is not: mean 0 and std 1 leave it exactly as it is.
    let (mut m, mut s) = (fm.obs_mean.clone(), fm.obs_std.clone());
    if !state_only {
        m.extend(std::iter::repeat_n(0.0, ad));
        s.extend(std::iter::repeat_n(1.0, ad));
    }
    m.extend_from_slice(&fm.obs_mean);
    s.extend_from_slice(&fm.obs_std);
    let family = mp.family.name();
    let props = [("family", family), ("algo", mp.algo.as_str())];

    // Encoder.
    let ctx_shape = [
        Axis::Named("trajectories"),
        Axis::Named("steps"),
        Axis::Fixed(td),
    ];
    let mask_shape = [Axis::Named("trajectories"), Axis::Named("steps")];
    let z_shape = [Axis::Fixed(1), Axis::Fixed(zd)];
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
    let encoder = g.model(
        "smile_context_encoder",
        "SMILe context encoder: raw transitions [trajectories, steps, transition] and their \
         mask -> the posterior mean of z [1, z_dim]",
        vec![
            value_info(names::CONTEXT, &ctx_shape),
            value_info(names::MASK, &mask_shape),
        ],
        vec![value_info(names::Z, &z_shape)],
        &props,
    )?;

    // Policy.
    let obs_shape = [Axis::Named("batch"), Axis::Fixed(od)];
    let pz_shape = [Axis::Named("batch"), Axis::Fixed(zd)];
    let act_shape = [Axis::Named("batch"), Axis::Fixed(ad)];
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
    let policy = g.model(
        "smile_policy",
        "SMILe conditioned policy: raw observations [batch, obs_dim] and z [batch, z_dim] -> \
         the deterministic action tanh(mu) [batch, act_dim]",
        vec![
            value_info(names::OBSERVATION, &obs_shape),
            value_info(names::Z, &pz_shape),
        ],
        vec![value_info(names::ACTION, &act_shape)],
        &props,
    )?;

    let meta = OnnxMeta {
        format: "smile-meta-policy-onnx".into(),
        opset: OPSET,
        ir_version: IR_VERSION,
        family: family.into(),
        algo: mp.algo.clone(),
        kind: if state_only {
            "state-only"
        } else {
            "state-action"
        }
        .into(),
        transition: if state_only { "[s, s']" } else { "[s, a, s']" }.into(),
        obs_dim: od,
        act_dim: ad,
        transition_dim: td,
        r_dim: fm.r_dim,
        z_dim: zd,
        encoder: GraphInfo {
            file: ENCODER_FILE.into(),
            inputs: vec![
                tensor_info(names::CONTEXT, &ctx_shape),
                tensor_info(names::MASK, &mask_shape),
            ],
            outputs: vec![tensor_info(names::Z, &z_shape)],
        },
        policy: GraphInfo {
            file: POLICY_FILE.into(),
            inputs: vec![
                tensor_info(names::OBSERVATION, &obs_shape),
                tensor_info(names::Z, &pz_shape),
            ],
            outputs: vec![tensor_info(names::ACTION, &act_shape)],
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
    };
    Ok(OnnxExport {
        encoder,
        policy,
        meta,
    })
}

/// One context of a [`Reference`], as a runtime is fed it, with the trainer's outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceContext {
    /// Index of the task in the demo file.
    pub task: usize,
    /// `[trajectories, steps, transition]` of `context`.
    pub shape: [usize; 3],
    /// Raw transitions, row-major, padded (padding is finite junk, masked out).
    pub context: Vec<f32>,
    /// `[trajectories, steps]`: 1 for a real step.
    pub mask: Vec<f32>,
    /// The trainer's z (posterior mean) for the unmasked transitions.
    pub z: Vec<f32>,
    /// Raw observations `[n, obs_dim]`: the states of all the task's trajectories.
    pub observations: Vec<f32>,
    /// The trainer's deterministic actions `[n, act_dim]` for them with `z`.
    pub actions: Vec<f32>,
}

/// Contexts with the trainer's z and actions, to hold a runtime's outputs against.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// Observation width.
    pub obs_dim: usize,
    /// Action width.
    pub act_dim: usize,
    /// Latent width.
    pub z_dim: usize,
    /// The contexts.
    pub contexts: Vec<ReferenceContext>,
}

/// The value a padded cell holds: finite, and far from any demo value, so that a graph which
/// let padding through would be caught.
const PAD: f32 = 3.25;

/// The trainer's z and actions on every task of `demos` (held-out contexts), two contexts a
/// task: its first trajectory alone, and all its trajectories padded to a common length
/// plus two junk steps and one junk trajectory, all masked out. Observations: the states of
/// all the task's trajectories. Reference values come from [`ConditionedActor`] on `mp`, the
/// path evaluation and the blob parity use.
pub fn reference(mp: &MetaPolicy, demos: &DemoDataset) -> Result<Reference> {
    check_demos_fit(mp, demos, "the contexts")?;
    let (od, ad, zd) = (demos.obs_dim, demos.act_dim, mp.z_dim());
    let so = mp.encoder.config().state_only;
    let td = if so { 2 * od } else { 2 * od + ad };
    let mut mp = mp.clone();
    let mut contexts = Vec::new();
    for (task, t) in demos.tasks.iter().enumerate() {
        let trajs: Vec<&Trajectory> = t.trajectories.iter().filter(|t| !t.is_empty()).collect();
        if trajs.is_empty() {
            continue;
        }
        let observations: Vec<f32> = trajs.iter().flat_map(|t| t.obs.iter().copied()).collect();
        for (ctx, pad_steps, pad_trajs) in [(&trajs[..1], 0, 0), (&trajs[..], 2, 1)] {
            let z = ConditionedActor::latent(&mut mp, ctx)?;
            let steps = ctx.iter().map(|t| t.len()).max().unwrap_or(0) + pad_steps;
            let n = ctx.len() + pad_trajs;
            let mut context = vec![PAD; n * steps * td];
            let mut mask = vec![0.0f32; n * steps];
            for (j, traj) in ctx.iter().enumerate() {
                for (i, row) in raw_transitions(traj, od, ad, so).iter().enumerate() {
                    let at = (j * steps + i) * td;
                    context[at..at + td].copy_from_slice(row);
                    mask[j * steps + i] = 1.0;
                }
            }
            let mut actions = vec![0.0f32; observations.len() / od * ad];
            for (o, a) in observations
                .chunks_exact(od)
                .zip(actions.chunks_exact_mut(ad))
            {
                ConditionedActor::act(&mut mp, o, &z, a)?;
            }
            contexts.push(ReferenceContext {
                task,
                shape: [n, steps, td],
                context,
                mask,
                z,
                observations: observations.clone(),
                actions,
            });
        }
    }
    if contexts.is_empty() {
        return Err(Error::Data("the contexts hold no transitions".into()));
    }
    Ok(Reference {
        obs_dim: od,
        act_dim: ad,
        z_dim: zd,
        contexts,
    })
}

impl Reference {
    /// Observations over all contexts.
    pub fn observation_count(&self) -> usize {
        self.contexts
            .iter()
            .map(|c| c.observations.len() / self.obs_dim.max(1))
            .sum()
    }

    /// As safetensors: per context `i`, `{i}.context`, `{i}.mask`, `{i}.z` (`[1, z_dim]`),
    /// `{i}.observation`, `{i}.action`; the header metadata maps `{i}.task` to the task index.
    pub fn to_safetensors(&self) -> Result<Vec<u8>> {
        use safetensors::tensor::{Dtype, TensorView};
        let bytes = |v: &[f32]| -> Vec<u8> { v.iter().flat_map(|x| x.to_le_bytes()).collect() };
        let mut owned: Vec<(String, Vec<usize>, Vec<u8>)> = Vec::new();
        let mut meta = HashMap::new();
        for (i, c) in self.contexts.iter().enumerate() {
            let [n, s, td] = c.shape;
            let rows = c.observations.len() / self.obs_dim.max(1);
            owned.push((format!("{i}.context"), vec![n, s, td], bytes(&c.context)));
            owned.push((format!("{i}.mask"), vec![n, s], bytes(&c.mask)));
            owned.push((format!("{i}.z"), vec![1, self.z_dim], bytes(&c.z)));
            owned.push((
                format!("{i}.observation"),
                vec![rows, self.obs_dim],
                bytes(&c.observations),
            ));
            owned.push((
                format!("{i}.action"),
                vec![rows, self.act_dim],
                bytes(&c.actions),
            ));
            meta.insert(format!("{i}.task"), c.task.to_string());
        }
        meta.insert("contexts".into(), self.contexts.len().to_string());
        let views = owned
            .iter()
            .map(|(name, shape, data)| {
                TensorView::new(Dtype::F32, shape.clone(), data)
                    .map(|v| (name.clone(), v))
                    .map_err(|e| Error::Data(format!("reference tensor {name}: {e}")))
            })
            .collect::<Result<Vec<_>>>()?;
        safetensors::tensor::serialize(views, Some(meta))
            .map_err(|e| Error::Data(format!("reference serialisation: {e}")))
    }
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> Error + '_ {
    move |e| Error::Io {
        path: path.to_path_buf(),
        source: e,
    }
}

/// True if `dir` is empty or holds an earlier ONNX export (its description file and nothing
/// but the files an export writes): only such a directory is replaced.
fn replaceable(dir: &Path) -> Result<bool> {
    let ours = [ENCODER_FILE, POLICY_FILE, META_FILE, REFERENCE_FILE];
    let mut has_meta = false;
    let mut empty = true;
    for entry in std::fs::read_dir(dir).map_err(io_err(dir))? {
        let name = entry.map_err(io_err(dir))?.file_name();
        empty = false;
        match name.to_str() {
            Some(n) if n == META_FILE => has_meta = true,
            Some(n) if ours.contains(&n) => {}
            _ => return Ok(false),
        }
    }
    Ok(empty || has_meta)
}

/// Writes `export` (and `reference`, if any) to the directory `out`: everything goes to a
/// temporary directory beside `out` first, which is renamed to `out` once complete, so a
/// failure leaves nothing half-written. An existing `out` is replaced only if it is empty or
/// an earlier ONNX export. Returns the file paths written.
pub fn write_dir(
    out: &Path,
    export: &OnnxExport,
    reference: Option<(&Reference, &str)>,
) -> Result<Vec<PathBuf>> {
    let usage = |why: String| Error::Usage(format!("cannot write {}: {why}", out.display()));
    let name = out
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| usage("not a directory name".into()))?;
    if out.is_file() {
        return Err(usage(
            "it is a file; -o takes a directory for --format onnx".into(),
        ));
    }
    if out.is_dir() && !replaceable(out)? {
        return Err(usage(
            "the directory holds other files than an ONNX export; choose a new or empty one".into(),
        ));
    }
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&parent).map_err(|e| usage(e.to_string()))?;
    let tmp = parent.join(format!(".{name}.onnx-tmp-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir(&tmp).map_err(|e| usage(e.to_string()))?;
    let result = (|| -> Result<()> {
        let mut meta = export.meta.clone();
        checkpoint::write_atomic(&tmp.join(ENCODER_FILE), &export.encoder)?;
        checkpoint::write_atomic(&tmp.join(POLICY_FILE), &export.policy)?;
        if let Some((r, source)) = reference {
            checkpoint::write_atomic(&tmp.join(REFERENCE_FILE), &r.to_safetensors()?)?;
            meta.reference = Some(ReferenceInfo {
                file: REFERENCE_FILE.into(),
                source: source.into(),
                contexts: r.contexts.len(),
                observations: r.observation_count(),
            });
        }
        let json =
            serde_json::to_vec_pretty(&meta).map_err(|e| Error::Data(format!("onnx.json: {e}")))?;
        checkpoint::write_atomic(&tmp.join(META_FILE), &json)?;
        // Swap in: an earlier export moves aside first and goes once the new one is in place.
        let old = parent.join(format!(".{name}.onnx-old-{}", std::process::id()));
        let had_old = out.is_dir();
        if had_old {
            std::fs::rename(out, &old).map_err(io_err(out))?;
        }
        if let Err(e) = std::fs::rename(&tmp, out) {
            if had_old {
                let _ = std::fs::rename(&old, out);
            }
            return Err(io_err(out)(e));
        }
        if had_old {
            let _ = std::fs::remove_dir_all(&old);
        }
        Ok(())
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(match e {
            Error::Usage(m) => Error::Usage(m),
            other => usage(other.to_string()),
        });
    }
    let mut files = vec![out.join(ENCODER_FILE), out.join(POLICY_FILE)];
    if reference.is_some() {
        files.push(out.join(REFERENCE_FILE));
    }
    files.push(out.join(META_FILE));
    Ok(files)
}
