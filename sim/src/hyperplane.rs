//! The ant-linclass task's hyperplane: its normal drawn from the task's seed. Apart from the
//! environment (`ant_linclass.rs`) so that the task type (`task.rs`) reads it without importing
//! the environment back.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Dimension of the points to classify.
pub const POINT_DIM: usize = 4;

/// The unit normal of hyperplane `seed`: a standard normal 4-vector, normalised (uniform on the
/// sphere, so every orientation is equally likely).
pub fn hyperplane_normal(seed: u64) -> [f32; POINT_DIM] {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x4c49_4e43_4c41_5353); // "LINCLASS"
    loop {
        let w: [f32; POINT_DIM] = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
        let norm = w.iter().map(|x| x * x).sum::<f32>().sqrt();
        // A draw this close to 0 has no direction worth normalising; draw again.
        if norm > 1e-3 {
            return w.map(|x| x / norm);
        }
    }
}
