// The per-surface shaders of hyrt_core::kernels::shading over the shadow codes of a
// frame buffer: `shade_rt_pixel`, `shade_rt_surface`, `shade_raster_surface` and
// `shade_raster_pixel`, each with
// its `sum_visible_lights` loop (WGSL has no closures). `index` is the surface's row in
// the stage's `shadow` binding (`index * slots + slot`: one slot per light, or with area
// lights and ambient occlusion the slots of hyrt_core::kernels::soft_shadow): a pixel for
// the primary stages, a secondary ray for `bounce_shading`.
//
// Also the ambient light every one of them starts from (`ambient`, `unlit`), and the
// ambient occlusion that scales it (`occluded_object`).
//
// A frame that denoised its stochastic shadows (`shadow_denoise`) shades the primary
// surfaces from the filtered channels (hyrt_core::kernels::soft_shadow::SurfaceShadow's
// `filtered`): the stage is compiled with `DENOISED` true and `filtered_channel(index, c)`
// reading its `visibility` binding (hyrt_gpu::shader::filtered_visibility_wgsl); every
// other stage, and `bounce_shading` (secondary hits shade from their codes), with
// `DENOISED` false.
//
// Prepended by `hyrt_gpu::shader::surface_shading_source` after shading.wgsl,
// ambient_light.wgsl and the soft-shadow kernels (soft_shadow.wgsl); the stage binds
// `shadow: array<u32>`, `lights: array<LightRecord>` (the frame's),
// `params: FrameParams`, `slot_params: SlotParams`, `ambient_light: AmbientLightRecord`
// (the frame's) and `ambient_texels: array<vec4<f32>>`.

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

// mirrors hyrt_core::kernels::soft_shadow::ambient_occlusion of the surface's codes
// (`index`'s row): the fraction of its occlusion rays that met nothing. Call only with
// occlusion rays (`ambient_light.ao_samples > 0`).
fn ambient_occlusion(index: u32) -> f32 {
    let samples = ambient_light.ao_samples;
    let first = index * slot_params.slots + slot_params.light_slots;
    var lit = 0u;
    for (var k = 0u; k < samples; k++) {
        lit += select(0u, 1u, shadow[first + k] == SHADOW_LIT);
    }
    return ao_fraction(lit, samples);
}

// mirrors hyrt_core::kernels::soft_shadow::occluded_object: the denoised channel (the
// last) where the frame has one (DENOISED), else the codes' ambient occlusion; the record
// kept as it is (its bits) without occlusion rays.
fn occluded_object(index: u32, obj: ObjectRecord) -> ObjectRecord {
    if !STOCHASTIC || ambient_light.ao_samples == 0u {
        return obj;
    }
    var o = obj;
    if DENOISED {
        o.occlusion = mul(obj.occlusion, filtered_channel(index, slot_params.channels - 1u));
    } else {
        o.occlusion = mul(obj.occlusion, ambient_occlusion(index));
    }
    return o;
}

// The loop of hyrt_core::kernels::shading::sum_visible_lights over a surface's slots,
// with the shade_ray_traced_with closure (`raster` false) or the shade_raster one
// (`raster` true): a light of one slot where its code is SHADOW_LIT, at light_incidence;
// an area light of N slots the mean `(1 / N) sum shade(l_s, weight_s)` over its samples
// whose ray reached it, or where the frame denoised (DENOISED) the sum over its samples
// that traced a ray, lit or not, `(1 / N) sum shade(l_s, weight_s)`, times its filtered
// visibility.
fn sum_visible_slots(index: u32, p: vec3<f32>, obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>,
                     diffuse_scale: f32, raster: bool) -> vec3<f32> {
    var c = vec3<f32>(0.0);
    var slot = index * slot_params.slots;
    var area = 0u;
    for (var i = 0u; i < params.light_count; i++) {
        let light = lights[i];
        if light_is_area(light) {
            let count = light.samples;
            var sum = vec3<f32>(0.0);
            var seen = false;
            for (var sample = 0u; sample < count; sample++) {
                let code = shadow[slot + sample];
                var counts = light_is_visible(code);
                if DENOISED {
                    counts = code != SHADOW_NO_RAY;
                }
                if counts {
                    let ls = area_light_sample(light, p, sample);
                    if ls.valid {
                        sum = rounded3(sum + shade_slot(obj, n, v, ls.l, ls.weight, diffuse_scale, raster));
                        seen = true;
                    }
                }
            }
            if seen {
                if DENOISED {
                    let v = filtered_channel(index, area);
                    c = rounded3(c + mul3(div_rn3(sum, u32_to_f32_rn(count)), vec3<f32>(v)));
                } else {
                    c = rounded3(c + div_rn3(sum, u32_to_f32_rn(count)));
                }
            }
            slot += count;
            area += 1u;
        } else {
            if light_is_visible(shadow[slot]) {
                let inc = light_incidence(light, p);
                c = rounded3(c + shade_slot(obj, n, v, inc.l, inc.e, diffuse_scale, raster));
            }
            slot += 1u;
        }
    }
    return c;
}

// The shade closure of sum_visible_slots.
fn shade_slot(obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, e: vec3<f32>, diffuse_scale: f32,
              raster: bool) -> vec3<f32> {
    if raster {
        return shade_raster(obj, n, v, l, e);
    }
    return shade_ray_traced_with(obj, n, v, l, e, diffuse_scale);
}

// mirrors hyrt_core::kernels::shading::sum_visible_lights with the
// shade_ray_traced_with closure (diffuse scaled by `diffuse_scale`) of
// hyrt_core::kernels::bounce::shade_bouncing; scale 1: that of shade_rt_surface. With
// area lights or occlusion (STOCHASTIC), over the surface's slots.
fn sum_visible_lights_rt(index: u32, p: vec3<f32>, obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>,
                         diffuse_scale: f32) -> vec3<f32> {
    if STOCHASTIC {
        return sum_visible_slots(index, p, obj, n, v, diffuse_scale, false);
    }
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
fn shade_rt_surface(index: u32, s: SurfaceRecord, shaded: ObjectRecord, v: vec3<f32>) -> vec3<f32> {
    let obj = occluded_object(index, shaded);
    return unlit(obj, s.normal, v) + sum_visible_lights_rt(index, s.position, obj, s.normal, v, 1.0);
}

// mirrors hyrt_core::kernels::shading::shade_rt_pixel
fn shade_rt_pixel(pixel: u32, s: SurfaceRecord, obj: ObjectRecord, eye: vec3<f32>) -> vec3<f32> {
    return shade_rt_surface(pixel, s, obj, normalize_or_zero(eye - s.position));
}

// mirrors hyrt_core::kernels::shading::sum_visible_lights with the
// shade_raster closure of hyrt_core::kernels::shading::shade_raster_surface. With area
// lights or occlusion (STOCHASTIC), over the surface's slots.
fn sum_visible_lights_raster(index: u32, p: vec3<f32>, obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    if STOCHASTIC {
        return sum_visible_slots(index, p, obj, n, v, 1.0, true);
    }
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
fn shade_raster_surface(index: u32, s: SurfaceRecord, shaded: ObjectRecord, v: vec3<f32>) -> vec3<f32> {
    let obj = occluded_object(index, shaded);
    return unlit(obj, s.normal, v) + sum_visible_lights_raster(index, s.position, obj, s.normal, v);
}

// mirrors hyrt_core::kernels::shading::shade_raster_pixel
fn shade_raster_pixel(pixel: u32, s: SurfaceRecord, obj: ObjectRecord, eye: vec3<f32>) -> vec3<f32> {
    return shade_raster_surface(pixel, s, obj, normalize_or_zero(eye - s.position));
}
