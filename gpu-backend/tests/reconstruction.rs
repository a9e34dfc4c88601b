//! `reconstruction` on the GPU against the CPU reference
//! (`hyrt_cpu::reconstruction::reconstruction`): the CPU G-buffer is uploaded, the
//! GPU stage runs, every surface record is compared (ids exactly, floats in ulps).

mod common;

use common::test_context;
use hyrt_conformance::ulp_distance;
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::formats::{CameraRecord, GBufferTexel, SurfaceRecord, GBUF_HIT};
use hyrt_core::frame::PreparedScene;
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::glam::{Mat4, Vec3};
use hyrt_core::scene::{Camera, Material, Mesh, RenderMode, Scene};
use hyrt_cpu::reconstruction::reconstruction;
use hyrt_cpu::visibility_raster::visibility_raster;
use hyrt_gpu::buffers::{FrameBuffers, FrameParams, SceneBuffers};
use hyrt_gpu::reconstruction::ReconstructionStage;
use hyrt_gpu::{gpu_buffer, GpuContext};

// ---------------------------------------------------------------------------------------------
// Tolerances (each with its cause)
// ---------------------------------------------------------------------------------------------

/// Position, per component, in ulps of the larger magnitude of the three terms
/// `w*v0`, `u*v1`, `v*v2`: the driver may fuse `w * v0 + u * v1` and `(..) + v * v2`
/// into multiply-adds (one rounding instead of two each), so the sum can differ by a
/// couple of roundings of its terms, which is many ulps of a result that cancels
/// towards zero. Measured on lavapipe: 0 (bit-identical).
const POSITION_ULPS_OF_TERMS: f64 = 4.0;
/// Position error bound, in ulps: a chain of about ten multiplies and adds, any pair
/// of which the driver may fuse (measured: 2 on lavapipe).
const POSITION_ERROR_ULPS: u64 = 8;
/// Normals, per component, in ulps of 1 (unit vectors: an ulp bound relative to a
/// component near zero is meaningless): fused multiply-adds in the interpolation, the
/// cross product and the dot product (a few roundings of values up to 1), `sqrt`
/// (correctly rounded on lavapipe, WGSL allows more) and the division (2.5 ulp in WGSL).
/// Measured on lavapipe: 0 (bit-identical).
const NORMAL_ULPS_OF_ONE: f64 = 16.0;

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

fn prepare(scene: &Scene) -> PreparedScene {
    let geometry = WorldGeometry::build(scene);
    let bvh = Bvh::build(&geometry, BvhPreset::default());
    PreparedScene::new(geometry, bvh, 0.0)
}

/// Run the GPU stage on `gbuffer` and read the surfaces back.
fn gpu_reconstruction(
    ctx: &GpuContext,
    stage: &ReconstructionStage,
    scene: &PreparedScene,
    cam: &CameraRecord,
    gbuffer: &[GBufferTexel],
) -> Vec<SurfaceRecord> {
    let buffers = SceneBuffers::new(ctx, scene);
    let frame = FrameBuffers::new(ctx, cam.width, cam.height, buffers.light_count).unwrap();
    let params = FrameParams::new(cam.width, cam.height, buffers.light_count, 0.5);
    frame.write_uniforms(ctx, cam, &params);
    ctx.queue.write_buffer(&frame.gbuffer, 0, bytemuck::cast_slice(gbuffer));
    // Garbage in the output first: every texel must be written.
    let garbage = vec![0xA5u8; gbuffer.len() * std::mem::size_of::<SurfaceRecord>()];
    ctx.queue.write_buffer(&frame.surfaces, 0, &garbage);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    ctx.checked(|| stage.encode(ctx, &mut encoder, &buffers, &frame, None)).unwrap();
    ctx.queue.submit([encoder.finish()]);
    gpu_buffer::read_back(ctx, &frame.surfaces, gbuffer.len()).unwrap()
}

#[derive(Debug, Default)]
struct Report {
    hits: usize,
    position_exact: usize,
    worst_position_ulps: u64,
    worst_position_ulps_of_terms: f64,
    worst_error_ulps: u64,
    worst_normal_ulps_of_one: f64,
    worst_geometric_normal_ulps_of_one: f64,
}

/// Compare GPU and CPU reconstruction of `gbuffer`; assert the bounds.
fn compare(
    ctx: &GpuContext,
    stage: &ReconstructionStage,
    name: &str,
    scene: &PreparedScene,
    cam: &CameraRecord,
    gbuffer: &[GBufferTexel],
) -> Report {
    let g = &scene.geometry;
    let eye = Vec3::from(cam.eye);
    let cpu = reconstruction(gbuffer, g, eye);
    let gpu = gpu_reconstruction(ctx, stage, scene, cam, gbuffer);
    let mut r = Report::default();
    for (i, ((c, q), t)) in cpu.iter().zip(&gpu).zip(gbuffer).enumerate() {
        let at = format!("{name}: pixel {i}: cpu {c:?} gpu {q:?}");
        assert_eq!((c.object, c.triangle), (q.object, q.triangle), "{at}");
        if !c.is_hit() {
            assert_eq!(bytemuck::bytes_of(c), bytemuck::bytes_of(q), "{at}");
            continue;
        }
        q.validate().unwrap_or_else(|e| panic!("{at}: {e}"));
        r.hits += 1;
        // Scale of the position's terms, per component.
        let tri = g.triangles[c.triangle as usize];
        let (u, v) = (t.bary_u, t.bary_v);
        let w = (1.0 - u) - v;
        let [v0, v1, v2] = tri.vertices();
        r.position_exact += (c.position == q.position) as usize;
        for k in 0..3 {
            let scale = (w * v0[k]).abs().max((u * v1[k]).abs()).max((v * v2[k]).abs());
            let ulp_of_terms = (f32::from_bits(scale.to_bits() + 1) - scale) as f64;
            let e = (c.position[k] as f64 - q.position[k] as f64).abs();
            let in_terms = if e == 0.0 { 0.0 } else { e / ulp_of_terms };
            r.worst_position_ulps = r.worst_position_ulps.max(ulp_distance(c.position[k], q.position[k]));
            r.worst_position_ulps_of_terms = r.worst_position_ulps_of_terms.max(in_terms);
            assert!(in_terms <= POSITION_ULPS_OF_TERMS, "{at}: position[{k}] {in_terms} ulps of its terms");
        }
        let eu = ulp_distance(c.position_error, q.position_error);
        r.worst_error_ulps = r.worst_error_ulps.max(eu);
        assert!(eu <= POSITION_ERROR_ULPS, "{at}: position_error {eu} ulps");
        let one_ulp = f32::EPSILON as f64;
        for k in 0..3 {
            let en = (c.normal[k] as f64 - q.normal[k] as f64).abs() / one_ulp;
            let eg = (c.geometric_normal[k] as f64 - q.geometric_normal[k] as f64).abs() / one_ulp;
            r.worst_normal_ulps_of_one = r.worst_normal_ulps_of_one.max(en);
            r.worst_geometric_normal_ulps_of_one = r.worst_geometric_normal_ulps_of_one.max(eg);
            assert!(en <= NORMAL_ULPS_OF_ONE, "{at}: normal[{k}] {en} ulps of 1");
            assert!(eg <= NORMAL_ULPS_OF_ONE, "{at}: geometric_normal[{k}] {eg} ulps of 1");
        }
    }
    eprintln!("{name}: {} x {}: {r:?}", cam.width, cam.height);
    r
}

fn scene_with(objects: Vec<(Mesh, Mat4, RenderMode)>, camera: Option<Camera>) -> Scene {
    let mut s = Scene::default();
    for (mesh, transform, render_mode) in objects {
        s.add_object(mesh, Material::grey(), transform, render_mode);
    }
    s.camera = camera;
    s
}

// ---------------------------------------------------------------------------------------------
// Tests
// ---------------------------------------------------------------------------------------------

#[test]
fn reconstruction_default_scene_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let stage = ReconstructionStage::new(&ctx);
    let scene = Scene::default_scene();
    let prepared = prepare(&scene);
    for (w, h) in [(67, 41), (160, 90)] {
        let cam = CameraRecord::new(&scene.camera.unwrap(), w, h);
        let gbuffer = visibility_raster(&prepared.geometry, &cam).gbuffer;
        let r = compare(&ctx, &stage, "default scene", &prepared, &cam, &gbuffer);
        assert!(r.hits > (w * h) as usize / 4);
    }
}

#[test]
fn reconstruction_back_faces_degenerate_and_far_triangles_match_cpu() {
    let Some(ctx) = test_context() else { return };
    let stage = ReconstructionStage::new(&ctx);
    // A torus seen partly from inside its hole (back faces, silhouettes where the
    // interpolated normal turns away), a grid far from the origin, and degenerate
    // triangles that a synthetic G-buffer "hits" (zero geometric normal, shading
    // normal falls back to the direction of the eye).
    let mut degenerate = Mesh { name: "degenerate".into(), ..Default::default() };
    degenerate.positions =
        vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 1.0), Vec3::new(2.0, 2.0, 2.0), Vec3::new(0.5, 0.5, 0.5)];
    degenerate.indices = vec![[0, 1, 2], [3, 3, 3]];
    let scene = scene_with(
        vec![
            (Mesh::torus("t", 1.0, 0.4, 24, 12), Mat4::from_rotation_x(0.3), RenderMode::RayTraced),
            (
                Mesh::grid("far", 9),
                Mat4::from_translation(Vec3::new(3.0e4, -2.0, -1.0e4)) * Mat4::from_scale(Vec3::splat(50.0)),
                RenderMode::Raster,
            ),
            (degenerate, Mat4::IDENTITY, RenderMode::Raster),
        ],
        None,
    );
    let prepared = prepare(&scene);
    let camera = Camera {
        eye: Vec3::new(0.2, 0.9, 0.6),
        target: Vec3::new(0.0, -0.5, -1.0),
        up: Vec3::Y,
        fov_y_deg: 80.0,
        near: 0.05,
        far: 100.0,
    };
    let cam = CameraRecord::new(&camera, 64, 48);
    let mut gbuffer = visibility_raster(&prepared.geometry, &cam).gbuffer;
    // Synthetic texels: the far grid and the degenerate triangles at a spread of
    // barycentrics (including the corners and edges), both facings.
    let bary = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.25, 0.5], [0.1, 0.0], [0.3333333, 0.3333333]];
    let mut k = 0;
    for (object, triangles) in [(1u32, 0..162u32), (2, 0..2)] {
        for triangle in triangles {
            let [u, v] = bary[k % bary.len()];
            gbuffer[k] = GBufferTexel { bary_u: u, bary_v: v, depth: 0.5, triangle, object, flags: GBUF_HIT };
            k += 1;
        }
    }
    let r = compare(&ctx, &stage, "torus, far grid, degenerate", &prepared, &cam, &gbuffer);
    assert!(r.hits > 500);
}
