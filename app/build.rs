include!("../build-support/mujoco_rpath.rs");

fn main() {
    mujoco_rpath();
}
