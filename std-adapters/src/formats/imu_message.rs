//! `sensor_msgs/Imu` messages as recordings hold them: ROS 1's packed little-endian
//! serialisation and ROS 2's CDR (either byte order, with its 4-byte encapsulation header).
//!
//! Only the header stamp, the frame and the two rates are read: the orientation estimate and
//! the covariances are passed over. A message too short for its layout, or with a frame name
//! longer than the message, is an error with the reason; never a panic.

use slamesh_core::imu::ImuSample;

/// One decoded message.
#[derive(Debug, Clone, PartialEq)]
pub struct ImuMessage {
    /// The reading: the header stamp (seconds), the angular velocity and linear acceleration.
    pub reading: ImuSample,
    /// The header's frame.
    pub frame_id: String,
}

/// Doubles after the header: orientation (4), its covariance (9), angular velocity (3), its
/// covariance (9), linear acceleration (3), its covariance (9).
const DOUBLES: usize = 4 + 9 + 3 + 9 + 3 + 9;
/// Where the angular velocity and the linear acceleration start among them.
const GYRO_AT: usize = 13;
const ACCEL_AT: usize = 25;

/// Why an IMU message could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ImuMessageError {
    /// The message (`len` bytes) ends inside `what`, which starts at byte `at`.
    Short {
        /// The message's length.
        len: usize,
        /// The field.
        what: &'static str,
        /// Where it starts.
        at: usize,
    },
    /// A CDR encapsulation (its first two bytes) that is neither big- nor little-endian CDR.
    Encapsulation([u8; 2]),
    /// Too short (this many bytes) for a CDR header.
    NoHeader(usize),
}

impl std::fmt::Display for ImuMessageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ImuMessageError::Short { len, what, at } => {
                write!(f, "{len} bytes, too short for its {what} at byte {at}")
            }
            ImuMessageError::Encapsulation(h) => {
                write!(f, "CDR encapsulation {h:?} is neither CDR_BE nor CDR_LE")
            }
            ImuMessageError::NoHeader(len) => write!(f, "{len} bytes, too short for a CDR header"),
        }
    }
}

impl std::error::Error for ImuMessageError {}

/// A little reader over a message's bytes.
struct Bytes<'a> {
    data: &'a [u8],
    at: usize,
    big: bool,
}

impl<'a> Bytes<'a> {
    fn take(&mut self, n: usize, what: &'static str) -> Result<&'a [u8], ImuMessageError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.data.len());
        let Some(end) = end else {
            return Err(ImuMessageError::Short {
                len: self.data.len(),
                what,
                at: self.at,
            });
        };
        let s = &self.data[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u32(&mut self, what: &'static str) -> Result<u32, ImuMessageError> {
        let b: [u8; 4] = self.take(4, what)?.try_into().unwrap_or_default();
        Ok(if self.big {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        })
    }

    fn f64(&mut self, what: &'static str) -> Result<f64, ImuMessageError> {
        let b: [u8; 8] = self.take(8, what)?.try_into().unwrap_or_default();
        Ok(if self.big {
            f64::from_be_bytes(b)
        } else {
            f64::from_le_bytes(b)
        })
    }

    /// Skips to a multiple of `n` counted from `from` (CDR aligns from the body's start).
    fn align(&mut self, n: usize, from: usize) {
        let rel = self.at - from;
        self.at += (n - rel % n) % n;
    }

    fn text(&mut self) -> Result<String, ImuMessageError> {
        let n = self.u32("frame_id's length")? as usize;
        let s = self.take(n, "frame_id")?;
        Ok(String::from_utf8_lossy(s)
            .trim_end_matches('\0')
            .to_string())
    }
}

/// The stamp, rates and frame after the header's frame name.
fn rest(
    b: &mut Bytes<'_>,
    sec: f64,
    nsec: u32,
    frame_id: String,
) -> Result<ImuMessage, ImuMessageError> {
    let mut v = [0.0; DOUBLES];
    for slot in &mut v {
        *slot = b.f64("rates")?;
    }
    let three = |k: usize| [v[k], v[k + 1], v[k + 2]];
    Ok(ImuMessage {
        reading: ImuSample {
            stamp: sec + f64::from(nsec) * 1e-9,
            gyro: three(GYRO_AT),
            accel: three(ACCEL_AT),
        },
        frame_id,
    })
}

/// A ROS 1 message.
pub fn parse_ros1(data: &[u8]) -> Result<ImuMessage, ImuMessageError> {
    let mut b = Bytes {
        data,
        at: 0,
        big: false,
    };
    b.u32("header's seq")?;
    let sec = b.u32("stamp")?;
    let nsec = b.u32("stamp")?;
    let frame = b.text()?;
    rest(&mut b, f64::from(sec), nsec, frame)
}

/// A ROS 2 message: the CDR encapsulation header, then the body.
pub fn parse_cdr(data: &[u8]) -> Result<ImuMessage, ImuMessageError> {
    let big = match data.get(..2) {
        Some([0, 0]) => true,
        Some([0, 1]) => false,
        Some(&[a, b]) => return Err(ImuMessageError::Encapsulation([a, b])),
        _ => return Err(ImuMessageError::NoHeader(data.len())),
    };
    let mut b = Bytes { data, at: 4, big };
    let sec = b.u32("stamp")? as i32;
    let nsec = b.u32("stamp")?;
    let frame = b.text()?;
    b.align(8, 4);
    rest(&mut b, f64::from(sec), nsec, frame)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The doubles of a message: orientation, covariances zero, the rates as given.
    fn doubles(gyro: [f64; 3], accel: [f64; 3]) -> Vec<f64> {
        let mut v = vec![0.0; DOUBLES];
        v[3] = 1.0;
        v[GYRO_AT..GYRO_AT + 3].copy_from_slice(&gyro);
        v[ACCEL_AT..ACCEL_AT + 3].copy_from_slice(&accel);
        v
    }

    #[test]
    fn reads_ros1_and_cdr_in_both_byte_orders() {
        let (gyro, accel) = ([0.1, -0.2, 0.3], [0.5, 0.25, 9.81]);
        let mut ros1 = Vec::new();
        for w in [7u32, 1_317_000_000, 250_000_000, 3] {
            ros1.extend_from_slice(&w.to_le_bytes());
        }
        ros1.extend_from_slice(b"imu");
        for d in doubles(gyro, accel) {
            ros1.extend_from_slice(&d.to_le_bytes());
        }
        let m = parse_ros1(&ros1).unwrap();
        assert_eq!((m.reading.gyro, m.reading.accel), (gyro, accel));
        assert!((m.reading.stamp - 1_317_000_000.25).abs() < 1e-6);
        assert_eq!(m.frame_id, "imu");
        for big in [false, true] {
            let w4 = |v: u32| {
                if big {
                    v.to_be_bytes()
                } else {
                    v.to_le_bytes()
                }
            };
            let mut cdr = vec![0, u8::from(!big), 0, 0];
            cdr.extend_from_slice(&w4(1_317_000_000));
            cdr.extend_from_slice(&w4(250_000_000));
            cdr.extend_from_slice(&w4(4));
            cdr.extend_from_slice(b"imu\0");
            // The body is 16 bytes so far: aligned to 8 already.
            for d in doubles(gyro, accel) {
                cdr.extend_from_slice(&if big {
                    d.to_be_bytes()
                } else {
                    d.to_le_bytes()
                });
            }
            let m = parse_cdr(&cdr).unwrap();
            assert_eq!(
                (m.reading.gyro, m.reading.accel, m.frame_id.as_str()),
                (gyro, accel, "imu")
            );
        }
    }

    #[test]
    fn malformed_messages_are_errors_with_their_reason() {
        let e = parse_ros1(&[0; 10]).unwrap_err();
        let short = ImuMessageError::Short {
            len: 10,
            what: "stamp",
            at: 8,
        };
        assert_eq!(e, short);
        assert_eq!(e.to_string(), "10 bytes, too short for its stamp at byte 8");
        let mut long_name = vec![0u8; 12];
        long_name.extend_from_slice(&1000u32.to_le_bytes());
        assert!(parse_ros1(&long_name)
            .unwrap_err()
            .to_string()
            .contains("frame_id"));
        let e = parse_cdr(&[1, 2, 0, 0]).unwrap_err();
        assert_eq!(e, ImuMessageError::Encapsulation([1, 2]));
        assert!(e.to_string().contains("neither CDR_BE nor CDR_LE"), "{e}");
        assert_eq!(parse_cdr(&[0]).unwrap_err(), ImuMessageError::NoHeader(1));
        let mut short = vec![0, 1, 0, 0];
        short.extend_from_slice(&[0; 12]);
        assert!(parse_cdr(&short)
            .unwrap_err()
            .to_string()
            .contains("too short for its rates"));
    }
}
