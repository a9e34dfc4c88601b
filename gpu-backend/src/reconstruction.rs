//! `reconstruction` (paper eq. 1): rebuild the world-space surface at every pixel
//! from the visibility G-buffer, one thread per pixel (8x8 groups), mirroring
//! [`hyrt_core::kernels::reconstruction::reconstruct_texel`] and the kernels it calls
//! (`hyrt_core::kernels::barycentric::{reconstruct_position, position_error_bound,
//! interpolate_normal, geometric_normal}`, `hyrt_core::kernels::shading::orient_to_seen_side`)
//! in `shaders/reconstruction.wgsl`, operation for operation. Normalization is
//! `sqrt` then division, as on the CPU (WGSL's `inverseSqrt` is not exact).
//!
//! Reads: `frame.gbuffer`, `frame.camera` (eye, image size), `frame.params` (the band),
//! `scene.triangles`,
//! `scene.normals`, `scene.objects` (`first_triangle`). Writes: `frame.surfaces`
//! (every texel of the camera's image).
//!
//! Every product that feeds a sum is kept unfused (`mul`), so on a device that rounds
//! f32 operations as IEEE 754 (lavapipe) the surfaces are the CPU's bits; WGSL allows
//! a division within 2.5 ulp, where a device may differ by a few ulp (the bounds are in
//! `tests/reconstruction.rs`); ids are identical.

use hyrt_core::formats::wgsl::declarations;
use hyrt_core::frame::PrimaryBarycentrics;

use crate::buffers::{FrameBuffers, SceneBuffers};
use crate::shader::{ray_wgsl, surface_wgsl};
use crate::GpuContext;

/// Side of the square workgroup (`@workgroup_size(8, 8, 1)`).
const GROUP: u32 = 8;

const SHADER: &str = include_str!("shaders/reconstruction.wgsl");

/// The WGSL of the stage: the generated records and format constants, the ray kernels
/// with their exact f32 constants (the watertight test of re-intersected barycentrics),
/// the surface kernels, then the shader.
pub fn shader_source() -> String {
    format!("{}{}\n{}\n{}", declarations(), ray_wgsl(), surface_wgsl(), SHADER)
}

/// The `reconstruction` stage: one compute pipeline per source of barycentrics
/// (`main`: the raster's; `main_reintersected`: the camera rays', mirroring
/// `hyrt_core::kernels::reconstruction::reconstruct_texel_reintersected` and
/// `hyrt_core::kernels::camera::primary_ray`).
pub struct ReconstructionStage {
    /// (pipeline, its bind group layout): the raster's barycentrics, then re-intersected.
    raster: (wgpu::ComputePipeline, wgpu::BindGroupLayout),
    reintersected: (wgpu::ComputePipeline, wgpu::BindGroupLayout),
}

impl ReconstructionStage {
    /// Build the pipeline.
    pub fn new(ctx: &GpuContext) -> Self {
        let module = ctx.device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("reconstruction"),
            source: wgpu::ShaderSource::Wgsl(shader_source().into()),
        });
        let pipeline = |entry: &str| {
            let p = ctx.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("reconstruction"),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            });
            let layout = p.get_bind_group_layout(0);
            (p, layout)
        };
        ReconstructionStage { raster: pipeline("main"), reintersected: pipeline("main_reintersected") }
    }

    /// Record the pass over `frame.band` (the frame parameters describe it; the camera
    /// uniform, the whole image).
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        barycentrics: PrimaryBarycentrics,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        if frame.width == 0 || frame.band.rows == 0 {
            return;
        }
        let (pipeline, layout) = match barycentrics {
            PrimaryBarycentrics::Raster => &self.raster,
            PrimaryBarycentrics::Reintersected => &self.reintersected,
        };
        let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("reconstruction"),
            layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: scene.triangles.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: scene.normals.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: scene.objects.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: frame.camera.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: frame.gbuffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 5, resource: frame.surfaces.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: frame.params.as_entire_binding() },
            ],
        });
        let mut pass = crate::timing::begin_timed_pass(encoder, "reconstruction", timing);
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(frame.width.div_ceil(GROUP), frame.band.rows.div_ceil(GROUP), 1);
    }
}
