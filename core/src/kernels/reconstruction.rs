//! The `reconstruction` kernel (paper eq. 1): the world-space surface at one
//! G-buffer texel, from the [`crate::kernels::barycentric`] kernels.
//!
//! WGSL mirror: `reconstruct_texel` in the GPU backend's `reconstruction.wgsl`.

use glam::Vec3;

use crate::formats::{GBufferTexel, SurfaceRecord, GBUF_BACK_FACE};
use crate::geometry::WorldGeometry;
use crate::kernels::barycentric::{geometric_normal, interpolate_normal, position_error_bound, reconstruct_position};
use crate::kernels::shading::orient_to_seen_side;

/// Rebuild the surface at one G-buffer texel seen from `eye`.
#[inline]
pub fn reconstruct_texel(t: &GBufferTexel, geometry: &WorldGeometry, eye: Vec3) -> SurfaceRecord {
    if !t.is_hit() {
        return SurfaceRecord::MISS;
    }
    let gi = geometry.global_triangle(t.object, t.triangle);
    let [v0, v1, v2] = geometry.triangles[gi].vertices();
    let p = reconstruct_position(t.bary_u, t.bary_v, v0, v1, v2);
    let err = position_error_bound(t.bary_u, t.bary_v, v0, v1, v2).max_element();
    let ng = geometric_normal(v0, v1, v2);
    let ns = interpolate_normal(t.bary_u, t.bary_v, geometry.normals[gi], ng);
    // The side the raster saw, exactly (the sign of the snapped triangle's area).
    let (ng, ns) = orient_to_seen_side(ng, ns, t.flags & GBUF_BACK_FACE != 0);
    // A degenerate triangle without vertex normals has no normal at all: shade it as
    // facing the viewer.
    let ns = if ns == Vec3::ZERO { (eye - p).normalize_or(Vec3::Y) } else { ns };
    // Keep the shading normal in the viewer's hemisphere of the geometric normal
    // (interpolated normals can point away at silhouettes).
    let ns = if ng != Vec3::ZERO && ns.dot(ng) < 0.0 { ng } else { ns };
    SurfaceRecord {
        position: p.into(),
        position_error: err,
        normal: ns.into(),
        object: t.object,
        geometric_normal: ng.into(),
        triangle: gi as u32,
    }
}
