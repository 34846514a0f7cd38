//! The run's own files as sinks: the report (`report.json`, its frame records spooled as they
//! come, [`ReportFile`]) and the trajectories (`poses_tum.txt`, `poses_kitti.txt`,
//! [`Trajectories`]). Each is a [`Sink`]: put one in any [`Sinks`](crate::run::Sinks) and it
//! writes what `slamesh run` writes.
//!
//! A run feeds its own through their typed methods rather than through a fan-out, for two
//! reasons: a file the run cannot write stops the run (a failing sink is only dropped), and
//! the report's counts go into the summary both are written from ([`ReportFile::health`]).
//!
//! What is not here, and why: the mesh and the map file (`--save-map`) take the map's cells as
//! a window evicts them and the whole map at the end, so the map's owner writes them
//! ([`crate::run::window::Window::evict_to`], the end of [`crate::run::Run::finish`]). The
//! checkpoint is the run's memory, not an output: it asks the report for its mark
//! ([`ReportFile::mark`]) so that a resumed run cuts the spool back there.
//!
//! Guarantees: every file is written to a temporary name and renamed; a run that used no frame
//! writes its report (every frame's reason) and no trajectory.

use crate::formats::trajectory::{write_kitti_line, write_tum_line};
use crate::io::atomic::{open_cut, write_atomic};
use crate::io::error::FileError;
use crate::run::options::RunOptions;
use crate::run::report::{FrameRecord, Health, OutcomeCost, Summary};
use crate::run::sink::{FrameEvent, Sink, SinkFault};
use serde::Serialize;
use slamesh_core::Pose;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// `report.json`: the run, its configuration and summary, then a record per frame. The records
/// are spooled one JSON object a line as frames come (`.report.frames.spool` beside it), so
/// they cost no memory; the report is made from the spool at the end and the spool removed.
pub struct ReportFile {
    lines: BufWriter<File>,
    spool: PathBuf,
    report: PathBuf,
    head: Head,
}

/// What `report.json` holds before its summary.
#[derive(Debug, Clone)]
struct Head {
    input: String,
    preset: String,
    config: String,
}

impl ReportFile {
    /// A new report for the run `opts` describes, into `opts.out`.
    pub fn create(opts: &RunOptions) -> Result<Self, FileError> {
        let spool = spool_path(&opts.out);
        let file = File::create(&spool)
            .map_err(|e| FileError::at(&spool, format!("cannot create: {e}")))?;
        Ok(Self::with(opts, file))
    }

    /// The report of a run resumed from a checkpoint that marked `bytes` of its spool
    /// ([`mark`](Self::mark)): what was spooled after the mark is cut off.
    pub fn resume(opts: &RunOptions, bytes: u64) -> Result<Self, FileError> {
        Ok(Self::with(opts, open_cut(&spool_path(&opts.out), bytes)?))
    }

    fn with(opts: &RunOptions, file: File) -> Self {
        ReportFile {
            lines: BufWriter::new(file),
            spool: spool_path(&opts.out),
            report: opts.out.join("report.json"),
            head: Head {
                input: opts.input.clone(),
                preset: opts.preset.clone(),
                config: crate::run::config_file::documented_toml(&opts.config, &opts.preset),
            },
        }
    }

    /// Spools one frame's record.
    pub fn add(&mut self, record: &FrameRecord) -> Result<(), FileError> {
        serde_json::to_writer(&mut self.lines, record)
            .map_err(std::io::Error::from)
            .and_then(|()| self.lines.write_all(b"\n"))
            .map_err(|e| self.cannot_write(e))
    }

    /// Writes out what is spooled; returns the spool's length, where a resumed run cuts it.
    pub fn mark(&mut self) -> Result<u64, FileError> {
        self.lines.flush().map_err(|e| self.cannot_write(e))?;
        Ok(self.spool.metadata().map_or(0, |m| m.len()))
    }

    /// How the frames spooled so far went, and what each outcome cost (read back from the
    /// spool a line at a time).
    pub fn health(&mut self) -> Result<(Health, Vec<OutcomeCost>), FileError> {
        self.mark()?;
        Health::of_spool(&self.spool)
    }

    /// Writes `report.json` with `summary` and every spooled record, then removes the spool.
    pub fn write(&mut self, summary: &Summary) -> Result<(), FileError> {
        self.mark()?;
        write_report(&self.report, &self.head, summary, &self.spool)?;
        let _ = std::fs::remove_file(&self.spool);
        Ok(())
    }

    fn cannot_write(&self, e: std::io::Error) -> FileError {
        FileError::at(&self.spool, format!("cannot write: {e}"))
    }
}

impl Sink for ReportFile {
    fn name(&self) -> String {
        "report".into()
    }

    fn frame(&mut self, event: Arc<FrameEvent>) -> Result<(), SinkFault> {
        self.add(&event.record).map_err(SinkFault::from)
    }

    /// With the summary, writes `report.json`; without one, keeps the spool for a resumed run.
    fn finish(&mut self, summary: Option<&Summary>) -> Result<Option<String>, SinkFault> {
        let done = match summary {
            Some(s) => self
                .write(s)
                .map(|()| Some(format!("{}", self.report.display()))),
            None => self.mark().map(|_| None),
        };
        done.map_err(SinkFault::from)
    }
}

/// What a run writes as it goes, beside the sinks' files: the mesh's spool (what the window
/// evicts, then the whole map at the end), the report's spool, the map file being saved
/// (`--save-map`: cells a window evicts go in as they leave), and where its checkpoints go.
pub(crate) struct RunFiles {
    /// The mesh's spool.
    pub(crate) spool: crate::outputs::mesh_spool::MeshSpool,
    /// `report.json`, its frame records spooled as they come.
    pub(crate) report: ReportFile,
    /// The map file being written (`--save-map`).
    pub(crate) saved_map: Option<crate::formats::map_file::MapWriter>,
    /// The checkpoint's file.
    pub(crate) checkpoint: PathBuf,
    /// The path of the saved map the run started from (stamped poses): a map the run saves
    /// keeps it before its own.
    pub(crate) start_path: Vec<(f64, slamesh_core::Pose)>,
}

/// The files a run itself may write into its output folder (its stages' are theirs:
/// [`crate::stage::RunStage::outputs`]).
pub const OWN_FILES: [&str; 6] = [
    "poses_kitti.txt",
    "poses_tum.txt",
    "mesh.ply",
    "mesh.obj",
    "topview.png",
    "report.json",
];

/// Removes from `out` those of `names` a run before left there, so that what the folder holds
/// after a new run is that run's; says which went. A file that cannot be removed is said and
/// left (the run replaces it if it writes it).
pub fn remove_stale<'a>(out: &Path, names: impl IntoIterator<Item = &'a str>) {
    let mut gone = Vec::new();
    for name in names {
        let path = out.join(name);
        if !path.is_file() {
            continue;
        }
        match std::fs::remove_file(&path) {
            Ok(()) => gone.push(name),
            Err(e) => log::warn!(
                "{}: a run before left it, and it cannot be removed: {e}",
                path.display()
            ),
        }
    }
    if !gone.is_empty() {
        log::info!(
            "removed what a run before left in {}: {}",
            out.display(),
            gone.join(", ")
        );
    }
}

/// The spool of a run's frame records in `out`, until `report.json` is written.
fn spool_path(out: &Path) -> PathBuf {
    out.join(".report.frames.spool")
}

/// Writes `report`: `head` and `summary`, then the frame records spooled in `frames` (one JSON
/// object a line).
fn write_report(
    report: &Path,
    head: &Head,
    summary: &Summary,
    frames: &Path,
) -> Result<(), FileError> {
    #[derive(Serialize)]
    struct WithSummary<'a> {
        input: &'a str,
        preset: &'a str,
        config: &'a str,
        summary: &'a Summary,
    }
    let head = WithSummary {
        input: &head.input,
        preset: &head.preset,
        config: &head.config,
        summary,
    };
    let head = serde_json::to_string_pretty(&head)
        .map_err(|e| FileError::at(report, format!("cannot write: {e}")))?;
    write_atomic(report, |w| {
        // The head object without its closing brace, then the streamed frame records.
        let open = head
            .trim_end()
            .strip_suffix('}')
            .unwrap_or(&head)
            .trim_end();
        w.write_all(open.as_bytes())?;
        w.write_all(b",\n  \"frames\": [\n")?;
        let lines = std::io::BufReader::new(File::open(frames)?);
        for (k, line) in std::io::BufRead::lines(lines).enumerate() {
            let line = line?;
            if k > 0 {
                w.write_all(b",\n")?;
            }
            w.write_all(b"    ")?;
            w.write_all(line.as_bytes())?;
        }
        w.write_all(b"\n  ]\n}\n")
    })
}

/// `poses_tum.txt` and `poses_kitti.txt`, written from the run's summary at its end (the poses
/// as loop closure left them).
pub struct Trajectories {
    out: PathBuf,
}

impl Trajectories {
    /// The trajectories of a run into `out`.
    pub fn new(out: &Path) -> Self {
        Trajectories {
            out: out.to_path_buf(),
        }
    }

    /// Writes the summary's poses; nothing when no frame was used.
    pub fn write(&self, summary: &Summary) -> Result<(), FileError> {
        if summary.poses.is_empty() {
            return Ok(());
        }
        // An interrupted run's KITTI file ends where it stopped.
        let frames = summary.interrupted.unwrap_or(summary.frames);
        let stamped: Vec<(usize, f64, Pose)> = summary
            .poses
            .iter()
            .zip(&summary.stamps)
            .map(|(&(i, p), &t)| (i, t, p))
            .collect();
        write_trajectories(&self.out, frames, &stamped)
    }
}

impl Sink for Trajectories {
    fn name(&self) -> String {
        "trajectories".into()
    }

    fn frame(&mut self, _: Arc<FrameEvent>) -> Result<(), SinkFault> {
        Ok(())
    }

    fn finish(&mut self, summary: Option<&Summary>) -> Result<Option<String>, SinkFault> {
        let Some(s) = summary else { return Ok(None) };
        self.write(s)?;
        Ok((!s.poses.is_empty()).then(|| format!("{}", self.out.join("poses_tum.txt").display())))
    }
}

/// Writes `poses_tum.txt` (the used frames, each `(index, stamp, pose)`) and `poses_kitti.txt`
/// (every one of `frames` frames, a skipped one holding the last pose) into `out`.
///
/// The TUM file has one line per used frame with its timestamp; the KITTI file has one line per
/// frame (KITTI files have no timestamps); the report lists the skipped frames.
pub fn write_trajectories(
    out: &Path,
    frames: usize,
    stamped: &[(usize, f64, Pose)],
) -> Result<(), FileError> {
    write_atomic(&out.join("poses_tum.txt"), |w| {
        writeln!(
            w,
            "# timestamp tx ty tz qx qy qz qw (LiDAR pose in the first LiDAR frame)"
        )?;
        stamped
            .iter()
            .try_for_each(|(_, t, p)| write_tum_line(w, *t, p))
    })?;
    write_atomic(&out.join("poses_kitti.txt"), |w| {
        let mut held = Pose::identity();
        let mut next = stamped.iter().peekable();
        for i in 0..frames {
            if let Some((_, _, p)) = next.next_if(|(j, _, _)| *j == i) {
                held = *p;
            }
            write_kitti_line(w, &held)?;
        }
        Ok(())
    })
}
