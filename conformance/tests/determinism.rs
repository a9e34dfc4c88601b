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
    let opts = FrameOptions { weight: 0.7 };
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
