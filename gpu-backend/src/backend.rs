//! [`GpuBackend`]: the stages in one command buffer, all frame data on the GPU
//! from raster to final image, one readback at the end.

use std::collections::TryReserveError;
use std::sync::Arc;
use std::time::Instant;

use hyrt_core::formats::{
    CameraRecord, GBufferTexel, HitRecord, RayRecord, SurfaceRecord, RAY_KIND_REFLECTION, RAY_KIND_REFRACTION,
    RAY_KIND_SHADOW,
};
use hyrt_core::frame::{
    Backend, BounceStats, Frame, FrameOptions, FrameStats, PreparedScene, RenderError, StageTime, StageWork,
};
use hyrt_core::kernels::bounce::MAX_DEPTH_LIMIT;
use hyrt_core::plan::{BounceBuffer, FrameBuffer, FramePlan, Step};
use hyrt_core::stage::Stage;

use crate::band::{self, Band, BandMerge, BounceRoom, Room};
use crate::bounce_shading::BounceShadingStage;
use crate::bounce_trace::BounceTraceStage;
use crate::buffers::{
    FrameBuffers, FrameParams, SceneBuffers, SlotParams, COUNTER_HITS, COUNTER_OCCLUDED, COUNTER_REFLECTION,
    COUNTER_REFRACTION,
};
use crate::compaction::CompactionStage;
use crate::composition::CompositionStage;
use crate::gpu_buffer::{extend_from_bytes, read_back_each, read_back_many};
use crate::paging::{object_page_shift, page_shift, word_page_shift, Table, TablePages, MAX_PAGES};
use crate::present::Present;
use crate::raster_shading::RasterShadingStage;
use crate::reconstruction::{NormalMapping, ReconstructionStage};
use crate::rt_shading::{RtShadingBouncingStage, RtShadingStage};
use crate::secondary_rays::SecondaryRaysStage;
use crate::shadow_denoise::{GpuHistory, ShadowDenoiseStage};
use crate::shadow_rays::ShadowRaysStage;
use crate::texture::Specialization;
use crate::timing::StageTimer;
use crate::visibility_raster::{VisibilityMode, VisibilityRasterStage};
use crate::{AdapterPolicy, GpuContext, GpuError};

/// The most steps a plan has: every stage of the primary hits but `bvh_build` (which
/// runs on the CPU, once per scene), and the five stages of each bounce depth
/// (`secondary_rays`, `bounce_trace`, `compaction`, `shadow_rays`, `bounce_shading`) up
/// to the deepest a frame accepts.
const MAX_STEPS: u32 = Stage::ALL.len() as u32 - 1 - 3 + 5 * MAX_DEPTH_LIMIT;

/// Storage buffers the bounce stages bind in one shader stage, at most: `secondary_rays`
/// binds the scan's three (flags, levels, the list's count) and eleven of its own (objects,
/// triangles, the G-buffer, the parents' surfaces, rays, hits and count, the rays, links
/// and counters it writes, the surface tables); `bounce_shading` as many (the depth's rays,
/// count, hits, surfaces and shadow codes, objects, triangles, lights, the environment's
/// texels, the next depth's links and radiance, the radiance it writes, the surface tables
/// and the ambient light's texels). WebGPU's default limit is 8;
/// `GpuContext::new` asks for all the adapter has. On a device with fewer, the backend renders frames
/// without bounces and refuses the others with `GpuError::Limits`.
pub const BOUNCE_STORAGE_BUFFERS: u32 = 14;

/// The pipelines of the bounce stages (and of `rt_shading` gathering the first bounce).
struct BounceStages {
    secondary_rays: Arc<SecondaryRaysStage>,
    bounce_trace: Arc<BounceTraceStage>,
    bounce_shading: BounceShadingStage,
    rt_shading: RtShadingBouncingStage,
}

/// The stages that read the surface tables, compiled for one [`Specialization`] (the
/// others, `reconstruction`, `compaction` and `composition`, read none). The stages that
/// shade no surface (in `Arc`s) read no ambient light and no mask slot: two
/// specializations that differ only in [`Specialization::ambient_image`] and
/// [`Specialization::stochastic`] share them ([`Specialization::same_rays`]).
struct SurfaceStages {
    visibility_raster: Arc<VisibilityRasterStage>,
    shadow_rays: Arc<ShadowRaysStage>,
    rt_shading: RtShadingStage,
    raster_shading: RasterShadingStage,
    /// `None` on a device with fewer than [`BOUNCE_STORAGE_BUFFERS`] storage buffers per
    /// shader stage.
    bounces: Option<BounceStages>,
    /// The passes after `reconstruction` and `bounce_trace` of a scene with normal maps.
    normal_mapping: Option<Arc<NormalMapping>>,
}

impl SurfaceStages {
    /// Build the pipelines for scenes that need `s`, `visibility_raster` in `mode`; those
    /// that shade no surface taken from `sibling` where given (the stages of a
    /// specialization with the same rays, [`Specialization::same_rays`], in `mode`).
    fn new(
        ctx: &GpuContext,
        mode: VisibilityMode,
        s: Specialization,
        sibling: Option<&SurfaceStages>,
    ) -> Result<SurfaceStages, GpuError> {
        let (visibility_raster, shadow_rays, rt_shading, raster_shading) = ctx.checked(|| {
            (
                sibling.map_or_else(
                    || Arc::new(VisibilityRasterStage::specialized(ctx, mode, s)),
                    |t| t.visibility_raster.clone(),
                ),
                sibling.map_or_else(|| Arc::new(ShadowRaysStage::specialized(ctx, s)), |t| t.shadow_rays.clone()),
                RtShadingStage::specialized(ctx, s),
                RasterShadingStage::specialized(ctx, s),
            )
        })?;
        let bounces = if ctx.limits.max_storage_buffers_per_shader_stage >= BOUNCE_STORAGE_BUFFERS {
            let shared = sibling.and_then(|t| t.bounces.as_ref());
            Some(ctx.checked(|| {
                BounceStages {
                    secondary_rays: shared.map_or_else(
                        || Arc::new(SecondaryRaysStage::specialized(ctx, s)),
                        |b| b.secondary_rays.clone(),
                    ),
                    bounce_trace: shared
                        .map_or_else(|| Arc::new(BounceTraceStage::specialized(ctx, s)), |b| b.bounce_trace.clone()),
                    bounce_shading: BounceShadingStage::specialized(ctx, s),
                    rt_shading: RtShadingBouncingStage::specialized(ctx, s),
                }
            })?)
        } else {
            None
        };
        let normal_mapping = match (s.normal_mapped, sibling) {
            (false, _) => None,
            (true, Some(t)) => t.normal_mapping.clone(),
            (true, None) => Some(Arc::new(ctx.checked(|| NormalMapping::paged(ctx, s.pages))?)),
        };
        Ok(SurfaceStages { visibility_raster, shadow_rays, rt_shading, raster_shading, bounces, normal_mapping })
    }
}

/// Room for the secondary rays of each bounce depth in a frame that has no earlier
/// frame to size them by: one ray per this many pixels. The lists' counts stay on the
/// GPU; a frame with more rays runs again with room for them (a quarter more).
const FIRST_BOUNCE_ROOM_PIXELS_PER_RAY: u32 = 4;

/// What a frame's lists held, read back with the frame: the primary shadow rays, and
/// per bounce depth its rays, their shadow rays and its counters.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
struct Counts {
    shadow_rays: usize,
    /// The primary shadow rays of the band's own pixels (`shadow_rays` but in a band
    /// with a halo, [`crate::band`]): what the frame keeps.
    own_shadow_rays: usize,
    bounces: Vec<BounceCounts>,
    /// A band of a banded frame: where each light's rays start in its primary
    /// shadow-ray list, and in each bounce depth's (empty otherwise); three words per
    /// slot (`shaders/light_starts.wgsl`: the slot's first ray, its first and its last but
    /// one of the band's own pixels).
    primary_starts: Vec<u32>,
    bounce_starts: Vec<Vec<u32>>,
}

/// What one bounce depth's lists held.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct BounceCounts {
    rays: usize,
    shadow_rays: usize,
    /// `[reflection rays, refraction rays, hits, occluded shadow rays]`.
    counters: [u32; 4],
}

impl Counts {
    /// The room to run again with when a list outgrew `room`: a quarter more than its
    /// count (primary shadow rays never past one per (pixel, light) pair, which always
    /// fits); `None` when every list fit.
    fn grown(&self, room: &Room, pairs: usize) -> Option<Room> {
        // A list that fit keeps its room; one that did not gets a quarter more than its
        // count, at most `cap`.
        let more = |count: usize, have: u32, cap: usize| {
            if count <= have as usize {
                have
            } else {
                u32::try_from((count + count / 4).min(cap)).unwrap_or(u32::MAX)
            }
        };
        let grown = Room {
            shadow_rays: more(self.shadow_rays, room.shadow_rays, pairs),
            bounces: room
                .bounces
                .iter()
                .zip(self.bounces.iter().chain(std::iter::repeat(&BounceCounts::default())))
                .map(|(r, c)| BounceRoom {
                    rays: more(c.rays, r.rays, usize::MAX),
                    shadow_rays: more(c.shadow_rays, r.shadow_rays, usize::MAX),
                })
                .collect(),
        };
        (grown != *room).then_some(grown)
    }
}

/// The GPU backend. Pipelines are created once (those of scenes with surface tables, and
/// those of frames with stochastic shadow rays, the first time such a frame is rendered:
/// [`Specialization`]); scene buffers once per [`PreparedScene`] (the lights and the
/// ambient light written again when a frame's differ: area lights' samples and seeds,
/// ambient occlusion); frame buffers once per image size and count of shadow-mask slots
/// per surface (the light count without area lights and ambient occlusion).
///
/// Area lights and ambient occlusion render bit for bit the CPU reference's frame, denoised
/// (`shadow_denoise`, [`crate::shadow_denoise`]: its pipelines and those of the shading
/// stages that read its channels built the first time a frame denoises) or not
/// ([`FrameOptions::denoise`] false).
pub struct GpuBackend {
    ctx: GpuContext,
    reconstruction: ReconstructionStage,
    compaction: CompactionStage,
    composition: CompositionStage,
    /// The stages that read the surface tables, per specialization built so far; the
    /// first is [`Specialization::PLAIN`], built with the backend.
    stages: Vec<(Specialization, SurfaceStages)>,
    /// How `visibility_raster` computes the G-buffer, in every specialization.
    visibility_mode: VisibilityMode,
    timer: StageTimer,
    scene: Option<(u64, u64, SceneBuffers)>,
    /// Scenes uploaded whole, and changes written in place ([`GpuBackend::scene_writes`]).
    scene_writes: (u64, u64),
    frame: Option<FrameBuffers>,
    /// Milliseconds per step of the last run plan (of the last frame, summed over its bands).
    stage_ms: Vec<f64>,
    present: Present,
    /// [`GpuBackend::set_max_band_bytes`].
    max_band_bytes: Option<u64>,
    /// [`GpuBackend::last_frame_bands`].
    last_bands: u32,
    /// The `shadow_denoise` stage, built the first time a frame denoises (again for a scene
    /// whose lights are in other pages).
    shadow_denoise: Option<ShadowDenoiseStage>,
    /// What the last frame of the denoiser's temporal pass left for the next
    /// ([`FrameOptions::temporal`]), made by the first such frame.
    history: Option<GpuHistory>,
}

impl GpuBackend {
    /// Open a device under `policy` and build every pipeline.
    pub fn new(policy: AdapterPolicy) -> Result<GpuBackend, GpuError> {
        let ctx = GpuContext::new(policy)?;
        Self::with_context(ctx)
    }

    /// Build every pipeline of scenes without surface tables on an existing context.
    pub fn with_context(ctx: GpuContext) -> Result<GpuBackend, GpuError> {
        let (reconstruction, compaction, composition) =
            ctx.checked(|| (ReconstructionStage::new(&ctx), CompactionStage::new(&ctx), CompositionStage::new(&ctx)))?;
        let visibility_mode = VisibilityMode::default();
        let plain = SurfaceStages::new(&ctx, visibility_mode, Specialization::PLAIN, None)?;
        let timer = StageTimer::new(&ctx, MAX_STEPS)?;
        Ok(GpuBackend {
            ctx,
            reconstruction,
            compaction,
            composition,
            stages: vec![(Specialization::PLAIN, plain)],
            visibility_mode,
            timer,
            scene: None,
            scene_writes: (0, 0),
            frame: None,
            stage_ms: Vec::new(),
            present: Present::default(),
            max_band_bytes: None,
            last_bands: 0,
            shadow_denoise: None,
            history: None,
        })
    }

    /// The adapter, the triangle-id source, the timing method and the float probe
    /// ([`GpuContext::float_probe`](crate::GpuContext::float_probe)), in one line.
    pub fn describe(&self) -> String {
        let timing = if self.timer.is_active() && !crate::context::is_software(&self.ctx.info) {
            "GPU timestamp queries"
        } else {
            "wall clock per stage (submit and wait)"
        };
        let probe = match self.ctx.float_probe() {
            Ok(p) => p.to_string(),
            Err(e) => format!("float probe failed: {e}"),
        };
        format!(
            "{}; raster ids from {}; stage times from {timing}; {probe}",
            self.ctx.describe(),
            self.stages[0].1.visibility_raster.triangle_id_source()
        )
    }

    /// Switch how `visibility_raster` computes the G-buffer (the pipelines are rebuilt
    /// on a change). [`VisibilityMode::Exact`], the default, is bit-identical to the CPU
    /// reference; [`VisibilityMode::HardwareInterpolated`] is not, and exists for
    /// benchmarks that measure the device as a plain rasterizer.
    pub fn set_visibility_mode(&mut self, mode: VisibilityMode) -> Result<(), GpuError> {
        if self.visibility_mode != mode {
            for (s, stages) in &mut self.stages {
                let ctx = &self.ctx;
                stages.visibility_raster = Arc::new(ctx.checked(|| VisibilityRasterStage::specialized(ctx, mode, *s))?);
            }
            self.visibility_mode = mode;
        }
        Ok(())
    }

    /// The stages specialized as `s`, built now if no frame needed them before (but for
    /// those they share with the stages of a specialization with the same rays,
    /// [`Specialization::same_rays`], if built).
    fn stages(&mut self, s: Specialization) -> Result<&SurfaceStages, GpuError> {
        let at = match self.stages.iter().position(|(k, _)| *k == s) {
            Some(at) => at,
            None => {
                let sibling = self.stages.iter().find(|(k, _)| k.same_rays(s)).map(|(_, t)| t);
                let stages = SurfaceStages::new(&self.ctx, self.visibility_mode, s, sibling)?;
                self.stages.push((s, stages));
                self.stages.len() - 1
            }
        };
        Ok(&self.stages[at].1)
    }

    /// How scenes reached the device so far: `(whole uploads, in-place updates)`. A
    /// prepared scene is uploaded once; each change made to it in place
    /// ([`PreparedScene::move_objects`]) is written at the next frame, no more.
    pub fn scene_writes(&self) -> (u64, u64) {
        self.scene_writes
    }

    /// The device context.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// The most bytes one storage binding of a band holds: the device's limit, or less
    /// when [`GpuBackend::set_max_band_bytes`] asked for it.
    fn band_binding_limit(&self) -> u64 {
        let device = self.ctx.limits.max_storage_buffer_binding_size.min(self.ctx.limits.max_buffer_size);
        self.max_band_bytes.map_or(device, |b| b.clamp(1, device))
    }

    /// Render frames in bands whose storage bindings hold at most `bytes` (`None`: the
    /// device's `max_storage_buffer_binding_size`, the default). Frames are the same bit
    /// for bit whatever the bands ([`crate::band`]); smaller bands need less device
    /// memory at once and take more passes. For tests of banded frames at small sizes,
    /// and for applications that share the device's memory.
    pub fn set_max_band_bytes(&mut self, bytes: Option<u64>) {
        self.max_band_bytes = bytes;
    }

    /// The bands of rows the last frame was rendered in ([`crate::band`]): 1 when it fit
    /// the device's bindings whole.
    pub fn last_frame_bands(&self) -> u32 {
        self.last_bands
    }

    /// Render the frame band after band ([`crate::band`]) into `sink`: the frame's
    /// buffers, or a texture. The lists' counts of the whole frame; the stage times are
    /// the bands' sums.
    fn run_frame(
        &mut self,
        scene: &PreparedScene,
        plan: &FramePlan,
        camera: &CameraRecord,
        options: &FrameOptions,
        sink: &mut Sink<'_>,
    ) -> Result<Counts, GpuError> {
        // The scene on the device: kept, brought up to the scene's revision by writing what
        // changed (objects moved in place), or uploaded whole.
        let ctx = &self.ctx;
        let held = self.scene.as_mut().filter(|(id, _, _)| *id == scene.id());
        match held.and_then(|(_, revision, buffers)| Some((scene.changes_since(*revision)?, revision, buffers))) {
            Some((changes, revision, buffers)) => {
                if *revision != scene.revision() {
                    ctx.checked(|| buffers.apply(ctx, scene, &changes))?;
                    *revision = scene.revision();
                    self.scene_writes.1 += 1;
                }
            }
            None => {
                // Device memory is what bounds a scene (its tables past one binding are in
                // pages): running out of it says how much the scene needed.
                let buffers = ctx.checked(|| SceneBuffers::new(ctx, scene)).map_err(|e| match e {
                    GpuError::OutOfMemory(m) => GpuError::OutOfMemory(format!(
                        "the scene's tables need {} bytes of device memory: {m}",
                        scene_table_bytes(scene)
                    )),
                    e => e,
                })?;
                self.scene = Some((scene.id(), scene.revision(), buffers));
                self.scene_writes.0 += 1;
            }
        }
        // The frame's lights and ambient light: the scene's, or with area lights their
        // samples and this frame's seeds, with ambient occlusion its rays.
        let lighting = scene.frame_lighting(options);
        let held = &mut self.scene.as_mut().expect("scene buffers").2;
        let ambient = lighting.ambient.record();
        let culls = scene.geometry.interior_culls(camera);
        ctx.checked(|| {
            held.set_lighting(ctx, &lighting.lights, &ambient);
            held.set_interior_culls(ctx, &culls);
        })?;
        // The pipelines this scene's surface tables and the frame's rays need, built before
        // the first frame that needs them.
        let stochastic = plan.stochastic();
        let denoised = plan.runs(Stage::ShadowDenoise);
        let of_scene = self.scene.as_ref().expect("scene buffers").2.specialization;
        self.stages(Specialization { stochastic, denoised, ..of_scene })?;
        // Compiled for the scene's lights' pages (`crate::paging`).
        let light_pages = of_scene.pages.lights_only();
        if denoised && self.shadow_denoise.as_ref().is_none_or(|s| s.pages != light_pages) {
            let ctx = &self.ctx;
            self.shadow_denoise = Some(ctx.checked(|| ShadowDenoiseStage::paged(ctx, light_pages))?);
        }
        // Shadow-mask slots per surface: one per light, or with area lights and ambient
        // occlusion the slots of `hyrt_core::kernels::soft_shadow`.
        let slots = SlotParams::of(lighting.lights(), lighting.ambient.occlusion.samples);
        debug_assert_eq!(slots.slots, plan.lights(), "the plan's slots");
        let limit = self.band_binding_limit();
        let max_side = self.ctx.limits.max_texture_dimension_2d;
        let fit = band::rows_per_band(camera.width, camera.height, slots.slots, plan, limit, max_side)?;
        // A band of a denoised frame of several bands is rendered with a halo of rows.
        let halo = if denoised { crate::shadow_denoise::DENOISE_HALO } else { 0 };
        let mut rows = band::own_rows(fit, camera.height, halo)?;
        let mut banded = rows < camera.height;
        // The denoiser's temporal pass reads the previous frame's history at reprojected
        // rows: a frame in one band only (the history starts afresh as the CPU's does, on
        // another scene or channel count).
        let temporal = options.temporal && denoised;
        if temporal {
            if banded {
                return Err(temporal_banded(camera, limit));
            }
            let ctx = &self.ctx;
            if self.history.is_none() {
                self.history = Some(ctx.checked(|| GpuHistory::new(ctx))??);
            }
            let samples = hyrt_core::kernels::denoise::channel_samples(&lighting.lights, &lighting.ambient.occlusion);
            let history = self.history.as_mut().expect("the history");
            ctx.checked(|| history.prepare(ctx, scene.id(), scene.object_maps(), camera, &samples))??;
        }
        if let Sink::Frame(out) = sink {
            for b in out.buffers().collect::<Vec<_>>() {
                out.clear(b);
            }
        }
        let mut merge = BandMerge::default();
        let mut total = Counts::default();
        let mut stage_ms = vec![0.0; plan.steps().len()];
        let mut first_row = 0;
        self.last_bands = 0;
        while first_row < camera.height {
            let band = Band { first_row, rows: rows.min(camera.height - first_row) };
            let halo = if banded { halo } else { 0 };
            let (extended, own) = band::with_halo(band, camera.height, halo);
            let shape = (band::buffer_rows(rows, camera.height, halo), banded, &slots, stochastic);
            match self.run_band(scene, plan, camera, options, (extended, own), shape, sink, &mut merge)? {
                Some(counts) => {
                    total.add(&counts);
                    self.last_bands += 1;
                    stage_ms.iter_mut().zip(&self.stage_ms).for_each(|(sum, ms)| *sum += ms);
                    first_row += band.rows;
                }
                // A bounce list outgrew a binding: the band splits and runs again (not
                // in a frame of the temporal pass, which must be one band).
                None if temporal && band.rows > 1 => return Err(temporal_banded(camera, limit)),
                None if band.rows > 1 => {
                    rows = band.rows.div_ceil(2);
                    banded = true;
                }
                None => {
                    return Err(GpuError::Limits(format!(
                        "the bounce lists of one {}-pixel row need more than the {limit} bytes a storage binding holds",
                        camera.width
                    )))
                }
            }
        }
        if let Sink::Frame(out) = sink {
            merge.finish(out);
        }
        if temporal {
            self.history.as_mut().expect("the history").commit();
        }
        self.stage_ms = stage_ms;
        Ok(total)
    }

    /// Run the plan over `band` keeping its rows `own` (from the band's first row: all of
    /// them but for a halo, [`crate::band`]; of a frame whose buffers hold `rows` rows,
    /// `banded` if more than one band, with the mask `slots` per surface, `stochastic` if
    /// the frame traces stochastic rays) with room for its lists, then read it back or
    /// present it: its counts, or `None` when a list needs more room than a binding holds
    /// (the band must split). A band whose lists outgrow their room runs again with more.
    #[allow(clippy::too_many_arguments)]
    fn run_band(
        &mut self,
        scene: &PreparedScene,
        plan: &FramePlan,
        camera: &CameraRecord,
        options: &FrameOptions,
        (band, own): (Band, Band),
        (rows, banded, slots, stochastic): (u32, bool, &SlotParams, bool),
        sink: &mut Sink<'_>,
        merge: &mut BandMerge,
    ) -> Result<Option<Counts>, GpuError> {
        let lights = slots.slots;
        let pixels = camera.width as usize * rows as usize;
        let pairs = pixels * lights as usize;
        // Ray buffers hold the rays a band has, known only on the GPU after each list's
        // scan. A band starts with the last band's room (one shadow ray per pixel and
        // a ray per FIRST_BOUNCE_ROOM_PIXELS_PER_RAY pixels per bounce at first); if a
        // list finds more, its rays past the room are not written, and the band runs
        // again with room for them plus a quarter (primary shadow rays never past one
        // per (pixel, slot) pair, which always fits a band). What is returned traced
        // every ray. (`lights` here are the mask's slots: one per light without area
        // lights and ambient occlusion.)
        let mut room = self.first_room(plan, pixels, pairs, lights);
        loop {
            if band::bounce_binding_bytes(&room, lights) > self.band_binding_limit() {
                return Ok(None);
            }
            if !self.frame.as_ref().is_some_and(|f| f.fits(camera.width, rows, lights, plan, &room)) {
                self.frame = None; // free the old buffers before allocating new ones
                let (ctx, w) = (&self.ctx, camera.width);
                self.frame = Some(ctx.checked(|| FrameBuffers::for_plan(ctx, w, rows, lights, plan, &room))??);
            }
            let fb = self.frame.as_mut().expect("frame buffers");
            fb.set_band(&self.ctx, band, own, banded);
            fb.set_slots(&self.ctx, slots, stochastic);
            // The frame's cone spread, by the CPU's rule (0 unless colours vary over surfaces).
            self.run_plan(plan, camera, options, scene.geometry.materials(camera).spread)?;
            let counts = match sink {
                Sink::Frame(out) => self.read_back(plan, merge, out)?,
                Sink::Texture(_) => self.read_counts(plan)?,
            };
            let have = self.frame.as_ref().expect("frame buffers").room();
            match counts.grown(&have, pairs) {
                None => {
                    if let Sink::Texture(target) = sink {
                        let (ctx, fb) = (&self.ctx, self.frame.as_ref().expect("frame buffers"));
                        ctx.checked(|| {
                            let mut enc = ctx
                                .device
                                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("present") });
                            self.present.encode(ctx, &mut enc, fb, target);
                            ctx.queue.submit([enc.finish()]);
                        })?;
                    }
                    return Ok(Some(counts));
                }
                Some(more) => room = more,
            }
        }
    }

    /// The room a band starts with: the last band's where it had the list.
    fn first_room(&self, plan: &FramePlan, pixels: usize, pairs: usize, lights: u32) -> Room {
        let last = self.frame.as_ref().map(|f| f.room()).unwrap_or_default();
        let first_rays = (pixels as u32).div_ceil(FIRST_BOUNCE_ROOM_PIXELS_PER_RAY).max(1);
        let first = BounceRoom { rays: first_rays, shadow_rays: first_rays.saturating_mul(lights.max(1)) };
        // The last band's room where it fits this band's bindings (a band split in two
        // after its lists outgrew them starts afresh).
        let fits = |r: &BounceRoom| band::bounce_room_bytes(r, lights) <= self.band_binding_limit();
        let bounces = (0..plan.bounce_depth() as usize)
            .map(|d| last.bounces.get(d).copied().filter(fits).unwrap_or(first))
            .collect();
        let shadow_rays = last.shadow_rays.clamp(pixels.min(pairs) as u32, pairs as u32);
        Room { shadow_rays, bounces }
    }

    /// Render a frame and leave its final image on the GPU, in `target` (see
    /// [`crate::present`] for the texture it must be): nothing but the lists' counts
    /// are read back, so a display loop pays no transfer. The statistics have
    /// the stage times, the plan's skipped stages, the rays per kind and the bounces'
    /// counts (one small readback of the lists' counts per band); the pixel
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
        self.check_supported(scene, &plan)?;
        camera.validate().map_err(RenderError::InvalidCamera)?;
        crate::present::check_target(target, camera.width, camera.height).map_err(RenderError::InvalidOptions)?;
        let counts = self.run_frame(scene, &plan, camera, options, &mut Sink::Texture(target))?;
        let mut stats = FrameStats {
            width: camera.width,
            height: camera.height,
            skipped: plan.skipped().to_vec(),
            ..Default::default()
        };
        counts.fill(&mut stats);
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

    /// Encode and submit the plan's steps over the current frame buffers, with the
    /// frame's cone `spread` ([`FrameParams::pixel_spread`]). Stage times are kept for the
    /// statistics.
    fn run_plan(
        &mut self,
        plan: &FramePlan,
        camera: &CameraRecord,
        options: &FrameOptions,
        spread: f32,
    ) -> Result<(), GpuError> {
        let ctx = &self.ctx;
        let (sb, fb) = (&self.scene.as_ref().expect("scene buffers").2, self.frame.as_ref().expect("frame buffers"));
        let denoised = plan.runs(Stage::ShadowDenoise);
        let specialization = Specialization { stochastic: fb.stochastic, denoised, ..sb.specialization };
        let st = self
            .stages
            .iter()
            .find(|(s, _)| *s == specialization)
            .map(|(_, stages)| stages)
            .expect("run_frame builds the frame's specialization");
        let params = FrameParams::new(camera.width, camera.height, sb.light_count, options.weight)
            .with_composition(plan.composition())
            .with_pixel_spread(spread)
            .for_band(fb.band.first_row, fb.band.rows);
        debug_assert_eq!(params.validate(), Ok(()));
        fb.write_uniforms(ctx, camera, &params);
        if let Some(d) = &fb.denoise {
            // The pixel's angle by the CPU stage's own function.
            d.write_params(ctx, hyrt_core::kernels::denoise::pixel_angle(camera), options.temporal);
        }

        // With timestamp queries the frame is one command buffer and the GPU times each
        // stage. Without them each stage is submitted alone and waited for, so the wall
        // clock can time it (slower: it serializes CPU and GPU).
        // Lavapipe's timestamps do not measure its passes (it reported 0.07 ms for
        // reconstructing 921,600 pixels on a CPU): on software adapters each stage is
        // timed by the wall clock instead.
        let timed_by_gpu = self.timer.is_active() && !crate::context::is_software(&ctx.info);
        // The temporal pass's history, prepared by `run_frame`.
        let history = match options.temporal && denoised {
            true => Some(self.history.as_ref().expect("run_frame prepares the history")),
            false => None,
        };
        let mut wall_ms = Vec::with_capacity(plan.steps().len());
        let bounce = || st.bounces.as_ref().expect("plans with bounces need the bounce stages (check_supported)");
        ctx.checked(|| -> Result<(), GpuError> {
            let t = &self.timer;
            let mut enc =
                ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("hyrt frame") });
            // The plan's one loop: each step encodes its stage module and is timed.
            for (i, &step) in plan.steps().iter().enumerate() {
                let start = Instant::now();
                let slot = t.stage(i as u32);
                match step {
                    Step::VisibilityRaster => st.visibility_raster.encode(ctx, &mut enc, sb, fb, slot),
                    Step::Reconstruction => {
                        self.reconstruction.encode(ctx, &mut enc, sb, fb, options.barycentrics, slot);
                        if let Some(n) = &st.normal_mapping {
                            n.encode_primary(ctx, &mut enc, sb, fb);
                        }
                    }
                    Step::Compaction => self.compaction.encode(ctx, &mut enc, sb, fb, slot),
                    Step::ShadowRays => st.shadow_rays.encode(ctx, &mut enc, sb, fb, slot),
                    Step::ShadowDenoise => self
                        .shadow_denoise
                        .as_ref()
                        .expect("run_frame builds the denoiser")
                        .encode(ctx, &mut enc, sb, fb, history, slot),
                    Step::SecondaryRays { depth } => bounce().secondary_rays.encode(ctx, &mut enc, sb, fb, depth, slot),
                    Step::BounceTrace { depth } => {
                        bounce().bounce_trace.encode(ctx, &mut enc, sb, fb, depth, slot);
                        if let Some(n) = &st.normal_mapping {
                            n.encode_secondary(ctx, &mut enc, sb, fb, depth);
                        }
                    }
                    Step::BounceCompaction { depth } => {
                        let list = fb.bounces[depth as usize - 1].list(&fb.all_surfaces);
                        self.compaction.encode_list(ctx, &mut enc, sb, fb, &list, slot)
                    }
                    Step::BounceShadowRays { depth } => {
                        let list = fb.bounces[depth as usize - 1].list(&fb.all_surfaces);
                        st.shadow_rays.encode_list(ctx, &mut enc, sb, fb, &list, slot)
                    }
                    Step::BounceShading { depth, last } => {
                        bounce().bounce_shading.encode(ctx, &mut enc, sb, fb, depth, last, slot)
                    }
                    Step::RtShading { bounces: false } => st.rt_shading.encode(ctx, &mut enc, sb, fb, slot),
                    Step::RtShading { bounces: true } => bounce().rt_shading.encode(ctx, &mut enc, sb, fb, slot),
                    // `shade_ray_traced` is the shader's `weight < 1`.
                    Step::RasterShading { .. } => st.raster_shading.encode(ctx, &mut enc, sb, fb, slot),
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

    /// The lists' count buffers, in the order [`Counts::parse`] reads them: the primary
    /// shadow rays' (when planned), then per bounce depth its rays', its shadow rays'
    /// and its counters; in a banded frame then where each shadow-ray list's lights
    /// start (the primary list's, then each depth's).
    fn count_parts(&self, plan: &FramePlan) -> Vec<(&wgpu::Buffer, u64)> {
        let fb = self.frame.as_ref().expect("frame buffers");
        let mut parts = Vec::with_capacity(2 + 4 * fb.bounces.len());
        let rays = plan.produces(FrameBuffer::Rays);
        if rays {
            parts.push((&fb.ray_count, 4));
        }
        for b in &fb.bounces {
            parts.extend([(&b.ray_count, 4), (&b.shadow_ray_count, 4), (&b.counters, 16)]);
        }
        if fb.banded {
            // Three words per slot (`shaders/light_starts.wgsl`).
            let starts = 12 * fb.slots as u64;
            if rays {
                parts.push((&fb.light_starts, starts));
            }
            parts.extend(fb.bounces.iter().map(|b| (&b.light_starts, starts)));
        }
        parts
    }

    /// The lists' counts of the last run, read back alone.
    fn read_counts(&self, plan: &FramePlan) -> Result<Counts, GpuError> {
        let parts = self.count_parts(plan);
        let data = read_back_many(&self.ctx, &parts)?;
        let fb = self.frame.as_ref().expect("frame buffers");
        Ok(Counts::parse(plan, fb.banded, data.iter().map(|d| d.as_slice())))
    }

    /// Read the band's buffers the frame holds back and append them to `out` (see
    /// [`crate::band`] for how the bands merge); the lists' counts. One readback for the
    /// counts and what every frame returns, a second for the other stage outputs when
    /// asked. A count past its list's room appends nothing: the band runs again.
    fn read_back(&self, plan: &FramePlan, merge: &mut BandMerge, out: &mut Frame) -> Result<Counts, GpuError> {
        let ctx = &self.ctx;
        let fb = self.frame.as_ref().expect("frame buffers");
        let pixels = fb.width as usize * fb.band.rows as usize;
        // Mask slots per surface (one per light without area lights and occlusion).
        let lights = fb.slots as usize;
        let pairs = pixels * lights;
        // The first readback holds the counts: until then the primary occlusion results
        // are read to their room, and appended to the count.
        let count_parts = self.count_parts(plan);
        let mut counts = Counts {
            shadow_rays: fb.ray_capacity as usize,
            bounces: fb.bounces.iter().map(|_| BounceCounts::default()).collect(),
            ..Default::default()
        };
        let bytes = |b: FrameBuffer, counts: &Counts| -> usize {
            let (n, size) = match b {
                FrameBuffer::GBuffer => (pixels, std::mem::size_of::<GBufferTexel>()),
                FrameBuffer::Surfaces => (pixels, std::mem::size_of::<SurfaceRecord>()),
                FrameBuffer::Rays => (counts.shadow_rays, std::mem::size_of::<RayRecord>()),
                FrameBuffer::Occluded => (counts.shadow_rays, 4),
                FrameBuffer::Shadow => (pairs, 4),
                FrameBuffer::Visibility => (pixels, 4 * fb.channels as usize),
                FrameBuffer::Rt | FrameBuffer::Raster | FrameBuffer::Final => (pixels, 16),
                FrameBuffer::Bounce { buffer, depth } => {
                    let c = counts.bounces[depth as usize - 1];
                    let parents = match depth {
                        1 => pixels,
                        _ => counts.bounces[depth as usize - 2].rays,
                    };
                    match buffer {
                        BounceBuffer::Rays => (c.rays, std::mem::size_of::<RayRecord>()),
                        BounceBuffer::Links => (parents, 8),
                        BounceBuffer::Hits => (c.rays, std::mem::size_of::<HitRecord>()),
                        BounceBuffer::Surfaces => (c.rays, std::mem::size_of::<SurfaceRecord>()),
                        BounceBuffer::ShadowRays => (c.shadow_rays, std::mem::size_of::<RayRecord>()),
                        BounceBuffer::Occluded => (c.shadow_rays, 4),
                        BounceBuffer::Shadow => (c.rays * lights, 4),
                        BounceBuffer::Radiance => (c.rays, 16),
                    }
                }
            };
            n * size
        };
        // What earlier bands held: the offsets of this band's indices into the frame's lists.
        let pixel_offset = merge.pixels;
        let rays_before = |depth: u32| merge.rays.get(depth as usize - 1).copied().unwrap_or(0);
        // The band's own pixels (all of them but in a band with a halo, [`crate::band`]):
        // what the frame keeps of its per-pixel buffers; its ray indices made the frame's.
        let (own_lo, own_hi) = (fb.width as usize * fb.own.first_row as usize, fb.width as usize * band::own_end(fb));
        let own_pixels = |data: &[u8], size: usize| -> std::ops::Range<usize> {
            (own_lo * size).min(data.len())..(own_hi * size).min(data.len())
        };
        let ray_offset = pixel_offset.wrapping_sub(own_lo as u32);
        for always in [true, false] {
            let wanted = read_in(out, always);
            let mut parts: Vec<(&wgpu::Buffer, u64)> =
                wanted.iter().map(|&b| (fb.get(b), bytes(b, &counts) as u64)).collect();
            // The counts first, with the buffers every frame returns.
            let skip = if always { count_parts.len() } else { 0 };
            if always {
                parts.splice(0..0, count_parts.iter().copied());
                if skip == 0 {
                    counts = Counts::parse(plan, fb.banded, std::iter::empty());
                }
            }
            let mut count_data = Vec::with_capacity(skip);
            let mut fits = !always || skip == 0;
            let mut no_room: Option<(FrameBuffer, usize)> = None;
            read_back_each(ctx, &parts, |i, data| {
                let Some(b) = i.checked_sub(skip).map(|i| wanted[i]) else {
                    count_data.push(data.to_vec());
                    if count_data.len() == skip {
                        counts = Counts::parse(plan, fb.banded, count_data.iter().map(|d| d.as_slice()));
                        fits = counts.grown(&fb.room(), pairs).is_none();
                    }
                    return;
                };
                if !fits || no_room.is_some() {
                    return; // the band runs again with room for its rays, or the frame fails
                }
                // Lists read to their room before the counts were known: to the count.
                let data = &data[..bytes(b, &counts).min(data.len())];
                // Per-pixel buffers: the band's own rows; the primary lists: its own rays.
                let per_pixel = bytes(b, &counts) / pixels.max(1);
                let own = |data: &[u8]| own_pixels(data, per_pixel);
                let own_rays = |data: &[u8], size: usize| match fb.banded {
                    true => band::own_rays(data, size, &counts.primary_starts),
                    false => data.to_vec(),
                };
                let appended = match b {
                    FrameBuffer::GBuffer => extend_from_bytes(&mut out.gbuffer, &data[own(data)]),
                    FrameBuffer::Surfaces => extend_from_bytes(&mut out.surfaces, &data[own(data)]),
                    FrameBuffer::Rays => {
                        let data = own_rays(data, std::mem::size_of::<RayRecord>());
                        appended(&mut out.rays, &data, |r| band::offset_pixels(r, ray_offset))
                    }
                    FrameBuffer::Occluded => extend_from_bytes(&mut out.occluded, &own_rays(data, 4)),
                    // u32 codes on the GPU, u8 in the frame.
                    FrameBuffer::Shadow => shadow_codes_into(&mut out.shadow, &data[own(data)]),
                    FrameBuffer::Visibility => extend_from_bytes(&mut out.visibility, &data[own(data)]),
                    FrameBuffer::Rt => extend_from_bytes(&mut out.rt, &data[own(data)]),
                    FrameBuffer::Raster => extend_from_bytes(&mut out.raster, &data[own(data)]),
                    FrameBuffer::Final => extend_from_bytes(&mut out.final_image, &data[own(data)]),
                    FrameBuffer::Bounce { buffer, depth } => {
                        // A bounce ray's `pixel` is its primary pixel at every depth; a bounce
                        // shadow ray's, its surface in the depth's list.
                        let own = rays_before(depth);
                        let o = out.bounce_mut(depth);
                        match buffer {
                            BounceBuffer::Rays => appended(&mut o.rays, data, |r| band::offset_pixels(r, ray_offset)),
                            // Depth 1's parents are the pixels: the band's own (its halo
                            // spawns no ray, `secondary_rays`).
                            BounceBuffer::Links if depth == 1 => {
                                appended(&mut o.links, &data[own_pixels(data, 8)], |l| band::offset_links(l, own))
                            }
                            BounceBuffer::Links => appended(&mut o.links, data, |l| band::offset_links(l, own)),
                            BounceBuffer::Hits => extend_from_bytes(&mut o.hits, data),
                            BounceBuffer::Surfaces => extend_from_bytes(&mut o.surfaces, data),
                            BounceBuffer::ShadowRays => {
                                appended(&mut o.shadow_rays, data, |r| band::offset_pixels(r, own))
                            }
                            BounceBuffer::Occluded => extend_from_bytes(&mut o.occluded, data),
                            BounceBuffer::Shadow => shadow_codes_into(&mut o.shadow, data),
                            BounceBuffer::Radiance => extend_from_bytes(&mut o.radiance, data),
                        }
                    }
                };
                if appended.is_err() {
                    no_room = Some((b, data.len()));
                }
            })?;
            if let Some((b, n)) = no_room {
                return Err(GpuError::OutOfMemory(format!(
                    "no host memory to read back {n} more bytes of the frame's {b} (a {}x{} frame)",
                    fb.width,
                    fb.band.first_row + fb.band.rows
                )));
            }
            if !fits {
                return Ok(counts);
            }
        }
        merge.add((own_hi - own_lo) as u32, &counts.bounces.iter().map(|c| c.rays as u32).collect::<Vec<_>>());
        if fb.banded {
            merge.primary_lights.push(BandMerge::own_light_counts(&counts.primary_starts));
            merge.bounce_lights.resize(counts.bounces.len(), Vec::new());
            for (d, (c, starts)) in counts.bounces.iter().zip(&counts.bounce_starts).enumerate() {
                let slots = starts.len() / 3;
                merge.bounce_lights[d].push(BandMerge::light_counts(&starts[..slots], c.shadow_rays as u32));
            }
        }
        Ok(counts)
    }

    /// The statistics of a frame read back whole (every band), from its G-buffer,
    /// occlusion results and lists' counts.
    fn frame_stats(&self, plan: &FramePlan, camera: &CameraRecord, counts: &Counts, out: &Frame) -> FrameStats {
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
        counts.fill(&mut stats);
        stats.occluded_shadow_rays = out.occluded.iter().filter(|&&o| o != 0).count() as u64;
        stats.stage_ms = self.stage_times(plan, &stats);
        stats
    }
}

/// Where a frame's bands go: back into a [`Frame`], or into a texture on the GPU.
enum Sink<'a> {
    Frame(&'a mut Frame),
    Texture(&'a wgpu::Texture),
}

/// Append `data` read as `T`s to `dst`, then `fix` the appended elements (a band's
/// indices made the frame's).
fn appended<T: bytemuck::Pod>(
    dst: &mut Vec<T>,
    data: &[u8],
    fix: impl FnOnce(&mut [T]),
) -> Result<(), TryReserveError> {
    let start = dst.len();
    extend_from_bytes(dst, data)?;
    fix(&mut dst[start..]);
    Ok(())
}

/// `SHADOW_*` codes read back as u32 words, appended to the frame's u8 codes.
fn shadow_codes_into(dst: &mut Vec<u8>, data: &[u8]) -> Result<(), TryReserveError> {
    dst.try_reserve(data.len() / 4)?;
    dst.extend(data.chunks_exact(4).map(|w| bytemuck::pod_read_unaligned::<u32>(w) as u8));
    Ok(())
}

impl Counts {
    /// The counts from the data of [`GpuBackend::count_parts`], in its order (`banded`:
    /// with the lists' light starts).
    fn parse<'a>(plan: &FramePlan, banded: bool, mut data: impl Iterator<Item = &'a [u8]>) -> Counts {
        let word = |d: Option<&[u8]>| d.map_or(0, |d| bytemuck::pod_read_unaligned::<u32>(&d[..4]) as usize);
        let rays = plan.produces(FrameBuffer::Rays);
        let shadow_rays = if rays { word(data.next()) } else { 0 };
        let mut bounces = Vec::with_capacity(plan.bounce_depth() as usize);
        for _ in 0..plan.bounce_depth() {
            let rays = word(data.next());
            let shadow_rays = word(data.next());
            let counters = data.next().map_or([0; 4], |d| bytemuck::pod_read_unaligned::<[u32; 4]>(&d[..16]));
            bounces.push(BounceCounts { rays, shadow_rays, counters });
        }
        let words = |d: Option<&[u8]>| d.map_or(Vec::new(), bytemuck::pod_collect_to_vec::<u8, u32>);
        let (mut primary_starts, mut bounce_starts) = (Vec::new(), Vec::new());
        if banded {
            if rays {
                primary_starts = words(data.next());
            }
            bounce_starts = bounces.iter().map(|_| words(data.next())).collect();
        }
        let own_shadow_rays = match banded && rays {
            true => BandMerge::own_light_counts(&primary_starts).iter().map(|&n| n as usize).sum(),
            false => shadow_rays,
        };
        Counts { shadow_rays, own_shadow_rays, bounces, primary_starts, bounce_starts }
    }

    /// Add the counts of another band of the frame (its light starts are the band's
    /// own, kept by [`BandMerge`], not summed).
    fn add(&mut self, band: &Counts) {
        self.shadow_rays += band.own_shadow_rays;
        self.own_shadow_rays += band.own_shadow_rays;
        self.bounces.resize(band.bounces.len().max(self.bounces.len()), BounceCounts::default());
        for (sum, c) in self.bounces.iter_mut().zip(&band.bounces) {
            sum.rays += c.rays;
            sum.shadow_rays += c.shadow_rays;
            sum.counters.iter_mut().zip(c.counters).for_each(|(s, n)| *s += n);
        }
    }

    /// The frame statistics the counts give: the rays per kind of the primary list and
    /// of each bounce depth, its hits and occluded shadow rays.
    fn fill(&self, stats: &mut FrameStats) {
        stats.rays_per_kind[RAY_KIND_SHADOW as usize] = self.shadow_rays as u64;
        stats.bounces = self
            .bounces
            .iter()
            .map(|c| {
                let mut rays_per_kind = [0; hyrt_core::formats::RAY_KIND_COUNT];
                rays_per_kind[RAY_KIND_REFLECTION as usize] = c.counters[COUNTER_REFLECTION] as u64;
                rays_per_kind[RAY_KIND_REFRACTION as usize] = c.counters[COUNTER_REFRACTION] as u64;
                rays_per_kind[RAY_KIND_SHADOW as usize] = c.shadow_rays as u64;
                BounceStats {
                    rays_per_kind,
                    hits: c.counters[COUNTER_HITS] as u64,
                    occluded_shadow_rays: c.counters[COUNTER_OCCLUDED] as u64,
                }
            })
            .collect();
    }
}

impl GpuBackend {
    /// Refuse a plan this device cannot run: tables that need more than
    /// [`MAX_PAGES`] pages of one storage binding, or more storage buffers per shader stage
    /// with their pages than the device allows, and bounces on a device with fewer storage
    /// buffers per shader stage than the bounce stages bind ([`BOUNCE_STORAGE_BUFFERS`]).
    /// An error, never a frame without them.
    fn check_supported(&self, scene: &PreparedScene, plan: &FramePlan) -> Result<(), GpuError> {
        let storage = self.ctx.limits.max_storage_buffers_per_shader_stage;
        if plan.runs(Stage::ShadowDenoise) && storage < DENOISED_SHADING_STORAGE_BUFFERS {
            return Err(GpuError::Limits(format!(
                "the shadow denoiser's channels make the shading stages bind {DENOISED_SHADING_STORAGE_BUFFERS} storage buffers per shader stage; this device allows {storage} (render with --no-denoise)"
            )));
        }
        if scene.levels.is_some() && storage < TWO_LEVEL_STORAGE_BUFFERS {
            return Err(GpuError::Limits(format!(
                "a scene with moving objects (a two-level BVH) binds {TWO_LEVEL_STORAGE_BUFFERS} storage buffers per shader stage to trace shadow rays; this device allows {storage}"
            )));
        }
        let binding = self.ctx.limits.max_storage_buffer_binding_size.min(self.ctx.limits.max_buffer_size);
        // The tables that grow with the triangles or the objects and the surface tables go
        // in pages of one binding each (`crate::paging`), up to MAX_PAGES; each further page
        // binds one more storage buffer in the stages that read it.
        let surface_words = scene.geometry.surface.layout().map(|l| l.bytes() / 4);
        let Some(pages) = TablePages::of_scene(scene, &self.ctx.limits) else {
            let word_page = 1u64 << word_page_shift(&self.ctx.limits);
            return Err(GpuError::Limits(match surface_words {
                None => "the scene's textures, texture coordinates and vertex colours need 2^32 words or more, past what a shader can index".to_string(),
                Some(words) if words.div_ceil(word_page) > MAX_PAGES as u64 => format!(
                    "the scene's textures, texture coordinates and vertex colours need {} bytes: more than {MAX_PAGES} pages of {word_page} words (one storage binding of {binding} bytes each)",
                    words * 4
                ),
                Some(_) => format!(
                    "the scene's world records, BVH, placements, objects, instances or lights (emissive triangles) need more than {MAX_PAGES} pages (of {} world records or BVH nodes, of {} objects, instances or lights: one storage binding of {binding} bytes each)",
                    1u64 << page_shift(&self.ctx.limits),
                    1u64 << object_page_shift(&self.ctx.limits)
                ),
            }));
        };
        let extra = pages.extra_bindings(&Table::ALL);
        let most = match (plan.bounce_depth() > 0, scene.geometry.triangles.has_references()) {
            (true, true) => BY_REFERENCE_BOUNCE_STORAGE_BUFFERS,
            (true, false) => BOUNCE_STORAGE_BUFFERS,
            (false, _) => TWO_LEVEL_STORAGE_BUFFERS.max(DENOISED_SHADING_STORAGE_BUFFERS),
        };
        if extra > 0 && most + extra > storage {
            return Err(GpuError::Limits(format!(
                "the scene's world records, BVH, per-object tables (placements, objects, instances, lights) and surface tables take {} pages on this device (one storage binding of {binding} bytes each), which with the frame's other tables bind up to {} storage buffers per shader stage; this device allows {storage}",
                extra + Table::ALL.len() as u32,
                most + extra
            )));
        }
        if scene.geometry.triangles.has_references()
            && plan.bounce_depth() > 0
            && storage < BY_REFERENCE_BOUNCE_STORAGE_BUFFERS
        {
            return Err(GpuError::Limits(format!(
                "reflection and refraction in a scene with objects by reference bind {BY_REFERENCE_BOUNCE_STORAGE_BUFFERS} storage buffers per shader stage (bounce_trace); this device allows {storage} (render with max depth 0)"
            )));
        }
        let bounces = self.ctx.limits.max_storage_buffers_per_shader_stage >= BOUNCE_STORAGE_BUFFERS;
        match (plan.bounce_depth(), bounces) {
            (d, false) if d > 0 => Err(GpuError::Limits(format!(
                "reflection and refraction bind {BOUNCE_STORAGE_BUFFERS} storage buffers per shader stage; this device allows {} (request more, or render with max depth 0)",
                self.ctx.limits.max_storage_buffers_per_shader_stage
            ))),
            _ => Ok(()),
        }
    }
}

/// The buffers of the frame's first readback (`first`: the counts come with them) or of its
/// second (the other stage outputs it holds). The first brings what every frame returns
/// ([`FrameBuffer::always_returned`]), the G-buffer and the primary occlusion results,
/// which the frame's statistics count (`covered_pixels`, `occluded_shadow_rays`) even where
/// the frame does not hold them ([`FrameOptions::keep_gbuffer`]; `Frame::end` empties
/// them then).
fn read_in(out: &Frame, first: bool) -> Vec<FrameBuffer> {
    let counted = |b: FrameBuffer| matches!(b, FrameBuffer::GBuffer | FrameBuffer::Occluded);
    let in_first = |b: FrameBuffer| b.always_returned() || counted(b);
    out.plan.buffers().filter(|&b| in_first(b) == first && (out.holds(b) || counted(b))).collect()
}

/// What the world tables of `scene` take on the device, table by table, as
/// [`crate::buffers::SceneBuffers::new`] uploads them: `(what, bytes)`, the bytes `u64::MAX`
/// where the mesh words would pass 2^32 words.
pub fn world_table_bytes(scene: &PreparedScene) -> Vec<(String, u64)> {
    let t = &scene.geometry.triangles;
    let stored = t.stored_records().len() as u64;
    let mut tables = vec![(
        format!("{stored} stored world triangles"),
        stored * std::mem::size_of::<hyrt_core::formats::TriangleRecord>() as u64,
    )];
    if t.has_references() {
        let objects = scene.geometry.objects.len() as u64;
        let placement = std::mem::size_of::<hyrt_core::formats::PlacementRecord>() as u64;
        tables.push((format!("placements of {objects} objects"), objects * placement));
        let words = t.mesh_word_count() as u64;
        let words = if words >= hyrt_core::formats::INVALID_ID as u64 { u64::MAX } else { words * 4 };
        tables.push(("shared meshes (positions, normals, triangles)".to_string(), words));
    }
    tables
}

/// Bytes of the tables [`SceneBuffers::new`] uploads for `scene`: the world tables
/// ([`world_table_bytes`]), their normals, the BVH (both levels), the objects, lights and
/// instances, and the surface tables; the environment's and ambient light's texels aside.
pub fn scene_table_bytes(scene: &PreparedScene) -> u64 {
    use hyrt_core::formats::{InstanceRecord, LightRecord, ObjectRecord};
    use std::mem::size_of;
    let g = &scene.geometry;
    let world: u64 = world_table_bytes(scene).iter().map(|(_, b)| *b).fold(0, u64::saturating_add);
    let normals = g.triangles.stored_records().len() as u64 * Table::Normals.record_bytes();
    let (nodes, slots) = crate::paging::bvh_counts(scene);
    let instances = scene.levels.as_ref().map_or(0, |l| l.instances.len());
    let slot_bytes = Table::LeafTriangles.record_bytes() + Table::PrimIndices.record_bytes();
    let bvh = (nodes as u64 * Table::Nodes.record_bytes() + slots as u64 * slot_bytes) as usize;
    let records = g.objects.len() * size_of::<ObjectRecord>()
        + (g.lights.len() + g.emitters.len()) * size_of::<LightRecord>()
        + instances * size_of::<InstanceRecord>();
    let surface = g.surface.layout().map_or(0, |l| l.bytes());
    [world, normals, bvh as u64, records as u64, surface].into_iter().fold(0, u64::saturating_add)
}

/// Storage buffers `bounce_trace` binds in a scene with objects by reference: its 13 of a
/// two-level scene, the placements and the mesh words. `GpuContext::new` asks for all the adapter has.
pub const BY_REFERENCE_BOUNCE_STORAGE_BUFFERS: u32 = 15;

/// Storage buffers `rt_shading` and `raster_shading` bind in a denoised frame: their eight
/// and the frame's visibility. WebGPU's default limit is 8; `GpuContext::new` asks for all
/// the adapter has.
pub const DENOISED_SHADING_STORAGE_BUFFERS: u32 = 9;

/// Storage buffers `shadow_rays` binds in a two-level scene: its eight and the instance
/// table. WebGPU's default limit is 8; `GpuContext::new` asks for all the adapter has.
pub const TWO_LEVEL_STORAGE_BUFFERS: u32 = 9;

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
        self.check_supported(scene, &plan)?;
        camera.validate().map_err(RenderError::InvalidCamera)?;
        frame.begin(&plan, options);
        band::check_host_memory(frame, camera, plan.lights())?;
        let counts = self.run_frame(scene, &plan, camera, options, &mut Sink::Frame(frame))?;
        frame.stats = self.frame_stats(&plan, camera, &counts, frame);
        (frame.width, frame.height) = (camera.width, camera.height);
        frame.end();
        Ok(())
    }
}

/// The refusal of a frame of the denoiser's temporal pass ([`FrameOptions::temporal`]) that
/// does not fit one band of storage bindings of `limit` bytes: the history is read at
/// reprojected rows of the whole previous frame, which bands do not have.
fn temporal_banded(camera: &CameraRecord, limit: u64) -> GpuError {
    GpuError::Limits(format!(
        "the denoiser's temporal pass (FrameOptions::temporal, --temporal) renders a frame in one band only, and a \
         {}x{} frame needs more than the {limit} bytes a storage binding holds: render it smaller, or without \
         --temporal (each frame denoised on its own)",
        camera.width, camera.height
    ))
}
