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
//! | `rt_shading` | a ray-traced object has triangles and the weight is above 0 | [`SkipReason::NoRayTracedObjects`], [`SkipReason::WeightZero`] |
//! | `raster_shading` | unless every object with triangles is ray traced and the weight is 1 | [`SkipReason::AllRayTracedWeightOne`] |
//! | `composition` | always, as [`Composition::WeightedMean`] when both images exist, else a copy | |
//!
//! The reduced frames are the full frame bit for bit: with no ray-traced pixel the
//! weighted mean returns the raster texel; with weight 0 it returns
//! `raster * 1 + rt * 0 = raster`; with weight 1 and no rasterized object the raster
//! image is 0 on ray-traced pixels and the background elsewhere, so the mean is
//! `0 * 0 + rt * 1 = rt` where `rt` has coverage and the background elsewhere.
//!
//! # Bounces
//!
//! Reflection and refraction (issue 13) repeat a stage sequence per ray depth:
//! compaction of the secondary rays from the shaded surfaces, tracing them (closest
//! hit), rebuilding the surfaces they hit, shadow rays from those, shading, and
//! accumulating into the ray-traced image. They fit as steps that carry their depth:
//!
//! ```text
//! visibility_raster, reconstruction,
//! compaction{depth 0}, shadow_rays{depth 0},            // primary surfaces
//! secondary_rays{depth 1}, trace{depth 1}, ...           // bounce 1 reads depth 0's surfaces
//! rt_shading, raster_shading, composition
//! ```
//!
//! A bounce's steps read the previous depth's buffers and write their own, so the
//! plan stays a flat list that both backends run through the same loop; a scene
//! without a mirror or glass object plans no bounce at all.

use crate::formats::OBJ_RAY_TRACED;
use crate::frame::{FrameOptions, PreparedScene, RenderError};
use crate::stage::Stage;

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
    /// `rt_shading`: the ray-traced image, linear RGBA per pixel.
    Rt,
    /// `raster_shading`: the raster image, linear RGBA per pixel.
    Raster,
    /// `composition`: the final image, linear RGBA per pixel.
    Final,
}

impl FrameBuffer {
    /// Every frame buffer, in the order the stages write them.
    pub const ALL: [FrameBuffer; 8] = [
        FrameBuffer::GBuffer,
        FrameBuffer::Surfaces,
        FrameBuffer::Rays,
        FrameBuffer::Occluded,
        FrameBuffer::Shadow,
        FrameBuffer::Rt,
        FrameBuffer::Raster,
        FrameBuffer::Final,
    ];

    /// The buffer's one name: `--dump` files, conformance reports.
    pub const fn name(self) -> &'static str {
        match self {
            FrameBuffer::GBuffer => "gbuffer",
            FrameBuffer::Surfaces => "surfaces",
            FrameBuffer::Rays => "rays",
            FrameBuffer::Occluded => "occluded",
            FrameBuffer::Shadow => "shadow",
            FrameBuffer::Rt => "rt",
            FrameBuffer::Raster => "raster",
            FrameBuffer::Final => "final",
        }
    }

    /// The stage that writes it.
    pub const fn writer(self) -> Stage {
        match self {
            FrameBuffer::GBuffer => Stage::VisibilityRaster,
            FrameBuffer::Surfaces => Stage::Reconstruction,
            FrameBuffer::Rays => Stage::Compaction,
            FrameBuffer::Occluded | FrameBuffer::Shadow => Stage::ShadowRays,
            FrameBuffer::Rt => Stage::RtShading,
            FrameBuffer::Raster => Stage::RasterShading,
            FrameBuffer::Final => Stage::Composition,
        }
    }

    /// True for the buffers a display loop needs and every backend returns even
    /// without [`FrameOptions::stage_outputs`]: the final image, the G-buffer (pixel
    /// counts, picking) and the occlusion results (the frame's statistics).
    pub const fn always_returned(self) -> bool {
        matches!(self, FrameBuffer::GBuffer | FrameBuffer::Occluded | FrameBuffer::Final)
    }
}

impl std::fmt::Display for FrameBuffer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
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
    /// The frame options (the composition weight).
    Options,
}

/// How `composition` makes the final image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Composition {
    /// Both images exist: the weighted mean where the ray-traced image has coverage,
    /// the raster texel elsewhere (paper 3.5).
    WeightedMean,
    /// Only the raster image exists (no ray-traced object, or weight 0): a copy of it.
    CopyRaster,
    /// Only the ray-traced image exists (every object ray traced, weight 1): it where
    /// it has coverage, the background elsewhere.
    RtOverBackground,
}

impl Composition {
    /// The code the GPU's `composition` reads (`FrameParams::composition`).
    pub const fn code(self) -> u32 {
        match self {
            Composition::WeightedMean => 0,
            Composition::CopyRaster => 1,
            Composition::RtOverBackground => 2,
        }
    }
}

/// One stage of a plan, with what it needs to know of the plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Step {
    VisibilityRaster,
    Reconstruction,
    Compaction,
    ShadowRays,
    RtShading,
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
            Step::Compaction => Stage::Compaction,
            Step::ShadowRays => Stage::ShadowRays,
            Step::RtShading => Stage::RtShading,
            Step::RasterShading { .. } => Stage::RasterShading,
            Step::Composition(_) => Stage::Composition,
        }
    }

    /// The frame buffers this step reads, given whether the plan has shadow results
    /// (it has none without lights: shading then reads no mask).
    pub fn reads(self, with_shadow: bool) -> Vec<FrameBuffer> {
        use FrameBuffer as B;
        let shadow: &[B] = if with_shadow { &[B::Shadow] } else { &[] };
        match self {
            Step::VisibilityRaster => vec![],
            Step::Reconstruction => vec![B::GBuffer],
            Step::Compaction => vec![B::Surfaces],
            Step::ShadowRays => vec![B::Rays],
            Step::RtShading | Step::RasterShading { .. } => [&[B::Surfaces][..], shadow].concat(),
            Step::Composition(Composition::WeightedMean) => vec![B::Raster, B::Rt],
            Step::Composition(Composition::CopyRaster) => vec![B::Raster],
            Step::Composition(Composition::RtOverBackground) => vec![B::Rt],
        }
    }

    /// The frame buffers this step writes.
    pub const fn writes(self) -> &'static [FrameBuffer] {
        use FrameBuffer as B;
        match self {
            Step::VisibilityRaster => &[B::GBuffer],
            Step::Reconstruction => &[B::Surfaces],
            Step::Compaction => &[B::Rays],
            Step::ShadowRays => &[B::Occluded, B::Shadow],
            Step::RtShading => &[B::Rt],
            Step::RasterShading { .. } => &[B::Raster],
            Step::Composition(_) => &[B::Final],
        }
    }

    /// The scene and frame inputs this step reads.
    pub const fn inputs(self) -> &'static [Input] {
        use Input as I;
        match self {
            Step::VisibilityRaster => &[I::Triangles, I::Objects, I::Camera],
            Step::Reconstruction => &[I::Triangles, I::Normals, I::Camera],
            Step::Compaction => &[I::Lights],
            Step::ShadowRays => &[I::Bvh, I::Triangles],
            Step::RtShading => &[I::Objects, I::Lights, I::Camera],
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
}

impl FramePlan {
    /// The plan of a frame of `scene` under `options` (validated here, once).
    pub fn new(scene: &PreparedScene, options: &FrameOptions) -> Result<FramePlan, RenderError> {
        options.validate()?;
        let g = &scene.geometry;
        let with_triangles = || g.objects.iter().filter(|o| o.triangle_count > 0);
        let any_rt = with_triangles().any(|o| o.flags & OBJ_RAY_TRACED != 0);
        let any_raster = with_triangles().any(|o| o.flags & OBJ_RAY_TRACED == 0);
        Ok(FramePlan::from_counts(SceneNeeds {
            lights: g.lights.len() as u32,
            triangles: !g.triangles.is_empty(),
            ray_traced: any_rt,
            rasterized: any_raster,
            weight: options.weight,
        }))
    }

    /// The plan for what a scene holds (see the module docs for the rules).
    pub fn from_counts(needs: SceneNeeds) -> FramePlan {
        let SceneNeeds { lights, triangles, ray_traced, rasterized, weight } = needs;
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
        let rt = if !ray_traced {
            skip(Stage::RtShading, SkipReason::NoRayTracedObjects);
            false
        } else if weight == 0.0 {
            skip(Stage::RtShading, SkipReason::WeightZero);
            false
        } else {
            steps.push(Step::RtShading);
            true
        };
        let raster = if ray_traced && !rasterized && weight == 1.0 {
            skip(Stage::RasterShading, SkipReason::AllRayTracedWeightOne);
            false
        } else {
            steps.push(Step::RasterShading { shade_ray_traced: weight < 1.0 });
            true
        };
        steps.push(Step::Composition(match (raster, rt) {
            (true, true) => Composition::WeightedMean,
            (true, false) => Composition::CopyRaster,
            (false, true) => Composition::RtOverBackground,
            (false, false) => unreachable!("raster_shading is skipped only when rt_shading runs"),
        }));
        FramePlan { steps, skipped, lights }
    }

    /// The steps to run, in order.
    pub fn steps(&self) -> &[Step] {
        &self.steps
    }

    /// The stages left out, each with its reason, in stage order.
    pub fn skipped(&self) -> &[Skipped] {
        &self.skipped
    }

    /// True if the plan runs `stage`.
    pub fn runs(&self, stage: Stage) -> bool {
        self.steps.iter().any(|s| s.stage() == stage)
    }

    /// The step that runs `stage`, if any.
    pub fn step(&self, stage: Stage) -> Option<Step> {
        self.steps.iter().copied().find(|s| s.stage() == stage)
    }

    /// True if a step of the plan writes `buffer`.
    pub fn produces(&self, buffer: FrameBuffer) -> bool {
        self.runs(buffer.writer())
    }

    /// The buffers the plan writes, in stage order.
    pub fn buffers(&self) -> impl Iterator<Item = FrameBuffer> + '_ {
        FrameBuffer::ALL.into_iter().filter(|&b| self.produces(b))
    }

    /// The lights of the scene the plan was made for.
    pub fn lights(&self) -> u32 {
        self.lights
    }

    /// The frame buffers `step` reads in this plan.
    pub fn reads(&self, step: Step) -> Vec<FrameBuffer> {
        step.reads(self.produces(FrameBuffer::Shadow))
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
                    return Err(format!("{} reads {b} before any step writes it", step.stage()));
                }
            }
            written.extend_from_slice(step.writes());
        }
        Ok(())
    }
}

/// What [`FramePlan::from_counts`] decides on: the parts of a scene and of the
/// options that decide which stages a frame needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneNeeds {
    /// Lights in the scene.
    pub lights: u32,
    /// The scene has at least one triangle.
    pub triangles: bool,
    /// An object with triangles is ray traced.
    pub ray_traced: bool,
    /// An object with triangles is rasterized.
    pub rasterized: bool,
    /// The composition weight in [0, 1].
    pub weight: f32,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(lights: u32, triangles: bool, ray_traced: bool, rasterized: bool, weight: f32) -> FramePlan {
        FramePlan::from_counts(SceneNeeds { lights, triangles, ray_traced, rasterized, weight })
    }

    fn stages(p: &FramePlan) -> Vec<&'static str> {
        p.steps().iter().map(|s| s.stage().name()).collect()
    }

    #[test]
    fn the_full_scene_runs_every_frame_stage() {
        let p = plan(2, true, true, true, 0.5);
        assert_eq!(stages(&p), Stage::ALL[1..].iter().map(|s| s.name()).collect::<Vec<_>>());
        assert!(p.skipped().is_empty());
        assert_eq!(p.composition(), Composition::WeightedMean);
        assert_eq!(p.step(Stage::RasterShading), Some(Step::RasterShading { shade_ray_traced: true }));
        p.validate().unwrap();
    }

    #[test]
    fn no_ray_traced_objects_skip_rt_shading_and_copy_the_raster_image() {
        let p = plan(2, true, false, true, 1.0);
        assert!(!p.runs(Stage::RtShading));
        assert_eq!(p.skipped(), &[Skipped { stage: Stage::RtShading, reason: SkipReason::NoRayTracedObjects }]);
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
        assert_eq!(p.skipped(), &[Skipped { stage: Stage::RtShading, reason: SkipReason::WeightZero }]);
        assert_eq!(p.composition(), Composition::CopyRaster);
        p.validate().unwrap();
    }

    #[test]
    fn no_lights_skip_compaction_and_shadow_rays_and_shading_reads_no_mask() {
        let p = plan(0, true, true, true, 1.0);
        assert_eq!(stages(&p), ["visibility_raster", "reconstruction", "rt_shading", "raster_shading", "composition"]);
        assert!(p.skipped().iter().all(|s| s.reason == SkipReason::NoLights));
        assert_eq!(p.reads(Step::RtShading), [FrameBuffer::Surfaces]);
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
                            let ran = p.steps().len() + p.skipped().len();
                            assert_eq!(ran, Stage::ALL.len() - 1, "{p:?}");
                        }
                    }
                }
            }
        }
    }
}
