//! Stage `bounce_trace` on the GPU: the closest hit of each reflection and refraction
//! ray of one bounce through the BVH of the whole scene (ties to the lower triangle
//! index) and the surface it hit, rebuilt from the hit's barycentrics (paper eq. 1
//! again) on the side the ray saw: bit for bit `hyrt_cpu::bounce_trace`
//! ([`hyrt_core::bvh::Bvh::closest_hit_filtered`] walked as `traverse` walks it, the exact
//! watertight test of `shaders/ray.wgsl`, the alpha test of
//! [`hyrt_core::kernels::texture::alpha_accepts`] on hits on alpha-tested triangles,
//! [`hyrt_core::kernels::reconstruction::reconstruct_hit`] in `shaders/surface.wgsl`).
//!
//! Reads the depth's rays and count (indirect dispatch, one thread per ray), the BVH,
//! triangles, normals, the object records (offset errors) and the surface tables (alpha tests); with two levels
//! the instances too, and with objects by reference their placements and meshes
//! ([`crate::world_triangles`]). Writes one `HitRecord` and one `SurfaceRecord` per ray and
//! counts the hits.

use crate::buffers::{FrameBuffers, SceneBuffers};
use crate::paging::Table;
use crate::shader::{bind_paged_buffers, specialized_pipeline, surface_wgsl, EXACT_PRODUCTS};
use crate::shader::{preamble, ray_wgsl, storage_entry, uniform_entry};
use crate::texture::{texture_wgsl, Specialization};
use crate::GpuContext;

/// The WGSL of the stage for scenes that need `s`: the generated records, the ray kernels,
/// the surface kernels, the world-triangle accessors ([`crate::world_triangles`]), the
/// texture kernels, the shader and the walk of the scene's BVH (one tree, or two levels
/// with the instances' binding).
pub fn shader_source(s: Specialization) -> String {
    use crate::world_triangles::{world_normals_wgsl, world_triangles_wgsl};
    let walk = if s.two_level {
        concat!(include_str!("shaders/instance.wgsl"), include_str!("shaders/bounce_two_level.wgsl"))
    } else {
        "fn trace_closest(ray: RayRecord) -> ClosestHit {\n    return closest_hit(ray);\n}\n"
    };
    let source = preamble()
        + &ray_wgsl()
        + EXACT_PRODUCTS
        + &surface_wgsl()
        + &world_triangles_wgsl(s.by_reference.then_some((0, BY_REFERENCE_BINDING)))
        + &world_normals_wgsl(s.by_reference)
        + &texture_wgsl()
        + include_str!("shaders/bounce_trace.wgsl")
        + walk;
    crate::paging::paged_source(&source, s.pages)
}

/// The paged tables the stage reads ([`crate::paging`]).
const PAGED_TABLES: [Table; 10] = [
    Table::Nodes,
    Table::LeafTriangles,
    Table::PrimIndices,
    Table::Triangles,
    Table::Normals,
    Table::Surface,
    Table::MeshWords,
    Table::Objects,
    Table::Instances,
    Table::Placements,
];

/// The `bounce_trace` stage: one pipeline.
pub struct BounceTraceStage {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// Compiled for a two-level scene: binds `SceneBuffers::instances` too.
    two_level: bool,
    /// Compiled for a scene with objects by reference: binds the instances (at 14, read or
    /// not), then `SceneBuffers::placements` and `SceneBuffers::mesh_words` at 15 and 16.
    by_reference: bool,
}

/// Where the stage's by-reference bindings start (`placements`, then `mesh_words`).
const BY_REFERENCE_BINDING: u32 = 15;

impl BounceTraceStage {
    /// Compile the stage's pipeline for scenes whose surface tables need `s`.
    pub fn specialized(ctx: &GpuContext, s: Specialization) -> Self {
        let source = shader_source(s);
        let mut entries = vec![uniform_entry(0)];
        entries.extend((1..=7).map(|i| storage_entry(i, true)));
        entries.extend((8..=10).map(|i| storage_entry(i, false)));
        entries.extend([storage_entry(11, true), uniform_entry(12), storage_entry(13, true)]);
        if s.two_level || s.by_reference {
            entries.push(storage_entry(14, true));
        }
        if s.by_reference {
            entries.extend([storage_entry(BY_REFERENCE_BINDING, true), storage_entry(BY_REFERENCE_BINDING + 1, true)]);
        }
        entries.extend(s.pages.layout_entries(&PAGED_TABLES));
        let (pipeline, layout) = specialized_pipeline(ctx, "bounce_trace", &source, &entries, &s.constants());
        BounceTraceStage { pipeline, layout, two_level: s.two_level, by_reference: s.by_reference }
    }

    /// Trace the rays of `frame.bounces[depth - 1]`.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        depth: u32,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let b = &frame.bounces[depth as usize - 1];
        let buffers = [
            &frame.params,
            &b.rays,
            &b.ray_count,
            scene.bvh_nodes.first(),
            scene.bvh_leaf_triangles.first(),
            scene.bvh_prim_indices.first(),
            scene.triangles.first(),
            scene.normals.first(),
            &b.hits,
            &b.surfaces,
            &b.counters,
            scene.surface.words.first(),
            &scene.surface.layout,
            scene.objects.first(),
            scene.instances.first(),
            scene.placements.first(),
            scene.mesh_words.first(),
        ];
        let bound = match (self.by_reference, self.two_level) {
            (true, _) => &buffers[..],
            (false, true) => &buffers[..15],
            (false, false) => &buffers[..14],
        };
        let further = scene.further_pages(&PAGED_TABLES);
        let bind_group = bind_paged_buffers(ctx, "bounce_trace", &self.layout, bound, further);
        crate::shader::encode_list_pass(encoder, "bounce_trace", &self.pipeline, &bind_group, &b.ray_count, timing);
    }
}
