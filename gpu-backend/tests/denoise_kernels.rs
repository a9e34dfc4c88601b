//! The kernels of `shaders/shadow_denoise.wgsl` one by one against the core's
//! (`hyrt_core::kernels::denoise`: `pixel_footprint`, `tap_weight`, `value_weight`,
//! `raw_channels`, `noise_sigma`, `tile_agrees`, `atrous_pixel` at steps 1, 2 and 4,
//! `clamp_pixel`), bit for bit, at every pixel of seeded random images: three objects
//! and misses, normals and positions near planes (tap weights between 0 and 1), raw
//! values with the hard cases mixed in (no estimate, exact 0 and 1, tiles that agree),
//! noise deviations of 0 and not, random mask codes under a quad, a point and a sphere
//! light with ambient occlusion. (The whole stage against the CPU's: `tests/soft_shadows.rs`
//! and the conformance corpus' `stochastic_denoised_*` cases.)

mod common;

use common::test_context;
use hyrt_core::formats::{AmbientLightRecord, FrameParams, LightRecord, SurfaceRecord, SHADOW_LIT, SHADOW_NO_RAY};
use hyrt_core::glam::Vec3;
use hyrt_core::kernels::denoise::{
    atrous_pixel, channel_count, channel_samples, clamp_pixel, noise_sigma, pixel_footprint, raw_channels, tap_weight,
    tile_agrees, value_weight, DENOISE_TILE,
};
use hyrt_core::kernels::soft_shadow::{frame_lights, frame_occlusion, surface_slots, NO_ESTIMATE};
use hyrt_core::scene::Light;
use hyrt_gpu::buffers::SlotParams;
use hyrt_gpu::exact::same_bits;
use hyrt_gpu::gpu_buffer::{read_back, storage, upload};
use hyrt_gpu::shader::{
    bind_buffers, compute_pipeline, inexact_operations, shading_source, soft_shadow_wgsl, storage_entry, uniform_entry,
};
use hyrt_gpu::shadow_denoise::denoise_wgsl;
use wgpu::util::DeviceExt;

const WIDTH: usize = 40;
const HEIGHT: usize = 27;

/// Words per pixel before its channels: footprint, tap weight, value weight.
const HEAD: usize = 3;
/// Per-channel results per pixel: raw_channels, noise_sigma, atrous_pixel, clamp_pixel.
const PER_CHANNEL: usize = 4;

const ENTRY: &str = r#"
@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<uniform> ambient_light: AmbientLightRecord;
@group(0) @binding(2) var<uniform> slot_params: SlotParams;
@group(0) @binding(3) var<storage, read> lights: array<LightRecord>;
@group(0) @binding(4) var<storage, read> surfaces: array<SurfaceRecord>;
@group(0) @binding(5) var<storage, read> shadow: array<u32>;
@group(0) @binding(6) var<storage, read> raw: array<f32>;
@group(0) @binding(7) var<storage, read> values_in: array<f32>;
// The noise deviations (channels per pixel), then the tiles' flags (channels per tile).
@group(0) @binding(8) var<storage, read> inputs: array<f32>;
@group(0) @binding(9) var<storage, read_write> results: array<u32>;

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
    let per = HEAD + PER_CHANNEL * channels;
    let o = i * per;
    let step = 1u << (i % 3u);
    let centre = surfaces[i];
    let footprint = pixel_footprint(centre.position, EYE, PIXEL_ANGLE);
    results[o] = bitcast<u32>(footprint);
    let j = min(y + step, height - 1u) * width + (x + 1u) % width;
    results[o + 1u] = bitcast<u32>(tap_weight(centre, surfaces[j], mul(footprint, f32(step))));
    results[o + 2u] = bitcast<u32>(value_weight(raw[i * channels], raw[j * channels], inputs[i * channels]));
    let r = raw_channels(i, centre);
    let s = noise_sigma(width, height, x, y);
    let tiles_x = (width + DENOISE_TILE - 1u) / DENOISE_TILE;
    let t = (y / DENOISE_TILE) * tiles_x + x / DENOISE_TILE;
    var flags: ChannelFlags;
    var sigmas: Channels;
    for (var c = 0u; c < channels; c++) {
        flags[c] = inputs[width * height * channels + t * channels + c] != 0.0;
        sigmas[c] = inputs[i * channels + c];
    }
    let a = atrous_pixel(width, height, x, y, step, footprint, flags, sigmas);
    let k = clamp_pixel(width, height, x, y, flags, a);
    for (var c = 0u; c < channels; c++) {
        results[o + HEAD + c] = bitcast<u32>(r[c]);
        results[o + HEAD + channels + c] = bitcast<u32>(s[c]);
        results[o + HEAD + 2u * channels + c] = bitcast<u32>(a[c]);
        results[o + HEAD + 3u * channels + c] = bitcast<u32>(k[c]);
    }
    // tile_agrees of tile i / channels, channel i % channels.
    let tiles = tiles_x * ((height + DENOISE_TILE - 1u) / DENOISE_TILE);
    if i < tiles * channels {
        let tt = i / channels;
        let agrees = tile_agrees(width, height, tt % tiles_x, tt / tiles_x, i % channels);
        results[width * height * per + i] = select(0u, 1u, agrees);
    }
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

#[test]
fn denoise_kernels_match_cpu_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let (w, h) = (WIDTH, HEIGHT);
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
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
    let eye = Vec3::new(0.3, 2.5, 3.0);
    let pixel_angle = 0.0123f32;

    // Three objects on planes (and misses), normals near the planes'.
    let surfaces: Vec<SurfaceRecord> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let object = ((i % w) / 14) as u32;
            if (i * 7 + i / w) % 23 == 0 || object > 2 {
                return SurfaceRecord::MISS;
            }
            let base = [Vec3::Y, Vec3::new(0.0, 0.6, 0.8), Vec3::new(0.3, 0.9, -0.3).normalize()][object as usize];
            let jitter = Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
            let normal = (base + jitter * [0.0, 0.02, 0.3][rng.u32() as usize % 3]).normalize();
            let p = Vec3::new(x * 0.03, 0.0, y * 0.03) + base * rng.range(-0.02, 0.02);
            SurfaceRecord {
                position: p.into(),
                normal: normal.into(),
                geometric_normal: base.into(),
                object,
                triangle: 0,
                position_error: 1e-6,
            }
        })
        .collect();
    // Raw values: no estimate, 0, 1, fractions; some tiles all 1 (or all 0) in a channel.
    let raw: Vec<f32> = (0..w * h * channels)
        .map(|k| {
            let (i, c) = (k / channels, k % channels);
            let (tx, ty) = ((i % w) / DENOISE_TILE, (i / w) / DENOISE_TILE);
            if (tx + ty + c) % 3 == 0 {
                return ((tx + c) % 2) as f32;
            }
            match rng.u32() % 8 {
                0 => NO_ESTIMATE,
                1 => 0.0,
                2 => 1.0,
                _ => rng.unit(),
            }
        })
        .collect();
    let sigma: Vec<f32> =
        (0..w * h * channels).map(|_| if rng.u32().is_multiple_of(4) { 0.0 } else { rng.range(0.0, 0.3) }).collect();
    let (tiles_x, tiles_y) = (w.div_ceil(DENOISE_TILE), h.div_ceil(DENOISE_TILE));
    let flags: Vec<bool> = (0..tiles_x * tiles_y * channels).map(|_| !rng.u32().is_multiple_of(4)).collect();
    let codes: Vec<u32> = (0..w * h * slots)
        .map(|_| match rng.u32() % 3 {
            0 => SHADOW_NO_RAY as u32,
            1 => SHADOW_LIT as u32,
            _ => hyrt_core::formats::SHADOW_OCCLUDED as u32,
        })
        .collect();

    // f32 literals with exactly their values (widened to f64, printed shortest).
    let f = |x: f32| format!("{:?}", x as f64);
    let consts = format!(
        "const HEAD: u32 = {HEAD}u;\nconst PER_CHANNEL: u32 = {PER_CHANNEL}u;\nconst EYE: vec3<f32> = vec3<f32>({}, {}, {});\nconst PIXEL_ANGLE: f32 = {};\n",
        f(eye.x),
        f(eye.y),
        f(eye.z),
        f(pixel_angle)
    );
    let source = shading_source(&format!("{consts}{}\n{}\n{ENTRY}", soft_shadow_wgsl(), denoise_wgsl()));
    assert_eq!(inexact_operations(&source), Ok(Vec::new()));
    let entries = [
        uniform_entry(0),
        uniform_entry(1),
        uniform_entry(2),
        storage_entry(3, true),
        storage_entry(4, true),
        storage_entry(5, true),
        storage_entry(6, true),
        storage_entry(7, true),
        storage_entry(8, true),
        storage_entry(9, false),
    ];
    let (pipeline, layout) = compute_pipeline(&ctx, "denoise kernels test", &source, &entries);
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
    let per = HEAD + PER_CHANNEL * channels;
    let count = w * h * per + tiles_x * tiles_y * channels;
    let inputs: Vec<f32> = sigma.iter().copied().chain(flags.iter().map(|&f| f as u32 as f32)).collect();
    let params = FrameParams::new(w as u32, h as u32, lights.len() as u32, 1.0);
    let slot_params = SlotParams::of(&lights, ao.samples);
    assert_eq!(slot_params.channels as usize, channels);
    let buffers = [
        &uniform("params", bytemuck::bytes_of(&params)),
        &uniform("ambient light", bytemuck::bytes_of(&ambient)),
        &uniform("slot params", bytemuck::bytes_of(&slot_params)),
        &upload(&ctx, "lights", &lights),
        &upload(&ctx, "surfaces", &surfaces),
        &upload(&ctx, "shadow", &codes),
        &upload(&ctx, "raw", &raw),
        &upload(&ctx, "values", &raw),
        &upload(&ctx, "inputs", &inputs),
        &storage::<u32>(&ctx, "results", count).expect("results buffer"),
    ];
    let group = bind_buffers(&ctx, "denoise kernels test", &layout, &buffers);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(((w * h) as u32).div_ceil(64), 1, 1);
    }
    ctx.queue.submit([encoder.finish()]);
    let gpu = read_back::<u32>(&ctx, buffers[9], count).expect("read back");

    let names =
        ["pixel_footprint", "tap_weight", "value_weight", "raw_channels", "noise_sigma", "atrous_pixel", "clamp_pixel"];
    let mut differing = std::collections::BTreeMap::<&str, (usize, String)>::new();
    let mut check = |name: &'static str, at: String, g: u32, c: u32| {
        if !same_bits(g, c) {
            let e = differing.entry(name).or_insert_with(|| (0, format!("{at}: gpu {g:#010x} cpu {c:#010x}")));
            e.0 += 1;
        }
    };
    let (mut weights_between, mut filtered_changed) = (0, 0);
    let mut scratch = vec![0.0f32; lights.len()];
    let samples = channel_samples(&lights, &ao);
    for i in 0..w * h {
        let (x, y) = (i % w, i / w);
        let step = 1usize << (i % 3);
        let o = i * per;
        let at = || format!("pixel ({x}, {y})");
        let footprint = pixel_footprint(Vec3::from(surfaces[i].position), eye, pixel_angle);
        check(names[0], at(), gpu[o], footprint.to_bits());
        let j = (y + step).min(h - 1) * w + (x + 1) % w;
        let tw = tap_weight(&surfaces[i], &surfaces[j], footprint * step as f32);
        weights_between += (tw > 0.0 && tw < 1.0) as u32;
        check(names[1], at(), gpu[o + 1], tw.to_bits());
        check(
            names[2],
            at(),
            gpu[o + 2],
            value_weight(raw[i * channels], raw[j * channels], sigma[i * channels]).to_bits(),
        );
        let mut r = vec![0.0; channels];
        let mask: &[u8] = &codes[i * slots..(i + 1) * slots].iter().map(|&c| c as u8).collect::<Vec<_>>();
        raw_channels(mask, &lights, &ao, &surfaces[i], &mut scratch, &mut r);
        let mut s = vec![0.0; channels];
        noise_sigma(&raw, &surfaces, (w, h), (x, y), &samples, &mut s);
        let t = (y / DENOISE_TILE) * tiles_x + x / DENOISE_TILE;
        let f = &flags[t * channels..(t + 1) * channels];
        let mut a = vec![0.0; channels];
        atrous_pixel(
            &raw,
            &surfaces,
            (w, h),
            (x, y),
            step,
            footprint,
            (f, &sigma[i * channels..(i + 1) * channels]),
            &mut a,
        );
        filtered_changed += (a[..] != raw[i * channels..(i + 1) * channels]) as u32;
        let mut k = a.clone();
        clamp_pixel(&raw, &surfaces, (w, h), (x, y), f, &mut k);
        for c in 0..channels {
            let base = o + HEAD + c;
            check(names[3], format!("{} channel {c}", at()), gpu[base], r[c].to_bits());
            check(names[4], format!("{} channel {c}", at()), gpu[base + channels], s[c].to_bits());
            check(names[5], format!("{} channel {c}", at()), gpu[base + 2 * channels], a[c].to_bits());
            check(names[6], format!("{} channel {c}", at()), gpu[base + 3 * channels], k[c].to_bits());
        }
    }
    let mut agreeing = 0;
    for t in 0..tiles_x * tiles_y {
        let (tx, ty) = (t % tiles_x, t / tiles_x);
        for c in 0..channels {
            let pixels = (ty * DENOISE_TILE..((ty + 1) * DENOISE_TILE).min(h))
                .flat_map(|y| (tx * DENOISE_TILE..((tx + 1) * DENOISE_TILE).min(w)).map(move |x| y * w + x))
                .filter(|&i| surfaces[i].is_hit());
            let want = tile_agrees(pixels.map(|i| raw[i * channels + c]));
            agreeing += want as u32;
            check(
                "tile_agrees",
                format!("tile ({tx}, {ty}) channel {c}"),
                gpu[w * h * per + t * channels + c],
                want as u32,
            );
        }
    }
    assert!(differing.is_empty(), "GPU differs from core: {differing:#?}");
    assert!(
        weights_between > 50 && filtered_changed > 100 && agreeing > 5,
        "{weights_between} {filtered_changed} {agreeing}"
    );
}
