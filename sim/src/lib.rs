//! Planar and 3-D task families for meta-imitation learning, their paper splits, scripted
//! experts where honest, and the demo dataset format, on two physics backends.
//!
//! - [`Physics`] picks the plant per run: **Rapier** (default; robots built in code, the
//!   device's plant, nothing to install) or **MuJoCo** (feature `mujoco`; Gymnasium's XMLs in
//!   `sim/mujoco/` stepped by MuJoCo 3.17.0, bit-identical to Python MuJoCo on the same state
//!   and actions; `scripts/fetch-mujoco.sh` fetches the library). A family is written once; a
//!   [`Robot`] has one implementation per backend behind the crate's `Plant` trait
//!   (`plant.rs`), chosen by [`EnvConfig::physics`]. Demo files record their plant.
//! - [`Family`] names a task family (`point-goal`, `cheetah-vel`, `walker-dyn`, `ant-goal`,
//!   `ant-linclass`) and
//!   gives its meta-train / meta-test [`Task`] lists exactly as in the SMILe reference.
//! - [`make_env`] builds a `Box<dyn` [`Environment`]`>`; `reset(task, seed)` then `step(action)`
//!   returning a [`Transition`]. Environments are `Send`, deterministic, and never let a
//!   non-finite action reach the physics ([`SimError`]).
//! - [`EpisodeMetric`] turns the per-step [`StepInfo`] into the paper's per-episode metric.
//! - [`DemoDataset`] is the one demo file format (safetensors, grouped by task, with
//!   subsampling); [`record_trajectory`] rolls an expert out into a [`Trajectory`].
//!   Layout: `docs/DATASET.md`.
//! - [`render`] draws [`Frame`]s (from [`Environment::frame`]) as SVG files or one animated SVG.
//!
//! Robots: [`PointGoalEnv`] (a damped point mass, with the scripted [`PointGoalPdExpert`]) and
//! [`PlanarLeggedEnv`] (HalfCheetah and Walker2d analogues as Rapier multibodies with
//! torque motors, joint limits, damping and ground contact) use rapier2d; [`AntGoalEnv`]
//! (Gymnasium's Ant quadruped, [`ant`], walking to a goal) and [`AntLinClassEnv`] (the same
//! ant classifying pairs of points by walking to one of two targets) are rapier3d multibodies.
#![warn(missing_docs)]

pub mod ant;
pub mod ant_goal;
pub mod ant_linclass;
mod backends;
mod cheetah_vel;
mod dataset;
mod dynamics;
mod env;
mod error;
mod estimated;
mod export_report;
mod families;
mod family;
pub mod fidelity;
mod fsio;
mod hyperplane;
mod kinds;
pub mod legged;
#[cfg(feature = "mujoco")]
pub mod mujoco;
mod physics;
pub mod planar;
mod plant;
pub mod point_goal;
mod rapier_plant;
pub mod render;
mod robots;
pub mod seeds;
mod sensing;
mod sensor;
mod shipped;
mod spec;
mod task;
mod walker_dyn;

pub use ant_goal::AntGoalEnv;
pub use ant_linclass::AntLinClassEnv;
pub use dataset::{
    DatasetError, DemoDataset, FORMAT_NAME, FORMAT_VERSION, TaskDemos, Trajectory, TransitionRef,
    record_trajectory,
};
pub use dynamics::WalkerDynamics;
pub use env::{EpisodeMetric, make_env};
pub use error::{SimError, error_line, exit_code};
pub use estimated::{ESTIMATOR_CAPACITY, EstimatorTuning, PositionSensing, estimator_config};
pub use export_report::{ExportReport, Parity, ReportError, TaskResult};
pub use family::{
    EnvConfig, Environment, EvalDefaults, Family, FamilySpec, MetricKind, RunView, StepInfo, Task,
    Transition,
};
pub use fsio::{
    canonical_safetensors, remove_any, sha256_hex, temp_sibling, write_atomic, write_atomic_with,
};
pub use kinds::Physics;
pub use legged::{CheetahVelEnv, PlanarLeggedEnv, WalkerDynEnv};
pub use physics::MUJOCO_VERSION;
pub use plant::{Robot, TorsoPose};
pub use point_goal::{PointGoalEnv, PointGoalPdExpert};
pub use render::Frame;
pub use sensing::ObsComponent;
pub use sensor::{Sensor, SensorModel, SensorModelError, adc_lsb};
pub use shipped::{IntegrityError, SUMS_FILE, check_shipped, check_shipped_bytes, shipped_sha256};
pub use task::{
    GOAL_RADIUS, Split, TASK_VALUE_TOLERANCE, WALKER_NOMINAL_SEED, WALKER_TEST_SEED_BASE,
    WALKER_TRAIN_SEED_BASE,
};

#[cfg(test)]
mod api_tests {
    use super::*;

    fn assert_send<T: Send>() {}

    #[test]
    fn boxed_environments_are_send() {
        assert_send::<Box<dyn Environment>>();
        assert_send::<PointGoalEnv>();
        assert_send::<PlanarLeggedEnv>();
        assert_send::<AntGoalEnv>();
        assert_send::<AntLinClassEnv>();
    }
}
