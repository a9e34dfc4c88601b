//! Determinism: the same frame rendered twice, and with 1 or 2 rayon threads,
//! gives identical bits in every stage's output.

use hyrt::{FrameOptions, Renderer, Scene};
use hyrt_conformance::compare_frames;

#[test]
fn determinism_default_scene_same_bits_across_runs_and_threads() {
    let scene = Scene::default_scene();
    let cam = scene.camera.unwrap();
    let one = Renderer::cpu(Some(1));
    let two = Renderer::cpu(Some(2));
    let (p1, p2) = (one.prepare(&scene), two.prepare(&scene));
    assert_eq!(
        bytemuck::cast_slice::<_, u8>(&p1.bvh.nodes),
        bytemuck::cast_slice::<_, u8>(&p2.bvh.nodes),
        "BVH build differs across thread counts"
    );
    let opts = FrameOptions { weight: 0.7, ..FrameOptions::default() };
    // 131x77: not a multiple of any tile or block size.
    let a = one.render(&p1, &cam, 131, 77, &opts).unwrap();
    let b = one.render(&p1, &cam, 131, 77, &opts).unwrap();
    let c = two.render(&p2, &cam, 131, 77, &opts).unwrap();
    for (x, y, what) in [(&a, &b, "run twice"), (&a, &c, "1 vs 2 threads")] {
        for cmp in compare_frames(x, y) {
            assert!(cmp.is_exact(), "{what}: {} mismatches, first {}", cmp.mismatches, cmp.first.unwrap());
        }
    }
}

#[test]
fn determinism_reused_frame_buffers_give_the_same_bits() {
    // Buffers left from a frame of another size, scene and weight must not leak
    // into the next frame.
    let scene = Scene::default_scene();
    let cam = scene.camera.unwrap();
    let r = Renderer::cpu(Some(2));
    let prepared = r.prepare(&scene);
    let opts = FrameOptions { weight: 0.4, ..FrameOptions::default() };
    let fresh = r.render(&prepared, &cam, 83, 59, &opts).unwrap();
    let mut reused =
        r.render(&prepared, &cam, 120, 90, &FrameOptions { weight: 1.0, ..FrameOptions::default() }).unwrap();
    let mut other = Scene::default_scene();
    other.objects.truncate(2);
    let other = r.prepare(&other);
    r.render_into(&other, &cam, 83, 59, &FrameOptions::default(), &mut reused).unwrap();
    r.render_into(&prepared, &cam, 83, 59, &opts, &mut reused).unwrap();
    for cmp in compare_frames(&fresh, &reused) {
        assert!(cmp.is_exact(), "{} mismatches, first {}", cmp.mismatches, cmp.first.unwrap());
    }
    assert_eq!(fresh.stats.covered_pixels, reused.stats.covered_pixels);
    assert_eq!(fresh.stats.rays_per_kind, reused.stats.rays_per_kind);
}
