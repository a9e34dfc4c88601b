//! The frame as a plan: a frame runs only the stages its scene needs, on both
//! backends, and what it skips changes no bit of what it returns.
//!
//! For each case (no ray-traced object, no rasterized object, no light, weight 0 and
//! 1, an empty scene) the test checks the plan (which stages ran, which were skipped
//! and why, which buffers the frame holds), that the reduced frame's images are the
//! full pipeline's bit for bit (the eight stage functions called in a straight line,
//! as every frame ran before plans), and that the GPU backend runs the same plan and
//! returns the same bits (lavapipe in CI).

use hyrt_conformance::compare::compare_stages;
use hyrt_conformance::report::gpu_for_tests;
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, Frame, FrameOptions, PreparedScene};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::plan::{Composition, FrameBuffer, SkipReason};
use hyrt_core::scene::{RenderMode, Scene};
use hyrt_core::stage::Stage;
use hyrt_cpu::backend::CpuBackend;
use hyrt_cpu::traversal::Traversal;
use hyrt_cpu::{compaction, composition, raster_shading, reconstruction, rt_shading, shadow_rays, visibility_raster};

/// 97x61: not a multiple of any tile or block size.
const W: u32 = 97;
const H: u32 = 61;

struct Case {
    name: &'static str,
    scene: Scene,
    weight: f32,
    ran: &'static [Stage],
    skipped: &'static [(Stage, SkipReason)],
    composition: Composition,
}

fn default_scene() -> Scene {
    let mut s = Scene::default_scene();
    s.ensure_camera_and_lights();
    s
}

fn all(mode: RenderMode) -> Scene {
    let mut s = default_scene();
    for o in &mut s.objects {
        o.render_mode = mode;
    }
    s
}

/// The bounce stages: every case here renders at max depth 0, which skips them.
const BOUNCES: &[Stage] = &[Stage::SecondaryRays, Stage::BounceTrace, Stage::BounceShading];
/// Every stage of the paper's frame (all but the per-scene `bvh_build` and the bounces).
const EVERY: &[Stage] = &[
    Stage::VisibilityRaster,
    Stage::Reconstruction,
    Stage::Compaction,
    Stage::ShadowRays,
    Stage::RtShading,
    Stage::RasterShading,
    Stage::Composition,
];
/// Every frame stage but `rt_shading`.
const WITHOUT_RT: &[Stage] = &[
    Stage::VisibilityRaster,
    Stage::Reconstruction,
    Stage::Compaction,
    Stage::ShadowRays,
    Stage::RasterShading,
    Stage::Composition,
];

fn cases() -> Vec<Case> {
    use SkipReason as R;
    use Stage as S;
    let no_lights = {
        let mut s = default_scene();
        s.lights.clear();
        s
    };
    let empty = {
        let mut s = default_scene();
        s.objects.clear();
        s
    };
    vec![
        Case {
            name: "mixed",
            scene: default_scene(),
            weight: 0.6,
            ran: EVERY,
            skipped: &[],
            composition: Composition::WeightedMean,
        },
        Case {
            name: "no_ray_traced_objects",
            scene: all(RenderMode::Raster),
            weight: 1.0,
            ran: WITHOUT_RT,
            skipped: &[(S::RtShading, R::NoRayTracedObjects)],
            composition: Composition::CopyRaster,
        },
        Case {
            name: "no_rasterized_objects",
            scene: all(RenderMode::RayTraced),
            weight: 1.0,
            ran: &[S::VisibilityRaster, S::Reconstruction, S::Compaction, S::ShadowRays, S::RtShading, S::Composition],
            skipped: &[(S::RasterShading, R::AllRayTracedWeightOne)],
            composition: Composition::RtOverBackground,
        },
        Case {
            name: "no_rasterized_objects_weight_below_one",
            scene: all(RenderMode::RayTraced),
            weight: 0.3,
            ran: EVERY,
            skipped: &[],
            composition: Composition::WeightedMean,
        },
        Case {
            name: "no_lights",
            scene: no_lights,
            weight: 1.0,
            ran: &[S::VisibilityRaster, S::Reconstruction, S::RtShading, S::RasterShading, S::Composition],
            skipped: &[(S::Compaction, R::NoLights), (S::ShadowRays, R::NoLights)],
            composition: Composition::WeightedMean,
        },
        Case {
            name: "weight_zero",
            scene: default_scene(),
            weight: 0.0,
            ran: WITHOUT_RT,
            skipped: &[(S::RtShading, R::WeightZero)],
            composition: Composition::CopyRaster,
        },
        Case {
            name: "weight_one",
            scene: default_scene(),
            weight: 1.0,
            ran: EVERY,
            skipped: &[],
            composition: Composition::WeightedMean,
        },
        Case {
            name: "empty_scene",
            scene: empty,
            weight: 1.0,
            ran: &[S::VisibilityRaster, S::Reconstruction, S::RasterShading, S::Composition],
            skipped: &[
                (S::Compaction, R::NoGeometry),
                (S::ShadowRays, R::NoGeometry),
                (S::RtShading, R::NoRayTracedObjects),
            ],
            composition: Composition::CopyRaster,
        },
    ]
}

/// The frame every plan used to run: all eight stage functions in a straight line.
fn full_pipeline(p: &PreparedScene, cam: &CameraRecord, weight: f32) -> Frame {
    let g = &p.geometry;
    let eye = glam::Vec3::from(cam.eye);
    let vis = visibility_raster::visibility_raster(g, cam);
    let mut surfaces = Vec::new();
    // The default barycentrics (`FrameOptions::default().barycentrics`): re-intersected.
    reconstruction::reconstruction_reintersected_into(&vis.gbuffer, g, cam, &mut surfaces);
    let rays = compaction::compaction(&surfaces, &g.lights);
    let mut occluded = Vec::new();
    shadow_rays::shadow_rays_with(&p.bvh, g, &rays, Traversal::Scalar, &mut occluded);
    let mut shadow = Vec::new();
    compaction::shadow_mask_into(&rays, &occluded, surfaces.len(), g.lights.len(), &mut shadow);
    let rt = rt_shading::rt_shading(&surfaces, &shadow, &g.objects, &g.lights, &g.ambient, eye);
    let raster = raster_shading::raster_shading(&surfaces, &shadow, &g.objects, &g.lights, &g.ambient, eye, weight);
    let final_image = composition::composition(&raster, &rt, weight);
    Frame {
        width: cam.width,
        height: cam.height,
        gbuffer: vis.gbuffer,
        surfaces,
        rays,
        occluded,
        shadow,
        raster,
        rt,
        final_image,
        ..Frame::default()
    }
}

fn bits(img: &[[f32; 4]]) -> Vec<u32> {
    img.iter().flatten().map(|x| x.to_bits()).collect()
}

fn check_plan(case: &Case, backend: &str, f: &Frame) {
    let ran: Vec<Stage> = f.stats.stage_ms.iter().map(|t| t.stage).collect();
    assert_eq!(ran, case.ran, "{backend} / {}: stages that ran", case.name);
    let skipped: Vec<(Stage, SkipReason)> = f
        .stats
        .skipped
        .iter()
        .filter(|s| !BOUNCES.contains(&s.stage) && s.stage != Stage::ShadowDenoise)
        .map(|s| (s.stage, s.reason))
        .collect();
    assert_eq!(skipped, case.skipped, "{backend} / {}: skipped stages", case.name);
    // The bounces are skipped for `rt_shading`'s reason where it is skipped, else for
    // the depth.
    let rt_reason = case.skipped.iter().find(|(s, _)| *s == Stage::RtShading).map(|&(_, r)| r);
    let bounce_reason = rt_reason.unwrap_or(SkipReason::MaxDepthZero);
    // No case traces stochastic rays: `shadow_denoise` is skipped for that, or for the
    // reason the shadow rays are.
    let rays_reason = case.skipped.iter().find(|(s, _)| *s == Stage::ShadowRays).map(|&(_, r)| r);
    let denoise_reason = rays_reason.unwrap_or(SkipReason::NothingToDenoise);
    assert!(
        f.stats.skipped.iter().any(|s| s.stage == Stage::ShadowDenoise && s.reason == denoise_reason),
        "{backend} / {}: shadow_denoise skipped for {denoise_reason:?}: {:?}",
        case.name,
        f.stats.skipped
    );
    for &stage in BOUNCES {
        assert!(
            f.stats.skipped.iter().any(|s| s.stage == stage && s.reason == bounce_reason),
            "{backend} / {}: {stage} skipped for {bounce_reason:?}: {:?}",
            case.name,
            f.stats.skipped
        );
    }
    assert_eq!(f.plan.composition(), case.composition, "{backend} / {}", case.name);
    for b in FrameBuffer::ALL {
        let ran = case.ran.contains(&b.writer());
        let asked =
            FrameOptions { stage_outputs: f.stage_outputs, keep_gbuffer: f.keep_gbuffer, ..FrameOptions::default() };
        let held = ran && asked.returns(b);
        assert_eq!(f.buffer(b).is_some(), held, "{backend} / {}: buffer {b}", case.name);
        if !held {
            let len = match b {
                FrameBuffer::GBuffer => f.gbuffer.len(),
                FrameBuffer::Surfaces => f.surfaces.len(),
                FrameBuffer::Rays => f.rays.len(),
                FrameBuffer::Occluded => f.occluded.len(),
                FrameBuffer::Shadow => f.shadow.len(),
                FrameBuffer::Visibility => f.visibility.len(),
                FrameBuffer::Rt => f.rt.len(),
                FrameBuffer::Raster => f.raster.len(),
                FrameBuffer::Final => f.final_image.len(),
                FrameBuffer::Bounce { .. } => unreachable!("FrameBuffer::ALL holds the primary buffers only"),
            };
            assert_eq!(len, 0, "{backend} / {}: {b} not held is absent, not zero-filled", case.name);
        }
    }
    // Work per stage: shading stages shade only their pixels.
    for t in &f.stats.stage_ms {
        match t.stage {
            Stage::RtShading => assert_eq!(t.work.pixels, f.stats.ray_traced_pixels),
            Stage::ShadowRays => {
                assert_eq!(t.work.rays, f.stats.rays_per_kind, "{backend} / {}", case.name);
                if f.holds(FrameBuffer::Occluded) {
                    assert_eq!(t.work.rays.iter().sum::<u64>(), f.occluded.len() as u64);
                }
            }
            _ => {}
        }
    }
}

#[test]
fn plan_each_case_runs_only_what_it_needs_and_matches_the_full_pipeline() {
    let mut cpu = CpuBackend::new(Some(2));
    for case in cases() {
        let prepared = cpu.prepare(WorldGeometry::build(&case.scene), BvhPreset::default());
        let cam = CameraRecord::new(&case.scene.camera.unwrap(), W, H);
        let opts = FrameOptions { weight: case.weight, stage_outputs: true, max_depth: 0, ..FrameOptions::default() };
        let f = cpu.render(&prepared, &cam, &opts).unwrap();
        check_plan(&case, "cpu", &f);
        let full = full_pipeline(&prepared, &cam, case.weight);
        assert_eq!(bits(&f.final_image), bits(&full.final_image), "{}: final image", case.name);
        assert_eq!(f.gbuffer, full.gbuffer, "{}: gbuffer", case.name);
        for (b, mine, theirs) in [(FrameBuffer::Rt, &f.rt, &full.rt), (FrameBuffer::Raster, &f.raster, &full.raster)] {
            if f.holds(b) {
                assert_eq!(bits(mine), bits(theirs), "{}: {b}", case.name);
            }
        }
        if f.holds(FrameBuffer::Rays) {
            assert_eq!(f.occluded, full.occluded, "{}: occluded", case.name);
            assert_eq!(f.shadow, full.shadow, "{}: shadow", case.name);
        }
    }
}

#[test]
fn plan_each_case_is_the_same_on_the_gpu() {
    let Some(mut gpu) = gpu_for_tests() else { return };
    let mut cpu = CpuBackend::new(Some(2));
    for case in cases() {
        let prepared = cpu.prepare(WorldGeometry::build(&case.scene), BvhPreset::default());
        let cam = CameraRecord::new(&case.scene.camera.unwrap(), W, H);
        for stage_outputs in [true, false] {
            let opts = FrameOptions { weight: case.weight, stage_outputs, max_depth: 0, ..FrameOptions::default() };
            let c = cpu.render(&prepared, &cam, &opts).unwrap();
            let g = gpu.render(&prepared, &cam, &opts).unwrap();
            check_plan(&case, "gpu", &g);
            assert_eq!(c.buffers().collect::<Vec<_>>(), g.buffers().collect::<Vec<_>>(), "{}", case.name);
            for cmp in compare_stages(&c, &g) {
                assert!(cmp.is_exact(), "{} / {} / {} differs: {cmp:?}", case.name, cmp.stage, cmp.buffer);
            }
            assert_eq!(c.stats.rays_per_kind, g.stats.rays_per_kind, "{}", case.name);
        }
    }
}

/// A frame with more rays than the last one: the GPU grows its ray buffers (they
/// start with room for one ray per pixel) and still traces every ray: the frame runs
/// again with room for them.
#[test]
fn plan_gpu_ray_buffers_grow_with_the_rays_a_frame_has() {
    let Some(mut gpu) = gpu_for_tests() else { return };
    let mut cpu = CpuBackend::new(Some(2));
    let few = {
        let mut s = default_scene();
        s.lights.truncate(1);
        s
    };
    let many = {
        // The default lights four times over: about four rays per covered pixel and light.
        let mut s = default_scene();
        let lights = s.lights.clone();
        for _ in 0..3 {
            s.lights.extend(lights.iter().cloned());
        }
        s
    };
    let opts = FrameOptions { weight: 1.0, stage_outputs: true, max_depth: 0, ..FrameOptions::default() };
    for (scene, more_than_pixels) in [(&few, false), (&many, true), (&few, false), (&many, true)] {
        let prepared = cpu.prepare(WorldGeometry::build(scene), BvhPreset::default());
        let cam = CameraRecord::new(&scene.camera.unwrap(), W, H);
        let c = cpu.render(&prepared, &cam, &opts).unwrap();
        let g = gpu.render(&prepared, &cam, &opts).unwrap();
        assert_eq!(c.rays.len() > (W * H) as usize, more_than_pixels, "the case's ray count");
        for cmp in compare_stages(&c, &g) {
            assert!(cmp.is_exact(), "{} / {} differs: {cmp:?}", cmp.stage, cmp.buffer);
        }
    }
}
