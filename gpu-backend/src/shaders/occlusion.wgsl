// The directions of a surface's ambient-occlusion rays and the estimate they give: WGSL
// mirrors of hyrt_core::kernels::occlusion, same names as the core's functions, same
// operation order (sampling.wgsl says how).
//
// Prepended by `hyrt_gpu::shader::occlusion_wgsl` after sampling.wgsl (cosine_hemisphere,
// to_frame, u32_to_f32_rn and the vector helpers) and the generated constant AO_STREAM
// (the sample stream of ambient occlusion in sample_seed).

// An occlusion ray's direction; `valid` false for Rust's `None` (the direction would
// leave below the geometric surface; `d` is still the direction then).
struct AoDirection {
    d: vec3<f32>,
    valid: bool,
}

// mirrors hyrt_core::kernels::occlusion::ao_direction
fn ao_direction(n_shade: vec3<f32>, n_geo: vec3<f32>, u: vec2<f32>) -> AoDirection {
    let d = to_frame(cosine_hemisphere(u), n_shade);
    return AoDirection(d, sampling_dot3(d, n_geo) > 0.0);
}

// mirrors hyrt_core::kernels::occlusion::ao_fraction: unoccluded / samples, 1 without
// samples (each count converted as Rust's `as f32`).
fn ao_fraction(unoccluded: u32, samples: u32) -> f32 {
    if samples == 0u {
        return 1.0;
    }
    return div_rn(u32_to_f32_rn(unoccluded), u32_to_f32_rn(samples));
}
