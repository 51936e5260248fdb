//! What can be wrong with a recorded trace: one variant per problem, each naming the file,
//! line and column where it is, in the trace room's own words (no command-line flags).

use std::path::PathBuf;

/// The role of a column in a step test, for messages that say which one is missing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColumnRole {
    /// The time column ([`crate::trace::Columns::time`]).
    Time,
    /// The reference pressure ([`crate::trace::Columns::input`]).
    Reference,
    /// The probe's output ([`crate::trace::Columns::output`]).
    Probe,
}

impl std::fmt::Display for ColumnRole {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Time => "time",
            Self::Reference => "reference",
            Self::Probe => "probe",
        })
    }
}

/// Everything that can be wrong with a trace file, found once, when it is read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TraceError {
    /// The file could not be read.
    #[error("{path}: {action}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done ("cannot read").
        action: &'static str,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// The sample rate given for a file without a time column is not a rate.
    #[error("invalid sample rate: the sample rate must be a positive number of Hz up to {max:e}, not {}", short(*.given))]
    SampleRate {
        /// What was given.
        given: f64,
        /// The largest accepted ([`crate::trace::MAX_SAMPLE_RATE_HZ`]).
        max: f64,
    },
    /// A file without a time column was read without a sample rate.
    #[error("invalid sample rate: {path}: no time column and no sample rate")]
    NoSampleRate {
        /// The file.
        path: PathBuf,
    },
    /// The file has no header, or a header and no data rows.
    #[error("{path}:{line}: the file is empty ({what})")]
    Empty {
        /// The file.
        path: PathBuf,
        /// Where the data should have started.
        line: u64,
        /// What is missing.
        what: &'static str,
    },
    /// A required column is not in the header.
    #[error("{path}:1: missing column {column} (the header has: {found}); {}", missing_hint(*.role, *.needed))]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The column asked for, quoted and cut ([`crate::trace::echo`]).
        column: String,
        /// The header's column names, comma-separated, cut ([`crate::trace::echo`]).
        found: String,
        /// Which column it is.
        role: ColumnRole,
        /// Whether it was asked for by a step that needs it after reading (the reference of
        /// a file read without one).
        needed: bool,
    },
    /// A field is not a number.
    #[error("{path}:{line}:{column}: {value} in column {name} is not a number")]
    NotANumber {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// 1-based field position.
        column: usize,
        /// The column's name, quoted and cut ([`crate::trace::echo`]).
        name: String,
        /// The text found, quoted and cut ([`crate::trace::echo`]).
        value: String,
    },
    /// A field is NaN or infinite.
    #[error("{path}:{line}:{column}: value {value} in column {name} is not finite")]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// 1-based field position.
        column: usize,
        /// The column's name, quoted and cut ([`crate::trace::echo`]).
        name: String,
        /// The text found, quoted and cut ([`crate::trace::echo`]).
        value: String,
    },
    /// A row has the wrong number of fields, or the CSV is malformed.
    #[error("{path}:{line}: {message}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// What the CSV reader said.
        message: String,
    },
    /// Time does not increase from one row to the next.
    #[error("{path}:{line}:{column}: time in column {name} does not increase ({} then {})", short(*.previous), short(*.value))]
    TimeNotIncreasing {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// 1-based field position.
        column: usize,
        /// The column's name, quoted and cut ([`crate::trace::echo`]).
        name: String,
        /// The previous time.
        previous: f64,
        /// This row's time.
        value: f64,
    },
    /// The time step varies by more than 1 %.
    #[error("{path}:{line}:{column}: time step {step:.6e} {unit} in column {name} differs from the mean step {nominal:.6e} {unit} by {percent:.2} % (more than 1 % jitter: resample the trace or give the sample rate)")]
    NonUniformTime {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// 1-based field position.
        column: usize,
        /// The column's name, quoted and cut ([`crate::trace::echo`]).
        name: String,
        /// The offending step.
        step: f64,
        /// The mean step.
        nominal: f64,
        /// Relative deviation in percent.
        percent: f64,
        /// The time column's unit ("s", "ms", "µs", "ns").
        unit: &'static str,
    },
    /// Fewer than two samples: no time step.
    #[error("{path}: {samples} samples is too short: a trace needs at least 2")]
    TooShort {
        /// The file.
        path: PathBuf,
        /// Samples in the trace.
        samples: usize,
    },
    /// The ADC saturated: the signal sits flat at its extreme value, entered with a jump.
    #[error("{path}:{line}:{column}: column {name} looks clipped: {run} samples flat at its {which} value {} from this line on (the ADC saturated; re-record with more range)", short(*.value))]
    Clipped {
        /// The file.
        path: PathBuf,
        /// 1-based line where the flat run starts.
        line: u64,
        /// 1-based field position.
        column: usize,
        /// The column's name, quoted and cut ([`crate::trace::echo`]).
        name: String,
        /// Length of the flat run.
        run: usize,
        /// "largest" or "smallest".
        which: &'static str,
        /// The clipped value.
        value: f64,
    },
    /// A physical line (or a quoted record) is longer than [`crate::trace::MAX_LINE_BYTES`]:
    /// not a row of numbers. Refused before the reader's buffer grows for it.
    #[error("{path}:{line}: {} longer than {}: a row of numbers is a few hundred bytes; is this a text CSV file{}?", long_what(*.line, *.quoted), bytes(*.limit), if *.quoted { ", or is a quote left open" } else { "" })]
    LineTooLong {
        /// The file.
        path: PathBuf,
        /// 1-based line where the long line (or record) starts.
        line: u64,
        /// The limit, in bytes.
        limit: u64,
        /// Whether the line breaks are inside a quoted field (a record over many lines).
        quoted: bool,
    },
    /// The signals' buffers could not grow: the recording does not fit in memory.
    #[error("{path}:{line}: out of memory at line {line} ({rows} rows read): the recording is too long for this machine's memory; cut it into shorter tests")]
    OutOfMemory {
        /// The file.
        path: PathBuf,
        /// 1-based line being read.
        line: u64,
        /// Rows read so far.
        rows: usize,
    },
    /// The header is one column holding another delimiter: the file is separated by it.
    #[error("{path}:1: the header {header} is one column: its names are separated by {}, not by {}; read the file with the delimiter {}{}", delimiter_name(*.found), delimiter_name(*.expected), delimiter_name(*.found), if *.decimal_comma { ", and commas in numbers as decimal points (the rows have decimal commas)" } else { "" })]
    WrongDelimiter {
        /// The file.
        path: PathBuf,
        /// The header as found (cut, [`crate::trace::echo`]).
        header: String,
        /// The delimiter the file was read with.
        expected: u8,
        /// The delimiter the header holds.
        found: u8,
        /// Whether the first row's numbers have decimal commas too.
        decimal_comma: bool,
    },
    /// A number written with a decimal comma, read without decimal commas.
    #[error("{path}:{line}:{column}: {value} in column {name} is not a number: it has a decimal comma; read commas in numbers as decimal points")]
    DecimalComma {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// 1-based field position.
        column: usize,
        /// The column's name, quoted and cut ([`crate::trace::echo`]).
        name: String,
        /// The text found, quoted and cut ([`crate::trace::echo`]).
        value: String,
    },
    /// Decimal commas asked for with the comma as the delimiter.
    #[error("invalid delimiter: numbers with decimal commas need a delimiter other than ',' (every decimal comma would split a field)")]
    DecimalCommaDelimiter,
    /// A value too large for any pressure or time, which would overflow the fit's sums.
    #[error("{path}:{line}:{column}: {value} in column {name}: |value| above {max:e} cannot be a pressure or a time in any unit and overflows the fit's sums; is the column scaled?")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// 1-based field position.
        column: usize,
        /// The column's name, quoted and cut ([`crate::trace::echo`]).
        name: String,
        /// The text found, quoted and cut ([`crate::trace::echo`]).
        value: String,
        /// The largest magnitude accepted ([`crate::trace::MAX_MAGNITUDE`]).
        max: f64,
    },
    /// A time column without a unit in its name whose step, read as seconds, is slower than
    /// any probe's step test is sampled.
    #[error("{path}:{line}:{column}: time column {name} steps by {} per row: as seconds that is {} Hz, below the {} Hz a probe's step test is sampled at (milliseconds or sample numbers?); name the unit in the column's name (t_ms, t_us) or give the sample rate", short(*.step), short(*.rate_hz), short(*.min))]
    ImplausibleTime {
        /// The file.
        path: PathBuf,
        /// 1-based line of the second row.
        line: u64,
        /// 1-based field position.
        column: usize,
        /// The column's name, quoted and cut ([`crate::trace::echo`]).
        name: String,
        /// The mean step, in the file's numbers.
        step: f64,
        /// The rate it gives as seconds.
        rate_hz: f64,
        /// The lowest plausible rate ([`crate::trace::MIN_PLAUSIBLE_RATE_HZ`]).
        min: f64,
    },
    /// A column that a fit needs holds one value from its first row to its last.
    #[error("{path}: the {role} column {name} is constant ({}) from line {first} to line {last}: nothing to fit; {}", short(*.value), constant_hint(*.role))]
    Constant {
        /// The file.
        path: PathBuf,
        /// Which column.
        role: ColumnRole,
        /// The column's name, quoted and cut ([`crate::trace::echo`]).
        name: String,
        /// 1-based field position.
        column: usize,
        /// The value it holds.
        value: f64,
        /// 1-based line of the first row.
        first: u64,
        /// 1-based line of the last row.
        last: u64,
    },
    /// A run read in passes (`compensate`) is not a regular file: a pipe or a device, which
    /// cannot be read a second time.
    #[error("{path}: not a regular file (a pipe or a device): a run is read twice, to check it and then to compensate it row by row without holding it in memory; save it to a file first")]
    NotRereadable {
        /// The run's path.
        path: PathBuf,
    },
    /// Columns written beside the trace do not fit it, or the file changed since it was read.
    #[error("{path}: {message}")]
    Mismatch {
        /// The trace's file.
        path: PathBuf,
        /// What differs.
        message: String,
    },
}

/// A number for a message: six significant digits, without the binary fraction's tail
/// (`6561.85`, not `6561.849999999999`), in powers of ten outside `1e-4..1e7` (`1e300`, never
/// the 300 digits `{}` gives). The crate's other rooms use it as [`crate::error::number`].
#[must_use]
pub fn short(x: f64) -> String {
    let a = x.abs();
    if !x.is_finite() || a == 0.0 || (1e-4..1e7).contains(&a) {
        return format!("{x:.5e}")
            .parse::<f64>()
            .map_or_else(|_| x.to_string(), |r| r.to_string());
    }
    let s = format!("{x:.5e}");
    match s.split_once('e') {
        Some((mantissa, exponent)) if mantissa.contains('.') => {
            let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
            format!("{mantissa}e{exponent}")
        }
        _ => s,
    }
}

/// A byte count in the largest binary unit that divides it.
fn bytes(n: u64) -> String {
    match n {
        n if n >= 1 << 20 && n % (1 << 20) == 0 => format!("{} MiB", n >> 20),
        n if n >= 1 << 10 && n % (1 << 10) == 0 => format!("{} KiB", n >> 10),
        n => format!("{n} bytes"),
    }
}

/// A delimiter as a message names it: `';'`, or `tab`.
pub fn delimiter_name(d: u8) -> String {
    match d {
        b'\t' => "tab".into(),
        d if d.is_ascii_graphic() || d == b' ' => format!("'{}'", char::from(d)),
        d => format!("byte {d:#04x}"),
    }
}

fn long_what(line: u64, quoted: bool) -> String {
    if quoted {
        format!("the quoted record from line {line} is")
    } else {
        format!("line {line} is")
    }
}

fn constant_hint(role: ColumnRole) -> &'static str {
    match role {
        ColumnRole::Probe => "is it the right column, or was the probe connected?",
        ColumnRole::Reference => "is it the right column, and did the test have its step?",
        ColumnRole::Time => "is it the right column?",
    }
}

fn missing_hint(role: ColumnRole, needed: bool) -> String {
    match (role, needed) {
        (ColumnRole::Reference, true) => "this step needs the reference column (name it)".into(),
        (ColumnRole::Time, _) => "name the time column, or give the sample rate".into(),
        (role, _) => format!("name the {role} column"),
    }
}

impl TraceError {
    /// The kind of problem, one stable kebab-case word per variant (for `--json`).
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Io { .. } => "io",
            Self::SampleRate { .. } | Self::NoSampleRate { .. } => "invalid-argument",
            Self::Empty { .. } => "empty",
            Self::MissingColumn { .. } => "missing-column",
            Self::NotANumber { .. } => "not-a-number",
            Self::NonFinite { .. } => "non-finite",
            Self::Malformed { .. } => "malformed",
            Self::TimeNotIncreasing { .. } => "time-not-increasing",
            Self::NonUniformTime { .. } => "non-uniform-time",
            Self::TooShort { .. } => "too-short",
            Self::Clipped { .. } => "clipped",
            Self::Mismatch { .. } => "mismatch",
            Self::NotRereadable { .. } => "not-rereadable",
            Self::LineTooLong { .. } => "line-too-long",
            Self::OutOfMemory { .. } => "out-of-memory",
            Self::WrongDelimiter { .. } => "wrong-delimiter",
            Self::DecimalComma { .. } => "decimal-comma",
            Self::DecimalCommaDelimiter => "invalid-argument",
            Self::TooLarge { .. } => "too-large",
            Self::ImplausibleTime { .. } => "implausible-time",
            Self::Constant { .. } => "constant",
        }
    }

    /// The file, line and column the problem is at, as far as they are known.
    #[must_use]
    pub fn location(&self) -> (Option<&std::path::Path>, Option<u64>, Option<u64>) {
        match self {
            Self::NotANumber {
                path, line, column, ..
            }
            | Self::NonFinite {
                path, line, column, ..
            }
            | Self::TimeNotIncreasing {
                path, line, column, ..
            }
            | Self::NonUniformTime {
                path, line, column, ..
            }
            | Self::Clipped {
                path, line, column, ..
            }
            | Self::DecimalComma {
                path, line, column, ..
            }
            | Self::TooLarge {
                path, line, column, ..
            }
            | Self::ImplausibleTime {
                path, line, column, ..
            } => (Some(path), Some(*line), Some(*column as u64)),
            Self::Constant {
                path,
                first,
                column,
                ..
            } => (Some(path), Some(*first), Some(*column as u64)),
            Self::LineTooLong { path, line, .. } | Self::OutOfMemory { path, line, .. } => {
                (Some(path), Some(*line), None)
            }
            Self::WrongDelimiter { path, .. } => (Some(path), Some(1), None),
            Self::DecimalCommaDelimiter => (None, None, None),
            Self::Empty { path, line, .. } | Self::Malformed { path, line, .. } => {
                (Some(path), Some(*line), None)
            }
            Self::MissingColumn { path, .. } => (Some(path), Some(1), None),
            Self::Io { path, .. }
            | Self::TooShort { path, .. }
            | Self::Mismatch { path, .. }
            | Self::NotRereadable { path } => (Some(path), None, None),
            Self::SampleRate { .. } | Self::NoSampleRate { .. } => (None, None, None),
        }
    }
}

/// What stops [`crate::trace::Trace::write_csv_with`]: the output failed, or the trace did.
#[derive(Debug)]
pub enum CopyFailure {
    /// Writing to the output failed.
    Output(std::io::Error),
    /// The trace's own problem (its error names its file).
    Trace(TraceError),
}

impl From<std::io::Error> for CopyFailure {
    fn from(e: std::io::Error) -> Self {
        Self::Output(e)
    }
}

impl From<TraceError> for CopyFailure {
    fn from(e: TraceError) -> Self {
        Self::Trace(e)
    }
}
