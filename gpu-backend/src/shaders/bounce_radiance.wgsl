// The radiance a bouncing surface sends back: WGSL mirrors of the gathering kernels of
// hyrt_core::kernels::bounce (`lobe_radiance`, `shade_bouncing`,
// `shade_rt_pixel_bouncing`), same names, same operation order.
//
// Prepended after bounce.wgsl, shading.wgsl, ambient_light.wgsl and surface_shading.wgsl.
// The stage binds `lights`, `shadow`, `slot_params`, the ambient light (`ambient_light`,
// `ambient_texels`) and `child_radiance: array<vec4<f32>>` (the next depth's radiance,
// which the lobes' links index).

// mirrors hyrt_core::kernels::bounce::lobe_radiance: the traced child's radiance, else
// the ambient light's stand-in for the lobe `dir` of surface `obj` (shading normal `n`):
// the prefiltered environment along `dir` (`n` where the lobe has no direction) at the
// surface's roughness times the occlusion under an image-based light, else the uniform
// ENVIRONMENT_SPECULAR times `scale occlusion`.
fn lobe_radiance(link: u32, obj: ObjectRecord, dir: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    if link != INVALID_ID {
        return child_radiance[link].xyz;
    }
    if ambient_image_for(obj.flags) {
        var d = dir;
        if all(d == vec3<f32>(0.0)) {
            d = n;
        }
        return mul3(specular_radiance(d, obj.roughness), vec3<f32>(obj.occlusion));
    }
    return vec3<f32>(mul(ENVIRONMENT_SPECULAR, mul(ambient_light.scale, obj.occlusion)));
}

// mirrors hyrt_core::kernels::bounce::shade_bouncing; `index` is the surface's row of
// `shadow`, `children` its [reflection, refraction] links into `child_radiance`. The
// record is the surface's ambient occlusion's from here on (`occluded_object`).
fn shade_bouncing(index: u32, s: SurfaceRecord, shaded: ObjectRecord, l: Lobes, d: vec3<f32>,
                  children: vec2<u32>) -> vec3<f32> {
    let obj = occluded_object(index, shaded);
    let n = s.normal;
    let reflected = lobe_radiance(children.x, obj, l.reflect_dir, n);
    let refracted = lobe_radiance(children.y, obj, l.refract_dir, n);
    let v = -d;
    let base = obj.base_color;
    var constant = mul3(
        mul3(base, vec3<f32>(mul(mul(1.0 - obj.metallic, AMBIENT), l.diffuse_scale))),
        vec3<f32>(mul(ambient_light.scale, obj.occlusion)),
    );
    if ambient_image_for(obj.flags) {
        let diffuse = image_based_diffuse(base, obj.metallic, n, l.diffuse_scale);
        constant = rounded3(constant + mul3(diffuse, vec3<f32>(obj.occlusion)));
    }
    let ambient_term = rounded3(constant + obj.emissive);
    let direct = sum_visible_lights_rt(index, s.position, obj, s.normal, v, l.diffuse_scale);
    // Each partial sum behind the barrier: a device may reassociate an unguarded chain.
    return rounded3(rounded3(ambient_term + direct) + mul3(l.reflection, reflected)) + mul3(l.refraction, refracted);
}

// mirrors hyrt_core::kernels::bounce::shade_rt_pixel_bouncing
fn shade_rt_pixel_bouncing(pixel: u32, p: Parent, eye: vec3<f32>, children: vec2<u32>) -> vec3<f32> {
    let s = p.surface;
    let pl = parent_lobes(p);
    if pl.ok {
        return shade_bouncing(pixel, s, pl.obj, pl.lobes, p.d, children);
    }
    return shade_rt_pixel(pixel, s, p.object, eye);
}
