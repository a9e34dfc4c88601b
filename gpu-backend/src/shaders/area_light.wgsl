// One sample of a quad light, a sphere light, a sun of finite angular size or the table of
// emissive triangles seen from a surface point: WGSL mirrors of
// hyrt_core::kernels::area_light, same names as the core's functions, same operation
// order, every product through `mul` and every sum that feeds more arithmetic behind
// `rounded` (sampling.wgsl says why).
//
// Prepended by `hyrt_gpu::shader::area_light_wgsl` after sampling.wgsl (to_frame,
// uniform_cone, quad_point and the vector helpers) and the generated constants
// MIN_AREA_LIGHT_DISTANCE_SQ, TAU and ONE_BELOW_ONE; the stage binds `params: FrameParams`
// (its always-zero word makes the sun's infinite distance at run time: WGSL has no
// infinite literal) and defines the frame's emitter table, which the core kernels take as
// a slice: `emitter_count() -> u32` and `emitter_at(i: u32) -> EmitterRecord`
// (soft_shadow.wgsl reads it from the lights' binding, hyrt_gpu::buffers::SceneBuffers::lights).

// mirrors hyrt_core::kernels::area_light::LightSample; `valid` false for Rust's `None`
// (then every other field is zero).
struct LightSample {
    l: vec3<f32>,
    distance: f32,
    weight: vec3<f32>,
    valid: bool,
}

// Rust's `None`.
fn no_light_sample() -> LightSample {
    return LightSample(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), false);
}

// mirrors hyrt_core::kernels::area_light::sample_quad_light
fn sample_quad_light(corner: vec3<f32>, edge_u: vec3<f32>, edge_v: vec3<f32>, radiance: vec3<f32>, p: vec3<f32>,
                     u: vec2<f32>) -> LightSample {
    let q = quad_point(corner, edge_u, edge_v, u);
    let d = sampling_rounded3(q - p);
    let d2 = f32_max(sampling_dot3(d, d), MIN_AREA_LIGHT_DISTANCE_SQ);
    let distance = sqrt_rn(d2);
    let l = div_rn3(d, distance);
    let normal = sampling_cross3(edge_u, edge_v);
    // cos_light * area = (-l) . (edge_u x edge_v): the normal's length is the area.
    let cos_area = -sampling_dot3(l, normal);
    if cos_area <= 0.0 {
        return no_light_sample();
    }
    return LightSample(l, distance, sampling_scale3(radiance, div_rn(cos_area, d2)), true);
}

// mirrors hyrt_core::kernels::area_light::sphere_cone_one_minus_cos: s / (1 + sqrt(1 - s)),
// s = r2 / d2 (1 - s is never -0.0: f32_max).
fn sphere_cone_one_minus_cos(r2: f32, d2: f32) -> f32 {
    let s = div_rn(r2, d2);
    return div_rn(s, rounded(1.0 + sqrt_rn(f32_max(rounded(1.0 - s), 0.0))));
}

// mirrors hyrt_core::kernels::area_light::sample_sphere_light; not valid from inside the
// sphere. `b^2 - c` is never -0.0 (c > 0).
fn sample_sphere_light(centre: vec3<f32>, radius: f32, radiance: vec3<f32>, p: vec3<f32>, u: vec2<f32>) -> LightSample {
    let dc = sampling_rounded3(centre - p);
    let d2 = sampling_dot3(dc, dc);
    let r2 = mul(radius, radius);
    if d2 <= r2 {
        return no_light_sample();
    }
    let k = sphere_cone_one_minus_cos(r2, d2);
    let axis = div_rn3(dc, sqrt_rn(d2));
    let l = to_frame(uniform_cone(u, k), axis);
    let b = sampling_dot3(l, dc);
    let c = rounded(d2 - r2);
    let distance = rounded(b - sqrt_rn(f32_max(rounded(mul(b, b) - c), 0.0)));
    let solid_angle = mul(TAU, k);
    return LightSample(l, distance, sampling_scale3(radiance, solid_angle), true);
}

// mirrors hyrt_core::kernels::area_light::sample_sun: at infinite distance (+inf from its
// bits at run time).
fn sample_sun(direction: vec3<f32>, one_minus_cos: f32, illuminance: vec3<f32>, u: vec2<f32>) -> LightSample {
    let l = to_frame(uniform_cone(u, one_minus_cos), -direction);
    return LightSample(l, bitcast<f32>(F32_EXP_MASK | params.zero), illuminance, true);
}

// mirrors the tuple hyrt_core::kernels::area_light::pick_emitter returns: the emitter's
// index in the table, its picking probability and the sequence coordinate remapped into
// its bin.
struct EmitterPick {
    index: u32,
    p: f32,
    x: f32,
}

// mirrors hyrt_core::kernels::area_light::pick_emitter: the first emitter whose cdf
// exceeds `x` (binary search over the table, not empty), its probability and `x` remapped,
// `min((x - cdf_{i-1}) / p_i, ONE_BELOW_ONE)`.
fn pick_emitter(x: f32) -> EmitterPick {
    var lo = 0u;
    var hi = emitter_count() - 1u;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if x < emitter_at(mid).cdf {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    var below = 0.0;
    if lo != 0u {
        below = emitter_at(lo - 1u).cdf;
    }
    let p = rounded(emitter_at(lo).cdf - below);
    return EmitterPick(lo, p, f32_min(div_rn(rounded(x - below), p), ONE_BELOW_ONE));
}

// mirrors hyrt_core::kernels::area_light::triangle_point: (v0 + e1 (s (1 - v))) + e2 (s v),
// s = sqrt(u).
fn triangle_point(v0: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>, u: vec2<f32>) -> vec3<f32> {
    let s = sqrt_rn(u.x);
    let a = sampling_rounded3(v0 + sampling_scale3(e1, mul(s, rounded(1.0 - u.y))));
    return sampling_rounded3(a + sampling_scale3(e2, mul(s, u.y)));
}

// mirrors hyrt_core::kernels::area_light::sample_emitters; not valid for an empty table,
// where the point faces away from `p` (the back of a single-sided triangle) or `p` lies in
// its plane. `abs` is exact.
fn sample_emitters(p: vec3<f32>, u: vec2<f32>) -> LightSample {
    if emitter_count() == 0u {
        return no_light_sample();
    }
    let pick = pick_emitter(u.x);
    let e = emitter_at(pick.index);
    let q = triangle_point(e.v0, e.e1, e.e2, vec2<f32>(pick.x, u.y));
    let d = sampling_rounded3(q - p);
    let d2 = f32_max(sampling_dot3(d, d), MIN_AREA_LIGHT_DISTANCE_SQ);
    let distance = sqrt_rn(d2);
    let l = div_rn3(d, distance);
    let cos_one_side = -sampling_dot3(l, sampling_cross3(e.e1, e.e2));
    let cos_twice_area = select(cos_one_side, abs(cos_one_side), (e.flags & EMITTER_DOUBLE_SIDED) != 0u);
    if cos_twice_area <= 0.0 {
        return no_light_sample();
    }
    let scale = div_rn(div_rn(mul(cos_twice_area, 0.5), d2), pick.p);
    return LightSample(l, distance, sampling_scale3(e.radiance, scale), true);
}
