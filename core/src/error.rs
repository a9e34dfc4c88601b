//! Errors a caller cannot foresee: a file that does not exist, cannot be parsed,
//! or holds something hyrt cannot render (each names the file and the problem); and a
//! frame that cannot be rendered ([`RenderError`], [`GpuError`]).

use std::path::PathBuf;

/// Why a scene could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{path}: cannot read file: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The glTF file is malformed or refers to data that cannot be loaded.
    #[error("{path}: not a valid glTF 2.0 file: {message}")]
    Gltf { path: PathBuf, message: String },
    /// The TOML manifest does not parse or does not match the manifest schema.
    #[error("{path}: invalid scene manifest: {message}")]
    Manifest { path: PathBuf, message: String },
    /// An entry of a TOML manifest (a model file) could not be loaded. The message names the
    /// manifest, the entry (e.g. `model[1] 'bunny'`) and the underlying error, which names
    /// the model file.
    #[error("{path}: {entry}: {error}")]
    ManifestEntry {
        /// The manifest.
        path: PathBuf,
        /// The entry, e.g. `model[1] 'bunny'`.
        entry: String,
        /// Why it failed (an error naming the model file).
        error: Box<SceneError>,
    },
    /// The file parses but its content cannot be rendered (e.g. NaN vertex positions,
    /// indices out of range, a primitive mode other than triangles).
    #[error("{path}: {message}")]
    Content { path: PathBuf, message: String },
    /// The file extension is not one hyrt knows.
    #[error("{path}: unknown scene format (expected .glb, .gltf or .toml)")]
    UnknownFormat { path: PathBuf },
    /// An environment map file is not a Radiance HDR or OpenEXR image, or holds texels
    /// that cannot be rendered (zero size, a non-finite or negative channel). A file
    /// that cannot be read at all is [`SceneError::Io`].
    #[error("{path}: environment map: {problem}")]
    Environment {
        path: PathBuf,
        #[source]
        problem: EnvironmentMapError,
    },
}

/// Why texels cannot make an environment map.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EnvironmentMapError {
    /// The file extension is neither `.hdr` nor `.exr`.
    #[error("unknown environment map format (expected a Radiance .hdr or an OpenEXR .exr file)")]
    UnknownFormat,
    /// The file is not a readable image of its format.
    #[error("not a readable {format} image: {message}")]
    Decode {
        /// `Radiance HDR` or `OpenEXR`.
        format: &'static str,
        message: String,
    },
    /// The image has no texel.
    #[error("the image is empty ({width}x{height})")]
    ZeroSize { width: u32, height: u32 },
    /// The texel count is not `width * height`.
    #[error("{texels} texels for a {width}x{height} map")]
    SizeMismatch { width: u32, height: u32, texels: usize },
    /// A texel has a channel that is not finite, or is negative: radiance is neither.
    #[error("texel ({x}, {y}) is {rgb:?}: every channel must be finite and >= 0")]
    BadTexel { x: u32, y: u32, rgb: [f32; 3] },
    /// The file's header asks the decoder for more memory than an environment map may use.
    #[error("{what} would take {bytes} bytes, more than the {limit} bytes a decoded environment map may use")]
    TooLarge {
        /// What the header sizes (a layer's pixels, the output image, a block).
        what: String,
        /// The bytes it asks for (`usize::MAX` when the product overflows).
        bytes: usize,
        /// [`MAX_DECODED_MAP_BYTES`](crate::scene::environment::MAX_DECODED_MAP_BYTES).
        limit: usize,
    },
}

/// Why a scene could not be posed at a time of one of its animations ([`crate::scene::Scene::set_time`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnimationError {
    /// The scene has no animations (not a glTF file with `animations`).
    #[error("the scene has no animations")]
    NotAnimated,
    /// The animation index is out of range.
    #[error("animation {index} does not exist (the scene has {count})")]
    NoSuchAnimation { index: usize, count: usize },
    /// The pose leaves the camera or a directional light without a direction (a node scaled
    /// to zero, say); the scene is left as it was.
    #[error("animation '{animation}' at {time} s leaves the {what} of {node} degenerate (a zero scale?)")]
    Degenerate {
        animation: String,
        time: f32,
        /// The node, e.g. `node 3 'camera'`.
        node: String,
        /// `camera` or `directional light`.
        what: &'static str,
    },
}

/// A GPU backend failure: no adapter, a device that could not be created or was lost,
/// out of memory, a failed readback. Defined here, beside [`RenderError`]
/// which carries it typed ([`RenderError::Gpu`]), so a caller can match on
/// the kind of failure (fall back to the CPU on [`GpuError::DeviceLost`], say) without
/// downcasting; the GPU backend (`hyrt_gpu::GpuError`) re-exports it. Its messages are
/// strings because core does not depend on wgpu.
#[derive(Clone, Debug, thiserror::Error)]
pub enum GpuError {
    /// No Vulkan adapter at all (no driver, no GPU).
    #[error("no GPU adapter found (Vulkan); install a Vulkan driver, or use --backend cpu")]
    NoAdapter,
    /// Only software adapters exist and the policy asks for hardware.
    #[error(
        "only a software GPU adapter was found ({name}); set HYRT_GPU_ALLOW_SOFTWARE=1 to use it, or use --backend cpu"
    )]
    SoftwareOnly { name: String },
    /// The adapter refused the device (missing features or limits).
    #[error("cannot create a GPU device on {adapter}: {message}")]
    RequestDevice { adapter: String, message: String },
    /// The device was lost (driver reset, GPU removed).
    #[error("GPU device lost: {0}")]
    DeviceLost(String),
    /// A GPU allocation failed.
    #[error("GPU out of memory: {0}")]
    OutOfMemory(String),
    /// A wgpu validation error: a bug in hyrt, reported instead of a panic.
    #[error("GPU validation error (a hyrt bug, please report): {0}")]
    Validation(String),
    /// Mapping a buffer for readback failed.
    #[error("GPU readback failed: {0}")]
    Readback(String),
    /// The frame does not fit the device's limits (buffer size, dispatch size).
    #[error("frame exceeds GPU limits: {0}")]
    Limits(String),
}

/// Why a frame could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("invalid frame options: {0}")]
    InvalidOptions(String),
    #[error("invalid camera: {0}")]
    InvalidCamera(String),
    /// The backend cannot run a stage the frame's plan needs.
    #[error("the {backend} backend cannot run {stage} yet: {why}")]
    Unsupported { backend: &'static str, stage: String, why: &'static str },
    /// A frame that does not fit in memory: refused before its buffers are allocated
    /// (its least need exceeds what the system has available), or an allocation of one of
    /// its buffers failed. `needed` is in bytes (`None` where an allocation failed whose
    /// size the error does not carry); `available` is what the system reported (`None`:
    /// unknown).
    #[error(
        "a {width}x{height} frame does not fit in memory on the {backend} backend: {what}{}{}",
        match needed { Some(n) => format!(": {n} bytes needed"), None => String::new() },
        match available { Some(a) => format!(", {a} bytes available"), None => String::new() }
    )]
    OutOfMemory {
        backend: &'static str,
        width: u32,
        height: u32,
        needed: Option<u64>,
        available: Option<u64>,
        what: String,
    },
    /// The GPU backend's device failed: no adapter, device lost, out of memory, a
    /// readback that failed, a frame past the device's limits. Typed, so a caller can
    /// react to the kind (fall back to the CPU backend on a lost device, say).
    #[error(transparent)]
    Gpu(#[from] GpuError),
}
