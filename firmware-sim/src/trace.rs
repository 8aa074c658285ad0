//! What a run leaves behind: a CSV trace, an SVG plot and a printed summary.

use std::fmt::Write as _;
use std::path::Path;

use plotters::prelude::*;
use sim::RunView;

use crate::control::RunReport;

/// Writes the deterministic per-tick trace: time, the policy's obs, z, computed and applied
/// action, reward, metric sample, fault and overrun flags; with position-only sensing, then
/// the raw readings (`meas*`).
pub fn write_csv(path: &Path, report: &RunReport, z: &[f32]) -> std::io::Result<()> {
    let mut out = String::new();
    let first = report.records.first();
    let (obs_dim, act_dim) = first.map_or((0, 0), |r| (r.sensed.len(), r.applied.len()));
    let measured = first.map_or(0, |r| r.measured.len());
    let mut header = vec!["tick".to_string(), "time".to_string()];
    header.extend((0..obs_dim).map(|i| format!("obs{i}")));
    header.extend((0..z.len()).map(|i| format!("z{i}")));
    header.extend((0..act_dim).map(|i| format!("computed{i}")));
    header.extend((0..act_dim).map(|i| format!("action{i}")));
    header.extend(
        [
            "reward",
            "metric_sample",
            "forward_velocity",
            "fault",
            "overrun",
        ]
        .map(String::from),
    );
    header.extend((0..measured).map(|i| format!("meas{i}")));
    writeln!(out, "{}", header.join(",")).ok();
    for r in &report.records {
        let mut row = vec![r.tick.to_string(), format!("{}", r.time)];
        row.extend(r.sensed.iter().map(|v| format!("{v}")));
        row.extend(z.iter().map(|v| format!("{v}")));
        row.extend(r.computed.iter().map(|v| format!("{v}")));
        row.extend(r.applied.iter().map(|v| format!("{v}")));
        row.extend([
            format!("{}", r.reward),
            format!("{}", r.metric_sample),
            format!("{}", r.forward_velocity),
            (r.fault as u8).to_string(),
            (r.overrun as u8).to_string(),
        ]);
        row.extend(r.measured.iter().map(|v| format!("{v}")));
        writeln!(out, "{}", row.join(",")).ok();
    }
    crate::files::write_atomic(path, out.as_bytes())
}

/// Plots the run: the xy path to the goal (point-goal, ant-goal) or forward velocity against
/// the target over time (cheetah-vel, walker-dyn).
pub fn write_plot(path: &Path, report: &RunReport) -> Result<(), Box<dyn std::error::Error>> {
    // Drawn in memory, then written atomically: a failed write leaves no partial SVG.
    let mut svg = String::new();
    let root = SVGBackend::with_string(&mut svg, (720, 480)).into_drawing_area();
    root.fill(&WHITE)?;
    let family = report.task.family();
    let title = format!(
        "firmware-sim: {} {} (metric {:.3})",
        family,
        report.task.label(),
        report.metric
    );
    match family.spec().view {
        // `xy`: where the family observes its (x, y): point-goal first, the ant's torso last.
        RunView::GoalPath { xy } => {
            let goal = report.task.goal().unwrap_or_default();
            let mut chart = ChartBuilder::on(&root)
                .caption(title, ("sans-serif", 18))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(45)
                .build_cartesian_2d(-2.5f32..2.5f32, -2.5f32..2.5f32)?;
            chart
                .configure_mesh()
                .x_desc("x (m)")
                .y_desc("y (m)")
                .draw()?;
            let path_xy = report
                .records
                .iter()
                .map(|r| (r.plant_obs[xy], r.plant_obs[xy + 1]));
            chart
                .draw_series(LineSeries::new(path_xy, BLUE.stroke_width(2)))?
                .label("device path")
                .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLUE.stroke_width(2)));
            chart
                .draw_series(std::iter::once(Circle::new(
                    (goal[0], goal[1]),
                    6,
                    RED.filled(),
                )))?
                .label("goal")
                .legend(|(x, y)| Circle::new((x + 10, y), 5, RED.filled()));
            chart
                .configure_series_labels()
                .background_style(WHITE)
                .border_style(BLACK)
                .draw()?;
        }
        RunView::Velocity { target } => {
            let t_max = report.records.last().map_or(1.0, |r| r.time.max(1e-3));
            let target = if target {
                report.task.value() as f32
            } else {
                f32::NAN
            };
            let (lo, hi) = report
                .records
                .iter()
                .map(|r| r.forward_velocity)
                .chain(target.is_finite().then_some(target))
                .fold((0.0f32, 0.5f32), |(lo, hi), v| (lo.min(v), hi.max(v)));
            let mut chart = ChartBuilder::on(&root)
                .caption(title, ("sans-serif", 18))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(45)
                .build_cartesian_2d(0f32..t_max, (lo - 0.2)..(hi + 0.2))?;
            chart
                .configure_mesh()
                .x_desc("time (s)")
                .y_desc("forward velocity (m/s)")
                .draw()?;
            let v = report.records.iter().map(|r| (r.time, r.forward_velocity));
            chart
                .draw_series(LineSeries::new(v, BLUE.stroke_width(2)))?
                .label("velocity")
                .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLUE.stroke_width(2)));
            if target.is_finite() {
                chart
                    .draw_series(LineSeries::new([(0.0, target), (t_max, target)], RED))?
                    .label("target")
                    .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], RED));
            }
            chart
                .configure_series_labels()
                .background_style(WHITE)
                .border_style(BLACK)
                .draw()?;
        }
    }
    root.present()?;
    drop(root);
    Ok(crate::files::write_atomic(path, svg.as_bytes())?)
}

/// Human summary of a run.
pub fn summary(
    report: &RunReport,
    flash_used: usize,
    flash_budget: usize,
    ram_used: usize,
    ram_budget: usize,
) -> String {
    let (min, median, p99, max) = report.compute_percentiles();
    let kind = report.task.family().metric_kind();
    format!(
        "task            {} ({})\n\
         metric          {:?} = {:.4}\n\
         ticks           {} ({} plant steps each)\n\
         overruns        {}\n\
         faults          {}\n\
         compute (us)    min {:.2}  median {:.2}  p99 {:.2}  max {:.2}\n\
         flash           {flash_used} / {flash_budget} B\n\
         ram             {ram_used} / {ram_budget} B",
        report.task.label(),
        report.task.family(),
        kind,
        report.metric,
        report.records.len(),
        report.steps_per_tick,
        report.overruns,
        report.faults,
        min as f64 / 1e3,
        median as f64 / 1e3,
        p99 as f64 / 1e3,
        max as f64 / 1e3,
    )
}
