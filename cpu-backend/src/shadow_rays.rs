//! Stage `shadow_rays`: trace the compacted shadow-ray list through the BVH (paper 3.3),
//! any hit with early exit.
//!
//! The rays are traced by [`crate::traversal`]: by default in SIMD packets of consecutive
//! rays ([`Traversal::simd`]), with the scalar `Bvh::occluded` kept as
//! [`Traversal::Scalar`]; both give the same answer for every ray. The list is cut into
//! fixed-size chunks traced in parallel with rayon; the output is the same whatever the
//! thread count.
//!
//! In a scene with alpha-tested materials every ray is traced by the scalar
//! `Bvh::occluded_filtered`, which tests the alpha of each hit on such a triangle
//! ([`hyrt_core::kernels::texture::alpha_accepts`]) before taking it: the SIMD packets
//! do not test alpha yet, and a scene without alpha tests never takes this path.

use hyrt_core::bvh::Bvh;
use hyrt_core::formats::{RayRecord, SurfaceRecord};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::texture::alpha_accepts;
use rayon::prelude::*;

use crate::compaction::pair_ray;
use crate::traversal::{occluded_batch_into, occluded_generated_into, Traversal};

/// [`shadow_rays`] output value: something lies between the ray origin and the light.
pub const SHADOW_OCCLUDED: u32 = 1;
/// [`shadow_rays`] output value: the light is visible.
pub const SHADOW_VISIBLE: u32 = 0;

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
    if geometry.surface.alpha_tested() {
        return occluded_alpha_tested_into(bvh, geometry, rays.len(), |i| rays[i], out);
    }
    occluded_batch_into(bvh, &geometry.triangles, rays, traversal, out);
}

/// Any hit of `count` rays (`ray(i)`) with the alpha test, by the scalar traversal
/// (module docs), in chunks of `crate::traversal::TRAVERSAL_CHUNK` in parallel.
fn occluded_alpha_tested_into(
    bvh: &Bvh,
    geometry: &WorldGeometry,
    count: usize,
    ray: impl Fn(usize) -> RayRecord + Sync,
    out: &mut Vec<u32>,
) {
    let view = geometry.surface.view();
    let accept = |t: &_, global: u32, u, v| alpha_accepts(&view, t, global as usize, u, v);
    out.resize(count, SHADOW_VISIBLE);
    out.par_iter_mut().enumerate().with_min_len(crate::traversal::TRAVERSAL_CHUNK).for_each(|(i, o)| {
        let hit = bvh.occluded_filtered(&geometry.triangles, &ray(i), accept);
        *o = if hit { SHADOW_OCCLUDED } else { SHADOW_VISIBLE };
    });
}

/// [`shadow_rays_with`] over the rays of active pairs (`compaction::active_pairs_into`:
/// `k = light * surfaces.len() + surface`), each made as it is traced
/// (`compaction::pair_ray`): the same answers as tracing the list `compaction` writes,
/// without the list.
pub fn shadow_rays_of_pairs_into(
    bvh: &Bvh,
    geometry: &WorldGeometry,
    surfaces: &[SurfaceRecord],
    active: &[u32],
    traversal: Traversal,
    out: &mut Vec<u32>,
) {
    let lights = &geometry.lights;
    let ray = |i: usize| {
        let r = pair_ray(surfaces, lights, active[i]);
        debug_assert_eq!(r.validate(), Ok(()), "shadow_rays: invalid ray");
        r
    };
    if geometry.surface.alpha_tested() {
        return occluded_alpha_tested_into(bvh, geometry, active.len(), ray, out);
    }
    occluded_generated_into(bvh, &geometry.triangles, active.len(), ray, traversal, out);
}
