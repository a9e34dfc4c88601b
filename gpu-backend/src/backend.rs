//! [`GpuBackend`]: the stages in one command buffer, all frame data on the GPU
//! from raster to final image, one readback at the end.

use std::time::Instant;

use hyrt_core::formats::{CameraRecord, GBufferTexel, RayRecord, SurfaceRecord};
use hyrt_core::frame::{Backend, Frame, FrameOptions, FrameStats, PreparedScene, RenderError, StageTime, StageWork};
use hyrt_core::plan::{FrameBuffer, FramePlan, Step};
use hyrt_core::stage::Stage;

use crate::buffers::{FrameBuffers, FrameParams, SceneBuffers};
use crate::compaction::CompactionStage;
use crate::composition::CompositionStage;
use crate::gpu_buffer::{copy_into_vec, read_back_each};
use crate::present::Present;
use crate::raster_shading::RasterShadingStage;
use crate::reconstruction::ReconstructionStage;
use crate::rt_shading::RtShadingStage;
use crate::shadow_rays::ShadowRaysStage;
use crate::timing::StageTimer;
use crate::visibility_raster::{VisibilityMode, VisibilityRasterStage};
use crate::{AdapterPolicy, GpuContext, GpuError};

/// The most steps a plan has: every stage but `bvh_build` (which runs on the CPU,
/// once per scene).
const MAX_STEPS: u32 = Stage::ALL.len() as u32 - 1;

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
    /// Milliseconds per step of the last run plan.
    stage_ms: Vec<f64>,
    present: Present,
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
        let timer = StageTimer::new(&ctx, MAX_STEPS)?;
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
            stage_ms: Vec::new(),
            present: Present::default(),
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
        plan: &FramePlan,
        camera: &CameraRecord,
        options: &FrameOptions,
        out: &mut Frame,
    ) -> Result<(), GpuError> {
        // The ray count comes back with the frame's one readback: no extra round trip.
        self.run_with_room(scene, plan, camera, options, |b: &Self| b.read_back(plan, camera, out)).map(drop)
    }

    /// Run the plan over frame buffers with room for its rays, and `finish` (the
    /// frame's readback, which returns the ray count `compaction` found) after each
    /// run; the ray count.
    fn run_with_room(
        &mut self,
        scene: &PreparedScene,
        plan: &FramePlan,
        camera: &CameraRecord,
        options: &FrameOptions,
        mut finish: impl FnMut(&Self) -> Result<usize, GpuError>,
    ) -> Result<usize, GpuError> {
        {
            let ctx = &self.ctx;
            VisibilityRasterStage::check_size(ctx, camera.width, camera.height)?;
            if self.scene.as_ref().map(|(id, _)| *id) != Some(scene.id()) {
                self.scene = Some((scene.id(), ctx.checked(|| SceneBuffers::new(ctx, scene))?));
            }
        }
        let lights = scene.geometry.lights.len() as u32;
        let pixels = camera.width as usize * camera.height as usize;
        let pairs = pixels * lights as usize;
        // Ray buffers hold the rays a frame has, known only after `compaction`. A
        // frame starts with the last frame's room (one ray per pixel at first); if
        // `compaction` finds more, its rays past the room are not written, and the
        // frame runs again with room for them plus a quarter (never past one per pair,
        // which always fits). The frame that is returned traced every ray.
        let mut want = self.frame.as_ref().map_or(0, |f| f.ray_capacity).max(pixels.min(pairs) as u32);
        loop {
            if !self.frame.as_ref().is_some_and(|f| f.fits(camera.width, camera.height, lights, plan, want)) {
                self.frame = None; // free the old buffers before allocating new ones
                let (ctx, w, h) = (&self.ctx, camera.width, camera.height);
                self.frame = Some(ctx.checked(|| FrameBuffers::for_plan(ctx, w, h, lights, plan, want))??);
            }
            self.run_plan(plan, camera, options)?;
            let count = finish(self)?;
            let room = self.frame.as_ref().expect("frame buffers").ray_capacity as usize;
            if count <= room {
                return Ok(count);
            }
            want = (count + count / 4).min(pairs) as u32;
        }
    }

    /// Render a frame and leave its final image on the GPU, in `target` (see
    /// [`crate::present`] for the texture it must be): nothing but the 4-byte ray
    /// count is read back, so a display loop pays no transfer. The statistics have
    /// the stage times, the plan's skipped stages and the rays per kind; the pixel
    /// counts need the G-buffer on the CPU and are 0 here (use
    /// [`Backend::render_into`] for them).
    pub fn render_to_texture(
        &mut self,
        scene: &PreparedScene,
        camera: &CameraRecord,
        options: &FrameOptions,
        target: &wgpu::Texture,
    ) -> Result<FrameStats, RenderError> {
        let plan = FramePlan::new(scene, options)?;
        check_supported(&plan)?;
        camera.validate().map_err(RenderError::InvalidCamera)?;
        crate::present::check_target(target, camera.width, camera.height).map_err(RenderError::InvalidOptions)?;
        let count = self.run_with_room(scene, &plan, camera, options, |b: &Self| b.read_ray_count(&plan))?;
        let ctx = &self.ctx;
        let fb = self.frame.as_ref().expect("frame buffers");
        ctx.checked(|| {
            let mut enc = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("present") });
            self.present.encode(ctx, &mut enc, fb, target);
            ctx.queue.submit([enc.finish()]);
        })?;
        let mut stats = FrameStats {
            width: camera.width,
            height: camera.height,
            skipped: plan.skipped().to_vec(),
            ..Default::default()
        };
        stats.rays_per_kind[hyrt_core::formats::RAY_KIND_SHADOW as usize] = count as u64;
        stats.stage_ms = self.stage_times(&plan, &stats);
        Ok(stats)
    }

    /// The last run plan's step times, each with its work.
    fn stage_times(&self, plan: &FramePlan, stats: &FrameStats) -> Vec<StageTime> {
        let ms = self.stage_ms.iter().copied().chain(std::iter::repeat(0.0));
        plan.steps()
            .iter()
            .zip(ms)
            .map(|(&step, ms)| StageTime {
                stage: step.stage(),
                depth: step.depth(),
                ms,
                work: StageWork::of(step, stats),
            })
            .collect()
    }

    /// Encode and submit the plan's steps over the current frame buffers. Stage times
    /// are kept for the statistics.
    fn run_plan(&mut self, plan: &FramePlan, camera: &CameraRecord, options: &FrameOptions) -> Result<(), GpuError> {
        let ctx = &self.ctx;
        let (sb, fb) = (&self.scene.as_ref().expect("scene buffers").1, self.frame.as_ref().expect("frame buffers"));
        let params = FrameParams::new(camera.width, camera.height, fb.light_count, options.weight)
            .with_composition(plan.composition());
        debug_assert_eq!(params.validate(), Ok(()));
        fb.write_uniforms(ctx, camera, &params);

        // With timestamp queries the frame is one command buffer and the GPU times each
        // stage. Without them each stage is submitted alone and waited for, so the wall
        // clock can time it (slower: it serializes CPU and GPU).
        // Lavapipe's timestamps do not measure its passes (it reported 0.07 ms for
        // reconstructing 921,600 pixels on a CPU): on software adapters each stage is
        // timed by the wall clock instead.
        let timed_by_gpu = self.timer.is_active() && !crate::context::is_software(&ctx.info);
        let mut wall_ms = Vec::with_capacity(plan.steps().len());
        ctx.checked(|| -> Result<(), GpuError> {
            let t = &self.timer;
            let mut enc =
                ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("hyrt frame") });
            // The plan's one loop: each step encodes its stage module and is timed.
            for (i, &step) in plan.steps().iter().enumerate() {
                let start = Instant::now();
                let slot = t.stage(i as u32);
                match step {
                    Step::VisibilityRaster => self.visibility_raster.encode(ctx, &mut enc, sb, fb, slot),
                    Step::Reconstruction => self.reconstruction.encode(ctx, &mut enc, sb, fb, slot),
                    Step::Compaction => self.compaction.encode(ctx, &mut enc, sb, fb, slot),
                    Step::ShadowRays => self.shadow_rays.encode(ctx, &mut enc, sb, fb, slot),
                    Step::RtShading { bounces: false } => self.rt_shading.encode(ctx, &mut enc, sb, fb, slot),
                    Step::SecondaryRays { .. }
                    | Step::BounceTrace { .. }
                    | Step::BounceCompaction { .. }
                    | Step::BounceShadowRays { .. }
                    | Step::BounceShading { .. }
                    | Step::RtShading { bounces: true } => {
                        unreachable!("plans with bounces are refused by `check_supported` before they run")
                    }
                    // `shade_ray_traced` is the shader's `weight < 1`.
                    Step::RasterShading { .. } => self.raster_shading.encode(ctx, &mut enc, sb, fb, slot),
                    // The mode is the `composition` code in the frame parameters.
                    Step::Composition(_) => self.composition.encode(ctx, &mut enc, sb, fb, slot),
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
        self.stage_ms = if timed_by_gpu { self.timer.read_ms(ctx)?.unwrap_or_default() } else { wall_ms };
        Ok(())
    }

    /// The ray count `compaction` found in the last run (0 without it), read back alone.
    fn read_ray_count(&self, plan: &FramePlan) -> Result<usize, GpuError> {
        if !plan.produces(FrameBuffer::Rays) {
            return Ok(0);
        }
        let fb = self.frame.as_ref().expect("frame buffers");
        let mut count = 0;
        read_back_each(&self.ctx, &[(&fb.ray_count, 4)], |_, b| {
            count = bytemuck::pod_read_unaligned::<u32>(b) as usize
        })?;
        Ok(count)
    }

    /// Read the buffers the frame holds back into `out` (reusing its vectors) and
    /// fill in its statistics; the ray count. One readback for the ray count and what
    /// every frame returns, a second for the other stage outputs when asked. A count
    /// past the ray buffers' room leaves `out` to be overwritten by the frame's rerun.
    fn read_back(&self, plan: &FramePlan, camera: &CameraRecord, out: &mut Frame) -> Result<usize, GpuError> {
        let ctx = &self.ctx;
        let fb = self.frame.as_ref().expect("frame buffers");
        let pixels = camera.width as usize * camera.height as usize;
        let pairs = pixels * fb.light_count as usize;
        // The first readback holds the ray count: until then the ray buffers are read
        // to their room, and cut to the count after.
        let rays = plan.produces(FrameBuffer::Rays);
        let mut count = fb.ray_capacity as usize;
        let bytes = |b: FrameBuffer, count: usize| -> u64 {
            let (n, size) = match b {
                FrameBuffer::GBuffer => (pixels, std::mem::size_of::<GBufferTexel>()),
                FrameBuffer::Surfaces => (pixels, std::mem::size_of::<SurfaceRecord>()),
                FrameBuffer::Rays => (count, std::mem::size_of::<RayRecord>()),
                FrameBuffer::Occluded => (count, 4),
                FrameBuffer::Shadow => (pairs, 4),
                FrameBuffer::Rt | FrameBuffer::Raster | FrameBuffer::Final => (pixels, 16),
                FrameBuffer::Bounce { .. } => unreachable!("plans with bounces are refused before they run"),
            };
            (n * size) as u64
        };
        for always in [true, false] {
            let wanted: Vec<FrameBuffer> = out.buffers().filter(|b| b.always_returned() == always).collect();
            let mut parts: Vec<(&wgpu::Buffer, u64)> = wanted.iter().map(|&b| (fb.get(b), bytes(b, count))).collect();
            // The ray count first, with the buffers every frame returns.
            let with_count = always && rays;
            if with_count {
                parts.insert(0, (&fb.ray_count, 4));
            }
            let skip = with_count as usize;
            read_back_each(ctx, &parts, |i, data| match i.checked_sub(skip).map(|i| wanted[i]) {
                None => count = bytemuck::pod_read_unaligned::<u32>(data) as usize,
                Some(b) => match b {
                    FrameBuffer::GBuffer => copy_into_vec(&mut out.gbuffer, data),
                    FrameBuffer::Surfaces => copy_into_vec(&mut out.surfaces, data),
                    FrameBuffer::Rays => copy_into_vec(&mut out.rays, data),
                    FrameBuffer::Occluded => copy_into_vec(&mut out.occluded, data),
                    FrameBuffer::Shadow => {
                        // u32 codes on the GPU, u8 in the frame.
                        out.shadow.clear();
                        out.shadow.extend(data.chunks_exact(4).map(|w| bytemuck::pod_read_unaligned::<u32>(w) as u8));
                    }
                    FrameBuffer::Rt => copy_into_vec(&mut out.rt, data),
                    FrameBuffer::Raster => copy_into_vec(&mut out.raster, data),
                    FrameBuffer::Final => copy_into_vec(&mut out.final_image, data),
                    FrameBuffer::Bounce { .. } => unreachable!("plans with bounces are refused before they run"),
                },
            })?;
            if !rays {
                count = 0;
            }
            if count > fb.ray_capacity as usize {
                return Ok(count); // the frame runs again with room for its rays
            }
            out.occluded.truncate(count);
        }
        let mut stats = FrameStats {
            width: camera.width,
            height: camera.height,
            threads: 0,
            skipped: plan.skipped().to_vec(),
            ..Default::default()
        };
        for t in &out.gbuffer {
            if t.is_hit() {
                stats.covered_pixels += 1;
                stats.ray_traced_pixels += t.is_ray_traced() as u64;
            }
        }
        stats.raster_pixels = stats.covered_pixels - stats.ray_traced_pixels;
        // The GPU ray list holds shadow rays only (compaction makes no other kind yet).
        stats.rays_per_kind[hyrt_core::formats::RAY_KIND_SHADOW as usize] = count as u64;
        stats.occluded_shadow_rays = out.occluded.iter().filter(|&&o| o != 0).count() as u64;
        stats.stage_ms = self.stage_times(plan, &stats);
        out.width = camera.width;
        out.height = camera.height;
        out.stats = stats;
        Ok(count)
    }
}

/// Refuse a plan this backend cannot run yet: reflection and refraction bounces
/// (`FrameOptions::max_depth` above 0 on a scene with a ray-traced mirror or glass) run on
/// the CPU backend only so far. An error, never a frame without them.
fn check_supported(plan: &FramePlan) -> Result<(), RenderError> {
    match plan.steps().iter().find(|s| s.depth() > 0) {
        Some(step) => Err(RenderError::Unsupported {
            backend: "gpu",
            stage: step.label(),
            why: "reflection and refraction bounces run on the CPU backend only so far; use max depth 0 or the CPU backend",
        }),
        None => Ok(()),
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
        let plan = FramePlan::new(scene, options)?;
        check_supported(&plan)?;
        camera.validate().map_err(RenderError::InvalidCamera)?;
        frame.begin(&plan, options);
        self.render_frame(scene, &plan, camera, options, frame)?;
        frame.end();
        Ok(())
    }
}
