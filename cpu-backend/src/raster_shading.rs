//! Stage `raster_shading`: the ordinary raster shader (paper 3.4): Lambert from
//! every light plus ambient, on the pixels of rasterized objects. Rasterized
//! objects receive ray-traced shadows: the shader multiplies each light by the
//! shadow mask. Ray-traced objects are shaded here too only when the
//! composition weight is below 1 (the frame models only what it needs).
//!
//! Inputs: surfaces, the shadow mask, objects, lights, the composition weight.
//! Output: the raster image (linear RGBA, background where nothing is shaded).

use glam::Vec3;
use hyrt_core::formats::{LightRecord, ObjectRecord, SurfaceRecord, OBJ_RAY_TRACED};
use hyrt_core::kernels::shading::{shade_raster_pixel, BACKGROUND};
use rayon::prelude::*;

/// The stage. `shadow` is indexed `pixel * lights.len() + light`.
pub fn raster_shading(
    surfaces: &[SurfaceRecord],
    shadow: &[u8],
    objects: &[ObjectRecord],
    lights: &[LightRecord],
    weight: f32,
) -> Vec<[f32; 4]> {
    let mut out = Vec::new();
    raster_shading_into(surfaces, shadow, objects, lights, weight < 1.0, &mut out);
    out
}

/// [`raster_shading`] into a caller-owned image, reusing its allocation;
/// `shade_ray_traced` (the weight is below 1) shades ray-traced objects too, as the
/// plan's [`Step::RasterShading`](hyrt_core::plan::Step::RasterShading) says.
pub fn raster_shading_into(
    surfaces: &[SurfaceRecord],
    shadow: &[u8],
    objects: &[ObjectRecord],
    lights: &[LightRecord],
    shade_ray_traced: bool,
    out: &mut Vec<[f32; 4]>,
) {
    let nl = lights.len();
    let shade_rt_objects = shade_ray_traced;
    let background = Vec3::from(BACKGROUND).extend(1.0).into();
    surfaces
        .par_iter()
        .enumerate()
        .with_min_len(1024)
        .map(|(i, s)| {
            if !s.is_hit() {
                return background;
            }
            let obj = &objects[s.object as usize];
            if obj.flags & OBJ_RAY_TRACED != 0 && !shade_rt_objects {
                return [0.0; 4];
            }
            shade_raster_pixel(s, obj, &shadow[i * nl..(i + 1) * nl], lights).extend(1.0).into()
        })
        .collect_into_vec(out);
}
