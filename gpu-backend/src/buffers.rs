//! The GPU buffers of a scene and of a frame. Created once per scene and once
//! per image size and light count, reused across frames; every stage binds
//! these by name. Element layouts are the core formats (documented to the byte
//! in [`hyrt_core::formats`]) unless said otherwise here.

use hyrt_core::bvh::BvhNode;
use hyrt_core::formats::{
    CameraRecord, GBufferTexel, LightRecord, ObjectRecord, RayRecord, SurfaceRecord, TriangleRecord,
};
use hyrt_core::frame::PreparedScene;
use hyrt_core::plan::{FrameBuffer, FramePlan};

use crate::gpu_buffer::{storage, upload};
use crate::{GpuContext, GpuError};

/// The per-frame uniform parameters, defined in [`hyrt_core::formats`] (with the
/// other records the shaders declare); re-exported at their old path.
pub use hyrt_core::formats::FrameParams;

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

/// Per-frame buffers for one image size, light count and set of planned stages,
/// reused across frames. A buffer whose stage the plan skips is not allocated: its
/// field holds `empty` (one 16-byte buffer shared by every absent one), so bind
/// groups stay valid while no skipped stage is encoded.
pub struct FrameBuffers {
    pub width: u32,
    pub height: u32,
    pub light_count: u32,
    /// Rays `rays` and `occluded` have room for (0 when the plan traces none). The
    /// frame's rays are known only after `compaction`: a frame with more reallocates
    /// and runs again (see `GpuBackend`).
    pub ray_capacity: u32,
    /// The frame buffers allocated (the plan's, in [`FrameBuffer::ALL`] order).
    pub allocated: Vec<FrameBuffer>,
    /// Uniform `CameraRecord`.
    pub camera: wgpu::Buffer,
    /// Uniform [`FrameParams`].
    pub params: wgpu::Buffer,
    /// `array<GBufferTexel>`, one per pixel (`visibility_raster`).
    pub gbuffer: wgpu::Buffer,
    /// `array<SurfaceRecord>`, one per pixel (`reconstruction`).
    pub surfaces: wgpu::Buffer,
    /// `array<RayRecord>` with room for `ray_capacity` rays (`compaction`).
    pub rays: wgpu::Buffer,
    /// `array<u32>`, 4 words: `[ray_count, dispatch_x, dispatch_y, dispatch_z]`, written by
    /// `compaction`; the last three are indirect-dispatch arguments for one thread per ray.
    /// `ray_count` is the frame's true count, even past `ray_capacity`.
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
    /// The stand-in for every buffer the plan does not produce (16 bytes, never written).
    pub empty: wgpu::Buffer,
}

impl FrameBuffers {
    /// Every buffer of a `width` x `height` frame with `light_count` lights, with room
    /// for a ray per (pixel, light): what the stage tests bind.
    pub fn new(ctx: &GpuContext, width: u32, height: u32, light_count: u32) -> Result<FrameBuffers, GpuError> {
        let everything = FramePlan::from_counts(hyrt_core::plan::SceneNeeds {
            lights: light_count.max(1),
            triangles: true,
            ray_traced: true,
            rasterized: true,
            bouncing: false,
            weight: 0.5,
            max_depth: 0,
        });
        let pairs = width as usize * height as usize * light_count as usize;
        let capacity = u32::try_from(pairs).map_err(|_| GpuError::Limits(format!("{pairs} rays")))?;
        Self::for_plan(ctx, width, height, light_count, &everything, capacity)
    }

    /// Allocate the buffers `plan` produces for a `width` x `height` frame with
    /// `light_count` lights and room for `ray_capacity` rays.
    pub fn for_plan(
        ctx: &GpuContext,
        width: u32,
        height: u32,
        light_count: u32,
        plan: &FramePlan,
        ray_capacity: u32,
    ) -> Result<FrameBuffers, GpuError> {
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
        let empty = storage::<[u32; 4]>(ctx, "empty (a skipped stage's buffer)", 1)?;
        let allocated: Vec<FrameBuffer> = plan.buffers().collect();
        let ray_capacity = if plan.produces(FrameBuffer::Rays) { ray_capacity } else { 0 };
        let alloc = |b: FrameBuffer, f: &dyn Fn() -> Result<wgpu::Buffer, GpuError>| {
            if allocated.contains(&b) {
                f()
            } else {
                Ok(empty.clone())
            }
        };
        Ok(FrameBuffers {
            width,
            height,
            light_count,
            ray_capacity,
            camera: uniform("camera", std::mem::size_of::<CameraRecord>() as u64),
            params: uniform("frame params", std::mem::size_of::<FrameParams>() as u64),
            gbuffer: alloc(FrameBuffer::GBuffer, &|| storage::<GBufferTexel>(ctx, "gbuffer", pixels))?,
            surfaces: alloc(FrameBuffer::Surfaces, &|| storage::<SurfaceRecord>(ctx, "surfaces", pixels))?,
            rays: alloc(FrameBuffer::Rays, &|| storage::<RayRecord>(ctx, "rays", ray_capacity as usize))?,
            ray_count: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("ray count"),
                size: 16,
                usage: crate::gpu_buffer::STORAGE | wgpu::BufferUsages::INDIRECT,
                mapped_at_creation: false,
            }),
            occluded: alloc(FrameBuffer::Occluded, &|| storage::<u32>(ctx, "occluded", ray_capacity as usize))?,
            shadow: alloc(FrameBuffer::Shadow, &|| storage::<u32>(ctx, "shadow", pairs))?,
            rt: alloc(FrameBuffer::Rt, &|| storage::<[f32; 4]>(ctx, "rt image", pixels))?,
            raster: alloc(FrameBuffer::Raster, &|| storage::<[f32; 4]>(ctx, "raster image", pixels))?,
            final_image: alloc(FrameBuffer::Final, &|| storage::<[f32; 4]>(ctx, "final image", pixels))?,
            allocated,
            empty,
        })
    }

    /// True if these buffers fit a frame of this size and light count under `plan`
    /// with `rays` rays.
    pub fn fits(&self, width: u32, height: u32, light_count: u32, plan: &FramePlan, rays: u32) -> bool {
        (self.width, self.height, self.light_count) == (width, height, light_count)
            && self.allocated.iter().copied().eq(plan.buffers())
            && (!plan.produces(FrameBuffer::Rays) || rays <= self.ray_capacity)
    }

    /// The GPU buffer holding `buffer`.
    pub fn get(&self, buffer: FrameBuffer) -> &wgpu::Buffer {
        match buffer {
            FrameBuffer::GBuffer => &self.gbuffer,
            FrameBuffer::Surfaces => &self.surfaces,
            FrameBuffer::Rays => &self.rays,
            FrameBuffer::Occluded => &self.occluded,
            FrameBuffer::Shadow => &self.shadow,
            FrameBuffer::Rt => &self.rt,
            FrameBuffer::Raster => &self.raster,
            FrameBuffer::Final => &self.final_image,
            FrameBuffer::Bounce { .. } => unreachable!("plans with bounces are refused before buffers are bound"),
        }
    }

    /// Write the camera and frame parameters for the next frame.
    pub fn write_uniforms(&self, ctx: &GpuContext, camera: &CameraRecord, params: &FrameParams) {
        ctx.queue.write_buffer(&self.camera, 0, bytemuck::bytes_of(camera));
        ctx.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
    }
}
