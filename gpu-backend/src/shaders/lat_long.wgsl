// The lat-long lookup of hyrt_core::kernels::environment without a binding: the
// portable atan2 in turns, the direction's texture coordinates and the bilinear blend's
// lerp, WGSL mirrors by the same names, same operation order, every product that feeds a
// sum through `mul` (shading_helpers.wgsl). Shared by environment.wgsl (what secondary
// rays that leave the scene see) and ambient_light.wgsl (the image-based light's
// prefiltered levels).
//
// Prepended by `hyrt_gpu::shader::lat_long_wgsl` after the shading helpers and the
// generated constants ATAN_SERIES, TAN_PI_8, INV_TWO_PI.

// True for a NaN, from its bits (a comparison the compiler may assume false).
fn is_nan_f32(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7fffffffu) > 0x7f800000u;
}

// mirrors hyrt_core::kernels::environment::atan2_turns
fn atan2_turns(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    let swapped = ay > ax;
    let num = select(ay, ax, swapped);
    let den = select(ax, ay, swapped);
    if den == 0.0 || is_nan_f32(den) {
        return 0.0;
    }
    let t = div_rn(num, den);
    var s = t;
    var base = 0.0;
    if t > TAN_PI_8 {
        s = div_rn(t - 1.0, t + 1.0);
        base = 0.125;
    }
    let s2 = mul(s, s);
    var p = ATAN_SERIES[0];
    for (var i = 1u; i < 9u; i++) {
        p = mul(p, s2) + ATAN_SERIES[i];
    }
    var a = base + mul(mul(s, p), INV_TWO_PI);
    if swapped {
        a = 0.25 - a;
    }
    if x < 0.0 {
        a = 0.5 - a;
    }
    if y < 0.0 {
        return -a;
    }
    return a;
}

// mirrors hyrt_core::kernels::environment::direction_to_uv
fn direction_to_uv(d: vec3<f32>) -> vec2<f32> {
    var u = atan2_turns(d.x, -d.z);
    if u < 0.0 {
        u += 1.0;
    }
    let r = sqrt_rn(rounded(mul(d.x, d.x) + mul(d.z, d.z)));
    let v = 2.0 * atan2_turns(r, d.y);
    return vec2<f32>(u, v);
}

// mirrors the `lerp` of hyrt_core::kernels::environment::sample_bilinear_grid: a + (b - a) f
fn texel_lerp(a: vec3<f32>, b: vec3<f32>, f: f32) -> vec3<f32> {
    return a + mul3(b - a, vec3<f32>(f));
}

// The texels and weights of hyrt_core::kernels::environment::sample_bilinear_grid on a
// `w` x `h` lat-long grid at `(u, v)`: columns `i0`, `i1` (wrapping), rows `j0`, `j1`
// (clamped), fractions `fx`, `fy`. Every grid's sampler (sample_bilinear,
// sample_prefiltered_level) blends its own texels with them, in the core's order.
struct BilinearTaps {
    i0: i32,
    i1: i32,
    j0: i32,
    j1: i32,
    fx: f32,
    fy: f32,
}

// mirrors the index and weight part of hyrt_core::kernels::environment::sample_bilinear_grid
fn bilinear_taps(w: i32, h: i32, u: f32, v: f32) -> BilinearTaps {
    let x = mul(u, f32(w)) - 0.5;
    let y = mul(v, f32(h)) - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    var i0 = clamp(i32(x0), -1, w - 1);
    if i0 < 0 {
        i0 = w - 1;
    }
    var i1 = i0 + 1;
    if i1 >= w {
        i1 = 0;
    }
    let j = i32(y0);
    return BilinearTaps(i0, i1, clamp(j, 0, h - 1), clamp(j + 1, 0, h - 1), x - x0, y - y0);
}
