//! Helpers the `hyrt` facade's test files share: `mod common;` in each.
#![allow(dead_code)]

pub mod gltf;

use std::path::{Path, PathBuf};

use hyrt::{AdapterPolicy, BackendKind, Renderer};

/// The GPU renderer for tests: fails in CI without an adapter, skips visibly elsewhere.
pub fn gpu_renderer() -> Option<Renderer> {
    match Renderer::new(BackendKind::Gpu, Some(2), AdapterPolicy::AllowSoftware) {
        Ok(r) => Some(r),
        Err(e) if std::env::var_os("CI").is_some() => panic!("CI needs a GPU adapter (lavapipe): {e}"),
        Err(e) => {
            eprintln!("SKIPPED: no GPU adapter: {e}");
            None
        }
    }
}

/// `../shared/assets` (the paper's models and DamagedHelmet), or `None`, saying so.
pub fn shared_assets() -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets");
    if p.is_dir() {
        Some(p)
    } else {
        eprintln!("skipping: {} not found", p.display());
        None
    }
}

/// A fresh, empty folder `group/test` under Cargo's per-target temporary folder.
pub fn temp_dir(group: &str, test: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(group).join(test);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
