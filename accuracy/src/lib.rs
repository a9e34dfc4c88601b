//! Speed against error: every configuration of the pipeline the paper leaves open,
//! timed and scored against an f64 reference renderer ([`reference`](mod@reference)).
//!
//! Groups of configurations (each a full CPU frame built from the `hyrt_cpu` stage
//! functions, with one step changed; the pipeline itself is untouched):
//!
//! * `bvh`: every [`BvhPreset`]: build time, shadow-ray traversal speed.
//! * `barycentrics`: the G-buffer's f32 barycentrics against the same quantized to
//!   16-bit unorm ([`variants::quantize_unorm16`]) before reconstruction, and against
//!   each pixel's camera ray re-intersected with the rasterized triangle
//!   (`PrimaryBarycentrics::Reintersected`: hit points as exact as a ray tracer's; the
//!   pipeline's default, so every other group's frame takes them).
//! * `ray origin`: shadow-ray origins with no offset, a constant epsilon along the
//!   normal, Wächter and Binder's 256 ulps, and the error-bound offset the pipeline uses
//!   ([`variants::OffsetMethod`]).
//! * `shadows`: ray-traced shadows against shadow maps of several resolutions
//!   ([`shadow_map`]): the paper's claim that ray-traced shadows are more accurate.
//!
//! These four groups measure the paper's frame (max depth 0). Where the scene has a
//! ray-traced mirror or glass, three more measure the reflection and refraction bounces
//! against the reference with bounce paths ([`bounce_reference`]):
//!
//! * `max depth`: the frame at `max_depth` 0 to [`MAX_DEPTHS`].
//! * `bounce origin`: secondary-ray origins by each [`variants::OffsetMethod`]
//!   ([`bounce_variants::reoffset_secondary_rays`]), at the default depth.
//! * `throughput cut-off`: the path-weight cut-off below which a lobe is not traced
//!   ([`bounce_variants::CUTOFFS_LOG2`], spawned by [`bounce_variants::spawn_with_cutoff`]).
//!
//! [`leaks`] compares the ray-origin offsets again on the leak corpus (closed shells far
//! from the origin, lights sealed inside or outside), where they decide whether light
//! escapes. [`textures`] compares texture filtering (level 0 against ray-cone mip maps)
//! with a supersampled reference, and times the alpha test.
//!
//! Errors ([`metrics`]): shadow-mask mismatches against the reference (false shadows and
//! light leaks, over the (pixel, light) pairs both traced), hit-point error relative to
//! the scene extent, image RMSE, mean FLIP (`nv-flip`, NVIDIA's implementation) and wrong
//! pixels (8-bit sRGB codes off by more than [`metrics::WRONG_PIXEL_CODES`]).
//!
//! ```no_run
//! use hyrt_accuracy::{speed_vs_error, AccuracyOptions};
//! let mut scene = hyrt::Scene::default_scene();
//! scene.ensure_camera_and_lights();
//! let opts = AccuracyOptions { quick: true, threads: 2, width: 160, height: 90 };
//! let section = speed_vs_error("default", &scene, &opts, std::path::Path::new("report"), &|m| eprintln!("{m}"))?;
//! println!("{}", section.markdown);
//! # Ok::<(), hyrt_accuracy::AccuracyError>(())
//! ```

pub mod bounce_reference;
pub mod bounce_variants;
pub mod leaks;
pub mod metrics;
pub mod plot;
pub mod reference;
pub mod shadow_map;
pub mod textures;
pub mod variants;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::formats::{CameraRecord, SurfaceRecord};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::bounce::{bounces, DEFAULT_MAX_DEPTH};
use hyrt_core::scene::Scene;
use hyrt_cpu::compaction::{compaction, shadow_mask};
use hyrt_cpu::reconstruction::{reconstruction, reconstruction_reintersected_into};
use hyrt_cpu::shadow_rays::shadow_rays;
use hyrt_cpu::visibility_raster::visibility_raster;

use bounce_reference::{render_reference_bounces, BounceImage, REFERENCE_MAX_DEPTH};
use bounce_variants::{bounce_rt_image, cutoff_name, BounceVariant, PrimaryBuffers, CUTOFFS_LOG2};
use metrics::{HitPointError, ShadowComparison};
use reference::{compose_with_raster, render_reference, shade_image, ReferenceFrame};
use variants::OffsetMethod;

/// What [`speed_vs_error`] measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AccuracyOptions {
    /// Fewer runs per configuration (1 instead of [`FULL_RUNS`]) and fewer shadow-map
    /// resolutions ([`QUICK_SHADOW_MAP_RESOLUTIONS`]).
    pub quick: bool,
    /// Worker threads (0: one per core).
    pub threads: usize,
    pub width: u32,
    pub height: u32,
}

/// Runs per configuration without `quick`; the median is reported.
pub const FULL_RUNS: usize = 5;

/// Shadow-map resolutions (texels per side of a cube face) without `quick`.
pub const SHADOW_MAP_RESOLUTIONS: [u32; 4] = [512, 1024, 2048, 4096];

/// Shadow-map resolutions with `quick`.
pub const QUICK_SHADOW_MAP_RESOLUTIONS: [u32; 2] = [256, 1024];

/// The `max depth` group measures `max_depth` 0 to this (the issue's 0..8).
pub const MAX_DEPTHS: u32 = 8;

/// The depth of the `bounce origin` and `throughput cut-off` groups: the default (both backends).
pub const VARIANT_MAX_DEPTH: u32 = DEFAULT_MAX_DEPTH;

/// The groups of the paper's frame (max depth 0), scored against the reference without
/// bounces.
pub const FRAME_GROUPS: [&str; 4] = ["bvh", "barycentrics", "ray origin", "shadows"];

/// The groups of bounces, scored against the reference with bounce paths.
pub const BOUNCE_GROUPS: [&str; 3] = ["max depth", "bounce origin", "throughput cut-off"];

/// One configuration's measurements.
#[derive(Clone, Debug, PartialEq)]
pub struct AccuracyRow {
    pub scene: String,
    /// One of [`FRAME_GROUPS`] or [`BOUNCE_GROUPS`].
    pub group: String,
    pub configuration: String,
    /// Median time of the whole CPU frame with this configuration, in ms.
    pub frame_ms: f64,
    /// Median time of the step the group varies ([`AccuracyRow::stage`]), in ms.
    pub stage_ms: f64,
    /// What `stage_ms` covers.
    pub stage: String,
    /// BVH build time (median), for the `bvh` group.
    pub build_ms: Option<f64>,
    /// Shadow rays traced per second (millions), where shadows are ray traced.
    pub mrays_per_s: Option<f64>,
    /// Secondary (reflection and refraction) rays traced, all bounces; bounce groups only.
    pub secondary_rays: Option<u64>,
    pub shadow: ShadowComparison,
    /// Pixels whose primary hit differs from the reference's.
    pub primary_mismatches: u64,
    pub hit_error: HitPointError,
    pub rmse: f64,
    pub flip: f64,
    /// Pixels whose 8-bit sRGB codes differ from the reference's by more than
    /// [`metrics::WRONG_PIXEL_CODES`] ([`metrics::wrong_pixels`]).
    pub wrong_pixels: u64,
}

/// What [`speed_vs_error`] writes and returns.
#[derive(Clone, Debug)]
pub struct AccuracySection {
    /// A Markdown section (settings, table, plot link, notes).
    pub markdown: String,
    /// The plot files written into `out_dir`.
    pub plots: Vec<PathBuf>,
    pub rows: Vec<AccuracyRow>,
}

/// Why the measurement could not be made.
#[derive(Debug, thiserror::Error)]
pub enum AccuracyError {
    #[error("scene {scene}: no camera (call Scene::ensure_camera_and_lights first)")]
    NoCamera { scene: String },
    #[error("scene {scene}: image size must be non-zero, got {width}x{height}")]
    EmptyImage { scene: String, width: u32, height: u32 },
    #[error("scene {scene}: invalid camera: {message}")]
    InvalidCamera { scene: String, message: String },
    #[error("{path}: cannot create the output directory: {source}")]
    OutputDir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Plot(#[from] plot::PlotError),
    #[error("cannot start {threads} worker threads: {message}")]
    Threads { threads: usize, message: String },
}

/// One configuration of the frame.
#[derive(Clone, Copy, Debug)]
enum Config {
    /// The pipeline as is, with a BVH built with this preset (stage: shadow_rays).
    Bvh(BvhPreset),
    /// Where reconstruction takes barycentrics from (stage: quantization +
    /// reconstruction).
    Barycentrics(BarySource),
    /// Shadow-ray origins (stage: compaction + re-offset + shadow_rays).
    Offset(OffsetMethod),
    /// Shadow maps of this resolution, or ray-traced shadows for `None` (stage: shadows).
    Shadows(Option<u32>),
    /// The pipeline's shadows and bounces down to `max_depth`, with `variant`'s change
    /// (stage: the bounce stages).
    Bounces { max_depth: u32, variant: BounceVariant },
}

/// The barycentrics of the `barycentrics` group.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum BarySource {
    /// The raster's f32 barycentrics.
    Raster,
    /// The raster's, quantized to 16-bit unorm first.
    Unorm16,
    /// Each pixel's camera ray re-intersected with the rasterized triangle
    /// (`PrimaryBarycentrics::Reintersected`, the pipeline's default: every other group's
    /// frame takes it).
    Reintersected,
}

/// The outputs of one frame and its times.
struct FrameRun {
    surfaces: Vec<SurfaceRecord>,
    mask: Vec<u8>,
    image: Vec<[f32; 4]>,
    rays: usize,
    /// Secondary rays traced ([`Config::Bounces`]).
    secondary_rays: Option<u64>,
    frame_ms: f64,
    stage_ms: f64,
    shadow_ms: f64,
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Render one frame with `config`, timing the whole and the varied step.
/// `bvh` is the BVH to trace (for [`Config::Bvh`], one built with its preset).
fn run_frame(g: &WorldGeometry, bvh: &Bvh, camera: &CameraRecord, config: Config) -> FrameRun {
    let eye = Vec3::from(camera.eye);
    let extent = g.scene_extent();
    let t_frame = Instant::now();
    let gbuffer = visibility_raster(g, camera).gbuffer;
    let t_rec = Instant::now();
    let surfaces = match config {
        Config::Barycentrics(BarySource::Unorm16) => reconstruction(&variants::quantize_gbuffer(&gbuffer), g, eye),
        Config::Barycentrics(BarySource::Raster) => reconstruction(&gbuffer, g, eye),
        // The pipeline's default (`FrameOptions::default().barycentrics`).
        _ => {
            let mut s = Vec::new();
            reconstruction_reintersected_into(&gbuffer, g, camera, &mut s);
            s
        }
    };
    let rec_ms = ms_since(t_rec);
    let t_shadow = Instant::now();
    let (mask, rays, trace_ms) = match config {
        Config::Shadows(Some(res)) => (shadow_map::shadow_map_mask(g, &surfaces, res), 0, 0.0),
        _ => {
            let mut rays = compaction(&surfaces, &g.lights);
            if let Config::Offset(m) = config {
                if m != OffsetMethod::PIPELINE {
                    variants::reoffset_rays(&mut rays, &surfaces, &g.lights, m, extent);
                }
            }
            let t_trace = Instant::now();
            let occluded = shadow_rays(bvh, g, &rays);
            let trace_ms = ms_since(t_trace);
            (shadow_mask(&rays, &occluded, surfaces.len(), g.lights.len()), rays.len(), trace_ms)
        }
    };
    let shadow_ms = ms_since(t_shadow);
    let (image, bounce) = match config {
        Config::Bounces { max_depth, variant } => {
            let primary = PrimaryBuffers { gbuffer: &gbuffer, surfaces: &surfaces, shadow: &mask, eye };
            let b = bounce_rt_image(g, bvh, primary, max_depth, variant);
            (
                compose_with_raster(&b.rt, &surfaces, &mask, &g.objects, &g.lights, &g.ambient, eye),
                Some((b.rays, b.bounce_ms)),
            )
        }
        _ => (shade_image(&surfaces, &mask, &g.objects, &g.lights, &g.ambient, eye), None),
    };
    let frame_ms = ms_since(t_frame);
    let stage_ms = match config {
        Config::Bvh(_) => trace_ms,
        Config::Barycentrics(_) => rec_ms,
        Config::Offset(_) | Config::Shadows(_) => shadow_ms,
        Config::Bounces { .. } => bounce.map_or(0.0, |b| b.1),
    };
    let secondary_rays = bounce.map(|b| b.0);
    FrameRun { surfaces, mask, image, rays, secondary_rays, frame_ms, stage_ms, shadow_ms: trace_ms }
}

/// The final image of the CPU frame with bounces down to `max_depth` and `variant`'s
/// change, as [`speed_vs_error`] measures it: with [`BounceVariant::PIPELINE`], the
/// `CpuBackend`'s frame at `FrameOptions { max_depth, ..Default::default() }`.
pub fn frame_image(
    g: &WorldGeometry,
    bvh: &Bvh,
    camera: &CameraRecord,
    max_depth: u32,
    variant: BounceVariant,
) -> Vec<[f32; 4]> {
    run_frame(g, bvh, camera, Config::Bounces { max_depth, variant }).image
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// One configuration to measure.
struct Job {
    group: &'static str,
    configuration: String,
    stage: &'static str,
    config: Config,
}

/// Times of one run of a job.
#[derive(Clone, Copy, Default)]
struct RunTimes {
    frame_ms: f64,
    stage_ms: f64,
    shadow_ms: f64,
    build_ms: Option<f64>,
}

/// Score one frame against the reference (its image against `image`: the reference's own,
/// or with bounces): a row without times.
fn score(
    scene: &str,
    job: &Job,
    g: &WorldGeometry,
    refr: &ReferenceFrame,
    image: &[[f32; 4]],
    r: &FrameRun,
) -> AccuracyRow {
    AccuracyRow {
        scene: scene.to_string(),
        group: job.group.to_string(),
        configuration: job.configuration.clone(),
        frame_ms: 0.0,
        stage_ms: 0.0,
        stage: job.stage.to_string(),
        build_ms: None,
        mrays_per_s: None,
        secondary_rays: r.secondary_rays,
        shadow: metrics::compare_shadows(refr, &r.surfaces, &r.mask),
        primary_mismatches: metrics::primary_mismatches(refr, &r.surfaces),
        hit_error: metrics::hit_point_error(refr, &r.surfaces, g.scene_extent() as f64),
        rmse: metrics::rmse(image, &r.image),
        flip: metrics::flip_mean(image, &r.image, refr.width, refr.height),
        wrong_pixels: metrics::wrong_pixels(image, &r.image),
    }
}

/// Measure every configuration on `scene` (which needs a camera and lights; see
/// [`Scene::ensure_camera_and_lights`]), write the Pareto plot `accuracy-<scene>.png`
/// into `out_dir` and return the Markdown section. `progress` gets a line per step.
pub fn speed_vs_error(
    scene_name: &str,
    scene: &Scene,
    opts: &AccuracyOptions,
    out_dir: &Path,
    progress: &dyn Fn(&str),
) -> Result<AccuracySection, AccuracyError> {
    let camera = scene.camera.ok_or_else(|| AccuracyError::NoCamera { scene: scene_name.to_string() })?;
    if opts.width == 0 || opts.height == 0 {
        return Err(AccuracyError::EmptyImage {
            scene: scene_name.to_string(),
            width: opts.width,
            height: opts.height,
        });
    }
    let record = CameraRecord::new(&camera, opts.width, opts.height);
    record.validate().map_err(|message| AccuracyError::InvalidCamera { scene: scene_name.to_string(), message })?;
    std::fs::create_dir_all(out_dir)
        .map_err(|source| AccuracyError::OutputDir { path: out_dir.to_path_buf(), source })?;
    let mut builder = rayon::ThreadPoolBuilder::new();
    if opts.threads > 0 {
        builder = builder.num_threads(opts.threads);
    }
    let pool = builder.build().map_err(|e| AccuracyError::Threads { threads: opts.threads, message: e.to_string() })?;
    let threads = pool.current_num_threads();
    let (rows, notes) = measure_all(&pool, scene_name, scene, &camera, record, opts, progress);
    let slug: String =
        scene_name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' }).collect();
    let plot_path = out_dir.join(format!("accuracy-{slug}.png"));
    progress(&format!("{scene_name}: plotting {}", plot_path.display()));
    let size = format!("{}x{}, CPU, {threads} threads", opts.width, opts.height);
    let frame_rows: Vec<AccuracyRow> =
        rows.iter().filter(|r| FRAME_GROUPS.contains(&r.group.as_str())).cloned().collect();
    plot::pareto_plot(&plot_path, &format!("{scene_name}: speed against error ({size})"), &plot_panels(&frame_rows))?;
    let mut plots = vec![plot_path];
    let mut markdown = markdown(scene_name, opts, threads, &frame_rows, &notes, &plots[0]);
    let bounce_rows: Vec<AccuracyRow> =
        rows.iter().filter(|r| BOUNCE_GROUPS.contains(&r.group.as_str())).cloned().collect();
    match &notes.bounces {
        Ok(b) => {
            let path = out_dir.join(format!("accuracy-bounces-{slug}.png"));
            progress(&format!("{scene_name}: plotting {}", path.display()));
            let title = format!("{scene_name}: bounces, speed against error ({size})");
            plot::pareto_plot(&path, &title, &bounce_panels(&bounce_rows, opts))?;
            markdown += &bounce_markdown(scene_name, &bounce_rows, b, &path);
            plots.push(path);
        }
        Err(reason) => {
            let _ = writeln!(markdown, "No bounce groups on {scene_name}: {reason}.\n");
        }
    }
    Ok(AccuracySection { markdown, plots, rows })
}

/// Scene-level facts for the Markdown text.
struct Notes {
    triangles: usize,
    lights: usize,
    extent: f32,
    reference_ms: f64,
    runs: usize,
    /// The reference with bounces, or why the bounce groups did not run.
    bounces: Result<BounceNotes, &'static str>,
}

/// Facts about the bounce reference.
struct BounceNotes {
    reference_ms: f64,
    paths: bounce_reference::PathCounts,
    max_depth: u32,
}

fn measure_all(
    pool: &rayon::ThreadPool,
    scene_name: &str,
    scene: &Scene,
    camera: &hyrt_core::scene::Camera,
    record: CameraRecord,
    opts: &AccuracyOptions,
    progress: &dyn Fn(&str),
) -> (Vec<AccuracyRow>, Notes) {
    let geometry = WorldGeometry::build(scene);
    progress(&format!("{scene_name}: {} triangles, building the default BVH", geometry.triangle_count()));
    let bvh = pool.install(|| Bvh::build(&geometry, BvhPreset::default()));
    progress(&format!("{scene_name}: f64 reference at {}x{}", opts.width, opts.height));
    let t = Instant::now();
    let reference = pool.install(|| render_reference(&geometry, &bvh, camera, opts.width, opts.height));
    let reference_ms = ms_since(t);
    let bouncing = if geometry.objects.iter().any(bounces) {
        progress(&format!("{scene_name}: f64 reference bounce paths, max depth {REFERENCE_MAX_DEPTH}"));
        let t = Instant::now();
        let b = pool.install(|| render_reference_bounces(&geometry, &bvh, camera, &reference, REFERENCE_MAX_DEPTH));
        Ok((b, ms_since(t)))
    } else {
        Err("the scene has no ray-traced mirror or glass (`kernels::bounce::bounces`), so no frame traces a bounce")
    };
    let runs = if opts.quick { 1 } else { FULL_RUNS };
    let resolutions: &[u32] = if opts.quick { &QUICK_SHADOW_MAP_RESOLUTIONS } else { &SHADOW_MAP_RESOLUTIONS };
    let mut jobs = Vec::new();
    for preset in BvhPreset::ALL {
        let configuration = preset.name().to_string();
        jobs.push(Job { group: "bvh", configuration, stage: "shadow_rays", config: Config::Bvh(preset) });
    }
    for (source, name) in
        [(BarySource::Raster, "f32"), (BarySource::Unorm16, "unorm16"), (BarySource::Reintersected, "re-intersected")]
    {
        let (group, stage, config) = ("barycentrics", "quantize + reconstruction", Config::Barycentrics(source));
        jobs.push(Job { group, configuration: name.to_string(), stage, config });
    }
    for m in OffsetMethod::ALL {
        let (group, stage, config) = ("ray origin", "compaction + shadow_rays", Config::Offset(m));
        jobs.push(Job { group, configuration: m.name().to_string(), stage, config });
    }
    let shadow_configs = std::iter::once(None).chain(resolutions.iter().map(|&r| Some(r)));
    for res in shadow_configs {
        let configuration = res.map_or_else(|| "ray traced".to_string(), |r| format!("shadow map {r}"));
        jobs.push(Job { group: "shadows", configuration, stage: "shadows", config: Config::Shadows(res) });
    }
    if bouncing.is_ok() {
        jobs.extend(bounce_jobs());
    }
    // Runs go round-robin over the jobs, so that a change in machine load (other processes)
    // hits every configuration alike; the first run of each job is also scored.
    let mut rows: Vec<AccuracyRow> = Vec::new();
    let mut times: Vec<Vec<RunTimes>> = vec![Vec::new(); jobs.len()];
    let mut rays = vec![0usize; jobs.len()];
    for run in 0..runs {
        for (j, job) in jobs.iter().enumerate() {
            progress(&format!("{scene_name}: run {}/{runs}: {} {}", run + 1, job.group, job.configuration));
            let (built, build_ms) = match job.config {
                Config::Bvh(preset) => {
                    let t = Instant::now();
                    let b = pool.install(|| Bvh::build(&geometry, preset));
                    (Some(b), Some(ms_since(t)))
                }
                _ => (None, None),
            };
            let frame_bvh = built.as_ref().unwrap_or(&bvh);
            let r = pool.install(|| run_frame(&geometry, frame_bvh, &record, job.config));
            times[j].push(RunTimes { frame_ms: r.frame_ms, stage_ms: r.stage_ms, shadow_ms: r.shadow_ms, build_ms });
            if run == 0 {
                rays[j] = r.rays;
                let image = match (&bouncing, job.config) {
                    (Ok((b, _)), Config::Bounces { .. }) => &b.image,
                    _ => &reference.image,
                };
                rows.push(score(scene_name, job, &geometry, &reference, image, &r));
            }
        }
    }
    for ((row, t), n_rays) in rows.iter_mut().zip(&times).zip(&rays) {
        row.frame_ms = median(t.iter().map(|t| t.frame_ms).collect());
        row.stage_ms = median(t.iter().map(|t| t.stage_ms).collect());
        let builds: Vec<f64> = t.iter().filter_map(|t| t.build_ms).collect();
        row.build_ms = (!builds.is_empty()).then(|| median(builds));
        let shadow_ms = median(t.iter().map(|t| t.shadow_ms).collect());
        row.mrays_per_s = (*n_rays > 0 && shadow_ms > 0.0).then(|| *n_rays as f64 / (shadow_ms * 1e3));
    }
    let notes = Notes {
        triangles: geometry.triangle_count(),
        lights: geometry.lights.len(),
        extent: geometry.scene_extent(),
        reference_ms,
        runs,
        bounces: bouncing.map(|(b, ms): (BounceImage, f64)| BounceNotes {
            reference_ms: ms,
            paths: b.paths,
            max_depth: b.max_depth,
        }),
    };
    (rows, notes)
}

/// The jobs of the bounce groups.
fn bounce_jobs() -> Vec<Job> {
    let stage = "bounce stages";
    let mut jobs = Vec::new();
    for max_depth in 0..=MAX_DEPTHS {
        let config = Config::Bounces { max_depth, variant: BounceVariant::PIPELINE };
        jobs.push(Job { group: "max depth", configuration: max_depth.to_string(), stage, config });
    }
    for offset in OffsetMethod::ALL {
        let variant = BounceVariant { offset, ..BounceVariant::PIPELINE };
        let config = Config::Bounces { max_depth: VARIANT_MAX_DEPTH, variant };
        jobs.push(Job { group: "bounce origin", configuration: offset.name().to_string(), stage, config });
    }
    for log2 in CUTOFFS_LOG2 {
        let variant = BounceVariant { cutoff_log2: Some(log2), ..BounceVariant::PIPELINE };
        let config = Config::Bounces { max_depth: VARIANT_MAX_DEPTH, variant };
        jobs.push(Job { group: "throughput cut-off", configuration: cutoff_name(log2), stage, config });
    }
    jobs
}

/// One panel: `error` of each row against its frame time.
fn panel(rows: &[AccuracyRow], y_label: &str, error: &dyn Fn(&AccuracyRow) -> f64) -> plot::Panel {
    plot::Panel {
        y_label: y_label.to_string(),
        points: rows
            .iter()
            .map(|r| plot::PlotPoint {
                group: r.group.clone(),
                label: r.configuration.clone(),
                time_ms: r.frame_ms,
                error: error(r),
            })
            .collect(),
    }
}

fn plot_panels(rows: &[AccuracyRow]) -> Vec<plot::Panel> {
    vec![panel(rows, "shadow mismatch fraction", &|r| r.shadow.fraction()), panel(rows, "mean FLIP", &|r| r.flip)]
}

fn bounce_panels(rows: &[AccuracyRow], opts: &AccuracyOptions) -> Vec<plot::Panel> {
    let pixels = (opts.width as u64 * opts.height as u64) as f64;
    vec![
        panel(rows, "mean FLIP", &|r| r.flip),
        panel(rows, "RMSE (linear RGB)", &|r| r.rmse),
        panel(rows, "wrong pixel fraction", &|r| r.wrong_pixels as f64 / pixels),
    ]
}

/// A plot's file name, for a link from the Markdown next to it.
fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(|| path.display().to_string(), |f| f.to_string_lossy().into())
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "-".to_string(), |v| format!("{v:.digits$}"))
}

fn markdown(
    scene_name: &str,
    opts: &AccuracyOptions,
    threads: usize,
    rows: &[AccuracyRow],
    notes: &Notes,
    plot_path: &Path,
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "### Speed against error: {scene_name}\n");
    let primary = rows.first().map_or(0, |r| r.primary_mismatches);
    let _ = writeln!(
        s,
        "{}x{} pixels, {} triangles, {} lights, scene extent {:.3} (bounds diagonal); CPU backend stages, {threads} \
         threads; median of {} run(s) per configuration{}. The f64 reference (ray-cast primary visibility and \
         shadows in double precision through the default BVH) took {:.0} ms. These groups measure the paper's frame \
         (max depth 0: mirrors and glass reflect a uniform environment), scored against the reference without \
         bounces. Primary visibility of the raster differs from the reference in {primary} of {} pixels \
         (silhouettes and shared edges); the errors below are over the other pixels, except RMSE and FLIP (whole \
         image).\n",
        opts.width,
        opts.height,
        notes.triangles,
        notes.lights,
        notes.extent,
        notes.runs,
        if opts.quick { ", quick mode" } else { "" },
        notes.reference_ms,
        opts.width as u64 * opts.height as u64,
    );
    let _ = writeln!(
        s,
        "| group | configuration | frame ms | stage ms (stage) | build ms | Mrays/s | shadow mismatches (false \
         shadow / leak) | mismatch fraction | hit error max / mean (x extent) | RMSE | mean FLIP |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.2} ({}) | {} | {} | {} ({} / {}) | {:.2e} | {:.1e} / {:.1e} | {:.2e} | {:.2e} |",
            r.group,
            r.configuration,
            r.frame_ms,
            r.stage_ms,
            r.stage,
            opt(r.build_ms, 1),
            opt(r.mrays_per_s, 2),
            r.shadow.mismatches(),
            r.shadow.false_shadow,
            r.shadow.light_leak,
            r.shadow.fraction(),
            r.hit_error.max_rel,
            r.hit_error.mean_rel,
            r.rmse,
            r.flip,
        );
    }
    let _ = writeln!(s, "\n![speed against error, {scene_name}]({})\n", file_name(plot_path));
    let _ = writeln!(
        s,
        "Shadow mismatches count (pixel, light) pairs where both this configuration and the reference traced a \
         shadow ray from the same primary triangle. Offsets: `epsilon` moves the origin {} x extent along the \
         geometric normal; `256 ulps` is Wachter and Binder's integer-ulp offset (the pipeline's before the leak fix); \
         `error bound` is pbrt-v4's offset by the reconstructed point's own error bound, the pipeline's. Shadow maps: cube \
         maps of 6 x 90 degree faces per point light (one orthographic map per directional light), rendered with \
         the CPU `visibility_raster` stage, nearest texel, linear depth (distance to a point light, distance along a directional light), bias {} texel + {} \
         texel x tan(normal, light) (capped at {}); resolution is per face side; their time is rendering every face \
         on the CPU rasterizer each frame plus the lookups (a GPU rasterizes them far faster, and static lights \
         could keep them), so the time axis is the CPU backend's. FLIP: LDR-FLIP of the sRGB 8-bit images \
         (`nv-flip` crate, NVIDIA's implementation, default 67 pixels per degree). Times come from a machine \
         possibly shared with other work: compare them within a run only.\n",
        variants::CONSTANT_EPSILON_REL,
        shadow_map::SHADOW_MAP_CONSTANT_BIAS_TEXELS,
        shadow_map::SHADOW_MAP_SLOPE_BIAS_TEXELS,
        shadow_map::SHADOW_MAP_MAX_SLOPE,
    );
    s
}

/// The Markdown of the bounce groups: table, plot link, notes.
fn bounce_markdown(scene_name: &str, rows: &[AccuracyRow], notes: &BounceNotes, plot_path: &Path) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "#### Bounces: {scene_name}\n");
    let p = &notes.paths;
    let _ = writeln!(
        s,
        "Reflection and refraction against the f64 reference with bounce paths (every mirror and glass hit spawns \
         its reflection and refraction in f64, no throughput cut-off, no origin offset, down to max depth {}), which \
         took {:.0} ms more than the reference without them: {} secondary rays, the deepest at bounce {}, {} lobes \
         still alive at the depth limit (they see the uniform environment, as at a frame's deepest bounce), of path \
         weight at most {:.1e}. Each row is a whole CPU frame; `bounce ms` is its bounce stages (`secondary_rays` to \
         `bounce_shading`, every depth).\n",
        notes.max_depth, notes.reference_ms, p.rays, p.deepest, p.truncated, p.truncated_weight,
    );
    let _ = writeln!(
        s,
        "| group | configuration | frame ms | bounce ms | secondary rays | wrong pixels | RMSE | mean FLIP |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|---:|");
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.2} | {} | {} | {:.2e} | {:.2e} |",
            r.group,
            r.configuration,
            r.frame_ms,
            r.stage_ms,
            r.secondary_rays.map_or_else(|| "-".to_string(), |n| n.to_string()),
            r.wrong_pixels,
            r.rmse,
            r.flip,
        );
    }
    let _ = writeln!(s, "\n![bounces, speed against error, {scene_name}]({})\n", file_name(plot_path));
    let _ = writeln!(
        s,
        "`max depth` D is the pipeline's frame at `max_depth` D (the `CpuBackend` frame bit for bit; 0 is the paper's \
         frame, its mirrors and glass reflecting a uniform environment): the error falls as D grows until what is \
         left is the pipeline's own, the primary visibility of the raster (silhouettes), f32 reflection directions \
         (magnified by curved mirrors) and the throughput cut-off. `bounce origin` offsets the secondary-ray origins \
         of the frame at max depth {VARIANT_MAX_DEPTH} (the default) as the `ray origin` group does for shadow \
         rays (reflection rays to the seen side of the geometric normal, refraction rays to the other side); \
         `error bound` is the pipeline's. `throughput cut-off` at max depth {VARIANT_MAX_DEPTH}: a lobe whose path \
         weight (largest component) falls below the cut-off traces no ray and sees the uniform environment (paths off \
         a metal whose F0 has a component of 1, such as gold, never fall below any cut-off); the pipeline's is 1/256, and every row of the group (1/256 included, whose frame is the pipeline's bit for bit) \
         spawns its rays with the accuracy lab's spawner, so their times compare with each other. Wrong pixels: a \
         channel of the 8-bit sRGB image differs from the reference's by more than {} code(s) (one code is the \
         rounding of nearly equal values).\n",
        metrics::WRONG_PIXEL_CODES,
    );
    s
}
