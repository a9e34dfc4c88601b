//! Helpers the `hyrt` program's test files share.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

use hyrt::{AdapterPolicy, GpuBackend};

/// The facade's test glTF files (`hyrt/tests/common/gltf.rs`).
#[path = "../../../hyrt/tests/common/gltf.rs"]
pub mod gltf;

/// Whether a GPU adapter (software allowed) is present: fails in CI without one, skips
/// visibly elsewhere.
pub fn gpu_adapter() -> bool {
    let Err(e) = GpuBackend::new(AdapterPolicy::AllowSoftware) else { return true };
    assert!(std::env::var_os("CI").is_none(), "CI needs a GPU adapter (lavapipe): {e}");
    eprintln!("SKIPPED: no GPU adapter: {e}");
    false
}

/// The PNG `hyrt render SCENE --size 64x48 ARGS --out OUT` writes, as bytes.
fn render_png(scene: &Path, args: &[&str], out: &Path) -> Vec<u8> {
    let o = Command::new(env!("CARGO_BIN_EXE_hyrt"))
        .arg("render")
        .arg(scene)
        .args(["--size", "64x48", "--threads", "2"])
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}: {}", scene.display(), String::from_utf8_lossy(&o.stderr));
    std::fs::read(out).unwrap()
}

/// Issue 34: `hyrt render` with `args` (a backend, say) of a one-model manifest writes the
/// PNG of the file alone, byte for byte, for the animated sample at `--time 0.5`, a
/// textured and alpha-masked scene, and `shared/assets/DamagedHelmet.glb` (when
/// `../shared/assets` is there; skipped visibly otherwise). Each file is copied or written
/// into a temporary folder, the manifest beside it naming it by its name.
pub fn assert_one_model_manifests_render_their_files(args: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let copy = |from: PathBuf| {
        let to = dir.path().join(from.file_name().unwrap());
        std::fs::copy(&from, &to).unwrap();
        to
    };
    let mut cases = vec![(copy(root.join("assets/scenes/animated_box.gltf")), vec!["--time", "0.5"])];
    cases.push((gltf::alpha(dir.path()), vec![]));
    let helmet = root.join("../shared/assets/DamagedHelmet.glb");
    if helmet.is_file() {
        cases.push((copy(helmet), vec![]));
    } else {
        eprintln!("SKIPPED: {} not found", helmet.display());
    }
    for (file, extra) in cases {
        let args = [args, &extra].concat();
        let alone = render_png(&file, &args, &dir.path().join("alone.png"));
        let merged = render_png(&gltf::one_model_manifest(&file), &args, &dir.path().join("manifest.png"));
        assert!(alone == merged, "{} {args:?}: the one-model manifest's PNG is not the file's", file.display());
        eprintln!("{} {args:?}: the same PNG", file.display());
    }
}
