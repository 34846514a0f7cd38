//! Real packet captures (tests/fixtures/packets, with their sources in its README): decoded
//! by our decoders, point for point against an independent decoder's output; read the same
//! from pcap and pcapng.

use crate::common;

use slamesh::sources::capture::Capture;
use slamesh::sources::live::Live;
use slamesh::sources::packets::PacketOptions;
use slamesh::sources::replay::Replay;
use slamesh::sources::velodyne::{self, Decoder};
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/fixtures/packets")
        .join(name)
}

/// Every point of every Velodyne data packet in the capture, with its time, each packet
/// decoded as the model its product byte names.
fn decode_capture(path: &Path) -> Vec<([f32; 3], f64)> {
    let mut cap = Capture::open(path).unwrap();
    let mut out = Vec::new();
    let mut decoder: Option<Decoder> = None;
    while let Some(d) = cap.next_datagram().unwrap() {
        let Some(product) = velodyne::sniff(d.udp.payload) else {
            continue;
        };
        if decoder.as_ref().map(|d| d.model().product_id) != Some(product) {
            decoder = Some(Decoder::new(velodyne::model_of(product).unwrap()));
        }
        let dec = decoder.as_ref().unwrap();
        let t = velodyne::packet_time(d.udp.payload, d.time_s).unwrap();
        dec.decode(d.udp.payload, t, |f| out.push((f.point, f.time_s)))
            .unwrap();
    }
    out
}

/// The reference file's points (see the fixtures' make.py).
fn reference(name: &str) -> Vec<([f32; 3], f64)> {
    common::reference_points(&fixture(name))
}

#[test]
fn hdl32e_packets_decode_to_the_independent_decoders_points() {
    let ours = decode_capture(&fixture("hdl32e-street.pcap"));
    let theirs = reference("hdl32e-street.points");
    common::assert_same_points("hdl32e-street", &ours, &theirs);
}

#[test]
fn pcap_and_pcapng_give_the_same_points() {
    let a = decode_capture(&fixture("hdl32e-street.pcap"));
    let b = decode_capture(&fixture("hdl32e-street.pcapng"));
    assert!(!a.is_empty());
    assert_eq!(a, b);
}

use common::Frame;

/// A legacy pcap of Ethernet `frames`.
fn pcap(frames: &[Frame]) -> Vec<u8> {
    let mut out = Vec::new();
    for v in [0xa1b2_c3d4u32, 0x0004_0002, 0, 0, 65_535, 1] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for (f, orig, [sec, usec]) in frames {
        for v in [*sec, *usec, f.len() as u32, *orig] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(f);
    }
    out
}

#[test]
fn truncated_oversized_and_garbage_packets_are_skipped_and_counted() {
    let mut frames = common::capture_frames(&fixture("hdl32e-drive.pcap"));
    let data: Vec<usize> = (0..frames.len())
        .filter(|&k| frames[k].0.len() == 1248)
        .collect();
    // A data packet cut short by the capture, one whose blocks are garbage, one oversized
    // (its UDP length larger than the frame), and one dropped.
    let (cut, garbage, oversized, dropped) = (data[100], data[200], data[300], data[400]);
    frames[cut].0.truncate(600);
    for b in &mut frames[garbage].0[42 + 300..42 + 400] {
        *b = 0x5a;
    }
    frames[oversized].0[38..40].copy_from_slice(&2_000u16.to_be_bytes());
    frames.remove(dropped);
    let dir = common::scratch("packets-bad");
    let path = dir.join("bad.pcap");
    std::fs::write(&path, pcap(&frames)).unwrap();
    let replay = Replay::open(&path, &PacketOptions::default()).unwrap();
    let s = replay.stats();
    assert_eq!(
        s.capture.truncated, 2,
        "the cut frame and the oversized datagram"
    );
    assert_eq!(s.stream.bad_packets, 1, "the garbage blocks");
    // Four packets' points missing from the stream, each a gap: all but the good ones.
    assert_eq!(s.stream.gaps, 4);
    assert_eq!(replay.len(), 5, "every sweep is still there");
}

#[test]
fn a_capture_of_no_lidar_is_refused_with_what_it_holds() {
    let mut udp = vec![0u8; 42 + 100];
    udp[12..14].copy_from_slice(&[0x08, 0x00]);
    udp[14] = 0x45;
    udp[16..18].copy_from_slice(&128u16.to_be_bytes());
    udp[23] = 17;
    udp[38..40].copy_from_slice(&108u16.to_be_bytes());
    let dir = common::scratch("packets-none");
    let path = dir.join("dns.pcap");
    std::fs::write(&path, pcap(&[(udp.clone(), udp.len() as u32, [1, 0])])).unwrap();
    let e = Replay::open(&path, &PacketOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("no Velodyne data packets") && e.contains("1 of 100 bytes"),
        "{e}"
    );
    let e = Replay::open(
        &fixture("hdl32e-street.pcap"),
        &PacketOptions {
            sensor: Some("vlp16".into()),
            ..PacketOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("the packets are a HDL-32E's"), "{e}");
    std::fs::write(&path, b"not a capture at all").unwrap();
    assert!(Replay::open(&path, &PacketOptions::default()).is_err());
}

/// The capture of a car at about 15 m/s: the command runs it with --strict, a sweep a frame,
/// and every step is about the same length, as the car's speed is steady.
#[test]
fn a_replayed_capture_runs_end_to_end() {
    let out = common::scratch("packets-run");
    // Deskewing is off: the car is at speed from the first sweep, which cannot be deskewed
    // (no motion is known yet), and the third sweep, deskewed, then does not match the map of
    // the first two (docs/journal.md, "Packets").
    common::slamesh_run_ok(
        &fixture("hdl32e-drive.pcap"),
        &out,
        &["--strict", "--deskew", "off"],
    );
    let xyz = common::kitti_positions(&out.join("poses_kitti.txt"));
    assert_eq!(xyz.len(), 5, "five whole turns in the capture");
    for w in xyz.windows(2) {
        let step = (0..3)
            .map(|i| (w[1][i] - w[0][i]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!((1.2..1.4).contains(&step), "a step of {step:.3} m");
    }
}

/// The command's packet flags: `--sensor` names the model (and a wrong one is refused with
/// what the packets are), `--cut-azimuth` moves where turns are cut (each sweep then starts
/// there: its points' azimuths run from the cut round to it again).
#[test]
fn the_sensor_and_cut_flags_from_the_command_line() {
    let cap = fixture("hdl32e-drive.pcap");
    let out = common::scratch("packets-flags");
    let o = common::slamesh_run(&cap, &out, &["--sensor", "vlp32c"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--sensor vlp32c: the packets are a HDL-32E's"),
        "{err}"
    );
    common::slamesh_run_ok(
        &cap,
        &out,
        &[
            "--sensor",
            "hdl32",
            "--cut-azimuth",
            "180",
            "--deskew",
            "off",
        ],
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let frames = report["frames"].as_array().unwrap();
    assert!((4..=5).contains(&frames.len()), "{} sweeps", frames.len());
    // Sweeps cut at 180 degrees: the first point of each is behind the sensor.
    let mut replay = Replay::open(
        &cap,
        &PacketOptions {
            sensor: Some("hdl32".into()),
            cut_azimuth_deg: Some(180.0),
            ..PacketOptions::default()
        },
    )
    .unwrap();
    let (points, times) = replay.read_timed(0).unwrap();
    let times = times.unwrap();
    let first = points
        .iter()
        .zip(&times)
        .min_by(|a, b| a.1.total_cmp(b.1))
        .unwrap()
        .0;
    assert!(first[0] < 0.0, "the first point is behind: {first:?}");
    assert!(times.windows(2).all(|w| w[0] <= w[1]), "times run forward");
    let span = times.last().unwrap() - times[0];
    assert!((0.07..0.1).contains(&span), "a turn takes {span} s");
}

/// Sends the drive capture's packets to `to` ([`common::send_capture`]).
fn replay_to(to: std::net::SocketAddr, speed: f64) -> std::thread::JoinHandle<usize> {
    common::send_capture(&fixture("hdl32e-drive.pcap"), to, speed)
}

/// The live input: a thread sends the capture's packets to a socket on 127.0.0.1 as the
/// sensor did, and then three times as fast; the run listens, takes whole sweeps through its
/// bounded queue and tracks them. At three times the rate it may fall behind: then whole
/// sweeps are dropped and counted, never half sweeps.
#[test]
fn a_live_stream_runs_at_its_rate_and_three_times_faster() {
    use slamesh::run::session::Deskew;
    use slamesh::run::{run, Input, RunOptions};
    for (speed, name) in [(1.0, "live-1x"), (3.0, "live-3x")] {
        let options = PacketOptions {
            // Long enough for the sender's first packet on a busy machine: the listener
            // counts idle time from its start until then (a CI run once saw none in 400 ms).
            idle: Some(std::time::Duration::from_millis(2_000)),
            ..PacketOptions::default()
        };
        let mut input = Input::open_with(
            Path::new("udp://127.0.0.1:0"),
            None,
            Default::default(),
            &options,
        )
        .unwrap();
        let live = input.downcast_ref::<Live>().expect("a live input");
        let sender = replay_to(live.local_addr(), speed);
        let out = common::scratch(name);
        let opts = RunOptions {
            out: out.to_path_buf(),
            deskew: Deskew::Off,
            threads: 2,
            ..RunOptions::default()
        };
        let mut records = Vec::new();
        let summary =
            run::<slamesh_core::Lidar32Capacity>(&mut input, &opts, |r| records.push(r.clone()))
                .unwrap();
        assert_eq!(sender.join().unwrap(), 976, "every frame sent");
        let stats = &summary.input.clone().unwrap();
        let (sweeps, dropped) = (
            stats["sweeps"].as_u64().unwrap(),
            stats["sweeps_dropped"].as_u64().unwrap(),
        );
        println!(
            "{speed}x: {sweeps} sweeps, {dropped} dropped, {} used; latencies {:?} ms",
            summary.used,
            records
                .iter()
                .filter_map(|r| r.latency_ms)
                .map(|l| l.round())
                .collect::<Vec<_>>()
        );
        assert_eq!(sweeps, 5, "the capture's five whole turns");
        assert_eq!(
            summary.used as u64 + dropped,
            sweeps,
            "each sweep used or dropped whole"
        );
        assert!(
            summary.health.not_registered.is_empty(),
            "{:?}",
            summary.health
        );
        // Whole sweeps: each as many points as the capture's turns have (43 900 to 44 600).
        for r in &records {
            assert!(
                (43_000..45_000).contains(&r.points),
                "frame {}: {} points",
                r.frame,
                r.points
            );
            assert!(r.latency_ms.is_some_and(|l| (0.0..5_000.0).contains(&l)));
        }
        if speed == 1.0 {
            assert_eq!(dropped, 0, "at the sensor's rate nothing is dropped");
        }
    }
}

/// A run that does not keep up: the listener never waits for it, and the sweeps that find the
/// queue full are dropped whole and counted. Here nothing is read until the capture has been
/// sent (at twice its rate: at ten times, a busy machine's socket dropped datagrams): the queue
/// of one holds the first sweep, the other four are dropped, and the stream then gives that one
/// whole sweep and ends.
#[test]
fn a_full_queue_drops_whole_sweeps_and_counts_them() {
    use slamesh::sources::live::{Live, LiveOptions};
    let options = LiveOptions {
        queue: 1,
        packets: PacketOptions {
            idle: Some(std::time::Duration::from_millis(300)),
            ..PacketOptions::default()
        },
    };
    let mut live = Live::open("127.0.0.1:0", &options).unwrap();
    replay_to(live.local_addr(), 2.0).join().unwrap();
    std::thread::sleep(std::time::Duration::from_millis(500));
    let stats = live.stats();
    assert_eq!((stats.sweeps, stats.sweeps_dropped), (5, 4), "{stats:?}");
    assert_eq!(stats.sensor.as_deref(), Some("HDL-32E"));
    assert!(live.has(0));
    let (points, times) = live.read_timed(0).unwrap();
    assert!(
        (43_000..45_000).contains(&points.len()),
        "a whole sweep: {}",
        points.len()
    );
    assert_eq!(times.unwrap().len(), points.len());
    assert!(!live.has(1), "the stream ended");
    assert_eq!(live.frames(), 1);
    let _ = live.label(0);
}

/// The command on a live input: it listens, runs the sweeps as they come and, once the sensor
/// has been quiet for `--idle-timeout` seconds, writes its outputs with the input's counts.
#[test]
fn the_command_runs_a_live_input() {
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let out = common::scratch("packets-live-command");
    let input = format!("udp://127.0.0.1:{port}");
    let args = [
        "run",
        &input,
        "--out",
        out.to_str().unwrap(),
        "-q",
        "--sensor",
        "hdl32",
        "--idle-timeout",
        "0.5",
        "--deskew",
        "off",
    ];
    let child = common::slamesh_command(&args).spawn().unwrap();
    // Give it time to bind before sending.
    std::thread::sleep(std::time::Duration::from_millis(300));
    replay_to(format!("127.0.0.1:{port}").parse().unwrap(), 1.0)
        .join()
        .unwrap();
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(
        report["summary"]["input"]["sweeps"], 5,
        "{}",
        report["summary"]["input"]
    );
    assert_eq!(report["summary"]["used"], 5);
    assert!(report["frames"][0]["latency_ms"].as_f64().is_some());
}

/// The HDL-64E capture made by the fixtures' make.py (a street cast with a real unit's
/// calibration), its calibration, and the options that name them.
fn hdl64e() -> (PathBuf, PacketOptions) {
    (
        fixture("hdl64e-s2-street.pcap"),
        PacketOptions {
            sensor: Some("hdl64e-s2".into()),
            calibration: Some(fixture("hdl64e-s2.1-sztaki.yml")),
            ..PacketOptions::default()
        },
    )
}

/// Every 25th HDL-64E data packet, decoded alone, against velodyne_decoder's points of it:
/// the two-point distance corrections, both banks, the firing times.
#[test]
fn hdl64e_packets_decode_to_the_independent_decoders_points() {
    use slamesh::sources::packets::read_calibration;
    use slamesh::sources::velodyne::hdl64::{Generation, Hdl64};
    let (capture, options) = hdl64e();
    let calibration = read_calibration(options.calibration.as_deref().unwrap()).unwrap();
    let decoder = Hdl64::new(Generation::S2, &calibration).unwrap();
    let mut cap = Capture::open(&capture).unwrap();
    let (mut ours, mut k) = (Vec::new(), 0);
    while let Some(d) = cap.next_datagram().unwrap() {
        if k % 25 == 0 {
            let t = velodyne::packet_time(d.udp.payload, d.time_s).unwrap();
            decoder
                .decode(d.udp.payload, t, |f| ours.push((f.point, f.time_s)))
                .unwrap();
        }
        k += 1;
    }
    let theirs = reference("hdl64e-s2-street.points");
    common::assert_same_points("hdl64e-s2-street", &ours, &theirs);
}

/// The HDL-64E capture replayed: its three turns at 15 m/s down the street are steps of a
/// metre along x; without its calibration, or its generation, it is refused with what to give.
#[test]
fn a_replayed_hdl64e_capture_runs_end_to_end() {
    let (capture, options) = hdl64e();
    let out = common::scratch("packets-hdl64e");
    let calibration = options.calibration.clone().unwrap();
    common::slamesh_run_ok(
        &capture,
        &out,
        &[
            "--strict",
            "--sensor",
            "hdl64e-s2",
            "--calibration",
            calibration.to_str().unwrap(),
        ],
    );
    let xyz = common::kitti_positions(&out.join("poses_kitti.txt"));
    assert_eq!(xyz.len(), 3, "three whole turns");
    for w in xyz.windows(2) {
        let step = [w[1][0] - w[0][0], w[1][1] - w[0][1], w[1][2] - w[0][2]];
        assert!((step[0] - 1.0).abs() < 0.05, "a step of {step:?}");
        assert!(step[1].abs() < 0.02 && step[2].abs() < 0.02, "{step:?}");
    }
    let e = Replay::open(&capture, &PacketOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("HDL-64E packets") && e.contains("--calibration FILE"),
        "{e}"
    );
    let unnamed = PacketOptions {
        sensor: None,
        ..options
    };
    let e = Replay::open(&capture, &unnamed).unwrap_err().to_string();
    assert!(e.contains("--sensor hdl64e-s2 or hdl64e-s3"), "{e}");
}

/// Packets of the models no real capture of was found (VLP-16, Puck Hi-Res, VLP-32C) and of
/// the HDL-32E in dual mode, made by the fixtures' make.py, strongest and dual: each decoded
/// alone, against velodyne_decoder's points of it.
#[test]
fn every_model_and_return_mode_decodes_to_the_independent_decoders_points() {
    let ours = decode_capture(&fixture("velodyne-models.pcap"));
    let theirs = reference("velodyne-models.points");
    common::assert_same_points("velodyne-models", &ours, &theirs);
}
