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

/// A scene ready to render: `bvh_build` over `geometry`, timed, on the current rayon
/// pool (the global one unless called inside a pool's `install`). Needs no backend:
/// both backends render the same prepared scene.
pub fn prepare(geometry: WorldGeometry, preset: BvhPreset) -> hyrt_core::frame::PreparedScene {
    let t = std::time::Instant::now();
    let bvh = bvh_build(&geometry, preset);
    hyrt_core::frame::PreparedScene::new(geometry, bvh, t.elapsed().as_secs_f64() * 1e3)
}
