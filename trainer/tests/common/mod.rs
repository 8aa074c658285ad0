//! Shared by the trainer's integration tests: the demo fixtures, network weights as numbers.
#![allow(dead_code)]

mod demos;

pub use demos::*;

/// Every value of `vars`, in order, as one flat vector (to compare a network's weights).
pub fn flat_values(vars: &[candle_core::Var]) -> Vec<f32> {
    vars.iter()
        .flat_map(|v| {
            v.as_tensor()
                .flatten_all()
                .unwrap()
                .to_vec1::<f32>()
                .unwrap()
        })
        .collect()
}
