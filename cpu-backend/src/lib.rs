//! # hyrt-cpu
//!
//! The CPU backend: every stage of the hybrid pipeline on rayon, the bit-exact
//! reference the GPU backend is tested against and the renderer users fall back
//! on without a GPU. One module per stage, named as in [`hyrt_core::stage::Stage`];
//! each stage is a function from its declared inputs to its declared outputs.

pub mod backend;
pub mod bounce_shading;
pub mod bounce_trace;
pub mod bvh_build;
pub mod compaction;
pub mod composition;
pub mod memory;
pub mod raster_shading;
pub mod reconstruction;
pub mod rt_shading;
pub mod secondary_rays;
pub mod shadow_rays;
pub mod traversal;
pub mod visibility_raster;
