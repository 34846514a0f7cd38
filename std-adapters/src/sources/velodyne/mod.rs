//! Velodyne data packets decoded to points with each one's firing time: the VLP-16, the Puck
//! Hi-Res, the VLP-32C and the HDL-32E, single and dual return, with their factory tables
//! ([`tables`]); and the HDL-64E S2 and S3 with the unit's own calibration ([`hdl64`],
//! [`calibration`]).
//!
//! A data packet is 1 206 bytes: twelve blocks of a 2-byte flag (`FF EE`), the block's azimuth
//! (hundredths of a degree) and 32 channels of a 2-byte distance and a 1-byte reflectivity;
//! then the time of its first firing (microseconds past the hour), the return mode and the
//! model's product byte. Each channel's firing time comes from the model's timing table
//! ([`tables::Timing`]); its azimuth is the block's advanced by the packet's rotation rate over
//! that time, rounded to the hundredth of a degree as the sensor reports azimuths (the way
//! other decoders do it, so that their points and ours agree to the micrometre). The point, in
//! the sensor frame (x forward, y left, z up, metres):
//! `x = d cos(el) cos(az - off)`, `y = -d cos(el) sin(az - off)`, `z = d sin(el) + v`, with the
//! laser's elevation `el`, azimuth offset `off` and vertical offset `v`.
//!
//! Nothing here allocates or panics: a packet is checked whole before a point of it is handed
//! out, and a bad one is refused with what is wrong ([`PacketError`]). No `std`: firmware
//! could use it as it is.

pub mod calibration;
pub mod hdl64;
pub mod tables;

use tables::{Model, MODELS};

/// Bytes of a data packet.
pub const DATA_PACKET_BYTES: usize = 1206;
/// Bytes of a position (GPS) packet, which carries no points.
pub const POSITION_PACKET_BYTES: usize = 512;
/// The port data packets go to unless the sensor is set otherwise.
pub const DATA_PORT: u16 = 2368;
const BLOCKS: usize = 12;
const CHANNELS: usize = 32;
const BLOCK_BYTES: usize = 100;

/// Why a packet was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PacketError {
    /// Not 1 206 bytes.
    Size(usize),
    /// A block's flag is not `FF EE` (a different model, such as an HDL-64E, or damage).
    BlockFlag(usize),
    /// A block's azimuth is 360 degrees or more.
    Azimuth(usize),
    /// The product byte names another model than the one decoding.
    Product(u8),
    /// A return mode byte that is none of strongest, last and dual.
    ReturnMode(u8),
}

impl core::fmt::Display for PacketError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PacketError::Size(n) => {
                write!(f, "{n} bytes, not a {DATA_PACKET_BYTES}-byte data packet")
            }
            PacketError::BlockFlag(b) => write!(f, "block {b} does not start with FF EE"),
            PacketError::Azimuth(b) => write!(f, "block {b}'s azimuth is 360 degrees or more"),
            PacketError::Product(p) => write!(f, "product byte {p:#04x} is another model's"),
            PacketError::ReturnMode(m) => write!(f, "return mode byte {m:#04x} is unknown"),
        }
    }
}

/// Which return a point is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Return {
    /// The strongest (single-return mode, or dual mode's strongest).
    Strongest,
    /// The last.
    Last,
    /// Dual mode, when the strongest is the last.
    Both,
}

/// One decoded point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Firing {
    /// Sensor-frame position (metres).
    pub point: [f32; 3],
    /// Firing time (seconds, the packet's time base).
    pub time_s: f64,
    /// Azimuth (hundredths of a degree, 0 to 35 999): the channel's own; an HDL-64E's, its
    /// firing's (both of its banks sweep the same angles in a firing).
    pub azimuth: u16,
    /// Channel (laser index in the model's table).
    pub laser: u8,
    /// Reflectivity.
    pub intensity: u8,
    /// Which return.
    pub ret: Return,
}

/// The return mode of a packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReturnMode {
    /// One return a firing, the strongest.
    Strongest,
    /// One return a firing, the last.
    Last,
    /// Two blocks a firing: the last, then the strongest.
    Dual,
}

/// The model named by a packet's product byte, if this reader decodes it.
pub fn model_of(product_id: u8) -> Option<&'static Model> {
    MODELS.iter().find(|m| m.product_id == product_id)
}

/// The model named by `--sensor`'s value.
pub fn model_named(flag: &str) -> Option<&'static Model> {
    MODELS.iter().find(|m| m.flag == flag)
}

/// Whether `payload` looks like a Velodyne data packet (size and block flags), and its
/// product byte.
pub fn sniff(payload: &[u8]) -> Option<u8> {
    if payload.len() != DATA_PACKET_BYTES {
        return None;
    }
    let flags_ok =
        (0..BLOCKS).all(|b| payload[b * BLOCK_BYTES..b * BLOCK_BYTES + 2] == [0xff, 0xee]);
    flags_ok.then(|| payload[DATA_PACKET_BYTES - 1])
}

/// The packet's first-firing time: its microseconds past the hour, placed in the hour of
/// `reference_s` (any clock within half an hour of the sensor's, such as the capture's).
pub fn packet_time(payload: &[u8], reference_s: f64) -> Option<f64> {
    let b = payload.get(1200..1204)?;
    let toh = f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])) * 1e-6;
    let hour = (reference_s / 3600.0).floor() * 3600.0;
    let t = hour + toh;
    Some(if t > reference_s + 1800.0 {
        t - 3600.0
    } else if t < reference_s - 1800.0 {
        t + 3600.0
    } else {
        t
    })
}

/// A model's decoder: its tables as the decoding uses them.
#[derive(Debug, Clone)]
pub struct Decoder {
    model: &'static Model,
    /// Per laser: cos and sin of the elevation, cos and sin of the azimuth offset, the vertical
    /// offset.
    lasers: [[f32; 5]; CHANNELS],
    /// Per firing block and channel: the firing time (seconds, as `f32`, as the rounding of the
    /// azimuth is done).
    timing: [[f32; CHANNELS]; BLOCKS],
    /// Per channel: its firing time after its block's first (seconds, as `f32`; the same in
    /// every block) and its laser.
    channels: [(f32, u8); CHANNELS],
    /// cos and sin of 0 to 2.55 degrees by hundredths: a channel's azimuth is its block's and
    /// a little more, so its cos and sin come from the block's by the angle-sum formulas.
    deltas: [[f64; 2]; DELTAS],
}

/// Azimuth steps (hundredths of a degree) past a block's that [`Decoder`] tabulates.
const DELTAS: usize = 256;

/// cos and sin of an azimuth in hundredths of a degree.
fn cos_sin(hundredths: u32) -> [f64; 2] {
    let a = (f64::from(hundredths) * 0.01).to_radians();
    [a.cos(), a.sin()]
}

impl Decoder {
    /// A decoder for `model`.
    pub fn new(model: &'static Model) -> Self {
        let mut lasers = [[0.0f32; 5]; CHANNELS];
        for (i, (l, out)) in model.lasers.iter().zip(lasers.iter_mut()).enumerate() {
            let el = l.elevation_deg.to_radians() as f32;
            let off = l.azimuth_offset_deg.to_radians() as f32;
            *out = [
                el.cos(),
                el.sin(),
                off.cos(),
                off.sin(),
                model.vertical_offset_m(i) as f32,
            ];
        }
        let mut timing = [[0.0f32; CHANNELS]; BLOCKS];
        for (k, row) in timing.iter_mut().enumerate() {
            for (j, t) in row.iter_mut().enumerate() {
                *t = (model.timing.offset_us(k, j) * 1e-6) as f32;
            }
        }
        let n = model.lasers.len().max(1);
        let channels = core::array::from_fn(|j| (timing[0][j] - timing[0][0], (j % n) as u8));
        Self {
            model,
            lasers,
            timing,
            channels,
            deltas: core::array::from_fn(|d| cos_sin(d as u32)),
        }
    }

    /// The model.
    pub fn model(&self) -> &'static Model {
        self.model
    }

    /// Seconds from one packet's first firing to the next one's, in a return mode.
    pub fn packet_period_s(&self, mode: ReturnMode) -> f64 {
        let firings = if mode == ReturnMode::Dual {
            BLOCKS / 2
        } else {
            BLOCKS
        };
        self.model.timing.offset_us(firings, 0) * 1e-6
    }

    /// Decodes a data packet whose first firing was at `time_s` ([`packet_time`]), handing
    /// each point with a return to `sink` in firing order. Returns the packet's return mode;
    /// a packet that is not this model's is refused whole.
    pub fn decode(
        &self,
        payload: &[u8],
        time_s: f64,
        mut sink: impl FnMut(Firing),
    ) -> Result<ReturnMode, PacketError> {
        let mode = self.check(payload)?;
        let az = |b: usize| {
            u16::from_le_bytes([payload[b * BLOCK_BYTES + 2], payload[b * BLOCK_BYTES + 3]])
        };
        let dual = mode == ReturnMode::Dual;
        let firings = if dual { BLOCKS / 2 } else { BLOCKS };
        // The packet's rotation rate (hundredths of a degree a second), from its first and
        // last blocks' azimuths over the time between their firings.
        let turned = (i32::from(az(BLOCKS - 1)) - i32::from(az(0))).rem_euclid(36_000) as f32;
        let duration = self.timing[firings - 1][0] - self.timing[0][0];
        let rate = turned / duration;
        let channel = |b: usize, j: usize| {
            let at = b * BLOCK_BYTES + 4 + 3 * j;
            (
                u16::from_le_bytes([payload[at], payload[at + 1]]),
                payload[at + 2],
            )
        };
        let step = if dual { 2 } else { 1 };
        for b in (0..BLOCKS).step_by(step) {
            let k = b / step;
            let t0 = self.timing[k][0];
            let base = az(b);
            let [cos_b, sin_b] = cos_sin(u32::from(base));
            for j in 0..CHANNELS {
                let (first, second) = if dual {
                    (channel(b, j), channel(b + 1, j))
                } else {
                    (channel(b, j), (0, 0))
                };
                if first.0 == 0 && second.0 == 0 {
                    continue; // no return
                }
                let (dt, laser) = self.channels[j];
                // Rounded half away from zero, as `lround` does: the value is positive, and adding
                // a half is exact at this magnitude (a `round` call costs more than the rest).
                let turned = (base as f32 + rate * dt + 36_000.5) as u32 - 36_000;
                let delta = turned - u32::from(base);
                let azimuth = if turned >= 36_000 {
                    turned - 36_000
                } else {
                    turned
                };
                let cs = match self.deltas.get(delta as usize) {
                    // cos(b + d) and sin(b + d).
                    Some(&[cd, sd]) => [cos_b * cd - sin_b * sd, sin_b * cd + cos_b * sd],
                    None => cos_sin(azimuth),
                };
                let azimuth = azimuth as u16;
                let laser = usize::from(laser);
                let time = time_s + f64::from(t0 + dt);
                let mut emit = |(d, i): (u16, u8), ret: Return| {
                    if d != 0 {
                        sink(self.point(laser, azimuth, cs, d, i, time, ret));
                    }
                };
                if !dual {
                    let ret = if mode == ReturnMode::Last {
                        Return::Last
                    } else {
                        Return::Strongest
                    };
                    emit(first, ret);
                } else if first.0 == second.0 {
                    // The last return is the strongest.
                    emit(second, Return::Both);
                } else {
                    emit(first, Return::Last);
                    emit(second, Return::Strongest);
                }
            }
        }
        Ok(mode)
    }

    /// Checks a whole packet before any of it is decoded.
    fn check(&self, payload: &[u8]) -> Result<ReturnMode, PacketError> {
        if payload.len() != DATA_PACKET_BYTES {
            return Err(PacketError::Size(payload.len()));
        }
        for b in 0..BLOCKS {
            let at = b * BLOCK_BYTES;
            if payload[at..at + 2] != [0xff, 0xee] {
                return Err(PacketError::BlockFlag(b));
            }
            if u16::from_le_bytes([payload[at + 2], payload[at + 3]]) >= 36_000 {
                return Err(PacketError::Azimuth(b));
            }
        }
        let product = payload[DATA_PACKET_BYTES - 1];
        // Old HDL-32E firmware leaves both factory bytes zero.
        if product != self.model.product_id && !(product == 0 && self.model.flag == "hdl32") {
            return Err(PacketError::Product(product));
        }
        match payload[DATA_PACKET_BYTES - 2] {
            0x37 | 0x00 => Ok(ReturnMode::Strongest),
            0x38 => Ok(ReturnMode::Last),
            0x39 => Ok(ReturnMode::Dual),
            other => Err(PacketError::ReturnMode(other)),
        }
    }

    /// The point of channel `laser` at `azimuth`, whose cos and sin are given.
    #[allow(clippy::too_many_arguments)]
    fn point(
        &self,
        laser: usize,
        azimuth: u16,
        [cos_a, sin_a]: [f64; 2],
        raw: u16,
        intensity: u8,
        time_s: f64,
        ret: Return,
    ) -> Firing {
        let [cos_el, sin_el, cos_off, sin_off, v] = self.lasers[laser];
        let (sin_a, cos_a) = (sin_a as f32, cos_a as f32);
        // cos(a - off) and sin(a - off).
        let cos_r = cos_a * cos_off + sin_a * sin_off;
        let sin_r = sin_a * cos_off - cos_a * sin_off;
        let d = f32::from(raw) * self.model.distance_unit_m as f32;
        let xy = d * cos_el;
        Firing {
            point: [xy * cos_r, -xy * sin_r, d * sin_el + v],
            time_s,
            azimuth,
            laser: laser as u8,
            intensity,
            ret,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A packet of `model` whose block `b` has azimuth `az0 + 20 b` and every channel the
    /// distance `d` (raw units).
    pub(crate) fn packet(product: u8, mode: u8, az0: u16, d: u16) -> Vec<u8> {
        let mut p = vec![0u8; DATA_PACKET_BYTES];
        for b in 0..BLOCKS {
            let at = b * BLOCK_BYTES;
            p[at] = 0xff;
            p[at + 1] = 0xee;
            let az = (az0 + 20 * b as u16) % 36_000;
            p[at + 2..at + 4].copy_from_slice(&az.to_le_bytes());
            for j in 0..CHANNELS {
                let c = at + 4 + 3 * j;
                p[c..c + 2].copy_from_slice(&d.to_le_bytes());
                p[c + 2] = 100;
            }
        }
        p[1200..1204].copy_from_slice(&1_000_000u32.to_le_bytes());
        p[1204] = mode;
        p[1205] = product;
        p
    }

    #[test]
    fn a_vlp16_packet_decodes_to_its_lasers_angles_and_times() {
        let m = model_named("vlp16").unwrap();
        let dec = Decoder::new(m);
        let p = packet(0x22, 0x37, 9_000, 5_000); // 10 m at 90 degrees
        let mut got = Vec::new();
        assert_eq!(
            dec.decode(&p, 0.0, |f| got.push(f)),
            Ok(ReturnMode::Strongest)
        );
        assert_eq!(got.len(), BLOCKS * CHANNELS);
        // Channel 0, laser 0: -15 degrees, at 90 degrees azimuth: towards -y.
        let f = got[0];
        assert!(
            (f.point[0]).abs() < 1e-4
                && (f.point[1] + 10.0 * 15f32.to_radians().cos()).abs() < 1e-4
        );
        let v = 0.04191 * 15f64.to_radians().tan();
        assert!((f64::from(f.point[2]) - (-10.0 * 15f64.to_radians().sin() + v)).abs() < 1e-5);
        // The second sequence of block 0 fires 55.296 us later, and block 1 110.592 us later.
        assert!((got[16].time_s - 55.296e-6).abs() < 1e-9);
        assert!((got[32].time_s - 110.592e-6).abs() < 1e-9);
        assert_eq!(got[1].laser, 1);
        // The azimuth advances within a block at the packet's rate: 20 hundredths a block.
        assert_eq!(got[16].azimuth, 9_010);
    }

    #[test]
    fn bad_packets_are_refused_whole() {
        let dec = Decoder::new(model_named("hdl32").unwrap());
        let good = packet(0x21, 0x39, 100, 1_000);
        let mut n = 0;
        assert_eq!(dec.decode(&good, 0.0, |_| n += 1), Ok(ReturnMode::Dual));
        // Dual: equal returns give one point each.
        assert_eq!(n, BLOCKS / 2 * CHANNELS);
        assert_eq!(
            dec.decode(&good[..1205], 0.0, |_| {}),
            Err(PacketError::Size(1205))
        );
        let mut bad = good.clone();
        bad[300] = 0;
        assert_eq!(
            dec.decode(&bad, 0.0, |_| panic!()),
            Err(PacketError::BlockFlag(3))
        );
        let mut bad = good.clone();
        bad[1205] = 0x22;
        assert_eq!(
            dec.decode(&bad, 0.0, |_| panic!()),
            Err(PacketError::Product(0x22))
        );
        let mut bad = good.clone();
        bad[1204] = 0x40;
        assert_eq!(
            dec.decode(&bad, 0.0, |_| panic!()),
            Err(PacketError::ReturnMode(0x40))
        );
        let mut bad = good;
        bad[2..4].copy_from_slice(&40_000u16.to_le_bytes());
        assert_eq!(
            dec.decode(&bad, 0.0, |_| panic!()),
            Err(PacketError::Azimuth(0))
        );
    }

    #[test]
    fn packet_times_take_the_hour_of_a_nearby_clock() {
        let p = packet(0x22, 0x37, 0, 0); // 1 s past the hour
        let hour = 3600.0 * 400_000.0;
        assert_eq!(packet_time(&p, hour + 10.0), Some(hour + 1.0));
        // The clock just before the hour: the packet belongs to the next one.
        assert_eq!(packet_time(&p, hour - 5.0), Some(hour + 1.0));
    }
}
