// The stochastic shadow rays of area lights and ambient occlusion: WGSL mirrors of
// hyrt_core::kernels::soft_shadow (the sample streams and the samples a mask slot stands
// for), same names as the core's functions, same operation order (sampling.wgsl says how).
//
// A surface's shadow mask holds one code per *slot*: one per point, spot or directional
// light, `samples` per area light (quad, sphere, sun, emitters), in light order, then
// `ambient_light.ao_samples` ambient-occlusion slots (`slot_params.slots` in all,
// `slot_params.light_slots` of them the lights').
//
// Prepended by `hyrt_gpu::shader::soft_shadow_wgsl` after sampling.wgsl, area_light.wgsl,
// occlusion.wgsl, the generated constants LIGHT_QUAD, LIGHT_SPHERE, LIGHT_SUN,
// LIGHT_EMITTERS and the `SlotParams` declaration (hyrt_gpu::buffers::SlotParams). The
// stage binds `params: FrameParams`, `lights: array<LightRecord>` (the frame's: area
// lights carry their samples and seeds; the emitter table follows the records, see
// `emitter_at`), `ambient_light: AmbientLightRecord` (the frame's: its occlusion rays) and
// `slot_params: SlotParams` (the mask's slots, and the emitter table's length).

// The frame traces stochastic rays (hyrt_gpu::texture::Specialization::stochastic, a
// pipeline constant): false compiles the slot walks and the samplers out of the stages
// of frames without area lights and ambient occlusion, whose masks have one slot per
// light (the paper's).
override STOCHASTIC: bool = false;

// mirrors hyrt_core::formats::LightRecord::is_area
fn light_is_area(light: LightRecord) -> bool {
    return light.kind == LIGHT_QUAD || light.kind == LIGHT_SPHERE || light.kind == LIGHT_SUN
        || light.kind == LIGHT_EMITTERS;
}

// The length of the frame's emitter table (hyrt_core::geometry::WorldGeometry::emitters;
// 0 without one): what area_light.wgsl's mirrors take as the slice's length.
fn emitter_count() -> u32 {
    return slot_params.emitters;
}

// Emitter `i` of the frame's emitter table: packed into `lights` after the frame's
// `params.light_count` light records, one 96-byte slot per emitter, each field of the
// EmitterRecord in a LightRecord field of its type (hyrt_gpu::buffers::emitter_slot
// documents the layout to the byte): the stages bind no storage buffer more for it.
fn emitter_at(i: u32) -> EmitterRecord {
    let r = lights[params.light_count + i];
    return EmitterRecord(
        r.position_or_direction,
        r.inv_range_sq,
        r.radiance,
        r.kind,
        r.spot_direction,
        r.samples,
        vec3<f32>(r.spot_scale, r.spot_offset, r.size),
        r.seed,
    );
}

// mirrors hyrt_core::kernels::soft_shadow::light_slots
fn light_slots(light: LightRecord) -> u32 {
    return select(1u, light.samples, light_is_area(light));
}

// mirrors hyrt_core::kernels::soft_shadow::AmbientOcclusion (the frame's, from its
// ambient light record).
struct AmbientOcclusion {
    samples: u32,
    radius: f32,
    seed: u32,
}

// The frame's ambient occlusion (hyrt_core::kernels::shading::AmbientLight::occlusion).
fn frame_occlusion() -> AmbientOcclusion {
    return AmbientOcclusion(ambient_light.ao_samples, ambient_light.ao_radius, ambient_light.ao_seed);
}

// mirrors hyrt_core::kernels::soft_shadow::surface_key
fn surface_key(p: vec3<f32>) -> u32 {
    return hash_combine(hash_combine(hash_u32(bitcast<u32>(p.x)), bitcast<u32>(p.y)), bitcast<u32>(p.z));
}

// mirrors hyrt_core::kernels::soft_shadow::stream_seed
fn stream_seed(key: u32, seed: u32) -> u32 {
    return hash_combine(hash_u32(key), seed);
}

// mirrors hyrt_core::kernels::soft_shadow::area_light_sample; not valid (Rust's `None`)
// where the sampled point does not face `p`, and for a light that is no area light.
fn area_light_sample(light: LightRecord, p: vec3<f32>, sample: u32) -> LightSample {
    let u = sample_2d(sample, stream_seed(surface_key(p), light.seed));
    let radiance = light.radiance;
    let at = light.position_or_direction;
    if light.kind == LIGHT_QUAD {
        return sample_quad_light(at, light.edge_u, light.edge_v, radiance, p, u);
    }
    if light.kind == LIGHT_SPHERE {
        return sample_sphere_light(at, light.size, radiance, p, u);
    }
    if light.kind == LIGHT_SUN {
        return sample_sun(at, light.size, radiance, u);
    }
    if light.kind == LIGHT_EMITTERS {
        return sample_emitters(p, u);
    }
    return no_light_sample();
}

// mirrors hyrt_core::kernels::soft_shadow::occlusion_direction (`valid` false for Rust's
// `None`: below the geometric surface).
fn occlusion_direction(s: SurfaceRecord, ao: AmbientOcclusion, sample: u32) -> AoDirection {
    let u = sample_2d(sample, stream_seed(surface_key(s.position), ao.seed));
    return ao_direction(s.normal, s.geometric_normal, u);
}
