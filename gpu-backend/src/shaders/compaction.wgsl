// Stage `compaction` (per pair the kernels of hyrt_core::kernels::shadow): flag every
// (light, surface) pair whose light can contribute at the surface (k = light * slots +
// surface), then compact (scan.wgsl) into one shadow ray per active pair, light-major
// then surface order. The surfaces are the pixels' (depth 0) or those the secondary
// rays of bounce `list.depth` hit; surfaces at or past the live count (`live[0]`) have
// no pair.
//
// Prepended at pipeline creation: the generated records and format constants
// (hyrt_core::formats::wgsl), the stage's constants (WG, ITEMS, TILE, SHADOW_WG, ...),
// ray.wgsl and shading_helpers.wgsl (`light_incidence`, `light_can_contribute`, the
// exact arithmetic that reads `params.zero`). Followed by scan.wgsl.

@group(1) @binding(0) var<uniform> params: FrameParams;
@group(1) @binding(1) var<storage, read> surfaces: array<SurfaceRecord>;
@group(1) @binding(2) var<storage, read> lights: array<LightRecord>;
@group(1) @binding(3) var<storage, read_write> rays: array<RayRecord>;
@group(1) @binding(4) var<uniform> list: ListParams;
@group(1) @binding(5) var<storage, read> live: array<u32, 4>;
// Test entry point `scatter_indices` only (group 1 of its own): the compacted indices.
@group(1) @binding(6) var<storage, read_write> out_indices: array<u32>;

// mirrors hyrt_core::kernels::shadow::needs_shadow_ray
fn needs_shadow_ray(s: SurfaceRecord, light: LightRecord) -> bool {
    if s.object == INVALID_ID {
        return false;
    }
    let inc = light_incidence(light, s.position);
    return light_can_contribute(s.geometric_normal, s.normal, inc.l, inc.e);
}

// mirrors hyrt_core::kernels::shadow::shadow_ray. +inf (directional lights) comes from
// its bits at run time: no WGSL constant may hold it.
fn shadow_ray(s: SurfaceRecord, light: LightRecord, light_index: u32, pixel: u32) -> RayRecord {
    let origin = offset_ray_origin(s.position, s.position_error, s.geometric_normal, params.zero);
    var direction: vec3<f32>;
    var t_max: f32;
    if light.kind == LIGHT_DIRECTIONAL {
        direction = -light.position_or_direction;
        t_max = bitcast<f32>(F32_EXP_MASK | params.zero); // +inf
    } else {
        direction = light.position_or_direction - origin;
        t_max = bitcast<f32>(SHADOW_T_MAX_POINT_BITS);
    }
    return RayRecord(origin, 0.0, direction, t_max, pixel, RAY_KIND_SHADOW, 0u, light_index,
        vec3<f32>(1.0, 1.0, 1.0), 0.0);
}

// The flag of pair k = light * slots + surface.
fn element_flag(k: u32) -> u32 {
    let l = k / list.slots;
    let p = k - l * list.slots;
    if p >= live[0] {
        return 0u;
    }
    return select(0u, 1u, needs_shadow_ray(surfaces[p], lights[l]));
}

fn emit(k: u32, kept: bool, dst: u32) {
    // Rays past the buffer's room are not written: the backend sees the count, makes
    // room and runs the frame again.
    if kept && dst < arrayLength(&rays) {
        let l = k / list.slots;
        let p = k - l * list.slots;
        rays[dst] = shadow_ray(surfaces[p], lights[l], l, p);
    }
}

// Scan-only test entry point: the indices of the non-zero flags, in order.
@compute @workgroup_size(WG)
fn scatter_indices(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>,
                   @builtin(num_workgroups) nwg: vec3<u32>) {
    let t = tile_index(wid, nwg);
    var dst = scatter_base(lid, t);
    let base = t * TILE + lid * ITEMS;
    for (var j = 0u; j < ITEMS; j = j + 1u) {
        let k = base + j;
        if k < level.n && flags[k] != 0u {
            out_indices[dst] = k;
            dst = dst + 1u;
        }
    }
}
