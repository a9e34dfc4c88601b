// The instance kernels of hyrt_core::kernels::instance, for the two-level walks
// (`shadow_two_level.wgsl`, `bounce_two_level.wgsl`). Needs ray.wgsl (`opaque`,
// `mul_exact`).

// One row of an ObjectMap applied to a vector, `(r.x * v.x + r.y * v.y) + r.z * v.z`,
// every operation rounded once (unfused).
fn map_row(r: vec4<f32>, v: vec3<f32>, zero: u32) -> f32 {
    return opaque(opaque(mul_exact(r.x, v.x, zero) + mul_exact(r.y, v.y, zero), zero) + mul_exact(r.z, v.z, zero), zero);
}

// mirrors hyrt_core::kernels::instance::to_object_space: `(L (origin - t), L dir)` for the
// instance's map (rows map_x, map_y, map_z; `t` in their w).
fn to_object_space(inst: InstanceRecord, origin: vec3<f32>, dir: vec3<f32>, zero: u32) -> array<vec3<f32>, 2> {
    let q = vec3<f32>(opaque(origin.x - inst.map_x.w, zero), opaque(origin.y - inst.map_y.w, zero),
        opaque(origin.z - inst.map_z.w, zero));
    return array<vec3<f32>, 2>(
        vec3<f32>(map_row(inst.map_x, q, zero), map_row(inst.map_y, q, zero), map_row(inst.map_z, q, zero)),
        vec3<f32>(map_row(inst.map_x, dir, zero), map_row(inst.map_y, dir, zero), map_row(inst.map_z, dir, zero)));
}

// The ray moved into `inst`'s object space (hyrt_core::bvh::two_level's `object_ray`).
fn object_ray(inst: InstanceRecord, ray: RayRecord, zero: u32) -> RayRecord {
    let m = to_object_space(inst, ray.origin, ray.direction, zero);
    var r = ray;
    r.origin = m[0];
    r.direction = m[1];
    return r;
}
