// Stage `secondary_rays` (hyrt_core::kernels::bounce::spawn per parent and lobe, as
// hyrt_cpu::secondary_rays): the surfaces of depth d - 1 that bounce spawn the
// reflection and refraction rays of depth d = list.depth, compacted (scan.wgsl) into one
// list in their parents' order, reflection before refraction: element k is lobe k % 2 of
// parent k / 2. Parents are the pixels (d = 1: the G-buffer and the primary surfaces)
// or the rays of depth d - 1 (their hits and surfaces), as many as `live[0]`.
// Every element writes its parent's link: the child's index in the list, or INVALID_ID.
//
// Prepended: the generated records and constants, ray.wgsl, the shading helpers,
// shading.wgsl, the texture kernels, materials.wgsl, bounce.wgsl. Followed by scan.wgsl.

@group(1) @binding(0) var<uniform> params: FrameParams;
@group(1) @binding(1) var<uniform> list: ListParams;
@group(1) @binding(2) var<uniform> camera: CameraRecord;
@group(1) @binding(3) var<storage, read> objects: array<ObjectRecord>;
// Binding 4: the triangle flags (hyrt_gpu::world_triangles::triangle_flags_wgsl).
@group(1) @binding(5) var<storage, read> gbuffer: array<GBufferTexel>;
@group(1) @binding(6) var<storage, read> parent_surfaces: array<SurfaceRecord>;
@group(1) @binding(7) var<storage, read> parent_rays: array<RayRecord>;
@group(1) @binding(8) var<storage, read> parent_hits: array<HitRecord>;
@group(1) @binding(9) var<storage, read> live: array<u32, 4>;
@group(1) @binding(10) var<storage, read_write> rays: array<RayRecord>;
@group(1) @binding(11) var<storage, read_write> links: array<u32>;
@group(1) @binding(12) var<storage, read_write> counters: array<atomic<u32>, 4>;
@group(1) @binding(13) var<storage, read> surface: array<u32>;
@group(1) @binding(14) var<uniform> surface_layout: SurfaceLayout;

// Parent `i` (mirrors hyrt_cpu::secondary_rays::Parents::get).
fn parent(i: u32) -> Parent {
    if list.depth == 1u {
        return primary_parent(gbuffer[i], parent_surfaces[i], camera.eye, i);
    }
    return secondary_parent(parent_rays[i], parent_hits[i], parent_surfaces[i]);
}

// Whether parent `i` can spawn anything (mirrors hyrt_cpu::secondary_rays::Parents::may_bounce):
// a live parent that hit an object that bounces. At depth 1 only the band's own pixels
// `[live[1], live[2])` spawn (all of them but in a band rendered with a halo of rows,
// whose halo serves the denoiser alone: gpu-backend/src/band.rs).
fn may_bounce(i: u32) -> bool {
    if i >= live[0] || (list.depth == 1u && (i < live[1] || i >= live[2])) {
        return false;
    }
    let s = parent_surfaces[i];
    return s.object != INVALID_ID && bounces(objects[s.object]);
}

fn element_flag(k: u32) -> u32 {
    let i = k / 2u;
    if !may_bounce(i) {
        return 0u;
    }
    return select(0u, 1u, spawn(parent(i), list.depth, k % 2u).ok);
}

fn emit(k: u32, kept: bool, dst: u32) {
    links[k] = select(INVALID_ID, dst, kept);
    if !kept {
        return;
    }
    atomicAdd(&counters[k % 2u], 1u);
    // Rays past the buffer's room are not written: the backend sees the count, makes
    // room and runs the frame again.
    if dst < arrayLength(&rays) {
        rays[dst] = spawn(parent(k / 2u), list.depth, k % 2u).ray;
    }
}
