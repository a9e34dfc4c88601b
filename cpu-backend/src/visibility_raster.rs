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
//! top-left fill rule; zero-area triangles culled; no face culling, except that the
//! triangles that show the interior of a closed object no pixel can see inside are
//! dropped (below); depth test LESS
//! against a clear value of 1.0, with the depths of fragments that show a surface's
//! interior side (`shows_interior`: a back face, or a front face of a closed mesh wound
//! inward) pushed back by `INTERIOR_DEPTH_BIAS_ULPS` f32 steps so that they lose near-ties
//! at silhouettes (`depth_test_value`; the G-buffer keeps the unbiased depth).
//!
//! How it runs:
//! 1. *Setup and binning*, in parallel over chunks of `SETUP_CHUNK` source
//!    triangles: reject triangles wholly outside one frustum side, clip the rest,
//!    project, snap, cull zero-area ones, normalize the winding (one record per
//!    (sub-)triangle, in order; sub-triangles of a clipped triangle in fan order),
//!    then bin the chunk's triangles into [`TILE_SIZE`]-square tiles by their snapped
//!    pixel bounding box, skipping tiles a triangle provably misses. A triangle whose box
//!    holds no pixel centre, or one centre it does not cover, is dropped here (on a
//!    dense mesh most triangles are: of the dragon's 871,926 in `assets/scenes/dragon.toml`,
//!    403,470 have an empty box and 309,353 a box of one pixel). The setup runs eight
//!    triangles at a time (module `setup`). Dropping the uncovered one-pixel triangles
//!    took the dragon's setup from 29.2 to 34.3 ms and its fused tiles from 151.6 to 141.5
//!    ms (one thread, the binaries alternated twice), the other scenes unchanged.
//!    Also dropped here: an unclipped triangle that shows its object's interior
//!    (`shows_interior`) where the object is a closed mesh whose bounds lie wholly in
//!    front of the near plane ([`hyrt_core::kernels::raster::interior_hidden`], decided
//!    once a frame per object by [`WorldGeometry::interior_culls`]; the argument that no
//!    pixel loses its surface is there). Such a triangle can only win a pixel by rounding,
//!    where it lies nearer than the exterior in front of it; the setup, binning and tile
//!    walks of about half of every closed mesh's triangles go. The GPU's setup pass drops
//!    the same triangles. [`coverage_counts`] counts every triangle.
//! 2. *Tiles*, in parallel: each tile walks its bins chunk by chunk, i.e. in global
//!    triangle order (prefetching the triangle records ahead). Per triangle and row it
//!    gets the exact run of covered pixels from incremental integer edge walks (narrow
//!    boxes test each pixel instead), steps the exact edge values along it, skips
//!    fragments whose approximate depth certainly fails, and keeps per pixel the
//!    nearest fragment's depth and triangle (strictly smaller exact depth wins, so ties
//!    keep the earlier triangle). Then, per row, each run of pixels one triangle won
//!    gets its edge values stepped again and its barycentrics, once per pixel.
//!
//! With AVX-512 or AVX2 (run-time detection, [`SimdLevel::Avx512`], [`SimdLevel::Avx2`])
//! both steps of a tile take eight pixels at a time (`avx512`, `avx2`, sharing `lanes`:
//! every exact depth, no early rejection; rows up to eight pixels wide without walks),
//! lane by lane the same IEEE operations as the scalar kernels, so the same bits; elsewhere
//! they run pixel by pixel. AVX2 lacks AVX-512's conversion of i64 to f32: each span and run
//! takes exact i32 lanes, or i64 lanes through f64, by its edge values' magnitude, and the
//! scalar kernel beyond 2^51 (triangles far into the guard band).
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
    CameraRecord, GBufferTexel, TriangleRecord, GBUF_BACK_FACE, GBUF_HIT, GBUF_RAY_TRACED, TRI_ALPHA_TEST, TRI_INWARD,
    TRI_RAY_TRACED,
};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::raster::{
    barycentrics_in_original, clip_plane_distance, clip_polygon_against_plane, clip_position_from_eye, clip_to_window,
    culls_interior, depth_test_value, edge_bias, edge_function, guard_band_ndc, interpolate_depth,
    perspective_barycentrics, perspective_barycentrics_of_corners, pixel_center_fixed, pixel_covered, pixel_span,
    shows_interior, snap_to_fixed, triangle_area2, ClipVertex, CLIP_PLANES, DEPTH_INTERPOLATION_REL_ERROR, FIXED_ONE,
    INTERIOR_DEPTH_BIAS_ULPS, MAX_CLIP_VERTICES, MAX_FIXED_COORD, MAX_IMAGE_DIM,
};
use hyrt_core::kernels::texture::{alpha_accepts, SurfaceView};
use rayon::prelude::*;

use crate::traversal::SimdLevel;

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
#[cfg(target_arch = "x86_64")]
mod lanes;
mod setup;

/// Side of a square screen tile in pixels (llvmpipe's `TILE_SIZE` is 64 too): a
/// tile's scratch buffers (depth and winner: 8 bytes per pixel, 32 KiB) stay in L1/L2.
pub const TILE_SIZE: u32 = 64;
const TILE_PIXELS: usize = (TILE_SIZE * TILE_SIZE) as usize;
const _: () = assert!(TILE_PIXELS.is_power_of_two());
/// Triangles per parallel setup task: large enough to amortize the task and its
/// bins, small enough to balance two to sixteen threads on 10^4 to 10^6 triangles.
const SETUP_CHUNK: usize = 2048;
/// Setup chunks rasterized per batch (about 10^6 triangles): a frame's set-up triangles
/// and bins are held one batch at a time, so memory does not grow with the scene (the
/// 871 million triangles of 1,000 instanced dragons), and packed references
/// (`CHUNK_INDEX_BITS`) never overflow. Scenes of one batch are rasterized in one pass.
const BATCH_CHUNKS: usize = 512;
const _: () = assert!(BATCH_CHUNKS <= 1 << (32 - CHUNK_INDEX_BITS));
/// Depth buffer clear value: the far plane, like a GPU depth buffer cleared to 1.0.
/// With the LESS test a fragment at depth exactly 1.0 is therefore never visible.
const DEPTH_CLEAR: f32 = 1.0;
/// [`RasterTriangle::corners`] of a clipped triangle.
const NOT_CORNERS: [u8; 2] = [u8::MAX; 2];
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
/// exactly the setup, binning and tile traversal of [`visibility_raster`], but for every
/// triangle (the interiors of closed objects the raster drops included); used to
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
    /// For an unclipped triangle, the indices of the original v1 and v2 among the
    /// (reordered) vertices; `NOT_CORNERS` for a clipped one.
    corners: [u8; 2],
    /// `TriangleRecord::object` and `TriangleRecord::triangle` of the source triangle.
    object: u32,
    triangle: u32,
    /// `GBUF_HIT` plus `GBUF_RAY_TRACED` / `GBUF_BACK_FACE` as they apply.
    flags: u32,
    /// The triangle shows its surface's interior side (`shows_interior`): its depth
    /// loses near-ties (`depth_test_value`).
    interior: bool,
    /// Its material is alpha-tested (`TRI_ALPHA_TEST`): each fragment's texel alpha is
    /// tested before the depth test ([`AlphaTested`]).
    masked: bool,
}

impl RasterTriangle {
    #[inline]
    fn vertex(&self, i: usize) -> [i64; 2] {
        [self.x[i] as i64, self.y[i] as i64]
    }

    /// Exact (unbiased) edge values at the centre of pixel `(px, py)` and their change
    /// per pixel to the right: edge `i` runs from vertex `i + 1` to vertex `i + 2`, as
    /// in [`EdgeStepper`].
    #[inline]
    fn edge_values(&self, px: i64, py: i64) -> ([i64; 3], [i64; 3]) {
        let p = pixel_center_fixed(px, py);
        let edge = |i: usize| (self.vertex((i + 1) % 3), self.vertex((i + 2) % 3));
        (
            std::array::from_fn(|i| edge_function(edge(i).0, edge(i).1, p)),
            std::array::from_fn(|i| (edge(i).1[1] - edge(i).0[1]) * FIXED_ONE),
        )
    }
}

/// Frame constants shared by all setup tasks.
#[derive(Clone, Debug)]
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
    /// The objects whose triangles that show their interior are dropped at setup
    /// ([`WorldGeometry::interior_culls`]; empty: none).
    interior_culls: Vec<u32>,
}

impl Frame {
    /// The frame of `camera` for `geometry`'s triangles: [`Frame::new`] with the objects
    /// whose interior no pixel can see ([`culls_interior`]).
    fn for_geometry(geometry: &WorldGeometry, camera: &CameraRecord) -> Frame {
        Frame { interior_culls: geometry.interior_culls(camera), ..Frame::new(camera) }
    }

    /// The frame of `camera`, culling no object's interior.
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
            interior_culls: Vec::new(),
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
    let mut gbuffer = Vec::new();
    let covered_pixels = raster_frame(geometry, camera, TileKernel::detect(), &mut gbuffer);
    VisibilityOutput { gbuffer, width: camera.width, height: camera.height, covered_pixels }
}

/// [`visibility_raster`] into a caller-owned G-buffer, reusing its allocation from
/// frame to frame (no page faults on a buffer of the same size). Returns the number
/// of covered pixels. Every texel is written, whatever the buffer held before.
pub fn visibility_raster_into(
    geometry: &WorldGeometry,
    camera: &CameraRecord,
    gbuffer: &mut Vec<GBufferTexel>,
) -> usize {
    raster_frame(geometry, camera, TileKernel::detect(), gbuffer)
}

/// True if the raster takes `geometry`'s triangles in batches (over `BATCH_CHUNKS` setup
/// chunks, about a million triangles): a fused frame then keeps the texels whole-image
/// between batches ([`crate::memory`]).
pub fn batched(geometry: &WorldGeometry) -> bool {
    geometry.triangles.len().div_ceil(SETUP_CHUNK) > BATCH_CHUNKS
}

/// How the tiles are rasterized and resolved. Every kernel gives the same bits (the unit
/// tests compare them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum TileKernel {
    /// Pixel by pixel, with the early depth rejection (any target).
    Scalar,
    /// Pixel by pixel, every fragment's exact depth tested (for tests of the early
    /// rejection).
    #[cfg(test)]
    ScalarNoEarlyReject,
    /// Eight pixels at a time with AVX2 (`avx2`), detected at run time.
    #[cfg(target_arch = "x86_64")]
    Avx2,
    /// Eight pixels at a time with AVX-512 (`avx512`), detected at run time.
    #[cfg(target_arch = "x86_64")]
    Avx512,
}

impl TileKernel {
    /// The kernel of [`SimdLevel::detect`]: AVX-512 or AVX2 at those levels, else the
    /// scalar one.
    fn detect() -> TileKernel {
        match SimdLevel::detect() {
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx512 => TileKernel::Avx512,
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => TileKernel::Avx2,
            _ => TileKernel::Scalar,
        }
    }
}

/// [`visibility_raster`] with the tile kernel `kernel` (available on this CPU).
fn raster_frame(
    geometry: &WorldGeometry,
    camera: &CameraRecord,
    kernel: TileKernel,
    gbuffer: &mut Vec<GBufferTexel>,
) -> usize {
    raster_frame_in_batches(geometry, camera, kernel, gbuffer, BATCH_CHUNKS)
}

/// Rasterize the frame with the kernel of this CPU and run `hook` on each tile right after
/// its texels are final (see [`raster_tiles`]): the G-buffer into `gbuffer` if given, else
/// only into tile-local scratch (scenes of one batch).
pub(crate) fn visibility_raster_with<H: TileHook>(
    geometry: &WorldGeometry,
    camera: &CameraRecord,
    gbuffer: Option<&mut Vec<GBufferTexel>>,
    hook: &H,
    outs: Vec<H::Out>,
) -> RasterTiles<H::Counts> {
    raster_tiles(geometry, camera, TileKernel::detect(), gbuffer, Some((hook, outs)), BATCH_CHUNKS)
}

/// [`raster_frame`] in batches of `batch_chunks` setup chunks (tests take small ones).
fn raster_frame_in_batches(
    geometry: &WorldGeometry,
    camera: &CameraRecord,
    kernel: TileKernel,
    gbuffer: &mut Vec<GBufferTexel>,
    batch_chunks: usize,
) -> usize {
    raster_tiles::<NoHook>(geometry, camera, kernel, Some(gbuffer), None, batch_chunks).covered
}

/// The texels of one raster tile once they are final (after its last resolve), as a
/// [`TileHook`] reads them.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TileTexels<'a> {
    /// The tile's top-left pixel.
    pub origin: (usize, usize),
    /// Its width and height in pixels: [`TILE_SIZE`], less at the image's right and
    /// bottom edges.
    pub size: (usize, usize),
    /// Row-major, [`TILE_SIZE`] texels a row: texel `(lx, ly)` of the tile is
    /// `texels[ly * TILE_SIZE + lx]` (for `lx < size.0`).
    pub texels: &'a [GBufferTexel],
    /// Every texel of the tile is [`GBufferTexel::MISS`]: no triangle was binned to it.
    /// A hook may skip reading them (they are the misses all the same).
    pub all_miss: bool,
}

/// What runs on each raster tile right after its texels are final, while they are in
/// cache ([`raster_tiles`]): the fused executor's steps (`crate::fused`).
pub(crate) trait TileHook: Sync {
    /// What it writes for one tile (the tile's rows of the final image), one per raster
    /// tile in the order of [`tile_rows`] over [`raster_area`] with [`TILE_SIZE`].
    type Out: Send;
    /// Each worker's scratch, kept from tile to tile.
    type Scratch: Send;
    /// What it counts, summed over tiles.
    type Counts: Send + Default;
    fn scratch(&self) -> Self::Scratch;
    fn tile(&self, scratch: &mut Self::Scratch, texels: TileTexels<'_>, out: Self::Out) -> Self::Counts;
    fn add(a: Self::Counts, b: Self::Counts) -> Self::Counts;
}

/// The raster alone: no hook.
struct NoHook;

impl TileHook for NoHook {
    type Out = ();
    type Scratch = ();
    type Counts = ();
    fn scratch(&self) {}
    fn tile(&self, _: &mut (), _: TileTexels<'_>, _: ()) {}
    fn add(_: (), _: ()) {}
}

/// What [`raster_tiles`] gives.
pub(crate) struct RasterTiles<C> {
    /// Number of hit texels.
    pub covered: usize,
    /// The hook's counts, summed over tiles.
    pub counts: C,
    /// Time spent setting up and binning triangles (every batch's), before the tiles
    /// that read them.
    pub setup: std::time::Duration,
}

/// The top-left area of the image the raster's tiles cover (the image, at most
/// `MAX_IMAGE_DIM` a side): what [`TileHook::Out`] tiles.
pub(crate) fn raster_area(camera: &CameraRecord) -> (usize, usize) {
    (camera.width.min(MAX_IMAGE_DIM) as usize, camera.height.min(MAX_IMAGE_DIM) as usize)
}

/// Rasterize the frame in batches of `batch_chunks` setup chunks, the G-buffer into
/// `gbuffer` when given (every texel written, the buffer sized to the frame), and run
/// `hook` on each tile right after its last resolve, with one of `outs` (see
/// [`TileHook::Out`]).
///
/// Without a hook the tiles resolve straight into `gbuffer` (the staged frame). With one,
/// each worker resolves a tile into a tile-local G-buffer ([`TILE_PIXELS`] texels, 96 KiB),
/// copies it into `gbuffer` if given and hands it to the hook: a frame that wants no
/// whole-image G-buffer has none. Scenes of more than one batch keep their texels from
/// batch to batch in a whole-image G-buffer (`gbuffer`, or one of this call's), whose
/// tiles are copied into the tile-local one after the last batch.
fn raster_tiles<H: TileHook>(
    geometry: &WorldGeometry,
    camera: &CameraRecord,
    kernel: TileKernel,
    mut gbuffer: Option<&mut Vec<GBufferTexel>>,
    mut hook: Option<(&H, Vec<H::Out>)>,
    batch_chunks: usize,
) -> RasterTiles<H::Counts> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut setup = std::time::Duration::ZERO;
    let none = |setup| RasterTiles { covered: 0, counts: H::Counts::default(), setup };
    if let Some(gbuffer) = gbuffer.as_deref_mut() {
        // Sized, not filled: every texel of the rasterized area is written by its tile,
        // in parallel. A fresh buffer is zeroed (calloc); a reused one keeps its pages.
        if gbuffer.len() != w * h {
            *gbuffer = bytemuck::zeroed_vec(w * h);
        }
    }
    if w == 0 || h == 0 {
        return none(setup);
    }
    let frame = Frame::for_geometry(geometry, camera);
    if frame.width as usize != w || frame.height as usize != h {
        // Beyond MAX_IMAGE_DIM: those pixels belong to no tile and stay misses.
        if let Some(gbuffer) = gbuffer.as_deref_mut() {
            gbuffer.fill(GBufferTexel::MISS);
        }
    }
    if let Some((_, outs)) = &hook {
        assert_eq!(outs.len(), frame.tile_count(), "raster_tiles: one output per raster tile");
    }
    let chunks = geometry.triangles.len().div_ceil(SETUP_CHUNK);
    let alpha = AlphaTests::of(geometry);
    let timed = |setup: &mut std::time::Duration, range| {
        let t = std::time::Instant::now();
        let tris = setup_triangles(geometry, camera, &frame, range);
        *setup += t.elapsed();
        tris
    };
    if chunks <= batch_chunks {
        // One batch: each tile's scratch lives for its task only.
        let tris = timed(&mut setup, 0..chunks);
        let slices = match gbuffer {
            Some(gbuffer) => tile_slices(gbuffer, w, &frame).into_iter().map(Some).collect(),
            None => (0..frame.tile_count()).map(|_| None).collect::<Vec<_>>(),
        };
        let Some((hook, outs)) = hook else {
            let covered = slices
                .into_par_iter()
                .enumerate()
                .map_init(TileScratch::new, |scratch, (tile, rows)| {
                    let rows = rows.expect("a G-buffer where no hook reads the tiles");
                    if tris.tile_is_empty(tile) {
                        rows.into_iter().for_each(|r| r.fill(GBufferTexel::MISS));
                        return 0;
                    }
                    scratch.clear();
                    raster_tile(kernel, &tris, tile, frame.tile_rect(tile), scratch, rows, alpha, Resolve::Every)
                })
                .sum();
            return RasterTiles { covered, counts: H::Counts::default(), setup };
        };
        let (covered, counts) = slices
            .into_par_iter()
            .zip(outs)
            .enumerate()
            .map_init(
                || (TileScratch::new(), LocalTexels::new(), hook.scratch()),
                |(scratch, local, hs), (tile, (rows, out))| {
                    let rect = frame.tile_rect(tile);
                    // A tile no triangle is binned to: its texels are misses, and the hook
                    // is told so.
                    let covered = if tris.tile_is_empty(tile) {
                        local.set_all_miss();
                        0
                    } else {
                        scratch.clear();
                        raster_tile(kernel, &tris, tile, rect, scratch, local.rows(rect), alpha, Resolve::Every)
                    };
                    if let Some(rows) = rows {
                        local.copy_to(rows);
                    }
                    (covered, hook.tile(hs, local.texels(rect), out))
                },
            )
            .reduce(|| (0, H::Counts::default()), |a, b| (a.0 + b.0, H::add(a.1, b.1)));
        return RasterTiles { covered, counts, setup };
    }
    // Batches of `batch_chunks` chunks, in global order, each tile keeping its depth
    // buffer from batch to batch: a triangle of a later batch wins a pixel exactly when
    // it would in one pass (strictly nearer than every earlier one). After each batch a
    // tile writes the texels of the pixels that batch won (their final texels when no
    // later batch wins them); the first batch writes every texel.
    let mut own;
    let store = match gbuffer {
        Some(gbuffer) => gbuffer,
        None => {
            own = bytemuck::zeroed_vec(w * h);
            &mut own
        }
    };
    let mut counts = H::Counts::default();
    let mut scratches: Vec<TileScratch> = (0..frame.tile_count()).map(|_| TileScratch::new()).collect();
    let batches: Vec<usize> = (0..chunks).step_by(batch_chunks).collect();
    for (b, &first) in batches.iter().enumerate() {
        let tris = timed(&mut setup, first..(first + batch_chunks).min(chunks));
        let slices = tile_slices(store, w, &frame);
        let resolve = if b == 0 { Resolve::Every } else { Resolve::Won };
        let tiles = slices.into_par_iter().zip(scratches.par_iter_mut()).enumerate();
        match hook.take_if(|_| b + 1 == batches.len()) {
            None => tiles.for_each(|(tile, (rows, scratch))| {
                batch_tile(kernel, &tris, tile, frame.tile_rect(tile), scratch, rows, alpha, resolve);
            }),
            // The last batch: each tile's texels are final after its resolve.
            Some((hook, outs)) => {
                counts = tiles
                    .zip(outs)
                    .map_init(
                        || (LocalTexels::new(), hook.scratch()),
                        |(local, hs), ((tile, (mut rows, scratch)), out)| {
                            let rect = frame.tile_rect(tile);
                            let reborrowed = rows.iter_mut().map(|r| &mut **r).collect();
                            batch_tile(kernel, &tris, tile, rect, scratch, reborrowed, alpha, resolve);
                            local.copy_from(&rows);
                            hook.tile(hs, local.texels(rect), out)
                        },
                    )
                    .reduce(H::Counts::default, H::add);
            }
        }
    }
    // A pixel was won (in some batch) exactly when its stored depth fell below the clear
    // value: the depth test is LESS against DEPTH_CLEAR.
    let covered = scratches.par_iter().map(|s| s.depth.iter().filter(|&&d| d < DEPTH_CLEAR).count()).sum();
    RasterTiles { covered, counts, setup }
}

/// A tile-local G-buffer: one tile's texels, [`TILE_SIZE`] a row, and whether every one
/// is [`GBufferTexel::MISS`] (so that a run of empty tiles writes them once, not once a
/// tile).
struct LocalTexels {
    texels: Box<[GBufferTexel]>,
    all_miss: bool,
}

impl LocalTexels {
    fn new() -> LocalTexels {
        LocalTexels { texels: vec![GBufferTexel::MISS; TILE_PIXELS].into_boxed_slice(), all_miss: true }
    }
    /// The rows of the tile with inclusive pixel rectangle `rect`, for [`resolve_tile`]
    /// (which writes them: they are no longer taken for misses).
    fn rows(&mut self, rect: [i32; 4]) -> Vec<&mut [GBufferTexel]> {
        self.all_miss = false;
        let (tw, th) = ((rect[2] - rect[0] + 1) as usize, (rect[3] - rect[1] + 1) as usize);
        self.texels.chunks_mut(TILE_SIZE as usize).take(th).map(|r| &mut r[..tw]).collect()
    }
    /// Every texel a miss (a tile no triangle is binned to), written only where they
    /// were not all misses already.
    fn set_all_miss(&mut self) {
        if !self.all_miss {
            self.texels.fill(GBufferTexel::MISS);
            self.all_miss = true;
        }
    }
    fn texels(&self, rect: [i32; 4]) -> TileTexels<'_> {
        let size = ((rect[2] - rect[0] + 1) as usize, (rect[3] - rect[1] + 1) as usize);
        TileTexels { origin: (rect[0] as usize, rect[1] as usize), size, texels: &self.texels, all_miss: self.all_miss }
    }
    /// Copy the tile's rows out to a whole-image G-buffer's.
    fn copy_to(&self, rows: Vec<&mut [GBufferTexel]>) {
        for (row, local) in rows.into_iter().zip(self.texels.chunks(TILE_SIZE as usize)) {
            row.copy_from_slice(&local[..row.len()]);
        }
    }
    /// Copy the tile's rows in from a whole-image G-buffer's.
    fn copy_from(&mut self, rows: &[&mut [GBufferTexel]]) {
        self.all_miss = false;
        for (row, local) in rows.iter().zip(self.texels.chunks_mut(TILE_SIZE as usize)) {
            local[..row.len()].copy_from_slice(row);
        }
    }
}

/// One tile of one batch of [`raster_tiles`]: the batch's triangles binned to it depth
/// tested against what earlier batches left in `scratch`, then resolved into `rows` as
/// `resolve` says. A tile the batch bins nothing to has no winner in it: only the first
/// batch's misses are written.
#[allow(clippy::too_many_arguments)]
fn batch_tile(
    kernel: TileKernel,
    tris: &SetupTriangles,
    tile: usize,
    rect: [i32; 4],
    scratch: &mut TileScratch,
    rows: Vec<&mut [GBufferTexel]>,
    alpha: Option<AlphaTests>,
    resolve: Resolve,
) {
    if tris.tile_is_empty(tile) {
        if resolve == Resolve::Every {
            rows.into_iter().for_each(|r| r.fill(GBufferTexel::MISS));
        }
        return;
    }
    scratch.winner.fill(NO_WINNER);
    raster_tile(kernel, tris, tile, rect, scratch, rows, alpha, resolve);
}

/// Which texels of a tile [`resolve_tile`] writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Resolve {
    /// Every texel (misses where no triangle won); returns the hit count.
    Every,
    /// Only those of pixels a triangle of this batch won (the others keep what an
    /// earlier batch wrote); returns 0.
    Won,
}

/// Rasterize one tile's bins into `scratch` and resolve its texels into `rows` with
/// `kernel`; returns what [`resolve_tile`] counts.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn raster_tile(
    kernel: TileKernel,
    tris: &SetupTriangles,
    tile: usize,
    rect: [i32; 4],
    scratch: &mut TileScratch,
    rows: Vec<&mut [GBufferTexel]>,
    alpha: Option<AlphaTests>,
    resolve: Resolve,
) -> usize {
    match kernel {
        TileKernel::Scalar => {
            rasterize_tile_with(tris, tile, rect, &mut *scratch, alpha);
            resolve_tile::<ScalarTexels>(tris, scratch, rect, rows, resolve)
        }
        #[cfg(test)]
        TileKernel::ScalarNoEarlyReject => {
            rasterize_tile_with(tris, tile, rect, NoEarlyReject(scratch), alpha);
            resolve_tile::<ScalarTexels>(tris, scratch, rect, rows, resolve)
        }
        #[cfg(target_arch = "x86_64")]
        // SAFETY: only detected or tested where the CPU has AVX2.
        TileKernel::Avx2 => unsafe { avx2::tile(tris, tile, rect, scratch, rows, alpha, resolve) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: only detected or tested where the CPU has AVX-512.
        TileKernel::Avx512 => unsafe { avx512::tile(tris, tile, rect, scratch, rows, alpha, resolve) },
    }
}

/// Count, per pixel, the front- and back-facing rasterized triangles covering its
/// centre, with the same setup, binning and traversal as [`visibility_raster`] but
/// no depth test and no triangle dropped for showing a closed object's interior. For a
/// closed mesh inside the view volume every pixel has as many front as back coverings;
/// for an open, flat mesh every pixel of its footprint is covered exactly once.
pub fn coverage_counts(geometry: &WorldGeometry, camera: &CameraRecord) -> CoverageCounts {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut counts = vec![[0u32; 2]; w * h];
    if w > 0 && h > 0 {
        // Every triangle, the interiors the raster drops included: a count of coverage.
        let frame = Frame::new(camera);
        let chunks = geometry.triangles.len().div_ceil(SETUP_CHUNK);
        // Batches as the raster's: bounded memory, references in range.
        for first in (0..chunks).step_by(BATCH_CHUNKS) {
            let tris = setup_triangles(geometry, camera, &frame, first..(first + BATCH_CHUNKS).min(chunks));
            let slices = tile_slices(&mut counts, w, &frame);
            slices.into_par_iter().enumerate().for_each(|(tile, mut rows)| {
                let rect = frame.tile_rect(tile);
                rasterize_tile(&tris, tile, rect, &mut CountSink { rows: &mut rows });
            });
        }
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

/// The set-up triangles of one setup chunk (consecutive source triangles), in
/// order, and their bins: for each tile, the ascending indices (within the chunk)
/// of the triangles that may cover it.
struct SetupChunk {
    tris: Vec<RasterTriangle>,
    /// `bin_items[bin_start[tile]..bin_start[tile + 1]]` is the bin of `tile`.
    bin_start: Vec<u32>,
    bin_items: Vec<u16>,
}

impl SetupChunk {
    #[inline]
    fn bin(&self, tile: usize) -> &[u16] {
        &self.bin_items[self.bin_start[tile] as usize..self.bin_start[tile + 1] as usize]
    }
}

/// All set-up triangles, chunk by chunk, so in global triangle order. A triangle is
/// referred to as `chunk << CHUNK_INDEX_BITS | index`; references compare in
/// global order.
struct SetupTriangles {
    chunks: Vec<SetupChunk>,
}

impl SetupTriangles {
    #[inline]
    fn get(&self, reference: u32) -> &RasterTriangle {
        &self.chunks[(reference >> CHUNK_INDEX_BITS) as usize].tris
            [(reference & ((1 << CHUNK_INDEX_BITS) - 1)) as usize]
    }

    /// No triangle is binned to `tile`: every pixel of it is a miss, with nothing to
    /// rasterize or resolve.
    #[inline]
    fn tile_is_empty(&self, tile: usize) -> bool {
        self.chunks.iter().all(|c| c.bin(tile).is_empty())
    }
}

/// Set up and bin the source triangles of setup chunks `chunks` (chunk `c` holds global
/// triangles `c * SETUP_CHUNK ..`), in parallel over chunks; objects by reference have
/// their records made here ([`hyrt_core::geometry::WorldTriangles::fill`]).
fn setup_triangles(
    geometry: &WorldGeometry,
    camera: &CameraRecord,
    frame: &Frame,
    chunks: std::ops::Range<usize>,
) -> SetupTriangles {
    let n = geometry.triangles.len();
    let level = SimdLevel::detect();
    let setup = |tris: &[TriangleRecord]| {
        let mut out = Vec::with_capacity(tris.len() + tris.len() / 8);
        setup::setup_chunk(tris, camera, frame, level, &mut out);
        bin_chunk(out, frame)
    };
    let chunks = chunks
        .into_par_iter()
        .map_init(Vec::new, |buf, c| {
            let range = c * SETUP_CHUNK..((c + 1) * SETUP_CHUNK).min(n);
            match geometry.triangles.as_slice() {
                Some(all) => setup(&all[range]),
                None => {
                    geometry.triangles.fill(range, buf);
                    setup(buf)
                }
            }
        })
        .collect();
    SetupTriangles { chunks }
}

/// Bin the triangles of one chunk into tiles by their bounding box, skipping tiles
/// a triangle provably misses (a counting sort by tile, stable in triangle order).
fn bin_chunk(tris: Vec<RasterTriangle>, frame: &Frame) -> SetupChunk {
    let ts = TILE_SIZE as i32;
    let mut pairs: Vec<(u32, u16)> = Vec::with_capacity(tris.len() + tris.len() / 4);
    for (index, t) in tris.iter().enumerate() {
        let [x0, y0, x1, y1] = t.bbox;
        let (tx0, ty0, tx1, ty1) = (x0 / ts, y0 / ts, x1 / ts, y1 / ts);
        if tx0 == tx1 && ty0 == ty1 {
            pairs.push((ty0 as u32 * frame.tiles_x + tx0 as u32, index as u16));
            continue;
        }
        for ty in ty0..=ty1 {
            for tx in tx0..=tx1 {
                let tile = ty as u32 * frame.tiles_x + tx as u32;
                let r = frame.tile_rect(tile as usize);
                let (cx0, cy0) = (x0.max(r[0]), y0.max(r[1]));
                let (cx1, cy1) = (x1.min(r[2]), y1.min(r[3]));
                let e = EdgeStepper::new(t, cx0 as i64, cy0 as i64);
                if e.may_cover_block((cx1 - cx0 + 1) as i64, (cy1 - cy0 + 1) as i64) {
                    pairs.push((tile, index as u16));
                }
            }
        }
    }
    let mut bin_start = vec![0u32; frame.tile_count() + 1];
    for &(tile, _) in &pairs {
        bin_start[tile as usize + 1] += 1;
    }
    for i in 1..bin_start.len() {
        bin_start[i] += bin_start[i - 1];
    }
    let mut cursor = bin_start.clone();
    let mut bin_items = vec![0u16; pairs.len()];
    for (tile, index) in pairs {
        bin_items[cursor[tile as usize] as usize] = index;
        cursor[tile as usize] += 1;
    }
    SetupChunk { tris, bin_start, bin_items }
}

/// Outcode bits beyond the clip planes' (bit p for `CLIP_PLANES[p]`): the viewport
/// sides `x > w`, `x < -w`, `y > w`, `y < -w`. Used only to reject triangles wholly
/// beyond one side (in homogeneous space, so valid for any sign of w): such a
/// triangle cannot cover a pixel centre, whose NDC coordinates are inside (-1, 1).
const VIEWPORT_OUTCODES: [u32; 4] = [1 << 6, 1 << 7, 1 << 8, 1 << 9];
/// Outcode bits of the clip planes (`CLIP_PLANES`).
const CLIP_OUTCODES: u32 = (1 << CLIP_PLANES.len()) - 1;

/// Clip, project and snap one triangle; push zero or more sub-triangles. The scalar
/// setup, which the setup in lanes (module `setup`) must equal triangle for triangle.
#[cfg_attr(not(test), allow(dead_code))]
fn setup_triangle(tri: &TriangleRecord, camera: &CameraRecord, frame: &Frame, out: &mut Vec<RasterTriangle>) {
    let (m, eye) = (&camera.view_proj, camera.eye);
    let clip = [
        clip_position_from_eye(m, eye, tri.v0),
        clip_position_from_eye(m, eye, tri.v1),
        clip_position_from_eye(m, eye, tri.v2),
    ];
    setup_from_clip(tri, clip, frame, out);
}

/// [`setup_triangle`] from the clip positions of the triangle's vertices
/// (`clip_position_from_eye`): reject, clip, project, snap; push zero or more
/// sub-triangles.
fn setup_from_clip(tri: &TriangleRecord, clip: [[f32; 4]; 3], frame: &Frame, out: &mut Vec<RasterTriangle>) {
    let mut finite = true;
    for c in &clip {
        finite &= c[0].is_finite() & c[1].is_finite() & c[2].is_finite() & c[3].is_finite();
    }
    if !finite {
        return;
    }
    // Outcodes; all three vertices beyond one plane: nothing to draw.
    let (mut all, mut any) = (u32::MAX, 0u32);
    for c in &clip {
        let mut code = 0;
        for (p, plane) in CLIP_PLANES.iter().enumerate() {
            // Distances of finite positions are never NaN (at worst infinite).
            if clip_plane_distance(*plane, *c, frame.guard) < 0.0 {
                code |= 1 << p;
            }
        }
        let (x, y, w) = (c[0], c[1], c[3]);
        code |= if x > w { VIEWPORT_OUTCODES[0] } else { 0 };
        code |= if x < -w { VIEWPORT_OUTCODES[1] } else { 0 };
        code |= if y > w { VIEWPORT_OUTCODES[2] } else { 0 };
        code |= if y < -w { VIEWPORT_OUTCODES[3] } else { 0 };
        all &= code;
        any |= code;
    }
    if all != 0 {
        return;
    }
    let flags = raster_flags(tri);
    let corners = ClipVertex::triangle(clip);
    let outside = any & CLIP_OUTCODES;
    if outside == 0 {
        emit_triangle(tri, flags, true, [&corners[0], &corners[1], &corners[2]], frame, out);
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
        emit_triangle(tri, flags, false, [&poly[0], &poly[i], &poly[i + 1]], frame, out);
    }
}

/// Project, snap, cull and normalize one (sub-)triangle.
fn emit_triangle(
    src: &TriangleRecord,
    flags: u32,
    unclipped: bool,
    v: [&ClipVertex; 3],
    frame: &Frame,
    out: &mut Vec<RasterTriangle>,
) {
    let mut win = [[0.0f32; 3]; 3];
    let mut fixed = [[0i64; 2]; 3];
    for k in 0..3 {
        let p = clip_to_window(v[k].pos, frame.width_f, frame.height_f);
        if !(p[0].is_finite() && p[1].is_finite() && p[2].is_finite() && v[k].pos[3] > 0.0) {
            return;
        }
        fixed[k] = [snap_to_fixed(p[0]), snap_to_fixed(p[1])];
        if fixed[k][0].abs() > MAX_FIXED_COORD || fixed[k][1].abs() > MAX_FIXED_COORD {
            return;
        }
        win[k] = p;
    }
    finish_triangle(src, flags, unclipped, v, win, fixed, frame, out);
}

/// The G-buffer flags every fragment of `tri` starts with (the back-face flag is added
/// per sub-triangle by [`finish_triangle`]).
#[inline]
fn raster_flags(tri: &TriangleRecord) -> u32 {
    GBUF_HIT | if tri.flags & TRI_RAY_TRACED != 0 { GBUF_RAY_TRACED } else { 0 }
}

/// The end of [`emit_triangle`], from its vertices' window positions `win` and snapped
/// coordinates `fixed` (each vertex finite, `w > 0`, within [`MAX_FIXED_COORD`]): cull
/// zero-area triangles, normalize the winding and push the triangle if its pixel box
/// within the image is not empty.
#[allow(clippy::too_many_arguments)]
#[inline]
fn finish_triangle(
    src: &TriangleRecord,
    flags: u32,
    unclipped: bool,
    v: [&ClipVertex; 3],
    win: [[f32; 3]; 3],
    fixed: [[i64; 2]; 3],
    frame: &Frame,
    out: &mut Vec<RasterTriangle>,
) {
    let area = triangle_area2(fixed[0], fixed[1], fixed[2]);
    if area == 0 {
        return;
    }
    // Counter-clockwise on screen is a front face (see the kernel docs); normalize
    // clockwise triangles (back faces) by swapping v1 and v2.
    let (a, b, flags) = if area > 0 { (1, 2, flags) } else { (2, 1, flags | GBUF_BACK_FACE) };
    let interior = shows_interior(flags & GBUF_BACK_FACE != 0, src.flags & TRI_INWARD != 0);
    // The inside of a closed object no pixel can see (`interior_hidden`). Clipped
    // sub-triangles are kept, as the GPU's setup pass keeps them.
    if interior && unclipped && culls_interior(&frame.interior_culls, src.object) {
        return;
    }
    let xs = [fixed[0][0], fixed[a][0], fixed[b][0]];
    let ys = [fixed[0][1], fixed[a][1], fixed[b][1]];
    let [x0, x1] = pixel_span(min3(xs), max3(xs));
    let [y0, y1] = pixel_span(min3(ys), max3(ys));
    let bbox = [x0.max(0), y0.max(0), x1.min(frame.width as i64 - 1), y1.min(frame.height as i64 - 1)];
    if bbox[0] > bbox[2] || bbox[1] > bbox[3] {
        return;
    }
    let t = RasterTriangle {
        x: [xs[0] as i32, xs[1] as i32, xs[2] as i32],
        y: [ys[0] as i32, ys[1] as i32, ys[2] as i32],
        bbox: [bbox[0] as i32, bbox[1] as i32, bbox[2] as i32, bbox[3] as i32],
        area2: area.abs(),
        z: [win[0][2], win[a][2], win[b][2]],
        w: [v[0].pos[3], v[a].pos[3], v[b].pos[3]],
        bary: [v[0].bary, v[a].bary, v[b].bary],
        corners: if unclipped { [if a == 1 { 1 } else { 2 }, if a == 1 { 2 } else { 1 }] } else { NOT_CORNERS },
        object: src.object,
        triangle: src.triangle,
        flags,
        interior,
        masked: src.flags & TRI_ALPHA_TEST != 0,
    };
    // One candidate pixel whose centre the triangle does not cover (the tiles' biased
    // edge values there, `EdgeStepper`): the tile would find no fragment.
    if bbox[0] == bbox[2] && bbox[1] == bbox[3] && !pixel_covered(EdgeStepper::new(&t, bbox[0], bbox[1]).start) {
        return;
    }
    out.push(t);
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

/// A triangle as the per-span and per-fragment callbacks see it.
struct Fragment<'a> {
    tri: &'a RasterTriangle,
    reference: u32,
    /// Edge values over the triangle's box within the tile.
    stepper: EdgeStepper,
    /// The approximate depth (see [`DEPTH_REJECT_MARGIN`]): vertex depths in f64,
    /// `1 / area2` and the numerator's change per pixel to the right.
    z64: [f64; 3],
    inv_area: f64,
    dz: f64,
}

/// The pixels of one row of a triangle within a tile, `base..base + len` in tile-local
/// indices.
struct Span {
    base: usize,
    len: usize,
    /// Biased edge values (see [`EdgeStepper`]) at the first pixel.
    e: [i64; 3],
    /// Every pixel is covered (a run from the [`EdgeWalk`]s); else each is tested.
    covered: bool,
}

impl std::ops::Deref for Fragment<'_> {
    type Target = RasterTriangle;
    fn deref(&self) -> &RasterTriangle {
        self.tri
    }
}

/// Exact per-row bound of the covered run `[lo, hi]` contributed by one edge,
/// stepped from row to row without division (a Bresenham-style quotient and
/// remainder). With `E(y)` the biased edge value at the row's first pixel and `d`
/// its change per pixel, the edge admits pixel `k` iff `E + k d >= 0`:
/// for `d > 0` that is `k >= ceil(-E / d) = floor((-E + d - 1) / d)` (a lower
/// bound), for `d < 0` it is `k <= floor(E / -d)` (an upper bound), for `d = 0` all
/// or nothing. `quotient` is the bound for the current row.
#[derive(Clone, Copy, Debug)]
struct EdgeWalk {
    kind: WalkKind,
    quotient: i64,
    remainder: i64,
    divisor: i64,
    step_quotient: i64,
    step_remainder: i64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum WalkKind {
    Lower,
    Upper,
    Flat,
}

impl EdgeWalk {
    /// `e`: biased value at the first pixel of the first row; `dx`, `dy`: change per
    /// pixel right and per row down. `multi_row`: whether `step` will be called (its
    /// division is skipped otherwise).
    #[inline]
    fn new(e: i64, dx: i64, dy: i64, multi_row: bool) -> EdgeWalk {
        // Numerator at the first row and its change per row, and the divisor.
        let (kind, num, step, divisor) = if dx > 0 {
            (WalkKind::Lower, -e + dx - 1, -dy, dx)
        } else if dx < 0 {
            (WalkKind::Upper, e, dy, -dx)
        } else {
            (WalkKind::Flat, e, dy, 1)
        };
        let quotient = num.div_euclid(divisor);
        let (step_quotient, step_remainder) = if multi_row {
            let q = step.div_euclid(divisor);
            (q, step - q * divisor)
        } else {
            (0, 0)
        };
        EdgeWalk { kind, quotient, remainder: num - quotient * divisor, divisor, step_quotient, step_remainder }
    }

    /// Move to the next row.
    #[inline]
    fn step(&mut self) {
        self.quotient += self.step_quotient;
        self.remainder += self.step_remainder;
        if self.remainder >= self.divisor {
            self.remainder -= self.divisor;
            self.quotient += 1;
        }
    }

    /// Narrow the run `[lo, hi]` of the current row by this edge.
    #[inline]
    fn clip_run(&self, lo: &mut i64, hi: &mut i64) {
        match self.kind {
            WalkKind::Lower => *lo = (*lo).max(self.quotient),
            WalkKind::Upper => *hi = (*hi).min(self.quotient),
            // divisor 1: quotient is the edge value itself.
            WalkKind::Flat => {
                if self.quotient < 0 {
                    *hi = -1;
                }
            }
        }
    }
}

/// Triangles whose bounding box within a tile is at most this many pixels wide are
/// traversed by testing every pixel of the box; wider ones get each row's covered
/// run from their [`EdgeWalk`]s. Both visit exactly the same covered pixels.
const NARROW_BOX_WIDTH: i64 = 4;

/// Margin of the early depth rejection. The approximate depth is `num / area2`
/// with `num = sum e_i z_i` evaluated in f64 at a covered pixel, or stepped along a
/// covered run by `sum step_x_i z_i` (at most 64 steps). On covered pixels every
/// `e_i` lies in `[0, area2]` and every `z_i` in `[0, 1]`, and along a covered run
/// `|step_x_i| * steps <= area2`, so the f64 rounding errors add up to less than
/// `70 * 2^-52` of the depth range. The exact depth ([`interpolate_depth`], f32) is
/// within [`DEPTH_INTERPOLATION_REL_ERROR`] (8 * 2^-24) of the true value, which is at
/// most 1. If the approximate depth exceeds the stored one by more than the sum of both
/// (rounded up to 2^-20), the exact depth is at least the stored depth and fails LESS,
/// so skipping it changes nothing. (The stored value may be an interior side's biased
/// depth, and an interior fragment compares its biased depth: both only move the
/// comparison further in the same direction.)
const DEPTH_REJECT_MARGIN: f64 = 1.0 / (1u64 << 20) as f64;
const _: () = assert!(DEPTH_REJECT_MARGIN > DEPTH_INTERPOLATION_REL_ERROR + 70.0 * f64::EPSILON);

/// What the tile traversal does with covered pixel centres. `local_pixel` is
/// `(y - rect.y0) * TILE_SIZE + (x - rect.x0)`.
trait FragmentSink {
    /// Triangles whose box within a tile is at most this many pixels wide get no
    /// [`EdgeWalk`]s: their spans cover the box's row and [`Self::span`] tests each pixel.
    const NARROW_BOX_WIDTH: i64 = NARROW_BOX_WIDTH;
    /// False if the fragment certainly fails (its approximate depth, see
    /// [`DEPTH_REJECT_MARGIN`], is too far); `fragment` is then not called.
    fn early(&self, local_pixel: usize, approx_depth: f64) -> bool;
    /// A covered pixel centre with the exact (unbiased) edge values.
    fn fragment(&mut self, local_pixel: usize, t: &Fragment<'_>, e: [i64; 3]);
    /// Every pixel of `span`, with `early` and `fragment` per covered pixel centre;
    /// a sink may do the same work its own way, with the same result.
    #[inline(always)]
    fn span(&mut self, span: &Span, t: &Fragment<'_>) {
        span_scalar(self, span, t);
    }
}

/// [`FragmentSink::span`] pixel by pixel.
#[inline(always)]
fn span_scalar<S: FragmentSink + ?Sized>(sink: &mut S, span: &Span, t: &Fragment<'_>) {
    let s = &t.stepper;
    let mut e = span.e;
    let raw = |e: [i64; 3]| [e[0] - s.bias[0], e[1] - s.bias[1], e[2] - s.bias[2]];
    let z = t.z64;
    let approx = |r: [i64; 3]| r[0] as f64 * z[0] + r[1] as f64 * z[1] + r[2] as f64 * z[2];
    if !span.covered {
        // Test every pixel; the approximate depth is computed afresh at covered ones
        // only (see DEPTH_REJECT_MARGIN).
        for i in span.base..span.base + span.len {
            if (e[0] | e[1] | e[2]) >= 0 {
                let r = raw(e);
                if sink.early(i, approx(r) * t.inv_area) {
                    sink.fragment(i, t, r);
                }
            }
            e[0] += s.step_x[0];
            e[1] += s.step_x[1];
            e[2] += s.step_x[2];
        }
    } else {
        // Every pixel of the run is covered; the approximate depth's numerator steps
        // along it.
        let mut num = approx(raw(e));
        for i in span.base..span.base + span.len {
            debug_assert!((e[0] | e[1] | e[2]) >= 0, "run outside the triangle");
            if sink.early(i, num * t.inv_area) {
                sink.fragment(i, t, raw(e));
            }
            e[0] += s.step_x[0];
            e[1] += s.step_x[1];
            e[2] += s.step_x[2];
            num += t.dz;
        }
    }
}

impl FragmentSink for TileScratch {
    #[inline]
    fn early(&self, i: usize, approx_depth: f64) -> bool {
        approx_depth < self.depth[tile_index(i)] as f64 + DEPTH_REJECT_MARGIN
    }
    #[inline]
    fn fragment(&mut self, i: usize, t: &Fragment<'_>, e: [i64; 3]) {
        let i = tile_index(i);
        let d = interpolate_depth(e, t.area2, t.z);
        // LESS against the stored depth (clear value 1.0), interior sides pushed back
        // (`depth_test_value`: they lose near-ties at silhouettes); NaN and negative
        // depths are never written. The stored value is the biased one.
        let key = depth_test_value(d, t.interior);
        if key < self.depth[i] && d >= 0.0 {
            self.depth[i] = key;
            self.winner[i] = t.reference;
        }
    }
}

/// The scene's alpha tests, for a frame with alpha-tested materials.
#[derive(Clone, Copy)]
struct AlphaTests<'g> {
    geometry: &'g WorldGeometry,
    view: SurfaceView<'g>,
}

impl<'g> AlphaTests<'g> {
    /// The tests of `geometry`, `None` when no material is alpha-tested.
    fn of(geometry: &'g WorldGeometry) -> Option<AlphaTests<'g>> {
        geometry.surface.alpha_tested().then(|| AlphaTests { geometry, view: geometry.surface.view() })
    }

    /// Whether the fragment of masked triangle `t` with exact edge values `e` is there:
    /// [`alpha_accepts`] at the barycentrics its G-buffer texel would get.
    #[inline]
    fn accepts(&self, t: &RasterTriangle, e: [i64; 3]) -> bool {
        let [u, v] = t.barycentrics(e);
        let global = self.geometry.global_triangle(t.object, t.triangle);
        alpha_accepts(&self.view, &self.geometry.triangle(global), global, u, v)
    }
}

/// A depth-test sink in a scene with alpha-tested materials: a fragment of a masked
/// triangle enters `inner`'s depth test only where its texel passes ([`AlphaTests::accepts`]),
/// so a hole shows what lies behind it. Masked triangles' spans are walked pixel by pixel;
/// every other triangle's span goes to `inner` as it is (a SIMD kernel's eight pixels
/// at a time, say), so the result is `inner`'s bits with the holes cut.
struct AlphaTested<'g, S> {
    inner: S,
    tests: AlphaTests<'g>,
}

impl<S: FragmentSink> FragmentSink for AlphaTested<'_, S> {
    const NARROW_BOX_WIDTH: i64 = S::NARROW_BOX_WIDTH;
    #[inline]
    fn early(&self, i: usize, approx_depth: f64) -> bool {
        self.inner.early(i, approx_depth)
    }
    #[inline]
    fn fragment(&mut self, i: usize, t: &Fragment<'_>, e: [i64; 3]) {
        if t.masked && !self.tests.accepts(t, e) {
            return;
        }
        self.inner.fragment(i, t, e);
    }
    #[inline(always)]
    fn span(&mut self, span: &Span, t: &Fragment<'_>) {
        if t.masked {
            span_scalar(self, span, t);
        } else {
            self.inner.span(span, t);
        }
    }
}

/// A sink by mutable reference.
impl<S: FragmentSink + ?Sized> FragmentSink for &mut S {
    const NARROW_BOX_WIDTH: i64 = S::NARROW_BOX_WIDTH;
    #[inline(always)]
    fn early(&self, i: usize, approx_depth: f64) -> bool {
        (**self).early(i, approx_depth)
    }
    #[inline(always)]
    fn fragment(&mut self, i: usize, t: &Fragment<'_>, e: [i64; 3]) {
        (**self).fragment(i, t, e);
    }
    #[inline(always)]
    fn span(&mut self, span: &Span, t: &Fragment<'_>) {
        (**self).span(span, t);
    }
}

/// [`rasterize_tile`] into `sink`, through [`AlphaTested`] when the frame has alpha tests.
#[inline(always)]
fn rasterize_tile_with<S: FragmentSink>(
    tris: &SetupTriangles,
    tile: usize,
    rect: [i32; 4],
    mut sink: S,
    alpha: Option<AlphaTests>,
) {
    match alpha {
        Some(tests) => rasterize_tile(tris, tile, rect, &mut AlphaTested { inner: sink, tests }),
        None => rasterize_tile(tris, tile, rect, &mut sink),
    }
}

/// The depth test without the early rejection.
#[cfg(test)]
struct NoEarlyReject<'a>(&'a mut TileScratch);

#[cfg(test)]
impl FragmentSink for NoEarlyReject<'_> {
    #[inline]
    fn early(&self, _: usize, _: f64) -> bool {
        true
    }
    #[inline]
    fn fragment(&mut self, i: usize, t: &Fragment<'_>, e: [i64; 3]) {
        self.0.fragment(i, t, e);
    }
}

/// Counts front and back coverings of each pixel of a tile (no depth test).
struct CountSink<'a, 'b> {
    rows: &'a mut Vec<&'b mut [[u32; 2]]>,
}

impl FragmentSink for CountSink<'_, '_> {
    #[inline]
    fn early(&self, _: usize, _: f64) -> bool {
        true
    }
    #[inline]
    fn fragment(&mut self, i: usize, t: &Fragment<'_>, _: [i64; 3]) {
        let (row, col) = (i / TILE_SIZE as usize, i % TILE_SIZE as usize);
        self.rows[row][col][(t.flags & GBUF_BACK_FACE != 0) as usize] += 1;
    }
}

/// Walk the bin of the tile `rect` in order and hand every covered pixel centre to
/// `sink` (first `early`, then, if that passes, `fragment`).
#[inline]
fn rasterize_tile<S: FragmentSink>(tris: &SetupTriangles, tile: usize, rect: [i32; 4], sink: &mut S) {
    for (c, chunk) in tris.chunks.iter().enumerate() {
        let bin = chunk.bin(tile);
        for (k, &index) in bin.iter().enumerate() {
            // The bin's triangles are scattered over the chunk: fetch ahead.
            if let Some(&ahead) = bin.get(k + PREFETCH_AHEAD) {
                prefetch(&chunk.tris[ahead as usize]);
            }
            let t = &chunk.tris[index as usize];
            let reference = ((c as u32) << CHUNK_INDEX_BITS) | index as u32;
            rasterize_triangle(t, reference, rect, sink);
        }
    }
}

/// How many bin items ahead [`rasterize_tile`] prefetches the triangle record.
const PREFETCH_AHEAD: usize = 4;

/// Ask for the cache lines of `value` (a hint; no effect on results): one per 64 bytes of
/// its size, from its first byte.
#[inline(always)]
fn prefetch<T>(value: &T) {
    prefetch_run(value, std::mem::size_of::<T>().div_ceil(64));
}

/// Ask for every cache line `value` touches (a hint; no effect on results): its first
/// byte's, then one a line on up to its last byte's, so that a record straddling two lines
/// (half of the 48-byte `TriangleRecord`s) comes whole, where [`prefetch`] asks for one
/// line per 64 bytes of size from its start.
#[inline(always)]
pub(crate) fn prefetch_lines<T>(value: &T) {
    let offset = value as *const T as usize % 64;
    prefetch_run(value, (offset + std::mem::size_of::<T>()).div_ceil(64));
}

/// Prefetch `lines` cache lines, 64 bytes apart, from `value`'s first byte.
#[inline(always)]
fn prefetch_run<T>(value: &T, lines: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = value as *const T as *const i8;
        for line in 0..lines {
            // SAFETY: a prefetch never faults; the address lies within `value` or on a line
            // it touches.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * line)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (value, lines);
}

/// Hand the covered pixel centres of one triangle inside tile `rect` to `sink`.
#[inline]
fn rasterize_triangle<S: FragmentSink>(t: &RasterTriangle, reference: u32, rect: [i32; 4], sink: &mut S) {
    let x0 = t.bbox[0].max(rect[0]);
    let y0 = t.bbox[1].max(rect[1]);
    let x1 = t.bbox[2].min(rect[2]);
    let y1 = t.bbox[3].min(rect[3]);
    if x0 > x1 || y0 > y1 {
        return;
    }
    let s = EdgeStepper::new(t, x0 as i64, y0 as i64);
    let z64 = t.z.map(f64::from);
    let dz = s.step_x[0] as f64 * z64[0] + s.step_x[1] as f64 * z64[1] + s.step_x[2] as f64 * z64[2];
    let frag = Fragment { tri: t, reference, stepper: s, z64, inv_area: 1.0 / t.area2 as f64, dz };
    let n = (x1 - x0 + 1) as i64;
    // Narrow boxes test every pixel (cheaper than the walks' divisions).
    let narrow = n <= S::NARROW_BOX_WIDTH;
    let multi_row = y1 > y0;
    let mut walks = (!narrow).then(|| {
        [
            EdgeWalk::new(s.start[0], s.step_x[0], s.step_y[0], multi_row),
            EdgeWalk::new(s.start[1], s.step_x[1], s.step_y[1], multi_row),
            EdgeWalk::new(s.start[2], s.step_x[2], s.step_y[2], multi_row),
        ]
    });
    let mut row = s.start;
    for y in y0..=y1 {
        // The covered pixels of a row of a convex shape are one run [lo, hi].
        let (mut lo, mut hi) = (0i64, n - 1);
        if let Some(walks) = &walks {
            for walk in walks {
                walk.clip_run(&mut lo, &mut hi);
            }
        }
        if lo <= hi {
            let span = Span {
                base: (y - rect[1]) as usize * TILE_SIZE as usize + (x0 - rect[0]) as usize + lo as usize,
                len: (hi - lo + 1) as usize,
                e: [row[0] + lo * s.step_x[0], row[1] + lo * s.step_x[1], row[2] + lo * s.step_x[2]],
                covered: !narrow,
            };
            sink.span(&span, &frag);
        }
        if let Some(walks) = &mut walks {
            for walk in walks {
                walk.step();
            }
        }
        row[0] += s.step_y[0];
        row[1] += s.step_y[1];
        row[2] += s.step_y[2];
    }
}

/// Depth-test state of one tile. The winners' edge values are not kept: the resolve
/// steps them again along each run of one winner (exact integers, the same values).
struct TileScratch {
    depth: Box<[f32; TILE_PIXELS]>,
    winner: Box<[u32; TILE_PIXELS]>,
}

/// Index into a tile buffer: local pixels are below `TILE_PIXELS` by construction;
/// the mask (a no-op then) lets the compiler drop the bounds checks.
#[inline]
fn tile_index(i: usize) -> usize {
    debug_assert!(i < TILE_PIXELS);
    i & (TILE_PIXELS - 1)
}

impl TileScratch {
    fn new() -> TileScratch {
        TileScratch { depth: Box::new([DEPTH_CLEAR; TILE_PIXELS]), winner: Box::new([NO_WINNER; TILE_PIXELS]) }
    }
    fn clear(&mut self) {
        self.depth.fill(DEPTH_CLEAR);
        self.winner.fill(NO_WINNER);
    }
}

/// Writes the texels of a run of pixels that one triangle won.
trait TexelRun {
    /// `out[k]` from pixel `k` of the run: exact (unbiased) edge values `e + k * step`
    /// and stored depth-test value `depth[k]` (`depth.len() == out.len()`).
    fn run(t: &RasterTriangle, e: [i64; 3], step: [i64; 3], depth: &[f32], out: &mut [GBufferTexel]);
}

/// [`TexelRun`] texel by texel.
struct ScalarTexels;

impl TexelRun for ScalarTexels {
    #[inline(always)]
    fn run(t: &RasterTriangle, mut e: [i64; 3], step: [i64; 3], depth: &[f32], out: &mut [GBufferTexel]) {
        for (texel, &stored) in out.iter_mut().zip(depth) {
            let [u, v] = t.barycentrics(e);
            *texel = t.texel(u, v, stored);
            e[0] += step[0];
            e[1] += step[1];
            e[2] += step[2];
        }
    }
}

impl RasterTriangle {
    /// The G-buffer barycentrics `(u, v)` of the source triangle at a pixel centre with
    /// exact (unbiased) edge values `e`.
    #[inline(always)]
    fn barycentrics(&self, e: [i64; 3]) -> [f32; 2] {
        if self.corners == NOT_CORNERS {
            barycentrics_in_original(perspective_barycentrics(e, self.w), self.bary)
        } else {
            perspective_barycentrics_of_corners(e, self.w, self.corners[0] as usize, self.corners[1] as usize)
        }
    }

    /// The G-buffer texel of a pixel this triangle won, from its barycentrics and the
    /// depth test's stored value.
    #[inline(always)]
    fn texel(&self, bary_u: f32, bary_v: f32, stored: f32) -> GBufferTexel {
        // The depth test stored an interior side's depth INTERIOR_DEPTH_BIAS_ULPS steps
        // further; a winner's stored value is below 1.0, so the bias was not clamped
        // and stepping back gives the interpolated depth exactly.
        let depth = if self.interior { f32::from_bits(stored.to_bits() - INTERIOR_DEPTH_BIAS_ULPS) } else { stored };
        let texel =
            GBufferTexel { bary_u, bary_v, depth, triangle: self.triangle, object: self.object, flags: self.flags };
        if cfg!(debug_assertions) {
            texel.validate().expect("visibility_raster texel invariants");
        }
        texel
    }
}

/// Write every texel of one tile from its depth-test state, run of one winner by run;
/// returns the hit count.
#[inline(always)]
fn resolve_tile<R: TexelRun>(
    tris: &SetupTriangles,
    scratch: &TileScratch,
    rect: [i32; 4],
    mut rows: Vec<&mut [GBufferTexel]>,
    resolve: Resolve,
) -> usize {
    let mut covered = 0;
    for (ly, row) in rows.iter_mut().enumerate() {
        let first = ly * TILE_SIZE as usize;
        let winners = &scratch.winner[first..first + row.len()];
        let mut lx = 0;
        while lx < row.len() {
            let winner = winners[lx];
            let end = lx + winners[lx..].iter().position(|&w| w != winner).unwrap_or(row.len() - lx);
            if winner == NO_WINNER {
                if resolve == Resolve::Every {
                    row[lx..end].fill(GBufferTexel::MISS);
                }
            } else {
                let t = tris.get(winner);
                let (e, step) = t.edge_values(rect[0] as i64 + lx as i64, rect[1] as i64 + ly as i64);
                R::run(t, e, step, &scratch.depth[first + lx..first + end], &mut row[lx..end]);
                covered += end - lx;
            }
            lx = end;
        }
    }
    debug_assert_eq!(rows.len() as i32, rect[3] - rect[1] + 1);
    if resolve == Resolve::Every {
        covered
    } else {
        0
    }
}

/// Split a row-major image into per-tile lists of row slices (tile-major order), so
/// tiles can be written in parallel without copying.
fn tile_slices<'a, T>(buf: &'a mut [T], width: usize, frame: &Frame) -> Vec<Vec<&'a mut [T]>> {
    tile_rows(buf, width, (frame.width as usize, frame.height as usize), TILE_SIZE as usize)
}

/// The `tile`-square tiles of the top-left `area` (width, height) of a row-major image
/// `width` pixels wide, as lists of row slices, row-major over the tiles (partial tiles at
/// the right and bottom edges): tile `(tx, ty)` is entry `ty * area.0.div_ceil(tile) + tx`.
pub(crate) fn tile_rows<T>(buf: &mut [T], width: usize, area: (usize, usize), tile: usize) -> Vec<Vec<&mut [T]>> {
    let tiles_x = area.0.div_ceil(tile);
    let mut tiles: Vec<Vec<&mut [T]>> =
        (0..tiles_x * area.1.div_ceil(tile)).map(|_| Vec::with_capacity(tile)).collect();
    if width == 0 {
        return tiles;
    }
    for (y, row) in buf.chunks_mut(width).enumerate().take(area.1) {
        for (tx, seg) in row[..area.0].chunks_mut(tile).enumerate() {
            tiles[y / tile * tiles_x + tx].push(seg);
        }
    }
    tiles
}

#[cfg(test)]
mod tests {
    use super::*;
    use hyrt_core::glam::{Mat4, Quat, Vec3};
    use hyrt_core::scene::{AlphaMode, Camera, Material, Mesh, Object, ObjectSource, RenderMode, Scene};
    use proptest::prelude::*;

    fn bits(out: &VisibilityOutput) -> Vec<[u32; 6]> {
        out.gbuffer.iter().map(|t| t.to_bits()).collect()
    }

    /// A camera at `eye` looking at `(0, 0, -3)`.
    fn camera_towards_z(eye: Vec3, fov_y_deg: f32, near: f32, far: f32) -> Camera {
        Camera { eye, target: Vec3::new(0.0, 0.0, -3.0), up: Vec3::Y, fov_y_deg, near, far }
    }

    /// Many overlapping objects in arbitrary depth order, some crossing the near
    /// plane: lots of fragments the early rejection skips.
    fn cluttered_scene() -> Scene {
        let mut s = Scene::default();
        for k in 0..24u32 {
            let f = k as f32;
            let mesh = match k % 3 {
                0 => Mesh::uv_sphere("s", 12, 6),
                1 => Mesh::cube("c"),
                _ => Mesh::torus("t", 1.0, 0.3, 12, 6),
            };
            s.meshes.push(mesh);
            s.materials.push(Material::grey());
            s.objects.push(Object {
                id: k,
                name: format!("o{k}"),
                mesh: k as usize,
                transform: Mat4::from_translation(Vec3::new((f * 1.7).sin() * 2.0, (f * 0.9).cos(), -f * 0.4 + 3.0))
                    * Mat4::from_quat(Quat::from_rotation_y(f)),
                material: k as usize,
                render_mode: if k % 4 == 0 { RenderMode::RayTraced } else { RenderMode::Raster },
                source: ObjectSource::default(),
            });
        }
        s.camera = Some(camera_towards_z(Vec3::new(0.3, 0.5, 5.0), 70.0, 0.3, 40.0));
        s
    }

    /// Every tile kernel this CPU can run.
    fn kernels() -> Vec<TileKernel> {
        let mut k = vec![TileKernel::Scalar, TileKernel::ScalarNoEarlyReject];
        #[cfg(target_arch = "x86_64")]
        if SimdLevel::Avx2.is_available() {
            k.push(TileKernel::Avx2);
        }
        #[cfg(target_arch = "x86_64")]
        if SimdLevel::Avx512.is_available() {
            k.push(TileKernel::Avx512);
        }
        k
    }

    /// The G-buffer of every kernel, checked bit for bit against the first's.
    fn assert_kernels_agree(g: &WorldGeometry, cam: &CameraRecord) -> usize {
        let run = |kernel| {
            let mut gbuffer = Vec::new();
            let covered_pixels = raster_frame(g, cam, kernel, &mut gbuffer);
            VisibilityOutput { gbuffer, width: cam.width, height: cam.height, covered_pixels }
        };
        let kernels = kernels();
        let first = run(kernels[0]);
        for &k in &kernels[1..] {
            let other = run(k);
            assert_eq!(first.covered_pixels, other.covered_pixels, "{k:?}");
            assert!(bits(&first) == bits(&other), "{k:?} differs from {:?}", kernels[0]);
        }
        first.covered_pixels
    }

    /// Rasterizing in batches (here one setup chunk each) and reading objects by reference
    /// change no bit, with every kernel: the cluttered scene plus fine spheres, some
    /// sharing a mesh, several chunks in all, alpha tests included.
    #[test]
    fn batches_and_objects_by_reference_give_the_same_bits() {
        let mut scene = cluttered_scene();
        let sphere = Mesh::uv_sphere("fine", 48, 24);
        for k in 0..4 {
            let f = k as f32;
            let mut material = Material::grey();
            if k == 1 {
                material.alpha_mode = AlphaMode::Mask { cutoff: 0.5 };
                material.base_alpha = 0.7;
            }
            scene.add_object(
                sphere.clone(),
                material,
                Mat4::from_translation(Vec3::new(f - 1.5, 0.2 * f, -1.0 - f)) * Mat4::from_scale(Vec3::splat(0.6)),
                RenderMode::Raster,
            );
        }
        let stored = WorldGeometry::build(&scene);
        assert!(stored.triangles.len() > 3 * SETUP_CHUNK, "several chunks");
        let by_reference: Vec<bool> = (0..scene.objects.len()).map(|o| o % 3 != 1).collect();
        let referenced = WorldGeometry::build_placed(&scene, &by_reference);
        assert!(referenced.triangles.has_references());
        for (w, h) in [(160, 90), (67, 131)] {
            let cam = CameraRecord::new(&scene.camera.unwrap(), w, h);
            for kernel in kernels() {
                let mut one = Vec::new();
                let covered = raster_frame(&stored, &cam, kernel, &mut one);
                assert!(covered > 0);
                for (g, batch) in [(&stored, 1), (&referenced, 1), (&referenced, BATCH_CHUNKS), (&stored, 2)] {
                    let mut out = Vec::new();
                    let c = raster_frame_in_batches(g, &cam, kernel, &mut out, batch);
                    assert_eq!(c, covered, "{kernel:?}, batches of {batch}");
                    assert!(
                        out.iter().map(|t| t.to_bits()).eq(one.iter().map(|t| t.to_bits())),
                        "{kernel:?}, batches of {batch}, by reference: {}",
                        g.triangles.has_references()
                    );
                }
            }
        }
    }

    /// A hook that copies each tile's texels into its rows of an image and counts its hits.
    struct CopyTexels<'a>(std::marker::PhantomData<&'a ()>);

    impl<'a> TileHook for CopyTexels<'a> {
        type Out = Vec<&'a mut [GBufferTexel]>;
        type Scratch = ();
        type Counts = usize;
        fn scratch(&self) {}
        fn tile(&self, _: &mut (), t: TileTexels<'_>, rows: Self::Out) -> usize {
            assert_eq!((rows.len(), rows[0].len()), (t.size.1, t.size.0));
            for (ly, row) in rows.into_iter().enumerate() {
                row.copy_from_slice(&t.texels[ly * TILE_SIZE as usize..][..t.size.0]);
            }
            (0..t.size.1)
                .map(|ly| (0..t.size.0).filter(|&lx| t.texels[ly * TILE_SIZE as usize + lx].is_hit()).count())
                .sum()
        }
        fn add(a: usize, b: usize) -> usize {
            a + b
        }
    }

    /// The per-tile hook sees every tile's final texels, once, with and without a
    /// whole-image G-buffer, in one batch and in several, with every kernel; the G-buffer
    /// it keeps is the plain raster's.
    #[test]
    fn the_tile_hook_sees_the_final_texels_of_every_tile() {
        let mut scene = cluttered_scene();
        let sphere = Mesh::uv_sphere("fine", 48, 24);
        scene.add_object(sphere, Material::grey(), Mat4::from_scale(Vec3::splat(0.8)), RenderMode::Raster);
        let g = WorldGeometry::build(&scene);
        assert!(g.triangles.len() > 2 * SETUP_CHUNK, "several chunks");
        for (w, h) in [(160, 90), (67, 131)] {
            let cam = CameraRecord::new(&scene.camera.unwrap(), w, h);
            for kernel in kernels() {
                let mut want = Vec::new();
                let covered = raster_frame(&g, &cam, kernel, &mut want);
                for batch in [1, 2, BATCH_CHUNKS] {
                    for keep in [true, false] {
                        let mut seen = vec![GBufferTexel { triangle: 7, ..GBufferTexel::MISS }; want.len()];
                        let outs = tile_rows(&mut seen, w as usize, raster_area(&cam), TILE_SIZE as usize);
                        let mut kept = Vec::new();
                        let gbuffer = keep.then_some(&mut kept);
                        let hook = CopyTexels(std::marker::PhantomData);
                        let r = raster_tiles(&g, &cam, kernel, gbuffer, Some((&hook, outs)), batch);
                        let what = format!("{w}x{h}, {kernel:?}, batches of {batch}, G-buffer kept: {keep}");
                        assert_eq!((r.covered, r.counts), (covered, covered), "{what}");
                        assert!(seen.iter().map(|t| t.to_bits()).eq(want.iter().map(|t| t.to_bits())), "{what}");
                        match keep {
                            true => assert!(kept.iter().map(|t| t.to_bits()).eq(want.iter().map(|t| t.to_bits()))),
                            false => assert!(kept.is_empty(), "{what}"),
                        }
                    }
                }
            }
        }
    }

    /// The early depth rejection and the SIMD kernels change no bit.
    #[test]
    fn tile_kernels_give_the_same_bits() {
        for scene in [cluttered_scene(), Scene::default_scene()] {
            let g = WorldGeometry::build(&scene);
            for (w, h) in [(160, 90), (67, 131)] {
                let cam = CameraRecord::new(&scene.camera.unwrap(), w, h);
                assert!(assert_kernels_agree(&g, &cam) > 0);
            }
        }
    }

    /// Triangles from a few pixels to far into the guard band (a ground plane to the horizon
    /// under an eye near it, near plane 1 mm: clipped, its vertices up to 2^20 pixels out,
    /// edge values beyond 2^51) amid the cluttered scene: every kernel gives the same bits,
    /// and the AVX2 kernel's spans and runs take each of its conversions (i32 lanes, i64
    /// lanes through f64, the scalar code).
    #[test]
    fn tile_kernels_agree_on_huge_triangles() {
        let mut scene = cluttered_scene();
        let ground = Mat4::from_translation(Vec3::new(0.0, -0.6, 0.0)) * Mat4::from_scale(Vec3::splat(2.0e4));
        scene.add_object(Mesh::grid("ground", 2), Material::grey(), ground, RenderMode::Raster);
        let wall = Mat4::from_translation(Vec3::new(0.0, 0.0, -6.0)) * Mat4::from_scale(Vec3::new(8.0, 3.0, 1.0));
        scene.add_object(Mesh::uv_quad("wall"), Material::grey(), wall, RenderMode::Raster);
        scene.camera = Some(camera_towards_z(Vec3::new(0.3, 0.5, 5.0), 70.0, 0.001, 1.0e5));
        let g = WorldGeometry::build(&scene);
        for (w, h) in [(160, 90), (67, 131), (640, 360)] {
            let cam = CameraRecord::new(&scene.camera.unwrap(), w, h);
            assert!(assert_kernels_agree(&g, &cam) > 0);
        }
        #[cfg(target_arch = "x86_64")]
        if SimdLevel::Avx2.is_available() {
            // One thread, so that this thread's counts are this frame's.
            let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
            let taken = pool.install(|| {
                let before = avx2::tests::conversions_taken();
                let cam = CameraRecord::new(&scene.camera.unwrap(), 160, 90);
                raster_frame(&g, &cam, TileKernel::Avx2, &mut Vec::new());
                let after = avx2::tests::conversions_taken();
                [0, 1, 2].map(|c| after[c] - before[c])
            });
            assert!(taken.iter().all(|&n| n > 0), "spans and runs by conversion: {taken:?}");
        }
    }

    /// With alpha-tested materials (every other object masked, its alpha a vertex colour
    /// that crosses the cutoff inside triangles): every kernel cuts the same holes, and
    /// there are holes.
    #[test]
    fn tile_kernels_cut_the_same_holes() {
        let plain = cluttered_scene();
        let mut masked = plain.clone();
        for (k, m) in masked.meshes.iter_mut().enumerate().filter(|(k, _)| k % 2 == 0) {
            let alpha = |i: usize| ((i * 7 + k) % 5) as f32 / 4.0;
            m.attributes.colors = Some((0..m.positions.len()).map(|i| [1.0, 1.0, 1.0, alpha(i)]).collect());
        }
        for mat in masked.materials.iter_mut().step_by(2) {
            mat.alpha_mode = AlphaMode::Mask { cutoff: 0.5 };
        }
        let (g, g_plain) = (WorldGeometry::build(&masked), WorldGeometry::build(&plain));
        assert!(g.surface.alpha_tested());
        for (w, h) in [(160, 90), (67, 131)] {
            let cam = CameraRecord::new(&masked.camera.unwrap(), w, h);
            assert_kernels_agree(&g, &cam);
            let (holes, full) = (visibility_raster(&g, &cam).gbuffer, visibility_raster(&g_plain, &cam).gbuffer);
            let changed = holes.iter().zip(&full).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
            assert!(changed > (w * h / 20) as usize, "{changed} pixels changed at {w}x{h}");
        }
    }

    /// A soup of random triangles: any size, orientation and depth, some crossing the
    /// near plane or behind the eye.
    fn triangle_soup(seed: u64, count: usize, scale: f32) -> Scene {
        let mut state = seed | 1;
        let mut next = move || {
            // xorshift64*: deterministic, no dependency.
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            (state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut s = Scene::default();
        let mut mesh = Mesh { name: "soup".into(), ..Default::default() };
        for _ in 0..count {
            let centre = Vec3::new(next() * 6.0 - 3.0, next() * 4.0 - 2.0, next() * 8.0 - 6.0);
            let base = mesh.positions.len() as u32;
            for _ in 0..3 {
                let offset = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * scale;
                mesh.positions.push(centre + offset);
            }
            mesh.indices.push([base, base + 1, base + 2]);
        }
        // The soup twice (exact depth ties everywhere: the earlier triangle keeps the
        // pixel), and a closed mesh.
        s.add_object(mesh.clone(), Material::grey(), Mat4::IDENTITY, RenderMode::Raster);
        s.add_object(mesh, Material::grey(), Mat4::IDENTITY, RenderMode::RayTraced);
        s.add_object(Mesh::cube("c"), Material::grey(), Mat4::IDENTITY, RenderMode::RayTraced);
        s.camera = Some(camera_towards_z(Vec3::new(0.0, 0.0, 2.0), 60.0, 0.1, 20.0));
        s
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn tile_kernels_agree_on_triangle_soups(
            seed in any::<u64>(),
            count in 1usize..300,
            scale in prop::sample::select(vec![0.01f32, 0.2, 1.0, 8.0]),
            w in 1u32..200,
            h in 1u32..140,
        ) {
            let scene = triangle_soup(seed, count, scale);
            let g = WorldGeometry::build(&scene);
            let cam = CameraRecord::new(&scene.camera.unwrap(), w, h);
            assert_kernels_agree(&g, &cam);
        }
    }

    /// The run of one edge over `n` pixels for `rows` rows, by brute force.
    fn brute_runs(e: i64, dx: i64, dy: i64, n: i64, rows: i64) -> Vec<Option<(i64, i64)>> {
        (0..rows)
            .map(|r| {
                let ks: Vec<i64> = (0..n).filter(|k| e + r * dy + k * dx >= 0).collect();
                ks.first().map(|lo| (*lo, *ks.last().unwrap()))
            })
            .collect()
    }

    proptest! {
        #[test]
        fn edge_walk_matches_brute_force(
            e in -100_000i64..100_000,
            dx in -3000i64..3000,
            dy in -3000i64..3000,
            n in 1i64..65,
            rows in 1i64..65,
        ) {
            let mut walk = EdgeWalk::new(e, dx, dy, rows > 1);
            let expect = brute_runs(e, dx, dy, n, rows);
            for row in expect {
                let (mut lo, mut hi) = (0, n - 1);
                walk.clip_run(&mut lo, &mut hi);
                let got = (lo <= hi).then_some((lo, hi));
                prop_assert_eq!(got, row);
                walk.step();
            }
        }
    }

    /// The setup of `tris` in lanes at every level this CPU has equals the scalar setup
    /// (`setup_triangle`, one triangle at a time), triangle for triangle and bit for bit
    /// (the `Debug` form shows every field, `-0.0` and `0.0` apart).
    fn assert_setups_agree(tris: &[TriangleRecord], camera: &CameraRecord) {
        assert_setups_agree_culling(tris, camera, Vec::new());
    }

    /// [`assert_setups_agree`] in a frame that drops the interiors of the objects whose
    /// bits are set in `interior_culls` (`culls_interior`).
    fn assert_setups_agree_culling(tris: &[TriangleRecord], camera: &CameraRecord, interior_culls: Vec<u32>) {
        let frame = Frame { interior_culls, ..Frame::new(camera) };
        let mut expect = Vec::new();
        for t in tris {
            setup_triangle(t, camera, &frame, &mut expect);
        }
        let expect = format!("{expect:?}");
        for level in SimdLevel::available() {
            let mut out = Vec::new();
            setup::setup_chunk(tris, camera, &frame, level, &mut out);
            assert_eq!(format!("{out:?}"), expect, "setup in lanes at {level:?}");
        }
    }

    /// A world coordinate: mostly around the camera, some far out, some special.
    fn coordinate() -> impl Strategy<Value = f32> {
        prop_oneof![
            8 => -4.0f32..4.0,
            1 => -1.0e6f32..1.0e6,
            1 => prop::sample::select(vec![0.0, -0.0, 2.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e30, -3e38, 1e-30]),
        ]
    }

    /// A triangle around a coordinate, from a hundred-thousandth of a unit to 10^4 units
    /// across: most of the small ones fall between pixel centres.
    fn triangle() -> impl Strategy<Value = TriangleRecord> {
        (
            prop::array::uniform3(coordinate()),
            prop::array::uniform3(-1.0f32..1.0),
            prop::array::uniform3(-1.0f32..1.0),
            prop::sample::select(vec![1e-5f32, 1e-3, 1e-2, 0.3, 3.0, 1e4]),
            any::<bool>(),
        )
            .prop_map(|(c, a, b, size, traced)| TriangleRecord {
                v0: c,
                object: 0,
                v1: [c[0] + a[0] * size, c[1] + a[1] * size, c[2] + a[2] * size],
                triangle: 0,
                v2: [c[0] + b[0] * size, c[1] + b[1] * size, c[2] + b[2] * size],
                flags: if traced { TRI_RAY_TRACED } else { 0 },
            })
    }

    proptest! {
        #[test]
        fn setup_in_lanes_equals_the_scalar_setup(
            tris in prop::collection::vec(triangle(), 1..120),
            eye in prop::array::uniform3(-2.0f32..2.0),
            fov in 10.0f32..150.0,
            near in prop::sample::select(vec![1e-3f32, 0.1, 1.0]),
            w in 1u32..400,
            h in 1u32..300,
        ) {
            let camera = Camera { eye: Vec3::from(eye), target: Vec3::new(0.0, 0.0, -3.0), up: Vec3::Y, fov_y_deg: fov, near, far: 100.0 };
            assert_setups_agree(&tris, &CameraRecord::new(&camera, w, h));
        }

        /// The same with objects whose interiors are dropped: triangles of four objects,
        /// some wound inward (`TRI_INWARD`), in a frame that culls the interiors of the
        /// objects in `culls` (the lanes drop those triangles before the scalar code does).
        #[test]
        fn setup_in_lanes_equals_the_scalar_setup_culling_interiors(
            tris in prop::collection::vec((triangle(), 0u32..4, any::<bool>()), 1..120),
            eye in prop::array::uniform3(-2.0f32..2.0),
            fov in 10.0f32..150.0,
            w in 1u32..400,
            h in 1u32..300,
            culls in 0u32..16,
        ) {
            let tris: Vec<TriangleRecord> = tris
                .into_iter()
                .map(|(t, object, inward)| TriangleRecord { object, flags: t.flags | if inward { TRI_INWARD } else { 0 }, ..t })
                .collect();
            let camera = Camera { eye: Vec3::from(eye), target: Vec3::new(0.0, 0.0, -3.0), up: Vec3::Y, fov_y_deg: fov, near: 0.1, far: 100.0 };
            assert_setups_agree_culling(&tris, &CameraRecord::new(&camera, w, h), vec![culls]);
        }
    }

    /// The setup in lanes on the cases the lanes decide themselves: a fine mesh far away
    /// (triangles between pixel centres), meshes crossing the near plane and the image's
    /// sides, vertices far into the guard band (snapped coordinates past 2^23) and beyond
    /// it, a vertex at the eye, non-finite vertices; in groups of eight and a partial one.
    #[test]
    fn setup_in_lanes_equals_the_scalar_setup_on_hard_cases() {
        let mut scene = Scene::default();
        let fine = Mesh::uv_sphere("fine", 96, 48);
        for (k, (x, z, scale)) in
            [(0.0, -40.0, 1.0), (0.5, 1.5, 1.0), (-3.0, -1.0, 2.0), (0.0, -3.0, 0.05)].into_iter().enumerate()
        {
            let mode = if k % 2 == 0 { RenderMode::Raster } else { RenderMode::RayTraced };
            let place = Mat4::from_translation(Vec3::new(x, 0.0, z)) * Mat4::from_scale(Vec3::splat(scale));
            scene.add_object(fine.clone(), Material::grey(), place, mode);
        }
        let mut tris: Vec<TriangleRecord> = WorldGeometry::build(&scene).triangles.as_slice().unwrap().to_vec();
        let eye = Vec3::new(0.0, 0.0, 2.0);
        let t =
            |v0: [f32; 3], v1: [f32; 3], v2: [f32; 3]| TriangleRecord { v0, object: 0, v1, triangle: 0, v2, flags: 0 };
        tris.extend([
            // A vertex at the eye; one behind it.
            t(eye.into(), [0.1, 0.0, 0.0], [0.0, 0.1, 0.0]),
            t([0.0, 0.0, 3.0], [0.3, 0.0, -1.0], [0.0, 0.3, -1.0]),
            // Far into the guard band (window x about 2^17 pixels: snapped past 2^23), and
            // beyond it.
            t([0.0, 0.0, -1.0], [200.0, 0.0, -1.0], [0.0, 0.2, -1.0]),
            t([0.0, 0.0, -1.0], [2.0e6, 0.0, -1.0], [0.0, 0.2, -1.0]),
            t([-300.0, -1.0, -1.0], [300.0, -1.0, -1.0], [0.0, 400.0, -1.0]),
            // Non-finite vertices.
            t([f32::NAN, 0.0, -1.0], [0.1, 0.0, -1.0], [0.0, 0.1, -1.0]),
            t([0.0, 0.0, -1.0], [f32::INFINITY, 0.0, -1.0], [0.0, 0.1, -1.0]),
            t([0.0, 0.0, -1.0], [0.1, 0.0, -1.0], [0.0, f32::NEG_INFINITY, -1.0]),
            // Zero area, and a point.
            t([0.0, 0.0, -1.0], [0.1, 0.1, -1.0], [0.2, 0.2, -1.0]),
            t([0.0, 0.0, -1.0], [0.0, 0.0, -1.0], [0.0, 0.0, -1.0]),
        ]);
        let camera = camera_towards_z(eye, 60.0, 0.1, 50.0);
        for (w, h) in [(1280, 720), (67, 131), (1, 1)] {
            let cam = CameraRecord::new(&camera, w, h);
            assert_setups_agree(&tris, &cam);
            assert_setups_agree(&tris[tris.len() - 13..], &cam);
        }
    }
}
