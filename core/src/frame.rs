//! What a backend takes and gives: [`FrameOptions`] in, [`Frame`] out (every
//! stage's output, for `--dump` and conformance), with [`FrameStats`]; and the
//! [`Backend`] trait both backends implement.

use crate::formats::{CameraRecord, GBufferTexel, HitRecord, RayRecord, SurfaceRecord, RAY_KIND_COUNT};
use crate::plan::{BounceBuffer, FrameBuffer, FramePlan, Skipped, Step};
use crate::stage::Stage;

// What a backend takes: defined below the plan, which is made from the prepared scene
// and the options, and with the other errors (`crate::error`); re-exported here beside
// what a backend gives.
pub use crate::error::RenderError;
pub use crate::options::{FrameOptions, PrimaryBarycentrics, DEFAULT_AO_RADIUS_FRACTION, DEFAULT_SHADOW_SAMPLES};
pub use crate::prepared::{FrameLighting, PreparedScene, SceneChanges, CHANGE_LOG_LENGTH};

/// The `SHADOW_*` codes of [`Frame::shadow`], defined in [`crate::formats`]; re-exported
/// here for the code that still names them by their old path.
pub use crate::formats::{SHADOW_LIT, SHADOW_NO_RAY, SHADOW_OCCLUDED};

/// Milliseconds one stage took, and the work it did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageTime {
    pub stage: Stage,
    /// The bounce depth the step worked on (0: the primary hits).
    pub depth: u32,
    pub ms: f64,
    pub work: StageWork,
}

impl StageTime {
    /// The step's label: the stage name, with `{depth}` for a bounce step.
    pub fn label(&self) -> String {
        self.stage.label_at(self.depth)
    }
}

/// The work one stage did in a frame: the pixels it wrote or shaded, and the rays
/// it made or traced, per `RAY_KIND_*`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StageWork {
    /// Pixels the stage produced a result for: every pixel for `visibility_raster`
    /// and `composition`, the covered ones for `reconstruction`, the shaded ones for
    /// the shading stages.
    pub pixels: u64,
    /// Rays `compaction` listed or `shadow_rays` traced, per `RAY_KIND_*`.
    pub rays: [u64; RAY_KIND_COUNT],
}

impl StageWork {
    /// The work of `step` in a frame with these (complete) statistics.
    pub fn of(step: Step, stats: &FrameStats) -> StageWork {
        let bounce = |d: u32| stats.bounces.get(d as usize - 1).copied().unwrap_or_default();
        let pixels = match step {
            Step::VisibilityRaster | Step::Composition(_) => stats.width as u64 * stats.height as u64,
            Step::Reconstruction => stats.covered_pixels,
            Step::RtShading { .. } => stats.ray_traced_pixels,
            Step::RasterShading { shade_ray_traced } => {
                stats.raster_pixels + if shade_ray_traced { stats.ray_traced_pixels } else { 0 }
            }
            _ => 0,
        };
        let rays = match step {
            Step::Compaction | Step::ShadowRays => stats.rays_per_kind,
            Step::SecondaryRays { depth } | Step::BounceTrace { depth } | Step::BounceShading { depth, .. } => {
                let mut r = bounce(depth).rays_per_kind;
                r[crate::formats::RAY_KIND_SHADOW as usize] = 0;
                r
            }
            Step::BounceCompaction { depth } | Step::BounceShadowRays { depth } => {
                let mut r = [0; RAY_KIND_COUNT];
                r[crate::formats::RAY_KIND_SHADOW as usize] =
                    bounce(depth).rays_per_kind[crate::formats::RAY_KIND_SHADOW as usize];
                r
            }
            _ => [0; RAY_KIND_COUNT],
        };
        StageWork { pixels, rays }
    }
}

/// Counts of one bounce depth.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BounceStats {
    /// Rays of the depth per `RAY_KIND_*`: its reflection and refraction rays, and the
    /// shadow rays from the surfaces they hit.
    pub rays_per_kind: [u64; RAY_KIND_COUNT],
    /// Secondary rays that hit a surface (the rest left the scene and see the environment).
    pub hits: u64,
    /// Its shadow rays that found an occluder.
    pub occluded_shadow_rays: u64,
}

/// Counts and times of one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameStats {
    pub width: u32,
    pub height: u32,
    /// Pixels with a primary hit (any object).
    pub covered_pixels: u64,
    /// Pixels whose primary hit is a ray-traced object: the paper's "valid rays" (Table 2).
    pub ray_traced_pixels: u64,
    /// Pixels whose primary hit is a rasterized object.
    pub raster_pixels: u64,
    /// Rays in the ray list, per `RAY_KIND_*`.
    pub rays_per_kind: [u64; RAY_KIND_COUNT],
    /// Shadow rays that found an occluder.
    pub occluded_shadow_rays: u64,
    /// Per bounce depth (index `d - 1`), what it traced; empty when the plan has no bounce.
    pub bounces: Vec<BounceStats>,
    /// Worker threads the backend used.
    pub threads: usize,
    /// Milliseconds and work per stage that ran, in execution order: the frame's
    /// stages only (`bvh_build` runs once per scene: [`PreparedScene::bvh_build_ms`]).
    pub stage_ms: Vec<StageTime>,
    /// The stages the frame's plan left out, and why.
    pub skipped: Vec<Skipped>,
    /// How the backend ran the plan. With [`Executor::Fused`], `stage_ms` holds
    /// `visibility_raster`'s setup and binning alone, then each bounce step (depth above
    /// 0) where the plan traces bounces, and its tiles (depth test and resolve) and every
    /// other step ran in the tiles, timed together in `fused_ms`.
    pub executor: Executor,
    /// Milliseconds of the fused executor's tile pass ([`Executor::Fused`]): each
    /// raster tile's depth test and resolve, and every step of the plan after
    /// `visibility_raster` on its pixels, tile by tile; with bounces also the gathering of
    /// the bouncing pixels the tiles deferred and their `rt_shading` and `composition`
    /// after the bounce steps. Zero for a staged frame.
    pub fused_ms: f64,
}

/// How a backend runs a frame's plan ([`crate::plan::FramePlan`]): both run the same
/// stages' kernels and give the same bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Executor {
    /// Stage after stage over whole-image buffers, each stage timed: the reference, and the
    /// only executor that can return every stage's output ([`FrameOptions::stage_outputs`],
    /// `--dump`, conformance, the viewer's stage views). The GPU backend's executor.
    #[default]
    Staged,
    /// The CPU backend's fused, tiled frame: after `visibility_raster`, each screen tile runs
    /// reconstruction, shadow-ray generation and tracing, shading and composition while its
    /// data is in cache, with tile-local scratch instead of whole-image buffers. It returns
    /// the final image, and the G-buffer where the frame asks for it
    /// ([`FrameOptions::keep_gbuffer`]: otherwise the G-buffer lives in each raster tile's
    /// scratch only); it runs frames without stage outputs. Where the frame traces bounces,
    /// the tiles defer the pixels that bounce, whose rays are traced over all tiles at
    /// once after the raster, and finish them then.
    Fused,
}

impl Executor {
    /// Lower-case name (CLI, reports).
    pub fn name(self) -> &'static str {
        match self {
            Executor::Staged => "staged",
            Executor::Fused => "fused",
        }
    }
}

impl FrameStats {
    /// Time of one stage, if it ran: the sum over its depths.
    pub fn ms(&self, stage: Stage) -> Option<f64> {
        let mut times = self.stage_ms.iter().filter(|s| s.stage == stage).map(|s| s.ms).peekable();
        times.peek().is_some().then(|| times.sum())
    }
    /// Sum of the frame's stages (and of the fused executor's tiles).
    pub fn frame_ms(&self) -> f64 {
        self.stage_ms.iter().map(|s| s.ms).sum::<f64>() + self.fused_ms
    }
}

/// Every stage's output for one frame. Images are linear RGBA, row-major, row 0 on top.
#[derive(Clone, Debug, Default)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// `visibility_raster`: one texel per pixel; empty unless the frame was asked for it
    /// ([`FrameOptions::keep_gbuffer`] or [`FrameOptions::stage_outputs`]).
    pub gbuffer: Vec<GBufferTexel>,
    /// `reconstruction`: one record per pixel.
    pub surfaces: Vec<SurfaceRecord>,
    /// `compaction`: the shadow-ray list, light-major then pixel order.
    pub rays: Vec<RayRecord>,
    /// `shadow_rays`: one per ray, 1 = occluded, 0 = reached the light.
    pub occluded: Vec<u32>,
    /// Per pixel and light (`(y * width + x) * lights + light`): `SHADOW_*`. With area
    /// lights or ambient occlusion, per pixel and mask slot
    /// ([`crate::kernels::soft_shadow`]).
    pub shadow: Vec<u8>,
    /// `shadow_denoise`: per pixel, the filtered visibility of each area light, then the
    /// filtered ambient occlusion ([`crate::kernels::denoise::channel_count`] per pixel).
    pub visibility: Vec<f32>,
    /// `raster_shading`: rasterized objects (and ray-traced ones when weight < 1).
    pub raster: Vec<[f32; 4]>,
    /// `rt_shading`: ray-traced objects only; alpha 1 where shaded, 0 elsewhere.
    pub rt: Vec<[f32; 4]>,
    /// `composition`: the final image.
    pub final_image: Vec<[f32; 4]>,
    /// The bounce buffers, index `depth - 1` (a frame keeps the allocations of deeper
    /// levels than its plan has for later frames; [`Frame::buffer`] says what it holds).
    pub bounces: Vec<BounceBuffers>,
    pub stats: FrameStats,
    /// The plan the frame ran: which stages ran, which buffers exist.
    pub plan: FramePlan,
    /// The frame holds every buffer its plan produced ([`FrameOptions::stage_outputs`]),
    /// not only those a display loop needs.
    pub stage_outputs: bool,
    /// The frame holds the G-buffer ([`FrameOptions::keep_gbuffer`]) even without stage
    /// outputs. Without either, `gbuffer` is empty (the CPU's fused executor never writes
    /// it whole-image then).
    pub keep_gbuffer: bool,
}

/// The buffers of one bounce depth `d` ([`BounceBuffer`] says what each holds).
#[derive(Clone, Debug, Default)]
pub struct BounceBuffers {
    /// `secondary_rays`: the reflection and refraction rays of depth `d`.
    pub rays: Vec<RayRecord>,
    /// `secondary_rays`: per parent of depth `d - 1`, `[reflection, refraction]` child
    /// indices into `rays` (`INVALID_ID`: no ray).
    pub links: Vec<[u32; 2]>,
    /// `bounce_trace`: the closest hit of each ray.
    pub hits: Vec<HitRecord>,
    /// `bounce_trace`: the surface each ray hit.
    pub surfaces: Vec<SurfaceRecord>,
    /// `compaction`: the shadow rays from `surfaces`.
    pub shadow_rays: Vec<RayRecord>,
    /// `shadow_rays`: one per shadow ray, 1 = occluded.
    pub occluded: Vec<u32>,
    /// `shadow_rays`: per (ray, light), `ray * lights + light`: `SHADOW_*`.
    pub shadow: Vec<u8>,
    /// `bounce_shading`: the radiance each ray brings back (alpha 1).
    pub radiance: Vec<[f32; 4]>,
}

impl BounceBuffers {
    /// Empty `buffer`, keeping its allocation.
    fn clear(&mut self, buffer: BounceBuffer) {
        match buffer {
            BounceBuffer::Rays => self.rays.clear(),
            BounceBuffer::Links => self.links.clear(),
            BounceBuffer::Hits => self.hits.clear(),
            BounceBuffer::Surfaces => self.surfaces.clear(),
            BounceBuffer::ShadowRays => self.shadow_rays.clear(),
            BounceBuffer::Occluded => self.occluded.clear(),
            BounceBuffer::Shadow => self.shadow.clear(),
            BounceBuffer::Radiance => self.radiance.clear(),
        }
    }

    fn view(&self, buffer: BounceBuffer) -> BufferView<'_> {
        match buffer {
            BounceBuffer::Rays => BufferView::Rays(&self.rays),
            BounceBuffer::Links => BufferView::Links(&self.links),
            BounceBuffer::Hits => BufferView::Hits(&self.hits),
            BounceBuffer::Surfaces => BufferView::Surfaces(&self.surfaces),
            BounceBuffer::ShadowRays => BufferView::Rays(&self.shadow_rays),
            BounceBuffer::Occluded => BufferView::Words(&self.occluded),
            BounceBuffer::Shadow => BufferView::Codes(&self.shadow),
            BounceBuffer::Radiance => BufferView::Image(&self.radiance),
        }
    }
}

/// One frame buffer's contents, borrowed from a [`Frame`].
#[derive(Clone, Copy, Debug)]
pub enum BufferView<'a> {
    GBuffer(&'a [GBufferTexel]),
    Surfaces(&'a [SurfaceRecord]),
    Rays(&'a [RayRecord]),
    /// `occluded`: one word per ray.
    Words(&'a [u32]),
    /// `shadow`: one `SHADOW_*` code per (pixel, light).
    Codes(&'a [u8]),
    /// `visibility`: f32 channels per pixel.
    Values(&'a [f32]),
    /// `rt`, `raster`, `final`: linear RGBA per pixel; a bounce's radiance per ray.
    Image(&'a [[f32; 4]]),
    /// A bounce's closest hits.
    Hits(&'a [HitRecord]),
    /// A bounce's links from parents to children.
    Links(&'a [[u32; 2]]),
}

impl Frame {
    /// The contents of `buffer`, or `None` when the frame does not hold it: its stage
    /// did not run, or the backend returned only what a display loop needs
    /// ([`FrameOptions::returns`] false: no stage outputs, and not the final image or a
    /// G-buffer [`FrameOptions::keep_gbuffer`] asked for).
    pub fn buffer(&self, buffer: FrameBuffer) -> Option<BufferView<'_>> {
        if !self.holds(buffer) {
            return None;
        }
        Some(match buffer {
            FrameBuffer::GBuffer => BufferView::GBuffer(&self.gbuffer),
            FrameBuffer::Surfaces => BufferView::Surfaces(&self.surfaces),
            FrameBuffer::Rays => BufferView::Rays(&self.rays),
            FrameBuffer::Occluded => BufferView::Words(&self.occluded),
            FrameBuffer::Shadow => BufferView::Codes(&self.shadow),
            FrameBuffer::Visibility => BufferView::Values(&self.visibility),
            FrameBuffer::Rt => BufferView::Image(&self.rt),
            FrameBuffer::Raster => BufferView::Image(&self.raster),
            FrameBuffer::Final => BufferView::Image(&self.final_image),
            FrameBuffer::Bounce { buffer, depth } => self.bounces[depth as usize - 1].view(buffer),
        })
    }

    /// The final image as 8-bit sRGB RGBA, row 0 on top, 4 bytes per pixel: what a
    /// window or a PNG file shows ([`crate::kernels::shading::rgba_to_srgb8`]).
    pub fn final_srgb8(&self) -> Vec<u8> {
        self.final_image.iter().flat_map(|&p| crate::kernels::shading::rgba_to_srgb8(p)).collect()
    }

    /// True if the frame holds `buffer` (see [`Frame::buffer`]).
    pub fn holds(&self, buffer: FrameBuffer) -> bool {
        let options =
            FrameOptions { stage_outputs: self.stage_outputs, keep_gbuffer: self.keep_gbuffer, ..Default::default() };
        self.plan.produces(buffer) && options.returns(buffer)
    }

    /// The buffers the frame holds, in stage order ([`FramePlan::buffers`]).
    pub fn buffers(&self) -> impl Iterator<Item = FrameBuffer> + '_ {
        self.plan.buffers().filter(|&b| self.holds(b))
    }

    /// The buffers of bounce `depth` (1-based), grown on first use.
    pub fn bounce_mut(&mut self, depth: u32) -> &mut BounceBuffers {
        let i = depth as usize - 1;
        if self.bounces.len() <= i {
            self.bounces.resize_with(i + 1, BounceBuffers::default);
        }
        &mut self.bounces[i]
    }

    /// Record the plan a backend is about to run for this frame.
    pub fn begin(&mut self, plan: &FramePlan, options: &FrameOptions) {
        self.plan.clone_from(plan);
        self.stage_outputs = options.stage_outputs;
        self.keep_gbuffer = options.keep_gbuffer;
    }

    /// Empty every buffer the frame does not hold (keeping its allocation for a later
    /// frame that needs it). Backends call this when a frame is done: a skipped
    /// stage's buffer is absent, not zero-filled.
    pub fn end(&mut self) {
        for b in FrameBuffer::ALL {
            if !self.holds(b) {
                self.clear(b);
            }
        }
        for i in 0..self.bounces.len() {
            for b in BounceBuffer::ALL {
                if !self.holds(b.at(i as u32 + 1)) {
                    self.bounces[i].clear(b);
                }
            }
        }
    }

    /// Empty `buffer`, keeping its allocation (a backend that appends to the frame's
    /// buffers, as the GPU backend does band by band, starts from empty ones).
    pub fn clear(&mut self, buffer: FrameBuffer) {
        match buffer {
            FrameBuffer::GBuffer => self.gbuffer.clear(),
            FrameBuffer::Surfaces => self.surfaces.clear(),
            FrameBuffer::Rays => self.rays.clear(),
            FrameBuffer::Occluded => self.occluded.clear(),
            FrameBuffer::Shadow => self.shadow.clear(),
            FrameBuffer::Visibility => self.visibility.clear(),
            FrameBuffer::Rt => self.rt.clear(),
            FrameBuffer::Raster => self.raster.clear(),
            FrameBuffer::Final => self.final_image.clear(),
            FrameBuffer::Bounce { buffer, depth } => self.bounce_mut(depth).clear(buffer),
        }
    }
}

/// A renderer of hybrid frames. Both backends implement it over the same
/// [`PreparedScene`] and formats, so their outputs compare stage by stage.
pub trait Backend {
    /// Short name for reports ("cpu", "gpu").
    fn name(&self) -> &str;
    /// Render one frame of `scene` seen by `camera` into `frame`, reusing its
    /// buffers: a frame of the same size renders without allocating. Every field of
    /// `frame` is overwritten; the buffers of stages the frame's plan skips are
    /// emptied (absent, see [`Frame::buffer`]).
    fn render_into(
        &mut self,
        scene: &PreparedScene,
        camera: &CameraRecord,
        options: &FrameOptions,
        frame: &mut Frame,
    ) -> Result<(), RenderError>;

    /// Render one frame into new buffers.
    fn render(
        &mut self,
        scene: &PreparedScene,
        camera: &CameraRecord,
        options: &FrameOptions,
    ) -> Result<Frame, RenderError> {
        let mut frame = Frame::default();
        self.render_into(scene, camera, options, &mut frame)?;
        Ok(frame)
    }
}
