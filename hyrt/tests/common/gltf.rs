//! Small glTF files for tests. [`GltfFile`] collects a document built with serde_json, its
//! binary buffer and its PNG images, and writes them as a `.gltf` (the buffer and the images
//! in files beside it) or a `.glb` (all of them in the binary chunk). Below it, one file per
//! glTF feature hyrt reads, each laid out so that the feature shows in a frame taken by
//! [`hyrt::Scene::ensure_camera_and_lights`]'s camera (or the file's own), and
//! [`one_model_manifest`], the TOML manifest whose only model is a file.
//!
//! Shared by `hyrt/tests/manifest_paths.rs` and the `hyrt` program's tests
//! (`cli/tests/common/mod.rs` includes this file).

use std::path::{Path, PathBuf};

use hyrt::glam::Quat;
use serde_json::{json, Value};

/// glTF sampler filter and wrap codes.
pub const NEAREST: u32 = 9728;
pub const LINEAR: u32 = 9729;
pub const NEAREST_MIPMAP_NEAREST: u32 = 9984;
pub const LINEAR_MIPMAP_NEAREST: u32 = 9985;
pub const NEAREST_MIPMAP_LINEAR: u32 = 9986;
pub const LINEAR_MIPMAP_LINEAR: u32 = 9987;
pub const REPEAT: u32 = 10497;
pub const CLAMP_TO_EDGE: u32 = 33071;
pub const MIRRORED_REPEAT: u32 = 33648;

/// glTF accessor component types.
const UNSIGNED_BYTE: u32 = 5121;
const UNSIGNED_SHORT: u32 = 5123;
const FLOAT: u32 = 5126;

/// Texture coordinates of a quad's corners (see [`GltfFile::quad`]) showing the whole image
/// upright (glTF's (0, 0) is the image's top left).
pub const UPRIGHT: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];

/// Texture coordinates from `lo` to `hi` on both axes, upright: `hi - lo` tiles of the image.
pub fn tiled(lo: f32, hi: f32) -> [[f32; 2]; 4] {
    [[lo, hi], [hi, hi], [hi, lo], [lo, lo]]
}

/// A quaternion as glTF writes it, `[x, y, z, w]`.
pub fn quat(q: Quat) -> [f32; 4] {
    q.to_array()
}

/// The node `extras` that make an object ray traced or rasterized.
pub fn ray_traced(yes: bool) -> Value {
    json!({ "hyrt": { "ray_traced": yes } })
}

/// A white diffuse material whose base colour is texture `texture`; `info` keys are added to
/// its `baseColorTexture`, `extra` keys to the material.
pub fn textured(texture: usize, info: Value, extra: Value) -> Value {
    let mut base = json!({ "index": texture });
    merge(&mut base, info);
    let mut material = json!({ "pbrMetallicRoughness": {
        "baseColorTexture": base, "metallicFactor": 0.0, "roughnessFactor": 0.8
    } });
    merge(&mut material, extra);
    material
}

/// A plain diffuse material of linear colour `rgba`.
pub fn plain(rgba: [f32; 4]) -> Value {
    json!({ "pbrMetallicRoughness": { "baseColorFactor": rgba, "metallicFactor": 0.0, "roughnessFactor": 0.8 } })
}

/// Add the keys of object `extra` to object `to`.
fn merge(to: &mut Value, extra: Value) {
    if let Value::Object(extra) = extra {
        to.as_object_mut().unwrap().extend(extra);
    }
}

/// A PNG of `w x h` RGBA8 texels.
pub fn png(w: u32, h: u32, texels: &[[u8; 4]]) -> Vec<u8> {
    let mut out = Vec::new();
    let image = image::RgbaImage::from_raw(w, h, texels.concat()).unwrap();
    image.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png).unwrap();
    out
}

/// A glTF document being built: its JSON, binary buffer, accessors and images.
pub struct GltfFile {
    pub doc: Value,
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    images: Vec<Vec<u8>>,
}

impl GltfFile {
    /// A document with one scene and nothing in it.
    pub fn new() -> GltfFile {
        let doc = json!({
            "asset": { "version": "2.0", "generator": "hyrt tests/common/gltf.rs" },
            "scene": 0,
            "scenes": [{ "nodes": [] }],
        });
        GltfFile { doc, bin: Vec::new(), views: Vec::new(), accessors: Vec::new(), images: Vec::new() }
    }

    /// Append `value` to the document's array `key` (made when missing); its index.
    pub fn push(&mut self, key: &str, value: Value) -> usize {
        if self.doc[key].is_null() {
            self.doc[key] = json!([]);
        }
        let array = self.doc[key].as_array_mut().unwrap();
        array.push(value);
        array.len() - 1
    }

    /// A node listed in the scene; its index.
    pub fn root(&mut self, node: Value) -> usize {
        let n = self.push("nodes", node);
        self.doc["scenes"][0]["nodes"].as_array_mut().unwrap().push(json!(n));
        n
    }

    /// A root node named `name` placing `mesh` at `translation`, ray traced or rasterized;
    /// its index.
    pub fn place(&mut self, name: &str, mesh: usize, translation: [f32; 3], ray_traced: bool) -> usize {
        self.root(
            json!({ "name": name, "mesh": mesh, "translation": translation, "extras": self::ray_traced(ray_traced) }),
        )
    }

    /// Name an extension as used.
    pub fn uses(&mut self, extension: &str) {
        self.push("extensionsUsed", json!(extension));
    }

    /// `bytes` in a buffer view of their own (4-byte aligned); its index.
    fn view(&mut self, bytes: &[u8]) -> usize {
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        self.views.push(json!({ "buffer": 0, "byteOffset": offset, "byteLength": bytes.len() }));
        self.views.len() - 1
    }

    /// An accessor of `kind` elements with component type `component` over `bytes`; its index.
    fn accessor(&mut self, component: u32, kind: &str, normalized: bool, bytes: &[u8]) -> usize {
        let width = match kind {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            other => panic!("{other}"),
        };
        let size = match component {
            UNSIGNED_BYTE => 1,
            UNSIGNED_SHORT => 2,
            _ => 4,
        };
        let view = self.view(bytes);
        let mut accessor = json!({
            "bufferView": view, "componentType": component, "count": bytes.len() / (size * width), "type": kind,
        });
        if normalized {
            accessor["normalized"] = json!(true);
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// A float32 accessor of `kind` over `values`, with the bounds glTF requires of positions
    /// and key times; its index.
    pub fn floats(&mut self, kind: &str, values: &[f32]) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let a = self.accessor(FLOAT, kind, false, &bytes);
        let width = values.len() / self.accessors[a]["count"].as_u64().unwrap() as usize;
        let column = |k: usize| values.iter().skip(k).step_by(width).copied();
        let lo: Vec<f32> = (0..width).map(|k| column(k).fold(f32::INFINITY, f32::min)).collect();
        let hi: Vec<f32> = (0..width).map(|k| column(k).fold(f32::NEG_INFINITY, f32::max)).collect();
        self.accessors[a]["min"] = json!(lo);
        self.accessors[a]["max"] = json!(hi);
        a
    }

    /// A normalized unsigned 8-bit accessor of `kind` (colours); its index.
    pub fn unorm8(&mut self, kind: &str, values: &[u8]) -> usize {
        self.accessor(UNSIGNED_BYTE, kind, true, values)
    }

    /// A normalized unsigned 16-bit accessor of `kind` (colours); its index.
    pub fn unorm16(&mut self, kind: &str, values: &[u16]) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.accessor(UNSIGNED_SHORT, kind, true, &bytes)
    }

    /// A u16 index accessor; its index.
    pub fn indices(&mut self, indices: &[u16]) -> usize {
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        self.accessor(UNSIGNED_SHORT, "SCALAR", false, &bytes)
    }

    /// An image of `w x h` RGBA8 texels, stored as a PNG; its index.
    pub fn image(&mut self, w: u32, h: u32, texels: &[[u8; 4]]) -> usize {
        self.images.push(png(w, h, texels));
        self.images.len() - 1
    }

    /// A texture of image `image` with `sampler` (a glTF sampler object; `None`: the
    /// texture names no sampler); its index.
    pub fn texture(&mut self, image: usize, sampler: Option<Value>) -> usize {
        let texture = match sampler {
            Some(s) => json!({ "source": image, "sampler": self.push("samplers", s) }),
            None => json!({ "source": image }),
        };
        self.push("textures", texture)
    }

    /// A triangle-list primitive over the rectangle `[x0, y0, x1, y1]` of the XY plane
    /// (z = 0) facing +Z: corners counter-clockwise from `(x0, y0)`, `TEXCOORD_0` = `uv` per
    /// corner, `attributes` (accessor indices by name) added, material `material`.
    pub fn quad_primitive(&mut self, rect: [f32; 4], material: usize, uv: [[f32; 2]; 4], attributes: Value) -> Value {
        let [x0, y0, x1, y1] = rect;
        let position = self.floats("VEC3", &[x0, y0, 0.0, x1, y0, 0.0, x1, y1, 0.0, x0, y1, 0.0]);
        let normal = self.floats("VEC3", &[0.0, 0.0, 1.0].repeat(4));
        let uv = self.floats("VEC2", &uv.concat());
        let indices = self.indices(&[0, 1, 2, 0, 2, 3]);
        let mut all = json!({ "POSITION": position, "NORMAL": normal, "TEXCOORD_0": uv });
        merge(&mut all, attributes);
        json!({ "attributes": all, "indices": indices, "material": material })
    }

    /// A mesh of one unit quad ([`GltfFile::quad_primitive`] over `[-0.5, 0.5]^2`); its index.
    pub fn quad(&mut self, material: usize, uv: [[f32; 2]; 4], attributes: Value) -> usize {
        let primitive = self.quad_primitive([-0.5, -0.5, 0.5, 0.5], material, uv, attributes);
        self.push("meshes", json!({ "primitives": [primitive] }))
    }

    /// Write the file at `path`: a `.glb` with the buffer and the images in its binary chunk,
    /// or a `.gltf` with the buffer in `<stem>.bin` and image `i` in `<stem>_<i>.png` beside
    /// it. Returns `path`.
    pub fn write(mut self, path: &Path) -> PathBuf {
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        let glb = path.extension().is_some_and(|e| e == "glb");
        let images = std::mem::take(&mut self.images);
        for (i, png) in images.iter().enumerate() {
            let image = if glb {
                json!({ "bufferView": self.view(png), "mimeType": "image/png" })
            } else {
                let name = format!("{stem}_{i}.png");
                std::fs::write(path.with_file_name(&name), png).unwrap();
                json!({ "uri": name })
            };
            self.push("images", image);
        }
        self.doc["accessors"] = json!(self.accessors);
        self.doc["bufferViews"] = json!(self.views);
        self.doc["buffers"] = json!([{ "byteLength": self.bin.len() }]);
        if glb {
            let mut json = serde_json::to_vec(&self.doc).unwrap();
            json.resize(json.len().next_multiple_of(4), b' ');
            let total = 12 + 8 + json.len() + 8 + self.bin.len();
            let mut out = Vec::with_capacity(total);
            out.extend_from_slice(b"glTF");
            for word in [2, total as u32, json.len() as u32] {
                out.extend_from_slice(&word.to_le_bytes());
            }
            out.extend_from_slice(b"JSON");
            out.extend_from_slice(&json);
            out.extend_from_slice(&(self.bin.len() as u32).to_le_bytes());
            out.extend_from_slice(b"BIN\0");
            out.extend_from_slice(&self.bin);
            std::fs::write(path, out).unwrap();
        } else {
            let bin = format!("{stem}.bin");
            std::fs::write(path.with_file_name(&bin), &self.bin).unwrap();
            self.doc["buffers"][0]["uri"] = json!(bin);
            std::fs::write(path, serde_json::to_string_pretty(&self.doc).unwrap()).unwrap();
        }
        path.to_path_buf()
    }
}

/// Write `<stem>.toml` beside `file`: a manifest with one `[[model]]` naming the file by its
/// name, and nothing else (no camera, no lights: the file's are used). Returns its path.
pub fn one_model_manifest(file: &Path) -> PathBuf {
    let name = file.file_name().unwrap().to_str().unwrap();
    // A JSON string is a TOML basic string for a plain file name.
    let manifest = file.with_extension("toml");
    std::fs::write(&manifest, format!("[[model]]\nfile = {}\n", json!(name))).unwrap();
    manifest
}

/// Where quad `i` of a grid of `columns` columns goes: 1.1 apart, left to right, top down.
fn grid(i: usize, columns: usize) -> [f32; 3] {
    [(i % columns) as f32 * 1.1, -((i / columns) as f32) * 1.1, 0.0]
}

/// 2 x 2 texels: red, green / blue, white.
const FOUR: [[u8; 4]; 4] = [[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255], [255, 255, 255, 255]];

/// 16 x 16 texels: red and green ramps along x and y, blue on alternate texels, so that
/// minified, each mip level and filter gives other colours.
fn ramps16() -> Vec<[u8; 4]> {
    (0..256u32).map(|i| [(i % 16 * 16) as u8, (i / 16 * 16) as u8, ((i % 16 + i / 16) % 2 * 255) as u8, 255]).collect()
}

/// 4 x 4 texels, each a colour of its own.
fn palette16() -> Vec<[u8; 4]> {
    (0..16u32).map(|i| [(i % 4 * 85) as u8, (i / 4 * 85) as u8, ((i * 7) % 16 * 17) as u8, 255]).collect()
}

/// `samplers.gltf` (its images in PNG files beside it): six textured quads, 3 x 2, each with
/// a sampler of its own: every wrap mode on each axis, magnification nearest and linear,
/// minification without and with each kind of mip mapping. The top row magnifies a 2 x 2
/// image tiled three times, the bottom row minifies a 16 x 16 one; alternate quads are ray
/// traced.
pub fn samplers(dir: &Path) -> PathBuf {
    let mut g = GltfFile::new();
    let small = g.image(2, 2, &FOUR);
    let fine = g.image(16, 16, &ramps16());
    #[rustfmt::skip]
    let variants = [
        (small, REPEAT, REPEAT, NEAREST, NEAREST),
        (small, CLAMP_TO_EDGE, CLAMP_TO_EDGE, LINEAR, LINEAR),
        (small, MIRRORED_REPEAT, REPEAT, NEAREST, NEAREST_MIPMAP_LINEAR),
        (fine, REPEAT, MIRRORED_REPEAT, LINEAR, LINEAR_MIPMAP_LINEAR),
        (fine, CLAMP_TO_EDGE, MIRRORED_REPEAT, NEAREST, NEAREST_MIPMAP_NEAREST),
        (fine, MIRRORED_REPEAT, CLAMP_TO_EDGE, LINEAR, LINEAR_MIPMAP_NEAREST),
    ];
    for (i, (image, s, t, mag, min)) in variants.into_iter().enumerate() {
        let sampler = json!({ "wrapS": s, "wrapT": t, "magFilter": mag, "minFilter": min });
        let texture = g.texture(image, Some(sampler));
        let material = g.push("materials", textured(texture, json!({}), json!({})));
        let mesh = g.quad(material, tiled(-1.0, 2.0), json!({}));
        g.place(&format!("sampler{i}"), mesh, grid(i, 3), i % 2 == 1);
    }
    g.write(&dir.join("samplers.gltf"))
}

/// `texture_transform.glb`: four quads textured with a 4 x 4 palette under
/// `KHR_texture_transform`: an offset, a rotation, a scale, and all three with a `texCoord`
/// override to `TEXCOORD_1` (a mapping turned a quarter, on a texture without a sampler:
/// the defaults); alternate quads are ray traced.
pub fn texture_transform(dir: &Path) -> PathBuf {
    let mut g = GltfFile::new();
    g.uses("KHR_texture_transform");
    let image = g.image(4, 4, &palette16());
    let nearest = json!({ "magFilter": NEAREST, "minFilter": NEAREST });
    let transforms = [
        json!({ "offset": [0.25, 0.5] }),
        json!({ "rotation": 0.6 }),
        json!({ "scale": [3.0, 2.0] }),
        json!({ "offset": [0.1, 0.0], "rotation": -0.3, "scale": [2.0, 2.0], "texCoord": 1 }),
    ];
    for (i, transform) in transforms.into_iter().enumerate() {
        let second = i == 3;
        let texture = g.texture(image, (!second).then(|| nearest.clone()));
        let info = json!({ "texCoord": 0, "extensions": { "KHR_texture_transform": transform } });
        let material = g.push("materials", textured(texture, info, json!({})));
        let attributes = if second {
            json!({ "TEXCOORD_1": g.floats("VEC2", &[1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]) })
        } else {
            json!({})
        };
        let mesh = g.quad(material, UPRIGHT, attributes);
        g.place(&format!("transform{i}"), mesh, grid(i, 2), i % 2 == 1);
    }
    g.write(&dir.join("texture_transform.glb"))
}

/// `vertex_colours.gltf`: three quads with `COLOR_0`: float `VEC3` on a plain white material,
/// normalized 8-bit `VEC4` times a texture (ray traced), normalized 16-bit `VEC3`.
pub fn vertex_colours(dir: &Path) -> PathBuf {
    let mut g = GltfFile::new();
    let white = g.push("materials", plain([1.0, 1.0, 1.0, 1.0]));
    let image =
        g.image(2, 2, &[[255, 255, 255, 255], [128, 128, 128, 255], [200, 255, 200, 255], [255, 200, 255, 255]]);
    let texture = g.texture(image, Some(json!({ "magFilter": LINEAR })));
    let texture_material = g.push("materials", textured(texture, json!({}), json!({})));
    let rgb8 = [[0, 255, 255, 255], [255, 0, 255, 255], [255, 255, 0, 255], [40, 40, 40, 255]];
    let rgb16 = [[65535, 32768, 0], [0, 65535, 32768], [32768, 0, 65535], [65535, 65535, 0]];
    let colours = [
        json!({ "COLOR_0": g.floats("VEC3", &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0]) }),
        json!({ "COLOR_0": g.unorm8("VEC4", &rgb8.concat()) }),
        json!({ "COLOR_0": g.unorm16("VEC3", &rgb16.concat()) }),
    ];
    for (i, colour) in colours.into_iter().enumerate() {
        let material = if i == 1 { texture_material } else { white };
        let mesh = g.quad(material, UPRIGHT, colour);
        g.place(&format!("colours{i}"), mesh, grid(i, 3), i == 1);
    }
    g.write(&dir.join("vertex_colours.gltf"))
}

/// `alpha.glb`: in front of a blue backdrop, three quads whose alpha cuts holes: `MASK` at
/// cutoff 0.3 over a 4 x 4 texture of alphas 0, 50, 100 and 255 (nearest); `BLEND` (rendered
/// as a mask at 0.5) over a left-to-right alpha ramp (ray traced); `MASK` at the default
/// cutoff over vertex colours whose alpha is 0 at the bottom corners. The default lights in
/// front cast the quads' shadows, holes included, on the backdrop.
pub fn alpha(dir: &Path) -> PathBuf {
    let mut g = GltfFile::new();
    let backdrop_material = g.push("materials", plain([0.2, 0.4, 0.9, 1.0]));
    let backdrop = g.quad(backdrop_material, UPRIGHT, json!({}));
    g.root(json!({ "name": "backdrop", "mesh": backdrop, "translation": [1.1, 0.0, -0.6], "scale": [3.6, 1.6, 1.0] }));
    let alphas = [0u8, 255, 100, 50];
    let checker: Vec<[u8; 4]> = (0..16).map(|i| [255, 160, 40, alphas[(i + i / 4) % 4]]).collect();
    let ramp: Vec<[u8; 4]> = (0..8).map(|i| [230, 40, 200, (i * 36) as u8]).collect();
    let (checker, ramp) = (g.image(4, 4, &checker), g.image(8, 1, &ramp));
    let nearest = g.texture(checker, Some(json!({ "magFilter": NEAREST, "minFilter": NEAREST })));
    let linear = g.texture(ramp, Some(json!({ "magFilter": LINEAR, "minFilter": LINEAR, "wrapS": CLAMP_TO_EDGE })));
    let materials = [
        textured(nearest, json!({}), json!({ "alphaMode": "MASK", "alphaCutoff": 0.3 })),
        textured(linear, json!({}), json!({ "alphaMode": "BLEND" })),
        json!({ "alphaMode": "MASK", "pbrMetallicRoughness": { "metallicFactor": 0.0 } }),
    ];
    for (i, material) in materials.into_iter().enumerate() {
        let material = g.push("materials", material);
        let attributes = if i == 2 {
            let rgba = [[0.9, 0.9, 0.2, 0.0], [0.9, 0.9, 0.2, 0.0], [0.2, 0.9, 0.2, 1.0], [0.2, 0.9, 0.2, 1.0]];
            json!({ "COLOR_0": g.floats("VEC4", &rgba.concat()) })
        } else {
            json!({})
        };
        let mesh = g.quad(material, UPRIGHT, attributes);
        g.place(&format!("alpha{i}"), mesh, grid(i, 3), i == 1);
    }
    g.write(&dir.join("alpha.glb"))
}

/// `name` (`.gltf` or `.glb`): a grey backdrop and an arm of textured quads (a 2 x 2 image of
/// `texels`) that two animations move. Nodes: 0 `backdrop`, 1 `arm` (no mesh) with child 2
/// `hand` (a textured quad) with child 3 `finger` (the same mesh again).
///
/// Animation 0 `wave` (2 s): `arm` translation `LINEAR` (-1, 0, 0), (0, 0.6, 0), (0.5, 0, 0) at
/// 0, 1, 2 s; `arm` rotation `CUBICSPLINE` from none to a quarter turn about +Z, zero
/// tangents; `hand` scale `STEP` 1 then 1.4 at 1 s. Animation 1 `sway` (1 s): `arm`
/// rotation `LINEAR` to an eighth of a turn about -Z.
pub fn animated(dir: &Path, name: &str, texels: &[[u8; 4]; 4]) -> PathBuf {
    let mut g = GltfFile::new();
    let grey = g.push("materials", plain([0.6, 0.6, 0.6, 1.0]));
    let backdrop = g.quad(grey, UPRIGHT, json!({}));
    g.root(json!({ "name": "backdrop", "mesh": backdrop, "translation": [0.0, 0.0, -0.5], "scale": [4.0, 3.0, 1.0] }));
    let image = g.image(2, 2, texels);
    let texture = g.texture(image, Some(json!({ "magFilter": NEAREST })));
    let material = g.push("materials", textured(texture, json!({}), json!({})));
    let quad = g.quad(material, UPRIGHT, json!({}));
    g.root(json!({ "name": "arm", "translation": [-1.0, 0.0, 0.0], "children": [2] }));
    let hand = json!({ "name": "hand", "mesh": quad, "translation": [1.0, 0.0, 0.1], "children": [3] });
    g.push("nodes", hand);
    g.push(
        "nodes",
        json!({ "name": "finger", "mesh": quad, "translation": [0.8, 0.0, 0.0], "scale": [0.5, 0.5, 0.5] }),
    );
    let (t012, t02, t01) =
        (g.floats("SCALAR", &[0.0, 1.0, 2.0]), g.floats("SCALAR", &[0.0, 2.0]), g.floats("SCALAR", &[0.0, 1.0]));
    let translation = g.floats("VEC3", &[-1.0, 0.0, 0.0, 0.0, 0.6, 0.0, 0.5, 0.0, 0.0]);
    let zero = [0.0; 4];
    let quarter = quat(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2));
    let spline = g.floats("VEC4", &[zero, quat(Quat::IDENTITY), zero, zero, quarter, zero].concat());
    let scale = g.floats("VEC3", &[1.0, 1.0, 1.0, 1.4, 1.4, 1.4]);
    let eighth = quat(Quat::from_rotation_z(-std::f32::consts::FRAC_PI_4));
    let sway = g.floats("VEC4", &[quat(Quat::IDENTITY), eighth].concat());
    g.doc["animations"] = json!([
        { "name": "wave",
          "samplers": [
              sampler(t012, translation, "LINEAR"), sampler(t02, spline, "CUBICSPLINE"), sampler(t01, scale, "STEP")
          ],
          "channels": [channel(0, 1, "translation"), channel(1, 1, "rotation"), channel(2, 2, "scale")] },
        { "name": "sway", "samplers": [sampler(t01, sway, "LINEAR")], "channels": [channel(0, 1, "rotation")] }
    ]);
    g.write(&dir.join(name))
}

/// An animation sampler.
fn sampler(input: usize, output: usize, interpolation: &str) -> Value {
    json!({ "input": input, "output": output, "interpolation": interpolation })
}

/// An animation channel: `sampler` drives `path` of `node`.
fn channel(sampler: usize, node: usize, path: &str) -> Value {
    json!({ "sampler": sampler, "target": { "node": node, "path": path } })
}

/// `name` (`.gltf` or `.glb`): one textured quad, a 2 x 2 image of `texels` (bilinear).
pub fn textured_quad(dir: &Path, name: &str, texels: &[[u8; 4]; 4]) -> PathBuf {
    let mut g = GltfFile::new();
    let image = g.image(2, 2, texels);
    let texture = g.texture(image, Some(json!({ "magFilter": LINEAR })));
    let material = g.push("materials", textured(texture, json!({}), json!({})));
    let mesh = g.quad(material, UPRIGHT, json!({}));
    g.root(json!({ "name": "quad", "mesh": mesh }));
    g.write(&dir.join(name))
}

/// A ground (grey, 6 x 6 in the XZ plane), an orange post standing on it and a camera on a
/// turned rig looking down at them, with two `KHR_lights_punctual` lights. `infinite`: the
/// camera has no `zfar` and the lights are a spot (loaded as a point) and a bluish
/// directional light, written as `camera_lights_infinite.gltf`; else a `zfar`, a warm point
/// light and a directional one, as `camera_lights.glb`.
pub fn camera_and_lights(dir: &Path, infinite: bool) -> PathBuf {
    use std::f32::consts::FRAC_PI_2;
    let mut g = GltfFile::new();
    g.uses("KHR_lights_punctual");
    let grey = g.push("materials", plain([0.7, 0.7, 0.7, 1.0]));
    let orange = g.push("materials", plain([0.9, 0.45, 0.1, 1.0]));
    let (ground, post) = (g.quad(grey, UPRIGHT, json!({})), g.quad(orange, UPRIGHT, json!({})));
    let flat = quat(Quat::from_rotation_x(-FRAC_PI_2));
    g.root(json!({ "name": "ground", "mesh": ground, "rotation": flat, "scale": [6.0, 6.0, 1.0] }));
    g.root(json!({ "name": "post", "mesh": post, "translation": [0.0, 0.6, 0.0], "scale": [1.0, 1.2, 1.0] }));
    let perspective = if infinite {
        json!({ "yfov": 0.9, "znear": 0.05 })
    } else {
        json!({ "yfov": 0.7, "znear": 0.1, "zfar": 50.0 })
    };
    g.push("cameras", json!({ "type": "perspective", "perspective": perspective }));
    let rig =
        g.root(json!({ "name": "rig", "translation": [0.3, 0.2, 0.0], "rotation": quat(Quat::from_rotation_y(0.25)) }));
    let down = quat(Quat::from_rotation_x(-0.3));
    let camera =
        g.push("nodes", json!({ "name": "camera", "camera": 0, "translation": [0.0, 1.5, 4.0], "rotation": down }));
    g.doc["nodes"][rig]["children"] = json!([camera]);
    let lights = if infinite {
        json!([
            { "type": "spot", "color": [1.0, 0.9, 0.8], "intensity": 25.0, "spot": { "outerConeAngle": 0.6 } },
            { "type": "directional", "color": [0.6, 0.7, 1.0], "intensity": 1.0 }
        ])
    } else {
        json!([
            { "type": "point", "color": [1.0, 0.85, 0.7], "intensity": 20.0 },
            { "type": "directional", "intensity": 1.5 }
        ])
    };
    g.doc["extensions"] = json!({ "KHR_lights_punctual": { "lights": lights } });
    let bulb = if infinite { [-1.5, 2.0, 1.0] } else { [1.5, 2.5, 1.5] };
    g.root(json!({ "name": "bulb", "translation": bulb, "extensions": { "KHR_lights_punctual": { "light": 0 } } }));
    let sun = Quat::from_rotation_y(0.5) * Quat::from_rotation_x(-0.9);
    g.root(json!({ "name": "sun", "rotation": quat(sun), "extensions": { "KHR_lights_punctual": { "light": 1 } } }));
    g.write(&dir.join(if infinite { "camera_lights_infinite.gltf" } else { "camera_lights.glb" }))
}

/// `instanced.glb`: one mesh of two primitives (a textured left half, a plain red right
/// half) placed by four nodes: two side by side (one turned about +Y), one mirrored
/// (scale -1 in x) above them, and that one's child, smaller, below it.
pub fn instanced(dir: &Path) -> PathBuf {
    let mut g = GltfFile::new();
    let image = g.image(2, 2, &FOUR);
    let texture = g.texture(image, Some(json!({ "magFilter": NEAREST })));
    let left = g.push("materials", textured(texture, json!({}), json!({})));
    let right = g.push("materials", plain([0.8, 0.1, 0.1, 1.0]));
    let primitives = [
        g.quad_primitive([-0.5, -0.5, 0.0, 0.5], left, UPRIGHT, json!({})),
        g.quad_primitive([0.0, -0.5, 0.5, 0.5], right, UPRIGHT, json!({})),
    ];
    let mesh = g.push("meshes", json!({ "name": "halves", "primitives": primitives }));
    g.root(json!({ "name": "left", "mesh": mesh, "translation": [-1.3, 0.0, 0.0] }));
    let turned = quat(Quat::from_rotation_y(0.5));
    g.root(json!({ "name": "right", "mesh": mesh, "translation": [1.3, 0.0, 0.0], "rotation": turned }));
    let mirrored =
        g.root(json!({ "name": "mirrored", "mesh": mesh, "translation": [0.0, 0.7, 0.0], "scale": [-1.0, 0.8, 1.0] }));
    let child = g.push(
        "nodes",
        json!({ "name": "child", "mesh": mesh, "translation": [0.0, -1.6, 0.2], "scale": [0.7, 0.7, 0.7] }),
    );
    g.doc["nodes"][mirrored]["children"] = json!([child]);
    g.write(&dir.join("instanced.glb"))
}
