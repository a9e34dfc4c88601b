//! Tests of the `visibility_raster` stage: watertightness (every pixel of a closed
//! mesh or a flat grid covered exactly once), the fill rule against an independent
//! D3D11 top-left reference, clipping, hard inputs, determinism, and agreement with
//! an f64 ray cast through each pixel centre.

use std::collections::HashMap;

use hyrt_core::formats::{CameraRecord, GBufferTexel, GBUF_BACK_FACE, GBUF_HIT, GBUF_RAY_TRACED};
use hyrt_core::geometry::{MeshWinding, WorldGeometry};
use hyrt_core::glam::{DMat4, DVec3, DVec4, Mat4, Quat, Vec3, Vec4};
use hyrt_core::kernels::raster::FIXED_ONE;
use hyrt_core::scene::{Camera, Material, Mesh, RenderMode, Scene};
use hyrt_cpu::visibility_raster::{coverage_counts, visibility_raster, CoverageCounts, VisibilityOutput};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// Tolerances (each with its cause)
// ---------------------------------------------------------------------------------------------

/// Pixels whose centre lies within this distance (pixels) of a projected triangle
/// edge are not compared with the ray cast: snapping moves a vertex by up to
/// sqrt(2)/512 px (0.0028) and f32 projection adds ~1e-4 px, so the raster may
/// legitimately decide such pixels either way. The brief's "one subpixel".
const EDGE_MARGIN_PX: f64 = 1.0 / 256.0;
/// Largest on-screen displacement of a rasterized vertex from its exact f64
/// projection: the snap (half a subpixel on each axis, sqrt(2)/512 px) plus an
/// allowance of 1/1024 px for the f32 clip-space transform and divide.
const VERTEX_ERROR_PX: f64 = std::f64::consts::SQRT_2 / 512.0 + 1.0 / 1024.0;
/// First-order gain from a vertex displacement to a barycentric error: moving one
/// vertex by d changes a screen-space barycentric by at most d / h (h the smallest
/// altitude in px); three vertices give 3 d / h; the perspective division skews it
/// by at most w_max / w_min (applied separately); a factor 2 of margin on top.
const BARY_ERROR_GAIN: f64 = 6.0;
/// Rounding floor of the barycentric comparison: the result is rounded to f32
/// (half an ulp of 1 is 6e-8) and clipped vertices carry f32-interpolated
/// barycentrics (a few ulps).
const BARY_ROUNDING: f64 = 1e-6;
/// Relative gap in distance (measured from the eye, approximated as the near
/// distance plus the distance from the near plane) below which the two nearest
/// surfaces at a pixel are considered tied (touching or intersecting objects): there the raster's f32
/// depth and the snapped planes may legitimately pick either.
const DEPTH_TIE_RELATIVE: f64 = 1e-3;
/// Margin (px) around the projected outline of a grid within which a pixel may be
/// covered or not (the outline's vertices move by up to VERTEX_ERROR_PX).
const FOOTPRINT_MARGIN_PX: f64 = 1.0 / 64.0;

// ---------------------------------------------------------------------------------------------
// Scene helpers
// ---------------------------------------------------------------------------------------------

fn scene_with(objects: Vec<(Mesh, Mat4, RenderMode)>, camera: Option<Camera>) -> Scene {
    let mut s = Scene::default();
    for (mesh, transform, render_mode) in objects {
        s.add_object(mesh, Material::grey(), transform, render_mode);
    }
    s.camera = camera;
    s
}

fn raster(mesh: Mesh) -> (Mesh, Mat4, RenderMode) {
    (mesh, Mat4::IDENTITY, RenderMode::Raster)
}

/// A camera record whose world x, y are window x, y (pixels, y down) and whose
/// world z is the window depth: clip = (2x/W - 1, 1 - 2y/H, z, 1). For power-of-two
/// sizes and dyadic coordinates every f32 step of the rasterizer is exact, so
/// vertices can be placed exactly on pixel centres and subpixel ties. The eye is at the
/// origin, so the record's eye-relative matrix is this world-to-clip matrix.
fn window_camera(width: u32, height: u32) -> CameraRecord {
    let m = Mat4::from_cols(
        Vec4::new(2.0 / width as f32, 0.0, 0.0, 0.0),
        Vec4::new(0.0, -2.0 / height as f32, 0.0, 0.0),
        Vec4::new(0.0, 0.0, 1.0, 0.0),
        Vec4::new(-1.0, 1.0, 0.0, 1.0),
    );
    CameraRecord {
        view_proj: m.to_cols_array(),
        inv_view_proj: m.inverse().to_cols_array(),
        eye: [0.0, 0.0, 0.0],
        width,
        height,
        near: 0.5,
        far: 1.0,
        pad: 0,
    }
}

/// A mesh of separate triangles given by window-space corners (depth `z`).
fn triangles_mesh(tris: &[[[f32; 2]; 3]], z: f32) -> Mesh {
    let mut m = Mesh { name: "tris".into(), ..Default::default() };
    for t in tris {
        let base = m.positions.len() as u32;
        m.positions.extend(t.iter().map(|p| Vec3::new(p[0], p[1], z)));
        m.indices.push([base, base + 1, base + 2]);
    }
    m
}

/// Merge vertices closer than 1e-5 (the uv sphere's seam and south pole are
/// duplicated with sin(2 pi) and sin(pi) rounding apart in f32).
fn weld(mut mesh: Mesh) -> Mesh {
    let mut first: HashMap<[i64; 3], u32> = HashMap::new();
    let mut remap = Vec::with_capacity(mesh.positions.len());
    for (i, p) in mesh.positions.iter().enumerate() {
        let key = [p.x, p.y, p.z].map(|c| (c as f64 * 1e5).round() as i64);
        remap.push(*first.entry(key).or_insert(i as u32));
    }
    for idx in &mut mesh.indices {
        *idx = idx.map(|i| remap[i as usize]);
    }
    mesh
}

fn look_camera(eye: Vec3, target: Vec3, fov_y_deg: f32, near: f32, far: f32) -> Camera {
    Camera { eye, target, up: Vec3::Y, fov_y_deg, near, far }
}

fn render(scene: &Scene, cam: &CameraRecord) -> (WorldGeometry, VisibilityOutput) {
    let g = WorldGeometry::build(scene);
    let out = visibility_raster(&g, cam);
    check_output(&out, cam);
    (g, out)
}

/// Shape and invariants every output must satisfy.
fn check_output(out: &VisibilityOutput, cam: &CameraRecord) {
    assert_eq!((out.width, out.height), (cam.width, cam.height));
    assert_eq!(out.gbuffer.len(), (cam.width * cam.height) as usize);
    let mut hits = 0;
    for t in &out.gbuffer {
        t.validate().unwrap();
        hits += t.is_hit() as usize;
    }
    assert_eq!(out.covered_pixels, hits);
}

fn total(c: &CoverageCounts, i: usize) -> u32 {
    c.front[i] + c.back[i]
}

/// Assert per-pixel total coverage equals a reference mask.
macro_rules! assert_coverage_eq {
    ($c:expr, $mask:expr, $($arg:tt)*) => {{
        let c: &CoverageCounts = &$c;
        let m: &Vec<u32> = &$mask;
        for i in 0..m.len() {
            let (x, y) = (i as u32 % c.width, i as u32 / c.width);
            assert_eq!(total(c, i), m[i], "pixel ({x}, {y}): {}", format!($($arg)*));
        }
    }};
}

// ---------------------------------------------------------------------------------------------
// Independent references
// ---------------------------------------------------------------------------------------------

/// Snap an exact window coordinate (a dyadic f32) the way the rules say, with f64
/// and integer arithmetic instead of the kernel's f32 path: nearest, ties to even,
/// in the pixel-centre frame.
fn ref_snap(v: f32) -> i64 {
    ((v as f64 - 0.5) * FIXED_ONE as f64).round_ties_even() as i64
}

/// D3D11 functional spec 3.4.2.1, written from its wording (y down): a sample is
/// inside if it is strictly inside every edge, or on an edge that is a top edge
/// (exactly horizontal, the third vertex below it) or a left edge (not horizontal,
/// the triangle on its right). Degenerate triangles cover nothing.
fn d3d_covered(v: [[i64; 2]; 3], p: [i64; 2]) -> bool {
    let orient = |a: [i64; 2], b: [i64; 2], c: [i64; 2]| -> i128 {
        (b[0] - a[0]) as i128 * (c[1] - a[1]) as i128 - (b[1] - a[1]) as i128 * (c[0] - a[0]) as i128
    };
    if orient(v[0], v[1], v[2]) == 0 {
        return false;
    }
    for i in 0..3 {
        let (a, b, c) = (v[i], v[(i + 1) % 3], v[(i + 2) % 3]);
        let side = orient(a, b, p) * orient(a, b, c).signum();
        if side < 0 {
            return false;
        }
        if side == 0 {
            let top = a[1] == b[1] && c[1] > a[1];
            let left = a[1] != b[1] && {
                let num = (c[0] - a[0]) as i128 * (b[1] - a[1]) as i128 - (b[0] - a[0]) as i128 * (c[1] - a[1]) as i128;
                num * ((b[1] - a[1]) as i128).signum() > 0
            };
            if !(top || left) {
                return false;
            }
        }
    }
    true
}

/// Reference coverage mask of window-space triangles (exact dyadic corners).
fn d3d_mask(tris: &[[[f32; 2]; 3]], w: u32, h: u32) -> Vec<u32> {
    let mut mask = vec![0u32; (w * h) as usize];
    for t in tris {
        let v = t.map(|p| [ref_snap(p[0]), ref_snap(p[1])]);
        for y in 0..h as i64 {
            for x in 0..w as i64 {
                if d3d_covered(v, [x * FIXED_ONE, y * FIXED_ONE]) {
                    mask[(y * w as i64 + x) as usize] += 1;
                }
            }
        }
    }
    mask
}

// ---- f64 ray cast ---------------------------------------------------------------------------

struct RayHit {
    global: usize,
    t: f64,
    u: f64,
    v: f64,
    back: bool,
}

fn dvec(v: [f32; 3]) -> DVec3 {
    DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
}

/// The world-to-clip matrix the raster applies, in f64: the record's eye-relative
/// `view_proj` after a translation by `-eye` (the raster subtracts the eye first).
fn view_proj_f64(cam: &CameraRecord) -> DMat4 {
    DMat4::from_cols_array(&cam.view_proj.map(|c| c as f64)) * DMat4::from_translation(-dvec(cam.eye))
}

/// Near and far points of the ray through the centre of pixel (x, y). The inverse is
/// taken in f64 from the f32 `view_proj` the raster uses (checked against
/// `inv_view_proj`): the f32 inverse alone is off by more than the edge margin.
fn pixel_ray(cam: &CameraRecord, inv: &DMat4, x: u32, y: u32) -> (DVec3, DVec3) {
    let nx = (x as f64 + 0.5) / cam.width as f64 * 2.0 - 1.0;
    let ny = 1.0 - (y as f64 + 0.5) / cam.height as f64 * 2.0;
    let a = *inv * DVec4::new(nx, ny, 0.0, 1.0);
    let b = *inv * DVec4::new(nx, ny, 1.0, 1.0);
    (a.truncate() / a.w, b.truncate() / b.w)
}

/// Closest hit on the segment near -> far (depth 0..1) in f64 (Moller-Trumbore),
/// plus the second closest hit's parameter (for depth ties).
fn ray_cast(g: &WorldGeometry, near: DVec3, far: DVec3) -> Option<(RayHit, f64)> {
    let d = far - near;
    let mut best: Option<RayHit> = None;
    let mut second = f64::INFINITY;
    for (i, tri) in g.stored_table().iter().enumerate() {
        let (p0, p1, p2) = (dvec(tri.v0), dvec(tri.v1), dvec(tri.v2));
        let e1 = p1 - p0;
        let e2 = p2 - p0;
        let pv = d.cross(e2);
        let det = e1.dot(pv);
        if det == 0.0 || !det.is_finite() {
            continue;
        }
        let inv = 1.0 / det;
        let s = near - p0;
        let u = s.dot(pv) * inv;
        let q = s.cross(e1);
        let v = d.dot(q) * inv;
        let t = e2.dot(q) * inv;
        if !(u >= 0.0 && v >= 0.0 && u + v <= 1.0 && (0.0..=1.0).contains(&t)) {
            continue;
        }
        let back = e1.cross(e2).dot(d) > 0.0;
        match &best {
            Some(b) if t >= b.t => second = second.min(t),
            _ => {
                if let Some(b) = &best {
                    second = second.min(b.t);
                }
                best = Some(RayHit { global: i, t, u, v, back });
            }
        }
    }
    best.map(|b| (b, second))
}

/// Clip a triangle in f64 homogeneous space against 0 <= z <= w (same plane order
/// and fan as the raster) and project to window coordinates.
fn clipped_window_polygon(cam: &CameraRecord, vp: &DMat4, tri: [[f32; 3]; 3]) -> Vec<(DVec3, f64)> {
    let mut poly: Vec<DVec4> = tri.iter().map(|v| *vp * dvec(*v).extend(1.0)).collect();
    if poly.iter().any(|p| !p.is_finite()) {
        return Vec::new();
    }
    for plane in [|p: DVec4| p.z, |p: DVec4| p.w - p.z] {
        let mut out = Vec::new();
        for i in 0..poly.len() {
            let (a, b) = (poly[(i + poly.len() - 1) % poly.len()], poly[i]);
            let (da, db) = (plane(a), plane(b));
            if (da >= 0.0) != (db >= 0.0) {
                out.push(a + (b - a) * (da / (da - db)));
            }
            if db >= 0.0 {
                out.push(b);
            }
        }
        poly = out;
        if poly.len() < 3 {
            return Vec::new();
        }
    }
    let (w, h) = (cam.width as f64, cam.height as f64);
    poly.iter()
        .map(|p| (DVec3::new((p.x / p.w * 0.5 + 0.5) * w, (0.5 - p.y / p.w * 0.5) * h, p.z / p.w), p.w))
        .collect()
}

fn segment_distance(p: (f64, f64), a: DVec3, b: DVec3) -> f64 {
    let (ax, ay, bx, by) = (a.x, a.y, b.x, b.y);
    let (dx, dy) = (bx - ax, by - ay);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 { (((p.0 - ax) * dx + (p.1 - ay) * dy) / len2).clamp(0.0, 1.0) } else { 0.0 };
    let (cx, cy) = (ax + t * dx - p.0, ay + t * dy - p.1);
    (cx * cx + cy * cy).sqrt()
}

/// Per pixel: within EDGE_MARGIN_PX of some projected (clipped) triangle edge.
/// Per triangle: the barycentric tolerance (see BARY_ERROR_GAIN).
fn edge_mask_and_tolerances(g: &WorldGeometry, cam: &CameraRecord) -> (Vec<bool>, Vec<f64>) {
    let (w, h) = (cam.width as i64, cam.height as i64);
    let vp = view_proj_f64(cam);
    let mut near_edge = vec![false; (w * h) as usize];
    let mut tol = vec![f64::INFINITY; g.triangles.len()];
    for (ti, t) in g.stored_table().iter().enumerate() {
        let poly = clipped_window_polygon(cam, &vp, [t.v0, t.v1, t.v2]);
        if poly.is_empty() {
            continue;
        }
        for i in 0..poly.len() {
            let (a, b) = (poly[i].0, poly[(i + 1) % poly.len()].0);
            let m = EDGE_MARGIN_PX;
            let x0 = ((a.x.min(b.x) - m - 0.5).floor().max(0.0)) as i64;
            let x1 = ((a.x.max(b.x) + m - 0.5).ceil().min((w - 1) as f64)) as i64;
            let y0 = ((a.y.min(b.y) - m - 0.5).floor().max(0.0)) as i64;
            let y1 = ((a.y.max(b.y) + m - 0.5).ceil().min((h - 1) as f64)) as i64;
            for y in y0..=y1 {
                for x in x0..=x1 {
                    if segment_distance((x as f64 + 0.5, y as f64 + 0.5), a, b) <= m {
                        near_edge[(y * w + x) as usize] = true;
                    }
                }
            }
        }
        // Smallest altitude over the fan triangles, and the w spread.
        let mut h_min = f64::INFINITY;
        for i in 1..poly.len() - 1 {
            let [a, b, c] = [poly[0].0, poly[i].0, poly[i + 1].0];
            let area2 = ((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)).abs();
            let longest = [(a, b), (b, c), (c, a)]
                .iter()
                .map(|(p, q)| ((q.x - p.x).powi(2) + (q.y - p.y).powi(2)).sqrt())
                .fold(0.0, f64::max);
            h_min = h_min.min(area2 / longest);
        }
        let ws: Vec<f64> = poly.iter().map(|p| p.1).collect();
        let w_ratio = ws.iter().cloned().fold(0.0, f64::max) / ws.iter().cloned().fold(f64::INFINITY, f64::min);
        tol[ti] = BARY_ERROR_GAIN * VERTEX_ERROR_PX / h_min * w_ratio + BARY_ROUNDING;
    }
    (near_edge, tol)
}

/// Compare ids, facing and barycentrics of every pixel with the ray cast, except
/// near edges and at depth ties. Returns the number of compared pixels (hits and
/// misses).
fn assert_matches_ray_cast(g: &WorldGeometry, cam: &CameraRecord, out: &VisibilityOutput) -> usize {
    let vp = view_proj_f64(cam);
    let inv = vp.inverse();
    // The record's inverse is eye-relative too.
    let inv_rel = DMat4::from_cols_array(&cam.view_proj.map(|c| c as f64)).inverse();
    let inv32 = DMat4::from_cols_array(&cam.inv_view_proj.map(|c| c as f64));
    assert!(inv_rel.abs_diff_eq(inv32, 1e-3 * inv_rel.to_cols_array().iter().fold(0.0f64, |m, c| m.max(c.abs()))));
    let (near_edge, tol) = edge_mask_and_tolerances(g, cam);
    let mut compared = 0;
    for y in 0..cam.height {
        for x in 0..cam.width {
            let i = (y * cam.width + x) as usize;
            if near_edge[i] {
                continue;
            }
            let (n, f) = pixel_ray(cam, &inv, x, y);
            let hit = ray_cast(g, n, f);
            let texel = out.gbuffer[i];
            match hit {
                None => {
                    assert!(!texel.is_hit(), "pixel ({x}, {y}): raster hit {texel:?}, ray cast missed");
                    compared += 1;
                }
                Some((hit, second)) => {
                    let len = (f - n).length();
                    if (second - hit.t) * len <= DEPTH_TIE_RELATIVE * (hit.t * len + cam.near as f64) {
                        continue;
                    }
                    let rec = &g.triangle(hit.global);
                    assert!(texel.is_hit(), "pixel ({x}, {y}): raster missed, ray cast hit {rec:?}");
                    assert_eq!(
                        (texel.object, texel.triangle),
                        (rec.object, rec.triangle),
                        "pixel ({x}, {y}): ids differ from the ray cast"
                    );
                    assert_eq!(texel.flags & GBUF_BACK_FACE != 0, hit.back, "pixel ({x}, {y}): facing");
                    let t = tol[hit.global];
                    let (du, dv) = ((texel.bary_u as f64 - hit.u).abs(), (texel.bary_v as f64 - hit.v).abs());
                    assert!(
                        du <= t && dv <= t,
                        "pixel ({x}, {y}): barycentrics ({}, {}) vs ray cast ({}, {}), tolerance {t}",
                        texel.bary_u,
                        texel.bary_v,
                        hit.u,
                        hit.v
                    );
                    compared += 1;
                }
            }
        }
    }
    compared
}

// ---------------------------------------------------------------------------------------------
// Basic shapes of the output
// ---------------------------------------------------------------------------------------------

#[test]
fn visibility_raster_empty_geometry_is_all_miss() {
    let scene = scene_with(vec![], None);
    for (w, h) in [(1, 1), (64, 64), (70, 3)] {
        let cam = window_camera(w, h);
        let (_, out) = render(&scene, &cam);
        assert_eq!(out.covered_pixels, 0);
        assert!(out.gbuffer.iter().all(|t| t.to_bits() == GBufferTexel::MISS.to_bits()));
    }
    // Geometry entirely behind the camera: all miss too.
    let cam = Camera { eye: Vec3::ZERO, target: -Vec3::Z, up: Vec3::Y, fov_y_deg: 60.0, near: 0.1, far: 100.0 };
    let scene = scene_with(vec![(Mesh::cube("c"), Mat4::from_translation(Vec3::Z * 5.0), RenderMode::Raster)], None);
    let (_, out) = render(&scene, &CameraRecord::new(&cam, 32, 24));
    assert_eq!(out.covered_pixels, 0);
}

#[test]
fn visibility_raster_one_pixel_and_odd_sized_images() {
    // A quad larger than the image, split along a diagonal: every pixel of every
    // image size is covered exactly once, including the last partial tiles.
    for (w, h) in [(1, 1), (1, 7), (7, 1), (63, 65), (65, 33), (129, 127), (200, 1)] {
        let (fw, fh) = (w as f32, h as f32);
        let tris = [
            [[-0.75, -0.25], [-0.75, fh + 0.5], [fw + 1.0, fh + 0.5]],
            [[-0.75, -0.25], [fw + 1.0, fh + 0.5], [fw + 1.0, -0.25]],
        ];
        let mut mesh = triangles_mesh(&tris, 0.5);
        // Share the diagonal's vertices.
        mesh.positions.truncate(3);
        mesh.positions.push(Vec3::new(fw + 1.0, -0.25, 0.5));
        mesh.indices = vec![[0, 1, 2], [0, 2, 3]];
        let scene = scene_with(vec![raster(mesh)], None);
        let cam = window_camera(w, h);
        let (_, out) = render(&scene, &cam);
        assert_eq!(out.covered_pixels, (w * h) as usize, "{w}x{h}");
        let c = coverage_counts(&WorldGeometry::build(&scene), &cam);
        assert!((0..(w * h) as usize).all(|i| total(&c, i) == 1), "{w}x{h}");
        assert!(out.gbuffer.iter().all(|t| (t.depth - 0.5).abs() < 1e-6));
    }
}

// ---------------------------------------------------------------------------------------------
// Fill rule
// ---------------------------------------------------------------------------------------------

#[test]
fn visibility_raster_top_left_rule_on_pixel_centres() {
    let (w, h) = (16, 16);
    let cam = window_camera(w, h);
    let at = |x: u32, y: u32| (y * w + x) as usize;
    // A square with corners on pixel centres (2.5, 2.5) .. (10.5, 10.5), split along
    // either diagonal, each triangle in either winding: every centre of the square's
    // top and left sides and of the diagonal is covered once; right and bottom sides
    // are not covered.
    let (a, b, c, d) = ([2.5, 2.5], [10.5, 2.5], [10.5, 10.5], [2.5, 10.5]);
    let splits = [[[a, b, c], [a, c, d]], [[a, b, d], [b, c, d]]];
    for split in splits {
        for flip in 0..4 {
            let mut tris = split;
            if flip & 1 != 0 {
                tris[0].swap(1, 2);
            }
            if flip & 2 != 0 {
                tris[1].swap(1, 2);
            }
            let scene = scene_with(vec![raster(triangles_mesh(&tris, 0.5))], None);
            let c = coverage_counts(&WorldGeometry::build(&scene), &cam);
            for y in 0..h {
                for x in 0..w {
                    let inside = (2..10).contains(&x) && (2..10).contains(&y);
                    assert_eq!(total(&c, at(x, y)), inside as u32, "split {split:?} flip {flip} pixel ({x}, {y})");
                }
            }
            assert_eq!(c.front.iter().sum::<u32>() + c.back.iter().sum::<u32>(), 64);
            assert_coverage_eq!(c, d3d_mask(&tris, w, h), "split {split:?} flip {flip}");
        }
    }
}

#[test]
fn visibility_raster_top_left_edges_both_windings() {
    let (w, h) = (16, 16);
    let cam = window_camera(w, h);
    let cases: [[[f32; 2]; 3]; 6] = [
        // Horizontal top edge on a row of centres: covered.
        [[1.5, 3.5], [12.5, 3.5], [6.0, 11.0]],
        // Horizontal bottom edge on a row of centres: not covered.
        [[6.0, 1.0], [12.5, 9.5], [1.5, 9.5]],
        // Vertical left edge on a column of centres: covered.
        [[4.5, 1.5], [4.5, 13.5], [12.0, 7.0]],
        // Vertical right edge on a column of centres: not covered.
        [[11.5, 1.5], [3.0, 7.0], [11.5, 13.5]],
        // Sloped edges through centres (slope 1 and 1/2).
        [[1.5, 1.5], [13.5, 13.5], [1.5, 13.5]],
        [[0.5, 2.5], [14.5, 9.5], [14.5, 2.5]],
    ];
    for (k, t) in cases.iter().enumerate() {
        for tri in [*t, [t[0], t[2], t[1]]] {
            let scene = scene_with(vec![raster(triangles_mesh(&[tri], 0.25))], None);
            let c = coverage_counts(&WorldGeometry::build(&scene), &cam);
            assert_coverage_eq!(c, d3d_mask(&[tri], w, h), "case {k} {tri:?}");
        }
    }
    // Spot checks of the rule itself: (6, 3) on the top edge of case 0, (6, 9) on
    // the bottom edge of case 1, (4, 7) on the left edge of case 2, (11, 7) on the
    // right edge of case 3.
    let covered = |tri: [[f32; 2]; 3], x: u32, y: u32| d3d_mask(&[tri], w, h)[(y * w + x) as usize];
    assert_eq!(covered(cases[0], 6, 3), 1);
    assert_eq!(covered(cases[1], 6, 9), 0);
    assert_eq!(covered(cases[2], 4, 7), 1);
    assert_eq!(covered(cases[3], 11, 7), 0);
}

#[test]
fn visibility_raster_subpixel_ties_snap_to_even() {
    // Window x = 4.5 + k/512 snaps to (k/2 rounded to even)/256 past the centre of
    // column 4. A left edge there covers column 4 iff it snaps to the centre or left
    // of it; a right edge iff it snaps right of it. Rounding ties away from zero
    // (llvmpipe's scalar path) would flip the k = 1 cases.
    let (w, h) = (16, 16);
    let cam = window_camera(w, h);
    let run = |tri: [[f32; 2]; 3]| {
        let scene = scene_with(vec![raster(triangles_mesh(&[tri], 0.25))], None);
        let c = coverage_counts(&WorldGeometry::build(&scene), &cam);
        assert_coverage_eq!(c, d3d_mask(&[tri], w, h), "{tri:?}");
        c
    };
    let tie = 1.0 / 512.0;
    for (k, col4) in [(1, 1), (3, 0), (-1, 1), (-3, 1), (5, 0), (-5, 1)] {
        let x = 4.5 + k as f32 * tie;
        let c = run([[x, 1.5], [x, 13.5], [12.0, 7.0]]);
        assert_eq!(total(&c, (7 * w + 4) as usize), col4, "left edge at 4.5 + {k}/512");
    }
    for (k, col4) in [(1, 0), (3, 1), (-1, 0), (-3, 0)] {
        let x = 4.5 + k as f32 * tie;
        let c = run([[x, 1.5], [0.5, 7.0], [x, 13.5]]);
        assert_eq!(total(&c, (7 * w + 4) as usize), col4, "right edge at 4.5 + {k}/512");
    }
    for (k, row3) in [(1, 1), (3, 0), (5, 0), (-1, 1)] {
        let y = 3.5 + k as f32 * tie;
        let c = run([[1.5, y], [12.5, y], [6.0, 11.0]]);
        assert_eq!(total(&c, (3 * w + 6) as usize), row3, "top edge at 3.5 + {k}/512");
    }
    for (k, row9) in [(1, 0), (3, 1), (-1, 0)] {
        let y = 9.5 + k as f32 * tie;
        let c = run([[6.0, 1.0], [12.5, y], [1.5, y]]);
        assert_eq!(total(&c, (9 * w + 6) as usize), row9, "bottom edge at 9.5 + {k}/512");
    }
}

#[test]
fn visibility_raster_subpixel_and_sliver_triangles() {
    let (w, h) = (32, 32);
    let cam = window_camera(w, h);
    let cases: Vec<[[f32; 2]; 3]> = vec![
        // Tiny triangle around the centre of pixel (5, 5): exactly that pixel.
        [[5.45, 5.45], [5.6, 5.47], [5.5, 5.6]],
        // Tiny triangle between centres: nothing.
        [[5.7, 5.7], [5.9, 5.7], [5.8, 5.9]],
        // Zero area after snapping (all within 1/512 of each other): nothing.
        [[7.5, 7.5], [7.5 + 1.0 / 1024.0, 7.5], [7.5, 7.5 + 1.0 / 1024.0]],
        // Collinear: nothing.
        [[1.0, 1.0], [10.0, 10.0], [20.0, 20.0]],
        // Slivers along a row of centres, 1/256 px thick, both sides of it.
        [[0.25, 9.5], [30.75, 9.5], [30.75, 9.5 + 1.0 / 256.0]],
        [[0.25, 9.5], [30.75, 9.5 - 1.0 / 256.0], [30.75, 9.5]],
        // A long diagonal sliver crossing many tiles of the 64-pixel grid.
        [[0.1, 0.3], [31.9, 31.2], [31.9, 31.3]],
        // A needle touching one centre with its tip.
        [[12.5, 12.5], [30.0, 14.0], [30.0, 14.1]],
    ];
    for tri in &cases {
        for t in [*tri, [tri[0], tri[2], tri[1]]] {
            let scene = scene_with(vec![raster(triangles_mesh(&[t], 0.25))], None);
            let g = WorldGeometry::build(&scene);
            let c = coverage_counts(&g, &cam);
            assert_coverage_eq!(c, d3d_mask(&[t], w, h), "{t:?}");
            let out = visibility_raster(&g, &cam);
            check_output(&out, &cam);
            assert_eq!(out.covered_pixels as u32, c.front.iter().sum::<u32>() + c.back.iter().sum::<u32>());
        }
    }
    let single =
        |t| coverage_counts(&WorldGeometry::build(&scene_with(vec![raster(triangles_mesh(&[t], 0.25))], None)), &cam);
    let c = single(cases[0]);
    assert_eq!(total(&c, (5 * w + 5) as usize), 1);
    assert_eq!((0..(w * h) as usize).map(|i| total(&c, i)).sum::<u32>(), 1);
    for k in [1, 2, 3] {
        let c = single(cases[k]);
        assert_eq!((0..(w * h) as usize).map(|i| total(&c, i)).sum::<u32>(), 0, "case {k}");
    }
}

// ---------------------------------------------------------------------------------------------
// Watertightness
// ---------------------------------------------------------------------------------------------

/// A window-space grid of `n` x `n` cells from `origin` with cell size `cell`;
/// interior vertices moved by `jitter(i, j)` (boundary vertices stay on the
/// outline, so the covered area is exactly the snapped rectangle).
fn window_grid(n: u32, origin: [f32; 2], cell: f32, jitter: impl Fn(u32, u32) -> [f32; 2]) -> Mesh {
    let mut m = Mesh { name: "grid".into(), ..Default::default() };
    for j in 0..=n {
        for i in 0..=n {
            let mut p = [origin[0] + i as f32 * cell, origin[1] + j as f32 * cell];
            if i > 0 && j > 0 && i < n && j < n {
                let d = jitter(i, j);
                p = [p[0] + d[0], p[1] + d[1]];
            }
            m.positions.push(Vec3::new(p[0], p[1], 0.5));
        }
    }
    let row = n + 1;
    for j in 0..n {
        for i in 0..n {
            let a = j * row + i;
            let (b, c, d) = (a + 1, a + row, a + row + 1);
            if (i + j) % 2 == 0 {
                m.indices.push([a, c, b]);
                m.indices.push([b, c, d]);
            } else {
                m.indices.push([a, d, b]);
                m.indices.push([a, c, d]);
            }
        }
    }
    m
}

/// Covered exactly once inside the snapped rectangle (half-open: top and left
/// sides in, bottom and right out), never outside.
fn assert_window_grid_covered_once(
    n: u32,
    origin: [f32; 2],
    cell: f32,
    jitter: impl Fn(u32, u32) -> [f32; 2],
    w: u32,
    h: u32,
) {
    let cam = window_camera(w, h);
    let mesh = window_grid(n, origin, cell, jitter);
    let scene = scene_with(vec![raster(mesh)], None);
    let c = coverage_counts(&WorldGeometry::build(&scene), &cam);
    let (x0, y0) = (ref_snap(origin[0]), ref_snap(origin[1]));
    let (x1, y1) = (ref_snap(origin[0] + n as f32 * cell), ref_snap(origin[1] + n as f32 * cell));
    for y in 0..h {
        for x in 0..w {
            let (px, py) = (x as i64 * FIXED_ONE, y as i64 * FIXED_ONE);
            let inside = (x0..x1).contains(&px) && (y0..y1).contains(&py);
            assert_eq!(
                total(&c, (y * w + x) as usize),
                inside as u32,
                "grid n={n} origin={origin:?} cell={cell}: pixel ({x}, {y})"
            );
        }
    }
}

#[test]
fn visibility_raster_grid_on_pixel_centres_and_ties_covered_once() {
    let t = 1.0 / 512.0;
    let s = 1.0 / 256.0;
    // Vertices on pixel centres, on pixel corners, on 1/256 steps and on 1/512 ties.
    assert_window_grid_covered_once(8, [2.5, 3.5], 4.0, |_, _| [0.0, 0.0], 64, 64);
    assert_window_grid_covered_once(8, [2.0, 3.0], 4.0, |_, _| [0.0, 0.0], 64, 64);
    assert_window_grid_covered_once(
        10,
        [1.5 + s, 0.5 - s],
        5.0 + s,
        |i, j| [(i as f32 - 5.0) * s, (j as f32 - 5.0) * s],
        64,
        64,
    );
    assert_window_grid_covered_once(
        10,
        [1.5 + t, 0.5 + 3.0 * t],
        5.0 + 2.0 * t,
        |i, j| [((i * 7 + j) % 5) as f32 * t, ((i + j * 3) % 7) as f32 * t - 3.0 * t],
        64,
        64,
    );
    // Cells of one pixel and of half a pixel: every vertex on a centre or a tie.
    assert_window_grid_covered_once(40, [4.5, 4.5], 1.0, |i, j| [if (i + j) % 2 == 0 { t } else { -t }, 0.0], 64, 64);
    assert_window_grid_covered_once(
        40,
        [4.5 + t, 4.5 - t],
        0.5,
        |i, j| [((i + j) % 3) as f32 * t, ((i * j) % 3) as f32 * t],
        32,
        32,
    );
    // Crossing tile borders and the image border.
    assert_window_grid_covered_once(
        12,
        [-20.5, -3.5 + t],
        16.0,
        |i, j| [(i % 3) as f32 * t, (j % 5) as f32 * s],
        128,
        96,
    );
}

#[test]
fn visibility_raster_closed_mesh_covered_once() {
    // Closed meshes seen from several directions, entirely between near and far:
    // every pixel centre has as many front as back coverings; convex meshes are
    // covered at most once from each side; the visible hit is where coverage is.
    let meshes = [
        (weld(Mesh::uv_sphere("sphere", 32, 16)), true),
        (Mesh::cube("cube"), true),
        (Mesh::torus("torus", 1.0, 0.35, 32, 16), false),
        (weld(Mesh::uv_sphere("coarse", 7, 4)), true),
    ];
    let eyes =
        [Vec3::new(0.3, 0.4, 4.0), Vec3::new(-3.0, 2.0, -1.0), Vec3::new(0.0, 5.0, 0.01), Vec3::new(2.5, -1.0, 2.5)];
    for (mesh, convex) in &meshes {
        for (k, eye) in eyes.iter().enumerate() {
            let transform = Mat4::from_quat(Quat::from_rotation_y(0.3 * k as f32)) * Mat4::from_scale(Vec3::splat(0.9));
            let scene = scene_with(vec![(mesh.clone(), transform, RenderMode::Raster)], None);
            let g = WorldGeometry::build(&scene);
            for (w, h) in [(96, 64), (37, 41)] {
                let cam = CameraRecord::new(&look_camera(*eye, Vec3::ZERO, 50.0, 0.1, 50.0), w, h);
                let c = coverage_counts(&g, &cam);
                let out = visibility_raster(&g, &cam);
                check_output(&out, &cam);
                let mut covered = 0;
                for i in 0..(w * h) as usize {
                    assert_eq!(c.front[i], c.back[i], "{} eye {eye} {w}x{h}: pixel {i}", mesh.name);
                    assert!(c.front[i] <= if *convex { 1 } else { 2 }, "{} pixel {i}", mesh.name);
                    assert_eq!(out.gbuffer[i].is_hit(), c.front[i] > 0, "{} pixel {i}", mesh.name);
                    covered += (c.front[i] > 0) as usize;
                    // Seen from outside, the visible surface is a front face.
                    if out.gbuffer[i].is_hit() {
                        assert_eq!(out.gbuffer[i].flags & GBUF_BACK_FACE, 0);
                    }
                }
                assert!(covered > (w * h) as usize / 20, "{} eye {eye}: mesh barely visible", mesh.name);
            }
        }
    }
}

#[test]
fn visibility_raster_camera_inside_cube_sees_back_faces() {
    let scene = scene_with(vec![(Mesh::cube("room"), Mat4::from_scale(Vec3::splat(5.0)), RenderMode::RayTraced)], None);
    let cam = CameraRecord::new(
        &look_camera(Vec3::new(0.5, 0.2, 1.0), Vec3::new(-1.0, 0.0, -3.0), 70.0, 0.05, 100.0),
        48,
        32,
    );
    let (_, out) = render(&scene, &cam);
    assert_eq!(out.covered_pixels, 48 * 32);
    for t in &out.gbuffer {
        assert_eq!(t.flags, GBUF_HIT | GBUF_RAY_TRACED | GBUF_BACK_FACE);
        assert_eq!(t.object, 0);
    }
    let c = coverage_counts(&WorldGeometry::build(&scene), &cam);
    assert!(c.back.iter().all(|&n| n == 1) && c.front.iter().all(|&n| n == 0));
}

/// Perspective grid: outline corners in window space (f64), or None when a corner
/// is outside the depth range.
fn grid_outline(cam: &CameraRecord, transform: Mat4) -> Option<Vec<DVec3>> {
    let vp = view_proj_f64(cam);
    let mut out = Vec::new();
    for c in [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]] {
        let world = transform.transform_point3(Vec3::new(c[0], 0.0, c[1]));
        let p = vp * dvec(world.to_array()).extend(1.0);
        if !(p.w > 0.0 && p.z > 0.0 && p.z < p.w) {
            return None;
        }
        out.push(DVec3::new(
            (p.x / p.w * 0.5 + 0.5) * cam.width as f64,
            (0.5 - p.y / p.w * 0.5) * cam.height as f64,
            0.0,
        ));
    }
    Some(out)
}

/// Signed distance (px, positive inside) of a point to a convex polygon.
fn convex_signed_distance(poly: &[DVec3], p: (f64, f64)) -> f64 {
    let area: f64 = (0..poly.len())
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            a.x * b.y - b.x * a.y
        })
        .sum();
    let mut inside = true;
    let mut dist = f64::INFINITY;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let cross = (b.x - a.x) * (p.1 - a.y) - (b.y - a.y) * (p.0 - a.x);
        if cross * area.signum() < 0.0 {
            inside = false;
        }
        dist = dist.min(segment_distance(p, a, b));
    }
    if inside {
        dist
    } else {
        -dist
    }
}

/// A flat grid seen in perspective covers each pixel centre of its footprint once and none
/// outside it, counted with the sign of each triangle's facing (front minus back).
///
/// Why signed: snapping moves each vertex by up to half a subpixel, so a triangle narrower
/// than that on screen (a grid seen nearly edge-on) can come out of the snap with its
/// winding reversed. Shared vertices snap alike, so the grid stays watertight, but the
/// reversed sliver folds over its neighbours: a pixel centre under the fold is covered by
/// two front faces and the back face between them (pinned: `n = 9` in a 33x1 image, its
/// triangles 0.003 px wide). Any real rasterizer with a subpixel grid does the same. A
/// double covering by the fill rule (both triangles of a shared edge) counts 2.
fn assert_perspective_grid_covered_once(n: u32, transform: Mat4, cam: &CameraRecord) -> Result<(), TestCaseError> {
    let scene = scene_with(vec![(Mesh::grid("g", n), transform, RenderMode::Raster)], None);
    let g = WorldGeometry::build(&scene);
    let c = coverage_counts(&g, cam);
    let outline = grid_outline(cam, transform).expect("grid inside the depth range");
    for y in 0..cam.height {
        for x in 0..cam.width {
            let i = (y * cam.width + x) as usize;
            let d = convex_signed_distance(&outline, (x as f64 + 0.5, y as f64 + 0.5));
            let count = (i64::from(c.front[i]) - i64::from(c.back[i])).unsigned_abs() as u32;
            prop_assert!(count <= 1, "pixel ({}, {}) covered {} times ({:?})", x, y, count, (c.front[i], c.back[i]));
            // More than once only under a fold: front and back faces both there.
            prop_assert!(total(&c, i) <= 1 || c.front[i].min(c.back[i]) > 0, "pixel ({}, {})", x, y);
            if d > FOOTPRINT_MARGIN_PX {
                prop_assert_eq!(count, 1, "hole at pixel ({}, {}), {} px inside", x, y, d);
            } else if d < -FOOTPRINT_MARGIN_PX {
                prop_assert_eq!(count, 0, "pixel ({}, {}) covered {} px outside", x, y, -d);
            }
        }
    }
    Ok(())
}

#[test]
fn visibility_raster_perspective_grid_covered_once() {
    let cam = CameraRecord::new(&look_camera(Vec3::new(0.2, 1.0, 1.5), Vec3::ZERO, 60.0, 0.01, 100.0), 80, 60);
    for n in [1, 3, 16, 40] {
        let t = Mat4::from_quat(Quat::from_rotation_y(0.4)) * Mat4::from_scale(Vec3::splat(1.3));
        assert_perspective_grid_covered_once(n, t, &cam).unwrap();
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    #[test]
    fn visibility_raster_prop_random_grid_covered_once(
        n in 1u32..14,
        scale in 0.3f32..2.0,
        rot in prop::array::uniform3(-3.2f32..3.2),
        offset in prop::array::uniform3(-0.5f32..0.5),
        eye_dir in prop::array::uniform3(-1.0f32..1.0),
        eye_dist in 1.6f32..5.0,
        fov in 20.0f32..100.0,
        w in 1u32..97,
        h in 1u32..97,
    ) {
        let dir = Vec3::from(eye_dir);
        prop_assume!(dir.length() > 0.1 && dir.normalize().y.abs() < 0.99);
        let transform = Mat4::from_translation(Vec3::from(offset) * 0.5)
            * Mat4::from_quat(Quat::from_euler(hyrt_core::glam::EulerRot::XYZ, rot[0], rot[1], rot[2]))
            * Mat4::from_scale(Vec3::splat(scale));
        let eye = dir.normalize() * eye_dist * scale;
        let cam = CameraRecord::new(&look_camera(eye, Vec3::from(offset) * 0.3, fov, 0.01 * scale, 100.0 * scale), w, h);
        prop_assume!(grid_outline(&cam, transform).is_some());
        assert_perspective_grid_covered_once(n, transform, &cam)?;
    }

    #[test]
    fn visibility_raster_prop_window_grid_with_ties_covered_once(
        n in 1u32..12,
        origin in prop::array::uniform2(-2048i32..8192),
        cell in 256i32..4096,
        jitter_seed in any::<u64>(),
        size in prop::sample::select(vec![(32u32, 32u32), (64, 64), (128, 64)]),
    ) {
        // Everything on the 1/512 grid: positions k/512 with the jitter below an
        // eighth of a cell so no triangle flips.
        let t = 1.0 / 512.0;
        let amp = (cell / 8).max(1) as u64;
        let jitter = |i: u32, j: u32| {
            let hsh = jitter_seed ^ ((i as u64) << 32 | j as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            let a = (hsh % (2 * amp)) as i64 - amp as i64;
            let b = ((hsh >> 20) % (2 * amp)) as i64 - amp as i64;
            [a as f32 * t, b as f32 * t]
        };
        assert_window_grid_covered_once(n, [origin[0] as f32 * t, origin[1] as f32 * t], cell as f32 * t, jitter, size.0, size.1);
    }

    #[test]
    fn visibility_raster_prop_matches_d3d_top_left_reference(
        tris in prop::collection::vec(prop::array::uniform3(prop::array::uniform2(-4096i32..(48 * 512))), 1..4),
        snap_to_centres in any::<bool>(),
    ) {
        // Random triangles with vertices on the 1/512 grid (optionally on pixel
        // centres), many of them slivers and sharing edges by chance: the stage's
        // coverage equals the D3D11 reference exactly, pixel by pixel.
        let (w, h) = (64u32, 64u32);
        let pos = |k: i32| {
            if snap_to_centres { (k / 512) as f32 + 0.5 } else { k as f32 / 512.0 }
        };
        let tris: Vec<[[f32; 2]; 3]> = tris.iter().map(|t| t.map(|p| [pos(p[0]), pos(p[1])])).collect();
        let scene = scene_with(vec![raster(triangles_mesh(&tris, 0.5))], None);
        let c = coverage_counts(&WorldGeometry::build(&scene), &window_camera(w, h));
        let mask = d3d_mask(&tris, w, h);
        for (i, m) in mask.iter().enumerate() {
            prop_assert_eq!(total(&c, i), *m, "pixel {} of {:?}", i, tris);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Clipping
// ---------------------------------------------------------------------------------------------

#[test]
fn visibility_raster_near_plane_crossing_matches_analytic() {
    // Eye 1 above an infinite-looking ground (a 400 x 400 grid centred under the
    // eye, so half of it is behind the camera), looking along -Z with a 90 degree
    // square view and near = 2. The ground is hit at view distance 1 / -ndc_y, so
    // rows with ndc_y < -1/2 are clipped by the near plane; the grid ends at
    // distance 200, i.e. at ndc_y = -1/200.
    let (w, h) = (64u32, 64u32);
    let camera = look_camera(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 1.0, -1.0), 90.0, 2.0, 1000.0);
    let cam = CameraRecord::new(&camera, w, h);
    let scene =
        scene_with(vec![(Mesh::grid("ground", 16), Mat4::from_scale(Vec3::splat(400.0)), RenderMode::Raster)], None);
    let (g, out) = render(&scene, &cam);
    let c = coverage_counts(&g, &cam);
    let mut clipped_rows = 0;
    for y in 0..h {
        let ndc_y = 1.0 - (y as f64 + 0.5) / h as f64 * 2.0;
        let expect = ndc_y > -0.5 && ndc_y < -1.0 / 200.0;
        assert!((ndc_y + 0.5).abs() > 0.01 && (ndc_y + 1.0 / 200.0).abs() > 0.01, "test rows too close to a boundary");
        clipped_rows += (ndc_y < -0.5) as u32;
        for x in 0..w {
            let i = (y * w + x) as usize;
            assert_eq!(out.gbuffer[i].is_hit(), expect, "pixel ({x}, {y}) ndc_y {ndc_y}");
            assert_eq!(total(&c, i), expect as u32, "pixel ({x}, {y}) coverage");
            if expect {
                // Analytic depth of the ground at this row (directx projection):
                // z_ndc = f / (f - n) * (1 - n / d) with d = 1 / -ndc_y.
                let (n, f) = (2.0f64, 1000.0f64);
                let d = 1.0 / -ndc_y;
                let z = f / (f - n) * (1.0 - n / d);
                // Depth is affine in ndc_y here (z = f/(f-n) * (1 + n ndc_y)); snapped
                // vertices shift that plane by at most its slope times VERTEX_ERROR_PX.
                let slope_per_px = f / (f - n) * n * 2.0 / h as f64;
                let tol = 2.0 * slope_per_px * VERTEX_ERROR_PX + 1e-6;
                assert!(
                    (out.gbuffer[i].depth as f64 - z).abs() < tol,
                    "pixel ({x}, {y}) depth {} vs {z}",
                    out.gbuffer[i].depth
                );
                assert_eq!(out.gbuffer[i].flags & GBUF_BACK_FACE, 0, "the ground is seen from above");
            }
        }
    }
    assert_eq!(clipped_rows, 16);
    assert!(assert_matches_ray_cast(&g, &cam, &out) > 500);
}

#[test]
fn visibility_raster_near_and_far_clipped_closed_mesh() {
    // A long box crossing both the near and the far plane: the clipped shapes
    // stay watertight (at most one front and one back covering per pixel) and
    // agree with the analytic ray cast restricted to depth 0..1.
    let box_t = Mat4::from_translation(Vec3::new(0.0, 0.0, -10.0)) * Mat4::from_scale(Vec3::new(1.0, 0.7, 12.0));
    let scene = scene_with(vec![(weld(Mesh::uv_sphere("s", 24, 12)), box_t, RenderMode::Raster)], None);
    let camera = look_camera(Vec3::new(0.9, 0.2, 0.0), Vec3::new(-0.3, 0.0, -10.0), 60.0, 0.5, 18.0);
    let cam = CameraRecord::new(&camera, 72, 56);
    let (g, out) = render(&scene, &cam);
    let c = coverage_counts(&g, &cam);
    assert!(c.front.iter().chain(c.back.iter()).all(|&n| n <= 1));
    assert!(out.covered_pixels > 100);
    assert!(assert_matches_ray_cast(&g, &cam, &out) > 500);
}

#[test]
fn visibility_raster_huge_coordinates_use_the_guard_band() {
    // An edge from (-4e6, 10) to (4e6, 50) in window space crosses the image; the
    // triangle's other vertex is far below. Its vertices lie beyond the guard band,
    // so it is clipped there; on screen it is the half-plane below the edge.
    let (w, h) = (64u32, 64u32);
    let tri = [[-4.0e6f32, 10.0], [4.0e6, 50.0], [0.0, 3.0e7]];
    let scene = scene_with(vec![raster(triangles_mesh(&[tri], 0.5))], None);
    let cam = window_camera(w, h);
    let (g, out) = render(&scene, &cam);
    let c = coverage_counts(&g, &cam);
    for y in 0..h {
        for x in 0..w {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let line_y = 10.0 + (px + 4.0e6) / 8.0e6 * 40.0;
            let i = (y * w + x) as usize;
            assert!(total(&c, i) <= 1);
            if (py - line_y).abs() > 0.1 {
                assert_eq!(out.gbuffer[i].is_hit(), py > line_y, "pixel ({x}, {y})");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Hard inputs
// ---------------------------------------------------------------------------------------------

#[test]
fn visibility_raster_non_finite_and_degenerate_triangles_cover_nothing() {
    let cam = CameraRecord::new(&look_camera(Vec3::new(0.0, 1.0, 3.0), Vec3::ZERO, 60.0, 0.1, 50.0), 64, 48);
    let good = (Mesh::cube("cube"), Mat4::IDENTITY, RenderMode::Raster);
    let nan = f32::NAN;
    let inf = f32::INFINITY;
    let bad = Mesh {
        name: "bad".into(),
        positions: vec![
            Vec3::new(nan, 0.0, 0.0),
            Vec3::new(0.0, inf, 0.0),
            Vec3::new(-inf, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(2.0, 2.0, 2.0),
            Vec3::new(3.0e38, 0.0, 0.0),
            Vec3::new(0.0, nan, nan),
        ],
        normals: None,
        // NaN, Inf, overflowing, repeated-index and collinear triangles.
        indices: vec![[0, 3, 4], [1, 3, 4], [2, 4, 3], [3, 3, 4], [3, 4, 5], [6, 6, 3], [7, 0, 1], [4, 4, 4]],
        ..Default::default()
    };
    let (_, reference) = render(&scene_with(vec![good.clone()], None), &cam);
    let scene = scene_with(vec![good, (bad, Mat4::IDENTITY, RenderMode::Raster)], None);
    let g = WorldGeometry::build(&scene);
    assert!(g.non_finite_triangles >= 4);
    let out = visibility_raster(&g, &cam);
    check_output(&out, &cam);
    assert_eq!(
        out.gbuffer.iter().map(|t| t.to_bits()).collect::<Vec<_>>(),
        reference.gbuffer.iter().map(|t| t.to_bits()).collect::<Vec<_>>()
    );
    // A transform full of NaN: nothing at all.
    let mut nan_t = Mat4::IDENTITY;
    nan_t.w_axis.x = nan;
    let scene = scene_with(vec![(Mesh::cube("c"), nan_t, RenderMode::Raster)], None);
    assert_eq!(render(&scene, &cam).1.covered_pixels, 0);
}

#[test]
fn visibility_raster_far_from_origin_and_tiny_scales_stay_watertight() {
    // Embree's verify offset and 1e6: f32 world positions are coarse there, but
    // shared vertices are shared bits, so closed meshes stay watertight.
    for offset in [Vec3::new(148376.0, 1234.0, -223423.0), Vec3::new(1.0e6, -1.0e6, 5.0e5)] {
        for (mesh, scale) in [(weld(Mesh::uv_sphere("s", 32, 16)), 50.0f32), (Mesh::torus("t", 1.0, 0.4, 24, 12), 80.0)]
        {
            let t = Mat4::from_translation(offset) * Mat4::from_scale(Vec3::splat(scale));
            let scene = scene_with(vec![(mesh, t, RenderMode::Raster)], None);
            let g = WorldGeometry::build(&scene);
            let eye = offset + Vec3::new(1.0, 0.6, 3.0) * scale * 1.3;
            let cam = CameraRecord::new(&look_camera(eye, offset, 55.0, scale * 0.1, scale * 20.0), 72, 48);
            let c = coverage_counts(&g, &cam);
            let out = visibility_raster(&g, &cam);
            check_output(&out, &cam);
            assert!(out.covered_pixels > 200, "offset {offset}");
            for i in 0..c.front.len() {
                assert_eq!(c.front[i], c.back[i], "offset {offset} pixel {i}");
                assert!(c.front[i] <= 2);
            }
        }
    }
    // Tiny scale: a 1e-3 sized scene seen from close by matches the ray cast.
    let s = 1.0e-3f32;
    let scene = scene_with(
        vec![
            (weld(Mesh::uv_sphere("s", 24, 12)), Mat4::from_scale(Vec3::splat(s)), RenderMode::Raster),
            (
                Mesh::cube("c"),
                Mat4::from_translation(Vec3::new(2.5, 0.0, -1.0) * s) * Mat4::from_scale(Vec3::splat(0.8 * s)),
                RenderMode::RayTraced,
            ),
        ],
        None,
    );
    let cam = CameraRecord::new(
        &look_camera(Vec3::new(0.5, 1.0, 5.0) * s, Vec3::new(1.0, 0.0, 0.0) * s, 60.0, 0.01 * s, 100.0 * s),
        64,
        40,
    );
    let (g, out) = render(&scene, &cam);
    assert!(assert_matches_ray_cast(&g, &cam, &out) > 300);
    let c = coverage_counts(&g, &cam);
    assert!((0..c.front.len()).all(|i| c.front[i] == c.back[i] && c.front[i] <= 1));
}

// ---------------------------------------------------------------------------------------------
// Depth test, flags, determinism, ray cast
// ---------------------------------------------------------------------------------------------

#[test]
fn visibility_raster_depth_less_keeps_the_earlier_triangle() {
    let (w, h) = (32u32, 32u32);
    let cam = window_camera(w, h);
    let big = [[-1.0f32, -1.0], [40.0, -1.0], [-1.0, 40.0]];
    // Same triangle twice at the same depth: the first object wins everywhere.
    let scene = scene_with(vec![raster(triangles_mesh(&[big], 0.5)), raster(triangles_mesh(&[big], 0.5))], None);
    let (_, out) = render(&scene, &cam);
    assert!(out.covered_pixels > 0);
    assert!(out.gbuffer.iter().filter(|t| t.is_hit()).all(|t| t.object == 0));
    // A nearer triangle wins whatever the order; within one mesh too.
    for order in [[0.25f32, 0.75], [0.75, 0.25]] {
        let scene =
            scene_with(vec![raster(triangles_mesh(&[big], order[0])), raster(triangles_mesh(&[big], order[1]))], None);
        let (_, out) = render(&scene, &cam);
        let nearer = if order[0] < order[1] { 0 } else { 1 };
        assert!(out.gbuffer.iter().filter(|t| t.is_hit()).all(|t| t.object == nearer && t.depth == 0.25));
        let mut mesh = triangles_mesh(&[big], order[0]);
        mesh.positions.extend([big[0], big[1], big[2]].iter().map(|p| Vec3::new(p[0], p[1], order[1])));
        mesh.indices.push([3, 4, 5]);
        let (_, out) = render(&scene_with(vec![raster(mesh)], None), &cam);
        let first_nearer = if order[0] < order[1] { 0 } else { 1 };
        assert!(out.gbuffer.iter().filter(|t| t.is_hit()).all(|t| t.triangle == first_nearer));
    }
    // Depth exactly 1 (the clear value) fails LESS; depth 0 passes.
    let scene = scene_with(vec![raster(triangles_mesh(&[big], 1.0))], None);
    assert_eq!(render(&scene, &cam).1.covered_pixels, 0);
    let scene = scene_with(vec![raster(triangles_mesh(&[big], 0.0))], None);
    assert!(render(&scene, &cam).1.gbuffer.iter().filter(|t| t.is_hit()).all(|t| t.depth == 0.0));
}

#[test]
fn visibility_raster_texel_values_on_a_window_space_triangle() {
    // Affine camera (w = 1): barycentrics are the exact screen-space ones and the
    // depth interpolates linearly; flags carry the render mode and the facing.
    let (w, h) = (64u32, 64u32);
    let cam = window_camera(w, h);
    let tri = [Vec3::new(2.5, 2.5, 0.25), Vec3::new(60.5, 6.5, 0.5), Vec3::new(10.5, 58.5, 0.75)];
    let mesh = Mesh {
        name: "t".into(),
        positions: tri.to_vec(),
        normals: None,
        indices: vec![[0, 1, 2]],
        ..Default::default()
    };
    let scene = scene_with(vec![(mesh, Mat4::IDENTITY, RenderMode::RayTraced)], None);
    let (_, out) = render(&scene, &cam);
    let area = ((tri[1].x - tri[0].x) * (tri[2].y - tri[0].y) - (tri[1].y - tri[0].y) * (tri[2].x - tri[0].x)) as f64;
    let mut seen = 0;
    for y in 0..h {
        for x in 0..w {
            let t = out.gbuffer[(y * w + x) as usize];
            if !t.is_hit() {
                continue;
            }
            seen += 1;
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let e = |a: Vec3, b: Vec3| {
                ((b.x - a.x) as f64 * (py - a.y as f64) - (b.y - a.y) as f64 * (px - a.x as f64)) / area
            };
            let (u, v) = (e(tri[2], tri[0]), e(tri[0], tri[1]));
            // All vertices are on pixel centres, so snapping is exact: only f32
            // rounding of the result remains.
            assert!(
                (t.bary_u as f64 - u).abs() < 1e-6 && (t.bary_v as f64 - v).abs() < 1e-6,
                "({x}, {y}) {t:?} vs {u} {v}"
            );
            let depth = 0.25 * (1.0 - u - v) + 0.5 * u + 0.75 * v;
            assert!((t.depth as f64 - depth).abs() < 1e-6);
            // Clockwise on screen: a back face by the screen-space rule (this
            // mirrored camera is not a real one, so only the screen rule applies).
            assert_eq!(t.flags, GBUF_HIT | GBUF_RAY_TRACED | GBUF_BACK_FACE);
            assert_eq!((t.object, t.triangle), (0, 0));
        }
    }
    assert!(seen > 1000);
}

fn determinism_scenes() -> Vec<(Scene, CameraRecord)> {
    let default = Scene::default_scene();
    let cam = CameraRecord::new(&default.camera.unwrap(), 203, 117);
    let ground =
        scene_with(vec![(Mesh::grid("ground", 24), Mat4::from_scale(Vec3::splat(400.0)), RenderMode::Raster)], None);
    let gcam =
        CameraRecord::new(&look_camera(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.3, 0.8, -1.0), 80.0, 0.5, 300.0), 130, 70);
    vec![(default, cam), (ground, gcam)]
}

#[test]
fn visibility_raster_deterministic_across_thread_counts() {
    for (scene, cam) in determinism_scenes() {
        let g = WorldGeometry::build(&scene);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| visibility_raster(&g, &cam)).gbuffer.iter().map(|t| t.to_bits()).collect::<Vec<_>>()
        };
        let one = run(1);
        assert_eq!(one, run(2));
        assert_eq!(one, run(3));
        assert_eq!(one, run(2));
        assert!(one.iter().any(|b| b[5] & GBUF_HIT != 0));
    }
}

#[test]
fn visibility_raster_matches_ray_cast_default_scene() {
    let scene = Scene::default_scene();
    for (w, h) in [(96, 72), (67, 45)] {
        let cam = CameraRecord::new(&scene.camera.unwrap(), w, h);
        let (g, out) = render(&scene, &cam);
        let compared = assert_matches_ray_cast(&g, &cam, &out);
        assert!(compared > (w * h) as usize / 2, "only {compared} pixels compared");
        assert!(
            out.gbuffer.iter().any(|t| t.is_ray_traced())
                && out.gbuffer.iter().any(|t| t.is_hit() && !t.is_ray_traced())
        );
    }
}

#[test]
fn visibility_raster_matches_ray_cast_floating_objects() {
    let scene = scene_with(
        vec![
            (
                weld(Mesh::uv_sphere("s", 40, 20)),
                Mat4::from_translation(Vec3::new(-1.2, 0.3, 0.0)),
                RenderMode::RayTraced,
            ),
            (
                Mesh::torus("t", 1.0, 0.3, 40, 16),
                Mat4::from_translation(Vec3::new(1.3, 0.0, -0.5)) * Mat4::from_quat(Quat::from_rotation_x(1.1)),
                RenderMode::Raster,
            ),
            (
                Mesh::cube("c"),
                Mat4::from_translation(Vec3::new(0.2, -0.2, -3.0)) * Mat4::from_scale(Vec3::splat(0.7)),
                RenderMode::Raster,
            ),
            (
                Mesh::grid("floor", 6),
                Mat4::from_translation(Vec3::new(0.0, -1.6, 0.0)) * Mat4::from_scale(Vec3::splat(9.0)),
                RenderMode::Raster,
            ),
        ],
        None,
    );
    let cam =
        CameraRecord::new(&look_camera(Vec3::new(0.4, 1.5, 4.5), Vec3::new(0.0, -0.2, -0.5), 55.0, 0.1, 40.0), 120, 80);
    let (g, out) = render(&scene, &cam);
    let compared = assert_matches_ray_cast(&g, &cam, &out);
    assert!(compared > 120 * 80 * 3 / 4, "only {compared} pixels compared");
    // The floor is seen from above, the objects from outside: no back faces except
    // the torus' inner side seen through its hole is still its outer surface.
    assert!(out.gbuffer.iter().filter(|t| t.is_hit()).all(|t| t.flags & GBUF_BACK_FACE == 0));
}

#[test]
fn visibility_raster_into_a_reused_buffer_equals_a_fresh_one() {
    // A buffer left over from another scene (and filled with garbage) must not leak
    // into the next frame: every texel is written.
    let scene = hyrt_core::scene::Scene::default_scene();
    let g = hyrt_core::geometry::WorldGeometry::build(&scene);
    let cam = CameraRecord::new(&scene.camera.unwrap(), 97, 61);
    let fresh = hyrt_cpu::visibility_raster::visibility_raster(&g, &cam);
    let garbage = GBufferTexel { bary_u: 7.0, bary_v: -3.0, depth: 0.25, triangle: 5, object: 1, flags: 3 };
    let mut reused = vec![garbage; 97 * 61];
    let covered = hyrt_cpu::visibility_raster::visibility_raster_into(&g, &cam, &mut reused);
    assert_eq!(covered, fresh.covered_pixels);
    let bits = |b: &[GBufferTexel]| b.iter().map(|t| t.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&reused), bits(&fresh.gbuffer));
    // A buffer of another size is replaced.
    let mut wrong_size = vec![garbage; 3];
    hyrt_cpu::visibility_raster::visibility_raster_into(&g, &cam, &mut wrong_size);
    assert_eq!(bits(&wrong_size), bits(&fresh.gbuffer));
}

/// A closed convex mesh seen from outside shows only its exterior: no pixel may show the
/// side facing into it, even on silhouettes, where the face behind shares an edge with
/// the visible one and their depths tie to within rounding (`depth_test_value`), and far
/// from the origin, where only the eye-relative projection keeps the silhouettes in place.
/// Both windings: outward (the exterior is the front faces) and inward (the back faces,
/// `TRI_INWARD`).
#[test]
fn visibility_raster_closed_convex_meshes_show_no_interior_on_silhouettes() {
    let flip = |m: &Mesh| Mesh { indices: m.indices.iter().map(|&[a, b, c]| [a, c, b]).collect(), ..m.clone() };
    let (sphere, cube) = (Mesh::uv_sphere("sphere", 64, 32), Mesh::cube("cube"));
    let (sphere_in, cube_in) = (flip(&sphere), flip(&cube));
    let mut shown = 0;
    for (mesh, back_is_outside) in [(&sphere, false), (&sphere_in, true), (&cube, false), (&cube_in, true)] {
        for centre in [Vec3::ZERO, Vec3::new(3e4, -1e4, 2e4), Vec3::new(6e5, 2e5, -4e5)] {
            // Half size such that the sphere spans at least 400 ulps of its coordinates.
            let ulp = |x: f32| f32::from_bits(x.to_bits() + 1) - x;
            let r = (400.0 * ulp(centre.abs().max_element() + 1.0)).max(1.0);
            let mut scene = Scene::default();
            let t = Mat4::from_translation(centre) * Mat4::from_scale(Vec3::splat(r));
            scene.add_object(mesh.clone(), Material::grey(), t, RenderMode::Raster);
            let g = WorldGeometry::build(&scene);
            // Directions on a golden-angle spiral, plus two exactly in the planes of faces.
            let dirs = (0..24).map(|k| {
                let z = 1.0 - (k as f32 + 0.5) / 12.0;
                let a = k as f32 * 2.399_963;
                Vec3::new((1.0 - z * z).sqrt() * a.cos(), z, (1.0 - z * z).sqrt() * a.sin())
            });
            for dir in dirs.chain([Vec3::new(1.0, 1.0, 5.0), Vec3::new(0.3, 1.0, -4.0)]) {
                let eye = centre + dir.normalize() * (3.5 * r);
                let eye = if dir.y == 1.0 { t.transform_point3(dir) } else { eye };
                let cam = CameraRecord::new(&look_camera(eye, centre, 40.0, 0.1 * r, 10.0 * r), 320, 240);
                let out = visibility_raster(&g, &cam);
                for (i, texel) in out.gbuffer.iter().enumerate().filter(|(_, t)| t.is_hit()) {
                    shown += 1;
                    let back = texel.flags & GBUF_BACK_FACE != 0;
                    assert_eq!(back, back_is_outside, "centre {centre}, eye {eye}: pixel {i} shows the inside");
                }
            }
        }
    }
    assert!(shown > 1_000_000, "{shown} pixels");
}

// ---------------------------------------------------------------------------------------------
// Interiors of closed objects (`WorldGeometry::interior_culls`)
// ---------------------------------------------------------------------------------------------

/// `g` with no object's interior dropped: every mesh taken as open.
fn without_interior_culls(g: &WorldGeometry) -> WorldGeometry {
    let mut open = g.clone();
    open.windings.iter_mut().for_each(|w| *w = MeshWinding::Open);
    open
}

/// Closed meshes seen from outside, wholly in front of the near plane: dropping the
/// triangles that show their interior changes no texel (the uv sphere, the torus, the
/// cube, raster and ray traced, near and far, and a mirrored cube, whose back faces are
/// its exterior).
#[test]
fn visibility_raster_closed_objects_seen_from_outside_same_texels_without_their_interiors() {
    let cam = CameraRecord::new(&look_camera(Vec3::new(0.4, 0.9, 4.0), Vec3::ZERO, 50.0, 0.05, 50.0), 160, 120);
    let scene = scene_with(
        vec![
            (weld(Mesh::uv_sphere("s", 32, 16)), Mat4::from_translation(Vec3::new(-1.0, 0.0, 0.0)), RenderMode::Raster),
            (
                Mesh::torus("t", 0.6, 0.25, 24, 12),
                Mat4::from_translation(Vec3::new(1.0, 0.2, -1.0)),
                RenderMode::RayTraced,
            ),
            (Mesh::cube("c"), Mat4::from_translation(Vec3::new(0.0, -0.8, 2.5)), RenderMode::Raster),
            (
                Mesh::cube("m"),
                Mat4::from_scale_rotation_translation(
                    Vec3::new(-0.5, 0.5, 0.5),
                    Quat::from_rotation_y(0.7),
                    Vec3::new(0.3, 1.0, 1.5),
                ),
                RenderMode::Raster,
            ),
        ],
        None,
    );
    let (g, out) = render(&scene, &cam);
    assert_eq!(g.interior_culls(&cam), vec![0b1111], "every object closed and in front of the near plane");
    let all = visibility_raster(&without_interior_culls(&g), &cam);
    assert!(out.covered_pixels > 4000, "{} pixels", out.covered_pixels);
    assert_eq!(out.gbuffer, all.gbuffer);
}

/// An inside-out cube (a closed part wound inward) in front of a closed cube, in one
/// mesh that is closed and wound outward as a whole: the faces of the small cube that face
/// the camera show its interior and are dropped, so the pixels behind them show its far
/// faces, which face the camera; drawn whole, the near faces (back faces, nearest) win.
/// Elsewhere the texels are the same.
#[test]
fn visibility_raster_drops_the_interior_faces_of_a_closed_object() {
    let big = Mesh::cube("big");
    let mut small = Mesh::cube("small");
    small.indices.iter_mut().for_each(|t| t.swap(1, 2));
    let mut mesh = Mesh { name: "one".into(), ..Default::default() };
    for (m, t) in [
        (&big, Mat4::IDENTITY),
        (&small, Mat4::from_scale_rotation_translation(Vec3::splat(0.25), Quat::IDENTITY, Vec3::new(0.0, 0.0, 2.0))),
    ] {
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(m.positions.iter().map(|p| t.transform_point3(*p)));
        mesh.indices.extend(m.indices.iter().map(|i| i.map(|k| k + base)));
    }
    let small_ids = big.indices.len() as u32..mesh.indices.len() as u32;
    let cam = CameraRecord::new(&look_camera(Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO, 40.0, 0.1, 20.0), 64, 64);
    let (g, out) = render(&scene_with(vec![raster(mesh)], None), &cam);
    assert_eq!(g.windings, vec![MeshWinding::Outward]);
    assert_eq!(g.interior_culls(&cam), vec![1]);
    let all = visibility_raster(&without_interior_culls(&g), &cam);
    let centre = 32 * 64 + 32;
    let (culled, drawn) = (out.gbuffer[centre], all.gbuffer[centre]);
    assert!(small_ids.contains(&culled.triangle) && small_ids.contains(&drawn.triangle), "{culled:?} {drawn:?}");
    assert_eq!(culled.flags & GBUF_BACK_FACE, 0, "a far face of the small cube, facing the camera: {culled:?}");
    assert_ne!(drawn.flags & GBUF_BACK_FACE, 0, "a near face of the small cube, facing away: {drawn:?}");
    assert!(culled.depth > drawn.depth);
    let changed: Vec<usize> = (0..out.gbuffer.len()).filter(|&i| out.gbuffer[i] != all.gbuffer[i]).collect();
    assert!(
        changed.iter().all(|&i| small_ids.contains(&all.gbuffer[i].triangle)),
        "only the small cube's pixels change"
    );
    assert!(changed.len() > 20, "{} pixels", changed.len());
}

/// No interior is dropped where a pixel can see it: the camera inside a closed cube sees
/// its back faces, and a cube across the near plane shows its inside through the cut.
#[test]
fn visibility_raster_keeps_interiors_a_pixel_can_see() {
    let inside =
        CameraRecord::new(&look_camera(Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.0, 0.0, -1.0), 60.0, 0.01, 10.0), 32, 32);
    let (g, out) = render(&scene_with(vec![raster(Mesh::cube("c"))], None), &inside);
    assert_eq!(g.interior_culls(&inside), vec![0]);
    assert!(out.gbuffer.iter().all(|t| t.flags & GBUF_HIT != 0 && t.flags & GBUF_BACK_FACE != 0));
    // The near plane, 0.6 in front of the eye at z = 0.8, cuts the cube (-1 to 1) open.
    let cut = CameraRecord::new(&look_camera(Vec3::new(0.0, 0.0, 1.4), Vec3::ZERO, 60.0, 0.6, 10.0), 32, 32);
    let (g, out) = render(&scene_with(vec![raster(Mesh::cube("c"))], None), &cut);
    assert_eq!(g.interior_culls(&cut), vec![0]);
    assert_ne!(out.gbuffer[16 * 32 + 16].flags & GBUF_BACK_FACE, 0, "the inside, through the cut");
}
