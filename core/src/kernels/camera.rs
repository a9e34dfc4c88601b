//! Camera rays: the primary ray through a pixel centre, for what the raster pass
//! stands in for (paper 3.1). Benchmarks trace them against the BVH (closest hit) and
//! peers; the f64 reference renderer uses the same construction in double precision.

use glam::{Mat4, Vec3, Vec4};

use crate::formats::{CameraRecord, RayRecord};

/// Normalized device coordinates of the centre of pixel `(x, y)` (row 0 on top, NDC y up):
/// `ndc_x = (x + 0.5) / width * 2 - 1`, `ndc_y = 1 - (y + 0.5) / height * 2`.
#[inline]
pub fn pixel_centre_ndc(width: u32, height: u32, x: u32, y: u32) -> (f32, f32) {
    let nx = (x as f32 + 0.5) / width as f32 * 2.0 - 1.0;
    let ny = 1.0 - (y as f32 + 0.5) / height as f32 * 2.0;
    (nx, ny)
}

/// The primary ray of pixel `(x, y)`: from the eye through the pixel centre's point on
/// the far plane (NDC depth 1, unprojected with the eye-relative `inv_view_proj`, which
/// gives the direction directly), so `t = 1` is the far plane and `t_min = near / far` is
/// the near plane: the ray sees exactly the depth range the raster pass keeps. `kind` is [`RAY_KIND_PRIMARY`](crate::formats::RAY_KIND_PRIMARY), `pixel` is `y * width + x`.
#[inline]
pub fn primary_ray(camera: &CameraRecord, x: u32, y: u32) -> RayRecord {
    let (nx, ny) = pixel_centre_ndc(camera.width, camera.height, x, y);
    let inv = Mat4::from_cols_array(&camera.inv_view_proj);
    let far = inv * Vec4::new(nx, ny, 1.0, 1.0);
    let direction: Vec3 = far.truncate() / far.w;
    RayRecord {
        pixel: y * camera.width + x,
        ..RayRecord::query(camera.eye, direction.into(), camera.near / camera.far, 1.0)
    }
}

/// Every pixel's primary ray, in pixel order.
pub fn primary_rays(camera: &CameraRecord) -> Vec<RayRecord> {
    let (w, h) = (camera.width, camera.height);
    (0..h).flat_map(|y| (0..w).map(move |x| primary_ray(camera, x, y))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Camera;

    #[test]
    fn primary_ray_through_the_image_centre_looks_at_the_target() {
        let cam = Camera {
            eye: Vec3::new(0.0, 1.0, 5.0),
            target: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 60.0,
            near: 0.1,
            far: 50.0,
        };
        // An odd size has a pixel centre exactly on the optical axis.
        let rec = CameraRecord::new(&cam, 101, 51);
        let r = primary_ray(&rec, 50, 25);
        r.validate().unwrap();
        let d = Vec3::from(r.direction);
        assert!(d.normalize().abs_diff_eq(Vec3::NEG_Z, 1e-6), "{d}");
        // t = 1 lands on the far plane (eye at z = 5, looking down -z). Tolerance: the f32
        // inverse of the projection loses about log2(far / near) bits near depth 1.
        const UNPROJECT_REL_TOL: f32 = 1e-4;
        assert!((d.length() - rec.far).abs() <= rec.far * UNPROJECT_REL_TOL, "{} vs far {}", d.length(), rec.far);
        assert_eq!(r.pixel, 25 * 101 + 50);
    }

    #[test]
    fn primary_rays_project_back_to_their_pixel_centres() {
        let cam = Camera {
            eye: Vec3::new(3.0, 2.0, 4.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 50.0,
            near: 0.1,
            far: 100.0,
        };
        let rec = CameraRecord::new(&cam, 7, 5);
        let vp = Mat4::from_cols_array(&rec.view_proj);
        for r in primary_rays(&rec) {
            // Eye-relative: the point half way along the ray, minus the eye.
            let c = vp * (Vec3::from(r.direction) * 0.5).extend(1.0);
            let (x, y) = ((c.x / c.w * 0.5 + 0.5) * 7.0, (0.5 - c.y / c.w * 0.5) * 5.0);
            let (px, py) = ((r.pixel % 7) as f32 + 0.5, (r.pixel / 7) as f32 + 0.5);
            assert!((x - px).abs() < 1e-4 && (y - py).abs() < 1e-4, "pixel {}: projects to ({x}, {y})", r.pixel);
        }
    }
}
