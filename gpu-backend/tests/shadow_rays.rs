//! GPU `shadow_rays` against `hyrt_cpu::shadow_rays` (i.e. `Bvh::occluded`): the
//! same occlusion per ray and the same shadow mask, on the default scene, an
//! analytic occluder, rays through shared edges and vertices of closed meshes,
//! directional (t_max = +inf) rays and an empty BVH.

mod common;

use common::test_context;
use glam::{Mat4, Vec3};
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::formats::{CameraRecord, RayRecord, RAY_KIND_SHADOW};
use hyrt_core::frame::PreparedScene;
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::scene::{Material, Mesh, Object, ObjectSource, RenderMode, Scene};
use hyrt_gpu::buffers::{FrameBuffers, FrameParams, SceneBuffers};
use hyrt_gpu::compaction::CompactionStage;
use hyrt_gpu::gpu_buffer::read_back;
use hyrt_gpu::shadow_rays::{ShadowRaysStage, SHADOW_RAYS_WORKGROUP_SIZE};
use hyrt_gpu::GpuContext;

fn prepare(scene: &Scene) -> PreparedScene {
    let geometry = WorldGeometry::build(scene);
    let bvh = Bvh::build(&geometry, BvhPreset::default());
    PreparedScene::new(geometry, bvh, 0.0)
}

fn scene_of(meshes: Vec<(Mesh, Mat4)>) -> Scene {
    let mut scene = Scene::default();
    for (i, (mesh, transform)) in meshes.into_iter().enumerate() {
        scene.objects.push(Object {
            id: i as u32,
            name: mesh.name.clone(),
            mesh: i,
            transform,
            material: i,
            render_mode: RenderMode::RayTraced,
            source: ObjectSource::default(),
        });
        scene.meshes.push(mesh);
        scene.materials.push(Material::grey());
    }
    scene
}

fn shadow_ray(origin: Vec3, direction: Vec3, t_max: f32, pixel: u32) -> RayRecord {
    RayRecord {
        origin: origin.into(),
        t_min: 0.0,
        direction: direction.into(),
        t_max,
        pixel,
        kind: RAY_KIND_SHADOW,
        depth: 0,
        light: 0,
        throughput: [1.0; 3],
        cone: 0.0,
    }
}

/// True if some triangle has an exactly-zero f32 edge function for this ray with
/// the other two not of opposite signs: where both backends decide by the exact sign
/// (`hyrt_core::kernels::ray::meets_zero_edge_tie`).
fn meets_zero_edge(triangles: &[hyrt_core::formats::TriangleRecord], r: &RayRecord) -> bool {
    let (o, d) = (Vec3::from(r.origin), Vec3::from(r.direction));
    triangles.iter().any(|t| {
        let [v0, v1, v2] = t.vertices();
        hyrt_core::kernels::ray::meets_zero_edge_tie(o, d, v0, v1, v2)
    })
}

/// Upload `rays` (with `pixels` x `lights` frame), run the GPU stage; returns
/// (occluded per ray, shadow mask).
fn gpu_shadow_rays(
    ctx: &GpuContext,
    prepared: &PreparedScene,
    rays: &[RayRecord],
    width: u32,
    height: u32,
    lights: u32,
) -> (Vec<u32>, Vec<u32>) {
    let scene_buffers = SceneBuffers::new(ctx, prepared);
    let frame = FrameBuffers::new(ctx, width, height, lights).unwrap();
    let params = FrameParams::new(width, height, lights, 1.0);
    ctx.queue.write_buffer(&frame.params, 0, bytemuck::bytes_of(&params));
    ctx.queue.write_buffer(&frame.rays, 0, bytemuck::cast_slice(rays));
    let count = rays.len() as u32;
    let groups = count.div_ceil(SHADOW_RAYS_WORKGROUP_SIZE);
    let x = groups.min(65_535);
    let y = if groups == 0 { 1 } else { groups.div_ceil(x) };
    ctx.queue.write_buffer(&frame.ray_count, 0, bytemuck::cast_slice(&[count, x, y, 1]));
    // Garbage in the shadow mask: the stage must clear it.
    let pairs = (width * height * lights) as usize;
    ctx.queue.write_buffer(&frame.shadow, 0, bytemuck::cast_slice(&vec![7u32; pairs]));
    let stage = ShadowRaysStage::new(ctx);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    ctx.checked(|| stage.encode(ctx, &mut encoder, &scene_buffers, &frame, None)).unwrap();
    ctx.queue.submit([encoder.finish()]);
    (read_back(ctx, &frame.occluded, rays.len()).unwrap(), read_back(ctx, &frame.shadow, pairs).unwrap())
}

/// Compare with the CPU; returns the indices of mismatching rays (printed).
fn compare(
    ctx: &GpuContext,
    label: &str,
    prepared: &PreparedScene,
    rays: &[RayRecord],
    pixels: (u32, u32),
    lights: u32,
) -> (Vec<usize>, Vec<u32>) {
    let cpu = hyrt_cpu::shadow_rays::shadow_rays(&prepared.bvh, &prepared.geometry, rays);
    let (gpu, mask) = gpu_shadow_rays(ctx, prepared, rays, pixels.0, pixels.1, lights);
    let mismatches: Vec<usize> = (0..rays.len()).filter(|&i| cpu[i] != gpu[i]).collect();
    let occluded = cpu.iter().filter(|&&o| o != 0).count();
    eprintln!("{label}: {} rays, {occluded} occluded on the CPU, {} mismatches", rays.len(), mismatches.len());
    for &i in mismatches.iter().take(10) {
        eprintln!("  ray {i}: cpu {} gpu {}: {:?}", cpu[i], gpu[i], rays[i]);
    }
    // The mask is the CPU's scatter of the GPU's own occlusion results.
    let expected_mask = hyrt_cpu::compaction::shadow_mask(rays, &gpu, (pixels.0 * pixels.1) as usize, lights as usize);
    let expected_mask: Vec<u32> = expected_mask.iter().map(|&m| m as u32).collect();
    assert_eq!(mask, expected_mask, "{label}: shadow mask");
    (mismatches, cpu)
}

#[test]
fn shadow_rays_default_scene_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let scene = Scene::default_scene();
    let prepared = prepare(&scene);
    let camera = scene.camera.unwrap();
    let lights = prepared.geometry.lights.len() as u32;
    for (w, h) in [(67u32, 41u32), (160, 90)] {
        let record = CameraRecord::new(&camera, w, h);
        let vis = hyrt_cpu::visibility_raster::visibility_raster(&prepared.geometry, &record);
        let surfaces = hyrt_cpu::reconstruction::reconstruction(&vis.gbuffer, &prepared.geometry, camera.eye);
        let rays = hyrt_cpu::compaction::compaction(&surfaces, &prepared.geometry.lights);
        let (mismatches, cpu) = compare(&ctx, &format!("default {w}x{h}"), &prepared, &rays, (w, h), lights);
        assert!(cpu.iter().any(|&o| o != 0) && cpu.contains(&0));
        assert!(mismatches.is_empty(), "{} mismatches", mismatches.len());
    }
}

/// A unit square occluder (two triangles) at y = 1 over x, z in [0, 1]; rays from
/// a grid of floor points at y = 0 to a point light at (0.5, 2, 0.5): the ray
/// crosses y = 1 halfway, at the midpoint of the floor point and the light's
/// projection, so it is occluded iff that midpoint lies in the square.
#[test]
fn shadow_rays_analytic_occluder() {
    let Some(ctx) = test_context() else { return };
    let quad = Mesh {
        name: "quad".into(),
        positions: vec![
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ],
        normals: None,
        indices: vec![[0, 2, 1], [0, 3, 2]],
        ..Default::default()
    };
    let prepared = prepare(&scene_of(vec![(quad, Mat4::IDENTITY)]));
    let light = Vec3::new(0.5, 2.0, 0.5);
    let mut rays = Vec::new();
    let mut expected = Vec::new();
    let n = 41;
    for j in 0..n {
        for i in 0..n {
            // Floor points from -1.53 to 2.53: midpoints from -0.515 to 1.515.
            let p = Vec3::new(-1.53 + 4.06 * i as f32 / (n - 1) as f32, 0.0, -1.53 + 4.06 * j as f32 / (n - 1) as f32);
            let mid = (p + light) * 0.5;
            let inside = |c: f32| (0.0..=1.0).contains(&c);
            let margin = |c: f32| (c.abs()).min((c - 1.0).abs()) > 1e-3;
            if margin(mid.x) && margin(mid.z) {
                expected.push(Some(inside(mid.x) && inside(mid.z)));
            } else {
                expected.push(None);
            }
            rays.push(shadow_ray(p, light - p, 1.0 - 1.0 / 65536.0, rays.len() as u32));
        }
    }
    let (mismatches, cpu) = compare(&ctx, "analytic quad", &prepared, &rays, (n * n, 1), 1);
    assert!(mismatches.is_empty());
    for (i, e) in expected.iter().enumerate() {
        if let Some(e) = e {
            assert_eq!(cpu[i] != 0, *e, "ray {i}");
        }
    }
    assert!(cpu.iter().filter(|&&o| o != 0).count() > 100);
}

/// Rays aimed exactly at vertices and along shared edges of closed meshes (a cube,
/// with axis-aligned and diagonal directions, a UV sphere, a torus): rays that
/// cross a closed surface there must be occluded on both backends; grazing ones
/// are compared.
#[test]
fn shadow_rays_through_shared_edges_and_vertices() {
    let Some(ctx) = test_context() else { return };
    let cube = Mesh::cube("cube");
    let sphere = Mesh::uv_sphere("sphere", 16, 8);
    let scene = scene_of(vec![
        (cube, Mat4::IDENTITY),
        (sphere, Mat4::from_translation(Vec3::new(5.0, 0.25, -0.5)) * Mat4::from_scale(Vec3::splat(1.5))),
        (Mesh::torus("torus", 1.0, 0.35, 24, 12), Mat4::from_translation(Vec3::new(-5.0, 0.5, 0.0))),
    ]);
    let prepared = prepare(&scene);
    let g = &prepared.geometry;
    let mut rays = Vec::new();
    let mut must_hit = Vec::new();
    // Targets: every vertex and every edge midpoint of every triangle.
    let mut targets = Vec::new();
    for t in g.stored_table() {
        let [a, b, c] = t.vertices();
        targets.extend([a, b, c, (a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5].map(|p| (p, t.object)));
    }
    // Points inside the cube and the sphere; the torus (object 2) has no such
    // point on its axis, so its rays are compared only.
    let centres = [Vec3::ZERO, Vec3::new(5.0, 0.25, -0.5), Vec3::new(-5.0, 0.5, 0.0)];
    let others = [
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 0.0, -1.0),
        Vec3::new(1.0, 1.0, 1.0),
        Vec3::new(-0.3, 0.7, 0.2),
    ];
    for (k, &(target, object)) in targets.iter().enumerate() {
        let centre = centres[object as usize];
        // Radial: from far outside, through the target, ending inside the mesh
        // (must hit); and one other direction, which may only graze (compared only).
        for (d, must) in [(target - centre, object < 2), (others[k % others.len()], false)] {
            let origin = target + d.normalize() * 10.0;
            let dir = target - origin;
            let t_max = 1.0 + (centre - target).length().min(0.5) / dir.length();
            rays.push(shadow_ray(origin, dir, t_max, rays.len() as u32));
            must_hit.push(must);
        }
    }
    // Grazing rays along cube faces (origin in the face plane: 0 * inf slabs).
    for i in 0..64 {
        let s = -1.0 + 2.0 * i as f32 / 63.0;
        rays.push(shadow_ray(Vec3::new(s, 1.0, 5.0), Vec3::new(0.0, 0.0, -10.0), 1.0, rays.len() as u32));
        must_hit.push(false);
        rays.push(shadow_ray(Vec3::new(1.0, s, 5.0), Vec3::new(0.0, -0.0, -10.0), 1.0, rays.len() as u32));
        must_hit.push(false);
    }
    let count = rays.len() as u32;
    let (mismatches, cpu) = compare(&ctx, "closed meshes", &prepared, &rays, (count, 1), 1);
    let ties = rays.iter().filter(|r| meets_zero_edge(g.stored_table(), r)).count();
    eprintln!("closed meshes: {ties} rays meet an exactly-zero f32 edge function (decided by the exact sign)");
    assert!(ties > 100, "the test must exercise the exact-sign tie rule");
    let leaks: Vec<usize> = (0..rays.len()).filter(|&i| must_hit[i] && cpu[i] == 0).collect();
    assert!(leaks.is_empty(), "CPU leaks through the closed meshes at rays {leaks:?}");
    assert!(mismatches.is_empty(), "{} mismatches", mismatches.len());
}

/// Directional shadow rays (t_max = +inf), invalid rays (zero direction, NaN
/// origin, empty interval) and an empty BVH.
#[test]
fn shadow_rays_directional_invalid_and_empty_bvh() {
    let Some(ctx) = test_context() else { return };
    let scene = Scene::default_scene();
    let prepared = prepare(&scene);
    let mut rays = Vec::new();
    for i in 0..50 {
        let o = Vec3::new(-3.0 + i as f32 * 0.12, 0.01, 1.0 - i as f32 * 0.05);
        rays.push(shadow_ray(o, Vec3::new(0.3, 1.0, -0.4).normalize(), f32::INFINITY, i));
    }
    let mut invalid = shadow_ray(Vec3::ZERO, Vec3::ZERO, 1.0, 50);
    rays.push(invalid);
    invalid.direction = [0.0, 1.0, 0.0];
    invalid.origin = [f32::NAN, 0.0, 0.0];
    invalid.pixel = 51;
    // Invalid rays are reported visible; hyrt_cpu panics on them in debug builds,
    // so compare those on the GPU alone.
    let (occ, _) = gpu_shadow_rays(&ctx, &prepared, &[rays[50], invalid], 52, 1, 1);
    assert_eq!(occ, vec![0, 0]);
    rays.truncate(50);
    let (mismatches, cpu) = compare(&ctx, "directional", &prepared, &rays, (50, 1), 1);
    assert!(mismatches.is_empty());
    assert!(cpu.iter().any(|&o| o != 0) && cpu.contains(&0));

    // Empty BVH: nothing occludes; every ray is lit.
    let empty = prepare(&Scene::default());
    assert!(empty.bvh.is_empty());
    let (occ, mask) = gpu_shadow_rays(&ctx, &empty, &rays, 50, 1, 1);
    assert_eq!(occ, vec![0; 50]);
    assert_eq!(mask, vec![1; 50]);
    // Zero rays: the mask is cleared to SHADOW_NO_RAY.
    let (_, mask) = gpu_shadow_rays(&ctx, &prepared, &[], 5, 1, 2);
    assert_eq!(mask, vec![0; 10]);
}

/// The two stages chained on the GPU, as a frame runs them: compaction writes the
/// ray list and the indirect dispatch arguments, shadow_rays reads them (no
/// readback in between), with timestamp writes where the adapter has them. The
/// result equals the CPU's compaction + shadow_rays + shadow_mask.
#[test]
fn shadow_rays_after_gpu_compaction_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let scene = Scene::default_scene();
    let prepared = prepare(&scene);
    let camera = scene.camera.unwrap();
    let (w, h) = (67u32, 41u32);
    let lights = prepared.geometry.lights.len() as u32;
    let record = CameraRecord::new(&camera, w, h);
    let vis = hyrt_cpu::visibility_raster::visibility_raster(&prepared.geometry, &record);
    let surfaces = hyrt_cpu::reconstruction::reconstruction(&vis.gbuffer, &prepared.geometry, camera.eye);
    let rays = hyrt_cpu::compaction::compaction(&surfaces, &prepared.geometry.lights);
    let occluded = hyrt_cpu::shadow_rays::shadow_rays(&prepared.bvh, &prepared.geometry, &rays);
    let mask = hyrt_cpu::compaction::shadow_mask(&rays, &occluded, (w * h) as usize, lights as usize);

    let scene_buffers = SceneBuffers::new(&ctx, &prepared);
    let frame = FrameBuffers::new(&ctx, w, h, lights).unwrap();
    frame.write_uniforms(&ctx, &record, &FrameParams::new(w, h, lights, 1.0));
    ctx.queue.write_buffer(&frame.surfaces, 0, bytemuck::cast_slice(&surfaces));
    let compaction = CompactionStage::new(&ctx);
    let shadow = ShadowRaysStage::new(&ctx);
    eprintln!("timestamps: {}", ctx.timestamps);
    let queries = ctx.timestamps.then(|| {
        ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("stage timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count: 4,
        })
    });
    // Two frames through the same stages: scratch and buffers are reused.
    for _ in 0..2 {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        ctx.checked(|| {
            compaction.encode(&ctx, &mut encoder, &scene_buffers, &frame, queries.as_ref().map(|q| (q, 0)));
            shadow.encode(&ctx, &mut encoder, &scene_buffers, &frame, queries.as_ref().map(|q| (q, 2)));
        })
        .unwrap();
        ctx.queue.submit([encoder.finish()]);
        let gpu_occluded: Vec<u32> = read_back(&ctx, &frame.occluded, rays.len()).unwrap();
        let gpu_mask: Vec<u32> = read_back(&ctx, &frame.shadow, mask.len()).unwrap();
        let mismatches = (0..rays.len()).filter(|&i| gpu_occluded[i] != occluded[i]).count();
        eprintln!("chained {w}x{h}: {} rays, {mismatches} occlusion mismatches", rays.len());
        assert_eq!(mismatches, 0);
        assert_eq!(gpu_mask, mask.iter().map(|&m| m as u32).collect::<Vec<_>>());
    }
}

/// Pinned: the tie rule. In ray space (the ray is the +z axis from the origin, so the
/// shear is exact) the edge function of p2 -> p0 is `(1 + 2^-23)(-s (1 - 2^-24)) - 1 (-s)`:
/// the first product rounds to exactly `-s`, so the f32 value is 0, while the exact value
/// is `-s (2^-24 - 2^-47) < 0` and the other two edge functions are positive. Both
/// backends take the exact sign (Dekker's error-free products in f32,
/// `hyrt_core::kernels::ray::edge_sign_exact`): the ray misses by about 1e-10. (Before,
/// the GPU counted the zero as on the edge and reported a hit.)
#[test]
fn shadow_rays_pinned_zero_edge_exact_sign() {
    let Some(ctx) = test_context() else { return };
    let s = 1.0 / 1024.0;
    let p0 = Vec3::new(-s, -s * (1.0 - 2f32.powi(-24)), 1.0);
    let p1 = Vec3::new(1.0, -1.0, 1.0);
    let p2 = Vec3::new(1.0 + 2f32.powi(-23), 1.0, 1.0);
    let tri = Mesh {
        name: "tie".into(),
        positions: vec![p0, p1, p2],
        normals: None,
        indices: vec![[0, 1, 2]],
        ..Default::default()
    };
    let prepared = prepare(&scene_of(vec![(tri, Mat4::IDENTITY)]));
    assert_eq!(prepared.geometry.triangle(0).vertices(), [p0, p1, p2], "identity transform keeps the bits");
    // The f32 edge function p2 -> p0 is exactly zero.
    assert_eq!(p2.x * p0.y - p2.y * p0.x, 0.0);
    assert!((p2.x as f64) * (p0.y as f64) - (p2.y as f64) * (p0.x as f64) < 0.0);
    let ray = shadow_ray(Vec3::ZERO, Vec3::new(0.0, 0.0, 2.0), 1.0, 0);
    let cpu = hyrt_cpu::shadow_rays::shadow_rays(&prepared.bvh, &prepared.geometry, &[ray]);
    let (gpu, _) = gpu_shadow_rays(&ctx, &prepared, &[ray], 1, 1, 1);
    assert_eq!((cpu[0], gpu[0]), (0, 0), "both backends: the exact miss");
}
