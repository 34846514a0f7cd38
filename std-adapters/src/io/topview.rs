//! A picture of the mesh from above: triangles rasterised top-down, coloured by height and
//! shaded by slope, with trajectories drawn over it; written as PNG.

use crate::io::atomic::write_atomic;
use crate::io::error::FileError;
use slamesh_core::{Point, Pose};
use std::path::Path;

/// An RGB image being drawn.
pub struct TopView {
    width: usize,
    height: usize,
    /// World x, y of the image's lower-left corner, and metres per pixel.
    origin: [f64; 2],
    scale: f64,
    rgb: Vec<[u8; 3]>,
    top: Vec<f32>,
}

impl TopView {
    /// An image of the x-y box `[min, max]` (with a margin), at most `max_pixels` on its long
    /// side.
    pub fn new(min: [f64; 2], max: [f64; 2], max_pixels: usize) -> Self {
        let margin = 5.0;
        let (min, max) = (
            [min[0] - margin, min[1] - margin],
            [max[0] + margin, max[1] + margin],
        );
        let scale = ((max[0] - min[0]).max(max[1] - min[1]) / max_pixels.max(16) as f64).max(1e-3);
        let width = ((max[0] - min[0]) / scale).ceil() as usize + 1;
        let height = ((max[1] - min[1]) / scale).ceil() as usize + 1;
        TopView {
            width,
            height,
            origin: min,
            scale,
            rgb: vec![[24, 24, 28]; width * height],
            top: vec![f32::NEG_INFINITY; width * height],
        }
    }

    fn pixel(&self, x: f64, y: f64) -> (f64, f64) {
        (
            (x - self.origin[0]) / self.scale,
            (self.height as f64 - 1.0) - (y - self.origin[1]) / self.scale,
        )
    }

    /// Draws triangles coloured by height between `z_lo` and `z_hi`, the highest on top.
    pub fn triangles(
        &mut self,
        triangles: impl IntoIterator<Item = [Point; 3]>,
        z_lo: f32,
        z_hi: f32,
    ) {
        for t in triangles {
            let p = t.map(|v| self.pixel(v[0] as f64, v[1] as f64));
            let n = {
                let (a, b, c) = (t[0], t[1], t[2]);
                let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                let n = [
                    u[1] * v[2] - u[2] * v[1],
                    u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0],
                ];
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(1e-12);
                n[2].abs() / len
            };
            let z = (t[0][2] + t[1][2] + t[2][2]) / 3.0;
            let colour = shade(ramp((z - z_lo) / (z_hi - z_lo).max(1e-3)), 0.45 + 0.55 * n);
            let (x0, x1) = (
                p.iter().map(|q| q.0).fold(f64::INFINITY, f64::min),
                p.iter().map(|q| q.0).fold(f64::NEG_INFINITY, f64::max),
            );
            let (y0, y1) = (
                p.iter().map(|q| q.1).fold(f64::INFINITY, f64::min),
                p.iter().map(|q| q.1).fold(f64::NEG_INFINITY, f64::max),
            );
            let area =
                (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[2].0 - p[0].0) * (p[1].1 - p[0].1);
            for py in (y0.floor().max(0.0) as usize)
                ..=(y1.ceil().min(self.height as f64 - 1.0).max(0.0) as usize)
            {
                for px in (x0.floor().max(0.0) as usize)
                    ..=(x1.ceil().min(self.width as f64 - 1.0).max(0.0) as usize)
                {
                    let (cx, cy) = (px as f64 + 0.5, py as f64 + 0.5);
                    let inside = if area.abs() < 1e-12 {
                        // Vertical or degenerate seen from above: its outline.
                        (cx - p[0].0).abs() < 1.0 && (cy - p[0].1).abs() < 1.0
                    } else {
                        let e = |a: (f64, f64), b: (f64, f64)| {
                            ((b.0 - a.0) * (cy - a.1) - (cx - a.0) * (b.1 - a.1)) * area.signum()
                        };
                        e(p[0], p[1]) >= 0.0 && e(p[1], p[2]) >= 0.0 && e(p[2], p[0]) >= 0.0
                    };
                    let k = py * self.width + px;
                    if inside && z > self.top[k] {
                        self.top[k] = z;
                        self.rgb[k] = colour;
                    }
                }
            }
        }
    }

    /// Draws a trajectory as a line of `colour`.
    pub fn path(&mut self, poses: &[Pose], colour: [u8; 3]) {
        for w in poses.windows(2) {
            let (a, b) = (w[0].translation.vector, w[1].translation.vector);
            let (pa, pb) = (self.pixel(a.x, a.y), self.pixel(b.x, b.y));
            let steps = ((pb.0 - pa.0).abs().max((pb.1 - pa.1).abs()).ceil() as usize).max(1);
            for i in 0..=steps {
                let f = i as f64 / steps as f64;
                let (x, y) = (pa.0 + f * (pb.0 - pa.0), pa.1 + f * (pb.1 - pa.1));
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (px, py) = (x as i64 + dx, y as i64 + dy);
                    if px >= 0
                        && py >= 0
                        && (px as usize) < self.width
                        && (py as usize) < self.height
                    {
                        self.rgb[py as usize * self.width + px as usize] = colour;
                    }
                }
            }
        }
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Writes the image as an 8-bit RGB PNG (atomically).
    pub fn write_png(&self, path: &Path) -> Result<(), FileError> {
        write_atomic(path, |w| {
            let mut enc = png::Encoder::new(w, self.width as u32, self.height as u32);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            let mut writer = enc.write_header().map_err(std::io::Error::other)?;
            let data: Vec<u8> = self.rgb.iter().flatten().copied().collect();
            writer
                .write_image_data(&data)
                .map_err(std::io::Error::other)?;
            writer.finish().map_err(std::io::Error::other)
        })
    }
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

fn shade(c: [f32; 3], light: f32) -> [u8; 3] {
    c.map(|v| (v * light * 255.0).clamp(0.0, 255.0) as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_and_a_path_land_where_they_should_and_the_png_reads_back() {
        let mut v = TopView::new([0.0, 0.0], [10.0, 10.0], 200);
        let (w, h) = v.size();
        let background = v.rgb[0];
        v.triangles(
            [[[0.0, 0.0, 1.0], [10.0, 0.0, 1.0], [10.0, 10.0, 1.0]]],
            0.0,
            2.0,
        );
        // Below the diagonal is drawn, above it is not.
        let (px, py) = v.pixel(8.0, 2.0);
        assert_ne!(v.rgb[py as usize * w + px as usize], background);
        let (px, py) = v.pixel(2.0, 8.0);
        assert_eq!(v.rgb[py as usize * w + px as usize], background);
        v.path(
            &[
                Pose::translation(1.0, 9.0, 0.0),
                Pose::translation(9.0, 9.0, 0.0),
            ],
            [255, 0, 0],
        );
        let (px, py) = v.pixel(5.0, 9.0);
        assert_eq!(v.rgb[py as usize * w + px as usize], [255, 0, 0]);
        let dir = crate::test_support::scratch_dir("topview");
        v.write_png(&dir.join("t.png")).unwrap();
        let decoder = png::Decoder::new(std::io::BufReader::new(
            std::fs::File::open(dir.join("t.png")).unwrap(),
        ));
        let info = decoder.read_info().unwrap().info().clone();
        assert_eq!((info.width as usize, info.height as usize), (w, h));
    }
}
