//! Helpers shared by the accuracy test binaries.
//!
//! Each test binary compiles this module and uses a part of it.
#![allow(dead_code)]

use hyrt_accuracy::reference::{render_reference, ReferenceFrame};
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::scene::{Scene, ShadingModel};

/// The world tables of `scene`, its default BVH and its f64 reference at `w` x `h` (the
/// scene needs a camera).
pub fn reference_of(scene: &Scene, w: u32, h: u32) -> (WorldGeometry, Bvh, ReferenceFrame) {
    let g = WorldGeometry::build(scene);
    let bvh = Bvh::build(&g, BvhPreset::default());
    let r = render_reference(&g, &bvh, &scene.camera.expect("the scene has a camera"), w, h);
    (g, bvh, r)
}

/// The default scene with its camera and lights, shaded with the paper's model as the
/// report's accuracy sections shade it (`hyrt_benches`' `REPORT_SHADING`).
pub fn default_scene() -> Scene {
    let mut scene = Scene { shading: ShadingModel::Paper, ..Scene::default_scene() };
    scene.ensure_camera_and_lights();
    scene
}
