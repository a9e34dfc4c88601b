//! Coherent packets through the 8-wide tree ([`WideBvh`](hyrt_core::bvh::wide::WideBvh)) for closest hits: the
//! [`LANES`] rays of a packet are bounded by one frustum (interval arithmetic over their
//! origins and inverse directions, as Embree's coherent traversal does), and one frustum
//! test decides for all eight children of a wide node at once whether any lane can enter
//! them; only at a leaf are the lanes tested one by one (the packets' own box test of the
//! leaf's box, then the packets' triangle test of its triangles for the lanes that
//! entered, the vertices read from the wide leaf's structure of arrays: `test_leaf_lanes`).
//! Children are visited nearest first by the frustum's entry bound.
//!
//! A node test costs about one single-ray test of the wide node for the whole packet,
//! where the binary packets (module `packet`) test each lane against two children, and
//! the wide tree has a third of the binary tree's depth. It needs every valid lane's
//! direction to have the same sign on each axis, finite inverse directions, and origins
//! close together ([`MAX_ORIGIN_SPREAD`]); [`Frustum::new`] declines other packets, which
//! take the binary path. Packets from one point whose directions part are caught during
//! the walk, by the leaf boxes their frustum lets through and no lane enters
//! ([`MAX_IDLE_LEAF_BOXES`]), and take the binary path too. Primary rays from one eye are
//! the case it is for: measured on the teaser's 921,600 primary rays (1280x720, one
//! thread, interleaved rounds, the `ray_contest` example), 7.9 wide nodes, 2.4 leaf boxes
//! and 12.6 triangle tests per packet, and 15.2 Mrays/s against the binary packets' 10.3 (before the triangle culling
//! and the facing below); the committed report (`hyrt bench --quick`, 2 threads) has the
//! teaser's primary rays at 30.3 Mrays/s, 0.88 of Embree's coherent `rtcIntersect8`, where
//! the binary packets were at 0.65.
//!
//! The work per packet outside the walk matters as much as the walk here (a packet of
//! primary rays visits about eight wide nodes): the frustum's bounds are horizontal
//! reductions over the lanes ([`Lanes::min_lane`], also after every hit that narrows the
//! bound), its origin-spread limit is computed lane-wise, and the hits are written
//! straight into the output. Counted with callgrind on the teaser's primary rays (AVX2):
//! 1,039 million instructions for two passes before, 870 after the reductions alone (the
//! per-lane loop they replace was 10% of them). Timed (`ray_contest --kind primary
//! --packets-only`, one thread, the old and new binaries alternated three times): the
//! teaser's primary rays from 49.4 to 42.6 ms, Sponza's from 43.1 to 36.5, the near
//! bunny's from 21.8 to 16.3, the results unchanged ray for ray.
//!
//! Any hit was tried the same way and is not used: on the teaser's shadow rays the
//! frustum packets ran at 19.2 Mrays/s against the binary packets' 24.7 (which try the
//! previous packet's occluder first, and whose lanes leave the walk one by one), and on
//! the dragon's at 11.1 against 14.0.
//!
//! Two packets under one frustum were tried and not kept (issue 36; AMD EPYC Zen 5, AVX-512,
//! one thread, `ray_contest --kind primary --packets-only --rounds 7`, the two binaries
//! alternated twice, ms): consecutive packets (sixteen pixels of a row) whose frusta agree
//! in octant and whose joined origins stay within [`MAX_ORIGIN_SPREAD`] walked the wide
//! nodes once under the joined frustum (its bounds the extremes of both, the far bound the
//! greater), each packet testing a leaf's box and triangles with its own lanes and bound.
//! The teaser 33.9 to 35.6 against 36.6 to 39.1 and Sponza 30.0 to 33.1 against 30.5 to
//! 33.0, but the dragon 41.0 to 43.6 against 36.6 to 38.8 and the near bunny 13.6 to 14.9
//! against 13.2 to 14.7; culling each packet's leaf triangles by its own frustum instead of
//! the joined one changed neither. On dense meshes the longer frustum lets through leaves
//! that one of its packets does not enter (the interval bounds of a 1x16 row of rays are
//! looser than two 1x8 ones), and the node tests saved at the top of the tree do not pay
//! for them. (Lane operations in closures, such as a `map` of `Packet::new` over the
//! group's rays, are not compiled with the entry point's target features: the first build
//! ran four times slower.)
//!
//! # Why the results are the scalar reference's
//!
//! The frustum test only rejects a child when every valid lane's own slab test (the
//! scalar `ray_aabb_conservative` under the lane's current bound, as in `Packet::enter`)
//! rejects it: each bound of the frustum is the extreme of the lanes' rounded slab
//! distances. A lane's near distance on an axis is `fl(fl(p - o) * inv)`; rounding is
//! monotone, so `fl(p - o)` over the lanes' origins lies between its values at the
//! extreme origins, and the product of an interval by an interval of one sign takes its
//! extremes at the corners, rounded monotonically too. The smallest corner product is
//! thus no larger than any lane's near distance (the largest no smaller than any lane's
//! far distance, times `SLAB_FAR_SCALE`), and the frustum's interval
//! `[max of the near bounds, min of the far bounds]` contains every lane's. So a lane
//! reaches every leaf the binary packet (or the scalar traversal) would let it test,
//! and possibly more; testing more leaves changes no result (the argument of the wide
//! tree, `hyrt_core::bvh::wide`, and of the packets' child order): any hit is "some
//! reachable triangle is hit", closest hit the least `(t, triangle)` over them.
//!
//! The leaf's per-lane box test is the binary packets' (`Packet::enter` on the leaf's
//! box, which is a binary node's box bit for bit), so the lanes testing a triangle are
//! exactly those whose scalar traversal could reach its leaf under the current bound.
//!
//! Inside a leaf, the frustum is also tested against each triangle's own bounding box
//! (the eight boxes at once, from the leaf's structure-of-arrays vertices), and the
//! triangles no lane can reach are not tested. This is the culling the BVH does with its
//! leaf boxes, applied to the smallest box around the triangle: a ray whose watertight
//! test hits the triangle at `t` enters every box containing the triangle under a bound
//! of at least `t` widened by `BVH_CULL_SLACK`, with the same heuristic margin (and the
//! same documented corner case) as the leaf boxes themselves.

use hyrt_core::bvh::wide::{WideChild, WideLeaf, WideNode, WIDE};
use hyrt_core::bvh::{Bvh, BvhNode, ClosestHit, BVH_CULL_SLACK};
use hyrt_core::kernels::ray::{TriangleHit, SLAB_FAR_SCALE};
use hyrt_core::kernels::texture::SurfaceView;

use super::packet::{octant_near, ClosestLanes, Level, Packet};
use super::single::Stack;
use super::ANY_OCTANT;
use crate::lanes::{Lanes, LANES};

/// The bounds of a packet's rays for the wide node test, per axis: the origin and
/// inverse-direction extremes that bound every valid lane's slab distances.
pub(crate) struct Frustum<L: Lanes> {
    /// The near plane of every lane is the box maximum (inverse directions negative).
    near_is_max: [bool; 3],
    /// The origin giving the least `near - o` (positive inverse direction: the greatest
    /// origin; negative: the least, whose difference is the greatest, the product least).
    o_near: [L::F; 3],
    /// The origin giving the extreme `far - o` for the greatest far distance.
    o_far: [L::F; 3],
    inv_lo: [L::F; 3],
    inv_hi: [L::F; 3],
    /// The least widened `t_min` of the valid lanes.
    t_min_lo: L::F,
}

impl<L: Lanes> Frustum<L> {
    /// The frustum of `p`'s valid lanes, or `None` when their directions differ in sign on
    /// some axis or some inverse direction is infinite.
    #[inline(always)]
    pub fn new(p: &Packet<'_, L>, extent: f32) -> Option<Self> {
        if p.mixed || !p.finite_inv {
            return None;
        }
        let spread_limit = {
            // The shortest valid ray, `|d| * t_max` (`Vec3::length`'s operations, lane-wise).
            let d = &p.dir;
            let dot = L::add(L::add(L::mul(d[0], d[0]), L::mul(d[1], d[1])), L::mul(d[2], d[2]));
            let shortest = lane_range::<L>(L::mul(L::sqrt(dot), p.t_max), p.valid_lanes).0;
            extent.min(shortest) * MAX_ORIGIN_SPREAD
        };
        let (mut o_lo, mut o_hi, mut i_lo, mut i_hi) = ([0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3]);
        for a in 0..3 {
            (o_lo[a], o_hi[a]) = lane_range::<L>(p.origin[a], p.valid_lanes);
            (i_lo[a], i_hi[a]) = lane_range::<L>(p.inv_dir[a], p.valid_lanes);
        }
        let t_lo = lane_range::<L>(p.box_t_min, p.valid_lanes).0;
        if (0..3).any(|a| o_hi[a] - o_lo[a] > spread_limit) {
            return None;
        }
        let near_is_max = [p.near[0] >= 4, p.near[1] >= 4, p.near[2] >= 4];
        let pick = |a: usize, when_max: [f32; 3], otherwise: [f32; 3]| {
            L::splat(if near_is_max[a] { when_max[a] } else { otherwise[a] })
        };
        Some(Frustum {
            near_is_max,
            o_near: [pick(0, o_lo, o_hi), pick(1, o_lo, o_hi), pick(2, o_lo, o_hi)],
            o_far: [pick(0, o_hi, o_lo), pick(1, o_hi, o_lo), pick(2, o_hi, o_lo)],
            inv_lo: i_lo.map(L::splat),
            inv_hi: i_hi.map(L::splat),
            t_min_lo: L::splat(t_lo),
        })
    }

    /// [`Self::enter_signed`] with the frustum's own `near_is_max` (the tests).
    #[cfg(test)]
    fn enter(&self, node: &WideNode, t_far: f32) -> (u32, [f32; LANES]) {
        self.enter_signed(node, t_far, self.near_is_max)
    }

    /// The children of `node` some valid lane may enter under a far bound of at most
    /// `t_far` (mask), and a lower bound of every lane's entry distance per child.
    /// `near_is_max` is the frustum's own, given as constants by the walk of one octant
    /// ([`closest_hit`]).
    #[inline(always)]
    fn enter_signed(&self, node: &WideNode, t_far: f32, near_is_max: [bool; 3]) -> (u32, [f32; LANES]) {
        let lo = [L::load(&node.lo[0]), L::load(&node.lo[1]), L::load(&node.lo[2])];
        let hi = [L::load(&node.hi[0]), L::load(&node.hi[1]), L::load(&node.hi[2])];
        let (t_enter, t_exit) = self.slabs(lo, hi, t_far, near_is_max);
        let used = (1u32 << node.count) - 1;
        (L::bits(L::le(t_enter, t_exit)) & used, L::store(t_enter))
    }

    /// The triangles of `leaf` (its first `count`) some valid lane may hit before `t_far`:
    /// the frustum test of each triangle's bounding box (the exact minimum and maximum of
    /// its vertices). A box containing a triangle is entered by a ray that hits the
    /// triangle, as the leaf's own box is (the slack of `BVH_CULL_SLACK`); see the module
    /// docs.
    #[inline(always)]
    fn triangles(&self, leaf: &WideLeaf, count: u32, t_far: f32, near_is_max: [bool; 3]) -> u32 {
        let v = &leaf.v;
        let mut lo = [L::splat(0.0); 3];
        let mut hi = [L::splat(0.0); 3];
        for a in 0..3 {
            let (v0, v1, v2) = (L::load(&v[0][a]), L::load(&v[1][a]), L::load(&v[2][a]));
            lo[a] = L::min(L::min(v0, v1), v2);
            hi[a] = L::max(L::max(v0, v1), v2);
        }
        let (t_enter, t_exit) = self.slabs(lo, hi, t_far, near_is_max);
        L::bits(L::le(t_enter, t_exit)) & ((1u32 << count) - 1)
    }

    /// The frustum's entry and exit bounds of eight boxes (`lo`, `hi` per axis, a box per
    /// lane) for `[t_min, t_far]`; `near_is_max` is the frustum's own.
    #[inline(always)]
    fn slabs(&self, lo: [L::F; 3], hi: [L::F; 3], t_far: f32, near_is_max: [bool; 3]) -> (L::F, L::F) {
        debug_assert_eq!(near_is_max, self.near_is_max);
        let mut tn = [self.t_min_lo; 3];
        let mut tf = [L::splat(t_far); 3];
        let scale = L::splat(SLAB_FAR_SCALE);
        for a in 0..3 {
            let (near, far) = if near_is_max[a] { (hi[a], lo[a]) } else { (lo[a], hi[a]) };
            let dn = L::sub(near, self.o_near[a]);
            tn[a] = L::min(L::mul(dn, self.inv_lo[a]), L::mul(dn, self.inv_hi[a]));
            let df = L::sub(far, self.o_far[a]);
            tf[a] = L::mul(L::max(L::mul(df, self.inv_lo[a]), L::mul(df, self.inv_hi[a])), scale);
        }
        let t_enter = L::max(L::max(tn[0], tn[1]), L::max(tn[2], self.t_min_lo));
        let t_exit = L::min(L::min(tf[0], tf[1]), L::min(tf[2], L::splat(t_far)));
        (t_enter, t_exit)
    }
}

/// The largest spread of a packet's origins (on any axis) the frustum takes, as a
/// fraction of its shortest ray: the rays of a frame's shadow-ray list leave neighbouring
/// pixels, and where those pixels straddle a depth discontinuity their origins lie metres
/// apart; the frustum of such a packet spans much of the scene. Measured on the teaser's
/// shadow rays (one thread): without a limit the frustum packets visited 31 wide nodes and
/// tested 74 leaf boxes per packet, of which lanes entered 1.7 (8 equal rays: 6.4 nodes,
/// 1.1 leaves); with this limit 7.4 nodes and 2.6 leaf boxes. Primary rays share their
/// origin and always pass.
const MAX_ORIGIN_SPREAD: f32 = 0.02;

/// The length of the scene's diagonal (the BVH root box), which bounds the useful length
/// of an unbounded ray for [`MAX_ORIGIN_SPREAD`]; 0 for an empty BVH.
pub(crate) fn scene_extent(bvh: &Bvh) -> f32 {
    bvh.nodes.first().map_or(0.0, |n| (n.max() - n.min()).length())
}

/// The box of child `k` of a wide node as a binary node (the box the binary tree stores
/// for it, bit for bit), for the packets' per-lane box test.
#[inline(always)]
fn child_box(node: &WideNode, k: usize) -> BvhNode {
    BvhNode {
        aabb_min: [node.lo[0][k], node.lo[1][k], node.lo[2][k]],
        left_or_first: 0,
        aabb_max: [node.hi[0][k], node.hi[1][k], node.hi[2][k]],
        count: 0,
    }
}

/// Stack entries name a child by its parent and slot: `parent * WIDE + slot`.
#[inline(always)]
fn entry(parent: u32, slot: usize) -> u32 {
    parent * WIDE as u32 + slot as u32
}

/// The least and the greatest of `x`'s lanes where `valid` (a lane mask) is set: valid
/// lanes hold no NaN (finite origins and inverse directions, `t_min < t_max`), the others
/// are left out as infinities. Two horizontal reductions (this was a loop over the lanes,
/// about 10% of the instructions of the teaser's primary rays: it runs seven times per
/// packet and again after every hit that narrows the bound).
#[inline(always)]
fn lane_range<L: Lanes>(x: L::F, valid: L::F) -> (f32, f32) {
    let lo = L::min_lane(L::select(valid, x, L::splat(f32::INFINITY)));
    let hi = L::max_lane(L::select(valid, x, L::splat(f32::NEG_INFINITY)));
    (lo, hi)
}

/// Closest hit for every valid lane of `p` through the wide tree, lane `i` equal to
/// `Bvh::closest_hit` for ray `i` (as the binary packets: see the module docs). Children
/// are visited nearest first by the frustum's entry bound; a popped child is skipped when
/// that bound lies beyond every lane's widened closest hit.
///
/// `O` is the packet's octant (`packet::packet_octant`, given by the caller's
/// `octant_walk!`), or `ANY_OCTANT` to read it from the packet at run time (the levels
/// without `Lanes::OCTANT_WALKS`). Compiled once per octant, the frustum's near planes and
/// the leaves' per-lane box tests ([`Packet::enter_signed`]) read the node's rows at
/// constant offsets. Measured (AMD EPYC, one thread, `ray_contest --packets-only --kind
/// primary`, the binaries with and without alternated three times, medians of nine
/// rounds): 2 to 3% less time on every run of the dragon's, the teaser's, Sponza's and the
/// near bunny's primary rays at AVX-512 (the dragon 42.3 to 41.7 ms, the teaser 41.5 to
/// 40.4) and at AVX2 (the dragon 44.0 to 43.1 ms).
///
/// Returns whether it finished: the walk gives up on a packet whose frustum lets through
/// more than [`MAX_IDLE_LEAF_BOXES`] leaf boxes that no lane enters, having written
/// nothing, and the caller traces it in the binary packets' walk (see that constant).
#[inline(always)]
pub(crate) fn closest_hit<L: Lanes, const O: u8>(
    bvh: &Bvh,
    view: &SurfaceView,
    p: &Packet<'_, L>,
    f: &Frustum<L>,
    stack: &mut Stack,
    out: &mut [Option<ClosestHit>],
) -> bool {
    let near = if O == ANY_OCTANT { p.near } else { octant_near(O) };
    let near_is_max = near.map(|i| i >= 4);
    let wide = &bvh.wide;
    let widen = L::splat(1.0 + BVH_CULL_SLACK);
    let mut best = ClosestLanes::<L>::new(p);
    let mut t_far = L::mul(best.t, widen);
    let mut t_far_hi = lane_range::<L>(t_far, p.valid_lanes).1;
    let mut node = 0u32;
    let mut sp = 0usize;
    let mut idle_leaf_boxes = IdleLeafBoxes(0);
    'walk: loop {
        let n = &wide.nodes[node as usize];
        let (mask, t) = f.enter_signed(n, t_far_hi, near_is_max);
        if mask.is_power_of_two() {
            // One child entered: an inner node is visited next without the stack.
            if let WideChild::Node(c) = WideChild::decode(n.child[mask.trailing_zeros() as usize]) {
                node = c;
                continue 'walk;
            }
        }
        super::single::push_nearest_last(mask, |k| t[k], |k| entry(node, k), stack, &mut sp);
        loop {
            if sp == 0 {
                break 'walk;
            }
            sp -= 1;
            let (e, t_enter) = stack[sp];
            if t_enter > t_far_hi {
                continue;
            }
            let (parent, k) = ((e / WIDE as u32) as usize, (e % WIDE as u32) as usize);
            let parent = &wide.nodes[parent];
            match WideChild::decode(parent.child[k]) {
                WideChild::Node(c) => {
                    node = c;
                    continue 'walk;
                }
                WideChild::Leaf { leaf, count } => {
                    let m = p.enter_signed(&child_box(parent, k), t_far, near, true) & p.valid;
                    if m == 0 {
                        if idle_leaf_boxes.one_more_past_limit() {
                            return false;
                        }
                        continue;
                    }
                    let wleaf = &wide.leaves[leaf as usize];
                    let tris = f.triangles(wleaf, count, t_far_hi, near_is_max);
                    let improved = if view.alpha_tested() {
                        // The alpha test reads the records' flags: the slots' own records.
                        let first = wide.first_slots[leaf as usize];
                        let mut tris = tris;
                        let slots = std::iter::from_fn(|| {
                            let k = (tris != 0).then(|| tris.trailing_zeros())?;
                            tris &= tris - 1;
                            Some(first + k)
                        });
                        best.test_slots(&Level::world(bvh), view, p, m, slots) != 0
                    } else {
                        test_leaf_lanes(p, &mut best, wleaf, m, tris) != 0
                    };
                    if improved {
                        t_far = L::mul(best.t, widen);
                        t_far_hi = lane_range::<L>(t_far, p.valid_lanes).1;
                    }
                }
            }
        }
    }
    best.write_hits(out);
    true
}

/// The count of a packet's leaf boxes that its frustum let through and no lane entered,
/// kept out of line, in memory. The primary rays, which rarely count, took 5 to 10%
/// longer on the dragon and the near bunny (one thread, AVX2, `ray_contest --packets-only
/// --kind primary --rounds 9`, alternated three or four times with the walk without the
/// count) with the count as a local of the walk, whether the binary walk then took over
/// from inside the loop (inlined or not) or after it from the lanes' hits so far (those
/// passed by value); with the count out of line and the binary walk started afresh by the
/// caller, the dragon took 47.0 ms three times against 46.4 to 48.0, the near bunny 17.7 to
/// 17.9 against 17.7 to 18.0, the teaser 48.7 to 49.2 against 49.0 to 50.5.
struct IdleLeafBoxes(u32);

impl IdleLeafBoxes {
    /// Count one more; whether the count is now past [`MAX_IDLE_LEAF_BOXES`].
    #[cold]
    #[inline(never)]
    fn one_more_past_limit(&mut self) -> bool {
        self.0 += 1;
        self.0 > MAX_IDLE_LEAF_BOXES
    }
}

/// Leaf boxes a packet's frustum may let through without any lane entering them before
/// [`closest_hit`] gives up on the packet, which its caller then traces from the start in
/// the binary packets' walk (`packet::closest_hit`, which culls lane by lane at every
/// binary node; the leaves the frustum walk tested are tested again, which changes no
/// answer).
///
/// [`Frustum::new`] bounds the spread of a packet's origins, not of its directions: a
/// packet of rays from one point whose directions part (a list of active pixels jumps
/// from the end of one pixel row to the start of the next, or reflections off a curved
/// mirror) has a frustum spanning the wedge between its rays, and with one far bound for
/// all lanes (the greatest lane's) the wedge takes in every leaf between them, lanes
/// entering almost none. Rays from each light to the frame's shadow-ray origins (the
/// reversed shadow rays of `ray_contest --kind from-lights`, closest hit, one thread,
/// AVX2): the dragon's visited 203 wide nodes and tested 926 leaf boxes per packet, of
/// which lanes entered 3.7, and took 3.6 to 4.4 s against 0.14 s in the binary packets
/// alone. The packets' spread is a poor sign of that cost: declining packets whose unit
/// directions spread over more than 0.02 on an axis brought the dragon's to 0.14 s but cost
/// the teaser's reflection and refraction rays in packets 7% (a sphere's reflections
/// part, yet the frustum still pays there), and 0.1 left the dragon's at 0.67 s. The count
/// of idle leaf boxes measures the waste itself. Measured with an earlier form that handed
/// the packet to the binary walk from the lanes' hits so far (`ray_contest --packets-only
/// --threads 1 --rounds 3`, the limit read from the environment in one binary, ms; the
/// limits from none to 256, 64 and 16):
///
/// | rays | none | 256 | 64 | 16 |
/// |---|---:|---:|---:|---:|
/// | the dragon, from the lights | 4,367 | 154 | 130 | 128 |
/// | the far horse, from the lights | 3.46 | 2.53 | 1.96 | 1.80 |
/// | the teaser, from the lights | 130 | 103 | 92 | 90 |
/// | the teaser's reflections and refractions | 47.6 | 43.3 | 44.6 | 44.9 |
/// | primary rays (dragon, teaser, far horse) | 51.4, 55.0, 11.3 | 49.3, 52.0, 11.0 | 49.3, 53.5, 10.9 | 53.3, 58.8, 11.2 |
///
/// Primary rays from one eye, 1.7 to 2.2 leaves entered of 2.4 tested per packet, never
/// reach the limit. The final form, starting the binary walk afresh: the dragon's rays
/// from the lights 125 ms, the far horse's 1.92, the teaser's 88; the teaser's reflections
/// and refractions in packets 41.9 and 42.2 against 41.0 and 41.2 without a limit.
const MAX_IDLE_LEAF_BOXES: u32 = 64;

/// The packet's test (lanes `m`) of the triangles `tris` of a wide leaf, each triangle's
/// vertices read from the leaf's structure of arrays, which the frustum's triangle culling
/// ([`Frustum::triangles`]) has just read, instead of from the binary leaf's records: the
/// same bits (`WideBvh::validate`), one copy of the leaf in cache instead of two. Hits are
/// offered in slot order, with the lane's global triangle index, as
/// `ClosestLanes::test_slots` offers them; no alpha test (the caller takes the records
/// where the scene has alpha tests). Measured against the records (one thread, the two
/// interleaved in one process, `ray_contest --packets-only --kind primary`): the dragon's
/// primary rays 100 ms to 80, the far bunny's 20.6 to 16.9, Sponza's 80 to 77, the
/// teaser's unchanged; the same answers ray for ray.
///
/// The nine vertex values are read one by one (volatile reads) and handed over by value:
/// read as plain loads into a record or an array, LLVM's SLP vectorizer merged eight of
/// them into one `vgatherqps` at the AVX-512 level (the AVX2 build kept scalar loads), then
/// took the values apart again for the broadcasts. Without it (this 2-core Intel Xeon,
/// one thread, `ray_contest --kind primary --packets-only --with-avx2`, the two binaries
/// alternated three times, medians): the AVX-512 packets' primary rays 74.2 to 58.4 ms on
/// the teaser, 65.1 to 51.4 on Sponza, 61.5 to 53.0 on the dragon, 25.1 to 22.7 on the
/// near bunny, 13.5 to 13.1 on the far horse; the AVX2 build within 1%. The gather had
/// made AVX-512 the slower level for closest-hit packets on Intel (issue 36, item 4).
///
/// A leaf entered by fewer lanes than it has triangles left after the culling is tested
/// lane by lane instead ([`test_leaf_each_lane`]).
#[inline(always)]
fn test_leaf_lanes<L: Lanes>(p: &Packet<L>, best: &mut ClosestLanes<L>, leaf: &WideLeaf, m: u32, mut tris: u32) -> u32 {
    if m.count_ones() < tris.count_ones() {
        return test_leaf_each_lane(p, best, leaf, m, tris);
    }
    let mut improved = 0;
    while tris != 0 {
        let k = tris.trailing_zeros() as usize;
        tris &= tris - 1;
        // SAFETY: in-bounds reads of the leaf (k < WIDE); volatile so that they stay scalar.
        let at = |i: usize, a: usize| unsafe { std::ptr::read_volatile(&leaf.v[i][a][k]) };
        let vertices = [0, 1, 2].map(|i| [at(i, 0), at(i, 1), at(i, 2)]);
        let (hit, t, u, v, back) = p.intersect_vertices::<true>(m, vertices);
        if hit != 0 {
            improved |= best.offer(hit, t, u, v, back, leaf.ids[k]);
        }
    }
    improved
}

/// [`test_leaf_lanes`] one lane at a time: each lane of `m` against all the triangles
/// `tris` of the leaf at once, one per SIMD lane, straight from the leaf's structure of
/// arrays ([`Packet::lane_test`]: for each triangle the very values the packet's test
/// computes for that lane; the scalar kernel where an edge function is exactly zero, as
/// there). Each lane keeps the least `(t, triangle)` of its hits and its closest so far,
/// which is what offering the hits in slot order gives. One test per lane instead of one
/// per triangle, for the leaves where a packet's lanes part: on the dragon's primary rays
/// 1.7 leaves a packet, 3.6 lanes and 3.1 triangles each after the culling, 0.8 of them
/// entered by fewer lanes than triangles. Measured against the packet's test of every
/// triangle (AMD EPYC Zen 5, AVX-512, one thread, `ray_contest --kind primary
/// --packets-only --rounds 25`, the two interleaved round by round in one process, medians
/// of the per-round ratios; the host was noisy, single rounds' ratios spread over 0.8 to
/// 1.2): the dragon 0.94 (0.93 to 0.95 in four runs), the far bunny 0.98, the near bunny
/// 0.98, Sponza 0.99, the teaser 0.98, the horses 1.00 and 1.01. Other rules measured the
/// same within the noise (at most two lanes, at most three, lanes at most the triangles);
/// confirming each lane's candidates with the packet's test, as the any-hit lone-lane test
/// does (it must apply the alpha test), kept only half the gain (the dragon 0.99 and 0.98).
#[inline(always)]
fn test_leaf_each_lane<L: Lanes>(p: &Packet<L>, best: &mut ClosestLanes<L>, leaf: &WideLeaf, m: u32, tris: u32) -> u32 {
    let mut v = [[L::splat(0.0); 3]; 3];
    for (vertex, rows) in v.iter_mut().zip(&leaf.v) {
        for (axis, row) in vertex.iter_mut().zip(rows) {
            *axis = L::load(row);
        }
    }
    let mut improved = 0;
    let mut lanes = m;
    while lanes != 0 {
        let lane = lanes.trailing_zeros() as usize;
        lanes &= lanes - 1;
        let h = p.lane_test(lane, &v, tris);
        let mut slots = h.hit | h.exact;
        if slots == 0 {
            continue;
        }
        let (t, u, w, det) = (L::store(h.t), L::store(h.u), L::store(h.v), L::store(h.det));
        let mut closest = best.lane(lane);
        let mut changed = false;
        while slots != 0 {
            let k = slots.trailing_zeros() as usize;
            slots &= slots - 1;
            let hit = if h.exact >> k & 1 != 0 {
                p.scalar_lane(lane, [leaf.vertex(0, k), leaf.vertex(1, k), leaf.vertex(2, k)])
            } else {
                Some(TriangleHit { t: t[k], u: u[k], v: w[k], back_face: p.lane_back_face(lane, det[k]) })
            };
            if let Some(hit) = hit {
                changed |= closest.take_if_closer(leaf.ids[k], hit);
            }
        }
        if changed {
            best.set_lane(lane, closest);
            improved |= 1 << lane;
        }
    }
    improved
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lanes::Portable;
    use glam::Vec3;
    use hyrt_core::formats::RayRecord;
    use proptest::prelude::*;

    fn ray(o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> RayRecord {
        RayRecord { origin: o.into(), t_min, direction: d.into(), t_max, ..bytemuck::Zeroable::zeroed() }
    }

    /// A wide node of eight boxes `(centre, half extent)`, the last `8 - count` unused
    /// (the empty box, as `WideBvh` stores them).
    fn node(boxes: &[(Vec3, Vec3)], count: usize) -> WideNode {
        let mut n = WideNode::empty(count as u32);
        for (k, (c, h)) in boxes.iter().take(count).enumerate() {
            for a in 0..3 {
                n.lo[a][k] = c[a] - h[a];
                n.hi[a][k] = c[a] + h[a];
            }
        }
        n
    }

    fn vec3(r: f32) -> impl Strategy<Value = Vec3> {
        (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

        /// The frustum test never rejects a child that some valid lane's own box test
        /// (`Packet::enter`, the scalar slab test lane by lane) enters, under any far
        /// bound up to the lanes' greatest: what makes the coherent packets' results the
        /// scalar reference's. Packets of nearby origins and directions (coherent enough
        /// for `Frustum::new`), boxes around and along the rays, touching planes included
        /// (box faces through an origin).
        #[test]
        fn frustum_keeps_every_child_a_lane_enters(
            o in vec3(4.0),
            d in vec3(1.0),
            jitter in prop::collection::vec((vec3(1.0), vec3(1.0)), LANES),
            spread in prop::sample::select(vec![0.0f32, 1e-4, 1e-2]),
            turn in prop::sample::select(vec![0.0f32, 1e-3, 0.05]),
            boxes in prop::collection::vec((0.0f32..12.0, vec3(3.0), vec3(1.5)), LANES),
            count in 1usize..=LANES,
            bounded in prop::bool::ANY,
            far in 0.0f32..1.0,
        ) {
            prop_assume!(d.abs().min_element() > 0.05);
            let rays: Vec<RayRecord> = jitter
                .iter()
                .map(|&(jo, jd)| ray(o + jo * spread, d + jd * turn * d.abs(), 0.0, if bounded { 8.0 } else { f32::INFINITY }))
                .collect();
            let p = Packet::<Portable>::new(&rays).unwrap();
            let Some(f) = Frustum::<Portable>::new(&p, 100.0) else {
                // Declined (lanes of different signs): nothing to check.
                return Ok(());
            };
            // Boxes somewhere along the first ray, some with a face through its origin.
            let boxes: Vec<(Vec3, Vec3)> = boxes
                .iter()
                .enumerate()
                .map(|(k, &(t, off, h))| {
                    let c = o + d * t + off;
                    let h = h.abs() + Vec3::splat(1e-3);
                    if k % 3 == 0 { (o + h, h) } else { (c, h) }
                })
                .collect();
            let n = node(&boxes, count);
            // Far bounds: the lanes' own, and a nearer common one (as after hits). The entry
            // bounds come from the first test (pushed then), the pop test compares them
            // with the nearer bound later.
            let lanes_far = p.box_t_max;
            let hi = lane_range::<Portable>(lanes_far, p.valid_lanes).1;
            let (_, pushed_enter) = f.enter(&n, hi);
            let near = hi.min(far * 10.0);
            for (bound_hi, bound) in [(hi, lanes_far), (near, [near; LANES])] {
                let (mask, _) = f.enter(&n, bound_hi);
                for (k, &entry) in pushed_enter.iter().enumerate().take(count) {
                    let lanes = p.enter(&child_box(&n, k), bound) & p.valid;
                    if lanes != 0 {
                        prop_assert!(mask >> k & 1 != 0, "child {k} entered by lanes {lanes:08b}, rejected by the frustum");
                        // The pop test (`t_enter > t_far_hi` skips) keeps it.
                        prop_assert!(entry <= bound_hi, "child {k} entered by lanes {lanes:08b}, skipped when popped");
                    }
                }
                prop_assert_eq!(mask >> count, 0, "unused children are never entered");
            }
        }
    }

    /// Eight copies of one ray: the frustum is that ray, and its test enters exactly the
    /// children the ray enters.
    #[test]
    fn a_packet_of_one_ray_is_tested_exactly() {
        let r = ray(Vec3::new(0.1, 0.2, -3.0), Vec3::new(0.05, -0.02, 1.0), 0.0, f32::INFINITY);
        let rays = [r; LANES];
        let p = Packet::<Portable>::new(&rays).unwrap();
        let f = Frustum::<Portable>::new(&p, 100.0).unwrap();
        let boxes: Vec<(Vec3, Vec3)> =
            (0..LANES).map(|k| (Vec3::new(k as f32 * 0.3 - 1.0, 0.0, k as f32), Vec3::splat(0.2))).collect();
        let n = node(&boxes, LANES);
        let t_far = lane_range::<Portable>(p.box_t_max, p.valid_lanes).1;
        let (mask, _) = f.enter(&n, t_far);
        let want = (0..LANES).filter(|&k| p.enter(&child_box(&n, k), p.box_t_max) != 0).fold(0, |m, k| m | 1 << k);
        assert_eq!(mask, want);
        assert!(want != 0 && want != (1 << LANES) - 1, "the case enters some children, not all: {want:08b}");
    }

    /// Packets whose origins lie far apart (a depth discontinuity between neighbouring
    /// pixels) or whose directions differ in sign are declined.
    #[test]
    fn incoherent_packets_are_declined() {
        let d = Vec3::new(0.3, 1.0, 0.2);
        let mut rays = [ray(Vec3::ZERO, d, 0.0, 1.0); LANES];
        assert!(Frustum::<Portable>::new(&Packet::<Portable>::new(&rays).unwrap(), 100.0).is_some());
        rays[3].origin = [0.5, 0.0, 0.0];
        assert!(Frustum::<Portable>::new(&Packet::<Portable>::new(&rays).unwrap(), 100.0).is_none());
        rays[3].origin = [0.0; 3];
        rays[5].direction = [-0.3, 1.0, 0.2];
        assert!(Frustum::<Portable>::new(&Packet::<Portable>::new(&rays).unwrap(), 100.0).is_none());
    }

    /// A packet of rays from one point in two clusters, toward opposite corners of a fine
    /// grid (as a list of active pixels jumping from the end of one pixel row to the start
    /// of the next): its frustum spans the grid between them, which no lane enters, so
    /// the walk gives up after [`MAX_IDLE_LEAF_BOXES`] idle leaf boxes and writes nothing
    /// (the caller traces the packet in the binary walk). A packet toward neighbouring
    /// points finishes, with the scalar reference's hits.
    #[test]
    fn a_packet_parted_in_two_gives_up_and_a_coherent_one_finishes() {
        use hyrt_core::bvh::BvhPreset;
        use hyrt_core::geometry::WorldGeometry;
        use hyrt_core::scene::{Material, Mesh, RenderMode, Scene};
        let mut scene = Scene::default();
        let grid = glam::Mat4::from_scale(Vec3::new(10.0, 1.0, 10.0));
        scene.add_object(Mesh::grid("grid", 128), Material::grey(), grid, RenderMode::RayTraced);
        let g = WorldGeometry::build(&scene);
        let bvh = Bvh::build(&g, BvhPreset::default());
        assert!(!bvh.wide.is_empty());
        let eye = Vec3::new(0.0, 1.0, 0.0);
        let walk = |targets: [Vec3; LANES]| {
            let rays = targets.map(|p| ray(eye, p - eye, 0.0, f32::INFINITY));
            let p = Packet::<Portable>::new(&rays).unwrap();
            let f = Frustum::<Portable>::new(&p, scene_extent(&bvh)).expect("one origin, one octant");
            let mut out = [None; LANES];
            let done = closest_hit::<Portable, ANY_OCTANT>(
                &bvh,
                &SurfaceView::default(),
                &p,
                &f,
                &mut super::super::single::new_stack(),
                &mut out,
            );
            (done, rays, out)
        };
        // Both clusters in the octant of +x, -y, +z from the eye.
        let parted: [Vec3; LANES] = std::array::from_fn(|k| {
            let (base, step) = if k < 4 { (0.3, 0.01) } else { (4.6, -0.01) };
            Vec3::new(base + step * k as f32, 0.0, base + 0.002 * k as f32)
        });
        let (done, _, out) = walk(parted);
        assert!(!done, "the frustum walk gives up on the parted packet");
        assert!(out.iter().all(Option::is_none), "a packet given up writes nothing");
        let coherent: [Vec3; LANES] = std::array::from_fn(|k| Vec3::new(2.0 + 0.01 * k as f32, 0.0, 2.0));
        let (done, rays, out) = walk(coherent);
        assert!(done, "the frustum walk finishes the coherent packet");
        for (r, h) in rays.iter().zip(out) {
            let want = bvh.closest_hit(g.stored_table(), r).expect("every ray hits the grid");
            let h = h.expect("the packet finds it");
            assert_eq!(
                (h.triangle, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()),
                (want.triangle, want.t.to_bits(), want.u.to_bits(), want.v.to_bits())
            );
        }
    }
}
