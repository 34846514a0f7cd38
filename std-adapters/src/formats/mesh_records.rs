//! The records a mesh is spooled as and written from: a vertex record (position, normal,
//! variance as `f32`), a face record, the colour ramp over a vertex's float, properties
//! computed per vertex, and the counts of a finished file. Shared by the spool ([`crate::outputs::mesh_spool`]) and the writers that read
//! its records ([`crate::formats::ply`], [`crate::formats::obj`]), so that neither depends on the other.

/// Bytes of a spooled vertex: x, y, z, nx, ny, nz, variance as little-endian `f32` (a PLY
/// vertex record without colour).
pub const VERTEX_BYTES: usize = 28;
/// Bytes of a spooled face: a `u8` 3 and three little-endian `u32` (a PLY face record).
pub const FACE_BYTES: usize = 13;
/// A colour ramp over one float of the vertex records, for the writers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VertexColour {
    /// Which float of the record (2 for z, 6 for the variance).
    pub field: usize,
    /// The value at blue.
    pub low: f32,
    /// The value at red.
    pub high: f32,
}

impl VertexColour {
    /// The colour of a vertex record.
    pub fn of(&self, record: &[u8; VERTEX_BYTES]) -> [u8; 3] {
        let v = float(record, self.field);
        let f = (v - self.low) / (self.high - self.low).max(1e-6);
        ramp(f).map(|c| (c * 255.0).clamp(0.0, 255.0) as u8)
    }
}

/// Named `float` properties computed for each vertex from its position, appended to a PLY
/// mesh's vertex records (the navigation layers on the SLAM mesh, [`crate::navmap::layers`]).
pub trait VertexProperties {
    /// The properties' names, in order.
    fn names(&self) -> &[&'static str];
    /// The values at `position` (x, y, z), one for each name, into `out`.
    fn values(&mut self, position: [f32; 3], out: &mut [f32]);
}

/// Float `k` of a little-endian record.
pub fn float(rec: &[u8], k: usize) -> f32 {
    let b = |i: usize| rec.get(4 * k + i).copied().unwrap_or(0);
    f32::from_le_bytes([b(0), b(1), b(2), b(3)])
}

/// What a finished mesh file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MeshCounts {
    /// Vertices written.
    pub vertices: u64,
    /// Triangles written.
    pub triangles: u64,
}

/// A blue-green-yellow-red ramp over `f` in 0..1 (the picture's and the PLY colours).
pub fn ramp(f: f32) -> [f32; 3] {
    let f = f.clamp(0.0, 1.0);
    let stops = [
        [0.15, 0.3, 0.8],
        [0.1, 0.7, 0.6],
        [0.9, 0.85, 0.3],
        [0.85, 0.3, 0.2],
    ];
    let x = f * 3.0;
    let i = (x.floor() as usize).min(2);
    let t = x - i as f32;
    let (a, b) = (stops[i], stops[i + 1]);
    [
        a[0] + t * (b[0] - a[0]),
        a[1] + t * (b[1] - a[1]),
        a[2] + t * (b[2] - a[2]),
    ]
}
