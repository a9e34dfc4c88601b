//! Eight f32 lanes, three ways: AVX2 (`__m256`, chosen at run time), SSE2 (two `__m128`,
//! the x86-64 baseline) and plain arrays (any target). The traversal and the fused frame's
//! per-pixel kernels (`reconstruction`, `compaction`, `rt_shading`, `raster_shading`,
//! `composition`) are written once, generic over [`Lanes`], and every operation here is one
//! IEEE 754 f32 operation per lane (no fused multiply-add, no approximate reciprocal), an
//! exact conversion between f32 and i32, or a bit operation, so all three give the bits of
//! the scalar kernels lane by lane.
//!
//! `max`/`min` have the x86 `MAXPS`/`MINPS` semantics `a > b ? a : b` / `a < b ? a : b`:
//! a NaN in `a` (or equal values, `+0` vs `-0` included) gives `b`. That is exactly the
//! running `if candidate > acc { acc = candidate }` of
//! [`ray_aabb_conservative`](hyrt_core::kernels::ray::ray_aabb_conservative) with
//! `a = candidate, b = acc`.

use hyrt_core::formats::{RayRecord, TriangleRecord};

/// Lanes per packet.
pub const LANES: usize = 8;
/// Bit mask of all lanes.
pub const ALL_LANES: u32 = (1 << LANES) - 1;

/// Eight f32 lanes; masks are lanes with all bits set (true) or clear (false).
pub(crate) trait Lanes: Copy {
    type F: Copy;
    /// Whether the packet walks are compiled once per ray octant at this level
    /// (`octant_walk!`): the AVX2 and AVX-512 levels the stages run. The SSE2 and portable
    /// levels, fallbacks for CPUs without AVX2, walk with the octant read at run time and
    /// spare the build the copies: `hyrt-cpu`'s release build 57 s against 2m25 with them
    /// (1m13 since object-space instances take the octant walks too), for SSE2 walks about
    /// 5 to 8% slower (one thread, `ray_contest --simd sse2`: the teaser's reflections 31 to
    /// 33.5 ms single, the dragon's shadow rays 89 to 94 ms in packets).
    const OCTANT_WALKS: bool = false;
    fn splat(x: f32) -> Self::F;
    fn load(a: &[f32; LANES]) -> Self::F;
    fn store(v: Self::F) -> [f32; LANES];
    fn add(a: Self::F, b: Self::F) -> Self::F;
    fn sub(a: Self::F, b: Self::F) -> Self::F;
    fn mul(a: Self::F, b: Self::F) -> Self::F;
    fn div(a: Self::F, b: Self::F) -> Self::F;
    /// The correctly rounded square root per lane (IEEE 754, as `f32::sqrt`).
    fn sqrt(a: Self::F) -> Self::F;
    /// `a > b ? a : b` per lane.
    fn max(a: Self::F, b: Self::F) -> Self::F;
    /// `a < b ? a : b` per lane.
    fn min(a: Self::F, b: Self::F) -> Self::F;
    fn lt(a: Self::F, b: Self::F) -> Self::F;
    fn le(a: Self::F, b: Self::F) -> Self::F;
    fn eq(a: Self::F, b: Self::F) -> Self::F;
    fn and(a: Self::F, b: Self::F) -> Self::F;
    fn or(a: Self::F, b: Self::F) -> Self::F;
    /// `!a & b`.
    fn andnot(a: Self::F, b: Self::F) -> Self::F;
    /// For lanes holding integers of magnitude at most 2^24, the signs of `a * b - c * d`,
    /// exactly: the lanes where it is negative and those where it is zero, as bit masks
    /// (lane `i` is bit `i`). Computed in f64: each product (below 2^48) is exact, and the
    /// difference of two exact values is correctly rounded, so it is negative or zero
    /// exactly when the exact value is.
    fn cross_sign_bits(a: Self::F, b: Self::F, c: Self::F, d: Self::F) -> (u32, u32);
    /// All ones where the lanes' bit patterns are equal (an integer comparison: NaN
    /// patterns such as `INVALID_ID` compare as words).
    fn eq_bits(a: Self::F, b: Self::F) -> Self::F;
    /// `a ^ b` (bitwise; with `-0.0`, a sign flip: the exact `-a`).
    fn xor(a: Self::F, b: Self::F) -> Self::F;
    /// The lanes' bit patterns added as wrapping 32-bit integers (`next_float_up` and
    /// `next_float_down` step a float's bits by one).
    fn bits_add(a: Self::F, b: Self::F) -> Self::F;
    /// `mask ? a : b` per lane (`mask` all ones or all zeros per lane).
    fn select(mask: Self::F, a: Self::F, b: Self::F) -> Self::F;
    /// Clear the sign bit.
    fn abs(a: Self::F) -> Self::F;
    /// The lanes' sign bits as a bit mask (lane `i` is bit `i`).
    fn bits(mask: Self::F) -> u32;
    /// All ones where the lane's sign bit is set (`-0` and NaNs with the bit included).
    fn sign_mask(a: Self::F) -> Self::F;
    /// The lanes' bit patterns shifted right by `N`, zeros shifted in (`u32 >> N`).
    fn shr_bits<const N: i32>(a: Self::F) -> Self::F;
    /// The lanes' bit patterns shifted left by `N` (`u32 << N`).
    fn shl_bits<const N: i32>(a: Self::F) -> Self::F;
    /// The lanes' bit patterns as `i32` converted to f32 (`i as f32`; exact below 2^24).
    fn int_to_float(a: Self::F) -> Self::F;
    /// The lanes truncated to `i32`, as bit patterns (`x as i32` for `x` within the `i32`
    /// range; outside it `i32::MIN`, where `as` saturates: callers keep such lanes out).
    fn float_to_int(a: Self::F) -> Self::F;

    /// Lane `lane` of `a` in every lane.
    #[inline(always)]
    fn broadcast_lane(a: Self::F, lane: usize) -> Self::F {
        Self::splat(Self::store(a)[lane])
    }

    /// The least lane, for lanes holding no NaN (which of two equal zeros is unspecified;
    /// the value compares equal either way).
    #[inline(always)]
    fn min_lane(a: Self::F) -> f32 {
        Self::store(a).into_iter().fold(f32::INFINITY, f32::min)
    }
    /// The greatest lane, as [`Lanes::min_lane`].
    #[inline(always)]
    fn max_lane(a: Self::F) -> f32 {
        Self::store(a).into_iter().fold(f32::NEG_INFINITY, f32::max)
    }

    /// The first eight words of eight rays as lanes (origin x, y, z, `t_min`, direction x,
    /// y, z, `t_max`), word `w` of `rays[k]` in lane `k` of row `w`: a transpose, no
    /// arithmetic.
    #[inline(always)]
    fn ray_lanes(rays: &[RayRecord; LANES]) -> [Self::F; 8] {
        let word = |k: usize| Self::load(&bytemuck::cast_ref::<RayRecord, [[f32; 8]; 2]>(&rays[k])[0]);
        Self::transpose8([word(0), word(1), word(2), word(3), word(4), word(5), word(6), word(7)])
    }

    /// The 8x8 transpose: lane `k` of row `w` of the result is lane `w` of `rows[k]`.
    #[inline(always)]
    fn transpose8(rows: [Self::F; 8]) -> [Self::F; 8] {
        let rows = rows.map(Self::store);
        std::array::from_fn(|w| Self::load(&std::array::from_fn(|k| rows[k][w])))
    }

    /// Eight records of twelve words (48 bytes: [`TriangleRecord`], `SurfaceRecord`) as
    /// lanes, `[quad][word]`: word `4 * q + w` of `records[k]` in lane `k` of `out[q][w]`.
    /// A transpose, no arithmetic.
    #[inline(always)]
    fn quad_lanes(records: [&[f32; 12]; LANES]) -> [[Self::F; 4]; 3] {
        let mut v = [[[0.0f32; LANES]; 4]; 3];
        for (k, r) in records.iter().enumerate() {
            for (q, quad) in v.iter_mut().enumerate() {
                for (w, word) in quad.iter_mut().enumerate() {
                    word[k] = r[4 * q + w];
                }
            }
        }
        v.map(|v| v.map(|a| Self::load(&a)))
    }

    /// Four rows as eight quads, lane `k` of `rows[w]` in word `w` of quad `k` (one quad of
    /// [`Lanes::quad_lanes`] the other way, e.g. four colour channels to eight RGBA texels):
    /// a transpose, no arithmetic.
    #[inline(always)]
    fn quads(rows: [Self::F; 4]) -> [[f32; 4]; LANES] {
        let rows = rows.map(Self::store);
        std::array::from_fn(|k| std::array::from_fn(|w| rows[w][k]))
    }

    /// The vertices of eight triangles as lanes, `[vertex][axis]` with lane `k` from
    /// `tris[k]`: a transpose of the records' vertex words ([`Lanes::quad_lanes`]: each
    /// vertex and the word after it are a quad), no arithmetic.
    #[inline(always)]
    fn triangle_lanes(tris: [&TriangleRecord; LANES]) -> [[Self::F; 3]; 3] {
        let [v0, v1, v2] = Self::quad_lanes(words12(tris));
        [[v0[0], v0[1], v0[2]], [v1[0], v1[1], v1[2]], [v2[0], v2[1], v2[2]]]
    }

    #[inline(always)]
    fn gt(a: Self::F, b: Self::F) -> Self::F {
        Self::lt(b, a)
    }
    #[inline(always)]
    fn ge(a: Self::F, b: Self::F) -> Self::F {
        Self::le(b, a)
    }
}

/// Eight 48-byte records as the twelve words each that [`Lanes::quad_lanes`] reads.
#[inline(always)]
pub(crate) fn words12<T: bytemuck::Pod>(r: [&T; LANES]) -> [&[f32; 12]; LANES] {
    // Spelt out: no closure (`map`) on the lanes' paths.
    let w = bytemuck::cast_ref::<T, [f32; 12]>;
    [w(r[0]), w(r[1]), w(r[2]), w(r[3]), w(r[4]), w(r[5]), w(r[6]), w(r[7])]
}

/// The running bounds of the slab test (`ray_aabb_conservative`): the largest of the near
/// distances `tn` and `t_enter`, the smallest of the far distances `tf` and `t_exit`, per
/// lane, in the scalar order, so that a NaN distance (an origin on a slab plane with an
/// infinite inverse direction) is dropped as there. With `finite_inv` (no lane's inverse
/// direction is infinite) no distance is NaN and the order changes nothing the comparison
/// `t_enter <= t_exit` can see (only the sign of a zero): a shorter dependency chain with
/// the same answer.
#[inline(always)]
pub(crate) fn slab_bounds<L: Lanes>(
    tn: [L::F; 3],
    tf: [L::F; 3],
    t_enter: L::F,
    t_exit: L::F,
    finite_inv: bool,
) -> (L::F, L::F) {
    if finite_inv {
        (L::max(L::max(tn[0], tn[1]), L::max(tn[2], t_enter)), L::min(L::min(tf[0], tf[1]), L::min(tf[2], t_exit)))
    } else {
        let (mut t_enter, mut t_exit) = (t_enter, t_exit);
        for t in tn {
            t_enter = L::max(t, t_enter);
        }
        for t in tf {
            t_exit = L::min(t, t_exit);
        }
        (t_enter, t_exit)
    }
}

/// Plain arrays: the fallback on every target (LLVM vectorizes most of it).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Portable;

#[inline(always)]
fn map2(a: [f32; LANES], b: [f32; LANES], f: impl Fn(f32, f32) -> f32) -> [f32; LANES] {
    std::array::from_fn(|i| f(a[i], b[i]))
}

#[inline(always)]
fn mask(c: bool) -> f32 {
    f32::from_bits(if c { u32::MAX } else { 0 })
}

impl Lanes for Portable {
    type F = [f32; LANES];
    #[inline(always)]
    fn splat(x: f32) -> Self::F {
        [x; LANES]
    }
    #[inline(always)]
    fn load(a: &[f32; LANES]) -> Self::F {
        *a
    }
    #[inline(always)]
    fn store(v: Self::F) -> [f32; LANES] {
        v
    }
    #[inline(always)]
    fn add(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| a + b)
    }
    #[inline(always)]
    fn sub(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| a - b)
    }
    #[inline(always)]
    fn mul(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| a * b)
    }
    #[inline(always)]
    fn div(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| a / b)
    }
    #[inline(always)]
    fn sqrt(a: Self::F) -> Self::F {
        a.map(f32::sqrt)
    }
    #[inline(always)]
    fn max(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| if a > b { a } else { b })
    }
    #[inline(always)]
    fn min(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| if a < b { a } else { b })
    }
    #[inline(always)]
    fn lt(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| mask(a < b))
    }
    #[inline(always)]
    fn le(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| mask(a <= b))
    }
    #[inline(always)]
    fn eq(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| mask(a == b))
    }
    #[inline(always)]
    fn and(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| f32::from_bits(a.to_bits() & b.to_bits()))
    }
    #[inline(always)]
    fn or(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| f32::from_bits(a.to_bits() | b.to_bits()))
    }
    #[inline(always)]
    fn andnot(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| f32::from_bits(!a.to_bits() & b.to_bits()))
    }
    #[inline(always)]
    fn eq_bits(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| mask(a.to_bits() == b.to_bits()))
    }
    #[inline(always)]
    fn cross_sign_bits(a: Self::F, b: Self::F, c: Self::F, d: Self::F) -> (u32, u32) {
        let (mut neg, mut zero) = (0, 0);
        for i in 0..LANES {
            let x = a[i] as f64 * b[i] as f64 - c[i] as f64 * d[i] as f64;
            neg |= ((x < 0.0) as u32) << i;
            zero |= ((x == 0.0) as u32) << i;
        }
        (neg, zero)
    }
    #[inline(always)]
    fn xor(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| f32::from_bits(a.to_bits() ^ b.to_bits()))
    }
    #[inline(always)]
    fn bits_add(a: Self::F, b: Self::F) -> Self::F {
        map2(a, b, |a, b| f32::from_bits(a.to_bits().wrapping_add(b.to_bits())))
    }
    #[inline(always)]
    fn select(m: Self::F, a: Self::F, b: Self::F) -> Self::F {
        std::array::from_fn(|i| if m[i].to_bits() != 0 { a[i] } else { b[i] })
    }
    #[inline(always)]
    fn abs(a: Self::F) -> Self::F {
        std::array::from_fn(|i| a[i].abs())
    }
    #[inline(always)]
    fn bits(m: Self::F) -> u32 {
        m.iter().enumerate().fold(0, |acc, (i, x)| acc | ((x.to_bits() >> 31) << i))
    }
    #[inline(always)]
    fn sign_mask(a: Self::F) -> Self::F {
        std::array::from_fn(|i| mask(a[i].is_sign_negative()))
    }
    #[inline(always)]
    fn shr_bits<const N: i32>(a: Self::F) -> Self::F {
        a.map(|a| f32::from_bits(a.to_bits() >> N))
    }
    #[inline(always)]
    fn shl_bits<const N: i32>(a: Self::F) -> Self::F {
        a.map(|a| f32::from_bits(a.to_bits() << N))
    }
    #[inline(always)]
    fn int_to_float(a: Self::F) -> Self::F {
        a.map(|a| a.to_bits() as i32 as f32)
    }
    #[inline(always)]
    fn float_to_int(a: Self::F) -> Self::F {
        // CVTTPS2DQ: `i32::MIN` for NaN and out-of-range lanes.
        a.map(|a| f32::from_bits(if a > -2147483904.0 && a < 2147483648.0 { a as i32 } else { i32::MIN } as u32))
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use x86::{Avx2, Sse2};

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::{Lanes, RayRecord, LANES};
    use std::arch::x86_64::*;

    /// Two SSE2 registers (x86-64 baseline: always available).
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Sse2;

    macro_rules! sse2 {
        ($f:ident, $a:expr, $b:expr) => {
            // SAFETY: SSE2 is part of the x86-64 baseline.
            unsafe { [$f($a[0], $b[0]), $f($a[1], $b[1])] }
        };
    }

    impl Lanes for Sse2 {
        type F = [__m128; 2];
        #[inline(always)]
        fn quad_lanes(w: [&[f32; 12]; LANES]) -> [[Self::F; 4]; 3] {
            // SAFETY: SSE2 is baseline; unaligned loads of four in-bounds words of a
            // record (`[f32; 12]`: quad `q` is words `4 * q ..`).
            unsafe {
                let mut out = [[[_mm_setzero_ps(); 2]; 4]; 3];
                for (q, quad) in out.iter_mut().enumerate() {
                    for (h, half) in [0, 4].into_iter().enumerate() {
                        let r = |k: usize| _mm_loadu_ps(w[half + k].as_ptr().add(4 * q));
                        let (r0, r1, r2, r3) = (r(0), r(1), r(2), r(3));
                        // [x0 x1 y0 y1], [z0 z1 w0 w1], [x2 x3 y2 y3], [z2 z3 w2 w3].
                        let (u0, u1) = (_mm_unpacklo_ps(r0, r1), _mm_unpackhi_ps(r0, r1));
                        let (u2, u3) = (_mm_unpacklo_ps(r2, r3), _mm_unpackhi_ps(r2, r3));
                        quad[0][h] = _mm_shuffle_ps::<0x44>(u0, u2);
                        quad[1][h] = _mm_shuffle_ps::<0xEE>(u0, u2);
                        quad[2][h] = _mm_shuffle_ps::<0x44>(u1, u3);
                        quad[3][h] = _mm_shuffle_ps::<0xEE>(u1, u3);
                    }
                }
                out
            }
        }
        #[inline(always)]
        fn quads(rows: [Self::F; 4]) -> [[f32; 4]; LANES] {
            // SAFETY: SSE2 is baseline; unaligned stores of four words into each quad.
            unsafe {
                let mut out = [[0.0f32; 4]; LANES];
                for h in 0..2 {
                    let [r0, r1, r2, r3] = rows.map(|r| r[h]);
                    // [x0 y0 x1 y1], [x2 y2 x3 y3], [z0 w0 z1 w1], [z2 w2 z3 w3].
                    let (u0, u1) = (_mm_unpacklo_ps(r0, r1), _mm_unpackhi_ps(r0, r1));
                    let (u2, u3) = (_mm_unpacklo_ps(r2, r3), _mm_unpackhi_ps(r2, r3));
                    let q = &mut out[4 * h..4 * h + 4];
                    _mm_storeu_ps(q[0].as_mut_ptr(), _mm_movelh_ps(u0, u2));
                    _mm_storeu_ps(q[1].as_mut_ptr(), _mm_movehl_ps(u2, u0));
                    _mm_storeu_ps(q[2].as_mut_ptr(), _mm_movelh_ps(u1, u3));
                    _mm_storeu_ps(q[3].as_mut_ptr(), _mm_movehl_ps(u3, u1));
                }
                out
            }
        }
        #[inline(always)]
        fn splat(x: f32) -> Self::F {
            // SAFETY: SSE2 is baseline.
            unsafe { [_mm_set1_ps(x); 2] }
        }
        #[inline(always)]
        fn load(a: &[f32; LANES]) -> Self::F {
            // SAFETY: SSE2 is baseline; unaligned loads of 8 in-bounds floats.
            unsafe { [_mm_loadu_ps(a.as_ptr()), _mm_loadu_ps(a.as_ptr().add(4))] }
        }
        #[inline(always)]
        fn store(v: Self::F) -> [f32; LANES] {
            let mut out = [0.0; LANES];
            // SAFETY: SSE2 is baseline; unaligned stores of 8 in-bounds floats.
            unsafe {
                _mm_storeu_ps(out.as_mut_ptr(), v[0]);
                _mm_storeu_ps(out.as_mut_ptr().add(4), v[1]);
            }
            out
        }
        #[inline(always)]
        fn add(a: Self::F, b: Self::F) -> Self::F {
            sse2!(_mm_add_ps, a, b)
        }
        #[inline(always)]
        fn sub(a: Self::F, b: Self::F) -> Self::F {
            sse2!(_mm_sub_ps, a, b)
        }
        #[inline(always)]
        fn mul(a: Self::F, b: Self::F) -> Self::F {
            sse2!(_mm_mul_ps, a, b)
        }
        #[inline(always)]
        fn div(a: Self::F, b: Self::F) -> Self::F {
            sse2!(_mm_div_ps, a, b)
        }
        #[inline(always)]
        fn sqrt(a: Self::F) -> Self::F {
            // SAFETY: SSE2 is baseline.
            unsafe { a.map(|a| _mm_sqrt_ps(a)) }
        }
        #[inline(always)]
        fn max(a: Self::F, b: Self::F) -> Self::F {
            sse2!(_mm_max_ps, a, b)
        }
        #[inline(always)]
        fn min(a: Self::F, b: Self::F) -> Self::F {
            sse2!(_mm_min_ps, a, b)
        }
        #[inline(always)]
        fn lt(a: Self::F, b: Self::F) -> Self::F {
            sse2!(_mm_cmplt_ps, a, b)
        }
        #[inline(always)]
        fn le(a: Self::F, b: Self::F) -> Self::F {
            sse2!(_mm_cmple_ps, a, b)
        }
        #[inline(always)]
        fn eq(a: Self::F, b: Self::F) -> Self::F {
            sse2!(_mm_cmpeq_ps, a, b)
        }
        #[inline(always)]
        fn and(a: Self::F, b: Self::F) -> Self::F {
            sse2!(_mm_and_ps, a, b)
        }
        #[inline(always)]
        fn or(a: Self::F, b: Self::F) -> Self::F {
            sse2!(_mm_or_ps, a, b)
        }
        #[inline(always)]
        fn andnot(a: Self::F, b: Self::F) -> Self::F {
            sse2!(_mm_andnot_ps, a, b)
        }
        #[inline(always)]
        fn eq_bits(a: Self::F, b: Self::F) -> Self::F {
            let eq = |a: __m128, b: __m128| {
                // SAFETY: SSE2 is baseline.
                unsafe { _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_castps_si128(a), _mm_castps_si128(b))) }
            };
            [eq(a[0], b[0]), eq(a[1], b[1])]
        }
        #[inline(always)]
        fn cross_sign_bits(a: Self::F, b: Self::F, c: Self::F, d: Self::F) -> (u32, u32) {
            // SAFETY: SSE2 is baseline.
            unsafe {
                let (mut neg, mut zero) = (0, 0);
                for (shift, q) in [0, 2, 4, 6].into_iter().zip([0, 0, 1, 1]) {
                    // Lanes `shift` and `shift + 1`: the low or the high pair of register `q`.
                    let (a, b, c, d) = if shift % 4 == 0 {
                        (a[q], b[q], c[q], d[q])
                    } else {
                        (
                            _mm_movehl_ps(a[q], a[q]),
                            _mm_movehl_ps(b[q], b[q]),
                            _mm_movehl_ps(c[q], c[q]),
                            _mm_movehl_ps(d[q], d[q]),
                        )
                    };
                    let ab = _mm_mul_pd(_mm_cvtps_pd(a), _mm_cvtps_pd(b));
                    let x = _mm_sub_pd(ab, _mm_mul_pd(_mm_cvtps_pd(c), _mm_cvtps_pd(d)));
                    neg |= (_mm_movemask_pd(_mm_cmplt_pd(x, _mm_setzero_pd())) as u32) << shift;
                    zero |= (_mm_movemask_pd(_mm_cmpeq_pd(x, _mm_setzero_pd())) as u32) << shift;
                }
                (neg, zero)
            }
        }
        #[inline(always)]
        fn xor(a: Self::F, b: Self::F) -> Self::F {
            sse2!(_mm_xor_ps, a, b)
        }
        #[inline(always)]
        fn bits_add(a: Self::F, b: Self::F) -> Self::F {
            let add = |a: __m128, b: __m128| {
                // SAFETY: SSE2 is baseline.
                unsafe { _mm_castsi128_ps(_mm_add_epi32(_mm_castps_si128(a), _mm_castps_si128(b))) }
            };
            [add(a[0], b[0]), add(a[1], b[1])]
        }
        #[inline(always)]
        fn select(m: Self::F, a: Self::F, b: Self::F) -> Self::F {
            Self::or(Self::and(m, a), Self::andnot(m, b))
        }
        #[inline(always)]
        fn abs(a: Self::F) -> Self::F {
            Self::andnot(Self::splat(-0.0), a)
        }
        #[inline(always)]
        fn bits(m: Self::F) -> u32 {
            // SAFETY: SSE2 is baseline.
            unsafe { (_mm_movemask_ps(m[0]) | (_mm_movemask_ps(m[1]) << 4)) as u32 }
        }
        #[inline(always)]
        fn sign_mask(a: Self::F) -> Self::F {
            // SAFETY: SSE2 is baseline. Arithmetic shift right by 31 spreads the sign bit.
            unsafe { a.map(|a| _mm_castsi128_ps(_mm_srai_epi32::<31>(_mm_castps_si128(a)))) }
        }
        #[inline(always)]
        fn shr_bits<const N: i32>(a: Self::F) -> Self::F {
            // SAFETY: SSE2 is baseline.
            unsafe {
                [
                    _mm_castsi128_ps(_mm_srli_epi32::<N>(_mm_castps_si128(a[0]))),
                    _mm_castsi128_ps(_mm_srli_epi32::<N>(_mm_castps_si128(a[1]))),
                ]
            }
        }
        #[inline(always)]
        fn shl_bits<const N: i32>(a: Self::F) -> Self::F {
            // SAFETY: SSE2 is baseline.
            unsafe {
                [
                    _mm_castsi128_ps(_mm_slli_epi32::<N>(_mm_castps_si128(a[0]))),
                    _mm_castsi128_ps(_mm_slli_epi32::<N>(_mm_castps_si128(a[1]))),
                ]
            }
        }
        #[inline(always)]
        fn int_to_float(a: Self::F) -> Self::F {
            // SAFETY: SSE2 is baseline.
            unsafe { [_mm_cvtepi32_ps(_mm_castps_si128(a[0])), _mm_cvtepi32_ps(_mm_castps_si128(a[1]))] }
        }
        #[inline(always)]
        fn float_to_int(a: Self::F) -> Self::F {
            // SAFETY: SSE2 is baseline.
            unsafe { [_mm_castsi128_ps(_mm_cvttps_epi32(a[0])), _mm_castsi128_ps(_mm_cvttps_epi32(a[1]))] }
        }
        #[inline(always)]
        fn min_lane(a: Self::F) -> f32 {
            // SAFETY: SSE2 is baseline.
            unsafe { reduce4(_mm_min_ps(a[0], a[1]), |x, y| _mm_min_ps(x, y)) }
        }
        #[inline(always)]
        fn max_lane(a: Self::F) -> f32 {
            // SAFETY: SSE2 is baseline.
            unsafe { reduce4(_mm_max_ps(a[0], a[1]), |x, y| _mm_max_ps(x, y)) }
        }
    }

    /// `op` over the four lanes of `v` (halves, then pairs), lane 0 of the result.
    #[inline(always)]
    unsafe fn reduce4(v: __m128, op: impl Fn(__m128, __m128) -> __m128) -> f32 {
        let v = op(v, _mm_movehl_ps(v, v));
        _mm_cvtss_f32(op(v, _mm_shuffle_ps::<0b01>(v, v)))
    }

    /// One AVX2 register. Only constructed behind `is_x86_feature_detected!("avx2")`, and
    /// its code runs only inside `#[target_feature(enable = "avx2")]` functions.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Avx2;

    macro_rules! avx {
        ($f:ident, $a:expr, $b:expr) => {
            // SAFETY: `Avx2` code is only reached after run-time detection of AVX2.
            unsafe { $f($a, $b) }
        };
    }

    impl Lanes for Avx2 {
        type F = __m256;
        const OCTANT_WALKS: bool = true;
        #[inline(always)]
        fn ray_lanes(rays: &[RayRecord; LANES]) -> [Self::F; 8] {
            // SAFETY: see the type's docs; unaligned loads of the first eight words of each
            // (64-byte) record.
            let r = |k: usize| unsafe { _mm256_loadu_ps((&rays[k] as *const RayRecord).cast::<f32>()) };
            Self::transpose8([r(0), r(1), r(2), r(3), r(4), r(5), r(6), r(7)])
        }
        #[inline(always)]
        fn transpose8([r0, r1, r2, r3, r4, r5, r6, r7]: [Self::F; 8]) -> [Self::F; 8] {
            // SAFETY: see the type's docs.
            unsafe {
                // Pairs of rows interleaved, then quadruples, then halves.
                let (a0, a1) = (_mm256_unpacklo_ps(r0, r1), _mm256_unpackhi_ps(r0, r1));
                let (a2, a3) = (_mm256_unpacklo_ps(r2, r3), _mm256_unpackhi_ps(r2, r3));
                let (a4, a5) = (_mm256_unpacklo_ps(r4, r5), _mm256_unpackhi_ps(r4, r5));
                let (a6, a7) = (_mm256_unpacklo_ps(r6, r7), _mm256_unpackhi_ps(r6, r7));
                let (b0, b1) = (_mm256_shuffle_ps::<0x44>(a0, a2), _mm256_shuffle_ps::<0xEE>(a0, a2));
                let (b2, b3) = (_mm256_shuffle_ps::<0x44>(a1, a3), _mm256_shuffle_ps::<0xEE>(a1, a3));
                let (b4, b5) = (_mm256_shuffle_ps::<0x44>(a4, a6), _mm256_shuffle_ps::<0xEE>(a4, a6));
                let (b6, b7) = (_mm256_shuffle_ps::<0x44>(a5, a7), _mm256_shuffle_ps::<0xEE>(a5, a7));
                [
                    _mm256_permute2f128_ps::<0x20>(b0, b4),
                    _mm256_permute2f128_ps::<0x20>(b1, b5),
                    _mm256_permute2f128_ps::<0x20>(b2, b6),
                    _mm256_permute2f128_ps::<0x20>(b3, b7),
                    _mm256_permute2f128_ps::<0x31>(b0, b4),
                    _mm256_permute2f128_ps::<0x31>(b1, b5),
                    _mm256_permute2f128_ps::<0x31>(b2, b6),
                    _mm256_permute2f128_ps::<0x31>(b3, b7),
                ]
            }
        }
        #[inline(always)]
        fn quad_lanes(w: [&[f32; 12]; LANES]) -> [[Self::F; 4]; 3] {
            // SAFETY: see the type's docs; unaligned loads of four in-bounds words of a
            // record (`[f32; 12]`: quad `q` is words `4 * q ..`).
            unsafe {
                let mut out = [[_mm256_setzero_ps(); 4]; 3];
                for (q, quad) in out.iter_mut().enumerate() {
                    // Row k: record k's quad in the low half, record k + 4's in the high.
                    let r = |k: usize| {
                        let lo = _mm_loadu_ps(w[k].as_ptr().add(4 * q));
                        _mm256_insertf128_ps::<1>(
                            _mm256_castps128_ps256(lo),
                            _mm_loadu_ps(w[k + 4].as_ptr().add(4 * q)),
                        )
                    };
                    let (r0, r1, r2, r3) = (r(0), r(1), r(2), r(3));
                    // Per half: [x0 x1 y0 y1], [z0 z1 w0 w1], [x2 x3 y2 y3], [z2 z3 w2 w3].
                    let (u0, u1) = (_mm256_unpacklo_ps(r0, r1), _mm256_unpackhi_ps(r0, r1));
                    let (u2, u3) = (_mm256_unpacklo_ps(r2, r3), _mm256_unpackhi_ps(r2, r3));
                    *quad = [
                        _mm256_shuffle_ps::<0x44>(u0, u2),
                        _mm256_shuffle_ps::<0xEE>(u0, u2),
                        _mm256_shuffle_ps::<0x44>(u1, u3),
                        _mm256_shuffle_ps::<0xEE>(u1, u3),
                    ];
                }
                out
            }
        }
        #[inline(always)]
        fn quads([r0, r1, r2, r3]: [Self::F; 4]) -> [[f32; 4]; LANES] {
            // SAFETY: see the type's docs; unaligned stores of four words into each quad.
            unsafe {
                // Per half: [x0 y0 x1 y1], [x2 y2 x3 y3], [z0 w0 z1 w1], [z2 w2 z3 w3].
                let (u0, u1) = (_mm256_unpacklo_ps(r0, r1), _mm256_unpackhi_ps(r0, r1));
                let (u2, u3) = (_mm256_unpacklo_ps(r2, r3), _mm256_unpackhi_ps(r2, r3));
                // Quad k in the low half, quad k + 4 in the high.
                let q = [
                    _mm256_shuffle_ps::<0x44>(u0, u2),
                    _mm256_shuffle_ps::<0xEE>(u0, u2),
                    _mm256_shuffle_ps::<0x44>(u1, u3),
                    _mm256_shuffle_ps::<0xEE>(u1, u3),
                ];
                let mut out = [[0.0f32; 4]; LANES];
                for (k, q) in q.into_iter().enumerate() {
                    _mm_storeu_ps(out[k].as_mut_ptr(), _mm256_castps256_ps128(q));
                    _mm_storeu_ps(out[k + 4].as_mut_ptr(), _mm256_extractf128_ps::<1>(q));
                }
                out
            }
        }
        #[inline(always)]
        fn splat(x: f32) -> Self::F {
            // SAFETY: see the type's docs.
            unsafe { _mm256_set1_ps(x) }
        }
        #[inline(always)]
        fn load(a: &[f32; LANES]) -> Self::F {
            // SAFETY: see the type's docs; unaligned load of 8 in-bounds floats.
            unsafe { _mm256_loadu_ps(a.as_ptr()) }
        }
        #[inline(always)]
        fn store(v: Self::F) -> [f32; LANES] {
            let mut out = [0.0; LANES];
            // SAFETY: see the type's docs; unaligned store of 8 in-bounds floats.
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), v) };
            out
        }
        #[inline(always)]
        fn add(a: Self::F, b: Self::F) -> Self::F {
            avx!(_mm256_add_ps, a, b)
        }
        #[inline(always)]
        fn sub(a: Self::F, b: Self::F) -> Self::F {
            avx!(_mm256_sub_ps, a, b)
        }
        #[inline(always)]
        fn mul(a: Self::F, b: Self::F) -> Self::F {
            avx!(_mm256_mul_ps, a, b)
        }
        #[inline(always)]
        fn broadcast_lane(a: Self::F, lane: usize) -> Self::F {
            // SAFETY: see the type's docs.
            unsafe { _mm256_permutevar8x32_ps(a, _mm256_set1_epi32(lane as i32)) }
        }
        #[inline(always)]
        fn div(a: Self::F, b: Self::F) -> Self::F {
            avx!(_mm256_div_ps, a, b)
        }
        #[inline(always)]
        fn sqrt(a: Self::F) -> Self::F {
            // SAFETY: see the type's docs.
            unsafe { _mm256_sqrt_ps(a) }
        }
        #[inline(always)]
        fn max(a: Self::F, b: Self::F) -> Self::F {
            avx!(_mm256_max_ps, a, b)
        }
        #[inline(always)]
        fn min(a: Self::F, b: Self::F) -> Self::F {
            avx!(_mm256_min_ps, a, b)
        }
        #[inline(always)]
        fn lt(a: Self::F, b: Self::F) -> Self::F {
            // SAFETY: see the type's docs.
            unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(a, b) }
        }
        #[inline(always)]
        fn le(a: Self::F, b: Self::F) -> Self::F {
            // SAFETY: see the type's docs.
            unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(a, b) }
        }
        #[inline(always)]
        fn eq(a: Self::F, b: Self::F) -> Self::F {
            // SAFETY: see the type's docs.
            unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(a, b) }
        }
        #[inline(always)]
        fn and(a: Self::F, b: Self::F) -> Self::F {
            avx!(_mm256_and_ps, a, b)
        }
        #[inline(always)]
        fn or(a: Self::F, b: Self::F) -> Self::F {
            avx!(_mm256_or_ps, a, b)
        }
        #[inline(always)]
        fn andnot(a: Self::F, b: Self::F) -> Self::F {
            avx!(_mm256_andnot_ps, a, b)
        }
        #[inline(always)]
        fn eq_bits(a: Self::F, b: Self::F) -> Self::F {
            // SAFETY: see the type's docs.
            unsafe { _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_castps_si256(a), _mm256_castps_si256(b))) }
        }
        #[inline(always)]
        fn cross_sign_bits(a: Self::F, b: Self::F, c: Self::F, d: Self::F) -> (u32, u32) {
            // SAFETY: see the type's docs. (No closures: they would not inherit AVX.)
            unsafe {
                let (mut neg, mut zero) = (0, 0);
                for half in 0..2 {
                    let (a, b, c, d) = if half == 0 {
                        (
                            _mm256_castps256_ps128(a),
                            _mm256_castps256_ps128(b),
                            _mm256_castps256_ps128(c),
                            _mm256_castps256_ps128(d),
                        )
                    } else {
                        (
                            _mm256_extractf128_ps::<1>(a),
                            _mm256_extractf128_ps::<1>(b),
                            _mm256_extractf128_ps::<1>(c),
                            _mm256_extractf128_ps::<1>(d),
                        )
                    };
                    let ab = _mm256_mul_pd(_mm256_cvtps_pd(a), _mm256_cvtps_pd(b));
                    let x = _mm256_sub_pd(ab, _mm256_mul_pd(_mm256_cvtps_pd(c), _mm256_cvtps_pd(d)));
                    let z = _mm256_setzero_pd();
                    neg |= (_mm256_movemask_pd(_mm256_cmp_pd::<_CMP_LT_OQ>(x, z)) as u32) << (4 * half);
                    zero |= (_mm256_movemask_pd(_mm256_cmp_pd::<_CMP_EQ_OQ>(x, z)) as u32) << (4 * half);
                }
                (neg, zero)
            }
        }
        #[inline(always)]
        fn xor(a: Self::F, b: Self::F) -> Self::F {
            avx!(_mm256_xor_ps, a, b)
        }
        #[inline(always)]
        fn bits_add(a: Self::F, b: Self::F) -> Self::F {
            // SAFETY: see the type's docs.
            unsafe { _mm256_castsi256_ps(_mm256_add_epi32(_mm256_castps_si256(a), _mm256_castps_si256(b))) }
        }
        #[inline(always)]
        fn select(m: Self::F, a: Self::F, b: Self::F) -> Self::F {
            // SAFETY: see the type's docs. blendv takes `a` where the mask's sign bit is set.
            unsafe { _mm256_blendv_ps(b, a, m) }
        }
        #[inline(always)]
        fn abs(a: Self::F) -> Self::F {
            Self::andnot(Self::splat(-0.0), a)
        }
        #[inline(always)]
        fn bits(m: Self::F) -> u32 {
            // SAFETY: see the type's docs.
            unsafe { _mm256_movemask_ps(m) as u32 }
        }
        #[inline(always)]
        fn sign_mask(a: Self::F) -> Self::F {
            // SAFETY: see the type's docs. Arithmetic shift right by 31 spreads the sign bit.
            unsafe { _mm256_castsi256_ps(_mm256_srai_epi32::<31>(_mm256_castps_si256(a))) }
        }
        #[inline(always)]
        fn shr_bits<const N: i32>(a: Self::F) -> Self::F {
            // SAFETY: see the type's docs.
            unsafe { _mm256_castsi256_ps(_mm256_srli_epi32::<N>(_mm256_castps_si256(a))) }
        }
        #[inline(always)]
        fn shl_bits<const N: i32>(a: Self::F) -> Self::F {
            // SAFETY: see the type's docs.
            unsafe { _mm256_castsi256_ps(_mm256_slli_epi32::<N>(_mm256_castps_si256(a))) }
        }
        #[inline(always)]
        fn int_to_float(a: Self::F) -> Self::F {
            // SAFETY: see the type's docs.
            unsafe { _mm256_cvtepi32_ps(_mm256_castps_si256(a)) }
        }
        #[inline(always)]
        fn float_to_int(a: Self::F) -> Self::F {
            // SAFETY: see the type's docs.
            unsafe { _mm256_castsi256_ps(_mm256_cvttps_epi32(a)) }
        }
        #[inline(always)]
        fn min_lane(a: Self::F) -> f32 {
            // SAFETY: see the type's docs.
            unsafe {
                let half = _mm_min_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps::<1>(a));
                reduce4(half, |x, y| _mm_min_ps(x, y))
            }
        }
        #[inline(always)]
        fn max_lane(a: Self::F) -> f32 {
            // SAFETY: see the type's docs.
            unsafe {
                let half = _mm_max_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps::<1>(a));
                reduce4(half, |x, y| _mm_max_ps(x, y))
            }
        }
    }
}

// Three-vectors of lanes, with the scalar kernels' operation order. No closures: a closure
// does not inherit its caller's target features (see `avx2_entry_points`).

/// A 3-vector in every lane.
#[inline(always)]
pub(crate) fn splat3<L: Lanes>(v: [f32; 3]) -> [L::F; 3] {
    [L::splat(v[0]), L::splat(v[1]), L::splat(v[2])]
}

/// `a - b` per component and lane.
#[inline(always)]
pub(crate) fn sub3<L: Lanes>(a: [L::F; 3], b: [L::F; 3]) -> [L::F; 3] {
    [L::sub(a[0], b[0]), L::sub(a[1], b[1]), L::sub(a[2], b[2])]
}

/// The lanes of a 3-vector as arrays.
#[inline(always)]
pub(crate) fn store3<L: Lanes>(v: [L::F; 3]) -> [[f32; LANES]; 3] {
    [L::store(v[0]), L::store(v[1]), L::store(v[2])]
}

/// `(a.x * b.x) + (a.y * b.y) + (a.z * b.z)`, glam's `Vec3::dot`, per lane.
#[inline(always)]
pub(crate) fn dot3<L: Lanes>(a: [L::F; 3], b: [L::F; 3]) -> L::F {
    L::add(L::add(L::mul(a[0], b[0]), L::mul(a[1], b[1])), L::mul(a[2], b[2]))
}

/// glam's `normalize_or_zero` per lane: `v * (1 / sqrt(v.v))` where that reciprocal is
/// finite and positive, else zero.
#[inline(always)]
pub(crate) fn normalize_or_zero_lanes<L: Lanes>(v: [L::F; 3]) -> [L::F; 3] {
    let rcp = L::div(L::splat(1.0), L::sqrt(dot3::<L>(v, v)));
    // `rcp.is_finite() && rcp > 0`: NaN fails both comparisons.
    let ok = L::and(L::lt(L::splat(0.0), rcp), L::lt(rcp, L::splat(f32::INFINITY)));
    select3::<L>(ok, [L::mul(v[0], rcp), L::mul(v[1], rcp), L::mul(v[2], rcp)], zero3::<L>())
}

/// Zero in every component and lane.
#[inline(always)]
pub(crate) fn zero3<L: Lanes>() -> [L::F; 3] {
    [L::splat(0.0); 3]
}

/// `mask ? a : b` per component and lane.
#[inline(always)]
pub(crate) fn select3<L: Lanes>(mask: L::F, a: [L::F; 3], b: [L::F; 3]) -> [L::F; 3] {
    [L::select(mask, a[0], b[0]), L::select(mask, a[1], b[1]), L::select(mask, a[2], b[2])]
}

/// All ones in lane `k` where bit `k` of `bits` is set.
#[inline(always)]
pub(crate) fn mask_lanes<L: Lanes>(bits: u32) -> L::F {
    let mut m = [0.0f32; LANES];
    for (k, m) in m.iter_mut().enumerate() {
        *m = f32::from_bits(if bits >> k & 1 == 1 { u32::MAX } else { 0 });
    }
    L::load(&m)
}

/// Run `$generic` at SIMD level `$level` (a [`SimdLevel`](crate::traversal::SimdLevel)
/// this CPU has): the entry points of [`avx2_entry_points`] at the AVX-512 and AVX2
/// levels, the SSE2 lanes at SSE2, the portable lanes elsewhere.
macro_rules! dispatch {
    ($level:expr, $generic:ident, $avx512:ident, $avx2:ident, ($($arg:expr),*)) => {
        match $level {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: callers pass only levels this CPU has (`SimdLevel::detect`,
            // `Traversal::level`).
            $crate::traversal::SimdLevel::Avx512 => unsafe { $avx512($($arg),*) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as above.
            $crate::traversal::SimdLevel::Avx2 => unsafe { $avx2($($arg),*) },
            #[cfg(target_arch = "x86_64")]
            $crate::traversal::SimdLevel::Sse2 => $generic::<$crate::lanes::Sse2>($($arg),*),
            _ => $generic::<$crate::lanes::Portable>($($arg),*),
        }
    };
}
pub(crate) use dispatch;

/// `$generic` on the AVX2 lanes, compiled once with the features of
/// [`SimdLevel::Avx2`](crate::traversal::SimdLevel) (`$avx2`) and once with those of
/// [`SimdLevel::Avx512`](crate::traversal::SimdLevel) (`$avx512`: the same lanes; `Avx2`'s
/// contract holds, AVX-512F implies AVX2). Both levels include the bit-manipulation
/// instructions every AVX2 CPU has (BMI1, BMI2, LZCNT, POPCNT; integer only, no float
/// result changes): the walks' lane masks use `popcnt`, `tzcnt` and `blsr` instead of
/// their multi-instruction fallbacks. `$generic` must be `#[inline(always)]` down to its
/// lanes' operations, so that they compile with the features. Callers must have detected
/// the features ([`SimdLevel::is_available`](crate::traversal::SimdLevel::is_available)
/// lists the same ones).
macro_rules! avx2_entry_points {
    ($generic:ident, $avx2:ident, $avx512:ident, ($($arg:ident: $ty:ty),*) $(-> $ret:ty)?) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
        #[allow(clippy::too_many_arguments)]
        unsafe fn $avx2($($arg: $ty),*) $(-> $ret)? {
            $generic::<$crate::lanes::Avx2>($($arg),*)
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,avx512f,avx512vl,avx512dq,avx512bw,bmi1,bmi2,lzcnt,popcnt")]
        #[allow(clippy::too_many_arguments)]
        unsafe fn $avx512($($arg: $ty),*) $(-> $ret)? {
            $generic::<$crate::lanes::Avx2>($($arg),*)
        }
    };
}
pub(crate) use avx2_entry_points;

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Values that exercise NaN, signed zeros, infinities and rounding.
    const SAMPLES: [f32; LANES] = [0.0, -0.0, f32::NAN, f32::INFINITY, -1.5, 1.0 / 3.0, 1e-40, -3e38];

    fn check<L: Lanes>() {
        let a = L::load(&SAMPLES);
        let mut rot = SAMPLES;
        rot.rotate_left(3);
        let b = L::load(&rot);
        let p = Portable::load(&SAMPLES);
        let q = Portable::load(&rot);
        let same = |x: L::F, y: [f32; LANES]| {
            let x = L::store(x);
            for i in 0..LANES {
                assert_eq!(x[i].to_bits(), y[i].to_bits(), "lane {i}: {} vs {}", x[i], y[i]);
            }
        };
        same(L::add(a, b), Portable::add(p, q));
        same(L::sub(a, b), Portable::sub(p, q));
        same(L::mul(a, b), Portable::mul(p, q));
        same(L::div(a, b), Portable::div(p, q));
        same(L::max(a, b), Portable::max(p, q));
        same(L::min(a, b), Portable::min(p, q));
        same(L::abs(a), Portable::abs(p));
        for (lane, &x) in SAMPLES.iter().enumerate() {
            same(L::broadcast_lane(a, lane), [x; LANES]);
        }
        same(L::xor(a, b), Portable::xor(p, q));
        same(L::xor(a, L::splat(-0.0)), SAMPLES.map(|x| -x));
        same(L::bits_add(a, b), Portable::bits_add(p, q));
        let one = f32::from_bits(1);
        same(L::bits_add(a, L::splat(one)), SAMPLES.map(|x| f32::from_bits(x.to_bits().wrapping_add(1))));
        same(L::sqrt(a), Portable::sqrt(p));
        same(L::sqrt(L::abs(b)), Portable::sqrt(Portable::abs(q)));
        same(L::shr_bits::<23>(a), SAMPLES.map(|x| f32::from_bits(x.to_bits() >> 23)));
        same(L::shl_bits::<23>(a), SAMPLES.map(|x| f32::from_bits(x.to_bits() << 23)));
        same(L::int_to_float(a), SAMPLES.map(|x| x.to_bits() as i32 as f32));
        same(L::float_to_int(a), Portable::float_to_int(p));
        let ints = [-2147483904.0, -2147483648.0, -100.4, -0.5, 99.9, 2147483520.0, 2147483648.0, f32::NEG_INFINITY];
        same(
            L::float_to_int(L::load(&ints)),
            ints.map(
                |x| f32::from_bits(if x > -2147483904.0 && x < 2147483648.0 { x as i32 } else { i32::MIN } as u32),
            ),
        );
        assert_eq!(
            Portable::float_to_int(Portable::load(&ints)).map(f32::to_bits)[..6],
            [i32::MIN as u32, i32::MIN as u32, -100i32 as u32, 0, 99, 2147483520]
        );
        for (x, y) in
            [(L::lt(a, b), Portable::lt(p, q)), (L::le(a, b), Portable::le(p, q)), (L::eq(a, b), Portable::eq(p, q))]
        {
            same(x, y);
            assert_eq!(L::bits(x), Portable::bits(y));
            same(L::select(x, a, b), Portable::select(y, p, q));
        }
        same(L::splat(-0.0), Portable::splat(-0.0));
        // The transpose of eight triangle records: every word to its lane.
        let records: Vec<TriangleRecord> = (0..LANES)
            .map(|k| {
                let w = |i: usize| {
                    std::array::from_fn(|a| SAMPLES[(k + 3 * i + a) % LANES] + (100 * k + 10 * i + a) as f32)
                };
                TriangleRecord { v0: w(0), object: 7, v1: w(1), triangle: 8, v2: w(2), flags: 9 }
            })
            .collect();
        let tris: [&TriangleRecord; LANES] = std::array::from_fn(|k| &records[k]);
        let (lanes, portable) = (L::triangle_lanes(tris), Portable::triangle_lanes(tris));
        for i in 0..3 {
            for a in 0..3 {
                same(lanes[i][a], portable[i][a]);
                let want: [f32; LANES] = std::array::from_fn(|k| [records[k].v0, records[k].v1, records[k].v2][i][a]);
                assert_eq!(portable[i][a].map(f32::to_bits), want.map(f32::to_bits));
            }
        }
        // The same records as twelve words each, the ids' words included.
        let words: [&[f32; 12]; LANES] = std::array::from_fn(|k| bytemuck::cast_ref(&records[k]));
        let (lanes, portable) = (L::quad_lanes(words), Portable::quad_lanes(words));
        for q in 0..3 {
            for w in 0..4 {
                same(lanes[q][w], portable[q][w]);
                let want: [f32; LANES] = std::array::from_fn(|k| words[k][4 * q + w]);
                assert_eq!(portable[q][w].map(f32::to_bits), want.map(f32::to_bits));
            }
        }
        // And back: four rows of lanes to eight quads.
        for q in 0..3 {
            let (got, want) = (L::quads(lanes[q]), Portable::quads(portable[q]));
            for k in 0..LANES {
                assert_eq!(got[k].map(f32::to_bits), want[k].map(f32::to_bits), "quad {q}, lane {k}");
                let record: [f32; 4] = std::array::from_fn(|w| words[k][4 * q + w]);
                assert_eq!(want[k].map(f32::to_bits), record.map(f32::to_bits), "quad {q}, lane {k}");
            }
        }
        // Exact signs of `a * b - c * d` for integers up to 2^24: products that differ
        // by one where f32 products would round to the same value.
        let big = 16_777_215.0f32; // 2^24 - 1
        let (a, b, c, d) = (
            [big, big, -big, 3.0, 0.0, big, -5.0, 16_777_216.0],
            [big, -big, big, 4.0, 7.0, big - 2.0, 0.0, 16_777_216.0],
            [big - 1.0, big - 1.0, big + 1.0, 2.0, 1.0, big - 1.0, 0.0, 16_777_216.0],
            [big + 1.0, -(big + 1.0), big - 1.0, 6.0, 0.0, big - 1.0, 9.0, 16_777_216.0],
        );
        // (2^24-1)^2 - (2^24-2)(2^24) = 1; -(2^24-1)^2 + (2^24-2)(2^24) = -1;
        // -(2^24-1)^2 - (2^24)(2^24-2) < 0; 12 - 12 = 0; 0 - 0 = 0; (2^24-1)(2^24-3) - (2^24-2)^2 = -1;
        // 0 - 0 = 0; 2^48 - 2^48 = 0.
        let want = (0b0010_0110, 0b1101_1000);
        let lanes = |v: [f32; LANES]| L::load(&v);
        assert_eq!(L::cross_sign_bits(lanes(a), lanes(b), lanes(c), lanes(d)), want);
        assert_eq!(Portable::cross_sign_bits(a, b, c, d), want);
        // Bit-pattern equality: NaN patterns equal themselves, `-0` is not `+0`.
        let ids = [u32::MAX, 0, 0x8000_0000, 0x7fc0_0000, u32::MAX, 1, 7, u32::MAX].map(f32::from_bits);
        let invalid = L::splat(f32::from_bits(u32::MAX));
        assert_eq!(L::bits(L::eq_bits(L::load(&ids), invalid)), 0b1001_0001);
        assert_eq!(
            Portable::bits(Portable::eq_bits(Portable::load(&ids), Portable::splat(f32::from_bits(u32::MAX)))),
            0b1001_0001
        );
        assert_eq!(L::bits(L::eq_bits(L::load(&ids), L::splat(0.0))), 0b10);
        // The transpose of eight ray records' first eight words: every word to its lane.
        let rays: [RayRecord; LANES] = std::array::from_fn(|k| {
            let w = |i: usize| SAMPLES[(k + i) % LANES] + (100 * k + 10 * i) as f32;
            RayRecord {
                origin: [w(0), w(1), w(2)],
                t_min: w(3),
                direction: [w(4), w(5), w(6)],
                t_max: w(7),
                pixel: 11,
                kind: 12,
                ..bytemuck::Zeroable::zeroed()
            }
        });
        let (lanes, portable) = (L::ray_lanes(&rays), Portable::ray_lanes(&rays));
        for (w, (row, want)) in lanes.into_iter().zip(portable).enumerate() {
            same(row, want);
            let words: [f32; LANES] = std::array::from_fn(|k| bytemuck::cast_ref::<RayRecord, [f32; 16]>(&rays[k])[w]);
            assert_eq!(want.map(f32::to_bits), words.map(f32::to_bits));
        }
        // Horizontal extremes of NaN-free lanes, the extreme in every position.
        for k in 0..LANES {
            let mut v: [f32; LANES] = std::array::from_fn(|i| (i as f32 - 3.5) * 0.7);
            v[k] = -1e30;
            assert_eq!(L::min_lane(L::load(&v)), -1e30, "least in lane {k}");
            v[k] = f32::INFINITY;
            assert_eq!(L::max_lane(L::load(&v)), f32::INFINITY, "greatest in lane {k}");
            assert_eq!(L::min_lane(L::load(&v)), Portable::min_lane(Portable::load(&v)));
        }
    }

    /// A check over lanes, run at every SIMD level this machine has by [`at_every_level`].
    pub(crate) trait LevelCheck {
        fn check<L: Lanes>(&self) -> Result<(), proptest::test_runner::TestCaseError>;
    }

    /// `c` on the portable lanes, SSE2 and, where detected, AVX2.
    pub(crate) fn at_every_level<C: LevelCheck>(c: &C) -> Result<(), proptest::test_runner::TestCaseError> {
        c.check::<Portable>()?;
        #[cfg(target_arch = "x86_64")]
        {
            c.check::<Sse2>()?;
            if is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 detected just above.
                unsafe { check_with_avx2(c)? };
            }
        }
        Ok(())
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn check_with_avx2<C: LevelCheck>(c: &C) -> Result<(), proptest::test_runner::TestCaseError> {
        c.check::<Avx2>()
    }

    /// `got` is `want` bit for bit, NaNs aside: any NaN stands for any other (Rust does not
    /// promise which NaN an operation on NaNs gives, and LLVM may swap the operands of `+`
    /// and `*`).
    pub(crate) fn same_bits(got: f32, want: f32) -> bool {
        got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan())
    }

    #[test]
    fn portable_lanes_follow_maxps_semantics() {
        let m = Portable::max(
            [f32::NAN, 1.0, -0.0, 0.0, 2.0, 0.0, 0.0, 0.0],
            [1.0, f32::NAN, 0.0, -0.0, 1.0, 0.0, 0.0, 0.0],
        );
        assert!(m[0] == 1.0 && m[1].is_nan() && m[2].to_bits() == 0 && m[3].to_bits() == (-0.0f32).to_bits());
        assert_eq!(m[4], 2.0);
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn sse2_lanes_equal_portable_bit_for_bit() {
        check::<Sse2>();
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_lanes_equal_portable_bit_for_bit() {
        if is_x86_feature_detected!("avx2") {
            // SAFETY: AVX2 detected just above.
            unsafe { check_avx2() }
        } else {
            eprintln!("no AVX2 on this machine: AVX2 lanes not checked");
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn check_avx2() {
        check::<Avx2>();
    }
}
