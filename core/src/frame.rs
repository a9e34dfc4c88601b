//! What a backend takes and gives: [`FrameOptions`] in, [`Frame`] out (every
//! stage's output, for `--dump` and conformance), with [`FrameStats`]; and the
//! [`Backend`] trait both backends implement.

use crate::bvh::two_level::{MoveError, TwoLevelBvh};
use crate::bvh::Bvh;
use crate::error::GpuError;
use crate::formats::INVALID_ID;
use crate::formats::{CameraRecord, GBufferTexel, HitRecord, RayRecord, SurfaceRecord, RAY_KIND_COUNT};
use crate::geometry::WorldGeometry;
use crate::kernels::bounce::MAX_DEPTH_LIMIT;
use crate::plan::{BounceBuffer, FrameBuffer, FramePlan, Skipped, Step};
use crate::scene::Scene;
use crate::stage::Stage;

/// The `SHADOW_*` codes of [`Frame::shadow`], defined in [`crate::formats`]; re-exported
/// here for the code that still names them by their old path.
pub use crate::formats::{SHADOW_LIT, SHADOW_NO_RAY, SHADOW_OCCLUDED};

/// A scene ready to render: world-space tables and the BVH over all of them,
/// built once and shared by every frame and by both backends.
///
/// A scene prepared with moving objects ([`PreparedScene::with_levels`]) also holds a
/// two-level BVH ([`TwoLevelBvh`]): its objects in object space move between frames
/// ([`PreparedScene::move_objects`]) without preparing the scene again. Then `bvh` is the
/// world-space level alone (the objects baked into world space), which a backend may
/// trace with its fastest traversal before the object-space instances.
#[derive(Clone, Debug)]
pub struct PreparedScene {
    pub geometry: WorldGeometry,
    /// The BVH over every traceable triangle, or over those baked into world space when
    /// `levels` is set.
    pub bvh: Bvh,
    /// The two levels when some object is traced in its own space (moving objects, meshes
    /// shared by several objects); `None` when `bvh` is the whole scene.
    pub levels: Option<TwoLevelBvh>,
    /// Time the `bvh_build` stage took, in milliseconds.
    pub bvh_build_ms: f64,
    /// Unique per prepared scene (clones share it: same content): backends that keep the scene's
    /// tables on a device key their caches by it. Fields are public for reading;
    /// build with [`PreparedScene::new`] so the id stays unique.
    id: u64,
    /// Bumped by every change made in place ([`PreparedScene::move_objects`],
    /// [`PreparedScene::update_lights`]); 0 as prepared.
    revision: u64,
    /// What each of the last [`CHANGE_LOG_LENGTH`] revisions changed, oldest first.
    changes: std::collections::VecDeque<(u64, SceneChanges)>,
}

/// Revisions whose changes a [`PreparedScene`] remembers: a device cache further behind
/// takes the whole scene again.
pub const CHANGE_LOG_LENGTH: usize = 64;

/// What changed in a prepared scene between two revisions ([`PreparedScene::changes_since`]):
/// what a backend holding the older revision on a device must write again.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SceneChanges {
    /// Objects whose triangles, normals, record (and instance) were rewritten, sorted.
    pub objects: Vec<u32>,
    /// The light table.
    pub lights: bool,
    /// Bottom levels refitted to a deformed mesh ([`PreparedScene::deform_mesh`]): their
    /// nodes and leaf triangles, at the same places, sorted.
    pub bottoms: Vec<u32>,
}

impl SceneChanges {
    fn merge(&mut self, other: &SceneChanges) {
        self.objects.extend_from_slice(&other.objects);
        self.objects.sort_unstable();
        self.objects.dedup();
        self.lights |= other.lights;
        self.bottoms.extend_from_slice(&other.bottoms);
        self.bottoms.sort_unstable();
        self.bottoms.dedup();
    }
}

/// Copy the levels' offset errors (one per object, [`TwoLevelBvh::offset_errors`]) into the
/// object records the stages read; objects that did not move keep the values they had.
fn take_offset_errors(geometry: &mut WorldGeometry, levels: &TwoLevelBvh) {
    for (o, e) in geometry.objects.iter_mut().zip(&levels.offset_errors) {
        o.offset_error = *e;
    }
}

/// A fresh [`PreparedScene`] id.
fn next_id() -> u64 {
    static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
    NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
}

impl PreparedScene {
    /// A prepared scene with a fresh id.
    pub fn new(geometry: WorldGeometry, bvh: Bvh, bvh_build_ms: f64) -> Self {
        PreparedScene {
            geometry,
            bvh,
            levels: None,
            bvh_build_ms,
            id: next_id(),
            revision: 0,
            changes: Default::default(),
        }
    }

    /// A prepared scene traced through two levels: `bvh` becomes a copy of the
    /// world-space level (empty when every object is an instance); without object-space
    /// instances it is [`PreparedScene::new`] with that level.
    pub fn with_levels(mut geometry: WorldGeometry, levels: TwoLevelBvh, bvh_build_ms: f64) -> Self {
        let bvh = levels.world_level().cloned().unwrap_or_default();
        take_offset_errors(&mut geometry, &levels);
        let levels = levels.has_object_space_instances().then_some(levels);
        PreparedScene { geometry, bvh, levels, bvh_build_ms, id: next_id(), revision: 0, changes: Default::default() }
    }

    /// The id device caches are keyed by. Mutating the public fields after a
    /// backend has seen the scene is not supported: prepare a new scene instead, or change
    /// it with [`PreparedScene::move_objects`] and [`PreparedScene::update_lights`], which
    /// keep the id and bump the [`PreparedScene::revision`].
    pub fn id(&self) -> u64 {
        self.id
    }

    /// How many in-place changes the scene has had (0 as prepared).
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// What changed after revision `since` (everything up to the current revision, merged),
    /// for a backend that holds revision `since` on a device and writes only that again;
    /// `None` when the log no longer reaches back that far (take the whole scene).
    pub fn changes_since(&self, since: u64) -> Option<SceneChanges> {
        if since > self.revision {
            return None;
        }
        let mut all = SceneChanges::default();
        let mut next = since + 1;
        for (revision, c) in self.changes.iter().filter(|(r, _)| *r > since) {
            if *revision != next {
                return None;
            }
            all.merge(c);
            next += 1;
        }
        (next == self.revision + 1).then_some(all)
    }

    /// Record one in-place change as a new revision.
    fn record(&mut self, change: SceneChanges) {
        self.revision += 1;
        self.changes.push_back((self.revision, change));
        if self.changes.len() > CHANGE_LOG_LENGTH {
            self.changes.pop_front();
        }
    }

    /// Take the scene's lights again after they changed (an animation moved one, or
    /// changed its colour): the light table is rewritten, a new revision (a new id when
    /// the number of lights changed).
    pub fn update_lights(&mut self, scene: &Scene) {
        let count = self.geometry.lights.len();
        self.geometry.lights = scene.lights.iter().map(crate::formats::LightRecord::from_light).collect();
        if self.geometry.lights.len() == count {
            self.record(SceneChanges { lights: true, ..SceneChanges::default() });
        } else {
            // Another number of lights: a new scene for every device cache.
            self.id = next_id();
        }
    }

    /// Move objects between frames: after the transforms (or render modes) of `objects`
    /// changed in `scene` (the scene this was prepared from), rewrite their world tables
    /// and their instances and rebuild the top level; bottom levels are untouched. The
    /// result equals preparing the changed scene again with the same moving objects.
    ///
    /// Fails, changing nothing, when an object was not prepared as moving (it is baked
    /// into world space; a scene prepared without levels has every object baked), does not
    /// exist, or its transform cannot be traced in object space ([`MoveError`]). A move is
    /// a new [`PreparedScene::revision`]; the id stays, so a device holding the scene
    /// writes only what moved ([`PreparedScene::changes_since`]).
    pub fn move_objects(&mut self, scene: &Scene, objects: &[u32]) -> Result<(), MoveError> {
        let Some(levels) = &mut self.levels else {
            return Err(match objects.first() {
                Some(&object) if (object as usize) < scene.objects.len() => MoveError::Baked { object },
                Some(&object) => MoveError::NoObject { object, objects: scene.objects.len() },
                None => return Ok(()),
            });
        };
        let moves = levels.moves(scene, objects)?;
        self.geometry.update_objects(scene, objects);
        levels.apply_moves(scene, &self.geometry, moves);
        take_offset_errors(&mut self.geometry, levels);
        let mut moved = objects.to_vec();
        moved.sort_unstable();
        moved.dedup();
        self.record(SceneChanges { objects: moved, ..SceneChanges::default() });
        Ok(())
    }

    /// A deforming mesh: after `scene.meshes[mesh]` got new vertex positions (or normals;
    /// the same triangles), rewrite the world tables of every object drawing it and refit
    /// its bottom level ([`TwoLevelBvh::deform_mesh`]); a new revision. Every object drawing
    /// the mesh must have been prepared as moving (else [`MoveError::Baked`], changing
    /// nothing). When triangles became degenerate or stopped being so, the levels are built
    /// again and the scene gets a new id.
    pub fn deform_mesh(&mut self, scene: &Scene, mesh: usize) -> Result<(), MoveError> {
        let users: Vec<u32> = scene.objects.iter().filter(|o| o.mesh == mesh).map(|o| o.id).collect();
        let moving = |o: u32| self.levels.as_ref().is_some_and(|l| l.in_object_space[o as usize]);
        if let Some(&object) = users.iter().find(|&&o| !moving(o)) {
            return Err(MoveError::Baked { object });
        }
        let Some(levels) = &mut self.levels else {
            return Ok(());
        };
        self.geometry.deform_mesh(scene, mesh);
        let rebuilt = levels.deform_mesh(scene, &self.geometry, mesh)?;
        take_offset_errors(&mut self.geometry, levels);
        if rebuilt {
            self.bvh = levels.world_level().cloned().unwrap_or_default();
            self.id = next_id();
        } else {
            let bottoms =
                levels.mesh_bottom.get(mesh).filter(|&&b| b != INVALID_ID).map(|&b| vec![b]).unwrap_or_default();
            self.record(SceneChanges { objects: users, bottoms, ..SceneChanges::default() });
        }
        Ok(())
    }
}

/// Per-frame settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameOptions {
    /// Composition weight of the ray-traced image in [0, 1] (paper 3.5):
    /// final = (1 - weight) * raster + weight * rt on ray-traced pixels.
    pub weight: f32,
    /// Return every stage's output in the [`Frame`] (for `--dump`, conformance).
    /// When false (the default: what a display loop needs), the frame holds only the
    /// final image, the G-buffer and the occlusion results
    /// ([`FrameBuffer::always_returned`]): the GPU backend then reads back one combined
    /// buffer per frame.
    pub stage_outputs: bool,
    /// The deepest bounce of reflection and refraction rays traced from ray-traced
    /// mirrors and glass ([`crate::kernels::bounce`]), at most [`MAX_DEPTH_LIMIT`];
    /// 0 traces none (the paper's frame: shadow rays only).
    pub max_depth: u32,
    /// Where `reconstruction` takes the primary hits' barycentrics from.
    pub barycentrics: PrimaryBarycentrics,
}

/// The barycentrics `reconstruction` rebuilds primary hit points from (paper eq. 1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum PrimaryBarycentrics {
    /// The raster's: interpolated at the pixel centre in the snapped triangle (vertices on
    /// a 1/256-pixel grid), so hit points carry the snapping error (about 7e-6 of the
    /// scene's diagonal on the teaser).
    #[default]
    Raster,
    /// The pixel's camera ray intersected with the triangle the raster found, by the
    /// watertight kernel ([`crate::kernels::reconstruction::reintersected_barycentrics`]):
    /// hit points as exact as a ray tracer's, visibility still the raster's. Where the ray
    /// misses that triangle (a pixel centre the snapped triangle covers and the exact one
    /// does not, at its edges) the raster's barycentrics are kept. Both backends,
    /// bit-identical (the GPU's `reconstruction` mirrors the camera ray and the test).
    Reintersected,
}

impl PrimaryBarycentrics {
    /// Lower-case name (CLI, reports).
    pub fn name(self) -> &'static str {
        match self {
            PrimaryBarycentrics::Raster => "raster",
            PrimaryBarycentrics::Reintersected => "reintersected",
        }
    }
}

impl Default for FrameOptions {
    /// Weight 1 (ray-traced objects shaded by the tracer alone), no stage outputs,
    /// reflection and refraction to [`crate::kernels::bounce::DEFAULT_MAX_DEPTH`]
    /// bounces (a scene without ray-traced mirrors or glass plans none; `max_depth: 0`
    /// gives the paper's frame, shadow rays only).
    fn default() -> Self {
        FrameOptions {
            weight: 1.0,
            stage_outputs: false,
            max_depth: crate::kernels::bounce::DEFAULT_MAX_DEPTH,
            barycentrics: PrimaryBarycentrics::Raster,
        }
    }
}

impl FrameOptions {
    /// The default options with every stage's output returned (`--dump`, tests).
    pub fn with_stage_outputs() -> Self {
        FrameOptions { stage_outputs: true, ..FrameOptions::default() }
    }

    /// Check the options: the weight is a number in [0, 1]. [`FramePlan::new`] calls
    /// this, so every backend validates options in one place.
    pub fn validate(&self) -> Result<(), RenderError> {
        if !(0.0..=1.0).contains(&self.weight) {
            return Err(RenderError::InvalidOptions(format!(
                "composition weight must be in [0, 1], got {}",
                self.weight
            )));
        }
        if self.max_depth > MAX_DEPTH_LIMIT {
            return Err(RenderError::InvalidOptions(format!(
                "max depth must be at most {MAX_DEPTH_LIMIT}, got {}",
                self.max_depth
            )));
        }
        Ok(())
    }
}

/// Why a frame could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("invalid frame options: {0}")]
    InvalidOptions(String),
    #[error("invalid camera: {0}")]
    InvalidCamera(String),
    /// The backend cannot run a stage the frame's plan needs.
    #[error("the {backend} backend cannot run {stage} yet: {why}")]
    Unsupported { backend: &'static str, stage: String, why: &'static str },
    /// A frame that does not fit in memory: refused before its buffers are allocated
    /// (its least need exceeds what the system has available), or an allocation of one of
    /// its buffers failed. `needed` is in bytes (`None` where an allocation failed whose
    /// size the error does not carry); `available` is what the system reported (`None`:
    /// unknown).
    #[error(
        "a {width}x{height} frame does not fit in memory on the {backend} backend: {what}{}{}",
        match needed { Some(n) => format!(": {n} bytes needed"), None => String::new() },
        match available { Some(a) => format!(", {a} bytes available"), None => String::new() }
    )]
    OutOfMemory {
        backend: &'static str,
        width: u32,
        height: u32,
        needed: Option<u64>,
        available: Option<u64>,
        what: String,
    },
    /// The GPU backend's device failed: no adapter, device lost, out of memory, a
    /// readback that failed, a frame past the device's limits. Typed, so a caller can
    /// react to the kind (fall back to the CPU backend on a lost device, say).
    #[error(transparent)]
    Gpu(#[from] GpuError),
}

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
}

impl FrameStats {
    /// Time of one stage, if it ran: the sum over its depths.
    pub fn ms(&self, stage: Stage) -> Option<f64> {
        let mut times = self.stage_ms.iter().filter(|s| s.stage == stage).map(|s| s.ms).peekable();
        times.peek().is_some().then(|| times.sum())
    }
    /// Sum of the frame's stages.
    pub fn frame_ms(&self) -> f64 {
        self.stage_ms.iter().map(|s| s.ms).sum()
    }
}

/// Every stage's output for one frame. Images are linear RGBA, row-major, row 0 on top.
#[derive(Clone, Debug, Default)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// `visibility_raster`: one texel per pixel.
    pub gbuffer: Vec<GBufferTexel>,
    /// `reconstruction`: one record per pixel.
    pub surfaces: Vec<SurfaceRecord>,
    /// `compaction`: the shadow-ray list, light-major then pixel order.
    pub rays: Vec<RayRecord>,
    /// `shadow_rays`: one per ray, 1 = occluded, 0 = reached the light.
    pub occluded: Vec<u32>,
    /// Per pixel and light (`(y * width + x) * lights + light`): `SHADOW_*`.
    pub shadow: Vec<u8>,
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
    /// ([`FrameOptions::stage_outputs`] false and not [`FrameBuffer::always_returned`]).
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
        self.plan.produces(buffer) && (self.stage_outputs || buffer.always_returned())
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
