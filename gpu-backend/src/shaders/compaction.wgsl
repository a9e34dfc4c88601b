// Stage `compaction` (per pair the kernels of hyrt_core::kernels::shadow, and with area
// lights or ambient occlusion those of hyrt_core::kernels::soft_shadow): flag every
// (slot, surface) pair that needs a shadow ray (k = slot * slots + surface, `slots` the
// list's room), then compact (scan.wgsl) into one shadow ray per active pair, slot-major
// then surface order; a ray's `light` field is its slot. Without area lights and ambient
// occlusion a surface has one slot per light (the paper's pairs, `STOCHASTIC` false);
// with them, `samples` slots per area light and then the occlusion rays' (soft_shadow.wgsl).
// The surfaces are the pixels' (depth 0) or those the secondary rays of bounce
// `list.depth` hit; surfaces at or past the live count (`live[0]`) have no pair.
//
// Prepended at pipeline creation: the generated records and format constants
// (hyrt_core::formats::wgsl), the stage's constants (WG, ITEMS, TILE, SHADOW_WG, ...),
// ray.wgsl, shading_helpers.wgsl (`light_incidence`, `light_can_contribute`, the
// exact arithmetic that reads `params.zero`) and the soft-shadow kernels
// (`hyrt_gpu::shader::soft_shadow_wgsl`). Followed by scan.wgsl.

@group(1) @binding(0) var<uniform> params: FrameParams;
@group(1) @binding(1) var<storage, read> surfaces: array<SurfaceRecord>;
@group(1) @binding(2) var<storage, read> lights: array<LightRecord>;
@group(1) @binding(3) var<storage, read_write> rays: array<RayRecord>;
@group(1) @binding(4) var<uniform> list: ListParams;
@group(1) @binding(5) var<storage, read> live: array<u32, 4>;
// The frame's ambient light (its occlusion rays) and mask slots; read where STOCHASTIC.
@group(1) @binding(6) var<uniform> ambient_light: AmbientLightRecord;
@group(1) @binding(7) var<uniform> slot_params: SlotParams;
// Test entry point `scatter_indices` only (group 1 of its own): the compacted indices.
@group(1) @binding(8) var<storage, read_write> out_indices: array<u32>;

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

// mirrors hyrt_core::kernels::soft_shadow::Slot: sample `sample` of light `light` (0 for
// a light that is not an area light), or, `occlusion` set, ambient-occlusion ray `sample`.
struct Slot {
    occlusion: bool,
    light: u32,
    sample: u32,
}

// mirrors `hyrt_core::kernels::soft_shadow::slot_table(lights, ao)[slot]`: the lights'
// slots in light order (`light_slots` each), then the occlusion rays'.
fn slot_table_entry(slot: u32) -> Slot {
    if slot >= slot_params.light_slots {
        return Slot(true, 0u, slot - slot_params.light_slots);
    }
    var first = 0u;
    for (var l = 0u; l < params.light_count; l++) {
        let k = light_slots(lights[l]);
        if slot < first + k {
            return Slot(false, l, slot - first);
        }
        first += k;
    }
    // Not reached: `light_slots` is the lights' slots.
    return Slot(true, 0u, slot);
}

// mirrors hyrt_core::kernels::soft_shadow::needs_slot_ray over the frame's `lights` and
// occlusion.
fn needs_slot_ray(s: SurfaceRecord, slot: Slot) -> bool {
    if s.object == INVALID_ID {
        return false;
    }
    if !slot.occlusion {
        let light = lights[slot.light];
        if !light_is_area(light) {
            return needs_shadow_ray(s, light);
        }
        let ls = area_light_sample(light, s.position, slot.sample);
        if ls.valid {
            return light_can_contribute(s.geometric_normal, s.normal, ls.l, ls.weight);
        }
        return false;
    }
    return occlusion_direction(s, frame_occlusion(), slot.sample).valid;
}

// mirrors hyrt_core::kernels::shadow::shadow_ray_record
fn shadow_ray_record(origin: vec3<f32>, direction: vec3<f32>, t_max: f32, light_index: u32, pixel: u32) -> RayRecord {
    return RayRecord(origin, 0.0, direction, t_max, pixel, RAY_KIND_SHADOW, 0u, light_index,
        vec3<f32>(1.0, 1.0, 1.0), 0.0);
}

// mirrors hyrt_core::kernels::soft_shadow::slot_ray over the frame's `lights` and
// occlusion: the ray of slot `slot_index` (standing for `slot`) of surface `s`, the
// surface `index` of its list. +inf (suns) comes from its bits at run time.
fn slot_ray(s: SurfaceRecord, slot: Slot, slot_index: u32, index: u32) -> RayRecord {
    let p = s.position;
    let origin = offset_ray_origin(p, s.position_error, s.geometric_normal, params.zero);
    if !slot.occlusion {
        let light = lights[slot.light];
        if !light_is_area(light) {
            return shadow_ray(s, light, slot_index, index);
        }
        let ls = area_light_sample(light, p, slot.sample);
        if !ls.valid {
            return shadow_ray_record(origin, vec3<f32>(0.0), 0.0, slot_index, index);
        }
        if light.kind == LIGHT_SUN {
            return shadow_ray_record(origin, ls.l, bitcast<f32>(F32_EXP_MASK | params.zero), slot_index, index);
        }
        // (p + l * distance) - origin, glam's order, each step rounded apart.
        let end = sampling_rounded3(p + sampling_scale3(ls.l, ls.distance));
        let direction = sampling_rounded3(end - origin);
        return shadow_ray_record(origin, direction, bitcast<f32>(SHADOW_T_MAX_POINT_BITS), slot_index, index);
    }
    let ao = frame_occlusion();
    let d = occlusion_direction(s, ao, slot.sample);
    let direction = select(vec3<f32>(0.0), d.d, d.valid);
    return shadow_ray_record(origin, direction, ao.radius, slot_index, index);
}

// The flag of pair k = slot * slots + surface.
fn element_flag(k: u32) -> u32 {
    let l = k / list.slots;
    let p = k - l * list.slots;
    if p >= live[0] {
        return 0u;
    }
    if STOCHASTIC {
        return select(0u, 1u, needs_slot_ray(surfaces[p], slot_table_entry(l)));
    }
    return select(0u, 1u, needs_shadow_ray(surfaces[p], lights[l]));
}

fn emit(k: u32, kept: bool, dst: u32) {
    // Rays past the buffer's room are not written: the backend sees the count, makes
    // room and runs the frame again.
    if kept && dst < arrayLength(&rays) {
        let l = k / list.slots;
        let p = k - l * list.slots;
        if STOCHASTIC {
            rays[dst] = slot_ray(surfaces[p], slot_table_entry(l), l, p);
        } else {
            rays[dst] = shadow_ray(surfaces[p], lights[l], l, p);
        }
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
