//! The PCD reader (ascii, binary, binary_compressed with its LZF decoder) on arbitrary bytes:
//! points or a `FileError` naming the file, never a panic or an unbounded allocation.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.pcd");
    if let Err(e) = slamesh::formats::pcd::parse_pcd(path, data) {
        assert_eq!(e.path, path);
        assert!(!e.reason.is_empty());
    }
});
