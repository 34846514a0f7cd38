//! HDL-64E S2 and S3 data packets, decoded with the unit's own calibration
//! ([`super::calibration`]): no factory table fits every unit of the HDL-64E.
//!
//! Its packet is a VLP's size with blocks of either bank: a block flagged `FF EE` holds lasers
//! 0 to 31, one flagged `FF DD` lasers 32 to 63; the two banks fire together, so a firing is
//! two blocks and a packet six firings (three in dual-return mode, where the blocks come as
//! strongest upper, strongest lower, last upper, last lower; the packet has no return-mode
//! byte, so dual mode is told by block 0 and block 2 sharing an azimuth). The firing times
//! follow the manuals' tables: a firing every 48 us (S2) or 57.6 us (S3), within it lasers in
//! fours every 6 us (7.2 us) at 0, 1.26, 2.46 and 3.66 us (0, 1.3, 2.5 and 3.7 us).
//!
//! A point applies its laser's calibration as the S3 manual's formulas give it (and
//! velodyne_decoder does): the distance correction, two-point below 25.04 m (interpolated
//! from the near points 2.40 m along x and 1.93 m along y; z takes the mean of x's and y's),
//! then the horizontal offset across the beam and the vertical offset. Velodyne's ROS driver
//! applies the vertical offset along the laser's elevation instead, which moves points by up
//! to a few centimetres; docs/design.md §1.15 says which is followed and why.
//!
//! Nothing here allocates after construction or panics on a packet.

use super::calibration::Calibration;
use super::{
    cos_sin, Firing, PacketError, Return, ReturnMode, BLOCKS, BLOCK_BYTES, CHANNELS,
    DATA_PACKET_BYTES, DELTAS,
};

/// Which HDL-64E: they differ in their firing times.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Generation {
    /// S2 and S2.1.
    S2,
    /// S3.
    S3,
}

impl Generation {
    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Generation::S2 => "HDL-64E S2",
            Generation::S3 => "HDL-64E S3",
        }
    }

    /// Microseconds after its firing's first laser that laser `j` of a bank fires, and the
    /// time between firings.
    fn timing_us(self) -> (f64, f64, [f64; 4]) {
        match self {
            Generation::S2 => (48.0, 6.0, [0.0, 1.26, 2.46, 3.66]),
            Generation::S3 => (57.6, 7.2, [0.0, 1.3, 2.5, 3.7]),
        }
    }
}

/// A laser's calibration, as the decoding uses it (`f32`, as velodyne_decoder does, so that
/// the two agree to the micrometre).
#[derive(Debug, Clone, Copy, Default)]
struct Laser {
    cos_v: f32,
    sin_v: f32,
    cos_r: f32,
    sin_r: f32,
    dist: f32,
    dist_x: f32,
    dist_y: f32,
    vert: f32,
    horiz: f32,
    two_point: bool,
}

/// The lasers of an HDL-64E.
pub const LASERS: usize = 64;

/// An HDL-64E unit's decoder.
#[derive(Debug, Clone)]
pub struct Hdl64 {
    generation: Generation,
    lasers: [Laser; LASERS],
    resolution: f32,
    /// Per block and channel: the firing time after the packet's first (seconds, `f32`).
    timing: [[f32; CHANNELS]; BLOCKS],
    /// cos and sin of 0 to 2.55 degrees by hundredths: a laser's azimuth is its block's and a
    /// little more, so its cos and sin come from the block's by the angle-sum formulas.
    deltas: [[f64; 2]; DELTAS],
}

/// Whether `payload` is an HDL-64E data packet by its shape: its size, and every block
/// flagged `FF EE` or `FF DD` with both flags present.
pub fn sniff(payload: &[u8]) -> bool {
    if payload.len() != DATA_PACKET_BYTES {
        return false;
    }
    let flag = |b: usize| [payload[b * BLOCK_BYTES], payload[b * BLOCK_BYTES + 1]];
    (0..BLOCKS).all(|b| matches!(flag(b), [0xff, 0xee] | [0xff, 0xdd]))
        && (0..BLOCKS).any(|b| flag(b) == [0xff, 0xdd])
}

impl Hdl64 {
    /// The decoder of a `generation` unit with this calibration, which must have 64 lasers.
    pub fn new(generation: Generation, calibration: &Calibration) -> Result<Self, String> {
        if calibration.lasers.len() != LASERS {
            return Err(format!(
                "the calibration has {} lasers; an HDL-64E has {LASERS}",
                calibration.lasers.len()
            ));
        }
        let mut lasers = [Laser::default(); LASERS];
        for (out, c) in lasers.iter_mut().zip(&calibration.lasers) {
            let (v, r) = (c.vert_correction as f32, c.rot_correction as f32);
            *out = Laser {
                cos_v: v.cos(),
                sin_v: v.sin(),
                cos_r: r.cos(),
                sin_r: r.sin(),
                dist: c.dist_correction as f32,
                dist_x: c.dist_correction_x as f32,
                dist_y: c.dist_correction_y as f32,
                vert: c.vert_offset_correction as f32,
                horiz: c.horiz_offset_correction as f32,
                two_point: c.two_point(),
            };
        }
        let (firing, fours, pattern) = generation.timing_us();
        let timing = core::array::from_fn(|b| {
            core::array::from_fn(|j| {
                ((firing * (b / 2) as f64 + fours * (j / 4) as f64 + pattern[j % 4]) * 1e-6) as f32
            })
        });
        Ok(Self {
            generation,
            lasers,
            resolution: calibration.distance_resolution_m as f32,
            timing,
            deltas: core::array::from_fn(|d| cos_sin(d as u32)),
        })
    }

    /// Its name.
    pub fn name(&self) -> &'static str {
        self.generation.name()
    }

    /// Seconds from one packet's first firing to the next one's.
    pub fn packet_period_s(&self, mode: ReturnMode) -> f64 {
        let (firing, _, _) = self.generation.timing_us();
        let firings = if mode == ReturnMode::Dual { 3.0 } else { 6.0 };
        firings * firing * 1e-6
    }

    /// Decodes a data packet whose first firing was at `time_s`, handing each point with a
    /// return to `sink` in block and channel order. Returns the packet's return mode
    /// (strongest, or dual); a packet that is not an HDL-64E's is refused whole.
    pub fn decode(
        &self,
        payload: &[u8],
        time_s: f64,
        mut sink: impl FnMut(Firing),
    ) -> Result<ReturnMode, PacketError> {
        check_blocks(payload)?;
        let az = |b: usize| word(payload, b * BLOCK_BYTES + 2);
        let dual = az(0) == az(2);
        let turned = (i32::from(az(BLOCKS - 1)) - i32::from(az(0))).rem_euclid(36_000) as f32;
        let last = if dual { (BLOCKS - 1) / 2 } else { BLOCKS - 1 };
        let rate = turned / (self.timing[last][0] - self.timing[0][0]);
        for b in 0..BLOCKS {
            // Dual mode: blocks 0 and 1 of each four hold the strongest returns, 2 and 3 the
            // last ones of the same firing.
            if !(dual && b % 4 > 1) {
                self.decode_block(payload, b, dual, rate, time_s, &mut sink);
            }
        }
        Ok(if dual {
            ReturnMode::Dual
        } else {
            ReturnMode::Strongest
        })
    }

    /// Hands `sink` the firings of block `b` (with its last returns' block in dual mode),
    /// the sensor turning at `rate` (hundredths of a degree a second).
    #[inline]
    fn decode_block(
        &self,
        payload: &[u8],
        b: usize,
        dual: bool,
        rate: f32,
        time_s: f64,
        sink: &mut impl FnMut(Firing),
    ) {
        let channel = |b: usize, j: usize| {
            let at = b * BLOCK_BYTES + 4 + 3 * j;
            (word(payload, at), payload[at + 2])
        };
        let bank = if word(payload, b * BLOCK_BYTES) == 0xeeff {
            0
        } else {
            32
        };
        let (t0, row) = if dual {
            (self.timing[b / 4 * 2][0], b / 4 * 2 + b % 2)
        } else {
            (self.timing[b / 2 * 2][0], b)
        };
        let base = word(payload, b * BLOCK_BYTES + 2);
        let [cos_b, sin_b] = cos_sin(u32::from(base));
        for j in 0..CHANNELS {
            let strongest = channel(b, j);
            let last = if dual { channel(b + 2, j) } else { (0, 0) };
            if strongest.0 == 0 && last.0 == 0 {
                continue;
            }
            let time = self.timing[row][j];
            // Rounded as `lround` rounds, as the sensor reports azimuths.
            let turned = (f32::from(base) + rate * (time - t0) + 36_000.5) as u32 - 36_000;
            let [c, s] = match self.deltas.get((turned - u32::from(base)) as usize) {
                // cos(b + d) and sin(b + d).
                Some(&[cd, sd]) => [cos_b * cd - sin_b * sd, sin_b * cd + cos_b * sd],
                None => cos_sin(turned % 36_000),
            };
            let (c, s) = (c as f32, s as f32);
            let laser = bank + j;
            let time_s = time_s + f64::from(time);
            let mut emit = |(d, intensity): (u16, u8), ret: Return| {
                if d != 0 {
                    sink(Firing {
                        point: self.xyz(&self.lasers[laser], c, s, d),
                        time_s,
                        // The firing's azimuth, for cutting turns: both banks of a firing
                        // sweep the same angles, so a turn is cut between whole firings.
                        azimuth: base,
                        laser: laser as u8,
                        intensity,
                        ret,
                    });
                }
            };
            if !dual {
                emit(strongest, Return::Strongest);
            } else if strongest.0 == last.0 {
                emit(strongest, Return::Both);
            } else {
                emit(last, Return::Last);
                emit(strongest, Return::Strongest);
            }
        }
    }

    /// The point (sensor frame, metres) of laser `l` at the azimuth whose cos and sin are
    /// given, for a raw distance.
    #[inline(always)]
    fn xyz(&self, l: &Laser, cos_a: f32, sin_a: f32, raw: u16) -> [f32; 3] {
        // cos(a - r) and sin(a - r).
        let cos_rot = cos_a * l.cos_r + sin_a * l.sin_r;
        let sin_rot = sin_a * l.cos_r - cos_a * l.sin_r;
        let measured = f32::from(raw) * self.resolution;
        const FAR: f32 = 25.04;
        const NEAR_X: f32 = 2.40;
        const NEAR_Y: f32 = 1.93;
        const SPAN_X: f32 = 1.0 / (FAR - NEAR_X);
        const SPAN_Y: f32 = 1.0 / (FAR - NEAR_Y);
        // The two-point correction, computed for every point and weighed in by whether it
        // applies: near and far points mix in a scene, and a branch on it was mispredicted
        // often enough to cost more than the arithmetic.
        let xy = (measured + l.dist) * l.cos_v;
        let (xx, yy) = ((xy * sin_rot).abs(), (xy * cos_rot).abs());
        let (cx, cy) = ((xx - NEAR_X) * SPAN_X, (yy - NEAR_Y) * SPAN_Y);
        let near_x = cx * l.dist + (1.0 - cx) * l.dist_x;
        let near_y = cy * l.dist + (1.0 - cy) * l.dist_y;
        let w = f32::from(u8::from(l.two_point && measured < FAR));
        let dx = l.dist + w * (near_x - l.dist);
        let dy = l.dist + w * (near_y - l.dist);
        let dz = l.dist + w * ((near_x + near_y) / 2.0 - l.dist);
        // The manual's frame (y forward), then x forward, y left.
        let x = (measured + dx) * l.cos_v * sin_rot - l.horiz * cos_rot;
        let y = (measured + dy) * l.cos_v * cos_rot + l.horiz * sin_rot;
        let z = (measured + dz) * l.sin_v + l.vert;
        [y, -x, z]
    }
}

/// The little-endian 16-bit word at byte `at`.
#[inline(always)]
fn word(payload: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([payload[at], payload[at + 1]])
}

/// A data packet's size, and each block's flag and azimuth: an error names the first that is
/// not an HDL-64E's.
fn check_blocks(payload: &[u8]) -> Result<(), PacketError> {
    if payload.len() != DATA_PACKET_BYTES {
        return Err(PacketError::Size(payload.len()));
    }
    for b in 0..BLOCKS {
        if !matches!(word(payload, b * BLOCK_BYTES), 0xeeff | 0xddff) {
            return Err(PacketError::BlockFlag(b));
        }
        if word(payload, b * BLOCK_BYTES + 2) >= 36_000 {
            return Err(PacketError::Azimuth(b));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::calibration::{Calibration, LaserCorrection};
    use super::*;

    fn calibration(two_point: bool) -> Calibration {
        Calibration {
            distance_resolution_m: 0.002,
            lasers: (0..LASERS)
                .map(|i| LaserCorrection {
                    vert_correction: (-24.0 + 0.4 * i as f64).to_radians(),
                    rot_correction: 0.01,
                    dist_correction: 1.0,
                    dist_correction_x: if two_point { 1.1 } else { 0.0 },
                    dist_correction_y: if two_point { 1.05 } else { 0.0 },
                    vert_offset_correction: 0.2,
                    horiz_offset_correction: 0.026,
                })
                .collect(),
        }
    }

    /// A packet of six firings 0.2 degrees apart from `az0`, every channel at `d`.
    fn packet(az0: u16, d: u16, dual: bool) -> Vec<u8> {
        let mut p = vec![0u8; DATA_PACKET_BYTES];
        for b in 0..BLOCKS {
            let at = b * BLOCK_BYTES;
            p[at] = 0xff;
            p[at + 1] = if b % 2 == 0 { 0xee } else { 0xdd };
            let firing = if dual { b / 4 } else { b / 2 } as u16;
            p[at + 2..at + 4].copy_from_slice(&(az0 + 20 * firing).to_le_bytes());
            for j in 0..CHANNELS {
                p[at + 4 + 3 * j..at + 6 + 3 * j].copy_from_slice(&d.to_le_bytes());
            }
        }
        p
    }

    #[test]
    fn points_lie_at_the_corrected_distance_from_their_laser() {
        let h = Hdl64::new(Generation::S2, &calibration(false)).unwrap();
        let mut got = Vec::new();
        let mode = h.decode(&packet(9_000, 25_000, false), 1.0, |f| got.push(f));
        assert_eq!(mode, Ok(ReturnMode::Strongest));
        assert_eq!(got.len(), BLOCKS * CHANNELS);
        for f in &got {
            // Less its laser's height, the point is 50 m + 1 m from the origin (the offset
            // across the beam adds micrometres).
            let l = &h.lasers[usize::from(f.laser)];
            let p = [f.point[0], f.point[1], f.point[2] - l.vert];
            let r = p.iter().map(|v| v * v).sum::<f32>().sqrt();
            assert!((r - 51.0).abs() < 0.05, "{r}");
        }
        // Block 1 is the lower bank: lasers 32 to 63, firing with block 0.
        assert_eq!((got[0].laser, got[32].laser, got[64].laser), (0, 32, 0));
        assert_eq!(got[0].time_s, got[32].time_s);
        assert!((got[64].time_s - 1.0 - 48e-6).abs() < 1e-9);
        assert!((got[5].time_s - 1.0 - 7.26e-6).abs() < 1e-9);
        // Facing 90 degrees clockwise: toward -y.
        assert!(got[0].point[1] < -40.0, "{:?}", got[0].point);
        assert_eq!(h.packet_period_s(ReturnMode::Strongest), 288e-6);
    }

    #[test]
    fn dual_packets_and_two_point_corrections() {
        let h = Hdl64::new(Generation::S3, &calibration(true)).unwrap();
        let mut n = 0;
        assert_eq!(
            h.decode(&packet(100, 1_000, true), 0.0, |_| n += 1),
            Ok(ReturnMode::Dual)
        );
        // Equal returns: one point a laser a firing, three firings.
        assert_eq!(n, 3 * LASERS);
        // Near points take the two-point correction: 2 m + about 1.05 to 1.1 m.
        let mut near = Vec::new();
        h.decode(&packet(100, 1_000, false), 0.0, |f| near.push(f))
            .unwrap();
        let r = near[0].point.iter().map(|v| v * v).sum::<f32>().sqrt();
        assert!((2.9..3.4).contains(&r), "{r}");
    }

    #[test]
    fn bad_packets_and_calibrations_are_refused() {
        let h = Hdl64::new(Generation::S2, &calibration(false)).unwrap();
        let good = packet(0, 100, false);
        assert!(sniff(&good));
        assert_eq!(
            h.decode(&good[1..], 0.0, |_| panic!()),
            Err(PacketError::Size(1205))
        );
        let mut bad = good.clone();
        bad[100] = 0;
        assert!(!sniff(&bad));
        assert_eq!(
            h.decode(&bad, 0.0, |_| panic!()),
            Err(PacketError::BlockFlag(1))
        );
        let mut bad = good;
        bad[2..4].copy_from_slice(&36_000u16.to_le_bytes());
        assert_eq!(
            h.decode(&bad, 0.0, |_| panic!()),
            Err(PacketError::Azimuth(0))
        );
        let mut short = calibration(false);
        short.lasers.truncate(32);
        assert!(Hdl64::new(Generation::S2, &short)
            .unwrap_err()
            .contains("32 lasers"));
    }
}
