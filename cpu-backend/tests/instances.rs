//! The object-space pass of two-level scenes in packets
//! (`hyrt_cpu::traversal::occluded_in_object_space_into`,
//! `closest_hit_in_object_space_into`), after the world-space level traced as the
//! backend traces it: every ray's answer is the scalar two-level walk's
//! (`TwoLevelBvh::occluded_filtered`, `closest_hit_filtered`) bit for bit, at every SIMD
//! level, on scenes of shared, moving, scaled, rotated and mirrored instances, alpha-tested
//! instances, instances far from the origin, and random transforms; and the backend's
//! frames of such a scene are the same whatever traversal it is set to.

use std::sync::Arc;

use glam::{Mat4, Quat, Vec3};
use hyrt_core::bvh::two_level::{INSTANCE_IDENTITY, INSTANCE_MIRRORED};
use hyrt_core::bvh::{BvhPreset, ClosestHit};
use hyrt_core::formats::{CameraRecord, RayRecord, TriangleRecord, INVALID_ID, RAY_KIND_SHADOW};
use hyrt_core::frame::{Backend, FrameOptions, PreparedScene};
use hyrt_core::kernels::texture::alpha_accepts;
use hyrt_core::scene::{
    AlphaMode, Camera, Filter, Light, Material, MaterialKind, Mesh, Object, ObjectSource, RenderMode, Sampler, Scene,
    TextureBinding, TextureImage, UvTransform, Wrap,
};
use hyrt_cpu::backend::CpuBackend;
use hyrt_cpu::bvh_build::prepare_moving;
use hyrt_cpu::shadow_rays::{SHADOW_OCCLUDED, SHADOW_VISIBLE};
use hyrt_cpu::traversal::{
    closest_hit_alpha_batch_into, closest_hit_in_object_space_into, occluded_alpha_batch_into,
    occluded_in_object_space_into, Traversal, LANES,
};
use proptest::prelude::*;

fn ray(origin: Vec3, direction: Vec3, t_max: f32) -> RayRecord {
    RayRecord {
        origin: origin.into(),
        t_min: 0.0,
        direction: direction.into(),
        t_max,
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

/// Another object drawing mesh `mesh` (shared: traced as an instance).
fn copy_of(scene: &mut Scene, mesh: usize, transform: Mat4, render_mode: RenderMode) -> u32 {
    let id = scene.objects.len() as u32;
    scene.objects.push(Object {
        id,
        name: format!("copy {id}"),
        mesh,
        transform,
        material: 0,
        render_mode,
        source: ObjectSource::default(),
    });
    id
}

/// A raster floor, a 3x3 grid of spheres sharing one mesh (scaled, rotated, one mirrored,
/// one squashed), a moving torus and a static cube, around `centre`.
fn shared_and_moving(centre: Vec3) -> (Scene, Vec<u32>) {
    let mut scene = Scene::default();
    let at = |p: Vec3| Mat4::from_translation(centre + p);
    scene.add_object(
        Mesh::grid("floor", 24),
        Material::grey(),
        at(Vec3::ZERO) * Mat4::from_scale(Vec3::splat(8.0)),
        RenderMode::Raster,
    );
    let sphere = scene.add_object(
        Mesh::uv_sphere("sphere", 20, 10),
        Material::grey(),
        at(Vec3::new(-2.0, 0.6, -2.0)),
        RenderMode::RayTraced,
    );
    let mesh = scene.objects[sphere as usize].mesh;
    for k in 1..9 {
        let (i, j) = ((k % 3) as f32, (k / 3) as f32);
        let scale = match k {
            4 => Vec3::new(-0.7, 0.7, 0.7),
            6 => Vec3::new(1.2, 0.3, 0.9),
            _ => Vec3::splat(0.4 + 0.1 * k as f32),
        };
        let m = at(Vec3::new(-2.0 + 2.0 * i, 0.8, -2.0 + 2.0 * j))
            * Mat4::from_scale_rotation_translation(scale, Quat::from_rotation_y(0.3 * k as f32), Vec3::ZERO);
        copy_of(&mut scene, mesh, m, if k % 2 == 0 { RenderMode::RayTraced } else { RenderMode::Raster });
    }
    let torus = scene.add_object(
        Mesh::torus("torus", 0.8, 0.25, 24, 12),
        Material::grey(),
        at(Vec3::new(0.5, 2.0, 0.5)) * Mat4::from_rotation_x(0.7),
        RenderMode::RayTraced,
    );
    scene.add_object(Mesh::cube("cube"), Material::grey(), at(Vec3::new(3.0, 0.5, 3.0)), RenderMode::Raster);
    (scene, vec![torus])
}

/// Rays of every kind through `prepared`'s scene: shadow rays from a grid on the floor
/// (`y = centre.y`) to a point light, row by row (coherent packets, many stopped in the
/// world-space level, many reaching instances); primary-like rays from an eye; rays
/// through the world vertices of instanced triangles (shared edges and vertices: ties);
/// random rays; every third with a finite `t_max`.
fn rays_through(prepared: &PreparedScene, centre: Vec3, seed: u64) -> Vec<RayRecord> {
    let mut rng = Rng(seed | 1);
    let mut rays = Vec::new();
    let light = centre + Vec3::new(1.0, 6.0, 0.5);
    for j in 0..48 {
        for i in 0..48 {
            let p = centre + Vec3::new(-4.0 + i as f32 / 6.0, 1e-3, -4.0 + j as f32 / 6.0);
            let d = light - p;
            rays.push(ray(p, d, if (i + j) % 3 == 0 { 0.6 } else { 1.0 }));
        }
    }
    let eye = centre + Vec3::new(-1.0, 4.0, 9.0);
    for j in 0..40 {
        for i in 0..40 {
            let target = centre + Vec3::new(-4.0 + i as f32 / 5.0, 2.5 - j as f32 / 8.0, 0.0);
            rays.push(ray(eye, target - eye, f32::INFINITY));
        }
    }
    let g = &prepared.geometry;
    let levels = prepared.levels.as_ref().expect("two levels");
    for inst in levels.instances.iter().filter(|i| i.flags & INSTANCE_IDENTITY == 0) {
        let o = &g.objects[inst.object as usize];
        for k in 0..64 {
            let t = g.triangle((o.first_triangle + (k * 37) % o.triangle_count) as usize);
            let target = Vec3::from(if k % 2 == 0 { t.v0 } else { t.v1 });
            let from = eye + rng.unit() * 0.3;
            rays.push(ray(from, target - from, f32::INFINITY));
        }
    }
    let (lo, hi) = g.bounds;
    for k in 0..2000 {
        let o = lo + (hi - lo) * Vec3::new(rng.next(), rng.next(), rng.next());
        rays.push(ray(o, rng.unit(), if k % 3 == 0 { (hi - lo).length() * 0.2 } else { f32::INFINITY }));
    }
    rays
}

fn bits(h: &Option<ClosestHit>) -> Option<(u32, u32, u32, u32, bool)> {
    h.map(|h| (h.triangle, h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.back_face))
}

/// Every traversal's two passes against the scalar two-level walk, ray by ray. Returns
/// (rays occluded, rays whose closest hit is on an object-space instance).
fn check(prepared: &PreparedScene, rays: &[RayRecord]) -> (usize, usize) {
    let levels = prepared.levels.as_ref().expect("two levels");
    let g = &prepared.geometry;
    let view = g.surface.view();
    let accept = |t: &TriangleRecord, id: u32, u: f32, v: f32| alpha_accepts(&view, t, id as usize, u, v);
    let reference_any: Vec<bool> = rays.iter().map(|r| levels.occluded_filtered(r, accept)).collect();
    let reference_closest: Vec<Option<ClosestHit>> =
        rays.iter().map(|r| levels.closest_hit_filtered(r, accept)).collect();
    let mut traversals = vec![Traversal::Scalar];
    traversals.extend(Traversal::available_simd());
    for traversal in traversals {
        // The world-space level first, as the backend traces it, then the object-space pass.
        let mut any = Vec::new();
        occluded_alpha_batch_into(&prepared.bvh, g.traversal_table(), &view, rays, traversal, &mut any);
        occluded_in_object_space_into(levels, &view, |i| rays[i], traversal, &mut any);
        for (k, (&a, &b)) in any.iter().zip(&reference_any).enumerate() {
            assert_eq!(a == SHADOW_OCCLUDED, b, "{traversal:?}: any hit of ray {k}: {:?}", rays[k]);
            assert!(a == SHADOW_OCCLUDED || a == SHADOW_VISIBLE);
        }
        let mut closest = Vec::new();
        closest_hit_alpha_batch_into(&prepared.bvh, g.traversal_table(), &view, rays, traversal, &mut closest);
        closest_hit_in_object_space_into(levels, &view, rays, traversal, &mut closest);
        for (k, (a, b)) in closest.iter().zip(&reference_closest).enumerate() {
            assert_eq!(bits(a), bits(b), "{traversal:?}: closest hit of ray {k}: {:?}", rays[k]);
        }
    }
    let on_instance = reference_closest
        .iter()
        .flatten()
        .filter(|h| levels.object_instance[g.triangle(h.triangle as usize).object as usize] != INVALID_ID)
        .count();
    (reference_any.iter().filter(|&&b| b).count(), on_instance)
}

#[test]
fn shared_moving_scaled_and_mirrored_instances_match_the_scalar_walk() {
    let centre = Vec3::ZERO;
    let (scene, moving) = shared_and_moving(centre);
    let prepared = prepare_moving(&scene, BvhPreset::default(), &moving);
    let levels = prepared.levels.as_ref().unwrap();
    assert!(levels.instances.iter().any(|i| i.flags & INSTANCE_MIRRORED != 0), "a mirrored instance");
    assert!(levels.world_level().is_some(), "a world-space level besides the instances");
    let rays = rays_through(&prepared, centre, 3);
    let (occluded, on_instance) = check(&prepared, &rays);
    assert!(occluded > rays.len() / 4 && occluded < rays.len() * 3 / 4, "{occluded} of {} occluded", rays.len());
    assert!(on_instance > 1000, "{on_instance} closest hits on instances");
}

/// Far from the origin the maps' translations dwarf the meshes: the moved rays' rounding
/// must still be the scalar walk's.
#[test]
fn instances_far_from_the_origin_match_the_scalar_walk() {
    let centre = Vec3::new(1.0e5, -3.0e4, 7.0e4);
    let (scene, moving) = shared_and_moving(centre);
    let prepared = prepare_moving(&scene, BvhPreset::default(), &moving);
    let rays = rays_through(&prepared, centre, 5);
    let (occluded, on_instance) = check(&prepared, &rays);
    assert!(occluded > 500 && on_instance > 500, "{occluded} occluded, {on_instance} on instances");
}

/// Every object an instance (no world-space level): the world pass finds nothing and the
/// object-space pass everything.
#[test]
fn a_scene_of_instances_only_matches_the_scalar_walk() {
    let centre = Vec3::new(0.0, 0.0, 0.0);
    let (scene, _) = shared_and_moving(centre);
    let all: Vec<u32> = (0..scene.objects.len() as u32).collect();
    let prepared = prepare_moving(&scene, BvhPreset::default(), &all);
    assert!(prepared.levels.as_ref().unwrap().world_level().is_none());
    let rays = rays_through(&prepared, centre, 9);
    let (occluded, on_instance) = check(&prepared, &rays);
    assert!(occluded > 1000 && on_instance > 2000, "{occluded} occluded, {on_instance} on instances");
}

/// Two alpha-tested fences (a 4x4 checker of opaque and clear texels) sharing one quad,
/// the second mirrored, in front of a wall: the instances bring the alpha flag, the hit
/// record their object, and the packets test the texels as the scalar walk does.
#[test]
fn alpha_tested_instances_match_the_scalar_walk() {
    let mut scene = Scene::default();
    let grey = Material { base_color: Vec3::splat(0.5), ..Material::grey() };
    let wall = Mat4::from_translation(Vec3::new(0.0, 0.0, -1.0)) * Mat4::from_scale(Vec3::new(6.0, 4.0, 1.0));
    scene.add_object(Mesh::uv_quad("wall"), grey, wall, RenderMode::Raster);
    let texels: Vec<[u8; 4]> =
        (0..16).map(|k| if (k % 4 + k / 4) % 2 == 0 { [255, 0, 0, 255] } else { [0, 0, 255, 0] }).collect();
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
    let first = scene.add_object(
        Mesh::uv_quad("fence"),
        fence,
        Mat4::from_translation(Vec3::new(-1.2, 0.0, 0.0)),
        RenderMode::RayTraced,
    );
    let mesh = scene.objects[first as usize].mesh;
    let mirrored = Mat4::from_translation(Vec3::new(1.2, 0.0, 0.3)) * Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0));
    let second = copy_of(&mut scene, mesh, mirrored, RenderMode::Raster);
    scene.objects[second as usize].material = scene.objects[first as usize].material;
    scene.lights.push(Light::Directional { direction: Vec3::NEG_Z, color: Vec3::ONE, intensity: 1.0 });
    let prepared = prepare_moving(&scene, BvhPreset::default(), &[]);
    let levels = prepared.levels.as_ref().unwrap();
    assert_eq!(levels.instances.iter().filter(|i| i.flags & INSTANCE_IDENTITY == 0).count(), 2);
    // Rays from in front toward the wall, neighbours close together (packets straddling
    // holes).
    let mut rng = Rng(77);
    let mut rays = Vec::new();
    for k in 0..4096 {
        let base = Vec3::new((k / 64) as f32 / 32.0 - 1.0, (k % 64) as f32 / 32.0 - 1.0, 0.0);
        let origin = Vec3::new(rng.next() * 0.2, rng.next() * 0.2, 3.0) + base * 0.5;
        let target = Vec3::new(base.x * 2.5, base.y * 1.5, -1.0) + (rng.unit() * 0.05);
        rays.push(ray(origin, target - origin, if k % 2 == 0 { 1.0 } else { f32::INFINITY }));
    }
    let (occluded, on_instance) = check(&prepared, &rays);
    assert!(occluded > 500 && on_instance > 500 && on_instance < 3500, "{occluded} occluded, {on_instance} on fences");
}

/// The CPU backend's frame of a moving scene, shadow and bounce rays included, is the same
/// with the scalar walks as in packets (the object-space pass follows the backend's
/// traversal settings).
#[test]
fn backend_frames_of_moving_scenes_are_identical_with_scalar_and_simd_traversals() {
    let (mut scene, moving) = shared_and_moving(Vec3::ZERO);
    // The spheres mirrors, so bounce rays leave instances (a mirrored one too) and meet
    // others.
    let (sphere_material, sphere_mesh) = (scene.objects[1].material, scene.objects[1].mesh);
    for o in scene.objects.iter_mut().filter(|o| o.mesh == sphere_mesh) {
        o.material = sphere_material;
    }
    scene.materials[sphere_material].kind = MaterialKind::Specular;
    scene.materials[sphere_material].metallic = 1.0;
    scene.lights.push(Light::point(Vec3::new(1.0, 6.0, 0.5), Vec3::ONE, 40.0));
    let prepared = prepare_moving(&scene, BvhPreset::default(), &moving);
    let camera = Camera::look_at(Vec3::new(-1.0, 4.0, 9.0), Vec3::new(0.0, 0.8, 0.0), Vec3::Y);
    let cam = CameraRecord::new(&camera, 160, 120);
    let mut backend = CpuBackend::new(Some(2));
    let options = FrameOptions::with_stage_outputs();
    let simd = backend.render(&prepared, &cam, &options).unwrap();
    backend.set_shadow_traversal(Traversal::Scalar);
    backend.set_bounce_traversal(Traversal::Scalar);
    let scalar = backend.render(&prepared, &cam, &options).unwrap();
    assert!(simd.occluded == scalar.occluded, "shadow rays differ");
    assert!(simd.occluded.contains(&SHADOW_OCCLUDED) && simd.occluded.contains(&SHADOW_VISIBLE));
    assert!(simd.bounces.first().is_some_and(|b| b.rays.len() > 1000), "bounce rays off the mirrors");
    for (a, b) in simd.bounces.iter().zip(&scalar.bounces) {
        // Not assert_eq: the buffers are long.
        assert!(a.hits == b.hits, "bounce hits differ");
        assert!(a.occluded == b.occluded, "bounce shadow rays differ");
    }
    let image_bits = |img: &[[f32; 4]]| img.iter().flat_map(|p| p.map(f32::to_bits)).collect::<Vec<u32>>();
    assert!(image_bits(&simd.final_image) == image_bits(&scalar.final_image), "final images differ");
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
        prop::array::uniform3(-30.0f32..30.0),
    )
        .prop_map(|(a, angle, s, mirror, t)| transform(a, angle, s, mirror, t))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Three copies of a sphere and one of a torus under random maps, with a static floor:
    /// packets of rays from random points (coherent runs of [`LANES`] toward one target,
    /// then incoherent ones) answer as the scalar walk.
    #[test]
    fn random_instances_match_the_scalar_walk(
        maps in prop::array::uniform4(transforms()),
        seed in any::<u64>(),
    ) {
        let mut scene = Scene::default();
        scene.add_object(Mesh::grid("floor", 8), Material::grey(), Mat4::from_scale(Vec3::splat(60.0)), RenderMode::Raster);
        let s = scene.add_object(Mesh::uv_sphere("sphere", 12, 6), Material::grey(), maps[0], RenderMode::RayTraced);
        let mesh = scene.objects[s as usize].mesh;
        copy_of(&mut scene, mesh, maps[1], RenderMode::RayTraced);
        copy_of(&mut scene, mesh, maps[2], RenderMode::Raster);
        let t = scene.add_object(Mesh::torus("torus", 1.0, 0.3, 12, 8), Material::grey(), maps[3], RenderMode::RayTraced);
        let prepared = prepare_moving(&scene, BvhPreset::default(), &[t]);
        let g = &prepared.geometry;
        let (lo, hi) = g.bounds;
        let mut rng = Rng(seed | 1);
        let mut rays = Vec::new();
        for k in 0..256 {
            let origin = lo + (hi - lo) * Vec3::new(rng.next(), rng.next(), rng.next());
            // Toward an instance's centre, a packet at a time, or anywhere.
            let target = maps[(k / LANES) % 4].transform_point3(Vec3::ZERO) + rng.unit() * 0.5;
            let d = if k % 64 < 48 { target - origin } else { rng.unit() };
            rays.push(ray(origin, d, if k % 5 == 0 { (hi - lo).length() * 0.3 } else { f32::INFINITY }));
        }
        check(&prepared, &rays);
    }
}
