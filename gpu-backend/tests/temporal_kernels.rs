//! The kernels of `shaders/temporal.wgsl` one by one against the core's
//! (`hyrt_core::kernels::temporal`: `apply_motion`, `move_normal`, `previous_window`,
//! `bilinear_taps`, `accepts`, `plausible`, `temporal_blend`, `neighbourhood_mean`,
//! `temporal_pixel`, and `hyrt_core::kernels::denoise::raw_range`), bit for bit, at every
//! pixel of a seeded frame and its history: planes seen by a camera that moved since the
//! previous frame (of another size), one object moving (a motion record), one without a
//! record (past `motion_count`), misses, normals and points near and off their planes,
//! raw and history values with the hard cases mixed in (no estimate, exact 0 and 1), and
//! random arguments for the scalar kernels (window points on and off the image, exact 0
//! and 1 histories). (The whole pass against the CPU's: `tests/soft_shadows.rs`.)

mod common;

use common::test_context;
use hyrt_core::formats::{
    AmbientLightRecord, CameraRecord, FrameParams, LightRecord, MotionRecord, SurfaceRecord, SHADOW_LIT,
};
use hyrt_core::glam::{Mat4, Quat, Vec3};
use hyrt_core::kernels::camera::primary_ray;
use hyrt_core::kernels::denoise::{channel_count, channel_samples, pixel_angle, pixel_footprint, raw_range};
use hyrt_core::kernels::instance::world_to_object;
use hyrt_core::kernels::soft_shadow::{frame_lights, frame_occlusion, surface_slots, NO_ESTIMATE};
use hyrt_core::kernels::temporal::{
    accepts, apply_motion, bilinear_taps, motion_record, move_normal, neighbourhood_mean, plausible, previous_window,
    temporal_blend, temporal_pixel, History,
};
use hyrt_core::scene::{Camera, Light};
use hyrt_gpu::buffers::SlotParams;
use hyrt_gpu::exact::same_bits;
use hyrt_gpu::gpu_buffer::{read_back, storage, upload};
use hyrt_gpu::shader::{
    bind_buffers, compute_pipeline, inexact_operations, shading_source, soft_shadow_wgsl, storage_entry, uniform_entry,
};
use hyrt_gpu::shadow_denoise::{denoise_wgsl, temporal_wgsl, TemporalParams};
use wgpu::util::DeviceExt;

const WIDTH: usize = 40;
const HEIGHT: usize = 27;
const PREV_WIDTH: usize = 44;
const PREV_HEIGHT: usize = 30;

/// Words per pixel before its channels (see `ENTRY`).
const HEAD: usize = 23;
/// Per-channel results per pixel: this frame's mean and count, the history's mean and
/// count, the raw range's low and high, temporal_pixel's value.
const PER_CHANNEL: usize = 7;
/// Input words per pixel: a window point (2), a tolerance, plausible's history, mean and
/// count, temporal_blend's current, history, low, high and length.
const INPUTS: usize = 11;

const ENTRY: &str = r#"
@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<uniform> ambient_light: AmbientLightRecord;
@group(0) @binding(2) var<uniform> slot_params: SlotParams;
@group(0) @binding(3) var<uniform> prev_camera: CameraRecord;
@group(0) @binding(4) var<uniform> temporal: TemporalParams;
@group(0) @binding(5) var<storage, read> lights: array<LightRecord>;
@group(0) @binding(6) var<storage, read> surfaces: array<SurfaceRecord>;
@group(0) @binding(7) var<storage, read> shadow: array<u32>;
@group(0) @binding(8) var<storage, read> raw: array<f32>;
@group(0) @binding(9) var<storage, read> values_in: array<f32>;
@group(0) @binding(10) var<storage, read> motion: array<MotionRecord>;
@group(0) @binding(11) var<storage, read> prev_surfaces: array<SurfaceRecord>;
@group(0) @binding(12) var<storage, read> prev_values: array<f32>;
@group(0) @binding(13) var<storage, read> prev_lengths: array<u32>;
@group(0) @binding(14) var<storage, read> inputs: array<u32>;
@group(0) @binding(15) var<storage, read_write> results: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    let width = params.width;
    let height = params.height;
    if i >= width * height {
        return;
    }
    let channels = slot_params.channels;
    let x = i % width;
    let y = i / width;
    let per = HEAD + PER_CHANNEL * channels + 1u;
    let o = i * per;
    let ins = i * INPUTS;
    let s = surfaces[i];
    let m = object_motion(s.object);
    let p = apply_motion(m, s.position);
    let n = move_normal(m, s.normal);
    for (var k = 0u; k < 3u; k++) {
        results[o + k] = bitcast<u32>(p[k]);
        results[o + 3u + k] = bitcast<u32>(n[k]);
    }
    let window = previous_window(p);
    results[o + 6u] = window.found;
    results[o + 7u] = bitcast<u32>(window.at.x);
    results[o + 8u] = bitcast<u32>(window.at.y);
    let point = vec2<f32>(bitcast<f32>(inputs[ins]), bitcast<f32>(inputs[ins + 1u]));
    let taps = bilinear_taps(point, prev_camera.width, prev_camera.height);
    let real = bilinear_taps(window.at, prev_camera.width, prev_camera.height);
    let tolerance = bitcast<f32>(inputs[ins + 2u]);
    for (var t = 0u; t < 4u; t++) {
        results[o + 9u + t] = select(0xffffffffu, taps.index[t], taps.valid[t]);
        results[o + 13u + t] = bitcast<u32>(taps.weight[t]);
        let k = select(0u, real.index[t], real.valid[t]);
        results[o + 17u + t] = select(0u, 1u, accepts(s, p, n, prev_surfaces[k], tolerance));
    }
    let h = bitcast<f32>(inputs[ins + 3u]);
    let mean = bitcast<f32>(inputs[ins + 4u]);
    results[o + 21u] = select(0u, 1u, plausible(h, mean, inputs[ins + 5u]));
    let blend = temporal_blend(bitcast<f32>(inputs[ins + 6u]), bitcast<f32>(inputs[ins + 7u]),
        bitcast<f32>(inputs[ins + 8u]), bitcast<f32>(inputs[ins + 9u]), inputs[ins + 10u]);
    results[o + 22u] = bitcast<u32>(blend);
    let now = neighbourhood_mean(false, width, height, x, y);
    let pw = prev_camera.width;
    let ph = prev_camera.height;
    let then = neighbourhood_mean(true, pw, ph, x * pw / width, y * ph / height);
    let range = raw_range(width, height, x, y);
    let footprint = pixel_footprint(s.position, EYE, PIXEL_ANGLE);
    let r = temporal_pixel(width, height, x, y, footprint, channel_samples());
    for (var c = 0u; c < channels; c++) {
        let b = o + HEAD + PER_CHANNEL * c;
        results[b] = bitcast<u32>(now.mean[c]);
        results[b + 1u] = now.count[c];
        results[b + 2u] = bitcast<u32>(then.mean[c]);
        results[b + 3u] = then.count[c];
        results[b + 4u] = bitcast<u32>(range.lo[c]);
        results[b + 5u] = bitcast<u32>(range.hi[c]);
        results[b + 6u] = bitcast<u32>(r.values[c]);
    }
    results[o + HEAD + PER_CHANNEL * channels] = r.length;
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

    fn unit(&mut self) -> f32 {
        (self.u32() >> 8) as f32 / (1u32 << 24) as f32
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
}

/// The planes of the test's objects: object 0 the floor, 1 a slab 0.3 above it (which
/// moves along itself), 2 a tilted plane; a pixel's object by its column, some misses.
fn plane(object: u32) -> (Vec3, f32) {
    match object {
        0 => (Vec3::Y, 0.0),
        1 => (Vec3::Y, 0.3),
        _ => (Vec3::new(0.3, 0.9, -0.3).normalize(), 0.1),
    }
}

/// The surfaces `camera` sees: at each pixel the plane of the object of its column
/// (`band` columns each), jittered; a miss on a pattern or where the ray misses.
fn surfaces_of(camera: &CameraRecord, band: usize, rng: &mut Rng, jitter: bool) -> Vec<SurfaceRecord> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    (0..w * h)
        .map(|i| {
            let object = ((i % w) / band) as u32;
            if (i * 7 + i / w) % 29 == 0 || object > 2 {
                return SurfaceRecord::MISS;
            }
            let ray = primary_ray(camera, (i % w) as u32, (i / w) as u32);
            let (o, d) = (Vec3::from(ray.origin), Vec3::from(ray.direction));
            let (n, c) = plane(object);
            let t = (c - o.dot(n)) / d.dot(n);
            if t.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                return SurfaceRecord::MISS;
            }
            let mut p = o + d * t;
            let mut normal = n;
            if jitter {
                // Most near the plane, some well off it or turned.
                p += n * [0.0, 1e-4, 0.05][rng.u32() as usize % 3] * rng.range(-1.0, 1.0);
                let j = Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                normal = (n + j * [0.0, 0.02, 0.6][rng.u32() as usize % 3]).normalize();
            }
            SurfaceRecord {
                position: p.into(),
                normal: normal.into(),
                geometric_normal: n.into(),
                object,
                triangle: 0,
                position_error: 1e-6,
            }
        })
        .collect()
}

/// A visible share around world point `p`: smooth, with plateaus of exactly 0 and 1.
fn field(p: Vec3, c: usize) -> f32 {
    let v = 0.5 + 0.8 * (p.x * 2.0 + c as f32).sin() * (p.z * 1.5).cos();
    v.clamp(0.0, 1.0)
}

/// Per pixel and channel: `field` at its surface, quantized to `samples` with noise (or
/// exact), a few without an estimate; misses 0 (the raw channels' rule).
fn values_of(surfaces: &[SurfaceRecord], channels: usize, samples: &[u32], rng: &mut Rng) -> Vec<f32> {
    (0..surfaces.len() * channels)
        .map(|k| {
            let (i, c) = (k / channels, k % channels);
            let s = &surfaces[i];
            if !s.is_hit() {
                return 0.0;
            }
            if rng.u32().is_multiple_of(23) {
                return NO_ESTIMATE;
            }
            let v = field(Vec3::from(s.position), c);
            match rng.u32() % 4 {
                0 => v,
                _ => {
                    let n = samples[c] as f32;
                    ((v * n + rng.range(-1.0, 1.0)).round() / n).clamp(0.0, 1.0)
                }
            }
        })
        .collect()
}

#[test]
fn temporal_kernels_match_cpu_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let (w, h) = (WIDTH, HEIGHT);
    let (pw, ph) = (PREV_WIDTH, PREV_HEIGHT);
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let quad = Light::Quad {
        corner: Vec3::new(-0.5, 2.0, -0.5),
        edge_u: Vec3::X,
        edge_v: Vec3::Z,
        color: Vec3::ONE,
        intensity: 3.0,
    };
    let sphere = Light::Sphere { position: Vec3::new(1.0, 1.5, 0.5), radius: 0.3, color: Vec3::ONE, intensity: 5.0 };
    let point = Light::point(Vec3::new(0.0, 3.0, 1.0), Vec3::ONE, 4.0);
    let lights = frame_lights(&[quad, point, sphere].map(|l| LightRecord::from_light(&l)), 3, 5);
    let ao = frame_occlusion(2, 0.5, 5);
    let channels = channel_count(&lights, &ao);
    let slots = surface_slots(&lights, &ao);
    assert_eq!(channels, 3);
    let samples = channel_samples(&lights, &ao);

    // The camera now and a frame ago (moved, another image size).
    let eye = Vec3::new(0.3, 2.5, 3.0);
    let camera = CameraRecord::new(&Camera::look_at(eye, Vec3::new(0.0, 0.2, 0.0), Vec3::Y), w as u32, h as u32);
    let prev_eye = eye + Vec3::new(-0.05, 0.02, 0.03);
    let prev_camera =
        CameraRecord::new(&Camera::look_at(prev_eye, Vec3::new(-0.04, 0.2, 0.01), Vec3::Y), pw as u32, ph as u32);
    let angle = pixel_angle(&camera);
    // Object 1 moved along its plane and turned about y; object 2 has no record.
    let before = Mat4::from_rotation_translation(Quat::from_rotation_y(0.1), Vec3::new(0.03, 0.0, -0.02));
    let after = Mat4::from_rotation_translation(Quat::from_rotation_y(0.13), Vec3::new(0.0, 0.0, 0.0));
    let moving = motion_record(&world_to_object(before).unwrap(), &world_to_object(after).unwrap());
    assert_ne!(moving, MotionRecord::NONE);
    let motion = vec![MotionRecord::NONE, moving];

    let surfaces = surfaces_of(&camera, 14, &mut rng, true);
    let prev_surfaces = surfaces_of(&prev_camera, 15, &mut rng, false);
    let raw = values_of(&surfaces, channels, &samples, &mut rng);
    let prev_values = values_of(&prev_surfaces, channels, &[64; 3], &mut rng);
    let prev_lengths: Vec<u32> = (0..pw * ph).map(|_| rng.u32() % 8).collect();
    let inputs: Vec<u32> = (0..w * h)
        .flat_map(|_| {
            let special = [0.0f32, 1.0, 0.5, NO_ESTIMATE];
            let pick = |rng: &mut Rng| match rng.u32() % 3 {
                0 => special[rng.u32() as usize % 4],
                _ => rng.unit(),
            };
            let wx = rng.range(-1.5, pw as f32 + 1.5);
            let wy = if rng.u32().is_multiple_of(5) {
                (rng.u32() % ph as u32) as f32 + 0.5
            } else {
                rng.range(-1.5, ph as f32 + 1.5)
            };
            let tol = rng.range(0.0, 0.05);
            let hist = [0.0, 1.0, rng.unit()][rng.u32() as usize % 3];
            let mean = [hist, rng.unit(), 1.0 - hist][rng.u32() as usize % 3];
            let n = 1 + rng.u32() % 200;
            let (cur, hh) = (pick(&mut rng), pick(&mut rng));
            let (lo, hi) = match rng.u32() % 4 {
                0 => (f32::INFINITY, f32::NEG_INFINITY),
                _ => {
                    let (a, b) = (rng.unit(), rng.unit());
                    (a.min(b), a.max(b))
                }
            };
            let len = rng.u32() % 8;
            [wx, wy, tol, hist, mean]
                .map(f32::to_bits)
                .into_iter()
                .chain([n])
                .chain([cur, hh, lo, hi].map(f32::to_bits).into_iter().chain([len]))
        })
        .collect();
    assert_eq!(inputs.len(), w * h * INPUTS);

    let f = |x: f32| format!("{:?}", x as f64);
    let consts = format!(
        "const HEAD: u32 = {HEAD}u;\nconst PER_CHANNEL: u32 = {PER_CHANNEL}u;\nconst INPUTS: u32 = {INPUTS}u;\nconst EYE: vec3<f32> = vec3<f32>({}, {}, {});\nconst PIXEL_ANGLE: f32 = {};\n",
        f(eye.x),
        f(eye.y),
        f(eye.z),
        f(angle)
    );
    let source =
        shading_source(&format!("{consts}{}\n{}\n{}\n{ENTRY}", soft_shadow_wgsl(), denoise_wgsl(), temporal_wgsl()));
    assert_eq!(inexact_operations(&source), Ok(Vec::new()));
    let mut entries = vec![uniform_entry(0), uniform_entry(1), uniform_entry(2), uniform_entry(3), uniform_entry(4)];
    entries.extend((5..15).map(|b| storage_entry(b, true)));
    entries.push(storage_entry(15, false));
    let (pipeline, layout) = compute_pipeline(&ctx, "temporal kernels test", &source, &entries);
    let uniform = |label: &str, contents: &[u8]| {
        ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage: wgpu::BufferUsages::UNIFORM,
        })
    };
    let ambient = AmbientLightRecord {
        scale: 1.0,
        image: 0,
        ao_samples: ao.samples,
        ao_seed: ao.seed,
        ao_radius: ao.radius,
        ..bytemuck::Zeroable::zeroed()
    };
    let per = HEAD + PER_CHANNEL * channels + 1;
    let count = w * h * per;
    let params = FrameParams::new(w as u32, h as u32, lights.len() as u32, 1.0);
    let slot_params = SlotParams::of(&lights, ao.samples);
    assert_eq!(slot_params.channels as usize, channels);
    // Two records: object 2 has none (MOTION_NONE past the count).
    let temporal = TemporalParams::new(true, motion.len() as u32, &samples);
    let codes = vec![SHADOW_LIT as u32; w * h * slots];
    let buffers = [
        &uniform("params", bytemuck::bytes_of(&params)),
        &uniform("ambient light", bytemuck::bytes_of(&ambient)),
        &uniform("slot params", bytemuck::bytes_of(&slot_params)),
        &uniform("previous camera", bytemuck::bytes_of(&prev_camera)),
        &uniform("temporal", bytemuck::bytes_of(&temporal)),
        &upload(&ctx, "lights", &lights),
        &upload(&ctx, "surfaces", &surfaces),
        &upload(&ctx, "shadow", &codes),
        &upload(&ctx, "raw", &raw),
        &upload(&ctx, "values", &raw),
        &upload(&ctx, "motion", &motion),
        &upload(&ctx, "previous surfaces", &prev_surfaces),
        &upload(&ctx, "previous values", &prev_values),
        &upload(&ctx, "previous lengths", &prev_lengths),
        &upload(&ctx, "inputs", &inputs),
        &storage::<u32>(&ctx, "results", count).expect("results buffer"),
    ];
    let group = bind_buffers(&ctx, "temporal kernels test", &layout, &buffers);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(((w * h) as u32).div_ceil(64), 1, 1);
    }
    ctx.queue.submit([encoder.finish()]);
    let gpu = read_back::<u32>(&ctx, buffers[15], count).expect("read back");

    let mut differing = std::collections::BTreeMap::<&str, (usize, String)>::new();
    let mut check = |name: &'static str, at: String, g: u32, c: u32| {
        if !same_bits(g, c) {
            let e = differing.entry(name).or_insert_with(|| (0, format!("{at}: gpu {g:#010x} cpu {c:#010x}")));
            e.0 += 1;
        }
    };
    let history =
        History { camera: &prev_camera, surfaces: &prev_surfaces, visibility: &prev_values, length: &prev_lengths };
    let mut seen = std::collections::BTreeMap::<&str, u32>::new();
    let mut count_if = |name: &'static str, yes: bool| *seen.entry(name).or_default() += yes as u32;
    for i in 0..w * h {
        let (x, y) = (i % w, i / w);
        let o = i * per;
        let ins = &inputs[i * INPUTS..(i + 1) * INPUTS];
        let at = || format!("pixel ({x}, {y})");
        let s = &surfaces[i];
        let m = motion.get(s.object as usize).unwrap_or(&MotionRecord::NONE);
        let p = apply_motion(m, Vec3::from(s.position));
        let n = move_normal(m, Vec3::from(s.normal));
        for k in 0..3 {
            check("apply_motion", at(), gpu[o + k], p[k].to_bits());
            check("move_normal", at(), gpu[o + 3 + k], n[k].to_bits());
        }
        let window = previous_window(p, &prev_camera);
        count_if("window found", window.is_some());
        check("previous_window", at(), gpu[o + 6], window.is_some() as u32);
        if let Some([wx, wy]) = window {
            check("previous_window", at(), gpu[o + 7], wx.to_bits());
            check("previous_window", at(), gpu[o + 8], wy.to_bits());
        }
        let point = [f32::from_bits(ins[0]), f32::from_bits(ins[1])];
        let taps = bilinear_taps(point, (pw, ph));
        let real = window.map(|win| bilinear_taps(win, (pw, ph)));
        let tolerance = f32::from_bits(ins[2]);
        for (t, &(k, wt)) in taps.iter().enumerate() {
            check("bilinear_taps", at(), gpu[o + 9 + t], k.map_or(u32::MAX, |k| k as u32));
            check("bilinear_taps", at(), gpu[o + 13 + t], wt.to_bits());
            count_if("taps off the image", k.is_none());
            if let Some(real) = real {
                let k = real[t].0.unwrap_or(0);
                let yes = accepts(s, p, n, &prev_surfaces[k], tolerance);
                count_if("accepted", yes);
                check("accepts", at(), gpu[o + 17 + t], yes as u32);
            }
        }
        let yes = plausible(f32::from_bits(ins[3]), f32::from_bits(ins[4]), ins[5]);
        count_if("plausible", yes);
        check("plausible", at(), gpu[o + 21], yes as u32);
        let [cur, hist, lo, hi] = [6, 7, 8, 9].map(|k| f32::from_bits(ins[k]));
        check("temporal_blend", at(), gpu[o + 22], temporal_blend(cur, hist, (lo, hi), ins[10]).to_bits());
        let now = neighbourhood_mean(&raw, &surfaces, (w, h), (x, y), channels);
        let then = neighbourhood_mean(&prev_values, &prev_surfaces, (pw, ph), (x * pw / w, y * ph / h), channels);
        let (lo, hi) = raw_range(&raw, &surfaces, (w, h), (x, y), channels);
        let footprint = pixel_footprint(Vec3::from(s.position), eye, angle);
        let mut out = vec![0.0f32; channels];
        let length =
            temporal_pixel(&raw, &surfaces, (w, h), (x, y), (footprint, &samples), &motion, &history, &mut out);
        count_if("history counts", length > 0);
        count_if("blended", length > 0 && out[..] != raw[i * channels..(i + 1) * channels]);
        count_if("history dropped", s.is_hit() && window.is_some() && length == 0);
        for c in 0..channels {
            let b = o + HEAD + PER_CHANNEL * c;
            let at = || format!("pixel ({x}, {y}) channel {c}");
            check("neighbourhood_mean", at(), gpu[b], now[c].0.to_bits());
            check("neighbourhood_mean", at(), gpu[b + 1], now[c].1);
            check("neighbourhood_mean (history)", at(), gpu[b + 2], then[c].0.to_bits());
            check("neighbourhood_mean (history)", at(), gpu[b + 3], then[c].1);
            check("raw_range", at(), gpu[b + 4], lo[c].to_bits());
            check("raw_range", at(), gpu[b + 5], hi[c].to_bits());
            check("temporal_pixel", at(), gpu[b + 6], out[c].to_bits());
        }
        check("temporal_pixel (length)", at(), gpu[o + HEAD + PER_CHANNEL * channels], length);
    }
    assert!(differing.is_empty(), "GPU differs from core: {differing:#?}");
    eprintln!("cases seen: {seen:?}");
    let at_least = |name: &str, n: u32| assert!(seen.get(name).copied().unwrap_or(0) >= n, "{name}: {seen:?}");
    at_least("window found", 500);
    at_least("taps off the image", 50);
    at_least("accepted", 500);
    at_least("plausible", 100);
    at_least("history counts", 100);
    at_least("blended", 100);
    at_least("history dropped", 20);
}
