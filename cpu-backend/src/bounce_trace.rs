//! Stage `bounce_trace`: trace the reflection and refraction rays of one bounce through
//! the BVH of the whole scene (closest hit, ties to the lower triangle index) and
//! rebuild the surfaces they hit from the hits' barycentrics (paper eq. 1 again,
//! [`hyrt_core::kernels::reconstruction::reconstruct_hit`]), on the side each ray saw
//! (the sign of the watertight determinant).
//!
//! Inputs: the rays of depth `d`, the BVH, triangles and normals. Outputs: one
//! [`HitRecord`] and one [`SurfaceRecord`] per ray (`MISS` where it left the scene).
//! The rays are traced by [`crate::traversal`]: SIMD packets of consecutive rays by
//! default (the rays of one parent's neighbours are neighbours in the list, so
//! reflections off one mirror stay coherent), the scalar `Bvh::closest_hit` as the
//! reference; both give the same hits, and both test alpha on alpha-tested triangles
//! (packets where the single-ray path was asked for: it does not).

use glam::Vec3;
use hyrt_core::bvh::two_level::TwoLevelBvh;
use hyrt_core::bvh::{Bvh, ClosestHit};
use hyrt_core::formats::{HitRecord, RayRecord, SurfaceRecord};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::reconstruction::{reconstruct_hit, secondary_normal_mapped};
use hyrt_core::kernels::texture::Materials;
use rayon::prelude::*;

use crate::traversal::{closest_hit_alpha_batch_into, closest_hit_in_object_space_into, Traversal};

/// The stage into caller-owned buffers; `closest` is scratch kept between frames. With
/// `levels` (a scene with object-space instances) `bvh` is its world-space level, traced
/// first with `traversal`, then every ray goes through the object-space instances.
#[allow(clippy::too_many_arguments)]
pub fn bounce_trace_into(
    bvh: &Bvh,
    levels: Option<&TwoLevelBvh>,
    geometry: &WorldGeometry,
    materials: &Materials,
    rays: &[RayRecord],
    traversal: Traversal,
    closest: &mut Vec<Option<ClosestHit>>,
    hits: &mut Vec<HitRecord>,
    surfaces: &mut Vec<SurfaceRecord>,
) {
    closest_hit_alpha_batch_into(bvh, geometry.traversal_table(), &geometry.surface.view(), rays, traversal, closest);
    if let Some(levels) = levels {
        // The object-space pass: from each ray's hit in the world-space level, the closer
        // hit over the object-space instances (in packets; the scalar
        // `TwoLevelBvh::closest_hit_in_object_space` for the scalar reference).
        closest_hit_in_object_space_into(levels, &geometry.surface.view(), rays, traversal, closest);
    }
    closest.par_iter().with_min_len(4096).map(|&h| HitRecord::from_hit(h)).collect_into_vec(hits);
    rays.par_iter()
        .zip(hits.par_iter())
        .with_min_len(1024)
        .map(|(r, h)| reconstruct_hit(h, geometry, Vec3::from(r.direction)))
        .collect_into_vec(surfaces);
    if materials.normal_mapped_any() {
        surfaces
            .par_iter_mut()
            .zip(rays.par_iter().zip(hits.par_iter()))
            .with_min_len(1024)
            .for_each(|(s, (r, h))| *s = secondary_normal_mapped(r, h, s, materials));
    }
    if cfg!(debug_assertions) {
        for (i, (h, s)) in hits.iter().zip(surfaces.iter()).enumerate() {
            if let Err(e) = h.validate().and_then(|()| s.validate()) {
                panic!("bounce_trace: ray {i}: {e}");
            }
        }
    }
}
