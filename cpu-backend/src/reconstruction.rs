//! Stage `reconstruction`: G-buffer + triangle table -> world-space hit points
//! and normals (paper eq. 1), one [`SurfaceRecord`] per pixel.
//!
//! Inputs: the G-buffer, the world geometry, the camera eye. Output: the surface
//! buffer. Pure per-pixel map of [`hyrt_core::kernels::reconstruction::reconstruct_texel`].

use glam::Vec3;
use hyrt_core::formats::{CameraRecord, GBufferTexel, SurfaceRecord};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::camera::primary_ray;
use hyrt_core::kernels::reconstruction::{reconstruct_texel, reconstruct_texel_reintersected};
use rayon::prelude::*;

/// The stage: reconstruct every pixel in parallel.
pub fn reconstruction(gbuffer: &[GBufferTexel], geometry: &WorldGeometry, eye: Vec3) -> Vec<SurfaceRecord> {
    let mut out = Vec::new();
    reconstruction_into(gbuffer, geometry, eye, &mut out);
    out
}

/// [`reconstruction`] into a caller-owned buffer, reusing its allocation.
pub fn reconstruction_into(
    gbuffer: &[GBufferTexel],
    geometry: &WorldGeometry,
    eye: Vec3,
    out: &mut Vec<SurfaceRecord>,
) {
    gbuffer.par_iter().with_min_len(1024).map(|t| reconstruct_texel(t, geometry, eye)).collect_into_vec(out);
    validate(out);
}

/// [`reconstruction_into`] with re-intersected barycentrics
/// ([`hyrt_core::frame::PrimaryBarycentrics::Reintersected`]): every hit texel's camera
/// ray ([`primary_ray`]) meets its triangle by the watertight kernel.
pub fn reconstruction_reintersected_into(
    gbuffer: &[GBufferTexel],
    geometry: &WorldGeometry,
    camera: &CameraRecord,
    out: &mut Vec<SurfaceRecord>,
) {
    let w = camera.width as usize;
    gbuffer
        .par_iter()
        .enumerate()
        .with_min_len(1024)
        .map(|(i, t)| {
            if !t.is_hit() {
                return SurfaceRecord::MISS;
            }
            let ray = primary_ray(camera, (i % w) as u32, (i / w) as u32);
            reconstruct_texel_reintersected(t, geometry, &ray)
        })
        .collect_into_vec(out);
    validate(out);
}

/// Debug builds: every record valid.
fn validate(out: &[SurfaceRecord]) {
    if cfg!(debug_assertions) {
        for (i, s) in out.iter().enumerate() {
            if let Err(e) = s.validate() {
                panic!("reconstruction: pixel {i}: {e}");
            }
        }
    }
}
