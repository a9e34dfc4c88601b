//! The `hyrt` program on the GPU backend, on whatever Vulkan adapter is present
//! (lavapipe in CI); the facade's GPU frames are tested in `hyrt/tests/gpu.rs`.

use std::process::Command;

mod common;

use common::gpu_adapter;

#[test]
fn cli_backend_auto_says_what_it_took_and_gpu_fails_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.png");
    let o = Command::new(env!("CARGO_BIN_EXE_hyrt"))
        .env_remove("HYRT_GPU_ALLOW_SOFTWARE")
        .args(["render", "--backend", "auto", "--size", "32x18", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("auto -> "), "auto must say which backend it took: {err}");
    // Without permission for software adapters, `gpu` either finds hardware or says how to allow lavapipe.
    let o = Command::new(env!("CARGO_BIN_EXE_hyrt"))
        .env_remove("HYRT_GPU_ALLOW_SOFTWARE")
        .args(["render", "--backend", "gpu", "--size", "32x18", "--out"])
        .arg(dir.path().join("g.png"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("panicked"), "{err}");
    if !o.status.success() {
        assert!(err.contains("HYRT_GPU_ALLOW_SOFTWARE") || err.contains("no GPU adapter"), "{err}");
    }
}

#[test]
fn cli_backend_gpu_renders_default_scene_and_sponza_with_software_allowed() {
    if !gpu_adapter() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let assets = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets");
    let mut scenes = vec![None];
    if assets.is_dir() {
        scenes.push(Some(assets.join("sponza.glb")));
    }
    for (i, scene) in scenes.iter().enumerate() {
        let out = dir.path().join(format!("gpu{i}.png"));
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_hyrt"));
        cmd.args(["render", "--backend", "gpu", "--allow-software-gpu", "--size", "64x36", "--out"]).arg(&out);
        if let Some(s) = scene {
            cmd.arg(s);
        }
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(String::from_utf8_lossy(&o.stderr).contains("backend: gpu"));
        assert_eq!(image::open(&out).unwrap().width(), 64);
    }
}

/// An animation rendered frame by frame (`--frames --fps`): its moving objects traced
/// through two levels and moved between frames; the GPU's images are the CPU's, byte for
/// byte.
#[test]
fn cli_animation_frames_are_the_same_on_both_backends() {
    if !gpu_adapter() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/animated_box.gltf");
    for backend in ["cpu", "gpu"] {
        let o = Command::new(env!("CARGO_BIN_EXE_hyrt"))
            .env("HYRT_GPU_ALLOW_SOFTWARE", "1")
            .arg("render")
            .arg(&scene)
            .args(["--backend", backend, "--frames", "3", "--fps", "2", "--size", "64x48", "--out"])
            .arg(dir.path().join(format!("{backend}.png")))
            .output()
            .unwrap();
        assert!(o.status.success(), "{backend}: {}", String::from_utf8_lossy(&o.stderr));
    }
    for i in 0..3 {
        let read = |b: &str| image::open(dir.path().join(format!("{b}_{i:04}.png"))).unwrap().to_rgba8().into_raw();
        assert_eq!(read("cpu"), read("gpu"), "frame {i} differs");
    }
}

/// Issue 34 on the GPU backend: a one-model manifest renders its file's PNG.
#[test]
fn cli_one_model_manifest_writes_the_files_png_on_the_gpu() {
    if !gpu_adapter() {
        return;
    }
    common::assert_one_model_manifests_render_their_files(&["--backend", "gpu", "--allow-software-gpu"]);
}
