//! The one merge every scene file goes through. A glTF file loaded alone ([`Scene::load`] of a
//! `.glb`/`.gltf`) and each `[[model]]` of a TOML manifest are placed into the scene by the
//! same three steps, so that whatever a loaded file holds reaches a manifest's scene too:
//!
//! 1. `Merge::add_file`, once per file however many models use it: its meshes and decoded
//!    images join the scene (shared by every model placing the file), its loader notes too.
//! 2. `Merge::place`, once per model: the file's materials (a manifest's override applied,
//!    their texture indices moved past the textures of the files before), its objects at the
//!    model's placement (once per `repeat` copy), its lights and its camera (moved by the
//!    model's matrix), its node hierarchy and animations (their nodes, objects, camera and
//!    lights renumbered into the scene's, one copy of the hierarchy per `repeat` copy, all
//!    driven by the same animation).
//! 3. `Merge::finish`: the lights and camera (the files' unless the manifest gives its
//!    own), the scene's animations, the rest pose.
//!
//! A file loaded alone is a model with the identity placement, its own object names and no
//! overrides (`Model::file_alone`); such a placement copies the file's transforms, lights
//! and camera as they are (no multiplication by the identity, which could turn a `-0.0`
//! into `0.0`), so a one-model manifest without a transform gives the same scene, and the
//! same image, as the file alone.
//!
//! **Animations.** A model's placement becomes a node of the hierarchy above the file's
//! roots (a `matrix` node: [`SceneNode::gltf_index`] `None`), unless it is the identity;
//! the rest pose of an animated model is then posed through the hierarchy, so that
//! [`Scene::reset_pose`] gives it back bit for bit. The scene's animations:
//!
//! * one animated model: its file's animations, names and order kept, except that the one
//!   its `animation` key names (if any) comes first;
//! * several: first [`ALL_ANIMATIONS`], playing every animated model's chosen animation (its
//!   `animation` key, else its file's first) together, then every model's animations, named
//!   `<model name>/<animation name>` in manifest order.
//!
//! Animation 0 is what `hyrt render --time T` plays without `--animation`.

use glam::{Mat4, Vec3};

use super::animation::{Animation, AnimationChannel, NodeTransform, SceneAnimation, SceneNode};
use super::files::Budget;
use super::{Camera, Light, Material, Object, RenderMode, Scene, ShadingModel};

/// The name of the animation that plays every animated model of a manifest together (the
/// scene's first when several models are animated).
pub const ALL_ANIMATIONS: &str = "all";

/// How a model's objects are named.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Naming<'a> {
    /// As the file names them (a file loaded alone).
    AsFile,
    /// `<name>/<object name>`, or `<name>#<copy>/<object name>` for `repeat` copies.
    Prefixed(&'a str),
    /// `<name>`, or `<name>#<copy>`: a built-in shape's single object.
    Whole(&'a str),
}

impl<'a> Naming<'a> {
    /// The model's name; `None` for a file loaded alone.
    fn model_name(self) -> Option<&'a str> {
        match self {
            Naming::AsFile => None,
            Naming::Prefixed(name) | Naming::Whole(name) => Some(name),
        }
    }
}

/// Where and how a model places a file.
pub(crate) struct Model<'a> {
    /// The manifest's name for it (`model[1] 'bunny'`), prefixed to the file's notes and
    /// used in messages; `None` for a file loaded alone.
    pub label: Option<&'a str>,
    pub naming: Naming<'a>,
    /// The model matrix; each copy is placed at `translate(offset) * matrix`.
    pub matrix: Mat4,
    /// World offsets of the copies (one `Vec3::ZERO` without `repeat`).
    pub copies: &'a [Vec3],
    /// A manifest's material override, applied to every material of the file.
    pub material: Option<&'a dyn Fn(&Material) -> Material>,
    /// A manifest's render mode for every object of the model.
    pub render_mode: Option<RenderMode>,
    /// The file animation this model plays in the scene's first animation, by name (default:
    /// the file's first).
    pub animation: Option<&'a str>,
}

impl Model<'_> {
    /// A file loaded alone: the identity placement, one copy, the file's names, no overrides.
    pub(crate) fn file_alone() -> Model<'static> {
        Model {
            label: None,
            naming: Naming::AsFile,
            matrix: Mat4::IDENTITY,
            copies: &[Vec3::ZERO],
            material: None,
            render_mode: None,
            animation: None,
        }
    }
}

/// Where a file's meshes and images start in the merged scene.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FileSlot {
    meshes: usize,
    textures: usize,
}

/// A model's animations, moved onto its nodes in the merged hierarchy.
struct AnimatedModel {
    /// The model's name, for `<model name>/<animation name>`.
    name: String,
    /// Index of the animation it plays in [`ALL_ANIMATIONS`].
    chosen: usize,
    animations: Vec<Animation>,
}

/// The camera of the first model file that has one.
struct ModelCamera {
    camera: Camera,
    /// The model it came from (`None`: a file loaded alone).
    label: Option<String>,
}

/// A scene being merged from files and models; see the module docs.
pub(crate) struct Merge {
    scene: Scene,
    budget: Budget,
    /// The model files' lights, moved by their model matrices.
    lights: Vec<Light>,
    camera: Option<ModelCamera>,
    /// The merged hierarchy of every animated model.
    nodes: Vec<SceneNode>,
    animated: Vec<AnimatedModel>,
    /// Whether a placement node was added (the rest pose is then posed through it).
    placed_hierarchy: bool,
    /// The manifest's models whose files gave lights, and how many each.
    light_sources: Vec<(String, usize)>,
}

impl Merge {
    pub(crate) fn new(budget: Budget) -> Merge {
        Merge {
            // Every scene loaded from a file (a glTF file alone, or a manifest's models)
            // is shaded with the glTF BRDF unless a manifest's `shading` says otherwise:
            // glTF materials mean metallic-roughness (issue 37).
            scene: Scene { shading: ShadingModel::Gltf, ..Scene::default() },
            budget,
            lights: Vec::new(),
            camera: None,
            nodes: Vec::new(),
            animated: Vec::new(),
            placed_hierarchy: false,
            light_sources: Vec::new(),
        }
    }

    /// The scene merged so far (a manifest sets its environment here).
    pub(crate) fn scene_mut(&mut self) -> &mut Scene {
        &mut self.scene
    }

    /// Add a loaded file's meshes, images and notes (each note prefixed with `label`), and
    /// grow the budget by its `input_bytes` (the file's and its buffers' bytes); the returned
    /// slot places it, as often as models ask.
    pub(crate) fn add_file(&mut self, file: &Scene, input_bytes: usize, label: Option<&str>) -> FileSlot {
        self.budget.add_input(input_bytes);
        let slot = FileSlot { meshes: self.scene.meshes.len(), textures: self.scene.textures.len() };
        self.scene.meshes.extend(file.meshes.iter().cloned());
        self.scene.textures.extend(file.textures.iter().cloned());
        self.scene.notes.extend(file.notes.iter().map(|n| match label {
            Some(label) => format!("{label}: {n}"),
            None => n.clone(),
        }));
        slot
    }

    /// Place `file` (added at `slot`) as `model` says. `mode_from_extras` tells, per object of
    /// the file, whether its render mode came from a `hyrt` extra (kept under a material
    /// override) or from its material (decided again after the override). The message says
    /// what is wrong (an unknown `animation`, past the load's budget).
    pub(crate) fn place(
        &mut self,
        file: &Scene,
        slot: FileSlot,
        mode_from_extras: &[bool],
        model: &Model,
    ) -> Result<(), String> {
        let copies = model.copies.len();
        let name_bytes = model.naming.model_name().map_or(0, |name| name.len() + 1);
        // A file's objects (and hierarchy) are placed again by every model naming it: charged
        // before they are.
        let placed_bytes = file.materials.len() * std::mem::size_of::<Material>()
            + file.objects.iter().map(|o| std::mem::size_of::<Object>() + name_bytes + o.name.len()).sum::<usize>()
            + file.animation.as_ref().map_or(0, |a| {
                (a.nodes().len() + 1) * std::mem::size_of::<SceneNode>()
                    + a.animations().iter().map(|a| a.channels().len()).sum::<usize>()
                        * std::mem::size_of::<AnimationChannel>()
            });
        self.budget.take(copies, placed_bytes, "objects and materials placed")?;
        let chosen = match (model.animation, &file.animation) {
            (None, _) => 0,
            (Some(wanted), Some(animation)) => animation.find(wanted).ok_or_else(|| {
                let names: Vec<String> = animation.animations().iter().map(|a| format!("'{}'", a.name())).collect();
                format!("animation '{wanted}': the file has no animation of that name (it has {})", names.join(", "))
            })?,
            (Some(wanted), None) => return Err(format!("animation '{wanted}': the file has no animations")),
        };

        let material_offset = self.scene.materials.len();
        self.scene.materials.extend(file.materials.iter().map(|m| {
            let mut m = match model.material {
                Some(apply) => apply(m),
                None => m.clone(),
            };
            if let Some(texture) = m.base_color_texture.as_mut() {
                texture.image += slot.textures;
            }
            m
        }));
        let light_offset = self.lights.len();
        let gives_camera = self.camera.is_none() && file.camera.is_some();
        let mut hierarchy_copies = Vec::with_capacity(copies);
        for (c, offset) in model.copies.iter().enumerate() {
            let placed = Mat4::from_translation(*offset) * model.matrix;
            let identity = placed == Mat4::IDENTITY;
            let copy = if copies > 1 { format!("#{c}") } else { String::new() };
            let first_object = self.scene.objects.len() as u32;
            for (object, &decided_by_extras) in file.objects.iter().zip(mode_from_extras) {
                let material = material_offset + object.material;
                let render_mode = match model.render_mode {
                    Some(mode) => mode,
                    None if decided_by_extras => object.render_mode,
                    None => self.scene.materials[material].default_render_mode(),
                };
                let id = u32::try_from(self.scene.objects.len())
                    .map_err(|_| "more than 2^32 objects (object ids are 32-bit)".to_string())?;
                self.scene.objects.push(Object {
                    id,
                    name: match model.naming {
                        Naming::AsFile => object.name.clone(),
                        Naming::Prefixed(name) => format!("{name}{copy}/{}", object.name),
                        Naming::Whole(name) => format!("{name}{copy}"),
                    },
                    mesh: slot.meshes + object.mesh,
                    transform: if identity { object.transform } else { placed * object.transform },
                    material,
                    render_mode,
                    source: object.source.clone(),
                });
            }
            if let Some(animation) = &file.animation {
                // Copy 0 places the file's camera (when it is the scene's) and its lights.
                let first = c == 0;
                let placement = (!identity).then_some(placed);
                let base = self.hierarchy_copy(animation, placement, model.label, first_object, |node| {
                    (first && gives_camera && node.camera, node.light.filter(|_| first).map(|l| light_offset + l))
                });
                hierarchy_copies.push(base);
            }
        }

        let identity = model.matrix == Mat4::IDENTITY;
        if let (Some(label), false) = (model.label, file.lights.is_empty()) {
            self.light_sources.push((label.to_string(), file.lights.len()));
        }
        self.lights.extend(file.lights.iter().map(|&light| match light {
            _ if identity => light,
            // The light's properties (intensity, range, cone angles) are not scaled by the
            // transform: KHR_lights_punctual says so of a node's scale.
            Light::Point { position, color, intensity, range } => {
                Light::Point { position: model.matrix.transform_point3(position), color, intensity, range }
            }
            Light::Spot { position, direction, color, intensity, inner_cone_angle, outer_cone_angle, range } => {
                Light::Spot {
                    position: model.matrix.transform_point3(position),
                    direction: model.matrix.transform_vector3(direction).normalize_or(direction),
                    color,
                    intensity,
                    inner_cone_angle,
                    outer_cone_angle,
                    range,
                }
            }
            Light::Directional { direction, color, intensity } => Light::Directional {
                direction: model.matrix.transform_vector3(direction).normalize_or(direction),
                color,
                intensity,
            },
            Light::Sun { direction, angular_diameter, color, intensity } => Light::Sun {
                direction: model.matrix.transform_vector3(direction).normalize_or(direction),
                angular_diameter,
                color,
                intensity,
            },
            // Area lights are placed with the model: their size follows its transform (a
            // sphere's radius by the cube root of the volume scale), their radiance does not.
            Light::Quad { corner, edge_u, edge_v, color, intensity } => Light::Quad {
                corner: model.matrix.transform_point3(corner),
                edge_u: model.matrix.transform_vector3(edge_u),
                edge_v: model.matrix.transform_vector3(edge_v),
                color,
                intensity,
            },
            Light::Sphere { position, radius, color, intensity } => Light::Sphere {
                position: model.matrix.transform_point3(position),
                radius: radius * model.matrix.determinant().abs().cbrt(),
                color,
                intensity,
            },
        }));
        if let (true, Some(c)) = (gives_camera, file.camera) {
            let camera = if identity {
                c
            } else {
                // Near and far scale with the model's size (the cube root of its volume scale).
                let volume_scale = model.matrix.determinant().abs().cbrt();
                Camera {
                    eye: model.matrix.transform_point3(c.eye),
                    target: model.matrix.transform_point3(c.target),
                    up: model.matrix.transform_vector3(c.up).normalize_or(c.up),
                    fov_y_deg: c.fov_y_deg,
                    near: c.near * volume_scale,
                    far: c.far * volume_scale,
                }
            };
            self.camera = Some(ModelCamera { camera, label: model.label.map(str::to_string) });
        }

        if let Some(animation) = &file.animation {
            let animations = animation
                .animations()
                .iter()
                .map(|a| {
                    // Every copy's nodes follow the same samplers.
                    let channels = hierarchy_copies
                        .iter()
                        .flat_map(|&base| {
                            a.channels().iter().map(move |ch| AnimationChannel { node: base + ch.node, ..*ch })
                        })
                        .collect();
                    Animation::new(a.name().to_string(), channels, a.samplers().to_vec())
                })
                .collect::<Result<Vec<_>, String>>()?;
            let name = model.naming.model_name().unwrap_or_default().to_string();
            self.animated.push(AnimatedModel { name, chosen, animations });
        }
        Ok(())
    }

    /// Append one copy of `animation`'s hierarchy, under a node placing it at `placement`
    /// (`None`: the identity, no node), its objects renumbered from `first_object`, and `camera_and_light`
    /// deciding per node whether it keeps placing the scene's camera and which scene light it
    /// places. Returns the index in the merged hierarchy of the copy's first file node.
    fn hierarchy_copy(
        &mut self,
        animation: &SceneAnimation,
        placement: Option<Mat4>,
        label: Option<&str>,
        first_object: u32,
        camera_and_light: impl Fn(&SceneNode) -> (bool, Option<usize>),
    ) -> usize {
        let placement = placement.map(|placed| {
            self.nodes.push(SceneNode {
                gltf_index: None,
                label: format!("{} placement", label.unwrap_or("the model's")),
                parent: None,
                transform: NodeTransform::Matrix(placed),
                rest: placed,
                objects: Vec::new(),
                camera: false,
                light: None,
            });
            self.placed_hierarchy = true;
            self.nodes.len() - 1
        });
        let base = self.nodes.len();
        for node in animation.nodes() {
            let (camera, light) = camera_and_light(node);
            self.nodes.push(SceneNode {
                gltf_index: node.gltf_index,
                label: match label {
                    Some(label) => format!("{label}: {}", node.label),
                    None => node.label.clone(),
                },
                parent: node.parent.map(|p| base + p).or(placement),
                transform: node.transform,
                rest: node.rest,
                objects: node.objects.iter().map(|o| first_object + o).collect(),
                camera,
                light,
            });
        }
        base
    }

    /// The merged scene: lights (`lights`, a manifest's own, else the model files'), the
    /// camera (the first model file's, unless `own_camera`: the manifest then sets its own),
    /// the animations and the rest pose; notes say which camera and lights were taken.
    pub(crate) fn finish(mut self, lights: Option<Vec<Light>>, own_camera: bool) -> Result<Scene, String> {
        match lights {
            Some(lights) => {
                self.scene.lights = lights;
                self.nodes.iter_mut().for_each(|n| n.light = None);
            }
            None => {
                if !self.light_sources.is_empty() {
                    let from: Vec<String> =
                        self.light_sources.iter().map(|(label, n)| format!("{n} from {label}")).collect();
                    self.scene.notes.push(format!(
                        "{} lights taken from the model files ({})",
                        self.lights.len(),
                        from.join(", ")
                    ));
                }
                self.scene.lights = std::mem::take(&mut self.lights);
            }
        }
        if own_camera {
            self.nodes.iter_mut().for_each(|n| n.camera = false);
        }
        match (self.camera.take(), own_camera) {
            (Some(ModelCamera { label: Some(label), .. }), true) => {
                self.scene.notes.push(format!("camera: {label}'s file camera is not used: the manifest's [camera] is"));
            }
            (Some(ModelCamera { label, camera }), false) => {
                if let Some(label) = label {
                    self.scene.notes.push(format!("camera taken from {label}: {}", describe_camera(&camera)));
                }
                self.scene.camera = Some(camera);
            }
            _ => {}
        }
        let animations = scene_animations(std::mem::take(&mut self.animated))?;
        if !animations.is_empty() {
            self.scene.animation = Some(SceneAnimation::new(std::mem::take(&mut self.nodes), animations)?);
            if self.placed_hierarchy {
                self.scene
                    .pose(None)
                    .map_err(|(node, what)| format!("the rest pose leaves the {what} of {node} degenerate"))?;
            }
        }
        Ok(self.scene)
    }
}

/// `eye [..], target [..], up [..], fov 45 deg, near 0.01, far 1000`.
pub(crate) fn describe_camera(c: &Camera) -> String {
    format!(
        "eye {:.4?}, target {:.4?}, up {:.3?}, fov {} deg, near {}, far {}",
        c.eye.to_array(),
        c.target.to_array(),
        c.up.to_array(),
        c.fov_y_deg,
        c.near,
        c.far
    )
}

/// The scene's animations from its animated models (see the module docs).
fn scene_animations(mut animated: Vec<AnimatedModel>) -> Result<Vec<Animation>, String> {
    match animated.len() {
        0 => return Ok(Vec::new()),
        1 => {
            let model = animated.remove(0);
            let mut animations = model.animations;
            let chosen = animations.remove(model.chosen);
            animations.insert(0, chosen);
            return Ok(animations);
        }
        _ => {}
    }
    let (mut channels, mut samplers) = (Vec::new(), Vec::new());
    for model in &animated {
        let a = &model.animations[model.chosen];
        let base = samplers.len();
        channels.extend(a.channels().iter().map(|c| AnimationChannel { sampler: base + c.sampler, ..*c }));
        samplers.extend(a.samplers().iter().cloned());
    }
    let mut animations = vec![Animation::new(ALL_ANIMATIONS.to_string(), channels, samplers)?];
    for model in animated {
        for a in model.animations {
            let name = format!("{}/{}", model.name, a.name());
            animations.push(Animation::new(name, a.channels().to_vec(), a.samplers().to_vec())?);
        }
    }
    Ok(animations)
}
