//! The `reconstruction` kernel (paper eq. 1): the world-space surface at one
//! G-buffer texel, from the [`crate::kernels::barycentric`] kernels.
//!
//! WGSL mirror: `reconstruct_texel` in the GPU backend's `reconstruction.wgsl`;
//! `reconstruct_hit` in `bounce.wgsl`.

use glam::Vec3;

use crate::formats::{GBufferTexel, HitRecord, RayRecord, SurfaceRecord, GBUF_BACK_FACE};
use crate::geometry::WorldGeometry;
use crate::kernels::barycentric::{geometric_normal, interpolate_normal, position_error_bound, reconstruct_position};
use crate::kernels::ray::WatertightRay;
use crate::kernels::shading::orient_to_seen_side;

/// Rebuild the surface at one G-buffer texel seen from `eye`, from the raster's
/// barycentrics.
#[inline]
pub fn reconstruct_texel(t: &GBufferTexel, geometry: &WorldGeometry, eye: Vec3) -> SurfaceRecord {
    if !t.is_hit() {
        return SurfaceRecord::MISS;
    }
    texel_surface(t, geometry, eye, (t.bary_u, t.bary_v))
}

/// The barycentrics `(u, v)` of the point where `ray` (the pixel's camera ray,
/// [`crate::kernels::camera::primary_ray`]) meets the triangle the G-buffer texel `t` names,
/// by the watertight kernel over `0 < t < inf` (the raster already chose the triangle, so
/// the near and far planes play no part); the raster's barycentrics where the ray misses
/// the triangle (its centre covered by the snapped triangle, not by the exact one) or the
/// test is degenerate. `t` must be a hit.
#[inline]
pub fn reintersected_barycentrics(t: &GBufferTexel, geometry: &WorldGeometry, ray: &RayRecord) -> (f32, f32) {
    let gi = geometry.global_triangle(t.object, t.triangle);
    let [v0, v1, v2] = geometry.triangle(gi).vertices();
    WatertightRay::new(Vec3::from(ray.origin), Vec3::from(ray.direction))
        .and_then(|w| w.intersect(0.0, f32::INFINITY, v0, v1, v2))
        .map_or((t.bary_u, t.bary_v), |h| (h.u, h.v))
}

/// Rebuild the surface at one G-buffer texel from the barycentrics of its camera ray
/// `ray` ([`reintersected_barycentrics`]); the facing stays the raster's (the side
/// visibility chose).
#[inline]
pub fn reconstruct_texel_reintersected(t: &GBufferTexel, geometry: &WorldGeometry, ray: &RayRecord) -> SurfaceRecord {
    if !t.is_hit() {
        return SurfaceRecord::MISS;
    }
    texel_surface(t, geometry, Vec3::from(ray.origin), reintersected_barycentrics(t, geometry, ray))
}

/// The surface of a hit texel at barycentrics `(u, v)` of its triangle, seen from `eye`.
#[inline]
fn texel_surface(t: &GBufferTexel, geometry: &WorldGeometry, eye: Vec3, (u, v): (f32, f32)) -> SurfaceRecord {
    let gi = geometry.global_triangle(t.object, t.triangle);
    let tri = geometry.triangle(gi);
    let [v0, v1, v2] = tri.vertices();
    let p = reconstruct_position(u, v, v0, v1, v2);
    // A degenerate triangle without vertex normals is shaded as facing the viewer.
    let toward_viewer = || (eye - p).normalize_or(Vec3::Y);
    surface_at(geometry, gi, &tri, u, v, t.flags & GBUF_BACK_FACE != 0, p, toward_viewer)
}

/// Rebuild the surface a secondary ray hit (`bounce_trace`): the paper's eq. 1 again,
/// from the closest hit's barycentrics, on the side the ray saw (the hit's exact
/// facing, `HIT_BACK_FACE`). A miss gives [`SurfaceRecord::MISS`].
#[inline]
pub fn reconstruct_hit(hit: &HitRecord, geometry: &WorldGeometry, direction: Vec3) -> SurfaceRecord {
    if !hit.is_hit() {
        return SurfaceRecord::MISS;
    }
    let gi = hit.triangle as usize;
    let tri = geometry.triangle(gi);
    let [v0, v1, v2] = tri.vertices();
    let p = reconstruct_position(hit.u, hit.v, v0, v1, v2);
    let toward_viewer = || (-direction).normalize_or(Vec3::Y);
    surface_at(geometry, gi, &tri, hit.u, hit.v, hit.is_back_face(), p, toward_viewer)
}

/// The surface record at barycentrics `(u, v)` of global triangle `gi` (record `tri`), whose point
/// `p` the caller reconstructed, seen from its back when `back_face`; a degenerate
/// triangle without vertex normals gets the normal `toward_viewer()`.
#[inline]
#[allow(clippy::too_many_arguments)]
fn surface_at(
    geometry: &WorldGeometry,
    gi: usize,
    tri: &crate::formats::TriangleRecord,
    u: f32,
    v: f32,
    back_face: bool,
    p: Vec3,
    toward_viewer: impl FnOnce() -> Vec3,
) -> SurfaceRecord {
    let [v0, v1, v2] = tri.vertices();
    // Its object's offset error: what tracing its rays in the object's own space adds
    // (0 for an object baked into world space; `kernels::instance`).
    let err = position_error_bound(u, v, v0, v1, v2).max_element() + geometry.objects[tri.object as usize].offset_error;
    let ng = geometric_normal(v0, v1, v2);
    let ns = interpolate_normal(u, v, geometry.triangles.normals(gi), ng);
    // The side the ray saw, exactly (for primary hits the sign of the snapped triangle's
    // area, for secondary hits the sign of the watertight determinant).
    let (ng, ns) = orient_to_seen_side(ng, ns, back_face);
    let ns = if ns == Vec3::ZERO { toward_viewer() } else { ns };
    // Keep the shading normal in the viewer's hemisphere of the geometric normal
    // (interpolated normals can point away at silhouettes).
    let ns = if ng != Vec3::ZERO && ns.dot(ng) < 0.0 { ng } else { ns };
    SurfaceRecord {
        position: p.into(),
        position_error: err,
        normal: ns.into(),
        object: tri.object,
        geometric_normal: ng.into(),
        triangle: gi as u32,
    }
}
