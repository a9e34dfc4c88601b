// Normal mapping of the surfaces a frame makes: WGSL of the passes that
// `hyrt_gpu::reconstruction::NormalMapping` records after `reconstruction` (the primary
// hits, `hyrt_core::kernels::reconstruction::primary_normal_mapped`) and after
// `bounce_trace` (each bounce's hits, `secondary_normal_mapped`), in scenes with normal
// maps only. This file holds what both passes bind.
//
// Prepended with the generated records, the shading helpers, shading.wgsl (`cross3`,
// `log2_portable`), the texture kernels and materials.wgsl (`normal_mapped`), and a
// generated `NORMAL_MAPPING_WG` (the ray lists' workgroup size, whose indirect dispatch
// arguments the lists' counts hold).

@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<storage, read> objects: array<ObjectRecord>;
@group(0) @binding(2) var<storage, read> surface: array<u32>;
@group(0) @binding(3) var<uniform> surface_layout: SurfaceLayout;
@group(0) @binding(4) var<storage, read_write> surfaces: array<SurfaceRecord>;
// Then the pass's own bindings and entry point (`hyrt_gpu::reconstruction::NormalMapping`):
// the primary pass binds `gbuffer` and `camera`, the secondary pass a bounce's `rays`,
// `ray_count` and `hits`.
