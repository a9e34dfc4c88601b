//! The fused, tiled executor ([`Executor::Fused`]): the frame's plan run tile by tile
//! instead of stage by stage.
//!
//! `visibility_raster` sets up and bins triangles to its 64-pixel tiles as in the staged
//! frame; then each raster tile, in parallel, is depth-tested and resolved into a
//! tile-local G-buffer, and right after (in a scene the raster takes in batches, after the
//! last batch) each of its [`FUSED_TILE`]-square tiles runs the rest of the plan from
//! those texels while they are in cache (the raster's per-tile hook,
//! [`TileHook`](crate::visibility_raster::TileHook)):
//!
//! 1. `reconstruction` of the tile's pixels into tile-local surfaces
//!    ([`Reconstruct::pixel`]);
//! 2. `compaction` and `shadow_rays`, light by light: the tile's active (pixel, light)
//!    pairs ([`needs_shadow_ray`]) become rays ([`shadow_ray`], the pixel numbered in the
//!    whole image as the staged list numbers it) in blocks of
//!    [`TILE_WIDTH`] x [`TILE_HEIGHT`] pixels (one packet each where every pixel is
//!    active, as the staged traversal orders them), traced at once on this thread
//!    (`occluded_serial`, then the object-space pass of a two-level scene), and their
//!    answers written to a tile-local shadow mask ([`shadow_code`]);
//! 3. `rt_shading`, `raster_shading` and `composition` per pixel
//!    ([`rt_shading_pixel`], [`raster_shading_pixel`], [`composition_pixel`]) into the
//!    final image.
//!
//! A tile no triangle covers writes the background and does nothing else. Nothing
//! whole-image is written but the final image, and the G-buffer where the frame asks for it
//! ([`FrameOptions::keep_gbuffer`]: each raster tile's texels are copied out to it): no
//! surface records, no ray list or active pairs, no shadow mask, no raster or ray-traced
//! image. A scene the raster takes in batches keeps its texels whole-image between
//! batches ([`crate::memory`]).
//!
//! A raster tile is four fused tiles: fused tiles of 16, 32 and 64 pixels measured within
//! noise of each other on the teaser (when they read a whole-image G-buffer), and 32 keeps
//! a tile's scratch, beside the raster tile's 128 KiB, within L2.
//!
//! Every step calls the very kernel the staged stage calls for that pixel or ray, and a
//! shadow ray's answer does not depend on the packet it is traced in (the traversals are
//! exact), so the final image, the G-buffer and the frame's counts are the staged frame's
//! bit for bit, whatever the thread count or SIMD level (`hyrt-conformance`'s
//! `fused_frames_are_the_staged_frames_over_the_corpus` checks it on every case, with and
//! without the G-buffer kept).
//!
//! Frames that return stage outputs or trace bounces run staged ([`Executor::Fused`]).
//!
//! [`Executor::Fused`]: hyrt_core::frame::Executor::Fused
//! [`FrameOptions::keep_gbuffer`]: hyrt_core::frame::FrameOptions::keep_gbuffer
//! [`needs_shadow_ray`]: hyrt_core::kernels::shadow::needs_shadow_ray
//! [`shadow_ray`]: hyrt_core::kernels::shadow::shadow_ray
//! [`shadow_code`]: hyrt_core::kernels::shadow::shadow_code
//! [`TILE_WIDTH`]: crate::traversal::tiles::TILE_WIDTH
//! [`TILE_HEIGHT`]: crate::traversal::tiles::TILE_HEIGHT

use hyrt_core::formats::{CameraRecord, GBufferTexel, RayRecord, SurfaceRecord, SHADOW_NO_RAY};
use hyrt_core::frame::{FrameOptions, PreparedScene};
use hyrt_core::kernels::shading::BACKGROUND_RGBA;
use hyrt_core::kernels::shadow::{needs_shadow_ray, shadow_code, shadow_ray};
use hyrt_core::kernels::texture::Materials;
use hyrt_core::plan::{Composition, FramePlan, Step};

use crate::composition::composition_pixel;
use crate::raster_shading::{raster_shading_pixel, Primary};
use crate::reconstruction::Reconstruct;
use crate::rt_shading::rt_shading_pixel;
use crate::traversal::tiles::{TILE_HEIGHT, TILE_WIDTH};
use crate::traversal::{occluded_in_object_space_serial, occluded_serial, Traversal, SHADOW_VISIBLE};
use crate::visibility_raster::{raster_area, tile_rows, visibility_raster_with, TileHook, TileTexels, TILE_SIZE};

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
    /// `raster_shading` runs, and whether it shades ray-traced objects too.
    pub raster_shading: Option<bool>,
    /// How `composition` composes.
    pub composition: Composition,
}

impl FusedSteps {
    /// The steps of `plan`, or `None` where the fused tiles cannot run it (bounces).
    pub fn of(plan: &FramePlan) -> Option<FusedSteps> {
        let mut steps = FusedSteps {
            shadow_rays: false,
            rt_shading: false,
            raster_shading: None,
            composition: Composition::CopyRaster,
        };
        for &step in plan.steps() {
            match step {
                Step::VisibilityRaster | Step::Reconstruction | Step::Compaction => {}
                Step::ShadowRays => steps.shadow_rays = true,
                Step::RtShading { bounces: false } => steps.rt_shading = true,
                Step::RasterShading { shade_ray_traced } => steps.raster_shading = Some(shade_ray_traced),
                Step::Composition(mode) => steps.composition = mode,
                Step::RtShading { bounces: true }
                | Step::SecondaryRays { .. }
                | Step::BounceTrace { .. }
                | Step::BounceCompaction { .. }
                | Step::BounceShadowRays { .. }
                | Step::BounceShading { .. } => return None,
            }
        }
        Some(steps)
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

/// One worker's tile-local buffers, kept from tile to tile.
#[derive(Default)]
struct TileScratch {
    surfaces: Vec<SurfaceRecord>,
    /// `SHADOW_*` per (tile pixel, light), `pixel * lights + light`.
    shadow: Vec<u8>,
    /// One light's rays, and the tile pixel each leaves.
    rays: Vec<RayRecord>,
    at: Vec<u32>,
    occluded: Vec<u32>,
    /// The object-space pass's gathered rays.
    object_space: (Vec<RayRecord>, Vec<u32>),
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
}

/// What [`fused_frame`] counts and times.
#[derive(Clone, Copy, Debug, Default)]
pub struct FusedFrame {
    /// `visibility_raster`'s hit texels.
    pub covered_pixels: u64,
    /// The tiles' counts.
    pub counts: TileCounts,
    /// Time `visibility_raster` spent setting up and binning triangles, before the tiles
    /// (whose depth tests and resolves run with the fused steps).
    pub raster_setup: std::time::Duration,
}

/// Run a fused frame on the current rayon pool: `visibility_raster`, and in each of its
/// [`TILE_SIZE`](crate::visibility_raster::TILE_SIZE)-square tiles, right after the tile's
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
        primary: Primary { gbuffer: &[], materials: &materials, eye: camera.eye.into() },
        weight: options.weight,
        traversal,
    };
    let area = raster_area(camera);
    if area != (w, h) {
        // Pixels beyond the raster's reach (`MAX_IMAGE_DIM`) are misses: the background.
        let background = composition_pixel(steps.composition, &BACKGROUND_RGBA, &[0.0; 4], inputs.weight);
        for (y, row) in final_image.chunks_mut(w.max(1)).enumerate() {
            row[if y < area.1 { area.0 } else { 0 }..].fill(background);
        }
    }
    let outs = tile_rows(final_image, w, area, TILE_SIZE as usize);
    let raster = visibility_raster_with(&scene.geometry, camera, gbuffer, &inputs, outs);
    FusedFrame { covered_pixels: raster.covered as u64, counts: raster.counts, raster_setup: raster.setup }
}

/// The fused steps as the raster's per-tile hook: a raster tile's texels are split into
/// [`FUSED_TILE`]-square tiles.
impl<'a> TileHook for TileInputs<'a> {
    /// The raster tile's rows of the final image.
    type Out = Vec<&'a mut [[f32; 4]]>;
    type Scratch = TileScratch;
    type Counts = TileCounts;

    fn scratch(&self) -> TileScratch {
        TileScratch::default()
    }

    fn tile(&self, scratch: &mut TileScratch, texels: TileTexels<'_>, mut rows: Self::Out) -> TileCounts {
        let ((x0, y0), (tw, th), stride) = (texels.origin, texels.size, TILE_SIZE as usize);
        let mut counts = TileCounts::default();
        for sy in (0..th).step_by(FUSED_TILE) {
            for sx in (0..tw).step_by(FUSED_TILE) {
                let sub = rows[sy..(sy + FUSED_TILE).min(th)].iter_mut().map(|r| &mut r[sx..(sx + FUSED_TILE).min(tw)]);
                let local = TexelTile { texels: &texels.texels[sy * stride + sx..], stride };
                counts = counts + tile(self, (x0 + sx, y0 + sy), local, sub.collect(), scratch);
            }
        }
        counts
    }

    fn add(a: TileCounts, b: TileCounts) -> TileCounts {
        a + b
    }
}

/// A fused tile's texels: texel `(lx, ly)` of the tile is `texels[ly * stride + lx]`.
#[derive(Clone, Copy)]
struct TexelTile<'a> {
    texels: &'a [GBufferTexel],
    stride: usize,
}

/// One tile with top-left pixel `(x0, y0)`, texels `texels` and final-image rows `rows`.
fn tile(
    inputs: &TileInputs,
    (x0, y0): (usize, usize),
    TexelTile { texels, stride }: TexelTile,
    mut rows: Vec<&mut [[f32; 4]]>,
    s: &mut TileScratch,
) -> TileCounts {
    let TileInputs { scene, camera, steps, .. } = *inputs;
    let g = &scene.geometry;
    let (width, tw, th) = (camera.width as usize, rows.first().map_or(0, |r| r.len()), rows.len());
    let texel = |lx: usize, ly: usize| &texels[ly * stride + lx];
    let mut counts = TileCounts::default();
    // A tile no triangle covers: the background, which every plan composes there.
    if (0..th).all(|ly| (0..tw).all(|lx| !texel(lx, ly).is_hit())) {
        let background = composition_pixel(steps.composition, &BACKGROUND_RGBA, &[0.0; 4], inputs.weight);
        rows.iter_mut().for_each(|r| r.fill(background));
        return counts;
    }

    // reconstruction
    s.surfaces.clear();
    let mut cache = None;
    for ly in 0..th {
        for lx in 0..tw {
            let t = texel(lx, ly);
            counts.ray_traced_pixels += (t.is_hit() && t.is_ray_traced()) as u64;
            s.surfaces.push(inputs.reconstruct.pixel(t, g, (x0 + lx) as u32, (y0 + ly) as u32, &mut cache));
        }
    }
    crate::reconstruction::validate(&s.surfaces);

    // compaction and shadow_rays, light by light
    let lights = &g.lights;
    let nl = lights.len();
    s.shadow.clear();
    s.shadow.resize(tw * th * nl, SHADOW_NO_RAY);
    if steps.shadow_rays {
        let (table, view) = (g.traversal_table(), &g.surface.view());
        for (l, light) in lights.iter().enumerate() {
            s.rays.clear();
            s.at.clear();
            for by in (0..th).step_by(TILE_HEIGHT as usize) {
                for bx in (0..tw).step_by(TILE_WIDTH as usize) {
                    for ly in by..(by + TILE_HEIGHT as usize).min(th) {
                        for lx in bx..(bx + TILE_WIDTH as usize).min(tw) {
                            let k = ly * tw + lx;
                            let surface = &s.surfaces[k];
                            if needs_shadow_ray(surface, light) {
                                let pixel = ((y0 + ly) * width + x0 + lx) as u32;
                                let ray = shadow_ray(surface, light, l as u32, pixel);
                                debug_assert_eq!(ray.validate(), Ok(()), "fused shadow ray");
                                s.rays.push(ray);
                                s.at.push(k as u32);
                            }
                        }
                    }
                }
            }
            s.occluded.clear();
            s.occluded.resize(s.rays.len(), SHADOW_VISIBLE);
            occluded_serial(&scene.bvh, table, view, &s.rays, inputs.traversal, &mut s.occluded);
            if let Some(levels) = &scene.levels {
                let rays = &s.rays;
                occluded_in_object_space_serial(
                    levels,
                    view,
                    |k| rays[k],
                    inputs.traversal,
                    &mut s.object_space,
                    &mut s.occluded,
                );
            }
            for (&k, &o) in s.at.iter().zip(&s.occluded) {
                s.shadow[k as usize * nl + l] = shadow_code(o != 0);
                counts.occluded += (o != 0) as u64;
            }
            counts.shadow_rays += s.rays.len() as u64;
        }
    }

    // rt_shading, raster_shading, composition (a pixel's texel `i` in the tile's texels)
    let primary = &Primary { gbuffer: texels, ..inputs.primary };
    for (ly, row) in rows.iter_mut().enumerate() {
        for (lx, out) in row.iter_mut().enumerate() {
            let k = ly * tw + lx;
            let (i, surface, shadow) = (ly * stride + lx, &s.surfaces[k], &s.shadow[k * nl..(k + 1) * nl]);
            let rt = match steps.rt_shading {
                true => rt_shading_pixel(primary, lights, i, surface, shadow),
                false => [0.0; 4],
            };
            let raster = match steps.raster_shading {
                Some(shade_ray_traced) => raster_shading_pixel(primary, lights, shade_ray_traced, i, surface, shadow),
                None => [0.0; 4],
            };
            *out = composition_pixel(steps.composition, &raster, &rt, inputs.weight);
        }
    }
    counts
}
