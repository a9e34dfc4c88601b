// Shading kernels of `rt_shading`, `raster_shading` and `composition`: WGSL mirrors of
// `hyrt_core::kernels::shading`, same names, same operation order.
//
// Prepended at pipeline creation by `hyrt_gpu::rt_shading::shading_source`, after the
// generated declarations and `shading_helpers.wgsl` (exact arithmetic, light evaluation:
// see there for the rules every product follows).

// mirrors hyrt_core::kernels::shading::log2_portable
fn log2_portable(x: f32) -> f32 {
    let bits = bitcast<u32>(x);
    var e = i32((bits >> 23u) & 0xffu) - 127;
    var m = bitcast<f32>((bits & 0x007fffffu) | 0x3f800000u);
    if m > SQRT_2 {
        m = m * 0.5;
        e += 1;
    }
    let t = (m - 1.0) / (m + 1.0);
    let t2 = mul(t, t);
    var p = LOG2_SERIES[0];
    p = mul(p, t2) + LOG2_SERIES[1];
    p = mul(p, t2) + LOG2_SERIES[2];
    p = mul(p, t2) + LOG2_SERIES[3];
    p = mul(p, t2) + LOG2_SERIES[4];
    return f32(e) + mul(mul(t, p), TWO_OVER_LN_2);
}

// mirrors hyrt_core::kernels::shading::exp2_portable
fn exp2_portable(z: f32) -> f32 {
    // mirrors `z.is_nan() || z < POW_FLUSH_EXPONENT`
    if !(z >= POW_FLUSH_EXPONENT) {
        return 0.0;
    }
    let n = round(z);
    let g = mul(z - n, LN_2);
    var q = EXP_SERIES[0];
    q = mul(q, g) + EXP_SERIES[1];
    q = mul(q, g) + EXP_SERIES[2];
    q = mul(q, g) + EXP_SERIES[3];
    q = mul(q, g) + EXP_SERIES[4];
    q = mul(q, g) + EXP_SERIES[5];
    q = mul(q, g) + EXP_SERIES[6];
    q = mul(q, g) + EXP_SERIES[7];
    return q * bitcast<f32>(u32(i32(n) + 127) << 23u);
}

// mirrors hyrt_core::kernels::shading::pow_portable
fn pow_portable(x: f32, y: f32) -> f32 {
    if !(x >= F32_MIN_POSITIVE) {
        return 0.0;
    }
    return exp2_portable(mul(y, log2_portable(min(x, 1.0))));
}

// mirrors hyrt_core::kernels::shading::blinn_phong_exponent
fn blinn_phong_exponent(roughness: f32) -> f32 {
    let a = max(mul(roughness, roughness), 1e-3);
    return clamp(rounded(2.0 / mul(a, a)) - 2.0, 1.0, 1e4);
}

// mirrors hyrt_core::kernels::shading::shade_ray_traced
fn shade_ray_traced(obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, e: vec3<f32>) -> vec3<f32> {
    return shade_ray_traced_with(obj, n, v, l, e, 1.0);
}

// mirrors hyrt_core::kernels::shading::shade_ray_traced_with
fn shade_ray_traced_with(obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, e: vec3<f32>,
                         diffuse_scale: f32) -> vec3<f32> {
    let ndl = dot3(n, l);
    if (ndl <= 0.0) {
        return vec3<f32>(0.0);
    }
    let base = obj.base_color;
    let diffuse = mul3(base, vec3<f32>(mul(mul(1.0 - obj.metallic, FRAC_1_PI), diffuse_scale)));
    let f0 = lerp3(vec3<f32>(DIELECTRIC_F0), base, obj.metallic);
    let h = normalize_or_zero(l + v);
    let s = blinn_phong_exponent(obj.roughness);
    let spec = mul3(f0, vec3<f32>(mul((s + 8.0) / (8.0 * PI), pow_portable(max(dot3(n, h), 0.0), s))));
    return mul3(mul3(diffuse + spec, e), vec3<f32>(ndl));
}

// mirrors hyrt_core::kernels::shading::shade_raster
fn shade_raster(obj: ObjectRecord, n: vec3<f32>, l: vec3<f32>, e: vec3<f32>) -> vec3<f32> {
    let ndl = dot3(n, l);
    if (ndl <= 0.0) {
        return vec3<f32>(0.0);
    }
    return mul3(mul3(mul3(obj.base_color, vec3<f32>(FRAC_1_PI)), e), vec3<f32>(ndl));
}

// The light filter of hyrt_core::kernels::shading::sum_visible_lights: a light counts
// when its shadow ray reached it. WGSL has no closures: each shading stage writes the
// loop of `sum_visible_lights` with its own shader (`sum_visible_lights_rt`,
// `sum_visible_lights_raster`) and this filter.
fn light_is_visible(shadow_code: u32) -> bool {
    return shadow_code == SHADOW_LIT;
}

// mirrors hyrt_core::kernels::shading::ambient
fn ambient(obj: ObjectRecord) -> vec3<f32> {
    let base = obj.base_color;
    let f0 = lerp3(vec3<f32>(DIELECTRIC_F0), base, obj.metallic);
    return mul3(base, vec3<f32>(mul(1.0 - obj.metallic, AMBIENT))) + mul3(f0, vec3<f32>(ENVIRONMENT_SPECULAR));
}

// mirrors hyrt_core::kernels::shading::compose
fn compose(raster: vec3<f32>, rt: vec3<f32>, weight: f32) -> vec3<f32> {
    return mul3(raster, vec3<f32>(1.0 - weight)) + mul3(rt, vec3<f32>(weight));
}

// True when the invocation `id` of the 2D pixel-grid dispatch is a pixel of the image
// (the grid is rounded up to whole workgroups).
fn pixel_in_image(id: vec3<u32>, width: u32, height: u32) -> bool {
    return id.x < width && id.y < height;
}
