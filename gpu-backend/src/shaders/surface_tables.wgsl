// The surface tables of a scene (hyrt_core::geometry::SurfaceTables: per-object material
// records and first triangles, per-triangle texture coordinates and vertex colours,
// texture records, the sRGB decoding table and texels), packed into one storage buffer of
// words as hyrt_core::formats::SurfaceLayout says: each record's fields in order, f32
// fields as their bits. These accessors rebuild the records from the words, so the
// kernels read the tables as the CPU's hyrt_core::kernels::texture::SurfaceView does.
//
// Prepended by `hyrt_gpu::texture::texture_wgsl` after the generated records and a
// generated prelude with the records' sizes in words (MATERIAL_WORDS, TRIANGLE_UV_WORDS,
// TRIANGLE_COLOR_WORDS, TEXTURE_WORDS, from the Rust sizes). The including stage binds
// `surface: array<u32>` and `surface_layout: SurfaceLayout` (a uniform). A scene without
// surface tables binds one word and the zero layout, and its pipelines are specialized
// with both constants below false (`hyrt_gpu::texture::Specialization`): every read of
// the tables is behind one of them, so those pipelines never read the word, and the
// driver removes the code that would.

// The scene has surface tables: shading reads each point's shaded object record
// (hyrt_core::kernels::texture::Materials::varying).
override SURFACE_TABLES: bool = false;
// Some material is alpha-tested: hits on TRI_ALPHA_TEST triangles are alpha-tested.
override ALPHA_TESTED: bool = false;

fn surface_f32(at: u32) -> f32 {
    return bitcast<f32>(surface[at]);
}

// `SurfaceView::materials[object]`
fn surface_material(object: u32) -> MaterialRecord {
    let at = surface_layout.materials + MATERIAL_WORDS * object;
    return MaterialRecord(surface[at], surface[at + 1u], surface_f32(at + 2u), surface_f32(at + 3u),
        surface[at + 4u], surface[at + 5u], surface[at + 6u], surface_f32(at + 7u), surface[at + 8u],
        surface[at + 9u], surface_f32(at + 10u));
}

// mirrors hyrt_core::geometry::WorldGeometry::global_triangle: the global index of the
// triangle record `t` (its object's first triangle, packed beside the materials, plus its
// index within the object).
fn global_triangle(t: TriangleRecord) -> u32 {
    return surface[surface_layout.first_triangles + t.object] + t.triangle;
}

// `SurfaceView::uvs[triangle]` (global triangle index)
fn surface_uv(triangle: u32) -> TriangleUvRecord {
    let at = surface_layout.uvs + TRIANGLE_UV_WORDS * triangle;
    return TriangleUvRecord(
        vec2<f32>(surface_f32(at), surface_f32(at + 1u)),
        vec2<f32>(surface_f32(at + 2u), surface_f32(at + 3u)),
        vec2<f32>(surface_f32(at + 4u), surface_f32(at + 5u)),
        surface_f32(at + 6u),
        surface[at + 7u],
    );
}

// `SurfaceView::colors[triangle][corner]`: a corner's linear RGBA vertex colour.
fn surface_color(triangle: u32, corner: u32) -> vec4<f32> {
    let at = surface_layout.colors + TRIANGLE_COLOR_WORDS * triangle + 4u * corner;
    return vec4<f32>(surface_f32(at), surface_f32(at + 1u), surface_f32(at + 2u), surface_f32(at + 3u));
}

// `SurfaceView::tangents[triangle][corner]`: a corner's world tangent and bitangent sign.
fn surface_tangent(triangle: u32, corner: u32) -> vec4<f32> {
    let at = surface_layout.tangents + TRIANGLE_TANGENT_WORDS * triangle + 4u * corner;
    return vec4<f32>(surface_f32(at), surface_f32(at + 1u), surface_f32(at + 2u), surface_f32(at + 3u));
}

// `SurfaceView::textures[index]`
fn surface_texture(index: u32) -> TextureRecord {
    let at = surface_layout.textures + TEXTURE_WORDS * index;
    return TextureRecord(surface[at], surface[at + 1u], surface[at + 2u], surface[at + 3u], surface[at + 4u],
        surface[at + 5u], surface[at + 6u], surface[at + 7u], surface[at + 8u], surface[at + 9u]);
}

// `hyrt_core::kernels::texture::srgb8_table()[code]`: the linear value of an sRGB code.
fn surface_srgb8(code: u32) -> f32 {
    return surface_f32(surface_layout.srgb + code);
}

// `SurfaceView::texels[index]`: a packed RGBA8 texel (hyrt_core::formats::pack_texel).
fn surface_texel(index: u32) -> u32 {
    return surface[surface_layout.texels + index];
}
