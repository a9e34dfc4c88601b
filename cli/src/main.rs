//! The `hyrt` command-line program.
//!
//! `hyrt render [SCENE] --out frame.png --size 1280x720 --backend cpu --weight W
//! --eye X,Y,Z --target X,Y,Z --fov DEG --environment MAP.hdr --dump DIR`: with no SCENE
//! it renders the built-in default scene; `--out frame.exr` writes linear OpenEXR. An
//! animated glTF scene renders at `--time T` seconds of its first animation (or
//! `--animation NAME`), or `--frames N --fps F` renders N frames from there to numbered images.
//!
//! `hyrt view [SCENE]`: the same scene, backend, size and camera options in a window,
//! every stage's buffer on screen (see `view`).
//!
//! `hyrt bench [--quick] [--out DIR]`: the benchmark report (Table 2 reproduction, peers,
//! scaling) as `DIR/report.md` plus PNG plots; see `hyrt_benches::bench`.

mod dump;
mod view;

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand, ValueEnum};
use hyrt::{glam::Vec3, AdapterPolicy, BackendKind, BvhPreset, FrameOptions, Renderer, Scene, Stage};

#[derive(Parser)]
#[command(name = "hyrt", version, about = "Hybrid rasterization + ray-tracing renderer")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene (.glb, .gltf or .toml manifest; the built-in default scene if none) to a
    /// PNG or an OpenEXR file.
    Render(RenderArgs),
    /// Open a window on the scene (the built-in default scene if none): fly through it,
    /// show any stage's buffer, the stage times and counts live, toggle objects between
    /// ray traced and rasterized by clicking them.
    ///
    /// Keys: 1 final, 2 raster, 3 ray-traced image, 4 barycentrics, 5 depth, 6 normals,
    /// 7 triangle ids, 8 object ids, 9 ray traced/rasterized, 0 shadow mask (L: next
    /// light), minus rays per pixel, = bounce depth; drag turns, the wheel zooms, Tab
    /// orbit/fly, WASD (Q/E down/up, Shift faster) moves, R resets the camera, C the
    /// scene's camera; click toggles the object under the cursor; [ and ] (or a drag on
    /// the bar) the weight; Space plays the animation (comma and period step it); H hides
    /// the overlay; P writes the view to a PNG, O with the overlay; Esc quits.
    View(view::ViewArgs),
    /// Run the conformance corpus: every stage of a candidate backend against the CPU
    /// reference, with a report (report.md, difference images).
    Conformance(ConformanceArgs),
    /// Measure: the paper's Table 2 on both backends, peers (Embree, lavapipe) on the same
    /// rays, scaling with pixels and triangles; writes DIR/report.md and PNG plots.
    Bench(BenchArgs),
}

#[derive(Clone, Copy, ValueEnum)]
enum CandidateArg {
    /// The GPU backend (Vulkan; lavapipe with --allow-software-gpu).
    Gpu,
    /// The CPU backend on one thread (determinism against the two-thread reference).
    Cpu1,
}

#[derive(clap::Args)]
struct ConformanceArgs {
    /// Directory for report.md and the difference images.
    #[arg(long, default_value = "conformance-report")]
    out: PathBuf,
    /// What to compare with the CPU reference (two threads).
    #[arg(long, value_enum, default_value = "gpu")]
    against: CandidateArg,
    /// Accept a software GPU adapter (Mesa lavapipe), as for `render`.
    #[arg(long)]
    allow_software_gpu: bool,
    /// Only the cases whose name contains this text.
    #[arg(long)]
    filter: Option<String>,
}

#[derive(Clone, Copy, ValueEnum)]
enum SceneSetArg {
    /// The built-in default scene only (no model files needed).
    Default,
    /// The default scene plus the manifests in assets/scenes (when ../shared/assets exists).
    All,
}

#[derive(clap::Args)]
struct BenchArgs {
    /// Fewer frames, repetitions and sizes: a few minutes on a 2-core machine.
    #[arg(long)]
    quick: bool,
    /// Output folder for report.md and the plots.
    #[arg(long, default_value = "bench-report")]
    out: PathBuf,
    /// Frames per measurement (medians; default 5 with --quick, 21 without).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1000))]
    frames: Option<u32>,
    /// Repetitions per peer ray-tracing measurement (default 3 with --quick, 7 without).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeats: Option<u32>,
    /// Image size of the Table 2 reproduction and the peers, WIDTHxHEIGHT.
    #[arg(long, value_parser = parse_size)]
    table_size: Option<(u32, u32)>,
    /// Image sizes of the pixel-count scaling, comma-separated WIDTHxHEIGHT list.
    #[arg(long, value_delimiter = ',', value_parser = parse_size)]
    sizes: Option<Vec<(u32, u32)>>,
    /// Thread counts of the peer comparison, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,2", value_parser = clap::value_parser!(u32).range(1..=1024))]
    peer_threads: Vec<u32>,
    /// Worker threads of the CPU backend for whole frames (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Which scenes.
    #[arg(long, value_enum, default_value = "all")]
    scenes: SceneSetArg,
    /// Do not measure the GPU backend.
    #[arg(long)]
    no_gpu: bool,
    /// Skip the speed-against-error section (f64 reference, configurations, shadow maps).
    #[arg(long)]
    no_accuracy: bool,
    /// Accept a software GPU adapter (Mesa lavapipe) (also: environment HYRT_GPU_ALLOW_SOFTWARE=1).
    #[arg(long)]
    allow_software_gpu: bool,
    /// Run hyrt's SIMD traversals at this level instead of this CPU's best (also:
    /// environment HYRT_SIMD), so one machine measures each path; the report says which
    /// ran. A level the CPU lacks is an error.
    #[arg(long, value_enum)]
    simd: Option<SimdArg>,
}

#[derive(Clone, Copy, ValueEnum)]
enum SimdArg {
    Avx512,
    Avx2,
    Sse2,
    Portable,
}

#[derive(Clone, Copy, ValueEnum)]
enum BackendArg {
    /// The CPU reference backend.
    Cpu,
    /// The GPU backend (Vulkan); fails when no adapter is found.
    Gpu,
    /// A hardware GPU if there is one, else the CPU backend (says which it took).
    Auto,
}

#[derive(Clone, Copy, ValueEnum)]
enum PresetArg {
    Fastest,
    VeryFast,
    Fast,
    Medium,
    Slow,
    VerySlow,
}

/// What `render` and `view` share: the scene, the backend, the image size, the camera and
/// the frame's options.
#[derive(clap::Args)]
struct SceneArgs {
    /// Scene file: .glb, .gltf or .toml manifest. Omit for the built-in default scene.
    scene: Option<PathBuf>,
    /// Environment map that reflection and refraction rays leaving the scene see: an
    /// equirectangular Radiance .hdr or OpenEXR .exr file (overrides the manifest's
    /// `environment`; without either, the default sky).
    #[arg(long)]
    environment: Option<PathBuf>,
    /// How direct light is shaded on every object: `paper` (the 2011 model: Lambert on
    /// rasterized objects, Blinn-Phong on ray-traced ones) or `gltf` (the glTF
    /// metallic-roughness BRDF on both). Overrides the manifest's `shading`; default gltf
    /// (the paper's figures and the report use paper).
    #[arg(long, value_parser = named(hyrt::ShadingModel::ALL, hyrt::ShadingModel::name))]
    shading: Option<hyrt::ShadingModel>,
    /// The constant ambient light, >= 0: 0.06 by default (the paper's look); 0 removes the
    /// constant ambient and environment terms (with the glTF BRDF the environment's
    /// image-based light stays: a black environment removes it too), leaving direct light
    /// and emission. Overrides the manifest's `ambient`.
    #[arg(long, value_parser = parse_ambient)]
    ambient: Option<hyrt::Ambient>,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720", value_parser = parse_size)]
    size: (u32, u32),
    /// Backend.
    #[arg(long, value_enum, default_value = "cpu")]
    backend: BackendArg,
    /// Accept a software GPU adapter (Mesa lavapipe) for --backend gpu/auto
    /// (also: environment HYRT_GPU_ALLOW_SOFTWARE=1).
    #[arg(long)]
    allow_software_gpu: bool,
    /// Composition weight of the ray-traced image in [0, 1] (paper 3.5).
    #[arg(long, default_value_t = 1.0, value_parser = parse_weight)]
    weight: f32,
    /// Camera position X,Y,Z (overrides the scene's camera).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    eye: Option<Vec3>,
    /// Camera target X,Y,Z (overrides the scene's camera).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    target: Option<Vec3>,
    /// Vertical field of view in degrees (overrides the scene's camera).
    #[arg(long, value_parser = parse_fov)]
    fov: Option<f32>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Pose an animated glTF scene at this time in seconds (of its first animation, or
    /// --animation's). Times before the first key take the first pose and times past the
    /// animation's end its last (glTF clamps; there is no looping). A scene without
    /// animations is an error.
    #[arg(long, value_parser = parse_time, allow_hyphen_values = true)]
    time: Option<f32>,
    /// The animation --time and --fps play, by name (default: the file's first).
    #[arg(long)]
    animation: Option<String>,
    /// BVH build preset (obvhs).
    #[arg(long, value_enum)]
    bvh_preset: Option<PresetArg>,
    /// Deepest bounce of the reflection and refraction rays of ray-traced mirrors and
    /// glass; 0 traces none (the paper's frame). Default 4, on either backend.
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..=hyrt::MAX_DEPTH_LIMIT as i64))]
    max_depth: Option<u32>,
    /// Shadow rays per pixel for each area light (quad, sphere, sun: soft shadows);
    /// point, spot and directional lights keep one. Default 4.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=hyrt::MAX_SAMPLES as i64))]
    shadow_samples: Option<u32>,
    /// Ambient-occlusion rays per pixel (0, the default: none): their unoccluded fraction
    /// scales the ambient and environment light.
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=hyrt::MAX_SAMPLES as i64))]
    ao_samples: u32,
    /// How far ambient-occlusion rays look, in scene units (default: a twentieth of the
    /// scene's extent).
    #[arg(long)]
    ao_radius: Option<f32>,
    /// Shade area lights and ambient occlusion from their raw samples, without the
    /// `shadow_denoise` filter.
    #[arg(long)]
    no_denoise: bool,
    /// With --frames: each frame takes its own samples of area lights and ambient
    /// occlusion, and the denoiser accumulates them over the frames (the temporal pass
    /// reprojects through camera and object motion; the GPU backend renders such frames
    /// in one band of storage bindings only, and refuses larger ones).
    #[arg(long)]
    temporal: bool,
    /// Where primary hit points come from: each pixel's camera ray re-intersected with the
    /// rasterized triangle (default: as exact as a ray tracer's hit points; visibility stays
    /// the raster's), or the raster's barycentrics (a few percent faster; hit points carry
    /// the raster's 1/256-pixel vertex snapping).
    #[arg(long, value_enum, default_value = "reintersected")]
    barycentrics: BarycentricsArg,
    /// How the CPU backend runs a frame: fused (default: tile by tile in cache, where the
    /// frame returns only its image, as without --dump; mirrors' and glass's bounces run over
    /// the pixels that bounce, after the tiles) or staged (stage after stage over
    /// whole-image buffers, each stage timed). The same image.
    #[arg(long, value_enum, default_value = "fused")]
    executor: ExecutorArg,
}

#[derive(Clone, Copy, ValueEnum)]
enum ExecutorArg {
    Fused,
    Staged,
}

/// How a linear frame is displayed (PNG output, the viewer's window).
#[derive(clap::Args, Clone, Copy)]
pub(crate) struct DisplayArgs {
    /// Exposure of PNG output and of the viewer's window, in stops (the colour times
    /// 2^STOPS before tone mapping).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true, value_parser = parse_stops)]
    pub exposure: f32,
    /// Tone-mapping operator of PNG output and of the viewer's window: none (clamp, the
    /// paper's images), the Khronos PBR Neutral operator, or Hill's ACES fit. Default: the
    /// one the scene's shading model is meant for (khronos-pbr-neutral for the glTF BRDF,
    /// none for the paper's model).
    #[arg(long, value_parser = named(hyrt::ToneMap::ALL, hyrt::ToneMap::name))]
    pub tone_map: Option<hyrt::ToneMap>,
}

impl DisplayArgs {
    /// The display settings for a scene shaded with `shading`: `--tone-map`, else
    /// [`hyrt::ToneMap::for_shading`].
    pub fn resolve(self, shading: hyrt::ShadingModel) -> Display {
        Display { exposure: self.exposure, tone_map: self.tone_map.unwrap_or(hyrt::ToneMap::for_shading(shading)) }
    }
}

/// How a linear frame is displayed: [`DisplayArgs`] with the operator decided.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Display {
    /// In stops.
    pub exposure: f32,
    pub tone_map: hyrt::ToneMap,
}

#[derive(clap::Args)]
struct RenderArgs {
    #[command(flatten)]
    common: SceneArgs,
    /// Output image: a name ending in .exr writes the linear image as 32-bit float OpenEXR
    /// (unclamped, before exposure and tone mapping), anything else an 8-bit sRGB PNG.
    #[arg(long, default_value = "frame.png")]
    out: PathBuf,
    #[command(flatten)]
    display: DisplayArgs,
    /// Write every stage's output (npy, png, frame.json) into this directory.
    #[arg(long)]
    dump: Option<PathBuf>,
    /// Render this many frames (reusing every buffer) and report the median time of
    /// each stage over them; the image is the last frame's (with --temporal: the frames'
    /// samples accumulated). With --fps: that many frames of the animation, each to its own
    /// numbered image.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    frames: u32,
    /// Render --frames N frames of the animation at --time (default 0) + i / FPS seconds, each
    /// prepared from the scene posed at its time, to numbered images: --out frame.png writes
    /// frame_0000.png, frame_0001.png, ...; --dump holds the last frame's stages.
    #[arg(long, value_parser = parse_fps)]
    fps: Option<f32>,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum BarycentricsArg {
    Raster,
    Reintersected,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("expected WIDTHxHEIGHT, got '{s}'"))?;
    let w: u32 = w.trim().parse().map_err(|_| format!("bad width in '{s}'"))?;
    let h: u32 = h.trim().parse().map_err(|_| format!("bad height in '{s}'"))?;
    const MAX: u32 = 16384;
    if w == 0 || h == 0 || w > MAX || h > MAX {
        return Err(format!("size must be between 1x1 and {MAX}x{MAX}, got {w}x{h}"));
    }
    Ok((w, h))
}

fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|c| c.trim().parse::<f32>().map_err(|_| format!("bad number '{c}' in '{s}'")))
        .collect::<Result<_, _>>()?;
    match v[..] {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Ok(Vec3::new(x, y, z)),
        [_, _, _] => Err(format!("coordinates must be finite, got '{s}'")),
        _ => Err(format!("expected X,Y,Z, got '{s}'")),
    }
}

/// A number that `ok` accepts; otherwise `"{rule}, got {s}"`.
fn parse_f32(s: &str, ok: impl Fn(f32) -> bool, rule: &str) -> Result<f32, String> {
    let x: f32 = s.parse().map_err(|_| format!("bad number '{s}'"))?;
    if ok(x) {
        Ok(x)
    } else {
        Err(format!("{rule}, got {s}"))
    }
}

fn parse_weight(s: &str) -> Result<f32, String> {
    parse_f32(s, |w| (0.0..=1.0).contains(&w), "weight must be in [0, 1]")
}

fn parse_fov(s: &str) -> Result<f32, String> {
    parse_f32(s, |f| f > 0.0 && f < 180.0, "field of view must be in (0, 180) degrees")
}

fn parse_time(s: &str) -> Result<f32, String> {
    parse_f32(s, f32::is_finite, "time must be a finite number of seconds")
}

fn parse_fps(s: &str) -> Result<f32, String> {
    parse_f32(s, |f| f > 0.0 && f.is_finite(), "frames per second must be a positive finite number")
}

/// A scene loaded, posed and lit as [`SceneArgs`] say.
/// What the chosen animation moves: its objects are prepared as moving, and posing the
/// scene at another time moves them (and retakes the lights when it moves one) rather than
/// preparing the whole scene again. Nothing for a scene without an animation.
pub(crate) struct Motion {
    objects: Vec<u32>,
    lights: bool,
}

impl Motion {
    pub(crate) fn of(scene: &Scene, animation: Option<usize>) -> Motion {
        match (animation, &scene.animation) {
            (Some(a), Some(nodes)) => Motion { objects: nodes.moved_objects(a), lights: nodes.moves_lights(a) },
            _ => Motion { objects: Vec::new(), lights: false },
        }
    }

    /// The scene prepared with the animation's objects moving.
    pub(crate) fn prepare(&self, renderer: &Renderer, scene: &Scene) -> hyrt::PreparedScene {
        if self.objects.is_empty() {
            renderer.prepare(scene)
        } else {
            renderer.prepare_moving(scene, &self.objects)
        }
    }

    /// After the scene was posed at another time: move what the animation moves.
    pub(crate) fn apply(&self, prepared: &mut hyrt::PreparedScene, scene: &Scene) -> Result<(), String> {
        prepared.move_objects(scene, &self.objects).map_err(|e| e.to_string())?;
        if self.lights {
            prepared.update_lights(scene);
        }
        Ok(())
    }
}

struct Loaded {
    scene: Scene,
    /// The animation `--time`, `--animation` (or `--fps`) chose.
    animation: Option<usize>,
    /// `--time`, or 0.
    start_time: f32,
    /// The scene's camera with the command line's overrides.
    camera: hyrt::Camera,
    /// Milliseconds the loading took.
    load_ms: f64,
}

impl SceneArgs {
    /// The scene's file name, or "the default scene".
    fn name(&self) -> String {
        self.scene.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| "the default scene".into())
    }

    /// The animation `--time` or `--animation` asks for, or the first when `play` (`None`
    /// when none of them is given): `--animation`'s, else the first. A scene without
    /// animations, or without one of that name, is an error.
    fn chosen_animation(&self, scene: &Scene, play: bool) -> Result<Option<usize>, String> {
        if self.time.is_none() && self.animation.is_none() && !play {
            return Ok(None);
        }
        let name = self.name();
        let Some(animation) = &scene.animation else {
            return Err(format!("{name} has no animations: --time, --animation and --fps pose an animated glTF scene"));
        };
        match &self.animation {
            None => Ok(Some(0)),
            Some(wanted) => animation.find(wanted).map(Some).ok_or_else(|| {
                let names: Vec<String> = animation.animations().iter().map(|a| format!("'{}'", a.name())).collect();
                format!("{name} has no animation '{wanted}' (it has {})", names.join(", "))
            }),
        }
    }

    /// Load the scene (the default scene without a file), pose it at `--time` of the
    /// chosen animation (`play`: an animation is wanted even without `--time`), add the
    /// default camera and lights where it has none, and take `--environment`.
    fn load(&self, play: bool) -> Result<Loaded, String> {
        let started = Instant::now();
        let mut scene = match &self.scene {
            Some(path) => Scene::load(path).map_err(|e| e.to_string())?,
            None => Scene::default_scene(),
        };
        let animation = self.chosen_animation(&scene, play)?;
        let start_time = self.time.unwrap_or(0.0);
        if let Some(a) = animation {
            scene.set_time(a, start_time).map_err(|e| e.to_string())?;
        }
        scene.ensure_camera_and_lights();
        if let Some(path) = &self.environment {
            scene.environment = hyrt::Environment::load(path).map_err(|e| e.to_string())?;
        }
        if let Some(shading) = self.shading {
            scene.shading = shading;
        }
        if let Some(ambient) = self.ambient {
            scene.ambient = ambient;
        }
        for note in &scene.notes {
            eprintln!("note: {note}");
        }
        let camera = self.camera(&scene)?;
        Ok(Loaded { scene, animation, start_time, camera, load_ms: ms_since(started) })
    }

    /// The scene's camera with the command line's overrides.
    fn camera(&self, scene: &Scene) -> Result<hyrt::Camera, String> {
        let mut camera = scene.camera.expect("ensure_camera_and_lights sets a camera");
        if let Some(eye) = self.eye {
            camera.eye = eye;
        }
        if let Some(target) = self.target {
            camera.target = target;
        }
        if let Some(fov) = self.fov {
            camera.fov_y_deg = fov;
        }
        if (camera.target - camera.eye).length_squared() == 0.0 {
            return Err("camera eye and target are the same point".into());
        }
        if (camera.target - camera.eye).cross(camera.up).length_squared() == 0.0 {
            camera.up = if camera.up.dot(Vec3::Z).abs() < 0.9 { Vec3::Z } else { Vec3::X };
        }
        Ok(camera)
    }

    /// The BVH preset `--bvh-preset` names.
    fn bvh_preset(&self) -> BvhPreset {
        match self.bvh_preset {
            None => BvhPreset::default(),
            Some(PresetArg::Fastest) => BvhPreset::Fastest,
            Some(PresetArg::VeryFast) => BvhPreset::VeryFast,
            Some(PresetArg::Fast) => BvhPreset::Fast,
            Some(PresetArg::Medium) => BvhPreset::Medium,
            Some(PresetArg::Slow) => BvhPreset::Slow,
            Some(PresetArg::VerySlow) => BvhPreset::VerySlow,
        }
    }

    /// The backend `--backend` names.
    fn backend_kind(&self) -> BackendKind {
        match self.backend {
            BackendArg::Cpu => BackendKind::Cpu,
            BackendArg::Gpu => BackendKind::Gpu,
            BackendArg::Auto => BackendKind::Auto,
        }
    }

    /// Whether a software GPU adapter is accepted (`--allow-software-gpu` or the environment).
    fn adapter_policy(&self) -> AdapterPolicy {
        if self.allow_software_gpu {
            AdapterPolicy::AllowSoftware
        } else {
            AdapterPolicy::from_env()
        }
    }

    /// Give the CPU backend `--executor`'s executor (the GPU has one).
    fn set_executor(&self, renderer: &mut Renderer) {
        if let Some(cpu) = renderer.cpu_backend() {
            cpu.set_executor(match self.executor {
                ExecutorArg::Fused => hyrt::Executor::Fused,
                ExecutorArg::Staged => hyrt::Executor::Staged,
            });
        }
    }

    /// The frame options `--weight`, `--max-depth`, `--barycentrics`, `--shadow-samples` and
    /// `--ao-*` say, returning every
    /// stage's output with `stage_outputs` and the G-buffer with `keep_gbuffer`.
    fn frame_options(&self, stage_outputs: bool, keep_gbuffer: bool) -> FrameOptions {
        let barycentrics = match self.barycentrics {
            BarycentricsArg::Raster => hyrt::PrimaryBarycentrics::Raster,
            BarycentricsArg::Reintersected => hyrt::PrimaryBarycentrics::Reintersected,
        };
        FrameOptions {
            weight: self.weight,
            stage_outputs,
            keep_gbuffer,
            max_depth: self.max_depth.unwrap_or(hyrt::DEFAULT_MAX_DEPTH),
            barycentrics,
            shadow_samples: self.shadow_samples.unwrap_or(hyrt::DEFAULT_SHADOW_SAMPLES),
            ao_samples: self.ao_samples,
            ao_radius: self.ao_radius,
            frame_index: 0,
            denoise: !self.no_denoise,
            temporal: false,
        }
    }
}

/// The timed lines of a frame, `(label, ms)` in the order they ran: each step's (a bounce
/// step carries its depth: `compaction{2}`), and for a fused frame its tiles' line, which
/// holds the raster tiles' depth tests and resolves and every later step but the bounce
/// steps, which have their lines (`visibility_raster`'s line is its setup and binning then).
fn timed_lines(s: &hyrt::FrameStats) -> Vec<(String, f64)> {
    let mut lines: Vec<(String, f64)> = s.stage_ms.iter().map(|t| (t.label(), t.ms)).collect();
    if s.executor == hyrt::Executor::Fused {
        lines.push((FUSED_TILES_LABEL.to_string(), s.fused_ms));
    }
    lines
}

/// The fused frame's line in `hyrt render`'s times: the raster's tiles and every step after
/// `visibility_raster` but the bounce steps ([`hyrt::FrameStats::fused_ms`]).
const FUSED_TILES_LABEL: &str = "fused tiles";

/// `frame.png` -> `frame_0007.png`: frame `i` of an animation rendered to `out`.
fn numbered(out: &std::path::Path, i: u32) -> PathBuf {
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = match out.extension() {
        Some(ext) => format!("{stem}_{i:04}.{}", ext.to_string_lossy()),
        None => format!("{stem}_{i:04}"),
    };
    out.with_file_name(name)
}

/// A parser of the values `all` by their names (clap lists the names in the help and in
/// its errors).
fn named<T: Copy + Send + Sync + 'static, const N: usize>(
    all: [T; N],
    name: fn(T) -> &'static str,
) -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(all.map(name))
        .map(move |s| all.into_iter().find(|&t| name(t) == s).expect("one of the listed names"))
}

/// An ambient level: a finite number >= 0 ([`hyrt::Ambient::new`]).
fn parse_ambient(s: &str) -> Result<hyrt::Ambient, String> {
    s.trim().parse::<f32>().map_err(|e| format!("'{s}': {e}")).and_then(hyrt::Ambient::new)
}

/// An exposure in stops: finite, within +-64.
fn parse_stops(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(x) if x.is_finite() && x.abs() <= 64.0 => Ok(x),
        _ => Err(format!("expected an exposure in stops between -64 and 64, got '{s}'")),
    }
}

/// Write the final image as OpenEXR (a name ending in .exr: linear) or PNG (through the
/// exposure and tone-mapping operator of `display`).
fn write_image(path: &std::path::Path, w: u32, h: u32, frame: &hyrt::Frame, display: Display) -> Result<(), String> {
    let exr = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if exr {
        hyrt::image_io::write_exr(path, w, h, &frame.final_image)
    } else {
        hyrt::image_io::write_png_tone_mapped(path, w, h, &frame.final_image, display.exposure, display.tone_map)
    }
    .map_err(|e| e.to_string())
}

/// Milliseconds since `t`.
fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn render(args: RenderArgs) -> Result<(), String> {
    let common = &args.common;
    let Loaded { mut scene, animation, start_time, mut camera, load_ms } = common.load(args.fps.is_some())?;
    let t = Instant::now();
    let mut renderer = Renderer::new(common.backend_kind(), common.threads, common.adapter_policy())
        .map_err(|e| e.to_string())?
        .with_bvh_preset(common.bvh_preset());
    common.set_executor(&mut renderer);
    let start_ms = ms_since(t);
    eprintln!("backend: {}", renderer.choice_details());
    let (w, h) = common.size;
    let t = Instant::now();
    let motion = Motion::of(&scene, animation);
    let mut prepared = motion.prepare(&renderer, &scene);
    let prepare_ms = ms_since(t);
    // Every stage's output is kept only for --dump (the GPU then reads them back too).
    // An image to write needs no G-buffer (`--dump` returns every stage's output).
    let options = common.frame_options(args.dump.is_some(), false);
    let temporal = common.temporal;
    let mut per_frame = Vec::with_capacity(args.frames as usize);
    // What the frames add to the prepared scene: the resident memory now, and the peak from
    // now on (Linux; the scene's load and preparation do not count).
    let load_peak = hyrt::memory::peak_resident_bytes();
    let before_frames = hyrt::memory::reset_peak_resident_bytes().then(hyrt::memory::resident_bytes).flatten();
    let mut frame = hyrt::Frame::default();
    // Wall clock of each frame (the call, readback included) and the sum of its stages.
    let mut walls = Vec::with_capacity(args.frames as usize);
    // With --fps each frame poses the scene at its time and moves what the animation moves
    // (frame 0 is the pose set above); without, the same prepared scene renders every frame.
    let playing = animation.zip(args.fps);
    for i in 0..args.frames {
        if let (Some((a, fps)), true) = (playing, i > 0) {
            scene.set_time(a, start_time + i as f32 / fps).map_err(|e| e.to_string())?;
            camera = common.camera(&scene)?;
            motion.apply(&mut prepared, &scene)?;
        }
        let t = Instant::now();
        // With --temporal, frames take their own samples and blend them over time.
        let options = match temporal {
            true => FrameOptions { frame_index: i, temporal: true, ..options },
            false => options,
        };
        renderer.render_into(&prepared, &camera, w, h, &options, &mut frame).map_err(|e| e.to_string())?;
        walls.push((ms_since(t), frame.stats.frame_ms()));
        per_frame.push(timed_lines(&frame.stats));
        if let Some((_, fps)) = playing {
            let out = numbered(&args.out, i);
            write_image(&out, w, h, &frame, args.display.resolve(scene.shading))?;
            println!("wrote {} (t = {:.4} s)", out.display(), start_time + i as f32 / fps);
        }
    }
    // Median per step (stage and depth) over the frames (the lower middle for an even count).
    let median = |label: &str| -> f64 {
        let mut v: Vec<f64> = per_frame.iter().filter_map(|f| f.iter().find(|t| t.0 == label).map(|t| t.1)).collect();
        v.sort_by(f64::total_cmp);
        v[(v.len() - 1) / 2]
    };
    let frame_bytes = before_frames.zip(hyrt::memory::peak_resident_bytes()).map(|(b, p)| p.saturating_sub(b));
    if playing.is_none() {
        write_image(&args.out, w, h, &frame, args.display.resolve(scene.shading))?;
    }

    let s = &frame.stats;
    let name = common.scene.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| "default scene".into());
    println!(
        "{name}: {} objects, {} triangles, {} lights, environment: {}; {}x{} on {}",
        scene.objects.len(),
        prepared.geometry.triangle_count(),
        prepared.geometry.lights.len(),
        scene.environment.describe(),
        w,
        h,
        renderer.choice(),
    );
    println!(
        "covered pixels {}, valid rays (ray-traced pixels) {}, raster pixels {}, shadow rays {} ({} occluded)",
        s.covered_pixels, s.ray_traced_pixels, s.raster_pixels, s.rays_per_kind[0], s.occluded_shadow_rays
    );
    if args.frames > 1 {
        println!("median of {} frames:", args.frames);
    }
    for (i, b) in s.bounces.iter().enumerate() {
        let k = |kind: u32| b.rays_per_kind[kind as usize];
        println!(
            "bounce {}: reflection rays {}, refraction rays {}, hits {}, shadow rays {} ({} occluded)",
            i + 1,
            k(hyrt::formats::RAY_KIND_REFLECTION),
            k(hyrt::formats::RAY_KIND_REFRACTION),
            b.hits,
            k(hyrt::formats::RAY_KIND_SHADOW),
            b.occluded_shadow_rays
        );
    }
    let mut frame_ms = 0.0;
    println!("  {:<18} {:>9.2} ms (once per scene)", Stage::BvhBuild.name(), prepared.bvh_build_ms);
    // The steps in the order they ran (a bounce step carries its depth: `compaction{2}`),
    // then the stages the plan skipped.
    for (label, _) in timed_lines(s) {
        let ms = median(&label);
        println!("  {label:<18} {ms:>9.2} ms");
        frame_ms += ms;
    }
    for k in &s.skipped {
        println!("  {:<18} {:>12} ({})", k.stage.name(), "skipped", k.reason);
    }
    println!("  {:<18} {:>9.2} ms (sum of the stages above, without bvh_build)", "frame", frame_ms);
    // Cold against warm: what one frame costs from the command line, and what each
    // further frame costs once buffers, pipelines and pages are in place.
    println!(
        "cold: scene load {load_ms:.1} ms, backend start {start_ms:.1} ms (device and shaders on the GPU), \
         prepare {prepare_ms:.1} ms (world tables and bvh_build); first frame {:.1} ms wall clock \
         ({:.1} ms in its stages)",
        walls[0].0, walls[0].1
    );
    if walls.len() > 1 {
        let mut warm: Vec<(f64, f64)> = walls[1..].to_vec();
        warm.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (wall, stages) = warm[(warm.len() - 1) / 2];
        println!(
            "warm: median of {} frames after the first: {wall:.1} ms wall clock ({stages:.1} ms in its stages)",
            warm.len()
        );
    } else {
        println!("warm: not measured (one frame; --frames 3 measures the frames after the first)");
    }
    // The CPU backend's level per kind of walk where it measures AVX-512 against AVX2.
    for line in hyrt::simd_tuning::summary() {
        println!("simd level, {line}");
    }
    if let Some(bytes) = frame_bytes {
        let pixels = (w as u64 * h as u64).max(1);
        println!(
            "frame memory: {:.1} bytes per pixel beyond the scene ({:.1} MiB: peak resident memory while rendering \
             minus resident memory before; {} executor)",
            bytes as f64 / pixels as f64,
            bytes as f64 / (1u64 << 20) as f64,
            frame.stats.executor.name()
        );
    }
    if let Some(peak) = hyrt::memory::peak_resident_bytes().map(|p| p.max(load_peak.unwrap_or(0))) {
        println!("peak resident memory: {:.0} MiB (the whole process)", peak as f64 / (1u64 << 20) as f64);
    }
    if playing.is_none() {
        println!("wrote {}", args.out.display());
    }
    if let Some(dir) = &args.dump {
        let files = dump::write_dump(dir, &scene, &prepared, (&camera, &options), &frame, renderer.backend_name())
            .map_err(|e| e.to_string())?;
        println!("dumped {} files to {}", files.len(), dir.display());
    }
    Ok(())
}

fn conformance(args: ConformanceArgs) -> Result<(), String> {
    use hyrt_conformance::report::{known_deviations_path, run_case, KnownDeviations, Report};
    let mut cases = hyrt_conformance::corpus::corpus();
    if let Some(f) = &args.filter {
        cases.retain(|c| c.name.contains(f.as_str()));
        if cases.is_empty() {
            return Err(format!("no corpus case matches '{f}'"));
        }
    }
    let mut reference = hyrt::CpuBackend::new(Some(2));
    let (mut candidate, name, missing_guarantees): (Box<dyn hyrt::Backend>, String, Vec<String>) = match args.against {
        CandidateArg::Gpu => {
            let policy = if args.allow_software_gpu { AdapterPolicy::AllowSoftware } else { AdapterPolicy::from_env() };
            let gpu = hyrt::GpuBackend::new(policy).map_err(|e| e.to_string())?;
            let name = format!("gpu: {}", gpu.describe());
            let missing = hyrt_conformance::report::missing_guarantees(gpu.context());
            (Box::new(gpu), name, missing)
        }
        CandidateArg::Cpu1 => (Box::new(hyrt::CpuBackend::new(Some(1))), "cpu, 1 thread".into(), Vec::new()),
    };
    eprintln!("reference: cpu, 2 threads; candidate: {name}; {} cases", cases.len());
    let mut results = Vec::with_capacity(cases.len());
    for (i, case) in cases.iter().enumerate() {
        eprintln!("[{}/{}] {} ({}x{})", i + 1, cases.len(), case.name, case.width, case.height);
        results.push(run_case(&mut reference, candidate.as_mut(), case));
    }
    let report = Report { reference: "cpu, 2 threads".into(), candidate: name, missing_guarantees, results };
    // The recorded deviations describe the GPU backend on lavapipe; any other candidate
    // (another driver, the CPU on one thread) is held to exact agreement.
    let known = match args.against {
        CandidateArg::Gpu => KnownDeviations::load(&known_deviations_path()).unwrap_or_else(|e| {
            eprintln!("note: no recorded deviations ({e}); holding the candidate to exact agreement");
            KnownDeviations::default()
        }),
        CandidateArg::Cpu1 => KnownDeviations::default(),
    };
    let files = report.write(&args.out, &known).map_err(|e| format!("{}: {e}", args.out.display()))?;
    println!("{}", report.summary_markdown());
    println!("wrote {} files to {} (report.md)", files.len(), args.out.display());
    let (violations, _) = report.check(&known);
    if violations.is_empty() {
        Ok(())
    } else {
        for v in &violations {
            eprintln!("  {v}");
        }
        let missing = report.attribution().map_or(String::new(), |m| format!(" ({m})"));
        Err(format!("{} differences beyond the recorded deviations{missing}", violations.len()))
    }
}

fn bench(args: BenchArgs) -> Result<(), String> {
    use hyrt::SimdLevel;
    use hyrt_benches::bench::{BenchOptions, SceneSet};
    if let Some(s) = args.simd {
        let level = match s {
            SimdArg::Avx512 => SimdLevel::Avx512,
            SimdArg::Avx2 => SimdLevel::Avx2,
            SimdArg::Sse2 => SimdLevel::Sse2,
            SimdArg::Portable => SimdLevel::Portable,
        };
        hyrt::force_simd_level(Some(level))?;
    }
    let mut o = if args.quick { BenchOptions::quick(args.out.clone()) } else { BenchOptions::full(args.out.clone()) };
    if let Some(f) = args.frames {
        o.frames = f as usize;
    }
    if let Some(r) = args.repeats {
        o.repeats = r as usize;
    }
    if let Some(s) = args.table_size {
        o.table_size = s;
    }
    if let Some(s) = args.sizes {
        o.pixel_sizes = s;
    }
    o.peer_threads = args.peer_threads.iter().map(|&t| t as usize).collect();
    o.frame_threads = args.threads;
    o.scenes = match args.scenes {
        SceneSetArg::Default => SceneSet::DefaultOnly,
        SceneSetArg::All => SceneSet::All,
    };
    o.gpu = !args.no_gpu;
    o.accuracy = !args.no_accuracy;
    if args.allow_software_gpu {
        o.policy = AdapterPolicy::AllowSoftware;
    }
    o.command_line = std::env::args().collect::<Vec<_>>().join(" ");
    let progress = indicatif::ProgressBar::new(0);
    progress.set_style(
        indicatif::ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} {wide_msg}")
            .map_err(|e| e.to_string())?,
    );
    progress.enable_steady_tick(std::time::Duration::from_millis(200));
    let (report, path) = hyrt_benches::bench::run_and_write(&o, &progress).map_err(|e| e.to_string())?;
    progress.finish_and_clear();
    println!("wrote {} ({} sections, {} plots)", path.display(), report.sections.len(), report.files.len());
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::View(args) => view::view(args),
        Command::Conformance(args) => conformance(args),
        Command::Bench(args) => bench(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
