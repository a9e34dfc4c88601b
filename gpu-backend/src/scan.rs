//! The deterministic list compaction the list stages share (`compaction`,
//! `secondary_rays`): a portable reduce-then-scan over u32 flags (no atomics, no
//! decoupled look-back: WebGPU has no forward-progress guarantee), in
//! `shaders/scan.wgsl`. A stage's module defines which elements are kept
//! (`element_flag`) and what a kept element writes (`emit`); this module owns the
//! level structure, the scratch buffers and the passes.
//!
//! A tile is [`SCAN_TILE`] = [`SCAN_WORKGROUP_SIZE`] x [`SCAN_ITEMS_PER_THREAD`] elements;
//! each thread owns consecutive elements and the workgroup scans the per-thread sums
//! (Hillis-Steele, log2 of the workgroup size barriers: barriers are the expensive part
//! on lavapipe, so threads do serial work first).
//!
//! Level 0 is the flags; level `i + 1` holds one value per tile of level `i`, until a
//! level fits one tile (the top). One compute pass, in order: `flags_reduce` (flags and
//! per-tile counts), `reduce` per level up to the top, `scan_top` (one workgroup; writes
//! the list's count and the indirect-dispatch arguments of its consumers), `downsweep`
//! per level back down (each tile scanned in place, offset by the level above),
//! `scatter` (each element once, kept ones with their list index). Integer sums are
//! exact, so the list is stable and identical on every run and backend. Dispatches use
//! 2D grids past 65535 tiles.

use std::collections::HashMap;
use std::sync::Mutex;

use crate::gpu_buffer::storage;
use crate::shader::{dynamic_uniform_entry, storage_entry, StageModule, MAX_WORKGROUPS_PER_DIMENSION};
use crate::{GpuContext, GpuError};

/// Threads per scan workgroup. Tunable: larger means fewer tiles but more barrier
/// steps in the workgroup scan (log2 of it), which dominate on lavapipe.
pub const SCAN_WORKGROUP_SIZE: u32 = 64;
/// Consecutive flags each thread sums serially before the workgroup scan.
pub const SCAN_ITEMS_PER_THREAD: u32 = 8;
/// Elements per tile (one workgroup) at every scan level.
pub const SCAN_TILE: u32 = SCAN_WORKGROUP_SIZE * SCAN_ITEMS_PER_THREAD;

/// Scans kept per stage between frames (one per list size: the primary list and one
/// per bounce depth); past it the cache starts afresh.
const MAX_CACHED_SCANS: usize = 64;

/// Per-level uniform (`Level` in scan.wgsl), 16 bytes, one per dynamic offset slot.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct LevelParams {
    pub n: u32,
    pub src_off: u32,
    pub dst_off: u32,
    pub src_is_flags: u32,
}

/// The level structure of a scan over `n` flags: sizes and offsets of levels 1.. in
/// the `levels` scratch buffer.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ScanPlan {
    pub n: u32,
    /// (element count, offset in `levels`) of levels 1..=top.
    pub levels: Vec<(u32, u32)>,
}

impl ScanPlan {
    pub fn new(n: u32) -> ScanPlan {
        let mut levels = Vec::new();
        let mut count = n.div_ceil(SCAN_TILE);
        let mut off = 0u32;
        loop {
            levels.push((count, off));
            off += count.max(1);
            if count <= SCAN_TILE {
                break;
            }
            count = count.div_ceil(SCAN_TILE);
        }
        ScanPlan { n, levels }
    }

    pub fn levels_len(&self) -> u32 {
        self.levels.iter().map(|&(c, _)| c.max(1)).sum()
    }

    /// Uniform slot `i`: level `i` (0 = flags) with the level above as `dst`.
    pub fn params(&self) -> Vec<LevelParams> {
        let mut out = vec![LevelParams { n: self.n, src_off: 0, dst_off: self.levels[0].1, src_is_flags: 1 }];
        for (i, &(count, off)) in self.levels.iter().enumerate() {
            let dst_off = self.levels.get(i + 1).map_or(0, |l| l.1);
            out.push(LevelParams { n: count, src_off: off, dst_off, src_is_flags: 0 });
        }
        out
    }
}

/// Workgroup grid of `tiles` tiles: x-major, `x <= 65535`.
pub(crate) fn grid(tiles: u32) -> (u32, u32) {
    if tiles == 0 {
        return (0, 1);
    }
    let x = tiles.min(MAX_WORKGROUPS_PER_DIMENSION);
    (x, tiles.div_ceil(x))
}

/// Scratch of one scan size.
pub(crate) struct Scratch {
    pub plan: ScanPlan,
    pub flags: wgpu::Buffer,
    pub levels: wgpu::Buffer,
    /// One [`LevelParams`] per uniform slot, `stride` bytes apart.
    pub params: wgpu::Buffer,
    pub stride: u32,
}

impl Scratch {
    pub fn new(ctx: &GpuContext, n: u32, with_flags: bool) -> Result<Scratch, GpuError> {
        let plan = ScanPlan::new(n);
        let stride = ctx.limits.min_uniform_buffer_offset_alignment.max(16);
        let params = plan.params();
        let mut bytes = vec![0u8; params.len() * stride as usize];
        for (i, p) in params.iter().enumerate() {
            let o = i * stride as usize;
            bytes[o..o + 16].copy_from_slice(bytemuck::bytes_of(p));
        }
        let params_buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("scan levels params"),
            size: bytes.len() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        ctx.queue.write_buffer(&params_buf, 0, &bytes);
        Ok(Scratch {
            flags: storage::<u32>(ctx, "scan flags", if with_flags { n.max(1) as usize } else { 1 })?,
            levels: storage::<u32>(ctx, "scan levels", plan.levels_len() as usize)?,
            params: params_buf,
            plan,
            stride,
        })
    }
}

/// The scan constants and `shaders/scan.wgsl`: what a list stage's module ends with
/// (after its `element_flag` and `emit`, and `ray.wgsl` for `SHADOW_WG` and
/// `MAX_DISPATCH`).
pub(crate) fn scan_wgsl() -> String {
    format!(
        "const WG = {SCAN_WORKGROUP_SIZE}u;\nconst ITEMS = {SCAN_ITEMS_PER_THREAD}u;\nconst TILE = {SCAN_TILE}u;\n{}",
        include_str!("shaders/scan.wgsl")
    )
}

/// The scan pipelines of one stage's module: group 0 is the scan's (level uniform with a
/// dynamic offset, flags, levels, the list's count), group 1 the stage's own.
pub(crate) struct ListScan {
    pub flags_reduce: wgpu::ComputePipeline,
    pub reduce: wgpu::ComputePipeline,
    pub scan_top: wgpu::ComputePipeline,
    pub downsweep: wgpu::ComputePipeline,
    pub scatter: wgpu::ComputePipeline,
    pub scan_layout: wgpu::BindGroupLayout,
    pub list_layout: wgpu::BindGroupLayout,
    scratch: Mutex<HashMap<u32, Scratch>>,
}

/// The entries of the scan's group-0 layout.
pub(crate) fn scan_entries() -> [wgpu::BindGroupLayoutEntry; 4] {
    [dynamic_uniform_entry(0), storage_entry(1, false), storage_entry(2, false), storage_entry(3, false)]
}

/// The scan's group-0 layout.
pub(crate) fn scan_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("scan"), entries: &scan_entries() })
}

/// A compute pipeline of `module`'s `entry` over `groups`, with values for the module's
/// pipeline-overridable `constants`.
pub(crate) fn pipeline(
    module: &StageModule,
    entry: &str,
    groups: &[(&wgpu::BindGroupLayout, &[wgpu::BindGroupLayoutEntry])],
    constants: &[(&str, f64)],
) -> wgpu::ComputePipeline {
    module.compute_pipeline(entry, entry, &module.pipeline_layout(entry, groups), constants)
}

impl ListScan {
    /// The scan of `module` (which ends with [`scan_wgsl`]), whose group 1 has `entries`,
    /// with values for the module's pipeline-overridable `constants`.
    pub fn new(
        ctx: &GpuContext,
        label: &str,
        module: &StageModule,
        entries: &[wgpu::BindGroupLayoutEntry],
        constants: &[(&str, f64)],
    ) -> Self {
        let device = &ctx.device;
        let scan_layout = scan_layout(device);
        let list_layout =
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries });
        let scan_entries = scan_entries();
        let scan = (&scan_layout, scan_entries.as_slice());
        let with_list = [scan, (&list_layout, entries)];
        ListScan {
            flags_reduce: pipeline(module, "flags_reduce", &with_list, constants),
            reduce: pipeline(module, "reduce", &[scan], constants),
            scan_top: pipeline(module, "scan_top", &[scan], constants),
            downsweep: pipeline(module, "downsweep", &[scan], constants),
            scatter: pipeline(module, "scatter", &with_list, constants),
            scan_layout,
            list_layout,
            scratch: Mutex::new(HashMap::new()),
        }
    }

    /// The scan's group 0 over `scratch`, with `flags` as level 0 and `count` (16
    /// bytes: `[count, dispatch_x, dispatch_y, 1]`) as the list's count.
    pub fn scan_bind_group(
        &self,
        ctx: &GpuContext,
        scratch: &Scratch,
        flags: &wgpu::Buffer,
        count: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("scan"),
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
                wgpu::BindGroupEntry { binding: 3, resource: count.as_entire_binding() },
            ],
        })
    }

    /// Flag, scan and scatter `n` elements with the stage's group 1 `list` (buffers at
    /// bindings 0, 1, ...) and `further` entries after them (the further pages of a paged
    /// table among them, [`crate::paging`]), the list's count into `count`. Scratch is kept
    /// per `n`.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_paged(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        label: &str,
        n: u32,
        list: &[&wgpu::Buffer],
        further: Vec<wgpu::BindGroupEntry<'_>>,
        count: &wgpu::Buffer,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let mut cache = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        if !cache.contains_key(&n) {
            if cache.len() >= MAX_CACHED_SCANS {
                cache.clear();
            }
            // Allocation failures surface as wgpu errors (ctx.checked), like any frame
            // buffer; `storage` only refuses sizes past the device limits, which the
            // frame buffers (larger) were refused for already.
            match Scratch::new(ctx, n, true) {
                Ok(s) => cache.insert(n, s),
                Err(_) => return,
            };
        }
        let scratch = &cache[&n];
        let scan_group = self.scan_bind_group(ctx, scratch, &scratch.flags, count);
        let list_group = crate::shader::bind_paged_buffers(ctx, label, &self.list_layout, list, further);
        self.encode_passes(
            encoder,
            label,
            scratch,
            &scan_group,
            &list_group,
            &self.flags_reduce,
            &self.scatter,
            timing,
        );
    }

    /// The passes of one scan. `first` computes level 0 and its per-tile counts
    /// (`flags_reduce`, or `reduce` over given flags); `last` scatters.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_passes(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        label: &str,
        scratch: &Scratch,
        scan_group: &wgpu::BindGroup,
        group1: &wgpu::BindGroup,
        first: &wgpu::ComputePipeline,
        last: &wgpu::ComputePipeline,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let plan = &scratch.plan;
        let slot = |i: usize| i as u32 * scratch.stride;
        let mut pass = crate::timing::begin_timed_pass(encoder, label, timing);
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
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The level structure: each level holds one value per tile of the level below, the
    /// top fits one tile, levels do not overlap in the scratch.
    #[test]
    fn scan_plan_levels_cover_the_largest_frame() {
        let t = SCAN_TILE;
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
