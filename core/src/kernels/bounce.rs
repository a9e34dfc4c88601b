//! Secondary-ray kernels (reflection and refraction, the paper's future work): which
//! surfaces bounce, the directions and Fresnel weights of their two lobes, the rays
//! they spawn, the radiance they send back, and the default sky that rays leaving the
//! scene see when it has no environment map ([`crate::kernels::environment`]).
//!
//! # The model
//!
//! A ray-traced object whose material is [`MATERIAL_SPECULAR`] or [`MATERIAL_GLASS`]
//! *bounces*: where a primary or secondary ray sees it and the frame's depth budget
//! ([`crate::frame::FrameOptions::max_depth`]) is not spent, it spawns a reflection ray
//! and, for glass, a refraction ray (Whitted). Its radiance towards the viewer is
//!
//! ```text
//! L = diffuse_scale * (ambient diffuse + direct diffuse) + emission
//!     + direct specular + R * L(reflection) + T * L(refraction)
//! ```
//!
//! * `R = F_dielectric(cos, eta) (1 - metallic) + Schlick(base, cos) metallic`: the exact
//!   unpolarized dielectric Fresnel term with the glTF IOR for dielectrics
//!   ([`fresnel_dielectric`]), Schlick's with `F0 = base colour` for metals
//!   ([`fresnel_schlick`]);
//! * `T = base (1 - metallic) transmission (1 - F_dielectric)`, zero under total
//!   internal reflection; `diffuse_scale = 1 - transmission`;
//! * a lobe whose ray is not traced (its path weight fell below [`MIN_THROUGHPUT`], or
//!   no direction leaves on the right side of the surface) sees the ambient light's
//!   stand-in ([`lobe_radiance`]): the uniform [`ENVIRONMENT_SPECULAR`] in the paper's
//!   model, as every specular surface did before secondary rays, the prefiltered
//!   environment in the glTF model;
//! * a surface that does not bounce (a diffuse or rasterized object, or the depth budget
//!   spent) is shaded as a primary hit is: [`crate::kernels::shading::shade_rt_surface`]
//!   or, for rasterized objects, the raster shader.
//!
//! Reflection is sharp whatever the roughness (glossy reflection is not modelled). Media
//! are not nested: every glass surface separates its object's IOR from air (IOR 1), the
//! exterior being the side its outward normals face ([`crate::formats::TRI_INWARD`]).
//!
//! Radiance is gathered bottom-up: `bounce_shading` runs from the deepest bounce to the
//! first, each ray adding its children's radiance in a fixed order (reflection, then
//! refraction), so the sum is the same on every backend without atomics.
//!
//! WGSL mirrors: the functions of `bounce.wgsl`, by the same names.

use glam::Vec3;

use crate::kernels::soft_shadow::{Lights, SurfaceShadow};

use crate::formats::{
    GBufferTexel, HitRecord, ObjectRecord, RayRecord, SurfaceRecord, GBUF_BACK_FACE, INVALID_ID, MATERIAL_GLASS,
    MATERIAL_SPECULAR, OBJ_RAY_TRACED, RAY_KIND_REFLECTION, RAY_KIND_REFRACTION, TRI_INWARD,
};
use crate::geometry::WorldTriangles;
use crate::kernels::environment::environment_radiance;
pub use crate::kernels::environment::{sky, SKY_GROUND, SKY_HORIZON, SKY_ZENITH};
use crate::kernels::ray::offset_ray_origin;
use crate::kernels::shading::{
    shade_raster_surface, shade_rt_pixel, shade_rt_surface, sum_visible_lights, AmbientLight, AMBIENT,
    ENVIRONMENT_SPECULAR,
};
use crate::kernels::texture::Materials;
use crate::scene::Environment;

/// Bounces a frame traces unless told otherwise: enough for a ray to enter and leave a
/// glass sphere and see a mirror (4 surfaces), the issue's minimum.
pub const DEFAULT_MAX_DEPTH: u32 = 4;

/// The largest `max_depth` a frame accepts. Each bounce can double the rays (a glass
/// surface spawns two), so the lists are bounded by `2^depth` per pixel before the
/// throughput cut-off; 16 keeps that far beyond any visible contribution.
pub const MAX_DEPTH_LIMIT: u32 = 16;

/// A secondary ray is traced only if the largest component of its path weight (the
/// product of the lobe weights from the pixel) is at least this: 1/256, one step of an
/// 8-bit linear channel for radiance up to 1. Below it the lobe sees
/// [`ENVIRONMENT_SPECULAR`] instead. The report measures what the cut costs in error.
pub const MIN_THROUGHPUT: f32 = 1.0 / 256.0;

/// Index of refraction outside every object (air).
pub const IOR_OUTSIDE: f32 = 1.0;

/// Whether an object bounces secondary rays: ray traced, with triangles, and a
/// specular or glass material.
#[inline]
pub fn bounces(obj: &ObjectRecord) -> bool {
    obj.flags & OBJ_RAY_TRACED != 0
        && obj.triangle_count > 0
        && (obj.material_kind == MATERIAL_SPECULAR || obj.material_kind == MATERIAL_GLASS)
}

/// `a . b` in a stated order, `(x + y) + z` of rounded products (glam's order; the WGSL
/// mirror `dot3` keeps it unfused).
#[inline]
fn dot(a: Vec3, b: Vec3) -> f32 {
    a.dot(b)
}

/// `x > 0`, false for NaN (a direction that rounding made NaN or zero spawns no ray).
#[inline]
fn is_positive(x: f32) -> bool {
    x > 0.0
}

/// The mirror direction of `d` about the unit normal `n`: `d - n (2 (d . n))`.
#[inline]
pub fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - n * (2.0 * dot(d, n))
}

/// Snell's law: the refracted direction of the unit direction `d` through the unit
/// normal `n` facing it (`d . n <= 0`), with `eta = ior_incident / ior_transmitted`;
/// `None` under total internal reflection. `t = eta d + (eta cos_i - cos_t) n` with
/// `cos_i = -d . n` and `cos_t = sqrt(1 - eta^2 (1 - cos_i^2))` (PBR 4th ed. 9.3.2).
#[inline]
pub fn refract(d: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = (-dot(d, n)).clamp(0.0, 1.0);
    let sin2_t = (eta * eta) * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(d * eta + n * (eta * cos_i - cos_t))
}

/// The exact unpolarized Fresnel reflectance of a dielectric interface (PBR 4th ed.
/// `FrDielectric`, eq. 9.7), for the cosine `cos_i` in `[0, 1]` on the incident side and
/// `eta = ior_incident / ior_transmitted`: `(r_par^2 + r_perp^2) / 2` with
/// `r_perp = (eta cos_i - cos_t) / (eta cos_i + cos_t)` and
/// `r_par = (cos_i - eta cos_t) / (cos_i + eta cos_t)`; 1 under total internal reflection.
#[inline]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (eta * eta) * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_perp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_par = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    (r_par * r_par + r_perp * r_perp) * 0.5
}

/// Schlick's approximation `F0 + (1 - F0) (1 - cos)^5` (the glTF metal Fresnel), the
/// fifth power as four rounded products.
#[inline]
pub fn fresnel_schlick(f0: Vec3, cos: f32) -> Vec3 {
    let m = 1.0 - cos.clamp(0.0, 1.0);
    let m2 = m * m;
    let m5 = (m2 * m2) * m;
    f0 + (Vec3::ONE - f0) * m5
}

/// The two lobes of a bouncing surface seen along `d`: weights and directions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lobes {
    /// Weight of the reflected radiance (`R` of the module docs).
    pub reflection: Vec3,
    /// Weight of the refracted radiance (`T`); zero under total internal reflection and
    /// for objects without transmission.
    pub refraction: Vec3,
    /// Unit direction of the reflection ray (normalized after [`reflect`], so rounding
    /// does not build up over bounces), on the seen side of the geometric normal; zero
    /// when none leaves on that side.
    pub reflect_dir: Vec3,
    /// Unit direction of the refraction ray, on the far side of the geometric normal;
    /// zero when none (total internal reflection, no transmission, or it would leave on
    /// the wrong side).
    pub refract_dir: Vec3,
    /// Scale of the diffuse terms: `1 - transmission`.
    pub diffuse_scale: f32,
}

/// The lobes of surface `s` of a bouncing object `obj`, seen along the unit direction
/// `d`; `exterior` says the seen side is the object's outside (see [`sees_exterior`]).
///
/// The normals of `s` face the seen side (reconstruction orients them). Each direction
/// comes from the shading normal; where that would leave on the wrong side of the
/// geometric normal (interpolated normals at silhouettes), from the geometric normal
/// instead, and where that fails too (grazing rounding), no ray.
#[inline]
pub fn lobes(obj: &ObjectRecord, s: &SurfaceRecord, d: Vec3, exterior: bool) -> Lobes {
    let ns = Vec3::from(s.normal);
    let ng = Vec3::from(s.geometric_normal);
    let base = Vec3::from(obj.base_color);
    let cos_i = -dot(d, ns);
    let glass = obj.material_kind == MATERIAL_GLASS;
    // Only glass has an inside; other objects are seen from outside on both faces.
    let eta = if exterior || !glass { IOR_OUTSIDE / obj.ior } else { obj.ior / IOR_OUTSIDE };
    let f = fresnel_dielectric(cos_i, eta);
    // `F (1 - m) + Schlick m` rather than a lerp: exactly F for dielectrics and exactly
    // Schlick for metals (a lerp's `f + (s - f) m` is not `s` at m = 1 in floating point).
    let reflection = Vec3::splat(f * (1.0 - obj.metallic)) + fresnel_schlick(base, cos_i) * obj.metallic;

    let mut reflect_dir = reflect(d, ns).normalize_or_zero();
    if !is_positive(dot(reflect_dir, ng)) {
        reflect_dir = reflect(d, ng).normalize_or_zero();
    }
    if !is_positive(dot(reflect_dir, ng)) {
        reflect_dir = Vec3::ZERO;
    }

    let transmission = if glass { obj.transmission } else { 0.0 };
    let mut refraction = base * (((1.0 - obj.metallic) * transmission) * (1.0 - f));
    let mut refract_dir = Vec3::ZERO;
    if refraction.max_element() > 0.0 {
        let through = |n: Vec3| refract(d, n, eta).map(Vec3::normalize_or_zero).filter(|t| dot(*t, ng) < 0.0);
        refract_dir = through(ns).or_else(|| through(ng)).unwrap_or(Vec3::ZERO);
    }
    if refract_dir == Vec3::ZERO {
        refraction = Vec3::ZERO;
    }
    Lobes { reflection, refraction, reflect_dir, refract_dir, diffuse_scale: 1.0 - transmission }
}

/// Whether the seen side of a surface is its object's exterior: the side the outward
/// normals face. glTF meshes face outward with their front faces; a mesh flagged
/// [`crate::formats::TRI_INWARD`] with its back faces. `back_face` is the exact facing of
/// the hit (`GBUF_BACK_FACE`, `HIT_BACK_FACE`).
#[inline]
pub fn sees_exterior(back_face: bool, inward: bool) -> bool {
    back_face == inward
}

/// The secondary rays of a surface with lobes `l`, reached with path weight
/// `throughput`: `[reflection, refraction]`, each `None` when its direction is missing
/// or its path weight `throughput * weight` falls below [`MIN_THROUGHPUT`].
///
/// Origins are offset off the surface by the point's own error bound
/// ([`offset_ray_origin`]): reflection rays to the seen side of the geometric normal,
/// refraction rays to the other side. `pixel` is the pixel the path started at;
/// `depth` the bounce the rays belong to (1 for rays from primary hits); `cone` the
/// footprint's width at the surface, which the rays carry on ([`RayRecord::cone`]).
#[inline]
pub fn secondary_rays(
    s: &SurfaceRecord,
    l: &Lobes,
    throughput: Vec3,
    pixel: u32,
    depth: u32,
    cone: f32,
) -> [Option<RayRecord>; 2] {
    let p = Vec3::from(s.position);
    let ng = Vec3::from(s.geometric_normal);
    let ray = |dir: Vec3, weight: Vec3, side: Vec3, kind: u32| {
        let t = throughput * weight;
        (dir != Vec3::ZERO && t.max_element() >= MIN_THROUGHPUT).then(|| RayRecord {
            origin: offset_ray_origin(p, s.position_error, side).into(),
            t_min: 0.0,
            direction: dir.into(),
            t_max: f32::INFINITY,
            pixel,
            kind,
            depth,
            light: INVALID_ID,
            throughput: t.into(),
            cone,
        })
    };
    [
        ray(l.reflect_dir, l.reflection, ng, RAY_KIND_REFLECTION),
        ray(l.refract_dir, l.refraction, -ng, RAY_KIND_REFRACTION),
    ]
}

/// The radiance a lobe of surface `obj` (shading normal `n`) in direction `dir` sees: its
/// traced child's (`link` into `radiance`) or, when the lobe's ray was not traced, the
/// ambient light's stand-in: for the paper's model the uniform [`ENVIRONMENT_SPECULAR`]
/// times the scene's level and the occlusion (`scale occlusion`, [`AmbientLight`]); for
/// the glTF model under an image-based light the prefiltered environment
/// ([`crate::kernels::ibl::ImageBasedLight::specular_radiance`]) along `dir` (along `n` where the lobe has no
/// direction) at the surface's roughness, times the occlusion. WGSL: `lobe_radiance`.
#[inline]
pub fn lobe_radiance(
    link: u32,
    radiance: &[[f32; 4]],
    obj: &ObjectRecord,
    dir: Vec3,
    n: Vec3,
    ambient: &AmbientLight,
) -> Vec3 {
    if link != INVALID_ID {
        return Vec3::from_slice(&radiance[link as usize][..3]);
    }
    match ambient.image_for(obj.flags) {
        None => Vec3::splat(ENVIRONMENT_SPECULAR * (ambient.scale * obj.occlusion)),
        Some(ibl) => {
            let dir = if dir == Vec3::ZERO { n } else { dir };
            ibl.specular_radiance(dir, obj.roughness) * obj.occlusion
        }
    }
}

/// The radiance a bouncing surface sends along `-d` (the module docs' `L`): its diffuse
/// terms scaled by `l.diffuse_scale`, the specular lobe of every light its shadow ray
/// reached (`shadow`: its `SHADOW_*` codes), and what its lobes see times their weights:
/// [`lobe_radiance`] of its `[reflection, refraction]` `children` in `radiance` (the next
/// depth's, [`INVALID_ID`] where a lobe traced no ray). The diffuse part of the ambient
/// light is [`crate::kernels::shading::ambient`]'s (the constant term, and under an
/// image-based light [`crate::kernels::ibl::ImageBasedLight::diffuse`]), scaled by `l.diffuse_scale`; the
/// specular part is what the lobes see.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn shade_bouncing<'s, 'l>(
    s: &SurfaceRecord,
    obj: &ObjectRecord,
    l: &Lobes,
    d: Vec3,
    shadow: impl Into<SurfaceShadow<'s>>,
    lights: impl Into<Lights<'l>>,
    ambient_light: &AmbientLight,
    children: [u32; 2],
    radiance: &[[f32; 4]],
) -> Vec3 {
    let p = Vec3::from(s.position);
    let n = Vec3::from(s.normal);
    let shadow = shadow.into();
    let lights: Lights = lights.into();
    let occluded = crate::kernels::soft_shadow::occluded_object(obj, shadow, &lights, &ambient_light.occlusion);
    let obj = occluded.as_ref().unwrap_or(obj);
    let reflected = lobe_radiance(children[0], radiance, obj, l.reflect_dir, n, ambient_light);
    let refracted = lobe_radiance(children[1], radiance, obj, l.refract_dir, n, ambient_light);
    let v = -d;
    let base = Vec3::from(obj.base_color);
    // The constant ambient, occluded, the environment's diffuse light under an image-based
    // light, and the emission ([`crate::kernels::shading::unlit`]'s parts; the specular
    // lobe's environment is what its traced ray sees).
    let constant = base * (((1.0 - obj.metallic) * AMBIENT) * l.diffuse_scale) * (ambient_light.scale * obj.occlusion);
    let constant = match ambient_light.image_for(obj.flags) {
        None => constant,
        Some(ibl) => constant + ibl.diffuse(base, obj.metallic, n, l.diffuse_scale) * obj.occlusion,
    };
    let ambient = constant + Vec3::from(obj.emissive);
    let direct = sum_visible_lights(shadow, lights, p, |li, e| {
        crate::kernels::shading::shade_ray_traced_with(obj, n, v, li, e, l.diffuse_scale)
    });
    ambient + direct + l.reflection * reflected + l.refraction * refracted
}

/// A surface that can spawn the rays of the next bounce: a pixel's primary hit
/// ([`primary_parent`]) or the hit of a secondary ray ([`secondary_parent`]). It is what
/// `secondary_rays` spawns from and what `bounce_shading` and `rt_shading` shade.
#[derive(Clone, Copy, Debug)]
pub struct Parent<'a> {
    /// The surface seen (normals oriented to the seen side), or [`SurfaceRecord::MISS`].
    pub surface: &'a SurfaceRecord,
    /// Unit direction it was seen along: from the eye, or the ray's direction.
    pub d: Vec3,
    /// The exact facing of the hit: `GBUF_BACK_FACE` of the raster, `HIT_BACK_FACE` of
    /// the watertight ray/triangle test.
    pub back_face: bool,
    /// Path weight from the pixel to this surface: 1 for primary hits, the ray's
    /// `throughput` for secondary ones.
    pub throughput: Vec3,
    /// The pixel the path started at.
    pub pixel: u32,
    /// The width of the pixel's footprint cone at the surface (0 in frames without
    /// textures: [`Materials::spread`]).
    pub cone: f32,
    /// The hit object's record as shading sees it at this point ([`Materials::at`]: its
    /// base colour textured); zeros for a miss.
    pub object: ObjectRecord,
}

/// The shaded record of the object at a parent's surface (zeros for a miss).
#[inline]
fn parent_object(m: &Materials, s: &SurfaceRecord, u: f32, v: f32, cone: f32, d: Vec3) -> ObjectRecord {
    if s.is_hit() {
        m.at(s, u, v, cone, d)
    } else {
        bytemuck::Zeroable::zeroed()
    }
}

/// The primary hit of pixel `pixel` as a parent: seen along `-(eye - p)` normalized
/// (the negated view vector of [`crate::kernels::shading::shade_rt_pixel`]), its footprint
/// the spread times the eye's distance, its object shaded at the G-buffer's barycentrics.
#[inline]
pub fn primary_parent<'a>(t: &GBufferTexel, s: &'a SurfaceRecord, eye: Vec3, pixel: u32, m: &Materials) -> Parent<'a> {
    let mut p = primary_parent_shaded(t, s, eye, pixel, m, bytemuck::Zeroable::zeroed());
    p.object = parent_object(m, s, t.bary_u, t.bary_v, p.cone, p.d);
    p
}

/// [`primary_parent`] with its object's record given: `object` is what [`primary_parent`]
/// would shade it with ([`Materials::at`], made once per pixel by an executor that reads
/// it several times, as the CPU backend's fused frame does). The direction, facing and
/// footprint are made here as there.
#[inline]
pub fn primary_parent_shaded<'a>(
    t: &GBufferTexel,
    s: &'a SurfaceRecord,
    eye: Vec3,
    pixel: u32,
    m: &Materials,
    object: ObjectRecord,
) -> Parent<'a> {
    let to_eye = eye - Vec3::from(s.position);
    let d = -to_eye.normalize_or_zero();
    let cone = primary_cone(m, to_eye);
    Parent { surface: s, d, back_face: t.flags & GBUF_BACK_FACE != 0, throughput: Vec3::ONE, pixel, cone, object }
}

/// The footprint's width at a primary hit `to_eye` away from the eye: the spread times
/// the distance (0 without textures, without computing the distance). WGSL: `primary_cone`.
#[inline]
pub fn primary_cone(m: &Materials, to_eye: Vec3) -> f32 {
    if m.spread == 0.0 {
        0.0
    } else {
        m.spread * to_eye.length()
    }
}

/// The hit of a secondary ray as a parent (its direction is unit: [`Lobes`]): its
/// footprint the ray's at its origin widened by the spread over the distance travelled.
#[inline]
pub fn secondary_parent<'a>(ray: &RayRecord, hit: &HitRecord, s: &'a SurfaceRecord, m: &Materials) -> Parent<'a> {
    let d = Vec3::from(ray.direction);
    let cone = if m.spread == 0.0 { 0.0 } else { ray.cone + m.spread * hit.t };
    let object = parent_object(m, s, hit.u, hit.v, cone, d);
    Parent {
        surface: s,
        d,
        back_face: hit.is_back_face(),
        throughput: Vec3::from(ray.throughput),
        pixel: ray.pixel,
        cone,
        object,
    }
}

/// The lobes of a parent whose object bounces ([`bounces`]), with its shaded object
/// ([`Parent::object`]); `None` for a miss or a surface that does not bounce. `triangles`
/// give the mesh's winding ([`TRI_INWARD`]), hence which side is the exterior.
#[inline]
pub fn parent_lobes<'p>(p: &'p Parent, triangles: &WorldTriangles) -> Option<(&'p ObjectRecord, Lobes)> {
    let s = p.surface;
    if !s.is_hit() {
        return None;
    }
    let obj = &p.object;
    if !bounces(obj) {
        return None;
    }
    let inward = triangles.flags(s.triangle as usize) & TRI_INWARD != 0;
    Some((obj, lobes(obj, s, p.d, sees_exterior(p.back_face, inward))))
}

/// The rays of bounce `depth` a parent spawns: `[reflection, refraction]`, both `None`
/// where it does not bounce ([`parent_lobes`], [`secondary_rays`]).
#[inline]
pub fn spawn(p: &Parent, triangles: &WorldTriangles, depth: u32) -> [Option<RayRecord>; 2] {
    match parent_lobes(p, triangles) {
        Some((_, l)) => secondary_rays(p.surface, &l, p.throughput, p.pixel, depth, p.cone),
        None => [None, None],
    }
}

/// The most rays [`spawn`] makes for a parent on surface `s`, its object read from
/// `objects` (the records as the scene holds them: [`Materials::at`] changes no field this
/// reads; only a hit's object is read): none for a miss or an object that does not
/// [`bounce`](bounces), one (the reflection) for a mirror, two for glass, whose refraction
/// is the second lobe. An executor sizes a bounce's ray list
/// by it before spawning, so that each parent spawns once, straight into its place
/// (the CPU's `secondary_rays`). The property test `spawn_never_exceeds_its_bound`
/// checks it against [`spawn`].
#[inline]
pub fn spawn_bound(s: &SurfaceRecord, objects: &[ObjectRecord]) -> u32 {
    if !s.is_hit() {
        return 0;
    }
    let obj = &objects[s.object as usize];
    if !bounces(obj) {
        0
    } else if obj.material_kind == MATERIAL_GLASS {
        2
    } else {
        1
    }
}

/// The radiance a secondary ray brings back (`bounce_shading`), seen from its parent:
/// the scene's environment `env` where it left the scene
/// ([`crate::kernels::environment::environment_radiance`]: [`sky`] bit for bit without a
/// map); [`shade_bouncing`] on a surface that
/// bounces, its lobes seeing their `children` (links into the next depth's
/// `radiance`, [`INVALID_ID`] where no ray was traced, as for every lobe at the plan's
/// deepest bounce); the ray-traced shader on other ray-traced objects; and the raster
/// shader ([`shade_raster_surface`], seen along the ray) on rasterized objects, as a
/// raster pass would shade them. `shadow`: the hit's `SHADOW_*` codes, one per light.
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn shade_secondary_hit<'s, 'l>(
    p: &Parent,
    env: &Environment,
    triangles: &WorldTriangles,
    shadow: impl Into<SurfaceShadow<'s>>,
    lights: impl Into<Lights<'l>>,
    ambient: &AmbientLight,
    children: [u32; 2],
    radiance: &[[f32; 4]],
) -> Vec3 {
    let shadow: SurfaceShadow = shadow.into();
    let s = p.surface;
    if !s.is_hit() {
        return environment_radiance(env, p.d);
    }
    if let Some((obj, l)) = parent_lobes(p, triangles) {
        return shade_bouncing(s, obj, &l, p.d, shadow, lights, ambient, children, radiance);
    }
    let obj = &p.object;
    if obj.flags & OBJ_RAY_TRACED != 0 {
        shade_rt_surface(s, obj, shadow, lights, ambient, -p.d)
    } else {
        shade_raster_surface(s, obj, shadow, lights, ambient, -p.d)
    }
}

/// `rt_shading` with bounces, at one ray-traced pixel: [`shade_bouncing`] where its
/// object bounces (its lobes seeing the first bounce's radiance through `children`),
/// [`crate::kernels::shading::shade_rt_pixel`] bit for bit elsewhere.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn shade_rt_pixel_bouncing<'s, 'l>(
    p: &Parent,
    triangles: &WorldTriangles,
    shadow: impl Into<SurfaceShadow<'s>>,
    lights: impl Into<Lights<'l>>,
    ambient: &AmbientLight,
    eye: Vec3,
    children: [u32; 2],
    radiance: &[[f32; 4]],
) -> Vec3 {
    let shadow: SurfaceShadow = shadow.into();
    let s = p.surface;
    match parent_lobes(p, triangles) {
        Some((obj, l)) => shade_bouncing(s, obj, &l, p.d, shadow, lights, ambient, children, radiance),
        None => shade_rt_pixel(s, &p.object, shadow, lights, ambient, eye),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::MATERIAL_DIFFUSE;
    use proptest::prelude::*;

    /// Relative tolerance of the Fresnel and Snell identities below: a few dozen
    /// roundings of values of order 1 in f32 (2^-24 each), against f64 algebra.
    const F32_IDENTITY_TOL: f32 = 1e-5;

    fn unit(theta: f32, phi: f32) -> Vec3 {
        Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin())
    }

    #[test]
    fn normal_incidence_reflects_four_percent_at_ior_one_and_a_half() {
        let f = fresnel_dielectric(1.0, 1.0 / 1.5);
        assert!((f - 0.04).abs() < 1e-7, "{f}");
        // The same from inside the glass (Fresnel is symmetric at normal incidence).
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-7);
        assert_eq!(fresnel_dielectric(0.0, 1.0 / 1.5), 1.0, "grazing incidence reflects everything");
    }

    #[test]
    fn total_internal_reflection_starts_at_the_critical_angle() {
        let eta = 1.5f32;
        let critical = (1.0 / eta).asin();
        let just_below = critical - 1e-3;
        let just_above = critical + 1e-3;
        let d = |a: f32| Vec3::new(a.sin(), -a.cos(), 0.0);
        assert!(refract(d(just_below), Vec3::Y, eta).is_some());
        assert!(refract(d(just_above), Vec3::Y, eta).is_none());
        assert_eq!(fresnel_dielectric(just_above.cos(), eta), 1.0);
        assert!(fresnel_dielectric(just_below.cos(), eta) < 1.0);
    }

    #[test]
    fn schlick_is_f0_at_normal_incidence_and_one_at_grazing() {
        let f0 = Vec3::new(1.0, 0.77, 0.34);
        assert_eq!(fresnel_schlick(f0, 1.0), f0);
        assert_eq!(fresnel_schlick(f0, 0.0), Vec3::ONE);
    }

    proptest! {
        /// Snell's law (`sin_t = eta sin_i`), the refracted ray on the far side, and
        /// energy: reflectance in [0, 1], equal from both sides of the interface along
        /// the reciprocal path (Stokes relations).
        #[test]
        fn refraction_obeys_snell_and_fresnel_is_reciprocal(theta in 0.0f32..1.55, phi in 0.0f32..std::f32::consts::TAU, ior in 1.0f32..2.5) {
            let n = Vec3::Y;
            let d = -unit(theta, phi);
            let eta = 1.0 / ior;
            let t = refract(d, n, eta).expect("entering a denser medium never reflects totally");
            prop_assert!((t.length() - 1.0).abs() < F32_IDENTITY_TOL);
            prop_assert!(t.dot(n) < 0.0);
            let sin_i = d.cross(n).length();
            let sin_t = t.cross(n).length();
            prop_assert!((sin_t - eta * sin_i).abs() < F32_IDENTITY_TOL, "sin_t {} vs {}", sin_t, eta * sin_i);
            let f_in = fresnel_dielectric(-d.dot(n), eta);
            // The reverse path: `-t` meets the interface from inside, where `-n` faces it.
            let f_out = fresnel_dielectric((-t).dot(n), ior);
            prop_assert!((0.0..=1.0).contains(&f_in));
            prop_assert!((f_in - f_out).abs() < F32_IDENTITY_TOL * 10.0, "{} vs {}", f_in, f_out);
            // Back along the refracted ray reversed: the original direction reversed.
            let back = refract(-t, -n, ior).expect("the reverse path exists");
            prop_assert!((back + d).length() < F32_IDENTITY_TOL * 10.0);
        }

        /// A bouncing parent spawns at most [`spawn_bound`] rays, whatever its material's
        /// factors, the side it is seen from, the view and the path weight: [`spawn`] is
        /// [`parent_lobes`] (nothing for a miss or an object that does not bounce, where
        /// the bound is 0) then [`secondary_rays`] of [`lobes`], which this drives
        /// directly (no triangle table). The CPU's `secondary_rays` writes each parent's
        /// rays into room sized by the bound.
        #[test]
        fn spawn_never_exceeds_its_bound(
            kind in prop_oneof![Just(MATERIAL_DIFFUSE), Just(MATERIAL_SPECULAR), Just(MATERIAL_GLASS)],
            ray_traced in any::<bool>(),
            triangle_count in 0u32..3,
            metallic in prop_oneof![Just(0.0f32), Just(1.0f32), 0.0f32..1.0],
            transmission in prop_oneof![Just(0.0f32), Just(1.0f32), 0.0f32..1.0],
            ior in 1.0f32..2.5,
            base in prop_oneof![Just(0.0f32), Just(1.0f32), 0.0f32..1.0],
            (theta, phi) in (0.0f32..3.1, 0.0f32..std::f32::consts::TAU),
            (g_theta, g_phi) in (0.0f32..1.6, 0.0f32..std::f32::consts::TAU),
            exterior in any::<bool>(),
            throughput in prop_oneof![Just(1.0f32), 0.0f32..0.01],
            hit in prop_oneof![4 => Just(true), 1 => Just(false)],
        ) {
            let obj = ObjectRecord {
                triangle_count,
                flags: if ray_traced { OBJ_RAY_TRACED } else { 0 },
                material_kind: kind,
                base_color: [base; 3],
                metallic,
                transmission,
                ior,
                ..bytemuck::Zeroable::zeroed()
            };
            let s = if hit {
                SurfaceRecord {
                    position: [0.5, 1.0, -2.0],
                    position_error: 1e-6,
                    normal: Vec3::Y.into(),
                    object: 0,
                    geometric_normal: unit(g_theta, g_phi).into(),
                    triangle: 0,
                }
            } else {
                SurfaceRecord::MISS
            };
            let bound = spawn_bound(&s, std::slice::from_ref(&obj));
            if !s.is_hit() || !bounces(&obj) {
                prop_assert_eq!(bound, 0);
            } else {
                let d = -unit(theta, phi);
                let l = lobes(&obj, &s, d, exterior);
                let rays = secondary_rays(&s, &l, Vec3::splat(throughput), 7, 1, 0.0);
                let n = rays.iter().flatten().count() as u32;
                prop_assert!(n <= bound, "{} rays, bound {}: {:?} {:?}", n, bound, obj, l);
                // The bound is tight for a mirror seen head on at full weight.
                if kind != MATERIAL_GLASS && throughput == 1.0 && base == 1.0 && metallic == 1.0 && theta < 0.5 && g_theta < 0.5 {
                    prop_assert_eq!(n, bound);
                }
            }
        }

        /// Reflection keeps the angle and the length and mirrors the normal component.
        #[test]
        fn reflection_mirrors_the_normal_component(theta in 0.0f32..1.57, phi in 0.0f32..std::f32::consts::TAU) {
            let n = Vec3::Y;
            let d = -unit(theta, phi);
            let r = reflect(d, n);
            prop_assert!((r.length() - 1.0).abs() < F32_IDENTITY_TOL);
            prop_assert!((r.dot(n) + d.dot(n)).abs() < F32_IDENTITY_TOL);
            prop_assert!((r - n * r.dot(n) - (d - n * d.dot(n))).length() < F32_IDENTITY_TOL);
        }
    }
}
