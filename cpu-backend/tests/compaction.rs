//! Stage `compaction`: the parallel compaction equals a sequential filter, in
//! order, for any flag pattern and size, and the ray list it builds is exactly
//! the set of (light, pixel) pairs whose light can contribute.

use hyrt_core::formats::{LightRecord, SurfaceRecord, INVALID_ID, RAY_KIND_SHADOW};
use hyrt_core::kernels::scan::compact_sequential;
use hyrt_cpu::compaction::{compact, compaction, shadow_mask, COMPACTION_BLOCK};
use proptest::prelude::*;

const B: usize = COMPACTION_BLOCK;

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap()
}

/// Sizes around the block boundaries and a large one.
fn sizes() -> Vec<usize> {
    vec![0, 1, 2, B - 1, B, B + 1, 2 * B - 1, 2 * B + 1, 3 * B + 17, 1 << 20]
}

#[test]
fn compaction_edge_sizes_all_none_alternating() {
    for n in sizes() {
        let all = vec![1u32; n];
        let none = vec![0u32; n];
        let alt: Vec<u32> = (0..n as u32).map(|i| i % 2).collect();
        let last: Vec<u32> = (0..n).map(|i| (i + 1 == n) as u32).collect();
        for flags in [&all, &none, &alt, &last] {
            for t in [1, 2] {
                let got = pool(t).install(|| compact(flags));
                assert_eq!(got, compact_sequential(flags), "size {n}, {t} threads");
            }
        }
        assert_eq!(compact(&all).len(), n);
        assert!(compact(&none).is_empty());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn compaction_equals_sequential_filter(
        flags in prop_oneof![
            proptest::collection::vec(0u32..3, 0..3 * B + 5),
            proptest::collection::vec(prop_oneof![9 => Just(0u32), 1 => any::<u32>()], 0..5 * B),
        ],
        threads in 1usize..=2,
    ) {
        let got = pool(threads).install(|| compact(&flags));
        let want = compact_sequential(&flags);
        prop_assert_eq!(got.len(), flags.iter().filter(|&&f| f != 0).count());
        prop_assert_eq!(got, want);
    }
}

/// A surface whose position is known to within 1e-6 (an error bound as reconstruction
/// gives one for coordinates near 1).
fn surface(p: [f32; 3], n: [f32; 3]) -> SurfaceRecord {
    SurfaceRecord { position: p, position_error: 1e-6, normal: n, object: 0, geometric_normal: n, triangle: 0 }
}

#[test]
fn compaction_builds_one_ray_per_contributing_pair_in_light_major_order() {
    let up = [0.0, 1.0, 0.0];
    let surfaces = vec![
        surface([0.0, 0.0, 0.0], up),
        SurfaceRecord::MISS,
        surface([1.0, 0.0, 0.0], up),
        surface([2.0, 0.0, 0.0], [0.0, -1.0, 0.0]), // faces away from both lights
    ];
    let lights = vec![
        LightRecord::point([0.0, 5.0, 0.0], [1.0; 3]),
        LightRecord::directional([0.0, -1.0, 0.0], [1.0; 3]),
        LightRecord::point([0.0, 5.0, 0.0], [0.0; 3]), // no energy
    ];
    let rays = compaction(&surfaces, &lights);
    let pairs: Vec<(u32, u32)> = rays.iter().map(|r| (r.light, r.pixel)).collect();
    assert_eq!(pairs, vec![(0, 0), (0, 2), (1, 0), (1, 2)]);
    for r in &rays {
        r.validate().unwrap();
        assert_eq!(r.kind, RAY_KIND_SHADOW);
        // Offset along the normal by the error bound (and one more step), nowhere else.
        assert!(r.origin[1] > 1e-6 && r.origin[1] < 2e-6, "origin offset above the surface: {r:?}");
        assert_eq!((r.origin[0], r.origin[2]), (surfaces[r.pixel as usize].position[0], 0.0));
        assert_ne!(r.light, INVALID_ID);
    }
    // Point light rays end just before the light; directional ones are unbounded.
    assert!(rays[0].t_max < 1.0 && rays[2].t_max.is_infinite());
    let mask = shadow_mask(&rays, &[0, 1, 0, 0], surfaces.len(), lights.len());
    use hyrt_core::formats::{SHADOW_LIT as L, SHADOW_NO_RAY as N, SHADOW_OCCLUDED as O};
    assert_eq!(mask, vec![L, L, N, N, N, N, O, L, N, N, N, N]);
}
