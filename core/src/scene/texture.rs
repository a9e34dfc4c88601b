//! Textures in the scene model: decoded images, the glTF sampler, a material's texture
//! binding (image, sampler, texture-coordinate set, `KHR_texture_transform`) and its alpha
//! mode.
//!
//! An image holds 8-bit RGBA texels as the file stores them: a base-colour texture's RGB
//! is sRGB-encoded (glTF 2.0, "Metallic-Roughness Material"), its alpha linear. Mip levels
//! and the decoding to linear values belong to the frame's preparation
//! ([`crate::formats::TextureSet`]) and the sampling kernels
//! ([`crate::kernels::texture`]), not to the scene.

use std::path::PathBuf;

use glam::Vec2;

/// A decoded image: `width x height` RGBA8 texels, row-major, row 0 on top (glTF's texture
/// space: `(0, 0)` is the first texel of the first row, the image's top left).
#[derive(Clone, Debug, PartialEq)]
pub struct TextureImage {
    /// A readable name (the glTF image name, its URI, or `image<i>`).
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// `width * height` texels, `[r, g, b, a]`.
    pub texels: Vec<[u8; 4]>,
    /// The file the image was read from, when it was a file of its own.
    pub source: Option<PathBuf>,
}

impl TextureImage {
    /// The largest side [`TextureImage::new`] accepts: 16384 texels, the largest 2D texture
    /// a GPU commonly allows (WebGPU's `maxTextureDimension2D` on desktop adapters), so an
    /// image loaded here is one a GPU renderer could also hold as a texture.
    pub const MAX_SIDE: u32 = 16384;

    /// An image of `width x height` texels, checked: both sides in `1..=MAX_SIDE` and
    /// exactly `width * height` texels.
    pub fn new(name: String, width: u32, height: u32, texels: Vec<[u8; 4]>) -> Result<TextureImage, String> {
        if width == 0 || height == 0 || width > Self::MAX_SIDE || height > Self::MAX_SIDE {
            return Err(format!("a {width}x{height} image: each side must be between 1 and {} texels", Self::MAX_SIDE));
        }
        if texels.len() != width as usize * height as usize {
            return Err(format!("{} texels for a {width}x{height} image", texels.len()));
        }
        Ok(TextureImage { name, width, height, texels, source: None })
    }

    /// Texel `(x, y)`: column `x < width`, row `y < height`.
    #[inline]
    pub fn texel(&self, x: u32, y: u32) -> [u8; 4] {
        self.texels[y as usize * self.width as usize + x as usize]
    }
}

/// How a texture coordinate outside `[0, 1]` maps into the image (glTF sampler `wrapS`,
/// `wrapT`; default [`Wrap::Repeat`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Wrap {
    /// `REPEAT` (10497): the image tiles the plane.
    #[default]
    Repeat,
    /// `CLAMP_TO_EDGE` (33071): the border texels extend outwards.
    ClampToEdge,
    /// `MIRRORED_REPEAT` (33648): tiles alternate with their mirror images.
    MirroredRepeat,
}

impl Wrap {
    /// The code shared with the GPU ([`crate::formats::TextureRecord::wrap_s`], `wrap_t`).
    pub const fn code(self) -> u32 {
        match self {
            Wrap::Repeat => crate::formats::WRAP_REPEAT,
            Wrap::ClampToEdge => crate::formats::WRAP_CLAMP,
            Wrap::MirroredRepeat => crate::formats::WRAP_MIRROR,
        }
    }
}

/// Nearest texel or bilinear interpolation of the four nearest.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Filter {
    Nearest,
    #[default]
    Linear,
}

/// A glTF sampler. `min` and `mip` together are glTF's `minFilter`: `NEAREST` and `LINEAR`
/// sample level 0 only (`mip: None`); the `*_MIPMAP_*` values choose a level from the
/// pixel's footprint, `mip` saying whether two levels are blended (`Linear`, trilinear)
/// or the nearest level is taken. A sampler that leaves a filter undefined gets `Linear`
/// (glTF leaves the choice to the renderer: this is the smooth one), mip maps included.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Sampler {
    pub wrap_s: Wrap,
    pub wrap_t: Wrap,
    /// Filter when a texel covers more than a pixel (level of detail <= 0).
    pub mag: Filter,
    /// Filter within a level when a pixel covers more than a texel.
    pub min: Filter,
    /// Filter between mip levels; `None`: no mip maps (level 0 only).
    pub mip: Option<Filter>,
}

impl Default for Sampler {
    fn default() -> Self {
        Sampler {
            wrap_s: Wrap::Repeat,
            wrap_t: Wrap::Repeat,
            mag: Filter::Linear,
            min: Filter::Linear,
            mip: Some(Filter::Linear),
        }
    }
}

/// `KHR_texture_transform`: texture coordinates become `T * R * S * uv` with `S` the scale,
/// `R` a rotation by `rotation` radians (counter-clockwise in UV space, as the extension's
/// matrix says) and `T` the offset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    pub offset: Vec2,
    pub rotation: f32,
    pub scale: Vec2,
}

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform { offset: Vec2::ZERO, rotation: 0.0, scale: Vec2::ONE }
    }
}

impl UvTransform {
    /// Whether the transform leaves coordinates as they are (then it is not applied at all,
    /// so untransformed coordinates keep their exact bits).
    pub fn is_identity(&self) -> bool {
        *self == UvTransform::default()
    }

    /// The transformed coordinate, as the extension writes it: `u' = c sx u + s sy v + ox`,
    /// `v' = -s sx u + c sy v + oy` (`c`, `s`: cosine and sine of the rotation).
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        if self.is_identity() {
            return uv;
        }
        let (s, c) = self.rotation.sin_cos();
        let (su, sv) = (uv.x * self.scale.x, uv.y * self.scale.y);
        Vec2::new(c * su + s * sv + self.offset.x, -s * su + c * sv + self.offset.y)
    }
}

/// A material's use of a texture: which image, sampled how, with which coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureBinding {
    /// Index into [`super::Scene::textures`].
    pub image: usize,
    pub sampler: Sampler,
    /// The texture-coordinate set: 0 (`TEXCOORD_0`) or 1 (`TEXCOORD_1`).
    pub tex_coord: u32,
    pub transform: UvTransform,
}

/// How a material's alpha (base-colour factor alpha x texture alpha x vertex-colour alpha)
/// is used (glTF `alphaMode`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum AlphaMode {
    /// Alpha is ignored: the surface is opaque.
    #[default]
    Opaque,
    /// Alpha-tested: where alpha < `cutoff` there is no surface at all, for the raster and
    /// for every ray (glTF `MASK`, `alphaCutoff`, default 0.5).
    Mask { cutoff: f32 },
    /// glTF `BLEND`. hyrt has no transparency sorting: it renders such a material as
    /// [`AlphaMode::Mask`] at [`AlphaMode::BLEND_CUTOFF`] (the loader says so in a note),
    /// so a fence or a leaf card drawn with `BLEND` still has its holes.
    Blend,
}

impl AlphaMode {
    /// The cutoff a `BLEND` material is tested at: half-covered texels stay.
    pub const BLEND_CUTOFF: f32 = 0.5;
    /// glTF's default `alphaCutoff`.
    pub const DEFAULT_CUTOFF: f32 = 0.5;

    /// The cutoff the alpha test uses, `None` for an opaque material.
    pub fn cutoff(self) -> Option<f32> {
        match self {
            AlphaMode::Opaque => None,
            AlphaMode::Mask { cutoff } => Some(cutoff),
            AlphaMode::Blend => Some(Self::BLEND_CUTOFF),
        }
    }
}

/// Per-vertex attributes a mesh may carry besides positions and normals.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexAttributes {
    /// `TEXCOORD_0` and `TEXCOORD_1`, one per position each, when present.
    pub tex_coords: [Option<Vec<Vec2>>; 2],
    /// `COLOR_0` as linear RGBA (glTF vertex colours are linear), one per position.
    pub colors: Option<Vec<[f32; 4]>>,
    /// `TANGENT`, one per position: the object-space unit tangent (`xyz`, along increasing
    /// u of the normal texture's coordinates) and the bitangent's sign (`w`, +1 or -1:
    /// `bitangent = cross(normal, tangent.xyz) * w`). Without it, a normal-mapped mesh
    /// gets MikkTSpace tangents ([`crate::geometry::tangents`]).
    pub tangents: Option<Vec<[f32; 4]>>,
}
