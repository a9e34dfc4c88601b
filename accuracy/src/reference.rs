//! The f64 reference renderer: primary visibility by ray casting through every pixel
//! centre and shadows from the exact hit point to every light, all in double precision.
//!
//! * Camera: the view-projection is rebuilt in f64 from the [`Camera`] (glam's `dcamera`,
//!   the same right-handed directx projection as [`Camera::view_projection`]) and each
//!   pixel's ray is unprojected exactly as `hyrt_core::kernels::camera::primary_ray` does
//!   it in f32: from the eye to the pixel centre's point on the far plane, `t` in
//!   `(near / far, 1)`.
//! * Triangles: the f32 vertices of `WorldGeometry::triangles` are exact in f64. The
//!   ray/triangle test is the watertight test (Woop, Benthin, Wald 2013) evaluated in
//!   f64 ([`intersect_triangle_f64`]); its edge functions are exactly antisymmetric, so a
//!   ray through a shared edge hits both neighbours (ties at equal `t` go to the lower
//!   global triangle index, as in [`Bvh::closest_hit`]).
//! * Traversal: the scene's [`Bvh`] (f32 boxes, conservative for the f32 vertices),
//!   walked by the one traversal loop of `hyrt_core::bvh::traversal`, tested in f64 with
//!   every box widened by [`REFERENCE_BOX_MARGIN`] and the far slab distance by
//!   [`REFERENCE_SLAB_FAR_SCALE`], so rounding in the f64 slab test can only visit more
//!   boxes, never lose a hit.
//! * Shadows: from the f64 hit point `p = w v0 + u v1 + v v2` (barycentrics of the f64
//!   test; `p` lies on its triangle's plane within about 1e-16 |p|) straight to each
//!   light, no origin offset: the hit triangle itself is excluded by id, and hits closer
//!   than [`REFERENCE_SHADOW_T_MIN`] of the segment are ignored (see there).
//! * Shading: the f64 surface is rounded to a [`SurfaceRecord`] and shaded with the CPU
//!   backend's shading and composition stages (the kernels of
//!   `hyrt_core::kernels::shading`), so an image error against it measures only the
//!   geometry and shadow decisions of a configuration.

use glam::{DMat4, DVec3, DVec4, Vec3};
use hyrt_core::bvh::traversal::{traverse, LeafFlow, NodeTest};
use hyrt_core::bvh::{Bvh, BvhNode};
use hyrt_core::formats::{
    LightRecord, ObjectRecord, SurfaceRecord, TriangleRecord, INVALID_ID, LIGHT_DIRECTIONAL, LIGHT_SPOT,
};
use hyrt_core::frame::{SHADOW_LIT, SHADOW_NO_RAY, SHADOW_OCCLUDED};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::shading::AmbientLight;
use hyrt_core::scene::Camera;
use rayon::prelude::*;

/// Unit roundoff of f64, 2^-53.
pub const F64_UNIT_ROUNDOFF: f64 = f64::EPSILON * 0.5;

/// pbrt-v4's gamma(n) = n u / (1 - n u) for f64 (Higham lemma 3.1).
pub const fn gamma64(n: u32) -> f64 {
    let nu = n as f64 * F64_UNIT_ROUNDOFF;
    nu / (1.0 - nu)
}

/// Relative widening of every BVH box before the f64 slab test: each side moves out by
/// `2^-20 (|min| + |max|)` per axis. The boxes already bound the f32 vertices exactly
/// (min/max of f32 values are exact); the margin only has to absorb the f64 slab test's
/// own rounding (a few 2^-53), so 2^-20 is generous. A wider box costs a visit, never a hit.
pub const REFERENCE_BOX_MARGIN: f64 = 1.0 / (1u64 << 20) as f64;

/// Scale of the far slab distances (pbrt-v4 `Bounds3::IntersectP`, `1 + 2 gamma(3)`, in f64).
pub const REFERENCE_SLAB_FAR_SCALE: f64 = 1.0 + 2.0 * gamma64(3);

/// Shadow rays of the reference ignore occluders with `t <= REFERENCE_SHADOW_T_MIN` (and,
/// for point lights, `t >= 1 - REFERENCE_SHADOW_T_MIN`) on the segment from the hit point
/// (`t = 0`) to the light (`t = 1`).
///
/// Why an epsilon at all: the f64 hit point lies within about `gamma64(7) |p|` (1e-15
/// relative) of its triangle's plane, so a *neighbour* sharing an edge or vertex with the
/// hit triangle (not excluded by id) can be hit at `t` of that order when `p` is on the
/// shared edge. 1e-9 is a million times above that, and about 60 times below the relative
/// precision of an f32 coordinate (2^-24 = 6e-8), so any occluder the f32 pipeline can
/// resolve at all is kept. The far end mirrors the pipeline's `SHADOW_T_MAX_POINT`: a
/// point light sitting on a surface is not occluded by it.
pub const REFERENCE_SHADOW_T_MIN: f64 = 1e-9;

/// A hit of the f64 ray/triangle test: `t` and the barycentric weights of `v1` (`u`) and
/// `v2` (`v`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit64 {
    pub t: f64,
    pub u: f64,
    pub v: f64,
}

/// A ray prepared for the f64 watertight test (the ray-space transform of Woop et al.).
#[derive(Clone, Copy, Debug)]
pub struct Ray64 {
    pub origin: DVec3,
    pub dir: DVec3,
    kz: usize,
    shear: DVec3,
    inv_dir: DVec3,
}

fn permute(v: DVec3, kz: usize) -> DVec3 {
    match kz {
        0 => DVec3::new(v.y, v.z, v.x),
        1 => DVec3::new(v.z, v.x, v.y),
        _ => v,
    }
}

impl Ray64 {
    /// `None` for a non-finite origin or direction or a zero direction (hits nothing).
    pub fn new(origin: DVec3, dir: DVec3) -> Option<Ray64> {
        if !(origin.is_finite() && dir.is_finite()) || dir == DVec3::ZERO {
            return None;
        }
        let a = dir.abs();
        // Largest axis last (ties: z, then y), as in hyrt_core::kernels::ray.
        let kz = if a.x > a.y && a.x > a.z {
            0
        } else if a.y > a.z {
            1
        } else {
            2
        };
        let d = permute(dir, kz);
        let shear = DVec3::new(d.x / d.z, d.y / d.z, 1.0 / d.z);
        Some(Ray64 { origin, dir, kz, shear, inv_dir: DVec3::ONE / dir })
    }

    fn transform(&self, p: DVec3) -> DVec3 {
        let q = permute(p - self.origin, self.kz);
        DVec3::new(q.x - self.shear.x * q.z, q.y - self.shear.y * q.z, q.z)
    }

    /// The watertight test for `t_min < t < t_max`, both faces.
    pub fn intersect(&self, t_min: f64, t_max: f64, v0: Vec3, v1: Vec3, v2: Vec3) -> Option<Hit64> {
        let p0 = self.transform(v0.as_dvec3());
        let p1 = self.transform(v1.as_dvec3());
        let p2 = self.transform(v2.as_dvec3());
        // e(a, b) = a.x b.y - a.y b.x is exactly antisymmetric (products commute, the
        // difference negates exactly): neighbours see a shared edge with opposite signs.
        let e = |a: DVec3, b: DVec3| a.x * b.y - a.y * b.x;
        let (e0, e1, e2) = (e(p1, p2), e(p2, p0), e(p0, p1));
        // Zeros accepted on both sides (a ray through an edge hits both neighbours).
        if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
            return None;
        }
        let det = e0 + e1 + e2;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let t_scaled = e0 * (self.shear.z * p0.z) + e1 * (self.shear.z * p1.z) + e2 * (self.shear.z * p2.z);
        let t = t_scaled / det;
        // Positive form: NaN rejects.
        if !(t > t_min && t < t_max) {
            return None;
        }
        Some(Hit64 { t, u: e1 / det, v: e2 / det })
    }

    /// Entry distance into a node's box widened by [`REFERENCE_BOX_MARGIN`], or `None`.
    fn enter(&self, node: &BvhNode, t_min: f64, t_max: f64) -> Option<f64> {
        let (lo, hi) = (node.min().as_dvec3(), node.max().as_dvec3());
        let m = (lo.abs() + hi.abs()) * REFERENCE_BOX_MARGIN;
        let (lo, hi) = (lo - m, hi + m);
        let mut t0 = t_min;
        let mut t1 = t_max;
        for a in 0..3 {
            let inv = self.inv_dir[a];
            let (near, far) = if inv.is_sign_negative() { (hi[a], lo[a]) } else { (lo[a], hi[a]) };
            let tn = (near - self.origin[a]) * inv;
            let tf = (far - self.origin[a]) * inv * REFERENCE_SLAB_FAR_SCALE;
            // NaN (origin on a slab plane, zero direction component) does not constrain.
            if tn > t0 {
                t0 = tn;
            }
            if tf < t1 {
                t1 = tf;
            }
        }
        (t0 <= t1).then_some(t0)
    }
}

/// [`Ray64::intersect`] for a single ray.
pub fn intersect_triangle_f64(
    origin: DVec3,
    dir: DVec3,
    t_min: f64,
    t_max: f64,
    v0: Vec3,
    v1: Vec3,
    v2: Vec3,
) -> Option<Hit64> {
    Ray64::new(origin, dir)?.intersect(t_min, t_max, v0, v1, v2)
}

/// The f64 node test of [`traverse`]: [`Ray64::enter`] over `(t_min, bound)`, where the
/// bound is `t_max` (any hit) or the closest `t` so far; nearer child first (ties left);
/// a stale entry is skipped when its entry distance lies beyond the bound (equal entry
/// distance is kept: the lower-index tie rule needs those boxes).
struct Interval64<'r> {
    ray: &'r Ray64,
    t_min: f64,
}

impl NodeTest for Interval64<'_> {
    type Entry = f64;
    type Bound = f64;

    #[inline]
    fn enter_root(&self, root: &BvhNode, t_far: &f64) -> Option<f64> {
        self.ray.enter(root, self.t_min, *t_far)
    }

    #[inline]
    fn enter(&self, node: &BvhNode, _parent: f64, t_far: &f64) -> Option<f64> {
        self.ray.enter(node, self.t_min, *t_far)
    }

    #[inline]
    fn right_first(&self, _left: &BvhNode, _right: &BvhNode, left_entry: f64, right_entry: f64) -> bool {
        right_entry < left_entry
    }

    /// A fresh entry passed `t_enter <= t_far` when tested (the entry distance never
    /// exceeds the far bound), so only stale ones are compared.
    #[inline]
    fn resume(&self, _node: &BvhNode, t_enter: f64, t_far: &f64, stale: bool) -> Option<f64> {
        (!stale || t_enter <= *t_far).then_some(t_enter)
    }
}

/// Closest hit `(global triangle, hit)` through the BVH in f64; ties at equal `t` go to
/// the lower triangle index.
pub fn closest_hit_f64(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    ray: &Ray64,
    t_min: f64,
    t_max: f64,
) -> Option<(u32, Hit64)> {
    closest_hit_f64_excluding(bvh, triangles, ray, t_min, t_max, INVALID_ID)
}

/// [`closest_hit_f64`] ignoring triangle `exclude` (`INVALID_ID`: none): the surface a
/// secondary ray leaves ([`crate::bounce_reference`]).
pub fn closest_hit_f64_excluding(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    ray: &Ray64,
    t_min: f64,
    t_max: f64,
    exclude: u32,
) -> Option<(u32, Hit64)> {
    let mut best: Option<(u32, Hit64)> = None;
    let mut best_t = t_max;
    traverse(&bvh.nodes, &Interval64 { ray, t_min }, &mut best_t, |leaf, _, best_t| {
        let mut flow = LeafFlow::Continue;
        leaf.slots().for_each(|slot| {
            let id = bvh.prim_indices[slot as usize];
            if id == exclude {
                return;
            }
            let tri = &triangles[id as usize];
            if let Some(h) = ray.intersect(t_min, t_max, tri.v0.into(), tri.v1.into(), tri.v2.into()) {
                let better = match best {
                    None => true,
                    Some((bid, b)) => h.t < b.t || (h.t == b.t && id < bid),
                };
                if better {
                    best = Some((id, h));
                    *best_t = h.t;
                    flow = LeafFlow::Narrowed;
                }
            }
        });
        flow
    });
    best
}

/// Any hit with `t_min < t < t_max` through the BVH in f64, ignoring triangle `exclude`.
pub fn occluded_f64(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    ray: &Ray64,
    t_min: f64,
    t_max: f64,
    exclude: u32,
) -> bool {
    traverse(&bvh.nodes, &Interval64 { ray, t_min }, &mut t_max.clone(), |leaf, _, _| {
        let hit = leaf.slots().any(|slot| {
            let id = bvh.prim_indices[slot as usize];
            let tri = &triangles[id as usize];
            id != exclude && ray.intersect(t_min, t_max, tri.v0.into(), tri.v1.into(), tri.v2.into()).is_some()
        });
        if hit {
            LeafFlow::Stop
        } else {
            LeafFlow::Continue
        }
    })
}

/// The camera in f64: eye and the inverse view-projection.
#[derive(Clone, Copy, Debug)]
pub struct Camera64 {
    pub eye: DVec3,
    pub inv_view_proj: DMat4,
    pub width: u32,
    pub height: u32,
    /// `near / far`: the ray parameter of the near plane.
    pub t_near: f64,
}

impl Camera64 {
    /// [`Camera::view_projection`] rebuilt in f64 (right-handed, directx depth).
    pub fn new(camera: &Camera, width: u32, height: u32) -> Camera64 {
        let eye = camera.eye.as_dvec3();
        let view = glam::dcamera::rh::view::look_at_mat4(eye, camera.target.as_dvec3(), camera.up.as_dvec3());
        let proj = glam::dcamera::rh::proj::directx::perspective(
            (camera.fov_y_deg as f64).to_radians(),
            width as f64 / height as f64,
            camera.near as f64,
            camera.far as f64,
        );
        Camera64 {
            eye,
            inv_view_proj: (proj * view).inverse(),
            width,
            height,
            t_near: camera.near as f64 / camera.far as f64,
        }
    }

    /// The primary ray of pixel `(x, y)`: eye to the pixel centre's far-plane point.
    pub fn primary_ray(&self, x: u32, y: u32) -> (DVec3, DVec3) {
        let nx = (x as f64 + 0.5) / self.width as f64 * 2.0 - 1.0;
        let ny = 1.0 - (y as f64 + 0.5) / self.height as f64 * 2.0;
        let far = self.inv_view_proj * DVec4::new(nx, ny, 1.0, 1.0);
        (self.eye, far.truncate() / far.w - self.eye)
    }
}

/// The reference primary hit of one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceHit {
    pub object: u32,
    /// Global triangle index into `WorldGeometry::triangles`.
    pub triangle: u32,
    pub t: f64,
    /// Barycentric weights of `v1` and `v2`.
    pub u: f64,
    pub v: f64,
    /// World-space hit point, `w v0 + u v1 + v v2` in f64.
    pub position: DVec3,
}

impl ReferenceHit {
    /// The hit `h` of global triangle `id`, its point rebuilt as `w v0 + u v1 + v v2` in f64.
    pub fn new(triangles: &[TriangleRecord], id: u32, h: Hit64) -> ReferenceHit {
        let tri = &triangles[id as usize];
        let [v0, v1, v2] = tri.vertices().map(|v| v.as_dvec3());
        let position = v0 * (1.0 - h.u - h.v) + v1 * h.u + v2 * h.v;
        ReferenceHit { object: tri.object, triangle: id, t: h.t, u: h.u, v: h.v, position }
    }
}

/// What the reference renderer produces for one view.
#[derive(Clone, Debug)]
pub struct ReferenceFrame {
    pub width: u32,
    pub height: u32,
    /// Per pixel (`y * width + x`).
    pub hits: Vec<Option<ReferenceHit>>,
    /// Per pixel and light (`pixel * lights + light`): `SHADOW_NO_RAY` (no hit, or the
    /// light cannot contribute), `SHADOW_LIT` or `SHADOW_OCCLUDED`.
    pub shadow: Vec<u8>,
    /// The f64 surfaces rounded to f32 records, for the shading stages.
    pub surfaces: Vec<SurfaceRecord>,
    /// Final image (linear RGBA) from the CPU shading stages at composition weight 1.
    pub image: Vec<[f32; 4]>,
}

/// An f64 surface: the rounded record the shading kernels read, and the f64 normals
/// (unit, facing the viewer) the reference's own decisions use.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Surface64 {
    pub record: SurfaceRecord,
    /// Geometric normal (zero for a degenerate triangle).
    pub ng: DVec3,
    /// Shading normal, in the geometric normal's hemisphere.
    pub ns: DVec3,
    /// The viewer sees the triangle's back (its winding's normal points away): the f64
    /// form of `GBUF_BACK_FACE` and `HIT_BACK_FACE`.
    pub back_face: bool,
}

/// The surface record of an f64 hit seen from the direction `to_viewer` (from the point
/// towards the eye or the ray's origin): mirrors `hyrt_core::kernels::reconstruction`
/// (geometric and interpolated shading normal, both facing the viewer: decided here by the
/// sign of `n . to_viewer` in f64, exact enough to be the truth, where the pipeline takes
/// the raster's `GBUF_BACK_FACE` or the watertight test's determinant because an f32 dot
/// product is not exact; the shading normal kept in the geometric normal's hemisphere), in
/// f64, rounded at the end.
pub(crate) fn surface_of(hit: &ReferenceHit, geometry: &WorldGeometry, to_viewer: DVec3) -> Surface64 {
    let tri = geometry.triangle(hit.triangle as usize);
    let [v0, v1, v2] = tri.vertices().map(|v| v.as_dvec3());
    let ng = (v1 - v0).cross(v2 - v0).normalize_or_zero();
    let w = 1.0 - hit.u - hit.v;
    let [n0, n1, n2] = geometry.triangles.normals(hit.triangle as usize).map(|n| n.as_dvec3());
    let ns = (n0 * w + n1 * hit.u + n2 * hit.v).normalize_or_zero();
    let ns = if ns == DVec3::ZERO {
        if ng == DVec3::ZERO {
            to_viewer.normalize_or(DVec3::Y)
        } else {
            ng
        }
    } else {
        ns
    };
    let back_face = ng.dot(to_viewer) < 0.0;
    let (ng, ns) = if back_face { (-ng, -ns) } else { (ng, ns) };
    let ns = if ng != DVec3::ZERO && ns.dot(ng) < 0.0 { ng } else { ns };
    let s = SurfaceRecord {
        position: hit.position.as_vec3().into(),
        position_error: 0.0,
        normal: ns.as_vec3().normalize().into(),
        object: hit.object,
        geometric_normal: ng.as_vec3().normalize_or_zero().into(),
        triangle: hit.triangle,
    };
    Surface64 { record: s, ng, ns, back_face }
}

/// Reference shadow decision for one (surface, light): `SHADOW_NO_RAY` where the light
/// cannot contribute (back side of either normal, no energy: the f64 form of
/// `hyrt_core::kernels::shading::light_can_contribute`), else traced in f64.
pub(crate) fn reference_shadow(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    hit: &ReferenceHit,
    ng: DVec3,
    ns: DVec3,
    light: &LightRecord,
) -> u8 {
    let pd = Vec3::from(light.position_or_direction).as_dvec3();
    let (dir, t_max) = if light.kind == LIGHT_DIRECTIONAL {
        (-pd, f64::INFINITY)
    } else {
        (pd - hit.position, 1.0 - REFERENCE_SHADOW_T_MIN)
    };
    let energy = light.radiance.iter().any(|&r| r > 0.0) && reference_falloff(light, dir) > 0.0;
    if !(ng.dot(dir) > 0.0 && ns.dot(dir) > 0.0 && energy) {
        return SHADOW_NO_RAY;
    }
    let Some(ray) = Ray64::new(hit.position, dir) else {
        return SHADOW_NO_RAY;
    };
    if occluded_f64(bvh, triangles, &ray, REFERENCE_SHADOW_T_MIN, t_max, hit.triangle) {
        SHADOW_OCCLUDED
    } else {
        SHADOW_LIT
    }
}

/// `KHR_lights_punctual`'s range window and spot cone factor in f64 at the offset `dir`
/// from the surface to the light (the f64 form of
/// `hyrt_core::kernels::shading::light_falloff`); 1 for directional lights.
fn reference_falloff(light: &LightRecord, dir: DVec3) -> f64 {
    if light.kind == LIGHT_DIRECTIONAL {
        return 1.0;
    }
    let d2 = dir.length_squared();
    let mut f = 1.0;
    if light.inv_range_sq > 0.0 {
        let x = d2 * f64::from(light.inv_range_sq);
        f = (1.0 - x * x).clamp(0.0, 1.0);
    }
    if light.kind == LIGHT_SPOT {
        let cd = -Vec3::from(light.spot_direction).as_dvec3().dot(dir / d2.sqrt());
        let a = (cd * f64::from(light.spot_scale) + f64::from(light.spot_offset)).clamp(0.0, 1.0);
        f *= a * a;
    }
    f
}

/// The shading stages of the CPU backend over surfaces and a shadow mask, composed at
/// weight 1 (the pipeline's default): the final image.
pub fn shade_image(
    surfaces: &[SurfaceRecord],
    shadow: &[u8],
    objects: &[ObjectRecord],
    lights: &[LightRecord],
    ambient: &AmbientLight,
    eye: Vec3,
) -> Vec<[f32; 4]> {
    let rt = hyrt_cpu::rt_shading::rt_shading(surfaces, shadow, objects, lights, ambient, eye);
    compose_with_raster(&rt, surfaces, shadow, objects, lights, ambient, eye)
}

/// The rest of [`shade_image`] after `rt_shading` (with or without bounces): the raster
/// shading stage (seen from `eye`) and composition at weight 1.
pub fn compose_with_raster(
    rt: &[[f32; 4]],
    surfaces: &[SurfaceRecord],
    shadow: &[u8],
    objects: &[ObjectRecord],
    lights: &[LightRecord],
    ambient: &AmbientLight,
    eye: Vec3,
) -> Vec<[f32; 4]> {
    let raster = hyrt_cpu::raster_shading::raster_shading(surfaces, shadow, objects, lights, ambient, eye, 1.0);
    hyrt_cpu::composition::composition(&raster, rt, 1.0)
}

/// Render the f64 reference of `camera` at `width` x `height` (both > 0). `bvh` must be
/// built over `geometry`. Runs on the current rayon pool.
pub fn render_reference(
    geometry: &WorldGeometry,
    bvh: &Bvh,
    camera: &Camera,
    width: u32,
    height: u32,
) -> ReferenceFrame {
    let cam = Camera64::new(camera, width, height);
    let tris = geometry.stored_table();
    let nl = geometry.lights.len();
    let per_pixel: Vec<(Option<ReferenceHit>, SurfaceRecord, Vec<u8>)> = (0..width as usize * height as usize)
        .into_par_iter()
        .with_min_len(256)
        .map(|i| {
            let (x, y) = ((i % width as usize) as u32, (i / width as usize) as u32);
            let (o, d) = cam.primary_ray(x, y);
            let hit = Ray64::new(o, d).and_then(|r| closest_hit_f64(bvh, tris, &r, cam.t_near, 1.0));
            let Some((id, h)) = hit else {
                return (None, SurfaceRecord::MISS, vec![SHADOW_NO_RAY; nl]);
            };
            let rh = ReferenceHit::new(tris, id, h);
            let s = surface_of(&rh, geometry, cam.eye - rh.position);
            let shadow = geometry.lights.iter().map(|l| reference_shadow(bvh, tris, &rh, s.ng, s.ns, l)).collect();
            (Some(rh), s.record, shadow)
        })
        .collect();
    let mut hits = Vec::with_capacity(per_pixel.len());
    let mut surfaces = Vec::with_capacity(per_pixel.len());
    let mut shadow = Vec::with_capacity(per_pixel.len() * nl);
    for (h, s, m) in per_pixel {
        hits.push(h);
        surfaces.push(s);
        shadow.extend_from_slice(&m);
    }
    let image = shade_image(&surfaces, &shadow, &geometry.objects, &geometry.lights, &geometry.ambient, camera.eye);
    ReferenceFrame { width, height, hits, shadow, surfaces, image }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f64_test_pins_exact_values_and_both_faces() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let h = intersect_triangle_f64(DVec3::new(0.25, 0.25, 1.0), DVec3::NEG_Z, 0.0, f64::INFINITY, a, b, c).unwrap();
        assert_eq!((h.t, h.u, h.v), (1.0, 0.25, 0.25));
        // From behind: the same point.
        let h = intersect_triangle_f64(DVec3::new(0.25, 0.25, -2.0), DVec3::Z, 0.0, f64::INFINITY, a, b, c).unwrap();
        assert_eq!((h.t, h.u, h.v), (2.0, 0.25, 0.25));
        // Bounds are open: t == t_max and t == t_min miss.
        assert!(intersect_triangle_f64(DVec3::new(0.25, 0.25, 1.0), DVec3::NEG_Z, 0.0, 1.0, a, b, c).is_none());
        assert!(intersect_triangle_f64(DVec3::new(0.25, 0.25, 1.0), DVec3::NEG_Z, 1.0, 2.0, a, b, c).is_none());
        // Non-finite input and degenerate triangles never hit.
        assert!(Ray64::new(DVec3::splat(f64::NAN), DVec3::Z).is_none());
        assert!(Ray64::new(DVec3::ZERO, DVec3::ZERO).is_none());
        assert!(intersect_triangle_f64(DVec3::new(0.0, 0.0, 1.0), DVec3::NEG_Z, 0.0, 9.0, a, a, c).is_none());
    }

    #[test]
    fn a_ray_through_a_shared_edge_hits_both_triangles() {
        // Two triangles sharing the diagonal (1, 0) - (0, 1) of the unit square.
        let (p0, p1, p2, p3) = (Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0));
        let o = DVec3::new(0.5, 0.5, 3.0);
        let first = intersect_triangle_f64(o, DVec3::NEG_Z, 0.0, 9.0, p0, p1, p2).unwrap();
        let second = intersect_triangle_f64(o, DVec3::NEG_Z, 0.0, 9.0, p1, p3, p2).unwrap();
        assert_eq!(first.t, 3.0);
        assert_eq!(second.t, 3.0);
    }

    #[test]
    fn camera_rays_go_from_the_eye_through_the_pixel_centre_to_the_far_plane() {
        let cam = Camera {
            eye: Vec3::new(0.0, 1.0, 5.0),
            target: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 90.0,
            near: 0.5,
            far: 50.0,
        };
        let c = Camera64::new(&cam, 2, 2);
        assert_eq!(c.t_near, 0.01);
        // Pixel (1, 0) is right of and above the centre: at the far plane (depth 50),
        // tan 45 deg puts it at x = y - 1 = 50 * 0.5.
        let (o, d) = c.primary_ray(1, 0);
        assert_eq!(o, DVec3::new(0.0, 1.0, 5.0));
        let far = o + d;
        assert!((far - DVec3::new(25.0, 26.0, -45.0)).length() < 1e-12, "{far}");
    }
}
