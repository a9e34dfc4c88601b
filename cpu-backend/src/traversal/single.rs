//! One ray at a time through the wide view of the BVH ([`WideBvh`]): the ray's slab test
//! runs against a node's sixteen child boxes at once ([`WideNode16`], two halves of eight
//! lanes), then the children it enters are visited nearest first (closest hit) or in
//! stored order (any hit); the leaves are the view's 8-triangle leaves ([`WideLeaf`]).
//! This is the path for rays that do not travel together (reflections off curved mirrors,
//! refractions), where a packet's lanes diverge and most of its box tests are wasted;
//! Embree's `rtcIntersect1` and its `rtcIntersect8` (which walks the lanes of an
//! incoherent packet one at a time) are the peers. (Measured in one `hyrt bench --quick`,
//! 2 threads, AVX-512 lanes, with 8-wide nodes: the teaser's 75,529 secondary rays at 5.4
//! Mrays/s against 4.3 in packets and Embree's `rtcIntersect1` at 5.5; primary rays 12.9
//! against `rtcIntersect1`'s 11.3; but 2 to 3 times slower than the packets on primary and
//! shadow rays, the bunny's and the dragon's shadow rays included, so those stay in
//! packets.)
//!
//! Sixteen children a node, not eight: the walk waits on a chain of dependent steps from
//! one node to the next (a node's plane rows, its slab distances, the entered mask, the
//! next child's reference) and on the branches along it, not on the box tests'
//! arithmetic, so a flatter tree with twice the box tests a node is faster. The teaser's
//! reflection and refraction rays visit 10.1 nodes each instead of 13.5 (the same 3.7
//! leaves; counted with a scalar walk of both trees), and a node entered on several
//! children takes the nearest of sixteen. Measured against the 8-wide nodes (AMD EPYC,
//! one thread, `ray_contest --singles-only --rounds 9` to `11`, the two binaries
//! alternated two or three times, ms): the teaser's reflections at AVX-512 23.9 to 24.5
//! against 25.2 to 25.8, at AVX2 25.8 to 25.9 against 26.1 to 28.0; shadow rays one at a
//! time, the far horse 0.66 to 0.69 against 0.76 to 0.80, the far bunny 5.54 to 5.56
//! against 6.39 to 6.53, the dragon 79.8 to 84.8 against 87.3 to 91.9. Reading each
//! entered child's distance with a permute of its half (a branch on the half first) was
//! 2 to 3% slower than storing the two halves once and reading by slot. The 16-wide nodes
//! are a second set of nodes over the same leaves (the frustum packets keep the 8-wide
//! ones), built by the same dynamic program (`hyrt_core::bvh::wide`). In the quick report
//! (`hyrt bench --quick`, 2 threads) the teaser's reflections went from 0.96 (0.90 to 0.99)
//! to 1.01 (0.80 to 1.03) of Embree's `rtcIntersect8` at AVX-512 (12.06 ms against 12.21;
//! `rtcIntersect1` 13.10). With `--simd avx2` they did not move: 13.18 ms against 13.02
//! for the 8-wide nodes in an earlier run of the same day, 0.93 (0.89 to 0.96) of
//! `rtcIntersect8` in that run against 0.98 in the earlier one, Embree's own time moving
//! by 4% between the two. On a Zen 3 EPYC (family 25 model 1, AVX2 and no AVX-512; one
//! thread, `ray_contest --singles-only --kind bounce --rounds 11`, the binaries alternated
//! three times) the teaser's reflections took 27.2 to 27.4 ms against 28.8 to 29.6 with the
//! 8-wide nodes, so the wider node holds there too.
//!
//! Tried on that Zen 3 and not kept (the same command; the host was noisy, with the same
//! binary moving from 27 to 34 ms between runs): the second half of the node test skipped
//! for nodes of at most eight children (a branch on slot 8's box being empty; 45% of the
//! teaser's 16-wide nodes have at most eight): 27.7 to 28.1 ms against 28.0 to 30.1, and the
//! dragon's shadow rays 87.7 to 116.6 against 85.6 to 106.2, within the noise both ways;
//! and, as an upper bound before writing its error argument, the far planes' scale folded
//! into a second inverse direction (one multiply less per plane, not yet shown
//! conservative): about 2% in five alternations (pair ratios 0.93 to 1.05), too little for
//! a second rounding argument.
//!
//! Tried on the Zen 3 since and not kept (one thread, `ray_contest --singles-only --kind
//! bounce --rounds 11 teaser`, the two binaries alternated three times, ms): a node entered
//! on several children visiting the nearest (a scan of the entered slots with selects) and
//! pushing the others unsorted in stored order, instead of pushing them nearest last: 28.4
//! to 28.8 against 25.9 to 26.1 (the unsorted stack pops far children before near ones,
//! which the closest hit then no longer culls); and, again, the far planes' scale folded
//! into a second inverse direction, this time with an argument that the octant walks then
//! enter every box the scalar test enters. Rounding is monotone, so with `a = rn(plane -
//! origin)` and `c = rn(inv * S')` it is enough that the exact `a c >= rn(a inv) S` where
//! `a inv > 0` (with `t_min >= 0` a negative far distance already lies below `t_enter`);
//! for normal products `S' (1 - u) >= S (1 + u)` holds two ulps above `SLAB_FAR_SCALE`
//! (one falls short by `O(u^2)`); the products stay normal for rays with origin components
//! zero or at least 2^-64 in magnitude and inverse directions between 2^-36 and 2^120 (or
//! infinite: both forms give the same infinity or NaN), in trees whose planes are zero or
//! at least 2^-64, the other rays and trees taking the walk for no octant. A property test
//! of the distances (20,000 cases, failing at zero ulps) and of the walks' masks against
//! `ray_aabb_conservative` passed, and the traversal tests too. Measured against the walk
//! without it (the binaries interleaved, three runs each): 26.5 to 27.3 ms against 26.2 to
//! 26.8, and the first, unguarded version 26.4 to 27.9. The 2% of the first runs (25.3 to
//! 26.0 against 26.1 to 26.2) did not come back: a code-layout effect, not the multiply.
//!
//! Tried on the Zen 5 (AVX-512, family 26) and not kept (one thread, `ray_contest
//! --singles-only --kind bounce --rounds 31 teaser`, each variant behind a switch read per
//! turn and interleaved round by round with the plain walk in one process; medians of the
//! per-round ratios, AVX2 and AVX-512): the second half skipped again, now flagged in the
//! node's reference (a bit the parent's child slot carries, so nothing more is read): 1.00
//! both; the entered children ordered without data-dependent branches (each one's rank
//! among them from SIMD compares of the entry distances, then written to its stack slot):
//! 1.08 and 1.07; two entered children ordered by one select, the nearer kept in registers
//! instead of pushed and popped: 1.01 and 1.00 when ties go to the higher slot first, as the
//! insertion sort's do, but 1.04 and 1.03 when they go to the lower slot; ties (children
//! entered at `t_min`, whose boxes hold the ray's origin) broken by exit distance: 1.04
//! and 1.05 nearest exit first, 1.09 farthest exit first. The tie order alone moves the
//! teaser's reflections by 3%, but none of the orders tried beat slot order.
//!
//! Results are the scalar reference's (`Bvh::occluded`, `Bvh::closest_hit`) ray for ray:
//!
//! * The box test of a child is [`ray_aabb_conservative`] with the interval of the scalar
//!   traversal (`t_min * (1 - BVH_CULL_SLACK)`, `bound * (1 + BVH_CULL_SLACK)`), lane by lane
//!   with the same IEEE operations as the packets (`Packet::enter`), so a child is entered
//!   exactly when the scalar test would enter it under the same bound. The wide tree
//!   skips the intermediate binary boxes, which only lets more leaves be tested.
//! * A leaf's triangles (up to eight, [`WideLeaf`]) are tested at once, one per lane, with
//!   the scalar kernel's operations (`watertight::intersect`, as the packets do; lanes
//!   with an exactly-zero edge function are redone with [`WatertightRay::intersect`]
//!   itself). Hits are taken in slot order with the scalar rule for equal `t` (the lower
//!   triangle index wins), so the closest hit does not depend on the order leaves are
//!   reached in.
//! * A node popped from the stack is skipped when its entry distance lies beyond the
//!   widened closest hit so far: the scalar pop test.
//!
//! The measurements below were taken on the 8-wide nodes ([`WideNode`]) unless they say
//! otherwise.
//!
//! Where the time goes (AMD EPYC, AVX2, one thread; counted with a counter build of this
//! walk, profiled with `perf record` on `ray_contest --singles-only`; before the wide
//! view's SAH collapse, `hyrt_core::bvh::wide`). Per ray: the
//! dragon's shadow rays visit 3.75 wide nodes (7.56 children each) and 0.66 leaves (5.6
//! triangles each), the teaser's 6.4 nodes and 1.1 leaves, the teaser's reflection and
//! refraction rays 13.6 nodes and 3.7 leaves (6.0 triangles each). At about 90 cycles a
//! visit the walk waits on memory: the hottest instructions are the first use of a node's
//! plane row and of a leaf's first vertex row (a leaf is 320 bytes, five lines; a node
//! 256 bytes, four), then reloads of the ray's constants that AVX2's sixteen registers
//! cannot hold (AVX-512's thirty-two can). Embree's single rays ran at 1.36 times these on
//! the dragon's shadow rays (9.4 against 6.9 Mrays/s) and 1.1 to 1.2 times on the
//! teaser's reflections, before the walks were compiled once per ray octant
//! ([`octant_walk!`]: about a fifth fewer instructions per ray, 12 to 20% less time). After
//! it, where the time goes is the same loads of node and leaf lines, spread over the eight
//! copies; a node test's arithmetic is not the bound: computing the slab distances as one
//! fused multiply-subtract per plane (`lo * inv - origin * inv`, Embree's form, which
//! needs an error analysis of its own to stay conservative) measured, before the octant
//! walks, 3 to 4% faster on the dragon's and the far horse's shadow rays and the teaser's
//! reflections, 4% slower on the teaser's shadow rays. Tried and not kept, each measured
//! against the walk above in one process, interleaved rounds: prefetching every pushed
//! child's node or leaf (all its lines; within the noise, the teaser slower), the leaf
//! test's early exit for any hit (about 2% slower), leaves of at most 4 triangles (see
//! `hyrt_core::bvh::wide`), a higher-quality binary tree (obvhs' slow and very slow
//! presets: the same speed on the teaser's reflections), and packets through the frustum
//! test with single rays where it declines them, for the reflections (64 ms against 48 for
//! single rays alone). Also tried: walking `K` rays of one octant in turn, one visit each
//! (the walk as a step function over a per-ray state, rays bucketed by octant per chunk),
//! so that one ray's node and leaf loads overlap another's arithmetic, as pointer-chasing
//! code interleaves lookups. Slower for every `K` (the teaser's reflection and refraction
//! rays, one thread, interleaved rounds in one process: 37.2 ms for the walk above, 45.6
//! for the step function with `K` = 1, 46.4, 51.1 and 53.0 for `K` = 2, 3 and 4): the
//! out-of-order core already overlaps what the interleaving would, and the state kept in
//! memory between visits costs more than it hides. Tried since, for the closest-hit walk
//! on the teaser's reflection and refraction rays (one thread, AVX-512, `ray_contest
//! --singles-only --kind bounce --rounds 15`, the binaries with and without alternated
//! three times, ms), and not kept: each chunk's rays traced grouped by octant (a counting
//! sort of the chunk, answers written back in ray order; 26.2 against 25.4: it breaks up
//! the runs of neighbouring pixels); the children pushed by rank, counted branch-free with
//! lane compares and a population count (28.3 to 29.7 against 25.0 to 26.2, and the
//! frustum packets' primary rays 2 to 12% slower); a node entered on exactly two children
//! visiting the nearer without the insertion loop (25.6 to 25.8 against 25.0 to 25.2).
//! Also not kept (the variant behind a switch, interleaved round by round in one process,
//! `ray_contest --singles-only --kind bounce --rounds 21 --threads 1 teaser`, three runs,
//! ms): the entered children pushed through a sorting network, with no branch on their
//! order (each lane's key its distance's bits with the slot in the low four, the six
//! compare-exchange stages of a bitonic sort of eight keys in one register, the children
//! and distances permuted by the sorted slots and stored as eight entries, the entered
//! ones first), the nearest child taken by a min-reduction of the keys: at AVX-512 26.9,
//! 28.2 and 28.6 against 26.2, 27.1 and 28.0 for the insertion, at AVX2 29.6 and 26.5
//! against 28.9 and 26.2; reading the nearest back from the stack instead of reducing was
//! slower still (about 10%). The insertion mispredicts, but the core runs ahead on its
//! predictions, while the network's six dependent stages sit on the walk's chain at every
//! node with two or more children entered.
//!
//! Against Embree, the teaser's reflection and refraction rays (callgrind `--cache-sim=yes
//! --branch-sim=yes`, AVX2 lanes and Embree's AVX2 `rtcIntersect8`, `ray_contest --kind
//! bounce --threads 1 --singles-only` or `--embree-only`, the traversal alone with
//! `--toggle-collect`; before the SAH collapse): per ray, instructions 3,174 against
//! Embree's 1,731, L1 data misses 19.4 against 11.5, mispredicted branches 34.4 against
//! 24.8. This walk's mispredictions: 11.5 per ray at the branch on how many children a
//! node test entered, 6.8 in the insertion of the entered children by distance, 6.3 at the
//! leaf-or-node decode of the next reference. Embree runs half the instructions and misses
//! less, at a lower rate per cycle: the time was 1.06 times Embree's.
//!
//! Fewer lines per visit, tried and not kept (issue 36; this project's AMD EPYC, family 25,
//! AVX-512 lanes, one thread, `ray_contest --singles-only --kind shadow` and `--kind
//! bounce`, every variant behind a switch and interleaved round by round in one process,
//! medians of 15 rounds, ms; every variant gave the scalar answers ray for ray):
//!
//! * *used lanes*: leaves storing only their used lanes, each leaf's nine vertex rows of
//!   `count` floats back to back in slot order (36 bytes a triangle, the ids apart), read
//!   with the same eight-lane loads (lanes past the count lie outside the active mask);
//! * *4/8 rows*: leaves of at most 4 triangles as rows of 4 floats at 32-byte alignment
//!   (144 bytes, always three lines; 128-bit loads, zeros above), the others as today;
//! * *quantized*: child boxes as bytes (Ylitie et al. 2017), per axis an origin (the
//!   children's least minimum) and a power-of-two scale, each plane rounded outward at
//!   build time and checked with the decode the walk runs (`origin + q as f32 * scale`),
//!   decoded per visit before the unchanged slab test: 128-byte nodes, two lines, and
//!   conservative, hence the same answers;
//! * *looser boxes*: those decoded boxes stored in the full node, to separate the visits
//!   the coarser boxes add from the decode's cost.
//!
//! | rays | today | used lanes | 4/8 rows | quantized | looser boxes |
//! |---|---:|---:|---:|---:|---:|
//! | teaser, shadow | 112.6 | 114.5 | 132.3 | 158.3 | 125.8 |
//! | Sponza, shadow | 103.1 | 105.2 | 116.9 | 154.9 | 119.8 |
//! | near horse, shadow | 8.39 | 8.77 | 8.99 | 10.57 | 8.61 |
//! | far horse, shadow | 0.92 | 1.04 | 1.05 | 1.17 | 0.94 |
//! | near bunny, shadow | 14.34 | 14.75 | 15.26 | 17.91 | 14.75 |
//! | far bunny, shadow | 6.12 | 6.43 | 6.64 | 7.69 | 6.40 |
//! | dragon, shadow | 85.9 | 85.0 | 91.6 | 102.4 | 87.2 |
//! | teaser, reflections and refractions | 26.4 | 26.9 | 27.8 | 31.7 | 27.5 |
//!
//! Callgrind (AVX2, `--cache-sim=yes --branch-sim=yes`, the near bunny's shadow rays), per
//! ray in the same order: instructions 1,081, 1,102, 1,181, 1,280 and 1,106; L1 data misses
//! (its 32 KB L1) 4.91, 4.08, 4.60, 4.03 and 4.97; mispredicted branches 5.60, 5.63 and
//! 6.75 for the first three. The wide leaves hold 5.1 to 5.9 triangles on these scenes, so
//! used lanes save a third of the leaf bytes (the dragon's 52 MB to 31 MB, the teaser's 7.9
//! to 4.9) and a sixth of the L1 misses, for 2% more instructions (a row's address is
//! `9 first + (3 i + k) count` with the ray's axis `k`). That pays only where the leaves
//! outgrow the 32 MB L3: the dragon, 0 to 6% faster at AVX-512 in six runs and 12% at AVX2
//! (104.9 against 92.3 ms, one run); elsewhere the leaves stay in L2 and L3, and it was 2 to
//! 5% slower (the far horse's 6,085 rays 13%). The 4/8 rows lose on the branch between the
//! two leaf tests. Quantized nodes lose twice: the coarser boxes alone cost 2 to 16% (Sponza
//! and the teaser most) in added visits, and the decode (per node three origin and three
//! scale broadcasts, six conversions, multiplies and adds: 16% more instructions than the
//! same boxes stored in full) costs more than loading half the node lines saves. So a node
//! test's added arithmetic is not hidden behind its loads on this machine; a decode folded
//! into the slab distances (Embree's `q * (scale * inv) + (origin - o) * inv`) would need
//! an error bound of its own to stay conservative.
//!
//! Where the closest-hit walk's time goes, and four more variants not kept (issue 36; the
//! teaser's reflection and refraction rays, AMD EPYC, one thread, `ray_contest
//! --singles-only --kind bounce --rounds 15` to `21`, variants behind a switch in one
//! process unless said otherwise, ms; every variant gave the scalar answers ray for ray):
//!
//! * *Cache misses are not the bound.* Every ray traced twice in a row, the second walk
//!   finding its nodes and leaves in L1: 50.0 against 26.1 once, so the second walk
//!   costs 24. Loads that miss take under a tenth of the time; the rest is the chain from
//!   a node's plane rows through the slab distances and the entered mask to the next
//!   child's reference, and the mispredicted branches on it. This is why the variants with
//!   fewer lines per visit above lost to their added instructions.
//! * *Embree's hybrid for closest hit.* Those of eight consecutive rays that share an
//!   octant walk the wide nodes together (each child's box for all lanes, the lanes' mask
//!   and entry distances on a packet stack, Embree's rule for the next child: one nearer
//!   for some lane replaces it), each lane going on alone from a leaf, or from a node that
//!   at most `T` lanes enter, with its closest hit so far: 28.1 against 25.1 at Embree's
//!   `T` = 7, 28.1 at `T` = 4. Per ray 0.69 node visits of the packet (of about 14) and 2.5
//!   restarts alone: these rays share little of the tree, and the top nodes they share
//!   stay in L1. (Embree's `rtcIntersect8` is about 5% faster than its `rtcIntersect1` on
//!   these rays, and this walk about as fast as `rtcIntersect1`.)
//! * *The previous ray's leaf first* (the leaf that held the previous ray's hit tested
//!   before the root, for a tight bound from the start, and skipped when reached again):
//!   26.2 against 25.8.
//! * *Children ordered by octant at the collapse* (Ylitie et al. 2017: slot `s` takes the
//!   child lying furthest towards the corner with sign bits `s`, greedily by the dot
//!   product of its centre's offset with that diagonal; empty slots between), visited in
//!   the order `j ^ octant` (the entered mask permuted by bit swaps or by a table), the
//!   others pushed far to near without a branch (no insertion, no branch on how many
//!   children were entered): 26.0 against 25.7 for the insertion on the same tree, 27.0 to
//!   27.2 against 26.7 in a second run; that order on the tree as collapsed, 30.2.
//! * *The far scale folded into a second inverse direction*, `(far - origin) * inv_far`
//!   with `inv_far = inv_dir * (SLAB_FAR_SCALE + 2^-22)`: one product fewer on the chain,
//!   and a superset of the scalar test's boxes (proved and property-tested for rays with
//!   `t_min >= 0`, inverse directions of at least 2^-30 and every origin and plane
//!   coordinate zero or at least 2^-64, other rays left to the generic walk). 2.3% faster
//!   behind a switch in one binary at AVX-512 and AVX2, but as its own binary, alternated
//!   three times with the previous one: AVX2 26.33 to 26.76 against 26.35 to 26.77,
//!   AVX-512 26.51 to 27.10 against 26.14 to 26.40. (Also within the noise: prefetching
//!   each node's line of child references on arrival; the nearest child kept in registers
//!   through the insertion, a compare and a select per child, instead of read back from
//!   the stack: 26.58 to 26.81 against 26.23 to 26.77, separate binaries.)
//!
//! What a reflection or refraction ray of the teaser does (counted with a throw-away
//! counter build, the 75,526 rays traced three times): 13.5 wide node visits, of which
//! 20% enter no child, 46% one, 18% two, 10% three and 5% more; 3.7 leaf visits, 1.04 of
//! them with a hit, and the first leaf hit is nearly always the final one (1.03 closest
//! hits improved per ray); 1.9 stack entries culled at the pop; 98% of the rays hit. The
//! set-up of the rays alone (each ray prepared and dropped before its walk) takes 0.64 ms
//! of the 25.5, so Embree's eight-ray set-up in `rtcIntersect8` cannot explain more than
//! 2 of its 5% over `rtcIntersect1`. Callgrind (AVX2, `--branch-sim=yes`, a crude
//! predictor model): 3,165 instructions, 307 branches and 34.5 mispredictions per ray;
//! the most at the branch on none, one or several children entered (11.5), the insertion
//! (6.8), the node-or-leaf decode (6.0), the push loop's exit (3.8) and the leaf test's
//! early exit (1.9).
//!
//! The closest-hit walk now tests leaves without that early exit (every lane through the
//! depth, the division and the bound; the any-hit walk already did), and its octant
//! walks take only rays whose inverse directions are finite (the others go to the
//! generic walk), so the node test has no branch on it; the plane rows are the node's
//! fields ([`WideNode16::near_far`]), with no run-time alignment check of a byte view. The
//! teaser's reflections, one thread, `ray_contest --singles-only --kind bounce --rounds
//! 41`, the binaries alternated five times, ms: AVX-512 25.2 to 25.5 against 25.6 to 26.2,
//! AVX2 25.8 to 26.5 against 25.9 to 26.4 (unchanged). The same finite-direction split in
//! the any-hit walk made its shadow rays 2 to 5% slower (the teaser 113 against 108 ms,
//! the near horse 8.3 against 8.1), so that walk keeps its branch; computing the leaf
//! test's error bound without its branch on any lane hit was 4% slower. The entry
//! distances of a node's children stay in their register and the insertion takes each by
//! a permute (`Lanes::lane`), not by a store of the eight and a narrower load from it:
//! 24.4 to 24.6 against 24.5 to 25.1 ms at AVX-512, 24.6 to 25.3 against 24.9 to 25.5 at
//! AVX2 (seven pairs).
//!
//! Tried after those and not kept (same measurement, separate binaries alternated three
//! or four times, ms): a node entered on exactly two children taking the nearer by
//! selects and pushing the other (Embree's two-child case, no branch on their order and
//! no insertion): 24.2 to 24.9 against 24.2 to 24.7, neutral; the leaf bits of a node's
//! children read with one sign-mask of its child references, so that a one-child descent
//! into an inner node skips the node-or-leaf decode: 24.0 to 24.4 against 23.7 to 24.0 at
//! AVX-512, 24.8 to 25.3 against 24.0 to 24.8 at AVX2 (the decode it skips is predicted
//! from the branch just before it); `codegen-units = 1` for the release build: within the
//! noise. The generic walk alone (no octant copies, the plane rows picked per ray at run
//! time) was only 1 to 3% slower on these rays (AVX-512 24.5 to 25.2 against 24.4 to 24.8,
//! AVX2 25.3 to 25.6 against 24.8), against 12 to 20% on shadow rays: rays of mixed
//! octants spread over eight copies of the walk's branches. The generic walk with each
//! ray's plane rows picked once (row indices into the node read as rows) instead of per
//! node was slower still: 25.4 to 26.1 against 24.9 to 26.0 at AVX-512, 26.6 to 27.3
//! against 25.7 to 25.9 at AVX2. Where the row stands against Embree after these (`hyrt
//! bench --quick`, 2 threads): 0.96 at AVX-512 and 0.95 with `--simd avx2`, hyrt's single rays ahead of
//! Embree's `rtcIntersect1` (12.44 against 12.84 ms) and 3 to 4% behind its
//! `rtcIntersect8`. (That contest runs its contenders in a fixed cyclic order, so Embree's
//! `rtcIntersect8` always follows its `rtcIntersect1` on the same tree, warm; in
//! `ray_contest`, where it follows hyrt's single rays, it took 24.9 ms against the
//! report's 24.3 at one thread, hyrt's single rays 25.2 and 25.1. With every contender's
//! pass run three times in a row, `--passes 3`, hyrt's ratio was 0.98 and 0.99 against
//! 1.00 and 1.01 for one pass: Embree's more compact tree gains more from warm caches.)
//!
//! Where the closest-hit walk's samples fall (`perf record -e cpu-clock` on `ray_contest
//! --singles-only --kind bounce --threads 1`, AVX-512, one octant copy of the walk): the
//! node test 36%, the insertion of several entered children 20%, the leaf test and its
//! hits 35%, the pops 5%, the one-child descent 4%. Tried against that and not kept (the
//! teaser's reflection and refraction rays, one thread, AVX-512, `ray_contest
//! --singles-only --kind bounce --rounds 11` to `15`, separate binaries or a switch read
//! once, alternated three or four times, ms; every variant gave the scalar answers):
//!
//! * *Other trees.* The wide view collapsed from other obvhs trees of the same triangles:
//!   leaves of one triangle (the collapse then forms every wide leaf itself), obvhs' leaf
//!   collapse at traversal costs 1, 3 and 5, its spatial pre-splits with leaves of one or
//!   up to eight triangles: 23.6 to 26.9 against 23.7 to 25.9 for today's tree, all within
//!   the noise. The tree is not where these rays lose.
//! * *No bounds checks* on the walk's node, leaf, stack and child reads (unchecked
//!   indexing, as an experiment): 25.5 to 26.3 against 25.5 to 25.8. The checks (about a
//!   hundred instructions a ray) are predicted and cost nothing measurable.
//! * *Eight rays prepared at once* (the constants of [`WideRay`] for eight consecutive
//!   rays computed lane-wise as `Packet::new` does, each walk starting from broadcasts of
//!   its lane): 25.4 to 27.0 against 25.1 to 26.4. The set-up is off the walk's chain.
//!
//! Whether a contender starts warm matters more than these: `ray_contest --cold 96` reads
//! 96 MB on every worker before each timed turn, and the teaser's reflections then run
//! at 0.99 to 1.00 of Embree's `rtcIntersect8` at two threads, as without it (three
//! alternations), while the report's contest, where `rtcIntersect8` follows
//! `rtcIntersect1` on the same tree and hyrt's single rays follow its packets on the
//! binary tree, gave 0.96 (0.90 to 0.99) at the same commit. A frame does the same: its
//! bounce stage follows the shadow stage, whose packets walk the binary tree and its leaf
//! records, not the wide view. Sharing one set of leaves between the packets and the
//! single rays (the one wide tree) is what would give these rays warm leaves.
//!
//! [`ray_aabb_conservative`]: hyrt_core::kernels::ray::ray_aabb_conservative
//! [`WideNode`]: hyrt_core::bvh::wide::WideNode

use glam::Vec3;
use hyrt_core::bvh::wide::{WideBvh, WideChild, WideLeaf, WideNode16, WIDE, WIDE16, WIDE16_STACK_SIZE};
use hyrt_core::bvh::{ClosestHit, BVH_CULL_SLACK};
use hyrt_core::formats::{RayRecord, INVALID_ID};
use hyrt_core::kernels::ray::{
    permute_axes, permuted_axis_order, safe_inverse_dir, TriangleHit, WatertightRay, SLAB_FAR_SCALE,
};

use super::watertight::{self, LaneHits, RaySpace};
use super::ANY_OCTANT;
use crate::lanes::{slab_bounds, Lanes, LANES};

const _: () = assert!(hyrt_core::bvh::wide::WIDE == LANES);

/// The traversal stack of one ray: (child reference, entry distance). Allocated once per
/// chunk of rays and reused.
pub(crate) type Stack = Vec<(u32, f32)>;

/// A stack with room for any tree `Bvh::build` returns (for the 16-wide nodes, so also
/// for the 8-wide ones of the frustum walk).
pub(crate) fn new_stack() -> Stack {
    vec![(0, 0.0); WIDE16_STACK_SIZE]
}

/// One ray prepared for the wide traversal: the scalar traversal's constants, and the
/// slab test's origin and inverse direction in every lane.
struct WideRay<L: Lanes> {
    wt: WatertightRay,
    t_min: f32,
    t_max: f32,
    origin: [L::F; 3],
    inv_dir: [L::F; 3],
    /// The ray's octant: bit `a` set where the inverse direction's component `a` is
    /// negative (its sign bit, as the scalar slab test reads it). The walks are compiled
    /// once per octant ([`octant_walk!`]), so a node test loads its near and far plane rows
    /// from constant offsets ([`WideNode16::near_far`]).
    octant: u8,
    /// The leaf vertices' rows in the ray's axis order (`permute_axes`'s `kx, ky, kz`):
    /// picked once per ray instead of once per leaf row.
    vertex_rows: [usize; 3],
    /// No inverse direction is infinite: no slab distance is NaN.
    finite_inv: bool,
    box_t_min: L::F,
    /// The watertight constants in every lane: the origin in the permuted axis order
    /// (`permute_axes(origin, kz)`), the shear, the interval.
    origin_perm: [L::F; 3],
    shear: [L::F; 3],
    t_min_lanes: L::F,
    t_max_lanes: L::F,
}

impl<L: Lanes> WideRay<L> {
    /// `None` for a ray the scalar traversal rejects (`TraversalRay::new`): non-finite or
    /// zero direction, non-finite origin, empty or NaN interval.
    #[inline(always)]
    fn new(ray: &RayRecord) -> Option<Self> {
        let (o, d) = (Vec3::from(ray.origin), Vec3::from(ray.direction));
        let wt = WatertightRay::new(o, d)?;
        // Positive form, so that NaN bounds reject.
        let non_empty = ray.t_min < ray.t_max;
        if !non_empty {
            return None;
        }
        let inv = safe_inverse_dir(d);
        let op = permute_axes(o, wt.kz);
        Some(WideRay {
            origin_perm: [L::splat(op.x), L::splat(op.y), L::splat(op.z)],
            shear: [L::splat(wt.shear.x), L::splat(wt.shear.y), L::splat(wt.shear.z)],
            t_min_lanes: L::splat(ray.t_min),
            t_max_lanes: L::splat(ray.t_max),
            wt,
            t_min: ray.t_min,
            t_max: ray.t_max,
            origin: [L::splat(o.x), L::splat(o.y), L::splat(o.z)],
            inv_dir: [L::splat(inv.x), L::splat(inv.y), L::splat(inv.z)],
            octant: (0..3).map(|a| (inv[a].is_sign_negative() as u8) << a).sum(),
            vertex_rows: permuted_axis_order(wt.kz),
            finite_inv: inv.is_finite(),
            box_t_min: L::splat(ray.t_min * (1.0 - BVH_CULL_SLACK)),
        })
    }

    /// The slab test of the node's children for `[box_t_min, t_far]`, one half of eight
    /// at a time: the mask of children entered (child `8 h + k` at bit `8 h + k`) and each
    /// half's entry distances. `O` is the ray's octant, or [`ANY_OCTANT`] to read it from
    /// the ray; `finite_inv` is [`Self::finite_inv`], or `true` where the caller's walk
    /// takes only such rays (as `packet`'s `enter_signed`).
    #[inline(always)]
    fn enter<const O: u8>(&self, node: &WideNode16, t_far: L::F, finite_inv: bool) -> (u32, [L::F; 2]) {
        debug_assert!(O == ANY_OCTANT || O == self.octant);
        debug_assert!(!finite_inv || self.finite_inv);
        let octant = if O == ANY_OCTANT { self.octant } else { O };
        let mut mask = 0;
        let mut entry = [t_far; 2];
        for (h, entry) in entry.iter_mut().enumerate() {
            let mut tn = [self.box_t_min; 3];
            let mut tf = [t_far; 3];
            for a in 0..3 {
                let (near, far) = node.near_far(a, octant >> a & 1 != 0);
                tn[a] = L::mul(L::sub(L::load(&near[h]), self.origin[a]), self.inv_dir[a]);
                tf[a] =
                    L::mul(L::mul(L::sub(L::load(&far[h]), self.origin[a]), self.inv_dir[a]), L::splat(SLAB_FAR_SCALE));
            }
            let (t_enter, t_exit) = slab_bounds::<L>(tn, tf, self.box_t_min, t_far, finite_inv);
            mask |= opaque(L::bits(L::le(t_enter, t_exit))) << (WIDE * h);
            *entry = t_enter;
        }
        // No mask of the used children: an unused child has the empty box (`lo = +inf`,
        // `hi = -inf`), whose near distance on every axis is `+inf` and far distance
        // `-inf` (an infinite plane minus a finite origin, times a non-zero inverse: never
        // NaN), so no ray enters it (tested: `unused_children_are_never_entered`). Reading
        // `count` would take the node's eighth cache line at every visit: without it the
        // teaser's reflections took 26.8 to 28.6 ms against 27.8 to 29.3 (Zen 3, AVX2, one
        // thread, `ray_contest --singles-only --kind bounce --rounds 11`, the two binaries
        // alternated three times).
        debug_assert_eq!(mask >> node.count, 0, "an unused child entered");
        (mask, entry)
    }
}

impl<L: Lanes> WideRay<L> {
    /// The watertight test against the leaf's first `count` triangles, one per lane: the
    /// lanes hit and their `t, u, v`, determinant. Lanes the lane form cannot decide
    /// (`LaneHits::exact`) are left to [`Self::exact_lane`]. Without the early exit of
    /// [`watertight::intersect`] for both walks: a leaf is entered alone, by one ray, and
    /// the branch on whether any lane passed the edge tests mispredicts more than the depth
    /// and the division it skips cost (closest hit on the teaser's reflection and
    /// refraction rays; any hit measured so before).
    #[inline(always)]
    fn intersect_leaf(&self, leaf: &WideLeaf, count: u32) -> LaneHits<L> {
        let p = [self.transform(&leaf.v[0]), self.transform(&leaf.v[1]), self.transform(&leaf.v[2])];
        let active = (1u32 << count) - 1;
        watertight::intersect::<L, false>(active, p, &self.shear, self.t_min_lanes, self.t_max_lanes)
    }

    /// One vertex of every lane in ray space (`WatertightRay::transform`): the rows in the
    /// ray's axis order, then [`watertight::ray_space`].
    #[inline(always)]
    fn transform(&self, v: &[[f32; LANES]; 3]) -> RaySpace<L> {
        let [kx, ky, kz] = self.vertex_rows;
        let v = [L::load(&v[kx]), L::load(&v[ky]), L::load(&v[kz])];
        watertight::ray_space::<L>(v, &self.origin_perm, &self.shear)
    }

    /// The scalar kernel on lane `k` of a leaf.
    #[inline(never)]
    fn exact_lane(&self, leaf: &WideLeaf, k: usize) -> Option<TriangleHit> {
        let v = |i| Vec3::from(leaf.vertex(i, k));
        self.wt.intersect(self.t_min, self.t_max, v(0), v(1), v(2))
    }
}

/// `x`, through an empty `asm!` so that the compiler cannot see its origin: the two
/// halves' sign masks of [`WideRay::enter`] then stay two `movmskps` and an `or` (at
/// AVX-512 two mask moves). Without it, LLVM merges the two compares into one mask by
/// packing them (`vpackssdw`, `vextracti128`, `vpacksswb`, `vpshufd`, `vpmovmskb` at AVX2;
/// `vinsertf64x4`, `vpmovd2m` at AVX-512), a longer chain from the box tests to the next
/// node. Measured on the teaser's reflections (one thread, `ray_contest --singles-only
/// --kind bounce --rounds 11`, the two binaries alternated three times, ms): AVX2 24.2 to
/// 25.0 against 25.1 to 25.5, AVX-512 23.4 to 23.7 against 24.1 to 24.3.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn opaque(mut x: u32) -> u32 {
    // SAFETY: an empty instruction string; it reads and writes `x` only, in a register.
    unsafe {
        std::arch::asm!("/* {0:e} */", inout(reg) x, options(pure, nomem, nostack, preserves_flags));
    }
    x
}

/// `x` as it is (no `asm!` barrier off x86-64).
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn opaque(x: u32) -> u32 {
    x
}

/// Push the children in `mask` (entry `id(k)` for child `k`) with their entry distances,
/// the nearest on top (ties in stored order; the order changes no result).
#[inline(always)]
pub(super) fn push_nearest_last(
    mut mask: u32,
    t: impl Fn(usize) -> f32,
    id: impl Fn(usize) -> u32,
    stack: &mut [(u32, f32)],
    sp: &mut usize,
) {
    let base = *sp;
    while mask != 0 {
        let k = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        let e = (id(k), t(k));
        // Insertion from the top: entries nearer than `e` move up.
        let mut j = *sp;
        while j > base && stack[j - 1].1 < e.1 {
            stack[j] = stack[j - 1];
            j -= 1;
        }
        stack[j] = e;
        *sp += 1;
    }
}

/// The closest hit of one ray through `wide`, equal to `Bvh::closest_hit`.
#[inline(always)]
pub(crate) fn closest_hit<L: Lanes>(wide: &WideBvh, ray: &RayRecord, stack: &mut [(u32, f32)]) -> Option<ClosestHit> {
    let r = WideRay::<L>::new(ray)?;
    octant_walk!(if r.finite_inv => r.octant, closest_hit_in::<L>(wide, &r, stack))
}

/// [`closest_hit`] for a ray of octant `O` (or [`ANY_OCTANT`]).
#[inline(always)]
fn closest_hit_in<L: Lanes, const O: u8>(
    wide: &WideBvh,
    r: &WideRay<L>,
    stack: &mut [(u32, f32)],
) -> Option<ClosestHit> {
    let widen = 1.0 + BVH_CULL_SLACK;
    let mut best = ClosestHit { triangle: INVALID_ID, t: r.t_max, u: 0.0, v: 0.0, back_face: false };
    let mut t_far = r.t_max * widen;
    let mut t_far_lanes = L::splat(t_far);
    // The node or leaf being visited (the root first), and the stack of those entered
    // but not visited yet.
    let mut current = 0u32;
    let mut sp = 0usize;
    'walk: loop {
        match WideChild::decode(current) {
            WideChild::Node(n) => {
                let node = &wide.nodes16[n as usize];
                // The octant walks take only rays with finite inverse directions.
                let (mask, t) = r.enter::<O>(node, t_far_lanes, O != ANY_OCTANT || r.finite_inv);
                if mask & mask.wrapping_sub(1) == 0 && mask != 0 {
                    // One child entered: visit it next.
                    current = node.child[mask.trailing_zeros() as usize & (WIDE16 - 1)];
                    continue 'walk;
                }
                if mask != 0 {
                    // Several: the nearest next, the others on the stack. The entry
                    // distances stored once and read by slot (a permute per child would
                    // first branch on its half).
                    let (t0, t1) = (L::store(t[0]), L::store(t[1]));
                    let t: [f32; WIDE16] = std::array::from_fn(|k| if k < WIDE { t0[k] } else { t1[k - WIDE] });
                    push_nearest_last(mask, |k| t[k & (WIDE16 - 1)], |k| node.child[k & (WIDE16 - 1)], stack, &mut sp);
                    sp -= 1;
                    current = stack[sp].0;
                    continue 'walk;
                }
            }
            WideChild::Leaf { leaf, count } => 'leaf: {
                let leaf = &wide.leaves[leaf as usize];
                let h = r.intersect_leaf(leaf, count);
                if h.hit | h.exact == 0 {
                    break 'leaf;
                }
                let (t, u, v, det) = (L::store(h.t), L::store(h.u), L::store(h.v), L::store(h.det));
                let mut improved = false;
                // Slot order, as the scalar leaf loop.
                let mut lanes = h.hit | h.exact;
                while lanes != 0 {
                    let k = lanes.trailing_zeros() as usize;
                    lanes &= lanes - 1;
                    let hit = if h.exact >> k & 1 != 0 {
                        r.exact_lane(leaf, k)
                    } else {
                        Some(TriangleHit { t: t[k], u: u[k], v: v[k], back_face: r.wt.back_face(det[k]) })
                    };
                    if let Some(hit) = hit {
                        improved |= best.take_if_closer(leaf.ids[k], hit);
                    }
                }
                if improved {
                    t_far = best.t * widen;
                    t_far_lanes = L::splat(t_far);
                }
            }
        }
        // Pop the next entry still worth visiting: the scalar pop test (entries pushed
        // under the current bound pass it).
        loop {
            if sp == 0 {
                break 'walk;
            }
            sp -= 1;
            let (child, t_enter) = stack[sp];
            if t_enter <= t_far {
                current = child;
                continue 'walk;
            }
        }
    }
    (best.triangle != INVALID_ID).then_some(best)
}

/// Any hit of one ray through `wide`, equal to `Bvh::occluded`. Children are visited in
/// stored order (the first hit ends the walk; ordering them would cost more than it
/// saves on shadow rays), branchy as tinybvh's and Embree's any-hit walks: the first
/// child entered is visited next without going through the stack, the others are pushed
/// (the last first), so a node entered on one child only, the common case, costs no
/// stack traffic. (Measured against pushing every child and popping the first, the same
/// binary, interleaved rounds, one thread, `ray_contest --singles-only --kind shadow`: 2
/// to 7% faster on the dragon, the far bunny, the near horse and the teaser.)
#[inline(always)]
pub(crate) fn occluded<L: Lanes>(wide: &WideBvh, ray: &RayRecord, stack: &mut [(u32, f32)]) -> bool {
    let Some(r) = WideRay::<L>::new(ray) else {
        return false;
    };
    octant_walk!(r.octant, occluded_in::<L>(wide, &r, stack))
}

/// [`occluded`] for a ray of octant `O` (or [`ANY_OCTANT`]).
#[inline(always)]
fn occluded_in<L: Lanes, const O: u8>(wide: &WideBvh, r: &WideRay<L>, stack: &mut [(u32, f32)]) -> bool {
    let t_far = L::splat(r.t_max * (1.0 + BVH_CULL_SLACK));
    let mut current = 0u32;
    let mut sp = 0usize;
    loop {
        match WideChild::decode(current) {
            WideChild::Node(n) => {
                let node = &wide.nodes16[n as usize];
                let mut mask = r.enter::<O>(node, t_far, r.finite_inv).0;
                if mask != 0 {
                    let first = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    while mask != 0 {
                        let k = 31 - mask.leading_zeros() as usize;
                        mask &= !(1 << k);
                        stack[sp].0 = node.child[k & (WIDE16 - 1)];
                        sp += 1;
                    }
                    current = node.child[first & (WIDE16 - 1)];
                    continue;
                }
            }
            WideChild::Leaf { leaf, count } => {
                let leaf = &wide.leaves[leaf as usize];
                let h = r.intersect_leaf(leaf, count);
                if h.hit != 0 {
                    return true;
                }
                let mut exact = h.exact;
                while exact != 0 {
                    let k = exact.trailing_zeros() as usize;
                    exact &= exact - 1;
                    if r.exact_lane(leaf, k).is_some() {
                        return true;
                    }
                }
            }
        }
        if sp == 0 {
            return false;
        }
        sp -= 1;
        current = stack[sp].0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lanes::Portable;
    use proptest::prelude::*;

    /// `WideRay::enter` for the octant `O`.
    fn enter<const O: u8>(r: &WideRay<Portable>, node: &WideNode16, t_far: f32) -> u32 {
        r.enter::<O>(node, Portable::splat(t_far), r.finite_inv).0
    }

    /// A coordinate: zeros of both signs and values on the boxes' planes often.
    fn coordinate() -> impl Strategy<Value = f32> {
        prop_oneof![Just(0.0f32), Just(-0.0f32), Just(1.0f32), Just(-1.0f32), -4.0f32..4.0]
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 1024, ..ProptestConfig::default() })]

        /// The node test never enters a child past the node's count (the empty box), for
        /// any ray the walks take: directions with zero components of either sign
        /// (infinite inverses, the walk for any octant), origins on the used boxes'
        /// planes, any far bound. The walks rely on it instead of masking by `count`.
        #[test]
        fn unused_children_are_never_entered(
            o in [coordinate(), coordinate(), coordinate()],
            d in [coordinate(), coordinate(), coordinate()],
            t_min in prop_oneof![Just(0.0f32), 0.0f32..1.0],
            t_max in prop_oneof![Just(f32::INFINITY), 1.0f32..100.0],
            t_far in prop_oneof![Just(f32::INFINITY), Just(f32::MAX), 0.0f32..100.0],
            boxes in prop::collection::vec(([coordinate(), coordinate(), coordinate()], [0.0f32..2.0, 0.0f32..2.0, 0.0f32..2.0]), WIDE16),
            count in 1usize..=WIDE16,
        ) {
            let ray = RayRecord { origin: o, t_min, direction: d, t_max, ..bytemuck::Zeroable::zeroed() };
            let Some(r) = WideRay::<Portable>::new(&ray) else {
                // Rejected before any node test (a zero direction).
                return Ok(());
            };
            let mut node = WideNode16::empty(count as u32);
            for (k, (c, h)) in boxes.iter().take(count).enumerate() {
                for a in 0..3 {
                    node.lo[a][k / WIDE][k % WIDE] = c[a] - h[a];
                    node.hi[a][k / WIDE][k % WIDE] = c[a] + h[a];
                }
            }
            prop_assert_eq!(enter::<ANY_OCTANT>(&r, &node, t_far) >> count, 0);
            if r.finite_inv {
                let mask = match r.octant {
                    0 => enter::<0>(&r, &node, t_far),
                    1 => enter::<1>(&r, &node, t_far),
                    2 => enter::<2>(&r, &node, t_far),
                    3 => enter::<3>(&r, &node, t_far),
                    4 => enter::<4>(&r, &node, t_far),
                    5 => enter::<5>(&r, &node, t_far),
                    6 => enter::<6>(&r, &node, t_far),
                    _ => enter::<7>(&r, &node, t_far),
                };
                prop_assert_eq!(mask >> count, 0);
            }
        }
    }

    /// The test above reaches the non-finite walk: a ray along an axis, from the plane of a
    /// used box, enters that box and nothing else.
    #[test]
    fn a_ray_along_an_axis_enters_only_its_box() {
        let ray = RayRecord {
            origin: [0.0, 1.0, -5.0],
            t_min: 0.0,
            direction: [0.0, 0.0, 1.0],
            t_max: f32::INFINITY,
            ..bytemuck::Zeroable::zeroed()
        };
        let r = WideRay::<Portable>::new(&ray).unwrap();
        assert!(!r.finite_inv);
        let mut node = WideNode16::empty(1);
        for a in 0..3 {
            node.lo[a][0][0] = [-1.0, 1.0, -1.0][a];
            node.hi[a][0][0] = [1.0, 2.0, 1.0][a];
        }
        assert_eq!(enter::<ANY_OCTANT>(&r, &node, f32::INFINITY), 1);
    }
}
