//! The world-space scene tables every stage reads: one [`TriangleRecord`] per
//! triangle (objects contiguous, in mesh order), per-corner world normals, one
//! [`ObjectRecord`] per object and one [`LightRecord`] per light (and, for a scene whose
//! emissive objects are lights, their triangles' [`EmitterRecord`] table, [`emitter_table`]);
//! and the scene's [`Environment`], which `bounce_shading` reads where secondary rays leave
//! the scene.
//!
//! Vertices are transformed to world space once, here, in f32, so the raster,
//! the BVH and reconstruction (on either backend) see the very same bits.

pub mod tangents;
mod triangles;

use std::collections::HashMap;
use std::sync::Arc;

use bytemuck::Zeroable;

use glam::{DVec3, Mat3, Mat4, Vec2, Vec3};

use crate::formats::{
    CameraRecord, EmitterRecord, LightRecord, MaterialRecord, ObjectRecord, SurfaceLayout, TextureSet, TriangleRecord,
    TriangleUvRecord, EMITTER_DOUBLE_SIDED, LIGHT_EMITTERS, MAT_ALPHA_TEST, MAT_ANY_TEXTURE, MAT_EMISSIVE,
    MAT_METALLIC_ROUGHNESS, MAT_NORMAL, MAT_OCCLUSION, MAT_TEXTURED, MAT_VERTEX_COLORS, OBJ_RAY_TRACED, TEXEL_LINEAR,
    TEXEL_SRGB, TRI_ALPHA_TEST, TRI_INWARD, TRI_RAY_TRACED,
};
use crate::kernels::ibl::AmbientLight;
use crate::kernels::texture::{triangle_lod_bias, SurfaceView};
use crate::scene::{Environment, Material, MaterialKind, Mesh, RenderMode, Scene, TextureBinding};

pub use triangles::{
    world_normals, world_record, ByReference, MeshSource, MeshWords, ObjectTransform, Placement, WorldTriangles,
};

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
    /// signed volume (divergence theorem, in f64) tells outward from inward. Two sorts:
    /// about 0.2 s for the 871k-triangle dragon on the CI machine, once per mesh.
    pub fn of_mesh(mesh: &Mesh) -> MeshWinding {
        // Canonical vertex ids: positions sorted by their bits (-0 as +0), equal ones merged.
        let key = |i: u32| mesh.positions[i as usize].to_array().map(|c| (c + 0.0).to_bits());
        let mut order: Vec<u32> = (0..mesh.positions.len() as u32).collect();
        order.sort_by_cached_key(|&i| key(i));
        let mut canon = vec![0u32; mesh.positions.len()];
        let mut id = 0u32;
        for (k, &i) in order.iter().enumerate() {
            if k > 0 && key(order[k - 1]) != key(i) {
                id += 1;
            }
            canon[i as usize] = id;
        }
        // Every directed edge as (unordered pair, direction bit), sorted: each pair must have
        // as many edges one way as the other (a cycle). Sorting, not hashing: the dragon's
        // 2.6 million edges sort faster than they scatter into a hash table.
        let mut edges: Vec<u64> = Vec::with_capacity(mesh.indices.len() * 3);
        for idx in &mesh.indices {
            if idx.iter().any(|&i| i as usize >= canon.len()) {
                return MeshWinding::Open;
            }
            let c = idx.map(|i| canon[i as usize]);
            for (a, b) in [(c[0], c[1]), (c[1], c[2]), (c[2], c[0])] {
                if a != b {
                    edges.push((a.min(b) as u64) << 33 | (a.max(b) as u64) << 1 | (a < b) as u64);
                }
            }
        }
        if edges.is_empty() {
            return MeshWinding::Open;
        }
        edges.sort_unstable();
        let mut run = 0usize;
        while run < edges.len() {
            let pair = edges[run] >> 1;
            let end = run + edges[run..].iter().take_while(|&&e| e >> 1 == pair).count();
            let forward = edges[run..end].iter().filter(|&&e| e & 1 == 1).count();
            if 2 * forward != end - run {
                return MeshWinding::Open;
            }
            run = end;
        }
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        let mut volume = 0.0f64;
        // Relative to one of its vertices (a closed surface's volume does not depend on the
        // point), so a mesh modelled far from its origin does not cancel its volume away.
        let o = mesh.positions[mesh.indices[0][0] as usize].as_dvec3();
        for idx in &mesh.indices {
            let [a, b, c] = idx.map(|i| mesh.positions[i as usize].as_dvec3() - o);
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
    /// All triangles and their world-space unit normals at the three corners (the mesh's
    /// vertex normals when it has them, else the geometric normal, zero for a degenerate
    /// triangle); object `o` owns `objects[o].first_triangle ..+ triangle_count`, stored
    /// or by reference ([`WorldTriangles`]).
    pub triangles: WorldTriangles,
    pub objects: Vec<ObjectRecord>,
    pub lights: Vec<LightRecord>,
    /// The emitter table of a scene whose emissive objects are lights
    /// ([`Scene::emissive_lights`], [`emitter_table`]); empty otherwise. Not empty exactly
    /// when `lights` ends with the [`LIGHT_EMITTERS`] record that samples it.
    pub emitters: Vec<EmitterRecord>,
    /// World bounds of the triangles' finite vertices (min, max); a unit box around the
    /// origin for a scene without finite vertices.
    pub bounds: (Vec3, Vec3),
    /// Triangles with a NaN or infinite vertex. They stay in the table (ids must
    /// not shift) but no stage can hit them.
    pub non_finite_triangles: usize,
    /// What secondary rays that leave the scene see ([`Scene::environment`]; a map is
    /// shared, not copied).
    pub environment: Environment,
    /// The frame's ambient light: the scene's constant level ([`Scene::ambient`]) and, for
    /// a scene shaded with the glTF model, its environment's image-based light
    /// ([`crate::kernels::ibl::AmbientLight`], computed here once).
    pub ambient: AmbientLight,
    /// Textures, vertex colours and alpha tests: empty tables for a scene that has none
    /// ([`SurfaceTables::is_empty`]).
    pub surface: SurfaceTables,
    /// Per object: its mesh's winding in the mesh's own space ([`MeshWinding::of_mesh`],
    /// two sorts of its vertices), kept so that moving an object
    /// ([`WorldGeometry::update_object`]) does not classify its mesh again.
    pub windings: Vec<MeshWinding>,
    /// Per object: the bounds of its finite world vertices and its triangles with a
    /// non-finite one, so that moving an object rescans only it.
    pub extents: Vec<ObjectExtent>,
}

/// The world-space extent of one object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectExtent {
    /// Bounds of the finite vertices of its triangles (`lo > hi` when there is none).
    pub lo: Vec3,
    pub hi: Vec3,
    /// Triangles with a NaN or infinite vertex.
    pub non_finite_triangles: usize,
}

impl Default for ObjectExtent {
    fn default() -> Self {
        ObjectExtent { lo: Vec3::splat(f32::INFINITY), hi: Vec3::splat(f32::NEG_INFINITY), non_finite_triangles: 0 }
    }
}

impl ObjectExtent {
    /// The extent of `mesh` placed by `to_world`: [`ObjectExtent::of`] the placed
    /// positions, bit for bit (the same `transform_point3`, and min and max are exact and
    /// do not depend on order). When every position is used and lands finite, one pass
    /// over the positions that keeps none of them (a moved object by reference costs no
    /// allocation and no pass over its triangles); otherwise the placed positions are made
    /// and [`ObjectExtent::of`] decides.
    pub fn of_placed(mesh: &MeshSource, to_world: &Mat4) -> ObjectExtent {
        if mesh.every_vertex_used {
            let mut e = ObjectExtent::default();
            let mut finite = true;
            for p in &mesh.positions {
                let v = to_world.transform_point3(*p);
                finite &= v.is_finite();
                e.lo = e.lo.min(v);
                e.hi = e.hi.max(v);
            }
            if finite {
                return e;
            }
        }
        let world: Vec<Vec3> = mesh.positions.iter().map(|p| to_world.transform_point3(*p)).collect();
        ObjectExtent::of(&world, &mesh.indices)
    }

    /// The extent of triangles `indices` over world vertices `world`.
    pub fn of(world: &[Vec3], indices: &[[u32; 3]]) -> ObjectExtent {
        let mut e = ObjectExtent::default();
        if world.iter().all(|v| v.is_finite()) {
            // Every vertex finite (the common case): the bounds of those the triangles use.
            let mut used = vec![false; world.len()];
            for idx in indices {
                for &i in idx {
                    used[i as usize] = true;
                }
            }
            for (v, _) in world.iter().zip(&used).filter(|(_, &u)| u) {
                e.lo = e.lo.min(*v);
                e.hi = e.hi.max(*v);
            }
            return e;
        }
        for idx in indices {
            let mut finite = true;
            for &i in idx {
                let v = world[i as usize];
                if v.is_finite() {
                    e.lo = e.lo.min(v);
                    e.hi = e.hi.max(v);
                } else {
                    finite = false;
                }
            }
            e.non_finite_triangles += !finite as usize;
        }
        e
    }
}

/// What materials add to the plain colour of [`ObjectRecord`]: built only for a scene
/// whose materials use textures, vertex colours or alpha tests; each table is empty when
/// nothing needs it (a frame then binds and reads none of them).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurfaceTables {
    /// The sampled textures, one per (image, sampler) pair in use.
    pub textures: TextureSet,
    /// One per object (indexed by object id); empty when no object needs one.
    pub materials: Vec<MaterialRecord>,
    /// One per triangle when any object is textured (zeros for untextured ones).
    pub uvs: Vec<TriangleUvRecord>,
    /// The vertex colours (linear RGBA) at the three corners of each triangle when any
    /// object has them (opaque white for the others).
    pub colors: Vec<[[f32; 4]; 3]>,
    /// The world-space tangents at the three corners of each triangle (`xyz` unit, `w` the
    /// bitangent's sign) when any object is normal-mapped ([`tangents`]; zeros for the
    /// others).
    pub tangents: Vec<[[f32; 4]; 3]>,
}

impl SurfaceTables {
    /// The tables as the kernels read them.
    pub fn view(&self) -> SurfaceView<'_> {
        SurfaceView {
            materials: &self.materials,
            uvs: &self.uvs,
            colors: &self.colors,
            tangents: &self.tangents,
            textures: &self.textures.records,
            texels: &self.textures.texels,
        }
    }

    /// No material of the scene uses a texture, vertex colours or an alpha test.
    pub fn is_empty(&self) -> bool {
        self.materials.is_empty()
    }

    /// Whether some object is alpha-tested.
    pub fn alpha_tested(&self) -> bool {
        self.view().alpha_tested()
    }

    /// Where each table lies when packed into one buffer of words ([`SurfaceLayout`]);
    /// `None` when they hold 2^32 words or more.
    pub fn layout(&self) -> Option<SurfaceLayout> {
        SurfaceLayout::new(crate::formats::TableCounts {
            materials: self.materials.len(),
            uvs: self.uvs.len(),
            colors: self.colors.len(),
            tangents: self.tangents.len(),
            textures: self.textures.records.len(),
            texels: self.textures.texels.len(),
        })
    }

    /// The tables packed into one buffer of words as [`SurfaceLayout`] says (the GPU binds
    /// them so), with their layout; `None` as [`SurfaceTables::layout`]. `objects` are the
    /// scene's (their first triangles are packed beside the materials; ignored without
    /// surface tables).
    pub fn packed(&self, objects: &[ObjectRecord]) -> Option<(SurfaceLayout, Vec<u32>)> {
        let layout = self.layout()?;
        let mut words = Vec::with_capacity(layout.words as usize);
        words.extend_from_slice(bytemuck::cast_slice(&self.materials));
        if !self.materials.is_empty() {
            assert_eq!(objects.len(), self.materials.len(), "one material record per object");
            words.extend(objects.iter().map(|o| o.first_triangle));
        }
        words.extend_from_slice(bytemuck::cast_slice(&self.uvs));
        words.extend_from_slice(bytemuck::cast_slice(&self.colors));
        words.extend_from_slice(bytemuck::cast_slice(&self.tangents));
        words.extend_from_slice(bytemuck::cast_slice(&self.textures.records));
        if !self.textures.is_empty() {
            words.extend_from_slice(bytemuck::cast_slice(crate::kernels::texture::srgb8_table()));
        }
        words.extend_from_slice(&self.textures.texels);
        debug_assert_eq!(words.len(), layout.words as usize);
        Some((layout, words))
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.textures.bytes()
            + self.materials.len() * std::mem::size_of::<MaterialRecord>()
            + self.uvs.len() * std::mem::size_of::<TriangleUvRecord>()
            + (self.colors.len() + self.tangents.len()) * std::mem::size_of::<[[f32; 4]; 3]>()
    }
}

/// A material's textures that a mesh can sample (it has their coordinate set), each with
/// its `MAT_*` flag and texel encoding, in [`crate::kernels::texture::Materials::at`]'s
/// order; the first is the one whose coordinates and size the triangles' records use.
fn material_textures(material: &Material, mesh: &Mesh) -> Vec<(u32, TextureBinding, u32)> {
    let maps = &material.maps;
    [
        (MAT_TEXTURED, material.base_color_texture, TEXEL_SRGB),
        (MAT_METALLIC_ROUGHNESS, maps.metallic_roughness, TEXEL_LINEAR),
        (MAT_OCCLUSION, maps.occlusion, TEXEL_LINEAR),
        (MAT_EMISSIVE, maps.emissive, TEXEL_SRGB),
        (MAT_NORMAL, maps.normal, TEXEL_LINEAR),
    ]
    .into_iter()
    .filter_map(|(flag, binding, encoding)| binding.map(|b| (flag, b, encoding)))
    .filter(|(_, b, _)| mesh.attributes.tex_coords.get(b.tex_coord as usize).is_some_and(Option::is_some))
    .collect()
}

/// What an object's material and mesh ask of [`SurfaceTables`].
fn material_flags(material: &Material, mesh: &Mesh) -> u32 {
    material_textures(material, mesh).iter().fold(0, |f, (flag, _, _)| f | flag)
        | if mesh.attributes.colors.is_some() { MAT_VERTEX_COLORS } else { 0 }
        | if material.alpha_mode.cutoff().is_some() { MAT_ALPHA_TEST } else { 0 }
}

/// Build the [`SurfaceTables`] of `scene`, given the triangles already in world space.
fn surface_tables(scene: &Scene, triangles: &WorldTriangles) -> SurfaceTables {
    let flags: Vec<u32> =
        scene.objects.iter().map(|o| material_flags(&scene.materials[o.material], &scene.meshes[o.mesh])).collect();
    let mut t = SurfaceTables::default();
    if flags.iter().all(|&f| f == 0) {
        return t;
    }
    let any = |bit: u32| flags.iter().any(|&f| f & bit != 0);
    let (textured, colored, normal_mapped) = (any(MAT_ANY_TEXTURE), any(MAT_VERTEX_COLORS), any(MAT_NORMAL));
    if textured {
        t.uvs = vec![TriangleUvRecord::default(); triangles.len()];
    }
    if colored {
        t.colors = vec![[[1.0; 4]; 3]; triangles.len()];
    }
    if normal_mapped {
        t.tangents = vec![[[0.0; 4]; 3]; triangles.len()];
    }
    // Each mesh's object-space tangents for a coordinate set, made once however many
    // objects draw it.
    let mut mesh_tangents: HashMap<(usize, u32), Vec<[[f32; 4]; 3]>> = HashMap::new();
    let mut records: HashMap<(usize, crate::scene::Sampler, u32), u32> = HashMap::new();
    let mut first = 0usize;
    for (obj, &f) in scene.objects.iter().zip(&flags) {
        let (mesh, material) = (&scene.meshes[obj.mesh], &scene.materials[obj.material]);
        let range = first..first + mesh.indices.len();
        first = range.end;
        let mut record = MaterialRecord {
            flags: f,
            base_alpha: material.base_alpha,
            alpha_cutoff: material.alpha_mode.cutoff().unwrap_or(0.0),
            occlusion_strength: material.maps.occlusion_strength,
            normal_scale: material.maps.normal_scale,
            ..MaterialRecord::PLAIN
        };
        let maps = material_textures(material, mesh);
        for &(flag, binding, encoding) in &maps {
            let image = &scene.textures[binding.image];
            let index = *records
                .entry((binding.image, binding.sampler, encoding))
                .or_insert_with(|| t.textures.add(image, &binding.sampler, encoding));
            match flag {
                MAT_TEXTURED => record.texture = index,
                MAT_METALLIC_ROUGHNESS => record.metallic_roughness = index,
                MAT_OCCLUSION => record.occlusion = index,
                MAT_EMISSIVE => record.emissive = index,
                _ => record.normal = index,
            }
            // The first texture (`maps` is in `Materials::at`'s order) sets the coordinates.
            if record.uv_texture == crate::formats::INVALID_ID {
                record.uv_texture = index;
            }
            if flag == MAT_NORMAL {
                let corners = mesh_tangents
                    .entry((obj.mesh, binding.tex_coord))
                    .or_insert_with(|| tangents::mesh_tangents(mesh, binding.tex_coord));
                tangents::world_tangents(&mut t.tangents[range.clone()], corners, &obj.transform);
            }
        }
        if let Some(&(_, binding, _)) = maps.first() {
            let image = &scene.textures[binding.image];
            let coords = mesh.attributes.tex_coords[binding.tex_coord as usize].as_ref().expect("filtered on it");
            let mut world = Vec::new();
            triangles.fill(range.clone(), &mut world);
            fill_uvs(&mut t.uvs[range.clone()], mesh, &world, coords, &binding.transform, image);
        }
        if let Some(colors) = &mesh.attributes.colors {
            for (out, idx) in t.colors[range.clone()].iter_mut().zip(&mesh.indices) {
                *out = idx.map(|i| colors[i as usize]);
            }
        }
        t.materials.push(record);
    }
    t
}

/// The texture coordinates of an object's triangles (transformed) and their level-of-detail
/// constants.
fn fill_uvs(
    out: &mut [TriangleUvRecord],
    mesh: &Mesh,
    triangles: &[TriangleRecord],
    coords: &[Vec2],
    transform: &crate::scene::UvTransform,
    image: &crate::scene::TextureImage,
) {
    for ((out, idx), tri) in out.iter_mut().zip(&mesh.indices).zip(triangles) {
        let uv = idx.map(|i| transform.apply(coords[i as usize]));
        *out = TriangleUvRecord {
            uv0: uv[0].into(),
            uv1: uv[1].into(),
            uv2: uv[2].into(),
            lod_bias: triangle_lod_bias(tri.vertices(), uv, image.width, image.height),
            pad: 0,
        };
    }
}

/// The light records of `scene` as the frame's tables hold them: its lights, then the
/// [`LIGHT_EMITTERS`] record where the emitter table `emitters` is not empty.
pub fn light_records(scene: &Scene, emitters: &[EmitterRecord]) -> Vec<LightRecord> {
    let mut lights: Vec<LightRecord> = scene.lights.iter().map(LightRecord::from_light).collect();
    if !emitters.is_empty() {
        lights.push(LightRecord::emitters());
    }
    lights
}

/// Points per side of the barycentric lattice an emissive texture is averaged over, per
/// triangle: the centroids of the `EMITTER_TEXTURE_GRID^2` equal sub-triangles of the
/// triangle's regular subdivision (an exact stratification of its area).
pub const EMITTER_TEXTURE_GRID: u32 = 4;

/// Texture points averaged per emissive triangle ([`EMITTER_TEXTURE_GRID`] squared).
pub const EMITTER_TEXTURE_POINTS: u32 = EMITTER_TEXTURE_GRID * EMITTER_TEXTURE_GRID;

/// Rec. 709 luminance weights of linear RGB: how an emitter's radiance counts towards
/// its picking probability (the cdf of [`EmitterRecord`]).
pub const LUMINANCE_WEIGHTS: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// The barycentrics `(u, v)` (weights of v1 and v2) of the [`EMITTER_TEXTURE_POINTS`]
/// lattice points: the centroid of each sub-triangle of the regular subdivision into
/// `n^2` (`n` = [`EMITTER_TEXTURE_GRID`]), upward ones then downward ones.
pub fn emitter_texture_points() -> Vec<(f32, f32)> {
    let n = EMITTER_TEXTURE_GRID;
    let f = n as f32;
    let mut points = Vec::with_capacity(EMITTER_TEXTURE_POINTS as usize);
    for i in 0..n {
        for j in 0..n - i {
            points.push(((i as f32 + 1.0 / 3.0) / f, (j as f32 + 1.0 / 3.0) / f));
            if i + j + 1 < n {
                points.push(((i as f32 + 2.0 / 3.0) / f, (j as f32 + 2.0 / 3.0) / f));
            }
        }
    }
    points
}

/// The mean of an emissive texture's RGB over a triangle whose texture coordinates are
/// `uv` (in the table, transformed): the texture at every [`emitter_texture_points`] point,
/// each at the level of detail of its share of the triangle's texel area (`0.5 log2(area /
/// points)`, level 0's texels), so the points together filter the whole triangle; in f64.
/// Computed once when the scene is prepared, on the CPU.
fn mean_texture(view: &crate::kernels::texture::SurfaceView, tex: u32, uv: &TriangleUvRecord) -> [f64; 3] {
    use crate::kernels::texture::{interpolate_uv, sample_texture};
    let record = &view.textures[tex as usize];
    let scale = Vec2::new(record.width as f32, record.height as f32);
    let (a, b) = ((Vec2::from(uv.uv1) - Vec2::from(uv.uv0)) * scale, (Vec2::from(uv.uv2) - Vec2::from(uv.uv0)) * scale);
    let texels = 0.5 * (a.x as f64 * b.y as f64 - a.y as f64 * b.x as f64).abs();
    let lod = match texels / EMITTER_TEXTURE_POINTS as f64 {
        t if t.is_finite() && t > 1.0 => (0.5 * t.log2()) as f32,
        _ => 0.0,
    };
    let points = emitter_texture_points();
    let mut sum = [0.0f64; 3];
    for &(u, v) in &points {
        let texel = sample_texture(view.texels, record, interpolate_uv(uv, u, v), lod);
        for (s, t) in sum.iter_mut().zip(texel) {
            *s += t as f64;
        }
    }
    sum.map(|s| s / points.len() as f64)
}

/// The emitter table of `scene` over its world tables `g` (triangles, object records and
/// surface tables already built): empty unless [`Scene::emissive_lights`]; else every
/// triangle of every object whose record's `emissive` is non-zero, in world space (an
/// instance's by its transform), in triangle order, with its radiance (the emission, times
/// the emissive texture's mean over the triangle where the material has one:
/// [`EMITTER_TEXTURE_POINTS`] points) and the cumulative probability of picking it, in
/// proportion to its power `area x luminance(radiance)` ([`LUMINANCE_WEIGHTS`]), summed in
/// f64 and rounded once to f32, the last exactly 1. Triangles of zero (or non-finite)
/// power are left out.
pub fn emitter_table(scene: &Scene, g: &WorldGeometry) -> Vec<EmitterRecord> {
    if !scene.emissive_lights {
        return Vec::new();
    }
    let view = g.surface.view();
    let mut table = Vec::new();
    let mut tris = Vec::new();
    for (oi, o) in g.objects.iter().enumerate() {
        let emissive = Vec3::from(o.emissive);
        if emissive == Vec3::ZERO {
            continue;
        }
        let double_sided = scene.materials[scene.objects[oi].material].double_sided;
        let texture =
            view.materials.get(oi).filter(|m| m.flags & MAT_EMISSIVE != 0 && !view.uvs.is_empty()).map(|m| m.emissive);
        let first = o.first_triangle as usize;
        g.triangles.fill(first..first + o.triangle_count as usize, &mut tris);
        for (k, t) in tris.iter().enumerate() {
            let [v0, v1, v2] = t.vertices();
            let (e1, e2) = (v1 - v0, v2 - v0);
            let scale = match texture {
                Some(tex) => mean_texture(&view, tex, &view.uvs[first + k]),
                None => [1.0; 3],
            };
            let radiance = Vec3::new(
                (emissive.x as f64 * scale[0]) as f32,
                (emissive.y as f64 * scale[1]) as f32,
                (emissive.z as f64 * scale[2]) as f32,
            );
            table.push(EmitterRecord {
                v0: v0.into(),
                cdf: 0.0,
                e1: e1.into(),
                flags: if double_sided { EMITTER_DOUBLE_SIDED } else { 0 },
                e2: e2.into(),
                object: oi as u32,
                radiance: radiance.into(),
                triangle: t.triangle,
            });
        }
    }
    with_emitter_cdf(table)
}

/// An emitter's power up to a constant, what its picking probability is proportional to:
/// its area (`|e1 x e2| / 2`) times the luminance of its radiance ([`LUMINANCE_WEIGHTS`]),
/// in f64; 0 (or NaN) for one that emits nothing, infinite or NaN for non-finite vertices.
pub fn emitter_power(e: &EmitterRecord) -> f64 {
    let (e1, e2) = (Vec3::from(e.e1).as_dvec3(), Vec3::from(e.e2).as_dvec3());
    let area = 0.5 * e1.cross(e2).length();
    let luminance: f64 = (0..3).map(|c| LUMINANCE_WEIGHTS[c] * e.radiance[c] as f64).sum();
    area * luminance
}

/// `table` without its emitters of zero or non-finite power ([`emitter_power`]; non-finite
/// vertices too), each given its cumulative picking probability (`cdf`): the powers summed
/// in table order in f64, divided by their total, rounded once to f32 (so non-decreasing);
/// the last set to exactly 1.
pub fn with_emitter_cdf(mut table: Vec<EmitterRecord>) -> Vec<EmitterRecord> {
    let finite = |e: &EmitterRecord| [e.v0, e.e1, e.e2].iter().all(|v| Vec3::from(*v).is_finite());
    table.retain(|e| finite(e) && emitter_power(e) > 0.0 && emitter_power(e).is_finite());
    let total: f64 = table.iter().map(emitter_power).sum();
    let mut sum = 0.0f64;
    for e in table.iter_mut() {
        sum += emitter_power(e);
        e.cdf = (sum / total) as f32;
    }
    if let Some(last) = table.last_mut() {
        last.cdf = 1.0;
    }
    table
}

impl WorldGeometry {
    /// Transform every object of `scene` to world space, every object stored.
    pub fn build(scene: &Scene) -> WorldGeometry {
        WorldGeometry::build_placed(scene, &[])
    }

    /// [`WorldGeometry::build`] with the objects flagged in `by_reference` (indexed by
    /// object id; shorter means false) kept by reference (`triangles`):
    /// their mesh once, however many objects draw it, and their transform; their records
    /// are made on read, the same bits as stored ones.
    pub fn build_placed(scene: &Scene, by_reference: &[bool]) -> WorldGeometry {
        let mut g = WorldGeometry::default();
        // Each mesh classified once, however many objects share it.
        let mut windings: Vec<Option<MeshWinding>> = vec![None; scene.meshes.len()];
        let mut mesh_slot: Vec<Option<u32>> = vec![None; scene.meshes.len()];
        let mut meshes = Vec::new();
        let mut placements = Vec::with_capacity(scene.objects.len());
        let mut counts = Vec::with_capacity(scene.objects.len());
        let mut first = 0u32;
        for (oi, obj) in scene.objects.iter().enumerate() {
            debug_assert_eq!(obj.id as usize, oi, "object ids must equal their index");
            let count = scene.meshes[obj.mesh].indices.len() as u32;
            let winding = *windings[obj.mesh].get_or_insert_with(|| MeshWinding::of_mesh(&scene.meshes[obj.mesh]));
            g.objects.push(ObjectRecord { first_triangle: first, triangle_count: count, ..ObjectRecord::zeroed() });
            g.windings.push(winding);
            first += count;
            counts.push(count);
            placements.push(by_reference.get(oi).copied().unwrap_or(false).then(|| {
                let mesh = *mesh_slot[obj.mesh].get_or_insert_with(|| {
                    meshes.push(Arc::new(MeshSource::of_mesh(&scene.meshes[obj.mesh])));
                    meshes.len() as u32 - 1
                });
                ByReference { mesh, transform: ObjectTransform::new(obj.transform), flags: 0 }
            }));
        }
        g.triangles = WorldTriangles::with_placements(&counts, placements, meshes);
        g.extents = vec![ObjectExtent::default(); scene.objects.len()];
        for oi in 0..scene.objects.len() {
            g.write_object(scene, oi, g.windings[oi]);
        }
        g.environment = scene.environment.clone();
        g.ambient = AmbientLight::of_scene(scene);
        g.surface = surface_tables(scene, &g.triangles);
        g.union_extents();
        g.emitters = emitter_table(scene, &g);
        g.lights = light_records(scene, &g.emitters);
        if cfg!(debug_assertions) {
            g.validate().expect("world geometry invariants");
        }
        g
    }

    /// Write object `oi`'s triangles, normals (or its reference), record and extent (its
    /// `first_triangle` already set) from the scene's current transform, material and
    /// render mode: the one writer of [`WorldGeometry::build`] and
    /// [`WorldGeometry::update_object`]. `winding` is the mesh's, in its own space.
    fn write_object(&mut self, scene: &Scene, oi: usize, winding: MeshWinding) {
        let obj = &scene.objects[oi];
        let mesh = &scene.meshes[obj.mesh];
        let mat = &scene.materials[obj.material];
        let rt = obj.render_mode == RenderMode::RayTraced;
        let winding = winding.transformed(Mat3::from_mat4(obj.transform).determinant());
        let masked = mat.alpha_mode.cutoff().is_some();
        let tri_flags = if rt { TRI_RAY_TRACED } else { 0 }
            | if winding == MeshWinding::Inward { TRI_INWARD } else { 0 }
            | if masked { TRI_ALPHA_TEST } else { 0 };
        let transform = ObjectTransform::new(obj.transform);
        let first = self.objects[oi].first_triangle;
        let count = mesh.indices.len() as u32;
        self.extents[oi] = match self.triangles.placement(oi as u32, first) {
            Placement::Stored { first_record } => {
                let world: Vec<Vec3> = mesh.positions.iter().map(|p| obj.transform.transform_point3(*p)).collect();
                let (tris, normals) = self.triangles.object_mut(first_record, count);
                for ((ti, idx), (tri, normals)) in mesh.indices.iter().enumerate().zip(tris.iter_mut().zip(normals)) {
                    let corners = idx.map(|i| world[i as usize]);
                    *tri = world_record(corners, obj.id, ti as u32, tri_flags);
                    *normals = world_normals(corners, *idx, mesh.normals.as_deref(), &transform.normal_matrix);
                }
                ObjectExtent::of(&world, &mesh.indices)
            }
            Placement::ByReference(r) => {
                self.triangles.set_reference(oi as u32, transform, tri_flags);
                ObjectExtent::of_placed(self.triangles.mesh(r.mesh), &obj.transform)
            }
        };
        let ior = match mat.kind {
            MaterialKind::Glass { ior } => ior,
            _ => 1.5,
        };
        self.objects[oi] = ObjectRecord {
            first_triangle: first,
            triangle_count: count,
            flags: if rt { OBJ_RAY_TRACED } else { 0 } | scene.shading.object_flags(),
            material_kind: mat.kind.code(),
            base_color: mat.base_color.into(),
            metallic: mat.metallic,
            roughness: mat.roughness,
            transmission: mat.transmission,
            ior,
            offset_error: 0.0,
            emissive: mat.emissive.into(),
            occlusion: 1.0,
        };
    }

    /// Rewrite object `object`'s tables after its transform or render mode changed in
    /// `scene` (the scene these tables were built from: same meshes and materials): its
    /// triangles and normals in place (or its reference), its record, its texture
    /// level-of-detail constants and the scene bounds. Nothing else is touched; the result
    /// equals [`WorldGeometry::build_placed`] of the changed scene. Costs one pass over the
    /// object's vertices and triangles (an object by reference whose mesh uses every
    /// vertex: one pass over its positions, kept nowhere, [`ObjectExtent::of_placed`]) plus
    /// one over the objects for the bounds.
    pub fn update_object(&mut self, scene: &Scene, object: u32) {
        self.update_objects(scene, &[object]);
    }

    /// After `scene.meshes[mesh]` got new vertex positions or normals (the same triangles):
    /// take the new mesh for the objects that draw it by reference and rewrite the tables
    /// of every object drawing it ([`WorldGeometry::update_objects`]).
    pub fn deform_mesh(&mut self, scene: &Scene, mesh: usize) {
        let users: Vec<u32> = scene.objects.iter().filter(|o| o.mesh == mesh).map(|o| o.id).collect();
        let mut refreshed = Vec::new();
        for &o in &users {
            if let Placement::ByReference(r) = self.triangles.placement(o, self.objects[o as usize].first_triangle) {
                if !refreshed.contains(&r.mesh) {
                    self.triangles.set_mesh(r.mesh, MeshSource::of_mesh(&scene.meshes[mesh]));
                    refreshed.push(r.mesh);
                }
            }
        }
        self.update_objects(scene, &users);
    }

    /// [`WorldGeometry::update_object`] for several objects: each object's tables
    /// rewritten, then the bounds (and the texture tables) once.
    pub fn update_objects(&mut self, scene: &Scene, objects: &[u32]) {
        for &object in objects {
            let oi = object as usize;
            self.write_object(scene, oi, self.windings[oi]);
        }
        self.union_extents();
        if !self.surface.uvs.is_empty() {
            self.surface = surface_tables(scene, &self.triangles);
        }
        if scene.emissive_lights {
            self.set_emitters(emitter_table(scene, self));
        }
        if cfg!(debug_assertions) {
            self.validate().expect("world geometry invariants");
        }
    }

    /// Take a new emitter table: the [`LIGHT_EMITTERS`] record follows the other lights
    /// exactly when it is not empty (the other records untouched).
    pub fn set_emitters(&mut self, emitters: Vec<EmitterRecord>) {
        self.lights.retain(|l| l.kind != LIGHT_EMITTERS);
        if !emitters.is_empty() {
            self.lights.push(LightRecord::emitters());
        }
        self.emitters = emitters;
    }

    /// Set what depends on every object's extent: the triangles with a NaN or infinite
    /// vertex (`non_finite_triangles`) and the bounds of the finite vertices (`bounds`; a
    /// unit box around the origin when there is none).
    fn union_extents(&mut self) {
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let mut non_finite = 0;
        for e in &self.extents {
            lo = lo.min(e.lo);
            hi = hi.max(e.hi);
            non_finite += e.non_finite_triangles;
        }
        self.non_finite_triangles = non_finite;
        self.bounds = if lo.x <= hi.x { (lo, hi) } else { (Vec3::splat(-1.0), Vec3::splat(1.0)) };
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The table as the traversals take it for their debug checks of leaf copies: the
    /// whole table when every object is stored, else empty (no check).
    pub fn traversal_table(&self) -> &[TriangleRecord] {
        self.triangles.as_slice().unwrap_or(&[])
    }

    /// The whole table as a slice by global id, for code that needs one (the accuracy
    /// lab's f64 references). Panics when some object is by reference: such a table is
    /// never whole in memory (build it with [`WorldGeometry::build`]).
    pub fn stored_table(&self) -> &[TriangleRecord] {
        self.triangles.as_slice().expect("a world table with every object stored (WorldGeometry::build)")
    }

    /// The objects whose triangles that show their interior the raster drops this frame
    /// ([`crate::kernels::raster::culls_interior`]), one bit per object (object `o` at bit
    /// `o % 32` of word `o / 32`, [`crate::kernels::raster::interior_cull_words`]): closed meshes ([`MeshWinding`] not
    /// open), without an alpha test (its holes show the inside) and without a non-finite
    /// vertex (the raster skips such triangles, which opens the surface), whose world
    /// bounds lie wholly in front of `camera`'s near plane
    /// ([`crate::kernels::raster::interior_hidden`]).
    pub fn interior_culls(&self, camera: &CameraRecord) -> Vec<u32> {
        let mut bits = vec![0u32; crate::kernels::raster::interior_cull_words(self.objects.len())];
        for (o, ((record, winding), extent)) in self.objects.iter().zip(&self.windings).zip(&self.extents).enumerate() {
            let closed = *winding != MeshWinding::Open && record.triangle_count > 0;
            if closed
                && extent.non_finite_triangles == 0
                && self.triangles.flags(record.first_triangle as usize) & TRI_ALPHA_TEST == 0
                && crate::kernels::raster::interior_hidden(camera, extent.lo.into(), extent.hi.into())
            {
                bits[o / 32] |= 1 << (o % 32);
            }
        }
        bits
    }

    /// The world record of global triangle `id` ([`WorldTriangles::get`]).
    #[inline]
    pub fn triangle(&self, id: usize) -> TriangleRecord {
        self.triangles.get(id)
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

    /// What shading knows of materials in a frame seen by `camera`: the objects, the
    /// surface tables and, when some object's colour varies over its surface, the frame's
    /// cone spread ([`crate::kernels::texture::camera_pixel_spread`]; 0 otherwise, so an
    /// untextured frame's rays carry zero cones as they did before textures).
    pub fn materials(&self, camera: &crate::formats::CameraRecord) -> crate::kernels::texture::Materials<'_> {
        let surface = self.surface.view();
        let spread = if surface.colour_varies() { crate::kernels::texture::camera_pixel_spread(camera) } else { 0.0 };
        crate::kernels::texture::Materials { objects: &self.objects, surface, spread }
    }

    /// Length of the bounds' diagonal: the scene's scale for relative errors.
    pub fn scene_extent(&self) -> f32 {
        (self.bounds.1 - self.bounds.0).length()
    }

    /// Check every record and the object/triangle cross references.
    pub fn validate(&self) -> Result<(), String> {
        if self.extents.len() != self.objects.len() {
            return Err("extents and objects differ in length".into());
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
        for t in self.triangles.iter() {
            t.validate()?;
            let o = self.objects.get(t.object as usize).ok_or("triangle with unknown object")?;
            if t.triangle >= o.triangle_count {
                return Err(format!("triangle index out of its object's range: {t:?}"));
            }
        }
        for l in &self.lights {
            l.validate()?;
        }
        let emitter_lights = self.lights.iter().filter(|l| l.kind == LIGHT_EMITTERS).count();
        if emitter_lights != (!self.emitters.is_empty()) as usize {
            return Err(format!(
                "{emitter_lights} emitter lights for an emitter table of {} triangles",
                self.emitters.len()
            ));
        }
        for (k, e) in self.emitters.iter().enumerate() {
            e.validate().map_err(|m| format!("emitter {k}: {m}"))?;
            if k > 0 && e.cdf < self.emitters[k - 1].cdf {
                return Err(format!("emitter {k}: its cdf decreases"));
            }
        }
        if self.emitters.last().is_some_and(|e| e.cdf != 1.0) {
            return Err("the emitter table's last cdf is not 1".into());
        }
        let s = &self.surface;
        if !s.is_empty() {
            s.textures.validate()?;
            if s.materials.len() != self.objects.len() {
                return Err("material records and objects differ in length".into());
            }
            for (k, m) in s.materials.iter().enumerate() {
                m.validate(s.textures.records.len()).map_err(|e| format!("object {k}: {e}"))?;
                let masked = m.flags & MAT_ALPHA_TEST != 0;
                let o = &self.objects[k];
                let mut tris = Vec::new();
                self.triangles
                    .fill(o.first_triangle as usize..(o.first_triangle + o.triangle_count) as usize, &mut tris);
                if tris.iter().any(|t| (t.flags & TRI_ALPHA_TEST != 0) != masked) {
                    return Err(format!("object {k}: triangle alpha-test flags disagree with its material"));
                }
            }
            for (len, what) in [
                (s.uvs.len(), "texture coordinates"),
                (s.colors.len(), "vertex colours"),
                (s.tangents.len(), "tangents"),
            ] {
                if len != 0 && len != self.triangles.len() {
                    return Err(format!("{what}: {len} records for {} triangles", self.triangles.len()));
                }
            }
        } else if self.triangles.iter().any(|t| t.flags & TRI_ALPHA_TEST != 0) {
            return Err("alpha-tested triangles in a scene without material records".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Material;
    use glam::Mat4;

    fn flipped(mesh: &Mesh) -> Mesh {
        Mesh { indices: mesh.indices.iter().map(|&[a, b, c]| [a, c, b]).collect(), ..mesh.clone() }
    }

    #[test]
    fn winding_tells_closed_outward_inward_and_open_meshes_apart() {
        // The built-in cube has 24 vertices (split per face): closed through equal positions.
        let cube = Mesh::cube("cube");
        assert_eq!(MeshWinding::of_mesh(&cube), MeshWinding::Outward);
        assert_eq!(MeshWinding::of_mesh(&flipped(&cube)), MeshWinding::Inward);
        assert_eq!(MeshWinding::of_mesh(&Mesh::uv_sphere("s", 16, 8)), MeshWinding::Outward);
        // Open: a grid, a cube missing a face, an inconsistently wound cube.
        assert_eq!(MeshWinding::of_mesh(&Mesh::grid("g", 4)), MeshWinding::Open);
        let mut holed = cube.clone();
        holed.indices.truncate(10);
        assert_eq!(MeshWinding::of_mesh(&holed), MeshWinding::Open);
        let mut mixed = cube.clone();
        mixed.indices[0] = [mixed.indices[0][0], mixed.indices[0][2], mixed.indices[0][1]];
        assert_eq!(MeshWinding::of_mesh(&mixed), MeshWinding::Open);
        // A sheet modelled twice back to back is a cycle enclosing nothing: open.
        let sheet = Mesh::grid("g", 2);
        let mut twice = sheet.clone();
        twice.indices.extend(flipped(&sheet).indices);
        assert_eq!(MeshWinding::of_mesh(&twice), MeshWinding::Open);
        // Out-of-range indices and empty meshes are open, not a panic.
        let mut bad = cube.clone();
        bad.indices[3] = [0, 1, 999];
        assert_eq!(MeshWinding::of_mesh(&bad), MeshWinding::Open);
        assert_eq!(MeshWinding::of_mesh(&Mesh::default()), MeshWinding::Open);
        // Far from its own origin (1e7: the terms about the origin would be 1e21).
        let far =
            Mesh { positions: cube.positions.iter().map(|p| *p + Vec3::new(1e7, -3e6, 5e6)).collect(), ..cube.clone() };
        assert_eq!(MeshWinding::of_mesh(&far), MeshWinding::Outward);
        assert_eq!(MeshWinding::of_mesh(&flipped(&far)), MeshWinding::Inward);
        // A mirror swaps outward and inward.
        assert_eq!(MeshWinding::Outward.transformed(-1.0), MeshWinding::Inward);
        assert_eq!(MeshWinding::Inward.transformed(-2.0), MeshWinding::Outward);
        assert_eq!(MeshWinding::Open.transformed(-1.0), MeshWinding::Open);
    }

    /// What a device reads of a table with objects by reference: the mesh words hold each
    /// shared mesh once (its positions, normals and triangles where the offsets say), and a
    /// placement per object names its stored records or its transform, normal matrix, mesh
    /// and flags; a table of stored objects has every placement stored from its first id.
    #[test]
    fn placements_and_mesh_words_describe_every_object() {
        let mut scene = Scene::default();
        let torus = Mesh::torus("torus", 1.0, 0.3, 8, 6);
        let mut material = Material::grey();
        material.alpha_mode = crate::scene::AlphaMode::Mask { cutoff: 0.5 };
        scene.add_object(Mesh::grid("floor", 2), Material::grey(), Mat4::IDENTITY, RenderMode::Raster);
        scene.add_object(torus.clone(), material, Mat4::from_translation(Vec3::X), RenderMode::RayTraced);
        scene.add_object(Mesh::cube("cube"), Material::grey(), Mat4::from_scale(Vec3::splat(-2.0)), RenderMode::Raster);
        let mut copy = scene.objects[1].clone();
        copy.id = 3;
        copy.transform = Mat4::from_rotation_z(0.5) * Mat4::from_scale(Vec3::new(1.0, -2.0, 3.0));
        scene.objects.push(copy);
        let g = WorldGeometry::build_placed(&scene, &[false, true, false, true]);
        let (words, meshes) = g.triangles.mesh_words().expect("a small table");
        assert_eq!(meshes.len(), 1, "the torus once, for both of its objects");
        assert_eq!(words.len(), g.triangles.mesh_word_count());
        let m = meshes[0];
        let vec3 = |first: u32, i: usize| {
            Vec3::from_array(std::array::from_fn(|k| f32::from_bits(words[first as usize + 3 * i + k])))
        };
        assert!(torus.positions.iter().enumerate().all(|(i, p)| vec3(m.positions, i) == *p));
        let normals = torus.normals.as_ref().expect("the torus has normals");
        assert!(normals.iter().enumerate().all(|(i, n)| vec3(m.normals, i) == *n));
        let indices = &words[m.indices as usize..];
        assert!(torus.indices.iter().flatten().zip(indices).all(|(a, b)| a == b));
        let mut stored_records = 0;
        for (o, r) in g.objects.iter().enumerate() {
            let p = g.triangles.placement_record(o as u32, r.first_triangle, r.triangle_count, &meshes);
            assert_eq!(p.validate(), Ok(()));
            assert_eq!((p.first_triangle, p.triangle_count), (r.first_triangle, r.triangle_count));
            assert_eq!(p.flags, g.triangles.flags(r.first_triangle as usize), "object {o}");
            assert_eq!(p.by_reference(), o % 2 == 1, "object {o}");
            if p.by_reference() {
                let t = ObjectTransform::new(scene.objects[o].transform);
                assert_eq!(Vec3::from(p.to_world_w), t.to_world.w_axis.truncate());
                assert_eq!(Vec3::from(p.normal_y), t.normal_matrix.y_axis);
                assert_eq!((p.mesh_indices, p.mesh_positions, p.mesh_normals), (m.indices, m.positions, m.normals));
            } else {
                assert_eq!(p.first_record, stored_records, "object {o}: stored after the stored objects before it");
                stored_records += r.triangle_count;
            }
        }
        assert_eq!(g.triangles.stored_records().len(), stored_records as usize);
        assert_eq!(g.triangles.stored_normals().len(), stored_records as usize);
        // Where a stored triangle's record and normals lie (what the fused tiles prefetch):
        // the very values `get` and `normals` give; none for an object by reference.
        for (o, r) in g.objects.iter().enumerate() {
            for id in (r.first_triangle..r.first_triangle + r.triangle_count).map(|i| i as usize) {
                match g.triangles.stored_at(id) {
                    Some((record, normals)) => {
                        assert!(o % 2 == 0, "object {o} is by reference");
                        assert_eq!(bytemuck::bytes_of(record), bytemuck::bytes_of(&g.triangles.get(id)));
                        assert_eq!(*normals, g.triangles.normals(id), "triangle {id}");
                    }
                    None => assert!(o % 2 == 1, "object {o} is stored"),
                }
            }
        }
        let all_stored = WorldGeometry::build(&scene);
        for (o, r) in all_stored.objects.iter().enumerate() {
            let p = all_stored.triangles.placement_record(o as u32, r.first_triangle, r.triangle_count, &[]);
            assert_eq!((p.by_reference(), p.first_record), (false, r.first_triangle));
        }
    }

    /// An object by reference gets the extent its stored copy gets, bit for bit, also on
    /// the paths that cannot take the one pass over the placed positions: a mesh with a
    /// vertex no triangle uses (far away: it must not count), one with a vertex that lands
    /// non-finite; and a move keeps them equal. (Indices out of range never get here: the
    /// scene's meshes are checked when loaded.)
    #[test]
    fn objects_by_reference_have_the_extents_of_stored_ones() {
        let sphere = Mesh::uv_sphere("sphere", 12, 6);
        let mut unused = sphere.clone();
        unused.positions.push(Vec3::splat(1e6));
        let mut non_finite = Mesh::cube("cube");
        non_finite.positions[3] = Vec3::new(f32::NAN, 0.0, 0.0);
        let mut scene = Scene::default();
        let place = |k: f32| {
            Mat4::from_scale_rotation_translation(
                Vec3::new(-0.5, 2.0, 0.25 * k),
                glam::Quat::from_rotation_y(0.3 * k),
                Vec3::new(3.0 * k, -1.0, 1e4),
            )
        };
        for (k, mesh) in [sphere, unused, non_finite].into_iter().enumerate() {
            scene.add_object(mesh, Material::grey(), place(k as f32 + 1.0), RenderMode::RayTraced);
        }
        let stored = WorldGeometry::build(&scene);
        let mut by_reference = WorldGeometry::build_placed(&scene, &[true; 3]);
        assert!(by_reference.triangles.has_references());
        let same = |a: &WorldGeometry, b: &WorldGeometry| {
            for (x, y) in a.extents.iter().zip(&b.extents) {
                assert_eq!(
                    (x.lo.to_array().map(f32::to_bits), x.hi.to_array().map(f32::to_bits)),
                    (y.lo.to_array().map(f32::to_bits), y.hi.to_array().map(f32::to_bits))
                );
                assert_eq!(x.non_finite_triangles, y.non_finite_triangles);
            }
            assert_eq!(a.bounds, b.bounds);
        };
        same(&stored, &by_reference);
        assert!(stored.extents[1].hi.x < 1e5, "the unused far vertex does not count");
        assert!(stored.extents[2].non_finite_triangles > 0);
        for o in &mut scene.objects {
            o.transform = Mat4::from_rotation_x(0.4) * o.transform;
        }
        by_reference.update_objects(&scene, &[0, 1, 2]);
        same(&WorldGeometry::build(&scene), &by_reference);
    }

    #[test]
    fn inward_closed_meshes_flag_their_triangles() {
        let mut scene = Scene::default();
        let cube = Mesh::cube("cube");
        scene.add_object(cube.clone(), Material::grey(), Mat4::IDENTITY, RenderMode::Raster);
        scene.add_object(flipped(&cube), Material::grey(), Mat4::IDENTITY, RenderMode::RayTraced);
        // Mirrored by its transform: inward becomes outward.
        scene.add_object(
            flipped(&cube),
            Material::grey(),
            Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0)),
            RenderMode::Raster,
        );
        scene.add_object(Mesh::grid("g", 2), Material::grey(), Mat4::IDENTITY, RenderMode::Raster);
        let g = WorldGeometry::build(&scene);
        let inward: Vec<bool> = g
            .objects
            .iter()
            .map(|o| {
                let mut tris = Vec::new();
                g.triangles.fill(o.first_triangle as usize..(o.first_triangle + o.triangle_count) as usize, &mut tris);
                assert!(tris.iter().all(|t| t.flags & TRI_INWARD == tris[0].flags & TRI_INWARD));
                tris[0].flags & TRI_INWARD != 0
            })
            .collect();
        assert_eq!(inward, vec![false, true, false, false]);
        assert!(g.triangles.iter().filter(|t| t.object == 1).all(|t| t.flags & TRI_RAY_TRACED != 0));
    }
}
