//! `visibility_raster` on the GPU against the CPU reference
//! (`hyrt_cpu::visibility_raster::visibility_raster`), texel by texel.
//!
//! Ids (triangle, object) and flags are compared exactly; a pixel where they differ
//! must lie within [`EDGE_MARGIN_PX`] of a projected triangle edge (the vertex maths
//! of lavapipe and of the CPU emulation may snap a vertex one subpixel apart) and
//! there may be at most [`MAX_ID_MISMATCHES`] of them per image. Barycentrics and
//! depth are compared on pixels whose ids match.

mod common;

use common::test_context;
use hyrt_conformance::ulp_distance;
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::formats::{CameraRecord, GBufferTexel, TriangleRecord};
use hyrt_core::frame::PreparedScene;
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::glam::{DMat4, DVec4, Mat4, Vec3, Vec4};
use hyrt_core::scene::{Camera, Material, Mesh, Object, ObjectSource, RenderMode, Scene};
use hyrt_cpu::visibility_raster::visibility_raster;
use hyrt_gpu::buffers::{FrameBuffers, FrameParams, SceneBuffers};
use hyrt_gpu::visibility_raster::VisibilityRasterStage;
use hyrt_gpu::{gpu_buffer, GpuContext};

// ---------------------------------------------------------------------------------------------
// Tolerances (each with its cause)
// ---------------------------------------------------------------------------------------------

/// A pixel whose ids or flags differ from the CPU's must have its centre within this
/// distance (px) of a projected triangle edge: lavapipe's vertex maths (fused
/// multiply-adds, `x * (1/w)`) may put a snapped vertex one subpixel (1/256 px) away
/// from the CPU emulation's on rounding boundaries (`hyrt_core::kernels::raster`,
/// "Where this differs from lavapipe").
const EDGE_MARGIN_PX: f64 = 1.0 / 256.0;
/// At most this many id mismatches per image: each needs a pixel centre within
/// 1/256 px of an edge *and* a vertex on a rounding boundary, which is rare.
const MAX_ID_MISMATCHES: usize = 4;
/// Absolute barycentric tolerance (in units of 2^-23, the ulp of 1.0; barycentrics lie
/// in [0, 1], so an ulp bound relative to the value itself is meaningless near 0):
/// lavapipe interpolates `(u, v)` in f32 from plane equations set up on the
/// *unsnapped* f32 window positions, the CPU from exact edge functions of the
/// *snapped* positions in f64. A vertex moved by up to sqrt(2)/512 px changes a
/// barycentric by up to that over the triangle's smallest altitude in pixels, which
/// is several 1e-4 on the small triangles of these scenes; see `BARY_SNAP_GAIN`.
const BARY_ROUNDING_ULPS_OF_ONE: f64 = 64.0;
/// First-order gain from the snap displacement to a barycentric error: up to
/// `3 * SNAP_PX / altitude_px` (three vertices), times 2 margin for the perspective
/// skew of these scenes.
const BARY_SNAP_GAIN: f64 = 6.0;
/// Largest displacement of a snapped vertex from its f32 window position: half a
/// subpixel on each axis.
const SNAP_PX: f64 = std::f64::consts::SQRT_2 / 512.0;
/// Depth rounding tolerance in ulps of the depth value: lavapipe evaluates the z/w
/// plane in f32 (a plane equation, `a + dzdx * x + dzdy * y`), the CPU in f64 from
/// exact edge functions, rounded once.
const DEPTH_ROUNDING_ULPS: f64 = 64.0;
/// First-order gain from the snap displacement to a depth error: lavapipe's plane is
/// set up on the unsnapped f32 window positions, the CPU's on the snapped ones; moving
/// each of three vertices by `SNAP_PX` moves the plane by up to `SNAP_PX * |grad z|`
/// each; times 2 margin.
const DEPTH_SNAP_GAIN: f64 = 6.0;

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
/// pixel centres.
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
        eye: [0.0, 0.0, -1.0],
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
    let params = FrameParams { width: cam.width, height: cam.height, light_count: buffers.light_count, weight: 0.5 };
    frame.write_uniforms(ctx, cam, &params);
    // Garbage in the G-buffer first: every texel must be written.
    let garbage = vec![0xA5u8; (cam.width * cam.height) as usize * std::mem::size_of::<GBufferTexel>()];
    ctx.queue.write_buffer(&frame.gbuffer, 0, &garbage);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    ctx.checked(|| stage.encode(ctx, &mut encoder, &buffers, &frame, None)).unwrap();
    ctx.queue.submit([encoder.finish()]);
    gpu_buffer::read_back(ctx, &frame.gbuffer, (cam.width * cam.height) as usize).unwrap()
}

/// Distance (px, f64) from `p` to the segment `a`-`b`.
fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    let t = if len2 > 0.0 { (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0) } else { 0.0 };
    let q = [a[0] + t * d[0], a[1] + t * d[1]];
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt()
}

/// Window-space outlines (f64) of every triangle, clipped to `0 <= z <= w`.
fn projected_outlines(g: &WorldGeometry, cam: &CameraRecord) -> Vec<Vec<[f64; 3]>> {
    g.triangles.iter().filter_map(|t| outline(t, cam)).collect()
}

/// Window-space outline (f64) of one triangle, clipped to `0 <= z <= w`; None if
/// nothing is left or a vertex is not finite.
fn outline(t: &TriangleRecord, cam: &CameraRecord) -> Option<Vec<[f64; 3]>> {
    let vp = DMat4::from_cols_array(&cam.view_proj.map(f64::from));
    let (w, h) = (cam.width as f64, cam.height as f64);
    {
        let mut poly: Vec<DVec4> = t.vertices().iter().map(|v| vp * v.as_dvec3().extend(1.0)).collect();
        if !poly.iter().all(|p| p.is_finite()) {
            return None;
        }
        for plane in [|p: DVec4| p.z, |p: DVec4| p.w - p.z] {
            let mut next = Vec::new();
            for i in 0..poly.len() {
                let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
                let (da, db) = (plane(a), plane(b));
                if da >= 0.0 {
                    next.push(a);
                }
                if (da >= 0.0) != (db >= 0.0) {
                    next.push(a + (b - a) * (da / (da - db)));
                }
            }
            poly = next;
        }
        if poly.len() < 3 {
            return None;
        }
        Some(poly.iter().map(|p| [(p.x / p.w * 0.5 + 0.5) * w, (0.5 - p.y / p.w * 0.5) * h, p.z / p.w]).collect())
    }
}

/// Distance from the centre of pixel `(x, y)` to the nearest projected edge.
fn edge_distance(outlines: &[Vec<[f64; 3]>], x: u32, y: u32) -> f64 {
    let p = [x as f64 + 0.5, y as f64 + 0.5];
    let mut best = f64::INFINITY;
    for poly in outlines {
        for i in 0..poly.len() {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            best = best.min(segment_distance(p, [a[0], a[1]], [b[0], b[1]]));
        }
    }
    best
}

/// Magnitude of the screen-space gradient (per px) of the window depth over a
/// projected outline (z/w is affine in screen space: any three corners give it).
fn depth_gradient(outline: &[[f64; 3]]) -> f64 {
    let (a, b, c) = (outline[0], outline[1], outline[2]);
    let (ux, uy, uz) = (b[0] - a[0], b[1] - a[1], b[2] - a[2]);
    let (vx, vy, vz) = (c[0] - a[0], c[1] - a[1], c[2] - a[2]);
    let det = ux * vy - uy * vx;
    if det == 0.0 {
        return f64::INFINITY;
    }
    let gx = (uz * vy - uy * vz) / det;
    let gy = (ux * vz - uz * vx) / det;
    (gx * gx + gy * gy).sqrt()
}

/// Smallest altitude (px) of a projected (clipped) outline: twice its area over its
/// longest chord.
fn min_altitude(outline: &[[f64; 3]]) -> f64 {
    let n = outline.len();
    let mut area2 = 0.0;
    for i in 0..n {
        let (a, b) = (outline[i], outline[(i + 1) % n]);
        area2 += a[0] * b[1] - b[0] * a[1];
    }
    let mut longest: f64 = 0.0;
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (outline[i], outline[j]);
            longest = longest.max(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt());
        }
    }
    area2.abs() / longest.max(f64::MIN_POSITIVE)
}

/// Statistics of one comparison.
#[derive(Debug, Default)]
struct Report {
    hits: usize,
    id_mismatches: usize,
    worst_mismatch_edge_px: f64,
    worst_bary_ulps_of_one: f64,
    worst_bary_over_tolerance: f64,
    worst_depth_ulps: u64,
    worst_depth_over_tolerance: f64,
}

/// Compare the GPU and CPU G-buffers of `scene` under `cam`; assert the bounds.
fn compare(ctx: &GpuContext, stage: &VisibilityRasterStage, name: &str, scene: &Scene, cam: &CameraRecord) -> Report {
    let prepared = prepare(scene);
    let g = &prepared.geometry;
    let cpu = visibility_raster(g, cam).gbuffer;
    let gpu = gpu_raster(ctx, stage, &prepared, cam);
    assert_eq!(cpu.len(), gpu.len());
    let outlines = projected_outlines(g, cam);
    let vp = DMat4::from_cols_array(&cam.view_proj.map(f64::from));
    let mut r = Report::default();
    for (i, (c, q)) in cpu.iter().zip(&gpu).enumerate() {
        let (x, y) = (i as u32 % cam.width, i as u32 / cam.width);
        q.validate().unwrap_or_else(|e| panic!("{name}: pixel ({x}, {y}): {e}"));
        r.hits += c.is_hit() as usize;
        let ids = |t: &GBufferTexel| (t.triangle, t.object, t.flags);
        if ids(c) != ids(q) {
            r.id_mismatches += 1;
            let d = edge_distance(&outlines, x, y);
            eprintln!("{name}: id mismatch at ({x}, {y}): cpu {c:?} gpu {q:?}, {d:.6} px from an edge");
            r.worst_mismatch_edge_px = r.worst_mismatch_edge_px.max(d);
            assert!(d <= EDGE_MARGIN_PX, "{name}: pixel ({x}, {y}) differs {d} px from the nearest edge");
            continue;
        }
        if !c.is_hit() {
            assert_eq!(c.to_bits(), q.to_bits(), "{name}: miss texel ({x}, {y})");
            continue;
        }
        // Barycentric tolerance from the triangle's projected shape.
        let gi = g.global_triangle(c.object, c.triangle);
        let tri = g.triangles[gi];
        let shape = outline(&tri, cam);
        let altitude = shape.as_ref().map_or(0.0, |o| min_altitude(o));
        let gradient = shape.as_ref().map_or(f64::INFINITY, |o| depth_gradient(o));
        let ws: Vec<f64> = tri.vertices().iter().map(|v| (vp * v.as_dvec3().extend(1.0)).w.abs()).collect();
        let skew =
            ws.iter().cloned().fold(0.0, f64::max) / ws.iter().cloned().fold(f64::INFINITY, f64::min).max(1e-300);
        let one_ulp = f32::EPSILON as f64;
        let bary_tol =
            BARY_ROUNDING_ULPS_OF_ONE * one_ulp + BARY_SNAP_GAIN * skew.min(1e6) * SNAP_PX / altitude.max(1e-9);
        for (a, b) in [(c.bary_u, q.bary_u), (c.bary_v, q.bary_v)] {
            let e = (a as f64 - b as f64).abs();
            r.worst_bary_ulps_of_one = r.worst_bary_ulps_of_one.max(e / one_ulp);
            r.worst_bary_over_tolerance = r.worst_bary_over_tolerance.max(e / bary_tol);
            assert!(e <= bary_tol, "{name}: pixel ({x}, {y}) barycentric {a} vs {b} (tolerance {bary_tol})");
        }
        let du = ulp_distance(c.depth, q.depth);
        r.worst_depth_ulps = r.worst_depth_ulps.max(du);
        let depth_ulp = (f32::from_bits(c.depth.to_bits() + 1) - c.depth) as f64;
        let depth_tol = DEPTH_ROUNDING_ULPS * depth_ulp + DEPTH_SNAP_GAIN * SNAP_PX * gradient;
        let de = (c.depth as f64 - q.depth as f64).abs();
        r.worst_depth_over_tolerance = r.worst_depth_over_tolerance.max(de / depth_tol);
        assert!(de <= depth_tol, "{name}: pixel ({x}, {y}) depth {} vs {} (tolerance {depth_tol})", c.depth, q.depth);
    }
    eprintln!("{name}: {} x {}: {:?}", cam.width, cam.height, r);
    assert!(r.id_mismatches <= MAX_ID_MISMATCHES, "{name}: {} id mismatches", r.id_mismatches);
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
fn visibility_raster_empty_and_non_finite_geometry() {
    let Some(ctx) = test_context() else { return };
    let stage = VisibilityRasterStage::new(&ctx);
    let max = ctx.limits.max_texture_dimension_2d;
    assert!(VisibilityRasterStage::check_size(&ctx, max, 1).is_ok());
    assert!(VisibilityRasterStage::check_size(&ctx, 1, max + 1).is_err());
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
