//! Stage `shadow_rays` on the GPU: trace the compacted shadow-ray list through the
//! BVH, any hit with early exit (mirrors [`hyrt_core::bvh::Bvh::occluded_filtered`] with
//! the alpha test of [`hyrt_core::kernels::texture::alpha_accepts`], the CPU's reference
//! traversal, and [`hyrt_core::kernels::shadow::shadow_code`]): a hit on an alpha-tested
//! triangle where its alpha fails the cutoff is no hit.
//!
//! Reads `frame.rays`, `frame.ray_count` (indirect dispatch: one thread per ray,
//! [`SHADOW_RAYS_WORKGROUP_SIZE`] per workgroup, threads past the count exit),
//! `frame.params`, `frame.slot_params` (the mask's slots per surface), `scene.bvh_nodes`,
//! `scene.bvh_leaf_triangles`,
//! `scene.surface` (the alpha test's tables, and each object's first triangle: a leaf
//! triangle's global index without a 9th storage buffer for the BVH's `prim_indices`).
//! Writes `frame.occluded` (1 occluded, 0 reached the light, per ray) and
//! `frame.shadow` (cleared to `SHADOW_NO_RAY`, then `SHADOW_LIT` or
//! `SHADOW_OCCLUDED` at `pixel * slots + light` for every ray: `slots` the frame's mask
//! slots per surface, `frame.slot_params`, and a ray's `light` its slot; one slot per
//! light without area lights and ambient occlusion).
//!
//! The WGSL (`shaders/ray.wgsl`, `shaders/shadow_rays.wgsl`) mirrors the core ray
//! kernels function by function and operation by operation, every product kept
//! unfused, so its decisions are the CPU's, bit for bit, on a device that rounds f32
//! operations as IEEE 754 (lavapipe): also the tie rule of an exactly-zero edge
//! function, decided by the exact sign both sides compute in f32
//! (`hyrt_core::kernels::ray::edge_sign_exact`).

use crate::buffers::{FrameBuffers, ListBuffers, SceneBuffers};
use crate::paging::Table;
use crate::shader::{
    bind_paged_buffers, preamble, ray_wgsl, shader_module, slot_params_wgsl, storage_entry, uniform_entry,
    EXACT_PRODUCTS,
};
pub use crate::shader::{MAX_WORKGROUPS_PER_DIMENSION, SHADOW_RAYS_WORKGROUP_SIZE};
use crate::texture::{texture_wgsl, Specialization};
use crate::GpuContext;

/// The paged tables the stage reads ([`crate::paging`]; the instances with two levels).
const PAGED_TABLES: [Table; 4] = [Table::Nodes, Table::LeafTriangles, Table::Surface, Table::Instances];

/// The WGSL of the stage for scenes that need `s`.
pub fn shader_source(s: Specialization) -> String {
    // The walk of the scene's BVH: one tree, or two levels with the instances' binding.
    let walk = if s.two_level {
        concat!(include_str!("shaders/instance.wgsl"), include_str!("shaders/shadow_two_level.wgsl"))
    } else {
        "fn trace_occluded(ray: RayRecord) -> bool {\n    return occluded_any(ray);\n}\n"
    };
    let source = preamble()
        + &slot_params_wgsl()
        + &ray_wgsl()
        + EXACT_PRODUCTS
        + &texture_wgsl()
        + include_str!("shaders/shadow_rays.wgsl")
        + walk;
    crate::paging::paged_source(&source, s.pages)
}

/// The `shadow_rays` stage: one pipeline, one bind group layout.
pub struct ShadowRaysStage {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// Compiled for a two-level scene: binds `SceneBuffers::instances` too.
    two_level: bool,
}

impl ShadowRaysStage {
    /// Compile the stage's pipeline for scenes without surface tables.
    pub fn new(ctx: &GpuContext) -> Self {
        Self::specialized(ctx, Specialization::PLAIN)
    }

    /// Compile the stage's pipeline for scenes whose surface tables need `s`.
    pub fn specialized(ctx: &GpuContext, s: Specialization) -> Self {
        let module = shader_module(ctx, "shadow_rays", &shader_source(s));
        let mut entries = vec![
            uniform_entry(0),
            storage_entry(1, true),
            storage_entry(2, true),
            storage_entry(3, true),
            storage_entry(4, true),
            storage_entry(5, false),
            storage_entry(6, false),
            uniform_entry(7),
            storage_entry(8, false),
            storage_entry(9, true),
            uniform_entry(10),
            uniform_entry(11),
        ];
        if s.two_level {
            entries.push(storage_entry(12, true));
        }
        entries.extend(s.pages.layout_entries(&PAGED_TABLES));
        let layout = ctx.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shadow_rays"),
            entries: &entries,
        });
        let pipeline_layout = module.pipeline_layout("shadow_rays", &[(&layout, &entries)]);
        let pipeline = module.compute_pipeline("shadow_rays", "shadow_rays", &pipeline_layout, &s.constants());
        ShadowRaysStage { pipeline, layout, two_level: s.two_level }
    }

    /// Clear `frame.shadow`, then trace every ray of `frame.rays` (count and
    /// dispatch size from `frame.ray_count`, written by `compaction`).
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        self.encode_list(ctx, encoder, scene, frame, &frame.primary_list(), timing)
    }

    /// The stage over one list: clear its shadow codes, trace its shadow rays.
    pub fn encode_list(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        list: &ListBuffers,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let buffers = [
            &frame.params,
            list.shadow_rays,
            list.shadow_ray_count,
            scene.bvh_nodes.first(),
            scene.bvh_leaf_triangles.first(),
            list.occluded,
            list.shadow,
            list.params,
            list.counters,
            scene.surface.words.first(),
            &scene.surface.layout,
            &frame.slot_params,
            scene.instances.first(),
        ];
        let bound = if self.two_level { &buffers[..] } else { &buffers[..12] };
        let further = scene.further_pages(&PAGED_TABLES);
        let bind_group = bind_paged_buffers(ctx, "shadow_rays", &self.layout, bound, further);
        // SHADOW_NO_RAY is 0.
        encoder.clear_buffer(list.shadow, 0, None);
        let mut pass = crate::timing::begin_timed_pass(encoder, "shadow_rays", timing);
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.dispatch_workgroups_indirect(list.shadow_ray_count, 4);
    }
}
