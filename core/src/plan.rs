//! The frame as a plan of stages.
//!
//! Each [`Stage`] declares what it reads and writes: the frame buffers
//! ([`FrameBuffer`], one per stage output) and the scene inputs ([`Input`]).
//! A [`FramePlan`], built from the prepared scene and the frame options by
//! [`FramePlan::new`], lists the [`Step`]s a frame runs and the stages it skips,
//! each with its [`SkipReason`]: a frame models only what its scene needs.
//!
//! Both backends execute a plan through one loop that times each step; readback,
//! `--dump`, the conformance comparison and the report iterate over the buffers the
//! plan produces ([`FramePlan::produces`]) instead of naming [`Frame`](crate::frame::Frame)
//! fields by hand. A buffer the plan does not produce is absent from the frame (empty,
//! and [`Frame::buffer`](crate::frame::Frame::buffer) gives `None`), never zero-filled.
//!
//! # The rules
//!
//! | stage | runs when | otherwise |
//! |---|---|---|
//! | `visibility_raster` | always (it finds the covered pixels) | |
//! | `reconstruction` | always (shading reads its surfaces) | |
//! | `compaction` | the scene has a light and a triangle | [`SkipReason::NoLights`], [`SkipReason::NoGeometry`] |
//! | `shadow_rays` | as `compaction` | as `compaction` |
//! | `shadow_denoise` | as `compaction`, the frame traces stochastic rays (an area light or ambient occlusion) and [`FrameOptions::denoise`] | [`SkipReason::NothingToDenoise`], or `compaction`'s reason |
//! | `rt_shading` | a ray-traced object has triangles and the weight is above 0 | [`SkipReason::NoRayTracedObjects`], [`SkipReason::WeightZero`] |
//! | `raster_shading` | unless every object with triangles is ray traced and the weight is 1 | [`SkipReason::AllRayTracedWeightOne`] |
//! | `composition` | always, as [`Composition::WeightedMean`] when both images exist, else a copy | |
//! | `secondary_rays`, `bounce_trace`, `bounce_shading` | `rt_shading` runs, a ray-traced object bounces ([`crate::kernels::bounce::bounces`]: specular or glass) and `max_depth > 0`; once per depth | [`SkipReason::MaxDepthZero`], [`SkipReason::NoMirrorsOrGlass`], or `rt_shading`'s reason |
//!
//! The reduced frames are the full frame bit for bit: with no ray-traced pixel the
//! weighted mean returns the raster texel; with weight 0 it returns
//! `raster * 1 + rt * 0 = raster`; with weight 1 and no rasterized object the raster
//! image is 0 on ray-traced pixels and the background elsewhere, so the mean is
//! `0 * 0 + rt * 1 = rt` where `rt` has coverage and the background elsewhere.
//!
//! # Bounces
//!
//! Reflection and refraction repeat the paper's idea per ray depth `d = 1..=D`
//! (`D = max_depth`): `secondary_rays` compacts the rays the surfaces of depth `d - 1`
//! spawn into the list of depth `d` (with each parent's links to its children),
//! `bounce_trace` finds their closest hits and rebuilds the surfaces hit, and
//! `compaction` and `shadow_rays` run again over those surfaces. Then `bounce_shading`
//! runs from `D` down to 1, each ray adding its children's radiance, and `rt_shading`
//! adds the first bounce's to the pixels:
//!
//! ```text
//! visibility_raster, reconstruction, compaction, shadow_rays,
//! secondary_rays{1}, bounce_trace{1}, compaction{1}, shadow_rays{1},
//! secondary_rays{2}, bounce_trace{2}, compaction{2}, shadow_rays{2},
//! bounce_shading{2}, bounce_shading{1},
//! rt_shading, raster_shading, composition
//! ```
//!
//! Each bounce step reads the buffers of its own depth and its neighbour's
//! ([`FrameBuffer::Bounce`]), so the plan stays a flat list that both backends run
//! through the same loop; a scene without a mirror or glass object plans no bounce and
//! allocates nothing for one.

use crate::error::RenderError;
use crate::formats::OBJ_RAY_TRACED;
use crate::kernels::bounce::bounces;
use crate::options::FrameOptions;
use crate::prepared::PreparedScene;
use crate::stage::Stage;

/// The composition codes, defined with [`crate::formats::FrameParams`] that carries them
/// to the GPU; re-exported here, where a plan chooses one.
pub use crate::formats::Composition;

/// A frame buffer: one stage output, kept in [`Frame`](crate::frame::Frame).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FrameBuffer {
    /// `visibility_raster`: one [`GBufferTexel`](crate::formats::GBufferTexel) per pixel.
    GBuffer,
    /// `reconstruction`: one [`SurfaceRecord`](crate::formats::SurfaceRecord) per pixel.
    Surfaces,
    /// `compaction`: the ray list, one [`RayRecord`](crate::formats::RayRecord) per ray.
    Rays,
    /// `shadow_rays`: one `u32` per ray, 1 occluded, 0 reached the light.
    Occluded,
    /// `shadow_rays`: one `SHADOW_*` code per (pixel, light).
    Shadow,
    /// `shadow_denoise`: per pixel, the filtered visibility of each area light, then the
    /// filtered ambient occlusion, f32 ([`crate::kernels::denoise`]).
    Visibility,
    /// `rt_shading`: the ray-traced image, linear RGBA per pixel.
    Rt,
    /// `raster_shading`: the raster image, linear RGBA per pixel.
    Raster,
    /// `composition`: the final image, linear RGBA per pixel.
    Final,
    /// A buffer of bounce `depth` (1 for the rays from primary hits).
    Bounce { buffer: BounceBuffer, depth: u32 },
}

/// The buffers of one bounce depth `d`: what the bounce stages write.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BounceBuffer {
    /// `secondary_rays`: the reflection and refraction rays of depth `d`, one
    /// [`RayRecord`](crate::formats::RayRecord) each, in their parents' order.
    Rays,
    /// `secondary_rays`: per parent (the pixels for `d = 1`, else the rays of depth
    /// `d - 1`), the indices of its `[reflection, refraction]` children in
    /// [`BounceBuffer::Rays`], `INVALID_ID` where the lobe spawned no ray.
    Links,
    /// `bounce_trace`: one [`HitRecord`](crate::formats::HitRecord) per ray.
    Hits,
    /// `bounce_trace`: one [`SurfaceRecord`](crate::formats::SurfaceRecord) per ray
    /// (`SurfaceRecord::MISS` where the ray left the scene).
    Surfaces,
    /// `compaction`: the shadow rays from the surfaces of depth `d`; their `pixel` is
    /// the index of the secondary ray whose surface they leave.
    ShadowRays,
    /// `shadow_rays`: one word per shadow ray, 1 occluded.
    Occluded,
    /// `shadow_rays`: one `SHADOW_*` code per (secondary ray, light).
    Shadow,
    /// `bounce_shading`: the radiance each ray brings back (linear RGB, alpha 1).
    Radiance,
}

impl BounceBuffer {
    /// Every bounce buffer, in the order the stages write them.
    pub const ALL: [BounceBuffer; 8] = [
        BounceBuffer::Rays,
        BounceBuffer::Links,
        BounceBuffer::Hits,
        BounceBuffer::Surfaces,
        BounceBuffer::ShadowRays,
        BounceBuffer::Occluded,
        BounceBuffer::Shadow,
        BounceBuffer::Radiance,
    ];

    /// The buffer's name within its depth (`--dump` writes `bounce{d}_{name}`).
    pub const fn name(self) -> &'static str {
        match self {
            BounceBuffer::Rays => "rays",
            BounceBuffer::Links => "links",
            BounceBuffer::Hits => "hits",
            BounceBuffer::Surfaces => "surfaces",
            BounceBuffer::ShadowRays => "shadow_rays",
            BounceBuffer::Occluded => "occluded",
            BounceBuffer::Shadow => "shadow",
            BounceBuffer::Radiance => "radiance",
        }
    }

    /// The stage that writes it.
    pub const fn writer(self) -> Stage {
        match self {
            BounceBuffer::Rays | BounceBuffer::Links => Stage::SecondaryRays,
            BounceBuffer::Hits | BounceBuffer::Surfaces => Stage::BounceTrace,
            BounceBuffer::ShadowRays => Stage::Compaction,
            BounceBuffer::Occluded | BounceBuffer::Shadow => Stage::ShadowRays,
            BounceBuffer::Radiance => Stage::BounceShading,
        }
    }

    /// The buffer at depth `depth`.
    pub const fn at(self, depth: u32) -> FrameBuffer {
        FrameBuffer::Bounce { buffer: self, depth }
    }
}

impl FrameOptions {
    /// True if a frame under these options returns `buffer` where its plan writes it:
    /// every buffer with [`FrameOptions::stage_outputs`], else the final image and, with
    /// [`FrameOptions::keep_gbuffer`], the G-buffer.
    pub fn returns(&self, buffer: FrameBuffer) -> bool {
        self.stage_outputs || buffer.always_returned() || (self.keep_gbuffer && buffer == FrameBuffer::GBuffer)
    }
}

impl FrameBuffer {
    /// The buffers of the primary hits (no bounce), in the order the stages write them.
    pub const ALL: [FrameBuffer; 9] = [
        FrameBuffer::GBuffer,
        FrameBuffer::Surfaces,
        FrameBuffer::Rays,
        FrameBuffer::Occluded,
        FrameBuffer::Shadow,
        FrameBuffer::Visibility,
        FrameBuffer::Rt,
        FrameBuffer::Raster,
        FrameBuffer::Final,
    ];

    /// The buffer's kind name (a bounce buffer's without its depth: see
    /// [`FrameBuffer::label`]).
    pub const fn name(self) -> &'static str {
        match self {
            FrameBuffer::Bounce { buffer, .. } => buffer.name(),
            FrameBuffer::GBuffer => "gbuffer",
            FrameBuffer::Surfaces => "surfaces",
            FrameBuffer::Rays => "rays",
            FrameBuffer::Occluded => "occluded",
            FrameBuffer::Shadow => "shadow",
            FrameBuffer::Visibility => "visibility",
            FrameBuffer::Rt => "rt",
            FrameBuffer::Raster => "raster",
            FrameBuffer::Final => "final",
        }
    }

    /// The buffer's one name: `--dump` files, conformance reports. The primary
    /// buffers' [`FrameBuffer::name`]; `bounce{d}_{name}` for a bounce buffer.
    pub fn label(self) -> String {
        match self {
            FrameBuffer::Bounce { buffer, depth } => format!("bounce{depth}_{}", buffer.name()),
            _ => self.name().to_string(),
        }
    }

    /// The bounce depth it belongs to: 0 for the primary buffers.
    pub const fn depth(self) -> u32 {
        match self {
            FrameBuffer::Bounce { depth, .. } => depth,
            _ => 0,
        }
    }

    /// The stage that writes it.
    pub const fn writer(self) -> Stage {
        match self {
            FrameBuffer::Bounce { buffer, .. } => buffer.writer(),
            FrameBuffer::GBuffer => Stage::VisibilityRaster,
            FrameBuffer::Surfaces => Stage::Reconstruction,
            FrameBuffer::Rays => Stage::Compaction,
            FrameBuffer::Occluded | FrameBuffer::Shadow => Stage::ShadowRays,
            FrameBuffer::Visibility => Stage::ShadowDenoise,
            FrameBuffer::Rt => Stage::RtShading,
            FrameBuffer::Raster => Stage::RasterShading,
            FrameBuffer::Final => Stage::Composition,
        }
    }

    /// True for the buffer a display loop needs and every backend returns even without
    /// [`FrameOptions::stage_outputs`]: the final image. The G-buffer comes with it when
    /// [`FrameOptions::keep_gbuffer`] asks (picking; [`FrameOptions::returns`]). The
    /// frame's statistics count the rest (covered pixels and occluded shadow rays among
    /// them); the fused CPU frame writes nothing else whole-image.
    pub const fn always_returned(self) -> bool {
        matches!(self, FrameBuffer::Final)
    }
}

impl std::fmt::Display for FrameBuffer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.label())
    }
}

/// A scene or per-frame input a stage reads (not written by any frame stage).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Input {
    /// The world triangle table.
    Triangles,
    /// The world normals at the triangles' corners.
    Normals,
    /// The object table (materials, flags).
    Objects,
    /// The light list.
    Lights,
    /// The BVH over the whole scene.
    Bvh,
    /// The camera of the frame.
    Camera,
    /// The frame options (the composition weight, the bounce depth).
    Options,
    /// What secondary rays that leave the scene see: the default sky or the scene's
    /// environment map ([`crate::geometry::WorldGeometry::environment`]).
    Environment,
    /// What the backend kept of the previous frame for the denoiser's temporal pass
    /// ([`crate::kernels::temporal::History`]: its camera, surfaces, visibility, and the
    /// objects' transforms), read where [`FrameOptions::temporal`] asks for it.
    History,
}

/// One stage of a plan, with what it needs to know of the plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Step {
    VisibilityRaster,
    Reconstruction,
    Compaction,
    ShadowRays,
    ShadowDenoise,
    /// Spawn the rays of bounce `depth` from the surfaces of `depth - 1`.
    SecondaryRays {
        depth: u32,
    },
    /// Trace the rays of bounce `depth` (closest hit) and rebuild the surfaces hit.
    BounceTrace {
        depth: u32,
    },
    /// `compaction` over the surfaces of bounce `depth`.
    BounceCompaction {
        depth: u32,
    },
    /// `shadow_rays` for the shadow rays of bounce `depth`.
    BounceShadowRays {
        depth: u32,
    },
    /// Shade the hits of bounce `depth` and gather their children's radiance; `last`:
    /// `depth` is the plan's deepest bounce (its surfaces spawn nothing).
    BounceShading {
        depth: u32,
        last: bool,
    },
    /// `bounces`: the plan traces bounces, so bouncing pixels add their children's
    /// radiance.
    RtShading {
        bounces: bool,
    },
    /// `shade_ray_traced`: ray-traced objects are shaded by the raster shader too
    /// (the composition weight is below 1).
    RasterShading {
        shade_ray_traced: bool,
    },
    Composition(Composition),
}

impl Step {
    /// The stage this step runs.
    pub const fn stage(self) -> Stage {
        match self {
            Step::VisibilityRaster => Stage::VisibilityRaster,
            Step::Reconstruction => Stage::Reconstruction,
            Step::Compaction | Step::BounceCompaction { .. } => Stage::Compaction,
            Step::ShadowRays | Step::BounceShadowRays { .. } => Stage::ShadowRays,
            Step::ShadowDenoise => Stage::ShadowDenoise,
            Step::SecondaryRays { .. } => Stage::SecondaryRays,
            Step::BounceTrace { .. } => Stage::BounceTrace,
            Step::BounceShading { .. } => Stage::BounceShading,
            Step::RtShading { .. } => Stage::RtShading,
            Step::RasterShading { .. } => Stage::RasterShading,
            Step::Composition(_) => Stage::Composition,
        }
    }

    /// The bounce depth the step works on: 0 for the primary hits.
    pub const fn depth(self) -> u32 {
        match self {
            Step::SecondaryRays { depth }
            | Step::BounceTrace { depth }
            | Step::BounceCompaction { depth }
            | Step::BounceShadowRays { depth }
            | Step::BounceShading { depth, .. } => depth,
            _ => 0,
        }
    }

    /// The step's name with its depth: the stage name, and `{d}` after it for a bounce
    /// step (`compaction{2}`): frame tables and errors.
    pub fn label(self) -> String {
        self.stage().label_at(self.depth())
    }

    /// The frame buffers this step reads, given whether the plan has shadow results
    /// (it has none without lights: shading then reads no mask) and denoised ones.
    fn reads(self, with_shadow: bool, denoised: bool) -> Vec<FrameBuffer> {
        use BounceBuffer as K;
        use FrameBuffer as B;
        let shadow: &[B] = match (with_shadow, denoised) {
            (false, _) => &[],
            (true, false) => &[B::Shadow],
            (true, true) => &[B::Shadow, B::Visibility],
        };
        match self {
            Step::VisibilityRaster => vec![],
            Step::Reconstruction => vec![B::GBuffer],
            Step::Compaction => vec![B::Surfaces],
            Step::ShadowRays => vec![B::Rays],
            Step::ShadowDenoise => vec![B::Surfaces, B::Shadow],
            Step::SecondaryRays { depth: 1 } => vec![B::GBuffer, B::Surfaces],
            Step::SecondaryRays { depth } => {
                vec![K::Rays.at(depth - 1), K::Hits.at(depth - 1), K::Surfaces.at(depth - 1)]
            }
            Step::BounceTrace { depth } => vec![K::Rays.at(depth)],
            Step::BounceCompaction { depth } => vec![K::Surfaces.at(depth)],
            Step::BounceShadowRays { depth } => vec![K::ShadowRays.at(depth)],
            Step::BounceShading { depth, last } => {
                let mut r = vec![K::Rays.at(depth), K::Hits.at(depth), K::Surfaces.at(depth)];
                if with_shadow {
                    r.push(K::Shadow.at(depth));
                }
                if !last {
                    r.extend([K::Links.at(depth + 1), K::Radiance.at(depth + 1)]);
                }
                r
            }
            Step::RtShading { bounces } => {
                let mut r = [&[B::Surfaces][..], shadow].concat();
                if bounces {
                    r.extend([B::GBuffer, K::Links.at(1), K::Radiance.at(1)]);
                }
                r
            }
            Step::RasterShading { .. } => [&[B::Surfaces][..], shadow].concat(),
            Step::Composition(Composition::WeightedMean) => vec![B::Raster, B::Rt],
            Step::Composition(Composition::CopyRaster) => vec![B::Raster],
            Step::Composition(Composition::RtOverBackground) => vec![B::Rt],
        }
    }

    /// The frame buffers this step writes.
    pub fn writes(self) -> Vec<FrameBuffer> {
        use BounceBuffer as K;
        use FrameBuffer as B;
        match self {
            Step::VisibilityRaster => vec![B::GBuffer],
            Step::Reconstruction => vec![B::Surfaces],
            Step::Compaction => vec![B::Rays],
            Step::ShadowRays => vec![B::Occluded, B::Shadow],
            Step::ShadowDenoise => vec![B::Visibility],
            Step::SecondaryRays { depth } => vec![K::Rays.at(depth), K::Links.at(depth)],
            Step::BounceTrace { depth } => vec![K::Hits.at(depth), K::Surfaces.at(depth)],
            Step::BounceCompaction { depth } => vec![K::ShadowRays.at(depth)],
            Step::BounceShadowRays { depth } => vec![K::Occluded.at(depth), K::Shadow.at(depth)],
            Step::BounceShading { depth, .. } => vec![K::Radiance.at(depth)],
            Step::RtShading { .. } => vec![B::Rt],
            Step::RasterShading { .. } => vec![B::Raster],
            Step::Composition(_) => vec![B::Final],
        }
    }

    /// The scene and frame inputs this step reads.
    pub const fn inputs(self) -> &'static [Input] {
        use Input as I;
        match self {
            Step::VisibilityRaster => &[I::Triangles, I::Objects, I::Camera],
            Step::Reconstruction => &[I::Triangles, I::Normals, I::Camera],
            Step::Compaction | Step::BounceCompaction { .. } => &[I::Lights],
            Step::ShadowRays | Step::BounceShadowRays { .. } => &[I::Bvh, I::Triangles],
            Step::ShadowDenoise => &[I::Lights, I::Camera, I::Options, I::History],
            Step::SecondaryRays { .. } => &[I::Triangles, I::Objects, I::Camera, I::Options],
            Step::BounceTrace { .. } => &[I::Bvh, I::Triangles, I::Normals],
            Step::BounceShading { .. } => &[I::Objects, I::Lights, I::Triangles, I::Environment],
            Step::RtShading { .. } => &[I::Objects, I::Lights, I::Camera, I::Triangles],
            Step::RasterShading { .. } => &[I::Objects, I::Lights, I::Options],
            Step::Composition(_) => &[I::Options],
        }
    }
}

/// Why a plan leaves a stage out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SkipReason {
    /// The scene has no light: no shadow ray to compact or trace.
    NoLights,
    /// The scene has no triangle: no pixel is covered, no ray starts anywhere.
    NoGeometry,
    /// No object with triangles is ray traced: the ray-traced image would be empty.
    NoRayTracedObjects,
    /// The composition weight is 0: the ray-traced image would be weighted out.
    WeightZero,
    /// Every object with triangles is ray traced and the weight is 1: the raster
    /// image would only hold the background, which `composition` fills in.
    AllRayTracedWeightOne,
    /// The frame options ask for no bounce (`max_depth` 0).
    MaxDepthZero,
    /// No ray-traced object with triangles has a specular or glass material.
    NoMirrorsOrGlass,
    /// The frame traces no stochastic rays (no area light, no ambient occlusion), or its
    /// options turn the denoiser off ([`FrameOptions::denoise`]).
    NothingToDenoise,
}

impl SkipReason {
    /// A short explanation for the user.
    pub const fn describe(self) -> &'static str {
        match self {
            SkipReason::NoLights => "no lights",
            SkipReason::NoGeometry => "no triangles",
            SkipReason::NoRayTracedObjects => "no ray-traced objects",
            SkipReason::WeightZero => "composition weight 0",
            SkipReason::AllRayTracedWeightOne => "every object ray traced, weight 1",
            SkipReason::MaxDepthZero => "max depth 0",
            SkipReason::NoMirrorsOrGlass => "no ray-traced mirror or glass",
            SkipReason::NothingToDenoise => "no area light or ambient occlusion to denoise, or the denoiser is off",
        }
    }
}

impl std::fmt::Display for SkipReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.describe())
    }
}

/// A stage a plan leaves out, and why.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Skipped {
    pub stage: Stage,
    pub reason: SkipReason,
}

/// The stages one frame runs, in order, and the ones it skips.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FramePlan {
    steps: Vec<Step>,
    skipped: Vec<Skipped>,
    lights: u32,
    depth: u32,
    stochastic: bool,
    channels: u32,
}

impl FramePlan {
    /// The plan of a frame of `scene` under `options` (validated here, once).
    pub fn new(scene: &PreparedScene, options: &FrameOptions) -> Result<FramePlan, RenderError> {
        options.validate()?;
        let g = &scene.geometry;
        let with_triangles = || g.objects.iter().filter(|o| o.triangle_count > 0);
        let any_rt = with_triangles().any(|o| o.flags & OBJ_RAY_TRACED != 0);
        let any_raster = with_triangles().any(|o| o.flags & OBJ_RAY_TRACED == 0);
        let lighting = scene.frame_lighting(options);
        let plan = FramePlan::from_counts(SceneNeeds {
            lights: lighting.slots() as u32,
            triangles: !g.triangles.is_empty(),
            ray_traced: any_rt,
            rasterized: any_raster,
            bouncing: g.objects.iter().any(bounces),
            weight: options.weight,
            max_depth: options.max_depth,
            denoise: options.denoise && lighting.is_stochastic(),
        });
        let channels = match plan.runs(Stage::ShadowDenoise) {
            true => crate::kernels::denoise::channel_count(&lighting.lights, &lighting.ambient.occlusion) as u32,
            false => 0,
        };
        Ok(FramePlan { stochastic: lighting.is_stochastic(), channels, ..plan })
    }

    /// The plan for what a scene holds (see the module docs for the rules).
    pub fn from_counts(needs: SceneNeeds) -> FramePlan {
        let SceneNeeds { lights, triangles, ray_traced, rasterized, bouncing, weight, max_depth, denoise } = needs;
        let mut steps = vec![Step::VisibilityRaster, Step::Reconstruction];
        let mut skipped = Vec::new();
        let mut skip = |stage, reason| skipped.push(Skipped { stage, reason });

        let rays = match (lights > 0, triangles) {
            (true, true) => None,
            (false, _) => Some(SkipReason::NoLights),
            (true, false) => Some(SkipReason::NoGeometry),
        };
        match rays {
            None => steps.extend([Step::Compaction, Step::ShadowRays]),
            Some(reason) => {
                skip(Stage::Compaction, reason);
                skip(Stage::ShadowRays, reason);
            }
        }
        match (rays, denoise) {
            (None, true) => steps.push(Step::ShadowDenoise),
            (None, false) => skip(Stage::ShadowDenoise, SkipReason::NothingToDenoise),
            (Some(reason), _) => skip(Stage::ShadowDenoise, reason),
        }
        let rt = if !ray_traced {
            Err(SkipReason::NoRayTracedObjects)
        } else if weight == 0.0 {
            Err(SkipReason::WeightZero)
        } else {
            Ok(())
        };
        let depth = match rt {
            Err(reason) => Err(reason),
            Ok(()) if max_depth == 0 => Err(SkipReason::MaxDepthZero),
            Ok(()) if !bouncing => Err(SkipReason::NoMirrorsOrGlass),
            Ok(()) => Ok(max_depth),
        };
        match depth {
            Ok(depth) => {
                for d in 1..=depth {
                    steps.extend([Step::SecondaryRays { depth: d }, Step::BounceTrace { depth: d }]);
                    if rays.is_none() {
                        steps.extend([Step::BounceCompaction { depth: d }, Step::BounceShadowRays { depth: d }]);
                    }
                }
                steps.extend((1..=depth).rev().map(|d| Step::BounceShading { depth: d, last: d == depth }));
            }
            Err(reason) => {
                for stage in [Stage::SecondaryRays, Stage::BounceTrace, Stage::BounceShading] {
                    skip(stage, reason);
                }
            }
        }
        let depth = depth.unwrap_or(0);
        if let Err(reason) = rt {
            skip(Stage::RtShading, reason);
        } else {
            steps.push(Step::RtShading { bounces: depth > 0 });
        }
        let raster = if ray_traced && !rasterized && weight == 1.0 {
            skip(Stage::RasterShading, SkipReason::AllRayTracedWeightOne);
            false
        } else {
            steps.push(Step::RasterShading { shade_ray_traced: weight < 1.0 });
            true
        };
        steps.push(Step::Composition(match (raster, rt.is_ok()) {
            (true, true) => Composition::WeightedMean,
            (true, false) => Composition::CopyRaster,
            (false, true) => Composition::RtOverBackground,
            (false, false) => unreachable!("raster_shading is skipped only when rt_shading runs"),
        }));
        skipped.sort_by_key(|s| s.stage);
        FramePlan { steps, skipped, lights, depth, stochastic: false, channels: 0 }
    }

    /// The steps to run, in order.
    pub fn steps(&self) -> &[Step] {
        &self.steps
    }

    /// The stages left out, each with its reason, in stage order.
    pub fn skipped(&self) -> &[Skipped] {
        &self.skipped
    }

    /// True if the plan runs `stage` (at any depth).
    pub fn runs(&self, stage: Stage) -> bool {
        self.steps.iter().any(|s| s.stage() == stage)
    }

    /// The first step that runs `stage`, if any (for a stage that runs at several
    /// depths, the primary one, or the shallowest bounce).
    pub fn step(&self, stage: Stage) -> Option<Step> {
        self.steps.iter().copied().find(|s| s.stage() == stage)
    }

    /// True if a step of the plan writes `buffer`.
    pub fn produces(&self, buffer: FrameBuffer) -> bool {
        self.steps.iter().any(|s| s.writes().contains(&buffer))
    }

    /// The buffers the plan writes: the primary ones in stage order, then each bounce
    /// depth's in [`BounceBuffer::ALL`] order.
    pub fn buffers(&self) -> impl Iterator<Item = FrameBuffer> + '_ {
        let bounce = (1..=self.depth).flat_map(|d| BounceBuffer::ALL.into_iter().map(move |b| b.at(d)));
        FrameBuffer::ALL.into_iter().chain(bounce).filter(|&b| self.produces(b))
    }

    /// The shadow-mask slots per surface of the frame the plan was made for: one per
    /// light, more for area lights and ambient occlusion
    /// ([`crate::kernels::soft_shadow::surface_slots`]; the scene's light count where it
    /// has no area light and traces no occlusion).
    pub fn lights(&self) -> u32 {
        self.lights
    }

    /// The channels `shadow_denoise` writes per pixel ([`FrameBuffer::Visibility`]): one
    /// per area light, then one for the ambient occlusion; 0 where it does not run.
    pub fn visibility_channels(&self) -> u32 {
        self.channels
    }

    /// Whether the frame traces stochastic rays: samples of area lights, or ambient
    /// occlusion ([`crate::kernels::soft_shadow`]).
    pub fn stochastic(&self) -> bool {
        self.stochastic
    }

    /// The deepest bounce the plan traces: 0 when it traces none.
    pub fn bounce_depth(&self) -> u32 {
        self.depth
    }

    /// The frame buffers `step` reads in this plan.
    pub fn reads(&self, step: Step) -> Vec<FrameBuffer> {
        step.reads(self.produces(FrameBuffer::Shadow), self.produces(FrameBuffer::Visibility))
    }

    /// How `composition` runs (every plan has a composition step).
    pub fn composition(&self) -> Composition {
        match self.step(Stage::Composition) {
            Some(Step::Composition(c)) => c,
            _ => Composition::WeightedMean,
        }
    }

    /// Check that every step reads only what an earlier step wrote.
    pub fn validate(&self) -> Result<(), String> {
        let mut written: Vec<FrameBuffer> = Vec::new();
        for &step in &self.steps {
            for b in self.reads(step) {
                if !written.contains(&b) {
                    return Err(format!("{} reads {b} before any step writes it", step.label()));
                }
            }
            written.extend(step.writes());
        }
        Ok(())
    }
}

/// What [`FramePlan::from_counts`] decides on: the parts of a scene and of the
/// options that decide which stages a frame needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneNeeds {
    /// Shadow-mask slots per surface ([`FramePlan::lights`]): the lights, or more where
    /// area lights and ambient occlusion take several.
    pub lights: u32,
    /// The scene has at least one triangle.
    pub triangles: bool,
    /// An object with triangles is ray traced.
    pub ray_traced: bool,
    /// An object with triangles is rasterized.
    pub rasterized: bool,
    /// A ray-traced object with triangles bounces secondary rays
    /// ([`crate::kernels::bounce::bounces`]).
    pub bouncing: bool,
    /// The composition weight in [0, 1].
    pub weight: f32,
    /// The deepest bounce the options allow.
    pub max_depth: u32,
    /// The frame traces stochastic rays (area lights, ambient occlusion) and denoises
    /// them: `shadow_denoise` runs.
    pub denoise: bool,
}

impl SceneNeeds {
    /// A scene with `lights` lights that needs every stage of the primary hits (ray-traced
    /// and rasterized objects composed at weight 0.5, no bounce): what stage tests bind
    /// and what buffer sizes are checked against.
    pub fn every_primary_stage(lights: u32) -> SceneNeeds {
        SceneNeeds {
            lights,
            triangles: true,
            ray_traced: true,
            rasterized: true,
            bouncing: false,
            weight: 0.5,
            max_depth: 0,
            denoise: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(lights: u32, triangles: bool, ray_traced: bool, rasterized: bool, weight: f32) -> FramePlan {
        FramePlan::from_counts(SceneNeeds {
            lights,
            triangles,
            ray_traced,
            rasterized,
            bouncing: ray_traced,
            weight,
            max_depth: 0,
            denoise: false,
        })
    }

    fn bouncing_plan(lights: u32, max_depth: u32) -> FramePlan {
        FramePlan::from_counts(SceneNeeds {
            lights,
            triangles: true,
            ray_traced: true,
            rasterized: true,
            bouncing: true,
            weight: 1.0,
            max_depth,
            denoise: false,
        })
    }

    fn stages(p: &FramePlan) -> Vec<&'static str> {
        p.steps().iter().map(|s| s.stage().name()).collect()
    }

    #[test]
    fn the_full_scene_runs_every_frame_stage_but_the_bounces_at_depth_zero() {
        let p = plan(2, true, true, true, 0.5);
        let bounce = [Stage::SecondaryRays, Stage::BounceTrace, Stage::BounceShading];
        let want: Vec<_> = Stage::ALL[1..]
            .iter()
            .filter(|s| !bounce.contains(s) && **s != Stage::ShadowDenoise)
            .map(|s| s.name())
            .collect();
        assert_eq!(stages(&p), want);
        assert!(p.skipped().iter().all(|s| (s.reason == SkipReason::MaxDepthZero && bounce.contains(&s.stage))
            || (s.stage == Stage::ShadowDenoise && s.reason == SkipReason::NothingToDenoise)));
        // A frame with stochastic rays denoises them right after tracing them.
        let mut needs = SceneNeeds::every_primary_stage(2);
        needs.denoise = true;
        let p = FramePlan::from_counts(needs);
        let names = stages(&p);
        assert_eq!(names[3..5], ["shadow_rays", "shadow_denoise"]);
        assert!(p.reads(Step::RtShading { bounces: false }).contains(&FrameBuffer::Visibility));
        p.validate().unwrap();
        assert_eq!(p.bounce_depth(), 0);
        assert_eq!(p.composition(), Composition::WeightedMean);
        assert_eq!(p.step(Stage::RasterShading), Some(Step::RasterShading { shade_ray_traced: true }));
        p.validate().unwrap();
    }

    #[test]
    fn no_ray_traced_objects_skip_rt_shading_and_copy_the_raster_image() {
        let p = plan(2, true, false, true, 1.0);
        assert!(!p.runs(Stage::RtShading));
        assert!(p.skipped().contains(&Skipped { stage: Stage::RtShading, reason: SkipReason::NoRayTracedObjects }));
        assert_eq!(p.composition(), Composition::CopyRaster);
        assert!(!p.produces(FrameBuffer::Rt));
        p.validate().unwrap();
    }

    #[test]
    fn all_ray_traced_at_weight_one_skips_raster_shading() {
        let p = plan(1, true, true, false, 1.0);
        assert!(!p.runs(Stage::RasterShading));
        assert_eq!(p.composition(), Composition::RtOverBackground);
        assert!(!p.produces(FrameBuffer::Raster));
        p.validate().unwrap();
        // Below weight 1 the raster shader shades the ray-traced objects too.
        let p = plan(1, true, true, false, 0.75);
        assert_eq!(p.step(Stage::RasterShading), Some(Step::RasterShading { shade_ray_traced: true }));
        assert_eq!(p.composition(), Composition::WeightedMean);
    }

    #[test]
    fn weight_zero_skips_rt_shading() {
        let p = plan(1, true, true, true, 0.0);
        assert!(p
            .skipped()
            .iter()
            .all(|s| s.reason == SkipReason::WeightZero || s.reason == SkipReason::NothingToDenoise));
        assert!(p.skipped().contains(&Skipped { stage: Stage::RtShading, reason: SkipReason::WeightZero }));
        assert_eq!(p.composition(), Composition::CopyRaster);
        p.validate().unwrap();
    }

    #[test]
    fn no_lights_skip_compaction_and_shadow_rays_and_shading_reads_no_mask() {
        let p = plan(0, true, true, true, 1.0);
        assert_eq!(stages(&p), ["visibility_raster", "reconstruction", "rt_shading", "raster_shading", "composition"]);
        assert!(p.skipped().iter().all(|s| [SkipReason::NoLights, SkipReason::MaxDepthZero].contains(&s.reason)));
        assert_eq!(p.reads(Step::RtShading { bounces: false }), [FrameBuffer::Surfaces]);
        assert!(!p.produces(FrameBuffer::Rays) && !p.produces(FrameBuffer::Shadow));
        p.validate().unwrap();
    }

    #[test]
    fn an_empty_scene_rasterizes_the_background_only() {
        let p = plan(1, false, false, false, 1.0);
        assert_eq!(stages(&p), ["visibility_raster", "reconstruction", "raster_shading", "composition"]);
        assert_eq!(p.composition(), Composition::CopyRaster);
        p.validate().unwrap();
    }

    #[test]
    fn every_plan_reads_only_what_it_wrote() {
        for lights in [0, 3] {
            for triangles in [false, true] {
                for ray_traced in [false, true] {
                    for rasterized in [false, true] {
                        for weight in [0.0, 0.25, 1.0] {
                            let p = plan(lights, triangles, ray_traced && triangles, rasterized && triangles, weight);
                            p.validate().unwrap();
                            assert!(p.produces(FrameBuffer::Final));
                            let mut ran: Vec<Stage> = p.steps().iter().map(|s| s.stage()).collect();
                            ran.extend(p.skipped().iter().map(|s| s.stage));
                            ran.sort();
                            ran.dedup();
                            assert_eq!(ran.len(), Stage::ALL.len() - 1, "{p:?}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn bounces_repeat_the_ray_stages_per_depth_and_gather_deepest_first() {
        let p = bouncing_plan(1, 2);
        let labels: Vec<String> = p.steps().iter().map(|s| s.label()).collect();
        assert_eq!(
            labels,
            [
                "visibility_raster",
                "reconstruction",
                "compaction",
                "shadow_rays",
                "secondary_rays{1}",
                "bounce_trace{1}",
                "compaction{1}",
                "shadow_rays{1}",
                "secondary_rays{2}",
                "bounce_trace{2}",
                "compaction{2}",
                "shadow_rays{2}",
                "bounce_shading{2}",
                "bounce_shading{1}",
                "rt_shading",
                "raster_shading",
                "composition"
            ]
        );
        p.validate().unwrap();
        assert_eq!(p.bounce_depth(), 2);
        assert!(p.produces(BounceBuffer::Radiance.at(2)) && !p.produces(BounceBuffer::Radiance.at(3)));
        assert_eq!(p.buffers().filter(|b| b.depth() == 2).count(), BounceBuffer::ALL.len());
        assert_eq!(BounceBuffer::Links.at(2).label(), "bounce2_links");
        assert_eq!(p.skipped(), [Skipped { stage: Stage::ShadowDenoise, reason: SkipReason::NothingToDenoise }]);
        // Only the gathering of radiance reads what rays leaving the scene see.
        let env: Vec<String> =
            p.steps().iter().filter(|s| s.inputs().contains(&Input::Environment)).map(|s| s.label()).collect();
        assert_eq!(env, ["bounce_shading{2}", "bounce_shading{1}"]);
    }

    #[test]
    fn bounces_without_lights_trace_no_shadow_rays_and_shade_without_masks() {
        let p = bouncing_plan(0, 1);
        p.validate().unwrap();
        assert!(!p.produces(BounceBuffer::Shadow.at(1)));
        assert_eq!(
            p.reads(Step::BounceShading { depth: 1, last: true }),
            [BounceBuffer::Rays.at(1), BounceBuffer::Hits.at(1), BounceBuffer::Surfaces.at(1)]
        );
    }

    #[test]
    fn no_mirror_or_glass_plans_no_bounce() {
        let p = FramePlan::from_counts(SceneNeeds { bouncing: false, ..SceneNeeds { ..bouncing_needs() } });
        assert_eq!(p.bounce_depth(), 0);
        assert!(p.skipped().contains(&Skipped { stage: Stage::BounceTrace, reason: SkipReason::NoMirrorsOrGlass }));
        assert_eq!(p.buffers().filter(|b| b.depth() > 0).count(), 0);
    }

    fn bouncing_needs() -> SceneNeeds {
        SceneNeeds {
            lights: 1,
            triangles: true,
            ray_traced: true,
            rasterized: true,
            bouncing: true,
            weight: 1.0,
            max_depth: 4,
            denoise: false,
        }
    }

    #[test]
    fn every_bouncing_plan_reads_only_what_it_wrote() {
        for lights in [0, 2] {
            for max_depth in 0..6 {
                for weight in [0.0, 0.5, 1.0] {
                    for rasterized in [false, true] {
                        let p = FramePlan::from_counts(SceneNeeds {
                            lights,
                            max_depth,
                            weight,
                            rasterized,
                            ..bouncing_needs()
                        });
                        p.validate().unwrap();
                        let want = if weight == 0.0 { 0 } else { max_depth };
                        assert_eq!(p.bounce_depth(), want);
                    }
                }
            }
        }
    }
}
