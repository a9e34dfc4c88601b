//! Shadow maps, the rasterized alternative to ray-traced shadows the paper argues
//! against: one cube map (6 faces of 90 degrees) per point light, one orthographic map
//! over the scene per directional light, each face rendered with the CPU backend's
//! `visibility_raster` stage from a camera at the light.
//!
//! Lookup, per (pixel, light) that needs a shadow ray (`hyrt_cpu::compaction::needs_shadow_ray`,
//! the same pairs the ray tracer traces): project the reconstructed surface point into
//! the face its direction from the light falls in, take the nearest texel, and compare
//! linear depths: the distance to a point light (as omnidirectional shadow maps store it,
//! e.g. LearnOpenGL's "Point Shadows"), the distance along a directional light's
//! direction. The occluder's depth is rebuilt from the face's
//! G-buffer (triangle and barycentrics at the texel centre, paper eq. 1) rather than read
//! from the window depth `z / w`: linear depth in f32 is far more precise than the
//! hyperbolic one, so the comparison isolates what resolution costs. A texel with no
//! triangle is lit.

use glam::{Mat4, Vec3, Vec4};
use hyrt_core::formats::{CameraRecord, GBufferTexel, LightRecord, SurfaceRecord, LIGHT_DIRECTIONAL};
use hyrt_core::frame::{SHADOW_LIT, SHADOW_NO_RAY, SHADOW_OCCLUDED};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::barycentric::reconstruct_position;
use hyrt_core::kernels::shading::light_incidence;
use hyrt_core::scene::Camera;
use hyrt_cpu::compaction::needs_shadow_ray;
use hyrt_cpu::visibility_raster::visibility_raster_into;
use rayon::prelude::*;

/// Constant depth bias, in texels of world size at the receiver's depth (a cube-face
/// texel spans at most `2 d / resolution` at distance `d`): covers the
/// occluder depth being taken at the texel centre rather than at the receiver (curvature,
/// neighbouring triangles of a mesh). The usual starting value of a constant bias of one
/// texel (the "normal offset" / slope-scaled scheme in Microsoft's "Common Techniques to
/// Improve Shadow Depth Maps"), not tuned per scene.
pub const SHADOW_MAP_CONSTANT_BIAS_TEXELS: f32 = 1.0;

/// Slope-scaled bias, in texels times `tan` of the angle between the receiver's
/// geometric normal and the direction to the light: the receiver is at most half a texel
/// diagonal (0.71 texel) from the texel centre's ray, so a plane's depth differs there by
/// at most 0.71 x texel x tan; 1.0 covers it (D3D's `SlopeScaledDepthBias` in world
/// units; the `tan(acos(n.l))` bias of the common shadow-mapping tutorials).
pub const SHADOW_MAP_SLOPE_BIAS_TEXELS: f32 = 1.0;

/// Cap on the slope factor (`tan` 84 degrees): grazing receivers would otherwise get
/// an unbounded bias and lose every shadow.
pub const SHADOW_MAP_MAX_SLOPE: f32 = 10.0;

/// Near plane of the cube-map faces as a fraction of the scene extent: nothing closer to
/// the light than this casts a shadow (geometry through a light is not expected).
pub const SHADOW_MAP_NEAR_REL: f32 = 1e-4;

/// The six cube faces: axis and up vector.
const CUBE_FACES: [(Vec3, Vec3); 6] = [
    (Vec3::X, Vec3::Y),
    (Vec3::NEG_X, Vec3::Y),
    (Vec3::Y, Vec3::Z),
    (Vec3::NEG_Y, Vec3::Z),
    (Vec3::Z, Vec3::Y),
    (Vec3::NEG_Z, Vec3::Y),
];

/// Which cube face the direction `d` (from the light) falls in: the index in
/// `CUBE_FACES` of its largest-magnitude axis (ties: x before y before z).
#[inline]
pub fn cube_face(d: Vec3) -> usize {
    let a = d.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    axis * 2 + (d[axis] < 0.0) as usize
}

/// One rendered shadow-map face.
struct Face {
    record: CameraRecord,
    view_proj: Mat4,
    /// Origin depths are measured from: the light, or the orthographic camera's eye.
    origin: Vec3,
    /// `None`: depth is the distance to `origin` (point light); `Some(d)`: depth is
    /// measured along `d` (directional light).
    axis: Option<Vec3>,
    /// World size of one texel at depth `d`: `texel_at_depth.0 + d * texel_at_depth.1`.
    texel_at_depth: (f32, f32),
}

fn perspective_face(light: Vec3, axis: Vec3, up: Vec3, res: u32, near: f32, far: f32) -> Face {
    let cam = Camera { eye: light, target: light + axis, up, fov_y_deg: 90.0, near, far };
    let record = CameraRecord::new(&cam, res, res);
    // A 90-degree face spans depth d by 2d in world units over `res` texels. Lookups
    // project world points with the world-to-clip matrix (the record's is eye-relative).
    Face {
        view_proj: cam.view_projection(res, res),
        record,
        origin: light,
        axis: None,
        texel_at_depth: (0.0, 2.0 / res as f32),
    }
}

fn orthographic_face(geometry: &WorldGeometry, dir: Vec3, res: u32) -> Face {
    let (lo, hi) = geometry.bounds;
    let center = (lo + hi) * 0.5;
    let r = ((hi - lo).length() * 0.5).max(1e-3);
    let dir = dir.normalize();
    let eye = center - dir * (2.0 * r);
    let up = if dir.cross(Vec3::Y).length_squared() > 1e-6 { Vec3::Y } else { Vec3::Z };
    let view = glam::camera::rh::view::look_to_mat4(eye, dir, up);
    let proj = glam::camera::rh::proj::directx::orthographic(-r, r, -r, r, r * 0.5, r * 3.5);
    let vp = proj * view;
    // The record's matrices are eye-relative (the raster projects `p - eye`).
    let vp_from_eye = proj * glam::camera::rh::view::look_to_mat4(Vec3::ZERO, dir, up);
    let record = CameraRecord {
        view_proj: vp_from_eye.to_cols_array(),
        inv_view_proj: vp_from_eye.inverse().to_cols_array(),
        eye: eye.into(),
        width: res,
        height: res,
        near: r * 0.5,
        far: r * 3.5,
        pad: 0,
    };
    Face { view_proj: vp, record, origin: eye, axis: Some(dir), texel_at_depth: (2.0 * r / res as f32, 0.0) }
}

/// The shadow decision of one receiver point against one rendered face.
fn lookup(face: &Face, gbuffer: &[GBufferTexel], geometry: &WorldGeometry, p: Vec3, ng: Vec3, l: Vec3) -> u8 {
    let res = face.record.width;
    let clip = face.view_proj * Vec4::new(p.x, p.y, p.z, 1.0);
    let (nx, ny) = (clip.x / clip.w, clip.y / clip.w);
    let texel = |ndc: f32| (((ndc + 1.0) * 0.5 * res as f32).floor() as i64).clamp(0, res as i64 - 1) as usize;
    let (tx, ty) = (texel(nx), texel(-ny));
    let t = &gbuffer[ty * res as usize + tx];
    if !t.is_hit() {
        return SHADOW_LIT;
    }
    let [v0, v1, v2] = geometry.triangle(geometry.global_triangle(t.object, t.triangle)).vertices();
    let depth = |q: Vec3| match face.axis {
        None => (q - face.origin).length(),
        Some(d) => (q - face.origin).dot(d),
    };
    let occluder = depth(reconstruct_position(t.bary_u, t.bary_v, v0, v1, v2));
    let receiver = depth(p);
    let texel_size = face.texel_at_depth.0 + receiver * face.texel_at_depth.1;
    let cos = ng.dot(l).abs();
    let tan = if cos > 0.0 {
        ((1.0 - cos * cos).max(0.0).sqrt() / cos).min(SHADOW_MAP_MAX_SLOPE)
    } else {
        SHADOW_MAP_MAX_SLOPE
    };
    let bias = texel_size * (SHADOW_MAP_CONSTANT_BIAS_TEXELS + SHADOW_MAP_SLOPE_BIAS_TEXELS * tan);
    if receiver - bias > occluder {
        SHADOW_OCCLUDED
    } else {
        SHADOW_LIT
    }
}

/// The shadow mask (`pixel * lights + light`, `SHADOW_*`) of `surfaces` from shadow
/// maps of `resolution` texels per side (per cube face for point lights). Pairs the
/// ray tracer would not trace are `SHADOW_NO_RAY`, as in the pipeline's mask.
pub fn shadow_map_mask(geometry: &WorldGeometry, surfaces: &[SurfaceRecord], resolution: u32) -> Vec<u8> {
    let lights = &geometry.lights;
    let nl = lights.len();
    let mut mask = vec![SHADOW_NO_RAY; surfaces.len() * nl];
    if nl == 0 || resolution == 0 {
        return mask;
    }
    let extent = geometry.scene_extent();
    let mut gbuffer = Vec::new();
    for (li, light) in lights.iter().enumerate() {
        let faces: Vec<(Option<usize>, Face)> = face_cameras(geometry, light, resolution, extent);
        for (index, face) in &faces {
            visibility_raster_into(geometry, &face.record, &mut gbuffer);
            let light_pos = Vec3::from(light.position_or_direction);
            mask.par_chunks_mut(nl).zip(surfaces.par_iter()).with_min_len(1024).for_each(|(m, s)| {
                if !needs_shadow_ray(s, light) {
                    return;
                }
                let p = Vec3::from(s.position);
                if let Some(i) = index {
                    if cube_face(p - light_pos) != *i {
                        return;
                    }
                }
                let l = light_incidence(light, p).0;
                m[li] = lookup(face, &gbuffer, geometry, p, Vec3::from(s.geometric_normal), l);
            });
        }
    }
    mask
}

/// The faces of one light: six `(Some(face index), face)` for a point light, one
/// `(None, face)` for a directional light.
fn face_cameras(geometry: &WorldGeometry, light: &LightRecord, res: u32, extent: f32) -> Vec<(Option<usize>, Face)> {
    let pd = Vec3::from(light.position_or_direction);
    if light.kind == LIGHT_DIRECTIONAL {
        return vec![(None, orthographic_face(geometry, pd, res))];
    }
    let (lo, hi) = geometry.bounds;
    // Far plane: beyond the farthest corner of the world bounds.
    let far_corner = (pd - lo).abs().max((pd - hi).abs()).length();
    let near = (SHADOW_MAP_NEAR_REL * extent).max(1e-6);
    let far = (far_corner * 1.01).max(near * 2.0);
    CUBE_FACES
        .iter()
        .enumerate()
        .map(|(i, &(axis, up))| (Some(i), perspective_face(pd, axis, up, res, near, far)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cube_face_picks_the_dominant_axis() {
        assert_eq!(cube_face(Vec3::new(2.0, 1.0, -1.0)), 0);
        assert_eq!(cube_face(Vec3::new(-2.0, 1.0, -1.0)), 1);
        assert_eq!(cube_face(Vec3::new(0.0, 3.0, 1.0)), 2);
        assert_eq!(cube_face(Vec3::new(0.0, -3.0, 1.0)), 3);
        assert_eq!(cube_face(Vec3::new(0.0, 0.5, 1.0)), 4);
        assert_eq!(cube_face(Vec3::new(0.0, 0.5, -1.0)), 5);
        for (i, (axis, up)) in CUBE_FACES.iter().enumerate() {
            assert_eq!(cube_face(*axis), i);
            assert_eq!(axis.dot(*up), 0.0);
        }
    }
}
