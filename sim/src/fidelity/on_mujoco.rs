//! The probe's plant on the MuJoCo backend: the starts, action order and state vector of
//! `docs/scripts/fidelity_mujoco.py`, through `sim::mujoco::MjPlant`.
use super::{PI, Plant, Robot, Start};
use crate::mujoco::{MjPlant, xml};
use crate::plant::{Plant as _, Robot as PlantRobot};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

pub(super) struct MjProbe {
    plant: MjPlant,
    robot: Robot,
    welded: bool,
    /// ctrl[i] = action[perm[i]]: actuator i drives the joint number perm[i] (qpos order).
    perm: Vec<usize>,
}

fn plant_robot(robot: Robot) -> PlantRobot {
    match robot {
        Robot::Cheetah => PlantRobot::HalfCheetah,
        Robot::Walker => PlantRobot::Walker2d,
        Robot::Ant => PlantRobot::Ant,
    }
}

/// The rest pose: qpos0, the ant's `init_qpos` custom numeric (as the probe script).
fn rest_qpos(plant: &MjPlant, robot: Robot) -> Vec<f64> {
    let qpos0 = plant.model().qpos0().to_vec();
    match robot {
        Robot::Ant => plant.model().numeric_data()[..qpos0.len()].to_vec(),
        _ => qpos0,
    }
}

/// The XML with the root joints removed and the torso body at its rest height + `lift`.
fn welded_xml(robot: Robot, lift: f32) -> String {
    let (roots, rest_z): (&[&str], f64) = match robot {
        Robot::Cheetah => (&["rootx", "rootz", "rooty"], 0.7),
        Robot::Walker => (&["rootx", "rootz", "rooty"], 1.25),
        // The free joint puts the torso at init_qpos z.
        Robot::Ant => (&["root"], 0.55),
    };
    let mut text = xml(plant_robot(robot)).to_string();
    for name in roots {
        let key = format!("name=\"{name}\"");
        let at = text
            .find(&key)
            .expect("the vendored XML names its root joints");
        let start = text[..at].rfind("<joint").expect("a joint element");
        let end = at + text[at..].find("/>").expect("a closed joint element") + 2;
        text.replace_range(start..end, "");
    }
    let tag = text.find("<body name=\"torso\"").expect("a torso body");
    let pos = tag + text[tag..].find("pos=\"").expect("the torso's pos") + 5;
    let close = pos + text[pos..].find('"').expect("a closed pos");
    let z = rest_z + f64::from(lift);
    text.replace_range(pos..close, &format!("0 0 {z}"));
    text
}

impl MjProbe {
    pub(super) fn build(robot: Robot, start: Start) -> Self {
        let which = plant_robot(robot);
        let full = MjPlant::new(which).expect("the MuJoCo backend loads its own XMLs");
        let rest = rest_qpos(&full, robot);
        let (mut plant, welded) = match start {
            Start::Welded(lift) => {
                let plant = MjPlant::from_xml(which, &welded_xml(robot, lift))
                    .expect("the welded XML loads");
                (plant, true)
            }
            _ => (full, false),
        };
        let model = plant.model();
        let joints: Vec<usize> = model
            .actuator_trnid()
            .iter()
            .map(|t| model.jnt_qposadr()[t[0] as usize] as usize)
            .collect();
        let mut order = joints.clone();
        order.sort_unstable();
        let perm = joints
            .iter()
            .map(|q| order.iter().position(|o| o == q).unwrap_or(0))
            .collect();
        let nv = plant.qvel().len();
        let root = rest.len() - order.len();
        match start {
            Start::Noise(seed) => {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                let walker = robot == Robot::Walker;
                let r = if walker { 5e-3 } else { 0.1 };
                let qpos: Vec<f64> = rest.iter().map(|q| q + rng.random_range(-r..r)).collect();
                let qvel: Vec<f64> = (0..nv)
                    .map(|_| {
                        if walker {
                            rng.random_range(-r..r)
                        } else {
                            let n: f64 = StandardNormal.sample(&mut rng);
                            0.1 * n
                        }
                    })
                    .collect();
                let _ = plant.set_state(&qpos, &qvel);
            }
            Start::Rest => {
                let _ = plant.set_state(&rest, &vec![0.0; nv]);
            }
            Start::Welded(_) => {
                let _ = plant.set_state(&rest[root..], &vec![0.0; nv]);
            }
        }
        Self {
            plant,
            robot,
            welded,
            perm,
        }
    }

    fn planar(&self) -> bool {
        self.robot != Robot::Ant
    }

    fn up_z(&self) -> f32 {
        if self.welded {
            return 1.0;
        }
        let q = &self.plant.qpos()[3..7];
        (1.0 - 2.0 * (q[1] * q[1] + q[2] * q[2])) as f32
    }
}

impl Plant for MjProbe {
    fn step(&mut self, action: &[f32]) {
        let ctrl: Vec<f64> = self
            .perm
            .iter()
            .map(|&j| f64::from(action[j].clamp(-1.0, 1.0)))
            .collect();
        self.plant.step_ctrl(&ctrl);
        // The script measures contacts on the state reached.
        self.plant.forward();
    }

    fn state(&self) -> Vec<f32> {
        let (q, v) = (self.plant.qpos(), self.plant.qvel());
        let mut s: Vec<f64> = match (self.planar(), self.welded) {
            (true, false) => q[1..].iter().chain(v).copied().collect(),
            (true, true) => [0.0, 0.0]
                .iter()
                .chain(q)
                .chain(&[0.0; 3])
                .chain(v)
                .copied()
                .collect(),
            (false, false) => q[2..].iter().chain(v).copied().collect(),
            (false, true) => [0.0, 1.0, 0.0, 0.0, 0.0]
                .iter()
                .chain(q)
                .chain(&[0.0; 6])
                .chain(v)
                .copied()
                .collect(),
        };
        // The ant's quaternion with w >= 0, as FIDELITY.md's state vector.
        if !self.planar() && s[1] < 0.0 {
            s[1..5].iter_mut().for_each(|c| *c = -*c);
        }
        s.into_iter().map(|x| x as f32).collect()
    }

    fn x(&self) -> f32 {
        if self.welded {
            0.0
        } else {
            self.plant.qpos()[0] as f32
        }
    }

    fn height(&self) -> f32 {
        self.plant.torso().position[2]
    }

    fn tilt(&self) -> f32 {
        match (self.planar(), self.welded) {
            (_, true) => 0.0,
            (true, false) => self.plant.qpos()[2] as f32,
            (false, false) => self.up_z().clamp(-1.0, 1.0).acos(),
        }
    }

    fn upside_down(&self) -> bool {
        if self.planar() {
            self.tilt().abs() > PI / 2.0
        } else {
            self.up_z() < 0.0
        }
    }

    fn healthy(&self) -> bool {
        if self.robot != Robot::Walker || self.welded {
            return true;
        }
        let z = self.height();
        z > 0.8 && z < 2.0 && self.tilt().abs() < 1.0
    }

    fn penetration(&self) -> f32 {
        self.plant.ground_penetration() as f32
    }
}
