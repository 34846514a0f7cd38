//! `mesh`: the map's shown triangles as RViz markers, one `TRIANGLE_LIST` marker a tile of
//! [`TILE_CELLS`]³ cells (namespace `mesh`, id from the tile's key): only the tiles whose
//! layers changed are sent again, and a marker replaces the tile's last one.
//!
//! Paced: a frame sends at most [`FRAME_POINTS`] points, in messages of at most about
//! [`MESSAGE_POINTS`]; changed tiles wait their turn in the order they first changed, each
//! sent with its latest triangles (a tile that changes again while it waits is sent once). A
//! 64-beam scan changes more of the mesh than that, so the mesh on the topic lags the map by
//! a few frames where the sensor looks, and the bursts stay small enough for a DDS reader's
//! socket (large bursts were lost, and the DDS writer's repair of large samples is slow).
//!
//! The triangles are [`TiledMesh`]'s (which the node's `map` reads too); this module owns the
//! queue of tiles to send (one entry a tile at most) and the markers.

use crate::navmap::tiled_mesh::{tile_of, TileKey, TiledMesh};
use crate::ros2::messages::{Colour, Header, Marker, MarkerArray, PoseMsg, Vector3};
use slamesh_core::cell::{Axis, CellKey};
use slamesh_core::lattice::LatticeTable;
use slamesh_core::layer::{Layer, Shown};
use std::collections::{BTreeSet, VecDeque};

pub use crate::navmap::tiled_mesh::TILE_CELLS;

/// Points in one message, at most, unless one tile has more (a tile's marker goes whole): about
/// 60 KB, one UDP datagram on loopback.
pub const MESSAGE_POINTS: usize = 2_500;

/// Points a frame sends, at most (about 720 KB): more when one tile alone has more.
pub const FRAME_POINTS: usize = 30_000;

/// The map's triangles by tile, and the tiles waiting to be sent.
pub struct MeshTiles {
    mesh: TiledMesh,
    /// Tiles to send, oldest change first, and the same as a set.
    waiting: VecDeque<TileKey>,
    queued: BTreeSet<TileKey>,
}

/// A marker id for a tile: its key's three coordinates folded into 31 bits (two tiles 1 024
/// tiles apart along an axis share one; a map that large has other limits first).
fn tile_id(t: (i32, i32, i32)) -> i32 {
    let b = |v: i32| (v.rem_euclid(1024)) as u32;
    ((b(t.0) << 20) | (b(t.1) << 10) | b(t.2)) as i32
}

impl MeshTiles {
    /// For the map's `lattice`, showing triangles as `shown` says.
    pub fn new(lattice: LatticeTable, shown: Shown) -> Self {
        MeshTiles {
            mesh: TiledMesh::new(lattice, shown),
            waiting: VecDeque::new(),
            queued: BTreeSet::new(),
        }
    }

    fn queue(&mut self, tile: TileKey) {
        if self.queued.insert(tile) {
            self.waiting.push_back(tile);
        }
    }

    /// Takes the layers a frame changed; their tiles wait to be sent.
    pub fn update<'a>(&mut self, layers: impl IntoIterator<Item = &'a (CellKey, Axis, Layer)>) {
        let layers: Vec<&(CellKey, Axis, Layer)> = layers.into_iter().collect();
        for (key, _, _) in &layers {
            self.queue(tile_of(key));
        }
        self.mesh.update(layers);
    }

    /// Forgets every tile's triangles (after a loop closure, whose update holds every layer):
    /// every tile is sent again, deleted if the update leaves it empty.
    pub fn clear(&mut self) {
        for t in self.mesh.clear() {
            self.queue(t);
        }
    }

    /// The triangles by tile.
    pub fn mesh(&self) -> &TiledMesh {
        &self.mesh
    }

    /// Tiles waiting to be sent.
    pub fn waiting(&self) -> usize {
        self.waiting.len()
    }

    /// Tiles whose message was not sent wait again, behind the others (a tile already waiting
    /// keeps its place).
    pub fn again(&mut self, tiles: &[TileKey]) {
        for &t in tiles {
            self.queue(t);
        }
    }

    /// The next waiting tiles' markers, `points` points at most (at least one tile), at
    /// `header`'s stamp and frame, in messages of about [`MESSAGE_POINTS`] points: each tile's
    /// triangles, or its deletion when it has none; each message with its tiles, for
    /// [`MeshTiles::again`] should it not go out.
    pub fn next_messages(
        &mut self,
        points: usize,
        header: &Header,
    ) -> Vec<(MarkerArray, Vec<TileKey>)> {
        let mut out: Vec<(MarkerArray, Vec<TileKey>)> = Vec::new();
        let (mut in_frame, mut in_message) = (0, 0);
        while let Some(&t) = self.waiting.front() {
            let n = self.points_of(t);
            if in_frame > 0 && in_frame + n > points {
                break;
            }
            self.waiting.pop_front();
            self.queued.remove(&t);
            let marker = self.marker(t, header);
            if out.is_empty() || in_message > 0 && in_message + n > MESSAGE_POINTS {
                out.push((MarkerArray::default(), Vec::new()));
                in_message = 0;
            }
            in_frame += n;
            in_message += n;
            let (message, tiles) = out.last_mut().expect("a message");
            message.markers.push(marker);
            tiles.push(t);
        }
        out
    }

    fn points_of(&self, t: TileKey) -> usize {
        self.mesh.points_of(t).count()
    }

    fn marker(&self, t: TileKey, header: &Header) -> Marker {
        {
            {
                let points: Vec<Vector3> = self
                    .mesh
                    .points_of(t)
                    .map(|&[x, y, z]| Vector3 { x, y, z })
                    .collect();
                Marker {
                    header: header.clone(),
                    ns: "mesh".into(),
                    id: tile_id(t),
                    kind: Marker::TRIANGLE_LIST,
                    action: if points.is_empty() {
                        Marker::DELETE
                    } else {
                        Marker::ADD
                    },
                    pose: PoseMsg::default(),
                    scale: Vector3 {
                        x: 1.0,
                        y: 1.0,
                        z: 1.0,
                    },
                    color: Colour {
                        r: 0.55,
                        g: 0.7,
                        b: 0.85,
                        a: 1.0,
                    },
                    points,
                    ..Marker::default()
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::flat_layer;

    fn tiles() -> MeshTiles {
        let config = slamesh_core::Config::default();
        MeshTiles::new(config.lattice().table(), Shown::new(&config.mesh))
    }

    fn header() -> Header {
        Header {
            frame_id: "map".into(),
            ..Header::default()
        }
    }

    #[test]
    fn changed_tiles_go_out_paced_once_each_and_emptied_ones_are_deleted() {
        let mut t = tiles();
        // Three tiles: two cells in tile (0, 0, 0), one in (1, 0, 0), one in (0, 2, 0).
        let layers: Vec<(CellKey, Axis, Layer)> = [(0, 0), (1, 0), (8, 0), (0, 16)]
            .iter()
            .map(|&(x, y)| (CellKey { x, y, z: 0 }, Axis::Z, flat_layer()))
            .collect();
        t.update(&layers);
        assert_eq!(t.waiting(), 3);
        let per_layer = t.mesh().triangles() / 4 * 3;
        assert!(per_layer > 0);
        // A budget of one layer's points: one tile a frame (the first whole, even if larger).
        let first = t.next_messages(per_layer, &header());
        assert_eq!(first.len(), 1);
        assert_eq!(first[0].0.markers.len(), 1);
        assert_eq!(first[0].0.markers[0].points.len(), 2 * per_layer);
        assert_eq!(first[0].1, [(0, 0, 0)]);
        // A tile changed again while it waits is still sent once, with its latest triangles.
        t.update(&layers[2..3]);
        let rest: Vec<Marker> = (0..4)
            .flat_map(|_| t.next_messages(per_layer, &header()))
            .flat_map(|m| m.0.markers)
            .collect();
        assert_eq!(rest.len(), 2);
        assert_eq!(t.waiting(), 0);
        assert!(rest
            .iter()
            .all(|m| m.action == Marker::ADD && m.header.frame_id == "map"));
        // A layer that shows nothing empties its tile: the tile's marker is deleted.
        t.update(&[(CellKey { x: 8, y: 0, z: 0 }, Axis::Z, Layer::UNKNOWN)]);
        let gone = t.next_messages(usize::MAX, &header());
        assert_eq!(gone[0].0.markers[0].action, Marker::DELETE);
        assert_eq!(gone[0].0.markers[0].id, tile_id((1, 0, 0)));
    }

    #[test]
    fn a_tile_whose_message_was_not_sent_waits_again_behind_the_others() {
        let mut t = tiles();
        let layers: Vec<(CellKey, Axis, Layer)> = [(0, 0), (8, 0), (0, 16)]
            .iter()
            .map(|&(x, y)| (CellKey { x, y, z: 0 }, Axis::Z, flat_layer()))
            .collect();
        t.update(&layers);
        let first = t.next_messages(1, &header());
        assert_eq!(first[0].1, [(0, 0, 0)]);
        t.again(&first[0].1);
        // One already waiting keeps its place (sent once).
        t.again(&[(1, 0, 0)]);
        assert_eq!(t.waiting(), 3);
        let order: Vec<TileKey> = (0..3)
            .flat_map(|_| t.next_messages(1, &header()))
            .flat_map(|m| m.1)
            .collect();
        assert_eq!(order, [(1, 0, 0), (0, 2, 0), (0, 0, 0)]);
    }

    #[test]
    fn tile_ids() {
        assert_ne!(tile_id((0, 0, 1)), tile_id((0, 1, 0)));
        assert!(tile_id((-1, -1, -1)) >= 0);
    }
}
