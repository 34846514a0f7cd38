//! Resident memory of this process, from `/proc/self/status` (Linux; `None` elsewhere), and
//! what a memory cap leaves to the process beside the pipeline.

/// A `/proc/self/status` field in bytes (`VmRSS`, `VmHWM`, ...).
fn status_bytes(field: &str) -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = text.lines().find(|l| l.starts_with(field))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Current resident set size in bytes.
pub fn rss_bytes() -> Option<u64> {
    status_bytes("VmRSS:")
}

/// Peak resident set size of the process so far, in bytes.
pub fn peak_rss_bytes() -> Option<u64> {
    status_bytes("VmHWM:")
}

/// Headroom for the rest of the process under a memory cap, above its resident memory at the
/// start: welding a set of evicted layers or of the final map (about 11 MB for a set of
/// [`SET_LAYERS`](crate::io::mesh_spool::SET_LAYERS), measured in `tests/memory.rs`), IO
/// buffers, thread stacks and the allocator's slack.
pub const PROCESS_HEADROOM_BYTES: usize = 16 << 20;

/// What a memory cap leaves to the rest of the process: its resident memory now and
/// [`PROCESS_HEADROOM_BYTES`].
pub fn other_bytes() -> usize {
    rss_bytes().unwrap_or(0) as usize + PROCESS_HEADROOM_BYTES
}

/// Bytes as megabytes (10^6), for reports.
pub fn mb(bytes: u64) -> f64 {
    bytes as f64 / 1e6
}
