//! The CLI's exit on SIGINT, SIGTERM and SIGHUP: the unfinished outputs' temporary files are
//! removed ([`crate::file::remove_unfinished`]), one line says what was not written, and the
//! process exits with the conventional status 128 + the signal's number. The library never
//! installs this by itself: the `unlag` binary calls [`install`].

/// Handles SIGINT, SIGTERM and SIGHUP on a thread of their own (see the module). When the
/// handlers cannot be installed, the signals keep their default action (the run is killed and
/// its temporary, `.unlag-*.partial`, is removed by the next run writing beside it once stale).
#[cfg(unix)]
pub fn install() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
        return;
    };
    let _ = std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            if let Some(signal) = signals.forever().next() {
                let name = match signal {
                    SIGINT => "SIGINT",
                    SIGTERM => "SIGTERM",
                    _ => "SIGHUP",
                };
                // Exits with the writes held, so that none reports being stopped.
                crate::file::remove_unfinished(|abandoned| {
                    match abandoned.first() {
                        Some(path) => crate::errln!(
                            "error: interrupted by {name}: {} was not written (its unfinished \
                             copy is removed; a file already there is unchanged)",
                            path.display()
                        ),
                        None => crate::errln!("error: interrupted by {name}"),
                    }
                    std::process::exit(128 + signal)
                });
            }
        });
}

/// Other platforms keep the signals' default actions.
#[cfg(not(unix))]
pub fn install() {}
