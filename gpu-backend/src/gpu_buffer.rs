//! Storage buffers of core formats: creation, upload and readback.

use bytemuck::Pod;
use wgpu::util::DeviceExt;

use crate::{GpuContext, GpuError};

/// Usage of every hyrt storage buffer: read and written by shaders, copied to and
/// from for uploads, readbacks and `--dump`.
pub const STORAGE: wgpu::BufferUsages =
    wgpu::BufferUsages::STORAGE.union(wgpu::BufferUsages::COPY_SRC).union(wgpu::BufferUsages::COPY_DST);

/// WebGPU forbids zero-sized bindings: empty tables get one zeroed element.
fn non_empty<T: Pod>(data: &[T]) -> std::borrow::Cow<'_, [T]> {
    if data.is_empty() {
        std::borrow::Cow::Owned(vec![T::zeroed()])
    } else {
        std::borrow::Cow::Borrowed(data)
    }
}

/// A storage buffer initialized with `data` (one zeroed element if empty).
pub fn upload<T: Pod>(ctx: &GpuContext, label: &str, data: &[T]) -> wgpu::Buffer {
    ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::cast_slice(&non_empty(data)),
        usage: STORAGE,
    })
}

/// An uninitialized (zeroed by wgpu) storage buffer of `count` elements of `T`
/// (at least one), checked against the device's limits.
pub fn storage<T: Pod>(ctx: &GpuContext, label: &str, count: usize) -> Result<wgpu::Buffer, GpuError> {
    let size = (count.max(1) * std::mem::size_of::<T>()) as u64;
    let max = ctx.limits.max_storage_buffer_binding_size.min(ctx.limits.max_buffer_size);
    if size > max {
        return Err(GpuError::Limits(format!(
            "{label}: {size} bytes exceeds the device's {max}-byte storage buffer limit"
        )));
    }
    Ok(ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage: STORAGE,
        mapped_at_creation: false,
    }))
}

/// Copy byte ranges `[0, len)` of several buffers back to the CPU with one staging
/// buffer, one submission and one map (waits for the GPU). Lengths are rounded up to
/// wgpu's copy alignment; the returned vectors have the requested lengths.
pub fn read_back_many(ctx: &GpuContext, parts: &[(&wgpu::Buffer, u64)]) -> Result<Vec<Vec<u8>>, GpuError> {
    let mut out = Vec::with_capacity(parts.len());
    read_back_each(ctx, parts, |_, bytes| out.push(bytes.to_vec()))?;
    Ok(out)
}

/// [`read_back_many`] without the copies: `each(i, bytes)` sees part `i`'s bytes in
/// the mapped staging buffer, in order (empty for a zero length), so the caller can
/// copy them into buffers it keeps across frames.
pub fn read_back_each(
    ctx: &GpuContext,
    parts: &[(&wgpu::Buffer, u64)],
    mut each: impl FnMut(usize, &[u8]),
) -> Result<(), GpuError> {
    let align = |n: u64| n.div_ceil(wgpu::COPY_BUFFER_ALIGNMENT) * wgpu::COPY_BUFFER_ALIGNMENT;
    let total: u64 = parts.iter().map(|(_, n)| align(*n)).sum();
    if total == 0 {
        (0..parts.len()).for_each(|i| each(i, &[]));
        return Ok(());
    }
    let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("hyrt readback"),
        size: total,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("readback") });
    let mut offset = 0;
    for (buffer, n) in parts {
        if *n > 0 {
            encoder.copy_buffer_to_buffer(buffer, 0, &staging, offset, align(*n));
        }
        offset += align(*n);
    }
    ctx.queue.submit([encoder.finish()]);
    let slice = staging.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    ctx.device
        .poll(wgpu::PollType::Wait { submission_index: None, timeout: None })
        .map_err(|e| GpuError::Readback(e.to_string()))?;
    rx.recv().map_err(|e| GpuError::Readback(e.to_string()))?.map_err(|e| GpuError::Readback(e.to_string()))?;
    {
        let view = slice.get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
        let mut offset = 0usize;
        for (i, (_, n)) in parts.iter().enumerate() {
            each(i, &view[offset..offset + *n as usize]);
            offset += align(*n) as usize;
        }
    }
    staging.unmap();
    Ok(())
}

/// Append `bytes` read as `T`s to `dst` (`bytes` need not be aligned for `T`; its length
/// must be a multiple of `T`'s size); an error, and `dst` unchanged, where the allocator
/// cannot make room.
pub fn extend_from_bytes<T: Pod>(dst: &mut Vec<T>, bytes: &[u8]) -> Result<(), std::collections::TryReserveError> {
    let size = std::mem::size_of::<T>();
    debug_assert_eq!(bytes.len() % size, 0, "whole elements");
    dst.try_reserve(bytes.len() / size)?;
    let start = dst.len();
    dst.resize(start + bytes.len() / size, T::zeroed());
    bytemuck::cast_slice_mut::<T, u8>(&mut dst[start..]).copy_from_slice(bytes);
    Ok(())
}

/// Copy the first `count` elements of `buffer` back to the CPU (waits for the GPU).
pub fn read_back<T: Pod>(ctx: &GpuContext, buffer: &wgpu::Buffer, count: usize) -> Result<Vec<T>, GpuError> {
    let size = (count * std::mem::size_of::<T>()) as u64;
    if size == 0 {
        return Ok(Vec::new());
    }
    let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("hyrt readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("readback") });
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, size);
    ctx.queue.submit([encoder.finish()]);
    let slice = staging.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    ctx.device
        .poll(wgpu::PollType::Wait { submission_index: None, timeout: None })
        .map_err(|e| GpuError::Readback(e.to_string()))?;
    rx.recv().map_err(|e| GpuError::Readback(e.to_string()))?.map_err(|e| GpuError::Readback(e.to_string()))?;
    let out = {
        let view = slice.get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
        bytemuck::pod_collect_to_vec::<u8, T>(&view[..])
    };
    staging.unmap();
    Ok(out)
}

/// A 2D texture of one layer, one mip level and one sample (render targets, the
/// raster's G-buffer attachments, an application's `present` target).
pub fn texture_2d(
    ctx: &GpuContext,
    label: &str,
    width: u32,
    height: u32,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}
