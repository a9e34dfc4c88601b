//! A wide view of the binary [`super::Bvh`] for the CPU's SIMD traversals: the same boxes
//! with up to [`WIDE`] children per node ([`WideNode`], the frustum packets' nodes: eight
//! child boxes against a packet's frustum at once), the same boxes again with up to
//! [`WIDE16`] children per node over the same leaves ([`WideNode16`], the single rays'
//! nodes: one ray against sixteen child boxes, two registers of eight lanes), and each
//! leaf's triangles as structure of arrays ([`WideLeaf`]: one ray against all of a leaf's
//! triangles at once).
//!
//! Built by collapsing the binary tree with the surface area heuristic, optimally for it
//! (Ylitie et al. 2017, "Efficient incoherent ray traversal on GPUs through compressed wide
//! BVHs", section 4): every child of a wide node is a binary node, either a wide node of
//! its own or a wide leaf (a binary subtree of at most [`WIDE`] triangles: its slots are
//! adjacent, the tree being depth first, and its triangles are tested in one go under its
//! root's box). A dynamic program over the binary tree, children before parents, gives
//! each subtree's least cost as at most `i` children of a wide node, `i` from 1 to
//! [`WIDE`]: a wide node costs its box's area, a wide leaf [`WIDE_LEAF_COST`] times its
//! box's area (the 8-lane leaf test costs the same for one triangle or eight); the root's
//! plan is then read back top down (`SahPlan`).
//!
//! It replaced a greedy collapse (Wald et al. 2008, "Getting rid of packets": each wide
//! node repeatedly opens its inner child of largest area, every subtree of at most
//! [`WIDE`] triangles one leaf), which merged subtrees whose triangles lie far apart into
//! one large leaf box and opened nodes by area alone: the plan's surface area cost is 2
//! to 10% lower on the test grids. Measured (AMD EPYC, one thread, `ray_contest`, medians
//! of 9 to 15 rounds, ms; the two collapses switched in one binary and alternated, then
//! the final binary against the previous one): the teaser's reflection and refraction
//! rays (single rays) 24.8 to 25.8 against 25.9 to 27.7 at AVX-512 (final binary: 26.0
//! against 26.7 to 26.9, three alternations; two threads, against Embree's best, 0.96 to
//! 1.01 against 0.95), 25.9 to 26.1 against 26.5 to 27.3 at AVX2; single-ray shadow rays:
//! the teaser 106.8 to 110.4 against 112.0 to 114.0, the near horse 7.95 to 8.02 against
//! 8.38 to 8.52, the dragon 87.6 to 88.1 against 86.3 to 86.7; primary rays (frustum
//! packets) within the noise, the dragon 40.9 to 41.4 against 42.1 to 42.8. The leaf cost
//! was measured from 0.6 to 2.5 ([`WIDE_LEAF_COST`]). The dynamic program (about 35 sums
//! per binary node) adds no measurable time to `bvh_build` (`hyrt render --frames 1
//! --threads 2`, three alternations: the dragon 676 to 774 ms against 663 to 689, Sponza
//! 41 to 45 against 41 to 54). Timed alone, one thread: 0.44 ms of the bunny's 2.1 ms
//! collapse (31,887 binary nodes; a deforming mesh pays it at every refit), 6.7 ms of the
//! dragon's 78 ms (423,265).
//!
//! Smaller wide leaves (with the greedy collapse: subtrees of at most 4 triangles merged
//! instead of 8, issue 36's "small leaves") measured slower for the single rays on this
//! 8-lane leaf test (AMD EPYC, AVX2, one thread, `ray_contest --singles-only`, the two
//! alternated three times on a noisy host): the dragon's shadow rays 197 to 212 ms against
//! 170 to 212, the far bunny's 12.3 to 14.6 against 10.9 to 12.1; the teaser's reflection
//! rays within the noise. A 4-triangle leaf fills half the lanes of the test it costs.
//! Leaves storing only their used lanes, and child boxes quantized to bytes (nodes of two
//! lines), were measured too and not kept: see the single-ray walk's docs in `hyrt-cpu`
//! (`traversal::single`).
//!
//! The 16-wide nodes come from the same dynamic program with sixteen slots a node, whose
//! leaves are given: exactly the 8-wide view's leaves, never opened, so both node sets
//! share one copy of the leaves. Their surface area cost is at most the 8-wide nodes'
//! (those are one of the plans it weighs). The single rays walk them because the walk is
//! bound by the chain from node to node and the branches on it, not by the box tests: the
//! teaser's reflection and refraction rays visit 10.1 nodes each instead of 13.5 (4 wide:
//! 20.5), for the same 3.7 leaves, and run about 5% faster at AVX-512 (see the single-ray
//! walk's docs in `hyrt-cpu`). Building them adds 3 to 7% to `bvh_build` (`hyrt render
//! --frames 1 --threads 2`, three alternations: the dragon 673 to 695 ms against 643 to
//! 679, the near bunny 35.5 to 37.4 against 33.5 to 35.5).
//!
//! Children keep the binary tree's depth-first order, and wide nodes are numbered depth
//! first, so the layout keeps the binary tree's locality. No box is recomputed: every
//! child box is a binary node's box, bit for bit, and every leaf slot is in exactly one
//! wide leaf. The GPU walks the binary tree; this view never leaves the CPU.
//!
//! Skipping the intermediate binary boxes (and testing a merged leaf's triangles under
//! one box) changes which boxes a ray is tested against, never which triangles can be its
//! result: culling stays conservative (a box is skipped only when the ray's widened
//! interval misses it, [`BVH_CULL_SLACK`](super::BVH_CULL_SLACK)), and closest hits
//! resolve ties by the lower triangle index, so the traversal finds the scalar
//! reference's closest hit in any visiting order (the one rounding corner case of
//! `BVH_CULL_SLACK` aside, as for the packets).

use bytemuck::{Pod, Zeroable};

use super::Bvh;
use crate::formats::{BvhNode, BVH_MAX_LEAF_SIZE};

/// Children per wide node: one AVX2 register of box distances.
pub const WIDE: usize = 8;

/// A child reference with this bit set is a leaf (see [`WideNode::child`]).
pub const WIDE_LEAF_BIT: u32 = 1 << 31;
/// Bits of the leaf index in a leaf reference; a tree with more leaves has no wide view.
pub const WIDE_LEAF_INDEX_BITS: u32 = 28;
const INDEX_MASK: u32 = (1 << WIDE_LEAF_INDEX_BITS) - 1;
const _: () = assert!(BVH_MAX_LEAF_SIZE as usize <= 1 << (31 - WIDE_LEAF_INDEX_BITS));
const _: () = assert!(BVH_MAX_LEAF_SIZE as usize <= WIDE);

/// The cost of a wide leaf per unit of box area, relative to a wide node's, in the
/// collapse's surface area heuristic: 1, one 8-lane leaf test (five cache lines) costing
/// about a node test (four). Measured on the teaser's reflection rays (AMD EPYC, one
/// thread, `ray_contest --singles-only --kind bounce`): flat from 0.6 to 1.2 (25.3 to 25.8
/// ms), 2.5 slower (25.7 to 27.6).
pub const WIDE_LEAF_COST: f32 = 1.0;

/// One wide node: the boxes of up to [`WIDE`] children as structure of arrays, and their
/// references.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `lo` | [[f32; 8]; 3] | box minimum of each child, by axis (x, y, z) |
/// | 96 | `hi` | [[f32; 8]; 3] | box maximum of each child, by axis |
/// | 192 | `child` | [u32; 8] | inner: index of a wide node; leaf: [`WIDE_LEAF_BIT`], triangle count - 1 in bits 28..31, index into [`WideBvh::leaves`] in bits 0..28 |
/// | 224 | `count` | u32 | children in use (the first `count`; 1 to 8) |
/// | 228 | `pad` | [u32; 7] | zero |
///
/// 256 bytes, four cache lines. Unused children have the empty box (`lo = +inf`,
/// `hi = -inf`), which no slab test enters, and reference 0.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct WideNode {
    pub lo: [[f32; WIDE]; 3],
    pub hi: [[f32; WIDE]; 3],
    pub child: [u32; WIDE],
    pub count: u32,
    pub pad: [u32; 7],
}
const _: () = assert!(std::mem::size_of::<WideNode>() == 256);

impl WideNode {
    /// A node of `count` children with every slot empty: the empty box (`lo = +inf`,
    /// `hi = -inf`), which no slab test enters, and reference 0. The form of unused slots.
    pub fn empty(count: u32) -> Self {
        WideNode {
            lo: [[f32::INFINITY; WIDE]; 3],
            hi: [[f32::NEG_INFINITY; WIDE]; 3],
            child: [0; WIDE],
            count,
            pad: [0; 7],
        }
    }
}

/// Children per node of the single-ray walks' nodes ([`WideNode16`]): two registers of
/// eight lanes.
pub const WIDE16: usize = 2 * WIDE;

/// Entries of a single-ray traversal stack over the [`WideNode16`] nodes (and over the
/// 8-wide nodes, which need fewer): a level consumes at least one binary level, and
/// visiting a node leaves at most `WIDE16 - 1` more entries than it took.
pub const WIDE16_STACK_SIZE: usize = (WIDE16 - 1) * super::BVH_STACK_SIZE + 1;

/// One node of the single-ray walks: the boxes of up to [`WIDE16`] children as structure
/// of arrays, each row in two halves of eight lanes, and their references. Its children
/// are [`WideNode16`]s and the leaves of [`WideBvh::leaves`].
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `lo` | [[[f32; 8]; 2]; 3] | box minimum of child `8 h + k` at `lo[axis][h][k]` |
/// | 192 | `hi` | [[[f32; 8]; 2]; 3] | box maximum, the same way |
/// | 384 | `child` | [u32; 16] | inner: index into [`WideBvh::nodes16`]; leaf: as [`WideNode::child`] |
/// | 448 | `count` | u32 | children in use (the first `count`; 1 to 16) |
/// | 452 | `pad` | [u32; 15] | zero |
///
/// 512 bytes, eight cache lines. Unused children have the empty box and reference 0, as
/// in [`WideNode`].
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct WideNode16 {
    pub lo: [[[f32; WIDE]; 2]; 3],
    pub hi: [[[f32; WIDE]; 2]; 3],
    pub child: [u32; WIDE16],
    pub count: u32,
    pub pad: [u32; 15],
}
const _: () = assert!(std::mem::size_of::<WideNode16>() == 512);

impl WideNode16 {
    /// A node of `count` children with every slot empty, as [`WideNode::empty`].
    pub fn empty(count: u32) -> Self {
        WideNode16 {
            lo: [[[f32::INFINITY; WIDE]; 2]; 3],
            hi: [[[f32::NEG_INFINITY; WIDE]; 2]; 3],
            child: [0; WIDE16],
            count,
            pad: [0; 15],
        }
    }

    /// Axis `a`'s near and far plane rows (both halves) for a ray whose inverse direction
    /// on that axis is negative (`negative`: the maxima are the near planes) or not. Field
    /// reads, with no run-time check, for the single-ray walks' node test.
    #[inline(always)]
    pub fn near_far(&self, a: usize, negative: bool) -> (&[[f32; WIDE]; 2], &[[f32; WIDE]; 2]) {
        if negative {
            (&self.hi[a], &self.lo[a])
        } else {
            (&self.lo[a], &self.hi[a])
        }
    }
}

/// The triangles of one binary leaf, lane `k` holding its `k`-th slot (`first + k`), as
/// structure of arrays for a one-ray, eight-triangle test.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `v` | [[[f32; 8]; 3]; 3] | `v[i][a][k]`: coordinate `a` of vertex `v_i` of the lane's triangle, the bits of `Bvh::leaf_triangles` |
/// | 288 | `ids` | [u32; 8] | the lane's global triangle index (`Bvh::prim_indices`) |
///
/// 320 bytes, five cache lines. Lanes past the leaf's count hold NaN vertices and
/// `INVALID_ID`; the count travels in the reference.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct WideLeaf {
    pub v: [[[f32; WIDE]; 3]; 3],
    pub ids: [u32; WIDE],
}
const _: () = assert!(std::mem::size_of::<WideLeaf>() == 320);

/// A decoded child reference.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WideChild {
    /// A wide node's index.
    Node(u32),
    /// A leaf: its index in [`WideBvh::leaves`] and its triangle count (1 to 8).
    Leaf { leaf: u32, count: u32 },
}

impl WideChild {
    /// Decode a reference of [`WideNode::child`].
    #[inline(always)]
    pub fn decode(r: u32) -> WideChild {
        if r & WIDE_LEAF_BIT == 0 {
            WideChild::Node(r)
        } else {
            WideChild::Leaf { leaf: r & INDEX_MASK, count: ((r >> WIDE_LEAF_INDEX_BITS) & 7) + 1 }
        }
    }

    /// Encode; `None` for an index that does not fit.
    fn encode(self) -> Option<u32> {
        match self {
            WideChild::Node(i) => (i & WIDE_LEAF_BIT == 0).then_some(i),
            WideChild::Leaf { leaf, count } => {
                let fits = leaf <= INDEX_MASK && (1..=BVH_MAX_LEAF_SIZE).contains(&count);
                fits.then(|| WIDE_LEAF_BIT | ((count - 1) << WIDE_LEAF_INDEX_BITS) | leaf)
            }
        }
    }
}

/// The wide view of a binary tree: nodes, root first, and leaves in the order the
/// collapse reaches them. Empty when the binary tree is empty, or too large to encode
/// (more than 2^28 leaves or 2^31 nodes); traversals then use the binary tree.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WideBvh {
    pub nodes: Vec<WideNode>,
    pub leaves: Vec<WideLeaf>,
    /// The first slot of each leaf (its binary leaf's `left_or_first`).
    pub first_slots: Vec<u32>,
    /// The same leaves under nodes of up to [`WIDE16`] children, root first: the tree the
    /// single-ray walks take (see the module docs). Empty with `nodes`.
    pub nodes16: Vec<WideNode16>,
}

impl WideLeaf {
    /// The leaf of `count` slots from `first`.
    fn new(bvh: &Bvh, first: u32, count: u32) -> WideLeaf {
        let mut leaf = WideLeaf { v: [[[f32::NAN; WIDE]; 3]; 3], ids: [crate::formats::INVALID_ID; WIDE] };
        for k in 0..count as usize {
            let slot = first as usize + k;
            let t = &bvh.leaf_triangles[slot];
            for (lanes, v) in leaf.v.iter_mut().zip([t.v0, t.v1, t.v2]) {
                for (lane, x) in lanes.iter_mut().zip(v) {
                    lane[k] = x;
                }
            }
            leaf.ids[k] = bvh.prim_indices[slot];
        }
        leaf
    }

    /// Vertex `i` of lane `k`.
    #[inline]
    pub fn vertex(&self, i: usize, k: usize) -> [f32; 3] {
        [self.v[i][0][k], self.v[i][1][k], self.v[i][2][k]]
    }
}

/// The leaf slots of every binary node's subtree as `(first, count)`: a leaf's own, an
/// inner node's children's when they are adjacent (left first), else `None`. The flattened
/// trees of `Bvh::build` are depth first, so every subtree's slots are adjacent.
fn subtree_slots(nodes: &[BvhNode]) -> Vec<Option<(u32, u32)>> {
    let mut ranges = vec![None; nodes.len()];
    // Children follow their parents: reverse order visits children first.
    for (i, n) in nodes.iter().enumerate().rev() {
        ranges[i] = if n.is_leaf() {
            Some((n.left_or_first, n.count))
        } else {
            let l = n.left_or_first as usize;
            match (ranges.get(l).copied().flatten(), ranges.get(l + 1).copied().flatten()) {
                (Some((a, m)), Some((b, k))) if a + m == b => Some((a, m + k)),
                _ => None,
            }
        };
    }
    ranges
}

/// Which binary subtrees may become wide leaves in a [`SahPlan`].
enum LeafRule<'a> {
    /// Any subtree of at most [`WIDE`] triangles, when that costs less (the 8-wide view).
    Fits,
    /// Exactly the binary nodes marked: each is a leaf and is never opened (the 16-wide
    /// nodes over the 8-wide view's leaves).
    Given(&'a [bool]),
}

/// The collapse's plan (see the module docs): for every binary node `b` and slot count `i`
/// (1 to `W`), the least cost of `b`'s subtree as at most `i` children of a `W`-wide node,
/// and how it is reached.
struct SahPlan<const W: usize> {
    /// `cost[b][i - 1]`.
    cost: Vec<[f32; W]>,
    /// `split[b][i - 1]`: 0 for `b` itself as one child (see `leaf`), else `j`: `b`'s left
    /// binary child as at most `j` children and its right one as at most `i - j`.
    split: Vec<[u8; W]>,
    /// `b` as one child: a wide leaf (true), or a wide node whose `W` slots go
    /// `inner[b]` to the left binary child and the rest to the right one.
    leaf: Vec<bool>,
    inner: Vec<u8>,
}

impl<const W: usize> SahPlan<W> {
    /// The plan of `nodes` (children after their parents), `ranges` their subtrees' slots
    /// ([`subtree_slots`]), a wide leaf costing `leaf_cost` times its area, leaves as
    /// `rule` allows.
    fn new(nodes: &[BvhNode], ranges: &[Option<(u32, u32)>], leaf_cost: f32, rule: LeafRule<'_>) -> Self {
        let n = nodes.len();
        let mut p =
            SahPlan { cost: vec![[0.0; W]; n], split: vec![[0; W]; n], leaf: vec![false; n], inner: vec![0; n] };
        for b in (0..n).rev() {
            // Boxes of giant extent overflow the area (an infinite or, flat, a NaN product):
            // their costs are infinite and the plan still valid, if not the best.
            let area = half_area(&nodes[b]);
            let area = if area.is_nan() { f32::INFINITY } else { area };
            let given = match rule {
                LeafRule::Fits => None,
                LeafRule::Given(leaves) => Some(leaves[b]),
            };
            if nodes[b].is_leaf() || given == Some(true) {
                // A binary leaf under a given leaf is never reached; one that is not
                // under one cannot be (the given leaves cover every slot).
                p.cost[b] = [if given == Some(false) { f32::INFINITY } else { leaf_cost * area }; W];
                p.leaf[b] = true;
                continue;
            }
            let (l, r) = (nodes[b].left_or_first as usize, nodes[b].left_or_first as usize + 1);
            let (cl, cr) = (p.cost[l], p.cost[r]);
            // The best split of `i` slots between the two children: (cost, left share).
            let best = |i: usize| {
                let mut best = (cl[0] + cr[i - 2], 1);
                for j in 2..i {
                    let c = cl[j - 1] + cr[i - j - 1];
                    if c < best.0 {
                        best = (c, j);
                    }
                }
                best
            };
            let (below, j) = best(W);
            let node = area + below;
            let fits = given.is_none() && ranges[b].is_some_and(|(_, count)| count as usize <= WIDE);
            let leaf = if fits { leaf_cost * area } else { f32::INFINITY };
            let one = leaf.min(node);
            p.leaf[b] = fits && leaf <= node;
            p.inner[b] = j as u8;
            p.cost[b][0] = one;
            for i in 2..=W {
                let (c, j) = best(i);
                (p.cost[b][i - 1], p.split[b][i - 1]) = if c < one { (c, j as u8) } else { (one, 0) };
            }
        }
        p
    }

    /// The children of the wide node made of binary node `b`, in depth-first order, each
    /// with whether it is a leaf. A root that is a wide leaf makes a wide root with one
    /// child.
    fn children(&self, nodes: &[BvhNode], b: usize) -> Vec<(usize, bool)> {
        if self.leaf[b] {
            return vec![(b, true)];
        }
        let mut out = Vec::with_capacity(W);
        let l = nodes[b].left_or_first as usize;
        let j = self.inner[b] as usize;
        self.emit(nodes, l, j, &mut out);
        self.emit(nodes, l + 1, W - j, &mut out);
        out
    }

    /// The children that binary node `b` becomes with at most `i` slots.
    fn emit(&self, nodes: &[BvhNode], b: usize, i: usize, out: &mut Vec<(usize, bool)>) {
        match self.split[b][i - 1] as usize {
            0 => out.push((b, self.leaf[b])),
            j => {
                let l = nodes[b].left_or_first as usize;
                self.emit(nodes, l, j, out);
                self.emit(nodes, l + 1, i - j, out);
            }
        }
    }
}

/// Surface area of a binary node's box (half of it: only compared).
fn half_area(n: &BvhNode) -> f32 {
    box_half_area(n.min(), n.max())
}

/// Half the surface area of the box from `lo` to `hi`.
fn box_half_area(lo: glam::Vec3, hi: glam::Vec3) -> f32 {
    let e = hi - lo;
    e.x * e.y + e.y * e.z + e.z * e.x
}

/// The 16-wide nodes over the wide leaves `leaf_refs` (each binary node made a wide leaf,
/// with its reference): the same dynamic program with [`WIDE16`] slots and exactly those
/// leaves, read back depth first. `None` if the plan made a leaf of another node (it
/// cannot: the given leaves are never opened).
fn collapse16(nodes: &[BvhNode], ranges: &[Option<(u32, u32)>], leaf_refs: &[Option<u32>]) -> Option<Vec<WideNode16>> {
    let given: Vec<bool> = leaf_refs.iter().map(Option::is_some).collect();
    let plan = SahPlan::<WIDE16>::new(nodes, ranges, WIDE_LEAF_COST, LeafRule::Given(&given));
    read_back(nodes, &plan, |c, leaf| match (leaf_refs[c], leaf) {
        (Some(r), true) => Some(Some(r)),
        (None, false) => Some(None),
        _ => None,
    })
}

/// The nodes of `plan` over the binary `nodes`, root first, depth first (a node's first
/// child's subtree right after it). Each child `c` of a node goes to `leaf(c, the plan
/// makes it a leaf)`: `Some(Some(reference))` for a wide leaf, `Some(None)` for a node of
/// its own (numbered in that order), `None` to give up (then `None`).
fn read_back<N: NodeView, const W: usize>(
    nodes: &[BvhNode],
    plan: &SahPlan<W>,
    mut leaf: impl FnMut(usize, bool) -> Option<Option<u32>>,
) -> Option<Vec<N>> {
    const { assert!(N::WIDTH == W, "a plan of the nodes' width") };
    let mut out = vec![N::zeroed()];
    // (binary node, wide node to fill), depth first.
    let mut todo = vec![(0usize, 0usize)];
    while let Some((b, w)) = todo.pop() {
        let children = plan.children(nodes, b);
        let mut node = N::empty(children.len() as u32);
        let mut inner = Vec::new();
        for (k, &(c, is_leaf)) in children.iter().enumerate() {
            let r = match leaf(c, is_leaf)? {
                Some(r) => r,
                None => {
                    let index = out.len() + inner.len();
                    inner.push((c, index));
                    index as u32
                }
            };
            node.set_slot(k, &nodes[c], r);
        }
        out[w] = node;
        out.resize(out.len() + inner.len(), N::zeroed());
        // Depth first: the first child's subtree next.
        todo.extend(inner.into_iter().rev());
    }
    Some(out)
}

impl WideBvh {
    /// Bytes held by the view: both sets of nodes, the leaves and their first slots.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(self.nodes.as_slice())
            + std::mem::size_of_val(self.nodes16.as_slice())
            + std::mem::size_of_val(self.leaves.as_slice())
            + std::mem::size_of_val(self.first_slots.as_slice())
    }

    /// Collapse `bvh`'s binary tree (see the module docs).
    pub fn collapse(bvh: &Bvh) -> WideBvh {
        let nodes = &bvh.nodes;
        if nodes.is_empty() || nodes.len() > INDEX_MASK as usize {
            return WideBvh::default();
        }
        let ranges = subtree_slots(nodes);
        let plan = SahPlan::<WIDE>::new(nodes, &ranges, WIDE_LEAF_COST, LeafRule::Fits);
        let (mut leaves, mut first_slots) = (Vec::new(), Vec::new());
        // The reference of each binary node made a wide leaf.
        let mut leaf_refs = vec![None; nodes.len()];
        let wide = read_back::<WideNode, WIDE>(nodes, &plan, |c, leaf| match ranges[c] {
            Some((first, count)) if leaf => {
                let r = WideChild::Leaf { leaf: leaves.len() as u32, count }.encode()?;
                leaves.push(WideLeaf::new(bvh, first, count));
                first_slots.push(first);
                Some(Some(*leaf_refs[c].insert(r)))
            }
            _ => Some(None),
        });
        let Some(wide) = wide else {
            return WideBvh::default();
        };
        let Some(nodes16) = collapse16(nodes, &ranges, &leaf_refs) else {
            return WideBvh::default();
        };
        WideBvh { nodes: wide, leaves, first_slots, nodes16 }
    }

    /// True if there is no wide view (use the binary tree).
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Check the view against its binary tree: the wide leaves partition the slots, each
    /// the slots of one binary subtree, with that subtree's box bit for bit and its
    /// triangles bit for bit; every wide node but the root is referenced once, after its
    /// parent, and its children's boxes lie inside its box there; unused children are
    /// empty.
    pub fn validate(&self, bvh: &Bvh) -> Result<(), String> {
        if self.nodes.is_empty() {
            return if bvh.nodes.is_empty() || bvh.nodes.len() > INDEX_MASK as usize {
                Ok(())
            } else {
                Err("no wide view of a non-empty tree".into())
            };
        }
        // Every binary subtree's slots and box.
        // A box as (min x, y, z, max x, y, z).
        let corners = |lo: [f32; 3], hi: [f32; 3]| [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]];
        let subtrees: std::collections::HashMap<(u32, u32), [u32; 6]> = subtree_slots(&bvh.nodes)
            .into_iter()
            .zip(&bvh.nodes)
            .filter_map(|(r, n)| r.map(|r| (r, corners(n.aabb_min, n.aabb_max).map(f32::to_bits))))
            .collect();
        let mut seen = Vec::new();
        // Each leaf's reference and box bits, as the 8-wide nodes give them.
        let mut leaf_refs = vec![None; self.leaves.len()];
        validate_nodes("wide", &self.nodes, |i, k, leaf, count, b| {
            let (Some(l), Some(&first)) = (self.leaves.get(leaf as usize), self.first_slots.get(leaf as usize)) else {
                return Err(format!("wide node {i}: leaf {leaf} out of range"));
            };
            if first as usize + count as usize > bvh.leaf_triangles.len()
                || bytemuck::bytes_of(l) != bytemuck::bytes_of(&WideLeaf::new(bvh, first, count))
            {
                return Err(format!("wide leaf {leaf} differs from slots {first}.. of the binary tree"));
            }
            if subtrees.get(&(first, count)) != Some(&b.map(f32::to_bits)) {
                return Err(format!("wide leaf {leaf}: no binary subtree with its slots and box"));
            }
            seen.push((first, count));
            leaf_refs[leaf as usize] = Some((self.nodes[i].child[k], b.map(f32::to_bits)));
            Ok(())
        })?;
        if seen.len() != self.leaves.len() || self.first_slots.len() != self.leaves.len() {
            return Err(format!("{} leaves referenced, {} stored", seen.len(), self.leaves.len()));
        }
        // The leaves partition the slots.
        seen.sort_unstable();
        let mut next = 0;
        for (first, count) in seen {
            if first != next {
                return Err(format!("slots {next}..{first} in no wide leaf, or in two"));
            }
            next = first + count;
        }
        if next as usize != bvh.leaf_triangles.len() {
            return Err(format!("slots {next}.. in no wide leaf"));
        }
        self.validate_nodes16(&leaf_refs)
    }

    /// The 16-wide nodes: every leaf referenced once, with the reference and the box the
    /// 8-wide nodes give it (`leaf_refs`), and [`validate_nodes`]' structure.
    fn validate_nodes16(&self, leaf_refs: &[Option<(u32, [u32; 6])>]) -> Result<(), String> {
        if self.nodes16.is_empty() {
            return Err("no 16-wide nodes".into());
        }
        let mut seen = vec![false; self.leaves.len()];
        validate_nodes("16-wide", &self.nodes16, |i, k, leaf, _, b| {
            let l = leaf as usize;
            if leaf_refs.get(l).copied().flatten() != Some((self.nodes16[i].child[k], b.map(f32::to_bits))) {
                return Err(format!("16-wide node {i}: child {k} is not leaf {leaf} as the 8-wide nodes give it"));
            }
            if std::mem::replace(&mut seen[l], true) {
                return Err(format!("16-wide nodes: leaf {leaf} referenced twice"));
            }
            Ok(())
        })?;
        if seen.iter().any(|s| !s) {
            return Err("a leaf is in no 16-wide node".into());
        }
        Ok(())
    }
}

/// A node of either set, as [`read_back`] writes it and [`validate_nodes`] reads it.
trait NodeView: Zeroable + Copy {
    /// Children slots.
    const WIDTH: usize;
    /// The node's own `empty`: `count` children, every slot empty.
    fn empty(count: u32) -> Self;
    /// Child `k`: binary node `n`'s box and the reference `r`.
    fn set_slot(&mut self, k: usize, n: &BvhNode, r: u32);
    /// Children in use.
    fn used(&self) -> u32;
    /// Child `k`'s box as (min x, y, z, max x, y, z).
    fn slot_box(&self, k: usize) -> [f32; 6];
    /// Child `k`'s reference.
    fn slot_ref(&self, k: usize) -> u32;
}

impl NodeView for WideNode {
    const WIDTH: usize = WIDE;
    fn empty(count: u32) -> Self {
        WideNode::empty(count)
    }
    fn set_slot(&mut self, k: usize, n: &BvhNode, r: u32) {
        for a in 0..3 {
            self.lo[a][k] = n.aabb_min[a];
            self.hi[a][k] = n.aabb_max[a];
        }
        self.child[k] = r;
    }
    fn used(&self) -> u32 {
        self.count
    }
    fn slot_box(&self, k: usize) -> [f32; 6] {
        [self.lo[0][k], self.lo[1][k], self.lo[2][k], self.hi[0][k], self.hi[1][k], self.hi[2][k]]
    }
    fn slot_ref(&self, k: usize) -> u32 {
        self.child[k]
    }
}

impl NodeView for WideNode16 {
    const WIDTH: usize = WIDE16;
    fn empty(count: u32) -> Self {
        WideNode16::empty(count)
    }
    fn set_slot(&mut self, k: usize, n: &BvhNode, r: u32) {
        let (h, j) = (k / WIDE, k % WIDE);
        for a in 0..3 {
            self.lo[a][h][j] = n.aabb_min[a];
            self.hi[a][h][j] = n.aabb_max[a];
        }
        self.child[k] = r;
    }
    fn used(&self) -> u32 {
        self.count
    }
    fn slot_box(&self, k: usize) -> [f32; 6] {
        let (h, j) = (k / WIDE, k % WIDE);
        [self.lo[0][h][j], self.lo[1][h][j], self.lo[2][h][j], self.hi[0][h][j], self.hi[1][h][j], self.hi[2][h][j]]
    }
    fn slot_ref(&self, k: usize) -> u32 {
        self.child[k]
    }
}

/// The structure both node sets share (`what` names the set in errors): every node but
/// the root is referenced once, after its parent, and its children's boxes lie inside its
/// box there; unused children have the empty box. Each leaf child goes to `leaf(node,
/// slot, leaf index, triangle count, its box)`.
fn validate_nodes<N: NodeView>(
    what: &str,
    nodes: &[N],
    mut leaf: impl FnMut(usize, usize, u32, u32, [f32; 6]) -> Result<(), String>,
) -> Result<(), String> {
    let mut referenced = vec![false; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        if !(1..=N::WIDTH as u32).contains(&n.used()) {
            return Err(format!("{what} node {i}: {} children", n.used()));
        }
        for k in 0..N::WIDTH {
            let b = n.slot_box(k);
            if k >= n.used() as usize {
                if b[..3].iter().any(|&x| x != f32::INFINITY) || b[3..].iter().any(|&x| x != f32::NEG_INFINITY) {
                    return Err(format!("{what} node {i}: unused child {k} has a box"));
                }
                continue;
            }
            match WideChild::decode(n.slot_ref(k)) {
                WideChild::Node(c) => {
                    let c = c as usize;
                    if c <= i || c >= nodes.len() || std::mem::replace(&mut referenced[c], true) {
                        return Err(format!("{what} node {i}: child {k} names node {c} badly"));
                    }
                    // Boxes nest: the child node's children lie in this child's box.
                    let m = &nodes[c];
                    let inside = (0..m.used() as usize).all(|j| {
                        let m = m.slot_box(j);
                        (0..3).all(|a| m[a] >= b[a] && m[3 + a] <= b[3 + a])
                    });
                    if !inside {
                        return Err(format!("{what} node {c} is not inside its box in node {i}"));
                    }
                }
                WideChild::Leaf { leaf: l, count } => leaf(i, k, l, count, b)?,
            }
        }
    }
    if referenced.iter().skip(1).any(|r| !r) {
        return Err(format!("a {what} node is not referenced"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::BvhPreset;
    use crate::formats::{TriangleRecord, TRI_RAY_TRACED};
    use crate::geometry::WorldGeometry;
    use glam::Vec3;

    /// `n` small triangles on a jittered grid of the plane z = 0 (and a few stacked in z).
    fn grid(n: usize) -> WorldGeometry {
        let (mut records, mut normals) = (Vec::new(), Vec::new());
        for i in 0..n {
            let (x, y, z) = ((i % 37) as f32, ((i / 37) % 23) as f32, (i / (37 * 23)) as f32);
            let o = Vec3::new(x * 1.1, y * 0.9 + 0.01 * x, z * 2.0);
            records.push(TriangleRecord {
                v0: o.into(),
                object: 0,
                v1: (o + Vec3::new(0.5, 0.0, 0.1)).into(),
                triangle: i as u32,
                v2: (o + Vec3::new(0.0, 0.5, 0.2)).into(),
                flags: TRI_RAY_TRACED,
            });
            normals.push([Vec3::Z; 3]);
        }
        WorldGeometry { triangles: crate::geometry::WorldTriangles::stored(records, normals), ..Default::default() }
    }

    #[test]
    fn near_far_rows_swap_with_the_direction_sign() {
        let mut node = WideNode16::zeroed();
        for a in 0..3 {
            for h in 0..2 {
                for k in 0..WIDE {
                    node.lo[a][h][k] = (100 * a + 10 * h + k) as f32;
                    node.hi[a][h][k] = -((100 * a + 10 * h + k) as f32) - 1.0;
                }
            }
        }
        for a in 0..3 {
            assert_eq!(node.near_far(a, false), (&node.lo[a], &node.hi[a]));
            assert_eq!(node.near_far(a, true), (&node.hi[a], &node.lo[a]));
        }
    }

    #[test]
    fn references_round_trip_and_reject_what_does_not_fit() {
        for c in [WideChild::Node(0), WideChild::Node(12345), WideChild::Leaf { leaf: 7, count: 1 }] {
            assert_eq!(WideChild::decode(c.encode().unwrap()), c);
        }
        let big = WideChild::Leaf { leaf: INDEX_MASK, count: BVH_MAX_LEAF_SIZE };
        assert_eq!(WideChild::decode(big.encode().unwrap()), big);
        assert_eq!((WideChild::Leaf { leaf: INDEX_MASK + 1, count: 1 }).encode(), None);
        assert_eq!((WideChild::Leaf { leaf: 0, count: 0 }).encode(), None);
        assert_eq!((WideChild::Leaf { leaf: 0, count: BVH_MAX_LEAF_SIZE + 1 }).encode(), None);
        assert_eq!(WideChild::Node(WIDE_LEAF_BIT).encode(), None);
    }

    /// Every preset, from one triangle (a leaf root) to a few thousand: the view validates
    /// against its tree, nodes are wide, a tree of at most `WIDE` triangles is one leaf,
    /// and the view's surface area cost is the plan's least cost, at most that of the
    /// greedy collapse it replaced (each node opening its inner child of largest area,
    /// every subtree of at most `WIDE` triangles one leaf).
    #[test]
    fn collapsed_views_validate_and_merge_small_subtrees() {
        for n in [1, 2, 7, 8, 9, 100, 3000] {
            let g = grid(n);
            for preset in BvhPreset::ALL {
                let bvh = Bvh::build(&g, preset);
                let wide = &bvh.wide;
                wide.validate(&bvh).unwrap_or_else(|e| panic!("{n} triangles, {preset:?}: {e}"));
                assert!(!wide.is_empty());
                let slots = bvh.leaf_triangles.len();
                if slots <= WIDE {
                    assert_eq!((wide.nodes.len(), wide.leaves.len()), (1, 1), "{n} triangles, {preset:?}");
                    assert_eq!(wide.nodes[0].count, 1);
                }
                let ranges = subtree_slots(&bvh.nodes);
                let plan = SahPlan::<WIDE>::new(&bvh.nodes, &ranges, WIDE_LEAF_COST, LeafRule::Fits);
                let (got, want) = (view_cost(&wide.nodes), plan.cost[0][0]);
                // The plan sums children first, the view node by node: rounding apart.
                let close = |a: f32, b: f32| (a - b).abs() <= 1e-4 * b.abs().max(1e-30);
                assert!(close(got, want), "{n} triangles, {preset:?}: view cost {got}, plan {want}");
                // The 16-wide nodes over the same leaves: their plan's cost, and at most the
                // 8-wide nodes' (those are one plan of at most 16 children a node).
                let got16 = view_cost(&wide.nodes16);
                assert!(got16 <= got * (1.0 + 1e-4), "{n} triangles, {preset:?}: 16-wide {got16} > 8-wide {got}");
                assert!(wide.nodes16.len() <= wide.nodes.len(), "{n} triangles, {preset:?}");
                let greedy = greedy_cost(&bvh);
                assert!(want <= greedy * (1.0 + 1e-4), "{n} triangles, {preset:?}: {want} > greedy {greedy}");
                if n == 3000 {
                    let children: u32 = wide.nodes.iter().map(|w| w.count).sum();
                    assert!(children as f32 / wide.nodes.len() as f32 > 3.0, "{preset:?}: narrow nodes");
                }
            }
        }
    }

    /// The surface area cost of a wide view's nodes (either set) as [`SahPlan`] counts it:
    /// each node but the root its box's area (the root's binary node's, summed over its
    /// children's planes here as the union), each leaf `WIDE_LEAF_COST` times its box's
    /// area.
    fn view_cost<N: NodeView>(nodes: &[N]) -> f32 {
        let area = box_half_area;
        let mut cost = 0.0;
        let mut todo = vec![(0usize, None)];
        while let Some((w, own)) = todo.pop() {
            let node = &nodes[w];
            let mut union = (Vec3::INFINITY, Vec3::NEG_INFINITY);
            for k in 0..node.used() as usize {
                let b = node.slot_box(k);
                let (lo, hi) = (Vec3::new(b[0], b[1], b[2]), Vec3::new(b[3], b[4], b[5]));
                union = (union.0.min(lo), union.1.max(hi));
                match WideChild::decode(node.slot_ref(k)) {
                    WideChild::Leaf { .. } => cost += WIDE_LEAF_COST * area(lo, hi),
                    WideChild::Node(c) => todo.push((c as usize, Some(area(lo, hi)))),
                }
            }
            // A wide root with one leaf child is that leaf; otherwise the root's own box.
            let leaf_root = node.used() == 1 && matches!(WideChild::decode(node.slot_ref(0)), WideChild::Leaf { .. });
            cost += own.unwrap_or(if leaf_root { 0.0 } else { area(union.0, union.1) });
        }
        cost
    }

    /// The cost of the greedy collapse the plan replaced.
    fn greedy_cost(bvh: &Bvh) -> f32 {
        let nodes = &bvh.nodes;
        let ranges = subtree_slots(nodes);
        let is_leaf = |b: usize| ranges[b].is_some_and(|(_, count)| count as usize <= WIDE);
        if is_leaf(0) {
            return WIDE_LEAF_COST * half_area(&nodes[0]);
        }
        let mut cost = 0.0;
        let mut todo = vec![0usize];
        while let Some(b) = todo.pop() {
            cost += half_area(&nodes[b]);
            let l = nodes[b].left_or_first as usize;
            let mut children = vec![l, l + 1];
            while children.len() < WIDE {
                let inner = children.iter().enumerate().filter(|&(_, &c)| !is_leaf(c));
                let best = inner.fold(None, |best: Option<(usize, f32)>, (k, &c)| {
                    let a = half_area(&nodes[c]);
                    if best.is_none_or(|(_, b)| a > b) {
                        Some((k, a))
                    } else {
                        best
                    }
                });
                let Some((k, _)) = best else { break };
                let l = nodes[children[k]].left_or_first as usize;
                children.splice(k..=k, [l, l + 1]);
            }
            for c in children {
                if is_leaf(c) {
                    cost += WIDE_LEAF_COST * half_area(&nodes[c]);
                } else {
                    todo.push(c);
                }
            }
        }
        cost
    }

    #[test]
    fn validation_catches_a_changed_box_leaf_or_reference() {
        let g = grid(500);
        let bvh = Bvh::build(&g, BvhPreset::default());
        let mut bad = bvh.clone();
        // A smaller box (a larger one is only slower, still conservative).
        bad.wide.nodes[0].lo[0][0] += 0.001;
        assert!(bad.wide.validate(&bvh).is_err());
        let mut bad = bvh.clone();
        bad.wide.leaves[3].v[1][2][0] += 1.0;
        assert!(bad.wide.validate(&bvh).is_err());
        let mut bad = bvh.clone();
        let k = (0..WIDE).find(|&k| matches!(WideChild::decode(bad.wide.nodes[0].child[k]), WideChild::Node(_)));
        bad.wide.nodes[0].child[k.unwrap()] = 0;
        assert!(bad.wide.validate(&bvh).is_err());
        // The 16-wide nodes: a box, a leaf named twice, a node not referenced.
        let mut bad = bvh.clone();
        bad.wide.nodes16[0].hi[1][0][0] -= 0.001;
        assert!(bad.wide.validate(&bvh).is_err());
        let mut bad = bvh.clone();
        let leaves: Vec<usize> = (0..WIDE16)
            .filter(|&k| matches!(WideChild::decode(bad.wide.nodes16[1].child[k]), WideChild::Leaf { .. }))
            .collect();
        assert!(leaves.len() >= 2, "a 16-wide node with two leaves");
        let n = &mut bad.wide.nodes16[1];
        n.child[leaves[1]] = n.child[leaves[0]];
        for a in 0..3 {
            let (h0, j0, h1, j1) = (leaves[0] / WIDE, leaves[0] % WIDE, leaves[1] / WIDE, leaves[1] % WIDE);
            (n.lo[a][h1][j1], n.hi[a][h1][j1]) = (n.lo[a][h0][j0], n.hi[a][h0][j0]);
        }
        assert!(bad.wide.validate(&bvh).is_err());
        let mut bad = bvh.clone();
        bad.wide.nodes16.push(WideNode16::zeroed());
        assert!(bad.wide.validate(&bvh).is_err());
        assert!(WideBvh::default().validate(&bvh).is_err());
        assert!(WideBvh::default().validate(&Bvh::default()).is_ok());
    }
}
