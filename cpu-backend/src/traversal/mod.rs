//! Batch ray traversal: every ray of a list through the scene's [`Bvh`], one ray at a
//! time with the scalar reference ([`Bvh::occluded`], [`Bvh::closest_hit`]), in packets
//! of [`LANES`] consecutive rays traced together with SIMD (module `packet`: primary and
//! shadow rays), or one ray at a time through the 16-wide nodes of the same tree's wide
//! view with SIMD box and leaf tests (module `single`: reflection and refraction rays,
//! which spread out).
//! Closest-hit packets whose rays travel together (primary rays from one eye) go through
//! the 8-wide view instead, one frustum test per wide node for the whole packet (module
//! `frustum`); the others, and every any-hit packet, walk the binary tree.
//!
//! All give the same answer for every ray: the SIMD code runs the scalar kernels'
//! IEEE operations lane by lane (see `packet` for the argument and the one closest-hit
//! rounding corner case that `BVH_CULL_SLACK` documents). The tests in
//! `cpu-backend/tests/traversal.rs` compare them ray by ray, and
//! `conformance/tests/traversal.rs` over the whole conformance corpus.
//!
//! Packets need no per-scene structure: they walk the core binary BVH as it is (sibling
//! pairs share a cache line, so one packet box test per child reads one line), which
//! keeps `bvh_build` unchanged and the GPU and CPU on the very same tree. (A 4-wide tree
//! collapsed from it, same boxes and leaves, was tried and measured slower for these
//! packets: about 14 instead of 21 Mrays/s on the teaser's shadow rays, one thread. Testing
//! four grandchildren skips the two intermediate boxes that cull for the packet, and the
//! traversal is bound by the latency of the node-to-node dependency chain more than by
//! instruction count.)
//!
//! Consecutive rays make a packet; the stage's lists are light-major then pixel-major, so
//! a packet is a short run of neighbouring pixels and their rays are coherent. A frame's
//! shadow rays made from compaction's (light, pixel) pairs as they are traced
//! ([`occluded_pairs_tiled_into`], the frame without stage outputs) are made and traced in
//! 2x4 pixel tiles instead (module `tiles`): measured on the frame's `shadow_rays` stage
//! (`hyrt render assets/scenes/<scene>.toml --frames 9 --threads 1 --max-depth 0`, the
//! previous and the new binary alternated five or six times, median of the pair ratios):
//! teaser and Sponza 0.91, the near and far bunnies and the near horse 0.88, the far horse
//! 0.82, the dragon 1.00; images identical. A list given as records is traced in its own
//! order: copying its 64-byte records into tile order cost more than it saved on the
//! teaser and Sponza (per window and per packet both tried; also earlier: 28.6 against
//! 30.4 Mrays/s, one thread). [`sort_into_tiles`] puts such a list in tile order once, for
//! a caller that traces it more than once or hands it to another tracer too (`hyrt bench`'s
//! peers: the tile order lifted hyrt's packets against Embree's `rtcOccluded8`, which gains
//! less from it, from 0.92 to 1.11 on the far horse and from 1.01 to 1.04 on the dragon).
//!
//! Any hit: each packet first tries the triangle that stopped a lane of the previous
//! packet of its chunk (neighbouring pixels, same light: often the same occluder), then the
//! rest of that triangle's leaf, which changes no result (the argument is at
//! `packet::occluded`); 15 to 25% faster on the teaser's and Sponza's shadow rays. Lanes
//! diverge gracefully: each stack entry carries the mask of lanes that entered the node,
//! so a lane drops out of subtrees it misses, and rays with different direction signs
//! take per-lane near planes. A leaf entered by fewer lanes than it holds triangles is
//! tested one lane at a time, each lane's ray against all its triangles at once (the
//! records transposed into lanes, `Lanes::triangle_lanes`; the undecided and alpha-tested
//! hits confirmed by the packet test, `packet::occluded_lanes_alone`): where lanes part,
//! at the leaves around their own origins, that replaces one mostly idle packet test per
//! triangle. A packet with fewer than two valid rays is traced one ray at a time with the
//! scalar code (the per-packet fallback).
//!
//! SIMD level: AVX2 (8 lanes in one register) when the CPU has it, compiled for AVX-512
//! too where the CPU has that (same operations, more registers and mask registers), else
//! SSE2 (two 4-lane registers, the x86-64 baseline), else plain arrays; chosen at run
//! time, stable Rust only. All give the same bits.
//!
//! Where the time goes on the scenes where Embree's packets were faster (shadow rays
//! leaving dense scanned meshes, the list order of the frame, one thread). Leaf visits and
//! the lanes that entered them, counted over the contest's rays before the lone-lane leaf
//! test:
//!
//! | scene | leaf visits per packet | by 1 lane | by 2 | by 8 | triangles per leaf |
//! |---|---:|---:|---:|---:|---:|
//! | teaser | 3.2 | 19% | 15% | 29% | 4.2 |
//! | dragon | 5.6 | 51% | 28% | 0.1% | 4.1 |
//! | bunny far | 17 | 42% | 29% | 0.3% | 4.4 |
//! | horse far | 23 | 50% | 30% | 0% | 4.4 |
//!
//! Those leaves surround each ray's own origin: entered and tested, their triangles all
//! rejected (the hit would be at `t` near 0, under `t_min`); a lane reaches them alone,
//! which is what the lone-lane leaf test serves. Callgrind (AVX2, `--cache-sim=yes
//! --branch-sim=yes`, the dragon's and the near bunny's shadow rays, before that test):
//! instructions per ray, hyrt's packets 1,026, hyrt's single rays 668, Embree's
//! `rtcOccluded8` 380; L1 data misses 4.6, 3.6 and 3.2; mispredicted branches 4.2, 3.2 and
//! 3.3. Embree's BVH8 packets switch to single rays as soon as a lane drops out (its
//! hybrid traversal) and do about a third of the instructions; hyrt's eight-lane tests keep
//! more of the machine busy per instruction, which is why the time was only 1.2 times
//! Embree's. Skipping tests early when no lane passes the edge tests pays off for closest
//! hit, not here (see `Packet::intersect`). The node-to-node dependency chain (box loads
//! from L3: the teaser's nodes are 2 MB) is the rest.
//!
//! The same count today, the shadow lists in tile order ([`sort_into_tiles`], as `hyrt
//! bench` traces them), with the lone-lane leaf tests and the octant walks (callgrind
//! 3.19, `--cache-sim=yes --branch-sim=yes`, AVX2, `--toggle-collect` on hyrt's chunk
//! function and on Embree's call, `ray_contest --threads 1 --rounds 1`: two passes of the
//! list each), per ray, hyrt against Embree's `rtcOccluded8` (default context):
//!
//! | rays | instructions | L1 data misses | last-level misses | mispredicted branches |
//! |---|---:|---:|---:|---:|
//! | far horse, shadow | 1,569 / 755 | 8.8 / 3.6 | 0.54 / 0.00 | 9.5 / 8.6 |
//! | dragon, shadow | 627 / 291 | 3.9 / 1.1 | 0.21 / 0.24 | 3.3 / 2.7 |
//! | teaser, reflections (single rays / `rtcIntersect8`) | 3,270 / 1,726 | 19.3 / 11.8 | 0.82 / 0.69 | 28.6 / 25.3 |
//!
//! (The simulated last level is the host's 256 MB, so its misses are first touches; and
//! callgrind simulates no prefetcher: 1.5 of hyrt's L1 misses per ray, on both scenes, are
//! `Packet::new` reading the list's 64-byte records in order, which Embree's calls read as
//! well through the contest's conversion to its ray packets.) hyrt
//! runs about twice Embree's instructions and two to three times its L1 misses in about
//! the same time (`hyrt bench --quick`, 2 threads: the far horse 1.08, the dragon 0.97, the
//! reflections 1.00): its eight-lane tests do more work per instruction and its misses
//! mostly hit L2. What is left is Embree's: fewer, denser steps (8-wide nodes of
//! four-triangle leaves for every walk, one copy of the tree warm for all its calls).
//!
//! Tried for those scenes and not kept (any hit, `ray_contest --kind shadow
//! --packets-only`, one thread, AVX-512 lanes, the variants interleaved in one process):
//!
//! * Handing a packet's last lanes to single rays, as Embree's hybrid traversal does: at a
//!   binary node entered by at most `k` lanes, each goes on alone through the wide view
//!   from the wide node or leaf made of that subtree. Slower on six of the seven scenes
//!   for every `k` from 1 to 5 (teaser 56 ms against 59 to 66, the dragon 76 against 79
//!   to 92, the near bunny 12.5 against 13.4 to 14.9), faster only on the far horse (its
//!   6,084 rays: 1.25 against 1.01 ms at `k = 5`). The lanes a packet loses are mostly
//!   near their leaves, where little of the binary walk is left, and a wide walk costs
//!   more to start than that; preparing each lane's ray once per packet, or leaving out
//!   the occluder cache on both sides, did not change the verdict.
//! * A walk without the child-order branch (both children pushed with their lane masks,
//!   empty masks not pushed, every node popped). That branch causes 61% of the
//!   mispredicted branches on the far bunny (callgrind `--branch-sim`), but passing every
//!   step through the stack was 12 to 54% slower (the teaser 53 against 82 ms). The same
//!   branch replaced by selects while the near child stays in registers (any hit: the
//!   left child next when a lane enters it, else the right; the right child's entry
//!   written to the stack at every inner node and kept by adding `both entered` to the
//!   stack pointer; one branch left, on neither child entered) was slower too (`ray_contest
//!   --packets-only --kind shadow --rounds 15 --threads 1`, interleaved round by round in
//!   one process, ms): at AVX-512 the far bunny 5.10 against 4.83, the dragon 66.1 against
//!   61.9, the teaser 62.9 against 48.3; at AVX2 the far bunny 5.33 against 5.08, the near
//!   horse 6.58 against 5.88. The selects wait for both children's box tests, where the
//!   predicted branch lets the next node's loads start before the tests resolve.
//! * Choosing single rays for a whole packet whose origins spread over more than `k`
//!   times the mean leaf box (the far horse's packets span dozens of leaves): the far
//!   horse went from 0.73 to 0.90 times Embree at `k = 1`, but the dragon fell from 0.82
//!   to 0.65 and the near bunny from 0.96 to 0.80, and no `k` helped one without hurting
//!   the others: the spread does not tell where the lanes part.
//! * Other leaf sizes (obvhs' `collapse_traversal_cost` 1, 1.5 and 5 instead of 3; at most
//!   4 triangles per leaf instead of 8): within the noise on every scene.
//! * Prefetching for the binary walk (a hook in `hyrt_core`'s walk, tried twice, one
//!   thread, interleaved in one process): a pushed node's pair of children (within the
//!   noise on the dragon, the far bunny, the near horse, the teaser and Sponza), and a
//!   leaf child's triangle records as soon as its parent's pair is read (the dragon 3%
//!   faster, the horses and bunnies 1 to 6% slower). The leaf records' loads are 16% of the
//!   dragon's packet time and the node loads about 11%, but they sit on the walk's
//!   dependency chain, which a prefetch one step ahead hardly shortens. A third time, on
//!   the Zen 5 and only for a leaf pushed as the far child (its records prefetched while
//!   the near subtree is walked; a `NodeTest` hook at the push): the dragon 0.99 and 1.01
//!   at AVX2 and AVX-512, the near bunny, the far horse and the teaser 1.00 to 1.02.
//! * Embree's hybrid on the 8-wide tree (issue 36): packets walking the wide nodes (each
//!   child's box tested for all lanes, the entering lanes' mask on the stack with the
//!   child), a node entered by at most `T` lanes finished by each of them alone through the
//!   same tree from that node (the branchy single-ray any-hit walk of module `single`, so
//!   switching costs one ray set-up per lane and nothing else), leaves lane by lane or, with
//!   more than `P` lanes, triangle by triangle for the packet. Bit for bit the scalar
//!   answers, and slower on every scene measured (AMD EPYC, AVX2, one thread, `ray_contest
//!   --packets-only --kind shadow`, interleaved with the binary packets in one process,
//!   binary packets first): the dragon 89 ms against 105 (`T` = 1, leaves lane by lane), 112
//!   (`P` = 2), 108 to 113 (`T` = 3); the far bunny 7.3 against 8.6 to 9.3; the near horse
//!   8.1 against 9.8 to 11.7; the teaser 116 against 157 to 239; Embree's own threshold
//!   (`T` = 7: single rays as soon as a lane drops out) 120 against 100 on the dragon and 165
//!   against 91 on the teaser. The binary walk culls lanes at every level where the wide
//!   node tests eight grandchildren, and its occluder cache and lone-lane leaf tests have
//!   no counterpart there yet; and the single-ray walk it hands lanes to runs at about 0.7
//!   of Embree's single rays (the dragon's shadow rays: 6.9 against 9.4 Mrays/s), so that
//!   walk comes first. (It has since been compiled once per ray octant, `single`'s
//!   `octant_walk!`: 12 to 20% less time, and one thread now traces the far horse's and
//!   the far bunny's shadow rays as fast one at a time as in packets.)
//! * The binary packets handing lanes to that faster single-ray walk, measured again after
//!   it: at a binary node entered by at most `k` lanes that is the root of a wide node or
//!   wide leaf (a map from binary node to wide reference made by the collapse), each lane
//!   not yet stopped walks that wide subtree alone, the packet skips it for them. Slower
//!   for every `k` (AMD EPYC, AVX2, one thread, `ray_contest --packets-only --kind shadow`,
//!   interleaved in one process): the dragon 131 to 146 ms against 181 to 231 for `k` = 1
//!   to 5, the near bunny 22.4 against 30.5 to 32.5, the far bunny 11.6 against 15.9 to
//!   18.0, the far horse 1.86 to 2.15 against 2.64 to 3.47; handing every lane off at once
//!   (`k` = 8, single rays from the root's wide node) measured as the single rays do. Part
//!   of the loss is the packet walk's own code: the same node test with the hand-off
//!   compiled in but never taken was 13 to 16% slower than the plain walk (the far horse
//!   2.10 against 1.86 ms, the dragon 169 against 146); against that, lone lanes handed
//!   off (`k` = 1) cost the dragon 37% more and the far horse 38%. A lone lane's subtree
//!   is mostly one wide leaf near its origin (0.65 hand-offs per ray on the far horse,
//!   0.63 wide nodes each), which the lone-lane leaf test already serves, and a stop found
//!   alone does not refresh the packet's occluder cache.
//! * The packets' node test compiled per octant as the single rays' (nine copies of the
//!   any-hit walk, the mixed case included): not measured then, because `hyrt-cpu`'s
//!   release build ran past 15 minutes. It has since landed in a narrower form: eight
//!   octant copies of the any-hit walk, the mixed and non-finite packets left to the
//!   generic one (`packet::occluded`, `AnyHitLanes`): 5 to 9% less time on every scene
//!   measured. Only the AVX2 and AVX-512 levels compile walks per octant
//!   (`Lanes::OCTANT_WALKS`; the single rays' too): with the SSE2 and portable fallbacks
//!   compiled per octant as well, `hyrt-cpu`'s release build took 2m25 on this project's
//!   2-core host, against 57 s without (1m13 once object-space instances took them too;
//!   1m15 before the packets' octant walks). Folding the far planes' `SLAB_FAR_SCALE` into
//!   a second inverse direction (`inv * S'`, `S'` two ulps above the scale, conservative
//!   where the lanes' `t_min >= 0` and `inv * S'` stays finite; one multiply less per
//!   plane) measured within the noise on the dragon, the far bunny, the far horse and the
//!   teaser, so the octant walks keep the scalar test's form.
//! * Slab distances as one fused multiply-add per plane, `plane * inv + offset` with the
//!   offset `-origin * inv` per lane (Embree's form), in the octant walks (AVX2 with FMA,
//!   AVX-512). Unguarded, it is not conservative: the offset's rounding (up to `u |origin *
//!   inv|`, not relative to the distance) can move a plane past a ray that grazes it. A
//!   conservative form was built with a written error argument and a property test against
//!   `ray_aabb_conservative` (offsets rounded outward by `2^-21 |offset|`, far distances
//!   scaled by `1 + 2^-19`, a guard on `|origin * inv|` and `|coordinate * inv|`), and
//!   measured against the plain walk (AMD EPYC, one thread, `ray_contest --packets-only
//!   --kind shadow --rounds 15`, the binaries alternated three times, ms): the unguarded
//!   form 58.2 to 59.7 on the dragon against 60.0 to 61.3 for the plain walk (the single
//!   rays' reflections 1% faster); the conservative form with a near and a far offset per
//!   axis 61.2 to 62.6 on the dragon, 4.47 to 4.53 against 4.66 to 4.69 on the far bunny,
//!   0.74 to 0.76 against 0.78 on the far horse, the teaser unchanged, and at AVX2 no change
//!   anywhere; one offset per axis with one slack for the three far planes 63.9 to 66.2 on
//!   the dragon (a ray nearly parallel to one axis has a huge offset on it, and the shared
//!   slack then widens every box on the other axes: shadow rays from the floor points below
//!   a light, for one). The second offset is one more register per axis in the node test,
//!   and the widening adds visits: together they take the whole gain of the fused
//!   operation.
//! * Leaf triangles packed for the packets, 36 bytes a slot (the vertices alone, a second
//!   copy beside `Bvh::leaf_triangles`, transposed for the lone-lane test with loads at
//!   12-byte steps; the alpha test still reading the records): a quarter fewer leaf bytes,
//!   41 MB of nodes and leaves on the dragon against 52. The dragon's shadow rays in tile
//!   order, two threads, `ray_contest --kind shadow --rounds 11`, two alternations: 31.75
//!   and 31.77 ms against 32.00 and 32.14, and Embree's best over hyrt 1.00 and 0.99
//!   against 1.01 and 1.00; one thread, packets alone, the dragon, the far bunny, the far
//!   horse and the near bunny within 1%. The packets are not bound by the leaf bytes.
//! * Shadow rays traced backwards, from each point or spot light to the ray's origin (as
//!   `ray_contest --kind from-lights` makes them, every ray of a packet from one point;
//!   timed as any hit in the binary packets in a throw-away build of the contest): slower
//!   (two threads: the far horse 0.72 against 0.62 ms, the dragon 44 against 39 ms), and
//!   a different answer near the origins' surfaces (102 of the far horse's 176 occluded rays, 8,316 of the dragon's
//!   1,058,277): the origin offset is made for a ray leaving the surface, and a ray
//!   arriving there would need a bound on its `t`'s error near 1 instead.
//! * The tree's arrays on 2 MiB pages. Embree's BVH lives on transparent huge pages (59 MB
//!   of `AnonHugePages` in `ray_contest`'s mappings on the dragon; this host's THP setting
//!   is `madvise`), hyrt's on 4 KiB pages, and the dragon's 52 MB of nodes and leaf records
//!   are far past the 2,048 entries (8 MB) of Zen 3's second-level TLB. The nodes, leaf
//!   records and wide view advised `MADV_HUGEPAGE` and collapsed (`MADV_COLLAPSE`) after
//!   `bvh_build`, and measured against the same binary without (two threads, `ray_contest
//!   --kind shadow --rounds 11 dragon`, alternated three times): 32.4 to 33.2 ms either way;
//!   the dragon's single rays and the teaser's reflections (one thread) within 1%. Page
//!   walks are not where the time goes.
//! * Sibling pairs of the binary tree kept on one cache line. `BvhNode` is 32-byte aligned
//!   and the pairs start at odd indices (the root alone at 0), so whether a pair shares a
//!   line depends on where the allocator put the array: in `ray_contest` the dragon's, the
//!   near bunny's and the far horse's pairs straddled two lines, the teaser's and Sponza's
//!   did not. The same tree copied to arrays at both alignments, interleaved round by
//!   round in one process (Zen 5, AVX2, one thread, `--packets-only --kind both`): 0.99 to
//!   1.02 of the straddling copy's time on the dragon, the near bunny, the near horse and
//!   the teaser, shadow and primary rays. The second line comes with the first (the
//!   adjacent-line prefetcher), so the layout stays as it is.
//! * Two more on the Zen 5 (AVX2, one thread, `ray_contest --kind shadow --packets-only
//!   --rounds 11`, the two binaries alternated three times, ms): the lone-lane leaf test
//!   out of line (its own AVX2 function, so that the walk's registers stay the walk's):
//!   the dragon 53.4 to 55.1 against 50.7 to 53.2, the teaser 36.2 to 37.7 against 35.5 to
//!   36.0; and the occluder cache dropped after a packet it stopped no lane of (so that
//!   lit regions stop retesting a stale leaf): the dragon 48.9 to 53.5 against 50.7 to
//!   52.9, the teaser 35.3 to 36.4 against 35.2 to 35.5, the near horse 4.46 to 4.53
//!   against 4.34 to 4.49: within the noise or slower.
//! * Where the time goes now, the dragon's shadow rays in packets (`perf record` at 10 kHz,
//!   one thread, each sample's address followed through its inlined frames with
//!   `addr2line -i`): the walk and its node tests 47% (the first read of a node's planes
//!   10%), the lone-lane leaf tests 39% (the first read of the leaf's records 10 to 13%),
//!   the slot loop's leaf tests 7%, `Packet::new` 5%. Per packet (2x4 pixels): 15 inner
//!   nodes, 2.65 leaves, 2.43 of them taken lane by lane (4.4 lane tests), 0.8 packet
//!   tests of a triangle. Two ways to hide the leaf records' first read were slower (one
//!   thread, `--packets-only`, the binaries alternated three times, ms): prefetching an
//!   entered leaf child's records in the node test (the dragon 66.4 to 68.5 against 64.2 to
//!   65.0, the far bunny, the near horse and the teaser 4 to 10% slower), and deferring the
//!   leaves taken lane by lane (up to eight queued, their records prefetched when queued,
//!   tested when the queue fills or the walk ends; a lane such a leaf would stop walks on
//!   meanwhile): the dragon 71.0 to 72.0 against 64.3 to 66.3, the teaser 58.6 to 62.8
//!   against 51.2 to 52.0. Also measured: from one thread to two, hyrt's packets scale 1.93
//!   times on the dragon and Embree's `rtcOccluded8` 2.03 times (61.7 to 32.0 ms against
//!   65.2 to 32.1, one run): one thread is 1.06 of Embree, two 1.00.
//! * The dragon's list in two parts (a throw-away filter in `ray_contest`, one thread,
//!   eleven rounds, packets against `rtcOccluded8`): the rays leaving the floor (origin
//!   `y` below 0.06) are 862,000 of the 1,058,277 and 81% of the packets, but take 27.6
//!   ms (32 ns a ray; Embree 26.0, 0.95); the rays leaving the dragon's surface are
//!   196,000 and take 41.3 ms (210 ns a ray; Embree 40.5, 0.98), about 25 binary node
//!   tests and 14 leaves a packet, nearly all of them taken lane by lane around the
//!   origins of a mesh with about eight triangles a pixel. Only 6.5% of the rays are
//!   occluded, so the occluder cache has little to find. Of the leaves taken lane by lane,
//!   those with at most four triangles entered by two or more lanes are 7% (so testing
//!   two lanes' rays against four triangles in one eight-lane test would save little);
//!   most have five to eight triangles and one or two lanes. Also measured and not kept:
//!   prefetching each packet's ray records two packets ahead with a non-temporal hint
//!   (two threads, three alternations: within the noise, 31.9 to 32.4 against 32.0 to 32.7
//!   ms), and a second process tracing the dragon with Embree on the other core while hyrt
//!   traces on one (62.7 and 63.5 ms against 63.6 and 64.4 alone): no sign that the two
//!   threads' loss is cache or memory pressure. The teaser's reflection rays put in tile
//!   order (2 to 16 pixels square) ran 2% faster for both hyrt's single rays and Embree's
//!   `rtcIntersect8`, the ratio unchanged.
//! * The same split on an AMD EPYC Zen 5 (AVX-512 at full width; Embree on its AVX-512
//!   kernels; hyrt's packets at AVX-512, 256-bit operations), where the dragon's row was
//!   the one shadow-ray row below 1.0 in the quick report (0.92 to 0.99 in four runs; 1.07
//!   at one thread: hyrt 55.9 ms against Embree's `rtcOccluded8` 59.8, then 27.8 against
//!   27.6 at two, Embree scaling 2.17 times and hyrt 2.01). `ray_contest --kind shadow
//!   --rounds 11` with the same throw-away filter (origin `y` below or above 0.06), ms:
//!
//!   | rays | count | hyrt, 1 thread | Embree | hyrt, 2 threads | Embree |
//!   |---|---:|---:|---:|---:|---:|
//!   | from the floor | 861,901 | 21.8 | 20.8 (0.95) | 12.7 | 10.8 (0.86) |
//!   | from the dragon | 196,376 | 34.4 | 37.7 (1.10) | 17.0 | 17.8 (1.05) |
//!
//!   The row is lost on the floor's rays, and at two threads: from one thread to two,
//!   hyrt's packets scale 1.67 to 1.92 times on them (21.8 ms; 11.3 to 13.1 in six runs at
//!   two threads), Embree's 1.93 to 2.11 (20.8; 9.9 to 10.8). Counted per packet (a counter
//!   build): the floor's packets test 13.4 binary nodes (6.5 of them entered by no lane)
//!   and 0.84 leaves (0.79 lane by lane, 1.6 lanes and 5.6 triangles each: leaves of the
//!   dragon's base that rays passing by it enter); the dragon's test 102 nodes (41 entered
//!   by none) and 10.6 leaves (9.6 lane by lane). Where the floor's time goes (`perf
//!   record`, one thread; two threads the same within 1%): node tests 24%, the walk 21%,
//!   the lone-lane leaf tests 35% (the records' transpose, with their first reads, 21%),
//!   `Packet::new` 9%. Not the cause of the scaling: rayon's chunks (4,096 rays a chunk
//!   instead of 1,024: within the noise, both tracers use the same chunks) or two hardware
//!   threads of one core (two copies of an `openssl speed sha256` run at full speed on the
//!   two CPUs at once). This VM has no hardware performance counters, so the L3 and memory
//!   traffic of the two threads could not be counted.
//! * Where on the floor the dragon's row is lost (Zen 5, one thread, `ray_contest --kind
//!   shadow --rounds 11 --passes 5` on windows of 30,000 to 60,000 of the floor's rays in
//!   tile order, a throw-away filter): the windows far from the dragon (2 to 5 binary node
//!   tests a packet, no leaf) run at 1.0 to 1.4 of Embree's `rtcOccluded8`; the windows of
//!   floor rays passing under and through the dragon (36 to 45 node tests, 2.8 to 3.5
//!   leaves, 2 to 2.75 of the 8 lanes occluded a packet) at 0.81 to 0.93. There Embree's
//!   `rtcOccluded8` runs 1.26 to 1.30 times as fast as its own `rtcOccluded1`, which
//!   hyrt's single rays match (3.16, 3.01 and 1.96 ms against 3.03, 3.09 and 1.92), while
//!   hyrt's binary packets run 1.12 to 1.23 times its single rays (2.78, 2.68 and 1.60 ms;
//!   Embree 2.40, 2.42 and 1.48). The gap is what Embree's packets gain where eight
//!   coherent rays go deep into a dense mesh. Three walks tried for it (issue 36), each
//!   the scalar answers ray for ray, interleaved with the binary packets round by round in
//!   one process (a switch read per turn), not kept:
//!   - The wide tree's upper levels under the packet's frustum (one `Frustum` test of a
//!     wide node's eight children for all lanes, as the primary rays' walk), each wide
//!     leaf it lets through handed to the binary walk at the binary subtree it was made of
//!     (a per-lane box test first, then the core walk started at that node, with the
//!     occluder cache and the lone-lane leaf tests). Whole lists, ms: Sponza 31.5 against
//!     35.6, but the teaser 43.2 against 41.6 and the dragon 78.9 against 63.2 (its floor's
//!     rays 31.2 against 26.2, its surface's 50.7 against 36.8); the bunnies and horses
//!     within 2%. On the dragon the frustum lets through 7.6 leaf boxes a packet, of which
//!     lanes enter 2.5: the interval bounds of rays converging on a light are loose beside
//!     a dense mesh.
//!   - Packets on the 8-wide nodes with exact per-lane child tests (each child's box for
//!     the lanes that entered the node, their mask on the stack), a child entered by at
//!     most `T` lanes and every leaf handed to the binary walk from its binary node with
//!     those lanes: on the two hardest floor windows, 3.07 and 2.27 ms against 2.54 and
//!     2.21 at `T` = 0, 3.13 and 2.39 against 2.56 and 2.20 at `T` = 3, 2.73 and 2.75
//!     against 2.34 and 2.36 at `T` = 7 (Embree's threshold). (A leaf test closure passed
//!     on as `&mut F` is called out of line and compiled without the target features,
//!     eight times slower: wrap it in an `#[inline(always)]` closure.)
//!   - Any hit visiting the nearer child first (the closest hit's order by the first
//!     lane's direction) instead of the left, on two hard windows (a build counting node
//!     and leaf visits, both variants): 2.78 and 2.96 ms against 2.63 and 2.82.
//!
//! Two-level scenes (moving objects, shared meshes): the world-space level is traced as
//! above, then the object-space instances in packets (module `instances`,
//! [`occluded_in_object_space_into`], [`closest_hit_in_object_space_into`]).
//!
//! Work is split into chunks of [`TRAVERSAL_CHUNK`] rays run in parallel on the current
//! rayon pool (use [`with_threads`] for a given thread count); results are in ray order
//! and independent of the thread count.

/// The octant parameter of a walk compiled for no one octant: the walk reads the ray's
/// or the packet's octant at run time (the levels without `Lanes::OCTANT_WALKS`, the
/// packets whose lanes' signs differ). Octants proper are 0 to 7 (bit `a` set where the
/// inverse direction's component `a` is negative).
const ANY_OCTANT: u8 = 8;

/// `$walk::<$lanes, O>($args)` for the octant `O` equal to `$octant` (0 to 7): one copy of
/// each walk per octant (the single rays' `single::WideRay::octant`, the packets'
/// `packet::packet_octant`), as Embree's and tinybvh's direction-sign kernels, so that the
/// node test's plane rows are constant offsets rather than per-ray indices held in
/// registers or reloaded (issue 36, item 3). For the single rays, with the leaf's vertex
/// rows picked once per ray (`single::WideRay::vertex_rows`) instead of per row, measured
/// against the walk with per-ray plane rows (AMD EPYC, AVX2, one thread, `ray_contest
/// --singles-only`): callgrind instructions per ray 1,326 to 1,013 on the near bunny's
/// shadow rays and 3,808 to 3,174 on the teaser's reflection and refraction rays; time (the
/// two binaries alternated three times, medians of seven rounds) the dragon's shadow rays
/// 193 to 152 ms, the teaser's 231 to 189, the near bunny's 28.0 to 22.3, the far horse's
/// 1.75 to 1.46, the teaser's reflections and refractions 49.5 to 43.3. Specialising on the
/// permutation axis `kz` as well (24 copies; tried before the vertex rows were picked per
/// ray) measured no faster than the octants alone, at more than twice the compile time. For
/// the packets, see `packet::occluded`.
///
/// At the levels without `Lanes::OCTANT_WALKS`, or where the optional condition of
/// `octant_walk!(if $cond => $octant, ...)` is false (`$octant` is then not evaluated), the
/// one walk of [`ANY_OCTANT`] instead.
macro_rules! octant_walk {
    (if $cond:expr => $octant:expr, $($walk:ident)::+ ::<$lanes:ty>($($arg:expr),*)) => {
        if <$lanes as $crate::lanes::Lanes>::OCTANT_WALKS && $cond {
            match $octant {
                0 => $($walk)::+::<$lanes, 0>($($arg),*),
                1 => $($walk)::+::<$lanes, 1>($($arg),*),
                2 => $($walk)::+::<$lanes, 2>($($arg),*),
                3 => $($walk)::+::<$lanes, 3>($($arg),*),
                4 => $($walk)::+::<$lanes, 4>($($arg),*),
                5 => $($walk)::+::<$lanes, 5>($($arg),*),
                6 => $($walk)::+::<$lanes, 6>($($arg),*),
                _ => $($walk)::+::<$lanes, 7>($($arg),*),
            }
        } else {
            $($walk)::+::<$lanes, { $crate::traversal::ANY_OCTANT }>($($arg),*)
        }
    };
    ($octant:expr, $($walk:ident)::+ ::<$lanes:ty>($($arg:expr),*)) => {
        octant_walk!(if true => $octant, $($walk)::+::<$lanes>($($arg),*))
    };
}

mod frustum;
mod instances;
mod packet;
mod single;
pub(crate) mod tiles;
pub mod tuning;
mod watertight;

use rayon::prelude::*;

use hyrt_core::bvh::two_level::TwoLevelBvh;
use hyrt_core::bvh::{Bvh, ClosestHit};
use hyrt_core::formats::{RayRecord, TriangleRecord};
use hyrt_core::kernels::texture::{alpha_accepts, SurfaceView};

pub use crate::lanes::LANES;
use crate::lanes::{avx2_entry_points, dispatch, Lanes};
use packet::Packet;
pub use tiles::{sort_into_tiles, tile_key};

/// Any-hit answer of [`occluded_batch_into`] and its siblings (the output values of
/// `shadow_rays`): something lies between the ray origin and the light.
pub const SHADOW_OCCLUDED: u32 = 1;
/// Any-hit answer: the light is visible.
pub const SHADOW_VISIBLE: u32 = 0;

/// Rays per rayon task: a multiple of [`LANES`], large enough to amortize scheduling (tens
/// of microseconds of work), small enough to balance uneven rays across threads.
pub const TRAVERSAL_CHUNK: usize = 1024;
const _: () = assert!(TRAVERSAL_CHUNK / LANES * LANES == TRAVERSAL_CHUNK);

/// The instruction set the packet code runs with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SimdLevel {
    /// The AVX2 code compiled for AVX-512 (F, VL, DQ, BW): the same 256-bit operations,
    /// with mask registers and 32 vector registers at the compiler's disposal (5 to 7%
    /// faster on the teaser's, Sponza's, the bunny's and the dragon's shadow and primary
    /// rays on this project's AMD EPYC). Detected at run time.
    Avx512,
    /// 256-bit AVX2 registers (x86-64 with AVX2 and the bit-manipulation instructions
    /// that come with it, BMI1, BMI2, LZCNT and POPCNT; detected at run time).
    Avx2,
    /// Two 128-bit SSE2 registers (every x86-64 CPU).
    Sse2,
    /// Plain `[f32; 8]` arrays (any target).
    Portable,
}

/// Environment variable forcing the SIMD level [`SimdLevel::detect`] returns (`avx512`,
/// `avx2`, `sse2`, `portable`), so one machine measures every path; a level this CPU
/// lacks, or an unknown name, is ignored. [`force_simd_level`] does the same from code and
/// takes precedence.
pub const SIMD_ENV: &str = "HYRT_SIMD";

/// The level [`force_simd_level`] set: 0 none, else 1 + the index in [`SimdLevel::ALL`].
static FORCED_LEVEL: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(0);

/// Make [`SimdLevel::detect`] (and so [`Traversal::simd`], [`Traversal::for_bounces`] and
/// the backends made after this call) use `level`, or the best level again with `None`.
/// Fails, changing nothing, for a level this CPU cannot run.
pub fn force_simd_level(level: Option<SimdLevel>) -> Result<(), String> {
    use std::sync::atomic::Ordering;
    match level {
        None => FORCED_LEVEL.store(0, Ordering::Relaxed),
        Some(l) if l.is_available() => {
            let i = SimdLevel::ALL.iter().position(|&x| x == l).expect("every level is in ALL");
            FORCED_LEVEL.store(i as u8 + 1, Ordering::Relaxed);
        }
        Some(l) => return Err(format!("this CPU cannot run the {} traversal level", l.name())),
    }
    Ok(())
}

/// Whether [`SimdLevel::detect`] is not the best level of this CPU (forced by
/// [`force_simd_level`] or [`SIMD_ENV`]), for reports.
pub fn simd_level_forced() -> bool {
    SimdLevel::detect() != SimdLevel::best()
}

impl SimdLevel {
    /// Every level, best first.
    pub const ALL: [SimdLevel; 4] = [SimdLevel::Avx512, SimdLevel::Avx2, SimdLevel::Sse2, SimdLevel::Portable];

    /// The level of a [`SimdLevel::name`].
    pub fn from_name(name: &str) -> Option<SimdLevel> {
        SimdLevel::ALL.into_iter().find(|l| l.name() == name.trim())
    }

    /// The level traversals use: the one [`force_simd_level`] set, else the one the
    /// [`SIMD_ENV`] variable names (when this CPU has it), else the best this CPU supports.
    pub fn detect() -> SimdLevel {
        SimdLevel::forced().unwrap_or_else(SimdLevel::best)
    }

    /// The level [`force_simd_level`] or [`SIMD_ENV`] forces (the best level included), if
    /// any: then the stages run it for every kind of walk instead of measuring
    /// ([`tuning::applies`]).
    pub fn forced() -> Option<SimdLevel> {
        let forced = FORCED_LEVEL.load(std::sync::atomic::Ordering::Relaxed);
        if forced > 0 {
            return Some(SimdLevel::ALL[forced as usize - 1]);
        }
        std::env::var(SIMD_ENV).ok().and_then(|v| SimdLevel::from_name(&v)).filter(|l| l.is_available())
    }

    /// The best level this CPU supports.
    pub fn best() -> SimdLevel {
        #[cfg(target_arch = "x86_64")]
        {
            if SimdLevel::Avx512.is_available() {
                return SimdLevel::Avx512;
            }
            if SimdLevel::Avx2.is_available() {
                return SimdLevel::Avx2;
            }
            SimdLevel::Sse2
        }
        #[cfg(not(target_arch = "x86_64"))]
        SimdLevel::Portable
    }

    /// Whether this CPU can run the level.
    pub fn is_available(self) -> bool {
        match self {
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx512 => {
                SimdLevel::Avx2.is_available()
                    && is_x86_feature_detected!("avx512f")
                    && is_x86_feature_detected!("avx512vl")
                    && is_x86_feature_detected!("avx512dq")
                    && is_x86_feature_detected!("avx512bw")
            }
            #[cfg(target_arch = "x86_64")]
            // The features of `lanes::avx2_entry_points`: AVX2 and the bit-manipulation
            // instructions every AVX2 CPU has.
            SimdLevel::Avx2 => {
                is_x86_feature_detected!("avx2")
                    && is_x86_feature_detected!("bmi1")
                    && is_x86_feature_detected!("bmi2")
                    && is_x86_feature_detected!("lzcnt")
                    && is_x86_feature_detected!("popcnt")
            }
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Sse2 => true,
            #[cfg(not(target_arch = "x86_64"))]
            SimdLevel::Avx512 | SimdLevel::Avx2 | SimdLevel::Sse2 => false,
            SimdLevel::Portable => true,
        }
    }

    /// Every level this CPU can run, best first.
    pub fn available() -> Vec<SimdLevel> {
        SimdLevel::ALL.into_iter().filter(|l| l.is_available()).collect()
    }

    /// Lower-case name (reports).
    pub fn name(self) -> &'static str {
        match self {
            SimdLevel::Avx512 => "avx512",
            SimdLevel::Avx2 => "avx2",
            SimdLevel::Sse2 => "sse2",
            SimdLevel::Portable => "portable",
        }
    }
}

/// How a batch is traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Traversal {
    /// One ray at a time with [`Bvh::occluded`] / [`Bvh::closest_hit`] (the reference).
    Scalar,
    /// Packets of [`LANES`] rays at the given SIMD level (an unavailable level falls back
    /// to the best available one).
    Packet(SimdLevel),
    /// One ray at a time through the wide view of the BVH (`Bvh::wide`), the sixteen
    /// child boxes of a node, or the triangles of a leaf, tested at once at the given SIMD
    /// level (module `single`). For rays that do not travel together. A BVH without a
    /// wide view is traced with packets.
    Single(SimdLevel),
    /// [`Traversal::Packet`] at the level this CPU runs the kind of walk faster, AVX-512 or
    /// AVX2, measured interleaved while the stages trace (module [`tuning`]). The stages'
    /// default on a CPU with AVX-512 where no level is forced.
    PacketAuto,
    /// [`Traversal::Single`] at the level measured as [`Traversal::PacketAuto`]'s is.
    SingleAuto,
}

impl Traversal {
    /// Packets at the best SIMD level of this CPU: the default of the `shadow_rays` stage.
    /// Where the CPU has AVX-512 and no level is forced, [`Traversal::PacketAuto`]: the
    /// faster of AVX-512 and AVX2 for each kind of walk, measured ([`tuning`]).
    pub fn simd() -> Traversal {
        if tuning::applies() {
            Traversal::PacketAuto
        } else {
            Traversal::Packet(SimdLevel::detect())
        }
    }

    /// Single rays through the wide tree at the best SIMD level of this CPU: the default of
    /// the `bounce_trace` stage. Reflection and refraction rays spread out where packets
    /// need their lanes to travel together; measured (`hyrt bench --quick`, 2 threads, one
    /// run, AVX-512 lanes) on the teaser's 75,529 secondary rays: 5.4 Mrays/s single
    /// against 4.3 in packets (and Embree's `rtcIntersect1` 5.5). Packets stay faster on
    /// coherent rays (primary and shadow rays: 2 to 3 times).
    pub fn for_bounces() -> Traversal {
        if tuning::applies() {
            Traversal::SingleAuto
        } else {
            Traversal::Single(SimdLevel::detect())
        }
    }

    /// Every SIMD traversal this CPU runs: packets and single rays at each available level,
    /// and measured ones where [`tuning::applies`] (what tests compare with the scalar
    /// reference).
    pub fn available_simd() -> Vec<Traversal> {
        let fixed = SimdLevel::available().into_iter().flat_map(|l| [Traversal::Packet(l), Traversal::Single(l)]);
        let auto = [Traversal::PacketAuto, Traversal::SingleAuto].into_iter().filter(|_| tuning::applies());
        fixed.chain(auto).collect()
    }

    /// Short name (reports): `scalar`, `packet-<level>`, `single-<level>`, `packet-auto` or
    /// `single-auto`.
    pub fn name(self) -> String {
        match self {
            Traversal::Scalar => "scalar".into(),
            Traversal::Packet(l) => format!("packet-{}", l.name()),
            Traversal::Single(l) => format!("single-{}", l.name()),
            Traversal::PacketAuto => "packet-auto".into(),
            Traversal::SingleAuto => "single-auto".into(),
        }
    }

    /// The SIMD level used on this CPU for a walk of kind `walk` (`None` for scalar): a
    /// measured traversal's the level [`tuning`] runs that kind at now.
    fn level(self, walk: tuning::Walk) -> Option<SimdLevel> {
        match self {
            Traversal::Scalar => None,
            Traversal::Packet(l) | Traversal::Single(l) if l.is_available() => Some(l),
            Traversal::Packet(_) | Traversal::Single(_) => Some(SimdLevel::detect()),
            Traversal::PacketAuto | Traversal::SingleAuto => Some(tuning::current(walk)),
        }
    }

    /// Whether rays go one at a time through the wide view (which `bvh` must have).
    fn single(self, bvh: &Bvh) -> bool {
        matches!(self, Traversal::Single(_) | Traversal::SingleAuto) && !bvh.wide.is_empty()
    }

    /// Whether the level is measured ([`tuning`]).
    fn auto(self) -> bool {
        matches!(self, Traversal::PacketAuto | Traversal::SingleAuto)
    }
}

impl Default for Traversal {
    fn default() -> Self {
        Traversal::simd()
    }
}

/// Run `f` on a fresh rayon pool of `threads` workers (at least one): the batch functions
/// use whatever pool they are called on.
pub fn with_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build().expect("rayon thread pool").install(f)
}

/// Any hit for every ray (`t_min < t < t_max`), in ray order: [`SHADOW_OCCLUDED`] or
/// [`SHADOW_VISIBLE`], into `out` (resized to `rays.len()`). `triangles` is the table
/// `bvh` was built from. Rays the scalar traversal rejects (non-finite, zero direction,
/// empty interval) are visible.
pub fn occluded_batch_into(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    rays: &[RayRecord],
    traversal: Traversal,
    out: &mut Vec<u32>,
) {
    occluded_alpha_batch_into(bvh, triangles, &SurfaceView::default(), rays, traversal, out)
}

/// [`occluded_batch_into`] in a scene whose surface tables are `view`: hits on
/// alpha-tested triangles count only where their texel passes
/// ([`hyrt_core::kernels::texture::alpha_accepts`], as `Bvh::occluded_filtered`). Packets and
/// the scalar reference test alpha; the single-ray path does not, so a scene with
/// alpha tests traces packets where `traversal` asks for single rays.
pub fn occluded_alpha_batch_into(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    view: &SurfaceView,
    rays: &[RayRecord],
    traversal: Traversal,
    out: &mut Vec<u32>,
) {
    // Every element is written below: resizing alone keeps a reused buffer's memory
    // untouched until the chunks write it (no serial clear of megabytes).
    out.resize(rays.len(), SHADOW_VISIBLE);
    let mode = traversal_mode(bvh, view, traversal, true);
    out.par_chunks_mut(TRAVERSAL_CHUNK)
        .zip(rays.par_chunks(TRAVERSAL_CHUNK))
        .for_each(|(out, rays)| occluded_any_chunk(bvh, triangles, view, rays, out, mode));
}

/// [`occluded_generated_into`] for a frame's shadow rays made from their (light, pixel)
/// pairs: `active` holds the pairs `k = light * pixels + pixel`, increasing (as
/// `compaction` writes them; pixels of an image `width` pixels wide), `ray(i)` makes the
/// ray of pair `active[i]`. Traced in packets of pixel tiles (module `tiles`): the same
/// answers, in the pairs' order. Windows of whole tile rows run in parallel; each
/// window's rays are made in tile order, traced as one chunk, and their answers written
/// back to the pairs' order.
#[allow(clippy::too_many_arguments)]
pub fn occluded_pairs_tiled_into(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    view: &SurfaceView,
    active: &[u32],
    pixels: u32,
    width: u32,
    ray: impl Fn(usize) -> RayRecord + Sync,
    traversal: Traversal,
    out: &mut Vec<u32>,
) {
    out.resize(active.len(), SHADOW_VISIBLE); // every element is written below
    let mode = traversal_mode(bvh, view, traversal, true);
    let (pixels, width) = (pixels.max(1), width.max(1));
    tile_windows(active, pixels, width, out).into_par_iter().for_each_init(
        || (Vec::new(), Vec::new(), Vec::new(), Vec::new()),
        |(coords, order, rays, answers), (start, out)| {
            tiles::coords(&active[start..start + out.len()], pixels, width, coords);
            tiles::tile_order(coords, order);
            rays.clear();
            rays.extend(order.iter().map(|&o| ray(start + o as usize)));
            answers.resize(out.len(), SHADOW_VISIBLE);
            occluded_any_chunk(bvh, triangles, view, rays, answers, mode);
            for (&o, &a) in order.iter().zip(answers.iter()) {
                out[o as usize] = a;
            }
        },
    );
}

/// Rays per window of the tiled traversal at least (windows hold whole tile rows: with
/// every pixel active, 4 rows of the image).
const TILE_WINDOW: usize = TRAVERSAL_CHUNK;

/// The output split into windows of whole tile rows (`tiles::windows`): `(first ray,
/// its answers)` per window.
fn tile_windows<'o>(active: &[u32], pixels: u32, width: u32, out: &'o mut [u32]) -> Vec<(usize, &'o mut [u32])> {
    let ends = tiles::windows(active, pixels, width, TILE_WINDOW);
    let mut windows = Vec::with_capacity(ends.len());
    let (mut rest, mut start) = (out, 0);
    for &end in &ends {
        let (head, tail) = rest.split_at_mut(end - start);
        windows.push((start, head));
        (rest, start) = (tail, end);
    }
    windows
}

/// How a batch is traced: at `level` (none: the scalar reference), single rays or
/// packets, the level measured per chunk or not.
#[derive(Clone, Copy)]
struct Mode {
    level: Option<SimdLevel>,
    single: bool,
    auto: bool,
}

impl Mode {
    /// Trace a chunk of `rays` rays of an any-hit (`any_hit`) or closest-hit walk with
    /// `trace` at this mode's level, or where it is measured at the level [`tuning::timed`]
    /// gives (timed). Not called for the scalar reference.
    #[inline(always)]
    fn run<R>(self, any_hit: bool, rays: usize, trace: impl FnOnce(SimdLevel) -> R) -> R {
        match self.level {
            Some(_) if self.auto => tuning::timed(tuning::Walk::of(any_hit, self.single), rays, trace),
            Some(level) => trace(level),
            None => unreachable!("the scalar reference has no level"),
        }
    }
}

/// The [`Mode`] of `traversal` on `bvh` for an any-hit or closest-hit walk
/// ([`Traversal::level`], [`Traversal::single`]), packets instead of single rays where
/// `view` has alpha tests.
fn traversal_mode(bvh: &Bvh, view: &SurfaceView, traversal: Traversal, any_hit: bool) -> Mode {
    let single = traversal.single(bvh) && !view.alpha_tested();
    let level = traversal.level(tuning::Walk::of(any_hit, single));
    Mode { level, single, auto: traversal.auto() }
}

/// [`occluded_batch_into`] over `count` rays made as they are traced, `ray(i)` for ray
/// `i`, a chunk of [`TRAVERSAL_CHUNK`] at a time in a buffer that stays in cache: the
/// answers of tracing the list `ray(0..count)`, without writing the list to memory.
pub fn occluded_generated_into(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    view: &SurfaceView,
    count: usize,
    ray: impl Fn(usize) -> RayRecord + Sync,
    traversal: Traversal,
    out: &mut Vec<u32>,
) {
    out.resize(count, SHADOW_VISIBLE); // every element is written below, as above
    let mode = traversal_mode(bvh, view, traversal, true);
    out.par_chunks_mut(TRAVERSAL_CHUNK).enumerate().for_each_init(
        || Vec::with_capacity(TRAVERSAL_CHUNK),
        |rays, (c, out)| {
            rays.clear();
            rays.extend((c * TRAVERSAL_CHUNK..c * TRAVERSAL_CHUNK + out.len()).map(&ray));
            occluded_any_chunk(bvh, triangles, view, rays, out, mode);
        },
    );
}

/// [`occluded_alpha_batch_into`] on the calling thread, into `out` (one answer per ray):
/// for rays made by their executor where it traces them (the fused frame's tiles).
pub(crate) fn occluded_serial(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    view: &SurfaceView,
    rays: &[RayRecord],
    traversal: Traversal,
    out: &mut [u32],
) {
    debug_assert_eq!(rays.len(), out.len());
    occluded_any_chunk(bvh, triangles, view, rays, out, traversal_mode(bvh, view, traversal, true))
}

/// Any hit for one chunk of rays with the traversal `(level, single)` of
/// [`Traversal::level`] and [`Traversal::single`] (no level: the scalar reference).
fn occluded_any_chunk(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    view: &SurfaceView,
    rays: &[RayRecord],
    out: &mut [u32],
    mode: Mode,
) {
    match mode.level {
        None => {
            for (o, r) in out.iter_mut().zip(rays) {
                *o = occlusion(scalar_occluded(bvh, triangles, view, r));
            }
        }
        Some(_) if mode.single => mode.run(true, rays.len(), |level| occluded_single_chunk(bvh, rays, out, level)),
        Some(_) => mode.run(true, rays.len(), |level| occluded_chunk(bvh, triangles, view, rays, out, level)),
    }
}

/// The alpha test the scalar walks take as `accept` (`Bvh::occluded_filtered` and kin,
/// `TwoLevelBvh`'s) in a scene whose surface tables are `view`: [`alpha_accepts`] of the
/// hit record and its global triangle.
#[inline(always)]
pub(crate) fn alpha_test<'v>(view: &'v SurfaceView) -> impl Fn(&TriangleRecord, u32, f32, f32) -> bool + Copy + 'v {
    move |t, id, u, v| alpha_accepts(view, t, id as usize, u, v)
}

/// The scalar reference's any hit with the alpha test of `view`.
#[inline(always)]
fn scalar_occluded(bvh: &Bvh, triangles: &[TriangleRecord], view: &SurfaceView, r: &RayRecord) -> bool {
    bvh.occluded_filtered(triangles, r, alpha_test(view))
}

/// The scalar reference's closest hit with the alpha test of `view`.
#[inline(always)]
fn scalar_closest_hit(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    view: &SurfaceView,
    r: &RayRecord,
) -> Option<ClosestHit> {
    bvh.closest_hit_filtered(triangles, r, alpha_test(view))
}

/// [`occluded_batch_into`] into a new vector.
pub fn occluded_batch(bvh: &Bvh, triangles: &[TriangleRecord], rays: &[RayRecord], traversal: Traversal) -> Vec<u32> {
    let mut out = Vec::new();
    occluded_batch_into(bvh, triangles, rays, traversal, &mut out);
    out
}

/// The closest hit of every ray (`t_min < t < t_max`, ties to the lower triangle index),
/// in ray order, into `out` (resized to `rays.len()`). `triangles` as in
/// [`occluded_batch_into`].
pub fn closest_hit_batch_into(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    rays: &[RayRecord],
    traversal: Traversal,
    out: &mut Vec<Option<ClosestHit>>,
) {
    closest_hit_alpha_batch_into(bvh, triangles, &SurfaceView::default(), rays, traversal, out)
}

/// [`closest_hit_batch_into`] with the alpha tests of `view`, as
/// [`occluded_alpha_batch_into`] (`Bvh::closest_hit_filtered`).
pub fn closest_hit_alpha_batch_into(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    view: &SurfaceView,
    rays: &[RayRecord],
    traversal: Traversal,
    out: &mut Vec<Option<ClosestHit>>,
) {
    out.resize(rays.len(), None); // every element is written below, as above
    let mode = traversal_mode(bvh, view, traversal, false);
    out.par_chunks_mut(TRAVERSAL_CHUNK).zip(rays.par_chunks(TRAVERSAL_CHUNK)).for_each(|(out, rays)| {
        match mode.level {
            None => {
                for (o, r) in out.iter_mut().zip(rays) {
                    *o = scalar_closest_hit(bvh, triangles, view, r);
                }
            }
            Some(_) if mode.single => {
                mode.run(false, rays.len(), |level| closest_hit_single_chunk(bvh, rays, out, level))
            }
            Some(_) => mode.run(false, rays.len(), |level| closest_hit_chunk(bvh, triangles, view, rays, out, level)),
        }
    });
}

/// [`closest_hit_batch_into`] into a new vector.
pub fn closest_hit_batch(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    rays: &[RayRecord],
    traversal: Traversal,
) -> Vec<Option<ClosestHit>> {
    let mut out = Vec::new();
    closest_hit_batch_into(bvh, triangles, rays, traversal, &mut out);
    out
}

/// The `shadow_rays` code of an any-hit answer.
#[inline(always)]
fn occlusion(hit: bool) -> u32 {
    if hit {
        SHADOW_OCCLUDED
    } else {
        SHADOW_VISIBLE
    }
}

/// Where each of [`LANES`] rays meets its own triangle, `rays[i]` against `tris[i]`, by
/// the watertight kernel over each ray's `(t_min, t_max)` (reconstruction's
/// re-intersection of a block of pixels): the lanes hit and their `(u, v)`, each lane's
/// answer that of `WatertightRay::new(origin, direction)` and `intersect` on its triangle.
/// `None` where fewer than two rays can hit anything (the packet's rule): trace those
/// alone.
#[inline(always)]
pub(crate) fn intersect_each<L: Lanes>(
    rays: &[RayRecord; LANES],
    tris: [&TriangleRecord; LANES],
) -> Option<(u32, [f32; LANES], [f32; LANES])> {
    let packet = Packet::<L>::new(rays)?;
    let (hit, _, u, v, _) = packet.intersect_each(packet.valid, tris);
    Some((hit, L::store(u), L::store(v)))
}

/// Dispatch one chunk to the code compiled for `level` (available on this CPU).
fn occluded_chunk(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    view: &SurfaceView,
    rays: &[RayRecord],
    out: &mut [u32],
    level: SimdLevel,
) {
    dispatch!(
        level,
        occluded_packets,
        occluded_packets_avx512,
        occluded_packets_avx2,
        (bvh, triangles, view, rays, out)
    )
}

fn closest_hit_chunk(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    view: &SurfaceView,
    rays: &[RayRecord],
    out: &mut [Option<ClosestHit>],
    level: SimdLevel,
) {
    dispatch!(
        level,
        closest_hit_packets,
        closest_hit_packets_avx512,
        closest_hit_packets_avx2,
        (bvh, triangles, view, rays, out)
    )
}

fn occluded_single_chunk(bvh: &Bvh, rays: &[RayRecord], out: &mut [u32], level: SimdLevel) {
    dispatch!(level, occluded_single, occluded_single_avx512, occluded_single_avx2, (bvh, rays, out))
}

fn closest_hit_single_chunk(bvh: &Bvh, rays: &[RayRecord], out: &mut [Option<ClosestHit>], level: SimdLevel) {
    dispatch!(level, closest_hit_single, closest_hit_single_avx512, closest_hit_single_avx2, (bvh, rays, out))
}

/// The object-space pass of any hit in a two-level scene ([`TwoLevelBvh`]): `out[i]`
/// holds the answer of the world-space level (`levels.world_level()`, traced already by
/// [`occluded_alpha_batch_into`] or [`occluded_generated_into`]) for ray `ray(i)`; each
/// ray found visible there is traced through the object-space instances and marked
/// [`SHADOW_OCCLUDED`] when it hits one. Together: any hit over the whole scene, ray by ray
/// [`TwoLevelBvh::occluded_filtered`] with the alpha test of `view`.
///
/// In packets (module `instances`) at the SIMD level of `traversal` (also for
/// [`Traversal::Single`]), the visible rays of each chunk gathered into full packets; one
/// ray at a time with `TwoLevelBvh::occluded_in_object_space` for [`Traversal::Scalar`].
pub fn occluded_in_object_space_into(
    levels: &TwoLevelBvh,
    view: &SurfaceView,
    ray: impl Fn(usize) -> RayRecord + Sync,
    traversal: Traversal,
    out: &mut [u32],
) {
    let level = traversal.level(tuning::Walk::AnyHitPackets);
    out.par_chunks_mut(TRAVERSAL_CHUNK).enumerate().for_each_init(
        || (Vec::with_capacity(TRAVERSAL_CHUNK), Vec::with_capacity(TRAVERSAL_CHUNK)),
        |scratch, (c, out)| object_space_chunk(levels, view, |k| ray(c * TRAVERSAL_CHUNK + k), level, scratch, out),
    );
}

/// [`occluded_in_object_space_into`] on the calling thread, for rays made by their
/// executor where it traces them (the fused frame's tiles): `out[k]` is ray `ray(k)`'s
/// world-space answer, and becomes the whole scene's.
pub(crate) fn occluded_in_object_space_serial(
    levels: &TwoLevelBvh,
    view: &SurfaceView,
    ray: impl Fn(usize) -> RayRecord,
    traversal: Traversal,
    scratch: &mut (Vec<RayRecord>, Vec<u32>),
    out: &mut [u32],
) {
    object_space_chunk(levels, view, ray, traversal.level(tuning::Walk::AnyHitPackets), scratch, out)
}

/// The object-space pass over one chunk: the rays `out` says are visible (`ray(k)` for
/// `out[k]`) gathered into `scratch` (rays, their positions) and traced at `level` (none:
/// the scalar walk).
fn object_space_chunk(
    levels: &TwoLevelBvh,
    view: &SurfaceView,
    ray: impl Fn(usize) -> RayRecord,
    level: Option<SimdLevel>,
    (rays, index): &mut (Vec<RayRecord>, Vec<u32>),
    out: &mut [u32],
) {
    rays.clear();
    index.clear();
    for (k, o) in out.iter().enumerate() {
        if *o == SHADOW_VISIBLE {
            index.push(k as u32);
            rays.push(ray(k));
        }
    }
    match level {
        None => {
            let accept = alpha_test(view);
            for (&k, r) in index.iter().zip(rays.iter()) {
                out[k as usize] = occlusion(levels.occluded_in_object_space(r, accept));
            }
        }
        Some(level) => dispatch!(
            level,
            occluded_instance_packets,
            occluded_instance_packets_avx512,
            occluded_instance_packets_avx2,
            (levels, view, rays, index, out)
        ),
    }
}

/// The object-space pass of closest hit in a two-level scene: `closest[i]` holds ray
/// `rays[i]`'s closest hit in the world-space level (traced already by
/// [`closest_hit_alpha_batch_into`]); each ray is traced through the object-space
/// instances and `closest[i]` becomes the closer of the two (`(t, triangle)` order).
/// Together: ray by ray [`TwoLevelBvh::closest_hit_filtered`] with the alpha test of
/// `view`. Packets at the SIMD level of `traversal` (also for [`Traversal::Single`]: the
/// single-ray path has no instance form yet), the scalar walk for [`Traversal::Scalar`].
pub fn closest_hit_in_object_space_into(
    levels: &TwoLevelBvh,
    view: &SurfaceView,
    rays: &[RayRecord],
    traversal: Traversal,
    closest: &mut [Option<ClosestHit>],
) {
    assert_eq!(rays.len(), closest.len(), "one world-space hit per ray");
    let level = traversal.level(tuning::Walk::ClosestHitPackets);
    closest.par_chunks_mut(TRAVERSAL_CHUNK).zip(rays.par_chunks(TRAVERSAL_CHUNK)).for_each(|(out, rays)| match level {
        None => {
            let accept = alpha_test(view);
            for (c, r) in out.iter_mut().zip(rays) {
                *c = levels.closest_hit_in_object_space(r, *c, accept);
            }
        }
        Some(level) => dispatch!(
            level,
            closest_instance_packets,
            closest_instance_packets_avx512,
            closest_instance_packets_avx2,
            (levels, view, rays, out)
        ),
    });
}

avx2_entry_points!(
    occluded_packets,
    occluded_packets_avx2,
    occluded_packets_avx512,
    (bvh: &Bvh, triangles: &[TriangleRecord], view: &SurfaceView, rays: &[RayRecord], out: &mut [u32])
);
avx2_entry_points!(
    closest_hit_packets,
    closest_hit_packets_avx2,
    closest_hit_packets_avx512,
    (bvh: &Bvh, triangles: &[TriangleRecord], view: &SurfaceView, rays: &[RayRecord], out: &mut [Option<ClosestHit>])
);
avx2_entry_points!(occluded_single, occluded_single_avx2, occluded_single_avx512, (bvh: &Bvh, rays: &[RayRecord], out: &mut [u32]));
avx2_entry_points!(
    closest_hit_single,
    closest_hit_single_avx2,
    closest_hit_single_avx512,
    (bvh: &Bvh, rays: &[RayRecord], out: &mut [Option<ClosestHit>])
);

avx2_entry_points!(
    occluded_instance_packets,
    occluded_instance_packets_avx2,
    occluded_instance_packets_avx512,
    (levels: &TwoLevelBvh, view: &SurfaceView, rays: &[RayRecord], index: &[u32], out: &mut [u32])
);
avx2_entry_points!(
    closest_instance_packets,
    closest_instance_packets_avx2,
    closest_instance_packets_avx512,
    (levels: &TwoLevelBvh, view: &SurfaceView, rays: &[RayRecord], out: &mut [Option<ClosestHit>])
);

/// The object-space pass of any hit over `rays` (packets of consecutive entries), ray `j`
/// answering for `out[index[j]]`.
#[inline(always)]
fn occluded_instance_packets<L: Lanes>(
    levels: &TwoLevelBvh,
    view: &SurfaceView,
    rays: &[RayRecord],
    index: &[u32],
    out: &mut [u32],
) {
    let accept = alpha_test(view);
    let mut cache = instances::InstanceCache::default();
    for (rays, index) in rays.chunks(LANES).zip(index.chunks(LANES)) {
        let hit = match Packet::<L>::new(rays) {
            Some(p) => instances::occluded(levels, view, &p, &mut cache),
            None => rays
                .iter()
                .enumerate()
                .filter(|(_, r)| levels.occluded_in_object_space(r, accept))
                .fold(0, |m, (k, _)| m | 1 << k),
        };
        for (k, &i) in index.iter().enumerate() {
            out[i as usize] = occlusion(hit >> k & 1 != 0);
        }
    }
}

/// The object-space pass of closest hit over `rays` in packets of consecutive rays.
#[inline(always)]
fn closest_instance_packets<L: Lanes>(
    levels: &TwoLevelBvh,
    view: &SurfaceView,
    rays: &[RayRecord],
    out: &mut [Option<ClosestHit>],
) {
    let accept = alpha_test(view);
    for (out, rays) in out.chunks_mut(LANES).zip(rays.chunks(LANES)) {
        match Packet::<L>::new(rays) {
            Some(p) => instances::closest_hit(levels, view, &p, out),
            None => {
                for (c, r) in out.iter_mut().zip(rays) {
                    *c = levels.closest_hit_in_object_space(r, *c, accept);
                }
            }
        }
    }
}

#[inline(always)]
fn occluded_single<L: Lanes>(bvh: &Bvh, rays: &[RayRecord], out: &mut [u32]) {
    let mut stack = single::new_stack();
    for (o, r) in out.iter_mut().zip(rays) {
        *o = occlusion(single::occluded::<L>(&bvh.wide, r, &mut stack));
    }
}

#[inline(always)]
fn closest_hit_single<L: Lanes>(bvh: &Bvh, rays: &[RayRecord], out: &mut [Option<ClosestHit>]) {
    let mut stack = single::new_stack();
    for (o, r) in out.iter_mut().zip(rays) {
        *o = single::closest_hit::<L>(&bvh.wide, r, &mut stack);
    }
}

/// How many packets ahead of the one being traced the packet loops prefetch the ray
/// records ([`prefetch_packet`]).
const PREFETCH_PACKETS_AHEAD: usize = 4;

/// Prefetch the records of packet `k` of `rays` (rays `k * LANES ..`), where it exists,
/// into every cache level: a list of 64-byte records is read once, one packet at a time,
/// and the hardware prefetchers left `Packet::new`'s first reads of the records waiting on
/// memory (11% of the primary rays' packet time on Sponza in `perf record` samples, at the
/// records' transpose). Measured with and without, interleaved round by round in one
/// process (AMD EPYC Zen 5, AVX-512, `ray_contest --packets-only --rounds 21`, medians of
/// the per-round ratios, with / without; with the switch inverted, 1.12 to 1.69 on the
/// primary rays). Primary rays at two threads: the dragon 0.89 and 0.91, Sponza 0.85 and
/// 0.87, the teaser 0.86 and 0.87, the horses and bunnies 0.69 to 0.80; at one thread the
/// dragon 0.91, Sponza 0.91, the teaser 0.84, the rest 0.72 to 0.79. Shadow rays in tile
/// order at two threads: the teaser 0.85, Sponza 0.88, the near bunny 0.86, the dragon
/// 0.92, the near horse 0.95; the far horse's and the far bunny's short lists (6,085 and
/// 39,781 rays) within the noise. One to sixteen packets ahead measured alike (the teaser's and the
/// dragon's primary rays 0.87 to 0.91); four leaves about a microsecond. (An earlier try
/// at two packets ahead with the non-temporal hint measured within the noise on the
/// dragon's shadow rays.) The single rays' loop gained nothing from it (the teaser's
/// reflections, a list of 75,526 rays: 12.60 against 12.73 ms) and does not prefetch.
#[inline(always)]
fn prefetch_packet(rays: &[RayRecord], k: usize) {
    if let Some(packet) = rays.get(k * LANES..) {
        for r in packet.iter().take(LANES) {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: a prefetch is a hint, it reads no memory the program can observe;
            // the address is an element of `rays`. SSE is part of x86-64.
            unsafe {
                std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>((r as *const RayRecord).cast());
            }
            #[cfg(not(target_arch = "x86_64"))]
            let _ = r;
        }
    }
}

#[inline(always)]
fn occluded_packets<L: Lanes>(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    view: &SurfaceView,
    rays: &[RayRecord],
    out: &mut [u32],
) {
    let mut cache = None;
    for (i, (out, packet_rays)) in out.chunks_mut(LANES).zip(rays.chunks(LANES)).enumerate() {
        prefetch_packet(rays, i + PREFETCH_PACKETS_AHEAD);
        let Some(p) = Packet::<L>::new(packet_rays) else {
            for (o, r) in out.iter_mut().zip(packet_rays) {
                *o = occlusion(scalar_occluded(bvh, triangles, view, r));
            }
            continue;
        };
        let hit = packet::occluded::<L>(&packet::Level::world(bvh), view, &p, &mut cache);
        // A fixed-size array copied out, not a loop over the slice: the loop was vectorized
        // for 64 answers at a time in zmm registers, whose constants every call of the
        // AVX-512 entry point broadcast (Intel lowers the clock for 512-bit work).
        let answers: [u32; LANES] = std::array::from_fn(|i| occlusion(hit & (1 << i) != 0));
        out.copy_from_slice(&answers[..out.len()]);
    }
}

#[inline(always)]
fn closest_hit_packets<L: Lanes>(
    bvh: &Bvh,
    triangles: &[TriangleRecord],
    view: &SurfaceView,
    rays: &[RayRecord],
    out: &mut [Option<ClosestHit>],
) {
    // Coherent packets go through the wide view with one frustum test per node.
    let extent = frustum::scene_extent(bvh);
    let mut stack = if bvh.wide.is_empty() { Vec::new() } else { single::new_stack() };
    for (i, (out, packet_rays)) in out.chunks_mut(LANES).zip(rays.chunks(LANES)).enumerate() {
        prefetch_packet(rays, i + PREFETCH_PACKETS_AHEAD);
        let Some(p) = Packet::<L>::new(packet_rays) else {
            for (o, r) in out.iter_mut().zip(packet_rays) {
                *o = scalar_closest_hit(bvh, triangles, view, r);
            }
            continue;
        };
        let coherent = if bvh.wide.is_empty() { None } else { frustum::Frustum::new(&p, extent) };
        // The frustum walk may give up on a packet (`frustum::closest_hit`): the binary
        // walk then takes it, as it takes the packets the frustum declines.
        let done = match coherent {
            Some(f) => {
                octant_walk!(packet::packet_octant(&p), frustum::closest_hit::<L>(bvh, view, &p, &f, &mut stack, out))
            }
            None => false,
        };
        if !done {
            packet::closest_hit(&packet::Level::world(bvh), view, &p, out);
        }
    }
}
