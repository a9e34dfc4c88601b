// The viewer's present pass (cli/src/view/present.rs): the frame (linear, from
// GpuBackend::render_to_texture) or a stage view (sRGB RGBA8, converted on the CPU),
// with the overlay (premultiplied RGBA8) over its top-left corner, into the window's
// surface. One full-screen triangle; pixels are read with textureLoad, one texel each.

struct Params {
    source_hdr: u32,
    surface_srgb: u32,
    overlay_w: u32,
    overlay_h: u32,
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

@fragment
fn fs_main(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(position.xy);
    var c: vec3<f32>;
    if (params.source_hdr != 0u) {
        let l = textureLoad(frame_texture, p, 0).rgb;
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
