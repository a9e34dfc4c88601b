//! Tests of the ray kernels (`hyrt_core::kernels::ray`) and the BVH traversal
//! (`hyrt_core::bvh`): watertightness on closed meshes, axis-parallel rays with signed
//! zeros, BVH against brute force for every preset, self-intersection after the origin
//! offset, NaN/Inf robustness, degenerate triangles, pinned exact-float cases.

use std::collections::HashMap;

use glam::{Mat4, Quat, Vec3};
use hyrt_core::bvh::{Bvh, BvhPreset, ClosestHit};
use hyrt_core::formats::{RayRecord, TriangleRecord, RAY_KIND_SHADOW, TRI_RAY_TRACED};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::barycentric::{position_error_bound, reconstruct_position};
use hyrt_core::kernels::ray::{
    edge_sign_exact, intersect_triangle_watertight, offset_ray_origin, offset_ray_origin_integer_ulps, product_error,
    ray_aabb_conservative, safe_inverse_dir, TriangleHit,
};
use hyrt_core::scene::{Material, Mesh, Object, ObjectSource, RenderMode, Scene};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

fn ray(origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> RayRecord {
    RayRecord::query(origin.into(), dir.into(), t_min, t_max)
}

/// Geometry from raw triangles (one object), without `WorldGeometry::build`, so that
/// NaN vertices and soups can be fed directly.
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

/// World geometry of one mesh placed with `transform`, through the real scene path.
fn placed(mesh: Mesh, transform: Mat4) -> WorldGeometry {
    let scene = Scene {
        meshes: vec![mesh],
        materials: vec![Material::grey()],
        objects: vec![Object {
            id: 0,
            name: "mesh".into(),
            mesh: 0,
            transform,
            material: 0,
            render_mode: RenderMode::RayTraced,
            source: ObjectSource::default(),
        }],
        ..Scene::default()
    };
    WorldGeometry::build(&scene)
}

fn hit_on(tri: &TriangleRecord, r: &RayRecord) -> Option<TriangleHit> {
    intersect_triangle_watertight(
        r.origin.into(),
        r.direction.into(),
        r.t_min,
        r.t_max,
        tri.v0.into(),
        tri.v1.into(),
        tri.v2.into(),
    )
}

/// Brute force over all triangles with the same kernel: the lexicographic minimum of
/// (t, triangle index).
fn brute_closest(g: &WorldGeometry, r: &RayRecord) -> Option<ClosestHit> {
    let mut best: Option<ClosestHit> = None;
    for (i, tri) in g.stored_table().iter().enumerate() {
        if let Some(h) = hit_on(tri, r) {
            if best.is_none_or(|b| h.t < b.t) {
                best = Some(ClosestHit { triangle: i as u32, t: h.t, u: h.u, v: h.v, back_face: h.back_face });
            }
        }
    }
    best
}

fn brute_any(g: &WorldGeometry, r: &RayRecord) -> bool {
    g.stored_table().iter().any(|t| hit_on(t, r).is_some())
}

fn hit_bits(h: Option<ClosestHit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.triangle, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()))
}

// ---------------------------------------------------------------------------------------------
// Watertightness on closed meshes
// ---------------------------------------------------------------------------------------------

/// Position key with -0 folded into +0.
fn key(p: Vec3) -> [u32; 3] {
    (p + Vec3::ZERO).to_array().map(f32::to_bits)
}

/// Points to aim at on a closed mesh: the midpoints (and a third) of every edge shared by
/// exactly two triangles, and every vertex all of whose edges are shared that way (so a
/// seam or pole where positions differ by rounding is not aimed at).
fn aim_points(g: &WorldGeometry) -> Vec<Vec3> {
    type EdgeKey = ([u32; 3], [u32; 3]);
    let mut edges: HashMap<EdgeKey, (u32, Vec3, Vec3)> = HashMap::new();
    for t in g.stored_table() {
        let v = t.vertices();
        for i in 0..3 {
            let (a, b) = (v[i], v[(i + 1) % 3]);
            let (ka, kb) = (key(a), key(b));
            let k = if ka < kb { (ka, kb) } else { (kb, ka) };
            edges.entry(k).or_insert((0, a, b)).0 += 1;
        }
    }
    let mut vertex_ok: HashMap<[u32; 3], (bool, Vec3)> = HashMap::new();
    let mut points = Vec::new();
    for (&(ka, kb), &(count, a, b)) in &edges {
        let shared = count == 2;
        for (k, p) in [(ka, a), (kb, b)] {
            let e = vertex_ok.entry(k).or_insert((true, p));
            e.0 &= shared;
        }
        if shared {
            points.push(a * 0.5 + b * 0.5);
            points.push(a + (b - a) * (1.0 / 3.0));
        }
    }
    points.extend(vertex_ok.values().filter(|(ok, _)| *ok).map(|&(_, p)| p));
    points.sort_by_key(|p| key(*p));
    points
}

/// Rays from outside aimed exactly at shared edges and vertices must hit, at or before
/// the aimed point (no leak through the mesh), for the BVH and brute force alike.
fn assert_no_leaks(g: &WorldGeometry, outward: impl Fn(Vec3) -> Vec3, label: &str) {
    let points = aim_points(g);
    assert!(points.len() > 20, "{label}: too few aim points");
    for preset in [BvhPreset::Fastest, BvhPreset::Medium, BvhPreset::VerySlow] {
        let bvh = Bvh::build(g, preset);
        let mut rays = 0;
        for &p in &points {
            let n = outward(p).normalize();
            let side = n.any_orthonormal_vector();
            for tilt in [Vec3::ZERO, side * 0.6, -side * 0.6, n.cross(side) * 0.6] {
                let dir_out = (n + tilt).normalize();
                let dist = g.scene_extent();
                let origin = p + dir_out * dist;
                let r = ray(origin, p - origin, 0.0, f32::INFINITY);
                let hit = bvh.closest_hit(g.stored_table(), &r);
                let Some(h) = hit else {
                    panic!("{label} {preset:?}: leak: ray {r:?} aimed at {p:?} hits nothing");
                };
                assert!(h.t < 1.01, "{label} {preset:?}: ray aimed at {p:?} first hits at t = {}", h.t);
                assert!(bvh.occluded(g.stored_table(), &r), "{label}: occluded disagrees with closest_hit");
                assert!(brute_any(g, &r), "{label}: brute force leaks at {p:?}");
                rays += 1;
            }
        }
        assert!(rays > 80);
    }
}

fn sphere_outward(c: Vec3) -> impl Fn(Vec3) -> Vec3 {
    move |p| p - c
}

#[test]
fn watertight_closed_meshes_never_leak() {
    let far = Vec3::new(148376.0, 1234.0, -223423.0);
    let rot = Quat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1);
    let placements: [(&str, Vec3, f32); 4] =
        [("origin", Vec3::ZERO, 1.0), ("tiny", Vec3::ZERO, 1e-3), ("far", far, 1.0), ("far_large", far, 50.0)];
    for (name, centre, scale) in placements {
        let m = Mat4::from_scale_rotation_translation(Vec3::splat(scale), rot, centre);
        let world_centre = m.transform_point3(Vec3::ZERO);

        let g = placed(Mesh::uv_sphere("sphere", 24, 12), m);
        assert_no_leaks(&g, sphere_outward(world_centre), &format!("sphere {name}"));

        let g = placed(Mesh::cube("cube"), m);
        assert_no_leaks(&g, sphere_outward(world_centre), &format!("cube {name}"));

        // Torus: outward from the nearest point of its ring (object space).
        let (major, minor) = (1.0, 0.4);
        let g = placed(Mesh::torus("torus", major, minor, 24, 12), m);
        let inv = m.inverse();
        let outward = move |p: Vec3| {
            let q = inv.transform_point3(p);
            let ring = Vec3::new(q.x, 0.0, q.z).normalize() * major;
            m.transform_vector3(q - ring)
        };
        assert_no_leaks(&g, outward, &format!("torus {name}"));
    }
}

/// A quad split along its diagonal: a ray exactly through the diagonal hits both
/// triangles at exactly the same t, and the lower index wins (pinned exact floats).
#[test]
fn shared_diagonal_tie_goes_to_lower_index() {
    let (a, b, c, d) =
        (Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(-1.0, 0.0, 1.0));
    for order in [[[b, c, d], [a, b, d]], [[a, b, d], [b, c, d]]] {
        let g = soup(&order);
        let r = ray(Vec3::new(0.25, 3.0, -0.25), Vec3::new(0.0, -1.0, 0.0), 0.0, f32::INFINITY);
        let h0 = hit_on(&g.triangle(0), &r).unwrap();
        let h1 = hit_on(&g.triangle(1), &r).unwrap();
        assert_eq!(h0.t.to_bits(), h1.t.to_bits());
        assert!((h0.t - 3.0).abs() <= 4.0 * f32::EPSILON);
        for preset in BvhPreset::ALL {
            let bvh = Bvh::build(&g, preset);
            assert_eq!(bvh.closest_hit(g.stored_table(), &r).unwrap().triangle, 0);
        }
    }
}

/// Rays aimed exactly at every shared vertex and edge midpoint of closed meshes hit several
/// triangles at (nearly) the same t, often in different leaves: the BVH must return
/// exactly what brute force returns (lower index on equal t), for every preset.
#[test]
fn ties_at_shared_vertices_match_brute_force() {
    let m =
        Mat4::from_scale_rotation_translation(Vec3::splat(3.0), Quat::from_rotation_y(0.4), Vec3::new(5.0, -2.0, 1.0));
    for mesh in [Mesh::uv_sphere("sphere", 32, 16), Mesh::torus("torus", 1.0, 0.3, 32, 16)] {
        let g = placed(mesh, m);
        let eye = Vec3::new(40.0, 30.0, 20.0);
        let rays: Vec<RayRecord> = aim_points(&g).into_iter().map(|p| ray(eye, p - eye, 0.0, f32::INFINITY)).collect();
        let want: Vec<_> = rays.iter().map(|r| hit_bits(brute_closest(&g, r))).collect();
        assert!(want.iter().filter(|w| w.is_some()).count() > 500);
        for preset in BvhPreset::ALL {
            let bvh = Bvh::build(&g, preset);
            for (r, w) in rays.iter().zip(&want) {
                assert_eq!(hit_bits(bvh.closest_hit(g.stored_table(), r)), *w, "{preset:?} {r:?}");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Axis-parallel rays with signed zeros (tinybvh `tiny_bvh_axis_ray_test` spirit)
// ---------------------------------------------------------------------------------------------

const SIGNED_UNITS: [f32; 4] = [-1.0, -0.0, 0.0, 1.0];

fn axis_directions() -> Vec<Vec3> {
    let mut dirs = Vec::new();
    for x in SIGNED_UNITS {
        for y in SIGNED_UNITS {
            for z in SIGNED_UNITS {
                if x != 0.0 || y != 0.0 || z != 0.0 {
                    dirs.push(Vec3::new(x, y, z));
                }
            }
        }
    }
    dirs
}

/// Exact reference for integer-coordinate rays with unit/zero direction components:
/// entry distance into the closed box over `[t_min, t_max]`.
fn exact_box(o: Vec3, d: Vec3, t_min: f32, t_max: f32, lo: Vec3, hi: Vec3) -> Option<f32> {
    let (mut t0, mut t1) = (t_min as f64, t_max as f64);
    for a in 0..3 {
        let (o, d, lo, hi) = (o[a] as f64, d[a] as f64, lo[a] as f64, hi[a] as f64);
        if d == 0.0 {
            if o < lo || o > hi {
                return None;
            }
        } else {
            let (n, f) = if d > 0.0 { ((lo - o) / d, (hi - o) / d) } else { ((hi - o) / d, (lo - o) / d) };
            t0 = t0.max(n);
            t1 = t1.min(f);
        }
    }
    (t0 <= t1).then_some(t0 as f32)
}

#[test]
fn axis_rays_against_boxes_match_exact_reference() {
    let (lo, hi) = (Vec3::splat(-1.0), Vec3::splat(1.0));
    let flat_lo = Vec3::new(-1.0, 0.0, -1.0);
    let flat_hi = Vec3::new(1.0, 0.0, 1.0);
    let coords = [-2.0f32, -1.0, -0.0, 0.0, 1.0, 2.0];
    let mut hits = 0;
    for d in axis_directions() {
        let inv = safe_inverse_dir(d);
        for (a, i) in d.to_array().iter().zip(inv.to_array()) {
            if *a == 0.0 {
                assert!(i.is_infinite() && i.is_sign_negative() == a.is_sign_negative());
            }
        }
        for &x in &coords {
            for &y in &coords {
                for &z in &coords {
                    let o = Vec3::new(x, y, z);
                    for t_max in [f32::INFINITY, 1.0, 0.5] {
                        for (blo, bhi) in [(lo, hi), (flat_lo, flat_hi)] {
                            let got = ray_aabb_conservative(o, inv, 0.0, t_max, blo, bhi);
                            let want = exact_box(o, d, 0.0, t_max, blo, bhi);
                            assert_eq!(got, want, "o {o:?} d {d:?} t_max {t_max} box {blo:?}..{bhi:?}");
                            hits += got.is_some() as u32;
                        }
                    }
                }
            }
        }
    }
    assert!(hits > 1000);
}

/// The origin lies exactly on a slab plane and the direction is parallel to it (both
/// signs of zero): `0 * inf = NaN` must be dropped, the ray is inside the closed slab.
#[test]
fn slab_nan_from_origin_on_plane_is_dropped() {
    let (lo, hi) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 1.0));
    for zero in [0.0f32, -0.0] {
        for plane in [0.0f32, 1.0] {
            let o = Vec3::new(plane, 0.5, -1.0);
            let d = Vec3::new(zero, 0.0, 1.0);
            let inv = safe_inverse_dir(d);
            assert!(((plane - o.x) * inv.x).is_nan());
            assert_eq!(ray_aabb_conservative(o, inv, 0.0, f32::INFINITY, lo, hi), Some(1.0));
        }
        // Just outside the plane: miss.
        let o = Vec3::new(-f32::MIN_POSITIVE, 0.5, -1.0);
        let inv = safe_inverse_dir(Vec3::new(zero, 0.0, 1.0));
        assert_eq!(ray_aabb_conservative(o, inv, 0.0, f32::INFINITY, lo, hi), None);
    }
}

/// Exact (f64) closed point-in-triangle test in the plane of two axes.
fn exact_inside_2d(p: [f64; 2], t: [[f64; 2]; 3]) -> bool {
    let e = |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
    let (e0, e1, e2) = (e(t[0], t[1]), e(t[1], t[2]), e(t[2], t[0]));
    (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0) || (e0 <= 0.0 && e1 <= 0.0 && e2 <= 0.0)
}

/// Rays along each axis (other components +0 or -0) against triangles in the
/// perpendicular plane: the hit decision equals the exact closed point-in-triangle test,
/// on vertices, edges and the shared diagonal included.
#[test]
fn axis_rays_against_triangles_match_exact_inside_test() {
    let quad = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    let tris2d = [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]], [[-1.0, -1.0], [0.5, -0.25], [0.0, 1.0]]];
    let grid: Vec<f64> = (-6..=6).map(|i| i as f64 * 0.25).collect();
    let mut hits = 0;
    for axis in 0..3 {
        let lift = |u: f64, v: f64, w: f32| {
            let mut p = [0.0f32; 3];
            p[(axis + 1) % 3] = u as f32;
            p[(axis + 2) % 3] = v as f32;
            p[axis] = w;
            Vec3::from(p)
        };
        for sign in [-1.0f32, 1.0] {
            for zeros in [(0.0f32, 0.0f32), (-0.0, 0.0), (0.0, -0.0), (-0.0, -0.0)] {
                let mut d = [0.0f32; 3];
                d[axis] = sign;
                d[(axis + 1) % 3] = zeros.0;
                d[(axis + 2) % 3] = zeros.1;
                let d = Vec3::from(d);
                for t2 in &tris2d {
                    let v = t2.map(|q| lift(q[0], q[1], 0.5));
                    for &u in &grid {
                        for &w in &grid {
                            let o = lift(u, w, 0.5 - 2.0 * sign);
                            let got = intersect_triangle_watertight(o, d, 0.0, f32::INFINITY, v[0], v[1], v[2]);
                            let want = exact_inside_2d([u, w], *t2);
                            assert_eq!(got.is_some(), want, "axis {axis} d {d:?} o {o:?} tri {t2:?}");
                            if let Some(h) = got {
                                assert!((h.t - 2.0).abs() <= 4.0 * f32::EPSILON, "t = {}", h.t);
                                hits += 1;
                            }
                        }
                    }
                }
            }
        }
    }
    assert!(hits > 500);
}

// ---------------------------------------------------------------------------------------------
// NaN / Inf, degenerate triangles
// ---------------------------------------------------------------------------------------------

const BAD: [f32; 3] = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];

#[test]
fn non_finite_inputs_never_hit_and_never_panic() {
    let (v0, v1, v2) = (Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
    let (o, d) = (Vec3::new(0.0, 0.0, 1.0), Vec3::NEG_Z);
    assert!(intersect_triangle_watertight(o, d, 0.0, f32::INFINITY, v0, v1, v2).is_some());
    for bad in BAD {
        for axis in 0..3 {
            let poison = |v: Vec3| {
                let mut w = v;
                w[axis] = bad;
                w
            };
            let cases = [
                intersect_triangle_watertight(poison(o), d, 0.0, f32::INFINITY, v0, v1, v2),
                intersect_triangle_watertight(o, poison(d), 0.0, f32::INFINITY, v0, v1, v2),
                intersect_triangle_watertight(o, d, 0.0, f32::INFINITY, poison(v0), v1, v2),
                intersect_triangle_watertight(o, d, 0.0, f32::INFINITY, v0, poison(v1), v2),
                intersect_triangle_watertight(o, d, 0.0, f32::INFINITY, v0, v1, poison(v2)),
            ];
            assert!(cases.iter().all(|c| c.is_none()), "bad {bad} axis {axis}: {cases:?}");
        }
        if bad.is_nan() {
            assert!(intersect_triangle_watertight(o, d, bad, f32::INFINITY, v0, v1, v2).is_none());
            assert!(intersect_triangle_watertight(o, d, 0.0, bad, v0, v1, v2).is_none());
            let inv = safe_inverse_dir(d);
            assert_eq!(ray_aabb_conservative(o, inv, bad, 1e9, v0, v1.max(v2)), None);
            assert_eq!(ray_aabb_conservative(o, inv, 0.0, bad, v0, v1.max(v2)), None);
        }
    }
    // Huge but finite vertices: no panic, no overflow garbage (the translated coordinates
    // overflow to infinity, so det is not finite and nothing is hit).
    let huge = Vec3::new(f32::MAX, -f32::MAX, f32::MAX);
    assert!(intersect_triangle_watertight(-huge, huge, 0.0, f32::INFINITY, huge, v1, v2).is_none());
    assert!(intersect_triangle_watertight(o, Vec3::ZERO, 0.0, f32::INFINITY, v0, v1, v2).is_none());

    // Through the BVH: non-finite triangles are left out, non-finite rays hit nothing.
    let nan = Vec3::splat(f32::NAN);
    let g = soup(&[[v0, v1, v2], [v0 + Vec3::Z, nan, v2 + Vec3::Z], [Vec3::INFINITY, v1, v2]]);
    for preset in BvhPreset::ALL {
        let bvh = Bvh::build(&g, preset);
        bvh.validate(&g).unwrap();
        assert_eq!(bvh.prim_indices.iter().filter(|&&i| i != 0).count(), 0);
        let good = ray(o + Vec3::Z, d, 0.0, f32::INFINITY);
        assert_eq!(bvh.closest_hit(g.stored_table(), &good).unwrap().triangle, 0);
        for bad in BAD {
            for r in [
                ray(Vec3::new(bad, 0.0, 1.0), d, 0.0, f32::INFINITY),
                ray(o, Vec3::new(0.0, bad, -1.0), 0.0, f32::INFINITY),
                ray(o, d, if bad == f32::NEG_INFINITY { f32::INFINITY } else { bad }, f32::INFINITY),
                ray(o, d, 0.0, -bad.abs()),
                ray(o, d, 0.0, if bad.is_nan() { bad } else { -1.0 }),
                ray(o, Vec3::ZERO, 0.0, f32::INFINITY),
            ] {
                assert_eq!(bvh.closest_hit(g.stored_table(), &r), None, "{r:?}");
                assert!(!bvh.occluded(g.stored_table(), &r), "{r:?}");
            }
        }
        // t_min = -inf is a legal (if odd) interval: same as 0, hits are still
        // conservatively in front of the origin.
        let wide = ray(o + Vec3::Z, d, f32::NEG_INFINITY, f32::INFINITY);
        assert_eq!(bvh.closest_hit(g.stored_table(), &wide), bvh.closest_hit(g.stored_table(), &good));
    }
}

proptest! {
    /// A triangle with two equal vertices (or all three) has det == 0 in every ray space:
    /// no ray ever hits it, not even one aimed exactly at its vertices.
    #[test]
    fn degenerate_triangles_never_hit(
        a in prop::array::uniform3(-100.0f32..100.0),
        b in prop::array::uniform3(-100.0f32..100.0),
        o in prop::array::uniform3(-100.0f32..100.0),
        s in 0.0f32..1.0,
        which in 0usize..4,
    ) {
        let (a, b, o) = (Vec3::from(a), Vec3::from(b), Vec3::from(o));
        let tri = match which {
            0 => [a, a, b],
            1 => [a, b, a],
            2 => [b, a, a],
            _ => [a, a, a],
        };
        for target in [a, b, a + (b - a) * s] {
            let d = target - o;
            let h = intersect_triangle_watertight(o, d, 0.0, f32::INFINITY, tri[0], tri[1], tri[2]);
            prop_assert!(h.is_none(), "{tri:?} hit by {o:?} -> {d:?}: {h:?}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// BVH against brute force, every preset
// ---------------------------------------------------------------------------------------------

fn coord() -> impl Strategy<Value = f32> {
    -10.0f32..10.0
}

fn vec3() -> impl Strategy<Value = Vec3> {
    prop::array::uniform3(coord()).prop_map(Vec3::from)
}

/// A triangle soup: random triangles of mixed sizes, some sharing vertices from a pool,
/// a few degenerate or non-finite ones.
fn triangle_soup() -> impl Strategy<Value = Vec<[Vec3; 3]>> {
    let pool = prop::collection::vec(vec3(), 4..12);
    (pool, prop::collection::vec((vec3(), vec3(), vec3(), 0u8..10, 0.01f32..3.0, any::<[u8; 3]>()), 1..80)).prop_map(
        |(pool, specs)| {
            specs
                .into_iter()
                .map(|(c, a, b, kind, size, pick)| match kind {
                    // Small triangle around a centre.
                    0..=3 => [c, c + a * (size * 0.1), c + b * (size * 0.1)],
                    // Large triangle.
                    4 | 5 => [c, a, b],
                    // Mesh-like: vertices shared through the pool.
                    6 | 7 => pick.map(|p| pool[p as usize % pool.len()]),
                    // Degenerate: a repeated vertex.
                    8 => [c, a, c],
                    // Non-finite vertex.
                    _ => [c, Vec3::new(f32::NAN, a.y, a.z), b],
                })
                .collect()
        },
    )
}

/// Random rays: aimed at a point of a random triangle (so most hit), or in a random
/// direction; random t ranges.
fn rays_for(n: usize) -> impl Strategy<Value = Vec<(Vec3, Vec3, usize, [f32; 2], f32, f32)>> {
    prop::collection::vec(
        (
            prop::array::uniform3(-15.0f32..15.0).prop_map(Vec3::from),
            vec3(),
            0..n.max(1),
            [0.0f32..1.0, 0.0f32..1.0],
            prop_oneof![Just(0.0f32), 0.0f32..0.5],
            prop_oneof![Just(f32::INFINITY), 0.1f32..2.0],
        ),
        32,
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    #[test]
    fn bvh_queries_equal_brute_force(
        (tris, rays) in triangle_soup().prop_flat_map(|t| { let n = t.len(); (Just(t), rays_for(n)) })
    ) {
        let g = soup(&tris);
        for preset in BvhPreset::ALL {
            let bvh = Bvh::build(&g, preset);
            prop_assert!(bvh.validate(&g).is_ok());
            for &(o, d, target, bary, t_min, t_max) in &rays {
                let [v0, v1, v2] = tris[target];
                let (u, v) = if bary[0] + bary[1] > 1.0 { (1.0 - bary[0], 1.0 - bary[1]) } else { (bary[0], bary[1]) };
                let aim = v0 * (1.0 - u - v) + v1 * u + v2 * v;
                for dir in [aim - o, d] {
                    let r = ray(o, dir, t_min, t_max);
                    let want = brute_closest(&g, &r);
                    let got = bvh.closest_hit(g.stored_table(), &r);
                    prop_assert_eq!(hit_bits(got), hit_bits(want), "{:?} closest_hit {:?}", preset, r);
                    prop_assert_eq!(bvh.occluded(g.stored_table(), &r), brute_any(&g, &r), "{:?} occluded {:?}", preset, r);
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Ray origin offset: no self-intersection, no false shadow occlusion
// (Mitsuba 3 `test_ray_offset` spirit)
// ---------------------------------------------------------------------------------------------

/// The point at barycentrics `(u, v)` as `reconstruction` computes it, with its error
/// bound (the record's `position_error`, the largest component).
fn bary_point(t: [Vec3; 3], u: f32, v: f32) -> (Vec3, f32) {
    (reconstruct_position(u, v, t[0], t[1], t[2]), position_error_bound(u, v, t[0], t[1], t[2]).max_element())
}

/// The renderer's geometric normal: `WorldGeometry::build`'s face normal.
fn face_normal(t: [Vec3; 3]) -> Vec3 {
    (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero()
}

fn unit_dir() -> impl Strategy<Value = Vec3> {
    prop::array::uniform3(-1.0f32..1.0).prop_filter_map("non-zero", |a| Vec3::from(a).try_normalize())
}

/// Place a unit-ish triangle at `centre` with `scale`; `None` if quantization made it a
/// sliver (the test is about offsets, not about triangles rounding has destroyed).
fn placed_triangle(centre: Vec3, scale: f32, a: Vec3, b: Vec3, c: Vec3) -> Option<[Vec3; 3]> {
    let t = [centre + a * scale, centre + b * scale, centre + c * scale];
    let n = face_normal(t);
    // Shape check on the placed (rounded) vertices: every height at least 5% of the
    // longest edge.
    let area2 = (t[1] - t[0]).cross(t[2] - t[0]).length();
    let longest = (t[1] - t[0]).length().max((t[2] - t[1]).length()).max((t[0] - t[2]).length());
    (n != Vec3::ZERO && area2 >= 0.05 * longest * longest).then_some(t)
}

/// A triangle placed at `10^dist_exp` along `dir_c` with scale `10^scale_exp`
/// ([`placed_triangle`]) and the reconstructed point at barycentrics `bary` (folded into
/// the triangle) with its error bound.
fn point_on_placed_triangle(
    dir_c: Vec3,
    dist_exp: f32,
    scale_exp: f32,
    corners: [Vec3; 3],
    bary: [f32; 2],
) -> Option<([Vec3; 3], Vec3, f32)> {
    let t = placed_triangle(dir_c * 10f32.powf(dist_exp), 10f32.powf(scale_exp), corners[0], corners[1], corners[2])?;
    let (u, v) = if bary[0] + bary[1] > 1.0 { (1.0 - bary[0], 1.0 - bary[1]) } else { (bary[0], bary[1]) };
    let (p, e) = bary_point(t, u, v);
    Some((t, p, e))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    /// Points on a triangle (barycentric combinations), offset along the oriented
    /// geometric normal, then shot into that side: the ray never re-hits the triangle,
    /// at distances 0 and 1e4..1e6 from the origin and scales 1e-3..1e3.
    #[test]
    fn offset_rays_never_rehit_their_triangle(
        dir_c in unit_dir(),
        dist_exp in prop_oneof![Just(f32::NEG_INFINITY), 4.0f32..6.0],
        scale_exp in -3.0f32..3.0,
        a in unit_dir(), b in unit_dir(), c in unit_dir(),
        bary in [0.0f32..1.0, 0.0f32..1.0],
        out in unit_dir(),
        cos_min in prop_oneof![Just(0.05f32), Just(0.5)],
    ) {
        let Some((t, p, e)) = point_on_placed_triangle(dir_c, dist_exp, scale_exp, [a, b, c], bary) else { return Ok(()) };
        let n = face_normal(t);
        for side in [n, -n] {
            // A direction into `side`'s half space, at least `cos_min` away from grazing.
            let mut d = out;
            if d.dot(side) < 0.0 { d = -d; }
            if d.dot(side) < cos_min { d = (d + side * cos_min * 2.0).normalize(); }
            for (method, o) in [("error bound", offset_ray_origin(p, e, side)), ("integer ulps", offset_ray_origin_integer_ulps(p, side))] {
                let h = intersect_triangle_watertight(o, d, 0.0, f32::INFINITY, t[0], t[1], t[2]);
                prop_assert!(h.is_none(), "{method}: self hit {h:?}: tri {t:?} p {p:?} o {o:?} d {d:?}");
            }
        }
    }

    /// The error-bound offset puts the origin strictly on the chosen side of the
    /// triangle's exact plane (decided in f64, where the plane through the f32 vertices is
    /// exact to 2^-50 relative), and moves it by at most a few ulps of the coordinates:
    /// `OFFSET_ERROR_SCALE * |n|_1 <= 1.74` error bounds plus one step per coordinate.
    #[test]
    fn error_bound_offset_crosses_the_exact_plane_by_a_few_ulps(
        dir_c in unit_dir(),
        dist_exp in prop_oneof![Just(f32::NEG_INFINITY), 0.0f32..6.0],
        scale_exp in -3.0f32..3.0,
        a in unit_dir(), b in unit_dir(), c in unit_dir(),
        bary in [0.0f32..1.0, 0.0f32..1.0],
    ) {
        let Some((t, p, e)) = point_on_placed_triangle(dir_c, dist_exp, scale_exp, [a, b, c], bary) else { return Ok(()) };
        let n = face_normal(t);
        let [d0, d1, d2] = t.map(|x| x.as_dvec3());
        let exact_n = (d1 - d0).cross(d2 - d0);
        for side in [n, -n] {
            let o = offset_ray_origin(p, e, side);
            let dist = (o.as_dvec3() - d0).dot(exact_n) * exact_n.dot(side.as_dvec3()).signum();
            prop_assert!(dist > 0.0, "origin {o:?} not beyond the plane of {t:?} (p {p:?}, error {e})");
            let ulp = |x: f32| (f32::from_bits(x.abs().to_bits() + 1) - x.abs()) as f64;
            for i in 0..3 {
                let moved = (o[i] as f64 - p[i] as f64).abs();
                prop_assert!(moved <= 1.75 * e as f64 * (1.0 + 1e-6) + 2.0 * ulp(o[i].abs().max(p[i].abs())),
                    "axis {i}: moved {moved} for error {e}");
            }
        }
    }

    /// A point on a plane (two triangles) shoots a shadow ray (t_max = 1) at a light
    /// exactly above it along the plane normal: never occluded, at any distance/scale.
    #[test]
    fn shadow_rays_to_light_above_plane_are_not_occluded(
        dir_c in unit_dir(),
        dist_exp in prop_oneof![Just(f32::NEG_INFINITY), 4.0f32..6.0],
        scale_exp in -3.0f32..3.0,
        normal in unit_dir(),
        bary in [0.0f32..1.0, 0.0f32..1.0],
        height in 0.01f32..10.0,
    ) {
        let centre = dir_c * 10f32.powf(dist_exp);
        let scale = 10f32.powf(scale_exp);
        let s = normal.any_orthonormal_vector();
        let t = s.cross(normal);
        let corners = [-s - t, s - t, s + t, -s + t].map(|q| centre + q * scale);
        let quad = [[corners[0], corners[1], corners[2]], [corners[0], corners[2], corners[3]]];
        let g = soup(&quad);
        let bvh = Bvh::build(&g, BvhPreset::default());
        for tri in quad {
            // Skip triangles rounding has destroyed (small scale far from the origin).
            let Some(tri) = placed_triangle(Vec3::ZERO, 1.0, tri[0], tri[1], tri[2]) else { continue };
            let n = face_normal(tri);
            let up = if n.dot(normal) < 0.0 { -n } else { n };
            let (p, e) = bary_point(tri, bary[0] * 0.5, bary[1] * 0.5);
            let light = p + up * (height * scale);
            let o = offset_ray_origin(p, e, up);
            // The light must lie beyond the offset origin (a few ulps of the coordinates
            // with the error-bound offset): a light closer to the surface than that is
            // behind the origin and no shadow ray can reach it.
            if (light - p).dot(up) < 4.0 * (o - p).dot(up) { continue; }
            let mut r = ray(o, light - o, 0.0, 1.0);
            r.kind = RAY_KIND_SHADOW;
            r.light = 0;
            prop_assert!(r.validate().is_ok());
            prop_assert!(!bvh.occluded(g.stored_table(), &r), "false occlusion: p {p:?} o {o:?} light {light:?} quad {quad:?}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Pinned exact-float cases
// ---------------------------------------------------------------------------------------------

/// Exact values of simple hits: barycentrics are (weight of v1, weight of v2); both
/// faces are hit; hits at t_min or t_max exactly are excluded (t_min < t < t_max).
#[test]
fn pinned_exact_hits() {
    let (v0, v1, v2) = (Vec3::ZERO, Vec3::X, Vec3::Y);
    let o = Vec3::new(0.25, 0.5, 2.0);
    let h = intersect_triangle_watertight(o, Vec3::NEG_Z, 0.0, f32::INFINITY, v0, v1, v2).unwrap();
    assert_eq!((h.t, h.u, h.v), (2.0, 0.25, 0.5));
    let back = intersect_triangle_watertight(Vec3::new(0.25, 0.5, -2.0), Vec3::Z, 0.0, f32::INFINITY, v0, v1, v2);
    assert_eq!(back.map(|h| (h.t, h.u, h.v)), Some((2.0, 0.25, 0.5)));
    // Strict interval.
    assert!(intersect_triangle_watertight(o, Vec3::NEG_Z, 0.0, 2.0, v0, v1, v2).is_none());
    assert!(intersect_triangle_watertight(o, Vec3::NEG_Z, 2.0, 3.0, v0, v1, v2).is_none());
    assert!(intersect_triangle_watertight(o, Vec3::NEG_Z, 1.999_999_9, 2.000_000_2, v0, v1, v2).is_some());
    // Exactly through vertex v1 and along the edge v0-v2.
    let h =
        intersect_triangle_watertight(Vec3::new(1.0, 0.0, 1.0), Vec3::NEG_Z, 0.0, f32::INFINITY, v0, v1, v2).unwrap();
    assert_eq!((h.t, h.u, h.v), (1.0, 1.0, 0.0));
    let h =
        intersect_triangle_watertight(Vec3::new(0.0, 0.5, 1.0), Vec3::NEG_Z, 0.0, f32::INFINITY, v0, v1, v2).unwrap();
    assert_eq!((h.t, h.u, h.v), (1.0, 0.0, 0.5));
    // A hair outside the edge: miss.
    let eps = Vec3::new(-f32::MIN_POSITIVE, 0.5, 1.0);
    assert!(intersect_triangle_watertight(eps, Vec3::NEG_Z, 0.0, f32::INFINITY, v0, v1, v2).is_none());
    // Origin on the triangle: t would be 0, rejected (conservatively positive t).
    assert!(
        intersect_triangle_watertight(Vec3::new(0.25, 0.25, 0.0), Vec3::Z, 0.0, f32::INFINITY, v0, v1, v2).is_none()
    );
}

/// The facing of a hit comes from the determinant's sign: the front of a triangle is the
/// side its right-handed normal `(v1 - v0) x (v2 - v0)` points to, whichever axis the
/// ray space puts last and whichever way the ray travels along it.
#[test]
fn hits_know_the_face_they_hit() {
    let tri = [Vec3::new(0.1, -0.3, 0.2), Vec3::new(1.2, 0.4, -0.1), Vec3::new(-0.2, 1.1, 0.3)];
    let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
    let centre = (tri[0] + tri[1] + tri[2]) / 3.0;
    // Directions whose largest component is each axis, both signs, from both sides.
    for d in [Vec3::new(0.3, 0.2, 1.0), Vec3::new(1.0, 0.1, 0.4), Vec3::new(0.2, 1.0, -0.3)] {
        for d in [d, -d] {
            let o = centre - d * 3.0;
            let h = intersect_triangle_watertight(o, d, 0.0, f32::INFINITY, tri[0], tri[1], tri[2]).unwrap();
            assert_eq!(h.back_face, n.dot(d) > 0.0, "direction {d}");
            let w = hyrt_core::kernels::ray::WatertightRay::new(o, d).unwrap();
            assert_eq!(w.facing(tri[0], tri[1], tri[2]), h.back_face, "facing, direction {d}");
        }
    }
    // Through a vertex (the f64 fallback decides the edges): still the exact facing.
    let h =
        intersect_triangle_watertight(Vec3::new(1.0, 0.0, 1.0), Vec3::NEG_Z, 0.0, 9.0, Vec3::ZERO, Vec3::X, Vec3::Y);
    assert!(!h.unwrap().back_face);
    let h = intersect_triangle_watertight(Vec3::new(1.0, 0.0, -1.0), Vec3::Z, 0.0, 9.0, Vec3::ZERO, Vec3::X, Vec3::Y);
    assert!(h.unwrap().back_face);
}

/// Pinned: the f32 edge function of v1-v2 rounds to exactly 0 (both products round to
/// 1 + 2^-22) while its exact value is -2^-46, so the ray passes a hair outside the
/// edge. The exact sign (Dekker's error-free products) sees that and misses; a plain f32
/// test would report a hit. The mirrored triangle (v0 on the other side) contains the
/// ray and is hit, with the f32 edge values (the zero one stays zero).
#[test]
fn pinned_exact_sign_decides_rounded_zero_edge() {
    let (o, d) = (Vec3::new(0.0, 0.0, 1.0), Vec3::NEG_Z);
    let ulp = f32::EPSILON; // 2^-23
    let v1 = Vec3::new(1.0 + ulp, 1.0 + 2.0 * ulp, 0.0);
    let v2 = Vec3::new(-1.0, -(1.0 + ulp), 0.0);
    assert_eq!(v1.x * v2.y - v1.y * v2.x, 0.0);
    assert_eq!(edge_sign_exact(v1, v2), -(2f32.powi(-46)), "the exact value, here representable");
    assert_eq!(edge_sign_exact(v2, v1), 2f32.powi(-46), "antisymmetric");
    let outside = Vec3::new(1.0, -1.0, 0.0);
    let inside = Vec3::new(-1.0, 1.0, 0.0);
    assert_eq!(intersect_triangle_watertight(o, d, 0.0, f32::INFINITY, outside, v1, v2), None);
    let h = intersect_triangle_watertight(o, d, 0.0, f32::INFINITY, inside, v1, v2).unwrap();
    assert_eq!(h.t, 1.0);
    assert_eq!(h.u + h.v, 1.0, "on the v1-v2 edge: w is exactly 0 in f32");
}

/// `a * b = p + product_error(a, b, p)` exactly, for `p` the rounded product: checked in
/// f64, where the product of two f32 values is exact.
#[test]
fn product_error_is_the_exact_rounding_error() {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        // Magnitudes 2^-40 .. 2^40, random significands and signs.
        let m = 1.0 + (state >> 40) as f32 / (1u64 << 24) as f32;
        let e = ((state >> 8) % 81) as i32 - 40;
        let s = if state & 1 == 0 { 1.0 } else { -1.0 };
        s * m * 2f32.powi(e)
    };
    for _ in 0..200_000 {
        let (a, b) = (next(), next());
        let p = a * b;
        let exact = a as f64 * b as f64;
        assert_eq!(p as f64 + product_error(a, b, p) as f64, exact, "{a:e} * {b:e}");
    }
}

proptest! {
    /// Where an f32 edge function is exactly zero, [`edge_sign_exact`] has the exact sign
    /// (the f64 value's: both products are exact in f64) and is antisymmetric. The cases
    /// are built to round to zero: `b` is `a` scaled by `k` (parallel), its y nudged by
    /// the first of -8..=8 ulps that makes the f32 value exactly zero.
    #[test]
    fn edge_sign_exact_has_the_exact_sign(ax in -1.0e3f32..1.0e3, ay in -1.0e3f32..1.0e3, k in 0.01f32..100.0) {
        let nudge = |x: f32, n: i32| f32::from_bits((x.to_bits() as i32 + n) as u32);
        let a = Vec3::new(ax, ay, 0.0);
        let b = (-8..=8)
            .map(|n| Vec3::new(ax * k, nudge(ay * k, n), 0.0))
            .find(|b| a.x * b.y - a.y * b.x == 0.0);
        prop_assume!(b.is_some());
        let b = b.unwrap();
        let exact = a.x as f64 * b.y as f64 - a.y as f64 * b.x as f64;
        let s = edge_sign_exact(a, b);
        prop_assert_eq!(s.partial_cmp(&0.0), exact.partial_cmp(&0.0), "{:?} {:?}: {} vs {}", a, b, s, exact);
        prop_assert_eq!(edge_sign_exact(b, a), -s);
    }
}

proptest! {
    /// The origin lies exactly on the triangle's (tilted) plane, so the exact t is 0 and
    /// `t_min = 0` excludes it; the shear rounds, so the computed t can come out a tiny
    /// positive number. The conservative bound (t > deltaT) must reject it for every
    /// direction.
    #[test]
    fn origin_exactly_on_the_plane_never_hits(
        (y, z) in (1u32..63).prop_flat_map(|y| (Just(y), 1u32..64 - y)),
        d in unit_dir(),
    ) {
        let (y, z) = (y as f32 / 64.0, z as f32 / 64.0);
        // On the plane x + y + z = 1 (exact: dyadic coordinates).
        let o = Vec3::new(1.0 - y - z, y, z);
        let (v0, v1, v2) = (Vec3::X, Vec3::Y, Vec3::Z);
        let h = intersect_triangle_watertight(o, d, 0.0, f32::INFINITY, v0, v1, v2);
        prop_assert!(h.is_none(), "{o:?} {d:?}: {h:?}");
    }
}

/// The conservative `t > error` bound of the watertight test does not depend on the
/// length of the ray direction: a triangle 0.05 to 100 scene units in front of the origin
/// is hit with directions of length 1e-6 to 1e6 times the scene's scale, in scenes of
/// scale 1e-6 to 1e6. pbrt-v4's bound, which this kernel followed before, adds the z
/// scaled by 1 / d.z (units of t) to world-space x and y: with directions 1e-6 times the
/// scene's distances it was 0.96 t at one scene unit and 226 t at 100, so those hits were
/// rejected.
#[test]
fn conservative_t_bound_holds_for_any_direction_length() {
    for scene_exp in [-6i32, -3, 0, 3, 6] {
        let s = 10f32.powi(scene_exp);
        let tri = [Vec3::new(-s, -s, 0.3 * s), Vec3::new(s, -s, 0.3 * s), Vec3::new(0.0, s, 0.3 * s)];
        // Slightly oblique, so that the shear is not trivial, towards a point well inside.
        let (target, unit) = (Vec3::new(0.1, -0.2, 0.3) * s, Vec3::new(0.01, -0.02, 1.0).normalize());
        for dist in [0.05f32, 1.0, 100.0] {
            let origin = target - unit * (dist * s);
            for dir_exp in [-6i32, -3, 0, 3, 6] {
                let len = 10f32.powi(dir_exp) * s;
                let dir = unit * len;
                let want_t = dist * s / len;
                let case = format!("scene 1e{scene_exp}, {dist} units away, |d| 1e{dir_exp} x scale");
                let hit = intersect_triangle_watertight(origin, dir, 0.0, f32::INFINITY, tri[0], tri[1], tri[2]);
                let hit = hit.unwrap_or_else(|| panic!("{case}: no hit"));
                // Tolerance: f32 rounding of the origin, direction and vertices (the hit
                // distance is recovered from sums of products of them), far below 1e-4.
                assert!((hit.t - want_t).abs() <= want_t * 1e-4, "{case}: t {} vs {want_t}", hit.t);
            }
        }
    }
}

/// `next_float_up` / `next_float_down` (pbrt-v4's `NextFloatUp` / `NextFloatDown`) at
/// zeros, signs and infinities; the error-bound offset of pinned points.
#[test]
fn pinned_error_bound_offsets() {
    use hyrt_core::kernels::ray::{next_float_down, next_float_up, OFFSET_ERROR_SCALE};
    assert_eq!(next_float_up(0.0).to_bits(), 1);
    assert_eq!(next_float_up(-0.0).to_bits(), 1);
    assert_eq!(next_float_down(0.0).to_bits(), 0x8000_0001);
    assert_eq!(next_float_up(1.0).to_bits(), 1.0f32.to_bits() + 1);
    assert_eq!(next_float_up(-1.0).to_bits(), (-1.0f32).to_bits() - 1);
    assert_eq!(next_float_down(-1.0).to_bits(), (-1.0f32).to_bits() + 1);
    assert_eq!(next_float_up(f32::INFINITY), f32::INFINITY);
    assert_eq!(next_float_down(f32::NEG_INFINITY), f32::NEG_INFINITY);
    assert_eq!(next_float_up(f32::MAX), f32::INFINITY);
    // A zero normal (degenerate triangle) or a zero error bound leaves the point.
    let p = Vec3::new(1e5, -3.0, 0.5);
    assert_eq!(offset_ray_origin(p, 0.01, Vec3::ZERO), p);
    assert_eq!(offset_ray_origin(p, 0.0, Vec3::Y), p);
    // Axis-aligned: only y moves, by the scaled bound and one more step up.
    let o = offset_ray_origin(p, 0.01, Vec3::Y);
    assert_eq!((o.x, o.z), (p.x, p.z));
    assert_eq!(o.y, next_float_up(-3.0 + 0.01 * OFFSET_ERROR_SCALE));
    // At 1e5 the offset of a reconstructed point is a few ulps (0.0078 each), where
    // Wachter and Binder's 256 ulps are 2 units.
    let t = [Vec3::new(1e5, 0.0, 0.0), Vec3::new(1e5 + 1.0, 0.0, 0.0), Vec3::new(1e5, 0.0, 1.0)];
    let (q, e) = bary_point(t, 0.25, 0.25);
    let o = offset_ray_origin(q, e, Vec3::Y);
    assert!(o.y > 0.0 && o.y < 8.0 * 0.0078, "{o:?} (error {e})");
    let w = offset_ray_origin_integer_ulps(q, Vec3::Y);
    assert!(w.x == q.x && (w.y - q.y) < 1e-3, "near zero W-B moves y by 2^-16: {w:?}");
    let w = offset_ray_origin_integer_ulps(q, Vec3::X);
    assert!((w.x - q.x - 2.0).abs() < 1e-6, "256 ulps of 1e5 = 2 units: {w:?}");
}
