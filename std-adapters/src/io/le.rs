//! Little-endian records of a run's state ([`crate::run::checkpoint`] and the parts of a run
//! that keep their own state in it): `put_*` append to a byte vector; [`Decoder`] reads them
//! back from the front of a slice, every read checked, so damaged bytes are an error that
//! says what ran out or was wrong, never a panic. Numbers are kept bit for bit.

use nalgebra::{Quaternion, Translation3, UnitQuaternion, Vector3};
use slamesh_core::Pose;

/// Appends a `u8`.
pub fn put_u8(e: &mut Vec<u8>, v: u8) {
    e.push(v);
}

/// Appends a `u32`.
pub fn put_u32(e: &mut Vec<u8>, v: u32) {
    e.extend_from_slice(&v.to_le_bytes());
}

/// Appends a `u64`.
pub fn put_u64(e: &mut Vec<u8>, v: u64) {
    e.extend_from_slice(&v.to_le_bytes());
}

/// Appends an `f64`.
pub fn put_f64(e: &mut Vec<u8>, v: f64) {
    e.extend_from_slice(&v.to_le_bytes());
}

/// Appends three `f64`.
pub fn put_vec3(e: &mut Vec<u8>, v: &Vector3<f64>) {
    for x in v.iter() {
        put_f64(e, *x);
    }
}

/// Appends a text: its length (`u32`), then its UTF-8 bytes.
pub fn put_str(e: &mut Vec<u8>, s: &str) {
    put_u32(e, s.len() as u32);
    e.extend_from_slice(s.as_bytes());
}

/// Appends whether `v` is there (a byte), then it (or `none`'s bytes, so that the record
/// keeps its size).
pub fn put_option<T: Copy>(e: &mut Vec<u8>, v: Option<T>, none: T, put: fn(&mut Vec<u8>, T)) {
    e.push(u8::from(v.is_some()));
    put(e, v.unwrap_or(none));
}

/// Appends a text that may be missing: a byte, then the text when there.
pub fn put_opt_str(e: &mut Vec<u8>, s: Option<&str>) {
    e.push(u8::from(s.is_some()));
    if let Some(s) = s {
        put_str(e, s);
    }
}

/// Appends a pose: translation, then the quaternion `(i, j, k, w)`: 56 bytes, exact.
pub fn put_pose(e: &mut Vec<u8>, p: &Pose) {
    let t = &p.translation.vector;
    let q = p.rotation.quaternion();
    for v in [t.x, t.y, t.z, q.i, q.j, q.k, q.w] {
        put_f64(e, v);
    }
}

/// Why [`Decoder`] could not read what was written: the file is truncated or damaged, in
/// words (a caller names the file).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Damaged(pub String);

impl std::fmt::Display for Damaged {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Damaged {}

impl From<&str> for Damaged {
    fn from(why: &str) -> Self {
        Damaged(why.to_string())
    }
}

impl From<String> for Damaged {
    fn from(why: String) -> Self {
        Damaged(why)
    }
}

/// Where a caller's errors are words: a damaged record's words.
impl From<Damaged> for String {
    fn from(d: Damaged) -> Self {
        d.0
    }
}

/// Checked reads from the front of a byte slice.
pub struct Decoder<'a> {
    /// What is left to read.
    pub bytes: &'a [u8],
}

impl<'a> Decoder<'a> {
    /// The next `n` bytes.
    pub fn take(&mut self, n: usize) -> Result<&'a [u8], Damaged> {
        if self.bytes.len() < n {
            return Err("the file ends early (truncated)".into());
        }
        let (head, rest) = self.bytes.split_at(n);
        self.bytes = rest;
        Ok(head)
    }

    /// The next `K` bytes.
    pub fn array<const K: usize>(&mut self) -> Result<[u8; K], Damaged> {
        let mut a = [0u8; K];
        a.copy_from_slice(self.take(K)?);
        Ok(a)
    }

    /// A `u8`.
    pub fn u8(&mut self) -> Result<u8, Damaged> {
        Ok(self.array::<1>()?[0])
    }

    /// A byte that must be 0 or 1.
    pub fn flag(&mut self) -> Result<bool, Damaged> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            b => Err(format!("a flag of {b}").into()),
        }
    }

    /// A `u32`.
    pub fn u32(&mut self) -> Result<u32, Damaged> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    /// An `i32`.
    pub fn i32(&mut self) -> Result<i32, Damaged> {
        Ok(i32::from_le_bytes(self.array()?))
    }

    /// A `u64`.
    pub fn u64(&mut self) -> Result<u64, Damaged> {
        Ok(u64::from_le_bytes(self.array()?))
    }

    /// A `u64` as a `usize`.
    pub fn usize(&mut self) -> Result<usize, Damaged> {
        usize::try_from(self.u64()?).map_err(|_| "a count too large for this machine".into())
    }

    /// An `f64`.
    pub fn f64(&mut self) -> Result<f64, Damaged> {
        Ok(f64::from_le_bytes(self.array()?))
    }

    /// Three `f64`.
    pub fn vec3(&mut self) -> Result<Vector3<f64>, Damaged> {
        Ok(Vector3::new(self.f64()?, self.f64()?, self.f64()?))
    }

    /// What [`put_option`] wrote, read by `read`.
    pub fn option<T>(
        &mut self,
        read: impl FnOnce(&mut Self) -> Result<T, Damaged>,
    ) -> Result<Option<T>, Damaged> {
        let there = self.flag()?;
        let v = read(self)?;
        Ok(there.then_some(v))
    }

    /// A count of items of at least `min_bytes` each: refused when the rest of the bytes
    /// cannot hold them (so a damaged count never sizes an allocation).
    pub fn count(&mut self, min_bytes: usize) -> Result<usize, Damaged> {
        let n = self.u64()?;
        if n.saturating_mul(min_bytes as u64) > self.bytes.len() as u64 {
            return Err(format!("a count of {n} runs past the end of the file").into());
        }
        Ok(n as usize)
    }

    /// What [`put_str`] wrote.
    pub fn string(&mut self) -> Result<String, Damaged> {
        let n = self.u32()? as usize;
        String::from_utf8(self.take(n)?.to_vec()).map_err(|_| "a text is not UTF-8".into())
    }

    /// What [`put_opt_str`] wrote.
    pub fn opt_string(&mut self) -> Result<Option<String>, Damaged> {
        match self.flag()? {
            true => Ok(Some(self.string()?)),
            false => Ok(None),
        }
    }

    /// What [`put_pose`] wrote; refused unless finite.
    pub fn pose(&mut self) -> Result<Pose, Damaged> {
        let mut v = [0.0; 7];
        for x in &mut v {
            *x = self.f64()?;
        }
        if !v.iter().all(|x| x.is_finite()) {
            return Err("a pose is not finite".into());
        }
        Ok(Pose::from_parts(
            Translation3::new(v[0], v[1], v[2]),
            UnitQuaternion::new_unchecked(Quaternion::new(v[6], v[3], v[4], v[5])),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn what_is_put_reads_back_and_damage_is_an_error() {
        let mut e = Vec::new();
        put_u8(&mut e, 7);
        put_u64(&mut e, 1 << 40);
        put_f64(&mut e, -0.1);
        put_vec3(&mut e, &Vector3::new(1.0, f64::MIN_POSITIVE, -3.5));
        put_option(&mut e, Some(2.5), 0.0, put_f64);
        put_option(&mut e, None, 0.0, put_f64);
        put_opt_str(&mut e, Some("up"));
        put_opt_str(&mut e, None);
        let mut d = Decoder { bytes: &e };
        assert_eq!(d.u8(), Ok(7));
        assert_eq!(d.usize(), Ok(1 << 40));
        assert_eq!(d.f64().map(f64::to_bits), Ok((-0.1f64).to_bits()));
        assert_eq!(d.vec3(), Ok(Vector3::new(1.0, f64::MIN_POSITIVE, -3.5)));
        assert_eq!(d.option(Decoder::f64), Ok(Some(2.5)));
        assert_eq!(d.option(Decoder::f64), Ok(None));
        assert_eq!(d.opt_string(), Ok(Some("up".to_string())));
        assert_eq!(d.opt_string(), Ok(None));
        assert!(d.bytes.is_empty());
        let mut short = Decoder { bytes: &e[..3] };
        assert!(short.u64().is_err());
        let mut bad_flag = Decoder { bytes: &[2, 0] };
        assert_eq!(bad_flag.flag(), Err(Damaged("a flag of 2".into())));
    }
}
