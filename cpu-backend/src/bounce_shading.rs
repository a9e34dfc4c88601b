//! Stage `bounce_shading`: the radiance each ray of bounce `d` brings back to its
//! parent, deepest bounce first, so every ray can add its children's (the rays of
//! `d + 1` it spawned) without atomics, in a fixed order: the sum is the same on every
//! backend and thread count.
//!
//! Inputs: the rays, hits, surfaces and shadow codes of depth `d`; unless `d` is the
//! plan's deepest bounce, the links and radiance of depth `d + 1`; the materials, triangles,
//! lights, the scene's environment and ambient light. Output: one linear RGBA value per ray (alpha 1). The
//! kernel is [`hyrt_core::kernels::bounce::shade_secondary_hit`]: the environment (the
//! default sky or the scene's map) on a miss, the
//! bouncing shader on mirrors and glass, the ray-traced shader on other ray-traced
//! objects and the raster shader on rasterized ones.

use hyrt_core::formats::{HitRecord, RayRecord, SurfaceRecord, INVALID_ID};
use hyrt_core::geometry::WorldTriangles;
use hyrt_core::kernels::bounce::{secondary_parent, shade_secondary_hit};
use hyrt_core::kernels::shading::AmbientLight;
use hyrt_core::kernels::soft_shadow::{surface_slots, Lights};
use hyrt_core::kernels::texture::Materials;
use hyrt_core::scene::Environment;
use rayon::prelude::*;

/// The next depth's buffers a bounce gathers from.
#[derive(Clone, Copy)]
pub struct Children<'a> {
    /// Per ray of this depth, its `[reflection, refraction]` children.
    pub links: &'a [[u32; 2]],
    /// The radiance of the next depth's rays.
    pub radiance: &'a [[f32; 4]],
}

/// The stage into a caller-owned buffer. `shadow` is indexed `ray * slots + slot`
/// (empty without lights; one slot per light without area lights or occlusion); `children` is `None` at the plan's deepest bounce; `env` is
/// what the rays that hit nothing see, `ambient` the frame's ambient light.
#[allow(clippy::too_many_arguments)]
pub fn bounce_shading_into<'l>(
    rays: &[RayRecord],
    hits: &[HitRecord],
    surfaces: &[SurfaceRecord],
    shadow: &[u8],
    materials: &Materials,
    triangles: &WorldTriangles,
    lights: impl Into<Lights<'l>>,
    env: &Environment,
    ambient: &AmbientLight,
    children: Option<Children>,
    out: &mut Vec<[f32; 4]>,
) {
    let lights: Lights = lights.into();
    // Mask slots per ray ([`hyrt_core::kernels::soft_shadow`]); none without lights.
    let nl = if shadow.is_empty() { 0 } else { surface_slots(&lights, &ambient.occlusion) };
    let lights = if nl == 0 { Lights::default() } else { lights };
    let (links, radiance): (&[[u32; 2]], &[[f32; 4]]) = match children {
        Some(c) => (c.links, c.radiance),
        None => (&[], &[]),
    };
    (0..rays.len())
        .into_par_iter()
        .with_min_len(1024)
        .map(|i| {
            let p = secondary_parent(&rays[i], &hits[i], &surfaces[i], materials);
            let kids = links.get(i).copied().unwrap_or([INVALID_ID; 2]);
            shade_secondary_hit(&p, env, triangles, &shadow[i * nl..(i + 1) * nl], lights, ambient, kids, radiance)
                .extend(1.0)
                .into()
        })
        .collect_into_vec(out);
}
