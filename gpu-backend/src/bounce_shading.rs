//! Stage `bounce_shading` on the GPU: the radiance each ray of bounce `d` brings back to
//! its parent, deepest bounce first, each ray adding its children's in a fixed order:
//! bit for bit `hyrt_cpu::bounce_shading` (per ray
//! [`hyrt_core::kernels::bounce::shade_secondary_hit`]: the environment on a miss, the
//! bouncing shader on mirrors and glass, the ray-traced shader on other ray-traced
//! objects, the raster shader on rasterized ones).
//!
//! Reads the depth's rays, count (indirect dispatch), hits, surfaces and shadow codes
//! (their slots per `frame.slot_params`: area lights' samples and occlusion rays as for
//! the primary hits);
//! unless it is the plan's deepest bounce, the next depth's links and radiance; objects,
//! triangles, lights (with an emitter light, the emitter table its samples pick from,
//! packed after the records: [`crate::buffers::SceneBuffers::lights`]), the scene's
//! environment and ambient light (its image-based light's
//! texels under the glTF model), and the surface tables (each hit's object shaded as
//! [`hyrt_core::kernels::texture::Materials::at`] sees it, its footprint the ray's cone
//! widened over the hit's distance). Writes one linear RGBA value per ray.
//! Also home of the WGSL the radiance-gathering stages share (this one and `rt_shading`
//! with bounces).

use crate::buffers::{FrameBuffers, SceneBuffers};
use crate::shader::{environment_wgsl, radiance_source, specialized_pipeline, storage_entry, uniform_entry};
use crate::texture::Specialization;
use crate::GpuContext;

/// The paged tables the stage reads besides the triangle flags' ([`crate::paging`]).
const PAGED_TABLES: [crate::paging::Table; 3] =
    [crate::paging::Table::Objects, crate::paging::Table::Lights, crate::paging::Table::Surface];

/// The `bounce_shading` stage: one pipeline.
pub struct BounceShadingStage {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

/// The WGSL of the stage for scenes that need `s` (its triangle flags read as
/// [`crate::world_triangles::triangle_flags_wgsl`] says).
pub fn shader_source(s: Specialization) -> String {
    let source = radiance_source(&format!(
        "{}\n{}\n{}",
        environment_wgsl(),
        include_str!("shaders/bounce_shading.wgsl"),
        crate::world_triangles::triangle_flags_wgsl(0, 8, s.by_reference)
    ));
    crate::paging::paged_source(&source, s.flags_pages())
}

impl BounceShadingStage {
    /// Compile the stage's pipeline for scenes whose surface tables need `s`.
    pub fn specialized(ctx: &GpuContext, s: Specialization) -> Self {
        let source = shader_source(s);
        let mut entries = vec![uniform_entry(0), uniform_entry(1)];
        entries.extend((2..=9).map(|i| storage_entry(i, true)));
        entries.push(uniform_entry(10));
        entries.extend((11..=13).map(|i| storage_entry(i, true)));
        entries.push(storage_entry(14, false));
        entries.extend([storage_entry(15, true), uniform_entry(16)]);
        entries.extend([uniform_entry(17), storage_entry(18, true), uniform_entry(19)]);
        entries.extend(s.flags_layout_entries(&PAGED_TABLES));
        let (pipeline, layout) = specialized_pipeline(ctx, "bounce_shading", &source, &entries, &s.shading_constants());
        BounceShadingStage { pipeline, layout }
    }

    /// Shade the rays of `frame.bounces[depth - 1]`, gathering from depth `depth + 1`
    /// unless `last`.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        depth: u32,
        last: bool,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let b = &frame.bounces[depth as usize - 1];
        let (links, child_radiance) = match last {
            true => (&frame.empty, &frame.empty),
            false => {
                let c = &frame.bounces[depth as usize];
                (&c.links, &c.radiance)
            }
        };
        let bind_group = crate::shader::bind_paged_buffers(
            ctx,
            "bounce_shading",
            &self.layout,
            &[
                &frame.params,
                &b.list,
                &b.rays,
                &b.ray_count,
                &b.hits,
                &b.surfaces,
                &b.shadow,
                scene.objects.first(),
                scene.flags_table(),
                scene.lights.first(),
                &scene.environment,
                &scene.environment_texels,
                links,
                child_radiance,
                &b.radiance,
                scene.surface.words.first(),
                &scene.surface.layout,
                &scene.ambient_light,
                &scene.ambient_texels,
                &frame.slot_params,
            ],
            scene.flags_table_pages(&PAGED_TABLES),
        );
        crate::shader::encode_list_pass(encoder, "bounce_shading", &self.pipeline, &bind_group, &b.ray_count, timing);
    }
}
