//! The report's files: `report.md`, `report.json` and its SVG plots, the metric per test task
//! with a band of +- one std over seeds (one line per method and setting, as the paper's
//! Figure 2), and the metric against the number of context demos. Above `report`, which only
//! aggregates: the arrow runs one way.

use std::path::{Path, PathBuf};

use plotters::coord::types::{RangedCoordf32, RangedCoordf64};
use plotters::prelude::*;

use super::Report;
use trainer::{Error, Result};

impl Report {
    /// Writes `report.md`, `report.json`, `tasks.svg` and (with several context sizes)
    /// `context-sizes.svg` into `dir`.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        std::fs::create_dir_all(dir).map_err(|e| Error::Io {
            path: dir.to_path_buf(),
            source: e,
        })?;
        let md = dir.join("report.md");
        trainer::checkpoint::write_atomic(&md, self.markdown().as_bytes())?;
        let json = dir.join("report.json");
        let text = serde_json::to_string_pretty(self).map_err(|e| Error::Serialise {
            what: "report.json",
            reason: e.to_string(),
        })?;
        trainer::checkpoint::write_atomic(&json, text.as_bytes())?;
        let tasks = dir.join("tasks.svg");
        per_task(self, &tasks)?;
        let mut written = vec![md, json, tasks];
        if self.context_sizes.len() > 1 {
            let sizes = dir.join("context-sizes.svg");
            by_context_size(self, &sizes)?;
            written.push(sizes);
        }
        Ok(written)
    }
}

fn err(path: &Path) -> impl Fn(&dyn std::fmt::Display) -> Error + '_ {
    move |e| Error::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(e.to_string()),
    }
}

fn label(r: &super::Row) -> String {
    if r.setting == "-" {
        format!("{} ({} seeds, mean {:.3})", r.method, r.seeds.len(), r.mean)
    } else {
        format!(
            "{}, {} ({} seeds, mean {:.3})",
            r.method,
            r.setting,
            r.seeds.len(),
            r.mean
        )
    }
}

fn y_range(values: impl Iterator<Item = f32>) -> std::ops::Range<f32> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((0.0f32, f32::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if hi.is_finite() && hi > lo {
        lo..hi * 1.1
    } else {
        lo..lo + 1.0
    }
}

/// What a chart of the report is: its file, size, caption, axes and descriptions.
struct ChartSpec<'a> {
    path: &'a Path,
    size: (u32, u32),
    caption: String,
    x: std::ops::Range<f64>,
    y: std::ops::Range<f32>,
    x_desc: &'a str,
    y_desc: &'a str,
}

/// The drawing area `ChartSpec::draw` hands to its series.
type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf32>>;

impl ChartSpec<'_> {
    /// Draws the axes, then `series` (the methods' lines), then the legend, in memory, and
    /// writes the SVG atomically: a failed write leaves no partial file.
    fn draw(self, series: impl FnOnce(&mut Chart<'_, '_>) -> Result<()>) -> Result<()> {
        let e = err(self.path);
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, self.size).into_drawing_area();
            root.fill(&WHITE).map_err(|x| e(&x))?;
            let mut chart = ChartBuilder::on(&root)
                .caption(self.caption, ("sans-serif", 17))
                .margin(12)
                .x_label_area_size(38)
                .y_label_area_size(50)
                .build_cartesian_2d(self.x, self.y)
                .map_err(|x| e(&x))?;
            chart
                .configure_mesh()
                .x_desc(self.x_desc)
                .y_desc(self.y_desc)
                .draw()
                .map_err(|x| e(&x))?;
            series(&mut chart)?;
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(|x| e(&x))?;
            root.present().map_err(|x| e(&x))?;
        }
        trainer::checkpoint::write_atomic(self.path, svg.as_bytes())
    }
}

/// Metric per task (x = task parameter), mean over seeds with a +- std band.
pub fn per_task(report: &Report, path: &Path) -> Result<()> {
    let e = err(path);
    let xs = report
        .rows
        .iter()
        .flat_map(|r| r.task_values.iter().copied());
    let (x0, x1) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    let (x0, x1) = if x0.is_finite() && x1 > x0 {
        (x0, x1)
    } else {
        (0.0, 1.0)
    };
    let ys = y_range(report.rows.iter().flat_map(|r| {
        r.task_mean
            .iter()
            .zip(&r.task_std)
            .map(|(m, s)| m + s)
            .collect::<Vec<_>>()
    }));
    let spec = ChartSpec {
        path,
        size: (800, 500),
        caption: format!(
            "{}: {} per test task (band: +- std over seeds)",
            report.env, report.metric
        ),
        x: x0..x1,
        y: ys,
        x_desc: report.env.value_name(),
        y_desc: &report.metric,
    };
    spec.draw(|chart| {
        for (i, r) in report.rows.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let mut band: Vec<(f64, f32)> = r
                .task_values
                .iter()
                .zip(r.task_mean.iter().zip(&r.task_std))
                .map(|(&x, (m, s))| (x, m + s))
                .collect();
            band.extend(
                r.task_values
                    .iter()
                    .zip(r.task_mean.iter().zip(&r.task_std))
                    .rev()
                    .map(|(&x, (m, s))| (x, m - s)),
            );
            chart
                .draw_series(std::iter::once(Polygon::new(
                    band,
                    color.mix(0.15).filled(),
                )))
                .map_err(|x| e(&x))?;
            let line: Vec<(f64, f32)> = r
                .task_values
                .iter()
                .copied()
                .zip(r.task_mean.iter().copied())
                .collect();
            chart
                .draw_series(LineSeries::new(line, color.stroke_width(2)))
                .map_err(|x| e(&x))?
                .label(label(r))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
        }
        Ok(())
    })
}

/// Metric (mean over tasks and seeds) against the number of context demos.
pub fn by_context_size(report: &Report, path: &Path) -> Result<()> {
    let e = err(path);
    let k0 = *report.context_sizes.first().unwrap_or(&1) as f64;
    let k1 = *report.context_sizes.last().unwrap_or(&1) as f64;
    let (k0, k1) = if k1 > k0 { (k0, k1) } else { (k0, k0 + 1.0) };
    let spec = ChartSpec {
        path,
        size: (640, 420),
        caption: format!("{}: {} vs context demos", report.env, report.metric),
        x: k0..k1,
        y: y_range(report.rows.iter().flat_map(|r| r.by_context_size.clone())),
        x_desc: "demos in the context",
        y_desc: &report.metric,
    };
    spec.draw(|chart| {
        for (i, r) in report.rows.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let pts: Vec<(f64, f32)> = report
                .context_sizes
                .iter()
                .map(|&k| k as f64)
                .zip(r.by_context_size.iter().copied())
                .collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                .map_err(|x| e(&x))?
                .label(label(r))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
            chart
                .draw_series(pts.into_iter().map(|p| Circle::new(p, 3, color.filled())))
                .map_err(|x| e(&x))?;
        }
        Ok(())
    })
}
