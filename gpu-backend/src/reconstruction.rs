//! `reconstruction` (paper eq. 1): rebuild the world-space surface at every pixel
//! from the visibility G-buffer, one thread per pixel (8x8 groups), mirroring
//! [`hyrt_core::kernels::reconstruction::reconstruct_texel`] and the kernels it calls
//! (`hyrt_core::kernels::barycentric::{reconstruct_position, position_error_bound,
//! interpolate_normal, geometric_normal}`, `hyrt_core::kernels::shading::orient_to_seen_side`)
//! in `shaders/reconstruction.wgsl`, operation for operation. Normalization is
//! `sqrt_rn` then `div_rn`, as the CPU's `sqrt` then division (WGSL's `inverseSqrt`,
//! `sqrt` and `/` are not exact).
//!
//! Reads: `frame.gbuffer`, `frame.camera` (eye, image size), `frame.params` (the band),
//! `scene.triangles`,
//! `scene.normals`, `scene.objects` (`first_triangle`); in a scene with objects by
//! reference also `scene.placements` and `scene.mesh_words` ([`crate::world_triangles`]:
//! those objects' records and normals made on read). Writes: `frame.surfaces` (every texel
//! of the camera's image).
//!
//! Every product that feeds a sum is kept unfused (`mul`), and divisions and roots are
//! exact (`div_rn`, `sqrt_rn`), so the surfaces are the CPU's bits on any device that
//! rounds `+`, `-` and `*` as IEEE 754 (lavapipe, the NVIDIA H200).

use hyrt_core::frame::PrimaryBarycentrics;

use crate::buffers::{FrameBuffers, SceneBuffers};
use crate::paging::{paged_source, Table, TablePages};
use crate::shader::{preamble, ray_wgsl, shader_module, surface_wgsl};
use crate::GpuContext;

/// Side of the square workgroup (`@workgroup_size(8, 8, 1)`).
const GROUP: u32 = 8;

const SHADER: &str = include_str!("shaders/reconstruction.wgsl");

/// Where the stage's by-reference bindings start (`placements`, then `mesh_words`).
const BY_REFERENCE_BINDING: u32 = 7;

/// The WGSL of the stage: the generated records and format constants, the ray kernels
/// with their exact f32 constants (the watertight test of re-intersected barycentrics),
/// the surface kernels, the world-triangle accessors (through placements for a scene with
/// objects `by_reference`, [`crate::world_triangles`]), then the shader.
pub fn shader_source(by_reference: bool) -> String {
    use crate::world_triangles::{world_normals_wgsl, world_triangles_wgsl};
    format!(
        "{}{}\n{}\n{}\n{}\n{}",
        preamble(),
        ray_wgsl(),
        surface_wgsl(),
        world_triangles_wgsl(by_reference.then_some((0, BY_REFERENCE_BINDING))),
        world_normals_wgsl(by_reference),
        SHADER
    )
}

/// The `reconstruction` stage: one compute pipeline per source of barycentrics
/// (`main`: the raster's; `main_reintersected`: the camera rays', mirroring
/// `hyrt_core::kernels::reconstruction::reconstruct_texel_reintersected` and
/// `hyrt_core::kernels::camera::primary_ray`), for scenes of stored objects, and the same
/// for other kinds of scene (objects by reference, tables in pages: [`crate::paging`]),
/// built the first time one is rendered.
pub struct ReconstructionStage {
    plain: std::sync::Arc<Pipelines>,
    others: std::sync::Mutex<Vec<(Kind, std::sync::Arc<Pipelines>)>>,
}

/// A kind of scene: objects by reference or not, and its tables' pages.
type Kind = (bool, TablePages);

/// The paged tables the normal-mapping passes read ([`crate::paging`]).
const NORMAL_MAPPING_TABLES: [Table; 2] = [Table::Objects, Table::Surface];

/// The pipelines of one kind of scene.
struct Pipelines {
    /// (pipeline, its bind group layout): the raster's barycentrics, then re-intersected.
    raster: (wgpu::ComputePipeline, wgpu::BindGroupLayout),
    reintersected: (wgpu::ComputePipeline, wgpu::BindGroupLayout),
}

impl ReconstructionStage {
    /// Build the pipelines of scenes of stored objects.
    pub fn new(ctx: &GpuContext) -> Self {
        ReconstructionStage {
            plain: std::sync::Arc::new(Pipelines::new(ctx, (false, TablePages::default()))),
            others: std::sync::Mutex::new(Vec::new()),
        }
    }

    /// Build the pipelines of both kinds of scene (unpaged) now.
    pub fn with_by_reference(ctx: &GpuContext) -> Self {
        let stage = Self::new(ctx);
        stage.pipelines(ctx, (true, TablePages::default()));
        stage
    }

    /// The pipelines of scenes of `kind`.
    fn pipelines(&self, ctx: &GpuContext, kind: Kind) -> std::sync::Arc<Pipelines> {
        if kind == (false, TablePages::default()) {
            return self.plain.clone();
        }
        let mut others = self.others.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, p)) = others.iter().find(|(k, _)| *k == kind) {
            return p.clone();
        }
        let p = std::sync::Arc::new(Pipelines::new(ctx, kind));
        others.push((kind, p.clone()));
        p
    }
}

impl Pipelines {
    fn new(ctx: &GpuContext, (by_reference, pages): Kind) -> Self {
        let module = shader_module(ctx, "reconstruction", &paged_source(&shader_source(by_reference), pages));
        // The layout as wgpu would derive it (a passthrough module has no reflection).
        let pipeline = |entry: &str| {
            let (group, layout) = module.derived_layout("reconstruction", &[(entry, wgpu::ShaderStages::COMPUTE)]);
            (module.compute_pipeline("reconstruction", entry, &layout, &[]), group)
        };
        Pipelines { raster: pipeline("main"), reintersected: pipeline("main_reintersected") }
    }
}

impl ReconstructionStage {
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
        let pipelines = self.pipelines(ctx, (scene.by_reference, scene.specialization.pages));
        let (pipeline, layout) = match barycentrics {
            PrimaryBarycentrics::Raster => &pipelines.raster,
            PrimaryBarycentrics::Reintersected => &pipelines.reintersected,
        };
        let mut buffers = vec![
            scene.triangles.first(),
            scene.normals.first(),
            scene.objects.first(),
            &frame.camera,
            &frame.gbuffer,
            &frame.surfaces,
            &frame.params,
        ];
        if scene.by_reference {
            buffers.extend([scene.placements.first(), scene.mesh_words.first()]);
        }
        let tables = [Table::Triangles, Table::Normals, Table::Objects, Table::Placements, Table::MeshWords];
        let further = scene.further_pages(&tables);
        let group = crate::shader::bind_paged_buffers(ctx, "reconstruction", layout, &buffers, further);
        let mut pass = crate::timing::begin_timed_pass(encoder, "reconstruction", timing);
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(frame.width.div_ceil(GROUP), frame.band.rows.div_ceil(GROUP), 1);
    }
}

/// The primary pass of [`NormalMapping`]: its bindings after the shared ones, and its entry.
const PRIMARY_NORMAL_MAPPING: &str = r#"
@group(0) @binding(5) var<storage, read> gbuffer: array<GBufferTexel>;
@group(0) @binding(6) var<uniform> camera: CameraRecord;

// One thread per pixel of the band, as `reconstruction`'s `main`.
@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let pixel = gid.y * params.width + gid.x;
    surfaces[pixel] = primary_normal_mapped(gbuffer[pixel], surfaces[pixel], camera.eye);
}
"#;

/// The secondary pass of [`NormalMapping`]: its bindings after the shared ones, and its
/// entry.
const SECONDARY_NORMAL_MAPPING: &str = r#"
@group(0) @binding(5) var<storage, read> rays: array<RayRecord>;
@group(0) @binding(6) var<storage, read> ray_count: array<u32, 4>;
@group(0) @binding(7) var<storage, read> hits: array<HitRecord>;

// One thread per ray of a bounce's list, as `bounce_trace`'s `main`.
@compute @workgroup_size(NORMAL_MAPPING_WG)
fn main(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>,
        @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = (wid.y * nwg.x + wid.x) * NORMAL_MAPPING_WG + lid;
    if i >= min(ray_count[0], arrayLength(&rays)) {
        return;
    }
    surfaces[i] = secondary_normal_mapped(rays[i], hits[i], surfaces[i]);
}
"#;

/// Normal mapping of the surfaces a frame makes, in a scene with normal maps
/// (`Specialization::normal_mapped`): after `reconstruction`, each pixel's surface through
/// `primary_normal_mapped` (the primary pass, part of the `reconstruction` step); after
/// `bounce_trace`, each hit's through `secondary_normal_mapped` (the secondary pass, part
/// of that step), mirrors of `hyrt_core::kernels::reconstruction`'s kernels in
/// `shaders/materials.wgsl` (`normal_mapped`, mirror of
/// `hyrt_core::kernels::texture::Materials::normal_mapped`). The CPU runs the same kernels
/// at the same points (`hyrt_cpu::reconstruction::normal_mapping_into`,
/// `hyrt_cpu::bounce_trace`). Compiled with `SURFACE_TABLES` on (a normal-mapped scene
/// has surface tables), and for the pages of its object records and surface tables
/// ([`crate::paging`]).
pub struct NormalMapping {
    primary: (wgpu::ComputePipeline, wgpu::BindGroupLayout),
    secondary: (wgpu::ComputePipeline, wgpu::BindGroupLayout),
}

impl NormalMapping {
    /// Compile both passes for surface tables in one binding.
    pub fn new(ctx: &GpuContext) -> Self {
        Self::paged(ctx, TablePages::default())
    }

    /// The WGSL of the primary and the secondary pass for tables in the pages `pages` gives
    /// them.
    pub fn shader_sources(pages: TablePages) -> [String; 2] {
        let common = format!(
            "{}\n{}\nconst NORMAL_MAPPING_WG: u32 = {}u;\n{}",
            crate::texture::texture_wgsl(),
            crate::texture::materials_wgsl(),
            crate::shader::SHADOW_RAYS_WORKGROUP_SIZE,
            include_str!("shaders/normal_mapping.wgsl")
        );
        [PRIMARY_NORMAL_MAPPING, SECONDARY_NORMAL_MAPPING]
            .map(|entry| paged_source(&crate::shader::shading_source(&format!("{common}{entry}")), pages))
    }

    /// Compile both passes for object records and surface tables in the pages `pages`
    /// gives them.
    pub fn paged(ctx: &GpuContext, pages: TablePages) -> Self {
        use crate::shader::{specialized_pipeline, storage_entry, uniform_entry};
        let [primary, secondary] = Self::shader_sources(pages);
        let shared = [
            uniform_entry(0),
            storage_entry(1, true),
            storage_entry(2, true),
            uniform_entry(3),
            storage_entry(4, false),
        ];
        let constants = [("SURFACE_TABLES", 1.0), ("ALPHA_TESTED", 0.0)];
        let surface_pages = pages.layout_entries(&NORMAL_MAPPING_TABLES);
        let build = |label: &str, source: &str, own: &[wgpu::BindGroupLayoutEntry]| {
            let entries: Vec<_> = shared.iter().chain(own).chain(&surface_pages).copied().collect();
            specialized_pipeline(ctx, label, source, &entries, &constants)
        };
        NormalMapping {
            primary: build("reconstruction normal mapping", &primary, &[storage_entry(5, true), uniform_entry(6)]),
            secondary: build(
                "bounce_trace normal mapping",
                &secondary,
                &[storage_entry(5, true), storage_entry(6, true), storage_entry(7, true)],
            ),
        }
    }

    /// Record the primary pass over `frame.band`, after `reconstruction`.
    pub fn encode_primary(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
    ) {
        if frame.width == 0 || frame.band.rows == 0 {
            return;
        }
        let (pipeline, layout) = &self.primary;
        let buffers = [
            &frame.params,
            scene.objects.first(),
            scene.surface.words.first(),
            &scene.surface.layout,
            &frame.surfaces,
            &frame.gbuffer,
            &frame.camera,
        ];
        let further = scene.further_pages(&NORMAL_MAPPING_TABLES);
        let group = crate::shader::bind_paged_buffers(ctx, "reconstruction normal mapping", layout, &buffers, further);
        let mut pass = crate::timing::begin_timed_pass(encoder, "reconstruction normal mapping", None);
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(frame.width.div_ceil(GROUP), frame.band.rows.div_ceil(GROUP), 1);
    }

    /// Record the secondary pass over the hits of `frame.bounces[depth - 1]`, after
    /// `bounce_trace`.
    pub fn encode_secondary(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        depth: u32,
    ) {
        let b = &frame.bounces[depth as usize - 1];
        let (pipeline, layout) = &self.secondary;
        let buffers = [
            &frame.params,
            scene.objects.first(),
            scene.surface.words.first(),
            &scene.surface.layout,
            &b.surfaces,
            &b.rays,
            &b.ray_count,
            &b.hits,
        ];
        let further = scene.further_pages(&NORMAL_MAPPING_TABLES);
        let group = crate::shader::bind_paged_buffers(ctx, "bounce_trace normal mapping", layout, &buffers, further);
        crate::shader::encode_list_pass(encoder, "bounce_trace normal mapping", pipeline, &group, &b.ray_count, None);
    }
}
