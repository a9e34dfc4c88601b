//! Batch traversal (`hyrt_cpu::traversal`): every SIMD level available on this CPU gives,
//! ray by ray, the scalar reference's hit or miss (`Bvh::occluded`) and closest hit
//! (`Bvh::closest_hit`: triangle, and `t`, `u`, `v` bit for bit). Random soups and rays
//! (proptest), shared edges and vertices hit exactly, axis-parallel rays with signed
//! zeros, huge and tiny scales, degenerate triangles, and the ray lists of real frames.

use std::path::PathBuf;

use glam::{Mat4, Vec3};
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::formats::{CameraRecord, RayRecord, TriangleRecord, TRI_RAY_TRACED};
use hyrt_core::frame::{Backend, FrameOptions, PreparedScene};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::camera::primary_rays;
use hyrt_core::scene::{Material, Mesh, RenderMode, Scene};
use hyrt_cpu::backend::CpuBackend;
use hyrt_cpu::traversal::{
    closest_hit_batch, occluded_batch, occluded_pairs_tiled_into, with_threads, Traversal, LANES,
};
use proptest::prelude::*;

/// Compare every available packet level with the scalar reference on `rays`; returns the
/// number of occluded rays (so callers can check the case is not trivial).
fn check(g: &WorldGeometry, bvh: &Bvh, rays: &[RayRecord]) -> usize {
    let t = g.stored_table();
    let want_any = occluded_batch(bvh, t, rays, Traversal::Scalar);
    let want_closest = closest_hit_batch(bvh, t, rays, Traversal::Scalar);
    for kind in Traversal::available_simd() {
        let level = kind.name();
        let any = occluded_batch(bvh, t, rays, kind);
        let closest = closest_hit_batch(bvh, t, rays, kind);
        for (i, r) in rays.iter().enumerate() {
            assert_eq!(any[i], want_any[i], "{level:?} occluded, ray {i}: {r:?}");
            let bits = |h: Option<hyrt_core::bvh::ClosestHit>| {
                h.map(|h| (h.triangle, h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.back_face))
            };
            assert_eq!(bits(closest[i]), bits(want_closest[i]), "{level:?} closest hit, ray {i}: {r:?}");
            assert_eq!(any[i] != 0, closest[i].is_some(), "ray {i}: any hit and closest hit disagree");
        }
    }
    want_any.iter().filter(|&&o| o != 0).count()
}

fn ray(o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> RayRecord {
    RayRecord::query(o.into(), d.into(), t_min, t_max)
}

fn soup(tris: &[[Vec3; 3]]) -> WorldGeometry {
    let (mut records, mut normals) = (Vec::new(), Vec::new());
    for (i, t) in tris.iter().enumerate() {
        records.push(TriangleRecord {
            v0: t[0].into(),
            object: 0,
            v1: t[1].into(),
            triangle: i as u32,
            v2: t[2].into(),
            flags: TRI_RAY_TRACED,
        });
        normals.push([Vec3::Y; 3]);
    }
    WorldGeometry { triangles: hyrt_core::geometry::WorldTriangles::stored(records, normals), ..Default::default() }
}

/// A scene of the given meshes, each with its transform.
fn mesh_scene(meshes: Vec<(Mesh, Mat4)>) -> WorldGeometry {
    let mut s = Scene::default();
    for (m, t) in meshes {
        s.add_object(m, Material::grey(), t, RenderMode::RayTraced);
    }
    WorldGeometry::build(&s)
}

/// Rays from `eye` to every target, and from each target's mirror image through `eye`
/// back: coherent groups of [`LANES`] when the targets are neighbours.
fn rays_to(eye: Vec3, targets: &[Vec3]) -> Vec<RayRecord> {
    targets.iter().map(|&p| ray(eye, p - eye, 0.0, f32::INFINITY)).collect()
}

/// Every vertex and edge midpoint of an `n` x `n` grid in the unit square (XZ plane,
/// centred): exactly on shared vertices, and on shared edges up to rounding.
fn grid_targets(n: u32, to_world: Mat4) -> Vec<Vec3> {
    let mut out = Vec::new();
    for j in 0..=2 * n {
        for i in 0..=2 * n {
            let p = Vec3::new(i as f32 / (2 * n) as f32 - 0.5, 0.0, j as f32 / (2 * n) as f32 - 0.5);
            out.push(to_world.transform_point3(p));
        }
    }
    out
}

#[test]
fn default_scene_frame_and_primary_rays_match_scalar() {
    let scene = Scene::default_scene();
    let g = WorldGeometry::build(&scene);
    let bvh = Bvh::build(&g, BvhPreset::default());
    let cam = CameraRecord::new(&scene.camera.unwrap(), 160, 90);
    let prepared = PreparedScene::new(g, bvh, 0.0);
    let frame = CpuBackend::new(Some(2)).render(&prepared, &cam, &FrameOptions::with_stage_outputs()).unwrap();
    let (g, bvh) = (&prepared.geometry, &prepared.bvh);
    let occluded = check(g, bvh, &frame.rays);
    assert!(occluded > 0 && occluded < frame.rays.len(), "{occluded} of {}", frame.rays.len());
    // The stage's output is the packet traversal's.
    assert_eq!(frame.occluded, occluded_batch(bvh, g.stored_table(), &frame.rays, Traversal::Scalar));
    let primary = primary_rays(&cam);
    let hits = check(g, bvh, &primary);
    assert!(hits > primary.len() / 2, "{hits} of {}", primary.len());
}

#[test]
fn shared_vertices_and_edges_of_grids_and_closed_meshes() {
    for preset in [BvhPreset::Fastest, BvhPreset::Medium, BvhPreset::Slow] {
        let grid = Mat4::from_scale(Vec3::splat(4.0));
        let g = mesh_scene(vec![
            (Mesh::grid("grid", 8), grid),
            (Mesh::cube("cube"), Mat4::from_translation(Vec3::new(0.0, 1.0, 0.0))),
            (
                Mesh::uv_sphere("sphere", 12, 8),
                Mat4::from_translation(Vec3::new(1.2, 0.6, -1.1)) * Mat4::from_scale(Vec3::splat(0.5)),
            ),
        ]);
        let bvh = Bvh::build(&g, preset);
        let targets = grid_targets(8, grid);
        let mut rays = Vec::new();
        // Straight down (direction (+-0, -1, +-0)) onto every grid vertex and edge
        // midpoint, with every sign of zero, and from a few slanted eyes.
        for zx in [0.0f32, -0.0] {
            for zz in [0.0f32, -0.0] {
                rays.extend(
                    targets.iter().map(|p| ray(*p + Vec3::Y * 3.0, Vec3::new(zx, -1.0, zz), 0.0, f32::INFINITY)),
                );
                rays.extend(targets.iter().map(|p| ray(*p - Vec3::Y * 3.0, Vec3::new(zx, 2.0, zz), 0.0, 10.0)));
            }
        }
        for eye in [Vec3::new(0.3, 5.0, 0.2), Vec3::new(-6.0, 2.0, 7.0), Vec3::new(0.0, 1.0, 0.0)] {
            rays.extend(rays_to(eye, &targets));
        }
        // Along the grid lines, in the plane of the grid (axis-parallel, zero y).
        for k in 0..=8 {
            let c = k as f32 / 8.0 * 4.0 - 2.0;
            rays.push(ray(Vec3::new(-5.0, 0.0, c), Vec3::new(1.0, 0.0, 0.0), 0.0, f32::INFINITY));
            rays.push(ray(Vec3::new(c, -0.0, 5.0), Vec3::new(-0.0, -0.0, -1.0), 0.0, f32::INFINITY));
        }
        // Cube corners and the sphere's poles from inside and outside.
        for eye in [Vec3::new(0.0, 1.0, 0.0), Vec3::new(3.0, 4.0, 5.0)] {
            let corners: Vec<Vec3> = (0..8)
                .map(|i| {
                    Vec3::new(0.0, 1.0, 0.0)
                        + Vec3::new((i & 1) as f32 - 0.5, ((i >> 1) & 1) as f32 - 0.5, ((i >> 2) & 1) as f32 - 0.5)
                })
                .collect();
            rays.extend(rays_to(eye, &corners));
        }
        let occluded = check(&g, &bvh, &rays);
        assert!(occluded > rays.len() / 2, "{preset:?}: {occluded} of {}", rays.len());
    }
}

#[test]
fn triangle_fans_hit_at_their_centre() {
    // Fans of 3..40 triangles around a common centre vertex; rays aimed exactly at the
    // centre from many directions hit one of the fan's triangles.
    let mut tris = Vec::new();
    for (k, n) in [3u32, 7, 16, 40].into_iter().enumerate() {
        let c = Vec3::new(k as f32 * 3.0, 0.25, -0.5);
        for i in 0..n {
            let a = std::f32::consts::TAU * i as f32 / n as f32;
            let b = std::f32::consts::TAU * (i + 1) as f32 / n as f32;
            let p = |a: f32| c + Vec3::new(a.cos(), a.sin() * 0.3, a.sin());
            tris.push([c, p(a), if i + 1 == n { p(0.0) } else { p(b) }]);
        }
    }
    let g = soup(&tris);
    let bvh = Bvh::build(&g, BvhPreset::Medium);
    let mut rays = Vec::new();
    for k in 0..4 {
        let c = Vec3::new(k as f32 * 3.0, 0.25, -0.5);
        for i in 0..32 {
            let a = i as f32 * 0.19;
            let eye = c + Vec3::new(a.cos() * 2.0, 3.0 + a.sin(), a.sin() * 2.0);
            rays.push(ray(eye, c - eye, 0.0, f32::INFINITY));
        }
    }
    let occluded = check(&g, &bvh, &rays);
    assert_eq!(occluded, rays.len());
}

#[test]
fn huge_and_tiny_scales() {
    for scale in [1e-6f32, 1e-3, 1e5, 1e6] {
        let shift = Vec3::new(scale * 3.0, -scale, scale * 0.5);
        let to_world = Mat4::from_translation(shift) * Mat4::from_scale(Vec3::splat(scale));
        let g = mesh_scene(vec![
            (Mesh::grid("grid", 6), to_world * Mat4::from_scale(Vec3::splat(4.0))),
            (
                Mesh::uv_sphere("sphere", 10, 6),
                to_world * Mat4::from_translation(Vec3::new(0.5, 0.5, 0.0)) * Mat4::from_scale(Vec3::splat(0.4)),
            ),
            (Mesh::torus("torus", 0.6, 0.2, 16, 8), to_world * Mat4::from_translation(Vec3::new(-0.8, 0.3, 0.4))),
        ]);
        let bvh = Bvh::build(&g, BvhPreset::Medium);
        let targets = grid_targets(6, to_world * Mat4::from_scale(Vec3::splat(4.0)));
        let mut rays = Vec::new();
        for eye in [Vec3::new(0.2, 3.0, 0.1), Vec3::new(-5.0, 1.0, 6.0)] {
            let eye = to_world.transform_point3(eye);
            rays.extend(rays_to(eye, &targets));
            // Unit directions too: the kernel's conservative `t > 0` bound adds world-space
            // vertex magnitudes to `t`-space ones (pbrt-v4's `deltaX`), so with
            // directions of length 1e-6 it rejects every hit at the 1e-6 scale.
            rays.extend(targets.iter().map(|&p| ray(eye, (p - eye).normalize(), 0.0, f32::INFINITY)));
        }
        let occluded = check(&g, &bvh, &rays);
        assert!(occluded > rays.len() / 4, "scale {scale}: {occluded} of {}", rays.len());
    }
}

#[test]
fn degenerate_triangles_and_invalid_rays() {
    let nan = Vec3::splat(f32::NAN);
    let tris = [
        [Vec3::ZERO, Vec3::X, Vec3::Z],
        [Vec3::ZERO, Vec3::ZERO, Vec3::Z],    // two equal vertices
        [Vec3::ZERO, Vec3::X, Vec3::X * 2.0], // collinear
        [Vec3::ZERO, Vec3::X, nan],           // non-finite
        [Vec3::X, Vec3::new(1.0, 0.0, 1.0), Vec3::Z],
        [Vec3::new(0.5, 0.0, 0.5), Vec3::new(0.5, 1.0, 0.5), Vec3::new(0.5, 0.0, 0.5 + 1e-30)], // sliver
    ];
    let g = soup(&tris);
    let bvh = Bvh::build(&g, BvhPreset::Medium);
    let mut rays = Vec::new();
    for i in 0..24 {
        let x = i as f32 / 12.0 - 0.5;
        rays.push(ray(Vec3::new(x, 1.0, 0.5), Vec3::NEG_Y, 0.0, f32::INFINITY));
        rays.push(ray(Vec3::new(x, -1.0, 0.5), Vec3::new(0.0, 1.0, 0.0), 0.0, 2.0));
        rays.push(ray(Vec3::new(-1.0, 0.0, x), Vec3::X, 0.0, f32::INFINITY));
    }
    // Rays the traversal rejects: empty or NaN interval, zero or non-finite direction.
    rays.push(ray(Vec3::new(0.3, 1.0, 0.3), Vec3::NEG_Y, 2.0, 1.0));
    rays.push(ray(Vec3::new(0.3, 1.0, 0.3), Vec3::NEG_Y, f32::NAN, 1.0));
    rays.push(ray(Vec3::new(0.3, 1.0, 0.3), Vec3::ZERO, 0.0, 1.0));
    rays.push(ray(Vec3::new(0.3, 1.0, 0.3), Vec3::new(0.0, f32::NEG_INFINITY, 0.0), 0.0, 1.0));
    rays.push(ray(nan, Vec3::NEG_Y, 0.0, 1.0));
    let occluded = check(&g, &bvh, &rays);
    assert!(occluded > 10, "{occluded}");
    // The same rejected rays inside packets, between valid ones: the packet's lane
    // validity must match the scalar rejection lane by lane.
    let invalid = rays[rays.len() - 5..].to_vec();
    let mut mixed = Vec::new();
    for (k, r) in rays[..72].iter().enumerate() {
        mixed.push(*r);
        if k % 3 == 1 {
            mixed.push(invalid[k % invalid.len()]);
        }
    }
    let occluded = check(&g, &bvh, &mixed);
    assert!(occluded > 10, "{occluded}");
}

#[test]
fn results_do_not_depend_on_thread_count() {
    let scene = Scene::default_scene();
    let g = WorldGeometry::build(&scene);
    let bvh = Bvh::build(&g, BvhPreset::default());
    let primary = primary_rays(&CameraRecord::new(&scene.camera.unwrap(), 200, 120));
    let run = |threads| {
        with_threads(threads, || {
            (
                occluded_batch(&bvh, g.stored_table(), &primary, Traversal::simd()),
                closest_hit_batch(&bvh, g.stored_table(), &primary, Traversal::simd()),
            )
        })
    };
    assert_eq!(run(1), run(2));
}

fn vec3(range: f32) -> impl Strategy<Value = Vec3> {
    (-range..range, -range..range, -range..range).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// A direction with some components forced to +0 or -0 (axis-parallel rays).
fn direction() -> impl Strategy<Value = Vec3> {
    (vec3(1.0), 0u32..27).prop_map(|(d, zeros)| {
        let mut d = d;
        for a in 0..3 {
            match (zeros / 3u32.pow(a as u32)) % 3 {
                1 => d[a] = 0.0,
                2 => d[a] = -0.0,
                _ => {}
            }
        }
        if d.abs().max_element() == 0.0 {
            d.y = -1.0;
        }
        d
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Random triangle soups and bundles of nearby rays (so that packets form), some of
    /// them axis-parallel, with random intervals.
    #[test]
    fn random_soups_match_scalar(
        tris in prop::collection::vec((vec3(4.0), vec3(1.5), vec3(1.5)), 1..160),
        bundles in prop::collection::vec((vec3(6.0), direction(), 0.0f32..0.3, prop::bool::ANY), 1..12),
        preset in prop::sample::select(vec![BvhPreset::Fastest, BvhPreset::Medium, BvhPreset::Slow]),
    ) {
        let tris: Vec<[Vec3; 3]> = tris.iter().map(|&(c, a, b)| [c, c + a, c + b]).collect();
        let g = soup(&tris);
        let bvh = Bvh::build(&g, preset);
        let mut rays = Vec::new();
        for (k, &(o, d, spread, bounded)) in bundles.iter().enumerate() {
            for i in 0..LANES + k % 3 {
                let jitter = Vec3::new((i % 3) as f32, (i / 3) as f32, 0.5) * spread;
                // Aim near the centre of some triangle so many rays hit.
                let target = (tris[(k * 7 + i) % tris.len()][0] + tris[(k * 7 + i) % tris.len()][1]) * 0.5;
                let dir = if i % 2 == 0 { d } else { target + jitter - o };
                let t_max = if bounded { 1.0 } else { f32::INFINITY };
                rays.push(ray(o + jitter * 0.1, dir, (i % 4) as f32 * 0.05, t_max));
            }
        }
        check(&g, &bvh, &rays);
    }
}

/// Sponza, the bunny and the teaser: the shadow rays of a real CPU frame and the primary
/// rays of the scene's camera.
#[test]
fn shared_asset_frames_match_scalar() {
    let assets = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets");
    if !assets.is_dir() {
        eprintln!("{} not found: skipping the shared-asset traversal test", assets.display());
        return;
    }
    let teaser = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/teaser.toml");
    for path in [assets.join("sponza.glb"), assets.join("bunny.glb"), teaser] {
        let mut scene = Scene::load(&path).unwrap();
        scene.ensure_camera_and_lights();
        let g = WorldGeometry::build(&scene);
        let bvh = Bvh::build(&g, BvhPreset::default());
        let cam = CameraRecord::new(&scene.camera.unwrap(), 320, 180);
        let prepared = PreparedScene::new(g, bvh, 0.0);
        let options = FrameOptions::with_stage_outputs();
        let frame = CpuBackend::new(Some(2)).render(&prepared, &cam, &options).unwrap();
        let (g, bvh) = (&prepared.geometry, &prepared.bvh);
        let occluded = check(g, bvh, &frame.rays);
        assert!(occluded > 0, "{}: no occluded shadow ray", path.display());
        let hits = check(g, bvh, &primary_rays(&cam));
        assert!(hits > 0, "{}: no primary hit", path.display());
    }
}

/// Shadow rays traced in pixel tiles (`occluded_pairs_tiled_into`) answer as the list
/// order does, ray by ray, at every traversal: frames whose sizes leave partial tiles at the
/// right and bottom edges, of the default scene (several lights) and, where present, the
/// teaser, on 1 and 2 threads.
#[test]
fn tiled_shadow_rays_answer_as_the_list_order() {
    let teaser = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/teaser.toml");
    let mut scenes = vec![(Scene::default_scene(), 157, 91)];
    if PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets").is_dir() {
        let mut s = Scene::load(&teaser).unwrap();
        s.ensure_camera_and_lights();
        scenes.push((s, 203, 117));
    }
    for (scene, w, h) in scenes {
        let g = WorldGeometry::build(&scene);
        let bvh = Bvh::build(&g, BvhPreset::default());
        let cam = CameraRecord::new(&scene.camera.unwrap(), w, h);
        let prepared = PreparedScene::new(g, bvh, 0.0);
        let frame = CpuBackend::new(Some(2)).render(&prepared, &cam, &FrameOptions::with_stage_outputs()).unwrap();
        let (g, bvh) = (&prepared.geometry, &prepared.bvh);
        let lights = frame.rays.iter().map(|r| r.light).max().unwrap_or(0) + 1;
        assert!(lights > 1 || w == 203, "the default scene has several lights");
        let want = occluded_batch(bvh, g.stored_table(), &frame.rays, Traversal::Scalar);
        assert!(want.contains(&0) && want.contains(&1));
        let view = g.surface.view();
        for kind in std::iter::once(Traversal::Scalar).chain(Traversal::available_simd()) {
            for threads in [1, 2] {
                let mut got = Vec::new();
                let rays = &frame.rays;
                let pixels = w * h;
                let pairs: Vec<u32> = rays.iter().map(|r| r.light * pixels + r.pixel).collect();
                with_threads(threads, || {
                    let table = g.stored_table();
                    occluded_pairs_tiled_into(bvh, table, &view, &pairs, pixels, w, |i| rays[i], kind, &mut got)
                });
                let differ = got.iter().zip(&want).filter(|(a, b)| a != b).count();
                assert_eq!(differ, 0, "{}, {w}x{h}, {threads} threads: {differ} rays differ", kind.name());
                assert_eq!(got.len(), want.len());
            }
        }
    }
}

/// Closest-hit packets from one point whose rays part in two clusters (a list of active
/// pixels that jumps from the end of one pixel row to the start of the next): the
/// coherent walk gives up on them and the binary packets take over
/// (`traversal::frustum`'s `MAX_IDLE_LEAF_BOXES`), with the same answers, interleaved
/// with packets of neighbouring rays that stay in the coherent walk.
#[test]
fn packets_from_one_point_parted_in_two_match_scalar() {
    let g = mesh_scene(vec![
        (Mesh::grid("grid", 96), Mat4::from_scale(Vec3::new(10.0, 1.0, 10.0))),
        (
            Mesh::uv_sphere("sphere", 24, 12),
            Mat4::from_translation(Vec3::new(1.5, 0.6, 1.5)) * Mat4::from_scale(Vec3::splat(0.5)),
        ),
    ]);
    let bvh = Bvh::build(&g, BvhPreset::default());
    let eye = Vec3::new(0.2, 1.5, 0.1);
    let mut rays = Vec::new();
    for k in 0..64 {
        let row = (k / 8) as f32;
        for i in 0..8 {
            // Odd packets: four rays near the eye's foot, four toward the far corner.
            let (x, z) = if k % 2 == 1 && i >= 4 {
                (4.5 - 0.01 * i as f32, 4.0 - 0.1 * row)
            } else {
                (0.5 + 0.6 * row + 0.01 * i as f32, 0.4 + 0.05 * i as f32)
            };
            let t_max = if i % 3 == 0 { 2.5 } else { f32::INFINITY };
            rays.push(ray(eye, Vec3::new(x, 0.0, z) - eye, 0.0, t_max));
        }
    }
    let occluded = check(&g, &bvh, &rays);
    assert!(occluded > rays.len() / 2, "{occluded} of {}", rays.len());
}

/// Packets whose rays diverge: every packet mixes direction octants and dominant axes
/// (the per-lane near planes and axis permutations of the packet code), from inside and
/// outside a closed sphere and a cube.
#[test]
fn divergent_packets_match_scalar() {
    let g = mesh_scene(vec![
        (Mesh::uv_sphere("sphere", 16, 10), Mat4::from_scale(Vec3::splat(2.0))),
        (Mesh::cube("cube"), Mat4::from_translation(Vec3::new(3.0, 0.0, 0.0))),
    ]);
    let bvh = Bvh::build(&g, BvhPreset::Medium);
    let mut rays = Vec::new();
    for origin in [Vec3::ZERO, Vec3::new(0.3, -0.2, 0.1), Vec3::new(6.0, 1.0, -2.0)] {
        for k in 0..64 {
            let a = k as f32 * 0.61;
            let d = Vec3::new(a.cos(), (a * 1.7).sin(), (a * 0.3).cos() - 0.5);
            rays.push(ray(origin, d, 0.0, if k % 3 == 0 { 1.5 } else { f32::INFINITY }));
        }
    }
    let occluded = check(&g, &bvh, &rays);
    assert!(occluded > rays.len() / 2, "{occluded} of {}", rays.len());
}

/// Packets whose lanes part near their origins, so most leaves are entered by fewer lanes
/// than they hold triangles and each lane is tested alone against the whole leaf (the
/// any-hit packets' `occluded_lanes_alone`): shadow rays from scattered points just off a
/// dense sphere to a light, some blocked by a second sphere, and rays straight down onto
/// the vertices and edge midpoints of a fine grid in scattered order (exactly-zero edge
/// functions, left to the scalar kernel's tie rule).
#[test]
fn lanes_alone_in_dense_leaves_match_scalar() {
    let grid = Mat4::from_translation(Vec3::new(0.0, -2.5, 0.0)) * Mat4::from_scale(Vec3::splat(8.0));
    let g = mesh_scene(vec![
        (Mesh::uv_sphere("dense", 96, 48), Mat4::from_scale(Vec3::splat(2.0))),
        (
            Mesh::uv_sphere("occluder", 24, 12),
            Mat4::from_translation(Vec3::new(0.4, 3.2, 0.2)) * Mat4::from_scale(Vec3::splat(0.7)),
        ),
        (Mesh::grid("grid", 64), grid),
    ]);
    let bvh = Bvh::build(&g, BvhPreset::Medium);
    let light = Vec3::new(0.5, 6.0, 0.3);
    // Neighbouring rays far apart: index k takes point (k * 7919) mod n.
    let scatter = |n: usize| (0..n).map(move |k| k * 7919 % n);
    let n = 4096;
    let mut rays: Vec<RayRecord> = scatter(n)
        .map(|i| {
            let (theta, phi) = ((i as f32 + 0.5) / n as f32 * std::f32::consts::PI, i as f32 * 2.399_963);
            let normal = Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
            let p = normal * 2.0 * (1.0 + 1e-3);
            ray(p, light - p, 1e-4, 1.0)
        })
        .collect();
    let targets = grid_targets(64, grid);
    let m = targets.len();
    rays.extend(scatter(m).map(|i| ray(targets[i] + Vec3::Y * 9.0, Vec3::new(0.0, -1.0, 0.0), 0.0, f32::INFINITY)));
    let occluded = check(&g, &bvh, &rays);
    assert!(occluded > n / 8 && occluded < rays.len() - n / 8, "{occluded} of {} occluded", rays.len());
}

/// Coherent shadow rays in each of the eight direction octants, so that every octant copy
/// of the any-hit packet walk runs (a packet takes its octant's walk when its lanes'
/// directions share their signs; the rays of each group here do): from a cap of points
/// just off a dense sphere towards a light in that octant, a smaller sphere half way
/// stopping some of them; and rays from the light back across the sphere, which share one
/// origin (the closest-hit packets' frustum walk, also compiled per octant). Each octant
/// gives both answers.
#[test]
fn octant_packets_match_scalar() {
    let signs: Vec<Vec3> = (0..8)
        .map(|o| {
            Vec3::new(
                if o & 1 != 0 { -1.0 } else { 1.0 },
                if o & 2 != 0 { -1.0 } else { 1.0 },
                if o & 4 != 0 { -1.0 } else { 1.0 },
            )
        })
        .collect();
    let mut meshes = vec![(Mesh::uv_sphere("dense", 64, 32), Mat4::from_scale(Vec3::splat(2.0)))];
    for s in &signs {
        let at = Mat4::from_translation(*s * 4.0) * Mat4::from_scale(Vec3::splat(0.25));
        meshes.push((Mesh::uv_sphere("occluder", 16, 8), at));
    }
    let g = mesh_scene(meshes);
    let bvh = Bvh::build(&g, BvhPreset::Medium);
    for (o, s) in signs.iter().enumerate() {
        let light = *s * 8.0;
        let l = s.normalize();
        let e1 = l.cross(Vec3::Y + Vec3::X * 0.3).normalize();
        let e2 = l.cross(e1);
        // An n x n grid of offsets across the light's direction, row by row (coherent).
        let n = 32;
        let across = |k: usize| e1 * ((k % n) as f32 / n as f32 - 0.5) + e2 * ((k / n) as f32 / n as f32 - 0.5);
        let rays: Vec<RayRecord> = (0..n * n)
            .map(|k| {
                let p = (l + across(k) * 2.0).normalize() * 2.0 * (1.0 + 1e-3);
                ray(p, light - p, 1e-4, 1.0)
            })
            .collect();
        for r in &rays {
            let d = Vec3::from(r.direction);
            assert_eq!(d.signum(), *s, "octant {o}: every ray in the light's octant");
        }
        let occluded = check(&g, &bvh, &rays);
        assert!(occluded > 0 && occluded < rays.len(), "octant {o}: {occluded} of {} occluded", rays.len());
        // From the light to a square across the dense sphere's front, its corners past the
        // sphere: one origin, so the closest-hit packets take the frustum walk, in the
        // opposite octant.
        let eye_rays: Vec<RayRecord> = (0..n * n)
            .map(|k| {
                let q = l * 2.0 + across(k) * 5.0;
                ray(light, q - light, 0.0, f32::INFINITY)
            })
            .collect();
        for r in &eye_rays {
            assert_eq!(
                Vec3::from(r.direction).signum(),
                -*s,
                "octant {o}: every ray from the light in the opposite octant"
            );
        }
        let hits = check(&g, &bvh, &eye_rays);
        assert!(hits > 0 && hits < eye_rays.len(), "octant {o}: {hits} of {} rays from the light hit", eye_rays.len());
    }
}

/// The backend's shadow traversal setting changes nothing in the frame.
#[test]
fn backend_frames_are_identical_with_scalar_and_simd_shadow_rays() {
    let scene = Scene::default_scene();
    let g = WorldGeometry::build(&scene);
    let bvh = Bvh::build(&g, BvhPreset::default());
    let prepared = PreparedScene::new(g, bvh, 0.0);
    let cam = CameraRecord::new(&scene.camera.unwrap(), 200, 120);
    let mut backend = CpuBackend::new(Some(2));
    assert_eq!(backend.shadow_traversal(), Traversal::simd());
    let simd = backend.render(&prepared, &cam, &FrameOptions::with_stage_outputs()).unwrap();
    backend.set_shadow_traversal(Traversal::Scalar);
    let scalar = backend.render(&prepared, &cam, &FrameOptions::with_stage_outputs()).unwrap();
    assert_eq!(simd.occluded, scalar.occluded);
    assert_eq!(simd.shadow, scalar.shadow);
    let bits = |img: &[[f32; 4]]| img.iter().flat_map(|p| p.map(f32::to_bits)).collect::<Vec<u32>>();
    assert_eq!(bits(&simd.final_image), bits(&scalar.final_image));
    assert!(simd.occluded.contains(&1) && simd.occluded.contains(&0));
}

/// The any-hit packets try the previous packet's occluder first (see `packet::occluded`):
/// shadow rays from a fine floor grid, row by row (consecutive packets share occluders),
/// to a point light above a board of many small triangles, a large tilted quad and a
/// sphere. Some packets are stopped whole by the cached triangle, some only in part; every
/// third ray ends below the occluders (the cached triangle lies beyond its interval), and
/// with spatial splits (`Slow`) a triangle sits in several leaves, so the cached leaf's box
/// may miss a lane the triangle would stop.
#[test]
fn occluder_cache_cases_match_scalar() {
    let board = Mat4::from_translation(Vec3::new(-1.0, 1.0, 0.5)) * Mat4::from_scale(Vec3::splat(3.0));
    let quad = Mat4::from_translation(Vec3::new(1.5, 1.2, -1.0))
        * Mat4::from_rotation_x(0.4)
        * Mat4::from_scale(Vec3::splat(2.5));
    let sphere = Mat4::from_translation(Vec3::new(0.5, 1.5, 1.5)) * Mat4::from_scale(Vec3::splat(0.6));
    let g = mesh_scene(vec![
        (Mesh::grid("floor", 4), Mat4::from_scale(Vec3::splat(8.0))),
        (Mesh::grid("board", 24), board),
        (Mesh::grid("quad", 1), quad),
        (Mesh::uv_sphere("sphere", 12, 8), sphere),
    ]);
    let light = Vec3::new(0.3, 4.0, 0.2);
    let mut rays = Vec::new();
    let n = 96;
    for j in 0..n {
        for i in 0..n {
            let p = Vec3::new(i as f32 / n as f32 * 8.0 - 4.0, 0.0, j as f32 / n as f32 * 8.0 - 4.0);
            let t_max = if (i + j) % 3 == 0 { 0.2 } else { 1.0 };
            rays.push(ray(p, light - p, 1e-4, t_max));
        }
    }
    for preset in [BvhPreset::Medium, BvhPreset::Slow] {
        let bvh = Bvh::build(&g, preset);
        let occluded = check(&g, &bvh, &rays);
        assert!(occluded > rays.len() / 8 && occluded < rays.len() / 2, "{preset:?}: {occluded} of {}", rays.len());
    }
}
