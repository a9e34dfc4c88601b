//! [`GpuBackend`]: the stages in one command buffer, all frame data on the GPU
//! from raster to final image, one readback at the end.

use std::time::Instant;

use hyrt_core::formats::{CameraRecord, GBufferTexel, RayRecord, SurfaceRecord, RAY_KIND_COUNT};
use hyrt_core::frame::{Backend, Frame, FrameOptions, FrameStats, PreparedScene, RenderError, StageTime};
use hyrt_core::stage::Stage;

use crate::buffers::{FrameBuffers, FrameParams, SceneBuffers};
use crate::compaction::CompactionStage;
use crate::composition::CompositionStage;
use crate::gpu_buffer::read_back_many;
use crate::raster_shading::RasterShadingStage;
use crate::reconstruction::ReconstructionStage;
use crate::rt_shading::RtShadingStage;
use crate::shadow_rays::ShadowRaysStage;
use crate::timing::StageTimer;
use crate::visibility_raster::{VisibilityMode, VisibilityRasterStage};
use crate::{AdapterPolicy, GpuContext, GpuError};

/// The per-frame stages, in execution order (`bvh_build` runs on the CPU, once per scene).
const FRAME_STAGES: [Stage; 7] = [
    Stage::VisibilityRaster,
    Stage::Reconstruction,
    Stage::Compaction,
    Stage::ShadowRays,
    Stage::RtShading,
    Stage::RasterShading,
    Stage::Composition,
];

/// The GPU backend. Pipelines are created once; scene buffers once per
/// [`PreparedScene`]; frame buffers once per image size and light count.
pub struct GpuBackend {
    ctx: GpuContext,
    visibility_raster: VisibilityRasterStage,
    reconstruction: ReconstructionStage,
    compaction: CompactionStage,
    shadow_rays: ShadowRaysStage,
    rt_shading: RtShadingStage,
    raster_shading: RasterShadingStage,
    composition: CompositionStage,
    timer: StageTimer,
    scene: Option<(u64, SceneBuffers)>,
    frame: Option<FrameBuffers>,
}

impl GpuBackend {
    /// Open a device under `policy` and build every pipeline.
    pub fn new(policy: AdapterPolicy) -> Result<GpuBackend, GpuError> {
        let ctx = GpuContext::new(policy)?;
        Self::with_context(ctx)
    }

    /// Build every pipeline on an existing context.
    pub fn with_context(ctx: GpuContext) -> Result<GpuBackend, GpuError> {
        let (visibility_raster, reconstruction, compaction, shadow_rays, rt_shading, raster_shading, composition) = ctx
            .checked(|| {
                (
                    VisibilityRasterStage::new(&ctx),
                    ReconstructionStage::new(&ctx),
                    CompactionStage::new(&ctx),
                    ShadowRaysStage::new(&ctx),
                    RtShadingStage::new(&ctx),
                    RasterShadingStage::new(&ctx),
                    CompositionStage::new(&ctx),
                )
            })?;
        let timer = StageTimer::new(&ctx, FRAME_STAGES.len() as u32)?;
        Ok(GpuBackend {
            ctx,
            visibility_raster,
            reconstruction,
            compaction,
            shadow_rays,
            rt_shading,
            raster_shading,
            composition,
            timer,
            scene: None,
            frame: None,
        })
    }

    /// The adapter, the triangle-id source and the timing method, in one line.
    pub fn describe(&self) -> String {
        let timing = if self.timer.is_active() && !crate::context::is_software(&self.ctx.info) {
            "GPU timestamp queries"
        } else {
            "wall clock per stage (submit and wait)"
        };
        format!(
            "{}; raster ids from {}; stage times from {timing}",
            self.ctx.describe(),
            self.visibility_raster.triangle_id_source()
        )
    }

    /// Switch how `visibility_raster` computes the G-buffer (the pipelines are rebuilt
    /// on a change). [`VisibilityMode::Exact`], the default, is bit-identical to the CPU
    /// reference; [`VisibilityMode::HardwareInterpolated`] is not, and exists for
    /// benchmarks that measure the device as a plain rasterizer.
    pub fn set_visibility_mode(&mut self, mode: VisibilityMode) -> Result<(), GpuError> {
        if self.visibility_raster.mode() != mode {
            let stage = self.ctx.checked(|| VisibilityRasterStage::with_mode(&self.ctx, mode))?;
            self.visibility_raster = stage;
        }
        Ok(())
    }

    /// The device context.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    fn render_frame(
        &mut self,
        scene: &PreparedScene,
        camera: &CameraRecord,
        options: &FrameOptions,
        out: &mut Frame,
    ) -> Result<(), GpuError> {
        let ctx = &self.ctx;
        VisibilityRasterStage::check_size(ctx, camera.width, camera.height)?;
        if self.scene.as_ref().map(|(id, _)| *id) != Some(scene.id()) {
            self.scene = Some((scene.id(), ctx.checked(|| SceneBuffers::new(ctx, scene))?));
        }
        let lights = scene.geometry.lights.len() as u32;
        if !self.frame.as_ref().is_some_and(|f| f.fits(camera.width, camera.height, lights)) {
            self.frame = None; // free the old buffers before allocating new ones
            self.frame = Some(ctx.checked(|| FrameBuffers::new(ctx, camera.width, camera.height, lights))??);
        }
        let (sb, fb) = (&self.scene.as_ref().expect("scene buffers").1, self.frame.as_ref().expect("frame buffers"));
        let params = FrameParams::new(camera.width, camera.height, lights, options.weight);
        debug_assert_eq!(params.validate(), Ok(()));
        fb.write_uniforms(ctx, camera, &params);

        // With timestamp queries the frame is one command buffer and the GPU times each
        // stage. Without them each stage is submitted alone and waited for, so the wall
        // clock can time it (slower: it serializes CPU and GPU).
        // Lavapipe's timestamps do not measure its passes (it reported 0.07 ms for
        // reconstructing 921,600 pixels on a CPU): on software adapters each stage is
        // timed by the wall clock instead.
        let timed_by_gpu = self.timer.is_active() && !crate::context::is_software(&ctx.info);
        let mut wall_ms = Vec::with_capacity(FRAME_STAGES.len());
        ctx.checked(|| -> Result<(), GpuError> {
            let t = &self.timer;
            let mut enc =
                ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("hyrt frame") });
            for (i, stage) in FRAME_STAGES.iter().enumerate() {
                let start = Instant::now();
                let slot = t.stage(i as u32);
                match stage {
                    Stage::VisibilityRaster => self.visibility_raster.encode(ctx, &mut enc, sb, fb, slot),
                    Stage::Reconstruction => self.reconstruction.encode(ctx, &mut enc, sb, fb, slot),
                    Stage::Compaction => self.compaction.encode(ctx, &mut enc, sb, fb, slot),
                    Stage::ShadowRays => self.shadow_rays.encode(ctx, &mut enc, sb, fb, slot),
                    Stage::RtShading => self.rt_shading.encode(ctx, &mut enc, sb, fb, slot),
                    Stage::RasterShading => self.raster_shading.encode(ctx, &mut enc, sb, fb, slot),
                    Stage::Composition => self.composition.encode(ctx, &mut enc, sb, fb, slot),
                    Stage::BvhBuild => unreachable!("bvh_build is not a GPU frame stage"),
                }
                if !timed_by_gpu {
                    let done = std::mem::replace(
                        &mut enc,
                        ctx.device
                            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("hyrt stage") }),
                    );
                    ctx.queue.submit([done.finish()]);
                    ctx.device
                        .poll(wgpu::PollType::Wait { submission_index: None, timeout: None })
                        .map_err(|e| GpuError::DeviceLost(e.to_string()))?;
                    wall_ms.push(start.elapsed().as_secs_f64() * 1e3);
                }
            }
            t.resolve(&mut enc);
            ctx.queue.submit([enc.finish()]);
            Ok(())
        })??;
        // One readback at the end: the ray count, the occlusion results, the G-buffer
        // (for the pixel counts) and the final image, in one staging buffer. The other
        // stage outputs only when asked (`--dump`, conformance).
        let pixels = camera.width as usize * camera.height as usize;
        let pairs = pixels * lights as usize;
        let bytes = |n: usize, size: usize| (n * size) as u64;
        let mut parts = read_back_many(
            ctx,
            &[
                (&fb.ray_count, 4),
                (&fb.occluded, bytes(pairs, 4)),
                (&fb.gbuffer, bytes(pixels, std::mem::size_of::<GBufferTexel>())),
                (&fb.final_image, bytes(pixels, 16)),
            ],
        )?
        .into_iter();
        let mut next = || parts.next().expect("one part per request");
        let count = (bytemuck::pod_read_unaligned::<u32>(&next()) as usize).min(pairs);
        let mut occluded: Vec<u32> = bytemuck::pod_collect_to_vec(&next());
        occluded.truncate(count);
        out.occluded = occluded;
        out.gbuffer = bytemuck::pod_collect_to_vec(&next());
        out.final_image = bytemuck::pod_collect_to_vec(&next());
        if options.stage_outputs {
            let mut parts = read_back_many(
                ctx,
                &[
                    (&fb.surfaces, bytes(pixels, std::mem::size_of::<SurfaceRecord>())),
                    (&fb.rays, bytes(count, std::mem::size_of::<RayRecord>())),
                    (&fb.shadow, bytes(pairs, 4)),
                    (&fb.rt, bytes(pixels, 16)),
                    (&fb.raster, bytes(pixels, 16)),
                ],
            )?
            .into_iter();
            let mut next = || parts.next().expect("one part per request");
            out.surfaces = bytemuck::pod_collect_to_vec(&next());
            out.rays = bytemuck::pod_collect_to_vec(&next());
            out.shadow = bytemuck::pod_collect_to_vec::<u8, u32>(&next()).into_iter().map(|s| s as u8).collect();
            out.rt = bytemuck::pod_collect_to_vec(&next());
            out.raster = bytemuck::pod_collect_to_vec(&next());
        } else {
            for v in [&mut out.rt, &mut out.raster] {
                v.clear();
            }
            out.surfaces.clear();
            out.rays.clear();
            out.shadow.clear();
        }
        let mut stage_ms = vec![StageTime { stage: Stage::BvhBuild, ms: scene.bvh_build_ms }];
        let ms = if timed_by_gpu { self.timer.read_ms(ctx)?.unwrap_or_default() } else { wall_ms };
        stage_ms.extend(FRAME_STAGES.iter().zip(ms).map(|(&stage, ms)| StageTime { stage, ms }));
        let mut stats =
            FrameStats { width: camera.width, height: camera.height, threads: 0, stage_ms, ..Default::default() };
        for t in &out.gbuffer {
            if t.is_hit() {
                stats.covered_pixels += 1;
                stats.ray_traced_pixels += t.is_ray_traced() as u64;
            }
        }
        stats.raster_pixels = stats.covered_pixels - stats.ray_traced_pixels;
        // The GPU ray list holds shadow rays only (compaction makes no other kind yet).
        let mut per_kind = [0u64; RAY_KIND_COUNT];
        per_kind[hyrt_core::formats::RAY_KIND_SHADOW as usize] = count as u64;
        stats.rays_per_kind = per_kind;
        stats.occluded_shadow_rays = out.occluded.iter().filter(|&&o| o != 0).count() as u64;
        out.width = camera.width;
        out.height = camera.height;
        out.stats = stats;
        Ok(())
    }
}

impl Backend for GpuBackend {
    fn name(&self) -> &str {
        "gpu"
    }

    fn render_into(
        &mut self,
        scene: &PreparedScene,
        camera: &CameraRecord,
        options: &FrameOptions,
        frame: &mut Frame,
    ) -> Result<(), RenderError> {
        if !(0.0..=1.0).contains(&options.weight) {
            return Err(RenderError::InvalidOptions(format!(
                "composition weight must be in [0, 1], got {}",
                options.weight
            )));
        }
        camera.validate().map_err(RenderError::InvalidCamera)?;
        self.render_frame(scene, camera, options, frame).map_err(|e| RenderError::Backend(Box::new(e)))
    }
}
