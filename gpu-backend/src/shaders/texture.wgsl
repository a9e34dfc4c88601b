// Texture kernels: WGSL mirrors of `hyrt_core::kernels::texture`, same names, same
// operation order. Filtering is done by hand from texel loads (never the hardware
// sampler, whose filtering weights are fixed-point and differ between GPUs), so the
// results are the CPU's bits.
//
// Prepended at pipeline creation by `hyrt_gpu::texture::texture_wgsl`, after a generated
// prelude that defines UNORM8_SCALE from its Rust value, and after surface_tables.wgsl
// (the accessors of the packed surface tables: `surface_texel`, `surface_texture`,
// `surface_srgb8`, ...).
// Needs the generated records and format constants
// (`hyrt_core::formats::wgsl::declarations`) and `rounded` and `mul` over an always-zero
// uniform word: every product that feeds a sum goes through `mul`, so that it cannot be
// fused into a multiply-add. The including stage binds what surface_tables.wgsl reads.
// The level of detail (`hit_lod`) and the shaded object record are in materials.wgsl,
// for the shading stages.

// Rust's `f32::is_nan`, as a test of the bits: exponent all ones, mantissa not zero.
fn texture_is_nan(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7fffffffu) > F32_EXP_MASK;
}

// mirrors hyrt_core::kernels::texture::srgb8_to_linear
fn srgb8_to_linear(code: u32) -> f32 {
    // The table packed with the surface tables (`hyrt_gpu::texture` docs).
    return surface_srgb8(code);
}

// mirrors hyrt_core::kernels::texture::unorm8_to_f32
fn unorm8_to_f32(code: u32) -> f32 {
    return mul(f32(code), UNORM8_SCALE);
}

// mirrors hyrt_core::kernels::texture::decode_texel
fn decode_texel(t: u32, encoding: u32) -> vec4<f32> {
    let a = unorm8_to_f32(t >> 24u);
    if encoding == TEXEL_SRGB {
        return vec4<f32>(srgb8_to_linear(t & 0xffu), srgb8_to_linear((t >> 8u) & 0xffu),
            srgb8_to_linear((t >> 16u) & 0xffu), a);
    }
    return vec4<f32>(unorm8_to_f32(t & 0xffu), unorm8_to_f32((t >> 8u) & 0xffu), unorm8_to_f32((t >> 16u) & 0xffu), a);
}

// mirrors hyrt_core::kernels::texture::wrap_coordinate
fn wrap_coordinate(x: f32, wrap: u32) -> f32 {
    if !f32_is_finite(x) {
        return 0.0;
    }
    if wrap == WRAP_CLAMP {
        // Rust's `clamp(0, 1)` (keeps -0.0, which WGSL's `clamp` need not).
        if x < 0.0 {
            return 0.0;
        }
        if x > 1.0 {
            return 1.0;
        }
        return x;
    } else if wrap == WRAP_MIRROR {
        let h = mul(x, 0.5);
        return (h - floor(h)) * 2.0;
    }
    // `x - floor(x)` can round up to 1 for a tiny negative x: keep it in [0, 1).
    let f = x - floor(x);
    if f >= 1.0 {
        return 0.0;
    }
    return f;
}

// mirrors hyrt_core::kernels::texture::wrap_index
// (`rem_euclid(i, m)` with m > 0: WGSL's `%` truncates like Rust's, and a negative
// remainder gets m added.)
fn wrap_index(i: i32, n: u32, wrap: u32) -> u32 {
    let m = i32(n);
    var k: i32;
    if wrap == WRAP_CLAMP {
        k = clamp(i, 0, m - 1);
    } else if wrap == WRAP_MIRROR {
        var r = i % (2 * m);
        if r < 0 {
            r += 2 * m;
        }
        if r >= m {
            k = 2 * m - 1 - r;
        } else {
            k = r;
        }
    } else {
        k = i % m;
        if k < 0 {
            k += m;
        }
    }
    return u32(k);
}

// Width and height of level `level` of `tex` (TextureRecord::level_size).
fn texture_level_size(tex: TextureRecord, level: u32) -> vec2<u32> {
    return vec2<u32>(max(tex.width >> level, 1u), max(tex.height >> level, 1u));
}

// Index in the texels of level `level`'s first texel (TextureRecord::level_offset).
fn texture_level_offset(tex: TextureRecord, level: u32) -> u32 {
    var at = tex.first_texel;
    for (var k = 0u; k < level; k++) {
        let size = texture_level_size(tex, k);
        at += size.x * size.y;
    }
    return at;
}

// mirrors hyrt_core::kernels::texture::fetch (private there): a texel of the level at
// `base` (`w` x `h` texels) at integer indices, wrapped, as linear RGBA.
fn fetch_texel(tex: TextureRecord, base: u32, w: u32, h: u32, x: i32, y: i32) -> vec4<f32> {
    let i = wrap_index(x, w, tex.wrap_s);
    let j = wrap_index(y, h, tex.wrap_t);
    return decode_texel(surface_texel(base + j * w + i), tex.encoding);
}

// mirrors hyrt_core::kernels::texture::lerp4
fn lerp4(a: vec4<f32>, b: vec4<f32>, t: f32) -> vec4<f32> {
    return vec4<f32>(
        rounded(a.x + mul(b.x - a.x, t)),
        rounded(a.y + mul(b.y - a.y, t)),
        rounded(a.z + mul(b.z - a.z, t)),
        rounded(a.w + mul(b.w - a.w, t)),
    );
}

// mirrors hyrt_core::kernels::texture::sample_level
fn sample_level(tex: TextureRecord, level: u32, uv: vec2<f32>, filter_mode: u32) -> vec4<f32> {
    let size = texture_level_size(tex, level);
    let w = size.x;
    let h = size.y;
    let base = texture_level_offset(tex, level);
    let x = mul(wrap_coordinate(uv.x, tex.wrap_s), f32(w));
    let y = mul(wrap_coordinate(uv.y, tex.wrap_t), f32(h));
    if filter_mode == FILTER_NEAREST {
        return fetch_texel(tex, base, w, h, i32(floor(x)), i32(floor(y)));
    }
    // Behind the barrier: `xs - floor(xs)` must not be reassociated into `x - (0.5 + x0)`.
    let xs = rounded(x - 0.5);
    let ys = rounded(y - 0.5);
    let x0 = floor(xs);
    let y0 = floor(ys);
    let fx = xs - x0;
    let fy = ys - y0;
    let i = i32(x0);
    let j = i32(y0);
    let top = lerp4(fetch_texel(tex, base, w, h, i, j), fetch_texel(tex, base, w, h, i + 1, j), fx);
    let bottom = lerp4(fetch_texel(tex, base, w, h, i, j + 1), fetch_texel(tex, base, w, h, i + 1, j + 1), fx);
    return lerp4(top, bottom, fy);
}

// mirrors hyrt_core::kernels::texture::sample_texture
fn sample_texture(tex: TextureRecord, uv: vec2<f32>, lod_in: f32) -> vec4<f32> {
    if texture_is_nan(lod_in) || lod_in <= 0.0 {
        return sample_level(tex, 0u, uv, tex.mag_filter);
    }
    if tex.mip_filter == FILTER_NO_MIP {
        return sample_level(tex, 0u, uv, tex.min_filter);
    }
    let top = f32(tex.levels - 1u);
    // Rust's `min` of a number (`lod` is not NaN here).
    let lod = select(lod_in, top, top < lod_in);
    if tex.mip_filter == FILTER_NEAREST {
        // Nearest level: round half up (`floor(lod + 0.5)`).
        let nearest = floor(lod + 0.5);
        let level = u32(select(nearest, top, top < nearest));
        return sample_level(tex, level, uv, tex.min_filter);
    }
    let l0 = floor(lod);
    let f = lod - l0;
    let fine = sample_level(tex, u32(l0), uv, tex.min_filter);
    if f == 0.0 {
        return fine;
    }
    let coarse = sample_level(tex, u32(l0) + 1u, uv, tex.min_filter);
    return lerp4(fine, coarse, f);
}

// mirrors hyrt_core::kernels::texture::interpolate_uv
// (`w` is hyrt_core::kernels::barycentric::bary_w, written out: `surface.wgsl`, which
// has it, is not part of every stage that samples.)
fn interpolate_uv(t: TriangleUvRecord, u: f32, v: f32) -> vec2<f32> {
    let w = (1.0 - u) - v;
    return vec2<f32>(
        rounded(rounded(mul(w, t.uv0.x) + mul(u, t.uv1.x)) + mul(v, t.uv2.x)),
        rounded(rounded(mul(w, t.uv0.y) + mul(u, t.uv1.y)) + mul(v, t.uv2.y)),
    );
}

// mirrors hyrt_core::kernels::texture::interpolate_color
fn interpolate_color(c0: vec4<f32>, c1: vec4<f32>, c2: vec4<f32>, u: f32, v: f32) -> vec4<f32> {
    let w = (1.0 - u) - v;
    return vec4<f32>(
        rounded(mul(w, c0.x) + mul(u, c1.x)) + mul(v, c2.x),
        rounded(mul(w, c0.y) + mul(u, c1.y)) + mul(v, c2.y),
        rounded(mul(w, c0.z) + mul(u, c1.z)) + mul(v, c2.z),
        rounded(mul(w, c0.w) + mul(u, c1.w)) + mul(v, c2.w),
    );
}

// mirrors hyrt_core::kernels::texture::alpha_at
fn alpha_at(tex: TextureRecord, uv: vec2<f32>) -> f32 {
    return sample_level(tex, 0u, uv, tex.mag_filter).w;
}

// mirrors hyrt_core::kernels::texture::alpha_passes
fn alpha_passes(alpha: f32, cutoff: f32) -> bool {
    return alpha >= cutoff;
}

// mirrors hyrt_core::kernels::texture::alpha_accepts: whether the alpha-tested triangle
// `tri` (global index `global`) is there at its barycentrics (u, v).
fn alpha_accepts(tri: TriangleRecord, global: u32, u: f32, v: f32) -> bool {
    let m = surface_material(tri.object);
    var a = m.base_alpha;
    if (m.flags & MAT_TEXTURED) != 0u {
        a = mul(a, alpha_at(surface_texture(m.texture), interpolate_uv(surface_uv(global), u, v)));
    }
    if (m.flags & MAT_VERTEX_COLORS) != 0u {
        let c = interpolate_color(surface_color(global, 0u), surface_color(global, 1u), surface_color(global, 2u), u, v);
        a = mul(a, c.w);
    }
    return alpha_passes(a, m.alpha_cutoff);
}
