//! glTF node animation: a procedural animated file built here (a box translated and rotated,
//! a parent stepping and its child scaled along a cubic spline, a light and a camera moving),
//! loaded, posed at several times and compared with the transforms written out by hand; the
//! committed sample scene (`assets/scenes/animated_box.gltf`) is this file; malformed
//! animation data is an error naming the file and the problem.

use std::f32::consts::{FRAC_PI_2, FRAC_PI_4};
use std::path::{Path, PathBuf};

use hyrt_core::glam::{Mat4, Quat, Vec3};
use hyrt_core::scene::animation::Keyframes;
use hyrt_core::scene::{Interpolation, Light, Scene};
use hyrt_core::{AnimationError, SceneError};
use serde_json::{json, Value};

#[path = "../fuzz/harness.rs"]
mod harness;

/// Posed transforms against the hand-written ones: slerp goes through `acos` and `sin`, and
/// each world matrix is a product of two or three f32 matrices with entries up to 2: a few
/// ulp of 2.
const POSE_TOLERANCE: f32 = 1e-5;

/// The committed sample scene: the file [`animated_box`] builds.
fn sample_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/animated_box.gltf")
}

/// A fresh, empty folder for one test.
fn temp_dir(test: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("animation").join(test);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The binary buffer and the accessors of a glTF file being built.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    /// A float accessor of `count` elements of `kind` (`SCALAR`, `VEC3`, `VEC4`) holding
    /// `values`, in its own buffer view; returns its index.
    fn floats(&mut self, kind: &str, values: &[f32]) -> usize {
        let width = match kind {
            "SCALAR" => 1,
            "VEC3" => 3,
            "VEC4" => 4,
            other => panic!("{other}"),
        };
        let offset = self.bin.len();
        for v in values {
            self.bin.extend_from_slice(&v.to_le_bytes());
        }
        self.views.push(json!({ "buffer": 0, "byteOffset": offset, "byteLength": values.len() * 4 }));
        let mut accessor = json!({
            "bufferView": self.views.len() - 1, "componentType": 5126,
            "count": values.len() / width, "type": kind,
        });
        // Key times and positions carry bounds, as glTF requires.
        if kind != "VEC4" {
            let column = |k: usize| values.iter().skip(k).step_by(width).copied();
            let lo: Vec<f32> = (0..width).map(|k| column(k).fold(f32::INFINITY, f32::min)).collect();
            let hi: Vec<f32> = (0..width).map(|k| column(k).fold(f32::NEG_INFINITY, f32::max)).collect();
            accessor["min"] = json!(lo);
            accessor["max"] = json!(hi);
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// An accessor of `count` elements of `kind` with component type `component` (the glTF
    /// code) over `bytes`, in its own buffer view (padded to 4 bytes); returns its index.
    fn raw(&mut self, component: u32, kind: &str, count: usize, bytes: &[u8]) -> usize {
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        self.views.push(json!({ "buffer": 0, "byteOffset": offset, "byteLength": bytes.len() }));
        self.accessors.push(json!({
            "bufferView": self.views.len() - 1, "componentType": component, "count": count, "type": kind,
        }));
        self.accessors.len() - 1
    }

    /// A u16 index accessor; returns its index.
    fn indices(&mut self, indices: &[u16]) -> usize {
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        self.raw(5123, "SCALAR", indices.len(), &bytes)
    }

    /// The document with its accessors, views and the buffer as a base64 data URI.
    fn finish(self, mut doc: Value) -> Value {
        doc["accessors"] = json!(self.accessors);
        doc["bufferViews"] = json!(self.views);
        doc["buffers"] = json!([{
            "byteLength": self.bin.len(),
            "uri": format!("data:application/octet-stream;base64,{}", harness::base64(&self.bin)),
        }]);
        doc
    }
}

fn quat(q: Quat) -> [f32; 4] {
    q.to_array()
}

/// The animated glTF (also `assets/scenes/animated_box.gltf`). Nodes: 0 `ground` (static),
/// 1 `box`, 2 `spinner` with child 3 `satellite`, 4 `camera`, 5 `lamp` (a point light).
///
/// Animation 0 `move` (2 s):
/// * `box` translation, `LINEAR`, keys 0, 1, 2 s: (-1, 0, 0), (1, 0, 0), (1, 1, 0);
/// * `box` rotation, `LINEAR` (slerp), keys 0, 2 s: identity, 90 degrees about +Y;
/// * `spinner` rotation, `STEP`, keys 0, 1 s: identity, 90 degrees about +Z;
/// * `satellite` scale, `CUBICSPLINE`, keys 0, 2 s: values 0.5, 1, in/out tangents (per
///   second) 0 and 0.5 at 2 s, so the scale is exactly 0.5 + t^2 / 8;
/// * `lamp` translation, `STEP`, keys 0, 1 s: (2, 4, 2), (-2, 4, 2).
///
/// Animation 1 `dolly` (2 s): `camera` translation, `LINEAR`, (0, 1, 6) to (0, 1.5, 7).
fn animated_box() -> Value {
    animated_doc(|_, _| {})
}

/// Accessors of [`animated_box`] that tests point samplers at.
const CUBE: usize = 0;
const T02: usize = 5;
const BOX_TRANSLATION: usize = 7;
const BOX_ROTATION: usize = 8;
const CAMERA_TRANSLATION: usize = 12;

/// Add a channel to animation `animation` driving `path` of `node` with sampler `sampler`.
fn push_channel(doc: &mut Value, animation: usize, sampler: usize, node: usize, path: &str) {
    doc["animations"][animation]["channels"]
        .as_array_mut()
        .unwrap()
        .push(json!({ "sampler": sampler, "target": { "node": node, "path": path } }));
}

/// [`animated_box`] changed by `edit`, which may add accessors before the buffer is written.
fn animated_doc(edit: impl FnOnce(&mut Builder, &mut Value)) -> Value {
    let mut b = Builder::default();
    #[rustfmt::skip]
    let cube = b.floats("VEC3", &[
        -0.5, -0.5, -0.5,  0.5, -0.5, -0.5,  0.5, 0.5, -0.5,  -0.5, 0.5, -0.5,
        -0.5, -0.5, 0.5,  0.5, -0.5, 0.5,  0.5, 0.5, 0.5,  -0.5, 0.5, 0.5,
    ]);
    #[rustfmt::skip]
    let cube_indices = b.indices(&[
        0, 2, 1, 0, 3, 2,  4, 5, 6, 4, 6, 7,  0, 1, 5, 0, 5, 4,
        3, 6, 2, 3, 7, 6,  0, 4, 7, 0, 7, 3,  1, 2, 6, 1, 6, 5,
    ]);
    let ground = b.floats("VEC3", &[-4.0, 0.0, -4.0, 4.0, 0.0, -4.0, 4.0, 0.0, 4.0, -4.0, 0.0, 4.0]);
    let ground_indices = b.indices(&[0, 2, 1, 0, 3, 2]);
    let t012 = b.floats("SCALAR", &[0.0, 1.0, 2.0]);
    let t02 = b.floats("SCALAR", &[0.0, 2.0]);
    let t01 = b.floats("SCALAR", &[0.0, 1.0]);
    let box_translation = b.floats("VEC3", &[-1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0]);
    let box_rotation = b.floats("VEC4", &[quat(Quat::IDENTITY), quat(Quat::from_rotation_y(FRAC_PI_2))].concat());
    let spinner_rotation = b.floats("VEC4", &[quat(Quat::IDENTITY), quat(Quat::from_rotation_z(FRAC_PI_2))].concat());
    // [in-tangent, value, out-tangent] per key, each a VEC3 with equal components.
    let spline: Vec<f32> = [0.0, 0.5, 0.0, 0.5, 1.0, 0.0].iter().flat_map(|&v| [v; 3]).collect();
    let satellite_scale = b.floats("VEC3", &spline);
    let lamp_translation = b.floats("VEC3", &[2.0, 4.0, 2.0, -2.0, 4.0, 2.0]);
    let camera_translation = b.floats("VEC3", &[0.0, 1.0, 6.0, 0.0, 1.5, 7.0]);
    let sampler = |input: usize, output: usize, interpolation: &str| json!({ "input": input, "output": output, "interpolation": interpolation });
    let channel = |sampler: usize, node: usize, path: &str| json!({ "sampler": sampler, "target": { "node": node, "path": path } });
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": "hyrt core/tests/animation.rs (animated_box)" },
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": { "KHR_lights_punctual": { "lights": [
            { "type": "point", "color": [1.0, 0.95, 0.9], "intensity": 60.0 }
        ]}},
        "scene": 0,
        "scenes": [{ "nodes": [0, 1, 2, 4, 5] }],
        "nodes": [
            { "name": "ground", "mesh": 1, "translation": [0.0, -1.0, 0.0] },
            { "name": "box", "mesh": 0 },
            { "name": "spinner", "translation": [0.0, 0.0, -2.0], "children": [3] },
            { "name": "satellite", "mesh": 0, "translation": [1.5, 0.0, 0.0], "scale": [0.5, 0.5, 0.5] },
            { "name": "camera", "camera": 0, "translation": [0.0, 1.0, 6.0] },
            { "name": "lamp", "translation": [2.0, 4.0, 2.0], "extensions": { "KHR_lights_punctual": { "light": 0 } } }
        ],
        "cameras": [{ "type": "perspective", "perspective": { "yfov": 0.8, "znear": 0.1, "zfar": 100.0 } }],
        "meshes": [
            { "name": "cube", "primitives": [{ "attributes": { "POSITION": cube }, "indices": cube_indices, "material": 0 }] },
            { "name": "ground", "primitives": [{ "attributes": { "POSITION": ground }, "indices": ground_indices, "material": 1 }] }
        ],
        "materials": [
            { "name": "orange", "pbrMetallicRoughness": { "baseColorFactor": [0.9, 0.45, 0.1, 1.0], "metallicFactor": 0.0 } },
            { "name": "grey", "pbrMetallicRoughness": { "baseColorFactor": [0.7, 0.7, 0.7, 1.0], "metallicFactor": 0.0 } }
        ],
        "animations": [
            { "name": "move",
              "samplers": [
                  sampler(t012, box_translation, "LINEAR"),
                  sampler(t02, box_rotation, "LINEAR"),
                  sampler(t01, spinner_rotation, "STEP"),
                  sampler(t02, satellite_scale, "CUBICSPLINE"),
                  sampler(t01, lamp_translation, "STEP")
              ],
              "channels": [
                  channel(0, 1, "translation"),
                  channel(1, 1, "rotation"),
                  channel(2, 2, "rotation"),
                  channel(3, 3, "scale"),
                  channel(4, 5, "translation")
              ] },
            { "name": "dolly",
              "samplers": [sampler(t02, camera_translation, "LINEAR")],
              "channels": [channel(0, 4, "translation")] }
        ]
    });
    // Accessor indices the tests name.
    assert_eq!(
        (cube, t02, box_translation, box_rotation, camera_translation),
        (CUBE, T02, BOX_TRANSLATION, BOX_ROTATION, CAMERA_TRANSLATION)
    );
    edit(&mut b, &mut doc);
    b.finish(doc)
}

/// Write `doc` as `name` in a fresh folder for `test`.
fn write(test: &str, name: &str, doc: &Value) -> PathBuf {
    let path = temp_dir(test).join(name);
    std::fs::write(&path, serde_json::to_string_pretty(doc).unwrap()).unwrap();
    path
}

fn load(test: &str, doc: &Value) -> Scene {
    Scene::load(&write(test, "animated.gltf", doc)).unwrap_or_else(|e| panic!("{e}"))
}

fn object<'s>(scene: &'s Scene, name: &str) -> &'s hyrt_core::scene::Object {
    scene.objects.iter().find(|o| o.name.starts_with(name)).unwrap_or_else(|| panic!("no object {name}"))
}

fn assert_mat_near(actual: Mat4, expected: Mat4, what: &str) {
    let diff = (actual - expected).to_cols_array().iter().fold(0.0f32, |m, d| m.max(d.abs()));
    assert!(diff <= POSE_TOLERANCE, "{what}: expected\n{expected}\ngot\n{actual}\n(largest difference {diff})");
}

fn bits(m: Mat4) -> [u32; 16] {
    m.to_cols_array().map(f32::to_bits)
}

/// The `move` animation's transforms at time `t`, by hand.
fn expected_move(t: f32) -> (Mat4, Mat4, Vec3) {
    let c = t.clamp(0.0, 2.0);
    let box_translation = if c <= 1.0 { Vec3::new(-1.0 + 2.0 * c, 0.0, 0.0) } else { Vec3::new(1.0, c - 1.0, 0.0) };
    let box_world = Mat4::from_translation(box_translation) * Mat4::from_rotation_y(FRAC_PI_4 * c);
    let spin = if c >= 1.0 { FRAC_PI_2 } else { 0.0 };
    let scale = 0.5 + c * c / 8.0;
    let satellite_world = Mat4::from_translation(Vec3::new(0.0, 0.0, -2.0))
        * Mat4::from_rotation_z(spin)
        * Mat4::from_translation(Vec3::new(1.5, 0.0, 0.0))
        * Mat4::from_scale(Vec3::splat(scale));
    let lamp = if c >= 1.0 { Vec3::new(-2.0, 4.0, 2.0) } else { Vec3::new(2.0, 4.0, 2.0) };
    (box_world, satellite_world, lamp)
}

#[test]
fn the_animated_file_loads_with_its_hierarchy_and_animations() {
    let scene = load("loads", &animated_box());
    let animation = scene.animation.as_ref().expect("the file has animations");
    assert_eq!(animation.nodes().len(), 6);
    let names: Vec<&str> = animation.animations().iter().map(|a| a.name()).collect();
    assert_eq!(names, ["move", "dolly"]);
    assert_eq!(animation.find("dolly"), Some(1));
    assert_eq!(animation.find("walk"), None);
    assert_eq!(animation.animations()[0].duration(), 2.0);
    let interpolations: Vec<Interpolation> =
        animation.animations()[0].samplers().iter().map(|s| s.interpolation()).collect();
    use Interpolation::*;
    assert_eq!(interpolations, [Linear, Linear, Step, CubicSpline, Step]);
    assert!(matches!(animation.animations()[0].samplers()[3].values(), Keyframes::Vectors(v) if v.len() == 6));
    let satellite = &animation.nodes()[3];
    assert_eq!((satellite.label.as_str(), satellite.parent), ("node 3 'satellite'", Some(2)));
    assert_eq!(satellite.objects, [2]);
    assert!(animation.nodes()[4].camera && animation.nodes()[5].light == Some(0));
    assert!(
        scene.notes.iter().any(|n| n.contains("2 animation(s): 'move' (2.000 s), 'dolly' (2.000 s)")),
        "{:?}",
        scene.notes
    );
}

/// What each animation moves: `move` drives the box (whose child is the satellite) and
/// the lamp; `dolly` only the camera. The objects it names are exactly those whose
/// transforms change as it plays.
#[test]
fn moved_objects_are_the_ones_an_animation_moves() {
    let mut scene = load("moved", &animated_box());
    let id = |name: &str| object(&scene, name).id;
    let (box_id, satellite) = (id("box"), id("satellite"));
    let animation = scene.animation.clone().unwrap();
    assert_eq!(animation.moved_objects(0), [box_id.min(satellite), box_id.max(satellite)]);
    assert!(animation.moves_lights(0));
    assert_eq!(animation.moved_objects(1), Vec::<u32>::new());
    assert!(!animation.moves_lights(1));
    assert!(animation.moved_objects(7).is_empty() && !animation.moves_lights(7));
    let rest: Vec<Mat4> = scene.objects.iter().map(|o| o.transform).collect();
    scene.set_time(0, 0.75).unwrap();
    let changed: Vec<u32> =
        scene.objects.iter().zip(&rest).filter(|(o, r)| bits(o.transform) != bits(**r)).map(|(o, _)| o.id).collect();
    assert_eq!(changed, animation.moved_objects(0));
}

#[test]
fn posing_matches_the_transforms_written_by_hand() {
    let mut scene = load("pose", &animated_box());
    let ground = object(&scene, "ground").transform;
    for t in [-1.0f32, 0.0, 0.25, 0.5, 0.999, 1.0, 1.5, 2.0, 7.0] {
        scene.set_time(0, t).unwrap();
        let (box_world, satellite_world, lamp) = expected_move(t);
        assert_mat_near(object(&scene, "box").transform, box_world, &format!("box at {t} s"));
        assert_mat_near(object(&scene, "satellite").transform, satellite_world, &format!("satellite at {t} s"));
        let Light::Point { position, .. } = scene.lights[0] else { panic!("a point light") };
        assert!(position.abs_diff_eq(lamp, POSE_TOLERANCE), "lamp at {t} s: {position}");
        assert_eq!(bits(object(&scene, "ground").transform), bits(ground), "the ground is not animated");
        assert_eq!(scene.camera.unwrap().eye, Vec3::new(0.0, 1.0, 6.0), "`move` does not move the camera");
    }
}

#[test]
fn the_camera_follows_its_node() {
    let mut scene = load("camera", &animated_box());
    let loaded = scene.camera.unwrap();
    let dolly = scene.animation.as_ref().unwrap().find("dolly").unwrap();
    for t in [0.0f32, 0.5, 2.0, 3.0] {
        scene.set_time(dolly, t).unwrap();
        let camera = scene.camera.unwrap();
        let eye = Vec3::new(0.0, 1.0, 6.0) + Vec3::new(0.0, 0.5, 1.0) * (t.min(2.0) / 2.0);
        assert!(camera.eye.abs_diff_eq(eye, POSE_TOLERANCE), "eye at {t} s: {}", camera.eye);
        assert!((camera.target - camera.eye).abs_diff_eq(Vec3::NEG_Z, POSE_TOLERANCE), "looks along -Z");
        assert_eq!(camera.up, Vec3::Y);
        assert_eq!((camera.fov_y_deg, camera.near, camera.far), (loaded.fov_y_deg, loaded.near, loaded.far));
    }
    // `dolly` drives only the camera: the box is back in its rest pose.
    scene.set_time(0, 2.0).unwrap();
    scene.set_time(dolly, 1.0).unwrap();
    assert_eq!(object(&scene, "box").transform, Mat4::IDENTITY);
}

#[test]
fn reset_pose_restores_the_loaded_scene_bit_for_bit() {
    let loaded = load("reset", &animated_box());
    let mut scene = loaded.clone();
    scene.set_time(0, 1.3).unwrap();
    assert_ne!(bits(object(&scene, "box").transform), bits(object(&loaded, "box").transform));
    scene.set_time(1, 1.3).unwrap();
    scene.reset_pose();
    for (a, b) in scene.objects.iter().zip(&loaded.objects) {
        assert_eq!(bits(a.transform), bits(b.transform), "{}", a.name);
    }
    assert_eq!(scene.camera, loaded.camera);
    assert_eq!(scene.lights, loaded.lights);
}

#[test]
fn set_time_errors_say_what_is_wrong() {
    let mut still = Scene::default_scene();
    assert_eq!(still.set_time(0, 1.0), Err(AnimationError::NotAnimated));
    let mut scene = load("errors", &animated_box());
    assert_eq!(scene.set_time(2, 1.0), Err(AnimationError::NoSuchAnimation { index: 2, count: 2 }));
    // The camera scaled to zero on its way: no direction to look along. An error naming the
    // node, and the scene is left as it was.
    let doc = animated_doc(|b, doc| {
        let zero = b.floats("VEC3", &[1.0, 1.0, 1.0, 0.0, 0.0, 0.0]);
        doc["animations"][1]["samplers"].as_array_mut().unwrap().push(json!({ "input": T02, "output": zero }));
        push_channel(doc, 1, 1, 4, "scale");
    });
    let mut scene = load("errors_zero_scale", &doc);
    let before = scene.clone();
    scene.set_time(1, 1.0).unwrap();
    let err = scene.set_time(1, 2.0).unwrap_err();
    assert!(
        matches!(&err, AnimationError::Degenerate { node, what: "camera", .. } if node == "node 4 'camera'"),
        "{err}"
    );
    assert!(err.to_string().contains("'dolly' at 2 s"), "{err}");
    scene.set_time(1, 0.0).unwrap();
    assert_eq!(scene.camera, before.camera);
}

#[test]
fn normalized_integer_rotations_are_decoded_and_normalized() {
    let doc = animated_doc(|b, doc| {
        // 90 degrees about +Z as normalized i16: (0, 0, 23170, 23170) / 32767, length 0.99999.
        let mut bytes = Vec::new();
        for c in [0i16, 0, 0, 32767, 0, 0, 23170, 23170] {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
        let rotation = b.raw(5122, "VEC4", 2, &bytes);
        b.accessors[rotation]["normalized"] = json!(true);
        doc["animations"][0]["samplers"][2]["output"] = json!(rotation);
    });
    let mut scene = load("normalized", &doc);
    scene.set_time(0, 1.0).unwrap();
    let (_, satellite_world, _) = expected_move(1.0);
    assert_mat_near(object(&scene, "satellite").transform, satellite_world, "satellite with i16 rotation keys");
    let Keyframes::Rotations(keys) = scene.animation.as_ref().unwrap().animations()[0].samplers()[2].values() else {
        panic!("rotations")
    };
    // Normalized when loaded: unit to f32 rounding (a few ulp of 1).
    const UNIT_TOLERANCE: f32 = 4.0 * f32::EPSILON;
    assert!(keys.iter().all(|q| (q.length() - 1.0).abs() <= UNIT_TOLERANCE), "{keys:?}");
}

#[test]
fn skins_morph_targets_weights_and_stray_channels_are_noted() {
    let doc = animated_doc(|_, doc| {
        doc["skins"] = json!([{ "joints": [2] }]);
        doc["nodes"][1]["skin"] = json!(0);
        doc["meshes"][0]["primitives"][0]["targets"] = json!([{ "POSITION": CUBE }]);
        doc["nodes"].as_array_mut().unwrap().push(json!({ "name": "stray" }));
        push_channel(doc, 0, 2, 1, "weights");
        push_channel(doc, 0, 0, 6, "translation");
    });
    let scene = load("notes", &doc);
    let has = |text: &str| scene.notes.iter().any(|n| n.contains(text));
    assert!(has("skins are not applied (node 1 'box')"), "{:?}", scene.notes);
    assert!(has("morph targets are not applied (mesh 0 'cube')"), "{:?}", scene.notes);
    assert!(has("morph target weights are not animated (animation 0 'move' channel 5)"), "{:?}", scene.notes);
    assert!(
        has("nodes outside the scene rendered are ignored (animation 0 'move' channel 6 (node 6))"),
        "{:?}",
        scene.notes
    );
    // The supported channels still play.
    let mut scene = scene;
    scene.set_time(0, 0.5).unwrap();
    assert_mat_near(object(&scene, "box").transform, expected_move(0.5).0, "box");
}

/// Load `doc` as `name` and return the error's message, which must name the file.
fn load_error(test: &str, doc: &Value) -> String {
    let path = write(test, "bad.gltf", doc);
    let err = Scene::load(&path).map(|_| ()).expect_err("malformed animation data");
    let message = err.to_string();
    assert!(message.starts_with(&path.display().to_string()), "{message}");
    match err {
        SceneError::Content { .. } | SceneError::Gltf { .. } => message,
        other => panic!("{other:?}"),
    }
}

#[test]
fn malformed_animation_data_is_an_error_naming_the_file_and_the_problem() {
    type Edit = fn(&mut Builder, &mut Value);
    let cases: [(&str, Edit, &str); 16] = [
        ("cubic_count", |_, d| d["animations"][0]["samplers"][3]["output"] = json!(BOX_TRANSLATION),
         "sampler 3 (CUBICSPLINE scale): 3 output values for 2 key times; CUBICSPLINE needs 6"),
        ("linear_count", |_, d| d["animations"][0]["samplers"][0]["input"] = json!(T02),
         "sampler 0 (LINEAR translation): 3 output values for 2 key times; LINEAR needs 2"),
        ("input_type", |_, d| d["animations"][0]["samplers"][0]["input"] = json!(BOX_TRANSLATION),
         "sampler 0: input (key times) must be float32 SCALAR, found F32 Vec3"),
        ("rotation_type", |_, d| d["animations"][0]["samplers"][1]["output"] = json!(BOX_TRANSLATION),
         "sampler 1: output of a rotation channel must be float32 or normalized 8/16-bit integer VEC4, found F32 Vec3"),
        ("translation_type", |_, d| d["animations"][0]["samplers"][0]["output"] = json!(BOX_ROTATION),
         "sampler 0: output of a translation channel must be float32 VEC3, found F32 Vec4"),
        ("unnormalized", |b, d| {
            let bytes = [0u8, 0, 0, 255, 0, 0, 180, 180];
            d["animations"][0]["samplers"][2]["output"] = json!(b.raw(5121, "VEC4", 2, &bytes));
        }, "found U8 Vec4"),
        ("decreasing", |b, d| d["animations"][0]["samplers"][0]["input"] = json!(b.floats("SCALAR", &[0.0, 2.0, 1.0])),
         "key times must increase strictly: time 2 is 1 after 2"),
        ("negative", |b, d| d["animations"][0]["samplers"][0]["input"] = json!(b.floats("SCALAR", &[-1.0, 0.0, 1.0])),
         "key time 0 is -1: times are finite seconds from 0"),
        ("one_cubic_key", |b, d| {
            d["animations"][0]["samplers"][3]["input"] = json!(b.floats("SCALAR", &[0.0]));
            d["animations"][0]["samplers"][3]["output"] = json!(b.floats("VEC3", &[0.0; 9]));
        }, "1 key times; CUBICSPLINE needs at least 2"),
        ("not_finite", |b, d| {
            d["animations"][0]["samplers"][1]["output"] = json!(b.floats("VEC4", &[0.0, 0.0, 0.0, 1.0, f32::NAN, 0.0, 0.0, 1.0]));
        }, "output value 1 is not finite"),
        ("zero_rotation", |b, d| {
            d["animations"][0]["samplers"][1]["output"] = json!(b.floats("VEC4", &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]));
        }, "rotation value 1 is the zero quaternion"),
        ("matrix_node", |_, d| {
            d["nodes"][1]["matrix"] = json!(Mat4::IDENTITY.to_cols_array());
        }, "animation 'move' drives node 1 'box', which has a matrix"),
        ("twice", |_, d| push_channel(d, 0, 0, 1, "translation"),
         "animation 0 'move' channel 5: drives the translation of node 1, as channel 0 does"),
        ("shared_sampler", |_, d| push_channel(d, 0, 1, 2, "translation"),
         "channel 5: sampler 1 drives both rotations and translations or scales"),
        ("short_accessor", |b, _| b.accessors[CAMERA_TRANSLATION]["count"] = json!(50),
         "animation 1 'dolly' sampler 0: output accessor 12: 50 elements of 12 bytes"),
        ("target_node", |_, d| push_channel(d, 0, 0, 60, "translation"),
         "animations[0].channels[5].target.node"),
    ];
    for (name, edit, expected) in cases {
        let message = load_error(name, &animated_doc(edit));
        assert!(message.contains(expected), "{name}: {message}\n(expected it to contain: {expected})");
    }
    for (name, edit, expected) in [
        ("sampler_index", (|_, d| push_channel(d, 0, 9, 1, "scale")) as Edit, "animations[0].channels[5].sampler"),
        ("interpolation", |_, d| d["animations"][0]["samplers"][0]["interpolation"] = json!("CUBIC"), "interpolation"),
        ("path", |_, d| d["animations"][0]["channels"][0]["target"]["path"] = json!("colour"), "path"),
    ] {
        let message = load_error(name, &animated_doc(edit));
        assert!(message.contains("not a valid glTF 2.0 file") && message.contains(expected), "{name}: {message}");
    }
}

#[test]
fn the_committed_sample_scene_is_the_procedural_file() {
    let built = serde_json::to_string_pretty(&animated_box()).unwrap() + "\n";
    if std::env::var_os("HYRT_WRITE_SAMPLE").is_some() {
        std::fs::write(sample_path(), &built).unwrap();
    }
    let committed = std::fs::read_to_string(sample_path()).unwrap_or_default();
    assert!(
        committed == built,
        "{} differs from animated_box(); rewrite it with HYRT_WRITE_SAMPLE=1 cargo test -p hyrt-core --test animation",
        sample_path().display()
    );
    assert!(built.len() < 20_000, "the sample stays small: {} bytes", built.len());
}

/// Write the animated file and `manifest` beside it in a fresh folder; load both.
fn alone_and_manifest(test: &str, manifest: &str) -> (Scene, Scene) {
    let alone = write(test, "animated.gltf", &animated_box());
    let path = alone.with_file_name("scene.toml");
    std::fs::write(&path, manifest).unwrap();
    let load = |p: &Path| Scene::load(p).unwrap_or_else(|e| panic!("{e}"));
    (load(&alone), load(&path))
}

/// A one-model manifest plays the file's animations as the file alone does: the same names,
/// and at every time the same transforms, camera and lights, bit for bit.
#[test]
fn a_one_model_manifest_plays_the_files_animations_bit_for_bit() {
    let (mut alone, mut manifest) = alone_and_manifest("one_model", "[[model]]\nfile = \"animated.gltf\"\n");
    let names =
        |s: &Scene| s.animation.as_ref().unwrap().animations().iter().map(|a| a.name().to_string()).collect::<Vec<_>>();
    assert_eq!(names(&manifest), names(&alone));
    let same = |a: &Scene, m: &Scene, what: &str| {
        for (x, y) in a.objects.iter().zip(&m.objects) {
            assert_eq!(format!("animated/{}", x.name), y.name);
            assert_eq!(bits(x.transform), bits(y.transform), "{what}: {}", x.name);
        }
        assert_eq!((a.camera, &a.lights), (m.camera, &m.lights), "{what}");
    };
    same(&alone, &manifest, "rest pose");
    for (animation, t) in [(0, 0.25), (0, 1.3), (1, 0.5), (0, 2.5)] {
        alone.set_time(animation, t).unwrap();
        manifest.set_time(animation, t).unwrap();
        same(&alone, &manifest, &format!("animation {animation} at {t} s"));
    }
    assert_eq!(
        manifest.animation.as_ref().unwrap().moved_objects(0),
        alone.animation.as_ref().unwrap().moved_objects(0)
    );
}

/// A model placed by a transform and repeated plays its animation under its placement: every
/// copy moves as the file alone does, then goes where the copy is placed; the file's lamp and
/// camera move with the model, and `reset_pose` gives the loaded scene back bit for bit.
#[test]
fn a_placed_repeated_model_plays_its_animation_under_its_placement() {
    let (mut alone, mut manifest) = alone_and_manifest(
        "placed",
        "[[model]]\nfile = \"animated.gltf\"\nname = \"m\"\ntranslate = [3.0, 0.0, -1.0]\n\
         rotate_deg = [0.0, 30.0, 0.0]\nscale = 2.0\nrepeat = { count = [2, 1, 1], step = [10.0, 0.0, 0.0] }\n",
    );
    let model = Mat4::from_scale_rotation_translation(
        Vec3::splat(2.0),
        Quat::from_rotation_y(30f32.to_radians()),
        Vec3::new(3.0, 0.0, -1.0),
    );
    let loaded = manifest.clone();
    let moved = manifest.animation.as_ref().unwrap().moved_objects(0);
    assert_eq!(moved.len(), 4, "box and satellite of both copies: {moved:?}");
    for t in [0.0f32, 0.6, 1.5] {
        alone.set_time(0, t).unwrap();
        manifest.set_time(0, t).unwrap();
        for (c, offset) in [(0, 0.0f32), (1, 10.0)] {
            let placed = Mat4::from_translation(Vec3::new(offset, 0.0, 0.0)) * model;
            for name in ["box", "satellite", "ground"] {
                let expected = placed * object(&alone, name).transform;
                let actual = object(&manifest, &format!("m#{c}/{name}")).transform;
                // The placement multiplies entries of up to 2 by up to 13 (a few ulp of 26).
                let diff = (actual - expected).to_cols_array().iter().fold(0.0f32, |m, d| m.max(d.abs()));
                assert!(diff < 1e-4, "copy {c} {name} at {t} s: {diff}\n{actual}\n{expected}");
            }
        }
        let (Light::Point { position: p, .. }, Light::Point { position: q, .. }) =
            (alone.lights[0], manifest.lights[0])
        else {
            panic!("point lights")
        };
        assert!(q.abs_diff_eq(model.transform_point3(p), 1e-4), "the lamp follows copy 0 at {t} s: {q}");
        assert_eq!(manifest.lights.len(), 1, "lights are the model's, not one per copy");
        let eye = manifest.camera.unwrap().eye;
        assert!(eye.abs_diff_eq(model.transform_point3(alone.camera.unwrap().eye), 1e-4), "camera at {t} s: {eye}");
    }
    manifest.reset_pose();
    for (a, b) in manifest.objects.iter().zip(&loaded.objects) {
        assert_eq!(bits(a.transform), bits(b.transform), "{}", a.name);
    }
    assert_eq!((manifest.camera, &manifest.lights), (loaded.camera, &loaded.lights));
}

/// Several animated models: `all` plays each model's chosen animation together, and each
/// model's own animations follow under `<model>/<animation>`.
#[test]
fn several_animated_models_play_together_in_all() {
    let (alone, manifest) = alone_and_manifest(
        "several",
        "[[model]]\nfile = \"animated.gltf\"\nname = \"a\"\nanimation = \"dolly\"\n\
         [[model]]\nfile = \"animated.gltf\"\nname = \"b\"\ntranslate = [0.0, 0.0, -20.0]\n",
    );
    let animation = manifest.animation.as_ref().unwrap();
    let names: Vec<&str> = animation.animations().iter().map(|a| a.name()).collect();
    assert_eq!(names, ["all", "a/move", "a/dolly", "b/move", "b/dolly"]);
    let at = |scene: &Scene, animation: usize, t: f32| {
        let mut scene = scene.clone();
        scene.set_time(animation, t).unwrap();
        scene
    };
    let t = 0.8;
    let (both, dolly, moved) = (at(&manifest, 0, t), at(&alone, 1, t), at(&alone, 0, t));
    // `a` plays `dolly`: its camera (the scene's) moves, its box stays.
    assert_eq!(both.camera, dolly.camera);
    assert_eq!(bits(object(&both, "a/box").transform), bits(object(&alone, "box").transform));
    // `b` plays `move` 20 m behind.
    let b_box = Mat4::from_translation(Vec3::new(0.0, 0.0, -20.0)) * object(&moved, "box").transform;
    assert_mat_near(object(&both, "b/box").transform, b_box, "b's box");
    // `b/move` moves only b.
    let only_b = at(&manifest, 3, t);
    assert_eq!(bits(object(&only_b, "a/box").transform), bits(object(&alone, "box").transform));
    assert_mat_near(object(&only_b, "b/box").transform, b_box, "b's box alone");
}

#[test]
fn a_model_animation_that_does_not_exist_is_an_error_naming_the_model() {
    let dir = temp_dir("unknown_animation");
    std::fs::write(dir.join("animated.gltf"), serde_json::to_string(&animated_box()).unwrap()).unwrap();
    for (manifest, expected) in [
        ("file = \"animated.gltf\"\nanimation = \"walk\"", "no animation of that name (it has 'move', 'dolly')"),
        ("builtin = \"cube\"\nanimation = \"walk\"", "a built-in shape has none"),
    ] {
        std::fs::write(dir.join("scene.toml"), format!("[[model]]\n{manifest}\n")).unwrap();
        let message = Scene::load(&dir.join("scene.toml")).expect_err(manifest).to_string();
        assert!(
            message.contains("scene.toml") && message.contains("model[0]") && message.contains(expected),
            "{message}"
        );
    }
}
