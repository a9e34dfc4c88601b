//! Linear RGBA images to 8-bit sRGB PNG files.

use std::path::Path;

use hyrt_core::kernels::shading::rgba_to_srgb8;

use crate::Error;

/// Encode a linear RGBA image (row 0 on top) as an sRGB PNG. Alpha is written
/// as-is (clamped), so the ray-traced image keeps its coverage.
pub fn write_png(path: &Path, width: u32, height: u32, pixels: &[[f32; 4]]) -> Result<(), Error> {
    assert_eq!(pixels.len(), (width * height) as usize, "image size mismatch");
    let bytes: Vec<u8> = pixels.iter().flat_map(|&p| rgba_to_srgb8(p)).collect();
    image::save_buffer(path, &bytes, width, height, image::ExtendedColorType::Rgba8).map_err(|e| match e {
        image::ImageError::IoError(source) => Error::Write { path: path.to_path_buf(), source },
        other => Error::Image { path: path.to_path_buf(), message: other.to_string() },
    })
}
