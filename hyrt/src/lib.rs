//! # hyrt
//!
//! A hybrid renderer after Sabino et al. (SBGames 2011): a raster pass stands in
//! for primary rays, the hit points are rebuilt from barycentrics, active pixels
//! are compacted into a ray list, shadow rays are traced through a BVH of the
//! whole scene, ray-traced objects are shaded by the tracer, the rest by an
//! ordinary raster shader, and the two images are composed by a weighted mean.
//!
//! This facade re-exports what users need and picks a backend. The example in
//! `examples/orbit.rs` (`cargo run --release -p hyrt --example orbit`) loads a scene,
//! orbits the camera, moves an object, switches it to ray traced and falls back to
//! the CPU when there is no GPU; in short:
//!
//! ```
//! use hyrt::{BackendKind, AdapterPolicy, Camera, FrameOptions, Renderer, Scene, Stage};
//! use hyrt::glam::Vec3;
//! let mut scene = Scene::default_scene();
//! scene.ensure_camera_and_lights();
//! // A GPU if there is one, else the CPU reference; `choice()` says which.
//! let mut renderer = Renderer::new(BackendKind::Auto, None, AdapterPolicy::HardwareOnly).unwrap();
//! let prepared = renderer.prepare(&scene);
//! let camera = Camera::look_at(Vec3::new(0.0, 2.0, 8.0), Vec3::ZERO, Vec3::Y);
//! let frame = renderer.render(&prepared, &camera, 64, 48, &FrameOptions::default()).unwrap();
//! let rgba8: Vec<u8> = frame.final_srgb8(); // ready for a window or a PNG
//! assert_eq!(rgba8.len(), 64 * 48 * 4);
//! assert!(frame.stats.ms(Stage::ShadowRays).is_some());
//! ```
//!
//! # Threads
//!
//! A [`Renderer`] is `Send`: move it to the thread that renders. It renders through
//! `&mut self` (a backend keeps its frame buffers between frames), so sharing one
//! between threads takes a `Mutex`; [`PreparedScene`]s are plain data, `Send + Sync`,
//! and can be shared by several renderers. The CPU backend runs each frame on its own
//! rayon pool of the threads it was given.
//!
//! # Cargo features
//!
//! - `gpu` (on by default): the wgpu backend. Without it `hyrt` compiles no wgpu,
//!   [`BackendKind::Gpu`] is an error and [`BackendKind::Auto`] picks the CPU.

pub mod image_io;

pub use hyrt_core::bvh::two_level::{MoveError, TwoLevelBvh};
pub use hyrt_core::bvh::{Bvh, BvhPreset};
pub use hyrt_core::formats;
pub use hyrt_core::frame::{
    Backend, BounceBuffers, BounceStats, BufferView, Executor, Frame, FrameOptions, FrameStats, PreparedScene,
    PrimaryBarycentrics, RenderError, SceneChanges, StageTime, StageWork, CHANGE_LOG_LENGTH,
};
pub use hyrt_core::frame::{DEFAULT_AO_RADIUS_FRACTION, DEFAULT_SHADOW_SAMPLES};
pub use hyrt_core::geometry::WorldGeometry;
pub use hyrt_core::kernels::bounce::{DEFAULT_MAX_DEPTH, MAX_DEPTH_LIMIT, MIN_THROUGHPUT};
pub use hyrt_core::kernels::soft_shadow::MAX_SAMPLES;
pub use hyrt_core::kernels::tone_map::ToneMap;
pub use hyrt_core::plan::{BounceBuffer, Composition, FrameBuffer, FramePlan, SkipReason, Skipped, Step};
pub use hyrt_core::scene::{
    Ambient, Camera, Environment, EnvironmentMap, EnvironmentMapError, Light, Material, MaterialKind, MaterialMaps,
    Mesh, Object, RenderMode, Scene, ShadingModel,
};
pub use hyrt_core::stage::Stage;
pub use hyrt_core::{glam, memory, AnimationError, GpuError, SceneError};
pub use hyrt_cpu::backend::CpuBackend;
/// The CPU backend's SIMD level per kind of walk, measured AVX-512 against AVX2 while the
/// stages trace: which level each kind runs at ([`simd_tuning::levels`]).
pub use hyrt_cpu::traversal::tuning as simd_tuning;
/// How the CPU backend traces rays (`CpuBackend::set_shadow_traversal`,
/// `CpuBackend::set_bounce_traversal`) and which SIMD level it runs.
pub use hyrt_cpu::traversal::{force_simd_level, SimdLevel, Traversal};
#[cfg(feature = "gpu")]
pub use hyrt_gpu::{backend::GpuBackend, shader::FloatOps, wgpu, AdapterPolicy, GpuContext};

/// Which adapters a GPU backend accepts (the `gpu` feature is off: there is none).
#[cfg(not(feature = "gpu"))]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AdapterPolicy {
    /// A hardware GPU only.
    HardwareOnly,
    /// A software adapter (lavapipe) is accepted too.
    AllowSoftware,
}

#[cfg(not(feature = "gpu"))]
impl AdapterPolicy {
    /// `HardwareOnly`: without the `gpu` feature the policy has no effect.
    pub fn from_env() -> Self {
        AdapterPolicy::HardwareOnly
    }
}

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

/// Everything that can go wrong in the facade.
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
    /// The GPU backend could not start (no adapter, device refused, ...).
    #[cfg(feature = "gpu")]
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// [`BackendKind::Gpu`] was asked of a build without the `gpu` feature.
    #[error("hyrt was built without the `gpu` cargo feature: no GPU backend")]
    NoGpuFeature,
}

/// The backend a [`Renderer`] drives.
enum Active {
    Cpu(Box<CpuBackend>),
    #[cfg(feature = "gpu")]
    Gpu(Box<GpuBackend>),
}

/// A backend plus the BVH preset it prepares scenes with. Scenes are prepared
/// (world tables, BVH) on the CPU, once, and fed to either backend, so both trace
/// the very same BVH. See the crate docs for the threading model.
pub struct Renderer {
    active: Active,
    preset: BvhPreset,
    /// Short: "cpu (8 threads)", "gpu (NVIDIA ...)".
    choice: String,
    /// Why, and what the backend runs on, in full.
    details: String,
}

// A renderer moves to the thread that renders (checked at compile time).
const _: fn() = || {
    fn send<T: Send>() {}
    send::<Renderer>();
    fn send_sync<T: Send + Sync>() {}
    send_sync::<PreparedScene>();
};

impl Renderer {
    /// The CPU backend with `threads` workers (`None`: one per core).
    pub fn cpu(threads: Option<usize>) -> Self {
        Self::with_cpu_backend(CpuBackend::new(threads))
    }

    /// Render with a CPU backend the caller built.
    pub fn with_cpu_backend(cpu: CpuBackend) -> Self {
        let choice = format!("cpu ({} threads)", cpu.threads());
        let details = format!("{choice}: the CPU reference backend");
        Renderer { active: Active::Cpu(Box::new(cpu)), preset: BvhPreset::default(), choice, details }
    }

    /// Render with a GPU backend the caller built, e.g. on its own device
    /// (`GpuBackend::with_context(GpuContext::from_device(..))`), so frames can stay on
    /// the GPU ([`GpuBackend::render_to_texture`], through [`Renderer::gpu_backend`]).
    #[cfg(feature = "gpu")]
    pub fn with_gpu_backend(gpu: GpuBackend) -> Self {
        let choice = format!("gpu ({})", gpu.context().info.name);
        let details = format!("gpu: {}", gpu.describe());
        Renderer { active: Active::Gpu(Box::new(gpu)), preset: BvhPreset::default(), choice, details }
    }

    /// The backend `kind` asks for. `policy` says whether a software GPU adapter
    /// (lavapipe) is acceptable. [`Renderer::choice`] says what was taken;
    /// [`Renderer::choice_details`] why, and on what.
    pub fn new(kind: BackendKind, threads: Option<usize>, policy: AdapterPolicy) -> Result<Self, Error> {
        #[cfg(feature = "gpu")]
        match kind {
            BackendKind::Cpu => Ok(Renderer::cpu(threads)),
            BackendKind::Gpu => Ok(Renderer::with_gpu_backend(GpuBackend::new(policy)?)),
            BackendKind::Auto => Ok(match GpuBackend::new(policy) {
                Ok(gpu) => {
                    let mut r = Renderer::with_gpu_backend(gpu);
                    r.details = format!("auto -> {}", r.details);
                    r
                }
                Err(e) => {
                    let mut r = Renderer::cpu(threads);
                    r.details = format!("auto -> {} (no usable GPU: {e})", r.details);
                    r
                }
            }),
        }
        #[cfg(not(feature = "gpu"))]
        {
            let _ = policy;
            match kind {
                BackendKind::Gpu => Err(Error::NoGpuFeature),
                BackendKind::Cpu => Ok(Renderer::cpu(threads)),
                BackendKind::Auto => {
                    let mut r = Renderer::cpu(threads);
                    r.details = format!("auto -> {} (built without the gpu feature)", r.details);
                    Ok(r)
                }
            }
        }
    }

    /// Which backend renders, in a few words ("cpu (8 threads)", "gpu (llvmpipe ...)").
    pub fn choice(&self) -> &str {
        &self.choice
    }

    /// Which backend renders, why it was chosen and what it runs on, in full.
    pub fn choice_details(&self) -> &str {
        &self.details
    }

    /// Use another BVH build preset for [`Renderer::prepare`].
    pub fn with_bvh_preset(mut self, preset: BvhPreset) -> Self {
        self.preset = preset;
        self
    }

    /// The rendering backend's name ("cpu" or "gpu").
    pub fn backend_name(&self) -> &str {
        self.backend().name()
    }

    /// Worker threads of the CPU backend; `None` on the GPU.
    pub fn threads(&self) -> Option<usize> {
        match &self.active {
            Active::Cpu(c) => Some(c.threads()),
            #[cfg(feature = "gpu")]
            Active::Gpu(_) => None,
        }
    }

    /// The backend, as the trait both implement.
    pub fn backend(&self) -> &dyn Backend {
        match &self.active {
            Active::Cpu(c) => c.as_ref(),
            #[cfg(feature = "gpu")]
            Active::Gpu(g) => g.as_ref(),
        }
    }

    fn backend_mut(&mut self) -> &mut dyn Backend {
        match &mut self.active {
            Active::Cpu(c) => c.as_mut(),
            #[cfg(feature = "gpu")]
            Active::Gpu(g) => g.as_mut(),
        }
    }

    /// The CPU backend when it renders (for its settings: [`CpuBackend::set_executor`],
    /// [`CpuBackend::set_shadow_traversal`], ...).
    pub fn cpu_backend(&mut self) -> Option<&mut CpuBackend> {
        match &mut self.active {
            Active::Cpu(c) => Some(c),
            #[cfg(feature = "gpu")]
            Active::Gpu(_) => None,
        }
    }

    /// The GPU backend when it renders (for [`GpuBackend::render_to_texture`] and
    /// its device).
    #[cfg(feature = "gpu")]
    pub fn gpu_backend(&mut self) -> Option<&mut GpuBackend> {
        match &mut self.active {
            Active::Gpu(g) => Some(g.as_mut()),
            Active::Cpu(_) => None,
        }
    }

    /// World tables + BVH of a scene (the `bvh_build` stage, on the CPU: rayon's
    /// global pool), built once per scene and usable by any renderer. A scene whose copies
    /// of shared meshes would take more than 1 GiB stored
    /// ([`hyrt_cpu::bvh_build::AUTO_INSTANCING_BYTES`]) traces them as instances of one
    /// mesh instead, as [`Renderer::prepare_moving`] with no moving object does.
    pub fn prepare(&self, scene: &Scene) -> PreparedScene {
        hyrt_cpu::bvh_build::prepare_scene(scene, self.preset)
    }

    /// [`Renderer::prepare`] for a scene whose objects `moving` (by id) move between
    /// frames: they are traced in their own space through a two-level BVH, so that
    /// [`PreparedScene::move_objects`] moves them (after their transforms change in the
    /// scene) without preparing the scene again. Both backends render it, bit for bit
    /// alike (the GPU needs 9 storage buffers per shader stage for it).
    pub fn prepare_moving(&self, scene: &Scene, moving: &[u32]) -> PreparedScene {
        hyrt_cpu::bvh_build::prepare_moving(scene, self.preset, moving)
    }

    /// Render one frame of `width` x `height` pixels.
    pub fn render(
        &mut self,
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
        &mut self,
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
        self.backend_mut().render_into(prepared, &record, options, frame)
    }
}

/// Write a frame's final image as an 8-bit sRGB PNG ([`Frame::final_srgb8`]).
pub fn save_png(frame: &Frame, path: &std::path::Path) -> Result<(), Error> {
    image_io::write_png(path, frame.width, frame.height, &frame.final_image)
}

/// Write a frame's final image as a linear 32-bit float OpenEXR file, unclamped: the
/// frame's values bit for bit ([`image_io::write_exr`]).
pub fn save_exr(frame: &Frame, path: &std::path::Path) -> Result<(), Error> {
    image_io::write_exr(path, frame.width, frame.height, &frame.final_image)
}
