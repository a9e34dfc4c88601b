// What shading knows of materials: WGSL mirrors of `hyrt_core::kernels::texture::hit_lod`
// and `Materials::at` (`shaded_object`: an object's record as shading sees it at a point,
// its base colour textured and vertex-coloured), and the parents of
// `hyrt_core::kernels::bounce` (`Parent`, `primary_parent`, `secondary_parent`,
// `primary_cone`), which carry their footprint cone and shaded record; same names, same
// operation order.
//
// Prepended by `hyrt_gpu::texture::materials_wgsl` after a generated prelude with
// LOD_MIN_AREA and LOD_MIN_COSINE from their Rust values; needs the shading helpers
// (`mul`, `rounded`, `dot3`, `normalize_or_zero`, F32_MAX), shading.wgsl (`log2_portable`)
// and the texture kernels (`hyrt_gpu::texture::texture_wgsl`). The including stage binds
// `objects: array<ObjectRecord>`, `params: FrameParams` (`pixel_spread`, the frame's cone
// spread, 0 without textures or vertex colours) and the surface tables.

// mirrors hyrt_core::kernels::texture::hit_lod
fn hit_lod(bias: f32, cone_width: f32, cos: f32) -> f32 {
    // Rust's `max` of a number and a possible NaN (NaN gives the other operand).
    let a = abs(cos);
    let c = select(LOD_MIN_COSINE, a, a > LOD_MIN_COSINE);
    var w = F32_MAX;
    if f32_is_finite(cone_width) {
        w = select(LOD_MIN_AREA, cone_width, cone_width > LOD_MIN_AREA);
    }
    // The difference behind the barrier: a device may reassociate an unguarded chain.
    return rounded(bias + rounded(log2_portable(w) - log2_portable(c)));
}

// mirrors hyrt_core::kernels::texture::texture_lod
fn texture_lod(lod: f32, reference: TextureRecord, tex: TextureRecord) -> f32 {
    if tex.width == reference.width && tex.height == reference.height {
        return lod;
    }
    let area = f32(tex.width * tex.height);
    let reference_area = f32(reference.width * reference.height);
    // Behind the barrier: the sampler subtracts the level from it, and a device may
    // reassociate an unguarded chain of sums.
    return rounded(lod + mul(0.5, rounded(log2_portable(area) - log2_portable(reference_area))));
}

// mirrors the `sample` closure of hyrt_core::kernels::texture::Materials::at: texture
// `index` at `uv` and level `lod` of the material's uv texture `reference`.
fn sample_material_texture(index: u32, reference: TextureRecord, uv: vec2<f32>, lod: f32) -> vec4<f32> {
    let tex = surface_texture(index);
    return sample_texture(tex, uv, texture_lod(lod, reference, tex));
}

// mirrors hyrt_core::kernels::texture::vertex_coloured (private there)
fn vertex_coloured(c: vec3<f32>, triangle: u32, u: f32, v: f32) -> vec3<f32> {
    let k = interpolate_color(surface_color(triangle, 0u), surface_color(triangle, 1u), surface_color(triangle, 2u), u, v);
    return vec3<f32>(mul(c.x, k.x), mul(c.y, k.y), mul(c.z, k.z));
}

// mirrors hyrt_core::kernels::texture::Materials::varying (a pipeline constant:
// surface_tables.wgsl)
fn materials_vary() -> bool {
    return SURFACE_TABLES;
}

// mirrors hyrt_core::kernels::texture::Materials::at: the record of the object hit at
// surface `s` as shading sees it there (barycentrics `u`, `v`, footprint `cone`, seen
// along the unit direction `d`).
fn shaded_object(s: SurfaceRecord, u: f32, v: f32, cone: f32, d: vec3<f32>) -> ObjectRecord {
    var obj = objects[s.object];
    if !materials_vary() {
        return obj;
    }
    let m = surface_material(s.object);
    let global = s.triangle;
    if (m.flags & MAT_ANY_TEXTURE) != 0u {
        let t = surface_uv(global);
        let cos = dot3(d, s.geometric_normal);
        let lod = hit_lod(t.lod_bias, cone, cos);
        let uv = interpolate_uv(t, u, v);
        let reference = surface_texture(m.uv_texture);
        if (m.flags & MAT_TEXTURED) != 0u {
            let texel = sample_material_texture(m.texture, reference, uv, lod);
            let c = obj.base_color;
            obj.base_color = vec3<f32>(mul(c.x, texel.x), mul(c.y, texel.y), mul(c.z, texel.z));
        }
        if (m.flags & MAT_VERTEX_COLORS) != 0u {
            obj.base_color = vertex_coloured(obj.base_color, global, u, v);
        }
        if (m.flags & MAT_METALLIC_ROUGHNESS) != 0u {
            let texel = sample_material_texture(m.metallic_roughness, reference, uv, lod);
            obj.roughness = mul(obj.roughness, texel.y);
            obj.metallic = mul(obj.metallic, texel.z);
        }
        if (m.flags & MAT_OCCLUSION) != 0u {
            let texel = sample_material_texture(m.occlusion, reference, uv, lod);
            obj.occlusion = mul(obj.occlusion, rounded(1.0 + mul(m.occlusion_strength, rounded(texel.x - 1.0))));
        }
        if (m.flags & MAT_EMISSIVE) != 0u {
            let texel = sample_material_texture(m.emissive, reference, uv, lod);
            let e = obj.emissive;
            obj.emissive = vec3<f32>(mul(e.x, texel.x), mul(e.y, texel.y), mul(e.z, texel.z));
        }
    } else if (m.flags & MAT_VERTEX_COLORS) != 0u {
        obj.base_color = vertex_coloured(obj.base_color, global, u, v);
    }
    return obj;
}

// mirrors hyrt_core::kernels::texture::Materials::normal_mapped
fn normal_mapped(s: SurfaceRecord, u: f32, v: f32, cone: f32, d: vec3<f32>, back_face: bool) -> SurfaceRecord {
    if !materials_vary() || s.object == INVALID_ID {
        return s;
    }
    let m = surface_material(s.object);
    if (m.flags & MAT_NORMAL) == 0u {
        return s;
    }
    let global = s.triangle;
    let ng = s.geometric_normal;
    let t = surface_uv(global);
    let lod = hit_lod(t.lod_bias, cone, dot3(d, ng));
    let texel = sample_material_texture(m.normal, surface_texture(m.uv_texture), interpolate_uv(t, u, v), lod);
    let side = select(1.0, -1.0, back_face);
    let n = mul3(s.normal, vec3<f32>(side));
    let c0 = surface_tangent(global, 0u);
    let c1 = surface_tangent(global, 1u);
    let c2 = surface_tangent(global, 2u);
    let tangent_in = interpolate_color(c0, c1, c2, u, v).xyz;
    let along = dot3(n, tangent_in);
    let tangent = normalize_or_zero(vec3<f32>(
        rounded(tangent_in.x - mul(n.x, along)),
        rounded(tangent_in.y - mul(n.y, along)),
        rounded(tangent_in.z - mul(n.z, along)),
    ));
    if all(tangent == vec3<f32>(0.0)) {
        return s;
    }
    let sign = select(1.0, -1.0, c0.w < 0.0);
    let bitangent = mul3(cross3(n, tangent), vec3<f32>(sign));
    let x = mul(rounded(mul(texel.x, 2.0) - 1.0), m.normal_scale);
    let y = mul(rounded(mul(texel.y, 2.0) - 1.0), m.normal_scale);
    let z = rounded(mul(texel.z, 2.0) - 1.0);
    let sum = vec3<f32>(
        rounded(rounded(mul(tangent.x, x) + mul(bitangent.x, y)) + mul(n.x, z)),
        rounded(rounded(mul(tangent.y, x) + mul(bitangent.y, y)) + mul(n.y, z)),
        rounded(rounded(mul(tangent.z, x) + mul(bitangent.z, y)) + mul(n.z, z)),
    );
    let mapped = mul3(normalize_or_zero(sum), vec3<f32>(side));
    if all(mapped == vec3<f32>(0.0)) {
        return s;
    }
    var r = s;
    if any(ng != vec3<f32>(0.0)) && dot3(mapped, ng) < 0.0 {
        r.normal = ng;
    } else {
        r.normal = mapped;
    }
    return r;
}

// mirrors hyrt_core::kernels::reconstruction::primary_normal_mapped
fn primary_normal_mapped(t: GBufferTexel, s: SurfaceRecord, eye: vec3<f32>) -> SurfaceRecord {
    if s.object == INVALID_ID {
        return s;
    }
    let to_eye = eye - s.position;
    let d = -normalize_or_zero(to_eye);
    return normal_mapped(s, t.bary_u, t.bary_v, primary_cone(to_eye), d, (t.flags & GBUF_BACK_FACE) != 0u);
}

// mirrors hyrt_core::kernels::reconstruction::secondary_normal_mapped
fn secondary_normal_mapped(ray: RayRecord, hit: HitRecord, s: SurfaceRecord) -> SurfaceRecord {
    if s.object == INVALID_ID {
        return s;
    }
    var cone = 0.0;
    if params.pixel_spread != 0.0 {
        cone = ray.cone + mul(params.pixel_spread, hit.t);
    }
    return normal_mapped(s, hit.u, hit.v, cone, ray.direction, (hit.flags & HIT_BACK_FACE) != 0u);
}

// mirrors hyrt_core::kernels::bounce::Parent
struct Parent {
    surface: SurfaceRecord,
    d: vec3<f32>,
    back_face: bool,
    throughput: vec3<f32>,
    pixel: u32,
    cone: f32,
    object: ObjectRecord,
}

// mirrors hyrt_core::kernels::bounce::parent_object (private there): the shaded record
// of the object at a parent's surface, zeros for a miss.
fn parent_object(s: SurfaceRecord, u: f32, v: f32, cone: f32, d: vec3<f32>) -> ObjectRecord {
    if s.object != INVALID_ID {
        return shaded_object(s, u, v, cone, d);
    }
    var none: ObjectRecord;
    return none;
}

// mirrors hyrt_core::kernels::bounce::primary_cone
fn primary_cone(to_eye: vec3<f32>) -> f32 {
    if params.pixel_spread == 0.0 {
        return 0.0;
    }
    // glam's `length`: the square root of the dot product.
    return mul(params.pixel_spread, sqrt_rn(dot3(to_eye, to_eye)));
}

// mirrors hyrt_core::kernels::bounce::primary_parent
fn primary_parent(t: GBufferTexel, s: SurfaceRecord, eye: vec3<f32>, pixel: u32) -> Parent {
    let to_eye = eye - s.position;
    let d = -normalize_or_zero(to_eye);
    let cone = primary_cone(to_eye);
    let object = parent_object(s, t.bary_u, t.bary_v, cone, d);
    return Parent(s, d, (t.flags & GBUF_BACK_FACE) != 0u, vec3<f32>(1.0), pixel, cone, object);
}

// mirrors hyrt_core::kernels::bounce::secondary_parent
fn secondary_parent(ray: RayRecord, hit: HitRecord, s: SurfaceRecord) -> Parent {
    let d = ray.direction;
    var cone = 0.0;
    if params.pixel_spread != 0.0 {
        cone = ray.cone + mul(params.pixel_spread, hit.t);
    }
    let object = parent_object(s, hit.u, hit.v, cone, d);
    return Parent(s, d, (hit.flags & HIT_BACK_FACE) != 0u, ray.throughput, ray.pixel, cone, object);
}
