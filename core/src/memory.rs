//! What the host can give a frame: both backends check a frame's host buffers against
//! it before allocating them (the CPU backend every buffer, `hyrt_cpu::memory`; the GPU
//! backend the frame it reads back), so a frame that cannot fit is an error, not an
//! abort.

/// Environment variable capping, in bytes, the memory a frame may count on (below what
/// the system reports): for shared machines, and for tests that must see a refusal
/// whatever the machine has.
pub const MEMORY_LIMIT_ENV: &str = "HYRT_MEMORY_LIMIT";

/// The memory a frame may count on now: `MemAvailable` of `/proc/meminfo` on Linux
/// (what the system can give without swapping), capped by [`MEMORY_LIMIT_ENV`]; `None`
/// where neither is known (the check is then left to the fallible reservations).
pub fn available_bytes() -> Option<u64> {
    let system = std::fs::read_to_string("/proc/meminfo").ok().and_then(|info| {
        let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
        let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kib.saturating_mul(1024))
    });
    let cap = std::env::var(MEMORY_LIMIT_ENV).ok().and_then(|v| v.trim().parse::<u64>().ok());
    match (system, cap) {
        (Some(s), Some(c)) => Some(s.min(c)),
        (s, c) => s.or(c),
    }
}

/// The process's peak resident memory since it started or since the last
/// [`reset_peak_resident_bytes`], in bytes: `VmHWM` of `/proc/self/status` on Linux;
/// `None` elsewhere.
pub fn peak_resident_bytes() -> Option<u64> {
    status_kib("VmHWM:").map(|k| k.saturating_mul(1024))
}

/// The process's resident memory now, in bytes (`VmRSS`); `None` where unknown.
pub fn resident_bytes() -> Option<u64> {
    status_kib("VmRSS:").map(|k| k.saturating_mul(1024))
}

/// Reset the peak [`peak_resident_bytes`] reports to the resident memory now (Linux 4.0+:
/// `5` into `/proc/self/clear_refs`); false where that is not possible.
pub fn reset_peak_resident_bytes() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

fn status_kib(key: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(key))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
