//! Stage `secondary_rays` on the GPU: the surfaces of depth `d - 1` that bounce
//! (ray-traced mirrors and glass) spawn the reflection and refraction rays of depth `d`,
//! compacted into one list in their parents' order, reflection before refraction, bit
//! for bit the list of `hyrt_cpu::secondary_rays` (per parent and lobe the kernels of
//! [`hyrt_core::kernels::bounce`], mirrored in `shaders/bounce.wgsl`).
//!
//! Reads for `d = 1` the G-buffer, the primary surfaces and the camera (one parent per
//! pixel), else the rays, hits and surfaces of depth `d - 1` and their count (one parent
//! per live ray); objects, triangles, and the surface tables (each parent's object
//! shaded where it was hit, [`hyrt_core::kernels::texture::Materials::at`]: its base
//! colour weighs the lobes; the rays carry their footprint cone on). Writes the rays of
//! depth `d`, their count (`[count, dispatch_x, dispatch_y, 1]`, the indirect-dispatch
//! arguments of the depth's other stages: no count comes back to the CPU mid-frame),
//! each parent's `[reflection, refraction]` links (the child's index, or `INVALID_ID`),
//! and the depth's reflection and refraction counters. The list is compacted by the shared scan
//! ([`crate::scan`]) over two elements per parent slot.

use crate::buffers::{BounceBuffers, FrameBuffers, SceneBuffers};
use crate::scan::{scan_wgsl, ListScan};
use crate::shader::{bounce_wgsl, shading_source};
use crate::shader::{ray_wgsl, shader_module, storage_entry, uniform_entry};
use crate::texture::{materials_wgsl, texture_wgsl, Specialization};
use crate::GpuContext;

/// The paged tables the stage reads besides the triangle flags' ([`crate::paging`]).
const PAGED_TABLES: [crate::paging::Table; 2] = [crate::paging::Table::Objects, crate::paging::Table::Surface];

/// The WGSL of the stage for scenes that need `s` (its triangle flags read as
/// [`crate::world_triangles::triangle_flags_wgsl`] says).
pub fn shader_source(s: Specialization) -> String {
    let source = shading_source(
        &(ray_wgsl()
            + &texture_wgsl()
            + &materials_wgsl()
            + &bounce_wgsl()
            + include_str!("shaders/secondary_rays.wgsl")
            + &crate::world_triangles::triangle_flags_wgsl(1, 4, s.by_reference)
            + &scan_wgsl()),
    );
    crate::paging::paged_source(&source, s.flags_pages())
}

/// The `secondary_rays` stage: the shared scan over its module.
pub struct SecondaryRaysStage {
    scan: ListScan,
}

impl SecondaryRaysStage {
    /// Compile the stage's pipelines for scenes whose surface tables need `s`.
    pub fn specialized(ctx: &GpuContext, s: Specialization) -> Self {
        let module = shader_module(ctx, "secondary_rays", &shader_source(s));
        let mut entries = vec![uniform_entry(0), uniform_entry(1), uniform_entry(2)];
        entries.extend((3..=9).map(|i| storage_entry(i, true)));
        entries.extend((10..=12).map(|i| storage_entry(i, false)));
        entries.extend([storage_entry(13, true), uniform_entry(14)]);
        entries.extend(s.flags_layout_entries(&PAGED_TABLES));
        SecondaryRaysStage { scan: ListScan::new(ctx, "secondary_rays", &module, &entries, &s.constants()) }
    }

    /// Spawn the rays of `frame.bounces[depth - 1]` from the parents of depth
    /// `depth - 1`; clears the depth's counters first.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        depth: u32,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let b: &BounceBuffers = &frame.bounces[depth as usize - 1];
        let (parent_surfaces, parent_rays, parent_hits, live) = match depth {
            1 => (&frame.surfaces, &frame.empty, &frame.empty, &frame.pixel_count),
            _ => {
                let p = &frame.bounces[depth as usize - 2];
                (&p.surfaces, &p.rays, &p.hits, &p.ray_count)
            }
        };
        encoder.clear_buffer(&b.counters, 0, None);
        let buffers = [
            &frame.params,
            &b.list,
            &frame.camera,
            scene.objects.first(),
            scene.flags_table(),
            &frame.gbuffer,
            parent_surfaces,
            parent_rays,
            parent_hits,
            live,
            &b.rays,
            &b.links,
            &b.counters,
            scene.surface.words.first(),
            &scene.surface.layout,
        ];
        let further = scene.flags_table_pages(&PAGED_TABLES);
        self.scan.encode_paged(ctx, encoder, "secondary_rays", 2 * b.parents, &buffers, further, &b.ray_count, timing);
    }
}
