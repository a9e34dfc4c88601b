//! Stage `bvh_build`: build the BVH over the whole scene (once per scene, not per frame).
//!
//! A thin wrapper over [`Bvh::build`]: the builder and the flattened layout live in
//! `hyrt_core::bvh` so that both backends trace the very same tree (conformance then
//! compares kernels, not builders).

use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::geometry::WorldGeometry;

/// Build the scene's BVH with an obvhs preset ([`BvhPreset::default`] unless the user
/// asks otherwise). Deterministic; validated in debug builds.
pub fn bvh_build(geometry: &WorldGeometry, preset: BvhPreset) -> Bvh {
    Bvh::build(geometry, preset)
}
