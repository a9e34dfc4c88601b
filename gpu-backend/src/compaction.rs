//! Stage `compaction` on the GPU: active (pixel, slot) pairs -> the shadow-ray
//! list, slot-major then pixel order, bit for bit the list of
//! `hyrt_cpu::compaction::compaction_slots_into`; per pair the kernels of
//! [`hyrt_core::kernels::shadow`], with the shading stages' light evaluation
//! (`shaders/shading_helpers.wgsl`), and in a frame with area lights or ambient occlusion
//! those of [`hyrt_core::kernels::soft_shadow`] (`needs_slot_ray`, `slot_ray` in
//! `shaders/compaction.wgsl`, over the samplers of `shaders/soft_shadow.wgsl`).
//!
//! # Slots
//!
//! A surface has one shadow-mask slot per point, spot or directional light: a pair is a
//! (pixel, light), as in the paper. With area lights and ambient occlusion it has
//! `samples` slots per area light, then one per occlusion ray
//! ([`hyrt_core::kernels::soft_shadow::slot_table`]); a ray's `light` field is its slot.
//! The slot table is not uploaded: the shader walks the frame's lights (each area light's
//! `samples`) to the slot's light, and the uniform [`crate::buffers::SlotParams`] says how
//! many slots the lights take. Frames of point, spot and directional lights without
//! occlusion run the stage compiled without the walk and the samplers (the pipeline
//! constant `STOCHASTIC` false: [`crate::texture::Specialization::stochastic`]); the
//! others, a second compilation built the first time a frame needs it.
//!
//! Reads `frame.surfaces` (or, at bounce depth `d`, the surfaces the rays of depth `d`
//! hit, as many as that list's count), `scene.lights` (with an emitter light, whose samples
//! pick emissive triangles, the emitter table after the records:
//! [`crate::buffers::SceneBuffers::lights`]) and `scene.ambient_light` (the frame's:
//! [`crate::buffers::SceneBuffers::set_lighting`]), `frame.params`, `frame.slot_params`
//! (with the emitter table's length). Writes
//! `frame.rays` and `frame.ray_count` (`[count, dispatch_x, dispatch_y, 1]`:
//! indirect-dispatch arguments for one thread per ray in workgroups of
//! [`SHADOW_RAYS_WORKGROUP_SIZE`](crate::shadow_rays::SHADOW_RAYS_WORKGROUP_SIZE),
//! `dispatch_x <= 65535`), or the bounce's shadow rays and their count. Scratch (flags
//! and scan levels) is owned by the stage and kept per list size. In a frame rendered in
//! bands ([`crate::band`]) it also writes where each slot's rays start in the list
//! (`light_starts`, `shaders/light_starts.wgsl`: one binary search per slot), so that
//! the bands' lists merge into the frame's slot-major order.
//!
//! # Scan
//!
//! The flags are indexed `k = slot * room + surface` (`room`: the pixels, or the
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
//! The sample streams are integer arithmetic and the samples' warps correctly rounded
//! operations in the core's order (`shaders/sampling.wgsl`, `shaders/area_light.wgsl`,
//! `shaders/occlusion.wgsl`), so an area light's or an occlusion ray's flag and record
//! are the CPU's on the same terms. On lavapipe the conformance corpus finds no
//! difference.

use std::sync::{Arc, Mutex, OnceLock};

use crate::buffers::{FrameBuffers, ListBuffers, SceneBuffers};
use crate::paging::{paged_source, Table, TablePages};
use crate::scan::{pipeline, scan_entries, scan_wgsl, ListScan, Scratch};
use crate::shader::{
    bind_buffers, main_pipeline, preamble, ray_wgsl, shader_module, shading_helpers, soft_shadow_wgsl, storage_entry,
    uniform_entry, StageModule,
};
use crate::texture::Specialization;

/// Threads per workgroup of `shaders/light_starts.wgsl` (one per light).
const LIGHT_STARTS_GROUP: u32 = 64;
use crate::{GpuContext, GpuError};

/// The compaction WGSL: the generated records and format constants, `ray.wgsl`, the
/// shading helpers (the light evaluation the shading stages use), the soft-shadow kernels
/// (area-light samples, occlusion directions), `compaction.wgsl`, then the scan.
pub fn compaction_wgsl() -> String {
    preamble()
        + &ray_wgsl()
        + &shading_helpers()
        + &soft_shadow_wgsl()
        + include_str!("shaders/compaction.wgsl")
        + &scan_wgsl()
}

/// The bindings of the stage's group 1 (`shaders/compaction.wgsl`), but for the test
/// entry point's.
fn list_entries() -> [wgpu::BindGroupLayoutEntry; 8] {
    [
        uniform_entry(0),        // params
        storage_entry(1, true),  // surfaces
        storage_entry(2, true),  // lights
        storage_entry(3, false), // rays
        uniform_entry(4),        // list
        storage_entry(5, true),  // live
        uniform_entry(6),        // ambient light (its occlusion rays)
        uniform_entry(7),        // slot params
    ]
}

/// The `compaction` stage: the shared scan over the stage's flags (compiled for frames of
/// one slot per light, and for frames with stochastic rays the first time one comes), and
/// the test entry point that scatters the indices of given flags.
pub struct CompactionStage {
    scan: ListScan,
    /// The scan compiled with `STOCHASTIC` (module docs), built the first time a frame
    /// traces stochastic rays.
    stochastic: OnceLock<ListScan>,
    /// The stage's module, which both scans compile.
    module: StageModule,
    /// The scans of scenes whose lights are in pages ([`TablePages::lights_only`]), plain
    /// and stochastic, each built the first time a frame needs it.
    paged: Mutex<Vec<(TablePages, bool, Arc<ListScan>)>>,
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
        let plain = Specialization::PLAIN.stochastic_constant();
        let scan = ListScan::new(ctx, "compaction", &module, &list_entries(), &[plain]);
        let test_entries = [storage_entry(8, false)];
        let test_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("compaction scan test"),
            entries: &test_entries,
        });
        let scan_entries = scan_entries();
        let with_test = [(&scan.scan_layout, scan_entries.as_slice()), (&test_layout, test_entries.as_slice())];
        let starts_module =
            shader_module(ctx, "compaction light starts", &(preamble() + include_str!("shaders/light_starts.wgsl")));
        let starts_entries =
            [storage_entry(0, true), storage_entry(1, true), storage_entry(2, false), storage_entry(3, true)];
        let starts_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("compaction light starts"),
            entries: &starts_entries,
        });
        CompactionStage {
            light_starts: (
                main_pipeline("compaction light starts", &starts_module, &starts_layout, &starts_entries, &[]),
                starts_layout,
            ),
            scatter_indices: pipeline(&module, "scatter_indices", &with_test, &[plain]),
            reduce_for_test: pipeline(&module, "reduce", &with_test, &[plain]),
            scan,
            stochastic: OnceLock::new(),
            module,
            paged: Mutex::new(Vec::new()),
            test_layout,
        }
    }

    /// The scan of frames with stochastic rays, compiled now if no frame needed it before.
    fn stochastic_scan(&self, ctx: &GpuContext) -> &ListScan {
        self.stochastic.get_or_init(|| {
            let constant = Specialization { stochastic: true, ..Specialization::PLAIN }.stochastic_constant();
            ListScan::new(ctx, "compaction (stochastic)", &self.module, &list_entries(), &[constant])
        })
    }

    /// The scan of frames whose lights are in the pages `pages` gives them
    /// ([`crate::paging`]), stochastic or not: compiled now if no frame needed it before.
    fn paged_scan(&self, ctx: &GpuContext, pages: TablePages, stochastic: bool) -> Arc<ListScan> {
        let mut cache = self.paged.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, _, scan)) = cache.iter().find(|(p, s, _)| (*p, *s) == (pages, stochastic)) {
            return scan.clone();
        }
        let module = shader_module(ctx, "compaction (lights in pages)", &paged_source(&compaction_wgsl(), pages));
        let constant = Specialization { stochastic, ..Specialization::PLAIN }.stochastic_constant();
        let entries = [list_entries().as_slice(), &pages.layout_entries(&[Table::Lights])].concat();
        let scan = Arc::new(ListScan::new(ctx, "compaction (lights in pages)", &module, &entries, &[constant]));
        cache.push((pages, stochastic, scan.clone()));
        scan
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
    /// banded frame where each slot's rays start, [`crate::band`]). The frame's slots are
    /// `frame.slots` ([`FrameBuffers::set_slots`]).
    pub fn encode_list(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        list: &ListBuffers,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let n = list.slots * frame.slots;
        let buffers = [
            &frame.params,
            list.surfaces,
            scene.lights.first(),
            list.shadow_rays,
            list.params,
            list.live,
            &scene.ambient_light,
            &frame.slot_params,
        ];
        let pages = scene.specialization.pages.lights_only();
        let paged;
        let scan = match (pages.any(), frame.stochastic) {
            (true, stochastic) => {
                paged = self.paged_scan(ctx, pages, stochastic);
                &*paged
            }
            (false, true) => self.stochastic_scan(ctx),
            (false, false) => &self.scan,
        };
        let further = scene.further_pages(&[Table::Lights]);
        scan.encode_paged(ctx, encoder, "compaction", n, &buffers, further, list.shadow_ray_count, timing);
        if frame.banded && frame.slots > 0 {
            let (pipeline, layout) = &self.light_starts;
            let group = bind_buffers(
                ctx,
                "compaction light starts",
                layout,
                &[list.shadow_rays, list.shadow_ray_count, list.light_starts, list.bounds],
            );
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("compaction light starts"),
                timestamp_writes: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups((3 * frame.slots).div_ceil(LIGHT_STARTS_GROUP), 1, 1);
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
            entries: &[wgpu::BindGroupEntry { binding: 8, resource: out_indices.as_entire_binding() }],
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
