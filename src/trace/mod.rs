//! Recorded traces: reading a step test from CSV, checking it, writing results back.
//!
//! This module owns the file boundary. A trace is a CSV file with a header row; by default the
//! columns are `t` (seconds), `u` (the reference pressure) and `y` (the probe's output). Other
//! names are chosen with [`Columns`]; without a time column the sample rate is given instead.
//! Everything is checked here, once: empty files, missing columns, non-numbers, NaN and
//! infinities, time that does not increase or jitters by more than 1 %, and clipped ADC
//! channels. Each problem is reported with the file, line and column.
//!
//! Results are written back beside the trace's own columns by [`Trace::write_csv_with`], which
//! streams the rows to any writer (the file room's `write_atomically_with` puts them on disk
//! without ever leaving a half-written file). Problems are [`TraceError`]s, in this room's
//! own words: the trace room imports nothing of the rooms after it.
//!
//! Its modules: `rows` reads the header and checks each row (the one path both [`Trace::read`]
//! and the streamed passes of [`stream`] take), `timing` checks the time column and gives the
//! sample rate, `clip` finds clipped channels, `write` writes rows back, [`unit`](mod@unit) reads units
//! from column names, and the errors are in [`TraceError`].

use std::io::Read;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

mod clip;
mod error;
mod rows;
pub mod stream;
mod timing;
pub mod unit;
mod write;
pub use clip::{CLIP_MIN_RUN, CLIP_MIN_RUN_AT_END};
pub use error::{short, ColumnRole, CopyFailure, TraceError};
pub use unit::{time_unit, PressureUnit};

use clip::check_clipping;
use rows::{check_columns, hex, Hashing, Rows};
use timing::{jitters, Steps};

/// The trace room's result.
pub type Result<T, E = TraceError> = std::result::Result<T, E>;

/// Highest sample rate a record or a model file may carry (1 GHz).
pub const MAX_SAMPLE_RATE_HZ: f64 = 1e9;

/// Longest line (or quoted record) a trace may have: 1 MiB. A row of numbers is a few hundred
/// bytes; a longer line is not a row (a binary file, a file without line ends, a device such
/// as `/dev/zero`), and the CSV reader would grow its buffer for it until memory runs out.
/// The limit is checked on the bytes as they are read, before the reader's buffer grows.
pub const MAX_LINE_BYTES: u64 = 1 << 20;

/// Largest magnitude a value may have. No pressure in any unit (1e100 Pa is beyond any star's
/// core) and no time comes near it, and the fit squares the values and sums the squares over
/// up to a billion rows: below 1e100 those sums stay under 1e209, far from `f64`'s 1.8e308,
/// while 1e300 overflows to infinity at the first square.
pub const MAX_MAGNITUDE: f64 = 1e100;

/// Lowest sample rate a time column without a unit in its name is believed in seconds. The
/// dynamics a pressure probe is tested for (line and cavity resonances, diaphragms, the
/// transport delay of its tubing) lie between about 10 Hz and a few MHz; a step test sampled
/// below 10 Hz sees none of them, so such a column is much more likely milliseconds,
/// microseconds or sample numbers than seconds.
pub const MIN_PLAUSIBLE_RATE_HZ: f64 = 10.0;

/// Characters of a header or a cell an error message echoes before cutting it ([`echo`]).
pub const ECHO_CHARS: usize = 32;

/// A header or a cell as a message echoes it: quoted, control characters escaped (a tab as
/// `\t`), and when longer than [`ECHO_CHARS`] characters, cut there with an ellipsis and
/// followed by its length and the byte of the file where it starts:
/// `'0000…' (10485760 bytes at byte 7)`. A 10 MB cell does not make a 10 MB message.
#[must_use]
pub fn echo(text: &str, at_byte: u64) -> String {
    match text.char_indices().nth(ECHO_CHARS) {
        None => format!("'{}'", text.escape_debug()),
        Some((cut, _)) => format!(
            "'{}…' ({} bytes at byte {at_byte})",
            text.get(..cut).unwrap_or("").escape_debug(),
            text.len()
        ),
    }
}

/// Rows read before the signals' buffers are sized from the file's length.
const SIZING_ROWS: usize = 64;

/// Allowed deviation of one time step from the mean step.
pub const MAX_JITTER: f64 = 0.01;

/// Whether a record sampled at `rate_hz` is at another rate than `expected_hz`: further from it
/// than the jitter a clock has ([`MAX_JITTER`], relative to `expected_hz`).
#[must_use]
pub fn rate_differs(rate_hz: f64, expected_hz: f64) -> bool {
    (rate_hz - expected_hz).abs() / expected_hz > MAX_JITTER
}

/// Which columns hold what, and the sample rate when there is no time column.
#[derive(Debug, Clone, PartialEq)]
pub struct Columns {
    /// Time column, in seconds (ignored when `sample_rate_hz` is given).
    pub time: String,
    /// Reference (true pressure) column.
    pub input: String,
    /// Probe output column.
    pub output: String,
    /// Sample rate in Hz, when the file has no time column.
    pub sample_rate_hz: Option<f64>,
    /// Whether the reference column must be present (fitting needs it; compensating does not).
    /// A trace read for a fit is also refused when its reference or probe column is constant.
    pub require_input: bool,
    /// The byte between fields: `b','` by default, `b';'` or `b'\t'` for files written where
    /// the comma is the decimal point. Results are written back with the same delimiter.
    pub delimiter: u8,
    /// Whether a comma in a number is its decimal point (`0,5` is one half); only with a
    /// delimiter other than `,`. Results are written back with decimal commas too.
    pub decimal_comma: bool,
}

impl Default for Columns {
    fn default() -> Self {
        Self {
            time: "t".into(),
            input: "u".into(),
            output: "y".into(),
            sample_rate_hz: None,
            require_input: true,
            delimiter: b',',
            decimal_comma: false,
        }
    }
}

/// One recorded test.
#[derive(Debug, Clone)]
pub struct Trace {
    /// The file it came from.
    pub path: PathBuf,
    /// SHA-256 of the file's bytes, lower-case hex.
    pub sha256: String,
    /// Sample rate in Hz.
    pub sample_rate_hz: f64,
    /// Reference pressure, when the file has it.
    pub u: Option<Vec<f64>>,
    /// Probe output.
    pub y: Vec<f64>,
    /// 1-based field position of the reference column (for messages).
    pub u_column: Option<usize>,
    /// 1-based field position of the probe column (for messages).
    pub y_column: usize,
    /// The header, to write the columns back.
    pub headers: csv::StringRecord,
    /// The file's delimiter and whether its numbers have decimal commas, to write it back alike.
    dialect: (u8, bool),
    /// Where the rows are read again to be written back with new columns (they are not kept:
    /// a trace holds its two signals, 16 bytes a sample).
    source: Source,
}

/// Where a trace's rows come from.
#[derive(Debug, Clone, PartialEq)]
enum Source {
    /// The file at the trace's path, read again (and checked unchanged) when written back.
    File,
    /// Bytes given to [`Trace::parse`].
    Bytes(std::sync::Arc<[u8]>),
}

/// Pushes `x`, growing `v` with `try_reserve` (doubling) so that a recording too long for the
/// memory is an error, not an abort.
fn grow<T>(v: &mut Vec<T>, x: T, oom: impl Fn() -> TraceError) -> Result<()> {
    if v.len() == v.capacity() {
        v.try_reserve(v.len().max(SIZING_ROWS)).map_err(|_| oom())?;
    }
    v.push(x);
    Ok(())
}

/// An error when the signal `x` (of column `column`, named `name`) has two or more samples, all
/// equal: a fit cannot learn from a constant reference or probe.
fn check_constant(
    path: &Path,
    x: &[f64],
    lines: &[u64],
    role: ColumnRole,
    name: &str,
    column: usize,
) -> Result<()> {
    if let (Some(&first), true) = (x.first(), x.len() >= 2) {
        if x.iter().all(|&v| v == first) {
            return Err(TraceError::Constant {
                path: path.to_path_buf(),
                role,
                name: name.to_string(),
                column,
                value: first,
                first: lines.first().copied().unwrap_or(0),
                last: lines.last().copied().unwrap_or(0),
            });
        }
    }
    Ok(())
}

impl Trace {
    /// Reads and checks a trace.
    ///
    /// # Errors
    /// [`TraceError`] naming the file, line and column of the first problem found.
    /// A pipe or a device is read once, its bytes kept to write the rows back.
    pub fn read(path: &Path, columns: &Columns) -> Result<Self> {
        let (mut reader, size) = Hashing::open(path)?;
        let mut trace = Self::parse_reader(path, &mut reader, size, columns)?;
        trace.sha256 = hex(&reader.hasher.finalize());
        trace.source = match reader.kept {
            Some(bytes) => Source::Bytes(bytes.into()),
            None => Source::File,
        };
        Ok(trace)
    }

    /// Parses a trace from bytes; `path` is used for messages and provenance.
    ///
    /// # Errors
    /// As [`Trace::read`].
    pub fn parse(path: &Path, bytes: &[u8], columns: &Columns) -> Result<Self> {
        let mut trace = Self::parse_reader(path, bytes, bytes.len() as u64, columns)?;
        trace.sha256 = hex(&Sha256::digest(bytes));
        trace.source = Source::Bytes(bytes.into());
        Ok(trace)
    }

    /// Parses and checks a trace as it streams from `reader` (`size` bytes long, to size the
    /// signals' buffers); the hash and the source are the caller's to set. The rows are
    /// [`Rows`]'s, checked as the streamed passes check them; the sample rate is [`Steps`]'s.
    fn parse_reader<R: Read>(path: &Path, reader: R, size: u64, columns: &Columns) -> Result<Self> {
        let p = || path.to_path_buf();
        check_columns(columns)?;
        // Not trimmed by the reader: a field's place in the record gives its byte in the file.
        let mut rows = Rows::new(path, reader, columns, csv::Trim::None)?;
        let (t_idx, u_idx, y_idx) = (rows.layout.t_idx, rows.layout.u_idx, rows.layout.y_idx);

        let mut t = Vec::new();
        let mut u = Vec::new();
        let mut y = Vec::new();
        let mut lines: Vec<u64> = Vec::new();
        let mut steps = Steps::default();
        while let Some(line) = rows.next_record()? {
            let n = lines.len();
            let oom = || TraceError::OutOfMemory {
                path: p(),
                line,
                rows: n,
            };
            if n == SIZING_ROWS {
                // The file's length over the bytes a row has taken so far: room for all the
                // rows at once, instead of buffers doubling (and briefly tripling) as they grow.
                let start = rows.record().position().map_or(0, csv::Position::byte);
                let per_row = (start / SIZING_ROWS as u64).max(1);
                let more = usize::try_from(size / per_row + size / per_row / 8).unwrap_or(0);
                for (v, used) in [(&mut t, t_idx), (&mut u, u_idx), (&mut y, Some(y_idx))] {
                    if used.is_some() {
                        v.try_reserve(more).map_err(|_| oom())?;
                    }
                }
                lines.try_reserve(more).map_err(|_| oom())?;
            }
            let row = rows.row(line)?;
            steps.push(row.t, line);
            if let Some(v) = row.t {
                grow(&mut t, v, oom)?;
            }
            if let Some(v) = row.u {
                grow(&mut u, v, oom)?;
            }
            grow(&mut y, row.y, oom)?;
            grow(&mut lines, line, oom)?;
        }
        let layout = &rows.layout;
        let sample_rate_hz = steps.sample_rate(path, columns, layout, |nominal| {
            Ok(t.windows(2)
                .zip(lines.iter().skip(1))
                .find_map(|(w, &line)| match *w {
                    [a, b] if jitters(b - a, nominal) => Some((line, b - a)),
                    _ => None,
                }))
        })?;
        if columns.require_input {
            let signals = [
                (u_idx.map(|i| (&u[..], i)), ColumnRole::Reference),
                (Some((&y[..], y_idx)), ColumnRole::Probe),
            ];
            for (signal, role) in signals {
                let Some((x, i)) = signal else { continue };
                check_constant(path, x, &lines, role, &layout.name_of(i), i + 1)?;
            }
        }
        check_clipping(path, &y, &lines, y_idx + 1, &layout.name_of(y_idx))?;
        if let Some(ui) = u_idx {
            check_clipping(path, &u, &lines, ui + 1, &layout.name_of(ui))?;
        }
        // The sizing estimate leaves room to spare: give it back (the signals live for the run).
        u.shrink_to_fit();
        y.shrink_to_fit();
        Ok(Self {
            path: p(),
            sha256: String::new(),
            sample_rate_hz,
            u: u_idx.map(|_| u),
            y,
            u_column: u_idx.map(|i| i + 1),
            y_column: y_idx + 1,
            headers: layout.headers.clone(),
            dialect: (columns.delimiter, columns.decimal_comma),
            source: Source::File,
        })
    }

    /// Number of samples.
    #[must_use]
    pub fn len(&self) -> usize {
        self.y.len()
    }

    /// Whether the trace has no samples (never true for a trace that was read).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }

    /// The reference column, or an error naming the file when it has none.
    ///
    /// # Errors
    /// [`TraceError::MissingColumn`] when the file has no reference column.
    pub fn input(&self) -> Result<&[f64]> {
        self.u.as_deref().ok_or_else(|| TraceError::MissingColumn {
            path: self.path.clone(),
            column: echo("u", 0),
            found: echo(&self.headers.iter().collect::<Vec<_>>().join(", "), 0),
            role: ColumnRole::Reference,
            needed: true,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Trace> {
        Trace::parse(Path::new("x.csv"), text.as_bytes(), &Columns::default())
    }

    #[test]
    fn reads_a_good_trace() {
        let tr = parse("t,u,y\n0,0,0\n0.001,1,0.5\n0.002,1,0.9\n").unwrap();
        assert_eq!(tr.len(), 3);
        assert!((tr.sample_rate_hz - 1000.0).abs() < 1e-6);
        assert_eq!(tr.y, vec![0.0, 0.5, 0.9]);
        assert_eq!(tr.sha256.len(), 64);
    }

    #[test]
    fn names_line_and_column_of_a_bad_value() {
        let e = parse("t,u,y\n0,0,0\n0.001,1,abc\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("x.csv:3:3:"), "{e}");
        assert!(e.contains("'abc'"), "{e}");
        let e = parse("t,u,y\n0,0,0\n0.001,NaN,1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("x.csv:3:2:") && e.contains("not finite"),
            "{e}"
        );
    }

    #[test]
    fn rejects_jitter_and_backwards_time() {
        let e = parse("t,u,y\n0,0,0\n0.001,1,1\n0.0025,1,1\n0.0035,1,1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("jitter"), "{e}");
        let e = parse("t,u,y\n0,0,0\n0.001,1,1\n0.001,1,1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("x.csv:4:1:") && e.contains("does not increase"),
            "{e}"
        );
    }

    #[test]
    fn clipping_is_found_but_a_quantised_plateau_is_not() {
        let mut s = String::from("t,u,y\n");
        // A ringing response clipped at 1.2.
        for k in 0..60 {
            let t = k as f64 * 1e-3;
            let y = (1.0 - (-(k as f64) / 10.0).exp() * ((k as f64) * 0.5).cos() * 1.0).min(1.2);
            s.push_str(&format!("{t},{},{y}\n", u8::from(k > 0)));
        }
        let e = parse(&s).unwrap_err().to_string();
        assert!(e.contains("clipped"), "{e}");
        // A settled quantised step: fine.
        let mut s = String::from("t,u,y\n");
        for k in 0..60 {
            let t = k as f64 * 1e-3;
            let y = ((1.0 - (-(k as f64) / 5.0).exp()) * 256.0).round() / 256.0;
            s.push_str(&format!("{t},{},{y}\n", u8::from(k > 0)));
        }
        assert!(parse(&s).is_ok());
    }

    #[test]
    fn a_reference_clipped_to_the_end_is_found_but_an_ideal_step_is_not() {
        // A noisy reference whose step saturates the ADC at 0.9 and stays there.
        let mut state = 3u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.01
        };
        let mut s = String::from("t,u,y\n");
        for k in 0..200 {
            let u = if k < 50 {
                noise()
            } else {
                (1.0 + noise()).min(0.9)
            };
            let y = if k < 50 {
                0.0
            } else {
                1.0 - (-(k as f64 - 50.0) / 8.0).exp()
            } + noise();
            s.push_str(&format!("{},{u},{y}\n", k as f64 * 1e-3));
        }
        let e = parse(&s).unwrap_err().to_string();
        assert!(e.contains("column 'u' looks clipped"), "{e}");
        // A noise-free step: flat before and after, not clipping.
        let mut s = String::from("t,u,y\n");
        for k in 0..200 {
            let u = if k < 50 { 0.0 } else { 1.0 };
            let y = if k < 50 {
                0.0
            } else {
                1.0 - (-(k as f64 - 50.0) / 8.0).exp()
            };
            s.push_str(&format!("{},{u},{y}\n", k as f64 * 1e-3));
        }
        assert!(parse(&s).is_ok());
    }

    #[test]
    fn a_file_is_read_with_the_hash_of_its_bytes() {
        // Streaming it back out is tested with the file room's writer (file/write.rs).
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("in.csv");
        let text = "t,u,y\n# a comment\n0, 0,0\n0.001,1,0.5\n0.002,1,0.75\n";
        std::fs::write(&input, text).unwrap();
        let tr = Trace::read(&input, &Columns::default()).unwrap();
        assert_eq!(tr.sha256, hex(&Sha256::digest(text.as_bytes())));
        assert_eq!(tr.y, [0.0, 0.5, 0.75]);
    }

    #[test]
    fn buffers_are_sized_from_the_file_not_doubled() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("long.csv");
        let mut text = String::from("t,u,y\n");
        for k in 0..10_000 {
            text.push_str(&format!(
                "{},{},{}\n",
                k as f64 * 1e-3,
                u8::from(k > 100),
                f64::from(u8::from(k > 102)) * 0.5
            ));
        }
        std::fs::write(&input, &text).unwrap();
        let tr = Trace::read(&input, &Columns::default()).unwrap();
        assert_eq!(tr.len(), 10_000);
        // Room for the rows and an eighth more, never the doubling growth gives.
        assert!(tr.y.capacity() < 10_000 * 5 / 4, "{}", tr.y.capacity());
    }

    fn parse_with(text: &str, columns: &Columns) -> Result<Trace> {
        Trace::parse(Path::new("x.csv"), text.as_bytes(), columns)
    }

    /// A step test at 10 kHz: `t,u,y` rows, each field through `cell`, joined by `sep`.
    fn step_test(header: &str, sep: &str, time_scale: f64, cell: fn(String) -> String) -> String {
        let mut s = format!("{header}\n");
        for k in 0..200 {
            let u = if k < 50 { 0.0 } else { 1.0 };
            let y = if k < 50 {
                0.0
            } else {
                1.0 - (-(f64::from(k) - 50.0) / 8.0).exp()
            };
            let fields = [f64::from(k) * 1e-4 * time_scale, u, y].map(|v| cell(format!("{v}")));
            s.push_str(&fields.join(sep));
            s.push('\n');
        }
        s
    }

    #[test]
    fn echo_cuts_long_text_and_says_its_length_and_byte() {
        assert_eq!(echo("abc", 9), "'abc'");
        assert_eq!(echo("t\tu", 0), "'t\\tu'");
        let huge = "0".repeat(10 << 20);
        let e = echo(&huge, 7);
        assert!(e.len() < 80, "{e}");
        assert!(e.ends_with("…' (10485760 bytes at byte 7)"), "{e}");
        // Cut on a character, not inside one.
        let e = echo(&"µ".repeat(100), 0);
        assert!(
            e.starts_with(&format!("'{}…'", "µ".repeat(ECHO_CHARS))),
            "{e}"
        );
    }

    #[test]
    fn an_endless_line_is_refused_before_it_is_buffered() {
        // `/dev/zero` in a reader: it never ends, so only the line limit stops the read.
        let e = Trace::parse_reader(
            Path::new("zero"),
            std::io::repeat(0),
            0,
            &Columns::default(),
        )
        .unwrap_err();
        assert!(matches!(e, TraceError::LineTooLong { line: 1, .. }), "{e}");
        assert_eq!(
            e.to_string(),
            "zero:1: line 1 is longer than 1 MiB: a row of numbers is a few hundred bytes; is \
             this a text CSV file?"
        );
        // A long second line, and a quoted field whose record runs over many short lines.
        let long = format!("t,u,y\n0,0,{}\n", "1".repeat(2 << 20));
        let e = parse(&long).unwrap_err().to_string();
        assert!(e.starts_with("x.csv:2: line 2 is longer than 1 MiB"), "{e}");
        let quoted = format!("t,u,y\n0,0,0\n0,0,\"{}\"\n", "1\n".repeat(1 << 20));
        let e = parse(&quoted).unwrap_err().to_string();
        assert!(
            e.starts_with("x.csv:3: the quoted record from line 3"),
            "{e}"
        );
        // Long comments and many lines are fine: only one line's length counts.
        let mut ok = format!("# {}\n", "'\"".repeat(1000));
        ok.push_str(&step_test("t,u,y", ",", 1.0, |c| c));
        assert!(parse(&ok).is_ok());
    }

    #[test]
    fn a_recording_too_long_for_memory_is_an_error_not_an_abort() {
        // A file said to be 2^64 bytes long: the buffers sized for it cannot be had.
        let text = step_test("t,u,y", ",", 1.0, |c| c);
        let e = Trace::parse_reader(
            Path::new("x.csv"),
            text.as_bytes(),
            u64::MAX,
            &Columns::default(),
        )
        .unwrap_err();
        assert!(
            matches!(
                e,
                TraceError::OutOfMemory {
                    rows: SIZING_ROWS,
                    ..
                }
            ),
            "{e}"
        );
        assert!(
            e.to_string()
                .contains("out of memory at line 66 (64 rows read)"),
            "{e}"
        );
    }

    #[test]
    fn a_long_cell_is_echoed_cut_with_its_byte() {
        let text = format!("t,u,y\n0,0,0\n0.0001,1, {}\n", "x".repeat(100_000));
        let e = parse(&text).unwrap_err().to_string();
        assert!(e.len() < 200, "{e}");
        // The cell starts after "t,u,y\n0,0,0\n0.0001,1, ".
        assert!(
            e.contains("…' (100000 bytes at byte 22) in column 'y' is not a number"),
            "{e}"
        );
        let header = format!("t,u,{}\n0,0,0\n", "v".repeat(100_000));
        let e = parse(&header).unwrap_err().to_string();
        assert!(e.len() < 300, "{e}");
        assert!(e.contains("(100006 bytes at byte 0)"), "{e}");
    }

    #[test]
    fn another_delimiter_in_the_header_is_named_with_the_decimal_comma() {
        let semi = step_test("t;u;y", ";", 1.0, |c| c);
        let e = parse(&semi).unwrap_err();
        assert!(
            matches!(
                e,
                TraceError::WrongDelimiter {
                    found: b';',
                    decimal_comma: false,
                    ..
                }
            ),
            "{e}"
        );
        assert!(
            e.to_string().contains("separated by ';', not by ','"),
            "{e}"
        );
        let comma = step_test("t;u;y", ";", 1.0, |c| c.replace('.', ","));
        let e = parse(&comma).unwrap_err();
        assert!(
            matches!(
                e,
                TraceError::WrongDelimiter {
                    decimal_comma: true,
                    ..
                }
            ),
            "{e}"
        );
        let tab = step_test("t\tu\ty", "\t", 1.0, |c| c);
        let e = parse(&tab).unwrap_err().to_string();
        assert!(
            e.contains("'t\\tu\\ty'") && e.contains("separated by tab"),
            "{e}"
        );
        // Read with the delimiter, the decimal commas are named next.
        let semi_columns = Columns {
            delimiter: b';',
            ..Columns::default()
        };
        let e = parse_with(&comma, &semi_columns).unwrap_err();
        assert!(
            matches!(
                e,
                TraceError::DecimalComma {
                    line: 3,
                    column: 1,
                    ..
                }
            ),
            "{e}"
        );
        assert!(
            e.to_string().starts_with(
                "x.csv:3:1: '0,0001' in column 't' is not a number: it has a decimal comma"
            ),
            "{e}"
        );
        // And read with both.
        let both = Columns {
            decimal_comma: true,
            ..semi_columns.clone()
        };
        let tr = parse_with(&comma, &both).unwrap();
        let plain = parse(&step_test("t,u,y", ",", 1.0, |c| c)).unwrap();
        assert_eq!(tr.y, plain.y);
        assert!((tr.sample_rate_hz - 10_000.0).abs() < 1e-6);
        assert!(parse_with(
            &tab,
            &Columns {
                delimiter: b'\t',
                ..Columns::default()
            }
        )
        .is_ok());
    }

    #[test]
    fn results_are_written_back_in_the_files_own_dialect() {
        let columns = Columns {
            delimiter: b';',
            decimal_comma: true,
            ..Columns::default()
        };
        let tr = parse_with("t;u;y\n0;0;0\n0,001;1;0,5\n", &columns).unwrap();
        let mut out = Vec::new();
        tr.write_csv_with(&mut out, &[("u_hat", &[0.25, 1.5])])
            .unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "t;u;y;u_hat\n0;0;0;0,25\n0,001;1;0,5;1,5\n"
        );
    }

    #[test]
    fn decimal_commas_with_the_comma_delimiter_are_refused() {
        let columns = Columns {
            decimal_comma: true,
            ..Columns::default()
        };
        let e = parse_with("t,u,y\n0,0,0\n", &columns).unwrap_err();
        assert!(matches!(e, TraceError::DecimalCommaDelimiter), "{e}");
        assert_eq!(e.kind(), "invalid-argument");
    }

    #[test]
    fn the_time_unit_is_read_from_the_column_name() {
        for (name, unit) in [
            ("t", None),
            ("time", None),
            ("t_ms", Some("ms")),
            ("time_ms", Some("ms")),
            ("t[ms]", Some("ms")),
            ("t (ms)", Some("ms")),
            ("t_us", Some("µs")),
            ("t [µs]", Some("µs")),
            ("time_s", Some("s")),
            ("t_ns", Some("ns")),
            ("t_probe", None),
        ] {
            assert_eq!(time_unit(name).map(|(s, _)| s), unit, "{name}");
        }
        // Milliseconds: 0.1 ms steps are 10 kHz.
        let ms = step_test("t_ms,u,y", ",", 1e3, |c| c);
        let columns = Columns {
            time: "t_ms".into(),
            ..Columns::default()
        };
        let tr = parse_with(&ms, &columns).unwrap();
        assert!(
            (tr.sample_rate_hz - 10_000.0).abs() < 1e-3,
            "{}",
            tr.sample_rate_hz
        );
        // Jitter is said in the column's unit.
        let e = parse_with("t_ms,u,y\n0,0,0\n1,1,1\n2.5,1,1\n3.5,1,2\n", &columns)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("ms in column 't_ms' differs from the mean step 1.166667e0 ms"),
            "{e}"
        );
    }

    #[test]
    fn a_time_column_too_slow_for_seconds_is_refused_unless_its_unit_is_named() {
        // Sample numbers in a column named `t`: 1 Hz if seconds.
        let samples = step_test("t,u,y", ",", 1e4, |c| c);
        let e = parse(&samples).unwrap_err();
        assert!(
            matches!(
                e,
                TraceError::ImplausibleTime {
                    line: 3,
                    column: 1,
                    ..
                }
            ),
            "{e}"
        );
        let text = e.to_string();
        assert!(
            text.contains("steps by 1 per row: as seconds that is 1 Hz, below the 10 Hz"),
            "{text}"
        );
        // Named seconds are believed; 10 Hz and faster is believed without a name.
        let named = Columns {
            time: "time_s".into(),
            ..Columns::default()
        };
        let tr = parse_with(&samples.replacen("t,", "time_s,", 1), &named).unwrap();
        assert!((tr.sample_rate_hz - 1.0).abs() < 1e-9);
        assert!(parse(&step_test("t,u,y", ",", 1e3, |c| c)).is_ok());
    }

    #[test]
    fn values_no_sum_can_hold_are_refused_where_they_are() {
        let e = parse("t,u,y\n0,0,0\n0.001,1e300,0.5\n0.002,1,0.9\n").unwrap_err();
        assert!(
            matches!(
                e,
                TraceError::TooLarge {
                    line: 3,
                    column: 2,
                    ..
                }
            ),
            "{e}"
        );
        assert!(
            e.to_string()
                .contains("'1e300' in column 'u': |value| above 1e100"),
            "{e}"
        );
        assert!(parse("t,u,y\n0,0,0\n0.001,-1e99,0.5\n0.002,1,0.9\n").is_ok());
    }

    #[test]
    fn a_constant_column_is_refused_for_a_fit_only() {
        let text = "t,u,y\n0,0,0.25\n0.001,1,0.25\n0.002,1,0.25\n";
        let e = parse(text).unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.csv: the probe column 'y' is constant (0.25) from line 2 to line 4: nothing to \
             fit; is it the right column, or was the probe connected?"
        );
        assert_eq!(e.location().1, Some(2));
        let e = parse("t,u,y\n0,3,0\n0.001,3,1\n0.002,3,2\n").unwrap_err();
        assert!(
            e.to_string()
                .contains("the reference column 'u' is constant (3)"),
            "{e}"
        );
        let run = Columns {
            require_input: false,
            ..Columns::default()
        };
        assert!(parse_with(text, &run).is_ok());
    }

    #[test]
    fn numbers_in_messages_are_short() {
        assert_eq!(error::short(1e300), "1e300");
        assert_eq!(error::short(0.25), "0.25");
        let e = parse_with(
            "y\n1\n",
            &Columns {
                sample_rate_hz: Some(1e300),
                ..Columns::default()
            },
        )
        .unwrap_err()
        .to_string();
        assert!(e.ends_with("not 1e300"), "{e}");
    }

    #[test]
    fn csv_round_trip_keeps_columns() {
        let tr = parse("t,u,y\n0,0,0\n0.001,1,0.5\n").unwrap();
        let mut out = Vec::new();
        tr.write_csv_with(&mut out, &[("u_hat", &[0.0, 1.0])])
            .unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "t,u,y,u_hat\n0,0,0,0\n0.001,1,0.5,1\n"
        );
    }
}
