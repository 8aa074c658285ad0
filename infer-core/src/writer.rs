//! The blob writer (feature `alloc`): float layers + normalisation + calibration data in,
//! quantized blob bytes out. The trainer's exporter calls this; nothing else writes blobs.

extern crate alloc;

use alloc::vec::Vec;

use crate::error::{Error, Result};
use crate::format::{
    self, Activation, Bytes, ENVELOPE_LEN, FORMAT_VERSION, Header, LayerRecord, Layers, MAGIC,
    ModelKind, Payload, Quant,
};

mod check;

/// One float dense layer, `y = act(W x + b)`, weights row-major `[out][in]`.
#[derive(Debug, Clone, PartialEq)]
pub struct FloatLayer {
    /// Input width.
    pub in_dim: usize,
    /// Output width.
    pub out_dim: usize,
    /// `out_dim * in_dim` weights, row `o` holds the weights of output `o`.
    pub weights: Vec<f32>,
    /// `out_dim` biases.
    pub bias: Vec<f32>,
    /// Non-linearity after the layer.
    pub activation: Activation,
}

impl FloatLayer {
    fn forward(&self, x: &[f32]) -> Vec<f32> {
        (0..self.out_dim)
            .map(|o| {
                let row = &self.weights[o * self.in_dim..(o + 1) * self.in_dim];
                let s: f32 = row.iter().zip(x).map(|(w, v)| w * v).sum();
                self.activation.apply(s + self.bias[o])
            })
            .collect()
    }
}

/// A float model in the exact structure of a blob; also the `f32` reference implementation
/// the quantized blobs are measured against.
#[derive(Debug, Clone, PartialEq)]
pub struct FloatModel {
    /// What the encoder reads per transition.
    pub kind: ModelKind,
    /// Observation dimension.
    pub obs_dim: usize,
    /// Action dimension.
    pub act_dim: usize,
    /// Per-transition representation dimension.
    pub r_dim: usize,
    /// Latent dimension.
    pub z_dim: usize,
    /// Observation normalisation mean (`obs_dim`).
    pub obs_mean: Vec<f32>,
    /// Observation normalisation std (`obs_dim`, > 0).
    pub obs_std: Vec<f32>,
    /// Action scale: `action = tanh(mean) * scale + offset`.
    pub act_scale: Vec<f32>,
    /// Action offset.
    pub act_offset: Vec<f32>,
    /// Per-transition encoder MLP: transition -> r.
    pub encoder: Vec<FloatLayer>,
    /// Head: summed per-trajectory mean r -> posterior mean of z.
    pub z_head: Vec<FloatLayer>,
    /// Policy MLP: `[norm(obs), z]` -> pre-tanh action mean (last activation identity).
    pub policy: Vec<FloatLayer>,
}

/// Sample inputs from which the `w8a8` activation scales are calibrated.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Calibration {
    /// Contexts: each is a list of trajectories, each a list of raw transitions
    /// `[s, a, s']` (state-action) or `[s, s']` (state-only), unnormalised.
    pub contexts: Vec<Vec<Vec<Vec<f32>>>>,
    /// Raw observations; observation `i` is paired with the latent of context `i % n`.
    pub observations: Vec<Vec<f32>>,
}

fn run(layers: &[FloatLayer], x: &[f32], mut tap: impl FnMut(usize, &[f32])) -> Vec<f32> {
    let mut v = x.to_vec();
    for (i, l) in layers.iter().enumerate() {
        tap(i, &v);
        v = l.forward(&v);
    }
    v
}

impl FloatModel {
    /// Width of one raw context transition: `[s, a, s']` or `[s, s']`.
    pub(crate) fn transition_dim(&self) -> usize {
        match self.kind {
            ModelKind::StateAction => 2 * self.obs_dim + self.act_dim,
            ModelKind::StateOnly => 2 * self.obs_dim,
        }
    }

    pub(crate) fn normalise(&self, x: &[f32]) -> Vec<f32> {
        x.iter()
            .zip(&self.obs_mean)
            .zip(&self.obs_std)
            .map(|((v, m), s)| (v - m) / s)
            .collect()
    }

    /// The encoder input row for one raw transition.
    fn encoder_input(&self, t: &[f32]) -> Vec<f32> {
        let o = self.obs_dim;
        let mut row = self.normalise(&t[..o]);
        let next_at = match self.kind {
            ModelKind::StateAction => {
                row.extend_from_slice(&t[o..o + self.act_dim]);
                o + self.act_dim
            }
            ModelKind::StateOnly => o,
        };
        row.extend(self.normalise(&t[next_at..next_at + o]));
        row
    }

    fn context_sum(
        &self,
        context: &[Vec<Vec<f32>>],
        mut tap: impl FnMut(usize, &[f32]),
    ) -> Vec<f32> {
        let mut sum = alloc::vec![0.0f32; self.r_dim];
        for trajectory in context.iter().filter(|t| !t.is_empty()) {
            let mut traj = alloc::vec![0.0f32; self.r_dim];
            for t in trajectory {
                let r = run(&self.encoder, &self.encoder_input(t), &mut tap);
                traj.iter_mut().zip(&r).for_each(|(a, b)| *a += b);
            }
            let n = trajectory.len() as f32;
            sum.iter_mut().zip(&traj).for_each(|(s, t)| *s += t / n);
        }
        sum
    }

    /// Float reference of [`ContextEncoder`](crate::ContextEncoder): posterior mean of z.
    pub fn latent(&self, context: &[Vec<Vec<f32>>]) -> Vec<f32> {
        run(
            &self.z_head,
            &self.context_sum(context, |_, _| {}),
            |_, _| {},
        )
    }

    /// Float reference of [`Policy::act`](crate::Policy::act).
    pub fn act(&self, obs: &[f32], z: &[f32]) -> Vec<f32> {
        let mut x = self.normalise(obs);
        x.extend_from_slice(z);
        let mean = run(&self.policy, &x, |_, _| {});
        mean.iter()
            .enumerate()
            .map(|(i, m)| libm::tanhf(*m) * self.act_scale[i] + self.act_offset[i])
            .collect()
    }

    /// The range of each input channel of each layer of (encoder, z_head, policy) on
    /// `calib`: the largest absolute value, except that no channel's exceeds the layer's
    /// `quantile` of |input| pooled over its channels (1.0: the plain maximum). A quantile
    /// below 1 gives up the rarest values (clipped) for a finer step on all the others.
    fn input_ranges_at(&self, calib: &Calibration, quantile: f32) -> [Vec<Vec<f32>>; 3] {
        let mut ranges = self.input_ranges(calib);
        if quantile >= 1.0 {
            return ranges;
        }
        let pooled = |layers: &[FloatLayer]| -> Vec<Vec<f32>> {
            layers.iter().map(|_| Vec::new()).collect()
        };
        let mut seen = [
            pooled(&self.encoder),
            pooled(&self.z_head),
            pooled(&self.policy),
        ];
        self.trace(calib, |stack, layer, x| {
            seen[stack][layer].extend(x.iter().map(|v| v.abs()));
        });
        for (stack, values) in ranges.iter_mut().zip(seen.iter_mut()) {
            for (layer, v) in stack.iter_mut().zip(values.iter_mut()) {
                if v.is_empty() {
                    continue;
                }
                v.sort_unstable_by(f32::total_cmp);
                let at = ((v.len() - 1) as f32 * quantile) as usize;
                let cap = v[at];
                if cap > 0.0 {
                    layer.iter_mut().for_each(|r| *r = r.min(cap));
                }
            }
        }
        ranges
    }

    /// Largest absolute value of each input channel of each layer of (encoder, z_head,
    /// policy) on `calib`.
    fn input_ranges(&self, calib: &Calibration) -> [Vec<Vec<f32>>; 3] {
        let zeros = |layers: &[FloatLayer]| -> Vec<Vec<f32>> {
            layers
                .iter()
                .map(|l| alloc::vec![0.0f32; l.in_dim])
                .collect()
        };
        let mut ranges = [
            zeros(&self.encoder),
            zeros(&self.z_head),
            zeros(&self.policy),
        ];
        self.trace(calib, |stack, layer, x| {
            ranges[stack][layer]
                .iter_mut()
                .zip(x)
                .for_each(|(m, v)| *m = m.max(v.abs()));
        });
        ranges
    }

    /// Runs `calib` through the encoder, the z head and the policy (observation `i` with the
    /// latent of context `i % n`), calling `tap(stack, layer, input)` with every layer's input
    /// (stack 0: encoder, 1: z head, 2: policy).
    fn trace(&self, calib: &Calibration, mut tap: impl FnMut(usize, usize, &[f32])) {
        let mut latents = Vec::new();
        for context in &calib.contexts {
            let sum = self.context_sum(context, |i, x| tap(0, i, x));
            latents.push(run(&self.z_head, &sum, |i, x| tap(1, i, x)));
        }
        for (i, obs) in calib.observations.iter().enumerate() {
            let mut x = self.normalise(obs);
            x.extend_from_slice(&latents[i % latents.len()]);
            run(&self.policy, &x, |l, v| tap(2, l, v));
        }
    }
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Owned bytes of one quantized layer, before they are borrowed into a [`LayerRecord`].
struct EncodedLayer {
    layer: (u16, u16, Activation),
    quant: Quant,
    weights: Vec<u8>,
    bias: Vec<u8>,
    weight_scale: Vec<u8>,
    input_scale: Vec<u8>,
    unsigned_input: bool,
}

/// Headroom over the calibrated range of each input channel of an MLP's first layer: those
/// channels (observations, actions, z, the encoder sum) get one scale each, and values a bit
/// beyond what calibration saw (other tasks) must not clip. Measured on 12 point-goal
/// policies (docs/RESULTS.md): 1.25 beat 1.0 and 1.5 on action error.
const FIRST_LAYER_HEADROOM: f32 = 1.25;

/// Per-row symmetric int8 quantization of `weights` (`[out][in]`): the bytes and the scales.
fn quantize_rows(weights: &[f32], in_dim: usize) -> (Vec<u8>, Vec<f32>) {
    let mut q = Vec::with_capacity(weights.len());
    let mut scales = Vec::new();
    for row in weights.chunks_exact(in_dim.max(1)) {
        let max = row.iter().fold(0.0f32, |m, w| m.max(w.abs()));
        // An all-zero row quantizes to zeros under any scale; 1 keeps scales > 0.
        let scale = if max > 0.0 { max / 127.0 } else { 1.0 };
        q.extend(
            row.iter()
                .map(|w| crate::kernels::quantize(*w, scale) as u8),
        );
        scales.push(scale);
    }
    (q, scales)
}

/// Quantizes one layer. `input_range` holds the calibrated largest absolute value of each
/// input channel (W8A8 only); `unsigned_input` says the input follows a ReLU.
fn encode_layer(
    l: &FloatLayer,
    quant: Quant,
    input_range: &[f32],
    unsigned_input: bool,
) -> Result<EncodedLayer> {
    let dims = (
        u16::try_from(l.in_dim).map_err(|_| Error::TooLarge)?,
        u16::try_from(l.out_dim).map_err(|_| Error::TooLarge)?,
        l.activation,
    );
    let bias = f32_bytes(&l.bias);
    let (weights, weight_scale, input_scale, unsigned_input) = match quant {
        Quant::F32 => (f32_bytes(&l.weights), Vec::new(), Vec::new(), false),
        Quant::W8A32 => {
            let (weights, scales) = quantize_rows(&l.weights, l.in_dim);
            (weights, f32_bytes(&scales), Vec::new(), false)
        }
        Quant::W8A8 => {
            let (weights, scales, s_in) = encode_w8a8(l, input_range, unsigned_input);
            (
                weights,
                f32_bytes(&scales),
                f32_bytes(&s_in),
                unsigned_input,
            )
        }
    };
    Ok(EncodedLayer {
        layer: dims,
        quant,
        weights,
        bias,
        weight_scale,
        input_scale,
        unsigned_input,
    })
}

/// A W8A8 layer's int8 weights, their per-row scales and its input scales (one where all are
/// equal).
fn encode_w8a8(
    l: &FloatLayer,
    input_range: &[f32],
    unsigned_input: bool,
) -> (Vec<u8>, Vec<f32>, Vec<f32>) {
    // A hidden layer (input after a ReLU) quantizes its input unsigned with the layer's
    // widest range: per-unit ranges overfit the calibration (a unit rarely active there
    // clips elsewhere; measured: z error 3-10x). A first layer's channels are different
    // quantities (observation, action, z, r sums): each gets its own scale with
    // headroom, at most the layer's widest range.
    let levels = if unsigned_input { 255.0 } else { 127.0 };
    let widest = input_range.iter().fold(0.0f32, |m, r| m.max(*r));
    let s_in: Vec<f32> = input_range
        .iter()
        .map(|&r| {
            // (A channel never non-zero in calibration takes the widest range too.)
            let r = if unsigned_input || r <= 0.0 {
                widest
            } else {
                (r * FIRST_LAYER_HEADROOM).min(widest)
            };
            if r > 0.0 { r / levels } else { 1.0 }
        })
        .collect();
    // y_o = sum_i w_oi x_i = sum_i (w_oi s_i) q_i: the input scales fold into the
    // weights, which are then quantized per row as usual.
    let folded: Vec<f32> = l
        .weights
        .chunks_exact(l.in_dim.max(1))
        .flat_map(|row| row.iter().zip(&s_in).map(|(w, s)| w * s))
        .collect();
    let (weights, scales) = quantize_rows(&folded, l.in_dim);
    // Equal scales (a hidden layer's) are stored once.
    let s_in = if s_in.iter().all(|s| *s == s_in[0]) {
        s_in[..1.min(s_in.len())].to_vec()
    } else {
        s_in
    };
    (weights, scales, s_in)
}

fn records(encoded: &[EncodedLayer]) -> Layers<'_> {
    let mut layers = Layers::default();
    for e in encoded {
        // Length was checked against `MAX_LAYERS` in `FloatModel::check`.
        let _ = layers.push(LayerRecord {
            in_dim: e.layer.0,
            out_dim: e.layer.1,
            activation: e.layer.2,
            quant: e.quant,
            weights: Bytes(&e.weights),
            bias: Bytes(&e.bias),
            weight_scale: Bytes(&e.weight_scale),
            input_scale: Bytes(&e.input_scale),
            unsigned_input: e.unsigned_input,
        });
    }
    layers
}

/// How [`write_blob_with`] quantizes, beyond the blob's scheme.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WriteOptions {
    /// `w8a8`'s activation ranges capped at each layer's `range_quantile` of |input| on the
    /// calibration (1.0: the maximum). A quantile below 1 gives up the rarest values (clipped)
    /// for a finer step on all the others.
    pub range_quantile: f32,
    /// A higher precision for the first and last layer of each MLP, where int8 activations
    /// cost the most (the raw observations, actions and latents in; the action mean out);
    /// `None` stores every layer at the blob's quantization.
    pub edges: Option<Quant>,
    /// A higher precision for every layer of the context encoder and the z head: they run
    /// once per teaching, not per control tick, so their cost does not matter at run time;
    /// `None` stores them as the policy (with its edges).
    pub context: Option<Quant>,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            range_quantile: 1.0,
            edges: None,
            context: None,
        }
    }
}

/// Quantizes `model` with `quant` and returns the blob bytes. `calibration` is required for
/// [`Quant::W8A8`] (every row of the model's dimension, finite) and ignored otherwise. The blob is loaded back before it is returned.
pub fn write_blob(model: &FloatModel, quant: Quant, calibration: &Calibration) -> Result<Vec<u8>> {
    write_blob_with(model, quant, calibration, &WriteOptions::default())
}

/// [`write_blob`] with [`WriteOptions`]: capped activation ranges, higher-precision edges.
pub fn write_blob_with(
    model: &FloatModel,
    quant: Quant,
    calibration: &Calibration,
    options: &WriteOptions,
) -> Result<Vec<u8>> {
    model.check()?;
    let edges = options.edges.unwrap_or(quant);
    let context = options.context;
    if let Some(finer) = [Some(edges), context]
        .into_iter()
        .flatten()
        .find(|q| !q.at_least(quant))
    {
        return Err(Error::FinerBelowQuant {
            asked: finer,
            quant,
        });
    }
    if quant == Quant::W8A8 {
        calibration.check(model)?;
    }
    let ranges = if quant == Quant::W8A8 {
        model.input_ranges_at(calibration, options.range_quantile.clamp(0.5, 1.0))
    } else {
        Default::default()
    };
    let encode = |layers: &[FloatLayer], ranges: &[Vec<f32>], whole: Option<Quant>| {
        let last = layers.len().saturating_sub(1);
        layers
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let range = ranges.get(i).map_or(&[][..], Vec::as_slice);
                let q = match whole {
                    Some(q) => q.max_precision(if i == 0 || i == last { edges } else { quant }),
                    None if i == 0 || i == last => edges,
                    None => quant,
                };
                // Only an input produced by a ReLU of the same MLP is known to be >= 0.
                let unsigned =
                    q == Quant::W8A8 && i > 0 && layers[i - 1].activation == Activation::Relu;
                encode_layer(l, q, range, unsigned)
            })
            .collect::<Result<Vec<_>>>()
    };
    let encoder = encode(&model.encoder, &ranges[0], context)?;
    let z_head = encode(&model.z_head, &ranges[1], context)?;
    let policy = encode(&model.policy, &ranges[2], None)?;
    let dim = |d: usize| u16::try_from(d).map_err(|_| Error::TooLarge);
    let (mean, std) = (f32_bytes(&model.obs_mean), f32_bytes(&model.obs_std));
    let (scale, offset) = (f32_bytes(&model.act_scale), f32_bytes(&model.act_offset));
    let payload = Payload {
        header: Header {
            kind: model.kind,
            quant,
            obs_dim: dim(model.obs_dim)?,
            act_dim: dim(model.act_dim)?,
            r_dim: dim(model.r_dim)?,
            z_dim: dim(model.z_dim)?,
        },
        obs_mean: Bytes(&mean),
        obs_std: Bytes(&std),
        act_scale: Bytes(&scale),
        act_offset: Bytes(&offset),
        encoder: records(&encoder),
        z_head: records(&z_head),
        policy: records(&policy),
    };
    let body = postcard::to_allocvec(&payload).map_err(|_| Error::Shape("postcard"))?;
    let len = u32::try_from(body.len()).map_err(|_| Error::TooLarge)?;
    let mut blob = Vec::with_capacity(ENVELOPE_LEN + body.len());
    blob.extend_from_slice(&MAGIC);
    blob.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    blob.extend_from_slice(&len.to_le_bytes());
    blob.extend_from_slice(&format::crc32(&body).to_le_bytes());
    blob.extend_from_slice(&body);
    // Loaded back: a failure here is a writer bug, returned as the loader's error.
    crate::model::Model::from_bytes(&blob)?;
    Ok(blob)
}

/// Sizes of a model built by [`FloatModel::random`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dims {
    /// Observation dimension.
    pub obs: usize,
    /// Action dimension.
    pub act: usize,
    /// Per-transition representation dimension.
    pub r: usize,
    /// Latent dimension.
    pub z: usize,
    /// Width of the two hidden layers of each MLP.
    pub hidden: usize,
}

impl Dims {
    /// The project's default sizes (obs 20, act 6, r 32, z 16) at the given hidden width.
    pub const fn default_with_hidden(hidden: usize) -> Self {
        Self {
            obs: 20,
            act: 6,
            r: 32,
            z: 16,
            hidden,
        }
    }
}

impl FloatModel {
    /// A randomly initialised model (uniform fan-in init, seeded, deterministic): encoder and
    /// policy with two hidden ReLU layers, a linear r -> z head (the smallest blob; the
    /// trainer's default head is a 64 x 64 MLP), identity normalisation and unit action scale. For tests,
    /// benchmarks and footprint measurements; trained models come from the trainer's export.
    pub fn random(kind: ModelKind, dims: Dims, seed: u64) -> Self {
        let mut state = seed;
        let mut next = move || {
            // SplitMix64: tiny, seedable, and the same on every platform.
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        };
        let mut mlp = |sizes: &[usize], last: Activation| -> Vec<FloatLayer> {
            sizes
                .windows(2)
                .enumerate()
                .map(|(i, w)| {
                    let bound = 1.0 / libm::sqrtf(w[0] as f32);
                    FloatLayer {
                        in_dim: w[0],
                        out_dim: w[1],
                        weights: (0..w[0] * w[1]).map(|_| next() * bound).collect(),
                        bias: (0..w[1]).map(|_| next() * bound).collect(),
                        activation: if i + 2 == sizes.len() {
                            last
                        } else {
                            Activation::Relu
                        },
                    }
                })
                .collect()
        };
        let transition = match kind {
            ModelKind::StateAction => 2 * dims.obs + dims.act,
            ModelKind::StateOnly => 2 * dims.obs,
        };
        let h = dims.hidden;
        FloatModel {
            kind,
            obs_dim: dims.obs,
            act_dim: dims.act,
            r_dim: dims.r,
            z_dim: dims.z,
            obs_mean: alloc::vec![0.0; dims.obs],
            obs_std: alloc::vec![1.0; dims.obs],
            act_scale: alloc::vec![1.0; dims.act],
            act_offset: alloc::vec![0.0; dims.act],
            encoder: mlp(&[transition, h, h, dims.r], Activation::Identity),
            z_head: mlp(&[dims.r, dims.z], Activation::Identity),
            policy: mlp(&[dims.obs + dims.z, h, h, dims.act], Activation::Identity),
        }
    }
}
