// The kernels of the denoiser's temporal pass: WGSL twins of hyrt_core::kernels::temporal,
// same names as the core's functions, same operation order (every product through `mul`,
// every sum that feeds more arithmetic behind `rounded`, `/` and `sqrt` through div_rn and
// sqrt_rn; `floor` is exact). The kernels read the images they walk from the stage's
// bindings by name:
//
// * this frame's `surfaces: array<SurfaceRecord>` and raw channels `raw: array<f32>`
//   (`slot_params.channels` per pixel), `width` x `height`;
// * the previous frame's camera `prev_camera: CameraRecord` (its image's size), surfaces
//   `prev_surfaces: array<SurfaceRecord>`, accumulated channels `prev_values: array<f32>`
//   and history lengths `prev_lengths: array<u32>`;
// * the objects' motion `motion: array<MotionRecord>` (one per object, made on the host by
//   hyrt_core::kernels::temporal::motion_records), of which `temporal.motion_count` count.
//
// Prepended by `hyrt_gpu::shadow_denoise::temporal_wgsl` after `denoise_wgsl` and the
// generated constants TEMPORAL_MAX_LENGTH, TEMPORAL_NORMAL_COS, TEMPORAL_PLANE_FOOTPRINTS
// and TEMPORAL_TOLERANCE (from their Rust values).

// The motion of object `object`: its record, or one that does not move (MOTION_NONE) past
// the records (the CPU's `motion.get(o).unwrap_or(&MotionRecord::NONE)`).
fn object_motion(object: u32) -> MotionRecord {
    if object < temporal.motion_count {
        return motion[object];
    }
    var m: MotionRecord;
    m.map_x = vec4<f32>(1.0, 0.0, 0.0, 0.0);
    m.map_y = vec4<f32>(0.0, 1.0, 0.0, 0.0);
    m.map_z = vec4<f32>(0.0, 0.0, 1.0, 0.0);
    m.translation = vec3<f32>(0.0);
    m.flags = MOTION_NONE;
    return m;
}

// One row of apply_motion: ((m_0 q.x + m_1 q.y) + m_2 q.z) + m_3.
fn motion_row(r: vec4<f32>, q: vec3<f32>) -> f32 {
    return rounded(rounded(mul(r.x, q.x) + mul(r.y, q.y)) + mul(r.z, q.z)) + r.w;
}

// mirrors hyrt_core::kernels::temporal::apply_motion
fn apply_motion(m: MotionRecord, p: vec3<f32>) -> vec3<f32> {
    if (m.flags & MOTION_NONE) != 0u {
        return p;
    }
    let q = vec3<f32>(rounded(p.x - m.translation.x), rounded(p.y - m.translation.y), rounded(p.z - m.translation.z));
    return vec3<f32>(motion_row(m.map_x, q), motion_row(m.map_y, q), motion_row(m.map_z, q));
}

// One row of move_normal: (m_0 n.x + m_1 n.y) + m_2 n.z.
fn normal_row(r: vec4<f32>, n: vec3<f32>) -> f32 {
    return rounded(mul(r.x, n.x) + mul(r.y, n.y)) + mul(r.z, n.z);
}

// mirrors hyrt_core::kernels::temporal::move_normal
fn move_normal(m: MotionRecord, n: vec3<f32>) -> vec3<f32> {
    if (m.flags & MOTION_NONE) != 0u {
        return n;
    }
    let v = vec3<f32>(normal_row(m.map_x, n), normal_row(m.map_y, n), normal_row(m.map_z, n));
    let len2 = dot3(v, v);
    if len2 > 0.0 {
        return div_rn3(v, sqrt_rn(len2));
    }
    return n;
}

// A window point of the previous image, or none (`found` 0).
struct PreviousWindow {
    found: u32,
    at: vec2<f32>,
}

// Row `r` of hyrt_core::kernels::raster::clip_position of `v` (glam's order, unfused).
fn clip_row(m: mat4x4<f32>, r: u32, v: vec3<f32>) -> f32 {
    let c0 = m[0];
    let c1 = m[1];
    let c2 = m[2];
    let c3 = m[3];
    return rounded(rounded(rounded(mul(c0[r], v.x) + mul(c1[r], v.y)) + mul(c2[r], v.z)) + c3[r]);
}

// mirrors hyrt_core::kernels::temporal::previous_window with the camera `prev_camera`:
// hyrt_core::kernels::raster::clip_position_from_eye, then clip_to_window.
fn previous_window(p: vec3<f32>) -> PreviousWindow {
    let m = prev_camera.view_proj;
    let v = vec3<f32>(rounded(p.x - prev_camera.eye.x), rounded(p.y - prev_camera.eye.y), rounded(p.z - prev_camera.eye.z));
    let clip = vec4<f32>(clip_row(m, 0u, v), clip_row(m, 1u, v), clip_row(m, 2u, v), clip_row(m, 3u, v));
    let w = f32(prev_camera.width);
    let h = f32(prev_camera.height);
    let ndc_x = div_rn(clip.x, clip.w);
    let ndc_y = div_rn(clip.y, clip.w);
    let x = mul(rounded(mul(ndc_x, 0.5) + 0.5), w);
    let y = mul(rounded(0.5 - mul(ndc_y, 0.5)), h);
    // Not behind the eye (nor NaN), and inside the image.
    let found = clip.w > 0.0 && x >= 0.0 && x < w && y >= 0.0 && y < h;
    return PreviousWindow(select(0u, 1u, found), vec2<f32>(x, y));
}

// The four taps of bilinear_taps: pixel indices (where `valid`) and weights.
struct Taps {
    index: array<u32, 4>,
    valid: array<bool, 4>,
    weight: array<f32, 4>,
}

// mirrors hyrt_core::kernels::temporal::bilinear_taps of window point `w` in a `width` x
// `height` image, in its order (x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1).
fn bilinear_taps(w: vec2<f32>, width: u32, height: u32) -> Taps {
    let gx = rounded(w.x - 0.5);
    let gy = rounded(w.y - 0.5);
    let x0 = floor(gx);
    let y0 = floor(gy);
    let fx = rounded(gx - x0);
    let fy = rounded(gy - y0);
    let ex = rounded(1.0 - fx);
    let ey = rounded(1.0 - fy);
    var taps: Taps;
    taps.weight[0] = mul(ex, ey);
    taps.weight[1] = mul(fx, ey);
    taps.weight[2] = mul(ex, fy);
    taps.weight[3] = mul(fx, fy);
    let fw = f32(width);
    let fh = f32(height);
    for (var t = 0u; t < 4u; t++) {
        let xx = rounded(x0 + f32(t & 1u));
        let yy = rounded(y0 + f32(t >> 1u));
        let inside = xx >= 0.0 && yy >= 0.0 && xx < fw && yy < fh;
        taps.valid[t] = inside;
        taps.index[t] = select(0u, u32(yy) * width + u32(xx), inside);
    }
    return taps;
}

// mirrors hyrt_core::kernels::temporal::accepts
fn accepts(current: SurfaceRecord, p: vec3<f32>, n: vec3<f32>, previous: SurfaceRecord, tolerance: f32) -> bool {
    if previous.object == INVALID_ID || previous.object != current.object {
        return false;
    }
    let np = previous.normal;
    let d = vec3<f32>(rounded(previous.position.x - p.x), rounded(previous.position.y - p.y), rounded(previous.position.z - p.z));
    return dot3(np, n) >= TEMPORAL_NORMAL_COS && abs(dot3(d, np)) <= tolerance;
}

// mirrors hyrt_core::kernels::temporal::plausible
fn plausible(history: f32, mean: f32, count: u32) -> bool {
    let n = u32_to_f32_rn(count);
    let spread = sqrt_rn(div_rn(f32_max(mul(history, rounded(1.0 - history)), 0.0), n));
    let band = rounded(mul(TEMPORAL_TOLERANCE, spread)) + div_rn(1.0, n);
    return abs(rounded(mean - history)) <= band;
}

// mirrors hyrt_core::kernels::temporal::temporal_blend
fn temporal_blend(current: f32, history: f32, lo: f32, hi: f32, length: u32) -> f32 {
    if history < 0.0 {
        return current;
    }
    var h = history;
    if lo <= hi {
        h = denoise_min(f32_max(history, lo), hi);
    }
    if current < 0.0 {
        return h;
    }
    return h + div_rn(rounded(current - h), u32_to_f32_rn(length + 1u));
}

// The object of pixel `j` of this frame's surfaces, or of the previous frame's.
fn temporal_object(previous: bool, j: u32) -> u32 {
    if previous {
        return prev_surfaces[j].object;
    }
    return surfaces[j].object;
}

// Value `k` of this frame's raw channels, or of the previous frame's accumulated ones.
fn temporal_value(previous: bool, k: u32) -> f32 {
    if previous {
        return prev_values[k];
    }
    return raw[k];
}

// Per channel, a neighbourhood's mean and how many values it has.
struct ChannelMeans {
    mean: Channels,
    count: array<u32, MAX_CHANNELS>,
}

// mirrors hyrt_core::kernels::temporal::neighbourhood_mean at hit pixel (x, y) of the
// `width` x `height` image: of `raw` over `surfaces`, or (`previous`) of `prev_values` over
// `prev_surfaces` (rows, then columns, of the CLAMP_RADIUS square clipped to the image).
fn neighbourhood_mean(previous: bool, width: u32, height: u32, x: u32, y: u32) -> ChannelMeans {
    let channels = slot_params.channels;
    var sums: Channels;
    var res: ChannelMeans;
    for (var c = 0u; c < channels; c++) {
        sums[c] = 0.0;
        res.count[c] = 0u;
        res.mean[c] = 0.0;
    }
    let object = temporal_object(previous, y * width + x);
    let y0 = u32(max(i32(y) - CLAMP_RADIUS, 0));
    let y1 = u32(min(i32(y) + CLAMP_RADIUS, i32(height) - 1));
    let x0 = u32(max(i32(x) - CLAMP_RADIUS, 0));
    let x1 = u32(min(i32(x) + CLAMP_RADIUS, i32(width) - 1));
    for (var yy = y0; yy <= y1; yy++) {
        for (var xx = x0; xx <= x1; xx++) {
            let j = yy * width + xx;
            let o = temporal_object(previous, j);
            if o == INVALID_ID || o != object {
                continue;
            }
            for (var c = 0u; c < channels; c++) {
                let v = temporal_value(previous, j * channels + c);
                if v >= 0.0 {
                    sums[c] = rounded(sums[c] + v);
                    res.count[c] += 1u;
                }
            }
        }
    }
    for (var c = 0u; c < channels; c++) {
        if res.count[c] > 0u {
            res.mean[c] = div_rn(sums[c], u32_to_f32_rn(res.count[c]));
        }
    }
    return res;
}

// A neighbourhood's range per channel.
struct ChannelRange {
    lo: Channels,
    hi: Channels,
}

// mirrors hyrt_core::kernels::denoise::raw_range at pixel (x, y) of the `width` x `height`
// image: the range of `raw` in its neighbourhood.
fn raw_range(width: u32, height: u32, x: u32, y: u32) -> ChannelRange {
    let channels = slot_params.channels;
    var res: ChannelRange;
    for (var c = 0u; c < channels; c++) {
        res.lo[c] = bitcast<f32>(0x7f800000u);
        res.hi[c] = bitcast<f32>(0xff800000u);
    }
    let object = surfaces[y * width + x].object;
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
                    res.lo[c] = denoise_min(res.lo[c], v);
                    res.hi[c] = f32_max(res.hi[c], v);
                }
            }
        }
    }
    return res;
}

// What temporal_pixel makes of a pixel: its channels and the frames behind them.
struct TemporalPixel {
    values: Channels,
    length: u32,
}

// mirrors hyrt_core::kernels::temporal::temporal_pixel at pixel (x, y) of the `width` x
// `height` frame whose pixel spans `footprint` (pixel_footprint), `samples` per channel and
// frame: its raw channels blended with the previous frame's, and their new history length.
fn temporal_pixel(width: u32, height: u32, x: u32, y: u32, footprint: f32, samples: array<u32, MAX_CHANNELS>)
    -> TemporalPixel {
    let channels = slot_params.channels;
    let i = y * width + x;
    var res: TemporalPixel;
    res.length = 0u;
    for (var c = 0u; c < channels; c++) {
        res.values[c] = raw[i * channels + c];
    }
    let s = surfaces[i];
    if s.object == INVALID_ID {
        return res;
    }
    let m = object_motion(s.object);
    let p = apply_motion(m, s.position);
    let window = previous_window(p);
    if window.found == 0u {
        return res;
    }
    let n = move_normal(m, s.normal);
    let tolerance = mul(footprint, TEMPORAL_PLANE_FOOTPRINTS);
    let pw = prev_camera.width;
    let ph = prev_camera.height;
    var taps = bilinear_taps(window.at, pw, ph);
    for (var t = 0u; t < 4u; t++) {
        if !(taps.valid[t] && accepts(s, p, n, prev_surfaces[taps.index[t]], tolerance)) {
            taps.valid[t] = false;
            taps.weight[t] = 0.0;
        }
    }
    // The heaviest accepted tap, the first of equal weights (the CPU's fold keeps the
    // earlier).
    var found = false;
    var centre = 0u;
    var best = 0.0;
    for (var t = 0u; t < 4u; t++) {
        if taps.valid[t] && (!found || !(best >= taps.weight[t])) {
            found = true;
            centre = taps.index[t];
            best = taps.weight[t];
        }
    }
    if !found {
        return res;
    }
    var old: Channels;
    for (var c = 0u; c < channels; c++) {
        var sum = 0.0;
        var weight = 0.0;
        for (var t = 0u; t < 4u; t++) {
            if taps.valid[t] {
                let v = prev_values[taps.index[t] * channels + c];
                let w = taps.weight[t];
                if v >= 0.0 && w > 0.0 {
                    sum = rounded(sum + mul(w, v));
                    weight = rounded(weight + w);
                }
            }
        }
        old[c] = NO_ESTIMATE;
        if weight > 0.0 {
            old[c] = div_rn(sum, weight);
        }
    }
    var behind = 0xffffffffu;
    for (var t = 0u; t < 4u; t++) {
        if taps.valid[t] {
            behind = min(behind, prev_lengths[taps.index[t]]);
        }
    }
    let now = neighbourhood_mean(false, width, height, x, y);
    let then = neighbourhood_mean(true, pw, ph, centre % pw, centre / pw);
    for (var c = 0u; c < channels; c++) {
        let count = now.count[c];
        if old[c] >= 0.0 && count > 0u && then.count[c] > 0u
            && !plausible(then.mean[c], now.mean[c], count * samples[c]) {
            return res;
        }
    }
    let length = min(behind + 1u, TEMPORAL_MAX_LENGTH);
    let range = raw_range(width, height, x, y);
    for (var c = 0u; c < channels; c++) {
        res.values[c] = temporal_blend(raw[i * channels + c], old[c], range.lo[c], range.hi[c], length);
    }
    res.length = length;
    return res;
}
