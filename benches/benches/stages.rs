//! Criterion benchmarks: the BVH build per obvhs preset, every CPU stage, and whole
//! frames, at 1280x720 on the default scene and (when `../shared/assets` is present) the
//! paper's teaser; then every GPU stage and whole GPU frames when a Vulkan adapter is
//! available (`HYRT_GPU_ALLOW_SOFTWARE=1` accepts Mesa lavapipe, a software rasterizer
//! on the CPU). `cargo bench -p hyrt-benches --bench stages`; each stage reads the
//! previous stage's real output.

use criterion::{criterion_group, criterion_main, Criterion};
use hyrt::{formats::CameraRecord, FrameOptions, Renderer};
use hyrt_benches::bench_scenes;
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::frame::{Backend, Frame};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::stage::Stage;
use hyrt_cpu::backend::CpuBackend;
use hyrt_cpu::{compaction, composition, raster_shading, reconstruction, rt_shading, shadow_rays, visibility_raster};
use hyrt_gpu::backend::GpuBackend;
use hyrt_gpu::buffers::{FrameBuffers, FrameParams, SceneBuffers};
use hyrt_gpu::{AdapterPolicy, GpuContext};

const W: u32 = 1280;
const H: u32 = 720;

fn stages(c: &mut Criterion) {
    for b in bench_scenes() {
        let cam = b.scene.camera.unwrap();
        let rec = CameraRecord::new(&cam, W, H);
        let g = WorldGeometry::build(&b.scene);
        let eye = cam.eye;
        let mut group = c.benchmark_group(b.name);
        group.sample_size(10);
        for preset in BvhPreset::ALL {
            group.bench_function(format!("bvh_build/{}", preset.name()), |bn| bn.iter(|| Bvh::build(&g, preset)));
        }
        let bvh = Bvh::build(&g, BvhPreset::default());
        group.bench_function("visibility_raster", |bn| bn.iter(|| visibility_raster::visibility_raster(&g, &rec)));
        let vis = visibility_raster::visibility_raster(&g, &rec);
        group.bench_function("reconstruction", |bn| bn.iter(|| reconstruction::reconstruction(&vis.gbuffer, &g, eye)));
        let surfaces = reconstruction::reconstruction(&vis.gbuffer, &g, eye);
        group.bench_function("compaction", |bn| bn.iter(|| compaction::compaction(&surfaces, &g.lights)));
        let rays = compaction::compaction(&surfaces, &g.lights);
        group.bench_function("shadow_rays", |bn| bn.iter(|| shadow_rays::shadow_rays(&bvh, &g, &rays)));
        let occluded = shadow_rays::shadow_rays(&bvh, &g, &rays);
        let mask = compaction::shadow_mask(&rays, &occluded, surfaces.len(), g.lights.len());
        group.bench_function("rt_shading", |bn| {
            bn.iter(|| rt_shading::rt_shading(&surfaces, &mask, &g.objects, &g.lights, &g.ambient, eye))
        });
        let rt = rt_shading::rt_shading(&surfaces, &mask, &g.objects, &g.lights, &g.ambient, eye);
        group.bench_function("raster_shading", |bn| {
            bn.iter(|| raster_shading::raster_shading(&surfaces, &mask, &g.objects, &g.lights, &g.ambient, eye, 1.0))
        });
        let raster = raster_shading::raster_shading(&surfaces, &mask, &g.objects, &g.lights, &g.ambient, eye, 1.0);
        group.bench_function("composition", |bn| bn.iter(|| composition::composition(&raster, &rt, 1.0)));
        let mut r = Renderer::cpu(None);
        let prepared = r.prepare(&b.scene);
        group.bench_function("frame", |bn| {
            // The paper's frame (shadow rays only), as the stage benches above.
            let paper = FrameOptions { max_depth: 0, ..FrameOptions::default() };
            bn.iter(|| r.render(&prepared, &cam, W, H, &paper).unwrap())
        });
        group.finish();
    }
}

/// A GPU adapter under the environment's policy, or a message saying why the GPU
/// benchmarks are skipped.
fn gpu_context() -> Option<GpuContext> {
    match GpuContext::new(AdapterPolicy::from_env()) {
        Ok(ctx) => {
            eprintln!("hyrt-benches: GPU benchmarks on {}", ctx.describe());
            Some(ctx)
        }
        Err(e) => {
            eprintln!("hyrt-benches: GPU benchmarks skipped: {e} (HYRT_GPU_ALLOW_SOFTWARE=1 accepts lavapipe)");
            None
        }
    }
}

/// Every GPU stage alone (recorded, submitted and waited for, on buffers that hold a real
/// frame's data), then whole frames through [`GpuBackend`].
fn gpu_stages(c: &mut Criterion) {
    let Some(ctx) = gpu_context() else { return };
    let vis = hyrt_gpu::visibility_raster::VisibilityRasterStage::new(&ctx);
    let rec_stage = hyrt_gpu::reconstruction::ReconstructionStage::new(&ctx);
    let compact = hyrt_gpu::compaction::CompactionStage::new(&ctx);
    let shadow = hyrt_gpu::shadow_rays::ShadowRaysStage::new(&ctx);
    let rt = hyrt_gpu::rt_shading::RtShadingStage::new(&ctx);
    let raster = hyrt_gpu::raster_shading::RasterShadingStage::new(&ctx);
    let compose = hyrt_gpu::composition::CompositionStage::new(&ctx);
    let mut backend = match GpuBackend::new(AdapterPolicy::from_env()) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("hyrt-benches: GPU frame benchmarks skipped: {e}");
            return;
        }
    };
    for b in bench_scenes() {
        let cam = b.scene.camera.unwrap();
        let camera = CameraRecord::new(&cam, W, H);
        let prepared = CpuBackend::new(None).prepare(WorldGeometry::build(&b.scene), BvhPreset::default());
        let lights = prepared.geometry.lights.len() as u32;
        let sb = SceneBuffers::new(&ctx, &prepared);
        let fb = match FrameBuffers::new(&ctx, W, H, lights) {
            Ok(fb) => fb,
            Err(e) => {
                eprintln!("hyrt-benches: GPU benchmarks of {} skipped: {e}", b.name);
                continue;
            }
        };
        fb.write_uniforms(&ctx, &camera, &FrameParams::new(W, H, lights, 1.0));
        let run = |stages: &[Stage]| {
            let mut enc = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("bench") });
            for s in stages {
                match s {
                    Stage::VisibilityRaster => vis.encode(&ctx, &mut enc, &sb, &fb, None),
                    Stage::Reconstruction => {
                        rec_stage.encode(&ctx, &mut enc, &sb, &fb, hyrt::PrimaryBarycentrics::Raster, None)
                    }
                    Stage::Compaction => compact.encode(&ctx, &mut enc, &sb, &fb, None),
                    Stage::ShadowRays => shadow.encode(&ctx, &mut enc, &sb, &fb, None),
                    Stage::RtShading => rt.encode(&ctx, &mut enc, &sb, &fb, None),
                    Stage::RasterShading => raster.encode(&ctx, &mut enc, &sb, &fb, None),
                    Stage::Composition => compose.encode(&ctx, &mut enc, &sb, &fb, None),
                    Stage::BvhBuild => unreachable!("bvh_build runs on the CPU"),
                    Stage::SecondaryRays | Stage::BounceTrace | Stage::BounceShading | Stage::ShadowDenoise => {
                        unreachable!("not in `frame_stages`")
                    }
                }
            }
            ctx.queue.submit([enc.finish()]);
            ctx.device.poll(wgpu::PollType::Wait { submission_index: None, timeout: None }).expect("GPU wait");
        };
        // The paper's frame: no bounce, and no `shadow_denoise` (a frame of point lights
        // has no area light or ambient occlusion to denoise).
        let bounces = [Stage::SecondaryRays, Stage::BounceTrace, Stage::BounceShading, Stage::ShadowDenoise];
        let frame_stages: Vec<Stage> =
            Stage::ALL.into_iter().filter(|&s| s != Stage::BvhBuild && !bounces.contains(&s)).collect();
        // One whole frame first, so every stage's inputs are a real frame's.
        run(&frame_stages);
        let mut group = c.benchmark_group(format!("{}/gpu", b.name));
        group.sample_size(10);
        for &s in &frame_stages {
            group.bench_function(s.name(), |bn| bn.iter(|| run(&[s])));
        }
        let options = FrameOptions { weight: 1.0, stage_outputs: false, max_depth: 0, ..FrameOptions::default() };
        let mut frame = Frame::default();
        group.bench_function("frame", |bn| {
            bn.iter(|| backend.render_into(&prepared, &camera, &options, &mut frame).unwrap())
        });
        group.finish();
    }
}

criterion_group!(benches, stages, gpu_stages);
criterion_main!(benches);
