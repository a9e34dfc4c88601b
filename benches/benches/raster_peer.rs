//! The report's raster peer row, narrowed: the CPU `visibility_raster` (on a pool of
//! `HYRT_RASTER_THREADS` threads, default 2) against the GPU backend's own raster of the
//! same pass (`VisibilityMode::HardwareInterpolated`; Mesa lavapipe when
//! `HYRT_GPU_ALLOW_SOFTWARE=1` and no hardware adapter), on the teaser (or the default
//! scene) at 1280x720, interleaved round by round in one process so that both see the
//! same machine. Prints each side's median and the median of the per-round ratios.
//! `cargo bench -p hyrt-benches --bench raster_peer` (`HYRT_RASTER_ROUNDS`, default 31).

use std::time::Instant;

use hyrt_benches::bench_scenes;
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::geometry::WorldGeometry;
use hyrt_cpu::backend::CpuBackend;
use hyrt_cpu::visibility_raster::visibility_raster_into;
use hyrt_gpu::buffers::{FrameBuffers, FrameParams, SceneBuffers};
use hyrt_gpu::visibility_raster::{VisibilityMode, VisibilityRasterStage};
use hyrt_gpu::{AdapterPolicy, GpuContext};

const W: u32 = 1280;
const H: u32 = 720;

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    // `cargo bench` passes `--bench`; a filter argument selects nothing here.
    let threads = env_usize("HYRT_RASTER_THREADS", 2);
    let rounds = env_usize("HYRT_RASTER_ROUNDS", 31).max(1);
    let scenes = bench_scenes();
    let b = scenes.iter().find(|b| b.name == "teaser").unwrap_or(&scenes[0]);
    let cam = b.scene.camera.unwrap();
    let camera = CameraRecord::new(&cam, W, H);
    let g = WorldGeometry::build(&b.scene);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("rayon pool");
    let mut gbuffer = Vec::new();
    let mut cpu = || {
        let t = Instant::now();
        pool.install(|| visibility_raster_into(&g, &camera, &mut gbuffer));
        t.elapsed().as_secs_f64() * 1e3
    };
    let gpu = match GpuContext::new(AdapterPolicy::from_env()) {
        Ok(ctx) => {
            eprintln!("raster_peer: GPU {}", ctx.describe());
            let prepared = CpuBackend::new(None).prepare(g.clone(), BvhPreset::default());
            let lights = prepared.geometry.lights.len() as u32;
            let sb = SceneBuffers::new(&ctx, &prepared);
            let fb = FrameBuffers::new(&ctx, W, H, lights).expect("frame buffers");
            fb.write_uniforms(&ctx, &camera, &FrameParams::new(W, H, lights, 1.0));
            let stage = VisibilityRasterStage::with_mode(&ctx, VisibilityMode::HardwareInterpolated);
            Some((ctx, sb, fb, stage))
        }
        Err(e) => {
            eprintln!("raster_peer: no GPU peer: {e} (HYRT_GPU_ALLOW_SOFTWARE=1 accepts lavapipe)");
            None
        }
    };
    let gpu_run = |(ctx, sb, fb, stage): &(GpuContext, SceneBuffers, FrameBuffers, VisibilityRasterStage)| {
        // As the GPU backend times a stage on a software adapter: encode, submit, wait.
        let t = Instant::now();
        let mut enc = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("peer") });
        stage.encode(ctx, &mut enc, sb, fb, None);
        ctx.queue.submit([enc.finish()]);
        ctx.device.poll(wgpu::PollType::Wait { submission_index: None, timeout: None }).expect("GPU wait");
        t.elapsed().as_secs_f64() * 1e3
    };
    // Warm-up.
    cpu();
    if let Some(g) = &gpu {
        gpu_run(g);
    }
    let (mut cpu_ms, mut gpu_ms, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..rounds {
        let c = cpu();
        cpu_ms.push(c);
        if let Some(g) = &gpu {
            let p = gpu_run(g);
            gpu_ms.push(p);
            ratios.push(p / c);
        }
    }
    // FNV-1a over every texel's bits: the same G-buffer gives the same digest.
    let digest = gbuffer
        .iter()
        .flat_map(|t| t.to_bits())
        .fold(0xcbf2_9ce4_8422_2325u64, |h, word| (h ^ word as u64).wrapping_mul(0x0000_0100_0000_01b3));
    println!("raster_peer: {}, {W}x{H}, {threads} CPU threads, {rounds} rounds", b.name);
    println!("  G-buffer digest {digest:016x}");
    println!("  cpu visibility_raster median {:.3} ms", median(cpu_ms));
    if !gpu_ms.is_empty() {
        println!("  gpu hardware-interpolated raster median {:.3} ms", median(gpu_ms));
        println!("  gpu / cpu median ratio {:.2}", median(ratios));
    }
}
