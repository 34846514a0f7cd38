//! The KITTI `.bin` reader on arbitrary bytes: a result or a `FileError`, never a panic; a
//! result has one point per whole 16-byte record.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    match slamesh::formats::kitti::parse_bin(Path::new("fuzz.bin"), data) {
        Ok(points) => assert_eq!(points.len() * 16, data.len()),
        Err(e) => assert!(!e.reason.is_empty()),
    }
});
