//! A memory cap split into the shares it was given to: the process as it stood when the run
//! started (with its headroom), the map, the look-ahead's filter and loop closure's thread
//! ([`Window::shares`]), and what is left. Made once, when the cap becomes a layer budget; said
//! at the start, and written in `report.json` beside the peak the kernel counted (`VmHWM`), so
//! a run under a cap shows where its memory was meant to go and whether it stayed there.

use crate::run::memory;
use crate::run::window::Window;
use serde::{Deserialize, Serialize};
use slamesh_core::Capacity;

/// One share of the cap.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Share {
    /// What it is for: `process`, `map`, `filter ahead`, `loop closure`, `unassigned`.
    pub name: String,
    /// Megabytes (10^6) it may hold.
    pub allowed_mb: f64,
}

/// The cap and its shares; their sum is the cap.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MemoryBudget {
    /// The cap, megabytes.
    pub cap_mb: f64,
    /// The map's layer budget.
    pub layers: usize,
    /// Shares in the order they are taken; `unassigned` last.
    pub shares: Vec<Share>,
    /// The process's peak resident memory at the end of the run, megabytes (set then).
    pub peak_mb: Option<f64>,
}

impl MemoryBudget {
    /// The shares of a cap of `cap_bytes` whose `other_bytes` go to the rest of the process,
    /// for a layer budget of `layers` with the filter ahead and loop closure on or off.
    pub fn of<C: Capacity>(
        cap_bytes: usize,
        other_bytes: usize,
        layers: usize,
        (filter_ahead, closing): (bool, bool),
    ) -> Self {
        let mut shares = vec![("process", other_bytes)];
        shares.extend(
            Window::shares::<C>(layers, filter_ahead, closing)
                .into_iter()
                .filter(|s| s.1 > 0),
        );
        let taken: usize = shares.iter().map(|s| s.1).sum();
        shares.push(("unassigned", cap_bytes.saturating_sub(taken)));
        MemoryBudget {
            cap_mb: memory::mb(cap_bytes as u64),
            layers,
            shares: shares
                .into_iter()
                .map(|(name, bytes)| Share {
                    name: name.to_string(),
                    allowed_mb: memory::mb(bytes as u64),
                })
                .collect(),
            peak_mb: None,
        }
    }

    /// One line: `memory cap 64 MB: process 13.2, map (15 910 layers) 31.0, ... MB`.
    pub fn describe(&self) -> String {
        let shares: Vec<String> = self
            .shares
            .iter()
            .map(|s| match s.name.as_str() {
                "map" => format!("map ({} layers) {:.1}", self.layers, s.allowed_mb),
                name => format!("{name} {:.1}", s.allowed_mb),
            })
            .collect();
        format!("memory cap {} MB: {} MB", self.cap_mb, shares.join(", "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamesh_core::KittiCapacity;

    #[test]
    fn the_shares_add_up_to_the_cap_and_off_ones_are_left_out() {
        let other = 20_000_000;
        let cap = 120_000_000;
        let layers = 2_000;
        let with = MemoryBudget::of::<KittiCapacity>(cap, other, layers, (true, true));
        let names: Vec<&str> = with.shares.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "process",
                "map",
                "filter ahead",
                "loop closure",
                "unassigned"
            ]
        );
        let sum: f64 = with.shares.iter().map(|s| s.allowed_mb).sum();
        assert!((sum - 120.0).abs() < 1e-6, "{with:?}");
        let run = Window::least_cap_bytes::<KittiCapacity>(other, true);
        assert!(run > other, "the map and the filter take some of it");
        let without = MemoryBudget::of::<KittiCapacity>(cap, other, layers, (false, false));
        let names: Vec<&str> = without.shares.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["process", "map", "unassigned"]);
        assert!(without
            .describe()
            .starts_with("memory cap 120 MB: process 20.0, map (2000"));
    }
}
