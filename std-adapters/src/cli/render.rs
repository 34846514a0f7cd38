//! `slamesh render`: a picture of any PLY mesh, from above (hill-shaded) or from an oblique
//! angle, coloured by height, with a scale bar, a colour scale and a legend; `--clip-above`
//! leaves out what is above a height (a roof).

use crate::cli::error::CliError;
use crate::formats::ply::read_ply_mesh;
use crate::outputs::topview::map::Cut;
use crate::outputs::topview::{Projection, TopView};
use crate::say;
use clap::{Args, ValueEnum};
use slamesh_core::Point;
use std::path::PathBuf;

/// `slamesh render`'s arguments.
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// The mesh (PLY, e.g. <run dir>/mesh.ply).
    pub mesh: PathBuf,
    /// The picture to write (PNG).
    #[arg(long, default_value = "render.png")]
    pub out: PathBuf,
    /// From above, or obliquely.
    #[arg(long, value_enum, default_value_t = ViewFlag::Top)]
    pub view: ViewFlag,
    /// Oblique view: where the viewer stands, degrees counter-clockwise from +x (-90: south).
    #[arg(long, default_value_t = -90.0, allow_hyphen_values = true)]
    pub azimuth: f64,
    /// Oblique view: how far it looks down, degrees.
    #[arg(long, default_value_t = 35.0, value_parser = elevation)]
    pub elevation: f64,
    /// Pixels on the picture's long side.
    #[arg(long, default_value_t = 1600, value_parser = clap::value_parser!(u32).range(64..=16384))]
    pub pixels: u32,
    /// Leave out the triangles above this height (metres; a triangle by its middle): the roof
    /// of a map of a building.
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub clip_above: Option<f64>,
}

/// `--view`.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewFlag {
    /// Straight down, north up, hill-shaded.
    Top,
    /// From --azimuth, looking down at --elevation.
    Oblique,
}

fn elevation(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    if (5.0..=90.0).contains(&v) {
        Ok(v)
    } else {
        Err("between 5 and 90 degrees".into())
    }
}

/// Draws the mesh and writes the picture.
pub fn render(args: &RenderArgs) -> Result<(), CliError> {
    let mut mesh = read_ply_mesh(&args.mesh)?;
    let cut = args.clip_above.map(|m| Cut::above(m as f32));
    if let Some(cut) = &cut {
        let v = &mesh.vertices;
        mesh.triangles
            .retain(|t| !cut.hides(&t.map(|i| v[i as usize])));
    }
    let projection = match args.view {
        ViewFlag::Top => Projection::Top,
        ViewFlag::Oblique => Projection::Oblique {
            azimuth_deg: args.azimuth,
            elevation_deg: args.elevation,
        },
    };
    // Colours from the 2nd to the 98th percentile of the heights, so that a few stray
    // vertices do not wash the picture out.
    let mut heights: Vec<f32> = mesh.vertices.iter().map(|v| v[2]).collect();
    heights.sort_by(f32::total_cmp);
    let at = |f: f64| {
        heights
            .get(((heights.len() as f64 - 1.0) * f).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    let (z_lo, z_hi) = (at(0.02), at(0.98).max(at(0.02) + 1.0));
    let z_hi = match &cut {
        Some(c) => z_hi.min(c.top()).max(z_lo + 0.5),
        None => z_hi,
    };
    let projected: Vec<Point> = mesh.vertices.iter().map(|&v| projection.apply(v)).collect();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in &projected {
        for k in 0..2 {
            lo[k] = lo[k].min(f64::from(p[k]));
            hi[k] = hi[k].max(f64::from(p[k]));
        }
    }
    if mesh.triangles.is_empty() {
        (lo, hi) = ([0.0; 2], [1.0; 2]);
    }
    let pixels = args.pixels as usize;
    let mut view = match args.view {
        ViewFlag::Top => TopView::new(lo, hi, pixels),
        ViewFlag::Oblique => TopView::oblique(lo, hi, pixels),
    };
    view.projected(
        mesh.triangles.iter().map(|t| {
            let corners = t.map(|i| i as usize);
            (
                corners.map(|i| projected[i]),
                corners.map(|i| mesh.vertices[i]),
            )
        }),
        z_lo,
        z_hi,
    );
    let bar = view.scale_bar();
    view.colour_scale(z_lo, z_hi);
    let mut legend = vec![format!("{} triangles", mesh.triangles.len())];
    legend.extend(cut.as_ref().map(Cut::describe));
    view.legend(&legend);
    view.write_png(&args.out)?;
    let (w, h) = view.size();
    say!(
        "wrote {} ({w} x {h} pixels, {} triangles, heights {z_lo:.1} to {z_hi:.1} m, scale bar {bar} m)",
        args.out.display(),
        mesh.triangles.len()
    );
    Ok(())
}
