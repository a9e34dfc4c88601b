//! The one BVH traversal loop: depth first over the flattened [`Bvh`](super::Bvh) nodes
//! with a fixed stack of [`BVH_STACK_SIZE`] entries, generic over the node test (the ray
//! representation: [`NodeTest`]) and over the leaf test (a closure).
//!
//! Every traversal in hyrt runs this loop: any hit and closest hit of the scalar f32 ray
//! ([`Bvh::occluded`](super::Bvh::occluded), [`Bvh::closest_hit`](super::Bvh::closest_hit)),
//! the f64 reference of the accuracy harness, and the CPU backend's SIMD packets (a lane
//! mask per stack entry). Like obvhs' `traverse!`, the loop owns only the walk (root
//! test, the pair of children, which goes first, the stack, the pop test); what a ray is
//! and what a hit means belong to the caller:
//!
//! * [`NodeTest`]: how a ray enters a node's box given its parent's [`NodeTest::Entry`]
//!   (an entry distance, or the mask of lanes that entered the parent) and the current
//!   far [`NodeTest::Bound`], which child of a pair goes first, and whether a node popped
//!   from the stack is still worth visiting.
//! * The leaf test, `FnMut(Leaf, Entry, &mut Bound) -> LeafFlow`: tests the leaf's
//!   triangles ([`Leaf::slots`], in slot order from [`Leaf::start`]), narrows the bound
//!   (closest hit so far; lanes done) and says whether to go on ([`LeafFlow`]).
//!
//! The walk: a node whose box the ray enters is visited; at an inner node both children
//! are tested, and when both are entered the one [`NodeTest::right_first`] names is
//! visited next and the other pushed with its entry. When a leaf test narrows the bound,
//! the entries already on the stack were tested against the old bound and are *stale*:
//! [`NodeTest::resume`] is told so when they are popped, and re-tests (a scalar ray
//! compares the pushed entry distance with the bound, a packet re-tests the box).
//! Entries pushed after the last narrowing passed the current bound already.
//!
//! Where later features plug in:
//!
//! * Alpha test: a leaf test that, after the watertight test accepts a triangle, reads the
//!   material's alpha texture at the hit's barycentrics and drops the hit (neither taking
//!   it nor narrowing the bound) when the texel is transparent. Any hit then stops only on
//!   an opaque hit; nothing in the loop changes.
//! * Instancing: a leaf whose slots name instances (a BLAS and a transform) instead of
//!   triangles. Its leaf test transforms the ray into the instance's space (a new
//!   [`NodeTest`] value for the same ray kind, the bound carried over: `t` is preserved by
//!   an affine transform of origin and direction), calls [`traverse`] on the BLAS's nodes
//!   with a triangle leaf test, and returns [`LeafFlow::Narrowed`] when the BLAS traversal
//!   narrowed the bound (or [`LeafFlow::Stop`] when it stopped). The stack is per call, so
//!   the nesting costs one more stack frame of [`BVH_STACK_SIZE`] entries.

use std::iter::Chain;
use std::ops::Range;

use super::BVH_STACK_SIZE;
use crate::formats::BvhNode;

/// How a ray representation tests nodes during [`traverse`].
///
/// Implemented by the scalar f32 ray (in this module's parent), by the f64 reference ray
/// and by the CPU backend's packets. All methods are called in the loop's inner paths:
/// implementations should be `#[inline]` (the SIMD packets need `#[inline(always)]` to be
/// compiled with their caller's target features).
pub trait NodeTest {
    /// What entering a node yields, kept with a node on the stack and handed to the
    /// children's tests and to the leaf test: an entry distance, or the mask of the lanes
    /// that entered.
    type Entry: Copy;
    /// The far bound leaf tests narrow and node tests read: `t_max` or the closest hit so
    /// far, per ray or per lane, or the mask of lanes already done.
    type Bound;

    /// The test of the root node: `None` when the ray misses it (the traversal ends).
    fn enter_root(&self, root: &BvhNode, bound: &Self::Bound) -> Option<Self::Entry>;

    /// The test of a child `node` whose parent was entered with `parent`.
    fn enter(&self, node: &BvhNode, parent: Self::Entry, bound: &Self::Bound) -> Option<Self::Entry>;

    /// With both children entered: true to visit the right one first (the left one is then
    /// pushed), false for the left one.
    fn right_first(&self, left: &BvhNode, right: &BvhNode, left_entry: Self::Entry, right_entry: Self::Entry) -> bool;

    /// The test of a node popped from the stack, pushed with `pushed`: `None` to skip it.
    /// `stale` is true when a leaf test narrowed the bound since the node was pushed; when
    /// false, the node was entered under the current bound.
    fn resume(&self, node: &BvhNode, pushed: Self::Entry, bound: &Self::Bound, stale: bool) -> Option<Self::Entry>;
}

/// A leaf reached by the traversal: its node index and its slots (indices into
/// `Bvh::prim_indices` and `Bvh::leaf_triangles`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Leaf {
    /// Index of the leaf node in `Bvh::nodes`.
    pub node: u32,
    /// The leaf's first slot.
    pub first: u32,
    /// One past the leaf's last slot.
    pub end: u32,
    /// The slot [`Leaf::slots`] starts from: `first` during traversal; another slot of the
    /// leaf when a caller retests a known leaf starting at a known triangle (the packets'
    /// occluder cache).
    pub start: u32,
}

impl Leaf {
    /// Leaf node `index`, slots from the first.
    #[inline(always)]
    pub fn new(index: usize, node: &BvhNode) -> Leaf {
        debug_assert!(node.is_leaf());
        let first = node.left_or_first;
        Leaf { node: index as u32, first, end: first + node.count, start: first }
    }

    /// Leaf node `index`, slots from `start` (which must be one of them).
    #[inline(always)]
    pub fn starting_at(index: usize, node: &BvhNode, start: u32) -> Leaf {
        let leaf = Leaf { start, ..Leaf::new(index, node) };
        debug_assert!((leaf.first..leaf.end).contains(&start));
        leaf
    }

    /// Every slot of the leaf once: `start .. end`, then round to `first .. start` (just
    /// `first .. end` during traversal). Internal iteration (`for_each`, `any`, `try_for_each`)
    /// runs the two ranges as two plain loops.
    #[inline(always)]
    pub fn slots(&self) -> Chain<Range<u32>, Range<u32>> {
        (self.start..self.end).chain(self.first..self.start)
    }
}

/// What a leaf test tells the traversal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LeafFlow {
    /// Go on; the bound is unchanged.
    Continue,
    /// Go on; the bound was narrowed (nodes on the stack are stale).
    Narrowed,
    /// End the traversal now (any hit found; every lane done).
    Stop,
}

/// `leaf_test` itself. Rust accepts `#[inline(always)]` on a closure passed as an argument
/// but not on one bound with `let`: `let t = inline_leaf_test(#[inline(always)] |..| ..)`
/// gives a leaf test that can be named (called before [`traverse`] too) and is still
/// inlined. Leaf tests must be: a closure left out of line would be compiled without the
/// caller's target features (the packets' AVX2), and measured 3 to 5 times slower.
#[inline(always)]
pub fn inline_leaf_test<E, B, F: FnMut(Leaf, E, &mut B) -> LeafFlow>(leaf_test: F) -> F {
    leaf_test
}

/// Walk the tree `nodes` (root first; empty: nothing is visited) with the node test `ray`
/// and the far bound `bound`, calling `leaf` on every leaf entered, in the order the walk
/// reaches them (see the module docs). Returns true if a leaf test stopped the traversal.
///
/// The tree must be at most [`BVH_STACK_SIZE`] deep (`Bvh::build` guarantees it).
#[inline(always)]
pub fn traverse<R: NodeTest>(
    nodes: &[BvhNode],
    ray: &R,
    bound: &mut R::Bound,
    mut leaf: impl FnMut(Leaf, R::Entry, &mut R::Bound) -> LeafFlow,
) -> bool {
    let Some(root) = nodes.first() else {
        return false;
    };
    let Some(mut entry) = ray.enter_root(root, bound) else {
        return false;
    };
    let mut stack = [(0u32, entry); BVH_STACK_SIZE];
    let mut sp = 0usize;
    // Entries below this stack index were pushed before the last narrowing of the bound.
    let mut stale = 0usize;
    let mut n = 0usize;
    loop {
        let node = &nodes[n];
        if node.is_leaf() {
            match leaf(Leaf::new(n, node), entry, bound) {
                LeafFlow::Continue => {}
                LeafFlow::Narrowed => stale = sp,
                LeafFlow::Stop => return true,
            }
        } else {
            let l = node.left_or_first as usize;
            let (left, right) = (&nodes[l], &nodes[l + 1]);
            match (ray.enter(left, entry, bound), ray.enter(right, entry, bound)) {
                (Some(el), Some(er)) => {
                    let (near, far, e_near, e_far) =
                        if ray.right_first(left, right, el, er) { (l + 1, l, er, el) } else { (l, l + 1, el, er) };
                    stack[sp] = (far as u32, e_far);
                    sp += 1;
                    (n, entry) = (near, e_near);
                    continue;
                }
                (Some(el), None) => {
                    (n, entry) = (l, el);
                    continue;
                }
                (None, Some(er)) => {
                    (n, entry) = (l + 1, er);
                    continue;
                }
                (None, None) => {}
            }
        }
        // Pop the next node still worth visiting.
        loop {
            if sp == 0 {
                return false;
            }
            sp -= 1;
            let (next, pushed) = stack[sp];
            let is_stale = sp < stale;
            if is_stale {
                stale = sp;
            }
            if let Some(e) = ray.resume(&nodes[next as usize], pushed, bound, is_stale) {
                (n, entry) = (next as usize, e);
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leaf_slots_start_at_the_start_slot_and_wrap_round() {
        let node = BvhNode { aabb_min: [0.0; 3], left_or_first: 10, aabb_max: [1.0; 3], count: 4 };
        let all: Vec<u32> = Leaf::new(3, &node).slots().collect();
        assert_eq!(all, [10, 11, 12, 13]);
        let wrapped: Vec<u32> = Leaf::starting_at(3, &node, 12).slots().collect();
        assert_eq!(wrapped, [12, 13, 10, 11]);
        assert_eq!(Leaf::starting_at(3, &node, 12).node, 3);
    }

    /// A node test that enters every node and records nothing: the walk visits every leaf
    /// exactly once, left first, and an empty tree visits none.
    struct Everything;

    impl NodeTest for Everything {
        type Entry = ();
        type Bound = ();
        fn enter_root(&self, _: &BvhNode, _: &()) -> Option<()> {
            Some(())
        }
        fn enter(&self, _: &BvhNode, _: (), _: &()) -> Option<()> {
            Some(())
        }
        fn right_first(&self, _: &BvhNode, _: &BvhNode, _: (), _: ()) -> bool {
            false
        }
        fn resume(&self, _: &BvhNode, _: (), _: &(), _: bool) -> Option<()> {
            Some(())
        }
    }

    #[test]
    fn the_walk_reaches_every_leaf_in_depth_first_order_and_stops_on_request() {
        let inner = |left| BvhNode { aabb_min: [0.0; 3], left_or_first: left, aabb_max: [1.0; 3], count: 0 };
        let leaf = |first| BvhNode { aabb_min: [0.0; 3], left_or_first: first, aabb_max: [1.0; 3], count: 1 };
        // 0 -> (1, 2); 1 -> (3, 4); leaves 2, 3, 4 hold slots 2, 0, 1.
        let nodes = [inner(1), inner(3), leaf(2), leaf(0), leaf(1)];
        let mut seen = Vec::new();
        let stopped = traverse(&nodes, &Everything, &mut (), |l, _, _| {
            seen.push((l.node, l.first));
            LeafFlow::Continue
        });
        assert!(!stopped);
        assert_eq!(seen, [(3, 0), (4, 1), (2, 2)]);
        let mut count = 0;
        assert!(traverse(&nodes, &Everything, &mut (), |_, _, _| {
            count += 1;
            if count == 2 {
                LeafFlow::Stop
            } else {
                LeafFlow::Continue
            }
        }));
        assert_eq!(count, 2);
        assert!(!traverse(&[], &Everything, &mut (), |_, _, _| LeafFlow::Stop));
    }
}
