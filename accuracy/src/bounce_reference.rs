//! The f64 reference's bounce paths: the Whitted model of `hyrt_core::kernels::bounce`
//! (the pipeline's reflection and refraction) followed in double precision.
//!
//! From every ray-traced mirror or glass hit ([`bounces`]) the reference spawns the
//! reflection and, for glass, the refraction ray of [`lobes_f64`] (the same model and
//! material parameters as `kernels::bounce::lobes`: the exact dielectric Fresnel term,
//! Schlick's with `F0 = base colour` for metals, Snell's law with total internal
//! reflection, the exterior decided by the exact side of the hit; all in f64), traces
//! it with [`closest_hit_f64_excluding`] and shades what it hits as the pipeline's
//! `bounce_shading` does (`kernels::bounce::shade_secondary_hit`): shadow rays from
//! the hit in f64 ([`crate::reference`]), the bouncing shader on mirrors and glass, the
//! ray-traced shader on other ray-traced objects, the raster shader on rasterized ones,
//! the scene's environment on a miss. Radiance is gathered in f64.
//!
//! What differs from the pipeline, on purpose:
//!
//! * no throughput cut-off: every lobe with a non-zero weight is traced, down to
//!   [`REFERENCE_MAX_DEPTH`] bounces (a lobe still alive there sees
//!   `ENVIRONMENT_SPECULAR`, as at the pipeline's deepest bounce; [`PathCounts`]
//!   counts them and their largest path weight);
//! * no origin offset: a secondary ray starts at the f64 hit point itself, excludes the
//!   triangle it leaves (a planar triangle cannot be hit again by a ray leaving it) and
//!   ignores hits closer than [`REFERENCE_BOUNCE_T_MIN_REL`] times the scene's scale
//!   (see there for why any epsilon at all).
//!
//! What it shares with the pipeline: the local shading (ambient and direct light) of each
//! surface comes from the f32 kernels on the f64 surface rounded to a `SurfaceRecord`,
//! as [`crate::reference`] does for primary hits; and the environment a ray leaving the
//! scene sees is the f32 kernel `kernels::environment::environment_radiance` (the default
//! sky or the map's bilinear lookup) evaluated on the f64 direction rounded to f32. So an
//! image error against this reference measures geometry, visibility, shadow decisions and
//! the bounce paths (directions, Fresnel weights, cut-off, depth), not the shading
//! arithmetic.

use glam::{DVec3, Vec3};
use hyrt_core::bvh::Bvh;
use hyrt_core::formats::{ObjectRecord, INVALID_ID, MATERIAL_GLASS, OBJ_RAY_TRACED, TRI_INWARD};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::bounce::{
    bounces, lobe_radiance, sees_exterior, shade_bouncing, Lobes, IOR_OUTSIDE, MAX_DEPTH_LIMIT,
};
use hyrt_core::kernels::environment::environment_radiance;
use hyrt_core::kernels::shading::{shade_raster_surface, shade_rt_pixel, shade_rt_surface};
use hyrt_core::scene::Camera;
use rayon::prelude::*;

use crate::reference::{
    closest_hit_f64_excluding, compose_with_raster, reference_shadow, surface_of, Ray64, ReferenceFrame, ReferenceHit,
    Surface64,
};

/// The reference's depth limit: four times the largest `max_depth` a frame accepts
/// (`kernels::bounce::MAX_DEPTH_LIMIT`, 16), so that it is deeper than any frame it
/// scores. What it still cuts is reported ([`PathCounts`]: the lobes alive at the limit
/// and their largest path weight), not assumed small: total internal reflection has
/// weight 1 and a metal whose F0 has a component of 1 (the gold of the default scene and
/// the teaser) keeps that component's weight at 1, so paths caught inside glass or inside a
/// mirror shell lose weight slowly or never. Measured (`hyrt bench --quick`): the default
/// scene at 320x180 cut lobes of path weight up to 1.5e-2 at depth 16 and 7.2e-5 at 64 (4
/// times the rays); at 1280x720, 34,924 lobes of weight up to 3.9e-2 at 64; the teaser
/// 107 lobes of weight 1 (paths between the golden bunny's own surfaces, the only mirror
/// there; not examined further). Without a cut-off a glass surface spawns two rays, so the
/// cost of a scene whose glass objects face each other can grow as 2^depth per pixel; the
/// report's scenes have one glass ball at most.
pub const REFERENCE_MAX_DEPTH: u32 = 4 * MAX_DEPTH_LIMIT;

/// Secondary rays of the reference ignore hits with `t <= REFERENCE_BOUNCE_T_MIN_REL * scale`
/// (unit directions, so `t` is a distance), where `scale` is the larger of the origin's
/// largest coordinate and the scene extent.
///
/// Why an epsilon at all: the ray leaves the f64 hit point, which lies within about
/// `gamma64(7) |p|` (1e-15 relative) of its triangle's plane, so a *neighbour* sharing an
/// edge or vertex with the triangle it leaves (which is excluded by id) can be hit at a
/// distance of that order when the point is on the shared edge. 1e-9 is a million times
/// above that and about 60 times below the relative precision of an f32 coordinate
/// (2^-24 = 6e-8), so any surface the f32 pipeline can resolve is kept. It is
/// [`crate::reference::REFERENCE_SHADOW_T_MIN`]'s reasoning for rays without an end point.
pub const REFERENCE_BOUNCE_T_MIN_REL: f64 = 1e-9;

/// `kernels::bounce::reflect` in f64: `d - n (2 (d . n))`.
#[inline]
pub fn reflect_f64(d: DVec3, n: DVec3) -> DVec3 {
    d - n * (2.0 * d.dot(n))
}

/// `kernels::bounce::refract` in f64 (Snell's law; `None` under total internal
/// reflection), `eta = ior_incident / ior_transmitted`, `n` facing `d`.
#[inline]
pub fn refract_f64(d: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
    let cos_i = (-d.dot(n)).clamp(0.0, 1.0);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(d * eta + n * (eta * cos_i - cos_t))
}

/// `kernels::bounce::fresnel_dielectric` in f64: the exact unpolarized reflectance
/// `(r_par^2 + r_perp^2) / 2`, 1 under total internal reflection.
#[inline]
pub fn fresnel_dielectric_f64(cos_i: f64, eta: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_perp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_par = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    (r_par * r_par + r_perp * r_perp) * 0.5
}

/// `kernels::bounce::fresnel_schlick` in f64: `F0 + (1 - F0) (1 - cos)^5`.
#[inline]
pub fn fresnel_schlick_f64(f0: DVec3, cos: f64) -> DVec3 {
    let m = 1.0 - cos.clamp(0.0, 1.0);
    f0 + (DVec3::ONE - f0) * m.powi(5)
}

/// The two lobes of a bouncing surface in f64 (`kernels::bounce::Lobes`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lobes64 {
    pub reflection: DVec3,
    /// Zero under total internal reflection, without transmission, or without a
    /// direction on the far side.
    pub refraction: DVec3,
    /// Unit, on the seen side of the geometric normal; zero when none leaves there.
    pub reflect_dir: DVec3,
    /// Unit, on the far side of the geometric normal; zero when none.
    pub refract_dir: DVec3,
}

/// `kernels::bounce::lobes` in f64, for the unit normals `ns` (shading) and `ng`
/// (geometric) facing the viewer and the unit view direction `d`; `exterior` as there.
/// The same fallbacks: each direction from the shading normal, else from the geometric
/// normal, else none.
pub fn lobes_f64(obj: &ObjectRecord, ns: DVec3, ng: DVec3, d: DVec3, exterior: bool) -> Lobes64 {
    let base = Vec3::from(obj.base_color).as_dvec3();
    let metallic = obj.metallic as f64;
    let ior = obj.ior as f64;
    let cos_i = -d.dot(ns);
    let glass = obj.material_kind == MATERIAL_GLASS;
    let eta = if exterior || !glass { IOR_OUTSIDE as f64 / ior } else { ior / IOR_OUTSIDE as f64 };
    let f = fresnel_dielectric_f64(cos_i, eta);
    let reflection = DVec3::splat(f * (1.0 - metallic)) + fresnel_schlick_f64(base, cos_i) * metallic;

    let mut reflect_dir = reflect_f64(d, ns).normalize_or_zero();
    if reflect_dir.dot(ng) <= 0.0 {
        reflect_dir = reflect_f64(d, ng).normalize_or_zero();
    }
    if reflect_dir.dot(ng) <= 0.0 {
        reflect_dir = DVec3::ZERO;
    }

    let transmission = if glass { obj.transmission as f64 } else { 0.0 };
    let mut refraction = base * ((1.0 - metallic) * transmission * (1.0 - f));
    let mut refract_dir = DVec3::ZERO;
    if refraction.max_element() > 0.0 {
        let through = |n: DVec3| refract_f64(d, n, eta).map(DVec3::normalize_or_zero).filter(|t| t.dot(ng) < 0.0);
        refract_dir = through(ns).or_else(|| through(ng)).unwrap_or(DVec3::ZERO);
    }
    if refract_dir == DVec3::ZERO {
        refraction = DVec3::ZERO;
    }
    Lobes64 { reflection, refraction, reflect_dir, refract_dir }
}

/// What the paths of one image did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathCounts {
    /// Secondary rays traced.
    pub rays: u64,
    /// The deepest bounce a traced ray belonged to (0: none traced).
    pub deepest: u32,
    /// Lobes with a non-zero weight and a direction that were not traced because the
    /// depth limit was reached (they saw `ENVIRONMENT_SPECULAR`).
    pub truncated: u64,
    /// The largest path weight (largest component of the product of the lobe weights
    /// from the pixel) of those lobes: a bound on how much of a pixel's radiance, per unit
    /// of what the lobe would have seen, the limit left out.
    pub truncated_weight: f64,
}

impl PathCounts {
    fn add(self, o: PathCounts) -> PathCounts {
        PathCounts {
            rays: self.rays + o.rays,
            deepest: self.deepest.max(o.deepest),
            truncated: self.truncated + o.truncated,
            truncated_weight: self.truncated_weight.max(o.truncated_weight),
        }
    }
}

/// The reference image with bounces ([`render_reference_bounces`]).
#[derive(Clone, Debug)]
pub struct BounceImage {
    /// Final image (linear RGBA), composed as [`crate::reference::shade_image`] composes.
    pub image: Vec<[f32; 4]>,
    pub max_depth: u32,
    pub paths: PathCounts,
}

/// Where a path is: the bounce of the ray that reached the surface (0 for the eye's) and
/// the path weight from the pixel to it.
#[derive(Clone, Copy, Debug)]
struct PathState {
    depth: u32,
    weight: DVec3,
}

/// The bounce paths of one view.
struct Paths<'a> {
    geometry: &'a WorldGeometry,
    bvh: &'a Bvh,
    max_depth: u32,
    extent: f64,
}

impl Paths<'_> {
    /// The f64 shadow codes of a surface, one per light.
    fn shadow(&self, hit: &ReferenceHit, s: &Surface64) -> Vec<u8> {
        let g = self.geometry;
        g.lights.iter().map(|l| reference_shadow(self.bvh, g.stored_table(), hit, s.ng, s.ns, l)).collect()
    }

    /// The radiance a bouncing surface (its object bounces, seen along the unit `d` by a ray
    /// `at` a depth and path weight) sends back: `shade_bouncing`'s local terms (its
    /// lobes' weights zero, so exactly its ambient and direct light, in f32) plus what
    /// the f64 lobes see times their weights.
    fn bouncing(
        &self,
        hit: &ReferenceHit,
        s: &Surface64,
        shadow: &[u8],
        d: DVec3,
        at: PathState,
        counts: &mut PathCounts,
    ) -> DVec3 {
        let g = self.geometry;
        let obj = &g.objects[hit.object as usize];
        let inward = g.triangle(hit.triangle as usize).flags & TRI_INWARD != 0;
        let l = lobes_f64(obj, s.ns, s.ng, d, sees_exterior(s.back_face, inward));
        let transmission = if obj.material_kind == MATERIAL_GLASS { obj.transmission } else { 0.0 };
        let local_lobes = Lobes {
            reflection: Vec3::ZERO,
            refraction: Vec3::ZERO,
            reflect_dir: Vec3::ZERO,
            refract_dir: Vec3::ZERO,
            diffuse_scale: 1.0 - transmission,
        };
        let (ambient, d32) = (&g.ambient, d.as_vec3());
        let local = shade_bouncing(&s.record, obj, &local_lobes, d32, shadow, &g.lights, ambient, [INVALID_ID; 2], &[]);
        let mut out = local.as_dvec3();
        let n = Vec3::from(s.record.normal);
        for (dir, weight) in [(l.reflect_dir, l.reflection), (l.refract_dir, l.refraction)] {
            if weight == DVec3::ZERO {
                continue;
            }
            // What an untraced lobe sees: the kernels' stand-in (the paper's uniform
            // environment specular, or the glTF model's prefiltered environment).
            let stand_in = || lobe_radiance(INVALID_ID, &[], obj, dir.as_vec3(), n, ambient).as_dvec3();
            let seen = if dir == DVec3::ZERO {
                stand_in()
            } else if at.depth >= self.max_depth {
                counts.truncated += 1;
                counts.truncated_weight = counts.truncated_weight.max((at.weight * weight).max_element());
                stand_in()
            } else {
                let next = PathState { depth: at.depth + 1, weight: at.weight * weight };
                self.trace(hit.position, dir, hit.triangle, next, counts)
            };
            out += weight * seen;
        }
        out
    }

    /// The radiance a secondary ray (`at` its bounce and path weight) brings back from
    /// `origin` along the unit `d`, leaving triangle `exclude`.
    fn trace(&self, origin: DVec3, d: DVec3, exclude: u32, at: PathState, counts: &mut PathCounts) -> DVec3 {
        counts.rays += 1;
        counts.deepest = counts.deepest.max(at.depth);
        let g = self.geometry;
        let t_min = REFERENCE_BOUNCE_T_MIN_REL * origin.abs().max_element().max(self.extent);
        let hit = Ray64::new(origin, d)
            .and_then(|ray| closest_hit_f64_excluding(self.bvh, g.stored_table(), &ray, t_min, f64::INFINITY, exclude));
        let Some((id, h)) = hit else {
            return environment_radiance(&g.environment, d.as_vec3()).as_dvec3();
        };
        let rh = ReferenceHit::new(g.stored_table(), id, h);
        let s = surface_of(&rh, g, -d);
        let shadow = self.shadow(&rh, &s);
        let obj = &g.objects[rh.object as usize];
        if bounces(obj) {
            self.bouncing(&rh, &s, &shadow, d, at, counts)
        } else if obj.flags & OBJ_RAY_TRACED != 0 {
            shade_rt_surface(&s.record, obj, &shadow, &g.lights, &g.ambient, (-d).as_vec3()).as_dvec3()
        } else {
            shade_raster_surface(&s.record, obj, &shadow, &g.lights, &g.ambient, (-d).as_vec3()).as_dvec3()
        }
    }
}

/// The reference image of `reference` (rendered by [`crate::reference::render_reference`]
/// for `camera` over `geometry` and `bvh`) with bounce paths down to `max_depth`
/// (0: none, the image is `reference.image` bit for bit). Pixels of ray-traced objects
/// that do not bounce, and rasterized pixels, keep the reference's own shading. Runs on
/// the current rayon pool.
pub fn render_reference_bounces(
    geometry: &WorldGeometry,
    bvh: &Bvh,
    camera: &Camera,
    reference: &ReferenceFrame,
    max_depth: u32,
) -> BounceImage {
    let paths = Paths { geometry, bvh, max_depth, extent: geometry.scene_extent() as f64 };
    let eye = camera.eye.as_dvec3();
    let nl = geometry.lights.len();
    let (rt, counts): (Vec<[f32; 4]>, Vec<PathCounts>) = reference
        .hits
        .par_iter()
        .zip(&reference.surfaces)
        .enumerate()
        .with_min_len(64)
        .map(|(i, (hit, s))| {
            let Some(hit) = hit else { return ([0.0; 4], PathCounts::default()) };
            let obj = &geometry.objects[hit.object as usize];
            if obj.flags & OBJ_RAY_TRACED == 0 {
                return ([0.0; 4], PathCounts::default());
            }
            let shadow = &reference.shadow[i * nl..(i + 1) * nl];
            if max_depth == 0 || !bounces(obj) {
                return (
                    shade_rt_pixel(s, obj, shadow, &geometry.lights, &geometry.ambient, camera.eye).extend(1.0).into(),
                    PathCounts::default(),
                );
            }
            let mut counts = PathCounts::default();
            let d = (hit.position - eye).normalize();
            let surface = surface_of(hit, geometry, -d);
            let eye_path = PathState { depth: 0, weight: DVec3::ONE };
            let l = paths.bouncing(hit, &surface, shadow, d, eye_path, &mut counts);
            (l.as_vec3().extend(1.0).into(), counts)
        })
        .unzip();
    let paths = counts.into_iter().fold(PathCounts::default(), PathCounts::add);
    let (objects, lights) = (&geometry.objects, &geometry.lights);
    let (surfaces, shadow, ambient) = (&reference.surfaces, &reference.shadow, &geometry.ambient);
    let image = compose_with_raster(&rt, surfaces, shadow, objects, lights, ambient, eye.as_vec3());
    BounceImage { image, max_depth, paths }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hyrt_core::kernels::bounce::{fresnel_dielectric, fresnel_schlick, refract};

    /// Agreement of the f32 kernels with their f64 mirrors: a few dozen roundings of
    /// values of order 1 in f32 (2^-24 each), as `kernels::bounce`'s own identity tests.
    const F32_KERNEL_TOL: f64 = 1e-5;

    #[test]
    fn f64_fresnel_and_snell_match_the_f32_kernels() {
        for i in 0..=40 {
            let cos = i as f64 / 40.0;
            for eta in [1.0 / 1.5, 1.5, 1.0 / 1.33, 2.4] {
                let f = fresnel_dielectric_f64(cos, eta);
                let f32k = fresnel_dielectric(cos as f32, eta as f32) as f64;
                assert!((f - f32k).abs() < F32_KERNEL_TOL, "cos {cos} eta {eta}: {f} {f32k}");
            }
            let f0 = DVec3::new(1.0, 0.76, 0.33);
            let s = fresnel_schlick_f64(f0, cos);
            let s32 = fresnel_schlick(f0.as_vec3(), cos as f32).as_dvec3();
            assert!((s - s32).abs().max_element() < F32_KERNEL_TOL, "{s} {s32}");
        }
        // Exact values: 4% at normal incidence for IOR 1.5, total reflection past the critical angle.
        assert!((fresnel_dielectric_f64(1.0, 1.0 / 1.5) - 0.04).abs() < 1e-15);
        assert_eq!(fresnel_dielectric_f64(0.5, 1.5), 1.0);
        let d = DVec3::new(0.6, -0.8, 0.0);
        let t = refract_f64(d, DVec3::Y, 1.0 / 1.5).unwrap();
        assert!((t.x - 0.6 / 1.5).abs() < 1e-15 && t.y < 0.0 && (t.length() - 1.0).abs() < 1e-15);
        let t32 = refract(d.as_vec3(), Vec3::Y, 1.0 / 1.5).unwrap().as_dvec3();
        assert!((t - t32).length() < F32_KERNEL_TOL);
        assert!(
            refract_f64(-d, -DVec3::Y, 1.5).is_some()
                && refract_f64(DVec3::new(0.8, -0.6, 0.0), DVec3::Y, 1.5).is_none()
        );
    }
}
