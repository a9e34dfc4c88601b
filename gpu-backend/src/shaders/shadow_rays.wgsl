// Stage `shadow_rays` (mirrors hyrt_core::bvh::Bvh::occluded_filtered with the alpha
// test of hyrt_core::kernels::texture::alpha_accepts, the CPU's reference traversal):
// one thread per ray of the compacted list, any hit with early exit; a hit on an
// alpha-tested triangle (TRI_ALPHA_TEST) where its alpha fails the cutoff is no hit.
// Indirect dispatch from `ray_count`; threads past the count exit. Writes `occluded[ray]`
// (1/0) and `shadow[pixel * slot_params.slots + light]` (SHADOW_LIT or SHADOW_OCCLUDED;
// the caller cleared it to SHADOW_NO_RAY): a ray's `light` is its mask slot, one per
// light without area lights and ambient occlusion (hyrt_core::kernels::soft_shadow); at
// a bounce depth `pixel` is the secondary ray the shadow ray leaves from, and occluded
// rays are counted.
//
// Prepended at pipeline creation: the generated records and format constants
// (hyrt_core::formats::wgsl), the `SlotParams` declaration, the ray constants and ray.wgsl, `rounded` and `mul` over
// `params.zero`, the texture kernels (`hyrt_gpu::texture::texture_wgsl`). Appended:
// `trace_occluded`, the walk of the scene's BVH: `occluded_any` for a single-level tree,
// or for a two-level one `shadow_two_level.wgsl` (with the instances' binding).

@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<storage, read> rays: array<RayRecord>;
@group(0) @binding(2) var<storage, read> ray_count: array<u32, 4>;
@group(0) @binding(3) var<storage, read> bvh_nodes: array<BvhNode>;
@group(0) @binding(4) var<storage, read> bvh_leaf_triangles: array<TriangleRecord>;
@group(0) @binding(5) var<storage, read_write> occluded: array<u32>;
@group(0) @binding(6) var<storage, read_write> shadow: array<u32>;
@group(0) @binding(7) var<uniform> list: ListParams;
// The list's statistics, [reflection, refraction, hits, occluded]; bounce depths only.
@group(0) @binding(8) var<storage, read_write> counters: array<atomic<u32>, 4>;
// The surface tables (alpha tests). The leaf triangle's global index comes from its
// object's first triangle packed with them (`global_triangle`): a binding of the BVH's
// `prim_indices` would be the 9th storage buffer, past WebGPU's default limit.
@group(0) @binding(9) var<storage, read> surface: array<u32>;
@group(0) @binding(10) var<uniform> surface_layout: SurfaceLayout;
// The frame's mask slots per surface (the codes' stride).
@group(0) @binding(11) var<uniform> slot_params: SlotParams;

// mirrors hyrt_core::bvh::Bvh::occluded_filtered with alpha_accepts. An empty BVH is
// uploaded as one zero node: an inner node whose left child would be itself, which no
// real tree has (children always follow their parent), so it is recognized from the data.
fn occluded_any(ray: RayRecord) -> bool {
    let root = bvh_nodes[0];
    if !traversal_ray_valid(ray) || (root.count == 0u && root.left_or_first == 0u) {
        return false;
    }
    return occluded_from(traversal_ray_new(ray), 0u, 0u, INVALID_ID, 0u);
}

// mirrors hyrt_core::bvh::Bvh::occluded_ray: the any-hit walk of the tree whose root is
// node `root`, a hit on an alpha-tested triangle (its flags or `alpha_flags`) counting
// where its alpha passes. `object` INVALID_ID: the triangles' records name their object
// (a single-level tree, the world-space level); else the hit is on that object, whose
// first triangle is `first_triangle` (an instance of a shared bottom level).
fn occluded_from(r: TraversalRay, root: u32, alpha_flags: u32, object: u32, first_triangle: u32) -> bool {
    if enter(r, bvh_nodes[root], r.t_max).x == 0.0 {
        return false;
    }
    var stack: array<u32, BVH_STACK_SIZE>;
    var sp = 0u;
    var n = root;
    loop {
        let node = bvh_nodes[n];
        if node.count > 0u {
            for (var slot = node.left_or_first; slot < node.left_or_first + node.count; slot = slot + 1u) {
                let t = bvh_leaf_triangles[slot];
                let h = watertight_intersect(r.wt, r.t_min, r.t_max, t.v0, t.v1, t.v2, params.zero);
                // ALPHA_TESTED (a pipeline constant): no alpha test compiled in scenes without one.
                let opaque_hit = !ALPHA_TESTED || ((t.flags | alpha_flags) & TRI_ALPHA_TEST) == 0u;
                if h.hit && (opaque_hit || alpha_accepts_on(t, object, first_triangle, h.u, h.v)) {
                    return true;
                }
            }
        } else {
            let l = node.left_or_first;
            let hit_l = enter(r, bvh_nodes[l], r.t_max);
            let hit_r = enter(r, bvh_nodes[l + 1u], r.t_max);
            if hit_l.x != 0.0 && hit_r.x != 0.0 {
                // Nearer child first; ties go left.
                let right_first = hit_r.y < hit_l.y;
                // A tree deeper than the stack fails Bvh::validate; never overflow anyway.
                if sp < BVH_STACK_SIZE {
                    stack[sp] = select(l + 1u, l, right_first);
                    sp = sp + 1u;
                }
                n = select(l, l + 1u, right_first);
                continue;
            }
            if hit_l.x != 0.0 {
                n = l;
                continue;
            }
            if hit_r.x != 0.0 {
                n = l + 1u;
                continue;
            }
        }
        if sp == 0u {
            return false;
        }
        sp = sp - 1u;
        n = stack[sp];
    }
    return false;
}

// The alpha test of a hit on leaf triangle `t` (hyrt_core::kernels::texture::alpha_accepts
// as the CPU's leaf tests call it): on its own object, or on the instance's `object`.
fn alpha_accepts_on(t: TriangleRecord, object: u32, first_triangle: u32, u: f32, v: f32) -> bool {
    if object == INVALID_ID {
        return alpha_accepts(t, global_triangle(t), u, v);
    }
    var w = t;
    w.object = object;
    return alpha_accepts(w, first_triangle + t.triangle, u, v);
}

// mirrors hyrt_core::kernels::shadow::shadow_code
fn shadow_code(occluded: bool) -> u32 {
    return select(SHADOW_LIT, SHADOW_OCCLUDED, occluded);
}

@compute @workgroup_size(SHADOW_WG)
fn shadow_rays(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>,
               @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = (wid.y * nwg.x + wid.x) * SHADOW_WG + lid;
    // The list may have more rays than the buffer has room for (the backend then
    // runs the frame again with more room): trace only those written.
    if i >= min(ray_count[0], arrayLength(&rays)) {
        return;
    }
    let ray = rays[i];
    let o = trace_occluded(ray);
    occluded[i] = select(0u, 1u, o);
    if o && list.depth > 0u {
        atomicAdd(&counters[3], 1u);
    }
    shadow[ray.pixel * slot_params.slots + ray.light] = shadow_code(o);
}
