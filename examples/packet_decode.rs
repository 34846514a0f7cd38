//! What decoding a packet capture costs, in two parts timed apart over `--repeat` passes
//! (medians): reading the capture from memory (its container and network layers, the sensor's
//! packets kept), and decoding those packets to points with their times, cut into sweeps
//! (reported per sweep and per point). Any sensor the command reads: a Velodyne told from its
//! packets, an HDL-64E with its calibration (`--calibration`, `--sensor hdl64e-s2|hdl64e-s3`), an
//! Ouster by its metadata (`--metadata`, or the capture's name with `.json`).
//!
//! `cargo run --release --example packet_decode -- --capture FILE [--metadata JSON]
//! [--calibration YAML --sensor hdl64e-s2|hdl64e-s3] [--repeat N]`

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::sources::capture::Capture;
use slamesh::sources::packets::{identify, PacketOptions, Sensor, SensorHint, SensorStream};
use std::io::Cursor;
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let path = flags
        .value("--capture")
        .ok_or("--capture FILE is required")?
        .to_string();
    let options = PacketOptions {
        metadata: flags.value("--metadata").map(Into::into),
        calibration: flags.value("--calibration").map(Into::into),
        sensor: flags.value("--sensor").map(Into::into),
        ..PacketOptions::default()
    };
    let repeat: usize = flags.parse_or("--repeat", 20)?;
    let bytes = std::fs::read(&path)?;
    let hint = SensorHint::new(&options, Some(Path::new(&path)))?;
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    // Reading the capture: container and network layers, the sensor's packets kept.
    let mut sensor: Option<(Sensor, u16)> = None;
    let mut packets: Vec<(f64, Vec<u8>)> = Vec::new();
    let mut reads = Vec::new();
    for _ in 0..repeat {
        let t = Instant::now();
        let mut cap = Capture::from_reader(Path::new(&path), Cursor::new(bytes.clone()))?;
        packets.clear();
        while let Some(d) = cap.next_datagram()? {
            if sensor.is_none() {
                sensor = identify(d.udp.payload, &hint)?.map(|s| (s, d.udp.dst_port));
            }
            if sensor
                .as_ref()
                .is_some_and(|(_, port)| *port == d.udp.dst_port)
            {
                packets.push((d.time_s, d.udp.payload.to_vec()));
            }
        }
        reads.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let (sensor, port) = sensor.ok_or("no data packets of a sensor this reader decodes")?;
    // Decoding: packets to points with their times, cut into sweeps.
    let (mut decodes, mut sweeps_done, mut points) = (Vec::new(), 0, 0);
    for _ in 0..repeat {
        let t = Instant::now();
        let mut stream = SensorStream::new(&sensor, port, None);
        let (mut n_sweeps, mut n_points) = (0, 0);
        for (time, p) in &packets {
            if let Some(s) = stream.datagram(port, p, *time) {
                n_sweeps += 1;
                n_points += s.points.len();
            }
        }
        if let Some(s) = stream.finish() {
            n_sweeps += 1;
            n_points += s.points.len();
        }
        n_points += stream.stats().partial_firings as usize;
        decodes.push(t.elapsed().as_secs_f64() * 1e3);
        (sweeps_done, points) = (n_sweeps, n_points);
    }
    let (read, decode) = (median(reads), median(decodes));
    let per_point_us = decode * 1e3 / points.max(1) as f64;
    println!(
        "{path}: {}, {} packets, {points} points, {sweeps_done} whole sweeps; medians of {repeat} \
         passes: reading {read:.2} ms, decoding {decode:.2} ms ({:.3} ms a sweep of its points, \
         {per_point_us:.4} us a point; a 64-beam sweep of 130 000 points at that rate: {:.2} ms)",
        sensor.name(),
        packets.len(),
        decode / sweeps_done.max(1) as f64,
        per_point_us * 130_000.0 / 1e3
    );
    Ok(())
}
