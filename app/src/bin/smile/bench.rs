//! `smile bench`.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use smile_app::bench::{
    DiscBenchShape, SacBenchShape, Timing, bench_disc_step, bench_sac_update, bench_smile_pairs,
};

/// What `smile bench` times.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Workload {
    /// One SAC update (torch_reference.py `sac`: batch 256, obs 20 + z 16, act 6).
    Sac,
    /// One context-encoder + discriminator update (torch_reference.py `disc`).
    Disc,
    /// Whole SMILe iterations on meta-train demos: by default point-goal at smile_proto.py's
    /// layout (4 rollouts, then 100 pairs; 8 tasks x 64 expert + 64 policy rows, 8 x 32 SAC
    /// rows; gradient penalty 1), or a SMILe config file's (`--config`).
    Pair,
}

/// Arguments of `smile bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Workloads to time.
    #[arg(long, value_enum, num_args = 1.., default_values_t = [Workload::Sac])]
    workload: Vec<Workload>,
    /// Hidden widths to time, one shape per value: `256` is `--layers` layers of 256,
    /// `512,512,512` names every layer (for `disc`: the discriminator's; for `pair`: the
    /// discriminator's and SAC's).
    #[arg(long, num_args = 1.., default_values = ["64", "128", "256"])]
    hidden: Vec<String>,
    /// Hidden layers of a shape given as one width (torch_reference's `--layers`).
    #[arg(long, default_value_t = 2)]
    layers: usize,
    /// The SMILe authors' shapes for `sac` (3 x 256 at batch 1024, z 64) and `disc`
    /// (3 x 512, encoder 2 x 256 -> r 64 -> z 64), instead of `--hidden` and the shape flags.
    #[arg(long)]
    authors: bool,
    /// SAC batch rows (torch_reference's `--batch`).
    #[arg(long, default_value_t = 256)]
    batch: usize,
    /// Context latent width (torch_reference's `--z-dim`).
    #[arg(long, default_value_t = 16)]
    z_dim: usize,
    /// Per-transition representation width of the encoder (torch_reference's `--r-dim`).
    #[arg(long, default_value_t = 32)]
    r_dim: usize,
    /// Width of the encoder's two hidden layers for `disc` (torch_reference's
    /// `--enc-hidden`; default: the discriminator's first width).
    #[arg(long)]
    enc_hidden: Option<usize>,
    /// Timed iterations per width (for `pair`: whole SMILe iterations, default 20).
    #[arg(long)]
    iters: Option<usize>,
    /// Untimed warm-up iterations per width (for `pair`: default 2).
    #[arg(long)]
    warmup: Option<usize>,
    /// Demos for `pair` (meta-train demos of the config's family).
    #[arg(
        long,
        default_value = "assets/experts/point-goal/demos-train-4x-sub20.safetensors"
    )]
    demos: PathBuf,
    /// For `pair`: a SMILe config file (e.g. docs/configs/authors-cv-smile.toml) whose
    /// networks, batches and schedule are timed as they are, instead of the prototype's
    /// layout at `--hidden`.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Learner threads: for `sac` and `disc` the step runs in a pool of this many threads that
    /// splits its large products; for `pair` SMILe's `learner_threads` (N > 1 also overlaps the
    /// discriminator and SAC steps of each pair).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..=256))]
    learner_threads: u16,
    /// Also write the results as one JSON array to this file.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// `256` -> `layers` x 256, `512,512,512` -> as given.
fn parse_hidden(v: &str, layers: usize) -> Result<Vec<usize>> {
    let widths = v
        .split(',')
        .map(|w| w.trim().parse::<usize>())
        .collect::<Result<Vec<_>, _>>()
        .with_context(|| {
            format!("--hidden {v:?}: widths are positive integers, e.g. 256 or 512,512,512")
        })?;
    if widths.is_empty() || widths.contains(&0) {
        bail!("--hidden {v:?}: widths are positive integers, e.g. 256 or 512,512,512");
    }
    Ok(if widths.len() == 1 {
        vec![widths[0]; layers.max(1)]
    } else {
        widths
    })
}

/// `256x3` or `64,128`.
fn label(h: &[usize]) -> String {
    if h.iter().all(|w| *w == h[0]) {
        format!("{}x{}", h[0], h.len())
    } else {
        h.iter()
            .map(|w| w.to_string())
            .collect::<Vec<_>>()
            .join(",")
    }
}

fn row(h: &str, t: &Timing, flops: f64) -> String {
    format!(
        "{h:>12} {:>12.1} {:>10.1} {:>10.1} {:>10.1} {:>12} {:>8.3} {:>8.1}",
        t.median_us,
        t.p10_us,
        t.p90_us,
        t.updates_per_s,
        t.cpu_mean_us.map_or("n/a".into(), |c| format!("{c:.1}")),
        flops / 1e9,
        flops / t.median_us / 1e3,
    )
}

/// What every workload's table shares: the arguments, the parsed widths, the thread counts and
/// the table header; rows go to `rows` for `--json`.
struct Bench<'a> {
    a: &'a BenchArgs,
    shapes: Vec<Vec<usize>>,
    threads: usize,
    pool: trainer::threads::LearnerPool,
    header: String,
    rows: Vec<serde_json::Value>,
}

/// Run the benchmarks and print a table per workload.
pub fn run(a: BenchArgs) -> Result<()> {
    let header = format!(
        "{:>12} {:>12} {:>10} {:>10} {:>10} {:>12} {:>8} {:>8}",
        "hidden", "median_us", "p10_us", "p90_us", "upd/s", "cpu_mean_us", "GFLOP", "GFLOP/s"
    );
    let shapes: Vec<Vec<usize>> = a
        .hidden
        .iter()
        .map(|h| parse_hidden(h, a.layers))
        .collect::<Result<_>>()?;
    let mut b = Bench {
        a: &a,
        shapes,
        threads: trainer::threads::compute_threads(),
        pool: trainer::threads::LearnerPool::new(a.learner_threads.into())?,
        header,
        rows: Vec::new(),
    };
    for &w in &a.workload {
        match w {
            Workload::Sac => b.sac()?,
            Workload::Disc => b.disc()?,
            Workload::Pair => b.pair()?,
        }
    }
    if let Some(p) = &a.json {
        std::fs::write(p, serde_json::to_string_pretty(&b.rows)? + "\n")?;
    }
    Ok(())
}

impl Bench<'_> {
    /// Prints the table header, then times each shape of `workload` with `bench` and prints
    /// and records its row.
    fn time_each<S: Clone + Send + Sync + serde::Serialize>(
        &mut self,
        workload: &str,
        list: Vec<S>,
        hidden: fn(&S) -> &Vec<usize>,
        flops: fn(&S) -> f64,
        bench: fn(S, usize, usize) -> trainer::Result<Timing>,
    ) -> Result<()> {
        println!("{}", self.header);
        let (warmup, iters) = (self.a.warmup.unwrap_or(20), self.a.iters.unwrap_or(200));
        for shape in list {
            let f = flops(&shape);
            let t = self.pool.install(|| bench(shape.clone(), warmup, iters))?;
            println!("{}", row(&label(hidden(&shape)), &t, f));
            self.rows.push(serde_json::json!({"workload": workload, "H": hidden(&shape)[0], "shape": shape, "threads": self.threads, "learner_threads": self.pool.threads(), "flops": f, "gflop_per_s": f / t.median_us / 1e3, "timing": t}));
        }
        Ok(())
    }

    /// One SAC update per shape.
    fn sac(&mut self) -> Result<()> {
        let (a, shapes, threads, pool) = (self.a, &self.shapes, self.threads, &self.pool);
        let list: Vec<SacBenchShape> = if a.authors {
            vec![SacBenchShape::authors()]
        } else {
            shapes
                .iter()
                .map(|h| SacBenchShape {
                    batch: a.batch,
                    z_dim: a.z_dim,
                    ..SacBenchShape::with_hidden(h.clone())
                })
                .collect()
        };
        let first = &list[0];
        println!(
            "sac update, batch {}, obs {} + z {}, act {}, candle threads {threads}, \
             learner threads {}",
            first.batch,
            first.obs_dim,
            first.z_dim,
            first.act_dim,
            pool.threads()
        );
        self.time_each(
            "sac",
            list,
            |s| &s.hidden,
            SacBenchShape::flops,
            bench_sac_update,
        )
    }

    /// One discriminator + encoder step per shape.
    fn disc(&mut self) -> Result<()> {
        let (a, shapes, threads, pool) = (self.a, &self.shapes, self.threads, &self.pool);
        let list: Vec<DiscBenchShape> = if a.authors {
            vec![DiscBenchShape::authors()]
        } else {
            shapes
                .iter()
                .map(|h| DiscBenchShape {
                    r_dim: a.r_dim,
                    z_dim: a.z_dim,
                    ..DiscBenchShape::with_hidden(h.clone(), vec![a.enc_hidden.unwrap_or(h[0]); 2])
                })
                .collect()
        };
        let first = &list[0];
        println!(
            "disc + encoder update, {} tasks x {} x {} context steps through the encoder \
             ({}) -> r {} -> z {}, {} + {} rows per task, obs {}, act {}, gp {}, \
             candle threads {threads}, learner threads {}",
            first.tasks,
            first.ctx_trajs,
            first.ctx_len,
            match a.enc_hidden {
                _ if a.authors => label(&first.enc_hidden),
                Some(w) => format!("{w}x2"),
                None => "each shape's first width x 2".into(),
            },
            first.r_dim,
            first.z_dim,
            first.samples,
            first.samples,
            first.obs_dim,
            first.act_dim,
            first.gp_weight,
            pool.threads()
        );
        self.time_each(
            "disc",
            list,
            |s| &s.hidden,
            DiscBenchShape::flops,
            bench_disc_step,
        )
    }

    /// Whole SMILe iterations (rollouts and update pairs) on real demos.
    fn pair(&mut self) -> Result<()> {
        let (a, shapes, threads) = (self.a, &self.shapes, self.threads);
        let rows = &mut self.rows;
        let demos = sim::DemoDataset::read(&a.demos)
            .with_context(|| format!("reading the demos {}", a.demos.display()))?;
        let file = match &a.config {
            Some(p) => {
                let text = std::fs::read_to_string(p)
                    .with_context(|| format!("reading {}", p.display()))?;
                let cfg: trainer::smile::SmileConfig = trainer::from_toml_over_defaults(&text)
                    .with_context(|| format!("parsing {}", p.display()))?;
                Some(cfg)
            }
            None => None,
        };
        let configs: Vec<(String, trainer::smile::SmileConfig)> = match file {
            Some(cfg) => vec![(
                label(&cfg.disc_hidden),
                trainer::smile::SmileConfig {
                    env: demos.family,
                    physics: demos.physics,
                    learner_threads: a.learner_threads.into(),
                    ..cfg
                },
            )],
            None => shapes
                .iter()
                .map(|h| {
                    let mut cfg = trainer::smile::SmileConfig {
                        env: demos.family,
                        physics: demos.physics,
                        rollouts_per_iter: 4,
                        updates_per_iter: 100,
                        sac_per_task: 32,
                        disc_hidden: h.clone(),
                        learner_threads: a.learner_threads.into(),
                        ..Default::default()
                    };
                    cfg.sac.hidden = h.clone();
                    (label(h), cfg)
                })
                .collect(),
        };
        for (name, cfg) in configs {
            println!(
                "SMILe iterations on {} ({}, {} plant): {} rollouts + {} pairs, disc {} on {} + {} rows x {} tasks, \
                 SAC {} on {} x {} rows, candle threads {threads}, learner threads {}",
                demos.family,
                a.demos.display(),
                demos.physics,
                cfg.rollouts_per_iter,
                cfg.updates_per_iter,
                label(&cfg.disc_hidden),
                cfg.disc_per_task,
                cfg.disc_per_task,
                cfg.tasks_per_batch,
                label(&cfg.sac.hidden),
                cfg.sac_per_task,
                cfg.tasks_per_batch,
                a.learner_threads
            );
            println!(
                "{:>12} {:>14} {:>22} {:>10}",
                "disc hidden", "per_pair_us", "updates_only_per_pair", "pairs/s"
            );
            let t = bench_smile_pairs(cfg, &demos, a.warmup.unwrap_or(2), a.iters.unwrap_or(20))?;
            println!(
                "{name:>12} {:>14.1} {:>22.1} {:>10.1}",
                t.per_pair_us, t.updates_only_per_pair_us, t.pairs_per_s
            );
            rows.push(serde_json::json!({"workload": "pair", "hidden": name, "config": a.config, "threads": threads, "learner_threads": a.learner_threads, "timing": t}));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hidden_takes_a_width_or_every_layer() {
        assert_eq!(parse_hidden("256", 3).unwrap(), vec![256; 3]);
        assert_eq!(parse_hidden("512,512,512", 2).unwrap(), vec![512; 3]);
        assert_eq!(parse_hidden("64,32", 2).unwrap(), vec![64, 32]);
        assert!(parse_hidden("0", 2).is_err());
        assert!(parse_hidden("a,1", 2).is_err());
        assert_eq!(label(&[256, 256, 256]), "256x3");
        assert_eq!(label(&[64, 32]), "64,32");
    }
}
