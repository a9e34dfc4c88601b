//! Packets of [`LANES`] rays traversing the core binary [`Bvh`] together: one box test
//! (or one triangle test) runs for all rays of the packet at once, lane by lane with the
//! very operations of the scalar kernels in `hyrt_core::kernels::ray`, so each lane's
//! result is the scalar one bit for bit.
//!
//! * Box test: [`ray_aabb_conservative`] with the widened interval of `Bvh::occluded` /
//!   `Bvh::closest_hit` (`t_min * (1 - BVH_CULL_SLACK)`, `t_far * (1 + BVH_CULL_SLACK)`),
//!   the near/far planes chosen by the sign of each lane's inverse direction (read once per
//!   node when the lanes agree, blended per lane when they do not), and the running
//!   max/min in the same order with the same NaN rule (x86 `MAXPS`/`MINPS` are exactly
//!   `if candidate > acc { acc = candidate }`).
//! * Triangle test: [`WatertightRay::intersect`] per lane: the axis permutation of each
//!   lane (applied to the vertex once when the lanes share it, blended otherwise), every
//!   product and sum in the scalar order, no fused multiply-add.
//!   The lane form is `watertight::intersect`, shared with the single-ray leaf test. A
//!   lane whose f32 edge function is exactly zero is redone with the scalar kernel (whose
//!   exact tie rule has no lane form).
//!
//! The walk is the one traversal loop of `hyrt_core::bvh::traversal` with the packets'
//! node tests (`AnyHitLanes`, `ClosestHitLanes`) and leaf tests. A lane takes part in a
//! node while its ray entered the node's box (the traversal keeps a lane mask per stack
//! entry). Any hit: a lane stops at its first hit, the packet when all lanes stopped.
//! Closest hit: the per-lane culling bound is the lane's closest hit so far, widened as
//! in the scalar code; a node popped from the stack is re-tested against the current
//! bound if some lane's closest hit improved since it was pushed, which is exactly the
//! scalar pop test `t_enter <= best * (1 + slack)` (the entry distance does not depend on
//! the far bound).
//!
//! Child order is the packet's own, so a lane may see nodes in another order than the
//! scalar traversal (which goes to the child it enters first). Any hit: left child first,
//! as stored (measured about 15% faster on the teaser's shadow rays than near-first by a
//! majority vote of the lanes' entry distances; and against the closest-hit order, which
//! does not wait for the box tests, `ray_contest --packets-only --kind shadow --rounds 15
//! --threads 1`, the three interleaved in one process, ms: near first by the box centres
//! along the first lane's direction 75.7 on the dragon, 6.00 on the far bunny and 56.7 on
//! the teaser, far first 68.9, 5.80 and 54.5, left first 65.5, 5.20 and 51.7). Closest hit:
//! near first by the children's box centres along the first valid lane's direction (as fast
//! as the vote, and it does not wait for the box tests). The order does not change results:
//! for any hit that changes nothing (a lane enters a node exactly when its ray passes the
//! box tests of the node and all its ancestors, as in the scalar traversal, so the result
//! "some triangle of some reachable leaf is hit" is the same); for closest hit the result
//! is the minimum `(t, triangle)` over the same triangles except in the rounding corner
//! case described at `BVH_CULL_SLACK`.
//!
//! [`ray_aabb_conservative`]: hyrt_core::kernels::ray::ray_aabb_conservative

use glam::Vec3;
use hyrt_core::bvh::traversal::{inline_leaf_test, traverse, Leaf, LeafFlow, NodeTest};
use hyrt_core::bvh::two_level::{TwoLevelBvh, INSTANCE_ALPHA_TEST, INSTANCE_IDENTITY};
use hyrt_core::bvh::{Bvh, BvhNode, ClosestHit, BVH_CULL_SLACK};
use hyrt_core::formats::{RayRecord, TriangleRecord, INVALID_ID, TRI_ALPHA_TEST};
use hyrt_core::kernels::ray::{permute_axes, TriangleHit, WatertightRay, SLAB_FAR_SCALE};
use hyrt_core::kernels::texture::{alpha_accepts, SurfaceView};

use super::watertight;
use super::ANY_OCTANT;
use crate::lanes::{slab_bounds, Lanes, ALL_LANES, LANES};

/// A tree as the packets' leaf tests see it: a single-level [`Bvh`] (its slots hold global
/// triangle indices, its triangles their own flags), or the bottom level of an
/// object-space instance of a [`TwoLevelBvh`] (slots hold mesh-local indices; the
/// instance brings the first global index, its object and its alpha flag: the scalar
/// `TwoLevelBvh::occluded_in_instance` and `closest_in_instance`).
#[derive(Clone, Copy)]
pub(crate) struct Level<'a> {
    pub bvh: &'a Bvh,
    /// Added to a slot's index: the global triangle index.
    first_triangle: u32,
    /// Or-ed into every triangle's flags (the instance's [`INSTANCE_ALPHA_TEST`]).
    alpha_flags: u32,
    /// The object an alpha test reads in the hit record, [`INVALID_ID`] for the record's
    /// own (see `two_level::hit_record`).
    object: u32,
}

impl<'a> Level<'a> {
    /// A single-level tree, or the world-space level of a two-level one.
    #[inline(always)]
    pub fn world(bvh: &'a Bvh) -> Self {
        Level { bvh, first_triangle: 0, alpha_flags: 0, object: INVALID_ID }
    }

    /// The bottom level of object-space instance `i` of `levels` (not the world-space
    /// level, whose rays are not moved).
    #[inline(always)]
    pub fn instance(levels: &'a TwoLevelBvh, i: usize) -> Self {
        let inst = &levels.instances[i];
        debug_assert_eq!(inst.flags & INSTANCE_IDENTITY, 0);
        Level {
            bvh: &levels.bottoms[inst.bottom as usize],
            first_triangle: inst.first_triangle,
            alpha_flags: inst.flags & INSTANCE_ALPHA_TEST,
            object: inst.object,
        }
    }

    /// The global triangle index of slot `slot`.
    #[inline(always)]
    pub fn global(&self, slot: u32) -> u32 {
        self.first_triangle + self.bvh.prim_indices[slot as usize]
    }
}

/// Up to [`LANES`] rays prepared for traversal, lane `i` from `rays[i]`.
pub(crate) struct Packet<'a, L: Lanes> {
    /// The rays (lanes redone with the scalar kernel read them).
    pub(super) rays: &'a [RayRecord],
    /// Lanes holding a ray that can hit something (see `Packet::new`).
    pub valid: u32,
    /// `valid` as a lane mask (all ones in the valid lanes).
    pub(super) valid_lanes: L::F,
    pub(super) origin: [L::F; 3],
    /// The directions (the frustum's origin-spread limit reads their lengths).
    pub(super) dir: [L::F; 3],
    pub(super) inv_dir: [L::F; 3],
    /// The direction of the first valid lane (orders children).
    dir0: [f32; 3],
    /// Per axis: index of the near plane in a node read as `[f32; 8]`: `4 + a` (the max)
    /// where the valid lanes' inverse directions are negative, else `a` (when they all
    /// agree, the usual case).
    pub(super) near: [usize; 3],
    /// True if every valid lane's inverse direction is finite (no zero or subnormal
    /// direction component): slab distances are then never NaN.
    pub(super) finite_inv: bool,
    /// True if the valid lanes' direction signs differ on some axis: the box test then
    /// picks the near plane per lane, from `neg_lanes`.
    pub(super) mixed: bool,
    /// All ones where the lane's inverse direction is negative, per axis.
    neg_lanes: [L::F; 3],
    /// The origin with its axes permuted per lane (`permute_axes(origin, kz)`).
    origin_perm: [L::F; 3],
    /// The lanes' common `kz`, if they share one (the usual case).
    kz: Option<u32>,
    /// All ones where `kz == 0`, resp. `kz == 1` (used when the lanes' `kz` differ).
    kz0: L::F,
    kz1: L::F,
    shear: [L::F; 3],
    t_min: L::F,
    pub(super) t_max: L::F,
    pub(super) box_t_min: L::F,
    /// `t_max * (1 + BVH_CULL_SLACK)`: the far bound of box tests for any hit.
    pub(super) box_t_max: L::F,
}

/// Lane mask from booleans.
#[inline(always)]
fn lane_mask(b: bool) -> f32 {
    f32::from_bits(if b { u32::MAX } else { 0 })
}

impl<'a, L: Lanes> Packet<'a, L> {
    /// Prepare `rays` (at most [`LANES`]). A lane is valid exactly when the scalar
    /// traversal would trace its ray: finite origin and direction, non-zero direction,
    /// `t_min < t_max` (`WatertightRay::new` and `TraversalRay::new` in `hyrt_core`).
    /// `None` when fewer than two lanes are valid: such rays are traced alone.
    ///
    /// The per-ray constants are those of `WatertightRay::new` and `safe_inverse_dir`,
    /// computed lane-wise with the same operations: the validity tests, the axis `kz` of
    /// `max_component_index`, `permute_axes` as blends, and the divisions (`1 / d` on
    /// each axis; `d.x / d.z`, `d.y / d.z` of the permuted direction; its `1 / d.z` is the
    /// inverse direction on axis `kz`, the same division). Nothing here branches per lane:
    /// the per-lane code it replaced took about a quarter of the any-hit time on the
    /// teaser's shadow rays.
    ///
    /// The records come in through one 8x8 transpose in registers ([`Lanes::ray_lanes`]; a
    /// short packet padded to eight first). The scalar copy into an array that the lanes were
    /// then loaded from, which it replaced, wrote 64 words and read them back as eight vectors,
    /// each load waiting on eight smaller stores it cannot be forwarded from: 6.1% of the
    /// dragon's packet time in `perf record` samples (AMD EPYC, AVX2, one thread,
    /// `ray_contest --packets-only --kind shadow`), 4.6% after; the two binaries
    /// alternated three times (`--rounds 11`), the dragon 64.1 to 67.8 ms against 66.3 to
    /// 70.8, the teaser 50.7 to 51.9 against 51.2 to 52.4, the near bunny unchanged.
    #[inline(always)]
    pub fn new(rays: &'a [RayRecord]) -> Option<Self> {
        debug_assert!(rays.len() <= LANES);
        // Structure of arrays. A short packet is padded with rays of origin 0, direction 1
        // and an empty interval: invalid, with finite quotients (never used).
        let w = match <&[RayRecord; LANES]>::try_from(rays) {
            Ok(full) => L::ray_lanes(full),
            Err(_) => {
                let pad = RayRecord { direction: [1.0; 3], ..bytemuck::Zeroable::zeroed() };
                L::ray_lanes(&std::array::from_fn(|i| rays.get(i).copied().unwrap_or(pad)))
            }
        };
        let o = [w[0], w[1], w[2]];
        let d = [w[4], w[5], w[6]];
        let (t_min, t_max) = (w[3], w[7]);
        let zero = L::splat(0.0);
        let inf = L::splat(f32::INFINITY);
        // `Vec3::is_finite` of origin and direction (NaN compares false), `dir != 0`
        // (`-0 == 0`), `t_min < t_max` (false for NaN).
        let finite = |v: L::F| L::lt(L::abs(v), inf);
        let all_finite = L::and(
            L::and(L::and(finite(o[0]), finite(o[1])), L::and(finite(o[2]), finite(d[0]))),
            L::and(finite(d[1]), finite(d[2])),
        );
        let zero_dir = L::and(L::and(L::eq(d[0], zero), L::eq(d[1], zero)), L::eq(d[2], zero));
        // Lanes past the end have an empty interval: `present` changes nothing, kept as a
        // guard.
        let present = (1u32 << rays.len()) - 1;
        let valid_lanes = L::andnot(zero_dir, L::and(all_finite, L::lt(t_min, t_max)));
        let valid = L::bits(valid_lanes) & present;
        debug_assert_eq!(valid, L::bits(valid_lanes));
        if valid.count_ones() < 2 {
            return None;
        }
        let first = valid.trailing_zeros() as usize;
        let dir0 = rays[first].direction;
        // 1 / x keeps the sign of x (also for +-0): the inverse's signs are the direction's.
        let neg_bits = [L::bits(d[0]) & valid, L::bits(d[1]) & valid, L::bits(d[2]) & valid];
        let mixed = neg_bits.iter().any(|&b| b != 0 && b != valid);
        let near = |a: usize| if neg_bits[a] >> first & 1 != 0 { 4 + a } else { a };
        // max_component_index(|d|): x > y ? (x > z ? 0 : 2) : (y > z ? 1 : 2).
        let (ax, ay, az) = (L::abs(d[0]), L::abs(d[1]), L::abs(d[2]));
        let x_gt_y = L::lt(ay, ax);
        let kz0 = L::and(x_gt_y, L::lt(az, ax));
        let kz1 = L::andnot(x_gt_y, L::lt(az, ay));
        let (k0, k1) = (L::bits(kz0) & valid, L::bits(kz1) & valid);
        let kz = if k0 == valid {
            Some(0)
        } else if k1 == valid {
            Some(1)
        } else if k0 | k1 == 0 {
            Some(2)
        } else {
            None
        };
        // permute_axes: kz = 0: (y, z, x); kz = 1: (z, x, y); kz = 2: (x, y, z).
        let permute = |v: &[L::F; 3]| {
            [
                L::select(kz0, v[1], L::select(kz1, v[2], v[0])),
                L::select(kz0, v[2], L::select(kz1, v[0], v[1])),
                L::select(kz0, v[0], L::select(kz1, v[1], v[2])),
            ]
        };
        let dp = permute(&d);
        let one = L::splat(1.0);
        // safe_inverse_dir: 1 / d per component.
        let inv_dir = [L::div(one, d[0]), L::div(one, d[1]), L::div(one, d[2])];
        let infinite = L::or(
            L::or(L::eq(L::abs(inv_dir[0]), inf), L::eq(L::abs(inv_dir[1]), inf)),
            L::eq(L::abs(inv_dir[2]), inf),
        );
        Some(Packet {
            dir0,
            finite_inv: L::bits(infinite) & valid == 0,
            rays,
            valid,
            valid_lanes,
            origin: o,
            dir: d,
            inv_dir,
            near: [near(0), near(1), near(2)],
            mixed,
            neg_lanes: [L::sign_mask(d[0]), L::sign_mask(d[1]), L::sign_mask(d[2])],
            origin_perm: permute(&o),
            kz,
            kz0,
            kz1,
            // WatertightRay::new: (d.x / d.z, d.y / d.z, 1 / d.z) of the permuted direction.
            shear: [L::div(dp[0], dp[2]), L::div(dp[1], dp[2]), permute(&inv_dir)[2]],
            t_min,
            t_max,
            box_t_min: L::mul(t_min, L::splat(1.0 - BVH_CULL_SLACK)),
            box_t_max: L::mul(t_max, L::splat(1.0 + BVH_CULL_SLACK)),
        })
    }

    /// The conservative slab test of every lane against `node`'s box for the interval
    /// `[box_t_min, t_far]`: the mask of lanes that enter.
    #[inline(always)]
    pub(super) fn enter(&self, node: &BvhNode, t_far: L::F) -> u32 {
        if !self.mixed {
            return self.enter_signed(node, t_far, self.near, self.finite_inv);
        }
        // The scalar order: x, y, z for both running bounds.
        let mut tn = [self.box_t_min; 3];
        let mut tf = [t_far; 3];
        for a in 0..3 {
            let t_lo = L::mul(L::sub(L::splat(node.aabb_min[a]), self.origin[a]), self.inv_dir[a]);
            let t_hi = L::mul(L::sub(L::splat(node.aabb_max[a]), self.origin[a]), self.inv_dir[a]);
            tn[a] = L::select(self.neg_lanes[a], t_hi, t_lo);
            tf[a] = L::mul(L::select(self.neg_lanes[a], t_lo, t_hi), L::splat(SLAB_FAR_SCALE));
        }
        let (t_enter, t_exit) = slab_bounds::<L>(tn, tf, self.box_t_min, t_far, self.finite_inv);
        L::bits(L::le(t_enter, t_exit))
    }

    /// [`Self::enter`] for lanes whose inverse directions share their signs: `near[a]` is
    /// the index of axis `a`'s near plane in the node read as `[f32; 8]` ([`Packet::near`];
    /// the far plane is the other one), `finite_inv` [`Packet::finite_inv`]. With both
    /// constants (the octant walks of [`AnyHitLanes`]) the plane loads are fixed offsets and
    /// the NaN-safe branch of [`slab_bounds`] is gone.
    #[inline(always)]
    pub(super) fn enter_signed(&self, node: &BvhNode, t_far: L::F, near: [usize; 3], finite_inv: bool) -> u32 {
        // The scalar order: x, y, z for both running bounds.
        let mut tn = [self.box_t_min; 3];
        let mut tf = [t_far; 3];
        // The node as 8 floats: min at 0..3, max at 4..7 (`BvhNode` layout).
        let b: &[f32; 8] = bytemuck::cast_ref(node);
        for a in 0..3 {
            let (near, far) = (b[near[a] & 7], b[(near[a] ^ 4) & 7]);
            tn[a] = L::mul(L::sub(L::splat(near), self.origin[a]), self.inv_dir[a]);
            tf[a] = L::mul(L::mul(L::sub(L::splat(far), self.origin[a]), self.inv_dir[a]), L::splat(SLAB_FAR_SCALE));
        }
        let (t_enter, t_exit) = slab_bounds::<L>(tn, tf, self.box_t_min, t_far, finite_inv);
        L::bits(L::le(t_enter, t_exit))
    }

    /// A vertex in every lane's ray space (`WatertightRay::transform`): permuted by each
    /// lane's `kz` (once when the lanes share it, blended otherwise), then
    /// [`watertight::ray_space`].
    #[inline(always)]
    fn transform(&self, v: [f32; 3]) -> [L::F; 3] {
        match self.kz {
            Some(kz) => {
                let v = permute_axes(Vec3::from(v), kz);
                watertight::ray_space::<L>(
                    [L::splat(v.x), L::splat(v.y), L::splat(v.z)],
                    &self.origin_perm,
                    &self.shear,
                )
            }
            None => self.transform_lanes([L::splat(v[0]), L::splat(v[1]), L::splat(v[2])]),
        }
    }

    /// [`Self::transform`] of a vertex that differs per lane (lane `i` a vertex of the
    /// triangle lane `i` meets).
    #[inline(always)]
    fn transform_lanes(&self, v: [L::F; 3]) -> [L::F; 3] {
        let v = match self.kz {
            Some(kz) => match kz {
                0 => [v[1], v[2], v[0]],
                1 => [v[2], v[0], v[1]],
                _ => v,
            },
            // kz = 0: (y, z, x); kz = 1: (z, x, y); kz = 2: (x, y, z).
            None => [
                L::select(self.kz0, v[1], L::select(self.kz1, v[2], v[0])),
                L::select(self.kz0, v[2], L::select(self.kz1, v[0], v[1])),
                L::select(self.kz0, v[0], L::select(self.kz1, v[1], v[2])),
            ],
        };
        watertight::ray_space::<L>(v, &self.origin_perm, &self.shear)
    }

    /// `WatertightRay::intersect` for the lanes in `active` against one triangle, with the
    /// rays' own `(t_min, t_max)`: the mask of lanes hit and, in those lanes, `t, u, v`,
    /// and the mask of lanes that see the triangle's back face
    /// (`WatertightRay::back_face` of the determinant, the f32 sum of the edge functions
    /// that the scalar kernel computes too, also where it redoes a lane).
    #[inline(always)]
    pub(super) fn intersect<const EARLY_OUT: bool>(
        &self,
        active: u32,
        tri: &TriangleRecord,
    ) -> (u32, L::F, L::F, L::F, u32) {
        self.intersect_vertices::<EARLY_OUT>(active, [tri.v0, tri.v1, tri.v2])
    }

    /// [`Self::intersect`] against the triangle of vertices `v`, taken by value: a caller
    /// reading them from a wide leaf's structure of arrays builds no record in memory (a
    /// record built there became, at the AVX-512 level, one eight-lane gather of its
    /// vertices followed by extractions for the broadcasts).
    #[inline(always)]
    pub(super) fn intersect_vertices<const EARLY_OUT: bool>(
        &self,
        active: u32,
        v: [[f32; 3]; 3],
    ) -> (u32, L::F, L::F, L::F, u32) {
        let p = [self.transform(v[0]), self.transform(v[1]), self.transform(v[2])];
        self.intersect_in_ray_space::<EARLY_OUT>(active, p, |_| v)
    }

    /// [`Self::intersect`] with lane `i` against its own triangle `tris[i]`: the vertices
    /// of the eight triangles as lanes ([`Lanes::triangle_lanes`]), each in its lane's ray
    /// space ([`Self::transform_lanes`]), so lane `i` gets the values [`Self::intersect`]
    /// computes for it against `tris[i]`.
    #[inline(always)]
    pub(crate) fn intersect_each(&self, active: u32, tris: [&TriangleRecord; LANES]) -> (u32, L::F, L::F, L::F, u32) {
        let v = L::triangle_lanes(tris);
        let p = [self.transform_lanes(v[0]), self.transform_lanes(v[1]), self.transform_lanes(v[2])];
        self.intersect_in_ray_space::<false>(active, p, |i| [tris[i].v0, tris[i].v1, tris[i].v2])
    }

    /// The rest of [`Self::intersect`] from the vertices in ray space `p`, lane `i`'s
    /// triangle's vertices `tri(i)` (for the lanes the scalar kernel redoes).
    #[inline(always)]
    fn intersect_in_ray_space<const EARLY_OUT: bool>(
        &self,
        active: u32,
        p: [[L::F; 3]; 3],
        tri: impl Fn(usize) -> [[f32; 3]; 3],
    ) -> (u32, L::F, L::F, L::F, u32) {
        let h = watertight::intersect::<L, EARLY_OUT>(active, p, &self.shear, self.t_min, self.t_max);
        let (mut hit, exact) = (h.hit, h.exact);
        let (mut t_out, mut u_out, mut v_out) = (h.t, h.u, h.v);
        if exact != 0 {
            let (mut ts, mut us, mut vs) = (L::store(t_out), L::store(u_out), L::store(v_out));
            let mut lanes = exact;
            while lanes != 0 {
                let i = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                if let Some(h) = self.scalar_lane(i, tri(i)) {
                    hit |= 1 << i;
                    (ts[i], us[i], vs[i]) = (h.t, h.u, h.v);
                }
            }
            (t_out, u_out, v_out) = (L::load(&ts), L::load(&us), L::load(&vs));
        }
        // back_face: (det > 0) == (shear.z > 0).
        let zero = L::splat(0.0);
        let back = !(L::bits(L::gt(h.det, zero)) ^ L::bits(L::gt(self.shear[2], zero)));
        (hit, t_out, u_out, v_out, back)
    }

    /// Lane `lane`'s ray against up to eight triangles at once, one per lane of `v` (their
    /// vertices, [`Lanes::triangle_lanes`]), the lanes `active`: `WatertightRay::intersect`
    /// lane by lane with the ray's constants (`WatertightRay::new`, which `Packet::new`
    /// computes lane-wise with the same operations) and the vertex transform of
    /// [`Self::transform`], so each triangle gets the very values [`Self::intersect`]
    /// computes for this lane: every lane's `t, u, v` and determinant, the triangles hit
    /// (`hit`, the alpha test not applied) and those whose exactly-zero edge function
    /// leaves the answer to the scalar kernel (`exact`).
    #[inline(always)]
    pub(super) fn lane_test(&self, lane: usize, v: &[[L::F; 3]; 3], active: u32) -> watertight::LaneHits<L> {
        // The lane's own constants, `WatertightRay::new` of its ray, taken from the lanes
        // where `Packet::new` computed them (the same operations, bit for bit).
        let own = |x: L::F| L::broadcast_lane(x, lane);
        let kz = if L::bits(self.kz0) >> lane & 1 != 0 {
            0
        } else if L::bits(self.kz1) >> lane & 1 != 0 {
            1
        } else {
            2
        };
        let o = self.origin_perm.map(own);
        let shear = self.shear.map(own);
        // `Self::transform`'s operations: permuted vertex minus permuted origin, then shear.
        let ray_space = |p: &[L::F; 3]| leaf_ray_space::<L>(p, kz, &o, &shear);
        let p = [ray_space(&v[0]), ray_space(&v[1]), ray_space(&v[2])];
        watertight::intersect::<L, false>(active, p, &shear, own(self.t_min), own(self.t_max))
    }

    /// Whether lane `lane`'s hit of determinant `det` is on a back face
    /// (`WatertightRay::back_face` with the lane's shear).
    #[inline(always)]
    pub(super) fn lane_back_face(&self, lane: usize, det: f32) -> bool {
        (det > 0.0) == (L::store(self.shear[2])[lane] > 0.0)
    }

    /// Lane `lane`'s ray against the vertices `v` with the scalar kernel
    /// (`WatertightRay::intersect`, as [`Self::intersect`] redoes the lanes it cannot
    /// decide).
    #[inline(never)]
    pub(super) fn scalar_lane(&self, lane: usize, v: [[f32; 3]; 3]) -> Option<TriangleHit> {
        let r = &self.rays[lane];
        WatertightRay::new(r.origin.into(), r.direction.into())
            .and_then(|w| w.intersect(r.t_min, r.t_max, v[0].into(), v[1].into(), v[2].into()))
    }

    /// [`Self::intersect`] against the triangle in leaf slot `slot` of `level`, its hits
    /// kept only where an alpha-tested triangle's texel passes ([`alpha_lanes`]).
    #[inline(always)]
    pub(super) fn intersect_slot<const EARLY_OUT: bool>(
        &self,
        level: &Level,
        view: &SurfaceView,
        active: u32,
        slot: u32,
    ) -> (u32, L::F, L::F, L::F, u32) {
        let tri = &level.bvh.leaf_triangles[slot as usize];
        let (mut hit, t, u, v, back) = self.intersect::<EARLY_OUT>(active, tri);
        if hit != 0 && (tri.flags | level.alpha_flags) & TRI_ALPHA_TEST != 0 {
            hit = alpha_lanes::<L>(view, level, tri, slot, hit, u, v);
        }
        (hit, t, u, v, back)
    }
}

/// One vertex of eight triangles in one ray's space: permuted by `kz` (in registers),
/// then [`watertight::ray_space`].
#[inline(always)]
fn leaf_ray_space<L: Lanes>(p: &[L::F; 3], kz: u32, o: &[L::F; 3], shear: &[L::F; 3]) -> [L::F; 3] {
    // permute_axes: kz = 0: (y, z, x); kz = 1: (z, x, y); kz = 2: (x, y, z).
    let q = match kz {
        0 => [p[1], p[2], p[0]],
        1 => [p[2], p[0], p[1]],
        _ => *p,
    };
    watertight::ray_space::<L>(q, o, shear)
}

/// The lanes of `hit` (hits on the alpha-tested triangle `tri`, slot `slot` of `level`, at
/// barycentrics `u`, `v`) whose texel passes the alpha test ([`alpha_accepts`]): a rejected
/// hit is no hit, as in `Bvh::occluded_filtered`. Only called for triangles flagged
/// [`TRI_ALPHA_TEST`] (by themselves or by their instance), which exist only in scenes
/// whose `view` holds their materials.
#[inline(never)]
#[cold]
fn alpha_lanes<L: Lanes>(
    view: &SurfaceView,
    level: &Level,
    tri: &TriangleRecord,
    slot: u32,
    hit: u32,
    u: L::F,
    v: L::F,
) -> u32 {
    let (us, vs) = (L::store(u), L::store(v));
    let global = level.global(slot) as usize;
    // The record the scalar walks give `accept` (an instance's object in it).
    let record = if level.object == INVALID_ID { *tri } else { TriangleRecord { object: level.object, ..*tri } };
    let tri = &record;
    let mut kept = hit;
    let mut lanes = hit;
    while lanes != 0 {
        let i = lanes.trailing_zeros() as usize;
        lanes &= lanes - 1;
        if !alpha_accepts(view, tri, global, us[i], vs[i]) {
            kept &= !(1 << i);
        }
    }
    kept
}

/// Lane mask to the node test's answer: `None` when no lane is left.
#[inline(always)]
fn lanes(m: u32) -> Option<u32> {
    (m != 0).then_some(m)
}

/// The any-hit node test of a packet: the entry is the mask of lanes that entered the
/// node, the bound the mask of lanes already stopped (they drop out of popped nodes), the
/// far end of every box test the rays' `t_max` widened; children left first, as stored.
///
/// `O` is [`ANY_OCTANT`] for any packet, or the octant of a packet whose valid lanes all
/// lie in it (bit `a` set where the inverse direction's component `a` is negative) with
/// finite inverse directions: the same box test compiled with the plane offsets of that
/// octant ([`Packet::enter_signed`]).
pub(super) struct AnyHitLanes<'p, 'a, L: Lanes, const O: u8>(pub &'p Packet<'a, L>);

/// [`Packet::near`] of a packet whose lanes lie in `octant` (bit `a` set where the inverse
/// direction's component `a` is negative): axis `a`'s near plane is the box maximum, index
/// `4 + a` of a node read as `[f32; 8]`, where the bit is set, else the minimum, `a`.
#[inline(always)]
pub(super) const fn octant_near(octant: u8) -> [usize; 3] {
    let o = octant as usize;
    [(o & 1) << 2, 1 + ((o >> 1 & 1) << 2), 2 + ((o >> 2 & 1) << 2)]
}

/// The octant of a packet whose lanes share their direction signs (not [`Packet::mixed`]).
#[inline(always)]
pub(super) fn packet_octant<L: Lanes>(p: &Packet<'_, L>) -> u8 {
    debug_assert!(!p.mixed);
    (0..3).map(|a| u8::from(p.near[a] >= 4) << a).sum()
}

impl<L: Lanes, const O: u8> AnyHitLanes<'_, '_, L, O> {
    const NEAR: [usize; 3] = octant_near(O);

    /// The lanes that enter `node`'s box.
    #[inline(always)]
    fn enter_box(&self, node: &BvhNode) -> u32 {
        let p = self.0;
        if O == ANY_OCTANT {
            p.enter(node, p.box_t_max)
        } else {
            debug_assert!(!p.mixed && p.finite_inv && p.near == Self::NEAR);
            p.enter_signed(node, p.box_t_max, Self::NEAR, true)
        }
    }
}

impl<L: Lanes, const O: u8> NodeTest for AnyHitLanes<'_, '_, L, O> {
    type Entry = u32;
    type Bound = u32;

    #[inline(always)]
    fn enter_root(&self, root: &BvhNode, done: &u32) -> Option<u32> {
        lanes(self.enter_box(root) & self.0.valid & !done)
    }

    #[inline(always)]
    fn enter(&self, node: &BvhNode, m: u32, _done: &u32) -> Option<u32> {
        lanes(self.enter_box(node) & m)
    }

    #[inline(always)]
    fn right_first(&self, _left: &BvhNode, _right: &BvhNode, _ml: u32, _mr: u32) -> bool {
        false
    }

    #[inline(always)]
    fn resume(&self, _node: &BvhNode, m: u32, done: &u32, _stale: bool) -> Option<u32> {
        lanes(m & !done)
    }
}

/// The closest-hit node test of a packet: the entry is the mask of lanes that entered the
/// node, the bound every lane's closest `t` so far widened by `1 + BVH_CULL_SLACK` (the far
/// end of box tests); near child first by the box centres along the first valid lane's
/// direction; a stale node is re-tested against the current bound, which is exactly the
/// scalar pop test `t_enter <= best * (1 + slack)` (the entry distance does not depend on
/// the far bound).
pub(super) struct ClosestHitLanes<'p, 'a, L: Lanes>(pub &'p Packet<'a, L>);

impl<L: Lanes> NodeTest for ClosestHitLanes<'_, '_, L> {
    type Entry = u32;
    type Bound = L::F;

    #[inline(always)]
    fn enter_root(&self, root: &BvhNode, t_far: &L::F) -> Option<u32> {
        lanes(self.0.enter(root, *t_far) & self.0.valid)
    }

    #[inline(always)]
    fn enter(&self, node: &BvhNode, m: u32, t_far: &L::F) -> Option<u32> {
        lanes(self.0.enter(node, *t_far) & m)
    }

    /// The child whose box centre lies further back along the first valid lane's direction
    /// (computed from the boxes alone, so it does not wait for the box tests).
    #[inline(always)]
    fn right_first(&self, a: &BvhNode, b: &BvhNode, _ml: u32, _mr: u32) -> bool {
        let d = &self.0.dir0;
        let c = |k: usize| (b.aabb_min[k] + b.aabb_max[k]) - (a.aabb_min[k] + a.aabb_max[k]);
        c(0) * d[0] + c(1) * d[1] + c(2) * d[2] < 0.0
    }

    #[inline(always)]
    fn resume(&self, node: &BvhNode, m: u32, t_far: &L::F, stale: bool) -> Option<u32> {
        lanes(if stale { m & self.0.enter(node, *t_far) } else { m })
    }
}

/// The triangle that last stopped a lane of an any-hit packet: the leaf node holding it
/// and its slot in `Bvh::leaf_triangles` (see [`occluded`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Occluder {
    leaf: u32,
    slot: u32,
}

/// Any hit for every valid lane: the mask of lanes whose ray hits a triangle with
/// `t_min < t < t_max`, equal lane by lane to `Bvh::occluded`.
///
/// `cache` is the occluder of the previous packet (neighbouring pixels, same light): its
/// leaf is tested first, with the leaf test of the traversal, starting at its triangle and
/// wrapping round to the leaf's other triangles; it is replaced by the last occluder this
/// packet finds. A lane stopped there is occluded for the scalar traversal too: the lane
/// must also pass the scalar box test of the leaf, and then it passes the box tests of
/// every ancestor, because a box containing another gives a slab interval containing the
/// other's (each slab distance is a monotone function of the plane, rounding included,
/// when no inverse direction is infinite, which the cache requires), so the scalar
/// traversal reaches the leaf and its triangle test gives the same hit. Lanes
/// the cache does not stop traverse as usual. Measured on one thread: the triangle alone
/// made the teaser's shadow rays 12% faster and Sponza's 18%; the rest of the leaf 3 to 6%
/// more; no change on the bunny and the dragon.
///
/// At the levels with `Lanes::OCTANT_WALKS`, a packet whose lanes share the signs of their
/// directions and have finite inverse directions (the usual case: [`Packet::mixed`] and
/// [`Packet::finite_inv`]) walks with a node test compiled for its octant ([`AnyHitLanes`]
/// of that octant), the others with [`ANY_OCTANT`]. The same node tests, operation for
/// operation; the octant's plane offsets are constants and the tests for mixed signs and
/// infinite inverses are gone from the walk. Measured (AMD EPYC, one thread, `ray_contest
/// --packets-only --kind shadow`, the binaries with and without alternated three times,
/// medians of nine rounds): the dragon 66.7 to 61.9 ms, the far bunny 5.16 to 4.69, the far
/// horse 0.87 to 0.80, the teaser 51.7 to 47.8 at AVX-512; the dragon 66.6 to 63.3 and
/// Sponza 42.0 to 40.1 at AVX2. Object-space instances (`instances::occluded`) take the
/// octant walks too: the paper's frame of the teaser with its bunny moving, two levels
/// against the flat scene (staged executor, `moving_report --no-gpu --frames 9`, the
/// binaries alternated three times) 1.14 to 1.16 against 1.18 to 1.24, the 16 moving
/// bunnies 1.09 to 1.12 against 1.12 to 1.13.
#[inline(always)]
pub(crate) fn occluded<L: Lanes>(
    level: &Level,
    view: &SurfaceView,
    p: &Packet<L>,
    cache: &mut Option<Occluder>,
) -> u32 {
    let nodes = &level.bvh.nodes;
    let cached = if p.finite_inv { *cache } else { None };
    // The lanes stopped so far (the traversal's bound).
    let mut done = 0u32;
    // Any hit of the lanes `m` against the leaf's triangles in slot order from its start,
    // until every lane is stopped; the last triangle that stops a lane becomes the cache.
    // `inline(always)` on the leaf tests: a closure not inlined would be compiled without
    // the caller's target features (AVX2), its lane operations out of line.
    let mut leaf_test = inline_leaf_test(
        #[inline(always)]
        |leaf: Leaf, mut m: u32, done: &mut u32| {
            // Fewer lanes than triangles: each lane against all the triangles at once
            // (not for the occluder cache's retest, which starts at a given slot).
            if m.count_ones() < leaf.end - leaf.first && leaf.start == leaf.first {
                occluded_lanes_alone(level, view, p, leaf, m, done, cache);
                return if *done == p.valid { LeafFlow::Stop } else { LeafFlow::Continue };
            }
            for slot in leaf.slots() {
                let hit = p.intersect_slot::<false>(level, view, m, slot).0;
                if hit != 0 {
                    *done |= hit;
                    m &= !hit;
                    *cache = Some(Occluder { leaf: leaf.node, slot });
                    if m == 0 {
                        break;
                    }
                }
            }
            if *done == p.valid {
                LeafFlow::Stop
            } else {
                LeafFlow::Continue
            }
        },
    );
    if let Some(c) = cached {
        let n = c.leaf as usize;
        let m = p.enter(&nodes[n], p.box_t_max) & p.valid;
        if m != 0 && leaf_test(Leaf::starting_at(n, &nodes[n], c.slot), m, &mut done) == LeafFlow::Stop {
            return done;
        }
    }
    octant_walk!(if !p.mixed && p.finite_inv => packet_octant(p), any_hit_walk::<L>(nodes, p, &mut done, leaf_test));
    done
}

/// The any-hit walk of `p` with the node test of octant `O` ([`AnyHitLanes`]).
#[inline(always)]
fn any_hit_walk<L: Lanes, const O: u8>(
    nodes: &[BvhNode],
    p: &Packet<'_, L>,
    done: &mut u32,
    leaf_test: impl FnMut(Leaf, u32, &mut u32) -> LeafFlow,
) {
    traverse(nodes, &AnyHitLanes::<L, O>(p), done, leaf_test);
}

/// Any hit of the lanes `m` against a leaf one lane at a time, each lane's ray against all
/// the leaf's triangles at once (one per lane of the SIMD test, [`Packet::lane_test`]),
/// instead of one packet test per triangle: for a leaf entered by fewer lanes than it has
/// triangles, which is most leaves where the lanes part (shadow rays leaving a dense mesh
/// each reach the leaves around their own origin alone).
///
/// The lane-wise test computes the packet test's IEEE operations on the same values, so
/// a triangle it hits without leaving the answer to the scalar kernel is a hit of the
/// packet test for that lane; every other candidate (an exactly-zero edge function, or a
/// hit on an alpha-tested triangle) is confirmed by the packet's own test for that lane
/// ([`Packet::intersect_slot`], the scalar kernel and the alpha test included). Candidates
/// are taken in slot order, so a lane stops exactly where the slot loop would have stopped
/// it, and the stopping triangle becomes the occluder cache, as in the slot loop. (Until
/// December 2026 every candidate was confirmed; taking the decided hits as they are
/// measured 2 to 3% less time on the dragon's, the near bunny's and the teaser's shadow
/// rays, AVX2, one thread, interleaved round by round in one process.)
///
/// Measured against the previous binary (`ray_contest --threads 1 --rounds 5 --kind shadow
/// all`, the two alternated three times; Embree's best / hyrt, the three runs' medians):
/// the dragon from 0.78-0.85 to 0.94-0.98, the far bunny from 0.77-0.85 to 0.95-0.99, the
/// far horse from 0.68-0.76 to 0.82-0.96, the near bunny from 0.83-0.95 to 1.00-1.03, the
/// near horse from 0.94-1.08 to 1.11-1.12; the teaser and Sponza unchanged with AVX-512
/// lanes, Sponza 2 to 4% slower with AVX2. Other rules for taking a leaf alone measured no
/// better: `lanes + 1 < triangles`, `2 * lanes <= triangles`, at least 3 triangles, at most
/// 3 lanes. Taking the triangles from the wide view's leaves (already in lanes,
/// [`WideLeaf`](hyrt_core::bvh::wide::WideLeaf)) instead of transposing the records was as
/// fast on the small scans and slower on the dragon (0.79): a second copy of the triangles
/// to keep in cache.
#[inline(always)]
fn occluded_lanes_alone<L: Lanes>(
    level: &Level,
    view: &SurfaceView,
    p: &Packet<L>,
    leaf: Leaf,
    m: u32,
    done: &mut u32,
    cache: &mut Option<Occluder>,
) {
    let tris = &level.bvh.leaf_triangles[leaf.first as usize..leaf.end as usize];
    // Lanes past the leaf's triangles repeat its last one; they are not tested.
    let v = L::triangle_lanes(std::array::from_fn(|k| &tris[k.min(tris.len() - 1)]));
    let all = (1u32 << tris.len()) - 1;
    let mut lanes = m;
    while lanes != 0 {
        let lane = lanes.trailing_zeros() as usize;
        lanes &= lanes - 1;
        let h = p.lane_test(lane, &v, all);
        let mut candidates = h.hit | h.exact;
        while candidates != 0 {
            let k = candidates.trailing_zeros();
            let slot = leaf.first + k;
            candidates &= candidates - 1;
            // A hit the lane test decided (not left to the scalar kernel) on a triangle
            // without the alpha test is the packet test's own verdict for this lane.
            let decided = h.hit >> k & 1 != 0 && (tris[k as usize].flags | level.alpha_flags) & TRI_ALPHA_TEST == 0;
            if decided || p.intersect_slot::<false>(level, view, 1 << lane, slot).0 != 0 {
                *done |= 1 << lane;
                *cache = Some(Occluder { leaf: leaf.node, slot });
                break;
            }
        }
    }
}

/// The closest hit so far of every lane of a packet: `t` (the rays' `t_max` where none
/// yet), barycentrics, facing and triangle. Shared by the binary packets and the coherent
/// ones (`frustum`).
pub(super) struct ClosestLanes<L: Lanes> {
    pub t: L::F,
    u: L::F,
    v: L::F,
    /// Lanes whose closest hit is a back face.
    back: u32,
    id: [u32; LANES],
}

impl<L: Lanes> ClosestLanes<L> {
    /// No hit yet.
    #[inline(always)]
    pub fn new(p: &Packet<'_, L>) -> Self {
        ClosestLanes { t: p.t_max, u: L::splat(0.0), v: L::splat(0.0), back: 0, id: [INVALID_ID; LANES] }
    }

    /// The hits `hits` found so far (lane `i` from `hits[i]`; the ray's `t_max` and no
    /// triangle where `None`).
    #[inline(always)]
    pub fn from_hits(p: &Packet<'_, L>, hits: &[Option<ClosestHit>]) -> Self {
        let mut best = ClosestLanes::new(p);
        let (mut t, mut u, mut v) = (L::store(best.t), [0.0; LANES], [0.0; LANES]);
        for (i, h) in hits.iter().enumerate().take(LANES) {
            if let Some(h) = h {
                (t[i], u[i], v[i]) = (h.t, h.u, h.v);
                best.id[i] = h.triangle;
                best.back |= u32::from(h.back_face) << i;
            }
        }
        (best.t, best.u, best.v) = (L::load(&t), L::load(&u), L::load(&v));
        best
    }

    /// Lane `k`'s closest hit so far (triangle [`INVALID_ID`] at the ray's `t_max` where
    /// none yet), for the scalar code.
    #[inline(always)]
    pub fn lane(&self, k: usize) -> ClosestHit {
        let (t, u, v) = (L::store(self.t)[k], L::store(self.u)[k], L::store(self.v)[k]);
        ClosestHit { triangle: self.id[k], t, u, v, back_face: self.back >> k & 1 != 0 }
    }

    /// Set lane `k`'s closest hit (found by the scalar code).
    #[inline(always)]
    pub fn set_lane(&mut self, k: usize, h: ClosestHit) {
        let (mut t, mut u, mut v) = (L::store(self.t), L::store(self.u), L::store(self.v));
        (t[k], u[k], v[k]) = (h.t, h.u, h.v);
        (self.t, self.u, self.v) = (L::load(&t), L::load(&u), L::load(&v));
        self.id[k] = h.triangle;
        self.back = (self.back & !(1 << k)) | u32::from(h.back_face) << k;
    }

    /// Flip the facing of the lanes `m` (hits found in a mirrored instance, whose object
    /// space faces the other way).
    #[inline(always)]
    pub fn flip_facing(&mut self, m: u32) {
        self.back ^= m;
    }

    /// Take the hits `hit` (at `t, u, v` per lane, back faces in `back`) on triangle `id`
    /// where they are nearer than the lane's closest so far, or as near with a lower
    /// triangle index (the scalar rule for ties). The mask of lanes that improved.
    #[inline(always)]
    pub fn offer(&mut self, hit: u32, t: L::F, u: L::F, v: L::F, back: u32, id: u32) -> u32 {
        let mut take = hit & L::bits(L::lt(t, self.t));
        let mut ties = hit & L::bits(L::eq(t, self.t));
        while ties != 0 {
            let i = ties.trailing_zeros() as usize;
            ties &= ties - 1;
            if id < self.id[i] {
                take |= 1 << i;
            }
        }
        if take == 0 {
            return 0;
        }
        let mut sel = [0.0; LANES];
        for (i, s) in sel.iter_mut().enumerate() {
            if take & (1 << i) != 0 {
                *s = lane_mask(true);
                self.id[i] = id;
            }
        }
        self.back = (self.back & !take) | (back & take);
        let sel = L::load(&sel);
        self.t = L::select(sel, t, self.t);
        self.u = L::select(sel, u, self.u);
        self.v = L::select(sel, v, self.v);
        take
    }

    /// Test the lanes `m` against the triangles of leaf slots `slots` of `level` (with
    /// the alpha test of `view`) and take their hits ([`Self::offer`]). The mask of lanes
    /// that improved.
    #[inline(always)]
    pub fn test_slots(
        &mut self,
        level: &Level,
        view: &SurfaceView,
        p: &Packet<'_, L>,
        m: u32,
        slots: impl Iterator<Item = u32>,
    ) -> u32 {
        let mut improved = 0;
        for slot in slots {
            let (hit, t, u, v, back) = p.intersect_slot::<true>(level, view, m, slot);
            if hit != 0 {
                improved |= self.offer(hit, t, u, v, back, level.global(slot));
            }
        }
        improved
    }

    /// The lanes' closest hits.
    #[inline(always)]
    pub fn hits(&self) -> [Option<ClosestHit>; LANES] {
        let mut out = [None; LANES];
        self.write_hits(&mut out);
        out
    }

    /// The closest hits of the first `out.len()` lanes into `out`.
    #[inline(always)]
    pub fn write_hits(&self, out: &mut [Option<ClosestHit>]) {
        let (t, u, v) = (L::store(self.t), L::store(self.u), L::store(self.v));
        for (i, o) in out.iter_mut().enumerate().take(LANES) {
            *o = (self.id[i] != INVALID_ID).then(|| {
                let back_face = self.back >> i & 1 != 0;
                ClosestHit { triangle: self.id[i], t: t[i], u: u[i], v: v[i], back_face }
            });
        }
    }
}

/// Closest hit for every valid lane, lane `i` equal to `Bvh::closest_hit` for ray `i`
/// (see the module docs for the one rounding corner case).
#[inline(always)]
pub(crate) fn closest_hit<L: Lanes>(level: &Level, view: &SurfaceView, p: &Packet<L>, out: &mut [Option<ClosestHit>]) {
    let mut best = ClosestLanes::<L>::new(p);
    closest_hit_from(level, view, p, &mut best);
    best.write_hits(out);
}

/// [`closest_hit`] from the closest hits `best` found so far (in other trees: the
/// world-space level, other instances): a lane's hit in `level` replaces its best under
/// the same `(t, triangle)` order, the boxes culled against the best so far, as the scalar
/// walk carries its bound across the levels. The mask of lanes whose best changed.
#[inline(always)]
pub(crate) fn closest_hit_from<L: Lanes>(
    level: &Level,
    view: &SurfaceView,
    p: &Packet<L>,
    best: &mut ClosestLanes<L>,
) -> u32 {
    let widen = L::splat(1.0 + BVH_CULL_SLACK);
    let mut t_far = L::mul(best.t, widen);
    let mut changed = 0;
    let leaf_test = inline_leaf_test(
        #[inline(always)]
        |leaf: Leaf, m: u32, t_far: &mut L::F| {
            let improved = best.test_slots(level, view, p, m, leaf.slots());
            if improved != 0 {
                changed |= improved;
                *t_far = L::mul(best.t, widen);
                LeafFlow::Narrowed
            } else {
                LeafFlow::Continue
            }
        },
    );
    traverse(&level.bvh.nodes, &ClosestHitLanes(p), &mut t_far, leaf_test);
    changed
}

const _: () = assert!(ALL_LANES.count_ones() as usize == LANES);
// A leaf's triangles fit the lanes of one test (`occluded_lanes_alone`).
const _: () = assert!(hyrt_core::bvh::BVH_MAX_LEAF_SIZE as usize <= LANES);
