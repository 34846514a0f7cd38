//! The Velodyne decoders on arbitrary packets, for every model and the HDL-64E with a real
//! unit's calibration: a packet is refused whole or decoded to at most 384 finite points (768
//! for an HDL-64E in dual mode), each within the range a raw distance can give.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::sources::velodyne::calibration::Calibration;
use slamesh::sources::velodyne::hdl64::{self, Generation, Hdl64};
use slamesh::sources::velodyne::{tables::MODELS, Decoder};
use std::sync::OnceLock;

/// The fixtures' HDL-64E calibration, read once.
fn hdl64e() -> &'static Hdl64 {
    static DECODER: OnceLock<Hdl64> = OnceLock::new();
    DECODER.get_or_init(|| {
        let text = include_str!("../../tests/fixtures/packets/hdl64e-s2.1-sztaki.yml");
        Hdl64::new(Generation::S2, &Calibration::parse(text).unwrap()).unwrap()
    })
}

fuzz_target!(|data: &[u8]| {
    for model in &MODELS {
        let dec = Decoder::new(model);
        let mut n = 0;
        let r = dec.decode(data, 0.0, |f| {
            n += 1;
            let r = f.point.iter().map(|v| f64::from(*v).powi(2)).sum::<f64>().sqrt();
            assert!(f.point.iter().all(|v| v.is_finite()) && r < 300.0, "{f:?}");
            assert!(f.azimuth < 36_000);
        });
        if r.is_err() {
            assert_eq!(n, 0, "a refused packet gave no point");
        }
        assert!(n <= 12 * 32, "{n} points");
    }
    let _ = hdl64::sniff(data);
    let mut n = 0;
    let r = hdl64e().decode(data, 0.0, |f| {
        n += 1;
        let r = f.point.iter().map(|v| f64::from(*v).powi(2)).sum::<f64>().sqrt();
        assert!(f.point.iter().all(|v| v.is_finite()) && r < 300.0, "{f:?}");
        assert!(f.azimuth < 36_000 && f.laser < 64);
    });
    if r.is_err() {
        assert_eq!(n, 0, "a refused packet gave no point");
    }
    assert!(n <= 2 * 6 * 64, "{n} points");
});
