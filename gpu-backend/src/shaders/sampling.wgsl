// The sample sequence and the warps of stochastic rays: WGSL mirrors of
// hyrt_core::kernels::sampling, same names as the core's functions, same operation
// order. The sequence is u32 arithmetic (WGSL's wraps as the Rust side's `wrapping_*`
// operations do; `reverse_bits` is `reverseBits`) and one exact conversion to f32. In
// the warps every float operation is the Rust kernel's correctly rounded one, in its
// order: `/` and `sqrt` through div_rn and sqrt_rn, every product through `mul` and every
// sum that feeds more arithmetic behind `rounded` (the barrier the including stage
// defines: no multiply-add fusion, no algebraic rewriting of a product or sum into its
// neighbours). Vector operations are glam's scalar Vec3 ones, component by component
// (`sampling_dot3`, `sampling_cross3`, ...: names of their own, since the stages' helper
// files disagree on `mul3`).
//
// Prepended by `hyrt_gpu::shader::sampling_wgsl` after the generated constants
// SIN_SERIES, COS_SERIES and FRAC_PI_4, in a stage whose source begins with
// `hyrt_gpu::shader::preamble` (div_rn, sqrt_rn, div_rn3) and defines
// `rounded(x: f32) -> f32` and `mul(a: f32, b: f32) -> f32` (the shading helpers, or the
// ray stages' EXACT_PRODUCTS).

// mirrors Rust's f32::max: the larger operand, the other one where one is NaN (from its
// bits: a comparison a compiler may assume NaN-free does not decide it). WGSL's `max` is
// indeterminate for NaN. Equal operands give `x`: for max(-0.0, +0.0) Rust's result
// depends on its code generation (x86's maxss keeps either operand, aarch64's fmaxnm
// gives +0.0), so no caller here relies on it: every `f32_max(v, 0.0)` below has
// v != -0.0 for the inputs the core documents.
fn f32_max(x: f32, y: f32) -> f32 {
    let x_nan = (bitcast<u32>(x) & ~F32_SIGN_MASK) > F32_EXP_MASK;
    return select(x, y, x_nan || y > x);
}

// mirrors Rust's f32::min as f32_max mirrors f32::max: the smaller operand, the other one
// where one is NaN (from its bits); equal operands give `x`.
fn f32_min(x: f32, y: f32) -> f32 {
    let x_nan = (bitcast<u32>(x) & ~F32_SIGN_MASK) > F32_EXP_MASK;
    return select(x, y, x_nan || y < x);
}

// Rust's `x as f32` for a u32: rounded to nearest even, from integer operations (WGSL
// allows either neighbour for an integer above 2^24).
fn u32_to_f32_rn(x: u32) -> f32 {
    // Bits below the 24 an f32 keeps: 0 up to 2^24.
    let shift = select(0u, 8u - countLeadingZeros(x), x >= (1u << 24u));
    let kept = x >> shift;
    let rest = x & ((1u << shift) - 1u);
    let half = (1u << shift) >> 1u;
    let up = rest > half || (half != 0u && rest == half && (kept & 1u) == 1u);
    // kept + up <= 2^24 and the power of two are exact, so is their product.
    return mul(f32(kept + select(0u, 1u, up)), f32(1u << shift));
}

// `v * s` (glam's Vec3 * f32), each product behind the barrier.
fn sampling_scale3(v: vec3<f32>, s: f32) -> vec3<f32> {
    return vec3<f32>(mul(v.x, s), mul(v.y, s), mul(v.z, s));
}

fn sampling_rounded3(v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(rounded(v.x), rounded(v.y), rounded(v.z));
}

// glam's Vec3::dot: (x * x') + (y * y') + (z * z'), left to right.
fn sampling_dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return rounded(rounded(mul(a.x, b.x) + mul(a.y, b.y)) + mul(a.z, b.z));
}

// glam's Vec3::cross: (y z' - y' z, z x' - z' x, x y' - x' y).
fn sampling_cross3(a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        rounded(mul(a.y, b.z) - mul(b.y, a.z)),
        rounded(mul(a.z, b.x) - mul(b.z, a.x)),
        rounded(mul(a.x, b.y) - mul(b.x, a.y)),
    );
}

// mirrors hyrt_core::kernels::sampling::hash_u32 (lowbias32)
fn hash_u32(x_in: u32) -> u32 {
    var x = x_in;
    x ^= x >> 16u;
    x = x * 0x7feb352du;
    x ^= x >> 15u;
    x = x * 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

// mirrors hyrt_core::kernels::sampling::hash_combine
fn hash_combine(seed: u32, value: u32) -> u32 {
    return seed ^ (((hash_u32(value) + 0x9e3779b9u) + (seed << 6u)) + (seed >> 2u));
}

// mirrors hyrt_core::kernels::sampling::sample_seed
fn sample_seed(pixel: u32, stream: u32, frame: u32) -> u32 {
    return hash_combine(hash_combine(hash_u32(pixel), stream), frame);
}

// mirrors hyrt_core::kernels::sampling::laine_karras_permutation (Vegdahl's constants)
fn laine_karras_permutation(x_in: u32, seed: u32) -> u32 {
    var x = x_in;
    x ^= x * 0x3d20adeau;
    x = x + seed;
    x = x * ((seed >> 16u) | 1u);
    x ^= x * 0x05526c56u;
    x ^= x * 0x53a22864u;
    return x;
}

// mirrors hyrt_core::kernels::sampling::nested_uniform_scramble
fn nested_uniform_scramble(x: u32, seed: u32) -> u32 {
    return reverseBits(laine_karras_permutation(reverseBits(x), seed));
}

// mirrors hyrt_core::kernels::sampling::sobol_2d: the two 32-bit fractions of point `index`
// (the CPU looks the second up a byte at a time; the xor over the index's bits is the same).
fn sobol_2d(index: u32) -> vec2<u32> {
    var y = 0u;
    var v = 1u << 31u;
    var i = index;
    while i != 0u {
        if (i & 1u) != 0u {
            y ^= v;
        }
        i >>= 1u;
        v ^= v >> 1u;
    }
    return vec2<u32>(reverseBits(index), y);
}

// mirrors hyrt_core::kernels::sampling::unit_f32: the top 24 bits times 2^-24, exact.
fn unit_f32(x: u32) -> f32 {
    return mul(f32(x >> 8u), 0x1p-24f);
}

// mirrors hyrt_core::kernels::sampling::sample_2d
fn sample_2d(index: u32, seed: u32) -> vec2<f32> {
    let shuffled = nested_uniform_scramble(index, hash_combine(seed, 0u));
    let p = sobol_2d(shuffled);
    return vec2<f32>(
        unit_f32(nested_uniform_scramble(p.x, hash_combine(seed, 1u))),
        unit_f32(nested_uniform_scramble(p.y, hash_combine(seed, 2u))),
    );
}

// mirrors hyrt_core::kernels::sampling::sin_cos_quarter: `(sin x, cos x)` as `.x`, `.y`,
// for |x| <= pi/4, Horner steps over SIN_SERIES and COS_SERIES (six terms each, a const
// assertion in hyrt_gpu::shader says so).
fn sin_cos_quarter(x: f32) -> vec2<f32> {
    let x2 = mul(x, x);
    var s = SIN_SERIES[0];
    for (var i = 1u; i < 6u; i++) {
        s = rounded(mul(s, x2) + SIN_SERIES[i]);
    }
    var c = COS_SERIES[0];
    for (var i = 1u; i < 6u; i++) {
        c = rounded(mul(c, x2) + COS_SERIES[i]);
    }
    return vec2<f32>(mul(x, s), c);
}

// mirrors hyrt_core::kernels::sampling::concentric_disk (Shirley and Chiu's map)
fn concentric_disk(u: vec2<f32>) -> vec2<f32> {
    let a = rounded(mul(2.0, u.x) - 1.0);
    let b = rounded(mul(2.0, u.y) - 1.0);
    if a == 0.0 && b == 0.0 {
        return vec2<f32>(0.0, 0.0);
    }
    if abs(a) > abs(b) {
        let sc = sin_cos_quarter(mul(FRAC_PI_4, div_rn(b, a)));
        return vec2<f32>(mul(a, sc.y), mul(a, sc.x));
    }
    let sc = sin_cos_quarter(mul(FRAC_PI_4, div_rn(a, b)));
    return vec2<f32>(mul(b, sc.x), mul(b, sc.y));
}

// mirrors hyrt_core::kernels::sampling::cosine_hemisphere (Malley's method)
fn cosine_hemisphere(u: vec2<f32>) -> vec3<f32> {
    let xy = concentric_disk(u);
    let x = xy.x;
    let y = xy.y;
    // 1 - x^2 - y^2 is never -0.0 (a difference is -0.0 only from -0.0 - +0.0).
    let z = sqrt_rn(f32_max(rounded(rounded(1.0 - mul(x, x)) - mul(y, y)), 0.0));
    return vec3<f32>(x, y, z);
}

// mirrors hyrt_core::kernels::sampling::uniform_cone. `k (2 - k)` is -0.0 only for a
// `one_minus_cos_max` of -0.0 or below, outside the documented [0, 2] (f32_max).
fn uniform_cone(u: vec2<f32>, one_minus_cos_max: f32) -> vec3<f32> {
    let xy = concentric_disk(u);
    let x = xy.x;
    let y = xy.y;
    let r2 = rounded(mul(x, x) + mul(y, y));
    if r2 == 0.0 {
        return vec3<f32>(0.0, 0.0, 1.0);
    }
    let k = mul(r2, one_minus_cos_max);
    let sin_theta = sqrt_rn(f32_max(mul(k, rounded(2.0 - k)), 0.0));
    let scale = div_rn(sin_theta, sqrt_rn(r2));
    return vec3<f32>(mul(x, scale), mul(y, scale), rounded(1.0 - k));
}

// The tangent and bitangent of orthonormal_basis (Rust's `(t, b)`).
struct OrthonormalBasis {
    t: vec3<f32>,
    b: vec3<f32>,
}

// mirrors hyrt_core::kernels::sampling::orthonormal_basis (Duff et al. 2017); the sign
// of n.z with `>= 0.0`, as in Rust (-0.0 counts as positive, NaN as negative).
fn orthonormal_basis(n: vec3<f32>) -> OrthonormalBasis {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = div_rn(-1.0, rounded(sign + n.z));
    let b = mul(mul(n.x, n.y), a);
    let t = vec3<f32>(rounded(1.0 + mul(mul(sign, mul(n.x, n.x)), a)), mul(sign, b), mul(-sign, n.x));
    let bt = vec3<f32>(b, rounded(sign + mul(mul(n.y, n.y), a)), -n.y);
    return OrthonormalBasis(t, bt);
}

// mirrors hyrt_core::kernels::sampling::to_frame: (t local.x + b local.y) + n local.z
fn to_frame(local: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let f = orthonormal_basis(n);
    let tb = sampling_rounded3(sampling_scale3(f.t, local.x) + sampling_scale3(f.b, local.y));
    return sampling_rounded3(tb + sampling_scale3(n, local.z));
}

// mirrors hyrt_core::kernels::sampling::quad_point: (corner + edge_u u) + edge_v v
fn quad_point(corner: vec3<f32>, edge_u: vec3<f32>, edge_v: vec3<f32>, u: vec2<f32>) -> vec3<f32> {
    let cu = sampling_rounded3(corner + sampling_scale3(edge_u, u.x));
    return sampling_rounded3(cu + sampling_scale3(edge_v, u.y));
}
