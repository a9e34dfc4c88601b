//! Stage `bvh_build`: build the BVH over the whole scene (once per scene, not per frame).
//!
//! A thin wrapper over [`Bvh::build`]: the builder and the flattened layout live in
//! `hyrt_core::bvh` so that both backends trace the very same tree (conformance then
//! compares kernels, not builders).

use hyrt_core::bvh::two_level::TwoLevelBvh;
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::frame::PreparedScene;
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::scene::Scene;

/// Build the scene's BVH with an obvhs preset ([`BvhPreset::default`] unless the user
/// asks otherwise). Deterministic; validated in debug builds.
pub fn bvh_build(geometry: &WorldGeometry, preset: BvhPreset) -> Bvh {
    Bvh::build(geometry, preset)
}

/// A scene ready to render: `bvh_build` over `geometry`, timed, on the current rayon
/// pool (the global one unless called inside a pool's `install`). Needs no backend:
/// both backends render the same prepared scene.
pub fn prepare(geometry: WorldGeometry, preset: BvhPreset) -> PreparedScene {
    let t = std::time::Instant::now();
    let bvh = bvh_build(&geometry, preset);
    PreparedScene::new(geometry, bvh, t.elapsed().as_secs_f64() * 1e3)
}

/// [`prepare`] for a scene whose objects `moving` (by id) move between frames: a
/// two-level BVH ([`TwoLevelBvh`]) with those objects, and every object sharing its mesh
/// with another, in object space, the rest baked into the world-space level; the
/// `bvh_build` stage times both levels. Move them with
/// [`PreparedScene::move_objects`](hyrt_core::frame::PreparedScene::move_objects).
pub fn prepare_moving(scene: &Scene, geometry: WorldGeometry, preset: BvhPreset, moving: &[u32]) -> PreparedScene {
    let t = std::time::Instant::now();
    let mut flags = vec![false; scene.objects.len()];
    for &o in moving {
        if let Some(f) = flags.get_mut(o as usize) {
            *f = true;
        }
    }
    let levels = TwoLevelBvh::build(scene, &geometry, preset, &flags);
    PreparedScene::with_levels(geometry, levels, t.elapsed().as_secs_f64() * 1e3)
}
