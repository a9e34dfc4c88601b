//! Stage `reconstruction`: G-buffer + triangle table -> world-space hit points
//! and normals (paper eq. 1), one [`SurfaceRecord`] per pixel.
//!
//! Inputs: the G-buffer, the world geometry, the camera eye. Output: the surface
//! buffer. Pure per-pixel map of [`hyrt_core::kernels::reconstruction::reconstruct_texel`]
//! (its cached form: a run of pixels on one triangle sets the triangle up once).

use glam::Vec3;
use hyrt_core::formats::{CameraRecord, GBufferTexel, SurfaceRecord};
use hyrt_core::frame::PrimaryBarycentrics;
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::camera::primary_ray;
use hyrt_core::kernels::reconstruction::{
    reconstruct_texel_cached, reconstruct_texel_reintersected_cached, TriangleSetup,
};
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
    gbuffer
        .par_iter()
        .with_min_len(1024)
        .map_init(|| None, |cache, t| reconstruct_texel_cached(t, geometry, eye, cache))
        .collect_into_vec(out);
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
    let pixel = Reconstruct::Reintersected(camera);
    gbuffer
        .par_iter()
        .enumerate()
        .with_min_len(1024)
        .map_init(|| None, |cache, (i, t)| pixel.pixel(t, geometry, (i % w) as u32, (i / w) as u32, cache))
        .collect_into_vec(out);
    validate(out);
}

/// The stage's per-pixel kernel as every executor runs it: the staged functions above
/// over the whole image, the fused frame (`crate::fused`) over a tile's pixels.
#[derive(Clone, Copy, Debug)]
pub enum Reconstruct<'a> {
    /// The raster's barycentrics, seen from the eye ([`reconstruct_texel_cached`]).
    Raster(Vec3),
    /// Re-intersected barycentrics: the pixel's camera ray ([`primary_ray`]) against the
    /// texel's triangle ([`reconstruct_texel_reintersected_cached`]).
    Reintersected(&'a CameraRecord),
}

impl<'a> Reconstruct<'a> {
    /// The kernel `barycentrics` asks for, for a frame seen by `camera`.
    pub fn new(barycentrics: PrimaryBarycentrics, camera: &'a CameraRecord) -> Self {
        match barycentrics {
            PrimaryBarycentrics::Raster => Reconstruct::Raster(Vec3::from(camera.eye)),
            PrimaryBarycentrics::Reintersected => Reconstruct::Reintersected(camera),
        }
    }

    /// The surface of pixel `(x, y)` whose G-buffer texel is `t`; `cache` keeps the last
    /// triangle's setup for the next pixel (`None` to start).
    #[inline]
    pub fn pixel(
        &self,
        t: &GBufferTexel,
        geometry: &WorldGeometry,
        x: u32,
        y: u32,
        cache: &mut Option<TriangleSetup>,
    ) -> SurfaceRecord {
        match *self {
            Reconstruct::Raster(eye) => reconstruct_texel_cached(t, geometry, eye, cache),
            Reconstruct::Reintersected(_) if !t.is_hit() => SurfaceRecord::MISS,
            Reconstruct::Reintersected(camera) => {
                reconstruct_texel_reintersected_cached(t, geometry, &primary_ray(camera, x, y), cache)
            }
        }
    }
}

/// Debug builds: every record valid.
pub(crate) fn validate(out: &[SurfaceRecord]) {
    if cfg!(debug_assertions) {
        for (i, s) in out.iter().enumerate() {
            if let Err(e) = s.validate() {
                panic!("reconstruction: pixel {i}: {e}");
            }
        }
    }
}
