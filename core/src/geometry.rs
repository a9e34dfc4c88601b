//! The world-space scene tables every stage reads: one [`TriangleRecord`] per
//! triangle (objects contiguous, in mesh order), per-corner world normals, one
//! [`ObjectRecord`] per object and one [`LightRecord`] per light.
//!
//! Vertices are transformed to world space once, here, in f32, so the raster,
//! the BVH and reconstruction (on either backend) see the very same bits.

use std::collections::HashMap;

use glam::{DVec3, Mat3, Vec3};

use crate::formats::{LightRecord, ObjectRecord, TriangleRecord, OBJ_RAY_TRACED, TRI_INWARD, TRI_RAY_TRACED};
use crate::scene::{MaterialKind, Mesh, RenderMode, Scene};

/// How a mesh's triangles are wound, as far as the renderer needs to know: which side of a
/// closed mesh is its exterior.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshWinding {
    /// Not a closed, consistently wound surface (or one enclosing no volume, such as a
    /// sheet modelled twice back to back): no exterior. glTF's convention applies, front
    /// faces (counter-clockwise) out.
    Open,
    /// Closed, and the right-handed normals point out of the enclosed volume (glTF's
    /// convention).
    Outward,
    /// Closed, and the normals point into the enclosed volume (as some scans have it; the
    /// horse of `../shared/assets`): back faces are the exterior.
    Inward,
}

/// Relative size under which a closed mesh's signed volume counts as none (a sheet
/// modelled twice back to back, whose volume is rounding noise): `1e-9` of the cube of its
/// bounding box's diagonal, far above the f64 rounding of the sum (about `1e-16` of it per
/// triangle) and far below any solid's volume.
pub const MESH_VOLUME_EPSILON: f64 = 1e-9;

impl MeshWinding {
    /// Classify a mesh in its own space. Closed means every directed edge between two
    /// positions (equal positions are one vertex, so split normals or seams do not open
    /// it) is matched by as many edges the other way: the surface is a cycle, and its
    /// signed volume (divergence theorem, in f64) tells outward from inward. O(triangles)
    /// with hashing.
    pub fn of_mesh(mesh: &Mesh) -> MeshWinding {
        let mut ids: HashMap<[u32; 3], u32> = HashMap::with_capacity(mesh.positions.len());
        let canon: Vec<u32> = mesh
            .positions
            .iter()
            .map(|p| {
                let n = ids.len() as u32;
                *ids.entry(p.to_array().map(|c| (c + 0.0).to_bits())).or_insert(n)
            })
            .collect();
        let mut edges: HashMap<(u32, u32), i32> = HashMap::with_capacity(mesh.indices.len() * 3);
        for idx in &mesh.indices {
            let Some(c) = idx.iter().map(|&i| canon.get(i as usize).copied()).collect::<Option<Vec<u32>>>() else {
                return MeshWinding::Open;
            };
            for (a, b) in [(c[0], c[1]), (c[1], c[2]), (c[2], c[0])] {
                if a != b {
                    // +1 for a -> b, -1 for b -> a, keyed by the unordered pair.
                    *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
                }
            }
        }
        if edges.is_empty() || edges.values().any(|&n| n != 0) {
            return MeshWinding::Open;
        }
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        let mut volume = 0.0f64;
        for idx in &mesh.indices {
            let [a, b, c] = idx.map(|i| mesh.positions[i as usize].as_dvec3());
            if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                return MeshWinding::Open;
            }
            lo = lo.min(a).min(b).min(c);
            hi = hi.max(a).max(b).max(c);
            volume += a.dot(b.cross(c)) / 6.0;
        }
        let scale = (hi - lo).length().powi(3);
        if volume.abs() <= MESH_VOLUME_EPSILON * scale {
            MeshWinding::Open
        } else if volume > 0.0 {
            MeshWinding::Outward
        } else {
            MeshWinding::Inward
        }
    }

    /// The winding after a transform whose linear part has determinant `det` (a mirror,
    /// `det < 0`, swaps outward and inward).
    pub fn transformed(self, det: f32) -> MeshWinding {
        match (self, det < 0.0) {
            (MeshWinding::Outward, true) => MeshWinding::Inward,
            (MeshWinding::Inward, true) => MeshWinding::Outward,
            (w, _) => w,
        }
    }
}

/// World-space tables of a scene.
#[derive(Clone, Debug, Default)]
pub struct WorldGeometry {
    /// All triangles; object `o` owns `objects[o].first_triangle ..+ triangle_count`.
    pub triangles: Vec<TriangleRecord>,
    /// World-space unit normals at the three corners of each triangle: the mesh's
    /// vertex normals when it has them, else the geometric normal (zero for a
    /// degenerate triangle).
    pub normals: Vec<[Vec3; 3]>,
    pub objects: Vec<ObjectRecord>,
    pub lights: Vec<LightRecord>,
    /// World bounds of all finite vertices (min, max); a unit box around the
    /// origin for a scene without finite vertices.
    pub bounds: (Vec3, Vec3),
    /// Triangles with a NaN or infinite vertex. They stay in the table (ids must
    /// not shift) but no stage can hit them.
    pub non_finite_triangles: usize,
}

impl WorldGeometry {
    /// Transform every object of `scene` to world space.
    pub fn build(scene: &Scene) -> WorldGeometry {
        let mut g = WorldGeometry::default();
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        // Each mesh classified once, however many objects share it.
        let mut windings: Vec<Option<MeshWinding>> = vec![None; scene.meshes.len()];
        for (oi, obj) in scene.objects.iter().enumerate() {
            debug_assert_eq!(obj.id as usize, oi, "object ids must equal their index");
            let mesh = &scene.meshes[obj.mesh];
            let mat = &scene.materials[obj.material];
            let rt = obj.render_mode == RenderMode::RayTraced;
            let winding = windings[obj.mesh]
                .get_or_insert_with(|| MeshWinding::of_mesh(mesh))
                .transformed(Mat3::from_mat4(obj.transform).determinant());
            let tri_flags =
                if rt { TRI_RAY_TRACED } else { 0 } | if winding == MeshWinding::Inward { TRI_INWARD } else { 0 };
            let normal_matrix = Mat3::from_mat4(obj.transform).inverse().transpose();
            let world: Vec<Vec3> = mesh.positions.iter().map(|p| obj.transform.transform_point3(*p)).collect();
            for w in &world {
                if w.is_finite() {
                    lo = lo.min(*w);
                    hi = hi.max(*w);
                }
            }
            let first = g.triangles.len() as u32;
            for (ti, idx) in mesh.indices.iter().enumerate() {
                let [a, b, c] = idx.map(|i| world[i as usize]);
                if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                    g.non_finite_triangles += 1;
                }
                g.triangles.push(TriangleRecord {
                    v0: a.into(),
                    object: obj.id,
                    v1: b.into(),
                    triangle: ti as u32,
                    v2: c.into(),
                    flags: tri_flags,
                });
                let face = (b - a).cross(c - a).normalize_or_zero();
                let n = match &mesh.normals {
                    Some(ns) => idx.map(|i| {
                        let n = (normal_matrix * ns[i as usize]).normalize_or_zero();
                        if n == Vec3::ZERO {
                            face
                        } else {
                            n
                        }
                    }),
                    None => [face; 3],
                };
                g.normals.push(n);
            }
            let ior = match mat.kind {
                MaterialKind::Glass { ior } => ior,
                _ => 1.5,
            };
            g.objects.push(ObjectRecord {
                first_triangle: first,
                triangle_count: mesh.indices.len() as u32,
                flags: if rt { OBJ_RAY_TRACED } else { 0 },
                material_kind: mat.kind.code(),
                base_color: mat.base_color.into(),
                metallic: mat.metallic,
                roughness: mat.roughness,
                transmission: mat.transmission,
                ior,
                pad: 0,
            });
        }
        g.lights = scene.lights.iter().map(LightRecord::from_light).collect();
        g.bounds = if lo.x <= hi.x { (lo, hi) } else { (Vec3::splat(-1.0), Vec3::splat(1.0)) };
        if cfg!(debug_assertions) {
            g.validate().expect("world geometry invariants");
        }
        g
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Number of objects whose render mode is ray traced.
    pub fn ray_traced_object_count(&self) -> usize {
        self.objects.iter().filter(|o| o.flags & OBJ_RAY_TRACED != 0).count()
    }

    /// The global triangle index of (object, triangle within object).
    #[inline]
    pub fn global_triangle(&self, object: u32, triangle: u32) -> usize {
        (self.objects[object as usize].first_triangle + triangle) as usize
    }

    /// Length of the bounds' diagonal: the scene's scale for relative errors.
    pub fn scene_extent(&self) -> f32 {
        (self.bounds.1 - self.bounds.0).length()
    }

    /// Check every record and the object/triangle cross references.
    pub fn validate(&self) -> Result<(), String> {
        if self.normals.len() != self.triangles.len() {
            return Err("normals and triangles differ in length".into());
        }
        let mut next = 0u32;
        for (oi, o) in self.objects.iter().enumerate() {
            o.validate()?;
            if o.first_triangle != next {
                return Err(format!("object {oi}: triangles not contiguous"));
            }
            next += o.triangle_count;
        }
        if next as usize != self.triangles.len() {
            return Err("object triangle counts do not add up".into());
        }
        for t in &self.triangles {
            t.validate()?;
            let o = self.objects.get(t.object as usize).ok_or("triangle with unknown object")?;
            if t.triangle >= o.triangle_count {
                return Err(format!("triangle index out of its object's range: {t:?}"));
            }
        }
        for l in &self.lights {
            l.validate()?;
        }
        Ok(())
    }
}
