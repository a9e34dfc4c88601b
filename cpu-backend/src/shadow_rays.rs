//! Stage `shadow_rays`: trace the compacted shadow-ray list through the BVH (paper 3.3),
//! any hit with early exit.
//!
//! The rays are traced by [`crate::traversal`]: by default in SIMD packets of consecutive
//! rays ([`Traversal::simd`]), with the scalar `Bvh::occluded` kept as
//! [`Traversal::Scalar`]; both give the same answer for every ray. The list is cut into
//! fixed-size chunks traced in parallel with rayon; the output is the same whatever the
//! thread count.
//!
//! In a scene with alpha-tested materials a hit on such a triangle counts only where its
//! texel passes ([`hyrt_core::kernels::texture::alpha_accepts`]): the packets and the
//! scalar reference both test it (`crate::traversal::occluded_alpha_batch_into`).

use hyrt_core::bvh::two_level::TwoLevelBvh;
use hyrt_core::bvh::Bvh;
use hyrt_core::formats::{RayRecord, SurfaceRecord};
use hyrt_core::geometry::WorldGeometry;

use crate::compaction::pair_ray;
use crate::traversal::{
    occluded_alpha_batch_into, occluded_generated_into, occluded_in_object_space_into, occluded_pairs_tiled_into,
    Traversal,
};
use hyrt_core::kernels::soft_shadow::Slots;

/// [`shadow_rays`] output values, the traversal's any-hit answers: re-exported from
/// [`crate::traversal`], which makes them.
pub use crate::traversal::{SHADOW_OCCLUDED, SHADOW_VISIBLE};

/// Trace every ray (any hit with `t_min < t < t_max`). Returns one u32 per ray, in ray
/// order: [`SHADOW_OCCLUDED`] or [`SHADOW_VISIBLE`]. Rays are checked with
/// [`RayRecord::validate`] in debug builds (an invalid ray is a bug of the stage that
/// made it); in release builds an invalid ray is reported visible.
pub fn shadow_rays(bvh: &Bvh, geometry: &WorldGeometry, rays: &[RayRecord]) -> Vec<u32> {
    let mut out = Vec::new();
    shadow_rays_into(bvh, geometry, rays, &mut out);
    out
}

/// [`shadow_rays`] into a caller-owned buffer, reusing its allocation.
pub fn shadow_rays_into(bvh: &Bvh, geometry: &WorldGeometry, rays: &[RayRecord], out: &mut Vec<u32>) {
    shadow_rays_with(bvh, geometry, rays, Traversal::simd(), out)
}

/// [`shadow_rays_into`] with an explicit traversal (scalar reference or packets).
pub fn shadow_rays_with(
    bvh: &Bvh,
    geometry: &WorldGeometry,
    rays: &[RayRecord],
    traversal: Traversal,
    out: &mut Vec<u32>,
) {
    if cfg!(debug_assertions) {
        if let Some(e) = rays.iter().find_map(|r| r.validate().err()) {
            panic!("shadow_rays: invalid ray: {e}");
        }
    }
    occluded_alpha_batch_into(bvh, geometry.traversal_table(), &geometry.surface.view(), rays, traversal, out);
}

/// [`shadow_rays_with`] over the rays of active pairs (`compaction::active_pairs_into`:
/// `k = slot * surfaces.len() + surface`, over the frame's mask `slots`), each made as it is traced
/// (`compaction::pair_ray`): the same answers as tracing the list `compaction` writes,
/// without the list.
///
/// With `image_width`, `surfaces` are the pixels of an image that wide and the rays are
/// traced in packets of pixel tiles (`crate::traversal::occluded_pairs_tiled_into`:
/// the same answers, faster). A list given as such ([`shadow_rays_with`]: a frame that
/// keeps its stage outputs, the peers of `hyrt bench`) is traced in its own order: copying
/// its 64-byte records into tile order cost more than the tiles saved on the teaser and
/// Sponza.
#[allow(clippy::too_many_arguments)]
pub fn shadow_rays_of_pairs_into(
    bvh: &Bvh,
    geometry: &WorldGeometry,
    surfaces: &[SurfaceRecord],
    slots: &Slots,
    active: &[u32],
    image_width: Option<u32>,
    traversal: Traversal,
    out: &mut Vec<u32>,
) {
    let ray = |i: usize| {
        let r = pair_ray(surfaces, slots, active[i]);
        debug_assert_eq!(r.validate(), Ok(()), "shadow_rays: invalid ray");
        r
    };
    let (table, view) = (geometry.traversal_table(), &geometry.surface.view());
    match image_width {
        Some(width) => {
            let pixels = surfaces.len() as u32;
            occluded_pairs_tiled_into(bvh, table, view, active, pixels, width, ray, traversal, out)
        }
        None => occluded_generated_into(bvh, table, view, active.len(), ray, traversal, out),
    }
}

/// The object-space pass of a scene with moving objects (or shared meshes): after
/// [`shadow_rays_with`] or [`shadow_rays_of_pairs_into`] traced the world-space level
/// (`PreparedScene::bvh`), trace the rays it found visible through the object-space
/// instances of `levels` (`crate::traversal::occluded_in_object_space_into`: packets at
/// the SIMD level of `traversal`, or one ray at a time with
/// [`TwoLevelBvh::occluded_in_object_space`] for the scalar reference). `ray(i)` makes ray
/// `i` as the first pass did. Together: any hit over the whole scene.
pub fn shadow_rays_in_object_space(
    levels: &TwoLevelBvh,
    geometry: &WorldGeometry,
    ray: impl Fn(usize) -> RayRecord + Sync,
    traversal: Traversal,
    out: &mut [u32],
) {
    occluded_in_object_space_into(levels, &geometry.surface.view(), ray, traversal, out);
}
