//! Frames larger than the device's bindings: the GPU backend renders them in bands of
//! rows (`hyrt_gpu::band`) and returns the CPU reference's frame bit for bit.
//!
//! On lavapipe a storage binding holds 128 MiB: the teaser at 3840x2160 with 4 lights
//! has 398 MB of surfaces and up to 2.1 GB of shadow rays, and renders in 16 bands.

use hyrt_conformance::compare::compare_stages;
use hyrt_conformance::corpus::shared_assets;
use hyrt_conformance::report::gpu_for_tests;
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, FrameOptions};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::glam::Vec3;
use hyrt_core::scene::{Light, Scene};
use hyrt_cpu::backend::CpuBackend;

#[test]
fn gpu_renders_the_teaser_at_3840x2160_with_4_lights_as_the_cpu() {
    let Some(mut gpu) = gpu_for_tests() else { return };
    if shared_assets().is_none() {
        eprintln!("SKIPPED: ../shared/assets not found (the teaser's models)");
        return;
    }
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/teaser.toml");
    let mut scene = Scene::load(&path).unwrap();
    // The teaser's two lights and two more: a warm one low on the left, a cold one high
    // on the right.
    scene.lights.push(Light::Point {
        position: Vec3::new(-6.0, 3.0, -2.0),
        color: Vec3::new(1.0, 0.7, 0.5),
        intensity: 30.0,
        range: None,
    });
    scene.lights.push(Light::Point {
        position: Vec3::new(2.0, 9.0, 2.5),
        color: Vec3::new(0.5, 0.6, 1.0),
        intensity: 50.0,
        range: None,
    });
    assert_eq!(scene.lights.len(), 4);
    let camera = CameraRecord::new(&scene.camera.unwrap(), 3840, 2160);
    let mut cpu = CpuBackend::new(Some(2));
    let prepared = cpu.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    let options = FrameOptions { stage_outputs: true, ..FrameOptions::default() };
    let reference = cpu.render(&prepared, &camera, &options).unwrap();
    let frame = gpu.render(&prepared, &camera, &options).unwrap();
    let bands = gpu.last_frame_bands();
    eprintln!(
        "3840x2160, 4 lights: {} shadow rays, {} bands on the GPU ({})",
        reference.rays.len(),
        bands,
        gpu.describe()
    );
    assert!(bands > 1 || gpu.context().limits.max_storage_buffer_binding_size >= 1 << 31, "{bands} bands");
    assert!(reference.rays.len() > 10_000_000, "{} shadow rays", reference.rays.len());
    for cmp in compare_stages(&reference, &frame) {
        assert!(cmp.is_exact(), "cpu vs gpu: {} / {} differs: {cmp:?}", cmp.stage, cmp.buffer);
    }
    assert_eq!(reference.stats.rays_per_kind, frame.stats.rays_per_kind);
    assert_eq!(reference.stats.bounces, frame.stats.bounces);
    assert_eq!(reference.stats.occluded_shadow_rays, frame.stats.occluded_shadow_rays);
}
