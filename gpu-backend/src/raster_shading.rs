//! Stage `raster_shading` (per pixel [`hyrt_core::kernels::shading::shade_raster_pixel`],
//! as `hyrt_cpu::raster_shading`): the ordinary
//! raster shader (paper 3.4), Lambert from every light whose shadow ray reached it
//! plus ambient, on the pixels of rasterized objects, and on those of ray-traced
//! objects only when the composition weight is below 1; one compute invocation per pixel.
//!
//! Each pixel's object is shaded with its record as the pixel sees it
//! (`shaders/primary_object.wgsl`, mirror of `hyrt_cpu::raster_shading::Primary::object`):
//! where materials vary (textures, vertex colours), its base colour textured at the
//! G-buffer's barycentrics and the eye's footprint.
//!
//! Reads `frame.surfaces`, `frame.shadow`, `scene.objects`, `scene.lights`,
//! `frame.params` (width, height, light count, weight, cone spread), `frame.camera` (the
//! eye), `frame.slot_params` (the mask's slots), `scene.ambient_light` (and under an
//! image-based light `scene.ambient_texels`); where materials vary also `frame.gbuffer`
//! and `scene.surface`. Area lights and ambient occlusion as in `rt_shading`
//! ([`crate::rt_shading`]), the denoised visibility too (`frame.visibility`, binding 13),
//! and an emitter light's samples from the emitter table in `scene.lights`
//! ([`crate::buffers::SceneBuffers::lights`]).
//! Writes `frame.raster`: linear RGBA; `BACKGROUND` with alpha 1 on pixels without
//! a hit, (0, 0, 0, 0) on ray-traced pixels when the weight is 1, alpha 1 where shaded.

use crate::buffers::{FrameBuffers, SceneBuffers};
use crate::paging::{paged_source, Table};
use crate::shader::{
    bind_paged_buffers, encode_pixel_pass, specialized_pipeline, storage_entry, surface_shading_source_for,
    uniform_entry,
};
use crate::texture::Specialization;
use crate::GpuContext;

/// The WGSL of the stage for scenes that need `s`.
pub fn shader_source(s: Specialization) -> String {
    let source = surface_shading_source_for(
        &format!("{}\n{}", include_str!("shaders/primary_object.wgsl"), include_str!("shaders/raster_shading.wgsl")),
        s.denoised.then_some(VISIBILITY),
    );
    paged_source(&source, s.pages)
}

/// The paged tables the stage reads ([`crate::paging`]).
const PAGED_TABLES: [Table; 3] = [Table::Objects, Table::Lights, Table::Surface];

/// The `raster_shading` stage.
pub struct RasterShadingStage {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// Compiled for denoised frames: binds `frame.visibility`.
    denoised: bool,
}

/// The binding of `frame.visibility` in a denoised frame.
const VISIBILITY: u32 = 13;

impl RasterShadingStage {
    /// Compile the stage's pipeline for scenes without surface tables.
    pub fn new(ctx: &GpuContext) -> Self {
        Self::specialized(ctx, Specialization::PLAIN)
    }

    /// Compile the stage's pipeline for scenes whose surface tables need `s`.
    pub fn specialized(ctx: &GpuContext, s: Specialization) -> Self {
        let source = shader_source(s);
        let visibility = [storage_entry(VISIBILITY, true)];
        let (pipeline, layout) = specialized_pipeline(
            ctx,
            "raster_shading",
            &source,
            &[
                &[
                    storage_entry(0, true),  // surfaces
                    storage_entry(1, true),  // shadow
                    storage_entry(2, true),  // objects
                    storage_entry(3, true),  // lights
                    uniform_entry(4),        // params
                    storage_entry(5, false), // raster
                    storage_entry(6, true),  // gbuffer
                    uniform_entry(7),        // camera
                    storage_entry(8, true),  // surface tables
                    uniform_entry(9),        // surface layout
                    uniform_entry(10),       // ambient light
                    storage_entry(11, true), // ambient light texels
                    uniform_entry(12),       // slot params
                ][..],
                if s.denoised { &visibility } else { &[] },
                &s.pages.layout_entries(&PAGED_TABLES),
            ]
            .concat(),
            &s.shading_constants(),
        );
        RasterShadingStage { pipeline, layout, denoised: s.denoised }
    }

    /// Record the stage: `frame.raster` from `frame.surfaces`, `frame.shadow`,
    /// `scene.objects`, `scene.lights` and `frame.params` (and, where materials vary,
    /// `frame.gbuffer`, `frame.camera` and `scene.surface`).
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let visibility = [&frame.visibility];
        let bind_group = bind_paged_buffers(
            ctx,
            "raster_shading",
            &self.layout,
            &[
                &[
                    &frame.surfaces,
                    &frame.shadow,
                    scene.objects.first(),
                    scene.lights.first(),
                    &frame.params,
                    &frame.raster,
                    &frame.gbuffer,
                    &frame.camera,
                    scene.surface.words.first(),
                    &scene.surface.layout,
                    &scene.ambient_light,
                    &scene.ambient_texels,
                    &frame.slot_params,
                ][..],
                if self.denoised { &visibility } else { &[] },
            ]
            .concat(),
            scene.further_pages(&PAGED_TABLES),
        );
        encode_pixel_pass(encoder, "raster_shading", &self.pipeline, &bind_group, frame.width, frame.band.rows, timing);
    }
}
