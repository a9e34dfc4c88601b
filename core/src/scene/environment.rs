//! What rays that leave the scene see: the default sky, or an equirectangular (latitude-
//! longitude) environment map read from a Radiance HDR (`.hdr`) or OpenEXR (`.exr`) file.
//!
//! Only secondary rays (reflection, refraction) see the environment; pixels no primary ray
//! hits keep the frame's [`crate::kernels::shading::BACKGROUND`]. The lookup is the kernel
//! [`crate::kernels::environment::environment_radiance`], whose docs give the mapping from
//! directions to texels.
//!
//! # Layout of a map
//!
//! `width x height` texels of linear RGB radiance (alpha is not used; the loader stores
//! 1), row-major, row 0 on top: texel `(i, j)` (column `i`, row `j`) is
//! `texels[j * width + i]`. Its centre is seen along the direction of texture coordinates
//! `u = (i + 0.5) / width`, `v = (j + 0.5) / height`, with (y up, the world's +Y)
//!
//! ```text
//! phi = 2 pi u,  theta = pi v,
//! d = (sin theta sin phi,  cos theta,  -sin theta cos phi)
//! ```
//!
//! so row 0 is the top (+Y), the middle row the horizon, the last row straight down; the
//! left edge (`u = 0`) and the right edge (`u = 1`) meet at -Z, the image's centre
//! (`u = 0.5`) is +Z, `u = 0.25` is +X and `u = 0.75` is -X. A camera looking down -Z
//! (the default glTF view) therefore sees the map's seam ahead, and a mirror facing it the
//! map's centre. This is Mitsuba 3's lat-long convention (`u = atan2(x, -z) / 2 pi`
//! wrapped into `[0, 1)`, `v = acos(y) / pi`), so an HDRI is oriented as there. Seen from
//! inside, the map is not mirrored: facing any column with +Y up, the columns to its
//! right in the stored image lie to the viewer's right (facing the centre, +Z, the right
//! is -X, `u = 0.75`).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::files::{Disk, SceneFiles};
use crate::SceneError;

/// Defined with the other errors in [`crate::error`]; re-exported here, where maps are made.
pub use crate::error::EnvironmentMapError;

/// What rays that leave the scene see. The default is [`Environment::Sky`].
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Environment {
    /// The default sky ([`crate::kernels::bounce::sky`]): a gradient from the horizon to
    /// the zenith above, the ground colour below.
    #[default]
    Sky,
    /// An equirectangular map (shared: cloning a scene does not copy its texels).
    Map(Arc<EnvironmentMap>),
}

impl Environment {
    /// The map of a Radiance HDR (`.hdr`) or OpenEXR (`.exr`) file, chosen by the
    /// extension (any case). Errors name the file: [`SceneError::Io`] when it cannot be
    /// read, [`SceneError::Environment`] when it is not such an image or holds texels
    /// that cannot be rendered (see [`EnvironmentMap::new`]).
    pub fn load(path: &Path) -> Result<Environment, SceneError> {
        Environment::load_from(path, &Disk)
    }

    /// [`Environment::load`] reading the file from `files`.
    pub fn load_from(path: &Path, files: &dyn SceneFiles) -> Result<Environment, SceneError> {
        load_map(path, files).map(|m| Environment::Map(Arc::new(m)))
    }

    /// The map, if there is one.
    pub fn map(&self) -> Option<&EnvironmentMap> {
        match self {
            Environment::Sky => None,
            Environment::Map(m) => Some(m),
        }
    }

    /// A short description for notes and reports: `default sky` or `W x H map from FILE`.
    pub fn describe(&self) -> String {
        match self {
            Environment::Sky => "default sky".into(),
            Environment::Map(m) => match &m.source {
                Some(p) => format!("{}x{} map from {}", m.width, m.height, p.display()),
                None => format!("{}x{} map", m.width, m.height),
            },
        }
    }
}

/// The most bytes one decoded buffer of an environment map may take: the `image` crate's
/// default allocation limit (512 MiB), which its decoders apply to the image they return.
/// An 8192 x 4096 map in RGBA f32 takes exactly this much, the largest HDRI sizes in common
/// use (16k x 8k) do not fit.
pub const MAX_DECODED_MAP_BYTES: usize = 512 << 20;

/// An equirectangular environment map: linear RGB radiance, laid out as the module docs
/// say. Built through [`EnvironmentMap::new`] (or [`Environment::load`]), so every map
/// holds `width * height >= 1` texels whose colour channels are finite and non-negative.
#[derive(Clone, PartialEq)]
pub struct EnvironmentMap {
    width: u32,
    height: u32,
    texels: Vec<[f32; 4]>,
    source: Option<PathBuf>,
}

impl std::fmt::Debug for EnvironmentMap {
    /// The size and the source, not the texels.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EnvironmentMap")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("source", &self.source)
            .finish_non_exhaustive()
    }
}

impl EnvironmentMap {
    /// A map of `width x height` texels, row 0 on top (module docs). Alpha is kept but
    /// not used. Errors: a zero size, a texel count other than `width * height`, a colour
    /// channel that is NaN, infinite or negative (the first such texel is named).
    pub fn new(width: u32, height: u32, texels: Vec<[f32; 4]>) -> Result<EnvironmentMap, EnvironmentMapError> {
        if width == 0 || height == 0 {
            return Err(EnvironmentMapError::ZeroSize { width, height });
        }
        if texels.len() as u64 != width as u64 * height as u64 {
            return Err(EnvironmentMapError::SizeMismatch { width, height, texels: texels.len() });
        }
        if let Some(k) = texels.iter().position(|t| !t[..3].iter().all(|c| c.is_finite() && *c >= 0.0)) {
            let t = texels[k];
            return Err(EnvironmentMapError::BadTexel {
                x: (k % width as usize) as u32,
                y: (k / width as usize) as u32,
                rgb: [t[0], t[1], t[2]],
            });
        }
        Ok(EnvironmentMap { width, height, texels, source: None })
    }

    /// Texels per row.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Rows.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The texels, row-major, row 0 on top.
    pub fn texels(&self) -> &[[f32; 4]] {
        &self.texels
    }

    /// Texel `(i, j)`: column `i < width`, row `j < height`.
    #[inline]
    pub fn texel(&self, i: u32, j: u32) -> [f32; 4] {
        self.texels[j as usize * self.width as usize + i as usize]
    }

    /// The file the map was read from, if it was.
    pub fn source(&self) -> Option<&Path> {
        self.source.as_deref()
    }
}

/// Read and validate a map file (see [`Environment::load`]).
fn load_map(path: &Path, files: &dyn SceneFiles) -> Result<EnvironmentMap, SceneError> {
    let fail = |problem| SceneError::Environment { path: path.to_path_buf(), problem };
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    let (format, name) = match ext.as_deref() {
        Some("hdr") => (image::ImageFormat::Hdr, "Radiance HDR"),
        Some("exr") => (image::ImageFormat::OpenExr, "OpenEXR"),
        _ => return Err(fail(EnvironmentMapError::UnknownFormat)),
    };
    let bytes = files.read(path).map_err(|source| SceneError::Io { path: path.to_path_buf(), source })?;
    if format == image::ImageFormat::OpenExr {
        check_exr_header(&bytes).map_err(fail)?;
    }
    // The decoders check the header against the image crate's default limits (512 MiB
    // per allocation), so a huge or lying header is an error, not an abort.
    let decoded = image::ImageReader::with_format(std::io::Cursor::new(bytes), format)
        .decode()
        .map_err(|e| fail(EnvironmentMapError::Decode { format: name, message: e.to_string() }))?;
    // RGB (what both decoders give) is taken as is; RGBA texels are built from it once.
    let rgb = decoded.into_rgb32f();
    let (width, height) = rgb.dimensions();
    let texels = rgb.pixels().map(|p| [p.0[0], p.0[1], p.0[2], 1.0]).collect();
    drop(rgb);
    let mut map = EnvironmentMap::new(width, height, texels).map_err(fail)?;
    map.source = Some(path.to_path_buf());
    Ok(map)
}

/// Check what an OpenEXR file's headers make a decoder allocate before any pixel is read,
/// against [`MAX_DECODED_MAP_BYTES`]. `image` checks only the display window (the image it
/// returns); the `exr` crate sizes its buffers from each layer's data window and block size,
/// so a header claiming a huge data window behind a small display window made a 604-byte
/// file allocate 1.7 GB (fuzz seed 1, execution 484588; `loader_regressions.rs`).
fn check_exr_header(bytes: &[u8]) -> Result<(), EnvironmentMapError> {
    use exr::meta::attribute::LevelMode;
    use exr::meta::BlockDescription;
    let decode = |message: String| EnvironmentMapError::Decode { format: "OpenEXR", message };
    let meta = exr::meta::MetaData::read_from_buffered(bytes, false).map_err(|e| decode(e.to_string()))?;
    let check = |what: String, factors: &[usize]| {
        let bytes = factors.iter().try_fold(1usize, |a, &f| a.checked_mul(f)).unwrap_or(usize::MAX);
        if bytes > MAX_DECODED_MAP_BYTES {
            return Err(EnvironmentMapError::TooLarge { what, bytes, limit: MAX_DECODED_MAP_BYTES });
        }
        Ok(())
    };
    for (k, header) in meta.headers.iter().enumerate() {
        let (data, display) = (header.layer_size, header.shared_attributes.display_window.size);
        // Every channel's sample is at most 4 bytes (f32, u32); the returned image is RGBA
        // f32 at most.
        let sample_bytes = header.channels.list.len().saturating_mul(4);
        // Resolution levels below the full one add at most 1/3 (mip maps) or 3 (rip maps)
        // of its pixels: `4` bounds both.
        let levels = match header.blocks {
            BlockDescription::Tiles(t) if t.level_mode != LevelMode::Singular => 4,
            _ => 1,
        };
        check(format!("layer {k}'s {}x{} data window", data.0, data.1), &[data.0, data.1, sample_bytes, levels])?;
        check(format!("layer {k}'s {}x{} display window", display.0, display.1), &[display.0, display.1, 16])?;
        // A block's pixels decompressed: a tile, or a run of 1 to 256 scan lines (as many as
        // its compression packs together: `scan_lines_per_block`).
        let block = match header.blocks {
            BlockDescription::Tiles(t) => [t.tile_size.0, t.tile_size.1],
            BlockDescription::ScanLines => [data.0, header.compression.scan_lines_per_block()],
        };
        check(format!("layer {k}'s {}x{} block", block[0], block[1]), &[block[0], block[1], sample_bytes])?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_rejects_what_is_not_radiance() {
        assert_eq!(EnvironmentMap::new(0, 4, vec![]), Err(EnvironmentMapError::ZeroSize { width: 0, height: 4 }));
        assert_eq!(
            EnvironmentMap::new(2, 2, vec![[0.0; 4]; 3]),
            Err(EnvironmentMapError::SizeMismatch { width: 2, height: 2, texels: 3 })
        );
        let mut t = vec![[0.5, 0.5, 0.5, 1.0]; 6];
        t[4] = [0.5, -0.25, 0.5, 1.0];
        assert_eq!(
            EnvironmentMap::new(3, 2, t.clone()),
            Err(EnvironmentMapError::BadTexel { x: 1, y: 1, rgb: [0.5, -0.25, 0.5] })
        );
        t[4] = [f32::INFINITY, 0.0, 0.0, 1.0];
        assert!(matches!(EnvironmentMap::new(3, 2, t.clone()), Err(EnvironmentMapError::BadTexel { x: 1, y: 1, .. })));
        t[4] = [0.0, 0.0, f32::NAN, 1.0];
        assert!(matches!(EnvironmentMap::new(3, 2, t.clone()), Err(EnvironmentMapError::BadTexel { x: 1, y: 1, .. })));
        // Alpha is not radiance: any value passes.
        t[4] = [0.0, 0.0, 0.0, f32::NAN];
        let m = EnvironmentMap::new(3, 2, t).unwrap();
        assert_eq!((m.width(), m.height(), m.texel(2, 1)), (3, 2, [0.5, 0.5, 0.5, 1.0]));
    }
}
