//! Linear RGBA images to 8-bit sRGB PNG files.

use std::path::Path;

use hyrt_core::kernels::shading::linear_to_srgb8;

use crate::Error;

/// Encode a linear RGBA image (row 0 on top) as an sRGB PNG. Alpha is written
/// as-is (clamped), so the ray-traced image keeps its coverage.
pub fn write_png(path: &Path, width: u32, height: u32, pixels: &[[f32; 4]]) -> Result<(), Error> {
    assert_eq!(pixels.len(), (width * height) as usize, "image size mismatch");
    let mut bytes = Vec::with_capacity(pixels.len() * 4);
    for p in pixels {
        bytes.extend_from_slice(&[
            linear_to_srgb8(p[0]),
            linear_to_srgb8(p[1]),
            linear_to_srgb8(p[2]),
            (p[3].clamp(0.0, 1.0) * 255.0 + 0.5) as u8,
        ]);
    }
    image::save_buffer(path, &bytes, width, height, image::ExtendedColorType::Rgba8).map_err(|e| match e {
        image::ImageError::IoError(source) => Error::Write { path: path.to_path_buf(), source },
        other => Error::Image { path: path.to_path_buf(), message: other.to_string() },
    })
}
