//! The report's "Scale through instancing" section: `assets/scenes/dragons_1000.toml`,
//! 1,000 copies of the 871,414-triangle dragon (871 million triangles), rendered on the CPU
//! backend. `Renderer::prepare` traces the copies as instances of one mesh
//! (`hyrt_cpu::bvh_build::prepare_scene`): one bottom level, one mesh in the world tables
//! (its copies by reference), a raster that makes each copy's world triangles batch by
//! batch. Measured: the load, the preparation (world tables and both levels), the frame
//! (medians after a warm-up frame), and the process's peak resident memory over all of it
//! (`VmHWM`, reset before the load), against what the stored world tables would take.

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

/// Measure the scene with `threads` on the CPU backend at `options.table_size`.
pub fn run(options: &BenchOptions, progress: &ProgressBar) -> Result<Instancing, BenchError> {
    let threads = options.frame_threads.unwrap_or_else(rayon::current_num_threads);
    let mut out = Instancing { size: options.table_size, threads, ..Instancing::default() };
    if options.scenes == super::scenes::SceneSet::DefaultOnly {
        out.skipped = Some("only the default scene was asked for (`--scenes default`)".into());
        return Ok(out);
    }
    if super::scenes::shared_assets().is_none() {
        out.skipped = Some("the shared assets (the dragon) are not there".into());
        return Ok(out);
    }
    progress.set_message(format!("instancing: loading {SCENE}"));
    let resets = reset_peak_resident_bytes();
    out.resident_before = resident_bytes();
    let t = Instant::now();
    let bench = match super::scenes::load_manifest(SCENE) {
        Ok(b) => b,
        Err(e) => {
            out.skipped = Some(e);
            return Ok(out);
        }
    };
    out.load_ms = t.elapsed().as_secs_f64() * 1e3;
    let scene = bench.scene;
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
    let b = &prepared.bvh;
    out.levels_bytes = prepared.levels.as_ref().map_or(0, |l| l.bytes())
        + std::mem::size_of_val(b.nodes.as_slice())
        + std::mem::size_of_val(b.leaf_triangles.as_slice())
        + std::mem::size_of_val(b.prim_indices.as_slice());
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

fn mib(bytes: u64) -> String {
    format!("{:.0} MiB", bytes as f64 / (1u64 << 20) as f64)
}

impl Instancing {
    /// The report section.
    pub fn section(&self) -> Section {
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
        let lo = self.frame_ms.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = self.frame_ms.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        t.row([
            "frame".to_string(),
            format!("{:.0} ms ({:.0} to {:.0})", median(&self.frame_ms).unwrap_or(f64::NAN), lo, hi),
        ]);
        t.row(["covered pixels".to_string(), count(self.covered_pixels)]);
        t.row([
            "world tables held (stored would be)".to_string(),
            format!("{} ({})", mib(self.world_table_bytes as u64), mib(self.stored_table_bytes as u64)),
        ]);
        t.row(["BVH levels".to_string(), mib(self.levels_bytes as u64)]);
        t.row([
            "peak resident memory of the process (before the load)".to_string(),
            match (self.peak_resident, self.resident_before) {
                (Some(p), Some(b)) => format!("{} ({})", mib(p), mib(b)),
                (Some(p), None) => mib(p),
                _ => "not known on this system".to_string(),
            },
        ]);
        md += &t.to_markdown();
        if let Some(img) = &self.image {
            let _ = writeln!(md, "\n![1,000 instanced dragons]({img})\n");
        }
        Section::new("Scale through instancing", md)
    }
}
