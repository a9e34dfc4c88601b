//! The CPU backend's SIMD packet traversal against its scalar reference over the whole
//! conformance corpus (the traversal issue's point 2): every case's shadow rays (any hit)
//! and one primary ray per pixel (closest hit: triangle, `t`, `u`, `v` bit for bit), at
//! every SIMD level this CPU has, and the whole frame rendered with either `shadow_rays`
//! traversal gives the same bits in every stage.

use hyrt_conformance::compare::compare_stages;
use hyrt_conformance::corpus::corpus;
use hyrt_conformance::report::render_case;
use hyrt_core::bvh::{BvhPreset, ClosestHit};
use hyrt_core::formats::CameraRecord;
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::camera::primary_rays;
use hyrt_cpu::backend::CpuBackend;
use hyrt_cpu::traversal::{closest_hit_alpha_batch_into, occluded_alpha_batch_into, Traversal};

fn bits(h: &Option<ClosestHit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.triangle, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()))
}

#[test]
fn traversal_packets_match_scalar_over_the_corpus() {
    let mut packets = CpuBackend::new(Some(2));
    let mut scalar = CpuBackend::new(Some(2));
    scalar.set_shadow_traversal(Traversal::Scalar);
    scalar.set_bounce_traversal(Traversal::Scalar);
    let (mut shadow_rays, mut occluded, mut primary, mut hits) = (0, 0, 0, 0);
    for case in corpus() {
        let p = packets.prepare(WorldGeometry::build(&case.scene), BvhPreset::default());
        let a = render_case(&mut packets, &p, &case).unwrap();
        let b = render_case(&mut scalar, &p, &case).unwrap();
        for cmp in compare_stages(&a, &b) {
            assert!(
                cmp.is_exact(),
                "{}: packets vs scalar: {} / {} differs: {cmp:?}",
                case.name,
                cmp.stage,
                cmp.buffer
            );
        }
        let (g, bvh) = (&p.geometry, &p.bvh);
        let cam = primary_rays(&CameraRecord::new(&case.camera, case.width, case.height));
        // With the scene's alpha tests, as the frame traces (the texture cases have some).
        let view = g.surface.view();
        let any_hit = |kind| {
            let mut out = Vec::new();
            occluded_alpha_batch_into(bvh, g.stored_table(), &view, &a.rays, kind, &mut out);
            out
        };
        let closest_hit = |kind| {
            let mut out = Vec::new();
            closest_hit_alpha_batch_into(bvh, g.stored_table(), &view, &cam, kind, &mut out);
            out
        };
        let (want_any, want_closest) = (any_hit(Traversal::Scalar), closest_hit(Traversal::Scalar));
        for kind in Traversal::available_simd() {
            let level = kind.name();
            let any = any_hit(kind);
            assert_eq!(any, want_any, "{}: {level:?} any hit", case.name);
            let closest = closest_hit(kind);
            for (i, (x, y)) in closest.iter().zip(&want_closest).enumerate() {
                assert_eq!(bits(x), bits(y), "{}: {level:?} closest hit of pixel {i}", case.name);
            }
        }
        shadow_rays += a.rays.len();
        occluded += want_any.iter().filter(|&&o| o != 0).count();
        primary += cam.len();
        hits += want_closest.iter().filter(|h| h.is_some()).count();
    }
    // Not a vacuous comparison: both answers occur in bulk.
    assert!(occluded > 1000 && shadow_rays - occluded > 1000, "{occluded} of {shadow_rays} shadow rays occluded");
    assert!(hits > 1000 && primary - hits > 1000, "{hits} of {primary} primary rays hit");
}
