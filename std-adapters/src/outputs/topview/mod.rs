//! A picture of the mesh: triangles rasterised from above (or obliquely), coloured by height,
//! shaded, with trajectories, their start and end, a scale bar, a colour scale and a legend
//! drawn over it; written as PNG. [`map`] makes a run's picture (a roof over the path cut
//! away); [`glyphs`] is the legends' font.
//!
//! From above, the shading is a hill-shade of the drawn heights (light from the north-west,
//! 45 degrees up), so that walls, kerbs and objects read as edges; a triangle is also darker
//! the steeper it is. Obliquely, each triangle is lit from the viewer.

pub mod glyphs;
pub mod map;
pub mod plots;

use crate::formats::mesh_records::ramp;
use crate::io::atomic::write_atomic;
use crate::io::error::FileError;
use slamesh_core::{Point, Pose};
use std::path::Path;

/// Where the picture is seen from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// Straight down, north (+y) up.
    Top,
    /// From the side the `azimuth_deg` (from +x, counter-clockwise) points to, looking down
    /// at `elevation_deg`.
    Oblique {
        /// The viewer's direction from the scene, degrees counter-clockwise from +x.
        azimuth_deg: f64,
        /// How far the view looks down, degrees (90: from above).
        elevation_deg: f64,
    },
}

impl Projection {
    /// A world point in picture coordinates: `x` to the right, `y` up, `z` toward the viewer.
    pub fn apply(&self, p: Point) -> Point {
        match *self {
            Projection::Top => p,
            Projection::Oblique {
                azimuth_deg,
                elevation_deg,
            } => {
                let (sa, ca) = (
                    azimuth_deg.to_radians().sin(),
                    azimuth_deg.to_radians().cos(),
                );
                let (se, ce) = (
                    elevation_deg.to_radians().sin(),
                    elevation_deg.to_radians().cos(),
                );
                let [x, y, z] = p.map(f64::from);
                // Right: perpendicular to the viewer's direction; toward the viewer: the
                // direction tilted up by the elevation; up: the third axis.
                let (rx, ry) = (-sa, ca);
                let toward = [ca * ce, sa * ce, se];
                let right = rx * x + ry * y;
                let depth = toward[0] * x + toward[1] * y + toward[2] * z;
                let up = -se * (ca * x + sa * y) + ce * z;
                [right as f32, up as f32, depth as f32]
            }
        }
    }
}

/// An RGB image being drawn.
pub struct TopView {
    width: usize,
    height: usize,
    /// World x, y of the image's lower-left corner, and metres per pixel.
    origin: [f64; 2],
    scale: f64,
    rgb: Vec<[u8; 3]>,
    top: Vec<f32>,
    /// Whether the drawn heights are hill-shaded (from above) when first drawn over.
    relief: bool,
}

impl TopView {
    /// An image of the x-y box `[min, max]` (with a margin), at most `max_pixels` on its long
    /// side, seen from above.
    pub fn new(min: [f64; 2], max: [f64; 2], max_pixels: usize) -> Self {
        Self::with_margin(min, max, max_pixels, 5.0)
    }

    /// As [`new`](Self::new), with `margin` metres around the box.
    pub fn with_margin(min: [f64; 2], max: [f64; 2], max_pixels: usize, margin: f64) -> Self {
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
            rgb: vec![BACKGROUND; width * height],
            top: vec![f32::NEG_INFINITY; width * height],
            relief: true,
        }
    }

    /// An image of the picture-plane box `[min, max]` of an oblique projection (no
    /// hill-shade: triangles are lit from the viewer).
    pub fn oblique(min: [f64; 2], max: [f64; 2], max_pixels: usize) -> Self {
        TopView {
            relief: false,
            ..Self::new(min, max, max_pixels)
        }
    }

    fn pixel(&self, x: f64, y: f64) -> (f64, f64) {
        (
            (x - self.origin[0]) / self.scale,
            (self.height as f64 - 1.0) - (y - self.origin[1]) / self.scale,
        )
    }

    /// Draws triangles seen from above, coloured by height between `z_lo` and `z_hi`, the
    /// highest on top.
    pub fn triangles(
        &mut self,
        triangles: impl IntoIterator<Item = [Point; 3]>,
        z_lo: f32,
        z_hi: f32,
    ) {
        self.projected(triangles.into_iter().map(|t| (t, t)), z_lo, z_hi);
    }

    /// Draws triangles given as (picture coordinates from [`Projection::apply`], world
    /// corners): coloured by world height between `z_lo` and `z_hi`, the nearest on top.
    pub fn projected(
        &mut self,
        triangles: impl IntoIterator<Item = ([Point; 3], [Point; 3])>,
        z_lo: f32,
        z_hi: f32,
    ) {
        for (t, world) in triangles {
            let p = t.map(|v| self.pixel(v[0] as f64, v[1] as f64));
            // How directly the triangle faces the viewer (from above: how flat it is).
            let facing = {
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
            let z = (world[0][2] + world[1][2] + world[2][2]) / 3.0;
            let depth = (t[0][2] + t[1][2] + t[2][2]) / 3.0;
            let colour = shade(
                ramp((z - z_lo) / (z_hi - z_lo).max(1e-3)),
                0.45 + 0.55 * facing,
            );
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
                        // Seen edge-on (a wall from above): its outline.
                        (cx - p[0].0).abs() < 1.0 && (cy - p[0].1).abs() < 1.0
                    } else {
                        let e = |a: (f64, f64), b: (f64, f64)| {
                            ((b.0 - a.0) * (cy - a.1) - (cx - a.0) * (b.1 - a.1)) * area.signum()
                        };
                        e(p[0], p[1]) >= 0.0 && e(p[1], p[2]) >= 0.0 && e(p[2], p[0]) >= 0.0
                    };
                    let k = py * self.width + px;
                    if inside && depth > self.top[k] {
                        self.top[k] = depth;
                        self.rgb[k] = colour;
                    }
                }
            }
        }
    }

    /// Shades the drawn heights once, before anything is drawn over them: a hill-shade with
    /// light from the north-west at 45 degrees, 1 on flat ground, darker on slopes and steps
    /// facing away, brighter on those facing the light.
    fn shade_relief(&mut self) {
        if !self.relief {
            return;
        }
        self.relief = false;
        let (w, h) = (self.width, self.height);
        let light = [-0.5f64, 0.5, std::f64::consts::FRAC_1_SQRT_2];
        let z = |x: usize, y: usize| {
            let v = self.top[y * w + x];
            v.is_finite().then_some(f64::from(v))
        };
        // A pixel's factor reads only the heights, so the colours are shaded in place.
        for y in 0..h {
            for x in 0..w {
                let Some(c) = z(x, y) else { continue };
                let at = |x: Option<usize>, y: Option<usize>| match (x, y) {
                    (Some(x), Some(y)) if x < w && y < h => z(x, y).unwrap_or(c),
                    _ => c,
                };
                // Image rows run southward: north is y - 1.
                let dzdx =
                    (at(Some(x + 1), Some(y)) - at(x.checked_sub(1), Some(y))) / (2.0 * self.scale);
                let dzdy =
                    (at(Some(x), y.checked_sub(1)) - at(Some(x), Some(y + 1))) / (2.0 * self.scale);
                let n = [-dzdx, -dzdy, 1.0];
                let len = (n[0] * n[0] + n[1] * n[1] + 1.0).sqrt();
                let lit = (n[0] * light[0] + n[1] * light[1] + n[2] * light[2]) / len;
                let f = (0.25 + 0.75 * lit / light[2]).clamp(0.25, 1.3) as f32;
                let k = y * w + x;
                self.rgb[k] = self.rgb[k].map(|v| (f32::from(v) * f).min(255.0) as u8);
            }
        }
    }

    /// Draws a trajectory as a line of `colour`.
    pub fn path(&mut self, poses: &[Pose], colour: [u8; 3]) {
        self.shade_relief();
        for w in poses.windows(2) {
            let (a, b) = (w[0].translation.vector, w[1].translation.vector);
            let (pa, pb) = (self.pixel(a.x, a.y), self.pixel(b.x, b.y));
            let steps = ((pb.0 - pa.0).abs().max((pb.1 - pa.1).abs()).ceil() as usize).max(1);
            for i in 0..=steps {
                let f = i as f64 / steps as f64;
                let (x, y) = (pa.0 + f * (pb.0 - pa.0), pa.1 + f * (pb.1 - pa.1));
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    self.put(x as i64 + dx, y as i64 + dy, colour);
                }
            }
        }
    }

    fn put(&mut self, x: i64, y: i64, colour: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            self.rgb[y as usize * self.width + x as usize] = colour;
        }
    }

    /// Sets the pixels from `(x0, y0)` to `(x1, y1)`, both corners included.
    fn fill(&mut self, x0: i64, x1: i64, y0: i64, y1: i64, colour: [u8; 3]) {
        for y in y0..=y1 {
            for x in x0..=x1 {
                self.put(x, y, colour);
            }
        }
    }

    /// Draws a scale bar in the lower-left corner: a round length (1, 2 or 5 times a power
    /// of ten metres) near a fifth of the width, white on a dark outline, with its length in
    /// metres written above it. Returns the length.
    pub fn scale_bar(&mut self) -> f64 {
        self.shade_relief();
        let want = self.width as f64 * self.scale / 5.0;
        let power = 10f64.powf(want.log10().floor());
        let metres = [5.0, 2.0, 1.0]
            .iter()
            .map(|m| m * power)
            .find(|&m| m <= want)
            .unwrap_or(power);
        let length = (metres / self.scale).round() as i64;
        let (x0, y0) = (12i64, self.height as i64 - 14);
        self.fill(x0 - 1, x0 + length + 1, y0 - 4, y0 + 1, [0, 0, 0]);
        self.fill(x0, x0 + length, y0 - 3, y0, [255, 255, 255]);
        let label = if metres >= 1.0 {
            format!("{metres:.0} m")
        } else {
            format!("{metres} m")
        };
        self.text(x0, y0 - 22, &label);
        metres
    }

    /// Writes `text` in white 3 x 5 glyphs ([`glyphs`]) three pixels a dot, its top-left
    /// corner at `(x, y)`: 12 pixels a character, 15 high.
    fn text(&mut self, x: i64, y: i64, text: &str) {
        let mut at = x;
        for ch in text.chars() {
            let rows = glyphs::glyph(ch);
            for (r, bits) in rows.iter().enumerate() {
                for col in 0..3 {
                    if bits & (0b100 >> col) != 0 {
                        let (px, py) = (at + 3 * col, y + 3 * r as i64);
                        self.fill(px, px + 2, py, py + 2, [255, 255, 255]);
                    }
                }
            }
            at += 12;
        }
    }

    /// Writes `lines` in the upper-left corner, white on a dark box.
    pub fn legend(&mut self, lines: &[String]) {
        self.shade_relief();
        if lines.is_empty() {
            return;
        }
        let widest = lines.iter().map(|l| l.chars().count()).max().unwrap_or(0) as i64;
        let (x0, y0) = (8i64, 8i64);
        self.fill(
            x0,
            x0 + 12 * widest + 8,
            y0,
            y0 + 22 * lines.len() as i64 + 4,
            [0, 0, 0],
        );
        for (k, line) in lines.iter().enumerate() {
            self.text(x0 + 6, y0 + 6 + 22 * k as i64, line);
        }
    }

    /// Writes `text` white on a black box with its top-left corner at world `(x, y)` (a
    /// chart's tick label).
    pub fn label_at(&mut self, x: f64, y: f64, text: &str) {
        self.shade_relief();
        let (px, py) = self.pixel(x, y);
        let (px, py) = (px.round() as i64, py.round() as i64);
        let n = text.chars().count() as i64;
        self.fill(px - 2, px + 12 * n, py - 2, py + 16, [0, 0, 0]);
        self.text(px, py, text);
    }

    /// A square marker of `colour` (with a black outline) at world `(x, y)`: a path's start
    /// or end.
    pub fn marker(&mut self, x: f64, y: f64, colour: [u8; 3]) {
        self.shade_relief();
        let (px, py) = self.pixel(x, y);
        let (px, py) = (px.round() as i64, py.round() as i64);
        self.fill(px - 6, px + 6, py - 6, py + 6, [0, 0, 0]);
        self.fill(px - 4, px + 4, py - 4, py + 4, colour);
    }

    /// The colour scale of heights `z_lo` to `z_hi` (metres) along the right edge, with its
    /// ends' heights written beside it.
    pub fn colour_scale(&mut self, z_lo: f32, z_hi: f32) {
        self.shade_relief();
        let label = |z: f32| format!("{z:.1} m");
        let room = 12 * label(z_lo).len().max(label(z_hi).len()) as i64 + 8;
        let (w, h) = (self.width as i64, self.height as i64);
        let (x1, bar) = (w - room - 10, 14i64);
        let (top, bottom) = (40i64, (h * 2 / 5).max(120).min(h - 30));
        self.fill(x1 - bar - 1, x1 + 1, top - 1, bottom + 1, [0, 0, 0]);
        for y in top..=bottom {
            let f = (bottom - y) as f32 / (bottom - top).max(1) as f32;
            self.fill(x1 - bar, x1, y, y, shade(ramp(f), 1.0));
        }
        self.fill(x1 + 2, w - 4, top - 4, top + 16, [0, 0, 0]);
        self.text(x1 + 6, top - 2, &label(z_hi));
        self.fill(x1 + 2, w - 4, bottom - 14, bottom + 6, [0, 0, 0]);
        self.text(x1 + 6, bottom - 12, &label(z_lo));
    }

    /// The height drawn on top at world `(x, y)` (from above), if anything was drawn there.
    pub fn height_at(&self, x: f64, y: f64) -> Option<f32> {
        let (px, py) = self.pixel(x, y);
        if px < 0.0 || py < 0.0 {
            return None;
        }
        let (px, py) = (px as usize, py as usize);
        (px < self.width && py < self.height)
            .then(|| self.top[py * self.width + px])
            .filter(|z| z.is_finite())
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Writes the image as an 8-bit RGB PNG (atomically).
    pub fn write_png(&mut self, path: &Path) -> Result<(), FileError> {
        self.shade_relief();
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

/// The picture's background.
const BACKGROUND: [u8; 3] = [24, 24, 28];

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
        let background = BACKGROUND;
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

    #[test]
    fn a_step_is_shaded_and_the_scale_bar_is_a_round_length() {
        // A 1 m step down eastward at x = 5: its face looks east, away from the light in the
        // north-west, and is drawn dark; the flat ground on both sides keeps its colour.
        let mut v = TopView::new([0.0, 0.0], [10.0, 10.0], 200);
        let quad = |x0: f32, x1: f32, z: f32| {
            [
                [[x0, 0.0, z], [x1, 0.0, z], [x1, 10.0, z]],
                [[x0, 0.0, z], [x1, 10.0, z], [x0, 10.0, z]],
            ]
        };
        v.triangles(
            quad(0.0, 5.0, 1.0).into_iter().chain(quad(5.0, 10.0, 0.0)),
            -1.0,
            2.0,
        );
        let at = |v: &TopView, x: f64| {
            let (px, py) = v.pixel(x, 5.0);
            v.rgb[py as usize * v.width + px as usize]
        };
        let before = [2.0, 8.0].map(|x| at(&v, x));
        let metres = v.scale_bar();
        assert_eq!(
            [2.0, 8.0].map(|x| at(&v, x)),
            before,
            "flat ground keeps its colour"
        );
        let sum = |c: [u8; 3]| c.iter().map(|&x| u32::from(x)).sum::<u32>();
        let step = (0..8)
            .map(|i| sum(at(&v, 4.7 + 0.08 * f64::from(i))))
            .min()
            .unwrap();
        assert!(
            2 * step < sum(before[0]).min(sum(before[1])),
            "{step} against {before:?}"
        );
        // 20 m across 200-odd pixels: a fifth is 4 m, the bar 2 m.
        assert_eq!(metres, 2.0);
        let (w, h) = v.size();
        let white = v.rgb.iter().filter(|&&c| c == [255, 255, 255]).count();
        assert!(white > 40 && white < w * h / 20, "{white} white pixels");
    }

    #[test]
    fn the_oblique_projection_keeps_lengths_and_looks_down() {
        let p = Projection::Oblique {
            azimuth_deg: -90.0,
            elevation_deg: 30.0,
        };
        // The viewer is south of the scene: +x is to the right, a higher point is higher up
        // the picture, and a point nearer the viewer (south) is nearer.
        let o = p.apply([0.0, 0.0, 0.0]);
        let right = p.apply([1.0, 0.0, 0.0]);
        let high = p.apply([0.0, 0.0, 1.0]);
        let south = p.apply([0.0, -1.0, 0.0]);
        assert!((right[0] - o[0] - 1.0).abs() < 1e-6 && (right[1] - o[1]).abs() < 1e-6);
        assert!(high[1] > o[1] && south[2] > o[2]);
        let length = |a: Point, b: Point| {
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
        };
        assert!((length(o, south) - 1.0).abs() < 1e-6, "a rotation");
        assert_eq!(Projection::Top.apply([1.0, 2.0, 3.0]), [1.0, 2.0, 3.0]);
    }
}
