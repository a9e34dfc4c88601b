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

pub mod dump;
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

/// Which backend renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackendKind {
    /// The CPU reference backend (rayon).
    Cpu,
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
}

/// A backend plus the BVH preset it prepares scenes with.
pub struct Renderer {
    backend: RefCell<CpuBackend>,
    preset: BvhPreset,
}

impl Renderer {
    /// The CPU backend with `threads` workers (`None`: one per core).
    pub fn cpu(threads: Option<usize>) -> Self {
        Renderer { backend: RefCell::new(CpuBackend::new(threads)), preset: BvhPreset::default() }
    }

    /// Use another BVH build preset for [`Renderer::prepare`].
    pub fn with_bvh_preset(mut self, preset: BvhPreset) -> Self {
        self.preset = preset;
        self
    }

    /// The backend's name.
    pub fn backend_name(&self) -> String {
        self.backend.borrow().name().to_string()
    }

    /// Worker threads of the backend.
    pub fn threads(&self) -> usize {
        self.backend.borrow().threads()
    }

    /// World tables + BVH of a scene (the `bvh_build` stage), built once per scene.
    pub fn prepare(&self, scene: &Scene) -> PreparedScene {
        self.backend.borrow().prepare(WorldGeometry::build(scene), self.preset)
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
        self.backend.borrow_mut().render_into(prepared, &record, options, frame)
    }
}
