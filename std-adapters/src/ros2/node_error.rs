//! Why the ROS 2 node, or one of its topics or services, could not be made ([`NodeError`]):
//! what [`crate::ros2::node`] and the listening thread ([`crate::ros2::listen`]) say.

/// Why the node, or one of its topics or services, could not be made.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NodeError {
    /// A name ROS 2 does not take: the name, what it should be, and RustDDS's reason.
    Name {
        /// The name.
        name: String,
        /// What it should be ("a ROS 2 name", "a node name").
        kind: &'static str,
        /// RustDDS's reason.
        why: String,
    },
    /// The node could not start: what it was doing ("join DDS domain 0"), and why.
    Start {
        /// What it was doing.
        doing: String,
        /// Why it could not.
        why: String,
    },
    /// A topic or service could not be made: its name, what was asked ("subscribe"), and why.
    Topic {
        /// The topic's or service's name.
        name: String,
        /// What was asked.
        doing: &'static str,
        /// Why it could not.
        why: String,
    },
}

impl std::fmt::Display for NodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NodeError::Name { name, kind, why } => write!(f, "{name}: not {kind} ({why})"),
            NodeError::Start { doing, why } => write!(f, "cannot {doing}: {why}"),
            NodeError::Topic { name, doing, why } => write!(f, "{name}: cannot {doing}: {why}"),
        }
    }
}

impl std::error::Error for NodeError {}
