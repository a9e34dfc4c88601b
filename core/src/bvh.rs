//! The flattened, GPU-ready BVH over the world triangle table, and its reference
//! traversal.
//!
//! Built once per scene with [obvhs](https://github.com/DGriffin91/obvhs) (PLOC +
//! reinsertion + leaf collapse, optional spatial pre-splits), then flattened into two
//! storage buffers both backends read:
//!
//! * `nodes`: [`BvhNode`], 32 bytes each; node 0 is the root. Siblings are stored as
//!   adjacent pairs, so an inner node needs only the index of its left child.
//! * `prim_indices`: u32 global triangle indices into
//!   [`WorldGeometry::triangles`](crate::geometry::WorldGeometry::triangles), one per leaf
//!   *slot*. A leaf owns the slots `left_or_first .. left_or_first + count`; every slot
//!   belongs to exactly one leaf. With spatial pre-splits (presets [`BvhPreset::Slow`] and
//!   [`BvhPreset::VerySlow`]) one triangle may occupy slots in several leaves.
//! * `leaf_triangles`: [`TriangleRecord`]s in slot order, `leaf_triangles[s] ==
//!   triangles[prim_indices[s]]` bit for bit (same 48-byte record, so the GPU reuses the
//!   triangle table's WGSL struct). Traversal reads a leaf's triangles contiguously from
//!   here instead of through `prim_indices` (about 20% more shadow rays per second on
//!   the CPU); `prim_indices` is read only to report the global index of a hit. The
//!   vertices are copies of the triangle table's bits, so the raster, the BVH and
//!   reconstruction still see the same numbers.
//!
//! Both arrays are in depth-first order (left child first): children follow their parent
//! and leaf slots follow each other in the order a traversal reaches them.
//!
//! Only *traceable* triangles are in the tree ([`triangle_is_traceable`]): finite
//! vertices and no two equal vertices (such triangles have `det == 0` for every ray, see
//! [`crate::kernels::ray`], so leaving them out changes no result). A scene without
//! traceable triangles gives a BVH with no nodes; every query on it misses.
//!
//! Traversal ([`Bvh::occluded`], [`Bvh::closest_hit`]) runs the one traversal loop of
//! [`traversal`] (shared with the f64 reference and the CPU packets), which uses a fixed
//! stack of [`BVH_STACK_SIZE`] entries (no allocation per ray); the scalar ray visits the
//! nearer child first and calls the conservative slab test and the watertight triangle
//! test of [`crate::kernels::ray`]. The tree depth is bounded by the stack size: if obvhs
//! ever returns a deeper tree (pathological input), the build falls back to a balanced
//! object-median split whose depth is logarithmic.
//!
//! ```
//! use hyrt_core::{bvh::{Bvh, BvhPreset}, geometry::WorldGeometry, scene::Scene};
//! use hyrt_core::formats::{RayRecord, RAY_KIND_PRIMARY, INVALID_ID};
//! let geometry = WorldGeometry::build(&Scene::default_scene());
//! let bvh = Bvh::build(&geometry, BvhPreset::default());
//! bvh.validate(&geometry).unwrap();
//! let eye = Scene::default_scene().camera.unwrap().eye;
//! let ray = RayRecord {
//!     origin: eye.into(), t_min: 0.0, direction: (-eye).into(), t_max: f32::INFINITY,
//!     pixel: 0, kind: RAY_KIND_PRIMARY, depth: 0, light: INVALID_ID, throughput: [1.0; 3], cone: 0.0,
//! };
//! let hit = bvh.closest_hit(geometry.traversal_table(), &ray);
//! assert_eq!(hit.is_some(), bvh.occluded(geometry.traversal_table(), &ray));
//! ```

use std::time::Duration;

use bytemuck::Zeroable;
use glam::{Vec3, Vec3A};
use obvhs::{bvh2::builder::build_bvh2_from_tris, triangle::Triangle, BvhBuildParams};

use crate::formats::{RayRecord, TriangleRecord, INVALID_ID, TRI_ALPHA_TEST};
use crate::geometry::WorldGeometry;
use crate::kernels::ray::{gamma, ray_aabb_conservative, safe_inverse_dir, TriangleHit, WatertightRay};

pub mod traversal;
pub mod two_level;
pub mod wide;

use traversal::{inline_leaf_test, traverse, Leaf, LeafFlow, NodeTest};

/// The node record and its leaf size bound, defined with the other GPU records in
/// [`crate::formats`]; re-exported here, where the tree is built.
pub use crate::formats::{BvhNode, BVH_MAX_LEAF_SIZE};

/// Entries of the fixed traversal stack, and therefore the largest allowed tree depth
/// (root at depth 0): descending pushes at most one sibling per level, so a leaf at depth
/// `d` is reached with at most `d` entries on the stack. 64 covers any balanced tree of
/// up to 2^64 leaves; obvhs' PLOC trees stay far below it on real scenes (its own default
/// traversal stack is 96). A GPU mirror can use the same bound (64 x 8 bytes of private
/// memory for closest hit, 64 x 4 for any hit).
pub const BVH_STACK_SIZE: usize = 64;

/// Relative margin added around the leaf boxes of a pre-split BVH. obvhs computes the
/// boxes of triangle pieces from clipped vertices (`splits.rs`: `v0 + s * (v1 - v0)`, a
/// handful of rounded operations, and repeated splits re-clip the original triangle
/// against the previous piece's box), so a piece box can miss its exact piece by a few
/// ulps of the coordinates, which would leave a crack between pieces. gamma(16) of the
/// coordinate magnitude bounds those errors with room to spare; the widened box is then
/// clipped back to the union of its triangles' full boxes, so it never grows past them.
pub const SPLIT_LEAF_MARGIN: f32 = gamma(16);

/// Relative slack of box culling during traversal: a box is skipped only if the ray's
/// interval, widened to `[t_min * (1 - slack), t_bound * (1 + slack)]`, misses it (where
/// `t_bound` is `t_max`, or the closest hit so far).
///
/// The slab test and the triangle test round differently: a hit on a triangle vertex or
/// edge that lies on its leaf's box boundary can come out a few ulps *before* the box's
/// computed entry. Without slack such a box would be culled against an equal-`t` hit
/// already found (breaking the lower-index tie rule) or against `t_max` (a shadow ray
/// missing an occluder at the light). The triangle's `t` error is a few ulps of
/// `max(t, triangle size)` (pbrt-v4's `deltaT`), so 2^-12 (4096 ulps) covers triangles up
/// to about a thousand times larger than their distance; the cost is a rare extra box
/// visit. It is a heuristic bound, not a proof: for a sliver or huge triangle right at the
/// origin two hits within its rounding error in different leaves can still resolve
/// differently than a brute-force search would (deterministically either way).
pub const BVH_CULL_SLACK: f32 = 1.0 / 4096.0;

/// The traversal cost, against a triangle test's 1, with which obvhs' leaf collapse of the
/// default preset ([`BvhPreset::Medium`]) weighs keeping an inner node against merging its
/// subtree of at most `max_prims_per_leaf` (8) triangles into one leaf. obvhs' own
/// `medium_build` says 3. hyrt's walks test a leaf's triangles eight at a time (the
/// packets' lone lanes against all of a leaf's triangles at once, the wide view's leaves
/// in one SIMD test), so a node visit costs more here than a triangle, and larger leaves
/// pay: measured with both trees in one process, interleaved round by round
/// (`ray_contest --packets-only --kind shadow --rounds 15 --threads 1`, AMD EPYC, ms,
/// 3 then 5), at AVX-512 the dragon 62.3 and 58.5, the far bunny 5.15 and 4.80, the far
/// horse 0.79 and 0.73, the near bunny 10.4 and 9.9, the teaser 48.0 and 48.5; at AVX2 the
/// dragon 62.5 and 60.2, the far bunny 4.97 and 4.66, the far horse 0.81 and 0.76, Sponza
/// 39.4 and 39.7, the near horse 5.79 and 5.72; primary rays the dragon 41.0 and 39.9, the
/// teaser 40.4 both; the teaser's reflections one at a time 25.7 and 25.5. 8 built the
/// same trees as 5 on these scenes, 1 was 25 to 30% slower on the dragon's, the far
/// bunny's and the far horse's shadow rays. Results do not depend on the tree.
pub const MEDIUM_COLLAPSE_TRAVERSAL_COST: f32 = 5.0;

/// obvhs build presets, fastest build to best tree.
///
/// The default is [`BvhPreset::Medium`]. The BVH is built once per scene, so tree quality
/// pays off on every frame, but past `Medium` it barely improves. Measured on a synthetic
/// 98,696-triangle scene (a floor, 8 spheres, 8 tori; 2M shadow rays from random surface
/// points to a point light), traversal work per ray (nodes visited / triangles tested)
/// and single-thread build time:
///
/// | preset | nodes | triangles | build |
/// |---|---:|---:|---:|
/// | `Fastest` | 39.5 | 3.3 | 27 ms |
/// | `VeryFast` | 33.3 | 10.8 | 20-80 ms |
/// | `Fast` | 26.8 | 10.6 | 29-50 ms |
/// | `Medium` | 26.2 | 11.0 | 31-35 ms |
/// | `Slow` | 24.7 | 10.5 | 69-79 ms |
/// | `VerySlow` | 24.5 | 9.8 | 197-212 ms |
///
/// `Medium` does the work of `Fast` or better for about the same build time, and is
/// within about 7% of `VerySlow`'s work for a sixth of its build time (which would be
/// seconds on million-triangle scenes); the pre-split presets also duplicate triangles
/// in leaves. obvhs itself describes `medium_build` as "around the same build time as
/// embree but with faster traversal". (The table predates `Medium`'s leaf collapse cost of
/// [`MEDIUM_COLLAPSE_TRAVERSAL_COST`]: its row is obvhs' `medium_build` as it is.)
///
/// More reinsertion or a wider PLOC search on top of `Medium` (issue 36, AMD EPYC Zen 3),
/// counted on the frames' shadow rays in the scalar any-hit walk (binary nodes visited /
/// triangles tested per ray; a temporary counter in the walk) with the build time of the
/// dragon's 871,818 triangles and of the teaser's 135,905 (one process, 2 threads):
///
/// | on top of `Medium` | far horse | far bunny | dragon | teaser | Sponza | build: dragon, teaser |
/// |---|---:|---:|---:|---:|---:|---:|
/// | nothing | 22.8 / 15.0 | 25.3 / 14.4 | 10.4 / 3.55 | 23.1 / 5.13 | 21.2 / 4.01 | 0.60 s, 53 ms |
/// | reinsertion ratio 0.3 | 22.3 / 14.6 | 24.7 / 14.1 | 10.1 / 3.31 | 21.3 / 4.78 | 21.3 / 3.87 | 2.2 s, 277 ms |
/// | reinsertion ratio 1.0 | 21.6 / 13.9 | 24.2 / 13.7 | 9.9 / 3.02 | 21.7 / 5.06 | 20.9 / 3.79 | 7.1 s, 684 ms |
/// | search distance 32 | 22.8 / 14.9 | 25.6 / 14.3 | 10.4 / 3.50 | 27.1 / 5.26 | 21.2 / 4.74 | 0.75 s, 103 ms |
///
/// 2 to 8% less work for 4 to 12 times the build (the teaser's primary rays: 11% fewer
/// nodes at 0.3); timed (reinsertion 0.3 with a search distance of 24, `ray_contest
/// --kind shadow`, 2 threads, alternated twice with `Medium`, each against Embree), the
/// shadow rays' change was within the host's noise: not taken.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BvhPreset {
    Fastest,
    VeryFast,
    Fast,
    #[default]
    Medium,
    Slow,
    VerySlow,
}

impl BvhPreset {
    /// Every preset, fastest build first.
    pub const ALL: [BvhPreset; 6] = [
        BvhPreset::Fastest,
        BvhPreset::VeryFast,
        BvhPreset::Fast,
        BvhPreset::Medium,
        BvhPreset::Slow,
        BvhPreset::VerySlow,
    ];

    /// The obvhs build parameters of this preset.
    pub const fn params(self) -> BvhBuildParams {
        match self {
            BvhPreset::Fastest => BvhBuildParams::fastest_build(),
            BvhPreset::VeryFast => BvhBuildParams::very_fast_build(),
            BvhPreset::Fast => BvhBuildParams::fast_build(),
            BvhPreset::Medium => BvhBuildParams {
                collapse_traversal_cost: MEDIUM_COLLAPSE_TRAVERSAL_COST,
                ..BvhBuildParams::medium_build()
            },
            BvhPreset::Slow => BvhBuildParams::slow_build(),
            BvhPreset::VerySlow => BvhBuildParams::very_slow_build(),
        }
    }

    /// Whether the preset splits large triangles into several leaves.
    pub const fn uses_spatial_splits(self) -> bool {
        self.params().pre_split
    }

    /// Snake-case name (CLI, `frame.json`).
    pub const fn name(self) -> &'static str {
        match self {
            BvhPreset::Fastest => "fastest",
            BvhPreset::VeryFast => "very_fast",
            BvhPreset::Fast => "fast",
            BvhPreset::Medium => "medium",
            BvhPreset::Slow => "slow",
            BvhPreset::VerySlow => "very_slow",
        }
    }
}

/// The closest hit of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestHit {
    /// Global triangle index into `WorldGeometry::triangles`.
    pub triangle: u32,
    /// Ray parameter of the hit.
    pub t: f32,
    /// Barycentric weight of the triangle's `v1`.
    pub u: f32,
    /// Barycentric weight of the triangle's `v2`.
    pub v: f32,
    /// The ray hit the triangle's back face ([`crate::kernels::ray::TriangleHit::back_face`]).
    pub back_face: bool,
}

impl ClosestHit {
    /// Whether a hit on triangle `triangle` at `t` is nearer than this one, or as near with
    /// a lower triangle index: the rule for ties of every closest-hit walk, so that a
    /// closest hit does not depend on the order its triangles are tested in.
    #[inline(always)]
    pub fn is_closer(&self, triangle: u32, t: f32) -> bool {
        t < self.t || (t == self.t && triangle < self.triangle)
    }

    /// Take `hit` on triangle `triangle` where it [`Self::is_closer`]; whether it was
    /// taken.
    #[inline(always)]
    pub fn take_if_closer(&mut self, triangle: u32, hit: TriangleHit) -> bool {
        let closer = self.is_closer(triangle, hit.t);
        if closer {
            *self = ClosestHit { triangle, t: hit.t, u: hit.u, v: hit.v, back_face: hit.back_face };
        }
        closer
    }
}

/// A flattened BVH; see the module docs for the layout.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh {
    /// Nodes, root first; empty when the scene has no traceable triangle.
    pub nodes: Vec<BvhNode>,
    /// Global triangle index into `WorldGeometry::triangles`, per leaf slot.
    pub prim_indices: Vec<u32>,
    /// The preset it was built with.
    pub build_preset: BvhPreset,
    /// Depth of the deepest leaf (root = 0); at most [`BVH_STACK_SIZE`].
    pub max_depth: u32,
    /// The triangle records in slot order: `leaf_triangles[s]` is a copy of
    /// `WorldGeometry::triangles[prim_indices[s]]`, so a leaf's triangles are contiguous
    /// in memory and traversal reads them without the indirection.
    pub leaf_triangles: Vec<TriangleRecord>,
    /// The 8-wide view of the same tree for the CPU's single-ray traversal
    /// ([`wide::WideBvh`]); derived from `nodes`, never uploaded.
    pub wide: wide::WideBvh,
}

/// True if a triangle can ever be hit: all vertices finite and no two vertices equal.
/// (A triangle with two equal vertices has `det == 0` in every ray space: its three edge
/// functions are `0, e, -e` exactly.) Only these go into the BVH.
#[inline]
pub fn triangle_is_traceable(t: &TriangleRecord) -> bool {
    let [a, b, c] = t.vertices();
    a.is_finite() && b.is_finite() && c.is_finite() && a != b && b != c && c != a
}

/// obvhs' nodes as [`BvhNode`]s (same boxes, same indices; not yet flattened).
fn obvhs_nodes(bvh2: &obvhs::bvh2::Bvh2) -> Vec<BvhNode> {
    bvh2.nodes
        .iter()
        .map(|n| {
            let b = n.aabb();
            BvhNode::from_box(b.min.into(), b.max.into(), n.first_index, n.prim_count)
        })
        .collect()
}

/// Re-emit a tree in depth-first order (left child first): sibling pairs allocated as
/// they are reached, leaf slots written out in the order the leaves are reached.
///
/// obvhs' raw output can hold nodes no longer reachable (a root collapsed into a leaf)
/// and, with spatial splits, leaves sharing slots (two leaves naming slot 0 when both hold
/// pieces of the same triangle, while another slot of that triangle goes unused). The
/// flattened copy has neither: every node is reachable exactly once, every slot belongs
/// to exactly one leaf, and children always follow their parent.
fn flatten(nodes: &[BvhNode], prims: &[u32]) -> (Vec<BvhNode>, Vec<u32>) {
    let mut out_nodes = vec![BvhNode::zeroed()];
    let mut out_prims = Vec::with_capacity(prims.len());
    // (source node, destination node)
    let mut todo = vec![(0usize, 0usize)];
    while let Some((src, dst)) = todo.pop() {
        let n = nodes[src];
        if n.is_leaf() {
            let first = n.left_or_first as usize;
            out_nodes[dst] = BvhNode { left_or_first: out_prims.len() as u32, ..n };
            out_prims.extend_from_slice(&prims[first..first + n.count as usize]);
        } else {
            let left = out_nodes.len();
            out_nodes.push(BvhNode::zeroed());
            out_nodes.push(BvhNode::zeroed());
            out_nodes[dst] = BvhNode { left_or_first: left as u32, ..n };
            todo.push((n.left_or_first as usize + 1, left + 1));
            todo.push((n.left_or_first as usize, left));
        }
    }
    (out_nodes, out_prims)
}

/// Bounds of a triangle's vertices.
#[inline]
fn triangle_box(t: &TriangleRecord) -> (Vec3, Vec3) {
    let [a, b, c] = t.vertices();
    (a.min(b).min(c), a.max(b).max(c))
}

/// A ray prepared for traversal (checked once, constants precomputed).
#[derive(Clone, Copy, Debug)]
pub(crate) struct TraversalRay {
    wt: WatertightRay,
    inv_dir: Vec3,
    t_min: f32,
    t_max: f32,
    /// `t_min * (1 - BVH_CULL_SLACK)`: the near bound of box tests.
    box_t_min: f32,
}

impl TraversalRay {
    /// `None` for a ray that can hit nothing: non-finite origin or direction, zero
    /// direction, or an empty / NaN `(t_min, t_max)` interval.
    #[inline]
    pub(crate) fn new(ray: &RayRecord) -> Option<TraversalRay> {
        let dir = Vec3::from(ray.direction);
        let wt = WatertightRay::new(Vec3::from(ray.origin), dir)?;
        // Positive form, so that NaN bounds reject.
        let non_empty = ray.t_min < ray.t_max;
        non_empty.then(|| TraversalRay {
            wt,
            inv_dir: safe_inverse_dir(dir),
            t_min: ray.t_min,
            t_max: ray.t_max,
            box_t_min: ray.t_min * (1.0 - BVH_CULL_SLACK),
        })
    }

    /// Entry distance into a node's box for the interval `[t_min, t_far]`, both ends
    /// widened by [`BVH_CULL_SLACK`].
    #[inline]
    fn enter(&self, node: &BvhNode, t_far: f32) -> Option<f32> {
        let t_far = t_far * (1.0 + BVH_CULL_SLACK);
        ray_aabb_conservative(self.wt.origin, self.inv_dir, self.box_t_min, t_far, node.min(), node.max())
    }
}

/// The scalar ray's node test: the entry distance is kept per stack entry, the bound is
/// `t_max` (any hit) or the closest `t` so far, children go nearer first (ties left), and
/// a stale entry is skipped when its entry distance lies beyond the widened bound.
impl NodeTest for TraversalRay {
    type Entry = f32;
    type Bound = f32;

    #[inline(always)]
    fn enter_root(&self, root: &BvhNode, bound: &f32) -> Option<f32> {
        self.enter(root, *bound)
    }

    #[inline(always)]
    fn enter(&self, node: &BvhNode, _parent: f32, bound: &f32) -> Option<f32> {
        TraversalRay::enter(self, node, *bound)
    }

    #[inline(always)]
    fn right_first(&self, _left: &BvhNode, _right: &BvhNode, left_entry: f32, right_entry: f32) -> bool {
        right_entry < left_entry
    }

    /// A fresh entry passed `t_enter <= bound * (1 + slack)` when it was tested (the slab
    /// test's entry never exceeds its far bound), so only stale ones are compared.
    #[inline(always)]
    fn resume(&self, _node: &BvhNode, t_enter: f32, bound: &f32, stale: bool) -> Option<f32> {
        (!stale || t_enter <= *bound * (1.0 + BVH_CULL_SLACK)).then_some(t_enter)
    }
}

impl Bvh {
    /// Build the BVH over the traceable triangles of `geometry` (see the module docs).
    /// Deterministic: the same geometry and preset give the same buffers. Validated in
    /// debug builds.
    /// A table with objects by reference is made whole first (its records made on read).
    pub fn build(geometry: &WorldGeometry, preset: BvhPreset) -> Bvh {
        Bvh::build_triangles(&geometry.triangles.whole(), preset)
    }

    /// [`Bvh::build_filtered`] over the stored objects of a world table that `keep_object`
    /// accepts (objects by reference are never in it): the same tree as over the whole
    /// table by global id (the stored records are in global order), with `prim_indices`
    /// global ids. The world-space level of [`two_level::TwoLevelBvh`].
    pub fn build_stored(
        triangles: &crate::geometry::WorldTriangles,
        objects: &[crate::formats::ObjectRecord],
        preset: BvhPreset,
        keep_object: &dyn Fn(u32) -> bool,
    ) -> Bvh {
        let records = triangles.stored_records();
        let mut bvh = Bvh::build_filtered(records, preset, &|i| keep_object(records[i as usize].object));
        if triangles.has_references() {
            for p in &mut bvh.prim_indices {
                let t = &records[*p as usize];
                *p = objects[t.object as usize].first_triangle + t.triangle;
            }
            // The wide view copies the ids into its leaves: collapse it again.
            bvh.wide = wide::WideBvh::collapse(&bvh);
        }
        bvh
    }

    /// [`Bvh::build`] over a triangle table of any space: the world table of a scene, or
    /// one mesh's object-space triangles (a bottom level of [`two_level::TwoLevelBvh`]).
    /// `prim_indices` are indices into `triangles`.
    pub fn build_triangles(triangles: &[TriangleRecord], preset: BvhPreset) -> Bvh {
        Bvh::build_filtered(triangles, preset, &|_| true)
    }

    /// [`Bvh::build_triangles`] over the triangles `keep` accepts (by index into
    /// `triangles`): the world-space bottom level of [`two_level::TwoLevelBvh`] holds only
    /// the objects baked into world space. Validate with [`Bvh::validate_filtered`].
    pub fn build_filtered(triangles: &[TriangleRecord], preset: BvhPreset, keep: &dyn Fn(u32) -> bool) -> Bvh {
        let mut ids = Vec::new();
        let mut obvhs_tris = Vec::new();
        for (i, t) in triangles.iter().enumerate() {
            if triangle_is_traceable(t) && keep(i as u32) {
                ids.push(i as u32);
                let [a, b, c] = t.vertices();
                obvhs_tris.push(Triangle { v0: Vec3A::from(a), v1: Vec3A::from(b), v2: Vec3A::from(c) });
            }
        }
        let mut bvh = Bvh { build_preset: preset, ..Bvh::default() };
        if !ids.is_empty() {
            let bvh2 = build_bvh2_from_tris(&obvhs_tris, preset.params(), &mut Duration::default());
            let nodes = obvhs_nodes(&bvh2);
            let prims: Vec<u32> = bvh2.primitive_indices.iter().map(|&p| ids[p as usize]).collect();
            (bvh.nodes, bvh.prim_indices) = flatten(&nodes, &prims);
            if bvh2.uses_spatial_splits {
                bvh.widen_split_leaves(triangles);
            }
            bvh.finish(triangles);
            if bvh.max_depth as usize > BVH_STACK_SIZE {
                bvh = Bvh::build_median(triangles, &ids, preset);
            }
        }
        if cfg!(debug_assertions) {
            bvh.validate_filtered(triangles, keep).expect("BVH invariants");
        }
        bvh
    }

    /// The fallback builder: balanced object-median splits on the longest centroid axis,
    /// leaves of at most [`BVH_MAX_LEAF_SIZE`] triangles, depth `ceil(log2(n / 8))`.
    /// `ids` are the traceable global triangle indices.
    pub(crate) fn build_median(triangles: &[TriangleRecord], ids: &[u32], preset: BvhPreset) -> Bvh {
        let mut items: Vec<(Vec3, u32)> = ids
            .iter()
            .map(|&i| {
                let [a, b, c] = triangles[i as usize].vertices();
                ((a + b + c) * (1.0 / 3.0), i)
            })
            .collect();
        let mut nodes = vec![BvhNode::zeroed()];
        // (node index, item range)
        let mut todo = vec![(0usize, 0usize, items.len())];
        while let Some((node, start, end)) = todo.pop() {
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            let (mut clo, mut chi) = (lo, hi);
            for &(c, i) in &items[start..end] {
                let (a, b) = triangle_box(&triangles[i as usize]);
                lo = lo.min(a);
                hi = hi.max(b);
                clo = clo.min(c);
                chi = chi.max(c);
            }
            if (end - start) as u32 <= BVH_MAX_LEAF_SIZE {
                nodes[node] = BvhNode::from_box(lo, hi, start as u32, (end - start) as u32);
                continue;
            }
            let extent = chi - clo;
            let axis = if extent.x >= extent.y && extent.x >= extent.z {
                0
            } else if extent.y >= extent.z {
                1
            } else {
                2
            };
            items[start..end].sort_unstable_by(|a, b| a.0[axis].total_cmp(&b.0[axis]).then(a.1.cmp(&b.1)));
            let left = nodes.len();
            nodes.push(BvhNode::zeroed());
            nodes.push(BvhNode::zeroed());
            nodes[node] = BvhNode::from_box(lo, hi, left as u32, 0);
            let mid = start + (end - start) / 2;
            todo.push((left + 1, mid, end));
            todo.push((left, start, mid));
        }
        let mut bvh = Bvh {
            nodes,
            prim_indices: items.iter().map(|&(_, i)| i).collect(),
            build_preset: preset,
            max_depth: 0,
            leaf_triangles: Vec::new(),
            wide: wide::WideBvh::default(),
        };
        bvh.finish(triangles);
        bvh
    }

    /// Refit the tree to new vertex positions of the same triangles (a deforming mesh):
    /// the leaf copies taken again, each leaf box the union of its triangles' boxes, each
    /// inner box the union of its children's, the wide view collapsed again; the topology
    /// stays. Returns false, changing nothing, when the set of traceable triangles is not
    /// the one the tree was built over (a triangle became degenerate, or a degenerate one
    /// became traceable): rebuild then. Leaves of a pre-split tree get their triangles'
    /// whole boxes (looser than their pieces', still conservative).
    pub fn refit(&mut self, triangles: &[TriangleRecord]) -> bool {
        let mut in_tree = vec![false; triangles.len()];
        for &p in &self.prim_indices {
            match in_tree.get_mut(p as usize) {
                Some(seen) => *seen = true,
                None => return false,
            }
        }
        if triangles.iter().zip(&in_tree).any(|(t, &seen)| triangle_is_traceable(t) != seen) {
            return false;
        }
        let order = self.preorder();
        for &(n, _) in order.iter().rev() {
            let node = self.nodes[n as usize];
            let (lo, hi) = if node.is_leaf() {
                let slots = node.left_or_first as usize..(node.left_or_first + node.count) as usize;
                self.prim_indices[slots]
                    .iter()
                    .map(|&p| triangle_box(&triangles[p as usize]))
                    .fold((Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)), |(lo, hi), (a, b)| {
                        (lo.min(a), hi.max(b))
                    })
            } else {
                let (l, r) = (&self.nodes[node.left_or_first as usize], &self.nodes[node.left_or_first as usize + 1]);
                (l.min().min(r.min()), l.max().max(r.max()))
            };
            self.nodes[n as usize].aabb_min = lo.into();
            self.nodes[n as usize].aabb_max = hi.into();
        }
        self.finish(triangles);
        if cfg!(debug_assertions) {
            self.validate_triangles(triangles).expect("refitted BVH invariants");
        }
        true
    }

    /// Fill the derived fields: `max_depth`, `leaf_triangles` and `wide`.
    fn finish(&mut self, triangles: &[TriangleRecord]) {
        self.max_depth = self.compute_max_depth();
        self.leaf_triangles = self.prim_indices.iter().map(|&i| triangles[i as usize]).collect();
        self.wide = wide::WideBvh::collapse(self);
    }

    /// Nodes in an order where every child comes after its parent (pre-order), with depths.
    fn preorder(&self) -> Vec<(u32, u32)> {
        let mut out = Vec::with_capacity(self.nodes.len());
        if self.nodes.is_empty() {
            return out;
        }
        let mut todo = vec![(0u32, 0u32)];
        while let Some((n, d)) = todo.pop() {
            out.push((n, d));
            let node = &self.nodes[n as usize];
            if !node.is_leaf() {
                todo.push((node.left_or_first + 1, d + 1));
                todo.push((node.left_or_first, d + 1));
            }
        }
        out
    }

    fn compute_max_depth(&self) -> u32 {
        self.preorder().iter().map(|&(_, d)| d).max().unwrap_or(0)
    }

    /// Make pre-split leaf boxes conservative (see [`SPLIT_LEAF_MARGIN`]) and refit the
    /// inner boxes.
    fn widen_split_leaves(&mut self, triangles: &[TriangleRecord]) {
        let order = self.preorder();
        for &(n, _) in order.iter().rev() {
            let node = self.nodes[n as usize];
            let (lo, hi) = if node.is_leaf() {
                let (mut ulo, mut uhi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
                for slot in node.left_or_first..node.left_or_first + node.count {
                    let (a, b) = triangle_box(&triangles[self.prim_indices[slot as usize] as usize]);
                    ulo = ulo.min(a);
                    uhi = uhi.max(b);
                }
                let margin = ulo.abs().max(uhi.abs()) * SPLIT_LEAF_MARGIN;
                ((node.min() - margin).max(ulo), (node.max() + margin).min(uhi))
            } else {
                let l = &self.nodes[node.left_or_first as usize];
                let r = &self.nodes[node.left_or_first as usize + 1];
                (l.min().min(r.min()), l.max().max(r.max()))
            };
            self.nodes[n as usize].aabb_min = lo.into();
            self.nodes[n as usize].aabb_max = hi.into();
        }
    }

    /// Check every invariant against the geometry it was built from: node boxes finite and
    /// ordered; every node reachable exactly once from the root, children inside their
    /// parent; leaves partition `prim_indices`; every slot names a traceable triangle whose
    /// box lies in the leaf box (with spatial splits: the leaf box lies in the union of its
    /// triangles' boxes) and whose record `leaf_triangles` copies bit for bit; every
    /// traceable triangle is in some leaf; depth within [`BVH_STACK_SIZE`] and equal to
    /// `max_depth`.
    pub fn validate(&self, geometry: &WorldGeometry) -> Result<(), String> {
        self.validate_triangles(&geometry.triangles.whole())
    }

    /// [`Bvh::validate`] against the triangle table it was built from
    /// ([`Bvh::build_triangles`]).
    pub fn validate_triangles(&self, triangles: &[TriangleRecord]) -> Result<(), String> {
        self.validate_filtered(triangles, &|_| true)
    }

    /// [`Bvh::validate_triangles`] for a tree built by [`Bvh::build_filtered`] with `keep`:
    /// exactly the kept traceable triangles are in its leaves.
    pub fn validate_filtered(&self, triangles: &[TriangleRecord], keep: &dyn Fn(u32) -> bool) -> Result<(), String> {
        let wanted = |i: usize| triangle_is_traceable(&triangles[i]) && keep(i as u32);
        let traceable = (0..triangles.len()).filter(|&i| wanted(i)).count();
        if self.leaf_triangles.len() != self.prim_indices.len() {
            return Err("leaf_triangles and prim_indices differ in length".into());
        }
        if self.nodes.is_empty() {
            if !self.prim_indices.is_empty() || self.max_depth != 0 {
                return Err("BVH without nodes has slots or depth".into());
            }
            if traceable != 0 {
                return Err(format!("BVH without nodes but {traceable} traceable triangles"));
            }
            return self.wide.validate(self).map_err(|e| format!("wide view: {e}"));
        }
        let splits = self.build_preset.uses_spatial_splits();
        let mut node_seen = vec![false; self.nodes.len()];
        let mut slot_seen = vec![false; self.prim_indices.len()];
        let mut tri_seen = vec![false; triangles.len()];
        let mut depth = 0u32;
        // (node, depth, parent)
        let mut todo = vec![(0u32, 0u32, 0u32)];
        while let Some((n, d, parent)) = todo.pop() {
            let node = self.nodes.get(n as usize).ok_or_else(|| format!("node {n} out of range"))?;
            if std::mem::replace(&mut node_seen[n as usize], true) {
                return Err(format!("node {n} reachable twice"));
            }
            node.validate().map_err(|e| format!("node {n}: {e}"))?;
            let p = &self.nodes[parent as usize];
            if !(node.min().cmpge(p.min()).all() && node.max().cmple(p.max()).all()) {
                return Err(format!("node {n} not inside its parent {parent}: {node:?} vs {p:?}"));
            }
            depth = depth.max(d);
            if !node.is_leaf() {
                let l = node.left_or_first;
                if l == 0 || l as usize + 1 >= self.nodes.len() {
                    return Err(format!("inner node {n} with children {l}, {} out of range", l + 1));
                }
                todo.push((l, d + 1, n));
                todo.push((l + 1, d + 1, n));
                continue;
            }
            let (first, count) = (node.left_or_first as usize, node.count as usize);
            if first + count > self.prim_indices.len() {
                return Err(format!("leaf {n} slots {first}..{} out of range", first + count));
            }
            let (mut ulo, mut uhi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for (slot, &ti) in self.prim_indices.iter().enumerate().skip(first).take(count) {
                if std::mem::replace(&mut slot_seen[slot], true) {
                    return Err(format!("slot {slot} in two leaves"));
                }
                let ti = ti as usize;
                let t = triangles.get(ti).ok_or_else(|| format!("slot {slot}: triangle {ti} out of range"))?;
                if !wanted(ti) {
                    return Err(format!("slot {slot}: triangle {ti} is not traceable or not kept: {t:?}"));
                }
                tri_seen[ti] = true;
                if bytemuck::bytes_of(t) != bytemuck::bytes_of(&self.leaf_triangles[slot]) {
                    return Err(format!("slot {slot}: leaf copy differs from triangle {ti}"));
                }
                let (a, b) = triangle_box(t);
                let inside = a.cmpge(node.min()).all() && b.cmple(node.max()).all();
                if !splits && !inside {
                    return Err(format!("triangle {ti} not inside its leaf {n}: {node:?}"));
                }
                ulo = ulo.min(a);
                uhi = uhi.max(b);
            }
            if splits && !(node.min().cmpge(ulo).all() && node.max().cmple(uhi).all()) {
                return Err(format!("split leaf {n} larger than its triangles: {node:?}"));
            }
        }
        if let Some(n) = node_seen.iter().position(|s| !s) {
            return Err(format!("node {n} unreachable"));
        }
        if let Some(s) = slot_seen.iter().position(|s| !s) {
            return Err(format!("slot {s} in no leaf"));
        }
        if let Some(t) = (0..triangles.len()).find(|&t| wanted(t) && !tri_seen[t]) {
            return Err(format!("traceable triangle {t} in no leaf"));
        }
        if depth as usize > BVH_STACK_SIZE {
            return Err(format!("depth {depth} exceeds the traversal stack ({BVH_STACK_SIZE})"));
        }
        if depth != self.max_depth {
            return Err(format!("max_depth is {} but the tree is {depth} deep", self.max_depth));
        }
        self.wide.validate(self).map_err(|e| format!("wide view: {e}"))?;
        Ok(())
    }

    /// Any hit with `t_min < t < t_max` (shadow rays): early exit on the first hit found.
    /// Invalid rays (non-finite, zero direction, empty interval) hit nothing.
    ///
    /// `triangles` is the table the BVH was built from. Traversal reads the slot-ordered
    /// copy in `leaf_triangles`; debug builds check every tested slot against `triangles`.
    /// Alpha-tested triangles count as any other: [`Bvh::occluded_filtered`] tests them.
    pub fn occluded(&self, triangles: &[TriangleRecord], ray: &RayRecord) -> bool {
        self.occluded_filtered(triangles, ray, |_, _, _, _| true)
    }

    /// [`Bvh::occluded`] where a hit on a triangle flagged [`TRI_ALPHA_TEST`] counts only
    /// if `accept(triangle, global index, u, v)` says so (the alpha test of
    /// [`crate::kernels::texture::alpha_accepts`]); a rejected hit neither stops the walk
    /// nor narrows anything. Other triangles never call `accept`.
    #[inline(always)]
    pub fn occluded_filtered(
        &self,
        triangles: &[TriangleRecord],
        ray: &RayRecord,
        accept: impl Fn(&TriangleRecord, u32, f32, f32) -> bool,
    ) -> bool {
        let Some(r) = TraversalRay::new(ray) else {
            return false;
        };
        self.occluded_ray(&r, 0, |slot, u, v| {
            let id = self.prim_indices[slot as usize];
            accept(self.leaf_triangle(triangles, slot), id, u, v)
        })
    }

    /// The any-hit walk of a prepared ray: a hit on slot `s` counts unless the triangle's
    /// flags or `alpha_flags` hold [`TRI_ALPHA_TEST`] and `accept(s, u, v)` refuses it.
    /// Shared by [`Bvh::occluded_filtered`] and the bottom levels of
    /// [`two_level::TwoLevelBvh`] (where the instance brings the alpha flag).
    #[inline(always)]
    pub(crate) fn occluded_ray(
        &self,
        r: &TraversalRay,
        alpha_flags: u32,
        accept: impl Fn(u32, f32, f32) -> bool,
    ) -> bool {
        // `inline(always)` on the leaf tests: the loop and its tests stay one function.
        let leaf_test = inline_leaf_test(
            #[inline(always)]
            |leaf: Leaf, _: f32, _: &mut f32| {
                for slot in leaf.slots() {
                    let t = &self.leaf_triangles[slot as usize];
                    if let Some(h) = r.wt.intersect(r.t_min, r.t_max, t.v0.into(), t.v1.into(), t.v2.into()) {
                        if (t.flags | alpha_flags) & TRI_ALPHA_TEST == 0 || accept(slot, h.u, h.v) {
                            return LeafFlow::Stop;
                        }
                    }
                }
                LeafFlow::Continue
            },
        );
        traverse(&self.nodes, r, &mut r.t_max.clone(), leaf_test)
    }

    /// The closest hit with `t_min < t < t_max`. Hits at exactly equal `t` (a ray through a
    /// shared edge or vertex) go to the lower global triangle index. Invalid rays hit
    /// nothing. `triangles` as in [`Bvh::occluded`].
    ///
    /// Boxes are pruned against the closest `t` found so far, widened by
    /// [`BVH_CULL_SLACK`], so the result is the brute-force minimum of `(t, triangle)` over
    /// all triangles except in the corner case that constant's docs describe.
    pub fn closest_hit(&self, triangles: &[TriangleRecord], ray: &RayRecord) -> Option<ClosestHit> {
        self.closest_hit_filtered(triangles, ray, |_, _, _, _| true)
    }

    /// [`Bvh::closest_hit`] where a hit on a triangle flagged [`TRI_ALPHA_TEST`] counts
    /// only if `accept` says so, as in [`Bvh::occluded_filtered`].
    #[inline(always)]
    pub fn closest_hit_filtered(
        &self,
        triangles: &[TriangleRecord],
        ray: &RayRecord,
        accept: impl Fn(&TriangleRecord, u32, f32, f32) -> bool,
    ) -> Option<ClosestHit> {
        let r = TraversalRay::new(ray)?;
        let mut best = ClosestHit { triangle: INVALID_ID, t: r.t_max, u: 0.0, v: 0.0, back_face: false };
        self.closest_ray(
            &r,
            &mut best,
            |slot| self.prim_indices[slot as usize],
            0,
            |slot, id, u, v| accept(self.leaf_triangle(triangles, slot), id, u, v),
        );
        (best.triangle != INVALID_ID).then_some(best)
    }

    /// The closest-hit walk of a prepared ray from the hit `best` found so far (`t_max`
    /// and no triangle to start): a hit on slot `s` is reported as triangle `id_of(s)` and
    /// replaces `best` when it is closer, or as close with a lower id, and passes the alpha
    /// test as in [`Bvh::occluded_ray`] (`accept(s, id, u, v)`). `back_face` is the
    /// determinant's facing in this tree's space. Returns true when `best` changed.
    #[inline(always)]
    pub(crate) fn closest_ray(
        &self,
        r: &TraversalRay,
        best: &mut ClosestHit,
        id_of: impl Fn(u32) -> u32,
        alpha_flags: u32,
        accept: impl Fn(u32, u32, f32, f32) -> bool,
    ) -> bool {
        let mut found = false;
        let mut bound = best.t;
        let leaf_test = inline_leaf_test(
            #[inline(always)]
            |leaf: Leaf, _: f32, t_best: &mut f32| {
                let mut flow = LeafFlow::Continue;
                for slot in leaf.slots() {
                    let t = &self.leaf_triangles[slot as usize];
                    if let Some(h) = r.wt.intersect(r.t_min, r.t_max, t.v0.into(), t.v1.into(), t.v2.into()) {
                        let id = id_of(slot);
                        // `*t_best` is `best.t`: both change only together, below.
                        if best.is_closer(id, h.t)
                            && ((t.flags | alpha_flags) & TRI_ALPHA_TEST == 0 || accept(slot, id, h.u, h.v))
                        {
                            *best = ClosestHit { triangle: id, t: h.t, u: h.u, v: h.v, back_face: h.back_face };
                            *t_best = h.t;
                            found = true;
                            flow = LeafFlow::Narrowed;
                        }
                    }
                }
                flow
            },
        );
        traverse(&self.nodes, r, &mut bound, leaf_test);
        found
    }

    /// The triangle of leaf slot `slot` (debug builds check the copy against `triangles`
    /// unless it is empty: [`crate::geometry::WorldGeometry::traversal_table`]).
    #[inline(always)]
    fn leaf_triangle(&self, triangles: &[TriangleRecord], slot: u32) -> &TriangleRecord {
        let t = &self.leaf_triangles[slot as usize];
        debug_assert!(triangles.is_empty() || *t == triangles[self.prim_indices[slot as usize] as usize]);
        t
    }

    /// True if the BVH has no nodes (no traceable triangle).
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Bytes held by the tree: its nodes, slots and triangle copies, and its wide view
    /// ([`wide::WideBvh::bytes`]).
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(self.nodes.as_slice())
            + std::mem::size_of_val(self.prim_indices.as_slice())
            + std::mem::size_of_val(self.leaf_triangles.as_slice())
            + self.wide.bytes()
    }

    /// The node buffer as bytes, for upload.
    pub fn node_bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.nodes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::TRI_RAY_TRACED;

    fn geometry(tris: &[[Vec3; 3]]) -> WorldGeometry {
        let (mut records, mut normals) = (Vec::new(), Vec::new());
        for (i, t) in tris.iter().enumerate() {
            records.push(TriangleRecord {
                v0: t[0].into(),
                object: 0,
                v1: t[1].into(),
                triangle: i as u32,
                v2: t[2].into(),
                flags: TRI_RAY_TRACED,
            });
            normals.push([Vec3::Y; 3]);
        }
        WorldGeometry { triangles: crate::geometry::WorldTriangles::stored(records, normals), ..Default::default() }
    }

    fn ray(o: Vec3, d: Vec3) -> RayRecord {
        RayRecord::query(o.into(), d.into(), 0.0, f32::INFINITY)
    }

    /// Triangles growing geometrically along x: obvhs' PLOC chains them into a tree
    /// deeper than the traversal stack, so the build must fall back to median splits.
    #[test]
    fn deep_chain_falls_back_to_median_split() {
        let tris: Vec<[Vec3; 3]> = (0..600)
            .map(|i| {
                let x = 1.13f32.powi(i) - 1.0;
                let s = 1.13f32.powi(i) * 0.01;
                [Vec3::new(x, 0.0, 0.0), Vec3::new(x + s, 0.0, 0.0), Vec3::new(x, s, 0.0)]
            })
            .collect();
        let g = geometry(&tris);
        let obvhs_tris: Vec<Triangle> =
            tris.iter().map(|t| Triangle { v0: t[0].into(), v1: t[1].into(), v2: t[2].into() }).collect();
        let ids: Vec<u32> = (0..tris.len() as u32).collect();
        let median = Bvh::build_median(g.stored_table(), &ids, BvhPreset::Medium);
        median.validate(&g).unwrap();
        // 600 / 8 = 75 leaves: depth ceil(log2(75)) = 7.
        assert_eq!(median.max_depth, 7);
        for preset in BvhPreset::ALL {
            let raw = build_bvh2_from_tris(&obvhs_tris, preset.params(), &mut Duration::default());
            // `depth` counts levels (a lone leaf is 1); the stack bound is on edges.
            assert!(raw.depth(0) - 1 > BVH_STACK_SIZE, "{preset:?}: obvhs tree not deep");
            let bvh = Bvh::build(&g, preset);
            bvh.validate(&g).unwrap();
            assert_eq!(bvh.nodes, median.nodes, "{preset:?}");
            assert_eq!(bvh.prim_indices, median.prim_indices, "{preset:?}");
        }
        // Beyond i = 350 the triangles are larger than 1e16 and their edge functions
        // (products of two coordinates) overflow f32: unhittable by design.
        for (i, t) in tris.iter().enumerate().take(350) {
            let c = (t[0] + t[1] + t[2]) / 3.0;
            let hit = median.closest_hit(g.stored_table(), &ray(c + Vec3::Z, Vec3::NEG_Z)).unwrap();
            assert_eq!(hit.triangle, i as u32);
        }
    }

    /// `Bvh::bytes` counts the wide view beside the binary tree, at the documented sizes
    /// (the report's memory rows take it).
    #[test]
    fn bytes_count_the_binary_tree_and_the_wide_view() {
        let tris: Vec<[Vec3; 3]> = (0..300)
            .map(|i| {
                let c = Vec3::new((i % 17) as f32, (i / 17) as f32, (i % 5) as f32 * 0.3);
                [c, c + Vec3::X * 0.5, c + Vec3::Y * 0.5]
            })
            .collect();
        let bvh = Bvh::build(&geometry(&tris), BvhPreset::Medium);
        let w = &bvh.wide;
        assert!(!w.nodes16.is_empty() && !w.leaves.is_empty());
        let wide = 256 * w.nodes.len() + 512 * w.nodes16.len() + 320 * w.leaves.len() + 4 * w.first_slots.len();
        assert_eq!(w.bytes(), wide);
        let binary = 32 * bvh.nodes.len() + 4 * bvh.prim_indices.len() + 48 * bvh.leaf_triangles.len();
        assert_eq!(bvh.bytes(), binary + wide);
    }

    /// Pinned (found by a randomized search): with spatial splits and few triangles,
    /// obvhs skips the leaf collapse and two leaves name slot 0 (both pieces of triangle
    /// 0) while slot 5 (also triangle 0) is in no leaf. The flattened copy gives every
    /// leaf its own slots, and both pieces are still found.
    #[test]
    fn pinned_presplit_leaves_sharing_a_slot_are_flattened() {
        let tris = [
            [[9.329468, 9.269577, -5.326501], [8.254894, 6.7223434, -9.476224], [3.8572035, -6.653434, 5.7591]],
            [[5.275055, 2.4031878, 4.9783344], [5.4808893, 2.0498235, 5.2556744], [5.461748, 2.077035, 5.35121]],
            [[9.347248, 0.5261822, -9.408352], [8.874341, 0.3317358, -9.209116], [9.638064, 0.6561403, -9.3794775]],
            [
                [-5.1863933, -3.3541927, -7.999065],
                [-3.774321, -7.2043858, 7.141865],
                [0.9800291, -2.453792, -0.87600136],
            ],
            [[8.208429, -7.1369004, 6.1280994], [8.461, -7.592343, 6.125361], [8.697524, -6.8933563, 5.9329395]],
        ]
        .map(|t| t.map(Vec3::from));
        let g = geometry(&tris);
        let obvhs_tris: Vec<Triangle> =
            tris.iter().map(|t| Triangle { v0: t[0].into(), v1: t[1].into(), v2: t[2].into() }).collect();
        let raw = build_bvh2_from_tris(&obvhs_tris, BvhPreset::Slow.params(), &mut Duration::default());
        assert_eq!(raw.primitive_indices, [0, 1, 2, 3, 4, 0]);
        let leaf_firsts: Vec<u32> = raw.nodes.iter().filter(|n| n.is_leaf()).map(|n| n.first_index).collect();
        assert_eq!(leaf_firsts.iter().filter(|&&f| f == 0).count(), 2);
        for preset in [BvhPreset::Slow, BvhPreset::VerySlow] {
            let bvh = Bvh::build(&g, preset);
            bvh.validate(&g).unwrap();
            assert_eq!(bvh.prim_indices.iter().filter(|&&p| p == 0).count(), 2);
            let t = tris[0];
            for (u, v) in [(0.1, 0.1), (0.8, 0.1), (0.1, 0.8), (0.4, 0.4), (0.0, 0.5)] {
                let p = t[0] * (1.0 - u - v) + t[1] * u + t[2] * v;
                let o = p + Vec3::new(0.3, 20.0, 0.1);
                let hit = bvh.closest_hit(g.stored_table(), &ray(o, p - o)).unwrap();
                assert_eq!(hit.triangle, 0, "{preset:?} ({u}, {v})");
            }
        }
    }

    #[test]
    fn empty_and_untraceable_geometry_gives_empty_bvh() {
        let nan = Vec3::splat(f32::NAN);
        let g = geometry(&[[Vec3::ZERO, Vec3::X, nan], [Vec3::ZERO, Vec3::ZERO, Vec3::Y]]);
        for preset in BvhPreset::ALL {
            let bvh = Bvh::build(&g, preset);
            assert!(bvh.is_empty());
            bvh.validate(&g).unwrap();
            let r = ray(Vec3::new(0.1, 0.1, 1.0), Vec3::NEG_Z);
            assert!(!bvh.occluded(g.stored_table(), &r));
            assert_eq!(bvh.closest_hit(g.stored_table(), &r), None);
        }
        let empty = WorldGeometry::default();
        assert!(Bvh::build(&empty, BvhPreset::default()).is_empty());
    }

    #[test]
    fn validate_catches_broken_trees() {
        let tris: Vec<[Vec3; 3]> = (0..40)
            .map(|i| {
                [Vec3::new(i as f32, 0.0, 0.0), Vec3::new(i as f32 + 0.5, 0.0, 0.0), Vec3::new(i as f32, 1.0, 0.0)]
            })
            .collect();
        let g = geometry(&tris);
        let bvh = Bvh::build(&g, BvhPreset::Medium);
        bvh.validate(&g).unwrap();
        let mut b = bvh.clone();
        b.prim_indices[0] = 10_000;
        assert!(b.validate(&g).is_err());
        let mut b = bvh.clone();
        b.nodes[1].aabb_max[0] += 1000.0;
        assert!(b.validate(&g).is_err());
        let mut b = bvh.clone();
        b.max_depth += 1;
        assert!(b.validate(&g).is_err());
        let mut b = bvh.clone();
        b.leaf_triangles[3].v1[2] = 0.5;
        assert!(b.validate(&g).is_err());
        let mut b = bvh.clone();
        b.leaf_triangles.pop();
        assert!(b.validate(&g).is_err());
        let mut b = bvh.clone();
        let leaf = b.nodes.iter().position(|n| n.is_leaf()).unwrap();
        b.nodes[leaf].aabb_min[1] += 0.25;
        assert!(b.validate(&g).is_err());
    }
}
