//! A mutation fuzzer over the scene loaders: glTF/GLB (`Scene::load_from`), TOML manifests
//! and environment maps (`Environment::load_from`), all from files held in memory.
//!
//! Each execution `n` of a run with seed `s` is a pure function of `(s, n)`: it picks a seed
//! input (real files from `shared/assets`, the repository's manifests and sample glTF files,
//! and small files built here), applies one to four mutations (byte-level, or
//! structure-aware: the GLB container, its JSON as JSON, the manifest as TOML, the image
//! headers) and loads the result; a glTF or GLB input is loaded through two manifests as
//! well ([`through_manifests`]): one naming it alone, one merging it with a textured model.
//! An execution fails when a load panics, runs past [`EXEC_TIME_LIMIT`], allocates past
//! [`ALLOC_LIMIT_BYTES`] live bytes, gives a scene that refers past its own tables
//! ([`inconsistency`]), or returns an error whose message does not name the file (through a
//! manifest: the manifest, and the model file an entry fails on). Shared by
//! `tests/fuzz_loaders.rs` (a short run in `cargo test`) and `examples/fuzz_loaders.rs`
//! (long runs; `--only N` writes execution N's files to disk).
//!
//! The including crate root must declare `#[global_allocator] static A: harness::Counting`.

#![allow(dead_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::collections::HashMap;
use std::io::Write;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use hyrt_core::scene::{Environment, Scene};
use hyrt_core::SceneError;
use serde_json::{json, Value};

/// The longest one load of an execution may take. The largest seed (a 1.7 MB GLB) loads in
/// well under a second in a debug-assertions build; 20 s leaves room for a loaded machine.
pub const EXEC_TIME_LIMIT: Duration = Duration::from_secs(20);

/// The most live heap one execution may add. Loaders budget decoded data at 64 MiB plus
/// 16 bytes per input byte (a few MB here) and the image decoders refuse more than 512 MiB
/// per image (the `image` crate's default limit), converted once to RGBA f32 (4/3 of it):
/// 1.5 GiB is above any legitimate peak and far below what an unbounded allocation reaches.
pub const ALLOC_LIMIT_BYTES: usize = 3 << 29;

/// Real seed files larger than this are not used: every execution on them parses them whole.
const MAX_REAL_SEED_BYTES: u64 = 2 << 20;

/// A global allocator counting live bytes; past [`ALLOC_LIMIT_BYTES`] above the execution's
/// starting point it reports the execution and aborts (no unwinding out of an allocator).
pub struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static BASELINE: AtomicUsize = AtomicUsize::new(usize::MAX);
static CURRENT_EXEC: AtomicU64 = AtomicU64::new(u64::MAX);
static CURRENT_SEED: AtomicU64 = AtomicU64::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        over_limit(layout.size());
        System.alloc(layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        over_limit(layout.size());
        System.alloc_zeroed(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > layout.size() {
            over_limit(new_size - layout.size());
        } else {
            LIVE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
        }
        System.realloc(ptr, layout, new_size)
    }
}

fn over_limit(size: usize) {
    let live = LIVE.fetch_add(size, Ordering::Relaxed) + size;
    let base = BASELINE.load(Ordering::Relaxed);
    if base != usize::MAX && live > base.saturating_add(ALLOC_LIMIT_BYTES) {
        die("allocation limit exceeded", size);
    }
}

/// Report the execution being run and abort, without allocating.
fn die(what: &str, size: usize) -> ! {
    let mut buf = [0u8; 256];
    let mut cursor = std::io::Cursor::new(&mut buf[..]);
    let _ = write!(
        cursor,
        "\nfuzz_loaders: {what} (request {size} bytes) in execution {} of seed {}; reproduce with \
         `cargo run --release -p hyrt-core --example fuzz_loaders -- --seed {} --only {}`\n",
        CURRENT_EXEC.load(Ordering::Relaxed),
        CURRENT_SEED.load(Ordering::Relaxed),
        CURRENT_SEED.load(Ordering::Relaxed),
        CURRENT_EXEC.load(Ordering::Relaxed),
    );
    let n = cursor.position() as usize;
    let _ = std::io::stderr().write_all(&buf[..n]);
    std::process::abort()
}

/// splitmix64: small, fast, and every execution's generator is seeded independently.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    pub fn chance(&mut self, percent: usize) -> bool {
        self.below(100) < percent
    }
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// What a seed is, deciding how it is loaded and mutated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    Glb,
    Gltf,
    Manifest,
    Image,
}

/// One input: the file to load and the files it may refer to, in memory.
#[derive(Clone)]
pub struct Seed {
    pub kind: Kind,
    pub main: PathBuf,
    pub files: HashMap<PathBuf, Vec<u8>>,
}

/// Where the in-memory files live (no such folder is read: every file is in the map).
const ROOT: &str = "/fuzz";

pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A GLB container around `json` and `bin`, lengths and padding as the specification says.
pub fn glb(json: &[u8], bin: Option<&[u8]>) -> Vec<u8> {
    let pad = |n: usize| (4 - n % 4) % 4;
    let mut json = json.to_vec();
    json.extend(std::iter::repeat_n(b' ', pad(json.len())));
    let mut body = Vec::new();
    body.extend((json.len() as u32).to_le_bytes());
    body.extend(b"JSON");
    body.extend(&json);
    if let Some(bin) = bin {
        let mut bin = bin.to_vec();
        bin.extend(std::iter::repeat_n(0, pad(bin.len())));
        body.extend((bin.len() as u32).to_le_bytes());
        body.extend(b"BIN\0");
        body.extend(&bin);
    }
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend(((12 + body.len()) as u32).to_le_bytes());
    out.extend(body);
    out
}

/// The binary buffer of the small scene: a quad (4 positions, 4 normals, 6 u16 indices)
/// and a sparse substitution (one u8 index, one position).
pub fn small_bin() -> Vec<u8> {
    let mut bin = Vec::new();
    for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]] {
        bin.extend(p.iter().flat_map(|c| c.to_le_bytes()));
    }
    for _ in 0..4 {
        bin.extend([0.0f32, 0.0, 1.0].iter().flat_map(|c| c.to_le_bytes()));
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend(i.to_le_bytes());
    }
    bin.extend([2u8, 0, 0, 0]);
    bin.extend([1.0f32, 2.0, 0.0].iter().flat_map(|c| c.to_le_bytes()));
    bin
}

/// The JSON of the small scene over [`small_bin`] (108 bytes): two meshes, a hierarchy, a
/// camera, two lights, materials with the extensions hyrt reads, `hyrt` extras, a sparse
/// accessor, a primitive without indices and a line primitive.
pub fn small_json(buffer: Value) -> Value {
    json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "color": [1.0, 0.9, 0.8], "intensity": 20.0, "range": 5.0},
            {"type": "spot", "intensity": 3.0, "spot": {"innerConeAngle": 0.1, "outerConeAngle": 0.5}},
            {"type": "directional", "intensity": 2.0}
        ]}},
        "scene": 0,
        "scenes": [{"nodes": [0, 3]}],
        "nodes": [
            {"name": "root", "children": [1, 2], "translation": [0.0, 1.0, 0.0], "rotation": [0.0, 0.0, 0.0, 1.0], "scale": [1.0, 2.0, 1.0]},
            {"mesh": 0, "extras": {"hyrt": {"ray_traced": true}}},
            {"mesh": 1, "matrix": [1.0,0.0,0.0,0.0, 0.0,1.0,0.0,0.0, 0.0,0.0,1.0,0.0, 2.0,0.0,0.0,1.0]},
            {"camera": 0, "translation": [0.0, 0.0, 5.0], "children": [4, 5]},
            {"extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"extensions": {"KHR_lights_punctual": {"light": 2}}, "rotation": [0.6, 0.0, 0.0, 0.8]}
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
        "meshes": [
            {"name": "quad", "primitives": [
                {"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0},
                {"attributes": {"POSITION": 3}, "mode": 1}
            ]},
            {"primitives": [{"attributes": {"POSITION": 3}, "material": 1}], "extras": {"note": "kept"}}
        ],
        "materials": [
            {"name": "gold", "pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.8, 0.3, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.2}},
            {"extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": 1.33}},
             "extras": {"hyrt": {"ray_traced": false}}}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 0, "byteOffset": 48, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
            {"componentType": 5126, "count": 3, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 2.0, 0.0],
             "sparse": {"count": 1, "indices": {"bufferView": 2, "componentType": 5121}, "values": {"bufferView": 2, "byteOffset": 4}}}
        ],
        "bufferViews": [
            {"buffer": 0, "byteLength": 96},
            {"buffer": 0, "byteOffset": 96, "byteLength": 12},
            {"buffer": 0, "byteOffset": 108, "byteLength": 16}
        ],
        "buffers": [buffer]
    })
}

/// A Radiance HDR file of `w x h` texels, flat (uncompressed) RGBE scanlines.
pub fn small_hdr(w: usize, h: usize) -> Vec<u8> {
    let mut out = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\nEXPOSURE=1.0\n\n-Y {h} +X {w}\n").into_bytes();
    for k in 0..w * h {
        out.extend([(k * 37 % 256) as u8, 128, 64, 129]);
    }
    out
}

/// A small OpenEXR file written by the `image` crate's encoder.
pub fn small_exr() -> Vec<u8> {
    let (w, h) = (4u32, 2u32);
    let pixels: Vec<f32> = (0..w * h * 3).map(|k| k as f32 * 0.125).collect();
    let mut out = std::io::Cursor::new(Vec::new());
    image::DynamicImage::ImageRgb32F(image::ImageBuffer::from_raw(w, h, pixels).expect("sized buffer"))
        .write_to(&mut out, image::ImageFormat::OpenExr)
        .expect("the EXR encoder writes a small image");
    out.into_inner()
}

/// A small PNG (`w x h` RGBA8, a gradient with holes in its alpha) or JPEG (RGB).
pub fn small_image(w: u32, h: u32, format: image::ImageFormat) -> Vec<u8> {
    let texels: Vec<u8> =
        (0..w * h).flat_map(|k| [(k * 37) as u8, (k * 11) as u8, 200, if k % 3 == 0 { 0 } else { 255 }]).collect();
    let rgba = image::RgbaImage::from_raw(w, h, texels).expect("sized buffer");
    let image = match format {
        image::ImageFormat::Jpeg => image::DynamicImage::ImageRgb8(image::DynamicImage::ImageRgba8(rgba).to_rgb8()),
        _ => image::DynamicImage::ImageRgba8(rgba),
    };
    let mut out = std::io::Cursor::new(Vec::new());
    image.write_to(&mut out, format).expect("the encoder writes a small image");
    out.into_inner()
}

/// The small scene's JSON with textures: `TEXCOORD_0` and `COLOR_0` on the quad, a masked
/// material with a sampler and `KHR_texture_transform` sampling `first_image`, a `BLEND`
/// material sampling a JPEG data URI, and a normal texture (not used).
pub fn textured_json(buffer: Value, first_image: Value) -> Value {
    let mut v = small_json(buffer);
    let jpeg = format!("data:image/jpeg;base64,{}", base64(&small_image(8, 8, image::ImageFormat::Jpeg)));
    v["meshes"][0]["primitives"][0]["attributes"] = json!({"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 4, "COLOR_0": 5});
    v["accessors"].as_array_mut().expect("accessors").extend([
        json!({"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC2"}),
        json!({"bufferView": 2, "componentType": 5121, "normalized": true, "count": 4, "type": "VEC4"}),
    ]);
    v["materials"] = json!([
        {"name": "fence", "alphaMode": "MASK", "alphaCutoff": 0.4, "normalTexture": {"index": 1},
         "pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.9, 0.8, 0.9], "metallicFactor": 0.0,
            "baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0.5, 0.0], "rotation": 0.3, "scale": [2.0, 2.0]}}}}},
        {"alphaMode": "BLEND", "pbrMetallicRoughness": {"baseColorTexture": {"index": 1, "texCoord": 0}}}
    ]);
    v["textures"] = json!([{"source": 0, "sampler": 0}, {"source": 1}]);
    v["samplers"] = json!([{"magFilter": 9728, "minFilter": 9986, "wrapS": 33648, "wrapT": 33071}]);
    v["images"] = json!([first_image, {"uri": jpeg}]);
    v["extensionsUsed"].as_array_mut().expect("extensions").push(json!("KHR_texture_transform"));
    v
}

fn one(kind: Kind, name: &str, bytes: Vec<u8>) -> Seed {
    let main = Path::new(ROOT).join(name);
    Seed { kind, main: main.clone(), files: HashMap::from([(main, bytes)]) }
}

/// The seeds built in code (no file is read).
pub fn built_seeds() -> Vec<Seed> {
    let bin = small_bin();
    let glb_json = serde_json::to_vec(&small_json(json!({"byteLength": bin.len()}))).expect("JSON");
    let small_glb = glb(&glb_json, Some(&bin));
    let data_uri = format!("data:application/octet-stream;base64,{}", base64(&bin));
    let embedded =
        serde_json::to_vec_pretty(&small_json(json!({"byteLength": bin.len(), "uri": data_uri}))).expect("JSON");
    let mut external = one(
        Kind::Gltf,
        "external.gltf",
        serde_json::to_vec(&small_json(json!({"byteLength": bin.len(), "uri": "data%20file.bin"}))).expect("JSON"),
    );
    external.files.insert(Path::new(ROOT).join("data file.bin"), bin.clone());
    let manifest_text = "description = \"fuzz\"\nenvironment = \"sky.hdr\"\n\n[camera]\neye = [0.0, 1.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\n\
         fov_deg = 50.0\nnear = 0.1\nfar = 50.0\n\n[[light]]\ntype = \"point\"\nposition = [1.0, 4.0, 1.0]\nintensity = 10.0\n\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.0, -1.0, 0.0]\ncolor = [1.0, 0.9, 0.8]\nintensity = 0.5\n\n\
         [[model]]\nfile = \"small.glb\"\nname = \"small\"\ntranslate = [0.0, 1.0, 0.0]\nrotate_deg = [0.0, 30.0, 0.0]\n\
         scale = 2.0\nrender_mode = \"ray_traced\"\nmaterial = { base_color = [1.0, 0.8, 0.3], metallic = 1.0, roughness = 0.2, kind = \"specular\" }\n\n\
         [[model]]\nfile = \"embedded.gltf\"\nrotate_axis_angle = { axis = [0.0, 1.0, 0.0], angle_deg = 45.0 }\nscale = [1.0, 2.0, 3.0]\n\
         material = { transmission = 1.0, ior = 1.5 }\n\n[[model]]\nbuiltin = \"grid\"\nscale = [20.0, 1.0, 20.0]\n\n\
         [[model]]\nbuiltin = \"sphere\"\n"
    .to_string();
    let mut manifest = one(Kind::Manifest, "scene.toml", manifest_text.into_bytes());
    for (name, bytes) in [("small.glb", &small_glb), ("embedded.gltf", &embedded)] {
        manifest.files.insert(Path::new(ROOT).join(name), bytes.clone());
    }
    manifest.files.insert(Path::new(ROOT).join("sky.hdr"), small_hdr(8, 4));
    let png = small_image(4, 4, image::ImageFormat::Png);
    let mut textured = one(
        Kind::Gltf,
        "textured.gltf",
        serde_json::to_vec_pretty(&textured_json(
            json!({"byteLength": bin.len(), "uri": data_uri}),
            json!({"uri": "wall%20a.png"}),
        ))
        .expect("JSON"),
    );
    textured.files.insert(Path::new(ROOT).join("wall a.png"), png.clone());
    let textured_glb = textured_glb();
    // Textured models merged: two files with two images each, one of them repeated.
    let textured_manifest_text = "[[model]]\nfile = \"textured.glb\"\ntranslate = [1.0, 0.0, 0.0]\n\n\
         [[model]]\nfile = \"textured.gltf\"\nscale = 0.5\nrepeat = { count = [2, 1, 1], step = [2.0, 0.0, 0.0] }\n\
         material = { roughness = 0.5 }\n\n[[model]]\nbuiltin = \"cube\"\n";
    let mut textured_manifest = textured.clone();
    textured_manifest.kind = Kind::Manifest;
    textured_manifest.main = Path::new(ROOT).join("textured_scene.toml");
    textured_manifest.files.insert(textured_manifest.main.clone(), textured_manifest_text.as_bytes().to_vec());
    textured_manifest.files.insert(Path::new(ROOT).join("textured.glb"), textured_glb.clone());
    // One animated file placed twice.
    let animated = one(Kind::Gltf, "animated.gltf", animated_gltf());
    let animated_manifest_text = "[[model]]\nfile = \"animated.gltf\"\n\n[[model]]\nfile = \"animated.gltf\"\n\
         name = \"second\"\ntranslate = [3.0, 0.0, 0.0]\nrotate_deg = [0.0, 90.0, 0.0]\n";
    let mut animated_manifest = one(Kind::Manifest, "animated_scene.toml", animated_manifest_text.as_bytes().to_vec());
    animated_manifest.files.extend(animated.files.clone());
    vec![
        one(Kind::Glb, "small.glb", small_glb.clone()),
        one(Kind::Gltf, "embedded.gltf", embedded),
        external,
        manifest,
        one(Kind::Image, "sky.hdr", small_hdr(8, 4)),
        one(Kind::Image, "sky.exr", small_exr()),
        textured,
        one(Kind::Glb, "textured.glb", textured_glb),
        textured_manifest,
        animated,
        animated_manifest,
    ]
}

/// The textured scene ([`textured_json`]) as a GLB whose first image, a PNG, is a buffer
/// view after the geometry (its second is the JPEG data URI).
pub fn textured_glb() -> Vec<u8> {
    let bin = small_bin();
    let png = small_image(4, 4, image::ImageFormat::Png);
    let mut textured_bin = bin.clone();
    textured_bin.extend(&png);
    while !textured_bin.len().is_multiple_of(4) {
        textured_bin.push(0);
    }
    let mut glb_json =
        textured_json(json!({"byteLength": textured_bin.len()}), json!({"bufferView": 3, "mimeType": "image/png"}));
    glb_json["bufferViews"]
        .as_array_mut()
        .expect("views")
        .push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": png.len()}));
    glb(&serde_json::to_vec(&glb_json).expect("JSON"), Some(&textured_bin))
}

/// The small scene ([`small_json`]) animated, as a `.gltf` with its buffer in a data URI:
/// animation `rise` (1 s) moves node 0 (`root`, the quads' parent) up one unit (`LINEAR`)
/// and turns node 5 (the directional light) from its rest rotation to none (`STEP`). Its
/// keys follow [`small_bin`]'s data in the buffer: 2 times, 2 translations, 2 rotations.
pub fn animated_gltf() -> Vec<u8> {
    let mut bin = small_bin();
    let keys_at = bin.len();
    let keys: [f32; 16] = [0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.6, 0.0, 0.0, 0.8, 0.0, 0.0, 0.0, 1.0];
    bin.extend(keys.iter().flat_map(|k| k.to_le_bytes()));
    let uri = format!("data:application/octet-stream;base64,{}", base64(&bin));
    let mut v = small_json(json!({"byteLength": bin.len(), "uri": uri}));
    v["bufferViews"].as_array_mut().expect("views").push(json!({"buffer": 0, "byteOffset": keys_at, "byteLength": 64}));
    v["accessors"].as_array_mut().expect("accessors").extend([
        json!({"bufferView": 3, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0.0], "max": [1.0]}),
        json!({"bufferView": 3, "byteOffset": 8, "componentType": 5126, "count": 2, "type": "VEC3"}),
        json!({"bufferView": 3, "byteOffset": 32, "componentType": 5126, "count": 2, "type": "VEC4"}),
    ]);
    v["animations"] = json!([{"name": "rise",
        "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}},
                     {"sampler": 1, "target": {"node": 5, "path": "rotation"}}],
        "samplers": [{"input": 4, "output": 5, "interpolation": "LINEAR"},
                     {"input": 4, "output": 6, "interpolation": "STEP"}]}]);
    serde_json::to_vec_pretty(&v).expect("JSON")
}

/// Seeds from real files: the GLBs of `shared/assets` up to [`MAX_REAL_SEED_BYTES`], the
/// repository's manifests with every model file replaced by the small GLB (so a manifest
/// execution does not parse a large model), and its sample glTF files (`assets/scenes`).
/// Missing files are skipped.
pub fn real_seeds(repo_root: &Path) -> Vec<Seed> {
    let mut seeds = Vec::new();
    let assets = repo_root.join("../shared/assets");
    let mut names: Vec<PathBuf> =
        std::fs::read_dir(&assets).map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect()).unwrap_or_default();
    names.sort();
    for path in names {
        let small = std::fs::metadata(&path).map(|m| m.len() <= MAX_REAL_SEED_BYTES).unwrap_or(false);
        if path.extension().is_some_and(|e| e == "glb") && small {
            if let Ok(bytes) = std::fs::read(&path) {
                let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
                seeds.push(one(Kind::Glb, &name, bytes));
            }
        }
    }
    let small_glb = built_seeds().swap_remove(0).files.into_values().next().unwrap_or_default();
    let mut manifests: Vec<PathBuf> = std::fs::read_dir(repo_root.join("assets/scenes"))
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    manifests.sort();
    for path in manifests {
        let Ok(text) = std::fs::read_to_string(&path) else { continue };
        let name = format!("scenes/{}", path.file_name().map(|n| n.to_string_lossy()).unwrap_or_default());
        // The folder holds sample glTF files too (`animated_box.gltf`).
        let kind = match path.extension().and_then(|e| e.to_str()) {
            Some("gltf") => Kind::Gltf,
            Some("glb") => Kind::Glb,
            _ => Kind::Manifest,
        };
        let mut seed = one(kind, &name, text.clone().into_bytes());
        let dir = Path::new(ROOT).join("scenes");
        if let Ok(toml::Value::Table(t)) = text.parse::<toml::Value>() {
            for model in t.get("model").and_then(|m| m.as_array()).into_iter().flatten() {
                if let Some(file) = model.get("file").and_then(|f| f.as_str()) {
                    seed.files.insert(dir.join(file), small_glb.clone());
                }
            }
            if let Some(env) = t.get("environment").and_then(|f| f.as_str()) {
                seed.files.insert(dir.join(env), small_hdr(8, 4));
            }
        }
        seeds.push(seed);
    }
    seeds
}

/// Numbers that break things: zero, one, negatives, powers of two at integer widths,
/// JSON's largest exact integer, beyond-f32 magnitudes.
const INTERESTING: [f64; 18] = [
    0.0,
    1.0,
    -1.0,
    2.0,
    3.0,
    255.0,
    65535.0,
    65536.0,
    2147483647.0,
    4294967295.0,
    4294967296.0,
    9007199254740991.0,
    1e39,
    -1e39,
    1e308,
    0.5,
    -0.0,
    1e-45,
];

/// glTF field names worth setting on any object, with values of the right and wrong kinds.
const GLTF_KEYS: [&str; 22] = [
    "bufferView",
    "buffer",
    "byteOffset",
    "byteLength",
    "byteStride",
    "count",
    "componentType",
    "type",
    "children",
    "mesh",
    "material",
    "indices",
    "camera",
    "mode",
    "sparse",
    "uri",
    "scene",
    "nodes",
    "matrix",
    "extensionsRequired",
    "extensionsUsed",
    "version",
];

fn interesting_value(rng: &mut Rng) -> Value {
    match rng.below(12) {
        0 => json!(*rng.pick(&INTERESTING)),
        1 => json!(-*rng.pick(&INTERESTING)),
        2 => json!(rng.below(8)),
        3 => json!(*rng.pick(&[5120, 5121, 5122, 5123, 5125, 5126, 0, 5124])),
        4 => json!(*rng.pick(&["SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4", "VEC5", ""])),
        5 => json!([rng.below(8), rng.below(8), 0]),
        6 => json!(null),
        7 => json!(rng.chance(50)),
        8 => json!({}),
        9 => json!(*rng.pick(&[
            "",
            "1.0",
            "2.0",
            "3.0",
            "data:",
            "data:;base64,!!",
            "%ff%fe",
            "../x.bin",
            "file:///dev/zero",
            "http://x"
        ])),
        10 => json!(["KHR_draco_mesh_compression"]),
        _ => json!({"count": rng.below(4), "indices": {"bufferView": rng.below(4), "componentType": 5121},
                    "values": {"bufferView": rng.below(4)}}),
    }
}

/// Every JSON node, as paths (object keys and array indices) from the root.
fn json_paths(v: &Value, prefix: &mut Vec<PathStep>, out: &mut Vec<Vec<PathStep>>) {
    out.push(prefix.clone());
    match v {
        Value::Object(m) => {
            for (k, child) in m {
                prefix.push(PathStep::Key(k.clone()));
                json_paths(child, prefix, out);
                prefix.pop();
            }
        }
        Value::Array(a) => {
            for (i, child) in a.iter().enumerate() {
                prefix.push(PathStep::Index(i));
                json_paths(child, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

#[derive(Clone)]
enum PathStep {
    Key(String),
    Index(usize),
}

fn json_at<'v>(v: &'v mut Value, path: &[PathStep]) -> Option<&'v mut Value> {
    path.iter().try_fold(v, |v, step| match step {
        PathStep::Key(k) => v.get_mut(k.as_str()),
        PathStep::Index(i) => v.get_mut(*i),
    })
}

/// One structure-aware mutation of a glTF JSON document.
fn mutate_json(v: &mut Value, rng: &mut Rng) {
    let mut paths = Vec::new();
    json_paths(v, &mut Vec::new(), &mut paths);
    let path = rng.pick(&paths).clone();
    let choice = rng.below(10);
    if !v.is_object() {
        *v = interesting_value(rng);
        return;
    }
    // Whole-document mutations first.
    match choice {
        8 => {
            // glTF 1.0 shapes: a 1.x version, or keyed objects where arrays belong.
            if rng.chance(50) {
                v["asset"] = json!({"version": "1.0"});
            } else if let Some(m) = v.get_mut("meshes") {
                *m = json!({"mesh_0": {"primitives": []}});
            }
            return;
        }
        9 => {
            let list = if rng.chance(50) { "extensionsRequired" } else { "extensionsUsed" };
            v[list] = json!(["KHR_draco_mesh_compression"]);
            return;
        }
        _ => {}
    }
    let Some(node) = json_at(v, &path) else { return };
    match choice {
        0 | 1 => *node = interesting_value(rng),
        2 => match node {
            Value::Object(m) if !m.is_empty() => {
                let key = m.keys().nth(rng.below(m.len())).cloned().unwrap_or_default();
                m.remove(&key);
            }
            Value::Array(a) if !a.is_empty() => {
                a.remove(rng.below(a.len()));
            }
            _ => *node = json!(null),
        },
        3 => {
            if let Value::Object(m) = node {
                m.insert(rng.pick(&GLTF_KEYS).to_string(), interesting_value(rng));
            }
        }
        4 => match node {
            Value::Array(a) if !a.is_empty() => {
                let k = rng.below(a.len());
                let copy = a[k].clone();
                for _ in 0..1 + rng.below(3) {
                    a.push(copy.clone());
                }
            }
            Value::Number(n) => {
                let x = n.as_f64().unwrap_or(0.0);
                *node = json!(x + *rng.pick(&[-1.0, 1.0, 4.0, 1e6, -1e6]));
            }
            _ => *node = interesting_value(rng),
        },
        5 => {
            // A cycle or a second parent in the node hierarchy.
            if let Some(nodes) = v.get_mut("nodes").and_then(Value::as_array_mut) {
                let n = nodes.len().max(1);
                let k = rng.below(n);
                if let Some(Value::Object(m)) = nodes.get_mut(k) {
                    m.insert("children".into(), json!([rng.below(n), k]));
                }
            }
        }
        6 => {
            // Deep nesting in extras.
            let mut deep = json!(1);
            for _ in 0..rng.below(300) {
                deep = json!([deep]);
            }
            if let Value::Object(m) = node {
                m.insert("extras".into(), deep);
            }
        }
        _ => {
            // Mesh instancing: many nodes naming one mesh.
            if let Some(nodes) = v.get_mut("nodes").and_then(Value::as_array_mut) {
                for _ in 0..rng.below(64) {
                    nodes.push(json!({"mesh": 0}));
                }
            }
        }
    }
}

fn byte_mutation(bytes: &mut Vec<u8>, rng: &mut Rng) {
    let len = bytes.len();
    match rng.below(8) {
        0 if len > 0 => {
            let k = rng.below(len);
            bytes[k] ^= 1 << rng.below(8);
        }
        1 if len > 0 => {
            let k = rng.below(len);
            bytes[k] = rng.next() as u8;
        }
        2 => {
            let k = rng.below(len + 1);
            let n = 1 + rng.below(16);
            let insert: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
            bytes.splice(k..k, insert);
        }
        3 if len > 0 => {
            let k = rng.below(len);
            let n = (1 + rng.below(64)).min(len - k);
            bytes.drain(k..k + n);
        }
        4 => bytes.truncate(rng.below(len + 1)),
        5 if len >= 4 => {
            let k = rng.below(len - 3);
            let v = *rng.pick(&[0u32, 1, 0x7f, 0x80, 0xff, 0xffff, 0x7fff_ffff, 0x8000_0000, 0xffff_ffff, 12, 20]);
            bytes[k..k + 4].copy_from_slice(&v.to_le_bytes());
        }
        6 if len > 0 => {
            // Duplicate a range.
            let k = rng.below(len);
            let n = (1 + rng.below(256)).min(len - k);
            let copy = bytes[k..k + n].to_vec();
            let at = rng.below(len + 1);
            bytes.splice(at..at, copy);
        }
        _ if len > 0 => {
            // An ASCII digit where a digit is (numbers in text formats).
            let k = rng.below(len);
            if bytes[k].is_ascii_digit() {
                bytes[k] = b"0123456789-.e"[rng.below(13)];
            } else {
                bytes[k] = rng.next() as u8;
            }
        }
        _ => bytes.push(rng.next() as u8),
    }
}

/// The JSON and binary chunks of a well-formed GLB, if it is one.
fn glb_parts(bytes: &[u8]) -> Option<(Value, Option<Vec<u8>>)> {
    let u32_at = |k: usize| bytes.get(k..k + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    let json_len = u32_at(12)?;
    let json = serde_json::from_slice(bytes.get(20..20 + json_len)?).ok()?;
    let bin_at = 20 + json_len;
    let bin = u32_at(bin_at).and_then(|n| bytes.get(bin_at + 8..bin_at + 8 + n)).map(<[u8]>::to_vec);
    Some((json, bin))
}

fn mutate_glb(bytes: &mut Vec<u8>, rng: &mut Rng) {
    match rng.below(4) {
        0 | 1 => {
            if let Some((mut json, bin)) = glb_parts(bytes) {
                mutate_json(&mut json, rng);
                let text = serde_json::to_vec(&json).unwrap_or_default();
                *bytes = glb(&text, bin.as_deref());
            } else {
                byte_mutation(bytes, rng);
            }
        }
        2 => {
            // A header or chunk-header field: version, total length, chunk lengths and types.
            let at = *rng.pick(&[4usize, 8, 12, 16]);
            if bytes.len() >= at + 4 {
                let v = *rng.pick(&[0u32, 1, 3, 11, 12, 19, 20, 0x7fff_ffff, 0xffff_ffff]);
                let v = if rng.chance(50) { v } else { rng.next() as u32 % (bytes.len() as u32 + 16) };
                bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
            }
        }
        _ => byte_mutation(bytes, rng),
    }
}

fn mutate_gltf(bytes: &mut Vec<u8>, rng: &mut Rng) {
    match serde_json::from_slice::<Value>(bytes) {
        Ok(mut json) if rng.chance(75) => {
            mutate_json(&mut json, rng);
            *bytes = serde_json::to_vec(&json).unwrap_or_default();
        }
        _ => byte_mutation(bytes, rng),
    }
}

/// Values for manifest fields: wrong types, non-finite and huge numbers, paths that are
/// missing, the manifest itself, or another kind of file.
fn toml_value(rng: &mut Rng) -> toml::Value {
    use toml::Value as T;
    match rng.below(10) {
        0 => T::Float(*rng.pick(&[f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e39, -1e39, 0.0, -0.0, 1e-45, 180.0])),
        1 => T::Integer(*rng.pick(&[0, -1, 1, i64::MAX, i64::MIN, 1 << 32])),
        2 => T::String(
            rng.pick(&["scene.toml", "missing.glb", "sky.hdr", "small.glb", "", "/", "..", "grid", "glass"])
                .to_string(),
        ),
        3 => T::Array(vec![T::Float(1.0), T::Float(f64::NAN), T::Float(0.0)]),
        4 => T::Array(vec![]),
        5 => T::Array(vec![T::Float(1e30); 3]),
        6 => T::Boolean(true),
        7 => T::Table(Default::default()),
        8 => T::Array(vec![T::Float(0.0); 3]),
        _ => T::Float(rng.below(200) as f64 - 20.0),
    }
}

const MANIFEST_KEYS: [&str; 20] = [
    "file",
    "builtin",
    "name",
    "translate",
    "rotate_deg",
    "rotate_axis_angle",
    "scale",
    "render_mode",
    "material",
    "environment",
    "eye",
    "target",
    "up",
    "fov_deg",
    "near",
    "far",
    "type",
    "position",
    "direction",
    "intensity",
];

/// The paths of every table in a TOML document.
fn toml_tables(v: &toml::Value, prefix: &mut Vec<PathStep>, out: &mut Vec<Vec<PathStep>>) {
    match v {
        toml::Value::Table(t) => {
            out.push(prefix.clone());
            for (k, child) in t {
                prefix.push(PathStep::Key(k.clone()));
                toml_tables(child, prefix, out);
                prefix.pop();
            }
        }
        toml::Value::Array(a) => {
            for (i, child) in a.iter().enumerate() {
                prefix.push(PathStep::Index(i));
                toml_tables(child, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

fn toml_at<'v>(v: &'v mut toml::Value, path: &[PathStep]) -> Option<&'v mut toml::Value> {
    path.iter().try_fold(v, |v, step| match step {
        PathStep::Key(k) => v.get_mut(k.as_str()),
        PathStep::Index(i) => v.get_mut(*i),
    })
}

fn mutate_manifest(bytes: &mut Vec<u8>, rng: &mut Rng) {
    let parsed = std::str::from_utf8(bytes).ok().and_then(|t| t.parse::<toml::Value>().ok());
    let Some(mut value) = parsed.filter(|_| rng.chance(80)) else {
        byte_mutation(bytes, rng);
        return;
    };
    if rng.chance(10) {
        // Many models naming one file or shape.
        if let Some(models) = value.get_mut("model").and_then(toml::Value::as_array_mut) {
            if let Some(first) = models.first().cloned() {
                for _ in 0..rng.below(200) {
                    models.push(first.clone());
                }
            }
        }
    } else {
        let mut tables = Vec::new();
        toml_tables(&value, &mut Vec::new(), &mut tables);
        let path = rng.pick(&tables).clone();
        let Some(toml::Value::Table(table)) = toml_at(&mut value, &path) else { return };
        match rng.below(3) {
            0 if !table.is_empty() => {
                let key = table.keys().nth(rng.below(table.len())).cloned().unwrap_or_default();
                table.remove(&key);
            }
            1 if !table.is_empty() => {
                let key = table.keys().nth(rng.below(table.len())).cloned().unwrap_or_default();
                table.insert(key, toml_value(rng));
            }
            _ => {
                table.insert(rng.pick(&MANIFEST_KEYS).to_string(), toml_value(rng));
            }
        }
    }
    match toml::to_string(&value) {
        Ok(text) => *bytes = text.into_bytes(),
        Err(_) => byte_mutation(bytes, rng),
    }
}

fn mutate_image(bytes: &mut Vec<u8>, rng: &mut Rng) {
    if bytes.starts_with(b"\x89PNG") && bytes.len() >= 33 && rng.chance(50) {
        // The PNG header's width and height (with the chunk's checksum mended, so the
        // decoder reads them): sizes the budget or the decoder must refuse.
        let dims = *rng.pick(&[(16384u32, 16384u32), (0, 4), (1 << 31, 1), (65535, 65535), (4, 100_000), (1, 1)]);
        bytes[16..20].copy_from_slice(&dims.0.to_be_bytes());
        bytes[20..24].copy_from_slice(&dims.1.to_be_bytes());
        let crc = crc32(&bytes[12..29]);
        bytes[29..33].copy_from_slice(&crc.to_be_bytes());
        return;
    }
    if bytes.starts_with(b"#?") && rng.chance(50) {
        // The HDR header: its resolution line and format.
        if let Some(at) = bytes.windows(3).position(|w| w == b"-Y ") {
            let end = bytes[at..].iter().position(|&b| b == b'\n').map(|e| at + e).unwrap_or(bytes.len());
            let dims = *rng.pick(&[
                "-Y 100000 +X 100000",
                "-Y 0 +X 8",
                "+Y 4 -X 8",
                "-Y 4 +X 4294967296",
                "-Y 65535 +X 65535",
                "-Y 4 +X 8 extra",
                "-Y -4 +X 8",
                "-Y 1 +X 1",
            ]);
            let mut out = bytes[..at].to_vec();
            out.extend(dims.as_bytes());
            out.extend(&bytes[end..]);
            *bytes = out;
            return;
        }
    }
    byte_mutation(bytes, rng);
}

/// CRC-32 (ISO-HDLC, PNG's chunk checksum).
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

/// Mutate one file of `seed` (mostly the main file) 1 to 4 times.
pub fn mutate(seed: &Seed, rng: &mut Rng) -> Seed {
    let mut out = seed.clone();
    let target = if rng.chance(85) || out.files.len() == 1 {
        out.main.clone()
    } else {
        let mut names: Vec<&PathBuf> = out.files.keys().collect();
        names.sort();
        (*rng.pick(&names)).clone()
    };
    if rng.chance(3) {
        out.files.remove(&target);
        return out;
    }
    let ext = target.extension().and_then(|e| e.to_str()).unwrap_or("").to_string();
    let Some(bytes) = out.files.get_mut(&target) else { return out };
    for _ in 0..1 + rng.below(4) {
        match ext.as_str() {
            "glb" => mutate_glb(bytes, rng),
            "gltf" => mutate_gltf(bytes, rng),
            "toml" => mutate_manifest(bytes, rng),
            "hdr" | "exr" | "png" => mutate_image(bytes, rng),
            _ => byte_mutation(bytes, rng),
        }
    }
    out
}

/// Load what a seed says, as the library's users do: `Ok` when it loads and the scene is
/// consistent ([`inconsistency`]), else the error's message or the inconsistency.
pub fn load(seed: &Seed) -> Result<(), String> {
    match attempt(seed) {
        Ok(None) => Ok(()),
        Ok(Some(problem)) => Err(format!("{}: loaded, but the scene is inconsistent: {problem}", seed.main.display())),
        Err(e) => Err(e.to_string()),
    }
}

/// Load what a seed says: the loaded scene's [`inconsistency`], if any, or the error.
fn attempt(seed: &Seed) -> Result<Option<String>, SceneError> {
    match seed.kind {
        Kind::Image => Environment::load_from(&seed.main, &seed.files).map(|_| None),
        _ => Scene::load_from(&seed.main, &seed.files).map(|scene| inconsistency(&scene)),
    }
}

/// What in a loaded scene refers past its own tables, which the renderer indexes without
/// checks (`geometry::surface_tables` indexes `textures` by a material's image): an object's
/// id other than its index, its mesh or material, a material's base-colour image.
pub fn inconsistency(scene: &Scene) -> Option<String> {
    for (k, o) in scene.objects.iter().enumerate() {
        if o.id as usize != k || o.mesh >= scene.meshes.len() || o.material >= scene.materials.len() {
            return Some(format!(
                "object {k} '{}' has id {}, mesh {} of {}, material {} of {}",
                o.name,
                o.id,
                o.mesh,
                scene.meshes.len(),
                o.material,
                scene.materials.len()
            ));
        }
    }
    scene.materials.iter().enumerate().find_map(|(k, m)| {
        let image = m.base_color_texture?.image;
        (image >= scene.textures.len())
            .then(|| format!("material {k} '{}' samples image {image} of {}", m.name, scene.textures.len()))
    })
}

/// What is wrong with `error`, from loading `seed`, if anything: it must name the file
/// loaded and, when a manifest entry failed, the entry's model file: one of `model_files`
/// (the model files of a manifest built around an input; not checked when empty).
fn unnamed(seed: &Seed, error: &SceneError, model_files: &[PathBuf]) -> Option<String> {
    let message = error.to_string();
    let name = seed.main.display().to_string();
    if !message.contains(&name) {
        return Some(format!("the error does not name {name}: {message}"));
    }
    if let SceneError::ManifestEntry { error: inner, .. } = error {
        let inner = inner.to_string();
        if !model_files.is_empty() && !model_files.iter().any(|f| inner.contains(&f.display().to_string())) {
            return Some(format!("the error does not name the model file: {message}"));
        }
    }
    None
}

/// The input of execution `n` of a run with `seed`.
pub fn input(seeds: &[Seed], run_seed: u64, n: u64) -> Seed {
    input_and_rng(seeds, run_seed, n).0
}

/// [`input`], and the execution's generator after it (what it draws next does not change
/// the input).
fn input_and_rng(seeds: &[Seed], run_seed: u64, n: u64) -> (Seed, Rng) {
    let mut rng = Rng::new(run_seed ^ n.wrapping_mul(0xD6E8_FEB8_6659_FD93));
    let base = rng.pick(seeds);
    // One execution in 32 loads a seed unmutated (they must load, or fail as they are).
    if rng.below(32) == 0 {
        return (base.clone(), rng);
    }
    let input = mutate(base, &mut rng);
    (input, rng)
}

/// The loads of execution `n` of a run with `seed`: its [`input`], then the input through
/// manifests ([`through_manifests`]).
pub fn loads(seeds: &[Seed], run_seed: u64, n: u64) -> Vec<Seed> {
    let (input, mut rng) = input_and_rng(seeds, run_seed, n);
    let mut loads = through_manifests(&input, &mut rng);
    loads.insert(0, input);
    loads
}

/// The manifest [`through_manifests`] writes beside a glTF/GLB input, naming it alone.
pub const ONE_MODEL_MANIFEST: &str = "fuzz_one_model.toml";

/// The manifest [`through_manifests`] writes beside a glTF/GLB input, merging it with
/// [`MERGE_PARTNER`].
pub const MERGED_MANIFEST: &str = "fuzz_merged.toml";

/// The textured model ([`textured_glb`]) merged with an input, beside it.
pub const MERGE_PARTNER: &str = "fuzz_partner.glb";

/// [`textured_glb`], built once.
fn merge_partner() -> &'static [u8] {
    static PARTNER: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    PARTNER.get_or_init(textured_glb)
}

/// A glTF or GLB input loaded as scenes composed from files load it: through a manifest
/// beside it naming it alone ([`ONE_MODEL_MANIFEST`]), and through one merging it with a
/// textured model ([`MERGED_MANIFEST`], [`MERGE_PARTNER`]), the partner first or last and
/// each entry sometimes moved, scaled, repeated or given a material override, as `rng`
/// draws. Empty for other inputs.
pub fn through_manifests(input: &Seed, rng: &mut Rng) -> Vec<Seed> {
    if !matches!(input.kind, Kind::Glb | Kind::Gltf) {
        return Vec::new();
    }
    let dir = input.main.parent().unwrap_or(Path::new(ROOT));
    let file = input.main.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let entry = |file: &str| toml::Table::from_iter([("file".to_string(), toml::Value::String(file.to_string()))]);
    let manifest = |name: &str, entries: Vec<toml::Table>| {
        let mut seed = input.clone();
        seed.kind = Kind::Manifest;
        seed.main = dir.join(name);
        let models = toml::Value::Array(entries.into_iter().map(toml::Value::Table).collect());
        let text = toml::to_string(&toml::Table::from_iter([("model".to_string(), models)]));
        seed.files.insert(seed.main.clone(), text.expect("a manifest of strings and numbers").into_bytes());
        seed
    };
    let alone = manifest(ONE_MODEL_MANIFEST, vec![entry(&file)]);
    let mut entries = vec![entry(MERGE_PARTNER), entry(&file)];
    for e in &mut entries {
        place(e, rng);
    }
    if rng.chance(50) {
        entries.reverse();
    }
    let mut merged = manifest(MERGED_MANIFEST, entries);
    merged.files.insert(dir.join(MERGE_PARTNER), merge_partner().to_vec());
    vec![alone, merged]
}

/// Sometimes move, scale or repeat a manifest's model entry, or override its materials'
/// factors: what a manifest does to a file's objects and materials.
fn place(entry: &mut toml::Table, rng: &mut Rng) {
    use toml::Value as T;
    let vector = |rng: &mut Rng| T::Array((0..3).map(|_| T::Float(rng.below(9) as f64 - 4.0)).collect());
    if rng.chance(50) {
        entry.insert("translate".into(), vector(rng));
    }
    if rng.chance(30) {
        entry.insert("scale".into(), T::Float(*rng.pick(&[0.5, 2.0, -1.0])));
    }
    if rng.chance(25) {
        let count = T::Array((0..3).map(|_| T::Integer(1 + rng.below(3) as i64)).collect());
        let repeat = toml::Table::from_iter([("count".to_string(), count), ("step".to_string(), vector(rng))]);
        entry.insert("repeat".into(), T::Table(repeat));
    }
    if rng.chance(20) {
        entry.insert("material".into(), T::Table(toml::Table::from_iter([("roughness".to_string(), T::Float(0.5))])));
    }
}

/// What a run found.
#[derive(Debug, Default)]
pub struct Report {
    pub executions: u64,
    /// Executions whose input loaded.
    pub loaded: u64,
    /// Executions whose input was refused (with an error naming the file).
    pub refused: u64,
    /// Loads of inputs through the manifests built around them ([`through_manifests`])
    /// that loaded.
    pub manifest_loaded: u64,
    /// Loads of inputs through manifests that were refused.
    pub manifest_refused: u64,
    /// Failures: execution number and what went wrong.
    pub failures: Vec<(u64, String)>,
}

static EXEC_STARTED_MS: AtomicU64 = AtomicU64::new(0);
static WATCHDOG: AtomicBool = AtomicBool::new(false);

/// Start the watchdog thread (once): it aborts the process, naming the execution, when one
/// runs past [`EXEC_TIME_LIMIT`].
fn start_watchdog(epoch: Instant) {
    if WATCHDOG.swap(true, Ordering::SeqCst) {
        return;
    }
    std::thread::spawn(move || loop {
        std::thread::sleep(Duration::from_millis(200));
        let started = EXEC_STARTED_MS.load(Ordering::Relaxed);
        let now = epoch.elapsed().as_millis() as u64;
        if started != 0 && now.saturating_sub(started) > EXEC_TIME_LIMIT.as_millis() as u64 {
            die("time limit exceeded (a hang)", 0);
        }
    });
}

/// Run executions `range` of a run with `run_seed`; `progress` is called every so often with
/// the report so far.
pub fn run(seeds: &[Seed], run_seed: u64, range: std::ops::Range<u64>, mut progress: impl FnMut(&Report)) -> Report {
    let epoch = Instant::now() - Duration::from_millis(1);
    start_watchdog(epoch);
    CURRENT_SEED.store(run_seed, Ordering::Relaxed);
    let mut report = Report::default();
    let previous_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    for n in range {
        let Ok(loads) = catch_unwind(|| loads(seeds, run_seed, n)) else {
            report.failures.push((n, "the harness's mutator panicked".into()));
            continue;
        };
        CURRENT_EXEC.store(n, Ordering::Relaxed);
        report.executions += 1;
        for (k, seed) in loads.iter().enumerate() {
            BASELINE.store(LIVE.load(Ordering::Relaxed), Ordering::Relaxed);
            EXEC_STARTED_MS.store(epoch.elapsed().as_millis() as u64, Ordering::Relaxed);
            let outcome = catch_unwind(AssertUnwindSafe(|| attempt(seed)));
            EXEC_STARTED_MS.store(0, Ordering::Relaxed);
            BASELINE.store(usize::MAX, Ordering::Relaxed);
            // Loads after the first are the input through manifests beside it.
            let (via, model_files, loaded, refused) = if k == 0 {
                (String::new(), Vec::new(), &mut report.loaded, &mut report.refused)
            } else {
                let files = vec![loads[0].main.clone(), seed.main.with_file_name(MERGE_PARTNER)];
                let via = format!("through {}: ", seed.main.display());
                (via, files, &mut report.manifest_loaded, &mut report.manifest_refused)
            };
            let problem = match outcome {
                Ok(Ok(None)) => {
                    *loaded += 1;
                    None
                }
                Ok(Ok(Some(inconsistency))) => Some(format!("the loaded scene is inconsistent: {inconsistency}")),
                Ok(Err(error)) => {
                    *refused += 1;
                    unnamed(seed, &error, &model_files)
                }
                Err(panic) => {
                    let what = panic
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_default();
                    Some(format!("panic: {what}"))
                }
            };
            if let Some(problem) = problem {
                report.failures.push((n, format!("{via}{problem}")));
            }
        }
        if report.executions % 10_000 == 0 {
            progress(&report);
        }
    }
    std::panic::set_hook(previous_hook);
    report
}

/// Write the files of one input under `dir` (for a look, or a regression test).
pub fn write_input(seed: &Seed, dir: &Path) -> std::io::Result<()> {
    for (path, bytes) in &seed.files {
        let relative = path.strip_prefix(ROOT).unwrap_or(path);
        let target = dir.join(relative);
        if let Some(parent) = target.parent() {
            std::fs::create_dir_all(parent)?;
        }
        std::fs::write(target, bytes)?;
    }
    Ok(())
}
