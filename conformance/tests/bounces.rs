//! Reflection and refraction on both backends: the GPU backend (lavapipe in CI) traces
//! every bounce bit-identical to the CPU reference, buffer by buffer (each depth's rays,
//! links, hits, surfaces, shadow rays, occlusion, shadow codes and radiance), and the
//! images that gather them.

use glam::Vec3;
use hyrt_conformance::compare::compare_stages;
use hyrt_conformance::corpus::corpus;
use hyrt_conformance::report::{gpu_for_tests, render_case};
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::{
    CameraRecord, SurfaceRecord, TriangleRecord, GBUF_BACK_FACE, INVALID_ID, MATERIAL_GLASS, RAY_KIND_REFLECTION,
    RAY_KIND_REFRACTION,
};
use hyrt_core::frame::{Backend, Frame, FrameOptions};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::ray::meets_zero_edge_tie;
use hyrt_core::plan::Step;
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

/// For each ray of bounce `depth`, the index of its parent: a pixel for depth 1, a ray of
/// depth `depth - 1` beyond (inverted from the parents' links).
fn parents_of(frame: &Frame, depth: u32) -> Vec<usize> {
    let b = &frame.bounces[depth as usize - 1];
    let mut parent = vec![usize::MAX; b.rays.len()];
    for (p, links) in b.links.iter().enumerate() {
        for &child in links {
            if child != INVALID_ID {
                parent[child as usize] = p;
            }
        }
    }
    assert!(parent.iter().all(|&p| p != usize::MAX), "every ray has a parent");
    parent
}

/// The surface a ray of `depth` left from: its parent's (a pixel's primary surface, or
/// the surface the parent ray hit).
fn parent_surface(frame: &Frame, depth: u32, parent: usize) -> SurfaceRecord {
    match depth {
        1 => frame.surfaces[parent],
        d => frame.bounces[d as usize - 2].surfaces[parent],
    }
}

/// The signed distance, in f64, of `p` from the plane of triangle `t`, positive on the
/// side `n` faces.
fn side_of(t: &TriangleRecord, n: Vec3, p: Vec3) -> f64 {
    let [v0, v1, v2] = t.vertices().map(|v| v.as_dvec3());
    let mut normal = (v1 - v0).cross(v2 - v0);
    if normal.dot(n.as_dvec3()) < 0.0 {
        normal = -normal;
    }
    normal.dot(p.as_dvec3() - v0)
}

/// The secondary rays of the `bounce_*` corpus on the CPU reference (the GPU matches it
/// bit for bit in `tests/corpus.rs`): every case bounces; no ray hits the triangle it
/// leaves (no self-intersection); every origin lies on the right side of that triangle's
/// plane, exactly (f64): reflection rays on the seen side, refraction rays on the other;
/// the parallel mirrors reach the depth limit; the high-index sphere reflects totally
/// inside; rays refracted into closed glass all hit it again or what it holds (none
/// escapes through a shared edge or vertex).
#[test]
fn bounce_corpus_offsets_leave_every_surface_on_the_right_side() {
    let mut cpu = CpuBackend::new(Some(2));
    let cases: Vec<_> = corpus().into_iter().filter(|c| c.name.starts_with("bounce_")).collect();
    assert_eq!(cases.len(), 6);
    for case in &cases {
        let prepared = cpu.prepare(WorldGeometry::build(&case.scene), BvhPreset::default());
        let frame = render_case(&mut cpu, &prepared, case).unwrap();
        let g = &prepared.geometry;
        let depth = frame.plan.bounce_depth();
        assert_eq!(depth, case.max_depth, "{}", case.name);
        let (mut rays, mut total_internal, mut entering, mut ties) = (0usize, 0usize, 0usize, 0usize);
        for d in 1..=depth {
            let b = &frame.bounces[d as usize - 1];
            let parents = parents_of(&frame, d);
            for (i, r) in b.rays.iter().enumerate() {
                rays += 1;
                let s = parent_surface(&frame, d, parents[i]);
                let t = &g.triangle(s.triangle as usize);
                let hit = &b.hits[i];
                assert!(
                    !hit.is_hit() || hit.triangle != s.triangle,
                    "{}: bounce {d} ray {i} hits the triangle it leaves: {r:?} {hit:?}",
                    case.name
                );
                let side = side_of(t, Vec3::from(s.geometric_normal), Vec3::from(r.origin));
                let want_seen_side = r.kind == RAY_KIND_REFLECTION;
                assert!(
                    (side > 0.0) == want_seen_side && side != 0.0,
                    "{}: bounce {d} ray {i} (kind {}) starts on the wrong side ({side:e}) of triangle {}",
                    case.name,
                    r.kind,
                    s.triangle
                );
                let object = g.objects[s.object as usize].material_kind;
                if r.kind == RAY_KIND_REFRACTION && object == MATERIAL_GLASS {
                    // Entering a closed glass mesh from outside: it must hit that mesh.
                    let from_outside = if d == 1 {
                        frame.gbuffer[parents[i]].flags & GBUF_BACK_FACE == 0
                    } else {
                        !frame.bounces[d as usize - 2].hits[parents[i]].is_back_face()
                    };
                    if from_outside {
                        entering += 1;
                        assert!(
                            hit.is_hit(),
                            "{}: bounce {d} ray {i} entered glass object {} and left it without a hit: {hit:?}",
                            case.name,
                            s.object
                        );
                        let (o, dir) = (Vec3::from(r.origin), Vec3::from(r.direction));
                        ties += g.stored_table().iter().any(|t| {
                            let [v0, v1, v2] = t.vertices();
                            t.object == s.object && meets_zero_edge_tie(o, dir, v0, v1, v2)
                        }) as usize;
                    }
                }
                // A parent inside glass whose reflection was traced but not its
                // refraction: total internal reflection.
                if r.kind == RAY_KIND_REFLECTION && d > 1 && object == MATERIAL_GLASS {
                    let links = frame.bounces[d as usize - 1].links[parents[i]];
                    let inside = frame.bounces[d as usize - 2].hits[parents[i]].is_back_face();
                    total_internal += (inside && links[1] == INVALID_ID) as usize;
                }
            }
        }
        eprintln!(
            "{}: {rays} secondary rays over {depth} bounces, {entering} entering glass ({ties} through an exactly-zero edge), {total_internal} totally reflected inside",
            case.name
        );
        assert!(rays > 0, "{}: nothing bounces", case.name);
        match case.name.as_str() {
            "bounce_parallel_mirrors" => {
                assert!(frame.stats.bounces[depth as usize - 1].rays_per_kind[RAY_KIND_REFLECTION as usize] > 0)
            }
            "bounce_glass_total_internal_reflection" => assert!(total_internal > 0, "no total internal reflection"),
            "bounce_through_shared_edges_and_vertices" => {
                assert!(ties > 0, "the case must send refracted rays through exactly-zero edge functions")
            }
            _ => {}
        }
    }
}

/// A scene without lights still bounces: no shadow ray at any depth, no compaction or
/// shadow_rays step planned for them, and the radiance gathered all the same (the GPU
/// matches it in `tests/corpus.rs`).
#[test]
fn bounces_without_lights_plan_no_shadow_rays() {
    let mut cpu = CpuBackend::new(Some(2));
    let case = corpus().into_iter().find(|c| c.name == "degenerate_no_lights").expect("the case");
    let prepared = cpu.prepare(WorldGeometry::build(&case.scene), BvhPreset::default());
    let frame = render_case(&mut cpu, &prepared, &case).unwrap();
    assert_eq!(frame.plan.bounce_depth(), case.max_depth);
    let b = &frame.stats.bounces[0];
    assert!(b.rays_per_kind[RAY_KIND_REFLECTION as usize] > 0 && b.rays_per_kind[RAY_KIND_REFRACTION as usize] > 0);
    assert!(frame.stats.bounces.iter().all(|b| b.rays_per_kind[0] == 0), "no shadow ray");
    assert!(frame
        .plan
        .steps()
        .iter()
        .all(|s| !matches!(s, Step::BounceCompaction { .. } | Step::BounceShadowRays { .. })));
    assert!(frame.bounces[0].radiance.iter().any(|r| r[0] > 0.0), "the lobes see the sky");
}
