//! The report's "Scale through instancing" section: `assets/scenes/dragons_1000.toml`,
//! 1,000 copies of the 871,414-triangle dragon (871 million triangles), rendered on the CPU
//! backend. `Renderer::prepare` traces the copies as instances of one mesh
//! (`hyrt_cpu::bvh_build::prepare_scene`): one bottom level, one mesh in the world tables
//! (its copies by reference), a raster that makes each copy's world triangles batch by
//! batch. Measured: the load, the preparation (world tables and both levels), the frame
//! (medians after a warm-up frame), and the process's peak resident memory over all of it
//! (`VmHWM`, reset before the load), against what the stored world tables would take. The
//! GPU backend renders `dragons_30` (30 of them: a frame of the 1,000 takes lavapipe tens
//! of minutes), against the CPU backend in the same run ([`run_gpu`]).

use std::fmt::Write as _;
use std::time::Instant;

use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, FrameOptions};
use hyrt_core::memory::{peak_resident_bytes, reset_peak_resident_bytes, resident_bytes};
use indicatif::ProgressBar;

use super::report::{count, Section, Table};
use super::stats::median;
use super::{BenchError, BenchOptions};

/// The manifest measured (in `assets/scenes/`).
pub const SCENE: &str = "dragons_1000";

/// What the section reports.
#[derive(Clone, Debug, Default)]
pub struct Instancing {
    /// Why nothing was measured (no shared assets, a load error).
    pub skipped: Option<String>,
    pub objects: usize,
    pub instanced_objects: usize,
    pub triangles: u64,
    pub load_ms: f64,
    pub prepare_ms: f64,
    pub bvh_build_ms: f64,
    pub frame_ms: Vec<f64>,
    pub size: (u32, u32),
    pub threads: usize,
    pub world_table_bytes: usize,
    pub stored_table_bytes: usize,
    pub levels_bytes: usize,
    pub resident_before: Option<u64>,
    pub peak_resident: Option<u64>,
    pub covered_pixels: u64,
    /// The executor that ran the frames (the CPU backend's default: fused where it can).
    pub executor: &'static str,
    pub image: Option<String>,
}

/// A manifest loaded for the section, after a reset of the peak resident memory.
struct Loaded {
    scene: hyrt_core::scene::Scene,
    load_ms: f64,
    /// The peak resident memory could be reset (it is counted from the load on).
    resets: bool,
    resident_before: Option<u64>,
}

/// Load manifest `name` (the shared assets there, the section asked for), or say why not.
fn load(name: &str, options: &BenchOptions, progress: &ProgressBar) -> Result<Loaded, String> {
    if options.scenes == super::scenes::SceneSet::DefaultOnly {
        return Err("only the default scene was asked for (`--scenes default`)".into());
    }
    if super::scenes::shared_assets().is_none() {
        return Err("the shared assets (the dragon) are not there".into());
    }
    progress.set_message(format!("instancing: loading {name}"));
    let resets = reset_peak_resident_bytes();
    let resident_before = resident_bytes();
    let t = Instant::now();
    let bench = super::scenes::load_manifest(name)?;
    Ok(Loaded { scene: bench.scene, load_ms: t.elapsed().as_secs_f64() * 1e3, resets, resident_before })
}

/// `median (least to greatest, n frames)` of frame times in ms.
fn frame_times(v: &[f64]) -> String {
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let n = match v.len() {
        1 => "1 frame".to_string(),
        n => format!("{n} frames"),
    };
    format!("{:.0} ms ({:.0} to {:.0}, {n})", median(v).unwrap_or(f64::NAN), lo, hi)
}

/// The peak resident memory from a load on, what the process held before it, and what the
/// scene and its frames added.
fn resident(peak: Option<u64>, before: Option<u64>) -> String {
    match (peak, before) {
        (Some(p), Some(b)) => format!("{} ({} before; {} added)", mib(p), mib(b), mib(p.saturating_sub(b))),
        (Some(p), None) => mib(p),
        _ => "not known on this system".to_string(),
    }
}

/// Measure the scene with `threads` on the CPU backend at `options.table_size`.
pub fn run(options: &BenchOptions, progress: &ProgressBar) -> Result<Instancing, BenchError> {
    let threads = options.frame_threads.unwrap_or_else(rayon::current_num_threads);
    let mut out = Instancing { size: options.table_size, threads, ..Instancing::default() };
    let loaded = match load(SCENE, options, progress) {
        Ok(l) => l,
        Err(why) => {
            out.skipped = Some(why);
            return Ok(out);
        }
    };
    let (scene, resets) = (loaded.scene, loaded.resets);
    (out.load_ms, out.resident_before) = (loaded.load_ms, loaded.resident_before);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| BenchError::Options(format!("cannot start {threads} threads: {e}")))?;
    progress.set_message(format!("instancing: preparing {SCENE}"));
    let t = Instant::now();
    let prepared = pool.install(|| hyrt_cpu::bvh_build::prepare_scene(&scene, BvhPreset::default()));
    out.prepare_ms = t.elapsed().as_secs_f64() * 1e3;
    out.bvh_build_ms = prepared.bvh_build_ms;
    out.objects = scene.objects.len();
    out.instanced_objects = prepared.levels.as_ref().map_or(0, |l| l.in_object_space.iter().filter(|&&b| b).count());
    out.triangles = prepared.geometry.triangle_count() as u64;
    out.world_table_bytes = prepared.geometry.triangles.bytes();
    out.stored_table_bytes = prepared.geometry.triangles.stored_bytes();
    // The levels, and the copy of the world-space level `PreparedScene::bvh` holds.
    out.levels_bytes = prepared.levels.as_ref().map_or(0, |l| l.bytes()) + prepared.bvh.bytes();
    let camera = CameraRecord::new(&scene.camera.expect("the manifest has a camera"), out.size.0, out.size.1);
    let mut backend = hyrt_cpu::backend::CpuBackend::new(Some(threads));
    let frame_options = FrameOptions::default();
    let render_error = |source| BenchError::Render { scene: SCENE.into(), source };
    // One warm-up frame, then the measured ones (at most three: a frame takes seconds).
    let measured = options.frames.clamp(1, 3);
    let mut frame = hyrt_core::frame::Frame::default();
    for k in 0..=measured {
        progress.set_message(format!("instancing: frame {k} of {measured}"));
        let t = Instant::now();
        backend.render_into(&prepared, &camera, &frame_options, &mut frame).map_err(render_error)?;
        if k > 0 {
            out.frame_ms.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    out.peak_resident = if resets { peak_resident_bytes() } else { None };
    out.covered_pixels = frame.stats.covered_pixels;
    out.executor = frame.stats.executor.name();
    let path = options.out_dir.join(format!("{SCENE}.png"));
    hyrt::save_png(&frame, &path)
        .map_err(|e| BenchError::Write { path, source: std::io::Error::other(e.to_string()) })?;
    out.image = Some(format!("{SCENE}.png"));
    Ok(out)
}

/// The manifest the GPU backend renders (in `assets/scenes/`): 30 of the dragons, which a
/// software rasterizer renders in about half a minute a frame.
pub const GPU_SCENE: &str = "dragons_30";

/// The GPU backend on [`GPU_SCENE`] (and the CPU backend on it, for comparison).
#[derive(Clone, Debug, Default)]
pub struct GpuInstancing {
    /// Why nothing was measured (no GPU backend, no shared assets, a load error).
    pub skipped: Option<String>,
    /// The backend's description.
    pub label: String,
    pub triangles: u64,
    pub by_reference: bool,
    pub load_ms: f64,
    pub prepare_ms: f64,
    /// The first frame: the scene's upload, the pipelines it needs, the frame and its
    /// G-buffer read back (the ids compared with the CPU's).
    pub first_frame_ms: f64,
    pub frame_ms: Vec<f64>,
    pub cpu_frame_ms: Vec<f64>,
    /// The tables the device holds ([`hyrt_gpu::backend::scene_table_bytes`]).
    pub device_table_bytes: u64,
    /// What the world records would take stored.
    pub stored_table_bytes: usize,
    pub resident_before: Option<u64>,
    pub peak_resident: Option<u64>,
    /// The G-buffers' triangle and object ids are the CPU's, pixel for pixel.
    pub same_ids: bool,
    pub covered_pixels: u64,
}

/// Measure [`GPU_SCENE`] on `gpu` (the report's GPU backend) and on the CPU backend with
/// `threads`, at `options.table_size`: the load, the preparation, the first frame and the
/// next ones (one in a quick run, else two), the peak resident memory of the process from
/// the load on (on a software rasterizer the device's memory is the process's).
pub fn run_gpu(
    options: &BenchOptions,
    gpu: Option<&mut super::FrameBackend>,
    progress: &ProgressBar,
) -> Result<GpuInstancing, BenchError> {
    let mut out = GpuInstancing::default();
    let Some(gpu) = gpu else {
        out.skipped = Some("no GPU backend in this run".into());
        return Ok(out);
    };
    out.label = gpu.label.clone();
    let loaded = match load(GPU_SCENE, options, progress) {
        Ok(l) => l,
        Err(why) => {
            out.skipped = Some(why);
            return Ok(out);
        }
    };
    let (scene, resets) = (loaded.scene, loaded.resets);
    (out.load_ms, out.resident_before) = (loaded.load_ms, loaded.resident_before);
    let t = Instant::now();
    let prepared = hyrt_cpu::bvh_build::prepare_scene(&scene, BvhPreset::default());
    out.prepare_ms = t.elapsed().as_secs_f64() * 1e3;
    out.triangles = prepared.geometry.triangle_count() as u64;
    out.by_reference = prepared.geometry.triangles.has_references();
    out.device_table_bytes = hyrt_gpu::backend::scene_table_bytes(&prepared);
    out.stored_table_bytes = prepared.geometry.triangles.stored_bytes();
    let camera = CameraRecord::new(
        &scene.camera.expect("the manifest has a camera"),
        options.table_size.0,
        options.table_size.1,
    );
    let measured = if options.quick { 1 } else { 2 };
    let gpu_frames = timed_frames(gpu.backend.as_mut(), &prepared, &camera, measured, "GPU", progress)?;
    out.peak_resident = if resets { peak_resident_bytes() } else { None };
    let threads = options.frame_threads.unwrap_or_else(rayon::current_num_threads);
    let mut cpu = hyrt_cpu::backend::CpuBackend::new(Some(threads));
    let cpu_frames = timed_frames(&mut cpu, &prepared, &camera, measured, "CPU", progress)?;
    (out.first_frame_ms, out.frame_ms, out.covered_pixels) = (gpu_frames.first_ms, gpu_frames.ms, gpu_frames.covered);
    out.cpu_frame_ms = cpu_frames.ms;
    out.same_ids = !cpu_frames.ids.is_empty() && cpu_frames.ids == gpu_frames.ids;
    Ok(out)
}

/// What [`timed_frames`] measured on one backend.
struct TimedFrames {
    /// The first frame (with a GPU backend: the scene's upload and its pipelines too).
    first_ms: f64,
    /// The frames after it.
    ms: Vec<f64>,
    /// The first frame's G-buffer as (triangle, object) per pixel.
    ids: Vec<(u32, u32)>,
    covered: u64,
}

/// [`GPU_SCENE`] rendered on `backend`: a first frame that keeps its G-buffer (the ids the
/// backends are compared by), then `measured` frames with the default options.
fn timed_frames(
    backend: &mut dyn Backend,
    prepared: &hyrt_core::frame::PreparedScene,
    camera: &CameraRecord,
    measured: usize,
    name: &str,
    progress: &ProgressBar,
) -> Result<TimedFrames, BenchError> {
    let render_error = |source| BenchError::Render { scene: GPU_SCENE.into(), source };
    let mut frame = hyrt_core::frame::Frame::default();
    let mut out = TimedFrames { first_ms: 0.0, ms: Vec::new(), ids: Vec::new(), covered: 0 };
    for k in 0..=measured {
        progress.set_message(format!("instancing: {GPU_SCENE} on the {name} backend, frame {k} of {measured}"));
        let options = FrameOptions { keep_gbuffer: k == 0, ..FrameOptions::default() };
        let t = Instant::now();
        backend.render_into(prepared, camera, &options, &mut frame).map_err(render_error)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        match k {
            0 => {
                out.first_ms = ms;
                out.ids = frame.gbuffer.iter().map(|t| (t.triangle, t.object)).collect();
            }
            _ => out.ms.push(ms),
        }
    }
    out.covered = frame.stats.covered_pixels;
    Ok(out)
}

impl GpuInstancing {
    /// The section's part on the GPU backend.
    pub fn markdown(&self, size: (u32, u32)) -> String {
        let mut md = format!(
            "**The GPU backend** on `assets/scenes/{GPU_SCENE}.toml`, 30 of the dragons (a frame of all 1,000, \
             871 million triangles, takes lavapipe tens of minutes), against the CPU backend in the same run, {}x{}: {}.\n\n",
            size.0, size.1, self.label
        );
        if let Some(why) = &self.skipped {
            let _ = writeln!(md, "Not measured: {why}.\n");
            return md;
        }
        let mut t = Table::new(["", "this run"]).align(1, super::report::Align::Left);
        t.row([
            "triangles".to_string(),
            format!("{} ({})", count(self.triangles), if self.by_reference { "by reference" } else { "stored" }),
        ]);
        t.row(["load (`Scene::load`)".to_string(), format!("{:.0} ms", self.load_ms)]);
        t.row(["prepare (world tables + `bvh_build`)".to_string(), format!("{:.0} ms", self.prepare_ms)]);
        t.row([
            "first GPU frame (upload, pipelines, frame, its G-buffer read back)".to_string(),
            format!("{:.0} ms", self.first_frame_ms),
        ]);
        t.row(["GPU frame".to_string(), frame_times(&self.frame_ms)]);
        t.row(["CPU frame, same run".to_string(), frame_times(&self.cpu_frame_ms)]);
        t.row([
            "scene tables on the device (world records stored would be)".to_string(),
            format!("{} ({})", mib(self.device_table_bytes), mib(self.stored_table_bytes as u64)),
        ]);
        t.row([
            "peak resident memory of the process from the load on (on lavapipe the device's too)".to_string(),
            resident(self.peak_resident, self.resident_before),
        ]);
        t.row(["covered pixels".to_string(), count(self.covered_pixels)]);
        t.row([
            "triangle and object ids".to_string(),
            if self.same_ids { "the CPU's, pixel for pixel" } else { "DIFFER from the CPU's" }.to_string(),
        ]);
        md += &t.to_markdown();
        md
    }
}

fn mib(bytes: u64) -> String {
    format!("{:.0} MiB", bytes as f64 / (1u64 << 20) as f64)
}

impl Instancing {
    /// The report section, with the GPU backend's part.
    pub fn section(&self, gpu: &GpuInstancing) -> Section {
        let mut section = self.cpu_section();
        section.markdown += "\n";
        section.markdown += &gpu.markdown(self.size);
        section
    }

    /// The section's part on the CPU backend.
    fn cpu_section(&self) -> Section {
        let mut md = String::new();
        let _ = writeln!(
            md,
            "`assets/scenes/{SCENE}.toml`: 1,000 copies of the Stanford dragon (871,414 triangles each) placed by the \
             manifest's `repeat`, ray traced, on a rasterized floor. `Renderer::prepare` sees copies of a shared mesh \
             whose stored world tables would pass 1 GiB and traces them as instances of one object-space bottom \
             level; the world tables hold the mesh once and make each copy's records when read (the raster does so \
             a batch of about a million triangles at a time). CPU backend, {} threads, {}x{}, the frame's default \
             options{}; the frame times are the median of {} frames after a warm-up frame, with the least and \
             greatest.\n",
            self.threads,
            self.size.0,
            self.size.1,
            if self.executor.is_empty() {
                String::new()
            } else {
                format!(", the backend's default executor (this frame: {})", self.executor)
            },
            self.frame_ms.len()
        );
        if let Some(why) = &self.skipped {
            let _ = writeln!(md, "Not measured: {why}.\n");
            return Section::new("Scale through instancing", md);
        }
        let mut t = Table::new(["", "this run"]).align(1, super::report::Align::Left);
        t.row([
            "objects (instances of the dragon)".to_string(),
            format!("{} ({})", count(self.objects as u64), count(self.instanced_objects as u64)),
        ]);
        t.row(["triangles".to_string(), count(self.triangles)]);
        t.row(["load (`Scene::load`)".to_string(), format!("{:.0} ms", self.load_ms)]);
        t.row([
            "prepare (world tables + `bvh_build`)".to_string(),
            format!("{:.0} ms (`bvh_build` {:.0} ms)", self.prepare_ms, self.bvh_build_ms),
        ]);
        t.row(["frame".to_string(), frame_times(&self.frame_ms)]);
        t.row(["covered pixels".to_string(), count(self.covered_pixels)]);
        t.row([
            "world tables held (stored would be)".to_string(),
            format!("{} ({})", mib(self.world_table_bytes as u64), mib(self.stored_table_bytes as u64)),
        ]);
        t.row(["BVH levels (binary trees and their wide views)".to_string(), mib(self.levels_bytes as u64)]);
        t.row([
            "peak resident memory of the process from the load on".to_string(),
            resident(self.peak_resident, self.resident_before),
        ]);
        md += &t.to_markdown();
        if let Some(img) = &self.image {
            let _ = writeln!(md, "\n![1,000 instanced dragons]({img})\n");
        }
        Section::new("Scale through instancing", md)
    }
}
