//! The stochastic-ray kernels of `shaders/sampling.wgsl`, `shaders/area_light.wgsl` and
//! `shaders/occlusion.wgsl` one by one against the core's (`hyrt_core::kernels::sampling`,
//! `area_light`, `occlusion`), bit for bit, on seeded random inputs with the hard cases
//! mixed in: every mirrored function's every output word, named when it differs.

mod common;

use common::test_context;
use hyrt_core::formats::FrameParams;
use hyrt_core::glam::Vec3;
use hyrt_core::kernels::area_light::{
    sample_quad_light, sample_sphere_light, sample_sun, sphere_cone_one_minus_cos, sun_one_minus_cos, LightSample,
};
use hyrt_core::kernels::occlusion::{ao_direction, ao_fraction, AO_STREAM};
use hyrt_core::kernels::sampling::{
    concentric_disk, cosine_hemisphere, hash_combine, hash_u32, laine_karras_permutation, nested_uniform_scramble,
    orthonormal_basis, quad_point, sample_2d, sample_seed, sin_cos_quarter, sobol_2d, to_frame, uniform_cone, unit_f32,
};
use hyrt_gpu::exact::same_bits;
use hyrt_gpu::gpu_buffer::{read_back, storage, upload};
use hyrt_gpu::shader::{
    area_light_wgsl, bind_buffers, compute_pipeline, inexact_operations, occlusion_wgsl, sampling_wgsl, shading_source,
    storage_entry, uniform_entry,
};
use wgpu::util::DeviceExt;

/// Input words per query (the `Query` fields, in order) and result words per query.
const IN: usize = 48;
const OUT: usize = 63;

const ENTRY: &str = r#"
@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<storage, read> inputs: array<u32>;
@group(0) @binding(2) var<storage, read_write> results: array<u32>;

// The emitter table area_light.wgsl's emitter samplers read, empty: they are not called
// here (tests/soft_shadow_kernels.rs compares them over tables as the stages pack them).
fn emitter_count() -> u32 {
    return 0u;
}

fn emitter_at(i: u32) -> EmitterRecord {
    return EmitterRecord();
}

fn in_u(i: u32) -> u32 {
    return inputs[i];
}

fn in_f(i: u32) -> f32 {
    return bitcast<f32>(inputs[i]);
}

fn in_v2(i: u32) -> vec2<f32> {
    return vec2<f32>(in_f(i), in_f(i + 1u));
}

fn in_v3(i: u32) -> vec3<f32> {
    return vec3<f32>(in_f(i), in_f(i + 1u), in_f(i + 2u));
}

fn out_u(o: u32, x: u32) {
    results[o] = x;
}

fn out_f(o: u32, x: f32) {
    results[o] = bitcast<u32>(x);
}

fn out_v2(o: u32, v: vec2<f32>) {
    out_f(o, v.x);
    out_f(o + 1u, v.y);
}

fn out_v3(o: u32, v: vec3<f32>) {
    out_f(o, v.x);
    out_f(o + 1u, v.y);
    out_f(o + 2u, v.z);
}

// valid, l, distance, weight: 8 words (0 for an invalid sample's fields).
fn out_sample(o: u32, s: LightSample) {
    out_u(o, select(0u, 1u, s.valid));
    out_v3(o + 1u, s.l);
    out_f(o + 4u, s.distance);
    out_v3(o + 5u, s.weight);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let q = gid.x;
    if q >= arrayLength(&results) / OUT {
        return;
    }
    let i = q * IN;
    let o = q * OUT;
    let pixel = in_u(i);
    let stream = in_u(i + 1u);
    let frame = in_u(i + 2u);
    let index = in_u(i + 3u);
    let seed = in_u(i + 4u);
    let x = in_u(i + 5u);
    let unoccluded = in_u(i + 6u);
    let samples = in_u(i + 7u);
    let u = in_v2(i + 8u);
    let omc = in_f(i + 10u);
    let n = in_v3(i + 11u);
    let local = in_v3(i + 14u);
    let n_geo = in_v3(i + 17u);
    let corner = in_v3(i + 20u);
    let edge_u = in_v3(i + 23u);
    let edge_v = in_v3(i + 26u);
    let radiance = in_v3(i + 29u);
    let p = in_v3(i + 32u);
    let centre = in_v3(i + 35u);
    let radius = in_f(i + 38u);
    let direction = in_v3(i + 39u);
    let angle = in_f(i + 42u);
    let r2 = in_f(i + 43u);
    let d2 = in_f(i + 44u);

    out_u(o, hash_u32(x));
    out_u(o + 1u, hash_combine(seed, x));
    out_u(o + 2u, sample_seed(pixel, stream, frame));
    out_u(o + 3u, laine_karras_permutation(x, seed));
    out_u(o + 4u, nested_uniform_scramble(x, seed));
    let sobol = sobol_2d(index);
    out_u(o + 5u, sobol.x);
    out_u(o + 6u, sobol.y);
    out_f(o + 7u, unit_f32(x));
    out_v2(o + 8u, sample_2d(index, seed));
    out_v2(o + 10u, sin_cos_quarter(angle));
    out_v2(o + 12u, concentric_disk(u));
    out_v3(o + 14u, cosine_hemisphere(u));
    out_v3(o + 17u, uniform_cone(u, omc));
    let basis = orthonormal_basis(n);
    out_v3(o + 20u, basis.t);
    out_v3(o + 23u, basis.b);
    out_v3(o + 26u, to_frame(local, n));
    out_v3(o + 29u, quad_point(corner, edge_u, edge_v, u));
    out_sample(o + 32u, sample_quad_light(corner, edge_u, edge_v, radiance, p, u));
    out_f(o + 40u, sphere_cone_one_minus_cos(r2, d2));
    out_sample(o + 41u, sample_sphere_light(centre, radius, radiance, p, u));
    out_sample(o + 49u, sample_sun(direction, omc, radiance, u));
    let ao = ao_direction(n, n_geo, u);
    out_u(o + 57u, select(0u, 1u, ao.valid));
    // Rust's None has no direction: zeros, as for the light samples.
    out_v3(o + 58u, select(vec3<f32>(0.0), ao.d, ao.valid));
    out_f(o + 61u, ao_fraction(unoccluded, samples));
    out_u(o + 62u, AO_STREAM);
}
"#;

/// The function behind each result word.
const NAMES: [&str; OUT] = [
    "hash_u32",
    "hash_combine",
    "sample_seed",
    "laine_karras_permutation",
    "nested_uniform_scramble",
    "sobol_2d[0]",
    "sobol_2d[1]",
    "unit_f32",
    "sample_2d[0]",
    "sample_2d[1]",
    "sin_cos_quarter.sin",
    "sin_cos_quarter.cos",
    "concentric_disk[0]",
    "concentric_disk[1]",
    "cosine_hemisphere.x",
    "cosine_hemisphere.y",
    "cosine_hemisphere.z",
    "uniform_cone.x",
    "uniform_cone.y",
    "uniform_cone.z",
    "orthonormal_basis.t.x",
    "orthonormal_basis.t.y",
    "orthonormal_basis.t.z",
    "orthonormal_basis.b.x",
    "orthonormal_basis.b.y",
    "orthonormal_basis.b.z",
    "to_frame.x",
    "to_frame.y",
    "to_frame.z",
    "quad_point.x",
    "quad_point.y",
    "quad_point.z",
    "sample_quad_light.is_some",
    "sample_quad_light.l.x",
    "sample_quad_light.l.y",
    "sample_quad_light.l.z",
    "sample_quad_light.distance",
    "sample_quad_light.weight.x",
    "sample_quad_light.weight.y",
    "sample_quad_light.weight.z",
    "sphere_cone_one_minus_cos",
    "sample_sphere_light.is_some",
    "sample_sphere_light.l.x",
    "sample_sphere_light.l.y",
    "sample_sphere_light.l.z",
    "sample_sphere_light.distance",
    "sample_sphere_light.weight.x",
    "sample_sphere_light.weight.y",
    "sample_sphere_light.weight.z",
    "sample_sun.is_some",
    "sample_sun.l.x",
    "sample_sun.l.y",
    "sample_sun.l.z",
    "sample_sun.distance",
    "sample_sun.weight.x",
    "sample_sun.weight.y",
    "sample_sun.weight.z",
    "ao_direction.is_some",
    "ao_direction.x",
    "ao_direction.y",
    "ao_direction.z",
    "ao_fraction",
    "AO_STREAM",
];

/// One query's inputs (the entry point's order).
#[derive(Clone, Copy, Debug, Default)]
struct Query {
    pixel: u32,
    stream: u32,
    frame: u32,
    index: u32,
    seed: u32,
    x: u32,
    unoccluded: u32,
    samples: u32,
    u: [f32; 2],
    one_minus_cos: f32,
    n: Vec3,
    local: Vec3,
    n_geo: Vec3,
    corner: Vec3,
    edge_u: Vec3,
    edge_v: Vec3,
    radiance: Vec3,
    p: Vec3,
    centre: Vec3,
    radius: f32,
    direction: Vec3,
    angle: f32,
    r2: f32,
    d2: f32,
}

impl Query {
    fn words(&self) -> [u32; IN] {
        let mut w = [0u32; IN];
        let mut k = 0;
        let mut put = |x: u32| {
            w[k] = x;
            k += 1;
        };
        for x in [self.pixel, self.stream, self.frame, self.index, self.seed, self.x, self.unoccluded, self.samples] {
            put(x);
        }
        let mut fl = |xs: &[f32]| xs.iter().for_each(|x| put(x.to_bits()));
        fl(&self.u);
        fl(&[self.one_minus_cos]);
        for v in
            [self.n, self.local, self.n_geo, self.corner, self.edge_u, self.edge_v, self.radiance, self.p, self.centre]
        {
            fl(&v.to_array());
        }
        fl(&[self.radius]);
        fl(&self.direction.to_array());
        fl(&[self.angle, self.r2, self.d2]);
        w
    }
}

fn light_sample_words(s: Option<LightSample>) -> [u32; 8] {
    match s {
        None => [0; 8],
        Some(s) => {
            let f = [s.l.x, s.l.y, s.l.z, s.distance, s.weight.x, s.weight.y, s.weight.z].map(f32::to_bits);
            [1, f[0], f[1], f[2], f[3], f[4], f[5], f[6]]
        }
    }
}

fn cpu_results(q: &Query) -> [u32; OUT] {
    let mut r = Vec::with_capacity(OUT);
    let v3 = |r: &mut Vec<u32>, v: Vec3| r.extend(v.to_array().map(f32::to_bits));
    r.push(hash_u32(q.x));
    r.push(hash_combine(q.seed, q.x));
    r.push(sample_seed(q.pixel, q.stream, q.frame));
    r.push(laine_karras_permutation(q.x, q.seed));
    r.push(nested_uniform_scramble(q.x, q.seed));
    r.extend(sobol_2d(q.index));
    r.push(unit_f32(q.x).to_bits());
    r.extend(sample_2d(q.index, q.seed).map(f32::to_bits));
    let (s, c) = sin_cos_quarter(q.angle);
    r.extend([s.to_bits(), c.to_bits()]);
    r.extend(concentric_disk(q.u).map(f32::to_bits));
    v3(&mut r, cosine_hemisphere(q.u));
    v3(&mut r, uniform_cone(q.u, q.one_minus_cos));
    let (t, b) = orthonormal_basis(q.n);
    v3(&mut r, t);
    v3(&mut r, b);
    v3(&mut r, to_frame(q.local, q.n));
    v3(&mut r, quad_point(q.corner, q.edge_u, q.edge_v, q.u));
    r.extend(light_sample_words(sample_quad_light(q.corner, q.edge_u, q.edge_v, q.radiance, q.p, q.u)));
    r.push(sphere_cone_one_minus_cos(q.r2, q.d2).to_bits());
    r.extend(light_sample_words(sample_sphere_light(q.centre, q.radius, q.radiance, q.p, q.u)));
    r.extend(light_sample_words(Some(sample_sun(q.direction, q.one_minus_cos, q.radiance, q.u))));
    match ao_direction(q.n, q.n_geo, q.u) {
        None => r.extend([0; 4]),
        Some(d) => {
            r.push(1);
            v3(&mut r, d);
        }
    }
    r.push(ao_fraction(q.unoccluded, q.samples).to_bits());
    r.push(AO_STREAM);
    r.try_into().expect("OUT words")
}

/// A seeded xorshift64 stream.
struct Rng(u64);

impl Rng {
    fn u32(&mut self) -> u32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 32) as u32
    }

    /// Uniform in [0, 1), on the 2^-24 grid the sequence's points lie on.
    fn unit(&mut self) -> f32 {
        unit_f32(self.u32())
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
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

    /// Log-uniform in [2^-lo, 2^hi).
    fn log(&mut self, lo: i32, hi: i32) -> f32 {
        (2.0f32).powf(self.range(-(lo as f32), hi as f32))
    }
}

/// 1 - 2^-24: the largest point of the sequence below 1.
const ALMOST_ONE: f32 = 1.0 - 1.0 / 16_777_216.0;

/// Seeded queries with the hard cases mixed in by index: sequence points and plain
/// uniforms for `u`, with u = 0, 1 - 2^-24, the disk's centre (1/2, 1/2), its axes
/// (a or b zero) and diagonals (|a| == |b|); unit normals with z = 0, -0.0, +-1 and near
/// -1; cones from empty to wider than the hemisphere (one_minus_cos 0, 1e-30, the real
/// sun's, up to 2 and beyond); quads facing either way, points in their plane and on their
/// corner; sphere lights seen from outside, from their surface, from inside and from
/// afar; sample counts up to 2^32 - 1 (above 2^24 the conversion rounds).
fn queries(count: usize) -> Vec<Query> {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let sun = sun_one_minus_cos(0.53f64.to_radians());
    let hard_u32 = [0u32, 1, u32::MAX, 0x8000_0000, 0x0000_0100, 0xffff_ff00];
    (0..count)
        .map(|k| {
            let mut q = Query {
                pixel: rng.u32(),
                stream: if k % 5 == 0 { AO_STREAM } else { rng.u32() % 8 },
                frame: rng.u32() % 64,
                index: if k % 3 == 0 { rng.u32() } else { rng.u32() % 4096 },
                seed: rng.u32(),
                x: rng.u32(),
                ..Default::default()
            };
            if k % 11 == 0 {
                q.x = hard_u32[(k / 11) % hard_u32.len()];
                q.index = hard_u32[(k / 7) % hard_u32.len()];
                q.seed = hard_u32[(k / 13) % hard_u32.len()];
            }
            // The sample counts: small, 0, and above 2^24 (rounded conversions).
            q.samples = match k % 7 {
                0 => 0,
                1 => u32::MAX,
                2 => (1 << 24) + 1 + rng.u32() % (1 << 30),
                _ => 1 + rng.u32() % 256,
            };
            q.unoccluded = match k % 13 {
                0 => q.samples,
                1 => 0,
                _ => rng.u32() % q.samples.max(1),
            };
            // The sequence point.
            let t = rng.unit();
            q.u = match k % 16 {
                0 => [0.0, 0.0],
                1 => [ALMOST_ONE, ALMOST_ONE],
                2 => [0.5, 0.5],
                3 => [t, t],
                4 => [t, 1.0 - t],
                5 => [0.5, t],
                6 => [t, 0.5],
                7 => [0.0, ALMOST_ONE],
                8 => [ALMOST_ONE, t],
                9 | 10 => [rng.unit(), rng.unit()],
                _ => sample_2d(rng.u32() % 4096, sample_seed(q.pixel, q.stream, q.frame)),
            };
            q.one_minus_cos = match k % 12 {
                0 => 0.0,
                1 => 1e-30,
                2 => sun,
                3 => 2.0,
                4 => 1.0,
                5 => 3.0,
                6 => 1e30,
                7 => f32::MIN_POSITIVE / 8.0,
                _ => rng.log(40, 1),
            };
            // The normals.
            let normal = |j: usize, rng: &mut Rng| match j % 14 {
                0 => Vec3::Z,
                1 => -Vec3::Z,
                2 => Vec3::X,
                3 => Vec3::new(0.6, 0.8, 0.0),
                4 => Vec3::new(0.6, -0.8, -0.0),
                5 => Vec3::new(0.0, 1.0, -0.0),
                6 => Vec3::new(3.4526698e-4, 0.0, -ALMOST_ONE),
                7 => {
                    let v = rng.unit_vec();
                    let v = Vec3::new(v.x, v.y, -0.0);
                    // z stays -0.0 through the normalization.
                    if v.length_squared() > 1e-4 {
                        v.normalize()
                    } else {
                        Vec3::new(0.0, -1.0, -0.0)
                    }
                }
                8 => Vec3::new(rng.range(-1e-3, 1e-3), rng.range(-1e-3, 1e-3), -1.0).normalize(),
                _ => rng.unit_vec(),
            };
            q.n = normal(k, &mut rng);
            q.local = match k % 3 {
                0 => cosine_hemisphere(q.u),
                1 => rng.vec(2.0),
                _ => uniform_cone(q.u, q.one_minus_cos),
            };
            q.n_geo = match k % 4 {
                0 => q.n,
                1 => (q.n + rng.vec(0.8)).normalize_or_zero(),
                _ => normal(k / 3, &mut rng),
            };
            // The quad and the shading point.
            q.corner = rng.vec(3.0);
            q.edge_u = rng.vec(2.0);
            q.edge_v = rng.vec(2.0);
            q.radiance = Vec3::new(rng.range(0.0, 20.0), rng.range(0.0, 5.0), rng.range(0.0, 1.0));
            q.p = match k % 10 {
                // In the quad's plane, on a corner, on the sampled point itself.
                0 => q.corner + q.edge_u * rng.unit() + q.edge_v * rng.unit(),
                1 => q.corner,
                2 => quad_point(q.corner, q.edge_u, q.edge_v, q.u),
                _ => rng.vec(4.0),
            };
            // The sphere: seen from outside, from its surface, from inside, from afar.
            q.radius = rng.log(6, 1);
            q.centre = match k % 9 {
                0 => q.p,
                1 => q.p + rng.unit_vec() * q.radius,
                2 => q.p + rng.unit_vec() * (q.radius * rng.range(0.0, 1.0)),
                3 => q.p + rng.unit_vec() * (q.radius * 1.000_001),
                4 => q.p + rng.unit_vec() * rng.log(0, 14),
                _ => q.p + rng.unit_vec() * (q.radius * rng.range(1.0, 40.0)),
            };
            q.direction = normal(k / 5, &mut rng);
            let quarter = std::f32::consts::FRAC_PI_4;
            q.angle = match k % 8 {
                0 => 0.0,
                1 => -0.0,
                2 => quarter,
                3 => -quarter,
                4 => rng.log(40, 0) * quarter,
                _ => rng.range(-quarter, quarter),
            };
            let r2 = rng.log(30, 4);
            (q.r2, q.d2) = match k % 8 {
                0 => (r2, r2),
                1 => (r2, r2 * 1.000_001),
                2 => (r2 * 1e-12, r2),
                3 => (0.0, r2),
                _ => (r2, r2 * rng.range(1.0, 1000.0)),
            };
            q
        })
        .collect()
}

#[test]
fn sampling_kernels_match_cpu_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let count = 1 << 13;
    let qs = queries(count);
    let inputs: Vec<u32> = qs.iter().flat_map(|q| q.words()).collect();
    let source = shading_source(&format!(
        "const IN: u32 = {IN}u;\nconst OUT: u32 = {OUT}u;\n{}\n{}\n{}\n{ENTRY}",
        sampling_wgsl(),
        area_light_wgsl(),
        occlusion_wgsl()
    ));
    // Only correctly rounded operations and the exact helpers (checked by shader_module in
    // debug builds only).
    assert_eq!(inexact_operations(&source), Ok(Vec::new()));
    let entries = [uniform_entry(0), storage_entry(1, true), storage_entry(2, false)];
    let (pipeline, layout) = compute_pipeline(&ctx, "sampling kernels test", &source, &entries);
    let params = ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("params"),
        contents: bytemuck::bytes_of(&FrameParams::new(1, 1, 0, 0.5)),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let input_buffer = upload(&ctx, "inputs", &inputs);
    let results = storage::<u32>(&ctx, "results", count * OUT).expect("results buffer");
    let group = bind_buffers(&ctx, "sampling kernels test", &layout, &[&params, &input_buffer, &results]);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups((count as u32).div_ceil(64), 1, 1);
    }
    ctx.queue.submit([encoder.finish()]);
    let gpu = read_back::<u32>(&ctx, &results, count * OUT).expect("read back");

    let want: Vec<[u32; OUT]> = qs.iter().map(cpu_results).collect();
    // The inputs reach both outcomes of every Option.
    for (word, name) in [(32, "sample_quad_light"), (41, "sample_sphere_light"), (57, "ao_direction")] {
        let some = want.iter().filter(|w| w[word] == 1).count();
        assert!(some > count / 20 && some < count - count / 20, "{name}: Some in {some} of {count}");
    }
    let mut per_function = std::collections::BTreeMap::<&str, usize>::new();
    let mut first = std::collections::BTreeMap::<&str, String>::new();
    for (k, (q, want)) in qs.iter().zip(&want).enumerate() {
        for (word, (&g, &c)) in gpu[k * OUT..(k + 1) * OUT].iter().zip(want).enumerate() {
            if !same_bits(g, c) {
                *per_function.entry(NAMES[word]).or_default() += 1;
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
    assert!(
        per_function.is_empty(),
        "{}: differing words per function {per_function:?}; first: {first:#?}",
        ctx.info.name
    );
}
