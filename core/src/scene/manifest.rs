//! The TOML scene manifest: a scene composed of glTF/GLB files and built-in shapes, each
//! placed with its own transform, render mode and material override, plus a camera and lights.
//!
//! ```toml
//! description = "golden bunny in the grey Sponza atrium"   # optional, free text
//! environment = "maps/courtyard.hdr"   # optional: what reflection and refraction rays leaving
//!                                      # the scene see (.hdr or .exr); default: the built-in sky
//! shading = "gltf"              # optional: "gltf" (the glTF metallic-roughness BRDF on every
//!                               # object, the default) | "paper" (the paper's 2011 model)
//! ambient = 0.06                # optional: the constant ambient light, >= 0 (default 0.06;
//!                               # 0 removes it; with a black environment, whose image-based
//!                               # light the glTF BRDF adds, direct light and emission alone)
//! emissive_lights = true        # optional (default false): emissive objects light the scene,
//!                               # their triangles sampled by area as one area light
//!
//! [camera]                      # optional; without it: the first camera of a model file, else none
//! eye = [9.0, 2.6, 3.0]
//! target = [0.0, 1.8, 0.0]
//! up = [0.0, 1.0, 0.0]          # default +Y
//! fov_deg = 55.0                # vertical field of view, default 45
//! near = 0.05                   # default: far / 1000
//! far = 80.0                    # default: twice the distance from the eye to the farthest corner of the scene bounds
//!
//! [[light]]                     # zero or more; without any: the model files' lights, else none
//! type = "point"                # "point" | "directional" | "spot" (glTF's KHR_lights_punctual),
//!                               # or the area lights "quad" | "sphere" (below)
//! position = [3.0, 9.0, 3.0]    # point and spot lights only
//! color = [1.0, 0.95, 0.9]      # linear RGB, default [1, 1, 1]
//! intensity = 150.0             # scales color: candela for point and spot lights (which fall
//!                               # off with 1/d^2), lux for directional ones
//! range = 20.0                  # optional, point and spot lights: fades to nothing at this
//!                               # distance (the extension's window 1 - (d/range)^4); default none
//!
//! [[light]]
//! type = "directional"
//! direction = [-0.3, -1.0, -0.2] # the direction the light travels; normalised on load
//! intensity = 0.5
//!
//! [[light]]
//! type = "spot"
//! position = [0.0, 6.0, 0.0]
//! direction = [0.0, -1.0, 0.0]  # the cone's axis, from the light; normalised on load
//! intensity = 80.0
//! inner_cone_deg = 10.0         # optional: full light within this angle of the axis, default 0
//! outer_cone_deg = 25.0         # optional: none beyond it (> inner, <= 90), default 45; the
//!                               # extension's smooth falloff between
//!
//! [[light]]                     # area lights: soft shadows, `--shadow-samples` rays per surface
//! type = "quad"                 # a parallelogram; not visible to the camera
//! corner = [-0.5, 3.0, -0.5]
//! edge_u = [1.0, 0.0, 0.0]
//! edge_v = [0.0, 0.0, 1.0]      # emits to the side of cross(edge_u, edge_v): here -Y, downwards
//! intensity = 20.0              # nits: the emitted radiance, whatever the size
//!
//! [[light]]
//! type = "sphere"
//! position = [2.0, 2.0, 0.0]
//! radius = 0.25
//! intensity = 40.0              # nits
//!
//! [[light]]
//! type = "directional"
//! direction = [-0.3, -1.0, -0.2]
//! angular_diameter_deg = 0.53   # optional: above 0, a sun with soft shadows (lux, as directional)
//! intensity = 3.0
//!
//! [[model]]                     # one or more
//! file = "../../../shared/assets/sponza.glb"   # relative to this manifest's folder (or absolute)
//! name = "sponza"               # optional; default: the file stem, or the builtin's name
//! render_mode = "raster"        # optional: "raster" | "ray_traced"
//! material = { base_color = [0.8, 0.8, 0.8], metallic = 0.0, roughness = 0.9 }
//!
//! [[model]]
//! file = "../../../shared/assets/bunny.glb"
//! translate = [0.42, -0.73, 0.04]            # metres, default [0, 0, 0]
//! rotate_deg = [0.0, 30.0, 0.0]              # Euler angles in degrees, see below
//! # rotate_axis_angle = { axis = [0, 1, 0], angle_deg = 30 }   # or this, not both
//! scale = 25.0                               # uniform, or per axis: [sx, sy, sz]; default 1
//! render_mode = "ray_traced"
//! [model.material]
//! base_color = [1.0, 0.76, 0.33]
//! metallic = 1.0
//! roughness = 0.2
//! kind = "specular"             # "diffuse" | "specular" | "glass"; default: derived, see below
//! # transmission = 1.0, ior = 1.5, name = "gold" are the other keys
//!
//! [[model]]
//! builtin = "grid"              # instead of file: "grid" | "sphere" | "cube" | "torus"
//! scale = [20.0, 1.0, 20.0]
//!
//! [[model]]
//! file = "../../../shared/assets/dragon.glb"
//! repeat = { count = [40, 1, 25], step = [0.25, 0.0, 0.2] }   # 1,000 copies on a grid
//!
//! [[model]]
//! file = "walker.glb"
//! animation = "walk"            # which of the file's animations plays (default: its first)
//! ```
//!
//! Unknown keys are errors everywhere (`deny_unknown_fields`), so typos do not pass silently.
//!
//! * **Paths.** `file` and `environment` are resolved against the folder holding the manifest
//!   (an absolute path is used as is). There is no variable substitution. The same file used by several models is
//!   read once, and its meshes are shared.
//! * **Transform.** Model matrix = translate * rotate * scale (scale first). `rotate_deg =
//!   [rx, ry, rz]` rotates about the world X axis first, then Y, then Z, i.e.
//!   `R = Rz(rz) * Ry(ry) * Rx(rx)`. `rotate_axis_angle` rotates right-handedly about `axis`
//!   (normalised). Scales must be non-zero (negative mirrors). Each object of the file is placed
//!   at `model * object_transform`.
//! * **Repeat.** `repeat = { count = [nx, ny, nz], step = [dx, dy, dz] }` places `nx * ny * nz`
//!   copies (at most 2^20), copy `(i, j, k)` at `translate(i dx, j dy, k dz) * model`, x
//!   fastest; objects are named `<model name>#<copy>/<object name>`. Copies share the
//!   model's meshes, so a renderer can trace them as instances of one mesh.
//! * **Built-ins** (the procedural meshes of the default scene, grey diffuse material):
//!   `grid` is a unit square in the XZ plane centred at the origin facing +Y (16 x 16 quads),
//!   `sphere` a UV sphere of radius 1 (48 x 24), `cube` spans -1..1 on each axis, `torus`
//!   lies in the XZ plane with ring radius 1 and tube radius 0.35 (48 x 24).
//! * **What a model carries.** Everything its file holds, as the file loaded alone has it:
//!   meshes with their texture coordinates and vertex colours, materials with their
//!   base-colour textures (images, samplers, `KHR_texture_transform`), alpha modes and
//!   render-mode extras, cameras, lights, the node hierarchy and animations. A file loaded
//!   alone and a file placed by a manifest go through one merge ([`super::merge`]): a
//!   one-model manifest without a transform or overrides gives the same scene, and the same
//!   image, as the file alone (object names aside: `<model name>/<object name>`).
//! * **Material override.** Applies to every material of the model; keys left out keep the
//!   file's values. It changes factors, not textures: a textured material keeps its
//!   base-colour texture, alpha mode and cutoff, and an overridden `base_color` multiplies
//!   the texture as glTF's `baseColorFactor` does (so `base_color = [1, 1, 1]` shows the
//!   texture as it is, and a gold `base_color` tints it). `kind` left out is derived from the
//!   resulting factors with the glTF loader's rule (transmission > 0: glass; metallic >= 0.5:
//!   specular; else diffuse). `ior` (>= 1) is used by glass; left out, it keeps the file's
//!   glass ior, else 1.5. `emissive` (linear RGB, >= 0) is the emitted radiance, glTF's
//!   `emissiveFactor` times its strength (so a built-in shape can glow).
//! * **Render mode** of each object: the model's `render_mode`, else the glTF `hyrt` extra,
//!   else [`Material::default_render_mode`] of the (overridden) material.
//! * **Names and ids.** Objects are named `<model name>/<object name>` (a built-in: the model
//!   name) and numbered in manifest order, so ids stay equal to their index.
//! * **Cameras and lights in model files.** When the manifest has no `[camera]`, the first
//!   model file camera is used, moved by its model transform (near/far scaled by the cube root
//!   of the transform's volume scale). When it has no `[[light]]`, the model files' lights are
//!   used, moved by their model transform; intensities are not changed. A note says which
//!   camera was used, with every value it has and where each came from (the manifest's, a
//!   model's, or derived), and which lights. No default camera or lights are added here
//!   ([`super::Scene::ensure_camera_and_lights`]).
//! * **Animations** of model files play as they do in the file alone: a model's placement
//!   sits above its file's root nodes, and copies made by `repeat` all follow the same
//!   animation. With one animated model the scene has its file's animations (same names);
//!   with several, the scene's first animation, `all`, plays every animated model's
//!   `animation` (a name; default its file's first) together, followed by each model's
//!   animations named `<model name>/<animation name>` ([`super::merge`]).
//! * **Environment.** An equirectangular (latitude-longitude) map in a Radiance HDR or OpenEXR
//!   file, linear RGB, oriented as [`super::environment`] documents (row 0 straight up, the
//!   image's centre towards +Z, its left and right edges meeting at -Z; Mitsuba 3's
//!   convention). Without it, rays leaving the scene see the default sky
//!   ([`crate::kernels::bounce::sky`]). Primary rays that hit nothing keep the background.
//!
//! Errors name the manifest and the entry, e.g.
//! `scenes/teaser.toml: model[1] 'bunny': scenes/../x.glb: cannot read file: No such file or directory`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Mat4, Quat, Vec3};
use serde::Deserialize;

use super::files::{Budget, Disk, SceneFiles};
use super::gltf_loader::{load_gltf_detailed, material_kind, LoadedGltf};
use super::merge::{FileSlot, Merge, Model, Naming};
use super::{
    farthest_corner, Ambient, Camera, Environment, Light, Material, MaterialKind, Mesh, RenderMode, Scene, ShadingModel,
};
use crate::SceneError;

/// `KHR_materials_ior` default, used when a manifest makes a material glass without an ior.
const DEFAULT_IOR: f32 = 1.5;

/// Default vertical field of view in degrees (the same as [`Scene::ensure_camera_and_lights`]).
const DEFAULT_FOV_DEG: f32 = 45.0;

/// Derived far plane: this many times the distance from the eye to the farthest bounds corner,
/// so that the whole scene lies well inside the frustum depth range.
const DERIVED_FAR_FACTOR: f32 = 2.0;

/// Derived near plane: far divided by this. 1000 keeps float32 depth in [0, 1] resolving
/// millimetres at metres (the depth buffer is not reversed).
const DERIVED_NEAR_DIVISOR: f32 = 1000.0;

/// A scene manifest, as parsed from TOML; see the module docs for the schema.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Free text, ignored.
    #[serde(default)]
    pub description: Option<String>,
    /// An environment map (`.hdr`, `.exr`), relative to the manifest's folder.
    #[serde(default)]
    pub environment: Option<PathBuf>,
    /// The shading model's name ([`crate::kernels::shading::ShadingModel::name`]).
    #[serde(default)]
    pub shading: Option<String>,
    /// The constant ambient light ([`crate::kernels::shading::Ambient`]).
    #[serde(default)]
    pub ambient: Option<f32>,
    /// Whether emissive objects are lights ([`Scene::emissive_lights`]); default false.
    #[serde(default)]
    pub emissive_lights: bool,
    /// `[camera]`.
    #[serde(default)]
    pub camera: Option<CameraEntry>,
    /// `[[light]]` tables.
    #[serde(default, rename = "light")]
    pub lights: Vec<LightEntry>,
    /// `[[model]]` tables, at least one.
    #[serde(default, rename = "model")]
    pub models: Vec<ModelEntry>,
}

/// `[camera]`: a perspective camera.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraEntry {
    pub eye: [f32; 3],
    pub target: [f32; 3],
    /// Default +Y.
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    /// Vertical field of view in degrees, in (0, 180); default 45.
    #[serde(default = "default_fov")]
    pub fov_deg: f32,
    /// Default: `far / 1000`.
    #[serde(default)]
    pub near: Option<f32>,
    /// Default: twice the distance from the eye to the farthest corner of the scene bounds.
    #[serde(default)]
    pub far: Option<f32>,
}

/// The kind of a `[[light]]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LightType {
    Point,
    Directional,
    Spot,
    Quad,
    Sphere,
}

/// `[[light]]`: a point light (`position`), a directional light (`direction`; with
/// `angular_diameter_deg` a sun) or a spot light (`position` and `direction`, the cone's
/// axis), as glTF's `KHR_lights_punctual` defines them; or an area light: a quad
/// (`corner`, `edge_u`, `edge_v`, emitting to the side of `cross(edge_u, edge_v)`) or a
/// sphere (`position`, `radius`) ([`Light`]).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightEntry {
    #[serde(rename = "type")]
    pub kind: LightType,
    /// Point and spot lights: world position.
    #[serde(default)]
    pub position: Option<[f32; 3]>,
    /// Directional lights: the direction the light travels; spot lights: the direction the
    /// cone points (both normalised on load).
    #[serde(default)]
    pub direction: Option<[f32; 3]>,
    /// Linear RGB, default white.
    #[serde(default = "default_color")]
    pub color: [f32; 3],
    /// Scales `color`, >= 0: candela for point and spot lights, lux for directional lights
    /// and suns, nits (the emitted radiance) for quads and spheres.
    pub intensity: f32,
    /// Point and spot lights: the distance at which the light has faded to nothing (the
    /// extension's window over 1/d²). Default: no cutoff.
    #[serde(default)]
    pub range: Option<f32>,
    /// Spot lights: the angle from the axis (degrees) within which the light is full.
    /// Default 0.
    #[serde(default)]
    pub inner_cone_deg: Option<f32>,
    /// Spot lights: the angle from the axis (degrees) beyond which there is no light,
    /// greater than `inner_cone_deg`, at most 90. Default 45 (glTF's pi/4).
    #[serde(default)]
    pub outer_cone_deg: Option<f32>,
    /// Directional lights: the angle (degrees, in `[0, 180)`) the light's disk spans; above
    /// 0 the light is a sun with soft shadows (the real sun: about 0.53). Default 0.
    #[serde(default)]
    pub angular_diameter_deg: Option<f32>,
    /// Quads: one corner.
    #[serde(default)]
    pub corner: Option<[f32; 3]>,
    /// Quads: the two edges from `corner`; the light emits to the side of their cross
    /// product.
    #[serde(default)]
    pub edge_u: Option<[f32; 3]>,
    #[serde(default)]
    pub edge_v: Option<[f32; 3]>,
    /// Spheres: the radius, > 0.
    #[serde(default)]
    pub radius: Option<f32>,
}

/// A built-in procedural shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Builtin {
    /// Unit square in XZ centred at the origin, facing +Y, 16 x 16 quads.
    Grid,
    /// UV sphere of radius 1, 48 segments x 24 rings.
    Sphere,
    /// Cube from -1 to 1.
    Cube,
    /// Torus in XZ, ring radius 1, tube radius 0.35, 48 x 24.
    Torus,
}

impl Builtin {
    fn name(self) -> &'static str {
        match self {
            Builtin::Grid => "grid",
            Builtin::Sphere => "sphere",
            Builtin::Cube => "cube",
            Builtin::Torus => "torus",
        }
    }

    /// The shape as a file of one mesh and one object of [`Material::grey`], placed by a model
    /// as a file's objects are.
    fn as_file(self) -> Scene {
        let mut shape = Scene::default();
        shape.add_object(self.mesh(), Material::grey(), Mat4::IDENTITY, RenderMode::Raster);
        shape
    }

    fn mesh(self) -> Mesh {
        match self {
            Builtin::Grid => Mesh::grid("grid", 16),
            Builtin::Sphere => Mesh::uv_sphere("sphere", 48, 24),
            Builtin::Cube => Mesh::cube("cube"),
            Builtin::Torus => Mesh::torus("torus", 1.0, 0.35, 48, 24),
        }
    }
}

/// `rotate_axis_angle = { axis = [x, y, z], angle_deg = a }`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisAngle {
    pub axis: [f32; 3],
    pub angle_deg: f32,
}

/// `scale = s` or `scale = [sx, sy, sz]`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged, expecting = "a number or an array of 3 numbers")]
pub enum Scale {
    Uniform(f32),
    PerAxis([f32; 3]),
}

/// `kind` in a material override.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum KindName {
    Diffuse,
    Specular,
    Glass,
}

/// `material = { ... }`: overrides for every material of a model.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialOverride {
    pub name: Option<String>,
    /// Linear RGB, each >= 0.
    pub base_color: Option<[f32; 3]>,
    /// In [0, 1].
    pub metallic: Option<f32>,
    /// In [0, 1].
    pub roughness: Option<f32>,
    /// In [0, 1].
    pub transmission: Option<f32>,
    /// >= 1.
    pub ior: Option<f32>,
    pub kind: Option<KindName>,
    /// Emitted linear radiance (glTF `emissiveFactor` times its strength), each >= 0; it
    /// multiplies the model's emissive texture as glTF's factor does.
    pub emissive: Option<[f32; 3]>,
}

/// `[[model]]`: a glTF/GLB file or a built-in shape, placed in the world.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelEntry {
    /// A `.glb`/`.gltf` file, relative to the manifest's folder. Exactly one of `file`, `builtin`.
    #[serde(default)]
    pub file: Option<PathBuf>,
    #[serde(default)]
    pub builtin: Option<Builtin>,
    /// Default: the file stem, or the built-in's name.
    #[serde(default)]
    pub name: Option<String>,
    #[serde(default)]
    pub translate: [f32; 3],
    /// Euler angles in degrees: X first, then Y, then Z (world axes).
    #[serde(default)]
    pub rotate_deg: Option<[f32; 3]>,
    #[serde(default)]
    pub rotate_axis_angle: Option<AxisAngle>,
    #[serde(default)]
    pub scale: Option<Scale>,
    #[serde(default)]
    pub render_mode: Option<RenderMode>,
    #[serde(default)]
    pub material: Option<MaterialOverride>,
    /// Place the model on a grid of copies: every copy shares the model's meshes (one
    /// mesh in memory however many copies; a renderer may trace them as instances).
    #[serde(default)]
    pub repeat: Option<Repeat>,
    /// The animation of the file this model plays in the scene's first animation, by name
    /// (default: the file's first); see the module docs.
    #[serde(default)]
    pub animation: Option<String>,
}

/// `repeat = { count = [nx, ny, nz], step = [dx, dy, dz] }`: `nx * ny * nz` copies of a
/// model, copy `(i, j, k)` moved by `(i dx, j dy, k dz)` in world space after the model's
/// own transform. At most [`MAX_REPEAT_COPIES`] copies.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Repeat {
    pub count: [u32; 3],
    pub step: [f32; 3],
}

/// Most copies one `repeat` makes (a typo of an extra digit is an error, not an
/// allocation of billions of objects).
pub const MAX_REPEAT_COPIES: u64 = 1 << 20;

impl Repeat {
    /// The world offsets of the copies, x fastest, or an error message.
    fn offsets(&self) -> Result<Vec<Vec3>, String> {
        let step = finite(self.step, "repeat.step")?;
        let total = self.count.iter().map(|&c| c as u64).product::<u64>();
        if self.count.contains(&0) || total > MAX_REPEAT_COPIES {
            return Err(format!(
                "repeat.count {:?} must have every count at least 1 and at most {MAX_REPEAT_COPIES} copies in all",
                self.count
            ));
        }
        let [nx, ny, nz] = self.count;
        Ok((0..nz)
            .flat_map(|k| (0..ny).flat_map(move |j| (0..nx).map(move |i| Vec3::new(i as f32, j as f32, k as f32))))
            .map(|c| c * step)
            .collect())
    }
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}
fn default_fov() -> f32 {
    DEFAULT_FOV_DEG
}
fn default_color() -> [f32; 3] {
    [1.0, 1.0, 1.0]
}

/// Load a TOML scene manifest; see the module docs for the schema.
pub fn load_manifest(path: &Path) -> Result<Scene, SceneError> {
    load_manifest_from(path, &Disk)
}

/// [`load_manifest`] reading the manifest, its model files and its environment map from
/// `files`.
pub fn load_manifest_from(path: &Path, files: &dyn SceneFiles) -> Result<Scene, SceneError> {
    let bytes = files.read(path).map_err(|source| SceneError::Io { path: path.to_path_buf(), source })?;
    let invalid = |message: String| SceneError::Manifest { path: path.to_path_buf(), message };
    let text = std::str::from_utf8(&bytes).map_err(|e| invalid(format!("not UTF-8 text: {e}")))?;
    let manifest: Manifest = toml::from_str(text).map_err(|e| invalid(e.to_string()))?;
    build(&manifest, path, files, Budget::for_input(bytes.len()))
}

/// A finite vector, or an error message naming `what`.
fn finite(v: [f32; 3], what: &str) -> Result<Vec3, String> {
    let v = Vec3::from(v);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{what} {v} is not finite"))
    }
}

fn unit_interval(v: Option<f32>, what: &str) -> Result<(), String> {
    match v {
        Some(x) if !(0.0..=1.0).contains(&x) => Err(format!("material.{what} = {x} is not in [0, 1]")),
        _ => Ok(()),
    }
}

impl ModelEntry {
    /// The model matrix, validated.
    fn matrix(&self) -> Result<Mat4, String> {
        let t = finite(self.translate, "translate")?;
        let r = match (self.rotate_deg, self.rotate_axis_angle) {
            (Some(_), Some(_)) => return Err("give rotate_deg or rotate_axis_angle, not both".into()),
            (Some(e), None) => {
                let e = finite(e, "rotate_deg")?;
                Quat::from_rotation_z(e.z.to_radians())
                    * Quat::from_rotation_y(e.y.to_radians())
                    * Quat::from_rotation_x(e.x.to_radians())
            }
            (None, Some(aa)) => {
                let axis = finite(aa.axis, "rotate_axis_angle.axis")?;
                let axis = axis.try_normalize().ok_or("rotate_axis_angle.axis is zero")?;
                if !aa.angle_deg.is_finite() {
                    return Err(format!("rotate_axis_angle.angle_deg {} is not finite", aa.angle_deg));
                }
                Quat::from_axis_angle(axis, aa.angle_deg.to_radians())
            }
            (None, None) => Quat::IDENTITY,
        };
        let s = match self.scale {
            None => Vec3::ONE,
            Some(Scale::Uniform(s)) => Vec3::splat(s),
            Some(Scale::PerAxis(s)) => Vec3::from(s),
        };
        if !s.is_finite() || s.cmpeq(Vec3::ZERO).any() {
            return Err(format!("scale {s} must be finite and non-zero"));
        }
        Ok(Mat4::from_scale_rotation_translation(s, r, t))
    }
}

impl MaterialOverride {
    fn validate(&self) -> Result<(), String> {
        for (c, what) in [(self.base_color, "material.base_color"), (self.emissive, "material.emissive")] {
            if let Some(c) = c {
                let c = finite(c, what)?;
                if c.min_element() < 0.0 {
                    return Err(format!("{what} {c} has a negative component"));
                }
            }
        }
        unit_interval(self.metallic, "metallic")?;
        unit_interval(self.roughness, "roughness")?;
        unit_interval(self.transmission, "transmission")?;
        match self.ior {
            Some(ior) if !(ior >= 1.0 && ior.is_finite()) => {
                Err(format!("material.ior = {ior} must be finite and >= 1"))
            }
            _ => Ok(()),
        }
    }

    fn apply(&self, m: &Material) -> Material {
        let metallic = self.metallic.unwrap_or(m.metallic);
        let transmission = self.transmission.unwrap_or(m.transmission);
        let ior = self.ior.unwrap_or(match m.kind {
            MaterialKind::Glass { ior } => ior,
            _ => DEFAULT_IOR,
        });
        Material {
            name: self.name.clone().unwrap_or_else(|| m.name.clone()),
            base_color: self.base_color.map(Vec3::from).unwrap_or(m.base_color),
            emissive: self.emissive.map(Vec3::from).unwrap_or(m.emissive),
            metallic,
            roughness: self.roughness.unwrap_or(m.roughness),
            transmission,
            kind: match self.kind {
                Some(KindName::Diffuse) => MaterialKind::Diffuse,
                Some(KindName::Specular) => MaterialKind::Specular,
                Some(KindName::Glass) => MaterialKind::Glass { ior },
                None => material_kind(metallic, transmission, ior),
            },
            // Textures and alpha stay the model's: an override changes factors only.
            ..m.clone()
        }
    }
}

impl CameraEntry {
    fn validate(&self) -> Result<(Vec3, Vec3, Vec3), String> {
        let eye = finite(self.eye, "camera.eye")?;
        let target = finite(self.target, "camera.target")?;
        let up = finite(self.up, "camera.up")?;
        if (target - eye).cross(up).length_squared() <= 0.0 {
            return Err("camera: eye equals target, or up is parallel to the view direction".into());
        }
        if !(self.fov_deg > 0.0 && self.fov_deg < 180.0) {
            return Err(format!("camera.fov_deg = {} must lie in (0, 180)", self.fov_deg));
        }
        if let Some(near) = self.near {
            if !(near > 0.0 && near.is_finite()) {
                return Err(format!("camera.near = {near} must be finite and > 0"));
            }
        }
        if let Some(far) = self.far {
            if !(far.is_finite() && far > self.near.unwrap_or(0.0)) {
                return Err(format!("camera.far = {far} must be finite and > near"));
            }
        }
        Ok((eye, target, up))
    }

    /// The camera, its near and far planes derived where not given (from the scene's
    /// `bounds`), and a note saying which values it has and where each came from.
    fn camera(&self, bounds: Option<(Vec3, Vec3)>) -> Result<(Camera, String), String> {
        let (eye, target, up) = self.validate()?;
        let (far, far_from) = match (self.far, self.near) {
            (Some(far), _) => (far, "given"),
            (None, near) => {
                let bounds_far =
                    bounds.map(|(lo, hi)| DERIVED_FAR_FACTOR * farthest_corner(eye, lo, hi)).filter(|&f| f > 0.0);
                let far = bounds_far.unwrap_or(DERIVED_FAR_FACTOR * (target - eye).length());
                let far = far.max(2.0 * near.unwrap_or(0.0));
                let from = match bounds_far {
                    Some(_) => "not given: twice the distance to the farthest corner of the scene bounds",
                    None => "not given: twice the distance to the target (the scene has no finite vertex)",
                };
                (far, from)
            }
        };
        let (near, near_from) = match self.near {
            Some(near) => (near, "given".to_string()),
            None => (far / DERIVED_NEAR_DIVISOR, format!("not given: far / {DERIVED_NEAR_DIVISOR}")),
        };
        let camera = Camera { eye, target, up: up.normalize(), fov_y_deg: self.fov_deg, near, far };
        let note = format!(
            "camera: the manifest's [camera]: eye {:.4?}, target {:.4?}, up {:.3?}, fov {} deg, near {near:.5} ({near_from}), \
             far {far:.4} ({far_from})",
            camera.eye.to_array(),
            camera.target.to_array(),
            camera.up.to_array(),
            camera.fov_y_deg,
        );
        Ok((camera, note))
    }
}

impl LightEntry {
    fn to_light(&self) -> Result<Light, String> {
        // Colour and intensity ranges, cone angles and the range: `Light::validate`, below.
        let color = finite(self.color, "color")?;
        let intensity = self.intensity;
        let direction = |d| finite(d, "direction")?.try_normalize().ok_or_else(|| "direction is zero".to_string());
        let range = self.range;
        let cone = self.inner_cone_deg.is_some() || self.outer_cone_deg.is_some();
        if self.kind != LightType::Spot && cone {
            return Err("`inner_cone_deg` and `outer_cone_deg` are for spot lights".into());
        }
        if !matches!(self.kind, LightType::Point | LightType::Spot) && range.is_some() {
            return Err("`range` is for point and spot lights".into());
        }
        if self.kind != LightType::Directional && self.angular_diameter_deg.is_some() {
            return Err("`angular_diameter_deg` is for directional lights".into());
        }
        let quad_keys = self.corner.is_some() || self.edge_u.is_some() || self.edge_v.is_some();
        if self.kind != LightType::Quad && quad_keys {
            return Err("`corner`, `edge_u` and `edge_v` are for quad lights".into());
        }
        if self.kind != LightType::Sphere && self.radius.is_some() {
            return Err("`radius` is for sphere lights".into());
        }
        let light = match (self.kind, self.position, self.direction) {
            (LightType::Point, Some(p), None) => {
                Light::Point { position: finite(p, "position")?, color, intensity, range }
            }
            (LightType::Directional, None, Some(d)) => match self.angular_diameter_deg {
                Some(deg) if deg != 0.0 => {
                    Light::Sun { direction: direction(d)?, angular_diameter: deg.to_radians(), color, intensity }
                }
                _ => Light::Directional { direction: direction(d)?, color, intensity },
            },
            (LightType::Quad, None, None) => match (self.corner, self.edge_u, self.edge_v) {
                (Some(c), Some(u), Some(v)) => Light::Quad {
                    corner: finite(c, "corner")?,
                    edge_u: finite(u, "edge_u")?,
                    edge_v: finite(v, "edge_v")?,
                    color,
                    intensity,
                },
                _ => return Err("a quad light needs `corner`, `edge_u` and `edge_v`".into()),
            },
            (LightType::Sphere, Some(p), None) => match self.radius {
                Some(radius) => Light::Sphere { position: finite(p, "position")?, radius, color, intensity },
                None => return Err("a sphere light needs `radius`".into()),
            },
            (LightType::Quad, _, _) => {
                return Err("a quad light needs `corner`, `edge_u` and `edge_v`, no `position` or `direction`".into())
            }
            (LightType::Sphere, _, _) => {
                return Err("a sphere light needs `position` and `radius`, no `direction`".into())
            }
            (LightType::Spot, Some(p), Some(d)) => Light::Spot {
                position: finite(p, "position")?,
                direction: direction(d)?,
                color,
                intensity,
                inner_cone_angle: self.inner_cone_deg.unwrap_or(0.0).to_radians(),
                outer_cone_angle: self.outer_cone_deg.map_or(Light::DEFAULT_OUTER_CONE_ANGLE, f32::to_radians),
                range,
            },
            (LightType::Point, _, _) => return Err("a point light needs `position` and no `direction`".into()),
            (LightType::Directional, _, _) => {
                return Err("a directional light needs `direction` and no `position`".into())
            }
            (LightType::Spot, _, _) => return Err("a spot light needs `position` and `direction`".into()),
        };
        light.validate().map(|()| light)
    }
}

/// Build the scene a parsed manifest describes; `path` is the manifest (for relative paths
/// and error messages). Every model goes through the same [`Merge`] as a file loaded alone.
fn build(manifest: &Manifest, path: &Path, files: &dyn SceneFiles, budget: Budget) -> Result<Scene, SceneError> {
    let invalid = |message: String| SceneError::Manifest { path: path.to_path_buf(), message };
    if manifest.models.is_empty() {
        return Err(invalid("no [[model]] entries: a scene needs at least one".into()));
    }
    let dir = path.parent().unwrap_or(Path::new(""));
    // Each file is read and converted once, whatever the number of models placing it; the
    // merged scene's budget grows by every file's input bytes, as the file's own did.
    let mut loaded_files: HashMap<PathBuf, (FileSlot, LoadedGltf)> = HashMap::new();
    let mut builtins: HashMap<Builtin, (FileSlot, Scene)> = HashMap::new();
    let mut merged = Merge::new(budget);
    if let Some(name) = &manifest.shading {
        merged.scene_mut().shading = ShadingModel::from_name(name).ok_or_else(|| {
            let known: Vec<&str> = ShadingModel::ALL.iter().map(|m| m.name()).collect();
            invalid(format!("shading = \"{name}\": unknown model (known: {})", known.join(", ")))
        })?;
    }
    if let Some(level) = manifest.ambient {
        merged.scene_mut().ambient = Ambient::new(level).map_err(invalid)?;
    }
    merged.scene_mut().emissive_lights = manifest.emissive_lights;
    if let Some(file) = &manifest.environment {
        merged.scene_mut().environment = Environment::load_from(&dir.join(file), files).map_err(|e| {
            SceneError::ManifestEntry { path: path.to_path_buf(), entry: "environment".into(), error: Box::new(e) }
        })?;
    }

    for (i, entry) in manifest.models.iter().enumerate() {
        let name = match (&entry.name, &entry.file, entry.builtin) {
            (Some(n), _, _) => n.clone(),
            (None, Some(f), _) => f.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default(),
            (None, None, Some(b)) => b.name().to_string(),
            (None, None, None) => String::new(),
        };
        let label = format!("model[{i}] '{name}'");
        let at = |message: String| invalid(format!("{label}: {message}"));
        let matrix = entry.matrix().map_err(at)?;
        let copies = match &entry.repeat {
            Some(r) => r.offsets().map_err(at)?,
            None => vec![Vec3::ZERO],
        };
        if let Some(o) = &entry.material {
            o.validate().map_err(at)?;
        }
        let (source, slot, from_extras): (&Scene, FileSlot, &[bool]) = match (&entry.file, entry.builtin) {
            (Some(_), Some(_)) => return Err(at("give `file` or `builtin`, not both".into())),
            (None, None) => return Err(at("needs `file` or `builtin`".into())),
            (None, Some(b)) => {
                if entry.animation.is_some() {
                    return Err(at("`animation` names an animation of a model file; a built-in shape has none".into()));
                }
                let (slot, shape) = builtins.entry(b).or_insert_with(|| {
                    let shape = b.as_file();
                    (merged.add_file(&shape, 0, None), shape)
                });
                (&*shape, *slot, &[false][..])
            }
            (Some(file), None) => {
                let resolved = dir.join(file);
                if !loaded_files.contains_key(&resolved) {
                    let entry_error = |e| SceneError::ManifestEntry {
                        path: path.to_path_buf(),
                        entry: label.clone(),
                        error: Box::new(e),
                    };
                    let bytes = files
                        .read(&resolved)
                        .map_err(|source| entry_error(SceneError::Io { path: resolved.clone(), source }))?;
                    let loaded = load_gltf_detailed(&resolved, &bytes, files).map_err(entry_error)?;
                    let slot = merged.add_file(&loaded.scene, loaded.input_bytes, Some(&label));
                    loaded_files.insert(resolved.clone(), (slot, loaded));
                }
                let (slot, loaded) = &loaded_files[&resolved];
                (&loaded.scene, *slot, &loaded.mode_from_extras[..])
            }
        };
        let override_material = entry.material.as_ref().map(|o| move |m: &Material| o.apply(m));
        let model = Model {
            label: Some(&label),
            naming: if entry.builtin.is_some() { Naming::Whole(&name) } else { Naming::Prefixed(&name) },
            matrix,
            copies: &copies,
            material: override_material.as_ref().map(|f| f as &dyn Fn(&Material) -> Material),
            render_mode: entry.render_mode,
            animation: entry.animation.as_deref(),
        };
        merged.place(source, slot, from_extras, &model).map_err(at)?;
    }

    let lights = match manifest.lights.is_empty() {
        true => None,
        false => Some(
            manifest
                .lights
                .iter()
                .enumerate()
                .map(|(i, l)| l.to_light().map_err(|m| invalid(format!("light[{i}]: {m}"))))
                .collect::<Result<Vec<Light>, SceneError>>()?,
        ),
    };
    let mut scene = merged.finish(lights, manifest.camera.is_some()).map_err(invalid)?;
    if let Some(c) = &manifest.camera {
        let (camera, note) = c.camera(scene.world_bounds()).map_err(invalid)?;
        scene.camera = Some(camera);
        scene.notes.push(note);
    }
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(text: &str) -> ModelEntry {
        toml::from_str(text).unwrap()
    }

    /// Tolerance for rotations through quaternions of right angles: a few ulp of 1.
    const ROTATION_TOLERANCE: f32 = 1e-6;

    #[test]
    fn module_doc_example_matches_the_schema() {
        let source = include_str!("manifest.rs");
        let example: String = source
            .lines()
            .skip_while(|l| *l != "//! ```toml")
            .skip(1)
            .take_while(|l| *l != "//! ```")
            .map(|l| format!("{}\n", l.trim_start_matches("//!").strip_prefix(' ').unwrap_or("")))
            .collect();
        let m: Manifest = toml::from_str(&example).unwrap_or_else(|e| panic!("{e}\n{example}"));
        assert_eq!((m.models.len(), m.lights.len()), (5, 6));
        assert!(m.lights.iter().all(|l| l.to_light().is_ok()));
        assert_eq!(m.models[3].repeat.map(|r| r.offsets().unwrap().len()), Some(1000));
        assert_eq!(m.environment.as_deref(), Some(Path::new("maps/courtyard.hdr")));
        assert_eq!(m.models[1].render_mode, Some(RenderMode::RayTraced));
        assert_eq!(m.models[2].builtin, Some(Builtin::Grid));
        assert_eq!(m.models[4].animation.as_deref(), Some("walk"));
        for (i, model) in m.models.iter().enumerate() {
            model.matrix().unwrap_or_else(|e| panic!("model[{i}]: {e}"));
        }
        m.camera.unwrap().validate().unwrap();
        assert!(m.lights.iter().all(|l| l.to_light().is_ok()));
    }

    #[test]
    fn euler_rotation_applies_x_then_y_then_z() {
        // X first then Z: Y -> Z -> Z and Z -> -Y -> X. (Z first then X would send Z to -Y.)
        let m = model("builtin = 'cube'\nrotate_deg = [90.0, 0.0, 90.0]").matrix().unwrap();
        assert!(m.transform_vector3(Vec3::Y).abs_diff_eq(Vec3::Z, ROTATION_TOLERANCE));
        assert!(m.transform_vector3(Vec3::Z).abs_diff_eq(Vec3::X, ROTATION_TOLERANCE));
    }

    #[test]
    fn transform_scales_then_rotates_then_translates() {
        let m = model("builtin = 'cube'\ntranslate = [1.0, 2.0, 3.0]\nrotate_axis_angle = { axis = [0.0, 0.0, 5.0], angle_deg = 90.0 }\nscale = [2.0, 1.0, 1.0]")
            .matrix()
            .unwrap();
        // (1, 0, 0) -> scale (2, 0, 0) -> rotate about Z (0, 2, 0) -> translate (1, 4, 3).
        assert!(m.transform_point3(Vec3::X).abs_diff_eq(Vec3::new(1.0, 4.0, 3.0), ROTATION_TOLERANCE));
        let uniform = model("builtin = 'cube'\nscale = 3.0").matrix().unwrap();
        assert_eq!(uniform, Mat4::from_scale(Vec3::splat(3.0)));
        assert_eq!(model("builtin = 'cube'").matrix().unwrap(), Mat4::IDENTITY);
    }

    #[test]
    fn material_override_keeps_unset_fields_and_derives_the_kind() {
        let gold = Material {
            name: "gold".into(),
            base_color: Vec3::new(1.0, 0.8, 0.2),
            metallic: 1.0,
            roughness: 0.3,
            transmission: 0.0,
            kind: MaterialKind::Specular,
            ..Material::grey()
        };
        let glassy = MaterialOverride { transmission: Some(1.0), ..Default::default() }.apply(&gold);
        assert_eq!(glassy.kind, MaterialKind::Glass { ior: DEFAULT_IOR });
        assert_eq!((glassy.name.as_str(), glassy.base_color, glassy.roughness), ("gold", gold.base_color, 0.3));
        let denser = MaterialOverride { ior: Some(1.9), ..Default::default() }.apply(&glassy);
        assert_eq!(denser.kind, MaterialKind::Glass { ior: 1.9 });
        let kept_ior = MaterialOverride { roughness: Some(0.1), ..Default::default() }.apply(&denser);
        assert_eq!(kept_ior.kind, MaterialKind::Glass { ior: 1.9 }, "a glass material keeps its ior");
        let matte = MaterialOverride { metallic: Some(0.0), ..Default::default() }.apply(&gold);
        assert_eq!(matte.kind, MaterialKind::Diffuse);
        let forced = MaterialOverride { kind: Some(KindName::Diffuse), ..Default::default() }.apply(&gold);
        assert_eq!((forced.kind, forced.metallic), (MaterialKind::Diffuse, 1.0), "explicit kind wins");
    }

    #[test]
    fn area_light_entries_parse_and_validate() {
        let light = |text: &str| toml::from_str::<LightEntry>(text).unwrap().to_light();
        let quad = light("type = 'quad'\ncorner = [0.0, 3.0, 0.0]\nedge_u = [1.0, 0.0, 0.0]\nedge_v = [0.0, 0.0, 2.0]\nintensity = 4.0");
        assert_eq!(
            quad,
            Ok(Light::Quad {
                corner: Vec3::new(0.0, 3.0, 0.0),
                edge_u: Vec3::X,
                edge_v: Vec3::new(0.0, 0.0, 2.0),
                color: Vec3::ONE,
                intensity: 4.0
            })
        );
        let sphere = light("type = 'sphere'\nposition = [1.0, 2.0, 3.0]\nradius = 0.5\nintensity = 1.0");
        assert_eq!(
            sphere,
            Ok(Light::Sphere { position: Vec3::new(1.0, 2.0, 3.0), radius: 0.5, color: Vec3::ONE, intensity: 1.0 })
        );
        let Ok(Light::Sun { direction, angular_diameter, .. }) =
            light("type = 'directional'\ndirection = [0.0, -2.0, 0.0]\nangular_diameter_deg = 0.53\nintensity = 3.0")
        else {
            panic!("a directional light with an angular size is a sun")
        };
        assert_eq!((direction, angular_diameter), (Vec3::NEG_Y, 0.53f32.to_radians()));
        assert!(matches!(
            light("type = 'directional'\ndirection = [0.0, -1.0, 0.0]\nangular_diameter_deg = 0.0\nintensity = 3.0"),
            Ok(Light::Directional { .. })
        ));
        let errors = [
            // Parallel edges span no area.
            ("type = 'quad'\ncorner = [0.0, 0.0, 0.0]\nedge_u = [1.0, 0.0, 0.0]\nedge_v = [2.0, 0.0, 0.0]\nintensity = 1.0", "no area"),
            ("type = 'quad'\ncorner = [0.0, 0.0, 0.0]\nedge_u = [1.0, 0.0, 0.0]\nintensity = 1.0", "needs `corner`"),
            ("type = 'quad'\nposition = [0.0, 0.0, 0.0]\ncorner = [0.0, 0.0, 0.0]\nedge_u = [1.0, 0.0, 0.0]\nedge_v = [0.0, 0.0, 1.0]\nintensity = 1.0", "no `position`"),
            ("type = 'sphere'\nposition = [0.0, 0.0, 0.0]\nradius = 0.0\nintensity = 1.0", "radius 0"),
            ("type = 'sphere'\nposition = [0.0, 0.0, 0.0]\nintensity = 1.0", "needs `radius`"),
            ("type = 'point'\nposition = [0.0, 0.0, 0.0]\nradius = 1.0\nintensity = 1.0", "for sphere lights"),
            ("type = 'point'\nposition = [0.0, 0.0, 0.0]\nedge_u = [1.0, 0.0, 0.0]\nintensity = 1.0", "for quad lights"),
            ("type = 'spot'\nposition = [0.0, 0.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\nangular_diameter_deg = 1.0\nintensity = 1.0", "for directional"),
            ("type = 'directional'\ndirection = [0.0, -1.0, 0.0]\nangular_diameter_deg = 180.0\nintensity = 1.0", "(0, 180)"),
            ("type = 'quad'\ncorner = [0.0, 0.0, 0.0]\nedge_u = [1.0, 0.0, 0.0]\nedge_v = [0.0, 0.0, 1.0]\nrange = 2.0\nintensity = 1.0", "point and spot"),
        ];
        for (text, why) in errors {
            let e = light(text).expect_err(text);
            assert!(e.contains(why), "{text}: {e} (expected it to say {why:?})");
        }
    }

    #[test]
    fn light_entries_validate_their_shape() {
        let light = |text: &str| toml::from_str::<LightEntry>(text).unwrap().to_light();
        assert_eq!(
            light("type = 'directional'\ndirection = [0.0, 0.0, -4.0]\nintensity = 2.0"),
            Ok(Light::Directional { direction: Vec3::NEG_Z, color: Vec3::ONE, intensity: 2.0 })
        );
        assert!(light("type = 'point'\nposition = [0.0, 1.0, 0.0]\nintensity = -1.0").is_err());
        assert!(light("type = 'point'\nposition = [0.0, 1.0, 0.0]\ncolor = [1.0, -1.0, 0.0]\nintensity = 1.0").is_err());
        assert!(light("type = 'directional'\nposition = [0.0, 1.0, 0.0]\nintensity = 1.0").is_err());
    }

    #[test]
    fn spot_lights_and_ranges_parse_with_their_defaults_and_rules() {
        let light = |text: &str| toml::from_str::<LightEntry>(text).unwrap().to_light();
        let spot = "type = 'spot'\nposition = [0.0, 4.0, 0.0]\ndirection = [0.0, -2.0, 0.0]\nintensity = 5.0";
        assert_eq!(
            light(&format!("{spot}\ninner_cone_deg = 10.0\nouter_cone_deg = 30.0\nrange = 8.0")),
            Ok(Light::Spot {
                position: Vec3::new(0.0, 4.0, 0.0),
                direction: Vec3::NEG_Y,
                color: Vec3::ONE,
                intensity: 5.0,
                inner_cone_angle: 10f32.to_radians(),
                outer_cone_angle: 30f32.to_radians(),
                range: Some(8.0),
            })
        );
        // glTF's defaults: inner 0, outer pi/4, no range.
        let Ok(Light::Spot { inner_cone_angle, outer_cone_angle, range, .. }) = light(spot) else { panic!() };
        assert_eq!((inner_cone_angle, outer_cone_angle, range), (0.0, std::f32::consts::FRAC_PI_4, None));
        assert_eq!(
            light("type = 'point'\nposition = [0.0, 1.0, 0.0]\nintensity = 1.0\nrange = 3.0"),
            Ok(Light::Point { position: Vec3::Y, color: Vec3::ONE, intensity: 1.0, range: Some(3.0) })
        );
        let fails = |text: &str, says: &str| {
            let err = light(text).unwrap_err();
            assert!(err.contains(says), "{text}: {err}");
        };
        fails(&format!("{spot}\ninner_cone_deg = 30.0\nouter_cone_deg = 30.0"), "cone angles");
        fails(&format!("{spot}\nouter_cone_deg = 91.0"), "cone angles");
        fails(&format!("{spot}\ninner_cone_deg = -1.0"), "cone angles");
        fails(&format!("{spot}\nrange = 0.0"), "range 0");
        fails(&format!("{spot}\nrange = inf"), "range inf");
        fails("type = 'spot'\nposition = [0.0, 4.0, 0.0]\nintensity = 1.0", "needs `position` and `direction`");
        fails("type = 'spot'\nposition = [0.0, 4.0, 0.0]\ndirection = [0.0, 0.0, 0.0]\nintensity = 1.0", "zero");
        fails("type = 'point'\nposition = [0.0, 1.0, 0.0]\nintensity = 1.0\nouter_cone_deg = 20.0", "for spot lights");
        fails("type = 'directional'\ndirection = [0.0, -1.0, 0.0]\nintensity = 1.0\nrange = 2.0", "`range` is for");
    }

    #[test]
    fn shading_key_sets_the_model_and_names_an_unknown_one() {
        let load = |shading: &str| {
            let text = format!("{shading}\n[[model]]\nbuiltin = 'cube'\n");
            let files: HashMap<PathBuf, Vec<u8>> = [(PathBuf::from("s.toml"), text.into_bytes())].into();
            load_manifest_from(Path::new("s.toml"), &files)
        };
        assert_eq!(load("").unwrap().shading, ShadingModel::Gltf);
        assert_eq!(load("shading = 'gltf'").unwrap().shading, ShadingModel::Gltf);
        assert_eq!(load("shading = 'paper'").unwrap().shading, ShadingModel::Paper);
        assert_eq!(load("").unwrap().ambient, Ambient::default());
        assert_eq!(load("ambient = 0.0").unwrap().ambient, Ambient(0.0));
        assert!(load("ambient = -1.0").unwrap_err().to_string().contains("ambient -1"));
        let err = load("shading = 'phong'").unwrap_err().to_string();
        assert!(err.contains("s.toml") && err.contains("phong") && err.contains("gltf"), "{err}");
    }

    #[test]
    fn emissive_lights_key_is_a_boolean_off_by_default() {
        let load = |key: &str| {
            let text = format!(
                "{key}
[[model]]
builtin = 'cube'
material = {{ emissive = [1.0, 0.5, 0.0] }}
"
            );
            let files: HashMap<PathBuf, Vec<u8>> = [(PathBuf::from("s.toml"), text.into_bytes())].into();
            load_manifest_from(Path::new("s.toml"), &files)
        };
        assert!(!load("").unwrap().emissive_lights);
        assert!(!load("emissive_lights = false").unwrap().emissive_lights);
        let scene = load("emissive_lights = true").unwrap();
        assert!(scene.emissive_lights);
        // The cube's 12 triangles, all glowing: one emitter light over them.
        let g = crate::geometry::WorldGeometry::build(&scene);
        assert_eq!((g.emitters.len(), g.lights.len()), (12, 1));
        for bad in ["emissive_lights = 1", "emissive_lights = 'yes'"] {
            let err = load(bad).unwrap_err().to_string();
            assert!(err.contains("s.toml") && err.contains("emissive_lights") && err.contains("bool"), "{bad}: {err}");
        }
    }
}
