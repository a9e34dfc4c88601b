//! What a backend renders from: the scene prepared once ([`PreparedScene`]: the world
//! tables and the BVH, or its two levels), and the in-place changes it logs for device
//! caches ([`SceneChanges`]). Re-exported by [`crate::frame`].

use std::borrow::Cow;

use glam::Vec3;

use crate::bvh::two_level::{MoveError, TwoLevelBvh};
use crate::bvh::Bvh;
use crate::formats::{EmitterRecord, LightRecord, ObjectMap, INVALID_ID, MAP_IDENTITY};
use crate::geometry::WorldGeometry;
use crate::kernels::shading::AmbientLight;
use crate::kernels::soft_shadow::{frame_lights, frame_occlusion, is_stochastic, surface_slots, Lights};
use crate::options::{FrameOptions, DEFAULT_AO_RADIUS_FRACTION};
use crate::scene::Scene;

/// The lights and ambient light of one frame ([`PreparedScene::frame_lighting`]).
#[derive(Clone, Debug)]
pub struct FrameLighting<'a> {
    pub lights: Cow<'a, [LightRecord]>,
    /// The emitter table the lights' [`crate::formats::LIGHT_EMITTERS`] record samples
    /// (the scene's, [`WorldGeometry::emitters`]; empty without one).
    pub emitters: &'a [EmitterRecord],
    pub ambient: Cow<'a, AmbientLight>,
}

impl FrameLighting<'_> {
    /// The lights with their emitter table, as the kernels that sample them take them.
    pub fn lights(&self) -> Lights<'_> {
        Lights::new(&self.lights, self.emitters)
    }

    /// Whether the frame has emissive meshes as lights (an emitter table).
    pub fn has_emitters(&self) -> bool {
        !self.emitters.is_empty()
    }

    /// Whether the frame traces stochastic rays (an area light, or ambient occlusion).
    pub fn is_stochastic(&self) -> bool {
        is_stochastic(&self.lights, &self.ambient.occlusion)
    }

    /// The slots of a surface's shadow mask ([`crate::kernels::soft_shadow::surface_slots`]).
    pub fn slots(&self) -> usize {
        surface_slots(&self.lights, &self.ambient.occlusion)
    }
}

/// A scene ready to render: world-space tables and the BVH over all of them,
/// built once and shared by every frame and by both backends.
///
/// A scene prepared with moving objects ([`PreparedScene::with_levels`]) also holds a
/// two-level BVH ([`TwoLevelBvh`]): its objects in object space move between frames
/// ([`PreparedScene::move_objects`]) without preparing the scene again. Then `bvh` is the
/// world-space level alone (the objects baked into world space), which a backend may
/// trace with its fastest traversal before the object-space instances.
#[derive(Clone, Debug)]
pub struct PreparedScene {
    pub geometry: WorldGeometry,
    /// The BVH over every traceable triangle, or over those baked into world space when
    /// `levels` is set.
    pub bvh: Bvh,
    /// The two levels when some object is traced in its own space (moving objects, meshes
    /// shared by several objects); `None` when `bvh` is the whole scene.
    pub levels: Option<TwoLevelBvh>,
    /// Time the `bvh_build` stage took, in milliseconds.
    pub bvh_build_ms: f64,
    /// Unique per prepared scene (clones share it: same content): backends that keep the scene's
    /// tables on a device key their caches by it. Fields are public for reading;
    /// build with [`PreparedScene::new`] so the id stays unique.
    id: u64,
    /// Bumped by every change made in place ([`PreparedScene::move_objects`],
    /// [`PreparedScene::update_lights`]); 0 as prepared.
    revision: u64,
    /// What each of the last [`CHANGE_LOG_LENGTH`] revisions changed, oldest first.
    changes: std::collections::VecDeque<(u64, SceneChanges)>,
}

/// Revisions whose changes a [`PreparedScene`] remembers: a device cache further behind
/// takes the whole scene again.
pub const CHANGE_LOG_LENGTH: usize = 64;

/// What changed in a prepared scene between two revisions ([`PreparedScene::changes_since`]):
/// what a backend holding the older revision on a device must write again.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SceneChanges {
    /// Objects whose triangles, normals, record (and instance) were rewritten, sorted.
    pub objects: Vec<u32>,
    /// The light table.
    pub lights: bool,
    /// Bottom levels refitted to a deformed mesh ([`PreparedScene::deform_mesh`]): their
    /// nodes and leaf triangles, at the same places, sorted.
    pub bottoms: Vec<u32>,
}

impl SceneChanges {
    fn merge(&mut self, other: &SceneChanges) {
        self.objects.extend_from_slice(&other.objects);
        self.objects.sort_unstable();
        self.objects.dedup();
        self.lights |= other.lights;
        self.bottoms.extend_from_slice(&other.bottoms);
        self.bottoms.sort_unstable();
        self.bottoms.dedup();
    }
}

/// Copy the levels' offset errors (one per object, [`TwoLevelBvh::offset_errors`]) into the
/// object records the stages read; objects that did not move keep the values they had.
fn take_offset_errors(geometry: &mut WorldGeometry, levels: &TwoLevelBvh) {
    for (o, e) in geometry.objects.iter_mut().zip(&levels.offset_errors) {
        o.offset_error = *e;
    }
}

/// A fresh [`PreparedScene`] id.
fn next_id() -> u64 {
    static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
    NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
}

impl PreparedScene {
    /// A prepared scene with a fresh id.
    pub fn new(geometry: WorldGeometry, bvh: Bvh, bvh_build_ms: f64) -> Self {
        PreparedScene {
            geometry,
            bvh,
            levels: None,
            bvh_build_ms,
            id: next_id(),
            revision: 0,
            changes: Default::default(),
        }
    }

    /// A prepared scene traced through two levels: `bvh` becomes a copy of the
    /// world-space level (empty when every object is an instance); without object-space
    /// instances it is [`PreparedScene::new`] with that level.
    pub fn with_levels(mut geometry: WorldGeometry, levels: TwoLevelBvh, bvh_build_ms: f64) -> Self {
        let bvh = levels.world_level().cloned().unwrap_or_default();
        take_offset_errors(&mut geometry, &levels);
        let levels = levels.has_object_space_instances().then_some(levels);
        PreparedScene { geometry, bvh, levels, bvh_build_ms, id: next_id(), revision: 0, changes: Default::default() }
    }

    /// The id device caches are keyed by. Mutating the public fields after a
    /// backend has seen the scene is not supported: prepare a new scene instead, or change
    /// it with [`PreparedScene::move_objects`] and [`PreparedScene::update_lights`], which
    /// keep the id and bump the [`PreparedScene::revision`].
    pub fn id(&self) -> u64 {
        self.id
    }

    /// The diagonal of the scene's bounds (every traceable triangle's, the moving
    /// objects' where they are now): the scale of derived lengths such as the default
    /// ambient-occlusion radius. 0 for a scene with nothing to trace.
    pub fn extent(&self) -> f32 {
        let roots = self.bvh.nodes.first().into_iter().chain(self.levels.iter().flat_map(|l| l.top.first()));
        let (lo, hi) = roots.fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), n| {
            (lo.min(Vec3::from(n.aabb_min)), hi.max(Vec3::from(n.aabb_max)))
        });
        if lo.cmple(hi).all() {
            (hi - lo).length()
        } else {
            0.0
        }
    }

    /// The lights and ambient light a frame under `options` shades with: the scene's,
    /// with its area lights given `options.shadow_samples` rays and their streams seeded
    /// for `options.frame_index`, and the ambient occlusion `options` asks for
    /// ([`crate::kernels::soft_shadow`]). Borrowed where the frame traces nothing
    /// stochastic (the scene's own tables, bit for bit).
    pub fn frame_lighting(&self, options: &FrameOptions) -> FrameLighting<'_> {
        let g = &self.geometry;
        let lights = match g.lights.iter().any(LightRecord::is_area) {
            true => Cow::Owned(frame_lights(&g.lights, options.shadow_samples, options.frame_index)),
            false => Cow::Borrowed(&g.lights[..]),
        };
        let ambient = match options.ao_samples {
            0 => Cow::Borrowed(&g.ambient),
            samples => {
                let radius = options.ao_radius.unwrap_or(DEFAULT_AO_RADIUS_FRACTION * self.extent());
                let occlusion = frame_occlusion(samples, radius, options.frame_index);
                Cow::Owned(AmbientLight { occlusion, ..g.ambient.clone() })
            }
        };
        FrameLighting { lights, emitters: &g.emitters, ambient }
    }

    /// Per object, its world-to-object map now: its instance's for an object traced in
    /// its own space (one that can move: [`PreparedScene::move_objects`]), else
    /// [`MAP_IDENTITY`] (baked into world space, it never moves). What the denoiser's
    /// temporal pass compares from frame to frame ([`crate::kernels::temporal::motion_records`]).
    pub fn object_maps(&self) -> Vec<ObjectMap> {
        let count = self.geometry.objects.len();
        let Some(levels) = &self.levels else {
            return vec![MAP_IDENTITY; count];
        };
        (0..count)
            .map(|o| match levels.object_instance.get(o) {
                Some(&i) if i != INVALID_ID && levels.in_object_space[o] => {
                    levels.instances[i as usize].world_to_object()
                }
                _ => MAP_IDENTITY,
            })
            .collect()
    }

    /// How many in-place changes the scene has had (0 as prepared).
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// What changed after revision `since` (everything up to the current revision, merged),
    /// for a backend that holds revision `since` on a device and writes only that again;
    /// `None` when the log no longer reaches back that far (take the whole scene).
    pub fn changes_since(&self, since: u64) -> Option<SceneChanges> {
        if since > self.revision {
            return None;
        }
        let mut all = SceneChanges::default();
        let mut next = since + 1;
        for (revision, c) in self.changes.iter().filter(|(r, _)| *r > since) {
            if *revision != next {
                return None;
            }
            all.merge(c);
            next += 1;
        }
        (next == self.revision + 1).then_some(all)
    }

    /// Record one in-place change as a new revision.
    fn record(&mut self, change: SceneChanges) {
        self.revision += 1;
        self.changes.push_back((self.revision, change));
        if self.changes.len() > CHANGE_LOG_LENGTH {
            self.changes.pop_front();
        }
    }

    /// Take the scene's lights again after they changed (an animation moved one, or
    /// changed its colour): the light table is rewritten, a new revision (a new id when
    /// the number of lights changed).
    pub fn update_lights(&mut self, scene: &Scene) {
        let count = self.geometry.lights.len();
        self.geometry.lights = crate::geometry::light_records(scene, &self.geometry.emitters);
        if self.geometry.lights.len() == count {
            self.record(SceneChanges { lights: true, ..SceneChanges::default() });
        } else {
            // Another number of lights: a new scene for every device cache.
            self.id = next_id();
        }
    }

    /// Move objects between frames: after the transforms (or render modes) of `objects`
    /// changed in `scene` (the scene this was prepared from), rewrite their world tables
    /// and their instances and rebuild the top level; bottom levels are untouched. The
    /// result equals preparing the changed scene again with the same moving objects.
    ///
    /// Fails, changing nothing, when an object was not prepared as moving (it is baked
    /// into world space; a scene prepared without levels has every object baked), does not
    /// exist, or its transform cannot be traced in object space ([`MoveError`]). A move is
    /// a new [`PreparedScene::revision`]; the id stays, so a device holding the scene
    /// writes only what moved ([`PreparedScene::changes_since`]).
    pub fn move_objects(&mut self, scene: &Scene, objects: &[u32]) -> Result<(), MoveError> {
        let Some(levels) = &mut self.levels else {
            return Err(match objects.first() {
                Some(&object) if (object as usize) < scene.objects.len() => MoveError::Baked { object },
                Some(&object) => MoveError::NoObject { object, objects: scene.objects.len() },
                None => return Ok(()),
            });
        };
        let moves = levels.moves(scene, objects)?;
        let lights = self.geometry.lights.len();
        self.geometry.update_objects(scene, objects);
        levels.apply_moves(scene, &self.geometry, moves);
        take_offset_errors(&mut self.geometry, levels);
        let mut moved = objects.to_vec();
        moved.sort_unstable();
        moved.dedup();
        // Emitters that moved move the emitter table; one that emptied it (or filled it)
        // changed the number of lights: a new scene for every device cache.
        let emitters = !self.geometry.emitters.is_empty();
        if self.geometry.lights.len() != lights {
            self.id = next_id();
        } else {
            self.record(SceneChanges { objects: moved, lights: emitters, ..SceneChanges::default() });
        }
        Ok(())
    }

    /// A deforming mesh: after `scene.meshes[mesh]` got new vertex positions (or normals;
    /// the same triangles), rewrite the world tables of every object drawing it and refit
    /// its bottom level ([`TwoLevelBvh::deform_mesh`]); a new revision. Every object drawing
    /// the mesh must have been prepared as moving (else [`MoveError::Baked`], changing
    /// nothing). When triangles became degenerate or stopped being so, the levels are built
    /// again and the scene gets a new id.
    pub fn deform_mesh(&mut self, scene: &Scene, mesh: usize) -> Result<(), MoveError> {
        let users: Vec<u32> = scene.objects.iter().filter(|o| o.mesh == mesh).map(|o| o.id).collect();
        let moving = |o: u32| self.levels.as_ref().is_some_and(|l| l.in_object_space[o as usize]);
        if let Some(&object) = users.iter().find(|&&o| !moving(o)) {
            return Err(MoveError::Baked { object });
        }
        let Some(levels) = &mut self.levels else {
            return Ok(());
        };
        let lights = self.geometry.lights.len();
        self.geometry.deform_mesh(scene, mesh);
        let rebuilt = levels.deform_mesh(scene, &self.geometry, mesh)?;
        let rebuilt = rebuilt || self.geometry.lights.len() != lights;
        take_offset_errors(&mut self.geometry, levels);
        if rebuilt {
            self.bvh = levels.world_level().cloned().unwrap_or_default();
            self.id = next_id();
        } else {
            let bottoms =
                levels.mesh_bottom.get(mesh).filter(|&&b| b != INVALID_ID).map(|&b| vec![b]).unwrap_or_default();
            // Emitters move with the deformed triangles, as with a move (`move_objects`).
            let lights = !self.geometry.emitters.is_empty();
            self.record(SceneChanges { objects: users, lights, bottoms });
        }
        Ok(())
    }
}
