//! `slamesh merge`: two saved maps of one site made one ([`crate::merge`]).

use crate::cli::error::CliError;
use crate::merge::{self, MergeSettings};
use crate::say;
use clap::Args;
use std::io::Write;
use std::path::PathBuf;

/// `slamesh merge`'s arguments.
#[derive(Args, Debug)]
pub struct MergeArgs {
    /// The map the result is in the frame of (`run --save-map`).
    pub a: PathBuf,
    /// The map found in A and fused into it.
    pub b: PathBuf,
    /// The merged map file (written only when B was found; a temporary file until then).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write what the merge did as JSON to FILE: the transform, every place of B's path
    /// searched for in A with its scores, cells, layers and seconds.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
}

/// Merges B into A, or says why not.
pub fn merge(args: &MergeArgs) -> Result<(), CliError> {
    let r = merge::merge(&args.a, &args.b, &args.out, &MergeSettings::default())?;
    let found = r.probes.iter().filter(|p| p.found).count();
    let [x, y, z] = r.translation_m;
    let q = r.rotation_xyzw;
    let yaw = 2.0 * q[2].atan2(q[3]);
    say!(
        "slamesh: B found in A at ({x:.2}, {y:.2}, {z:.2}) m, turned {:.1} degrees about z: {found} \
         of {} places along B's path found, two agreeing; {:.1} s searching",
        yaw.to_degrees(),
        r.probes.len(),
        r.seconds[0]
    );
    say!(
        "slamesh: {} cells ({} layers) in A, {} ({}) in B, {} ({}) merged; {} of B's vertices \
         fused in {:.1} s; wrote {}",
        r.cells[0],
        r.layers[0],
        r.cells[1],
        r.layers[1],
        r.cells[2],
        r.layers[2],
        r.vertices_fused,
        r.seconds[1],
        args.out.display()
    );
    if let Some(path) = &args.report {
        crate::io::atomic::write_atomic(path, |w| {
            serde_json::to_writer_pretty(&mut *w, &r).map_err(std::io::Error::other)?;
            writeln!(w)
        })?;
    }
    Ok(())
}
