// Stage `shadow_denoise` (as hyrt_cpu::shadow_denoise::shadow_denoise_into): the passes
// over the band's pixels, each an entry point of its own with its own bindings (the
// backend builds one pipeline per entry point, each over the bindings it uses):
//
// 1. `raw_pass`: each pixel's raw channels (raw_channels) into `raw_out`;
// 1b. in a frame of the temporal pass (hyrt_core::options::FrameOptions::temporal), then
//    `temporal_pass`: each pixel's raw channels blended with the history (temporal_pixel)
//    into `accumulated_out`, the frames behind them into `lengths_out` (where the history
//    does not count, `temporal.usable` 0: the raw channels, 0). The passes below then read
//    the accumulated channels as `raw` and as the first pass's `values_in` but for the
//    clamp, which reads this frame's raw channels; the noise deviations count each
//    channel's samples times the frames behind the pixel (`lengths` plus one);
// 2. `tiles_pass`: per DENOISE_TILE x DENOISE_TILE tile (aligned to the band's rows, which
//    start at a multiple of DENOISE_TILE of the image's) and channel, whether the tile is
//    filtered (not tile_agrees) into `tile_filter_out`;
// 3. `sigma_pass`: each pixel's noise_sigma into `sigma_out`;
// 4. `atrous_pass`, DENOISE_PASSES times (`denoise.step` 1, 2, 4, ...), from `values_in`
//    (the raw channels at first) into `values_out`, the last (`denoise.last`) clamped
//    (clamp_pixel) into the frame's visibility.
//
// The CPU stage skips the passes where no tile is filtered; here they run and copy every
// value (atrous_pixel copies a pixel whose tile filters nothing, clamp_pixel changes only
// filtered channels): the same bits.
//
// Prepended: the generated records and constants, the shading helpers, the soft-shadow
// kernels (soft_shadow.wgsl) and shadow_denoise.wgsl.

@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<uniform> camera: CameraRecord;
@group(0) @binding(2) var<uniform> slot_params: SlotParams;
@group(0) @binding(3) var<uniform> ambient_light: AmbientLightRecord;
@group(0) @binding(4) var<uniform> denoise: DenoiseParams;
@group(0) @binding(5) var<storage, read> surfaces: array<SurfaceRecord>;
@group(0) @binding(6) var<storage, read> shadow: array<u32>;
@group(0) @binding(7) var<storage, read> lights: array<LightRecord>;
@group(0) @binding(8) var<storage, read_write> raw_out: array<f32>;
@group(0) @binding(9) var<storage, read> raw: array<f32>;
@group(0) @binding(10) var<storage, read_write> sigma_out: array<f32>;
@group(0) @binding(11) var<storage, read> sigma: array<f32>;
@group(0) @binding(12) var<storage, read_write> tile_filter_out: array<u32>;
@group(0) @binding(13) var<storage, read> tile_filter: array<u32>;
@group(0) @binding(14) var<storage, read> values_in: array<f32>;
@group(0) @binding(15) var<storage, read_write> values_out: array<f32>;
@group(0) @binding(16) var<uniform> prev_camera: CameraRecord;
@group(0) @binding(17) var<uniform> temporal: TemporalParams;
@group(0) @binding(18) var<storage, read> motion: array<MotionRecord>;
@group(0) @binding(19) var<storage, read> prev_surfaces: array<SurfaceRecord>;
@group(0) @binding(20) var<storage, read> prev_values: array<f32>;
@group(0) @binding(21) var<storage, read> prev_lengths: array<u32>;
@group(0) @binding(22) var<storage, read_write> accumulated_out: array<f32>;
@group(0) @binding(23) var<storage, read_write> lengths_out: array<u32>;
@group(0) @binding(24) var<storage, read> lengths: array<u32>;

fn in_band(id: vec3<u32>) -> bool {
    return id.x < params.width && id.y < params.height;
}

@compute @workgroup_size(8, 8, 1)
fn raw_pass(@builtin(global_invocation_id) id: vec3<u32>) {
    if !in_band(id) {
        return;
    }
    let i = id.y * params.width + id.x;
    let channels = slot_params.channels;
    let v = raw_channels(i, surfaces[i]);
    for (var c = 0u; c < channels; c++) {
        raw_out[i * channels + c] = v[c];
    }
}

@compute @workgroup_size(8, 8, 1)
fn temporal_pass(@builtin(global_invocation_id) id: vec3<u32>) {
    if !in_band(id) {
        return;
    }
    let i = id.y * params.width + id.x;
    let channels = slot_params.channels;
    var res: TemporalPixel;
    res.length = 0u;
    for (var c = 0u; c < channels; c++) {
        res.values[c] = raw[i * channels + c];
    }
    if temporal.usable != 0u {
        var samples: array<u32, MAX_CHANNELS>;
        for (var c = 0u; c < channels; c++) {
            samples[c] = temporal.samples[c / 4u][c % 4u];
        }
        let footprint = pixel_footprint(surfaces[i].position, camera.eye, denoise.pixel_angle);
        res = temporal_pixel(params.width, params.height, id.x, id.y, footprint, samples);
    }
    for (var c = 0u; c < channels; c++) {
        accumulated_out[i * channels + c] = res.values[c];
    }
    lengths_out[i] = res.length;
}

@compute @workgroup_size(8, 8, 1)
fn tiles_pass(@builtin(global_invocation_id) id: vec3<u32>) {
    let tiles_x = (params.width + DENOISE_TILE - 1u) / DENOISE_TILE;
    let tiles_y = (params.height + DENOISE_TILE - 1u) / DENOISE_TILE;
    if id.x >= tiles_x || id.y >= tiles_y {
        return;
    }
    let channels = slot_params.channels;
    let t = id.y * tiles_x + id.x;
    for (var c = 0u; c < channels; c++) {
        let agrees = tile_agrees(params.width, params.height, id.x, id.y, c);
        tile_filter_out[t * channels + c] = select(1u, 0u, agrees);
    }
}

@compute @workgroup_size(8, 8, 1)
fn sigma_pass(@builtin(global_invocation_id) id: vec3<u32>) {
    if !in_band(id) {
        return;
    }
    let i = id.y * params.width + id.x;
    let channels = slot_params.channels;
    var frames = 1u;
    if denoise.temporal != 0u {
        frames = lengths[i] + 1u;
    }
    let s = noise_sigma_frames(params.width, params.height, id.x, id.y, frames);
    for (var c = 0u; c < channels; c++) {
        sigma_out[i * channels + c] = s[c];
    }
}

@compute @workgroup_size(8, 8, 1)
fn atrous_pass(@builtin(global_invocation_id) id: vec3<u32>) {
    if !in_band(id) {
        return;
    }
    let x = id.x;
    let y = id.y;
    let i = y * params.width + x;
    let channels = slot_params.channels;
    let tiles_x = (params.width + DENOISE_TILE - 1u) / DENOISE_TILE;
    let t = (y / DENOISE_TILE) * tiles_x + x / DENOISE_TILE;
    var flags: ChannelFlags;
    var s: Channels;
    for (var c = 0u; c < channels; c++) {
        flags[c] = tile_filter[t * channels + c] != 0u;
        s[c] = sigma[i * channels + c];
    }
    let footprint = pixel_footprint(surfaces[i].position, camera.eye, denoise.pixel_angle);
    var res = atrous_pixel(params.width, params.height, x, y, denoise.step, footprint, flags, s);
    if denoise.last != 0u {
        res = clamp_pixel(params.width, params.height, x, y, flags, res);
    }
    for (var c = 0u; c < channels; c++) {
        values_out[i * channels + c] = res[c];
    }
}
