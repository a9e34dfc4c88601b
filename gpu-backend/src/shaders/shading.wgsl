// Shading kernels shared by `rt_shading`, `raster_shading` and `composition`:
// WGSL mirrors of `hyrt_core::kernels::shading`, same names, same operation order.
//
// Prepended at pipeline creation by `hyrt_gpu::rt_shading::shading_source`, after a
// generated prelude that defines the constants from their Rust values, bit for bit:
//   AMBIENT, ENVIRONMENT_SPECULAR, BACKGROUND, DIELECTRIC_F0, MIN_LIGHT_DISTANCE_SQ,
//   FRAC_1_PI, PI (std::f32::consts), LIGHT_DIRECTIONAL, OBJ_RAY_TRACED, INVALID_ID,
//   SHADOW_LIT, F32_MAX.
// Vectors are combined component by component exactly as glam's scalar Vec3 does;
// dot products are written out (x, then y, then z) as glam's `Vec3::dot`.
// WGSL may still fuse a multiply and an add (the tests bound that in ulp).

// hyrt_core::formats::SurfaceRecord (48 bytes).
struct SurfaceRecord {
    position: vec3<f32>,
    position_error: f32,
    normal: vec3<f32>,
    object: u32,
    geometric_normal: vec3<f32>,
    triangle: u32,
}

// hyrt_core::formats::ObjectRecord (48 bytes).
struct ObjectRecord {
    first_triangle: u32,
    triangle_count: u32,
    flags: u32,
    material_kind: u32,
    base_color: vec3<f32>,
    metallic: f32,
    roughness: f32,
    transmission: f32,
    ior: f32,
    pad: u32,
}

// hyrt_core::formats::LightRecord (32 bytes).
struct LightRecord {
    position_or_direction: vec3<f32>,
    kind: u32,
    radiance: vec3<f32>,
    pad: u32,
}

// hyrt_core::formats::CameraRecord (160 bytes).
struct CameraRecord {
    view_proj: mat4x4<f32>,
    inv_view_proj: mat4x4<f32>,
    eye: vec3<f32>,
    width: u32,
    height: u32,
    near: f32,
    far: f32,
    pad: u32,
}

// hyrt_gpu::buffers::FrameParams (16 bytes).
struct FrameParams {
    width: u32,
    height: u32,
    light_count: u32,
    weight: f32,
}

// mirrors glam::Vec3::dot: (x * x') + (y * y') + (z * z').
fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

// mirrors glam::Vec3::normalize_or_zero: v * (1 / sqrt(v.v)) when that reciprocal
// is finite and positive, else zero.
fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let rcp = 1.0 / sqrt(dot3(v, v));
    if (rcp > 0.0 && rcp <= F32_MAX) {
        return v * rcp;
    }
    return vec3<f32>(0.0);
}

// mirrors glam::Vec3::lerp: a * (1 - s) + b * s.
fn lerp3(a: vec3<f32>, b: vec3<f32>, s: f32) -> vec3<f32> {
    return a * (1.0 - s) + b * s;
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
    return Incidence(d / sqrt(d2), radiance / d2);
}

// mirrors hyrt_core::kernels::shading::blinn_phong_exponent
fn blinn_phong_exponent(roughness: f32) -> f32 {
    let a = max(roughness * roughness, 1e-3);
    return clamp(2.0 / (a * a) - 2.0, 1.0, 1e4);
}

// mirrors hyrt_core::kernels::shading::shade_ray_traced
fn shade_ray_traced(obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, e: vec3<f32>) -> vec3<f32> {
    let ndl = dot3(n, l);
    if (ndl <= 0.0) {
        return vec3<f32>(0.0);
    }
    let base = obj.base_color;
    let diffuse = base * ((1.0 - obj.metallic) * FRAC_1_PI);
    let f0 = lerp3(vec3<f32>(DIELECTRIC_F0), base, obj.metallic);
    let h = normalize_or_zero(l + v);
    let s = blinn_phong_exponent(obj.roughness);
    let spec = f0 * ((s + 8.0) / (8.0 * PI) * pow(max(dot3(n, h), 0.0), s));
    return (diffuse + spec) * e * ndl;
}

// mirrors hyrt_core::kernels::shading::shade_raster
fn shade_raster(obj: ObjectRecord, n: vec3<f32>, l: vec3<f32>, e: vec3<f32>) -> vec3<f32> {
    let ndl = dot3(n, l);
    if (ndl <= 0.0) {
        return vec3<f32>(0.0);
    }
    return obj.base_color * FRAC_1_PI * e * ndl;
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
    return base * ((1.0 - obj.metallic) * AMBIENT) + f0 * ENVIRONMENT_SPECULAR;
}

// mirrors hyrt_core::kernels::shading::compose
fn compose(raster: vec3<f32>, rt: vec3<f32>, weight: f32) -> vec3<f32> {
    return raster * (1.0 - weight) + rt * weight;
}

// True when the invocation `id` of the 2D pixel-grid dispatch is a pixel of the image
// (the grid is rounded up to whole workgroups).
fn pixel_in_image(id: vec3<u32>, width: u32, height: u32) -> bool {
    return id.x < width && id.y < height;
}
