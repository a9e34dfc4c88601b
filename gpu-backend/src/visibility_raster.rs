//! `visibility_raster` (paper 3.2) on the hardware raster pipeline: every triangle
//! of the scene table is drawn (non-indexed, vertices pulled from
//! [`SceneBuffers::triangles`]) into two render targets and a depth buffer, then a
//! compute pass resolves the targets into [`FrameBuffers::gbuffer`], texel for texel
//! the format of `hyrt_cpu::visibility_raster`.
//!
//! Reads: `scene.triangles`, `frame.camera`. Writes: `frame.gbuffer` (every texel).
//!
//! Raster pass (`vs_main` / `fs_main` in `shaders/visibility_raster.wgsl`):
//! * vertex `i` is corner `i % 3` of global triangle `i / 3`; its clip position is
//!   `camera.view_proj * (v, 1)`. A triangle with a non-finite clip coordinate gets
//!   the same clip position outside the view volume at all three corners (so NaN
//!   reaches neither the rasterizer nor a target) and is clipped away, as the CPU
//!   skips it;
//! * a per-vertex barycentric attribute `(1,0,0)`, `(0,1,0)`, `(0,0,1)`, interpolated
//!   perspective-correct, gives `(u, v)` = the weights of v1 and v2 at the pixel centre;
//! * no culling; depth `Depth32Float`, compare `Less`, cleared to 1.0: the nearest
//!   fragment wins and, at equal depth, the earlier triangle (primitive order);
//! * targets: [`ID_FORMAT`] holds the global triangle index + 1 (0, the clear value,
//!   is a miss); [`SURFACE_FORMAT`] holds `(u, v, window depth, front_facing as 0/1)`.
//!   The window depth is the fragment's `position.z`, the very value the depth test saw;
//! * the triangle id comes from `@builtin(primitive_index)` when the device has
//!   `PRIMITIVE_INDEX` ([`GpuContext::primitive_index`]), else from a flat-interpolated
//!   vertex output `vertex_index / 3` (vertices are not shared, so every corner of a
//!   triangle carries its id); [`VisibilityRasterStage::triangle_id_source`] says which.
//!
//! Facing: wgpu's `FrontFace::Ccw` is counter-clockwise in y-up NDC, which is
//! counter-clockwise on the y-down screen too (the viewport flips the axis, not the
//! picture): the CPU's "front" (`triangle_area2 > 0`). A fragment that is not front
//! facing gets `GBUF_BACK_FACE`.
//!
//! Resolve pass (`resolve`): one thread per pixel (8x8 groups): id 0 gives
//! `GBufferTexel::MISS`, else the triangle's record gives `triangle`, `object` and
//! `GBUF_RAY_TRACED` (from `TRI_RAY_TRACED`), the surface target the rest.
//!
//! The render targets are created per image size and cached in the stage. Image sides
//! must be within the device's `max_texture_dimension_2d` (8192 by default).
//!
//! Where it can differ from the CPU reference: the CPU emulates lavapipe's rules
//! (top-left fill rule, 1/256 px snapping, LESS), but the vertex maths (fused
//! multiply-adds, `x * (1/w)`) can put a snapped vertex one subpixel away on rounding
//! boundaries, and the depth and barycentrics are interpolated in f32 from the
//! unsnapped window positions where the CPU uses exact edge functions and f64; see
//! `hyrt_core::kernels::raster` and the bounds in `tests/visibility_raster.rs`.

use std::sync::Mutex;

use crate::buffers::{FrameBuffers, SceneBuffers};
use crate::{GpuContext, GpuError};

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

const SHADER: &str = include_str!("shaders/visibility_raster.wgsl");

/// Triangle id source names reported by [`VisibilityRasterStage::triangle_id_source`].
pub const ID_FROM_PRIMITIVE_INDEX: &str = "@builtin(primitive_index)";
pub const ID_FROM_FLAT_VERTEX_OUTPUT: &str = "flat-interpolated vertex_index / 3";

/// The WGSL of the stage, specialized for the triangle id source.
pub fn shader_source(primitive_index: bool) -> String {
    if primitive_index {
        format!(
            "enable primitive_index;\n{}",
            SHADER
                .replace("TRIANGLE_ID_PARAMETER", "@builtin(primitive_index) primitive: u32,")
                .replace("TRIANGLE_ID_EXPRESSION", "primitive")
        )
    } else {
        SHADER.replace("TRIANGLE_ID_PARAMETER", "").replace("TRIANGLE_ID_EXPRESSION", "in.triangle")
    }
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
            ctx.device
                .create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage,
                    view_formats: &[],
                })
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

/// The `visibility_raster` stage: a raster pipeline and a resolve compute pipeline.
pub struct VisibilityRasterStage {
    raster: wgpu::RenderPipeline,
    resolve: wgpu::ComputePipeline,
    raster_layout: wgpu::BindGroupLayout,
    resolve_layout: wgpu::BindGroupLayout,
    primitive_index: bool,
    /// Render targets of the last image size.
    targets: Mutex<Option<std::sync::Arc<Targets>>>,
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
        let primitive_index = primitive_index && ctx.primitive_index;
        let module = ctx.device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("visibility_raster"),
            source: wgpu::ShaderSource::Wgsl(shader_source(primitive_index).into()),
        });
        let raster = ctx.device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("visibility_raster"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
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
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
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
        let resolve = ctx.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("visibility_raster resolve"),
            layout: None,
            module: &module,
            entry_point: Some("resolve"),
            compilation_options: Default::default(),
            cache: None,
        });
        VisibilityRasterStage {
            raster_layout: raster.get_bind_group_layout(0),
            resolve_layout: resolve.get_bind_group_layout(0),
            raster,
            resolve,
            primitive_index,
            targets: Mutex::new(None),
        }
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

    /// Check that a `width` x `height` frame fits the device's render targets
    /// (`max_texture_dimension_2d`); [`Self::encode`] assumes it does.
    pub fn check_size(ctx: &GpuContext, width: u32, height: u32) -> Result<(), GpuError> {
        let max = ctx.limits.max_texture_dimension_2d;
        if width > max || height > max {
            return Err(GpuError::Limits(format!(
                "visibility_raster: {width}x{height} exceeds the device's {max}-pixel render target side"
            )));
        }
        Ok(())
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

    /// Record the raster pass and the resolve pass. The camera uniform must describe a
    /// `frame.width` x `frame.height` image, which must pass [`Self::check_size`].
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let (width, height) = (frame.width, frame.height);
        if width == 0 || height == 0 {
            return;
        }
        let targets = self.targets(ctx, width, height);
        let raster_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("visibility_raster"),
            layout: &self.raster_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: scene.triangles.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: frame.camera.as_entire_binding() },
            ],
        });
        let resolve_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("visibility_raster resolve"),
            layout: &self.resolve_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: scene.triangles.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: frame.camera.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&targets.id) },
                wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::TextureView(&targets.surface) },
                wgpu::BindGroupEntry { binding: 4, resource: frame.gbuffer.as_entire_binding() },
            ],
        });
        {
            let clear = |view| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })
            };
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("visibility_raster"),
                color_attachments: &[clear(&targets.id), clear(&targets.surface)],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &targets.depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(DEPTH_CLEAR),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: timing.map(|(query_set, i)| wgpu::RenderPassTimestampWrites {
                    query_set,
                    beginning_of_pass_write_index: Some(i),
                    end_of_pass_write_index: None,
                }),
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if scene.triangle_count > 0 {
                pass.set_pipeline(&self.raster);
                pass.set_bind_group(0, &raster_group, &[]);
                // Saturating: a table that large exceeds the storage binding limits anyway.
                pass.draw(0..scene.triangle_count.saturating_mul(3), 0..1);
            }
        }
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
        pass.dispatch_workgroups(width.div_ceil(RESOLVE_GROUP), height.div_ceil(RESOLVE_GROUP), 1);
    }
}
