// The per-surface shaders of hyrt_core::kernels::shading over the shadow codes of a
// frame buffer: `shade_rt_pixel`, `shade_rt_surface`, `shade_raster_surface` and
// `shade_raster_pixel`, each with
// its `sum_visible_lights` loop (WGSL has no closures). `index` is the surface's row in
// the stage's `shadow` binding (`index * light_count + light`): a pixel for the primary
// stages, a secondary ray for `bounce_shading`.
//
// Also the ambient light every one of them starts from (`ambient`, `unlit`).
//
// Prepended by `hyrt_gpu::shader::surface_shading_source` after shading.wgsl and
// ambient_light.wgsl; the stage binds `shadow: array<u32>`, `lights: array<LightRecord>`,
// `params: FrameParams`, `ambient_light: AmbientLightRecord` and
// `ambient_texels: array<vec4<f32>>`.

// mirrors hyrt_core::kernels::shading::ambient: the constant terms times
// `scale occlusion`; under an image-based light (ambient_image_for) the constant diffuse
// term and image_based_light times the occlusion.
fn ambient(obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let base = obj.base_color;
    let constant = mul(ambient_light.scale, obj.occlusion);
    if ambient_image_for(obj.flags) {
        let diffuse = mul3(mul3(base, vec3<f32>(mul(1.0 - obj.metallic, AMBIENT))), vec3<f32>(constant));
        let ibl = image_based_light(base, obj.metallic, obj.roughness, n, v);
        return rounded3(diffuse + mul3(ibl, vec3<f32>(obj.occlusion)));
    }
    let f0 = lerp3(vec3<f32>(DIELECTRIC_F0), base, obj.metallic);
    let a = mul3(base, vec3<f32>(mul(1.0 - obj.metallic, AMBIENT))) + mul3(f0, vec3<f32>(ENVIRONMENT_SPECULAR));
    return mul3(rounded3(a), vec3<f32>(constant));
}

// mirrors hyrt_core::kernels::shading::unlit
// (Behind the barrier: its callers add the lights to it, and a device may reassociate an
// unguarded chain of sums.)
fn unlit(obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    return rounded3(ambient(obj, n, v) + obj.emissive);
}

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
    return unlit(obj, s.normal, v) + sum_visible_lights_rt(index, s.position, obj, s.normal, v, 1.0);
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
    return unlit(obj, s.normal, v) + sum_visible_lights_raster(index, s.position, obj, s.normal, v);
}

// mirrors hyrt_core::kernels::shading::shade_raster_pixel
fn shade_raster_pixel(pixel: u32, s: SurfaceRecord, obj: ObjectRecord, eye: vec3<f32>) -> vec3<f32> {
    return shade_raster_surface(pixel, s, obj, normalize_or_zero(eye - s.position));
}
