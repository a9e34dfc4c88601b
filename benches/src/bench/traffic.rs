//! The bytes a CPU frame moves through its whole-image buffers, per pixel, for each
//! executor ([`Executor`]), and a copy loop's rate to set them against.
//!
//! The model counts every whole-image buffer of the paper's frame (max depth 0, no stage
//! outputs) once for each pass that writes it and once for each pass that reads it, as if
//! nothing stayed in cache between passes. With `P` pixels, `L` lights (0 where the plan
//! traces no shadow ray), `R` shadow rays and `S` shading stages (`rt_shading`,
//! `raster_shading`: 1 or 2):
//!
//! | staged buffer | written | read |
//! |---|---:|---:|
//! | G-buffer (`visibility_raster`) | 24 P | 24 P (`reconstruction`) |
//! | surfaces (`reconstruction`) | 48 P | 48 P L (`compaction`, light by light) + 48 R (`shadow_rays` makes each ray from its pixel's surface) + 48 P S (shading) |
//! | compaction's flags (`u32` per pixel and light) | 4 P L | 8 P L (counted, then scattered) |
//! | active pairs (`u32` per ray) | 4 R | 8 R (`shadow_rays`, then the shadow mask) |
//! | occluded (`u32` per ray) | 4 R | 4 R (the shadow mask) |
//! | shadow mask (a byte per pixel and light) | P L | P L S (shading) |
//! | raster and ray-traced images (16 B each, as planned) | 16 P each | 16 P each (`composition`) |
//! | final image | 16 P | - |
//!
//! The fused executor ([`Executor::Fused`]) writes the final image alone: 16 bytes a pixel
//! whatever the lights. Its raster tiles' texels and its tiles' surfaces, rays and masks are
//! tile-local scratch that stays in cache (a frame that asks for its G-buffer,
//! `FrameOptions::keep_gbuffer`, would write 24 more; the paper's frame does not). Neither
//! counts `visibility_raster`'s own scratch (per tile), the scene's tables, the BVH, or the
//! cache lines a write first reads.

use std::time::Instant;

use hyrt_core::formats::RAY_KIND_SHADOW;
use hyrt_core::frame::{Executor, FrameStats};
use hyrt_core::plan::{FramePlan, Step};

use super::stats::median;

/// Bytes of a G-buffer texel, a surface record, an RGBA f32 image pixel.
const GBUFFER: u64 = 24;
const SURFACE: u64 = 48;
const IMAGE: u64 = 16;
/// Bytes of a compaction flag, an active pair, an occlusion result (`u32` each).
const WORD: u64 = 4;

/// What of a frame decides its buffers' sizes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameShape {
    pub pixels: u64,
    /// Lights the frame traces shadow rays to (0 without `compaction` and `shadow_rays`).
    pub lights: u64,
    /// Shadow rays traced.
    pub shadow_rays: u64,
    /// `rt_shading` ran (the ray-traced image exists).
    pub rt_shading: bool,
    /// `raster_shading` ran (the raster image exists).
    pub raster_shading: bool,
}

impl FrameShape {
    /// The shape of a frame of `plan` from its statistics (the paper's frame: bounce
    /// buffers are not counted).
    pub fn of(plan: &FramePlan, stats: &FrameStats) -> FrameShape {
        let has = |f: fn(&Step) -> bool| plan.steps().iter().any(f);
        let shadow = has(|s| matches!(s, Step::ShadowRays));
        FrameShape {
            pixels: stats.width as u64 * stats.height as u64,
            lights: if shadow { plan.lights() as u64 } else { 0 },
            shadow_rays: stats.rays_per_kind[RAY_KIND_SHADOW as usize],
            rt_shading: has(|s| matches!(s, Step::RtShading { .. })),
            raster_shading: has(|s| matches!(s, Step::RasterShading { .. })),
        }
    }
}

/// Bytes a frame writes and reads in its whole-image buffers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Traffic {
    pub written: u64,
    pub read: u64,
}

impl Traffic {
    pub fn total(&self) -> u64 {
        self.written + self.read
    }

    /// Bytes per pixel of a frame of `pixels` pixels.
    pub fn per_pixel(&self, pixels: u64) -> f64 {
        self.total() as f64 / pixels.max(1) as f64
    }

    /// The rate moving these bytes in `ms` milliseconds: GB/s (10^9 bytes a second).
    pub fn gb_per_s(&self, ms: f64) -> f64 {
        self.total() as f64 / (ms * 1e6)
    }
}

/// The bytes a frame of `shape` moves when `executor` runs it (the module docs' model).
pub fn frame_traffic(shape: &FrameShape, executor: Executor) -> Traffic {
    let FrameShape { pixels: p, lights: l, shadow_rays: r, .. } = *shape;
    if executor == Executor::Fused {
        return Traffic { written: IMAGE * p, read: 0 };
    }
    let shading = shape.rt_shading as u64 + shape.raster_shading as u64;
    let images = shading * IMAGE * p;
    let written = GBUFFER * p + SURFACE * p + WORD * p * l + 2 * WORD * r + p * l + images + IMAGE * p;
    let read =
        GBUFFER * p + SURFACE * (p * l + r + p * shading) + 2 * WORD * p * l + 3 * WORD * r + p * l * shading + images;
    Traffic { written, read }
}

/// Bytes the copy loop copies.
pub const COPY_BYTES: usize = 256 << 20;

/// GB/s of one thread copying `bytes` bytes with `copy_from_slice`, counting the bytes
/// read and the bytes written (as [`frame_traffic`] does): the median of `runs` copies,
/// after one that touches every page.
pub fn copy_gb_per_s(bytes: usize, runs: usize) -> f64 {
    let src = vec![1u8; bytes];
    let mut dst = vec![0u8; bytes];
    dst.copy_from_slice(&src);
    let ms: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            let t = Instant::now();
            dst.copy_from_slice(std::hint::black_box(&src));
            std::hint::black_box(&mut dst);
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    Traffic { written: bytes as u64, read: bytes as u64 }.gb_per_s(median(&ms).unwrap_or(f64::NAN))
}

#[cfg(test)]
mod tests {
    use super::*;
    use hyrt_core::frame::StageTime;
    use hyrt_core::stage::Stage;

    fn shape(lights: u64, shadow_rays: u64, rt: bool, raster: bool) -> FrameShape {
        FrameShape { pixels: 100, lights, shadow_rays, rt_shading: rt, raster_shading: raster }
    }

    #[test]
    fn the_staged_frame_counts_every_buffer_once_per_pass() {
        // 100 pixels, 2 lights, 150 shadow rays, both shading stages.
        let t = frame_traffic(&shape(2, 150, true, true), Executor::Staged);
        // G-buffer 24, surfaces 48, flags 8, mask 2, raster + rt 32, final 16 per pixel;
        // pairs and occluded 8 per ray.
        assert_eq!(t.written, 100 * (24 + 48 + 8 + 2 + 32 + 16) + 150 * 8);
        // G-buffer 24, surfaces 48 x (2 lights + 2 shadings), flags 16, mask 2 x 2,
        // images 32 per pixel; surfaces 48, pairs 8, occluded 4 per ray.
        assert_eq!(t.read, 100 * (24 + 48 * 4 + 16 + 4 + 32) + 150 * (48 + 12));
        assert_eq!(t.per_pixel(100), (t.written + t.read) as f64 / 100.0);
    }

    #[test]
    fn without_lights_or_a_second_image_the_staged_frame_moves_less() {
        // No light: G-buffer and surfaces, one shading stage and its image, the final image.
        let t = frame_traffic(&shape(0, 0, false, true), Executor::Staged);
        assert_eq!(t, Traffic { written: 100 * (24 + 48 + 16 + 16), read: 100 * (24 + 48 + 16) });
    }

    #[test]
    fn the_fused_frame_moves_the_final_image_alone_whatever_the_lights() {
        for s in [shape(0, 0, false, true), shape(4, 300, true, true)] {
            let t = frame_traffic(&s, Executor::Fused);
            assert_eq!(t, Traffic { written: 100 * 16, read: 0 });
            assert_eq!(t.per_pixel(s.pixels), 16.0);
        }
        // 1 GB in 1 s.
        assert_eq!(Traffic { written: 5e8 as u64, read: 5e8 as u64 }.gb_per_s(1e3), 1.0);
    }

    /// The shape of a real frame: the default scene's plan and its counts.
    #[test]
    fn the_shape_of_the_default_scenes_frame_comes_from_its_plan_and_stats() {
        let s = crate::bench::scenes::default_scene();
        let prepared = crate::bench::prepare(&s.scene, Some(1));
        let plan = FramePlan::new(&prepared, &crate::bench::paper_frame()).expect("plan");
        let mut stats = FrameStats {
            width: 20,
            height: 10,
            stage_ms: vec![StageTime { stage: Stage::VisibilityRaster, depth: 0, ms: 1.0, work: Default::default() }],
            ..Default::default()
        };
        stats.rays_per_kind[RAY_KIND_SHADOW as usize] = 77;
        let shape = FrameShape::of(&plan, &stats);
        assert_eq!(shape.pixels, 200);
        assert_eq!(shape.shadow_rays, 77);
        assert_eq!(shape.lights, plan.lights() as u64);
        assert!(shape.lights > 0, "the default scene has lights");
        assert_eq!(shape.rt_shading, plan.steps().iter().any(|s| matches!(s, Step::RtShading { .. })));
    }

    #[test]
    fn the_copy_loop_gives_a_rate() {
        let r = copy_gb_per_s(1 << 20, 3);
        assert!(r.is_finite() && r > 0.0, "{r}");
    }
}
