//! Drawable snapshots of an episode and their rendering to SVG (one file per frame, or one
//! animated SVG of the whole episode).

/// Which plane a frame shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum View {
    /// Looking down on the x-y plane (point-goal, and the Ant families later).
    Top,
    /// Looking at the x-z plane from the side, ground at height 0 (cheetah, walker).
    Side,
}

/// What a shape stands for; decides its colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// Part of the robot.
    Robot,
    /// The goal or target.
    Goal,
    /// The ground.
    Ground,
    /// A guide line (e.g. the circle of possible goals).
    Guide,
}

/// A primitive in world coordinates (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// A filled disc.
    Circle {
        /// Centre.
        center: [f32; 2],
        /// Radius.
        radius: f32,
        /// Meaning.
        role: Role,
    },
    /// An outlined circle.
    Ring {
        /// Centre.
        center: [f32; 2],
        /// Radius.
        radius: f32,
        /// Meaning.
        role: Role,
    },
    /// A thick segment with round ends (a capsule).
    Capsule {
        /// One end.
        a: [f32; 2],
        /// The other end.
        b: [f32; 2],
        /// Half thickness.
        radius: f32,
        /// Meaning.
        role: Role,
    },
}

/// One drawable snapshot of an environment.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Plane shown.
    pub view: View,
    /// Simulated time of the snapshot, seconds.
    pub time: f32,
    /// Primitives to draw, in order.
    pub shapes: Vec<Shape>,
}
