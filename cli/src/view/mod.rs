//! `hyrt view [SCENE]`: a window (winit) on the chosen backend that shows any stage of
//! the hybrid frame live, with an overlay of frame rate, stage times and counts.
//!
//! Keys: 1-9, 0, -, = pick the view ([`stages::View`]); Tab orbit/fly; drag turns, the
//! wheel zooms, WASD (Q/E down/up, Shift faster) moves; R resets the camera, C takes the
//! scene's camera; a click toggles the object under the cursor between ray traced and
//! rasterized; [ and ] (or a drag on the overlay's upper slider) set the composition weight;
//! Space plays and pauses the animation (looping), comma and period step it by 1/30 s; L picks the shadow mask's light; H hides the
//! overlay; P writes the current view as PNG, O the window as shown (with the overlay);
//! Page Up and Page Down (or a drag on the overlay's lower slider, ±8 stops) change the
//! exposure by half a stop and T cycles the tone-mapping
//! operators (the final, raster and rt views; `--exposure`, `--tone-map` start them, as
//! in `hyrt render`); Esc quits.
//!
//! Unattended: `--frames N --screenshot FILE` renders N frames at `--size` (whatever
//! the window's size), writes the last one's final image (no overlay: the same PNG as
//! `hyrt render` of the scene, camera and size) and exits; `--script FILE` applies
//! actions at given frames ([`script`]); a playing animation then advances 1/30 s a
//! frame, so runs repeat.

mod camera;
mod overlay;
mod present;
mod script;
mod stages;

use std::collections::HashSet;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use hyrt::formats::{CameraRecord, RAY_KIND_REFLECTION, RAY_KIND_REFRACTION, RAY_KIND_SHADOW};
use hyrt::{BackendKind, Frame, FrameOptions, FrameStats, PreparedScene, RenderMode, Renderer, Scene};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use camera::{Controller, Mode};
use overlay::{Overlay, OverlayImage, Slider};
use present::{CpuPresenter, GpuPresenter};
use script::{Action, Script};
use stages::{Rgba8, View};

/// `hyrt view`'s arguments.
#[derive(clap::Args)]
pub struct ViewArgs {
    #[command(flatten)]
    common: crate::SceneArgs,
    /// Render this many frames, then exit (with --screenshot: write the last one's final
    /// image first). Without it the viewer runs until the window closes.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    frames: Option<u32>,
    /// With --frames: the PNG the last frame's final image goes to (no overlay; rendered
    /// at --size, so it equals `hyrt render` of the same scene, camera and size).
    #[arg(long, requires = "frames")]
    screenshot: Option<PathBuf>,
    /// Actions to apply at given frames, one per line: `FRAME ACTION [ARGS]`
    /// (see `hyrt view --help-script`).
    #[arg(long)]
    script: Option<PathBuf>,
    /// Print the script language and exit.
    #[arg(long)]
    help_script: bool,
    /// Start with the overlay hidden (H shows it).
    #[arg(long)]
    no_overlay: bool,
    /// The window's exposure and tone mapping (Page Up / Page Down change the exposure by
    /// half a stop, T cycles the operators).
    #[command(flatten)]
    display: crate::DisplayArgs,
}

/// What stops the viewer.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    #[error("no window system to open a window on: {0}")]
    NoDisplay(String),
    #[error("cannot open the window: {0}")]
    Window(String),
    #[error("cannot show the frame: {0}")]
    Present(String),
    #[error("{0}")]
    Setup(String),
    #[error(transparent)]
    Render(#[from] hyrt::RenderError),
    #[error("{path}: {message}")]
    Write { path: PathBuf, message: String },
}

/// Run the viewer.
pub fn view(args: ViewArgs) -> Result<(), String> {
    if args.help_script {
        println!("{}", script::HELP);
        return Ok(());
    }
    let script = match &args.script {
        Some(p) => Script::load(p)?,
        None => Script::default(),
    };
    let loaded = args.common.load(false)?;
    if std::env::var_os("DISPLAY").is_none() {
        return Err(ViewError::NoDisplay(
            "DISPLAY is not set (hyrt view needs an X11 display: a desktop session, XWayland, or Xvfb)".into(),
        )
        .to_string());
    }
    let event_loop = EventLoop::new().map_err(|e| {
        let display = std::env::var("DISPLAY").unwrap_or_default();
        ViewError::NoDisplay(format!("cannot connect to the X server of DISPLAY={display} ({e})")).to_string()
    })?;
    let mut app = App { args, script, loaded: Some(loaded), running: None, error: None };
    event_loop.run_app(&mut app).map_err(|e| ViewError::Window(e.to_string()).to_string())?;
    if let Some(e) = app.error {
        return Err(e.to_string());
    }
    let done = app.running.as_ref().map_or(0, |r| r.frames_done);
    match (&app.args.screenshot, app.args.frames) {
        (Some(path), Some(n)) if done < n => {
            Err(format!("the viewer closed after {done} of {n} frames: {} not written", path.display()))
        }
        _ => Ok(()),
    }
}

struct App {
    args: ViewArgs,
    script: Script,
    loaded: Option<crate::Loaded>,
    running: Option<Running>,
    error: Option<ViewError>,
}

/// Where frames go.
enum Presenter {
    Cpu(CpuPresenter),
    Gpu(Box<GpuPresenter>),
}

/// The mouse's state.
#[derive(Default)]
struct Mouse {
    at: (f64, f64),
    /// Where the left button went down, and whether it has moved far enough to be a drag.
    pressed: Option<((f64, f64), bool)>,
    /// The press began on this slider.
    on_slider: Option<Slider>,
}

/// The viewer once its window is open.
struct Running {
    window: Arc<Window>,
    presenter: Presenter,
    renderer: Renderer,
    scene: Scene,
    prepared: PreparedScene,
    /// What the animation moves: posing it moves those objects, not the whole scene.
    motion: crate::Motion,
    animation: Option<usize>,
    time: f32,
    playing: bool,
    initial_camera: hyrt::Camera,
    controller: Controller,
    options: FrameOptions,
    /// Each frame takes its own samples of area lights and ambient occlusion, which the
    /// denoiser accumulates over the frames ([`FrameOptions::temporal`]); off after the GPU
    /// backend refused a frame too large for its temporal pass.
    temporal: bool,
    view: View,
    light: usize,
    frame: Frame,
    /// The statistics of the last frame (from `frame`, or from `render_to_texture`).
    stats: FrameStats,
    /// The last frame was read back (`frame` is current, pixel counts are real).
    read_back: bool,
    overlay: Option<Overlay>,
    show_overlay: bool,
    /// How the final, raster and rt images are displayed: exposure in stops and operator.
    display: crate::Display,
    overlay_image: Option<OverlayImage>,
    keys: HashSet<KeyCode>,
    mouse: Mouse,
    pending_pick: Option<(u32, u32)>,
    pending_screenshot: Option<bool>,
    last: Instant,
    /// Since when, and how many frames began since: the frame rate's window.
    fps_window: (Instant, u32),
    fps: f64,
    frames_done: u32,
    screenshots: u32,
    message: String,
}

/// The largest exposure, in stops, either way (`hyrt render --exposure`'s range).
const EXPOSURE_LIMIT: f32 = 64.0;

fn err(e: impl std::fmt::Display) -> ViewError {
    ViewError::Setup(e.to_string())
}

impl App {
    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<Running, ViewError> {
        let common = &self.args.common;
        let (w, h) = common.size;
        let attributes = Window::default_attributes().with_title("hyrt").with_inner_size(PhysicalSize::new(w, h));
        let window = Arc::new(event_loop.create_window(attributes).map_err(|e| ViewError::Window(e.to_string()))?);
        let policy = common.adapter_policy();
        let (renderer, presenter) = match common.backend_kind() {
            BackendKind::Cpu => (Renderer::cpu(common.threads), None),
            kind => match open_gpu(&window, policy, w, h) {
                Ok((r, p)) => (r, Some(p)),
                Err(e) if kind == BackendKind::Auto => {
                    eprintln!("backend: auto -> cpu (no usable GPU for the window: {e})");
                    (Renderer::cpu(common.threads), None)
                }
                Err(e) => return Err(e),
            },
        };
        let mut renderer = renderer.with_bvh_preset(common.bvh_preset());
        common.set_executor(&mut renderer);
        // The denoiser accumulates the frames' samples while the view holds (on either
        // backend; the GPU's in frames of one band, see `render`).
        let temporal = true;
        eprintln!("backend: {}", renderer.choice_details());
        let presenter = match presenter {
            Some(p) => Presenter::Gpu(Box::new(p)),
            None => Presenter::Cpu(CpuPresenter::new(window.clone())?),
        };
        let crate::Loaded { scene, animation, start_time, camera, .. } =
            self.loaded.take().expect("the scene is loaded once");
        // Space plays the animation --time or --animation chose, else the scene's first.
        let animation = animation.or(scene.animation.as_ref().filter(|a| !a.animations().is_empty()).map(|_| 0));
        let motion = crate::Motion::of(&scene, animation);
        let prepared = motion.prepare(&renderer, &scene);
        let size = scene.world_bounds().map_or(10.0, |(lo, hi)| (hi - lo).length());
        let display = self.args.display.resolve(scene.shading);
        let overlay = match Overlay::load() {
            Ok(o) => Some(o),
            Err(e) => {
                eprintln!("warning: running without the overlay: {e}");
                None
            }
        };
        Ok(Running {
            window,
            presenter,
            renderer,
            scene,
            prepared,
            motion,
            animation,
            time: start_time,
            playing: false,
            initial_camera: camera,
            controller: Controller::new(camera, size),
            // The G-buffer for picking (and its views), whatever the view.
            options: common.frame_options(false, true),
            temporal,
            view: View::Final,
            light: 0,
            frame: Frame::default(),
            stats: FrameStats::default(),
            read_back: false,
            overlay,
            show_overlay: !self.args.no_overlay,
            display,
            overlay_image: None,
            keys: HashSet::new(),
            mouse: Mouse::default(),
            pending_pick: None,
            pending_screenshot: None,
            last: Instant::now(),
            fps_window: (Instant::now(), 0),
            fps: 0.0,
            frames_done: 0,
            screenshots: 0,
            message: String::new(),
        })
    }

    /// Render and show one frame; `Ok(true)` when the viewer is done.
    fn redraw(&mut self) -> Result<bool, ViewError> {
        let args = &self.args;
        let r = self.running.as_mut().expect("open");
        let mut quit = false;
        for action in self.script.at(r.frames_done) {
            quit |= r.apply(action)?;
        }
        if quit {
            return Ok(true);
        }
        let now = Instant::now();
        let dt = now.duration_since(r.last).as_secs_f64();
        r.last = now;
        // Frames per second over the last half second or more (one slow frame is its own window).
        let (since, frames) = &mut r.fps_window;
        *frames += 1;
        let window = now.duration_since(*since).as_secs_f64();
        if window >= 0.5 {
            r.fps = (*frames - 1) as f64 / window;
            (*since, *frames) = (now, 1);
        }
        let unattended = args.frames.is_some();
        // Unattended runs step the animation by a fixed 1/30 s a frame, so they repeat.
        r.update(if unattended { 1.0 / 30.0 } else { dt as f32 })?;
        let (width, height) = if unattended {
            args.common.size
        } else {
            let s = r.window.inner_size();
            (s.width.max(1), s.height.max(1))
        };
        let last = args.frames.is_some_and(|n| r.frames_done + 1 >= n);
        let want_frame = last && args.screenshot.is_some();
        r.render(width, height, want_frame)?;
        if last {
            if let Some(path) = &args.screenshot {
                let (f, d) = (&r.frame, r.display);
                hyrt::image_io::write_png_tone_mapped(path, f.width, f.height, &f.final_image, d.exposure, d.tone_map)
                    .map_err(|e| ViewError::Write { path: path.clone(), message: e.to_string() })?;
                println!("wrote {} ({width}x{height}, frame {})", path.display(), r.frames_done + 1);
            }
        }
        r.frames_done += 1;
        Ok(last)
    }
}

/// A GPU renderer on a device that can present to `window`, and its presenter.
fn open_gpu(
    window: &Arc<Window>,
    policy: hyrt::AdapterPolicy,
    width: u32,
    height: u32,
) -> Result<(Renderer, GpuPresenter), ViewError> {
    let instance = hyrt::GpuContext::vulkan_instance(Some(Box::new(window.clone())));
    let surface = instance.create_surface(window.clone()).map_err(|e| ViewError::Present(e.to_string()))?;
    let ctx = hyrt::GpuContext::with_instance(&instance, Some(&surface), policy).map_err(err)?;
    let presenter = GpuPresenter::new(&ctx, surface, width, height)?;
    let gpu = hyrt::GpuBackend::with_context(ctx).map_err(err)?;
    Ok((Renderer::with_gpu_backend(gpu), presenter))
}

impl Running {
    /// Advance the animation and the held keys' motion by `dt` seconds.
    fn update(&mut self, dt: f32) -> Result<(), ViewError> {
        let k = |c: KeyCode| self.keys.contains(&c) as i32 as f32;
        let fast =
            if self.keys.contains(&KeyCode::ShiftLeft) || self.keys.contains(&KeyCode::ShiftRight) { 4.0 } else { 1.0 };
        let forward = k(KeyCode::KeyW) - k(KeyCode::KeyS);
        let right = k(KeyCode::KeyD) - k(KeyCode::KeyA);
        let up = k(KeyCode::KeyE) - k(KeyCode::KeyQ);
        self.controller.travel(forward, right, up, dt.min(0.25) * fast);
        if self.playing {
            self.pose(self.time + dt)?;
        }
        Ok(())
    }

    /// Pose the scene at `t` seconds of its animation (looping over its duration) and move
    /// what it moves.
    fn pose(&mut self, t: f32) -> Result<(), ViewError> {
        let (Some(a), Some(anim)) = (self.animation, &self.scene.animation) else { return Ok(()) };
        let duration = anim.animations()[a].duration();
        self.time = if duration > 0.0 && t > duration { t.rem_euclid(duration) } else { t.max(0.0) };
        self.scene.set_time(a, self.time).map_err(err)?;
        self.motion.apply(&mut self.prepared, &self.scene).map_err(err)?;
        Ok(())
    }

    /// Render a `width` x `height` frame of the current view and show it. `want_frame`:
    /// the frame's buffers must be read back (a screenshot of the final image).
    fn render(&mut self, width: u32, height: u32, want_frame: bool) -> Result<(), ViewError> {
        let camera = self.controller.camera;
        self.options.stage_outputs = self.view.needs_stage_outputs();
        if self.temporal {
            self.options.frame_index = self.options.frame_index.wrapping_add(1);
            self.options.temporal = true;
        }
        // The GPU keeps the final image on the device unless a pick, a screenshot or a
        // stage view needs the frame on the CPU.
        let on_device = matches!(self.presenter, Presenter::Gpu(_))
            && self.view == View::Final
            && !want_frame
            && self.pending_pick.is_none()
            && self.pending_screenshot.is_none();
        let rendered = if on_device {
            let Presenter::Gpu(p) = &mut self.presenter else { unreachable!() };
            let target = p.frame_texture(width, height);
            let gpu = self.renderer.gpu_backend().expect("the GPU presenter goes with the GPU backend");
            let record = CameraRecord::new(&camera, width, height);
            gpu.render_to_texture(&self.prepared, &record, &self.options, &target).map(|stats| (stats, false))
        } else {
            self.renderer
                .render_into(&self.prepared, &camera, width, height, &self.options, &mut self.frame)
                .map(|()| (self.frame.stats.clone(), true))
        };
        (self.stats, self.read_back) = match rendered {
            Ok(r) => r,
            // The GPU backend's temporal pass renders a frame in one band only: a frame
            // too large for that is denoised on its own from then on.
            Err(e @ hyrt::RenderError::Gpu(hyrt::GpuError::Limits(_)))
                if self.options.temporal && self.renderer.cpu_backend().is_none() =>
            {
                self.temporal = false;
                self.options.temporal = false;
                self.message = format!("frames denoised each on its own: {e}");
                eprintln!("{}", self.message);
                return self.render(width, height, want_frame);
            }
            Err(e) => return Err(e.into()),
        };
        self.resolve_pick();
        let lights = self.prepared.geometry.lights.len();
        let display = (hyrt_core::kernels::tone_map::exposure_scale(self.display.exposure), self.display.tone_map);
        let image = (!on_device).then(|| stages::colours(self.view, &self.frame, self.light, lights, display));
        if let Some(with_overlay) = self.pending_screenshot.take() {
            self.screenshot(image.as_deref().expect("read back"), width, height, with_overlay)?;
        }
        self.overlay_image = match (&self.overlay, self.show_overlay) {
            (Some(o), true) => Some(o.draw(
                &self.overlay_lines(width, height),
                [Slider::Weight.fraction(self.options.weight), Slider::Exposure.fraction(self.display.exposure)],
            )),
            _ => None,
        };
        let overlay = self.overlay_image.as_ref();
        match &mut self.presenter {
            Presenter::Cpu(p) => p.present(image.as_deref().expect("read back"), width, height, overlay),
            Presenter::Gpu(p) => {
                p.resize(self.window.inner_size().width, self.window.inner_size().height);
                p.present(width, height, image.as_deref(), overlay, display)
            }
        }
    }

    /// Toggle the object under a pending click between ray traced and rasterized.
    fn resolve_pick(&mut self) {
        let Some((x, y)) = self.pending_pick.take() else { return };
        let (w, h) = (self.frame.width, self.frame.height);
        if x >= w || y >= h {
            return;
        }
        let texel = self.frame.gbuffer[(y * w + x) as usize];
        if !texel.is_hit() {
            self.message = format!("pick ({x}, {y}): no object");
            println!("{}", self.message);
            return;
        }
        let Some(object) = self.scene.objects.iter_mut().find(|o| o.id == texel.object) else { return };
        object.render_mode = match object.render_mode {
            RenderMode::RayTraced => RenderMode::Raster,
            RenderMode::Raster => RenderMode::RayTraced,
        };
        self.message =
            format!("pick ({x}, {y}): object {} '{}' is now {}", object.id, object.name, object.render_mode.name());
        println!("{}", self.message);
        // The render mode is part of the prepared world tables: prepare again.
        self.prepared = self.motion.prepare(&self.renderer, &self.scene);
    }

    /// Write the current view (`with_overlay`: as the window shows it) to a numbered PNG.
    fn screenshot(&mut self, image: &[Rgba8], width: u32, height: u32, with_overlay: bool) -> Result<(), ViewError> {
        let mut pixels = image.to_vec();
        if let (true, Some(o)) = (with_overlay, &self.overlay_image) {
            overlay::compose(&mut pixels, width, o);
        }
        // The next number no file has yet.
        let path = loop {
            let path = PathBuf::from(format!("hyrt-view-{:04}.png", self.screenshots));
            self.screenshots += 1;
            if !path.exists() {
                break path;
            }
        };
        image::save_buffer(&path, pixels.as_flattened(), width, height, image::ColorType::Rgba8)
            .map_err(|e| ViewError::Write { path: path.clone(), message: e.to_string() })?;
        self.message = format!("wrote {}", path.display());
        println!("{}", self.message);
        Ok(())
    }

    /// The overlay's text.
    fn overlay_lines(&self, width: u32, height: u32) -> Vec<String> {
        let s = &self.stats;
        let gpu = matches!(self.presenter, Presenter::Gpu(_));
        let mut lines = vec![
            format!("hyrt view: {}", self.renderer.choice()),
            format!(
                "{width}x{height}   {} FPS   stages {:.2} ms",
                if self.fps > 0.0 { format!("{:.1}", self.fps) } else { "-".into() },
                s.frame_ms()
            ),
        ];
        let key = View::KEYS[View::ALL.iter().position(|v| *v == self.view).unwrap_or(0)];
        let mut view = format!("view {key}: {}", self.view.name());
        if self.view == View::Shadow {
            view += &format!(", light {} of {}", self.light + 1, self.prepared.geometry.lights.len());
        }
        if gpu && self.view != View::Final {
            view += " (read back, drawn on the CPU)";
        }
        lines.push(view);
        if self.read_back {
            if let Some(why) = stages::missing(self.view, &self.frame) {
                lines.push(format!("  nothing to show: {why}"));
            }
            lines.push(format!(
                "pixels: covered {}, ray traced {}, rasterized {}",
                s.covered_pixels, s.ray_traced_pixels, s.raster_pixels
            ));
        } else {
            lines.push("pixels: not counted (the frame stays on the GPU; any other view counts)".into());
        }
        let kind =
            |k: u32| s.rays_per_kind[k as usize] + s.bounces.iter().map(|b| b.rays_per_kind[k as usize]).sum::<u64>();
        // The primary shadow rays' occlusion is counted from the read-back results.
        let occluded = match self.read_back {
            true => format!(
                " ({} occluded)",
                s.occluded_shadow_rays + s.bounces.iter().map(|b| b.occluded_shadow_rays).sum::<u64>()
            ),
            false => String::new(),
        };
        lines.push(format!(
            "rays: shadow {}{occluded}, reflection {}, refraction {}, bounces {}",
            kind(RAY_KIND_SHADOW),
            kind(RAY_KIND_REFLECTION),
            kind(RAY_KIND_REFRACTION),
            s.bounces.len()
        ));
        // Milliseconds per stage (summed over the bounces' depths), in the order they ran.
        let times: Vec<String> = hyrt::Stage::ALL
            .iter()
            .filter_map(|&stage| s.ms(stage).map(|ms| format!("{} {ms:.1}", stage.name())))
            .collect();
        for chunk in times.chunks(4) {
            lines.push(format!("ms: {}", chunk.join("  ")));
        }
        let c = &self.controller.camera;
        lines.push(format!(
            "camera {} (Tab): eye {:.2}, {:.2}, {:.2}",
            self.controller.mode.name(),
            c.eye.x,
            c.eye.y,
            c.eye.z
        ));
        if let (Some(a), Some(anim)) = (self.animation, &self.scene.animation) {
            let a = &anim.animations()[a];
            let state = if self.playing { "playing" } else { "paused" };
            lines.push(format!(
                "animation '{}' {:.2} / {:.2} s, {state} (Space; , . step)",
                a.name(),
                self.time,
                a.duration()
            ));
        }
        lines.push(format!("weight {:.2} ([ ] or the upper bar)", self.options.weight));
        lines.push(format!(
            "exposure {:+.1} stops (PgUp PgDn or the lower bar), tone map {} (T)",
            self.display.exposure,
            self.display.tone_map.name()
        ));
        lines.push("1 final 2 raster 3 rt 4 bary 5 depth 6 normal 7 tri 8 obj 9 rt/raster".into());
        lines.push("0 shadow (L: light) - ray count = bounce depth".into());
        lines.push("drag turn, wheel zoom, WASD QE move, R reset, C scene cam".into());
        lines.push("click: ray traced <-> raster, H hide, P png, O png+overlay".into());
        if !self.message.is_empty() {
            lines.push(self.message.clone());
        }
        lines
    }

    /// Do what a key or a script line asks.
    fn apply(&mut self, action: Action) -> Result<bool, ViewError> {
        match action {
            Action::View(v) => {
                self.view = v;
                self.message.clear();
            }
            Action::ToggleMode => {
                self.controller.mode = match self.controller.mode {
                    Mode::Orbit => Mode::Fly,
                    Mode::Fly => Mode::Orbit,
                }
            }
            Action::Reset => self.controller.camera = self.initial_camera,
            Action::SceneCamera => {
                if let Some(c) = self.scene.camera {
                    self.controller.camera = c;
                }
            }
            Action::PlayPause => {
                self.playing = !self.playing && self.animation.is_some();
                if self.animation.is_none() {
                    self.message = "the scene has no animation".into();
                }
            }
            Action::StepTime(dt) => {
                self.playing = false;
                self.pose(self.time + dt)?;
            }
            Action::SetTime(t) => self.pose(t)?,
            Action::AddWeight(d) => self.options.weight = (self.options.weight + d).clamp(0.0, 1.0),
            Action::SetWeight(w) => self.options.weight = w.clamp(0.0, 1.0),
            Action::NextLight => self.light = (self.light + 1) % self.prepared.geometry.lights.len().max(1),
            Action::ToggleOverlay => self.show_overlay = !self.show_overlay,
            Action::AddExposure(stops) => {
                self.display.exposure = (self.display.exposure + stops).clamp(-EXPOSURE_LIMIT, EXPOSURE_LIMIT)
            }
            Action::SetExposure(stops) => self.display.exposure = stops.clamp(-EXPOSURE_LIMIT, EXPOSURE_LIMIT),
            Action::NextToneMap => {
                let all = hyrt::ToneMap::ALL;
                let at = all.iter().position(|&t| t == self.display.tone_map).unwrap_or(0);
                self.display.tone_map = all[(at + 1) % all.len()];
            }
            Action::Screenshot { overlay } => self.pending_screenshot = Some(overlay),
            Action::Orbit(dx, dy) => self.controller.rotate(dx, dy),
            Action::Zoom(f) => self.controller.zoom(f),
            Action::Move(f, r, u) => {
                let mode = self.controller.mode;
                self.controller.mode = Mode::Fly;
                self.controller.travel(f, r, u, 1.0 / self.controller.speed);
                self.controller.mode = mode;
            }
            Action::Click(x, y) => self.pending_pick = Some((x, y)),
            Action::Quit => return Ok(true),
        }
        Ok(false)
    }

    /// A key went down: `Ok(true)` to quit.
    fn key(&mut self, code: KeyCode) -> Result<bool, ViewError> {
        let view_keys = [
            KeyCode::Digit1,
            KeyCode::Digit2,
            KeyCode::Digit3,
            KeyCode::Digit4,
            KeyCode::Digit5,
            KeyCode::Digit6,
            KeyCode::Digit7,
            KeyCode::Digit8,
            KeyCode::Digit9,
            KeyCode::Digit0,
            KeyCode::Minus,
            KeyCode::Equal,
        ];
        let action = if let Some(i) = view_keys.iter().position(|k| *k == code) {
            Action::View(View::ALL[i])
        } else {
            match code {
                KeyCode::Tab => Action::ToggleMode,
                KeyCode::KeyR => Action::Reset,
                KeyCode::KeyC => Action::SceneCamera,
                KeyCode::Space => Action::PlayPause,
                KeyCode::Comma => Action::StepTime(-1.0 / 30.0),
                KeyCode::Period => Action::StepTime(1.0 / 30.0),
                KeyCode::BracketLeft => Action::AddWeight(-0.05),
                KeyCode::BracketRight => Action::AddWeight(0.05),
                KeyCode::KeyL => Action::NextLight,
                KeyCode::KeyH => Action::ToggleOverlay,
                KeyCode::PageUp => Action::AddExposure(0.5),
                KeyCode::PageDown => Action::AddExposure(-0.5),
                KeyCode::KeyT => Action::NextToneMap,
                KeyCode::KeyP => Action::Screenshot { overlay: false },
                KeyCode::KeyO => Action::Screenshot { overlay: true },
                KeyCode::Escape => Action::Quit,
                _ => return Ok(false),
            }
        };
        self.apply(action)
    }

    /// Set `slider`'s value from window x on its track.
    fn drag_slider(&mut self, slider: Slider, x: f64) {
        let Some(o) = &self.overlay_image else { return };
        let value = o.value_at(slider, x);
        match slider {
            Slider::Weight => self.options.weight = value,
            Slider::Exposure => self.display.exposure = value,
        }
    }

    /// True over the overlay's panel: a click there picks nothing.
    fn on_overlay(&self, (x, y): (f64, f64)) -> bool {
        self.overlay_image.as_ref().is_some_and(|o| x < o.width as f64 && y < o.height as f64)
    }

    fn on_slider(&self, (x, y): (f64, f64)) -> Option<Slider> {
        self.overlay_image.as_ref().and_then(|o| o.slider_at(x, y)).map(|(s, _)| s)
    }

    fn mouse_event(&mut self, event: &WindowEvent) {
        match *event {
            WindowEvent::CursorMoved { position, .. } => {
                let (x, y) = (position.x, position.y);
                let (px, py) = self.mouse.at;
                self.mouse.at = (x, y);
                if let Some((start, dragged)) = &mut self.mouse.pressed {
                    if (x - start.0).abs() + (y - start.1).abs() > 3.0 {
                        *dragged = true;
                    }
                    let dragged = *dragged;
                    if let Some(slider) = self.mouse.on_slider {
                        self.drag_slider(slider, x);
                    } else if dragged {
                        self.controller.rotate(((x - px) * 0.005) as f32, ((y - py) * 0.005) as f32);
                    }
                }
            }
            WindowEvent::MouseInput { state, button: MouseButton::Left, .. } => match state {
                ElementState::Pressed => {
                    self.mouse.pressed = Some((self.mouse.at, false));
                    self.mouse.on_slider = self.on_slider(self.mouse.at);
                }
                ElementState::Released => {
                    if let Some((_, dragged)) = self.mouse.pressed.take() {
                        let (x, y) = self.mouse.at;
                        if let Some(slider) = self.mouse.on_slider {
                            self.drag_slider(slider, x);
                        } else if !dragged && x >= 0.0 && y >= 0.0 && !self.on_overlay((x, y)) {
                            self.pending_pick = Some((x as u32, y as u32));
                        }
                    }
                    self.mouse.on_slider = None;
                }
            },
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => (p.y / 40.0) as f32,
                };
                self.controller.zoom(lines * 0.1);
            }
            _ => {}
        }
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.running.is_some() || self.error.is_some() {
            return;
        }
        match self.open(event_loop) {
            Ok(r) => {
                r.window.request_redraw();
                self.running = Some(r);
            }
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(r) = self.running.as_mut() else { return };
        let outcome = match &event {
            WindowEvent::CloseRequested => Ok(true),
            WindowEvent::RedrawRequested => self.redraw(),
            WindowEvent::KeyboardInput { event, .. } => {
                let PhysicalKey::Code(code) = event.physical_key else { return };
                match event.state {
                    ElementState::Pressed => {
                        r.keys.insert(code);
                        if event.repeat {
                            Ok(false)
                        } else {
                            r.key(code)
                        }
                    }
                    ElementState::Released => {
                        r.keys.remove(&code);
                        Ok(false)
                    }
                }
            }
            // Keys released while another window had the focus never arrive: stop moving.
            WindowEvent::Focused(false) => {
                r.keys.clear();
                r.mouse.pressed = None;
                Ok(false)
            }
            WindowEvent::Resized(_) => {
                r.window.request_redraw();
                Ok(false)
            }
            _ => {
                r.mouse_event(&event);
                Ok(false)
            }
        };
        match outcome {
            Ok(false) => {}
            Ok(true) => event_loop.exit(),
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        // Frames follow each other as fast as they render: the overlay's numbers are live.
        if let Some(r) = &self.running {
            r.window.request_redraw();
        }
    }
}
