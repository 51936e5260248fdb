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

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

mod error;
pub use error::{ColumnRole, CopyFailure, TraceError};

/// The trace room's result.
pub type Result<T, E = TraceError> = std::result::Result<T, E>;

/// Highest sample rate a record or a model file may carry (1 GHz).
pub const MAX_SAMPLE_RATE_HZ: f64 = 1e9;

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
    pub require_input: bool,
}

impl Default for Columns {
    fn default() -> Self {
        Self {
            time: "t".into(),
            input: "u".into(),
            output: "y".into(),
            sample_rate_hz: None,
            require_input: true,
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

/// A reader that hashes what passes through it.
struct Hashing<R> {
    inner: R,
    hasher: Sha256,
}

impl Hashing<std::io::BufReader<std::fs::File>> {
    /// Opens the file at `path` to be read through a buffer and hashed; with its length.
    fn open(path: &Path) -> Result<(Self, u64)> {
        let cannot_read = |source| TraceError::Io {
            path: path.to_path_buf(),
            action: "cannot read",
            source,
        };
        let file = std::fs::File::open(path).map_err(cannot_read)?;
        let meta = file.metadata().map_err(cannot_read)?;
        if meta.is_dir() {
            return Err(cannot_read(std::io::Error::other("it is a directory")));
        }
        let reader = Self {
            inner: std::io::BufReader::with_capacity(1 << 16, file),
            hasher: Sha256::new(),
        };
        Ok((reader, meta.len()))
    }
}

impl<R: Read> Read for Hashing<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.hasher.update(buf.get(..n).unwrap_or(&[]));
        Ok(n)
    }
}

/// The CSV reader every trace is read (and read again) with.
fn csv_reader<R: Read>(reader: R) -> csv::Reader<R> {
    csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(reader)
}

impl Trace {
    /// Reads and checks a trace.
    ///
    /// # Errors
    /// [`TraceError`] naming the file, line and column of the first problem found.
    pub fn read(path: &Path, columns: &Columns) -> Result<Self> {
        let (mut reader, size) = Hashing::open(path)?;
        let mut trace = Self::parse_reader(path, &mut reader, size, columns)?;
        trace.sha256 = hex(&reader.hasher.finalize());
        trace.source = Source::File;
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
    /// signals' buffers); the hash and the source are the caller's to set.
    fn parse_reader<R: Read>(path: &Path, reader: R, size: u64, columns: &Columns) -> Result<Self> {
        let p = || path.to_path_buf();
        if let Some(fs) = columns.sample_rate_hz {
            if !(fs.is_finite() && fs > 0.0 && fs <= MAX_SAMPLE_RATE_HZ) {
                return Err(TraceError::SampleRate {
                    given: fs,
                    max: MAX_SAMPLE_RATE_HZ,
                });
            }
        }
        let mut reader = csv_reader(reader);
        let headers = reader.headers().map_err(|e| csv_error(path, &e))?.clone();
        if headers.is_empty() || headers.iter().all(str::is_empty) {
            return Err(TraceError::Empty {
                path: p(),
                line: 1,
                what: "no header row",
            });
        }
        let find = |name: &str| headers.iter().position(|h| h == name);
        let found = headers.iter().collect::<Vec<_>>().join(", ");
        let y_idx = find(&columns.output).ok_or_else(|| TraceError::MissingColumn {
            path: p(),
            column: columns.output.clone(),
            found: found.clone(),
            role: ColumnRole::Probe,
            needed: false,
        })?;
        let u_idx = match find(&columns.input) {
            Some(i) => Some(i),
            None if columns.require_input => {
                return Err(TraceError::MissingColumn {
                    path: p(),
                    column: columns.input.clone(),
                    found: found.clone(),
                    role: ColumnRole::Reference,
                    needed: false,
                })
            }
            None => None,
        };
        let t_idx = if columns.sample_rate_hz.is_some() {
            None
        } else {
            Some(
                find(&columns.time).ok_or_else(|| TraceError::MissingColumn {
                    path: p(),
                    column: columns.time.clone(),
                    found: found.clone(),
                    role: ColumnRole::Time,
                    needed: false,
                })?,
            )
        };

        let mut t = Vec::new();
        let mut u = Vec::new();
        let mut y = Vec::new();
        let mut lines: Vec<u64> = Vec::new();
        let mut rec = csv::StringRecord::new();
        loop {
            match reader.read_record(&mut rec) {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) => return Err(csv_error(path, &e)),
            }
            if lines.len() == SIZING_ROWS {
                // The file's length over the bytes a row has taken so far: room for all the
                // rows at once, instead of buffers doubling (and briefly tripling) as they grow.
                let start = rec.position().map_or(0, csv::Position::byte);
                let per_row = (start / SIZING_ROWS as u64).max(1);
                let rows = usize::try_from(size / per_row + size / per_row / 8).unwrap_or(0);
                for v in [&mut t, &mut u, &mut y] {
                    v.reserve(rows);
                }
                lines.reserve(rows);
            }
            let line = rec.position().map_or(0, csv::Position::line);
            let field = |idx: usize| -> Result<f64> {
                let text = rec.get(idx).unwrap_or("");
                let name = headers.get(idx).unwrap_or("").to_string();
                let v: f64 = text.parse().map_err(|_| TraceError::NotANumber {
                    path: p(),
                    line,
                    column: idx + 1,
                    name: name.clone(),
                    value: text.to_string(),
                })?;
                if !v.is_finite() {
                    return Err(TraceError::NonFinite {
                        path: p(),
                        line,
                        column: idx + 1,
                        name,
                        value: text.to_string(),
                    });
                }
                Ok(v)
            };
            if let Some(i) = t_idx {
                t.push(field(i)?);
            }
            if let Some(i) = u_idx {
                u.push(field(i)?);
            }
            y.push(field(y_idx)?);
            lines.push(line);
        }
        if y.is_empty() {
            return Err(TraceError::Empty {
                path: p(),
                line: 2,
                what: "a header and no data rows",
            });
        }
        let sample_rate_hz = match (columns.sample_rate_hz, t_idx) {
            (Some(fs), _) => fs,
            (None, Some(ti)) => check_time(path, &t, &lines, ti + 1, &columns.time)?,
            (None, None) => unreachable_fs(path)?,
        };
        if sample_rate_hz.is_nan() || sample_rate_hz > MAX_SAMPLE_RATE_HZ {
            return Err(TraceError::Malformed {
                path: p(),
                line: 3,
                message: format!(
                    "the time column's step gives a sample rate of {sample_rate_hz:e} Hz, above \
                     the {:e} Hz a model may carry: is the time in seconds?",
                    MAX_SAMPLE_RATE_HZ
                ),
            });
        }
        check_clipping(path, &y, &lines, y_idx + 1, &columns.output)?;
        if let Some(ui) = u_idx {
            check_clipping(path, &u, &lines, ui + 1, &columns.input)?;
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
            headers,
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
            column: "u".into(),
            found: self.headers.iter().collect::<Vec<_>>().join(", "),
            role: ColumnRole::Reference,
            needed: true,
        })
    }

    /// Writes this trace as CSV with extra columns appended, row by row: the rows are read
    /// again from the file (which must not have changed since it was read: its hash is
    /// checked at the end) and written with the new values beside them.
    ///
    /// # Errors
    /// [`CopyFailure::Trace`] with [`TraceError::Mismatch`] when a column's length differs from
    /// the trace's or the file changed, [`CopyFailure::Output`] when `out` fails.
    pub fn write_csv_with(
        &self,
        out: &mut dyn Write,
        extra: &[(&str, &[f64])],
    ) -> std::result::Result<(), CopyFailure> {
        for (name, col) in extra {
            if col.len() != self.len() {
                return Err(TraceError::Mismatch {
                    path: self.path.clone(),
                    message: format!(
                        "column '{name}' has {} values for {} rows",
                        col.len(),
                        self.len()
                    ),
                }
                .into());
            }
        }
        let changed = || -> CopyFailure {
            TraceError::Mismatch {
                path: self.path.clone(),
                message: "the file changed while unlag was running; run again".into(),
            }
            .into()
        };
        let mut header = self.headers.iter().collect::<Vec<_>>().join(",");
        for (name, _) in extra {
            header.push(',');
            header.push_str(name);
        }
        header.push('\n');
        out.write_all(header.as_bytes())?;
        let mut copy = |reader: &mut dyn Read| -> std::result::Result<(), CopyFailure> {
            let mut reader = csv_reader(reader);
            let mut rec = csv::StringRecord::new();
            // Skip the header.
            reader.headers().map_err(|_| changed())?;
            let mut k = 0;
            let mut line = Vec::with_capacity(128);
            while reader.read_record(&mut rec).map_err(|_| changed())? {
                line.clear();
                for (i, f) in rec.iter().enumerate() {
                    if i > 0 {
                        line.push(b',');
                    }
                    line.extend_from_slice(f.as_bytes());
                }
                for (_, col) in extra {
                    let v = col.get(k).copied().ok_or_else(changed)?;
                    // `{}` on f64 prints the shortest text that reads back to the same value.
                    write!(line, ",{v}")?;
                }
                line.push(b'\n');
                out.write_all(&line)?;
                k += 1;
            }
            if k == self.len() {
                Ok(())
            } else {
                Err(changed())
            }
        };
        match &self.source {
            Source::Bytes(bytes) => copy(&mut &bytes[..]),
            Source::File => {
                let (mut reader, _) = Hashing::open(&self.path)?;
                copy(&mut reader)?;
                if hex(&reader.hasher.finalize()) == self.sha256 {
                    Ok(())
                } else {
                    Err(changed())
                }
            }
        }
    }
}

fn unreachable_fs(path: &Path) -> Result<f64> {
    Err(TraceError::NoSampleRate {
        path: path.to_path_buf(),
    })
}

fn csv_error(path: &Path, e: &csv::Error) -> TraceError {
    let line = e.position().map_or(0, csv::Position::line);
    let message = match e.kind() {
        csv::ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => format!("expected {expected_len} fields like the header, found {len}"),
        csv::ErrorKind::Utf8 { .. } => "the file is not UTF-8 text".to_string(),
        _ => e.to_string(),
    };
    TraceError::Malformed {
        path: path.to_path_buf(),
        line,
        message,
    }
}

/// Checks that time increases uniformly and returns the sample rate.
fn check_time(path: &Path, t: &[f64], lines: &[u64], column: usize, name: &str) -> Result<f64> {
    let n = t.len();
    let (Some(&first), Some(&last)) = (t.first(), t.last()) else {
        return Err(TraceError::Empty {
            path: path.to_path_buf(),
            line: 2,
            what: "a header and no data rows",
        });
    };
    if n < 2 {
        return Err(TraceError::TooShort {
            path: path.to_path_buf(),
            samples: n,
        });
    }
    for (k, w) in t.windows(2).enumerate() {
        if let [a, b] = *w {
            if b <= a {
                return Err(TraceError::TimeNotIncreasing {
                    path: path.to_path_buf(),
                    line: lines.get(k + 1).copied().unwrap_or(0),
                    column,
                    name: name.to_string(),
                    previous: a,
                    value: b,
                });
            }
        }
    }
    let nominal = (last - first) / (n - 1) as f64;
    for (k, w) in t.windows(2).enumerate() {
        if let [a, b] = *w {
            let step = b - a;
            let dev = (step - nominal).abs() / nominal;
            if dev > MAX_JITTER {
                return Err(TraceError::NonUniformTime {
                    path: path.to_path_buf(),
                    line: lines.get(k + 1).copied().unwrap_or(0),
                    column,
                    name: name.to_string(),
                    step,
                    nominal,
                    percent: dev * 100.0,
                });
            }
        }
    }
    Ok(1.0 / nominal)
}

/// Shortest flat run at an extreme that counts as clipping.
pub const CLIP_MIN_RUN: usize = 5;

/// Shortest flat run at an extreme, lasting to the end of the record, that counts as clipping
/// when the rest of the record is noisy.
pub const CLIP_MIN_RUN_AT_END: usize = 20;

/// Fraction of the samples outside `start..end` that repeat their predecessor exactly.
fn repeat_fraction_outside(x: &[f64], start: usize, end: usize) -> f64 {
    let (mut repeats, mut pairs) = (0usize, 0usize);
    for (i, w) in x.windows(2).enumerate() {
        if (start.saturating_sub(1)..end).contains(&i) {
            continue;
        }
        pairs += 1;
        if let [a, b] = *w {
            if a == b {
                repeats += 1;
            }
        }
    }
    if pairs == 0 {
        1.0
    } else {
        repeats as f64 / pairs as f64
    }
}

/// Detects a saturated ADC: the signal sits flat at its largest (or smallest) value for at
/// least [`CLIP_MIN_RUN`] samples, and enters that run with a jump of more than 5 times the
/// typical sample-to-sample change. A settled, quantised signal also repeats its final value,
/// but it enters the plateau in steps of about one typical change, so it is not flagged.
fn check_clipping(path: &Path, x: &[f64], lines: &[u64], column: usize, name: &str) -> Result<()> {
    if x.len() < 4 * CLIP_MIN_RUN {
        return Ok(());
    }
    let mut diffs: Vec<f64> = x
        .windows(2)
        .filter_map(|w| match *w {
            [a, b] if a != b => Some((b - a).abs()),
            _ => None,
        })
        .collect();
    if diffs.is_empty() {
        return Ok(());
    }
    let mid = diffs.len() / 2;
    diffs.select_nth_unstable_by(mid, f64::total_cmp);
    let typical = diffs.get(mid).copied().unwrap_or(0.0);
    let max = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = x.iter().copied().fold(f64::INFINITY, f64::min);
    for (level, which) in [(max, "largest"), (min, "smallest")] {
        let mut k = 0;
        while k < x.len() {
            if x.get(k) == Some(&level) {
                let start = k;
                while x.get(k) == Some(&level) {
                    k += 1;
                }
                let run = k - start;
                let entry_jump = start
                    .checked_sub(1)
                    .and_then(|i| x.get(i))
                    .map_or(0.0, |prev| (level - prev).abs());
                // A run that lasts to the end of the record may be a noise-free step's
                // settled value; it is clipping when the rest of the record is noisy (its
                // samples rarely repeat) and the run is long.
                let clipped = if k < x.len() {
                    run >= CLIP_MIN_RUN
                } else {
                    run >= CLIP_MIN_RUN_AT_END && repeat_fraction_outside(x, start, k) < 0.2
                };
                if clipped && entry_jump > 5.0 * typical {
                    return Err(TraceError::Clipped {
                        path: path.to_path_buf(),
                        line: lines.get(start).copied().unwrap_or(0),
                        column,
                        name: name.to_string(),
                        run,
                        which,
                        value: level,
                    });
                }
            } else {
                k += 1;
            }
        }
    }
    Ok(())
}

fn hex(bytes: &[u8]) -> String {
    use std::fmt::Write as _;
    let mut s = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(s, "{b:02x}");
    }
    s
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
            s.push_str(&format!("{t},1,{y}\n"));
        }
        let e = parse(&s).unwrap_err().to_string();
        assert!(e.contains("clipped"), "{e}");
        // A settled quantised step: fine.
        let mut s = String::from("t,u,y\n");
        for k in 0..60 {
            let t = k as f64 * 1e-3;
            let y = ((1.0 - (-(k as f64) / 5.0).exp()) * 256.0).round() / 256.0;
            s.push_str(&format!("{t},1,{y}\n"));
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
                0.5
            ));
        }
        std::fs::write(&input, &text).unwrap();
        let tr = Trace::read(&input, &Columns::default()).unwrap();
        assert_eq!(tr.len(), 10_000);
        // Room for the rows and an eighth more, never the doubling growth gives.
        assert!(tr.y.capacity() < 10_000 * 5 / 4, "{}", tr.y.capacity());
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
