//! Stage `shadow_rays`: trace the compacted shadow-ray list through the BVH (paper 3.3),
//! any hit with early exit.
//!
//! Each ray is independent, so the list is cut into fixed-size chunks traced in parallel
//! with rayon; the output is the same whatever the thread count.

use rayon::prelude::*;

use hyrt_core::bvh::Bvh;
use hyrt_core::formats::RayRecord;
use hyrt_core::geometry::WorldGeometry;

/// [`shadow_rays`] output value: something lies between the ray origin and the light.
pub const SHADOW_OCCLUDED: u32 = 1;
/// [`shadow_rays`] output value: the light is visible.
pub const SHADOW_VISIBLE: u32 = 0;

/// Rays per rayon task: large enough to amortize scheduling (a few microseconds of work
/// per chunk), small enough to balance uneven rays across threads.
pub const SHADOW_RAY_CHUNK: usize = 1024;

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
    let triangles = &geometry.triangles;
    out.clear();
    out.resize(rays.len(), SHADOW_VISIBLE);
    out.par_chunks_mut(SHADOW_RAY_CHUNK).zip(rays.par_chunks(SHADOW_RAY_CHUNK)).for_each(|(out, rays)| {
        for (o, ray) in out.iter_mut().zip(rays) {
            if cfg!(debug_assertions) {
                if let Err(e) = ray.validate() {
                    panic!("shadow_rays: invalid ray: {e}");
                }
            }
            *o = if bvh.occluded(triangles, ray) { SHADOW_OCCLUDED } else { SHADOW_VISIBLE };
        }
    });
}
