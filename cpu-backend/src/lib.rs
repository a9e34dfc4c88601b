//! # hyrt-cpu
//!
//! The CPU backend: every stage of the hybrid pipeline on rayon, the bit-exact
//! reference the GPU backend is tested against and the renderer users fall back
//! on without a GPU. One module per stage, named as in [`hyrt_core::stage::Stage`];
//! each stage is a function from its declared inputs to its declared outputs.
//!
//! Two executors run a frame's plan over those stages ([`hyrt_core::frame::Executor`]):
//! [`backend`]'s staged loop (stage after stage over whole-image buffers, the reference)
//! and [`fused`]'s tiles (every step after `visibility_raster` per screen tile, in cache).
//! Both call each stage's per-pixel kernels; neither has a stage's logic of its own.

pub mod backend;
pub mod bounce_shading;
pub mod bounce_trace;
pub mod bvh_build;
pub mod compaction;
pub mod composition;
pub mod fused;
pub(crate) mod lanes;
pub mod memory;
pub mod raster_shading;
pub mod reconstruction;
pub mod rt_shading;
pub mod secondary_rays;
pub mod shadow_denoise;
pub mod shadow_rays;
pub mod traversal;
pub mod visibility_raster;
