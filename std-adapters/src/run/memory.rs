//! Resident memory of this process, from `/proc/self/status` (Linux; `None` elsewhere).

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

/// Bytes as megabytes (10^6), for reports.
pub fn mb(bytes: u64) -> f64 {
    bytes as f64 / 1e6
}
