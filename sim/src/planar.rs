//! Shared pieces of the planar articulated robots (cheetah, walker).

/// Both planar legged robots have six torque-controlled joints.
pub const ACT_DIM: usize = 6;
/// Observation of both planar legged robots: torso height and angle, six joint angles, torso
/// (vx, vz, angular velocity), six joint velocities. The torso x is never observed.
pub const OBS_DIM: usize = 17;
