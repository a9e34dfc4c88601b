//! Linear RGBA images to files: 8-bit sRGB PNG ([`write_png`], or through an exposure and
//! a tone-mapping operator: [`write_png_tone_mapped`]) or linear 32-bit float OpenEXR
//! ([`write_exr`]).

use std::path::Path;

use hyrt_core::kernels::shading::rgba_to_srgb8;
use hyrt_core::kernels::tone_map::{display, exposure_scale, ToneMap};

use crate::Error;

/// The facade's error for an `image` crate failure writing `path`.
fn write_error(path: &Path, e: image::ImageError) -> Error {
    match e {
        image::ImageError::IoError(source) => Error::Write { path: path.to_path_buf(), source },
        other => Error::Image { path: path.to_path_buf(), message: other.to_string() },
    }
}

/// Encode a linear RGBA image (row 0 on top) as an sRGB PNG. Alpha is written
/// as-is (clamped), so the ray-traced image keeps its coverage.
pub fn write_png(path: &Path, width: u32, height: u32, pixels: &[[f32; 4]]) -> Result<(), Error> {
    write_png_tone_mapped(path, width, height, pixels, 0.0, ToneMap::None)
}

/// [`write_png`] with every colour first scaled by an exposure of `exposure_stops` and
/// mapped by `tone_map` ([`hyrt_core::kernels::tone_map::display`]); 0 stops and
/// [`ToneMap::None`] write what [`write_png`] writes.
pub fn write_png_tone_mapped(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[[f32; 4]],
    exposure_stops: f32,
    tone_map: ToneMap,
) -> Result<(), Error> {
    assert_eq!(pixels.len(), (width * height) as usize, "image size mismatch");
    let scale = exposure_scale(exposure_stops);
    let bytes: Vec<u8> = pixels.iter().flat_map(|&p| rgba_to_srgb8(display(p, scale, tone_map))).collect();
    image::save_buffer(path, &bytes, width, height, image::ExtendedColorType::Rgba8).map_err(|e| write_error(path, e))
}

/// Write a linear RGBA image (row 0 on top) as an OpenEXR file of 32-bit float `R`, `G`,
/// `B`, `A` channels (the `image` crate's encoder: RLE compression, lossless, in 64 x 64
/// tiles): the values exactly, unclamped and without a transfer curve, so reading the file
/// back gives the same bits. An image of zero size or whose
/// pixel count is not `width * height` is an [`Error::Image`].
pub fn write_exr(path: &Path, width: u32, height: u32, pixels: &[[f32; 4]]) -> Result<(), Error> {
    let wrong = |message: String| Error::Image { path: path.to_path_buf(), message };
    if width == 0 || height == 0 {
        return Err(wrong(format!("an OpenEXR image needs at least one pixel, not {width}x{height}")));
    }
    if pixels.len() as u64 != width as u64 * height as u64 {
        return Err(wrong(format!("{} pixels for a {width}x{height} image", pixels.len())));
    }
    let flat: Vec<f32> = pixels.iter().flatten().copied().collect();
    let buffer = image::Rgba32FImage::from_raw(width, height, flat).expect("the length was checked above");
    buffer.save_with_format(path, image::ImageFormat::OpenExr).map_err(|e| write_error(path, e))
}
