//! The command's own text on the terminal: tables and summaries go to standard output, or to
//! standard error when standard output carries the data (`-o -`). A write that fails (a full
//! disk, a closed pipe) is kept, the rest of the text dropped, and the error reported once at
//! exit with a non-zero status: printing never panics.

use std::io::Write as _;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, PoisonError};

static DATA_ON_STDOUT: AtomicBool = AtomicBool::new(false);
static FAILED: Mutex<Option<std::io::Error>> = Mutex::new(None);

/// Prints `args` as the command's text (see the module).
pub fn print(args: std::fmt::Arguments<'_>) {
    if DATA_ON_STDOUT.load(Ordering::Relaxed) {
        let _ = std::io::stderr().lock().write_fmt(args);
        return;
    }
    let mut failed = FAILED.lock().unwrap_or_else(PoisonError::into_inner);
    if failed.is_none() {
        if let Err(e) = std::io::stdout().lock().write_fmt(args) {
            *failed = Some(e);
        }
    }
}

/// A line beside the command's result: with `json` on standard error, out of the way of the
/// one JSON object on standard output; else with the command's text.
pub fn note(json: bool, line: &str) {
    if json {
        warn(format_args!("{line}\n"));
    } else {
        print(format_args!("{line}\n"));
    }
}

/// From now on the command's text goes to standard error: standard output is the data.
pub fn data_on_stdout() {
    DATA_ON_STDOUT.store(true, Ordering::Relaxed);
}

/// Whether standard output carries the data (`-o -`).
#[must_use]
pub fn stdout_is_data() -> bool {
    DATA_ON_STDOUT.load(Ordering::Relaxed)
}

/// Flushes standard output and returns the first error writing to it, if any.
///
/// # Errors
/// The first write error.
pub fn finish() -> std::io::Result<()> {
    let mut failed = FAILED.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some(e) = failed.take() {
        return Err(e);
    }
    std::io::stdout().lock().flush()
}

/// `println!` for the command's text (see [`crate::cli::console`]).
#[macro_export]
#[doc(hidden)]
macro_rules! outln {
    () => {
        $crate::cli::console::print(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::cli::console::print(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// Writes `args` to standard error; a failure there (a full or closed stderr) has nowhere to
/// be reported and is dropped, never a panic.
pub fn warn(args: std::fmt::Arguments<'_>) {
    let _ = std::io::stderr().lock().write_fmt(args);
}

/// `eprintln!` that never panics (see [`warn`]).
#[macro_export]
#[doc(hidden)]
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::cli::console::warn(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// A time for a person to read: four significant digits in the unit that suits it (`2.1 ms`,
/// `37.5 µs`, `1.25 s`), not `0.002100000 s`. `--json` keeps the seconds in full.
#[must_use]
pub fn duration(seconds: f64) -> String {
    let a = seconds.abs();
    let (scale, unit) = match a {
        a if a == 0.0 || !a.is_finite() || a >= 1.0 => (1.0, "s"),
        a if a >= 1e-3 => (1e3, "ms"),
        a if a >= 1e-6 => (1e6, "µs"),
        _ => (1e9, "ns"),
    };
    let v = seconds * scale;
    let digits = match v.abs() {
        v if v >= 100.0 => 1,
        v if v >= 10.0 => 2,
        _ => 3,
    };
    let text = format!("{v:.digits$}");
    let text = if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.')
    } else {
        &text
    };
    format!("{text} {unit}")
}

#[cfg(test)]
mod duration_tests {
    use super::duration;

    #[test]
    fn times_are_read_in_the_unit_that_suits_them() {
        assert_eq!(duration(0.0021), "2.1 ms");
        assert_eq!(duration(0.002_900_000_1), "2.9 ms");
        assert_eq!(duration(3.75e-5), "37.5 µs");
        assert_eq!(duration(1.25), "1.25 s");
        assert_eq!(duration(0.0), "0 s");
        assert_eq!(duration(-0.0123456), "-12.35 ms");
        assert_eq!(duration(2.5e-9), "2.5 ns");
        assert_eq!(duration(123.456), "123.5 s");
    }
}
