//! The GPU buffers of a scene and of a frame. Created once per scene and once
//! per image size and count of shadow-mask slots ([`SlotParams`]), reused across frames;
//! every stage binds
//! these by name. Element layouts are the core formats (documented to the byte
//! in [`hyrt_core::formats`]) unless said otherwise here.

use hyrt_core::formats::{
    AmbientLightRecord, BvhNode, CameraRecord, EmitterRecord, EnvironmentRecord, GBufferTexel, HitRecord,
    InstanceRecord, LightRecord, ListParams, ObjectRecord, PlacementRecord, RayRecord, SurfaceRecord, TriangleRecord,
};
use hyrt_core::frame::{PreparedScene, SceneChanges};
use hyrt_core::geometry::MeshWords;
use hyrt_core::kernels::soft_shadow::Lights;
use hyrt_core::plan::{BounceBuffer, FrameBuffer, FramePlan};

use crate::band::Band;
use crate::gpu_buffer::{storage, upload};
use crate::paging::{PagedBuffer, Table, TablePages};
use crate::texture::{Specialization, SurfaceBuffers};
use crate::{GpuContext, GpuError};

/// The per-frame uniform parameters, defined in [`hyrt_core::formats`] (with the
/// other records the shaders declare); re-exported at their old path.
pub use hyrt_core::formats::FrameParams;

/// The shadow-mask slots of a frame as the GPU stages read them (one uniform buffer,
/// [`FrameBuffers::slot_params`]): a surface's mask holds `slots` codes, one per point,
/// spot or directional light, [`LightRecord::samples`] per area light (in light order),
/// then the ambient occlusion's rays ([`hyrt_core::kernels::soft_shadow`]); the lights'
/// take the first `light_slots`. A frame without area lights and ambient occlusion has
/// one slot per light: `slots == light_slots ==` its light count (the paper's mask).
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `slots` | u32 | slots per surface ([`FramePlan::lights`]) |
/// | 4 | `light_slots` | u32 | slots of the lights ([`hyrt_core::kernels::soft_shadow::lights_slots`]): the first ambient-occlusion slot |
/// | 8 | `channels` | u32 | the denoised channels per pixel ([`FramePlan::visibility_channels`]: one per area light, then one for the ambient occlusion); read where the frame denoises (`shadow_denoise`, [`FrameBuffer::Visibility`]) |
/// | 12 | `emitters` | u32 | the length of the frame's emitter table ([`hyrt_core::geometry::WorldGeometry::emitters`], which its [`hyrt_core::formats::LIGHT_EMITTERS`] light samples), packed into the lights' binding after the records ([`SceneBuffers::lights`]); 0 without one |
///
/// 16 bytes. Defined here, not with the core records: only the GPU stages read it (the
/// CPU backend walks [`hyrt_core::kernels::soft_shadow::Slots`]). A uniform, and no slot
/// table: `rt_shading` and `raster_shading` already bind 8 storage buffers, WebGPU's
/// default limit per shader stage, and `compaction` 7 (the scan's 3 among them), so the
/// stages walk the frame's light records (each area light's `samples`) to a slot's light
/// instead of reading a table, and no stage binds a storage buffer more than before area
/// lights (the device's limits are requested as before, `GpuContext::new`); for the same
/// reason the emitter table travels in the lights' binding.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SlotParams {
    pub slots: u32,
    pub light_slots: u32,
    pub channels: u32,
    pub emitters: u32,
}

impl SlotParams {
    /// The slots of a frame with `lights` (the frame's records: area lights carry their
    /// samples; with the emitter table, whose length it holds) and `ao_samples` occlusion
    /// rays per surface.
    pub fn of<'a>(lights: impl Into<Lights<'a>>, ao_samples: u32) -> SlotParams {
        let lights = lights.into();
        let light_slots = hyrt_core::kernels::soft_shadow::lights_slots(&lights) as u32;
        let channels = lights.iter().filter(|l| l.is_area()).count() as u32 + (ao_samples > 0) as u32;
        let emitters = lights.emitters.len() as u32;
        SlotParams { slots: light_slots + ao_samples, light_slots, channels, emitters }
    }

    /// One slot per light: `light_count` point, spot or directional lights, no occlusion.
    pub fn per_light(light_count: u32) -> SlotParams {
        SlotParams { slots: light_count, light_slots: light_count, channels: 0, emitters: 0 }
    }
}

impl hyrt_core::formats::wgsl::WgslStruct for SlotParams {
    const NAME: &'static str = "SlotParams";

    fn fields() -> Vec<hyrt_core::formats::wgsl::Field> {
        use hyrt_core::formats::wgsl::{field_type, Field};
        vec![
            Field { name: "slots", ty: field_type::<Self, _>(|r| &r.slots), offset: std::mem::offset_of!(Self, slots) },
            Field {
                name: "light_slots",
                ty: field_type::<Self, _>(|r| &r.light_slots),
                offset: std::mem::offset_of!(Self, light_slots),
            },
            Field {
                name: "channels",
                ty: field_type::<Self, _>(|r| &r.channels),
                offset: std::mem::offset_of!(Self, channels),
            },
            Field {
                name: "emitters",
                ty: field_type::<Self, _>(|r| &r.emitters),
                offset: std::mem::offset_of!(Self, emitters),
            },
        ]
    }
}

/// The room of the ray lists, defined in [`crate::band`] (which sizes bands by it);
/// re-exported at their old path.
pub use crate::band::{BounceRoom, Room};

/// Scene tables on the GPU (from a [`PreparedScene`]; built once per scene). The tables
/// that grow with the scene ([`PagedBuffer`]: `triangles`, `normals`, `bvh_nodes`,
/// `bvh_leaf_triangles`, `bvh_prim_indices`, `placements`, `objects`, `instances`,
/// `lights`, `mesh_words` and the surface tables' words) are split into pages of one
/// storage binding each where they outgrow one ([`crate::paging`]; `specialization.pages`
/// says how).
pub struct SceneBuffers {
    /// `array<TriangleRecord>`: the world triangle table by global id; with objects by
    /// reference, the stored objects' records alone, by record index
    /// ([`hyrt_core::geometry::WorldTriangles::stored_records`]).
    pub triangles: PagedBuffer,
    /// `array<f32>`, 9 per triangle (per stored record with objects by reference): the
    /// world normals at its three corners (x, y, z each).
    pub normals: PagedBuffer,
    /// Whether some object is kept by reference: its records are made on read from
    /// `placements` and `mesh_words` ([`crate::world_triangles`]).
    pub by_reference: bool,
    /// `array<PlacementRecord>`, one per object, with objects by reference; one zero record
    /// (read by no stage) otherwise.
    pub placements: PagedBuffer,
    /// `array<u32>`: every shared mesh's positions, normals and triangles, once
    /// ([`hyrt_core::geometry::WorldTriangles::mesh_words`]); one zero word without objects
    /// by reference.
    pub mesh_words: PagedBuffer,
    /// Where each mesh starts in `mesh_words`.
    mesh_offsets: Vec<MeshWords>,
    /// `array<ObjectRecord>`.
    pub objects: PagedBuffer,
    /// `array<LightRecord>`: the frame's lights ([`SceneBuffers::set_lighting`]: the scene's,
    /// with area lights given the frame's samples and seeds), then the scene's emitter table
    /// ([`hyrt_core::geometry::WorldGeometry::emitters`]), one [`emitter_slot`] per emitter
    /// ([`packed_lights`]): record `light_count + i` is emitter `i`, which the stages that
    /// sample area lights read there (`shaders/soft_shadow.wgsl`'s `emitter_at`;
    /// [`SlotParams::emitters`] says how many). Packed rather than bound on its own: the
    /// shading stages already bind 8 storage buffers, WebGPU's default limit, and
    /// `bounce_shading` [`crate::backend::BOUNCE_STORAGE_BUFFERS`]. In pages where the
    /// emitters outgrow one binding ([`Table::Lights`]).
    pub lights: PagedBuffer,
    /// `array<BvhNode>`: the flattened BVH ([`hyrt_core::bvh`]); empty BVH: one zero node and `bvh_node_count == 0`.
    /// A scene with two levels: every level's nodes, the top level's first
    /// ([`hyrt_core::bvh::two_level::PackedLevels`]).
    pub bvh_nodes: PagedBuffer,
    /// `array<TriangleRecord>`: triangles in BVH leaf order (`Bvh::leaf_triangles`; every
    /// bottom level's in turn with two levels).
    pub bvh_leaf_triangles: PagedBuffer,
    /// `array<u32>`: global triangle index of each leaf slot (`Bvh::prim_indices`); with
    /// two levels, each bottom level's, to which an instance adds its first triangle.
    pub bvh_prim_indices: PagedBuffer,
    /// `array<InstanceRecord>`: a two-level scene's instances, each naming its level's
    /// root in `bvh_nodes`; one zero record (bound by no stage) for a single-level scene.
    pub instances: PagedBuffer,
    /// The pipelines the scene needs ([`Specialization::of_scene`]).
    pub specialization: Specialization,
    /// Uniform [`EnvironmentRecord`]: what secondary rays that leave the scene see.
    pub environment: wgpu::Buffer,
    /// `array<vec4<f32>>`: the environment map's texels (one zero texel for the sky).
    pub environment_texels: wgpu::Buffer,
    /// Uniform [`AmbientLightRecord`]: the frame's ambient light
    /// ([`hyrt_core::geometry::WorldGeometry::ambient`] with the frame's ambient occlusion,
    /// [`SceneBuffers::set_lighting`]), its constant level and whether the scene has an
    /// image-based light.
    pub ambient_light: wgpu::Buffer,
    /// `array<vec4<f32>>`: the image-based light's tables
    /// ([`hyrt_core::kernels::ibl::AmbientLight::texels`]; one zero texel without one).
    pub ambient_texels: wgpu::Buffer,
    /// The surface tables (materials, texture coordinates, vertex colours, textures),
    /// packed into one table of words (in pages where they outgrow one binding) with their
    /// layout; one unread word without them.
    pub surface: SurfaceBuffers,
    /// `array<u32>`: the objects whose triangles that show their interior the raster's
    /// setup drops this frame, one bit each
    /// ([`hyrt_core::geometry::WorldGeometry::interior_culls`], written per frame by
    /// [`SceneBuffers::set_interior_culls`]; none until then).
    pub interior_culls: wgpu::Buffer,
    pub triangle_count: u32,
    pub object_count: u32,
    pub light_count: u32,
    pub bvh_node_count: u32,
    /// What `lights` and `ambient_light` hold now (the scene's, or the last frame's).
    held_lights: Vec<LightRecord>,
    held_ambient: AmbientLightRecord,
    /// What `interior_culls` holds now.
    held_interior_culls: Vec<u32>,
}

impl SceneBuffers {
    /// Upload the tables of `scene`.
    pub fn new(ctx: &GpuContext, scene: &PreparedScene) -> SceneBuffers {
        let g = &scene.geometry;
        let by_reference = g.triangles.has_references();
        // With objects by reference: the stored records, each mesh once, a placement per object.
        let (triangles, normals, placements, (mesh_words, mesh_offsets)) = match by_reference {
            false => (
                g.triangles.stored_records(),
                corner_normals(g, 0..g.triangles.len()),
                Vec::new(),
                (Vec::new(), Vec::new()),
            ),
            true => {
                let words = g.triangles.mesh_words().expect("mesh words fewer than 2^32 (check_supported)");
                let placements = placement_records(g, &words.1);
                let normals = g.triangles.stored_normals().iter().flat_map(|n| n.iter().flat_map(|v| v.to_array()));
                (g.triangles.stored_records(), normals.collect(), placements, words)
            }
        };
        let (environment, texels) = EnvironmentRecord::of(&g.environment);
        debug_assert_eq!(environment.validate(texels.len()), Ok(()));
        let environment_header = uniform(ctx, "environment", std::mem::size_of::<EnvironmentRecord>() as u64);
        ctx.queue.write_buffer(&environment_header, 0, bytemuck::bytes_of(&environment));
        let ambient = g.ambient.record();
        let ambient_texels = g.ambient.texels();
        debug_assert_eq!(ambient.validate(ambient_texels.len()), Ok(()));
        let ambient_header = uniform(ctx, "ambient light", std::mem::size_of::<AmbientLightRecord>() as u64);
        ctx.queue.write_buffer(&ambient_header, 0, bytemuck::bytes_of(&ambient));
        let packed = scene.levels.as_ref().map(|l| l.packed());
        // As many words as `WorldGeometry::interior_culls` gives, no object culled.
        let culls_none = vec![0u32; hyrt_core::kernels::raster::interior_cull_words(g.objects.len())];
        let specialization = Specialization::of_scene(scene, &ctx.limits);
        let pages = specialization.pages;
        let (nodes, leaf_triangles, prim_indices, instances) = match &packed {
            Some(p) => (&p.nodes, &p.leaf_triangles, &p.prim_indices, &p.instances[..]),
            None => (&scene.bvh.nodes, &scene.bvh.leaf_triangles, &scene.bvh.prim_indices, &[][..]),
        };
        SceneBuffers {
            environment: environment_header,
            environment_texels: upload::<[f32; 4]>(ctx, "environment texels", texels),
            ambient_light: ambient_header,
            ambient_texels: upload::<[f32; 4]>(ctx, "ambient light texels", &ambient_texels),
            triangles: PagedBuffer::upload::<TriangleRecord>(ctx, Table::Triangles, triangles, pages),
            normals: PagedBuffer::upload(ctx, Table::Normals, &normals, pages),
            by_reference,
            placements: PagedBuffer::upload::<PlacementRecord>(ctx, Table::Placements, &placements, pages),
            mesh_words: PagedBuffer::upload::<u32>(ctx, Table::MeshWords, &mesh_words, pages),
            mesh_offsets,
            objects: PagedBuffer::upload::<ObjectRecord>(ctx, Table::Objects, &g.objects, pages),
            lights: PagedBuffer::upload(ctx, Table::Lights, &packed_lights(&g.lights, &g.emitters), pages),
            bvh_nodes: PagedBuffer::upload::<BvhNode>(ctx, Table::Nodes, nodes, pages),
            bvh_leaf_triangles: PagedBuffer::upload::<TriangleRecord>(ctx, Table::LeafTriangles, leaf_triangles, pages),
            bvh_prim_indices: PagedBuffer::upload::<u32>(ctx, Table::PrimIndices, prim_indices, pages),
            instances: PagedBuffer::upload::<InstanceRecord>(ctx, Table::Instances, instances, pages),
            specialization,
            surface: SurfaceBuffers::new(ctx, &g.surface, &g.objects, pages),
            interior_culls: upload::<u32>(ctx, "interior culls", &culls_none),
            held_interior_culls: culls_none,
            triangle_count: g.triangles.len() as u32,
            object_count: g.objects.len() as u32,
            light_count: g.lights.len() as u32,
            bvh_node_count: nodes.len() as u32,
            held_lights: g.lights.clone(),
            held_ambient: ambient,
        }
    }
}

impl SceneBuffers {
    /// The table the bounce kernels read triangle flags from
    /// ([`crate::world_triangles::triangle_flags_wgsl`]): the placements with objects by
    /// reference, else the triangles.
    pub fn flags_table(&self) -> &wgpu::Buffer {
        self.flags_paged().first()
    }

    /// The further pages of [`SceneBuffers::flags_table`] ([`crate::paging`]), then those
    /// of `tables`.
    pub fn flags_table_pages(&self, tables: &[Table]) -> Vec<wgpu::BindGroupEntry<'_>> {
        self.flags_paged().further().chain(self.further_pages(tables)).collect()
    }

    /// The table the triangle flags are read from: the placements or the triangles.
    fn flags_paged(&self) -> &PagedBuffer {
        match self.by_reference {
            true => &self.placements,
            false => &self.triangles,
        }
    }

    /// The table `table` ([`crate::paging`]).
    pub fn paged(&self, table: Table) -> &PagedBuffer {
        match table {
            Table::Triangles => &self.triangles,
            Table::Normals => &self.normals,
            Table::LeafTriangles => &self.bvh_leaf_triangles,
            Table::PrimIndices => &self.bvh_prim_indices,
            Table::Nodes => &self.bvh_nodes,
            Table::Surface => &self.surface.words,
            Table::MeshWords => &self.mesh_words,
            Table::Placements => &self.placements,
            Table::Objects => &self.objects,
            Table::Instances => &self.instances,
            Table::Lights => &self.lights,
        }
    }

    /// The further pages of `tables`, in order: none for an unpaged one.
    pub fn further_pages(&self, tables: &[Table]) -> Vec<wgpu::BindGroupEntry<'_>> {
        tables.iter().flat_map(|&t| self.paged(t).further()).collect()
    }

    /// The pages of `scene`'s tables on this device, taken again for a table whose length
    /// changed (its stages follow the specialization; `check_supported` counted them).
    fn pages_again(&mut self, ctx: &GpuContext, scene: &PreparedScene) -> TablePages {
        self.specialization.pages = TablePages::of_scene(scene, &ctx.limits).unwrap_or_default();
        self.specialization.pages
    }

    /// Write the mesh words of `scene` again (a mesh deformed): in place when their layout
    /// is the one held, else into new pages (the scene's pages taken again), with every
    /// placement again (their offsets).
    fn write_meshes(&mut self, ctx: &GpuContext, scene: &PreparedScene) {
        let (words, offsets) = scene.geometry.triangles.mesh_words().expect("mesh words fewer than 2^32");
        if offsets == self.mesh_offsets && (words.len() * 4).max(4) as u64 == self.mesh_words.size() {
            self.mesh_words.write(&ctx.queue, 0, bytemuck::cast_slice(&words));
        } else {
            let pages = self.pages_again(ctx, scene);
            self.mesh_words = PagedBuffer::upload::<u32>(ctx, Table::MeshWords, &words, pages);
            self.mesh_offsets = offsets;
            let placements = placement_records(&scene.geometry, &self.mesh_offsets);
            self.placements.write(&ctx.queue, 0, bytemuck::cast_slice(&placements));
        }
    }

    /// Set the objects whose interior the raster's setup drops this frame
    /// ([`hyrt_core::geometry::WorldGeometry::interior_culls`] for the frame's camera),
    /// writing them where they differ from what the buffer holds.
    pub fn set_interior_culls(&mut self, ctx: &GpuContext, bits: &[u32]) {
        debug_assert_eq!(bits.len(), self.held_interior_culls.len(), "one bit per object of the scene");
        if bits != self.held_interior_culls.as_slice() {
            ctx.queue.write_buffer(&self.interior_culls, 0, bytemuck::cast_slice(bits));
            self.held_interior_culls.clear();
            self.held_interior_culls.extend_from_slice(bits);
        }
    }

    /// Hold the lights and ambient light of the next frame
    /// ([`PreparedScene::frame_lighting`]: with area lights, their samples and the frame's
    /// seeds; with ambient occlusion, its rays), writing what differs from what the
    /// buffers hold (nothing for a frame of the scene's own lighting after another).
    pub fn set_lighting(&mut self, ctx: &GpuContext, lights: &[LightRecord], ambient: &AmbientLightRecord) {
        debug_assert_eq!(lights.len(), self.held_lights.len(), "a frame's lights are the scene's");
        // By their bits: a record's fields compare as floats, where 0.0 == -0.0.
        let held: &[u8] = bytemuck::cast_slice(&self.held_lights);
        if !lights.is_empty() && bytemuck::cast_slice::<LightRecord, u8>(lights) != held {
            self.lights.write(&ctx.queue, 0, bytemuck::cast_slice(lights));
            self.held_lights.clear();
            self.held_lights.extend_from_slice(lights);
        }
        if bytemuck::bytes_of(ambient) != bytemuck::bytes_of(&self.held_ambient) {
            ctx.queue.write_buffer(&self.ambient_light, 0, bytemuck::bytes_of(ambient));
            self.held_ambient = *ambient;
        }
    }
}

/// Every object's [`PlacementRecord`], its mesh in the words at `meshes`.
fn placement_records(g: &hyrt_core::geometry::WorldGeometry, meshes: &[MeshWords]) -> Vec<PlacementRecord> {
    let records: Vec<PlacementRecord> = (0..g.objects.len() as u32).map(|o| placement_record(g, o, meshes)).collect();
    debug_assert_eq!(records.iter().try_for_each(PlacementRecord::validate), Ok(()));
    records
}

/// Object `o`'s [`PlacementRecord`].
fn placement_record(g: &hyrt_core::geometry::WorldGeometry, o: u32, meshes: &[MeshWords]) -> PlacementRecord {
    let r = &g.objects[o as usize];
    g.triangles.placement_record(o, r.first_triangle, r.triangle_count, meshes)
}

/// Emitter `e` in a slot of the lights' binding ([`SceneBuffers::lights`], read back by
/// `shaders/soft_shadow.wgsl`'s `emitter_at`): each [`EmitterRecord`] field in a
/// [`LightRecord`] field of its WGSL type, so that no value is read through another type.
///
/// | offset | [`LightRecord`] field | [`EmitterRecord`] field |
/// |---:|---|---|
/// | 0 | `position_or_direction` | `v0` |
/// | 12 | `kind` | `flags` |
/// | 16 | `radiance` | `e1` |
/// | 28 | `inv_range_sq` | `cdf` |
/// | 32 | `spot_direction` | `e2` |
/// | 44 | `spot_scale` | `radiance[0]` |
/// | 48 | `spot_offset` | `radiance[1]` |
/// | 52 | `size` | `radiance[2]` |
/// | 56 | `samples` | `object` |
/// | 60 | `seed` | `triangle` |
/// | 64 | `edge_u`, `pad0`, `edge_v`, `pad1` | zero |
///
/// 96 bytes per emitter (the record's 64 and 32 of zeros). The slot is no light: only
/// `emitter_at` reads it (the stages walk `params.light_count` records).
pub fn emitter_slot(e: &EmitterRecord) -> LightRecord {
    LightRecord {
        position_or_direction: e.v0,
        kind: e.flags,
        radiance: e.e1,
        inv_range_sq: e.cdf,
        spot_direction: e.e2,
        spot_scale: e.radiance[0],
        spot_offset: e.radiance[1],
        size: e.radiance[2],
        samples: e.object,
        seed: e.triangle,
        ..bytemuck::Zeroable::zeroed()
    }
}

/// What [`SceneBuffers::lights`] holds: the light records `lights`, then each of `emitters`
/// in its [`emitter_slot`].
pub fn packed_lights(lights: &[LightRecord], emitters: &[EmitterRecord]) -> Vec<LightRecord> {
    lights.iter().copied().chain(emitters.iter().map(emitter_slot)).collect()
}

/// The corner normals of global triangles `range` as the GPU reads them: nine floats each.
fn corner_normals(g: &hyrt_core::geometry::WorldGeometry, range: std::ops::Range<usize>) -> Vec<f32> {
    let mut normals = Vec::new();
    g.triangles.fill_normals(range, &mut normals);
    normals.iter().flat_map(|n| n.iter().flat_map(|v| v.to_array())).collect()
}

impl SceneBuffers {
    /// Write what changed in `scene` since the revision these buffers hold
    /// ([`PreparedScene::changes_since`]): each moved object's triangles, normals and
    /// record, the top level's nodes and the instances, the nodes and leaf triangles of
    /// refitted bottom levels, the lights; the surface tables
    /// again when the scene has them (a move changes its texture level-of-detail
    /// constants). Everything else (the bottom levels, the other objects) stays as uploaded.
    pub fn apply(&mut self, ctx: &GpuContext, scene: &PreparedScene, changes: &SceneChanges) {
        let g = &scene.geometry;
        if self.by_reference && !changes.bottoms.is_empty() {
            // Deformed meshes: their words again (a move writes none).
            self.write_meshes(ctx, scene);
        }
        for &o in &changes.objects {
            let record = &g.objects[o as usize];
            let range = record.first_triangle as usize..(record.first_triangle + record.triangle_count) as usize;
            // Where its records are: by global id, or with objects by reference its placement
            // says (an object by reference has none: its placement is its transform).
            let first_record = match self.by_reference {
                false => Some(range.start),
                true => {
                    let p = placement_record(g, o, &self.mesh_offsets);
                    let size = std::mem::size_of::<PlacementRecord>();
                    self.placements.write(&ctx.queue, (o as usize * size) as u64, bytemuck::bytes_of(&p));
                    (!p.by_reference()).then_some(p.first_record as usize)
                }
            };
            if let Some(first) = first_record {
                let mut triangles = Vec::new();
                g.triangles.fill(range.clone(), &mut triangles);
                let offset = (first * std::mem::size_of::<TriangleRecord>()) as u64;
                self.triangles.write(&ctx.queue, offset, bytemuck::cast_slice(&triangles));
                self.normals.write(&ctx.queue, (first * 9 * 4) as u64, bytemuck::cast_slice(&corner_normals(g, range)));
            }
            let offset = o as u64 * std::mem::size_of::<ObjectRecord>() as u64;
            self.objects.write(&ctx.queue, offset, bytemuck::bytes_of(record));
        }
        if let (false, Some(levels)) = (changes.objects.is_empty(), &scene.levels) {
            self.bvh_nodes.write(&ctx.queue, 0, bytemuck::cast_slice(&levels.top));
            self.instances.write(&ctx.queue, 0, bytemuck::cast_slice(&levels.packed_instances()));
            // Refitted bottom levels (deformed meshes): same places, new boxes and vertices.
            for &b in &changes.bottoms {
                let (node_base, nodes, slot_base) = levels.packed_bottom(b as usize);
                let node_offset = node_base as u64 * std::mem::size_of::<BvhNode>() as u64;
                self.bvh_nodes.write(&ctx.queue, node_offset, bytemuck::cast_slice(&nodes));
                let leaf = &levels.bottoms[b as usize].leaf_triangles;
                let slot_offset = slot_base as u64 * std::mem::size_of::<TriangleRecord>() as u64;
                self.bvh_leaf_triangles.write(&ctx.queue, slot_offset, bytemuck::cast_slice(leaf));
            }
        }
        // The lights changed, or emitters moved or deformed (`PreparedScene::move_objects` and
        // `deform_mesh` log those as the lights' too): the emitter table's length may change
        // with the light count's the same.
        if changes.lights {
            let packed = packed_lights(&g.lights, &g.emitters);
            let bytes: &[u8] = bytemuck::cast_slice(&packed);
            match bytes.len() as u64 == self.lights.size() {
                true => self.lights.write(&ctx.queue, 0, bytes),
                // Another length (a deformed emitter): its pages again, and the stages'
                // (`check_supported` counted them).
                false => {
                    let pages = self.pages_again(ctx, scene);
                    self.lights = PagedBuffer::upload(ctx, Table::Lights, &packed, pages);
                }
            }
            self.held_lights.clone_from(&g.lights);
        }
        if !changes.objects.is_empty() && !g.surface.is_empty() {
            self.surface = SurfaceBuffers::new(ctx, &g.surface, &g.objects, self.specialization.pages);
        }
    }
}

/// Per-frame buffers for one band size (image width and rows), count of mask slots per
/// surface ([`SlotParams`]: the light count in a frame without area lights and ambient
/// occlusion) and set of planned stages, reused across frames. A buffer whose stage the plan skips is not
/// allocated: its field holds `empty` (one 64-byte buffer shared by every absent one),
/// so bind groups stay valid while no skipped stage is encoded.
///
/// The per-pixel buffers hold one band of `rows` rows (the whole image when the frame
/// fits the device's bindings, see [`crate::band`]); `band` is the band being rendered,
/// at most `rows` rows, and the pixel stages run over `width` x `band.rows` pixels.
pub struct FrameBuffers {
    pub width: u32,
    /// Rows the per-pixel buffers hold.
    pub rows: u32,
    /// The band being rendered ([`FrameBuffers::set_band`]); the whole of `rows` at first.
    pub band: Band,
    /// The rows of `band` the frame keeps (`band` itself but in a denoised banded frame,
    /// whose bands are rendered with a halo of rows: [`crate::band`]), from the band's
    /// first row: `own.first_row` rows of halo above them.
    pub own: Band,
    /// The frame is rendered in more than one band: `compaction` also writes where each
    /// slot's rays start in its list (`light_starts`), so that the bands' lists can be
    /// merged into the frame's slot-major order.
    pub banded: bool,
    /// Shadow-mask slots per surface ([`SlotParams::slots`]): what the shadow codes, the
    /// pairs of `compaction` and `light_starts` are sized by.
    pub slots: u32,
    /// The frame traces stochastic rays (area lights, ambient occlusion): `compaction` and
    /// the shading stages run their pipelines specialized for slots
    /// ([`crate::texture::Specialization::stochastic`]). Set with the slots
    /// ([`FrameBuffers::set_slots`]).
    pub stochastic: bool,
    /// Rays `rays` and `occluded` have room for (0 when the plan traces none). The
    /// frame's rays are known only after `compaction`: a frame with more reallocates
    /// and runs again (see `GpuBackend`).
    pub ray_capacity: u32,
    /// The buffers of each bounce depth the plan traces (depth `i + 1` at `i`).
    pub bounces: Vec<BounceBuffers>,
    /// `array<u32, 4>`: `[pixels, own_lo, own_hi, 0]`, the live count of the primary
    /// surfaces (the list stages read every list's count from a buffer), then the band's
    /// own pixels `[own_lo, own_hi)` (all of them but in a band with a halo, whose other
    /// pixels spawn no bounce: `secondary_rays`).
    pub pixel_count: wgpu::Buffer,
    /// Uniform [`ListParams`] of the primary hits' list (depth 0).
    pub list: wgpu::Buffer,
    /// The frame buffers allocated (the plan's, in [`FrameBuffer::ALL`] order).
    pub allocated: Vec<FrameBuffer>,
    /// Uniform `CameraRecord`.
    pub camera: wgpu::Buffer,
    /// Uniform [`FrameParams`].
    pub params: wgpu::Buffer,
    /// Uniform [`SlotParams`] of the frame ([`FrameBuffers::set_slots`]; one slot per light
    /// until then).
    pub slot_params: wgpu::Buffer,
    /// `array<GBufferTexel>`, one per pixel (`visibility_raster`).
    pub gbuffer: wgpu::Buffer,
    /// `array<SurfaceRecord>`, one per pixel (`reconstruction`).
    pub surfaces: wgpu::Buffer,
    /// `array<RayRecord>` with room for `ray_capacity` rays (`compaction`).
    pub rays: wgpu::Buffer,
    /// `array<u32>`, 4 words: `[ray_count, dispatch_x, dispatch_y, dispatch_z]`, written by
    /// `compaction`; the last three are indirect-dispatch arguments for one thread per ray.
    /// `ray_count` is the frame's true count, even past `ray_capacity`.
    pub ray_count: wgpu::Buffer,
    /// `array<u32>`, one per ray slot: 1 occluded, 0 reached the light (`shadow_rays`).
    pub occluded: wgpu::Buffer,
    /// `array<u32>`, three per slot: the index of the slot's first ray in `rays`, then of
    /// its first ray from the band's own rows (`own`), then of its first past them
    /// (`compaction`, in banded frames only; `shaders/light_starts.wgsl`).
    pub light_starts: wgpu::Buffer,
    /// `array<u32, 4>`: `[0, 0, u32::MAX, 0]`, the surface bounds of the bounce lists'
    /// light starts (every surface is the band's own).
    pub all_surfaces: wgpu::Buffer,
    /// `array<f32>`, [`FrameBuffers::channels`] per pixel: the denoised visibility
    /// (`shadow_denoise`).
    pub visibility: wgpu::Buffer,
    /// The denoised channels per pixel ([`FramePlan::visibility_channels`]; 0 when the plan
    /// does not denoise).
    pub channels: u32,
    /// The scratch of `shadow_denoise`, when the plan runs it.
    pub denoise: Option<crate::shadow_denoise::DenoiseBuffers>,
    /// `array<u32>`, `pixels * slots`, index `pixel * slots + slot`: the `SHADOW_*` codes
    /// of [`hyrt_core::frame`] (u32 here; u8 on the CPU, converted on readback).
    pub shadow: wgpu::Buffer,
    /// `array<vec4<f32>>`, one per pixel: `rt_shading`, `raster_shading`, `composition`.
    pub rt: wgpu::Buffer,
    pub raster: wgpu::Buffer,
    pub final_image: wgpu::Buffer,
    /// The stand-in for every buffer the plan does not produce, and for the inputs a
    /// stage does not read in a given call (the parents' rays at depth 1, the children
    /// of the deepest bounce): 64 bytes, never written.
    pub empty: wgpu::Buffer,
}

/// The GPU buffers of one bounce depth `d`: the [`BounceBuffer`]s of the plan, each
/// with room for its list, and the lists' counts.
pub struct BounceBuffers {
    pub depth: u32,
    pub room: BounceRoom,
    /// Parents of the depth's rays: the pixels for depth 1, the ray room of depth `d - 1`.
    pub parents: u32,
    /// Uniform [`ListParams`] of the depth.
    pub list: wgpu::Buffer,
    /// `array<RayRecord>`, `room.rays` (`secondary_rays`).
    pub rays: wgpu::Buffer,
    /// `array<u32, 4>`: `[rays, dispatch_x, dispatch_y, 1]` of the depth's rays, written by
    /// `secondary_rays` (the true count, even past the room).
    pub ray_count: wgpu::Buffer,
    /// `array<vec2<u32>>`, one per parent (`secondary_rays`).
    pub links: wgpu::Buffer,
    /// `array<HitRecord>`, `room.rays` (`bounce_trace`).
    pub hits: wgpu::Buffer,
    /// `array<SurfaceRecord>`, `room.rays` (`bounce_trace`).
    pub surfaces: wgpu::Buffer,
    /// `array<RayRecord>`, `room.shadow_rays` (`compaction`).
    pub shadow_rays: wgpu::Buffer,
    /// `array<u32, 4>`: the shadow rays' count and dispatch (`compaction`).
    pub shadow_ray_count: wgpu::Buffer,
    /// `array<u32>`, `room.shadow_rays` (`shadow_rays`).
    pub occluded: wgpu::Buffer,
    /// `array<u32>`, three per slot: where each slot's rays start in `shadow_rays`
    /// (`compaction`, in banded frames only; the other two as the primary list's).
    pub light_starts: wgpu::Buffer,
    /// `array<u32>`, `room.rays * slots` `SHADOW_*` codes (`shadow_rays`).
    pub shadow: wgpu::Buffer,
    /// `array<vec4<f32>>`, `room.rays` (`bounce_shading`).
    pub radiance: wgpu::Buffer,
    /// `array<atomic<u32>, 4>`: the depth's statistics, `[reflection rays, refraction
    /// rays, hits, occluded shadow rays]` (integer sums: the same whatever the order).
    pub counters: wgpu::Buffer,
}

/// Indices of [`BounceBuffers::counters`].
pub const COUNTER_REFLECTION: usize = 0;
/// See [`COUNTER_REFLECTION`].
pub const COUNTER_REFRACTION: usize = 1;
/// See [`COUNTER_REFLECTION`].
pub const COUNTER_HITS: usize = 2;
/// See [`COUNTER_REFLECTION`].
pub const COUNTER_OCCLUDED: usize = 3;

/// The buffers of one list of shadow rays as `compaction` and `shadow_rays` bind them:
/// the primary hits' or those of one bounce depth.
pub struct ListBuffers<'a> {
    /// Room of `surfaces`.
    pub slots: u32,
    /// Uniform [`ListParams`].
    pub params: &'a wgpu::Buffer,
    /// `array<u32, 4>` whose first word is the live count of `surfaces`.
    pub live: &'a wgpu::Buffer,
    pub surfaces: &'a wgpu::Buffer,
    pub shadow_rays: &'a wgpu::Buffer,
    pub shadow_ray_count: &'a wgpu::Buffer,
    pub occluded: &'a wgpu::Buffer,
    pub light_starts: &'a wgpu::Buffer,
    /// `array<u32, 4>` whose words 1 and 2 bound the surfaces the band keeps (see
    /// [`FrameBuffers::pixel_count`]).
    pub bounds: &'a wgpu::Buffer,
    pub shadow: &'a wgpu::Buffer,
    /// `array<atomic<u32>, 4>`, written at bounce depths only.
    pub counters: &'a wgpu::Buffer,
}

impl BounceBuffers {
    /// The depth's shadow-ray list, its surfaces bounded by `bounds` (all of them:
    /// [`FrameBuffers::all_surfaces`]).
    pub fn list<'a>(&'a self, bounds: &'a wgpu::Buffer) -> ListBuffers<'a> {
        ListBuffers {
            slots: self.room.rays,
            params: &self.list,
            live: &self.ray_count,
            surfaces: &self.surfaces,
            shadow_rays: &self.shadow_rays,
            shadow_ray_count: &self.shadow_ray_count,
            occluded: &self.occluded,
            light_starts: &self.light_starts,
            bounds,
            shadow: &self.shadow,
            counters: &self.counters,
        }
    }

    /// The list parameters of the depth, the deepest when `last`.
    pub fn params(&self, last: bool) -> ListParams {
        ListParams { slots: self.room.rays, parents: self.parents, depth: self.depth, last: last as u32 }
    }

    /// The GPU buffer holding `buffer`.
    pub fn get(&self, buffer: BounceBuffer) -> &wgpu::Buffer {
        match buffer {
            BounceBuffer::Rays => &self.rays,
            BounceBuffer::Links => &self.links,
            BounceBuffer::Hits => &self.hits,
            BounceBuffer::Surfaces => &self.surfaces,
            BounceBuffer::ShadowRays => &self.shadow_rays,
            BounceBuffer::Occluded => &self.occluded,
            BounceBuffer::Shadow => &self.shadow,
            BounceBuffer::Radiance => &self.radiance,
        }
    }
}

/// A small buffer of four u32 words: a list's count and indirect-dispatch arguments, or
/// counters.
fn words4(ctx: &GpuContext, label: &str) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: 16,
        usage: crate::gpu_buffer::STORAGE | wgpu::BufferUsages::INDIRECT,
        mapped_at_creation: false,
    })
}

/// A uniform buffer of `size` bytes, written before each frame (or once, for a scene's
/// headers).
fn uniform(ctx: &GpuContext, label: &str, size: u64) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

impl FrameBuffers {
    /// Every buffer of a `width` x `height` frame of one band with `light_count` lights
    /// (one mask slot each: no area light, no occlusion), with room for a ray per (pixel,
    /// light): what the stage tests bind.
    pub fn new(ctx: &GpuContext, width: u32, height: u32, light_count: u32) -> Result<FrameBuffers, GpuError> {
        let everything = FramePlan::from_counts(hyrt_core::plan::SceneNeeds::every_primary_stage(light_count.max(1)));
        let pairs = width as usize * height as usize * light_count as usize;
        let capacity = u32::try_from(pairs).map_err(|_| GpuError::Limits(format!("{pairs} rays")))?;
        let room = Room { shadow_rays: capacity, bounces: Vec::new() };
        Self::for_plan(ctx, width, height, light_count, &everything, &room)
    }

    /// Allocate the buffers `plan` produces for bands of `width` x `rows` pixels with
    /// `slots` shadow-mask slots per surface ([`FramePlan::lights`]) and the lists' `room`
    /// (the primary shadow rays', and one entry per bounce depth of the plan). The band is
    /// the first `rows` rows until [`FrameBuffers::set_band`]; the slots are one per light
    /// until [`FrameBuffers::set_slots`].
    pub fn for_plan(
        ctx: &GpuContext,
        width: u32,
        rows: u32,
        slots: u32,
        plan: &FramePlan,
        room: &Room,
    ) -> Result<FrameBuffers, GpuError> {
        let pixels = width as usize * rows as usize;
        let pairs = pixels * slots as usize;
        let uniform = |label: &str, size: u64| uniform(ctx, label, size);
        // One element of the largest record a shader binds (`RayRecord`, 64 bytes).
        let empty = storage::<RayRecord>(ctx, "empty (a skipped stage's buffer)", 1)?;
        let allocated: Vec<FrameBuffer> = plan.buffers().collect();
        let ray_capacity = if plan.produces(FrameBuffer::Rays) { room.shadow_rays } else { 0 };
        let depths = plan.bounce_depth() as usize;
        assert_eq!(room.bounces.len(), depths, "one room per bounce depth");
        let mut bounces = Vec::with_capacity(depths);
        let mut parents = pixels as u32;
        for (i, &r) in room.bounces.iter().enumerate() {
            let depth = i as u32 + 1;
            let label = |name: &str| format!("bounce{depth}_{name}");
            let (rays, shadow_rays) = (r.rays as usize, r.shadow_rays as usize);
            bounces.push(BounceBuffers {
                depth,
                room: r,
                parents,
                list: uniform(&label("list"), std::mem::size_of::<ListParams>() as u64),
                rays: storage::<RayRecord>(ctx, &label("rays"), rays)?,
                ray_count: words4(ctx, &label("ray_count")),
                links: storage::<[u32; 2]>(ctx, &label("links"), parents as usize)?,
                hits: storage::<HitRecord>(ctx, &label("hits"), rays)?,
                surfaces: storage::<SurfaceRecord>(ctx, &label("surfaces"), rays)?,
                shadow_rays: storage::<RayRecord>(ctx, &label("shadow_rays"), shadow_rays)?,
                shadow_ray_count: words4(ctx, &label("shadow_ray_count")),
                occluded: storage::<u32>(ctx, &label("occluded"), shadow_rays)?,
                light_starts: storage::<u32>(ctx, &label("light_starts"), 3 * slots as usize)?,
                shadow: storage::<u32>(ctx, &label("shadow"), rays * slots.max(1) as usize)?,
                radiance: storage::<[f32; 4]>(ctx, &label("radiance"), rays)?,
                counters: words4(ctx, &label("counters")),
            });
            parents = r.rays;
        }
        let alloc = |b: FrameBuffer, f: &dyn Fn() -> Result<wgpu::Buffer, GpuError>| {
            if allocated.contains(&b) {
                f()
            } else {
                Ok(empty.clone())
            }
        };
        let channels = plan.visibility_channels();
        let denoise = match plan.produces(FrameBuffer::Visibility) {
            true => Some(crate::shadow_denoise::DenoiseBuffers::new(ctx, width, rows, channels)?),
            false => None,
        };
        let frame = FrameBuffers {
            width,
            rows,
            band: Band { first_row: 0, rows },
            own: Band { first_row: 0, rows },
            banded: false,
            slots,
            stochastic: false,
            ray_capacity,
            bounces,
            pixel_count: words4(ctx, "pixel count"),
            list: uniform("list params", std::mem::size_of::<ListParams>() as u64),
            camera: uniform("camera", std::mem::size_of::<CameraRecord>() as u64),
            params: uniform("frame params", std::mem::size_of::<FrameParams>() as u64),
            slot_params: uniform("slot params", std::mem::size_of::<SlotParams>() as u64),
            gbuffer: alloc(FrameBuffer::GBuffer, &|| storage::<GBufferTexel>(ctx, "gbuffer", pixels))?,
            surfaces: alloc(FrameBuffer::Surfaces, &|| storage::<SurfaceRecord>(ctx, "surfaces", pixels))?,
            rays: alloc(FrameBuffer::Rays, &|| storage::<RayRecord>(ctx, "rays", ray_capacity as usize))?,
            ray_count: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("ray count"),
                size: 16,
                usage: crate::gpu_buffer::STORAGE | wgpu::BufferUsages::INDIRECT,
                mapped_at_creation: false,
            }),
            occluded: alloc(FrameBuffer::Occluded, &|| storage::<u32>(ctx, "occluded", ray_capacity as usize))?,
            light_starts: storage::<u32>(ctx, "light_starts", 3 * slots as usize)?,
            all_surfaces: words4(ctx, "all surfaces"),
            visibility: alloc(FrameBuffer::Visibility, &|| {
                storage::<f32>(ctx, "visibility", pixels * channels as usize)
            })?,
            channels,
            denoise,
            shadow: alloc(FrameBuffer::Shadow, &|| storage::<u32>(ctx, "shadow", pairs))?,
            rt: alloc(FrameBuffer::Rt, &|| storage::<[f32; 4]>(ctx, "rt image", pixels))?,
            raster: alloc(FrameBuffer::Raster, &|| storage::<[f32; 4]>(ctx, "raster image", pixels))?,
            final_image: alloc(FrameBuffer::Final, &|| storage::<[f32; 4]>(ctx, "final image", pixels))?,
            allocated,
            empty,
        };
        frame.write_lists(ctx);
        Ok(frame)
    }

    /// True if these buffers fit bands of `width` x `rows` pixels with `slots` mask slots
    /// per surface under `plan` with lists that need `room`.
    pub fn fits(&self, width: u32, rows: u32, slots: u32, plan: &FramePlan, room: &Room) -> bool {
        (self.width, self.rows, self.slots) == (width, rows, slots)
            && self.allocated.iter().copied().eq(plan.buffers())
            && (!plan.produces(FrameBuffer::Rays) || room.shadow_rays <= self.ray_capacity)
            && self.bounces.len() == room.bounces.len()
            && self
                .bounces
                .iter()
                .zip(&room.bounces)
                .all(|(b, r)| r.rays <= b.room.rays && r.shadow_rays <= b.room.shadow_rays)
    }

    /// The room these buffers have.
    pub fn room(&self) -> Room {
        Room { shadow_rays: self.ray_capacity, bounces: self.bounces.iter().map(|b| b.room).collect() }
    }

    /// The primary hits' shadow-ray list.
    pub fn primary_list(&self) -> ListBuffers<'_> {
        ListBuffers {
            slots: self.width * self.rows,
            params: &self.list,
            live: &self.pixel_count,
            surfaces: &self.surfaces,
            shadow_rays: &self.rays,
            shadow_ray_count: &self.ray_count,
            occluded: &self.occluded,
            light_starts: &self.light_starts,
            bounds: &self.pixel_count,
            shadow: &self.shadow,
            counters: &self.empty,
        }
    }

    /// The GPU buffer holding `buffer`.
    pub fn get(&self, buffer: FrameBuffer) -> &wgpu::Buffer {
        match buffer {
            FrameBuffer::GBuffer => &self.gbuffer,
            FrameBuffer::Surfaces => &self.surfaces,
            FrameBuffer::Rays => &self.rays,
            FrameBuffer::Occluded => &self.occluded,
            FrameBuffer::Shadow => &self.shadow,
            FrameBuffer::Visibility => &self.visibility,
            FrameBuffer::Rt => &self.rt,
            FrameBuffer::Raster => &self.raster,
            FrameBuffer::Final => &self.final_image,
            FrameBuffer::Bounce { buffer, depth } => self.bounces[depth as usize - 1].get(buffer),
        }
    }

    /// Write the camera and frame parameters for the next frame.
    pub fn write_uniforms(&self, ctx: &GpuContext, camera: &CameraRecord, params: &FrameParams) {
        ctx.queue.write_buffer(&self.camera, 0, bytemuck::bytes_of(camera));
        ctx.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
    }

    /// Render `band` next (at most [`FrameBuffers::rows`] rows), keeping its rows `own`
    /// (from the band's first row: `band` but for a halo, [`crate::band`]): the pixel
    /// stages run over its pixels, and the primary surfaces' live count is its pixel
    /// count. The [`FrameParams`] of the band are the caller's to write
    /// ([`FrameParams::for_band`]). `banded`: the frame has more than one band.
    pub fn set_band(&mut self, ctx: &GpuContext, band: Band, own: Band, banded: bool) {
        debug_assert!(band.rows <= self.rows, "{band:?} in buffers of {} rows", self.rows);
        debug_assert!(own.first_row + own.rows <= band.rows, "{own:?} in {band:?}");
        self.band = band;
        self.own = own;
        self.banded = banded;
        let pixels = self.width * band.rows;
        let (lo, hi) = (self.width * own.first_row, self.width * (own.first_row + own.rows));
        ctx.queue.write_buffer(&self.pixel_count, 0, bytemuck::bytes_of(&[pixels, lo, hi, 0]));
    }

    /// The frame's mask slots next ([`SlotParams`], whose `slots` must be these buffers'),
    /// and whether it traces stochastic rays (`stochastic`: the pipelines specialized for
    /// slots run).
    pub fn set_slots(&mut self, ctx: &GpuContext, slots: &SlotParams, stochastic: bool) {
        debug_assert_eq!(slots.slots, self.slots, "{slots:?} in buffers of {} slots", self.slots);
        self.stochastic = stochastic;
        ctx.queue.write_buffer(&self.slot_params, 0, bytemuck::bytes_of(slots));
    }

    /// Write what the lists' room fixes: the primary surfaces' live count (all `rows`),
    /// every list's [`ListParams`] (once, when the buffers are made) and one mask slot
    /// per light ([`SlotParams::per_light`], until [`FrameBuffers::set_slots`]).
    fn write_lists(&self, ctx: &GpuContext) {
        ctx.queue.write_buffer(&self.slot_params, 0, bytemuck::bytes_of(&SlotParams::per_light(self.slots)));
        let pixels = self.width * self.rows;
        ctx.queue.write_buffer(&self.pixel_count, 0, bytemuck::bytes_of(&[pixels, 0, pixels, 0]));
        ctx.queue.write_buffer(&self.all_surfaces, 0, bytemuck::bytes_of(&[0, 0, u32::MAX, 0]));
        let primary = ListParams { slots: pixels, parents: 0, depth: 0, last: 0 };
        ctx.queue.write_buffer(&self.list, 0, bytemuck::bytes_of(&primary));
        for b in &self.bounces {
            let list = b.params(b.depth as usize == self.bounces.len());
            debug_assert_eq!(list.validate(), Ok(()));
            ctx.queue.write_buffer(&b.list, 0, bytemuck::bytes_of(&list));
        }
    }
}
