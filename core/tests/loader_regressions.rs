//! Inputs the loader fuzzer (`fuzz/harness.rs`) found crashing a loader, minimized, and the
//! plain refusals of what hyrt does not read (glTF 1.0, Draco). Each must give an error that
//! names the file and the problem, loaded alone and through a one-model manifest (whose
//! error names the manifest, the entry and the file too). And textured models through
//! manifests (issue 34: a manifest kept a file's textured materials but not its images, and
//! the renderer indexed past the scene's textures): a bad image is an error naming the
//! manifest, the entry and the file; merged models keep every model's textures.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use hyrt_core::geometry::WorldGeometry;
use hyrt_core::scene::Scene;

// The fuzz harness's file builders; its allocator is not installed.
#[path = "../fuzz/harness.rs"]
mod harness;
use harness::glb;

/// The one-model manifest [`refusals`] writes beside a glTF or GLB input.
const WRAPPER: &str = "wrapper.toml";

/// The message of the error loading `path` from `files`, which must name each of `names`.
fn refused(path: &Path, files: &HashMap<PathBuf, Vec<u8>>, names: &[&Path]) -> String {
    let message = match Scene::load_from(path, files) {
        Ok(_) => panic!("{} loaded", path.display()),
        Err(e) => e.to_string(),
    };
    for name in names {
        assert!(message.contains(&name.display().to_string()), "the error does not name {}: {message}", name.display());
    }
    message
}

/// Load `bytes` as the file `name` (in memory) and, a glTF or GLB file, through a one-model
/// manifest beside it ([`WRAPPER`]); the errors' messages, the file's first.
fn refusals(name: &str, bytes: &[u8]) -> Vec<String> {
    let path = PathBuf::from("/mem").join(name);
    let mut files = HashMap::from([(path.clone(), bytes.to_vec())]);
    let mut messages = vec![refused(&path, &files, &[&path])];
    if path.extension().is_some_and(|e| e == "gltf" || e == "glb") {
        let manifest = path.with_file_name(WRAPPER);
        files.insert(manifest.clone(), format!("[[model]]\nfile = \"{name}\"\n").into_bytes());
        let message = refused(&manifest, &files, &[&manifest, &path]);
        assert!(message.contains("model[0]"), "the error does not name the manifest's entry: {message}");
        messages.push(message);
    }
    messages
}

/// [`refusals`] of `bytes` as the file `name`, each message saying each of `problems`.
fn refused_with(name: &str, bytes: &[u8], problems: &[&str]) {
    for message in refusals(name, bytes) {
        for problem in problems {
            assert!(message.contains(problem), "the error does not say '{problem}': {message}");
        }
    }
}

#[test]
fn position_accessor_index_out_of_range_is_an_error_not_a_panic() {
    // Fuzz seed 16, execution 2274 (a mutated sponza.glb): gltf-json's validation indexed
    // the accessors by the POSITION index before checking it.
    let json = r#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":4}}]}],
                   "accessors":[{"componentType":5126,"count":3,"type":"VEC3"}]}"#;
    refused_with("bad_position.gltf", json.as_bytes(), &["POSITION", "accessor 4 does not exist"]);
    refusals("bad_position.glb", &glb(json.as_bytes(), None));
}

#[test]
fn gltf_1_files_say_so() {
    let json = r#"{"asset":{"version":"1.0"},"meshes":{"m":{"primitives":[]}},"nodes":{}}"#;
    refused_with("old.gltf", json.as_bytes(), &["glTF 1.0", "2.0 only"]);
    // Version 1.0 written as 1.x but deserializing as 2.0 would.
    let shaped_as_2 = r#"{"asset":{"version":"1.1"}}"#;
    refused_with("old2.gltf", shaped_as_2.as_bytes(), &["glTF 1.1"]);
    // Keyed objects without a version: still 1.0's shape.
    refused_with("old3.gltf", br#"{"asset":{},"accessors":{"a":{}}}"#, &["glTF 1.0"]);
    // KHR_binary_glTF: a GLB of version 1.
    let mut binary = glb(json.as_bytes(), None);
    binary[4] = 1;
    refused_with("old.glb", &binary, &["glTF 1.0 binary"]);
    refused_with("future.gltf", br#"{"asset":{"version":"3.0"}}"#, &["asset.version is '3.0'"]);
}

#[test]
fn draco_compressed_meshes_say_so() {
    let required = r#"{"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],
                       "extensionsRequired":["KHR_draco_mesh_compression"]}"#;
    refused_with("draco.glb", &glb(required.as_bytes(), None), &["Draco-compressed"]);
    // Used but not required: primitives whose positions only the extension holds.
    let used = r#"{"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],
                   "scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
                   "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
                   "accessors":[{"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,1]}]}"#;
    refused_with("draco_used.gltf", used.as_bytes(), &["Draco-compressed", "accessors[0].bufferView"]);
}

#[test]
fn glb_headers_that_lie_are_errors() {
    let good = glb(br#"{"asset":{"version":"2.0"}}"#, None);
    for (at, value, problem) in [
        (8usize, 4u32, "GLB header declares 4 bytes"),
        (8, 0xffff_ffff, "GLB header declares"),
        (12, 0xffff_fff0, "JSON chunk declares"),
        (16, u32::from_le_bytes(*b"BIN\0"), "where the JSON chunk belongs"),
    ] {
        let mut bytes = good.clone();
        bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
        refused_with("lying.glb", &bytes, &[problem]);
    }
    refused_with("short.glb", b"glTF\x02\0", &["GLB header truncated"]);
}

#[test]
fn many_instances_of_a_large_mesh_exceed_the_budget_instead_of_memory() {
    // A sparse accessor without a buffer view (zeros but for one position) of 2^22 - 1
    // positions, instanced by 100 primitives: 100 x 48 MiB from a few kilobytes of JSON.
    let primitives = vec![r#"{"attributes":{"POSITION":0}}"#; 100].join(",");
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
            "meshes":[{{"primitives":[{primitives}]}}],
            "accessors":[{{"componentType":5126,"count":4194303,"type":"VEC3","min":[0,0,0],"max":[0,0,0],
                "sparse":{{"count":1,"indices":{{"bufferView":0,"componentType":5121}},"values":{{"bufferView":0}}}}}}],
            "bufferViews":[{{"buffer":0,"byteLength":12}}],
            "buffers":[{{"byteLength":12,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAA"}}]}}"#
    );
    refused_with("amplified.gltf", json.as_bytes(), &["budget"]);
}

#[test]
fn missing_model_and_buffer_files_name_the_file() {
    let manifest = "[[model]]\nfile = \"nowhere.glb\"\n";
    refused_with("scene.toml", manifest.as_bytes(), &["nowhere.glb", "model[0]"]);
    let gltf = r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":4,"uri":"gone%20away.bin"}]}"#;
    refused_with("external.gltf", gltf.as_bytes(), &[&Path::new("/mem").join("gone away.bin").display().to_string()]);
}

#[test]
fn an_openexr_header_claiming_huge_tiles_is_refused_before_decoding() {
    // Fuzz seed 1, execution 484588 (a mutated environment map of the built-in seeds): 604
    // bytes whose header gives a 10682432 x 64 tile; the `exr` crate sized its block buffer
    // from it and asked for 1.7 GB before reading a pixel.
    let path = PathBuf::from("/mem/sky.exr");
    let bytes = include_bytes!("fuzz_inputs/exr_huge_tile.exr").to_vec();
    let mut files = HashMap::from([(path.clone(), bytes)]);
    let message = hyrt_core::scene::Environment::load_from(&path, &files).unwrap_err().to_string();
    assert!(message.contains("/mem/sky.exr"), "the error does not name the file: {message}");
    assert!(message.contains("10682432x64 block") && message.contains("536870912 bytes"), "{message}");
    // As a manifest's environment map.
    let manifest = path.with_file_name(WRAPPER);
    files.insert(manifest.clone(), b"environment = \"sky.exr\"\n\n[[model]]\nbuiltin = \"cube\"\n".to_vec());
    let message = refused(&manifest, &files, &[&manifest, &path]);
    assert!(message.contains("environment") && message.contains("10682432x64 block"), "{message}");
}

/// The seed of the fuzz harness's [`harness::built_seeds`] loading `name` (in `/fuzz`).
fn built(name: &str) -> harness::Seed {
    let seeds = harness::built_seeds();
    seeds.into_iter().find(|s| s.main.file_name().is_some_and(|n| n == name)).unwrap_or_else(|| panic!("no {name}"))
}

/// `files` with the manifest `text` beside `beside` (as [`WRAPPER`]); the manifest's path.
fn with_manifest(files: &mut HashMap<PathBuf, Vec<u8>>, beside: &Path, text: &str) -> PathBuf {
    let manifest = beside.with_file_name(WRAPPER);
    files.insert(manifest.clone(), text.as_bytes().to_vec());
    manifest
}

#[test]
fn a_textured_model_with_a_bad_image_through_a_manifest_names_the_manifest_the_entry_and_the_file() {
    // `textured.gltf` samples `wall a.png` beside it (image 0) and a JPEG data URI; every
    // message names the image as well as the files.
    let gltf = built("textured.gltf");
    let png = gltf.main.with_file_name("wall a.png");
    let good_png = gltf.files[&png].clone();
    for (what, image, problem) in [
        ("missing", None, format!("cannot read '{}'", png.display())),
        // The PNG decoder's words.
        ("truncated", Some(good_png[..good_png.len() / 2].to_vec()), "unexpected end of file".into()),
        ("not an image", Some(b"not a PNG".to_vec()), "neither a PNG nor a JPEG".into()),
    ] {
        let mut files = gltf.files.clone();
        match image {
            Some(bytes) => files.insert(png.clone(), bytes),
            None => files.remove(&png),
        };
        let manifest = with_manifest(&mut files, &gltf.main, "[[model]]\nfile = \"textured.gltf\"\n");
        let message = refused(&manifest, &files, &[&manifest, &gltf.main]);
        assert!(
            message.contains("model[0]") && message.contains("image 0") && message.contains(&problem),
            "{what}: {message}"
        );
        // The second of two models: its entry is named, not the first's.
        files.extend(built("textured.glb").files);
        let two = "[[model]]\nfile = \"textured.glb\"\n\n[[model]]\nfile = \"textured.gltf\"\n";
        let manifest = with_manifest(&mut files, &gltf.main, two);
        let message = refused(&manifest, &files, &[&manifest, &gltf.main]);
        assert!(
            message.contains("model[1]") && !message.contains("model[0]") && message.contains(&problem),
            "{what}: {message}"
        );
    }
    // A GLB whose embedded PNG (a buffer view) lost its signature.
    let mut glb = built("textured.glb");
    let bytes = glb.files.get_mut(&glb.main).expect("the GLB");
    let at = bytes.windows(4).position(|w| w == b"\x89PNG").expect("the embedded PNG");
    bytes[at..at + 8].fill(0);
    let manifest = with_manifest(&mut glb.files, &glb.main, "[[model]]\nfile = \"textured.glb\"\n");
    let message = refused(&manifest, &glb.files, &[&manifest, &glb.main]);
    assert!(message.contains("model[0]") && message.contains("image 0"), "{message}");
}

/// Objects of [`harness::textured_json`] with a base-colour texture: the quad's triangles and
/// the second mesh (its line primitive is skipped).
const TEXTURED_OBJECTS_PER_FILE: usize = 2;

#[test]
fn manifests_merging_textured_models_keep_every_models_textures() {
    let (gltf, glb) = (built("textured.gltf"), built("textured.glb"));
    let alone = |seed: &harness::Seed| Scene::load_from(&seed.main, &seed.files).unwrap_or_else(|e| panic!("{e}"));
    let files_alone = [(gltf.main.clone(), alone(&gltf)), (glb.main.clone(), alone(&glb))];
    let mut files = gltf.files.clone();
    files.extend(glb.files.clone());
    for (text, distinct_files) in [
        (
            "[[model]]\nfile = \"textured.glb\"\n\n[[model]]\nfile = \"textured.gltf\"\ntranslate = [2.0, 0.0, 0.0]\n",
            true,
        ),
        (
            "[[model]]\nfile = \"textured.gltf\"\nrepeat = { count = [2, 1, 1], step = [3.0, 0.0, 0.0] }\n\n\
             [[model]]\nbuiltin = \"cube\"\n\n[[model]]\nfile = \"textured.glb\"\nmaterial = { roughness = 0.5 }\n",
            true,
        ),
        // One file twice: whether its images are kept once or twice, each model samples them.
        ("[[model]]\nfile = \"textured.glb\"\n\n[[model]]\nfile = \"textured.glb\"\nscale = 2.0\n", false),
    ] {
        let manifest = with_manifest(&mut files, &gltf.main, text);
        let scene = Scene::load_from(&manifest, &files).unwrap_or_else(|e| panic!("{e}"));
        if distinct_files {
            let sum: usize = files_alone.iter().map(|(_, s)| s.textures.len()).sum();
            assert_eq!(scene.textures.len(), sum, "{text}");
        }
        // What the renderer indexes without checks: every material's image is in the scene.
        assert_eq!(harness::inconsistency(&scene), None, "{text}");
        // Every object of a file samples the image it samples in the file alone.
        let mut textured_objects = 0;
        for object in &scene.objects {
            let Some(file) = &object.source.file else { continue };
            let (_, source) = files_alone.iter().find(|(p, _)| p == file).expect("a file of the manifest");
            let original = source.objects.iter().find(|o| o.source == object.source).expect("the file's object");
            let binding = |s: &Scene, material: usize| s.materials[material].base_color_texture.map(|t| t.image);
            let (image, original_image) = (binding(&scene, object.material), binding(source, original.material));
            assert_eq!(image.is_some(), original_image.is_some(), "{}", object.name);
            if let (Some(i), Some(j)) = (image, original_image) {
                assert_eq!(
                    *scene.textures[i], *source.textures[j],
                    "{}: image {i} against {j} of the file",
                    object.name
                );
                textured_objects += 1;
            }
        }
        // Each manifest places two textured models at least.
        assert!(textured_objects >= 2 * TEXTURED_OBJECTS_PER_FILE, "{text}: {textured_objects} textured objects");
        // What the renderer does next (issue 34 panicked here, indexing the textures).
        WorldGeometry::build(&scene);
    }
}
