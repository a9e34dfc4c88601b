//! `present`: the final image into a texture the application owns, so that a frame
//! can stay on the GPU and bond with the application's own raster pipeline (the
//! paper's point). Not a stage of the plan: it runs after `composition`, when the
//! caller asks for it ([`crate::backend::GpuBackend::render_to_texture`]).
//!
//! Reads `frame.final_image` and the frame size (the first two words of
//! `frame.params`). Writes the texture: linear RGBA, row 0 at the top, as stored.
//! The texture must be 2D, the frame's size, one mip level, usable as a storage
//! binding, in one of [`PRESENT_FORMATS`]: these are storage-capable on every
//! WebGPU device without extra features and hold linear values as they are (a
//! display pass applies the sRGB curve, as for any HDR render target).

use std::collections::HashMap;
use std::sync::Mutex;

use crate::buffers::FrameBuffers;
use crate::shader::{encode_pixel_pass, main_pipeline, preamble, shader_module, storage_entry, uniform_entry};
use crate::GpuContext;

/// The texture formats `present` writes.
pub const PRESENT_FORMATS: [wgpu::TextureFormat; 2] =
    [wgpu::TextureFormat::Rgba16Float, wgpu::TextureFormat::Rgba32Float];

/// Why a texture cannot receive a frame, in words for the caller.
pub fn check_target(texture: &wgpu::Texture, width: u32, height: u32) -> Result<(), String> {
    let s = texture.size();
    if (s.width, s.height, s.depth_or_array_layers) != (width, height, 1)
        || texture.dimension() != wgpu::TextureDimension::D2
    {
        return Err(format!(
            "target texture is {}x{}x{} ({:?}); the frame is {width}x{height} (2D, one layer)",
            s.width,
            s.height,
            s.depth_or_array_layers,
            texture.dimension()
        ));
    }
    if !PRESENT_FORMATS.contains(&texture.format()) {
        return Err(format!("target texture format {:?}: use one of {PRESENT_FORMATS:?}", texture.format()));
    }
    if !texture.usage().contains(wgpu::TextureUsages::STORAGE_BINDING) {
        return Err("target texture lacks TextureUsages::STORAGE_BINDING".into());
    }
    Ok(())
}

/// The `present` pass: one pipeline per target format, built when first asked for.
#[derive(Default)]
pub struct Present {
    pipelines: Mutex<HashMap<wgpu::TextureFormat, (wgpu::ComputePipeline, wgpu::BindGroupLayout)>>,
}

fn format_name(format: wgpu::TextureFormat) -> &'static str {
    match format {
        wgpu::TextureFormat::Rgba16Float => "rgba16float",
        wgpu::TextureFormat::Rgba32Float => "rgba32float",
        other => unreachable!("check_target refuses {other:?}"),
    }
}

impl Present {
    /// Record the copy of `frame.final_image` into `texture` (checked with
    /// [`check_target`] first).
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        frame: &FrameBuffers,
        texture: &wgpu::Texture,
    ) {
        let format = texture.format();
        let mut pipelines = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        let (pipeline, layout) = pipelines.entry(format).or_insert_with(|| {
            let source =
                preamble() + &include_str!("shaders/present.wgsl").replace("TARGET_FORMAT", format_name(format));
            let device = &ctx.device;
            let module = shader_module(ctx, "present", &source);
            let texture_entry = wgpu::BindGroupLayoutEntry {
                binding: 2,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::StorageTexture {
                    access: wgpu::StorageTextureAccess::WriteOnly,
                    format,
                    view_dimension: wgpu::TextureViewDimension::D2,
                },
                count: None,
            };
            let entries = [storage_entry(0, true), uniform_entry(1), texture_entry, storage_entry(3, true)];
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("present"),
                entries: &entries,
            });
            (main_pipeline("present", &module, &layout, &entries, &[]), layout)
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let bind_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("present"),
            layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: frame.final_image.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: frame.params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&view) },
                wgpu::BindGroupEntry { binding: 3, resource: frame.pixel_count.as_entire_binding() },
            ],
        });
        encode_pixel_pass(encoder, "present", pipeline, &bind_group, frame.width, frame.band.rows, None);
    }
}
