//! Stage `compaction`: active (pixel, light) pairs -> the shadow-ray list
//! (paper 3.3: one thread per active ray, no idle threads for missed pixels).
//!
//! Inputs: the surface buffer and the light list. Output: [`RayRecord`]s,
//! light-major then in pixel order (neighbouring rays go to the same light from
//! neighbouring pixels, which keeps traversal coherent).
//!
//! The compaction itself ([`compact`]) is a parallel, stable, deterministic
//! exclusive prefix sum over u32 flags; it equals
//! [`hyrt_core::kernels::scan::compact_sequential`] for every input.

use std::sync::atomic::{AtomicU8, Ordering};

use glam::Vec3;
use hyrt_core::formats::{LightRecord, RayRecord, SurfaceRecord, INVALID_ID, LIGHT_DIRECTIONAL, RAY_KIND_SHADOW};
use hyrt_core::frame::{SHADOW_LIT, SHADOW_NO_RAY, SHADOW_OCCLUDED};
use hyrt_core::kernels::ray::offset_ray_origin;
use hyrt_core::kernels::shading::{light_can_contribute, light_incidence};
use rayon::prelude::*;

/// Flags per block of the parallel scan. A multiple of 64 so blocks align with
/// cache lines; large enough that the sequential scan over block sums is cheap.
pub const COMPACTION_BLOCK: usize = 4096;

/// Shadow rays to point lights end just before the light: `t_max = 1 - 2^-16`
/// of the origin-to-light segment. A light sitting exactly on a surface (a hard
/// case) is then not occluded by that surface: the watertight test's t error is a
/// few ulp (pbrt-v4's gamma(3) conservative bound), far below 2^-16.
pub const SHADOW_T_MAX_POINT: f32 = 1.0 - 1.0 / 65536.0;

/// Indices of the non-zero `flags`, in increasing order: a parallel exclusive
/// scan over per-block counts, then a parallel scatter. Stable and deterministic.
pub fn compact(flags: &[u32]) -> Vec<u32> {
    let mut out = Vec::new();
    compact_into(flags, &mut out);
    out
}

/// [`compact`] into a caller-owned buffer, reusing its allocation.
pub fn compact_into(flags: &[u32], out: &mut Vec<u32>) {
    let counts: Vec<u32> =
        flags.par_chunks(COMPACTION_BLOCK).map(|c| c.iter().filter(|&&f| f != 0).count() as u32).collect();
    let (offsets, total) = hyrt_core::kernels::scan::exclusive_scan_sums(&counts);
    out.clear();
    out.resize(total as usize, 0);
    // Split the output into the disjoint ranges each block writes.
    let mut slices = Vec::with_capacity(counts.len());
    let mut rest: &mut [u32] = out;
    for &c in &counts {
        let (head, tail) = rest.split_at_mut(c as usize);
        slices.push(head);
        rest = tail;
    }
    flags.par_chunks(COMPACTION_BLOCK).zip(slices).enumerate().for_each(|(b, (chunk, dst))| {
        let base = b * COMPACTION_BLOCK;
        let mut k = 0;
        for (i, &f) in chunk.iter().enumerate() {
            if f != 0 {
                dst[k] = (base + i) as u32;
                k += 1;
            }
        }
        debug_assert_eq!(k, dst.len());
    });
    debug_assert_eq!(offsets.len(), counts.len());
}

/// Whether the pixel's surface needs a shadow ray towards `light`: it has a
/// primary hit and the light can contribute there (front side of both normals,
/// non-zero energy). The cheap test of the flag pass.
#[inline]
pub fn needs_shadow_ray(s: &SurfaceRecord, light: &LightRecord) -> bool {
    if !s.is_hit() {
        return false;
    }
    let (l, e) = light_incidence(light, Vec3::from(s.position));
    light_can_contribute(Vec3::from(s.geometric_normal), Vec3::from(s.normal), l, e)
}

/// The shadow ray from a surface point to a light. Call only where
/// [`needs_shadow_ray`] holds.
#[inline]
pub fn shadow_ray(s: &SurfaceRecord, light: &LightRecord, light_index: u32, pixel: u32) -> RayRecord {
    let p = Vec3::from(s.position);
    // Off the surface by the reconstructed point's own error bound, on the side the
    // viewer saw (the normal is oriented by reconstruction from the raster's facing).
    let origin = offset_ray_origin(p, s.position_error, Vec3::from(s.geometric_normal));
    let (direction, t_max) = if light.kind == LIGHT_DIRECTIONAL {
        (-Vec3::from(light.position_or_direction), f32::INFINITY)
    } else {
        (Vec3::from(light.position_or_direction) - origin, SHADOW_T_MAX_POINT)
    };
    RayRecord {
        origin: origin.into(),
        t_min: 0.0,
        direction: direction.into(),
        t_max,
        pixel,
        kind: RAY_KIND_SHADOW,
        depth: 0,
        light: light_index,
        throughput: [1.0; 3],
        pad: 0,
    }
}

/// Buffers [`compaction_into`] keeps between frames: the flags and the indices
/// of the active (light, pixel) pairs.
#[derive(Clone, Debug, Default)]
pub struct CompactionScratch {
    pub flags: Vec<u32>,
    pub active: Vec<u32>,
}

/// The stage: flag every (light, pixel) pair whose light can contribute at the
/// pixel's surface, compact the flags, and build one shadow ray per survivor.
pub fn compaction(surfaces: &[SurfaceRecord], lights: &[LightRecord]) -> Vec<RayRecord> {
    let mut rays = Vec::new();
    compaction_into(surfaces, lights, &mut CompactionScratch::default(), &mut rays);
    rays
}

/// [`compaction`] into caller-owned buffers, reusing their allocations.
pub fn compaction_into(
    surfaces: &[SurfaceRecord],
    lights: &[LightRecord],
    scratch: &mut CompactionScratch,
    rays: &mut Vec<RayRecord>,
) {
    let n = surfaces.len();
    (0..n * lights.len())
        .into_par_iter()
        .with_min_len(4096)
        .map(|k| {
            let (l, p) = (k / n, k % n);
            needs_shadow_ray(&surfaces[p], &lights[l]) as u32
        })
        .collect_into_vec(&mut scratch.flags);
    compact_into(&scratch.flags, &mut scratch.active);
    scratch
        .active
        .par_iter()
        .with_min_len(1024)
        .map(|&k| {
            let (l, p) = (k as usize / n, k as usize % n);
            shadow_ray(&surfaces[p], &lights[l], l as u32, p as u32)
        })
        .collect_into_vec(rays);
    if cfg!(debug_assertions) {
        for r in rays.iter() {
            if let Err(e) = r.validate() {
                panic!("compaction: {e}");
            }
        }
    }
}

/// Scatter the traced shadow rays back to a per-(pixel, light) mask of
/// `SHADOW_*` values, indexed `pixel * lights + light`.
pub fn shadow_mask(rays: &[RayRecord], occluded: &[u32], pixels: usize, lights: usize) -> Vec<u8> {
    let mut mask = Vec::new();
    shadow_mask_into(rays, occluded, pixels, lights, &mut mask);
    mask
}

/// [`shadow_mask`] into a caller-owned buffer, reusing its allocation.
///
/// In parallel: each ray writes its own (pixel, light) cell. The list must hold at most
/// one ray per pair, as compaction's does (its pairs strictly increase, checked in debug
/// builds); of two rays for one pair, either result could land.
pub fn shadow_mask_into(rays: &[RayRecord], occluded: &[u32], pixels: usize, lights: usize, mask: &mut Vec<u8>) {
    assert_eq!(rays.len(), occluded.len(), "one occlusion result per ray");
    debug_assert!(
        rays.windows(2).all(|w| (w[0].light, w[0].pixel) < (w[1].light, w[1].pixel)),
        "shadow_mask: rays not in compaction's order (light, then pixel, each pair once)"
    );
    mask.clear();
    mask.resize(pixels * lights, SHADOW_NO_RAY);
    // SAFETY: `AtomicU8` has the size, alignment and bit validity of `u8`, and `mask` stays
    // mutably borrowed while `cells` lives (what the unstable `AtomicU8::from_mut_slice`
    // does). Relaxed stores are plain byte stores; the scope's join orders them before
    // the return.
    let cells: &[AtomicU8] = unsafe { &*(mask.as_mut_slice() as *mut [u8] as *const [AtomicU8]) };
    rays.par_iter().zip(occluded).with_min_len(4096).for_each(|(r, &o)| {
        debug_assert!(r.light != INVALID_ID);
        let value = if o != 0 { SHADOW_OCCLUDED } else { SHADOW_LIT };
        cells[r.pixel as usize * lights + r.light as usize].store(value, Ordering::Relaxed);
    });
}
