//! The readers on files made by an independent encoder (`tests/fixtures/pcd/make.py`): a PCL
//! `binary_compressed` PCD whose LZF stream has back-references, and an ASCII PCD with extra
//! fields and a field of COUNT 3 before `x`. Both must decode to the points the script wrote
//! (`expected.txt`), exactly: they are multiples of 1/8.

use slamesh::formats::pcd::read_pcd;
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/fixtures/pcd")
        .join(name)
}

fn expected() -> Vec<[f32; 3]> {
    std::fs::read_to_string(fixture("expected.txt"))
        .unwrap()
        .lines()
        .map(|l| {
            let v: Vec<f32> = l.split_whitespace().map(|w| w.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}

#[test]
fn a_pcl_style_compressed_pcd_with_back_references_decodes_exactly() {
    let want = expected();
    assert_eq!(want.len(), 168);
    let got = read_pcd(&fixture("compressed_backrefs.pcd")).unwrap();
    assert_eq!(got, want);
}

#[test]
fn an_ascii_pcd_with_extra_fields_and_a_count_of_three_decodes_exactly() {
    let got = read_pcd(&fixture("ascii_extra_fields.pcd")).unwrap();
    assert_eq!(got, expected());
}

#[test]
fn a_corrupt_back_reference_is_an_error_naming_the_file() {
    let mut bytes = std::fs::read(fixture("compressed_backrefs.pcd")).unwrap();
    // The first control byte of the LZF stream, just after the two sizes, becomes a
    // back-reference reaching before the start of the output.
    let data = bytes
        .windows(22)
        .position(|w| w == b"DATA binary_compressed")
        .unwrap()
        + 23;
    bytes[data + 8] = 0xff;
    let dir = crate::common::scratch("readers");
    let path = dir.join("corrupt.pcd");
    std::fs::write(&path, &bytes).unwrap();
    let e = read_pcd(&path).unwrap_err().to_string();
    assert!(e.contains("corrupt.pcd"), "{e}");
}
