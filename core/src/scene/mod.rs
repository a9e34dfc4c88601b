//! The scene model: meshes (indexed triangles), objects (mesh + world transform +
//! material + object id), materials with a render mode and a kind, lights and a
//! perspective camera; plus the loaders.
//!
//! * [`Scene::load`] picks the loader from the file extension: `.glb`/`.gltf`
//!   ([`gltf_loader`]) or `.toml` ([`manifest`]).
//! * [`Scene::default_scene`] is the built-in scene (paper Figure 8).
//! * [`Scene::set_time`] poses a glTF scene with animations at a time ([`animation`]).
//! * [`Scene::ensure_camera_and_lights`] frames a scene that has no camera and adds
//!   default lights to one that has none, and records a note saying so.

pub mod animation;
pub mod default_scene;
pub mod environment;
pub mod files;
pub mod framing;
pub mod gltf_loader;
pub mod manifest;
pub mod merge;
pub mod texture;

pub use animation::{Animation, AnimationSampler, Interpolation, SceneAnimation, SceneNode};
pub use environment::{Environment, EnvironmentMap, EnvironmentMapError};
pub use files::{Disk, SceneFiles};
pub use texture::{AlphaMode, Filter, Sampler, TextureBinding, TextureImage, UvTransform, VertexAttributes, Wrap};

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Mat4, Vec3};

pub use crate::kernels::shading::{Ambient, ShadingModel};
use crate::SceneError;

/// An indexed triangle mesh in its own (object) space.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// A readable name (glTF mesh name, or a generated one).
    pub name: String,
    /// Object-space vertex positions.
    pub positions: Vec<Vec3>,
    /// Object-space vertex normals, one per position, when the source has them.
    /// Without them shading uses the geometric (face) normal.
    pub normals: Option<Vec<Vec3>>,
    /// Triangles as three indices into `positions`.
    pub indices: Vec<[u32; 3]>,
    /// Texture coordinates and vertex colours, when the source has them.
    pub attributes: VertexAttributes,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }
}

/// Whether an object is shaded by the ray tracer or by the ordinary raster shader.
/// Every object is rasterized for primary visibility either way (paper 3.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RenderMode {
    /// Shaded by the raster shader (paper 3.4); still casts and receives ray-traced shadows.
    Raster,
    /// Shaded by the ray tracer (paper 3.3).
    RayTraced,
}

impl RenderMode {
    /// The name used in manifests, `frame.json` and the CLI.
    pub const fn name(self) -> &'static str {
        match self {
            RenderMode::Raster => "raster",
            RenderMode::RayTraced => "ray_traced",
        }
    }
}

/// What light does at a surface. Kinds whose secondary rays are not traced yet
/// (reflection, refraction) still load and are shaded with their local terms.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum MaterialKind {
    /// Lambertian.
    Diffuse,
    /// Specular / mirror (metallic in glTF terms).
    Specular,
    /// Glass: transmissive with an index of refraction.
    Glass {
        /// Index of refraction (glTF `KHR_materials_ior`, default 1.5).
        ior: f32,
    },
}

impl MaterialKind {
    /// Numeric code used in [`crate::formats::ObjectRecord::material_kind`].
    pub const fn code(self) -> u32 {
        match self {
            MaterialKind::Diffuse => crate::formats::MATERIAL_DIFFUSE,
            MaterialKind::Specular => crate::formats::MATERIAL_SPECULAR,
            MaterialKind::Glass { .. } => crate::formats::MATERIAL_GLASS,
        }
    }
    /// The name used in manifests and `frame.json`.
    pub const fn name(self) -> &'static str {
        match self {
            MaterialKind::Diffuse => "diffuse",
            MaterialKind::Specular => "specular",
            MaterialKind::Glass { .. } => "glass",
        }
    }
}

/// A surface material.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    /// Linear RGB base colour (glTF `baseColorFactor`).
    pub base_color: Vec3,
    /// glTF metallic factor in [0, 1].
    pub metallic: f32,
    /// glTF roughness factor in [0, 1].
    pub roughness: f32,
    /// `KHR_materials_transmission` factor in [0, 1].
    pub transmission: f32,
    pub kind: MaterialKind,
    /// The base-colour factor's alpha in [0, 1] (glTF `baseColorFactor[3]`).
    pub base_alpha: f32,
    /// glTF `baseColorTexture`: multiplies the base colour (and its alpha the alpha).
    pub base_color_texture: Option<TextureBinding>,
    /// glTF `alphaMode` and `alphaCutoff`.
    pub alpha_mode: AlphaMode,
    /// Emitted linear radiance: glTF `emissiveFactor` times `KHR_materials_emissive_strength`
    /// (zero: none).
    pub emissive: Vec3,
    /// glTF `doubleSided`: as an emitter (`Scene::emissive_lights`) the surface emits on both
    /// sides, else only on its front (counter-clockwise) side. Shading is two-sided either way.
    pub double_sided: bool,
    /// The textures beyond the base colour's.
    pub maps: MaterialMaps,
}

/// The textures of a glTF metallic-roughness material other than its base colour's. All
/// of a material's textures are sampled at the texture coordinates of the first it has
/// (base colour, metallic-roughness, occlusion, emissive), which the loader checks or notes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialMaps {
    /// glTF `metallicRoughnessTexture`, linear: blue scales metallic, green roughness.
    pub metallic_roughness: Option<TextureBinding>,
    /// glTF `occlusionTexture`, linear: red is the ambient occlusion, blended towards 1 by
    /// [`MaterialMaps::occlusion_strength`].
    pub occlusion: Option<TextureBinding>,
    /// glTF `occlusionTexture.strength` in [0, 1] (1 unless given).
    pub occlusion_strength: f32,
    /// glTF `emissiveTexture`, sRGB: scales [`Material::emissive`].
    pub emissive: Option<TextureBinding>,
    /// glTF `normalTexture`, linear: the tangent-space normal `2 texel - 1`, its x and y
    /// scaled by [`MaterialMaps::normal_scale`], replaces the shading normal
    /// ([`crate::kernels::texture::Materials::normal_mapped`]).
    pub normal: Option<TextureBinding>,
    /// glTF `normalTexture.scale` (1 unless given).
    pub normal_scale: f32,
}

impl Default for MaterialMaps {
    fn default() -> Self {
        MaterialMaps {
            metallic_roughness: None,
            occlusion: None,
            occlusion_strength: 1.0,
            emissive: None,
            normal: None,
            normal_scale: 1.0,
        }
    }
}

impl Material {
    /// A grey diffuse material (the paper's grey Sponza).
    pub fn grey() -> Self {
        Material {
            name: "grey".into(),
            base_color: Vec3::splat(0.8),
            metallic: 0.0,
            roughness: 1.0,
            transmission: 0.0,
            kind: MaterialKind::Diffuse,
            base_alpha: 1.0,
            base_color_texture: None,
            alpha_mode: AlphaMode::Opaque,
            emissive: Vec3::ZERO,
            double_sided: false,
            maps: MaterialMaps::default(),
        }
    }

    /// The documented default rule for glTF materials without a `hyrt` extra:
    /// metallic (factor >= 0.5) or transmissive (factor > 0) materials are ray traced,
    /// everything else is rasterized.
    pub fn default_render_mode(&self) -> RenderMode {
        if self.metallic >= 0.5 || self.transmission > 0.0 {
            RenderMode::RayTraced
        } else {
            RenderMode::Raster
        }
    }
}

/// Where an object came from, for the `frame.json` object table.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ObjectSource {
    /// The file it was loaded from; `None` for built-in geometry.
    pub file: Option<PathBuf>,
    /// glTF node index.
    pub node: Option<usize>,
    /// glTF mesh index.
    pub mesh: Option<usize>,
    /// glTF primitive index within the mesh.
    pub primitive: Option<usize>,
}

/// A mesh placed in the world with a material and a render mode.
#[derive(Clone, Debug)]
pub struct Object {
    /// Object id: its index in [`Scene::objects`]; written to the G-buffer.
    pub id: u32,
    pub name: String,
    /// Index into [`Scene::meshes`].
    pub mesh: usize,
    /// Object-to-world transform.
    pub transform: Mat4,
    /// Index into [`Scene::materials`].
    pub material: usize,
    pub render_mode: RenderMode,
    pub source: ObjectSource,
}

/// A punctual light, as glTF's `KHR_lights_punctual` defines them. `intensity` scales
/// `color` in the extension's units: candela (lm/sr) for point and spot lights, lux (lm/m²)
/// for directional lights, taken as linear radiometric values without a luminous-efficacy
/// factor (as the Khronos sample viewer does). So a surface's outgoing radiance is the BRDF
/// x `color` x `intensity` (over the squared distance, for point and spot lights) x N.L.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    Point {
        position: Vec3,
        color: Vec3,
        intensity: f32,
        /// The extension's `range`: the light fades to nothing at this distance, with its
        /// recommended window `clamp(1 - (d / range)^4, 0, 1)` over the 1/d² falloff
        /// ([`crate::kernels::shading::light_falloff`]). `None`: no cutoff.
        range: Option<f32>,
    },
    /// `direction` is the direction the light travels (from the light into the scene).
    Directional { direction: Vec3, color: Vec3, intensity: f32 },
    /// A point light limited to a cone around `direction` (the way it points, from the
    /// light into the scene): full inside `inner_cone_angle`, none beyond
    /// `outer_cone_angle` (radians from the axis, `0 <= inner < outer <= pi/2`), the
    /// extension's smooth falloff between.
    Spot {
        position: Vec3,
        direction: Vec3,
        color: Vec3,
        intensity: f32,
        inner_cone_angle: f32,
        outer_cone_angle: f32,
        /// As [`Light::Point`]'s.
        range: Option<f32>,
    },
    /// An area light: the parallelogram `corner + [0, 1] edge_u + [0, 1] edge_v`, emitting
    /// to the side of `edge_u x edge_v` with radiance `color * intensity` (nits: unlike a
    /// point light's candela, its brightness does not depend on its size). Not visible
    /// to the camera (lights are not geometry); its shadows are soft, traced with
    /// `FrameOptions::shadow_samples` rays per surface.
    Quad { corner: Vec3, edge_u: Vec3, edge_v: Vec3, color: Vec3, intensity: f32 },
    /// An area light: a sphere of `radius` around `position`, emitting radiance `color *
    /// intensity` (nits) in every direction; sampled as [`Light::Quad`].
    Sphere { position: Vec3, radius: f32, color: Vec3, intensity: f32 },
    /// A directional light of finite angular size (a sun): it travels along `direction`,
    /// its disk spans `angular_diameter` (radians, in `(0, pi)`), and `color * intensity`
    /// is its illuminance at normal incidence (lux), as a directional light's. Sampled as
    /// [`Light::Quad`].
    Sun { direction: Vec3, angular_diameter: f32, color: Vec3, intensity: f32 },
}

impl Light {
    /// A point light without a range.
    pub fn point(position: Vec3, color: Vec3, intensity: f32) -> Light {
        Light::Point { position, color, intensity, range: None }
    }

    /// glTF's default cone of a spot light: inner 0, outer pi/4.
    pub const DEFAULT_OUTER_CONE_ANGLE: f32 = std::f32::consts::FRAC_PI_4;

    /// Check the values a light must have to be rendered: finite, non-negative colour and
    /// intensity, unit-length directions, cone angles with `0 <= inner < outer <= pi/2`, a
    /// positive finite range. The message names the problem.
    pub fn validate(&self) -> Result<(), String> {
        let (color, intensity) = match *self {
            Light::Point { color, intensity, .. }
            | Light::Directional { color, intensity, .. }
            | Light::Spot { color, intensity, .. }
            | Light::Quad { color, intensity, .. }
            | Light::Sphere { color, intensity, .. }
            | Light::Sun { color, intensity, .. } => (color, intensity),
        };
        if !color.is_finite() || color.min_element() < 0.0 {
            return Err(format!("color {color} must be finite and non-negative"));
        }
        if !(intensity >= 0.0 && intensity.is_finite()) {
            return Err(format!("intensity {intensity} must be finite and >= 0"));
        }
        let unit = |d: Vec3, what: &str| match d.is_finite() && (d.length() - 1.0).abs() <= 1e-5 {
            true => Ok(()),
            false => Err(format!("{what} {d} is not a unit vector")),
        };
        let range_ok = |range: Option<f32>| match range {
            Some(r) if !(r > 0.0 && r.is_finite()) => Err(format!("range {r} must be finite and > 0")),
            _ => Ok(()),
        };
        if let Light::Point { position, .. } | Light::Spot { position, .. } | Light::Sphere { position, .. } = *self {
            if !position.is_finite() {
                return Err(format!("position {position} is not finite"));
            }
        }
        match *self {
            Light::Point { range, .. } => range_ok(range),
            Light::Directional { direction, .. } => unit(direction, "direction"),
            Light::Spot { direction, inner_cone_angle, outer_cone_angle, range, .. } => {
                unit(direction, "direction")?;
                if !(inner_cone_angle >= 0.0
                    && inner_cone_angle < outer_cone_angle
                    && outer_cone_angle <= std::f32::consts::FRAC_PI_2)
                {
                    return Err(format!(
                        "cone angles inner {inner_cone_angle} and outer {outer_cone_angle} (radians) need \
                         0 <= inner < outer <= pi/2"
                    ));
                }
                range_ok(range)
            }
            Light::Quad { corner, edge_u, edge_v, .. } => {
                if !(corner.is_finite() && edge_u.is_finite() && edge_v.is_finite()) {
                    return Err(format!("corner {corner} and edges {edge_u}, {edge_v} must be finite"));
                }
                let area = edge_u.cross(edge_v).length();
                if !(area > 0.0 && area.is_finite()) {
                    return Err(format!(
                        "edges {edge_u} and {edge_v} span no area: they must be non-zero and not parallel"
                    ));
                }
                Ok(())
            }
            Light::Sphere { radius, .. } => match radius > 0.0 && radius.is_finite() {
                true => Ok(()),
                false => Err(format!("radius {radius} must be finite and > 0")),
            },
            Light::Sun { direction, angular_diameter, .. } => {
                unit(direction, "direction")?;
                match angular_diameter > 0.0 && angular_diameter < std::f32::consts::PI {
                    true => Ok(()),
                    false => {
                        Err(format!("angular diameter {} deg must lie in (0, 180)", angular_diameter.to_degrees()))
                    }
                }
            }
        }
    }

    /// Whether the light has an area (quad, sphere, sun): its shadows are soft, traced with
    /// several rays per surface.
    pub fn is_area(&self) -> bool {
        matches!(self, Light::Quad { .. } | Light::Sphere { .. } | Light::Sun { .. })
    }
}

/// A perspective camera (right-handed, looking from `eye` to `target`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f32,
    /// Near and far clip distances (> 0, near < far).
    pub near: f32,
    pub far: f32,
}

impl Camera {
    /// Vertical field of view of [`Camera::look_at`], in degrees.
    pub const DEFAULT_FOV_Y_DEG: f32 = 45.0;
    /// [`Camera::look_at`]'s near plane as a fraction of the eye-to-target distance:
    /// anything nearer than 1% of the distance to what the camera looks at is clipped.
    pub const DEFAULT_NEAR_FRACTION: f32 = 0.01;
    /// [`Camera::look_at`]'s far plane as a multiple of the eye-to-target distance:
    /// with near at 1% of it, depth spans a 1e5 ratio, which f32 depth holds to well
    /// under a pixel's depth step near the target.
    pub const DEFAULT_FAR_MULTIPLE: f32 = 1000.0;
    /// The smallest near plane [`Camera::look_at`] sets (an eye on its target, or
    /// nearly): the near plane of a 0.01-unit look-at distance, so scenes in metres
    /// keep a usable depth range however close the eye is.
    pub const MIN_NEAR: f32 = 1e-4;

    /// A camera at `eye` looking at `target` with `up` roughly up, a 45 degree vertical
    /// field of view, and near and far planes scaled to the eye-to-target distance
    /// ([`Self::DEFAULT_NEAR_FRACTION`], [`Self::DEFAULT_FAR_MULTIPLE`]). Set the fields
    /// afterwards to change any of them.
    ///
    /// ```
    /// use hyrt_core::glam::Vec3;
    /// use hyrt_core::scene::Camera;
    /// let cam = Camera::look_at(Vec3::new(0.0, 2.0, 10.0), Vec3::ZERO, Vec3::Y);
    /// assert!(cam.near > 0.0 && cam.near < 1.0 && cam.far > 100.0);
    /// ```
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3) -> Camera {
        let near = ((target - eye).length() * Self::DEFAULT_NEAR_FRACTION).max(Self::MIN_NEAR);
        let far = near * (Self::DEFAULT_FAR_MULTIPLE / Self::DEFAULT_NEAR_FRACTION);
        Camera { eye, target, up, fov_y_deg: Self::DEFAULT_FOV_Y_DEG, near, far }
    }

    /// World-to-view matrix (right-handed, -Z forward).
    pub fn view(&self) -> Mat4 {
        glam::camera::rh::view::look_at_mat4(self.eye, self.target, self.up)
    }
    /// View-to-clip matrix in the WebGPU convention: NDC y up, depth in [0, 1]
    /// (glam's right-handed `directx` projection; the viewport flips y).
    pub fn projection(&self, aspect: f32) -> Mat4 {
        glam::camera::rh::proj::directx::perspective(self.fov_y_deg.to_radians(), aspect, self.near, self.far)
    }
    /// World-to-clip matrix for an image of `width` x `height` pixels.
    pub fn view_projection(&self, width: u32, height: u32) -> Mat4 {
        self.projection(width as f32 / height as f32) * self.view()
    }
    /// Eye-relative world-to-clip matrix: `clip = M * (p - eye, 1)`, the projection times the
    /// view's rotation alone (no translation). The stages project `p - eye` with it
    /// ([`crate::formats::CameraRecord::view_proj`]): far from the origin a full matrix
    /// would add a translation of the eye's size to products of that size, and lose the
    /// positions' low bits (at 1e5, about 0.01 units); `p - eye` is exact or nearly so for
    /// every point near the eye.
    pub fn view_projection_from_eye(&self, width: u32, height: u32) -> Mat4 {
        let view = glam::camera::rh::view::look_at_mat4(Vec3::ZERO, self.target - self.eye, self.up);
        self.projection(width as f32 / height as f32) * view
    }
}

/// The largest distance from `eye` to a corner of the box `lo..hi` (what a far plane
/// derived from the scene bounds must reach: the glTF loader's and the manifest's).
pub(crate) fn farthest_corner(eye: Vec3, lo: Vec3, hi: Vec3) -> f32 {
    (0..8)
        .map(|k| {
            let c = Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            (c - eye).length()
        })
        .fold(0.0, f32::max)
}

/// A loaded scene.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    pub meshes: Vec<Mesh>,
    pub materials: Vec<Material>,
    pub objects: Vec<Object>,
    pub lights: Vec<Light>,
    pub camera: Option<Camera>,
    /// What rays that leave the scene see: the default sky, or an environment map
    /// (manifest key `environment`, `hyrt render --environment FILE`).
    pub environment: Environment,
    /// Decoded images that materials' textures sample ([`TextureBinding::image`] indexes
    /// them); shared, so cloning a scene does not copy texels.
    pub textures: Vec<Arc<TextureImage>>,
    /// Human-readable notes about what the loader decided (default lights added,
    /// camera framed automatically, primitives skipped, ...). The CLI prints them.
    pub notes: Vec<String>,
    /// The node hierarchy and animations of a glTF file that has some ([`Scene::set_time`]
    /// poses the scene); `None` for every other scene.
    pub animation: Option<SceneAnimation>,
    /// How direct light is shaded on every object (manifest key `shading`, `hyrt render
    /// --shading`): the paper's model or the glTF BRDF. Scenes loaded from files and
    /// [`Scene::default_scene`] use the glTF BRDF; a `Scene` built by hand starts with the
    /// paper's model ([`ShadingModel::default`]) until it says otherwise.
    pub shading: ShadingModel,
    /// The constant ambient light (manifest key `ambient`, `hyrt render --ambient`):
    /// [`crate::kernels::shading::AMBIENT`] by default, 0 for none. With the glTF model the
    /// environment's image-based light comes on top of it
    /// ([`crate::kernels::ibl::AmbientLight`]).
    pub ambient: Ambient,
    /// Whether emissive objects light the scene (manifest key `emissive_lights`): every
    /// triangle of an object whose material's `emissive` is non-zero becomes part of one
    /// area light sampled by area ([`crate::formats::LIGHT_EMITTERS`],
    /// [`crate::geometry::emitter_table`]). Off by default: emission is then only seen.
    pub emissive_lights: bool,
}

impl Scene {
    /// Load a scene from a `.glb`, `.gltf` or `.toml` file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        Scene::load_from(path, &Disk)
    }

    /// [`Scene::load`] reading the file, and every file it refers to, from `files` (files
    /// in memory, say); errors name the files as [`Scene::load`]'s do.
    pub fn load_from(path: &Path, files: &dyn SceneFiles) -> Result<Scene, SceneError> {
        let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
        match ext.as_deref() {
            Some("glb") | Some("gltf") => gltf_loader::load_gltf_from(path, files),
            Some("toml") => manifest::load_manifest_from(path, files),
            _ => Err(SceneError::UnknownFormat { path: path.to_path_buf() }),
        }
    }

    /// Add a mesh with its own material as a new object (id = its index, name =
    /// the mesh's name, no source file). Returns the object id.
    pub fn add_object(&mut self, mesh: Mesh, material: Material, transform: Mat4, render_mode: RenderMode) -> u32 {
        let id = self.objects.len() as u32;
        let name = mesh.name.clone();
        self.meshes.push(mesh);
        self.materials.push(material);
        self.objects.push(Object {
            id,
            name,
            mesh: self.meshes.len() - 1,
            transform,
            material: self.materials.len() - 1,
            render_mode,
            source: ObjectSource::default(),
        });
        id
    }

    /// Total triangle count over all objects.
    pub fn triangle_count(&self) -> usize {
        self.objects.iter().map(|o| self.meshes[o.mesh].triangle_count()).sum()
    }

    /// World-space bounds (min, max) of all finite object vertices; `None` if there are none.
    pub fn world_bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for o in &self.objects {
            for p in &self.meshes[o.mesh].positions {
                let w = o.transform.transform_point3(*p);
                if w.is_finite() {
                    lo = lo.min(w);
                    hi = hi.max(w);
                }
            }
        }
        (lo.x <= hi.x).then_some((lo, hi))
    }

    /// Whether emissive meshes light the scene: [`Scene::emissive_lights`] and some object's
    /// material emits (a non-zero `emissive`; its texture may still leave every triangle
    /// black, which [`crate::geometry::emitter_table`] tells).
    pub fn emits_light(&self) -> bool {
        self.emissive_lights && self.objects.iter().any(|o| self.materials[o.material].emissive != Vec3::ZERO)
    }

    /// Give the scene a camera if it has none and default lights if it has none (nor
    /// emissive meshes as lights, [`Scene::emits_light`]); each
    /// decision is recorded in [`Scene::notes`]. An interior (a building, a room: free space
    /// that the scene's surfaces enclose) is seen from inside, lights inside too
    /// ([`framing::interior_view`]); anything else is framed from outside, its bounding
    /// sphere fitting the field of view.
    pub fn ensure_camera_and_lights(&mut self) {
        let (lo, hi) = self.world_bounds().unwrap_or((Vec3::splat(-1.0), Vec3::splat(1.0)));
        let center = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1e-3);
        let interior = if self.camera.is_none() { framing::interior_view(self, lo, hi) } else { None };
        if let Some(view) = &interior {
            self.notes.push(view.note.clone());
            self.camera = Some(view.camera);
        }
        if self.camera.is_none() {
            let fov_y_deg = 45.0f32;
            // Distance at which a sphere of `radius` fits the vertical field of view.
            let dist = radius / (fov_y_deg.to_radians() * 0.5).sin();
            let dir = Vec3::new(0.35, 0.3, 1.0).normalize();
            let cam = Camera {
                eye: center + dir * dist,
                target: center,
                up: Vec3::Y,
                fov_y_deg,
                near: (dist - radius).max(dist * 1e-3).max(1e-4) * 0.5,
                far: (dist + radius) * 2.0,
            };
            self.notes.push(format!(
                "no camera in the scene: framed automatically (eye {:.3?}, target {:.3?}, fov {fov_y_deg} deg)",
                cam.eye, cam.target
            ));
            self.camera = Some(cam);
        }
        // A scene lit by its emissive meshes alone (`emissive_lights`) gets no default lights.
        let unlit = self.lights.is_empty() && !self.emits_light();
        if let (true, Some(view)) = (unlit, &interior) {
            // Inside: above the eye and above the point looked at, each bright enough for
            // an irradiance of about 2.5 there (as outside lights give the centre).
            let [key, fill] = view.lights;
            let dist2 = |p: Vec3, at: Vec3| (p - at).length_squared().max(1e-6);
            self.lights.push(Light::point(key, Vec3::ONE, 2.5 * dist2(key, view.camera.eye)));
            self.lights.push(Light::point(fill, Vec3::ONE, 2.5 * dist2(fill, view.camera.target)));
            self.notes.push(format!(
                "no lights in the scene: added two default point lights inside, at {key:.3?} and {fill:.3?}"
            ));
        }
        if unlit && self.lights.is_empty() {
            // A key light above and to the side of the camera, and a weaker fill light.
            let eye = self.camera.map(|c| c.eye).unwrap_or(center + Vec3::Z * radius * 3.0);
            let side = (eye - center).cross(Vec3::Y).normalize_or(Vec3::X);
            let key = center + Vec3::Y * radius * 2.0 + side * radius * 1.5 + (eye - center) * 0.5;
            let fill = center + Vec3::Y * radius * 1.5 - side * radius * 2.0 + (eye - center) * 0.3;
            let key_d2 = (key - center).length_squared();
            let fill_d2 = (fill - center).length_squared();
            self.lights.push(Light::point(key, Vec3::ONE, 2.5 * key_d2));
            self.lights.push(Light::point(fill, Vec3::ONE, 0.8 * fill_d2));
            self.notes
                .push(format!("no lights in the scene: added two default point lights at {key:.3?} and {fill:.3?}"));
        }
    }
}
