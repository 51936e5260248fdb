//! A run read in passes over its file instead of held in memory: each pass reads the rows
//! again, so that what a command keeps does not grow with the record.
//!
//! [`RunRows`] reads one pass: every row's numbers, checked by the same row-checking path as
//! [`Trace::read`](super::Trace::read)'s (the same messages with the file, line and column). [`scan`] is the first pass:
//! the checks that need the whole record (time that increases uniformly, the sample rate) from
//! running figures, and a [`RunChecks`] that finishes the clipping checks in the next passes.
//! [`Median`] is the median of a streamed quantity in two passes, in fixed memory.
//!
//! A run is read from a regular file: a pipe or a device cannot be read twice, and is refused
//! after its first pass ([`TraceError::NotRereadable`]).

use std::io::BufReader;
use std::path::{Path, PathBuf};

use sha2::Digest;

use super::rows::{check_columns, hex, Hashing, Rows};
use super::timing::Steps;
use super::write::{self, row_line};
use super::{Columns, Result, TraceError, CLIP_MIN_RUN, CLIP_MIN_RUN_AT_END};

pub use super::rows::Row;
pub use super::write::changed;

/// One pass over a run's rows: [`Row`]s checked by the same path as [`Trace::read`]'s.
///
/// [`Trace::read`]: super::Trace::read
pub struct RunRows {
    rows: Rows<Hashing<BufReader<std::fs::File>>>,
    /// Whether the file is a regular file (which can be read again).
    rereadable: bool,
}

impl RunRows {
    /// Opens `path` for one pass and reads its header. `trim`: the fields as written back
    /// ([`csv::Trim::All`]) or as checked ([`csv::Trim::None`], where a field's place gives
    /// its byte in the file).
    ///
    /// # Errors
    /// As [`Trace::read`](super::Trace::read) for the header.
    pub fn open(path: &Path, columns: &Columns, trim: csv::Trim) -> Result<Self> {
        check_columns(columns)?;
        let (hashing, _) = Hashing::open(path)?;
        let rereadable = std::fs::metadata(path).is_ok_and(|m| m.is_file());
        Ok(Self {
            rows: Rows::new(path, hashing, columns, trim)?,
            rereadable,
        })
    }

    /// The next row, checked; `None` at the end of the file.
    ///
    /// # Errors
    /// As [`Trace::read`](super::Trace::read) for a row.
    pub fn next_row(&mut self) -> Result<Option<Row>> {
        self.rows.next_row()
    }

    /// The fields of the row last read, as the reader gave them.
    #[must_use]
    pub fn record(&self) -> &csv::StringRecord {
        self.rows.record()
    }

    /// The header, trimmed.
    #[must_use]
    pub fn headers(&self) -> &csv::StringRecord {
        &self.rows.layout.headers
    }

    /// Whether the file has the reference column.
    #[must_use]
    pub fn has_reference(&self) -> bool {
        self.rows.layout.u_idx.is_some()
    }

    /// The SHA-256 of the bytes read so far (all of the file once [`RunRows::next_row`] has
    /// given `None`), lower-case hex.
    #[must_use]
    pub fn sha256(self) -> String {
        hex(&self.rows.into_inner().hasher.finalize())
    }
}

/// The median of a quantity streamed twice, in fixed memory: the first pass counts the values
/// by their top 16 bits, the second by the next 16 within the bucket that holds the median,
/// with each sub-bucket's least and greatest value. The median is exact when it is the least
/// or greatest value of its sub-bucket, or the sub-bucket holds one value (a quantised signal);
/// otherwise it is that sub-bucket's least value, within 2^-20 of it relative. Values must be
/// positive (or zero) and finite; the median is the element at `count / 2` of the sorted values,
/// as [`slice::select_nth_unstable`] gives it.
#[derive(Debug, Clone)]
pub struct Median {
    coarse: Vec<u64>,
    /// Top 16 bits of the median's bucket, and the values below it.
    bucket: Option<(u64, u64)>,
    fine: Vec<(u64, f64, f64)>,
    count: u64,
    second: u64,
}

impl Default for Median {
    fn default() -> Self {
        Self::new()
    }
}

impl Median {
    /// No values yet.
    #[must_use]
    pub fn new() -> Self {
        Self {
            coarse: Vec::new(),
            bucket: None,
            fine: Vec::new(),
            count: 0,
            second: 0,
        }
    }

    /// A value of the first pass.
    pub fn first(&mut self, v: f64) {
        if self.coarse.is_empty() {
            self.coarse = vec![0; 1 << 16];
        }
        let key = v.to_bits() >> 48;
        if let Some(c) = self.coarse.get_mut(key as usize) {
            *c += 1;
        }
        self.count += 1;
    }

    /// Ends the first pass.
    pub fn end_first(&mut self) {
        if self.count == 0 {
            return;
        }
        let mid = self.count / 2;
        let mut below = 0;
        for (b, &c) in self.coarse.iter().enumerate() {
            if below + c > mid {
                self.bucket = Some((b as u64, below));
                break;
            }
            below += c;
        }
        self.coarse = Vec::new();
        self.fine = vec![(0, f64::INFINITY, f64::NEG_INFINITY); 1 << 16];
    }

    /// A value of the second pass (the same values in the same order as the first).
    pub fn second(&mut self, v: f64) {
        self.second += 1;
        let bits = v.to_bits();
        if self.bucket.map(|(b, _)| b) != Some(bits >> 48) {
            return;
        }
        if let Some((c, lo, hi)) = self.fine.get_mut(((bits >> 32) & 0xffff) as usize) {
            *c += 1;
            *lo = lo.min(v);
            *hi = hi.max(v);
        }
    }

    /// The median after the second pass; `None` without values.
    #[must_use]
    pub fn value(&self) -> Option<f64> {
        let (_, mut below) = self.bucket?;
        let mid = self.count / 2;
        for &(c, lo, hi) in &self.fine {
            if below + c > mid {
                return Some(if below + c - 1 == mid { hi } else { lo });
            }
            below += c;
        }
        None
    }

    /// Values counted.
    #[must_use]
    pub fn count(&self) -> u64 {
        self.count
    }
}

/// The clipping check of one channel ([`super::check_clipping`]) over three passes.
#[derive(Debug, Clone)]
struct ClipScan {
    column: usize,
    name: String,
    n: usize,
    max: f64,
    min: f64,
    repeats: usize,
    diffs: Median,
    prev: Option<f64>,
    /// The typical change, once known; `None`: nothing to check.
    typical: Option<f64>,
    /// Per level (largest, smallest): the current run's start line, start index, length and
    /// entry jump; the first clipped run found.
    runs: [LevelRun; 2],
    k: usize,
}

#[derive(Debug, Clone, Default)]
struct LevelRun {
    current: Option<(u64, usize, usize, f64)>,
    found: Option<(u64, usize)>,
}

impl ClipScan {
    fn new(column: usize, name: String) -> Self {
        Self {
            column,
            name,
            n: 0,
            max: f64::NEG_INFINITY,
            min: f64::INFINITY,
            repeats: 0,
            diffs: Median::new(),
            prev: None,
            typical: None,
            runs: Default::default(),
            k: 0,
        }
    }

    fn first(&mut self, x: f64) {
        if let Some(p) = self.prev {
            if p == x {
                self.repeats += 1;
            } else {
                self.diffs.first((x - p).abs());
            }
        }
        self.prev = Some(x);
        self.n += 1;
        self.max = self.max.max(x);
        self.min = self.min.min(x);
    }

    fn end_first(&mut self) {
        self.prev = None;
        self.diffs.end_first();
    }

    fn second(&mut self, x: f64) {
        if let Some(p) = self.prev {
            if p != x {
                self.diffs.second((x - p).abs());
            }
        }
        self.prev = Some(x);
    }

    fn end_second(&mut self) {
        self.prev = None;
        if self.n >= 4 * CLIP_MIN_RUN {
            self.typical = self.diffs.value();
        }
        self.diffs = Median::new();
    }

    fn third(&mut self, x: f64, line: u64) {
        let Some(typical) = self.typical else { return };
        let k = self.k;
        for (level, run) in [self.max, self.min].into_iter().zip(&mut self.runs) {
            if x == level {
                if run.current.is_none() {
                    let jump = self.prev.map_or(0.0, |p| (level - p).abs());
                    run.current = Some((line, k, 0, jump));
                }
                if let Some(c) = &mut run.current {
                    c.2 += 1;
                }
            } else if let Some((start_line, _, length, jump)) = run.current.take() {
                if run.found.is_none() && length >= CLIP_MIN_RUN && jump > 5.0 * typical {
                    run.found = Some((start_line, length));
                }
            }
        }
        self.prev = Some(x);
        self.k += 1;
    }

    fn end_third(&mut self, path: &Path) -> Result<()> {
        let Some(typical) = self.typical else {
            return Ok(());
        };
        let n = self.n;
        for (level, run) in [self.max, self.min].into_iter().zip(&mut self.runs) {
            if let Some((start_line, start, length, jump)) = run.current.take() {
                // A run that lasts to the end of the record: clipping when the rest of the
                // record is noisy (its samples rarely repeat) and the run is long. The pairs
                // outside it are those before its entry; its own pairs all repeat.
                let pairs = start.saturating_sub(1);
                let repeats = self.repeats - (n - 1 - start);
                let fraction = if pairs == 0 {
                    1.0
                } else {
                    repeats as f64 / pairs as f64
                };
                if run.found.is_none()
                    && length >= CLIP_MIN_RUN_AT_END
                    && fraction < 0.2
                    && jump > 5.0 * typical
                {
                    run.found = Some((start_line, length));
                }
            }
            let _ = level;
        }
        for ((level, which), run) in [(self.max, "largest"), (self.min, "smallest")]
            .into_iter()
            .zip(&self.runs)
        {
            if let Some((line, run)) = run.found {
                return Err(TraceError::Clipped {
                    path: path.to_path_buf(),
                    line,
                    column: self.column,
                    name: self.name.clone(),
                    run,
                    which,
                    value: level,
                });
            }
        }
        Ok(())
    }
}

/// What the first pass over a run found: its length and sample rate, its header and dialect.
#[derive(Debug, Clone)]
pub struct RunInfo {
    /// The file.
    pub path: PathBuf,
    /// Rows.
    pub len: usize,
    /// Sample rate in Hz.
    pub sample_rate_hz: f64,
    /// Whether the file has the reference column.
    pub has_reference: bool,
    /// The header, trimmed, to write the columns back.
    pub headers: csv::StringRecord,
    /// SHA-256 of the file's bytes, lower-case hex.
    pub sha256: String,
    /// The reference's first samples (up to 64), for a filter's resting level.
    pub reference_head: Vec<f64>,
    /// The probe's first samples (up to 64).
    pub probe_head: Vec<f64>,
}

/// The checks of a run that need more than its first pass: the clipping of its probe and
/// reference channels. Give it every row of the second pass, then of the third, then call
/// [`RunChecks::finish`].
#[derive(Debug, Clone)]
pub struct RunChecks {
    path: PathBuf,
    y: ClipScan,
    u: Option<ClipScan>,
}

impl RunChecks {
    /// A row of the second pass.
    pub fn second(&mut self, row: &Row) {
        self.y.second(row.y);
        if let (Some(c), Some(u)) = (&mut self.u, row.u) {
            c.second(u);
        }
    }

    /// Ends the second pass.
    pub fn end_second(&mut self) {
        self.y.end_second();
        if let Some(c) = &mut self.u {
            c.end_second();
        }
    }

    /// A row of the third pass.
    pub fn third(&mut self, row: &Row) {
        self.y.third(row.y, row.line);
        if let (Some(c), Some(u)) = (&mut self.u, row.u) {
            c.third(u, row.line);
        }
    }

    /// Ends the third pass: the first clipped run, the probe's first.
    ///
    /// # Errors
    /// [`TraceError::Clipped`].
    pub fn finish(&mut self) -> Result<()> {
        self.y.end_third(&self.path)?;
        if let Some(c) = &mut self.u {
            c.end_third(&self.path)?;
        }
        Ok(())
    }
}

/// The first pass over a run (the reference not required, as `compensate` reads runs): every
/// row checked, the time column's steps, the sample rate; with `each` called on every row (a
/// caller's own running figures). The checks' order and messages are [`Trace::read`]'s: a bad
/// cell first, then time that does not increase, then jitter (found by a second look at the
/// file when the steps' extremes show there is some), then an implausible rate. A file that is
/// not a regular file (a pipe, a device) is refused after this pass, which it passed: it
/// cannot be read again.
///
/// # Errors
/// As [`Trace::read`]; [`TraceError::NotRereadable`].
///
/// [`Trace::read`]: super::Trace::read
pub fn scan(
    path: &Path,
    columns: &Columns,
    mut each: impl FnMut(&Row),
) -> Result<(RunInfo, RunChecks)> {
    let mut rows = RunRows::open(path, columns, csv::Trim::None)?;
    let layout = &rows.rows.layout;
    let mut checks = RunChecks {
        path: path.to_path_buf(),
        y: ClipScan::new(layout.y_idx + 1, layout.name_of(layout.y_idx)),
        u: layout
            .u_idx
            .map(|i| ClipScan::new(i + 1, layout.name_of(i))),
    };
    let headers = rows.headers().clone();
    let has_reference = rows.has_reference();
    let rereadable = rows.rereadable;
    let mut steps = Steps::default();
    let (mut reference_head, mut probe_head) = (Vec::new(), Vec::new());
    while let Some(row) = rows.next_row()? {
        steps.push(row.t, row.line);
        if probe_head.len() < 64 {
            probe_head.push(row.y);
            reference_head.extend(row.u);
        }
        checks.y.first(row.y);
        if let (Some(c), Some(u)) = (&mut checks.u, row.u) {
            c.first(u);
        }
        each(&row);
    }
    let layout = rows.rows.layout.clone();
    let sha256 = rows.sha256();
    let sample_rate_hz = steps.sample_rate(path, columns, &layout, |nominal| {
        if steps.any_jitters(nominal) {
            first_jitter(path, columns, nominal).map(Some)
        } else {
            Ok(None)
        }
    })?;
    if !rereadable {
        return Err(TraceError::NotRereadable {
            path: path.to_path_buf(),
        });
    }
    checks.y.end_first();
    if let Some(c) = &mut checks.u {
        c.end_first();
    }
    Ok((
        RunInfo {
            path: path.to_path_buf(),
            len: steps.rows(),
            sample_rate_hz,
            has_reference,
            headers,
            sha256,
            reference_head,
            probe_head,
        },
        checks,
    ))
}

/// The line and step of the first time step of the run at `path` that jitters by more than
/// [`MAX_JITTER`](super::MAX_JITTER) around `nominal`: a second look at the file, made only
/// when the first pass's extreme steps showed there is one.
///
/// # Errors
/// As [`RunRows::next_row`]; [`TraceError::Mismatch`] when no step jitters now (the file
/// changed).
fn first_jitter(path: &Path, columns: &Columns, nominal: f64) -> Result<(u64, f64)> {
    let mut rows = RunRows::open(path, columns, csv::Trim::None)?;
    let mut last: Option<f64> = None;
    while let Some(row) = rows.next_row()? {
        if let (Some(a), Some(b)) = (last, row.t) {
            let step: f64 = b - a;
            if super::timing::jitters(step, nominal) {
                return Ok((row.line, step));
            }
        }
        last = row.t;
    }
    Err(changed(path))
}

/// Writes one row of a run back with `extra` values after its fields: the fields as `rows`
/// read them (with [`csv::Trim::All`]), joined by the file's delimiter, each extra value as
/// the shortest text that reads back to it (with a decimal comma when the file has them);
/// `line` is a reused buffer. The same bytes as [`Trace::write_csv_with`](super::Trace::write_csv_with).
pub fn write_row(record: &csv::StringRecord, extra: &[f64], columns: &Columns, line: &mut Vec<u8>) {
    let dialect = (columns.delimiter, columns.decimal_comma);
    row_line(record, extra.iter().copied(), dialect, line);
}

/// The header line of a run written back with `extra` columns after its own.
#[must_use]
pub fn header_line(headers: &csv::StringRecord, extra: &[&str], columns: &Columns) -> String {
    write::header_line(headers, extra.iter().copied(), columns.delimiter)
}

/// Reads the run at `path` again from its start, to the end of the file, checking each row
/// against the first pass: the same number of rows and the same bytes.
///
/// # Errors
/// As [`RunRows::open`].
pub fn again(info: &RunInfo, columns: &Columns) -> Result<RunRows> {
    RunRows::open(&info.path, columns, csv::Trim::All)
}

/// Ends a pass opened by [`again`]: an error unless it read as many rows as the first pass
/// (`rows`) and the same bytes.
///
/// # Errors
/// [`TraceError::Mismatch`] when the file changed.
pub fn end_pass(info: &RunInfo, rows: RunRows, read: usize) -> Result<()> {
    if read == info.len && rows.sha256() == info.sha256 {
        Ok(())
    } else {
        Err(changed(&info.path))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exact_median(v: &[f64]) -> f64 {
        let mut s = v.to_vec();
        let mid = s.len() / 2;
        s.select_nth_unstable_by(mid, f64::total_cmp);
        s[mid]
    }

    fn streamed_median(v: &[f64]) -> Option<f64> {
        let mut m = Median::new();
        v.iter().for_each(|&x| m.first(x));
        m.end_first();
        v.iter().for_each(|&x| m.second(x));
        m.value()
    }

    #[test]
    fn the_streamed_median_is_the_selected_element() {
        // Noise-like values, quantised values (many equal), and a few values.
        let noise: Vec<f64> = crate::testing::gaussian(10_001, 5)
            .iter()
            .map(|v| v.abs())
            .collect();
        let quantised: Vec<f64> = noise.iter().map(|v| (v * 8.0).round() / 8.0).collect();
        for v in [
            &noise[..],
            &quantised[..],
            &noise[..3],
            &noise[..2],
            &noise[..1],
        ] {
            assert_eq!(streamed_median(v), Some(exact_median(v)), "{}", v.len());
        }
        assert_eq!(streamed_median(&[]), None);
    }

    #[test]
    fn the_first_pass_and_trace_read_give_the_same_message() {
        let dir = std::env::temp_dir().join(format!("unlag-same-message-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let columns = Columns {
            require_input: false,
            ..Columns::default()
        };
        let cases = [
            "t,u,y\n0,0,0\n0.001,x,1\n",
            "t,u,y\n0,0,0\n0.001,1\n",
            "t,u,y\n0,0,0\n0.001,1,inf\n",
            "t,u,y\n0,0,0\n0.001,1,1e300\n",
            "t,u,y\n0,0,0\n0.001,1,1\n0.001,1,1\n",
            "t,u,y\n0,0,0\n0.001,1,1\n0.0025,1,1\n0.003,0,1\n",
            "t,u,y\n0,0,0\n1,1,1\n2,0,1\n",
            "t,u,y\n",
            "t,u,y\n0,1,2\n",
            "a;b\n1;2\n",
            "x,y\n1,2\n",
        ];
        for (k, text) in cases.iter().enumerate() {
            let path = dir.join(format!("{k}.csv"));
            std::fs::write(&path, text).unwrap();
            let read = super::super::Trace::read(&path, &columns).unwrap_err();
            let streamed = scan(&path, &columns, |_| {}).unwrap_err();
            assert_eq!(read.to_string(), streamed.to_string(), "{text:?}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
