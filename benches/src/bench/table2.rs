//! The paper's Table 2 (scene, valid rays, FPS) reproduced: per-stage and per-frame
//! medians on the CPU backend (staged executor) and, when available, the GPU backend; the
//! CPU backend's fused frame beside the staged one; and the bytes each moves per pixel
//! against a copy loop's rate ([`super::traffic`]).

use std::fmt::Write as _;

use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Executor, FrameStats, PreparedScene};
use hyrt_core::plan::FramePlan;
use hyrt_core::scene::Camera;
use hyrt_core::stage::Stage;
use indicatif::ProgressBar;

use super::report::{count, num, Section, Table};
use super::scenes::{BenchScene, PaperRow, PAPER_TABLE2};
use super::stats::{median, FrameSummary};
use super::traffic::{copy_gb_per_s, frame_traffic, FrameShape, COPY_BYTES};
use super::{measure_frames, measure_frames_with, paper_frame, prepare, BenchError, BenchOptions, FrameBackend};

/// One scene's measurements.
pub struct Table2Row {
    pub name: String,
    pub scene_paper: Option<PaperRow>,
    pub prepared: PreparedScene,
    pub camera: CameraRecord,
    /// The scene's camera (for other image sizes).
    pub scene_camera: Camera,
    /// CPU backend, staged executor: medians and the last frame's counts.
    pub cpu: (FrameSummary, FrameStats),
    /// CPU backend as created (the fused executor for this frame), same threads: medians
    /// and the last frame's statistics (its `executor` says which ran).
    pub fused: (FrameSummary, FrameStats),
    /// Median milliseconds of the fused frame's tiles (`FrameStats::fused_ms`).
    pub fused_tiles_ms: f64,
    /// What sizes the frame's buffers (for the bytes it moves).
    pub shape: FrameShape,
    /// GPU backend, when measured.
    pub gpu: Option<(FrameSummary, FrameStats)>,
}

/// The Table 2 reproduction.
pub struct Table2 {
    pub rows: Vec<Table2Row>,
    pub size: (u32, u32),
    pub cpu_label: String,
    /// Label and short name of the GPU backend, when measured.
    pub gpu: Option<(String, String)>,
    /// GPU failures per scene (the row then has no GPU figures).
    pub gpu_errors: Vec<String>,
    /// Frames per measurement.
    pub frames: usize,
    /// One thread's copy rate in this run, GB/s read + written ([`copy_gb_per_s`]).
    pub copy_gb_s: f64,
}

/// Copies timed for the copy rate (the median is taken).
const COPY_RUNS: usize = 5;

/// Measure every scene at `options.table_size`: the staged CPU frame (`cpu`, per stage),
/// the fused CPU frame (a default `CpuBackend` of `options.frame_threads`), the GPU frame;
/// then one thread's copy rate.
pub fn run(
    options: &BenchOptions,
    scenes: &[BenchScene],
    cpu: &mut FrameBackend,
    mut gpu: Option<&mut FrameBackend>,
    progress: &ProgressBar,
) -> Result<Table2, BenchError> {
    let (w, h) = options.table_size;
    progress.inc_length(scenes.len() as u64 * (2 + gpu.is_some() as u64));
    // The CPU backend's default executor (fused for the paper's frame), the staged one's threads.
    let mut fused = hyrt_cpu::backend::CpuBackend::new(options.frame_threads);
    let mut rows = Vec::new();
    let mut gpu_errors = Vec::new();
    for s in scenes {
        progress.set_message(format!("Table 2: {} (bvh_build, CPU frames)", s.name));
        let prepared = prepare(&s.scene, options.frame_threads);
        let scene_camera = s.scene.camera.expect("bench scenes have a camera");
        let camera = CameraRecord::new(&scene_camera, w, h);
        let cpu_m = measure_frames(cpu.backend.as_mut(), &prepared, &camera, options.frames)
            .map_err(|source| BenchError::Render { scene: s.name.clone(), source })?;
        progress.inc(1);
        progress.set_message(format!("Table 2: {} (CPU frames, fused executor)", s.name));
        let render = |source| BenchError::Render { scene: s.name.clone(), source };
        let (fused_summary, fused_frames) =
            measure_frames_with(&mut fused, &prepared, &camera, options.frames, &paper_frame()).map_err(render)?;
        let fused_tiles_ms = median(&fused_frames.iter().map(|f| f.fused_ms).collect::<Vec<_>>()).unwrap_or(f64::NAN);
        let fused_m = (fused_summary, fused_frames.last().cloned().unwrap_or_default());
        let shape = FrameShape::of(&FramePlan::new(&prepared, &paper_frame()).map_err(render)?, &cpu_m.1);
        progress.inc(1);
        let gpu_m = match gpu.as_deref_mut() {
            Some(g) => {
                progress.set_message(format!("Table 2: {} ({} frames)", s.name, g.short));
                let r = measure_frames(g.backend.as_mut(), &prepared, &camera, options.frames);
                progress.inc(1);
                match r {
                    Ok(m) => Some(m),
                    Err(e) => {
                        gpu_errors.push(format!("{}: GPU frame failed: {e}", s.name));
                        None
                    }
                }
            }
            None => None,
        };
        rows.push(Table2Row {
            name: s.name.clone(),
            scene_paper: s.paper,
            prepared,
            camera,
            scene_camera,
            cpu: cpu_m,
            fused: fused_m,
            fused_tiles_ms,
            shape,
            gpu: gpu_m,
        });
    }
    progress.set_message("Table 2: copy loop");
    let copy_gb_s = copy_gb_per_s(COPY_BYTES, COPY_RUNS);
    Ok(Table2 {
        rows,
        size: options.table_size,
        cpu_label: cpu.label.clone(),
        gpu: gpu.map(|g| (g.label.clone(), g.short.clone())),
        gpu_errors,
        frames: options.frames,
        copy_gb_s,
    })
}

/// The per-frame stages that ran in some measured frame of `rows`, in order (every
/// stage but `bvh_build`; a stage no frame ran, such as the bounces of frames with max
/// depth 0, gets no column).
fn frame_stages(rows: &[Table2Row]) -> Vec<Stage> {
    Stage::ALL
        .into_iter()
        .filter(|&s| s != Stage::BvhBuild)
        .filter(|&s| {
            rows.iter().any(|r| r.cpu.0.ms(s).is_some() || r.gpu.as_ref().is_some_and(|(g, _)| g.ms(s).is_some()))
        })
        .collect()
}

impl Table2 {
    /// The report section: the paper's table quoted, the headline table, per-stage times.
    pub fn section(&self) -> Section {
        let (w, h) = self.size;
        let gpu_short = self.gpu.as_ref().map(|(_, s)| s.as_str());
        let mut md = String::new();
        let _ = writeln!(
            md,
            "The paper (Sabino et al. 2011, Table 2; AMD Phenom II X4 3.4 GHz, NVIDIA 9800 GTX+, OpenGL 3.1 + CUDA; \
             image size not stated; the paper writes 66.252 for 66,252):\n"
        );
        let mut paper = Table::new(["Scene", "Valid Rays", "FPS"]);
        for p in PAPER_TABLE2 {
            paper.row([p.scene.to_string(), count(p.valid_rays), num(p.fps, 0)]);
        }
        md.push_str(&paper.to_markdown());
        let _ = writeln!(
            md,
            "\nhyrt at {w}x{h}: valid rays are the pixels whose primary hit is a ray-traced object \
             (`FrameStats::ray_traced_pixels`); frame time is the median over frames of the sum of the per-frame \
             stages (without `bvh_build`, which runs once per scene); the CPU's staged frame is the one timed per \
             stage below, its fused frame (the CPU backend's default) is measured beside it (see \"The CPU frame, \
             staged and fused\"); the horse stands in for the paper's toad (same triangle count). CPU: {}.{}\n",
            self.cpu_label,
            self.gpu.as_ref().map(|(l, _)| format!(" GPU: {l}.")).unwrap_or_default()
        );
        let mut cols = vec![
            "scene".to_string(),
            "paper's row".into(),
            "triangles".into(),
            "valid rays (paper)".into(),
            "valid rays (hyrt)".into(),
            "shadow rays".into(),
            "CPU staged ms".into(),
            "CPU staged FPS".into(),
            "CPU fused FPS".into(),
        ];
        if let Some(g) = gpu_short {
            cols.push(format!("{g} ms"));
            cols.push(format!("{g} FPS"));
        }
        cols.push("paper FPS".into());
        let mut t = Table::new(cols).align(1, super::report::Align::Left);
        for r in &self.rows {
            let s = &r.cpu.1;
            let mut row = vec![
                r.name.clone(),
                r.scene_paper.map_or("-".into(), |p| p.scene.to_string()),
                count(r.prepared.geometry.triangle_count() as u64),
                r.scene_paper.map_or("-".into(), |p| count(p.valid_rays)),
                count(s.ray_traced_pixels),
                count(s.rays_per_kind.iter().sum()),
                num(r.cpu.0.frame_ms, 1),
                num(r.cpu.0.fps(), 1),
                num(r.fused.0.fps(), 1),
            ];
            if self.gpu.is_some() {
                match &r.gpu {
                    Some((g, _)) => row.extend([num(g.frame_ms, 1), num(g.fps(), 1)]),
                    None => row.extend(["failed".to_string(), "-".to_string()]),
                }
            }
            row.push(r.scene_paper.map_or("-".into(), |p| num(p.fps, 0)));
            t.row(row);
        }
        md.push_str(&t.to_markdown());

        let _ = writeln!(
            md,
            "\nMilliseconds per stage (medians; the CPU backend with the staged executor, `Executor::Staged`):\n"
        );
        let mut cols = vec!["scene".to_string(), "backend".into(), "bvh_build (once)".into()];
        let stages = frame_stages(&self.rows);
        cols.extend(stages.iter().map(|s| s.name().to_string()));
        cols.push("frame".into());
        let mut t = Table::new(cols).align(1, super::report::Align::Left);
        for r in &self.rows {
            let mut add = |backend: &str, m: &FrameSummary| {
                let mut row = vec![r.name.clone(), backend.to_string(), num(r.prepared.bvh_build_ms, 1)];
                row.extend(stages.iter().map(|&s| m.ms(s).map_or("-".into(), |ms| num(ms, 2))));
                row.push(num(m.frame_ms, 2));
                t.row(row);
            };
            add("CPU", &r.cpu.0);
            if let (Some((g, _)), Some(short)) = (&r.gpu, gpu_short) {
                add(short, g);
            }
        }
        md.push_str(&t.to_markdown());
        if gpu_short == Some("lavapipe") {
            let _ = writeln!(
                md,
                "\nlavapipe is Mesa's software Vulkan rasterizer: its \"GPU\" stages run on this machine's CPU cores \
                 (stage times from wall clock, submit and wait per stage), so its figures say nothing about a \
                 hardware GPU."
            );
        }
        for e in &self.gpu_errors {
            let _ = writeln!(md, "\n- {e}");
        }
        md.push_str(&self.executors_markdown());
        md.push_str(&self.traffic_markdown());
        Section::new(format!("Table 2 reproduction ({w}x{h})"), md)
    }
}

impl Table2 {
    /// "The CPU frame, staged and fused": per scene, the staged frame (the per-stage
    /// table's) against the fused frame of the same threads.
    fn executors_markdown(&self) -> String {
        let mut md = format!(
            "\n### The CPU frame, staged and fused\n\n\
             The per-stage table above runs the CPU backend's staged executor (`Executor::Staged`: stage after stage \
             over whole-image buffers, each stage timed). The CPU backend's default is the fused executor \
             (`Executor::Fused`): `visibility_raster` sets up and bins the triangles (\"visibility_raster\"), then \
             each raster tile is depth-tested and resolved into tile-local texels and, while they are in cache, its \
             {tile}x{tile} tiles run reconstruction, shadow rays, shading and composition, timed as a whole \
             (\"tiles\"). \
             The fused frame is measured with a default `CpuBackend` of the same thread count in the same run, \
             right after each scene's staged frames (medians of {} frames after a warm-up frame); both executors \
             give the same bits. \"staged / fused\" above 1: the fused frame is faster.\n\n",
            self.frames,
            tile = hyrt_cpu::fused::FUSED_TILE,
        );
        let mut t = Table::new([
            "scene",
            "threads",
            "staged frame (ms)",
            "fused frame (ms)",
            "staged / fused",
            "fused FPS",
            "fused: visibility_raster (ms)",
            "fused: tiles (ms)",
        ]);
        for r in &self.rows {
            let (fused, last) = &r.fused;
            // A frame the fused executor could not run ran staged: say so in its cell.
            let ran = if last.executor == Executor::Fused { String::new() } else { " (ran staged)".to_string() };
            t.row([
                r.name.clone(),
                last.threads.to_string(),
                num(r.cpu.0.frame_ms, 2),
                format!("{}{ran}", num(fused.frame_ms, 2)),
                num(r.cpu.0.frame_ms / fused.frame_ms, 2),
                num(fused.fps(), 1),
                fused.ms(Stage::VisibilityRaster).map_or("-".into(), |ms| num(ms, 2)),
                num(r.fused_tiles_ms, 2),
            ]);
        }
        md.push_str(&t.to_markdown());
        md
    }

    /// "Bytes a frame moves": per scene and executor, the bytes per pixel of the
    /// [`super::traffic`] model, and the rate they were moved at against the copy loop's.
    fn traffic_markdown(&self) -> String {
        let mut md = format!(
            "\n### Bytes a frame moves\n\n\
             The bytes each executor writes and reads per pixel in its whole-image buffers, counted from the \
             frame's pixels, lights and shadow rays (`hyrt_benches::bench::traffic`): every buffer once for each \
             pass that writes it and once for each pass that reads it, as if nothing stayed in cache between \
             passes. Staged: the G-buffer (24 B a pixel, written, read by `reconstruction`), the surfaces (48 B, \
             written; read by `compaction` once per light, by `shadow_rays` once per ray, by each shading stage), \
             compaction's flags (4 B per pixel and light, written, read twice), the active pairs and occlusion \
             results (4 B a ray each), the shadow mask (1 B per pixel and light, read by each shading stage), the \
             raster and ray-traced images (16 B each, read by `composition`) and the final image (16 B). Fused: \
             the final image written (16 B a pixel); its raster tiles' texels and its tiles' surfaces, rays and \
             masks stay in cache (a frame that keeps its G-buffer writes it too, 24 B more). Neither counts `visibility_raster`'s own scratch, the scene's tables \
             and BVH, or the reads a cache line's first write makes. \"Achieved\" is those bytes over the \
             frame's median time (the whole frame, every stage), against one thread copying {} MiB with \
             `copy_from_slice` in this run ({} GB/s counting the bytes read and written, median of {COPY_RUNS} \
             copies); the frames run on every worker thread.\n\n",
            COPY_BYTES >> 20,
            num(self.copy_gb_s, 1),
        );
        let mut t = Table::new([
            "scene",
            "executor",
            "written (B/pixel)",
            "read (B/pixel)",
            "moved (B/pixel)",
            "MB a frame",
            "frame (ms)",
            "achieved GB/s",
            "copy GB/s (1 thread)",
            "achieved / copy",
        ])
        .align(1, super::report::Align::Left);
        for r in &self.rows {
            let p = r.shape.pixels.max(1) as f64;
            for (executor, m) in [(Executor::Staged, &r.cpu.0), (Executor::Fused, &r.fused.0)] {
                let traffic = frame_traffic(&r.shape, executor);
                let gb_s = traffic.gb_per_s(m.frame_ms);
                t.row([
                    r.name.clone(),
                    executor.name().to_string(),
                    num(traffic.written as f64 / p, 1),
                    num(traffic.read as f64 / p, 1),
                    num(traffic.per_pixel(r.shape.pixels), 1),
                    num(traffic.total() as f64 / 1e6, 1),
                    num(m.frame_ms, 2),
                    num(gb_s, 2),
                    num(self.copy_gb_s, 1),
                    num(gb_s / self.copy_gb_s, 2),
                ]);
            }
        }
        md.push_str(&t.to_markdown());
        md
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hyrt_core::formats::RAY_KIND_SHADOW;

    fn summary(frame_ms: f64, raster_ms: f64) -> FrameSummary {
        FrameSummary { frames: 3, stage_ms: vec![(Stage::VisibilityRaster, raster_ms)], frame_ms }
    }

    /// A Table 2 of the default scene at 20x10 with made-up times: staged 8 ms, fused 4 ms.
    fn table2(fused_executor: Executor) -> Table2 {
        let s = super::super::scenes::default_scene();
        let prepared = prepare(&s.scene, Some(1));
        let scene_camera = s.scene.camera.expect("camera");
        let camera = CameraRecord::new(&scene_camera, 20, 10);
        let mut stats = FrameStats { width: 20, height: 10, threads: 2, ..Default::default() };
        stats.rays_per_kind[RAY_KIND_SHADOW as usize] = 300;
        let plan = FramePlan::new(&prepared, &paper_frame()).expect("plan");
        let shape = FrameShape::of(&plan, &stats);
        let fused_stats = FrameStats { executor: fused_executor, fused_ms: 3.0, ..stats.clone() };
        Table2 {
            rows: vec![Table2Row {
                name: "default".into(),
                scene_paper: None,
                prepared,
                camera,
                scene_camera,
                cpu: (summary(8.0, 1.0), stats),
                fused: (summary(4.0, 1.0), fused_stats),
                fused_tiles_ms: 3.0,
                shape,
                gpu: None,
            }],
            size: (20, 10),
            cpu_label: "cpu (2 threads, staged executor)".into(),
            gpu: None,
            gpu_errors: vec![],
            frames: 3,
            copy_gb_s: 10.0,
        }
    }

    #[test]
    fn the_fused_frame_stands_beside_the_staged_one_with_their_ratio() {
        let md = table2(Executor::Fused).section().markdown;
        assert!(md.contains("### The CPU frame, staged and fused"), "{md}");
        assert!(md.contains("| default | 2 | 8.00 | 4.00 | 2.00 | 250.0 | 1.00 | 3.00 |"), "{md}");
        // The headline table's FPS, staged and fused.
        assert!(md.contains("| CPU staged ms | CPU staged FPS | CPU fused FPS |"), "{md}");
        assert!(md.contains("| 8.0 | 125.0 | 250.0 |"), "{md}");
        assert!(md.contains("the CPU backend with the staged executor"), "{md}");
        // A frame the fused executor did not run says so.
        let md = table2(Executor::Staged).section().markdown;
        assert!(md.contains("| 4.00 (ran staged) |"), "{md}");
    }

    #[test]
    fn the_bytes_each_executor_moves_are_set_against_the_copy_rate() {
        let t = table2(Executor::Fused);
        let r = &t.rows[0];
        let md = t.section().markdown;
        assert!(md.contains("### Bytes a frame moves"), "{md}");
        // Fused: the final image written, 16 B a pixel, 200 pixels = 3,200 B in 4 ms = 0.0008 GB/s,
        // against 10 GB/s.
        assert!(md.contains("| default | fused | 16.0 | 0.0 | 16.0 | 0.0 | 4.00 | 0.00 | 10.0 | 0.00 |"), "{md}");
        let staged = frame_traffic(&r.shape, Executor::Staged);
        let row = format!(
            "| default | staged | {} | {} | {} |",
            num(staged.written as f64 / 200.0, 1),
            num(staged.read as f64 / 200.0, 1),
            num(staged.per_pixel(200), 1)
        );
        assert!(md.contains(&row), "{row}\n{md}");
        assert!(staged.total() > frame_traffic(&r.shape, Executor::Fused).total());
    }
}
