//! The BVH's records: its nodes ([`BvhNode`], built by [`crate::bvh`]) and the instances
//! of the two-level BVH ([`InstanceRecord`], [`crate::bvh::two_level`]) with their flags
//! and world-to-object maps ([`ObjectMap`]), declared in WGSL like every other record.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::wgsl::wgsl_struct;
use super::{INVALID_ID, TRI_ALPHA_TEST};

/// Largest number of triangle slots in one leaf: the `max_prims_per_leaf` of every obvhs
/// preset (`fastest_build` uses 1, the others 8), and the leaf size of the median
/// fallback.
pub const BVH_MAX_LEAF_SIZE: u32 = 8;

/// One BVH node, inner or leaf.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `aabb_min` | [f32; 3] | box minimum (world space, finite) |
/// | 12 | `left_or_first` | u32 | inner: index of the left child, the right child is `left_or_first + 1`; leaf: first slot in `prim_indices` |
/// | 16 | `aabb_max` | [f32; 3] | box maximum |
/// | 28 | `count` | u32 | 0: inner node; > 0: leaf with `count` slots `prim_indices[left_or_first ..][.. count]` |
///
/// 32 bytes; two siblings fill one 64-byte cache line when the array is 64-byte aligned.
/// Boxes are closed and conservative: a child's box lies inside its parent's, a leaf's
/// box contains its triangles (or, with spatial splits, the parts of them the leaf is
/// responsible for).
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct BvhNode {
    pub aabb_min: [f32; 3],
    pub left_or_first: u32,
    pub aabb_max: [f32; 3],
    pub count: u32,
}
const _: () = assert!(std::mem::size_of::<BvhNode>() == 32);
wgsl_struct!(BvhNode { aabb_min, left_or_first, aabb_max, count });

impl BvhNode {
    /// True for a leaf (`count > 0`).
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }

    /// Box minimum as a vector.
    #[inline]
    pub fn min(&self) -> Vec3 {
        Vec3::from(self.aabb_min)
    }

    /// Box maximum as a vector.
    #[inline]
    pub fn max(&self) -> Vec3 {
        Vec3::from(self.aabb_max)
    }

    /// Check: finite box with `min <= max`, leaf size at most [`BVH_MAX_LEAF_SIZE`].
    /// (Links are checked by [`Bvh::validate`](crate::bvh::Bvh::validate).)
    pub fn validate(&self) -> Result<(), String> {
        if !(self.min().is_finite() && self.max().is_finite()) {
            return Err(format!("node with a non-finite box: {self:?}"));
        }
        if !self.min().cmple(self.max()).all() {
            return Err(format!("node with min > max: {self:?}"));
        }
        if self.count > BVH_MAX_LEAF_SIZE {
            return Err(format!("leaf with more than {BVH_MAX_LEAF_SIZE} slots: {self:?}"));
        }
        Ok(())
    }

    #[inline]
    pub(crate) fn from_box(min: Vec3, max: Vec3, left_or_first: u32, count: u32) -> BvhNode {
        BvhNode { aabb_min: min.into(), left_or_first, aabb_max: max.into(), count }
    }
}

/// An instance's world-to-object map, as rows `[l_i0, l_i1, l_i2, t_i]`: the object point
/// of the world point `w` is `L (w - t)`, where `L` is the inverse of the object-to-world
/// linear part (rounded to f32 once) and `t` the object-to-world translation (exact).
/// Subtracting `t` first keeps the rounding of the map relative to the object's own size
/// rather than to its distance from the world origin: an object far out in the world is
/// mapped as precisely as one at the origin (the form Embree and OptiX instance
/// transforms round the same way).
pub type ObjectMap = [[f32; 4]; 3];

/// The identity map.
pub const MAP_IDENTITY: ObjectMap = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];

/// [`InstanceRecord::flags`]: the bottom level is in world space; rays are not moved.
pub const INSTANCE_IDENTITY: u32 = 1 << 8;
/// [`InstanceRecord::flags`]: the object's transform mirrors (negative determinant): a
/// back face in object space is a front face in the world.
pub const INSTANCE_MIRRORED: u32 = 1 << 9;
/// [`InstanceRecord::flags`]: the object is alpha-tested; its bottom level's own triangle
/// records carry no flags (they are shared by every instance of the mesh), so the
/// instance brings [`TRI_ALPHA_TEST`] (the same bit) to the leaf tests.
pub const INSTANCE_ALPHA_TEST: u32 = TRI_ALPHA_TEST;

/// One instance of a bottom level in the top level.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `map_x`, `map_y`, `map_z` | 3 x [f32; 4] | the rows of the world-to-object map ([`ObjectMap`]: `L (w - t)`; identity for the world-space level) |
/// | 48 | `bottom` | u32 | index of its bottom level (on the GPU: the index of that level's root in the one node buffer all levels share) |
/// | 52 | `object` | u32 | the object drawn; [`INVALID_ID`] for the world-space level, which holds many |
/// | 56 | `first_triangle` | u32 | added to the bottom level's slot indices: the global triangle index |
/// | 60 | `flags` | u32 | [`INSTANCE_IDENTITY`], [`INSTANCE_MIRRORED`], [`INSTANCE_ALPHA_TEST`] |
///
/// 64 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct InstanceRecord {
    pub map_x: [f32; 4],
    pub map_y: [f32; 4],
    pub map_z: [f32; 4],
    pub bottom: u32,
    pub object: u32,
    pub first_triangle: u32,
    pub flags: u32,
}
const _: () = assert!(std::mem::size_of::<InstanceRecord>() == 64);
wgsl_struct!(InstanceRecord { map_x, map_y, map_z, bottom, object, first_triangle, flags });

impl InstanceRecord {
    /// The world-to-object map ([`ObjectMap`], its rows).
    #[inline]
    pub fn world_to_object(&self) -> ObjectMap {
        [self.map_x, self.map_y, self.map_z]
    }

    /// Set the world-to-object map.
    pub fn set_world_to_object(&mut self, map: ObjectMap) {
        [self.map_x, self.map_y, self.map_z] = map;
    }

    /// Check: finite map (the identity for [`INSTANCE_IDENTITY`]), known flags, an object
    /// exactly when the level is in object space.
    pub fn validate(&self) -> Result<(), String> {
        let known = INSTANCE_IDENTITY | INSTANCE_MIRRORED | INSTANCE_ALPHA_TEST;
        if self.flags & !known != 0 {
            return Err(format!("instance with unknown flags: {self:?}"));
        }
        if !self.world_to_object().iter().flatten().all(|x| x.is_finite()) {
            return Err(format!("instance with a non-finite map: {self:?}"));
        }
        let identity = self.flags & INSTANCE_IDENTITY != 0;
        if identity
            && (self.world_to_object() != MAP_IDENTITY || self.object != INVALID_ID || self.flags != INSTANCE_IDENTITY)
        {
            return Err(format!("world-space instance with a map, an object or flags: {self:?}"));
        }
        if !identity && self.object == INVALID_ID {
            return Err(format!("object-space instance without an object: {self:?}"));
        }
        Ok(())
    }

    pub(crate) fn identity(bottom: u32) -> InstanceRecord {
        let [map_x, map_y, map_z] = MAP_IDENTITY;
        InstanceRecord { map_x, map_y, map_z, bottom, object: INVALID_ID, first_triangle: 0, flags: INSTANCE_IDENTITY }
    }
}
