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

/// Hands the memory freed so far back to the system, and has large blocks mapped on their own
/// again, as in a fresh process (glibc's `malloc_trim` and its mmap threshold at its starting
/// 128 KB; nothing elsewhere). glibc raises that threshold when a large block is freed, and
/// keeps the next ones in its heap: after a pipeline is dropped (a `--sweep auto` trial's),
/// the next one would add its own to the resident memory (kitti-mini 00: 47.5 MB peak against
/// 35.1 MB without the trial).
#[allow(unsafe_code)] // C functions, the only way to reach glibc's allocator
pub fn release_freed() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: neither takes a pointer; malloc_trim only returns free pages of the heap, and
    // mallopt only sets where the allocator maps blocks of their own.
    unsafe {
        libc::malloc_trim(0);
        libc::mallopt(libc::M_MMAP_THRESHOLD, 128 * 1024);
    }
}

/// Bytes welding holds a layer of a set at most: its slots (its neighbours' border vertices
/// too), clusters, sums, triangles and welded vertices (a set of 1 024 layers took 13.2 MB
/// above the frames' resident memory at the end of `tests/memory.rs`'s run).
pub const WELD_BYTES_PER_LAYER: usize = 14 * 1024;

/// Layers welded together under a memory cap ([`MeshSpool::set_layers`]): a quarter of a run's
/// usual [`SET_LAYERS`], so that welding holds about 3 MB at once (for more seams between
/// sets).
///
/// [`MeshSpool::set_layers`]: crate::outputs::mesh_spool::MeshSpool::set_layers
/// [`SET_LAYERS`]: crate::outputs::mesh_spool::SET_LAYERS
pub const CAPPED_SET_LAYERS: usize = 256;

/// Layers welded together by loop closure's rebuild under a memory cap
/// ([`crate::loop_closure::streaming`]): half of [`CAPPED_SET_LAYERS`], so that its weld and
/// the run's together hold about 5 MB at most.
pub const CLOSING_SET_LAYERS: usize = CAPPED_SET_LAYERS / 2;

/// The rest of the process's growth under a memory cap, beside the pipeline and welding: IO
/// buffers, thread stacks, the allocator's slack.
pub const OTHER_GROWTH_BYTES: usize = 4 << 20;

/// Headroom for the rest of the process under a memory cap, above its resident memory at the
/// start: welding a set of [`CAPPED_SET_LAYERS`] and [`OTHER_GROWTH_BYTES`].
pub const PROCESS_HEADROOM_BYTES: usize =
    CAPPED_SET_LAYERS * WELD_BYTES_PER_LAYER + OTHER_GROWTH_BYTES;

/// What a memory cap leaves to the rest of the process: its resident memory now and
/// [`PROCESS_HEADROOM_BYTES`].
pub fn other_bytes() -> usize {
    rss_bytes().unwrap_or(0) as usize + PROCESS_HEADROOM_BYTES
}

/// Bytes as megabytes (10^6), for reports.
pub fn mb(bytes: u64) -> f64 {
    bytes as f64 / 1e6
}
