//! The tile loops of [`visibility_raster`](super) with AVX-512 (F, VL, DQ, BW): the depth
//! test of a span and the texels of a run of one winner, eight pixels at a time. Every
//! lane does the scalar kernels' operations in their order, each one correctly rounded
//! IEEE 754 f32 operation (`VCVTQQ2PS` is Rust's `i64 as f32`, round to nearest even; no
//! fused multiply-add, no approximate reciprocal), so the G-buffer is bit-identical to the
//! scalar path's (the unit tests compare both). Only reached after run-time detection
//! ([`SimdLevel::Avx512`](crate::traversal::SimdLevel)).

use std::arch::x86_64::*;

use hyrt_core::formats::GBufferTexel;
use hyrt_core::kernels::raster::INTERIOR_DEPTH_BIAS_ULPS;

use super::{
    rasterize_tile_with, resolve_tile, AlphaTests, Fragment, FragmentSink, RasterTriangle, Resolve, SetupTriangles,
    Span, TexelRun, TileScratch, NOT_CORNERS, TILE_PIXELS,
};

/// Pixels per vector.
const LANES: usize = 8;
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
    rasterize_tile_with(tris, tile, rect, Avx512Sink(scratch), alpha);
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

/// The bit mask of the first `n` lanes (`n` at least 1).
#[inline(always)]
fn first_lanes(n: usize) -> __mmask8 {
    (u32::MAX >> (32 - n.min(LANES))) as __mmask8
}

/// The depth test of [`TileScratch`], a span at a time.
struct Avx512Sink<'a>(&'a mut TileScratch);

impl FragmentSink for Avx512Sink<'_> {
    /// One vector covers a row of up to eight pixels: no walks below that.
    const NARROW_BOX_WIDTH: i64 = LANES as i64;

    #[inline(always)]
    fn early(&self, i: usize, approx_depth: f64) -> bool {
        self.0.early(i, approx_depth)
    }

    #[inline(always)]
    fn fragment(&mut self, i: usize, t: &Fragment<'_>, e: [i64; 3]) {
        self.0.fragment(i, t, e);
    }

    /// Every pixel's exact depth (no early rejection: eight exact depths cost about
    /// what the approximate ones would), tested and stored as `TileScratch::fragment`
    /// does: `interpolate_depth`, `depth_test_value`, LESS and `d >= 0`.
    #[inline(always)]
    fn span(&mut self, span: &Span, t: &Fragment<'_>) {
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
            let jump = s.step_x.map(|d| _mm512_set1_epi64(d * LANES as i64));
            let bias = s.bias.map(|b| _mm512_set1_epi64(b));
            let z = t.z.map(|z| _mm256_set1_ps(z));
            let area = _mm256_set1_ps(t.area2 as f32);
            let zero = _mm256_setzero_ps();
            let one = _mm256_set1_ps(1.0);
            let abs_mask = _mm256_set1_epi32(i32::MAX);
            let ulps = _mm256_set1_epi32(INTERIOR_DEPTH_BIAS_ULPS as i32);
            let reference = _mm256_set1_epi32(t.reference as i32);
            let depth = self.0.depth.as_mut_ptr();
            let winner = self.0.winner.as_mut_ptr();
            let mut j = 0;
            while j < span.len {
                let mut live = first_lanes(span.len - j);
                if !span.covered {
                    let any = _mm512_or_si512(_mm512_or_si512(e[0], e[1]), e[2]);
                    live &= _mm512_cmpge_epi64_mask(any, _mm512_setzero_si512());
                }
                if live != 0 {
                    // interpolate_depth: ((f(e0) z0 + f(e1) z1) + f(e2) z2) / f(area2),
                    // from the exact (unbiased) values.
                    let f = |k: usize| _mm512_cvtepi64_ps(_mm512_sub_epi64(e[k], bias[k]));
                    let num = _mm256_add_ps(
                        _mm256_add_ps(_mm256_mul_ps(f(0), z[0]), _mm256_mul_ps(f(1), z[1])),
                        _mm256_mul_ps(f(2), z[2]),
                    );
                    let d = _mm256_div_ps(num, area);
                    // depth_test_value: an interior side's non-negative depth is pushed
                    // back by INTERIOR_DEPTH_BIAS_ULPS steps of |d|, at most 1.0 (MINPS
                    // gives 1.0 for a NaN, as f32::min). Other lanes keep d; lanes with
                    // d < 0 or NaN never store.
                    let key = if t.interior {
                        let stepped = _mm256_add_epi32(_mm256_and_si256(_mm256_castps_si256(d), abs_mask), ulps);
                        _mm256_min_ps(_mm256_castsi256_ps(stepped), one)
                    } else {
                        d
                    };
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
    /// `perspective_barycentrics` (`q_i = f(e_i) / w_i`, `s = (q0 + q1) + q2`,
    /// `b_i = q_i / s`), then `barycentrics_in_original` (`(b0 a0 + b1 a1) + b2 a2`) or the
    /// corners' weights, per lane.
    #[inline(always)]
    fn run(t: &RasterTriangle, e: [i64; 3], step: [i64; 3], depth: &[f32], out: &mut [GBufferTexel]) {
        debug_assert_eq!(depth.len(), out.len());
        // SAFETY: only compiled into `tile` (AVX-512 F, VL, DQ, BW); the stores write the
        // local arrays.
        unsafe {
            let mut e = [lanes_from(e[0], step[0]), lanes_from(e[1], step[1]), lanes_from(e[2], step[2])];
            let jump = step.map(|d| _mm512_set1_epi64(d * LANES as i64));
            let w = t.w.map(|w| _mm256_set1_ps(w));
            let attr = |k: usize| t.bary.map(|a| _mm256_set1_ps(a[k]));
            let (au, av) = (attr(0), attr(1));
            let mut u = [0.0f32; LANES];
            let mut v = [0.0f32; LANES];
            for (out, depth) in out.chunks_mut(LANES).zip(depth.chunks(LANES)) {
                let q = [0, 1, 2].map(|k| _mm256_div_ps(_mm512_cvtepi64_ps(e[k]), w[k]));
                let sum = _mm256_add_ps(_mm256_add_ps(q[0], q[1]), q[2]);
                let b = q.map(|q| _mm256_div_ps(q, sum));
                let (bu, bv) = if t.corners == NOT_CORNERS {
                    let mix = |a: [__m256; 3]| {
                        _mm256_add_ps(
                            _mm256_add_ps(_mm256_mul_ps(b[0], a[0]), _mm256_mul_ps(b[1], a[1])),
                            _mm256_mul_ps(b[2], a[2]),
                        )
                    };
                    (mix(au), mix(av))
                } else {
                    (b[t.corners[0] as usize], b[t.corners[1] as usize])
                };
                _mm256_storeu_ps(u.as_mut_ptr(), bu);
                _mm256_storeu_ps(v.as_mut_ptr(), bv);
                for (k, (texel, &stored)) in out.iter_mut().zip(depth).enumerate() {
                    *texel = t.texel(u[k], v[k], stored);
                }
                for k in 0..3 {
                    e[k] = _mm512_add_epi64(e[k], jump[k]);
                }
            }
        }
    }
}
