//! The networks: each a type with `new` and `forward`, built from one fused dense layer.
//!
//! * [`Mlp`] / [`FrozenMlp`]: ReLU MLPs (trainable; Polyak targets in their own storage).
//! * [`TanhGaussianPolicy`]: SAC's tanh-squashed Gaussian policy.
//! * [`ContextEncoder`]: the permutation-invariant encoder `q(z | c)` over expert demos, and the
//!   observation normalisation every meta-learner shares.
//! * [`Discriminator`]: SMILe's context-conditioned AIRL discriminator `D(x, z)` and its losses.
//! * [`MetaPolicy`]: encoder + conditioned policy, the artefact every meta-learner saves.

pub(crate) mod context;
mod discriminator;
mod fused;
mod meta_policy;
mod mlp;
mod policy;

pub use context::{
    ContextBatch, ContextConfig, ContextEncoder, ContextSpec, ObsNorm, policy_input,
};
pub(crate) use discriminator::bce_with_logits;
pub use discriminator::{DiscInput, DiscStats, Discriminator};
pub use fused::SharedCols;
pub(crate) use fused::TanhGaussian;
pub(crate) use fused::{OnSlices, SliceUpdate};
pub use meta_policy::{ConditionedActor, META_POLICY_FILE, MetaPolicy, TrainingMark};
pub(crate) use meta_policy::{mlp_load, mlp_tensors};
pub(crate) use mlp::check_shapes;
pub use mlp::{FrozenMlp, Input, Mlp};
pub use policy::{PolicySample, TanhGaussianPolicy};

/// A checkpoint's tensors, looked up by name: what each saved state is restored through.
pub(crate) type TensorLookup<'a> = &'a dyn Fn(&str) -> crate::error::Result<candle_core::Tensor>;

/// The single value of a one-element tensor (a loss or a mean), for logging.
pub(crate) fn scalar(t: &candle_core::Tensor) -> crate::error::Result<f32> {
    Ok(t.to_dtype(candle_core::DType::F32)?
        .flatten_all()?
        .to_vec1::<f32>()?[0])
}
