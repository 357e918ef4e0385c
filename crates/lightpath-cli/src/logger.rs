//! Shows the library's log records on stderr: warnings always (unless `--quiet`),
//! informational records with `--verbose`.

use log::{Level, LevelFilter, Log, Metadata, Record};

struct StderrLogger;

impl Log for StderrLogger {
    fn enabled(&self, metadata: &Metadata) -> bool {
        metadata.level() <= log::max_level()
    }

    fn log(&self, record: &Record) {
        if !self.enabled(record.metadata()) {
            return;
        }
        let prefix = match record.level() {
            Level::Error => "error",
            Level::Warn => "warning",
            Level::Info => "info",
            Level::Debug | Level::Trace => "debug",
        };
        eprintln!("{prefix}: {}", record.args());
    }

    fn flush(&self) {}
}

static LOGGER: StderrLogger = StderrLogger;

/// Installs the logger once; later calls only change the level.
pub fn init(quiet: bool, verbose: bool) {
    let _ = log::set_logger(&LOGGER);
    log::set_max_level(if quiet {
        LevelFilter::Error
    } else if verbose {
        LevelFilter::Info
    } else {
        LevelFilter::Warn
    });
}
