//! Real packet captures (tests/fixtures/packets, with their sources in its README): decoded
//! by our decoders, point for point against an independent decoder's output; read the same
//! from pcap and pcapng.

use slamesh::io::capture::Capture;
use slamesh::io::velodyne::{self, Decoder};
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/fixtures/packets")
        .join(name)
}

/// Every point of every Velodyne data packet in the capture, with its time.
fn decode_capture(path: &Path) -> Vec<([f32; 3], f64)> {
    let mut cap = Capture::open(path).unwrap();
    let mut out = Vec::new();
    let mut decoder: Option<Decoder> = None;
    while let Some(d) = cap.next_datagram().unwrap() {
        let Some(product) = velodyne::sniff(d.udp.payload) else {
            continue;
        };
        let dec = decoder.get_or_insert_with(|| Decoder::new(velodyne::model_of(product).unwrap()));
        let t = velodyne::packet_time(d.udp.payload, d.time_s).unwrap();
        dec.decode(d.udp.payload, t, |f| out.push((f.point, f.time_s)))
            .unwrap();
    }
    out
}

/// The reference file's points (see the fixtures' make.py).
fn reference(name: &str) -> Vec<([f32; 3], f64)> {
    let bytes = std::fs::read(fixture(name)).unwrap();
    bytes
        .chunks_exact(20)
        .map(|c| {
            let f = |k: usize| f32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap());
            (
                [f(0), f(1), f(2)],
                f64::from_le_bytes(c[12..20].try_into().unwrap()),
            )
        })
        .collect()
}

#[test]
fn hdl32e_packets_decode_to_the_independent_decoders_points() {
    let ours = decode_capture(&fixture("hdl32e-street.pcap"));
    let theirs = reference("hdl32e-street.points");
    assert_eq!(ours.len(), theirs.len(), "as many points");
    let (mut worst_m, mut worst_s) = (0.0f64, 0.0f64);
    for (k, ((p, t), (q, u))) in ours.iter().zip(&theirs).enumerate() {
        let d = (0..3)
            .map(|i| f64::from(p[i] - q[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        worst_m = worst_m.max(d);
        worst_s = worst_s.max((t - u).abs());
        assert!(d < 1e-3, "point {k}: {p:?} against {q:?}");
        assert!((t - u).abs() < 1e-6, "point {k}: time {t} against {u}");
    }
    println!(
        "{} points; worst {:.3} mm, {:.3} us",
        ours.len(),
        worst_m * 1e3,
        worst_s * 1e6
    );
}

#[test]
fn pcap_and_pcapng_give_the_same_points() {
    let a = decode_capture(&fixture("hdl32e-street.pcap"));
    let b = decode_capture(&fixture("hdl32e-street.pcapng"));
    assert!(!a.is_empty());
    assert_eq!(a, b);
}
