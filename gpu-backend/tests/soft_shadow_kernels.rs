//! The kernels of `shaders/soft_shadow.wgsl` one by one against the core's
//! (`hyrt_core::kernels::soft_shadow`: `surface_key`, `stream_seed`, `area_light_sample`,
//! `occlusion_direction`, `light_slots`), bit for bit, on seeded random surfaces and
//! lights of every kind (quad, sphere, sun, and a point light, which is no area light),
//! with the hard cases mixed in: signed zeros in a point's coordinates, points inside a
//! sphere light and behind a quad, large coordinates. (`needs_slot_ray` and `slot_ray`
//! are compared through the ray lists they make: `tests/soft_shadows.rs` and the
//! conformance corpus' `stochastic_*` cases.)

mod common;

use common::test_context;
use hyrt_core::formats::{AmbientLightRecord, FrameParams, LightRecord, SurfaceRecord};
use hyrt_core::glam::Vec3;
use hyrt_core::kernels::soft_shadow::{
    area_light_sample, frame_lights, frame_occlusion, light_slots, occlusion_direction, stream_seed, surface_key,
};
use hyrt_core::scene::Light;
use hyrt_gpu::exact::same_bits;
use hyrt_gpu::gpu_buffer::{read_back, storage, upload};
use hyrt_gpu::shader::{
    bind_buffers, compute_pipeline, inexact_operations, shading_source, soft_shadow_wgsl, storage_entry, uniform_entry,
};
use wgpu::util::DeviceExt;

/// Result words per query.
const OUT: usize = 17;

/// What each result word is.
const NAMES: [&str; OUT] = [
    "surface_key",
    "stream_seed",
    "area_light_sample.l.x",
    "area_light_sample.l.y",
    "area_light_sample.l.z",
    "area_light_sample.distance",
    "area_light_sample.weight.x",
    "area_light_sample.weight.y",
    "area_light_sample.weight.z",
    "area_light_sample.is_some",
    "occlusion_direction.x",
    "occlusion_direction.y",
    "occlusion_direction.z",
    "occlusion_direction.is_some",
    "light_slots",
    "light_is_area",
    "ambient_occlusion.samples",
];

const ENTRY: &str = r#"
@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<uniform> ambient_light: AmbientLightRecord;
@group(0) @binding(2) var<storage, read> lights: array<LightRecord>;
@group(0) @binding(3) var<storage, read> surfaces: array<SurfaceRecord>;
@group(0) @binding(4) var<storage, read> samples: array<u32>;
@group(0) @binding(5) var<storage, read_write> results: array<u32>;

fn out_v3(o: u32, v: vec3<f32>) {
    results[o] = bitcast<u32>(v.x);
    results[o + 1u] = bitcast<u32>(v.y);
    results[o + 2u] = bitcast<u32>(v.z);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= arrayLength(&samples) {
        return;
    }
    let s = surfaces[i];
    let light = lights[i];
    let k = samples[i];
    let o = i * OUT;
    let key = surface_key(s.position);
    results[o] = key;
    results[o + 1u] = stream_seed(key, light.seed);
    let ls = area_light_sample(light, s.position, k);
    out_v3(o + 2u, ls.l);
    results[o + 5u] = bitcast<u32>(ls.distance);
    out_v3(o + 6u, ls.weight);
    results[o + 9u] = select(0u, 1u, ls.valid);
    let ao = frame_occlusion();
    let d = occlusion_direction(s, ao, k);
    out_v3(o + 10u, select(vec3<f32>(0.0), d.d, d.valid));
    results[o + 13u] = select(0u, 1u, d.valid);
    results[o + 14u] = light_slots(light);
    results[o + 15u] = select(0u, 1u, light_is_area(light));
    results[o + 16u] = ao.samples;
}
"#;

struct Rng(u64);

impl Rng {
    fn u32(&mut self) -> u32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 32) as u32
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * (self.u32() >> 8) as f32 / (1u32 << 24) as f32
    }

    fn vec(&mut self, half: f32) -> Vec3 {
        Vec3::new(self.range(-half, half), self.range(-half, half), self.range(-half, half))
    }

    fn unit_vec(&mut self) -> Vec3 {
        loop {
            let v = self.vec(1.0);
            if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }
}

/// A light of every kind in turn, each area light with `samples` samples and a seed of
/// its own (`frame_lights`).
fn light(rng: &mut Rng, k: usize) -> LightRecord {
    let color = Vec3::new(1.0, 0.8, 0.6);
    let light = match k % 4 {
        0 => Light::Quad {
            corner: rng.vec(2.0) + Vec3::new(0.0, 2.0, 0.0),
            edge_u: rng.vec(1.0),
            edge_v: rng.vec(1.0),
            color,
            intensity: rng.range(0.5, 20.0),
        },
        1 => Light::Sphere { position: rng.vec(2.0), radius: rng.range(0.01, 1.5), color, intensity: 5.0 },
        2 => Light::Sun {
            direction: rng.unit_vec(),
            angular_diameter: rng.range(1e-4, 0.5),
            color,
            intensity: rng.range(0.5, 5.0),
        },
        _ => Light::point(rng.vec(3.0), color, 4.0),
    };
    frame_lights(&[LightRecord::from_light(&light)], 5, rng.u32()).remove(0)
}

/// A surface point with its normals; hard cases among them.
fn surface(rng: &mut Rng, k: usize) -> SurfaceRecord {
    let mut p = rng.vec(3.0);
    match k % 9 {
        0 => p.x = -0.0,
        1 => p = Vec3::new(0.0, -0.0, 0.0),
        2 => p *= 1.0e5,
        3 => p = Vec3::splat(0.0),
        _ => {}
    }
    let normal = rng.unit_vec();
    // A geometric normal near the shading one, or across it (rays below the surface).
    let geometric = match k % 5 {
        0 => (normal + rng.vec(1.5)).normalize_or(normal),
        _ => (normal + rng.vec(0.2)).normalize_or(normal),
    };
    SurfaceRecord {
        position: p.into(),
        position_error: 1e-6,
        normal: normal.into(),
        object: 0,
        geometric_normal: geometric.into(),
        triangle: 0,
    }
}

fn words(v: Vec3) -> [u32; 3] {
    v.to_array().map(f32::to_bits)
}

#[test]
fn soft_shadow_kernels_match_cpu_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let count = 1 << 13;
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let lights: Vec<LightRecord> = (0..count).map(|k| light(&mut rng, k)).collect();
    let surfaces: Vec<SurfaceRecord> = (0..count).map(|k| surface(&mut rng, k)).collect();
    let samples: Vec<u32> = (0..count).map(|k| if k % 7 == 0 { rng.u32() } else { rng.u32() % 64 }).collect();
    let ao = frame_occlusion(4, 0.5, 3);
    let ambient = AmbientLightRecord {
        scale: 1.0,
        image: 0,
        ao_samples: ao.samples,
        ao_seed: ao.seed,
        ao_radius: ao.radius,
        ..bytemuck::Zeroable::zeroed()
    };
    let source = shading_source(&format!("const OUT: u32 = {OUT}u;\n{}\n{ENTRY}", soft_shadow_wgsl()));
    assert_eq!(inexact_operations(&source), Ok(Vec::new()));
    let entries = [
        uniform_entry(0),
        uniform_entry(1),
        storage_entry(2, true),
        storage_entry(3, true),
        storage_entry(4, true),
        storage_entry(5, false),
    ];
    let (pipeline, layout) = compute_pipeline(&ctx, "soft shadow kernels test", &source, &entries);
    let uniform = |label: &str, contents: &[u8]| {
        ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage: wgpu::BufferUsages::UNIFORM,
        })
    };
    let params = uniform("params", bytemuck::bytes_of(&FrameParams::new(1, 1, 1, 1.0)));
    let ambient_buffer = uniform("ambient light", bytemuck::bytes_of(&ambient));
    let buffers = [
        &params,
        &ambient_buffer,
        &upload(&ctx, "lights", &lights),
        &upload(&ctx, "surfaces", &surfaces),
        &upload(&ctx, "samples", &samples),
        &storage::<u32>(&ctx, "results", count * OUT).expect("results buffer"),
    ];
    let group = bind_buffers(&ctx, "soft shadow kernels test", &layout, &buffers);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups((count as u32).div_ceil(64), 1, 1);
    }
    ctx.queue.submit([encoder.finish()]);
    let gpu = read_back::<u32>(&ctx, buffers[5], count * OUT).expect("read back");

    let (mut some_light, mut some_ao) = (0, 0);
    let mut differing = std::collections::BTreeMap::<&str, (usize, String)>::new();
    for k in 0..count {
        let (l, s, n) = (&lights[k], &surfaces[k], samples[k]);
        let p = Vec3::from(s.position);
        let key = surface_key(p);
        let mut want = [0u32; OUT];
        want[0] = key;
        want[1] = stream_seed(key, l.seed);
        if let Some(ls) = area_light_sample(l, &[], p, n) {
            want[2..5].copy_from_slice(&words(ls.l));
            want[5] = ls.distance.to_bits();
            want[6..9].copy_from_slice(&words(ls.weight));
            want[9] = 1;
            some_light += 1;
        }
        if let Some(d) = occlusion_direction(s, &ao, n) {
            want[10..13].copy_from_slice(&words(d));
            want[13] = 1;
            some_ao += 1;
        }
        want[14] = light_slots(l) as u32;
        want[15] = l.is_area() as u32;
        want[16] = ao.samples;
        for (word, (&g, &c)) in gpu[k * OUT..(k + 1) * OUT].iter().zip(&want).enumerate() {
            if !same_bits(g, c) {
                let e = differing.entry(NAMES[word]).or_insert_with(|| {
                    (0, format!("query {k}: gpu {g:#010x} cpu {c:#010x}, light {l:?}, surface {s:?}, sample {n}"))
                });
                e.0 += 1;
            }
        }
    }
    // Both outcomes of each Option are reached.
    assert!(some_light > count / 4 && some_light < count - count / 8, "area_light_sample: Some in {some_light}");
    assert!(some_ao > count / 4 && some_ao < count - count / 20, "occlusion_direction: Some in {some_ao}");
    assert!(differing.is_empty(), "{}: differing words per function: {differing:#?}", ctx.info.name);
}
