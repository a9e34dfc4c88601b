//! The two-level BVH (`hyrt_core::bvh::two_level`): a scene without instances answers as
//! the single-level tree bit for bit; instanced meshes (scaled, rotated, mirrored, shared)
//! stay watertight, rays leaving their surfaces with the instance's offset bound do not
//! hit them again, and hits report the right object's triangles and world facing.

use glam::{Mat4, Quat, Vec3};
use hyrt_core::bvh::two_level::{TwoLevelBvh, INSTANCE_IDENTITY};
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::formats::{RayRecord, INVALID_ID, RAY_KIND_SHADOW};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::barycentric::{geometric_normal, position_error_bound, reconstruct_position};
use hyrt_core::kernels::instance::{instance_position_error, world_to_object};
use hyrt_core::kernels::ray::offset_ray_origin;
use hyrt_core::scene::{Material, Mesh, Object, ObjectSource, RenderMode, Scene};
use proptest::prelude::*;

fn ray(origin: Vec3, direction: Vec3) -> RayRecord {
    RayRecord {
        origin: origin.into(),
        t_min: 0.0,
        direction: direction.into(),
        t_max: f32::INFINITY,
        pixel: 0,
        kind: RAY_KIND_SHADOW,
        depth: 0,
        light: INVALID_ID,
        throughput: [1.0; 3],
        cone: 0.0,
    }
}

/// Deterministic pseudo-random numbers in [0, 1) (xorshift), so the ray sets are fixed.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
    fn unit(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(self.next(), self.next(), self.next()) * 2.0 - 1.0;
            let l = v.length();
            if l > 0.1 && l <= 1.0 {
                return v / l;
            }
        }
    }
}

/// Rays from points around and inside the scene's bounds toward random directions.
fn random_rays(geometry: &WorldGeometry, n: usize, seed: u64) -> Vec<RayRecord> {
    let (lo, hi) = geometry.bounds;
    let mut rng = Rng(seed);
    (0..n)
        .map(|_| {
            let o = lo + (hi - lo) * Vec3::new(rng.next(), rng.next(), rng.next()) * 1.4 - (hi - lo) * 0.2;
            ray(o, rng.unit())
        })
        .collect()
}

/// One object of `mesh` with transform `m`.
fn one_object(mesh: Mesh, m: Mat4) -> Scene {
    let mut scene = Scene::default();
    scene.add_object(mesh, Material::grey(), m, RenderMode::RayTraced);
    scene
}

#[test]
fn a_scene_without_instances_is_the_single_level_tree() {
    let scene = Scene::default_scene();
    let geometry = WorldGeometry::build(&scene);
    let flat = Bvh::build(&geometry, BvhPreset::default());
    let levels = TwoLevelBvh::build(&scene, &geometry, BvhPreset::default(), &[]);
    levels.validate(&geometry).unwrap();
    assert_eq!(levels.instances.len(), 1);
    assert_eq!(levels.instances[0].flags, INSTANCE_IDENTITY);
    assert_eq!(levels.bottoms.len(), 1);
    let b = &levels.bottoms[0];
    assert_eq!((&b.nodes, &b.prim_indices, &b.leaf_triangles), (&flat.nodes, &flat.prim_indices, &flat.leaf_triangles));
    for r in random_rays(&geometry, 4000, 7) {
        assert_eq!(levels.closest_hit(&r), flat.closest_hit(geometry.stored_table(), &r), "{r:?}");
        assert_eq!(levels.occluded(&r), flat.occluded(geometry.stored_table(), &r), "{r:?}");
    }
}

/// Every object of the default scene an instance in its own space: the hits are the
/// single-level tree's up to the rounding of the maps. Where they differ, the two hits
/// are within that rounding of each other in `t` (a ray through a shared edge, or two
/// surfaces at nearly the same distance).
#[test]
fn every_object_an_instance_finds_the_same_hits_as_the_world_space_tree() {
    let scene = Scene::default_scene();
    let geometry = WorldGeometry::build(&scene);
    let flat = Bvh::build(&geometry, BvhPreset::default());
    let moving = vec![true; scene.objects.len()];
    let levels = TwoLevelBvh::build(&scene, &geometry, BvhPreset::default(), &moving);
    levels.validate(&geometry).unwrap();
    assert!(levels.instances.iter().all(|i| i.flags & INSTANCE_IDENTITY == 0));
    let (mut same, mut total) = (0, 0);
    for r in random_rays(&geometry, 4000, 11) {
        let (a, b) = (levels.closest_hit(&r), flat.closest_hit(geometry.stored_table(), &r));
        assert_eq!(a.is_some(), b.is_some(), "{r:?}: {a:?} vs {b:?}");
        assert_eq!(levels.occluded(&r), b.is_some(), "{r:?}");
        if let (Some(a), Some(b)) = (a, b) {
            total += 1;
            // The maps' rounding: a few ulps of the scene's coordinates (about 10), relative.
            let tolerance = 1e-4 * b.t.max(1.0);
            assert!((a.t - b.t).abs() <= tolerance, "{r:?}: {a:?} vs {b:?}");
            if a.triangle == b.triangle {
                same += 1;
                assert_eq!(a.back_face, b.back_face, "{r:?}");
            }
        }
    }
    assert!(total > 1000 && same * 100 >= total * 99, "{same} of {total} hits on the same triangle");
}

#[test]
fn objects_sharing_a_mesh_share_one_bottom_level() {
    let mut scene = one_object(Mesh::cube("cube"), Mat4::from_translation(Vec3::new(-3.0, 0.0, 0.0)));
    scene.objects.push(Object {
        id: 1,
        name: "cube 2".into(),
        mesh: 0,
        transform: Mat4::from_scale_rotation_translation(Vec3::splat(0.5), Quat::from_rotation_y(0.4), Vec3::X * 3.0),
        material: 0,
        render_mode: RenderMode::Raster,
        source: ObjectSource::default(),
    });
    let geometry = WorldGeometry::build(&scene);
    let levels = TwoLevelBvh::build(&scene, &geometry, BvhPreset::default(), &[]);
    levels.validate(&geometry).unwrap();
    assert_eq!(levels.bottoms.len(), 1, "one mesh, one bottom level, no world-space level");
    assert_eq!(levels.instances.len(), 2);
    for (x, object) in [(-3.0, 0), (3.0, 1)] {
        let r = ray(Vec3::new(x, 0.1, 10.0), Vec3::NEG_Z);
        let hit = levels.closest_hit(&r).expect("hits the cube");
        assert_eq!(geometry.triangle(hit.triangle as usize).object, object);
        // The second cube, half size, is turned by 0.4 about y: its front face is
        // 0.5 / cos(0.4) ahead of its centre along the ray.
        let expected_t = if object == 0 { 9.0 } else { 10.0 - 0.5 / 0.4f32.cos() };
        assert!((hit.t - expected_t).abs() < 1e-5, "{hit:?}");
        assert!(!hit.back_face);
    }
    assert!(levels.closest_hit(&ray(Vec3::new(0.0, 0.0, 10.0), Vec3::NEG_Z)).is_none());
}

/// A random object-to-world map: rotation, per-axis scale in [1/20, 20] (a mirror when
/// `mirror`), translation within 100.
fn transform(axis: [f32; 3], angle: f32, scale: [f32; 3], mirror: bool, t: [f32; 3]) -> Mat4 {
    let axis = Vec3::from(axis).try_normalize().unwrap_or(Vec3::Y);
    let scale = Vec3::from(scale).map(|s| 20f32.powf(s)) * if mirror { Vec3::new(-1.0, 1.0, 1.0) } else { Vec3::ONE };
    Mat4::from_scale_rotation_translation(scale, Quat::from_axis_angle(axis, angle), Vec3::from(t))
}

fn transforms() -> impl Strategy<Value = Mat4> {
    (
        prop::array::uniform3(-1.0f32..1.0),
        0.0f32..6.3,
        prop::array::uniform3(-1.0f32..1.0),
        any::<bool>(),
        prop::array::uniform3(-100.0f32..100.0),
    )
        .prop_map(|(a, angle, s, mirror, t)| transform(a, angle, s, mirror, t))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// A closed sphere, scaled, rotated and mirrored as an instance: every ray from its
    /// centre hits it (no crack between triangles in object space), with the world
    /// facing of the inside: the back faces of its outward triangles, the front faces of
    /// a mirror image (whose world triangles wind the other way).
    #[test]
    fn instanced_closed_meshes_stay_watertight(m in transforms(), seed in any::<u64>()) {
        let scene = one_object(Mesh::uv_sphere("sphere", 24, 12), m);
        let geometry = WorldGeometry::build(&scene);
        let levels = TwoLevelBvh::build(&scene, &geometry, BvhPreset::default(), &[true]);
        prop_assert!(levels.instances[0].flags & INSTANCE_IDENTITY == 0);
        let centre = m.transform_point3(Vec3::ZERO);
        let inside_is_back = m.determinant() > 0.0;
        let mut rng = Rng(seed | 1);
        for _ in 0..200 {
            let r = ray(centre, rng.unit());
            let hit = levels.closest_hit(&r);
            prop_assert!(hit.is_some_and(|h| h.back_face == inside_is_back), "{:?} escaped or saw the outside: {:?}", r, hit);
            prop_assert!(levels.occluded(&r));
        }
    }

    /// Rays leaving a point rebuilt on a world triangle of an instanced sphere, offset by the
    /// point's error bound plus `instance_position_error`: outward, they never hit the
    /// (convex) sphere again; inward, they do not hit the triangle they
    /// left.
    #[test]
    fn rays_leaving_an_instanced_surface_do_not_hit_it_again(m in transforms(), seed in any::<u64>()) {
        let scene = one_object(Mesh::uv_sphere("sphere", 16, 8), m);
        let geometry = WorldGeometry::build(&scene);
        let levels = TwoLevelBvh::build(&scene, &geometry, BvhPreset::default(), &[true]);
        let root = &levels.bottoms[0].nodes[0];
        let extra = instance_position_error(m, &world_to_object(m).unwrap(), root.min(), root.max());
        let mut rng = Rng(seed | 1);
        let mirrored = m.determinant() < 0.0;
        for _ in 0..100 {
            let gi = (rng.next() * geometry.triangles.len() as f32) as usize % geometry.triangles.len();
            let [v0, v1, v2] = geometry.triangle(gi).vertices();
            let ng = geometric_normal(v0, v1, v2);
            if ng == Vec3::ZERO {
                continue;
            }
            // The sphere's triangles face out in object space; a mirror turns them in.
            let outward = if mirrored { -ng } else { ng };
            let (u, v) = (rng.next(), rng.next());
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            let p = reconstruct_position(u, v, v0, v1, v2);
            let err = position_error_bound(u, v, v0, v1, v2).max_element() + extra;
            let d = rng.unit();
            let out = if d.dot(outward) > 0.0 { d } else { -d };
            let r = ray(offset_ray_origin(p, err, outward), out);
            let hit = levels.closest_hit(&r);
            prop_assert!(hit.is_none(), "outward ray {:?} from triangle {} hit {:?}", r, gi, hit);
            // Inward, the ray must not hit the triangle it left. (It may miss altogether: near
            // a sharp convex edge the offset along one face's normal crosses the plane of the
            // next face, in world space as in object space.)
            let r = ray(offset_ray_origin(p, err, -outward), -out);
            let hit = levels.closest_hit(&r);
            prop_assert!(hit.is_none_or(|h| h.triangle as usize != gi), "inward ray {:?} from {} hit {:?}", r, gi, hit);
        }
    }
}

/// Two sets of levels are the same, bit for bit. (Not `==`: the bottom levels' wide views
/// pad their leaves with NaN.)
fn assert_same_levels(a: &TwoLevelBvh, b: &TwoLevelBvh) {
    assert_eq!(
        (&a.top, &a.instances, &a.object_instance, &a.in_object_space),
        (&b.top, &b.instances, &b.object_instance, &b.in_object_space)
    );
    assert_eq!(a.bottoms.len(), b.bottoms.len());
    for (x, y) in a.bottoms.iter().zip(&b.bottoms) {
        assert_eq!((&x.nodes, &x.prim_indices, &x.leaf_triangles), (&y.nodes, &y.prim_indices, &y.leaf_triangles));
    }
}

/// The world tables of two builds are the same, field by field.
fn assert_same_tables(a: &WorldGeometry, b: &WorldGeometry) {
    assert_eq!(a.triangles, b.triangles);
    assert_eq!(a.objects, b.objects);
    assert_eq!(a.bounds, b.bounds);
    assert_eq!(a.non_finite_triangles, b.non_finite_triangles);
    assert_eq!(a.surface, b.surface);
}

/// Moving objects between frames: the world tables and the levels updated in place equal
/// a fresh build of the moved scene, the bottom levels are not rebuilt, and rays find the
/// objects where they now are.
#[test]
fn moved_objects_update_to_what_a_fresh_build_gives() {
    let mut scene = Scene::default_scene();
    let moving: Vec<bool> = (0..scene.objects.len()).map(|o| o == 1 || o == 3).collect();
    let mut geometry = WorldGeometry::build(&scene);
    let mut levels = TwoLevelBvh::build(&scene, &geometry, BvhPreset::default(), &moving);
    let bottoms_before = levels.bottoms.clone();
    for (frame, t) in [0.5f32, 1.25, -2.0].into_iter().enumerate() {
        scene.objects[1].transform = Mat4::from_scale_rotation_translation(
            Vec3::new(1.0, 1.5, 0.75),
            Quat::from_rotation_y(t),
            Vec3::new(t, 0.25 * t, -t),
        ) * Scene::default_scene().objects[1].transform;
        // The other moving object changes only how it is shaded.
        scene.objects[3].render_mode = if frame % 2 == 0 { RenderMode::Raster } else { RenderMode::RayTraced };
        for o in [1, 3] {
            geometry.update_object(&scene, o);
        }
        levels.update_objects(&scene, &geometry, &[1, 3]).unwrap();
        let fresh = WorldGeometry::build(&scene);
        assert_same_tables(&geometry, &fresh);
        assert_same_levels(&levels, &TwoLevelBvh::build(&scene, &fresh, BvhPreset::default(), &moving));
        assert_same_levels(&TwoLevelBvh { bottoms: bottoms_before.clone(), ..levels.clone() }, &levels);
        // A ray at the moved object's centre from outside its box finds it.
        let centre = scene.objects[1].transform.transform_point3(Vec3::ZERO);
        let r = ray(centre + Vec3::new(0.0, 0.0, 50.0), Vec3::NEG_Z);
        let hit = levels.closest_hit(&r).expect("the moved object is hit");
        let flat = Bvh::build(&geometry, BvhPreset::default()).closest_hit(geometry.stored_table(), &r).unwrap();
        assert_eq!(geometry.triangle(hit.triangle as usize).object, geometry.triangle(flat.triangle as usize).object);
        assert!((hit.t - flat.t).abs() <= 1e-4 * flat.t, "{hit:?} vs {flat:?}");
    }
}

#[test]
fn objects_that_cannot_move_are_refused_and_nothing_changes() {
    use hyrt_core::bvh::two_level::MoveError;
    let mut scene = Scene::default_scene();
    let geometry = WorldGeometry::build(&scene);
    let mut levels = TwoLevelBvh::build(&scene, &geometry, BvhPreset::default(), &[false, true]);
    let before = levels.clone();
    assert_eq!(levels.update_objects(&scene, &geometry, &[0]), Err(MoveError::Baked { object: 0 }));
    let n = scene.objects.len() as u32;
    assert_eq!(
        levels.update_objects(&scene, &geometry, &[n]),
        Err(MoveError::NoObject { object: n, objects: n as usize })
    );
    scene.objects[1].transform = Mat4::from_scale(Vec3::new(1.0, 0.0, 1.0));
    assert_eq!(levels.update_objects(&scene, &geometry, &[1]), Err(MoveError::BadTransform { object: 1 }));
    assert_same_levels(&levels, &before);
    assert!(MoveError::Baked { object: 0 }.to_string().contains("prepare the scene with it moving"));
}

/// A deforming mesh: a refitted bottom level answers as one built over the new positions
/// (the same closest hit for every ray), keeps its topology, and declines (returns false)
/// when a triangle stops being traceable.
#[test]
fn a_refitted_tree_answers_as_a_rebuilt_one() {
    let mut scene = one_object(Mesh::uv_sphere("sphere", 32, 16), Mat4::IDENTITY);
    let geometry = WorldGeometry::build(&scene);
    let mut bvh = Bvh::build(&geometry, BvhPreset::default());
    let topology: Vec<(u32, u32)> = bvh.nodes.iter().map(|n| (n.left_or_first, n.count)).collect();
    // A wobble: every vertex pushed out or in along its direction.
    for p in &mut scene.meshes[0].positions {
        *p *= 1.0 + 0.3 * (5.0 * p.x).sin() * (3.0 * p.y).cos();
    }
    let deformed = WorldGeometry::build(&scene);
    assert!(bvh.refit(deformed.stored_table()));
    bvh.validate(&deformed).unwrap();
    assert_eq!(topology, bvh.nodes.iter().map(|n| (n.left_or_first, n.count)).collect::<Vec<_>>());
    let rebuilt = Bvh::build(&deformed, BvhPreset::default());
    let mut rng = Rng(5);
    for _ in 0..3000 {
        let r = ray(rng.unit() * 3.0, rng.unit());
        assert_eq!(
            bvh.closest_hit(deformed.stored_table(), &r),
            rebuilt.closest_hit(deformed.stored_table(), &r),
            "{r:?}"
        );
        assert_eq!(bvh.occluded(deformed.stored_table(), &r), rebuilt.occluded(deformed.stored_table(), &r));
    }
    // A triangle collapsed to a sliver of two equal vertices: not traceable any more.
    let idx = scene.meshes[0].indices[40];
    scene.meshes[0].positions[idx[1] as usize] = scene.meshes[0].positions[idx[0] as usize];
    let collapsed = WorldGeometry::build(&scene);
    let before = bvh.clone();
    assert!(!bvh.refit(collapsed.stored_table()));
    assert_eq!(bvh.nodes, before.nodes, "a declined refit changes nothing");
}
