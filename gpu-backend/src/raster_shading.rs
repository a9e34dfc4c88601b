//! Stage `raster_shading` (per pixel [`hyrt_core::kernels::shading::shade_raster_pixel`],
//! as [`hyrt_cpu::raster_shading`]): the ordinary
//! raster shader (paper 3.4), Lambert from every light whose shadow ray reached it
//! plus ambient, on the pixels of rasterized objects, and on those of ray-traced
//! objects only when the composition weight is below 1; one compute invocation per pixel.
//!
//! Reads `frame.surfaces`, `frame.shadow`, `scene.objects`, `scene.lights`,
//! `frame.params` (width, height, light count, weight).
//! Writes `frame.raster`: linear RGBA; `BACKGROUND` with alpha 1 on pixels without
//! a hit, (0, 0, 0, 0) on ray-traced pixels when the weight is 1, alpha 1 where shaded.

use crate::buffers::{FrameBuffers, SceneBuffers};
use crate::shader::{
    bind_buffers, compute_pipeline, encode_pixel_pass, storage_entry, surface_shading_source, uniform_entry,
};
use crate::GpuContext;

/// The `raster_shading` stage.
pub struct RasterShadingStage {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl RasterShadingStage {
    /// Compile the stage's pipeline.
    pub fn new(ctx: &GpuContext) -> Self {
        let source = surface_shading_source(include_str!("shaders/raster_shading.wgsl"));
        let (pipeline, layout) = compute_pipeline(
            ctx,
            "raster_shading",
            &source,
            &[
                storage_entry(0, true),  // surfaces
                storage_entry(1, true),  // shadow
                storage_entry(2, true),  // objects
                storage_entry(3, true),  // lights
                uniform_entry(4),        // params
                storage_entry(5, false), // raster
            ],
        );
        RasterShadingStage { pipeline, layout }
    }

    /// Record the stage: `frame.raster` from `frame.surfaces`, `frame.shadow`,
    /// `scene.objects`, `scene.lights` and `frame.params`.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let bind_group = bind_buffers(
            ctx,
            "raster_shading",
            &self.layout,
            &[&frame.surfaces, &frame.shadow, &scene.objects, &scene.lights, &frame.params, &frame.raster],
        );
        encode_pixel_pass(encoder, "raster_shading", &self.pipeline, &bind_group, frame.width, frame.band.rows, timing);
    }
}
