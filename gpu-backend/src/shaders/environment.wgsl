// What secondary rays that leave the scene see: WGSL mirrors of
// hyrt_core::kernels::environment (the portable atan2 in turns, the lat-long lookup,
// the bilinear filter) and its `sky`, same names, same operation
// order, every product that feeds a sum through `mul` (shading_helpers.wgsl).
//
// Prepended by `hyrt_gpu::bounce::bounce_source` after the shading helpers and the
// generated constants ATAN_SERIES, TAN_PI_8, INV_TWO_PI, SKY_ZENITH, SKY_HORIZON,
// SKY_GROUND. The stage binds `environment: EnvironmentRecord` (uniform) and
// `environment_texels: array<vec4<f32>>`.

// True for a NaN, from its bits (a comparison the compiler may assume false).
fn is_nan_f32(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7fffffffu) > 0x7f800000u;
}

// mirrors hyrt_core::kernels::environment::sky
fn sky(d: vec3<f32>) -> vec3<f32> {
    let len = sqrt_rn(dot3(d, d));
    let y = div_rn(d.y, len);
    if is_nan_f32(y) || y < 0.0 {
        return SKY_GROUND;
    }
    return SKY_HORIZON + mul3(SKY_ZENITH - SKY_HORIZON, vec3<f32>(y));
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

fn environment_texel(i: i32, j: i32) -> vec3<f32> {
    return environment_texels[u32(j) * environment.width + u32(i)].xyz;
}

// mirrors the `lerp` of hyrt_core::kernels::environment::sample_bilinear: a + (b - a) f
fn texel_lerp(a: vec3<f32>, b: vec3<f32>, f: f32) -> vec3<f32> {
    return a + mul3(b - a, vec3<f32>(f));
}

// mirrors hyrt_core::kernels::environment::sample_bilinear
fn sample_bilinear(u: f32, v: f32) -> vec3<f32> {
    let w = i32(environment.width);
    let h = i32(environment.height);
    let x = mul(u, f32(w)) - 0.5;
    let y = mul(v, f32(h)) - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    var i0 = clamp(i32(x0), -1, w - 1);
    if i0 < 0 {
        i0 = w - 1;
    }
    var i1 = i0 + 1;
    if i1 >= w {
        i1 = 0;
    }
    let j = i32(y0);
    let j0 = clamp(j, 0, h - 1);
    let j1 = clamp(j + 1, 0, h - 1);
    let top = texel_lerp(environment_texel(i0, j0), environment_texel(i1, j0), fx);
    let bottom = texel_lerp(environment_texel(i0, j1), environment_texel(i1, j1), fx);
    return texel_lerp(top, bottom, fy);
}

// mirrors hyrt_core::kernels::environment::map_radiance
fn map_radiance(d: vec3<f32>) -> vec3<f32> {
    let uv = direction_to_uv(d);
    return sample_bilinear(uv.x, uv.y);
}

// mirrors hyrt_core::kernels::environment::environment_radiance
fn environment_radiance(d: vec3<f32>) -> vec3<f32> {
    if environment.kind == ENV_MAP {
        return map_radiance(d);
    }
    return sky(d);
}
