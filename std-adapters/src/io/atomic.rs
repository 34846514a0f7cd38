//! Writing a file so that a reader never sees it half written: write a temporary file beside
//! it, flush it to disk, then rename it over the target. A failed or interrupted write leaves
//! the previous file (if any) in place and removes the temporary.

use crate::io::error::FileError;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The temporary name used for `path` while it is written: hidden, in the same folder (so the
/// rename cannot cross file systems), tagged with the process id.
pub fn temporary_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp{}", std::process::id()))
}

/// Writes `path` through `fill`, atomically (see the module docs).
pub fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<(), FileError> {
    let tmp = temporary_path(path);
    let result = (|| {
        let mut w = BufWriter::new(File::create(&tmp)?);
        fill(&mut w)?;
        w.flush()?;
        w.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        FileError::at(path, format!("cannot write: {e}"))
    })
}

/// Opens an append-only file of an interrupted run for writing at its end, after cutting it
/// back to its first `keep` bytes; a file shorter than that is an error (it lost data the
/// run counted).
pub fn open_cut(path: &Path, keep: u64) -> Result<File, FileError> {
    use std::io::{Seek, SeekFrom};
    let fail = |what: String| FileError::at(path, format!("cannot resume: {what}"));
    let mut file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(path)
        .map_err(|e| fail(e.to_string()))?;
    let len = file.metadata().map_err(|e| fail(e.to_string()))?.len();
    if len < keep {
        return Err(fail(format!(
            "it holds {len} bytes, the checkpoint counted {keep}"
        )));
    }
    file.set_len(keep).map_err(|e| fail(e.to_string()))?;
    file.seek(SeekFrom::End(0))
        .map_err(|e| fail(e.to_string()))?;
    Ok(file)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_write_keeps_the_old_file_and_leaves_no_temporary() {
        let dir = crate::test_support::scratch_dir("atomic");
        let p = dir.join("out.txt");
        write_atomic(&p, |w| w.write_all(b"first")).unwrap();
        let e = write_atomic(&p, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(e.to_string().contains("out.txt") && e.reason.contains("disk full"));
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "first");
        assert!(!temporary_path(&p).exists());
    }
}
