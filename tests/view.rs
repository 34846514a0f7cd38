//! The live view and its recording (feature `view`): a recorded run read back (channels,
//! schemas, counts, one mesh update's content, the occupancy grid); a WebSocket client that subscribes and receives
//! a scan and a mesh update; and clients that must not stall the run (garbage, never reading).

use foxglove::messages::{Grid, PointCloud, SceneUpdate};
use foxglove::Decode;
use slamesh::navmap::NavMapOptions;
use slamesh::run::sink::FnSink;
use slamesh::run::{run_to, FrameEvent, FrameRecord, RunOptions, Sinks};
use slamesh::sources::recording::mcap::messages_of;
use slamesh::view::{View, ViewOptions};
use slamesh_core::{Config, KittiCapacity, Pipeline};
use slamesh_sim::Drive;
use std::collections::BTreeMap;
use std::time::{Duration, Instant};
use websocket::{Client, Message};

#[path = "common/scratch.rs"]
mod scratch;
use scratch::scratch;

#[test]
fn a_recorded_run_reads_back_with_its_channels_counts_and_mesh() {
    let out = scratch("record");
    let frames = 12;
    let mut drive = Drive::town(frames, 1);
    let opts = RunOptions {
        out: out.to_path_buf(),
        config: Config::default(),
        threads: 2,
        ..RunOptions::default()
    };
    let view = ViewOptions {
        serve: None,
        record: true,
        grid: Some(NavMapOptions::default()),
    };
    let mut records: Vec<FrameRecord> = Vec::new();
    // The view is one of the run's sinks, beside one that keeps the records.
    let mut sinks = Sinks::new();
    sinks.add(View::for_run(&view, &out, &opts.config).unwrap().unwrap());
    sinks.add(FnSink::new("records", |e: &FrameEvent| {
        records.push(e.record.clone())
    }));
    run_to::<KittiCapacity>(&mut drive, &opts, sinks).unwrap();
    assert!(!out.join("slam.mcap.tmp").exists());
    let bytes = std::fs::read(out.join("slam.mcap")).unwrap();

    let mut counts: BTreeMap<String, (String, String, usize)> = BTreeMap::new();
    let mut meshes = Vec::new();
    let mut scans = Vec::new();
    let mut grids = Vec::new();
    for m in messages_of(&bytes).unwrap() {
        let m = m.unwrap();
        let e = counts
            .entry(m.topic.clone())
            .or_insert((m.schema.clone(), m.encoding.clone(), 0));
        e.2 += 1;
        match m.topic.as_str() {
            "/mesh" => meshes.push(SceneUpdate::decode(&m.data[m.start..]).unwrap()),
            "/scan" => scans.push(PointCloud::decode(&m.data[m.start..]).unwrap()),
            "/map" => grids.push(Grid::decode(&m.data[m.start..]).unwrap()),
            _ => {}
        }
    }
    let schema = |t: &str| (counts[t].0.as_str(), counts[t].1.as_str(), counts[t].2);
    assert_eq!(schema("/scan"), ("foxglove.PointCloud", "protobuf", frames));
    assert_eq!(
        schema("/tf"),
        ("foxglove.FrameTransform", "protobuf", frames)
    );
    assert_eq!(
        schema("/mesh"),
        ("foxglove.SceneUpdate", "protobuf", frames)
    );
    // Every 10th frame and the last: frames 0 and 10, then the end.
    assert_eq!(
        schema("/trajectory"),
        ("foxglove.PosesInFrame", "protobuf", 3)
    );

    // The grid: after the 10th scan and at the end.
    assert_eq!(schema("/map"), ("foxglove.Grid", "protobuf", 2));
    check_grid(grids.last().unwrap(), &scans);

    // One mesh update: an entity per layer the frame fused, 36 vertices each, whole triangles.
    let (i, update) = (5, &meshes[5]);
    assert_eq!(update.entities.len(), records[i].scan_layers, "frame {i}");
    let mut triangles = 0;
    for e in &update.entities {
        assert_eq!(e.frame_id, "world");
        assert_eq!(e.id.split(',').count(), 4, "{}", e.id);
        let t = &e.triangles[0];
        assert_eq!(t.points.len(), 36);
        assert_eq!(t.indices.len() % 3, 0);
        assert!(t.indices.iter().all(|&j| j < 36));
        assert!(t.points.iter().all(|p| p.x.is_finite() && p.z.is_finite()));
        triangles += t.indices.len() / 3;
    }
    assert_eq!(triangles, records[i].triangles_updated, "frame {i}");
    // The scan: float32 x, y, z in the world frame, as many points as the frame kept.
    assert_eq!(scans[i].point_stride, 12);
    assert_eq!(scans[i].data.len(), 12 * records[i].points_kept);
}

/// A WebSocket client of the view at `address`, with the Foxglove SDK's subprotocol.
/// A grid on `/map`: five bytes a cell (RGBA and Nav2's value, agreeing), free and occupied
/// cells both, and every free cell within the square the scans reached (world frame).
fn check_grid(g: &Grid, scans: &[PointCloud]) {
    let names: Vec<&str> = g.fields.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["red", "green", "blue", "alpha", "occupancy"]);
    assert_eq!((g.cell_stride, g.row_stride), (5, 5 * g.column_count));
    assert_eq!(g.data.len() % g.row_stride as usize, 0);
    let (mut free, mut occupied) = (Vec::new(), 0);
    let res = g.cell_size.as_ref().unwrap().x;
    let pose = g.pose.as_ref().unwrap();
    let (p, q) = (
        pose.position.as_ref().unwrap(),
        pose.orientation.as_ref().unwrap(),
    );
    let corner = nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(p.x, p.y, p.z),
        nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z)),
    );
    for (k, cell) in g.data.chunks_exact(5).enumerate() {
        let (value, alpha) = (cell[4] as i8, cell[3]);
        assert!([-1, 0, 100].contains(&value), "{value}");
        assert_eq!(
            alpha == 0,
            value == -1,
            "unknown cells, and only they, are clear"
        );
        let (col, row) = (k % g.column_count as usize, k / g.column_count as usize);
        let centre = nalgebra::Point3::new((col as f64 + 0.5) * res, (row as f64 + 0.5) * res, 0.0);
        match value {
            0 => free.push(corner * centre),
            100 => occupied += 1,
            _ => {}
        }
    }
    assert!(
        free.len() > 1000 && occupied > 100,
        "{} {occupied}",
        free.len()
    );
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for s in scans {
        for xyz in s.data.chunks_exact(12) {
            for a in 0..2 {
                let c = f32::from_le_bytes(xyz[4 * a..4 * a + 4].try_into().unwrap()) as f64;
                (lo[a], hi[a]) = (lo[a].min(c), hi[a].max(c));
            }
        }
    }
    assert!(free
        .iter()
        .all(|c| (lo[0]..=hi[0]).contains(&c.x) && (lo[1]..=hi[1]).contains(&c.y)));
}

fn connect(address: &str) -> Client {
    let client = Client::connect(address, "foxglove.sdk.v1").unwrap();
    client.set_read_timeout(Duration::from_secs(20)).unwrap();
    client
}

/// Reads text messages until the channels `topics` are advertised; their ids.
fn advertised(ws: &mut Client, topics: &[&str]) -> BTreeMap<String, u64> {
    let mut ids = BTreeMap::new();
    while !topics.iter().all(|t| ids.contains_key(*t)) {
        if let Message::Text(t) = ws.read().unwrap() {
            let v: serde_json::Value = serde_json::from_str(&t).unwrap();
            if v["op"] == "advertise" {
                for c in v["channels"].as_array().unwrap() {
                    ids.insert(
                        c["topic"].as_str().unwrap().to_string(),
                        c["id"].as_u64().unwrap(),
                    );
                }
            }
        }
    }
    ids
}

/// A few frames of the town through a pipeline, each offered to `view`.
fn feed(
    view: &mut View,
    pipeline: &mut Pipeline<KittiCapacity>,
    drive: &Drive,
    frames: std::ops::Range<usize>,
) {
    for i in frames {
        pipeline.process_scan(&drive.scan(i)).unwrap();
        view.frame(pipeline, i, i as f64 * 0.1);
    }
}

/// A view serving on a free port of this machine (recording nothing), and its address.
fn serving(out: &std::path::Path) -> (View, String) {
    let opts = ViewOptions {
        serve: Some("127.0.0.1:0".into()),
        record: false,
        grid: None,
    };
    let view = View::start(&opts, out, &Config::default())
        .unwrap()
        .unwrap();
    let address = view.address.clone().unwrap();
    assert!(address.starts_with("127.0.0.1:"), "{address}");
    (view, address)
}

#[test]
fn a_websocket_client_subscribes_and_receives_a_scan_and_a_mesh_update() {
    let out = scratch("serve");
    let (mut view, address) = serving(&out);
    let mut ws = connect(&address);
    let ids = advertised(&mut ws, &["/scan", "/mesh"]);
    let subscribe = serde_json::json!({
        "op": "subscribe",
        "subscriptions": [
            {"id": 1, "channelId": ids["/scan"]},
            {"id": 2, "channelId": ids["/mesh"]},
        ]
    });
    ws.send(Message::Text(subscribe.to_string())).unwrap();
    // The server takes the subscription on its own threads: give it a moment before feeding.
    std::thread::sleep(Duration::from_millis(300));
    let drive = Drive::town(3, 1);
    let mut pipeline = Pipeline::<KittiCapacity>::new(Config::default()).unwrap();
    feed(&mut view, &mut pipeline, &drive, 0..3);
    let (mut scan, mut mesh) = (None, None);
    while scan.is_none() || mesh.is_none() {
        if let Message::Binary(b) = ws.read().unwrap() {
            // Opcode 1 (message data), subscription id (u32), log time (u64), payload.
            assert_eq!(b[0], 1);
            let sub = u32::from_le_bytes(b[1..5].try_into().unwrap());
            let payload = &b[13..];
            match sub {
                1 => scan = Some(PointCloud::decode(payload).unwrap()),
                2 => mesh = Some(SceneUpdate::decode(payload).unwrap()),
                other => panic!("subscription {other}"),
            }
        }
    }
    assert!(!scan.unwrap().data.is_empty());
    assert!(!mesh.unwrap().entities.is_empty());
    let stats = view.finish().unwrap();
    assert_eq!(stats.sent + stats.dropped, 3);
}

#[test]
fn garbage_and_clients_that_never_read_do_not_stall_the_run() {
    let out = scratch("hostile");
    let (mut view, address) = serving(&out);
    // A client that sends garbage, text and binary, and a publish it is not allowed.
    let mut rude = connect(&address);
    for m in [
        Message::Text("{not json".into()),
        Message::Text(r#"{"op":"advertise","channels":[{"id":1,"topic":"/x","encoding":"json","schemaName":"x"}]}"#.into()),
        Message::Binary(vec![1, 0, 0, 0, 9, 9, 9]),
        Message::Binary(vec![255; 4096]),
    ] {
        let _ = rude.send(m);
    }
    // A client that subscribes to everything and never reads again.
    let mut stuck = connect(&address);
    let ids = advertised(&mut stuck, &["/scan", "/mesh", "/tf", "/trajectory"]);
    let subscriptions: Vec<_> = ids
        .values()
        .enumerate()
        .map(|(k, id)| serde_json::json!({"id": k + 1, "channelId": id}))
        .collect();
    stuck
        .send(Message::Text(
            serde_json::json!({"op": "subscribe", "subscriptions": subscriptions}).to_string(),
        ))
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    // Many frames, each with its scan and the layers it changed: the loop's offers never wait.
    let drive = Drive::town(40, 1);
    let mut pipeline = Pipeline::<KittiCapacity>::new(Config::default()).unwrap();
    let mut slowest = Duration::ZERO;
    for i in 0..40 {
        pipeline.process_scan(&drive.scan(i)).unwrap();
        let t = Instant::now();
        view.frame(&pipeline, i, i as f64 * 0.1);
        slowest = slowest.max(t.elapsed());
    }
    assert!(
        slowest < Duration::from_millis(200),
        "an offer took {slowest:?}"
    );
    let t = Instant::now();
    let stats = view.finish().unwrap();
    assert!(
        t.elapsed() < Duration::from_secs(20),
        "finish took {:?}",
        t.elapsed()
    );
    assert_eq!(stats.sent + stats.dropped, 40);
    drop((rude, stuck));
}

/// A WebSocket client (RFC 6455), just what these tests need: the opening handshake (the
/// server's accept key is not checked), messages in frames of any length, fragmented or not,
/// pings answered, and masked frames sent. The server under test is the Foxglove SDK's.
mod websocket {
    use std::io::{self, BufRead, BufReader, Read, Write};
    use std::net::TcpStream;
    use std::time::Duration;

    pub enum Message {
        Text(String),
        Binary(Vec<u8>),
    }

    pub struct Client {
        reader: BufReader<TcpStream>,
        writer: TcpStream,
    }

    fn failed(why: String) -> io::Error {
        io::Error::other(why)
    }

    impl Client {
        /// Connects to `address` (host:port) and asks for the subprotocol `protocol`.
        pub fn connect(address: &str, protocol: &str) -> io::Result<Client> {
            let stream = TcpStream::connect(address)?;
            let mut writer = stream.try_clone()?;
            write!(
                writer,
                "GET / HTTP/1.1\r\nHost: {address}\r\nUpgrade: websocket\r\n\
                 Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\
                 Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: {protocol}\r\n\r\n"
            )?;
            let mut reader = BufReader::new(stream);
            let mut status = String::new();
            reader.read_line(&mut status)?;
            if !status.starts_with("HTTP/1.1 101") {
                return Err(failed(format!("handshake refused: {status}")));
            }
            loop {
                let mut line = String::new();
                if reader.read_line(&mut line)? == 0 || line == "\r\n" {
                    break;
                }
            }
            Ok(Client { reader, writer })
        }

        pub fn set_read_timeout(&self, timeout: Duration) -> io::Result<()> {
            self.writer.set_read_timeout(Some(timeout))
        }

        /// The next text or binary message, whole.
        pub fn read(&mut self) -> io::Result<Message> {
            let (mut opcode, mut message) = (0, Vec::new());
            loop {
                let mut head = [0u8; 2];
                self.reader.read_exact(&mut head)?;
                let length = match head[1] & 0x7f {
                    126 => {
                        let mut n = [0u8; 2];
                        self.reader.read_exact(&mut n)?;
                        u64::from(u16::from_be_bytes(n))
                    }
                    127 => {
                        let mut n = [0u8; 8];
                        self.reader.read_exact(&mut n)?;
                        u64::from_be_bytes(n)
                    }
                    n => u64::from(n),
                };
                let mut mask = [0u8; 4];
                if head[1] & 0x80 != 0 {
                    self.reader.read_exact(&mut mask)?;
                }
                let mut payload = vec![0u8; length as usize];
                self.reader.read_exact(&mut payload)?;
                for (i, b) in payload.iter_mut().enumerate() {
                    *b ^= mask[i % 4];
                }
                match head[0] & 0x0f {
                    0x8 => return Err(failed("the server closed the connection".into())),
                    0x9 => self.send_frame(0xa, &payload)?,
                    0xa => {}
                    code => {
                        if code != 0 {
                            opcode = code;
                        }
                        message.extend_from_slice(&payload);
                        if head[0] & 0x80 != 0 {
                            break;
                        }
                    }
                }
            }
            match opcode {
                1 => String::from_utf8(message)
                    .map(Message::Text)
                    .map_err(|e| failed(e.to_string())),
                2 => Ok(Message::Binary(message)),
                other => Err(failed(format!("opcode {other}"))),
            }
        }

        pub fn send(&mut self, message: Message) -> io::Result<()> {
            match message {
                Message::Text(t) => self.send_frame(0x1, t.as_bytes()),
                Message::Binary(b) => self.send_frame(0x2, &b),
            }
        }

        /// One final frame, masked as a client's must be.
        fn send_frame(&mut self, opcode: u8, payload: &[u8]) -> io::Result<()> {
            let mut frame = vec![0x80 | opcode];
            match payload.len() {
                n if n < 126 => frame.push(0x80 | n as u8),
                n if n <= 0xffff => {
                    frame.push(0x80 | 126);
                    frame.extend_from_slice(&(n as u16).to_be_bytes());
                }
                n => {
                    frame.push(0x80 | 127);
                    frame.extend_from_slice(&(n as u64).to_be_bytes());
                }
            }
            let mask = [0x5a, 0x17, 0xc3, 0x88];
            frame.extend_from_slice(&mask);
            frame.extend(payload.iter().enumerate().map(|(i, b)| b ^ mask[i % 4]));
            self.writer.write_all(&frame)
        }
    }
}
