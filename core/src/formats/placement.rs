//! [`PlacementRecord`]: where a device finds each object's world triangles when some objects
//! are kept by reference ([`crate::geometry::WorldTriangles`]).

use bytemuck::{Pod, Zeroable};

use super::wgsl::wgsl_struct;

use super::{INVALID_ID, TRI_ALPHA_TEST, TRI_INWARD, TRI_RAY_TRACED};

/// Where one object's world triangles are, for a device reading a table with objects by
/// reference ([`crate::geometry::WorldTriangles::placement_record`]): in the stored table
/// (`first_record`), or made on read from its mesh's words (positions, normals, indices:
/// [`crate::geometry::WorldTriangles::mesh_words`]) under its transform, by the operations
/// of [`crate::geometry::world_record`] and [`crate::geometry::world_normals`].
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `to_world_x` | [f32; 3] | x column of the object-to-world transform (glam `Mat4::x_axis`, its first three rows: `transform_point3` uses no other) |
/// | 12 | `first_triangle` | u32 | the object's first global triangle id |
/// | 16 | `to_world_y` | [f32; 3] | y column |
/// | 28 | `triangle_count` | u32 | its triangles |
/// | 32 | `to_world_z` | [f32; 3] | z column |
/// | 44 | `mesh_indices` | u32 | first word of its mesh's triangles (three vertex indices each) in the mesh words; [`INVALID_ID`] for a stored object |
/// | 48 | `to_world_w` | [f32; 3] | the translation (`w_axis`) |
/// | 60 | `mesh_positions` | u32 | first word of its mesh's positions (three f32 bit patterns each); [`INVALID_ID`] for a stored object |
/// | 64 | `normal_x` | [f32; 3] | x column of the normal matrix (the inverse transpose of the linear part, [`crate::geometry::ObjectTransform`]) |
/// | 76 | `mesh_normals` | u32 | first word of its mesh's vertex normals; [`INVALID_ID`] for a stored object or a mesh without normals |
/// | 80 | `normal_y` | [f32; 3] | y column |
/// | 92 | `flags` | u32 | the `TRI_*` flags of every triangle of the object ([`TRI_RAY_TRACED`], [`TRI_INWARD`], [`TRI_ALPHA_TEST`]; stored or by reference, an object's triangles share them) |
/// | 96 | `normal_z` | [f32; 3] | z column |
/// | 108 | `first_record` | u32 | a stored object: the index of its first record in the stored table (and of its first corner-normal triple); [`INVALID_ID`] by reference |
///
/// 112 bytes. A stored object's transform and mesh words are zero and unread.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PlacementRecord {
    pub to_world_x: [f32; 3],
    pub first_triangle: u32,
    pub to_world_y: [f32; 3],
    pub triangle_count: u32,
    pub to_world_z: [f32; 3],
    pub mesh_indices: u32,
    pub to_world_w: [f32; 3],
    pub mesh_positions: u32,
    pub normal_x: [f32; 3],
    pub mesh_normals: u32,
    pub normal_y: [f32; 3],
    pub flags: u32,
    pub normal_z: [f32; 3],
    pub first_record: u32,
}
const _: () = assert!(std::mem::size_of::<PlacementRecord>() == 112);
wgsl_struct!(PlacementRecord {
    to_world_x,
    first_triangle,
    to_world_y,
    triangle_count,
    to_world_z,
    mesh_indices,
    to_world_w,
    mesh_positions,
    normal_x,
    mesh_normals,
    normal_y,
    flags,
    normal_z,
    first_record
});

impl PlacementRecord {
    /// Whether the object's records are made on read (else stored from `first_record`).
    #[inline]
    pub fn by_reference(&self) -> bool {
        self.first_record == INVALID_ID
    }

    /// Check: known flags; a stored object names no mesh words; an object by reference
    /// names its mesh's indices and positions and has a finite transform and normal matrix.
    pub fn validate(&self) -> Result<(), String> {
        if self.flags & !(TRI_RAY_TRACED | TRI_INWARD | TRI_ALPHA_TEST) != 0 {
            return Err(format!("placement with unknown flags: {self:?}"));
        }
        if self.first_triangle.checked_add(self.triangle_count).is_none() {
            return Err(format!("placement past 2^32 triangles: {self:?}"));
        }
        if !self.by_reference() {
            let words = [self.mesh_indices, self.mesh_positions, self.mesh_normals];
            return match words == [INVALID_ID; 3] {
                true => Ok(()),
                false => Err(format!("stored placement naming mesh words: {self:?}")),
            };
        }
        if self.mesh_indices == INVALID_ID || self.mesh_positions == INVALID_ID {
            return Err(format!("placement by reference without its mesh: {self:?}"));
        }
        let columns = [
            self.to_world_x,
            self.to_world_y,
            self.to_world_z,
            self.to_world_w,
            self.normal_x,
            self.normal_y,
            self.normal_z,
        ];
        if !columns.iter().flatten().all(|x| x.is_finite()) {
            return Err(format!("placement by reference with a non-finite transform: {self:?}"));
        }
        Ok(())
    }
}
