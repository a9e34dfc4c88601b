//! Reflection and refraction on both backends: the GPU backend (lavapipe in CI) traces
//! every bounce bit-identical to the CPU reference, buffer by buffer (each depth's rays,
//! links, hits, surfaces, shadow rays, occlusion, shadow codes and radiance), and the
//! images that gather them.

use hyrt_conformance::compare::compare_stages;
use hyrt_conformance::report::gpu_for_tests;
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, FrameOptions};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::scene::Scene;
use hyrt_cpu::backend::CpuBackend;

#[test]
fn bounces_gpu_matches_cpu_on_the_default_scene_at_every_depth() {
    let Some(mut gpu) = gpu_for_tests() else { return };
    let mut cpu = CpuBackend::new(Some(2));
    let scene = Scene::default_scene();
    let prepared = cpu.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    let camera = CameraRecord::new(&scene.camera.unwrap(), 96, 54);
    for max_depth in [1, 2, 4] {
        let opts = FrameOptions { stage_outputs: true, max_depth, ..FrameOptions::default() };
        let expected = cpu.render(&prepared, &camera, &opts).unwrap();
        let actual = gpu.render(&prepared, &camera, &opts).unwrap();
        assert_eq!(expected.plan, actual.plan);
        assert_eq!(expected.plan.bounce_depth(), max_depth);
        assert!(expected.stats.bounces[0].rays_per_kind.iter().sum::<u64>() > 0, "the scene bounces");
        let comparisons = compare_stages(&expected, &actual);
        for d in 1..=max_depth {
            for name in ["rays", "links", "hits", "surfaces", "shadow_rays", "occluded", "shadow", "radiance"] {
                let label = format!("bounce{d}_{name}");
                let c = comparisons.iter().find(|c| c.buffer == label);
                assert!(c.is_some(), "max depth {max_depth}: {label} not compared");
            }
        }
        let compared = |label: &str| comparisons.iter().find(|c| c.buffer == label).map_or(0, |c| c.elements);
        eprintln!(
            "max depth {max_depth}: {:?} rays per depth, {} first-bounce radiance values compared",
            expected.stats.bounces.iter().map(|b| b.rays_per_kind).collect::<Vec<_>>(),
            compared("bounce1_radiance")
        );
        assert!(compared("bounce1_radiance") > 0 && compared("bounce1_links") == 96 * 54);
        let differ: Vec<String> = comparisons
            .into_iter()
            .filter(|c| !c.is_exact())
            .map(|c| format!("{} / {}: {c:?}", c.stage, c.buffer))
            .collect();
        assert!(differ.is_empty(), "max depth {max_depth}: GPU differs:\n{}", differ.join("\n"));
        assert_eq!(expected.stats.bounces, actual.stats.bounces, "max depth {max_depth}");
    }
}
