//! What the GPU backend does not render yet is refused with an error, never rendered
//! without it: textures, vertex colours and alpha tests (the CPU backend renders them).

mod common;

use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::RenderError;
use hyrt_core::frame::{Backend, FrameOptions};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::scene::{AlphaMode, Camera, Material, Mesh, RenderMode, Scene};
use hyrt_gpu::backend::GpuBackend;

#[test]
fn alpha_tested_scenes_are_refused_with_a_message() {
    let Some(ctx) = common::test_context() else { return };
    let mut scene = Scene::default();
    let masked = Material { alpha_mode: AlphaMode::Mask { cutoff: 0.5 }, base_alpha: 0.25, ..Material::grey() };
    scene.add_object(Mesh::cube("cube"), masked, glam::Mat4::IDENTITY, RenderMode::Raster);
    let mut gpu = GpuBackend::with_context(ctx).expect("pipelines");
    let prepared =
        hyrt_cpu::backend::CpuBackend::new(Some(1)).prepare(WorldGeometry::build(&scene), BvhPreset::default());
    let camera =
        CameraRecord::new(&Camera::look_at(glam::Vec3::new(0.0, 0.0, 5.0), glam::Vec3::ZERO, glam::Vec3::Y), 16, 16);
    let message = match gpu.render(&prepared, &camera, &FrameOptions::default()) {
        Err(e @ RenderError::Gpu(_)) => e.to_string(),
        other => panic!("expected a GPU error, got {:?}", other.map(|f| f.width)),
    };
    assert!(message.contains("alpha-tested") && message.contains("--backend cpu"), "{message}");
}
