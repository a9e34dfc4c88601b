//! The tile loops of [`visibility_raster`](super) with AVX-512 (F, VL, DQ, BW): the depth
//! test of a span and the texels of a run of one winner, eight pixels at a time. Every
//! lane does the scalar kernels' operations in their order, each one correctly rounded
//! IEEE 754 f32 operation (`VCVTQQ2PS` is Rust's `i64 as f32`, round to nearest even; no
//! fused multiply-add, no approximate reciprocal), so the G-buffer is bit-identical to the
//! scalar path's (the unit tests compare both). Only reached after run-time detection
//! ([`SimdLevel::Avx512`](crate::traversal::SimdLevel)).

use std::arch::x86_64::*;

use hyrt_core::formats::GBufferTexel;

use super::lanes::{edges, first_lanes, texels, DepthLanes, LaneSink, SpanLanes, LANES};
use super::{
    rasterize_tile_with, resolve_tile, AlphaTests, Fragment, RasterTriangle, Resolve, SetupTriangles, Span, TexelRun,
    TileScratch, TILE_PIXELS,
};

/// Pixel offsets of the lanes.
const LANE_OFFSETS: [i64; LANES] = [0, 1, 2, 3, 4, 5, 6, 7];

/// Rasterize and resolve one tile (see `raster_frame`); returns the hit count.
///
/// # Safety
/// The CPU must have AVX-512 F, VL, DQ and BW.
#[target_feature(enable = "avx2,avx512f,avx512vl,avx512dq,avx512bw")]
#[allow(clippy::too_many_arguments)]
pub(super) unsafe fn tile(
    tris: &SetupTriangles,
    tile: usize,
    rect: [i32; 4],
    scratch: &mut TileScratch,
    rows: Vec<&mut [GBufferTexel]>,
    alpha: Option<AlphaTests>,
    resolve: Resolve,
) -> usize {
    // Masked triangles (a frame with alpha tests) go pixel by pixel, the others eight at a time.
    rasterize_tile_with(tris, tile, rect, LaneSink::<Avx512Spans>::new(scratch), alpha);
    resolve_tile::<Avx512Texels>(tris, scratch, rect, rows, resolve)
}

/// `base + k * step` for the eight lanes `k` (`base` and `step` broadcast).
#[inline(always)]
fn lanes_from(base: i64, step: i64) -> __m512i {
    // SAFETY: only compiled into `tile` (AVX-512 F and DQ); the load reads 8 in-bounds i64.
    unsafe {
        let k = _mm512_loadu_si512(LANE_OFFSETS.as_ptr().cast());
        _mm512_add_epi64(_mm512_set1_epi64(base), _mm512_mullo_epi64(k, _mm512_set1_epi64(step)))
    }
}

/// The depth test of [`TileScratch`], a span at a time.
struct Avx512Spans;

impl SpanLanes for Avx512Spans {
    /// Every pixel's exact depth (no early rejection: eight exact depths cost about
    /// what the approximate ones would), tested and stored as `TileScratch::fragment`
    /// does: `interpolate_depth`, `depth_test_value`, LESS and `d >= 0`.
    #[inline(always)]
    fn span(scratch: &mut TileScratch, span: &Span, t: &Fragment<'_>) {
        let s = &t.stepper;
        debug_assert!(span.base + span.len <= TILE_PIXELS);
        // SAFETY: only compiled into `tile` (AVX-512 F, VL, DQ, BW). The masked loads and
        // stores touch lanes `base + j + k` with `k` below `span.len - j`, inside the tile
        // buffers (`base + len <= TILE_PIXELS`).
        unsafe {
            let e0 = lanes_from(span.e[0], s.step_x[0]);
            let e1 = lanes_from(span.e[1], s.step_x[1]);
            let e2 = lanes_from(span.e[2], s.step_x[2]);
            let mut e = [e0, e1, e2];
            let jump = edges(|k| _mm512_set1_epi64(s.step_x[k] * LANES as i64));
            let bias = edges(|k| _mm512_set1_epi64(s.bias[k]));
            let lanes = DepthLanes::new(t);
            let zero = _mm256_setzero_ps();
            let reference = _mm256_set1_epi32(t.reference as i32);
            let depth = scratch.depth.as_mut_ptr();
            let winner = scratch.winner.as_mut_ptr();
            let mut j = 0;
            while j < span.len {
                let mut live = first_lanes(span.len - j);
                if !span.covered {
                    let any = _mm512_or_si512(_mm512_or_si512(e[0], e[1]), e[2]);
                    live &= _mm512_cmpge_epi64_mask(any, _mm512_setzero_si512());
                }
                if live != 0 {
                    // From the exact (unbiased) values.
                    let (d, key) = lanes.depth(edges(|k| _mm512_cvtepi64_ps(_mm512_sub_epi64(e[k], bias[k]))));
                    let at = span.base + j;
                    let stored = _mm256_maskz_loadu_ps(live, depth.add(at));
                    let wins = live
                        & _mm256_cmp_ps_mask::<_CMP_LT_OQ>(key, stored)
                        & _mm256_cmp_ps_mask::<_CMP_GE_OQ>(d, zero);
                    _mm256_mask_storeu_ps(depth.add(at), wins, key);
                    _mm256_mask_storeu_epi32(winner.add(at).cast(), wins, reference);
                }
                for k in 0..3 {
                    e[k] = _mm512_add_epi64(e[k], jump[k]);
                }
                j += LANES;
            }
        }
    }
}

/// [`TexelRun`] eight texels at a time.
struct Avx512Texels;

impl TexelRun for Avx512Texels {
    /// [`texels`] from the lanes' `VCVTQQ2PS`.
    #[inline(always)]
    fn run(t: &RasterTriangle, e: [i64; 3], step: [i64; 3], depth: &[f32], out: &mut [GBufferTexel]) {
        // SAFETY: only compiled into `tile` (AVX-512 F, VL, DQ, BW); no memory access.
        unsafe {
            let mut e = [lanes_from(e[0], step[0]), lanes_from(e[1], step[1]), lanes_from(e[2], step[2])];
            let jump = edges(|k| _mm512_set1_epi64(step[k] * LANES as i64));
            texels(t, depth, out, || {
                let f = edges(|k| _mm512_cvtepi64_ps(e[k]));
                for k in 0..3 {
                    e[k] = _mm512_add_epi64(e[k], jump[k]);
                }
                f
            });
        }
    }
}
