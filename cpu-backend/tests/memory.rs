//! What a CPU frame needs in memory (`hyrt_cpu::memory`): the per-pixel figures of the
//! module's table, refusal before allocation, and a clean error for frames no machine
//! holds.

use glam::Vec3;
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, Executor, FrameOptions, RenderError};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::plan::FramePlan;
use hyrt_core::scene::{Camera, Scene};
use hyrt_cpu::backend::CpuBackend;
use hyrt_cpu::memory::{check_against, frame_bytes, FrameRun};

#[test]
fn default_scene_frame_bytes_per_pixel_match_the_table() {
    let scene = Scene::default_scene();
    let cpu = CpuBackend::new(Some(1));
    let prepared = cpu.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    assert_eq!(prepared.geometry.lights.len(), 2);
    for max_depth in [0, 4] {
        let plan = FramePlan::new(&prepared, &FrameOptions { max_depth, ..FrameOptions::default() }).unwrap();
        let b = frame_bytes(&plan, Executor::Staged, 100, 50);
        // 8 (raster counts) + 24 (G-buffer) + 48 (surfaces) + 2 x 4 (flags) + 2 (shadow
        // mask) + 3 x 16 (images) = 138; plus 2 x 72 (rays, indices, occlusion) = 282.
        assert_eq!((b.at_least, b.at_most), (138 * 5000, 282 * 5000), "max depth {max_depth}");
    }
    // Fused: 16 (final image), whatever the lights; + 24 (G-buffer) where the frame asks for
    // it; + 24 + 8 (texels, depth and winner between batches) for a batched scene. With
    // bounces (the scene's mirror and glass), at most every pixel bounces: its deferred
    // record twice, 2 x (4 + 24 + 48 + 16) + 8 (sort key) + 8 (link) + 2 x 2 (shadow codes).
    let plan = FramePlan::new(&prepared, &FrameOptions::default()).unwrap();
    assert!(plan.bounce_depth() > 0);
    let b = frame_bytes(&plan, Executor::Fused, 100, 50);
    assert_eq!((b.at_least, b.at_most), (16 * 5000, (16 + 204) * 5000));
    let flat = FramePlan::new(&prepared, &FrameOptions { max_depth: 0, ..FrameOptions::default() }).unwrap();
    let b = frame_bytes(&flat, Executor::Fused, 100, 50);
    assert_eq!((b.at_least, b.at_most), (16 * 5000, 16 * 5000));
    let kept = FrameOptions { keep_gbuffer: true, ..FrameOptions::default() };
    let b = frame_bytes(&flat, FrameRun::new(Executor::Fused, &kept, &prepared.geometry), 100, 50);
    assert_eq!((b.at_least, b.at_most), (40 * 5000, 40 * 5000));
    let batched = FrameRun { executor: Executor::Fused, keep_gbuffer: false, batched: true };
    assert_eq!(frame_bytes(&plan, batched, 100, 50).at_least, 48 * 5000);
    // No lights: no ray list, flags or mask.
    let mut dark = scene.clone();
    dark.lights.clear();
    let prepared = cpu.prepare(WorldGeometry::build(&dark), BvhPreset::default());
    let plan = FramePlan::new(&prepared, &FrameOptions::default()).unwrap();
    let b = frame_bytes(&plan, Executor::Staged, 10, 10);
    assert_eq!(b.at_least, b.at_most);
    assert!(b.at_least <= 128 * 100, "{b:?}");
}

#[test]
fn a_frame_larger_than_the_available_memory_is_refused_with_its_figures() {
    let scene = Scene::default_scene();
    let cpu = CpuBackend::new(Some(1));
    let prepared = cpu.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    let plan = FramePlan::new(&prepared, &FrameOptions::default()).unwrap();
    let need = frame_bytes(&plan, Executor::Staged, 16384, 16384).at_least;
    assert_eq!(need, 138 * 16384 * 16384);
    assert!(check_against(&plan, Executor::Staged, 16384, 16384, None).is_ok());
    assert!(check_against(&plan, Executor::Staged, 16384, 16384, Some(need)).is_ok());
    let e = check_against(&plan, Executor::Staged, 16384, 16384, Some(need - 1)).unwrap_err();
    assert!(
        matches!(e, RenderError::OutOfMemory { backend: "cpu", width: 16384, height: 16384, needed: Some(n), available: Some(a), .. } if n == need && a == need - 1),
        "{e:?}"
    );
    let msg = e.to_string();
    assert!(msg.contains("16384x16384") && msg.contains(&need.to_string()) && msg.contains("available"), "{msg}");
}

/// A frame of 2^20 x 2^20 pixels (the largest the raster accepts) needs about 150 TB:
/// refused by every machine before anything is allocated, and the backend renders the
/// next frame as usual.
#[test]
fn the_largest_frame_is_an_error_not_an_abort() {
    let scene = Scene::default_scene();
    let mut cpu = CpuBackend::new(Some(2));
    let prepared = cpu.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    let cam = scene.camera.unwrap_or(Camera::look_at(Vec3::new(0.0, 1.0, 5.0), Vec3::ZERO, Vec3::Y));
    let side = hyrt_core::kernels::raster::MAX_IMAGE_DIM;
    let e = cpu.render(&prepared, &CameraRecord::new(&cam, side, side), &FrameOptions::default()).unwrap_err();
    assert!(matches!(e, RenderError::OutOfMemory { .. }), "{e:?}");
    let ok = cpu.render(&prepared, &CameraRecord::new(&cam, 64, 32), &FrameOptions::default()).unwrap();
    assert_eq!(ok.final_image.len(), 64 * 32);
}
