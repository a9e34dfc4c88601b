// The radiance a bouncing surface sends back: WGSL mirrors of the gathering kernels of
// hyrt_core::kernels::bounce (`lobe_radiance`, `shade_bouncing`,
// `shade_rt_pixel_bouncing`), same names, same operation order.
//
// Prepended after bounce.wgsl, shading.wgsl and surface_shading.wgsl. The stage binds
// `lights`, `shadow` and `child_radiance: array<vec4<f32>>` (the next depth's radiance,
// which the lobes' links index).

// mirrors hyrt_core::kernels::bounce::lobe_radiance
fn lobe_radiance(link: u32, ambient_scale: f32) -> vec3<f32> {
    if link == INVALID_ID {
        return vec3<f32>(mul(ENVIRONMENT_SPECULAR, ambient_scale));
    }
    return child_radiance[link].xyz;
}

// mirrors hyrt_core::kernels::bounce::shade_bouncing; `index` is the surface's row of
// `shadow`, `children` its [reflection, refraction] links into `child_radiance`.
fn shade_bouncing(index: u32, s: SurfaceRecord, obj: ObjectRecord, l: Lobes, d: vec3<f32>,
                  children: vec2<u32>) -> vec3<f32> {
    let reflected = lobe_radiance(children.x, obj.ambient_scale);
    let refracted = lobe_radiance(children.y, obj.ambient_scale);
    let v = -d;
    let base = obj.base_color;
    let ambient_term = rounded3(
        mul3(mul3(base, vec3<f32>(mul(mul(1.0 - obj.metallic, AMBIENT), l.diffuse_scale))), vec3<f32>(obj.ambient_scale))
            + obj.emissive,
    );
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
