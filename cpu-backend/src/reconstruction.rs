//! Stage `reconstruction`: G-buffer + triangle table -> world-space hit points
//! and normals (paper eq. 1), one [`SurfaceRecord`] per pixel.
//!
//! Inputs: the G-buffer, the world geometry, the camera eye (and, for re-intersected
//! barycentrics, the camera). Output: the surface buffer. A per-pixel map of
//! [`hyrt_core::kernels::reconstruction::reconstruct_texel`] (or its re-intersected form),
//! which both executors run a `TILE_WIDTH` x `TILE_HEIGHT` block of eight pixels at a
//! time (`blocks`: `Reconstruct::block`, the kernel in eight SIMD lanes, bit for bit
//! the scalar kernel [`Reconstruct::pixel`]): the staged frame over bands of whole rows,
//! the fused frame (`crate::fused`) over each tile.

use glam::Vec3;
use hyrt_core::formats::{CameraRecord, GBufferTexel, RayRecord, SurfaceRecord, GBUF_BACK_FACE};
use hyrt_core::frame::PrimaryBarycentrics;
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::camera::primary_ray;
use hyrt_core::kernels::reconstruction::{
    primary_normal_mapped, reconstruct_texel_cached, reconstruct_texel_reintersected_cached, TriangleSetup,
};
use hyrt_core::kernels::texture::Materials;
use rayon::prelude::*;

use crate::lanes::{avx2_entry_points, dispatch, mask_lanes, Lanes, LANES};
use crate::traversal::intersect_each;
use crate::traversal::tiles::{TILE_HEIGHT, TILE_WIDTH};
use crate::traversal::SimdLevel;

pub(crate) mod lanes;

/// Pixels of the staged stage's parallel tasks (rounded to whole bands of
/// [`TILE_HEIGHT`] rows): enough to amortise a task, small enough to balance two to a few
/// dozen threads on a 1280x720 frame.
const BAND_PIXELS: usize = 8192;

/// The stage: reconstruct every pixel in parallel.
pub fn reconstruction(gbuffer: &[GBufferTexel], geometry: &WorldGeometry, eye: Vec3) -> Vec<SurfaceRecord> {
    let mut out = Vec::new();
    reconstruction_into(gbuffer, geometry, eye, &mut out);
    out
}

/// [`reconstruction`] into a caller-owned buffer, reusing its allocation. The raster's
/// barycentrics do not depend on where a pixel lies, so the texels are taken as an image
/// `TILE_WIDTH` pixels wide: a block is eight consecutive texels.
pub fn reconstruction_into(
    gbuffer: &[GBufferTexel],
    geometry: &WorldGeometry,
    eye: Vec3,
    out: &mut Vec<SurfaceRecord>,
) {
    image_into(&Reconstruct::Raster(eye), gbuffer, geometry, TILE_WIDTH as usize, out);
}

/// [`reconstruction_into`] with re-intersected barycentrics
/// ([`hyrt_core::frame::PrimaryBarycentrics::Reintersected`]): every hit texel's camera
/// ray ([`primary_ray`]) meets its triangle by the watertight kernel.
pub fn reconstruction_reintersected_into(
    gbuffer: &[GBufferTexel],
    geometry: &WorldGeometry,
    camera: &CameraRecord,
    out: &mut Vec<SurfaceRecord>,
) {
    image_into(&Reconstruct::Reintersected(camera), gbuffer, geometry, camera.width as usize, out);
}

/// `reconstruct` over the texels of an image `width` pixels wide, bands of rows in
/// parallel, each [`blocks`] at this CPU's SIMD level; a last, partial row (only where the
/// texels are not a whole image: [`reconstruction_into`]'s form) pixel by pixel.
fn image_into(
    reconstruct: &Reconstruct,
    gbuffer: &[GBufferTexel],
    geometry: &WorldGeometry,
    width: usize,
    out: &mut Vec<SurfaceRecord>,
) {
    // Every record is written below: resizing alone leaves a reused buffer untouched.
    out.resize(gbuffer.len(), SurfaceRecord::MISS);
    let level = SimdLevel::detect();
    let width = width.max(1);
    let band_rows = (BAND_PIXELS / width).max(1).next_multiple_of(TILE_HEIGHT as usize);
    let band = band_rows * width;
    out.par_chunks_mut(band).zip(gbuffer.par_chunks(band)).enumerate().for_each_init(
        BlockSetups::default,
        |setups, (b, (out, texels))| {
            let rows = texels.len() / width;
            let whole = rows * width;
            let at = ((0, b * band_rows), (width, rows), width);
            blocks(level, reconstruct, geometry, &texels[..whole], at, setups, &mut out[..whole]);
            for (k, (s, t)) in out.iter_mut().zip(texels).enumerate().skip(whole) {
                let (x, y) = ((k % width) as u32, (b * band_rows + k / width) as u32);
                *s = reconstruct.pixel(t, geometry, x, y, &mut setups.scalar);
            }
        },
    );
    validate(out);
}

/// The stage's normal mapping, after the surfaces are made (a scene with normal maps
/// only: `materials.normal_mapped_any()`): each hit's surface through core's
/// [`primary_normal_mapped`] at its G-buffer texel, in parallel. The fused frame runs the
/// same kernel on each tile's surfaces.
pub fn normal_mapping_into(gbuffer: &[GBufferTexel], materials: &Materials, eye: Vec3, surfaces: &mut [SurfaceRecord]) {
    surfaces
        .par_iter_mut()
        .zip(gbuffer.par_iter())
        .with_min_len(1024)
        .for_each(|(s, t)| *s = primary_normal_mapped(t, s, eye, materials));
}

/// The stage's per-pixel kernel as every executor runs it: the staged functions above
/// over the whole image, the fused frame (`crate::fused`) over a tile's pixels.
#[derive(Clone, Copy, Debug)]
pub enum Reconstruct<'a> {
    /// The raster's barycentrics, seen from the eye ([`reconstruct_texel_cached`]).
    Raster(Vec3),
    /// Re-intersected barycentrics: the pixel's camera ray ([`primary_ray`]) against the
    /// texel's triangle ([`reconstruct_texel_reintersected_cached`]).
    Reintersected(&'a CameraRecord),
}

impl<'a> Reconstruct<'a> {
    /// The kernel `barycentrics` asks for, for a frame seen by `camera`.
    pub fn new(barycentrics: PrimaryBarycentrics, camera: &'a CameraRecord) -> Self {
        match barycentrics {
            PrimaryBarycentrics::Raster => Reconstruct::Raster(Vec3::from(camera.eye)),
            PrimaryBarycentrics::Reintersected => Reconstruct::Reintersected(camera),
        }
    }

    /// The surface of pixel `(x, y)` whose G-buffer texel is `t`; `cache` keeps the last
    /// triangle's setup for the next pixel (`None` to start).
    #[inline]
    pub fn pixel(
        &self,
        t: &GBufferTexel,
        geometry: &WorldGeometry,
        x: u32,
        y: u32,
        cache: &mut Option<TriangleSetup>,
    ) -> SurfaceRecord {
        match *self {
            Reconstruct::Raster(eye) => reconstruct_texel_cached(t, geometry, eye, cache),
            Reconstruct::Reintersected(_) if !t.is_hit() => SurfaceRecord::MISS,
            Reconstruct::Reintersected(camera) => {
                reconstruct_texel_reintersected_cached(t, geometry, &primary_ray(camera, x, y), cache)
            }
        }
    }
}

/// The triangle setups of a block of [`LANES`] pixels (`Reconstruct::block`), kept from
/// block to block: neighbouring blocks usually share triangles.
#[derive(Default)]
pub struct BlockSetups {
    /// The distinct setups of the current block.
    setups: Vec<TriangleSetup>,
    /// The last block's last setup.
    last: Option<TriangleSetup>,
    /// For the scalar kernel's lanes.
    scalar: Option<TriangleSetup>,
}

impl BlockSetups {
    /// The index in `self.setups` of global triangle `gi`'s setup, made or reused.
    #[inline]
    fn of(&mut self, geometry: &WorldGeometry, gi: usize) -> usize {
        if let Some(i) = self.setups.iter().rposition(|s| s.index() == gi) {
            return i;
        }
        let setup = match self.last {
            Some(s) if s.index() == gi => s,
            _ => TriangleSetup::new(geometry, gi),
        };
        self.setups.push(setup);
        self.setups.len() - 1
    }
}

impl Reconstruct<'_> {
    /// [`Reconstruct::pixel`] of [`LANES`] pixels at once, `texels[k]` at pixel `xy[k]`:
    /// the lanes kernel ([`lanes::surfaces_lanes`]) for what it covers, the scalar kernel
    /// for lanes facing the viewer. The same records, bit for bit.
    #[inline(always)]
    pub(crate) fn block<L: crate::lanes::Lanes>(
        &self,
        texels: [&GBufferTexel; LANES],
        xy: [(u32, u32); LANES],
        geometry: &WorldGeometry,
        cache: &mut BlockSetups,
    ) -> [SurfaceRecord; LANES] {
        cache.setups.clear();
        let (mut hit, mut back) = (0u32, 0u32);
        let (mut u, mut v, mut at) = ([0.0f32; LANES], [0.0f32; LANES], [0usize; LANES]);
        // The usual block inside one triangle: its setup once, every lane's index 0.
        let first = texels[0];
        let one = texels.iter().all(|t| t.is_hit() && (t.object, t.triangle) == (first.object, first.triangle));
        if one {
            cache.of(geometry, geometry.global_triangle(first.object, first.triangle));
        }
        for (k, t) in texels.iter().enumerate() {
            if !t.is_hit() {
                continue;
            }
            if !one {
                at[k] = cache.of(geometry, geometry.global_triangle(t.object, t.triangle));
            }
            (u[k], v[k]) = (t.bary_u, t.bary_v);
            hit |= 1 << k;
            back |= ((t.flags & GBUF_BACK_FACE != 0) as u32) << k;
        }
        let Some(&last) = cache.setups.last() else {
            return [SurfaceRecord::MISS; LANES];
        };
        cache.last = Some(last);
        let setups: [&TriangleSetup; LANES] = std::array::from_fn(|k| &cache.setups[at[k]]);
        if let Reconstruct::Reintersected(camera) = *self {
            reintersected_lanes::<L>(camera, texels, hit, xy, setups, &mut u, &mut v);
        }
        let lanes = lanes::surfaces_lanes::<L>(setups, hit, back, &u, &v);
        let mut out = lanes.records(setups);
        let mut facing = lanes.viewer_facing;
        while facing != 0 {
            let k = facing.trailing_zeros() as usize;
            facing &= facing - 1;
            out[k] = self.pixel(texels[k], geometry, xy[k].0, xy[k].1, &mut cache.scalar);
        }
        out
    }
}

/// The re-intersected barycentrics (core's `reintersected_barycentrics`) of the hit lanes `hit`
/// of a block, pixel `xy[k]` (texel `texels[k]`) on the triangle of `setups[k]`, into `(u, v)` (which hold the
/// raster's, kept where the camera ray misses the triangle): the camera rays against their
/// triangles in lanes ([`intersect_each`]), the scalar kernel where fewer than two can hit.
#[inline(always)]
fn reintersected_lanes<L: crate::lanes::Lanes>(
    camera: &CameraRecord,
    texels: [&GBufferTexel; LANES],
    hit: u32,
    xy: [(u32, u32); LANES],
    setups: [&TriangleSetup; LANES],
    u: &mut [f32; LANES],
    v: &mut [f32; LANES],
) {
    // `reintersected_barycentrics`: the camera ray over `0 < t < inf`. A miss lane's zero
    // direction (and empty interval) makes it a lane that hits nothing.
    let direction = primary_directions::<L>(camera, xy);
    // The records' first eight words by a transpose in registers ([`Lanes::transpose8`]):
    // the eye, `t_min` 0, the direction and `t_max` +inf in a hit lane, zeros in a miss's.
    // The rest of each record stays zero: the test reads no more.
    let h = mask_lanes::<L>(hit);
    let [ex, ey, ez] = camera.eye;
    let words = L::transpose8([
        L::and(h, L::splat(ex)),
        L::and(h, L::splat(ey)),
        L::and(h, L::splat(ez)),
        L::splat(0.0),
        L::and(h, direction[0]),
        L::and(h, direction[1]),
        L::and(h, direction[2]),
        L::and(h, L::splat(f32::INFINITY)),
    ]);
    let mut rays = [<RayRecord as bytemuck::Zeroable>::zeroed(); LANES];
    for (ray, words) in rays.iter_mut().zip(words) {
        bytemuck::cast_mut::<RayRecord, [[f32; 8]; 2]>(ray)[0] = L::store(words);
    }
    if cfg!(debug_assertions) {
        for (k, ray) in rays.iter().enumerate().filter(|(k, _)| hit >> k & 1 == 1) {
            let want = primary_ray(camera, xy[k].0, xy[k].1).direction;
            assert_eq!(ray.direction.map(f32::to_bits), want.map(f32::to_bits), "lane {k}");
        }
    }
    match intersect_each::<L>(&rays, std::array::from_fn(|k| setups[k].record())) {
        Some((met, us, vs)) => {
            for k in 0..LANES {
                if met >> k & 1 == 1 {
                    (u[k], v[k]) = (us[k], vs[k]);
                }
            }
        }
        None => {
            for k in (0..LANES).filter(|k| hit >> k & 1 == 1) {
                (u[k], v[k]) = setups[k].reintersected_barycentrics(texels[k], &rays[k]);
            }
        }
    }
}

/// The surfaces of a tile of `tw` x `th` pixels whose top-left pixel is `(x0, y0)` into
/// `surfaces` (`tw * th`, row-major), from its texels `gbuffer` (texel `(lx, ly)` at
/// `ly * width + lx`): `reconstruction` a [`TILE_WIDTH`] x [`TILE_HEIGHT`] block at a
/// time ([`Reconstruct::block`]), at SIMD level `level` (one this CPU has). What both
/// executors run: the staged stage over bands of rows, the fused frame over its tiles.
#[allow(clippy::too_many_arguments)]
pub(crate) fn blocks(
    level: SimdLevel,
    reconstruct: &Reconstruct,
    geometry: &WorldGeometry,
    gbuffer: &[GBufferTexel],
    at: ((usize, usize), (usize, usize), usize),
    setups: &mut BlockSetups,
    surfaces: &mut [SurfaceRecord],
) {
    let (origin, size, width) = at;
    dispatch!(
        level,
        tile_reconstruction,
        tile_reconstruction_avx512,
        tile_reconstruction_avx2,
        (reconstruct, geometry, gbuffer, origin, size, width, setups, surfaces)
    );
}

/// [`blocks`] at lanes `L`.
///
/// Tried and not kept: asking for the next block's triangle records and corner normals
/// (`_mm_prefetch`) one or two blocks ahead. The first read of a record is half of
/// `TriangleSetup::new`'s samples on the dragon's frame, where nearly every pixel shows a
/// triangle of its own; with the prefetch that function's share of the frame's samples fell
/// from 4.3% to 2.3%, but the block loop's rose by as much, and the frame did not move
/// (`hyrt render assets/scenes/dragon.toml --frames 9 --threads 1`, the two binaries
/// alternated four times: 1.02 and 0.99 of the previous frame, AMD EPYC Zen 5). What the
/// fused tiles keep instead: every record the tile's pixels show asked for at once before
/// its first block (`fused::prefetch_triangles`), a burst of independent misses.
/// Also tried: the lanes of a block whose pixels lie on different triangles (`SetupLanes`
/// in `lanes`) by two transposes in registers (the record, and the corner and geometric
/// normals made contiguous in `TriangleSetup`) instead of 22 arrays filled word by word:
/// the dragon's fused tiles 1.002 and Sponza's 0.985 of before (medians of nine
/// alternations, one thread), 1.023 and 1.024 by minima. The dragon's blocks wait on the
/// records' first reads, not on the stores.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn tile_reconstruction<L: Lanes>(
    reconstruct: &Reconstruct,
    geometry: &WorldGeometry,
    gbuffer: &[GBufferTexel],
    (x0, y0): (usize, usize),
    (tw, th): (usize, usize),
    width: usize,
    setups: &mut BlockSetups,
    surfaces: &mut [SurfaceRecord],
) {
    const BW: usize = TILE_WIDTH as usize;
    const BH: usize = TILE_HEIGHT as usize;
    debug_assert_eq!(surfaces.len(), tw * th);
    for by in (0..th).step_by(BH) {
        for bx in (0..tw).step_by(BW) {
            // Lane `j` is the block's pixel `(bx + j % BW, by + j / BW)`; one outside the
            // tile is a miss.
            let at_lane = |j: usize| (bx + j % BW, by + j / BW);
            let inside = |(lx, ly): (usize, usize)| lx < tw && ly < th;
            let texels = std::array::from_fn(|j| match at_lane(j) {
                (lx, ly) if inside((lx, ly)) => &gbuffer[ly * width + lx],
                _ => &GBufferTexel::MISS,
            });
            let xy = std::array::from_fn(|j| {
                let (lx, ly) = at_lane(j);
                ((x0 + lx) as u32, (y0 + ly) as u32)
            });
            let block = reconstruct.block::<L>(texels, xy, geometry, setups);
            for (j, surface) in block.into_iter().enumerate() {
                let (lx, ly) = at_lane(j);
                if inside((lx, ly)) {
                    surfaces[ly * tw + lx] = surface;
                }
            }
        }
    }
}

avx2_entry_points!(
    tile_reconstruction,
    tile_reconstruction_avx2,
    tile_reconstruction_avx512,
    (
        reconstruct: &Reconstruct,
        geometry: &WorldGeometry,
        gbuffer: &[GBufferTexel],
        origin: (usize, usize),
        size: (usize, usize),
        width: usize,
        setups: &mut BlockSetups,
        surfaces: &mut [SurfaceRecord]
    )
);

/// The directions of the camera rays of pixels `xy` (core's [`primary_ray`], in lanes):
/// `pixel_centre_ndc`'s operations, then glam's `Mat4 * Vec4` (SSE2's order:
/// `((c0 * x + c1 * y) + c2 * z) + c3 * w`, here `z = w = 1`) and the division by `w`, each
/// an IEEE f32 operation, so each lane's direction is the scalar kernel's bit for bit
/// (`tests`' re-intersection proptest, and a debug assertion per lane).
#[inline(always)]
fn primary_directions<L: Lanes>(camera: &CameraRecord, xy: [(u32, u32); LANES]) -> [L::F; 3] {
    let (mut x, mut y) = ([0.0f32; LANES], [0.0f32; LANES]);
    for k in 0..LANES {
        // Exact: pixel coordinates are below 2^24.
        (x[k], y[k]) = (xy[k].0 as f32, xy[k].1 as f32);
    }
    let (half, two, one) = (L::splat(0.5), L::splat(2.0), L::splat(1.0));
    // pixel_centre_ndc: (x + 0.5) / width * 2 - 1 and 1 - (y + 0.5) / height * 2.
    let w = L::splat(camera.width as f32);
    let h = L::splat(camera.height as f32);
    let nx = L::sub(L::mul(L::div(L::add(L::load(&x), half), w), two), one);
    let ny = L::sub(one, L::mul(L::div(L::add(L::load(&y), half), h), two));
    let m = &camera.inv_view_proj;
    let mut far = [L::splat(0.0); 4];
    for (r, far) in far.iter_mut().enumerate() {
        // Column c, row r is m[c * 4 + r] (`Mat4::from_cols_array`).
        let xy = L::add(L::mul(L::splat(m[r]), nx), L::mul(L::splat(m[4 + r]), ny));
        let xyz = L::add(xy, L::mul(L::splat(m[8 + r]), one));
        *far = L::add(xyz, L::mul(L::splat(m[12 + r]), one));
    }
    [L::div(far[0], far[3]), L::div(far[1], far[3]), L::div(far[2], far[3])]
}

/// Debug builds: every record valid.
pub(crate) fn validate(out: &[SurfaceRecord]) {
    if cfg!(debug_assertions) {
        for (i, s) in out.iter().enumerate() {
            if let Err(e) = s.validate() {
                panic!("reconstruction: pixel {i}: {e}");
            }
        }
    }
}
