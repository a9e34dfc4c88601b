//! Textures, vertex colours and alpha tests on the CPU backend, on a scene whose right
//! answer is known: a square fence in the plane z = 0 whose 4 x 4 texture is a checker of
//! opaque and transparent texels (nearest filtering, so every texel is a hard square),
//! the opaque ones red and blue by column, in front of a grey wall at z = -1, lit by a
//! directional light travelling along -z. Then:
//!
//! * primary visibility (`visibility_raster`): a pixel shows the fence exactly where its
//!   camera ray crosses the fence at an opaque texel, else the wall;
//! * shadows (`shadow_rays`, any hit): a wall point is in shadow exactly where the fence
//!   above it (straight along +z) is opaque;
//! * closest hit (`bounce_trace`): a ray along -z stops at the fence's opaque texels and
//!   passes through its holes to the wall;
//! * colour (`raster_shading` and `rt_shading`): the fence's pixels take their texel's
//!   colour, whether the fence is rasterized or ray traced;
//! * vertex colours multiply the base colour.
//!
//! Colours are compared by which channel dominates: every shader adds a specular term of
//! the uniform environment that no base colour scales (`ENVIRONMENT_SPECULAR` times the
//! dielectric F0, 0.014 in each channel).
//!
//! "Exactly" up to pixels whose crossing lies within [`BORDER`] of a texel's border: the
//! raster's vertex snapping (1/256 pixel) and the barycentrics' rounding move a border by
//! far less than that, and no pixel centre of these views falls that close.

use std::sync::Arc;

use glam::{Mat4, Vec2, Vec3};
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::{CameraRecord, RayRecord, INVALID_ID, RAY_KIND_REFLECTION, SHADOW_OCCLUDED};
use hyrt_core::frame::{Backend, Frame, FrameOptions, PreparedScene};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::camera::primary_ray;
use hyrt_core::scene::{
    AlphaMode, Camera, Filter, Light, Material, Mesh, RenderMode, Sampler, Scene, TextureBinding, TextureImage,
    UvTransform, VertexAttributes, Wrap,
};
use hyrt_cpu::backend::CpuBackend;
use hyrt_cpu::bounce_trace::bounce_trace_into;
use hyrt_cpu::traversal::Traversal;

/// World distance from a texel border within which a pixel may go either way (see the
/// module docs).
const BORDER: f32 = 1e-3;

const SIZE: u32 = 96;

/// The fence's texel at texture coordinates `uv`: `(opaque, red)`.
fn fence_texel(uv: Vec2) -> (bool, bool) {
    let (i, j) = ((uv.x * 4.0).floor() as i32, (uv.y * 4.0).floor() as i32);
    ((i + j) % 2 == 0, i % 2 == 0)
}

/// Where the point `(x, y)` of the plane z = 0 is on the fence: `None` off it, else its
/// texel and whether it lies within [`BORDER`] of a texel border.
fn on_fence(x: f32, y: f32) -> Option<((bool, bool), bool)> {
    if !(x.abs() <= 1.0 && y.abs() <= 1.0) {
        return None;
    }
    let uv = Vec2::new((x + 1.0) / 2.0, (1.0 - y) / 2.0);
    let near = |w: f32| {
        let f = (w + 1.0) * 2.0; // texel borders of this axis at integers
        (f - f.round()).abs() * 0.5 < BORDER
    };
    Some((fence_texel(uv), near(x) || near(y)))
}

fn fence_scene(fence_mode: RenderMode) -> Scene {
    fence_scene_of(Mesh::uv_quad("fence"), fence_mode)
}

/// The fence scene with the fence made of `fence` (a mesh over the square from (-1, -1) to
/// (1, 1) in the plane z = 0 with `uv_quad`'s texture coordinates).
fn fence_scene_of(fence_mesh: Mesh, fence_mode: RenderMode) -> Scene {
    let mut scene = Scene::default();
    let wall = Mesh { name: "wall".into(), ..Mesh::uv_quad("wall") };
    let grey = Material { base_color: Vec3::splat(0.5), ..Material::grey() };
    let wall_at = Mat4::from_translation(Vec3::new(0.0, 0.0, -1.0)) * Mat4::from_scale(Vec3::new(4.0, 4.0, 1.0));
    scene.add_object(wall, grey, wall_at, RenderMode::Raster);
    let texels: Vec<[u8; 4]> = (0..16)
        .map(|k| {
            let (i, j) = (k % 4, k / 4);
            let (opaque, red) = ((i + j) % 2 == 0, i % 2 == 0);
            let a = if opaque { 255 } else { 0 };
            if red {
                [255, 0, 0, a]
            } else {
                [0, 0, 255, a]
            }
        })
        .collect();
    scene.textures.push(Arc::new(TextureImage::new("checker".into(), 4, 4, texels).unwrap()));
    let nearest = Sampler {
        wrap_s: Wrap::ClampToEdge,
        wrap_t: Wrap::ClampToEdge,
        mag: Filter::Nearest,
        min: Filter::Nearest,
        mip: None,
    };
    let fence = Material {
        name: "fence".into(),
        base_color: Vec3::ONE,
        base_color_texture: Some(TextureBinding {
            image: 0,
            sampler: nearest,
            tex_coord: 0,
            transform: UvTransform::default(),
        }),
        alpha_mode: AlphaMode::Mask { cutoff: 0.5 },
        ..Material::grey()
    };
    scene.add_object(fence_mesh, fence, Mat4::IDENTITY, fence_mode);
    scene.lights.push(Light::Directional { direction: Vec3::NEG_Z, color: Vec3::ONE, intensity: 1.0 });
    scene
}

fn camera() -> Camera {
    Camera::look_at(Vec3::new(0.3, -0.2, 5.0), Vec3::new(0.0, 0.0, -0.5), Vec3::Y)
}

fn render(scene: &Scene) -> (Frame, PreparedScene, CameraRecord) {
    let mut cpu = CpuBackend::new(Some(2));
    let prepared = cpu.prepare(WorldGeometry::build(scene), BvhPreset::default());
    let cam = CameraRecord::new(&camera(), SIZE, SIZE);
    let frame = cpu.render(&prepared, &cam, &FrameOptions::with_stage_outputs()).expect("frame");
    (frame, prepared, cam)
}

/// Where pixel `i`'s camera ray crosses the plane z = 0.
fn crossing(cam: &CameraRecord, i: u32) -> (f32, f32) {
    let r = primary_ray(cam, i % SIZE, i / SIZE);
    let (o, d) = (Vec3::from(r.origin), Vec3::from(r.direction));
    let p = o + d * (-o.z / d.z);
    (p.x, p.y)
}

#[test]
fn masked_texels_are_holes_for_the_raster_and_for_shadow_rays() {
    let (frame, _, cam) = render(&fence_scene(RenderMode::Raster));
    let (mut fence, mut holes, mut lit, mut shadowed) = (0, 0, 0, 0);
    for (i, t) in frame.gbuffer.iter().enumerate() {
        let (x, y) = crossing(&cam, i as u32);
        let expected = match on_fence(x, y) {
            Some((_, true)) => continue,
            Some(((true, _), false)) => 1,
            _ => 0,
        };
        assert!(t.is_hit(), "pixel {i} sees nothing");
        assert_eq!(t.object, expected, "pixel {i}: crossing ({x}, {y})");
        if expected == 1 {
            fence += 1;
            continue;
        }
        holes += on_fence(x, y).is_some() as u32;
        // A wall point: in shadow exactly under the fence's opaque texels.
        let p = frame.surfaces[i].position;
        let occluded = frame.shadow[i] == SHADOW_OCCLUDED;
        match on_fence(p[0], p[1]) {
            Some((_, true)) => {}
            Some(((true, _), false)) => {
                assert!(occluded, "wall pixel {i} at {p:?} is lit under an opaque texel");
                shadowed += 1;
            }
            _ => {
                assert!(!occluded, "wall pixel {i} at {p:?} is shadowed under a hole");
                lit += 1;
            }
        }
    }
    // The view sees many of each.
    assert!(fence > 500 && holes > 500 && lit > 500 && shadowed > 100, "{fence} {holes} {lit} {shadowed}");
}

/// A reflection ray of depth 1 (a list's ray `k`).
fn reflection_ray(origin: Vec3, direction: Vec3, t_max: f32, k: u32) -> RayRecord {
    RayRecord {
        origin: origin.into(),
        t_min: 0.0,
        direction: direction.into(),
        t_max,
        pixel: k,
        kind: RAY_KIND_REFLECTION,
        depth: 1,
        light: INVALID_ID,
        throughput: [1.0; 3],
        cone: 0.0,
    }
}

#[test]
fn closest_hits_pass_through_holes() {
    let (_, prepared, _) = render(&fence_scene(RenderMode::RayTraced));
    let mut rays = Vec::new();
    for k in 0..400 {
        let (x, y) = (-1.2 + 2.4 * ((k % 20) as f32 + 0.37) / 20.0, -1.2 + 2.4 * ((k / 20) as f32 + 0.41) / 20.0);
        rays.push(reflection_ray(Vec3::new(x, y, 2.0), Vec3::NEG_Z, f32::INFINITY, k));
    }
    for traversal in [Traversal::Scalar, Traversal::simd(), Traversal::for_bounces()] {
        let (mut closest, mut hits, mut surfaces) = (Vec::new(), Vec::new(), Vec::new());
        bounce_trace_into(
            &prepared.bvh,
            prepared.levels.as_ref(),
            &prepared.geometry,
            &hyrt_core::kernels::texture::Materials::plain(&prepared.geometry.objects),
            &rays,
            traversal,
            &mut closest,
            &mut hits,
            &mut surfaces,
        );
        for (r, s) in rays.iter().zip(&surfaces) {
            let expected = match on_fence(r.origin[0], r.origin[1]) {
                Some(((true, _), false)) => 1,
                Some((_, true)) => continue,
                _ => 0,
            };
            assert_eq!(s.object, expected, "{traversal:?}: ray at {:?}", r.origin);
        }
    }
}

#[test]
fn fence_pixels_take_their_texel_colour_rasterized_or_ray_traced() {
    for mode in [RenderMode::Raster, RenderMode::RayTraced] {
        let (frame, _, cam) = render(&fence_scene(mode));
        let image = if mode == RenderMode::Raster { &frame.raster } else { &frame.rt };
        let mut seen = [0; 2];
        for (i, t) in frame.gbuffer.iter().enumerate() {
            if t.object != 1 {
                continue;
            }
            let (x, y) = crossing(&cam, i as u32);
            let Some(((true, red), false)) = on_fence(x, y) else { continue };
            let c = image[i];
            let (want, other) = if red { (c[0], c[2]) } else { (c[2], c[0]) };
            assert!(want > 0.2 && other < 0.05 && c[1] < 0.05, "{mode:?}: pixel {i} (red: {red}): {c:?}");
            seen[red as usize] += 1;
        }
        assert!(seen[0] > 200 && seen[1] > 200, "{mode:?}: {seen:?}");
    }
}

#[test]
fn vertex_colours_multiply_the_base_colour() {
    let mut scene = Scene::default();
    let mut mesh = Mesh::uv_quad("coloured");
    mesh.attributes.tex_coords = [None, None];
    // Red on the left edge, green on the right.
    mesh.attributes.colors =
        Some(vec![[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0], [1.0, 0.0, 0.0, 1.0]]);
    scene.add_object(mesh, Material { base_color: Vec3::ONE, ..Material::grey() }, Mat4::IDENTITY, RenderMode::Raster);
    scene.lights.push(Light::Directional { direction: Vec3::NEG_Z, color: Vec3::ONE, intensity: 1.0 });
    let (frame, _, cam) = render(&scene);
    let (mut left, mut right) = (0, 0);
    for (i, t) in frame.gbuffer.iter().enumerate() {
        if !t.is_hit() {
            continue;
        }
        let (x, _) = crossing(&cam, i as u32);
        let c = frame.raster[i];
        if x < -0.5 {
            assert!(c[0] > 2.0 * c[1] && c[2] < 0.05, "pixel {i} at x = {x}: {c:?}");
            left += 1;
        } else if x > 0.5 {
            assert!(c[1] > 2.0 * c[0] && c[2] < 0.05, "pixel {i} at x = {x}: {c:?}");
            right += 1;
        }
    }
    assert!(left > 100 && right > 100, "{left} {right}");
}

#[test]
fn packets_test_alpha_as_the_scalar_reference_does() {
    use hyrt_cpu::traversal::{closest_hit_alpha_batch_into, occluded_alpha_batch_into};
    let (_, prepared, _) = render(&fence_scene(RenderMode::Raster));
    let (g, bvh) = (&prepared.geometry, &prepared.bvh);
    let view = g.surface.view();
    // Rays from above the fence to points of the wall, neighbours in the list close
    // together (packets of coherent rays that straddle holes), from a fixed LCG.
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((state >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    };
    let rays: Vec<RayRecord> = (0..4096)
        .map(|k| {
            let base = Vec3::new((k / 64) as f32 / 32.0 - 1.0, (k % 64) as f32 / 32.0 - 1.0, 0.0);
            let origin = Vec3::new(next() * 0.2, next() * 0.2, 3.0) + base * 0.5;
            let target = Vec3::new(base.x * 1.5 + next() * 0.05, base.y * 1.5 + next() * 0.05, -1.0);
            reflection_ray(origin, target - origin, if k % 2 == 0 { 1.0 } else { f32::INFINITY }, k)
        })
        .collect();
    let (mut reference_any, mut reference_closest) = (Vec::new(), Vec::new());
    occluded_alpha_batch_into(bvh, g.stored_table(), &view, &rays, Traversal::Scalar, &mut reference_any);
    closest_hit_alpha_batch_into(bvh, g.stored_table(), &view, &rays, Traversal::Scalar, &mut reference_closest);
    let holes =
        reference_closest.iter().filter(|h| h.is_some_and(|h| g.triangle(h.triangle as usize).object == 0)).count();
    assert!(holes > 500 && holes < 3500, "{holes} rays reach the wall");
    for traversal in Traversal::available_simd() {
        let (mut any, mut closest) = (Vec::new(), Vec::new());
        occluded_alpha_batch_into(bvh, g.stored_table(), &view, &rays, traversal, &mut any);
        closest_hit_alpha_batch_into(bvh, g.stored_table(), &view, &rays, traversal, &mut closest);
        assert_eq!(any, reference_any, "{traversal:?}: any hit");
        for (k, (a, b)) in closest.iter().zip(&reference_closest).enumerate() {
            let bits = |h: &Option<hyrt_core::bvh::ClosestHit>| {
                h.map(|h| (h.triangle, h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.back_face))
            };
            assert_eq!(bits(a), bits(b), "{traversal:?}: ray {k}");
        }
    }
}

/// The fence as `Mesh::grid(n)` stood up in the plane z = 0 over the square from (-1, -1)
/// to (1, 1), with `uv_quad`'s texture coordinates: the same texels on `2 n^2` triangles.
fn dense_fence(n: u32) -> Mesh {
    let grid = Mesh::grid("fence", n);
    // The grid's (x, 0, z) in [-0.5, 0.5]^2 becomes (2x, -2z, 0): u = x + 1/2, v = z + 1/2.
    let uv = grid.positions.iter().map(|p| Vec2::new(p.x + 0.5, p.z + 0.5)).collect();
    let positions = grid.positions.iter().map(|p| Vec3::new(2.0 * p.x, -2.0 * p.z, 0.0)).collect();
    // The same turn keeps the triangles' winding facing the normal (+z).
    Mesh {
        positions,
        normals: Some(vec![Vec3::Z; grid.positions.len()]),
        attributes: VertexAttributes { tex_coords: [Some(uv), None], ..VertexAttributes::default() },
        ..grid
    }
}

/// Shadow rays through a densely tessellated alpha-masked fence, neighbours in the list far
/// apart, so that a packet's lanes part at once and enter the fence's leaves one or two at
/// a time: the any-hit packets test such leaves lane by lane (`occluded_lanes_alone`),
/// where a hit on an alpha-tested triangle must still pass its texel. Every SIMD traversal
/// gives the scalar reference's answers, and the rays find both holes and opaque texels.
#[test]
fn packets_whose_lanes_part_test_alpha_as_the_scalar_reference_does() {
    use hyrt_cpu::traversal::occluded_alpha_batch_into;
    let scene = fence_scene_of(dense_fence(48), RenderMode::RayTraced);
    let cpu = CpuBackend::new(Some(2));
    let prepared = cpu.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    let (g, bvh) = (&prepared.geometry, &prepared.bvh);
    assert_eq!(g.triangle_count(), 2 + 2 * 48 * 48);
    let view = g.surface.view();
    // From points of the wall towards a light above the fence: ray k goes from the point
    // of index (k * 7919) mod n of a 64 x 64 grid of wall points.
    let n = 64 * 64;
    let rays: Vec<RayRecord> = (0..n)
        .map(|k| {
            let i = k * 7919 % n;
            let p = Vec3::new((i % 64) as f32 / 32.0 - 0.98, (i / 64) as f32 / 32.0 - 0.98, -1.0);
            let light = Vec3::new(0.1, -0.2, 4.0);
            reflection_ray(p, light - p, 1.0, k as u32)
        })
        .collect();
    let mut reference = Vec::new();
    occluded_alpha_batch_into(bvh, g.stored_table(), &view, &rays, Traversal::Scalar, &mut reference);
    let occluded = reference.iter().filter(|&&o| o == hyrt_cpu::traversal::SHADOW_OCCLUDED).count();
    assert!(occluded > n / 4 && occluded < 3 * n / 4, "{occluded} of {n} occluded");
    for traversal in Traversal::available_simd() {
        let mut any = Vec::new();
        occluded_alpha_batch_into(bvh, g.stored_table(), &view, &rays, traversal, &mut any);
        let differ = any.iter().zip(&reference).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{traversal:?}: {differ} of {n} rays differ from the scalar reference");
    }
}
