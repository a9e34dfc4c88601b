//! The image-based light's kernels of `shaders/ambient_light.wgsl` one by one against the
//! core's (`hyrt_core::kernels::ibl`), bit for bit, on seeded random inputs, under the
//! default sky's tables and under a small procedural environment map's:
//! `irradiance_sh9`, `split_sum_lookup`, `specular_radiance`, `image_based_light` and
//! `image_based_diffuse`. The stage tests (`shading.rs`, the conformance corpus) check
//! whole frames; this one names the kernel that differs.

mod common;

use std::sync::Arc;

use common::test_context;
use hyrt_core::formats::FrameParams;
use hyrt_core::glam::Vec3;
use hyrt_core::kernels::ibl::{AmbientLight, ImageBasedLight};
use hyrt_core::scene::{Environment, EnvironmentMap};
use hyrt_gpu::exact::same_bits;
use hyrt_gpu::gpu_buffer::{read_back, storage, upload};
use hyrt_gpu::shader::{
    ambient_light_wgsl, bind_buffers, compute_pipeline, inexact_operations, lat_long_wgsl, shading_source,
    storage_entry, uniform_entry,
};
use wgpu::util::DeviceExt;

/// Input words per query and result words per query.
const IN: usize = 16;
const OUT: usize = 14;

const ENTRY: &str = r#"
@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<uniform> ambient_light: AmbientLightRecord;
@group(0) @binding(2) var<storage, read> ambient_texels: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> inputs: array<f32>;
@group(0) @binding(4) var<storage, read_write> results: array<u32>;

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
    let r = vec3<f32>(inputs[i + 11u], inputs[i + 12u], inputs[i + 13u]);
    let x = inputs[i + 14u];
    let y = inputs[i + 15u];
    let e = irradiance_sh9(n);
    results[o] = bitcast<u32>(e.x);
    results[o + 1u] = bitcast<u32>(e.y);
    results[o + 2u] = bitcast<u32>(e.z);
    let ab = split_sum_lookup(x, y);
    results[o + 3u] = bitcast<u32>(ab.x);
    results[o + 4u] = bitcast<u32>(ab.y);
    let s = specular_radiance(r, roughness);
    results[o + 5u] = bitcast<u32>(s.x);
    results[o + 6u] = bitcast<u32>(s.y);
    results[o + 7u] = bitcast<u32>(s.z);
    let l = image_based_light(base, metallic, roughness, n, v);
    results[o + 8u] = bitcast<u32>(l.x);
    results[o + 9u] = bitcast<u32>(l.y);
    results[o + 10u] = bitcast<u32>(l.z);
    let d = image_based_diffuse(base, metallic, n, x);
    results[o + 11u] = bitcast<u32>(d.x);
    results[o + 12u] = bitcast<u32>(d.y);
    results[o + 13u] = bitcast<u32>(d.z);
}
"#;

const NAMES: [&str; OUT] = [
    "irradiance_sh9.x",
    "irradiance_sh9.y",
    "irradiance_sh9.z",
    "split_sum_lookup.a",
    "split_sum_lookup.b",
    "specular_radiance.x",
    "specular_radiance.y",
    "specular_radiance.z",
    "image_based_light.x",
    "image_based_light.y",
    "image_based_light.z",
    "image_based_diffuse.x",
    "image_based_diffuse.y",
    "image_based_diffuse.z",
];

fn cpu_results(ibl: &ImageBasedLight, q: &[f32]) -> [u32; OUT] {
    let base = Vec3::new(q[0], q[1], q[2]);
    let (metallic, roughness) = (q[3], q[4]);
    let n = Vec3::new(q[5], q[6], q[7]);
    let v = Vec3::new(q[8], q[9], q[10]);
    let r = Vec3::new(q[11], q[12], q[13]);
    let (x, y) = (q[14], q[15]);
    let e = ibl.irradiance.irradiance(n);
    let [a, b] = ibl.split_sum.lookup(x, y);
    let s = ibl.specular_radiance(r, roughness);
    let l = ibl.radiance(base, metallic, roughness, n, v);
    let d = ibl.diffuse(base, metallic, n, x);
    [e.x, e.y, e.z, a, b, s.x, s.y, s.z, l.x, l.y, l.z, d.x, d.y, d.z].map(f32::to_bits)
}

/// Seeded queries: unit vectors for n and v (v mostly on n's side, sometimes n itself or
/// grazing), a direction r of any length (some along the poles and the seam at -Z, where
/// the lat-long lookup wraps and clamps), colours, metallic and roughness in [0, 1] (a
/// tenth of them 0 or 1), and split-sum coordinates in [-0.25, 1.25] (outside: clamped).
fn queries(count: usize) -> Vec<f32> {
    let mut s = 0x2545_f491_4f6c_dd1du64;
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
        match k % 8 {
            0 => {}
            1 => v = n,
            2 => v = (v - n * n.dot(v)).normalize_or_zero(),
            _ => v = if v.dot(n) < 0.0 { -v } else { v },
        }
        let r = match k % 16 {
            3 => Vec3::Y,
            5 => -Vec3::Y * 3.0,
            7 => Vec3::new(0.0, 0.2, -1.0),
            9 => Vec3::new(-1e-3, 0.5, -1.0),
            _ => unit(&mut next) * (0.25 + 4.0 * next()),
        };
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
        q.extend(r.to_array());
        q.extend([next() * 1.5 - 0.25, next() * 1.5 - 0.25]);
    }
    q
}

/// A 24 x 12 map with a bright sun, coloured bands and a dark ground: every level of the
/// prefiltered tables varies across its texels.
fn procedural_map() -> Environment {
    let (w, h) = (24u32, 12u32);
    let texels = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| {
            let sun = if (i, j) == (5, 3) { 40.0 } else { 0.0 };
            let band = 0.2 + 0.6 * (i as f32 / w as f32);
            if j < h / 2 {
                [band + sun, 0.5 + sun, 1.0 - band * 0.5 + sun, 1.0]
            } else {
                [0.1, 0.08 + 0.02 * (j as f32), 0.05, 1.0]
            }
        })
        .collect();
    Environment::Map(Arc::new(EnvironmentMap::new(w, h, texels).expect("a valid map")))
}

#[test]
fn ambient_light_kernels_match_cpu_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let count = 1 << 13;
    let inputs = queries(count);
    let source = shading_source(&format!(
        "{}\n{}\nconst IN: u32 = {IN}u;\nconst OUT: u32 = {OUT}u;\n{ENTRY}",
        lat_long_wgsl(),
        ambient_light_wgsl()
    ));
    // Only correctly rounded operations and the exact helpers (checked by shader_module in
    // debug builds only).
    assert_eq!(inexact_operations(&source), Ok(Vec::new()));
    let entries =
        [uniform_entry(0), uniform_entry(1), storage_entry(2, true), storage_entry(3, true), storage_entry(4, false)];
    let (pipeline, layout) = compute_pipeline(&ctx, "ambient light kernels test", &source, &entries);
    let params = ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("params"),
        contents: bytemuck::bytes_of(&FrameParams::new(1, 1, 0, 0.5)),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let input_buffer = upload(&ctx, "inputs", &inputs);
    let mut failures = Vec::new();
    for (name, env) in [("sky", Environment::Sky), ("map", procedural_map())] {
        let light =
            AmbientLight { scale: 1.0, image: Some(Arc::new(ImageBasedLight::of(&env))), ..AmbientLight::default() };
        let ibl = light.image.as_deref().expect("an image");
        let record = ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("ambient light"),
            contents: bytemuck::bytes_of(&light.record()),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let texels = upload(&ctx, "ambient light texels", &light.texels());
        let results = storage::<u32>(&ctx, "results", count * OUT).expect("results buffer");
        let group = bind_buffers(
            &ctx,
            "ambient light kernels test",
            &layout,
            &[&params, &record, &texels, &input_buffer, &results],
        );
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups((count as u32).div_ceil(64), 1, 1);
        }
        ctx.queue.submit([encoder.finish()]);
        let gpu = read_back::<u32>(&ctx, &results, count * OUT).expect("read back");
        // The tables are not trivial: every kernel gives some light.
        for (word, kernel) in NAMES.iter().enumerate() {
            let lit = (0..count).any(|k| f32::from_bits(gpu[k * OUT + word]) > 0.0);
            assert!(lit, "{kernel}: never positive under the {name}'s tables");
        }
        let mut per_kernel = std::collections::BTreeMap::<&str, usize>::new();
        let mut first = std::collections::BTreeMap::<&str, String>::new();
        for k in 0..count {
            let q = &inputs[k * IN..(k + 1) * IN];
            let want = cpu_results(ibl, q);
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
        if !per_kernel.is_empty() {
            failures.push(format!("{name}: differing words per kernel {per_kernel:?}; first: {first:#?}"));
        }
    }
    assert!(failures.is_empty(), "{}: {}", ctx.info.name, failures.join("\n"));
}
