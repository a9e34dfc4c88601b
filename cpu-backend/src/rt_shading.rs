//! Stage `rt_shading`: shade the pixels of ray-traced objects (paper 3.3) with
//! Lambert + Blinn-Phong specular from every light, times the traced shadow
//! visibility.
//!
//! Inputs: surfaces, the shadow mask, the materials (objects; with textures or vertex
//! colours also the G-buffer's barycentrics and the surface tables), lights, the eye.
//! Output: the ray-traced image (linear RGBA; alpha 1 on ray-traced pixels, 0 elsewhere).

use glam::Vec3;
use hyrt_core::formats::{GBufferTexel, ObjectRecord, SurfaceRecord, OBJ_RAY_TRACED};
use hyrt_core::geometry::WorldTriangles;
use hyrt_core::kernels::bounce::{primary_parent, primary_parent_shaded, shade_rt_pixel_bouncing};
use hyrt_core::kernels::shading::{shade_rt_pixel, AmbientLight};
use hyrt_core::kernels::soft_shadow::{surface_slots, FilteredVisibility, Lights};
use hyrt_core::kernels::texture::Materials;

use crate::raster_shading::{pixel_codes, Primary};
use rayon::prelude::*;

pub(crate) mod lanes;

/// The stage on a scene without textures or vertex colours, under the frame's `ambient`
/// light (`WorldGeometry::ambient`). `shadow` is indexed `pixel * slots + slot`
/// ([`hyrt_core::kernels::soft_shadow`]: `pixel * lights.len() + light` without area
/// lights or occlusion).
pub fn rt_shading<'l>(
    surfaces: &[SurfaceRecord],
    shadow: &[u8],
    objects: &[ObjectRecord],
    lights: impl Into<Lights<'l>>,
    ambient: &AmbientLight,
    eye: Vec3,
) -> Vec<[f32; 4]> {
    let lights: Lights = lights.into();
    let mut out = Vec::new();
    let primary =
        Primary { gbuffer: &[], materials: &Materials::plain(objects), ambient, eye, visibility: Default::default() };
    rt_shading_into(surfaces, shadow, &primary, lights, &mut out);
    out
}

/// [`rt_shading`] into a caller-owned image, reusing its allocation, with any materials
/// (each pixel's object as [`Primary::object`] sees it).
pub fn rt_shading_into<'l>(
    surfaces: &[SurfaceRecord],
    shadow: &[u8],
    primary: &Primary,
    lights: impl Into<Lights<'l>>,
    out: &mut Vec<[f32; 4]>,
) {
    let lights: Lights = lights.into();
    let nl = surface_slots(&lights, &primary.ambient.occlusion);
    surfaces
        .par_iter()
        .enumerate()
        .with_min_len(1024)
        .map(|(i, s)| rt_shading_pixel(primary, lights, i, s, pixel_codes(shadow, nl, i, s)))
        .collect_into_vec(out);
}

/// The stage's kernel for one pixel `i` with surface `s` and its shadow codes (one per
/// light), in a frame without bounces: shaded with alpha 1 on ray-traced objects,
/// transparent black elsewhere. What [`rt_shading_into`] writes at `i`; the fused frame
/// (`crate::fused`) calls it tile by tile.
#[inline]
pub fn rt_shading_pixel<'l>(
    primary: &Primary,
    lights: impl Into<Lights<'l>>,
    i: usize,
    s: &SurfaceRecord,
    shadow: &[u8],
) -> [f32; 4] {
    let lights: Lights = lights.into();
    let Some(obj) = ray_traced(primary.materials.objects, s) else {
        return [0.0; 4];
    };
    let shadow = primary.visibility.surface(i, shadow);
    let c = if primary.materials.varying() {
        shade_rt_pixel(s, &primary.object(i, s), shadow, lights, primary.ambient, primary.eye)
    } else {
        shade_rt_pixel(s, obj, shadow, lights, primary.ambient, primary.eye)
    };
    c.extend(1.0).into()
}

/// The first bounce's results `rt_shading` gathers on the pixels of mirrors and glass.
#[derive(Clone, Copy)]
pub struct FirstBounce<'a> {
    /// The G-buffer (each pixel's exact facing).
    pub gbuffer: &'a [GBufferTexel],
    /// Per pixel, its `[reflection, refraction]` rays of depth 1.
    pub links: &'a [[u32; 2]],
    /// The radiance those rays bring back.
    pub radiance: &'a [[f32; 4]],
}

/// [`rt_shading_into`] in a frame that traces bounces: pixels whose object bounces add
/// what their reflection and refraction rays brought back
/// ([`hyrt_core::kernels::bounce::shade_rt_pixel_bouncing`]); every other pixel is
/// shaded as [`rt_shading_into`] shades it, bit for bit.
#[allow(clippy::too_many_arguments)]
pub fn rt_shading_bouncing_into<'l>(
    surfaces: &[SurfaceRecord],
    shadow: &[u8],
    materials: &Materials,
    triangles: &WorldTriangles,
    lights: impl Into<Lights<'l>>,
    ambient: &AmbientLight,
    eye: Vec3,
    bounce: FirstBounce,
    visibility: FilteredVisibility,
    out: &mut Vec<[f32; 4]>,
) {
    let lights: Lights = lights.into();
    let nl = surface_slots(&lights, &ambient.occlusion);
    let shading = BouncingShading { materials, triangles, lights, ambient, eye, radiance: bounce.radiance, visibility };
    surfaces
        .par_iter()
        .enumerate()
        .with_min_len(1024)
        .map(|(i, s)| {
            let shadow = &shadow[i * nl..(i + 1) * nl];
            rt_shading_bouncing_pixel(&shading, &bounce.gbuffer[i], s, i as u32, shadow, bounce.links[i])
        })
        .collect_into_vec(out);
}

/// What [`rt_shading_bouncing_pixel`] reads besides the pixel's own data.
#[derive(Clone, Copy)]
pub struct BouncingShading<'a> {
    pub materials: &'a Materials<'a>,
    pub triangles: &'a WorldTriangles,
    pub lights: Lights<'a>,
    pub ambient: &'a AmbientLight,
    pub eye: Vec3,
    /// The radiance the first bounce's rays bring back.
    pub radiance: &'a [[f32; 4]],
    /// `shadow_denoise`'s channels, where the frame denoised its stochastic shadows.
    pub visibility: FilteredVisibility<'a>,
}

/// The stage's kernel in a frame that traces bounces, for pixel `pixel` with texel `t`,
/// surface `s`, its shadow codes (one per light) and its `[reflection, refraction]` rays
/// of depth 1 (`children`, into `shading.radiance`): what [`rt_shading_bouncing_into`]
/// writes there; the fused frame (`crate::fused`) calls it on the pixels it deferred.
#[inline]
pub fn rt_shading_bouncing_pixel(
    shading: &BouncingShading,
    t: &GBufferTexel,
    s: &SurfaceRecord,
    pixel: u32,
    shadow: &[u8],
    children: [u32; 2],
) -> [f32; 4] {
    let (materials, eye) = (shading.materials, shading.eye);
    if ray_traced(materials.objects, s).is_none() {
        return [0.0; 4];
    }
    let record = primary_parent(t, s, eye, pixel, materials).object;
    rt_shading_bouncing_record(shading, t, s, pixel, &record, shadow, children)
}

/// [`rt_shading_bouncing_pixel`] with the pixel's record given: `record` is
/// [`primary_parent`]'s object there (the fused frame makes it once per pixel).
#[inline]
pub fn rt_shading_bouncing_record(
    shading: &BouncingShading,
    t: &GBufferTexel,
    s: &SurfaceRecord,
    pixel: u32,
    record: &ObjectRecord,
    shadow: &[u8],
    children: [u32; 2],
) -> [f32; 4] {
    let BouncingShading { materials, triangles, lights, ambient, eye, radiance, visibility } = *shading;
    if ray_traced(materials.objects, s).is_none() {
        return [0.0; 4];
    }
    let p = primary_parent_shaded(t, s, eye, pixel, materials, *record);
    let shadow = visibility.surface(pixel as usize, shadow);
    shade_rt_pixel_bouncing(&p, triangles, shadow, lights, ambient, eye, children, radiance).extend(1.0).into()
}

/// The object of surface `s` where it is a hit on a ray-traced object: the pixels the
/// stage shades.
#[inline]
fn ray_traced<'o>(objects: &'o [ObjectRecord], s: &SurfaceRecord) -> Option<&'o ObjectRecord> {
    if !s.is_hit() {
        return None;
    }
    let obj = &objects[s.object as usize];
    (obj.flags & OBJ_RAY_TRACED != 0).then_some(obj)
}
