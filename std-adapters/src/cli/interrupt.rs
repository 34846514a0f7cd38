//! Ctrl-C (SIGINT) and SIGTERM for the `slamesh` program. [`install`] (the program's `main`
//! only: a program that embeds the command, the Python module, keeps its own handling) sets
//! one handler for the process. While a command [listens](listen) (a run between frames, a
//! node, a live input), the first signal sets the flag it reads and it ends as it would at
//! the end of its input, writing what it has; a second signal, or one that comes while nothing
//! listens, ends the process at once with status 130, as the default handler would.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

/// The process's flag, when [`install`] set the handler.
static STOP: OnceLock<Arc<AtomicBool>> = OnceLock::new();
/// Whether a command reads the flag now.
static LISTENING: AtomicBool = AtomicBool::new(false);

/// The exit status of a process ended by SIGINT (128 + 2).
pub const INTERRUPTED_STATUS: u8 = 130;

/// Sets the process's handler; said and left to the default handling when it cannot be set.
pub fn install() {
    let flag = Arc::new(AtomicBool::new(false));
    let seen = flag.clone();
    let handler = move || {
        if !LISTENING.load(Ordering::SeqCst) || seen.swap(true, Ordering::SeqCst) {
            std::process::exit(i32::from(INTERRUPTED_STATUS));
        }
    };
    match ctrlc::set_handler(handler) {
        Ok(()) => {
            let _ = STOP.set(flag);
        }
        Err(e) => log::warn!("Ctrl-C will not end a run cleanly: {e}"),
    }
}

/// The process's flag, which a command reads from now on, when [`install`] set the handler
/// (the `slamesh` program); `None` in a program that embeds the command, whose own Ctrl-C
/// handling (Python's `KeyboardInterrupt`) is left as it is.
pub fn listen_if_installed() -> Option<Arc<AtomicBool>> {
    let flag = STOP.get()?;
    LISTENING.store(true, Ordering::SeqCst);
    Some(flag.clone())
}

/// The flag a command reads from now on: the process's when [`install`] set the handler
/// (the first signal then sets it), otherwise one set on the first signal by a handler set
/// now (`None` when none can be): for what only a signal ends (a live input, the node).
pub fn listen() -> Option<Arc<AtomicBool>> {
    if let Some(flag) = listen_if_installed() {
        return Some(flag);
    }
    let flag = Arc::new(AtomicBool::new(false));
    let set = flag.clone();
    match ctrlc::set_handler(move || set.store(true, Ordering::SeqCst)) {
        Ok(()) => Some(flag),
        Err(e) => {
            log::warn!("Ctrl-C will not end the run cleanly: {e}");
            None
        }
    }
}
