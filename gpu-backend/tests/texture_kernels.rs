//! The WGSL texture kernels (`shaders/texture.wgsl`, `shaders/materials.wgsl`,
//! [`hyrt_gpu::texture::texture_wgsl`], [`hyrt_gpu::texture::materials_wgsl`]) against the
//! CPU's ([`hyrt_core::kernels::texture`]), reading the surface tables packed into one
//! buffer as the stages do ([`SurfaceBuffers`]): a compute shader evaluates, for each of
//! thousands of queries from a seeded generator, `sample_texture`, `sample_level` (nearest
//! and bilinear), `alpha_at`, `alpha_passes`, `alpha_accepts`, `hit_lod`, `interpolate_uv`,
//! `interpolate_color`, `wrap_coordinate` and `wrap_index` (every wrap mode), the shaded
//! object record (`shaded_object`, mirror of `Materials::at`) and `primary_cone`, and
//! every result must have the CPU kernel's bits.
//!
//! The textures cover odd, power-of-two and 1 x N sizes, every wrap mode on each axis,
//! every filter combination (magnification, minification, mip mapping or none) and the
//! mip chains of [`TextureSet::add`]; one of them holds every 8-bit code in every channel,
//! so the whole sRGB table and the alpha scale are checked. The materials combine every
//! flag (textured, vertex colours, alpha-tested) with random base alphas and cutoffs. The
//! queries reach coordinates in [-3, 3], huge ones (1e7, 1e30, f32::MAX), NaN and
//! infinities, texel centres and edges, levels of detail NaN, negative, zero, fractional,
//! halves and past the chain, cosines zero, negative, tiny and NaN, and cone widths zero,
//! infinite and NaN. (Interpolated NaN coordinates and colours match as NaN, whatever
//! their sign: [`passes_nan`].)

mod common;

use bytemuck::{Pod, Zeroable};
use common::test_context;
use hyrt_core::formats::wgsl::declarations;
use hyrt_core::formats::{
    FrameParams, MaterialRecord, ObjectRecord, SurfaceLayout, SurfaceRecord, TextureSet, TriangleRecord,
    TriangleUvRecord, FILTER_LINEAR, FILTER_NEAREST, INVALID_ID, MAT_ALPHA_TEST, MAT_EMISSIVE, MAT_METALLIC_ROUGHNESS,
    MAT_NORMAL, MAT_OCCLUSION, MAT_TEXTURED, MAT_VERTEX_COLORS, TEXEL_LINEAR, TEXEL_SRGB,
};
use hyrt_core::geometry::SurfaceTables;
use hyrt_core::glam::{Vec2, Vec3};
use hyrt_core::kernels::bounce::primary_cone;
use hyrt_core::kernels::texture::{self as cpu, Materials};
use hyrt_core::scene::texture::{Filter, Sampler, TextureImage, Wrap};
use hyrt_gpu::gpu_buffer::{read_back, storage, upload};
use hyrt_gpu::shader::{bind_buffers, shading_source, specialized_pipeline, storage_entry, uniform_entry};
use hyrt_gpu::texture::{materials_wgsl, texture_wgsl, Specialization, SurfaceBuffers};
use hyrt_gpu::GpuContext;
use wgpu::util::DeviceExt;

// ---------------------------------------------------------------------------------------------
// Queries and the shader that answers them
// ---------------------------------------------------------------------------------------------

/// Declare the query record in Rust and, from the same field list, in WGSL
/// (`QUERY_WGSL`): scalars only (`u32`, `i32`, `f32`, spelled alike in both), so the two
/// layouts are the same.
macro_rules! query_record {
    ($(#[$doc:meta])* struct $name:ident { $($(#[$field_doc:meta])* $field:ident: $ty:ident,)+ }) => {
        $(#[$doc])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug, Pod, Zeroable)]
        struct $name {
            $($(#[$field_doc])* $field: $ty,)+
        }

        /// The WGSL declaration of the query record.
        const QUERY_WGSL: &str =
            concat!("struct ", stringify!($name), " {\n", $("    ", stringify!($field), ": ", stringify!($ty), ",\n",)+ "}\n");
    };
}

query_record! {
    /// One query: the inputs of every kernel under test (96 bytes).
    struct Query {
        texture: u32,
        /// For `sample_level`: below the texture's level count.
        level: u32,
        u: f32,
        v: f32,
        lod: f32,
        bias: f32,
        cone: f32,
        cosine: f32,
        bary_u: f32,
        bary_v: f32,
        /// Index into the triangles' uv records and colours.
        triangle: u32,
        /// `wrap_index`'s integer index, texel count and `wrap_coordinate`'s coordinate.
        index: i32,
        count: u32,
        coord: f32,
        /// `alpha_passes`: the cutoff, and a free alpha tested against it.
        cutoff: f32,
        alpha: f32,
        /// `alpha_accepts` and `shaded_object`: the object (its material), with
        /// `triangle` as the triangle hit and `bary_u`, `bary_v` as the hit's barycentrics.
        object: u32,
        /// `shaded_object`: the geometric normal (also `primary_cone`'s vector to the eye)
        /// and the direction the surface is seen along.
        nx: f32,
        ny: f32,
        nz: f32,
        dx: f32,
        dy: f32,
        dz: f32,
        pad: u32,
    }
}
const _: () = assert!(std::mem::size_of::<Query>() == 96);

/// Words each query writes.
const RESULT_WORDS: usize = 44;

/// The frame's cone spread the queries' `primary_cone` and `secondary_parent` see.
const SPREAD: f32 = 0.0017;

/// The test's entry point, after the shading helpers, `shading.wgsl`, the texture
/// kernels and [`QUERY_WGSL`]. Results as bits: word layout in [`cpu_results`].
const ENTRY: &str = r#"
@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<storage, read> surface: array<u32>;
@group(0) @binding(2) var<uniform> surface_layout: SurfaceLayout;
@group(0) @binding(3) var<storage, read> queries: array<Query>;
@group(0) @binding(4) var<storage, read> objects: array<ObjectRecord>;
@group(0) @binding(5) var<storage, read_write> results: array<u32>;

fn put4(at: u32, x: vec4<f32>) {
    results[at] = bitcast<u32>(x.x);
    results[at + 1u] = bitcast<u32>(x.y);
    results[at + 2u] = bitcast<u32>(x.z);
    results[at + 3u] = bitcast<u32>(x.w);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = id.x;
    if k >= arrayLength(&queries) {
        return;
    }
    let q = queries[k];
    let tex = surface_texture(q.texture);
    let uv = vec2<f32>(q.u, q.v);
    let at = k * 44u;
    put4(at, sample_texture(tex, uv, q.lod));
    put4(at + 4u, sample_level(tex, q.level, uv, FILTER_NEAREST));
    put4(at + 8u, sample_level(tex, q.level, uv, FILTER_LINEAR));
    let alpha = alpha_at(tex, uv);
    results[at + 12u] = bitcast<u32>(alpha);
    results[at + 13u] = select(0u, 1u, alpha_passes(alpha, q.cutoff));
    results[at + 14u] = bitcast<u32>(hit_lod(q.bias, q.cone, q.cosine));
    let st = interpolate_uv(surface_uv(q.triangle), q.bary_u, q.bary_v);
    results[at + 15u] = bitcast<u32>(st.x);
    results[at + 16u] = bitcast<u32>(st.y);
    let c = interpolate_color(surface_color(q.triangle, 0u), surface_color(q.triangle, 1u),
        surface_color(q.triangle, 2u), q.bary_u, q.bary_v);
    put4(at + 17u, c);
    for (var wrap = 0u; wrap < 3u; wrap++) {
        results[at + 21u + wrap] = bitcast<u32>(wrap_coordinate(q.coord, wrap));
        results[at + 24u + wrap] = wrap_index(q.index, q.count, wrap);
    }
    results[at + 27u] = select(0u, 1u, alpha_passes(q.alpha, q.cutoff));
    let n = vec3<f32>(q.nx, q.ny, q.nz);
    var s: SurfaceRecord;
    s.object = q.object;
    s.triangle = q.triangle;
    s.geometric_normal = n;
    let obj = shaded_object(s, q.bary_u, q.bary_v, q.cone, vec3<f32>(q.dx, q.dy, q.dz));
    put4(at + 28u, vec4<f32>(obj.base_color, obj.metallic));
    put4(at + 34u, vec4<f32>(obj.roughness, obj.occlusion, obj.emissive.x, obj.emissive.y));
    results[at + 38u] = bitcast<u32>(obj.emissive.z);
    results[at + 39u] = bitcast<u32>(texture_lod(q.lod, surface_texture(0u), tex));
    var tri: TriangleRecord;
    tri.object = q.object;
    results[at + 32u] = select(0u, 1u, alpha_accepts(tri, q.triangle, q.bary_u, q.bary_v));
    results[at + 33u] = bitcast<u32>(primary_cone(n));
    s.normal = normalize_or_zero(n);
    let d = vec3<f32>(q.dx, q.dy, q.dz);
    let front = normal_mapped(s, q.bary_u, q.bary_v, q.cone, d, false).normal;
    results[at + 40u] = bitcast<u32>(front.x);
    results[at + 41u] = bitcast<u32>(front.y);
    results[at + 42u] = bitcast<u32>(front.z);
    results[at + 43u] = bitcast<u32>(normal_mapped(s, q.bary_u, q.bary_v, q.cone, d, true).normal.y);
}
"#;

/// The names of the result words, for failure messages.
fn word_name(word: usize) -> &'static str {
    match word {
        0..=3 => "sample_texture",
        4..=7 => "sample_level nearest",
        8..=11 => "sample_level linear",
        12 => "alpha_at",
        13 => "alpha_passes(alpha_at)",
        14 => "hit_lod",
        15 | 16 => "interpolate_uv",
        17..=20 => "interpolate_color",
        21..=23 => "wrap_coordinate",
        24..=26 => "wrap_index",
        27 => "alpha_passes",
        28..=31 | 34..=38 => "shaded_object",
        32 => "alpha_accepts",
        33 => "primary_cone",
        39 => "texture_lod",
        _ => "normal_mapped",
    }
}

/// Whether result word `word` comes from a kernel that passes NaN inputs through
/// (`interpolate_uv` and `interpolate_color` of texture coordinates and colours that are
/// NaN or infinite): there any NaN matches any NaN. IEEE 754 does not say which NaN an
/// addition of two NaNs returns, and a compiler may commute the operands (x86 returns the
/// first, so a generated NaN, `0 * inf`, and a stored one come out in either order); what
/// uses the results cannot tell (`wrap_coordinate` maps every non-finite coordinate to 0).
/// Every other word, and every non-NaN result, must have the CPU's bits.
fn passes_nan(word: usize) -> bool {
    (15..=20).contains(&word)
}

/// The CPU kernels on one query, as the shader writes them.
fn cpu_results(tables: &SurfaceTables, objects: &[ObjectRecord], q: &Query) -> [u32; RESULT_WORDS] {
    let mut r = [0u32; RESULT_WORDS];
    let set = &tables.textures;
    let tex = &set.records[q.texture as usize];
    let uv = Vec2::new(q.u, q.v);
    let mut put4 = |at: usize, x: [f32; 4]| {
        for (c, v) in x.iter().enumerate() {
            r[at + c] = v.to_bits();
        }
    };
    put4(0, cpu::sample_texture(&set.texels, tex, uv, q.lod));
    put4(4, cpu::sample_level(&set.texels, tex, q.level, uv, FILTER_NEAREST));
    put4(8, cpu::sample_level(&set.texels, tex, q.level, uv, FILTER_LINEAR));
    put4(17, cpu::interpolate_color(&tables.colors[q.triangle as usize], q.bary_u, q.bary_v));
    let materials = Materials { objects, surface: tables.view(), spread: SPREAD };
    let n = Vec3::new(q.nx, q.ny, q.nz);
    let s = SurfaceRecord { object: q.object, triangle: q.triangle, geometric_normal: n.into(), ..SurfaceRecord::MISS };
    let obj = materials.at(&s, q.bary_u, q.bary_v, q.cone, Vec3::new(q.dx, q.dy, q.dz));
    let [red, green, blue] = obj.base_color;
    put4(28, [red, green, blue, obj.metallic]);
    put4(34, [obj.roughness, obj.occlusion, obj.emissive[0], obj.emissive[1]]);
    r[38] = obj.emissive[2].to_bits();
    r[39] = cpu::texture_lod(q.lod, &set.records[0], tex).to_bits();
    let s = SurfaceRecord { normal: n.normalize_or_zero().into(), ..s };
    let d = Vec3::new(q.dx, q.dy, q.dz);
    let front = materials.normal_mapped(&s, q.bary_u, q.bary_v, q.cone, d, false).normal;
    (r[40], r[41], r[42]) = (front[0].to_bits(), front[1].to_bits(), front[2].to_bits());
    r[43] = materials.normal_mapped(&s, q.bary_u, q.bary_v, q.cone, d, true).normal[1].to_bits();
    let alpha = cpu::alpha_at(&set.texels, tex, uv);
    r[12] = alpha.to_bits();
    r[13] = cpu::alpha_passes(alpha, q.cutoff) as u32;
    r[14] = cpu::hit_lod(q.bias, q.cone, q.cosine).to_bits();
    let st = cpu::interpolate_uv(&tables.uvs[q.triangle as usize], q.bary_u, q.bary_v);
    (r[15], r[16]) = (st.x.to_bits(), st.y.to_bits());
    for wrap in 0..3 {
        r[21 + wrap] = cpu::wrap_coordinate(q.coord, wrap as u32).to_bits();
        r[24 + wrap] = cpu::wrap_index(q.index, q.count, wrap as u32);
    }
    r[27] = cpu::alpha_passes(q.alpha, q.cutoff) as u32;
    let tri = TriangleRecord { object: q.object, ..bytemuck::Zeroable::zeroed() };
    r[32] = cpu::alpha_accepts(&materials.surface, &tri, q.triangle as usize, q.bary_u, q.bary_v) as u32;
    r[33] = primary_cone(&materials, n).to_bits();
    r
}

/// Run the shader on `queries` and read the result words back.
fn gpu_results(ctx: &GpuContext, tables: &SurfaceTables, objects: &[ObjectRecord], queries: &[Query]) -> Vec<u32> {
    let source = shading_source(&format!("{}\n{}\n{QUERY_WGSL}{ENTRY}", texture_wgsl(), materials_wgsl()));
    assert!(source.starts_with(&declarations()), "assembled as the shading stages are");
    let entries = [
        uniform_entry(0),
        storage_entry(1, true),
        uniform_entry(2),
        storage_entry(3, true),
        storage_entry(4, true),
        storage_entry(5, false),
    ];
    // Compiled as the stages of a scene with surface tables and alpha tests are.
    let tables_and_alpha = Specialization { surface_tables: true, alpha_tested: true, ..Specialization::PLAIN };
    let (pipeline, layout) =
        specialized_pipeline(ctx, "texture kernels test", &source, &entries, &tables_and_alpha.constants());
    let params = ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("params"),
        contents: bytemuck::bytes_of(&FrameParams::new(1, 1, 0, 0.5).with_pixel_spread(SPREAD)),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let surface = SurfaceBuffers::new(ctx, tables, objects, Default::default());
    let query_buffer = upload(ctx, "queries", queries);
    let object_buffer = upload(ctx, "objects", objects);
    let words = queries.len() * RESULT_WORDS;
    let results = storage::<u32>(ctx, "results", words).expect("results buffer");
    // Garbage first: every word must be written.
    ctx.queue.write_buffer(&results, 0, &vec![0xA5u8; words * 4]);
    let group = bind_buffers(
        ctx,
        "texture kernels test",
        &layout,
        &[&params, surface.words.first(), &surface.layout, &query_buffer, &object_buffer, &results],
    );
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups((queries.len() as u32).div_ceil(64), 1, 1);
    }
    ctx.queue.submit([encoder.finish()]);
    read_back(ctx, &results, words).expect("readback")
}

// ---------------------------------------------------------------------------------------------
// Inputs
// ---------------------------------------------------------------------------------------------

/// SplitMix64: a small seeded generator, the same sequence everywhere.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: u32) -> u32 {
        (self.next_u64() % n as u64) as u32
    }

    /// Uniform in `[lo, hi)`.
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        let unit = (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * unit
    }

    fn pick<T: Copy>(&mut self, xs: &[T]) -> T {
        xs[self.below(xs.len() as u32) as usize]
    }
}

const WRAPS: [Wrap; 3] = [Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat];
const FILTERS: [Filter; 2] = [Filter::Nearest, Filter::Linear];

/// The textures: one per filter combination (magnification x minification x mip
/// mapping or none), the sizes cycling through odd, power-of-two and 1 x N ones, the
/// wrap modes through all nine (s, t) pairs; random texels. Then a 256 x 1 texture of
/// every code (channel `c` of texel `k` is a permutation of `k`), nearest, unmipped.
fn texture_set(rng: &mut Rng) -> TextureSet {
    let sizes = [(5, 3), (8, 8), (1, 7), (16, 4), (7, 1), (1, 1), (3, 5), (32, 16), (13, 9), (2, 2), (1, 16), (64, 1)];
    let mut set = TextureSet::default();
    let mut k = 0;
    for mag in FILTERS {
        for min in FILTERS {
            for mip in [None, Some(Filter::Nearest), Some(Filter::Linear)] {
                let (w, h) = sizes[k % sizes.len()];
                let texels = (0..w * h).map(|_| rng.next_u64().to_le_bytes()[..4].try_into().unwrap()).collect();
                let image = TextureImage::new(format!("t{k}"), w, h, texels).unwrap();
                let sampler = Sampler { wrap_s: WRAPS[k % 3], wrap_t: WRAPS[(k / 3) % 3], mag, min, mip };
                set.add(&image, &sampler, [TEXEL_SRGB, TEXEL_LINEAR][k % 2]);
                k += 1;
            }
        }
    }
    let codes = (0..256u32).map(|k| [k as u8, (255 - k) as u8, (k * 7 % 256) as u8, (k * 13 % 256) as u8]).collect();
    let image = TextureImage::new("codes".into(), 256, 1, codes).unwrap();
    let nearest = Sampler { mag: Filter::Nearest, min: Filter::Nearest, mip: None, ..Sampler::default() };
    set.add(&image, &nearest, TEXEL_SRGB);
    set.add(&image, &nearest, TEXEL_LINEAR);
    set.validate().unwrap();
    set
}

/// Special values of every float input.
const SPECIAL: [f32; 12] =
    [0.0, -0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, -f32::MAX, 1e-45, -1e-45, 1e-30, 1.0, -1.0];

/// A texture coordinate along an axis of `n` texels: in [-3, 3], huge, special, on a
/// texel centre or edge (of level 0 or a smaller level), or just beside 0 and 1.
fn coordinate(rng: &mut Rng, n: u32) -> f32 {
    match rng.below(10) {
        0..=2 => rng.range(-3.0, 3.0),
        3 => rng.pick(&[1e7, -1e7, 1e30, -1e30, 16777217.0, 8388608.5, 3.0e38, -2.5e7]),
        4 => rng.pick(&SPECIAL),
        5 | 6 => {
            // A texel centre of some level: (i + 0.5) / n_level, i over three periods.
            let n = (n >> rng.below(4)).max(1);
            let i = rng.below(3 * n) as i32 - n as i32;
            (i as f32 + 0.5) / n as f32
        }
        7 | 8 => {
            let n = (n >> rng.below(4)).max(1);
            let i = rng.below(3 * n + 1) as i32 - n as i32;
            i as f32 / n as f32
        }
        _ => rng.pick(&[1.0 - f32::EPSILON / 2.0, 1.0 + f32::EPSILON, -f32::EPSILON / 2.0, 0.5, 2.0, -2.0, 1e-7]),
    }
}

/// A level of detail: special, negative, zero, fractional, halves, integers, past the
/// chain.
fn lod(rng: &mut Rng, levels: u32) -> f32 {
    let top = levels as f32;
    match rng.below(8) {
        0 => rng.pick(&SPECIAL),
        1 => rng.range(-4.0, 0.0),
        2 | 3 => rng.range(0.0, top + 1.0),
        4 => rng.below(levels + 2) as f32,
        5 => rng.below(levels + 1) as f32 + 0.5,
        6 => rng.pick(&[top + 3.0, 40.0, 1e30, 0.5, 0.49999997, 1e-7, 2.0 - f32::EPSILON]),
        _ => rng.below(levels) as f32 + rng.pick(&[f32::EPSILON, -f32::EPSILON, 0.25, 0.75]),
    }
}

/// A cosine between a ray and a normal: zero, negative, tiny, NaN, or any in [-1, 1].
fn cosine(rng: &mut Rng) -> f32 {
    match rng.below(4) {
        0 => rng.pick(&[0.0, -0.0, 1e-38, -1e-38, 1e-6, 1.0 / 8192.0, -1.0 / 8192.0, 1.0 / 8191.0, f32::NAN, -1.0]),
        1 => rng.pick(&SPECIAL),
        _ => rng.range(-1.0, 1.0),
    }
}

/// A cone width at a hit: zero, infinite, NaN, negative, tiny or spread over ten decades.
fn cone(rng: &mut Rng) -> f32 {
    match rng.below(4) {
        0 => rng.pick(&[0.0, -0.0, f32::INFINITY, f32::NAN, -1.0, 1e-45, 1e-38, f32::MAX, 1.0 / 256.0]),
        _ => 10f32.powf(rng.range(-8.0, 2.0)),
    }
}

/// A barycentric coordinate: mostly in [0, 1], with the corners, edges and a few
/// outside.
fn barycentric(rng: &mut Rng) -> f32 {
    match rng.below(4) {
        0 => rng.pick(&[0.0, 1.0, 0.5, 1.0 / 3.0, -0.0, 1e-8, 1.0 - f32::EPSILON / 2.0, -0.25, 1.5]),
        _ => rng.range(0.0, 1.0),
    }
}

/// Triangles' texture coordinates (in [-3, 3], with some huge and special ones, and a
/// level-of-detail bias over twenty levels) and vertex colours (in [0, 1], some beyond).
fn triangles(rng: &mut Rng, count: usize) -> (Vec<TriangleUvRecord>, Vec<[[f32; 4]; 3]>) {
    fn value(rng: &mut Rng) -> f32 {
        match rng.below(8) {
            0 => rng.pick(&[1e7, -1e30, 0.0, -0.0, 1.0, f32::NAN, f32::INFINITY]),
            _ => rng.range(-3.0, 3.0),
        }
    }
    let uvs = (0..count)
        .map(|_| TriangleUvRecord {
            uv0: [value(rng), value(rng)],
            uv1: [value(rng), value(rng)],
            uv2: [value(rng), value(rng)],
            lod_bias: rng.range(-5.0, 15.0),
            pad: 0,
        })
        .collect();
    let colors = (0..count)
        .map(|_| {
            std::array::from_fn(|_| {
                std::array::from_fn(|_| if rng.below(8) == 0 { rng.range(-1.0, 4.0) } else { rng.range(0.0, 1.0) })
            })
        })
        .collect();
    (uvs, colors)
}

/// Each triangle's corner tangents: random directions (some zero, some long) with either
/// bitangent sign.
fn tangents(rng: &mut Rng, count: usize) -> Vec<[[f32; 4]; 3]> {
    (0..count)
        .map(|_| {
            std::array::from_fn(|_| {
                let d = if rng.below(10) == 0 { Vec3::ZERO } else { direction(rng) * rng.range(0.5, 2.0) };
                [d.x, d.y, d.z, if rng.below(2) == 0 { 1.0 } else { -1.0 }]
            })
        })
        .collect()
}

/// The materials (one per object): every combination of the flags, each texture slot
/// cycling through the textures (of both encodings and different sizes, so the levels
/// of detail shift), with base alphas, cutoffs and occlusion strengths in [0, 1] (some 0
/// and 1); and the objects, with random base colours, factors and emission.
fn materials(rng: &mut Rng, textures: u32, count: u32) -> (Vec<MaterialRecord>, Vec<ObjectRecord>) {
    let unit = |rng: &mut Rng| if rng.below(4) == 0 { rng.pick(&[0.0, 1.0, 0.5]) } else { rng.range(0.0, 1.0) };
    let materials = (0..count)
        .map(|k| {
            let bits = [
                MAT_TEXTURED,
                MAT_VERTEX_COLORS,
                MAT_ALPHA_TEST,
                MAT_METALLIC_ROUGHNESS,
                MAT_OCCLUSION,
                MAT_EMISSIVE,
                MAT_NORMAL,
            ];
            let flags = bits.iter().enumerate().fold(0, |f, (bit, m)| f | if (k >> bit) & 1 != 0 { *m } else { 0 });
            let slot = |flag: u32, shift: u32| if flags & flag != 0 { (k + shift) % textures } else { INVALID_ID };
            let (texture, metallic_roughness, occlusion, emissive) =
                (slot(MAT_TEXTURED, 0), slot(MAT_METALLIC_ROUGHNESS, 3), slot(MAT_OCCLUSION, 5), slot(MAT_EMISSIVE, 7));
            let normal = slot(MAT_NORMAL, 11);
            let uv_texture = [texture, metallic_roughness, occlusion, emissive, normal]
                .into_iter()
                .find(|&t| t != INVALID_ID)
                .unwrap_or(INVALID_ID);
            let record = MaterialRecord {
                texture,
                flags,
                base_alpha: unit(rng),
                alpha_cutoff: if flags & MAT_ALPHA_TEST != 0 { unit(rng) } else { 0.0 },
                metallic_roughness,
                occlusion,
                emissive,
                occlusion_strength: unit(rng),
                uv_texture,
                normal,
                normal_scale: rng.range(-2.0, 2.0),
            };
            record.validate(textures as usize).unwrap();
            record
        })
        .collect();
    let objects = (0..count)
        .map(|_| ObjectRecord {
            base_color: std::array::from_fn(|_| rng.range(0.0, 1.0)),
            metallic: rng.range(0.0, 1.0),
            roughness: unit(rng),
            emissive: std::array::from_fn(|_| rng.range(0.0, 4.0)),
            occlusion: unit(rng),
            ..bytemuck::Zeroable::zeroed()
        })
        .collect();
    (materials, objects)
}

/// A unit vector in a random direction, or (rarely) a special one: an axis, a vector
/// with a zero or NaN component, a long one.
fn direction(rng: &mut Rng) -> Vec3 {
    match rng.below(8) {
        0 => rng.pick(&[Vec3::X, Vec3::NEG_Y, Vec3::new(0.0, -0.0, 1.0), Vec3::new(3.0, 4.0, 0.0), Vec3::ZERO]),
        1 => Vec3::new(rng.range(-1.0, 1.0), f32::NAN, 0.5),
        _ => Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)).normalize_or_zero(),
    }
}

/// `per_texture` random queries for each texture, and one at each texel centre of the
/// texture of every code (the last one), over `triangles` triangles and `objects` objects.
fn queries(rng: &mut Rng, set: &TextureSet, triangles: u32, objects: u32, per_texture: usize) -> Vec<Query> {
    let mut out = Vec::new();
    let codes = set.records.len() as u32 - 1;
    for texture in 0..set.records.len() as u32 {
        let tex = set.records[texture as usize];
        let n = if texture == codes { 256 } else { per_texture };
        for k in 0..n {
            let (u, v) = if texture == codes {
                ((k as f32 + 0.5) / 256.0, 0.5)
            } else {
                (coordinate(rng, tex.width), coordinate(rng, tex.height))
            };
            let count = rng.pick(&[1, 2, 3, 4, 5, 7, 8, 16, 17, 16384]);
            let index = match rng.below(6) {
                0 => rng.pick(&[i32::MIN, i32::MAX, -1, 0, -32768, 32768]),
                _ => rng.below(4 * count.min(64) + 2) as i32 - 2 * count.min(64) as i32 - 1,
            };
            let levels = tex.levels;
            let (n, d) = (direction(rng), direction(rng));
            out.push(Query {
                texture,
                level: rng.below(levels),
                u,
                v,
                lod: lod(rng, levels),
                bias: match rng.below(6) {
                    0 => rng.pick(&SPECIAL),
                    _ => rng.range(-5.0, 20.0),
                },
                cone: cone(rng),
                cosine: cosine(rng),
                bary_u: barycentric(rng),
                bary_v: barycentric(rng),
                triangle: rng.below(triangles),
                index,
                count,
                coord: coordinate(rng, count),
                cutoff: match rng.below(2) {
                    0 => rng.pick(&[0.0, 0.5, 1.0, 0.25, 1.0 / 255.0, 128.0 / 255.0]),
                    _ => rng.range(0.0, 1.0),
                },
                alpha: match rng.below(3) {
                    0 => rng.pick(&SPECIAL),
                    _ => rng.below(256) as f32 * cpu::UNORM8_SCALE,
                },
                object: rng.below(objects),
                nx: n.x,
                ny: n.y,
                nz: n.z,
                dx: d.x,
                dy: d.y,
                dz: d.z,
                pad: 0,
            });
        }
    }
    out
}

/// The generator reaches the cases the kernels branch on (a change of its draws that
/// lost one fails here, not silently).
fn assert_reaches_the_edge_cases(set: &TextureSet, queries: &[Query]) {
    let count = |f: &dyn Fn(&Query) -> bool| queries.iter().filter(|q| f(q)).count();
    let top = |q: &Query| (set.records[q.texture as usize].levels - 1) as f32;
    let cases = [
        ("lod NaN", count(&|q| q.lod.is_nan())),
        ("lod negative", count(&|q| q.lod < 0.0)),
        ("lod zero", count(&|q| q.lod == 0.0)),
        ("lod fractional", count(&|q| q.lod > 0.0 && q.lod < top(q) && q.lod.fract() != 0.0)),
        ("lod a half", count(&|q| q.lod.fract() == 0.5)),
        ("lod past the chain", count(&|q| q.lod > top(q) && top(q) > 0.0)),
        ("uv NaN", count(&|q| q.u.is_nan() || q.v.is_nan())),
        ("uv infinite", count(&|q| q.u.is_infinite() || q.v.is_infinite())),
        ("uv huge", count(&|q| q.u.abs() >= 1e7 && q.u.is_finite())),
        ("uv beyond 1e30", count(&|q| q.u.abs() >= 1e30 && q.u.is_finite())),
        ("uv on a texel centre", count(&|q| (q.u * set.records[q.texture as usize].width as f32).fract() == 0.5)),
        ("uv on a texel edge", count(&|q| (q.u * set.records[q.texture as usize].width as f32).fract() == 0.0)),
        ("repeat rounds to 1", count(&|q| q.coord < 0.0 && q.coord - q.coord.floor() >= 1.0)),
        ("cosine zero", count(&|q| q.cosine == 0.0)),
        ("cosine negative", count(&|q| q.cosine < 0.0)),
        ("cosine tiny", count(&|q| q.cosine != 0.0 && q.cosine.abs() < cpu::LOD_MIN_COSINE)),
        ("cone zero", count(&|q| q.cone == 0.0)),
        ("cone infinite", count(&|q| q.cone.is_infinite())),
        ("index beyond a period", count(&|q| q.index < 0 || q.index >= 2 * q.count as i32)),
    ];
    let missing: Vec<_> = cases.iter().filter(|(_, n)| *n == 0).map(|(name, _)| name).collect();
    assert!(missing.is_empty(), "the queries never reach: {missing:?}");
}

// ---------------------------------------------------------------------------------------------
// Test
// ---------------------------------------------------------------------------------------------

#[test]
fn texture_kernels_match_cpu_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let mut rng = Rng(0x7e87_04e5);
    let set = texture_set(&mut rng);
    let (uvs, colors) = triangles(&mut rng, 97);
    let (materials, objects) = materials(&mut rng, set.records.len() as u32, 128);
    let tangents = tangents(&mut rng, uvs.len());
    let tables = SurfaceTables { textures: set, materials, uvs, colors, tangents };
    let queries = queries(&mut rng, &tables.textures, tables.uvs.len() as u32, objects.len() as u32, 400);
    assert_reaches_the_edge_cases(&tables.textures, &queries);
    let gpu = gpu_results(&ctx, &tables, &objects, &queries);
    let mut failures = Vec::new();
    // Per kernel: how many words differ, how many of those on queries with a subnormal
    // input (a device that flushes subnormals differs there: its float probe says so),
    // and the first difference.
    let mut per_kernel = std::collections::BTreeMap::<&str, (usize, usize, usize)>::new();
    let mut first = std::collections::BTreeMap::<&str, String>::new();
    let mut accepted = 0;
    for (k, q) in queries.iter().enumerate() {
        let want = cpu_results(&tables, &objects, q);
        accepted += want[32] as usize;
        let got = &gpu[k * RESULT_WORDS..(k + 1) * RESULT_WORDS];
        for (word, (&g, &c)) in got.iter().zip(&want).enumerate() {
            if g != c && !(passes_nan(word) && f32::from_bits(g).is_nan() && f32::from_bits(c).is_nan()) {
                let entry = per_kernel.entry(word_name(word)).or_default();
                let subnormal = has_subnormal_input(q);
                let nans = f32::from_bits(g).is_nan() && f32::from_bits(c).is_nan();
                entry.0 += 1;
                entry.1 += subnormal as usize;
                entry.2 += nans as usize;
                failures.push(format!(
                    "query {k} word {word} ({}): gpu {g:#010x} ({}) cpu {c:#010x} ({}), {q:?}, texture {:?}, material {:?}",
                    word_name(word),
                    f32::from_bits(g),
                    f32::from_bits(c),
                    tables.textures.records[q.texture as usize],
                    tables.materials[q.object as usize],
                ));
                // The first difference of each kernel that neither a subnormal input nor a
                // NaN's bits explain ("plain"), else the first of any kind.
                let text = failures.last().cloned().unwrap_or_default();
                if !subnormal && !nans {
                    first.entry(word_name(word)).and_modify(|t| {
                        if !t.starts_with("plain") {
                            *t = format!("plain {text}");
                        }
                    });
                    first.entry(word_name(word)).or_insert_with(|| format!("plain {text}"));
                } else {
                    first.entry(word_name(word)).or_insert(text);
                }
            }
        }
    }
    eprintln!(
        "{} queries on {} textures ({} texels) and {} materials, {} result words compared, {} differ",
        queries.len(),
        tables.textures.records.len(),
        tables.textures.texels.len(),
        tables.materials.len(),
        queries.len() * RESULT_WORDS,
        failures.len()
    );
    // Both answers of the alpha test are reached.
    assert!(accepted > queries.len() / 10 && accepted < queries.len() * 9 / 10, "{accepted} accepted");
    assert!(
        failures.is_empty(),
        "{} words differ (per kernel: differing, of which with a subnormal input, of which NaN against NaN: {per_kernel:?}); the first per kernel (\"plain\" where neither explains it): {:#?}",
        failures.len(),
        first.values().collect::<Vec<_>>()
    );
}

/// Whether a query holds a subnormal float input.
fn has_subnormal_input(q: &Query) -> bool {
    [
        q.u, q.v, q.lod, q.bias, q.cone, q.cosine, q.bary_u, q.bary_v, q.coord, q.cutoff, q.alpha, q.nx, q.ny, q.nz,
        q.dx, q.dy, q.dz,
    ]
    .iter()
    .any(|x| x.is_subnormal())
}

#[test]
fn a_scene_without_surface_tables_binds_one_dummy_word_and_the_zero_layout() {
    let Some(ctx) = test_context() else { return };
    let empty = SurfaceBuffers::new(&ctx, &SurfaceTables::default(), &[], Default::default());
    assert_eq!((empty.record, empty.specialization), (SurfaceLayout::default(), Specialization::PLAIN));
    let layout = std::mem::size_of::<SurfaceLayout>() as u64;
    assert_eq!((empty.words.size(), empty.layout.size()), (4, layout), "bindings cannot be empty");
}
