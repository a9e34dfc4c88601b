// Shading kernels of `rt_shading`, `raster_shading` and `composition`: WGSL mirrors of
// `hyrt_core::kernels::shading`, same names, same operation order. (`ambient` and
// `unlit`, which read the frame's ambient light, are in surface_shading.wgsl: the stages
// that include only this file bind none.)
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
    let t = div_rn(m - 1.0, m + 1.0);
    let t2 = mul(t, t);
    var p = LOG2_SERIES[0];
    p = mul(p, t2) + LOG2_SERIES[1];
    p = mul(p, t2) + LOG2_SERIES[2];
    p = mul(p, t2) + LOG2_SERIES[3];
    p = mul(p, t2) + LOG2_SERIES[4];
    return rounded(f32(e) + mul(mul(t, p), TWO_OVER_LN_2));
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
    return clamp(rounded(div_rn(2.0, mul(a, a))) - 2.0, 1.0, 1e4);
}

// mirrors glam::Vec3::cross: (y z' - y' z, z x' - z' x, x y' - x' y).
fn cross3(a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        rounded(mul(a.y, b.z) - mul(b.y, a.z)),
        rounded(mul(a.z, b.x) - mul(b.z, a.x)),
        rounded(mul(a.x, b.y) - mul(b.x, a.y)),
    );
}

// Every sum, difference, square root and quotient below goes through `rounded` before
// it feeds more arithmetic, as `mul` does for products: the shader compiler may lower a
// square root or a quotient through a reciprocal and fuse that product into the sum that
// consumes it.

// mirrors hyrt_core::kernels::shading::schlick_weight
fn schlick_weight(v_dot_h: f32) -> f32 {
    let x = rounded(1.0 - abs(v_dot_h));
    let x2 = mul(x, x);
    return mul(mul(x2, x2), x);
}

// mirrors hyrt_core::kernels::shading::ggx_distribution
fn ggx_distribution(alpha: f32, n_dot_h: f32, sin_sq: f32) -> f32 {
    if (n_dot_h <= 0.0) {
        return 0.0;
    }
    let a2 = mul(alpha, alpha);
    let k = rounded(sin_sq + mul(mul(n_dot_h, n_dot_h), a2));
    return rounded(div_rn(a2, mul(PI, mul(k, k))));
}

// mirrors hyrt_core::kernels::shading::smith_visibility
fn smith_visibility(alpha: f32, n_dot_l: f32, n_dot_v: f32, h_dot_l: f32, h_dot_v: f32) -> f32 {
    if (h_dot_l <= 0.0 || h_dot_v <= 0.0) {
        return 0.0;
    }
    let a2 = mul(alpha, alpha);
    let one_minus_a2 = rounded(1.0 - a2);
    let gl = rounded(abs(n_dot_l) + rounded(sqrt_rn(rounded(a2 + mul(one_minus_a2, mul(n_dot_l, n_dot_l))))));
    let gv = rounded(abs(n_dot_v) + rounded(sqrt_rn(rounded(a2 + mul(one_minus_a2, mul(n_dot_v, n_dot_v))))));
    return rounded(div_rn(1.0, mul(gl, gv)));
}

// mirrors hyrt_core::kernels::shading::gltf_brdf
fn gltf_brdf(base: vec3<f32>, metallic: f32, roughness: f32, diffuse_scale: f32, n: vec3<f32>, v: vec3<f32>,
             l: vec3<f32>) -> vec3<f32> {
    let h = normalize_or_zero(l + v);
    let alpha = max(mul(roughness, roughness), GGX_MIN_ALPHA);
    let nxh = cross3(n, h);
    let d = ggx_distribution(alpha, dot3(n, h), dot3(nxh, nxh));
    let specular = mul(d, smith_visibility(alpha, dot3(n, l), dot3(n, v), dot3(h, l), dot3(h, v)));
    let w = schlick_weight(dot3(v, h));
    let f_dielectric = rounded(DIELECTRIC_F0 + mul(rounded(1.0 - DIELECTRIC_F0), w));
    let diffuse = mul3(base, vec3<f32>(mul(FRAC_1_PI, diffuse_scale)));
    let dielectric = mul3(diffuse, vec3<f32>(rounded(1.0 - f_dielectric))) + vec3<f32>(mul(specular, f_dielectric));
    let metal = mul3(base + mul3(vec3<f32>(1.0) - base, vec3<f32>(w)), vec3<f32>(specular));
    return mul3(dielectric, vec3<f32>(rounded(1.0 - metallic))) + mul3(metal, vec3<f32>(metallic));
}

// mirrors hyrt_core::kernels::shading::shade_gltf_with
fn shade_gltf_with(obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, e: vec3<f32>,
                   diffuse_scale: f32) -> vec3<f32> {
    let ndl = dot3(n, l);
    if (ndl <= 0.0) {
        return vec3<f32>(0.0);
    }
    let f = gltf_brdf(obj.base_color, obj.metallic, obj.roughness, diffuse_scale, n, v, l);
    return mul3(mul3(f, e), vec3<f32>(ndl));
}

// mirrors hyrt_core::kernels::shading::shade_ray_traced
fn shade_ray_traced(obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, e: vec3<f32>) -> vec3<f32> {
    return shade_ray_traced_with(obj, n, v, l, e, 1.0);
}

// mirrors hyrt_core::kernels::shading::shade_ray_traced_with
fn shade_ray_traced_with(obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, e: vec3<f32>,
                         diffuse_scale: f32) -> vec3<f32> {
    if ((obj.flags & OBJ_GLTF_BRDF) != 0u) {
        return shade_gltf_with(obj, n, v, l, e, diffuse_scale);
    }
    let ndl = dot3(n, l);
    if (ndl <= 0.0) {
        return vec3<f32>(0.0);
    }
    let base = obj.base_color;
    let diffuse = mul3(base, vec3<f32>(mul(mul(1.0 - obj.metallic, FRAC_1_PI), diffuse_scale)));
    let f0 = lerp3(vec3<f32>(DIELECTRIC_F0), base, obj.metallic);
    let h = normalize_or_zero(l + v);
    let s = blinn_phong_exponent(obj.roughness);
    let spec = mul3(f0, vec3<f32>(mul(div_rn(s + 8.0, 8.0 * PI), pow_portable(max(dot3(n, h), 0.0), s))));
    return mul3(mul3(diffuse + spec, e), vec3<f32>(ndl));
}

// mirrors hyrt_core::kernels::shading::shade_raster
fn shade_raster(obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, e: vec3<f32>) -> vec3<f32> {
    if ((obj.flags & OBJ_GLTF_BRDF) != 0u) {
        return shade_gltf_with(obj, n, v, l, e, 1.0);
    }
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

// mirrors hyrt_core::kernels::shading::compose
fn compose(raster: vec3<f32>, rt: vec3<f32>, weight: f32) -> vec3<f32> {
    return mul3(raster, vec3<f32>(1.0 - weight)) + mul3(rt, vec3<f32>(weight));
}

// True when the invocation `id` of the 2D pixel-grid dispatch is a pixel of the image
// (the grid is rounded up to whole workgroups).
fn pixel_in_image(id: vec3<u32>, width: u32, height: u32) -> bool {
    return id.x < width && id.y < height;
}
