//! The tile loops of [`visibility_raster`](super) with AVX2: the depth test of a span and
//! the texels of a run of one winner, eight pixels at a time, as the AVX-512 kernel does
//! ([`avx512`](super::avx512), the f32 maths shared in [`lanes`](super::lanes)), every
//! lane the scalar kernels' operations in their order, each one correctly rounded IEEE 754
//! f32 operation, so the G-buffer is bit-identical to the scalar path's (the unit tests
//! compare all kernels). Only reached after run-time detection
//! ([`SimdLevel::Avx2`](crate::traversal::SimdLevel)).
//!
//! AVX2 has no `VCVTQQ2PS`, AVX-512's `i64 as f32`. Each span and run therefore picks the
//! exact conversion its edge values allow ([`Conversion`]): i32 lanes where every value
//! fits, i64 lanes converted through f64 below 2^51, else the scalar kernel.

use std::arch::x86_64::*;

use hyrt_core::formats::GBufferTexel;

use super::lanes::{edges, first_lanes, texels, DepthLanes, LaneSink, SpanLanes, LANES};
use super::{
    rasterize_tile_with, resolve_tile, span_scalar, AlphaTests, Fragment, RasterTriangle, Resolve, ScalarTexels,
    SetupTriangles, Span, TexelRun, TileScratch, TILE_PIXELS,
};

/// Rasterize and resolve one tile (see `raster_frame`); returns the hit count.
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
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
    rasterize_tile_with(tris, tile, rect, LaneSink::<Avx2Spans>::new(scratch), alpha);
    resolve_tile::<Avx2Texels>(tris, scratch, rect, rows, resolve)
}

/// How the edge values of a span or run (each edge's lanes `first + k * step`, `k` below
/// its length rounded up to whole vectors) become f32 exactly as `edge_value_to_f32`
/// (`e as f32`: the exact integer rounded once, to nearest, ties to even) does. Chosen
/// per span and run from the largest magnitude among its lanes, at the first or the last
/// lane (the values are linear in `k`), so every path is exact by construction:
///
/// - [`Conversion::I32`], every `|e| < 2^31 - 1`: i32 lanes (exact: the i64 values
///   truncated to 32 bits, stepped in wrapping 32-bit arithmetic, are the values again as
///   they fit), and `VCVTDQ2PS` rounds the exact integer once under MXCSR's
///   round-to-nearest-even (the mode Rust assumes).
/// - [`Conversion::F64`], every `|e| < 2^51`: i64 lanes; adding `e` to the bits of
///   `1.5 * 2^52` puts `2^51 + e`, in `[0, 2^52)`, in the mantissa without a carry, so that
///   double is `1.5 * 2^52 + e` and subtracting `1.5 * 2^52` gives `e` exactly (both have
///   an ulp of 1); `VCVTPD2PS` then rounds that exact value once, to nearest even: the f32
///   of the integer. (An f64 that had rounded would round twice.)
/// - [`Conversion::Scalar`] beyond: the scalar kernels.
///
/// Which applies when. An edge value is `2^16 |edge| dist` (fixed point, 8 fractional
/// bits: the edge's length and the pixel centre's distance from its line, in pixels), and
/// at a covered pixel centre the three lie in `[0, area2]` (they are non-negative and add up
/// to `area2`, `2^17` times the triangle's area in pixels). Covered runs (every span of a
/// box wider than [`LANES`], every resolve run) take i32 lanes for triangles under `2^14`
/// pixels of area, less the few lanes past the run's end; f64 lanes for triangles under
/// `2^34` pixels (every triangle whose vertices lie in an image of up to `2^17` pixels a
/// side); the spans of narrow boxes (eight pixels at most, some outside the triangle) lie
/// within the box's width of it. The scalar fallback is left to triangles reaching far into the guard band: by
/// the ranges of `hyrt_core::kernels::raster` edge values stay below `2^61`, so clipped
/// triangles near the eye, vertices up to `2^20` pixels out, go there (the unit tests'
/// ground plane does).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Conversion {
    I32,
    F64,
    Scalar,
}

/// Largest `|e|` of [`Conversion::I32`]: one below `i32::MAX`, so that the biased values
/// the depth test steps (`e + bias`, `bias` 0 or -1) fit too.
const I32_MAX_ABS: u64 = (1 << 31) - 2;
/// Largest `|e|` of [`Conversion::F64`]: the magic-number conversion covers `[-2^51, 2^51)`.
const F64_MAX_ABS: u64 = (1 << 51) - 1;
/// `1.5 * 2^52`: its mantissa holds `2^51 + e` for the magic-number conversion.
const F64_MAGIC: f64 = (3u64 << 51) as f64;

impl Conversion {
    /// The conversion that is exact for the lanes `first[i] + k * step[i]` of every edge
    /// `i`, `k` below `len` rounded up to whole vectors.
    #[inline(always)]
    fn of(first: [i64; 3], step: [i64; 3], len: usize) -> Conversion {
        let steps = (len.next_multiple_of(LANES) - 1) as i64;
        let largest = (0..3).map(|i| first[i].unsigned_abs().max((first[i] + step[i] * steps).unsigned_abs())).max();
        let c = match largest.unwrap_or(0) {
            m if m <= I32_MAX_ABS => Conversion::I32,
            m if m <= F64_MAX_ABS => Conversion::F64,
            _ => Conversion::Scalar,
        };
        #[cfg(test)]
        tests::TAKEN.with(|n| n[c as usize].set(n[c as usize].get() + 1));
        c
    }
}

/// Eight lanes of exact edge values, held as their [`Conversion`] needs them.
trait EdgeLanes: Copy {
    /// The lanes `first + k * step` (`k` = 0 to 7).
    fn new(first: i64, step: i64) -> Self;
    /// Every lane `v`.
    fn splat(v: i64) -> Self;
    fn add(self, other: Self) -> Self;
    fn or(self, other: Self) -> Self;
    /// Bit `k` set where lane `k` is negative.
    fn negative(self) -> u8;
    /// Each lane as `edge_value_to_f32` gives it.
    fn to_f32(self) -> __m256;
}

/// [`Conversion::I32`]'s lanes.
#[derive(Clone, Copy)]
struct I32Lanes(__m256i);

impl EdgeLanes for I32Lanes {
    #[inline(always)]
    fn new(first: i64, step: i64) -> Self {
        // SAFETY: only compiled into `tile` (AVX2); no memory access. Wrapping 32-bit
        // arithmetic is exact modulo 2^32, and the lanes' values fit.
        unsafe {
            let k = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
            I32Lanes(_mm256_add_epi32(
                _mm256_set1_epi32(first as i32),
                _mm256_mullo_epi32(k, _mm256_set1_epi32(step as i32)),
            ))
        }
    }
    #[inline(always)]
    fn splat(v: i64) -> Self {
        // SAFETY: as in `new`.
        unsafe { I32Lanes(_mm256_set1_epi32(v as i32)) }
    }
    #[inline(always)]
    fn add(self, other: Self) -> Self {
        // SAFETY: as in `new`.
        unsafe { I32Lanes(_mm256_add_epi32(self.0, other.0)) }
    }
    #[inline(always)]
    fn or(self, other: Self) -> Self {
        // SAFETY: as in `new`.
        unsafe { I32Lanes(_mm256_or_si256(self.0, other.0)) }
    }
    #[inline(always)]
    fn negative(self) -> u8 {
        // SAFETY: as in `new`.
        unsafe { _mm256_movemask_ps(_mm256_castsi256_ps(self.0)) as u8 }
    }
    #[inline(always)]
    fn to_f32(self) -> __m256 {
        // SAFETY: as in `new`.
        unsafe { _mm256_cvtepi32_ps(self.0) }
    }
}

/// [`Conversion::F64`]'s lanes: i64, lanes 0 to 3 and 4 to 7.
#[derive(Clone, Copy)]
struct F64Lanes([__m256i; 2]);

impl EdgeLanes for F64Lanes {
    #[inline(always)]
    fn new(first: i64, step: i64) -> Self {
        // SAFETY: only compiled into `tile` (AVX2); no memory access.
        unsafe {
            let low = _mm256_setr_epi64x(first, first + step, first + 2 * step, first + 3 * step);
            F64Lanes([low, _mm256_add_epi64(low, _mm256_set1_epi64x(4 * step))])
        }
    }
    #[inline(always)]
    fn splat(v: i64) -> Self {
        // SAFETY: as in `new`.
        unsafe { F64Lanes([_mm256_set1_epi64x(v); 2]) }
    }
    #[inline(always)]
    fn add(self, other: Self) -> Self {
        // SAFETY: as in `new`.
        unsafe { F64Lanes([_mm256_add_epi64(self.0[0], other.0[0]), _mm256_add_epi64(self.0[1], other.0[1])]) }
    }
    #[inline(always)]
    fn or(self, other: Self) -> Self {
        // SAFETY: as in `new`.
        unsafe { F64Lanes([_mm256_or_si256(self.0[0], other.0[0]), _mm256_or_si256(self.0[1], other.0[1])]) }
    }
    #[inline(always)]
    fn negative(self) -> u8 {
        // SAFETY: as in `new`.
        unsafe {
            let half = |h: usize| _mm256_movemask_pd(_mm256_castsi256_pd(self.0[h])) as u8;
            half(0) | (half(1) << 4)
        }
    }
    #[inline(always)]
    fn to_f32(self) -> __m256 {
        // SAFETY: as in `new`.
        unsafe {
            let magic = _mm256_set1_pd(F64_MAGIC);
            let half = |h: usize| {
                let exact = _mm256_castsi256_pd(_mm256_add_epi64(self.0[h], _mm256_castpd_si256(magic)));
                _mm256_cvtpd_ps(_mm256_sub_pd(exact, magic))
            };
            _mm256_set_m128(half(1), half(0))
        }
    }
}

/// A vector of all-ones lanes where `bits` has the lane's bit.
#[inline(always)]
fn lane_mask(bits: u8) -> __m256 {
    // SAFETY: only compiled into `tile` (AVX2); no memory access.
    unsafe {
        let bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(bits as i32), bit), bit))
    }
}

/// The depth test of [`TileScratch`], a span at a time, by the span's [`Conversion`].
struct Avx2Spans;

impl SpanLanes for Avx2Spans {
    #[inline(always)]
    fn span(scratch: &mut TileScratch, span: &Span, t: &Fragment<'_>) {
        let s = &t.stepper;
        let raw = edges(|i| span.e[i] - s.bias[i]);
        match Conversion::of(raw, s.step_x, span.len) {
            Conversion::I32 => span_lanes::<I32Lanes>(scratch, span, t),
            Conversion::F64 => span_lanes::<F64Lanes>(scratch, span, t),
            Conversion::Scalar => span_scalar(scratch, span, t),
        }
    }
}

/// Every pixel's exact depth (no early rejection: eight exact depths cost about what the
/// approximate ones would), tested and stored as `TileScratch::fragment` does:
/// `interpolate_depth`, `depth_test_value`, LESS and `d >= 0` ([`DepthLanes::depth`]).
#[inline(always)]
fn span_lanes<L: EdgeLanes>(scratch: &mut TileScratch, span: &Span, t: &Fragment<'_>) {
    let s = &t.stepper;
    debug_assert!(span.base + span.len <= TILE_PIXELS);
    let mut e = edges(|i| L::new(span.e[i], s.step_x[i]));
    let jump = edges(|i| L::splat(s.step_x[i] * LANES as i64));
    let unbias = edges(|i| L::splat(-s.bias[i]));
    let lanes = DepthLanes::new(t);
    let depth = scratch.depth.as_mut_ptr();
    let winner = scratch.winner.as_mut_ptr().cast::<f32>();
    // SAFETY: only compiled into `tile` (AVX2). The full loads and stores touch pixels
    // `base + j` to `base + j + 7`, below TILE_PIXELS, of the tile's own buffers (those past
    // the span keep their values); the masked ones lanes `base + j + k` with `k` below
    // `span.len - j`, inside them (`base + len <= TILE_PIXELS`).
    unsafe {
        let zero = _mm256_setzero_ps();
        let reference = _mm256_castsi256_ps(_mm256_set1_epi32(t.reference as i32));
        let mut j = 0;
        while j < span.len {
            let mut live = first_lanes(span.len - j);
            if !span.covered {
                live &= !e[0].or(e[1]).or(e[2]).negative();
            }
            if live != 0 {
                let (d, key) = lanes.depth(edges(|i| e[i].add(unbias[i]).to_f32()));
                let live = lane_mask(live);
                let at = span.base + j;
                let wins = |stored| {
                    let better = _mm256_cmp_ps::<_CMP_LT_OQ>(key, stored);
                    _mm256_and_ps(_mm256_and_ps(live, better), _mm256_cmp_ps::<_CMP_GE_OQ>(d, zero))
                };
                if at + LANES <= TILE_PIXELS {
                    let stored = _mm256_loadu_ps(depth.add(at));
                    let wins = wins(stored);
                    if _mm256_movemask_ps(wins) != 0 {
                        _mm256_storeu_ps(depth.add(at), _mm256_blendv_ps(stored, key, wins));
                        let old = _mm256_loadu_ps(winner.add(at));
                        _mm256_storeu_ps(winner.add(at), _mm256_blendv_ps(old, reference, wins));
                    }
                } else {
                    let stored = _mm256_maskload_ps(depth.add(at), _mm256_castps_si256(live));
                    let wins = _mm256_castps_si256(wins(stored));
                    _mm256_maskstore_ps(depth.add(at), wins, key);
                    _mm256_maskstore_ps(winner.add(at), wins, reference);
                }
            }
            e = edges(|i| e[i].add(jump[i]));
            j += LANES;
        }
    }
}

/// [`TexelRun`] eight texels at a time, by the run's [`Conversion`].
struct Avx2Texels;

impl TexelRun for Avx2Texels {
    #[inline(always)]
    fn run(t: &RasterTriangle, e: [i64; 3], step: [i64; 3], depth: &[f32], out: &mut [GBufferTexel]) {
        match Conversion::of(e, step, out.len()) {
            Conversion::I32 => texel_lanes::<I32Lanes>(t, e, step, depth, out),
            Conversion::F64 => texel_lanes::<F64Lanes>(t, e, step, depth, out),
            Conversion::Scalar => ScalarTexels::run(t, e, step, depth, out),
        }
    }
}

/// [`texels`] from lanes `L`.
#[inline(always)]
fn texel_lanes<L: EdgeLanes>(t: &RasterTriangle, e: [i64; 3], step: [i64; 3], depth: &[f32], out: &mut [GBufferTexel]) {
    let mut e = edges(|i| L::new(e[i], step[i]));
    let jump = edges(|i| L::splat(step[i] * LANES as i64));
    texels(t, depth, out, || {
        let f = edges(|i| e[i].to_f32());
        e = edges(|i| e[i].add(jump[i]));
        f
    });
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::cell::Cell;

    thread_local! {
        /// How often this thread chose each [`Conversion`].
        pub(super) static TAKEN: [Cell<usize>; 3] = const { [const { Cell::new(0) }; 3] };
    }

    /// How often this thread chose each [`Conversion`] so far: i32 lanes, f64 lanes, the
    /// scalar code.
    pub(in super::super) fn conversions_taken() -> [usize; 3] {
        TAKEN.with(|n| n.each_ref().map(Cell::get))
    }

    /// The eight lanes `first + k * step` through `L`.
    #[target_feature(enable = "avx2")]
    fn lanes_as_f32<L: EdgeLanes>(first: i64, step: i64) -> [f32; LANES] {
        let mut out = [0.0; LANES];
        // SAFETY: stores eight f32 into `out`.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), L::new(first, step).add(L::splat(0)).to_f32()) };
        out
    }

    /// The lanes `first + k * step` through the conversion [`Conversion::of`] picks, against
    /// `as f32` (`edge_value_to_f32`) bit for bit; returns the conversion.
    fn check(first: i64, step: i64) -> Conversion {
        let c = Conversion::of([first; 3], [step; 3], LANES);
        // SAFETY: the callers checked for AVX2.
        let got = match c {
            Conversion::I32 => unsafe { lanes_as_f32::<I32Lanes>(first, step) },
            Conversion::F64 => unsafe { lanes_as_f32::<F64Lanes>(first, step) },
            Conversion::Scalar => return c,
        };
        for (k, g) in got.into_iter().enumerate() {
            let e = first + k as i64 * step;
            assert_eq!(g.to_bits(), (e as f32).to_bits(), "{c:?}: {e} as f32");
        }
        c
    }

    /// The boundaries: exact below 2^24, ties to even above it (`2^24 + 1`, `2^25 + 2`,
    /// `2^31 - 64`, `2^50 + 2^26`, each with its neighbours), the i32 lanes' and the f64
    /// lanes' limits from both sides, signs, and 2^53 and beyond left to the scalar code.
    #[test]
    fn lane_conversions_round_as_rust_does() {
        if !is_x86_feature_detected!("avx2") {
            return;
        }
        let i32_max = I32_MAX_ABS as i64;
        let f64_max = F64_MAX_ABS as i64;
        for centre in [0, 1 << 24, (1 << 24) + 1, (1 << 25) + 2, (1 << 31) - 64, 1 << 31, (1 << 50) + (1 << 26)] {
            for first in centre - 3..=centre + 3 {
                for step in [1, -1, 0] {
                    assert_ne!(check(first, step), Conversion::Scalar, "{first} + k * {step}");
                    assert_ne!(check(-first, -step), Conversion::Scalar, "{} + k * {}", -first, -step);
                }
            }
        }
        for (first, step, want) in [
            (i32_max - 7, 1, Conversion::I32),
            (i32_max - 6, 1, Conversion::F64),
            (-i32_max, 1, Conversion::I32),
            (-i32_max - 1, 1, Conversion::F64),
            (-i32_max + 7, -1, Conversion::I32),
            (f64_max - 7, 1, Conversion::F64),
            (f64_max - 6, 1, Conversion::Scalar),
            (-f64_max, 1, Conversion::F64),
            (-f64_max - 1, 1, Conversion::Scalar),
            (1 << 53, 1, Conversion::Scalar),
            (-(1 << 60), 1 << 38, Conversion::Scalar),
            // Lanes on both sides of zero, and the largest steps.
            (-(1 << 30), 1 << 28, Conversion::I32),
            ((1 << 50) - 7 * (1 << 38), 1 << 38, Conversion::F64),
        ] {
            assert_eq!(check(first, step), want, "{first} + k * {step}");
            assert_eq!(check(-first, -step), want, "{} + k * {}", -first, -step);
        }
    }

    proptest! {
        /// Random lanes at every magnitude, through whichever conversion applies.
        #[test]
        fn lane_conversions_match_as_f32(bits in 0u32..62, mantissa in any::<i64>(), step in -(1i64 << 38)..(1 << 38)) {
            if is_x86_feature_detected!("avx2") {
                check(mantissa >> (63 - bits), step >> (38 - bits.min(38)));
            }
        }
    }
}
