//! The speed-against-error module: the f64 reference against analytic scenes with known
//! answers, the variants' defining properties, and the entry point end to end.

mod common;

use common::reference_of;
use hyrt::formats::CameraRecord;
use hyrt::glam::{DVec3, Mat4, Quat, Vec3};
use hyrt::{Bvh, BvhPreset, Camera, Light, Material, Mesh, RenderMode, Scene, WorldGeometry};
use hyrt_accuracy::bounce_variants::CUTOFFS_LOG2;
use hyrt_accuracy::metrics::compare_shadows;
use hyrt_accuracy::plot::FONT_PATH;
use hyrt_accuracy::reference::{closest_hit_f64, Ray64};
use hyrt_accuracy::shadow_map::shadow_map_mask;
use hyrt_accuracy::variants::{reoffset_rays, OffsetMethod};
use hyrt_accuracy::{speed_vs_error, AccuracyError, AccuracyOptions, BOUNCE_GROUPS, MAX_DEPTHS};
use hyrt_core::frame::{SHADOW_LIT, SHADOW_NO_RAY, SHADOW_OCCLUDED};
use hyrt_cpu::compaction::compaction;
use hyrt_cpu::reconstruction::reconstruction;
use hyrt_cpu::shadow_rays::shadow_rays;
use hyrt_cpu::visibility_raster::visibility_raster;
use proptest::prelude::*;

/// Ground: a 20 x 20 square at y = 0. Occluder: a square of half-size `A` at height `H`.
const A: f64 = 1.0;
const H: f64 = 2.0;

/// Points closer than this to an analytic shadow or silhouette outline are not checked:
/// the f64 answer there is decided by rounding (about 1e-15), and f32 geometry (the
/// occluder's corners at +-1 and 2 are exact) is otherwise exact.
const OUTLINE_TOLERANCE: f64 = 1e-9;

fn add(scene: &mut Scene, mesh: Mesh, transform: Mat4) -> u32 {
    scene.add_object(mesh, Material::grey(), transform, RenderMode::Raster)
}

/// The quad-over-plane scene under one light, seen from straight above; the occluder
/// turned by `angle` radians about the vertical.
fn quad_scene(light: Light, angle: f32) -> Scene {
    let mut scene = Scene::default();
    add(&mut scene, Mesh::grid("ground", 4), Mat4::from_scale(Vec3::splat(20.0)));
    let occ = Mat4::from_translation(Vec3::new(0.0, H as f32, 0.0))
        * Mat4::from_rotation_y(angle)
        * Mat4::from_scale(Vec3::splat(2.0 * A as f32));
    add(&mut scene, Mesh::grid("occluder", 1), occ);
    scene.lights.push(light);
    scene.camera = Some(Camera {
        eye: Vec3::new(0.0, 12.0, 0.0),
        target: Vec3::ZERO,
        up: Vec3::NEG_Z,
        fov_y_deg: 50.0,
        near: 0.5,
        far: 40.0,
    });
    scene
}

/// Signed distance of `(x, z)` outside the square `[-s, s]^2` (negative inside).
fn square_distance(x: f64, z: f64, s: f64) -> f64 {
    (x.abs() - s).max(z.abs() - s)
}

#[test]
fn reference_shadow_of_a_quad_under_a_point_light_has_the_exact_outline() {
    let light_y = 6.0;
    let light = Light::point(Vec3::new(0.0, light_y as f32, 0.0), Vec3::ONE, 30.0);
    let scene = quad_scene(light, 0.0);
    let (_, _, r) = reference_of(&scene, 96, 96);
    // Central projection from the light: the shadow is the square scaled by y_l / (y_l - H).
    let s = A * light_y / (light_y - H);
    let (mut shadowed, mut lit, mut occluder) = (0, 0, 0);
    for (i, h) in r.hits.iter().enumerate() {
        let h = h.expect("the ground fills the view");
        let p = h.position;
        if h.object == 1 {
            occluder += 1;
            assert!(square_distance(p.x, p.z, A) <= OUTLINE_TOLERANCE && (p.y - H).abs() < 1e-12, "{p}");
            assert_eq!(r.shadow[i], SHADOW_LIT, "the occluder's top faces the light");
            continue;
        }
        assert!(p.y.abs() < 1e-12, "ground hit off the plane: {p}");
        let d = square_distance(p.x, p.z, s);
        if d.abs() < OUTLINE_TOLERANCE {
            continue;
        }
        let expected = if d < 0.0 { SHADOW_OCCLUDED } else { SHADOW_LIT };
        assert_eq!(r.shadow[i], expected, "pixel {i} at {p}: distance {d} to the shadow outline");
        if d < 0.0 {
            shadowed += 1;
        } else {
            lit += 1;
        }
    }
    assert!(shadowed > 100 && lit > 100 && occluder > 50, "{shadowed} {lit} {occluder}");
}

#[test]
fn reference_shadow_of_a_quad_under_a_directional_light_is_the_translated_square() {
    // Light travelling along d: a ground point is shadowed iff p - d * (H / -d.y) lands in the square.
    let d = Vec3::new(0.3, -1.0, 0.2);
    let scene = quad_scene(Light::Directional { direction: d, color: Vec3::ONE, intensity: 1.0 }, 0.0);
    let (_, _, r) = reference_of(&scene, 96, 96);
    let dd = d.as_dvec3();
    let mut shadowed = 0;
    for (i, h) in r.hits.iter().enumerate() {
        let h = h.unwrap();
        if h.object != 0 {
            continue;
        }
        let q = h.position - dd * (H / -dd.y);
        let dist = square_distance(q.x, q.z, A);
        if dist.abs() < OUTLINE_TOLERANCE {
            continue;
        }
        let expected = if dist < 0.0 { SHADOW_OCCLUDED } else { SHADOW_LIT };
        assert_eq!(r.shadow[i], expected, "pixel {i} at {}", h.position);
        shadowed += (dist < 0.0) as u32;
    }
    assert!(shadowed > 50, "{shadowed}");
}

/// A UV sphere of radius `radius` at `center` above the ground, lit from above.
fn sphere_scene(center: Vec3, radius: f32) -> Scene {
    let mut scene = Scene::default();
    add(
        &mut scene,
        Mesh::grid("ground", 2),
        Mat4::from_translation(center - Vec3::Y * 2.0 * radius) * Mat4::from_scale(Vec3::splat(12.0 * radius)),
    );
    add(
        &mut scene,
        Mesh::uv_sphere("sphere", 24, 12),
        Mat4::from_translation(center) * Mat4::from_scale(Vec3::splat(radius)),
    );
    scene.lights.push(Light::Point {
        position: center + Vec3::new(0.5, 3.0, 0.25) * radius,
        color: Vec3::ONE,
        intensity: 10.0,
        range: None,
    });
    scene.camera = Some(Camera {
        eye: center + Vec3::new(0.0, 2.0, 5.0) * radius,
        target: center - Vec3::Y * radius,
        up: Vec3::Y,
        fov_y_deg: 60.0,
        near: 0.1 * radius,
        far: 40.0 * radius,
    });
    scene
}

/// Radius of the largest ball about `c` inside the convex mesh (the smallest distance to
/// a face plane) and of the smallest ball containing it, in f64.
fn sphere_radii(g: &WorldGeometry, c: DVec3) -> (f64, f64) {
    let (mut r_in, mut r_out) = (f64::INFINITY, 0f64);
    for t in g.stored_table().iter().filter(|t| t.object == 1) {
        let [a, b, d] = t.vertices().map(|v| v.as_dvec3() - c);
        let n = (b - a).cross(d - a);
        if n.length() > 0.0 {
            r_in = r_in.min(a.dot(n.normalize()).abs());
        }
        r_out = r_out.max(a.length()).max(b.length()).max(d.length());
    }
    (r_in, r_out)
}

/// Distance from `c` to the segment `[p, q]`.
fn segment_distance(c: DVec3, p: DVec3, q: DVec3) -> f64 {
    let d = q - p;
    let t = ((c - p).dot(d) / d.length_squared()).clamp(0.0, 1.0);
    (p + d * t - c).length()
}

#[test]
fn reference_sphere_visibility_and_shadow_match_the_inscribed_and_circumscribed_balls() {
    for (center, radius) in [(Vec3::ZERO, 1.0f32), (Vec3::new(148376.0, 1234.0, -223423.0), 50.0)] {
        let scene = sphere_scene(center, radius);
        let (g, _, r) = reference_of(&scene, 80, 60);
        let c = center.as_dvec3();
        let (r_in, r_out) = sphere_radii(&g, c);
        assert!(r_in > 0.95 * radius as f64 && r_out < 1.001 * radius as f64, "{r_in} {r_out}");
        let Light::Point { position, .. } = scene.lights[0] else { unreachable!() };
        let light = position.as_dvec3();
        let cam = hyrt_accuracy::reference::Camera64::new(&scene.camera.unwrap(), 80, 60);
        let (mut sphere_pixels, mut checked_shadows) = (0, 0);
        for (i, h) in r.hits.iter().enumerate() {
            // Primary visibility: rays through the inner ball hit the sphere, rays missing the outer one do not.
            let (o, d) = cam.primary_ray(i as u32 % 80, i as u32 / 80);
            let miss_distance = segment_distance(c, o, o + d);
            let on_sphere = h.is_some_and(|h| h.object == 1);
            if miss_distance < r_in * (1.0 - 1e-9) {
                assert!(on_sphere, "pixel {i}: ray passes {miss_distance} from the centre, r_in {r_in}");
            } else if miss_distance > r_out * (1.0 + 1e-9) {
                assert!(!on_sphere, "pixel {i}: ray passes {miss_distance} from the centre, r_out {r_out}");
            }
            let Some(h) = h else { continue };
            if h.object == 1 {
                sphere_pixels += 1;
                // Convex: a face that sees the light is never shadowed by the sphere.
                assert_ne!(r.shadow[i], SHADOW_OCCLUDED, "self-shadow on a convex mesh at pixel {i}");
                continue;
            }
            let dist = segment_distance(c, h.position, light);
            if dist < r_in * (1.0 - 1e-9) {
                assert_eq!(r.shadow[i], SHADOW_OCCLUDED, "ground pixel {i} behind the sphere");
                checked_shadows += 1;
            } else if dist > r_out * (1.0 + 1e-9) {
                assert_eq!(r.shadow[i], SHADOW_LIT, "ground pixel {i} clear of the sphere");
            }
        }
        assert!(sphere_pixels > 200 && checked_shadows > 20, "{sphere_pixels} {checked_shadows}");
    }
}

/// The closed UV sphere at `center`, its triangles, and a BVH over them.
fn closed_sphere(center: Vec3, radius: f32) -> (WorldGeometry, Bvh) {
    let mut scene = Scene::default();
    add(
        &mut scene,
        Mesh::uv_sphere("sphere", 17, 9),
        Mat4::from_translation(center) * Mat4::from_scale(Vec3::splat(radius)),
    );
    let g = WorldGeometry::build(&scene);
    let bvh = Bvh::build(&g, BvhPreset::default());
    (g, bvh)
}

/// Rays from `origin` (inside the closed mesh) through each vertex and each edge
/// midpoint: exactly on shared vertices and edges, the hard cases of watertightness.
fn assert_no_holes(g: &WorldGeometry, bvh: &Bvh, origin: DVec3) {
    for t in g.stored_table() {
        let [a, b, c] = t.vertices().map(|v| v.as_dvec3());
        for target in [a, b, c, (a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5] {
            let ray = Ray64::new(origin, target - origin).unwrap();
            assert!(
                closest_hit_f64(bvh, g.stored_table(), &ray, 0.0, f64::INFINITY).is_some(),
                "ray from {origin} through {target} escapes the closed mesh"
            );
        }
    }
}

#[test]
fn f64_triangle_test_is_watertight_on_a_closed_mesh_through_vertices_and_edges() {
    for center in [Vec3::ZERO, Vec3::new(148376.0, 1234.0, -223423.0)] {
        let (g, bvh) = closed_sphere(center, 10.0);
        assert_no_holes(&g, &bvh, center.as_dvec3());
        assert_no_holes(&g, &bvh, center.as_dvec3() + DVec3::new(1.0, -2.5, 0.75));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn f64_triangle_test_is_watertight_for_random_directions(
        x in -1.0f64..1.0, y in -1.0f64..1.0, z in -1.0f64..1.0, far in any::<bool>(),
    ) {
        prop_assume!(x * x + y * y + z * z > 1e-6);
        let center = if far { Vec3::new(148376.0, 1234.0, -223423.0) } else { Vec3::ZERO };
        let (g, bvh) = closed_sphere(center, 10.0);
        let ray = Ray64::new(center.as_dvec3(), DVec3::new(x, y, z)).unwrap();
        prop_assert!(closest_hit_f64(&bvh, g.stored_table(), &ray, 0.0, f64::INFINITY).is_some());
    }

    #[test]
    fn f64_bvh_closest_hit_equals_brute_force(
        ox in -3.0f64..3.0, oy in 0.5f64..4.0, oz in -3.0f64..3.0,
        dx in -1.0f64..1.0, dy in -1.0f64..1.0, dz in -1.0f64..1.0,
    ) {
        prop_assume!(dx * dx + dy * dy + dz * dz > 1e-6);
        let g = WorldGeometry::build(&Scene::default_scene());
        let bvh = Bvh::build(&g, BvhPreset::Medium);
        let ray = Ray64::new(DVec3::new(ox, oy, oz), DVec3::new(dx, dy, dz)).unwrap();
        let got = closest_hit_f64(&bvh, g.stored_table(), &ray, 0.0, f64::INFINITY);
        let mut best: Option<(u32, f64)> = None;
        for (i, t) in g.stored_table().iter().enumerate() {
            if let Some(h) = ray.intersect(0.0, f64::INFINITY, t.v0.into(), t.v1.into(), t.v2.into()) {
                if best.is_none_or(|(_, bt)| h.t < bt) {
                    best = Some((i as u32, h.t));
                }
            }
        }
        prop_assert_eq!(got.map(|(i, h)| (i, h.t)), best);
    }
}

/// A plane tilted about two axes, far from the origin (f32 reconstruction error there is
/// large against the plane's own size), seen and lit from its front side.
fn tilted_plane_scene() -> Scene {
    let mut scene = Scene::default();
    let center = Vec3::new(310.0, 47.0, -205.0);
    let rot = Quat::from_rotation_x(0.7) * Quat::from_rotation_z(0.4);
    add(&mut scene, Mesh::grid("plane", 8), Mat4::from_scale_rotation_translation(Vec3::splat(10.0), rot, center));
    let n = rot * Vec3::Y;
    scene.lights.push(Light::point(center + n * 6.0 + Vec3::X * 2.0, Vec3::ONE, 40.0));
    scene.camera = Some(Camera {
        eye: center + n * 8.0 - Vec3::X * 3.0,
        target: center,
        up: Vec3::Y,
        fov_y_deg: 50.0,
        near: 0.1,
        far: 100.0,
    });
    scene
}

#[test]
fn no_offset_gives_shadow_acne_on_a_tilted_plane_and_the_robust_offsets_none() {
    let scene = tilted_plane_scene();
    let g = WorldGeometry::build(&scene);
    let bvh = Bvh::build(&g, BvhPreset::default());
    let cam = CameraRecord::new(&scene.camera.unwrap(), 96, 64);
    let surfaces = reconstruction(&visibility_raster(&g, &cam).gbuffer, &g, Vec3::from(cam.eye));
    let rays = compaction(&surfaces, &g.lights);
    assert!(rays.len() > 4000, "the plane fills the view and faces the light: {}", rays.len());
    let occluded_with = |method| {
        let mut rays = rays.clone();
        reoffset_rays(&mut rays, &surfaces, &g.lights, method, g.scene_extent());
        shadow_rays(&bvh, &g, &rays).iter().filter(|&&o| o != 0).count()
    };
    // Only the plane itself is in the scene: every occluded ray is a self-intersection.
    let none = occluded_with(OffsetMethod::None);
    assert!(none * 20 > rays.len(), "expected acne on over 5% of the rays without an offset, got {none}");
    assert_eq!(occluded_with(OffsetMethod::ErrorBound), 0);
    assert_eq!(occluded_with(OffsetMethod::IntegerUlps), 0);
    assert_eq!(occluded_with(OffsetMethod::Epsilon), 0);
}

#[test]
fn shadow_maps_converge_to_the_reference_as_resolution_grows() {
    for light in [
        Light::point(Vec3::new(0.7, 6.0, -0.4), Vec3::ONE, 30.0),
        Light::Directional { direction: Vec3::new(0.3, -1.0, 0.2), color: Vec3::ONE, intensity: 1.0 },
    ] {
        // Turned, so that the outline is aligned with neither the pixels nor the texels
        // (aligned, whole rows of pixels fall on one side of a texel row and the error
        // jumps with resolution instead of shrinking).
        let scene = quad_scene(light, 0.37);
        let (g, _, r) = reference_of(&scene, 128, 128);
        let cam = CameraRecord::new(&scene.camera.unwrap(), 128, 128);
        let surfaces = reconstruction(&visibility_raster(&g, &cam).gbuffer, &g, Vec3::from(cam.eye));
        let mismatches: Vec<u64> = [32, 128, 512, 2048]
            .iter()
            .map(|&res| {
                let c = compare_shadows(&r, &surfaces, &shadow_map_mask(&g, &surfaces, res));
                eprintln!("{res}: {c:?}");
                c.mismatches()
            })
            .collect();
        let compared = compare_shadows(&r, &surfaces, &shadow_map_mask(&g, &surfaces, 32)).compared;
        assert!(compared > 10_000, "{compared}");
        assert!(mismatches[0] > 0, "a 32-texel map cannot draw this outline exactly: {mismatches:?}");
        for w in mismatches.windows(2) {
            assert!(w[1] <= w[0], "{light:?}: mismatches must not grow with resolution: {mismatches:?}");
        }
        assert!(mismatches[3] * 8 <= mismatches[0], "{light:?}: {mismatches:?}");
        // The mask marks the same (pixel, light) pairs as traced as the ray tracer does.
        let mask = shadow_map_mask(&g, &surfaces, 64);
        let rays = compaction(&surfaces, &g.lights);
        assert_eq!(mask.iter().filter(|&&m| m != SHADOW_NO_RAY).count(), rays.len());
    }
}

#[test]
fn speed_vs_error_on_the_default_scene_writes_a_plot_and_a_table() {
    let mut scene = Scene::default_scene();
    scene.ensure_camera_and_lights();
    let dir = tempfile::tempdir().unwrap();
    let opts = AccuracyOptions { quick: true, threads: 2, width: 64, height: 36 };
    let result = speed_vs_error("default scene", &scene, &opts, dir.path(), &|_| {});
    if !std::path::Path::new(FONT_PATH).exists() {
        eprintln!("{FONT_PATH} missing: the entry point must say so");
        assert!(matches!(result, Err(AccuracyError::Plot(_))), "{result:?}");
        assert!(std::env::var_os("CI").is_none(), "CI installs fonts-dejavu-core (.ci/run): the plot must be drawn");
        return;
    }
    let s = result.unwrap();
    let groups = [
        ("bvh", BvhPreset::ALL.len()),
        ("barycentrics", 3),
        ("ray origin", 4),
        ("shadows", 3),
        ("max depth", MAX_DEPTHS as usize + 1),
        ("bounce origin", 4),
        ("throughput cut-off", CUTOFFS_LOG2.len()),
    ];
    assert_eq!(s.rows.len(), groups.iter().map(|g| g.1).sum::<usize>());
    for (group, n) in groups {
        assert_eq!(s.rows.iter().filter(|r| r.group == group).count(), n, "{group}");
    }
    for r in &s.rows {
        assert!(s.markdown.contains(&format!("| {} | {} |", r.group, r.configuration)), "{}", r.configuration);
        assert!(r.frame_ms > 0.0 && r.rmse.is_finite() && (0.0..=1.0).contains(&r.flip), "{r:?}");
        assert!(r.shadow.compared > 0 && r.hit_error.max_rel < 1e-2, "{r:?}");
        assert!(r.wrong_pixels <= 64 * 36, "{r:?}");
        assert_eq!(r.secondary_rays.is_some(), BOUNCE_GROUPS.contains(&r.group.as_str()), "{r:?}");
    }
    let row = |g: &str, c: &str| s.rows.iter().find(|r| r.group == g && r.configuration.starts_with(c)).unwrap();
    assert!(row("ray origin", "none").shadow.false_shadow > row("ray origin", "error bound").shadow.false_shadow);
    assert!(row("ray origin", "none").shadow.false_shadow > row("ray origin", "256 ulps").shadow.false_shadow);
    // Re-intersected barycentrics: hit points closer to the f64 reference's than the
    // raster's (which carry the 1/256-pixel vertex snapping).
    let (raster, exact) = (row("barycentrics", "f32").hit_error, row("barycentrics", "re-intersected").hit_error);
    assert!(exact.mean_rel < raster.mean_rel / 4.0, "{exact:?} vs {raster:?}");
    assert!(exact.max_rel <= raster.max_rel, "{exact:?} vs {raster:?}");
    // The pipeline's frame at max depth 4 three times: the same image, the same errors.
    let pipeline = row("max depth", "4");
    for other in [row("bounce origin", "error bound"), row("throughput cut-off", "1/256")] {
        assert_eq!((other.rmse, other.flip, other.wrong_pixels), (pipeline.rmse, pipeline.flip, pipeline.wrong_pixels));
        assert_eq!(other.secondary_rays, pipeline.secondary_rays);
    }
    assert_eq!(row("max depth", "0").secondary_rays, Some(0));
    assert!(row("max depth", "8").rmse < row("max depth", "0").rmse, "bounces bring the frame closer");
    assert_eq!(
        s.plots,
        vec![dir.path().join("accuracy-default_scene.png"), dir.path().join("accuracy-bounces-default_scene.png")]
    );
    for plot in &s.plots {
        let png = image::open(plot).unwrap();
        assert!(png.width() > 1000 && png.height() > 500);
    }
    assert!(s.markdown.contains("(accuracy-default_scene.png)"));
    assert!(s.markdown.contains("(accuracy-bounces-default_scene.png)"));
}

#[test]
fn speed_vs_error_skips_the_bounce_groups_without_mirror_or_glass_and_says_why() {
    if !std::path::Path::new(FONT_PATH).exists() {
        eprintln!("{FONT_PATH} missing: skipped (the default-scene test checks the error)");
        return;
    }
    let scene = quad_scene(Light::point(Vec3::new(0.7, 6.0, -0.4), Vec3::ONE, 30.0), 0.37);
    let dir = tempfile::tempdir().unwrap();
    let opts = AccuracyOptions { quick: true, threads: 1, width: 24, height: 24 };
    let s = speed_vs_error("quad", &scene, &opts, dir.path(), &|_| {}).unwrap();
    assert!(s.rows.iter().all(|r| !BOUNCE_GROUPS.contains(&r.group.as_str())));
    assert!(
        s.markdown.contains("No bounce groups on quad: the scene has no ray-traced mirror or glass"),
        "{}",
        s.markdown
    );
    assert_eq!(s.plots.len(), 1);
}

#[test]
fn speed_vs_error_rejects_an_empty_image_and_a_scene_without_camera() {
    let dir = tempfile::tempdir().unwrap();
    let opts = AccuracyOptions { quick: true, threads: 1, width: 0, height: 36 };
    let scene = Scene::default_scene();
    let e = speed_vs_error("s", &scene, &opts, dir.path(), &|_| {}).unwrap_err();
    assert!(matches!(e, AccuracyError::EmptyImage { .. }), "{e}");
    let e =
        speed_vs_error("s", &Scene::default(), &AccuracyOptions { width: 8, ..opts }, dir.path(), &|_| {}).unwrap_err();
    assert!(matches!(e, AccuracyError::NoCamera { .. }) && e.to_string().contains("scene s"), "{e}");
}
