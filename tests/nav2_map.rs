//! Nav2's occupancy grid as `map_server` reads it, with a reader of the tests' own: the
//! YAML's keys and the PGM's header and bytes (`map.yaml` + `map.pgm`, trinary), or the live
//! grid's cells as a trinary image would hold them.

use slamesh::navmap::live::{Cells, FREE, OCCUPIED};
use std::path::Path;

/// A Nav2 map as `map_server` reads it: its pixels (rows top-down), size, resolution and the
/// lower-left pixel's corner.
pub(crate) struct Nav2Map {
    pub(crate) pixels: Vec<u8>,
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) resolution: f64,
    pub(crate) origin: [f64; 2],
    pub(crate) free_thresh: f64,
}

impl Nav2Map {
    pub(crate) fn read(dir: &Path) -> Nav2Map {
        let yaml = std::fs::read_to_string(dir.join("map.yaml")).unwrap();
        let key = |k: &str| {
            yaml.lines()
                .find_map(|l| l.strip_prefix(&format!("{k}: ")))
                .unwrap_or_else(|| panic!("map.yaml has no {k}"))
                .to_string()
        };
        assert_eq!(key("image"), "map.pgm");
        assert_eq!(key("mode"), "trinary");
        assert_eq!(key("negate"), "0");
        let origin: Vec<f64> = key("origin")
            .trim_matches(|c| c == '[' || c == ']')
            .split(',')
            .map(|v| v.trim().parse().unwrap())
            .collect();
        let pgm = std::fs::read(dir.join("map.pgm")).unwrap();
        // P5, a comment, width height, 255, then the bytes.
        let mut fields = Vec::new();
        let mut at = 0;
        while fields.len() < 4 {
            while pgm[at].is_ascii_whitespace() {
                at += 1;
            }
            if pgm[at] == b'#' {
                while pgm[at] != b'\n' {
                    at += 1;
                }
                continue;
            }
            let start = at;
            while !pgm[at].is_ascii_whitespace() {
                at += 1;
            }
            fields.push(String::from_utf8(pgm[start..at].to_vec()).unwrap());
        }
        assert_eq!((fields[0].as_str(), fields[3].as_str()), ("P5", "255"));
        let (width, height) = (fields[1].parse().unwrap(), fields[2].parse().unwrap());
        let pixels = pgm[at + 1..].to_vec();
        assert_eq!(pixels.len(), width * height);
        Nav2Map {
            pixels,
            width,
            height,
            resolution: key("resolution").parse().unwrap(),
            origin: [origin[0], origin[1]],
            free_thresh: key("free_thresh").parse().unwrap(),
        }
    }

    /// map_server's reading of pixel `(col, row)`: 100 occupied, 0 free, -1 unknown.
    pub(crate) fn value(&self, col: usize, row: usize) -> i8 {
        let occ = (255.0 - self.pixels[row * self.width + col] as f64) / 255.0;
        if occ > 0.65 {
            100
        } else if occ < self.free_thresh {
            0
        } else {
            -1
        }
    }

    /// The live grid's `cells` (of `resolution` metres) as `map_server` would read them from
    /// a trinary image.
    pub(crate) fn of_live(cells: &Cells, resolution: f64) -> Nav2Map {
        let pixel = |v: i8| match v {
            FREE => 254,
            OCCUPIED => 0,
            _ => 205,
        };
        let rows = cells.data.chunks(cells.width).rev();
        Nav2Map {
            pixels: rows.flat_map(|r| r.iter().map(|v| pixel(*v))).collect(),
            width: cells.width,
            height: cells.height,
            resolution,
            origin: [cells.origin.0, cells.origin.1].map(|i| i as f64 * resolution),
            free_thresh: 0.19,
        }
    }

    /// The centre of pixel `(col, row)` in the grid's frame.
    pub(crate) fn centre(&self, col: usize, row: usize) -> [f64; 2] {
        [
            self.origin[0] + (col as f64 + 0.5) * self.resolution,
            self.origin[1] + ((self.height - 1 - row) as f64 + 0.5) * self.resolution,
        ]
    }
}
