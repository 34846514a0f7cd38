//! A second way out for the log's lines, beside the terminal: one tap a component installs
//! (the ROS 2 node's `/rosout`), handed every line the terminal shows at info level or above,
//! with its level, text, file and line. The command's logger ([`crate::cli`]) calls
//! [`forward`]; lines of the DDS stack's own (`rustdds`, `ros2_client`) are not forwarded, nor
//! a line the tap itself logs while it runs (no loop through it).

use std::cell::Cell;
use std::sync::Mutex;

/// What a tap is handed: the line's level, text, source file and line.
pub type Tap = Box<dyn Fn(log::Level, &str, &str, u32) + Send>;

static TAP: Mutex<Option<Tap>> = Mutex::new(None);

thread_local! {
    /// Set while this thread runs the tap.
    static IN_TAP: Cell<bool> = const { Cell::new(false) };
}

/// Targets whose lines are never forwarded: the transport's own, which a tap publishing
/// through it would otherwise feed back into itself.
const NOT_FORWARDED: [&str; 3] = ["rustdds", "ros2_client", "mio"];

/// Installs `tap` in place of any before.
pub fn install(tap: Tap) {
    if let Ok(mut t) = TAP.lock() {
        *t = Some(tap);
    }
}

/// Removes the tap.
pub fn remove() {
    if let Ok(mut t) = TAP.lock() {
        *t = None;
    }
}

/// Hands `record` to the tap, when one is installed and the line is at info level or above
/// and not the transport's.
pub fn forward(record: &log::Record) {
    if record.level() > log::Level::Info
        || NOT_FORWARDED.iter().any(|t| record.target().starts_with(t))
        || IN_TAP.with(Cell::get)
    {
        return;
    }
    let Ok(tap) = TAP.try_lock() else { return };
    let Some(tap) = tap.as_ref() else { return };
    IN_TAP.with(|f| f.set(true));
    let text = record.args().to_string();
    tap(
        record.level(),
        &text,
        record.file().unwrap_or(""),
        record.line().unwrap_or(0),
    );
    IN_TAP.with(|f| f.set(false));
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn lines_at_info_or_above_reach_the_tap_and_the_transport_s_do_not() {
        let seen: Arc<Mutex<Vec<String>>> = Arc::default();
        let into = seen.clone();
        install(Box::new(move |level, text, _, _| {
            into.lock().unwrap().push(format!("{level} {text}"));
        }));
        let line = |level, target: &str, text: &str| {
            forward(
                &log::Record::builder()
                    .level(level)
                    .target(target)
                    .args(format_args!("{text}"))
                    .build(),
            )
        };
        line(log::Level::Warn, "slamesh::ros2", "a cloud refused");
        line(log::Level::Info, "slamesh", "started");
        line(log::Level::Debug, "slamesh", "not shown");
        line(log::Level::Warn, "rustdds::dds", "the transport's");
        line(log::Level::Error, "ros2_client::rosout", "the tap's own");
        remove();
        line(log::Level::Warn, "slamesh", "after removal");
        let seen = seen.lock().unwrap();
        assert_eq!(*seen, ["WARN a cloud refused", "INFO started"]);
    }
}
