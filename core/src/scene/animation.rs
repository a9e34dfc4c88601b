//! Node animation: the glTF node hierarchy and its keyframed translations, rotations and
//! scales (glTF 2.0 section 3.11), kept on the scene so it can be posed at any time.
//!
//! A loaded glTF file with `animations` gets a [`SceneAnimation`] ([`Scene::animation`]):
//!
//! * its **nodes** ([`SceneNode`]), in the loader's walk order, so a parent precedes its
//!   children: each with its parent, its local transform (TRS or matrix), the matrix the
//!   loader placed it with, and what it places: objects, the scene's camera, a light;
//! * its **animations** ([`Animation`]): a name, channels (a node, a property, a sampler)
//!   and samplers (key times, key values, an [`Interpolation`]), validated when loaded.
//!
//! [`Scene::set_time`] poses the scene at a time of one animation: every node the animation
//! drives gets its sampled local transform (the properties no channel drives keep the node's
//! own), every node's world transform is `parent world * local`, and the objects, the camera
//! (eye = world translation, looking along world -Z, up = world +Y) and the lights (point:
//! world translation; directional: along world -Z) follow, by the loader's own formulas.
//! Nodes the animation does not drive, and whose ancestors it does not drive, get their
//! loaded transforms bit for bit; [`Scene::reset_pose`] restores the loaded pose exactly.
//! Times before an animation's first key take its first values, and times after its
//! [`Animation::duration`] its last (glTF clamps; a caller that wants a loop takes the time
//! modulo the duration). A camera's field of view, near and far planes do not change.
//!
//! Scenes without animations have no [`SceneAnimation`] and pay nothing. What is not
//! animated (morph target weights, skins) is listed in [`Scene::notes`] by the loader.
//!
//! ```no_run
//! use hyrt_core::scene::Scene;
//! let mut scene = Scene::load("walk.gltf".as_ref())?;
//! let animation = scene.animation.as_ref().and_then(|a| a.find("walk")).unwrap_or(0);
//! scene.set_time(animation, 1.25)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod sampling;

pub use sampling::{
    cubic_hermite, lerp, locate, sample_rotation, sample_vec3, slerp, step, Interpolation, KeyPosition,
    SLERP_LINEAR_COSINE,
};

use glam::{Mat4, Quat, Vec3};

use super::{Light, Scene};
use crate::error::AnimationError;

/// The node property a channel drives (glTF `channel.target.path`; `weights` is not
/// supported and never reaches the model).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AnimatedProperty {
    Translation,
    Rotation,
    Scale,
}

impl AnimatedProperty {
    /// The name glTF uses.
    pub const fn name(self) -> &'static str {
        match self {
            AnimatedProperty::Translation => "translation",
            AnimatedProperty::Rotation => "rotation",
            AnimatedProperty::Scale => "scale",
        }
    }
}

/// A sampler's output values, one per key (three per key for
/// [`Interpolation::CubicSpline`]: in-tangent, value, out-tangent).
#[derive(Clone, Debug, PartialEq)]
pub enum Keyframes {
    /// Translations or scales.
    Vectors(Vec<Vec3>),
    /// Rotations; the values (not the tangents) are unit quaternions.
    Rotations(Vec<Quat>),
}

impl Keyframes {
    fn len(&self) -> usize {
        match self {
            Keyframes::Vectors(v) => v.len(),
            Keyframes::Rotations(v) => v.len(),
        }
    }
}

/// Key times, key values and how to interpolate between them (glTF `animation.sampler`).
#[derive(Clone, Debug, PartialEq)]
pub struct AnimationSampler {
    times: Vec<f32>,
    values: Keyframes,
    interpolation: Interpolation,
}

impl AnimationSampler {
    /// A sampler, checked as glTF requires: at least one key (two for `CUBICSPLINE`), finite
    /// times from 0 on, strictly increasing, one value per key (three for `CUBICSPLINE`),
    /// every value finite. Rotation values (not tangents) are normalized here, so that they
    /// are unit as the specification says (normalized-integer keys are unit only to their
    /// quantization); a zero rotation value is an error. The message says what is wrong.
    pub fn new(times: Vec<f32>, mut values: Keyframes, interpolation: Interpolation) -> Result<Self, String> {
        let min_keys = match interpolation {
            Interpolation::CubicSpline => 2,
            Interpolation::Step | Interpolation::Linear => 1,
        };
        if times.len() < min_keys {
            return Err(format!("{} key times; {} needs at least {min_keys}", times.len(), interpolation.name()));
        }
        if let Some(k) = times.iter().position(|t| !t.is_finite() || *t < 0.0) {
            return Err(format!("key time {k} is {}: times are finite seconds from 0", times[k]));
        }
        if let Some(k) = times.windows(2).position(|w| w[1] <= w[0]) {
            return Err(format!(
                "key times must increase strictly: time {} is {} after {}",
                k + 1,
                times[k + 1],
                times[k]
            ));
        }
        let per_key = interpolation.outputs_per_key();
        if values.len() != times.len() * per_key {
            return Err(format!(
                "{} output values for {} key times; {} needs {}",
                values.len(),
                times.len(),
                interpolation.name(),
                times.len() * per_key
            ));
        }
        match &mut values {
            Keyframes::Vectors(v) => {
                if let Some(k) = v.iter().position(|x| !x.is_finite()) {
                    return Err(format!("output value {k} is not finite: {}", v[k]));
                }
            }
            Keyframes::Rotations(q) => {
                if let Some(k) = q.iter().position(|x| !x.is_finite()) {
                    return Err(format!("output value {k} is not finite: {}", q[k]));
                }
                for k in (per_key / 2..q.len()).step_by(per_key) {
                    let length = q[k].length();
                    if length == 0.0 {
                        return Err(format!("rotation value {k} is the zero quaternion"));
                    }
                    q[k] = Quat::from_vec4(glam::Vec4::from(q[k]) / length);
                }
            }
        }
        Ok(AnimationSampler { times, values, interpolation })
    }

    /// Key times in seconds, strictly increasing.
    pub fn times(&self) -> &[f32] {
        &self.times
    }
    /// Output values.
    pub fn values(&self) -> &Keyframes {
        &self.values
    }
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }
    /// The last key time.
    pub fn end(&self) -> f32 {
        self.times[self.times.len() - 1]
    }
}

/// One property of one node driven by one sampler (glTF `animation.channel`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AnimationChannel {
    /// Index into [`SceneAnimation::nodes`].
    pub node: usize,
    pub property: AnimatedProperty,
    /// Index into [`Animation::samplers`].
    pub sampler: usize,
}

/// A named set of channels played together (glTF `animation`).
#[derive(Clone, Debug, PartialEq)]
pub struct Animation {
    name: String,
    channels: Vec<AnimationChannel>,
    samplers: Vec<AnimationSampler>,
}

impl Animation {
    /// An animation, checked: each channel's sampler exists and holds the kind of value its
    /// property needs (rotations for rotation, vectors otherwise), and no two channels drive
    /// the same property of the same node. Node indices are checked by [`SceneAnimation::new`].
    pub fn new(name: String, channels: Vec<AnimationChannel>, samplers: Vec<AnimationSampler>) -> Result<Self, String> {
        for (c, channel) in channels.iter().enumerate() {
            let sampler = samplers
                .get(channel.sampler)
                .ok_or_else(|| format!("channel {c}: sampler {} does not exist", channel.sampler))?;
            let rotations = matches!(sampler.values, Keyframes::Rotations(_));
            if rotations != (channel.property == AnimatedProperty::Rotation) {
                return Err(format!(
                    "channel {c}: drives {} with {}",
                    channel.property.name(),
                    if rotations { "rotations" } else { "vectors" }
                ));
            }
            if let Some(first) =
                channels[..c].iter().position(|o| o.node == channel.node && o.property == channel.property)
            {
                return Err(format!(
                    "channels {first} and {c} both drive the {} of the same node",
                    channel.property.name()
                ));
            }
        }
        Ok(Animation { name, channels, samplers })
    }

    /// The glTF name, or `animation<i>` for an unnamed one.
    pub fn name(&self) -> &str {
        &self.name
    }
    pub fn channels(&self) -> &[AnimationChannel] {
        &self.channels
    }
    pub fn samplers(&self) -> &[AnimationSampler] {
        &self.samplers
    }
    /// The time of the last key of any of its samplers, in seconds (0 without samplers):
    /// from then on the animation holds its last pose.
    pub fn duration(&self) -> f32 {
        self.samplers.iter().map(AnimationSampler::end).fold(0.0, f32::max)
    }
}

/// A node's local transform as the file gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NodeTransform {
    /// A `matrix` (such a node cannot be animated: glTF requires TRS for animated nodes).
    Matrix(Mat4),
    /// `translation`, `rotation`, `scale`: local = T * R * S.
    Trs { translation: Vec3, rotation: Quat, scale: Vec3 },
}

/// A node of the hierarchy, as loaded.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneNode {
    /// Its index in its glTF file; `None` for a manifest model's placement (a `matrix` node
    /// above the file's roots, [`super::merge`]).
    pub gltf_index: Option<usize>,
    /// `node <i> '<name>'`, for messages.
    pub label: String,
    /// Index of its parent in [`SceneAnimation::nodes`] (always before it); `None` for a root.
    pub parent: Option<usize>,
    pub transform: NodeTransform,
    /// The local matrix the loader placed the node with (`transform` as a matrix, computed
    /// by the glTF reader): unanimated nodes keep it, so their world transforms are the
    /// loaded ones bit for bit.
    pub rest: Mat4,
    /// Ids of the objects it places ([`super::Object::id`]).
    pub objects: Vec<u32>,
    /// Whether it places the scene's camera.
    pub camera: bool,
    /// The index in [`Scene::lights`] of the light it places.
    pub light: Option<usize>,
}

/// The node hierarchy and the animations of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneAnimation {
    nodes: Vec<SceneNode>,
    animations: Vec<Animation>,
}

impl SceneAnimation {
    /// The hierarchy (every parent before its children) and its animations; the message
    /// says which index is out of range or which animated node has a matrix.
    pub fn new(nodes: Vec<SceneNode>, animations: Vec<Animation>) -> Result<Self, String> {
        for (i, node) in nodes.iter().enumerate() {
            if node.parent.is_some_and(|p| p >= i) {
                return Err(format!("{}: its parent is not before it", node.label));
            }
        }
        for animation in &animations {
            for channel in &animation.channels {
                let node = nodes
                    .get(channel.node)
                    .ok_or_else(|| format!("animation '{}': node {} does not exist", animation.name, channel.node))?;
                if matches!(node.transform, NodeTransform::Matrix(_)) {
                    return Err(format!(
                        "animation '{}' drives {}, which has a matrix: glTF allows only TRS on animated nodes",
                        animation.name, node.label
                    ));
                }
            }
        }
        Ok(SceneAnimation { nodes, animations })
    }

    pub fn nodes(&self) -> &[SceneNode] {
        &self.nodes
    }

    pub fn animations(&self) -> &[Animation] {
        &self.animations
    }

    /// The objects animation `animation` moves (sorted ids): those placed by a node one of
    /// its channels drives or by a descendant of one. Empty for an unknown animation. A
    /// renderer prepares them as moving (`Renderer::prepare_moving`) and moves them after
    /// each [`Scene::set_time`] instead of preparing the scene again.
    pub fn moved_objects(&self, animation: usize) -> Vec<u32> {
        let moved = self.moved_nodes(animation);
        let mut objects: Vec<u32> =
            self.nodes.iter().zip(&moved).filter(|(_, m)| **m).flat_map(|(n, _)| n.objects.iter().copied()).collect();
        objects.sort_unstable();
        objects.dedup();
        objects
    }

    /// Whether animation `animation` moves a light (a node it drives, or a descendant of
    /// one, places a light).
    pub fn moves_lights(&self, animation: usize) -> bool {
        self.nodes.iter().zip(self.moved_nodes(animation)).any(|(n, m)| m && n.light.is_some())
    }

    /// Per node: whether animation `animation` drives it or one of its ancestors (none for
    /// an unknown animation).
    fn moved_nodes(&self, animation: usize) -> Vec<bool> {
        let mut moved = vec![false; self.nodes.len()];
        for c in self.animations.get(animation).map_or(&[][..], |a| &a.channels[..]) {
            moved[c.node] = true;
        }
        // Parents come before their children: one pass carries a move down the hierarchy.
        for i in 0..self.nodes.len() {
            if let Some(p) = self.nodes[i].parent {
                moved[i] |= moved[p];
            }
        }
        moved
    }

    /// The index of the first animation named `name`.
    pub fn find(&self, name: &str) -> Option<usize> {
        self.animations.iter().position(|a| a.name == name)
    }

    /// Every node's world transform, in [`Self::nodes`] order: at time `t` of animation
    /// `animation` for `Some((animation, t))`, the loaded pose for `None`. An animation index
    /// out of range is the loaded pose too ([`Scene::set_time`] checks it).
    pub fn world_transforms(&self, pose: Option<(usize, f32)>) -> Vec<Mat4> {
        // The sampled TRS of the nodes the animation drives (the others: `None`).
        let mut driven: Vec<Option<(Vec3, Quat, Vec3)>> = vec![None; self.nodes.len()];
        if let Some(animation) = pose.and_then(|(a, _)| self.animations.get(a)) {
            let t = pose.map_or(0.0, |(_, t)| t);
            for channel in &animation.channels {
                let NodeTransform::Trs { translation, rotation, scale } = self.nodes[channel.node].transform else {
                    continue; // `new` refuses animated matrix nodes.
                };
                let trs = driven[channel.node].get_or_insert((translation, rotation, scale));
                let sampler = &animation.samplers[channel.sampler];
                match (&sampler.values, channel.property) {
                    (Keyframes::Vectors(v), AnimatedProperty::Translation) => {
                        trs.0 = sample_vec3(sampler.interpolation, &sampler.times, v, t)
                    }
                    (Keyframes::Vectors(v), AnimatedProperty::Scale) => {
                        trs.2 = sample_vec3(sampler.interpolation, &sampler.times, v, t)
                    }
                    (Keyframes::Rotations(q), AnimatedProperty::Rotation) => {
                        trs.1 = sample_rotation(sampler.interpolation, &sampler.times, q, t)
                    }
                    _ => {} // `Animation::new` refuses mismatched kinds.
                }
            }
        }
        let mut world: Vec<Mat4> = Vec::with_capacity(self.nodes.len());
        for (node, driven) in self.nodes.iter().zip(driven) {
            let local = match driven {
                Some((translation, rotation, scale)) => {
                    Mat4::from_scale_rotation_translation(scale, rotation, translation)
                }
                None => node.rest,
            };
            // The loader's product, `parent * local` with the identity above a root.
            let parent = node.parent.map_or(Mat4::IDENTITY, |p| world[p]);
            world.push(parent * local);
        }
        world
    }
}

/// A camera's eye, forward and up directions from its node's world transform (the loader's
/// convention: eye = world translation, forward = world -Z, up = world +Y, both normalized),
/// or `None` when they are degenerate: a non-finite eye, a zero forward or up, or forward
/// parallel to up.
pub(crate) fn camera_frame(world: Mat4) -> Option<(Vec3, Vec3, Vec3)> {
    let eye = world.transform_point3(Vec3::ZERO);
    let forward = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
    let up = world.transform_vector3(Vec3::Y).normalize_or_zero();
    let usable =
        eye.is_finite() && forward != Vec3::ZERO && up != Vec3::ZERO && forward.cross(up).length_squared() > 0.0;
    usable.then_some((eye, forward, up))
}

/// A point light's position from its node's world transform: the world translation.
pub(crate) fn light_position(world: Mat4) -> Vec3 {
    world.transform_point3(Vec3::ZERO)
}

/// A directional light's direction of travel from its node's world transform: world -Z,
/// normalized; `None` when it is zero or not finite.
pub(crate) fn light_direction(world: Mat4) -> Option<Vec3> {
    let direction = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
    (direction != Vec3::ZERO && direction.is_finite()).then_some(direction)
}

impl Scene {
    /// Pose the scene at time `t` (seconds, clamped to the animation's keys) of animation
    /// `animation` (an index into [`SceneAnimation::animations`]): objects, the camera and
    /// lights placed by nodes move as the module docs say. A camera or directional light
    /// the pose leaves degenerate (a zero scale, say) is an error and nothing changes.
    pub fn set_time(&mut self, animation: usize, t: f32) -> Result<(), AnimationError> {
        let nodes = self.animation.as_ref().ok_or(AnimationError::NotAnimated)?;
        let count = nodes.animations.len();
        let name = nodes
            .animations
            .get(animation)
            .map(|a| a.name.clone())
            .ok_or(AnimationError::NoSuchAnimation { index: animation, count })?;
        self.pose(Some((animation, t))).map_err(|(node, what)| AnimationError::Degenerate {
            animation: name,
            time: t,
            node,
            what,
        })
    }

    /// Put every node back where the loader placed it: objects, camera and lights get their
    /// loaded values bit for bit. Does nothing to a scene without animations.
    pub fn reset_pose(&mut self) {
        // The loaded pose is the one the loader checked: nothing in it is degenerate.
        let _ = self.pose(None);
    }

    /// Apply [`SceneAnimation::world_transforms`] to what the nodes place; on a degenerate
    /// camera or light, change nothing and say which node and what.
    pub(crate) fn pose(&mut self, pose: Option<(usize, f32)>) -> Result<(), (String, &'static str)> {
        let Some(animation) = self.animation.as_ref() else {
            return Ok(());
        };
        let world = animation.world_transforms(pose);
        let mut camera = self.camera;
        let mut lights = self.lights.clone();
        for (node, &world) in animation.nodes.iter().zip(&world) {
            if node.camera {
                let (eye, forward, up) = camera_frame(world).ok_or_else(|| (node.label.clone(), "camera"))?;
                if let Some(c) = camera.as_mut() {
                    (c.eye, c.target, c.up) = (eye, eye + forward, up);
                }
            }
            match node.light.and_then(|l| lights.get_mut(l)) {
                Some(Light::Point { position, .. }) => *position = light_position(world),
                Some(Light::Spot { position, direction, .. }) => {
                    *direction = light_direction(world).ok_or_else(|| (node.label.clone(), "spot light"))?;
                    *position = light_position(world);
                }
                Some(Light::Directional { direction, .. }) => {
                    *direction = light_direction(world).ok_or_else(|| (node.label.clone(), "directional light"))?
                }
                // glTF nodes carry KHR_lights_punctual lights only; area lights come from
                // manifests, which do not animate them.
                Some(Light::Quad { .. } | Light::Sphere { .. } | Light::Sun { .. }) | None => {}
            }
        }
        for (node, &world) in animation.nodes.iter().zip(&world) {
            for &id in &node.objects {
                if let Some(object) = self.objects.get_mut(id as usize) {
                    object.transform = world;
                }
            }
        }
        self.camera = camera;
        self.lights = lights;
        Ok(())
    }
}
