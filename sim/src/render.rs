//! Drawable snapshots of an episode and their rendering to SVG (one file per frame, or one
//! animated SVG of the whole episode).

/// Which plane a frame shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum View {
    /// Looking down on the x-y plane (point-goal, ant-goal).
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

/// Width and height of a rendered frame, pixels.
pub const IMAGE_SIZE: [u32; 2] = [480, 480];

/// World rectangle `[x_min, y_min, x_max, y_max]` shown by a frame: a fixed 5 m square for the
/// top view; for the side view a 4 m window following the robot, ground near the bottom.
fn viewport(frame: &Frame) -> [f32; 4] {
    match frame.view {
        View::Top => [-2.5, -2.5, 2.5, 2.5],
        View::Side => {
            let robot_x: Vec<f32> = frame
                .shapes
                .iter()
                .filter_map(|shape| match *shape {
                    Shape::Capsule {
                        a,
                        b,
                        role: Role::Robot,
                        ..
                    } => Some(0.5 * (a[0] + b[0])),
                    Shape::Circle {
                        center,
                        role: Role::Robot,
                        ..
                    } => Some(center[0]),
                    _ => None,
                })
                .collect();
            let center = if robot_x.is_empty() {
                0.0
            } else {
                robot_x.iter().sum::<f32>() / robot_x.len() as f32
            };
            [center - 2.0, -0.4, center + 2.0, 3.6]
        }
    }
}

fn colour(role: Role) -> &'static str {
    match role {
        Role::Robot => "#2b6cb0",
        Role::Goal => "#e53e3e",
        Role::Ground => "#4a5568",
        Role::Guide => "#a0aec0",
    }
}

/// The SVG elements of one frame (no document wrapper), in pixel coordinates.
fn frame_elements(frame: &Frame) -> String {
    let [x0, _, x1, y1] = viewport(frame);
    let scale = IMAGE_SIZE[0] as f32 / (x1 - x0);
    let px = |p: [f32; 2]| ((p[0] - x0) * scale, (y1 - p[1]) * scale);
    let mut out = String::new();
    for shape in &frame.shapes {
        let element = match *shape {
            Shape::Circle {
                center,
                radius,
                role,
            }
            | Shape::Ring {
                center,
                radius,
                role,
            } => {
                let (cx, cy) = px(center);
                let paint = if matches!(shape, Shape::Ring { .. }) {
                    format!(
                        r#"fill="none" stroke="{}" stroke-dasharray="4 4""#,
                        colour(role)
                    )
                } else {
                    format!(r#"fill="{}""#, colour(role))
                };
                let r = radius * scale;
                format!(r#"<circle cx="{cx:.1}" cy="{cy:.1}" r="{r:.1}" {paint}/>"#)
            }
            Shape::Capsule { a, b, radius, role } => {
                let ((ax, ay), (bx, by)) = (px(a), px(b));
                format!(
                    r#"<line x1="{ax:.1}" y1="{ay:.1}" x2="{bx:.1}" y2="{by:.1}" stroke="{}" stroke-width="{:.1}" stroke-linecap="round"/>"#,
                    colour(role),
                    (2.0 * radius * scale).max(1.0)
                )
            }
        };
        out.push_str(&element);
        out.push('\n');
    }
    out.push_str(&format!(
        r#"<text x="8" y="20" font-family="monospace" font-size="14">t = {:.2} s</text>"#,
        frame.time
    ));
    out.push('\n');
    out
}

fn document(body: &str) -> String {
    let [w, h] = IMAGE_SIZE;
    format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\">\n<rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n{body}</svg>\n"
    )
}

/// One frame as a standalone SVG document.
pub fn frame_to_svg(frame: &Frame) -> String {
    document(&frame_elements(frame))
}

/// An episode as one looping animated SVG (SMIL), `seconds_per_frame` per frame.
pub fn episode_to_animated_svg(frames: &[Frame], seconds_per_frame: f32) -> String {
    let n = frames.len().max(1);
    let total = seconds_per_frame.max(1e-3) * n as f32;
    let mut body = String::new();
    for (i, frame) in frames.iter().enumerate() {
        let start = i as f32 / n as f32;
        let end = (i + 1) as f32 / n as f32;
        let (key_times, values) = if i == 0 {
            (format!("0;{end:.6}"), "inline;none")
        } else {
            (format!("0;{start:.6};{end:.6}"), "none;inline;none")
        };
        body.push_str(&format!(
            "<g display=\"none\"><animate attributeName=\"display\" dur=\"{total:.3}s\" repeatCount=\"indefinite\" calcMode=\"discrete\" keyTimes=\"{key_times}\" values=\"{values}\"/>\n{}</g>\n",
            frame_elements(frame)
        ));
    }
    document(&body)
}

/// Writes `frame_00000.svg`, `frame_00001.svg`, ... into `dir` (created if missing) and
/// returns their paths.
pub fn write_svg_frames(
    frames: &[Frame],
    dir: impl AsRef<std::path::Path>,
) -> std::io::Result<Vec<std::path::PathBuf>> {
    let dir = dir.as_ref();
    std::fs::create_dir_all(dir)?;
    frames
        .iter()
        .enumerate()
        .map(|(i, frame)| {
            let path = dir.join(format!("frame_{i:05}.svg"));
            std::fs::write(&path, frame_to_svg(frame))?;
            Ok(path)
        })
        .collect()
}

/// Writes the episode as one animated SVG file at `path`.
pub fn write_animated_svg(
    frames: &[Frame],
    seconds_per_frame: f32,
    path: impl AsRef<std::path::Path>,
) -> std::io::Result<()> {
    std::fs::write(path, episode_to_animated_svg(frames, seconds_per_frame))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::env::make_env;
    use crate::family::EnvConfig;
    use crate::family::Family;

    fn frames_of(family: Family, steps: usize) -> Vec<Frame> {
        let mut env = make_env(family, EnvConfig::default()).unwrap();
        let mut frames = vec![env.frame()];
        for _ in 0..steps {
            env.step(&vec![0.5; env.act_dim()]).unwrap();
            frames.push(env.frame());
        }
        frames
    }

    #[test]
    fn point_goal_frames_show_robot_goal_and_circle_in_a_top_view() {
        let frames = frames_of(Family::POINT_GOAL, 3);
        assert!(frames.iter().all(|f| f.view == View::Top));
        let svg = frame_to_svg(&frames[3]);
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        assert_eq!(svg.matches("<circle").count(), 3);
        assert!(svg.contains(colour(Role::Goal)) && svg.contains("t = 0.30 s"));
    }

    #[test]
    fn legged_frames_are_side_views_with_every_capsule_and_the_ground() {
        for (family, capsules) in [(Family::CHEETAH_VEL, 8), (Family::WALKER_DYN, 7)] {
            let frames = frames_of(family, 2);
            let svg = frame_to_svg(&frames[2]);
            assert_eq!(frames[2].view, View::Side);
            assert_eq!(svg.matches("<line").count(), capsules + 1, "{family}");
            assert!(svg.contains(colour(Role::Ground)));
        }
    }

    #[test]
    fn animated_svg_has_one_group_per_frame_and_frames_are_written_to_disk() {
        let frames = frames_of(Family::POINT_GOAL, 4);
        let svg = episode_to_animated_svg(&frames, 0.1);
        assert_eq!(svg.matches("<animate ").count(), frames.len());
        assert!(svg.contains("dur=\"0.500s\""));
        let dir = std::env::temp_dir().join(format!("sim-frames-{}", std::process::id()));
        let paths = write_svg_frames(&frames, &dir).unwrap();
        assert_eq!(paths.len(), 5);
        assert!(std::fs::read_to_string(&paths[4]).unwrap().contains("<svg"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
