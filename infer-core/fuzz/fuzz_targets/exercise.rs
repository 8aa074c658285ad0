//! Shared by the fuzz targets: load a blob and, if it loads, run every entry point on it.

use infer_core::{ContextEncoder, Model, Policy};

/// `Model::from_bytes` returns a model or an error; a model that loads must also run without
/// panicking and without a non-finite action.
pub fn exercise(blob: &[u8]) {
    let Ok(model) = Model::from_bytes(blob) else { return };
    let h = *model.header();
    let (Ok(mut encoder), Ok(mut policy)) = (ContextEncoder::<256>::new(&model), Policy::<256>::new(&model)) else {
        return;
    };
    let obs = vec![0.25f32; h.obs_dim as usize];
    let act = vec![-0.5f32; h.act_dim as usize];
    let _ = encoder.push(&obs, &act, &obs);
    let mut z = vec![0.0f32; h.z_dim as usize];
    let _ = encoder.latent(&mut z);
    let mut action = vec![0.0f32; h.act_dim as usize];
    let _ = policy.act(&obs, &z, &mut action);
    assert!(action.iter().all(|a| a.is_finite()));
}
