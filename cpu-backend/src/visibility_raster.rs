//! `visibility_raster` (paper 3.2): rasterize every object into the visibility
//! G-buffer: per pixel the covering triangle's ids, its perspective-correct
//! barycentrics at the pixel centre, the window depth and the hit / ray-traced /
//! back-face flags.
//!
//! The rules are lavapipe's (llvmpipe on x86-64); the maths is in
//! [`hyrt_core::kernels::raster`], which documents each rule and its source. In short:
//! clip space in f32, homogeneous clipping against near (`z >= 0`) and far (`z <= w`)
//! and, only for vertices beyond it, a guard band; window x, y snapped to 1/256 pixel
//! (nearest, ties to even); exact 64-bit edge functions at pixel centres with the
//! top-left fill rule; zero-area triangles culled; no face culling; depth test LESS
//! against a clear value of 1.0.
//!
//! How it runs:
//! 1. *Setup*, in parallel over chunks of triangles: clip, project, snap, normalize
//!    the winding, cull; one [`RasterTriangle`]-like record per (sub-)triangle, in
//!    global triangle order (sub-triangles of a clipped triangle in fan order).
//! 2. *Binning* into [`TILE_SIZE`]-square tiles by the snapped pixel bounding box,
//!    skipping tiles the triangle provably misses; each bin keeps global order.
//! 3. *Tiles*, in parallel: each tile walks its bin in order with incremental
//!    integer edge stepping over the bounding box, keeps per pixel the nearest
//!    fragment (strictly smaller depth wins, so ties keep the earlier triangle), and
//!    then resolves barycentrics once per covered pixel.
//!
//! Every pixel is decided by one tile and every tile processes triangles in global
//! order, so the output does not depend on the number of threads.
//!
//! ```
//! use hyrt_core::{formats::CameraRecord, geometry::WorldGeometry, scene::Scene};
//! use hyrt_cpu::visibility_raster::visibility_raster;
//! let scene = Scene::default_scene();
//! let geometry = WorldGeometry::build(&scene);
//! let camera = CameraRecord::new(&scene.camera.unwrap(), 64, 48);
//! let out = visibility_raster(&geometry, &camera);
//! assert_eq!(out.gbuffer.len(), 64 * 48);
//! assert!(out.covered_pixels > 0);
//! ```

use hyrt_core::formats::{
    CameraRecord, GBufferTexel, TriangleRecord, GBUF_BACK_FACE, GBUF_HIT, GBUF_RAY_TRACED, TRI_RAY_TRACED,
};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::raster::{
    barycentrics_in_original, clip_plane_distance, clip_polygon_against_plane, clip_position, clip_to_window,
    edge_bias, edge_function, guard_band_ndc, interpolate_depth, perspective_barycentrics, pixel_center_fixed,
    pixel_span, snap_to_fixed, triangle_area2, ClipVertex, CLIP_PLANES, FIXED_ONE, MAX_CLIP_VERTICES, MAX_FIXED_COORD,
    MAX_IMAGE_DIM,
};
use rayon::prelude::*;

/// Side of a square screen tile in pixels (llvmpipe's `TILE_SIZE` is 64 too): a
/// tile's scratch buffers (depth, winner, edge values: 24 bytes per pixel, 96 KiB)
/// stay in L2.
pub const TILE_SIZE: u32 = 64;
const TILE_PIXELS: usize = (TILE_SIZE * TILE_SIZE) as usize;
/// Triangles per parallel setup task: large enough to amortize the task, small
/// enough to balance two to sixteen threads on 10^4 to 10^6 triangles.
const SETUP_CHUNK: usize = 2048;
/// Depth buffer clear value: the far plane, like a GPU depth buffer cleared to 1.0.
/// With the LESS test a fragment at depth exactly 1.0 is therefore never visible.
const DEPTH_CLEAR: f32 = 1.0;
/// Marks a pixel no fragment has won yet.
const NO_WINNER: u32 = u32::MAX;

/// The visibility G-buffer of one frame.
#[derive(Clone, Debug)]
pub struct VisibilityOutput {
    /// Row-major (`y * width + x`, row 0 at the top), one texel per pixel.
    pub gbuffer: Vec<GBufferTexel>,
    pub width: u32,
    pub height: u32,
    /// Number of hit texels.
    pub covered_pixels: usize,
}

/// Per-pixel coverage counts without depth test: how many rasterized triangles
/// cover each pixel centre, split by facing. Produced by [`coverage_counts`] with
/// exactly the setup, binning and tile traversal of [`visibility_raster`]; used to
/// check watertightness (no holes, no double coverage) and by conformance tests.
#[derive(Clone, Debug)]
pub struct CoverageCounts {
    /// Front-facing triangles covering each pixel centre (row-major).
    pub front: Vec<u32>,
    /// Back-facing triangles covering each pixel centre (row-major).
    pub back: Vec<u32>,
    pub width: u32,
    pub height: u32,
}

/// A set-up (sub-)triangle ready for traversal: snapped, counter-clockwise on screen.
#[derive(Clone, Copy, Debug)]
struct RasterTriangle {
    /// Snapped vertex positions (fixed point, pixel-centre frame), normalized so
    /// that `triangle_area2 > 0`.
    x: [i32; 3],
    y: [i32; 3],
    /// Inclusive pixel rectangle `[x0, y0, x1, y1]` that can be covered, clipped to
    /// the image.
    bbox: [i32; 4],
    /// Doubled area (> 0).
    area2: i64,
    /// Window depth `z / w` of each vertex.
    z: [f32; 3],
    /// Clip `w` of each vertex (> 0).
    w: [f32; 3],
    /// Barycentrics `(u, v)` of each vertex in the original triangle.
    bary: [[f32; 2]; 3],
    /// `TriangleRecord::object` and `TriangleRecord::triangle` of the source triangle.
    object: u32,
    triangle: u32,
    /// `GBUF_HIT` plus `GBUF_RAY_TRACED` / `GBUF_BACK_FACE` as they apply.
    flags: u32,
}

impl RasterTriangle {
    #[inline]
    fn vertex(&self, i: usize) -> [i64; 2] {
        [self.x[i] as i64, self.y[i] as i64]
    }
}

/// Frame constants shared by all setup tasks.
#[derive(Clone, Copy, Debug)]
struct Frame {
    /// Image size used by the viewport transform.
    width_f: f32,
    height_f: f32,
    /// Pixels actually rasterized (image size capped at `MAX_IMAGE_DIM`).
    width: u32,
    height: u32,
    tiles_x: u32,
    tiles_y: u32,
    guard: [f32; 2],
}

impl Frame {
    fn new(camera: &CameraRecord) -> Frame {
        let width = camera.width.min(MAX_IMAGE_DIM);
        let height = camera.height.min(MAX_IMAGE_DIM);
        Frame {
            width_f: camera.width as f32,
            height_f: camera.height as f32,
            width,
            height,
            tiles_x: width.div_ceil(TILE_SIZE),
            tiles_y: height.div_ceil(TILE_SIZE),
            guard: guard_band_ndc(camera.width, camera.height),
        }
    }
    fn tile_count(&self) -> usize {
        (self.tiles_x * self.tiles_y) as usize
    }
    /// Inclusive pixel rectangle of tile `index`.
    fn tile_rect(&self, index: usize) -> [i32; 4] {
        let tx = index as u32 % self.tiles_x;
        let ty = index as u32 / self.tiles_x;
        let x0 = tx * TILE_SIZE;
        let y0 = ty * TILE_SIZE;
        [
            x0 as i32,
            y0 as i32,
            ((x0 + TILE_SIZE).min(self.width) - 1) as i32,
            ((y0 + TILE_SIZE).min(self.height) - 1) as i32,
        ]
    }
}

/// Rasterize `geometry` as seen by `camera` into the visibility G-buffer.
///
/// Never panics on bad geometry: triangles with a non-finite clip coordinate, zero
/// area after snapping or nothing inside the view are skipped. An empty image
/// (width or height 0) gives an empty G-buffer.
pub fn visibility_raster(geometry: &WorldGeometry, camera: &CameraRecord) -> VisibilityOutput {
    let (w, h) = (camera.width as usize, camera.height as usize);
    // Zeroed (calloc) rather than filled: every texel of the rasterized area is
    // written by its tile, in parallel.
    let mut gbuffer: Vec<GBufferTexel> = bytemuck::zeroed_vec(w * h);
    if w == 0 || h == 0 {
        return VisibilityOutput { gbuffer, width: camera.width, height: camera.height, covered_pixels: 0 };
    }
    let frame = Frame::new(camera);
    if frame.width as usize != w || frame.height as usize != h {
        // Beyond MAX_IMAGE_DIM: those pixels belong to no tile and stay misses.
        gbuffer.fill(GBufferTexel::MISS);
    }
    let tris = setup_triangles(geometry, camera, &frame);
    let bins = bin_triangles(&tris, &frame);
    let slices = tile_slices(&mut gbuffer, w, &frame);
    let covered: usize = slices
        .into_par_iter()
        .enumerate()
        .map_init(TileScratch::new, |scratch, (tile, rows)| {
            scratch.clear();
            let rect = frame.tile_rect(tile);
            rasterize_tile(&tris, &bins[tile], rect, |i, t, e| {
                let depth = interpolate_depth(e, t.area2, t.z);
                // LESS against the stored depth (clear value 1.0); NaN and negative
                // depths are never written.
                if depth < scratch.depth[i] && depth >= 0.0 {
                    scratch.depth[i] = depth;
                    scratch.winner[i] = t.reference;
                    scratch.e12[i] = [e[1], e[2]];
                }
            });
            resolve_tile(&tris, scratch, rect, rows)
        })
        .sum();
    VisibilityOutput { gbuffer, width: camera.width, height: camera.height, covered_pixels: covered }
}

/// Count, per pixel, the front- and back-facing rasterized triangles covering its
/// centre, with the same setup, binning and traversal as [`visibility_raster`] but
/// no depth test. For a closed mesh inside the view volume every pixel has as many
/// front as back coverings; for an open, flat mesh every pixel of its footprint is
/// covered exactly once.
pub fn coverage_counts(geometry: &WorldGeometry, camera: &CameraRecord) -> CoverageCounts {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut counts = vec![[0u32; 2]; w * h];
    if w > 0 && h > 0 {
        let frame = Frame::new(camera);
        let tris = setup_triangles(geometry, camera, &frame);
        let bins = bin_triangles(&tris, &frame);
        let slices = tile_slices(&mut counts, w, &frame);
        slices.into_par_iter().enumerate().for_each(|(tile, mut rows)| {
            let rect = frame.tile_rect(tile);
            rasterize_tile(&tris, &bins[tile], rect, |i, t, _| {
                let row = i / TILE_SIZE as usize;
                let col = i % TILE_SIZE as usize;
                let back = (t.tri.flags & GBUF_BACK_FACE != 0) as usize;
                rows[row][col][back] += 1;
            });
        });
    }
    CoverageCounts {
        front: counts.iter().map(|c| c[0]).collect(),
        back: counts.iter().map(|c| c[1]).collect(),
        width: camera.width,
        height: camera.height,
    }
}

// ---------------------------------------------------------------------------------------------
// Setup
// ---------------------------------------------------------------------------------------------

/// Bits of a packed triangle reference holding the index within its setup chunk.
const CHUNK_INDEX_BITS: u32 = 14;
// A chunk's triangles can all be clipped into fans of up to MAX_CLIP_VERTICES - 2.
const _: () = assert!(SETUP_CHUNK * (MAX_CLIP_VERTICES - 2) <= 1 << CHUNK_INDEX_BITS);

/// Set-up triangles, in global triangle order, as one vector per setup chunk
/// (no copy into one array). A reference packs `chunk << CHUNK_INDEX_BITS | index`,
/// so references compare in global order.
struct SetupTriangles {
    chunks: Vec<Vec<RasterTriangle>>,
}

impl SetupTriangles {
    #[inline]
    fn get(&self, reference: u32) -> &RasterTriangle {
        &self.chunks[(reference >> CHUNK_INDEX_BITS) as usize][(reference & ((1 << CHUNK_INDEX_BITS) - 1)) as usize]
    }
    fn iter(&self) -> impl Iterator<Item = (u32, &RasterTriangle)> {
        self.chunks
            .iter()
            .enumerate()
            .flat_map(|(c, v)| v.iter().enumerate().map(move |(i, t)| (((c as u32) << CHUNK_INDEX_BITS) | i as u32, t)))
    }
}

/// Set up every triangle, in parallel.
fn setup_triangles(geometry: &WorldGeometry, camera: &CameraRecord, frame: &Frame) -> SetupTriangles {
    // Triangle counts beyond the packed reference range (2^32 / 2^14 chunks of
    // SETUP_CHUNK, about 5e8 triangles) are not rasterized.
    let max_chunks = 1usize << (32 - CHUNK_INDEX_BITS);
    let chunks = geometry
        .triangles
        .par_chunks(SETUP_CHUNK)
        .take(max_chunks)
        .map(|tris| {
            let mut out = Vec::with_capacity(tris.len() + tris.len() / 8);
            for t in tris {
                setup_triangle(t, camera, frame, &mut out);
            }
            out
        })
        .collect();
    SetupTriangles { chunks }
}

/// Clip, project and snap one triangle; push zero or more sub-triangles.
fn setup_triangle(tri: &TriangleRecord, camera: &CameraRecord, frame: &Frame, out: &mut Vec<RasterTriangle>) {
    let m = &camera.view_proj;
    let clip = [clip_position(m, tri.v0), clip_position(m, tri.v1), clip_position(m, tri.v2)];
    if !clip.iter().flatten().all(|c| c.is_finite()) {
        return;
    }
    let flags = GBUF_HIT | if tri.flags & TRI_RAY_TRACED != 0 { GBUF_RAY_TRACED } else { 0 };
    // Planes some vertex lies outside of; all three outside one plane: nothing left.
    let mut outside = 0u32;
    for (p, plane) in CLIP_PLANES.iter().enumerate() {
        let d = clip.map(|c| clip_plane_distance(*plane, c, frame.guard));
        // A NaN distance counts as outside (the polygon clipper treats it so).
        let out_count = d.iter().filter(|d| d.is_nan() || **d < 0.0).count();
        if out_count == 3 {
            return;
        }
        if out_count > 0 {
            outside |= 1 << p;
        }
    }
    let corners = ClipVertex::triangle(clip);
    if outside == 0 {
        emit_triangle(tri, flags, corners, frame, out);
        return;
    }
    let mut poly = [corners[0]; MAX_CLIP_VERTICES];
    poly[..3].copy_from_slice(&corners);
    let mut n = 3;
    let mut next = poly;
    for (p, plane) in CLIP_PLANES.iter().enumerate() {
        if outside & (1 << p) != 0 {
            n = clip_polygon_against_plane(*plane, frame.guard, &poly[..n], &mut next);
            std::mem::swap(&mut poly, &mut next);
            if n < 3 {
                return;
            }
        }
    }
    // Fan from the first vertex, like llvmpipe's clipper.
    for i in 1..n - 1 {
        emit_triangle(tri, flags, [poly[0], poly[i], poly[i + 1]], frame, out);
    }
}

/// Project, snap, cull and normalize one (sub-)triangle.
fn emit_triangle(src: &TriangleRecord, flags: u32, v: [ClipVertex; 3], frame: &Frame, out: &mut Vec<RasterTriangle>) {
    let win = v.map(|c| clip_to_window(c.pos, frame.width_f, frame.height_f));
    if !win.iter().flatten().all(|c| c.is_finite()) || !v.iter().all(|c| c.pos[3] > 0.0) {
        return;
    }
    let fixed = win.map(|p| [snap_to_fixed(p[0]), snap_to_fixed(p[1])]);
    if fixed.iter().flatten().any(|c| c.abs() > MAX_FIXED_COORD) {
        return;
    }
    let area = triangle_area2(fixed[0], fixed[1], fixed[2]);
    if area == 0 {
        return;
    }
    // Counter-clockwise on screen is a front face (see the kernel docs); normalize
    // clockwise triangles (back faces) by swapping v1 and v2.
    let (order, flags) = if area > 0 { ([0, 1, 2], flags) } else { ([0, 2, 1], flags | GBUF_BACK_FACE) };
    let p = order.map(|i| fixed[i]);
    let xs = p.map(|q| q[0]);
    let ys = p.map(|q| q[1]);
    let [x0, x1] = pixel_span(min3(xs), max3(xs));
    let [y0, y1] = pixel_span(min3(ys), max3(ys));
    let bbox = [x0.max(0), y0.max(0), x1.min(frame.width as i64 - 1), y1.min(frame.height as i64 - 1)];
    if bbox[0] > bbox[2] || bbox[1] > bbox[3] {
        return;
    }
    out.push(RasterTriangle {
        x: xs.map(|c| c as i32),
        y: ys.map(|c| c as i32),
        bbox: bbox.map(|c| c as i32),
        area2: area.abs(),
        z: order.map(|i| win[i][2]),
        w: order.map(|i| v[i].pos[3]),
        bary: order.map(|i| v[i].bary),
        object: src.object,
        triangle: src.triangle,
        flags,
    });
}

#[inline]
fn min3(v: [i64; 3]) -> i64 {
    v[0].min(v[1]).min(v[2])
}

#[inline]
fn max3(v: [i64; 3]) -> i64 {
    v[0].max(v[1]).max(v[2])
}

// ---------------------------------------------------------------------------------------------
// Binning and traversal
// ---------------------------------------------------------------------------------------------

/// Incremental evaluation of the three biased edge functions over pixel centres.
#[derive(Clone, Copy, Debug)]
struct EdgeStepper {
    /// Biased values (`edge_function + edge_bias`) at the start pixel.
    start: [i64; 3],
    /// Fill-rule biases (0 or -1) to recover the exact values.
    bias: [i64; 3],
    /// Change per pixel to the right and per pixel down.
    step_x: [i64; 3],
    step_y: [i64; 3],
}

impl EdgeStepper {
    /// Edge `i` runs from vertex `i + 1` to vertex `i + 2` (opposite vertex `i`).
    #[inline]
    fn new(t: &RasterTriangle, px: i64, py: i64) -> EdgeStepper {
        let p = pixel_center_fixed(px, py);
        let mut s = EdgeStepper { start: [0; 3], bias: [0; 3], step_x: [0; 3], step_y: [0; 3] };
        for i in 0..3 {
            let a = t.vertex((i + 1) % 3);
            let b = t.vertex((i + 2) % 3);
            s.bias[i] = edge_bias(a, b);
            s.start[i] = edge_function(a, b, p) + s.bias[i];
            s.step_x[i] = (b[1] - a[1]) * FIXED_ONE;
            s.step_y[i] = -(b[0] - a[0]) * FIXED_ONE;
        }
        s
    }

    /// False if some edge is negative at every pixel centre of a `nx` x `ny` block
    /// starting at the start pixel (the block is then certainly not covered).
    #[inline]
    fn may_cover_block(&self, nx: i64, ny: i64) -> bool {
        (0..3).all(|i| self.start[i] + (self.step_x[i] * (nx - 1)).max(0) + (self.step_y[i] * (ny - 1)).max(0) >= 0)
    }
}

/// Per tile, the references of the set-up triangles that may cover it, ascending.
fn bin_triangles(tris: &SetupTriangles, frame: &Frame) -> Vec<Vec<u32>> {
    let mut bins = vec![Vec::new(); frame.tile_count()];
    let ts = TILE_SIZE as i32;
    for (reference, t) in tris.iter() {
        let [x0, y0, x1, y1] = t.bbox;
        let (tx0, ty0, tx1, ty1) = (x0 / ts, y0 / ts, x1 / ts, y1 / ts);
        if tx0 == tx1 && ty0 == ty1 {
            bins[(ty0 as u32 * frame.tiles_x + tx0 as u32) as usize].push(reference);
            continue;
        }
        for ty in ty0..=ty1 {
            for tx in tx0..=tx1 {
                let tile = (ty as u32 * frame.tiles_x + tx as u32) as usize;
                let r = frame.tile_rect(tile);
                let (cx0, cy0) = (x0.max(r[0]), y0.max(r[1]));
                let (cx1, cy1) = (x1.min(r[2]), y1.min(r[3]));
                let e = EdgeStepper::new(t, cx0 as i64, cy0 as i64);
                if e.may_cover_block((cx1 - cx0 + 1) as i64, (cy1 - cy0 + 1) as i64) {
                    bins[tile].push(reference);
                }
            }
        }
    }
    bins
}

/// A triangle as the per-fragment callback sees it.
struct Fragment<'a> {
    tri: &'a RasterTriangle,
    reference: u32,
}

impl std::ops::Deref for Fragment<'_> {
    type Target = RasterTriangle;
    fn deref(&self) -> &RasterTriangle {
        self.tri
    }
}

/// Triangles whose clipped bounding box in a tile is at most this many pixels wide
/// are traversed by testing every pixel; wider ones compute each row's covered span
/// first (a division estimate corrected by exact tests), which skips the empty
/// parts of large bounding boxes. Both give exactly the same pixels.
const SPAN_MIN_WIDTH: i32 = 8;

/// Smallest `k` in `[0, n)` with `e + k * s >= 0` for an edge with `s > 0`
/// (`n` when there is none). `inv_s = 1 / s`; the estimate is corrected exactly.
#[inline]
fn first_inside(e: i64, s: i64, inv_s: f64, n: i64) -> i64 {
    if e >= 0 {
        return 0;
    }
    let mut k = ((-e) as f64 * inv_s).ceil().clamp(0.0, n as f64) as i64;
    while k < n && e + k * s < 0 {
        k += 1;
    }
    while k > 0 && e + (k - 1) * s >= 0 {
        k -= 1;
    }
    k
}

/// Largest `k` in `[0, n)` with `e + k * s >= 0` for an edge with `s < 0` and
/// `e >= 0`. `inv_s = 1 / s`; the estimate is corrected exactly.
#[inline]
fn last_inside(e: i64, s: i64, inv_s: f64, n: i64) -> i64 {
    let mut k = (e as f64 * -inv_s).floor().clamp(0.0, (n - 1) as f64) as i64;
    while k > 0 && e + k * s < 0 {
        k -= 1;
    }
    while k + 1 < n && e + (k + 1) * s >= 0 {
        k += 1;
    }
    k
}

/// Walk the bin of the tile `rect` in order and call `f(local_pixel, triangle,
/// exact_edge_values)` for every covered pixel centre, `local_pixel` being
/// `(y - rect.y0) * TILE_SIZE + (x - rect.x0)`.
#[inline]
fn rasterize_tile<F: FnMut(usize, &Fragment<'_>, [i64; 3])>(
    tris: &SetupTriangles,
    bin: &[u32],
    rect: [i32; 4],
    mut f: F,
) {
    for &reference in bin {
        let t = tris.get(reference);
        let x0 = t.bbox[0].max(rect[0]);
        let y0 = t.bbox[1].max(rect[1]);
        let x1 = t.bbox[2].min(rect[2]);
        let y1 = t.bbox[3].min(rect[3]);
        if x0 > x1 || y0 > y1 {
            continue;
        }
        let frag = Fragment { tri: t, reference };
        let s = EdgeStepper::new(t, x0 as i64, y0 as i64);
        let n = (x1 - x0 + 1) as i64;
        let inv = s.step_x.map(|d| if d != 0 { 1.0 / d as f64 } else { 0.0 });
        let mut row = s.start;
        for y in y0..=y1 {
            let base = (y - rect[1]) as usize * TILE_SIZE as usize + (x0 - rect[0]) as usize;
            if n <= SPAN_MIN_WIDTH as i64 {
                let mut e = row;
                for k in 0..n as usize {
                    if (e[0] | e[1] | e[2]) >= 0 {
                        f(base + k, &frag, [e[0] - s.bias[0], e[1] - s.bias[1], e[2] - s.bias[2]]);
                    }
                    e[0] += s.step_x[0];
                    e[1] += s.step_x[1];
                    e[2] += s.step_x[2];
                }
            } else {
                // The covered pixels of a row of a convex shape are one run [lo, hi].
                let (mut lo, mut hi) = (0i64, n - 1);
                for i in 0..3 {
                    let (e, d) = (row[i], s.step_x[i]);
                    if d > 0 {
                        lo = lo.max(first_inside(e, d, inv[i], n));
                    } else if e < 0 {
                        hi = -1;
                    } else if d < 0 {
                        hi = hi.min(last_inside(e, d, inv[i], n));
                    }
                }
                let mut e = [row[0] + lo * s.step_x[0], row[1] + lo * s.step_x[1], row[2] + lo * s.step_x[2]];
                for k in lo..=hi {
                    debug_assert!((e[0] | e[1] | e[2]) >= 0);
                    f(base + k as usize, &frag, [e[0] - s.bias[0], e[1] - s.bias[1], e[2] - s.bias[2]]);
                    e[0] += s.step_x[0];
                    e[1] += s.step_x[1];
                    e[2] += s.step_x[2];
                }
            }
            row[0] += s.step_y[0];
            row[1] += s.step_y[1];
            row[2] += s.step_y[2];
        }
    }
}

/// Depth-test state of one tile.
struct TileScratch {
    depth: Vec<f32>,
    winner: Vec<u32>,
    /// Exact edge values e1, e2 of the winning fragment (e0 = area2 - e1 - e2).
    e12: Vec<[i64; 2]>,
}

impl TileScratch {
    fn new() -> TileScratch {
        TileScratch {
            depth: vec![DEPTH_CLEAR; TILE_PIXELS],
            winner: vec![NO_WINNER; TILE_PIXELS],
            e12: vec![[0; 2]; TILE_PIXELS],
        }
    }
    fn clear(&mut self) {
        self.depth.fill(DEPTH_CLEAR);
        self.winner.fill(NO_WINNER);
    }
}

/// Write every texel of one tile from its depth-test state; returns the hit count.
fn resolve_tile(
    tris: &SetupTriangles,
    scratch: &TileScratch,
    rect: [i32; 4],
    mut rows: Vec<&mut [GBufferTexel]>,
) -> usize {
    let mut covered = 0;
    for (ly, row) in rows.iter_mut().enumerate() {
        for (lx, texel) in row.iter_mut().enumerate() {
            let i = ly * TILE_SIZE as usize + lx;
            let winner = scratch.winner[i];
            if winner == NO_WINNER {
                *texel = GBufferTexel::MISS;
                continue;
            }
            let t = tris.get(winner);
            let [e1, e2] = scratch.e12[i];
            let e = [t.area2 - e1 - e2, e1, e2];
            let b = perspective_barycentrics(e, t.w);
            let [u, v] = barycentrics_in_original(b, t.bary);
            *texel = GBufferTexel {
                bary_u: u,
                bary_v: v,
                depth: scratch.depth[i],
                triangle: t.triangle,
                object: t.object,
                flags: t.flags,
            };
            if cfg!(debug_assertions) {
                texel.validate().expect("visibility_raster texel invariants");
            }
            covered += 1;
        }
    }
    debug_assert_eq!(rows.len() as i32, rect[3] - rect[1] + 1);
    covered
}

/// Split a row-major image into per-tile lists of row slices (tile-major order), so
/// tiles can be written in parallel without copying.
fn tile_slices<'a, T>(buf: &'a mut [T], width: usize, frame: &Frame) -> Vec<Vec<&'a mut [T]>> {
    let mut tiles: Vec<Vec<&mut [T]>> =
        (0..frame.tile_count()).map(|_| Vec::with_capacity(TILE_SIZE as usize)).collect();
    let raster_w = frame.width as usize;
    for (y, row) in buf.chunks_mut(width).enumerate().take(frame.height as usize) {
        let ty = y / TILE_SIZE as usize;
        for (tx, seg) in row[..raster_w].chunks_mut(TILE_SIZE as usize).enumerate() {
            tiles[ty * frame.tiles_x as usize + tx].push(seg);
        }
    }
    tiles
}
