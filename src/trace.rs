//! Recorded traces: reading a step test from CSV, checking it, writing results back.
//!
//! This module owns the file boundary. A trace is a CSV file with a header row; by default the
//! columns are `t` (seconds), `u` (the reference pressure) and `y` (the probe's output). Other
//! names are chosen with [`Columns`]; without a time column the sample rate is given instead.
//! Everything is checked here, once: empty files, missing columns, non-numbers, NaN and
//! infinities, time that does not increase or jitters by more than 1 %, and clipped ADC
//! channels. Each problem is reported with the file, line and column.
//!
//! Output files are written to a temporary file in the same directory and renamed at the end
//! ([`write_atomically`]), so a failed run never leaves a half-written file.

use std::io::Write;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::error::{Error, Result};

/// Allowed deviation of one time step from the mean step.
pub const MAX_JITTER: f64 = 0.01;

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
    /// The rows as read, to write them back with new columns.
    pub records: Vec<csv::StringRecord>,
}

impl Trace {
    /// Reads and checks a trace.
    ///
    /// # Errors
    /// [`Error`] naming the file, line and column of the first problem found.
    pub fn read(path: &Path, columns: &Columns) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            action: "cannot read",
            source,
        })?;
        Self::parse(path, &bytes, columns)
    }

    /// Parses a trace from bytes; `path` is used for messages and provenance.
    ///
    /// # Errors
    /// As [`Trace::read`].
    pub fn parse(path: &Path, bytes: &[u8], columns: &Columns) -> Result<Self> {
        let p = || path.to_path_buf();
        if let Some(fs) = columns.sample_rate_hz {
            if !(fs.is_finite() && fs > 0.0 && fs <= crate::model::MAX_SAMPLE_RATE_HZ) {
                return Err(Error::InvalidArgument {
                    what: "--fs",
                    message: format!(
                        "the sample rate must be a positive number of Hz up to {:e}, not {fs:?}",
                        crate::model::MAX_SAMPLE_RATE_HZ
                    ),
                });
            }
        }
        let sha256 = hex(&Sha256::digest(bytes));
        let mut reader = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .comment(Some(b'#'))
            .from_reader(bytes);
        let headers = reader.headers().map_err(|e| csv_error(path, &e))?.clone();
        if headers.is_empty() || headers.iter().all(str::is_empty) {
            return Err(Error::Empty {
                path: p(),
                line: 1,
                what: "no header row",
            });
        }
        let find = |name: &str| headers.iter().position(|h| h == name);
        let found = headers.iter().collect::<Vec<_>>().join(", ");
        let y_idx = find(&columns.output).ok_or_else(|| Error::MissingColumn {
            path: p(),
            column: columns.output.clone(),
            found: found.clone(),
            hint: "; name the probe column with --y",
        })?;
        let u_idx = match find(&columns.input) {
            Some(i) => Some(i),
            None if columns.require_input => {
                return Err(Error::MissingColumn {
                    path: p(),
                    column: columns.input.clone(),
                    found: found.clone(),
                    hint: "; name the reference column with --u",
                })
            }
            None => None,
        };
        let t_idx = if columns.sample_rate_hz.is_some() {
            None
        } else {
            Some(find(&columns.time).ok_or_else(|| Error::MissingColumn {
                path: p(),
                column: columns.time.clone(),
                found: found.clone(),
                hint: "; name the time column with --t, or give the sample rate with --fs",
            })?)
        };

        let mut records = Vec::new();
        let mut t = Vec::new();
        let mut u = Vec::new();
        let mut y = Vec::new();
        let mut lines = Vec::new();
        for rec in reader.records() {
            let rec = rec.map_err(|e| csv_error(path, &e))?;
            let line = rec.position().map_or(0, csv::Position::line);
            let field = |idx: usize| -> Result<f64> {
                let text = rec.get(idx).unwrap_or("");
                let name = headers.get(idx).unwrap_or("").to_string();
                let v: f64 = text.parse().map_err(|_| Error::NotANumber {
                    path: p(),
                    line,
                    column: idx + 1,
                    name: name.clone(),
                    value: text.to_string(),
                })?;
                if !v.is_finite() {
                    return Err(Error::NonFinite {
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
            records.push(rec);
        }
        if y.is_empty() {
            return Err(Error::Empty {
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
        if sample_rate_hz.is_nan() || sample_rate_hz > crate::model::MAX_SAMPLE_RATE_HZ {
            return Err(Error::Malformed {
                path: p(),
                line: 3,
                message: format!(
                    "the time column's step gives a sample rate of {sample_rate_hz:e} Hz, above \
                     the {:e} Hz a model may carry: is the time in seconds?",
                    crate::model::MAX_SAMPLE_RATE_HZ
                ),
            });
        }
        check_clipping(path, &y, &lines, y_idx + 1, &columns.output)?;
        if let Some(ui) = u_idx {
            check_clipping(path, &u, &lines, ui + 1, &columns.input)?;
        }
        Ok(Self {
            path: p(),
            sha256,
            sample_rate_hz,
            u: u_idx.map(|_| u),
            y,
            u_column: u_idx.map(|i| i + 1),
            y_column: y_idx + 1,
            headers,
            records,
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
    /// [`Error::MissingColumn`] when the file has no reference column.
    pub fn input(&self) -> Result<&[f64]> {
        self.u.as_deref().ok_or_else(|| Error::MissingColumn {
            path: self.path.clone(),
            column: "u".into(),
            found: self.headers.iter().collect::<Vec<_>>().join(", "),
            hint: "; this step needs the reference column (name it with --u)",
        })
    }

    /// The CSV text of this trace with extra columns appended.
    ///
    /// # Errors
    /// [`Error::Mismatch`] when a column's length differs from the trace's.
    pub fn to_csv_with(&self, extra: &[(&str, &[f64])]) -> Result<Vec<u8>> {
        for (name, col) in extra {
            if col.len() != self.records.len() {
                return Err(Error::Mismatch {
                    path: self.path.clone(),
                    message: format!(
                        "column '{name}' has {} values for {} rows",
                        col.len(),
                        self.records.len()
                    ),
                });
            }
        }
        let mut out = Vec::with_capacity(self.records.len() * 48);
        let mut header = self.headers.iter().collect::<Vec<_>>().join(",");
        for (name, _) in extra {
            header.push(',');
            header.push_str(name);
        }
        header.push('\n');
        out.extend_from_slice(header.as_bytes());
        for (k, rec) in self.records.iter().enumerate() {
            let mut first = true;
            for f in rec {
                if !first {
                    out.push(b',');
                }
                first = false;
                out.extend_from_slice(f.as_bytes());
            }
            for (_, col) in extra {
                let v = col.get(k).copied().unwrap_or(f64::NAN);
                // `{}` on f64 prints the shortest text that reads back to the same value.
                let _ = write!(out, ",{v}");
            }
            out.push(b'\n');
        }
        Ok(out)
    }
}

fn unreachable_fs(path: &Path) -> Result<f64> {
    Err(Error::InvalidArgument {
        what: "--fs",
        message: format!("{}: no time column and no sample rate", path.display()),
    })
}

fn csv_error(path: &Path, e: &csv::Error) -> Error {
    let line = e.position().map_or(0, csv::Position::line);
    let message = match e.kind() {
        csv::ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => format!("expected {expected_len} fields like the header, found {len}"),
        csv::ErrorKind::Utf8 { .. } => "the file is not UTF-8 text".to_string(),
        _ => e.to_string(),
    };
    Error::Malformed {
        path: path.to_path_buf(),
        line,
        message,
    }
}

/// Checks that time increases uniformly and returns the sample rate.
fn check_time(path: &Path, t: &[f64], lines: &[u64], column: usize, name: &str) -> Result<f64> {
    let n = t.len();
    let (Some(&first), Some(&last)) = (t.first(), t.last()) else {
        return Err(Error::Empty {
            path: path.to_path_buf(),
            line: 2,
            what: "a header and no data rows",
        });
    };
    if n < 2 {
        return Err(Error::TooShort {
            path: path.to_path_buf(),
            samples: n,
            order: 0,
            delay: 0,
            needed: 2,
        });
    }
    for (k, w) in t.windows(2).enumerate() {
        if let [a, b] = *w {
            if b <= a {
                return Err(Error::TimeNotIncreasing {
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
                return Err(Error::NonUniformTime {
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
                    return Err(Error::Clipped {
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

/// Writes `bytes` to `path` so that nothing is lost or half-written:
///
/// - a regular file (new or existing) is written to a temporary file in its directory and
///   renamed over it at the end: readers never see a half-written file, and a failure leaves
///   any old file untouched. A new file takes the mode the umask gives (`0666 & !umask`), an
///   existing one keeps its own;
/// - a symbolic link is followed: the file it points to is replaced, the link stays;
/// - a character device or a pipe (`/dev/null`, `/dev/stdout`, a FIFO) is written in place
///   (it cannot be renamed over), and a full device is an error;
/// - `-` is standard output;
/// - a directory or a block device is refused.
///
/// Errors name `path`, never the temporary file.
///
/// # Errors
/// [`Error::Io`] when the target cannot be written.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let io = |action: &'static str, source: std::io::Error| Error::Io {
        path: path.to_path_buf(),
        action,
        source,
    };
    if path == Path::new("-") {
        let mut out = std::io::stdout().lock();
        return match out.write_all(bytes).and_then(|()| out.flush()) {
            // The reader stopped (`| head`): what it wanted, it has.
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
            r => r.map_err(|e| io("cannot write to standard output", e)),
        };
    }
    // Follow a symbolic link to the file it names, so that the link survives.
    let target = match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => std::fs::canonicalize(path)
            .map_err(|e| io("is a symbolic link to nowhere that can be written", e))?,
        _ => path.to_path_buf(),
    };
    let existing = match std::fs::metadata(&target) {
        Ok(m) => Some(m),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(e) => return Err(io("cannot write", bare(&e))),
    };
    if let Some(m) = &existing {
        if m.is_dir() {
            return Err(io(
                "cannot write",
                std::io::Error::other("it is a directory; give a file name"),
            ));
        }
        if !m.is_file() {
            #[cfg(unix)]
            {
                use std::os::unix::fs::FileTypeExt as _;
                if m.file_type().is_block_device() {
                    return Err(io(
                        "refused",
                        std::io::Error::other(
                            "it is a block device (a disk); unlag writes files, not disks",
                        ),
                    ));
                }
            }
            let mut f = std::fs::OpenOptions::new()
                .write(true)
                .open(&target)
                .map_err(|e| io("cannot write", bare(&e)))?;
            return f
                .write_all(bytes)
                .and_then(|()| f.flush())
                .map_err(|e| io("cannot write", bare(&e)));
        }
    }
    let dir = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(io(
            "cannot write",
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!("directory '{}' does not exist", dir.display()),
            ),
        ));
    }
    let mut builder = tempfile::Builder::new();
    builder.prefix(".unlag-").suffix(".partial");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        // Passed to open(2): the umask applies, as for any new file.
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder
        .tempfile_in(&dir)
        .map_err(|e| io("cannot write", bare(&e)))?;
    if let Some(m) = &existing {
        tmp.as_file()
            .set_permissions(m.permissions())
            .map_err(|e| io("cannot keep the mode of", bare(&e)))?;
    }
    tmp.write_all(bytes)
        .map_err(|e| io("cannot write", bare(&e)))?;
    tmp.as_file()
        .sync_all()
        .map_err(|e| io("cannot write", bare(&e)))?;
    tmp.persist(&target)
        .map_err(|e| io("cannot write", bare(&e.error)))?;
    Ok(())
}

/// The OS error without the temporary file's name that `tempfile` adds to its messages.
fn bare(e: &std::io::Error) -> std::io::Error {
    e.raw_os_error().map_or_else(
        || std::io::Error::new(e.kind(), e.kind().to_string()),
        std::io::Error::from_raw_os_error,
    )
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
    fn csv_round_trip_keeps_columns() {
        let tr = parse("t,u,y\n0,0,0\n0.001,1,0.5\n").unwrap();
        let out = tr.to_csv_with(&[("u_hat", &[0.0, 1.0])]).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "t,u,y,u_hat\n0,0,0,0\n0.001,1,0.5,1\n"
        );
    }
}
