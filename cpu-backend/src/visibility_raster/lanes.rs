//! What the SIMD tile kernels ([`avx2`](super::avx2), [`avx512`](super::avx512)) share: the
//! f32 maths of eight pixels at a time in 256-bit vectors, once each kernel has its lanes'
//! exact edge values as f32 (`edge_value_to_f32`, which each does its own way). Every lane
//! does the scalar kernel's operations in their order, one correctly rounded IEEE 754 f32
//! operation each (AVX: no fused multiply-add, no approximate reciprocal), so both kernels
//! give the scalar path's bits.

use std::arch::x86_64::*;

use hyrt_core::formats::GBufferTexel;
use hyrt_core::kernels::raster::INTERIOR_DEPTH_BIAS_ULPS;

use super::{Fragment, FragmentSink, RasterTriangle, Span, TileScratch, NOT_CORNERS};

/// Pixels per vector.
pub(super) const LANES: usize = 8;

/// `[f(0), f(1), f(2)]`, one per edge or vertex, spelt out: `array::map` and `from_fn` over
/// vectors can stay calls, compiled without the kernel's target features (one per intrinsic).
#[inline(always)]
pub(super) fn edges<T>(mut f: impl FnMut(usize) -> T) -> [T; 3] {
    [f(0), f(1), f(2)]
}

/// The bits of the first `n` lanes (`n` at least 1).
#[inline(always)]
pub(super) fn first_lanes(n: usize) -> u8 {
    (u32::MAX >> (32 - n.min(LANES))) as u8
}

/// A SIMD kernel's depth test of a span of [`TileScratch`].
pub(super) trait SpanLanes {
    /// What [`FragmentSink::span`] does for [`TileScratch`], the same depths and winners.
    fn span(scratch: &mut TileScratch, span: &Span, t: &Fragment<'_>);
}

/// The depth test of [`TileScratch`] with spans eight pixels at a time by `K`; single
/// fragments (masked triangles' in a frame with alpha tests) go to [`TileScratch`].
pub(super) struct LaneSink<'a, K>(&'a mut TileScratch, std::marker::PhantomData<K>);

impl<'a, K> LaneSink<'a, K> {
    #[inline(always)]
    pub(super) fn new(scratch: &'a mut TileScratch) -> Self {
        LaneSink(scratch, std::marker::PhantomData)
    }
}

impl<K: SpanLanes> FragmentSink for LaneSink<'_, K> {
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

    #[inline(always)]
    fn span(&mut self, span: &Span, t: &Fragment<'_>) {
        K::span(self.0, span, t);
    }
}

/// A triangle's depth-test constants, broadcast to the lanes.
pub(super) struct DepthLanes {
    z: [__m256; 3],
    area: __m256,
    interior: bool,
    one: __m256,
    abs_mask: __m256i,
    ulps: __m256i,
}

impl DepthLanes {
    #[inline(always)]
    pub(super) fn new(t: &RasterTriangle) -> DepthLanes {
        // SAFETY: only compiled into the SIMD kernels' `tile` (AVX2 at least); no memory access.
        unsafe {
            DepthLanes {
                z: edges(|k| _mm256_set1_ps(t.z[k])),
                area: _mm256_set1_ps(t.area2 as f32),
                interior: t.interior,
                one: _mm256_set1_ps(1.0),
                abs_mask: _mm256_set1_epi32(i32::MAX),
                ulps: _mm256_set1_epi32(INTERIOR_DEPTH_BIAS_ULPS as i32),
            }
        }
    }

    /// `(d, key)` per lane from the exact (unbiased) edge values as f32, `f`:
    /// `d` is `interpolate_depth`, `((f(e0) z0 + f(e1) z1) + f(e2) z2) / f(area2)`; `key`
    /// is `depth_test_value(d)`: an interior side's depth pushed back by
    /// `INTERIOR_DEPTH_BIAS_ULPS` steps of `|d|`, at most 1.0 (MINPS gives 1.0 for a NaN,
    /// as `f32::min`), other lanes `d`. Lanes with `d < 0` or NaN, where the two differ
    /// from the scalar `key`, must not store (the caller tests `d >= 0`).
    #[inline(always)]
    pub(super) fn depth(&self, f: [__m256; 3]) -> (__m256, __m256) {
        // SAFETY: only compiled into the SIMD kernels' `tile` (AVX2 at least); no memory access.
        unsafe {
            let num = _mm256_add_ps(
                _mm256_add_ps(_mm256_mul_ps(f[0], self.z[0]), _mm256_mul_ps(f[1], self.z[1])),
                _mm256_mul_ps(f[2], self.z[2]),
            );
            let d = _mm256_div_ps(num, self.area);
            let key = if self.interior {
                let stepped = _mm256_add_epi32(_mm256_and_si256(_mm256_castps_si256(d), self.abs_mask), self.ulps);
                _mm256_min_ps(_mm256_castsi256_ps(stepped), self.one)
            } else {
                d
            };
            (d, key)
        }
    }
}

/// [`TexelRun::run`](super::TexelRun::run) eight texels at a time: `next` gives the next
/// eight pixels' exact edge values as f32 (lanes past the run are computed and dropped).
/// Per lane `perspective_barycentrics` (`q_i = f(e_i) / w_i`, `s = (q0 + q1) + q2`,
/// `b_i = q_i / s`), then `barycentrics_in_original` (`(b0 a0 + b1 a1) + b2 a2`) or the
/// corners' weights (`perspective_barycentrics_of_corners`).
#[inline(always)]
pub(super) fn texels(
    t: &RasterTriangle,
    depth: &[f32],
    out: &mut [GBufferTexel],
    mut next: impl FnMut() -> [__m256; 3],
) {
    debug_assert_eq!(depth.len(), out.len());
    // SAFETY: only compiled into the SIMD kernels' `tile` (AVX2 at least); the stores write
    // the local arrays.
    unsafe {
        let w = edges(|k| _mm256_set1_ps(t.w[k]));
        let attr = |k: usize| edges(|i| _mm256_set1_ps(t.bary[i][k]));
        let (au, av) = (attr(0), attr(1));
        let mut u = [0.0f32; LANES];
        let mut v = [0.0f32; LANES];
        for (out, depth) in out.chunks_mut(LANES).zip(depth.chunks(LANES)) {
            let f = next();
            let q = edges(|k| _mm256_div_ps(f[k], w[k]));
            let sum = _mm256_add_ps(_mm256_add_ps(q[0], q[1]), q[2]);
            let b = edges(|k| _mm256_div_ps(q[k], sum));
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
        }
    }
}
