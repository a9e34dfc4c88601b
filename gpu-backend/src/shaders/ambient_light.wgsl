// The image-based light of the glTF shading model: WGSL mirrors of
// hyrt_core::kernels::ibl (the irradiance's nine harmonics, the split-sum table, the
// prefiltered environment and the light they give a surface), same names as the core's
// functions, same operation order, every product that feeds a sum through `mul`
// (shading_helpers.wgsl) and every sum that feeds more arithmetic behind `rounded`.
//
// Prepended by `hyrt_gpu::shader::ambient_light_wgsl` after the shading helpers,
// lat_long.wgsl (direction_to_uv, texel_lerp) and the generated constants SH9_TERMS,
// AMBIENT_TEXELS_SPLIT_SUM, SPLIT_SUM_SIZE, PREFILTER_LEVELS, PREFILTER_BASE_WIDTH,
// PREFILTER_BASE_HEIGHT and PREFILTERED_OFFSET (hyrt_core::kernels::ibl::prefiltered_offset
// of every level and of PREFILTER_LEVELS). The stage binds
// `ambient_light: AmbientLightRecord` (uniform) and `ambient_texels: array<vec4<f32>>`
// (hyrt_core::kernels::ibl::AmbientLight::texels: the irradiance coefficients, the
// split-sum cells from AMBIENT_TEXELS_SPLIT_SUM, the prefiltered levels from
// PREFILTERED_OFFSET[k]); they are read only when `ambient_light.image` is 1.

// The scene has an image-based light (hyrt_gpu::texture::Specialization::ambient_image, a
// pipeline constant): false compiles the image-based light out of the shading stages of
// scenes without one. True by default: evaluated where the frame's record asks for it.
override AMBIENT_IMAGE: bool = true;

// mirrors Rust's f32::clamp: `if x < lo { lo }`, then `if x > hi { hi }` (NaN stays NaN,
// where WGSL's `clamp` is min(max(x, lo), hi), indeterminate for NaN).
fn clamp_f32(x: f32, lo: f32, hi: f32) -> f32 {
    var y = x;
    if y < lo {
        y = lo;
    }
    if y > hi {
        y = hi;
    }
    return y;
}

// One term of IrradianceSh9::irradiance's sum: `e + c_k b`, behind the barrier.
fn sh9_term(e: vec3<f32>, k: u32, b: f32) -> vec3<f32> {
    return rounded3(e + mul3(ambient_texels[k].xyz, vec3<f32>(b)));
}

// mirrors hyrt_core::kernels::ibl::IrradianceSh9::irradiance: the nine terms of
// sh9_basis (1, x, y, z, xy, yz, xz, 3z² - 1, x² - y²) in order, from zero.
fn irradiance_sh9(n: vec3<f32>) -> vec3<f32> {
    let x = n.x;
    let y = n.y;
    let z = n.z;
    var e = vec3<f32>(0.0);
    e = sh9_term(e, 0u, 1.0);
    e = sh9_term(e, 1u, x);
    e = sh9_term(e, 2u, y);
    e = sh9_term(e, 3u, z);
    e = sh9_term(e, 4u, mul(x, y));
    e = sh9_term(e, 5u, mul(y, z));
    e = sh9_term(e, 6u, mul(x, z));
    e = sh9_term(e, 7u, rounded(mul(3.0, mul(z, z)) - 1.0));
    e = sh9_term(e, 8u, rounded(mul(x, x) - mul(y, y)));
    return e;
}

// A cell and the fraction towards the next one along one axis of the split-sum table.
struct SplitSumAt {
    i: u32,
    f: f32,
}

// mirrors the `at` closure of hyrt_core::kernels::ibl::SplitSumTable::lookup:
// `p = (x.clamp(0, 1) n - 1/2).clamp(0, n - 1)`, `i0 = min(floor(p) as usize, n - 2)`.
fn split_sum_at(x: f32) -> SplitSumAt {
    let n = SPLIT_SUM_SIZE;
    let p = clamp_f32(mul(clamp_f32(x, 0.0, 1.0), f32(n)) - 0.5, 0.0, f32(n - 1u));
    let i0 = min(u32(floor(p)), n - 2u);
    return SplitSumAt(i0, p - f32(i0));
}

// The cell `(i, j)` of the split-sum table: `cells[j * SPLIT_SUM_SIZE + i]`.
fn split_sum_cell(i: u32, j: u32) -> vec2<f32> {
    return ambient_texels[AMBIENT_TEXELS_SPLIT_SUM + j * SPLIT_SUM_SIZE + i].xy;
}

// mirrors the `lerp` closure of hyrt_core::kernels::ibl::SplitSumTable::lookup:
// `a + (b - a) f` per factor.
fn split_sum_lerp(a: vec2<f32>, b: vec2<f32>, f: f32) -> vec2<f32> {
    return vec2<f32>(rounded(a.x + mul(b.x - a.x, f)), rounded(a.y + mul(b.y - a.y, f)));
}

// mirrors hyrt_core::kernels::ibl::SplitSumTable::lookup: `(A, B)` bilinear between
// cell centres, clamped at the edges.
fn split_sum_lookup(n_dot_v: f32, roughness: f32) -> vec2<f32> {
    let x = split_sum_at(n_dot_v);
    let y = split_sum_at(roughness);
    let top = split_sum_lerp(split_sum_cell(x.i, y.i), split_sum_cell(x.i + 1u, y.i), x.f);
    let bottom = split_sum_lerp(split_sum_cell(x.i, y.i + 1u), split_sum_cell(x.i + 1u, y.i + 1u), x.f);
    return split_sum_lerp(top, bottom, y.f);
}

// Texel `(i, j)` of prefiltered level `k` (`width` columns), which starts at `offset`
// (PREFILTERED_OFFSET[k]).
fn prefiltered_texel(offset: u32, width: u32, i: i32, j: i32) -> vec3<f32> {
    return ambient_texels[offset + u32(j) * width + u32(i)].xyz;
}

// mirrors hyrt_core::kernels::environment::sample_bilinear_grid over prefiltered level
// `k` (PREFILTER_BASE >> k texels, from prefiltered_offset(k)), as
// hyrt_core::kernels::ibl::ImageBasedLight::specular_radiance samples it; the same
// operations as environment.wgsl's sample_bilinear.
fn sample_prefiltered_level(k: u32, u: f32, v: f32) -> vec3<f32> {
    let offset = PREFILTERED_OFFSET[k];
    let w = PREFILTER_BASE_WIDTH >> k;
    let t = bilinear_taps(i32(w), i32(PREFILTER_BASE_HEIGHT >> k), u, v);
    let top = rounded3(texel_lerp(prefiltered_texel(offset, w, t.i0, t.j0), prefiltered_texel(offset, w, t.i1, t.j0), t.fx));
    let bottom =
        rounded3(texel_lerp(prefiltered_texel(offset, w, t.i0, t.j1), prefiltered_texel(offset, w, t.i1, t.j1), t.fx));
    return rounded3(texel_lerp(top, bottom, t.fy));
}

// mirrors hyrt_core::kernels::ibl::ImageBasedLight::specular_radiance: the two levels
// around `roughness (LEVELS - 1)` at `r`'s lat-long coordinates, blended linearly.
fn specular_radiance(r: vec3<f32>, roughness: f32) -> vec3<f32> {
    let uv = direction_to_uv(r);
    let x = mul(clamp_f32(roughness, 0.0, 1.0), f32(PREFILTER_LEVELS - 1u));
    let k = min(u32(floor(x)), PREFILTER_LEVELS - 2u);
    let f = x - f32(k);
    let a = sample_prefiltered_level(k, uv.x, uv.y);
    let b = sample_prefiltered_level(k + 1u, uv.x, uv.y);
    return rounded3(a + mul3(b - a, vec3<f32>(f)));
}

// mirrors hyrt_core::kernels::ibl::ImageBasedLight::radiance: the split-sum specular
// lobe under the prefiltered environment plus the diffuse lobe under the irradiance.
fn image_based_light(base: vec3<f32>, metallic: f32, roughness: f32, n: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let n_dot_v = max(dot3(n, v), 0.0);
    var r = mul3(n, vec3<f32>(2.0 * n_dot_v)) - v;
    if all(r == vec3<f32>(0.0)) {
        r = n;
    }
    let ab = split_sum_lookup(n_dot_v, roughness);
    let f0 = lerp3(vec3<f32>(DIELECTRIC_F0), base, metallic);
    let specular = mul3(specular_radiance(r, roughness), rounded3(mul3(f0, vec3<f32>(ab.x)) + vec3<f32>(ab.y)));
    let kd = mul(1.0 - metallic, rounded(1.0 - rounded(mul(DIELECTRIC_F0, ab.x) + ab.y)));
    let diffuse = mul3(mul3(base, vec3<f32>(kd)), mul3(irradiance_sh9(n), vec3<f32>(FRAC_1_PI)));
    return rounded3(diffuse + specular);
}

// mirrors hyrt_core::kernels::ibl::ImageBasedLight::diffuse: the diffuse part of
// image_based_light alone, scaled by `diffuse_scale`.
fn image_based_diffuse(base: vec3<f32>, metallic: f32, n: vec3<f32>, diffuse_scale: f32) -> vec3<f32> {
    return mul3(mul3(base, vec3<f32>(mul(1.0 - metallic, diffuse_scale))), mul3(irradiance_sh9(n), vec3<f32>(FRAC_1_PI)));
}

// mirrors hyrt_core::kernels::ibl::AmbientLight::image_for: true when an object with
// `flags` is shaded with the frame's image-based light (the glTF model, and an image;
// never in a pipeline compiled without AMBIENT_IMAGE).
fn ambient_image_for(flags: u32) -> bool {
    return AMBIENT_IMAGE && (flags & OBJ_GLTF_BRDF) != 0u && ambient_light.image == 1u;
}
