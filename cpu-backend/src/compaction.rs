//! Stage `compaction`: active (pixel, light) pairs -> the shadow-ray list
//! (paper 3.3: one thread per active ray, no idle threads for missed pixels).
//!
//! Inputs: the surface buffer and the light list (with area lights and ambient occlusion,
//! the mask slots of [`hyrt_core::kernels::soft_shadow`]: a pair is then a (pixel, slot),
//! one per light sample or occlusion ray). Output: [`RayRecord`]s, light-major (slot-major)
//! then in pixel order (neighbouring rays go to the same light from neighbouring pixels,
//! which keeps traversal coherent).
//!
//! The compaction itself ([`compact`]) is a parallel, stable, deterministic
//! exclusive prefix sum over u32 flags; it equals
//! [`hyrt_core::kernels::scan::compact_sequential`] for every input. The per-pair
//! kernels ([`needs_shadow_ray`], [`shadow_ray`](hyrt_core::kernels::shadow::shadow_ray))
//! are [`hyrt_core::kernels::shadow`]'s.
//!
//! A frame that does not return a ray list (no `FrameOptions::stage_outputs`: the
//! primary hits' list and every bounce depth's) does not write it: the stage keeps the
//! active pairs ([`active_pairs_into`], 4 bytes a ray instead of 64), and `shadow_rays`
//! makes each pair's ray as it traces it ([`pair_ray`], the same record bit for bit), a
//! chunk at a time in cache (`shadow_rays::shadow_rays_of_pairs_into`).
//!
//! `lanes` has the same per-pair kernels over eight surfaces at once, for the fused
//! tiles (`crate::fused`): the same bits, lane by lane.

use std::collections::TryReserveError;
use std::sync::atomic::{AtomicU8, Ordering};

use hyrt_core::formats::{LightRecord, RayRecord, SurfaceRecord, INVALID_ID, SHADOW_NO_RAY};
use hyrt_core::kernels::shadow::shadow_code;
use hyrt_core::kernels::soft_shadow::{AmbientOcclusion, Slots};
use rayon::prelude::*;

pub(crate) mod lanes;

/// Kernels of [`hyrt_core::kernels::shadow`], re-exported at their old path for the
/// `hyrt` crate's accuracy tools.
pub use hyrt_core::kernels::shadow::{needs_shadow_ray, SHADOW_T_MAX_POINT};

/// Flags per block of the parallel scan. A multiple of 64 so blocks align with
/// cache lines; large enough that the sequential scan over block sums is cheap.
pub const COMPACTION_BLOCK: usize = 4096;

/// Indices of the non-zero `flags`, in increasing order: a parallel exclusive
/// scan over per-block counts, then a parallel scatter. Stable and deterministic.
/// Panics where the allocator refuses the output (frames use the fallible
/// [`compact_into`]).
pub fn compact(flags: &[u32]) -> Vec<u32> {
    let mut out = Vec::new();
    compact_into(flags, &mut out).unwrap_or_else(|e| panic!("compact: {e}"));
    out
}

/// [`compact`] into a caller-owned buffer, reusing its allocation; an error (and `out`
/// left empty) where the allocator cannot hold the indices.
pub fn compact_into(flags: &[u32], out: &mut Vec<u32>) -> Result<(), TryReserveError> {
    let counts: Vec<u32> =
        flags.par_chunks(COMPACTION_BLOCK).map(|c| c.iter().filter(|&&f| f != 0).count() as u32).collect();
    let (offsets, total) = hyrt_core::kernels::scan::exclusive_scan_sums(&counts);
    out.clear();
    crate::memory::reserve(out, total as usize)?;
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
    Ok(())
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
/// Panics where the allocator refuses the list (frames use the fallible
/// [`compaction_into`]).
pub fn compaction(surfaces: &[SurfaceRecord], lights: &[LightRecord]) -> Vec<RayRecord> {
    let mut rays = Vec::new();
    compaction_into(surfaces, lights, &mut CompactionScratch::default(), &mut rays)
        .unwrap_or_else(|e| panic!("compaction: {e}"));
    rays
}

/// [`compaction`] into caller-owned buffers, reusing their allocations; an error where
/// the allocator cannot hold the flags, the indices or the list (the frame then fails
/// with `RenderError::OutOfMemory` instead of aborting).
pub fn compaction_into(
    surfaces: &[SurfaceRecord],
    lights: &[LightRecord],
    scratch: &mut CompactionScratch,
    rays: &mut Vec<RayRecord>,
) -> Result<(), TryReserveError> {
    compaction_slots_into(surfaces, &Slots::new(lights, &AmbientOcclusion::default()), scratch, rays)
}

/// [`compaction_into`] over a frame's mask slots (area lights' samples, occlusion rays):
/// one ray per active (pixel, slot) pair, its `light` field the slot.
pub fn compaction_slots_into(
    surfaces: &[SurfaceRecord],
    slots: &Slots,
    scratch: &mut CompactionScratch,
    rays: &mut Vec<RayRecord>,
) -> Result<(), TryReserveError> {
    active_pairs_into(surfaces, slots, scratch)?;
    crate::memory::reserve(rays, scratch.active.len())?;
    scratch.active.par_iter().with_min_len(1024).map(|&k| pair_ray(surfaces, slots, k)).collect_into_vec(rays);
    if cfg!(debug_assertions) {
        for r in rays.iter() {
            if let Err(e) = r.validate() {
                panic!("compaction: {e}");
            }
        }
    }
    Ok(())
}

/// The stage without its list: the active pairs `k = slot * surfaces + surface`, in
/// the list's order, into `scratch.active` (each pair's ray is [`pair_ray`]). A scene of
/// point, spot and directional lights without occlusion has a slot per light.
pub fn active_pairs_into(
    surfaces: &[SurfaceRecord],
    slots: &Slots,
    scratch: &mut CompactionScratch,
) -> Result<(), TryReserveError> {
    let n = surfaces.len();
    crate::memory::reserve(&mut scratch.flags, n * slots.len())?;
    scratch.flags.clear();
    scratch.flags.resize(n * slots.len(), 0);
    // Slot-major, as the pairs are numbered: slot `l`'s flags are the `l`-th run of `n`.
    if n > 0 {
        scratch.flags.par_chunks_mut(n).enumerate().for_each(|(l, flags)| {
            flags.par_iter_mut().with_min_len(4096).zip(surfaces).for_each(|(f, s)| *f = slots.needs_ray(s, l) as u32);
        });
    }
    compact_into(&scratch.flags, &mut scratch.active)
}

/// The shadow ray of active pair `k = slot * surfaces.len() + surface`.
#[inline]
pub fn pair_ray(surfaces: &[SurfaceRecord], slots: &Slots, k: u32) -> RayRecord {
    let n = surfaces.len();
    let (l, p) = (k as usize / n, k as usize % n);
    slots.ray(&surfaces[p], l, p as u32)
}

/// Scatter the traced shadow rays back to a per-(pixel, light) mask of
/// `SHADOW_*` values, indexed `pixel * lights + light` (with area lights or occlusion,
/// `lights` is the slots per surface and a ray's `light` its slot).
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
    debug_assert!(rays.iter().all(|r| r.light != INVALID_ID));
    scatter_mask(occluded, |i| (rays[i].pixel as usize, rays[i].light as usize), pixels, lights, mask);
}

/// [`shadow_mask_into`] of rays given by their active pairs ([`active_pairs_into`]:
/// `k = light * pixels + pixel`, increasing).
pub fn shadow_mask_of_pairs_into(active: &[u32], occluded: &[u32], pixels: usize, lights: usize, mask: &mut Vec<u8>) {
    assert_eq!(active.len(), occluded.len(), "one occlusion result per ray");
    debug_assert!(active.windows(2).all(|w| w[0] < w[1]), "shadow_mask: pairs not increasing");
    let pair = |i: usize| (active[i] as usize % pixels.max(1), active[i] as usize / pixels.max(1));
    scatter_mask(occluded, pair, pixels, lights, mask);
}

/// Write `shadow_code(occluded[i])` at the (pixel, light) cell `pair(i)` of each ray `i`
/// (every cell at most once), `SHADOW_NO_RAY` elsewhere.
fn scatter_mask(
    occluded: &[u32],
    pair: impl Fn(usize) -> (usize, usize) + Sync,
    pixels: usize,
    lights: usize,
    mask: &mut Vec<u8>,
) {
    mask.clear();
    mask.resize(pixels * lights, SHADOW_NO_RAY);
    // SAFETY: `AtomicU8` has the size, alignment and bit validity of `u8`, and `mask` stays
    // mutably borrowed while `cells` lives (what the unstable `AtomicU8::from_mut_slice`
    // does). Relaxed stores are plain byte stores; the scope's join orders them before
    // the return.
    let cells: &[AtomicU8] = unsafe { &*(mask.as_mut_slice() as *mut [u8] as *const [AtomicU8]) };
    occluded.par_iter().enumerate().with_min_len(4096).for_each(|(i, &o)| {
        let (pixel, light) = pair(i);
        cells[pixel * lights + light].store(shadow_code(o != 0), Ordering::Relaxed);
    });
}
