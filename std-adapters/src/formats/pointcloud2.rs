//! `sensor_msgs/PointCloud2`: the message, in both serialisations robots record it in (ROS 1
//! and ROS 2's CDR), and its points, for any field layout.
//!
//! [`Cloud::parse_ros1`] and [`Cloud::parse_cdr`] read the message without copying its data;
//! [`Cloud::decode`] turns the points into a [`DecodedScan`]: fields are found by name, with
//! their offset and datatype (INT8 to FLOAT64), across `point_step`, `row_step`, organised
//! clouds and either byte order. A point with a non-finite coordinate, or at the origin (no
//! return), is dropped and counted. Every error is a sentence for the caller to put after the
//! file, topic and message index.
//!
//! Per-point time, relative to the message's header stamp, in seconds:
//!
//! | field | datatype | unit and reference | written by |
//! |---|---|---|---|
//! | `t`, `offset_time` | any integer | nanoseconds since the stamp | Ouster (`t`), Livox (`offset_time`) |
//! | `time`, `t` | FLOAT32 or FLOAT64, all below 1e6 | seconds relative to the stamp | Velodyne (`time`), converters (`t`) |
//! | `timestamp`, `time_stamp` | FLOAT64 over 1e15 | absolute nanoseconds | Livox (`timestamp`) |
//! | `timestamp`, `time_stamp`, `time` | FLOAT64 over 1e6 | absolute seconds | Hesai (`timestamp`) |
//!
//! The first field found in the order `t`, `time`, `timestamp`, `time_stamp`, `offset_time`
//! is used. Relative times must lie within [`MAX_SWEEP_S`] of the stamp; a field whose values
//! fit no row of the table is an error naming the field, its datatype and its range.

use slamesh_core::Point;

/// How far from the header stamp a point's time may be (seconds): a sweep takes 0.05 to 0.5 s.
pub const MAX_SWEEP_S: f64 = 1.0;

/// The datatype codes of `sensor_msgs/PointField`.
pub mod datatype {
    /// Signed 8-bit.
    pub const INT8: u8 = 1;
    /// Unsigned 8-bit.
    pub const UINT8: u8 = 2;
    /// Signed 16-bit.
    pub const INT16: u8 = 3;
    /// Unsigned 16-bit.
    pub const UINT16: u8 = 4;
    /// Signed 32-bit.
    pub const INT32: u8 = 5;
    /// Unsigned 32-bit.
    pub const UINT32: u8 = 6;
    /// 32-bit float.
    pub const FLOAT32: u8 = 7;
    /// 64-bit float.
    pub const FLOAT64: u8 = 8;
}

/// The names searched for a per-point time, in order.
pub const TIME_FIELDS: [&str; 5] = ["t", "time", "timestamp", "time_stamp", "offset_time"];

/// One `sensor_msgs/PointField`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    /// The field's name (`x`, `intensity`, `t`, ...).
    pub name: String,
    /// Byte offset within a point.
    pub offset: u32,
    /// One of [`datatype`].
    pub datatype: u8,
    /// Number of elements (1 for every field read here).
    pub count: u32,
}

impl Field {
    /// Size in bytes of one element, or `None` for an unknown datatype.
    pub fn size(&self) -> Option<usize> {
        Some(match self.datatype {
            datatype::INT8 | datatype::UINT8 => 1,
            datatype::INT16 | datatype::UINT16 => 2,
            datatype::INT32 | datatype::UINT32 | datatype::FLOAT32 => 4,
            datatype::FLOAT64 => 8,
            _ => return None,
        })
    }

    fn is_integer(&self) -> bool {
        (datatype::INT8..=datatype::UINT32).contains(&self.datatype)
    }
}

/// A `sensor_msgs/PointCloud2` message, borrowing its point data.
#[derive(Debug, Clone, PartialEq)]
pub struct Cloud<'a> {
    /// Header stamp, seconds.
    pub stamp: f64,
    /// Header stamp as it was written: whole nanoseconds (what a reply's header carries back,
    /// to the nanosecond: `stamp` is a round trip through `f64`, off by up to some 100 ns).
    pub stamp_ns: i64,
    /// Header frame id.
    pub frame_id: String,
    /// Rows (1 for an unorganised cloud).
    pub height: u32,
    /// Points per row.
    pub width: u32,
    /// The point fields.
    pub fields: Vec<Field>,
    /// Byte order of the point data.
    pub is_bigendian: bool,
    /// Bytes per point.
    pub point_step: u32,
    /// Bytes per row.
    pub row_step: u32,
    /// The point data.
    pub data: &'a [u8],
}

/// The points of one cloud, with what else each point carries.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DecodedScan {
    /// The kept points, in the sensor frame.
    pub points: Vec<Point>,
    /// Each kept point's time relative to the stamp (seconds), if the cloud has a time field.
    pub times: Option<Vec<f32>>,
    /// Each kept point's `intensity`, if present.
    pub intensity: Option<Vec<f32>>,
    /// Each kept point's `ring`, if present.
    pub ring: Option<Vec<u16>>,
    /// Points dropped for a non-finite coordinate.
    pub dropped_non_finite: usize,
    /// Points dropped for lying at the origin (no return).
    pub dropped_zero: usize,
}

/// Reads little- or big-endian values off a byte slice, with bounds checks.
struct Bytes<'a> {
    buf: &'a [u8],
    pos: usize,
    /// Alignment origin (CDR aligns relative to the end of its 4-byte header); `None` packs.
    align_from: Option<usize>,
    big: bool,
}

impl<'a> Bytes<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], CloudError> {
        if let Some(origin) = self.align_from {
            let a = n.min(8);
            if a > 1 {
                let rel = self.pos - origin;
                self.pos += (a - rel % a) % a;
            }
        }
        let end = self.pos.checked_add(n).filter(|&e| e <= self.buf.len());
        let end = end.ok_or_else(|| CloudError::Truncated(what.to_string()))?;
        let s = &self.buf[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u8(&mut self, what: &str) -> Result<u8, CloudError> {
        Ok(self.take(1, what)?[0])
    }
    fn u32(&mut self, what: &str) -> Result<u32, CloudError> {
        let b: [u8; 4] = self.take(4, what)?.try_into().expect("4 bytes");
        Ok(if self.big {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        })
    }
    /// A string: a u32 length, then bytes (CDR counts and drops a trailing NUL).
    fn string(&mut self, what: &str) -> Result<String, CloudError> {
        let n = self.u32(what)? as usize;
        let b = self.bytes_of(n, what)?;
        let b = b.strip_suffix(&[0]).unwrap_or(b);
        Ok(String::from_utf8_lossy(b).into_owned())
    }
    fn bytes_of(&mut self, n: usize, what: &str) -> Result<&'a [u8], CloudError> {
        let save = self.align_from.take();
        let r = self.take(n, what);
        self.align_from = save;
        r
    }
}

impl<'a> Cloud<'a> {
    /// Parses a ROS 1 serialised message (little-endian, packed).
    pub fn parse_ros1(buf: &'a [u8]) -> Result<Self, CloudError> {
        let mut b = Bytes {
            buf,
            pos: 0,
            align_from: None,
            big: false,
        };
        let _seq = b.u32("header.seq")?;
        let sec = b.u32("header.stamp")?;
        let nsec = b.u32("header.stamp")?;
        Self::parse_rest(&mut b, i64::from(sec), nsec)
    }

    /// Parses a ROS 2 message in CDR (either byte order, as its 4-byte header says).
    pub fn parse_cdr(buf: &'a [u8]) -> Result<Self, CloudError> {
        if buf.len() < 4 {
            return Err(CloudError::Encoding(
                "message shorter than its CDR header".into(),
            ));
        }
        let big = match buf[1] {
            0 | 2 => true,
            1 | 3 => false,
            k => {
                return Err(CloudError::Encoding(format!(
                    "unknown CDR representation {k}"
                )))
            }
        };
        Self::parse_cdr_from(buf, 4, big)
    }

    /// Parses a ROS 2 message's CDR body, the bytes after the 4-byte header, in the byte order
    /// the header said (what a DDS reader hands over).
    pub fn parse_cdr_body(body: &'a [u8], big_endian: bool) -> Result<Self, CloudError> {
        Self::parse_cdr_from(body, 0, big_endian)
    }

    /// The CDR body starting at `start` in `buf` (alignment counted from there).
    fn parse_cdr_from(buf: &'a [u8], start: usize, big: bool) -> Result<Self, CloudError> {
        let mut b = Bytes {
            buf,
            pos: start,
            align_from: Some(start),
            big,
        };
        let sec = b.u32("header.stamp")? as i32;
        let nsec = b.u32("header.stamp")?;
        Self::parse_rest(&mut b, i64::from(sec), nsec)
    }

    /// The message after its header's stamp, `sec` seconds and `nsec` nanoseconds.
    fn parse_rest(b: &mut Bytes<'a>, sec: i64, nsec: u32) -> Result<Self, CloudError> {
        let stamp = sec as f64 + nsec as f64 * 1e-9;
        let stamp_ns = sec * 1_000_000_000 + i64::from(nsec);
        let frame_id = b.string("header.frame_id")?;
        let height = b.u32("height")?;
        let width = b.u32("width")?;
        let n = b.u32("fields")? as usize;
        // Each field takes at least 13 bytes: a bad count must not reserve memory.
        if n > (b.buf.len() - b.pos) / 13 {
            return Err(CloudError::Layout(format!(
                "{n} fields do not fit in the message"
            )));
        }
        let mut fields = Vec::with_capacity(n);
        for _ in 0..n {
            let name = b.string("a field name")?;
            let offset = b.u32("a field offset")?;
            let datatype = b.u8("a field datatype")?;
            let count = b.u32("a field count")?;
            fields.push(Field {
                name,
                offset,
                datatype,
                count,
            });
        }
        let is_bigendian = b.u8("is_bigendian")? != 0;
        let point_step = b.u32("point_step")?;
        let row_step = b.u32("row_step")?;
        let len = b.u32("data")? as usize;
        let data = b.bytes_of(len, "data")?;
        Ok(Cloud {
            stamp,
            stamp_ns,
            frame_id,
            height,
            width,
            fields,
            is_bigendian,
            point_step,
            row_step,
            data,
        })
    }

    /// The field called `name`, checked to fit in `point_step`.
    fn field(&self, name: &str) -> Result<Option<&Field>, CloudError> {
        let Some(f) = self.fields.iter().find(|f| f.name == name) else {
            return Ok(None);
        };
        let size = f.size().ok_or_else(|| {
            CloudError::Layout(format!("field {name} has unknown datatype {}", f.datatype))
        })?;
        if f.offset as usize + size > self.point_step as usize {
            return Err(CloudError::Layout(format!(
                "field {name} (offset {}, {size} bytes) lies past point_step {}",
                f.offset, self.point_step
            )));
        }
        Ok(Some(f))
    }

    /// Decodes the points and everything they carry (times, intensity, ring). Errors say what
    /// is malformed.
    pub fn decode(&self) -> Result<DecodedScan, CloudError> {
        self.decode_with(true)
    }

    /// Decodes the points and their times, and with `extras` their intensity and ring (a run
    /// does not use them yet, and leaving them out saves a third of the decoding).
    pub fn decode_with(&self, extras: bool) -> Result<DecodedScan, CloudError> {
        let xyz = ["x", "y", "z"].map(|n| self.field(n));
        let [x, y, z] = match xyz {
            [Ok(Some(x)), Ok(Some(y)), Ok(Some(z))] => [x, y, z],
            [a, b, c] => {
                a?;
                b?;
                c?;
                return Err(CloudError::NoXyz);
            }
        };
        let intensity = self.field("intensity")?.filter(|_| extras);
        let ring = self.field("ring")?.filter(|_| extras);
        let time = TIME_FIELDS
            .iter()
            .map(|n| self.field(n))
            .find_map(|r| r.transpose())
            .transpose()?;
        let read = [Some(x), Some(y), Some(z), time, intensity, ring];
        disjoint(read.iter().flatten().copied()).map_err(CloudError::Overlap)?;
        if !self.has_points()? {
            return Ok(DecodedScan {
                times: time.map(|_| Vec::new()),
                ..DecodedScan::default()
            });
        }
        let big = self.is_bigendian;
        let mut out = DecodedScan::default();
        let mut raw_times: Vec<f64> = Vec::new();
        // The common layouts (float32 coordinates in the machine's byte order; a float32,
        // uint32 or float64 time) get a loop of their own, with no datatype dispatch per point.
        let [ox, oy, oz] = [x, y, z].map(|f| f.offset as usize);
        let f32_xyz = [x, y, z].iter().all(|f| f.datatype == datatype::FLOAT32) && !big;
        let fast = |p: &[u8]| [read_f32_le(p, ox), read_f32_le(p, oy), read_f32_le(p, oz)];
        let general = |p: &[u8]| [x, y, z].map(|f| read_value(p, f, big) as f32);
        let extras = (intensity, ring);
        let times = &mut raw_times;
        match (f32_xyz, time.map(|f| (f.datatype, f.offset as usize))) {
            (true, None) => self.gather(fast, None::<fn(&[u8]) -> f64>, extras, &mut out, times),
            (true, Some((datatype::FLOAT32, o))) if !big => {
                let t = move |p: &[u8]| read_f32_le(p, o) as f64;
                self.gather(fast, Some(t), extras, &mut out, times)
            }
            (true, Some((datatype::UINT32, o))) if !big => {
                let t = move |p: &[u8]| u32::from_le_bytes(array(p, o)) as f64;
                self.gather(fast, Some(t), extras, &mut out, times)
            }
            (true, Some((datatype::FLOAT64, o))) if !big => {
                let t = move |p: &[u8]| f64::from_le_bytes(array(p, o));
                self.gather(fast, Some(t), extras, &mut out, times)
            }
            _ => {
                let t = time.map(|f| move |p: &[u8]| read_value(p, f, big));
                self.gather(general, t, extras, &mut out, times)
            }
        }
        if let Some(f) = time {
            out.times = Some(relative_times(&f.name, f.datatype, &raw_times, self.stamp)?);
        }
        crate::formats::sensor_ranges::check(&out.points).map_err(CloudError::NotAScan)?;
        Ok(out)
    }

    /// Whether the cloud has points, its sizes checked against its data: an empty cloud has
    /// none whatever the other sizes say (rows of nothing are not walked: a height of 4
    /// billion empty rows would take seconds); a `point_step` of 0, a `row_step` shorter than
    /// a row's points, or `data` shorter than the rows is an error.
    fn has_points(&self) -> Result<bool, CloudError> {
        let (w, h, step) = (
            self.width as usize,
            self.height as usize,
            self.point_step as usize,
        );
        let row = self.row_step as usize;
        if w == 0 || h == 0 {
            return Ok(false);
        }
        if step == 0 {
            return Err(CloudError::Layout("point_step is 0".into()));
        }
        if row < w.saturating_mul(step) {
            return Err(CloudError::Layout(format!(
                "row_step {row} is shorter than width {w} x point_step {step}"
            )));
        }
        let need = h
            .checked_sub(1)
            .map_or(Some(0), |r| r.checked_mul(row)?.checked_add(w * step));
        match need {
            Some(n) if n <= self.data.len() => Ok(true),
            _ => Err(CloudError::Layout(format!(
                "data holds {} bytes, fewer than {h} rows of {w} points of {step} bytes",
                self.data.len()
            ))),
        }
    }

    /// Reads every point of the (size-checked) data with `xyz`, and its time with `time` into
    /// `raw_times`, dropping and counting those at the origin or not finite; the `extras`
    /// (intensity, ring) are read where given.
    #[inline(always)]
    fn gather(
        &self,
        xyz: impl Fn(&[u8]) -> [f32; 3],
        time: Option<impl Fn(&[u8]) -> f64>,
        (intensity, ring): (Option<&Field>, Option<&Field>),
        out: &mut DecodedScan,
        raw_times: &mut Vec<f64>,
    ) {
        let (w, h, step, row) = (
            self.width as usize,
            self.height as usize,
            self.point_step as usize,
            self.row_step as usize,
        );
        let n = w * h;
        // Locals, not `out`'s fields, in the loop: their lengths and counts stay in registers.
        let mut points: Vec<Point> = Vec::with_capacity(n);
        let mut times: Vec<f64> = Vec::with_capacity(if time.is_some() { n } else { 0 });
        let (mut non_finite, mut zero) = (0, 0);
        let big = self.is_bigendian;
        let mut inten: Vec<f32> = Vec::with_capacity(if intensity.is_some() { n } else { 0 });
        let mut rings: Vec<u16> = Vec::with_capacity(if ring.is_some() { n } else { 0 });
        for r in 0..h {
            let row_points = &self.data[r * row..][..w * step];
            for p in row_points.chunks_exact(step.max(1)) {
                let v = xyz(p);
                if !(v[0].is_finite() && v[1].is_finite() && v[2].is_finite()) {
                    non_finite += 1;
                    continue;
                }
                if v == [0.0; 3] {
                    zero += 1;
                    continue;
                }
                points.push(v);
                if let Some(t) = &time {
                    times.push(t(p));
                }
                if let Some(f) = intensity {
                    inten.push(read_value(p, f, big) as f32);
                }
                if let Some(f) = ring {
                    rings.push(read_ring(p, f, big));
                }
            }
        }
        out.points = points;
        out.dropped_non_finite = non_finite;
        out.dropped_zero = zero;
        *raw_times = times;
        out.intensity = intensity.map(|_| inten);
        out.ring = ring.map(|_| rings);
    }
}

/// Two fields a point is read by whose bytes overlap (refused by [`Cloud::decode`]): no sensor lays out a point
/// that way, and its values would be garbage (a float64 x, y and z laid over float32 data read
/// as points thousands of metres away).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Overlap {
    /// The first field: name, offset and size (bytes).
    pub first: (String, usize, usize),
    /// The second.
    pub second: (String, usize, usize),
}

impl std::fmt::Display for Overlap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ((a, a0, an), (b, b0, bn)) = (&self.first, &self.second);
        write!(
            f,
            "fields {a} (offset {a0}, {an} bytes) and {b} (offset {b0}, {bn} bytes) overlap: not \
             a point layout (a mistyped field?)"
        )
    }
}

/// Why a PointCloud2 message could not be decoded.
#[derive(Debug, Clone, PartialEq)]
pub enum CloudError {
    /// The message ends inside what it was read for (a field's name).
    Truncated(String),
    /// A CDR header or representation this decoder does not read.
    Encoding(String),
    /// Fields, steps and data whose sizes do not fit together: how.
    Layout(String),
    /// No x, y and z fields.
    NoXyz,
    /// Two of the fields read overlap ([`Overlap`]).
    Overlap(Overlap),
    /// The time field fits no reading of the table ([`times::relative_times`]): why.
    Times(String),
    /// The points cannot be a LiDAR's scan ([`crate::formats::sensor_ranges`]).
    NotAScan(crate::formats::sensor_ranges::AbsurdRanges),
}

impl std::fmt::Display for CloudError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CloudError::Truncated(what) => write!(f, "message ends inside {what}"),
            CloudError::Encoding(why) | CloudError::Layout(why) | CloudError::Times(why) => {
                f.write_str(why)
            }
            CloudError::NoXyz => f.write_str("no x, y and z fields"),
            CloudError::Overlap(o) => o.fmt(f),
            CloudError::NotAScan(a) => a.fmt(f),
        }
    }
}

impl std::error::Error for CloudError {}

/// The first two of `fields` (each checked to fit its point) whose bytes overlap, if any.
fn disjoint<'f>(fields: impl Iterator<Item = &'f Field> + Clone) -> Result<(), Overlap> {
    let span = |f: &Field| (f.name.clone(), f.offset as usize, f.size().unwrap_or(0));
    for (i, a) in fields.clone().enumerate() {
        for b in fields.clone().skip(i + 1) {
            let (a, b) = (span(a), span(b));
            if a.1 < b.1 + b.2 && b.1 < a.1 + a.2 {
                return Err(Overlap {
                    first: a,
                    second: b,
                });
            }
        }
    }
    Ok(())
}

/// A ring number: unsigned 8 or 16 bits read as they are, anything else through `f64`, clamped.
#[inline]
fn read_ring(p: &[u8], f: &Field, big: bool) -> u16 {
    let o = f.offset as usize;
    match (f.datatype, big) {
        (datatype::UINT8, _) => p[o] as u16,
        (datatype::UINT16, false) => u16::from_le_bytes([p[o], p[o + 1]]),
        (datatype::UINT16, true) => u16::from_be_bytes([p[o], p[o + 1]]),
        _ => {
            let v = read_value(p, f, big);
            if v > 0.0 {
                v.min(u16::MAX as f64) as u16
            } else {
                0
            }
        }
    }
}

/// The `N` bytes at `o` in point `p` (whose length covers them, checked by [`Cloud::field`]).
#[inline(always)]
fn array<const N: usize>(p: &[u8], o: usize) -> [u8; N] {
    p[o..o + N].try_into().expect("checked size")
}

/// A little-endian float32 at `o` in point `p` (whose length covers it).
#[inline(always)]
fn read_f32_le(p: &[u8], o: usize) -> f32 {
    f32::from_le_bytes(array(p, o))
}

/// One value of field `f` in point `p` (whose length covers the field, checked by
/// [`Cloud::field`]), as `f64`.
#[inline]
fn read_value(p: &[u8], f: &Field, big: bool) -> f64 {
    let o = f.offset as usize;
    macro_rules! get {
        ($t:ty, $n:expr) => {{
            let b: [u8; $n] = p[o..o + $n].try_into().expect("checked size");
            if big {
                <$t>::from_be_bytes(b) as f64
            } else {
                <$t>::from_le_bytes(b) as f64
            }
        }};
    }
    match f.datatype {
        datatype::INT8 => p[o] as i8 as f64,
        datatype::UINT8 => p[o] as f64,
        datatype::INT16 => get!(i16, 2),
        datatype::UINT16 => get!(u16, 2),
        datatype::INT32 => get!(i32, 4),
        datatype::UINT32 => get!(u32, 4),
        datatype::FLOAT32 => get!(f32, 4),
        _ => get!(f64, 8),
    }
}

#[doc(hidden)]
pub mod encode;
mod times;

pub use times::{file_points_and_times, file_relative_times, file_time_field, relative_times};

#[cfg(test)]
mod tests {
    use super::datatype::*;
    use super::*;

    fn field(name: &str, offset: u32, datatype: u8) -> Field {
        Field {
            name: name.into(),
            offset,
            datatype,
            count: 1,
        }
    }

    fn xyz_f32() -> Vec<Field> {
        vec![
            field("x", 0, FLOAT32),
            field("y", 4, FLOAT32),
            field("z", 8, FLOAT32),
        ]
    }

    #[test]
    fn a_ros1_cloud_parses_and_decodes() {
        let mut data = Vec::new();
        for p in [
            [1.0f32, 2.0, 3.0],
            [f32::NAN, 0.0, 0.0],
            [0.0; 3],
            [4.0, 5.0, 6.0],
        ] {
            p.iter()
                .for_each(|v| data.extend_from_slice(&v.to_le_bytes()));
        }
        let msg = encode::ros1(
            (10, 500_000_000),
            "velo",
            1,
            4,
            &xyz_f32(),
            false,
            12,
            48,
            &data,
        );
        let c = Cloud::parse_ros1(&msg).unwrap();
        assert_eq!((c.stamp, c.frame_id.as_str()), (10.5, "velo"));
        let d = c.decode().unwrap();
        assert_eq!(d.points, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!((d.dropped_non_finite, d.dropped_zero), (1, 1));
        assert!(d.times.is_none() && d.intensity.is_none());
    }

    #[test]
    fn malformed_clouds_say_what_is_wrong() {
        let data = vec![0u8; 24];
        let short = encode::ros1((0, 0), "", 1, 4, &xyz_f32(), false, 12, 48, &data);
        let e = Cloud::parse_ros1(&short)
            .unwrap()
            .decode()
            .unwrap_err()
            .to_string();
        assert!(e.contains("data holds 24 bytes"), "{e}");
        let past = vec![
            field("x", 0, FLOAT32),
            field("y", 4, FLOAT32),
            field("z", 10, FLOAT32),
        ];
        let m = encode::ros1((0, 0), "", 1, 2, &past, false, 12, 24, &data);
        let e = Cloud::parse_ros1(&m)
            .unwrap()
            .decode()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("field z") && e.contains("past point_step 12"),
            "{e}"
        );
        let no_x = vec![
            field("a", 0, FLOAT32),
            field("y", 4, FLOAT32),
            field("z", 8, FLOAT32),
        ];
        let m = encode::ros1((0, 0), "", 1, 2, &no_x, false, 12, 24, &data);
        let e = Cloud::parse_ros1(&m).unwrap().decode().unwrap_err();
        assert_eq!(e, CloudError::NoXyz);
        assert_eq!(e.to_string(), "no x, y and z fields");
        let e = Cloud::parse_ros1(&m[..73]).unwrap_err();
        assert_eq!(e, CloudError::Truncated("point_step".into()));
        assert_eq!(e.to_string(), "message ends inside point_step");
        let e = Cloud::parse_ros1(&m[..30]).unwrap_err().to_string();
        assert_eq!(e, "3 fields do not fit in the message");
        // float64 x, y and z laid over float32 data (a sensor's x, y, z, intensity) overlap.
        let over = vec![
            field("x", 0, FLOAT64),
            field("y", 4, FLOAT64),
            field("z", 8, FLOAT64),
        ];
        let m = encode::cdr((0, 0), "", 1, 1, &over, false, 16, 16, &[0u8; 16]);
        let e = Cloud::parse_cdr(&m)
            .unwrap()
            .decode()
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "fields x (offset 0, 8 bytes) and y (offset 4, 8 bytes) overlap: not a point \
             layout (a mistyped field?)"
        );
        // A time or an intensity laid over a coordinate too; fields nothing reads may.
        for (name, offset) in [("t", 8), ("intensity", 11), ("ring", 0)] {
            let mut fields = xyz_f32();
            fields.push(field(name, offset, UINT8));
            fields.push(field("label", 0, FLOAT32));
            let m = encode::cdr((0, 0), "", 1, 1, &fields, false, 16, 16, &[0u8; 16]);
            let e = Cloud::parse_cdr(&m)
                .unwrap()
                .decode()
                .unwrap_err()
                .to_string();
            assert!(
                e.contains(&format!("and {name} (offset {offset}, 1 bytes)")),
                "{e}"
            );
        }
    }

    #[test]
    fn the_stamp_is_kept_to_the_nanosecond() {
        // An epoch stamp: f64 seconds hold it to some 240 ns only.
        let (sec, nsec) = (1_733_560_000, 123_456_789);
        let m = encode::cdr((sec, nsec), "", 1, 0, &xyz_f32(), false, 12, 0, &[]);
        let c = Cloud::parse_cdr(&m).unwrap();
        assert_eq!(c.stamp_ns, 1_733_560_000_123_456_789);
        assert_ne!((c.stamp * 1e9) as i64, c.stamp_ns, "f64 seconds lose it");
        let m = encode::ros1((sec as u32, nsec), "", 1, 0, &xyz_f32(), false, 12, 0, &[]);
        assert_eq!(Cloud::parse_ros1(&m).unwrap().stamp_ns, c.stamp_ns);
        // Before 1970 (ROS 2's seconds are signed).
        let m = encode::cdr((-2, 5), "", 1, 0, &xyz_f32(), false, 12, 0, &[]);
        assert_eq!(Cloud::parse_cdr(&m).unwrap().stamp_ns, -1_999_999_995);
    }

    #[test]
    fn a_cloud_of_empty_rows_decodes_at_once() {
        // Found by the fuzzer: width 0 and 4 billion rows of 0 bytes walked every row.
        let m = encode::ros1((0, 0), "", u32::MAX, 0, &xyz_f32(), false, 12, 0, &[]);
        let start = std::time::Instant::now();
        let d = Cloud::parse_ros1(&m).unwrap().decode().unwrap();
        assert!(d.points.is_empty());
        assert!(start.elapsed().as_secs() < 1, "{:?}", start.elapsed());
    }

    #[test]
    fn time_fields_follow_the_table() {
        let case = |dt: u8, name: &str, vals: &[f64], stamp: u32| {
            let size = field("", 0, dt).size().unwrap() as u32;
            let mut fields = xyz_f32();
            fields.push(field(name, 12, dt));
            let step = 12 + size;
            let mut data = Vec::new();
            for (i, v) in vals.iter().enumerate() {
                [1.0f32 + i as f32, 1.0, 1.0]
                    .iter()
                    .for_each(|c| data.extend_from_slice(&c.to_le_bytes()));
                match dt {
                    UINT32 => data.extend_from_slice(&(*v as u32).to_le_bytes()),
                    FLOAT32 => data.extend_from_slice(&(*v as f32).to_le_bytes()),
                    _ => data.extend_from_slice(&v.to_le_bytes()),
                }
            }
            let n = vals.len() as u32;
            let m = encode::ros1((stamp, 0), "", 1, n, &fields, false, step, step * n, &data);
            Cloud::parse_ros1(&m)
                .unwrap()
                .decode()
                .map(|d| d.times.unwrap())
        };
        assert_eq!(
            case(UINT32, "t", &[0.0, 5e7], 100).unwrap(),
            vec![0.0, 0.05]
        );
        assert_eq!(
            case(FLOAT32, "time", &[-0.1, 0.0], 100).unwrap(),
            vec![-0.1, 0.0]
        );
        let abs = case(
            FLOAT64,
            "timestamp",
            &[1_700_000_000.0, 1_700_000_000.05],
            1_700_000_000,
        );
        let abs = abs.unwrap();
        assert!((abs[1] - 0.05).abs() < 1e-6, "{abs:?}");
        let ns = case(FLOAT64, "timestamp", &[1.7e18, 1.7e18 + 2e7], 1_700_000_000).unwrap();
        assert!((ns[1] - 0.02).abs() < 1e-6, "{ns:?}");
        let e = case(FLOAT64, "timestamp", &[1.6e9], 1_700_000_000)
            .unwrap_err()
            .to_string();
        assert!(e.contains("timestamp") && e.contains("no reading"), "{e}");
        let e = case(FLOAT32, "t", &[2e7], 0).unwrap_err().to_string();
        assert!(e.contains("FLOAT32"), "{e}");
    }

    /// One layout of the same points: field order, padding, byte order, xyz type and rows.
    struct Layout {
        order: [usize; 5],
        pad: u32,
        big: bool,
        xyz: u8,
        rows: u32,
    }

    /// The points `pts` (with intensity `i * 10` and time `i * 1 ms` in Ouster's `t`) laid out
    /// as `l` says, with a NaN point after every row's points in an organised cloud.
    fn laid_out(pts: &[[f32; 3]], l: &Layout) -> Vec<u8> {
        let xyz_size = if l.xyz == FLOAT64 { 8 } else { 4 };
        let sizes = [xyz_size, xyz_size, xyz_size, 4, 4];
        let names = ["x", "y", "z", "intensity", "t"];
        let types = [l.xyz, l.xyz, l.xyz, FLOAT32, UINT32];
        let mut fields = Vec::new();
        let mut off = 0;
        for &k in &l.order {
            fields.push(field(names[k], off, types[k]));
            off += sizes[k] + l.pad;
        }
        let step = off;
        let cols = pts.len() as u32 / l.rows + u32::from(l.rows > 1);
        let mut data = vec![0u8; (step * cols * l.rows) as usize];
        let put = |data: &mut Vec<u8>, at: usize, dt: u8, v: f64| {
            let b: Vec<u8> = match (dt, l.big) {
                (FLOAT64, false) => v.to_le_bytes().to_vec(),
                (FLOAT64, true) => v.to_be_bytes().to_vec(),
                (FLOAT32, false) => (v as f32).to_le_bytes().to_vec(),
                (FLOAT32, true) => (v as f32).to_be_bytes().to_vec(),
                (_, false) => (v as u32).to_le_bytes().to_vec(),
                (_, true) => (v as u32).to_be_bytes().to_vec(),
            };
            data[at..at + b.len()].copy_from_slice(&b);
        };
        let per_row = pts.len() / l.rows as usize;
        for r in 0..l.rows as usize {
            for c in 0..cols as usize {
                let at = (r * cols as usize + c) * step as usize;
                let i = r * per_row + c;
                let vals = if c < per_row {
                    let p = pts[i];
                    [
                        p[0] as f64,
                        p[1] as f64,
                        p[2] as f64,
                        i as f64 * 10.0,
                        i as f64 * 1e6,
                    ]
                } else {
                    [f64::NAN, 0.0, 0.0, 0.0, 0.0]
                };
                for (k, f) in fields.iter().enumerate() {
                    let which = l.order[k];
                    put(&mut data, at + f.offset as usize, f.datatype, vals[which]);
                }
            }
        }
        encode::cdr(
            (5, 0),
            "os",
            l.rows,
            cols,
            &fields,
            l.big,
            step,
            step * cols,
            &data,
        )
    }

    #[test]
    fn every_layout_decodes_to_the_same_points() {
        let pts: Vec<[f32; 3]> = (0..6)
            .map(|i| [i as f32 + 0.5, -2.0 * i as f32, 0.25])
            .collect();
        let base = Layout {
            order: [0, 1, 2, 3, 4],
            pad: 0,
            big: false,
            xyz: FLOAT32,
            rows: 1,
        };
        let want = Cloud::parse_cdr(&laid_out(&pts, &base))
            .unwrap()
            .decode()
            .unwrap();
        assert_eq!(want.points, pts);
        assert_eq!(want.intensity.as_ref().unwrap()[5], 50.0);
        assert!((want.times.as_ref().unwrap()[5] - 0.005).abs() < 1e-9);
        let variants = [
            Layout {
                order: [4, 3, 2, 0, 1],
                ..base
            },
            Layout { pad: 4, ..base },
            Layout { big: true, ..base },
            Layout {
                xyz: FLOAT64,
                ..base
            },
            Layout { rows: 2, ..base },
            Layout {
                order: [3, 1, 4, 0, 2],
                pad: 2,
                big: true,
                xyz: FLOAT64,
                rows: 3,
            },
        ];
        for (k, l) in variants.iter().enumerate() {
            let got = Cloud::parse_cdr(&laid_out(&pts, l))
                .unwrap()
                .decode()
                .unwrap();
            assert_eq!(got.points, want.points, "variant {k}");
            assert_eq!(got.intensity, want.intensity, "variant {k}");
            assert_eq!(got.times, want.times, "variant {k}");
            assert_eq!(
                got.dropped_non_finite,
                if l.rows > 1 { l.rows as usize } else { 0 }
            );
        }
    }
}
