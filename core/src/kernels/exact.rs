//! Correctly rounded division and square root from operations every GPU rounds
//! correctly: the specification of the WGSL helpers `div_rn` and `sqrt_rn`
//! (`gpu-backend/src/shaders/exact.wgsl`), which every shader uses instead of WGSL's `/`
//! on floats, `sqrt`, `normalize`, `length` and `distance`.
//!
//! # Why
//! The CPU kernels divide and take square roots with IEEE 754's correctly rounded `/` and
//! `sqrt`. Vulkan's SPIR-V precision rules (and WGSL's "Floating Point Accuracy") allow a
//! float division to be off by 2.5 ulp and `sqrt` to inherit `1 / inverseSqrt` (about
//! 3 ulp); NVIDIA's, AMD's and Intel's compilers turn `a / b` into `a * rcp(b)`. Only
//! lavapipe (LLVM) rounds them correctly. So a shader that uses them cannot give the
//! CPU's bits on real hardware. Integer arithmetic is exact everywhere, and so are
//! conversions of small integers to floats.
//!
//! # How
//! Both helpers work on the significands as integers:
//! - [`div_rn`]: `a = ma * 2^ea`, `b = mb * 2^eb` with 24-bit significands (subnormals
//!   normalized by counting leading zeros). After `ma < mb` is fixed by one shift, the
//!   quotient's 25 leading bits `q = floor(ma * 2^24 / mb)` (24 significand bits and a
//!   guard bit) and the remainder `r = ma * 2^24 - q * mb` (the sticky bit: `r != 0`)
//!   decide the rounding exactly.
//! - [`sqrt_rn`]: `x = m * 2^e` with `e` made even, `q = floor(sqrt(m * 2^25))` and
//!   `r = m * 2^25 - q^2`.
//!
//! `q` is first estimated with the float operation itself (`f32(ma) / f32(mb)`, or
//! `sqrt(f32(2m))`, on small exact integers, so the estimate is within a few units of
//! `q` on any conforming device). The remainders need 49 and 50 bits, but they are
//! computed modulo 2^32 (wrapping `u32` arithmetic, as WGSL's): the true remainder of an
//! estimate fewer than [`EXACT_ESTIMATE_UNITS`] units off is below 2^31 in magnitude, so
//! its 32 low bits, read as an `i32`, are it. The remainder over the divisor (or over
//! `2 q`) is the estimate's error in units; one float quotient of it, rounded down, brings
//! `q` within one unit, and one exact step each way finishes. No loops: lavapipe's LLVM
//! spent minutes on the scalar evolution of a correction loop inlined at every division.
//! Rounding (to nearest, ties to even) and the exponent, subnormal results included, are
//! then integer work on `q`, `r != 0` and the exponents.
//!
//! No float operation here may round differently on another device: the estimate may,
//! and the correction absorbs it. A device whose `/` or `sqrt` is off by more than the
//! correction allows (about 2^-20 relatively, some 40 times what Vulkan permits) gives
//! wrong results: the GPU backend's float probe checks the helpers on hard cases at start.
//!
//! NaN results: a NaN operand comes back quieted (the first NaN operand of a division, as
//! x86's `divss` does), an invalid operation (`0 / 0`, `inf / inf`, `sqrt` of a negative)
//! gives [`DEFAULT_NAN`], x86's "real indefinite". Other CPUs differ only in the NaN's
//! bits; the tests compare NaN results as NaN.

/// Sign bit of an f32.
const SIGN: u32 = 0x8000_0000;
/// Exponent field of an f32 (also the bits of +inf).
const EXP_MASK: u32 = 0x7f80_0000;
/// Stored significand bits of an f32.
const FRACTION: u32 = 0x007f_ffff;
/// The quiet bit of a NaN.
const QUIET: u32 = 0x0040_0000;
/// The implicit leading bit of a normal f32's significand.
const IMPLICIT: u32 = 0x0080_0000;
/// f32 exponent bias.
const BIAS: i32 = 127;

/// The NaN an invalid operation gives (x86's "real indefinite", what `0.0 / 0.0` and
/// `(-1.0f32).sqrt()` give on the machines the reference runs on).
pub const DEFAULT_NAN: u32 = 0xffc0_0000;

/// How many units (of the 25-bit `q`) the float estimate may be off. A correctly rounded
/// estimate is at most 1 off (the truncation of the scaled estimate); Vulkan's bounds (2.5
/// ulp for division, about 3 ulp for `sqrt` through `inverseSqrt`) allow 6 and 14. 32
/// leaves room for a device twice as loose. An estimate fewer than 32 units off keeps
/// every remainder below 2^31 in magnitude, so its wrapping computation is exact: under
/// 32 * 2^25 = 2^30 for a quotient, under 2 * 2^25 * 32 = 2^31 for a root.
pub const EXACT_ESTIMATE_UNITS: u32 = 32;

/// 2^24 as an f32: scales an estimate of a quotient or root in [1, 2) to its 25-bit
/// integer `q`.
const TWO_POW_24: f32 = 16_777_216.0;

/// 2^12 as an f32: `sqrt(m * 2^25) = sqrt(2 m) * 2^12`.
const TWO_POW_12: f32 = 4096.0;

/// A finite, non-zero magnitude's significand in [2^23, 2^24) and unbiased exponent:
/// `x = m * 2^(e - 23)`. Subnormals are normalized.
fn unpack(abs_bits: u32) -> (u32, i32) {
    let field = (abs_bits >> 23) as i32;
    if field == 0 {
        let shift = abs_bits.leading_zeros() - 8;
        (abs_bits << shift, 1 - BIAS - shift as i32)
    } else {
        ((abs_bits & FRACTION) | IMPLICIT, field - BIAS)
    }
}

/// The f32 bits of `q * 2^(e - 24)` rounded to nearest, ties to even, where `q` in
/// [2^24, 2^25) holds the 24 significand bits and a guard bit and `sticky` says whether
/// anything below `q` is non-zero: overflow gives infinity, small results are subnormal
/// (rounded once, from `q` and `sticky`) or zero. The sign is not included.
fn round_pack(q: u32, sticky: bool, e: i32) -> u32 {
    let biased = e + BIAS;
    if biased >= 255 {
        return EXP_MASK;
    }
    // A normal result drops the guard bit; a subnormal one drops 2 - biased bits more
    // (capped at 31: q < 2^25 then rounds to zero all the same).
    let (shift, base) = if biased >= 1 { (1, ((biased - 1) as u32) << 23) } else { ((2 - biased).min(31) as u32, 0) };
    let kept = q >> shift;
    let rest = q & ((1u32 << shift) - 1);
    let half = 1u32 << (shift - 1);
    let up = rest > half || (rest == half && (sticky || kept & 1 == 1));
    // The carry of a rounding up moves into the exponent (and to infinity) by itself.
    base + kept + up as u32
}

/// `a / b` correctly rounded (ties to even), from the estimate `estimate(x, y) ~ x / y`
/// of exact small integers: the correction makes the result independent of the estimate
/// while it is fewer than [`EXACT_ESTIMATE_UNITS`] units off the 25-bit quotient.
pub fn div_rn_with(a: f32, b: f32, estimate: impl Fn(f32, f32) -> f32) -> f32 {
    let (ab, bb) = (a.to_bits(), b.to_bits());
    let sign = (ab ^ bb) & SIGN;
    let (ax, bx) = (ab & !SIGN, bb & !SIGN);
    if ax > EXP_MASK {
        return f32::from_bits(ab | QUIET);
    }
    if bx > EXP_MASK {
        return f32::from_bits(bb | QUIET);
    }
    if ax == EXP_MASK {
        return f32::from_bits(if bx == EXP_MASK { DEFAULT_NAN } else { sign | EXP_MASK });
    }
    if bx == EXP_MASK {
        return f32::from_bits(sign);
    }
    if bx == 0 {
        return f32::from_bits(if ax == 0 { DEFAULT_NAN } else { sign | EXP_MASK });
    }
    if ax == 0 {
        return f32::from_bits(sign);
    }
    let (mut ma, ea) = unpack(ax);
    let (mb, eb) = unpack(bx);
    let mut e = ea - eb;
    if ma < mb {
        ma <<= 1;
        e -= 1;
    }
    // ma / mb in [1, 2): q = floor(ma * 2^24 / mb) in [2^24, 2^25).
    let numerator = ma << 24; // ma * 2^24 modulo 2^32
    let guess = estimate(ma as f32, mb as f32) * TWO_POW_24;
    let q0 = (guess as u32).clamp(1 << 24, (1 << 25) - 1);
    let r0 = numerator.wrapping_sub(q0.wrapping_mul(mb)) as i32;
    // One refinement by r0 / mb, the estimate's error in units (|r0 / mb| < 32; an
    // approximate quotient of it is within a thousandth), rounded down: within one unit.
    // (Truncation would round a negative error up, and could land two units above.)
    let mut q = q0.wrapping_add(((r0 as f32) / (mb as f32)).floor() as i32 as u32);
    let mut r = numerator.wrapping_sub(q.wrapping_mul(mb)) as i32;
    let step = mb as i32;
    if r < 0 {
        q = q.wrapping_sub(1);
        r += step;
    }
    if r >= step {
        q += 1;
        r -= step;
    }
    f32::from_bits(sign | round_pack(q, r != 0, e))
}

/// `sqrt(x)` correctly rounded (ties to even), from the estimate `estimate(y) ~ sqrt(y)`
/// of an exact small integer; see [`div_rn_with`].
pub fn sqrt_rn_with(x: f32, estimate: impl Fn(f32) -> f32) -> f32 {
    let bits = x.to_bits();
    let abs = bits & !SIGN;
    if abs > EXP_MASK {
        return f32::from_bits(bits | QUIET);
    }
    if abs == 0 {
        return x;
    }
    if bits & SIGN != 0 {
        return f32::from_bits(DEFAULT_NAN);
    }
    if abs == EXP_MASK {
        return x;
    }
    let (mut m, mut e) = unpack(abs);
    if e & 1 != 0 {
        m <<= 1;
        e -= 1;
    }
    // m in [2^23, 2^25): q = floor(sqrt(m * 2^25)) in [2^24, 2^25); sqrt(x) = q' 2^(e/2 - 24).
    let radicand = m << 25; // m * 2^25 modulo 2^32
    let guess = estimate((2 * m) as f32) * TWO_POW_12;
    let q0 = (guess as u32).clamp(1 << 24, (1 << 25) - 1);
    let r0 = radicand.wrapping_sub(q0.wrapping_mul(q0)) as i32;
    // One refinement by r0 / (2 q0) ~ sqrt(R) - q0 (off by (sqrt(R) - q0)^2 / (2 q0),
    // below 2^-15 for an estimate within 32 units), rounded down: within one unit.
    // (Truncation would round a negative error up, and could land two units above.)
    let mut q = q0.wrapping_add(((r0 as f32) / ((2 * q0) as f32)).floor() as i32 as u32);
    let mut r = radicand.wrapping_sub(q.wrapping_mul(q)) as i32;
    if r < 0 {
        // (q - 1)^2 = q^2 - (2q - 1)
        q = q.wrapping_sub(1);
        r = r.wrapping_add(q.wrapping_mul(2).wrapping_add(1) as i32);
    }
    if r > q.wrapping_mul(2) as i32 {
        // (q + 1)^2 = q^2 + 2q + 1
        r = r.wrapping_sub(q.wrapping_mul(2).wrapping_add(1) as i32);
        q += 1;
    }
    f32::from_bits(round_pack(q, r != 0, e >> 1))
}

/// `a / b` correctly rounded from integer arithmetic and an estimate by `/`: the
/// specification of WGSL's `div_rn`. Equals IEEE 754's `a / b` for every input (NaN
/// results as NaN).
pub fn div_rn(a: f32, b: f32) -> f32 {
    div_rn_with(a, b, |x, y| x / y)
}

/// `sqrt(x)` correctly rounded from integer arithmetic and an estimate by `sqrt`: the
/// specification of WGSL's `sqrt_rn`. Equals IEEE 754's `x.sqrt()` for every input (NaN
/// results as NaN).
pub fn sqrt_rn(x: f32) -> f32 {
    sqrt_rn_with(x, f32::sqrt)
}

/// The fixed operands of the exhaustive division sweeps (here and on the GPU,
/// `gpu-backend/tests/exact.rs`): ones, powers of two, all-ones significands, thirds and
/// tenths, subnormals, values near the overflow and underflow thresholds.
pub fn sweep_operands() -> Vec<f32> {
    let mut v = vec![1.0f32, -1.0, 2.0, 0.5, 3.0, 1.5, 0.1, 7.0, 1e-38, 1e30, f32::MAX, f32::MIN_POSITIVE];
    for bits in [
        0x3fff_ffffu32,
        0x3f7f_ffff,
        0x3f80_0001,
        0x4b7f_ffff,
        0x0000_0001,
        0x0000_0003,
        0x007f_ffff,
        0x0040_0001,
        0x3f55_5555,
        0x3eaa_aaab,
        0x7f7f_fffe,
        0x0080_0001,
        0x1000_0000,
        0x6000_0000,
        0x2000_0001,
        0x5eff_ffff,
        0x3fb5_04f3,
        0x3dcc_cccd,
    ] {
        v.push(f32::from_bits(bits));
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Bit equality, NaN equal to NaN whatever its bits (see the module docs).
    fn same(a: f32, b: f32) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    /// An estimate `k` ulp off (`k` may be negative), as a loose device's would be.
    fn off_by(x: f32, k: i32) -> f32 {
        f32::from_bits((x.to_bits() as i32 + k) as u32)
    }

    /// Special and boundary values: zeros, infinities, NaNs, the smallest and largest
    /// subnormals and normals, ones and neighbours, all-ones significands.
    fn specials() -> Vec<f32> {
        let mut v = vec![
            0.0,
            f32::INFINITY,
            f32::NAN,
            f32::from_bits(0x7fa0_0000), // a signalling NaN
            f32::from_bits(1),
            f32::from_bits(2),
            f32::from_bits(3),
            f32::from_bits(0x007f_ffff),
            f32::from_bits(0x0040_0000),
            f32::MIN_POSITIVE,
            f32::MAX,
            1.0,
            f32::from_bits(0x3f7f_ffff),
            f32::from_bits(0x3f80_0001),
            f32::from_bits(0x3fff_ffff),
            2.0,
            3.0,
            0.1,
            1e-38,
            1e38,
            f32::from_bits(0x4b7f_ffff),
        ];
        let neg: Vec<f32> = v.iter().map(|x| -x).collect();
        v.extend(neg);
        v
    }

    #[test]
    fn special_values_divide_and_root_as_ieee() {
        for &a in &specials() {
            assert!(same(sqrt_rn(a), a.sqrt()), "sqrt {a:e} ({:#x})", a.to_bits());
            for &b in &specials() {
                assert!(same(div_rn(a, b), a / b), "{a:e} / {b:e} ({:#x} / {:#x})", a.to_bits(), b.to_bits());
            }
        }
    }

    /// Exact ties and results on the edge of the subnormal range, where a second
    /// rounding would show: 2^-149 / 2 (a tie to zero), 3 * 2^-149 / 2 (a tie to even,
    /// up), the largest subnormal's neighbours divided by values just above and below 1,
    /// and the quotients that round up into the smallest normal or to infinity.
    #[test]
    fn subnormal_results_and_ties_round_once() {
        let tiny = f32::from_bits(1);
        let cases = [
            (tiny, 2.0),
            (f32::from_bits(3), 2.0),
            (f32::from_bits(5), 4.0),
            (f32::from_bits(0x007f_ffff), f32::from_bits(0x3f80_0001)),
            (f32::from_bits(0x007f_ffff), f32::from_bits(0x3f7f_ffff)),
            (f32::MIN_POSITIVE, f32::from_bits(0x3f80_0001)),
            (f32::MIN_POSITIVE, 3.0),
            (1.0, f32::MAX),
            (f32::MAX, f32::from_bits(0x3f7f_ffff)),
            (f32::MAX, 0.5),
            (1e-30, 1e20),
            (1.0, 3.0),
            (2.0, 3.0),
        ];
        for (a, b) in cases {
            for (x, y) in [(a, b), (-a, b), (a, -b)] {
                assert!(same(div_rn(x, y), x / y), "{x:e} / {y:e}");
            }
        }
    }

    /// The correction recovers the exact result from any estimate within the bound:
    /// every estimate up to 15 ulp (30 units of `q`, just inside the bound) off in
    /// either direction, on quotients and roots with every rounding outcome.
    #[test]
    fn loose_estimates_are_corrected() {
        let pairs = [(1.0f32, 3.0f32), (7.0, 9.0), (f32::from_bits(0x3fff_ffff), 1.5), (1e-40, 7.0), (5.0, 5.0)];
        for k in -15..=15 {
            for (a, b) in pairs {
                let got = div_rn_with(a, b, |x, y| off_by(x / y, k));
                assert!(same(got, a / b), "{a:e} / {b:e} with an estimate {k} ulp off");
            }
            // 0x3f800001 and 0x7163f6b8: roots just below an integer `q`, where a truncated
            // refinement of a high estimate landed two units above (found on lavapipe).
            let xs = [2.0f32, 3.0, 0.5, f32::from_bits(1), f32::MAX, 1e-20, f32::from_bits(0x3fff_ffff)];
            for x in xs.into_iter().chain([f32::from_bits(0x3f80_0001), f32::from_bits(0x7163_f6b8)]) {
                let got = sqrt_rn_with(x, |y| off_by(y.sqrt(), k));
                assert!(same(got, x.sqrt()), "sqrt {x:e} with an estimate {k} ulp off");
            }
        }
    }

    /// A sample of the exhaustive sweeps (`exhaustive_*`, ignored by default): square
    /// roots of 2^20 bit patterns spread over all 2^32, and quotients of 2^18 random pairs.
    #[test]
    fn sampled_bit_patterns_match_ieee() {
        for i in 0..(1u32 << 20) {
            let x = f32::from_bits(i.wrapping_mul(4099) ^ (i << 12));
            assert!(same(sqrt_rn(x), x.sqrt()), "sqrt {x:e} ({:#x})", x.to_bits());
        }
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..(1 << 18) {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let (a, b) = (f32::from_bits(s as u32), f32::from_bits((s >> 32) as u32));
            assert!(same(div_rn(a, b), a / b), "{a:e} / {b:e} ({:#x} / {:#x})", a.to_bits(), b.to_bits());
        }
    }

    /// Loose estimates over many operands: the refinement must land within one unit from
    /// any estimate inside the bound, above or below (the pinned cases above came from here).
    #[test]
    fn skewed_estimates_over_many_operands() {
        for k in [-15, -7, -1, 1, 7, 15] {
            for i in 0..(1u32 << 16) {
                let x = f32::from_bits(i.wrapping_mul(65_537 * 977) ^ (i << 9));
                let y = f32::from_bits(i.wrapping_mul(2_654_435_761));
                assert!(same(sqrt_rn_with(x, |v| off_by(v.sqrt(), k)), x.sqrt()), "sqrt {x:e}, skew {k}");
                assert!(same(div_rn_with(x, y, |a, b| off_by(a / b, k)), x / y), "{x:e} / {y:e}, skew {k}");
            }
        }
    }

    proptest! {
        #[test]
        fn quotients_match_ieee(a in any::<u32>(), b in any::<u32>(), k in -6i32..=6) {
            let (a, b) = (f32::from_bits(a), f32::from_bits(b));
            prop_assert!(same(div_rn(a, b), a / b));
            prop_assert!(same(div_rn_with(a, b, |x, y| off_by(x / y, k)), a / b));
        }

        #[test]
        fn roots_match_ieee(x in any::<u32>(), k in -14i32..=14) {
            let x = f32::from_bits(x);
            prop_assert!(same(sqrt_rn(x), x.sqrt()));
            prop_assert!(same(sqrt_rn_with(x, |y| off_by(y.sqrt(), k)), x.sqrt()));
        }
    }

    /// Every f32 bit pattern's square root (about 40 s in release on one core):
    /// `cargo test --release -p hyrt-core exhaustive -- --ignored`.
    #[test]
    #[ignore = "long: all 2^32 inputs; run with --release -- --ignored"]
    fn exhaustive_roots_match_ieee() {
        for i in 0..=u32::MAX {
            let x = f32::from_bits(i);
            assert!(same(sqrt_rn(x), x.sqrt()), "sqrt {x:e} ({i:#x})");
        }
    }

    /// Every f32 divisor under a few dozen dividends (ones, powers of two, all-ones
    /// significands, subnormals, the extremes), then every dividend over the same divisors.
    #[test]
    #[ignore = "long: 2 x 30 x 2^32 quotients; run with --release -- --ignored"]
    fn exhaustive_quotients_match_ieee() {
        let fixed = sweep_operands();
        for &a in &fixed {
            for i in 0..=u32::MAX {
                let b = f32::from_bits(i);
                assert!(same(div_rn(a, b), a / b), "{a:e} / {b:e} ({:#x} / {i:#x})", a.to_bits());
                assert!(same(div_rn(b, a), b / a), "{b:e} / {a:e} ({i:#x} / {:#x})", a.to_bits());
            }
        }
    }
}
