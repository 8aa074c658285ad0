//! Writes the hand-built reference point-goal policy as a w8a8 blob, and one PD-expert demo
//! per test goal, so the device can be tried without training anything:
//!
//! ```sh
//! cargo run -p firmware-sim --release --example pd_blob -- runs/pd
//! cargo run -p firmware-sim --release -- run --blob runs/pd/pd.blob --env point-goal --task 3 --context runs/pd/demos.safetensors -o runs/pd/device
//! ```

use std::path::PathBuf;

use firmware_sim::reference::pd_point_goal_model;
use infer_core::{Calibration, Quant, write_blob};
use sim::{
    DemoDataset, EnvConfig, Family, PointGoalPdExpert, Split, TaskDemos, make_env,
    record_trajectory,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "runs/pd".into()));
    std::fs::create_dir_all(&dir)?;
    let mut env = make_env(Family::PointGoal, EnvConfig::default())?;
    let expert = PointGoalPdExpert::default();
    let mut demos = DemoDataset::new(Family::PointGoal, Split::Test, "scripted-pd");
    let mut calibration = Calibration::default();
    for (i, task) in Family::PointGoal.test_tasks().iter().enumerate() {
        let demo = record_trajectory(env.as_mut(), task, 1000 + i as u64, |o, a| {
            expert.act(o, a).expect("oracle obs has the right length")
        })?;
        let rows = (0..demo.len())
            .filter_map(|k| demo.transition(k, 4, 2))
            .map(|t| [t.obs, t.action, t.next_obs].concat());
        calibration.contexts.push(vec![rows.collect()]);
        calibration
            .observations
            .extend(demo.obs.chunks(4).map(<[f32]>::to_vec));
        demos.tasks.push(TaskDemos {
            task: *task,
            trajectories: vec![demo],
        });
    }
    let blob = write_blob(&pd_point_goal_model(), Quant::W8A8, &calibration)?;
    std::fs::write(dir.join("pd.blob"), &blob)?;
    demos.write(dir.join("demos.safetensors"))?;
    println!(
        "wrote {} ({} bytes) and {}",
        dir.join("pd.blob").display(),
        blob.len(),
        dir.join("demos.safetensors").display()
    );
    Ok(())
}
