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

pub use crate::trace::unit::{duration, hz, pressure, si, significant};

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
        assert_eq!(duration(4000.0), "4000 s");
    }

    #[test]
    fn one_policy_four_significant_digits_and_the_prefix_that_suits() {
        use super::{hz, pressure, si, significant};
        use crate::trace::PressureUnit;
        assert_eq!(significant(6_561.849_999_999_999), "6562");
        assert_eq!(significant(0.320_031), "0.32");
        assert_eq!(significant(0.320_731), "0.3207");
        assert_eq!(significant(1.373_169e-9), "1.373e-9");
        assert_eq!(significant(-2.5e7), "-2.5e7");
        assert_eq!(significant(1.867_58), "1.868");
        assert_eq!(significant(20_000.0), "20000");
        assert_eq!(significant(0.0), "0");
        assert_eq!(significant(f64::NAN), "NaN");
        assert_eq!(significant(f64::INFINITY), "inf");
        assert_eq!(hz(111.974_674), "112 Hz");
        assert_eq!(hz(1_328_000.08), "1.328 MHz");
        assert_eq!(si(0.85, "Pa"), "850 mPa");
        assert_eq!(pressure(6_561.85, Some(PressureUnit::Pa)), "6.562 kPa");
        assert_eq!(pressure(6.56185, Some(PressureUnit::KPa)), "6.562 kPa");
        assert_eq!(pressure(0.2, Some(PressureUnit::MPa)), "200 kPa");
        assert_eq!(pressure(14.6959, Some(PressureUnit::Psi)), "14.7 psi");
        assert_eq!(pressure(6_561.85, None), "6562");
        assert_eq!(pressure(12.5, Some(PressureUnit::MV)), "12.5 mV");
    }
}
