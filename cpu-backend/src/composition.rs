//! Stage `composition`: the final image as the weighted mean of the raster and
//! ray-traced images (paper 3.5): `(1 - weight) * raster + weight * rt` where the
//! ray-traced image has coverage (alpha > 0), the raster image elsewhere.
//!
//! Inputs: both images and the weight in [0, 1]. Output: the final linear RGBA image.
//! A plan that made only one of the images composes by copying it
//! ([`Composition::CopyRaster`], [`Composition::RtOverBackground`]): the same bits
//! the weighted mean gives there (see [`hyrt_core::plan`]).

use glam::Vec4;
use hyrt_core::kernels::shading::{compose, BACKGROUND_RGBA};
use hyrt_core::plan::Composition;
use rayon::prelude::*;

pub(crate) mod lanes;

/// The stage.
pub fn composition(raster: &[[f32; 4]], rt: &[[f32; 4]], weight: f32) -> Vec<[f32; 4]> {
    let mut out = Vec::new();
    composition_into(Composition::WeightedMean, raster, rt, weight, &mut out);
    out
}

/// [`composition`] into a caller-owned image, reusing its allocation, composing as
/// `mode` says: the weighted mean of both images, or a copy of the one image the
/// plan made (the other is not read and may be empty).
pub fn composition_into(mode: Composition, raster: &[[f32; 4]], rt: &[[f32; 4]], weight: f32, out: &mut Vec<[f32; 4]>) {
    match mode {
        Composition::WeightedMean => assert_eq!(raster.len(), rt.len(), "images of different sizes"),
        Composition::CopyRaster => {
            out.clear();
            out.extend_from_slice(raster);
            return;
        }
        Composition::RtOverBackground => {
            let none = [0.0; 4];
            rt.par_iter().with_min_len(1024).map(|t| composition_pixel(mode, &none, t, weight)).collect_into_vec(out);
            return;
        }
    }
    raster
        .par_iter()
        .zip(rt.par_iter())
        .with_min_len(1024)
        .map(|(r, t)| composition_pixel(mode, r, t, weight))
        .collect_into_vec(out);
}

/// The stage's kernel for one pixel with raster colour `r` and ray-traced colour `t` (the
/// image `mode` does not read may be anything): what [`composition_into`] writes there;
/// the fused frame (`crate::fused`) calls it tile by tile.
#[inline]
pub fn composition_pixel(mode: Composition, r: &[f32; 4], t: &[f32; 4], weight: f32) -> [f32; 4] {
    match mode {
        Composition::CopyRaster => *r,
        Composition::RtOverBackground if t[3] > 0.0 => *t,
        Composition::RtOverBackground => BACKGROUND_RGBA,
        Composition::WeightedMean if t[3] > 0.0 => {
            let (r, t) = (Vec4::from(*r), Vec4::from(*t));
            compose(r.truncate(), t.truncate(), weight).extend(1.0).into()
        }
        Composition::WeightedMean => *r,
    }
}
