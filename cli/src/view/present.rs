//! Getting a frame onto the window. The CPU backend's frames are in memory and go
//! through a CPU framebuffer (softbuffer). The GPU backend's final image stays on the
//! device: `GpuBackend::render_to_texture` writes it into a texture, and a small render
//! pass draws that texture (sRGB-encoded) with the overlay blended on top into the
//! window's wgpu surface. The other stage views of the GPU backend are read back and
//! converted on the CPU, then uploaded (the legend says so).

use std::num::NonZeroU32;
use std::sync::Arc;

use hyrt::wgpu;
use winit::window::Window;

use super::overlay::{self, OverlayImage};
use super::stages::Rgba8;
use super::ViewError;

/// A CPU framebuffer on the window.
pub struct CpuPresenter {
    surface: softbuffer::Surface<Arc<Window>, Arc<Window>>,
    /// The frame with the overlay, before packing into the framebuffer's words.
    scratch: Vec<Rgba8>,
}

impl CpuPresenter {
    pub fn new(window: Arc<Window>) -> Result<CpuPresenter, ViewError> {
        let context =
            softbuffer::Context::new(window.clone()).map_err(|e| ViewError::Present(format!("softbuffer: {e}")))?;
        let surface =
            softbuffer::Surface::new(&context, window).map_err(|e| ViewError::Present(format!("softbuffer: {e}")))?;
        Ok(CpuPresenter { surface, scratch: Vec::new() })
    }

    /// Show `image` (`width` x `height`, opaque) with `overlay` over it.
    pub fn present(
        &mut self,
        image: &[Rgba8],
        width: u32,
        height: u32,
        overlay: Option<&OverlayImage>,
    ) -> Result<(), ViewError> {
        let err = |e: softbuffer::SoftBufferError| ViewError::Present(format!("softbuffer: {e}"));
        let (Some(w), Some(h)) = (NonZeroU32::new(width), NonZeroU32::new(height)) else { return Ok(()) };
        self.surface.resize(w, h).map_err(err)?;
        self.scratch.clear();
        self.scratch.extend_from_slice(image);
        if let Some(o) = overlay {
            overlay::compose(&mut self.scratch, width, o);
        }
        let mut buffer = self.surface.buffer_mut().map_err(err)?;
        for (dst, [r, g, b, _]) in buffer.iter_mut().zip(&self.scratch) {
            *dst = (*r as u32) << 16 | (*g as u32) << 8 | *b as u32;
        }
        buffer.present().map_err(err)
    }
}

/// `present.wgsl` after the tone mappers' constants, from core's values (one source).
fn shader_source() -> String {
    use hyrt_core::kernels::tone_map::{ACES_INPUT, ACES_OUTPUT, NEUTRAL_DESATURATION, NEUTRAL_START_COMPRESSION};
    // A Rust matrix given by rows as a WGSL matrix (given by columns) with the same rows.
    let matrix = |m: [[f32; 3]; 3]| {
        let columns: Vec<String> =
            (0..3).map(|j| format!("vec3<f32>({:?}, {:?}, {:?})", m[0][j], m[1][j], m[2][j])).collect();
        format!("mat3x3<f32>({})", columns.join(", "))
    };
    format!(
        "const NEUTRAL_START_COMPRESSION: f32 = {:?};\nconst NEUTRAL_DESATURATION: f32 = {:?};\n\
         const ACES_INPUT: mat3x3<f32> = {};\nconst ACES_OUTPUT: mat3x3<f32> = {};\n{}",
        NEUTRAL_START_COMPRESSION,
        NEUTRAL_DESATURATION,
        matrix(ACES_INPUT),
        matrix(ACES_OUTPUT),
        include_str!("present.wgsl")
    )
}

/// The shader's uniform: what the source is and where the overlay lies.
#[repr(C)]
#[derive(Clone, Copy)]
struct Params {
    /// 1: the frame texture (linear, needs the sRGB curve); 0: the view texture (sRGB).
    source_hdr: u32,
    /// 1: the surface encodes sRGB itself, so the shader writes linear values.
    surface_srgb: u32,
    overlay_w: u32,
    overlay_h: u32,
    /// The frame texture's exposure scale (`tone_map::exposure_scale`), as f32 bits.
    exposure: u32,
    /// The tone-mapping operator: its index in `hyrt::ToneMap::ALL`.
    tone_map: u32,
    pad: [u32; 2],
}

/// Textures of one frame size.
struct Targets {
    width: u32,
    height: u32,
    /// What `render_to_texture` writes: linear RGBA.
    frame: wgpu::Texture,
    /// Stage views converted on the CPU: sRGB RGBA8.
    view: wgpu::Texture,
}

/// A wgpu surface on the window, on the GPU backend's device.
pub struct GpuPresenter {
    device: wgpu::Device,
    queue: wgpu::Queue,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    targets: Option<Targets>,
    overlay: (wgpu::Texture, u32, u32),
}

/// The format of [`GpuPresenter::frame_texture`] (one of hyrt's present formats).
pub const FRAME_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

fn texture(
    device: &wgpu::Device,
    label: &str,
    w: u32,
    h: u32,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width: w.max(1), height: h.max(1), depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

impl GpuPresenter {
    /// A presenter on `surface` (created on the instance `ctx`'s adapter was picked from).
    pub fn new(
        ctx: &hyrt::GpuContext,
        surface: wgpu::Surface<'static>,
        width: u32,
        height: u32,
    ) -> Result<GpuPresenter, ViewError> {
        let caps = surface.get_capabilities(&ctx.adapter);
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| matches!(f, wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Rgba8Unorm))
            .or_else(|| caps.formats.first().copied())
            .ok_or_else(|| ViewError::Present(format!("the window's surface offers {} no format", ctx.info.name)))?;
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            format,
            color_space: Default::default(),
            width: width.max(1),
            height: height.max(1),
            present_mode: wgpu::PresentMode::AutoNoVsync,
            desired_maximum_frame_latency: 2,
            alpha_mode: caps.alpha_modes.first().copied().unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: vec![],
        };
        let device = ctx.device.clone();
        surface.configure(&device, &config);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("viewer present"),
            source: wgpu::ShaderSource::Wgsl(shader_source().into()),
        });
        let tex = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("viewer present"),
            entries: &[
                tex(0),
                tex(1),
                tex(2),
                wgpu::BindGroupLayoutEntry {
                    binding: 3,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("viewer present"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("viewer present"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState { format, blend: None, write_mask: wgpu::ColorWrites::ALL })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("viewer present params"),
            size: std::mem::size_of::<Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let overlay = texture(
            &device,
            "viewer overlay",
            1,
            1,
            wgpu::TextureFormat::Rgba8Unorm,
            wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        );
        Ok(GpuPresenter {
            queue: ctx.queue.clone(),
            device,
            surface,
            config,
            pipeline,
            layout,
            params,
            targets: None,
            overlay: (overlay, 0, 0),
        })
    }

    /// Follow the window's size.
    pub fn resize(&mut self, width: u32, height: u32) {
        if (width, height) != (self.config.width, self.config.height) && width > 0 && height > 0 {
            self.config.width = width;
            self.config.height = height;
            self.surface.configure(&self.device, &self.config);
        }
    }

    fn targets(&mut self, width: u32, height: u32) -> &Targets {
        if self.targets.as_ref().is_none_or(|t| (t.width, t.height) != (width, height)) {
            let d = &self.device;
            let frame = texture(
                d,
                "viewer frame",
                width,
                height,
                FRAME_FORMAT,
                wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
            );
            let view = texture(
                d,
                "viewer stage view",
                width,
                height,
                wgpu::TextureFormat::Rgba8Unorm,
                wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            );
            self.targets = Some(Targets { width, height, frame, view });
        }
        self.targets.as_ref().expect("just made")
    }

    /// The texture `render_to_texture` writes a `width` x `height` frame into.
    pub fn frame_texture(&mut self, width: u32, height: u32) -> wgpu::Texture {
        self.targets(width, height).frame.clone()
    }

    fn upload(&self, texture: &wgpu::Texture, pixels: &[Rgba8], width: u32, height: u32) {
        self.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            pixels.as_flattened(),
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(4 * width), rows_per_image: Some(height) },
            wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        );
    }

    /// Draw the frame texture (`view` = None; shown through `display`, an exposure scale
    /// and a tone-mapping operator) or a stage view converted on the CPU, with `overlay`
    /// over it, and present.
    pub fn present(
        &mut self,
        width: u32,
        height: u32,
        view: Option<&[Rgba8]>,
        overlay: Option<&OverlayImage>,
        display: (f32, hyrt::ToneMap),
    ) -> Result<(), ViewError> {
        self.targets(width, height);
        if let Some(pixels) = view {
            let t = self.targets.as_ref().expect("made above").view.clone();
            self.upload(&t, pixels, width, height);
        }
        let (ow, oh) = overlay.map_or((0, 0), |o| (o.width, o.height));
        if let Some(o) = overlay {
            if (self.overlay.1, self.overlay.2) != (ow, oh) {
                let t = texture(
                    &self.device,
                    "viewer overlay",
                    ow,
                    oh,
                    wgpu::TextureFormat::Rgba8Unorm,
                    wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                );
                self.overlay = (t, ow, oh);
            }
            self.upload(&self.overlay.0, &o.pixels, ow, oh);
        }
        let params = Params {
            source_hdr: view.is_none() as u32,
            surface_srgb: self.config.format.is_srgb() as u32,
            overlay_w: ow,
            overlay_h: oh,
            exposure: display.0.to_bits(),
            tone_map: hyrt::ToneMap::ALL.iter().position(|&t| t == display.1).unwrap_or(0) as u32,
            pad: [0; 2],
        };
        let words = [
            params.source_hdr,
            params.surface_srgb,
            params.overlay_w,
            params.overlay_h,
            params.exposure,
            params.tone_map,
            params.pad[0],
            params.pad[1],
        ];
        self.queue.write_buffer(&self.params, 0, &words.iter().flat_map(|w| w.to_le_bytes()).collect::<Vec<u8>>());
        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => return Ok(()),
            wgpu::CurrentSurfaceTexture::Outdated => {
                self.surface.configure(&self.device, &self.config);
                return Ok(());
            }
            other => return Err(ViewError::Present(format!("the window's surface: {other:?}"))),
        };
        let targets = self.targets.as_ref().expect("made above");
        let view_of = |t: &wgpu::Texture| t.create_view(&wgpu::TextureViewDescriptor::default());
        let (frame_view, stage_view, overlay_view) =
            (view_of(&targets.frame), view_of(&targets.view), view_of(&self.overlay.0));
        let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("viewer present"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&frame_view) },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&stage_view) },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&overlay_view) },
                wgpu::BindGroupEntry { binding: 3, resource: self.params.as_entire_binding() },
            ],
        });
        let target = view_of(&frame.texture);
        let mut encoder =
            self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("viewer present") });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("viewer present"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.draw(0..3, 0..1);
        }
        self.queue.submit([encoder.finish()]);
        self.queue.present(frame);
        Ok(())
    }
}
