//! Runs `Policy::act` in a loop, for instruction counting under callgrind (repeatable on a
//! noisy machine, unlike wall time):
//!
//! ```sh
//! cargo build -p infer-core --release --features alloc --example act_loop
//! valgrind --tool=callgrind target/release/examples/act_loop w8a8 64 1000
//! ```
//!
//! Instructions per `act` = (total of a run with N calls - total with 0 calls) / N.

use infer_core::{Calibration, Dims, FloatModel, Model, ModelKind, Policy, Quant, write_blob};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quant = match args.get(1).map(String::as_str) {
        Some("f32") => Quant::F32,
        Some("w8a32") => Quant::W8A32,
        _ => Quant::W8A8,
    };
    let hidden: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(64);
    let calls: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1000);
    let float = FloatModel::random(ModelKind::StateAction, Dims::default_with_hidden(hidden), 1);
    let t = vec![0.3f32; 2 * float.obs_dim + float.act_dim];
    let calib = Calibration {
        contexts: vec![vec![vec![t; 4]]],
        observations: vec![vec![0.2; float.obs_dim]],
    };
    let blob = write_blob(&float, quant, &calib).expect("random model writes");
    let model = Model::from_bytes(&blob).expect("blob loads");
    let mut policy = Policy::<128>::new(&model).expect("fits");
    let (mut obs, z, mut action) = (vec![0.1f32; 20], vec![0.2f32; 16], [0.0f32; 6]);
    let mut checksum = 0.0f32;
    for i in 0..calls {
        obs[i % 20] += 0.01;
        policy.act(&obs, &z, &mut action).expect("finite inputs");
        checksum += action[0];
    }
    println!("{quant:?} hidden {hidden}: {calls} calls, checksum {checksum}");
}
