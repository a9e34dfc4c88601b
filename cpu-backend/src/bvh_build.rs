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
/// with another, in object space, the rest baked into the world-space level. The objects
/// in object space are kept by reference in the world tables
/// ([`WorldGeometry::build_placed`]: their mesh once, however many objects draw it). The
/// `bvh_build` stage times both levels. Move them with
/// [`PreparedScene::move_objects`](hyrt_core::frame::PreparedScene::move_objects).
pub fn prepare_moving(scene: &Scene, preset: BvhPreset, moving: &[u32]) -> PreparedScene {
    let mut flags = vec![false; scene.objects.len()];
    for &o in moving {
        if let Some(f) = flags.get_mut(o as usize) {
            *f = true;
        }
    }
    let geometry = WorldGeometry::build_placed(scene, &TwoLevelBvh::object_space_objects(scene, &flags));
    let t = std::time::Instant::now();
    let levels = TwoLevelBvh::build(scene, &geometry, preset, &flags);
    PreparedScene::with_levels(geometry, levels, t.elapsed().as_secs_f64() * 1e3)
}

/// Bytes of world records and normals (84 per triangle) above which [`prepare_scene`]
/// traces meshes shared by several objects as instances instead of storing every copy:
/// 1 GiB, about 12.8 million stored triangles.
pub const AUTO_INSTANCING_BYTES: usize = 1 << 30;

/// What the facade's `Renderer::prepare` does: [`prepare`], unless the scene's copies of
/// shared meshes would take more than [`AUTO_INSTANCING_BYTES`] stored; then
/// [`prepare_moving`] with no moving object, so that every shared mesh is held once and
/// traced as instances (a scene of 1,000 dragons fits in memory). Scenes under the
/// threshold are prepared as they always were (the same frames, bit for bit).
pub fn prepare_scene(scene: &Scene, preset: BvhPreset) -> PreparedScene {
    if shared_mesh_bytes(scene) > AUTO_INSTANCING_BYTES {
        prepare_moving(scene, preset, &[])
    } else {
        prepare(WorldGeometry::build(scene), preset)
    }
}

/// Bytes the stored world records and normals of objects sharing their mesh would take.
pub fn shared_mesh_bytes(scene: &Scene) -> usize {
    let mut users = vec![0usize; scene.meshes.len()];
    for o in &scene.objects {
        users[o.mesh] += 1;
    }
    let per_triangle = hyrt_core::geometry::WorldTriangles::STORED_BYTES_PER_TRIANGLE;
    scene.objects.iter().filter(|o| users[o.mesh] > 1).map(|o| scene.meshes[o.mesh].indices.len() * per_triangle).sum()
}
