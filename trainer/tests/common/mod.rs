//! Shared by the trainer's integration tests: the demo fixtures.
#![allow(dead_code)]

mod demos;

pub use demos::*;
