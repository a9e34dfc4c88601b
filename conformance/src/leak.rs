//! The leak corpus: closed shells with point lights sealed inside, and the same shells lit
//! from outside, placed from the origin out to 1e6 with features down to about 100 ulps
//! of their coordinates.
//!
//! A point light sealed inside a closed mesh must leave everything outside it dark: every
//! shadow ray from outside crosses the shell, and the watertight ray/triangle test finds a
//! crossing on any closed mesh of shared vertices. A lit (pixel, light) pair outside is a
//! leak; the corpus counts them ([`count_leaks`]) over at least [`MIN_SHADOW_RAYS`] shadow
//! rays per scene. The two causes it was built to catch:
//! - *facing decided in floating point*: a double-sided face seen nearly edge-on had its
//!   normal turned into the shell by a rounded dot product, and its shadow ray started
//!   inside (the [`View::EdgeOn`] cameras sit exactly in the planes of faces);
//! - *offsets that grow with the coordinates*: a fixed 256-ulp origin offset is about 2
//!   units at 1e5, more than the gap between a floor and the shell above it.
//!
//! Each case has one shell (object 0, ray traced, grey; rays meet both faces of every
//! triangle, and the raster drops only the faces that show the inside of a closed shell
//! no pixel can see into) and a floor under it (object 1, rasterized) at a gap of a fifth
//! of the shell's half size, and that gap is never under 100 ulps of the coordinates ([`MIN_FEATURE_ULPS`]):
//! placements far from the origin scale the scene up until it is. The shells
//! ([`ShellKind`]): a cube of 8 shared vertices (12 triangles), an icosphere subdivided to
//! 5,120 triangles, a box of 6 x 8 x 8 two-triangle quads sharing their edges, and the
//! closed horse scan of `../shared/assets` (25,820 triangles, 0 boundary edges) when it is
//! there. With [`LightSide::Outside`] the lights are above and beside the shell: its lit
//! side must be lit and its shadow must fall on the floor (checked against an f64
//! reference by `hyrt`'s tests).

use std::collections::HashMap;

use glam::{DVec3, Mat4, Vec3};
use hyrt_core::formats::{RAY_KIND_SHADOW, SHADOW_LIT, SHADOW_OCCLUDED};
use hyrt_core::frame::Frame;
use hyrt_core::scene::{Camera, Light, Material, MaterialKind, Mesh, RenderMode, Scene};

use crate::corpus::{shared_assets, Case};

/// Image size of every leak case: with [`LIGHTS_PER_CASE`] lights it gives more than
/// [`MIN_SHADOW_RAYS`] shadow rays per scene.
pub const LEAK_WIDTH: u32 = 800;
pub const LEAK_HEIGHT: u32 = 600;
/// Point lights per case (all inside, or all outside the shell). Four keep the GPU
/// backend's ray buffer (one 64-byte record per pixel and light) within the 128 MiB that
/// WebGPU's default storage-buffer limit allows.
pub const LIGHTS_PER_CASE: usize = 4;
/// Each case traces at least this many shadow rays (the bar).
pub const MIN_SHADOW_RAYS: u64 = 1_000_000;
/// The floor's gap under the shell, as a fraction of the shell's half size.
pub const GAP_FRACTION: f32 = 0.2;
/// The smallest feature (the gap) is at least this many ulps of the largest coordinate.
pub const MIN_FEATURE_ULPS: f32 = 100.0;

/// Object ids of every leak scene.
pub const SHELL_OBJECT: u32 = 0;
pub const FLOOR_OBJECT: u32 = 1;

/// The closed shells of the corpus.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShellKind {
    /// 8 shared vertices, 12 triangles, flat (geometric) normals.
    Cube,
    /// An icosahedron subdivided 4 times onto the unit sphere: 5,120 triangles, smooth normals.
    Icosphere,
    /// A cube whose faces are 8 x 8 grids of two-triangle quads, vertices shared along the
    /// cube's edges too: 768 triangles.
    QuadBox,
    /// The closed, manifold horse scan (`../shared/assets/horse.glb`), smooth normals.
    Horse,
}

impl ShellKind {
    pub const ALL: [ShellKind; 4] = [ShellKind::Cube, ShellKind::Icosphere, ShellKind::QuadBox, ShellKind::Horse];

    pub const fn name(self) -> &'static str {
        match self {
            ShellKind::Cube => "cube",
            ShellKind::Icosphere => "icosphere",
            ShellKind::QuadBox => "quad_box",
            ShellKind::Horse => "horse",
        }
    }
}

/// Where the lights are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightSide {
    /// Sealed inside the shell: nothing outside may be lit.
    Inside,
    /// Above and beside it: the expected lit and shadowed regions.
    Outside,
}

/// How the camera looks at the shell (always from outside).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum View {
    /// From above and in front, the floor filling the image.
    Oblique,
    /// The eye exactly in the planes of the shell's top face and right face (`y = 1` and
    /// `x = 1` in shell space, the same f32 arithmetic as the vertices): those faces are
    /// seen edge-on, where a rounded facing test flips.
    EdgeOn,
}

/// One placement: a name and the shell's centre. The scale follows from the centre.
#[derive(Clone, Copy, Debug)]
pub struct Placement {
    pub name: &'static str,
    pub centre: Vec3,
    /// `Some(s)`: this half size instead of the one [`MIN_FEATURE_ULPS`] asks for (the
    /// issue's own scene, a radius-1 sphere at 2.3e5 with a 0.2 gap: 25 ulps).
    pub scale: Option<f32>,
}

impl Placement {
    /// Whether the corpus places `kind` here: the issue's own far placement (radius 1 at
    /// 2.3e5) is for the generated shells only, since the horse's 25,820 triangles shrunk
    /// to a radius of 1 there have edges of one or two ulps of the coordinates (0.016
    /// units), far below the corpus's 100-ulp features, and rounding makes a staircase of
    /// them.
    pub fn fits(&self, kind: ShellKind) -> bool {
        !(kind == ShellKind::Horse && self.scale.is_some())
    }
}

/// The placements: the origin, then 1e2 to 1e6 along an oblique direction, and the
/// issue's far scene (centre (1e5, 3e4, -2e5)) at its own size.
pub fn placements() -> Vec<Placement> {
    let dir = Vec3::new(0.6, 0.3, -0.74).normalize();
    let mut v = vec![Placement { name: "origin", centre: Vec3::ZERO, scale: None }];
    for (name, d) in [("1e2", 1e2f32), ("1e3", 1e3), ("1e4", 1e4), ("1e5", 1e5), ("1e6", 1e6)] {
        v.push(Placement { name, centre: dir * d, scale: None });
    }
    v.push(Placement { name: "issue_2e5_radius_1", centre: Vec3::new(1e5, 3e4, -2e5), scale: Some(1.0) });
    v
}

/// One ulp of `x` (the gap to the next float of larger magnitude).
pub fn ulp(x: f32) -> f32 {
    let a = x.abs();
    f32::from_bits(a.to_bits() + 1) - a
}

/// The half size of the shell at `centre`: 1, or larger so that the gap
/// (`GAP_FRACTION` of it) is [`MIN_FEATURE_ULPS`] ulps of the largest coordinate.
pub fn shell_scale(centre: Vec3) -> f32 {
    let far = centre.abs().max_element() + 100.0;
    (MIN_FEATURE_ULPS * ulp(far) / GAP_FRACTION).max(1.0)
}

/// A leak case: a conformance [`Case`] (scene, camera, image) and what it is made of.
#[derive(Clone, Debug)]
pub struct LeakCase {
    pub case: Case,
    pub shell: ShellKind,
    pub placement: &'static str,
    pub side: LightSide,
    pub view: View,
    /// Shell space to world: translate(centre) * scale(scale).
    pub shell_to_world: Mat4,
    pub scale: f32,
    /// The floor's gap in ulps of the largest coordinate near the shell: at least
    /// [`MIN_FEATURE_ULPS`] except at the issue's own placement (about 13).
    pub feature_ulps: f32,
}

/// Interior points (shell space) of the convex shells, all within 0.9 of the centre: the
/// inradius of the icosphere is 0.9966 and of the boxes 1. Two are near the bottom and the
/// top face, so that shadow rays also cross the shell right beside a light.
const CONVEX_INTERIOR: [Vec3; LIGHTS_PER_CASE] =
    [Vec3::ZERO, Vec3::new(0.45, 0.27, 0.18), Vec3::new(0.18, -0.81, 0.09), Vec3::new(0.09, 0.855, -0.045)];

/// Light positions outside, in shell space: above, beside, in front, behind; all cast the
/// shell's shadow on the floor somewhere in view.
const OUTSIDE: [Vec3; LIGHTS_PER_CASE] =
    [Vec3::new(2.0, 3.5, 1.5), Vec3::new(-3.0, 2.0, 0.5), Vec3::new(0.5, 4.0, -2.5), Vec3::new(-1.0, 2.5, 3.0)];

/// The shell meshes in shell space (within [-1, 1]^3, bottom at y = -1) with the light
/// positions inside them. `None` for the horse without `../shared/assets`.
pub fn shell(kind: ShellKind) -> Option<(Mesh, [Vec3; LIGHTS_PER_CASE])> {
    match kind {
        ShellKind::Cube => Some((indexed_cube(), CONVEX_INTERIOR)),
        ShellKind::Icosphere => Some((icosphere(4), CONVEX_INTERIOR)),
        ShellKind::QuadBox => Some((quad_box(8), CONVEX_INTERIOR)),
        ShellKind::Horse => {
            let path = shared_assets()?.join("horse.glb");
            let scene = Scene::load(&path).ok()?;
            let mesh = normalized(&scene.meshes[scene.objects.first()?.mesh]);
            let inside = interior_points(&mesh);
            Some((mesh, inside))
        }
    }
}

/// The cube [-1, 1]^3 as 8 shared vertices and 12 outward (counter-clockwise) triangles.
pub fn indexed_cube() -> Mesh {
    let positions =
        (0..8).map(|i| Vec3::new([-1.0, 1.0][i & 1], [-1.0, 1.0][(i >> 1) & 1], [-1.0, 1.0][(i >> 2) & 1])).collect();
    // Faces as quads (a, b, c, d) counter-clockwise seen from outside.
    let quads = [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]];
    let indices = quads.iter().flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]]).collect();
    Mesh { name: "cube".into(), positions, normals: None, indices, ..Default::default() }
}

/// An icosahedron subdivided `levels` times onto the unit sphere (20 * 4^levels
/// triangles, shared midpoints), outward, with the positions as smooth normals.
pub fn icosphere(levels: u32) -> Mesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut pos: Vec<DVec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let mut m = |i: u32, j: u32| {
                *mid.entry((i.min(j), i.max(j))).or_insert_with(|| {
                    pos.push(((pos[i as usize] + pos[j as usize]) * 0.5).normalize());
                    pos.len() as u32 - 1
                })
            };
            let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    let positions: Vec<Vec3> = pos.iter().map(|p| p.as_vec3()).collect();
    Mesh { name: "icosphere".into(), normals: Some(positions.clone()), positions, indices: faces, ..Default::default() }
}

/// The cube [-1, 1]^3 with each face an `n` x `n` grid of two-triangle quads; vertices are
/// shared within and across faces (equal positions merged), outward, flat normals.
pub fn quad_box(n: u32) -> Mesh {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut indices = Vec::new();
    let mut vertex = |p: Vec3| -> u32 {
        *index.entry(p.to_array().map(f32::to_bits)).or_insert_with(|| {
            positions.push(p);
            positions.len() as u32 - 1
        })
    };
    let coord = |i: u32| -1.0 + 2.0 * i as f32 / n as f32;
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            // (u, v, normal) right-handed for sign = +1; swapped for -1, so faces point out.
            let (mut ua, mut va) = ((axis + 1) % 3, (axis + 2) % 3);
            if sign < 0.0 {
                std::mem::swap(&mut ua, &mut va);
            }
            let at = |i: u32, j: u32| {
                let mut p = Vec3::ZERO;
                p[axis] = sign;
                p[ua] = coord(i);
                p[va] = coord(j);
                p
            };
            for j in 0..n {
                for i in 0..n {
                    let a = vertex(at(i, j));
                    let b = vertex(at(i + 1, j));
                    let c = vertex(at(i + 1, j + 1));
                    let d = vertex(at(i, j + 1));
                    indices.push([a, b, c]);
                    indices.push([a, c, d]);
                }
            }
        }
    }
    Mesh { name: "quad_box".into(), positions, normals: None, indices, ..Default::default() }
}

/// A mesh moved and scaled (in f32, once) to fit [-1, 1]^3 with its bounding box centred.
fn normalized(mesh: &Mesh) -> Mesh {
    let (lo, hi) = mesh
        .positions
        .iter()
        .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let centre = (lo + hi) * 0.5;
    let half = ((hi - lo) * 0.5).max_element();
    let positions = mesh.positions.iter().map(|p| (*p - centre) / half).collect();
    Mesh {
        name: mesh.name.clone(),
        positions,
        normals: mesh.normals.clone(),
        indices: mesh.indices.clone(),
        ..Default::default()
    }
}

/// Crossings of the ray `o + t d`, t > 0, with the mesh whose positions in f64 are `p`
/// (Moller-Trumbore; the directions used are generic, far from every edge of a scan).
fn crossings(mesh: &Mesh, p: &[DVec3], o: DVec3, d: DVec3) -> usize {
    mesh.indices
        .iter()
        .filter(|&&[a, b, c]| {
            let (v0, v1, v2) = (p[a as usize], p[b as usize], p[c as usize]);
            let (e1, e2) = (v1 - v0, v2 - v0);
            let q = d.cross(e2);
            let det = e1.dot(q);
            if det == 0.0 {
                return false;
            }
            let s = (o - v0) / det;
            let u = s.dot(q);
            let r = s.cross(e1);
            let v = d.dot(r);
            u >= 0.0 && v >= 0.0 && u + v <= 1.0 && e2.dot(r) > 0.0
        })
        .count()
}

/// [`LIGHTS_PER_CASE`] points well inside a closed mesh: candidates on a 12^3 grid of its
/// box, kept when three generic rays from them all cross the mesh an odd number of times,
/// ranked by their distance to the nearest vertex (the scan's triangles are small, so that
/// is close to the distance to the surface), taken greedily at least 0.15 apart.
pub fn interior_points(mesh: &Mesh) -> [Vec3; LIGHTS_PER_CASE] {
    let dirs = [DVec3::new(0.31, 0.87, 0.38), DVec3::new(-0.72, 0.11, 0.69), DVec3::new(0.23, -0.61, -0.76)];
    let positions: Vec<DVec3> = mesh.positions.iter().map(|p| p.as_dvec3()).collect();
    let n = 12;
    let mut inside: Vec<(f32, Vec3)> = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let c = |x: usize| -1.0 + (2.0 * x as f32 + 1.0) / n as f32;
                let p = Vec3::new(c(i), c(j), c(k));
                if dirs.iter().all(|&d| crossings(mesh, &positions, p.as_dvec3(), d) % 2 == 1) {
                    let clearance = mesh.positions.iter().map(|v| v.distance(p)).fold(f32::MAX, f32::min);
                    inside.push((clearance, p));
                }
            }
        }
    }
    inside.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut chosen: Vec<Vec3> = Vec::new();
    for &(_, p) in &inside {
        if chosen.len() < LIGHTS_PER_CASE && chosen.iter().all(|q| q.distance(p) >= 0.15) {
            chosen.push(p);
        }
    }
    assert_eq!(chosen.len(), LIGHTS_PER_CASE, "not enough interior points in {}", mesh.name);
    chosen.try_into().unwrap()
}

fn grey(name: &str) -> Material {
    Material {
        name: name.into(),
        base_color: Vec3::splat(0.7),
        metallic: 0.0,
        roughness: 0.9,
        transmission: 0.0,
        kind: MaterialKind::Diffuse,
        ..Material::grey()
    }
}

/// One leak case.
pub fn leak_case(
    kind: ShellKind,
    mesh: &Mesh,
    inside: &[Vec3; LIGHTS_PER_CASE],
    placement: &Placement,
    side: LightSide,
    view: View,
) -> LeakCase {
    let s = placement.scale.unwrap_or_else(|| shell_scale(placement.centre));
    let shell_to_world = Mat4::from_translation(placement.centre) * Mat4::from_scale(Vec3::splat(s));
    let mut scene = Scene::default();
    scene.add_object(mesh.clone(), grey("shell"), shell_to_world, RenderMode::RayTraced);
    // The floor: the grid (unit square, facing +Y) 80 half sizes wide, GAP_FRACTION below.
    let floor = shell_to_world
        * Mat4::from_translation(Vec3::new(0.0, -1.0 - GAP_FRACTION, 0.0))
        * Mat4::from_scale(Vec3::new(80.0, 1.0, 80.0));
    scene.add_object(Mesh::grid("floor", 8), grey("floor"), floor, RenderMode::Raster);
    let lights = match side {
        LightSide::Inside => inside,
        LightSide::Outside => &OUTSIDE,
    };
    for p in lights {
        let position = shell_to_world.transform_point3(*p);
        scene.lights.push(Light::point(position, Vec3::ONE, 10.0 * s * s));
    }
    let (eye, target) = match view {
        View::Oblique => (Vec3::new(1.3, 2.4, 4.4), Vec3::new(0.0, -0.9, 0.0)),
        View::EdgeOn => (Vec3::new(1.0, 1.0, 5.0), Vec3::new(-0.3, -0.9, 0.0)),
    };
    let camera = Camera {
        eye: shell_to_world.transform_point3(eye),
        target: shell_to_world.transform_point3(target),
        up: Vec3::Y,
        fov_y_deg: 50.0,
        near: 0.05 * s,
        far: 200.0 * s,
    };
    scene.camera = Some(camera);
    let side_name = match side {
        LightSide::Inside => "inside",
        LightSide::Outside => "outside",
    };
    let view_name = match view {
        View::Oblique => "oblique",
        View::EdgeOn => "edge_on",
    };
    let name = format!("leak_{}_{}_light_{side_name}_{view_name}", kind.name(), placement.name);
    let case = Case {
        name,
        stresses: "a closed shell around (or beside) point lights: no light may leak out of it",
        scene,
        camera,
        width: LEAK_WIDTH,
        height: LEAK_HEIGHT,
        weight: 1.0,
        // Shadow rays are what leaks; the shells are diffuse.
        max_depth: 0,
        moving: Vec::new(),
        shadow_samples: hyrt_core::frame::DEFAULT_SHADOW_SAMPLES,
        ao_samples: 0,
        denoise: false,
    };
    let far = placement.centre.abs().max_element() + 2.0 * s;
    let feature_ulps = GAP_FRACTION * s / ulp(far);
    LeakCase { case, shell: kind, placement: placement.name, side, view, shell_to_world, scale: s, feature_ulps }
}

/// Every shell (the horse only with `../shared/assets`) at every placement that
/// [`Placement::fits`] it, seen from both views, with the lights `side`.
pub fn leak_corpus(side: LightSide) -> Vec<LeakCase> {
    let mut cases = Vec::new();
    for kind in ShellKind::ALL {
        let Some((mesh, inside)) = shell(kind) else { continue };
        for placement in placements() {
            if !placement.fits(kind) {
                continue;
            }
            for view in [View::Oblique, View::EdgeOn] {
                cases.push(leak_case(kind, &mesh, &inside, &placement, side, view));
            }
        }
    }
    cases
}

/// Leaks in one frame of a [`LightSide::Inside`] case.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LeakCount {
    /// Shadow rays the frame traced.
    pub shadow_rays: u64,
    /// Of those, the ones that found the shell in the way.
    pub occluded: u64,
    /// (pixel, light) pairs whose shadow ray reached the light: each one a leak.
    pub lit_pairs: u64,
    /// Pixels with at least one lit pair, on the floor and on the shell's outside.
    pub lit_floor_pixels: u64,
    pub lit_shell_pixels: u64,
}

impl LeakCount {
    pub fn lit_pixels(&self) -> u64 {
        self.lit_floor_pixels + self.lit_shell_pixels
    }
}

/// Count what reached a light in a frame rendered with every stage output.
pub fn count_leaks(frame: &Frame) -> LeakCount {
    let pixels = frame.surfaces.len();
    let lights = frame.shadow.len().checked_div(pixels).unwrap_or(0);
    let mut c = LeakCount { shadow_rays: frame.stats.rays_per_kind[RAY_KIND_SHADOW as usize], ..LeakCount::default() };
    for (p, s) in frame.surfaces.iter().enumerate() {
        let mask = &frame.shadow[p * lights..(p + 1) * lights];
        let lit = mask.iter().filter(|&&m| m == SHADOW_LIT).count() as u64;
        c.occluded += mask.iter().filter(|&&m| m == SHADOW_OCCLUDED).count() as u64;
        c.lit_pairs += lit;
        if lit > 0 {
            if s.object == SHELL_OBJECT {
                c.lit_shell_pixels += 1;
            } else {
                c.lit_floor_pixels += 1;
            }
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every edge of a closed, consistently oriented mesh is used once in each direction;
    /// the generated shells are oriented outward (positive volume), the horse scan inward
    /// (as its file has it: double-sided surfaces make either work).
    fn assert_closed_and_oriented(mesh: &Mesh, outward: bool) {
        let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
        for &[a, b, c] in &mesh.indices {
            for e in [(a, b), (b, c), (c, a)] {
                *edges.entry(e).or_default() += 1;
            }
        }
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1, "{}: edge ({a}, {b}) used {n} times in one direction", mesh.name);
            assert_eq!(edges.get(&(b, a)), Some(&1), "{}: edge ({a}, {b}) has no twin", mesh.name);
        }
        // Outward: the signed volume is positive.
        let vol: f64 = mesh
            .indices
            .iter()
            .map(|&[a, b, c]| {
                let [p, q, r] = [a, b, c].map(|i| mesh.positions[i as usize].as_dvec3());
                p.dot(q.cross(r)) / 6.0
            })
            .sum();
        assert!((vol > 0.0) == outward && vol != 0.0, "{}: volume {vol}", mesh.name);
    }

    #[test]
    fn leak_shells_are_closed_and_outward() {
        let cube = indexed_cube();
        assert_eq!((cube.positions.len(), cube.indices.len()), (8, 12));
        assert_closed_and_oriented(&cube, true);
        let ico = icosphere(4);
        assert_eq!(ico.indices.len(), 5120);
        assert_closed_and_oriented(&ico, true);
        let qb = quad_box(8);
        assert_eq!((qb.indices.len(), qb.positions.len()), (768, 386));
        assert_closed_and_oriented(&qb, true);
        if let Some((horse, inside)) = shell(ShellKind::Horse) {
            assert_closed_and_oriented(&horse, false);
            for p in inside {
                let positions: Vec<DVec3> = horse.positions.iter().map(|p| p.as_dvec3()).collect();
                assert_eq!(
                    crossings(&horse, &positions, p.as_dvec3(), DVec3::new(0.5, 0.5, std::f64::consts::FRAC_1_SQRT_2))
                        % 2,
                    1,
                    "{p}"
                );
            }
        }
    }

    #[test]
    fn leak_lights_are_inside_the_convex_shells() {
        // The icosphere's inradius: the distance of its face planes from the centre.
        let ico = icosphere(4);
        let inradius = ico
            .indices
            .iter()
            .map(|&[a, b, c]| {
                let [p, q, r] = [a, b, c].map(|i| ico.positions[i as usize].as_dvec3());
                (q - p).cross(r - p).normalize().dot(p)
            })
            .fold(f64::MAX, f64::min);
        assert!(inradius > 0.99, "{inradius}");
        for p in CONVEX_INTERIOR {
            assert!((p.length() as f64) < inradius - 0.05 && p.abs().max_element() < 0.95);
        }
    }

    #[test]
    fn leak_scale_keeps_the_gap_at_least_100_ulps() {
        for p in placements().iter().filter(|p| p.scale.is_none()) {
            let s = shell_scale(p.centre);
            let gap = GAP_FRACTION * s;
            let far = p.centre.abs().max_element() + 2.0 * s;
            assert!(gap >= 0.99 * MIN_FEATURE_ULPS * ulp(far), "{}: gap {gap}, ulp {}", p.name, ulp(far));
        }
        assert_eq!(shell_scale(Vec3::ZERO), 1.0);
        assert!(shell_scale(Vec3::splat(1e6)) > 30.0);
    }
}
