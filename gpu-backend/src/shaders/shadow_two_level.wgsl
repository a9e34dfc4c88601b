// The shadow rays' walk of a two-level BVH (mirrors
// hyrt_core::bvh::two_level::TwoLevelBvh::occluded_filtered): the top level's nodes lead
// to instances; the world-space level is walked with the ray as it is, an object-space
// one with the ray moved into the instance's space. All levels share `bvh_nodes` and
// `bvh_leaf_triangles` (hyrt_core::bvh::two_level::PackedLevels: the top level's root is
// node 0, an instance's `bottom` its level's root). Appended to shadow_rays.wgsl, after
// instance.wgsl.

@group(0) @binding(12) var<storage, read> instances: array<InstanceRecord>;

fn instance_occludes(inst: InstanceRecord, ray: RayRecord, r: TraversalRay) -> bool {
    if (inst.flags & INSTANCE_IDENTITY) != 0u {
        return occluded_from(r, inst.bottom, 0u, INVALID_ID, 0u);
    }
    let ro = object_ray(inst, ray, params.zero);
    if !traversal_ray_valid(ro) {
        return false;
    }
    return occluded_from(traversal_ray_new(ro), inst.bottom, inst.flags & INSTANCE_ALPHA_TEST, inst.object,
        inst.first_triangle);
}

fn trace_occluded(ray: RayRecord) -> bool {
    if !traversal_ray_valid(ray) {
        return false;
    }
    let r = traversal_ray_new(ray);
    if enter(r, bvh_nodes[0], r.t_max).x == 0.0 {
        return false;
    }
    var stack: array<u32, BVH_STACK_SIZE>;
    var sp = 0u;
    var n = 0u;
    loop {
        let node = bvh_nodes[n];
        if node.count > 0u {
            // One instance per top-level leaf.
            if instance_occludes(instances[node.left_or_first], ray, r) {
                return true;
            }
        } else {
            let l = node.left_or_first;
            let hit_l = enter(r, bvh_nodes[l], r.t_max);
            let hit_r = enter(r, bvh_nodes[l + 1u], r.t_max);
            if hit_l.x != 0.0 && hit_r.x != 0.0 {
                let right_first = hit_r.y < hit_l.y;
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
