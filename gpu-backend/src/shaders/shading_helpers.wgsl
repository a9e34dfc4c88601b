// Shading helpers shared by the shading stages (`rt_shading`, `raster_shading`,
// `composition`) and `compaction`: exact f32 arithmetic and light evaluation, WGSL
// mirrors of `hyrt_core::kernels::shading`, same names, same operation order.
//
// Prepended at pipeline creation by `hyrt_gpu::rt_shading::shading_helpers`, after the
// generated records and format constants (`hyrt_core::formats::wgsl::declarations`) and
// a generated prelude that defines the shading constants from their Rust values, bit
// for bit: AMBIENT, ENVIRONMENT_SPECULAR, BACKGROUND, DIELECTRIC_F0,
// MIN_LIGHT_DISTANCE_SQ, FRAC_1_PI, PI (std::f32::consts), F32_MAX, ...
// Vectors are combined component by component exactly as glam's scalar Vec3 does;
// dot products are written out (x, then y, then z) as glam's `Vec3::dot`.
// Every product that feeds a sum goes through `mul`, which ORs the always-zero
// `params.zero` into its bits: the compiler cannot see through it, so it cannot fuse the
// product into a multiply-add (lavapipe does fuse plain vector expressions), and the
// results are the CPU's bits. Every stage that includes this file binds
// `params: FrameParams`.

fn rounded(x: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(x) | params.zero);
}

fn mul(a: f32, b: f32) -> f32 {
    return rounded(a * b);
}

fn rounded3(v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(rounded(v.x), rounded(v.y), rounded(v.z));
}

fn mul3(a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(mul(a.x, b.x), mul(a.y, b.y), mul(a.z, b.z));
}

// mirrors glam::Vec3::dot: (x * x') + (y * y') + (z * z').
fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return rounded(mul(a.x, b.x) + mul(a.y, b.y)) + mul(a.z, b.z);
}

// mirrors glam::Vec3::normalize_or_zero: v * (1 / sqrt(v.v)) (through div_rn and
// sqrt_rn) when that reciprocal is finite and positive, else zero.
fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let rcp = div_rn(1.0, sqrt_rn(dot3(v, v)));
    if (rcp > 0.0 && rcp <= F32_MAX) {
        // Each product behind the barrier: a caller's sum (the half vector `l + v`) would
        // otherwise fuse with it on devices that contract (NVIDIA does; lavapipe did not).
        return mul3(v, vec3<f32>(rcp));
    }
    return vec3<f32>(0.0);
}

// mirrors glam::Vec3::lerp: a * (1 - s) + b * s.
fn lerp3(a: vec3<f32>, b: vec3<f32>, s: f32) -> vec3<f32> {
    return mul3(a, vec3<f32>(1.0 - s)) + mul3(b, vec3<f32>(s));
}

// Result of `light_incidence`: the unit direction towards the light and the irradiance scale.
struct Incidence {
    l: vec3<f32>,
    e: vec3<f32>,
}

// mirrors hyrt_core::kernels::shading::light_incidence
fn light_incidence(light: LightRecord, p: vec3<f32>) -> Incidence {
    let radiance = light.radiance;
    let pd = light.position_or_direction;
    if (light.kind == LIGHT_DIRECTIONAL) {
        return Incidence(-pd, radiance);
    }
    let d = pd - p;
    let d2 = max(dot3(d, d), MIN_LIGHT_DISTANCE_SQ);
    let l = div_rn3(d, sqrt_rn(d2));
    return Incidence(l, mul3(div_rn3(radiance, d2), vec3<f32>(light_falloff(light, l, d2))));
}

// mirrors hyrt_core::kernels::shading::light_falloff: KHR_lights_punctual's range window
// and spot cone factor, 1 for a point light without a range.
fn light_falloff(light: LightRecord, l: vec3<f32>, d2: f32) -> f32 {
    var f = 1.0;
    if (light.inv_range_sq > 0.0) {
        let x = mul(d2, light.inv_range_sq);
        f = clamp(1.0 - mul(x, x), 0.0, 1.0);
    }
    if (light.kind == LIGHT_SPOT) {
        let cd = -dot3(light.spot_direction, l);
        let a = clamp(mul(cd, light.spot_scale) + light.spot_offset, 0.0, 1.0);
        f = mul(f, mul(a, a));
    }
    return f;
}

// mirrors glam::Vec3::max_element: max(x, max(y, z)), each `if a > b { a } else { b }`.
fn max_element3(v: vec3<f32>) -> f32 {
    let m_yz = select(v.z, v.y, v.y > v.z);
    return select(m_yz, v.x, v.x > m_yz);
}

// mirrors hyrt_core::kernels::shading::light_can_contribute
fn light_can_contribute(n_geo: vec3<f32>, n_shade: vec3<f32>, l: vec3<f32>, e: vec3<f32>) -> bool {
    return dot3(n_geo, l) > 0.0 && dot3(n_shade, l) > 0.0 && max_element3(e) > 0.0;
}
