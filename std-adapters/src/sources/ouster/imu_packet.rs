//! An Ouster's IMU packets: the legacy IMU profile (`udp_profile_imu: LEGACY`, every firmware's
//! default), 48 bytes to port 7503 (the metadata's `udp_port_imu`), little-endian: the system,
//! accelerometer and gyro timestamps (u64 nanoseconds, the sensor's clock, as its lidar
//! packets' column timestamps), then the acceleration (three f32, in g) and the angular
//! velocity (three f32, degrees a second), x y z in the IMU's frame.
//!
//! [`ImuPacket::sample`] turns one into a reading the run takes: m/s² and rad/s (as Ouster's
//! SDK gives them), stamped at the gyro's time, turned into the sensor frame (the points'
//! frame) by the rotation of the metadata's `imu_to_sensor_transform`. Its translation, the
//! IMU's 1 to 2 cm lever arm, is left to `[imu] translation_m`. Nothing here panics on a
//! datagram: another size is refused, named ([`ImuPacketError`]).

use slamesh_core::imu::{ImuSample, GRAVITY_M_S2};

/// The legacy IMU packet's size.
pub const IMU_PACKET_BYTES: usize = 48;

/// One IMU packet, as it came.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuPacket {
    /// When the packet was made (ns, the sensor's clock).
    pub sys_ts: u64,
    /// When the accelerometer was read (ns).
    pub accel_ts: u64,
    /// When the gyro was read (ns).
    pub gyro_ts: u64,
    /// Acceleration (g), the IMU's axes.
    pub accel_g: [f32; 3],
    /// Angular velocity (degrees a second), the IMU's axes.
    pub gyro_deg_s: [f32; 3],
}

/// Why a datagram is not an IMU packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImuPacketError {
    /// Not the legacy profile's 48 bytes.
    Size(usize),
}

impl core::fmt::Display for ImuPacketError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ImuPacketError::Size(n) => write!(
                f,
                "{n} bytes, not a legacy IMU packet's {IMU_PACKET_BYTES} (another \
                 udp_profile_imu is not read)"
            ),
        }
    }
}

impl ImuPacket {
    /// Reads a datagram's payload.
    pub fn decode(payload: &[u8]) -> Result<Self, ImuPacketError> {
        let bytes: &[u8; IMU_PACKET_BYTES] = payload
            .try_into()
            .map_err(|_| ImuPacketError::Size(payload.len()))?;
        let u64_at = |o: usize| {
            u64::from_le_bytes([
                bytes[o],
                bytes[o + 1],
                bytes[o + 2],
                bytes[o + 3],
                bytes[o + 4],
                bytes[o + 5],
                bytes[o + 6],
                bytes[o + 7],
            ])
        };
        let f32_at =
            |o: usize| f32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
        Ok(Self {
            sys_ts: u64_at(0),
            accel_ts: u64_at(8),
            gyro_ts: u64_at(16),
            accel_g: [f32_at(24), f32_at(28), f32_at(32)],
            gyro_deg_s: [f32_at(36), f32_at(40), f32_at(44)],
        })
    }

    /// A datagram's reading in the sensor frame ([`decode`](Self::decode), then
    /// [`sample`](Self::sample)).
    pub fn read(payload: &[u8], imu_to_sensor: &[f64; 16]) -> Result<ImuSample, ImuPacketError> {
        Ok(Self::decode(payload)?.sample(imu_to_sensor))
    }

    /// Acceleration (m/s²), the IMU's axes.
    pub fn accel_m_s2(&self) -> [f64; 3] {
        self.accel_g.map(|g| f64::from(g) * GRAVITY_M_S2)
    }

    /// Angular velocity (rad/s), the IMU's axes.
    pub fn gyro_rad_s(&self) -> [f64; 3] {
        self.gyro_deg_s.map(|d| f64::from(d).to_radians())
    }

    /// The reading in the sensor frame: turned by the rotation of `imu_to_sensor` (row-major
    /// 4x4, the metadata's), stamped at the gyro's time (seconds).
    pub fn sample(&self, imu_to_sensor: &[f64; 16]) -> ImuSample {
        let m = imu_to_sensor;
        let turn = |v: [f64; 3]| -> [f64; 3] {
            std::array::from_fn(|r| m[4 * r] * v[0] + m[4 * r + 1] * v[1] + m[4 * r + 2] * v[2])
        };
        ImuSample {
            stamp: self.gyro_ts as f64 / 1e9,
            gyro: turn(self.gyro_rad_s()),
            accel: turn(self.accel_m_s2()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_packet_reads_field_by_field_and_other_sizes_are_refused() {
        let mut p = Vec::new();
        for ts in [10u64, 20, 30] {
            p.extend(ts.to_le_bytes());
        }
        for v in [0.0f32, 0.5, 1.0, 90.0, -180.0, 0.0] {
            p.extend(v.to_le_bytes());
        }
        let packet = ImuPacket::decode(&p).unwrap();
        assert_eq!(
            (packet.sys_ts, packet.accel_ts, packet.gyro_ts),
            (10, 20, 30)
        );
        assert_eq!(packet.accel_g, [0.0, 0.5, 1.0]);
        // A sensor turned upside down about x: its z reads down in the sensor frame.
        let flip = [
            1.0, 0.0, 0.0, 6.0, 0.0, -1.0, 0.0, -11.0, 0.0, 0.0, -1.0, 7.0, 0.0, 0.0, 0.0, 1.0,
        ];
        let s = packet.sample(&flip);
        assert_eq!(s.stamp, 30e-9);
        assert_eq!(s.accel, [0.0, -0.5 * GRAVITY_M_S2, -GRAVITY_M_S2]);
        let half = std::f64::consts::FRAC_PI_2;
        assert_eq!(s.gyro, [half, 2.0 * half, -0.0]);
        assert_eq!(ImuPacket::decode(&p[..47]), Err(ImuPacketError::Size(47)));
        p.push(0);
        assert_eq!(ImuPacket::decode(&p), Err(ImuPacketError::Size(49)));
    }
}
