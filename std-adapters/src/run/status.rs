//! What became of a frame, as its record says it ([`FrameStatus`]): the core's registration
//! status, or skipped. Written in `report.json` and the report's spool by name
//! (`Converged`, `Skipped`), and read back by name.

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use slamesh_core::RegistrationStatus;
use std::fmt;

/// What became of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameStatus {
    /// The core's registration status (a frame searched for and not found is
    /// [`RegistrationStatus::NotLocalized`]).
    Registration(RegistrationStatus),
    /// Not registered: it could not be read or used, or was set aside (its record says why).
    Skipped,
}

impl FrameStatus {
    /// Every status: the core's in the order of its variants, then `Skipped` (the order the
    /// run's health counts them in).
    pub const ALL: [FrameStatus; RegistrationStatus::ALL.len() + 1] = {
        let mut all = [FrameStatus::Skipped; RegistrationStatus::ALL.len() + 1];
        let mut k = 0;
        while k < RegistrationStatus::ALL.len() {
            all[k] = FrameStatus::Registration(RegistrationStatus::ALL[k]);
            k += 1;
        }
        all
    };

    /// Its name, as the report writes it.
    pub fn name(self) -> &'static str {
        match self {
            FrameStatus::Registration(s) => s.name(),
            FrameStatus::Skipped => "Skipped",
        }
    }

    /// The status called `name`, if one is.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "Skipped" => Some(FrameStatus::Skipped),
            _ => RegistrationStatus::from_name(name).map(FrameStatus::Registration),
        }
    }

    /// Whether the frame was registered, normally or not
    /// ([`RegistrationStatus::is_registered`]); a skipped frame was not.
    pub fn is_registered(self) -> bool {
        matches!(self, FrameStatus::Registration(s) if s.is_registered())
    }
}

impl From<RegistrationStatus> for FrameStatus {
    fn from(s: RegistrationStatus) -> Self {
        FrameStatus::Registration(s)
    }
}

impl fmt::Display for FrameStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Compared by name: `record.status == "Converged"`.
impl PartialEq<str> for FrameStatus {
    fn eq(&self, name: &str) -> bool {
        self.name() == name
    }
}

impl PartialEq<&str> for FrameStatus {
    fn eq(&self, name: &&str) -> bool {
        self.name() == *name
    }
}

impl Serialize for FrameStatus {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for FrameStatus {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        FrameStatus::from_name(&name)
            .ok_or_else(|| serde::de::Error::custom(format!("no frame status {name:?}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_status_reads_back_by_its_name() {
        for s in FrameStatus::ALL {
            let text = serde_json::to_string(&s).unwrap();
            assert_eq!(text, format!("\"{}\"", s.name()));
            assert_eq!(serde_json::from_str::<FrameStatus>(&text).unwrap(), s);
        }
        assert!(serde_json::from_str::<FrameStatus>("\"Lost\"").is_err());
        assert!(!FrameStatus::Skipped.is_registered());
        assert!(FrameStatus::from(RegistrationStatus::Converged).is_registered());
    }
}
