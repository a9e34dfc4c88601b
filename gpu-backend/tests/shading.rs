//! GPU stages `rt_shading`, `raster_shading`, `composition` against the CPU
//! reference (`hyrt_cpu`), on the CPU's own inputs (surfaces, shadow mask, images),
//! and the GPU stage timer.
//!
//! Every channel must be bit-identical: the shaders mirror the kernels' order, keep
//! their products from fusing, and use the core's `pow_portable` instead of WGSL `pow`.
//! Misses, pixels a stage leaves to the other one and alpha are checked by kind too. The
//! shading stages are compiled as each scene needs them (`SceneBuffers::specialization`:
//! the glTF cases with their sky's image-based light).

mod common;

use std::collections::HashMap;
use std::sync::Arc;

use common::test_context;
use glam::Vec3;
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::formats::{CameraRecord, ObjectRecord, OBJ_RAY_TRACED};
use hyrt_core::frame::{Backend, Frame, FrameOptions, PreparedScene};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::shading::BACKGROUND_RGBA;
use hyrt_core::plan::FrameBuffer;
use hyrt_core::scene::{Environment, EnvironmentMap, Light, Scene, ShadingModel};
use hyrt_cpu::backend::CpuBackend;
use hyrt_gpu::buffers::{FrameBuffers, FrameParams, SceneBuffers};
use hyrt_gpu::composition::CompositionStage;
use hyrt_gpu::gpu_buffer::read_back;
use hyrt_gpu::raster_shading::RasterShadingStage;
use hyrt_gpu::rt_shading::RtShadingStage;
use hyrt_gpu::timing::StageTimer;
use hyrt_gpu::GpuContext;

/// f32 bits as integers ordered like the floats (-0 and +0 adjacent).
fn ordered(x: f32) -> i64 {
    let b = x.to_bits() as i32;
    (if b < 0 { i32::MIN - b } else { b }) as i64
}

/// Distance in ulp between two floats (u32::MAX if either is NaN).
fn ulp_distance(a: f32, b: f32) -> u32 {
    if a.is_nan() || b.is_nan() {
        return u32::MAX;
    }
    (ordered(a) - ordered(b)).unsigned_abs().min(u32::MAX as u64) as u32
}

/// A scene rendered by the CPU backend: the inputs and outputs of every stage.
struct Case {
    name: String,
    scene: PreparedScene,
    camera: CameraRecord,
    weight: f32,
    cpu: Frame,
}

fn cpu_case(name: &str, scene: &Scene, width: u32, height: u32, weight: f32) -> Case {
    let geometry = WorldGeometry::build(scene);
    let bvh = Bvh::build(&geometry, BvhPreset::default());
    let prepared = PreparedScene::new(geometry, bvh, 0.0);
    let camera = CameraRecord::new(&scene.camera.expect("scene camera"), width, height);
    let mut cpu = CpuBackend::new(Some(1))
        // The paper's frame: these tests run its rt_shading (the bounce stages have theirs).
        .render(&prepared, &camera, &FrameOptions { weight, max_depth: 0, ..FrameOptions::with_stage_outputs() })
        .expect("cpu render");
    if !cpu.holds(FrameBuffer::Rt) {
        // The frame's plan skipped rt_shading (weight 0): the stage tests still compare
        // the GPU stage with the CPU one, run on its own; its image, weighted by 0, leaves
        // the final image the raster copy the plan made.
        let g = &prepared.geometry;
        let eye = Vec3::from(camera.eye);
        cpu.rt = hyrt_cpu::rt_shading::rt_shading(&cpu.surfaces, &cpu.shadow, &g.objects, &g.lights, &g.ambient, eye);
    }
    Case { name: format!("{name} {width}x{height} w={weight}"), scene: prepared, camera, weight, cpu }
}

/// The default scene with a directional light (and one of its point lights).
fn directional_scene() -> Scene {
    let mut s = paper_default_scene();
    s.lights = vec![
        Light::Directional {
            direction: Vec3::new(-0.4, -1.0, -0.3).normalize(),
            color: Vec3::new(1.0, 0.9, 0.8),
            intensity: 2.5,
        },
        s.lights[0],
    ];
    s
}

/// The default scene without lights: ambient only, an empty shadow mask.
fn unlit_scene() -> Scene {
    let mut s = paper_default_scene();
    s.lights.clear();
    s
}

fn cases() -> Vec<Case> {
    let mut v = Vec::new();
    for (w, h) in [(67, 41), (160, 90)] {
        for weight in [1.0, 0.5, 0.0] {
            v.push(cpu_case("default", &paper_default_scene(), w, h, weight));
        }
    }
    for weight in [1.0, 0.5] {
        v.push(cpu_case("directional", &directional_scene(), 67, 41, weight));
    }
    v.push(cpu_case("unlit", &unlit_scene(), 33, 17, 0.5));
    // The glTF BRDF on both paths (OBJ_GLTF_BRDF): the default scene's metals, mirror
    // and glass, and the directional light.
    for weight in [1.0, 0.5, 0.0] {
        v.push(cpu_case("default gltf", &gltf(paper_default_scene()), 67, 41, weight));
    }
    v.push(cpu_case("directional gltf", &gltf(directional_scene()), 67, 41, 0.5));
    // The image-based light of an environment map (the cases above have the sky's).
    for weight in [1.0, 0.5] {
        let s = Scene { environment: procedural_environment(), ..gltf(directional_scene()) };
        v.push(cpu_case("directional gltf map", &s, 67, 41, weight));
    }
    v
}

/// A 16 x 8 environment map: a sky bright towards a sun, a dark ground.
fn procedural_environment() -> Environment {
    let (w, h) = (16u32, 8u32);
    let texels = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| match (i, j) {
            (3, 1) => [30.0, 28.0, 20.0, 1.0],
            (_, j) if j < h / 2 => [0.3 + 0.05 * i as f32, 0.5, 0.9 - 0.1 * j as f32, 1.0],
            _ => [0.15, 0.1 + 0.01 * i as f32, 0.05, 1.0],
        })
        .collect();
    Environment::Map(Arc::new(EnvironmentMap::new(w, h, texels).expect("a valid map")))
}

/// The default scene with the paper's model (it defaults to the glTF BRDF): the cases
/// below cover both models.
fn paper_default_scene() -> Scene {
    Scene { shading: ShadingModel::Paper, ..Scene::default_scene() }
}

/// `scene` shaded with the glTF BRDF.
fn gltf(scene: Scene) -> Scene {
    Scene { shading: ShadingModel::Gltf, ..scene }
}

/// GPU buffers holding the CPU's surfaces, shadow mask (u8 -> u32) and images.
struct Gpu {
    scene: SceneBuffers,
    frame: FrameBuffers,
}

fn upload_case(ctx: &GpuContext, c: &Case) -> Gpu {
    let (w, h) = (c.camera.width, c.camera.height);
    let lights = c.scene.geometry.lights.len() as u32;
    let scene = SceneBuffers::new(ctx, &c.scene);
    let frame = FrameBuffers::new(ctx, w, h, lights).expect("frame buffers");
    frame.write_uniforms(ctx, &c.camera, &FrameParams::new(w, h, lights, c.weight));
    ctx.queue.write_buffer(&frame.surfaces, 0, bytemuck::cast_slice(&c.cpu.surfaces));
    let shadow: Vec<u32> = c.cpu.shadow.iter().map(|&s| s as u32).collect();
    if !shadow.is_empty() {
        ctx.queue.write_buffer(&frame.shadow, 0, bytemuck::cast_slice(&shadow));
    }
    ctx.queue.write_buffer(&frame.raster, 0, bytemuck::cast_slice(&c.cpu.raster));
    ctx.queue.write_buffer(&frame.rt, 0, bytemuck::cast_slice(&c.cpu.rt));
    // Poison the outputs so that a pixel a stage forgets to write cannot match.
    let nan = vec![[f32::NAN; 4]; (w * h) as usize];
    ctx.queue.write_buffer(&frame.final_image, 0, bytemuck::cast_slice(&nan));
    Gpu { scene, frame }
}

/// Run one stage's `encode` and submit.
fn run(ctx: &GpuContext, encode: impl FnOnce(&mut wgpu::CommandEncoder)) {
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    encode(&mut encoder);
    ctx.queue.submit([encoder.finish()]);
}

fn image(ctx: &GpuContext, buffer: &wgpu::Buffer, pixels: usize) -> Vec<[f32; 4]> {
    read_back::<[f32; 4]>(ctx, buffer, pixels).expect("readback")
}

/// Worst errors over a comparison.
#[derive(Default, Debug)]
struct Worst {
    ulp: u32,
    rel: f32,
    compared: usize,
}

/// Compare RGB channels: each within `ulp_tol` ulp, or within `abs_tol(pixel, channel)`
/// absolute; alpha exactly equal. Returns the worst errors.
fn compare_rgb(what: &str, gpu: &[[f32; 4]], cpu: &[[f32; 4]]) -> Worst {
    assert_eq!(gpu.len(), cpu.len());
    let mut worst = Worst::default();
    let mut failures = Vec::new();
    for (i, (g, c)) in gpu.iter().zip(cpu).enumerate() {
        assert_eq!(g[3].to_bits(), c[3].to_bits(), "{what}: pixel {i} alpha gpu {g:?} cpu {c:?}");
        for ch in 0..3 {
            let d = ulp_distance(g[ch], c[ch]);
            let rel = if c[ch] != 0.0 { ((g[ch] - c[ch]) / c[ch]).abs() } else { (g[ch] - c[ch]).abs() };
            worst.ulp = worst.ulp.max(d);
            worst.rel = worst.rel.max(rel);
            worst.compared += 1;
            if d > 0 {
                failures.push(format!("pixel {i} ch {ch}: gpu {} cpu {} ({d} ulp, rel {rel:e})", g[ch], c[ch]));
            }
        }
    }
    eprintln!(
        "{what}: {} channels, worst {} ulp, worst relative {:e}, {} differ",
        worst.compared,
        worst.ulp,
        worst.rel,
        failures.len()
    );
    assert!(
        failures.is_empty(),
        "{what}: {} channels differ, first: {:?}",
        failures.len(),
        &failures[..failures.len().min(5)]
    );
    worst
}

fn object_of(c: &Case, pixel: usize) -> Option<&ObjectRecord> {
    let s = &c.cpu.surfaces[pixel];
    s.is_hit().then(|| &c.scene.geometry.objects[s.object as usize])
}

#[test]
fn rt_shading_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let mut stages = HashMap::new();
    let mut overall = Worst::default();
    for c in cases() {
        let gpu = upload_case(&ctx, &c);
        let s = gpu.scene.specialization;
        let stage = stages.entry(s).or_insert_with(|| RtShadingStage::specialized(&ctx, s));
        // Poison: every pixel must be written.
        let pixels = c.cpu.rt.len();
        ctx.queue.write_buffer(&gpu.frame.rt, 0, bytemuck::cast_slice(&vec![[f32::NAN; 4]; pixels]));
        run(&ctx, |e| stage.encode(&ctx, e, &gpu.scene, &gpu.frame, None));
        let out = image(&ctx, &gpu.frame.rt, pixels);
        let mut shaded = 0;
        for (i, (g, cp)) in out.iter().zip(&c.cpu.rt).enumerate() {
            match object_of(&c, i) {
                Some(obj) if obj.flags & OBJ_RAY_TRACED != 0 => {
                    shaded += 1;
                    assert_eq!(g[3], 1.0, "{}: pixel {i}", c.name);
                }
                // Misses and raster objects: exactly zero, as the CPU writes them.
                _ => {
                    assert_eq!(bytemuck::cast::<_, [u32; 4]>(*g), [0; 4], "{}: pixel {i}", c.name);
                    assert_eq!(*cp, [0.0; 4]);
                }
            }
        }
        assert!(shaded > 0, "{}: no ray-traced pixels", c.name);
        let w = compare_rgb(&format!("rt_shading {}", c.name), &out, &c.cpu.rt);
        overall.ulp = overall.ulp.max(w.ulp);
        overall.rel = overall.rel.max(w.rel);
    }
    eprintln!("rt_shading overall worst: {} ulp, relative {:e}", overall.ulp, overall.rel);
}

#[test]
fn raster_shading_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let mut stages = HashMap::new();
    let mut overall = Worst::default();
    for c in cases() {
        let gpu = upload_case(&ctx, &c);
        let s = gpu.scene.specialization;
        let stage = stages.entry(s).or_insert_with(|| RasterShadingStage::specialized(&ctx, s));
        let pixels = c.cpu.raster.len();
        ctx.queue.write_buffer(&gpu.frame.raster, 0, bytemuck::cast_slice(&vec![[f32::NAN; 4]; pixels]));
        run(&ctx, |e| stage.encode(&ctx, e, &gpu.scene, &gpu.frame, None));
        let out = image(&ctx, &gpu.frame.raster, pixels);
        let background = BACKGROUND_RGBA;
        let (mut misses, mut skipped) = (0, 0);
        for (i, g) in out.iter().enumerate() {
            match object_of(&c, i) {
                None => {
                    misses += 1;
                    assert_eq!(
                        bytemuck::cast::<_, [u32; 4]>(*g),
                        bytemuck::cast::<_, [u32; 4]>(background),
                        "{}: miss {i}",
                        c.name
                    );
                }
                // The weight < 1 rule: ray-traced objects are left at zero with weight 1.
                Some(obj) if obj.flags & OBJ_RAY_TRACED != 0 && c.weight >= 1.0 => {
                    skipped += 1;
                    assert_eq!(bytemuck::cast::<_, [u32; 4]>(*g), [0; 4], "{}: pixel {i}", c.name);
                }
                Some(_) => assert_eq!(g[3], 1.0, "{}: pixel {i}", c.name),
            }
        }
        assert!(misses > 0, "{}: the test wants background pixels", c.name);
        assert_eq!(skipped > 0, c.weight >= 1.0, "{}", c.name);
        let w = compare_rgb(&format!("raster_shading {}", c.name), &out, &c.cpu.raster);
        overall.ulp = overall.ulp.max(w.ulp);
        overall.rel = overall.rel.max(w.rel);
    }
    eprintln!("raster_shading overall worst: {} ulp, relative {:e}", overall.ulp, overall.rel);
}

#[test]
fn composition_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let stage = CompositionStage::new(&ctx);
    let mut overall = Worst::default();
    for c in cases() {
        let gpu = upload_case(&ctx, &c);
        let pixels = c.cpu.final_image.len();
        run(&ctx, |e| stage.encode(&ctx, e, &gpu.scene, &gpu.frame, None));
        let out = image(&ctx, &gpu.frame.final_image, pixels);
        for (i, (g, cp)) in out.iter().zip(&c.cpu.final_image).enumerate() {
            let t = c.cpu.rt[i];
            // Exact: no RT coverage (the raster texel copied), and weights 0 and 1
            // (x * 0 + y * 1 has one rounding-free product, fused or not).
            let rt_covered = t[3] > 0.0;
            if !rt_covered || c.weight == 0.0 || c.weight == 1.0 {
                assert_eq!(
                    bytemuck::cast::<_, [u32; 4]>(*g),
                    bytemuck::cast::<_, [u32; 4]>(*cp),
                    "{}: pixel {i} gpu {g:?} cpu {cp:?}",
                    c.name
                );
            }
        }
        let w = compare_rgb(&format!("composition {}", c.name), &out, &c.cpu.final_image);
        overall.ulp = overall.ulp.max(w.ulp);
        overall.rel = overall.rel.max(w.rel);
    }
    eprintln!("composition overall worst: {} ulp, relative {:e}", overall.ulp, overall.rel);
}

/// The three stages chained on the GPU (rt -> raster -> composition) give the
/// CPU's final image, bit for bit.
#[test]
fn composition_after_gpu_shading_matches_cpu_final_image() {
    let Some(ctx) = test_context() else { return };
    let (rt, raster, comp) = (RtShadingStage::new(&ctx), RasterShadingStage::new(&ctx), CompositionStage::new(&ctx));
    let c = cpu_case("default", &paper_default_scene(), 67, 41, 0.5);
    let gpu = upload_case(&ctx, &c);
    let pixels = c.cpu.final_image.len();
    let nan = vec![[f32::NAN; 4]; pixels];
    for b in [&gpu.frame.rt, &gpu.frame.raster, &gpu.frame.final_image] {
        ctx.queue.write_buffer(b, 0, bytemuck::cast_slice(&nan));
    }
    run(&ctx, |e| {
        rt.encode(&ctx, e, &gpu.scene, &gpu.frame, None);
        raster.encode(&ctx, e, &gpu.scene, &gpu.frame, None);
        comp.encode(&ctx, e, &gpu.scene, &gpu.frame, None);
    });
    let out = image(&ctx, &gpu.frame.final_image, pixels);
    compare_rgb("chained final image", &out, &c.cpu.final_image);
}

#[test]
fn timing_stage_timer_times_a_compute_pass() {
    let Some(ctx) = test_context() else { return };
    let stage = CompositionStage::new(&ctx);
    let c = cpu_case("default", &paper_default_scene(), 33, 17, 0.5);
    let gpu = upload_case(&ctx, &c);
    let timer = StageTimer::new(&ctx, 3).expect("timer");
    assert_eq!(timer.stages(), 3);
    assert_eq!(timer.is_active(), ctx.timestamps);
    assert!(timer.stage(3).is_none(), "out of range");
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    for i in 0..3 {
        stage.encode(&ctx, &mut encoder, &gpu.scene, &gpu.frame, timer.stage(i));
    }
    timer.resolve(&mut encoder);
    ctx.queue.submit([encoder.finish()]);
    let ms = timer.read_ms(&ctx).expect("read");
    eprintln!("timestamps: {} -> {ms:?}", ctx.timestamps);
    match ms {
        None => assert!(!ctx.timestamps, "timestamps available but no times"),
        Some(ms) => {
            assert_eq!(ms.len(), 3);
            assert!(ms.iter().all(|t| t.is_finite() && *t >= 0.0), "{ms:?}");
        }
    }
    // The pass still ran correctly with timestamps.
    let out = image(&ctx, &gpu.frame.final_image, c.cpu.final_image.len());
    assert_eq!(out.len(), c.cpu.final_image.len());
    assert!(out.iter().all(|p| p[3] == 1.0));
    // Too many stages is an error, not a panic.
    assert!(StageTimer::new(&ctx, wgpu::QUERY_SET_MAX_QUERIES).is_err());
}
