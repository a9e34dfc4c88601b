// Secondary-ray kernels (reflection and refraction): WGSL mirrors of
// hyrt_core::kernels::bounce, same names, same operation order, every product that
// feeds a sum through `mul` (shading_helpers.wgsl) so that the results are the CPU's
// bits. See the Rust module for the model (Whitted: a reflection ray and, for glass, a
// refraction ray per bouncing surface, exact dielectric Fresnel, Schlick for metals).
//
// Prepended by `hyrt_gpu::secondary_rays::bounce_wgsl` after the generated records,
// ray.wgsl, the shading helpers and materials.wgsl (`Parent`, whose shaded object the
// lobes read), with the generated constants IOR_OUTSIDE and MIN_THROUGHPUT. The stage
// binds `triangles` and `params`. The radiance the lobes gather is in
// bounce_radiance.wgsl.

// mirrors hyrt_core::kernels::bounce::bounces
fn bounces(obj: ObjectRecord) -> bool {
    return (obj.flags & OBJ_RAY_TRACED) != 0u && obj.triangle_count > 0u
        && (obj.material_kind == MATERIAL_SPECULAR || obj.material_kind == MATERIAL_GLASS);
}

// mirrors hyrt_core::kernels::bounce::reflect
fn reflect_dir(d: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let k = mul(2.0, dot3(d, n));
    return d - mul3(n, vec3<f32>(k));
}

// The result of `refract_dir`: `ok` false under total internal reflection.
struct Refracted {
    ok: bool,
    t: vec3<f32>,
}

// mirrors hyrt_core::kernels::bounce::refract
fn refract_dir(d: vec3<f32>, n: vec3<f32>, eta: f32) -> Refracted {
    let cos_i = clamp(-dot3(d, n), 0.0, 1.0);
    let sin2_t = mul(mul(eta, eta), 1.0 - mul(cos_i, cos_i));
    if sin2_t >= 1.0 {
        return Refracted(false, vec3<f32>(0.0));
    }
    let cos_t = sqrt_rn(1.0 - sin2_t);
    let k = mul(eta, cos_i) - cos_t;
    return Refracted(true, mul3(d, vec3<f32>(eta)) + mul3(n, vec3<f32>(k)));
}

// mirrors hyrt_core::kernels::bounce::fresnel_dielectric
fn fresnel_dielectric(cos_in: f32, eta: f32) -> f32 {
    let cos_i = clamp(cos_in, 0.0, 1.0);
    let sin2_t = mul(mul(eta, eta), 1.0 - mul(cos_i, cos_i));
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = sqrt_rn(1.0 - sin2_t);
    let r_perp = div_rn(mul(eta, cos_i) - cos_t, mul(eta, cos_i) + cos_t);
    let r_par = div_rn(cos_i - mul(eta, cos_t), cos_i + mul(eta, cos_t));
    return mul(rounded(mul(r_par, r_par) + mul(r_perp, r_perp)), 0.5);
}

// mirrors hyrt_core::kernels::bounce::fresnel_schlick
fn fresnel_schlick(f0: vec3<f32>, cos: f32) -> vec3<f32> {
    let m = 1.0 - clamp(cos, 0.0, 1.0);
    let m2 = mul(m, m);
    let m5 = mul(mul(m2, m2), m);
    return f0 + mul3(vec3<f32>(1.0) - f0, vec3<f32>(m5));
}

// mirrors hyrt_core::kernels::bounce::Lobes
struct Lobes {
    reflection: vec3<f32>,
    refraction: vec3<f32>,
    reflect_dir: vec3<f32>,
    refract_dir: vec3<f32>,
    diffuse_scale: f32,
}

fn is_zero3(v: vec3<f32>) -> bool {
    return v.x == 0.0 && v.y == 0.0 && v.z == 0.0;
}

// The `through` closure of hyrt_core::kernels::bounce::lobes: the unit refracted
// direction through `n` if it leaves on the far side of `ng`, else zero.
fn refract_through(d: vec3<f32>, n: vec3<f32>, ng: vec3<f32>, eta: f32) -> vec3<f32> {
    let r = refract_dir(d, n, eta);
    if !r.ok {
        return vec3<f32>(0.0);
    }
    let t = normalize_or_zero(r.t);
    if dot3(t, ng) < 0.0 {
        return t;
    }
    return vec3<f32>(0.0);
}

// mirrors hyrt_core::kernels::bounce::lobes
fn lobes(obj: ObjectRecord, s: SurfaceRecord, d: vec3<f32>, exterior: bool) -> Lobes {
    let ns = s.normal;
    let ng = s.geometric_normal;
    let base = obj.base_color;
    let cos_i = -dot3(d, ns);
    let glass = obj.material_kind == MATERIAL_GLASS;
    var eta = div_rn(obj.ior, IOR_OUTSIDE);
    if exterior || !glass {
        eta = div_rn(IOR_OUTSIDE, obj.ior);
    }
    let f = fresnel_dielectric(cos_i, eta);
    let reflection = vec3<f32>(mul(f, 1.0 - obj.metallic)) + mul3(fresnel_schlick(base, cos_i), vec3<f32>(obj.metallic));

    var rd = normalize_or_zero(reflect_dir(d, ns));
    if !(dot3(rd, ng) > 0.0) {
        rd = normalize_or_zero(reflect_dir(d, ng));
    }
    if !(dot3(rd, ng) > 0.0) {
        rd = vec3<f32>(0.0);
    }

    var transmission = 0.0;
    if glass {
        transmission = obj.transmission;
    }
    var refraction = mul3(base, vec3<f32>(mul(mul(1.0 - obj.metallic, transmission), 1.0 - f)));
    var td = vec3<f32>(0.0);
    if max_element3(refraction) > 0.0 {
        td = refract_through(d, ns, ng, eta);
        if is_zero3(td) {
            td = refract_through(d, ng, ng, eta);
        }
    }
    if is_zero3(td) {
        refraction = vec3<f32>(0.0);
    }
    return Lobes(reflection, refraction, rd, td, 1.0 - transmission);
}

// mirrors hyrt_core::kernels::bounce::sees_exterior
fn sees_exterior(back_face: bool, inward: bool) -> bool {
    return back_face == inward;
}

// One of the rays of hyrt_core::kernels::bounce::secondary_rays: `ok` false where the
// lobe spawns none.
struct SpawnedRay {
    ok: bool,
    ray: RayRecord,
}

// The `ray` closure of hyrt_core::kernels::bounce::secondary_rays.
fn lobe_ray(s: SurfaceRecord, dir: vec3<f32>, weight: vec3<f32>, throughput: vec3<f32>, side: vec3<f32>,
            kind: u32, pixel: u32, depth: u32, cone: f32) -> SpawnedRay {
    let t = mul3(throughput, weight);
    var r: RayRecord;
    if is_zero3(dir) || !(max_element3(t) >= MIN_THROUGHPUT) {
        return SpawnedRay(false, r);
    }
    let origin = offset_ray_origin(s.position, s.position_error, side, params.zero);
    let inf = bitcast<f32>(F32_EXP_MASK | params.zero);
    r = RayRecord(origin, 0.0, dir, inf, pixel, kind, depth, INVALID_ID, t, cone);
    return SpawnedRay(true, r);
}

// mirrors hyrt_core::kernels::bounce::secondary_rays: lobe 0 reflection, 1 refraction.
fn secondary_ray(s: SurfaceRecord, l: Lobes, throughput: vec3<f32>, pixel: u32, depth: u32, cone: f32,
                 lobe: u32) -> SpawnedRay {
    let ng = s.geometric_normal;
    if lobe == 0u {
        return lobe_ray(s, l.reflect_dir, l.reflection, throughput, ng, RAY_KIND_REFLECTION, pixel, depth, cone);
    }
    return lobe_ray(s, l.refract_dir, l.refraction, throughput, -ng, RAY_KIND_REFRACTION, pixel, depth, cone);
}

// The result of `parent_lobes`: `ok` false for a miss or a surface that does not bounce.
struct ParentLobes {
    ok: bool,
    obj: ObjectRecord,
    lobes: Lobes,
}

// mirrors hyrt_core::kernels::bounce::parent_lobes
fn parent_lobes(p: Parent) -> ParentLobes {
    var out: ParentLobes;
    out.ok = false;
    let s = p.surface;
    if s.object == INVALID_ID {
        return out;
    }
    let obj = p.object;
    if !bounces(obj) {
        return out;
    }
    let inward = (triangle_flags(s.object, s.triangle) & TRI_INWARD) != 0u;
    return ParentLobes(true, obj, lobes(obj, s, p.d, sees_exterior(p.back_face, inward)));
}

// mirrors hyrt_core::kernels::bounce::spawn, one lobe.
fn spawn(p: Parent, depth: u32, lobe: u32) -> SpawnedRay {
    let pl = parent_lobes(p);
    if !pl.ok {
        var none: SpawnedRay;
        none.ok = false;
        return none;
    }
    return secondary_ray(p.surface, pl.lobes, p.throughput, p.pixel, depth, p.cone, lobe);
}

