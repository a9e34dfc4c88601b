//! The `reconstruction` kernel (paper eq. 1): the world-space surface at one
//! G-buffer texel, from the [`crate::kernels::barycentric`] kernels.
//!
//! WGSL mirror: `reconstruct_texel` in the GPU backend's `reconstruction.wgsl`;
//! `reconstruct_hit` in `bounce.wgsl`.

use glam::Vec3;

use crate::formats::{GBufferTexel, HitRecord, RayRecord, SurfaceRecord, TriangleRecord, GBUF_BACK_FACE};
use crate::geometry::WorldGeometry;
use crate::kernels::barycentric::{geometric_normal, interpolate_normal, position_error_bound, reconstruct_position};
use crate::kernels::bounce::primary_cone;
use crate::kernels::ray::WatertightRay;
use crate::kernels::shading::orient_to_seen_side;
use crate::kernels::texture::Materials;

/// The primary hit `s` of G-buffer texel `t` with its material's normal map
/// ([`Materials::normal_mapped`]), seen as [`crate::kernels::bounce::primary_parent`] sees
/// it (footprint [`primary_cone`], direction from `eye`) at the G-buffer's barycentrics,
/// on the side the raster saw. What `reconstruction` does after [`reconstruct_texel`] in
/// a scene with normal maps. WGSL: `primary_normal_mapped`.
#[inline]
pub fn primary_normal_mapped(t: &GBufferTexel, s: &SurfaceRecord, eye: Vec3, m: &Materials) -> SurfaceRecord {
    if !s.is_hit() {
        return *s;
    }
    let to_eye = eye - Vec3::from(s.position);
    let d = -to_eye.normalize_or_zero();
    m.normal_mapped(s, t.bary_u, t.bary_v, primary_cone(m, to_eye), d, t.flags & GBUF_BACK_FACE != 0)
}

/// The surface `s` a secondary ray hit ([`reconstruct_hit`]) with its material's normal
/// map, seen as [`crate::kernels::bounce::secondary_parent`] sees it (the ray's cone
/// widened over the distance, its direction) on the side the ray saw. What
/// `bounce_trace` does after [`reconstruct_hit`] in a scene with normal maps. WGSL:
/// `secondary_normal_mapped`.
#[inline]
pub fn secondary_normal_mapped(ray: &RayRecord, hit: &HitRecord, s: &SurfaceRecord, m: &Materials) -> SurfaceRecord {
    if !s.is_hit() {
        return *s;
    }
    let cone = if m.spread == 0.0 { 0.0 } else { ray.cone + m.spread * hit.t };
    m.normal_mapped(s, hit.u, hit.v, cone, Vec3::from(ray.direction), hit.is_back_face())
}

/// Rebuild the surface at one G-buffer texel seen from `eye`, from the raster's
/// barycentrics.
#[inline]
pub fn reconstruct_texel(t: &GBufferTexel, geometry: &WorldGeometry, eye: Vec3) -> SurfaceRecord {
    reconstruct_texel_cached(t, geometry, eye, &mut None)
}

/// [`reconstruct_texel`] keeping its triangle's setup in `cache` for the next texel: a
/// run of texels on one triangle (neighbouring pixels) fetches its record and normals and
/// normalizes its geometric normal once. The same bits as [`reconstruct_texel`].
#[inline]
pub fn reconstruct_texel_cached(
    t: &GBufferTexel,
    geometry: &WorldGeometry,
    eye: Vec3,
    cache: &mut Option<TriangleSetup>,
) -> SurfaceRecord {
    if !t.is_hit() {
        return SurfaceRecord::MISS;
    }
    let setup = TriangleSetup::cached(cache, geometry, geometry.global_triangle(t.object, t.triangle));
    texel_surface(t, setup, eye, (t.bary_u, t.bary_v))
}

/// What reconstruction computes of a triangle before it looks at a texel's barycentrics:
/// its record, corner normals, unit geometric normal and its object's offset error.
#[derive(Clone, Copy, Debug)]
pub struct TriangleSetup {
    /// The global triangle index.
    gi: usize,
    tri: TriangleRecord,
    normals: [Vec3; 3],
    /// [`geometric_normal`] of its vertices (not yet oriented to the seen side).
    geometric: Vec3,
    /// `ObjectRecord::offset_error` of its object.
    offset_error: f32,
}

impl TriangleSetup {
    /// The setup of global triangle `gi`.
    #[inline]
    pub fn new(geometry: &WorldGeometry, gi: usize) -> TriangleSetup {
        let tri = geometry.triangle(gi);
        let [v0, v1, v2] = tri.vertices();
        TriangleSetup {
            gi,
            tri,
            normals: geometry.triangles.normals(gi),
            geometric: geometric_normal(v0, v1, v2),
            offset_error: geometry.objects[tri.object as usize].offset_error,
        }
    }

    /// The global triangle index.
    #[inline]
    pub fn index(&self) -> usize {
        self.gi
    }

    /// The triangle's record.
    #[inline]
    pub fn record(&self) -> &TriangleRecord {
        &self.tri
    }

    /// The triangle's corner normals (zero where it has none).
    #[inline]
    pub fn normals(&self) -> &[Vec3; 3] {
        &self.normals
    }

    /// Its unit geometric normal, not yet oriented to the seen side (zero when degenerate).
    #[inline]
    pub fn geometric(&self) -> Vec3 {
        self.geometric
    }

    /// `ObjectRecord::offset_error` of its object.
    #[inline]
    pub fn offset_error(&self) -> f32 {
        self.offset_error
    }

    /// The barycentrics of texel `t` (a hit on this triangle) that reconstruction uses
    /// with re-intersection: where the pixel's camera ray `ray` meets the triangle
    /// ([`reintersected_barycentrics`]).
    #[inline]
    pub fn reintersected_barycentrics(&self, t: &GBufferTexel, ray: &RayRecord) -> (f32, f32) {
        intersect_texel_triangle(t, &self.tri, ray)
    }

    /// The setup of `gi` from `cache` when it holds that triangle's, else made and kept there.
    #[inline]
    pub fn cached<'c>(cache: &'c mut Option<TriangleSetup>, geometry: &WorldGeometry, gi: usize) -> &'c TriangleSetup {
        match cache {
            Some(s) if s.gi == gi => {}
            _ => *cache = Some(TriangleSetup::new(geometry, gi)),
        }
        cache.as_ref().expect("set above")
    }
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
    intersect_texel_triangle(t, &geometry.triangle(gi), ray)
}

/// [`reintersected_barycentrics`] with the texel's triangle record `tri` given.
#[inline]
fn intersect_texel_triangle(t: &GBufferTexel, tri: &TriangleRecord, ray: &RayRecord) -> (f32, f32) {
    let [v0, v1, v2] = tri.vertices();
    WatertightRay::new(Vec3::from(ray.origin), Vec3::from(ray.direction))
        .and_then(|w| w.intersect(0.0, f32::INFINITY, v0, v1, v2))
        .map_or((t.bary_u, t.bary_v), |h| (h.u, h.v))
}

/// Rebuild the surface at one G-buffer texel from the barycentrics of its camera ray
/// `ray` ([`reintersected_barycentrics`]); the facing stays the raster's (the side
/// visibility chose).
#[inline]
pub fn reconstruct_texel_reintersected(t: &GBufferTexel, geometry: &WorldGeometry, ray: &RayRecord) -> SurfaceRecord {
    reconstruct_texel_reintersected_cached(t, geometry, ray, &mut None)
}

/// [`reconstruct_texel_reintersected`] keeping its triangle's setup in `cache`
/// ([`reconstruct_texel_cached`]). The same bits.
#[inline]
pub fn reconstruct_texel_reintersected_cached(
    t: &GBufferTexel,
    geometry: &WorldGeometry,
    ray: &RayRecord,
    cache: &mut Option<TriangleSetup>,
) -> SurfaceRecord {
    if !t.is_hit() {
        return SurfaceRecord::MISS;
    }
    let setup = TriangleSetup::cached(cache, geometry, geometry.global_triangle(t.object, t.triangle));
    texel_surface(t, setup, Vec3::from(ray.origin), intersect_texel_triangle(t, &setup.tri, ray))
}

/// The surface of a hit texel at barycentrics `(u, v)` of its triangle, seen from `eye`.
#[inline]
fn texel_surface(t: &GBufferTexel, setup: &TriangleSetup, eye: Vec3, (u, v): (f32, f32)) -> SurfaceRecord {
    let [v0, v1, v2] = setup.tri.vertices();
    let p = reconstruct_position(u, v, v0, v1, v2);
    // A degenerate triangle without vertex normals is shaded as facing the viewer.
    let toward_viewer = || (eye - p).normalize_or(Vec3::Y);
    surface_at(setup, u, v, t.flags & GBUF_BACK_FACE != 0, p, toward_viewer)
}

/// Rebuild the surface a secondary ray hit (`bounce_trace`): the paper's eq. 1 again,
/// from the closest hit's barycentrics, on the side the ray saw (the hit's exact
/// facing, `HIT_BACK_FACE`). A miss gives [`SurfaceRecord::MISS`].
#[inline]
pub fn reconstruct_hit(hit: &HitRecord, geometry: &WorldGeometry, direction: Vec3) -> SurfaceRecord {
    if !hit.is_hit() {
        return SurfaceRecord::MISS;
    }
    let setup = TriangleSetup::new(geometry, hit.triangle as usize);
    let [v0, v1, v2] = setup.tri.vertices();
    let p = reconstruct_position(hit.u, hit.v, v0, v1, v2);
    let toward_viewer = || (-direction).normalize_or(Vec3::Y);
    surface_at(&setup, hit.u, hit.v, hit.is_back_face(), p, toward_viewer)
}

/// The surface record at barycentrics `(u, v)` of the triangle of `setup`, whose point `p`
/// the caller reconstructed, seen from its back when `back_face`; a degenerate triangle
/// without vertex normals gets the normal `toward_viewer()`.
#[inline]
fn surface_at(
    setup: &TriangleSetup,
    u: f32,
    v: f32,
    back_face: bool,
    p: Vec3,
    toward_viewer: impl FnOnce() -> Vec3,
) -> SurfaceRecord {
    let [v0, v1, v2] = setup.tri.vertices();
    // Its object's offset error: what tracing its rays in the object's own space adds
    // (0 for an object baked into world space; `kernels::instance`).
    let err = position_error_bound(u, v, v0, v1, v2).max_element() + setup.offset_error;
    let ng = setup.geometric;
    let ns = interpolate_normal(u, v, setup.normals, ng);
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
        object: setup.tri.object,
        geometric_normal: ng.into(),
        triangle: setup.gi as u32,
    }
}
