//! The Velodyne decoder on arbitrary packets, for every model: a packet is refused whole or
//! decoded to at most 384 finite points, each within the range a raw distance can give.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::io::velodyne::{tables::MODELS, Decoder};

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
});
