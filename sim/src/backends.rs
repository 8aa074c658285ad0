//! Which implementation a [`Robot`] has on each physics backend, and its dimensions: the one
//! place that names every backend's robots (adding a robot or a backend is one arm here).

use crate::ant::AntRobot;
use crate::error::SimError;
use crate::kinds::Physics;
use crate::planar::PlanarRobot;
use crate::plant::{Plant, Robot};
use crate::rapier_plant::RapierPlant;

impl Robot {
    /// The robot's name in MuJoCo's and Gymnasium's terms.
    pub fn name(self) -> &'static str {
        match self {
            Robot::HalfCheetah => "half_cheetah",
            Robot::Walker2d => "walker2d",
            Robot::Ant => "ant",
        }
    }

    /// Observation dimension (the same on every backend).
    pub fn obs_dim(self) -> usize {
        match self {
            Robot::HalfCheetah | Robot::Walker2d => crate::planar::OBS_DIM,
            Robot::Ant => crate::ant::OBS_DIM,
        }
    }

    /// Action dimension.
    pub fn act_dim(self) -> usize {
        match self {
            Robot::HalfCheetah | Robot::Walker2d => crate::planar::ACT_DIM,
            Robot::Ant => crate::ant::ACT_DIM,
        }
    }

    /// Builds the robot on `physics`, reset with seed 0 and nominal dynamics.
    pub(crate) fn plant(self, physics: Physics) -> Result<Box<dyn Plant>, SimError> {
        match physics {
            Physics::Rapier => Ok(match self {
                Robot::HalfCheetah => Box::new(RapierPlant::<PlanarRobot>::new(
                    crate::robots::half_cheetah(),
                )),
                Robot::Walker2d => {
                    Box::new(RapierPlant::<PlanarRobot>::new(crate::robots::walker()))
                }
                Robot::Ant => Box::new(RapierPlant::<AntRobot>::new(crate::ant::ant())),
            }),
            Physics::Mujoco => mujoco_plant(self),
        }
    }
}

#[cfg(feature = "mujoco")]
fn mujoco_plant(robot: Robot) -> Result<Box<dyn Plant>, SimError> {
    Ok(Box::new(crate::mujoco::MjPlant::new(robot)?))
}

#[cfg(not(feature = "mujoco"))]
fn mujoco_plant(_: Robot) -> Result<Box<dyn Plant>, SimError> {
    Err(Physics::Mujoco.unavailable())
}
