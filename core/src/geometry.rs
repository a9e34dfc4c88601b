//! The world-space scene tables every stage reads: one [`TriangleRecord`] per
//! triangle (objects contiguous, in mesh order), per-corner world normals, one
//! [`ObjectRecord`] per object and one [`LightRecord`] per light.
//!
//! Vertices are transformed to world space once, here, in f32, so the raster,
//! the BVH and reconstruction (on either backend) see the very same bits.

use glam::{Mat3, Vec3};

use crate::formats::{LightRecord, ObjectRecord, TriangleRecord, OBJ_RAY_TRACED, TRI_RAY_TRACED};
use crate::scene::{MaterialKind, RenderMode, Scene};

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
        for (oi, obj) in scene.objects.iter().enumerate() {
            debug_assert_eq!(obj.id as usize, oi, "object ids must equal their index");
            let mesh = &scene.meshes[obj.mesh];
            let mat = &scene.materials[obj.material];
            let rt = obj.render_mode == RenderMode::RayTraced;
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
                    flags: if rt { TRI_RAY_TRACED } else { 0 },
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
