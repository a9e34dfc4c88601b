//! Stage `rt_shading` (per pixel [`hyrt_core::kernels::shading::shade_rt_pixel`], as
//! `hyrt_cpu::rt_shading`): shade the pixels of
//! ray-traced objects (paper 3.3) with Lambert + Blinn-Phong specular from every
//! light whose shadow ray reached it, plus ambient; one compute invocation per pixel.
//!
//! Each pixel's object is shaded with its record as the pixel sees it
//! (`shaders/primary_object.wgsl`; in frames with bounces the primary hit's parent,
//! `hyrt_core::kernels::bounce::primary_parent`): where materials vary (textures, vertex
//! colours), its base colour textured at the G-buffer's barycentrics and the eye's
//! footprint.
//!
//! Reads `frame.surfaces`, `frame.shadow`, `scene.objects`, `scene.lights`,
//! `frame.camera` (the eye), `frame.params` (width, height, light count, cone spread),
//! `frame.slot_params` (the mask's slots), `scene.ambient_light` (and under an
//! image-based light `scene.ambient_texels`); where materials vary also `frame.gbuffer`
//! and `scene.surface`. With area lights and ambient occlusion (pipelines specialized
//! with `STOCHASTIC`, [`Specialization::stochastic`]) each area light adds the mean of
//! its visible samples and the occlusion rays scale the ambient term
//! ([`hyrt_core::kernels::shading::sum_visible_lights`],
//! [`hyrt_core::kernels::soft_shadow::occluded_object`]); in a frame that denoised them
//! (pipelines specialized with [`Specialization::denoised`]) it also reads
//! `frame.visibility`, each area light adding the mean over its samples that traced a ray
//! times its filtered visibility and the filtered occlusion scaling the ambient term. An
//! emitter light's samples (emissive meshes as lights) read the emitter table packed into
//! `scene.lights` after the records ([`crate::buffers::SceneBuffers::lights`]; its length
//! in `frame.slot_params`); so does the bouncing pipeline ([`RtShadingBouncingStage`]).
//! Writes `frame.rt`: linear RGBA, alpha 1 on ray-traced pixels, (0, 0, 0, 0) elsewhere.
//!
//! Also home of the helpers the three shading stages share (WGSL assembly,
//! binding layouts, the pixel-grid dispatch, timestamp writes).

use crate::buffers::{FrameBuffers, SceneBuffers};
use crate::shader::{
    bind_paged_buffers, encode_pixel_pass, specialized_pipeline, storage_entry, surface_shading_source_for,
    uniform_entry,
};
use crate::texture::Specialization;
use crate::GpuContext;

/// The paged tables the stages read besides the triangle flags' ([`crate::paging`]).
const PAGED_TABLES: [crate::paging::Table; 3] =
    [crate::paging::Table::Objects, crate::paging::Table::Lights, crate::paging::Table::Surface];

/// The bindings of `shaders/rt_shading.wgsl`.
fn rt_entries() -> [wgpu::BindGroupLayoutEntry; 13] {
    [
        storage_entry(0, true),  // surfaces
        storage_entry(1, true),  // shadow
        storage_entry(2, true),  // objects
        storage_entry(3, true),  // lights
        uniform_entry(4),        // camera
        uniform_entry(5),        // params
        storage_entry(6, false), // rt
        storage_entry(7, true),  // gbuffer
        storage_entry(8, true),  // surface tables
        uniform_entry(9),        // surface layout
        uniform_entry(10),       // ambient light
        storage_entry(11, true), // ambient light texels
        uniform_entry(12),       // slot params
    ]
}

/// The buffers of [`rt_entries`], in binding order.
fn rt_buffers<'a>(scene: &'a SceneBuffers, frame: &'a FrameBuffers) -> [&'a wgpu::Buffer; 13] {
    [
        &frame.surfaces,
        &frame.shadow,
        scene.objects.first(),
        scene.lights.first(),
        &frame.camera,
        &frame.params,
        &frame.rt,
        &frame.gbuffer,
        scene.surface.words.first(),
        &scene.surface.layout,
        &scene.ambient_light,
        &scene.ambient_texels,
        &frame.slot_params,
    ]
}

/// `rt_pixel` of `shaders/rt_shading.wgsl` in the paper's frame (the closure of
/// `hyrt_cpu::rt_shading::rt_shading_into`).
const PAPER_RT_PIXEL: &str = "// mirrors hyrt_core::kernels::shading::shade_rt_pixel of the pixel's shaded object\nfn rt_pixel(pixel: u32, s: SurfaceRecord) -> vec3<f32> {\n    return shade_rt_pixel(pixel, s, primary_object(pixel, s), camera.eye);\n}\n";

/// The binding of `frame.visibility` in `rt_shading` of a denoised frame (after
/// [`rt_entries`]).
const RT_VISIBILITY: u32 = 13;

/// The binding of `frame.visibility` in `rt_shading` (bounces) of a denoised frame (after
/// [`rt_entries`] and the first bounce's three).
const RT_BOUNCING_VISIBILITY: u32 = 16;

/// The WGSL of [`RtShadingStage`] for scenes that need `s`.
pub fn shader_source(s: Specialization) -> String {
    let source = surface_shading_source_for(
        &format!(
            "{}\n{}\n{PAPER_RT_PIXEL}",
            include_str!("shaders/rt_shading.wgsl"),
            include_str!("shaders/primary_object.wgsl")
        ),
        s.denoised.then_some(RT_VISIBILITY),
    );
    crate::paging::paged_source(&source, s.pages)
}

/// The WGSL of [`RtShadingBouncingStage`] for scenes that need `s` (its triangle flags
/// read as [`crate::world_triangles::triangle_flags_wgsl`] says).
pub fn bouncing_shader_source(s: Specialization) -> String {
    let source = crate::shader::radiance_source_for(
        &format!(
            "{}\n{}\n{}",
            include_str!("shaders/rt_shading.wgsl"),
            include_str!("shaders/rt_shading_bouncing.wgsl"),
            crate::world_triangles::triangle_flags_wgsl(0, 13, s.by_reference)
        ),
        s.denoised.then_some(RT_BOUNCING_VISIBILITY),
    );
    crate::paging::paged_source(&source, s.flags_pages())
}

/// The `rt_shading` stage of the paper's frame.
pub struct RtShadingStage {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// Compiled for denoised frames: binds `frame.visibility`.
    denoised: bool,
}

/// The `rt_shading` stage of frames that trace bounces: mirrors and glass gather their
/// first bounce's radiance (`shaders/rt_shading_bouncing.wgsl`).
pub struct RtShadingBouncingStage {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// Compiled for denoised frames: binds `frame.visibility`.
    denoised: bool,
}

impl RtShadingStage {
    /// Compile the stage's pipeline for scenes without surface tables.
    pub fn new(ctx: &GpuContext) -> Self {
        Self::specialized(ctx, Specialization::PLAIN)
    }

    /// Compile the stage's pipeline for scenes whose surface tables need `s`.
    pub fn specialized(ctx: &GpuContext, s: Specialization) -> Self {
        let source = shader_source(s);
        let visibility = [storage_entry(RT_VISIBILITY, true)];
        let pages = s.pages.layout_entries(&PAGED_TABLES);
        let entries = [rt_entries().as_slice(), if s.denoised { &visibility } else { &[] }, &pages].concat();
        let (pipeline, layout) = specialized_pipeline(ctx, "rt_shading", &source, &entries, &s.shading_constants());
        RtShadingStage { pipeline, layout, denoised: s.denoised }
    }

    /// Record the stage: `frame.rt` from `frame.surfaces`, `frame.shadow`,
    /// `scene.objects`, `scene.lights`, `frame.camera` and `frame.params` (and, where
    /// materials vary, `frame.gbuffer` and `scene.surface`).
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let visibility = [&frame.visibility];
        let buffers = [rt_buffers(scene, frame).as_slice(), if self.denoised { &visibility } else { &[] }].concat();
        let bind_group =
            bind_paged_buffers(ctx, "rt_shading", &self.layout, &buffers, scene.further_pages(&PAGED_TABLES));
        encode_pixel_pass(encoder, "rt_shading", &self.pipeline, &bind_group, frame.width, frame.band.rows, timing);
    }
}

impl RtShadingBouncingStage {
    /// Compile the stage's pipeline for scenes whose surface tables need `s`.
    pub fn specialized(ctx: &GpuContext, s: Specialization) -> Self {
        let source = bouncing_shader_source(s);
        let visibility = [storage_entry(RT_BOUNCING_VISIBILITY, true)];
        let pages = s.flags_layout_entries(&PAGED_TABLES);
        let (pipeline, layout) = specialized_pipeline(
            ctx,
            "rt_shading (bounces)",
            &source,
            &[
                rt_entries().as_slice(),
                &[
                    storage_entry(13, true), // triangle flags (triangles, or placements)
                    storage_entry(14, true), // links of depth 1
                    storage_entry(15, true), // radiance of depth 1
                ],
                if s.denoised { &visibility } else { &[] },
                &pages,
            ]
            .concat(),
            &s.shading_constants(),
        );
        RtShadingBouncingStage { pipeline, layout, denoised: s.denoised }
    }

    /// Record the stage: as [`RtShadingStage::encode`], the pixels of mirrors and glass
    /// adding what `frame.bounces[0]` brought back.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let visibility = [&frame.visibility];
        let first = &frame.bounces[0];
        let bind_group = crate::shader::bind_paged_buffers(
            ctx,
            "rt_shading (bounces)",
            &self.layout,
            &[
                rt_buffers(scene, frame).as_slice(),
                &[scene.flags_table(), &first.links, &first.radiance],
                if self.denoised { &visibility } else { &[] },
            ]
            .concat(),
            scene.flags_table_pages(&PAGED_TABLES),
        );
        encode_pixel_pass(encoder, "rt_shading", &self.pipeline, &bind_group, frame.width, frame.band.rows, timing);
    }
}
