//! glTF 2.0 loader (`.gltf` with external or embedded buffers, and `.glb`).
//!
//! What is read, and how it maps onto the [scene model](super):
//!
//! * **Hierarchy.** The default scene (`scene`), else the first scene, else (with a note)
//!   every node that is no other node's child. Nodes are walked depth first, children in
//!   file order, with world transforms accumulated as `parent * node.matrix()`. A node
//!   reached twice (a cycle, or a node with two parents) is a [`SceneError::Content`] error.
//! * **Geometry.** Each primitive of mode `TRIANGLES` becomes one [`Mesh`] and, per node that
//!   instances it, one [`Object`]; a `(mesh, primitive)` pair instanced by several nodes shares
//!   one [`Mesh`]. Other modes (points, lines, strips, fans) are skipped with a note.
//!   `POSITION` must be float32 `VEC3`; `NORMAL` is kept when it is float32 `VEC3` with one
//!   normal per position (otherwise dropped, with a note); indices may be u8/u16/u32, and a
//!   primitive without indices gets `0..n`. Sparse accessors and accessors without a buffer
//!   view (all zeros) are supported. `TEXCOORD_0`, `TEXCOORD_1` (float32, or normalized
//!   unsigned 8/16-bit `VEC2`) and `COLOR_0` (the same types, `VEC3` or `VEC4`, linear) are
//!   kept with one value per position; another type or count is an error.
//! * **Textures.** A material's `baseColorTexture`, `metallicRoughnessTexture`,
//!   `occlusionTexture` (with its `strength`), `emissiveTexture` and `normalTexture` (with
//!   its `scale`) are read with their
//!   samplers (wrap modes, `magFilter`, `minFilter`; undefined filters are linear,
//!   mip-mapped), `texCoord` (0 or 1) and `KHR_texture_transform` (offset, rotation, scale,
//!   `texCoord` override). hyrt samples all of a material's textures at the first one's
//!   coordinates ([`super::MaterialMaps`]); a material whose textures differ there gets a
//!   note. Each image (PNG or JPEG, recognised by its signature; from a buffer view, a data
//!   URI or a file beside a `.gltf`) is decoded once to RGBA8 ([`TextureImage`]), its texels
//!   charged to the load's budget before the decoder allocates them. `TANGENT` (float32
//!   `VEC4`) is kept; a normal-mapped mesh without it gets MikkTSpace tangents
//!   ([`crate::geometry::tangents`]).
//! * **Names.** Object name: node name, else mesh name, else `node<i>`, then `#<primitive>`.
//!   Mesh name: mesh name (else `mesh<i>`), then `#<primitive>`.
//! * **Materials.** `baseColorFactor` (RGB, and alpha), `metallicFactor`, `roughnessFactor`,
//!   `alphaMode` with `alphaCutoff` (default 0.5; `BLEND` is rendered as a mask at 0.5,
//!   with a note: [`AlphaMode::Blend`]),
//!   `KHR_materials_transmission` factor (default 0) and `KHR_materials_ior` (default 1.5),
//!   `emissiveFactor` times `KHR_materials_emissive_strength` (default 1).
//!   Kind: transmission > 0 gives [`MaterialKind::Glass`], else metallic >= 0.5 gives
//!   [`MaterialKind::Specular`], else [`MaterialKind::Diffuse`]. Primitives without a material
//!   get [`Material::grey`].
//! * **Render mode.** An `extras` object `{"hyrt": {"ray_traced": true | false}}` on the node,
//!   the mesh or the material decides, in that order of precedence (node over mesh over
//!   material); without one, [`Material::default_render_mode`]. Any other key inside `"hyrt"`
//!   is an error (it catches typos); other keys of `extras` are ignored.
//! * **Camera.** The first perspective camera met in the walk: eye = the node's world
//!   translation, target = eye + the node's world -Z, up = the node's world +Y, `yfov`
//!   (radians) converted to degrees, `znear`; `zfar`, or when absent (infinite projection)
//!   twice the distance from the eye to the farthest corner of the scene bounds (at least
//!   twice `znear`; 1000 `znear` for a scene without finite vertices), with a note.
//!   `aspectRatio` is ignored: the output image decides. Orthographic cameras are skipped.
//! * **Lights** (`KHR_lights_punctual`). Point: the node's world translation. Directional:
//!   travels along the node's world -Z. Spot: at the node's translation, its cone along the
//!   node's world -Z, `innerConeAngle` and `outerConeAngle` as written (glTF's defaults 0
//!   and pi/4), the extension's smooth falloff between. `range` (point and spot lights):
//!   the extension's window over 1/d^2, unscaled by the node's scale as the extension says;
//!   on a directional light it is ignored with a note. A light that breaks the extension's
//!   rules (a cone beyond pi/2, a negative intensity) is left out with a note naming its
//!   node and the problem ([`Light::validate`]).
//!   Units: glTF gives point/spot intensity in candela (lm/sr) and directional intensity in
//!   lux (lm/m^2). Both are used as-is as [`Light`] `intensity`, which scales `color` (with
//!   1/d^2 falloff for point and spot lights), without a luminous efficacy, as the Khronos
//!   sample viewer does: a point light of intensity I lights a surface facing it at
//!   distance d like a directional light of intensity I / d^2.
//! * **Animations** (`animations`): each becomes an [`Animation`] of the scene's
//!   [`SceneAnimation`] ([`Scene::animation`]), which also keeps the hierarchy walked (per
//!   node: parent, TRS or matrix, the objects, camera and light it places), so that
//!   [`Scene::set_time`] can pose the scene; the scene loads in its rest pose (the nodes' own
//!   transforms). Channels drive `translation`, `rotation` or `scale` of a TRS node (an animated
//!   node with a `matrix` is an error, as glTF forbids it) through samplers: input float32
//!   `SCALAR` key times (finite, from 0, strictly increasing), output float32 `VEC3`
//!   (translation, scale) or float32 / normalized 8- and 16-bit integer `VEC4` (rotation,
//!   normalized to unit length when loaded), one value per key, three for `CUBICSPLINE` (which
//!   needs two keys); `STEP`, `LINEAR`, `CUBICSPLINE`. Any other type or count, a non-finite
//!   value, or two channels driving the same property of a node is a [`SceneError::Content`]
//!   error. Channels of morph target `weights`, and channels driving nodes outside the scene
//!   walked, are ignored with a note. A file without animations gets no hierarchy.
//! * **Skins and morph targets** are not applied: a skinned mesh renders unskinned in its bind
//!   pose (its vertices as stored) placed by its node, a mesh with morph targets renders its
//!   base geometry whatever its weights; a note names them.
//! * **Not added here:** a default camera or default lights; the caller decides
//!   ([`Scene::ensure_camera_and_lights`]).
//! * **One path.** The converted file reaches the [`Scene`] through the merge a manifest's
//!   models go through ([`super::merge`]), as a model with the identity placement and no
//!   overrides: whatever is read here reaches a manifest's scene the same way.
//!
//! Errors name the file: it cannot be read ([`SceneError::Io`]); it does not parse or
//! validate as glTF 2.0, or a buffer cannot be loaded or an accessor lies outside its buffer
//! ([`SceneError::Gltf`]); content hyrt cannot render: no `POSITION`, a position type other
//! than float32 `VEC3`, an index out of range, an index count not a multiple of 3
//! ([`SceneError::Content`]). NaN or infinite positions are loaded and counted in a note:
//! triangles using them are never hit nor covered.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use glam::{Mat4, Quat, Vec2, Vec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::{Mode, Semantic};

use super::animation::{
    camera_frame, light_direction, light_position, AnimatedProperty, Animation, AnimationChannel, AnimationSampler,
    Interpolation, Keyframes, NodeTransform, SceneAnimation, SceneNode,
};
use super::files::{Budget, Disk, SceneFiles};
use super::merge::{Merge, Model};
use super::texture::{AlphaMode, Filter, Sampler, TextureBinding, TextureImage, UvTransform, VertexAttributes, Wrap};
use super::{
    farthest_corner, Camera, Light, Material, MaterialKind, MaterialMaps, Mesh, Object, ObjectSource, RenderMode, Scene,
};
use crate::SceneError;

/// `KHR_materials_ior` default (the extension's specification: 1.5).
const DEFAULT_IOR: f32 = 1.5;

/// A material is specular when its metallic factor is at least this (the same threshold as
/// [`Material::default_render_mode`]).
const METALLIC_SPECULAR_THRESHOLD: f32 = 0.5;

/// The magic number that opens a binary glTF (GLB) file.
const GLB_MAGIC: &[u8; 4] = b"glTF";
/// GLB header: magic, version, total length (the glTF 2.0 specification, section 4.4.2).
const GLB_HEADER_BYTES: usize = 12;
/// GLB chunk header: length, type (the specification, section 4.4.3).
const GLB_CHUNK_HEADER_BYTES: usize = 8;
/// The extension name of Draco mesh compression, which hyrt does not decode.
const DRACO_EXTENSION: &str = "KHR_draco_mesh_compression";

/// Load a `.gltf` or `.glb` file; see the module docs for what is read.
pub fn load_gltf(path: &Path) -> Result<Scene, SceneError> {
    load_gltf_from(path, &Disk)
}

/// [`load_gltf`] reading the file, and a `.gltf` file's external buffers, from `files`.
pub fn load_gltf_from(path: &Path, files: &dyn SceneFiles) -> Result<Scene, SceneError> {
    let bytes = files.read(path).map_err(|source| SceneError::Io { path: path.to_path_buf(), source })?;
    load_alone(path, &bytes, files)
}

/// [`load_gltf`] of a file's content already in memory. `path` names the file in errors and
/// notes, and external buffers of a `.gltf` file are read from the disk relative to it.
pub fn load_gltf_slice(bytes: &[u8], path: &Path) -> Result<Scene, SceneError> {
    load_alone(path, bytes, &Disk)
}

/// A file loaded alone: converted, then placed as a manifest places a model ([`super::merge`]),
/// with the identity placement and no overrides.
fn load_alone(path: &Path, bytes: &[u8], files: &dyn SceneFiles) -> Result<Scene, SceneError> {
    let loaded = load_gltf_detailed(path, bytes, files)?;
    let mut merged = Merge::new(Budget::for_input(0));
    let slot = merged.add_file(&loaded.scene, loaded.input_bytes, None);
    let content = |message: String| SceneError::Content { path: path.to_path_buf(), message };
    merged.place(&loaded.scene, slot, &loaded.mode_from_extras, &Model::file_alone()).map_err(content)?;
    merged.finish(None, false).map_err(content)
}

/// A loaded glTF file plus what the manifest loader needs to apply its overrides.
pub(crate) struct LoadedGltf {
    pub scene: Scene,
    /// Per object: whether its render mode came from a `hyrt` extra (true) or from
    /// [`Material::default_render_mode`] (false).
    pub mode_from_extras: Vec<bool>,
    /// The bytes of the file and of its buffers (what a manifest's budget grows by).
    pub input_bytes: usize,
    /// The hierarchy walked when the file has no animations (with animations it is in
    /// [`Scene::animation`] and this is empty).
    #[cfg_attr(not(test), allow(dead_code))]
    pub unanimated_nodes: Vec<SceneNode>,
}

/// [`load_gltf_slice`], also telling which render modes came from `extras`.
pub(crate) fn load_gltf_detailed(path: &Path, bytes: &[u8], files: &dyn SceneFiles) -> Result<LoadedGltf, SceneError> {
    let gltf_err = |message: String| SceneError::Gltf { path: path.to_path_buf(), message };
    let (json, mut bin) =
        if bytes.starts_with(GLB_MAGIC) { split_glb(bytes).map_err(gltf_err)? } else { (bytes, None) };
    let root =
        gltf::json::Root::from_slice(json).map_err(|e| gltf_err(not_gltf2(json).unwrap_or_else(|| e.to_string())))?;
    check_version_and_extensions(&root).map_err(gltf_err)?;
    let draco_used = root.extensions_used.iter().any(|e| e == DRACO_EXTENSION);
    let document = gltf::Document::from_json_without_validation(root);
    // Draco-compressed primitives keep their data in the extension, so their accessors lack
    // the buffer views validation asks for: say why rather than what is missing.
    let tolerated_note = validate(&document).map_err(|e| {
        gltf_err(if draco_used { format!("{}; the validator reports: {e}", draco_message()) } else { e })
    })?;
    let base = path.parent().unwrap_or(Path::new(""));
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let (what, data) = match buffer.source() {
            gltf::buffer::Source::Bin => {
                ("the GLB binary chunk".to_string(), bin.take().map(<[u8]>::to_vec).ok_or("the file has none".into()))
            }
            source @ gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => (
                "an embedded data URI".to_string(),
                // A data URI never reaches the file system (the gltf crate decodes it).
                gltf::buffer::Data::from_source(source, None).map(|d| d.0).map_err(|e| e.to_string()),
            ),
            gltf::buffer::Source::Uri(uri) => match relative_uri_path(uri) {
                Ok(relative) => {
                    let file = base.join(relative);
                    (format!("'{}'", file.display()), files.read(&file).map_err(|e| e.to_string()))
                }
                Err(e) => (format!("URI '{uri}'"), Err(e)),
            },
        };
        let data = data.map_err(|e| gltf_err(format!("buffer {} ({what}): cannot load: {e}", buffer.index())))?;
        if data.len() < buffer.length() {
            return Err(gltf_err(format!(
                "buffer {} ({what}) holds {} bytes, the file declares {}",
                buffer.index(),
                data.len(),
                buffer.length()
            )));
        }
        buffers.push(data);
    }
    let input_bytes = buffers.iter().map(Vec::len).fold(bytes.len(), usize::saturating_add);
    let mut converter = Converter::new(path, &buffers, files, Budget::for_input(input_bytes));
    converter.scene.notes.extend(tolerated_note.map(|n| format!("{}: {n}", path.display())));
    converter.run(&document).map(|(scene, mode_from_extras, unanimated_nodes)| LoadedGltf {
        scene,
        mode_from_extras,
        input_bytes,
        unanimated_nodes,
    })
}

/// The JSON chunk and the binary chunk (if any) of a GLB file, every length checked
/// against the bytes there are.
fn split_glb(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), String> {
    let u32_at = |at: usize| bytes.get(at..at + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    let (Some(version), Some(length)) = (u32_at(4), u32_at(8)) else {
        return Err(format!("GLB header truncated: {} bytes, a header has {GLB_HEADER_BYTES}", bytes.len()));
    };
    match version {
        2 => {}
        1 => {
            return Err("this is a glTF 1.0 binary file (KHR_binary_glTF): hyrt reads glTF 2.0 only; convert it                         to glTF 2.0 first (for example with the Khronos glTF-Pipeline or Blender)"
                .into())
        }
        v => return Err(format!("GLB version {v}: hyrt reads GLB version 2 (glTF 2.0) only")),
    }
    let body = match bytes.get(GLB_HEADER_BYTES..length) {
        Some(body) => body,
        None => return Err(format!("GLB header declares {length} bytes, the file holds {}", bytes.len())),
    };
    let (json, rest) = glb_chunk(body, b"JSON")?;
    let bin = if rest.is_empty() { None } else { Some(glb_chunk(rest, b"BIN\0")?.0) };
    Ok((json, bin))
}

/// The first chunk of `bytes`, which must be of type `ty`, and what follows it.
fn glb_chunk<'b>(bytes: &'b [u8], ty: &[u8; 4]) -> Result<(&'b [u8], &'b [u8]), String> {
    let name = String::from_utf8_lossy(ty).trim_end_matches('\0').to_string();
    let Some(header) = bytes.get(..GLB_CHUNK_HEADER_BYTES) else {
        return Err(format!("GLB {name} chunk header truncated ({} bytes left)", bytes.len()));
    };
    if &header[4..] != ty {
        return Err(format!(
            "GLB chunk of type {:?} where the {name} chunk belongs",
            String::from_utf8_lossy(&header[4..])
        ));
    }
    let length = u32::from_le_bytes([header[0], header[1], header[2], header[3]]) as usize;
    let rest = &bytes[GLB_CHUNK_HEADER_BYTES..];
    match rest.get(..length) {
        Some(chunk) => Ok((chunk, &rest[length..])),
        None => Err(format!("GLB {name} chunk declares {length} bytes, {} are left", rest.len())),
    }
}

/// Why JSON that does not deserialize as glTF 2.0 is another thing hyrt does not read
/// (glTF 1.0, whose top-level `meshes`, `nodes`, ... are objects keyed by id rather than
/// arrays); `None` when it is not recognisably that.
fn not_gltf2(json: &[u8]) -> Option<String> {
    let value: serde_json::Value = serde_json::from_slice(json).ok()?;
    let version = value.get("asset").and_then(|a| a.get("version")).and_then(|v| v.as_str());
    const KEYED_IN_1_0: [&str; 7] = ["meshes", "nodes", "accessors", "bufferViews", "buffers", "materials", "scenes"];
    let keyed = KEYED_IN_1_0.iter().any(|k| value.get(k).is_some_and(|v| v.is_object()));
    (version.is_some_and(|v| v.starts_with("1.")) || keyed).then(|| gltf_1_message(version.unwrap_or("1.0")))
}

fn gltf_1_message(version: &str) -> String {
    format!(
        "this is a glTF {version} file: hyrt reads glTF 2.0 only; convert it to glTF 2.0 first (for example          with the Khronos glTF-Pipeline or Blender)"
    )
}

/// Refuse plainly what deserializes but hyrt does not read: a major version other than 2,
/// Draco-compressed meshes required to render.
fn check_version_and_extensions(root: &gltf::json::Root) -> Result<(), String> {
    let version = root.asset.version.as_str();
    if version.starts_with("1.") {
        return Err(gltf_1_message(version));
    }
    if !version.starts_with("2.") {
        return Err(format!("asset.version is '{version}': hyrt reads glTF 2.0 only"));
    }
    if root.extensions_required.iter().any(|e| e == DRACO_EXTENSION) {
        return Err(draco_message());
    }
    Ok(())
}

fn draco_message() -> String {
    format!(
        "the meshes are Draco-compressed ({DRACO_EXTENSION}), which hyrt does not decode; export the \
         file without Draco compression (or decompress it, e.g. with gltf-transform)"
    )
}

/// The relative file path of a buffer URI (percent-decoded, as the glTF specification
/// says URIs are); `file:` URIs name an absolute path; other schemes are refused.
fn relative_uri_path(uri: &str) -> Result<PathBuf, String> {
    if let Some(rest) = uri.strip_prefix("file://").or_else(|| uri.strip_prefix("file:")) {
        return Ok(PathBuf::from(rest));
    }
    if uri.contains(':') {
        return Err("unsupported URI scheme (hyrt reads relative paths, file: and data: URIs)".into());
    }
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut k = 0;
    while k < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        match (bytes[k], bytes.get(k + 1).copied().and_then(hex), bytes.get(k + 2).copied().and_then(hex)) {
            (b'%', Some(hi), Some(lo)) => {
                out.push((hi * 16 + lo) as u8);
                k += 3;
            }
            (b, _, _) => {
                out.push(b);
                k += 1;
            }
        }
    }
    String::from_utf8(out).map(PathBuf::from).map_err(|_| "the percent-decoded URI is not UTF-8".into())
}

/// Run the gltf crate's validation, tolerating two of its findings that the loader handles
/// itself: a `POSITION` accessor without `min`/`max` (required by the specification but not
/// needed here; a note is returned) and a primitive without `POSITION` (reported by the loader
/// as [`SceneError::Content`]). Any other finding is an error message listing them all.
fn validate(document: &gltf::Document) -> Result<Option<String>, String> {
    use gltf::json::validation::{Checked, Error, Validate};
    let root = document.as_json();
    // gltf-json 1.4.1's primitive check indexes `accessors` by the POSITION index before
    // anything checks that index (mesh.rs, `primitive_validate_hook`): check it first.
    let position = Checked::Valid(gltf::json::mesh::Semantic::Positions);
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            match primitive.attributes.get(&position) {
                Some(index) if index.value() >= root.accessors.len() => {
                    return Err(format!(
                    "meshes[{m}].primitives[{p}].attributes[\"POSITION\"]: accessor {} does not exist ({} accessors)",
                    index.value(),
                    root.accessors.len()
                ))
                }
                _ => {}
            }
        }
    }
    let mut fatal = Vec::new();
    let mut missing_bounds = 0usize;
    root.validate(root, gltf::json::Path::new, &mut |path, error| {
        let path = path().to_string();
        let position = path.contains("attributes[\"POSITION\"]");
        match error {
            Error::Missing if position && (path.ends_with(".min") || path.ends_with(".max")) => missing_bounds += 1,
            Error::Missing if path.ends_with("attributes[\"POSITION\"]") => {}
            _ => fatal.push(format!("{path}: {error}")),
        }
    });
    if !fatal.is_empty() {
        return Err(fatal.join("; "));
    }
    Ok((missing_bounds > 0).then(|| {
        format!("{missing_bounds} POSITION accessor bounds (min/max) are missing; tolerated, they are not used")
    }))
}

/// The state of one conversion.
struct Converter<'a> {
    path: &'a Path,
    buffers: &'a [Vec<u8>],
    scene: Scene,
    /// What may still be allocated for decoded data and objects.
    budget: Budget,
    /// Notes already recorded (a note said once per file, however many primitives repeat it).
    noted: HashSet<String>,
    mode_from_extras: Vec<bool>,
    /// (glTF mesh, primitive) -> index in `scene.meshes`.
    meshes: HashMap<(usize, usize), usize>,
    /// glTF material index (`None`: the default grey) -> index in `scene.materials`.
    materials: HashMap<Option<usize>, usize>,
    /// A camera without `zfar`: its far distance is derived from the bounds at the end.
    camera_needs_far: bool,
    /// Where a `.gltf` file's image files are read from.
    files: &'a dyn SceneFiles,
    /// glTF image index -> index in `scene.textures` (each image decoded once).
    images: HashMap<usize, usize>,
    /// The file's images as JSON (`gltf::Image::source` unwraps fields no validation
    /// checks: read them here instead).
    image_json: Vec<gltf::json::Image>,
    /// Per glTF buffer view: its bytes, or why they are out of range.
    views: Vec<Result<&'a [u8], String>>,
    /// The nodes walked, in walk order (what [`SceneAnimation`] keeps when the file has
    /// animations).
    nodes: Vec<SceneNode>,
    /// glTF node index -> index in `nodes` (`None`: not in the scene walked).
    node_slot: Vec<Option<usize>>,
    /// Labels of the nodes with a skin and of the meshes with morph targets met in the walk.
    skinned: Vec<String>,
    morphed: Vec<String>,
}

impl<'a> Converter<'a> {
    fn new(path: &'a Path, buffers: &'a [Vec<u8>], files: &'a dyn SceneFiles, budget: Budget) -> Self {
        Converter {
            path,
            buffers,
            scene: Scene::default(),
            budget,
            noted: HashSet::new(),
            mode_from_extras: Vec::new(),
            meshes: HashMap::new(),
            materials: HashMap::new(),
            camera_needs_far: false,
            files,
            images: HashMap::new(),
            image_json: Vec::new(),
            views: Vec::new(),
            nodes: Vec::new(),
            node_slot: Vec::new(),
            skinned: Vec::new(),
            morphed: Vec::new(),
        }
    }

    /// Record a note once per file.
    fn note_once(&mut self, note: String) {
        if self.noted.insert(note.clone()) {
            self.scene.notes.push(note);
        }
    }

    fn content(&self, message: String) -> SceneError {
        SceneError::Content { path: self.path.to_path_buf(), message }
    }

    /// Convert the document: the scene, whether each object's render mode came from extras,
    /// and the hierarchy walked unless the scene keeps it (when the file has animations).
    fn run(mut self, document: &gltf::Document) -> Result<(Scene, Vec<bool>, Vec<SceneNode>), SceneError> {
        self.image_json = document.as_json().images.clone();
        let buffers = self.buffers;
        self.views = document.views().map(|view| view_bytes(&view, buffers)).collect();
        let roots: Vec<gltf::Node> = match document.default_scene().or_else(|| document.scenes().next()) {
            Some(scene) => scene.nodes().collect(),
            None => {
                let mut is_child = vec![false; document.nodes().len()];
                for node in document.nodes() {
                    for child in node.children() {
                        is_child[child.index()] = true;
                    }
                }
                self.scene.notes.push(format!(
                    "{}: the file has no scene: using every node that has no parent",
                    self.path.display()
                ));
                document.nodes().filter(|n| !is_child[n.index()]).collect()
            }
        };
        // Depth-first, children in file order: a stack popped from the back, pushed reversed.
        // Each entry carries its parent's world transform and index in `self.nodes`.
        self.node_slot = vec![None; document.nodes().len()];
        let mut stack: Vec<(gltf::Node, Mat4, Option<usize>)> =
            roots.into_iter().rev().map(|n| (n, Mat4::IDENTITY, None)).collect();
        while let Some((node, parent, parent_slot)) = stack.pop() {
            if self.node_slot[node.index()].is_some() {
                return Err(self.content(format!(
                    "node {} is reached twice in the node hierarchy (a cycle, or a node with two parents)",
                    node.index()
                )));
            }
            let rest = Mat4::from_cols_array_2d(&node.transform().matrix());
            let world = parent * rest;
            let slot = self.visit(&node, world, rest, parent_slot)?;
            let children: Vec<gltf::Node> = node.children().collect();
            stack.extend(children.into_iter().rev().map(|c| (c, world, Some(slot))));
        }
        if self.camera_needs_far {
            self.derive_camera_far();
        }
        self.note_skins_and_morph_targets();
        if document.animations().len() > 0 {
            let animations = self.animations(document)?;
            let nodes = std::mem::take(&mut self.nodes);
            self.scene.animation = Some(SceneAnimation::new(nodes, animations).map_err(|e| self.content(e))?);
        }
        Ok((self.scene, self.mode_from_extras, self.nodes))
    }

    /// Convert what `node` places at `world` (its local matrix `rest`), record it in the
    /// hierarchy under `parent` and return its index there.
    fn visit(
        &mut self,
        node: &gltf::Node,
        world: Mat4,
        rest: Mat4,
        parent: Option<usize>,
    ) -> Result<usize, SceneError> {
        let node_label = match node.name() {
            Some(name) => format!("node {} '{name}'", node.index()),
            None => format!("node {}", node.index()),
        };
        let had_camera = self.scene.camera.is_some();
        if let Some(camera) = node.camera() {
            self.camera(&camera, &node_label, world);
        }
        let lights = self.scene.lights.len();
        if let Some(light) = node.light() {
            self.light(&light, &node_label, world);
        }
        let first_object = self.scene.objects.len() as u32;
        if node.skin().is_some() {
            self.skinned.push(node_label.clone());
        }
        self.place_mesh(node, world, &node_label)?;
        let transform = match node.transform() {
            gltf::scene::Transform::Matrix { matrix } => NodeTransform::Matrix(Mat4::from_cols_array_2d(&matrix)),
            gltf::scene::Transform::Decomposed { translation, rotation, scale } => NodeTransform::Trs {
                translation: Vec3::from(translation),
                rotation: Quat::from_array(rotation),
                scale: Vec3::from(scale),
            },
        };
        self.nodes.push(SceneNode {
            gltf_index: Some(node.index()),
            label: node_label,
            parent,
            transform,
            rest,
            objects: (first_object..self.scene.objects.len() as u32).collect(),
            camera: !had_camera && self.scene.camera.is_some(),
            light: (self.scene.lights.len() > lights).then_some(lights),
        });
        self.node_slot[node.index()] = Some(self.nodes.len() - 1);
        Ok(self.nodes.len() - 1)
    }

    /// One object per triangle primitive of the node's mesh, at `world`.
    fn place_mesh(&mut self, node: &gltf::Node, world: Mat4, node_label: &str) -> Result<(), SceneError> {
        let Some(mesh) = node.mesh() else {
            return Ok(());
        };
        let node_mode = self.hyrt_ray_traced(node.extras(), node_label)?;
        let mesh_label = match mesh.name() {
            Some(name) => format!("mesh {} '{name}'", mesh.index()),
            None => format!("mesh {}", mesh.index()),
        };
        let morphed = mesh.weights().is_some() || mesh.primitives().any(|p| p.morph_targets().len() > 0);
        if morphed && !self.morphed.contains(&mesh_label) {
            self.morphed.push(mesh_label.clone());
        }
        let mesh_mode = self.hyrt_ray_traced(mesh.extras(), &mesh_label)?;
        let base_name =
            node.name().or(mesh.name()).map(str::to_string).unwrap_or_else(|| format!("node{}", node.index()));
        for primitive in mesh.primitives() {
            let prim_label = format!("{mesh_label} primitive {}", primitive.index());
            if primitive.mode() != Mode::Triangles {
                let note = format!(
                    "{}: {prim_label}: mode {:?} is not TRIANGLES: skipped",
                    self.path.display(),
                    primitive.mode()
                );
                if self.noted.insert(note.clone()) {
                    self.scene.notes.push(note);
                }
                continue;
            }
            let key = (mesh.index(), primitive.index());
            let mesh_index = match self.meshes.get(&key) {
                Some(&i) => i,
                None => {
                    let name = format!(
                        "{}#{}",
                        mesh.name().map(str::to_string).unwrap_or_else(|| format!("mesh{}", mesh.index())),
                        primitive.index()
                    );
                    let m = self.read_primitive(&primitive, name, &prim_label)?;
                    self.scene.meshes.push(m);
                    self.meshes.insert(key, self.scene.meshes.len() - 1);
                    self.scene.meshes.len() - 1
                }
            };
            let gltf_material = primitive.material();
            let (material, material_mode) = self.material(&gltf_material)?;
            let from_extras = node_mode.or(mesh_mode).or(material_mode);
            let render_mode = match from_extras {
                Some(true) => RenderMode::RayTraced,
                Some(false) => RenderMode::Raster,
                None => self.scene.materials[material].default_render_mode(),
            };
            let id = u32::try_from(self.scene.objects.len())
                .map_err(|_| self.content("more than 2^32 objects (object ids are 32-bit)".into()))?;
            let object_bytes = std::mem::size_of::<Object>() + base_name.len();
            self.budget.take(1, object_bytes, "objects").map_err(|e| self.content(format!("{node_label}: {e}")))?;
            self.scene.objects.push(Object {
                id,
                name: format!("{base_name}#{}", primitive.index()),
                mesh: mesh_index,
                transform: world,
                material,
                render_mode,
                source: ObjectSource {
                    file: Some(self.path.to_path_buf()),
                    node: Some(node.index()),
                    mesh: Some(mesh.index()),
                    primitive: Some(primitive.index()),
                },
            });
            self.mode_from_extras.push(from_extras.is_some());
        }
        Ok(())
    }

    /// Read one triangle-list primitive into a [`Mesh`].
    fn read_primitive(&mut self, primitive: &gltf::Primitive, name: String, label: &str) -> Result<Mesh, SceneError> {
        let file = self.path.display().to_string();
        let Some(pos_acc) = primitive.get(&Semantic::Positions) else {
            return Err(self.content(format!("{label}: has no POSITION attribute")));
        };
        if pos_acc.data_type() != DataType::F32 || pos_acc.dimensions() != Dimensions::Vec3 {
            return Err(self.content(format!(
                "{label}: POSITION must be float32 VEC3, found {:?} {:?}",
                pos_acc.data_type(),
                pos_acc.dimensions()
            )));
        }
        let positions: Vec<Vec3> = read_accessor(&pos_acc, self.buffers, &mut self.budget, 12, read_vec3)
            .map_err(|e| self.gltf_error(format!("{label}: POSITION accessor {}: {e}", pos_acc.index())))?;
        let non_finite = positions.iter().filter(|p| !p.is_finite()).count();
        if non_finite > 0 {
            self.scene.notes.push(format!(
                "{file}: {label}: {non_finite} vertex positions are NaN or infinite; triangles using them are never hit"
            ));
        }
        let normals = match primitive.get(&Semantic::Normals) {
            None => None,
            Some(acc) if acc.data_type() != DataType::F32 || acc.dimensions() != Dimensions::Vec3 => {
                self.scene.notes.push(format!(
                    "{file}: {label}: NORMAL is {:?} {:?}, not float32 VEC3: ignored (face normals used)",
                    acc.data_type(),
                    acc.dimensions()
                ));
                None
            }
            Some(acc) if acc.count() != positions.len() => {
                self.scene.notes.push(format!(
                    "{file}: {label}: {} normals for {} positions: ignored (face normals used)",
                    acc.count(),
                    positions.len()
                ));
                None
            }
            Some(acc) => Some(
                read_accessor(&acc, self.buffers, &mut self.budget, 12, read_vec3)
                    .map_err(|e| self.gltf_error(format!("{label}: NORMAL accessor {}: {e}", acc.index())))?,
            ),
        };
        let flat: Vec<u32> = match primitive.indices() {
            None => {
                let n = u32::try_from(positions.len())
                    .map_err(|_| self.content(format!("{label}: more than 2^32 vertices")))?;
                self.budget
                    .take(positions.len(), 4, "implicit indices")
                    .map_err(|e| self.gltf_error(format!("{label}: {e}")))?;
                (0..n).collect()
            }
            Some(acc) => {
                if acc.dimensions() != Dimensions::Scalar {
                    return Err(self.content(format!("{label}: indices must be SCALAR, found {:?}", acc.dimensions())));
                }
                let (buffers, budget) = (self.buffers, &mut self.budget);
                let read = match acc.data_type() {
                    DataType::U8 => read_accessor(&acc, buffers, budget, 1, |b| b[0] as u32),
                    DataType::U16 => {
                        read_accessor(&acc, buffers, budget, 2, |b| u16::from_le_bytes([b[0], b[1]]) as u32)
                    }
                    DataType::U32 => {
                        read_accessor(&acc, buffers, budget, 4, |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    }
                    other => {
                        return Err(self.content(format!(
                            "{label}: indices must be unsigned 8/16/32-bit integers, found {other:?}"
                        )))
                    }
                };
                read.map_err(|e| self.gltf_error(format!("{label}: indices accessor {}: {e}", acc.index())))?
            }
        };
        if !flat.chunks_exact(3).remainder().is_empty() {
            return Err(
                self.content(format!("{label}: {} indices is not a multiple of 3 (mode TRIANGLES)", flat.len()))
            );
        }
        if let Some((k, &bad)) = flat.iter().enumerate().find(|(_, &i)| i as usize >= positions.len()) {
            return Err(self.content(format!(
                "{label}: index {bad} (at position {k} of the index list) is out of range: the primitive has {} vertices",
                positions.len()
            )));
        }
        let indices = flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        let mut attributes = VertexAttributes::default();
        for set in 0..2u32 {
            attributes.tex_coords[set as usize] = self
                .vertex_attribute(primitive, Semantic::TexCoords(set), positions.len(), label)?
                .map(|v| v.into_iter().map(|c| Vec2::new(c[0], c[1])).collect());
        }
        attributes.colors = self.vertex_attribute(primitive, Semantic::Colors(0), positions.len(), label)?;
        if let Some(acc) = primitive.get(&Semantic::Tangents) {
            if acc.data_type() != DataType::F32 {
                return Err(self.content(format!("{label}: TANGENT must be float32 VEC4, found {:?}", acc.data_type())));
            }
            attributes.tangents = self.vertex_attribute(primitive, Semantic::Tangents, positions.len(), label)?;
        }
        Ok(Mesh { name, positions, normals, indices, attributes })
    }

    /// A `TEXCOORD_n`, `COLOR_0` or `TANGENT` attribute as floats (`[x, y, 0, 1]` for `VEC2`,
    /// `[r, g, b, 1]` for `VEC3`), normalized integers divided by their maximum as glTF
    /// says; `None` without one. Any other type, or a count other than the positions', is
    /// an error: a texture mapped through a wrong attribute is silently wrong output.
    fn vertex_attribute(
        &mut self,
        primitive: &gltf::Primitive,
        semantic: Semantic,
        vertices: usize,
        label: &str,
    ) -> Result<Option<Vec<[f32; 4]>>, SceneError> {
        let Some(acc) = primitive.get(&semantic) else {
            return Ok(None);
        };
        let what = semantic.to_string();
        let dims = match (&semantic, acc.dimensions()) {
            (Semantic::TexCoords(_), Dimensions::Vec2) => 2,
            (Semantic::Colors(_), Dimensions::Vec3) => 3,
            (Semantic::Colors(_), Dimensions::Vec4) => 4,
            (Semantic::Tangents, Dimensions::Vec4) => 4,
            (_, other) => return Err(self.content(format!("{label}: {what} cannot be {other:?}"))),
        };
        let data_type = acc.data_type();
        match data_type {
            DataType::F32 => {}
            DataType::U8 | DataType::U16 if acc.normalized() => {}
            other => {
                return Err(self.content(format!(
                    "{label}: {what} must be float32 or normalized unsigned 8/16-bit, found {other:?}{}",
                    if acc.normalized() { "" } else { " (not normalized)" }
                )))
            }
        };
        if acc.count() != vertices {
            return Err(self.content(format!("{label}: {} {what} values for {vertices} positions", acc.count())));
        }
        let size = data_type.size();
        let values = read_accessor(&acc, self.buffers, &mut self.budget, dims * size, |b| {
            let mut v = [0.0, 0.0, 0.0, 1.0];
            for (k, c) in v.iter_mut().take(dims).enumerate() {
                *c = component_f32(data_type, &b[k * size..]);
            }
            v
        })
        .map_err(|e| self.gltf_error(format!("{label}: {what} accessor {}: {e}", acc.index())))?;
        if let Some(k) = values.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
            return Err(self.content(format!("{label}: {what} value {k} is not finite: {:?}", values[k])));
        }
        Ok(Some(values))
    }

    fn gltf_error(&self, message: String) -> SceneError {
        SceneError::Gltf { path: self.path.to_path_buf(), message }
    }

    /// The index in `scene.materials` of a glTF material (converted once), and its `hyrt` extra.
    fn material(&mut self, m: &gltf::Material) -> Result<(usize, Option<bool>), SceneError> {
        let mode = match m.index() {
            Some(i) => {
                let label = match m.name() {
                    Some(name) => format!("material {i} '{name}'"),
                    None => format!("material {i}"),
                };
                self.hyrt_ray_traced(m.extras(), &label)?
            }
            None => None,
        };
        if let Some(&i) = self.materials.get(&m.index()) {
            return Ok((i, mode));
        }
        let material = match m.index() {
            None => Material::grey(),
            Some(i) => self.convert_material(m, i)?,
        };
        self.scene.materials.push(material);
        self.materials.insert(m.index(), self.scene.materials.len() - 1);
        Ok((self.scene.materials.len() - 1, mode))
    }

    /// Convert a glTF material (see the module docs for the rule), decoding its base-colour
    /// texture's image the first time one uses it.
    fn convert_material(&mut self, m: &gltf::Material, index: usize) -> Result<Material, SceneError> {
        let label = match m.name() {
            Some(name) => format!("material {index} '{name}'"),
            None => format!("material {index}"),
        };
        let pbr = m.pbr_metallic_roughness();
        let [r, g, b, a] = pbr.base_color_factor();
        let metallic = pbr.metallic_factor();
        let transmission = m.transmission().map(|t| t.transmission_factor()).unwrap_or(0.0);
        let ior = m.ior().unwrap_or(DEFAULT_IOR);
        let base_color_texture = match pbr.base_color_texture() {
            None => None,
            Some(info) => Some(self.texture_binding(&info, &label, "baseColorTexture")?),
        };
        let metallic_roughness = match pbr.metallic_roughness_texture() {
            None => None,
            Some(info) => Some(self.texture_binding(&info, &label, "metallicRoughnessTexture")?),
        };
        let (occlusion, occlusion_strength) = match m.occlusion_texture() {
            None => (None, 1.0),
            Some(o) => {
                let strength = o.strength();
                if !(0.0..=1.0).contains(&strength) {
                    return Err(
                        self.content(format!("{label}: occlusionTexture.strength {strength} is outside [0, 1]"))
                    );
                }
                let transform = o.extension_value("KHR_texture_transform");
                let parts = TextureInfoParts { texture: o.texture(), tex_coord: o.tex_coord(), transform: None };
                let binding = self.binding_of(parts, transform, &label, "occlusionTexture")?;
                (Some(binding), strength)
            }
        };
        let emissive_texture = match m.emissive_texture() {
            None => None,
            Some(info) => Some(self.texture_binding(&info, &label, "emissiveTexture")?),
        };
        let strength = m.emissive_strength().unwrap_or(1.0);
        let emissive = Vec3::from(m.emissive_factor()) * strength;
        if !(emissive.is_finite() && emissive.min_element() >= 0.0) {
            return Err(self.content(format!(
                "{label}: emissiveFactor x KHR_materials_emissive_strength is {emissive}, not a finite non-negative colour"
            )));
        }
        let (normal, normal_scale) = match m.normal_texture() {
            None => (None, 1.0),
            Some(t) => {
                let scale = t.scale();
                if !scale.is_finite() {
                    return Err(self.content(format!("{label}: normalTexture.scale {scale} is not finite")));
                }
                let transform = t.extension_value("KHR_texture_transform");
                let parts = TextureInfoParts { texture: t.texture(), tex_coord: t.tex_coord(), transform: None };
                (Some(self.binding_of(parts, transform, &label, "normalTexture")?), scale)
            }
        };
        let maps = MaterialMaps {
            metallic_roughness,
            occlusion,
            occlusion_strength,
            emissive: emissive_texture,
            normal,
            normal_scale,
        };
        self.check_shared_coordinates(&label, base_color_texture, &maps);
        let alpha_mode = match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            gltf::material::AlphaMode::Mask => {
                let cutoff = m.alpha_cutoff().unwrap_or(AlphaMode::DEFAULT_CUTOFF);
                if !(0.0..=1.0).contains(&cutoff) {
                    return Err(self.content(format!("{label}: alphaCutoff {cutoff} is outside [0, 1]")));
                }
                AlphaMode::Mask { cutoff }
            }
            gltf::material::AlphaMode::Blend => {
                self.note_once(format!(
                    "{}: {label}: alphaMode BLEND is rendered as MASK at alpha {} (hyrt has no transparency sorting)",
                    self.path.display(),
                    AlphaMode::BLEND_CUTOFF
                ));
                AlphaMode::Blend
            }
        };
        Ok(Material {
            name: m.name().map(str::to_string).unwrap_or_else(|| format!("material{index}")),
            base_color: Vec3::new(r, g, b),
            metallic,
            roughness: pbr.roughness_factor(),
            transmission,
            kind: material_kind(metallic, transmission, ior),
            base_alpha: a,
            base_color_texture,
            alpha_mode,
            emissive,
            double_sided: m.double_sided(),
            maps,
        })
    }

    /// hyrt samples all of a material's textures at one set of coordinates, the first
    /// texture's (`hyrt_core::scene::MaterialMaps`): say so where the material's textures
    /// differ in coordinate set or transform.
    fn check_shared_coordinates(&mut self, label: &str, base: Option<TextureBinding>, maps: &MaterialMaps) {
        let all = [base, maps.metallic_roughness, maps.occlusion, maps.emissive, maps.normal];
        let mut bound = all.iter().flatten();
        let Some(first) = bound.next() else { return };
        if bound.any(|b| b.tex_coord != first.tex_coord || b.transform != first.transform) {
            self.note_once(format!(
                "{}: {label}: its textures use different texture coordinates or transforms; hyrt samples them all \
                 at the first's (TEXCOORD_{})",
                self.path.display(),
                first.tex_coord
            ));
        }
    }

    /// A material's texture (`slot`: its glTF name, for messages): its image (decoded
    /// once), sampler, coordinate set and `KHR_texture_transform`.
    fn texture_binding(
        &mut self,
        info: &gltf::texture::Info,
        label: &str,
        slot: &str,
    ) -> Result<TextureBinding, SceneError> {
        let transform = info.texture_transform().map(|t| UvTransformJson {
            tex_coord: t.tex_coord(),
            offset: t.offset(),
            rotation: t.rotation(),
            scale: t.scale(),
        });
        let parts = TextureInfoParts { texture: info.texture(), tex_coord: info.tex_coord(), transform };
        self.binding_of(parts, None, label, slot)
    }

    /// [`Self::texture_binding`] of a texture reference's parts; `extension` is its raw
    /// `KHR_texture_transform` object where the `gltf` crate does not parse it (the
    /// occlusion and normal textures).
    fn binding_of(
        &mut self,
        parts: TextureInfoParts,
        extension: Option<&gltf::json::Value>,
        label: &str,
        slot: &str,
    ) -> Result<TextureBinding, SceneError> {
        use gltf::texture::{MagFilter, MinFilter, WrappingMode};
        let texture = parts.texture;
        let image = self.image(texture.source().index(), label)?;
        let s = texture.sampler();
        let wrap = |w: WrappingMode| match w {
            WrappingMode::ClampToEdge => Wrap::ClampToEdge,
            WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
            WrappingMode::Repeat => Wrap::Repeat,
        };
        let mag = match s.mag_filter() {
            Some(MagFilter::Nearest) => Filter::Nearest,
            _ => Filter::Linear,
        };
        let (min, mip) = match s.min_filter() {
            Some(MinFilter::Nearest) => (Filter::Nearest, None),
            Some(MinFilter::Linear) => (Filter::Linear, None),
            Some(MinFilter::NearestMipmapNearest) => (Filter::Nearest, Some(Filter::Nearest)),
            Some(MinFilter::LinearMipmapNearest) => (Filter::Linear, Some(Filter::Nearest)),
            Some(MinFilter::NearestMipmapLinear) => (Filter::Nearest, Some(Filter::Linear)),
            Some(MinFilter::LinearMipmapLinear) | None => (Filter::Linear, Some(Filter::Linear)),
        };
        let sampler = Sampler { wrap_s: wrap(s.wrap_s()), wrap_t: wrap(s.wrap_t()), mag, min, mip };
        let json =
            match (parts.transform, extension) {
                (Some(t), _) => Some(t),
                (None, Some(value)) => Some(UvTransformJson::parse(value).map_err(|e| {
                    self.content(format!("{label}: {slot}'s KHR_texture_transform does not parse: {e}"))
                })?),
                (None, None) => None,
            };
        let (tex_coord, transform) = match json {
            None => (parts.tex_coord, UvTransform::default()),
            Some(t) => (
                t.tex_coord.unwrap_or(parts.tex_coord),
                UvTransform { offset: t.offset.into(), rotation: t.rotation, scale: t.scale.into() },
            ),
        };
        if tex_coord > 1 {
            return Err(self
                .content(format!("{label}: {slot} uses TEXCOORD_{tex_coord}; hyrt reads TEXCOORD_0 and TEXCOORD_1")));
        }
        let finite = transform.offset.is_finite() && transform.rotation.is_finite() && transform.scale.is_finite();
        if !finite {
            return Err(self.content(format!("{label}: {slot}'s KHR_texture_transform is not finite: {transform:?}")));
        }
        Ok(TextureBinding { image, sampler, tex_coord, transform })
    }

    /// The index in `scene.textures` of glTF image `index`, decoded (PNG or JPEG, from a
    /// buffer view, a data URI or a file beside a `.gltf`) the first time it is asked for.
    fn image(&mut self, index: usize, user: &str) -> Result<usize, SceneError> {
        if let Some(&i) = self.images.get(&index) {
            return Ok(i);
        }
        let json = self
            .image_json
            .get(index)
            .cloned()
            .ok_or_else(|| self.content(format!("{user}: image {index} does not exist")))?;
        let label = match &json.name {
            Some(name) => format!("image {index} '{name}'"),
            None => format!("image {index}"),
        };
        let fail = |message: String| SceneError::Content {
            path: self.path.to_path_buf(),
            message: format!("{label} (used by {user}): {message}"),
        };
        let (bytes, source) = match (&json.buffer_view, &json.uri) {
            (Some(view), None) => {
                let bytes = match self.views.get(view.value()) {
                    Some(Ok(bytes)) => bytes.to_vec(),
                    Some(Err(e)) => return Err(fail(e.clone())),
                    None => return Err(fail(format!("buffer view {} does not exist", view.value()))),
                };
                (bytes, None)
            }
            (None, Some(uri)) if uri.starts_with("data:") => {
                let data = gltf::buffer::Data::from_source(gltf::buffer::Source::Uri(uri), None)
                    .map(|d| d.0)
                    .map_err(|e| fail(format!("its data URI does not decode: {e}")))?;
                (data, None)
            }
            (None, Some(uri)) => {
                let relative = relative_uri_path(uri).map_err(|e| fail(format!("URI '{uri}': {e}")))?;
                let file = self.path.parent().unwrap_or(Path::new("")).join(relative);
                let data =
                    self.files.read(&file).map_err(|e| fail(format!("cannot read '{}': {e}", file.display())))?;
                self.budget.add_input(data.len());
                (data, Some(file))
            }
            _ => return Err(fail("an image needs exactly one of uri and bufferView".into())),
        };
        let decoded = decode_image(&bytes, &mut self.budget).map_err(fail)?;
        let name = json
            .name
            .clone()
            .or(json.uri.clone().filter(|u| !u.starts_with("data:")))
            .unwrap_or_else(|| format!("image{index}"));
        let mut image = TextureImage::new(name, decoded.0, decoded.1, decoded.2).map_err(fail)?;
        image.source = source;
        self.scene.textures.push(std::sync::Arc::new(image));
        self.images.insert(index, self.scene.textures.len() - 1);
        Ok(self.scene.textures.len() - 1)
    }

    /// Parse `{"hyrt": {"ray_traced": bool}}` out of an `extras` value.
    fn hyrt_ray_traced(&self, extras: &gltf::json::Extras, what: &str) -> Result<Option<bool>, SceneError> {
        let Some(raw) = extras else { return Ok(None) };
        let value: serde_json::Value = serde_json::from_str(raw.get())
            .map_err(|e| self.gltf_error(format!("{what}: extras are not valid JSON: {e}")))?;
        let Some(hyrt) = value.get("hyrt") else {
            return Ok(None);
        };
        let bad = || self.content(format!("{what}: extras.hyrt must be {{\"ray_traced\": true|false}}, found {hyrt}"));
        let obj = hyrt.as_object().ok_or_else(bad)?;
        if obj.keys().any(|k| k != "ray_traced") {
            return Err(bad());
        }
        match obj.get("ray_traced") {
            None => Ok(None),
            Some(v) => v.as_bool().map(Some).ok_or_else(bad),
        }
    }

    fn camera(&mut self, camera: &gltf::Camera, node_label: &str, world: Mat4) {
        if self.scene.camera.is_some() {
            return;
        }
        let file = self.path.display().to_string();
        let gltf::camera::Projection::Perspective(p) = camera.projection() else {
            self.scene.notes.push(format!("{file}: {node_label}: orthographic camera ignored"));
            return;
        };
        let fov_y_deg = p.yfov().to_degrees();
        let near = p.znear();
        let frame = camera_frame(world);
        let (Some((eye, forward, up)), true) =
            (frame, fov_y_deg > 0.0 && fov_y_deg < 180.0 && near > 0.0 && near.is_finite())
        else {
            self.scene.notes.push(format!(
                "{file}: {node_label}: camera ignored (degenerate transform, yfov {} rad or znear {near})",
                p.yfov()
            ));
            return;
        };
        let far = match p.zfar() {
            Some(far) if far > near && far.is_finite() => far,
            _ => {
                self.camera_needs_far = true;
                f32::INFINITY
            }
        };
        self.scene.camera = Some(Camera { eye, target: eye + forward, up, fov_y_deg, near, far });
    }

    /// Give a camera without a usable `zfar` a far distance from the scene bounds.
    fn derive_camera_far(&mut self) {
        let bounds = self.scene.world_bounds();
        let Some(cam) = self.scene.camera.as_mut() else {
            return;
        };
        let reach = bounds.map_or(0.0, |(lo, hi)| farthest_corner(cam.eye, lo, hi));
        // Twice the farthest corner (beyond twice near); 1000 near distances without geometry.
        cam.far = if reach > 0.0 { (2.0 * reach).max(2.0 * cam.near) } else { 1000.0 * cam.near };
        self.scene.notes.push(format!(
            "{}: camera has no finite zfar: far set to {:.4} from the scene bounds",
            self.path.display(),
            cam.far
        ));
    }

    fn light(&mut self, light: &gltf::khr_lights_punctual::Light, node_label: &str, world: Mat4) {
        use gltf::khr_lights_punctual::Kind;
        let file = self.path.display().to_string();
        let color = Vec3::from(light.color());
        let intensity = light.intensity();
        let range = light.range();
        let position = light_position(world);
        let loaded = match light.kind() {
            Kind::Directional => {
                let Some(direction) = light_direction(world) else {
                    self.scene.notes.push(format!("{file}: {node_label}: directional light with no direction ignored"));
                    return;
                };
                if range.is_some() {
                    self.scene.notes.push(format!("{file}: {node_label}: range of a directional light ignored"));
                }
                Light::Directional { direction, color, intensity }
            }
            Kind::Point => Light::Point { position, color, intensity, range },
            Kind::Spot { inner_cone_angle, outer_cone_angle } => {
                let Some(direction) = light_direction(world) else {
                    self.scene.notes.push(format!("{file}: {node_label}: spot light with no direction ignored"));
                    return;
                };
                Light::Spot { position, direction, color, intensity, inner_cone_angle, outer_cone_angle, range }
            }
        };
        match loaded.validate() {
            Ok(()) => self.scene.lights.push(loaded),
            Err(problem) => self.scene.notes.push(format!("{file}: {node_label}: light ignored: {problem}")),
        }
    }

    /// One note each for the skins and the morph targets met in the walk: neither is applied.
    fn note_skins_and_morph_targets(&mut self) {
        let file = self.path.display().to_string();
        let some = first_and_count;
        if !self.skinned.is_empty() {
            self.scene.notes.push(format!(
                "{file}: skins are not applied ({}): those meshes render unskinned, in their bind pose, placed by \
                 their node",
                some(&self.skinned)
            ));
        }
        if !self.morphed.is_empty() {
            self.scene.notes.push(format!(
                "{file}: morph targets are not applied ({}): those meshes render their base geometry, whatever \
                 their weights",
                some(&self.morphed)
            ));
        }
    }

    /// The file's animations (see the module docs). Channels of morph target `weights`, and
    /// channels driving nodes outside the scene walked, are left out with a note.
    fn animations(&mut self, document: &gltf::Document) -> Result<Vec<Animation>, SceneError> {
        use gltf::animation::Property;
        use gltf::json::validation::Checked;
        // gltf-json 1.4.1 validates an animation's samplers and channel sampler indices but
        // not its channels' targets, which `gltf::animation::Target` unwraps: check them here.
        for (a, animation) in document.as_json().animations.iter().enumerate() {
            for (c, channel) in animation.channels.iter().enumerate() {
                let at = format!("animations[{a}].channels[{c}].target");
                let node = channel.target.node.value();
                if node >= self.node_slot.len() {
                    return Err(self.gltf_error(format!(
                        "{at}.node: node {node} does not exist ({} nodes)",
                        self.node_slot.len()
                    )));
                }
                if let Checked::Invalid = channel.target.path {
                    return Err(self.gltf_error(format!("{at}.path: not translation, rotation, scale or weights")));
                }
            }
        }
        let mut weights: Vec<String> = Vec::new();
        let mut outside: Vec<String> = Vec::new();
        let mut animations = Vec::new();
        for animation in document.animations() {
            let label = match animation.name() {
                Some(name) => format!("animation {} '{name}'", animation.index()),
                None => format!("animation {}", animation.index()),
            };
            let mut samplers = Vec::new();
            // glTF sampler index -> (index in `samplers`, whether it holds rotations).
            let mut sampler_slot: HashMap<usize, (usize, bool)> = HashMap::new();
            // (node, property) -> the glTF channel driving it.
            let mut driven: HashMap<(usize, AnimatedProperty), usize> = HashMap::new();
            let mut channels = Vec::new();
            for channel in animation.channels() {
                let at = format!("{label} channel {}", channel.index());
                let target = channel.target();
                let property = match target.property() {
                    Property::Translation => AnimatedProperty::Translation,
                    Property::Rotation => AnimatedProperty::Rotation,
                    Property::Scale => AnimatedProperty::Scale,
                    Property::MorphTargetWeights => {
                        weights.push(at);
                        continue;
                    }
                };
                let Some(node) = self.node_slot[target.node().index()] else {
                    outside.push(format!("{at} (node {})", target.node().index()));
                    continue;
                };
                if let Some(first) = driven.insert((node, property), channel.index()) {
                    return Err(self.content(format!(
                        "{at}: drives the {} of node {}, as channel {first} does",
                        property.name(),
                        target.node().index()
                    )));
                }
                let sampler = channel.sampler();
                let rotations = property == AnimatedProperty::Rotation;
                let slot = match sampler_slot.get(&sampler.index()) {
                    Some(&(slot, held)) if held == rotations => slot,
                    Some(_) => {
                        return Err(self.content(format!(
                            "{at}: sampler {} drives both rotations and translations or scales",
                            sampler.index()
                        )))
                    }
                    None => {
                        samplers.push(self.animation_sampler(&sampler, property, &label)?);
                        sampler_slot.insert(sampler.index(), (samplers.len() - 1, rotations));
                        samplers.len() - 1
                    }
                };
                channels.push(AnimationChannel { node, property, sampler: slot });
            }
            let name =
                animation.name().map(str::to_string).unwrap_or_else(|| format!("animation{}", animation.index()));
            animations
                .push(Animation::new(name, channels, samplers).map_err(|e| self.content(format!("{label}: {e}")))?);
        }
        let file = self.path.display().to_string();
        let some = first_and_count;
        if !weights.is_empty() {
            self.scene.notes.push(format!(
                "{file}: morph target weights are not animated ({}): those channels are ignored",
                some(&weights)
            ));
        }
        if !outside.is_empty() {
            self.scene.notes.push(format!(
                "{file}: animation channels driving nodes outside the scene rendered are ignored ({})",
                some(&outside)
            ));
        }
        let summary: Vec<String> =
            animations.iter().map(|a| format!("'{}' ({:.3} s)", a.name(), a.duration())).collect();
        self.scene.notes.push(format!(
            "{file}: {} animation(s): {}; the scene is loaded in its rest pose (hyrt render --time T poses it)",
            animations.len(),
            summary.join(", ")
        ));
        Ok(animations)
    }

    /// A sampler's key times and values, checked (types here, counts and order in
    /// [`AnimationSampler::new`]): the input is float32 `SCALAR`; translations and scales are
    /// float32 `VEC3`, rotations float32 or normalized 8/16-bit integer `VEC4`.
    fn animation_sampler(
        &mut self,
        sampler: &gltf::animation::Sampler,
        property: AnimatedProperty,
        label: &str,
    ) -> Result<AnimationSampler, SceneError> {
        let at = format!("{label} sampler {}", sampler.index());
        let input = sampler.input();
        if input.data_type() != DataType::F32 || input.dimensions() != Dimensions::Scalar || input.normalized() {
            return Err(self.content(format!(
                "{at}: input (key times) must be float32 SCALAR, found {:?} {:?}",
                input.data_type(),
                input.dimensions()
            )));
        }
        let times = read_accessor(&input, self.buffers, &mut self.budget, 4, |b| component_f32(DataType::F32, b))
            .map_err(|e| self.gltf_error(format!("{at}: input accessor {}: {e}", input.index())))?;
        let output = sampler.output();
        let (dimensions, rotation) = match property {
            AnimatedProperty::Rotation => (Dimensions::Vec4, true),
            AnimatedProperty::Translation | AnimatedProperty::Scale => (Dimensions::Vec3, false),
        };
        let data_type = output.data_type();
        let type_ok = match data_type {
            DataType::F32 => !output.normalized(),
            DataType::I8 | DataType::U8 | DataType::I16 | DataType::U16 => rotation && output.normalized(),
            DataType::U32 => false,
        };
        if output.dimensions() != dimensions || !type_ok {
            let allowed = if rotation { "float32 or normalized 8/16-bit integer VEC4" } else { "float32 VEC3" };
            return Err(self.content(format!(
                "{at}: output of a {} channel must be {allowed}, found {:?} {:?}{}",
                property.name(),
                data_type,
                output.dimensions(),
                if output.normalized() { " (normalized)" } else { "" }
            )));
        }
        let size = data_type.size();
        let components = if rotation { 4 } else { 3 };
        let values = read_accessor(&output, self.buffers, &mut self.budget, components * size, |b| {
            let mut v = [0.0f32; 4];
            for (k, c) in v.iter_mut().take(components).enumerate() {
                *c = component_f32(data_type, &b[k * size..]);
            }
            v
        })
        .map_err(|e| self.gltf_error(format!("{at}: output accessor {}: {e}", output.index())))?;
        let values = if rotation {
            Keyframes::Rotations(values.into_iter().map(Quat::from_array).collect())
        } else {
            Keyframes::Vectors(values.into_iter().map(|v| Vec3::new(v[0], v[1], v[2])).collect())
        };
        let interpolation = match sampler.interpolation() {
            gltf::animation::Interpolation::Step => Interpolation::Step,
            gltf::animation::Interpolation::Linear => Interpolation::Linear,
            gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
        };
        AnimationSampler::new(times, values, interpolation)
            .map_err(|e| self.content(format!("{at} ({} {}): {e}", interpolation.name(), property.name())))
    }
}

/// `a`, or `a and 2 more`: what a note names of a list.
fn first_and_count(labels: &[String]) -> String {
    match labels {
        [first, rest @ ..] if !rest.is_empty() => format!("{first} and {} more", rest.len()),
        _ => labels.join(""),
    }
}

/// One accessor component as a float: float32 as it is, normalized integers as glTF maps
/// them (unsigned: `c / max`; signed: `max(c / max, -1)`). `b` starts at the component.
fn component_f32(data_type: DataType, b: &[u8]) -> f32 {
    match data_type {
        DataType::U8 => b[0] as f32 / 255.0,
        DataType::I8 => (b[0] as i8 as f32 / 127.0).max(-1.0),
        DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as f32 / 65535.0,
        DataType::I16 => (i16::from_le_bytes([b[0], b[1]]) as f32 / 32767.0).max(-1.0),
        DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
        DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
    }
}

/// The kind rule shared with the manifest: transmission > 0 is glass, metallic >= 0.5 is
/// specular, everything else is diffuse.
pub(crate) fn material_kind(metallic: f32, transmission: f32, ior: f32) -> MaterialKind {
    if transmission > 0.0 {
        MaterialKind::Glass { ior }
    } else if metallic >= METALLIC_SPECULAR_THRESHOLD {
        MaterialKind::Specular
    } else {
        MaterialKind::Diffuse
    }
}

/// Decode a PNG or JPEG image (told apart by their signatures, whatever the MIME type
/// says) to RGBA8: `(width, height, texels)`. Its texels are charged to `budget` before the
/// decoder allocates them (the decoder is limited to what is left of it), so a small file
/// claiming a huge image is an error, not an allocation.
fn decode_image(bytes: &[u8], budget: &mut Budget) -> Result<(u32, u32, Vec<[u8; 4]>), String> {
    let format = match image::guess_format(bytes) {
        Ok(f @ (image::ImageFormat::Png | image::ImageFormat::Jpeg)) => f,
        Ok(other) => return Err(format!("{other:?} images are not read (PNG and JPEG are)")),
        Err(_) => return Err("neither a PNG nor a JPEG image".into()),
    };
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(TextureImage::MAX_SIDE);
    limits.max_image_height = Some(TextureImage::MAX_SIDE);
    limits.max_alloc = Some(budget.left() as u64);
    reader.limits(limits);
    let (width, height) = reader.into_dimensions().map_err(|e| format!("{format:?} header: {e}"))?;
    budget.take(width as usize * height as usize, 4, "image texels")?;
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let mut limits = image::Limits::default();
    limits.max_alloc = Some((budget.left() as u64).saturating_add(width as u64 * height as u64 * 4));
    reader.limits(limits);
    let rgba = reader.decode().map_err(|e| format!("{format:?} data: {e}"))?.into_rgba8();
    let (w, h) = rgba.dimensions();
    Ok((w, h, rgba.pixels().map(|p| p.0).collect()))
}

fn read_vec3(b: &[u8]) -> Vec3 {
    let f = |k: usize| f32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]]);
    Vec3::new(f(0), f(4), f(8))
}

/// Read every element of an accessor (`elem` bytes each, decoded by `decode`), with its
/// sparse substitutions, checking every byte range; an accessor without a buffer view is
/// all zeros. Errors say what is out of range.
fn read_accessor<T: Copy>(
    acc: &gltf::Accessor,
    buffers: &[Vec<u8>],
    budget: &mut Budget,
    elem: usize,
    decode: impl Fn(&[u8]) -> T,
) -> Result<Vec<T>, String> {
    let count = acc.count();
    let zero = decode(&[0u8; 16][..elem]);
    // Charged before anything is allocated: an accessor without a buffer view (all zeros)
    // can declare any count, and accessors shared by many primitives are read once each.
    budget.take(count, std::mem::size_of::<T>(), "elements")?;
    let mut out = match acc.view() {
        None => vec![zero; count],
        Some(view) => {
            let stride = view.stride().unwrap_or(elem);
            let bytes = view_bytes(&view, buffers)?;
            if stride < elem {
                return Err(format!("byte stride {stride} is smaller than the element size {elem}"));
            }
            strided(bytes, acc.offset(), stride, count, elem, &decode)?
        }
    };
    if let Some(sparse) = acc.sparse() {
        let n = sparse.count();
        budget.take(n, std::mem::size_of::<usize>() + std::mem::size_of::<T>(), "sparse elements")?;
        let indices = sparse.indices();
        let index_bytes = view_bytes(&indices.view(), buffers)?;
        let index_size = match indices.index_type() {
            gltf::accessor::sparse::IndexType::U8 => 1,
            gltf::accessor::sparse::IndexType::U16 => 2,
            gltf::accessor::sparse::IndexType::U32 => 4,
        };
        let targets = strided(index_bytes, indices.offset(), index_size, n, index_size, |b: &[u8]| {
            b.iter().rev().fold(0usize, |acc, &x| (acc << 8) | x as usize)
        })?;
        let values = sparse.values();
        let value_bytes = view_bytes(&values.view(), buffers)?;
        let values = strided(value_bytes, values.offset(), elem, n, elem, &decode)?;
        for (target, value) in targets.into_iter().zip(values) {
            let slot = out.get_mut(target).ok_or_else(|| format!("sparse index {target} >= count {count}"))?;
            *slot = value;
        }
    }
    Ok(out)
}

/// The bytes of a buffer view, range-checked against its buffer.
fn view_bytes<'b>(view: &gltf::buffer::View, buffers: &'b [Vec<u8>]) -> Result<&'b [u8], String> {
    let buffer = buffers
        .get(view.buffer().index())
        .ok_or_else(|| format!("buffer view {} names a missing buffer", view.index()))?;
    view.offset().checked_add(view.length()).and_then(|end| buffer.get(view.offset()..end)).ok_or_else(|| {
        format!(
            "buffer view {} (bytes {}..+{}) lies outside buffer {} ({} bytes)",
            view.index(),
            view.offset(),
            view.length(),
            view.buffer().index(),
            buffer.len()
        )
    })
}

/// `count` elements of `elem` bytes at `offset + i * stride` within `bytes`, all range-checked.
fn strided<T>(
    bytes: &[u8],
    offset: usize,
    stride: usize,
    count: usize,
    elem: usize,
    decode: impl Fn(&[u8]) -> T,
) -> Result<Vec<T>, String> {
    if count == 0 {
        return Ok(Vec::new());
    }
    let end = (count - 1).checked_mul(stride).and_then(|x| x.checked_add(offset)).and_then(|x| x.checked_add(elem));
    match end {
        Some(end) if end <= bytes.len() => {}
        _ => {
            return Err(format!(
            "{count} elements of {elem} bytes (stride {stride}, offset {offset}) do not fit in a {}-byte buffer view",
            bytes.len()
        ))
        }
    }
    Ok((0..count).map(|i| decode(&bytes[offset + i * stride..offset + i * stride + elem])).collect())
}

/// The parts of a glTF texture reference (`textureInfo`, `occlusionTextureInfo`,
/// `normalTextureInfo`) that a [`TextureBinding`] is made of.
struct TextureInfoParts<'a> {
    texture: gltf::Texture<'a>,
    tex_coord: u32,
    transform: Option<UvTransformJson>,
}

/// A `KHR_texture_transform` object's values (the extension's defaults where absent).
#[derive(Clone, Copy, Debug, serde::Deserialize)]
#[serde(rename_all = "camelCase")]
struct UvTransformJson {
    tex_coord: Option<u32>,
    #[serde(default)]
    offset: [f32; 2],
    #[serde(default)]
    rotation: f32,
    #[serde(default = "unit_scale")]
    scale: [f32; 2],
}

fn unit_scale() -> [f32; 2] {
    [1.0, 1.0]
}

impl UvTransformJson {
    fn parse(value: &gltf::json::Value) -> Result<UvTransformJson, String> {
        serde_json::from_value(value.clone()).map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strided_reads_are_range_checked_without_overflow() {
        let bytes: Vec<u8> = (0..16).collect();
        let first = |b: &[u8]| b[0];
        assert_eq!(strided(&bytes, 1, 5, 3, 2, first), Ok(vec![1, 6, 11]));
        assert_eq!(strided(&bytes, 0, 4, 0, 4, first), Ok(vec![]));
        assert!(strided(&bytes, 0, 4, 5, 4, first).is_err(), "one element too many");
        assert!(strided(&bytes, 13, 4, 1, 4, first).is_err(), "offset pushes it out");
        assert!(strided(&bytes, 0, usize::MAX / 2, 3, 4, first).is_err(), "count * stride overflows");
        assert!(strided(&bytes, usize::MAX, 4, 1, 4, first).is_err(), "offset + elem overflows");
    }

    /// Every world transform the old walk computes (`parent * node.matrix()`, roots under the
    /// identity), by glTF node index, for the file's default scene (or first scene).
    fn walked_transforms(document: &gltf::Document) -> HashMap<usize, Mat4> {
        let mut out = HashMap::new();
        let scene = document.default_scene().or_else(|| document.scenes().next()).expect("a scene");
        let mut stack: Vec<(gltf::Node, Mat4)> = scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
        while let Some((node, parent)) = stack.pop() {
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            out.insert(node.index(), world);
            stack.extend(node.children().map(|c| (c, world)));
        }
        out
    }

    /// Every model of the shared assets, and the repository's sample scenes, loads to the
    /// transforms the walk computes, and the hierarchy kept for animation poses them again
    /// bit for bit.
    #[test]
    fn every_asset_loads_and_poses_the_walked_transforms_bit_for_bit() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut files = Vec::new();
        for dir in [root.join("../../shared/assets"), root.join("../assets/scenes")] {
            let Ok(entries) = std::fs::read_dir(&dir) else {
                eprintln!("{} is absent: its files are skipped", dir.display());
                continue;
            };
            files.extend(
                entries.map(|e| e.unwrap().path()).filter(|p| p.extension().is_some_and(|e| e == "glb" || e == "gltf")),
            );
        }
        let bits = |m: Mat4| m.to_cols_array().map(f32::to_bits);
        for path in files {
            let bytes = std::fs::read(&path).unwrap();
            let loaded = load_gltf_detailed(&path, &bytes, &Disk).unwrap_or_else(|e| panic!("{e}"));
            let json = if bytes.starts_with(GLB_MAGIC) { split_glb(&bytes).unwrap().0 } else { &bytes[..] };
            let document = gltf::Document::from_json_without_validation(gltf::json::Root::from_slice(json).unwrap());
            let walked = walked_transforms(&document);
            let hierarchy = match loaded.scene.animation.clone() {
                Some(animation) => animation,
                None => SceneAnimation::new(loaded.unanimated_nodes, Vec::new()).unwrap(),
            };
            let posed = hierarchy.world_transforms(None);
            let mut placed = 0;
            for (node, world) in hierarchy.nodes().iter().zip(posed) {
                assert_eq!(bits(world), bits(walked[&node.gltf_index.unwrap()]), "{}: {}", path.display(), node.label);
                for &id in &node.objects {
                    let object = &loaded.scene.objects[id as usize];
                    assert_eq!(bits(object.transform), bits(world), "{}: {}", path.display(), object.name);
                    placed += 1;
                }
            }
            assert_eq!(placed, loaded.scene.objects.len(), "{}: every object is placed by a node", path.display());
        }
    }

    #[test]
    fn material_kind_rule() {
        assert_eq!(material_kind(0.0, 0.0, 1.5), MaterialKind::Diffuse);
        assert_eq!(material_kind(0.49, 0.0, 1.5), MaterialKind::Diffuse);
        assert_eq!(material_kind(0.5, 0.0, 1.5), MaterialKind::Specular);
        assert_eq!(material_kind(1.0, 0.01, 1.33), MaterialKind::Glass { ior: 1.33 }, "transmission wins");
    }
}
