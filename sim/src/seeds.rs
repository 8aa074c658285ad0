//! Episode reset seeds by purpose, in one place. Each purpose has its own range, so training
//! rollouts, validation, evaluation, relabelling and demos never replay one another's initial
//! states, and the same purpose in two programs (the trainer's evaluation and firmware-sim's
//! device episodes) faces the same ones.

/// Training rollouts of a run seeded `s`: episode `e` resets with `s * TRAINING_SEED_STRIDE + e`
/// (SMILe's task rollouts, a SAC expert's episodes). A prime, so runs with nearby seeds do not
/// share episodes.
pub const TRAINING_SEED_STRIDE: u64 = 1_000_003;

/// A SAC expert's own evaluation episodes: `EXPERT_EVAL_SEED + k`.
pub const EXPERT_EVAL_SEED: u64 = 1_000_000;

/// Validation on held-out meta-train tasks (the kept policy's pick): context draw `d`,
/// episode `e` resets with `VALIDATION_SEED + d * 1000 + e`.
pub const VALIDATION_SEED: u64 = 3_000_000;

/// Meta-DAgger's relabelled rollouts: `DAGGER_SEED + episode`.
pub const DAGGER_SEED: u64 = 5_000_000;

/// Meta-test evaluation (the paper's protocol, its reference policies, rendered episodes and
/// firmware-sim's device episodes): draw `d`, rollout `r` resets with
/// `EVALUATION_SEED + d * 1000 + r`.
pub const EVALUATION_SEED: u64 = 7_000_000;
