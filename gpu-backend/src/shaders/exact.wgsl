// Correctly rounded division and square root from integer arithmetic: mirrors
// hyrt_core::kernels::exact (div_rn, sqrt_rn), step for step; the module docs there say
// why and how. Every shader divides floats and takes square roots only through these
// (a test walks every module's IR: gpu-backend/tests/exact.rs): WGSL's `/` on floats and
// `sqrt` may be off by 2.5 and about 3 ulp on real GPUs, which compute `a * rcp(b)`.
//
// Prepended to every stage's source after the generated records by
// `hyrt_gpu::shader::preamble`, with EXACT_DEFAULT_NAN generated from its Rust
// value. The estimate may be off by fewer than hyrt_core's EXACT_ESTIMATE_UNITS units.
//
// Only integer operations decide the result: the float estimate (`/` or `sqrt` of small
// exact integers) may be a few ulp off and is corrected exactly, without loops (lavapipe's
// LLVM took minutes over a correction loop inlined at every division). WGSL's u32 and i32
// arithmetic wraps, as the Rust side's `wrapping_*` operations do.

// The fields of an f32's bits, for every shader (each begins with this preamble).
const F32_SIGN_MASK: u32 = 0x80000000u;
const F32_EXP_MASK: u32 = 0x7f800000u;
const F32_FRACTION_MASK: u32 = 0x007fffffu;

// Rust's `f32::is_finite` (not inf, not NaN), as a test of the exponent bits: no float
// comparison a compiler may assume NaN-free.
fn f32_is_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & F32_EXP_MASK) != F32_EXP_MASK;
}

const EXACT_QUIET: u32 = 0x00400000u;
const EXACT_IMPLICIT: u32 = 0x00800000u;
const EXACT_BIAS: i32 = 127;

// A finite, non-zero magnitude's significand in [2^23, 2^24) and unbiased exponent:
// x = m * 2^(e - 23). Subnormals are normalized.
struct ExactUnpacked {
    m: u32,
    e: i32,
}

// mirrors hyrt_core::kernels::exact::unpack
fn exact_unpack(abs_bits: u32) -> ExactUnpacked {
    let field = i32(abs_bits >> 23u);
    let shift = countLeadingZeros(abs_bits) - 8u; // subnormals: normalize
    let subnormal = field == 0;
    return ExactUnpacked(
        select((abs_bits & F32_FRACTION_MASK) | EXACT_IMPLICIT, abs_bits << (shift & 31u), subnormal),
        select(field - EXACT_BIAS, 1 - EXACT_BIAS - i32(shift), subnormal),
    );
}

// mirrors hyrt_core::kernels::exact::round_pack: the bits of q * 2^(e - 24) rounded to
// nearest even, q in [2^24, 2^25) with its guard bit, `sticky` for anything below.
fn exact_round_pack(q: u32, sticky: bool, e: i32) -> u32 {
    let biased = e + EXACT_BIAS;
    let normal = biased >= 1;
    let shift = select(u32(min(2 - biased, 31)), 1u, normal);
    let base = select(0u, u32(max(biased, 1) - 1) << 23u, normal);
    let kept = q >> shift;
    let rest = q & ((1u << shift) - 1u);
    let half = 1u << (shift - 1u);
    let up = rest > half || (rest == half && (sticky || (kept & 1u) == 1u));
    return select(base + kept + select(0u, 1u, up), F32_EXP_MASK, biased >= 255);
}

// An estimate moved by `skew` ulp (0 in every stage; the helpers' test moves it to check
// the correction, as the Rust tests' loose estimates do).
fn exact_skewed(x: f32, skew: i32) -> f32 {
    return bitcast<f32>(bitcast<i32>(x) + skew);
}

// mirrors hyrt_core::kernels::exact::div_rn_with, the estimate `/` moved by `skew` ulp.
// Straight-line: the special cases are selected at the end (the general path runs on
// stand-in operands), which keeps lavapipe's compiler and real GPUs' branches simple.
fn div_rn_skewed(a: f32, b: f32, skew: i32) -> f32 {
    let ab = bitcast<u32>(a);
    let bb = bitcast<u32>(b);
    let sign = (ab ^ bb) & F32_SIGN_MASK;
    let ax = ab & ~F32_SIGN_MASK;
    let bx = bb & ~F32_SIGN_MASK;
    // Zeros, infinities and NaNs take the stand-in 1 / 1.
    let general = ax != 0u && bx != 0u && ax < F32_EXP_MASK && bx < F32_EXP_MASK;
    let ua = exact_unpack(select(0x3f800000u, ax, general));
    let ub = exact_unpack(select(0x3f800000u, bx, general));
    let below = ua.m < ub.m;
    let ma = select(ua.m, ua.m << 1u, below);
    let mb = ub.m;
    let e = ua.e - ub.e - select(0, 1, below);
    // ma / mb in [1, 2): q = floor(ma * 2^24 / mb) in [2^24, 2^25).
    let numerator = ma << 24u; // ma * 2^24 modulo 2^32
    let guess = exact_skewed(f32(ma) / f32(mb), skew) * 16777216.0;
    let q0 = clamp(u32(guess), 1u << 24u, (1u << 25u) - 1u);
    let r0 = bitcast<i32>(numerator - q0 * mb);
    // One refinement by r0 / mb (the estimate's error in units), rounded down: within one unit.
    let q1 = q0 + bitcast<u32>(i32(floor(f32(r0) / f32(mb))));
    let r1 = bitcast<i32>(numerator - q1 * mb);
    let step = i32(mb);
    let low = r1 < 0;
    let q2 = q1 - select(0u, 1u, low);
    let r2 = r1 + select(0, step, low);
    let high = r2 >= step;
    let q = q2 + select(0u, 1u, high);
    let r = r2 - select(0, step, high);
    let finite = sign | exact_round_pack(q, r != 0, e);
    // The special cases, the Rust kernel's early returns from last to first (the last
    // select that applies wins, as the first return that applies does there).
    var special = sign; // a zero dividend
    special = select(special, select(sign | F32_EXP_MASK, EXACT_DEFAULT_NAN, ax == 0u), bx == 0u);
    special = select(special, sign, bx == F32_EXP_MASK);
    special = select(special, select(sign | F32_EXP_MASK, EXACT_DEFAULT_NAN, bx == F32_EXP_MASK), ax == F32_EXP_MASK);
    special = select(special, bb | EXACT_QUIET, bx > F32_EXP_MASK);
    special = select(special, ab | EXACT_QUIET, ax > F32_EXP_MASK);
    return bitcast<f32>(select(special, finite, general));
}

// mirrors hyrt_core::kernels::exact::sqrt_rn_with, the estimate `sqrt` moved by `skew` ulp.
// Straight-line, as div_rn_skewed.
fn sqrt_rn_skewed(x: f32, skew: i32) -> f32 {
    let bits = bitcast<u32>(x);
    let abs_bits = bits & ~F32_SIGN_MASK;
    // Zeros, negatives, infinities and NaNs take the stand-in sqrt(1).
    let general = abs_bits != 0u && (bits & F32_SIGN_MASK) == 0u && abs_bits < F32_EXP_MASK;
    let u = exact_unpack(select(0x3f800000u, abs_bits, general));
    let odd = (u.e & 1) != 0;
    let m = select(u.m, u.m << 1u, odd);
    let e = u.e - select(0, 1, odd);
    // m in [2^23, 2^25): q = floor(sqrt(m * 2^25)) in [2^24, 2^25).
    let radicand = m << 25u; // m * 2^25 modulo 2^32
    let guess = exact_skewed(sqrt(f32(2u * m)), skew) * 4096.0;
    let q0 = clamp(u32(guess), 1u << 24u, (1u << 25u) - 1u);
    let r0 = bitcast<i32>(radicand - q0 * q0);
    // One refinement by r0 / (2 q0) ~ sqrt(R) - q0, rounded down: within one unit.
    let q1 = q0 + bitcast<u32>(i32(floor(f32(r0) / f32(2u * q0))));
    let r1 = bitcast<i32>(radicand - q1 * q1);
    // (q - 1)^2 = q^2 - (2q - 1); (q + 1)^2 = q^2 + 2q + 1
    let low = r1 < 0;
    let q2 = q1 - select(0u, 1u, low);
    let r2 = r1 + select(0, bitcast<i32>(2u * q2 + 1u), low);
    let high = r2 > bitcast<i32>(2u * q2);
    let r = r2 - select(0, bitcast<i32>(2u * q2 + 1u), high);
    let q = q2 + select(0u, 1u, high);
    let finite = exact_round_pack(q, r != 0, e >> 1u);
    // The special cases, in the Rust kernel's order: NaN, zero, negative, +infinity.
    var special = bits; // +-0 and +infinity are their own roots
    special = select(special, EXACT_DEFAULT_NAN, (bits & F32_SIGN_MASK) != 0u && abs_bits != 0u);
    special = select(special, bits | EXACT_QUIET, abs_bits > F32_EXP_MASK);
    return bitcast<f32>(select(special, finite, general));
}

// mirrors hyrt_core::kernels::exact::div_rn: a / b, correctly rounded (IEEE 754's `/`).
fn div_rn(a: f32, b: f32) -> f32 {
    return div_rn_skewed(a, b, 0);
}

// mirrors hyrt_core::kernels::exact::sqrt_rn: sqrt(x), correctly rounded (IEEE 754's).
fn sqrt_rn(x: f32) -> f32 {
    return sqrt_rn_skewed(x, 0);
}

// Component-wise `v / s`, each through div_rn (glam's Vec3 / f32).
fn div_rn3(v: vec3<f32>, s: f32) -> vec3<f32> {
    return vec3<f32>(div_rn(v.x, s), div_rn(v.y, s), div_rn(v.z, s));
}
