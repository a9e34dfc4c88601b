//! [`CpuBackend`]: runs the stages in order on a rayon pool and times each.

use std::time::Instant;

use glam::Vec3;
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::{CameraRecord, RAY_KIND_COUNT};
use hyrt_core::frame::{Backend, Frame, FrameOptions, FrameStats, PreparedScene, RenderError, StageTime};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::stage::Stage;

use crate::{
    bvh_build::bvh_build, compaction, composition::composition, raster_shading::raster_shading,
    reconstruction::reconstruction, rt_shading::rt_shading, shadow_rays::shadow_rays,
    visibility_raster::visibility_raster,
};

/// The CPU backend. Owns a rayon pool so that thread counts are explicit and a
/// frame never depends on whatever global pool the caller configured.
pub struct CpuBackend {
    pool: rayon::ThreadPool,
}

impl CpuBackend {
    /// A backend with `threads` worker threads (`None`: one per core).
    pub fn new(threads: Option<usize>) -> Self {
        let mut b = rayon::ThreadPoolBuilder::new().thread_name(|i| format!("hyrt-cpu-{i}"));
        if let Some(n) = threads {
            b = b.num_threads(n.max(1));
        }
        CpuBackend { pool: b.build().expect("rayon thread pool") }
    }

    /// Number of worker threads.
    pub fn threads(&self) -> usize {
        self.pool.current_num_threads()
    }

    /// Build the world tables and run the `bvh_build` stage on this backend's pool.
    pub fn prepare(&self, geometry: WorldGeometry, preset: BvhPreset) -> PreparedScene {
        self.pool.install(|| {
            let t = Instant::now();
            let bvh = bvh_build(&geometry, preset);
            PreparedScene { geometry, bvh, bvh_build_ms: t.elapsed().as_secs_f64() * 1e3 }
        })
    }
}

impl Default for CpuBackend {
    fn default() -> Self {
        CpuBackend::new(None)
    }
}

/// Run `f`, record its time under `stage`.
fn timed<T>(times: &mut Vec<StageTime>, stage: Stage, f: impl FnOnce() -> T) -> T {
    let t = Instant::now();
    let r = f();
    times.push(StageTime { stage, ms: t.elapsed().as_secs_f64() * 1e3 });
    r
}

impl Backend for CpuBackend {
    fn name(&self) -> &str {
        "cpu"
    }

    fn render(
        &mut self,
        scene: &PreparedScene,
        camera: &CameraRecord,
        options: &FrameOptions,
    ) -> Result<Frame, RenderError> {
        if !(0.0..=1.0).contains(&options.weight) {
            return Err(RenderError::InvalidOptions(format!(
                "composition weight must be in [0, 1], got {}",
                options.weight
            )));
        }
        camera.validate().map_err(RenderError::InvalidCamera)?;
        let g = &scene.geometry;
        let eye = Vec3::from(camera.eye);
        let threads = self.threads();
        Ok(self.pool.install(|| {
            let mut t = vec![StageTime { stage: Stage::BvhBuild, ms: scene.bvh_build_ms }];
            let vis = timed(&mut t, Stage::VisibilityRaster, || visibility_raster(g, camera));
            let surfaces = timed(&mut t, Stage::Reconstruction, || reconstruction(&vis.gbuffer, g, eye));
            let rays = timed(&mut t, Stage::Compaction, || compaction::compaction(&surfaces, &g.lights));
            let (occluded, shadow) = timed(&mut t, Stage::ShadowRays, || {
                let occluded = shadow_rays(&scene.bvh, g, &rays);
                let mask = compaction::shadow_mask(&rays, &occluded, surfaces.len(), g.lights.len());
                (occluded, mask)
            });
            let rt = timed(&mut t, Stage::RtShading, || rt_shading(&surfaces, &shadow, &g.objects, &g.lights, eye));
            let raster = timed(&mut t, Stage::RasterShading, || {
                raster_shading(&surfaces, &shadow, &g.objects, &g.lights, options.weight)
            });
            let final_image = timed(&mut t, Stage::Composition, || composition(&raster, &rt, options.weight));

            let mut stats =
                FrameStats { width: vis.width, height: vis.height, threads, stage_ms: t, ..FrameStats::default() };
            for texel in &vis.gbuffer {
                if texel.is_hit() {
                    stats.covered_pixels += 1;
                    if texel.is_ray_traced() {
                        stats.ray_traced_pixels += 1;
                    } else {
                        stats.raster_pixels += 1;
                    }
                }
            }
            let mut per_kind = [0u64; RAY_KIND_COUNT];
            for r in &rays {
                per_kind[r.kind as usize] += 1;
            }
            stats.rays_per_kind = per_kind;
            stats.occluded_shadow_rays = occluded.iter().filter(|&&o| o != 0).count() as u64;
            Frame {
                width: vis.width,
                height: vis.height,
                gbuffer: vis.gbuffer,
                surfaces,
                rays,
                occluded,
                shadow,
                raster,
                rt,
                final_image,
                stats,
            }
        }))
    }
}
