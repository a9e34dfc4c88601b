//! Objects that move between frames (`Renderer::prepare_moving`,
//! `PreparedScene::move_objects`): a moved scene renders as the same scene prepared again
//! after the move, bit for bit, on the CPU backend; the hybrid frame through two levels
//! matches the single-level frame up to the rounding of the instance maps; what cannot
//! move is refused with a reason.

use hyrt::glam::{Mat4, Quat, Vec3};
use hyrt::{AdapterPolicy, BackendKind, Camera, FrameOptions, MoveError, RenderMode, Renderer, Scene};

const W: u32 = 96;
const H: u32 = 72;

fn cpu() -> Renderer {
    Renderer::new(BackendKind::Cpu, Some(2), AdapterPolicy::HardwareOnly).unwrap()
}

fn camera(scene: &Scene) -> Camera {
    scene.camera.unwrap_or_else(|| Camera::look_at(Vec3::new(0.0, 3.0, 9.0), Vec3::ZERO, Vec3::Y))
}

/// The object of the default scene that moves: its sphere.
fn sphere(scene: &Scene) -> u32 {
    scene.objects.iter().position(|o| o.name.contains("sphere")).expect("the default scene has a sphere") as u32
}

#[test]
fn a_moved_scene_renders_as_the_scene_prepared_again() {
    let mut scene = Scene::default_scene();
    let moving = sphere(&scene);
    let mut renderer = cpu();
    let mut prepared = renderer.prepare_moving(&scene, &[moving]);
    assert!(prepared.levels.is_some());
    let options = FrameOptions { max_depth: 2, ..FrameOptions::default() };
    let rest = scene.objects[moving as usize].transform;
    for step in 1..4 {
        let turn =
            Mat4::from_rotation_translation(Quat::from_rotation_y(0.7 * step as f32), Vec3::X * 0.3 * step as f32);
        scene.objects[moving as usize].transform = turn * rest;
        // Every other step it also switches between ray traced and rasterized.
        scene.objects[moving as usize].render_mode =
            if step % 2 == 1 { RenderMode::Raster } else { RenderMode::RayTraced };
        prepared.move_objects(&scene, &[moving]).unwrap();
        let moved = renderer.render(&prepared, &camera(&scene), W, H, &options).unwrap();
        let again =
            renderer.render(&renderer.prepare_moving(&scene, &[moving]), &camera(&scene), W, H, &options).unwrap();
        assert_eq!(moved.final_srgb8(), again.final_srgb8(), "step {step}");
        assert_eq!(moved.shadow, again.shadow, "step {step}");
        // Against the scene prepared as one world-space tree: the same image but where a
        // hit or shadow edge falls within the maps' rounding (a few ulps of the scene).
        let flat = renderer.render(&renderer.prepare(&scene), &camera(&scene), W, H, &options).unwrap();
        let (a, b) = (moved.final_srgb8(), flat.final_srgb8());
        let differing = a.chunks(4).zip(b.chunks(4)).filter(|(x, y)| x != y).count();
        assert!(
            differing * 1000 <= (W * H) as usize,
            "step {step}: {differing} pixels differ from the single-level frame"
        );
    }
}

#[test]
fn objects_not_prepared_as_moving_are_refused() {
    let mut scene = Scene::default_scene();
    let moving = sphere(&scene);
    let other = (moving + 1) % scene.objects.len() as u32;
    let renderer = cpu();
    let mut prepared = renderer.prepare_moving(&scene, &[moving]);
    let id = prepared.id();
    assert_eq!(prepared.move_objects(&scene, &[other]), Err(MoveError::Baked { object: other }));
    scene.objects[moving as usize].transform = Mat4::from_scale(Vec3::ZERO);
    assert_eq!(prepared.move_objects(&scene, &[moving]), Err(MoveError::BadTransform { object: moving }));
    assert_eq!(prepared.id(), id, "a refused move changes nothing");
    let mut flat = renderer.prepare(&scene);
    assert_eq!(flat.move_objects(&scene, &[moving]), Err(MoveError::Baked { object: moving }));
}

/// Each move is a revision with what it changed; a device cache asks what changed since
/// the revision it holds, merged, until the log no longer reaches back that far.
#[test]
fn moves_are_revisions_a_device_can_catch_up_with() {
    let mut scene = Scene::default_scene();
    let (a, b) = (sphere(&scene), 0);
    let renderer = cpu();
    let mut prepared = renderer.prepare_moving(&scene, &[a, b]);
    let id = prepared.id();
    assert_eq!((prepared.revision(), prepared.changes_since(0)), (0, Some(hyrt::SceneChanges::default())));
    prepared.move_objects(&scene, &[a]).unwrap();
    prepared.move_objects(&scene, &[b, a]).unwrap();
    prepared.update_lights(&scene);
    assert_eq!((prepared.id(), prepared.revision()), (id, 3));
    assert_eq!(
        prepared.changes_since(1),
        Some(hyrt::SceneChanges { objects: vec![a.min(b), a.max(b)], lights: true, bottoms: vec![] })
    );
    assert_eq!(prepared.changes_since(3), Some(hyrt::SceneChanges::default()));
    assert_eq!(prepared.changes_since(4), None, "a revision the scene never had");
    for _ in 0..hyrt::CHANGE_LOG_LENGTH {
        prepared.move_objects(&scene, &[a]).unwrap();
    }
    assert_eq!(prepared.changes_since(0), None, "the log no longer reaches revision 0");
    assert!(prepared.changes_since(prepared.revision() - 2).is_some());
    scene.lights.pop();
    prepared.update_lights(&scene);
    assert_ne!(prepared.id(), id, "another number of lights is another scene for a device");
}

/// A deforming mesh (new vertex positions each frame): its bottom level is refitted, and
/// the frame is the one of the deformed scene prepared again; an object not prepared as
/// moving cannot deform.
#[test]
fn a_deformed_mesh_renders_as_the_scene_prepared_again() {
    let mut scene = Scene::default_scene();
    let moving = sphere(&scene);
    let mesh = scene.objects[moving as usize].mesh;
    let mut renderer = cpu();
    let mut prepared = renderer.prepare_moving(&scene, &[moving]);
    let id = prepared.id();
    let rest = scene.meshes[mesh].positions.clone();
    for step in 1..3 {
        for (p, r) in scene.meshes[mesh].positions.iter_mut().zip(&rest) {
            *p = *r * (1.0 + 0.2 * step as f32 * (4.0 * r.y).sin());
        }
        prepared.deform_mesh(&scene, mesh).unwrap();
        assert_eq!((prepared.id(), prepared.revision()), (id, step), "a refit is a revision of the same scene");
        let opts = FrameOptions::default();
        let a = renderer.render(&prepared, &camera(&scene), W, H, &opts).unwrap();
        let b = renderer.render(&renderer.prepare_moving(&scene, &[moving]), &camera(&scene), W, H, &opts).unwrap();
        assert_eq!(a.final_srgb8(), b.final_srgb8(), "step {step}");
    }
    let other = scene.objects.iter().position(|o| o.id != moving).unwrap();
    let other_mesh = scene.objects[other].mesh;
    assert_eq!(prepared.deform_mesh(&scene, other_mesh), Err(MoveError::Baked { object: other as u32 }));
}

/// The same two levels over stored world tables and over tables with the instanced objects
/// kept by reference (`prepare_moving`): the same frame bit for bit, as prepared, after
/// moves and after a deformation. The raster, reconstruction and every shading stage read
/// the made records exactly as they read stored ones.
#[test]
fn objects_by_reference_render_the_stored_tables_frame() {
    use hyrt_core::bvh::two_level::TwoLevelBvh;
    use hyrt_core::frame::PreparedScene;
    use hyrt_core::geometry::WorldGeometry;
    let mut scene = Scene::default_scene();
    // Two more copies of the sphere's mesh: shared meshes are instances too.
    let s = sphere(&scene);
    for k in 1..3 {
        let mut copy = scene.objects[s as usize].clone();
        copy.id = scene.objects.len() as u32;
        copy.transform = Mat4::from_translation(Vec3::new(-1.3 * k as f32, 0.2, 0.8)) * copy.transform;
        scene.objects.push(copy);
    }
    let moving = [s, 0];
    let mut renderer = cpu();
    let options = FrameOptions { max_depth: 2, keep_gbuffer: true, ..FrameOptions::default() };
    let stored_of = |scene: &Scene| {
        let mut flags = vec![false; scene.objects.len()];
        for &o in &moving {
            flags[o as usize] = true;
        }
        let geometry = WorldGeometry::build(scene);
        let levels = TwoLevelBvh::build(scene, &geometry, hyrt::BvhPreset::default(), &flags);
        PreparedScene::with_levels(geometry, levels, 0.0)
    };
    let mut referenced = renderer.prepare_moving(&scene, &moving);
    assert!(referenced.geometry.triangles.has_references());
    let frames = |renderer: &mut Renderer, a: &PreparedScene, b: &PreparedScene, scene: &Scene, what: &str| {
        let fa = renderer.render(a, &camera(scene), W, H, &options).unwrap();
        let fb = renderer.render(b, &camera(scene), W, H, &options).unwrap();
        let bits = |f: &hyrt::Frame| bytemuck::cast_slice::<_, u8>(&f.gbuffer).to_vec();
        assert!(bits(&fa) == bits(&fb), "{what}: G-buffers differ");
        assert_eq!(fa.final_srgb8(), fb.final_srgb8(), "{what}");
        assert_eq!(fa.shadow, fb.shadow, "{what}");
    };
    frames(&mut renderer, &referenced, &stored_of(&scene), &scene, "as prepared");
    for step in 1..3 {
        let t = Mat4::from_rotation_translation(Quat::from_rotation_y(0.5 * step as f32), Vec3::Z * 0.2 * step as f32);
        for &o in &moving {
            scene.objects[o as usize].transform = t * scene.objects[o as usize].transform;
        }
        referenced.move_objects(&scene, &moving).unwrap();
        frames(&mut renderer, &referenced, &stored_of(&scene), &scene, &format!("move {step}"));
    }
    let mesh = scene.objects[s as usize].mesh;
    for p in &mut scene.meshes[mesh].positions {
        *p *= 1.0 + 0.1 * p.y;
    }
    referenced.deform_mesh(&scene, mesh).unwrap();
    frames(&mut renderer, &referenced, &stored_of(&scene), &scene, "deformed");
}

/// A deforming emissive mesh (`emissive_lights`): its emitters move with its triangles, so
/// the revision names the light table, as a move does (a device holding the scene writes
/// the emitter table again), and the lights are those of the deformed scene prepared again.
#[test]
fn a_deformed_emissive_mesh_rewrites_the_light_table() {
    let mut scene = Scene::default_scene();
    scene.emissive_lights = true;
    let moving = sphere(&scene);
    let (mesh, material) = (scene.objects[moving as usize].mesh, scene.objects[moving as usize].material);
    scene.materials[material].emissive = Vec3::new(2.0, 1.5, 1.0);
    let mut renderer = cpu();
    let mut prepared = renderer.prepare_moving(&scene, &[moving]);
    assert!(!prepared.geometry.emitters.is_empty(), "the sphere emits");
    let (id, revision) = (prepared.id(), prepared.revision());
    for p in &mut scene.meshes[mesh].positions {
        *p *= 1.0 + 0.2 * p.y;
    }
    prepared.deform_mesh(&scene, mesh).unwrap();
    assert_eq!(prepared.id(), id, "the same triangles: a revision of the same scene");
    let changes = prepared.changes_since(revision).unwrap();
    assert!(changes.lights, "the emitters moved with the mesh: {changes:?}");
    let again = renderer.prepare_moving(&scene, &[moving]);
    let bits = |l: &[hyrt::formats::LightRecord]| bytemuck::cast_slice::<_, u8>(l).to_vec();
    assert!(bits(&prepared.geometry.lights) == bits(&again.geometry.lights), "lights as prepared again");
    let opts = FrameOptions::default();
    let a = renderer.render(&prepared, &camera(&scene), W, H, &opts).unwrap();
    let b = renderer.render(&again, &camera(&scene), W, H, &opts).unwrap();
    assert_eq!(a.final_srgb8(), b.final_srgb8());
}
