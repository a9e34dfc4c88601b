//! [`CpuBackend`]: runs the stages in order on a rayon pool and times each.

use std::collections::TryReserveError;
use std::time::Instant;

use glam::Vec3;
use hyrt_core::bvh::{BvhPreset, ClosestHit};
use hyrt_core::formats::{CameraRecord, RayRecord, SurfaceRecord, RAY_KIND_COUNT, RAY_KIND_SHADOW};
use hyrt_core::frame::{
    Backend, BounceBuffers, BounceStats, Executor, Frame, FrameLighting, FrameOptions, FrameStats, PreparedScene,
    PrimaryBarycentrics, RenderError, StageTime, StageWork,
};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::denoise::channel_count;
use hyrt_core::kernels::soft_shadow::{FilteredVisibility, Slots};
use hyrt_core::kernels::texture::Materials;
use hyrt_core::plan::{BounceBuffer, FrameBuffer, FramePlan, Step};

use rayon::prelude::*;

use crate::{
    bounce_shading::{bounce_shading_into, Children},
    bounce_trace::bounce_trace_into,
    compaction::{
        active_pairs_into, compaction_slots_into, pair_ray, shadow_mask_into, shadow_mask_of_pairs_into,
        CompactionScratch,
    },
    composition::composition_into,
    fused::{fused_frame, shade_deferred, Deferred, FusedSteps},
    memory,
    raster_shading::{raster_shading_into, Primary},
    reconstruction::{normal_mapping_into, reconstruction_into, reconstruction_reintersected_into},
    rt_shading::{rt_shading_bouncing_into, rt_shading_into, BouncingShading, FirstBounce},
    secondary_rays::{secondary_rays_into, Parents},
    shadow_denoise::{shadow_denoise_into, DenoiseScratch, Temporal, TemporalHistory},
    shadow_rays::{shadow_rays_in_object_space, shadow_rays_of_pairs_into, shadow_rays_with},
    traversal::Traversal,
    visibility_raster::visibility_raster_into,
};

/// The CPU backend. Owns a rayon pool so that thread counts are explicit and a
/// frame never depends on whatever global pool the caller configured.
pub struct CpuBackend {
    pool: rayon::ThreadPool,
    /// Stage buffers that are not part of a [`Frame`], kept between frames.
    scratch: CompactionScratch,
    /// `shadow_denoise`'s ping-pong buffer and tile flags, kept between frames.
    denoise: DenoiseScratch,
    /// What the last denoised frame left for the next one's temporal pass.
    history: TemporalHistory,
    /// `bounce_trace`'s closest hits before they become records, kept between frames.
    closest: Vec<Option<ClosestHit>>,
    /// The fused frame's bouncing pixels, kept between frames.
    deferred: Deferred,
    /// How `shadow_rays` and `bounce_compaction`'s shadow rays trace (any hit; SIMD packets
    /// by default, scalar for comparisons).
    shadow_traversal: Traversal,
    /// How `bounce_trace` traces (closest hit; single rays through the wide tree by default).
    bounce_traversal: Traversal,
    /// The executor of frames it can run ([`Executor::Fused`] by default).
    executor: Executor,
}

impl CpuBackend {
    /// A backend with `threads` worker threads (`None`: one per core).
    pub fn new(threads: Option<usize>) -> Self {
        let mut b = rayon::ThreadPoolBuilder::new().thread_name(|i| format!("hyrt-cpu-{i}"));
        if let Some(n) = threads {
            b = b.num_threads(n.max(1));
        }
        CpuBackend {
            pool: b.build().expect("rayon thread pool"),
            scratch: CompactionScratch::default(),
            denoise: DenoiseScratch::default(),
            history: TemporalHistory::default(),
            closest: Vec::new(),
            deferred: Deferred::default(),
            shadow_traversal: Traversal::simd(),
            bounce_traversal: Traversal::for_bounces(),
            executor: Executor::Fused,
        }
    }

    /// Run frames with `executor` from now on. [`Executor::Fused`] (the default) runs the
    /// fused tiles ([`crate::fused`]) wherever a frame allows it (no stage outputs: every
    /// frame that returns only its image, and its G-buffer if asked) and the staged loop
    /// elsewhere; [`Executor::Staged`] runs every frame
    /// stage by stage (per-stage times, for Table 2 and before/after comparisons). Both
    /// give the same frame; [`FrameStats::executor`] says which ran.
    pub fn set_executor(&mut self, executor: Executor) {
        self.executor = executor;
    }

    /// The executor set by [`CpuBackend::set_executor`].
    pub fn executor(&self) -> Executor {
        self.executor
    }

    /// The executor a frame of `plan` with `options` runs on.
    pub fn executor_for(&self, plan: &FramePlan, options: &FrameOptions) -> Executor {
        self.fused_steps(plan, options).map_or(Executor::Staged, |_| Executor::Fused)
    }

    /// What the fused tiles run of `plan` where the frame runs fused ([`Self::executor_for`]).
    /// Frames with stochastic rays (area lights, ambient occlusion) run staged: the fused
    /// tiles trace one shadow ray per light.
    fn fused_steps(&self, plan: &FramePlan, options: &FrameOptions) -> Option<FusedSteps> {
        match self.executor {
            Executor::Fused if !options.stage_outputs && !plan.stochastic() => Some(FusedSteps::of(plan)),
            _ => None,
        }
    }

    /// Trace shadow rays with `traversal` from now on ([`Traversal::simd`] by default;
    /// [`Traversal::Scalar`] is the reference path, for before/after comparisons). Both
    /// give the same frame.
    pub fn set_shadow_traversal(&mut self, traversal: Traversal) {
        self.shadow_traversal = traversal;
    }

    /// The traversal `shadow_rays` uses.
    pub fn shadow_traversal(&self) -> Traversal {
        self.shadow_traversal
    }

    /// Trace the reflection and refraction rays of `bounce_trace` with `traversal` from now
    /// on ([`Traversal::for_bounces`] by default; [`Traversal::Scalar`] is the reference).
    /// All give the same frame.
    pub fn set_bounce_traversal(&mut self, traversal: Traversal) {
        self.bounce_traversal = traversal;
    }

    /// The traversal `bounce_trace` uses.
    pub fn bounce_traversal(&self) -> Traversal {
        self.bounce_traversal
    }

    /// Number of worker threads.
    pub fn threads(&self) -> usize {
        self.pool.current_num_threads()
    }

    /// Build the world tables and run the `bvh_build` stage on this backend's pool.
    pub fn prepare(&self, geometry: WorldGeometry, preset: BvhPreset) -> PreparedScene {
        self.pool.install(|| crate::bvh_build::prepare(geometry, preset))
    }
}

/// `compaction` of one list of surfaces: its shadow-ray list into `rays` when the frame
/// returns it, else only the active pairs (in `scratch`, which `trace_list` reads).
fn compact_list(
    surfaces: &[SurfaceRecord],
    slots: &Slots,
    scratch: &mut CompactionScratch,
    rays: Option<&mut Vec<RayRecord>>,
) -> Result<(), std::collections::TryReserveError> {
    match rays {
        Some(rays) => compaction_slots_into(surfaces, slots, scratch, rays),
        None => active_pairs_into(surfaces, slots, scratch),
    }
}

/// `shadow_rays` of one list: the list `compact_list` wrote, or the rays of its active
/// pairs made as they are traced; the occlusion results and the shadow mask into `out`.
/// `image_width` where the surfaces are an image's pixels (depth 0: the generated rays
/// are traced in pixel tiles). The number of rays.
///
/// The bounces' shadow rays take the frame's shadow traversal (packets) too. Tried and
/// not kept: tracing them one ray at a time (`Traversal::for_bounces`), since their origins
/// are the hits of reflection rays (one thread, `hyrt render --frames 9 --shading paper`,
/// the two alternated six times in one binary, medians of the pair ratios): the teaser's
/// `shadow_rays{2}` to `{4}` took 0.64 to 0.76 of the packets' time but `shadow_rays{1}`
/// 0.94 (0.74 to 1.02), and the default scene's flat mirror, whose reflections stay
/// coherent, 1.46 at depth 1 and 1.28 at depth 2: a choice per list would need a measure
/// of the list's coherence.
#[allow(clippy::too_many_arguments)]
fn trace_list(
    scene: &PreparedScene,
    surfaces: &[SurfaceRecord],
    slots: &Slots,
    scratch: &CompactionScratch,
    list: Option<&[RayRecord]>,
    image_width: Option<u32>,
    traversal: Traversal,
    (occluded, shadow): (&mut Vec<u32>, &mut Vec<u8>),
) -> usize {
    let (bvh, g) = (&scene.bvh, &scene.geometry);
    let lights = slots.len();
    match list {
        Some(rays) => {
            shadow_rays_with(bvh, g, rays, traversal, occluded);
            if let Some(levels) = &scene.levels {
                shadow_rays_in_object_space(levels, g, |i| rays[i], traversal, occluded);
            }
            shadow_mask_into(rays, occluded, surfaces.len(), lights, shadow);
        }
        None => {
            shadow_rays_of_pairs_into(bvh, g, surfaces, slots, &scratch.active, image_width, traversal, occluded);
            if let Some(levels) = &scene.levels {
                let ray = |i: usize| pair_ray(surfaces, slots, scratch.active[i]);
                shadow_rays_in_object_space(levels, g, ray, traversal, occluded);
            }
            shadow_mask_of_pairs_into(&scratch.active, occluded, surfaces.len(), lights, shadow);
        }
    }
    occluded.len()
}

/// Rays per `RAY_KIND_*` in a list.
fn rays_per_kind(a: &[RayRecord]) -> [u64; RAY_KIND_COUNT] {
    a.par_iter()
        .with_min_len(16384)
        .fold(
            || [0u64; RAY_KIND_COUNT],
            |mut k, r| {
                k[r.kind as usize] += 1;
                k
            },
        )
        .reduce(|| [0u64; RAY_KIND_COUNT], |a, b| std::array::from_fn(|i| a[i] + b[i]))
}

/// Per bounce depth of `bounces`, what it traced: its rays per kind with `shadow_rays[d - 1]`
/// shadow rays, its hits and its occluded shadow rays.
fn bounce_stats(bounces: &[BounceBuffers], shadow_rays: &[usize]) -> Vec<BounceStats> {
    bounces
        .iter()
        .zip(shadow_rays)
        .map(|(b, &shadow)| BounceStats {
            rays_per_kind: {
                let mut k = rays_per_kind(&b.rays);
                k[RAY_KIND_SHADOW as usize] = shadow as u64;
                k
            },
            hits: b.hits.par_iter().filter(|h| h.is_hit()).count() as u64,
            occluded_shadow_rays: b.occluded.par_iter().filter(|&&o| o != 0).count() as u64,
        })
        .collect()
}

/// The error of a frame of `width` x `height` whose buffer `what` the allocator refused.
fn oom(width: u32, height: u32, what: &'static str) -> impl Fn(TryReserveError) -> RenderError {
    move |e| memory::out_of_memory(width, height, None, memory::available_bytes(), &format!("{what} ({e})"))
}

/// What the bounce steps read besides their buffers, the same for both executors.
struct BounceContext<'a> {
    scene: &'a PreparedScene,
    /// The frame's lights and ambient light ([`PreparedScene::frame_lighting`]).
    lighting: &'a FrameLighting<'a>,
    /// Their shadow-mask slots.
    slots: &'a Slots<'a>,
    materials: &'a Materials<'a>,
    /// How shadow rays trace (any hit).
    traversal: Traversal,
    /// How `bounce_trace` traces (closest hit).
    bounce_traversal: Traversal,
    /// Per depth (0: the primary hits'), whether the frame writes its shadow-ray list.
    lists: &'a [bool],
    /// The frame's width and height (its out-of-memory errors).
    size: (u32, u32),
}

/// One bounce step of a plan (`secondary_rays` to `bounce_shading`, at a depth above 0)
/// over the frame's bounce buffers `bounces`, from the first bounce's parents `first`: the
/// staged frame's (every pixel) or the fused frame's (the pixels its tiles deferred, in
/// pixel order, which spawn the same rays). The shadow rays of depth `d` are counted into
/// `shadow_rays[d]`.
fn bounce_step(
    cx: &BounceContext,
    step: Step,
    first: Parents,
    bounces: &mut [BounceBuffers],
    scratch: &mut CompactionScratch,
    closest: &mut Vec<Option<ClosestHit>>,
    shadow_rays: &mut [usize],
) -> Result<(), RenderError> {
    let (scene, g, materials) = (cx.scene, &cx.scene.geometry, cx.materials);
    let oom = |what| oom(cx.size.0, cx.size.1, what);
    match step {
        Step::SecondaryRays { depth } => {
            let (done, rest) = bounces.split_at_mut(depth as usize - 1);
            let parents = match done.last() {
                None => first,
                Some(prev) => Parents::Secondary { rays: &prev.rays, hits: &prev.hits, surfaces: &prev.surfaces },
            };
            let b = &mut rest[0];
            secondary_rays_into(parents, materials, &g.triangles, depth, &mut b.rays, &mut b.links)
                .map_err(oom("a bounce's ray list"))?
        }
        Step::BounceTrace { depth } => {
            let b = &mut bounces[depth as usize - 1];
            let levels = scene.levels.as_ref();
            bounce_trace_into(
                &scene.bvh,
                levels,
                g,
                cx.materials,
                &b.rays,
                cx.bounce_traversal,
                closest,
                &mut b.hits,
                &mut b.surfaces,
            )
        }
        Step::BounceCompaction { depth } => {
            let b = &mut bounces[depth as usize - 1];
            compact_list(&b.surfaces, cx.slots, scratch, cx.lists[depth as usize].then_some(&mut b.shadow_rays))
                .map_err(oom("a bounce's shadow rays"))?
        }
        Step::BounceShadowRays { depth } => {
            let b = &mut bounces[depth as usize - 1];
            let list = cx.lists[depth as usize].then_some(&b.shadow_rays[..]);
            let out = (&mut b.occluded, &mut b.shadow);
            shadow_rays[depth as usize] =
                trace_list(scene, &b.surfaces, cx.slots, scratch, list, None, cx.traversal, out);
        }
        Step::BounceShading { depth, last } => {
            let (this, deeper) = bounces.split_at_mut(depth as usize);
            let b = &mut this[depth as usize - 1];
            let children = (!last).then(|| Children { links: &deeper[0].links, radiance: &deeper[0].radiance });
            bounce_shading_into(
                &b.rays,
                &b.hits,
                &b.surfaces,
                &b.shadow,
                materials,
                &g.triangles,
                cx.lighting.lights(),
                &g.environment,
                &cx.lighting.ambient,
                children,
                &mut b.radiance,
            )
        }
        _ => unreachable!("{} is no bounce step", step.label()),
    }
    Ok(())
}

impl Default for CpuBackend {
    fn default() -> Self {
        CpuBackend::new(None)
    }
}

impl Backend for CpuBackend {
    fn name(&self) -> &str {
        "cpu"
    }

    fn render_into(
        &mut self,
        scene: &PreparedScene,
        camera: &CameraRecord,
        options: &FrameOptions,
        frame: &mut Frame,
    ) -> Result<(), RenderError> {
        let plan = FramePlan::new(scene, options)?;
        camera.validate().map_err(RenderError::InvalidCamera)?;
        // A frame that cannot fit is refused before anything is allocated, and the
        // buffers are reserved fallibly: an error, never an abort.
        let (width, height) = (camera.width, camera.height);
        let fused = self.fused_steps(&plan, options);
        let executor = fused.map_or(Executor::Staged, |_| Executor::Fused);
        let run = memory::FrameRun::new(executor, options, &scene.geometry);
        memory::check(&plan, run, width, height)?;
        let g = &scene.geometry;
        let eye = Vec3::from(camera.eye);
        let threads = self.threads();
        let (traversal, bounce_traversal) = (self.shadow_traversal, self.bounce_traversal);
        let scratch = &mut self.scratch;
        let denoise = &mut self.denoise;
        let history = &mut self.history;
        let closest = &mut self.closest;
        let f = frame;
        f.begin(&plan, options);
        if plan.bounce_depth() > 0 {
            f.bounce_mut(plan.bounce_depth());
        }
        memory::reserve_frame(f, &plan, run, width, height)?;
        let oom = |what: &'static str| oom(width, height, what);
        // A frame that does not return a shadow-ray list does not write it: `compaction`
        // keeps the active pairs and `shadow_rays` makes their rays as it traces them.
        let list = |depth: u32| match depth {
            0 => f.holds(FrameBuffer::Rays),
            d => f.holds(BounceBuffer::ShadowRays.at(d)),
        };
        let lists: Vec<bool> = (0..=plan.bounce_depth()).map(list).collect();
        // What shading knows of materials (textures, vertex colours; the plain object
        // records in a scene without them).
        let materials = g.materials(camera);
        let lighting = scene.frame_lighting(options);
        let slots = Slots::new(lighting.lights(), &lighting.ambient.occlusion);
        let (lights, ambient) = (lighting.lights(), &*lighting.ambient);
        // `shadow_denoise`'s channels per pixel (none unless the plan denoises).
        let channels = channel_count(&lights, &ambient.occlusion);
        let cx = BounceContext {
            scene,
            lighting: &lighting,
            slots: &slots,
            materials: &materials,
            traversal,
            bounce_traversal,
            lists: &lists,
            size: (width, height),
        };
        if let Some(steps) = fused {
            let deferred = &mut self.deferred;
            self.pool.install(|| -> Result<(), RenderError> {
                // The G-buffer whole-image only where the frame returns it.
                let gbuffer = run.keep_gbuffer.then_some(&mut f.gbuffer);
                let t = Instant::now();
                let run = fused_frame(scene, camera, options, steps, traversal, gbuffer, &mut f.final_image);
                // The raster's setup and binning alone; its tiles run with the fused steps.
                let raster_ms = run.raster_setup.as_secs_f64() * 1e3;
                let mut fused_ms = t.elapsed().as_secs_f64() * 1e3 - raster_ms;
                let (covered, counts) = (run.covered_pixels, run.counts);
                let mut stats = FrameStats {
                    width,
                    height,
                    threads,
                    skipped: plan.skipped().to_vec(),
                    covered_pixels: covered,
                    ray_traced_pixels: counts.ray_traced_pixels,
                    raster_pixels: covered - counts.ray_traced_pixels,
                    occluded_shadow_rays: counts.occluded,
                    executor,
                    ..FrameStats::default()
                };
                stats.rays_per_kind[RAY_KIND_SHADOW as usize] = counts.shadow_rays;
                let raster = Step::VisibilityRaster;
                let mut times =
                    vec![StageTime { stage: raster.stage(), depth: 0, ms: raster_ms, work: StageWork::default() }];
                if steps.bounces {
                    // The pixels the tiles deferred, gathered in pixel order; the bounce
                    // steps over their rays (every tile's at once), timed step by step; then
                    // their shading and composition.
                    let t = Instant::now();
                    deferred.gather(run.deferred, slots.len()).map_err(oom("the bouncing pixels"))?;
                    fused_ms += t.elapsed().as_secs_f64() * 1e3;
                    let mut shadow_rays = vec![0; lists.len()];
                    for &step in plan.steps().iter().filter(|s| s.depth() > 0) {
                        let t = Instant::now();
                        let first = deferred.parents(eye);
                        bounce_step(&cx, step, first, &mut f.bounces, scratch, closest, &mut shadow_rays)?;
                        let ms = t.elapsed().as_secs_f64() * 1e3;
                        times.push(StageTime {
                            stage: step.stage(),
                            depth: step.depth(),
                            ms,
                            work: StageWork::default(),
                        });
                    }
                    let t = Instant::now();
                    let first = &f.bounces[0];
                    let shading = BouncingShading {
                        materials: &materials,
                        triangles: &g.triangles,
                        lights,
                        ambient,
                        eye,
                        radiance: &first.radiance,
                        visibility: Default::default(),
                    };
                    shade_deferred(
                        deferred,
                        steps,
                        &shading,
                        &first.links,
                        options.weight,
                        width as usize,
                        &mut f.final_image,
                    );
                    fused_ms += t.elapsed().as_secs_f64() * 1e3;
                    stats.bounces = bounce_stats(&f.bounces[..plan.bounce_depth() as usize], &shadow_rays[1..]);
                }
                stats.fused_ms = fused_ms;
                let ran = [raster].into_iter().chain(plan.steps().iter().copied().filter(|s| s.depth() > 0));
                for (time, step) in times.iter_mut().zip(ran) {
                    time.work = StageWork::of(step, &stats);
                }
                stats.stage_ms = times;
                f.stats = stats;
                Ok(())
            })?;
            f.width = width;
            f.height = height;
            f.end();
            return Ok(());
        }
        self.pool.install(|| -> Result<(), RenderError> {
            let mut times = Vec::with_capacity(plan.steps().len());
            let mut covered = 0;
            // Shadow rays per list: the primary hits', then each bounce depth's.
            let mut shadow_rays = vec![0; lists.len()];
            // The plan's one loop: each step runs its stage module and is timed.
            for &step in plan.steps() {
                let t = Instant::now();
                match step {
                    Step::VisibilityRaster => covered = visibility_raster_into(g, camera, &mut f.gbuffer) as u64,
                    Step::Reconstruction => {
                        match options.barycentrics {
                            PrimaryBarycentrics::Raster => reconstruction_into(&f.gbuffer, g, eye, &mut f.surfaces),
                            PrimaryBarycentrics::Reintersected => {
                                reconstruction_reintersected_into(&f.gbuffer, g, camera, &mut f.surfaces)
                            }
                        }
                        if materials.normal_mapped_any() {
                            normal_mapping_into(&f.gbuffer, &materials, eye, &mut f.surfaces);
                        }
                    }
                    Step::Compaction => compact_list(&f.surfaces, &slots, scratch, lists[0].then_some(&mut f.rays))
                        .map_err(oom("the ray list"))?,
                    Step::ShadowRays => {
                        let list = lists[0].then_some(&f.rays[..]);
                        let out = (&mut f.occluded, &mut f.shadow);
                        let width = Some(camera.width);
                        shadow_rays[0] = trace_list(scene, &f.surfaces, &slots, scratch, list, width, traversal, out);
                    }
                    Step::ShadowDenoise => {
                        let temporal = options.temporal.then(|| Temporal {
                            scene: scene.id(),
                            maps: scene.object_maps(),
                            history: &mut *history,
                        });
                        let occlusion = &ambient.occlusion;
                        let out = &mut f.visibility;
                        shadow_denoise_into(&f.surfaces, &f.shadow, lights, occlusion, camera, denoise, temporal, out)
                    }
                    Step::SecondaryRays { .. }
                    | Step::BounceTrace { .. }
                    | Step::BounceCompaction { .. }
                    | Step::BounceShadowRays { .. }
                    | Step::BounceShading { .. } => {
                        let first = Parents::Primary { gbuffer: &f.gbuffer, surfaces: &f.surfaces, eye };
                        bounce_step(&cx, step, first, &mut f.bounces, scratch, closest, &mut shadow_rays)?
                    }
                    Step::RtShading { bounces: false } => {
                        let visibility = FilteredVisibility { values: &f.visibility, channels };
                        let primary = Primary { gbuffer: &f.gbuffer, materials: &materials, ambient, eye, visibility };
                        rt_shading_into(&f.surfaces, &f.shadow, &primary, lights, &mut f.rt)
                    }
                    Step::RtShading { bounces: true } => {
                        let visibility = FilteredVisibility { values: &f.visibility, channels };
                        let first = &f.bounces[0];
                        let bounce =
                            FirstBounce { gbuffer: &f.gbuffer, links: &first.links, radiance: &first.radiance };
                        rt_shading_bouncing_into(
                            &f.surfaces,
                            &f.shadow,
                            &materials,
                            &g.triangles,
                            lights,
                            ambient,
                            eye,
                            bounce,
                            visibility,
                            &mut f.rt,
                        )
                    }
                    Step::RasterShading { shade_ray_traced } => {
                        let visibility = FilteredVisibility { values: &f.visibility, channels };
                        raster_shading_into(
                            &f.surfaces,
                            &f.shadow,
                            &Primary { gbuffer: &f.gbuffer, materials: &materials, ambient, eye, visibility },
                            lights,
                            shade_ray_traced,
                            &mut f.raster,
                        )
                    }
                    Step::Composition(mode) => {
                        composition_into(mode, &f.raster, &f.rt, options.weight, &mut f.final_image)
                    }
                }
                let ms = t.elapsed().as_secs_f64() * 1e3;
                times.push(StageTime { stage: step.stage(), depth: step.depth(), ms, work: StageWork::default() });
            }

            let mut stats = FrameStats {
                width: camera.width,
                height: camera.height,
                threads,
                skipped: plan.skipped().to_vec(),
                ..FrameStats::default()
            };
            stats.covered_pixels = covered;
            stats.ray_traced_pixels = f.gbuffer.par_iter().filter(|t| t.is_hit() && t.is_ray_traced()).count() as u64;
            stats.raster_pixels = stats.covered_pixels - stats.ray_traced_pixels;
            stats.rays_per_kind[RAY_KIND_SHADOW as usize] = shadow_rays[0] as u64;
            stats.occluded_shadow_rays = f.occluded.par_iter().filter(|&&o| o != 0).count() as u64;
            stats.bounces = bounce_stats(&f.bounces[..plan.bounce_depth() as usize], &shadow_rays[1..]);
            for (time, &step) in times.iter_mut().zip(plan.steps()) {
                time.work = StageWork::of(step, &stats);
            }
            stats.stage_ms = times;
            f.width = camera.width;
            f.height = camera.height;
            f.stats = stats;
            Ok(())
        })?;
        f.end();
        Ok(())
    }
}
