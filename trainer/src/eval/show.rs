//! How an evaluation is shown: the markdown table and the per-task plot of [`EvalReport`].

use std::path::Path;

use super::{EvalReport, mean_std};
use crate::error::{Error, Result};

impl EvalReport {
    /// The report as a markdown table: one row per task, one column per method, then the
    /// means (and per-context-size means when there are several sizes).
    pub fn markdown(&self) -> String {
        let mut s = self.heading();
        self.task_rows(&mut s);
        self.summary_rows(&mut s);
        self.no_op_rows(&mut s);
        s
    }

    /// The title, the protocol and the table's head.
    fn heading(&self) -> String {
        let mut s = format!(
            "# {} on {} ({} tasks), metric: {} ({} is better)\n\nProtocol: context sizes {:?}, {} draws x {} deterministic rollouts, z = posterior mean{}.\n\n| task |",
            self.env,
            self.split,
            self.methods.first().map_or(0, |m| m.tasks.len()),
            self.metric,
            if self.lower_is_better {
                "lower"
            } else {
                "higher"
            },
            self.protocol.context_sizes,
            self.protocol.draws,
            self.protocol.rollouts,
            if self.env.spec().eval.falls_end_episodes {
                format!("; walker protocol: {}", self.protocol.label())
            } else {
                String::new()
            }
        );
        for m in &self.methods {
            s.push_str(&format!(" {} |", m.name));
        }
        if let Some(r) = &self.reference {
            s.push_str(&format!(" base: {} | expert: {} |", r.base, r.expert));
        }
        let columns = self.methods.len() + if self.reference.is_some() { 2 } else { 0 };
        s.push_str("\n|---|");
        s.push_str(&"---|".repeat(columns));
        s.push('\n');
        s
    }

    /// The reference's two cells (base, expert) of a row, `f` of their returns; none without
    /// a reference.
    fn reference_cells(&self, s: &mut String, f: &dyn Fn(&[f32]) -> String) {
        if let Some(r) = &self.reference {
            s.push_str(&format!(
                " {} | {} |",
                f(&r.base_returns),
                f(&r.expert_returns)
            ));
        }
    }

    /// One row per task.
    fn task_rows(&self, s: &mut String) {
        let Some(first) = self.methods.first() else {
            return;
        };
        for (i, t) in first.tasks.iter().enumerate() {
            s.push_str(&format!("| {} |", t.task));
            for m in &self.methods {
                s.push_str(&format!(" {:.3} |", m.tasks[i].metric));
            }
            self.reference_cells(s, &|r| r.get(i).map_or("-".into(), |x| format!("{x:.3}")));
            s.push('\n');
        }
    }

    /// The means over tasks and over episodes, the normalised score, the per-context-size
    /// means.
    fn summary_rows(&self, s: &mut String) {
        s.push_str("| **mean over tasks (+- std)** |");
        for m in &self.methods {
            s.push_str(&format!(" **{:.3}** +- {:.3} |", m.mean, m.std_over_tasks));
        }
        self.reference_cells(s, &|r| {
            let (m, sd) = mean_std(r);
            format!("{m:.3} +- {sd:.3}")
        });
        s.push_str("\n| episodes pooled (+- std) |");
        for m in &self.methods {
            s.push_str(&format!(" {:.3} +- {:.3} |", m.episode_mean, m.episode_std));
        }
        self.reference_cells(s, &|_| "-".into());
        s.push('\n');
        if self.reference.is_some() {
            s.push_str("| **normalised (R - R_base) / (R_expert - R_base)** |");
            for m in &self.methods {
                s.push_str(&match &m.normalised {
                    Some(n) => format!(
                        " **{}** ({} tasks, {} skipped) |",
                        n.score.map_or("-".into(), |x| format!("{x:.3}")),
                        n.tasks_used,
                        n.tasks_skipped
                    ),
                    None => " - |".into(),
                });
            }
            s.push_str(" 0 | 1 |\n");
        }
        if self.protocol.context_sizes.len() > 1 {
            for (j, k) in self.protocol.context_sizes.iter().enumerate() {
                s.push_str(&format!("| mean, {k} context demos |"));
                for m in &self.methods {
                    s.push_str(&format!(" {:.3} |", m.by_context_size[j]));
                }
                self.reference_cells(s, &|_| "-".into());
                s.push('\n');
            }
        }
    }

    /// ant-linclass's no-op rates (overall and per context size), where a method has one.
    fn no_op_rows(&self, s: &mut String) {
        if !self.methods.iter().any(|m| m.no_op_rate.is_some()) {
            return;
        }
        let cell = |x: Option<f32>| x.map_or(" - |".into(), |x| format!(" {x:.3} |"));
        s.push_str("| **no-op rate** (no decision) |");
        for m in &self.methods {
            s.push_str(&cell(m.no_op_rate));
        }
        s.push('\n');
        if self.protocol.context_sizes.len() > 1 {
            for (j, k) in self.protocol.context_sizes.iter().enumerate() {
                s.push_str(&format!("| no-op rate, {k} context demos |"));
                for m in &self.methods {
                    s.push_str(&cell(
                        m.no_op_by_context_size
                            .as_ref()
                            .and_then(|v| v.get(j).copied()),
                    ));
                }
                s.push('\n');
            }
        }
    }

    /// An SVG plot of the metric per task (x = task parameter), one line per method.
    pub fn plot_svg(&self, path: &Path) -> Result<()> {
        use plotters::prelude::*;
        let err = |e: &dyn std::fmt::Display| Error::Io {
            path: path.to_path_buf(),
            source: std::io::Error::other(e.to_string()),
        };
        let pts: Vec<(f64, f32)> = self
            .methods
            .iter()
            .flat_map(|m| m.tasks.iter().map(|t| (t.value, t.metric)))
            .collect();
        let (x0, x1) = pts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                (a.min(p.0), b.max(p.0))
            });
        let (y0, y1) = pts
            .iter()
            .filter(|p| p.1.is_finite())
            .fold((0.0f32, f32::NEG_INFINITY), |(a, b), p| {
                (a.min(p.1), b.max(p.1))
            });
        let (x0, x1) = if x0.is_finite() && x1 > x0 {
            (x0, x1)
        } else {
            (0.0, 1.0)
        };
        let y1 = if y1.is_finite() && y1 > y0 {
            y1 * 1.1
        } else {
            y0 + 1.0
        };
        // Drawn in memory, then written atomically: a failed write leaves no partial SVG.
        let mut svg = String::new();
        let root = SVGBackend::with_string(&mut svg, (760, 480)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let x_desc = self.env.value_name();
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("{} {} tasks: {}", self.env, self.split, self.metric),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(38)
            .y_label_area_size(50)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(self.metric.clone())
            .draw()
            .map_err(|e| err(&e))?;
        for (i, m) in self.methods.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let line: Vec<(f64, f32)> = m.tasks.iter().map(|t| (t.value, t.metric)).collect();
            chart
                .draw_series(LineSeries::new(line.clone(), color.stroke_width(2)))
                .map_err(|e| err(&e))?
                .label(format!("{} (mean {:.3})", m.name, m.mean))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
            chart
                .draw_series(line.into_iter().map(|p| Circle::new(p, 3, color.filled())))
                .map_err(|e| err(&e))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE)
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| err(&e))?;
        root.present().map_err(|e| err(&e))?;
        drop(chart);
        drop(root);
        crate::io::checkpoint::write_atomic(path, svg.as_bytes())
    }
}
