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
//!
//! The shaders are WGSL; where the device offers wgpu's passthrough they reach the driver
//! as SPIR-V hyrt writes from them ([`spirv`]: every float operation `NoContraction`, the
//! device's float-controls modes declared), else as WGSL through wgpu.

pub mod backend;
pub mod band;
pub mod bounce_shading;
pub mod bounce_trace;
pub mod buffers;
pub mod compaction;
pub mod composition;
pub mod context;
pub mod error;
pub mod exact;
pub mod gpu_buffer;
pub mod paging;
pub mod present;
pub mod raster_shading;
pub mod reconstruction;
pub mod rt_shading;
pub mod scan;
pub mod secondary_rays;
pub mod shader;
pub mod shadow_denoise;
pub mod shadow_rays;
pub mod spirv;
pub mod texture;
pub mod timing;
pub mod visibility_raster;
mod wgsl;
pub mod world_triangles;

pub use context::{AdapterPolicy, GpuContext};
pub use error::GpuError;
/// The wgpu hyrt is built on, for applications that share its device and textures.
pub use wgpu;
