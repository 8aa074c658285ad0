//! What the context encoder's z knows about the task: z (the posterior mean) for the
//! evaluation's context draws of every task, written as CSV for other tools, and a linear
//! probe that predicts the task parameter (goal (x, y), v*, the walker's log-factors, the
//! hyperplane's normal) from z.
//!
//! The probe is scored out of sample: for each task, a ridge regression `parameter ~ [z, 1]`
//! is fitted on the other tasks' rows and predicts this task's rows (leave one task out); R^2
//! is then `1 - SSE / SST` per parameter dimension over all rows. In-sample R^2 with a 16-D z
//! on a few dozen tasks would look good by chance alone. An R^2 near 0 (or below) means z
//! carries no linear trace of that parameter; near 1, z encodes it.

use std::path::Path;

use serde::Serialize;
use sim::{DemoDataset, Family, Split, Trajectory};

use super::{ConditionedActor, context_draw, contexts_for};
use crate::error::{Error, Result};

/// Ridge weight per row of the probe, on z standardised per dimension: coefficients shrink by
/// about 1 / 1.1. With a 16-D z and 25-32 tasks a nearly unregularised fit (1e-3) overfits
/// the held-in tasks (walker-dyn SMILe: R^2 -1.4 on held-out tasks, -0.37 at 0.1, -0.17 at 1);
/// at 1 a perfect linear code would read only about 0.7.
const RIDGE: f64 = 0.1;

/// z for one context draw of one task.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LatentRow {
    /// Task label.
    pub task: String,
    /// Task value (goal angle, v*, seed).
    pub value: f64,
    /// Trajectories in the context.
    pub context_size: usize,
    /// Draw index (the evaluation's draws).
    pub draw: usize,
    /// The task parameter the oracle sees.
    pub parameter: Vec<f32>,
    /// Posterior mean of z.
    pub z: Vec<f32>,
}

/// z for `draws` context draws of each size in `sizes`, for every task of `split`.
pub fn latents(
    actor: &mut dyn ConditionedActor,
    family: Family,
    split: Split,
    contexts: &DemoDataset,
    sizes: &[usize],
    draws: usize,
) -> Result<Vec<LatentRow>> {
    let tasks = family.tasks(split);
    let demos = contexts_for(contexts, family, &tasks)?;
    let mut rows = Vec::new();
    for (i, (task, td)) in tasks.iter().zip(&demos).enumerate() {
        let trajs: Vec<&Trajectory> = td.trajectories.iter().filter(|t| !t.is_empty()).collect();
        for &k in sizes {
            for d in 0..draws {
                rows.push(LatentRow {
                    task: task.label(),
                    value: task.value(),
                    context_size: k,
                    draw: d,
                    parameter: task.parameter(),
                    z: actor.latent(&context_draw(&trajs, i, k, d))?,
                });
            }
        }
    }
    Ok(rows)
}

/// Writes `rows` as CSV (`task_value,context_size,draw,param_0..,z_0..`), atomically.
pub fn write_csv(rows: &[LatentRow], path: &Path) -> Result<()> {
    let Some(first) = rows.first() else {
        return Err(Error::Data("no latents to write".into()));
    };
    let mut header = vec![
        "task_value".to_string(),
        "context_size".into(),
        "draw".into(),
    ];
    header.extend((0..first.parameter.len()).map(|j| format!("param_{j}")));
    header.extend((0..first.z.len()).map(|j| format!("z_{j}")));
    let mut text = header.join(",");
    text.push('\n');
    for r in rows {
        let mut cells = vec![
            r.value.to_string(),
            r.context_size.to_string(),
            r.draw.to_string(),
        ];
        cells.extend(r.parameter.iter().chain(&r.z).map(|x| x.to_string()));
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    crate::io::checkpoint::write_atomic(path, text.as_bytes())
}

/// Leave-one-task-out R^2 of the linear probe, one value per parameter dimension, from the
/// rows (of one context size, typically). Tasks are told apart by their value.
pub fn probe_r2(rows: &[LatentRow]) -> Result<Vec<f64>> {
    let predicted = probe_predictions(rows)?;
    let pd = predicted.first().map_or(0, Vec::len);
    let n = rows.len() as f64;
    Ok((0..pd)
        .map(|p| {
            let m = rows.iter().map(|r| r.parameter[p] as f64).sum::<f64>() / n;
            let (mut sse, mut sst) = (0.0f64, 0.0f64);
            for (r, guess) in rows.iter().zip(&predicted) {
                sse += (r.parameter[p] as f64 - guess[p]).powi(2);
                sst += (r.parameter[p] as f64 - m).powi(2);
            }
            if sst > 0.0 { 1.0 - sse / sst } else { f64::NAN }
        })
        .collect())
}

/// The linear probe's out-of-sample prediction of every row's task parameter: row `i`'s comes
/// from the ridge fitted on the rows of every other task (leave one task out), in row order.
/// Errors on fewer than 3 tasks.
pub fn probe_predictions(rows: &[LatentRow]) -> Result<Vec<Vec<f64>>> {
    let Some(first) = rows.first() else {
        return Err(Error::Data("the probe needs rows".into()));
    };
    let (zd, pd) = (first.z.len(), first.parameter.len());
    if let Some(bad) = rows
        .iter()
        .find(|r| r.z.len() != zd || r.parameter.len() != pd)
    {
        return Err(Error::Shape(format!(
            "the probe's rows disagree: z {} and parameter {} against {zd} and {pd} (task {})",
            bad.z.len(),
            bad.parameter.len(),
            bad.task
        )));
    }
    let mut values: Vec<f64> = rows.iter().map(|r| r.value).collect();
    values.sort_by(f64::total_cmp);
    values.dedup();
    if values.len() < 3 {
        return Err(Error::Data(format!(
            "the probe needs 3 or more tasks, got {}",
            values.len()
        )));
    }
    // Standardise z over all rows, so that the ridge treats every dimension alike.
    let n = rows.len() as f64;
    let mean: Vec<f64> = (0..zd)
        .map(|j| rows.iter().map(|r| r.z[j] as f64).sum::<f64>() / n)
        .collect();
    let sd: Vec<f64> = (0..zd)
        .map(|j| {
            let v = rows
                .iter()
                .map(|r| (r.z[j] as f64 - mean[j]).powi(2))
                .sum::<f64>()
                / n;
            v.sqrt().max(1e-12)
        })
        .collect();
    let features = |r: &LatentRow| -> Vec<f64> {
        let mut f: Vec<f64> = (0..zd).map(|j| (r.z[j] as f64 - mean[j]) / sd[j]).collect();
        f.push(1.0);
        f
    };
    let mut predicted = vec![Vec::new(); rows.len()];
    for held in &values {
        let train: Vec<&LatentRow> = rows.iter().filter(|r| r.value != *held).collect();
        let beta = ridge_fit(&train, &features, pd, zd + 1)?;
        for (r, out) in rows.iter().zip(predicted.iter_mut()) {
            if r.value == *held {
                let f = features(r);
                *out = beta
                    .iter()
                    .map(|b| f.iter().zip(b).map(|(x, w)| x * w).sum())
                    .collect();
            }
        }
    }
    Ok(predicted)
}

/// Per parameter dimension, the weights of `parameter ~ features` by ridge least squares.
fn ridge_fit(
    rows: &[&LatentRow],
    features: &dyn Fn(&LatentRow) -> Vec<f64>,
    pd: usize,
    fd: usize,
) -> Result<Vec<Vec<f64>>> {
    let mut gram = vec![vec![0.0f64; fd]; fd];
    let mut rhs = vec![vec![0.0f64; pd]; fd];
    for r in rows {
        let f = features(r);
        for (a, (g, h)) in gram.iter_mut().zip(rhs.iter_mut()).enumerate() {
            for (gb, fb) in g.iter_mut().zip(&f) {
                *gb += f[a] * fb;
            }
            for (hp, p) in h.iter_mut().zip(&r.parameter) {
                *hp += f[a] * *p as f64;
            }
        }
    }
    // The intercept (last feature) is not penalised.
    for (a, row) in gram.iter_mut().enumerate().take(fd - 1) {
        row[a] += RIDGE * rows.len() as f64;
    }
    solve(gram, rhs).map(|x| {
        (0..pd)
            .map(|p| x.iter().map(|row| row[p]).collect())
            .collect()
    })
}

/// Solves `a x = b` (b with several columns) by Gaussian elimination with partial pivoting.
fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<Vec<f64>>) -> Result<Vec<Vec<f64>>> {
    let n = a.len();
    for col in 0..n {
        let pivot = (col..n)
            .max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))
            .unwrap_or(col);
        if a[pivot][col].abs() < 1e-12 {
            return Err(Error::Data(
                "the probe's normal equations are singular".into(),
            ));
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let (pivot_a, pivot_b) = (a[col].clone(), b[col].clone());
        for (ar, br) in a.iter_mut().zip(b.iter_mut()).skip(col + 1) {
            let factor = ar[col] / pivot_a[col];
            for (x, p) in ar.iter_mut().zip(&pivot_a).skip(col) {
                *x -= factor * p;
            }
            for (x, p) in br.iter_mut().zip(&pivot_b) {
                *x -= factor * p;
            }
        }
    }
    let m = b.first().map_or(0, Vec::len);
    let mut x = vec![vec![0.0f64; m]; n];
    for row in (0..n).rev() {
        for k in 0..m {
            let tail: f64 = (row + 1..n).map(|j| a[row][j] * x[j][k]).sum();
            x[row][k] = (b[row][k] - tail) / a[row][row];
        }
    }
    Ok(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(value: f64, parameter: Vec<f32>, z: Vec<f32>) -> LatentRow {
        LatentRow {
            task: String::new(),
            value,
            context_size: 1,
            draw: 0,
            parameter,
            z,
        }
    }

    #[test]
    fn the_probe_finds_a_linear_code_and_not_noise() {
        // z = (2p + 1, noise) for 20 tasks: the probe recovers p; a z of pure noise does not.
        let mut coded = Vec::new();
        let mut noise = Vec::new();
        for t in 0..20 {
            let p = t as f32 / 10.0 - 1.0;
            let wiggle = ((t * 7919) % 13) as f32 / 13.0 - 0.5;
            coded.push(row(t as f64, vec![p], vec![2.0 * p + 1.0, wiggle]));
            noise.push(row(t as f64, vec![p], vec![wiggle, (t % 3) as f32]));
        }
        let r2 = probe_r2(&coded).unwrap();
        assert!(r2[0] > 0.95, "{r2:?}");
        let r2 = probe_r2(&noise).unwrap();
        assert!(r2[0] < 0.3, "{r2:?}");
        assert!(probe_r2(&coded[..2]).is_err());
        assert!(probe_r2(&[]).is_err());
    }

    #[test]
    fn the_csv_has_one_line_per_row_and_named_columns() {
        let dir = std::env::temp_dir().join(format!("latents-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("z.csv");
        write_csv(&[row(3.0, vec![0.5, 1.0], vec![0.25])], &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(
            text,
            "task_value,context_size,draw,param_0,param_1,z_0\n3,1,0,0.5,1,0.25\n"
        );
        std::fs::remove_dir_all(&dir).ok();
    }
}
