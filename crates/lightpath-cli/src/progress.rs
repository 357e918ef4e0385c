//! A progress bar on stderr, hidden when stderr is not a terminal or with `--quiet`:
//! elapsed time, ETA, samples per pixel so far, samples/s and rays/s.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use lightpath::render::Progress;
use std::io::IsTerminal;

/// Steps of the bar: progress is reported as a fraction and drawn in thousandths.
const STEPS: u64 = 1000;

/// Whether a bar would be drawn.
pub fn visible(quiet: bool) -> bool {
    !quiet && std::io::stderr().is_terminal()
}

pub fn bar(name: &str, quiet: bool) -> ProgressBar {
    if !visible(quiet) {
        return ProgressBar::with_draw_target(Some(STEPS), ProgressDrawTarget::hidden());
    }
    let bar = ProgressBar::with_draw_target(Some(STEPS), ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template(
            "{prefix} [{bar:16.cyan/blue}] {percent:>3}% {elapsed} ETA {eta} {wide_msg}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_prefix(name.to_string());
    bar
}

/// A spinner with a message for work of unknown length (loading, building), drawn only
/// where the bar would be.
pub fn spinner(message: &str, quiet: bool) -> ProgressBar {
    if !visible(quiet) {
        return ProgressBar::hidden();
    }
    let s = ProgressBar::new_spinner();
    s.set_style(ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("valid template"));
    s.set_message(message.to_string());
    s.enable_steady_tick(std::time::Duration::from_millis(120));
    s
}

/// `12.3 M` for 12.3e6.
pub fn si(v: f64) -> String {
    if v >= 1e9 {
        format!("{:.2} G", v / 1e9)
    } else if v >= 1e6 {
        format!("{:.2} M", v / 1e6)
    } else if v >= 1e3 {
        format!("{:.1} k", v / 1e3)
    } else {
        format!("{v:.0}")
    }
}

/// `12M` for 12.3e6: short, for the bar.
fn short(v: f64) -> String {
    let (v, unit) = if v >= 1e9 {
        (v / 1e9, "G")
    } else if v >= 1e6 {
        (v / 1e6, "M")
    } else if v >= 1e3 {
        (v / 1e3, "k")
    } else {
        (v, "")
    };
    if v < 10.0 && !unit.is_empty() {
        format!("{v:.1}{unit}")
    } else {
        format!("{v:.0}{unit}")
    }
}

/// The bar's message for a progress report (short enough for an 80-column terminal).
pub fn message(p: &Progress) -> String {
    let s = p.elapsed.as_secs_f64().max(1e-9);
    format!(
        "{} spp, {} samples/s, {} rays/s",
        p.spp,
        short(p.samples as f64 / s),
        short(p.rays as f64 / s)
    )
}

/// A callback for the library's progress reports (cheap when the bar is hidden).
pub fn callback(bar: &ProgressBar) -> impl Fn(&Progress) + Sync + '_ {
    let hidden = bar.is_hidden();
    move |p: &Progress| {
        if hidden {
            return;
        }
        bar.set_position((p.fraction * STEPS as f64) as u64);
        bar.set_message(message(p));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates() {
        assert_eq!(si(12_345_678.0), "12.35 M");
        assert_eq!(si(999.0), "999");
        let p = Progress {
            fraction: 0.5,
            spp: 8,
            samples: 2_000_000,
            rays: 6_000_000,
            elapsed: std::time::Duration::from_secs(2),
        };
        assert_eq!(message(&p), "8 spp, 1.0M samples/s, 3.0M rays/s");
        assert_eq!(short(123_456_789.0), "123M");
        assert_eq!(short(950.0), "950");
    }
}
