//! Shared by the GPU integration tests: `mod common;` in each test file.
#![allow(dead_code)]

use hyrt_gpu::{AdapterPolicy, GpuContext};

/// The context for GPU tests: software adapters allowed; a missing adapter fails
/// in CI and skips, visibly, elsewhere.
pub fn test_context() -> Option<GpuContext> {
    match GpuContext::new(AdapterPolicy::AllowSoftware) {
        Ok(ctx) => Some(ctx),
        Err(e) if std::env::var_os("CI").is_some() => panic!("CI needs a GPU adapter (lavapipe): {e}"),
        Err(e) => {
            eprintln!("SKIPPED: no GPU adapter: {e}");
            None
        }
    }
}
