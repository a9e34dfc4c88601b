//! # hyrt-core
//!
//! The shared heart of hyrt, a hybrid rasterization + ray-tracing renderer
//! (after Sabino et al., "Efficient Use of In-Game Ray-Tracing Techniques", SBGames 2011).
//!
//! * [`scene`]: meshes, objects, materials, lights, the camera, and the loaders
//!   (glTF 2.0, the TOML scene manifest, the built-in default scene).
//! * [`geometry`]: the world-space triangle table both backends and the BVH read.
//! * [`formats`]: every buffer that crosses to the GPU, `#[repr(C)]` + `Pod`,
//!   size-asserted and documented to the byte.
//! * [`kernels`]: small pure functions that *are* the specification: the CPU
//!   backend calls them, the WGSL shaders mirror them by name.
//! * [`bvh`]: the flattened, GPU-ready BVH built with obvhs, and its reference traversal.
//! * [`stage`]: the stage names, used for modules, timing labels and tests.
//! * [`plan`]: what each stage reads and writes, and the [`plan::FramePlan`] of
//!   the stages a frame of a given scene needs.
//!
//! ```
//! use hyrt_core::scene::Scene;
//! let scene = Scene::default_scene();
//! assert!(scene.objects.len() >= 6);
//! let geometry = hyrt_core::geometry::WorldGeometry::build(&scene);
//! assert!(geometry.triangle_count() > 0);
//! ```

pub mod bvh;
pub mod error;
pub mod formats;
pub mod frame;
pub mod geometry;
pub mod kernels;
pub mod memory;
mod options;
pub mod plan;
mod prepared;
pub mod scene;
pub mod stage;

pub use error::{AnimationError, GpuError, SceneError};
pub use glam;
