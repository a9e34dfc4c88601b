//! The kernels of `shaders/soft_shadow.wgsl` one by one against the core's
//! (`hyrt_core::kernels::soft_shadow`: `surface_key`, `stream_seed`, `area_light_sample`,
//! `occlusion_direction`, `light_slots`), bit for bit, on seeded random surfaces and
//! lights of every kind (quad, sphere, sun, and a point light, which is no area light),
//! with the hard cases mixed in: signed zeros in a point's coordinates, points inside a
//! sphere light and behind a quad, large coordinates; and the emitter table's kernels
//! (`hyrt_core::kernels::area_light`: `pick_emitter`, `triangle_point`, `sample_emitters`,
//! and `area_light_sample` of a `LIGHT_EMITTERS` light) over tables packed into the lights'
//! binding as the stages read them (`hyrt_gpu::buffers::packed_lights`). (`needs_slot_ray`
//! and `slot_ray` are compared through the ray lists they make: `tests/soft_shadows.rs`,
//! `tests/emissive_lights.rs` and the conformance corpus' `stochastic_*` cases.)

mod common;

use common::test_context;
use hyrt_core::formats::{
    AmbientLightRecord, EmitterRecord, FrameParams, LightRecord, SurfaceRecord, EMITTER_DOUBLE_SIDED,
};
use hyrt_core::geometry::with_emitter_cdf;
use hyrt_core::glam::Vec3;
use hyrt_core::kernels::area_light::{pick_emitter, sample_emitters, triangle_point, LightSample, ONE_BELOW_ONE};
use hyrt_core::kernels::soft_shadow::{
    area_light_sample, frame_lights, frame_occlusion, light_slots, occlusion_direction, stream_seed, surface_key,
    Lights,
};
use hyrt_core::scene::Light;
use hyrt_gpu::buffers::{packed_lights, SlotParams};
use hyrt_gpu::exact::same_bits;
use hyrt_gpu::gpu_buffer::{read_back, storage, upload};
use hyrt_gpu::shader::{
    bind_buffers, compute_pipeline, inexact_operations, shading_source, soft_shadow_wgsl, storage_entry, uniform_entry,
};
use hyrt_gpu::GpuContext;
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

/// The bindings of both tests' entries ([`entries`]): the frame's params, ambient light and
/// lights (with the emitter table after the records), each query's inputs at 3 (the test's
/// own) and sample index at 4, the results, the slot params; and a result writer.
const BINDINGS: &str = r#"
@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<uniform> ambient_light: AmbientLightRecord;
@group(0) @binding(2) var<storage, read> lights: array<LightRecord>;
@group(0) @binding(4) var<storage, read> samples: array<u32>;
@group(0) @binding(5) var<storage, read_write> results: array<u32>;
@group(0) @binding(6) var<uniform> slot_params: SlotParams;

fn out_v3(o: u32, v: vec3<f32>) {
    results[o] = bitcast<u32>(v.x);
    results[o + 1u] = bitcast<u32>(v.y);
    results[o + 2u] = bitcast<u32>(v.z);
}
"#;

/// The layout of [`BINDINGS`] and a test's binding 3.
fn entries() -> [wgpu::BindGroupLayoutEntry; 7] {
    [
        uniform_entry(0),
        uniform_entry(1),
        storage_entry(2, true),
        storage_entry(3, true),
        storage_entry(4, true),
        storage_entry(5, false),
        uniform_entry(6),
    ]
}

const ENTRY: &str = r#"
@group(0) @binding(3) var<storage, read> surfaces: array<SurfaceRecord>;

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

/// A uniform buffer of `contents`.
fn uniform(ctx: &GpuContext, contents: &[u8]) -> wgpu::Buffer {
    ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("kernel test uniform"),
        contents,
        usage: wgpu::BufferUsages::UNIFORM,
    })
}

/// `source`'s `main` over `buffers` (bound at 0, 1, 2, ... as `entries` declare them),
/// `queries` invocations in workgroups of 64: the results buffer `buffers[results]` read
/// back whole.
fn dispatch(
    ctx: &GpuContext,
    source: &str,
    entries: &[wgpu::BindGroupLayoutEntry],
    buffers: &[&wgpu::Buffer],
    results: usize,
    queries: usize,
) -> Vec<u32> {
    let (pipeline, layout) = compute_pipeline(ctx, "soft shadow kernels test", source, entries);
    let group = bind_buffers(ctx, "soft shadow kernels test", &layout, buffers);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups((queries as u32).div_ceil(64), 1, 1);
    }
    ctx.queue.submit([encoder.finish()]);
    let words = buffers[results].size() as usize / 4;
    read_back::<u32>(ctx, buffers[results], words).expect("read back")
}

/// Per differing result word, how many queries differ and the first of them.
type Differing = std::collections::BTreeMap<&'static str, (usize, String)>;

/// Compare query `k`'s result words `gpu` with the core's `want`, word by word (NaNs alike),
/// into `differing` under the words' `names`; `what` describes the query.
fn compare_words(
    differing: &mut Differing,
    names: &[&'static str],
    k: usize,
    gpu: &[u32],
    want: &[u32],
    what: impl Fn() -> String,
) {
    for (word, (&g, &c)) in gpu.iter().zip(want).enumerate() {
        if !same_bits(g, c) {
            let e = differing
                .entry(names[word])
                .or_insert_with(|| (0, format!("query {k}: gpu {g:#010x} cpu {c:#010x}, {}", what())));
            e.0 += 1;
        }
    }
}

/// A light sample as the result words write it: `l`, `distance`, `weight`, whether `Some`
/// (zeros for `None`).
fn sample_words(ls: Option<LightSample>) -> [u32; 8] {
    let mut w = [0u32; 8];
    if let Some(ls) = ls {
        w[0..3].copy_from_slice(&words(ls.l));
        w[3] = ls.distance.to_bits();
        w[4..7].copy_from_slice(&words(ls.weight));
        w[7] = 1;
    }
    w
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
    let source = shading_source(&format!("const OUT: u32 = {OUT}u;\n{}\n{BINDINGS}\n{ENTRY}", soft_shadow_wgsl()));
    assert_eq!(inexact_operations(&source), Ok(Vec::new()));
    let buffers = [
        &uniform(&ctx, bytemuck::bytes_of(&FrameParams::new(1, 1, 1, 1.0))),
        &uniform(&ctx, bytemuck::bytes_of(&ambient)),
        &upload(&ctx, "lights", &lights),
        &upload(&ctx, "surfaces", &surfaces),
        &upload(&ctx, "samples", &samples),
        &storage::<u32>(&ctx, "results", count * OUT).expect("results buffer"),
        // No emitter table (the lights are one per query).
        &uniform(&ctx, bytemuck::bytes_of(&SlotParams::of(&lights, ao.samples))),
    ];
    let gpu = dispatch(&ctx, &source, &entries(), &buffers, 5, count);

    let (mut some_light, mut some_ao) = (0, 0);
    let mut differing = Differing::new();
    for k in 0..count {
        let (l, s, n) = (&lights[k], &surfaces[k], samples[k]);
        let p = Vec3::from(s.position);
        let key = surface_key(p);
        let mut want = [0u32; OUT];
        want[0] = key;
        want[1] = stream_seed(key, l.seed);
        let ls = area_light_sample(l, &[], p, n);
        some_light += ls.is_some() as usize;
        want[2..10].copy_from_slice(&sample_words(ls));
        if let Some(d) = occlusion_direction(s, &ao, n) {
            want[10..13].copy_from_slice(&words(d));
            want[13] = 1;
            some_ao += 1;
        }
        want[14] = light_slots(l) as u32;
        want[15] = l.is_area() as u32;
        want[16] = ao.samples;
        compare_words(&mut differing, &NAMES, k, &gpu[k * OUT..(k + 1) * OUT], &want, || {
            format!("light {l:?}, surface {s:?}, sample {n}")
        });
    }
    // Both outcomes of each Option are reached.
    assert!(some_light > count / 4 && some_light < count - count / 8, "area_light_sample: Some in {some_light}");
    assert!(some_ao > count / 4 && some_ao < count - count / 20, "occlusion_direction: Some in {some_ao}");
    assert!(differing.is_empty(), "{}: differing words per function: {differing:#?}", ctx.info.name);
}

/// Input words per query of the emitter kernels: `x`, the triangle `v0, e1, e2`, the
/// sequence point `u`, the point `p` (the sample index in `samples`).
const EMITTER_IN: usize = 15;

/// Result words per query of the emitter kernels.
const EMITTER_OUT: usize = 23;

/// What each result word of the emitter kernels is.
const EMITTER_NAMES: [&str; EMITTER_OUT] = [
    "pick_emitter.index",
    "pick_emitter.p",
    "pick_emitter.x",
    "triangle_point.x",
    "triangle_point.y",
    "triangle_point.z",
    "sample_emitters.l.x",
    "sample_emitters.l.y",
    "sample_emitters.l.z",
    "sample_emitters.distance",
    "sample_emitters.weight.x",
    "sample_emitters.weight.y",
    "sample_emitters.weight.z",
    "sample_emitters.is_some",
    "area_light_sample(emitters).l.x",
    "area_light_sample(emitters).l.y",
    "area_light_sample(emitters).l.z",
    "area_light_sample(emitters).distance",
    "area_light_sample(emitters).weight.x",
    "area_light_sample(emitters).weight.y",
    "area_light_sample(emitters).weight.z",
    "area_light_sample(emitters).is_some",
    "light_slots(emitters)",
];

/// The emitter kernels of query `i` (inputs `queries`, in the words of `EMITTER_IN`) over
/// the table packed into `lights` after its one record, a `LIGHT_EMITTERS` light.
const EMITTER_ENTRY: &str = r#"
@group(0) @binding(3) var<storage, read> queries: array<u32>;

fn in_f32(q: u32, w: u32) -> f32 {
    return bitcast<f32>(queries[q * EMITTER_IN + w]);
}

fn in_v3(q: u32, w: u32) -> vec3<f32> {
    return vec3<f32>(in_f32(q, w), in_f32(q, w + 1u), in_f32(q, w + 2u));
}

fn out_sample(o: u32, ls: LightSample) {
    out_v3(o, ls.l);
    results[o + 3u] = bitcast<u32>(ls.distance);
    out_v3(o + 4u, ls.weight);
    results[o + 7u] = select(0u, 1u, ls.valid);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= arrayLength(&samples) {
        return;
    }
    let o = i * EMITTER_OUT;
    let x = in_f32(i, 0u);
    let u = vec2<f32>(in_f32(i, 10u), in_f32(i, 11u));
    let p = in_v3(i, 12u);
    // The core's pick_emitter takes a table that is not empty.
    if emitter_count() > 0u {
        let pick = pick_emitter(x);
        results[o] = pick.index;
        results[o + 1u] = bitcast<u32>(pick.p);
        results[o + 2u] = bitcast<u32>(pick.x);
    }
    out_v3(o + 3u, triangle_point(in_v3(i, 1u), in_v3(i, 4u), in_v3(i, 7u), u));
    out_sample(o + 6u, sample_emitters(p, u));
    let light = lights[0];
    out_sample(o + 14u, area_light_sample(light, p, samples[i]));
    results[o + 22u] = light_slots(light);
}
"#;

/// An emitter table of `n` triangles through the renderer's own cdf (`with_emitter_cdf`):
/// near the origin, most of a size, some tiny, every seventh dark (left out), a third
/// double-sided; with `giant`, the first is so much larger that the tiny ones' bins round
/// to zero width (never picked).
fn emitter_table(rng: &mut Rng, n: usize, giant: bool) -> Vec<EmitterRecord> {
    let records = (0..n)
        .map(|k| {
            let size = match (k, giant) {
                (0, true) => 300.0,
                _ if k % 4 == 1 => 1e-3,
                _ => 1.0,
            };
            let glow = if k % 7 == 6 { 0.0 } else { rng.range(0.05, 8.0) };
            EmitterRecord {
                v0: rng.vec(3.0).into(),
                cdf: 0.0,
                e1: (rng.vec(1.0) * size).into(),
                flags: if k % 3 == 0 { EMITTER_DOUBLE_SIDED } else { 0 },
                e2: (rng.vec(1.0) * size).into(),
                object: k as u32 % 5,
                radiance: [glow, glow * rng.range(0.0, 1.0), glow * 0.25],
                triangle: k as u32,
            }
        })
        .collect();
    with_emitter_cdf(records)
}

/// The inputs of one query of the emitter kernels over `table`: sequence coordinates at the
/// bins' edges, 0 and just below 1 among random ones; points on a triangle's corner and
/// in the plane of one among random ones.
fn emitter_query(rng: &mut Rng, k: usize, table: &[EmitterRecord]) -> [u32; EMITTER_IN] {
    let cdf = |rng: &mut Rng| table.get(rng.u32() as usize % table.len().max(1)).map_or(0.5, |e| e.cdf);
    let mut x = match k % 6 {
        0 => cdf(rng),
        1 => ONE_BELOW_ONE,
        2 => 0.0,
        _ => rng.range(0.0, 1.0),
    };
    if x >= 1.0 {
        x = ONE_BELOW_ONE;
    }
    let u = match k % 5 {
        0 => [0.0, ONE_BELOW_ONE],
        1 => [ONE_BELOW_ONE, 0.0],
        _ => [rng.range(0.0, 1.0), rng.range(0.0, 1.0)],
    };
    let scale = if k.is_multiple_of(11) { 1e4 } else { 2.0 };
    let triangle = [rng.vec(scale), rng.vec(scale), rng.vec(scale)];
    let p = match (k % 9, table.first()) {
        (0, Some(e)) => Vec3::from(e.v0),
        (1, Some(e)) => Vec3::from(e.v0) + Vec3::from(e.e1) * 0.5 + Vec3::from(e.e2) * 0.25,
        _ => rng.vec(4.0),
    };
    let mut q = [0u32; EMITTER_IN];
    q[0] = x.to_bits();
    for (w, v) in triangle.iter().enumerate() {
        q[1 + 3 * w..4 + 3 * w].copy_from_slice(&words(*v));
    }
    q[10..12].copy_from_slice(&u.map(f32::to_bits));
    q[12..15].copy_from_slice(&words(p));
    q
}

/// `pick_emitter`, `triangle_point`, `sample_emitters` and `area_light_sample` of a
/// `LIGHT_EMITTERS` light (with `light_slots` of it): the WGSL twins against the core's,
/// bit for bit, on seeded queries over tables of one emitter, two, dozens, hundreds (a
/// deeper binary search), bins of zero width beside a giant triangle, and an empty table;
/// each table packed after the light record as the stages read it (`packed_lights`,
/// `SlotParams::emitters`).
#[test]
fn emitter_kernels_match_cpu_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let source = shading_source(&format!(
        "const EMITTER_IN: u32 = {EMITTER_IN}u;\nconst EMITTER_OUT: u32 = {EMITTER_OUT}u;\n{}\n{BINDINGS}\n{EMITTER_ENTRY}",
        soft_shadow_wgsl()
    ));
    assert_eq!(inexact_operations(&source), Ok(Vec::new()));
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    let ambient: AmbientLightRecord = bytemuck::Zeroable::zeroed();
    let count = 1 << 12;
    let (mut differing, mut some, mut picked, mut zero_width) = (Differing::new(), 0, 0, 0);
    for (n, giant) in [(1, false), (2, false), (37, false), (700, false), (40, true), (0, false)] {
        let table = emitter_table(&mut rng, n, giant);
        assert!(n == 0 || table.last().map(|e| e.cdf) == Some(1.0), "{n} emitters: the last cdf is 1");
        let light = frame_lights(&[LightRecord::emitters()], 4, rng.u32()).remove(0);
        let lights = packed_lights(&[light], &table);
        let queries: Vec<u32> = (0..count).flat_map(|k| emitter_query(&mut rng, k, &table)).collect();
        let samples: Vec<u32> = (0..count).map(|k| if k % 7 == 0 { rng.u32() } else { rng.u32() % 64 }).collect();
        let buffers = [
            &uniform(&ctx, bytemuck::bytes_of(&FrameParams::new(1, 1, 1, 1.0))),
            &uniform(&ctx, bytemuck::bytes_of(&ambient)),
            &upload(&ctx, "lights", &lights),
            &upload(&ctx, "queries", &queries),
            &upload(&ctx, "samples", &samples),
            &storage::<u32>(&ctx, "results", count * EMITTER_OUT).expect("results buffer"),
            &uniform(&ctx, bytemuck::bytes_of(&SlotParams::of(Lights::new(&[light], &table), 0))),
        ];
        let gpu = dispatch(&ctx, &source, &entries(), &buffers, 5, count);
        let mut hits = vec![0usize; table.len()];
        for k in 0..count {
            let q = &queries[k * EMITTER_IN..(k + 1) * EMITTER_IN];
            let f = |w: usize| f32::from_bits(q[w]);
            let v3 = |w: usize| Vec3::new(f(w), f(w + 1), f(w + 2));
            let (x, u, p) = (f(0), [f(10), f(11)], v3(12));
            let mut want = [0u32; EMITTER_OUT];
            if !table.is_empty() {
                let (i, pick, remapped) = pick_emitter(&table, x);
                want[0..3].copy_from_slice(&[i as u32, pick.to_bits(), remapped.to_bits()]);
                hits[i] += 1;
            }
            want[3..6].copy_from_slice(&words(triangle_point(v3(1), v3(4), v3(7), u)));
            let ls = sample_emitters(&table, p, u);
            some += ls.is_some() as usize;
            want[6..14].copy_from_slice(&sample_words(ls));
            want[14..22].copy_from_slice(&sample_words(area_light_sample(&light, &table, p, samples[k])));
            want[22] = light_slots(&light) as u32;
            compare_words(
                &mut differing,
                &EMITTER_NAMES,
                k,
                &gpu[k * EMITTER_OUT..(k + 1) * EMITTER_OUT],
                &want,
                || format!("{n} emitters (giant {giant}), x {x}, u {u:?}, p {p}, sample {}", samples[k]),
            );
        }
        picked += hits.iter().filter(|&&h| h > 0).count();
        let below = |i: usize| if i == 0 { 0.0 } else { table[i - 1].cdf };
        zero_width += (0..table.len()).filter(|&i| table[i].cdf == below(i)).count();
    }
    // Both outcomes of sample_emitters, many bins picked, zero-width bins present (and so
    // skipped: a pick of one would differ from the core's or read a zero probability).
    assert!(some > count && some < 5 * count, "sample_emitters: Some in {some} of {}", 6 * count);
    assert!(picked > 300, "{picked} emitters picked");
    assert!(zero_width > 0, "no bin of zero width");
    assert!(differing.is_empty(), "{}: differing words per function: {differing:#?}", ctx.info.name);
}
