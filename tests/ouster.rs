//! Real Ouster captures (tests/fixtures/packets, with their sources in its README), one of
//! each packet profile: decoded point for point against Ouster's own SDK, replayed end to end
//! against the SDK's own trajectory of the same capture, taken live from a socket, and refused
//! with a clear message without their metadata.

use crate::common;

use slamesh::sources::capture::Capture;
use slamesh::sources::ouster::Sensor;
use slamesh::sources::packets::{read_metadata, PacketOptions};
use slamesh::sources::replay::Replay;
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/fixtures/packets")
        .join(name)
}

/// The columns the reference files hold: every 32nd (see the fixtures' make.py).
const SAMPLE: u16 = 32;

/// The points of every sampled column of every lidar packet in the capture, with their times.
fn decode_capture(sensor: &Sensor, path: &Path) -> (Vec<([f32; 3], f64)>, usize) {
    let mut cap = Capture::open(path).unwrap();
    let (mut out, mut packets) = (Vec::new(), 0);
    while let Some(d) = cap.next_datagram().unwrap() {
        if d.udp.payload.len() != sensor.packet_bytes() {
            continue;
        }
        packets += 1;
        sensor
            .decode(d.udp.payload, |f| {
                if f.column % SAMPLE == 0 {
                    out.push((f.point, f.time_s));
                }
            })
            .unwrap();
    }
    (out, packets)
}

/// The reference file's points.
fn reference(name: &str) -> Vec<([f32; 3], f64)> {
    common::reference_points(&fixture(name))
}

#[test]
fn every_profile_decodes_to_the_ouster_sdks_points() {
    for (name, profile, packets) in [
        ("ouster-os1-32-legacy", "LEGACY", 64),
        ("ouster-os0-32-dual", "RNG19_RFL8_SIG16_NIR16_DUAL", 64),
        ("ouster-os2-128-rng19", "RNG19_RFL8_SIG16_NIR16", 14),
        ("ouster-os1-128-lowdata", "RNG15_RFL8_NIR8", 192),
    ] {
        let sensor = read_metadata(&fixture(&format!("{name}.json"))).unwrap();
        assert_eq!(sensor.metadata().profile.name(), profile);
        let (ours, n) = decode_capture(&sensor, &fixture(&format!("{name}.pcap")));
        let theirs = reference(&format!("{name}.points"));
        assert_eq!(n, packets, "{name}: lidar packets");
        common::assert_same_points(name, &ours, &theirs);
    }
}

/// Every IMU packet of the moving OS1-128's capture (30, port 7503) decodes to what Ouster's
/// SDK makes of it (`ouster-os1-128-lowdata.imu`, from the fixtures' make.py): the three
/// timestamps exactly, the acceleration (m/s²) and angular velocity (rad/s) to the SDK's
/// single precision.
#[test]
fn every_imu_packet_decodes_to_the_ouster_sdks_values() {
    use slamesh::sources::ouster::imu_packet::ImuPacket;
    let text = std::fs::read_to_string(fixture("ouster-os1-128-lowdata.imu")).unwrap();
    let theirs: Vec<Vec<f64>> = (text.lines())
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split(' ').map(|v| v.parse().unwrap()).collect())
        .collect();
    let mut cap = Capture::open(&fixture("ouster-os1-128-lowdata.pcap")).unwrap();
    let mut ours = Vec::new();
    while let Some(d) = cap.next_datagram().unwrap() {
        if d.udp.dst_port == 7503 {
            ours.push(ImuPacket::decode(d.udp.payload).unwrap());
        }
    }
    assert_eq!((ours.len(), theirs.len()), (30, 30));
    for (k, (p, t)) in ours.iter().zip(&theirs).enumerate() {
        let stamps = [p.sys_ts, p.accel_ts, p.gyro_ts];
        assert_eq!(stamps.map(|s| s as f64), [t[0], t[1], t[2]], "packet {k}");
        let values = [p.accel_m_s2(), p.gyro_rad_s()].concat();
        for (j, (a, b)) in values.iter().zip(&t[3..]).enumerate() {
            // The SDK computes in f32: within its rounding.
            assert!(
                (a - b).abs() <= 2.0 * f64::from(f32::EPSILON) * b.abs().max(1e-3),
                "packet {k}, value {j}: {a} against the SDK's {b}"
            );
        }
    }
}

/// The SDK's trajectory of the same capture (`sdk_poses_kitti.txt`, from the SDK's tests):
/// each pose's translation.
fn sdk_positions() -> Vec<[f64; 3]> {
    common::kitti_positions(&fixture("ouster-os1-128-lowdata.sdk_poses_kitti.txt"))
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

/// The three-turn capture of a moving OS1-128 runs with --strict, its metadata found beside it,
/// a turn a frame cut at the sensor's own frame start; the trajectory is the SDK's own
/// (Ouster's SLAM on the same packets) within 3 cm a pose.
#[test]
fn a_replayed_ouster_capture_runs_end_to_end() {
    let out = common::scratch("ouster-run");
    common::slamesh_run_ok(&fixture("ouster-os1-128-lowdata.pcap"), &out, &["--strict"]);
    let ours = common::kitti_positions(&out.join("poses_kitti.txt"));
    let theirs = sdk_positions();
    assert_eq!(ours.len(), 3, "three whole turns");
    for (k, (a, b)) in ours.iter().zip(&theirs).enumerate() {
        let d = distance(*a, *b);
        println!(
            "pose {k}: {a:?} against the SDK's {b:?}: {:.1} cm",
            d * 100.0
        );
        assert!(d < 0.03, "pose {k} is {d:.3} m from the SDK's");
    }
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let input = &report["summary"]["input"];
    assert_eq!(input["stream"]["packets"], 192, "{input}");
    assert_eq!(input["stream"]["gaps"], 0, "{input}");
    assert_eq!(input["stream"]["partial_firings"], 0, "{input}");
    // Its IMU packets, every one, went to the run.
    assert_eq!(input["stream"]["imu_packets"], 30, "{input}");
    let imu = &report["summary"]["imu"];
    assert_eq!(imu["readings"]["taken"], 30, "{imu}");
}

/// Without its metadata an Ouster capture is refused with what to give; a wrong `--sensor`
/// is refused; `--cut-azimuth` cuts inside the sensor's frames, leaving two whole turns and
/// the part turns at the ends.
#[test]
fn the_metadata_is_asked_for_and_the_cut_can_move() {
    let dir = common::scratch("ouster-flags");
    let bare = dir.join("bare.pcap");
    std::fs::copy(fixture("ouster-os1-128-lowdata.pcap"), &bare).unwrap();
    let e = Replay::open(&bare, &PacketOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bare.pcap") && e.contains("Ouster") && e.contains("--metadata FILE"),
        "{e}"
    );
    let e = Replay::open(
        &bare,
        &PacketOptions {
            sensor: Some("ouster".into()),
            ..PacketOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("--sensor ouster") && e.contains("--metadata"),
        "{e}"
    );
    let meta = fixture("ouster-os1-128-lowdata.json");
    let e = Replay::open(
        &bare,
        &PacketOptions {
            sensor: Some("vlp16".into()),
            metadata: Some(meta.clone()),
            ..PacketOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("--sensor names a VLP-16"), "{e}");
    // Another unit's metadata: its packets are another size.
    let e = Replay::open(
        &bare,
        &PacketOptions {
            metadata: Some(fixture("ouster-os1-32-legacy.json")),
            ..PacketOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("no lidar packets of the Ouster's metadata (6464 bytes)"),
        "{e}"
    );
    let whole = Replay::open(
        &bare,
        &PacketOptions {
            metadata: Some(meta.clone()),
            ..PacketOptions::default()
        },
    )
    .unwrap();
    assert_eq!(whole.len(), 3);
    // Cut at 0 degrees: half a turn from the frames' start (180 degrees).
    let cut = Replay::open(
        &bare,
        &PacketOptions {
            metadata: Some(meta),
            cut_azimuth_deg: Some(0.0),
            ..PacketOptions::default()
        },
    )
    .unwrap();
    assert_eq!(cut.len(), 2);
    // Half a turn before the first cut and half after the last: about a turn's 107 000 points.
    let part = cut.stats().stream.partial_firings;
    assert!(
        (80_000..140_000).contains(&part),
        "{part} points in part turns"
    );
    let stamps = [cut.stamp(0), whole.stamp(0), whole.stamp(1)];
    assert!(
        stamps[1] < stamps[0] && stamps[0] < stamps[2],
        "a turn cut half way is stamped between whole ones: {stamps:?}"
    );
}

/// Damaged packets in an Ouster capture: cut short, of a wrong type, with a column past the
/// turn. Each is skipped and counted; the turns they were in lose those columns, not their
/// shape.
#[test]
fn damaged_ouster_packets_are_skipped_and_counted() {
    let path = fixture("ouster-os1-128-lowdata.pcap");
    let mut bytes = std::fs::read(&path).unwrap();
    // Records: a 16-byte header, then 42 bytes of Ethernet, IPv4 and UDP, then the packet.
    let mut records = Vec::new();
    let mut off = 24;
    while off + 16 <= bytes.len() {
        let incl = u32::from_le_bytes(bytes[off + 8..off + 12].try_into().unwrap()) as usize;
        records.push(off + 16 + 42);
        off += 16 + incl;
    }
    // Packet 10: type 7. Packet 20: column 3's measurement id past the turn.
    bytes[records[10]] = 7;
    let col3 = records[20] + 32 + 3 * (12 + 128 * 4) + 8;
    bytes[col3..col3 + 2].copy_from_slice(&5000u16.to_le_bytes());
    let dir = common::scratch("ouster-damaged");
    let damaged = dir.join("damaged.pcap");
    std::fs::write(&damaged, &bytes).unwrap();
    let replay = Replay::open(
        &damaged,
        &PacketOptions {
            metadata: Some(fixture("ouster-os1-128-lowdata.json")),
            ..PacketOptions::default()
        },
    )
    .unwrap();
    let s = replay.stats().stream;
    assert_eq!((s.packets, s.bad_packets), (190, 2), "{s:?}");
    assert_eq!(s.gaps, 2, "each refused packet is a gap in its turn");
    assert_eq!(replay.len(), 3);
}

/// An Ouster live: a thread sends the capture's packets to a socket as the sensor did; the
/// run, given the metadata, takes its three turns and tracks them as the replay does.
#[test]
fn a_live_ouster_stream_runs() {
    use slamesh::sources::live::{Live, LiveOptions};
    let options = LiveOptions {
        packets: PacketOptions {
            metadata: Some(fixture("ouster-os1-128-lowdata.json")),
            // Long enough for the sender's first packet on a busy machine: the listener
            // counts idle time from its start until then (a CI run once saw none in 400 ms).
            idle: Some(std::time::Duration::from_millis(2_000)),
            ..PacketOptions::default()
        },
        queue: 4,
    };
    let mut live = Live::open("127.0.0.1:0", &options).unwrap();
    let sender = common::send_capture(
        &fixture("ouster-os1-128-lowdata.pcap"),
        live.local_addr(),
        1.0,
    );
    let (mut points, mut readings) = (Vec::new(), Vec::new());
    let mut i = 0;
    while live.has(i) {
        let (p, times) = live.read_timed(i).unwrap();
        assert!(times.is_some_and(|t| t.len() == p.len()));
        points.push(p.len());
        readings.push(live.samples(i).len());
        assert!(live.samples(i).is_empty(), "handed once");
        i += 1;
    }
    // Its 192 lidar packets and 30 of its IMU's, all to the one port.
    assert_eq!(sender.join().unwrap(), 222);
    let stats = live.stats();
    assert_eq!(points.len(), 3, "three turns: {stats:?}");
    assert!(points.iter().all(|n| *n > 50_000), "{points:?}");
    assert_eq!((stats.sweeps, stats.sweeps_dropped), (3, 0), "{stats:?}");
    // The IMU's readings go with the turn they came before (100 a second: 10 a turn, less
    // those after the last turn ended).
    assert_eq!(stats.stream.imu_packets, 30, "{stats:?}");
    assert!(
        readings.iter().all(|n| (1..=12).contains(n)) && readings.iter().sum::<usize>() >= 20,
        "{readings:?}"
    );
}

/// An Ouster sends its IMU packets to a port of their own (the metadata's `udp_port_imu`):
/// live, that port is listened on beside the lidar port, and the readings go with the turns.
#[test]
fn a_live_ouster_s_imu_port_is_listened_on() {
    use slamesh::sources::live::{Live, LiveOptions};
    let dir = common::scratch("ouster-imu-port");
    // A free port for the IMU, named in a copy of the metadata.
    let imu_port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let meta = std::fs::read_to_string(fixture("ouster-os1-128-lowdata.json")).unwrap();
    let meta = meta.replace(
        "\"udp_port_imu\": 7503",
        &format!("\"udp_port_imu\": {imu_port}"),
    );
    std::fs::write(dir.join("meta.json"), meta).unwrap();
    let options = LiveOptions {
        packets: PacketOptions {
            metadata: Some(dir.join("meta.json")),
            idle: Some(std::time::Duration::from_millis(2_000)),
            ..PacketOptions::default()
        },
        queue: 4,
    };
    let mut live = Live::open("127.0.0.1:0", &options).unwrap();
    let lidar = live.local_addr();
    let imu = std::net::SocketAddr::new(lidar.ip(), imu_port);
    let sender = common::send_capture_routed(
        &fixture("ouster-os1-128-lowdata.pcap"),
        move |port| if port == 7503 { imu } else { lidar },
        1.0,
    );
    let mut readings = Vec::new();
    let mut i = 0;
    while live.has(i) {
        live.read_timed(i).unwrap();
        readings.push(live.samples(i).len());
        i += 1;
    }
    assert_eq!(sender.join().unwrap(), 222);
    let stats = live.stats();
    assert_eq!(stats.sweeps, 3, "{stats:?}");
    let port = stats.imu_port.expect("listened on its IMU port");
    assert_eq!(
        (port.port, port.packets, port.bad_packets),
        (imu_port, 30, 0)
    );
    assert_eq!(stats.stream.imu_packets, 0, "none came to the lidar port");
    assert!(
        readings.iter().all(|n| (1..=12).contains(n)) && readings.iter().sum::<usize>() >= 20,
        "{readings:?}"
    );
    drop(live);
}
