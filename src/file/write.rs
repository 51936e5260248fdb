//! Writing results so that nothing is lost or half-written: a temporary file renamed over the
//! target at the end, devices and standard output written in place.
//!
//! The temporary files being written are listed ([`remove_unfinished`] removes them: the CLI
//! calls it when interrupted by a signal; the library installs no signal handler), and a write
//! removes the stale temporaries an earlier, killed run left beside its output.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::Duration;

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

/// The temporary files of the writes under way, each with the output it becomes; `abandoned`
/// once [`remove_unfinished`] has run (no temporary is made or renamed after it).
struct Live {
    temporaries: Vec<(PathBuf, PathBuf)>,
    abandoned: bool,
}

static LIVE: Mutex<Live> = Mutex::new(Live {
    temporaries: Vec::new(),
    abandoned: false,
});

/// The outputs written to disk by this process, in order.
static WRITTEN: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn live() -> MutexGuard<'static, Live> {
    LIVE.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Removes the temporary files of the writes under way, then calls `then` with the outputs
/// they were for and returns what it returns. From then on no write makes or renames a
/// temporary (each fails instead), and while `then` runs none even finishes failing: a
/// program exiting on a signal exits in `then`, and no other thread reports the writes it
/// stopped. For the program's own signal handling (the `unlag` binary's, see
/// `unlag::cli::signals`), never from a signal handler itself (this takes a lock and
/// allocates).
pub fn remove_unfinished<R>(then: impl FnOnce(Vec<PathBuf>) -> R) -> R {
    let mut live = live();
    live.abandoned = true;
    let targets = std::mem::take(&mut live.temporaries)
        .into_iter()
        .map(|(tmp, target)| {
            let _ = std::fs::remove_file(&tmp);
            target
        })
        .collect();
    then(targets)
}

/// The files this process has written so far (by [`write_atomically`] and
/// [`write_atomically_with`], standard output and devices excepted), in order.
#[must_use]
pub fn written() -> Vec<PathBuf> {
    WRITTEN
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .clone()
}

/// A temporary file being written, listed in [`LIVE`] from its creation until it is renamed
/// over its target or removed (on drop).
struct Pending {
    tmp: Option<tempfile::NamedTempFile>,
    path: PathBuf,
}

impl Pending {
    /// Creates the temporary in `dir` and lists it, both under the lock, so that
    /// [`remove_unfinished`] never misses one.
    fn create(
        builder: &tempfile::Builder<'_, '_>,
        dir: &Path,
        target: &Path,
    ) -> std::io::Result<Self> {
        let mut live = live();
        if live.abandoned {
            return Err(interrupted());
        }
        let tmp = builder.tempfile_in(dir)?;
        let path = tmp.path().to_path_buf();
        live.temporaries.push((path.clone(), target.to_path_buf()));
        Ok(Self {
            tmp: Some(tmp),
            path,
        })
    }

    fn file(&mut self) -> std::io::Result<&mut std::fs::File> {
        self.tmp
            .as_mut()
            .map(tempfile::NamedTempFile::as_file_mut)
            .ok_or_else(interrupted)
    }

    /// Renames the temporary over `target` (unless the writes were abandoned meanwhile).
    fn persist(mut self, target: &Path) -> std::io::Result<()> {
        let mut live = live();
        if live.abandoned {
            return Err(interrupted());
        }
        let tmp = self.tmp.take().ok_or_else(interrupted)?;
        live.temporaries.retain(|(p, _)| *p != self.path);
        tmp.persist(target).map_err(|e| e.error)?;
        WRITTEN
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(target.to_path_buf());
        Ok(())
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        let mut live = live();
        // Removes the file (if still there).
        drop(self.tmp.take());
        live.temporaries.retain(|(p, _)| *p != self.path);
    }
}

fn interrupted() -> std::io::Error {
    std::io::Error::new(std::io::ErrorKind::Interrupted, "interrupted")
}

/// A temporary of an earlier run this old (by its modification time) is stale: its run was
/// killed (a write under way changes its temporary all the time).
pub const STALE_AFTER: Duration = Duration::from_secs(3600);

/// Removes the stale temporaries in `dir`: `.unlag-*.partial` regular files owned by `uid`
/// (this process's user: the owner of the temporary it has just made) not modified for
/// [`STALE_AFTER`], left by runs that were killed. Best effort: what cannot be removed stays.
#[cfg(unix)]
fn remove_stale(dir: &Path, uid: u32) {
    use std::os::unix::fs::MetadataExt as _;
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let now = std::time::SystemTime::now();
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        if !(name.starts_with(".unlag-") && name.ends_with(".partial")) {
            continue;
        }
        let Ok(m) = entry.metadata() else { continue };
        let old = m
            .modified()
            .ok()
            .and_then(|t| now.duration_since(t).ok())
            .is_some_and(|age| age > STALE_AFTER);
        if m.is_file() && m.uid() == uid && old {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Refuses to let an output replace the existing file at `path` when it is read-only (always)
/// or, unless `force`, when it is a regular file that is not one of the command's own outputs
/// (`own` is true of the first bytes of those; `what` names them in the message: "an output of
/// unlag compensate"). An empty file, a missing one, a device, a pipe and `-` pass (the write
/// says what is wrong with a directory). For a command to call before its work, so that a long
/// run does not end in a refusal.
///
/// # Errors
/// [`Error::NotReplaced`] naming `path`, the cause and the way out.
pub fn check_replace(
    path: &Path,
    own: impl Fn(&[u8]) -> bool,
    what: &str,
    force: bool,
) -> Result<()> {
    if path == Path::new("-") {
        return Ok(());
    }
    let Ok(m) = std::fs::metadata(path) else {
        return Ok(());
    };
    if !m.is_file() {
        return Ok(());
    }
    if m.permissions().readonly() {
        return Err(read_only(path));
    }
    if force || m.len() == 0 {
        return Ok(());
    }
    let mut head = Vec::with_capacity(4096);
    let read = std::fs::File::open(path)
        .and_then(|f| std::io::Read::read_to_end(&mut std::io::Read::take(f, 4096), &mut head));
    if read.is_ok() && own(&head) {
        return Ok(());
    }
    Err(Error::NotReplaced {
        path: path.to_path_buf(),
        reason: format!(
            "it exists and is not {what}, so it may be data of its own; give another output \
             name, or --force to replace it"
        ),
    })
}

fn read_only(path: &Path) -> Error {
    Error::NotReplaced {
        path: path.to_path_buf(),
        reason: "it exists and is read-only, so it is kept (even with --force); give another \
                 output name, or make it writable (chmod u+w) if it is to be replaced"
            .into(),
    }
}

/// Writes `bytes` to `path` so that nothing is lost or half-written:
///
/// - a regular file (new or existing) is written to a temporary file in its directory and
///   renamed over it at the end: readers never see a half-written file, and a failure leaves
///   any old file untouched. A new file takes the mode the umask gives (`0666 & !umask`), an
///   existing one keeps its own; a read-only file is never replaced (an error). Stale
///   temporaries of killed runs beside it are removed first (see [`STALE_AFTER`]); an
///   interrupted write's temporary is removed by [`remove_unfinished`];
/// - a symbolic link is followed: the file it points to is replaced, the link stays;
/// - a character device or a pipe (`/dev/null`, `/dev/stdout`, a FIFO) is written in place
///   (it cannot be renamed over), and a full device is an error;
/// - `-` is standard output;
/// - a directory or a block device is refused.
///
/// Errors name `path`, never the temporary file.
///
/// # Errors
/// [`Error::Io`] when the target cannot be written; [`Error::NotReplaced`] when it is a
/// read-only file.
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
        if m.is_file() && m.permissions().readonly() {
            return Err(read_only(path));
        }
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
    let mut tmp =
        Pending::create(&builder, &dir, &target).map_err(|e| io("cannot write", bare(&e)))?;
    let file = tmp.file().map_err(|e| io("cannot write", e))?;
    #[cfg(unix)]
    if let Ok(m) = file.metadata() {
        use std::os::unix::fs::MetadataExt as _;
        remove_stale(&dir, m.uid());
    }
    if let Some(m) = &existing {
        file.set_permissions(m.permissions())
            .map_err(|e| io("cannot keep the mode of", bare(&e)))?;
    }
    buffered(file, fill).map_err(|e| failed("cannot write", e))?;
    file.sync_all().map_err(|e| io("cannot write", bare(&e)))?;
    tmp.persist(&target)
        .map_err(|e| io("cannot write", bare(&e)))?;
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

    /// The temporaries listed for writes to `target`.
    fn listed(target: &Path) -> Vec<PathBuf> {
        live()
            .temporaries
            .iter()
            .filter(|(_, t)| t == target)
            .map(|(p, _)| p.clone())
            .collect()
    }

    #[test]
    fn a_temporary_is_listed_while_it_is_written_and_not_after() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.csv");
        let mut during = Vec::new();
        write_atomically_with(&out, |w| {
            during = listed(&out);
            Ok(w.write_all(b"a\n")?)
        })
        .unwrap();
        assert_eq!(during.len(), 1, "{during:?}");
        let name = during[0].file_name().unwrap().to_str().unwrap();
        assert!(
            name.starts_with(".unlag-") && name.ends_with(".partial"),
            "{name}"
        );
        assert_eq!(during[0].parent(), Some(dir.path()));
        assert!(listed(&out).is_empty());
        assert!(!during[0].exists());
        assert!(written().contains(&out));
        // A failed write: its temporary removed and unlisted, the old file kept.
        let e = write_atomically_with(&out, |w| {
            during = listed(&out);
            w.write_all(b"half")?;
            Err(WriteFailure::Output(std::io::Error::other(
                "the disk is full",
            )))
        })
        .unwrap_err();
        assert!(
            e.to_string()
                .starts_with(&format!("{}: cannot write", out.display())),
            "{e}"
        );
        assert_eq!(during.len(), 1);
        assert!(listed(&out).is_empty());
        assert!(!during[0].exists());
        assert_eq!(std::fs::read(&out).unwrap(), b"a\n");
    }

    #[cfg(unix)]
    #[test]
    fn a_write_removes_the_stale_temporaries_of_its_user_beside_it_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let at = |name: &str| dir.path().join(name);
        let long_ago = std::time::SystemTime::now() - STALE_AFTER - Duration::from_secs(60);
        let age = |p: &Path, t: std::time::SystemTime| {
            std::fs::File::options()
                .write(true)
                .open(p)
                .unwrap()
                .set_modified(t)
                .unwrap();
        };
        // Stale: a killed run's temporary. Kept: a recent one (a run under way), files not
        // named like a temporary, a directory named like one.
        let stale = at(".unlag-AbC123.partial");
        let recent = at(".unlag-XyZ789.partial");
        let others = [
            at(".unlag-AbC124.tmp"),
            at("unlag-AbC125.partial"),
            at("data.csv"),
        ];
        for p in others.iter().chain([&stale, &recent]) {
            std::fs::write(p, "x").unwrap();
        }
        for p in others.iter().chain([&stale]) {
            age(p, long_ago);
        }
        std::fs::create_dir(at(".unlag-dir000.partial")).unwrap();
        // Another user's stale temporary is theirs to remove (only root can make one here).
        let theirs = at(".unlag-Other1.partial");
        std::fs::write(&theirs, "x").unwrap();
        age(&theirs, long_ago);
        let chowned = std::os::unix::fs::chown(&theirs, Some(54_321), None).is_ok();
        write_atomically(&at("out.csv"), b"a\n").unwrap();
        assert!(!stale.exists());
        assert!(recent.exists());
        for p in &others {
            assert!(p.exists(), "{}", p.display());
        }
        assert!(at(".unlag-dir000.partial").is_dir());
        assert_eq!(theirs.exists(), chowned);
        assert_eq!(std::fs::read(at("out.csv")).unwrap(), b"a\n");
    }

    #[cfg(unix)]
    #[test]
    fn an_existing_file_is_replaced_when_it_is_the_commands_own_or_forced_never_when_read_only() {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = tempfile::tempdir().unwrap();
        let at = |name: &str| dir.path().join(name);
        let own = |head: &[u8]| head.starts_with(b"# mine");
        let what = "an output of this command";
        let check = |p: &Path, force| check_replace(p, own, what, force);
        // Nothing there, an empty file, the command's own, standard output, a device: go ahead.
        check(&at("new.csv"), false).unwrap();
        std::fs::write(at("empty.csv"), "").unwrap();
        check(&at("empty.csv"), false).unwrap();
        std::fs::write(at("own.csv"), "# mine\n1\n").unwrap();
        check(&at("own.csv"), false).unwrap();
        check(Path::new("-"), false).unwrap();
        check(Path::new("/dev/null"), false).unwrap();
        // Another file: refused without --force, saying why and what to do.
        std::fs::write(at("data.csv"), "t,y\n0,1\n").unwrap();
        let e = check(&at("data.csv"), false).unwrap_err();
        assert_eq!(e.kind(), "not-replaced");
        let text = e.to_string();
        assert!(
            text.starts_with(&format!("{}: refused", at("data.csv").display())),
            "{text}"
        );
        assert!(text.contains(what) && text.contains("--force"), "{text}");
        check(&at("data.csv"), true).unwrap();
        // Read-only: refused even with --force, and by the write itself.
        std::fs::set_permissions(at("own.csv"), std::fs::Permissions::from_mode(0o444)).unwrap();
        for force in [false, true] {
            let e = check(&at("own.csv"), force).unwrap_err();
            assert!(e.to_string().contains("read-only"), "{e}");
        }
        let e = write_atomically(&at("own.csv"), b"new").unwrap_err();
        assert!(e.to_string().contains("read-only"), "{e}");
        assert_eq!(std::fs::read(at("own.csv")).unwrap(), b"# mine\n1\n");
    }

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
