//! Flash and RAM footprint of a policy on the device, at the default sizes.
//!
//! ```sh
//! cargo run -p infer-core --release --features alloc --example footprint
//! ```
//!
//! Flash = blob bytes. RAM = what the device keeps while running: the runners' buffers
//! (sized by their capacity `W`, chosen to fit the widest layer) and the parsed `Model`
//! descriptors (slices into flash, no weights).

use core::mem::size_of;

use infer_core::{
    Calibration, ContextEncoder, Dims, FloatModel, Model, ModelKind, Policy, Quant, write_blob,
};

fn row<const W: usize>(hidden: usize, quant: Quant) {
    let float = FloatModel::random(ModelKind::StateAction, Dims::default_with_hidden(hidden), 1);
    let t: Vec<f32> = vec![0.1; 2 * float.obs_dim + float.act_dim];
    let calib = Calibration {
        contexts: vec![vec![vec![t; 4]]],
        observations: vec![vec![0.1; float.obs_dim]],
    };
    let blob = write_blob(&float, quant, &calib).expect("random model writes");
    let model = Model::from_bytes(&blob).expect("blob loads");
    assert!(model.max_width() <= W);
    let encoder = size_of::<ContextEncoder<'_, '_, W>>();
    let policy = size_of::<Policy<'_, '_, W>>();
    let descriptors = size_of::<Model<'_>>();
    println!(
        "| {hidden} | {quant:?} | {} | {:.1} | {W} | {encoder} | {policy} | {} | {descriptors} | {} |",
        blob.len(),
        blob.len() as f32 / 1024.0,
        encoder + policy,
        encoder + policy + descriptors,
    );
}

fn main() {
    println!(
        "obs 20, act 6, r 32, z 16; encoder 46-h-h-32, head 32-16 (linear), policy 36-h-h-6\n"
    );
    println!(
        "| hidden | quant | flash (blob) B | KiB | W | encoder state+scratch B | policy scratch B | runners B | model descriptors B | RAM total B |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for quant in [Quant::F32, Quant::W8A32, Quant::W8A8] {
        row::<64>(64, quant);
    }
    for quant in [Quant::F32, Quant::W8A32, Quant::W8A8] {
        row::<128>(128, quant);
    }
}
