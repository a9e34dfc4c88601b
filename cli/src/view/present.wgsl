// The viewer's present pass (cli/src/view/present.rs): the frame (linear, from
// GpuBackend::render_to_texture) or a stage view (sRGB RGBA8, converted on the CPU),
// with the overlay (premultiplied RGBA8) over its top-left corner, into the window's
// surface. One full-screen triangle; pixels are read with textureLoad, one texel each.

struct Params {
    source_hdr: u32,
    surface_srgb: u32,
    overlay_w: u32,
    overlay_h: u32,
    // The exposure scale's f32 bits and the operator's index in hyrt::ToneMap::ALL
    // (0 none, 1 Khronos PBR Neutral, 2 ACES): hyrt_core::kernels::tone_map::display.
    exposure: u32,
    tone_map: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var frame_texture: texture_2d<f32>;
@group(0) @binding(1) var view_texture: texture_2d<f32>;
@group(0) @binding(2) var overlay_texture: texture_2d<f32>;
@group(0) @binding(3) var<uniform> params: Params;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let p = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(p * 2.0 - 1.0, 0.0, 1.0);
}

fn encode(c: f32) -> f32 {
    let x = clamp(c, 0.0, 1.0);
    return select(1.055 * pow(x, 1.0 / 2.4) - 0.055, x * 12.92, x <= 0.0031308);
}

fn decode(c: f32) -> f32 {
    return select(pow((c + 0.055) / 1.055, 2.4), c / 12.92, c <= 0.04045);
}

// hyrt_core::kernels::tone_map::khronos_pbr_neutral (for display: not bit-exact).
fn khronos_pbr_neutral(c_in: vec3<f32>) -> vec3<f32> {
    let start = NEUTRAL_START_COMPRESSION;
    let desaturation = NEUTRAL_DESATURATION;
    let x = min(c_in.r, min(c_in.g, c_in.b));
    let offset = select(0.04, x - 6.25 * x * x, x < 0.08);
    let c = c_in - vec3<f32>(offset);
    let peak = max(c.r, max(c.g, c.b));
    if peak < start {
        return c;
    }
    let d = 1.0 - start;
    let new_peak = 1.0 - d * d / (peak + d - start);
    let g = 1.0 - 1.0 / (desaturation * (peak - new_peak) + 1.0);
    return mix(c * (new_peak / peak), vec3<f32>(new_peak), g);
}

// hyrt_core::kernels::tone_map::aces (Hill's fit). The constants are generated from
// core's (cli/src/view/present.rs: shader_source), NEUTRAL_* too.
fn aces(c: vec3<f32>) -> vec3<f32> {
    let v = ACES_INPUT * c;
    let a = v * (v + 0.0245786) - 0.000090537;
    let b = v * (0.983729 * v + 0.432951) + 0.238081;
    return clamp(ACES_OUTPUT * (a / b), vec3<f32>(0.0), vec3<f32>(1.0));
}

// hyrt_core::kernels::tone_map::display of a linear colour.
fn display(l: vec3<f32>) -> vec3<f32> {
    let c = max(l * bitcast<f32>(params.exposure), vec3<f32>(0.0));
    if params.tone_map == 1u {
        return khronos_pbr_neutral(c);
    }
    if params.tone_map == 2u {
        return aces(c);
    }
    return c;
}

@fragment
fn fs_main(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(position.xy);
    var c: vec3<f32>;
    if (params.source_hdr != 0u) {
        let l = display(textureLoad(frame_texture, p, 0).rgb);
        c = vec3<f32>(encode(l.r), encode(l.g), encode(l.b));
    } else {
        c = textureLoad(view_texture, p, 0).rgb;
    }
    if (u32(p.x) < params.overlay_w && u32(p.y) < params.overlay_h) {
        let o = textureLoad(overlay_texture, p, 0);
        c = o.rgb + c * (1.0 - o.a);
    }
    if (params.surface_srgb != 0u) {
        c = vec3<f32>(decode(c.r), decode(c.g), decode(c.b));
    }
    return vec4<f32>(c, 1.0);
}
