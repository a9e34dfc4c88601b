//! Inputs the loader fuzzer (`fuzz/harness.rs`) found crashing a loader, minimized, and the
//! plain refusals of what hyrt does not read (glTF 1.0, Draco). Each must give an error that
//! names the file and the problem.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use hyrt_core::scene::Scene;

/// Load `bytes` as the file `name` (in memory) and return the error's message.
fn refusal(name: &str, bytes: &[u8]) -> String {
    let path = PathBuf::from("/mem").join(name);
    let files = HashMap::from([(path.clone(), bytes.to_vec())]);
    let message = match Scene::load_from(&path, &files) {
        Ok(_) => panic!("{name} loaded"),
        Err(e) => e.to_string(),
    };
    assert!(message.contains(&path.display().to_string()), "the error does not name the file: {message}");
    message
}

/// A GLB container around `json` (no binary chunk).
fn glb(json: &str) -> Vec<u8> {
    let mut json = json.as_bytes().to_vec();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend((20 + json.len() as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(json);
    out
}

#[test]
fn position_accessor_index_out_of_range_is_an_error_not_a_panic() {
    // Fuzz seed 16, execution 2274 (a mutated sponza.glb): gltf-json's validation indexed
    // the accessors by the POSITION index before checking it.
    let json = r#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":4}}]}],
                   "accessors":[{"componentType":5126,"count":3,"type":"VEC3"}]}"#;
    let message = refusal("bad_position.gltf", json.as_bytes());
    assert!(message.contains("POSITION") && message.contains("accessor 4 does not exist"), "{message}");
    refusal("bad_position.glb", &glb(json));
}

#[test]
fn gltf_1_files_say_so() {
    let json = r#"{"asset":{"version":"1.0"},"meshes":{"m":{"primitives":[]}},"nodes":{}}"#;
    let message = refusal("old.gltf", json.as_bytes());
    assert!(message.contains("glTF 1.0") && message.contains("2.0 only"), "{message}");
    // Version 1.0 written as 1.x but deserializing as 2.0 would.
    let shaped_as_2 = r#"{"asset":{"version":"1.1"}}"#;
    assert!(refusal("old2.gltf", shaped_as_2.as_bytes()).contains("glTF 1.1"));
    // Keyed objects without a version: still 1.0's shape.
    assert!(refusal("old3.gltf", br#"{"asset":{},"accessors":{"a":{}}}"#).contains("glTF 1.0"));
    // KHR_binary_glTF: a GLB of version 1.
    let mut binary = glb(json);
    binary[4] = 1;
    assert!(refusal("old.glb", &binary).contains("glTF 1.0 binary"));
    assert!(refusal("future.gltf", br#"{"asset":{"version":"3.0"}}"#).contains("asset.version is '3.0'"));
}

#[test]
fn draco_compressed_meshes_say_so() {
    let required = r#"{"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],
                       "extensionsRequired":["KHR_draco_mesh_compression"]}"#;
    assert!(refusal("draco.glb", &glb(required)).contains("Draco-compressed"));
    // Used but not required: primitives whose positions only the extension holds.
    let used = r#"{"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],
                   "scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
                   "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
                   "accessors":[{"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,1]}]}"#;
    let message = refusal("draco_used.gltf", used.as_bytes());
    assert!(message.contains("Draco-compressed") && message.contains("accessors[0].bufferView"), "{message}");
}

#[test]
fn glb_headers_that_lie_are_errors() {
    let good = glb(r#"{"asset":{"version":"2.0"}}"#);
    for (at, value, problem) in [
        (8usize, 4u32, "GLB header declares 4 bytes"),
        (8, 0xffff_ffff, "GLB header declares"),
        (12, 0xffff_fff0, "JSON chunk declares"),
        (16, u32::from_le_bytes(*b"BIN\0"), "where the JSON chunk belongs"),
    ] {
        let mut bytes = good.clone();
        bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
        let message = refusal("lying.glb", &bytes);
        assert!(message.contains(problem), "{message}");
    }
    assert!(refusal("short.glb", b"glTF\x02\0").contains("GLB header truncated"));
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
    let message = refusal("amplified.gltf", json.as_bytes());
    assert!(message.contains("budget"), "{message}");
}

#[test]
fn missing_model_and_buffer_files_name_the_file() {
    let manifest = "[[model]]\nfile = \"nowhere.glb\"\n";
    let message = refusal("scene.toml", manifest.as_bytes());
    assert!(message.contains("nowhere.glb") && message.contains("model[0]"), "{message}");
    let gltf = r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":4,"uri":"gone%20away.bin"}]}"#;
    let message = refusal("external.gltf", gltf.as_bytes());
    assert!(message.contains(&Path::new("/mem").join("gone away.bin").display().to_string()), "{message}");
}

#[test]
fn an_openexr_header_claiming_huge_tiles_is_refused_before_decoding() {
    // Fuzz seed 1, execution 484588 (a mutated environment map of the built-in seeds): 604
    // bytes whose header gives a 10682432 x 64 tile; the `exr` crate sized its block buffer
    // from it and asked for 1.7 GB before reading a pixel.
    let path = PathBuf::from("/mem/sky.exr");
    let bytes = include_bytes!("fuzz_inputs/exr_huge_tile.exr").to_vec();
    let files = HashMap::from([(path.clone(), bytes)]);
    let message = hyrt_core::scene::Environment::load_from(&path, &files).unwrap_err().to_string();
    assert!(message.contains("/mem/sky.exr"), "the error does not name the file: {message}");
    assert!(message.contains("10682432x64 block") && message.contains("536870912 bytes"), "{message}");
}
