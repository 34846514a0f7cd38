//! What decoding a packet capture costs, in two parts timed apart over `--repeat` passes
//! (medians): reading the capture from memory (its container and network layers, the sensor's
//! packets kept), and decoding those packets to points with their times, cut into sweeps
//! (reported per sweep and per point).
//!
//! `cargo run --release --example packet_decode -- --capture FILE [--repeat N]`

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::io::capture::Capture;
use slamesh::io::sweep::Sweeps;
use slamesh::io::velodyne::{self, Decoder};
use std::io::Cursor;
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let path = flags
        .value("--capture")
        .ok_or("--capture FILE is required")?
        .to_string();
    let repeat: usize = flags.parse_or("--repeat", 20)?;
    let bytes = std::fs::read(&path)?;
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    // Reading the capture: container and network layers, the sensor's packets kept.
    let mut packets: Vec<(f64, Vec<u8>)> = Vec::new();
    let mut reads = Vec::new();
    for _ in 0..repeat {
        let t = Instant::now();
        let mut cap = Capture::from_reader(Path::new(&path), Cursor::new(bytes.clone()))?;
        packets.clear();
        while let Some(d) = cap.next_datagram()? {
            if velodyne::sniff(d.udp.payload).is_some() {
                packets.push((d.time_s, d.udp.payload.to_vec()));
            }
        }
        reads.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let product = packets
        .first()
        .and_then(|(_, p)| velodyne::sniff(p))
        .ok_or("no Velodyne data packets")?;
    let decoder = Decoder::new(velodyne::model_of(product).ok_or("a model not decoded")?);
    // Decoding: packets to points with their times, cut into sweeps.
    let (mut decodes, mut sweeps_done, mut points) = (Vec::new(), 0, 0);
    for _ in 0..repeat {
        let t = Instant::now();
        let mut sweeps = Sweeps::new(0.0);
        let (mut n_sweeps, mut n_points) = (0, 0);
        for (time, p) in &packets {
            let time = velodyne::packet_time(p, *time).unwrap_or(0.0);
            let _ = decoder.decode(p, time, |f| {
                n_points += 1;
                if sweeps.push(f.point, f.time_s, f.azimuth).is_some() {
                    n_sweeps += 1;
                }
            });
        }
        decodes.push(t.elapsed().as_secs_f64() * 1e3);
        (sweeps_done, points) = (n_sweeps, n_points);
    }
    let (read, decode) = (median(reads), median(decodes));
    let per_point_us = decode * 1e3 / points.max(1) as f64;
    println!(
        "{path}: {}, {} packets, {points} points, {sweeps_done} whole sweeps; medians of {repeat} \
         passes: reading {read:.2} ms, decoding {decode:.2} ms ({:.3} ms a sweep of its points, \
         {per_point_us:.4} us a point; a 64-beam sweep of 130 000 points at that rate: {:.2} ms)",
        decoder.model().name,
        packets.len(),
        decode / sweeps_done.max(1) as f64,
        per_point_us * 130_000.0 / 1e3
    );
    Ok(())
}
