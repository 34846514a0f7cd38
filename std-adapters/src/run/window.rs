//! Sliding-window map eviction for long runs on small computers.
//!
//! After each scan, cells leave the map when they were not seen for `max_age_frames` frames,
//! when their centre is farther than `radius_m` from the sensor, or, oldest first, when the map
//! holds more layers than a memory cap allows. Evicted layers can be shown to a callback first
//! (the run appends them to the output mesh), so nothing is lost.
//!
//! The memory cap ([`Window::max_layers`]) becomes a layer budget: the map is kept at most at
//! that many layers after each scan, and the pipeline is built with a map for the budget and
//! one scan's worth of new layers more ([`Window::map_layers`],
//! [`Pipeline::with_map_layers`](slamesh_core::Pipeline::with_map_layers)), so that the map
//! never holds more than the cap allows, even in the middle of a scan. What counts against the
//! cap: the scan buffers of the capacity class in full (a scan may fill them), the map's hash
//! table and layer pool for that many layers ([`Capacity::memory_bytes_with_map_layers`]), the
//! look-ahead's filter buffers when the next frame is filtered ahead ([`LookAhead::bytes`];
//! a cap too tight for them has the next frame read ahead but filtered in line), and the rest
//! of the process as the caller measures it. This is the formula of the least cap
//! ([`Window::least_cap_bytes`]), written once here; docs/journal.md measures its parts.

use crate::formats::map_file::MapWriter;
use crate::io::error::FileError;
use crate::loop_closure::streaming;
use crate::outputs::mesh_spool::MeshSpool;
use crate::run::lookahead::LookAhead;
use crate::run::memory;
use slamesh_core::cell::{Axis, CellKey};
use slamesh_core::layer::Layer;
use slamesh_core::map::{LayerRef, MeshMap};
use slamesh_core::{Capacity, Pose};

/// When cells leave the map.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Window {
    /// Evict cells not seen for more than this many frames.
    pub max_age_frames: Option<u32>,
    /// Evict cells whose centre is farther than this from the sensor (metres).
    pub radius_m: Option<f64>,
    /// Evict the oldest cells while the map holds more than this many layers.
    pub max_layers: Option<usize>,
}

/// Why a memory cap cannot be met.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CapTooSmall {
    /// The smallest cap (bytes) that leaves room for the map.
    pub needed_bytes: usize,
}

impl Window {
    /// The layer budget under a memory cap of `cap_bytes`, of which `other_bytes` go to the
    /// rest of the process (code, IO buffers, threads): the most layers the map may keep
    /// between scans with a pipeline of [`map_layers`](Self::map_layers) within the cap. At
    /// least one scan's worth (a smaller cap is refused with the bytes it needs), at most the
    /// capacity's. `filter_ahead`: the look-ahead's filter buffers count too;
    /// `loop_closure`: so does what loop closure's thread holds ([`loop_closure_bytes`]).
    pub fn max_layers<C: Capacity>(
        cap_bytes: usize,
        other_bytes: usize,
        filter_ahead: bool,
        loop_closure: bool,
    ) -> Result<usize, CapTooSmall> {
        let needed =
            |budget: usize| Self::run_bytes::<C>(budget, filter_ahead, loop_closure) + other_bytes;
        let (mut lo, mut hi) = (Self::least_budget::<C>(), C::MAP_LAYERS);
        if cap_bytes < needed(lo) {
            return Err(CapTooSmall {
                needed_bytes: needed(lo),
            });
        }
        // The largest budget that fits: `needed` grows with the budget.
        while lo < hi {
            let mid = lo + (hi - lo).div_ceil(2);
            if needed(mid) <= cap_bytes {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        Ok(lo)
    }

    /// The least memory cap for capacity `C` when `other_bytes` go to the rest of the
    /// process: the budget of one scan's layers (`filter_ahead`: with the look-ahead's filter).
    pub fn least_cap_bytes<C: Capacity>(other_bytes: usize, filter_ahead: bool) -> usize {
        Self::run_bytes::<C>(Self::least_budget::<C>(), filter_ahead, false) + other_bytes
    }

    /// [`least_cap_bytes`](Self::least_cap_bytes) with loop closure's thread
    /// ([`loop_closure_bytes`]), the next frame filtered in line.
    pub fn least_cap_bytes_closing<C: Capacity>(other_bytes: usize) -> usize {
        Self::run_bytes::<C>(Self::least_budget::<C>(), false, true) + other_bytes
    }

    /// The run's own bytes for a layer budget of `budget`: the pipeline's for a map of
    /// [`map_layers`](Self::map_layers), the look-ahead's filter when `filter_ahead`, and
    /// loop closure's thread when `loop_closure`.
    fn run_bytes<C: Capacity>(budget: usize, filter_ahead: bool, loop_closure: bool) -> usize {
        Self::shares::<C>(budget, filter_ahead, loop_closure)
            .iter()
            .map(|s| s.1)
            .sum()
    }

    /// The run's own bytes for a layer budget of `budget`, share by share: the pipeline with
    /// its map of [`map_layers`](Self::map_layers) (`"map"`), the look-ahead's filter
    /// (`"filter ahead"`, when `filter_ahead`) and loop closure's thread (`"loop closure"`,
    /// when `loop_closure`); a share that is off holds nothing.
    pub fn shares<C: Capacity>(
        budget: usize,
        filter_ahead: bool,
        loop_closure: bool,
    ) -> [(&'static str, usize); 3] {
        let map_layers = Self::map_layers::<C>(budget);
        let ahead = match filter_ahead {
            true => LookAhead::bytes::<C>(),
            false => 0,
        };
        let closing = match loop_closure {
            true => loop_closure_bytes::<C>(map_layers),
            false => 0,
        };
        [
            ("map", C::memory_bytes_with_map_layers(map_layers)),
            ("filter ahead", ahead),
            ("loop closure", closing),
        ]
    }

    /// The least layer budget: one scan's worth (a map that cannot hold what one scan sees
    /// cannot register the next), at most the capacity's.
    fn least_budget<C: Capacity>() -> usize {
        C::SCAN_LAYERS.min(C::MAP_LAYERS)
    }

    /// The layers a pipeline's map needs for a layer budget of `budget`: the budget and one
    /// scan's worth of new layers, at most the capacity's.
    pub fn map_layers<C: Capacity>(budget: usize) -> usize {
        budget.saturating_add(C::SCAN_LAYERS).min(C::MAP_LAYERS)
    }

    /// True if no rule is set.
    pub fn is_off(&self) -> bool {
        self.max_age_frames.is_none() && self.radius_m.is_none() && self.max_layers.is_none()
    }

    /// [`evict`](Self::evict), adding what leaves to `spool` (when given) as one welded set
    /// (docs/design.md §1.10), and to the map file being written (when given).
    pub fn evict_to(
        &self,
        map: &mut MeshMap,
        frame: u32,
        sensor: &Pose,
        spool: Option<&mut MeshSpool>,
        saved_map: Option<&mut MapWriter>,
    ) -> Result<usize, FileError> {
        if spool.is_none() && saved_map.is_none() {
            return Ok(self.evict(map, frame, sensor, |_| {}));
        }
        let mut evicted: Vec<(CellKey, Axis, Layer, u32)> = Vec::new();
        let n = self.evict(map, frame, sensor, |l| {
            evicted.push((l.key, l.axis, *l.layer, l.last_seen))
        });
        let layers = || {
            evicted
                .iter()
                .map(|(key, axis, layer, last_seen)| LayerRef {
                    key: *key,
                    axis: *axis,
                    layer,
                    last_seen: *last_seen,
                })
        };
        if let Some(spool) = spool {
            spool.add_layers(layers())?;
        }
        if let Some(saved) = saved_map {
            saved.add_layers(layers())?;
        }
        Ok(n)
    }

    /// Applies the rules after scan `frame` seen from `sensor`; shows each evicted layer to
    /// `on_evicted` first. Returns the number of cells evicted.
    pub fn evict(
        &self,
        map: &mut MeshMap,
        frame: u32,
        sensor: &Pose,
        mut on_evicted: impl FnMut(LayerRef<'_>),
    ) -> usize {
        if crate::mutants::on("window-never-evicts") {
            return 0;
        }
        let cell_size = map.lattice().cell_size;
        let centre = sensor.translation.vector;
        let far = |key: &CellKey| {
            self.radius_m.is_some_and(|r| {
                let c = key.centre(cell_size);
                (c - centre).norm() > r
            })
        };
        let old = |seen: u32| {
            self.max_age_frames
                .is_some_and(|a| frame.saturating_sub(seen) > a)
        };
        let mut evicted = 0;
        if self.max_age_frames.is_some() || self.radius_m.is_some() {
            evicted += map.evict_where(|k, c| old(c.last_seen) || far(k), &mut on_evicted);
        }
        if let Some(budget) = self.max_layers {
            if map.layer_count() > budget {
                let cutoff = oldest_cutoff(map, budget);
                evicted += map.evict_where(|_, c| c.last_seen <= cutoff, &mut on_evicted);
            }
        }
        evicted
    }
}

/// What loop closure's thread holds under a memory cap beside its spool on disk, for a run
/// whose map holds `map_layers` layers: its pipeline with half the scan buffers and a map the
/// size of the run's (`streaming::engine_bytes`), and the weld of a set of what leaves the
/// rebuilt map's window ([`memory::CLOSING_SET_LAYERS`]), which may run while the run welds
/// its own. Its poses (about 200 bytes a frame) come out of the process's headroom.
pub fn loop_closure_bytes<C: Capacity>(map_layers: usize) -> usize {
    streaming::engine_bytes::<C>(map_layers)
        + memory::CLOSING_SET_LAYERS * memory::WELD_BYTES_PER_LAYER
}

/// The largest `last_seen` such that evicting every cell seen at or before it leaves at most
/// `budget` layers.
fn oldest_cutoff(map: &MeshMap, budget: usize) -> u32 {
    let mut by_age: Vec<(u32, usize)> = map
        .cells()
        .map(|(_, c)| (c.last_seen, c.axes().count()))
        .collect();
    by_age.sort_unstable_by_key(|a| std::cmp::Reverse(a.0));
    let mut kept = 0;
    for &(seen, layers) in &by_age {
        kept += layers;
        if kept > budget {
            // Keep only cells seen after `seen` (ties go too).
            return seen;
        }
    }
    0
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamesh_core::cell::Axis;
    use slamesh_core::facing::Facing;
    use slamesh_core::lattice::{Lattice, VERTICES};
    use slamesh_core::layer::Layer;
    use slamesh_core::{KittiCapacity, SmallCapacity};

    /// Cells 0..10 along x (1 m apart), cell i seen at frame i, one layer each.
    fn map() -> MeshMap {
        let lattice = Lattice {
            cell_size: 1.0,
            full_cover: true,
        };
        let mut m = MeshMap::with_capacity(16, 16, lattice);
        let layer = Layer {
            pred: [0.5; VERTICES],
            var: [0.01; VERTICES],
            facing: Facing::Unknown,
        };
        for i in 0..10 {
            m.insert_layer(CellKey::new(i, 0, 0), Axis::Z, layer, i as u32)
                .unwrap();
        }
        m
    }

    fn xs(m: &MeshMap) -> Vec<i32> {
        let mut v: Vec<i32> = m.cells().map(|(k, _)| k.get(Axis::X)).collect();
        v.sort();
        v
    }

    #[test]
    fn each_rule_evicts_what_it_says_and_shows_the_layers_first() {
        let at = |x: f64| slamesh_core::Pose::translation(x, 0.5, 0.5);
        let mut m = map();
        let mut shown = 0;
        let w = Window {
            max_age_frames: Some(3),
            ..Window::default()
        };
        assert_eq!(w.evict(&mut m, 9, &at(9.5), |_| shown += 1), 6);
        assert_eq!((xs(&m), shown), (vec![6, 7, 8, 9], 6));

        let mut m = map();
        let w = Window {
            radius_m: Some(2.5),
            ..Window::default()
        };
        w.evict(&mut m, 9, &at(4.5), |_| {});
        assert_eq!(xs(&m), vec![2, 3, 4, 5, 6]);

        let mut m = map();
        let w = Window {
            max_layers: Some(4),
            ..Window::default()
        };
        w.evict(&mut m, 9, &at(0.0), |_| {});
        assert_eq!(xs(&m), vec![6, 7, 8, 9]);
        assert_eq!(m.layer_count(), 4);
        assert!(Window::default().is_off());
    }

    #[test]
    fn the_layer_budget_follows_the_cap() {
        type K = KittiCapacity;
        let scan = K::SCAN_LAYERS;
        // The pipeline with a map for the budget and one scan more, and the look-ahead.
        let bytes = |budget: usize| {
            K::memory_bytes_with_map_layers(budget + scan) + LookAhead::bytes::<K>()
        };
        let e = Window::max_layers::<K>(K::scan_bytes(), 0, true, false).unwrap_err();
        assert_eq!(e.needed_bytes, bytes(scan), "one scan's worth is the least");
        // The map is sized for the budget: under a third of the capacity's bound.
        assert!(e.needed_bytes < K::memory_bytes() / 3);
        let cap = bytes(scan + 10_000) + 7;
        let n = Window::max_layers::<K>(cap, 7, true, false).unwrap();
        assert_eq!(
            n,
            scan + 10_000,
            "7 bytes for the rest, and the budget fits exactly"
        );
        let n = Window::max_layers::<K>(cap, 8, true, false).unwrap();
        assert!(bytes(n) + 8 <= cap && bytes(n + 1) + 8 > cap, "{n}");
        // Reading ahead only: the look-ahead's filter is room for more layers (each with its
        // share of the hash table too: its packed cell and slots).
        let more = Window::max_layers::<K>(cap, 8, false, false).unwrap();
        let freed = LookAhead::bytes::<K>() / slamesh_core::capacity::MAP_LAYER_BYTES;
        assert!(
            more > n + freed * 8 / 10 && more <= n + freed,
            "{n} then {more}"
        );
        assert_eq!(
            Window::least_cap_bytes::<K>(0, false),
            Window::least_cap_bytes::<K>(0, true) - LookAhead::bytes::<K>()
        );
        let all = Window::max_layers::<SmallCapacity>(usize::MAX / 2, 0, true, false).unwrap();
        assert_eq!(all, SmallCapacity::MAP_LAYERS);
        assert_eq!(Window::map_layers::<SmallCapacity>(all), all);
    }
}
