// Stage `bounce_trace` (hyrt_core::bvh::Bvh::closest_hit_filtered with the alpha test of
// hyrt_core::kernels::texture::alpha_accepts, and
// hyrt_core::kernels::reconstruction::reconstruct_hit per ray, as hyrt_cpu::bounce_trace):
// the closest hit of each ray of bounce `list.depth` through the BVH of the whole scene
// (ties to the lower triangle index; a hit on an alpha-tested triangle where its alpha
// fails the cutoff neither counts nor narrows), and the surface it hit, rebuilt from the
// hit's barycentrics on the side the ray saw. One thread per ray, indirect dispatch from
// `ray_count`; threads past the count (or the room) exit.
//
// Prepended: the generated records and constants, ray.wgsl, `rounded` and `mul` over
// `params.zero`, surface.wgsl, the texture kernels (`hyrt_gpu::texture::texture_wgsl`).
// Appended: `trace_closest`, the walk of the scene's BVH: `closest_hit` for a single-level
// tree, or for a two-level one `bounce_two_level.wgsl` (with the instances' binding).

@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<storage, read> rays: array<RayRecord>;
@group(0) @binding(2) var<storage, read> ray_count: array<u32, 4>;
@group(0) @binding(3) var<storage, read> bvh_nodes: array<BvhNode>;
@group(0) @binding(4) var<storage, read> bvh_leaf_triangles: array<TriangleRecord>;
@group(0) @binding(5) var<storage, read> bvh_prim_indices: array<u32>;
@group(0) @binding(6) var<storage, read> triangles: array<TriangleRecord>;
@group(0) @binding(7) var<storage, read> normals: array<f32>;
@group(0) @binding(8) var<storage, read_write> hits: array<HitRecord>;
@group(0) @binding(9) var<storage, read_write> surfaces: array<SurfaceRecord>;
@group(0) @binding(10) var<storage, read_write> counters: array<atomic<u32>, 4>;
@group(0) @binding(11) var<storage, read> surface: array<u32>;
@group(0) @binding(12) var<uniform> surface_layout: SurfaceLayout;
// The object records: `surface_at` adds the hit object's offset error to the point's bound.
@group(0) @binding(13) var<storage, read> objects: array<ObjectRecord>;

// mirrors hyrt_core::bvh::ClosestHit (`triangle` INVALID_ID: no hit)
struct ClosestHit {
    triangle: u32,
    t: f32,
    u: f32,
    v: f32,
    back_face: bool,
}

// mirrors hyrt_core::bvh::Bvh::closest_hit_filtered with alpha_accepts, walked as
// hyrt_core::bvh::traversal::traverse walks it with the scalar ray's node test: nearer
// child first (ties left), the other pushed with its entry distance; a node popped after
// the bound narrowed is visited only if its entry lies within the widened bound. An empty
// BVH (one zero node) is recognized as in shadow_rays.wgsl.
fn closest_hit(ray: RayRecord) -> ClosestHit {
    let best = ClosestHit(INVALID_ID, ray.t_max, 0.0, 0.0, false);
    let root = bvh_nodes[0];
    if !traversal_ray_valid(ray) || (root.count == 0u && root.left_or_first == 0u) {
        return best;
    }
    return closest_from(traversal_ray_new(ray), 0u, best, 0u, INVALID_ID, 0u);
}

// mirrors hyrt_core::bvh::Bvh::closest_ray: the closest-hit walk of the tree whose root
// is node `root` from the hit `start` found so far (its `t` the bound), slot `s` reported
// as triangle `first_triangle + bvh_prim_indices[s]`; alpha-tested triangles (their flags
// or `alpha_flags`) tested on their own object, or on `object` when it is not INVALID_ID
// (an instance of a shared bottom level). `back_face` is the facing in this tree's space.
fn closest_from(r: TraversalRay, root: u32, start: ClosestHit, alpha_flags: u32, object: u32,
                first_triangle: u32) -> ClosestHit {
    var best = start;
    var t_best = best.t;
    let root_entry = enter(r, bvh_nodes[root], t_best);
    if root_entry.x == 0.0 {
        return best;
    }
    var stack_node: array<u32, BVH_STACK_SIZE>;
    var stack_entry: array<f32, BVH_STACK_SIZE>;
    var sp = 0u;
    // Entries below this stack index were pushed before the last narrowing of the bound.
    var stale = 0u;
    var n = root;
    loop {
        let node = bvh_nodes[n];
        var descend = false;
        if node.count > 0u {
            var narrowed = false;
            for (var slot = node.left_or_first; slot < node.left_or_first + node.count; slot = slot + 1u) {
                let tri = bvh_leaf_triangles[slot];
                let h = watertight_intersect(r.wt, r.t_min, r.t_max, tri.v0, tri.v1, tri.v2, params.zero);
                if h.hit {
                    let id = first_triangle + bvh_prim_indices[slot];
                    let closer = h.t < t_best || (h.t == t_best && id < best.triangle);
                    // ALPHA_TESTED (a pipeline constant): no alpha test compiled in scenes without one.
                    let opaque_hit = !ALPHA_TESTED || ((tri.flags | alpha_flags) & TRI_ALPHA_TEST) == 0u;
                    if closer && (opaque_hit || alpha_accepts_at(tri, object, id, h.u, h.v)) {
                        best = ClosestHit(id, h.t, h.u, h.v, h.back_face);
                        t_best = h.t;
                        narrowed = true;
                    }
                }
            }
            if narrowed {
                stale = sp;
            }
        } else {
            let l = node.left_or_first;
            let el = enter(r, bvh_nodes[l], t_best);
            let er = enter(r, bvh_nodes[l + 1u], t_best);
            if el.x != 0.0 && er.x != 0.0 {
                let right_first = er.y < el.y;
                // A tree deeper than the stack fails Bvh::validate; never overflow anyway.
                if sp < BVH_STACK_SIZE {
                    stack_node[sp] = select(l + 1u, l, right_first);
                    stack_entry[sp] = select(er.y, el.y, right_first);
                    sp = sp + 1u;
                }
                n = select(l, l + 1u, right_first);
                descend = true;
            } else if el.x != 0.0 {
                n = l;
                descend = true;
            } else if er.x != 0.0 {
                n = l + 1u;
                descend = true;
            }
        }
        if descend {
            continue;
        }
        // Pop the next node still worth visiting.
        var found = false;
        loop {
            if sp == 0u {
                break;
            }
            sp = sp - 1u;
            let next = stack_node[sp];
            let pushed = stack_entry[sp];
            let is_stale = sp < stale;
            if is_stale {
                stale = sp;
            }
            if !is_stale || pushed <= t_best * (1.0 + BVH_CULL_SLACK) {
                n = next;
                found = true;
                break;
            }
        }
        if !found {
            break;
        }
    }
    return best;
}


// The alpha test of a hit on leaf triangle `t`, global triangle `id`: on its own object,
// or on `object` (an instance's) when that is not INVALID_ID.
fn alpha_accepts_at(t: TriangleRecord, object: u32, id: u32, u: f32, v: f32) -> bool {
    if object == INVALID_ID {
        return alpha_accepts(t, id, u, v);
    }
    var w = t;
    w.object = object;
    return alpha_accepts(w, id, u, v);
}

// mirrors hyrt_core::formats::HitRecord::from_hit
fn hit_record(h: ClosestHit) -> HitRecord {
    if h.triangle == INVALID_ID {
        return HitRecord(0.0, 0.0, 0.0, INVALID_ID, 0u, 0u);
    }
    return HitRecord(h.t, h.u, h.v, h.triangle, HIT_FOUND | select(0u, HIT_BACK_FACE, h.back_face), 0u);
}

// mirrors hyrt_core::kernels::reconstruction::reconstruct_hit
fn reconstruct_hit(hit: HitRecord, direction: vec3<f32>) -> SurfaceRecord {
    if (hit.flags & HIT_FOUND) == 0u {
        return SurfaceRecord(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), INVALID_ID, vec3<f32>(0.0), INVALID_ID);
    }
    let gi = hit.triangle;
    let tri = world_triangle(gi);
    let p = reconstruct_position(hit.u, hit.v, tri.v0, tri.v1, tri.v2);
    return surface_at(gi, hit.u, hit.v, (hit.flags & HIT_BACK_FACE) != 0u, p, -direction);
}

@compute @workgroup_size(SHADOW_WG)
fn main(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>,
        @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = (wid.y * nwg.x + wid.x) * SHADOW_WG + lid;
    if i >= min(ray_count[0], arrayLength(&rays)) {
        return;
    }
    let ray = rays[i];
    let hit = hit_record(trace_closest(ray));
    hits[i] = hit;
    surfaces[i] = reconstruct_hit(hit, ray.direction);
    if (hit.flags & HIT_FOUND) != 0u {
        atomicAdd(&counters[2], 1u);
    }
}
