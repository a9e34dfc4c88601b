//! Bands: a frame larger than the device's bindings, rendered a band of whole rows at a
//! time, and the bands' outputs merged into the frame the CPU reference renders.
//!
//! A storage binding holds at most `max_storage_buffer_binding_size` bytes (128 MiB on
//! lavapipe and WebGPU's default), and a render target at most
//! `max_texture_dimension_2d` pixels a side. A 3840x2160 frame with 4 lights has 530 MB
//! of shadow rays and 398 MB of surfaces. So the backend picks the most rows whose
//! per-pixel and per-(pixel, light) buffers fit one binding ([`rows_per_band`]) and
//! runs the frame's whole plan once per band, each band a frame of its own in
//! everything but the image: `visibility_raster` draws every triangle clipped to the
//! band's rows with the whole image's setup (so each pixel gets the reference's bits),
//! re-intersected reconstruction casts the image rows' camera rays, and every other
//! stage works on the band's pixels, indexed from the band's first row
//! ([`hyrt_core::formats::FrameParams::first_row`]). Every stage is per pixel (or per
//! ray of a pixel), so a pixel's values do not depend on the band it is in.
//!
//! Merging (what [`BandMerge`] does on readback):
//! * per-pixel buffers, and the per-ray buffers of the bounce lists (which list their
//!   rays in their parents' order), are the bands' buffers one after the other;
//! * indices into the frame's lists are the band's plus what earlier bands held: a
//!   ray's `pixel` (a shadow or bounce ray's pixel, a bounce shadow ray's surface in its
//!   depth's list), a link's children;
//! * shadow-ray lists are light-major (every ray to light 0 in pixel order, then light 1,
//!   ...; with area lights and ambient occlusion, slot-major: a ray's `light` is its
//!   shadow-mask slot, [`crate::buffers::SlotParams`]): `compaction` of a banded frame also
//!   writes where each light's (slot's) rays start in the band's list
//!   (`shaders/light_starts.wgsl`), and the merge takes light 0's rays of every band, then
//!   light 1's, and so on, with their `occluded` words.
//!
//! # Denoised frames
//!
//! `shadow_denoise` filters each pixel over its neighbours up to
//! [`crate::shadow_denoise::DENOISE_HALO`] rows away (its à-trous taps, the raw
//! neighbourhood, the 8 x 8 tiles aligned to the image's rows). A band of a denoised frame
//! of several bands is therefore rendered over its rows and a halo of that many rows on
//! each side ([`with_halo`]: its first row aligned down to a multiple of the tile, so that
//! its tiles are the frame's; clipped to the image), and the merge keeps only the band's
//! own rows: the per-pixel buffers are cut to them, the primary shadow-ray lists to the
//! rays of its own pixels (`compaction` writes, per slot, where they start and end in the
//! band's list: `shaders/light_starts.wgsl`), and the halo's pixels spawn no bounce
//! (`secondary_rays` spawns only from the band's own pixels, `[live[1], live[2])`), so the
//! bounce lists hold the band's own rays alone. Every buffer of the merged frame is the
//! CPU reference's; `present` writes the band's own rows alone.
//!
//! Where this module counts `lights` per pixel, it means shadow-mask slots per surface
//! ([`hyrt_core::plan::FramePlan::lights`]): one per light in a frame without area lights
//! and ambient occlusion, more with them.
//!
//! A bounce list whose room outgrows a binding (reflection and refraction rays can
//! double with every depth) makes the band split in two and run again. A frame one row
//! of which does not fit is refused with [`GpuError::Limits`], naming what does not fit.

use hyrt_core::formats::{CameraRecord, GBufferTexel, HitRecord, RayRecord, SurfaceRecord, INVALID_ID};
use hyrt_core::frame::{Frame, RenderError};
use hyrt_core::plan::{FrameBuffer, FramePlan};

use crate::GpuError;

/// Rows `[first_row, first_row + rows)` of the image, rendered as one frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Band {
    pub first_row: u32,
    pub rows: u32,
}

/// The room of a frame's ray lists: what its buffers are allocated for. The counts are
/// known only on the GPU; a frame whose lists outgrow their room runs again with more
/// (see `GpuBackend`).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Room {
    /// Shadow rays of the primary hits.
    pub shadow_rays: u32,
    /// Per bounce depth (depth `i + 1` at `i`): its secondary rays and their shadow rays.
    pub bounces: Vec<BounceRoom>,
}

/// The room of one bounce depth's lists.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BounceRoom {
    /// Reflection and refraction rays (and their hits, surfaces, radiance).
    pub rays: u32,
    /// Shadow rays from the surfaces they hit.
    pub shadow_rays: u32,
}

/// Bytes of a pixel in the largest per-pixel buffer of a plan with `channels` denoised
/// channels: the surfaces (48), the G-buffer (24), an image (16), a bounce's links (8),
/// the denoiser's channels (4 each).
const fn pixel_bytes(channels: u32) -> u64 {
    let mut m = std::mem::size_of::<SurfaceRecord>();
    if std::mem::size_of::<GBufferTexel>() > m {
        m = std::mem::size_of::<GBufferTexel>();
    }
    if 16 > m {
        m = 16;
    }
    if 4 * channels as usize > m {
        m = 4 * channels as usize;
    }
    m as u64
}

/// Bytes of one (pixel, light) pair in the largest per-pair buffer: a shadow ray when the
/// plan traces them, else nothing (the scan's flags, `occluded` and the shadow codes
/// have 4 bytes a pair, below a pixel's surface).
fn pair_bytes(plan: &FramePlan) -> u64 {
    if plan.produces(FrameBuffer::Rays) {
        std::mem::size_of::<RayRecord>() as u64
    } else {
        4
    }
}

/// Bytes of the largest binding of a band of `pixels` pixels with `lights` lights under
/// `plan`, but for its bounce lists (see [`bounce_binding_bytes`]): its shadow rays, one
/// per pair at most, or its surfaces.
pub fn band_binding_bytes(pixels: u64, lights: u32, plan: &FramePlan) -> u64 {
    (pixels * pixel_bytes(plan.visibility_channels())).max(pixels * lights as u64 * pair_bytes(plan))
}

/// Bytes of the largest binding of the bounce lists with `room`: a depth's rays (64
/// bytes each; their hits, surfaces and radiance are smaller), its shadow rays, or its
/// shadow codes (4 bytes per ray and light).
pub fn bounce_binding_bytes(room: &Room, lights: u32) -> u64 {
    room.bounces.iter().map(|r| bounce_room_bytes(r, lights)).max().unwrap_or(0)
}

/// Bytes of the largest binding of one bounce depth with room `r` (see
/// [`bounce_binding_bytes`]).
pub fn bounce_room_bytes(r: &BounceRoom, lights: u32) -> u64 {
    let ray = std::mem::size_of::<RayRecord>().max(std::mem::size_of::<SurfaceRecord>());
    let ray = ray.max(std::mem::size_of::<HitRecord>()) as u64;
    (r.rays as u64 * ray).max(r.shadow_rays as u64 * ray).max(r.rays as u64 * lights.max(1) as u64 * 4)
}

/// The rows of each band of a `width` x `height` frame with `lights` lights under
/// `plan`: as many as fit `max_binding` bytes per binding and `max_side` pixels of
/// render target (every row when they all fit: one band). An error when the image is
/// wider than the render targets allow, or one row does not fit.
pub fn rows_per_band(
    width: u32,
    height: u32,
    lights: u32,
    plan: &FramePlan,
    max_binding: u64,
    max_side: u32,
) -> Result<u32, GpuError> {
    if width > max_side {
        return Err(GpuError::Limits(format!(
            "visibility_raster: a {width}-pixel-wide image exceeds the device's {max_side}-pixel render target side \
             (frames are split into bands of rows, not columns)"
        )));
    }
    let row = band_binding_bytes(width as u64, lights, plan);
    let rows = max_binding / row.max(1);
    if rows == 0 {
        return Err(GpuError::Limits(format!(
            "one row of a {width}-pixel-wide frame with {lights} lights needs {row} bytes in one storage binding; \
             the device allows {max_binding}"
        )));
    }
    Ok(rows.min(height as u64).min(max_side as u64) as u32)
}

/// The own rows of each band of a `height`-row frame whose buffers hold `fit` rows
/// ([`rows_per_band`]) when each band is rendered with `halo` rows more on each side
/// ([`with_halo`]; 0 but in denoised frames): every row when they fit at once (one band,
/// no halo). An error when the halo leaves no row.
pub fn own_rows(fit: u32, height: u32, halo: u32) -> Result<u32, GpuError> {
    if fit >= height || halo == 0 {
        return Ok(fit);
    }
    match fit.checked_sub(halo_rows(halo)) {
        Some(rows) if rows > 0 => Ok(rows),
        _ => Err(GpuError::Limits(format!(
            "shadow_denoise: a band of {fit} rows (what one storage binding holds) leaves no row besides the \
             {} rows of halo the denoiser reads across band edges",
            halo_rows(halo)
        ))),
    }
}

/// The most rows a band's halo adds: `halo` on each side, and up to a tile less one above
/// (its first row aligned down, [`with_halo`]).
fn halo_rows(halo: u32) -> u32 {
    2 * halo + hyrt_core::kernels::denoise::DENOISE_TILE as u32 - 1
}

/// The rows the frame buffers hold for bands of `rows` own rows of a `height`-row frame
/// with a `halo` ([`with_halo`]).
pub fn buffer_rows(rows: u32, height: u32, halo: u32) -> u32 {
    match halo {
        0 => rows,
        _ => (rows + halo_rows(halo)).min(height),
    }
}

/// `band` of a `height`-row frame rendered with `halo` rows more on each side, its first
/// row aligned down to a multiple of the denoiser's tile, clipped to the image: the band
/// rendered, and its own rows from the rendered band's first row (`band` itself, and all of
/// it, when `halo` is 0).
pub fn with_halo(band: Band, height: u32, halo: u32) -> (Band, Band) {
    if halo == 0 {
        return (band, Band { first_row: 0, rows: band.rows });
    }
    let tile = hyrt_core::kernels::denoise::DENOISE_TILE as u32;
    let first = band.first_row.saturating_sub(halo) / tile * tile;
    let end = (band.first_row + band.rows + halo).min(height);
    (Band { first_row: first, rows: end - first }, Band { first_row: band.first_row - first, rows: band.rows })
}

/// The end of the own rows of the band `frame` holds, from the band's first row.
pub fn own_end(frame: &crate::buffers::FrameBuffers) -> usize {
    (frame.own.first_row + frame.own.rows) as usize
}

/// The rays of a band's own pixels in its primary shadow-ray list `data` (elements of
/// `size` bytes), in slot order: per slot the range `[starts[slots + s], starts[2 slots +
/// s])` of the three words per slot of `shaders/light_starts.wgsl`.
pub fn own_rays(data: &[u8], size: usize, starts: &[u32]) -> Vec<u8> {
    let slots = starts.len() / 3;
    let mut out = Vec::with_capacity(data.len());
    for s in 0..slots {
        let (lo, hi) = (starts[slots + s] as usize * size, starts[2 * slots + s] as usize * size);
        out.extend_from_slice(&data[lo.min(data.len())..hi.min(data.len()).max(lo.min(data.len()))]);
    }
    out
}

/// The host bytes of the frame the backend reads back into `frame` (its plan and the
/// buffers it holds set by `Frame::begin`) at `width` x `height` with `lights` lights:
/// per pixel, the G-buffer (24), the surfaces (48), the images (16 each), the shadow
/// codes (1 per light) it holds. Lists are counted at their least (none): how many rays
/// they hold is known only when the frame runs, and they are reserved fallibly then.
pub fn host_frame_bytes(frame: &Frame, width: u32, height: u32, lights: u32) -> u64 {
    let pixels = width as u64 * height as u64;
    let per_pixel: u64 = frame
        .buffers()
        .map(|b| match b {
            FrameBuffer::GBuffer => std::mem::size_of::<GBufferTexel>() as u64,
            FrameBuffer::Surfaces => std::mem::size_of::<SurfaceRecord>() as u64,
            FrameBuffer::Shadow => lights as u64,
            FrameBuffer::Rt | FrameBuffer::Raster | FrameBuffer::Final => 16,
            FrameBuffer::Visibility => 4 * frame.plan.visibility_channels() as u64,
            FrameBuffer::Rays | FrameBuffer::Occluded | FrameBuffer::Bounce { .. } => 0,
        })
        .sum();
    pixels.saturating_mul(per_pixel)
}

/// Refuse a frame whose host buffers ([`host_frame_bytes`]) exceed the memory
/// available ([`hyrt_core::memory::available_bytes`]), before anything is allocated.
pub fn check_host_memory(frame: &Frame, camera: &CameraRecord, lights: u32) -> Result<(), RenderError> {
    let needed = host_frame_bytes(frame, camera.width, camera.height, lights);
    match hyrt_core::memory::available_bytes() {
        Some(available) if needed > available => Err(RenderError::OutOfMemory {
            backend: "gpu",
            width: camera.width,
            height: camera.height,
            needed: Some(needed),
            available: Some(available),
            what: "the frame's per-pixel buffers, read back to the host".into(),
        }),
        _ => Ok(()),
    }
}

/// What a banded frame's readback needs to merge the bands: the size of the lists of
/// earlier bands, and where each band's light-major lists change light.
#[derive(Clone, Debug, Default)]
pub struct BandMerge {
    /// Bands merged so far.
    pub bands: usize,
    /// Pixels of the earlier bands.
    pub pixels: u32,
    /// Per bounce depth (`d - 1`): the rays of the earlier bands.
    pub rays: Vec<u32>,
    /// Per band: the rays of each light in its primary shadow-ray list.
    pub primary_lights: Vec<Vec<u32>>,
    /// Per bounce depth (`d - 1`), per band: the rays of each light in its shadow-ray list.
    pub bounce_lights: Vec<Vec<Vec<u32>>>,
}

impl BandMerge {
    /// Count a band of `pixels` pixels whose bounce lists held `rays` rays per depth.
    pub fn add(&mut self, pixels: u32, rays: &[u32]) {
        self.bands += 1;
        self.pixels += pixels;
        self.rays.resize(rays.len().max(self.rays.len()), 0);
        self.rays.iter_mut().zip(rays).for_each(|(sum, n)| *sum += n);
    }

    /// The per-light counts of a light-major list of `count` rays whose lights start at
    /// `starts` (one per light, non-decreasing, at most `count`).
    pub fn light_counts(starts: &[u32], count: u32) -> Vec<u32> {
        let ends = starts.iter().skip(1).copied().chain(std::iter::once(count));
        starts.iter().zip(ends).map(|(&s, e)| e.saturating_sub(s)).collect()
    }

    /// The per-slot counts of a band's own rays in its primary shadow-ray list, from the
    /// three words per slot of `shaders/light_starts.wgsl`.
    pub fn own_light_counts(starts: &[u32]) -> Vec<u32> {
        let slots = starts.len() / 3;
        (0..slots).map(|s| starts[2 * slots + s].saturating_sub(starts[slots + s])).collect()
    }

    /// Put the frame's shadow-ray lists (and their `occluded` words), read back band after
    /// band, into light-major order: light 0's rays of every band, then light 1's, ...
    /// Nothing to do for a frame of one band.
    pub fn finish(&self, out: &mut Frame) {
        if self.bands <= 1 {
            return;
        }
        light_major(&mut out.rays, &self.primary_lights);
        light_major(&mut out.occluded, &self.primary_lights);
        for (d, lights) in self.bounce_lights.iter().enumerate() {
            if let Some(b) = out.bounces.get_mut(d) {
                light_major(&mut b.shadow_rays, lights);
                light_major(&mut b.occluded, lights);
            }
        }
    }
}

/// Add `offset` to each ray's `pixel` (its pixel, or its surface's index in its list),
/// wrapping (a band with a halo moves its rays' pixels back by the halo's).
pub fn offset_pixels(rays: &mut [RayRecord], offset: u32) {
    if offset != 0 {
        rays.iter_mut().for_each(|r| r.pixel = r.pixel.wrapping_add(offset));
    }
}

/// Add `offset` to each child index of `links` (not to [`INVALID_ID`]: no child).
pub fn offset_links(links: &mut [[u32; 2]], offset: u32) {
    if offset != 0 {
        for c in links.iter_mut().flatten().filter(|c| **c != INVALID_ID) {
            *c += offset;
        }
    }
}

/// Reorder `list`, the light-major lists of several bands one after the other (band `b`
/// holding `counts[b][l]` elements of light `l`), into one light-major list. A list
/// that does not hold them all (a buffer the frame does not return) is left as it is.
fn light_major<T: Copy>(list: &mut Vec<T>, counts: &[Vec<u32>]) {
    let total: u64 = counts.iter().flatten().map(|&c| c as u64).sum();
    if counts.len() <= 1 || list.len() as u64 != total {
        return;
    }
    let lights = counts.iter().map(Vec::len).max().unwrap_or(0);
    // Where each band's list starts in `list`.
    let band_starts: Vec<usize> = counts
        .iter()
        .scan(0usize, |at, c| {
            let start = *at;
            *at += c.iter().map(|&n| n as usize).sum::<usize>();
            Some(start)
        })
        .collect();
    let mut merged = Vec::with_capacity(list.len());
    for l in 0..lights {
        for (b, c) in counts.iter().enumerate() {
            let start = band_starts[b] + c.iter().take(l).map(|&n| n as usize).sum::<usize>();
            let n = c.get(l).copied().unwrap_or(0) as usize;
            merged.extend_from_slice(&list[start..start + n]);
        }
    }
    *list = merged;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn light_major_interleaves_the_bands_lights() {
        // Band 0: light 0 [a0, a1], light 1 [a2]; band 1: light 0 [b0], light 1 [b1, b2].
        let mut list = vec!["a0", "a1", "a2", "b0", "b1", "b2"];
        light_major(&mut list, &[vec![2, 1], vec![1, 2]]);
        assert_eq!(list, ["a0", "a1", "b0", "a2", "b1", "b2"]);
        // One band: unchanged; a list that is not all the bands' rays: unchanged.
        let mut one = vec![1, 2, 3];
        light_major(&mut one, &[vec![2, 1]]);
        assert_eq!(one, [1, 2, 3]);
        light_major(&mut one, &[vec![1], vec![1]]);
        assert_eq!(one, [1, 2, 3]);
    }

    #[test]
    fn light_counts_from_starts() {
        assert_eq!(BandMerge::light_counts(&[0, 3, 3], 7), [3, 0, 4]);
        assert_eq!(BandMerge::light_counts(&[], 0), Vec::<u32>::new());
    }

    fn plan(lights: u32) -> FramePlan {
        FramePlan::from_counts(hyrt_core::plan::SceneNeeds::every_primary_stage(lights))
    }

    #[test]
    fn bands_fit_the_bindings_and_the_render_targets() {
        const MIB128: u64 = 128 << 20;
        // 1280x720 with 2 lights fits whole: one band.
        assert_eq!(rows_per_band(1280, 720, 2, &plan(2), MIB128, 16384).unwrap(), 720);
        // 3840x2160 with 4 lights: a row's shadow rays are 3840 * 4 * 64 bytes.
        let rows = rows_per_band(3840, 2160, 4, &plan(4), MIB128, 16384).unwrap();
        assert_eq!(rows, 136);
        assert!(band_binding_bytes(3840 * rows as u64, 4, &plan(4)) <= MIB128);
        assert!(band_binding_bytes(3840 * (rows as u64 + 1), 4, &plan(4)) > MIB128);
        // Without lights the surfaces (48 bytes a pixel) are the largest binding.
        assert_eq!(rows_per_band(3840, 2160, 0, &plan(0), MIB128, 16384).unwrap(), 728);
        // Taller than the render targets: bands of at most their side.
        assert_eq!(rows_per_band(1, 20000, 1, &plan(1), MIB128, 16384).unwrap(), 16384);
        // Wider than them, or a row too large for a binding: refused, saying which.
        let wide = rows_per_band(16385, 4, 1, &plan(1), MIB128, 16384).unwrap_err().to_string();
        assert!(wide.contains("16385-pixel-wide"), "{wide}");
        let row = rows_per_band(16384, 4, 256, &plan(256), MIB128, 16384).unwrap_err().to_string();
        assert!(row.contains("256 lights") && row.contains("268435456 bytes"), "{row}");
    }

    #[test]
    fn links_keep_no_child() {
        let mut links = [[0, INVALID_ID], [INVALID_ID, 1]];
        offset_links(&mut links, 10);
        assert_eq!(links, [[10, INVALID_ID], [INVALID_ID, 11]]);
    }
}
