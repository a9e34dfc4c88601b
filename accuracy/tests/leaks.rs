//! The leak corpus with the lights *outside* the shells (`hyrt_conformance::leak`): the
//! error-bound origin offsets and the raster's facing must not cost correct shadows. Every
//! traced (pixel, light) pair of the CPU frame is checked against an exact decision: the
//! segment from the pipeline's own primary hit point (its G-buffer barycentrics on its
//! triangle, evaluated in f64: exactly on the triangle's plane) to the light, traced in f64
//! through the BVH ([`hyrt_accuracy::reference::occluded_f64`]). A pair may disagree only
//! where that decision is not stable under the pipeline's own uncertainty: where moving the
//! light by the rounding of the ray ([`light_tolerance`]), or the start off the surface by
//! the hit point's error ([`origin_tolerance`], the band the origin offset skips), flips it:
//! the segment grazes a silhouette of the shell, or an occluder lies within rounding of
//! the surface (a crease of the scan). Both kinds of disagreement are counted: false shadows (self-shadowing from
//! too small an offset, or a hit point behind its surface) and light where the shell is in
//! the way. The GPU backend renders the same scenes bit for bit (`conformance/tests/leaks.rs`).

use glam::{DVec3, Vec3};
use hyrt_accuracy::reference::{occluded_f64, Ray64, REFERENCE_SHADOW_T_MIN};
use hyrt_conformance::leak::{leak_corpus, LightSide, FLOOR_OBJECT, MIN_FEATURE_ULPS, MIN_SHADOW_RAYS, SHELL_OBJECT};
use hyrt_conformance::report::render_case;
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{FrameOptions, PreparedScene, PrimaryBarycentrics, SHADOW_LIT, SHADOW_NO_RAY, SHADOW_OCCLUDED};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::camera::primary_ray;
use hyrt_core::kernels::reconstruction::reintersected_barycentrics;
use hyrt_cpu::backend::CpuBackend;

/// How far the light may move before a decision counts as stable: the pipeline's shadow ray
/// differs from the exact segment by its origin offset (about two error bounds of the hit
/// point along the normal) and by the f32 rounding of its direction (`2^-24` of each
/// component, relative). Seen from the light's end, both shift the segment by less than
/// 16 error bounds plus `2^-20` of its length; 4 ulps of the light's coordinates cover the
/// rounding of its own position.
fn light_tolerance(p_error: f32, segment: DVec3, light: DVec3) -> f64 {
    let ulp = |x: f64| (x.abs() as f32).to_bits().checked_add(1).map_or(0.0, |b| f32::from_bits(b) as f64 - x.abs());
    16.0 * p_error as f64 + segment.length() / (1u64 << 20) as f64 + 4.0 * ulp(light.abs().max_element())
}

/// How far off its surface, along the seen side's normal, the exact start may move: the
/// pipeline's origin is the computed point (within one error bound of `p` per coordinate)
/// offset by at most `1.75` error bounds and one rounding step per coordinate
/// (`offset_ray_origin`); 4 error bounds and 2 ulps cover both.
fn origin_tolerance(p_error: f32, p: DVec3) -> f64 {
    let ulp = |x: f64| f32::from_bits((x.abs() as f32).to_bits() + 1) as f64 - x.abs();
    4.0 * p_error as f64 + 2.0 * ulp(p.abs().max_element())
}

/// The exact decision from `p` to `light`, ignoring the hit triangle itself.
fn exact_occluded(prepared: &PreparedScene, p: DVec3, light: DVec3, triangle: u32) -> bool {
    let ray = Ray64::new(p, light - p).expect("finite segment");
    let t_max = 1.0 - REFERENCE_SHADOW_T_MIN;
    occluded_f64(&prepared.bvh, prepared.geometry.stored_table(), &ray, REFERENCE_SHADOW_T_MIN, t_max, triangle)
}

#[derive(Debug, Default)]
struct Tally {
    traced: u64,
    lit_shell: u64,
    lit_floor: u64,
    shadowed_floor: u64,
    /// Disagreements with a stable exact decision: the failures.
    false_shadows: u64,
    false_light: u64,
    /// Disagreements where the exact decision flips within the tolerance.
    grazing: u64,
}

#[test]
fn leak_corpus_lights_outside_light_and_shadow_what_they_should() {
    let mut cpu = CpuBackend::new(Some(2));
    let mut failures = Vec::new();
    let mut total = Tally::default();
    // `render_case` renders with the default options: re-intersected barycentrics, which the
    // exact points below rebuild.
    assert_eq!(FrameOptions::default().barycentrics, PrimaryBarycentrics::Reintersected);
    for lc in leak_corpus(LightSide::Outside) {
        // The issue's own placement has a 13-ulp gap under the shell, below the corpus's
        // 100-ulp features: no light escapes there (`conformance/tests/leaks.rs`), but the
        // shadow outline on the floor is only resolved to about the gap (a few false
        // shadows of 2 million pairs, measured): not checked here.
        if lc.feature_ulps < 0.99 * MIN_FEATURE_ULPS {
            continue;
        }
        let prepared = cpu.prepare(WorldGeometry::build(&lc.case.scene), BvhPreset::default());
        let frame = render_case(&mut cpu, &prepared, &lc.case).unwrap();
        let camera = CameraRecord::new(&lc.case.camera, lc.case.width, lc.case.height);
        let lights = &prepared.geometry.lights;
        let mut t = Tally::default();
        for (pixel, s) in frame.surfaces.iter().enumerate() {
            if !s.is_hit() {
                continue;
            }
            let texel = frame.gbuffer[pixel];
            let [v0, v1, v2] = prepared.geometry.triangle(s.triangle as usize).vertices().map(|v| v.as_dvec3());
            // The exact point at the barycentrics the frame used: the default's, the
            // pixel's camera ray re-intersected with the raster's triangle.
            let ray = primary_ray(&camera, pixel as u32 % camera.width, pixel as u32 / camera.width);
            let (u, v) = reintersected_barycentrics(&texel, &prepared.geometry, &ray);
            let (u, v) = (u as f64, v as f64);
            let p = v0 * (1.0 - u - v) + v1 * u + v2 * v;
            for (l, light) in lights.iter().enumerate() {
                let got = frame.shadow[pixel * lights.len() + l];
                if got == SHADOW_NO_RAY {
                    continue;
                }
                t.traced += 1;
                match (got, s.object) {
                    (SHADOW_LIT, SHELL_OBJECT) => t.lit_shell += 1,
                    (SHADOW_LIT, FLOOR_OBJECT) => t.lit_floor += 1,
                    (SHADOW_OCCLUDED, FLOOR_OBJECT) => t.shadowed_floor += 1,
                    _ => {}
                }
                let light_pos = Vec3::from(light.position_or_direction).as_dvec3();
                let exact = exact_occluded(&prepared, p, light_pos, s.triangle);
                if exact == (got == SHADOW_OCCLUDED) {
                    continue;
                }
                let tol = light_tolerance(s.position_error, light_pos - p, light_pos);
                let lifted = p + Vec3::from(s.geometric_normal).as_dvec3() * origin_tolerance(s.position_error, p);
                let flips = exact_occluded(&prepared, lifted, light_pos, s.triangle) != exact
                    || [DVec3::X, DVec3::Y, DVec3::Z, -DVec3::X, -DVec3::Y, -DVec3::Z]
                        .iter()
                        .any(|&a| exact_occluded(&prepared, p, light_pos + a * tol, s.triangle) != exact);
                if flips {
                    t.grazing += 1;
                } else if got == SHADOW_OCCLUDED {
                    t.false_shadows += 1;
                    if t.false_shadows <= 3 {
                        eprintln!("{}: false shadow at pixel {pixel} (object {}), light {l}", lc.case.name, s.object);
                    }
                } else {
                    t.false_light += 1;
                    if t.false_light <= 3 {
                        eprintln!(
                            "{}: light through the shell at pixel {pixel} (object {}), light {l}",
                            lc.case.name, s.object
                        );
                    }
                }
            }
        }
        eprintln!("{}: {t:?}", lc.case.name);
        assert!(t.traced >= MIN_SHADOW_RAYS, "{}: only {} shadow rays", lc.case.name, t.traced);
        // The scene shows what it is meant to: a lit shell and a floor both lit and in shadow.
        assert!(t.lit_shell > 1000 && t.lit_floor > 10_000 && t.shadowed_floor > 1000, "{}: {t:?}", lc.case.name);
        if t.false_shadows + t.false_light > 0 {
            failures.push(format!("{}: {t:?}", lc.case.name));
        }
        total.traced += t.traced;
        total.grazing += t.grazing;
        total.false_shadows += t.false_shadows;
        total.false_light += t.false_light;
    }
    eprintln!("all light-outside cases: {total:?}");
    assert!(failures.is_empty(), "shadows differ from the exact decision:\n{}", failures.join("\n"));
    // Grazing pairs are rare: rounding of rays along the shadows' outlines (their count grows
    // with the distance from the origin; 0.05% of the pairs over the corpus, measured).
    assert!(total.grazing * 1000 < total.traced, "{total:?}");
}
