//! The map file reader on arbitrary bytes: the header, trailer, index and path are checked
//! on opening, every tile block before it is loaded; whatever loads fits the map it went into.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::formats::map_file::MapFile;
use slamesh_core::map::MeshMap;
use std::io::Cursor;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(mut file) = MapFile::from_reader(Path::new("fuzz.slamesh"), Cursor::new(data)) else {
        return;
    };
    assert!(file.index.iter().all(|e| e.offset + u64::from(e.len) <= data.len() as u64));
    let mut map = MeshMap::with_capacity(256, 512, file.info.lattice);
    if let Ok(layers) = file.load_all(&mut map) {
        assert_eq!(layers >= map.layer_count(), true);
        assert!(map.cell_count() <= 256);
    }
});
