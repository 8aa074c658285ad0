//! The cloning weight of the episodes' first steps (issue 70 item 3), shared by Meta-BC's
//! loss and SMILe + BC's cloning term.

use serde::{Deserialize, Serialize};

use crate::error::Result;

/// Demo transitions recorded before step `steps` of their episode are drawn `weight` times as
/// often as later ones (keyframe-weighted imitation, Wen et al. 2021). Where the state soon
/// says what the expert chose (ant-linclass: the torso's side from step 5-9), only the first
/// steps need the context to predict the action, and they are a small share of the rows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EarlyWeight {
    /// Transitions recorded at steps `0..steps` of their episode are weighted. Positive.
    pub steps: u32,
    /// How many times as often they are drawn: a whole number, at least 1.
    pub weight: u32,
}

impl EarlyWeight {
    /// How many times the transition recorded at `step` counts.
    pub fn copies(self, step: u32) -> u32 {
        if step < self.steps { self.weight } else { 1 }
    }

    /// Refuses a zero step count or weight, naming the key under `table` (`early`, `bc_early`).
    pub fn check(self, table: &str) -> Result<()> {
        crate::io::require_positive(&[
            (&format!("{table}.steps"), u64::from(self.steps)),
            (&format!("{table}.weight"), u64::from(self.weight)),
        ])
    }
}
