//! A progress bar on stderr, hidden when stderr is not a terminal or with `--quiet`.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;

/// Steps of the bar: progress is reported as a fraction and drawn in thousandths.
const STEPS: u64 = 1000;

pub fn bar(message: &str, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::with_draw_target(Some(STEPS), ProgressDrawTarget::hidden());
    }
    let bar = ProgressBar::new(STEPS);
    bar.set_style(
        ProgressStyle::with_template(
            "{msg} [{bar:40.cyan/blue}] {percent:>3}% {elapsed_precise} ETA {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_message(message.to_string());
    bar
}

/// A callback for the library's fractional progress.
pub fn callback(bar: &ProgressBar) -> impl Fn(f64) + Sync + '_ {
    move |f| bar.set_position((f * STEPS as f64) as u64)
}
