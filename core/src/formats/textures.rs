//! The texture formats a frame holds only when its scene's materials use them: every
//! sampled image with its mip chain in one texel array, one [`TextureRecord`] per
//! (image, sampler) pair, one [`MaterialRecord`] per object and one [`TriangleUvRecord`] per
//! triangle. A scene without textures, vertex colours or alpha-tested materials has none of
//! them ([`TextureSet::is_empty`]) and its frame is the frame it was before textures.
//!
//! Texels are RGBA8 packed in a `u32` (`r | g << 8 | b << 16 | a << 24`), RGB sRGB-encoded
//! (colours: base colour, emission) or linear (data: metallic-roughness, occlusion) as the
//! record's [`TextureRecord::encoding`] says, alpha linear; [`crate::kernels::texture`]
//! decodes them. Level `k + 1` of a chain is `max(1, floor(w / 2)) x max(1, floor(h / 2))`
//! texels, each the mean, in linear values, of the (up to) 2 x 2 texels of level `k` it
//! covers ([`mip_chain`]); the levels of a texture follow each other in
//! [`TextureSet::texels`], level 0 first.

use bytemuck::{Pod, Zeroable};

use super::wgsl::wgsl_struct;
use super::INVALID_ID;
use crate::scene::texture::{Filter, Sampler, TextureImage};

/// [`TextureRecord::wrap_s`], [`TextureRecord::wrap_t`]: `REPEAT`.
pub const WRAP_REPEAT: u32 = 0;
/// `CLAMP_TO_EDGE`.
pub const WRAP_CLAMP: u32 = 1;
/// `MIRRORED_REPEAT`.
pub const WRAP_MIRROR: u32 = 2;

/// [`TextureRecord::mag_filter`], [`TextureRecord::min_filter`], [`TextureRecord::mip_filter`]:
/// the nearest texel (level).
pub const FILTER_NEAREST: u32 = 0;
/// Bilinear within a level, linear between levels.
pub const FILTER_LINEAR: u32 = 1;
/// [`TextureRecord::mip_filter`]: no mip mapping, level 0 only.
pub const FILTER_NO_MIP: u32 = 2;

/// [`TextureRecord::encoding`]: RGB are sRGB-encoded colours (glTF base colour and
/// emissive textures).
pub const TEXEL_SRGB: u32 = 0;
/// RGB are linear values, `code / 255` (glTF metallic-roughness and occlusion textures).
pub const TEXEL_LINEAR: u32 = 1;

/// One sampled texture: where its levels are and how it is sampled.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `first_texel` | u32 | index of level 0's first texel in [`TextureSet::texels`] |
/// | 4 | `width` | u32 | level 0's width, 1..=16384 |
/// | 8 | `height` | u32 | level 0's height, 1..=16384 |
/// | 12 | `levels` | u32 | mip levels stored (1 when the sampler does not mip map) |
/// | 16 | `wrap_s` | u32 | `WRAP_*` along u |
/// | 20 | `wrap_t` | u32 | `WRAP_*` along v |
/// | 24 | `mag_filter` | u32 | `FILTER_NEAREST` or `FILTER_LINEAR` |
/// | 28 | `min_filter` | u32 | `FILTER_NEAREST` or `FILTER_LINEAR` |
/// | 32 | `mip_filter` | u32 | `FILTER_NEAREST`, `FILTER_LINEAR` or `FILTER_NO_MIP` |
/// | 36 | `encoding` | u32 | [`TEXEL_SRGB`] or [`TEXEL_LINEAR`]: how RGB decode |
///
/// 40 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct TextureRecord {
    pub first_texel: u32,
    pub width: u32,
    pub height: u32,
    pub levels: u32,
    pub wrap_s: u32,
    pub wrap_t: u32,
    pub mag_filter: u32,
    pub min_filter: u32,
    pub mip_filter: u32,
    pub encoding: u32,
}
const _: () = assert!(std::mem::size_of::<TextureRecord>() == 40);
wgsl_struct!(TextureRecord {
    first_texel,
    width,
    height,
    levels,
    wrap_s,
    wrap_t,
    mag_filter,
    min_filter,
    mip_filter,
    encoding
});

impl TextureRecord {
    /// Width and height of level `level` (`max(1, side >> level)`).
    #[inline]
    pub fn level_size(&self, level: u32) -> (u32, u32) {
        ((self.width >> level).max(1), (self.height >> level).max(1))
    }

    /// Index in [`TextureSet::texels`] of level `level`'s first texel.
    #[inline]
    pub fn level_offset(&self, level: u32) -> u32 {
        let mut at = self.first_texel;
        for k in 0..level {
            let (w, h) = self.level_size(k);
            at += w * h;
        }
        at
    }

    /// Texels of all its levels.
    pub fn texel_count(&self) -> u64 {
        (0..self.levels).map(|k| self.level_size(k)).map(|(w, h)| w as u64 * h as u64).sum()
    }

    /// Check: sides in range, levels no more than the chain has, known codes.
    pub fn validate(&self) -> Result<(), String> {
        let side = 1..=TextureImage::MAX_SIDE;
        let full_chain = 32 - self.width.max(self.height).leading_zeros();
        if !side.contains(&self.width) || !side.contains(&self.height) || self.levels == 0 || self.levels > full_chain {
            return Err(format!("texture record with bad size or level count: {self:?}"));
        }
        let wraps = [self.wrap_s, self.wrap_t].iter().all(|&w| w <= WRAP_MIRROR);
        let filters =
            self.mag_filter <= FILTER_LINEAR && self.min_filter <= FILTER_LINEAR && self.mip_filter <= FILTER_NO_MIP;
        let codes = wraps && filters && self.encoding <= TEXEL_LINEAR;
        if !codes || (self.mip_filter == FILTER_NO_MIP && self.levels != 1) {
            return Err(format!("texture record with unknown codes: {self:?}"));
        }
        Ok(())
    }
}

/// [`MaterialRecord::flags`]: the base colour is multiplied by [`MaterialRecord::texture`].
pub const MAT_TEXTURED: u32 = 1 << 0;
/// The base colour is multiplied by the interpolated vertex colour.
pub const MAT_VERTEX_COLORS: u32 = 1 << 1;
/// Alpha-tested: texels whose alpha is below [`MaterialRecord::alpha_cutoff`] are holes.
pub const MAT_ALPHA_TEST: u32 = 1 << 2;
/// Metallic and roughness are multiplied by [`MaterialRecord::metallic_roughness`]'s blue
/// and green.
pub const MAT_METALLIC_ROUGHNESS: u32 = 1 << 3;
/// The occlusion is [`MaterialRecord::occlusion`]'s red, blended towards 1 by
/// [`MaterialRecord::occlusion_strength`].
pub const MAT_OCCLUSION: u32 = 1 << 4;
/// The emission is multiplied by [`MaterialRecord::emissive`]'s colour.
pub const MAT_EMISSIVE: u32 = 1 << 5;
/// The shading normal comes from [`MaterialRecord::normal`] in the triangle's tangent
/// frame ([`crate::geometry::SurfaceTables::tangents`]).
pub const MAT_NORMAL: u32 = 1 << 6;
/// Every `MAT_*` flag that samples a texture at the triangle's texture coordinates.
pub const MAT_ANY_TEXTURE: u32 = MAT_TEXTURED | MAT_METALLIC_ROUGHNESS | MAT_OCCLUSION | MAT_EMISSIVE | MAT_NORMAL;

/// What an object's material adds to [`super::ObjectRecord`] when the scene has textures,
/// vertex colours or alpha tests; one per object, indexed by object id.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `texture` | u32 | index of its base-colour [`TextureRecord`], [`INVALID_ID`] without one |
/// | 4 | `flags` | u32 | `MAT_*` |
/// | 8 | `base_alpha` | f32 | the base-colour factor's alpha, [0, 1] |
/// | 12 | `alpha_cutoff` | f32 | the alpha test's cutoff ([0, 1]; 0 without [`MAT_ALPHA_TEST`]) |
/// | 16 | `metallic_roughness` | u32 | its metallic-roughness texture ([`TEXEL_LINEAR`]), [`INVALID_ID`] without [`MAT_METALLIC_ROUGHNESS`] |
/// | 20 | `occlusion` | u32 | its occlusion texture ([`TEXEL_LINEAR`]), [`INVALID_ID`] without [`MAT_OCCLUSION`] |
/// | 24 | `emissive` | u32 | its emissive texture ([`TEXEL_SRGB`]), [`INVALID_ID`] without [`MAT_EMISSIVE`] |
/// | 28 | `occlusion_strength` | f32 | glTF `occlusionTexture.strength`, [0, 1] |
/// | 32 | `uv_texture` | u32 | the texture whose size the triangles' [`TriangleUvRecord::lod_bias`] is computed for, [`INVALID_ID`] without textures |
/// | 36 | `normal` | u32 | its normal texture ([`TEXEL_LINEAR`]), [`INVALID_ID`] without [`MAT_NORMAL`] |
/// | 40 | `normal_scale` | f32 | glTF `normalTexture.scale`, finite |
///
/// 44 bytes. All its textures are sampled at the same coordinates, [`TriangleUvRecord`];
/// one whose size differs from `uv_texture`'s shifts the level of detail by
/// [`crate::kernels::texture::texture_lod`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct MaterialRecord {
    pub texture: u32,
    pub flags: u32,
    pub base_alpha: f32,
    pub alpha_cutoff: f32,
    pub metallic_roughness: u32,
    pub occlusion: u32,
    pub emissive: u32,
    pub occlusion_strength: f32,
    pub uv_texture: u32,
    pub normal: u32,
    pub normal_scale: f32,
}
const _: () = assert!(std::mem::size_of::<MaterialRecord>() == 44);
wgsl_struct!(MaterialRecord {
    texture,
    flags,
    base_alpha,
    alpha_cutoff,
    metallic_roughness,
    occlusion,
    emissive,
    occlusion_strength,
    uv_texture,
    normal,
    normal_scale
});

impl MaterialRecord {
    /// An untextured, opaque material without vertex colours.
    pub const PLAIN: MaterialRecord = MaterialRecord {
        texture: INVALID_ID,
        flags: 0,
        base_alpha: 1.0,
        alpha_cutoff: 0.0,
        metallic_roughness: INVALID_ID,
        occlusion: INVALID_ID,
        emissive: INVALID_ID,
        occlusion_strength: 1.0,
        uv_texture: INVALID_ID,
        normal: INVALID_ID,
        normal_scale: 1.0,
    };

    /// Check: known flags, each texture exactly when its flag is set, `uv_texture` one of
    /// them exactly when any is, alpha, cutoff and strength in [0, 1].
    pub fn validate(&self, textures: usize) -> Result<(), String> {
        let slot = |flag: u32, t: u32| if self.flags & flag != 0 { (t as usize) < textures } else { t == INVALID_ID };
        let slots = slot(MAT_TEXTURED, self.texture)
            && slot(MAT_METALLIC_ROUGHNESS, self.metallic_roughness)
            && slot(MAT_OCCLUSION, self.occlusion)
            && slot(MAT_EMISSIVE, self.emissive)
            && slot(MAT_NORMAL, self.normal);
        let used = [self.texture, self.metallic_roughness, self.occlusion, self.emissive, self.normal];
        let uv_ok = if self.flags & MAT_ANY_TEXTURE != 0 {
            used.contains(&self.uv_texture) && self.uv_texture != INVALID_ID
        } else {
            self.uv_texture == INVALID_ID
        };
        let unit = 0.0..=1.0;
        if self.flags & !(MAT_ANY_TEXTURE | MAT_VERTEX_COLORS | MAT_ALPHA_TEST) != 0
            || !slots
            || !uv_ok
            || !unit.contains(&self.base_alpha)
            || !unit.contains(&self.alpha_cutoff)
            || !unit.contains(&self.occlusion_strength)
            || !self.normal_scale.is_finite()
        {
            return Err(format!("material record with unknown flags, textures or factors: {self:?}"));
        }
        Ok(())
    }
}

/// A triangle's texture coordinates (the set its material's texture uses, with the
/// material's `KHR_texture_transform` applied) and the level-of-detail constant of ray
/// cones, [`crate::kernels::texture::triangle_lod_bias`]; zeros for a triangle whose
/// material has no texture.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `uv0` | [f32; 2] | at vertex 0 |
/// | 8 | `uv1` | [f32; 2] | at vertex 1 |
/// | 16 | `uv2` | [f32; 2] | at vertex 2 |
/// | 24 | `lod_bias` | f32 | `0.5 log2(texel area / world area)` |
/// | 28 | `pad` | u32 | zero |
///
/// 32 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TriangleUvRecord {
    pub uv0: [f32; 2],
    pub uv1: [f32; 2],
    pub uv2: [f32; 2],
    pub lod_bias: f32,
    pub pad: u32,
}
const _: () = assert!(std::mem::size_of::<TriangleUvRecord>() == 32);
wgsl_struct!(TriangleUvRecord { uv0, uv1, uv2, lod_bias, pad });

/// Where each table of [`crate::geometry::SurfaceTables`] lies in the one storage buffer the
/// GPU binds them all in (`surface: array<u32>`, one binding, so that stages near the
/// per-stage limit of storage buffers add only one). The tables follow each other as
/// consecutive u32 words, each record's fields in declaration order and f32 fields as
/// their bits:
///
/// 1. the [`MaterialRecord`]s (11 words each, one per object);
/// 2. each object's first global triangle (1 word each,
///    [`super::ObjectRecord::first_triangle`]): with it the alpha test finds a triangle
///    record's global index (`WorldGeometry::global_triangle`) in `shadow_rays`, whose 8
///    storage buffers on a WebGPU-default device leave no room for the BVH's
///    leaf-to-triangle table;
/// 3. the [`TriangleUvRecord`]s (8 words, one per triangle);
/// 4. the vertex colours (12 words per triangle: its three corners' linear RGBA);
/// 5. the world-space tangents (12 words per triangle: its three corners' `xyz`, unit,
///    and `w`, the bitangent's sign), when some material has a normal map;
/// 6. the [`TextureRecord`]s (10 words each);
/// 7. the sRGB decoding table, [`crate::kernels::texture::srgb8_table`] (256 f32), when
///    there are textures: read from the buffer where a shader samples, not compiled into
///    every stage that might (`hyrt_gpu::texture` says why);
/// 8. the texels ([`TextureSet::texels`]: a record's `first_texel` counts from `texels`).
///
/// An absent table takes no word. The GPU reads this record as a uniform beside the
/// buffer; a scene without surface tables has the zero record and binds a buffer of one
/// word that no shader reads (its stages are compiled without the code that reads the
/// tables: `hyrt_gpu::texture::Specialization`).
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `materials` | u32 | word index of the first [`MaterialRecord`] (object 0's) |
/// | 4 | `first_triangles` | u32 | word index of object 0's first global triangle |
/// | 8 | `uvs` | u32 | word index of the first [`TriangleUvRecord`] (global triangle 0's) |
/// | 12 | `colors` | u32 | word index of global triangle 0's vertex colours |
/// | 16 | `tangents` | u32 | word index of global triangle 0's tangents |
/// | 20 | `textures` | u32 | word index of the first [`TextureRecord`] |
/// | 24 | `srgb` | u32 | word index of the sRGB decoding of code 0 |
/// | 28 | `texels` | u32 | word index of texel 0 |
/// | 32 | `words` | u32 | words of all the tables (0 without surface tables) |
/// | 36 | `pad0`..`pad2` | u32 | zero (a uniform's size is a multiple of 16 bytes) |
///
/// 48 bytes. Build with [`crate::geometry::SurfaceTables::layout`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct SurfaceLayout {
    pub materials: u32,
    pub first_triangles: u32,
    pub uvs: u32,
    pub colors: u32,
    pub tangents: u32,
    pub textures: u32,
    pub srgb: u32,
    pub texels: u32,
    pub words: u32,
    pub pad0: u32,
    pub pad1: u32,
    pub pad2: u32,
}
const _: () = assert!(std::mem::size_of::<SurfaceLayout>() == 48);
wgsl_struct!(SurfaceLayout {
    materials,
    first_triangles,
    uvs,
    colors,
    tangents,
    textures,
    srgb,
    texels,
    words,
    pad0,
    pad1,
    pad2
});

impl SurfaceLayout {
    /// Words of one [`MaterialRecord`].
    pub const MATERIAL_WORDS: u32 = (std::mem::size_of::<MaterialRecord>() / 4) as u32;
    /// Words of one [`TriangleUvRecord`].
    pub const TRIANGLE_UV_WORDS: u32 = (std::mem::size_of::<TriangleUvRecord>() / 4) as u32;
    /// Words of one triangle's vertex colours (`[[f32; 4]; 3]`).
    pub const TRIANGLE_COLOR_WORDS: u32 = (std::mem::size_of::<[[f32; 4]; 3]>() / 4) as u32;
    /// Words of one triangle's tangents (`[[f32; 4]; 3]`).
    pub const TRIANGLE_TANGENT_WORDS: u32 = (std::mem::size_of::<[[f32; 4]; 3]>() / 4) as u32;
    /// Words of one [`TextureRecord`].
    pub const TEXTURE_WORDS: u32 = (std::mem::size_of::<TextureRecord>() / 4) as u32;
    /// Words of the sRGB decoding table: one per 8-bit code.
    pub const SRGB_WORDS: u32 = 256;

    /// The layout of tables of `counts.materials` material records (and as many first
    /// triangles), `counts.uvs` uv records, `counts.colors` triangles' vertex colours,
    /// `counts.tangents` triangles' tangents, `counts.textures` texture records (and the
    /// sRGB table when there are any) and `counts.texels` texels, in that order; `None`
    /// when they hold 2^32 words or more.
    pub fn new(counts: TableCounts) -> Option<SurfaceLayout> {
        let sizes = [
            counts.materials as u64 * Self::MATERIAL_WORDS as u64,
            counts.materials as u64,
            counts.uvs as u64 * Self::TRIANGLE_UV_WORDS as u64,
            counts.colors as u64 * Self::TRIANGLE_COLOR_WORDS as u64,
            counts.tangents as u64 * Self::TRIANGLE_TANGENT_WORDS as u64,
            counts.textures as u64 * Self::TEXTURE_WORDS as u64,
            if counts.textures > 0 { Self::SRGB_WORDS as u64 } else { 0 },
            counts.texels as u64,
        ];
        let mut starts = [0u32; 8];
        let mut end = 0u64;
        for (start, size) in starts.iter_mut().zip(sizes) {
            *start = u32::try_from(end).ok()?;
            end += size;
        }
        let [materials_at, first_triangles, uvs_at, colors_at, tangents_at, textures_at, srgb, texels_at] = starts;
        Some(SurfaceLayout {
            materials: materials_at,
            first_triangles,
            uvs: uvs_at,
            colors: colors_at,
            tangents: tangents_at,
            textures: textures_at,
            srgb,
            texels: texels_at,
            words: u32::try_from(end).ok()?,
            ..SurfaceLayout::default()
        })
    }

    /// Bytes of the buffer the tables are packed into (the words; at least one word: a
    /// binding cannot be empty).
    pub fn bytes(&self) -> u64 {
        4 * self.words.max(1) as u64
    }

    /// Check: the tables in order, within `words`.
    pub fn validate(&self) -> Result<(), String> {
        let starts = [
            self.materials,
            self.first_triangles,
            self.uvs,
            self.colors,
            self.tangents,
            self.textures,
            self.srgb,
            self.texels,
            self.words,
        ];
        if !starts.windows(2).all(|p| p[0] <= p[1]) {
            return Err(format!("surface layout with tables out of order: {self:?}"));
        }
        Ok(())
    }
}

/// How many records each table of a [`SurfaceLayout`] holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TableCounts {
    pub materials: usize,
    pub uvs: usize,
    pub colors: usize,
    pub tangents: usize,
    pub textures: usize,
    pub texels: usize,
}

/// Pack an RGBA8 texel as [`TextureSet::texels`] stores it.
#[inline]
pub fn pack_texel(t: [u8; 4]) -> u32 {
    u32::from_le_bytes(t)
}

/// The mip chain of `image` down to 1 x 1: level 0 is the image; each further level
/// averages, in linear values, the up to 2 x 2 texels of the level above that it covers
/// (`2x, 2x + 1` by `2y, 2y + 1`, the last row or column of an odd side taken once more by
/// the texel that reaches it), and encodes the mean again. With `encoding`
/// [`TEXEL_SRGB`], RGB are decoded by the table of
/// [`crate::kernels::texture::srgb8_to_linear`] and the mean encoded by
/// [`crate::kernels::shading::linear_to_srgb8`]; with [`TEXEL_LINEAR`] they are averaged
/// as codes and rounded, as alpha always is. Computed once on the CPU: the GPU is given the
/// same texels, never recomputes them.
pub fn mip_chain(image: &TextureImage, encoding: u32) -> Vec<Vec<[u8; 4]>> {
    use crate::kernels::shading::linear_to_srgb8;
    use crate::kernels::texture::srgb8_to_linear;
    let mut levels = vec![image.texels.clone()];
    let (mut w, mut h) = (image.width, image.height);
    while w > 1 || h > 1 {
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        let above = levels.last().expect("level 0 is there");
        let mut next = Vec::with_capacity(nw as usize * nh as usize);
        for y in 0..nh {
            // The rows (columns) of the level above this texel covers: two, and for the
            // last texel of an odd side three, so no row is dropped.
            let rows = (2 * y)..if y + 1 == nh { h } else { 2 * y + 2 };
            for x in 0..nw {
                let cols = (2 * x)..if x + 1 == nw { w } else { 2 * x + 2 };
                let mut sum = [0.0f32; 4];
                for yy in rows.clone() {
                    for xx in cols.clone() {
                        let t = above[(yy * w + xx) as usize];
                        for c in 0..3 {
                            sum[c] += if encoding == TEXEL_SRGB { srgb8_to_linear(t[c]) } else { t[c] as f32 };
                        }
                        sum[3] += t[3] as f32;
                    }
                }
                let n = (rows.len() * cols.len()) as f32;
                let code = |s: f32| (s / n + 0.5) as u8;
                let rgb = |c: usize| if encoding == TEXEL_SRGB { linear_to_srgb8(sum[c] / n) } else { code(sum[c]) };
                next.push([rgb(0), rgb(1), rgb(2), code(sum[3])]);
            }
        }
        levels.push(next);
        (w, h) = (nw, nh);
    }
    levels
}

/// Every texture a frame samples: the records and their texels, built once per scene.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TextureSet {
    pub records: Vec<TextureRecord>,
    /// All levels of all textures, packed ([`pack_texel`]).
    pub texels: Vec<u32>,
}

impl TextureSet {
    /// No texture at all.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Add `image` sampled with `sampler` (its mip chain when the sampler mip maps), its
    /// RGB encoded as `encoding` says ([`TEXEL_SRGB`], [`TEXEL_LINEAR`]), and return its
    /// record's index. Images shared by several samplers or encodings are stored once per
    /// pair: the caller dedupes (image, sampler, encoding).
    pub fn add(&mut self, image: &TextureImage, sampler: &Sampler, encoding: u32) -> u32 {
        let first_texel =
            u32::try_from(self.texels.len()).expect("texels beyond 2^32: the loader's budget prevents this");
        let levels = if sampler.mip.is_some() { mip_chain(image, encoding) } else { vec![image.texels.clone()] };
        let code = |f: Filter| match f {
            Filter::Nearest => FILTER_NEAREST,
            Filter::Linear => FILTER_LINEAR,
        };
        let record = TextureRecord {
            first_texel,
            width: image.width,
            height: image.height,
            levels: levels.len() as u32,
            wrap_s: sampler.wrap_s.code(),
            wrap_t: sampler.wrap_t.code(),
            mag_filter: code(sampler.mag),
            min_filter: code(sampler.min),
            mip_filter: sampler.mip.map(code).unwrap_or(FILTER_NO_MIP),
            encoding,
        };
        self.texels.extend(levels.iter().flatten().map(|&t| pack_texel(t)));
        self.records.push(record);
        (self.records.len() - 1) as u32
    }

    /// Bytes the set holds (records and texels).
    pub fn bytes(&self) -> usize {
        self.records.len() * std::mem::size_of::<TextureRecord>() + self.texels.len() * 4
    }

    /// Check every record, and that its levels lie inside the texels.
    pub fn validate(&self) -> Result<(), String> {
        for (k, r) in self.records.iter().enumerate() {
            r.validate().map_err(|e| format!("texture {k}: {e}"))?;
            if r.first_texel as u64 + r.texel_count() > self.texels.len() as u64 {
                return Err(format!("texture {k}: levels past the end of the texels ({r:?})"));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mip_chains_average_in_linear_light_and_keep_odd_edges() {
        // 3 x 2: black and white columns; the odd last column is folded into level 1.
        let texels = vec![
            [0, 0, 0, 255],
            [255, 255, 255, 255],
            [255, 255, 255, 0],
            [0, 0, 0, 255],
            [255, 255, 255, 255],
            [255, 255, 255, 0],
        ];
        let image = TextureImage::new("t".into(), 3, 2, texels).unwrap();
        let chain = mip_chain(&image, TEXEL_SRGB);
        assert_eq!(chain.len(), 2, "3x2 -> 1x1");
        // Mean of 2 black and 4 white texels in linear light is 2/3: sRGB 213, not 170.
        let expected = crate::kernels::shading::linear_to_srgb8(4.0 / 6.0);
        assert_eq!(expected, 213);
        assert_eq!(chain[1], vec![[213, 213, 213, 170]]);
        // Data textures average their codes: 4 x 255 / 6 = 170.
        assert_eq!(mip_chain(&image, TEXEL_LINEAR)[1], vec![[170, 170, 170, 170]]);
    }

    #[test]
    fn surface_tables_pack_one_after_another_as_their_layout_says() {
        let image = TextureImage::new("t".into(), 2, 1, vec![[1, 2, 3, 4], [5, 6, 7, 8]]).unwrap();
        let mut tables = crate::geometry::SurfaceTables::default();
        tables.textures.add(&image, &Sampler { mip: None, ..Sampler::default() }, TEXEL_SRGB);
        let textured = MaterialRecord { texture: 0, flags: MAT_TEXTURED, uv_texture: 0, ..MaterialRecord::PLAIN };
        tables.materials = vec![MaterialRecord::PLAIN, textured];
        tables.uvs = vec![TriangleUvRecord { uv1: [1.0, 0.0], lod_bias: -2.5, ..Default::default() }; 3];
        let objects = [0, 1]
            .map(|first_triangle| crate::formats::ObjectRecord { first_triangle, ..bytemuck::Zeroable::zeroed() });
        let (layout, words) = tables.packed(&objects).unwrap();
        layout.validate().unwrap();
        let starts =
            [layout.materials, layout.first_triangles, layout.uvs, layout.colors, layout.tangents, layout.textures];
        assert_eq!(starts, [0, 22, 24, 48, 48, 48], "no colours or tangents: those tables take no word");
        assert_eq!((layout.srgb, layout.texels, layout.words), (58, 314, 316));
        assert_eq!(words.len(), 316);
        assert_eq!(words[11..15], [0, MAT_TEXTURED, 1f32.to_bits(), 0]);
        assert_eq!(words[19], 0, "its uv texture");
        assert_eq!(words[22..24], [0, 1], "each object's first triangle");
        assert_eq!((f32::from_bits(words[24 + 2]), f32::from_bits(words[24 + 6])), (1.0, -2.5));
        assert_eq!(words[48..58], *bytemuck::cast_slice::<_, u32>(&tables.textures.records));
        assert_eq!(words[58..314], *bytemuck::cast_slice::<_, u32>(crate::kernels::texture::srgb8_table()));
        assert_eq!(words[314..], [pack_texel([1, 2, 3, 4]), pack_texel([5, 6, 7, 8])]);
        let none = crate::geometry::SurfaceTables::default().layout().unwrap();
        assert_eq!((none, none.bytes()), (SurfaceLayout::default(), 4), "the zero layout, one dummy word");
        none.validate().unwrap();
        assert!(SurfaceLayout { uvs: 50, ..layout }.validate().is_err());
        let huge = TableCounts { texels: 1 << 32, ..TableCounts::default() };
        assert_eq!(SurfaceLayout::new(huge), None, "2^32 words do not fit u32 indices");
    }

    #[test]
    fn records_of_a_set_point_at_their_levels() {
        let image = TextureImage::new("t".into(), 4, 2, vec![[10, 20, 30, 40]; 8]).unwrap();
        let mut set = TextureSet::default();
        assert_eq!(set.add(&image, &Sampler { mip: None, ..Sampler::default() }, TEXEL_SRGB), 0);
        assert_eq!(set.add(&image, &Sampler::default(), TEXEL_SRGB), 1);
        let r = set.records[1];
        assert_eq!((r.first_texel, r.levels, r.texel_count()), (8, 3, 8 + 2 + 1));
        assert_eq!((r.level_offset(1), r.level_offset(2), r.level_size(2)), (16, 18, (1, 1)));
        assert_eq!(set.texels.len(), 19);
        assert_eq!(set.texels[18], pack_texel([10, 20, 30, 40]), "a constant image keeps its texel in every level");
        set.validate().unwrap();
        let mut bad = set.clone();
        bad.records[1].levels = 4;
        assert!(bad.validate().is_err());
    }
}
