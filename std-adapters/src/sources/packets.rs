//! A sensor's packet stream made sweeps, wherever the packets come from (a capture file,
//! [`crate::sources::replay`]; a socket, [`crate::sources::live`]): which datagrams are the sensor's
//! data, which sensor it is, each packet decoded and its firings cut into turns.

use crate::io::error::FileError;
use crate::sources::ouster;
use crate::sources::ouster::imu_packet::ImuPacket;
use crate::sources::sweep::{Sweep, Sweeps};
use crate::sources::velodyne::calibration::Calibration;
use crate::sources::velodyne::hdl64::{self, Generation, Hdl64};
use crate::sources::velodyne::{self, tables::Model, Decoder, POSITION_PACKET_BYTES};
use serde::Serialize;
use slamesh_core::imu::ImuSample;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What a stream counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct StreamStats {
    /// The sensor's data packets decoded.
    pub packets: u64,
    /// Its packets refused as damaged (a bad flag, azimuth or byte).
    pub bad_packets: u64,
    /// Packets missing between those decoded.
    pub gaps: u64,
    /// Firings in part turns at the ends, or cut off by a jump in time (no sweep).
    pub partial_firings: u64,
    /// Jumps in the packets' time ([`crate::sources::sweep::MAX_GAP_S`]).
    pub time_jumps: u64,
    /// An Ouster's IMU packets decoded (absent from the report when none came).
    #[serde(skip_serializing_if = "is_zero")]
    pub imu_packets: u64,
    /// Its IMU packets refused (another size than the legacy profile's).
    #[serde(skip_serializing_if = "is_zero")]
    pub bad_imu_packets: u64,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// How to read packets, from a capture or live.
#[derive(Debug, Clone, Default)]
pub struct PacketOptions {
    /// The sensor (`--sensor`): one of [`sensor_names`]; `None` to tell it from the packets.
    pub sensor: Option<String>,
    /// An Ouster's metadata JSON (`--metadata`).
    pub metadata: Option<PathBuf>,
    /// An HDL-64E's calibration YAML (`--calibration`).
    pub calibration: Option<PathBuf>,
    /// Where sweeps are cut (degrees of azimuth; `None`: the sensor's
    /// [default](Sensor::default_cut_deg)).
    pub cut_azimuth_deg: Option<f64>,
    /// Live: end after this long without a packet (`None`: never).
    pub idle: Option<std::time::Duration>,
    /// Live: set to end the stream (Ctrl-C).
    pub stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

/// A sensor whose packets are decoded: a Velodyne model (its factory tables), an HDL-64E
/// unit (its own calibration), or an Ouster unit (its own metadata).
#[derive(Debug, Clone)]
pub enum Sensor {
    /// A Velodyne model.
    Velodyne(&'static Model),
    /// An HDL-64E unit.
    Hdl64(Arc<Hdl64>),
    /// An Ouster unit.
    Ouster(Arc<ouster::Sensor>),
}

impl Sensor {
    /// Its name for messages and reports.
    pub fn name(&self) -> String {
        match self {
            Sensor::Velodyne(m) => m.name.to_string(),
            Sensor::Hdl64(h) => h.name().to_string(),
            Sensor::Ouster(o) => o.name(),
        }
    }

    /// Where its turns are cut unless `--cut-azimuth` says: azimuth 0 for a Velodyne, the
    /// start of the sensor's own frame (column 0) for an Ouster.
    pub fn default_cut_deg(&self) -> f64 {
        match self {
            Sensor::Velodyne(_) | Sensor::Hdl64(_) => 0.0,
            Sensor::Ouster(o) => o.frame_start_deg(),
        }
    }
}

/// What the command line says of the sensor (`--sensor`, `--metadata`), before a packet is
/// seen.
#[derive(Debug, Clone, Default)]
pub struct SensorHint {
    velodyne: Option<&'static Model>,
    hdl64: Option<Arc<Hdl64>>,
    ouster: Option<Arc<ouster::Sensor>>,
}

/// The sensor names `--sensor` takes.
pub fn sensor_names() -> Vec<&'static str> {
    let mut names: Vec<&'static str> = velodyne::tables::MODELS.iter().map(|m| m.flag).collect();
    names.extend(HDL64.iter().map(|(flag, _)| *flag));
    names.push(OUSTER);
    names
}

const OUSTER: &str = "ouster";
/// The HDL-64E's names, by generation (their firing times differ, and the packets do not say).
const HDL64: [(&str, Generation); 2] =
    [("hdl64e-s2", Generation::S2), ("hdl64e-s3", Generation::S3)];

/// A Velodyne's calibration YAML.
pub fn read_calibration(path: &Path) -> Result<Calibration, FileError> {
    let text = std::fs::read_to_string(path).map_err(|e| FileError::at(path, e.to_string()))?;
    Calibration::parse(&text).map_err(|e| FileError::at(path, format!("calibration: {e}")))
}

/// An Ouster unit from its metadata JSON.
pub fn read_metadata(path: &Path) -> Result<ouster::Sensor, FileError> {
    let text = std::fs::read_to_string(path).map_err(|e| FileError::at(path, e.to_string()))?;
    let meta = ouster::metadata::Metadata::parse(&text)
        .map_err(|e| FileError::at(path, format!("Ouster metadata: {e}")))?;
    Ok(ouster::Sensor::new(meta))
}

impl SensorHint {
    /// The Ouster unit its metadata names, if it does.
    pub fn ouster(&self) -> Option<&Arc<ouster::Sensor>> {
        self.ouster.as_ref()
    }

    /// From `--sensor`, `--metadata` and `--calibration`; for a capture, `beside` is its
    /// path, and an Ouster's metadata saved beside it with the same name (`drive.pcap`,
    /// `drive.json`) is found without `--metadata`.
    pub fn new(options: &PacketOptions, beside: Option<&Path>) -> Result<Self, FileError> {
        let (sensor, metadata) = (options.sensor.as_deref(), options.metadata.as_deref());
        let here = || beside.unwrap_or(Path::new("--sensor"));
        let generation = HDL64.iter().find(|(f, _)| Some(*f) == sensor).map(|g| g.1);
        let hdl64 =
            match (&options.calibration, generation) {
                (Some(path), Some(g)) => {
                    let h = Hdl64::new(g, &read_calibration(path)?)
                        .map_err(|e| FileError::at(path, e))?;
                    Some(Arc::new(h))
                }
                (Some(path), None) => return Err(FileError::at(
                    path,
                    "--calibration is an HDL-64E's: name its generation with --sensor hdl64e-s2 \
                     or hdl64e-s3 (their firing times differ)",
                )),
                (None, Some(_)) => {
                    return Err(FileError::at(
                        here(),
                        "an HDL-64E needs the unit's own calibration: give its YAML with \
                     --calibration FILE",
                    ))
                }
                (None, None) => None,
            };
        let velodyne = match sensor {
            None | Some(OUSTER) => None,
            Some(_) if hdl64.is_some() => None,
            Some(s) => Some(velodyne::model_named(s).ok_or_else(|| {
                FileError::at(
                    here(),
                    format!("--sensor {s}: not one of {}", sensor_names().join(", ")),
                )
            })?),
        };
        if let (Some(m), Some(path)) = (velodyne, metadata) {
            return Err(FileError::at(
                path,
                format!("--metadata is an Ouster's, but --sensor names a {}", m.name),
            ));
        }
        let ouster = match (metadata, beside) {
            (Some(path), _) => Some(read_metadata(path)?),
            (None, Some(capture)) if velodyne.is_none() && hdl64.is_none() => {
                let json = capture.with_extension("json");
                match read_metadata(&json) {
                    Ok(o) => {
                        log::info!("the Ouster metadata beside the capture: {}", json.display());
                        Some(o)
                    }
                    // Named an Ouster: the reason the file beside it is not its metadata.
                    Err(e) if sensor == Some(OUSTER) && json.exists() => return Err(e),
                    Err(_) => None,
                }
            }
            _ => None,
        };
        if sensor == Some(OUSTER) && ouster.is_none() {
            return Err(FileError::at(
                here(),
                "--sensor ouster: the beam angles are in the sensor's metadata JSON; give it \
                 with --metadata FILE",
            ));
        }
        Ok(Self {
            velodyne,
            hdl64,
            ouster: ouster.map(Arc::new),
        })
    }

    /// The size of the Ouster's lidar packets, when the hint is an Ouster's metadata.
    pub fn ouster_packet_bytes(&self) -> Option<usize> {
        self.ouster.as_ref().map(|o| o.packet_bytes())
    }

    /// The HDL-64E named, when it is.
    pub fn hdl64(&self) -> Option<&'static str> {
        self.hdl64.as_ref().map(|h| h.name())
    }
}

/// What a datagram says of the sensor: `Ok(Some(sensor))` for a data packet of a sensor this
/// reader decodes (the one the hint names, when it does), `Ok(None)` for anything else, and
/// an error for a sensor's packets that cannot be read (another model than named, an
/// HDL-64E, an Ouster's without its metadata).
pub fn identify(payload: &[u8], hint: &SensorHint) -> Result<Option<Sensor>, String> {
    if let Some(o) = &hint.ouster {
        return Ok(o.matches(payload).then(|| Sensor::Ouster(o.clone())));
    }
    if let Some(h) = &hint.hdl64 {
        return Ok(hdl64::sniff(payload).then(|| Sensor::Hdl64(h.clone())));
    }
    if let Some(product) = velodyne::sniff(payload) {
        return match (hint.velodyne, velodyne::model_of(product)) {
            (Some(n), Some(f)) if n.product_id != f.product_id => Err(format!(
                "--sensor {}: the packets are a {}'s",
                n.flag, f.name
            )),
            (Some(m), _) | (None, Some(m)) => Ok(Some(Sensor::Velodyne(m))),
            (None, None) => Err(format!(
                "Velodyne data packets of product {product:#04x}, a model this reader does not \
                 decode (it reads {}); name one with --sensor if it is one of them",
                sensor_names().join(", ")
            )),
        };
    }
    if hdl64::sniff(payload) {
        return Err(
            "HDL-64E packets: they need the unit's own calibration; give its YAML \
                    with --calibration FILE and its generation with --sensor hdl64e-s2 or \
                    hdl64e-s3"
                .to_string(),
        );
    }
    if let Some(what) = ouster::sniff(payload) {
        return Err(format!(
            "{what}: their beam angles are in the sensor's metadata JSON; give it with \
             --metadata FILE (a capture's FILE.json beside it is found by itself)"
        ));
    }
    Ok(None)
}

/// One sensor's packets to sweeps.
#[derive(Debug)]
pub struct SensorStream {
    decoding: Decoding,
    port: u16,
    sweeps: Sweeps,
    stats: StreamStats,
    /// An Ouster's IMU readings not taken yet ([`SensorStream::take_imu`]); `None`: its IMU
    /// packets are passed over ([`SensorStream::without_imu`]).
    imu: Option<Vec<ImuSample>>,
}

#[derive(Debug)]
enum Decoding {
    Velodyne(VelodyneDecoder),
    Ouster(Arc<ouster::Sensor>),
}

/// A decoder of Velodyne data packets: a model's factory tables, or an HDL-64E unit's
/// calibration.
#[derive(Debug)]
enum VelodyneDecoder {
    /// Boxed: its tables are 6.5 KB; an HDL-64E's are shared.
    Tables(Box<Decoder>),
    Hdl64(Arc<Hdl64>),
}

impl VelodyneDecoder {
    fn decode(
        &self,
        payload: &[u8],
        time_s: f64,
        sink: impl FnMut(velodyne::Firing),
    ) -> Result<velodyne::ReturnMode, velodyne::PacketError> {
        match self {
            VelodyneDecoder::Tables(d) => d.decode(payload, time_s, sink),
            VelodyneDecoder::Hdl64(h) => h.decode(payload, time_s, sink),
        }
    }

    fn packet_period_s(&self, mode: velodyne::ReturnMode) -> f64 {
        match self {
            VelodyneDecoder::Tables(d) => d.packet_period_s(mode),
            VelodyneDecoder::Hdl64(h) => h.packet_period_s(mode),
        }
    }
}

/// Datagrams this short on an Ouster's lidar port are its IMU's (when both share a port),
/// not damaged lidar packets.
const OUSTER_SMALL_BYTES: usize = 256;

impl SensorStream {
    /// The stream of `sensor`'s data packets sent to `port`, cut at `cut_deg` degrees
    /// (`None`: the sensor's [default](Sensor::default_cut_deg)).
    pub fn new(sensor: &Sensor, port: u16, cut_deg: Option<f64>) -> Self {
        let cut = cut_deg.unwrap_or_else(|| sensor.default_cut_deg());
        let (decoding, sweeps) = match sensor {
            Sensor::Velodyne(m) => (
                Decoding::Velodyne(VelodyneDecoder::Tables(Box::new(Decoder::new(m)))),
                Sweeps::new(cut),
            ),
            Sensor::Hdl64(h) => (
                Decoding::Velodyne(VelodyneDecoder::Hdl64(h.clone())),
                Sweeps::new(cut),
            ),
            Sensor::Ouster(o) => {
                // Columns are a whole step apart: a turn that starts or ends within a step
                // of the cut is whole.
                let step = 36_000 / u32::from(o.metadata().columns_per_frame) + 1;
                (
                    Decoding::Ouster(o.clone()),
                    Sweeps::new(cut).whole_within(step),
                )
            }
        };
        Self {
            decoding,
            port,
            sweeps,
            stats: StreamStats::default(),
            imu: Some(Vec::new()),
        }
    }

    /// The stream passing an Ouster's IMU packets over, uncounted (a second reading of a
    /// capture whose readings were kept the first time).
    pub fn without_imu(mut self) -> Self {
        self.imu = None;
        self
    }

    /// The IMU readings decoded since the last call (an Ouster's IMU packets), in the sensor
    /// frame ([`ouster::imu_packet`]).
    pub fn take_imu(&mut self) -> Vec<ImuSample> {
        self.imu.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// An Ouster's IMU datagram: decoded into the readings waiting, or counted as refused.
    fn ouster_imu(&mut self, o: &ouster::Sensor, payload: &[u8]) {
        let Some(imu) = &mut self.imu else { return };
        match ImuPacket::read(payload, &o.metadata().imu_to_sensor) {
            Ok(reading) => {
                self.stats.imu_packets += 1;
                imu.push(reading);
            }
            Err(_) => self.stats.bad_imu_packets += 1,
        }
    }

    /// The sensor's name.
    pub fn sensor(&self) -> String {
        match &self.decoding {
            Decoding::Velodyne(VelodyneDecoder::Tables(d)) => d.model().name.to_string(),
            Decoding::Velodyne(VelodyneDecoder::Hdl64(h)) => h.name().to_string(),
            Decoding::Ouster(o) => o.name(),
        }
    }

    /// A datagram sent to `port`, received at `time_s` (any clock within half an hour of the
    /// sensor's): the sweep it completed, if it did. An Ouster's IMU packets (to its IMU port,
    /// or short ones to its lidar port) are decoded for [`take_imu`](Self::take_imu); other
    /// ports' datagrams and a Velodyne's position packets are passed over.
    pub fn datagram(&mut self, port: u16, payload: &[u8], time_s: f64) -> Option<Sweep> {
        if let Decoding::Ouster(o) = &self.decoding {
            let imu_port = o
                .metadata()
                .udp_port_imu
                .unwrap_or(ouster::metadata::IMU_PORT);
            let short = port == self.port && payload.len() <= OUSTER_SMALL_BYTES;
            if port == imu_port && port != self.port || short {
                let o = o.clone();
                self.ouster_imu(&o, payload);
                return None;
            }
        }
        if port != self.port {
            return None;
        }
        let mut done = None;
        let sweeps = &mut self.sweeps;
        match &self.decoding {
            Decoding::Velodyne(decoder) => {
                if payload.len() == POSITION_PACKET_BYTES {
                    return None;
                }
                let Some(t) = velodyne::packet_time(payload, time_s) else {
                    self.stats.bad_packets += 1;
                    return None;
                };
                match decoder.decode(payload, t, |f| {
                    if let Some(s) = sweeps.push(f.point, f.time_s, f.azimuth) {
                        done = Some(s);
                    }
                }) {
                    Ok(mode) => {
                        self.stats.packets += 1;
                        sweeps.packet(t, decoder.packet_period_s(mode));
                    }
                    Err(_) => self.stats.bad_packets += 1,
                }
            }
            Decoding::Ouster(o) => {
                match o.decode(payload, |f| {
                    if let Some(s) = sweeps.push(f.point, f.time_s, f.azimuth) {
                        done = Some(s);
                    }
                }) {
                    Ok(t) => {
                        self.stats.packets += 1;
                        if let Some(t) = t {
                            sweeps.packet(t, o.packet_period_s());
                        }
                    }
                    Err(_) => self.stats.bad_packets += 1,
                }
            }
        }
        done
    }

    /// What it counted so far (the part turn being filled counted as partial only once
    /// [`finish`](Self::finish)ed).
    pub fn stats(&self) -> StreamStats {
        StreamStats {
            gaps: self.sweeps.gaps,
            partial_firings: self.sweeps.partial_firings,
            time_jumps: self.sweeps.time_jumps,
            ..self.stats
        }
    }

    /// Ends the stream: the turn being filled, if it is whole (it ends within a column of the
    /// cut; [`Sweeps::finish`]).
    pub fn finish(&mut self) -> Option<Sweep> {
        self.sweeps.finish()
    }
}
