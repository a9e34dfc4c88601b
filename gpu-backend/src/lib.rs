//! # hyrt-gpu
//!
//! The GPU backend: the same stages as the CPU reference, with the same names,
//! over the same [`hyrt_core::formats`], in wgpu (a hardware raster pass for
//! `visibility_raster`, compute shaders for the rest). Each WGSL function
//! mirrors a core kernel by name and says so.
//!
//! [`context::GpuContext`] picks the adapter: Vulkan only (asked for
//! explicitly, so a missing driver never falls back to GL silently), hardware
//! preferred; a software adapter (Mesa lavapipe) only when the caller allows it
//! ([`context::AdapterPolicy::AllowSoftware`], or `HYRT_GPU_ALLOW_SOFTWARE=1`).

pub mod buffers;
pub mod context;
pub mod error;
pub mod gpu_buffer;
pub mod reconstruction;
pub mod visibility_raster;

pub use context::{AdapterPolicy, GpuContext};
pub use error::GpuError;
