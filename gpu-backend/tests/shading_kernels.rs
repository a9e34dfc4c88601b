//! The shading kernels of `shaders/shading.wgsl` and `shaders/shading_helpers.wgsl` one by
//! one against the core's (`hyrt_core::kernels::shading`), bit for bit, on seeded random
//! inputs: `schlick_weight`, `ggx_distribution`, `smith_visibility`, `gltf_brdf`,
//! `normalize_or_zero`, `pow_portable`, `blinn_phong_exponent` and `light_incidence` (of a
//! point light, and of a spot light with a range: `light_falloff`). The
//! stage tests (`shading.rs`) check whole frames; this one names the kernel that differs
//! when a device rounds some operation its own way (the float probe says which).

mod common;

use common::test_context;
use hyrt_core::formats::{FrameParams, LightRecord, LIGHT_SPOT};
use hyrt_core::glam::Vec3;
use hyrt_core::kernels::shading as cpu;
use hyrt_gpu::exact::same_bits;
use hyrt_gpu::gpu_buffer::{read_back, storage, upload};
use hyrt_gpu::shader::{bind_buffers, compute_pipeline, shading_source, storage_entry, uniform_entry};
use wgpu::util::DeviceExt;

/// Input words per query and result words per query.
const IN: usize = 20;
const OUT: usize = 18;

const ENTRY: &str = r#"
@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<storage, read> inputs: array<f32>;
@group(0) @binding(2) var<storage, read_write> results: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let q = gid.x;
    if q >= arrayLength(&results) / OUT {
        return;
    }
    let i = q * IN;
    let o = q * OUT;
    let base = vec3<f32>(inputs[i], inputs[i + 1u], inputs[i + 2u]);
    let metallic = inputs[i + 3u];
    let roughness = inputs[i + 4u];
    let n = vec3<f32>(inputs[i + 5u], inputs[i + 6u], inputs[i + 7u]);
    let v = vec3<f32>(inputs[i + 8u], inputs[i + 9u], inputs[i + 10u]);
    let l = vec3<f32>(inputs[i + 11u], inputs[i + 12u], inputs[i + 13u]);
    let x = inputs[i + 14u];
    let y = inputs[i + 15u];
    let z = inputs[i + 16u];
    let w = inputs[i + 17u];
    let u = inputs[i + 18u];
    results[o] = bitcast<u32>(schlick_weight(x));
    results[o + 1u] = bitcast<u32>(ggx_distribution(x, y, z));
    results[o + 2u] = bitcast<u32>(smith_visibility(x, y, z, w, u));
    let f = gltf_brdf(base, metallic, roughness, w, n, v, l);
    results[o + 3u] = bitcast<u32>(f.x);
    results[o + 4u] = bitcast<u32>(f.y);
    results[o + 5u] = bitcast<u32>(f.z);
    let m = normalize_or_zero(v + l);
    results[o + 6u] = bitcast<u32>(m.x);
    results[o + 7u] = bitcast<u32>(m.y);
    results[o + 8u] = bitcast<u32>(m.z);
    results[o + 9u] = bitcast<u32>(pow_portable(x, mul(y, 100.0)));
    results[o + 10u] = bitcast<u32>(blinn_phong_exponent(roughness));
    let position = mul3(l, vec3<f32>(10.0));
    let radiance = mul3(base, vec3<f32>(5.0));
    let light = LightRecord(position, LIGHT_POINT, radiance, 0.0, vec3<f32>(0.0), 0.0, 0.0, 0.0, 0u, 0u, vec3<f32>(0.0), 0u, vec3<f32>(0.0), 0u);
    let inc = light_incidence(light, v);
    results[o + 11u] = bitcast<u32>(inc.l.x);
    results[o + 12u] = bitcast<u32>(inc.l.y);
    results[o + 13u] = bitcast<u32>(inc.e.x);
    results[o + 14u] = bitcast<u32>(inc.e.z);
    results[o + 15u] = bitcast<u32>(dot3(n, l));
    // A spot light with a range at the same place, pointing along -n: the cone from the
    // scale and offset the inputs give, the window from `u`.
    let scale = 1.0 + mul(z, 20.0);
    let spot = LightRecord(position, LIGHT_SPOT, radiance, mul(u, 0.02), -n, scale, -mul(y, scale), 0.0, 0u, 0u, vec3<f32>(0.0), 0u, vec3<f32>(0.0), 0u);
    let s = light_incidence(spot, v);
    results[o + 16u] = bitcast<u32>(s.e.x);
    results[o + 17u] = bitcast<u32>(s.e.y);
}
"#;

const NAMES: [&str; OUT] = [
    "schlick_weight",
    "ggx_distribution",
    "smith_visibility",
    "gltf_brdf.x",
    "gltf_brdf.y",
    "gltf_brdf.z",
    "normalize_or_zero.x",
    "normalize_or_zero.y",
    "normalize_or_zero.z",
    "pow_portable",
    "blinn_phong_exponent",
    "light_incidence.l.x",
    "light_incidence.l.y",
    "light_incidence.e.x",
    "light_incidence.e.z",
    "dot3",
    "light_incidence.e.x (spot, range)",
    "light_incidence.e.y (spot, range)",
];

fn cpu_results(q: &[f32]) -> [u32; OUT] {
    let base = Vec3::new(q[0], q[1], q[2]);
    let (metallic, roughness) = (q[3], q[4]);
    let n = Vec3::new(q[5], q[6], q[7]);
    let v = Vec3::new(q[8], q[9], q[10]);
    let l = Vec3::new(q[11], q[12], q[13]);
    let (x, y, z, w, u) = (q[14], q[15], q[16], q[17], q[18]);
    let f = cpu::gltf_brdf(base, metallic, roughness, w, n, v, l);
    let m = (v + l).normalize_or_zero();
    let light = LightRecord::point((l * 10.0).into(), (base * 5.0).into());
    let (il, ie) = cpu::light_incidence(&light, v);
    let scale = 1.0 + z * 20.0;
    let spot = LightRecord {
        kind: LIGHT_SPOT,
        inv_range_sq: u * 0.02,
        spot_direction: (-n).into(),
        spot_scale: scale,
        spot_offset: -(y * scale),
        ..light
    };
    let (_, se) = cpu::light_incidence(&spot, v);
    [
        cpu::schlick_weight(x).to_bits(),
        cpu::ggx_distribution(x, y, z).to_bits(),
        cpu::smith_visibility(x, y, z, w, u).to_bits(),
        f.x.to_bits(),
        f.y.to_bits(),
        f.z.to_bits(),
        m.x.to_bits(),
        m.y.to_bits(),
        m.z.to_bits(),
        cpu::pow_portable(x, y * 100.0).to_bits(),
        cpu::blinn_phong_exponent(roughness).to_bits(),
        il.x.to_bits(),
        il.y.to_bits(),
        ie.x.to_bits(),
        ie.z.to_bits(),
        n.dot(l).to_bits(),
        se.x.to_bits(),
        se.y.to_bits(),
    ]
}

/// Seeded queries: unit vectors for n, v, l (v and l mostly on n's side), colours, metallic
/// and roughness in [0, 1] (a tenth of them 0 or 1), scalars in [0, 1].
fn queries(count: usize) -> Vec<f32> {
    let mut s = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        ((s >> 40) as f32) / (1u64 << 24) as f32
    };
    let unit = |next: &mut dyn FnMut() -> f32| {
        Vec3::new(next() * 2.0 - 1.0, next() * 2.0 - 1.0, next() * 2.0 - 1.0).normalize_or_zero()
    };
    let mut q = Vec::with_capacity(count * IN);
    for k in 0..count {
        let n = unit(&mut next);
        let mut v = unit(&mut next);
        let mut l = unit(&mut next);
        if k % 4 != 0 {
            v = if v.dot(n) < 0.0 { -v } else { v };
            l = if l.dot(n) < 0.0 { -l } else { l };
        }
        let edge = |x: f32, k: usize| match k % 10 {
            0 => 0.0,
            1 => 1.0,
            _ => x,
        };
        let metallic = edge(next(), k);
        let roughness = edge(next(), k / 10);
        q.extend([next(), next(), next(), metallic, roughness]);
        q.extend(n.to_array());
        q.extend(v.to_array());
        q.extend(l.to_array());
        q.extend([next(), next(), next(), next(), next(), 0.0]);
    }
    q
}

#[test]
fn shading_kernels_match_cpu_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let count = 1 << 14;
    let inputs = queries(count);
    let source = shading_source(&format!("const IN: u32 = {IN}u;\nconst OUT: u32 = {OUT}u;\n{ENTRY}"));
    let entries = [uniform_entry(0), storage_entry(1, true), storage_entry(2, false)];
    let (pipeline, layout) = compute_pipeline(&ctx, "shading kernels test", &source, &entries);
    let params = ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("params"),
        contents: bytemuck::bytes_of(&FrameParams::new(1, 1, 0, 0.5)),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let input_buffer = upload(&ctx, "inputs", &inputs);
    let results = storage::<u32>(&ctx, "results", count * OUT).expect("results buffer");
    let group = bind_buffers(&ctx, "shading kernels test", &layout, &[&params, &input_buffer, &results]);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups((count as u32).div_ceil(64), 1, 1);
    }
    ctx.queue.submit([encoder.finish()]);
    let gpu = read_back::<u32>(&ctx, &results, count * OUT).expect("read back");
    let mut per_kernel = std::collections::BTreeMap::<&str, usize>::new();
    let mut first = std::collections::BTreeMap::<&str, String>::new();
    for k in 0..count {
        let q = &inputs[k * IN..(k + 1) * IN];
        let want = cpu_results(q);
        for (word, (&g, &c)) in gpu[k * OUT..(k + 1) * OUT].iter().zip(&want).enumerate() {
            if !same_bits(g, c) {
                *per_kernel.entry(NAMES[word]).or_default() += 1;
                first.entry(NAMES[word]).or_insert_with(|| {
                    format!(
                        "query {k} {}: gpu {g:#010x} ({:e}) cpu {c:#010x} ({:e}), inputs {q:?}",
                        NAMES[word],
                        f32::from_bits(g),
                        f32::from_bits(c)
                    )
                });
            }
        }
    }
    assert!(per_kernel.is_empty(), "{}: differing words per kernel {per_kernel:?}; first: {:#?}", ctx.info.name, first);
}
