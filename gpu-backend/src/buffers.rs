//! The GPU buffers of a scene and of a frame. Created once per scene and once
//! per image size and light count, reused across frames; every stage binds
//! these by name. Element layouts are the core formats (documented to the byte
//! in [`hyrt_core::formats`]) unless said otherwise here.

use bytemuck::{Pod, Zeroable};
use hyrt_core::bvh::BvhNode;
use hyrt_core::formats::{
    CameraRecord, GBufferTexel, LightRecord, ObjectRecord, RayRecord, SurfaceRecord, TriangleRecord,
};
use hyrt_core::frame::PreparedScene;

use crate::gpu_buffer::{storage, upload};
use crate::{GpuContext, GpuError};

/// Per-frame parameters, one uniform buffer.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `width` | u32 | image width |
/// | 4 | `height` | u32 | image height |
/// | 8 | `light_count` | u32 | lights in the light list |
/// | 12 | `weight` | f32 | composition weight in [0, 1] |
/// | 16 | `zero` | u32 | always 0: shaders OR it into the bits of products, which the compiler cannot see through, so it cannot fuse them into multiply-adds (the CPU kernels round every product) |
/// | 20 | `pad` | [u32; 3] | zero (uniform structs are 16-byte multiples) |
///
/// 32 bytes. Build with [`FrameParams::new`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct FrameParams {
    pub width: u32,
    pub height: u32,
    pub light_count: u32,
    pub weight: f32,
    pub zero: u32,
    pub pad: [u32; 3],
}
const _: () = assert!(std::mem::size_of::<FrameParams>() == 32);

impl FrameParams {
    /// The parameters of a `width` x `height` frame with `light_count` lights.
    pub fn new(width: u32, height: u32, light_count: u32, weight: f32) -> Self {
        FrameParams { width, height, light_count, weight, zero: 0, pad: [0; 3] }
    }

    /// Check: a non-empty image, a weight in [0, 1], `zero` and padding zero.
    pub fn validate(&self) -> Result<(), String> {
        if self.zero != 0 || self.pad != [0; 3] {
            return Err(format!("frame parameters with non-zero zero/padding: {self:?}"));
        }
        if self.width == 0 || self.height == 0 {
            return Err(format!("empty image {}x{}", self.width, self.height));
        }
        if !(0.0..=1.0).contains(&self.weight) {
            return Err(format!("weight {} outside [0, 1]", self.weight));
        }
        Ok(())
    }
}

/// Scene tables on the GPU (from a [`PreparedScene`]; built once per scene).
pub struct SceneBuffers {
    /// `array<TriangleRecord>`: the world triangle table.
    pub triangles: wgpu::Buffer,
    /// `array<f32>`, 9 per triangle: the world normals at its three corners (x, y, z each).
    pub normals: wgpu::Buffer,
    /// `array<ObjectRecord>`.
    pub objects: wgpu::Buffer,
    /// `array<LightRecord>`.
    pub lights: wgpu::Buffer,
    /// `array<BvhNode>`: the flattened BVH ([`hyrt_core::bvh`]); empty BVH: one zero node and `bvh_node_count == 0`.
    pub bvh_nodes: wgpu::Buffer,
    /// `array<TriangleRecord>`: triangles in BVH leaf order (`Bvh::leaf_triangles`).
    pub bvh_leaf_triangles: wgpu::Buffer,
    /// `array<u32>`: global triangle index of each leaf slot (`Bvh::prim_indices`).
    pub bvh_prim_indices: wgpu::Buffer,
    pub triangle_count: u32,
    pub object_count: u32,
    pub light_count: u32,
    pub bvh_node_count: u32,
}

impl SceneBuffers {
    /// Upload the tables of `scene`.
    pub fn new(ctx: &GpuContext, scene: &PreparedScene) -> SceneBuffers {
        let g = &scene.geometry;
        let normals: Vec<f32> = g.normals.iter().flat_map(|n| n.iter().flat_map(|v| v.to_array())).collect();
        SceneBuffers {
            triangles: upload::<TriangleRecord>(ctx, "triangles", &g.triangles),
            normals: upload(ctx, "normals", &normals),
            objects: upload::<ObjectRecord>(ctx, "objects", &g.objects),
            lights: upload::<LightRecord>(ctx, "lights", &g.lights),
            bvh_nodes: upload::<BvhNode>(ctx, "bvh nodes", &scene.bvh.nodes),
            bvh_leaf_triangles: upload::<TriangleRecord>(ctx, "bvh leaf triangles", &scene.bvh.leaf_triangles),
            bvh_prim_indices: upload::<u32>(ctx, "bvh prim indices", &scene.bvh.prim_indices),
            triangle_count: g.triangles.len() as u32,
            object_count: g.objects.len() as u32,
            light_count: g.lights.len() as u32,
            bvh_node_count: scene.bvh.nodes.len() as u32,
        }
    }
}

/// Per-frame buffers for one image size and light count, reused across frames.
pub struct FrameBuffers {
    pub width: u32,
    pub height: u32,
    pub light_count: u32,
    /// Uniform `CameraRecord`.
    pub camera: wgpu::Buffer,
    /// Uniform [`FrameParams`].
    pub params: wgpu::Buffer,
    /// `array<GBufferTexel>`, one per pixel (`visibility_raster`).
    pub gbuffer: wgpu::Buffer,
    /// `array<SurfaceRecord>`, one per pixel (`reconstruction`).
    pub surfaces: wgpu::Buffer,
    /// `array<RayRecord>` with room for `pixels * lights` rays (`compaction`).
    pub rays: wgpu::Buffer,
    /// `array<u32>`, 4 words: `[ray_count, dispatch_x, dispatch_y, dispatch_z]`, written by
    /// `compaction`; the last three are indirect-dispatch arguments for one thread per ray.
    pub ray_count: wgpu::Buffer,
    /// `array<u32>`, one per ray slot: 1 occluded, 0 reached the light (`shadow_rays`).
    pub occluded: wgpu::Buffer,
    /// `array<u32>`, `pixels * lights`, index `pixel * lights + light`: the `SHADOW_*` codes
    /// of [`hyrt_core::frame`] (u32 here; u8 on the CPU, converted on readback).
    pub shadow: wgpu::Buffer,
    /// `array<vec4<f32>>`, one per pixel: `rt_shading`, `raster_shading`, `composition`.
    pub rt: wgpu::Buffer,
    pub raster: wgpu::Buffer,
    pub final_image: wgpu::Buffer,
}

impl FrameBuffers {
    /// Allocate the buffers of a `width` x `height` frame with `light_count` lights.
    pub fn new(ctx: &GpuContext, width: u32, height: u32, light_count: u32) -> Result<FrameBuffers, GpuError> {
        let pixels = width as usize * height as usize;
        let pairs = pixels * light_count as usize;
        let uniform = |label: &str, size: u64| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        Ok(FrameBuffers {
            width,
            height,
            light_count,
            camera: uniform("camera", std::mem::size_of::<CameraRecord>() as u64),
            params: uniform("frame params", std::mem::size_of::<FrameParams>() as u64),
            gbuffer: storage::<GBufferTexel>(ctx, "gbuffer", pixels)?,
            surfaces: storage::<SurfaceRecord>(ctx, "surfaces", pixels)?,
            rays: storage::<RayRecord>(ctx, "rays", pairs)?,
            ray_count: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("ray count"),
                size: 16,
                usage: crate::gpu_buffer::STORAGE | wgpu::BufferUsages::INDIRECT,
                mapped_at_creation: false,
            }),
            occluded: storage::<u32>(ctx, "occluded", pairs)?,
            shadow: storage::<u32>(ctx, "shadow", pairs)?,
            rt: storage::<[f32; 4]>(ctx, "rt image", pixels)?,
            raster: storage::<[f32; 4]>(ctx, "raster image", pixels)?,
            final_image: storage::<[f32; 4]>(ctx, "final image", pixels)?,
        })
    }

    /// True if these buffers fit a frame of this size and light count.
    pub fn fits(&self, width: u32, height: u32, light_count: u32) -> bool {
        (self.width, self.height, self.light_count) == (width, height, light_count)
    }

    /// Write the camera and frame parameters for the next frame.
    pub fn write_uniforms(&self, ctx: &GpuContext, camera: &CameraRecord, params: &FrameParams) {
        ctx.queue.write_buffer(&self.camera, 0, bytemuck::bytes_of(camera));
        ctx.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
    }
}
