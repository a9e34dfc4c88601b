//! [`WorldTriangles`]: the world-space triangle table of a scene, and where each object's
//! triangles live.
//!
//! Every triangle has a global id: object `o` owns `objects[o].first_triangle ..+
//! triangle_count`, in mesh order, whatever the storage. An object is either
//! - **stored**: its world records and corner normals are in the table (transformed once,
//!   when the scene is built or the object moves), or
//! - **by reference**: only its mesh (shared by every object drawing it) and its transform
//!   are kept, and a record is made when it is read ([`WorldTriangles::get`]), by the very
//!   operations that store one ([`world_record`], [`world_normals`]), so both give the
//!   same bits. This is how 1,000 instances of an 871k-triangle mesh fit in memory: the
//!   stored table would take 84 bytes per instanced triangle (73 GB).
//!
//! A table whose objects are all stored is indexed directly ([`WorldTriangles::as_slice`]);
//! only tables with objects by reference look an id's object up (a binary search over the
//! objects' first ids).

use std::borrow::Cow;
use std::sync::Arc;

use bytemuck::Zeroable;

use glam::{Mat3, Mat4, Vec3};

use crate::formats::{PlacementRecord, TriangleRecord, INVALID_ID};
use crate::scene::Mesh;

/// The part of a mesh that world records are made from, shared by the objects that draw
/// it by reference.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshSource {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub indices: Vec<[u32; 3]>,
    /// Every position is a corner of some triangle (and every index in range): an
    /// object's extent is then the bounds of all its placed positions
    /// ([`crate::geometry::ObjectExtent::of_placed`]), with no pass over the triangles.
    pub every_vertex_used: bool,
}

impl MeshSource {
    /// The positions, normals and triangles of `mesh`.
    pub fn of_mesh(mesh: &Mesh) -> MeshSource {
        let mut used = vec![false; mesh.positions.len()];
        let mut in_range = true;
        for &i in mesh.indices.iter().flatten() {
            match used.get_mut(i as usize) {
                Some(u) => *u = true,
                None => in_range = false,
            }
        }
        MeshSource {
            positions: mesh.positions.clone(),
            normals: mesh.normals.clone(),
            indices: mesh.indices.clone(),
            every_vertex_used: in_range && used.iter().all(|&u| u),
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        (self.positions.len() + self.normals.as_ref().map_or(0, Vec::len)) * std::mem::size_of::<Vec3>()
            + self.indices.len() * std::mem::size_of::<[u32; 3]>()
    }
}

/// An object's transform as its records are made: the point transform and the normal
/// matrix (the inverse transpose of its linear part).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectTransform {
    pub to_world: Mat4,
    pub normal_matrix: Mat3,
}

impl ObjectTransform {
    /// The transform of an object placed by `to_world`.
    pub fn new(to_world: Mat4) -> ObjectTransform {
        ObjectTransform { to_world, normal_matrix: Mat3::from_mat4(to_world).inverse().transpose() }
    }
}

/// The world record of triangle `index` of `mesh` (whose world vertices `world` gives)
/// for object `object`: the one way a record is made, stored or by reference.
#[inline]
pub fn world_record(world: [Vec3; 3], object: u32, index: u32, flags: u32) -> TriangleRecord {
    let [a, b, c] = world;
    TriangleRecord { v0: a.into(), object, v1: b.into(), triangle: index, v2: c.into(), flags }
}

/// The world-space unit normals at the corners of a triangle with world vertices `world`
/// and mesh indices `idx`: the mesh's vertex normals under the normal matrix when it has
/// them (the geometric normal where one vanishes), else the geometric normal (zero for a
/// degenerate triangle).
#[inline]
pub fn world_normals(world: [Vec3; 3], idx: [u32; 3], normals: Option<&[Vec3]>, normal_matrix: &Mat3) -> [Vec3; 3] {
    let [a, b, c] = world;
    let face = (b - a).cross(c - a).normalize_or_zero();
    match normals {
        Some(ns) => idx.map(|i| {
            let n = (*normal_matrix * ns[i as usize]).normalize_or_zero();
            if n == Vec3::ZERO {
                face
            } else {
                n
            }
        }),
        None => [face; 3],
    }
}

/// Where one shared mesh's words start in [`WorldTriangles::mesh_words`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshWords {
    /// First word of its triangles (three vertex indices each).
    pub indices: u32,
    /// First word of its positions (three f32 bit patterns each).
    pub positions: u32,
    /// First word of its vertex normals; [`INVALID_ID`] for a mesh without them.
    pub normals: u32,
}

/// An object whose records are made on read.
#[derive(Clone, Debug, PartialEq)]
pub struct ByReference {
    /// Index into [`WorldTriangles`]'s meshes.
    pub mesh: u32,
    pub transform: ObjectTransform,
    /// The `TRI_*` flags of every triangle of the object.
    pub flags: u32,
}

/// Where an object's triangles are.
#[derive(Clone, Debug, PartialEq)]
pub enum Placement {
    /// In the stored table from this record on.
    Stored { first_record: u32 },
    /// Made on read.
    ByReference(ByReference),
}

/// The world-space triangles of a scene and their corner normals; see the module docs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WorldTriangles {
    /// Stored objects' records, object after object.
    records: Vec<TriangleRecord>,
    /// Their world-space unit normals at the three corners.
    normals: Vec<[Vec3; 3]>,
    /// Per object, where its triangles are; empty while every object is stored and
    /// `records[id]` is triangle `id`.
    placements: Vec<Placement>,
    /// Per object, its first global id (with `placements`), and the total at the end.
    starts: Vec<u32>,
    /// The meshes of objects by reference.
    meshes: Vec<Arc<MeshSource>>,
    /// Number of triangles (global ids).
    len: usize,
}

impl WorldTriangles {
    /// A table of every object stored: `records` and `normals` in global order.
    pub fn stored(records: Vec<TriangleRecord>, normals: Vec<[Vec3; 3]>) -> WorldTriangles {
        assert_eq!(records.len(), normals.len(), "one normal triple per record");
        let len = records.len();
        WorldTriangles { records, normals, len, ..WorldTriangles::default() }
    }

    /// A table for objects of `counts` triangles each, placed as `by_reference` says
    /// (`Some((mesh, transform, flags))`, the mesh an index into `meshes`) or stored
    /// (`None`, zeroed records to be written with [`WorldTriangles::object_mut`]).
    pub fn with_placements(
        counts: &[u32],
        by_reference: Vec<Option<ByReference>>,
        meshes: Vec<Arc<MeshSource>>,
    ) -> WorldTriangles {
        assert_eq!(counts.len(), by_reference.len());
        let mut starts = Vec::with_capacity(counts.len() + 1);
        let (mut next, mut stored) = (0u32, 0u32);
        let mut placements = Vec::with_capacity(counts.len());
        for (&count, r) in counts.iter().zip(by_reference) {
            starts.push(next);
            next = next.checked_add(count).expect("triangle ids fit in u32");
            placements.push(match r {
                Some(r) => {
                    assert!((r.mesh as usize) < meshes.len(), "mesh of an object by reference");
                    Placement::ByReference(r)
                }
                None => {
                    stored += count;
                    Placement::Stored { first_record: stored - count }
                }
            });
        }
        starts.push(next);
        let any_reference = placements.iter().any(|p| matches!(p, Placement::ByReference(_)));
        WorldTriangles {
            records: vec![TriangleRecord::zeroed(); stored as usize],
            normals: vec![[Vec3::ZERO; 3]; stored as usize],
            placements: if any_reference { placements } else { Vec::new() },
            starts: if any_reference { starts } else { Vec::new() },
            meshes: if any_reference { meshes } else { Vec::new() },
            len: next as usize,
        }
    }

    /// Number of triangles.
    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }

    /// No triangles.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The whole table as a slice indexed by global id, when every object is stored.
    #[inline]
    pub fn as_slice(&self) -> Option<&[TriangleRecord]> {
        self.placements.is_empty().then_some(&self.records[..])
    }

    /// The stored objects' records, object after object (the whole table, by global id,
    /// when no object is by reference).
    pub fn stored_records(&self) -> &[TriangleRecord] {
        &self.records
    }

    /// The index into [`WorldTriangles::stored_records`] of global id `id`, when its
    /// object is stored.
    pub fn record_of(&self, id: usize) -> Option<usize> {
        if self.placements.is_empty() {
            return (id < self.len).then_some(id);
        }
        if id >= self.len {
            return None;
        }
        let (o, local) = self.locate(id);
        match &self.placements[o] {
            Placement::Stored { first_record } => Some(*first_record as usize + local),
            Placement::ByReference(_) => None,
        }
    }

    /// The whole table by global id: borrowed when every object is stored, else made (every
    /// record of the objects by reference, so as large as the stored table would be).
    pub fn whole(&self) -> Cow<'_, [TriangleRecord]> {
        match self.as_slice() {
            Some(all) => Cow::Borrowed(all),
            None => Cow::Owned(self.iter().collect()),
        }
    }

    /// Whether some object is by reference.
    pub fn has_references(&self) -> bool {
        !self.placements.is_empty()
    }

    /// Where object `object`'s triangles are (stored from `first_triangle` when every
    /// object is stored).
    pub fn placement(&self, object: u32, first_triangle: u32) -> Placement {
        match self.placements.get(object as usize) {
            Some(p) => p.clone(),
            None => Placement::Stored { first_record: first_triangle },
        }
    }

    /// The object owning global id `id` (a table with objects by reference only; a stored
    /// table's records name their object).
    #[inline]
    fn object_of(&self, id: usize) -> usize {
        debug_assert!(!self.starts.is_empty() && id < self.len);
        self.starts.partition_point(|&s| s as usize <= id) - 1
    }

    /// The object owning global id `id`, and `id`'s index within it (a table with objects
    /// by reference only).
    #[inline]
    fn locate(&self, id: usize) -> (usize, usize) {
        let o = self.object_of(id);
        (o, id - self.starts[o] as usize)
    }

    /// Triangle `id`'s world record.
    #[inline]
    pub fn get(&self, id: usize) -> TriangleRecord {
        if self.placements.is_empty() {
            return self.records[id];
        }
        let (o, local) = self.locate(id);
        match &self.placements[o] {
            Placement::Stored { first_record } => self.records[*first_record as usize + local],
            Placement::ByReference(r) => {
                let (world, _) = self.reference_vertices(r, local);
                world_record(world, o as u32, local as u32, r.flags)
            }
        }
    }

    /// Where triangle `id`'s record and corner normals are stored, for a caller that asks
    /// for their cache lines ahead of reading them; `None` for an object by reference
    /// (made on demand from its mesh).
    #[inline]
    pub fn stored_at(&self, id: usize) -> Option<(&TriangleRecord, &[Vec3; 3])> {
        let i = if self.placements.is_empty() {
            id
        } else {
            let (o, local) = self.locate(id);
            match &self.placements[o] {
                Placement::Stored { first_record } => *first_record as usize + local,
                Placement::ByReference(_) => return None,
            }
        };
        Some((self.records.get(i)?, self.normals.get(i)?))
    }

    /// Triangle `id`'s `TRI_*` flags (without making its record).
    #[inline]
    pub fn flags(&self, id: usize) -> u32 {
        if self.placements.is_empty() {
            return self.records[id].flags;
        }
        let (o, local) = self.locate(id);
        match &self.placements[o] {
            Placement::Stored { first_record } => self.records[*first_record as usize + local].flags,
            Placement::ByReference(r) => r.flags,
        }
    }

    /// Triangle `id`'s world-space unit normals at its corners.
    #[inline]
    pub fn normals(&self, id: usize) -> [Vec3; 3] {
        if self.placements.is_empty() {
            return self.normals[id];
        }
        let (o, local) = self.locate(id);
        match &self.placements[o] {
            Placement::Stored { first_record } => self.normals[*first_record as usize + local],
            Placement::ByReference(r) => {
                let (world, idx) = self.reference_vertices(r, local);
                let mesh = &self.meshes[r.mesh as usize];
                world_normals(world, idx, mesh.normals.as_deref(), &r.transform.normal_matrix)
            }
        }
    }

    /// The world vertices and mesh indices of triangle `local` of an object by reference.
    #[inline]
    fn reference_vertices(&self, r: &ByReference, local: usize) -> ([Vec3; 3], [u32; 3]) {
        let mesh = &self.meshes[r.mesh as usize];
        let idx = mesh.indices[local];
        (idx.map(|i| r.transform.to_world.transform_point3(mesh.positions[i as usize])), idx)
    }

    /// The objects whose triangles global ids `range` cover, in order, each with its local
    /// ids in that range: `(object, local range)` (a table with objects by reference only).
    fn object_runs(&self, range: std::ops::Range<usize>) -> impl Iterator<Item = (usize, std::ops::Range<usize>)> + '_ {
        let first = if range.is_empty() { self.placements.len() } else { self.object_of(range.start) };
        (first..self.placements.len()).map_while(move |o| {
            let start = self.starts[o] as usize;
            (start < range.end)
                .then(|| (o, range.start.max(start) - start..(self.starts[o + 1] as usize).min(range.end) - start))
        })
    }

    /// The records of global ids `range`, in order, into `out` (cleared first): one pass
    /// per object, whatever the storage.
    pub fn fill(&self, range: std::ops::Range<usize>, out: &mut Vec<TriangleRecord>) {
        self.fill_with(range, out, &self.records, |o, r, local, out| {
            let (mesh, m) = (&self.meshes[r.mesh as usize], &r.transform.to_world);
            out.extend(mesh.indices[local.clone()].iter().zip(local).map(|(idx, t)| {
                let world = idx.map(|i| m.transform_point3(mesh.positions[i as usize]));
                world_record(world, o as u32, t as u32, r.flags)
            }));
        });
    }

    /// The corner normals of global ids `range`, in order, into `out` (cleared first).
    pub fn fill_normals(&self, range: std::ops::Range<usize>, out: &mut Vec<[Vec3; 3]>) {
        self.fill_with(range, out, &self.normals, |_, r, local, out| {
            let mesh = &self.meshes[r.mesh as usize];
            out.extend(local.map(|t| {
                let (world, idx) = self.reference_vertices(r, t);
                world_normals(world, idx, mesh.normals.as_deref(), &r.transform.normal_matrix)
            }));
        });
    }

    /// [`WorldTriangles::fill`] and [`WorldTriangles::fill_normals`]: the entries of global
    /// ids `range` into `out` (cleared first), copied from `stored` (records or normals, by
    /// record index) for stored objects, and for each run of an object by reference appended
    /// by `made(object, reference, local ids, out)` (which can look its mesh up once a run).
    fn fill_with<T: Copy>(
        &self,
        range: std::ops::Range<usize>,
        out: &mut Vec<T>,
        stored: &[T],
        made: impl Fn(usize, &ByReference, std::ops::Range<usize>, &mut Vec<T>),
    ) {
        out.clear();
        if self.placements.is_empty() {
            out.extend_from_slice(&stored[range]);
            return;
        }
        for (o, local) in self.object_runs(range) {
            match &self.placements[o] {
                Placement::Stored { first_record } => {
                    let first = *first_record as usize;
                    out.extend_from_slice(&stored[first + local.start..first + local.end]);
                }
                Placement::ByReference(r) => made(o, r, local, out),
            }
        }
    }

    /// Every record, in global order.
    pub fn iter(&self) -> impl Iterator<Item = TriangleRecord> + '_ {
        const BLOCK: usize = 4096;
        let mut buf = Vec::with_capacity(BLOCK);
        (0..self.len.div_ceil(BLOCK)).flat_map(move |b| {
            self.fill(b * BLOCK..((b + 1) * BLOCK).min(self.len), &mut buf);
            std::mem::take(&mut buf)
        })
    }

    /// The records and normals of a stored object (`first_record ..+ count`), to write.
    pub fn object_mut(&mut self, first_record: u32, count: u32) -> (&mut [TriangleRecord], &mut [[Vec3; 3]]) {
        let r = first_record as usize..(first_record + count) as usize;
        (&mut self.records[r.clone()], &mut self.normals[r])
    }

    /// Set the transform and flags of an object by reference (it moved).
    pub fn set_reference(&mut self, object: u32, transform: ObjectTransform, flags: u32) {
        match self.placements.get_mut(object as usize) {
            Some(Placement::ByReference(r)) => {
                r.transform = transform;
                r.flags = flags;
            }
            _ => panic!("object {object} is not by reference"),
        }
    }

    /// Replace shared mesh `index` (it deformed: new positions or normals, the same
    /// triangles).
    pub fn set_mesh(&mut self, index: u32, mesh: MeshSource) {
        assert_eq!(mesh.indices, self.meshes[index as usize].indices, "a deformed mesh keeps its triangles");
        self.meshes[index as usize] = Arc::new(mesh);
    }

    /// The mesh an object by reference draws.
    pub fn mesh(&self, index: u32) -> &MeshSource {
        &self.meshes[index as usize]
    }

    /// The stored objects' corner normals, object after object (by record index, as
    /// [`WorldTriangles::stored_records`]).
    pub fn stored_normals(&self) -> &[[Vec3; 3]] {
        &self.normals
    }

    /// The meshes of objects by reference as one table of words, for a device that makes
    /// their records on read ([`PlacementRecord`]): each mesh's positions (three f32 bit
    /// patterns a vertex), then its vertex normals (likewise, when it has them), then its
    /// triangles (three vertex indices each), mesh after mesh. Returns the words and, per
    /// mesh, the first word of its `[indices, positions, normals]` (normals
    /// [`INVALID_ID`] for a mesh without them); `None` when they would take 2^32 words or
    /// more (word offsets are u32).
    pub fn mesh_words(&self) -> Option<(Vec<u32>, Vec<MeshWords>)> {
        let total = self.mesh_word_count();
        if total >= INVALID_ID as usize {
            return None;
        }
        let mut words = Vec::with_capacity(total);
        let mut offsets = Vec::with_capacity(self.meshes.len());
        let vec3_words = |v: &Vec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
        for m in &self.meshes {
            let positions = words.len() as u32;
            words.extend(m.positions.iter().flat_map(vec3_words));
            let normals = match &m.normals {
                Some(ns) => {
                    let first = words.len() as u32;
                    words.extend(ns.iter().flat_map(vec3_words));
                    first
                }
                None => INVALID_ID,
            };
            let indices = words.len() as u32;
            words.extend(m.indices.iter().flatten());
            offsets.push(MeshWords { indices, positions, normals });
        }
        Some((words, offsets))
    }

    /// The number of words [`WorldTriangles::mesh_words`] takes (it gives none from
    /// [`INVALID_ID`] words on).
    pub fn mesh_word_count(&self) -> usize {
        self.meshes
            .iter()
            .map(|m| 3 * (m.positions.len() + m.normals.as_ref().map_or(0, Vec::len) + m.indices.len()))
            .sum()
    }

    /// Object `object`'s [`PlacementRecord`] (its first global id `first_triangle`, its
    /// `count` triangles), its mesh found in the words of [`WorldTriangles::mesh_words`] at
    /// `meshes`: a stored object's first record and flags, or an object by reference's
    /// transform, normal matrix, mesh words and flags. A table without objects by reference
    /// has every object stored from its first id.
    pub fn placement_record(
        &self,
        object: u32,
        first_triangle: u32,
        count: u32,
        meshes: &[MeshWords],
    ) -> PlacementRecord {
        let mut record = PlacementRecord {
            first_triangle,
            triangle_count: count,
            mesh_indices: INVALID_ID,
            mesh_positions: INVALID_ID,
            mesh_normals: INVALID_ID,
            ..PlacementRecord::zeroed()
        };
        match self.placement(object, first_triangle) {
            Placement::Stored { first_record } => {
                record.first_record = first_record;
                // Every triangle of an object carries the object's flags.
                let own = &self.records[first_record as usize..(first_record + count) as usize];
                record.flags = own.first().map_or(0, |r| r.flags);
                debug_assert!(own.iter().all(|r| r.flags == record.flags), "object {object}: mixed triangle flags");
            }
            Placement::ByReference(r) => {
                let words = meshes[r.mesh as usize];
                let (m, n) = (r.transform.to_world, r.transform.normal_matrix);
                record.to_world_x = m.x_axis.truncate().into();
                record.to_world_y = m.y_axis.truncate().into();
                record.to_world_z = m.z_axis.truncate().into();
                record.to_world_w = m.w_axis.truncate().into();
                record.normal_x = n.x_axis.into();
                record.normal_y = n.y_axis.into();
                record.normal_z = n.z_axis.into();
                record.mesh_indices = words.indices;
                record.mesh_positions = words.positions;
                record.mesh_normals = words.normals;
                record.flags = r.flags;
                record.first_record = INVALID_ID;
            }
        }
        record
    }

    /// Bytes held: stored records and normals, placements and shared meshes.
    pub fn bytes(&self) -> usize {
        self.records.len() * std::mem::size_of::<TriangleRecord>()
            + self.normals.len() * std::mem::size_of::<[Vec3; 3]>()
            + self.placements.len() * std::mem::size_of::<Placement>()
            + self.starts.len() * 4
            + self.meshes.iter().map(|m| m.bytes()).sum::<usize>()
    }

    /// Bytes one stored triangle takes: its record and its corner normals.
    pub const STORED_BYTES_PER_TRIANGLE: usize =
        std::mem::size_of::<TriangleRecord>() + std::mem::size_of::<[Vec3; 3]>();

    /// Bytes every object's records and normals would take stored.
    pub fn stored_bytes(&self) -> usize {
        self.len * Self::STORED_BYTES_PER_TRIANGLE
    }
}
