// The kernels of the `shadow_denoise` stage: WGSL mirrors of hyrt_core::kernels::denoise,
// same names as the core's functions, same operation order (sampling.wgsl says how:
// `/` and `sqrt` through div_rn and sqrt_rn, every product through `mul`, every sum
// that feeds more arithmetic behind `rounded`). WGSL has no iterators or slices: a
// pixel's channels are an `array<f32, MAX_CHANNELS>` of which the first
// `slot_params.channels` count, and the kernels read the images they walk from the
// stage's bindings by name:
//
// * `surfaces: array<SurfaceRecord>` (the band's, `width` x `height`), `shadow: array<u32>`
//   (the mask, `slot_params.slots` codes per pixel), `lights`, `ambient_light`,
//   `slot_params` (`channels`: hyrt_core::kernels::denoise::channel_count);
// * `raw: array<f32>` (the raw channels, `channels` per pixel) and `values_in:
//   array<f32>` (an à-trous pass's input).
//
// Prepended by `hyrt_gpu::shadow_denoise::denoise_wgsl` after the shading helpers, the
// soft-shadow kernels (soft_shadow.wgsl) and the generated constants ATROUS_KERNEL,
// NORMAL_SQUARINGS, VALUE_TOLERANCE, CLAMP_RADIUS, DENOISE_TILE, MAX_CHANNELS and
// NO_ESTIMATE (from their Rust values).

// A pixel's channels.
alias Channels = array<f32, MAX_CHANNELS>;
// A tile's per-channel filter flags.
alias ChannelFlags = array<bool, MAX_CHANNELS>;

// The smaller of two values that are not NaN (the raw channels never are): Rust's f32::min.
fn denoise_min(x: f32, y: f32) -> f32 {
    return select(x, y, y < x);
}

// mirrors hyrt_core::kernels::denoise::pixel_footprint
fn pixel_footprint(p: vec3<f32>, eye: vec3<f32>, pixel_angle: f32) -> f32 {
    let d = p - eye;
    return mul(sqrt_rn(dot3(d, d)), pixel_angle);
}

// mirrors hyrt_core::kernels::denoise::tap_weight
fn tap_weight(centre: SurfaceRecord, other: SurfaceRecord, footprint: f32) -> f32 {
    if other.object == INVALID_ID || other.object != centre.object {
        return 0.0;
    }
    let n = centre.normal;
    var c = f32_max(dot3(n, other.normal), 0.0);
    for (var k = 0u; k < NORMAL_SQUARINGS; k++) {
        c = mul(c, c);
    }
    let plane = abs(dot3(other.position - centre.position, n));
    return mul(c, f32_max(1.0 - div_rn(plane, footprint), 0.0));
}

// mirrors hyrt_core::kernels::denoise::value_weight
fn value_weight(centre: f32, other: f32, sigma: f32) -> f32 {
    if centre < 0.0 {
        return 1.0;
    }
    let d = abs(other - centre);
    if sigma > 0.0 {
        return f32_max(1.0 - div_rn(d, mul(VALUE_TOLERANCE, sigma)), 0.0);
    }
    if d == 0.0 {
        return 1.0;
    }
    return 0.0;
}

// mirrors the area-light branch of hyrt_core::kernels::soft_shadow::light_visibility for
// `light`, whose slots start at `first` in `shadow`, at the hit `s`: the visible share of
// its samples' irradiance, NO_ESTIMATE where no sample traced a ray.
fn area_light_visibility(first: u32, light: LightRecord, s: SurfaceRecord) -> f32 {
    var lit = 0.0;
    var total = 0.0;
    for (var sample = 0u; sample < light.samples; sample++) {
        let code = shadow[first + sample];
        if code == SHADOW_NO_RAY {
            continue;
        }
        let ls = area_light_sample(light, s.position, sample);
        if ls.valid {
            // glam's Vec3::max_element: x.max(y.max(z)).
            let e = f32_max(ls.weight.x, f32_max(ls.weight.y, ls.weight.z));
            let c = mul(e, f32_max(dot3(s.normal, ls.l), 0.0));
            total = rounded(total + c);
            if code == SHADOW_LIT {
                lit = rounded(lit + c);
            }
        }
    }
    if total > 0.0 {
        return div_rn(lit, total);
    }
    return NO_ESTIMATE;
}

// mirrors hyrt_core::kernels::soft_shadow::ambient_occlusion of the mask row `index` of
// `shadow` (call with occlusion rays only).
fn mask_ambient_occlusion(index: u32) -> f32 {
    let samples = ambient_light.ao_samples;
    let first = index * slot_params.slots + slot_params.light_slots;
    var lit = 0u;
    for (var k = 0u; k < samples; k++) {
        lit += select(0u, 1u, shadow[first + k] == SHADOW_LIT);
    }
    return ao_fraction(lit, samples);
}

// mirrors hyrt_core::kernels::denoise::raw_channels of pixel `index` (its mask row of
// `shadow`) with surface `s`.
fn raw_channels(index: u32, s: SurfaceRecord) -> Channels {
    var res: Channels;
    let hit = s.object != INVALID_ID;
    var k = 0u;
    var slot = index * slot_params.slots;
    for (var i = 0u; i < params.light_count; i++) {
        let light = lights[i];
        if light_is_area(light) {
            var v = 0.0;
            if hit {
                v = area_light_visibility(slot, light, s);
            }
            res[k] = v;
            k++;
        }
        slot += light_slots(light);
    }
    if ambient_light.ao_samples > 0u {
        var v = 1.0;
        if hit {
            v = mask_ambient_occlusion(index);
        }
        res[k] = v;
    }
    return res;
}

// mirrors hyrt_core::kernels::denoise::channel_samples
fn channel_samples() -> array<u32, MAX_CHANNELS> {
    var res: array<u32, MAX_CHANNELS>;
    var k = 0u;
    for (var i = 0u; i < params.light_count; i++) {
        let light = lights[i];
        if light_is_area(light) {
            res[k] = light.samples;
            k++;
        }
    }
    if ambient_light.ao_samples > 0u {
        res[k] = ambient_light.ao_samples;
    }
    return res;
}

// mirrors the filter of hyrt_core::kernels::denoise::neighbourhood: pixel `j` is a hit on
// `object`.
fn in_neighbourhood(j: u32, object: u32) -> bool {
    let o = surfaces[j].object;
    return o != INVALID_ID && o == object;
}

// mirrors hyrt_core::kernels::denoise::noise_sigma at pixel (x, y) of the `width` x
// `height` image: the raw values of `raw` in its neighbourhood (rows, then columns, of
// the CLAMP_RADIUS square clipped to the image), each channel's samples those of one
// frame (channel_samples).
fn noise_sigma(width: u32, height: u32, x: u32, y: u32) -> Channels {
    return noise_sigma_frames(width, height, x, y, 1u);
}

// noise_sigma with each channel's samples those of `frames` frames (channel_samples times
// `frames`, a u32 product: the CPU stage's samples behind a pixel of the temporal pass).
fn noise_sigma_frames(width: u32, height: u32, x: u32, y: u32, frames: u32) -> Channels {
    var res: Channels;
    let channels = slot_params.channels;
    for (var c = 0u; c < channels; c++) {
        res[c] = 0.0;
    }
    let object = surfaces[y * width + x].object;
    if object == INVALID_ID {
        return res;
    }
    let samples = channel_samples();
    var sums: Channels;
    var counts: array<u32, MAX_CHANNELS>;
    for (var c = 0u; c < channels; c++) {
        sums[c] = 0.0;
        counts[c] = 0u;
    }
    let y0 = u32(max(i32(y) - CLAMP_RADIUS, 0));
    let y1 = u32(min(i32(y) + CLAMP_RADIUS, i32(height) - 1));
    let x0 = u32(max(i32(x) - CLAMP_RADIUS, 0));
    let x1 = u32(min(i32(x) + CLAMP_RADIUS, i32(width) - 1));
    for (var yy = y0; yy <= y1; yy++) {
        for (var xx = x0; xx <= x1; xx++) {
            let j = yy * width + xx;
            if !in_neighbourhood(j, object) {
                continue;
            }
            for (var c = 0u; c < channels; c++) {
                let v = raw[j * channels + c];
                if v >= 0.0 {
                    sums[c] = rounded(sums[c] + v);
                    counts[c] += 1u;
                }
            }
        }
    }
    for (var c = 0u; c < channels; c++) {
        if counts[c] > 0u {
            let m = div_rn(sums[c], u32_to_f32_rn(counts[c]));
            res[c] = sqrt_rn(div_rn(f32_max(mul(m, 1.0 - m), 0.0), u32_to_f32_rn(samples[c] * frames)));
        }
    }
    return res;
}

// mirrors hyrt_core::kernels::denoise::tile_agrees over channel `c` of `raw` at the hit
// pixels of tile (tx, ty) (DENOISE_TILE pixels a side, clipped to the `width` x `height`
// image), in row-major order (the CPU stage's iterator).
fn tile_agrees(width: u32, height: u32, tx: u32, ty: u32, c: u32) -> bool {
    let channels = slot_params.channels;
    var first = true;
    var value = 0.0;
    for (var y = ty * DENOISE_TILE; y < min((ty + 1u) * DENOISE_TILE, height); y++) {
        for (var x = tx * DENOISE_TILE; x < min((tx + 1u) * DENOISE_TILE, width); x++) {
            let i = y * width + x;
            if surfaces[i].object == INVALID_ID {
                continue;
            }
            let v = raw[i * channels + c];
            if first {
                if !(v == 0.0 || v == 1.0) {
                    return false;
                }
                value = v;
                first = false;
            } else if !(v == value) {
                return false;
            }
        }
    }
    return true;
}

// mirrors hyrt_core::kernels::denoise::atrous_pixel at pixel (x, y) of the `width` x
// `height` image: its channels of `values_in` filtered with taps `step` pixels apart;
// `flags[c]` says whether channel `c` is filtered there, `sigmas` are the pixel's
// noise_sigma, `footprint` its pixel_footprint.
fn atrous_pixel(width: u32, height: u32, x: u32, y: u32, step: u32, footprint: f32, flags: ChannelFlags,
                sigmas: Channels) -> Channels {
    let channels = slot_params.channels;
    let i = y * width + x;
    let centre = surfaces[i];
    var res: Channels;
    var filtered_any = false;
    for (var c = 0u; c < channels; c++) {
        res[c] = values_in[i * channels + c];
        filtered_any = filtered_any || flags[c];
    }
    if centre.object == INVALID_ID || !filtered_any {
        return res;
    }
    let tolerance = mul(footprint, f32(step));
    var sums: Channels;
    var weights: Channels;
    for (var c = 0u; c < channels; c++) {
        sums[c] = 0.0;
        weights[c] = 0.0;
    }
    for (var dy = -2; dy <= 2; dy++) {
        let yy = i32(y) + dy * i32(step);
        if yy < 0 || yy >= i32(height) {
            continue;
        }
        for (var dx = -2; dx <= 2; dx++) {
            let xx = i32(x) + dx * i32(step);
            if xx < 0 || xx >= i32(width) {
                continue;
            }
            let j = u32(yy) * width + u32(xx);
            let h = mul(ATROUS_KERNEL[abs(dx)], ATROUS_KERNEL[abs(dy)]);
            var w = h;
            if j != i {
                w = mul(h, tap_weight(centre, surfaces[j], tolerance));
            }
            if w == 0.0 {
                continue;
            }
            for (var c = 0u; c < channels; c++) {
                let v = values_in[j * channels + c];
                // Values without an estimate (NO_ESTIMATE, negative) weigh nothing.
                if v >= 0.0 {
                    let centre_value = values_in[i * channels + c];
                    var wc = w;
                    if j != i {
                        wc = mul(w, value_weight(centre_value, v, sigmas[c]));
                    }
                    weights[c] = rounded(weights[c] + wc);
                    sums[c] = rounded(sums[c] + mul(wc, v - f32_max(centre_value, 0.0)));
                }
            }
        }
    }
    for (var c = 0u; c < channels; c++) {
        if flags[c] && weights[c] > 0.0 {
            res[c] = f32_max(values_in[i * channels + c], 0.0) + div_rn(sums[c], weights[c]);
        }
    }
    return res;
}

// mirrors hyrt_core::kernels::denoise::clamp_pixel at pixel (x, y) of the `width` x
// `height` image: `res` (its filtered channels) clamped where `flags` (the filter) to the range of
// the raw values (`raw`) in its neighbourhood.
fn clamp_pixel(width: u32, height: u32, x: u32, y: u32, flags: ChannelFlags, res: Channels) -> Channels {
    let channels = slot_params.channels;
    var result = res;
    let object = surfaces[y * width + x].object;
    var filtered_any = false;
    for (var c = 0u; c < channels; c++) {
        filtered_any = filtered_any || flags[c];
    }
    if object == INVALID_ID || !filtered_any {
        return result;
    }
    var lo: Channels;
    var hi: Channels;
    for (var c = 0u; c < channels; c++) {
        lo[c] = bitcast<f32>(0x7f800000u);
        hi[c] = bitcast<f32>(0xff800000u);
    }
    let y0 = u32(max(i32(y) - CLAMP_RADIUS, 0));
    let y1 = u32(min(i32(y) + CLAMP_RADIUS, i32(height) - 1));
    let x0 = u32(max(i32(x) - CLAMP_RADIUS, 0));
    let x1 = u32(min(i32(x) + CLAMP_RADIUS, i32(width) - 1));
    for (var yy = y0; yy <= y1; yy++) {
        for (var xx = x0; xx <= x1; xx++) {
            let j = yy * width + xx;
            if !in_neighbourhood(j, object) {
                continue;
            }
            for (var c = 0u; c < channels; c++) {
                let v = raw[j * channels + c];
                if v >= 0.0 {
                    lo[c] = denoise_min(lo[c], v);
                    hi[c] = f32_max(hi[c], v);
                }
            }
        }
    }
    for (var c = 0u; c < channels; c++) {
        if flags[c] && result[c] >= 0.0 && lo[c] <= hi[c] {
            result[c] = denoise_min(f32_max(result[c], lo[c]), hi[c]);
        }
    }
    return result;
}
