//! What a caller of the GPU backend cannot foresee: no adapter, a device that
//! could not be created or was lost, out of memory, a failed readback.
//!
//! The enum lives in `hyrt_core::error` so that [`hyrt_core::frame::RenderError::Gpu`]
//! carries it typed; this module re-exports it under its old path.

pub use hyrt_core::error::GpuError;
