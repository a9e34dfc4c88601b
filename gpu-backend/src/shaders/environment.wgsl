// What secondary rays that leave the scene see: WGSL mirrors of
// hyrt_core::kernels::environment (the bilinear filter over the scene's map) and its
// `sky`, same names, same operation order, every product that feeds a sum through `mul`
// (shading_helpers.wgsl).
//
// Prepended by `hyrt_gpu::shader::environment_wgsl` after the shading helpers,
// lat_long.wgsl (atan2_turns, direction_to_uv, texel_lerp, is_nan_f32) and the generated
// constants SKY_ZENITH, SKY_HORIZON, SKY_GROUND. The stage binds
// `environment: EnvironmentRecord` (uniform) and `environment_texels: array<vec4<f32>>`.

// mirrors hyrt_core::kernels::environment::sky
fn sky(d: vec3<f32>) -> vec3<f32> {
    let len = sqrt_rn(dot3(d, d));
    let y = div_rn(d.y, len);
    if is_nan_f32(y) || y < 0.0 {
        return SKY_GROUND;
    }
    return SKY_HORIZON + mul3(SKY_ZENITH - SKY_HORIZON, vec3<f32>(y));
}

fn environment_texel(i: i32, j: i32) -> vec3<f32> {
    return environment_texels[u32(j) * environment.width + u32(i)].xyz;
}

// mirrors hyrt_core::kernels::environment::sample_bilinear (sample_bilinear_grid over the
// map's texels)
fn sample_bilinear(u: f32, v: f32) -> vec3<f32> {
    let t = bilinear_taps(i32(environment.width), i32(environment.height), u, v);
    let top = texel_lerp(environment_texel(t.i0, t.j0), environment_texel(t.i1, t.j0), t.fx);
    let bottom = texel_lerp(environment_texel(t.i0, t.j1), environment_texel(t.i1, t.j1), t.fx);
    return texel_lerp(top, bottom, t.fy);
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
