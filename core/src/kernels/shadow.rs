//! Shadow-ray kernels of the `compaction` and `shadow_rays` stages (paper 3.3): which
//! (pixel, light) pairs need a shadow ray, the ray itself, and the `SHADOW_*` code a
//! traced ray leaves in the per-(pixel, light) mask.
//!
//! WGSL mirrors: `needs_shadow_ray`, `shadow_ray` in the GPU backend's `compaction.wgsl`,
//! `shadow_code` in `shadow_rays.wgsl`.

use glam::Vec3;

use crate::formats::{
    LightRecord, RayRecord, SurfaceRecord, LIGHT_DIRECTIONAL, RAY_KIND_SHADOW, SHADOW_LIT, SHADOW_OCCLUDED,
};
use crate::kernels::ray::offset_ray_origin;
use crate::kernels::shading::{light_can_contribute, light_incidence};

/// Shadow rays to point lights end just before the light: `t_max = 1 - 2^-16`
/// of the origin-to-light segment. A light sitting exactly on a surface (a hard
/// case) is then not occluded by that surface: the watertight test's t error is a
/// few ulp (pbrt-v4's gamma(3) conservative bound), far below 2^-16.
pub const SHADOW_T_MAX_POINT: f32 = 1.0 - 1.0 / 65536.0;

/// Whether the pixel's surface needs a shadow ray towards `light`: it has a
/// primary hit and the light can contribute there (front side of both normals,
/// non-zero energy). The cheap test of the flag pass.
#[inline]
pub fn needs_shadow_ray(s: &SurfaceRecord, light: &LightRecord) -> bool {
    if !s.is_hit() {
        return false;
    }
    let (l, e) = light_incidence(light, Vec3::from(s.position));
    light_can_contribute(Vec3::from(s.geometric_normal), Vec3::from(s.normal), l, e)
}

/// The shadow ray from a surface point to a light. Call only where
/// [`needs_shadow_ray`] holds.
#[inline]
pub fn shadow_ray(s: &SurfaceRecord, light: &LightRecord, light_index: u32, pixel: u32) -> RayRecord {
    let p = Vec3::from(s.position);
    // Off the surface by the reconstructed point's own error bound, on the side the
    // viewer saw (the normal is oriented by reconstruction from the raster's facing).
    let origin = offset_ray_origin(p, s.position_error, Vec3::from(s.geometric_normal));
    let (direction, t_max) = if light.kind == LIGHT_DIRECTIONAL {
        (-Vec3::from(light.position_or_direction), f32::INFINITY)
    } else {
        (Vec3::from(light.position_or_direction) - origin, SHADOW_T_MAX_POINT)
    };
    shadow_ray_record(origin.into(), direction.into(), t_max, light_index, pixel)
}

/// The record of a shadow ray from `origin` along `direction` up to `t_max` (from
/// [`shadow_ray`]'s origin offset and direction).
#[inline]
pub fn shadow_ray_record(origin: [f32; 3], direction: [f32; 3], t_max: f32, light_index: u32, pixel: u32) -> RayRecord {
    RayRecord {
        origin,
        t_min: 0.0,
        direction,
        t_max,
        pixel,
        kind: RAY_KIND_SHADOW,
        depth: 0,
        light: light_index,
        throughput: [1.0; 3],
        cone: 0.0,
    }
}

/// The shadow-mask code of a traced shadow ray: [`SHADOW_OCCLUDED`] if something
/// blocked it, else [`SHADOW_LIT`]. Pairs without a ray keep `SHADOW_NO_RAY`.
#[inline]
pub fn shadow_code(occluded: bool) -> u8 {
    if occluded {
        SHADOW_OCCLUDED
    } else {
        SHADOW_LIT
    }
}
