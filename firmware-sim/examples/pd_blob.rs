//! Writes the hand-built reference point-goal policy as a w8a8 blob, and one PD-expert demo
//! per test goal, so the device can be tried without training anything:
//!
//! ```sh
//! cargo run -p firmware-sim --release --example pd_blob -- runs/pd
//! cargo run -p firmware-sim --release -- run --blob runs/pd/pd.blob --env point-goal --task 3 --context runs/pd/demos.safetensors -o runs/pd/device
//! ```

use std::path::PathBuf;

use firmware_sim::reference::pd_point_goal_blob;
use infer_core::Quant;
use sim::{
    DemoDataset, EnvConfig, Family, PointGoalPdExpert, Split, TaskDemos, make_env,
    record_trajectory,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "runs/pd".into()));
    std::fs::create_dir_all(&dir)?;
    let mut env = make_env(Family::POINT_GOAL, EnvConfig::default())?;
    let expert = PointGoalPdExpert::default();
    let mut demos = DemoDataset::new(Family::POINT_GOAL, Split::Test, "scripted-pd");
    for (i, task) in Family::POINT_GOAL.test_tasks().iter().enumerate() {
        let demo = record_trajectory(env.as_mut(), task, 1000 + i as u64, |o, a| {
            expert.act(o, a).expect("oracle obs has the right length")
        })?;
        demos.tasks.push(TaskDemos {
            task: *task,
            trajectories: vec![demo],
        });
    }
    let recorded: Vec<_> = demos.tasks.iter().map(|t| &t.trajectories[0]).collect();
    let blob = pd_point_goal_blob(Quant::W8A8, &recorded)?;
    std::fs::write(dir.join("pd.blob"), &blob)?;
    demos.write(dir.join("demos.safetensors"))?;
    println!(
        "wrote {} ({} bytes) and {}",
        dir.join("pd.blob").display(),
        blob.len(),
        dir.join("demos.safetensors").display()
    );
    let args = firmware_sim::reference::pd_run_args(
        &dir.join("pd.blob"),
        &dir.join("demos.safetensors"),
        &dir.join("device"),
    );
    println!("run it on the simulated device:");
    println!(
        "  cargo run -p firmware-sim --release -- {}",
        args.join(" ")
    );
    Ok(())
}
