//! Why a configuration could not be read ([`ConfigError`]), and why one value was refused
//! ([`BadValue`]): what [`crate::run::config_file`] says of a file, a preset or a value.

use std::fmt;

/// Why a configuration (a file's text, a preset's name) could not be read.
#[derive(Debug, Clone, PartialEq)]
pub enum ConfigError {
    /// The text is not TOML: the parser's reason.
    Toml(String),
    /// A preset that is not one of these.
    UnknownPreset {
        /// The name given.
        name: String,
        /// The presets there are.
        known: &'static [&'static str],
    },
    /// A key that is not one there: where (`[grid] cell_size`, `[lidar]`, `colour`), and the
    /// keys known there (none for a section or a top-level key).
    Unknown {
        /// Where.
        at: String,
        /// What it is taken for: `parameter`, `section`, `top-level key`.
        kind: &'static str,
        /// The keys known there.
        known: Vec<&'static str>,
    },
    /// A value refused: where (`[imu] bias_gain`, `preset`), and why.
    Value {
        /// Where.
        at: String,
        /// Why.
        why: BadValue,
    },
    /// Values that do not hold together (the core's check): the field and the reason.
    Invalid {
        /// The field.
        field: String,
        /// The reason.
        reason: String,
    },
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::Toml(why) => f.write_str(why),
            ConfigError::UnknownPreset { name, known } => {
                write!(f, "{name:?} is not one of {}", known.join(", "))
            }
            ConfigError::Unknown { at, kind, known } if known.is_empty() => {
                write!(f, "{at}: unknown {kind}")
            }
            ConfigError::Unknown { at, kind, known } => {
                write!(f, "{at}: unknown {kind} (known: {})", known.join(", "))
            }
            ConfigError::Value { at, why } => write!(f, "{at}: {why}"),
            ConfigError::Invalid { field, reason } => write!(f, "{field}: {reason}"),
        }
    }
}

impl std::error::Error for ConfigError {}

/// Why one value was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum BadValue {
    /// Not of the kind expected: what was expected, and what was found (its type or value).
    Expected {
        /// What was expected ("a number").
        what: &'static str,
        /// What was found.
        found: String,
    },
    /// A whole number out of the range of its field.
    OutOfRange(i64),
    /// A number that must be finite.
    NotFinite(f64),
    /// A number that must be positive (and finite).
    NotPositive(f64),
    /// None of the words allowed: them, and what was found.
    OneOf {
        /// The words allowed, as the message lists them.
        choices: String,
        /// What was found.
        found: String,
    },
}

impl fmt::Display for BadValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BadValue::Expected { what, found } => write!(f, "expected {what}, found {found}"),
            BadValue::OutOfRange(i) => write!(f, "{i} is out of range"),
            BadValue::NotFinite(x) => write!(f, "must be a finite number, found {x}"),
            BadValue::NotPositive(x) => write!(f, "must be a positive number, found {x}"),
            BadValue::OneOf { choices, found } => write!(f, "{found} is not one of {choices}"),
        }
    }
}
