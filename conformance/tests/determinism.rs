//! Determinism: the same frame rendered twice, and with 1 or 2 rayon threads,
//! gives identical bits in every stage's output (the corpus-wide version is in
//! `corpus.rs`; this one checks BVH builds and reused buffers).

use hyrt_conformance::compare::compare_stages;
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, FrameOptions};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::scene::Scene;
use hyrt_cpu::backend::CpuBackend;

#[test]
fn determinism_default_scene_same_bits_across_runs_and_threads() {
    let scene = Scene::default_scene();
    let mut one = CpuBackend::new(Some(1));
    let mut two = CpuBackend::new(Some(2));
    let p1 = one.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    let p2 = two.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    assert_eq!(
        bytemuck::cast_slice::<_, u8>(&p1.bvh.nodes),
        bytemuck::cast_slice::<_, u8>(&p2.bvh.nodes),
        "BVH build differs across thread counts"
    );
    let opts = FrameOptions { weight: 0.7, ..FrameOptions::with_stage_outputs() };
    // 131x77: not a multiple of any tile or block size.
    let cam = CameraRecord::new(&scene.camera.unwrap(), 131, 77);
    let a = one.render(&p1, &cam, &opts).unwrap();
    let b = one.render(&p1, &cam, &opts).unwrap();
    let c = two.render(&p2, &cam, &opts).unwrap();
    for (x, y, what) in [(&a, &b, "run twice"), (&a, &c, "1 vs 2 threads")] {
        for cmp in compare_stages(x, y) {
            assert!(cmp.is_exact(), "{what}: {} / {} differs: {cmp:?}", cmp.stage, cmp.buffer);
        }
    }
}

#[test]
fn determinism_reused_frame_buffers_give_the_same_bits() {
    // Buffers left from a frame of another size, scene and weight must not leak
    // into the next frame.
    let scene = Scene::default_scene();
    let camera = scene.camera.unwrap();
    let mut r = CpuBackend::new(Some(2));
    let prepared = r.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    let opts = FrameOptions { weight: 0.4, ..FrameOptions::with_stage_outputs() };
    let small = CameraRecord::new(&camera, 83, 59);
    let fresh = r.render(&prepared, &small, &opts).unwrap();
    let big = CameraRecord::new(&camera, 120, 90);
    let mut reused =
        r.render(&prepared, &big, &FrameOptions { weight: 1.0, ..FrameOptions::with_stage_outputs() }).unwrap();
    let mut other = Scene::default_scene();
    other.objects.truncate(2);
    let other = r.prepare(WorldGeometry::build(&other), BvhPreset::default());
    r.render_into(&other, &small, &FrameOptions::with_stage_outputs(), &mut reused).unwrap();
    r.render_into(&prepared, &small, &opts, &mut reused).unwrap();
    for cmp in compare_stages(&fresh, &reused) {
        assert!(cmp.is_exact(), "{} / {} differs: {cmp:?}", cmp.stage, cmp.buffer);
    }
    assert_eq!(fresh.stats.covered_pixels, reused.stats.covered_pixels);
    assert_eq!(fresh.stats.rays_per_kind, reused.stats.rays_per_kind);
}
