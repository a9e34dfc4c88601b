//! Helpers the `hyrt` program's test files share.

use hyrt::{AdapterPolicy, GpuBackend};

/// Whether a GPU adapter (software allowed) is present: fails in CI without one, skips
/// visibly elsewhere.
pub fn gpu_adapter() -> bool {
    let Err(e) = GpuBackend::new(AdapterPolicy::AllowSoftware) else { return true };
    assert!(std::env::var_os("CI").is_none(), "CI needs a GPU adapter (lavapipe): {e}");
    eprintln!("SKIPPED: no GPU adapter: {e}");
    false
}
