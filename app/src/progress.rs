//! Progress bars of the `smile` commands' long loops (experts, training, evaluation, the
//! quickstart): one style, hidden under `--quiet` so scripts get clean output. The library
//! reports progress through callbacks; the app draws it here.
//!
//! When stderr is not a terminal (a background run with its output in a log file) indicatif
//! hides its bar; a plain line then goes to stderr every [`interval`] seconds instead (5 s by
//! default, `SMILE_PROGRESS_INTERVAL_S` to change it), so a log shows where the run is:
//!
//! ```text
//! [progress] 1200/5000 updates (24%), 31/s, elapsed 0:00:38, ETA 0:02:02 sps 91 ...
//! ```

use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle, WeakProgressBar};

/// Environment variable: seconds between plain progress lines when stderr is not a terminal.
pub const INTERVAL_ENV: &str = "SMILE_PROGRESS_INTERVAL_S";

/// Default seconds between plain progress lines.
pub const DEFAULT_INTERVAL_S: f64 = 5.0;

/// The interval between plain progress lines: `SMILE_PROGRESS_INTERVAL_S` when it is a positive
/// number of seconds, else [`DEFAULT_INTERVAL_S`].
pub fn interval() -> Duration {
    std::env::var(INTERVAL_ENV)
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s > 0.0)
        .and_then(|s| Duration::try_from_secs_f64(s).ok())
        .unwrap_or(Duration::from_secs_f64(DEFAULT_INTERVAL_S))
}

/// A bar over `total` units named `what` with rate and ETA; hidden when `quiet`. When stderr is
/// not a terminal, plain progress lines replace it (see the module documentation).
pub fn bar(total: u64, quiet: bool, what: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(total);
    pb.set_style(
        ProgressStyle::with_template(&format!(
            "  {{elapsed_precise}} [{{bar:30}}] {{pos}}/{{len}} {what} {{per_sec}} ETA {{eta}} {{msg}}"
        ))
        .expect("the template is a literal and valid")
        .progress_chars("=> "),
    );
    if pb.is_hidden() {
        spawn_plain_lines(pb.downgrade(), what.to_string(), interval());
    }
    pb
}

/// Prints [`plain_line`] every `every` until the bar is finished or dropped.
fn spawn_plain_lines(bar: WeakProgressBar, what: String, every: Duration) {
    let poll = every.min(Duration::from_millis(100));
    let spawned = std::thread::Builder::new()
        .name("progress-lines".into())
        .spawn(move || {
            let mut last = Instant::now();
            // Where the bar stood when first seen: a resumed run starts part way, and its rate
            // counts only the units done in this process.
            let mut start = None;
            loop {
                std::thread::sleep(poll);
                let Some(pb) = bar.upgrade() else { return };
                if pb.is_finished() {
                    return;
                }
                let (base, since) = *start.get_or_insert((pb.position(), pb.elapsed()));
                if last.elapsed() >= every {
                    last = Instant::now();
                    eprintln!("{}", plain_line(&pb, &what, base, since));
                }
            }
        });
    // Without a thread the run goes on without progress lines; nothing else depends on them.
    drop(spawned);
}

fn hms(d: Duration) -> String {
    let s = d.as_secs();
    format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
}

/// `[progress] 1200/5000 updates (24%), 31/s, elapsed 0:00:38, ETA 0:02:02 <message>`, the rate
/// (and so the ETA) measured from position `base`, reached at `since` into the bar's life.
fn plain_line(pb: &ProgressBar, what: &str, base: u64, since: Duration) -> String {
    let pos = pb.position();
    let len = pb.length().unwrap_or(0);
    let percent = if len > 0 {
        format!(" ({:.0}%)", 100.0 * pos as f64 / len as f64)
    } else {
        String::new()
    };
    let message = pb.message();
    let message = if message.is_empty() {
        String::new()
    } else {
        format!(" {message}")
    };
    // The average since the start, not indicatif's decaying estimate: between slow units
    // (sweep cells of minutes) that one falls to 0/s and its ETA to centuries.
    let elapsed = pb.elapsed();
    let done = pos.saturating_sub(base);
    let rate = done as f64 / elapsed.saturating_sub(since).as_secs_f64().max(1e-9);
    let eta = if done == 0 || len < pos {
        "?".to_string()
    } else {
        hms(Duration::from_secs_f64((len - pos) as f64 / rate))
    };
    format!(
        "[progress] {pos}/{len} {what}{percent}, {}/s, elapsed {}, ETA {eta}{message}",
        if rate < 0.1 && done > 0 {
            format!("{:.4}", rate)
        } else {
            format!("{rate:.1}")
        },
        hms(elapsed),
    )
}

/// The line a log shows for a run's event; none for step counts, expert episodes and
/// checkpoints (the bar shows those).
pub fn log_line(e: &trainer::run::RunEvent) -> Option<String> {
    use trainer::Progress;
    use trainer::run::RunEvent;
    match e {
        RunEvent::Note(text) => Some(text.clone()),
        RunEvent::Started {
            what,
            total,
            done,
            unit,
            resumed,
        } => {
            let head = match resumed {
                true => format!("resuming from {} {done}\n", unit.word),
                false => String::new(),
            };
            Some(format!("{head}{what}; {total} {}", unit.plural))
        }
        RunEvent::Progress(Progress::Eval { step, score: s }, word) => Some(match s.val_mse {
            Some(mse) => format!(
                "{word} {step}: val mse {mse:.5}, {} {:.4}",
                s.what, s.metric
            ),
            None => format!(
                "{word} {step}: {} {:.4} (best {:.4})",
                s.what, s.metric, s.best
            ),
        }),
        RunEvent::Progress(Progress::Stopped(s), word) => Some(format!(
            "early stop at {word} {s}: the held-out selection metric stopped improving"
        )),
        RunEvent::Progress(
            Progress::Steps(_) | Progress::Episode { .. } | Progress::Checkpoint(_),
            _,
        ) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plain_line_says_where_the_run_is() {
        let pb = ProgressBar::hidden();
        pb.set_length(200);
        pb.set_position(50);
        pb.set_message("smile");
        let line = plain_line(&pb, "updates", 0, Duration::ZERO);
        assert!(
            line.starts_with("[progress] 50/200 updates (25%), "),
            "{line}"
        );
        assert!(line.ends_with(" smile"), "{line}");
        // Nothing done yet: no made-up ETA.
        pb.set_position(0);
        assert!(plain_line(&pb, "cells", 0, Duration::ZERO).contains("ETA ? smile"));
        assert_eq!(hms(Duration::from_secs(3723)), "1:02:03");
    }

    #[test]
    fn a_resumed_bar_counts_its_rate_from_where_it_started() {
        let pb = ProgressBar::hidden();
        pb.set_length(1000);
        pb.set_position(600);
        std::thread::sleep(Duration::from_millis(50));
        pb.set_position(610);
        let since = Duration::from_millis(1);
        let line = plain_line(&pb, "steps", 600, since);
        let rate: f64 = line
            .split(", ")
            .find_map(|part| part.strip_suffix("/s"))
            .and_then(|r| r.parse().ok())
            .expect("a rate");
        // 10 units in about 50 ms: about 200/s, not 610 / 50 ms = 12 200/s.
        assert!(rate < 400.0, "{line}");
        // The ETA follows: 390 units at that rate are seconds, not a fraction of one.
        assert!(!line.contains("ETA 0:00:00"), "{line}");
    }
}
