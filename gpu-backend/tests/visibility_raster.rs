//! `visibility_raster` on the GPU against the CPU reference
//! (`hyrt_cpu::visibility_raster::visibility_raster`), texel by texel.
//!
//! Every texel must be bit-identical: ids, flags, barycentrics and depth. The GPU's
//! fragment shader evaluates the reference kernels itself (exact edge functions of the
//! snapped positions, f32 steps kept from fusing) and writes the reference depth, and
//! vertices are handed to the hardware pre-snapped (see visibility_raster.wgsl). The
//! corpus-wide comparison, with the few recorded exceptions far from the origin, is in
//! hyrt-conformance.

mod common;

use common::test_context;
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::formats::{CameraRecord, GBufferTexel};
use hyrt_core::frame::PreparedScene;
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::glam::{Mat4, Vec3, Vec4};
use hyrt_core::scene::{Camera, Material, Mesh, Object, ObjectSource, RenderMode, Scene};
use hyrt_cpu::visibility_raster::visibility_raster;
use hyrt_gpu::buffers::{FrameBuffers, FrameParams, SceneBuffers};
use hyrt_gpu::visibility_raster::{VisibilityMode, VisibilityRasterStage};
use hyrt_gpu::{gpu_buffer, GpuContext};

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

fn scene_with(objects: Vec<(Mesh, Mat4, RenderMode)>, camera: Option<Camera>) -> Scene {
    let mut s = Scene::default();
    for (mesh, transform, render_mode) in objects {
        s.add_object(mesh, Material::grey(), transform, render_mode);
    }
    s.camera = camera;
    s
}

/// A camera record whose world x, y are window x, y (pixels, y down) and whose world
/// z is the window depth (as in the CPU raster tests): vertices can be put exactly on
/// pixel centres. The eye is at the origin, so the record's eye-relative matrix is this
/// world-to-clip matrix.
fn window_camera(width: u32, height: u32) -> CameraRecord {
    let m = Mat4::from_cols(
        Vec4::new(2.0 / width as f32, 0.0, 0.0, 0.0),
        Vec4::new(0.0, -2.0 / height as f32, 0.0, 0.0),
        Vec4::new(0.0, 0.0, 1.0, 0.0),
        Vec4::new(-1.0, 1.0, 0.0, 1.0),
    );
    CameraRecord {
        view_proj: m.to_cols_array(),
        inv_view_proj: m.inverse().to_cols_array(),
        eye: [0.0, 0.0, 0.0],
        width,
        height,
        near: 0.5,
        far: 1.0,
        pad: 0,
    }
}

/// A window-space grid of `n` x `n` cells (shared edges, both diagonal directions) from
/// `origin` with cell size `cell` at depth `z`.
fn window_grid(n: u32, origin: [f32; 2], cell: f32, z: f32) -> Mesh {
    let mut m = Mesh { name: "grid".into(), ..Default::default() };
    for j in 0..=n {
        for i in 0..=n {
            m.positions.push(Vec3::new(origin[0] + i as f32 * cell, origin[1] + j as f32 * cell, z));
        }
    }
    let row = n + 1;
    for j in 0..n {
        for i in 0..n {
            let a = j * row + i;
            let (b, c, d) = (a + 1, a + row, a + row + 1);
            if (i + j) % 2 == 0 {
                m.indices.push([a, c, b]);
                m.indices.push([b, c, d]);
            } else {
                m.indices.push([a, d, b]);
                m.indices.push([a, c, d]);
            }
        }
    }
    m
}

fn prepare(scene: &Scene) -> PreparedScene {
    let geometry = WorldGeometry::build(scene);
    let bvh = Bvh::build(&geometry, BvhPreset::default());
    PreparedScene::new(geometry, bvh, 0.0)
}

/// Run the GPU stage and read the G-buffer back.
fn gpu_raster(
    ctx: &GpuContext,
    stage: &VisibilityRasterStage,
    scene: &PreparedScene,
    cam: &CameraRecord,
) -> Vec<GBufferTexel> {
    let buffers = SceneBuffers::new(ctx, scene);
    let frame = FrameBuffers::new(ctx, cam.width, cam.height, buffers.light_count).unwrap();
    let params = FrameParams::new(cam.width, cam.height, buffers.light_count, 0.5);
    frame.write_uniforms(ctx, cam, &params);
    // Garbage in the G-buffer first: every texel must be written.
    let garbage = vec![0xA5u8; (cam.width * cam.height) as usize * std::mem::size_of::<GBufferTexel>()];
    ctx.queue.write_buffer(&frame.gbuffer, 0, &garbage);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    ctx.checked(|| stage.encode(ctx, &mut encoder, &buffers, &frame, None)).unwrap();
    ctx.queue.submit([encoder.finish()]);
    gpu_buffer::read_back(ctx, &frame.gbuffer, (cam.width * cam.height) as usize).unwrap()
}

/// Statistics of one comparison.
#[derive(Debug, Default)]
struct Report {
    hits: usize,
    id_mismatches: usize,
}

/// Compare the GPU and CPU G-buffers of `scene` under `cam` texel by texel: every bit
/// must agree.
fn compare(ctx: &GpuContext, stage: &VisibilityRasterStage, name: &str, scene: &Scene, cam: &CameraRecord) -> Report {
    let prepared = prepare(scene);
    let cpu = visibility_raster(&prepared.geometry, cam).gbuffer;
    let gpu = gpu_raster(ctx, stage, &prepared, cam);
    assert_eq!(cpu.len(), gpu.len());
    let mut r = Report::default();
    let mut first = None;
    for (i, (c, q)) in cpu.iter().zip(&gpu).enumerate() {
        let (x, y) = (i as u32 % cam.width, i as u32 / cam.width);
        q.validate().unwrap_or_else(|e| panic!("{name}: pixel ({x}, {y}): {e}"));
        r.hits += c.is_hit() as usize;
        if bytemuck::bytes_of(c) != bytemuck::bytes_of(q) {
            r.id_mismatches += usize::from((c.triangle, c.object, c.flags) != (q.triangle, q.object, q.flags));
            first.get_or_insert(format!("pixel ({x}, {y}): cpu {c:?} gpu {q:?}"));
        }
    }
    eprintln!("{name}: {} x {}: {:?}", cam.width, cam.height, r);
    assert!(first.is_none(), "{name}: texels differ ({} in ids); first at {}", r.id_mismatches, first.unwrap());
    r
}

// ---------------------------------------------------------------------------------------------
// Tests
// ---------------------------------------------------------------------------------------------

#[test]
fn visibility_raster_reports_its_triangle_id_source() {
    let Some(ctx) = test_context() else { return };
    let stage = VisibilityRasterStage::new(&ctx);
    eprintln!("adapter: {}; visibility_raster ids via {}", ctx.describe(), stage.triangle_id_source());
    let expect = if ctx.primitive_index {
        hyrt_gpu::visibility_raster::ID_FROM_PRIMITIVE_INDEX
    } else {
        hyrt_gpu::visibility_raster::ID_FROM_FLAT_VERTEX_OUTPUT
    };
    assert_eq!(stage.triangle_id_source(), expect);
}

#[test]
fn visibility_raster_flat_vertex_ids_equal_primitive_index_ids() {
    let Some(ctx) = test_context() else { return };
    let flat = VisibilityRasterStage::with_id_source(&ctx, false);
    assert_eq!(flat.triangle_id_source(), hyrt_gpu::visibility_raster::ID_FROM_FLAT_VERTEX_OUTPUT);
    let scene = Scene::default_scene();
    let cam = CameraRecord::new(&scene.camera.unwrap(), 67, 41);
    // The fallback variant against the CPU, and (where the device has it) bit for bit
    // against the primitive_index variant.
    let r = compare(&ctx, &flat, "default scene, flat ids", &scene, &cam);
    assert!(r.hits > 0);
    if ctx.primitive_index {
        let builtin = VisibilityRasterStage::with_id_source(&ctx, true);
        let prepared = prepare(&scene);
        let a = gpu_raster(&ctx, &flat, &prepared, &cam);
        let b = gpu_raster(&ctx, &builtin, &prepared, &cam);
        assert!(a.iter().zip(&b).all(|(a, b)| a.to_bits() == b.to_bits()));
    }
}

#[test]
fn visibility_raster_default_scene_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let stage = VisibilityRasterStage::new(&ctx);
    let scene = Scene::default_scene();
    for (w, h) in [(67, 41), (160, 90)] {
        let cam = CameraRecord::new(&scene.camera.unwrap(), w, h);
        let r = compare(&ctx, &stage, "default scene", &scene, &cam);
        assert!(r.hits > (w * h) as usize / 4);
    }
}

#[test]
fn visibility_raster_hardware_interpolated_mode_draws_the_same_pass_approximately() {
    // The benchmark peer's mode: the device's own interpolation. Not bit-identical (that
    // is the point of the exact mode) but the same picture: ids agree on nearly every
    // pixel and every texel is well formed.
    let Some(ctx) = test_context() else { return };
    let stage = VisibilityRasterStage::with_mode(&ctx, VisibilityMode::HardwareInterpolated);
    assert_eq!(stage.mode(), VisibilityMode::HardwareInterpolated);
    let scene = Scene::default_scene();
    let cam = CameraRecord::new(&scene.camera.unwrap(), 96, 54);
    let prepared = prepare(&scene);
    let cpu = visibility_raster(&prepared.geometry, &cam).gbuffer;
    let gpu = gpu_raster(&ctx, &stage, &prepared, &cam);
    let ids = |t: &GBufferTexel| (t.triangle, t.object, t.flags);
    let same = cpu.iter().zip(&gpu).filter(|(c, g)| ids(c) == ids(g)).count();
    assert!(gpu.iter().all(|t| t.validate().is_ok()));
    // Ids may differ only where a vertex snaps to the other side of a rounding tie or two
    // depths nearly tie: a few pixels on edges.
    const MIN_SAME_IDS_FRACTION: f64 = 0.99;
    assert!(same as f64 >= MIN_SAME_IDS_FRACTION * cpu.len() as f64, "{same} of {} pixels", cpu.len());
    assert!(gpu.iter().filter(|t| t.is_hit()).count() > cpu.len() / 4);
}

#[test]
fn visibility_raster_window_grids_on_pixel_centres_match_cpu() {
    let Some(ctx) = test_context() else { return };
    let stage = VisibilityRasterStage::new(&ctx);
    let cam = window_camera(64, 64);
    // Vertices on pixel centres, on pixel corners, and one-pixel cells.
    for (n, origin, cell) in [(8, [2.5, 3.5], 4.0), (8, [2.0, 3.0], 4.0), (40, [4.5, 4.5], 1.0)] {
        let scene = scene_with(vec![(window_grid(n, origin, cell, 0.5), Mat4::IDENTITY, RenderMode::Raster)], None);
        let r = compare(&ctx, &stage, "window grid", &scene, &cam);
        assert_eq!(r.id_mismatches, 0, "dyadic window coordinates are exact on both sides");
        assert!(r.hits > 0);
    }
}

#[test]
fn visibility_raster_perspective_grids_and_overlaps_match_cpu() {
    let Some(ctx) = test_context() else { return };
    let stage = VisibilityRasterStage::new(&ctx);
    // A shared-edge grid in perspective, a second one crossing it (depth order flips
    // along the intersection line), one of them ray traced and seen from behind.
    let scene = scene_with(
        vec![
            (Mesh::grid("a", 12), Mat4::from_scale(Vec3::splat(3.0)), RenderMode::Raster),
            (
                Mesh::grid("b", 7),
                Mat4::from_translation(Vec3::new(0.3, 0.2, 0.0))
                    * Mat4::from_rotation_z(0.4)
                    * Mat4::from_rotation_x(2.9)
                    * Mat4::from_scale(Vec3::splat(2.0)),
                RenderMode::RayTraced,
            ),
        ],
        None,
    );
    let camera = Camera {
        eye: Vec3::new(0.7, 2.5, 3.1),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 50.0,
        near: 0.1,
        far: 20.0,
    };
    for (w, h) in [(67, 41), (96, 64)] {
        let cam = CameraRecord::new(&camera, w, h);
        let r = compare(&ctx, &stage, "perspective grids", &scene, &cam);
        assert!(r.hits > (w * h) as usize / 4);
    }
}

#[test]
fn visibility_raster_near_plane_crossing_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let stage = VisibilityRasterStage::new(&ctx);
    // Eye 1 above a ground that extends behind the camera (the CPU test's scene):
    // the triangles under the eye cross the near plane.
    let camera = Camera {
        eye: Vec3::new(0.0, 1.0, 0.0),
        target: Vec3::new(0.0, 1.0, -1.0),
        up: Vec3::Y,
        fov_y_deg: 90.0,
        near: 2.0,
        far: 1000.0,
    };
    let scene =
        scene_with(vec![(Mesh::grid("ground", 16), Mat4::from_scale(Vec3::splat(400.0)), RenderMode::Raster)], None);
    // And one big triangle crossing the near plane, seen from below (a back face).
    let mut tri = Mesh { name: "tri".into(), ..Default::default() };
    tri.positions = vec![Vec3::new(-3.0, 1.5, 1.0), Vec3::new(3.0, 1.5, 1.0), Vec3::new(0.0, 1.5, -30.0)];
    tri.indices = vec![[0, 1, 2]];
    let mut both = scene.clone();
    both.meshes.push(tri);
    both.materials.push(Material::grey());
    both.objects.push(Object {
        id: 1,
        name: "tri".into(),
        mesh: 1,
        transform: Mat4::IDENTITY,
        material: 1,
        render_mode: RenderMode::RayTraced,
        source: ObjectSource::default(),
    });
    let cam = CameraRecord::new(&camera, 64, 64);
    let r = compare(&ctx, &stage, "near plane", &both, &cam);
    assert!(r.hits > 1000);
}

#[test]
fn visibility_raster_clipped_triangles_beyond_the_setup_slots_are_set_up_per_fragment() {
    let Some(ctx) = test_context() else { return };
    let stage = VisibilityRasterStage::new(&ctx);
    // 6,000 thin wedges from behind the eye to the far side of the view, every one
    // crossing the near plane: their fans need more than the 4,096 sub-triangle slots,
    // so some are set up by the setup pass and the rest in the fragment shader (which
    // of them depends on thread order); both must give the reference's texels.
    let camera = Camera {
        eye: Vec3::ZERO,
        target: Vec3::new(0.0, 0.0, -1.0),
        up: Vec3::Y,
        fov_y_deg: 60.0,
        near: 0.5,
        far: 100.0,
    };
    let n = 6000;
    let mut fan = Mesh { name: "wedges".into(), ..Default::default() };
    for i in 0..n {
        let a = i as f32 / n as f32 * std::f32::consts::TAU;
        let (x, y) = (a.cos() * 4.0, a.sin() * 3.0);
        let z = -5.0 - (i % 7) as f32;
        let base = fan.positions.len() as u32;
        fan.positions.extend([Vec3::new(0.0, 0.0, 1.0), Vec3::new(x, y, z), Vec3::new(x * 1.01 + 0.05, y * 1.01, z)]);
        fan.indices.push([base, base + 1, base + 2]);
    }
    let scene = scene_with(vec![(fan, Mat4::IDENTITY, RenderMode::Raster)], None);
    let r = compare(&ctx, &stage, "many clipped", &scene, &CameraRecord::new(&camera, 96, 72));
    assert!(r.hits > 1000, "{r:?}");
}

#[test]
fn visibility_raster_empty_and_non_finite_geometry() {
    let Some(ctx) = test_context() else { return };
    let stage = VisibilityRasterStage::new(&ctx);
    let cam = window_camera(32, 16);
    // No triangles at all: every texel is a miss.
    let empty = prepare(&scene_with(vec![], None));
    let out = gpu_raster(&ctx, &stage, &empty, &cam);
    assert!(out.iter().all(|t| t.to_bits() == GBufferTexel::MISS.to_bits()));
    // NaN, infinite and zero-area triangles draw nothing; a good one after them does.
    let mut m = Mesh { name: "bad".into(), ..Default::default() };
    let nan = f32::NAN;
    let inf = f32::INFINITY;
    for t in [
        [[nan, 2.0], [30.0, 2.0], [2.0, 14.0]],
        [[2.0, 2.0], [inf, 2.0], [2.0, 14.0]],
        [[2.0, 2.0], [30.0, 2.0], [-inf, nan]],
        [[2.0, 2.0], [30.0, 14.0], [16.0, 8.0]],
        [[4.0, 4.0], [12.0, 4.0], [4.0, 12.0]],
    ] {
        let b = m.positions.len() as u32;
        m.positions.extend(t.iter().map(|p| Vec3::new(p[0], p[1], 0.5)));
        m.indices.push([b, b + 1, b + 2]);
    }
    let scene = scene_with(vec![(m, Mat4::IDENTITY, RenderMode::Raster)], None);
    let r = compare(&ctx, &stage, "non-finite", &scene, &cam);
    assert_eq!(r.id_mismatches, 0);
    assert!(r.hits > 0);
    let out = gpu_raster(&ctx, &stage, &prepare(&scene), &cam);
    assert!(out.iter().filter(|t| t.is_hit()).all(|t| t.triangle == 4), "only the last triangle is drawn");
}
