//! `present`: a frame rendered on the application's own wgpu device stays on the GPU,
//! in a texture the application owns, with the bits of the CPU reference's final image.

use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, FrameOptions, RenderError};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::scene::Scene;
use hyrt_cpu::backend::CpuBackend;
use hyrt_gpu::backend::GpuBackend;
use hyrt_gpu::GpuContext;

/// The application's device: its own instance, adapter (any, software included),
/// device and queue, created without hyrt, with up to `storage_buffers` storage buffers
/// per shader stage (WebGPU's default is 8).
fn application_device(storage_buffers: u32) -> Option<(wgpu::Adapter, wgpu::Device, wgpu::Queue)> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN));
    let Some(adapter) = adapters.into_iter().next() else {
        assert!(std::env::var_os("CI").is_none(), "CI needs a GPU adapter (lavapipe)");
        eprintln!("SKIPPED: no GPU adapter");
        return None;
    };
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("application"),
        required_features: adapter.features() & wgpu::Features::PRIMITIVE_INDEX,
        required_limits: wgpu::Limits {
            max_storage_buffer_binding_size: adapter.limits().max_storage_buffer_binding_size,
            max_buffer_size: adapter.limits().max_buffer_size,
            max_storage_buffers_per_shader_stage:
                adapter.limits().max_storage_buffers_per_shader_stage.min(storage_buffers),
            ..wgpu::Limits::default()
        },
        ..Default::default()
    }))
    .expect("device");
    Some((adapter, device, queue))
}

/// The application's 2D render target.
fn target(
    ctx: &GpuContext,
    width: u32,
    height: u32,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    hyrt_gpu::gpu_buffer::texture_2d(ctx, "application target", width, height, format, usage)
}

/// Read an `Rgba32Float` texture back, rows unpadded.
fn read_texture(ctx: &GpuContext, texture: &wgpu::Texture) -> Vec<[f32; 4]> {
    let (w, h) = (texture.width(), texture.height());
    let row = (w * 16).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("texture readback"),
        size: (row * h) as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    enc.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &staging,
            layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row), rows_per_image: Some(h) },
        },
        texture.size(),
    );
    ctx.queue.submit([enc.finish()]);
    staging.slice(..).map_async(wgpu::MapMode::Read, |r| r.expect("map"));
    ctx.device.poll(wgpu::PollType::Wait { submission_index: None, timeout: None }).expect("poll");
    let view = staging.slice(..).get_mapped_range().expect("mapped");
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h as usize {
        let r = &view[y * row as usize..][..w as usize * 16];
        out.extend(r.chunks_exact(16).map(bytemuck::pod_read_unaligned::<[f32; 4]>));
    }
    out
}

#[test]
fn present_renders_on_the_applications_device_into_its_texture() {
    let Some((adapter, device, queue)) =
        application_device(wgpu::Limits::default().max_storage_buffers_per_shader_stage)
    else {
        return;
    };
    let mut gpu = GpuBackend::with_context(GpuContext::from_device(&adapter, device, queue)).expect("pipelines");
    let mut scene = Scene::default_scene();
    scene.ensure_camera_and_lights();
    let cpu = CpuBackend::new(Some(2));
    let prepared = cpu.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    // 75x41: rows of 1200 bytes, not a multiple of the 256-byte copy alignment.
    let cam = CameraRecord::new(&scene.camera.unwrap(), 75, 41);
    let opts = FrameOptions { weight: 0.7, stage_outputs: false, max_depth: 0, ..FrameOptions::default() };
    let usage = wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC;
    let texture = target(gpu.context(), 75, 41, wgpu::TextureFormat::Rgba32Float, usage);
    let stats = gpu.render_to_texture(&prepared, &cam, &opts, &texture).expect("frame");
    assert_eq!(stats.stage_ms.len(), 7, "seven steps: {:?}", stats.stage_ms);
    let on_gpu = read_texture(gpu.context(), &texture);
    let mut cpu = cpu;
    let reference = cpu.render(&prepared, &cam, &opts).unwrap();
    let bits = |v: &[[f32; 4]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&on_gpu), bits(&reference.final_image), "the texture holds the reference's final image");
    assert_eq!(stats.rays_per_kind, reference.stats.rays_per_kind);

    // A texture of the wrong size is refused with a message, not a panic.
    let small = target(gpu.context(), 8, 8, wgpu::TextureFormat::Rgba16Float, usage);
    match gpu.render_to_texture(&prepared, &cam, &opts, &small) {
        Err(RenderError::InvalidOptions(m)) => assert!(m.contains("8x8"), "{m}"),
        other => panic!("expected InvalidOptions, got {other:?}"),
    }

    // A frame wider than the device's render targets is a typed GPU error the
    // application can match on (here: render smaller, or fall back to the CPU).
    let side = gpu.context().limits.max_texture_dimension_2d + 1;
    let wide = CameraRecord::new(&scene.camera.unwrap(), side, 1);
    match gpu.render(&prepared, &wide, &opts) {
        Err(RenderError::Gpu(hyrt_gpu::GpuError::Limits(m))) => {
            assert!(m.contains(&format!("{side}-pixel-wide")), "{m}")
        }
        other => panic!("expected RenderError::Gpu(GpuError::Limits), got {:?}", other.map(|f| f.stats)),
    }
    // One taller than them renders in bands of rows, the reference's frame.
    let tall = CameraRecord::new(&scene.camera.unwrap(), 1, side);
    let (on_gpu, reference) =
        (gpu.render(&prepared, &tall, &opts).unwrap(), cpu.render(&prepared, &tall, &opts).unwrap());
    assert_eq!(bits(&on_gpu.final_image), bits(&reference.final_image), "a frame taller than the render targets");

    // The application's device keeps WebGPU's default of 8 storage buffers per shader
    // stage, fewer than the bounce stages bind: a frame with bounces is a typed error
    // naming the limit, never a frame without them; the frames above rendered all the same.
    assert_eq!(gpu.context().limits.max_storage_buffers_per_shader_stage, 8);
    let bouncing = FrameOptions { max_depth: 2, ..opts };
    match gpu.render(&prepared, &cam, &bouncing) {
        Err(RenderError::Gpu(hyrt_gpu::GpuError::Limits(m))) => assert!(m.contains("storage buffers"), "{m}"),
        other => panic!("expected RenderError::Gpu(GpuError::Limits), got {:?}", other.map(|f| f.stats)),
    }
}

/// With room for the bounce stages' storage buffers, a frame with reflection and
/// refraction (the default max depth) stays on the GPU too: the texture holds the CPU
/// reference's final image, and the statistics its bounces' counts.
#[test]
fn present_renders_bounces_into_the_applications_texture() {
    let Some((adapter, device, queue)) = application_device(hyrt_gpu::backend::BOUNCE_STORAGE_BUFFERS) else { return };
    let mut gpu = GpuBackend::with_context(GpuContext::from_device(&adapter, device, queue)).expect("pipelines");
    let scene = Scene::default_scene();
    let mut cpu = CpuBackend::new(Some(2));
    let prepared = cpu.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    let cam = CameraRecord::new(&scene.camera.unwrap(), 64, 36);
    let opts = FrameOptions::default();
    let usage = wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC;
    let texture = target(gpu.context(), 64, 36, wgpu::TextureFormat::Rgba32Float, usage);
    let stats = gpu.render_to_texture(&prepared, &cam, &opts, &texture).expect("frame");
    let reference = cpu.render(&prepared, &cam, &opts).unwrap();
    assert!(!reference.stats.bounces.is_empty());
    let bits = |v: &[[f32; 4]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&read_texture(gpu.context(), &texture)), bits(&reference.final_image));
    assert_eq!(stats.bounces, reference.stats.bounces);
    assert_eq!(stats.rays_per_kind, reference.stats.rays_per_kind);
}
