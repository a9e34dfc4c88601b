//! World triangles on the GPU: how the stages that read a triangle by its global id
//! (`visibility_raster`, `reconstruction`, `bounce_trace`) and those that read its flags
//! (the bounce kernels of `secondary_rays`, `bounce_shading` and `rt_shading` with
//! bounces) find it, stored or by reference ([`hyrt_core::geometry::WorldTriangles`]).
//!
//! A scene whose objects are all stored uploads one table by global id, as it always did,
//! and its stages are compiled with accessors that index it (`triangles[gi]`): the code and
//! bindings they always had. A scene with objects by reference
//! ([`crate::texture::Specialization::by_reference`]) uploads its stored records alone,
//! each shared mesh once ([`WorldTriangles::mesh_words`]) and one [`PlacementRecord`] per
//! object ([`WorldTriangles::placement_record`]); its stages are compiled with
//! `shaders/world_triangles.wgsl` (and `shaders/world_normals.wgsl` where normals are read),
//! which make an object by reference's records on read by the operations of
//! [`hyrt_core::geometry::world_record`] and [`hyrt_core::geometry::world_normals`]:
//! the same bits as the CPU backend's, which makes them the same way. The stages that read
//! only flags bind the placements instead of the triangles (every triangle of an object
//! carries its object's flags), so they bind no more than before.
//!
//! [`WorldTriangles`]: hyrt_core::geometry::WorldTriangles
//! [`WorldTriangles::mesh_words`]: hyrt_core::geometry::WorldTriangles::mesh_words
//! [`WorldTriangles::placement_record`]: hyrt_core::geometry::WorldTriangles::placement_record
//! [`PlacementRecord`]: hyrt_core::formats::PlacementRecord

/// The accessors `world_triangle(gi)` and `world_triangle_flags(gi)` of a stage that binds
/// `triangles: array<TriangleRecord>` (and defines `rounded` and `mul` over an always-zero
/// uniform word): indexing the table by global id, or, `by_reference` at `Some((group,
/// binding))`, through the placements and mesh words it declares at bindings `binding` and
/// `binding + 1` of `group` (`shaders/world_triangles.wgsl`; `triangles` then holds the
/// stored records alone).
pub fn world_triangles_wgsl(by_reference: Option<(u32, u32)>) -> String {
    match by_reference {
        None => String::from(
            "// World triangles, every object stored (hyrt_gpu::world_triangles): the table by global id.\n\
             fn world_triangle(gi: u32) -> TriangleRecord {\n    return triangles[gi];\n}\n\
             fn world_triangle_flags(gi: u32) -> u32 {\n    return triangles[gi].flags;\n}\n",
        ),
        Some((group, binding)) => format!(
            "@group({group}) @binding({binding}) var<storage, read> placements: array<PlacementRecord>;\n\
             @group({group}) @binding({}) var<storage, read> mesh_words: array<u32>;\n{}",
            binding + 1,
            include_str!("shaders/world_triangles.wgsl")
        ),
    }
}

/// `world_triangle_normals(gi, tri)`, the corner normals of global triangle `gi` whose
/// record `world_triangle` gave, for a stage that includes [`world_triangles_wgsl`] and
/// `shaders/surface.wgsl` and binds `normals: array<f32>` (nine per record).
pub fn world_normals_wgsl(by_reference: bool) -> String {
    match by_reference {
        false => String::from(
            "// Corner normals, every object stored (hyrt_gpu::world_triangles): nine floats per global id.\n\
             fn world_triangle_normals(gi: u32, tri: TriangleRecord) -> array<vec3<f32>, 3> {\n    \
             return array<vec3<f32>, 3>(corner_normal(gi, 0u), corner_normal(gi, 1u), corner_normal(gi, 2u));\n}\n",
        ),
        true => include_str!("shaders/world_normals.wgsl").to_string(),
    }
}

/// The binding the bounce kernels read triangle flags from, at `binding` of `group`, and
/// `triangle_flags(object, gi)`: the triangle table (`triangles[gi].flags`), or with
/// objects `by_reference` the placements (`placements[object].flags`: an object's
/// triangles share its flags). Bind [`crate::buffers::SceneBuffers::flags_table`] there.
pub fn triangle_flags_wgsl(group: u32, binding: u32, by_reference: bool) -> String {
    let (declaration, read) = match by_reference {
        false => ("triangles: array<TriangleRecord>", "triangles[gi].flags"),
        true => ("placements: array<PlacementRecord>", "placements[object].flags"),
    };
    format!(
        "// Triangle flags (hyrt_gpu::world_triangles::triangle_flags_wgsl).\n\
         @group({group}) @binding({binding}) var<storage, read> {declaration};\n\
         fn triangle_flags(object: u32, gi: u32) -> u32 {{\n    return {read};\n}}\n"
    )
}

/// The accessors of a scene with objects by reference with all they need, for a standalone
/// kernel (`tests/world_triangles_kernels.rs`): the generated records, the ray constants and
/// surface kernels, `rounded` and `mul` over `params.zero`, and the tables bound in group 0
/// from `binding` on: `params: FrameParams` (uniform), `triangles`, `normals`, `placements`,
/// `mesh_words` (and `objects` declared at `binding + 5` for the surface kernels, unread
/// unless the entry point calls `surface_at`). The caller appends its entry point.
pub fn by_reference_kernels_wgsl(binding: u32) -> String {
    use crate::shader::{preamble, ray_wgsl, surface_wgsl, EXACT_PRODUCTS};
    format!(
        "{}{}@group(0) @binding({binding}) var<uniform> params: FrameParams;\n\
         @group(0) @binding({}) var<storage, read> triangles: array<TriangleRecord>;\n\
         @group(0) @binding({}) var<storage, read> normals: array<f32>;\n\
         @group(0) @binding({}) var<storage, read> objects: array<ObjectRecord>;\n{EXACT_PRODUCTS}{}\n{}\n{}",
        preamble(),
        ray_wgsl(),
        binding + 1,
        binding + 2,
        binding + 5,
        surface_wgsl(),
        world_triangles_wgsl(Some((0, binding + 3))),
        world_normals_wgsl(true),
    )
}

#[cfg(test)]
mod tests {
    use crate::shader::inexact_operations;
    use crate::texture::Specialization;

    /// Every stage that reads world triangles parses, validates and uses only exact
    /// operations with its accessors of either kind (stored, by reference), without a
    /// device: `reconstruction`, `visibility_raster` (both modes, both id sources),
    /// `bounce_trace` and `bounce_shading`.
    #[test]
    fn stages_parse_with_either_kind_of_world_triangles() {
        for by_reference in [false, true] {
            let s = Specialization { by_reference, two_level: by_reference, ..Specialization::PLAIN };
            let mut sources = vec![
                ("reconstruction", crate::reconstruction::shader_source(by_reference)),
                ("bounce_trace", crate::bounce_trace::shader_source(s)),
                ("bounce_shading", crate::bounce_shading::shader_source(s)),
            ];
            for primitive_index in [false, true] {
                let raster = crate::visibility_raster::shader_source(primitive_index, true, by_reference);
                sources.push(("visibility_raster", raster));
            }
            for (stage, source) in sources {
                assert_eq!(inexact_operations(&source), Ok(Vec::new()), "{stage}, by reference: {by_reference}");
            }
        }
    }

    /// The same stages with their tables in pages ([`crate::paging`]: three pages of the
    /// world records, two of the leaf slots and of the nodes, three of the surface tables'
    /// words, three of the placements and objects, two of the instances and of the lights)
    /// parse, validate and use only exact operations, and read no paged table but through
    /// its accessor (nor its `arrayLength`).
    #[test]
    fn stages_parse_with_tables_in_pages() {
        use crate::paging::{paged_source, TablePages};
        let pages = TablePages {
            shift: 20,
            triangles: 3,
            slots: 2,
            nodes: 2,
            word_shift: 24,
            surface: 3,
            mesh_words: 2,
            object_shift: 19,
            placements: 3,
            objects: 3,
            instances: 2,
            lights: 2,
        };
        for by_reference in [false, true] {
            let s = Specialization { by_reference, two_level: by_reference, pages, ..Specialization::PLAIN };
            let [normal_mapping, secondary_normal_mapping] =
                crate::reconstruction::NormalMapping::shader_sources(pages);
            let mut sources = vec![
                ("reconstruction", paged_source(&crate::reconstruction::shader_source(by_reference), pages)),
                ("bounce_trace", crate::bounce_trace::shader_source(s)),
                ("bounce_shading", crate::bounce_shading::shader_source(s)),
                ("rt_shading", crate::rt_shading::shader_source(s)),
                ("rt_shading (bounces)", crate::rt_shading::bouncing_shader_source(s)),
                ("raster_shading", crate::raster_shading::shader_source(s)),
                ("secondary_rays", crate::secondary_rays::shader_source(s)),
                ("shadow_rays", crate::shadow_rays::shader_source(s)),
                ("normal mapping", normal_mapping),
                ("secondary normal mapping", secondary_normal_mapping),
                ("compaction", paged_source(&crate::compaction::compaction_wgsl(), pages.lights_only())),
                ("shadow_denoise", paged_source(&crate::shadow_denoise::shadow_denoise_wgsl(), pages.lights_only())),
            ];
            for primitive_index in [false, true] {
                let raster = crate::visibility_raster::shader_source(primitive_index, true, by_reference);
                sources.push(("visibility_raster", paged_source(&raster, pages)));
            }
            for (stage, source) in sources {
                assert_eq!(inexact_operations(&source), Ok(Vec::new()), "{stage}, by reference: {by_reference}");
                assert!(!source.contains("arrayLength(&placements)"), "{stage}: the placements' length in pages");
                let tables = [
                    "triangles",
                    "normals",
                    "bvh_nodes",
                    "bvh_leaf_triangles",
                    "bvh_prim_indices",
                    "surface",
                    "mesh_words",
                    "placements",
                    "objects",
                    "instances",
                    "lights",
                ];
                for table in tables {
                    let pattern = format!("{table}[");
                    let reads = source
                        .match_indices(&pattern)
                        .filter(|(i, _)| !source[..*i].ends_with(|c: char| c.is_ascii_alphanumeric() || c == '_'))
                        .count();
                    let accessor = usize::from(
                        source.contains(&format!("fn {table}_at(")) || source.contains(&format!("fn {table}_word(")),
                    );
                    // The accessor's own read of the first page is the only one left. The
                    // stages that read the triangle flags from the placements are compiled
                    // without the world records' pages (`Specialization::flags_pages`).
                    let flags_stage = ["bounce_shading", "rt_shading (bounces)", "secondary_rays"].contains(&stage);
                    let stored_flags =
                        flags_stage && by_reference && !["surface", "placements", "objects"].contains(&table);
                    assert!(reads <= accessor || stored_flags, "{stage}: {reads} reads of {table} past its pages");
                }
            }
        }
    }

    /// The flags accessor names the binding it is given and reads what each kind binds.
    #[test]
    fn triangle_flags_read_the_table_bound() {
        let stored = super::triangle_flags_wgsl(1, 4, false);
        assert!(stored.contains("@group(1) @binding(4) var<storage, read> triangles: array<TriangleRecord>;"));
        assert!(stored.contains("return triangles[gi].flags;"));
        let placed = super::triangle_flags_wgsl(0, 8, true);
        assert!(placed.contains("@group(0) @binding(8) var<storage, read> placements: array<PlacementRecord>;"));
        assert!(placed.contains("return placements[object].flags;"));
    }
}
