// One sample of a quad light, a sphere light or a sun of finite angular size seen from a
// surface point: WGSL mirrors of hyrt_core::kernels::area_light, same names as the core's
// functions, same operation order, every product through `mul` and every sum that feeds
// more arithmetic behind `rounded` (sampling.wgsl says why).
//
// Prepended by `hyrt_gpu::shader::area_light_wgsl` after sampling.wgsl (to_frame,
// uniform_cone, quad_point and the vector helpers) and the generated constants
// MIN_AREA_LIGHT_DISTANCE_SQ and TAU; the stage binds `params: FrameParams` (its
// always-zero word makes the sun's infinite distance at run time: WGSL has no infinite
// literal).

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
