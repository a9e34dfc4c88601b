//! Stage `compaction` on the GPU: active (pixel, light) pairs -> the shadow-ray
//! list, light-major then pixel order, bit for bit the list of
//! `hyrt_cpu::compaction::compaction`; per pair the kernels of
//! [`hyrt_core::kernels::shadow`], with the shading stages' light evaluation
//! (`shaders/shading_helpers.wgsl`).
//!
//! Reads `frame.surfaces`, `scene.lights`, `frame.params`. Writes `frame.rays`
//! and `frame.ray_count` (`[count, dispatch_x, dispatch_y, 1]`: indirect-dispatch
//! arguments for one thread per ray in workgroups of
//! [`SHADOW_RAYS_WORKGROUP_SIZE`](crate::shadow_rays::SHADOW_RAYS_WORKGROUP_SIZE),
//! `dispatch_x <= 65535`). Scratch (flags and scan levels) is owned by the stage
//! and reused while the frame size stays the same.
//!
//! # Scan
//!
//! A portable, deterministic reduce-then-scan over u32 flags, indexed
//! `k = light * pixels + pixel` (no atomics, no decoupled look-back: WebGPU has
//! no forward-progress guarantee). A tile is [`COMPACTION_TILE`] =
//! [`COMPACTION_WORKGROUP_SIZE`] x [`COMPACTION_ITEMS_PER_THREAD`] elements; each
//! thread owns consecutive elements and the workgroup scans the per-thread sums
//! (Hillis-Steele, log2 of the workgroup size barriers: barriers are the
//! expensive part on lavapipe, so threads do serial work first).
//!
//! Level 0 is the flags; level `i + 1` holds one value per tile of level `i`,
//! until a level fits one tile (the top). One compute pass, in order:
//! `flags_reduce` (flags and per-tile counts), `reduce` per level up to the top,
//! `scan_top` (one workgroup; writes the count and dispatch arguments),
//! `downsweep` per level back down (each tile scanned in place, offset by the
//! level above), `scatter_rays` (each active pair writes its ray at its scanned
//! index). Integer sums are exact, so the list is stable and identical on every
//! run and backend. Dispatches use 2D grids past 65535 tiles.
//!
//! # Agreement with the CPU
//!
//! The ray records are exact on any conformant device: the origin offset
//! (`offset_ray_origin`, by the surface's error bound) is a sum, products and
//! additions whose product feeding the addition is kept unfused (the `zero` uniform)
//! and a step to the next float done on the bits, the direction is one correctly
//! rounded subtraction, the rest are constants. A device that flushes subnormals
//! differs only where an error bound is subnormal (coordinates below about 1e-31).
//! The flags use `light_incidence`'s `sqrt` and divisions and two dot products,
//! which a GPU may fuse or round within 2.5 ulp: a flag can then differ only where
//! `n . l` is within a few ulps of zero (grazing light), or where `radiance / d^2` is
//! subnormal and flushed.
//! On lavapipe the default-scene tests find no difference.

use hyrt_core::formats::wgsl::declarations;
use std::sync::Mutex;

use crate::buffers::{FrameBuffers, SceneBuffers};
use crate::gpu_buffer::storage;
use crate::rt_shading::shading_helpers;
use crate::shadow_rays::{ray_wgsl, storage_entry, uniform_entry, MAX_WORKGROUPS_PER_DIMENSION};
use crate::{GpuContext, GpuError};

/// Threads per compaction workgroup. Tunable: larger means fewer tiles but more
/// barrier steps in the workgroup scan (log2 of it), which dominate on lavapipe.
pub const COMPACTION_WORKGROUP_SIZE: u32 = 64;
/// Consecutive flags each thread sums serially before the workgroup scan.
pub const COMPACTION_ITEMS_PER_THREAD: u32 = 8;
/// Elements per tile (one workgroup) at every scan level.
pub const COMPACTION_TILE: u32 = COMPACTION_WORKGROUP_SIZE * COMPACTION_ITEMS_PER_THREAD;

/// Per-level uniform (`Level` in compaction.wgsl), 16 bytes, one per dynamic
/// offset slot.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct LevelParams {
    n: u32,
    src_off: u32,
    dst_off: u32,
    src_is_flags: u32,
}

/// The level structure of a scan over `n` flags: sizes and offsets of levels
/// 1.. in the `levels` scratch buffer.
#[derive(Clone, Debug, PartialEq)]
struct ScanPlan {
    n: u32,
    /// (element count, offset in `levels`) of levels 1..=top.
    levels: Vec<(u32, u32)>,
}

fn div_ceil(a: u32, b: u32) -> u32 {
    a.div_ceil(b)
}

impl ScanPlan {
    fn new(n: u32) -> ScanPlan {
        let mut levels = Vec::new();
        let mut count = div_ceil(n, COMPACTION_TILE);
        let mut off = 0u32;
        loop {
            levels.push((count, off));
            off += count.max(1);
            if count <= COMPACTION_TILE {
                break;
            }
            count = div_ceil(count, COMPACTION_TILE);
        }
        ScanPlan { n, levels }
    }

    fn levels_len(&self) -> u32 {
        self.levels.iter().map(|&(c, _)| c.max(1)).sum()
    }

    /// Uniform slot `i`: level `i` (0 = flags) with the level above as `dst`.
    fn params(&self) -> Vec<LevelParams> {
        let mut out = vec![LevelParams { n: self.n, src_off: 0, dst_off: self.levels[0].1, src_is_flags: 1 }];
        for (i, &(count, off)) in self.levels.iter().enumerate() {
            let dst_off = self.levels.get(i + 1).map_or(0, |l| l.1);
            out.push(LevelParams { n: count, src_off: off, dst_off, src_is_flags: 0 });
        }
        out
    }
}

/// Workgroup grid of `tiles` tiles: x-major, `x <= 65535`.
fn grid(tiles: u32) -> (u32, u32) {
    if tiles == 0 {
        return (0, 1);
    }
    let x = tiles.min(MAX_WORKGROUPS_PER_DIMENSION);
    (x, tiles.div_ceil(x))
}

/// Scratch of one scan size.
struct Scratch {
    plan: ScanPlan,
    flags: wgpu::Buffer,
    levels: wgpu::Buffer,
    /// One [`LevelParams`] per uniform slot, `stride` bytes apart.
    params: wgpu::Buffer,
    stride: u32,
}

impl Scratch {
    fn new(ctx: &GpuContext, n: u32, with_flags: bool) -> Result<Scratch, GpuError> {
        let plan = ScanPlan::new(n);
        let stride = ctx.limits.min_uniform_buffer_offset_alignment.max(16);
        let params = plan.params();
        let mut bytes = vec![0u8; params.len() * stride as usize];
        for (i, p) in params.iter().enumerate() {
            let o = i * stride as usize;
            bytes[o..o + 16].copy_from_slice(bytemuck::bytes_of(p));
        }
        let params_buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("compaction levels params"),
            size: bytes.len() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        ctx.queue.write_buffer(&params_buf, 0, &bytes);
        Ok(Scratch {
            flags: storage::<u32>(ctx, "compaction flags", if with_flags { n as usize } else { 1 })?,
            levels: storage::<u32>(ctx, "compaction scan levels", plan.levels_len() as usize)?,
            params: params_buf,
            plan,
            stride,
        })
    }
}

/// The `compaction` stage: six entry points of one module, two bind group layouts
/// (scan, frame) plus the test layout.
pub struct CompactionStage {
    flags_reduce: wgpu::ComputePipeline,
    reduce: wgpu::ComputePipeline,
    scan_top: wgpu::ComputePipeline,
    downsweep: wgpu::ComputePipeline,
    scatter_rays: wgpu::ComputePipeline,
    scatter_indices: wgpu::ComputePipeline,
    scan_layout: wgpu::BindGroupLayout,
    frame_layout: wgpu::BindGroupLayout,
    test_layout: wgpu::BindGroupLayout,
    scratch: Mutex<Option<Scratch>>,
}

/// The compaction WGSL: the generated records and format constants, the stage's
/// constants, `ray.wgsl`, the shading helpers (the light evaluation the shading stages
/// use), `compaction.wgsl`.
fn compaction_wgsl() -> String {
    declarations()
        + &format!(
            "const WG = {COMPACTION_WORKGROUP_SIZE}u;\nconst ITEMS = {COMPACTION_ITEMS_PER_THREAD}u;\nconst TILE = {COMPACTION_TILE}u;\n"
        )
        + &ray_wgsl()
        + &shading_helpers()
        + include_str!("shaders/compaction.wgsl")
}

impl CompactionStage {
    pub fn new(ctx: &GpuContext) -> Self {
        let device = &ctx.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("compaction"),
            source: wgpu::ShaderSource::Wgsl(compaction_wgsl().into()),
        });
        let scan_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("compaction scan"),
            entries: &[
                uniform_entry(0, true),
                storage_entry(1, false),
                storage_entry(2, false),
                storage_entry(3, false),
            ],
        });
        let frame_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("compaction frame"),
            entries: &[
                uniform_entry(0, false),
                storage_entry(1, true),
                storage_entry(2, true),
                storage_entry(3, false),
            ],
        });
        let test_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("compaction scan test"),
            entries: &[storage_entry(4, false)],
        });
        let layout = |groups: &[Option<&wgpu::BindGroupLayout>]| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("compaction"),
                bind_group_layouts: groups,
                immediate_size: 0,
            })
        };
        let scan_only = layout(&[Some(&scan_layout)]);
        let with_frame = layout(&[Some(&scan_layout), Some(&frame_layout)]);
        let with_test = layout(&[Some(&scan_layout), Some(&test_layout)]);
        let pipeline = |entry: &str, layout: &wgpu::PipelineLayout| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        CompactionStage {
            flags_reduce: pipeline("flags_reduce", &with_frame),
            reduce: pipeline("reduce", &scan_only),
            scan_top: pipeline("scan_top", &scan_only),
            downsweep: pipeline("downsweep", &scan_only),
            scatter_rays: pipeline("scatter_rays", &with_frame),
            scatter_indices: pipeline("scatter_indices", &with_test),
            scan_layout,
            frame_layout,
            test_layout,
            scratch: Mutex::new(None),
        }
    }

    fn scan_bind_group(
        &self,
        ctx: &GpuContext,
        scratch: &Scratch,
        flags: &wgpu::Buffer,
        ray_count: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("compaction scan"),
            layout: &self.scan_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &scratch.params,
                        offset: 0,
                        size: wgpu::BufferSize::new(16),
                    }),
                },
                wgpu::BindGroupEntry { binding: 1, resource: flags.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: scratch.levels.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: ray_count.as_entire_binding() },
            ],
        })
    }

    /// The passes of one scan. `first` computes level 0 and its per-tile counts
    /// (`flags_reduce`, or `reduce` over given flags); `last` scatters.
    #[allow(clippy::too_many_arguments)]
    fn encode_passes(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        scratch: &Scratch,
        scan_group: &wgpu::BindGroup,
        group1: &wgpu::BindGroup,
        first: &wgpu::ComputePipeline,
        last: &wgpu::ComputePipeline,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let plan = &scratch.plan;
        let slot = |i: usize| i as u32 * scratch.stride;
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("compaction"),
            timestamp_writes: timing.map(|(query_set, i)| wgpu::ComputePassTimestampWrites {
                query_set,
                beginning_of_pass_write_index: Some(i),
                end_of_pass_write_index: Some(i + 1),
            }),
        });
        let dispatch =
            |pass: &mut wgpu::ComputePass<'_>, pipeline: &wgpu::ComputePipeline, level: usize, tiles: u32| {
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, scan_group, &[slot(level)]);
                pass.set_bind_group(1, group1, &[]);
                let (x, y) = grid(tiles);
                pass.dispatch_workgroups(x, y, 1);
            };
        let top = plan.levels.len(); // slot of the top level
                                     // Up: level 0 -> 1, then 1 -> 2, ... up to the top.
        dispatch(&mut pass, first, 0, plan.levels[0].0);
        for i in 1..top {
            dispatch(&mut pass, &self.reduce, i, plan.levels[i].0);
        }
        dispatch(&mut pass, &self.scan_top, top, 1);
        // Down: top-1 .. 1, then level 0.
        for i in (1..top).rev() {
            dispatch(&mut pass, &self.downsweep, i, plan.levels[i].0);
        }
        dispatch(&mut pass, last, 0, plan.levels[0].0);
    }

    /// Flag, scan and scatter: `frame.rays` and `frame.ray_count` of this frame.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let n = frame.width * frame.height * frame.light_count;
        let mut cache = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        if cache.as_ref().is_none_or(|s| s.plan.n != n) {
            // Allocation failures surface as wgpu errors (ctx.checked), like any
            // frame buffer; `storage` only refuses sizes past the device limits,
            // which FrameBuffers::new already refused for the larger ray buffer.
            *cache = Scratch::new(ctx, n, true).ok();
        }
        let Some(scratch) = cache.as_ref() else { return };
        let scan_group = self.scan_bind_group(ctx, scratch, &scratch.flags, &frame.ray_count);
        let frame_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("compaction frame"),
            layout: &self.frame_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: frame.params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: frame.surfaces.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: scene.lights.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: frame.rays.as_entire_binding() },
            ],
        });
        self.encode_passes(encoder, scratch, &scan_group, &frame_group, &self.flags_reduce, &self.scatter_rays, timing);
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
        let scan_group = self.scan_bind_group(ctx, &scratch, flags, count);
        let test_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("compaction scan test"),
            layout: &self.test_layout,
            entries: &[wgpu::BindGroupEntry { binding: 4, resource: out_indices.as_entire_binding() }],
        });
        self.encode_passes(encoder, &scratch, &scan_group, &test_group, &self.reduce, &self.scatter_indices, None);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The level structure: each level holds one value per tile of the level
    /// below, the top fits one tile, levels do not overlap in the scratch.
    #[test]
    fn scan_plan_levels_cover_the_largest_frame() {
        let t = COMPACTION_TILE;
        for n in [0, 1, t - 1, t, t + 1, t * t, t * t + 1, 1280 * 720 * 4, t * t * t + 7] {
            let plan = ScanPlan::new(n);
            let mut below = n;
            let mut next_off = 0;
            for &(count, off) in &plan.levels {
                assert_eq!(count, below.div_ceil(t), "n = {n}");
                assert_eq!(off, next_off, "n = {n}");
                next_off += count.max(1);
                below = count;
            }
            assert!(plan.levels.last().unwrap().0 <= t, "n = {n}: top fits one tile");
            assert!(plan.levels.len() == 1 || plan.levels[plan.levels.len() - 2].0 > t, "n = {n}: no extra level");
            assert_eq!(plan.levels_len(), next_off);
            let params = plan.params();
            assert_eq!(params.len(), plan.levels.len() + 1);
            assert_eq!((params[0].n, params[0].src_is_flags, params[0].dst_off), (n, 1, 0));
        }
        // 1280 x 720 x 4 flags: 7200 tiles, then 15, then the top.
        assert_eq!(ScanPlan::new(1280 * 720 * 4).levels, vec![(7200, 0), (15, 7200)]);
        assert_eq!(grid(7200), (7200, 1));
        assert_eq!(grid(65_536), (65_535, 2));
        assert_eq!(grid(0), (0, 1));
    }
}
