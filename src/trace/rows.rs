//! The rows of a trace file, read and checked once for every reader: the bounded CSV reader,
//! the header's columns, and each row's numbers with the file, line and column of a problem.
//!
//! [`Rows`] is the one row-checking path: [`Trace::read`](super::Trace::read) collects its
//! rows, the streamed passes of [`stream`](super::stream) consume them, so that the same file
//! gives the same message either way. The bytes pass through a [`Hashing`] reader on their way
//! in, which gives the file's SHA-256 once its rows are read.

use std::io::Read;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use super::{
    echo, ColumnRole, Columns, Result, TraceError, MAX_LINE_BYTES, MAX_MAGNITUDE,
    MAX_SAMPLE_RATE_HZ,
};

/// Rows looked at for decimal commas when the header shows the file has another delimiter.
const DELIMITER_ROWS: usize = 16;

/// One row of a trace: its time (when read), reference (when the file has one) and probe
/// values, and its line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// The time column's value, when it is read.
    pub t: Option<f64>,
    /// The reference.
    pub u: Option<f64>,
    /// The probe.
    pub y: f64,
    /// 1-based line of the file.
    pub line: u64,
}

/// A trace's rows as they are read from `R`: the header's [`Layout`], then each row checked.
/// The row's fields are read into one reused record: no allocation per row.
pub(super) struct Rows<R> {
    path: PathBuf,
    columns: Columns,
    reader: csv::Reader<LineLimit<R>>,
    /// The header's columns.
    pub(super) layout: Layout,
    rec: csv::StringRecord,
}

impl<R: Read> Rows<R> {
    /// Reads the header of `reader` (the file at `path`, for messages) and finds the columns
    /// of `columns` in it (checked by the caller with [`check_columns`]). `trim`: the fields as
    /// written back ([`csv::Trim::All`]) or as checked ([`csv::Trim::None`], where a field's
    /// place gives its byte in the file).
    pub(super) fn new(path: &Path, reader: R, columns: &Columns, trim: csv::Trim) -> Result<Self> {
        let mut reader = csv_reader(reader, columns.delimiter, trim);
        let layout = Layout::read(path, &mut reader, columns)?;
        Ok(Self {
            path: path.to_path_buf(),
            columns: columns.clone(),
            reader,
            layout,
            rec: csv::StringRecord::new(),
        })
    }

    /// The next row, checked: as many fields as the header, and the time, reference and probe
    /// numbers (in that order); `None` at the end of the file.
    pub(super) fn next_row(&mut self) -> Result<Option<Row>> {
        match self.next_record()? {
            Some(line) => self.row(line).map(Some),
            None => Ok(None),
        }
    }

    /// Reads the next record and checks it has as many fields as the header; its line, or
    /// `None` at the end of the file. Its numbers are [`Rows::row`]'s to check.
    pub(super) fn next_record(&mut self) -> Result<Option<u64>> {
        match self.reader.read_record(&mut self.rec) {
            Ok(true) => {}
            Ok(false) => return Ok(None),
            Err(e) => return Err(csv_error(&self.path, &e)),
        }
        let line = self.rec.position().map_or(0, csv::Position::line);
        self.layout.check_width(&self.path, &self.rec, line)?;
        Ok(Some(line))
    }

    /// The numbers of the record last read (at `line`), checked: time, reference, probe.
    pub(super) fn row(&self, line: u64) -> Result<Row> {
        let l = &self.layout;
        let field = |i: usize| l.field(&self.path, &self.columns, &self.rec, i);
        let t = l.t_idx.map(field).transpose()?;
        let u = l.u_idx.map(field).transpose()?;
        let y = field(l.y_idx)?;
        Ok(Row { t, u, y, line })
    }

    /// The fields of the row last read, as the reader gave them.
    pub(super) fn record(&self) -> &csv::StringRecord {
        &self.rec
    }

    /// The reader the rows came from.
    pub(super) fn into_inner(self) -> R {
        self.reader.into_inner().inner
    }
}

/// A reader that hashes what passes through it, and keeps it when asked (a pipe or a device,
/// which cannot be read again to write the rows back).
pub(super) struct Hashing<R> {
    inner: R,
    pub(super) hasher: Sha256,
    pub(super) kept: Option<Vec<u8>>,
}

impl Hashing<std::io::BufReader<std::fs::File>> {
    /// Opens the file at `path` to be read through a buffer and hashed; with its length.
    pub(super) fn open(path: &Path) -> Result<(Self, u64)> {
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
            kept: (!meta.is_file()).then(Vec::new),
        };
        Ok((reader, meta.len()))
    }
}

impl<R: Read> Read for Hashing<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        let read = buf.get(..n).unwrap_or(&[]);
        self.hasher.update(read);
        if let Some(kept) = &mut self.kept {
            kept.try_reserve(n)
                .map_err(|_| std::io::Error::from(std::io::ErrorKind::OutOfMemory))?;
            kept.extend_from_slice(read);
        }
        Ok(n)
    }
}

/// The CSV reader every trace is read (and read again) with: lines bounded by
/// [`MAX_LINE_BYTES`], the field count checked by the caller (to read a row of a file whose
/// header was split at the wrong delimiter).
pub(super) fn csv_reader<R: Read>(
    reader: R,
    delimiter: u8,
    trim: csv::Trim,
) -> csv::Reader<LineLimit<R>> {
    csv::ReaderBuilder::new()
        .trim(trim)
        .delimiter(delimiter)
        .flexible(true)
        .comment(Some(b'#'))
        .from_reader(LineLimit::new(reader, delimiter))
}

/// Where a [`LineLimit`] is in the CSV syntax, as far as the length of a record needs it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Syntax {
    RecordStart,
    FieldStart,
    Field,
    Quoted,
    QuoteInQuoted,
    Comment,
}

/// A reader that refuses a line, or a quoted record over many lines, longer than
/// [`MAX_LINE_BYTES`]: the bytes are counted as they pass, before the CSV reader's buffer grows
/// for them (it would grow without bound on a file without line ends).
pub(super) struct LineLimit<R> {
    inner: R,
    delimiter: u8,
    state: Syntax,
    /// Bytes since the last line end.
    physical: u64,
    /// Bytes since the current record started.
    record: u64,
    /// Line ends seen.
    newlines: u64,
    /// 1-based line the current record started on.
    record_line: u64,
}

/// The error a [`LineLimit`] gives, found again in the CSV reader's error.
#[derive(Debug)]
struct TooLong {
    line: u64,
    quoted: bool,
}

impl std::fmt::Display for TooLong {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "line {} is longer than {MAX_LINE_BYTES} bytes",
            self.line
        )
    }
}

impl std::error::Error for TooLong {}

impl<R> LineLimit<R> {
    fn new(inner: R, delimiter: u8) -> Self {
        Self {
            inner,
            delimiter,
            state: Syntax::RecordStart,
            physical: 0,
            record: 0,
            newlines: 0,
            record_line: 1,
        }
    }

    /// Counts one byte; an error when it makes its line or record too long.
    fn step(&mut self, b: u8) -> std::io::Result<()> {
        use Syntax::{Comment, Field, FieldStart, QuoteInQuoted, Quoted, RecordStart};
        if self.state == RecordStart {
            self.record = 0;
            self.record_line = self.newlines + 1;
        }
        self.state = match (self.state, b) {
            (Comment, b'\n') => RecordStart,
            (Comment, _) => Comment,
            (RecordStart, b'#') => Comment,
            (Quoted, b'"') => QuoteInQuoted,
            (Quoted, _) | (QuoteInQuoted, b'"') | (RecordStart | FieldStart, b'"') => Quoted,
            (_, b'\n' | b'\r') => RecordStart,
            (_, d) if d == self.delimiter => FieldStart,
            _ => Field,
        };
        if b == b'\n' {
            self.newlines += 1;
            self.physical = 0;
        } else {
            self.physical += 1;
        }
        self.record += 1;
        let too_long = if self.physical > MAX_LINE_BYTES {
            TooLong {
                line: self.newlines + 1,
                quoted: false,
            }
        } else if self.record > MAX_LINE_BYTES {
            TooLong {
                line: self.record_line,
                quoted: true,
            }
        } else {
            return Ok(());
        };
        Err(std::io::Error::other(too_long))
    }
}

impl<R: Read> Read for LineLimit<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        for &b in buf.get(..n).unwrap_or(&[]) {
            self.step(b)?;
        }
        Ok(n)
    }
}

/// Whether `text` reads as a number once its one comma is a decimal point.
fn has_decimal_comma(text: &str) -> bool {
    text.matches(',').count() == 1 && text.replace(',', ".").parse::<f64>().is_ok()
}

/// Of the delimiters a trace may be written with, one that the header's single field holds,
/// splitting it into columns, other than `delimiter`.
fn other_delimiter(header: &csv::StringRecord, delimiter: u8) -> Option<u8> {
    if header.len() != 1 {
        return None;
    }
    let only = header.get(0)?;
    [b';', b'\t', b',', b'|']
        .into_iter()
        .filter(|&d| d != delimiter)
        .find(|&d| {
            only.split(char::from(d))
                .filter(|f| !f.trim().is_empty())
                .count()
                >= 2
        })
}

/// Checks the options a trace is read with, before its file is opened.
pub(super) fn check_columns(columns: &Columns) -> Result<()> {
    if let Some(fs) = columns.sample_rate_hz {
        if !(fs.is_finite() && fs > 0.0 && fs <= MAX_SAMPLE_RATE_HZ) {
            return Err(TraceError::SampleRate {
                given: fs,
                max: MAX_SAMPLE_RATE_HZ,
            });
        }
    }
    if columns.decimal_comma && columns.delimiter == b',' {
        return Err(TraceError::DecimalCommaDelimiter);
    }
    Ok(())
}

/// Byte of the file where field `i` of `rec` (starting at byte `at`) starts, past its
/// leading blanks.
fn byte_of(rec: &csv::StringRecord, at: u64, i: usize) -> u64 {
    let text = rec.get(i).unwrap_or("");
    let lead = text.len() - text.trim_start().len();
    at + rec.range(i).map_or(0, |r| r.start as u64) + i as u64 + lead as u64
}

/// A trace's header: the columns found in it, to read its rows by.
#[derive(Debug, Clone)]
pub(super) struct Layout {
    /// The header as read.
    raw: csv::StringRecord,
    /// The same, trimmed.
    pub(super) headers: csv::StringRecord,
    /// Byte where the header starts.
    header_at: u64,
    pub(super) t_idx: Option<usize>,
    pub(super) u_idx: Option<usize>,
    pub(super) y_idx: usize,
}

impl Layout {
    /// Reads the header of `reader` and finds the columns of `columns` in it: a missing one is
    /// an error that says whether the file has another delimiter (a few rows are read to see
    /// whether its numbers have decimal commas).
    fn read<R: Read>(path: &Path, reader: &mut csv::Reader<R>, columns: &Columns) -> Result<Self> {
        let p = || path.to_path_buf();
        let raw = reader.headers().map_err(|e| csv_error(path, &e))?.clone();
        let mut headers = raw.clone();
        headers.trim();
        if headers.is_empty() || headers.iter().all(str::is_empty) {
            return Err(TraceError::Empty {
                path: p(),
                line: 1,
                what: "no header row",
            });
        }
        let header_at = raw.position().map_or(0, csv::Position::byte);
        let find = |name: &str| headers.iter().position(|h| h == name);
        let mut missing = |column: &str, role: ColumnRole| {
            if let Some(found) = other_delimiter(&raw, columns.delimiter) {
                // The rows are split at the same wrong delimiter: joined back, then split at
                // the header's, their numbers show whether their decimal point is a comma.
                // The first rows may be all zeros: a few are looked at.
                let mut row = csv::StringRecord::new();
                let mut decimal_comma = false;
                for _ in 0..DELIMITER_ROWS {
                    if !matches!(reader.read_record(&mut row), Ok(true)) {
                        break;
                    }
                    decimal_comma |= row
                        .iter()
                        .collect::<Vec<_>>()
                        .join(&char::from(columns.delimiter).to_string())
                        .split(char::from(found))
                        .any(|f| has_decimal_comma(f.trim()));
                }
                return TraceError::WrongDelimiter {
                    path: p(),
                    header: echo(raw.get(0).unwrap_or(""), header_at),
                    expected: columns.delimiter,
                    found,
                    decimal_comma,
                };
            }
            TraceError::MissingColumn {
                path: p(),
                column: echo(column, 0),
                found: echo(&headers.iter().collect::<Vec<_>>().join(", "), header_at),
                role,
                needed: false,
            }
        };
        let y_idx = match find(&columns.output) {
            Some(i) => i,
            None => return Err(missing(&columns.output, ColumnRole::Probe)),
        };
        let u_idx = match find(&columns.input) {
            Some(i) => Some(i),
            None if columns.require_input => {
                return Err(missing(&columns.input, ColumnRole::Reference))
            }
            None => None,
        };
        let t_idx = if columns.sample_rate_hz.is_some() {
            None
        } else {
            match find(&columns.time) {
                Some(i) => Some(i),
                None => return Err(missing(&columns.time, ColumnRole::Time)),
            }
        };
        Ok(Self {
            raw,
            headers,
            header_at,
            t_idx,
            u_idx,
            y_idx,
        })
    }

    /// Column `i`'s name as messages echo it.
    pub(super) fn name_of(&self, i: usize) -> String {
        echo(
            self.headers.get(i).unwrap_or(""),
            byte_of(&self.raw, self.header_at, i),
        )
    }

    /// An error unless `rec` has as many fields as the header.
    fn check_width(&self, path: &Path, rec: &csv::StringRecord, line: u64) -> Result<()> {
        if rec.len() == self.raw.len() {
            return Ok(());
        }
        Err(TraceError::Malformed {
            path: path.to_path_buf(),
            line,
            message: format!(
                "expected {} fields like the header, found {}",
                self.raw.len(),
                rec.len()
            ),
        })
    }

    /// The number in field `idx` of `rec`, checked: a number (with a decimal comma when
    /// `columns` say so), finite, and no larger than [`MAX_MAGNITUDE`].
    fn field(
        &self,
        path: &Path,
        columns: &Columns,
        rec: &csv::StringRecord,
        idx: usize,
    ) -> Result<f64> {
        let p = || path.to_path_buf();
        let line = rec.position().map_or(0, csv::Position::line);
        let at = rec.position().map_or(0, csv::Position::byte);
        let name_of = |i: usize| self.name_of(i);
        let text = rec.get(idx).unwrap_or("").trim();
        let value = || echo(text, byte_of(rec, at, idx));
        let parsed = if columns.decimal_comma && text.contains(',') {
            text.replace(',', ".").parse::<f64>()
        } else {
            text.parse::<f64>()
        };
        let Ok(v) = parsed else {
            return Err(
                if !columns.decimal_comma && columns.delimiter != b',' && has_decimal_comma(text) {
                    TraceError::DecimalComma {
                        path: p(),
                        line,
                        column: idx + 1,
                        name: name_of(idx),
                        value: value(),
                    }
                } else {
                    TraceError::NotANumber {
                        path: p(),
                        line,
                        column: idx + 1,
                        name: name_of(idx),
                        value: value(),
                    }
                },
            );
        };
        if !v.is_finite() {
            return Err(TraceError::NonFinite {
                path: p(),
                line,
                column: idx + 1,
                name: name_of(idx),
                value: value(),
            });
        }
        if v.abs() > MAX_MAGNITUDE {
            return Err(TraceError::TooLarge {
                path: p(),
                line,
                column: idx + 1,
                name: name_of(idx),
                value: value(),
                max: MAX_MAGNITUDE,
            });
        }
        Ok(v)
    }
}

fn csv_error(path: &Path, e: &csv::Error) -> TraceError {
    if let csv::ErrorKind::Io(io) = e.kind() {
        if let Some(long) = io.get_ref().and_then(|e| e.downcast_ref::<TooLong>()) {
            return TraceError::LineTooLong {
                path: path.to_path_buf(),
                line: long.line,
                limit: MAX_LINE_BYTES,
                quoted: long.quoted,
            };
        }
    }
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

pub(super) fn hex(bytes: &[u8]) -> String {
    use std::fmt::Write as _;
    let mut s = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(s, "{b:02x}");
    }
    s
}
