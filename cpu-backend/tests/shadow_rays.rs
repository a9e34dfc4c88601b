//! Stage `shadow_rays`: an analytic occluder scene with a closed-form answer, and
//! determinism across thread counts.

use glam::{Mat4, Vec3};
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::{RayRecord, RAY_KIND_SHADOW};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::ray::offset_ray_origin;
use hyrt_core::scene::{Light, Material, Mesh, Object, ObjectSource, RenderMode, Scene};
use hyrt_cpu::bvh_build::bvh_build;
use hyrt_cpu::shadow_rays::{shadow_rays, SHADOW_OCCLUDED, SHADOW_VISIBLE};

/// Height of the light above the floor.
const LIGHT_HEIGHT: f32 = 4.0;
/// Height of the square occluder.
const OCCLUDER_HEIGHT: f32 = 1.0;
/// Half side of the square occluder (a `Mesh::grid` scaled by 2).
const OCCLUDER_HALF: f32 = 1.0;
/// Half side of the floor (a `Mesh::grid` scaled by 12).
const FLOOR_HALF: f32 = 6.0;
/// Targets whose shadow-boundary coordinate is this close to the occluder edge are
/// skipped: the closed form is exact, the float ray is not (rounding of the origin
/// offset and the direction is far below this).
const BOUNDARY_MARGIN: f32 = 1e-3;

fn object(id: u32, mesh: usize, transform: Mat4) -> Object {
    Object {
        id,
        name: format!("object{id}"),
        mesh,
        transform,
        material: 0,
        render_mode: RenderMode::Raster,
        source: ObjectSource::default(),
    }
}

/// A floor (y = 0, 8 x 8 quads), a square occluder (y = 1, |x|, |z| <= 1, 3 x 3 quads)
/// and a point light at (0, 4, 0).
fn occluder_scene() -> (WorldGeometry, Vec3) {
    let light = Vec3::new(0.0, LIGHT_HEIGHT, 0.0);
    let scene = Scene {
        meshes: vec![Mesh::grid("floor", 8), Mesh::grid("occluder", 3)],
        materials: vec![Material::grey()],
        objects: vec![
            object(0, 0, Mat4::from_scale(Vec3::splat(2.0 * FLOOR_HALF))),
            object(
                1,
                1,
                Mat4::from_translation(Vec3::new(0.0, OCCLUDER_HEIGHT, 0.0))
                    * Mat4::from_scale(Vec3::splat(2.0 * OCCLUDER_HALF)),
            ),
        ],
        lights: vec![Light::point(light, Vec3::ONE, 1.0)],
        ..Scene::default()
    };
    (WorldGeometry::build(&scene), light)
}

fn shadow_ray(target: Vec3, normal: Vec3, light: Vec3, pixel: u32) -> RayRecord {
    // The floor points are exact; offset by an error bound of the size reconstruction
    // would give them (a few ulps of the coordinates).
    let origin = offset_ray_origin(target, 4.0 * f32::EPSILON * target.abs().max_element(), normal);
    RayRecord {
        origin: origin.into(),
        t_min: 0.0,
        direction: (light - origin).into(),
        t_max: 1.0,
        pixel,
        kind: RAY_KIND_SHADOW,
        depth: 0,
        light: 0,
        throughput: [1.0; 3],
        cone: 0.0,
    }
}

/// The segment from floor point (x, 0, z) to the light crosses the occluder plane at
/// (x, z) * (1 - h / H); it is blocked iff that point is inside the square.
fn closed_form(x: f32, z: f32) -> Option<bool> {
    let s = 1.0 - OCCLUDER_HEIGHT / LIGHT_HEIGHT;
    let (cx, cz) = ((x * s).abs(), (z * s).abs());
    if (cx - OCCLUDER_HALF).abs() < BOUNDARY_MARGIN || (cz - OCCLUDER_HALF).abs() < BOUNDARY_MARGIN {
        return None;
    }
    Some(cx < OCCLUDER_HALF && cz < OCCLUDER_HALF)
}

#[test]
fn shadow_rays_match_closed_form_occluder() {
    let (g, light) = occluder_scene();
    // Targets on a 0.05 grid over the floor, including points on the floor's shared
    // edges and vertices (grid spacing 1.5).
    let n = (2.0 * FLOOR_HALF / 0.05) as i32;
    let mut rays = Vec::new();
    let mut expected = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (-FLOOR_HALF + i as f32 * 0.05, -FLOOR_HALF + j as f32 * 0.05);
            if let Some(blocked) = closed_form(x, z) {
                rays.push(shadow_ray(Vec3::new(x, 0.0, z), Vec3::Y, light, rays.len() as u32));
                expected.push(if blocked { SHADOW_OCCLUDED } else { SHADOW_VISIBLE });
            }
        }
    }
    let occluded = expected.iter().filter(|&&e| e == SHADOW_OCCLUDED).count();
    assert!(occluded > 1000 && occluded < rays.len() / 2, "{occluded} of {}", rays.len());
    for preset in BvhPreset::ALL {
        let bvh = bvh_build(&g, preset);
        let got = shadow_rays(&bvh, &g, &rays);
        assert_eq!(got.len(), rays.len());
        for (k, (g, e)) in got.iter().zip(&expected).enumerate() {
            assert_eq!(g, e, "{preset:?}: ray {k} to {:?}", rays[k].origin);
        }
    }
}

/// Points on the occluder's top face see the light; points on its bottom face (offset
/// downwards, rays going up through the occluder) do not.
#[test]
fn shadow_rays_from_the_occluder_itself() {
    let (g, light) = occluder_scene();
    let bvh = bvh_build(&g, BvhPreset::default());
    let mut rays = Vec::new();
    for j in 0..=8 {
        for i in 0..=8 {
            let p = Vec3::new(-1.0 + i as f32 * 0.25, OCCLUDER_HEIGHT, -1.0 + j as f32 * 0.25);
            rays.push(shadow_ray(p, Vec3::Y, light, 0));
            rays.push(shadow_ray(p, Vec3::NEG_Y, light, 1));
        }
    }
    let got = shadow_rays(&bvh, &g, &rays);
    for (r, o) in rays.iter().zip(got) {
        let want = if r.pixel == 0 { SHADOW_VISIBLE } else { SHADOW_OCCLUDED };
        assert_eq!(o, want, "{r:?}");
    }
}

#[test]
fn shadow_rays_are_deterministic_across_thread_counts() {
    let (g, light) = occluder_scene();
    let bvh = bvh_build(&g, BvhPreset::default());
    // Rays from a pseudo-random set of floor points (a fixed LCG, no RNG dependency).
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((state >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    };
    let rays: Vec<RayRecord> = (0..10_000)
        .map(|k| shadow_ray(Vec3::new(next() * FLOOR_HALF, 0.0, next() * FLOOR_HALF), Vec3::Y, light, k))
        .collect();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| shadow_rays(&bvh, &g, &rays))
    };
    let one = run(1);
    let two = run(2);
    assert_eq!(one, two);
    let occluded = one.iter().filter(|&&o| o == SHADOW_OCCLUDED).count();
    assert!(occluded > 100 && occluded < 9_000, "{occluded}");
}

#[test]
fn shadow_rays_on_empty_inputs() {
    let (g, light) = occluder_scene();
    let bvh = bvh_build(&g, BvhPreset::default());
    assert!(shadow_rays(&bvh, &g, &[]).is_empty());
    let empty = WorldGeometry::default();
    let empty_bvh = bvh_build(&empty, BvhPreset::default());
    let rays = [shadow_ray(Vec3::ZERO, Vec3::Y, light, 0)];
    assert_eq!(shadow_rays(&empty_bvh, &empty, &rays), vec![SHADOW_VISIBLE]);
}
