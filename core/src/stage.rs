//! Stage boundaries of one scan, for callers that time or trace the pipeline.
//!
//! The core reads no clock. Instead it tells a [`Probe`] each time a scan moves from one stage
//! to the next; a std caller can read its clock there (the `slamesh` report and bench do), a
//! firmware caller can toggle a pin or count cycles. [`NoProbe`] does nothing.

/// A stage of [`Pipeline`](crate::Pipeline) processing. Registration repeats
/// `Bucket → Reconstruct → Associate → Solve` once per round.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// Range filter and voxel down-sampling.
    Filter,
    /// Transforming points into the world and sorting them into cells.
    Bucket,
    /// Layer choice and Gaussian-process reconstruction of every cell.
    Reconstruct,
    /// Pairing scan and map vertices into residuals.
    Associate,
    /// Levenberg-Marquardt.
    Solve,
    /// Fusing the final reconstruction into the map.
    Update,
    /// The scan is finished (accepted or rejected).
    Done,
}

impl Stage {
    /// The working stages, in pipeline order (without [`Stage::Done`]).
    pub const WORKING: [Stage; 6] = [
        Stage::Filter,
        Stage::Bucket,
        Stage::Reconstruct,
        Stage::Associate,
        Stage::Solve,
        Stage::Update,
    ];

    /// A short lower-case name.
    pub const fn name(self) -> &'static str {
        match self {
            Stage::Filter => "filter",
            Stage::Bucket => "bucket",
            Stage::Reconstruct => "reconstruct",
            Stage::Associate => "associate",
            Stage::Solve => "solve",
            Stage::Update => "update",
            Stage::Done => "done",
        }
    }
}

/// Told when a scan enters each stage.
pub trait Probe {
    /// The scan now enters `stage` (the previous one, if any, has ended).
    fn enter(&mut self, stage: Stage);
}

/// A probe that does nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoProbe;

impl Probe for NoProbe {
    fn enter(&mut self, _stage: Stage) {}
}
