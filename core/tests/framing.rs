//! The view a scene without a camera gets (`Scene::ensure_camera_and_lights`,
//! `hyrt_core::scene::framing`): objects framed from outside, interiors seen from inside.

use std::path::{Path, PathBuf};

use glam::{Mat4, Vec3};
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::formats::{CameraRecord, TRI_INWARD};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::camera::primary_rays;
use hyrt_core::kernels::raster::shows_interior;
use hyrt_core::scene::{Camera, Material, Mesh, RenderMode, Scene};

/// A quad centred at `c` spanned by the half-axes `u` and `v`, its front face towards `u x v`.
fn quad(name: &str, c: Vec3, u: Vec3, v: Vec3) -> Mesh {
    let n = u.cross(v).normalize();
    Mesh {
        name: name.into(),
        positions: vec![c - u - v, c + u - v, c + u + v, c - u + v],
        normals: Some(vec![n; 4]),
        indices: vec![[0, 1, 2], [0, 2, 3]],
        ..Default::default()
    }
}

/// A courtyard 20 x 10 (x by z), walls 8 high, open to the sky: a floor and four walls,
/// their front faces inwards (an open mesh each), and a ball in it.
fn courtyard() -> Scene {
    let mut s = Scene::default();
    let (hx, hz, h) = (10.0, 5.0, 8.0);
    let grey = Material::grey();
    let mut add = |m: Mesh| {
        s.add_object(m, grey.clone(), Mat4::IDENTITY, RenderMode::Raster);
    };
    add(quad("floor", Vec3::ZERO, Vec3::Z * hz, Vec3::X * hx));
    add(quad("east", Vec3::new(hx, h / 2.0, 0.0), Vec3::Z * hz, Vec3::Y * h / 2.0));
    add(quad("west", Vec3::new(-hx, h / 2.0, 0.0), Vec3::Y * h / 2.0, Vec3::Z * hz));
    add(quad("north", Vec3::new(0.0, h / 2.0, -hz), Vec3::X * hx, Vec3::Y * h / 2.0));
    add(quad("south", Vec3::new(0.0, h / 2.0, hz), Vec3::Y * h / 2.0, Vec3::X * hx));
    s.add_object(
        Mesh::uv_sphere("ball", 24, 12),
        Material::grey(),
        Mat4::from_translation(Vec3::new(3.0, 1.0, 1.0)),
        RenderMode::RayTraced,
    );
    s
}

/// What the camera's primary rays at `w` x `h` pixels see: the fractions that meet a
/// surface and that see a surface's interior side.
fn seen(scene: &Scene, camera: &Camera, w: u32, h: u32) -> (f32, f32) {
    let geometry = WorldGeometry::build(scene);
    let bvh = Bvh::build(&geometry, BvhPreset::Fastest);
    let table = geometry.stored_table();
    let (mut hits, mut interior) = (0, 0);
    for ray in primary_rays(&CameraRecord::new(camera, w, h)) {
        if let Some(hit) = bvh.closest_hit(table, &ray) {
            hits += 1;
            let inward = table[hit.triangle as usize].flags & TRI_INWARD != 0;
            interior += shows_interior(hit.back_face, inward) as usize;
        }
    }
    let n = (w * h) as f32;
    (hits as f32 / n, interior as f32 / n)
}

fn inside(p: Vec3, lo: Vec3, hi: Vec3) -> bool {
    p.cmpgt(lo).all() && p.cmplt(hi).all()
}

#[test]
fn a_courtyard_is_seen_from_inside_along_its_length() {
    let mut s = courtyard();
    s.ensure_camera_and_lights();
    let cam = s.camera.unwrap();
    assert!(inside(cam.eye, Vec3::new(-10.0, 0.0, -5.0), Vec3::new(10.0, 8.0, 5.0)), "{cam:?}");
    // A quarter of the way up between the floor and the top of the walls, give or take the
    // lattice step of the candidates (8 / 8 = 1 unit) that picked the eye's column.
    assert!(cam.eye.y > 0.5 && cam.eye.y < 3.0, "{cam:?}");
    let dir = (cam.target - cam.eye).normalize();
    assert!(dir.y.abs() < 1e-6 && dir.x.abs() > 0.9, "looks along the 20-unit length: {dir:?}");
    assert!(s.notes.iter().any(|n| n.contains("camera placed inside")), "{:?}", s.notes);
    // The default lights are inside too, under the open sky, above the floor.
    assert_eq!(s.lights.len(), 2);
    for light in &s.lights {
        let hyrt_core::scene::Light::Point { position, .. } = light else { panic!("{light:?}") };
        assert!(inside(*position, Vec3::new(-10.0, 0.0, -5.0), Vec3::new(10.0, 8.01, 5.0)), "{position:?}");
    }
    let (hit, interior) = seen(&s, &cam, 32, 18);
    // The walls fill the view but for the sky above them; no surface is seen from behind.
    assert!(hit > 0.7 && interior == 0.0, "hit {hit}, interior {interior}");
}

#[test]
fn objects_are_framed_from_outside() {
    // A ball on a ground plane: the plane covers half the sphere of directions at most.
    let mut ground = Scene::default();
    ground.add_object(
        Mesh::grid("ground", 4),
        Material::grey(),
        Mat4::from_scale(Vec3::splat(20.0)),
        RenderMode::Raster,
    );
    ground.add_object(
        Mesh::uv_sphere("ball", 24, 12),
        Material::grey(),
        Mat4::from_translation(Vec3::Y),
        RenderMode::RayTraced,
    );
    // A closed box wound outwards: a solid, whose inside is no place for a camera.
    let mut solid = Scene::default();
    solid.add_object(Mesh::cube("box"), Material::grey(), Mat4::from_scale(Vec3::splat(5.0)), RenderMode::Raster);
    for (name, mut s) in [("ball on a ground", ground), ("solid box", solid)] {
        let (lo, hi) = s.world_bounds().unwrap();
        s.ensure_camera_and_lights();
        let cam = s.camera.unwrap();
        assert!(!inside(cam.eye, lo, hi), "{name}: {cam:?}");
        assert!(s.notes.iter().any(|n| n.contains("framed automatically")), "{name}: {:?}", s.notes);
    }
}

/// `../shared/assets` if it holds `file`, else `None` with a message (the test skips).
fn shared_assets_with(file: &str) -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets");
    if dir.join(file).is_file() {
        Some(dir)
    } else {
        eprintln!("{} is absent: shared-asset test skipped", dir.display());
        None
    }
}

#[test]
fn sponza_is_seen_from_inside_the_atrium() {
    let Some(dir) = shared_assets_with("sponza.glb") else { return };
    let mut s = Scene::load(&dir.join("sponza.glb")).unwrap();
    assert!(s.camera.is_none(), "sponza.glb has no camera: this test is about the view it gets");
    let (lo, hi) = s.world_bounds().unwrap();
    s.ensure_camera_and_lights();
    let cam = s.camera.unwrap();
    assert!(inside(cam.eye, lo, hi), "{cam:?} not within {lo:?}..{hi:?}");
    // What the view shows: Sponza's inside (it fills the frame but for a strip of sky
    // through the courtyard's opening), none of it from behind its surfaces.
    let (hit, interior) = seen(&s, &cam, 64, 36);
    assert!(hit > 0.8 && interior < 0.02, "hit {hit}, interior {interior}: {cam:?}");
}

#[test]
fn shared_objects_are_framed_from_outside() {
    let Some(dir) = shared_assets_with("DamagedHelmet.glb") else { return };
    // The helmet's head cavity is free space its open meshes enclose, seen from inside on
    // front faces: 2.5% of the candidates, an object's cavity, not an interior.
    for file in ["DamagedHelmet.glb", "bunny.glb", "teapot.glb", "hard_cycloidal.glb"] {
        let mut s = Scene::load(&dir.join(file)).unwrap();
        assert!(s.camera.is_none(), "{file} has no camera: this test is about the view it gets");
        let (lo, hi) = s.world_bounds().unwrap();
        s.ensure_camera_and_lights();
        let cam = s.camera.unwrap();
        assert!(!inside(cam.eye, lo, hi), "{file}: {cam:?}");
        assert!(s.notes.iter().any(|n| n.contains("framed automatically")), "{file}: {:?}", s.notes);
    }
}
