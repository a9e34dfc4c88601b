//! Stage `compaction` on the GPU: active (pixel, light) pairs -> the shadow-ray
//! list, light-major then pixel order, bit for bit the list of
//! `hyrt_cpu::compaction::compaction`; per pair the kernels of
//! [`hyrt_core::kernels::shadow`], with the shading stages' light evaluation
//! (`shaders/shading_helpers.wgsl`).
//!
//! Reads `frame.surfaces` (or, at bounce depth `d`, the surfaces the rays of depth `d`
//! hit, as many as that list's count), `scene.lights`, `frame.params`. Writes
//! `frame.rays` and `frame.ray_count` (`[count, dispatch_x, dispatch_y, 1]`:
//! indirect-dispatch arguments for one thread per ray in workgroups of
//! [`SHADOW_RAYS_WORKGROUP_SIZE`](crate::shadow_rays::SHADOW_RAYS_WORKGROUP_SIZE),
//! `dispatch_x <= 65535`), or the bounce's shadow rays and their count. Scratch (flags
//! and scan levels) is owned by the stage and kept per list size. In a frame rendered in
//! bands ([`crate::band`]) it also writes where each light's rays start in the list
//! (`light_starts`, `shaders/light_starts.wgsl`: one binary search per light), so that
//! the bands' lists merge into the frame's light-major order.
//!
//! # Scan
//!
//! The flags are indexed `k = light * slots + surface` (`slots`: the pixels, or the
//! bounce's ray room; surfaces past the live count have none) and compacted by the
//! shared deterministic reduce-then-scan of [`crate::scan`].
//!
//! # Agreement with the CPU
//!
//! The ray records are exact on any conformant device: the origin offset
//! (`offset_ray_origin`, by the surface's error bound) is a sum, products and
//! additions whose product feeding the addition is kept unfused (the `zero` uniform)
//! and a step to the next float done on the bits, the direction is one correctly
//! rounded subtraction, the rest are constants. A device that flushes subnormals
//! differs only where an error bound is subnormal (coordinates below about 1e-31).
//! The flags use `light_incidence`'s square root and divisions (exact: `sqrt_rn`,
//! `div_rn`) and two dot products (each product unfused): a flag can differ only where
//! `radiance / d^2` is subnormal and the device flushes it (its float probe says so).
//! On lavapipe and the NVIDIA H200 the conformance corpus finds no difference.

use crate::buffers::{FrameBuffers, ListBuffers, SceneBuffers};
use crate::scan::{pipeline, scan_wgsl, ListScan, Scratch};
use crate::shader::{
    bind_buffers, main_pipeline, preamble, ray_wgsl, shader_module, shading_helpers, storage_entry, uniform_entry,
};

/// Threads per workgroup of `shaders/light_starts.wgsl` (one per light).
const LIGHT_STARTS_GROUP: u32 = 64;
use crate::{GpuContext, GpuError};

/// The compaction WGSL: the generated records and format constants, `ray.wgsl`, the
/// shading helpers (the light evaluation the shading stages use), `compaction.wgsl`,
/// then the scan.
fn compaction_wgsl() -> String {
    preamble() + &ray_wgsl() + &shading_helpers() + include_str!("shaders/compaction.wgsl") + &scan_wgsl()
}

/// The `compaction` stage: the shared scan over the stage's flags, and the test entry
/// point that scatters the indices of given flags.
pub struct CompactionStage {
    scan: ListScan,
    /// Banded frames: where each light's rays start in the list (`shaders/light_starts.wgsl`).
    light_starts: (wgpu::ComputePipeline, wgpu::BindGroupLayout),
    scatter_indices: wgpu::ComputePipeline,
    reduce_for_test: wgpu::ComputePipeline,
    test_layout: wgpu::BindGroupLayout,
}

impl CompactionStage {
    pub fn new(ctx: &GpuContext) -> Self {
        let device = &ctx.device;
        let module = shader_module(ctx, "compaction", &compaction_wgsl());
        let scan = ListScan::new(
            ctx,
            "compaction",
            &module,
            &[
                uniform_entry(0),        // params
                storage_entry(1, true),  // surfaces
                storage_entry(2, true),  // lights
                storage_entry(3, false), // rays
                uniform_entry(4),        // list
                storage_entry(5, true),  // live
            ],
            &[],
        );
        let test_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("compaction scan test"),
            entries: &[storage_entry(6, false)],
        });
        let with_test = [Some(&scan.scan_layout), Some(&test_layout)];
        let starts_module =
            shader_module(ctx, "compaction light starts", &(preamble() + include_str!("shaders/light_starts.wgsl")));
        let starts_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("compaction light starts"),
            entries: &[storage_entry(0, true), storage_entry(1, true), storage_entry(2, false)],
        });
        CompactionStage {
            light_starts: (
                main_pipeline(ctx, "compaction light starts", &starts_module, &starts_layout, &[]),
                starts_layout,
            ),
            scatter_indices: pipeline(device, &module, "scatter_indices", &with_test, &[]),
            reduce_for_test: pipeline(device, &module, "reduce", &with_test, &[]),
            scan,
            test_layout,
        }
    }

    /// Flag, scan and scatter the shadow rays of the primary hits: `frame.rays` and
    /// `frame.ray_count` of this frame.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        self.encode_list(ctx, encoder, scene, frame, &frame.primary_list(), timing)
    }

    /// The stage over one list's surfaces: its shadow rays and their count (and in a
    /// banded frame where each light's rays start, [`crate::band`]).
    pub fn encode_list(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        list: &ListBuffers,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let n = list.slots * frame.light_count;
        let buffers = [&frame.params, list.surfaces, &scene.lights, list.shadow_rays, list.params, list.live];
        self.scan.encode(ctx, encoder, "compaction", n, &buffers, list.shadow_ray_count, timing);
        if frame.banded && frame.light_count > 0 {
            let (pipeline, layout) = &self.light_starts;
            let group = bind_buffers(
                ctx,
                "compaction light starts",
                layout,
                &[list.shadow_rays, list.shadow_ray_count, list.light_starts],
            );
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("compaction light starts"),
                timestamp_writes: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(frame.light_count.div_ceil(LIGHT_STARTS_GROUP), 1, 1);
        }
    }

    /// The scan alone, for tests: the indices of the non-zero values among the
    /// first `n` of `flags` (u32), in increasing order, into `out_indices` (u32,
    /// room for `n`), and `[count, dispatch_x, dispatch_y, 1]` into `count`
    /// (16 bytes, storage). Same kernels and levels as [`Self::encode`], with
    /// `reduce` over the given flags instead of `flags_reduce`.
    pub fn encode_scan_for_test(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        flags: &wgpu::Buffer,
        n: u32,
        out_indices: &wgpu::Buffer,
        count: &wgpu::Buffer,
    ) -> Result<(), GpuError> {
        let scratch = Scratch::new(ctx, n, false)?;
        let scan_group = self.scan.scan_bind_group(ctx, &scratch, flags, count);
        let test_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("compaction scan test"),
            layout: &self.test_layout,
            entries: &[wgpu::BindGroupEntry { binding: 6, resource: out_indices.as_entire_binding() }],
        });
        self.scan.encode_passes(
            encoder,
            "compaction scan test",
            &scratch,
            &scan_group,
            &test_group,
            &self.reduce_for_test,
            &self.scatter_indices,
            None,
        );
        Ok(())
    }
}
