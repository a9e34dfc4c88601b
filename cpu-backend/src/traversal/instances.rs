//! The object-space pass of a two-level scene ([`TwoLevelBvh`]) in packets: the world-space
//! level is traced first like any single-level tree (the packets of module `packet`, the
//! frustum or single-ray paths), then the rays go through the object-space instances
//! (moving objects, shared meshes), [`LANES`] at a time.
//!
//! * **Top level.** The packet of world rays walks the top level with the packets' node
//!   tests (`AnyHitLanes`, `ClosestHitLanes`): a lane enters an instance's leaf exactly
//!   when the scalar walk's ray would (the same slab test, lane by lane). The world-space
//!   level's leaf is skipped (already traced).
//! * **Into object space.** At an instance's leaf, the lanes that entered it are moved into
//!   the instance's space by the scalar kernel ([`object_space_ray`]: the same bits as
//!   `TwoLevelBvh::occluded_in_instance`), and the moved rays make a new packet, which walks
//!   the instance's bottom level with the ordinary packet code (`packet::occluded`,
//!   `packet::closest_hit_from`; the instance brings the global triangle offset, its
//!   object and its alpha flag: `packet::Level::instance`). Lanes the move leaves invalid
//!   hit nothing there, as in the scalar walk. When fewer than two lanes are left, they
//!   are traced one at a time with the scalar instance tests.
//! * **Any hit** stops a lane at its first hit in any instance; the packet ends when every
//!   lane is stopped. Only the rays the world-space level left unoccluded are traced; they
//!   are gathered into full packets (neighbours in the list stay neighbours). The
//!   any-hit packets' occluder cache is kept per bottom level: a lane stopped by the cached
//!   leaf of another instance of the same mesh also reaches that leaf in the scalar walk
//!   (it entered the instance's top-level leaf, and the cached leaf's box contains its
//!   ancestors' test, as `packet::occluded` argues within one tree).
//! * **Closest hit** starts from each lane's hit in the world-space level, carries the
//!   per-lane bound across instances as the scalar walk carries its own, and flips the
//!   facing of hits found in a mirrored instance. Ties at equal `t` go to the lower global
//!   triangle across instances too (`ClosestLanes::offer`). The result equals the scalar
//!   `TwoLevelBvh::closest_hit_in_object_space` except in the rounding corner case of
//!   `BVH_CULL_SLACK` that every closest-hit packet shares.

use hyrt_core::bvh::traversal::{inline_leaf_test, traverse, Leaf, LeafFlow};
use hyrt_core::bvh::two_level::{object_space_ray, TwoLevelBvh, INSTANCE_IDENTITY, INSTANCE_MIRRORED};
use hyrt_core::bvh::{ClosestHit, BVH_CULL_SLACK};
use hyrt_core::formats::RayRecord;
use hyrt_core::kernels::texture::SurfaceView;

use super::packet::{self, AnyHitLanes, ClosestHitLanes, ClosestLanes, Level, Occluder, Packet};
use super::ANY_OCTANT;
use crate::lanes::{Lanes, LANES};

/// A lane with no ray: an empty interval, which `Packet::new` rejects.
const NO_RAY: RayRecord = RayRecord {
    origin: [0.0; 3],
    t_min: 0.0,
    direction: [1.0; 3],
    t_max: 0.0,
    pixel: 0,
    kind: 0,
    depth: 0,
    light: 0,
    throughput: [0.0; 3],
    cone: 0.0,
};

/// The occluder cache of the any-hit packets, for the bottom level it was found in.
#[derive(Default)]
pub(crate) struct InstanceCache {
    bottom: u32,
    occluder: Option<Occluder>,
}

/// The lanes `m` of `p` moved into instance `i`'s space; the other lanes empty.
#[inline(always)]
fn object_rays<L: Lanes>(levels: &TwoLevelBvh, i: usize, p: &Packet<L>, m: u32) -> [RayRecord; LANES] {
    let inst = &levels.instances[i];
    let mut rays = [NO_RAY; LANES];
    let mut lanes = m;
    while lanes != 0 {
        let k = lanes.trailing_zeros() as usize;
        lanes &= lanes - 1;
        rays[k] = object_space_ray(inst, &p.rays[k]);
    }
    rays
}

/// Any hit of the valid lanes of `p` (world rays) over the object-space instances of
/// `levels`: the mask of lanes hit, lane by lane `TwoLevelBvh::occluded_in_object_space`.
#[inline(always)]
pub(crate) fn occluded<L: Lanes>(
    levels: &TwoLevelBvh,
    view: &SurfaceView,
    p: &Packet<L>,
    cache: &mut InstanceCache,
) -> u32 {
    let accept = super::alpha_test(view);
    let mut done = 0u32;
    let leaf_test = inline_leaf_test(
        #[inline(always)]
        |leaf: Leaf, m: u32, done: &mut u32| {
            let i = leaf.first as usize;
            let inst = &levels.instances[i];
            if inst.flags & INSTANCE_IDENTITY != 0 {
                return LeafFlow::Continue;
            }
            let rays = object_rays(levels, i, p, m);
            let hit = match Packet::<L>::new(&rays[..p.rays.len()]) {
                Some(po) => {
                    if cache.bottom != inst.bottom {
                        *cache = InstanceCache { bottom: inst.bottom, occluder: None };
                    }
                    packet::occluded(&Level::instance(levels, i), view, &po, &mut cache.occluder)
                }
                None => {
                    let mut hit = 0;
                    let mut lanes = m;
                    while lanes != 0 {
                        let k = lanes.trailing_zeros() as usize;
                        lanes &= lanes - 1;
                        if levels.occluded_in_instance(i, &p.rays[k], accept) {
                            hit |= 1 << k;
                        }
                    }
                    hit
                }
            };
            *done |= hit;
            if *done == p.valid {
                LeafFlow::Stop
            } else {
                LeafFlow::Continue
            }
        },
    );
    traverse(&levels.top, &AnyHitLanes::<L, ANY_OCTANT>(p), &mut done, leaf_test);
    done
}

/// The closest hits of the valid lanes of `p` (world rays) over the object-space
/// instances of `levels`, from `hits` (lane `i`'s hit in the world-space level, `None`
/// for none), written back into `hits`: lane by lane
/// `TwoLevelBvh::closest_hit_in_object_space`.
#[inline(always)]
pub(crate) fn closest_hit<L: Lanes>(
    levels: &TwoLevelBvh,
    view: &SurfaceView,
    p: &Packet<L>,
    hits: &mut [Option<ClosestHit>],
) {
    let accept = super::alpha_test(view);
    let widen = L::splat(1.0 + BVH_CULL_SLACK);
    let mut best = ClosestLanes::<L>::from_hits(p, hits);
    let mut t_far = L::mul(best.t, widen);
    let leaf_test = inline_leaf_test(
        #[inline(always)]
        |leaf: Leaf, m: u32, t_far: &mut L::F| {
            let i = leaf.first as usize;
            let inst = &levels.instances[i];
            if inst.flags & INSTANCE_IDENTITY != 0 {
                return LeafFlow::Continue;
            }
            let rays = object_rays(levels, i, p, m);
            let changed = match Packet::<L>::new(&rays[..p.rays.len()]) {
                Some(po) => {
                    let changed = packet::closest_hit_from(&Level::instance(levels, i), view, &po, &mut best);
                    if inst.flags & INSTANCE_MIRRORED != 0 {
                        best.flip_facing(changed);
                    }
                    changed
                }
                None => {
                    let mut changed = 0;
                    let mut lanes = m;
                    while lanes != 0 {
                        let k = lanes.trailing_zeros() as usize;
                        lanes &= lanes - 1;
                        let mut h = best.lane(k);
                        if levels.closest_in_instance(i, &p.rays[k], &mut h, accept) {
                            best.set_lane(k, h);
                            changed |= 1 << k;
                        }
                    }
                    changed
                }
            };
            if changed != 0 {
                *t_far = L::mul(best.t, widen);
                LeafFlow::Narrowed
            } else {
                LeafFlow::Continue
            }
        },
    );
    traverse(&levels.top, &ClosestHitLanes(p), &mut t_far, leaf_test);
    let out = best.hits();
    hits.copy_from_slice(&out[..hits.len()]);
}
