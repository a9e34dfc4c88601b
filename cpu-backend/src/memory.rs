//! What a CPU frame needs in memory, checked before anything is allocated, and the
//! fallible reservations that keep a frame that does not fit from aborting the process.
//!
//! A frame's buffers are the ones its plan writes ([`FramePlan::buffers`]): the backend
//! keeps every one of them while the frame runs (later stages read them), and
//! [`Frame::end`](hyrt_core::frame::Frame::end) empties the ones the caller did not ask
//! for afterwards, keeping their allocations for the next frame. Per pixel, with `L`
//! lights:
//!
//! | buffer | bytes | when |
//! |---|---:|---|
//! | G-buffer ([`GBufferTexel`]) | 24 | always |
//! | `visibility_raster`'s per-pixel depth and winner (scratch) | 8 | always |
//! | surfaces ([`SurfaceRecord`]) | 48 | always |
//! | compaction flags (scratch, `u32` per pixel and light) | 4 L | with lights |
//! | shadow mask (`u8` per pixel and light) | L | with lights |
//! | raster, ray-traced and final images (`[f32; 4]`) | 16 each | as planned |
//! | ray list ([`RayRecord`]), its indices and occlusion results | at most 72 L (8 L without stage outputs: no list is written) | with lights |
//!
//! so the default scene's staged frame (two lights, no bounce) needs at least 138 bytes per
//! pixel and at most 282.
//!
//! The fused executor ([`crate::fused`]) keeps only the final image whole-image: 16 bytes
//! per pixel whatever the lights, plus each worker's tile scratch (a fixed size per thread,
//! independent of the image: the raster tile's depth, winner and texels, 128 KiB, and the
//! fused tile's, see [`crate::fused::FUSED_TILE`]). A frame that asks for its G-buffer
//! ([`FrameOptions::keep_gbuffer`]) adds it (24: 40 in all); a scene the raster takes in
//! batches ([`crate::visibility_raster::batched`], over a million triangles) keeps its
//! texels and each tile's depth and winner whole-image from batch to batch (24 + 8: 48 in
//! all). A frame that traces bounces also keeps, per pixel whose primary hit bounces (the
//! pixels the fused tiles defer), its index, texel, surface, raster colour and shadow
//! codes, 92 + L bytes, twice while they are gathered into pixel order, with an 8-byte
//! sort key, and the first bounce's link (8): at most 200 + 2 L bytes per pixel, at least
//! none (no pixel bounces), so the estimate counts them in its most only
//! ([`DEFERRED_PIXEL_BYTES`]).
//!
//! In both executors a bounce depth adds, per ray of that depth, 64 (the ray) + 24
//! (its hit) + 48 (its surface) + 16 (its radiance) + 8 (its link from the parent) + the
//! flags of its parents' lobes, and its own shadow rays: how many rays a depth has is
//! known only when it runs (at most two per parent), so bounce buffers are reserved
//! fallibly then, and the estimate counts their least (none). The staged frame's first
//! bounce has a link per pixel, the fused frame's one per bouncing pixel.
//!
//! [`GBufferTexel`]: hyrt_core::formats::GBufferTexel
//! [`FrameOptions::keep_gbuffer`]: hyrt_core::frame::FrameOptions::keep_gbuffer
//! [`SurfaceRecord`]: hyrt_core::formats::SurfaceRecord
//! [`RayRecord`]: hyrt_core::formats::RayRecord

use std::collections::TryReserveError;
use std::mem::size_of;

use hyrt_core::formats::{GBufferTexel, RayRecord, SurfaceRecord};
use hyrt_core::frame::{Executor, Frame, FrameOptions, RenderError};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::plan::{FrameBuffer, FramePlan};

/// The bytes a frame needs: `at_least` whatever the scene shows (the per-pixel buffers),
/// `at_most` when every pixel sends a shadow ray to every light (bounce rays not
/// counted: see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameBytes {
    pub at_least: u64,
    pub at_most: u64,
}

/// Bytes per pixel of [`visibility_raster`](crate::visibility_raster)'s depth and winner
/// scratch.
const RASTER_COUNTS_BYTES: u64 = 8;

/// Bytes of one pixel the fused tiles defer, without its shadow codes (one byte per light,
/// twice): its index, texel, surface and raster colour twice (the tiles' lists and the
/// gathered arrays), its sort key and its first-bounce link (the module docs).
pub const DEFERRED_PIXEL_BYTES: u64 =
    2 * (4 + size_of::<GBufferTexel>() as u64 + size_of::<SurfaceRecord>() as u64 + 16) + 8 + 8;

/// How a frame runs, as far as its memory goes besides its plan and size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameRun {
    pub executor: Executor,
    /// The frame returns its G-buffer ([`FrameOptions::returns`]).
    pub keep_gbuffer: bool,
    /// The raster takes the scene in batches ([`crate::visibility_raster::batched`]).
    pub batched: bool,
}

impl FrameRun {
    /// The run of a frame of `geometry` under `options` by `executor`.
    pub fn new(executor: Executor, options: &FrameOptions, geometry: &WorldGeometry) -> FrameRun {
        let keep_gbuffer = options.returns(FrameBuffer::GBuffer);
        FrameRun { executor, keep_gbuffer, batched: crate::visibility_raster::batched(geometry) }
    }
}

impl From<Executor> for FrameRun {
    /// A frame that asks for no G-buffer, of a scene the raster takes in one batch.
    fn from(executor: Executor) -> FrameRun {
        FrameRun { executor, keep_gbuffer: false, batched: false }
    }
}

/// What a frame of `plan` at `width` x `height` run as `run` says needs on this backend (the
/// module docs' table). Saturates instead of overflowing.
pub fn frame_bytes(plan: &FramePlan, run: impl Into<FrameRun>, width: u32, height: u32) -> FrameBytes {
    let run = run.into();
    let pixels = width as u64 * height as u64;
    if run.executor == Executor::Fused {
        let texels = size_of::<GBufferTexel>() as u64;
        let per_pixel = 16
            + if run.keep_gbuffer || run.batched { texels } else { 0 }
            + if run.batched { RASTER_COUNTS_BYTES } else { 0 };
        let b = pixels.saturating_mul(per_pixel);
        let deferred = match plan.bounce_depth() {
            0 => 0,
            _ => pixels.saturating_mul(DEFERRED_PIXEL_BYTES + 2 * plan.lights() as u64),
        };
        return FrameBytes { at_least: b, at_most: b.saturating_add(deferred) };
    }
    let lights = plan.lights() as u64;
    let pairs = pixels.saturating_mul(lights);
    let mut at_least = pixels.saturating_mul(RASTER_COUNTS_BYTES);
    let mut at_most = at_least;
    for b in plan.buffers() {
        let (least, most) = match b {
            FrameBuffer::GBuffer => (pixels.saturating_mul(size_of::<GBufferTexel>() as u64), 0),
            FrameBuffer::Surfaces => (pixels.saturating_mul(size_of::<SurfaceRecord>() as u64), 0),
            // The list, the compacted indices (`u32`) and the flags of every pair (`u32`).
            FrameBuffer::Rays => (pairs.saturating_mul(4), pairs.saturating_mul(size_of::<RayRecord>() as u64 + 4)),
            FrameBuffer::Occluded => (0, pairs.saturating_mul(4)),
            FrameBuffer::Shadow => (pairs, 0),
            // The channels and the denoiser's ping-pong copy.
            FrameBuffer::Visibility => (pixels.saturating_mul(8 * plan.visibility_channels() as u64), 0),
            FrameBuffer::Rt | FrameBuffer::Raster | FrameBuffer::Final => (pixels.saturating_mul(16), 0),
            FrameBuffer::Bounce { .. } => (0, 0),
        };
        at_least = at_least.saturating_add(least);
        at_most = at_most.saturating_add(least.saturating_add(most));
    }
    FrameBytes { at_least, at_most }
}

pub use hyrt_core::memory::{available_bytes, MEMORY_LIMIT_ENV};

/// The error of a frame that does not fit: what it needs, what is available.
pub fn out_of_memory(width: u32, height: u32, needed: Option<u64>, available: Option<u64>, what: &str) -> RenderError {
    RenderError::OutOfMemory { backend: "cpu", width, height, needed, available, what: what.to_string() }
}

/// Refuse a frame whose least need exceeds the available memory ([`available_bytes`]),
/// before allocating.
pub fn check(plan: &FramePlan, run: impl Into<FrameRun>, width: u32, height: u32) -> Result<FrameBytes, RenderError> {
    check_against(plan, run, width, height, available_bytes())
}

/// [`check`] against a given availability (`None`: unknown, nothing is refused).
pub fn check_against(
    plan: &FramePlan,
    run: impl Into<FrameRun>,
    width: u32,
    height: u32,
    available: Option<u64>,
) -> Result<FrameBytes, RenderError> {
    let need = frame_bytes(plan, run, width, height);
    match available {
        Some(avail) if need.at_least > avail => {
            Err(out_of_memory(width, height, Some(need.at_least), Some(avail), "the frame's per-pixel buffers"))
        }
        _ => Ok(need),
    }
}

/// Make room for `n` elements in `v` (its length is kept; the stages overwrite it), or
/// say which buffer did not fit.
pub fn reserve<T>(v: &mut Vec<T>, n: usize) -> Result<(), TryReserveError> {
    v.try_reserve_exact(n.saturating_sub(v.len()))
}

/// Reserve the per-pixel buffers of the frame fallibly, so that the stages that fill them
/// (`collect_into_vec`, `resize`) never allocate: a frame too large for the allocator
/// becomes [`RenderError::OutOfMemory`] instead of an abort.
pub fn reserve_frame(
    frame: &mut Frame,
    plan: &FramePlan,
    run: FrameRun,
    width: u32,
    height: u32,
) -> Result<(), RenderError> {
    let pixels = width as usize * height as usize;
    let pairs = pixels.saturating_mul(plan.lights() as usize);
    // `n` elements of `v` for the buffer `what`; the error names its bytes.
    fn fit<T>(v: &mut Vec<T>, n: usize, what: &str, (width, height): (u32, u32)) -> Result<(), RenderError> {
        reserve(v, n).map_err(|_| {
            let bytes = (n as u64).saturating_mul(size_of::<T>() as u64);
            out_of_memory(width, height, Some(bytes), available_bytes(), what)
        })
    }
    let size = (width, height);
    // The fused executor writes the final image alone, and the G-buffer where the frame
    // returns it (a batched scene's is the raster's: it sizes it).
    let written = |b: &FrameBuffer| match b {
        FrameBuffer::Final => true,
        FrameBuffer::GBuffer => run.executor == Executor::Staged || run.keep_gbuffer,
        _ => run.executor == Executor::Staged,
    };
    for b in plan.buffers().filter(written) {
        match b {
            FrameBuffer::GBuffer => fit(&mut frame.gbuffer, pixels, "the G-buffer", size)?,
            FrameBuffer::Surfaces => fit(&mut frame.surfaces, pixels, "the surfaces", size)?,
            FrameBuffer::Shadow => fit(&mut frame.shadow, pairs, "the shadow mask", size)?,
            FrameBuffer::Visibility => {
                let n = pixels.saturating_mul(plan.visibility_channels() as usize);
                fit(&mut frame.visibility, n, "the denoised visibility", size)?
            }
            FrameBuffer::Rt => fit(&mut frame.rt, pixels, "the ray-traced image", size)?,
            FrameBuffer::Raster => fit(&mut frame.raster, pixels, "the raster image", size)?,
            FrameBuffer::Final => fit(&mut frame.final_image, pixels, "the final image", size)?,
            // Sized by their ray counts: reserved by the stages that know them.
            FrameBuffer::Rays | FrameBuffer::Occluded | FrameBuffer::Bounce { .. } => {}
        }
    }
    Ok(())
}
