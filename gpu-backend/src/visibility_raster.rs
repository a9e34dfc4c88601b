//! `visibility_raster` (paper 3.2) on the hardware raster pipeline: every triangle
//! of the scene table is drawn (non-indexed, vertices pulled from
//! [`SceneBuffers::triangles`]) into two render targets and a depth buffer, then a
//! compute pass resolves the targets into [`FrameBuffers::gbuffer`], texel for texel
//! the format of `hyrt_cpu::visibility_raster`.
//!
//! Reads: `scene.triangles`, `frame.camera`, `scene.surface` (alpha tests),
//! `scene.interior_culls`. Writes:
//! `frame.gbuffer` (every texel).
//!
//! Raster pass (`vs_main` / `fs_main` in `shaders/visibility_raster.wgsl`): the
//! hardware only proposes fragments; the values are the CPU reference's, bit for bit.
//! * vertex `i` is corner `i % 3` of global triangle `i / 3`; its clip position is the
//!   reference's (`clip_position`, products kept from fusing). A triangle with a
//!   non-finite clip coordinate gets the same clip position outside the view volume at
//!   all three corners and is clipped away, as the CPU skips it;
//! * what reaches the hardware: when the reference draws the triangle unclipped and it
//!   lies inside the viewport, its corners *pre-snapped* (NDC rebuilt from the
//!   reference's fixed-point positions, w = 1), so the hardware's own snapping, fill rule
//!   (the same top-left rule) and 1/256 px precision cover exactly the reference's pixel
//!   centres; otherwise (near/far/guard-band clipping, or crossing the viewport border
//!   where lavapipe clips with its own rounding) a *cover triangle* over the reference's
//!   pixel bounding box plus a pixel;
//! * the fragment shader re-runs the reference's setup for its triangle (clipping,
//!   snapping, orientation) and its exact 64-bit edge functions at the pixel centre
//!   (as pairs of u32), discards what the reference does not cover, and computes the
//!   reference's barycentrics and depth in f32 (`hyrt_core::kernels::raster`); a fragment
//!   of an alpha-tested triangle (`TRI_ALPHA_TEST`) whose alpha fails the cutoff at those
//!   barycentrics ([`hyrt_core::kernels::texture::alpha_accepts`], the CPU's `AlphaTested`
//!   sink) is discarded before the depth test, so a hole shows what lies behind; it writes
//!   that depth as `frag_depth`, so the depth test (`Depth32Float`, `Less`, cleared to
//!   1.0: the nearest wins, at equal depth the earlier triangle) compares the reference's
//!   values in the reference's order;
//! * targets: [`ID_FORMAT`] holds the global triangle index + 1 (0, the clear value,
//!   is a miss); [`SURFACE_FORMAT`] holds `(u, v, depth, 1 if front else 0)`, facing
//!   from the sign of the reference's snapped area;
//! * the triangle id comes from `@builtin(primitive_index)` when the device has
//!   `PRIMITIVE_INDEX` ([`GpuContext::primitive_index`]), else from a flat-interpolated
//!   vertex output `vertex_index / 3` (vertices are not shared, so every corner of a
//!   triangle carries its id); [`VisibilityRasterStage::triangle_id_source`] says which.
//!
//! Setup pass (`setup`, exact mode): one thread per triangle runs the reference's setup
//! once and records what the raster pass needs (`RasterSetup`, 80 bytes); an unclipped
//! triangle that shows the interior of an object whose bit is set in
//! [`SceneBuffers::interior_culls`] (the CPU's `WorldGeometry::interior_culls` for the
//! frame's camera: closed meshes wholly in front of the near plane) is recorded as
//! nothing to draw, as the reference drops it. Triangles are
//! set up and drawn in batches whose records fit one storage binding
//! ([`batch_triangles`]: 1.67 million triangles under lavapipe's 128 MiB), each batch a
//! setup pass then a raster pass that keeps the targets and depth of the batches before
//! it; the draws keep the scene's order, so the depth test's tie rule (the earlier
//! triangle) and the G-buffer do not depend on the batch size. Only device memory bounds
//! the triangle count: one batch's records are held at a time.
//!
//! Resolve pass (`resolve`): one thread per pixel (8x8 groups): id 0 gives
//! `GBufferTexel::MISS`, else the triangle's record gives `triangle`, `object` and
//! `GBUF_RAY_TRACED` (from `TRI_RAY_TRACED`), the surface target the rest.
//!
//! Bands ([`crate::band`]): the render targets hold one band of rows (the whole image
//! when it fits), created per band size and cached in the stage. The vertex shader maps
//! the band's rows onto them (`window_to_ndc`, `band_window`; a triangle is pre-snapped
//! only when it lies inside the band, `presnap_in_band`, else covered) and skips
//! triangles whose pixel box misses the band; the fragment shader adds the band's first
//! row to its window position and evaluates the whole image's setup there, so a pixel's
//! texel does not depend on its band. The image's width must be within the device's
//! `max_texture_dimension_2d` (the adapter's own: 16384 on lavapipe).
//!
//! Agreement with the CPU reference: bit-identical on the conformance corpus on lavapipe
//! and on an NVIDIA H200 (hyrt-conformance). It rests on the device rasterizing with 8
//! subpixel bits and the top-left rule (Vulkan's `subPixelPrecisionBits`, as lavapipe and
//! desktop GPUs do) and computing conversions and `round` exactly; divisions go through
//! `div_rn`. Cost: the fragment shader's setup is per fragment, about 15x the old
//! raster pass on lavapipe (29.6 -> 435 ms at 1280x720, default scene).

use crate::shader::{preamble, shader_module};
use std::sync::Mutex;

use crate::buffers::{FrameBuffers, SceneBuffers};
use crate::paging::Table;
use crate::texture::Specialization;
use crate::GpuContext;

/// Render target of the triangle ids: global triangle index + 1, 0 = miss.
pub const ID_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;
/// Render target of `(u, v, depth, front_facing)`.
pub const SURFACE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// The depth buffer.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Depth clear value: the far plane (as the CPU's `DEPTH_CLEAR`).
const DEPTH_CLEAR: f32 = 1.0;
/// Side of the resolve pass's square workgroup (`@workgroup_size(8, 8, 1)`).
const RESOLVE_GROUP: u32 = 8;

const COMMON: &str = include_str!("shaders/visibility_common.wgsl");
const SHADER: &str = include_str!("shaders/visibility_raster.wgsl");
const INTERPOLATED_SHADER: &str = include_str!("shaders/visibility_raster_interpolated.wgsl");

/// How the stage computes the G-buffer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VisibilityMode {
    /// The CPU reference's kernels in the fragment shader: bit-identical to
    /// `hyrt_cpu::visibility_raster` (the module docs). The default.
    #[default]
    Exact,
    /// The hardware's own attribute interpolation and depth: NOT conformant (ids can
    /// differ on rounding ties and depth near-ties, barycentrics by up to 1e-1 on
    /// sub-pixel triangles; no alpha test: alpha-tested triangles are drawn without their
    /// holes). Only for benchmarks that measure the device as a plain rasterizer of the
    /// same pass. It draws every triangle: no setup pass, so no closed object's interior
    /// is dropped.
    HardwareInterpolated,
}

/// Triangle id source names reported by [`VisibilityRasterStage::triangle_id_source`].
pub const ID_FROM_PRIMITIVE_INDEX: &str = "@builtin(primitive_index)";
pub const ID_FROM_FLAT_VERTEX_OUTPUT: &str = "flat-interpolated vertex_index / 3";

/// The constants of `hyrt_core::kernels::raster` the shader mirrors, as WGSL (`{:?}`
/// prints the shortest decimal that parses back to the same f32).
fn raster_constants() -> String {
    use hyrt_core::kernels::raster::{
        FIXED_ONE, FIXED_ONE_F32, GUARD_BAND_PIXELS, INTERIOR_DEPTH_BIAS_ULPS, MAX_CLIP_VERTICES, MAX_FIXED_COORD,
        MAX_IMAGE_DIM, PIXEL_CENTER_OFFSET,
    };
    const _: () = assert!(FIXED_ONE.count_ones() == 1, "INV_FIXED_ONE_F32 must be exact");
    format!(
        "const HARDWARE_TRIANGLES_PER_TRIANGLE: u32 = {HARDWARE_TRIANGLES_PER_TRIANGLE}u;\nconst MAX_IMAGE_DIM: u32 = {MAX_IMAGE_DIM}u;\nconst GUARD_BAND_PIXELS: f32 = {GUARD_BAND_PIXELS:?};\n\
         const MAX_CLIP_VERTICES: u32 = {MAX_CLIP_VERTICES}u;\nconst PIXEL_CENTER_OFFSET: f32 = {PIXEL_CENTER_OFFSET:?};\n\
         const FIXED_ONE: i32 = {FIXED_ONE};\nconst FIXED_ONE_F32: f32 = {FIXED_ONE_F32:?};\n\
         const INV_FIXED_ONE_F32: f32 = {:?};\n\
         const MAX_FIXED_COORD_F32: f32 = {:?};\nconst INTERIOR_DEPTH_BIAS_ULPS: u32 = {INTERIOR_DEPTH_BIAS_ULPS}u;\n",
        // A power of two: x * (1 / FIXED_ONE_F32) is x / FIXED_ONE_F32, bit for bit.
        1.0 / FIXED_ONE_F32,
        MAX_FIXED_COORD as f32
    )
}

/// Where the raster's by-reference bindings start (`placements`, then `mesh_words`:
/// [`crate::world_triangles::world_triangles_wgsl`]), in a scene with objects by reference.
const BY_REFERENCE_BINDING: u32 = 13;

/// The world-triangle accessors of the stage ([`crate::world_triangles::world_triangles_wgsl`]).
fn world_triangles(by_reference: bool) -> String {
    crate::world_triangles::world_triangles_wgsl(by_reference.then_some((0, BY_REFERENCE_BINDING)))
}

/// The WGSL of [`VisibilityMode::HardwareInterpolated`], specialized for the triangle id
/// source and for objects by reference (whose records are made with products kept apart
/// by `camera.pad`, as the exact shader's).
fn interpolated_shader_source(primitive_index: bool, by_reference: bool) -> String {
    let mut world = world_triangles(by_reference);
    if by_reference {
        world += "fn rounded(x: f32) -> f32 {\n    return bitcast<f32>(bitcast<u32>(x) | camera.pad);\n}\n\
                  fn mul(a: f32, b: f32) -> f32 {\n    return rounded(a * b);\n}\n";
    }
    let source = if primitive_index {
        format!(
            "enable primitive_index;\n{}{COMMON}{}",
            preamble(),
            INTERPOLATED_SHADER
                .replace("TRIANGLE_ID_PARAMETER", "@builtin(primitive_index) primitive: u32,")
                .replace("TRIANGLE_ID_EXPRESSION", "primitive")
        )
    } else {
        let body =
            INTERPOLATED_SHADER.replace("TRIANGLE_ID_PARAMETER", "").replace("TRIANGLE_ID_EXPRESSION", "in.triangle");
        format!("{}{COMMON}{body}", preamble())
    };
    source + &world
}

/// The WGSL of the stage, specialized for the triangle id source and for conservative
/// depth (`early_depth_test`: the fragment shader declares that the depth it writes is
/// at least the interpolated one, so the device may keep its early depth test) and for
/// objects by reference (`by_reference`: the world triangles read through their
/// placements, [`crate::world_triangles`]).
pub fn shader_source(primitive_index: bool, early_depth_test: bool, by_reference: bool) -> String {
    let body = if primitive_index {
        SHADER
            .replace("TRIANGLE_ID_PARAMETER", "@builtin(primitive_index) primitive: u32,")
            .replace("TRIANGLE_ID_EXPRESSION", "primitive / HARDWARE_TRIANGLES_PER_TRIANGLE")
    } else {
        SHADER.replace("TRIANGLE_ID_PARAMETER", "").replace("TRIANGLE_ID_EXPRESSION", "in.triangle")
    };
    let body = body
        .replace("EARLY_DEPTH_TEST_ATTRIBUTE", if early_depth_test { "@early_depth_test(greater_equal)" } else { "" });
    let enable = if primitive_index { "enable primitive_index;\n" } else { "" };
    format!(
        "{enable}{}{}{COMMON}{body}{}{}",
        preamble(),
        raster_constants(),
        crate::texture::texture_wgsl(),
        world_triangles(by_reference)
    )
}

/// Render targets of one image size.
struct Targets {
    width: u32,
    height: u32,
    id: wgpu::TextureView,
    surface: wgpu::TextureView,
    depth: wgpu::TextureView,
}

impl Targets {
    fn new(ctx: &GpuContext, width: u32, height: u32) -> Targets {
        let make = |label: &str, format: wgpu::TextureFormat, usage: wgpu::TextureUsages| {
            crate::gpu_buffer::texture_2d(ctx, label, width, height, format, usage)
                .create_view(&wgpu::TextureViewDescriptor::default())
        };
        let target = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
        Targets {
            width,
            height,
            id: make("visibility ids", ID_FORMAT, target),
            surface: make("visibility surface", SURFACE_FORMAT, target),
            depth: make("visibility depth", DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT),
        }
    }
}

/// Bytes of one `RasterSetup` record of the shader (five 16-byte vectors).
pub const RASTER_SETUP_BYTES: u64 = 80;
/// Threads per workgroup of the setup pass (`@workgroup_size(64, 1, 1)`).
const SETUP_GROUP: u32 = 64;
/// Most workgroups per dispatch dimension (WebGPU's `maxComputeWorkgroupsPerDimension`).
const MAX_GROUPS_PER_DIMENSION: u32 = 65_535;

/// Hardware triangles drawn per scene triangle (`HARDWARE_TRIANGLES_PER_TRIANGLE` in the
/// shader, which explains it).
pub const HARDWARE_TRIANGLES_PER_TRIANGLE: u32 = 2;

/// Bytes of one `ClippedSetup` record of the shader (six 16-byte vectors).
pub const CLIPPED_SETUP_BYTES: u64 = 96;
/// Sub-triangle slots for clipped triangles, per triangle of a batch, at least
/// [`MIN_CLIPPED_SLOTS`]: clipping is rare (77 of 135,905 triangles in the teaser, each
/// a fan of at most 7), and a triangle that finds the slots full is set up per fragment
/// instead, with the same result.
const CLIPPED_SLOTS_PER_TRIANGLE: f64 = 1.0 / 16.0;
const MIN_CLIPPED_SLOTS: u32 = 4096;

/// Bytes of one `RasterBatch` uniform of the shader (first triangle, count, two pad words).
const RASTER_BATCH_BYTES: u64 = 16;

/// The most triangles of one batch whatever the device: 320 MiB of setup records. A
/// device whose bindings hold 4 GiB (an NVIDIA H200) would otherwise hold 53 million
/// records at once; a batch costs a setup and a raster pass (microseconds on such a
/// device), so smaller batches cost little and bound the memory the stage holds.
pub const MAX_BATCH_TRIANGLES: u32 = 1 << 22;

/// The most triangles of one batch on a device with `limits`: their setup records fit
/// one storage binding (and one buffer), at most [`MAX_BATCH_TRIANGLES`].
pub fn batch_triangles(limits: &wgpu::Limits) -> u32 {
    let binding = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
    (binding / RASTER_SETUP_BYTES).clamp(1, u64::from(MAX_BATCH_TRIANGLES)) as u32
}

/// The setup records of one triangle count, set up and drawn batch by batch: a scene of
/// `triangles` triangles is `batches()` batches of at most `batch` triangles each, in
/// the scene's order (the depth test keeps the earlier triangle at equal depth, and the
/// draws keep the order), so the G-buffer does not depend on the batch size.
struct Setups {
    triangles: u32,
    /// Triangles per batch ([`batch_triangles`], at most `triangles`).
    batch: u32,
    /// One batch's records: `RasterSetup` per triangle.
    buffer: wgpu::Buffer,
    clipped: wgpu::Buffer,
    clipped_count: wgpu::Buffer,
    /// One `RasterBatch` record per batch, `stride` bytes apart (the device's uniform
    /// offset alignment), bound one at a time.
    batch_records: wgpu::Buffer,
    stride: u64,
}

/// Batches of at most `batch` triangles in a scene of `triangles` (one when empty).
fn batch_count(triangles: u32, batch: u32) -> u32 {
    triangles.div_ceil(batch).max(1)
}

/// Batch `k`'s first triangle and triangle count.
fn batch_range(triangles: u32, batch: u32, k: u32) -> (u32, u32) {
    let first = k * batch;
    (first, batch.min(triangles - first))
}

impl Setups {
    fn batches(&self) -> u32 {
        batch_count(self.triangles, self.batch)
    }

    /// Batch `k`'s first triangle and triangle count.
    fn batch_range(&self, k: u32) -> (u32, u32) {
        batch_range(self.triangles, self.batch, k)
    }

    /// Batch `k`'s `RasterBatch` record, for binding 15.
    fn batch_binding(&self, k: u32) -> wgpu::BindingResource<'_> {
        wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: &self.batch_records,
            offset: u64::from(k) * self.stride,
            size: std::num::NonZeroU64::new(RASTER_BATCH_BYTES),
        })
    }
}

/// The `visibility_raster` stage: a setup compute pipeline (one thread per triangle),
/// a raster pipeline and a resolve compute pipeline.
pub struct VisibilityRasterStage {
    /// The setup pass (exact mode only).
    setup: Option<wgpu::ComputePipeline>,
    raster: wgpu::RenderPipeline,
    resolve: wgpu::ComputePipeline,
    setup_layout: Option<wgpu::BindGroupLayout>,
    raster_layout: wgpu::BindGroupLayout,
    resolve_layout: wgpu::BindGroupLayout,
    primitive_index: bool,
    mode: VisibilityMode,
    /// Compiled for a scene with objects by reference: binds the placements and mesh
    /// words at [`BY_REFERENCE_BINDING`] on.
    by_reference: bool,
    /// Render targets of the last image size.
    targets: Mutex<Option<std::sync::Arc<Targets>>>,
    /// Setup records of the last triangle count.
    setups: Mutex<Option<std::sync::Arc<Setups>>>,
}

impl VisibilityRasterStage {
    /// Build the pipelines, with the triangle id source the device supports.
    pub fn new(ctx: &GpuContext) -> Self {
        Self::with_id_source(ctx, ctx.primitive_index)
    }

    /// Build the pipelines with `@builtin(primitive_index)` ids if `primitive_index`
    /// (the device must have `PRIMITIVE_INDEX`, i.e. [`GpuContext::primitive_index`]),
    /// else with flat-interpolated vertex ids (any device). For tests of both variants.
    pub fn with_id_source(ctx: &GpuContext, primitive_index: bool) -> Self {
        Self::build(ctx, primitive_index, VisibilityMode::Exact, Specialization::PLAIN)
    }

    /// Build the pipelines of `mode` with the device's triangle id source.
    pub fn with_mode(ctx: &GpuContext, mode: VisibilityMode) -> Self {
        Self::specialized(ctx, mode, Specialization::PLAIN)
    }

    /// Build the pipelines of `mode` with the device's triangle id source, for scenes whose
    /// surface tables need `s` (in [`VisibilityMode::Exact`], the alpha test of
    /// `s.alpha_tested`; [`VisibilityMode::HardwareInterpolated`] has none).
    pub fn specialized(ctx: &GpuContext, mode: VisibilityMode, s: Specialization) -> Self {
        Self::build(ctx, ctx.primitive_index, mode, s)
    }

    fn build(ctx: &GpuContext, primitive_index: bool, mode: VisibilityMode, s: Specialization) -> Self {
        let primitive_index = primitive_index && ctx.primitive_index;
        // The exact shader's alpha test is a pipeline constant; the other has no constants.
        let constants = s.constants();
        let constants: &[(&str, f64)] = if mode == VisibilityMode::Exact { &constants } else { &[] };
        let source = match mode {
            VisibilityMode::Exact => shader_source(primitive_index, ctx.early_depth_test, s.by_reference),
            VisibilityMode::HardwareInterpolated => interpolated_shader_source(primitive_index, s.by_reference),
        };
        let module = shader_module(ctx, "visibility_raster", &crate::paging::paged_source(&source, s.pages));
        // The layouts as wgpu would derive them (a passthrough module has no reflection).
        let (raster_layout, raster_pipeline_layout) = module.derived_layout(
            "visibility_raster",
            &[("vs_main", wgpu::ShaderStages::VERTEX), ("fs_main", wgpu::ShaderStages::FRAGMENT)],
        );
        let vertex = module.entry("vs_main", naga::ShaderStage::Vertex, &raster_pipeline_layout, &[]);
        let fragment = module.entry("fs_main", naga::ShaderStage::Fragment, &raster_pipeline_layout, constants);
        let raster = ctx.device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("visibility_raster"),
            layout: Some(&raster_pipeline_layout.layout),
            vertex: wgpu::VertexState {
                module: &vertex.module,
                entry_point: Some("vs_main"),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: vertex.constants,
                    ..Default::default()
                },
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                strip_index_format: None,
                front_face: wgpu::FrontFace::Ccw,
                cull_mode: None,
                unclipped_depth: false,
                polygon_mode: wgpu::PolygonMode::Fill,
                conservative: false,
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &fragment.module,
                entry_point: Some("fs_main"),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: fragment.constants,
                    ..Default::default()
                },
                targets: &[
                    Some(wgpu::ColorTargetState { format: ID_FORMAT, blend: None, write_mask: wgpu::ColorWrites::ALL }),
                    Some(wgpu::ColorTargetState {
                        format: SURFACE_FORMAT,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    }),
                ],
            }),
            multiview_mask: None,
            cache: None,
        });
        let compute = |label: &str, entry_point: &str| {
            let (group, layout) = module.derived_layout(label, &[(entry_point, wgpu::ShaderStages::COMPUTE)]);
            (module.compute_pipeline(label, entry_point, &layout, &[]), group)
        };
        let setup = (mode == VisibilityMode::Exact).then(|| compute("visibility_raster setup", "setup"));
        let (resolve, resolve_layout) = compute("visibility_raster resolve", "resolve");
        let (setup, setup_layout) = setup.unzip();
        VisibilityRasterStage {
            setup_layout,
            raster_layout,
            resolve_layout,
            setup,
            raster,
            resolve,
            primitive_index,
            mode,
            by_reference: s.by_reference,
            targets: Mutex::new(None),
            setups: Mutex::new(None),
        }
    }

    /// The bindings that go with the triangles' in every bind group of the stage: the
    /// by-reference tables (placements, mesh words) from [`BY_REFERENCE_BINDING`] on, for a
    /// stage compiled for them, and the further pages of the triangles, placements and mesh
    /// words ([`crate::paging`]).
    fn scene_entries<'a>(&self, scene: &'a SceneBuffers) -> Vec<wgpu::BindGroupEntry<'a>> {
        let mut entries: Vec<wgpu::BindGroupEntry<'a>> = scene.triangles.further().collect();
        if self.by_reference {
            entries.extend([
                wgpu::BindGroupEntry {
                    binding: BY_REFERENCE_BINDING,
                    resource: scene.placements.first().as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: BY_REFERENCE_BINDING + 1,
                    resource: scene.mesh_words.first().as_entire_binding(),
                },
            ]);
            entries.extend(scene.further_pages(&[Table::Placements, Table::MeshWords]));
        }
        entries
    }

    /// How this stage computes the G-buffer.
    pub fn mode(&self) -> VisibilityMode {
        self.mode
    }

    /// Where the triangle ids come from: [`ID_FROM_PRIMITIVE_INDEX`] or
    /// [`ID_FROM_FLAT_VERTEX_OUTPUT`].
    pub fn triangle_id_source(&self) -> &'static str {
        if self.primitive_index {
            ID_FROM_PRIMITIVE_INDEX
        } else {
            ID_FROM_FLAT_VERTEX_OUTPUT
        }
    }

    /// The render targets for `width` x `height`, created on a size change.
    fn targets(&self, ctx: &GpuContext, width: u32, height: u32) -> std::sync::Arc<Targets> {
        let mut guard = self.targets.lock().unwrap_or_else(|e| e.into_inner());
        match &*guard {
            Some(t) if t.width == width && t.height == height => t.clone(),
            _ => {
                let t = std::sync::Arc::new(Targets::new(ctx, width, height));
                *guard = Some(t.clone());
                t
            }
        }
    }

    /// The setup records for `triangles` triangles, created when the count changes.
    fn setups(&self, ctx: &GpuContext, triangles: u32) -> std::sync::Arc<Setups> {
        let mut guard = self.setups.lock().unwrap_or_else(|e| e.into_inner());
        match &*guard {
            Some(s) if s.triangles == triangles => s.clone(),
            _ => {
                let make = |label, size, usage| {
                    ctx.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some(label),
                        size,
                        usage,
                        mapped_at_creation: false,
                    })
                };
                let storage = wgpu::BufferUsages::STORAGE;
                let batch = batch_triangles(&ctx.limits).min(triangles.max(1));
                let slots = ((batch as f64 * CLIPPED_SLOTS_PER_TRIANGLE) as u32).max(MIN_CLIPPED_SLOTS);
                let stride = u64::from(ctx.limits.min_uniform_buffer_offset_alignment).max(RASTER_BATCH_BYTES);
                let batches = batch_count(triangles, batch);
                let mut records = vec![0u8; (u64::from(batches) * stride) as usize];
                for k in 0..batches {
                    let (first, count) = batch_range(triangles, batch, k);
                    let words = [first, count, 0, 0];
                    let at = (u64::from(k) * stride) as usize;
                    records[at..at + RASTER_BATCH_BYTES as usize].copy_from_slice(bytemuck::cast_slice(&words));
                }
                let batch_records = wgpu::util::DeviceExt::create_buffer_init(
                    &ctx.device,
                    &wgpu::util::BufferInitDescriptor {
                        label: Some("visibility_raster batches"),
                        contents: &records,
                        usage: wgpu::BufferUsages::UNIFORM,
                    },
                );
                let s = std::sync::Arc::new(Setups {
                    triangles,
                    batch,
                    buffer: make("visibility_raster setups", u64::from(batch) * RASTER_SETUP_BYTES, storage),
                    clipped: make("visibility_raster clipped setups", slots as u64 * CLIPPED_SETUP_BYTES, storage),
                    clipped_count: make("visibility_raster clipped count", 4, storage | wgpu::BufferUsages::COPY_DST),
                    batch_records,
                    stride,
                });
                *guard = Some(s.clone());
                s
            }
        }
    }

    /// Record the setup, raster and resolve passes of `frame.band`: render targets of
    /// `frame.width` x `frame.rows` (at most the device's `max_texture_dimension_2d` a
    /// side: [`crate::band::rows_per_band`]), the band's rows drawn into their top. The
    /// camera uniform describes the whole image; the frame parameters the band. The
    /// setup records are the whole image's: a scene of one batch ([`batch_triangles`])
    /// is set up by the first band (`first_row` 0) and kept for the frame's other bands;
    /// one of several batches is set up and drawn batch by batch, in every band, the
    /// render targets and depth kept from one batch's raster pass to the next.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let (width, rows) = (frame.width, frame.band.rows);
        if width == 0 || rows == 0 {
            return;
        }
        debug_assert_eq!(self.by_reference, scene.by_reference, "a raster compiled for the scene's world triangles");
        let scene_entries = self.scene_entries(scene);
        let targets = self.targets(ctx, width, frame.rows);
        let (Some(setup), Some(setup_layout)) = (&self.setup, &self.setup_layout) else {
            // Hardware interpolated: no setup records, one draw of every triangle.
            let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("visibility_raster (hardware interpolated)"),
                layout: &self.raster_layout,
                entries: &[
                    &[
                        wgpu::BindGroupEntry { binding: 0, resource: scene.triangles.first().as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 1, resource: frame.camera.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 10, resource: frame.params.as_entire_binding() },
                    ],
                    &scene_entries[..],
                ]
                .concat(),
            });
            let pass = RasterPass { load: false, keep_depth: false, first_timestamp: true };
            // Saturating: a table that large exceeds the storage binding limits anyway.
            self.raster_pass(encoder, frame, &targets, &group, scene.triangle_count.saturating_mul(3), pass, timing);
            self.resolve_pass(ctx, encoder, scene, frame, &targets, timing);
            return;
        };
        let setups = self.setups(ctx, scene.triangle_count);
        let batches = setups.batches();
        let run_setup = frame.band.first_row == 0 || batches > 1;
        // Bindings: setup writes 6 (setups), 8 (clipped), 9 (count) and reads the interior
        // culls (16); the raster reads 5, 7,
        // the band (10) and the surface tables (11, 12); both read the batch (15).
        let group = |label, layout, k: u32, setup: bool| {
            let first_binding = if setup { 6 } else { 5 };
            let mut entries = vec![
                wgpu::BindGroupEntry { binding: 0, resource: scene.triangles.first().as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: frame.camera.as_entire_binding() },
                wgpu::BindGroupEntry { binding: first_binding, resource: setups.buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: first_binding + 2, resource: setups.clipped.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 15, resource: setups.batch_binding(k) },
            ];
            if setup {
                entries.extend([
                    wgpu::BindGroupEntry { binding: 9, resource: setups.clipped_count.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 16, resource: scene.interior_culls.as_entire_binding() },
                ]);
            } else {
                entries.extend([
                    wgpu::BindGroupEntry { binding: 10, resource: frame.params.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 11, resource: scene.surface.words.first().as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 12, resource: scene.surface.layout.as_entire_binding() },
                ]);
                entries.extend(scene.surface.words.further());
            }
            entries.extend(scene_entries.iter().cloned());
            ctx.device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(label), layout, entries: &entries })
        };
        for k in 0..batches {
            let (_, count) = setups.batch_range(k);
            if run_setup {
                let setup_group = group("visibility_raster setup", setup_layout, k, true);
                encoder.clear_buffer(&setups.clipped_count, 0, None);
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("visibility_raster setup"),
                    timestamp_writes: timing.filter(|_| k == 0).map(|(query_set, i)| {
                        wgpu::ComputePassTimestampWrites {
                            query_set,
                            beginning_of_pass_write_index: Some(i),
                            end_of_pass_write_index: None,
                        }
                    }),
                });
                if count > 0 {
                    let groups = count.div_ceil(SETUP_GROUP);
                    let gx = groups.min(MAX_GROUPS_PER_DIMENSION);
                    pass.set_pipeline(setup);
                    pass.set_bind_group(0, &setup_group, &[]);
                    pass.dispatch_workgroups(gx, groups.div_ceil(gx), 1);
                }
            }
            let raster_group = group("visibility_raster", &self.raster_layout, k, false);
            let pass = RasterPass { load: k > 0, keep_depth: k + 1 < batches, first_timestamp: k == 0 && !run_setup };
            let vertices = count * 3 * HARDWARE_TRIANGLES_PER_TRIANGLE;
            self.raster_pass(encoder, frame, &targets, &raster_group, vertices, pass, timing);
        }
        self.resolve_pass(ctx, encoder, scene, frame, &targets, timing);
    }

    /// One raster pass over the band's render targets: `vertices` hardware vertices
    /// drawn with `group`.
    #[allow(clippy::too_many_arguments)]
    fn raster_pass(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        frame: &FrameBuffers,
        targets: &Targets,
        group: &wgpu::BindGroup,
        vertices: u32,
        how: RasterPass,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let color = |view| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: if how.load { wgpu::LoadOp::Load } else { wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT) },
                    store: wgpu::StoreOp::Store,
                },
            })
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("visibility_raster"),
            color_attachments: &[color(&targets.id), color(&targets.surface)],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.depth,
                depth_ops: Some(wgpu::Operations {
                    load: if how.load { wgpu::LoadOp::Load } else { wgpu::LoadOp::Clear(DEPTH_CLEAR) },
                    store: if how.keep_depth { wgpu::StoreOp::Store } else { wgpu::StoreOp::Discard },
                }),
                stencil_ops: None,
            }),
            // Unless a setup pass ran first and wrote the start.
            timestamp_writes: timing.filter(|_| how.first_timestamp).map(|(query_set, i)| {
                wgpu::RenderPassTimestampWrites {
                    query_set,
                    beginning_of_pass_write_index: Some(i),
                    end_of_pass_write_index: None,
                }
            }),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        // The band's rows: the top of the render targets (the last band may be shorter).
        pass.set_viewport(0.0, 0.0, frame.width as f32, frame.band.rows as f32, 0.0, 1.0);
        if vertices > 0 {
            pass.set_pipeline(&self.raster);
            pass.set_bind_group(0, group, &[]);
            pass.draw(0..vertices, 0..1);
        }
    }

    /// The resolve pass of `frame.band`: render targets into the G-buffer. It writes the
    /// stage's last timestamp.
    fn resolve_pass(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        targets: &Targets,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let (width, rows) = (frame.width, frame.band.rows);
        let camera = [wgpu::BindGroupEntry { binding: 1, resource: frame.camera.as_entire_binding() }];
        let resolve_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("visibility_raster resolve"),
            layout: &self.resolve_layout,
            entries: &[
                &[
                    wgpu::BindGroupEntry { binding: 0, resource: scene.triangles.first().as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&targets.id) },
                    wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::TextureView(&targets.surface) },
                    wgpu::BindGroupEntry { binding: 4, resource: frame.gbuffer.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 10, resource: frame.params.as_entire_binding() },
                ][..],
                &self.scene_entries(scene)[..],
                // Records made on read keep their products apart with `camera.pad`.
                if self.by_reference { &camera[..] } else { &[] },
            ]
            .concat(),
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("visibility_raster resolve"),
            timestamp_writes: timing.map(|(query_set, i)| wgpu::ComputePassTimestampWrites {
                query_set,
                beginning_of_pass_write_index: None,
                end_of_pass_write_index: Some(i + 1),
            }),
        });
        pass.set_pipeline(&self.resolve);
        pass.set_bind_group(0, &resolve_group, &[]);
        pass.dispatch_workgroups(width.div_ceil(RESOLVE_GROUP), rows.div_ceil(RESOLVE_GROUP), 1);
    }
}

/// How [`VisibilityRasterStage::raster_pass`] treats the render targets.
#[derive(Clone, Copy)]
struct RasterPass {
    /// Keep what an earlier batch drew (else clear).
    load: bool,
    /// Keep the depth for a later batch (else discard it).
    keep_depth: bool,
    /// The pass writes the stage's first timestamp (no setup pass ran before it).
    first_timestamp: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Batches fill one binding (lavapipe's 128 MiB: 1,677,721 triangles), at most
    /// `MAX_BATCH_TRIANGLES` (a 4 GiB binding), at least one triangle.
    #[test]
    fn batches_fit_one_binding_and_the_cap() {
        let limits = |binding: u64| wgpu::Limits {
            max_storage_buffer_binding_size: binding,
            max_buffer_size: u64::MAX,
            ..wgpu::Limits::default()
        };
        assert_eq!(batch_triangles(&limits(128 << 20)), 1_677_721);
        assert_eq!(batch_triangles(&limits((4 << 30) - 4)), MAX_BATCH_TRIANGLES);
        assert_eq!(batch_triangles(&limits(16)), 1);
        assert!(u64::from(MAX_BATCH_TRIANGLES) * RASTER_SETUP_BYTES <= 320 << 20);
        assert!(MAX_BATCH_TRIANGLES.checked_mul(3 * HARDWARE_TRIANGLES_PER_TRIANGLE).is_some());
    }
}
