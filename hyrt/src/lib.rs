//! # hyrt
//!
//! A hybrid renderer after Sabino et al. (SBGames 2011): a raster pass stands in
//! for primary rays, the hit points are rebuilt from barycentrics, active pixels
//! are compacted into a ray list, shadow rays are traced through a BVH of the
//! whole scene, ray-traced objects are shaded by the tracer, the rest by an
//! ordinary raster shader, and the two images are composed by a weighted mean.
//!
//! This facade re-exports what users need and picks a backend.
//!
//! ```
//! use hyrt::{Renderer, Scene, FrameOptions};
//! let mut scene = Scene::default_scene();
//! scene.ensure_camera_and_lights();
//! let renderer = Renderer::cpu(Some(1));
//! let prepared = renderer.prepare(&scene);
//! let camera = scene.camera.unwrap();
//! let frame = renderer.render(&prepared, &camera, 64, 48, &FrameOptions::default()).unwrap();
//! assert_eq!(frame.final_image.len(), 64 * 48);
//! assert!(frame.stats.ray_traced_pixels > 0);
//! ```

pub mod image_io;

use std::cell::RefCell;

pub use hyrt_core::bvh::{Bvh, BvhPreset};
pub use hyrt_core::formats;
pub use hyrt_core::frame::{Backend, Frame, FrameOptions, FrameStats, PreparedScene, RenderError, StageTime};
pub use hyrt_core::geometry::WorldGeometry;
pub use hyrt_core::scene::{Camera, Light, Material, MaterialKind, Mesh, Object, RenderMode, Scene};
pub use hyrt_core::stage::Stage;
pub use hyrt_core::{glam, SceneError};
pub use hyrt_cpu::backend::CpuBackend;
pub use hyrt_gpu::backend::GpuBackend;
pub use hyrt_gpu::{AdapterPolicy, GpuError};

/// Which backend renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackendKind {
    /// The CPU reference backend (rayon).
    Cpu,
    /// The GPU backend (wgpu, Vulkan); fails when no adapter fits the policy.
    Gpu,
    /// A hardware GPU when there is one (or a software one if the policy allows),
    /// the CPU backend otherwise.
    Auto,
}

/// Everything that can go wrong in the facade and the command-line program.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error("{path}: cannot write: {source}")]
    Write {
        path: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: cannot encode image: {message}")]
    Image { path: std::path::PathBuf, message: String },
    #[error(transparent)]
    Gpu(#[from] GpuError),
}

/// A backend plus the BVH preset it prepares scenes with. Scenes are always
/// prepared (world tables, BVH) on the CPU, once, and fed to either backend, so
/// both trace the very same BVH.
pub struct Renderer {
    cpu: RefCell<CpuBackend>,
    gpu: Option<RefCell<GpuBackend>>,
    preset: BvhPreset,
    choice: String,
}

impl Renderer {
    /// The CPU backend with `threads` workers (`None`: one per core).
    pub fn cpu(threads: Option<usize>) -> Self {
        let cpu = CpuBackend::new(threads);
        let choice = format!("cpu ({} threads)", cpu.threads());
        Renderer { cpu: RefCell::new(cpu), gpu: None, preset: BvhPreset::default(), choice }
    }

    /// The backend `kind` asks for. `policy` says whether a software GPU adapter
    /// (lavapipe) is acceptable. [`Renderer::choice`] says what was taken and why.
    pub fn new(kind: BackendKind, threads: Option<usize>, policy: AdapterPolicy) -> Result<Self, Error> {
        let mut r = Renderer::cpu(threads);
        match kind {
            BackendKind::Cpu => {}
            BackendKind::Gpu => {
                let gpu = GpuBackend::new(policy)?;
                r.choice = format!("gpu: {}", gpu.describe());
                r.gpu = Some(RefCell::new(gpu));
            }
            BackendKind::Auto => match GpuBackend::new(policy) {
                Ok(gpu) => {
                    r.choice = format!("auto -> gpu: {}", gpu.describe());
                    r.gpu = Some(RefCell::new(gpu));
                }
                Err(e) => r.choice = format!("auto -> {} (no usable GPU: {e})", r.choice),
            },
        }
        Ok(r)
    }

    /// Which backend renders, on what, and why (for the user).
    pub fn choice(&self) -> &str {
        &self.choice
    }

    /// Use another BVH build preset for [`Renderer::prepare`].
    pub fn with_bvh_preset(mut self, preset: BvhPreset) -> Self {
        self.preset = preset;
        self
    }

    /// The rendering backend's name ("cpu" or "gpu").
    pub fn backend_name(&self) -> String {
        match &self.gpu {
            Some(g) => g.borrow().name().to_string(),
            None => self.cpu.borrow().name().to_string(),
        }
    }

    /// Worker threads of the CPU backend (which also prepares scenes).
    pub fn threads(&self) -> usize {
        self.cpu.borrow().threads()
    }

    /// World tables + BVH of a scene (the `bvh_build` stage, on the CPU), built once per scene.
    pub fn prepare(&self, scene: &Scene) -> PreparedScene {
        self.cpu.borrow().prepare(WorldGeometry::build(scene), self.preset)
    }

    /// Render one frame of `width` x `height` pixels.
    pub fn render(
        &self,
        prepared: &PreparedScene,
        camera: &Camera,
        width: u32,
        height: u32,
        options: &FrameOptions,
    ) -> Result<Frame, RenderError> {
        let mut frame = Frame::default();
        self.render_into(prepared, camera, width, height, options, &mut frame)?;
        Ok(frame)
    }

    /// Render into `frame`, reusing its buffers from an earlier frame (the way to
    /// render many frames: a frame of the same size then allocates nothing).
    pub fn render_into(
        &self,
        prepared: &PreparedScene,
        camera: &Camera,
        width: u32,
        height: u32,
        options: &FrameOptions,
        frame: &mut Frame,
    ) -> Result<(), RenderError> {
        if width == 0 || height == 0 {
            return Err(RenderError::InvalidOptions(format!("image size must be non-zero, got {width}x{height}")));
        }
        let record = formats::CameraRecord::new(camera, width, height);
        match &self.gpu {
            Some(g) => g.borrow_mut().render_into(prepared, &record, options, frame),
            None => self.cpu.borrow_mut().render_into(prepared, &record, options, frame),
        }
    }
}
