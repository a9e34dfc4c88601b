//! Stage `composition` (per pixel [`hyrt_core::kernels::shading::compose`], as
//! `hyrt_cpu::composition`): the final image as
//! the weighted mean `(1 - weight) * raster + weight * rt` (paper 3.5) where the
//! ray-traced image has coverage (alpha > 0), with alpha 1; the raster texel
//! unchanged elsewhere. One compute invocation per pixel.
//!
//! Reads `frame.raster`, `frame.rt`, `frame.params` (width, height, weight).
//! Writes `frame.final_image` (linear RGBA).

use crate::buffers::{FrameBuffers, SceneBuffers};
use crate::shader::{bind_buffers, compute_pipeline, encode_pixel_pass, shading_source, storage_entry, uniform_entry};
use crate::GpuContext;

/// The `composition` stage.
pub struct CompositionStage {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl CompositionStage {
    /// Compile the stage's pipeline.
    pub fn new(ctx: &GpuContext) -> Self {
        let source = shading_source(include_str!("shaders/composition.wgsl"));
        let (pipeline, layout) = compute_pipeline(
            ctx,
            "composition",
            &source,
            &[
                storage_entry(0, true),  // raster
                storage_entry(1, true),  // rt
                uniform_entry(2),        // params
                storage_entry(3, false), // final_image
            ],
        );
        CompositionStage { pipeline, layout }
    }

    /// Record the stage: `frame.final_image` from `frame.raster`, `frame.rt` and
    /// `frame.params`. `scene` is not read (the signature is every stage's).
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        _scene: &SceneBuffers,
        frame: &FrameBuffers,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let bind_group = bind_buffers(
            ctx,
            "composition",
            &self.layout,
            &[&frame.raster, &frame.rt, &frame.params, &frame.final_image],
        );
        encode_pixel_pass(encoder, "composition", &self.pipeline, &bind_group, frame.width, frame.band.rows, timing);
    }
}
