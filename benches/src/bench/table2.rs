//! The paper's Table 2 (scene, valid rays, FPS) reproduced: per-stage and per-frame
//! medians on the CPU backend and, when available, the GPU backend.

use std::fmt::Write as _;

use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{FrameStats, PreparedScene};
use hyrt_core::scene::Camera;
use hyrt_core::stage::Stage;
use indicatif::ProgressBar;

use super::report::{count, num, Section, Table};
use super::scenes::{BenchScene, PaperRow, PAPER_TABLE2};
use super::stats::FrameSummary;
use super::{measure_frames, prepare, BenchError, BenchOptions, FrameBackend};

/// One scene's measurements.
pub struct Table2Row {
    pub name: String,
    pub scene_paper: Option<PaperRow>,
    pub prepared: PreparedScene,
    pub camera: CameraRecord,
    /// The scene's camera (for other image sizes).
    pub scene_camera: Camera,
    /// CPU backend: medians and the last frame's counts.
    pub cpu: (FrameSummary, FrameStats),
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
}

/// Measure every scene at `options.table_size`.
pub fn run(
    options: &BenchOptions,
    scenes: &[BenchScene],
    cpu: &mut FrameBackend,
    mut gpu: Option<&mut FrameBackend>,
    progress: &ProgressBar,
) -> Result<Table2, BenchError> {
    let (w, h) = options.table_size;
    progress.inc_length(scenes.len() as u64 * (1 + gpu.is_some() as u64));
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
            gpu: gpu_m,
        });
    }
    Ok(Table2 {
        rows,
        size: options.table_size,
        cpu_label: cpu.label.clone(),
        gpu: gpu.map(|g| (g.label.clone(), g.short.clone())),
        gpu_errors,
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
             stages (without `bvh_build`, which runs once per scene); the horse stands in for the paper's toad \
             (same triangle count). CPU: {}.{}\n",
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
            "CPU ms".into(),
            "CPU FPS".into(),
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

        let _ = writeln!(md, "\nMilliseconds per stage (medians):\n");
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
        Section::new(format!("Table 2 reproduction ({w}x{h})"), md)
    }
}
