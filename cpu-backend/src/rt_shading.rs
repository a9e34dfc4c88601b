//! Stage `rt_shading`: shade the pixels of ray-traced objects (paper 3.3) with
//! Lambert + Blinn-Phong specular from every light, times the traced shadow
//! visibility.
//!
//! Inputs: surfaces, the shadow mask, objects, lights, the eye. Output: the
//! ray-traced image (linear RGBA; alpha 1 on ray-traced pixels, 0 elsewhere).

use glam::Vec3;
use hyrt_core::formats::{LightRecord, ObjectRecord, SurfaceRecord, OBJ_RAY_TRACED};
use hyrt_core::kernels::shading::shade_rt_pixel;
use rayon::prelude::*;

/// The stage. `shadow` is indexed `pixel * lights.len() + light`.
pub fn rt_shading(
    surfaces: &[SurfaceRecord],
    shadow: &[u8],
    objects: &[ObjectRecord],
    lights: &[LightRecord],
    eye: Vec3,
) -> Vec<[f32; 4]> {
    let mut out = Vec::new();
    rt_shading_into(surfaces, shadow, objects, lights, eye, &mut out);
    out
}

/// [`rt_shading`] into a caller-owned image, reusing its allocation.
pub fn rt_shading_into(
    surfaces: &[SurfaceRecord],
    shadow: &[u8],
    objects: &[ObjectRecord],
    lights: &[LightRecord],
    eye: Vec3,
    out: &mut Vec<[f32; 4]>,
) {
    let nl = lights.len();
    surfaces
        .par_iter()
        .enumerate()
        .with_min_len(1024)
        .map(|(i, s)| {
            if !s.is_hit() {
                return [0.0; 4];
            }
            let obj = &objects[s.object as usize];
            if obj.flags & OBJ_RAY_TRACED == 0 {
                return [0.0; 4];
            }
            shade_rt_pixel(s, obj, &shadow[i * nl..(i + 1) * nl], lights, eye).extend(1.0).into()
        })
        .collect_into_vec(out);
}
