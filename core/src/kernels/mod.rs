//! Core kernels: small pure functions that are the specification of every stage.
//! The CPU backend calls them; each WGSL function of the GPU backend mirrors one
//! by name and says so in a comment.

pub mod area_light;
pub mod barycentric;
pub mod bounce;
pub mod camera;
pub mod denoise;
pub mod environment;
pub mod exact;
pub mod ibl;
pub mod instance;
pub mod occlusion;
pub mod raster;
pub mod ray;
pub mod reconstruction;
pub mod sampling;
pub mod scan;
pub mod shading;
pub mod shadow;
pub mod soft_shadow;
pub mod temporal;
pub mod texture;
pub mod tone_map;
