//! Every buffer that crosses between stages and, later, to the GPU.
//!
//! Rules for this module (see `code-style-anchors.md`):
//! * `#[repr(C)]` + [`bytemuck::Pod`], sizes asserted at compile time;
//! * documented field by field with byte offsets, so a WGSL `struct` can be
//!   written from the comment alone (all fields are 4-byte scalars: WGSL `f32`/`u32`,
//!   no `vec3` padding rules are involved);
//! * a `validate()` that the stages call under `debug_assertions`;
//! * fields listed once more for WGSL (`wgsl_struct!`, checked against the Rust layout):
//!   the shaders' structs are generated from them ([`wgsl::declarations`]).

mod bvh;
mod placement;
mod records;
mod textures;
pub mod wgsl;

pub use bvh::*;
pub use placement::*;
pub use records::*;
pub use textures::*;

/// Marker for "no id" in every u32 id field (triangle, object, pixel, light).
pub const INVALID_ID: u32 = u32::MAX;
