//! `reconstruction` on the GPU against the CPU reference
//! (`hyrt_cpu::reconstruction::reconstruction`): the CPU G-buffer is uploaded, the
//! GPU stage runs, every surface record must be bit-identical.

mod common;

use common::test_context;
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::formats::{CameraRecord, GBufferTexel, SurfaceRecord, GBUF_HIT};
use hyrt_core::frame::{PreparedScene, PrimaryBarycentrics};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::glam::{Mat4, Vec3};
use hyrt_core::scene::{Camera, Material, Mesh, RenderMode, Scene};
use hyrt_cpu::reconstruction::{reconstruction, reconstruction_reintersected_into};
use hyrt_cpu::visibility_raster::visibility_raster;
use hyrt_gpu::buffers::{FrameBuffers, FrameParams, SceneBuffers};
use hyrt_gpu::reconstruction::ReconstructionStage;
use hyrt_gpu::{gpu_buffer, GpuContext};

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
    barycentrics: PrimaryBarycentrics,
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
    ctx.checked(|| stage.encode(ctx, &mut encoder, &buffers, &frame, barycentrics, None)).unwrap();
    ctx.queue.submit([encoder.finish()]);
    gpu_buffer::read_back(ctx, &frame.surfaces, gbuffer.len()).unwrap()
}

/// Statistics of one comparison.
#[derive(Debug, Default)]
struct Report {
    hits: usize,
}

/// Compare the GPU and CPU surfaces of `gbuffer` record by record, with the raster's and
/// with re-intersected barycentrics: every bit must agree (the shader keeps its products
/// from fusing and mirrors the kernels' order, the camera ray's included).
fn compare(
    ctx: &GpuContext,
    stage: &ReconstructionStage,
    name: &str,
    scene: &PreparedScene,
    cam: &CameraRecord,
    gbuffer: &[GBufferTexel],
) -> Report {
    let eye = Vec3::from(cam.eye);
    let mut r = Report::default();
    for barycentrics in [PrimaryBarycentrics::Raster, PrimaryBarycentrics::Reintersected] {
        let cpu = match barycentrics {
            PrimaryBarycentrics::Raster => reconstruction(gbuffer, &scene.geometry, eye),
            PrimaryBarycentrics::Reintersected => {
                let mut out = Vec::new();
                reconstruction_reintersected_into(gbuffer, &scene.geometry, cam, &mut out);
                out
            }
        };
        let gpu = gpu_reconstruction(ctx, stage, scene, cam, gbuffer, barycentrics);
        assert_eq!(cpu.len(), gpu.len());
        r.hits = 0;
        for (i, (c, q)) in cpu.iter().zip(&gpu).enumerate() {
            let at = format!("{name} ({barycentrics:?}): pixel {i}: cpu {c:?} gpu {q:?}");
            if c.is_hit() {
                q.validate().unwrap_or_else(|e| panic!("{at}: {e}"));
                r.hits += 1;
            }
            assert_eq!(bytemuck::bytes_of(c), bytemuck::bytes_of(q), "{at}");
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
