//! What a caller of the GPU backend cannot foresee: no adapter, a device that
//! could not be created or was lost, out of memory, a failed readback.

/// A GPU backend failure.
#[derive(Debug, thiserror::Error)]
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
