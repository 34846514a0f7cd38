//! The node's parameters as ROS 2 tools see them (`ros2 param list`, `get`, `set`,
//! `describe`): served by ros2-client's parameter services, on a thread of their own.
//!
//! What it guarantees: every parameter the node was started with is declared with the value
//! it runs with; [`LIVE`] ones are set while the node runs (the next frame uses them); every
//! other set is refused with a reason (set at start only), and nothing changes.

use ros2_client::parameters::ParameterValue;
use ros2_client::NodeOptions;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// The parameters that can be set while the node runs.
pub const LIVE: [&str; 1] = ["publish_mesh"];

/// Why a set was refused (the answer `ros2 param set` prints).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Refused {
    /// The parameter is read at start only.
    StartOnly(String),
    /// `publish_mesh` turned on where its publisher was not made at start.
    NotMadeAtStart,
    /// A true-or-false parameter given something else.
    NotABool(String),
}

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refused::StartOnly(name) => write!(
                f,
                "{name} is set at start only: restart the node with -p {name}:=VALUE (set while \
                 running: {})",
                LIVE.join(", ")
            ),
            Refused::NotMadeAtStart => write!(
                f,
                "publish_mesh was false at start: the mesh's publisher was not made (restart \
                 with -p publish_mesh:=true)"
            ),
            Refused::NotABool(name) => write!(f, "{name} is true or false"),
        }
    }
}

/// What can be set while the node runs, shared with the sink that reads it.
#[derive(Debug, Clone)]
pub struct Live {
    /// Whether `mesh` is published (only when it was at start: its publisher is made then).
    pub publish_mesh: Arc<AtomicBool>,
    /// Whether the mesh's publisher was made at start.
    mesh_made: bool,
    /// Whether the node has started: until then every declared value is taken.
    running: Arc<AtomicBool>,
}

impl Live {
    /// The live values as the node starts.
    pub fn new(publish_mesh: bool) -> Self {
        Live {
            publish_mesh: Arc::new(AtomicBool::new(publish_mesh)),
            mesh_made: publish_mesh,
            running: Arc::new(AtomicBool::new(false)),
        }
    }

    /// From now on, sets are checked ([`check`](Self::check)): the declared values are in.
    pub fn started(&self) {
        self.running.store(true, Ordering::Relaxed);
    }

    /// Whether `name` may take `value` now; why not when it may not.
    pub fn check(&self, name: &str, value: &ParameterValue) -> Result<(), Refused> {
        if !self.running.load(Ordering::Relaxed) {
            return Ok(());
        }
        match (name, value) {
            ("publish_mesh", ParameterValue::Boolean(on)) if *on && !self.mesh_made => {
                Err(Refused::NotMadeAtStart)
            }
            ("publish_mesh", ParameterValue::Boolean(_)) => Ok(()),
            ("publish_mesh", _) => Err(Refused::NotABool(name.into())),
            _ => Err(Refused::StartOnly(name.into())),
        }
    }

    /// Applies a value [`check`](Self::check) allowed.
    pub fn apply(&self, name: &str, value: &ParameterValue) {
        if let ("publish_mesh", ParameterValue::Boolean(on)) = (name, value) {
            self.publish_mesh.store(*on, Ordering::Relaxed);
            log::info!("parameter publish_mesh set to {on}");
        }
    }
}

/// The node's options: its parameters declared with `values`, sets checked and applied by
/// `live`; `/rosout` on (the node's log lines go there too: [`crate::ros2::node`]).
pub fn options(values: Vec<(String, ParameterValue)>, live: &Live) -> NodeOptions {
    let (check, apply) = (live.clone(), live.clone());
    let mut options = NodeOptions::new()
        .enable_rosout(true)
        .parameter_validator(Box::new(move |n, v| {
            check.check(n, v).map_err(|e| e.to_string())
        }))
        .parameter_set_action(Box::new(move |n, v| {
            apply.apply(n, v);
            Ok(())
        }));
    for (name, value) in values {
        options = options.declare_parameter(&name, value);
    }
    options
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_live_parameters_are_set_and_the_rest_are_refused_with_a_reason() {
        let live = Live::new(true);
        assert_eq!(
            live.check("preset", &ParameterValue::String("x".into())),
            Ok(())
        );
        live.started();
        assert_eq!(
            live.check("publish_mesh", &ParameterValue::Boolean(false)),
            Ok(())
        );
        live.apply("publish_mesh", &ParameterValue::Boolean(false));
        assert!(!live.publish_mesh.load(Ordering::Relaxed));
        let e = live.check("preset", &ParameterValue::String("fast".into()));
        assert_eq!(e, Err(Refused::StartOnly("preset".into())));
        assert!(e
            .unwrap_err()
            .to_string()
            .contains("preset is set at start only"));
        assert!(live
            .check("publish_mesh", &ParameterValue::Integer(1))
            .is_err());
        let off = Live::new(false);
        off.started();
        let e = off
            .check("publish_mesh", &ParameterValue::Boolean(true))
            .unwrap_err();
        assert_eq!(e, Refused::NotMadeAtStart);
        assert!(e.to_string().contains("was false at start"), "{e}");
    }
}
