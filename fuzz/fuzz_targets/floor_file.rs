//! The floor file reader (the scans' floor beside a saved map) on arbitrary bytes: checked
//! whole before anything is handed on; what it hands on is as many finite floors as it said.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::navmap::floor_file::FloorFile;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(file) = FloorFile::parse(Path::new("fuzz.floor"), data.to_vec()) else {
        return;
    };
    let mut n = 0;
    file.each(&mut |f| {
        assert!(f.at.iter().all(|v| v.is_finite()));
        n += 1;
    });
    assert_eq!(n, file.count);
    assert!(file.resolution > 0.0);
});
