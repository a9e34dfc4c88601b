//! Texture kernels: sRGB decoding, wrap modes, nearest and bilinear texel filtering, mip
//! level selection by ray cones, and the alpha test.
//!
//! Every operation is a correctly rounded f32 operation in a stated order, or a table
//! lookup, so the GPU's twins (`texture.wgsl`, filtering by hand from texel loads, never
//! the hardware sampler, whose filtering weights are fixed-point and differ between GPUs)
//! give the same bits. The logarithms of the level of detail are
//! [`crate::kernels::shading::log2_portable`].
//!
//! # Level of detail: ray cones
//! A pixel's footprint is a cone around its ray (Akenine-Moeller et al., "Improved Shader
//! and Texture Level of Detail Using Ray Cones", JCGT 2021): at distance `t` its width is
//! `W = t * spread`, `spread` the angle one pixel subtends (the camera's
//! [`pixel_spread`]). On a triangle whose texture coordinates cover `T` texels of area
//! over a world area `A`, seen at cosine `c` between ray and normal, the level is
//! `lambda = 0.5 log2(T / A) + log2(W / c)`: the first term is per triangle
//! ([`triangle_lod_bias`], stored in [`crate::formats::TriangleUvRecord::lod_bias`]), the
//! second per hit ([`hit_lod`]). A grazing view (small `c`) widens the footprint along
//! the surface and picks a coarser level, as a GPU's screen-space derivatives would.
//! Secondary rays carry their cone on: a reflection keeps the pixel's spread (exact for
//! flat mirrors; curved ones would widen it, which is not modelled), so `W` is the spread
//! times the whole path's length.

use glam::{Vec2, Vec3};

use crate::formats::{
    MaterialRecord, ObjectRecord, SurfaceRecord, TextureRecord, TriangleRecord, TriangleUvRecord, FILTER_NEAREST,
    FILTER_NO_MIP, MAT_ALPHA_TEST, MAT_ANY_TEXTURE, MAT_EMISSIVE, MAT_METALLIC_ROUGHNESS, MAT_NORMAL, MAT_OCCLUSION,
    MAT_TEXTURED, MAT_VERTEX_COLORS, TEXEL_SRGB, WRAP_CLAMP, WRAP_MIRROR,
};
use crate::kernels::shading::log2_portable;

/// The sRGB decoding of each 8-bit code (IEC 61966-2-1: `c / 12.92` up to 0.04045, else
/// `((c + 0.055) / 1.055)^2.4`, with `c = code / 255`), evaluated in f64 and rounded once
/// to f32. A table, not a formula, so that both backends decode with the same bits (the
/// GPU receives this table); pinned by a test.
pub fn srgb8_table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|code| {
            let c = code as f64 / 255.0;
            let linear = if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) };
            linear as f32
        })
    })
}

/// [`srgb8_table`] of one code. WGSL: `srgb8_to_linear`.
#[inline]
pub fn srgb8_to_linear(code: u8) -> f32 {
    srgb8_table()[code as usize]
}

/// An 8-bit alpha (or any linear unorm8) as f32: `code * (1 / 255)`, the product
/// correctly rounded (a multiplication, not a division: WGSL's division is not required to
/// be correctly rounded). WGSL: `unorm8_to_f32`.
#[inline]
pub fn unorm8_to_f32(code: u32) -> f32 {
    code as f32 * UNORM8_SCALE
}

/// `1 / 255` rounded to f32.
pub const UNORM8_SCALE: f32 = 1.0 / 255.0;

/// A packed texel ([`crate::formats::pack_texel`]) as linear RGBA: RGB through the sRGB
/// table when `encoding` is [`TEXEL_SRGB`], as unorm8 values (like alpha) when it is
/// [`crate::formats::TEXEL_LINEAR`]. WGSL: `decode_texel`.
#[inline]
pub fn decode_texel(t: u32, encoding: u32) -> [f32; 4] {
    let a = unorm8_to_f32(t >> 24);
    if encoding == TEXEL_SRGB {
        return [srgb8_to_linear(t as u8), srgb8_to_linear((t >> 8) as u8), srgb8_to_linear((t >> 16) as u8), a];
    }
    [unorm8_to_f32(t & 0xff), unorm8_to_f32((t >> 8) & 0xff), unorm8_to_f32((t >> 16) & 0xff), a]
}

/// A texture coordinate reduced to one period of its wrap mode, so that texel indices stay
/// small whatever the coordinate: `REPEAT` to `[0, 1)` (`x - floor(x)`), `MIRRORED_REPEAT` to
/// `[0, 2)` (`2 (x/2 - floor(x/2))`, both steps exact), `CLAMP_TO_EDGE` to `[0, 1]`. A
/// non-finite coordinate becomes 0. WGSL: `wrap_coordinate`.
#[inline]
pub fn wrap_coordinate(x: f32, wrap: u32) -> f32 {
    if !x.is_finite() {
        return 0.0;
    }
    if wrap == WRAP_CLAMP {
        x.clamp(0.0, 1.0)
    } else if wrap == WRAP_MIRROR {
        let h = x * 0.5;
        (h - h.floor()) * 2.0
    } else {
        // `x - floor(x)` can round up to 1 for a tiny negative x: keep it in [0, 1).
        let f = x - x.floor();
        if f >= 1.0 {
            0.0
        } else {
            f
        }
    }
}

/// The texel index along one axis of `n` texels for an integer index `i` (which may be one
/// outside `[0, n)` after bilinear's `- 0.5`, or up to `2n` for a mirrored coordinate).
/// WGSL: `wrap_index`.
#[inline]
pub fn wrap_index(i: i32, n: u32, wrap: u32) -> u32 {
    let n = n as i32;
    let k = if wrap == WRAP_CLAMP {
        i.clamp(0, n - 1)
    } else if wrap == WRAP_MIRROR {
        let m = rem_euclid(i, 2 * n);
        if m >= n {
            2 * n - 1 - m
        } else {
            m
        }
    } else {
        rem_euclid(i, n)
    };
    k as u32
}

/// `i.rem_euclid(n)` for `n > 0`, as a mask where `n` is a power of two (most textures'
/// sides: the same value in two's complement, without a division, which costs more than
/// the rest of a bilinear fetch).
#[inline]
fn rem_euclid(i: i32, n: i32) -> i32 {
    if n & (n - 1) == 0 {
        i & (n - 1)
    } else {
        i.rem_euclid(n)
    }
}

/// A texel of level `level` at integer indices (wrapped), as linear RGBA.
#[inline]
fn fetch(texels: &[u32], tex: &TextureRecord, base: u32, w: u32, h: u32, x: i32, y: i32) -> [f32; 4] {
    texel_at(texels, tex, base, w, wrap_index(x, w, tex.wrap_s), wrap_index(y, h, tex.wrap_t))
}

/// The texel at wrapped indices `(i, j)` of the level starting at `base`, `w` texels wide,
/// as linear RGBA.
#[inline]
fn texel_at(texels: &[u32], tex: &TextureRecord, base: u32, w: u32, i: u32, j: u32) -> [f32; 4] {
    decode_texel(texels[(base + j * w + i) as usize], tex.encoding)
}

/// `a + (b - a) * t` per channel, each operation rounded. WGSL: `lerp4`.
#[inline]
pub fn lerp4(a: [f32; 4], b: [f32; 4], t: f32) -> [f32; 4] {
    std::array::from_fn(|c| a[c] + (b[c] - a[c]) * t)
}

/// Level `level` of a texture at texture coordinate `uv`, nearest texel or bilinear
/// (`filter`), wrapped by the record's modes. Texel `(i, j)`'s centre is at
/// `((i + 0.5) / w, (j + 0.5) / h)`. WGSL: `sample_level`.
pub fn sample_level(texels: &[u32], tex: &TextureRecord, level: u32, uv: Vec2, filter: u32) -> [f32; 4] {
    let (w, h) = tex.level_size(level);
    let base = tex.level_offset(level);
    let x = wrap_coordinate(uv.x, tex.wrap_s) * w as f32;
    let y = wrap_coordinate(uv.y, tex.wrap_t) * h as f32;
    if filter == FILTER_NEAREST {
        return fetch(texels, tex, base, w, h, x.floor() as i32, y.floor() as i32);
    }
    let (x, y) = (x - 0.5, y - 0.5);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (i, j) = (x0 as i32, y0 as i32);
    // The four texels' wrapped indices, each axis's two once ([`fetch`]'s, per texel).
    let (i0, i1) = (wrap_index(i, w, tex.wrap_s), wrap_index(i + 1, w, tex.wrap_s));
    let (j0, j1) = (wrap_index(j, h, tex.wrap_t), wrap_index(j + 1, h, tex.wrap_t));
    let at = |i: u32, j: u32| texel_at(texels, tex, base, w, i, j);
    let top = lerp4(at(i0, j0), at(i1, j0), fx);
    let bottom = lerp4(at(i0, j1), at(i1, j1), fx);
    lerp4(top, bottom, fy)
}

/// A texture at `uv` and level of detail `lod` (`log2` of texels per pixel footprint,
/// [`hit_lod`]), as its sampler says: `lod <= 0` (magnified) or no mip maps: level 0 with
/// the magnification or minification filter; otherwise the level(s) around `lod`, clamped
/// to the chain, nearest or blended linearly. NaN `lod` counts as 0. WGSL: `sample_texture`.
pub fn sample_texture(texels: &[u32], tex: &TextureRecord, uv: Vec2, lod: f32) -> [f32; 4] {
    if lod.is_nan() || lod <= 0.0 {
        return sample_level(texels, tex, 0, uv, tex.mag_filter);
    }
    if tex.mip_filter == FILTER_NO_MIP {
        return sample_level(texels, tex, 0, uv, tex.min_filter);
    }
    let top = (tex.levels - 1) as f32;
    let lod = lod.min(top);
    if tex.mip_filter == FILTER_NEAREST {
        // Nearest level: round half up (`floor(lod + 0.5)`).
        let level = (lod + 0.5).floor().min(top) as u32;
        return sample_level(texels, tex, level, uv, tex.min_filter);
    }
    let l0 = lod.floor();
    let f = lod - l0;
    let fine = sample_level(texels, tex, l0 as u32, uv, tex.min_filter);
    if f == 0.0 {
        return fine;
    }
    let coarse = sample_level(texels, tex, l0 as u32 + 1, uv, tex.min_filter);
    lerp4(fine, coarse, f)
}

/// Barycentric interpolation of a triangle's texture coordinates at the hit `(u, v)`:
/// `(w uv0 + u uv1) + v uv2` per component with `w = (1 - u) - v`, the order of
/// [`crate::kernels::barycentric::reconstruct_position`]. WGSL: `interpolate_uv`.
#[inline]
pub fn interpolate_uv(t: &TriangleUvRecord, u: f32, v: f32) -> Vec2 {
    let w = crate::kernels::barycentric::bary_w(u, v);
    Vec2::new((w * t.uv0[0] + u * t.uv1[0]) + v * t.uv2[0], (w * t.uv0[1] + u * t.uv1[1]) + v * t.uv2[1])
}

/// Barycentric interpolation of the three vertex colours of a triangle, in the same order.
/// WGSL: `interpolate_color`.
#[inline]
pub fn interpolate_color(c: &[[f32; 4]; 3], u: f32, v: f32) -> [f32; 4] {
    let w = crate::kernels::barycentric::bary_w(u, v);
    std::array::from_fn(|k| (w * c[0][k] + u * c[1][k]) + v * c[2][k])
}

/// The smallest area (world units², texels) the level-of-detail constant divides by or
/// takes the logarithm of: a degenerate triangle (zero area in the world or in texture
/// space) gets the bias of this area instead of an infinity. `f32::MIN_POSITIVE`, the
/// smallest argument [`log2_portable`] is specified for.
pub const LOD_MIN_AREA: f32 = f32::MIN_POSITIVE;

/// The per-triangle term of the ray-cone level of detail (module docs):
/// `0.5 * (log2(texel area) - log2(world area))`, areas as the cross products' lengths
/// (twice the triangle's area in both spaces, so the factor cancels), texel area in level
/// 0's texels (`uv` scaled by `width`, `height`). Computed once per triangle when the frame
/// is prepared (the GPU is given it).
pub fn triangle_lod_bias(v: [Vec3; 3], uv: [Vec2; 3], width: u32, height: u32) -> f32 {
    let world = (v[1] - v[0]).cross(v[2] - v[0]).length();
    let scale = Vec2::new(width as f32, height as f32);
    let (a, b) = ((uv[1] - uv[0]) * scale, (uv[2] - uv[0]) * scale);
    let texel = (a.x * b.y - a.y * b.x).abs();
    let area = |x: f32| if x.is_finite() { x.max(LOD_MIN_AREA) } else { f32::MAX };
    0.5 * (log2_portable(area(texel)) - log2_portable(area(world)))
}

/// The angle one pixel subtends at the image's centre: `2 tan(fov_y / 2) / height`, the
/// spread of every ray cone of the frame.
pub fn pixel_spread(fov_y_deg: f32, height: u32) -> f32 {
    2.0 * (fov_y_deg.to_radians() * 0.5).tan() / height as f32
}

/// [`pixel_spread`] of the camera a record was built from: its projection's y scale
/// `1 / tan(fov_y / 2)` is the length of the eye-relative view-projection's second row
/// (the projection times a rotation), so the spread is `2 / (height * that length)`.
/// Computed once per frame on the CPU (the GPU is given it, `FrameParams::pixel_spread`).
pub fn camera_pixel_spread(camera: &crate::formats::CameraRecord) -> f32 {
    let m = glam::Mat4::from_cols_array(&camera.view_proj);
    let y_scale = m.row(1).truncate().length();
    2.0 / (camera.height as f32 * y_scale)
}

/// The smallest cosine [`hit_lod`] divides by: a ray grazing its triangle (cosine below
/// this, or 0) is taken as seen at this cosine, about 0.0001 rad from the plane, so the
/// footprint stays finite (level 13 more than head-on, past every chain of a 8192-texel
/// image).
pub const LOD_MIN_COSINE: f32 = 1.0 / 8192.0;

/// The level of detail of a hit: `bias + log2(cone_width / |cos|)` with `cone_width` the
/// footprint's width at the hit (the spread times the path's length) and `cos` the cosine
/// between the ray and the geometric normal. WGSL: `hit_lod`.
#[inline]
pub fn hit_lod(bias: f32, cone_width: f32, cos: f32) -> f32 {
    let c = cos.abs().max(LOD_MIN_COSINE);
    let w = if cone_width.is_finite() { cone_width.max(LOD_MIN_AREA) } else { f32::MAX };
    bias + (log2_portable(w) - log2_portable(c))
}

/// The level of detail of texture `tex` for a hit whose level is `lod` in texture
/// `reference`'s texels (the texture a material's [`TriangleUvRecord::lod_bias`] is computed
/// for, [`MaterialRecord::uv_texture`]): `lod` itself for a texture of the same size, else
/// `lod + 0.5 (log2(w h) - log2(w_ref h_ref))`, the ratio of their texel areas over the
/// same coordinates (the areas are exact in f32: sides are at most 2^14). WGSL:
/// `texture_lod`.
#[inline]
pub fn texture_lod(lod: f32, reference: &TextureRecord, tex: &TextureRecord) -> f32 {
    if (tex.width, tex.height) == (reference.width, reference.height) {
        return lod;
    }
    let area = |t: &TextureRecord| (t.width * t.height) as f32;
    lod + 0.5 * (log2_portable(area(tex)) - log2_portable(area(reference)))
}

/// The alpha test's sample: level 0 with the sampler's magnification filter, whatever the
/// footprint. The raster and every ray kind see the same holes at the same place (a
/// level chosen by footprint would let foliage thin out or fill in with distance, and
/// shadow rays have no footprint). WGSL: `alpha_at`.
#[inline]
pub fn alpha_at(texels: &[u32], tex: &TextureRecord, uv: Vec2) -> f32 {
    sample_level(texels, tex, 0, uv, tex.mag_filter)[3]
}

/// Whether an alpha-tested surface is there: `alpha >= cutoff` (glTF: "rendered fully
/// opaque" when greater than or equal). WGSL: `alpha_passes`.
#[inline]
pub fn alpha_passes(alpha: f32, cutoff: f32) -> bool {
    alpha >= cutoff
}

/// The tables of [`crate::geometry::SurfaceTables`] as slices: what the texture kernels
/// read (the GPU binds the same arrays). Empty slices for a scene without textures,
/// vertex colours or alpha tests.
#[derive(Clone, Copy, Debug, Default)]
pub struct SurfaceView<'a> {
    /// Per object ([`crate::formats::MaterialRecord`]); empty: no object needs one.
    pub materials: &'a [MaterialRecord],
    /// Per global triangle, when any object is textured.
    pub uvs: &'a [TriangleUvRecord],
    /// Per global triangle, when any object has vertex colours.
    pub colors: &'a [[[f32; 4]; 3]],
    /// Per global triangle, when any object is normal-mapped: each corner's world tangent
    /// and bitangent sign.
    pub tangents: &'a [[[f32; 4]; 3]],
    pub textures: &'a [TextureRecord],
    pub texels: &'a [u32],
}

impl SurfaceView<'_> {
    /// Whether some object is alpha-tested ([`MAT_ALPHA_TEST`]).
    pub fn alpha_tested(&self) -> bool {
        self.materials.iter().any(|m| m.flags & MAT_ALPHA_TEST != 0)
    }

    /// Whether some object's material varies over its surface: textured (any texture) or
    /// vertex-coloured.
    pub fn colour_varies(&self) -> bool {
        self.materials.iter().any(|m| m.flags & (MAT_ANY_TEXTURE | MAT_VERTEX_COLORS) != 0)
    }
}

/// Whether the alpha-tested triangle `tri` (global index `global`) is there at its
/// barycentrics `(u, v)`: the material's alpha (base-colour factor alpha, times the
/// texture's alpha at level 0 ([`alpha_at`]) when textured, times the interpolated vertex
/// colour's alpha when it has vertex colours, in that order) passes its cutoff
/// ([`alpha_passes`]). The visibility raster asks this of every fragment of such a
/// triangle and the traversals of every hit on one. WGSL: `alpha_accepts`.
#[inline]
pub fn alpha_accepts(view: &SurfaceView, tri: &TriangleRecord, global: usize, u: f32, v: f32) -> bool {
    let m = &view.materials[tri.object as usize];
    let mut a = m.base_alpha;
    if m.flags & MAT_TEXTURED != 0 {
        a *= alpha_at(view.texels, &view.textures[m.texture as usize], interpolate_uv(&view.uvs[global], u, v));
    }
    if m.flags & MAT_VERTEX_COLORS != 0 {
        a *= interpolate_color(&view.colors[global], u, v)[3];
    }
    alpha_passes(a, m.alpha_cutoff)
}

/// What shading knows of materials: the object records, the surface tables and the
/// frame's cone spread ([`pixel_spread`]; 0 in a scene without textures, whose cones are
/// then all 0 and never read).
#[derive(Clone, Copy, Debug)]
pub struct Materials<'a> {
    pub objects: &'a [ObjectRecord],
    pub surface: SurfaceView<'a>,
    pub spread: f32,
}

impl<'a> Materials<'a> {
    /// Materials without textures or vertex colours: every point is its object's record.
    pub fn plain(objects: &'a [ObjectRecord]) -> Materials<'a> {
        Materials { objects, surface: SurfaceView::default(), spread: 0.0 }
    }

    /// Whether any object's colour varies over its surface (textures, vertex colours):
    /// only then do shading stages read barycentrics and footprints.
    #[inline]
    pub fn varying(&self) -> bool {
        !self.surface.materials.is_empty()
    }

    /// The record of the object hit at surface `s` (a hit) as shading sees it there (`u`,
    /// `v` its barycentrics; `cone` the footprint and `d` the unit direction it was seen
    /// along, whose cosine with the geometric normal gives the level of detail,
    /// [`hit_lod`], shifted per texture by [`texture_lod`]); its object's own record
    /// where nothing varies. In this order:
    /// - base colour times the base-colour texture's RGB ([`MAT_TEXTURED`]);
    /// - times the interpolated vertex colour ([`MAT_VERTEX_COLORS`]);
    /// - roughness times the metallic-roughness texture's green, metallic times its blue
    ///   ([`MAT_METALLIC_ROUGHNESS`]);
    /// - the occlusion times `1 + strength (red - 1)` of the occlusion texture
    ///   ([`MAT_OCCLUSION`], glTF's blend towards 1);
    /// - emission times the emissive texture's RGB ([`MAT_EMISSIVE`]).
    ///
    /// WGSL: `shaded_object`.
    #[inline]
    pub fn at(&self, s: &SurfaceRecord, u: f32, v: f32, cone: f32, d: Vec3) -> ObjectRecord {
        let mut obj = self.objects[s.object as usize];
        if !self.varying() {
            return obj;
        }
        let m = &self.surface.materials[s.object as usize];
        let global = s.triangle as usize;
        if m.flags & MAT_ANY_TEXTURE != 0 {
            let t = &self.surface.uvs[global];
            let cos = d.dot(Vec3::from(s.geometric_normal));
            let lod = hit_lod(t.lod_bias, cone, cos);
            let uv = interpolate_uv(t, u, v);
            let reference = &self.surface.textures[m.uv_texture as usize];
            let sample = |index: u32| {
                let tex = &self.surface.textures[index as usize];
                sample_texture(self.surface.texels, tex, uv, texture_lod(lod, reference, tex))
            };
            if m.flags & MAT_TEXTURED != 0 {
                let texel = sample(m.texture);
                let c = obj.base_color;
                obj.base_color = [c[0] * texel[0], c[1] * texel[1], c[2] * texel[2]];
            }
            if m.flags & MAT_VERTEX_COLORS != 0 {
                obj.base_color = vertex_coloured(obj.base_color, &self.surface.colors[global], u, v);
            }
            if m.flags & MAT_METALLIC_ROUGHNESS != 0 {
                let texel = sample(m.metallic_roughness);
                obj.roughness *= texel[1];
                obj.metallic *= texel[2];
            }
            if m.flags & MAT_OCCLUSION != 0 {
                let texel = sample(m.occlusion);
                obj.occlusion *= 1.0 + m.occlusion_strength * (texel[0] - 1.0);
            }
            if m.flags & MAT_EMISSIVE != 0 {
                let texel = sample(m.emissive);
                let e = obj.emissive;
                obj.emissive = [e[0] * texel[0], e[1] * texel[1], e[2] * texel[2]];
            }
        } else if m.flags & MAT_VERTEX_COLORS != 0 {
            obj.base_color = vertex_coloured(obj.base_color, &self.surface.colors[global], u, v);
        }
        obj
    }
}

impl Materials<'_> {
    /// Whether some object is normal-mapped ([`MAT_NORMAL`]): only then do the stages
    /// that make surfaces call [`Materials::normal_mapped`]. The tangent table exists
    /// exactly then (`crate::geometry::SurfaceTables::tangents`), so this is a length test,
    /// not a scan of the materials: the fused frame asks it per tile.
    #[inline]
    pub fn normal_mapped_any(&self) -> bool {
        !self.surface.tangents.is_empty()
    }

    /// Surface `s` (a hit, or a miss, returned as it is) with its shading normal from its
    /// material's normal map ([`MAT_NORMAL`]; `s` itself without one): the texel at
    /// barycentrics `(u, v)`, level of detail as [`Materials::at`] picks it (footprint
    /// `cone`, unit direction `d` it was seen along), read as the tangent-space normal
    /// `((2 r - 1) scale, (2 g - 1) scale, 2 b - 1)`, in the frame of the triangle's
    /// interpolated tangent made orthogonal to the shading normal and the bitangent
    /// `cross(n, t) w` (`w` of the triangle's first corner), then normalized: glTF 2.0's
    /// normal texture. `back_face`: the surface was seen from its back, so `s`'s normals
    /// were turned around ([`crate::kernels::shading::orient_to_seen_side`]); the frame is
    /// the front's and the result is turned around again. As reconstruction does, a mapped
    /// normal below the geometric normal's hemisphere is replaced by the geometric normal,
    /// and one that cannot be made (a zero or parallel tangent, a zero result) leaves `s`
    /// as it is. WGSL: `normal_mapped`.
    #[inline]
    pub fn normal_mapped(
        &self,
        s: &SurfaceRecord,
        u: f32,
        v: f32,
        cone: f32,
        d: Vec3,
        back_face: bool,
    ) -> SurfaceRecord {
        if !self.varying() || !s.is_hit() {
            return *s;
        }
        let m = &self.surface.materials[s.object as usize];
        if m.flags & MAT_NORMAL == 0 {
            return *s;
        }
        let global = s.triangle as usize;
        let ng = Vec3::from(s.geometric_normal);
        let t = &self.surface.uvs[global];
        let lod = hit_lod(t.lod_bias, cone, d.dot(ng));
        let reference = &self.surface.textures[m.uv_texture as usize];
        let tex = &self.surface.textures[m.normal as usize];
        let texel = sample_texture(self.surface.texels, tex, interpolate_uv(t, u, v), texture_lod(lod, reference, tex));
        let side = if back_face { -1.0 } else { 1.0 };
        let n = Vec3::from(s.normal) * side;
        let c = &self.surface.tangents[global];
        // Corners interpolated as vertex colours are (the sign, `w`, is the first corner's).
        let [tx, ty, tz, _] = interpolate_color(c, u, v);
        let tangent = Vec3::new(tx, ty, tz);
        let tangent = (tangent - n * n.dot(tangent)).normalize_or_zero();
        if tangent == Vec3::ZERO {
            return *s;
        }
        let sign = if c[0][3] < 0.0 { -1.0 } else { 1.0 };
        let bitangent = n.cross(tangent) * sign;
        let x = (texel[0] * 2.0 - 1.0) * m.normal_scale;
        let y = (texel[1] * 2.0 - 1.0) * m.normal_scale;
        let z = texel[2] * 2.0 - 1.0;
        let mapped = ((tangent * x + bitangent * y) + n * z).normalize_or_zero() * side;
        if mapped == Vec3::ZERO {
            return *s;
        }
        let normal = if ng != Vec3::ZERO && mapped.dot(ng) < 0.0 { ng } else { mapped };
        SurfaceRecord { normal: normal.into(), ..*s }
    }
}

/// A base colour times the interpolated vertex colour ([`interpolate_color`]) at `(u, v)`.
#[inline]
fn vertex_coloured(c: [f32; 3], corners: &[[f32; 4]; 3], u: f32, v: f32) -> [f32; 3] {
    let k = interpolate_color(corners, u, v);
    [c[0] * k[0], c[1] * k[1], c[2] * k[2]]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::{TextureSet, FILTER_LINEAR, WRAP_REPEAT};
    use crate::scene::texture::{Filter, Sampler, TextureImage, Wrap};

    fn set_of(w: u32, h: u32, texels: Vec<[u8; 4]>, sampler: Sampler) -> TextureSet {
        let mut set = TextureSet::default();
        set.add(&TextureImage::new("t".into(), w, h, texels).unwrap(), &sampler, crate::formats::TEXEL_SRGB);
        set
    }

    #[test]
    fn srgb_table_is_the_standard_curve_pinned() {
        let t = srgb8_table();
        assert_eq!((t[0], t[255]), (0.0, 1.0));
        // Pinned bits (Python's f64 formula rounded to f32): a change of the formula or of
        // its rounding shows here, and the GPU receives this table.
        assert_eq!([t[10].to_bits(), t[128].to_bits(), t[200].to_bits()], [0x3b46eb61, 0x3e5d0a89, 0x3f13dc50]);
        assert!(t.windows(2).all(|p| p[0] < p[1]), "increasing");
        for code in 0..=255u8 {
            assert_eq!(crate::kernels::shading::linear_to_srgb8(srgb8_to_linear(code)), code, "round trip of {code}");
        }
    }

    #[test]
    fn wrap_modes_map_indices_into_the_image() {
        let n = 4;
        let repeat: Vec<u32> = (-5..9).map(|i| wrap_index(i, n, WRAP_REPEAT)).collect();
        assert_eq!(repeat, [3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0]);
        let clamp: Vec<u32> = (-2..6).map(|i| wrap_index(i, n, WRAP_CLAMP)).collect();
        assert_eq!(clamp, [0, 0, 0, 1, 2, 3, 3, 3]);
        let mirror: Vec<u32> = (-3..10).map(|i| wrap_index(i, n, WRAP_MIRROR)).collect();
        assert_eq!(mirror, [2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0, 1]);
        assert_eq!(wrap_coordinate(-1e-30, WRAP_REPEAT), 0.0, "stays below 1");
        assert_eq!(wrap_coordinate(2.25, WRAP_REPEAT), 0.25);
        assert_eq!(wrap_coordinate(-0.25, WRAP_MIRROR), 1.75);
        assert_eq!(wrap_coordinate(f32::NAN, WRAP_MIRROR), 0.0);
        assert_eq!(wrap_coordinate(1e30, WRAP_REPEAT), 0.0, "huge coordinates are whole periods");
    }

    #[test]
    fn the_power_of_two_mask_is_the_euclidean_remainder() {
        for n in (1..=70).chain([1 << 13, 1 << 14, 3 << 12, (1 << 15) - 1, 1 << 15]) {
            for i in (-300..300).chain([i32::MIN, i32::MIN + 1, i32::MAX - 1, i32::MAX, -(1 << 15), 1 << 15]) {
                assert_eq!(rem_euclid(i, n), i.rem_euclid(n), "{i} mod {n}");
            }
        }
    }

    #[test]
    fn bilinear_at_texel_centres_is_the_texel_and_between_is_the_mean() {
        // 2 x 1: black, white; nearest and bilinear, repeat and clamp.
        let texels = vec![[0, 0, 0, 255], [255, 255, 255, 255]];
        let linear = Sampler { wrap_s: Wrap::ClampToEdge, mip: None, ..Sampler::default() };
        let set = set_of(2, 1, texels.clone(), linear);
        let t = &set.records[0];
        let at = |u: f32| sample_level(&set.texels, t, 0, Vec2::new(u, 0.5), FILTER_LINEAR)[0];
        assert_eq!((at(0.25), at(0.75), at(0.5)), (0.0, 1.0, 0.5));
        assert_eq!((at(0.0), at(1.0)), (0.0, 1.0), "clamped at the edges");
        let repeat = set_of(2, 1, texels, Sampler { mip: None, ..Sampler::default() });
        let r = &repeat.records[0];
        let at = |u: f32| sample_level(&repeat.texels, r, 0, Vec2::new(u, 0.5), FILTER_LINEAR)[0];
        assert_eq!(at(0.0), 0.5, "repeat blends the last texel into the first");
        let near = |u: f32| sample_level(&repeat.texels, r, 0, Vec2::new(u, 0.5), FILTER_NEAREST)[0];
        assert_eq!((near(0.49), near(0.5), near(-0.01)), (0.0, 1.0, 1.0));
    }

    #[test]
    fn trilinear_blends_levels_and_nearest_mip_rounds() {
        // 2 x 2 checker of black and white: level 1 is the linear mean, 0.5 (sRGB 188).
        let (b, w) = ([0, 0, 0, 255], [255, 255, 255, 255]);
        let sampler = Sampler { min: Filter::Nearest, ..Sampler::default() };
        let set = set_of(2, 2, vec![b, w, w, b], sampler);
        let t = &set.records[0];
        let level1 = srgb8_to_linear(188);
        let uv = Vec2::new(0.25, 0.25);
        assert_eq!(sample_texture(&set.texels, t, uv, 0.0)[0], 0.0, "magnified: level 0");
        assert_eq!(sample_texture(&set.texels, t, uv, 1.0)[0], level1);
        assert_eq!(sample_texture(&set.texels, t, uv, 7.0)[0], level1, "clamped to the last level");
        assert_eq!(sample_texture(&set.texels, t, uv, 0.5)[0], 0.0 + (level1 - 0.0) * 0.5);
        let nearest_mip = set_of(2, 2, vec![b, w, w, b], Sampler { mip: Some(Filter::Nearest), ..sampler });
        let n = &nearest_mip.records[0];
        assert_eq!(sample_texture(&nearest_mip.texels, n, uv, 0.49)[0], 0.0);
        assert_eq!(sample_texture(&nearest_mip.texels, n, uv, 0.5)[0], level1);
    }

    #[test]
    fn the_spread_of_a_camera_record_is_its_field_of_view_over_its_rows() {
        let cam = crate::scene::Camera::look_at(Vec3::new(1.0, 2.0, 5.0), Vec3::new(-1.0, 0.0, 0.0), Vec3::Y);
        let record = crate::formats::CameraRecord::new(&cam, 640, 360);
        let (got, want) = (camera_pixel_spread(&record), pixel_spread(cam.fov_y_deg, 360));
        // Float rounding of the matrix (a few ulps of each entry).
        assert!((got - want).abs() <= 1e-6 * want, "{got} vs {want}");
    }

    #[test]
    fn lod_of_a_unit_texel_per_pixel_is_zero_and_grazing_is_coarser() {
        // A 1 x 1 world square mapped to a 256 x 256 texture: 256 texels per unit. Seen head
        // on by a cone 1/256 wide: one texel per footprint, level 0.
        let v = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let uv = [Vec2::ZERO, Vec2::X, Vec2::Y];
        let bias = triangle_lod_bias(v, uv, 256, 256);
        assert_eq!(bias, 8.0);
        assert_eq!(hit_lod(bias, 1.0 / 256.0, 1.0), 0.0);
        assert_eq!(hit_lod(bias, 1.0 / 64.0, -1.0), 2.0, "4 texels per footprint, either side");
        assert_eq!(hit_lod(bias, 1.0 / 256.0, 0.25), 2.0, "at cos 1/4 the footprint is 4x longer");
        assert_eq!(hit_lod(bias, 1.0 / 256.0, 0.0), 13.0, "grazing: LOD_MIN_COSINE");
        let degenerate = triangle_lod_bias([Vec3::ZERO; 3], uv, 256, 256);
        assert!(degenerate.is_finite() && degenerate > 15.0, "no world area: past the last level of any chain");
    }

    #[test]
    fn alpha_test_uses_level_zero_whatever_the_footprint() {
        let (hole, solid) = ([0, 0, 0, 0], [0, 0, 0, 255]);
        let set = set_of(2, 1, vec![hole, solid], Sampler { mag: Filter::Nearest, ..Sampler::default() });
        let t = &set.records[0];
        assert_eq!(alpha_at(&set.texels, t, Vec2::new(0.25, 0.5)), 0.0);
        assert_eq!(alpha_at(&set.texels, t, Vec2::new(0.75, 0.5)), 1.0);
        assert!(!alpha_passes(0.0, 0.5) && alpha_passes(0.5, 0.5));
    }
}
