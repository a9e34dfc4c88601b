//! GPU `compaction` against `hyrt_cpu::compaction`: the same ray list, bit for bit,
//! and the scan alone against the sequential compaction.

mod common;

use common::test_context;
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::formats::{CameraRecord, LightRecord, RayRecord, SurfaceRecord};
use hyrt_core::frame::PreparedScene;
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::scan::compact_sequential;
use hyrt_core::scene::Scene;
use hyrt_gpu::buffers::{FrameBuffers, FrameParams, SceneBuffers};
use hyrt_gpu::compaction::CompactionStage;
use hyrt_gpu::gpu_buffer::{read_back, storage, upload};
use hyrt_gpu::scan::SCAN_TILE as COMPACTION_TILE;
use hyrt_gpu::shadow_rays::SHADOW_RAYS_WORKGROUP_SIZE;
use hyrt_gpu::GpuContext;

fn prepare(scene: &Scene) -> PreparedScene {
    let geometry = WorldGeometry::build(scene);
    let bvh = Bvh::build(&geometry, BvhPreset::default());
    PreparedScene::new(geometry, bvh, 0.0)
}

/// CPU surfaces of a frame: visibility raster then reconstruction.
fn cpu_surfaces(prepared: &PreparedScene, scene: &Scene, width: u32, height: u32) -> Vec<SurfaceRecord> {
    let camera = scene.camera.unwrap();
    let record = CameraRecord::new(&camera, width, height);
    let vis = hyrt_cpu::visibility_raster::visibility_raster(&prepared.geometry, &record);
    hyrt_cpu::reconstruction::reconstruction(&vis.gbuffer, &prepared.geometry, camera.eye)
}

/// Run the GPU stage on `surfaces`; returns (ray_count words, rays).
fn gpu_compaction(
    ctx: &GpuContext,
    prepared: &PreparedScene,
    surfaces: &[SurfaceRecord],
    width: u32,
    height: u32,
) -> ([u32; 4], Vec<RayRecord>) {
    let lights = prepared.geometry.lights.len() as u32;
    let scene_buffers = SceneBuffers::new(ctx, prepared);
    let frame = FrameBuffers::new(ctx, width, height, lights).unwrap();
    let params = FrameParams::new(width, height, lights, 1.0);
    ctx.queue.write_buffer(&frame.params, 0, bytemuck::bytes_of(&params));
    ctx.queue.write_buffer(&frame.surfaces, 0, bytemuck::cast_slice(surfaces));
    let stage = CompactionStage::new(ctx);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    ctx.checked(|| stage.encode(ctx, &mut encoder, &scene_buffers, &frame, None)).unwrap();
    ctx.queue.submit([encoder.finish()]);
    let count: Vec<u32> = read_back(ctx, &frame.ray_count, 4).unwrap();
    let rays = read_back::<RayRecord>(ctx, &frame.rays, count[0] as usize).unwrap();
    (count.try_into().unwrap(), rays)
}

fn ray_bits(r: &RayRecord) -> [u32; 16] {
    bytemuck::cast(*r)
}

/// Dispatch arguments for `count` rays, as the stage must write them.
fn expected_dispatch(count: u32) -> [u32; 4] {
    let groups = count.div_ceil(SHADOW_RAYS_WORKGROUP_SIZE);
    let x = groups.min(65_535);
    let y = if groups == 0 { 1 } else { groups.div_ceil(x) };
    [count, x, y, 1]
}

/// Compare GPU and CPU ray lists; identical count and identical records.
fn compare(ctx: &GpuContext, prepared: &PreparedScene, surfaces: &[SurfaceRecord], width: u32, height: u32) -> usize {
    let cpu = hyrt_cpu::compaction::compaction(surfaces, &prepared.geometry.lights);
    let (count, gpu) = gpu_compaction(ctx, prepared, surfaces, width, height);
    assert_eq!(count, expected_dispatch(cpu.len() as u32), "{width}x{height}: ray count / dispatch");
    let mismatches: Vec<usize> = (0..cpu.len()).filter(|&i| ray_bits(&cpu[i]) != ray_bits(&gpu[i])).collect();
    eprintln!("{width}x{height}: {} rays, {} mismatching records", cpu.len(), mismatches.len());
    for &i in mismatches.iter().take(5) {
        eprintln!("  ray {i}: cpu {:?}\n          gpu {:?}", cpu[i], gpu[i]);
    }
    assert!(mismatches.is_empty(), "{width}x{height}: {} ray records differ", mismatches.len());
    cpu.len()
}

#[test]
fn compaction_default_scene_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let scene = Scene::default_scene();
    let prepared = prepare(&scene);
    assert_eq!(prepared.geometry.lights.len(), 2);
    for (w, h) in [(67, 41), (160, 90), (1, 1), (13, 7)] {
        let surfaces = cpu_surfaces(&prepared, &scene, w, h);
        let n = compare(&ctx, &prepared, &surfaces, w, h);
        if w * h > 100 {
            assert!(n > 0, "the default scene has lit pixels");
        }
    }
}

#[test]
fn compaction_all_miss_frame_gives_no_rays() {
    let Some(ctx) = test_context() else { return };
    let scene = Scene::default_scene();
    let prepared = prepare(&scene);
    let surfaces = vec![SurfaceRecord::MISS; 37 * 23];
    assert_eq!(compare(&ctx, &prepared, &surfaces, 37, 23), 0);
}

/// Directional lights (t_max = +inf), a light with zero energy, a light behind
/// every surface, and a point light: synthetic surfaces with varied normals.
#[test]
fn compaction_directional_and_dark_lights_match_cpu() {
    let Some(ctx) = test_context() else { return };
    let scene = Scene::default_scene();
    let mut prepared = prepare(&scene);
    prepared.geometry.lights = vec![
        LightRecord::directional([0.0, -1.0, 0.0], [1.0; 3]),
        LightRecord::point([0.0, 5.0, 0.0], [0.0; 3]),
        LightRecord::point([0.3, 4.0, -1.0], [5.0, 0.0, 1.0]),
        LightRecord::directional([0.6, 0.0, -0.8], [0.0, 0.0, 2.0]),
    ];
    let (w, h) = (29u32, 17u32);
    let mut surfaces = Vec::new();
    for i in 0..w * h {
        if i % 7 == 3 {
            surfaces.push(SurfaceRecord::MISS);
            continue;
        }
        let a = i as f32 * 0.37;
        let n = glam::Vec3::new(a.cos() * 0.6, (a * 0.5).sin(), a.sin() * 0.6).normalize();
        // Positions near zero (where the offset steps land on tiny values), of both signs,
        // and up to 1e6 from the origin; error bounds from zero (no offset, only the
        // step) to a few ulps of 1e6, as reconstruction gives them.
        let far = [1.0, 1.0, 1e3, 1e5, 1e6][(i % 5) as usize];
        let p = glam::Vec3::new((i as f32 - 200.0) * 0.013, (i % 11) as f32 * 0.004 - 0.02, -(i as f32) * 0.01) * far;
        let position_error = [0.0, 1e-6, 3e-7 * far, 0.3][(i % 4) as usize];
        surfaces.push(SurfaceRecord {
            position: p.into(),
            position_error,
            normal: n.into(),
            object: 0,
            geometric_normal: n.into(),
            triangle: 0,
        });
    }
    let n = compare(&ctx, &prepared, &surfaces, w, h);
    assert!(n > 100, "{n} rays");
}

fn run_scan(ctx: &GpuContext, stage: &CompactionStage, flags: &[u32]) -> (Vec<u32>, [u32; 4]) {
    let n = flags.len() as u32;
    let flags_buf = upload(ctx, "test flags", flags);
    let out = storage::<u32>(ctx, "test indices", flags.len()).unwrap();
    let count = storage::<u32>(ctx, "test count", 4).unwrap();
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    ctx.checked(|| stage.encode_scan_for_test(ctx, &mut encoder, &flags_buf, n, &out, &count)).unwrap().unwrap();
    ctx.queue.submit([encoder.finish()]);
    let c: Vec<u32> = read_back(ctx, &count, 4).unwrap();
    (read_back(ctx, &out, c[0] as usize).unwrap(), c.try_into().unwrap())
}

/// The multi-level scan alone: sizes around tile boundaries and a few hundred
/// thousand flags (three levels: 300,001 -> 586 tiles -> 2 -> top), all and none
/// active, non-0/1 flag values.
#[test]
fn compaction_scan_matches_sequential() {
    let Some(ctx) = test_context() else { return };
    let stage = CompactionStage::new(&ctx);
    let t = COMPACTION_TILE as usize;
    let mut rng = 0x9e37_79b9u32;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 17;
        rng ^= rng << 5;
        rng
    };
    let mut cases: Vec<Vec<u32>> = Vec::new();
    for n in [1, 2, t - 1, t, t + 1, t * t - 1, t * t, t * t + 1, 300_001] {
        cases.push((0..n).map(|_| (next() % 3 == 0) as u32 * (1 + next() % 5)).collect());
    }
    cases.push(vec![1; t * t + 3]);
    cases.push(vec![0; 2 * t + 5]);
    cases.push((0..300_000u32).map(|i| (i % 977 == 0) as u32).collect());
    for flags in &cases {
        let expected = compact_sequential(flags);
        let (got, count) = run_scan(&ctx, &stage, flags);
        assert_eq!(count, expected_dispatch(expected.len() as u32), "n = {}", flags.len());
        let first_diff = got.iter().zip(&expected).position(|(a, b)| a != b);
        assert_eq!(first_diff, None, "n = {}: first differing index", flags.len());
        assert_eq!(got.len(), expected.len());
    }
}

proptest::proptest! {
    #![proptest_config(proptest::test_runner::Config { cases: 24, ..Default::default() })]
    /// Random lengths (tile boundaries included by the range) and densities.
    #[test]
    fn compaction_scan_prop_equals_sequential(
        n in 0usize..3 * COMPACTION_TILE as usize + 5,
        density in 0u32..=8,
        seed in proptest::prelude::any::<u32>(),
    ) {
        let Some(ctx) = test_context() else { return Ok(()) };
        let stage = CompactionStage::new(&ctx);
        let mut rng = seed | 1;
        let flags: Vec<u32> = (0..n)
            .map(|_| {
                rng ^= rng << 13;
                rng ^= rng >> 17;
                rng ^= rng << 5;
                (rng % 8 < density) as u32
            })
            .collect();
        let (got, count) = run_scan(&ctx, &stage, &flags);
        let expected = compact_sequential(&flags);
        proptest::prop_assert_eq!(count, expected_dispatch(expected.len() as u32));
        proptest::prop_assert_eq!(got, expected);
    }
}
