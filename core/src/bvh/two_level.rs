//! The two-level BVH: bottom levels of triangles, a top level of instances.
//!
//! * **Bottom levels** are ordinary [`Bvh`]s. Each mesh that some object instances gets one,
//!   built once over the mesh's triangles in its own (object) space and shared by every
//!   object drawing that mesh; the objects that neither move nor share their mesh are baked
//!   into one more bottom level over their world-space triangles (today's single-level
//!   tree, restricted to them), which needs no transform at trace time.
//! * **Instances** ([`InstanceRecord`]): a bottom level, the world-to-object map of the
//!   object drawing it ([`crate::kernels::instance::world_to_object`]), the global index of
//!   the object's first triangle (a bottom level's slots hold mesh-local indices, so the
//!   global triangle is `first_triangle + prim_indices[slot]`) and flags. The world-space
//!   level is one instance flagged [`INSTANCE_IDENTITY`] (first triangle 0: its slots hold
//!   global indices already).
//! * **The top level** is a tree of [`BvhNode`]s over the instances' world boxes
//!   ([`crate::kernels::instance::instance_world_box`]), one instance per leaf: a leaf's
//!   `left_or_first` is the instance's index (the instances are stored in the order the
//!   tree's leaves are reached).
//!
//! Rays move into object space ([`crate::kernels::instance::to_object_space`]) when they
//! reach an instance leaf, unless the instance is the world-space level; the bottom level
//! is then walked by the same loop ([`super::traversal::traverse`]) and the same leaf tests
//! as a single-level tree, the far bound carried across levels (an affine map keeps the
//! ray parameter). Closest hits compare `(t, global triangle)` across instances exactly as
//! within one tree, so ties between instances go to the lower global index too. The
//! facing of a hit in a mirrored instance (negative determinant) is flipped back to world
//! space.
//!
//! Which objects become instances is the caller's choice (`moving`): an object that moves
//! between frames must be one, so that a move rewrites one instance and the top level, not
//! a bottom level. Objects sharing a mesh always are (the mesh is built once). A scene
//! with neither has one instance, and its answers are those of the single-level [`Bvh`]
//! bit for bit (the same tree, the same tests).

use std::time::Duration;

use bytemuck::Zeroable;
use glam::{Mat3, Vec3, Vec3A};

use obvhs::{aabb::Aabb, bvh2::builder::build_bvh2};

use super::traversal::{inline_leaf_test, traverse, Leaf, LeafFlow};
use super::{flatten, obvhs_nodes, Bvh, BvhPreset, ClosestHit, TraversalRay, BVH_STACK_SIZE};
use crate::formats::{BvhNode, ObjectMap, RayRecord, TriangleRecord, INVALID_ID, TRI_ALPHA_TEST};
use crate::geometry::WorldGeometry;
use crate::kernels::instance::{
    instance_box_margin, instance_position_error, instance_world_box, to_object_space, world_to_object,
};
use crate::scene::Scene;

/// The instance record and its flags, defined with the other GPU records in
/// [`crate::formats`]; re-exported here, where the levels are built.
pub use crate::formats::{InstanceRecord, INSTANCE_ALPHA_TEST, INSTANCE_IDENTITY, INSTANCE_MIRRORED};

/// Why objects could not move ([`TwoLevelBvh::update_objects`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MoveError {
    /// The object is baked into the world-space level with the static geometry.
    #[error(
        "object {object} was prepared as static (baked into world space): prepare the scene with it moving to move it"
    )]
    Baked { object: u32 },
    /// The object's new transform is not finite, not affine, singular or too badly
    /// conditioned to trace in object space.
    #[error("object {object}'s transform cannot be traced in object space (not finite, not affine, singular or too badly conditioned)")]
    BadTransform { object: u32 },
    /// No such object.
    #[error("object {object} does not exist (the scene has {objects})")]
    NoObject { object: u32, objects: usize },
}

/// A two-level BVH; see the module docs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TwoLevelBvh {
    /// The top level over the instances' world boxes, root first; leaves hold one
    /// instance each (`left_or_first` is its index, `count` 1). Empty when no instance
    /// has a traceable triangle.
    pub top: Vec<BvhNode>,
    /// The instances, in the order the top level's leaves are reached.
    pub instances: Vec<InstanceRecord>,
    /// The bottom levels.
    pub bottoms: Vec<Bvh>,
    /// Per object: the index of its instance, or [`INVALID_ID`] when it is baked into the
    /// world-space level (or has no traceable triangle).
    pub object_instance: Vec<u32>,
    /// Per object: traced in its own space (it moves or shares its mesh), not baked.
    pub in_object_space: Vec<bool>,
    /// Per mesh: the index of its object-space bottom level, or [`INVALID_ID`] when no
    /// object traced in its own space draws it.
    pub mesh_bottom: Vec<u32>,
    /// Per object: the extra error bound of points on it whose rays are traced in its
    /// space ([`instance_position_error`]); 0 for objects baked into world space. Goes to
    /// [`crate::formats::ObjectRecord::offset_error`] (`PreparedScene` copies it there).
    pub offset_errors: Vec<f32>,
    /// The preset every level was built with.
    pub build_preset: BvhPreset,
}

/// Per object: its world-to-object map when [`TwoLevelBvh::build`] makes it an instance
/// (flagged in `moving`, or sharing its mesh, and well conditioned).
fn instance_maps(scene: &Scene, moving: &[bool]) -> Vec<Option<ObjectMap>> {
    let mut users = vec![0u32; scene.meshes.len()];
    for o in &scene.objects {
        users[o.mesh] += 1;
    }
    scene
        .objects
        .iter()
        .map(|o| {
            let wanted = moving.get(o.id as usize).copied().unwrap_or(false) || users[o.mesh] > 1;
            wanted.then(|| world_to_object(o.transform)).flatten()
        })
        .collect()
}

impl TwoLevelBvh {
    /// Per object (by id): whether [`TwoLevelBvh::build`] with these `moving` flags traces
    /// it in its own space. Exactly these objects may be kept by reference in the world
    /// tables ([`WorldGeometry::build_placed`]): the world-space level holds the others.
    pub fn object_space_objects(scene: &Scene, moving: &[bool]) -> Vec<bool> {
        instance_maps(scene, moving).iter().map(Option::is_some).collect()
    }

    /// Build the levels of `scene` (whose world tables are `geometry`). Objects flagged in
    /// `moving` (indexed by object id; shorter means false) and objects sharing a mesh
    /// with another become instances of their mesh's bottom level; the others are baked
    /// into the world-space level. An object whose transform has no well-conditioned
    /// inverse ([`world_to_object`]) is baked whatever it is flagged. Validated in debug
    /// builds.
    pub fn build(scene: &Scene, geometry: &WorldGeometry, preset: BvhPreset, moving: &[bool]) -> TwoLevelBvh {
        // Per object: its world-to-object map when it is an instance.
        let maps = instance_maps(scene, moving);
        let mut levels = TwoLevelBvh { build_preset: preset, ..TwoLevelBvh::default() };
        // (instance, its world box) in object order, the world-space level first.
        let mut instances: Vec<(InstanceRecord, (Vec3, Vec3))> = Vec::new();
        if maps.iter().any(Option::is_none) {
            let baked = |o: u32| maps[o as usize].is_none();
            let world = Bvh::build_stored(&geometry.triangles, &geometry.objects, preset, &baked);
            if let Some(root) = world.nodes.first() {
                instances.push((InstanceRecord::identity(0), (root.min(), root.max())));
                levels.bottoms.push(world);
            }
        }
        let mut mesh_bottom = vec![INVALID_ID; scene.meshes.len()];
        for (o, map) in scene.objects.iter().zip(&maps) {
            let Some(map) = map else { continue };
            if mesh_bottom[o.mesh] == INVALID_ID {
                mesh_bottom[o.mesh] = levels.bottoms.len() as u32;
                levels.bottoms.push(Bvh::build_triangles(&object_triangles(scene, o.mesh, o.id), preset));
            }
            let bottom = mesh_bottom[o.mesh];
            if levels.bottoms[bottom as usize].nodes.is_empty() {
                continue;
            }
            let [map_x, map_y, map_z] = *map;
            let instance = InstanceRecord {
                map_x,
                map_y,
                map_z,
                bottom,
                object: o.id,
                first_triangle: geometry.objects[o.id as usize].first_triangle,
                flags: 0,
            };
            instances.push((instance, (Vec3::ZERO, Vec3::ZERO)));
        }
        levels.in_object_space = maps.iter().map(Option::is_some).collect();
        levels.mesh_bottom = mesh_bottom;
        levels.place(scene, geometry, &mut instances);
        levels.build_top(scene.objects.len(), instances);
        if cfg!(debug_assertions) {
            levels.validate(geometry).expect("two-level BVH invariants");
        }
        levels
    }

    /// Fill in the flags and world boxes of object-space instances from their objects'
    /// current transforms (`world_to_object` already set): the mirror flag, the alpha
    /// flag, and the mapped bottom-level box widened by the margin for the scene's
    /// current bounds ([`instance_box_margin`]). The world-space level keeps its box.
    fn place(&mut self, scene: &Scene, geometry: &WorldGeometry, instances: &mut [(InstanceRecord, (Vec3, Vec3))]) {
        self.offset_errors.resize(scene.objects.len(), 0.0);
        let (lo, hi) = geometry.bounds;
        let scene_magnitude = lo.abs().max(hi.abs()).max_element();
        for (instance, world_box) in instances.iter_mut() {
            let root = &self.bottoms[instance.bottom as usize].nodes[0];
            if instance.flags & INSTANCE_IDENTITY != 0 {
                *world_box = (root.min(), root.max());
                continue;
            }
            let o = &scene.objects[instance.object as usize];
            let record = &geometry.objects[instance.object as usize];
            let alpha = if record.triangle_count > 0 {
                geometry.triangle(record.first_triangle as usize).flags & TRI_ALPHA_TEST
            } else {
                0
            };
            let mirrored = Mat3::from_mat4(o.transform).determinant() < 0.0;
            instance.flags = alpha | if mirrored { INSTANCE_MIRRORED } else { 0 };
            let map = instance.world_to_object();
            self.offset_errors[instance.object as usize] =
                instance_position_error(o.transform, &map, root.min(), root.max());
            let margin = instance_box_margin(&map, o.transform, scene_magnitude);
            *world_box = instance_world_box(o.transform, root.min(), root.max(), margin);
        }
    }

    /// Move objects: after the transforms of `objects` changed in `scene` (and `geometry`
    /// was updated to match, [`WorldGeometry::update_object`]), give their instances the
    /// new maps and rebuild the top level. Bottom levels are untouched; the result equals
    /// [`TwoLevelBvh::build`] of the changed scene with the same `moving` flags. Every
    /// instance's box is recomputed (the margins follow the scene's bounds), which costs
    /// a few hundred operations per instance, and the top level is rebuilt over them.
    ///
    /// Fails, changing nothing, when an object is baked into the world-space level (build
    /// it as moving to move it) or its new transform cannot be inverted well
    /// ([`world_to_object`]).
    pub fn update_objects(
        &mut self,
        scene: &Scene,
        geometry: &WorldGeometry,
        objects: &[u32],
    ) -> Result<(), MoveError> {
        let moves = self.moves(scene, objects)?;
        self.apply_moves(scene, geometry, moves);
        Ok(())
    }

    /// The checks of [`TwoLevelBvh::update_objects`], changing nothing: each object's
    /// instance slot and new map, for [`TwoLevelBvh::apply_moves`].
    pub fn moves(&self, scene: &Scene, objects: &[u32]) -> Result<Vec<(u32, ObjectMap)>, MoveError> {
        let mut maps = Vec::with_capacity(objects.len());
        for &object in objects {
            let objects = self.in_object_space.len();
            if !*self.in_object_space.get(object as usize).ok_or(MoveError::NoObject { object, objects })? {
                return Err(MoveError::Baked { object });
            }
            let map =
                world_to_object(scene.objects[object as usize].transform).ok_or(MoveError::BadTransform { object })?;
            maps.push((self.object_instance[object as usize], map));
        }
        Ok(maps)
    }

    /// The changes of [`TwoLevelBvh::update_objects`] once [`TwoLevelBvh::moves`] has
    /// checked them (and `geometry` is updated).
    pub fn apply_moves(&mut self, scene: &Scene, geometry: &WorldGeometry, moves: Vec<(u32, ObjectMap)>) {
        for (slot, map) in moves {
            // An object without a traceable triangle has no instance.
            if let Some(instance) = self.instances.get_mut(slot as usize) {
                instance.set_world_to_object(map);
            }
        }
        self.place_all(scene, geometry);
    }

    /// A deforming mesh: after `scene.meshes[mesh]` got new vertex positions (same
    /// triangles; its objects' world tables updated, [`WorldGeometry::update_object`]),
    /// refit its bottom level ([`Bvh::refit`]; rebuilt instead when a triangle became
    /// degenerate or stopped being one), then place every instance again and rebuild the
    /// top level. Returns true when the levels were built again instead (triangles came or
    /// went; every packed offset may have changed: a device must take them whole).
    ///
    /// Fails, changing nothing, when some object drawing the mesh is baked into the
    /// world-space level ([`MoveError::Baked`]; prepare them as moving to deform the mesh).
    pub fn deform_mesh(&mut self, scene: &Scene, geometry: &WorldGeometry, mesh: usize) -> Result<bool, MoveError> {
        let users: Vec<u32> = scene.objects.iter().filter(|o| o.mesh == mesh).map(|o| o.id).collect();
        if let Some(&object) = users.iter().find(|&&o| !self.in_object_space.get(o as usize).copied().unwrap_or(false))
        {
            return Err(MoveError::Baked { object });
        }
        if users.is_empty() {
            return Ok(false);
        }
        let refitted = match self.mesh_bottom.get(mesh).filter(|&&b| b != INVALID_ID) {
            Some(&bottom) => self.bottoms[bottom as usize].refit(&object_triangles(scene, mesh, users[0])),
            // No traceable triangle at build: none has an instance yet.
            None => false,
        };
        if !refitted {
            // Triangles came or went: the levels again, with the same objects in their space.
            let moving = self.in_object_space.clone();
            *self = TwoLevelBvh::build(scene, geometry, self.build_preset, &moving);
            return Ok(true);
        }
        self.place_all(scene, geometry);
        Ok(false)
    }

    /// Place every instance again and rebuild the top level over them, in the order a
    /// fresh build hands them over (the world-space level, then objects).
    fn place_all(&mut self, scene: &Scene, geometry: &WorldGeometry) {
        let mut instances: Vec<(InstanceRecord, (Vec3, Vec3))> =
            self.instances.iter().map(|&i| (i, (Vec3::ZERO, Vec3::ZERO))).collect();
        instances.sort_by_key(|(i, _)| if i.flags & INSTANCE_IDENTITY != 0 { 0 } else { i.object as u64 + 1 });
        self.place(scene, geometry, &mut instances);
        self.build_top(scene.objects.len(), instances);
        if cfg!(debug_assertions) {
            self.validate(geometry).expect("two-level BVH invariants");
        }
    }

    /// Build the top level over `instances` (with their world boxes) and store the
    /// instances in the order its leaves are reached.
    fn build_top(&mut self, objects: usize, instances: Vec<(InstanceRecord, (Vec3, Vec3))>) {
        self.top.clear();
        self.instances.clear();
        self.object_instance = vec![INVALID_ID; objects];
        if instances.is_empty() {
            return;
        }
        let boxes: Vec<Aabb> =
            instances.iter().map(|(_, (lo, hi))| Aabb::new(Vec3A::from(*lo), Vec3A::from(*hi))).collect();
        let mut params = self.build_preset.params();
        params.max_prims_per_leaf = 1;
        params.pre_split = false;
        let bvh2 = build_bvh2(&boxes, params, &mut Duration::default());
        let (mut top, order) = flatten(&obvhs_nodes(&bvh2), &bvh2.primitive_indices);
        let deep = depth_of(&top) > BVH_STACK_SIZE;
        let order = if deep || top.iter().any(|n| n.count > 1) {
            // Never seen from obvhs with one primitive per leaf; a balanced tree instead.
            let (t, o) = median_top(&boxes);
            top = t;
            o
        } else {
            order
        };
        for (slot, &i) in order.iter().enumerate() {
            let (instance, _) = instances[i as usize];
            if instance.object != INVALID_ID {
                self.object_instance[instance.object as usize] = slot as u32;
            }
            self.instances.push(instance);
        }
        self.top = top;
    }

    /// Check the invariants: every bottom level valid against its triangles (the world
    /// table for the world-space level, the object-space copies it holds for the others:
    /// their leaves are checked for containment); instances valid, naming existing bottom
    /// levels and objects; the top level a valid tree whose leaves hold one instance each,
    /// in order, with boxes containing their instance's mapped bottom-level box.
    pub fn validate(&self, geometry: &WorldGeometry) -> Result<(), String> {
        for (i, inst) in self.instances.iter().enumerate() {
            inst.validate().map_err(|e| format!("instance {i}: {e}"))?;
            let bottom =
                self.bottoms.get(inst.bottom as usize).ok_or_else(|| format!("instance {i}: no bottom level"))?;
            if inst.flags & INSTANCE_IDENTITY != 0 {
                // Against the stored records, by record index (the world level holds only
                // stored objects, whatever the table's other objects are).
                let records = geometry.triangles.stored_records();
                // Its wide view names global ids, as its slots do.
                bottom.wide.validate(bottom).map_err(|e| format!("world-space level's wide view: {e}"))?;
                let mut by_record = bottom.clone();
                for p in &mut by_record.prim_indices {
                    *p = geometry.triangles.record_of(*p as usize).ok_or("world-space level: object by reference")?
                        as u32;
                }
                by_record.wide = super::wide::WideBvh::collapse(&by_record);
                let baked = |r: u32| self.in_object_space.get(records[r as usize].object as usize) == Some(&false);
                by_record.validate_filtered(records, &baked).map_err(|e| format!("world-space level: {e}"))?;
            } else {
                let o = geometry.objects.get(inst.object as usize).ok_or_else(|| format!("instance {i}: no object"))?;
                let own = self.object_instance[inst.object as usize] == i as u32
                    && self.in_object_space[inst.object as usize];
                if inst.first_triangle != o.first_triangle || !own {
                    return Err(format!("instance {i} and object {} disagree", inst.object));
                }
                if let Some(&s) = bottom.prim_indices.iter().find(|&&s| s >= o.triangle_count) {
                    return Err(format!("instance {i}: slot names triangle {s} of {}", o.triangle_count));
                }
            }
        }
        for (b, bottom) in self.bottoms.iter().enumerate() {
            if bottom.max_depth as usize > BVH_STACK_SIZE || bottom.leaf_triangles.len() != bottom.prim_indices.len() {
                return Err(format!("bottom level {b} malformed"));
            }
        }
        if self.top.is_empty() {
            return if self.instances.is_empty() { Ok(()) } else { Err("instances without a top level".into()) };
        }
        let mut seen = vec![false; self.instances.len()];
        let mut todo = vec![(0usize, 0usize, 0usize)];
        while let Some((n, depth, parent)) = todo.pop() {
            let node = self.top.get(n).ok_or_else(|| format!("top node {n} out of range"))?;
            node.validate().map_err(|e| format!("top node {n}: {e}"))?;
            let p = &self.top[parent];
            if !(node.min().cmpge(p.min()).all() && node.max().cmple(p.max()).all()) || depth > BVH_STACK_SIZE {
                return Err(format!("top node {n} outside its parent or too deep"));
            }
            if node.is_leaf() {
                let i = node.left_or_first as usize;
                if node.count != 1 || i >= seen.len() || std::mem::replace(&mut seen[i], true) {
                    return Err(format!("top leaf {n} does not hold one new instance"));
                }
                let bottom = &self.bottoms[self.instances[i].bottom as usize];
                let root = &bottom.nodes[0];
                if self.instances[i].flags & INSTANCE_IDENTITY != 0
                    && (root.min() != node.min() || root.max() != node.max())
                {
                    return Err(format!("top leaf {n}: not the world-space level's box"));
                }
            } else {
                let l = node.left_or_first as usize;
                if l <= n || l + 1 >= self.top.len() {
                    return Err(format!("top node {n}: children {l} out of order"));
                }
                todo.push((l, depth + 1, n));
                todo.push((l + 1, depth + 1, n));
            }
        }
        if seen.iter().any(|s| !s) {
            return Err("an instance in no top leaf".into());
        }
        Ok(())
    }

    /// Any hit with `t_min < t < t_max` over every instance, as [`Bvh::occluded_filtered`]:
    /// `accept` gets the hit triangle's record as its level holds it (object-space
    /// vertices in an instance) with its object set to the instance's, and its global id.
    pub fn occluded_filtered(&self, ray: &RayRecord, accept: impl Fn(&TriangleRecord, u32, f32, f32) -> bool) -> bool {
        self.occluded_walk(ray, false, accept)
    }

    /// [`TwoLevelBvh::occluded_filtered`] over the object-space instances only: for a
    /// caller that traced the world-space level already, with its own traversal of that
    /// [`Bvh`] (the CPU backend's packets), and traces only the rays it found unoccluded.
    pub fn occluded_in_object_space(
        &self,
        ray: &RayRecord,
        accept: impl Fn(&TriangleRecord, u32, f32, f32) -> bool,
    ) -> bool {
        self.occluded_walk(ray, true, accept)
    }

    /// Whether some instance is traced in object space (else the world-space level is the
    /// whole scene).
    pub fn has_object_space_instances(&self) -> bool {
        self.instances.iter().any(|i| i.flags & INSTANCE_IDENTITY == 0)
    }

    /// The world-space level, when some object is baked into it.
    pub fn world_level(&self) -> Option<&Bvh> {
        let i = self.instances.iter().find(|i| i.flags & INSTANCE_IDENTITY != 0)?;
        Some(&self.bottoms[i.bottom as usize])
    }

    #[inline(always)]
    fn occluded_walk(
        &self,
        ray: &RayRecord,
        skip_world: bool,
        accept: impl Fn(&TriangleRecord, u32, f32, f32) -> bool,
    ) -> bool {
        let Some(r) = TraversalRay::new(ray) else {
            return false;
        };
        let leaf_test = inline_leaf_test(|leaf: Leaf, _: f32, _: &mut f32| {
            let inst = &self.instances[leaf.first as usize];
            let hit = if inst.flags & INSTANCE_IDENTITY != 0 {
                let bottom = &self.bottoms[inst.bottom as usize];
                !skip_world
                    && bottom.occluded_ray(&r, 0, |slot, u, v| {
                        accept(&hit_record(inst, bottom, slot), bottom.prim_indices[slot as usize], u, v)
                    })
            } else {
                self.occluded_in_instance(leaf.first as usize, ray, &accept)
            };
            if hit {
                LeafFlow::Stop
            } else {
                LeafFlow::Continue
            }
        });
        traverse(&self.top, &r, &mut r.t_max.clone(), leaf_test)
    }

    /// The any-hit test of `ray` (in world space) against object-space instance `i` alone:
    /// the ray moved into the instance's space ([`object_space_ray`]), then its bottom
    /// level walked with the instance's alpha flag, `accept` as in
    /// [`TwoLevelBvh::occluded_filtered`]. What the two-level walk does at the instance's
    /// top-level leaf; for a caller that walks the top level itself (the CPU backend's
    /// packets, for their lanes traced one at a time). False for the world-space level.
    #[inline(always)]
    pub fn occluded_in_instance(
        &self,
        i: usize,
        ray: &RayRecord,
        accept: impl Fn(&TriangleRecord, u32, f32, f32) -> bool,
    ) -> bool {
        let Some((inst, bottom, ro)) = self.object_space(i, ray) else {
            return false;
        };
        bottom.occluded_ray(&ro, inst.flags & INSTANCE_ALPHA_TEST, |slot, u, v| {
            let id = inst.first_triangle + bottom.prim_indices[slot as usize];
            accept(&hit_record(inst, bottom, slot), id, u, v)
        })
    }

    /// The closest-hit test of `ray` (in world space) against object-space instance `i`
    /// alone, from `best` (the closest hit so far, or the ray's `t_max` and no triangle):
    /// as [`TwoLevelBvh::occluded_in_instance`], a hit replacing `best` when closer, or as
    /// close with a lower global triangle, its facing flipped back to world space in a
    /// mirrored instance. True when `best` changed. False for the world-space level.
    #[inline(always)]
    pub fn closest_in_instance(
        &self,
        i: usize,
        ray: &RayRecord,
        best: &mut ClosestHit,
        accept: impl Fn(&TriangleRecord, u32, f32, f32) -> bool,
    ) -> bool {
        let Some((inst, bottom, ro)) = self.object_space(i, ray) else {
            return false;
        };
        let id_of = |slot: u32| inst.first_triangle + bottom.prim_indices[slot as usize];
        let accept = |slot: u32, id: u32, u: f32, v: f32| accept(&hit_record(inst, bottom, slot), id, u, v);
        let found = bottom.closest_ray(&ro, best, id_of, inst.flags & INSTANCE_ALPHA_TEST, accept);
        if found && inst.flags & INSTANCE_MIRRORED != 0 {
            best.back_face = !best.back_face;
        }
        found
    }

    /// Object-space instance `i`, its bottom level and `ray` moved into its space, prepared;
    /// `None` for the world-space level or a moved ray that can hit nothing.
    #[inline(always)]
    fn object_space(&self, i: usize, ray: &RayRecord) -> Option<(&InstanceRecord, &Bvh, TraversalRay)> {
        let inst = &self.instances[i];
        if inst.flags & INSTANCE_IDENTITY != 0 {
            return None;
        }
        Some((inst, &self.bottoms[inst.bottom as usize], TraversalRay::new(&object_space_ray(inst, ray))?))
    }

    /// Any hit, no alpha test ([`Bvh::occluded`]).
    pub fn occluded(&self, ray: &RayRecord) -> bool {
        self.occluded_filtered(ray, |_, _, _, _| true)
    }

    /// The closest hit with `t_min < t < t_max` over every instance, as
    /// [`Bvh::closest_hit_filtered`]: ties at equal `t` go to the lower global triangle,
    /// across instances too; `back_face` is the world facing.
    pub fn closest_hit_filtered(
        &self,
        ray: &RayRecord,
        accept: impl Fn(&TriangleRecord, u32, f32, f32) -> bool,
    ) -> Option<ClosestHit> {
        self.closest_walk(ray, None, false, accept)
    }

    /// [`TwoLevelBvh::closest_hit_filtered`] over the object-space instances only, from
    /// `best`, the closest hit the caller found in the world-space level (with its own
    /// traversal): the closer of the two under the same `(t, triangle)` order.
    pub fn closest_hit_in_object_space(
        &self,
        ray: &RayRecord,
        best: Option<ClosestHit>,
        accept: impl Fn(&TriangleRecord, u32, f32, f32) -> bool,
    ) -> Option<ClosestHit> {
        self.closest_walk(ray, best, true, accept)
    }

    #[inline(always)]
    fn closest_walk(
        &self,
        ray: &RayRecord,
        start: Option<ClosestHit>,
        skip_world: bool,
        accept: impl Fn(&TriangleRecord, u32, f32, f32) -> bool,
    ) -> Option<ClosestHit> {
        let Some(r) = TraversalRay::new(ray) else {
            return start;
        };
        let mut best =
            start.unwrap_or(ClosestHit { triangle: INVALID_ID, t: r.t_max, u: 0.0, v: 0.0, back_face: false });
        let mut bound = best.t;
        let leaf_test = inline_leaf_test(|leaf: Leaf, _: f32, t_best: &mut f32| {
            let inst = &self.instances[leaf.first as usize];
            let found = if inst.flags & INSTANCE_IDENTITY != 0 {
                let bottom = &self.bottoms[inst.bottom as usize];
                let id_of = |slot: u32| bottom.prim_indices[slot as usize];
                let accept = |slot: u32, id: u32, u: f32, v: f32| accept(&hit_record(inst, bottom, slot), id, u, v);
                !skip_world && bottom.closest_ray(&r, &mut best, id_of, 0, accept)
            } else {
                self.closest_in_instance(leaf.first as usize, ray, &mut best, &accept)
            };
            if !found {
                return LeafFlow::Continue;
            }
            *t_best = best.t;
            LeafFlow::Narrowed
        });
        traverse(&self.top, &r, &mut bound, leaf_test);
        (best.triangle != INVALID_ID).then_some(best)
    }

    /// The closest hit, no alpha test ([`Bvh::closest_hit`]).
    pub fn closest_hit(&self, ray: &RayRecord) -> Option<ClosestHit> {
        self.closest_hit_filtered(ray, |_, _, _, _| true)
    }

    /// Bytes held by the levels (nodes, slots, triangle copies and wide views:
    /// [`Bvh::bytes`]) and the instances.
    pub fn bytes(&self) -> usize {
        self.bottoms.iter().map(Bvh::bytes).sum::<usize>()
            + std::mem::size_of_val(self.top.as_slice())
            + std::mem::size_of_val(self.instances.as_slice())
    }
}

/// Every level in one node buffer, one slot table and one instance table: what the GPU
/// binds ([`TwoLevelBvh::packed`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PackedLevels {
    /// The top level's nodes first (its root is node 0, its leaves name instances), then
    /// each bottom level's nodes in turn, their child and slot indices shifted to this
    /// buffer and to `leaf_triangles`.
    pub nodes: Vec<BvhNode>,
    /// Every bottom level's `leaf_triangles`, in turn.
    pub leaf_triangles: Vec<TriangleRecord>,
    /// Every bottom level's `prim_indices`, in turn (mesh-local indices for object-space
    /// levels, global ones for the world-space level: add the instance's `first_triangle`).
    pub prim_indices: Vec<u32>,
    /// The instances, each `bottom` replaced by the index of its level's root in `nodes`.
    pub instances: Vec<InstanceRecord>,
}

impl TwoLevelBvh {
    /// The levels packed for one set of bindings ([`PackedLevels`]).
    pub fn packed(&self) -> PackedLevels {
        let mut p = PackedLevels { nodes: self.top.clone(), ..PackedLevels::default() };
        for b in 0..self.bottoms.len() {
            let (_, nodes, _) = self.packed_bottom(b);
            p.nodes.extend(nodes);
            p.leaf_triangles.extend_from_slice(&self.bottoms[b].leaf_triangles);
            p.prim_indices.extend_from_slice(&self.bottoms[b].prim_indices);
        }
        p.instances = self.packed_instances();
        p
    }

    /// Bottom level `b` as [`TwoLevelBvh::packed`] places it: the index of its root in
    /// [`PackedLevels::nodes`], its nodes there (indices shifted), and the index of its
    /// first slot in [`PackedLevels::leaf_triangles`]. What a refit changes on a device.
    pub fn packed_bottom(&self, b: usize) -> (u32, Vec<BvhNode>, u32) {
        let node_base = self.top.len() as u32 + self.bottoms[..b].iter().map(|x| x.nodes.len() as u32).sum::<u32>();
        let slot_base = self.bottoms[..b].iter().map(|x| x.leaf_triangles.len() as u32).sum::<u32>();
        let nodes = self.bottoms[b]
            .nodes
            .iter()
            .map(|n| {
                let shift = if n.is_leaf() { slot_base } else { node_base };
                BvhNode { left_or_first: n.left_or_first + shift, ..*n }
            })
            .collect();
        (node_base, nodes, slot_base)
    }

    /// [`PackedLevels::instances`] alone: what a move changes in the packed levels, with
    /// the top level's nodes (the first `top.len()` of [`PackedLevels::nodes`], whose
    /// count a move keeps: one leaf per instance).
    pub fn packed_instances(&self) -> Vec<InstanceRecord> {
        let mut roots = Vec::with_capacity(self.bottoms.len());
        let mut base = self.top.len() as u32;
        for b in &self.bottoms {
            roots.push(base);
            base += b.nodes.len() as u32;
        }
        self.instances.iter().map(|i| InstanceRecord { bottom: roots[i.bottom as usize], ..*i }).collect()
    }
}

/// The ray moved into `inst`'s object space ([`to_object_space`]; the same `t` interval:
/// an affine map keeps the ray parameter). It can hit nothing there when the map
/// overflowed it or its direction vanished: the traversals reject such a ray as they
/// reject any invalid one. Not for the world-space level (its rays are not moved).
#[inline(always)]
pub fn object_space_ray(inst: &InstanceRecord, ray: &RayRecord) -> RayRecord {
    let (origin, direction) = to_object_space(&inst.world_to_object(), ray.origin.into(), ray.direction.into());
    RayRecord { origin: origin.into(), direction: direction.into(), ..*ray }
}

/// The record an alpha test reads for a hit on leaf slot `slot` of `bottom` through
/// `inst`: the leaf's copy, its object the instance's (a bottom level shared by several
/// objects names the first).
#[inline(always)]
fn hit_record(inst: &InstanceRecord, bottom: &Bvh, slot: u32) -> TriangleRecord {
    TriangleRecord { object: inst.object, ..bottom.leaf_triangles[slot as usize] }
}

/// A mesh's triangles in its own space, as its bottom level holds them: the mesh-local
/// index in `triangle`, `object` the first object drawing it, no flags (an instance
/// brings its object's). A vertex index out of range makes a NaN vertex (never traced).
fn object_triangles(scene: &Scene, mesh: usize, object: u32) -> Vec<TriangleRecord> {
    let mesh = &scene.meshes[mesh];
    mesh.indices
        .iter()
        .enumerate()
        .map(|(ti, idx)| {
            let [a, b, c] = idx.map(|i| mesh.positions.get(i as usize).copied().unwrap_or(Vec3::NAN));
            TriangleRecord { v0: a.into(), object, v1: b.into(), triangle: ti as u32, v2: c.into(), flags: 0 }
        })
        .collect()
}

/// Depth of the deepest node of a flattened tree (root 0).
fn depth_of(nodes: &[BvhNode]) -> usize {
    let mut deepest = 0;
    let mut todo = if nodes.is_empty() { vec![] } else { vec![(0usize, 0usize)] };
    while let Some((n, d)) = todo.pop() {
        deepest = deepest.max(d);
        if !nodes[n].is_leaf() {
            let l = nodes[n].left_or_first as usize;
            todo.push((l, d + 1));
            todo.push((l + 1, d + 1));
        }
    }
    deepest
}

/// A balanced top level (object-median splits of the box centres on the longest axis, one
/// box per leaf): the fallback if obvhs ever returns a tree too deep for the stack. Returns
/// the nodes (depth first) and the box index of each leaf slot.
fn median_top(boxes: &[Aabb]) -> (Vec<BvhNode>, Vec<u32>) {
    let mut items: Vec<u32> = (0..boxes.len() as u32).collect();
    let centre = |i: u32| Vec3::from(boxes[i as usize].center());
    let mut nodes = vec![BvhNode::zeroed()];
    let mut todo = vec![(0usize, 0usize, items.len())];
    while let Some((node, start, end)) = todo.pop() {
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let (mut clo, mut chi) = (lo, hi);
        for &i in &items[start..end] {
            lo = lo.min(boxes[i as usize].min.into());
            hi = hi.max(boxes[i as usize].max.into());
            clo = clo.min(centre(i));
            chi = chi.max(centre(i));
        }
        if end - start == 1 {
            nodes[node] = BvhNode::from_box(lo, hi, start as u32, 1);
            continue;
        }
        let axis = (chi - clo).max_position();
        items[start..end].sort_unstable_by(|&a, &b| centre(a)[axis].total_cmp(&centre(b)[axis]).then(a.cmp(&b)));
        let left = nodes.len();
        nodes.extend([BvhNode::zeroed(); 2]);
        nodes[node] = BvhNode::from_box(lo, hi, left as u32, 0);
        let mid = start + (end - start) / 2;
        todo.push((left + 1, mid, end));
        todo.push((left, start, mid));
    }
    (nodes, items)
}
