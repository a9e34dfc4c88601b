//! `hyrt bench`: the paper's Table 2 reproduced on both backends, peers (Intel Embree,
//! Mesa lavapipe) tracing and rasterizing the same rays with the same threads, scaling
//! with pixel and triangle counts, and moving objects (two levels against a rebuild, and
//! Embree's instances), written as a Markdown report with PNG plots.
//!
//! [`run`] measures and returns a [`Report`] (header plus ordered [`Section`]s, plots
//! already written into the output folder); more sections can be pushed before
//! [`Report::write`] writes `report.md`. All times are medians over repeated frames or
//! repetitions within this one run; nothing here asserts a speed.

pub mod bounces;
pub mod exact_helpers;
pub mod hit_points;
pub mod instancing;
pub mod machine;
pub mod moving;
pub mod peers;
pub mod plots;
pub mod report;
pub mod scaling;
pub mod scenes;
pub mod soft_shadows;
pub mod stats;
pub mod table2;
pub mod traffic;

#[cfg(feature = "embree")]
pub mod embree;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, Executor, Frame, FrameOptions, FrameStats, PreparedScene, RenderError};
use hyrt_core::geometry::WorldGeometry;
use hyrt_cpu::backend::CpuBackend;
use hyrt_gpu::backend::GpuBackend;
use hyrt_gpu::AdapterPolicy;
use indicatif::ProgressBar;

pub use report::{Report, Section, Table};
pub use scenes::{BenchScene, SceneSet};
pub use stats::{median, FrameSummary};

/// What can stop a benchmark run.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: cannot create the output folder: {source}")]
    CreateDir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("font {path}: {message} (plots need DejaVu Sans: Debian package fonts-dejavu-core)")]
    Font { path: PathBuf, message: String },
    #[error("plot {path}: {message}")]
    Plot { path: PathBuf, message: String },
    #[error("scene {scene}: {source}")]
    Render {
        scene: String,
        #[source]
        source: RenderError,
    },
    #[error("invalid benchmark options: {0}")]
    Options(String),
    #[error(transparent)]
    Accuracy(#[from] hyrt_accuracy::AccuracyError),
}

/// Settings of one benchmark run.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Folder for `report.md` and the plots (created if missing).
    pub out_dir: PathBuf,
    /// Frames per measurement (after one warm-up frame); medians are taken over them.
    pub frames: usize,
    /// Rounds of each peer ray-tracing contest: every contender of a ray list runs once
    /// per round, interleaved (`stats::interleaved_ms`); medians and per-round ratios.
    pub repeats: usize,
    /// Image size of the Table 2 reproduction and the peers.
    pub table_size: (u32, u32),
    /// Image sizes of the pixel-count scaling.
    pub pixel_sizes: Vec<(u32, u32)>,
    /// Thread counts the peers run with (rayon pools of that size).
    pub peer_threads: Vec<usize>,
    /// Worker threads of the CPU backend for whole frames (`None`: one per core).
    pub frame_threads: Option<usize>,
    /// Try the GPU backend (under `policy`); skipped with a note when no adapter fits.
    pub gpu: bool,
    pub policy: AdapterPolicy,
    /// Which scenes.
    pub scenes: SceneSet,
    /// Run the triangle-count scaling (loads the 871k-triangle dragon).
    pub triangle_scaling: bool,
    /// The command line, quoted at the top of the report.
    pub command_line: String,
    /// True for `--quick` (said in the report).
    pub quick: bool,
    /// Run the speed-against-error section ([`hyrt_accuracy`]) on the default scene
    /// and the teaser, at `table_size`.
    pub accuracy: bool,
}

/// The scenes of the speed-against-error section (by [`scenes::BenchScene::name`]).
const ACCURACY_SCENES: [&str; 2] = ["default", "teaser"];

impl BenchOptions {
    /// The `--quick` settings: a few minutes on a 2-core machine.
    pub fn quick(out_dir: PathBuf) -> BenchOptions {
        BenchOptions {
            out_dir,
            frames: 5,
            repeats: 3,
            table_size: (1280, 720),
            pixel_sizes: vec![(640, 360), (1280, 720), (1920, 1080)],
            peer_threads: vec![1, 2],
            frame_threads: None,
            gpu: true,
            policy: AdapterPolicy::from_env(),
            scenes: SceneSet::All,
            triangle_scaling: true,
            command_line: String::new(),
            quick: true,
            accuracy: true,
        }
    }

    /// The full settings: more frames and repetitions, up to 2160p.
    pub fn full(out_dir: PathBuf) -> BenchOptions {
        BenchOptions {
            frames: 21,
            repeats: 7,
            pixel_sizes: vec![(640, 360), (1280, 720), (1920, 1080), (3840, 2160)],
            quick: false,
            ..BenchOptions::quick(out_dir)
        }
    }

    fn check(&self) -> Result<(), BenchError> {
        let bad = |m: &str| Err(BenchError::Options(m.to_string()));
        if self.frames == 0 || self.repeats == 0 {
            return bad("frames and repeats must be at least 1");
        }
        if self.peer_threads.contains(&0) || self.frame_threads == Some(0) {
            return bad("thread counts must be at least 1");
        }
        if self.table_size.0 == 0 || self.table_size.1 == 0 || self.pixel_sizes.iter().any(|s| s.0 == 0 || s.1 == 0) {
            return bad("image sizes must be at least 1x1");
        }
        Ok(())
    }
}

/// A backend to measure frames on: the CPU one or the GPU one, with a label for the report.
pub struct FrameBackend {
    pub backend: Box<dyn Backend>,
    /// "cpu (2 threads)", "gpu: llvmpipe ... (software rasterizer, lavapipe)".
    pub label: String,
    /// Short column name: "CPU" or "GPU" / "lavapipe".
    pub short: String,
}

/// The CPU backend with the staged executor (every stage timed: Table 2's per-stage table,
/// the scaling, the bounces and the moving scenes' frames), and the GPU backend when
/// `options.gpu` and an adapter fits the policy (otherwise a note says why not). Table 2
/// measures the CPU's default, fused executor beside it ([`table2::run`]).
pub fn frame_backends(options: &BenchOptions, notes: &mut Vec<String>) -> (FrameBackend, Option<FrameBackend>) {
    let mut cpu = CpuBackend::new(options.frame_threads);
    cpu.set_executor(Executor::Staged);
    let cpu = FrameBackend {
        label: format!("cpu ({} threads, staged executor)", cpu.threads()),
        short: "CPU".into(),
        backend: Box::new(cpu),
    };
    if !options.gpu {
        notes.push("GPU backend not measured (disabled by the options)".into());
        return (cpu, None);
    }
    let gpu = match GpuBackend::new(options.policy) {
        Ok(g) => g,
        Err(e) => {
            notes.push(format!("GPU backend not measured: {e}"));
            return (cpu, None);
        }
    };
    let software = hyrt_gpu::context::is_software(&gpu.context().info);
    let (label, short) = if software {
        let threads = std::env::var("LP_NUM_THREADS").unwrap_or_else(|_| "default: one per core".into());
        (
            format!(
                "gpu on a SOFTWARE rasterizer (Mesa lavapipe, runs on this CPU; LP_NUM_THREADS {threads}): {}",
                gpu.describe()
            ),
            "lavapipe".to_string(),
        )
    } else {
        (format!("gpu: {}", gpu.describe()), "GPU".to_string())
    };
    (cpu, Some(FrameBackend { backend: Box::new(gpu), label, short }))
}

/// World tables and BVH of a scene (the `bvh_build` stage, timed), on a pool of the
/// backend's default size.
pub fn prepare(scene: &hyrt_core::scene::Scene, threads: Option<usize>) -> PreparedScene {
    CpuBackend::new(threads).prepare(WorldGeometry::build(scene), BvhPreset::default())
}

/// The options of the paper's frame, as Table 2 measures it: shadow rays only (the bounces
/// have their own section), no stage outputs kept.
pub fn paper_frame() -> FrameOptions {
    FrameOptions { weight: 1.0, stage_outputs: false, max_depth: 0, ..FrameOptions::default() }
}

/// One warm-up frame, then `frames` frames into the same reused [`Frame`]; returns the
/// summary and the last frame's statistics.
pub fn measure_frames(
    backend: &mut dyn Backend,
    prepared: &PreparedScene,
    camera: &CameraRecord,
    frames: usize,
) -> Result<(FrameSummary, FrameStats), RenderError> {
    let (summary, mut stats) = measure_frames_with(backend, prepared, camera, frames, &paper_frame())?;
    Ok((summary, stats.pop().expect("at least one frame")))
}

/// [`measure_frames`] with `options`; the summary and every measured frame's statistics.
pub fn measure_frames_with(
    backend: &mut dyn Backend,
    prepared: &PreparedScene,
    camera: &CameraRecord,
    frames: usize,
    options: &FrameOptions,
) -> Result<(FrameSummary, Vec<FrameStats>), RenderError> {
    let mut frame = Frame::default();
    backend.render_into(prepared, camera, options, &mut frame)?;
    let mut stats = Vec::with_capacity(frames);
    for _ in 0..frames {
        backend.render_into(prepared, camera, options, &mut frame)?;
        stats.push(frame.stats.clone());
    }
    let summary =
        FrameSummary::from_frames(&stats).ok_or_else(|| RenderError::InvalidOptions("no frame was measured".into()))?;
    Ok((summary, stats))
}

fn header(options: &BenchOptions, cpu: &FrameBackend, gpu: Option<&FrameBackend>) -> String {
    let m = machine::MachineInfo::detect();
    let mut h = String::new();
    let _ = writeln!(h, "Command: `{}`\n", options.command_line.trim());
    let mut t = Table::new(["", "this run"]).align(1, report::Align::Left);
    t.row(["machine".to_string(), format!("{} ({} logical cores)", m.cpu, m.cores)]);
    t.row(["OS".to_string(), m.os]);
    t.row(["load average at start (1, 5, 15 min)".to_string(), m.load]);
    t.row(["hyrt".to_string(), m.hyrt]);
    t.row(["rustc".to_string(), m.rustc]);
    t.row(["CPU backend".to_string(), cpu.label.clone()]);
    t.row(["GPU backend".to_string(), gpu.map_or("not measured (see notes)".to_string(), |g| g.label.clone())]);
    t.row(["Embree".to_string(), peers::embree_peer()]);
    let simd = hyrt_cpu::traversal::SimdLevel::detect();
    t.row([
        "SIMD level of hyrt's traversals".to_string(),
        if hyrt_cpu::traversal::simd_level_forced() {
            format!(
                "{} (forced: `--simd` or HYRT_SIMD; this CPU's best is {})",
                simd.name(),
                hyrt_cpu::traversal::SimdLevel::best().name()
            )
        } else {
            format!("{} (this CPU's best)", simd.name())
        },
    ]);
    t.row([
        "shading".to_string(),
        format!(
            "the {} model (`--shading {}`) on every scene of every section, so that Table 2 and the speed-against-error figures compare with the paper and with earlier reports (`hyrt render` shades glTF files, manifests and the default scene with the glTF BRDF unless told otherwise)",
            scenes::REPORT_SHADING.name(),
            scenes::REPORT_SHADING.name()
        ),
    ]);
    t.row([
        "settings".to_string(),
        format!(
            "{}; {} frames per measurement (medians, after one warm-up frame), at least {} interleaved rounds per peer contest (after a warm-up round; ratios taken round by round; each turn traces the list once, as a frame does; a list whose rounds would take its fastest contender under {} ms gets more rounds, at most {}; every contender in one pool whose workers are pinned one per CPU); Table 2 at {}x{}; BVH preset {}",
            if options.quick { "--quick" } else { "full" },
            options.frames,
            options.repeats,
            peers::MIN_CONTEST_MS,
            peers::MAX_ROUNDS,
            options.table_size.0,
            options.table_size.1,
            BvhPreset::default().name(),
        ),
    ]);
    h.push_str(&t.to_markdown());
    if let Some(w) = machine::busy_warning(m.cores) {
        let _ = write!(h, "\n{w}\n");
    }
    h
}

/// Run every measurement and write the plots into `options.out_dir`; returns the report
/// (not yet written: push more sections, then [`Report::write`]). `progress` shows the
/// steps (use [`ProgressBar::hidden`] for none).
pub fn run(options: &BenchOptions, progress: &ProgressBar) -> Result<Report, BenchError> {
    options.check()?;
    std::fs::create_dir_all(&options.out_dir)
        .map_err(|source| BenchError::CreateDir { path: options.out_dir.clone(), source })?;
    let mut notes = Vec::new();
    progress.set_message("opening backends");
    let (mut cpu, mut gpu) = frame_backends(options, &mut notes);
    let header = header(options, &cpu, gpu.as_ref());

    let t2_scenes = scenes::table2_scenes(options.scenes, &mut notes);
    let table2 = table2::run(options, &t2_scenes, &mut cpu, gpu.as_mut(), progress)?;
    let accuracy_scenes: Vec<(String, hyrt_core::scene::Scene)> = t2_scenes
        .iter()
        .filter(|s| options.accuracy && ACCURACY_SCENES.contains(&s.name.as_str()))
        .map(|s| (s.name.clone(), s.scene.clone()))
        .collect();
    let moving = moving::run(options, &t2_scenes, &mut cpu, gpu.as_mut(), progress)?;
    drop(t2_scenes);
    let peers = peers::run(options, &table2, progress)?;
    let scaling = scaling::run(options, &table2, &mut cpu, gpu.as_mut(), &mut notes, progress)?;
    let bounces = bounces::run(options, &table2, &mut cpu, gpu.as_mut(), progress)?;
    let exact_helpers = exact_helpers::run(options, &table2, gpu.as_mut(), progress)?;
    let soft_shadows = soft_shadows::run(options, progress)?;
    // Last, so that its 871 million triangles disturb no other measurement; its peak
    // resident memory is counted from a reset (what the process held before is reported).
    let gpu_instancing = instancing::run_gpu(options, gpu.as_mut(), progress)?;
    let instancing = instancing::run(options, progress)?;

    let mut sections = vec![
        table2.section(),
        bounces.section(&table2),
        exact_helpers.section(&table2),
        soft_shadows.section(&options.out_dir),
        peers.section(&table2),
        scaling.section.clone(),
        moving.section(),
        instancing.section(&gpu_instancing),
    ];
    let mut files = scaling.files.clone();
    files.extend(soft_shadows.plot.clone());
    if !accuracy_scenes.is_empty() {
        let (width, height) = options.table_size;
        let threads = options.frame_threads.unwrap_or_else(rayon::current_num_threads);
        let opts = hyrt_accuracy::AccuracyOptions { quick: options.quick, threads, width, height };
        let mut md = String::new();
        for (name, scene) in &accuracy_scenes {
            progress.set_message(format!("speed against error: {name}"));
            let report = |m: &str| progress.set_message(format!("speed against error: {name}: {m}"));
            let section = hyrt_accuracy::speed_vs_error(name, scene, &opts, &options.out_dir, &report)?;
            md += &section.markdown;
            md += "\n";
            files.extend(section.plots);
        }
        progress.set_message("speed against error: leak corpus");
        let report = |m: &str| progress.set_message(format!("speed against error: {m}"));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| hyrt_accuracy::AccuracyError::Threads { threads, message: e.to_string() })?;
        let rows = pool.install(|| hyrt_accuracy::leaks::leak_offsets(options.quick, &report));
        md += &hyrt_accuracy::leaks::leak_offsets_markdown(&rows);
        progress.set_message("speed against error: texture filtering");
        // Frames of under 0.1 s: 9 even in quick runs (3 left the same frame 15% apart).
        let runs = if options.quick { 9 } else { 21 };
        let (_, textures) = hyrt_accuracy::textures::texture_speed_vs_error(width, height, threads, runs);
        md += "\n### Texture filtering and the alpha test\n\n";
        md += &textures;
        sections.push(Section::new("Speed against error", md));
    }
    sections.push(goals(&table2, &peers));
    if !notes.is_empty() {
        let mut md = String::new();
        for n in &notes {
            let _ = writeln!(md, "- {n}");
        }
        sections.push(Section::new("Notes", md));
    }
    progress.set_message("done");
    let mut header = header;
    if let Some(l) = machine::load_average() {
        let _ = write!(header, "\nLoad average at the end of the run: {:.2} {:.2} {:.2}.\n", l[0], l[1], l[2]);
    }
    // Known only now: the level each kind of walk ran at, where the stages measured it.
    let tuned = hyrt_cpu::traversal::tuning::summary();
    if !tuned.is_empty() {
        let _ = writeln!(
            header,
            "\nSIMD level per kind of walk (the stages measured AVX-512 against AVX2 on interleaved chunks of \
             their rays and kept the faster; the packets named `packet-auto` below): {}.",
            tuned.join("; ")
        );
    }
    Ok(Report { title: "hyrt benchmark report".into(), header, sections, files })
}

/// Goals and how far hyrt is from each, from this run's figures.
fn goals(table2: &table2::Table2, peers: &peers::Peers) -> Section {
    let mut t = Table::new(["goal", "target", "hyrt (this run)", "hyrt / target"]);
    for g in peers.goals() {
        t.row(g);
    }
    for r in &table2.rows {
        let Some(p) = r.scene_paper else { continue };
        // The CPU backend's frame as it renders by default: fused.
        let fps = r.fused.0.fps();
        t.row([
            format!(
                "{}: the paper's FPS (9800 GTX+, CUDA), CPU backend, {} frame ({})",
                p.scene,
                r.fused.1.executor.name(),
                r.name
            ),
            format!("{} FPS", report::num(p.fps, 0)),
            format!("{} FPS", report::num(fps, 1)),
            report::num(fps / p.fps, 2),
        ]);
    }
    let md = format!(
        "Ratios above 1 mean hyrt meets the goal, except where a row names its own (\"1.5 would be ...\", \
         \"2.0 would be ...\"). Peer targets are measured in this same run with the same rays \
         and threads (see Peers): the contenders of a ray list run interleaved, round by round, so a ray goal's \
         ratio is the median of the rounds' ratios (hyrt's time against the fastest peer's of the same round), with \
         the least and greatest round in brackets; rates are medians over the rounds. \"Hybrid frame vs Embree \
         tracing the same frame\" takes hyrt's whole CPU frame as the CPU backend runs it by default: the fused \
         executor (the row names the executor that ran), measured right before the peers' rays. \"Raster + \
         reconstruction vs hyrt's own primary rays\" is the paper's premise: the staged frame's \
         `visibility_raster` and `reconstruction` medians (measured beside that fused frame, at the most threads) \
         against hyrt's packets tracing the same frame's primary rays; the ratio is the rays' time over the raster \
         and reconstruction's, and the goal is 2 (they cost at most half the rays). The paper's FPS rows take the \
         CPU backend's fused frame (Table 2). The paper's FPS were measured on 2011 GPU hardware at an unstated \
         image size.\n\n{}",
        t.to_markdown()
    );
    Section::new("Goals", md)
}

/// Write the report into `options.out_dir` and return its path: [`run`] then [`Report::write`].
pub fn run_and_write(options: &BenchOptions, progress: &ProgressBar) -> Result<(Report, PathBuf), BenchError> {
    let report = run(options, progress)?;
    let path = report.write(&options.out_dir)?;
    Ok((report, path))
}

/// Relative path of a file in the report folder, as the report links it.
pub fn link(dir: &Path, file: &Path) -> String {
    file.strip_prefix(dir).unwrap_or(file).display().to_string()
}
