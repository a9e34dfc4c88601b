// The bounce rays' walk of a two-level BVH (mirrors
// hyrt_core::bvh::two_level::TwoLevelBvh::closest_hit_filtered): the top level walked as
// `traverse` walks it with the scalar ray's node test, the bound (the closest `t` so far)
// carried into every instance's level and back; the facing of a hit in a mirrored
// instance flipped to the world's. Levels packed as in shadow_two_level.wgsl. Appended
// to bounce_trace.wgsl, after instance.wgsl.

@group(0) @binding(14) var<storage, read> instances: array<InstanceRecord>;

// `best` after the instance's level, from `best`.
fn instance_closest(inst: InstanceRecord, ray: RayRecord, r: TraversalRay, best: ClosestHit) -> ClosestHit {
    if (inst.flags & INSTANCE_IDENTITY) != 0u {
        return closest_from(r, inst.bottom, best, 0u, INVALID_ID, 0u);
    }
    let ro = object_ray(inst, ray, params.zero);
    if !traversal_ray_valid(ro) {
        return best;
    }
    var b = closest_from(traversal_ray_new(ro), inst.bottom, best, inst.flags & INSTANCE_ALPHA_TEST, inst.object,
        inst.first_triangle);
    // A changed hit is closer, or as close on a lower triangle: it differs in one of them.
    let changed = b.t != best.t || b.triangle != best.triangle;
    if changed && (inst.flags & INSTANCE_MIRRORED) != 0u {
        b.back_face = !b.back_face;
    }
    return b;
}

fn trace_closest(ray: RayRecord) -> ClosestHit {
    var best = ClosestHit(INVALID_ID, ray.t_max, 0.0, 0.0, false);
    if !traversal_ray_valid(ray) {
        return best;
    }
    let r = traversal_ray_new(ray);
    var t_best = r.t_max;
    if enter(r, bvh_nodes[0], t_best).x == 0.0 {
        return best;
    }
    var stack_node: array<u32, BVH_STACK_SIZE>;
    var stack_entry: array<f32, BVH_STACK_SIZE>;
    var sp = 0u;
    var stale = 0u;
    var n = 0u;
    loop {
        let node = bvh_nodes[n];
        var descend = false;
        if node.count > 0u {
            // One instance per top-level leaf.
            let b = instance_closest(instances[node.left_or_first], ray, r, best);
            if b.t != best.t || b.triangle != best.triangle {
                best = b;
                t_best = best.t;
                stale = sp;
            }
        } else {
            let l = node.left_or_first;
            let el = enter(r, bvh_nodes[l], t_best);
            let er = enter(r, bvh_nodes[l + 1u], t_best);
            if el.x != 0.0 && er.x != 0.0 {
                let right_first = er.y < el.y;
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
