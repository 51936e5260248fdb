//! Writing results so that nothing is lost or half-written: a temporary file renamed over the
//! target at the end, devices and standard output written in place.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// What stops a streamed write: the output failed, or what was being written did.
#[derive(Debug)]
pub enum WriteFailure {
    /// Writing to the output failed.
    Output(std::io::Error),
    /// The content could not be made (its error names its own file).
    Content(Error),
}

impl From<std::io::Error> for WriteFailure {
    fn from(e: std::io::Error) -> Self {
        Self::Output(e)
    }
}

impl From<Error> for WriteFailure {
    fn from(e: Error) -> Self {
        Self::Content(e)
    }
}

impl From<crate::trace::CopyFailure> for WriteFailure {
    fn from(e: crate::trace::CopyFailure) -> Self {
        match e {
            crate::trace::CopyFailure::Output(e) => Self::Output(e),
            crate::trace::CopyFailure::Trace(e) => Self::Content(e.into()),
        }
    }
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
    write_atomically_with(path, |out| Ok(out.write_all(bytes)?))
}

/// [`write_atomically`] for content made as it is written: `fill` writes it to the (buffered)
/// output, so that a long result never has to be held in memory. When `fill` fails, nothing is
/// left behind (a regular file's temporary is removed; a device or standard output may have
/// received part of it).
///
/// # Errors
/// [`Error::Io`] naming `path` when the output fails; `fill`'s own error otherwise.
pub fn write_atomically_with<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> std::result::Result<(), WriteFailure>,
{
    let io = |action: &'static str, source: std::io::Error| Error::Io {
        path: path.to_path_buf(),
        action,
        source,
    };
    let failed = |action: &'static str, f: WriteFailure| match f {
        WriteFailure::Output(e) => io(action, bare(&e)),
        WriteFailure::Content(e) => e,
    };
    let buffered = |w: &mut dyn Write, fill: F| -> std::result::Result<(), WriteFailure> {
        let mut out = std::io::BufWriter::with_capacity(1 << 16, w);
        fill(&mut out)?;
        out.flush()?;
        Ok(())
    };
    if path == Path::new("-") {
        let mut out = std::io::stdout().lock();
        return match buffered(&mut out, fill) {
            // The reader stopped (`| head`): what it wanted, it has.
            Err(WriteFailure::Output(e)) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
            r => r.map_err(|f| failed("cannot write to standard output", f)),
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
            return buffered(&mut f, fill).map_err(|e| failed("cannot write", e));
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
    buffered(tmp.as_file_mut(), fill).map_err(|e| failed("cannot write", e))?;
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
    use crate::trace::{Columns, Trace};

    #[test]
    fn a_trace_is_streamed_back_with_new_columns_and_a_changed_one_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("in.csv");
        let text = "t,u,y\n# a comment\n0, 0,0\n0.001,1,0.5\n0.002,1,0.75\n";
        std::fs::write(&input, text).unwrap();
        let tr = Trace::read(&input, &Columns::default()).unwrap();
        assert_eq!(tr.y, [0.0, 0.5, 0.75]);
        let out = dir.path().join("out.csv");
        write_atomically_with(&out, |w| {
            Ok(tr.write_csv_with(w, &[("u_hat", &[0.0, 1.0, 2.5])])?)
        })
        .unwrap();
        assert_eq!(
            std::fs::read_to_string(&out).unwrap(),
            "t,u,y,u_hat\n0,0,0,0\n0.001,1,0.5,1\n0.002,1,0.75,2.5\n"
        );
        // The input changes between reading and writing: nothing is written.
        std::fs::write(&input, text.replace("0.75", "0.70")).unwrap();
        let again = dir.path().join("again.csv");
        let e = write_atomically_with(&again, |w| {
            Ok(tr.write_csv_with(w, &[("u_hat", &[0.0, 1.0, 2.5])])?)
        })
        .unwrap_err();
        assert!(
            e.to_string().contains("changed while unlag was running"),
            "{e}"
        );
        assert!(!again.exists());
        // Only the output named is in the directory: no temporary left behind.
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 2, "{names:?}");
    }
}
