//! PCD point clouds (PCL's format, version 0.7 and older headers): `ascii`, `binary` and
//! `binary_compressed` data. Reads the `x`, `y`, `z` fields (any numeric type); other fields
//! are skipped. Errors name the file, the header line where it applies, and the reason.

use crate::formats::lzf;
use crate::formats::pointcloud2;
use crate::io::error::FileError;
use slamesh_core::Point;
use std::path::Path;

/// One field of a PCD record.
#[derive(Debug, Clone, PartialEq)]
struct Field {
    name: String,
    size: usize,
    kind: u8,
    count: usize,
}

impl Field {
    fn bytes(&self) -> usize {
        self.size * self.count
    }

    /// The first element of this field from its little-endian bytes.
    fn value(&self, b: &[u8]) -> f64 {
        let a = |n: usize| -> [u8; 8] {
            let mut v = [0u8; 8];
            v[..n].copy_from_slice(&b[..n]);
            v
        };
        match (self.kind, self.size) {
            (b'F', 4) => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            (b'F', 8) => f64::from_le_bytes(a(8)),
            (b'I', 1) => b[0] as i8 as f64,
            (b'I', 2) => i16::from_le_bytes([b[0], b[1]]) as f64,
            (b'I', 4) => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            (b'I', 8) => i64::from_le_bytes(a(8)) as f64,
            (b'U', n) => u64::from_le_bytes(a(n)) as f64,
            _ => f64::NAN,
        }
    }
}

#[derive(Debug)]
enum Data {
    Ascii,
    Binary,
    Compressed,
}

#[derive(Debug)]
struct Header {
    fields: Vec<Field>,
    points: usize,
    data: Data,
    /// Byte offset of the data.
    start: usize,
    /// Bytes of one point's record (every field, every element): checked against overflow.
    record: usize,
}

fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header, FileError> {
    let mut declared = Declared::default();
    let mut pos = 0;
    let mut line_no = 0;
    loop {
        line_no += 1;
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(FileError::at(path, "PCD header ends before its DATA line"));
        };
        let line = std::str::from_utf8(&bytes[pos..pos + len])
            .map_err(|_| FileError::new(path, Some(line_no), "PCD header is not text"))?
            .trim();
        pos += len + 1;
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let bad = |reason: String| FileError::new(path, Some(line_no), reason);
        let mut words = line.split_whitespace();
        let key = words.next().unwrap_or_default().to_ascii_uppercase();
        let rest: Vec<&str> = words.collect();
        if key == "DATA" {
            let data = match rest.first().copied() {
                Some("ascii") => Data::Ascii,
                Some("binary") => Data::Binary,
                Some("binary_compressed") => Data::Compressed,
                other => {
                    return Err(bad(format!(
                        "DATA: unknown encoding {other:?} (ascii, binary, binary_compressed)"
                    )))
                }
            };
            return declared.header(data, pos).map_err(bad);
        }
        declared.take(&key, &rest, line).map_err(bad)?;
    }
}

/// What a PCD header's lines before `DATA` declared.
#[derive(Default)]
struct Declared {
    names: Vec<String>,
    sizes: Vec<usize>,
    kinds: Vec<u8>,
    counts: Vec<usize>,
    width: Option<usize>,
    height: Option<usize>,
    points: Option<usize>,
}

impl Declared {
    /// Takes one line (`key` upper-cased, then the `rest` of its words), or says why not.
    fn take(&mut self, key: &str, rest: &[&str], line: &str) -> Result<(), String> {
        let numbers = || -> Result<Vec<usize>, String> {
            rest.iter()
                .map(|w| {
                    w.parse::<usize>()
                        .map_err(|_| format!("{key}: not a count: {w:?}"))
                })
                .collect()
        };
        match key {
            "VERSION" | "VIEWPOINT" => {}
            "FIELDS" | "COLUMNS" => self.names = rest.iter().map(|s| s.to_string()).collect(),
            "SIZE" => self.sizes = numbers()?,
            "TYPE" => {
                self.kinds = rest
                    .iter()
                    .map(|w| match w.as_bytes() {
                        [k @ (b'F' | b'I' | b'U')] => Ok(*k),
                        _ => Err(format!("TYPE: unknown type {w:?} (F, I or U)")),
                    })
                    .collect::<Result<_, _>>()?
            }
            "COUNT" => self.counts = numbers()?,
            "WIDTH" => self.width = numbers()?.first().copied(),
            "HEIGHT" => self.height = numbers()?.first().copied(),
            "POINTS" => self.points = numbers()?.first().copied(),
            _ => return Err(format!("not a PCD header line: {line:?}")),
        }
        Ok(())
    }

    /// The header, its data (`data`) starting at byte `start`: the fields declared, checked
    /// to agree and to be sizes this reader takes.
    fn header(mut self, data: Data, start: usize) -> Result<Header, String> {
        let n = self.names.len();
        if n == 0 {
            return Err("no FIELDS line before DATA".into());
        }
        if self.counts.is_empty() {
            self.counts = vec![1; n];
        }
        if self.sizes.len() != n || self.kinds.len() != n || self.counts.len() != n {
            return Err(format!(
                "FIELDS, SIZE, TYPE and COUNT disagree: {} names, {} sizes, {} types, {} counts",
                n,
                self.sizes.len(),
                self.kinds.len(),
                self.counts.len()
            ));
        }
        let points = match (self.points, self.width, self.height) {
            (Some(p), _, _) => p,
            (None, Some(w), Some(h)) => w.saturating_mul(h),
            _ => return Err("no POINTS, or WIDTH and HEIGHT, before DATA".into()),
        };
        let fields = (self.names.into_iter().zip(self.sizes))
            .zip(self.kinds.into_iter().zip(self.counts))
            .map(|((name, size), (kind, count))| Field {
                name,
                size,
                kind,
                count,
            })
            .collect::<Vec<_>>();
        let record = record_bytes(&fields)?;
        Ok(Header {
            fields,
            points,
            data,
            start,
            record,
        })
    }
}

/// A record's bytes, summed once here, where an overflow is an error; a field of a size
/// this reader does not take, or of no values, is one too.
fn record_bytes(fields: &[Field]) -> Result<usize, String> {
    let mut record = 0usize;
    for f in fields {
        let ok = match f.kind {
            b'F' => f.size == 4 || f.size == 8,
            _ => matches!(f.size, 1 | 2 | 4 | 8),
        };
        if !ok || f.count == 0 {
            return Err(format!(
                "field {}: unsupported size {} / count {}",
                f.name, f.size, f.count
            ));
        }
        record = f
            .size
            .checked_mul(f.count)
            .and_then(|b| record.checked_add(b))
            .ok_or_else(|| {
                format!(
                    "field {}: a count of {} makes a record too large",
                    f.name, f.count
                )
            })?;
    }
    Ok(record)
}

/// Reads the points of a PCD file (in the sensor frame, as stored).
pub fn read_pcd(path: &Path) -> Result<Vec<Point>, FileError> {
    let bytes = std::fs::read(path).map_err(|e| FileError::at(path, e.to_string()))?;
    parse_pcd(path, &bytes)
}

/// Parses the bytes of a PCD file read from `path` (named in errors).
pub fn parse_pcd(path: &Path, bytes: &[u8]) -> Result<Vec<Point>, FileError> {
    parse_pcd_timed(path, bytes, None).map(|(p, _)| p)
}

/// Reads a PCD file's points and, if it has a time field (`t`, `time`, `timestamp`,
/// `time_stamp` or `offset_time`), each point's time relative to `stamp` (seconds) by the
/// table in [`crate::formats::pointcloud2`].
pub fn read_pcd_timed(
    path: &Path,
    stamp: f64,
) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
    let bytes = std::fs::read(path).map_err(|e| FileError::at(path, e.to_string()))?;
    parse_pcd_timed(path, &bytes, Some(stamp))
}

/// [`parse_pcd`], with the points' times when `stamp` is given and the file has a time field.
pub fn parse_pcd_timed(
    path: &Path,
    bytes: &[u8],
    stamp: Option<f64>,
) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
    if bytes.is_empty() {
        return Err(FileError::at(path, "empty file"));
    }
    let h = parse_header(path, bytes)?;
    let index = |name: &str| {
        h.fields
            .iter()
            .position(|f| f.name == name)
            .ok_or_else(|| FileError::at(path, format!("PCD has no {name} field")))
    };
    let mut wanted = vec![index("x")?, index("y")?, index("z")?];
    let time = stamp.and_then(|stamp| {
        let k = pointcloud2::file_time_field(|n| h.fields.iter().position(|f| f.name == n))?;
        wanted.push(k);
        let f = &h.fields[k];
        let datatype = match (f.kind, f.size) {
            (b'F', 4) => pointcloud2::datatype::FLOAT32,
            (b'F', _) => pointcloud2::datatype::FLOAT64,
            _ => pointcloud2::datatype::UINT32,
        };
        Some((f.name.as_str(), datatype, stamp))
    });
    let rows = values(path, &h, &wanted, &bytes[h.start..])?;
    pointcloud2::file_points_and_times(&rows, time).map_err(|e| FileError::at(path, e.to_string()))
}

/// The values of fields `wanted` (first elements), point by point: `wanted.len()` a point.
fn values(path: &Path, h: &Header, wanted: &[usize], body: &[u8]) -> Result<Vec<f64>, FileError> {
    match h.data {
        Data::Ascii => read_ascii(path, h, wanted, body),
        Data::Binary => {
            let record = h.record;
            let offsets = offsets(&h.fields);
            let need = record.saturating_mul(h.points);
            if body.len() < need {
                return Err(FileError::at(
                    path,
                    format!(
                        "truncated: {} points of {record} bytes need {need} bytes of data, found {}",
                        h.points,
                        body.len()
                    ),
                ));
            }
            Ok(body[..need]
                .chunks_exact(record.max(1))
                .flat_map(|r| wanted.iter().map(|&k| h.fields[k].value(&r[offsets[k]..])))
                .collect())
        }
        Data::Compressed => {
            let word = |i: usize| {
                body.get(i..i + 4)
                    .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
            };
            let (Some(packed), Some(unpacked)) = (word(0), word(4)) else {
                return Err(FileError::at(path, "truncated: no compressed sizes"));
            };
            let data = body.get(8..8 + packed).ok_or_else(|| {
                FileError::at(
                    path,
                    format!(
                        "truncated: {packed} compressed bytes declared, {} present",
                        body.len().saturating_sub(8)
                    ),
                )
            })?;
            let record = h.record;
            if unpacked != record.saturating_mul(h.points) {
                return Err(FileError::at(
                    path,
                    format!(
                        "{unpacked} uncompressed bytes declared, {} points of {record} bytes need {}",
                        h.points,
                        record.saturating_mul(h.points)
                    ),
                ));
            }
            let raw = lzf::decompress(data, unpacked).map_err(|e| FileError::at(path, e))?;
            // Column-major: all points' values of field 0, then of field 1, ...
            let mut column = vec![0usize; h.fields.len()];
            let mut at = 0;
            for (k, f) in h.fields.iter().enumerate() {
                column[k] = at;
                at += f.bytes() * h.points;
            }
            Ok((0..h.points)
                .flat_map(|i| {
                    let (raw, column) = (&raw, &column);
                    wanted.iter().map(move |&k| {
                        let f = &h.fields[k];
                        f.value(&raw[column[k] + i * f.bytes()..])
                    })
                })
                .collect())
        }
    }
}

/// Byte offset of each field within a record.
fn offsets(fields: &[Field]) -> Vec<usize> {
    fields
        .iter()
        .scan(0, |at, f| {
            let o = *at;
            *at += f.bytes();
            Some(o)
        })
        .collect()
}

fn read_ascii(
    path: &Path,
    h: &Header,
    wanted: &[usize],
    body: &[u8],
) -> Result<Vec<f64>, FileError> {
    let text =
        std::str::from_utf8(body).map_err(|_| FileError::at(path, "ascii data is not text"))?;
    // Column of each field's first element.
    let columns: Vec<usize> = h
        .fields
        .iter()
        .scan(0, |at, f| {
            let o = *at;
            *at += f.count;
            Some(o)
        })
        .collect();
    // The header's count is untrusted: reserve no more than the text has lines for.
    let mut out = Vec::with_capacity(h.points.min(body.len() / 2) * wanted.len());
    let mut read = 0;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        for &k in wanted {
            let w = words.get(columns[k]).ok_or_else(|| {
                FileError::at(
                    path,
                    format!("data line {} has only {} values", i + 1, words.len()),
                )
            })?;
            let bad = |_| FileError::at(path, format!("data line {}: not a number: {w:?}", i + 1));
            // Coordinates parse as f32 (a decimal rounded once), a time as f64.
            let v = if out.len() % wanted.len() < 3 {
                w.parse::<f32>().map_err(bad)? as f64
            } else {
                w.parse::<f64>().map_err(bad)?
            };
            out.push(v);
        }
        read += 1;
        if read == h.points {
            break;
        }
    }
    if read < h.points {
        return Err(FileError::at(
            path,
            format!(
                "truncated: {} points declared, {} data lines",
                h.points, read
            ),
        ));
    }
    Ok(out)
}

/// Writes `points` as a PCD with float `x y z` fields in the given encoding
/// (`"ascii"`, `"binary"` or `"binary_compressed"`, the latter with literal-only LZF). For
/// tests and fuzz seeds only, so hidden from the docs: slamesh writes no PCD.
#[doc(hidden)]
pub fn encode_pcd(points: &[Point], encoding: &str) -> Vec<u8> {
    let mut out = format!(
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n\
         TYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\n\
         DATA {encoding}\n",
        n = points.len()
    )
    .into_bytes();
    match encoding {
        "ascii" => {
            for p in points {
                out.extend_from_slice(format!("{} {} {}\n", p[0], p[1], p[2]).as_bytes());
            }
        }
        "binary" => {
            for v in points.iter().flatten() {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        _ => {
            let mut raw = Vec::with_capacity(points.len() * 12);
            for c in 0..3 {
                for p in points {
                    raw.extend_from_slice(&p[c].to_le_bytes());
                }
            }
            let packed = lzf::compress_literal(&raw);
            out.extend_from_slice(&(packed.len() as u32).to_le_bytes());
            out.extend_from_slice(&(raw.len() as u32).to_le_bytes());
            out.extend_from_slice(&packed);
        }
    }
    out
}

/// Writes `points` with each one's time after the scan's stamp (seconds) as a binary PCD with
/// float `x y z t` fields, as a rolling-sweep sensor's driver records them. For the
/// simulator's drives and tests, so hidden from the docs like [`encode_pcd`].
#[doc(hidden)]
pub fn encode_pcd_timed(points: &[Point], times: &[f32]) -> Vec<u8> {
    let n = points.len().min(times.len());
    let mut out = format!(
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z t\n\
         SIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH {n}\nHEIGHT 1\n\
         VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA binary\n"
    )
    .into_bytes();
    for (p, t) in points.iter().zip(times) {
        for v in [p[0], p[1], p[2], *t] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str, bytes: &[u8]) -> crate::test_support::ScratchFile {
        crate::test_support::scratch_file("pcd", name, bytes)
    }

    #[test]
    fn all_three_encodings_round_trip() {
        let pts = vec![[1.5, -2.0, 0.25], [3.0, 4.0, 5.0], [-0.5, 0.0, 7.75]];
        for enc in ["ascii", "binary", "binary_compressed"] {
            let p = tmp(&format!("{enc}.pcd"), &encode_pcd(&pts, enc));
            assert_eq!(read_pcd(&p).unwrap(), pts, "{enc}");
        }
    }

    #[test]
    fn extra_fields_and_types_are_handled() {
        // x y z as doubles with an intensity byte and a 2-element field in between.
        let mut b = b"VERSION .7\nFIELDS x rgb y z intensity\nSIZE 8 4 8 8 1\nTYPE F U F F U\n\
COUNT 1 2 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary\n"
            .to_vec();
        b.extend_from_slice(&1.25f64.to_le_bytes());
        b.extend_from_slice(&[0u8; 8]);
        b.extend_from_slice(&(-3.0f64).to_le_bytes());
        b.extend_from_slice(&9.5f64.to_le_bytes());
        b.push(200);
        assert_eq!(
            read_pcd(&tmp("mixed.pcd", &b)).unwrap(),
            vec![[1.25, -3.0, 9.5]]
        );
    }

    #[test]
    fn a_time_field_gives_each_points_time() {
        let head =
            "FIELDS x y z t\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\nPOINTS 2\nDATA ascii\n";
        let b = format!("{head}1 2 3 0\n4 5 6 50000000\n");
        let (p, t) = parse_pcd_timed(Path::new("a.pcd"), b.as_bytes(), Some(9.0)).unwrap();
        assert_eq!(p, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(
            t,
            Some(vec![0.0, 0.05]),
            "Ouster's t: nanoseconds since the stamp"
        );
        let abs = b"FIELDS x y z timestamp\nSIZE 4 4 4 8\nTYPE F F F F\nCOUNT 1 1 1 1\n\
                    POINTS 2\nDATA ascii\n1 2 3 1700000000.0\n4 5 6 1700000000.1\n";
        let t = parse_pcd_timed(Path::new("a.pcd"), abs, Some(1_700_000_000.0))
            .unwrap()
            .1;
        assert!((t.unwrap()[1] - 0.1).abs() < 1e-6, "absolute seconds");
        // A folder without times: from the earliest point.
        let t = parse_pcd_timed(Path::new("a.pcd"), abs, Some(0.2))
            .unwrap()
            .1;
        assert!((t.unwrap()[1] - 0.1).abs() < 1e-6);
        let far = b"FIELDS x y z time\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n\
                    POINTS 2\nDATA ascii\n1 2 3 0\n4 5 6 30\n";
        let e = parse_pcd_timed(Path::new("a.pcd"), far, Some(0.0)).unwrap_err();
        assert!(
            e.to_string().contains("a.pcd") && e.reason.contains("time field time"),
            "{e}"
        );
        assert_eq!(
            parse_pcd_timed(Path::new("a.pcd"), abs, None).unwrap().1,
            None
        );
    }

    #[test]
    fn bad_files_are_errors_naming_the_file_and_reason() {
        let cases: [(&str, Vec<u8>, &str); 6] = [
            ("empty.pcd", vec![], "empty"),
            (
                "garbage.pcd",
                b"hello world\nDATA ascii\n".to_vec(),
                "not a PCD header",
            ),
            (
                "noxyz.pcd",
                b"FIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nPOINTS 0\nDATA ascii\n".to_vec(),
                "no x field",
            ),
            (
                "short.pcd",
                {
                    let b = encode_pcd(&[[1.0; 3]; 4], "binary");
                    b[..b.len() - 5].to_vec()
                },
                "truncated",
            ),
            (
                "nodata.pcd",
                b"FIELDS x y z\nSIZE 4 4 4\n".to_vec(),
                "ends before",
            ),
            (
                // Found by the fuzzer: the record's size overflowed.
                "hugecount.pcd",
                b"FIELDS x y z\nSIZE 8 4 4\nTYPE F F F\nCOUNT 1 1 13367767333989954681\nPOINTS 1\nDATA binary\n"
                    .to_vec(),
                "too large",
            ),
        ];
        for (name, bytes, reason) in cases {
            let e = read_pcd(&tmp(name, &bytes)).unwrap_err();
            assert!(e.to_string().contains(name), "{e}");
            assert!(e.reason.contains(reason), "{name}: {e}");
        }
        let mut c = encode_pcd(&[[1.0; 3]; 4], "binary_compressed");
        let n = c.len();
        c[n - 17] = 31; // the last literal run now claims more bytes than remain
        assert!(read_pcd(&tmp("corrupt.pcd", &c)).is_err());
    }
}
