//! Stage `raster_shading`: the ordinary raster shader (paper 3.4): Lambert from
//! every light plus ambient, on the pixels of rasterized objects. Rasterized
//! objects receive ray-traced shadows: the shader multiplies each light by the
//! shadow mask. Ray-traced objects are shaded here too only when the
//! composition weight is below 1 (the frame models only what it needs).
//!
//! Inputs: surfaces, the shadow mask, the materials (objects; with textures or vertex
//! colours also the G-buffer's barycentrics and the surface tables), the eye, lights, the
//! composition weight.
//! Output: the raster image (linear RGBA, background where nothing is shaded).

use glam::Vec3;
use hyrt_core::formats::{GBufferTexel, ObjectRecord, SurfaceRecord, OBJ_RAY_TRACED};
use hyrt_core::kernels::bounce::primary_parent;
use hyrt_core::kernels::shading::{shade_raster_pixel, AmbientLight, BACKGROUND_RGBA};
use hyrt_core::kernels::soft_shadow::{surface_slots, FilteredVisibility, Lights, SurfaceShadow};
use hyrt_core::kernels::texture::Materials;
use rayon::prelude::*;

pub(crate) mod lanes;

/// The stage on a scene without textures or vertex colours, seen from `eye` under the
/// frame's `ambient` light (`WorldGeometry::ambient`). `shadow` is indexed
/// `pixel * lights.len() + light`.
pub fn raster_shading<'l>(
    surfaces: &[SurfaceRecord],
    shadow: &[u8],
    objects: &[ObjectRecord],
    lights: impl Into<Lights<'l>>,
    ambient: &AmbientLight,
    eye: Vec3,
    weight: f32,
) -> Vec<[f32; 4]> {
    let lights: Lights = lights.into();
    let mut out = Vec::new();
    let primary =
        Primary { gbuffer: &[], materials: &Materials::plain(objects), ambient, eye, visibility: Default::default() };
    raster_shading_into(surfaces, shadow, &primary, lights, weight < 1.0, &mut out);
    out
}

/// What shading a primary hit reads besides its surface and the lights: the materials, the
/// frame's ambient light, the eye (the view direction; where materials vary over surfaces
/// also the footprint), where materials vary, the G-buffer's barycentrics, and where the
/// frame denoised its stochastic shadows, `shadow_denoise`'s channels.
#[derive(Clone, Copy)]
pub struct Primary<'a> {
    pub gbuffer: &'a [GBufferTexel],
    pub materials: &'a Materials<'a>,
    pub ambient: &'a AmbientLight,
    pub eye: Vec3,
    pub visibility: FilteredVisibility<'a>,
}

impl Primary<'_> {
    /// The record pixel `i`'s object is shaded with: [`Materials::at`] where materials
    /// vary, the object's own record elsewhere.
    #[inline]
    pub fn object(&self, i: usize, s: &SurfaceRecord) -> ObjectRecord {
        if self.materials.varying() {
            primary_parent(&self.gbuffer[i], s, self.eye, i as u32, self.materials).object
        } else {
            self.materials.objects[s.object as usize]
        }
    }
}

/// [`raster_shading`] into a caller-owned image, reusing its allocation, with any
/// materials; `shade_ray_traced` (the weight is below 1) shades ray-traced objects too,
/// as the plan's [`Step::RasterShading`](hyrt_core::plan::Step::RasterShading) says.
pub fn raster_shading_into<'l>(
    surfaces: &[SurfaceRecord],
    shadow: &[u8],
    primary: &Primary,
    lights: impl Into<Lights<'l>>,
    shade_ray_traced: bool,
    out: &mut Vec<[f32; 4]>,
) {
    let lights: Lights = lights.into();
    let nl = surface_slots(&lights, &primary.ambient.occlusion);
    surfaces
        .par_iter()
        .enumerate()
        .with_min_len(1024)
        .map(|(i, s)| raster_shading_pixel(primary, lights, shade_ray_traced, i, s, pixel_codes(shadow, nl, i, s)))
        .collect_into_vec(out);
}

/// The stage's kernel for one pixel `i` with surface `s` and its shadow codes (one per
/// light): the background on a miss, transparent black on a ray-traced object unless
/// `shade_ray_traced`, else the raster shader. What [`raster_shading_into`] writes at `i`;
/// the fused frame (`crate::fused`) calls it tile by tile.
#[inline]
pub fn raster_shading_pixel<'l>(
    primary: &Primary,
    lights: impl Into<Lights<'l>>,
    shade_ray_traced: bool,
    i: usize,
    s: &SurfaceRecord,
    shadow: &[u8],
) -> [f32; 4] {
    let lights: Lights = lights.into();
    if !s.is_hit() {
        return BACKGROUND_RGBA;
    }
    let obj = &primary.materials.objects[s.object as usize];
    if obj.flags & OBJ_RAY_TRACED != 0 && !shade_ray_traced {
        return [0.0; 4];
    }
    let shaded;
    let obj = if primary.materials.varying() {
        shaded = primary.object(i, s);
        &shaded
    } else {
        obj
    };
    raster_shading_record(primary, lights, shade_ray_traced, s, obj, primary.visibility.surface(i, shadow))
}

/// [`raster_shading_pixel`] with the pixel's record given: `record` is
/// [`Primary::object`] of the pixel (the fused frame makes it once per pixel and reads it
/// in every stage).
#[inline]
pub fn raster_shading_record<'l>(
    primary: &Primary,
    lights: impl Into<Lights<'l>>,
    shade_ray_traced: bool,
    s: &SurfaceRecord,
    record: &ObjectRecord,
    shadow: SurfaceShadow,
) -> [f32; 4] {
    let lights: Lights = lights.into();
    if !s.is_hit() {
        return BACKGROUND_RGBA;
    }
    if primary.materials.objects[s.object as usize].flags & OBJ_RAY_TRACED != 0 && !shade_ray_traced {
        return [0.0; 4];
    }
    shade_raster_pixel(s, record, shadow, lights, primary.ambient, primary.eye).extend(1.0).into()
}

/// Pixel `i`'s shadow codes in the frame's mask (`nl` per pixel): a miss has none (a plan
/// without shadow rays writes no mask, and no hit reads one then).
#[inline]
pub(crate) fn pixel_codes<'m>(shadow: &'m [u8], nl: usize, i: usize, s: &SurfaceRecord) -> &'m [u8] {
    if s.is_hit() {
        &shadow[i * nl..(i + 1) * nl]
    } else {
        &[]
    }
}
