//! Ctrl-C: the first press asks the run to stop (the fit's observer returns `false` at its next
//! iteration, a batch takes no new file, nothing unfinished is renamed into place); a second
//! press exits at once with status 130.
//!
//! The handler is installed once per process (the `ctrlc` crate allows no more) and stays
//! installed; between runs (e.g. after `run_cli` returned in a Python process) a press exits
//! the process with status 130, as the default SIGINT action would.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Once;

static REQUESTED: AtomicBool = AtomicBool::new(false);
static ACTIVE: AtomicUsize = AtomicUsize::new(0);
static INSTALL: Once = Once::new();

/// Whether a stop was asked for since the current run began.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed)
}

/// Marks a run as active for as long as it is alive, installing the handler on first use.
pub struct Guard(());

impl Guard {
    /// Starts a run: clears an earlier request and makes sure the handler is installed.
    pub fn start() -> Self {
        INSTALL.call_once(|| {
            // Failing to install (another handler owns SIGINT) only loses the clean stop.
            let _ = ctrlc::set_handler(|| {
                if ACTIVE.load(Ordering::SeqCst) == 0 || REQUESTED.swap(true, Ordering::SeqCst) {
                    std::process::exit(super::exit_code::INTERRUPTED);
                }
                eprintln!("interrupted: stopping after the current iteration (Ctrl-C again to quit at once)");
            });
        });
        if ACTIVE.fetch_add(1, Ordering::SeqCst) == 0 {
            REQUESTED.store(false, Ordering::SeqCst);
        }
        Guard(())
    }
}

impl Drop for Guard {
    fn drop(&mut self) {
        ACTIVE.fetch_sub(1, Ordering::SeqCst);
    }
}
