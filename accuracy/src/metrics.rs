//! Errors of a configuration against the f64 reference: shadow-mask mismatches,
//! hit-point error relative to the scene size, image RMSE and FLIP.

use glam::Vec3;
use hyrt_core::formats::SurfaceRecord;
use hyrt_core::frame::{SHADOW_LIT, SHADOW_NO_RAY, SHADOW_OCCLUDED};
use hyrt_core::kernels::shading::linear_to_srgb8;

use super::reference::ReferenceFrame;

/// Shadow-mask agreement over the (pixel, light) pairs both sides traced: the pixel's
/// primary hit is the same triangle in the configuration and the reference, and both
/// traced a shadow ray (neither says `SHADOW_NO_RAY`). Pixels whose primary visibility
/// differs are counted by [`primary_mismatches`] instead.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ShadowComparison {
    /// Pairs compared.
    pub compared: u64,
    /// Occluded here, lit in the reference (shadow acne, false shadows).
    pub false_shadow: u64,
    /// Lit here, occluded in the reference (light leaks, missing shadows).
    pub light_leak: u64,
}

impl ShadowComparison {
    /// All mismatching pairs.
    pub fn mismatches(&self) -> u64 {
        self.false_shadow + self.light_leak
    }
    /// Mismatches over compared pairs (0 when nothing was compared).
    pub fn fraction(&self) -> f64 {
        if self.compared == 0 {
            0.0
        } else {
            self.mismatches() as f64 / self.compared as f64
        }
    }
}

/// Compare a shadow mask (`pixel * lights + light`, `SHADOW_*`) of the configuration's
/// `surfaces` with the reference's.
pub fn compare_shadows(reference: &ReferenceFrame, surfaces: &[SurfaceRecord], mask: &[u8]) -> ShadowComparison {
    let nl = if surfaces.is_empty() { 0 } else { mask.len() / surfaces.len() };
    let mut c = ShadowComparison::default();
    for (i, (h, s)) in reference.hits.iter().zip(surfaces).enumerate() {
        let Some(h) = h else { continue };
        if !s.is_hit() || s.triangle != h.triangle {
            continue;
        }
        for l in 0..nl {
            let (r, t) = (reference.shadow[i * nl + l], mask[i * nl + l]);
            if r == SHADOW_NO_RAY || t == SHADOW_NO_RAY {
                continue;
            }
            c.compared += 1;
            match (t, r) {
                (SHADOW_OCCLUDED, SHADOW_LIT) => c.false_shadow += 1,
                (SHADOW_LIT, SHADOW_OCCLUDED) => c.light_leak += 1,
                _ => {}
            }
        }
    }
    c
}

/// Pixels whose primary hit differs from the reference's: hit against miss, or another
/// triangle (silhouettes, shared edges, sub-pixel triangles).
pub fn primary_mismatches(reference: &ReferenceFrame, surfaces: &[SurfaceRecord]) -> u64 {
    reference
        .hits
        .iter()
        .zip(surfaces)
        .filter(|(h, s)| match h {
            None => s.is_hit(),
            Some(h) => !s.is_hit() || s.triangle != h.triangle,
        })
        .count() as u64
}

/// Distance of hit points from the reference's, over pixels with the same primary
/// triangle, divided by the scene extent (diagonal of the world bounds).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HitPointError {
    pub pixels: u64,
    pub max_rel: f64,
    pub mean_rel: f64,
}

/// [`HitPointError`] of `surfaces` against the reference.
pub fn hit_point_error(reference: &ReferenceFrame, surfaces: &[SurfaceRecord], scene_extent: f64) -> HitPointError {
    let (mut n, mut max, mut sum) = (0u64, 0f64, 0f64);
    for (h, s) in reference.hits.iter().zip(surfaces) {
        let Some(h) = h else { continue };
        if !s.is_hit() || s.triangle != h.triangle {
            continue;
        }
        let d = (Vec3::from(s.position).as_dvec3() - h.position).length();
        n += 1;
        max = max.max(d);
        sum += d;
    }
    let extent = if scene_extent > 0.0 { scene_extent } else { 1.0 };
    HitPointError { pixels: n, max_rel: max / extent, mean_rel: if n == 0 { 0.0 } else { sum / n as f64 / extent } }
}

/// Root mean square difference of the linear RGB channels of two images.
pub fn rmse(a: &[[f32; 4]], b: &[[f32; 4]]) -> f64 {
    assert_eq!(a.len(), b.len(), "images of different sizes");
    if a.is_empty() {
        return 0.0;
    }
    let sum: f64 = a.iter().zip(b).map(|(x, y)| (0..3).map(|c| (x[c] as f64 - y[c] as f64).powi(2)).sum::<f64>()).sum();
    (sum / (3 * a.len()) as f64).sqrt()
}

/// Encode a linear RGBA image as 8-bit sRGB RGB (the PNG encoding of the CLI).
pub fn srgb8(image: &[[f32; 4]]) -> Vec<u8> {
    image.iter().flat_map(|p| [linear_to_srgb8(p[0]), linear_to_srgb8(p[1]), linear_to_srgb8(p[2])]).collect()
}

/// A pixel is *wrong* ([`wrong_pixels`]) when a channel of its 8-bit sRGB encoding
/// differs from the reference's by more than this many codes. One code is tolerated: two
/// linear values a few f32 ulps apart (the pipeline's f32 shading against the reference's
/// f64 paths) round to neighbouring codes whenever a code boundary falls between them,
/// however small their difference.
pub const WRONG_PIXEL_CODES: u8 = 1;

/// Pixels of `test` whose 8-bit sRGB encoding (the PNG the renderer writes) differs from
/// `reference`'s by more than [`WRONG_PIXEL_CODES`] in some channel.
pub fn wrong_pixels(reference: &[[f32; 4]], test: &[[f32; 4]]) -> u64 {
    assert_eq!(reference.len(), test.len(), "images of different sizes");
    reference
        .iter()
        .zip(test)
        .filter(|(r, t)| (0..3).any(|c| linear_to_srgb8(r[c]).abs_diff(linear_to_srgb8(t[c])) > WRONG_PIXEL_CODES))
        .count() as u64
}

/// Mean LDR-FLIP error (Andersson et al. 2020) of `test` against `reference`, both
/// linear RGBA of `width` x `height`, compared as the sRGB 8-bit images the renderer
/// writes, at NVIDIA's default viewing condition (`nv_flip::DEFAULT_PIXELS_PER_DEGREE`:
/// a 0.7 m distant 4K monitor, 67 pixels per degree). `nv-flip` wraps NVIDIA's C++ code.
pub fn flip_mean(reference: &[[f32; 4]], test: &[[f32; 4]], width: u32, height: u32) -> f64 {
    assert_eq!(reference.len(), test.len(), "images of different sizes");
    assert_eq!(reference.len(), width as usize * height as usize, "image size");
    if reference.is_empty() {
        return 0.0;
    }
    let r = nv_flip::FlipImageRgb8::with_data(width, height, &srgb8(reference));
    let t = nv_flip::FlipImageRgb8::with_data(width, height, &srgb8(test));
    let map = nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    nv_flip::FlipPool::from_image(&map).mean() as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rmse_of_a_constant_offset_is_the_offset() {
        let a = vec![[0.5f32, 0.25, 0.0, 1.0]; 10];
        let b = vec![[0.75f32, 0.5, 0.25, 1.0]; 10];
        assert!((rmse(&a, &b) - 0.25).abs() < 1e-12);
        assert_eq!(rmse(&a, &a), 0.0);
    }

    #[test]
    fn wrong_pixels_tolerate_one_srgb_code_and_count_two() {
        // linear_to_srgb8(0.2) is 124; 0.2 and a value two codes up.
        let a = vec![[0.2f32, 0.2, 0.2, 1.0]; 4];
        let mut b = a.clone();
        let code = linear_to_srgb8(0.2);
        let up = |codes: u8| {
            let mut x = 0.2f32;
            while linear_to_srgb8(x) < code + codes {
                x += 1e-4;
            }
            x
        };
        b[0][1] = up(1);
        assert_eq!(wrong_pixels(&a, &b), 0, "one code is rounding");
        b[1][2] = up(2);
        b[3][0] = 1.0;
        assert_eq!(wrong_pixels(&a, &b), 2);
        assert_eq!(wrong_pixels(&a, &a), 0);
    }

    #[test]
    fn flip_is_zero_for_equal_images_and_grows_with_the_difference() {
        let (w, h) = (32, 32);
        let a: Vec<[f32; 4]> = (0..w * h).map(|i| [(i % w) as f32 / w as f32, 0.3, 0.6, 1.0]).collect();
        let mut b = a.clone();
        for p in b.iter_mut().take(100) {
            p[0] = 1.0 - p[0];
        }
        let mut c = a.clone();
        for p in c.iter_mut().take(400) {
            p[0] = 1.0 - p[0];
        }
        assert_eq!(flip_mean(&a, &a, w as u32, h as u32), 0.0);
        let (fb, fc) = (flip_mean(&a, &b, w as u32, h as u32), flip_mean(&a, &c, w as u32, h as u32));
        assert!(fb > 0.0 && fc > fb, "{fb} {fc}");
    }
}
