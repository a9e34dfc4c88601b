//! Scene loading: the glTF loader on small files built here (every field checked), the TOML
//! manifest, error messages, and the shared test models and example manifests.

use std::path::{Path, PathBuf};

use hyrt_core::glam::{Mat4, Quat, Vec3, Vec4Swizzles};
use hyrt_core::scene::{Light, MaterialKind, RenderMode, Scene};
use hyrt_core::SceneError;
use serde_json::{json, Value};

/// Float comparisons of values that went through a few f32 matrix products: a few ulp of 1..30.
const TRANSFORM_TOLERANCE: f32 = 1e-5;

// ---------------------------------------------------------------------------------------------
// Helpers: temporary folders, a base64 encoder, glTF/GLB writers, the test glTF.

/// A fresh, empty folder for one test under Cargo's per-target temporary folder.
fn temp_dir(test: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("scene_loading").join(test);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[path = "../fuzz/harness.rs"]
mod harness;
use harness::base64;

/// Write `doc` as a `.gltf` with `bin` embedded as a data URI in buffer 0.
fn write_gltf(path: &Path, mut doc: Value, bin: &[u8]) {
    doc["buffers"] = json!([{
        "byteLength": bin.len(),
        "uri": format!("data:application/octet-stream;base64,{}", base64(bin)),
    }]);
    std::fs::write(path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
}

/// Write `doc` as a `.glb` with `bin` as its binary chunk.
fn write_glb(path: &Path, mut doc: Value, bin: &[u8]) {
    doc["buffers"] = json!([{ "byteLength": bin.len() }]);
    let mut json_chunk = serde_json::to_vec(&doc).unwrap();
    json_chunk.resize(json_chunk.len().next_multiple_of(4), b' ');
    let mut bin_chunk = bin.to_vec();
    bin_chunk.resize(bin_chunk.len().next_multiple_of(4), 0);
    let total = 12 + 8 + json_chunk.len() + 8 + bin_chunk.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_chunk.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_chunk);
    out.extend_from_slice(&(bin_chunk.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin_chunk);
    std::fs::write(path, out).unwrap();
}

fn push_f32s(bin: &mut Vec<u8>, values: &[f32]) {
    for v in values {
        bin.extend_from_slice(&v.to_le_bytes());
    }
}

/// Quad vertices (accessor 0), its normals (1), its u16 indices (2), a triangle (3).
const QUAD: [f32; 12] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0];
const QUAD_INDICES: [u16; 6] = [0, 1, 2, 0, 2, 3];
const TRI: [f32; 9] = [0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 2.0, 0.0];

/// The binary buffer of the test glTF: quad positions (0..48), quad normals (48..96),
/// quad indices (96..108), triangle positions (108..144).
fn tiny_bin() -> Vec<u8> {
    let mut bin = Vec::new();
    push_f32s(&mut bin, &QUAD);
    push_f32s(&mut bin, &[0.0, 0.0, 1.0].repeat(4));
    for i in QUAD_INDICES {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    push_f32s(&mut bin, &TRI);
    bin
}

/// The rotation of node "child": 90 degrees about +Y.
fn child_rotation() -> Quat {
    Quat::from_rotation_y(std::f32::consts::FRAC_PI_2)
}

/// The test glTF: a 2-level hierarchy with transforms, a mesh with two triangle primitives and
/// a LINES one, instanced twice; a second mesh without material instanced twice; a camera; a
/// point and a directional light; a metallic and a transmissive material; `hyrt` extras on a
/// node, a mesh and a material.
fn tiny_doc() -> Value {
    let r = child_rotation();
    let sun = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    json!({
        "asset": { "version": "2.0" },
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior"],
        "extensions": { "KHR_lights_punctual": { "lights": [
            { "type": "point", "color": [1.0, 0.5, 0.25], "intensity": 40.0 },
            { "type": "directional", "intensity": 3.0 }
        ]}},
        "scene": 0,
        "scenes": [{ "nodes": [0, 4, 5, 6, 7] }],
        "nodes": [
            { "name": "root", "translation": [1.0, 2.0, 3.0], "scale": [2.0, 2.0, 2.0], "children": [1, 2, 3] },
            { "name": "child", "translation": [0.0, 0.0, -1.0], "rotation": [r.x, r.y, r.z, r.w], "mesh": 0 },
            { "name": "instance", "translation": [5.0, 0.0, 0.0], "mesh": 0,
              "extras": { "hyrt": { "ray_traced": true } } },
            { "name": "cam", "translation": [0.0, 1.0, 10.0], "camera": 0 },
            { "name": "lamp", "translation": [0.0, 5.0, 0.0],
              "extensions": { "KHR_lights_punctual": { "light": 0 } } },
            { "name": "sun", "rotation": [sun.x, sun.y, sun.z, sun.w],
              "extensions": { "KHR_lights_punctual": { "light": 1 } } },
            { "mesh": 1 },
            { "name": "flat", "mesh": 1, "extras": { "hyrt": { "ray_traced": false } } }
        ],
        "cameras": [{ "type": "perspective", "perspective": { "yfov": 0.8, "znear": 0.05, "zfar": 200.0 } }],
        "meshes": [
            { "name": "quad", "primitives": [
                { "attributes": { "POSITION": 0, "NORMAL": 1 }, "indices": 2, "material": 0 },
                { "attributes": { "POSITION": 3 }, "material": 1 },
                { "attributes": { "POSITION": 0 }, "mode": 1 }
            ]},
            { "name": "tri", "primitives": [{ "attributes": { "POSITION": 3 } }],
              "extras": { "hyrt": { "ray_traced": true } } }
        ],
        "materials": [
            { "name": "gold", "pbrMetallicRoughness": {
                "baseColorFactor": [1.0, 0.8, 0.2, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.25 } },
            { "name": "glass", "pbrMetallicRoughness": { "metallicFactor": 0.0, "roughnessFactor": 0.05 },
              "extensions": {
                "KHR_materials_transmission": { "transmissionFactor": 0.9 },
                "KHR_materials_ior": { "ior": 1.33 } },
              "extras": { "hyrt": { "ray_traced": false } } }
        ],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
              "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0] },
            { "bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3" },
            { "bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR" },
            { "bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC3",
              "min": [0.0, 0.0, 0.0], "max": [2.0, 2.0, 0.0] }
        ],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": 48, "target": 34962 },
            { "buffer": 0, "byteOffset": 48, "byteLength": 48, "target": 34962 },
            { "buffer": 0, "byteOffset": 96, "byteLength": 12, "target": 34963 },
            { "buffer": 0, "byteOffset": 108, "byteLength": 36, "target": 34962 }
        ]
    })
}

/// Write the test glTF into `dir` and return its path.
fn write_tiny(dir: &Path) -> PathBuf {
    let path = dir.join("tiny.gltf");
    write_gltf(&path, tiny_doc(), &tiny_bin());
    path
}

/// A one-triangle glTF whose document has been modified by `edit`, with buffer `bin`.
fn triangle_gltf(dir: &Path, name: &str, bin: &[u8], edit: impl FnOnce(&mut Value)) -> PathBuf {
    let mut doc = json!({
        "asset": { "version": "2.0" },
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "name": "t", "mesh": 0 }],
        "meshes": [{ "name": "t", "primitives": [{ "attributes": { "POSITION": 0 }, "indices": 1 }] }],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
              "min": [0.0, 0.0, 0.0], "max": [2.0, 2.0, 0.0] },
            { "bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR" }
        ],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": 36 },
            { "buffer": 0, "byteOffset": 36, "byteLength": 12 }
        ]
    });
    edit(&mut doc);
    let path = dir.join(name);
    write_gltf(&path, doc, bin);
    path
}

/// Three positions then three u32 indices.
fn triangle_bin(positions: [f32; 9], indices: [u32; 3]) -> Vec<u8> {
    let mut bin = Vec::new();
    push_f32s(&mut bin, &positions);
    for i in indices {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    bin
}

fn assert_vec3_near(actual: Vec3, expected: Vec3, what: &str) {
    assert!(
        (actual - expected).abs().max_element() <= TRANSFORM_TOLERANCE,
        "{what}: expected {expected}, got {actual} (difference {})",
        actual - expected
    );
}

// ---------------------------------------------------------------------------------------------
// glTF loader.

/// (id, name, mesh, material, render mode, source node, source mesh, source primitive).
type ObjectSummary<'a> = (u32, &'a str, usize, usize, RenderMode, Option<usize>, Option<usize>, Option<usize>);

#[test]
fn tiny_gltf_loads_every_field() {
    let dir = temp_dir("tiny_gltf_loads_every_field");
    let path = write_tiny(&dir);
    let s = Scene::load(&path).unwrap();

    // Meshes: (quad, 0), (quad, 1), (tri, 0); the LINES primitive is skipped; instances share.
    assert_eq!(s.meshes.len(), 3);
    assert_eq!(s.meshes[0].name, "quad#0");
    assert_eq!(s.meshes[0].positions, QUAD.chunks(3).map(Vec3::from_slice).collect::<Vec<_>>());
    assert_eq!(s.meshes[0].normals.as_deref(), Some(&[Vec3::Z; 4][..]));
    assert_eq!(s.meshes[0].indices, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(s.meshes[1].name, "quad#1");
    assert_eq!(s.meshes[1].positions, TRI.chunks(3).map(Vec3::from_slice).collect::<Vec<_>>());
    assert_eq!(s.meshes[1].normals, None);
    assert_eq!(s.meshes[1].indices, vec![[0, 1, 2]], "non-indexed primitive gets 0..n");
    assert_eq!(s.meshes[2].name, "tri#0");
    assert_eq!(s.triangle_count(), 2 + 1 + 2 + 1 + 1 + 1);

    // Materials: gold, glass, then the default grey for the material-less primitive.
    assert_eq!(s.materials.len(), 3);
    let gold = &s.materials[0];
    assert_eq!(gold.name, "gold");
    assert_eq!(gold.base_color, Vec3::new(1.0, 0.8, 0.2));
    assert_eq!((gold.metallic, gold.roughness, gold.transmission), (1.0, 0.25, 0.0));
    assert_eq!(gold.kind, MaterialKind::Specular);
    let glass = &s.materials[1];
    assert_eq!(glass.name, "glass");
    assert_eq!(glass.base_color, Vec3::ONE, "glTF default base colour");
    assert_eq!((glass.metallic, glass.roughness, glass.transmission), (0.0, 0.05, 0.9));
    assert_eq!(glass.kind, MaterialKind::Glass { ior: 1.33 });
    assert_eq!(s.materials[2], hyrt_core::scene::Material::grey());

    // Objects in depth-first order: child (2 primitives), instance (2), node 6, "flat".
    let summary: Vec<ObjectSummary> = s
        .objects
        .iter()
        .map(|o| {
            (o.id, o.name.as_str(), o.mesh, o.material, o.render_mode, o.source.node, o.source.mesh, o.source.primitive)
        })
        .collect();
    use RenderMode::{Raster, RayTraced};
    assert_eq!(
        summary,
        vec![
            // metallic -> ray traced by the default rule
            (0, "child#0", 0, 0, RayTraced, Some(1), Some(0), Some(0)),
            // material extra says raster (overrides the transmissive default)
            (1, "child#1", 1, 1, Raster, Some(1), Some(0), Some(1)),
            // node extra says ray traced (overrides the material extra)
            (2, "instance#0", 0, 0, RayTraced, Some(2), Some(0), Some(0)),
            (3, "instance#1", 1, 1, RayTraced, Some(2), Some(0), Some(1)),
            // unnamed node: the mesh name; mesh extra says ray traced (grey would be raster)
            (4, "tri#0", 2, 2, RayTraced, Some(6), Some(1), Some(0)),
            // node extra (raster) overrides mesh extra (ray traced)
            (5, "flat#0", 2, 2, Raster, Some(7), Some(1), Some(0)),
        ]
    );
    assert!(s.objects.iter().all(|o| o.source.file.as_deref() == Some(path.as_path())));

    // World transforms: root = T(1,2,3) S(2); child = T(0,0,-1) R_y(90).
    let root = Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0)) * Mat4::from_scale(Vec3::splat(2.0));
    let child = Mat4::from_translation(Vec3::new(0.0, 0.0, -1.0)) * Mat4::from_quat(child_rotation());
    let o0 = s.objects[0].transform;
    assert_vec3_near(o0.transform_point3(Vec3::X), Vec3::new(1.0, 2.0, -1.0), "child maps +X");
    assert!(o0.abs_diff_eq(root * child, TRANSFORM_TOLERANCE));
    assert!(s.objects[2].transform.abs_diff_eq(root * Mat4::from_translation(Vec3::X * 5.0), TRANSFORM_TOLERANCE));
    assert_eq!(s.objects[4].transform, Mat4::IDENTITY);

    // Camera on node "cam" under root: eye = root * (0, 1, 10).
    let cam = s.camera.expect("camera");
    assert_vec3_near(cam.eye, Vec3::new(1.0, 4.0, 23.0), "eye");
    assert_vec3_near(cam.target, Vec3::new(1.0, 4.0, 22.0), "target");
    assert_vec3_near(cam.up, Vec3::Y, "up");
    assert!((cam.fov_y_deg - 0.8f32.to_degrees()).abs() < 1e-4, "fov {}", cam.fov_y_deg);
    assert_eq!((cam.near, cam.far), (0.05, 200.0));

    // Lights: the point light at the lamp, the sun pointing down (-Z rotated by -90 about X).
    assert_eq!(s.lights.len(), 2);
    match s.lights[0] {
        Light::Point { position, color, intensity, range } => {
            assert_vec3_near(position, Vec3::new(0.0, 5.0, 0.0), "point light");
            assert_eq!((color, intensity, range), (Vec3::new(1.0, 0.5, 0.25), 40.0, None));
        }
        other => panic!("expected a point light, got {other:?}"),
    }
    match s.lights[1] {
        Light::Directional { direction, color, intensity } => {
            assert_vec3_near(direction, Vec3::NEG_Y, "sun direction");
            assert_eq!((color, intensity), (Vec3::ONE, 3.0));
        }
        other => panic!("expected a directional light, got {other:?}"),
    }

    // The LINES primitive was skipped with one note (not one per instance).
    let lines: Vec<&String> = s.notes.iter().filter(|n| n.contains("primitive 2") && n.contains("skipped")).collect();
    assert_eq!(lines.len(), 1, "notes: {:?}", s.notes);
    assert!(lines[0].contains("tiny.gltf"), "{}", lines[0]);
}

/// `KHR_lights_punctual`'s spot lights and `range`, as the extension defines them: the cone
/// along the node's -Z in world space, its angles in radians as written (glTF's defaults
/// where absent), the range unscaled by the node's scale; a spot light that breaks the
/// extension's rules (outer cone beyond pi/2) is left out with a note naming the node.
#[test]
fn spot_lights_and_ranges_load_as_the_extension_defines_them() {
    let dir = temp_dir("spot_lights_and_ranges_load_as_the_extension_defines_them");
    let mut doc = tiny_doc();
    doc["extensions"]["KHR_lights_punctual"]["lights"] = json!([
        { "type": "point", "intensity": 40.0, "range": 7.5 },
        { "type": "spot", "color": [0.5, 1.0, 1.0], "intensity": 3.0, "range": 12.0,
          "spot": { "innerConeAngle": 0.25, "outerConeAngle": 0.5 } },
        { "type": "spot", "intensity": 1.0, "spot": {} },
        { "type": "spot", "intensity": 1.0, "spot": { "outerConeAngle": 2.0 } }
    ]);
    // The sun node (-Z turned to -Y) carries the first spot; two more nodes the others.
    doc["nodes"][5]["extensions"]["KHR_lights_punctual"]["light"] = json!(1);
    let nodes = doc["nodes"].as_array_mut().unwrap();
    nodes.push(json!({ "name": "default cone", "extensions": { "KHR_lights_punctual": { "light": 2 } } }));
    nodes.push(json!({ "name": "too wide", "extensions": { "KHR_lights_punctual": { "light": 3 } } }));
    doc["scenes"][0]["nodes"].as_array_mut().unwrap().extend([json!(8), json!(9)]);
    let path = dir.join("spots.gltf");
    write_gltf(&path, doc, &tiny_bin());
    let s = Scene::load(&path).unwrap();
    assert_eq!(s.lights.len(), 3, "{:?} {:?}", s.lights, s.notes);
    // The lamp sits under the root node, scaled by 2: its range stays 7.5.
    assert!(matches!(s.lights[0], Light::Point { range: Some(r), .. } if r == 7.5), "{:?}", s.lights[0]);
    match s.lights[1] {
        Light::Spot { position, direction, color, intensity, inner_cone_angle, outer_cone_angle, range } => {
            assert_vec3_near(position, Vec3::ZERO, "spot position");
            assert_vec3_near(direction, Vec3::NEG_Y, "spot direction");
            assert_eq!((color, intensity, range), (Vec3::new(0.5, 1.0, 1.0), 3.0, Some(12.0)));
            assert_eq!((inner_cone_angle, outer_cone_angle), (0.25, 0.5));
        }
        other => panic!("expected a spot light, got {other:?}"),
    }
    match s.lights[2] {
        Light::Spot { direction, inner_cone_angle, outer_cone_angle, range, .. } => {
            assert_vec3_near(direction, Vec3::NEG_Z, "default spot direction");
            assert_eq!((inner_cone_angle, outer_cone_angle, range), (0.0, std::f32::consts::FRAC_PI_4, None));
        }
        other => panic!("expected a spot light, got {other:?}"),
    }
    let ignored: Vec<&String> =
        s.notes.iter().filter(|n| n.contains("too wide") && n.contains("light ignored")).collect();
    assert_eq!(ignored.len(), 1, "notes: {:?}", s.notes);
    assert!(ignored[0].contains("spots.gltf") && ignored[0].contains("cone angles"), "{}", ignored[0]);
}

#[test]
fn glb_and_gltf_forms_load_the_same_scene() {
    let dir = temp_dir("glb_and_gltf_forms_load_the_same_scene");
    let gltf = Scene::load(&write_tiny(&dir)).unwrap();
    let glb_path = dir.join("tiny.glb");
    write_glb(&glb_path, tiny_doc(), &tiny_bin());
    let glb = Scene::load(&glb_path).unwrap();
    assert_eq!(format!("{:?}", gltf.meshes), format!("{:?}", glb.meshes));
    assert_eq!(gltf.materials, glb.materials);
    assert_eq!(gltf.lights, glb.lights);
    assert_eq!(gltf.camera, glb.camera);
    let strip = |s: &Scene| s.objects.iter().map(|o| (o.name.clone(), o.transform, o.render_mode)).collect::<Vec<_>>();
    assert_eq!(strip(&gltf), strip(&glb));
}

#[test]
fn loader_adds_no_camera_or_lights() {
    let dir = temp_dir("loader_adds_no_camera_or_lights");
    let path = triangle_gltf(&dir, "t.gltf", &triangle_bin(TRI, [0, 1, 2]), |_| {});
    let s = Scene::load(&path).unwrap();
    assert_eq!(s.objects.len(), 1);
    assert!(s.camera.is_none());
    assert!(s.lights.is_empty());
    assert!(s.notes.is_empty(), "{:?}", s.notes);
}

#[test]
fn infinite_camera_gets_a_far_plane_from_the_bounds() {
    let dir = temp_dir("infinite_camera_gets_a_far_plane_from_the_bounds");
    let path = triangle_gltf(&dir, "t.gltf", &triangle_bin(TRI, [0, 1, 2]), |doc| {
        doc["nodes"].as_array_mut().unwrap().push(json!({ "translation": [0.0, 0.0, 10.0], "camera": 0 }));
        doc["scenes"][0]["nodes"] = json!([0, 1]);
        doc["cameras"] = json!([{ "type": "perspective", "perspective": { "yfov": 1.0, "znear": 0.1 } }]);
    });
    let s = Scene::load(&path).unwrap();
    let cam = s.camera.unwrap();
    // Farthest corner of the bounds (0..2, 0..2, 0) from (0, 0, 10): sqrt(4 + 4 + 100).
    let expected = 2.0 * 108f32.sqrt();
    assert!((cam.far - expected).abs() < 1e-4, "far {} expected {expected}", cam.far);
    assert!(s.notes.iter().any(|n| n.contains("zfar")), "{:?}", s.notes);
}

#[test]
fn non_finite_positions_load_with_a_note() {
    let dir = temp_dir("non_finite_positions_load_with_a_note");
    let positions = [0.0, 0.0, 0.0, f32::NAN, 0.0, 0.0, 0.0, f32::INFINITY, 0.0];
    let path = triangle_gltf(&dir, "nan.gltf", &triangle_bin(positions, [0, 1, 2]), |_| {});
    let s = Scene::load(&path).unwrap();
    assert_eq!(s.triangle_count(), 1);
    assert!(s.meshes[0].positions[1].x.is_nan());
    assert_eq!(s.world_bounds(), Some((Vec3::ZERO, Vec3::ZERO)), "only the finite vertex counts");
    assert!(s.notes.iter().any(|n| n.contains("2 vertex positions are NaN or infinite")), "{:?}", s.notes);
}

#[test]
fn sparse_accessor_without_buffer_view_is_zeros_plus_substitutions() {
    let dir = temp_dir("sparse_accessor_without_buffer_view_is_zeros_plus_substitutions");
    // Sparse indices (u8) 1 and 2, padded to 4 bytes, then their two VEC3 values.
    let mut bin = vec![1u8, 2, 0, 0];
    push_f32s(&mut bin, &[3.0, 0.0, 0.0, 0.0, 4.0, 0.0]);
    let path = triangle_gltf(&dir, "sparse.gltf", &bin, |doc| {
        doc["meshes"][0]["primitives"][0] = json!({ "attributes": { "POSITION": 0 } });
        doc["accessors"] = json!([{
            "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [3.0, 4.0, 0.0],
            "sparse": { "count": 2,
                "indices": { "bufferView": 0, "componentType": 5121 },
                "values": { "bufferView": 1 } }
        }]);
        doc["bufferViews"] = json!([
            { "buffer": 0, "byteOffset": 0, "byteLength": 2 },
            { "buffer": 0, "byteOffset": 4, "byteLength": 24 }
        ]);
    });
    let s = Scene::load(&path).unwrap();
    assert_eq!(s.meshes[0].positions, vec![Vec3::ZERO, Vec3::new(3.0, 0.0, 0.0), Vec3::new(0.0, 4.0, 0.0)]);
    assert_eq!(s.meshes[0].indices, vec![[0, 1, 2]]);
}

#[test]
fn missing_position_bounds_are_tolerated_with_a_note() {
    let dir = temp_dir("missing_position_bounds_are_tolerated_with_a_note");
    let path = triangle_gltf(&dir, "no_bounds.gltf", &triangle_bin(TRI, [0, 1, 2]), |doc| {
        let acc = doc["accessors"][0].as_object_mut().unwrap();
        acc.remove("min");
        acc.remove("max");
    });
    let s = Scene::load(&path).unwrap();
    assert_eq!(s.triangle_count(), 1);
    assert_eq!(s.notes.len(), 1, "{:?}", s.notes);
    assert!(s.notes[0].contains("no_bounds.gltf") && s.notes[0].contains("min/max"), "{:?}", s.notes);
}

#[test]
fn missing_file_is_an_io_error_naming_the_path() {
    let path = temp_dir("missing_file_is_an_io_error_naming_the_path").join("nowhere.glb");
    let err = Scene::load(&path).unwrap_err();
    assert!(matches!(err, SceneError::Io { .. }), "{err:?}");
    assert!(err.to_string().contains("nowhere.glb"), "{err}");
}

#[test]
fn garbage_bytes_are_a_gltf_error_naming_the_path() {
    let dir = temp_dir("garbage_bytes_are_a_gltf_error_naming_the_path");
    for (name, bytes) in [
        ("garbage.glb", &b"\x00\x01definitely not glTF\xff\xfe"[..]),
        ("garbage.gltf", &b"{ this is not json"[..]),
        ("empty.glb", &b""[..]),
        ("truncated.glb", &b"glTF\x02\x00\x00\x00\xff\x00\x00\x00"[..]),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let err = Scene::load(&path).unwrap_err();
        assert!(matches!(err, SceneError::Gltf { .. }), "{name}: {err:?}");
        assert!(err.to_string().contains(name), "{err}");
    }
}

#[test]
fn index_out_of_range_is_a_content_error() {
    let dir = temp_dir("index_out_of_range_is_a_content_error");
    let path = triangle_gltf(&dir, "bad_index.gltf", &triangle_bin(TRI, [0, 1, 7]), |_| {});
    let err = Scene::load(&path).unwrap_err();
    assert!(matches!(err, SceneError::Content { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("bad_index.gltf") && msg.contains("index 7") && msg.contains("3 vertices"), "{msg}");
}

#[test]
fn missing_position_is_a_content_error() {
    let dir = temp_dir("missing_position_is_a_content_error");
    let path = triangle_gltf(&dir, "no_pos.gltf", &triangle_bin(TRI, [0, 1, 2]), |doc| {
        doc["meshes"][0]["primitives"][0]["attributes"] = json!({ "NORMAL": 0 });
    });
    let err = Scene::load(&path).unwrap_err();
    assert!(matches!(err, SceneError::Content { .. }), "{err:?}");
    assert!(err.to_string().contains("no_pos.gltf") && err.to_string().contains("POSITION"), "{err}");
}

#[test]
fn malformed_layouts_are_errors_not_panics() {
    let dir = temp_dir("malformed_layouts_are_errors_not_panics");
    let bin = triangle_bin(TRI, [0, 1, 2]);
    type Edit = fn(&mut Value);
    let cases: [(&str, Edit); 7] = [
        // The accessor reads past the end of its buffer view.
        ("past_view.gltf", |d| d["accessors"][0]["count"] = json!(4)),
        // The buffer view lies outside the buffer.
        ("past_buffer.gltf", |d| d["bufferViews"][0]["byteOffset"] = json!(40)),
        // A stride smaller than a VEC3 of f32.
        ("small_stride.gltf", |d| d["bufferViews"][0]["byteStride"] = json!(4)),
        // Positions as u16 (KHR_mesh_quantization is not supported).
        ("u16_positions.gltf", |d| d["accessors"][0]["componentType"] = json!(5123)),
        // Index count not a multiple of 3.
        ("two_indices.gltf", |d| d["accessors"][1]["count"] = json!(2)),
        // A reference to an accessor that does not exist.
        ("dangling.gltf", |d| d["meshes"][0]["primitives"][0]["indices"] = json!(9)),
        // A cycle in the node hierarchy.
        ("cycle.gltf", |d| d["nodes"] = json!([{ "mesh": 0, "children": [1] }, { "children": [0] }])),
    ];
    for (name, edit) in cases {
        let path = triangle_gltf(&dir, name, &bin, edit);
        let err = Scene::load(&path).expect_err(name);
        assert!(
            matches!(err, SceneError::Gltf { .. } | SceneError::Content { .. }),
            "{name}: unexpected error kind {err:?}"
        );
        assert!(err.to_string().contains(name), "{err}");
    }
}

#[test]
fn missing_external_buffer_is_an_error_naming_it() {
    let dir = temp_dir("missing_external_buffer_is_an_error_naming_it");
    let doc = json!({
        "asset": { "version": "2.0" },
        "buffers": [{ "byteLength": 48, "uri": "gone.bin" }],
    });
    let path = dir.join("external.gltf");
    std::fs::write(&path, doc.to_string()).unwrap();
    let err = Scene::load(&path).unwrap_err();
    assert!(matches!(err, SceneError::Gltf { .. }), "{err:?}");
    assert!(err.to_string().contains("external.gltf") && err.to_string().contains("gone.bin"), "{err}");
}

#[test]
fn bad_hyrt_extra_is_a_content_error() {
    let dir = temp_dir("bad_hyrt_extra_is_a_content_error");
    let path = triangle_gltf(&dir, "typo.gltf", &triangle_bin(TRI, [0, 1, 2]), |doc| {
        doc["nodes"][0]["extras"] = json!({ "hyrt": { "raytraced": true } });
    });
    let err = Scene::load(&path).unwrap_err();
    assert!(matches!(err, SceneError::Content { .. }), "{err:?}");
    assert!(err.to_string().contains("raytraced"), "{err}");
}

#[test]
fn unknown_extension_is_an_unknown_format_error() {
    let err = Scene::load(Path::new("scene.obj")).unwrap_err();
    assert!(matches!(err, SceneError::UnknownFormat { .. }), "{err:?}");
}

// ---------------------------------------------------------------------------------------------
// Manifest.

/// `dir/models/tiny.gltf` and a manifest `dir/scenes/<name>` holding `text`.
fn manifest_with_tiny(test: &str, text: &str) -> PathBuf {
    let dir = temp_dir(test);
    std::fs::create_dir_all(dir.join("models")).unwrap();
    std::fs::create_dir_all(dir.join("scenes")).unwrap();
    write_tiny(&dir.join("models"));
    let path = dir.join("scenes").join("test.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn manifest_composes_models_with_transforms_and_overrides() {
    let path = manifest_with_tiny(
        "manifest_composes_models_with_transforms_and_overrides",
        r#"
description = "two copies of the tiny file and a floor"

[camera]
eye = [0.0, 2.0, 10.0]
target = [0.0, 0.0, 0.0]
fov_deg = 60.0
near = 0.1
far = 50.0

[[light]]
type = "point"
position = [1.0, 2.0, 3.0]
color = [1.0, 0.5, 0.5]
intensity = 10.0

[[light]]
type = "directional"
direction = [0.0, -2.0, 0.0]
intensity = 0.5

[[model]]
file = "../models/tiny.gltf"
name = "a"

[[model]]
file = "../models/tiny.gltf"
name = "b"
translate = [10.0, 0.0, 0.0]
rotate_deg = [0.0, 90.0, 0.0]
scale = 3.0
render_mode = "raster"
material = { base_color = [0.1, 0.2, 0.3], metallic = 0.0, transmission = 0.0 }

[[model]]
builtin = "grid"
translate = [0.0, -1.0, 0.0]
rotate_axis_angle = { axis = [0.0, 0.0, 2.0], angle_deg = 180.0 }
scale = [20.0, 1.0, 10.0]
material = { metallic = 1.0 }
"#,
    );
    let tiny = Scene::load(&path.parent().unwrap().join("../models/tiny.gltf")).unwrap();
    let s = Scene::load(&path).unwrap();

    // The file is read once: its 3 meshes are shared by both models, plus the grid.
    assert_eq!(s.meshes.len(), 4);
    assert_eq!(s.meshes[3].triangle_count(), 16 * 16 * 2);
    // Materials are per model: 3 + 3 + 1.
    assert_eq!(s.materials.len(), 7);
    assert_eq!(s.objects.len(), 6 + 6 + 1);
    assert!(s.objects.iter().enumerate().all(|(i, o)| o.id as usize == i), "ids renumbered");

    // Model a: as in the file.
    for (o, t) in s.objects[..6].iter().zip(&tiny.objects) {
        assert_eq!(o.name, format!("a/{}", t.name));
        assert_eq!((o.mesh, o.material, o.render_mode, o.transform), (t.mesh, t.material, t.render_mode, t.transform));
        assert_eq!(o.source, t.source);
    }
    // Model b: moved, raster, overridden materials (kind re-derived: all diffuse now).
    let model_b = Mat4::from_scale_rotation_translation(
        Vec3::splat(3.0),
        Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
        Vec3::new(10.0, 0.0, 0.0),
    );
    for (o, t) in s.objects[6..12].iter().zip(&tiny.objects) {
        assert_eq!(o.name, format!("b/{}", t.name));
        assert_eq!(o.mesh, t.mesh, "meshes shared with model a");
        assert_eq!(o.material, 3 + t.material);
        assert_eq!(o.render_mode, RenderMode::Raster);
        assert!(o.transform.abs_diff_eq(model_b * t.transform, TRANSFORM_TOLERANCE), "{}", o.name);
    }
    for m in &s.materials[3..6] {
        assert_eq!(
            (m.base_color, m.metallic, m.transmission, m.kind),
            (Vec3::new(0.1, 0.2, 0.3), 0.0, 0.0, MaterialKind::Diffuse)
        );
    }
    assert_eq!(s.materials[3].roughness, 0.25, "roughness kept from the file");
    assert_eq!(s.materials[4].name, "glass", "name kept from the file");

    // The grid: named after the builtin; metallic override -> specular -> ray traced by default.
    let grid = &s.objects[12];
    assert_eq!(grid.name, "grid");
    assert_eq!(grid.mesh, 3);
    assert_eq!(s.materials[grid.material].kind, MaterialKind::Specular);
    assert_eq!(grid.render_mode, RenderMode::RayTraced);
    assert_eq!(grid.source.file, None);
    // Axis-angle: 180 degrees about Z flips +X to -X and +Y to -Y.
    assert_vec3_near(
        grid.transform.transform_point3(Vec3::new(0.5, 0.0, 0.5)),
        Vec3::new(-10.0, -1.0, 5.0),
        "grid corner",
    );
    assert_vec3_near(grid.transform.transform_vector3(Vec3::Y), Vec3::NEG_Y, "grid normal");

    // Camera and lights from the manifest only (the file's are not used).
    let cam = s.camera.unwrap();
    assert_eq!((cam.eye, cam.target, cam.up), (Vec3::new(0.0, 2.0, 10.0), Vec3::ZERO, Vec3::Y));
    assert_eq!((cam.fov_y_deg, cam.near, cam.far), (60.0, 0.1, 50.0));
    assert_eq!(
        s.lights,
        vec![
            Light::point(Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, 0.5, 0.5), 10.0),
            Light::Directional { direction: Vec3::NEG_Y, color: Vec3::ONE, intensity: 0.5 },
        ]
    );
    // The file's note (the skipped LINES primitive) is kept, once, prefixed with the model.
    assert_eq!(
        s.notes.iter().filter(|n| n.starts_with("model[0] 'a': ") && n.contains("skipped")).count(),
        1,
        "{:?}",
        s.notes
    );
}

#[test]
fn manifest_without_camera_and_lights_uses_the_files() {
    let path = manifest_with_tiny(
        "manifest_without_camera_and_lights_uses_the_files",
        r#"
[[model]]
file = "../models/tiny.gltf"
translate = [0.0, 0.0, -5.0]
scale = 0.5
"#,
    );
    let tiny = Scene::load(&path.parent().unwrap().join("../models/tiny.gltf")).unwrap();
    let s = Scene::load(&path).unwrap();
    let model = Mat4::from_translation(Vec3::new(0.0, 0.0, -5.0)) * Mat4::from_scale(Vec3::splat(0.5));
    let (cam, file_cam) = (s.camera.unwrap(), tiny.camera.unwrap());
    assert_vec3_near(cam.eye, model.transform_point3(file_cam.eye), "eye");
    assert_vec3_near(cam.target, model.transform_point3(file_cam.target), "target");
    assert!((cam.near - file_cam.near * 0.5).abs() < 1e-7 && (cam.far - file_cam.far * 0.5).abs() < 1e-4);
    assert_eq!(s.lights.len(), 2);
    let Light::Point { position, .. } = s.lights[0] else { panic!("{:?}", s.lights[0]) };
    assert_vec3_near(position, Vec3::new(0.0, 2.5, -5.0), "point light moved with the model");
    assert!(s.notes.iter().any(|n| n.contains("camera taken from model[0] 'tiny'")), "{:?}", s.notes);
    assert!(s.objects.iter().all(|o| o.name.starts_with("tiny/")), "default name is the file stem");
}

#[test]
fn manifest_camera_near_and_far_default_from_the_bounds() {
    let path = manifest_with_tiny(
        "manifest_camera_near_and_far_default_from_the_bounds",
        r#"
[camera]
eye = [0.0, 0.0, 10.0]
target = [0.0, 0.0, 0.0]

[[model]]
builtin = "cube"
"#,
    );
    let s = Scene::load(&path).unwrap();
    let cam = s.camera.unwrap();
    // Farthest corner of the cube (-1..1) from (0, 0, 10): sqrt(1 + 1 + 121).
    let far = 2.0 * 123f32.sqrt();
    assert!((cam.far - far).abs() < 1e-4, "far {}", cam.far);
    assert!((cam.near - far / 1000.0).abs() < 1e-7, "near {}", cam.near);
    assert_eq!((cam.up, cam.fov_y_deg), (Vec3::Y, 45.0));
    // One note says which camera, with each value and where it came from.
    assert_eq!(s.notes.len(), 1, "{:?}", s.notes);
    for part in ["the manifest's [camera]", "fov 45 deg", "(not given: far / 1000)", "far 22.1811 (not given: twice"] {
        assert!(s.notes[0].contains(part), "{part}: {:?}", s.notes);
    }
    assert!(s.lights.is_empty());
}

/// A manifest's own `[camera]` over a model file with a camera: the notes say plainly that
/// the manifest's is used (with its values) and the file's is not.
#[test]
fn manifest_camera_over_a_file_camera_says_which_is_used() {
    let path = manifest_with_tiny(
        "manifest_camera_over_a_file_camera_says_which_is_used",
        r#"
[camera]
eye = [0.0, 1.0, 9.0]
target = [0.0, 0.0, 0.0]
fov_deg = 50.0
near = 0.5

[[model]]
file = "../models/tiny.gltf"
"#,
    );
    let s = Scene::load(&path).unwrap();
    let cam = s.camera.unwrap();
    assert_eq!((cam.eye, cam.fov_y_deg, cam.near), (Vec3::new(0.0, 1.0, 9.0), 50.0, 0.5));
    let notes = s.notes.join("\n");
    assert!(!notes.contains("camera taken from"), "{notes}");
    assert!(notes.contains("camera: model[0] 'tiny''s file camera is not used: the manifest's [camera] is"), "{notes}");
    assert!(notes.contains("fov 50 deg, near 0.50000 (given), far"), "{notes}");
}

/// The error for `text` as a manifest next to the tiny model.
fn manifest_error(test: &str, text: &str) -> (PathBuf, SceneError) {
    let path = manifest_with_tiny(test, text);
    let err = Scene::load(&path).expect_err(text);
    (path, err)
}

#[test]
fn manifest_unknown_keys_are_rejected() {
    for (k, text) in [
        "colour = [1, 1, 1]\n[[model]]\nbuiltin = \"cube\"\n",
        "[[model]]\nbuiltin = \"cube\"\nscael = 2.0\n",
        "[[model]]\nbuiltin = \"cube\"\nmaterial = { metalic = 1.0 }\n",
        "[camera]\neye = [0, 0, 1]\ntarget = [0, 0, 0]\nfov = 40\n[[model]]\nbuiltin = \"cube\"\n",
        "[[light]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = 1\nsize = 3\n[[model]]\nbuiltin = \"cube\"\n",
    ]
    .into_iter()
    .enumerate()
    {
        let (path, err) = manifest_error(&format!("manifest_unknown_keys_are_rejected_{k}"), text);
        assert!(matches!(err, SceneError::Manifest { .. }), "{err:?}");
        let msg = err.to_string();
        assert!(msg.contains(&path.display().to_string()) && msg.contains("unknown field"), "{msg}");
    }
}

#[test]
fn manifest_missing_model_file_names_manifest_and_entry() {
    let (path, err) = manifest_error(
        "manifest_missing_model_file_names_manifest_and_entry",
        "[[model]]\nfile = \"../models/tiny.gltf\"\n\n[[model]]\nfile = \"../models/ghost.glb\"\nname = \"bunny\"\n",
    );
    assert!(
        matches!(&err, SceneError::ManifestEntry { error, .. } if matches!(**error, SceneError::Io { .. })),
        "{err:?}"
    );
    let msg = err.to_string();
    assert!(msg.starts_with(&format!("{}: model[1] 'bunny': ", path.display())), "{msg}");
    assert!(msg.contains("ghost.glb") && msg.contains("cannot read file"), "{msg}");
}

#[test]
fn manifest_invalid_entries_are_rejected_with_their_label() {
    let cases = [
        ("[[model]]\nfile = \"../models/tiny.gltf\"\nbuiltin = \"cube\"\n", "model[0] 'tiny': give `file` or `builtin`"),
        ("[[model]]\nname = \"x\"\n", "model[0] 'x': needs `file` or `builtin`"),
        ("[[model]]\nbuiltin = \"cube\"\nrotate_deg = [0, 1, 0]\nrotate_axis_angle = { axis = [0, 1, 0], angle_deg = 3 }\n", "not both"),
        ("[[model]]\nbuiltin = \"cube\"\nscale = [1, 0, 1]\n", "model[0] 'cube': scale"),
        ("[[model]]\nbuiltin = \"cube\"\nmaterial = { metallic = 1.5 }\n", "material.metallic = 1.5"),
        ("[[model]]\nbuiltin = \"cube\"\nmaterial = { ior = 0.5 }\n", "material.ior = 0.5"),
        ("[[model]]\nbuiltin = \"cube\"\nrender_mode = \"raytraced\"\n", "unknown variant `raytraced`"),
        ("[[model]]\nbuiltin = \"cone\"\n", "unknown variant `cone`"),
        ("[[model]]\nbuiltin = \"cube\"\nscale = \"big\"\n", "a number or an array of 3 numbers"),
        ("[[light]]\ntype = \"point\"\ndirection = [0, 1, 0]\nintensity = 1\n[[model]]\nbuiltin = \"cube\"\n", "light[0]: a point light needs `position`"),
        ("[[light]]\ntype = \"directional\"\ndirection = [0, 0, 0]\nintensity = 1\n[[model]]\nbuiltin = \"cube\"\n", "light[0]: direction is zero"),
        ("[camera]\neye = [0, 0, 0]\ntarget = [0, 0, 0]\n[[model]]\nbuiltin = \"cube\"\n", "eye equals target"),
        ("[camera]\neye = [0, 0, 1]\ntarget = [0, 0, 0]\nnear = 1.0\nfar = 0.5\n[[model]]\nbuiltin = \"cube\"\n", "camera.far = 0.5"),
        ("description = \"nothing\"\n", "no [[model]] entries"),
        ("[[model]\n", "TOML parse error"),
    ];
    for (k, (text, expected)) in cases.into_iter().enumerate() {
        let (path, err) = manifest_error(&format!("manifest_invalid_entries_are_rejected_{k}"), text);
        assert!(matches!(err, SceneError::Manifest { .. }), "{text}: {err:?}");
        let msg = err.to_string();
        assert!(
            msg.contains(&path.display().to_string()) && msg.contains(expected),
            "{text}\nexpected '{expected}' in: {msg}"
        );
    }
}

#[test]
fn manifest_errors_inside_a_model_file_name_both_files() {
    let dir = temp_dir("manifest_errors_inside_a_model_file_name_both_files");
    triangle_gltf(&dir, "bad.gltf", &triangle_bin(TRI, [0, 1, 9]), |_| {});
    let manifest = dir.join("m.toml");
    std::fs::write(&manifest, "[[model]]\nfile = \"bad.gltf\"\n").unwrap();
    let err = Scene::load(&manifest).unwrap_err();
    let msg = err.to_string();
    assert!(msg.starts_with(&format!("{}: model[0] 'bad': ", manifest.display())), "{msg}");
    assert!(msg.contains("bad.gltf") && msg.contains("index 9"), "{msg}");
}

// ---------------------------------------------------------------------------------------------
// Shared test models and the example manifests (skipped, with a message, without the folder).

/// `../shared/assets` of the repository, if present.
fn shared_assets() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets");
    if dir.join("bunny.glb").is_file() {
        Some(dir)
    } else {
        eprintln!("{} is absent: shared-asset test skipped", dir.display());
        None
    }
}

fn example_manifest(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes").join(name)
}

/// Normalised device coordinates (x, y) of every finite vertex of `objects`, with the scene camera.
fn ndc_bounds(s: &Scene, objects: impl Fn(&str) -> bool) -> (f32, f32, f32, f32) {
    let vp = s.camera.unwrap().view_projection(1280, 720);
    let (mut x0, mut x1, mut y0, mut y1) = (f32::MAX, f32::MIN, f32::MAX, f32::MIN);
    for o in s.objects.iter().filter(|o| objects(&o.name)) {
        for p in &s.meshes[o.mesh].positions {
            let clip = vp * o.transform.transform_point3(*p).extend(1.0);
            assert!(clip.w > 0.0, "{} has a vertex behind the camera", o.name);
            let ndc = clip.xy() / clip.w;
            (x0, x1, y0, y1) = (x0.min(ndc.x), x1.max(ndc.x), y0.min(ndc.y), y1.max(ndc.y));
        }
    }
    (x0, x1, y0, y1)
}

#[test]
fn shared_models_load_with_their_documented_counts() {
    let Some(dir) = shared_assets() else { return };
    for (file, triangles, vertices) in [
        ("sponza.glb", 66_454, 39_999),
        ("bunny.glb", 69_451, 34_834),
        ("teapot.glb", 6_320, 3_644),
        ("horse.glb", 25_820, 12_912),
        ("hard_dragon_res3.glb", 47_794, 22_998),
        ("hard_cycloidal.glb", 43_368, 21_384),
        ("hard_bunny_far.glb", 69_451, 34_834),
    ] {
        let s = Scene::load(&dir.join(file)).unwrap();
        assert_eq!((s.triangle_count(), s.meshes[0].positions.len()), (triangles, vertices), "{file}");
        assert_eq!(s.objects.len(), 1, "{file}");
        assert_eq!(s.meshes[0].normals.as_ref().map(Vec::len), Some(vertices), "{file}");
        assert_eq!(s.objects[0].render_mode, RenderMode::Raster, "{file}: grey material, no extras");
        assert!(s.camera.is_none() && s.lights.is_empty(), "{file}");
    }
    let bunny = Scene::load(&dir.join("bunny.glb")).unwrap();
    let (lo, hi) = bunny.world_bounds().unwrap();
    assert_eq!((lo, hi), (Vec3::new(-0.0946899, 0.0329874, -0.0618736), Vec3::new(0.0610091, 0.187321, 0.0587997)));
}

#[test]
fn ensure_camera_and_lights_on_the_bunny_adds_camera_lights_and_notes() {
    let Some(dir) = shared_assets() else { return };
    let mut s = Scene::load(&dir.join("bunny.glb")).unwrap();
    assert!(s.notes.is_empty());
    s.ensure_camera_and_lights();
    assert!(s.camera.is_some());
    assert_eq!(s.lights.len(), 2);
    assert!(s.lights.iter().all(|l| matches!(l, Light::Point { .. })));
    assert_eq!(s.notes.len(), 2, "{:?}", s.notes);
    assert!(s.notes[0].contains("no camera") && s.notes[1].contains("no lights"), "{:?}", s.notes);
}

#[test]
fn every_example_manifest_loads() {
    let Some(_) = shared_assets() else { return };
    let dir = example_manifest("");
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    names.sort();
    assert!(names.len() >= 6, "{names:?}");
    for path in names {
        let s = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert!(s.camera.is_some(), "{}: camera", path.display());
        // Lights, or emissive meshes that are (`emissive_lights = true`).
        assert!(!s.lights.is_empty() || s.emissive_lights, "{}: lights", path.display());
        assert!(s.triangle_count() > 0);
        assert!(s.objects.iter().any(|o| o.render_mode == RenderMode::RayTraced), "{}", path.display());
    }
}

#[test]
fn teaser_places_a_golden_bunny_on_the_sponza_floor_in_view() {
    let Some(_) = shared_assets() else { return };
    let s = Scene::load(&example_manifest("teaser.toml")).unwrap();
    assert_eq!(s.triangle_count(), 66_454 + 69_451);
    let sponza = s.objects.iter().find(|o| o.name.starts_with("sponza/")).unwrap();
    let bunny = s.objects.iter().find(|o| o.name.starts_with("bunny/")).unwrap();
    assert_eq!((sponza.render_mode, bunny.render_mode), (RenderMode::Raster, RenderMode::RayTraced));
    assert_eq!(s.materials[bunny.material].kind, MaterialKind::Specular);
    assert_eq!(s.materials[sponza.material].kind, MaterialKind::Diffuse);

    // The bunny stands on the courtyard floor (upper surface y = 0.0933), centred, 3.86 m tall.
    let (mut lo, mut hi) = (Vec3::MAX, Vec3::MIN);
    for p in &s.meshes[bunny.mesh].positions {
        let w = bunny.transform.transform_point3(*p);
        (lo, hi) = (lo.min(w), hi.max(w));
    }
    assert!((lo.y - 0.0933).abs() < 1e-3, "bunny base at {}", lo.y);
    assert!((hi.y - lo.y - 3.858).abs() < 1e-2 && lo.x.abs() < 2.0 && hi.x.abs() < 2.0, "{lo} {hi}");

    // The camera sees the whole bunny, at a good size.
    let (x0, x1, y0, y1) = ndc_bounds(&s, |n| n.starts_with("bunny/"));
    assert!(x0 > -1.0 && x1 < 1.0 && y0 > -1.0 && y1 < 1.0, "bunny NDC bounds {x0} {x1} {y0} {y1}");
    assert!((y1 - y0) / 2.0 > 0.3, "bunny height fraction {}", (y1 - y0) / 2.0);

    // Nothing of Sponza stands between the eye and the bunny's centre, nor the lights and its top.
    let centre = (lo + hi) * 0.5;
    let top = Vec3::new(centre.x, hi.y - 0.3, centre.z);
    let eye = s.camera.unwrap().eye;
    let lights: Vec<Vec3> = s
        .lights
        .iter()
        .filter_map(|l| match l {
            Light::Point { position, .. } => Some(*position),
            _ => None,
        })
        .collect();
    let mesh = &s.meshes[sponza.mesh];
    for (from, to, what) in [(eye, centre, "camera")].into_iter().chain(lights.iter().map(|&l| (l, top, "light"))) {
        let blocked = mesh.indices.iter().any(|t| {
            let [a, b, c] = t.map(|i| sponza.transform.transform_point3(mesh.positions[i as usize]));
            segment_hits_triangle(from, to, a, b, c)
        });
        assert!(!blocked, "Sponza blocks the {what} at {from}");
    }
}

/// Möller-Trumbore on the open segment `p..q` (test helper, not the renderer's kernel).
fn segment_hits_triangle(p: Vec3, q: Vec3, a: Vec3, b: Vec3, c: Vec3) -> bool {
    let d = q - p;
    let (e1, e2) = (b - a, c - a);
    let h = d.cross(e2);
    let det = e1.dot(h);
    if det.abs() < 1e-12 {
        return false;
    }
    let s = p - a;
    let u = s.dot(h) / det;
    let qv = s.cross(e1);
    let v = d.dot(qv) / det;
    let t = e2.dot(qv) / det;
    u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 1e-4 && t < 1.0 - 1e-4
}

#[test]
fn near_and_far_manifests_frame_their_model_large_and_small() {
    let Some(_) = shared_assets() else { return };
    for (file, model, min_height, max_height) in [
        // Near and far as the paper's Table 2 frames them (its valid-ray counts: the
        // exact check is hyrt's `paper_manifests_reproduce_table2_valid_rays`).
        ("bunny_near.toml", "bunny/", 0.4, 0.7),
        ("horse_near.toml", "horse/", 0.4, 0.7),
        ("dragon.toml", "dragon/", 0.4, 0.95),
        ("bunny_far.toml", "bunny/", 0.15, 0.45),
        ("horse_far.toml", "horse/", 0.03, 0.2),
    ] {
        let s = Scene::load(&example_manifest(file)).unwrap();
        let (x0, x1, y0, y1) = ndc_bounds(&s, |n| n.starts_with(model));
        assert!(x0 > -1.0 && x1 < 1.0 && y0 > -1.0 && y1 < 1.0, "{file}: NDC bounds {x0} {x1} {y0} {y1}");
        let height = (y1 - y0) / 2.0;
        assert!((min_height..=max_height).contains(&height), "{file}: height fraction {height}");
    }
    // The horse stands upright: after the manifest's rotation it is taller than wide and its
    // hooves are on y = 0.
    let s = Scene::load(&example_manifest("horse_near.toml")).unwrap();
    let (lo, hi) = s.world_bounds().unwrap();
    assert!(lo.y.abs() < 1e-3 && hi.y - lo.y > hi.x - lo.x, "{lo} {hi}");
    assert!(hi.z - lo.z > hi.y - lo.y, "head to tail along Z: {lo} {hi}");
}

/// `repeat` places a grid of copies sharing the model's mesh, x fastest, each moved by its
/// step after the model's own transform; bad counts and steps are errors naming the model.
#[test]
fn manifest_repeat_places_copies_sharing_one_mesh() {
    let dir = temp_dir("manifest_repeat_places_copies_sharing_one_mesh");
    let path = dir.join("grid.toml");
    std::fs::write(
        &path,
        "[[model]]\nbuiltin = \"cube\"\nname = \"box\"\ntranslate = [1.0, 0.0, 0.0]\nscale = 0.5\n\
         repeat = { count = [3, 1, 2], step = [2.0, 0.0, -1.0] }\n\
         [[model]]\nbuiltin = \"grid\"\n",
    )
    .unwrap();
    let s = Scene::load(&path).unwrap();
    assert_eq!(s.objects.len(), 7);
    let boxes: Vec<_> = s.objects.iter().filter(|o| o.name.starts_with("box#")).collect();
    assert_eq!(boxes.len(), 6);
    assert!(boxes.iter().all(|o| o.mesh == boxes[0].mesh), "one mesh for every copy");
    assert_eq!(boxes[4].name, "box#4");
    // Copy 4 is (i, j, k) = (1, 0, 1): the model's origin (1, 0, 0) moved by (2, 0, -1).
    let origin = boxes[4].transform.transform_point3(Vec3::ZERO);
    assert_eq!(origin, Vec3::new(3.0, 0.0, -1.0));
    assert_eq!(boxes[4].transform.transform_vector3(Vec3::X), Vec3::new(0.5, 0.0, 0.0));
    for (bad, says) in [
        ("count = [0, 1, 1], step = [1.0, 0.0, 0.0]", "repeat.count"),
        ("count = [2048, 1024, 1], step = [1.0, 0.0, 0.0]", "repeat.count"),
        ("count = [2, 1, 1], step = [1.0, nan, 0.0]", "repeat.step"),
    ] {
        std::fs::write(&path, format!("[[model]]\nbuiltin = \"cube\"\nrepeat = {{ {bad} }}\n")).unwrap();
        let e = Scene::load(&path).unwrap_err().to_string();
        assert!(e.contains(says) && e.contains("model[0]"), "{bad}: {e}");
    }
}
