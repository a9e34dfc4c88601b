// The per-surface shaders of hyrt_core::kernels::shading over the shadow codes of a
// frame buffer: `shade_rt_pixel`, `shade_rt_surface`, `shade_raster_surface` and
// `shade_raster_pixel`, each with
// its `sum_visible_lights` loop (WGSL has no closures). `index` is the surface's row in
// the stage's `shadow` binding (`index * light_count + light`): a pixel for the primary
// stages, a secondary ray for `bounce_shading`.
//
// Prepended by `hyrt_gpu::rt_shading::shading_source` after shading.wgsl; the stage
// binds `shadow: array<u32>`, `lights: array<LightRecord>` and `params: FrameParams`.

// mirrors hyrt_core::kernels::shading::sum_visible_lights with the
// shade_ray_traced_with closure (diffuse scaled by `diffuse_scale`) of
// hyrt_core::kernels::bounce::shade_bouncing; scale 1: that of shade_rt_surface.
fn sum_visible_lights_rt(index: u32, p: vec3<f32>, obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>,
                         diffuse_scale: f32) -> vec3<f32> {
    var c = vec3<f32>(0.0);
    let nl = params.light_count;
    for (var i = 0u; i < nl; i++) {
        if (light_is_visible(shadow[index * nl + i])) {
            let inc = light_incidence(lights[i], p);
            c += shade_ray_traced_with(obj, n, v, inc.l, inc.e, diffuse_scale);
        }
    }
    return c;
}

// mirrors hyrt_core::kernels::shading::shade_rt_surface
fn shade_rt_surface(index: u32, s: SurfaceRecord, obj: ObjectRecord, v: vec3<f32>) -> vec3<f32> {
    return unlit(obj) + sum_visible_lights_rt(index, s.position, obj, s.normal, v, 1.0);
}

// mirrors hyrt_core::kernels::shading::shade_rt_pixel
fn shade_rt_pixel(pixel: u32, s: SurfaceRecord, obj: ObjectRecord, eye: vec3<f32>) -> vec3<f32> {
    return shade_rt_surface(pixel, s, obj, normalize_or_zero(eye - s.position));
}

// mirrors hyrt_core::kernels::shading::sum_visible_lights with the
// shade_raster closure of hyrt_core::kernels::shading::shade_raster_surface.
fn sum_visible_lights_raster(index: u32, p: vec3<f32>, obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    var c = vec3<f32>(0.0);
    let nl = params.light_count;
    for (var i = 0u; i < nl; i++) {
        if (light_is_visible(shadow[index * nl + i])) {
            let inc = light_incidence(lights[i], p);
            c += shade_raster(obj, n, v, inc.l, inc.e);
        }
    }
    return c;
}

// mirrors hyrt_core::kernels::shading::shade_raster_surface
fn shade_raster_surface(index: u32, s: SurfaceRecord, obj: ObjectRecord, v: vec3<f32>) -> vec3<f32> {
    return unlit(obj) + sum_visible_lights_raster(index, s.position, obj, s.normal, v);
}

// mirrors hyrt_core::kernels::shading::shade_raster_pixel
fn shade_raster_pixel(pixel: u32, s: SurfaceRecord, obj: ObjectRecord, eye: vec3<f32>) -> vec3<f32> {
    return shade_raster_surface(pixel, s, obj, normalize_or_zero(eye - s.position));
}
