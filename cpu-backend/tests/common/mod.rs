//! What the soft-shadow tests share (`soft_shadows.rs`, `emissive_lights.rs`): the floor, box
//! and camera of their scene, where its quad light (or the emissive mesh standing for it)
//! lies, and the independent reference they check the frames' visibility against.
//! Each test binary uses part of it.
#![allow(dead_code)]

use glam::{Mat4, Vec3};
use hyrt_core::formats::{CameraRecord, RayRecord};
use hyrt_core::frame::{Backend, Frame, FrameOptions, PreparedScene};
use hyrt_core::kernels::area_light::polygon_irradiance_f64;
use hyrt_core::scene::{
    Ambient, Camera, Environment, EnvironmentMap, Material, MaterialKind, Mesh, RenderMode, Scene, ShadingModel,
};
use hyrt_cpu::backend::CpuBackend;

/// The light: 1 m x 1 m, 3 m above the floor, facing down (it emits to the side of
/// `EDGE_U x EDGE_V`).
pub const CORNER: Vec3 = Vec3::new(-0.5, 3.0, -0.5);
pub const EDGE_U: Vec3 = Vec3::new(1.0, 0.0, 0.0);
pub const EDGE_V: Vec3 = Vec3::new(0.0, 0.0, 1.0);
pub const RADIANCE: f32 = 5.0;
/// The floor's base colour.
pub const BASE: f32 = 0.6;

/// The bar for `visibility_raw.npy` at 256 samples against an independent trace.
pub const VISIBILITY_MAE: f64 = 0.01;

/// A grey diffuse material of base colour `base`.
pub fn material(base: f32) -> Material {
    Material {
        name: "grey".into(),
        base_color: Vec3::splat(base),
        metallic: 0.0,
        roughness: 1.0,
        kind: MaterialKind::Diffuse,
        ..Material::grey()
    }
}

/// The scene without its light: no ambient or environment light, the paper's model (a
/// Lambertian `base / pi` from raster shading), a 10 x 10 floor at y = 0 (left half
/// rasterized, right half ray traced), optionally a box floating between the floor and
/// the light, and the camera.
pub fn floor_scene(with_box: bool) -> Scene {
    let mut scene = Scene { shading: ShadingModel::Paper, ambient: Ambient(0.0), ..Scene::default() };
    let black = EnvironmentMap::new(1, 1, vec![[0.0, 0.0, 0.0, 1.0]]).expect("a black map");
    scene.environment = Environment::Map(std::sync::Arc::new(black));
    for (x, mode) in [(-2.5, RenderMode::Raster), (2.5, RenderMode::RayTraced)] {
        let place = Mat4::from_translation(Vec3::new(x, 0.0, 0.0)) * Mat4::from_scale(Vec3::new(5.0, 1.0, 10.0));
        scene.add_object(Mesh::grid("floor", 8), material(BASE), place, mode);
    }
    if with_box {
        let place = Mat4::from_translation(Vec3::new(0.1, 0.6, 0.0)) * Mat4::from_scale(Vec3::splat(0.3));
        scene.add_object(Mesh::cube("box"), material(0.5), place, RenderMode::Raster);
    }
    scene.camera = Some(Camera::look_at(Vec3::new(0.0, 2.6, 2.2), Vec3::new(0.0, 0.0, 0.0), Vec3::Y));
    scene
}

/// A `w` x `h` frame of `scene` from its camera.
pub fn render(
    cpu: &mut CpuBackend,
    prepared: &PreparedScene,
    scene: &Scene,
    (w, h): (u32, u32),
    options: &FrameOptions,
) -> Frame {
    let camera = CameraRecord::new(&scene.camera.expect("camera"), w, h);
    cpu.render(prepared, &camera, options).expect("frame")
}

/// Frames of `shadow_samples` rays per pixel and area light, without bounces, with every
/// stage output.
pub fn options(shadow_samples: u32) -> FrameOptions {
    FrameOptions { max_depth: 0, shadow_samples, ..FrameOptions::with_stage_outputs() }
}

/// The visibility of the light from `p` (normal `n`) traced towards the centres of a
/// 32 x 32 grid over it, each weighted by its irradiance `cos_light cos_surface / d^2`,
/// with the BVH's scalar any-hit query from `p` lifted 1e-4 along `n` (a plane or a box
/// face: no curvature to escape), ending as the renderer's rays do just short of the light
/// (`1 - 2^-16` of the way: an emissive mesh does not block the rays towards itself).
/// `None` where no grid point lights the surface.
pub fn traced_visibility(prepared: &PreparedScene, p: Vec3, n: Vec3) -> Option<f64> {
    const GRID: usize = 32;
    let light_normal = EDGE_U.cross(EDGE_V).normalize().as_dvec3();
    let origin = p + n * 1e-4;
    let (mut lit, mut all) = (0.0, 0.0);
    for i in 0..GRID {
        for j in 0..GRID {
            let (u, v) = ((i as f32 + 0.5) / GRID as f32, (j as f32 + 0.5) / GRID as f32);
            let q = CORNER + EDGE_U * u + EDGE_V * v;
            let d = (q - p).as_dvec3();
            let (dist, l) = (d.length(), d.normalize());
            let c = (-l.dot(light_normal)).max(0.0) * l.dot(n.as_dvec3()).max(0.0) / (dist * dist);
            if c <= 0.0 {
                continue;
            }
            all += c;
            let ray = RayRecord::query(origin.into(), (q - origin).into(), 0.0, 1.0 - 1.0 / 65536.0);
            if !prepared.bvh.occluded(prepared.geometry.traversal_table(), &ray) {
                lit += c;
            }
        }
    }
    (all > 0.0).then_some(lit / all)
}

/// The relative error of `frame`'s rasterized floor (its hits at x < 0 on the plane
/// y = 0) against the light's closed-form irradiance (Lambert's polygon formula) times the
/// paper's raster shader, Lambert's `BASE / pi` alone: the mean and the worst over those
/// pixels, and how many there are.
pub fn raster_floor_error(frame: &Frame) -> (f64, f64, usize) {
    let corners = [CORNER, CORNER + EDGE_U, CORNER + EDGE_U + EDGE_V, CORNER + EDGE_V].map(|c| c.as_dvec3().to_array());
    let (mut sum, mut count, mut worst) = (0.0f64, 0usize, 0.0f64);
    for (i, s) in frame.surfaces.iter().enumerate() {
        if !(s.is_hit() && s.position[0] < -1e-3 && s.position[1].abs() < 1e-3) {
            continue;
        }
        let p = Vec3::from(s.position).as_dvec3();
        let e = polygon_irradiance_f64(&corners, p.to_array(), [0.0, 1.0, 0.0], RADIANCE as f64);
        let want = BASE as f64 / std::f64::consts::PI * e;
        let got = frame.final_image[i][0] as f64;
        let rel = (got - want).abs() / want;
        sum += rel;
        count += 1;
        worst = worst.max(rel);
    }
    (sum / count as f64, worst, count)
}
