//! Writing a trace's rows back with new columns after its own: the header line and each row
//! as bytes, in the file's delimiter and decimal mark, for [`Trace::write_csv_with`] (a trace
//! held in memory) and the streamed passes of [`stream`](super::stream) alike.

use std::io::{Read, Write};
use std::path::Path;

use sha2::Digest;

use super::rows::{csv_reader, hex, Hashing};
use super::{CopyFailure, Source, Trace, TraceError};

/// The error of a trace whose file changed after it was first read.
#[must_use]
pub fn changed(path: &Path) -> TraceError {
    TraceError::Mismatch {
        path: path.to_path_buf(),
        message: "the file changed while unlag was running; run again".into(),
    }
}

/// The header line of a trace written back: its own `headers`, then the `extra` names, joined
/// by `delimiter`.
pub(super) fn header_line<'a>(
    headers: &csv::StringRecord,
    extra: impl IntoIterator<Item = &'a str>,
    delimiter: u8,
) -> String {
    let sep = char::from(delimiter);
    let mut header = headers.iter().collect::<Vec<_>>().join(&sep.to_string());
    for name in extra {
        header.push(sep);
        header.push_str(name);
    }
    header.push('\n');
    header
}

/// One row of a trace written back into `line` (a reused buffer): its fields as `record` holds
/// them, joined by `delimiter`, then each `extra` value as the shortest text that reads back
/// to it (with a decimal comma when `decimal_comma`).
pub(super) fn row_line(
    record: &csv::StringRecord,
    extra: impl IntoIterator<Item = f64>,
    (delimiter, decimal_comma): (u8, bool),
    line: &mut Vec<u8>,
) {
    line.clear();
    for (i, f) in record.iter().enumerate() {
        if i > 0 {
            line.push(delimiter);
        }
        line.extend_from_slice(f.as_bytes());
    }
    for v in extra {
        // `{}` on f64 prints the shortest text that reads back to the same value.
        let text = v.to_string();
        line.push(delimiter);
        if decimal_comma {
            line.extend_from_slice(text.replace('.', ",").as_bytes());
        } else {
            line.extend_from_slice(text.as_bytes());
        }
    }
    line.push(b'\n');
}

impl Trace {
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
        let mismatch = || -> CopyFailure { changed(&self.path).into() };
        let header = header_line(
            &self.headers,
            extra.iter().map(|(name, _)| *name),
            self.dialect.0,
        );
        out.write_all(header.as_bytes())?;
        let mut copy = |reader: &mut dyn Read| -> std::result::Result<(), CopyFailure> {
            let mut reader = csv_reader(reader, self.dialect.0, csv::Trim::All);
            let mut rec = csv::StringRecord::new();
            // Skip the header.
            reader.headers().map_err(|_| mismatch())?;
            let mut k = 0;
            let mut line = Vec::with_capacity(128);
            while reader.read_record(&mut rec).map_err(|_| mismatch())? {
                if extra.iter().any(|(_, col)| col.len() <= k) {
                    return Err(mismatch());
                }
                let values = extra.iter().filter_map(|(_, col)| col.get(k).copied());
                row_line(&rec, values, self.dialect, &mut line);
                out.write_all(&line)?;
                k += 1;
            }
            if k == self.len() {
                Ok(())
            } else {
                Err(mismatch())
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
                    Err(mismatch())
                }
            }
        }
    }
}
