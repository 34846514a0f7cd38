//! Writes messages, for tests, fixtures and the fuzz targets' seeds. Not a general writer: it
//! writes exactly the layouts it is given.

use super::Field;

/// A PointCloud2 in ROS 1 serialisation.
#[allow(clippy::too_many_arguments)]
pub fn ros1(
    stamp: (u32, u32),
    frame_id: &str,
    height: u32,
    width: u32,
    fields: &[Field],
    is_bigendian: bool,
    point_step: u32,
    row_step: u32,
    data: &[u8],
) -> Vec<u8> {
    let mut o = Vec::new();
    let u32le = |o: &mut Vec<u8>, v: u32| o.extend_from_slice(&v.to_le_bytes());
    u32le(&mut o, 0);
    u32le(&mut o, stamp.0);
    u32le(&mut o, stamp.1);
    u32le(&mut o, frame_id.len() as u32);
    o.extend_from_slice(frame_id.as_bytes());
    u32le(&mut o, height);
    u32le(&mut o, width);
    u32le(&mut o, fields.len() as u32);
    for f in fields {
        u32le(&mut o, f.name.len() as u32);
        o.extend_from_slice(f.name.as_bytes());
        u32le(&mut o, f.offset);
        o.push(f.datatype);
        u32le(&mut o, f.count);
    }
    o.push(is_bigendian as u8);
    u32le(&mut o, point_step);
    u32le(&mut o, row_step);
    u32le(&mut o, data.len() as u32);
    o.extend_from_slice(data);
    o.push(1);
    o
}

/// A PointCloud2 in little-endian CDR, as ROS 2 records it.
#[allow(clippy::too_many_arguments)]
pub fn cdr(
    stamp: (i32, u32),
    frame_id: &str,
    height: u32,
    width: u32,
    fields: &[Field],
    is_bigendian: bool,
    point_step: u32,
    row_step: u32,
    data: &[u8],
) -> Vec<u8> {
    let mut o = vec![0, 1, 0, 0];
    let u32le = |o: &mut Vec<u8>, v: u32| {
        while !(o.len() - 4).is_multiple_of(4) {
            o.push(0);
        }
        o.extend_from_slice(&v.to_le_bytes());
    };
    let string = |o: &mut Vec<u8>, s: &str| {
        u32le(o, s.len() as u32 + 1);
        o.extend_from_slice(s.as_bytes());
        o.push(0);
    };
    u32le(&mut o, stamp.0 as u32);
    u32le(&mut o, stamp.1);
    string(&mut o, frame_id);
    u32le(&mut o, height);
    u32le(&mut o, width);
    u32le(&mut o, fields.len() as u32);
    for f in fields {
        string(&mut o, &f.name);
        u32le(&mut o, f.offset);
        o.push(f.datatype);
        u32le(&mut o, f.count);
    }
    o.push(is_bigendian as u8);
    u32le(&mut o, point_step);
    u32le(&mut o, row_step);
    u32le(&mut o, data.len() as u32);
    o.extend_from_slice(data);
    o.push(1);
    o
}
