//! Progress bars shared by the long loops (training, evaluation, the quickstart): one style,
//! hidden under `--quiet` so scripts get clean output.

use indicatif::{ProgressBar, ProgressStyle};

/// A bar over `total` units named `what` with rate and ETA; hidden when `quiet`.
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
    pb
}
