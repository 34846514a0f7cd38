//! `points`: `sensor_msgs/PointCloud2` messages as the DDS reader hands them over (their CDR
//! body, in either byte order), decoded by the recordings' own decoder
//! ([`crate::formats::pointcloud2`]: every field layout it takes) into scans for the run.
//!
//! A message that cannot be a scan is refused with a sentence ([`Refused`]): malformed (a
//! `point_step` smaller than its fields, `data` shorter than `width * height * point_step`,
//! no x, y or z), empty (no point left once NaN and no-return points are dropped), or from
//! another frame than the scans before it.

use crate::formats::pointcloud2::Cloud;
use crate::sources::feed::TimedScan;
use rustdds::no_key::{Decode, DefaultDecoder, DeserializerAdapter};
use rustdds::RepresentationIdentifier;
use std::time::Instant;

/// A message's CDR body as it came, and its byte order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawMessage {
    /// Big-endian (the CDR header's `CDR_BE`).
    pub big_endian: bool,
    /// The bytes after the 4-byte CDR header.
    pub body: Vec<u8>,
}

impl crate::formats::ros_messages::Typed for RawMessage {
    const TYPE: (&'static str, &'static str) = ("sensor_msgs", "PointCloud2");
}

/// Takes a DDS sample's bytes as they are ([`RawMessage`]).
pub struct RawAdapter;

/// The decoder [`RawAdapter`] uses: a copy of the bytes.
#[derive(Debug, Clone, Copy)]
pub struct RawDecoder;

/// Never: taking bytes cannot fail.
#[derive(Debug)]
pub struct NoError;

impl std::fmt::Display for NoError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("no error")
    }
}

impl std::error::Error for NoError {}

impl DeserializerAdapter<RawMessage> for RawAdapter {
    type Error = NoError;
    type Decoded = RawMessage;

    fn supported_encodings() -> &'static [RepresentationIdentifier] {
        &[
            RepresentationIdentifier::CDR_LE,
            RepresentationIdentifier::CDR_BE,
        ]
    }

    fn transform_decoded(decoded: RawMessage) -> RawMessage {
        decoded
    }
}

impl DefaultDecoder<RawMessage> for RawAdapter {
    type Decoder = RawDecoder;
    const DECODER: RawDecoder = RawDecoder;
}

impl<'de> Decode<'de, RawMessage> for RawDecoder {
    type Error = NoError;

    fn decode_bytes(
        self,
        input_bytes: &'de [u8],
        encoding: RepresentationIdentifier,
    ) -> Result<RawMessage, NoError> {
        Ok(RawMessage {
            big_endian: encoding == RepresentationIdentifier::CDR_BE,
            body: input_bytes.to_vec(),
        })
    }
}

/// Why a message was not taken as a scan: its stamp (when it could be read) and a sentence.
#[derive(Debug, Clone, PartialEq)]
pub struct Refused {
    /// The header's stamp, seconds.
    pub stamp: Option<f64>,
    /// Why.
    pub reason: String,
}

/// The scans' frame: the first scan's, unless a parameter named it.
#[derive(Debug, Clone, Default)]
pub struct FrameCheck {
    /// The frame every scan must be in, once known.
    pub expected: Option<String>,
}

impl FrameCheck {
    /// Decodes `message` into a scan, come at `arrived`.
    pub fn scan(&mut self, message: &RawMessage, arrived: Instant) -> Result<TimedScan, Refused> {
        let refuse = |stamp, reason: String| Refused { stamp, reason };
        let cloud = Cloud::parse_cdr_body(&message.body, message.big_endian)
            .map_err(|e| refuse(None, e.to_string()))?;
        let stamp = Some(cloud.stamp);
        match &self.expected {
            Some(f) if *f != cloud.frame_id => {
                return Err(refuse(
                    stamp,
                    format!("frame {:?}, not the scans' {f:?}", cloud.frame_id),
                ))
            }
            _ => {}
        }
        let decoded = cloud
            .decode_with(false)
            .map_err(|e| refuse(stamp, e.to_string()))?;
        if decoded.points.is_empty() {
            return Err(refuse(
                stamp,
                format!(
                    "an empty cloud ({} x {} points, {} not finite, {} at the origin)",
                    cloud.width, cloud.height, decoded.dropped_non_finite, decoded.dropped_zero
                ),
            ));
        }
        if self.expected.is_none() {
            self.expected = Some(cloud.frame_id.clone());
        }
        Ok(TimedScan {
            stamp: cloud.stamp,
            stamp_ns: Some(cloud.stamp_ns),
            points: decoded.points,
            times: decoded.times,
            arrived,
            samples: Vec::new(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::pointcloud2::encode;

    /// A message of `points` (x, y, z float32) as a DDS reader hands it over.
    fn message(points: &[[f32; 3]], frame: &str, width: u32) -> RawMessage {
        let fields = [("x", 0u32), ("y", 4), ("z", 8)];
        let data: Vec<u8> = points
            .iter()
            .flat_map(|p| p.iter().flat_map(|v| v.to_le_bytes()))
            .collect();
        let full = encode::cdr(
            (12, 500_000_000),
            frame,
            1,
            width,
            &fields_of(&fields),
            false,
            12,
            width.saturating_mul(12),
            &data,
        );
        RawMessage {
            big_endian: false,
            body: full[4..].to_vec(),
        }
    }

    fn fields_of(f: &[(&str, u32)]) -> Vec<crate::formats::pointcloud2::Field> {
        f.iter()
            .map(|(n, o)| crate::formats::pointcloud2::Field {
                name: n.to_string(),
                offset: *o,
                datatype: crate::formats::pointcloud2::datatype::FLOAT32,
                count: 1,
            })
            .collect()
    }

    #[test]
    fn a_cloud_becomes_a_scan_and_bad_ones_say_why() {
        let mut check = FrameCheck::default();
        let now = Instant::now();
        let ok = message(&[[1.0, 2.0, 3.0], [f32::NAN, 0.0, 0.0]], "lidar", 2);
        let s = check.scan(&ok, now).unwrap();
        assert_eq!(s.points, vec![[1.0, 2.0, 3.0]]);
        assert_eq!(s.stamp, 12.5);
        let other = message(&[[1.0, 2.0, 3.0]], "camera", 1);
        let e = check.scan(&other, now).unwrap_err();
        assert!(e.reason.contains("camera"), "{e:?}");
        assert_eq!(e.stamp, Some(12.5));
        let empty = message(&[[f32::NAN, 0.0, 0.0]], "lidar", 1);
        assert!(check
            .scan(&empty, now)
            .unwrap_err()
            .reason
            .contains("empty"));
        let huge = message(&[[1.0, 2.0, 3.0]], "lidar", u32::MAX);
        assert!(check.scan(&huge, now).is_err());
        let cut = RawMessage {
            big_endian: false,
            body: ok.body[..ok.body.len() - 5].to_vec(),
        };
        assert!(check.scan(&cut, now).is_err());
    }
}
