//! The fused, tiled executor ([`Executor::Fused`]): the frame's plan run tile by tile
//! instead of stage by stage.
//!
//! `visibility_raster` sets up and bins triangles to its 64-pixel tiles as in the staged
//! frame; then each raster tile, in parallel, is depth-tested and resolved into a
//! tile-local G-buffer, and right after (in a scene the raster takes in batches, after the
//! last batch) each of its [`FUSED_TILE`]-square tiles runs the rest of the plan from
//! those texels while they are in cache (the raster's per-tile hook,
//! `visibility_raster::TileHook`):
//!
//! 1. `reconstruction` of the tile's pixels into tile-local surfaces, a
//!    `TILE_WIDTH` x `TILE_HEIGHT` block of eight pixels at a time
//!    (`reconstruction::Reconstruct::block`: core's kernel in eight SIMD lanes);
//! 2. `compaction` and `shadow_rays`, light by light: the tile's active (pixel, light)
//!    pairs ([`needs_shadow_ray`]) become rays ([`shadow_ray`], the pixel numbered in the
//!    whole image as the staged list numbers it), both kernels over a block's eight
//!    surfaces at once (`compaction::lanes`), in the staged traversal's order (one
//!    packet per block whose every pixel is active), traced at once on this thread
//!    (`occluded_serial`, then the object-space pass of a two-level scene), and their
//!    answers written to a tile-local shadow mask ([`shadow_code`]);
//! 3. `rt_shading`, `raster_shading` and `composition` into the final image, a block of
//!    eight pixels at a time (`rt_shading::lanes`, `raster_shading::lanes`,
//!    `composition::lanes`: the stages' kernels in eight SIMD lanes, each lane on
//!    its own object's record, or where materials vary over surfaces (textures, vertex
//!    colours) on the record the scalar stages shade its pixel with, its texture lookups
//!    made pixel by pixel: `Primary::object`). The pixels that bounce are finished later
//!    (see Bounces below).
//!
//! A tile no triangle covers writes the background and does nothing else; a raster tile
//! no triangle is binned to is not depth-tested or resolved at all, and its texels are not
//! read (`TileTexels::all_miss`): on the paper's scenes, a small object in a large image,
//! those tiles had cost a quarter of the far horse's frame (clearing the depth buffer,
//! resolving and scanning misses). Nothing
//! whole-image is written but the final image, and the G-buffer where the frame asks for it
//! ([`FrameOptions::keep_gbuffer`]: each raster tile's texels are copied out to it): no
//! surface records, no ray list or active pairs, no shadow mask, no raster or ray-traced
//! image. A scene the raster takes in batches keeps its texels whole-image between
//! batches ([`crate::memory`]).
//!
//! # Bounces
//!
//! In a frame that traces reflections and refractions ([`FusedSteps::bounces`]) step 3
//! skips the pixels whose primary hit bounces ([`may_bounce`]: mirrors and glass): the tile
//! defers them, keeping what the later steps read of each (its pixel index, texel,
//! surface, shadow codes and `raster_shading` colour) in a list per raster tile. Their
//! rays are incoherent and trace faster in large batches, so they are not traced in the
//! tiles: after the raster the backend gathers the lists in pixel order
//! ([`Deferred::gather`]), runs the plan's bounce steps over them with the very functions
//! of the staged frame (`backend::bounce_step`: `secondary_rays` from
//! [`Parents::Pixels`], which spawns the staged frame's rays of depth 1 in its order, then
//! `bounce_trace`, the bounces' `compaction` and `shadow_rays`, deeper `secondary_rays`,
//! and `bounce_shading` from the deepest bounce up), and [`shade_deferred`] shades and
//! composes the deferred pixels into the final image ([`rt_shading_bouncing_pixel`],
//! [`composition_pixel`]). Every other pixel of a bouncing plan is finished in its tile by
//! `rt_shading`'s kernel ([`rt_shading_pixel`](crate::rt_shading::rt_shading_pixel), in lanes), which is what `rt_shading` with
//! bounces gives there bit for bit.
//! The deferred pixels and the bounce buffers are sized by the pixels that bounce and
//! their rays, not by the image.
//!
//! A raster tile is four fused tiles: fused tiles of 16, 32 and 64 pixels measured within
//! noise of each other on the teaser (when they read a whole-image G-buffer), and 32 keeps
//! a tile's scratch, beside the raster tile's 128 KiB, within L2.
//!
//! Every step calls the very kernel the staged stage calls for that pixel or ray, or its
//! eight-lane form, which does the scalar kernel's operations in its order (each lane's
//! bits are the scalar kernel's: the lane modules' proptests), at the SIMD level of
//! [`SimdLevel::detect`] (as the raster's). A shadow ray's answer does not depend on the
//! packet it is traced in (the traversals are exact). So the final image, the G-buffer and
//! the frame's counts are the staged frame's bit for bit, whatever the thread count or
//! SIMD level (`hyrt-conformance`'s `fused_frames_are_the_staged_frames_over_the_corpus`
//! checks it on every case, with and without the G-buffer kept).
//!
//! Frames that return stage outputs run staged ([`Executor::Fused`]).
//!
//! [`Executor::Fused`]: hyrt_core::frame::Executor::Fused
//! [`FrameOptions::keep_gbuffer`]: hyrt_core::frame::FrameOptions::keep_gbuffer
//! [`needs_shadow_ray`]: hyrt_core::kernels::shadow::needs_shadow_ray
//! [`shadow_ray`]: hyrt_core::kernels::shadow::shadow_ray
//! [`shadow_code`]: hyrt_core::kernels::shadow::shadow_code

use std::collections::TryReserveError;

use glam::Vec3;
use hyrt_core::formats::{
    CameraRecord, GBufferTexel, LightRecord, ObjectRecord, RayRecord, SurfaceRecord, INVALID_ID, SHADOW_LIT,
    SHADOW_NO_RAY,
};
use hyrt_core::frame::{FrameOptions, PreparedScene};
use hyrt_core::kernels::reconstruction::primary_normal_mapped;
use hyrt_core::kernels::shading::BACKGROUND_RGBA;
use hyrt_core::kernels::shadow::{shadow_code, shadow_ray_record};
use hyrt_core::kernels::texture::Materials;
use hyrt_core::plan::{Composition, FramePlan, Step};

use crate::compaction::lanes::{shadow_ray_of_lane, shadow_rays_lanes, SurfaceLanes};
use crate::composition::composition_pixel;
use crate::composition::lanes::composition_lanes;
use crate::lanes::{avx2_entry_points, dispatch, store3, Lanes, LANES};
use crate::raster_shading::lanes::{raster_shading_lanes, PrimaryLanes};
use crate::raster_shading::{raster_shading_record, Primary};
use crate::reconstruction::{self, BlockSetups, Reconstruct};
use crate::rt_shading::lanes::rt_shading_lanes;
use crate::rt_shading::{rt_shading_bouncing_pixel, rt_shading_bouncing_record, BouncingShading};
use crate::secondary_rays::{may_bounce, Parents};
use crate::traversal::tiles::{TILE_HEIGHT, TILE_WIDTH};
use crate::traversal::{occluded_in_object_space_serial, occluded_serial, SimdLevel, Traversal, SHADOW_VISIBLE};
use crate::visibility_raster::{raster_area, tile_rows, visibility_raster_with, TileHook, TileTexels, TILE_SIZE};
use rayon::prelude::*;

/// Side of a fused tile in pixels. A tile's scratch is its surfaces (48 bytes a pixel), its
/// shadow mask (a byte per pixel and light) and one light's rays (64 bytes a pixel): at 32,
/// 48 KiB + 64 KiB, within a core's L2.
pub const FUSED_TILE: usize = 32;

/// What the fused tiles run of a plan: the plan's steps after `visibility_raster`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FusedSteps {
    /// `compaction` and `shadow_rays` run.
    pub shadow_rays: bool,
    /// `rt_shading` runs.
    pub rt_shading: bool,
    /// The plan traces bounces: the tiles defer the pixels whose primary hit bounces
    /// ([`may_bounce`]) to [`shade_deferred`], after the bounce steps.
    pub bounces: bool,
    /// `raster_shading` runs, and whether it shades ray-traced objects too.
    pub raster_shading: Option<bool>,
    /// How `composition` composes.
    pub composition: Composition,
}

impl FusedSteps {
    /// The steps of `plan` the tiles run. Its bounce steps (`secondary_rays` to
    /// `bounce_shading`) run after the tiles, over the pixels they defer (the module docs).
    pub fn of(plan: &FramePlan) -> FusedSteps {
        let mut steps = FusedSteps {
            shadow_rays: false,
            rt_shading: false,
            bounces: false,
            raster_shading: None,
            composition: Composition::CopyRaster,
        };
        for &step in plan.steps() {
            match step {
                // Frames that denoise trace stochastic rays, which run staged.
                Step::VisibilityRaster | Step::Reconstruction | Step::Compaction | Step::ShadowDenoise => {}
                Step::ShadowRays => steps.shadow_rays = true,
                Step::RtShading { bounces } => (steps.rt_shading, steps.bounces) = (true, bounces),
                Step::RasterShading { shade_ray_traced } => steps.raster_shading = Some(shade_ray_traced),
                Step::Composition(mode) => steps.composition = mode,
                Step::SecondaryRays { .. }
                | Step::BounceTrace { .. }
                | Step::BounceCompaction { .. }
                | Step::BounceShadowRays { .. }
                | Step::BounceShading { .. } => {}
            }
        }
        steps
    }
}

/// The counts of the fused tiles, summed over tiles: what the staged frame's statistics
/// count from its whole-image buffers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TileCounts {
    /// Pixels whose primary hit is a ray-traced object.
    pub ray_traced_pixels: u64,
    /// Shadow rays traced.
    pub shadow_rays: u64,
    /// Of those, the ones that found an occluder.
    pub occluded: u64,
}

impl std::ops::Add for TileCounts {
    type Output = TileCounts;
    fn add(self, o: TileCounts) -> TileCounts {
        TileCounts {
            ray_traced_pixels: self.ray_traced_pixels + o.ray_traced_pixels,
            shadow_rays: self.shadow_rays + o.shadow_rays,
            occluded: self.occluded + o.occluded,
        }
    }
}

/// What the raster's tiles give: their counts and the pixels they deferred, one list per
/// raster tile that has any, in the raster's tile order.
#[derive(Default)]
pub struct TileResults {
    pub counts: TileCounts,
    pub deferred: Vec<DeferredTile>,
}

/// A pixel whose primary hit bounces, as its tile leaves it: what the bounce steps and its
/// shading read of it (its shadow codes are in its [`DeferredTile`]).
#[derive(Clone, Copy)]
struct DeferredPixel {
    /// Its index in the image, `y * width + x`.
    pixel: u32,
    texel: GBufferTexel,
    surface: SurfaceRecord,
    /// Its `raster_shading` colour (zero where the plan has none).
    raster: [f32; 4],
}

/// One raster tile's deferred pixels, and their shadow codes (`lights` a pixel, in order).
#[derive(Default)]
pub struct DeferredTile {
    pixels: Vec<DeferredPixel>,
    shadow: Vec<u8>,
    /// Where materials vary over surfaces, each pixel's shaded record ([`Primary::object`]);
    /// empty elsewhere.
    records: Vec<ObjectRecord>,
}

/// The frame's deferred pixels in pixel order ([`Deferred::gather`]), one array per field:
/// the parents of the first bounce ([`Deferred::parents`]) and the pixels
/// [`shade_deferred`] finishes. The backend keeps it between frames.
#[derive(Default)]
pub struct Deferred {
    pub pixels: Vec<u32>,
    pub texels: Vec<GBufferTexel>,
    pub surfaces: Vec<SurfaceRecord>,
    /// The records their objects are shaded with ([`Primary::object`]), where materials
    /// vary over surfaces (empty elsewhere: each pixel's is its object's own).
    pub records: Vec<ObjectRecord>,
    /// `SHADOW_*` per (deferred pixel, light), `k * lights + light`.
    pub shadow: Vec<u8>,
    pub raster: Vec<[f32; 4]>,
    /// Sort keys: `pixel << 32 | tile << DEFERRED_TILE_BITS | index in the tile`.
    order: Vec<u64>,
}

/// Bits of a deferred pixel's index in its raster tile in [`Deferred`]'s sort keys.
const DEFERRED_TILE_BITS: u32 = (TILE_SIZE * TILE_SIZE).trailing_zeros();

impl Deferred {
    /// The deferred pixels of `tiles` (`lights` shadow codes a pixel), sorted by pixel: the
    /// order in which the staged `secondary_rays` meets them, so the first bounce's rays are
    /// the staged frame's list; their shaded records where the tiles kept them (materials
    /// vary). An error where the allocator cannot hold them.
    pub fn gather(&mut self, tiles: Vec<DeferredTile>, lights: usize) -> Result<(), TryReserveError> {
        let n = tiles.iter().map(|t| t.pixels.len()).sum::<usize>();
        let varying = tiles.iter().any(|t| !t.records.is_empty());
        assert!(tiles.len() < 1 << (32 - DEFERRED_TILE_BITS), "deferred pixels: too many raster tiles");
        self.order.clear();
        crate::memory::reserve(&mut self.order, n)?;
        for (t, tile) in tiles.iter().enumerate() {
            let key = |(j, p): (usize, &DeferredPixel)| {
                (p.pixel as u64) << 32 | ((t as u64) << DEFERRED_TILE_BITS) | j as u64
            };
            self.order.extend(tile.pixels.iter().enumerate().map(key));
        }
        self.order.par_sort_unstable();
        let at = |k: u64| {
            let low = k as u32;
            (&tiles[(low >> DEFERRED_TILE_BITS) as usize], (low & ((1 << DEFERRED_TILE_BITS) - 1)) as usize)
        };
        let pixel = |k: &u64| {
            let (tile, j) = at(*k);
            &tile.pixels[j]
        };
        crate::memory::reserve(&mut self.pixels, n)?;
        crate::memory::reserve(&mut self.texels, n)?;
        crate::memory::reserve(&mut self.surfaces, n)?;
        crate::memory::reserve(&mut self.records, if varying { n } else { 0 })?;
        crate::memory::reserve(&mut self.raster, n)?;
        crate::memory::reserve(&mut self.shadow, n * lights)?;
        let order = self.order.par_iter().with_min_len(1024);
        order.clone().map(|k| pixel(k).pixel).collect_into_vec(&mut self.pixels);
        order.clone().map(|k| pixel(k).texel).collect_into_vec(&mut self.texels);
        order.clone().map(|k| pixel(k).surface).collect_into_vec(&mut self.surfaces);
        self.records.clear();
        if varying {
            order.clone().map(|&k| at(k)).map(|(tile, j)| tile.records[j]).collect_into_vec(&mut self.records);
        }
        order.map(|k| pixel(k).raster).collect_into_vec(&mut self.raster);
        self.shadow.clear();
        self.shadow.resize(n * lights, SHADOW_NO_RAY);
        if lights > 0 {
            self.shadow.par_chunks_mut(lights).zip(&self.order).with_min_len(1024).for_each(|(codes, &k)| {
                let (tile, j) = at(k);
                codes.copy_from_slice(&tile.shadow[j * lights..(j + 1) * lights]);
            });
        }
        Ok(())
    }

    /// The deferred pixels as the first bounce's parents, seen from `eye`.
    pub fn parents(&self, eye: Vec3) -> Parents<'_> {
        Parents::Pixels {
            pixels: &self.pixels,
            texels: &self.texels,
            surfaces: &self.surfaces,
            records: &self.records,
            eye,
        }
    }
}

/// Finish the deferred pixels `d` into `final_image` (`width` pixels a row) once the bounce
/// steps ran: `rt_shading` with bounces ([`rt_shading_bouncing_pixel`], each pixel's rays
/// of depth 1 at `links[k]`) and `composition` with its raster colour.
pub fn shade_deferred(
    d: &Deferred,
    steps: FusedSteps,
    shading: &BouncingShading,
    links: &[[u32; 2]],
    weight: f32,
    width: usize,
    final_image: &mut [[f32; 4]],
) {
    assert_eq!(links.len(), d.pixels.len(), "one [reflection, refraction] link per deferred pixel");
    let nl = shading.lights.len();
    // Row by row: a row's deferred pixels are a run of the sorted list.
    final_image.par_chunks_mut(width.max(1)).enumerate().with_min_len(16).for_each(|(y, row)| {
        let first = (y * width) as u32;
        let lo = d.pixels.partition_point(|&p| p < first);
        let hi = lo + d.pixels[lo..].partition_point(|&p| p < first + width as u32);
        for k in lo..hi {
            let shadow = &d.shadow[k * nl..(k + 1) * nl];
            let (t, s, pixel) = (&d.texels[k], &d.surfaces[k], d.pixels[k]);
            let rt = match d.records.get(k) {
                Some(record) => rt_shading_bouncing_record(shading, t, s, pixel, record, shadow, links[k]),
                None => rt_shading_bouncing_pixel(shading, t, s, pixel, shadow, links[k]),
            };
            row[(d.pixels[k] - first) as usize] = composition_pixel(steps.composition, &d.raster[k], &rt, weight);
        }
    });
}

/// One worker's tile-local buffers, kept from tile to tile.
#[derive(Default)]
struct TileScratch {
    surfaces: Vec<SurfaceRecord>,
    /// Where materials vary over surfaces, each hit's record as shading sees it
    /// ([`Primary::object`]: its texture lookups), made once and read by every step.
    records: Vec<ObjectRecord>,
    /// Reconstruction's triangle setups.
    setups: BlockSetups,
    /// `SHADOW_*` per (tile pixel, light), `pixel * lights + light`.
    shadow: Vec<u8>,
    /// Each light's rays, and the tile pixel each leaves.
    rays: Vec<Vec<RayRecord>>,
    at: Vec<Vec<u32>>,
    occluded: Vec<u32>,
    /// The object-space pass's gathered rays.
    object_space: (Vec<RayRecord>, Vec<u32>),
    /// Shading's lit lanes, per light.
    lit: Vec<u32>,
}

/// Everything a tile reads, shared by all tiles.
struct TileInputs<'a> {
    scene: &'a PreparedScene,
    camera: &'a CameraRecord,
    steps: FusedSteps,
    reconstruct: Reconstruct<'a>,
    /// The materials and the eye; each tile reads its own texels (`gbuffer` empty here).
    primary: Primary<'a>,
    weight: f32,
    traversal: Traversal,
    /// The SIMD level of the per-pixel kernels ([`SimdLevel::detect`], as the raster's).
    level: SimdLevel,
    /// Whether the tiles prefetch their pixels' triangle records ([`prefetch_triangles`]).
    prefetch_triangles: bool,
}

/// What [`fused_frame`] counts and times, and the pixels its tiles deferred.
#[derive(Default)]
pub struct FusedFrame {
    /// `visibility_raster`'s hit texels.
    pub covered_pixels: u64,
    /// The tiles' counts.
    pub counts: TileCounts,
    /// Time `visibility_raster` spent setting up and binning triangles, before the tiles
    /// (whose depth tests and resolves run with the fused steps).
    pub raster_setup: std::time::Duration,
    /// Each raster tile's deferred pixels ([`FusedSteps::bounces`]), for [`Deferred::gather`].
    pub deferred: Vec<DeferredTile>,
}

/// Run a fused frame on the current rayon pool: `visibility_raster`, and in each of its
/// [`TILE_SIZE`]-square tiles, right after the tile's
/// texels are final, the fused steps over its [`FUSED_TILE`]-square tiles, from the
/// tile-local texels (see the module docs). The G-buffer goes into `gbuffer` when given
/// (the caller keeps it), else nowhere whole-image; the final image into `final_image`
/// (sized to the frame; its capacity reserved by the caller).
#[allow(clippy::too_many_arguments)]
pub fn fused_frame(
    scene: &PreparedScene,
    camera: &CameraRecord,
    options: &FrameOptions,
    steps: FusedSteps,
    traversal: Traversal,
    gbuffer: Option<&mut Vec<GBufferTexel>>,
    final_image: &mut Vec<[f32; 4]>,
) -> FusedFrame {
    let (w, h) = (camera.width as usize, camera.height as usize);
    // Every pixel is written by its tile: resizing only grows a new buffer.
    final_image.resize(w * h, [0.0; 4]);
    let materials: Materials = scene.geometry.materials(camera);
    let inputs = TileInputs {
        scene,
        camera,
        steps,
        reconstruct: Reconstruct::new(options.barycentrics, camera),
        primary: Primary {
            gbuffer: &[],
            materials: &materials,
            ambient: &scene.geometry.ambient,
            eye: camera.eye.into(),
            // Fused frames trace no stochastic rays: nothing to denoise.
            visibility: Default::default(),
        },
        weight: options.weight,
        traversal,
        level: SimdLevel::detect(),
        prefetch_triangles: scene.geometry.triangles.bytes() >= PREFETCH_TRIANGLES_MIN_BYTES,
    };
    let area = raster_area(camera);
    if area != (w, h) {
        // Pixels beyond the raster's reach (`MAX_IMAGE_DIM`) are misses: the background.
        let background = background(&inputs);
        for (y, row) in final_image.chunks_mut(w.max(1)).enumerate() {
            row[if y < area.1 { area.0 } else { 0 }..].fill(background);
        }
    }
    let outs = tile_rows(final_image, w, area, TILE_SIZE as usize);
    let raster = visibility_raster_with(&scene.geometry, camera, gbuffer, &inputs, outs);
    let TileResults { counts, deferred } = raster.counts;
    FusedFrame { covered_pixels: raster.covered as u64, counts, raster_setup: raster.setup, deferred }
}

/// The fused steps as the raster's per-tile hook: a raster tile's texels are split into
/// [`FUSED_TILE`]-square tiles.
impl<'a> TileHook for TileInputs<'a> {
    /// The raster tile's rows of the final image.
    type Out = Vec<&'a mut [[f32; 4]]>;
    type Scratch = TileScratch;
    type Counts = TileResults;

    fn scratch(&self) -> TileScratch {
        TileScratch::default()
    }

    fn tile(&self, scratch: &mut TileScratch, texels: TileTexels<'_>, mut rows: Self::Out) -> TileResults {
        if texels.all_miss {
            // No triangle in the raster tile: the background, as `tile` gives each of its
            // fused tiles (without reading the texels).
            let background = background(self);
            rows.iter_mut().for_each(|r| r.fill(background));
            return TileResults::default();
        }
        let ((x0, y0), (tw, th), stride) = (texels.origin, texels.size, TILE_SIZE as usize);
        let mut counts = TileCounts::default();
        let mut deferred = DeferredTile::default();
        for sy in (0..th).step_by(FUSED_TILE) {
            for sx in (0..tw).step_by(FUSED_TILE) {
                let sub = rows[sy..(sy + FUSED_TILE).min(th)].iter_mut().map(|r| &mut r[sx..(sx + FUSED_TILE).min(tw)]);
                let local = TexelTile { texels: &texels.texels[sy * stride + sx..], stride };
                counts = counts + tile(self, (x0 + sx, y0 + sy), local, sub.collect(), scratch, &mut deferred);
            }
        }
        let deferred = if deferred.pixels.is_empty() { Vec::new() } else { vec![deferred] };
        TileResults { counts, deferred }
    }

    fn add(mut a: TileResults, mut b: TileResults) -> TileResults {
        a.deferred.append(&mut b.deferred);
        TileResults { counts: a.counts + b.counts, deferred: a.deferred }
    }
}

/// The final colour of a pixel no triangle covers: the background, as every plan composes
/// it.
fn background(inputs: &TileInputs) -> [f32; 4] {
    composition_pixel(inputs.steps.composition, &BACKGROUND_RGBA, &[0.0; 4], inputs.weight)
}

/// Least size of the world triangle table (records and corner normals) for which the fused
/// tiles ask for the records of the triangles their pixels show before reconstructing
/// them ([`prefetch_triangles`]): half the 32 MB L3 of the machine measured (AMD EPYC Zen
/// 5). A smaller table mostly stays cached from one frame to the next, and the pass over
/// the texels then costs more than it saves: with it, Sponza's fused tiles (5.6 MB of
/// records and normals) took 1.016 of the time without it and the teaser's (11 MB) 1.019,
/// by minima of alternated runs (`hyrt render --frames 15 --threads 1`). The dragon's (73
/// MB) took 0.916 at one thread and 0.900 at two (medians of eleven alternations of
/// `--frames 9`; 0.945 and 0.857 by minima), the images identical.
const PREFETCH_TRIANGLES_MIN_BYTES: usize = 16 << 20;

/// Ask for the cache lines of the triangle records and corner normals that the texels of a
/// `tw` x `th` tile show (`texel(lx, ly)`), one triangle at a time along each row, all
/// before reconstruction reads the first: a burst of independent misses, where the
/// reconstruction's blocks would each wait on their own. On the dragon, whose pixels
/// nearly all show triangles of their own in a table far larger than the L3, the fused
/// tiles took 0.967 of their time (minima of 15 alternations, one thread) with the
/// prefetch of each value's first line, 0.964 of that again with every line a value
/// touches (half the 48-byte records straddle two); `TriangleSetup::new`'s share of the
/// samples fell from 6.5% to 3.9%. Asking one or two blocks ahead inside the
/// reconstruction instead gained nothing (`reconstruction::blocks`' docs).
#[inline(never)]
fn prefetch_triangles<'t>(
    g: &hyrt_core::geometry::WorldGeometry,
    texel: impl Fn(usize, usize) -> &'t GBufferTexel,
    (tw, th): (usize, usize),
) {
    for ly in 0..th {
        let mut last = (INVALID_ID, INVALID_ID);
        for lx in 0..tw {
            let t = texel(lx, ly);
            if t.is_hit() && (t.object, t.triangle) != last {
                last = (t.object, t.triangle);
                if let Some((record, normals)) = g.triangles.stored_at(g.global_triangle(t.object, t.triangle)) {
                    crate::visibility_raster::prefetch_lines(record);
                    crate::visibility_raster::prefetch_lines(normals);
                }
            }
        }
    }
}

/// A fused tile's texels: texel `(lx, ly)` of the tile is `texels[ly * stride + lx]`.
#[derive(Clone, Copy)]
struct TexelTile<'a> {
    texels: &'a [GBufferTexel],
    stride: usize,
}

/// One tile with top-left pixel `(x0, y0)`, texels `texels` and final-image rows `rows`;
/// the pixels it defers into `deferred`.
fn tile(
    inputs: &TileInputs,
    (x0, y0): (usize, usize),
    TexelTile { texels, stride }: TexelTile,
    mut rows: Vec<&mut [[f32; 4]]>,
    s: &mut TileScratch,
    deferred: &mut DeferredTile,
) -> TileCounts {
    let TileInputs { scene, camera, steps, .. } = *inputs;
    let g = &scene.geometry;
    let (width, tw, th) = (camera.width as usize, rows.first().map_or(0, |r| r.len()), rows.len());
    let texel = |lx: usize, ly: usize| &texels[ly * stride + lx];
    let mut counts = TileCounts::default();
    // One pass over the texels: whether any is a hit, and how many are ray traced.
    let mut any_hit = false;
    for ly in 0..th {
        for lx in 0..tw {
            let t = texel(lx, ly);
            any_hit |= t.is_hit();
            counts.ray_traced_pixels += (t.is_hit() && t.is_ray_traced()) as u64;
        }
    }
    if inputs.prefetch_triangles {
        prefetch_triangles(g, texel, (tw, th));
    }
    // A tile no triangle covers: the background, which every plan composes there.
    if !any_hit {
        let background = background(inputs);
        rows.iter_mut().for_each(|r| r.fill(background));
        return counts;
    }

    // reconstruction
    s.surfaces.clear();
    s.surfaces.resize(tw * th, SurfaceRecord::MISS);
    let at = ((x0, y0), (tw, th), stride);
    reconstruction::blocks(inputs.level, &inputs.reconstruct, g, texels, at, &mut s.setups, &mut s.surfaces);
    let materials = inputs.primary.materials;
    if materials.normal_mapped_any() {
        let eye = inputs.primary.eye;
        for (k, s) in s.surfaces.iter_mut().enumerate() {
            *s = primary_normal_mapped(texel(k % tw, k / tw), s, eye, materials);
        }
    }
    reconstruction::validate(&s.surfaces);
    let primary = &Primary { gbuffer: texels, ..inputs.primary };
    let varying = materials.varying();
    s.records.clear();
    if varying {
        s.records.resize(tw * th, bytemuck::Zeroable::zeroed());
        for (k, (record, surface)) in s.records.iter_mut().zip(&s.surfaces).enumerate() {
            if surface.is_hit() {
                *record = primary.object((k / tw) * stride + k % tw, surface);
            }
        }
    }

    // compaction and shadow_rays, light by light
    let lights = &g.lights;
    let nl = lights.len();
    s.shadow.clear();
    s.shadow.resize(tw * th * nl, SHADOW_NO_RAY);
    if steps.shadow_rays {
        let (table, view) = (g.traversal_table(), &g.surface.view());
        let (rays, at) = (&mut s.rays, &mut s.at);
        rays.resize_with(nl, Vec::new);
        at.resize_with(nl, Vec::new);
        let first_pixel = (y0 * width + x0) as u32;
        dispatch!(
            inputs.level,
            tile_shadow_rays,
            tile_shadow_rays_avx512,
            tile_shadow_rays_avx2,
            (lights, &s.surfaces, (tw, th), width as u32, first_pixel, rays, at)
        );
        for (l, (rays, at)) in s.rays.iter().zip(&s.at).enumerate() {
            s.occluded.clear();
            s.occluded.resize(rays.len(), SHADOW_VISIBLE);
            occluded_serial(&scene.bvh, table, view, rays, inputs.traversal, &mut s.occluded);
            if let Some(levels) = &scene.levels {
                occluded_in_object_space_serial(
                    levels,
                    view,
                    |k| rays[k],
                    inputs.traversal,
                    &mut s.object_space,
                    &mut s.occluded,
                );
            }
            for (&k, &o) in at.iter().zip(&s.occluded) {
                s.shadow[k as usize * nl + l] = shadow_code(o != 0);
                counts.occluded += (o != 0) as u64;
            }
            counts.shadow_rays += rays.len() as u64;
        }
    }

    // A pixel whose primary hit bounces waits for its rays: its texel, surface, shadow codes
    // and raster colour are kept for `shade_deferred`, after the bounce steps. (The shading
    // below may write it too; `shade_deferred` writes it last.)
    if steps.bounces {
        let objects = materials.objects;
        for ly in 0..th {
            for lx in (0..tw).filter(|&lx| may_bounce(&s.surfaces[ly * tw + lx], objects)) {
                let (k, i) = (ly * tw + lx, ly * stride + lx);
                let (surface, shadow) = (&s.surfaces[k], &s.shadow[k * nl..(k + 1) * nl]);
                let record = if varying { s.records[k] } else { objects[surface.object as usize] };
                let raster = match steps.raster_shading {
                    Some(shade_ray_traced) => {
                        raster_shading_record(primary, lights, shade_ray_traced, surface, &record, shadow.into())
                    }
                    None => [0.0; 4],
                };
                let pixel = ((y0 + ly) * width + x0 + lx) as u32;
                deferred.pixels.push(DeferredPixel { pixel, texel: texels[i], surface: *surface, raster });
                if varying {
                    deferred.records.push(record);
                }
                deferred.shadow.extend_from_slice(shadow);
            }
        }
    }

    // rt_shading, raster_shading, composition
    dispatch!(
        inputs.level,
        tile_shading,
        tile_shading_avx512,
        tile_shading_avx2,
        (inputs, &s.surfaces, &s.records, &s.shadow, (tw, th), &mut s.lit, &mut rows)
    );
    counts
}

/// `rt_shading`, `raster_shading` and `composition` of a tile's `surfaces` (`tw` x `th`,
/// row-major) with their shadow codes `shadow` (`pixel * lights + light`) into its
/// final-image `rows`, a [`TILE_WIDTH`] x [`TILE_HEIGHT`] block at a time: the stages'
/// kernels over the block's eight pixels at once ([`rt_shading_lanes`],
/// [`raster_shading_lanes`], [`composition_lanes`]), for objects' own records (materials
/// that do not vary). `lit` is scratch: per light, the block's lanes whose shadow ray
/// reached it.
#[inline(always)]
fn tile_shading<L: Lanes>(
    inputs: &TileInputs,
    surfaces: &[SurfaceRecord],
    records: &[ObjectRecord],
    shadow: &[u8],
    (tw, th): (usize, usize),
    lit: &mut Vec<u32>,
    rows: &mut [&mut [[f32; 4]]],
) {
    const BW: usize = TILE_WIDTH as usize;
    const BH: usize = TILE_HEIGHT as usize;
    let (steps, lights) = (inputs.steps, &inputs.scene.geometry.lights);
    let (objects, eye, nl) = (inputs.primary.materials.objects, inputs.primary.eye.into(), lights.len());
    let ambient = inputs.primary.ambient;
    // Where materials vary, each hit's record at its pixel (`records`: `Primary::object`),
    // as the scalar stages shade it.
    let varying = !records.is_empty();
    lit.resize(nl, 0);
    let none = [L::splat(0.0); 4];
    for by in (0..th).step_by(BH) {
        for bx in (0..tw).step_by(BW) {
            // Lane `j` is the block's pixel `(bx + j % BW, by + j / BW)`; one outside the
            // tile is a miss, and not written.
            let at_lane = |j: usize| (bx + j % BW, by + j / BW);
            let inside = |(lx, ly): (usize, usize)| lx < tw && ly < th;
            let block_surfaces = std::array::from_fn(|j| match at_lane(j) {
                (lx, ly) if inside((lx, ly)) => &surfaces[ly * tw + lx],
                _ => &SurfaceRecord::MISS,
            });
            let block = if varying {
                let block_records = std::array::from_fn(|j| match at_lane(j) {
                    (lx, ly) if inside((lx, ly)) => &records[ly * tw + lx],
                    // Not read: the lane is a miss.
                    _ => &records[0],
                });
                PrimaryLanes::<L>::load_shaded(block_surfaces, objects, block_records)
            } else {
                PrimaryLanes::<L>::load(block_surfaces, objects)
            };
            lit.fill(0);
            if bx + BW <= tw && by + BH <= th {
                // The usual block, whole inside the tile: its two rows' codes, lane by lane
                // for each light, without a bounds test per lane.
                let rows: [&[u8]; BH] = std::array::from_fn(|r| &shadow[((by + r) * tw + bx) * nl..][..BW * nl]);
                for (l, lit) in lit.iter_mut().enumerate() {
                    for j in 0..LANES {
                        *lit |= ((rows[j / BW][(j % BW) * nl + l] == SHADOW_LIT) as u32) << j;
                    }
                }
            } else {
                for j in 0..LANES {
                    let (lx, ly) = at_lane(j);
                    if inside((lx, ly)) {
                        let codes = &shadow[(ly * tw + lx) * nl..][..nl];
                        for (lit, &code) in lit.iter_mut().zip(codes) {
                            *lit |= ((code == SHADOW_LIT) as u32) << j;
                        }
                    }
                }
            }
            let rt = if steps.rt_shading { rt_shading_lanes::<L>(&block, lit, lights, ambient, eye) } else { none };
            let raster = match steps.raster_shading {
                Some(shade_ray_traced) => {
                    raster_shading_lanes::<L>(&block, lit, lights, ambient, eye, shade_ray_traced)
                }
                None => none,
            };
            let out = composition_lanes::<L>(steps.composition, raster, rt, inputs.weight);
            // Lane `j`'s texel: a transpose in registers.
            for (j, texel) in L::quads(out).into_iter().enumerate() {
                let (lx, ly) = at_lane(j);
                if inside((lx, ly)) {
                    rows[ly][lx] = texel;
                }
            }
        }
    }
}

avx2_entry_points!(
    tile_shading,
    tile_shading_avx2,
    tile_shading_avx512,
    (
        inputs: &TileInputs,
        surfaces: &[SurfaceRecord],
        records: &[ObjectRecord],
        shadow: &[u8],
        size: (usize, usize),
        lit: &mut Vec<u32>,
        rows: &mut [&mut [[f32; 4]]]
    )
);

/// The shadow rays of a tile's `surfaces` (`tw` x `th`, row-major), light by light into
/// `rays[l]`, each with its tile pixel in `at[l]`: `compaction`'s kernels over the eight
/// surfaces of each [`TILE_WIDTH`] x [`TILE_HEIGHT`] block at once
/// ([`crate::compaction::lanes`]), the block's origins offset once for every light. The
/// rays come in the staged traversal's order (block by block, then row by row), so a
/// block whose every pixel is active is one packet. `first_pixel` is the tile's top-left
/// pixel in the whole image, `width` the image's width.
#[inline(always)]
fn tile_shadow_rays<L: Lanes>(
    lights: &[LightRecord],
    surfaces: &[SurfaceRecord],
    (tw, th): (usize, usize),
    width: u32,
    first_pixel: u32,
    rays: &mut [Vec<RayRecord>],
    at: &mut [Vec<u32>],
) {
    const BW: usize = TILE_WIDTH as usize;
    const BH: usize = TILE_HEIGHT as usize;
    // Room for a ray per pixel and light: what the blocks below write into.
    for (rays, at) in rays.iter_mut().zip(at.iter_mut()) {
        rays.clear();
        at.clear();
        rays.reserve(tw * th);
        at.reserve(tw * th);
    }
    for by in (0..th).step_by(BH) {
        for bx in (0..tw).step_by(BW) {
            // Lane `j` is the block's pixel `(bx + j % BW, by + j / BW)`; one outside the
            // tile is a miss.
            let at_lane = |j: usize| (bx + j % BW, by + j / BW);
            let block = SurfaceLanes::<L>::load(std::array::from_fn(|j| match at_lane(j) {
                (lx, ly) if lx < tw && ly < th => &surfaces[ly * tw + lx],
                _ => &SurfaceRecord::MISS,
            }));
            let o = block.origin;
            for (l, light) in lights.iter().enumerate() {
                let (mut active, direction, t_max) = shadow_rays_lanes::<L>(&block, light);
                if active == 0 {
                    continue;
                }
                // Each lane's first eight words (origin, `t_min`, direction, `t_max`) by a
                // transpose in registers; the rest is `shadow_ray_record`'s constants and
                // the pixel.
                let d = direction;
                let t = [L::splat(0.0), L::splat(t_max)];
                let words = L::transpose8([o[0], o[1], o[2], t[0], d[0], d[1], d[2], t[1]]);
                let template = shadow_ray_record([0.0; 3], [0.0; 3], t_max, l as u32, 0);
                // Written in place into the room reserved above (a `push` each kept the
                // lengths in memory: a fifth of this function's samples on Sponza).
                let (rays, at) = (&mut rays[l], &mut at[l]);
                let (written, spare_rays, spare_at) = (rays.len(), rays.spare_capacity_mut(), at.spare_capacity_mut());
                let mut n = 0;
                while active != 0 {
                    // An active lane is a hit, so a pixel of the tile.
                    let j = active.trailing_zeros() as usize;
                    active &= active - 1;
                    let (lx, ly) = at_lane(j);
                    let mut ray = RayRecord { pixel: first_pixel + ly as u32 * width + lx as u32, ..template };
                    bytemuck::cast_mut::<RayRecord, [[f32; 8]; 2]>(&mut ray)[0] = L::store(words[j]);
                    debug_assert_eq!(
                        ray,
                        shadow_ray_of_lane(&store3::<L>(o), &store3::<L>(d), t_max, j, l as u32, ray.pixel),
                        "fused shadow ray"
                    );
                    debug_assert_eq!(ray.validate(), Ok(()), "fused shadow ray");
                    spare_rays[n].write(ray);
                    spare_at[n].write((ly * tw + lx) as u32);
                    n += 1;
                }
                // SAFETY: both lists had `written` elements and their next `n` slots were
                // written just above (within the room reserved: a pixel adds at most one ray
                // a light).
                unsafe {
                    rays.set_len(written + n);
                    at.set_len(written + n);
                }
            }
        }
    }
}

avx2_entry_points!(
    tile_shadow_rays,
    tile_shadow_rays_avx2,
    tile_shadow_rays_avx512,
    (
        lights: &[LightRecord],
        surfaces: &[SurfaceRecord],
        size: (usize, usize),
        width: u32,
        first_pixel: u32,
        rays: &mut [Vec<RayRecord>],
        at: &mut [Vec<u32>]
    )
);
