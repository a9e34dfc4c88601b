//! Stage `shadow_denoise`: the stochastic visibility of area lights and ambient occlusion,
//! filtered over the visibility buffer (issue 38 item 4) with core's
//! [`hyrt_core::kernels::denoise`] kernels: the raw channels of every pixel
//! ([`raw_channels`]), the 8 x 8 tiles that need filtering per channel ([`tile_agrees`]:
//! not those fully lit or in umbra), then [`DENOISE_PASSES`] à-trous passes
//! ([`atrous_pixel`]), row by row in parallel; where frames follow each other
//! ([`hyrt_core::frame::FrameOptions::temporal`]), the temporal pass
//! ([`hyrt_core::kernels::temporal`]) against the previous frame the backend kept
//! ([`TemporalHistory`]). Deterministic: each output is a fixed sum over fixed taps,
//! whatever the thread count.
//!
//! Inputs: the surfaces, the shadow mask, the frame's lights and ambient occlusion, the
//! eye and a pixel's angle, and for the temporal pass the previous frame's history and
//! the objects' transforms ([`Temporal`]). Output: `channels` f32 per pixel
//! ([`hyrt_core::kernels::denoise::channel_count`]).

use glam::Vec3;
use hyrt_core::formats::{CameraRecord, LightRecord, ObjectMap, SurfaceRecord};
use hyrt_core::kernels::denoise::{
    atrous_pixel, channel_count, channel_samples, clamp_pixel, noise_sigma, pixel_angle, pixel_footprint, raw_channels,
    tile_agrees, DENOISE_PASSES, DENOISE_TILE, MAX_CHANNELS,
};
use hyrt_core::kernels::soft_shadow::{surface_slots, AmbientOcclusion, Lights};
use hyrt_core::kernels::temporal::{motion_records, temporal_pixel, History};
use rayon::prelude::*;

/// Buffers the stage keeps between frames.
#[derive(Clone, Debug, Default)]
pub struct DenoiseScratch {
    /// The other half of the ping-pong between passes.
    pub values: Vec<f32>,
    /// The raw channels, which bound the filtered ones.
    pub raw: Vec<f32>,
    /// Per pixel and channel, the noise deviation of the raw value (`noise_sigma`).
    pub sigma: Vec<f32>,
    /// Per tile and channel, whether the tile is filtered.
    pub filter: Vec<bool>,
    /// This frame's raw channels where the temporal pass accumulates them (the clamp's
    /// bounds).
    pub current: Vec<f32>,
    /// The temporal pass's spare per-pixel history lengths.
    pub lengths: Vec<u32>,
}

/// What the backend keeps of the last frame it denoised, for the next frame's temporal
/// pass.
#[derive(Clone, Debug)]
pub struct TemporalHistory {
    /// The prepared scene it showed ([`hyrt_core::frame::PreparedScene::id`]); `None`
    /// before any frame. Another scene starts afresh.
    pub scene: Option<u64>,
    /// Its camera.
    pub camera: CameraRecord,
    /// Each object's world-to-object map then.
    pub maps: Vec<ObjectMap>,
    /// Its surfaces.
    pub surfaces: Vec<SurfaceRecord>,
    /// Its visibility after the temporal pass, `channels` per pixel.
    pub visibility: Vec<f32>,
    /// Per pixel, the frames that visibility stands for.
    pub length: Vec<u32>,
    /// Channels per pixel.
    pub channels: usize,
}

impl Default for TemporalHistory {
    /// No frame yet.
    fn default() -> Self {
        TemporalHistory {
            scene: None,
            camera: bytemuck::Zeroable::zeroed(),
            maps: Vec::new(),
            surfaces: Vec::new(),
            visibility: Vec::new(),
            length: Vec::new(),
            channels: 0,
        }
    }
}

/// A frame's temporal pass: the scene it shows, the objects' maps now
/// ([`hyrt_core::frame::PreparedScene::object_maps`]) and the history, which the pass
/// reads and then replaces with this frame.
pub struct Temporal<'a> {
    pub scene: u64,
    pub maps: Vec<ObjectMap>,
    pub history: &'a mut TemporalHistory,
}

/// The stage over a `width` x `height` image: `surfaces` and their mask `shadow`
/// (`surface_slots` codes per pixel) under `lights` and `ao`, seen from `camera`, into
/// `out` (`channel_count(lights, ao)` values per pixel): the raw channels, blended with the
/// previous frames' where `temporal` is given (the history then becomes this frame's),
/// then filtered.
#[allow(clippy::too_many_arguments)]
pub fn shadow_denoise_into<'l>(
    surfaces: &[SurfaceRecord],
    shadow: &[u8],
    lights: impl Into<Lights<'l>>,
    ao: &AmbientOcclusion,
    camera: &CameraRecord,
    scratch: &mut DenoiseScratch,
    temporal: Option<Temporal>,
    out: &mut Vec<f32>,
) {
    let lights = lights.into();
    let (width, height) = (camera.width as usize, camera.height as usize);
    let channels = channel_count(&lights, ao);
    let slots = surface_slots(&lights, ao);
    assert!(channels <= MAX_CHANNELS, "{channels} denoised channels, at most {MAX_CHANNELS}");
    assert_eq!(surfaces.len(), width * height);
    out.clear();
    out.resize(surfaces.len() * channels, 0.0);
    if channels == 0 || surfaces.is_empty() {
        return;
    }
    // Raw channels, a row at a time.
    let row = width * channels;
    out.par_chunks_mut(row).enumerate().for_each(|(y, values)| {
        let mut lights_scratch = vec![0.0f32; lights.len()];
        for x in 0..width {
            let i = y * width + x;
            let codes = if surfaces[i].is_hit() { &shadow[i * slots..(i + 1) * slots] } else { &[][..] };
            let v = &mut values[x * channels..(x + 1) * channels];
            raw_channels(codes, lights, ao, &surfaces[i], &mut lights_scratch, v);
        }
    });
    // Frames that follow each other: the raw channels accumulated over them, and per pixel
    // the frames behind its value.
    // The spatial clamp bounds the result by this frame's raw values (so that an umbra
    // stays exactly dark however the history was resampled).
    let lengths = match temporal {
        Some(t) => {
            scratch.current.clone_from(out);
            Some(temporal_into(surfaces, (lights.records, ao), camera, t, scratch, out))
        }
        None => None,
    };
    filter_into(surfaces, (lights.records, ao), camera, lengths, scratch, out);
}

/// The temporal pass over the raw channels `out` (in place): each pixel blended with its
/// previous frame's accumulated channels ([`temporal_pixel`]); the history becomes this
/// frame's. Returns the frames behind each pixel's value now (its new history lengths).
fn temporal_into<'h>(
    surfaces: &[SurfaceRecord],
    (lights, ao): (&[LightRecord], &AmbientOcclusion),
    camera: &CameraRecord,
    Temporal { scene, maps, history }: Temporal<'h>,
    scratch: &mut DenoiseScratch,
    out: &mut Vec<f32>,
) -> &'h [u32] {
    let (width, height) = (camera.width as usize, camera.height as usize);
    let channels = channel_count(lights, ao);
    let usable = history.scene == Some(scene) && history.channels == channels && !history.surfaces.is_empty();
    let mut length = std::mem::take(&mut scratch.lengths);
    length.clear();
    length.resize(surfaces.len(), 0);
    if usable {
        let motion = motion_records(&history.maps, &maps);
        let (eye, angle) = (Vec3::from(camera.eye), pixel_angle(camera));
        let previous = History {
            camera: &history.camera,
            surfaces: &history.surfaces,
            visibility: &history.visibility,
            length: &history.length,
        };
        let raw = &*out;
        let samples = &channel_samples(lights, ao);
        scratch.values.clear();
        scratch.values.resize(out.len(), 0.0);
        scratch.values.par_chunks_mut(width * channels).zip(length.par_chunks_mut(width)).enumerate().for_each(
            |(y, (values, lengths))| {
                for x in 0..width {
                    let footprint = pixel_footprint(Vec3::from(surfaces[y * width + x].position), eye, angle);
                    let v = &mut values[x * channels..(x + 1) * channels];
                    let at = (footprint, &samples[..]);
                    lengths[x] = temporal_pixel(raw, surfaces, (width, height), (x, y), at, &motion, &previous, v);
                }
            },
        );
        std::mem::swap(out, &mut scratch.values);
    }
    history.scene = Some(scene);
    history.camera = *camera;
    history.maps = maps;
    history.surfaces.clear();
    history.surfaces.extend_from_slice(surfaces);
    history.visibility.clone_from(out);
    scratch.lengths = std::mem::replace(&mut history.length, length);
    history.channels = channels;
    &history.length
}

/// The spatial filter over the (raw or accumulated) channels `out`, in place: the tiles to
/// filter ([`tile_agrees`]), each pixel's noise ([`noise_sigma`], from the samples behind
/// it: the channel's per frame times the frames in `lengths` plus one), the à-trous passes,
/// the clamp to the range of this frame's raw values (the input's, or `scratch.current`
/// where the input accumulates frames).
fn filter_into(
    surfaces: &[SurfaceRecord],
    (lights, ao): (&[LightRecord], &AmbientOcclusion),
    camera: &CameraRecord,
    lengths: Option<&[u32]>,
    scratch: &mut DenoiseScratch,
    out: &mut Vec<f32>,
) {
    let (width, height) = (camera.width as usize, camera.height as usize);
    let channels = channel_count(lights, ao);
    if channels == 0 || surfaces.is_empty() {
        return;
    }
    let row = width * channels;
    // Tiles whose hit pixels agree on 0 or 1 keep them.
    let (tiles_x, tiles_y) = (width.div_ceil(DENOISE_TILE), height.div_ceil(DENOISE_TILE));
    let raw = &*out;
    scratch.filter.clear();
    scratch.filter.resize(tiles_x * tiles_y * channels, false);
    scratch.filter.par_chunks_mut(channels).enumerate().for_each(|(t, filter)| {
        let (tx, ty) = (t % tiles_x, t / tiles_x);
        let pixels = (ty * DENOISE_TILE..((ty + 1) * DENOISE_TILE).min(height))
            .flat_map(|y| (tx * DENOISE_TILE..((tx + 1) * DENOISE_TILE).min(width)).map(move |x| y * width + x))
            .filter(|&i| surfaces[i].is_hit());
        for (c, f) in filter.iter_mut().enumerate() {
            *f = !tile_agrees(pixels.clone().map(|i| raw[i * channels + c]));
        }
    });
    if !scratch.filter.iter().any(|&f| f) {
        return;
    }
    let (eye, angle) = (Vec3::from(camera.eye), pixel_angle(camera));
    scratch.raw.clone_from(out);
    let samples = channel_samples(lights, ao);
    let raw = &scratch.raw;
    scratch.sigma.clear();
    scratch.sigma.resize(out.len(), 0.0);
    let filter = &scratch.filter;
    // Only a filtered tile's pixels read their noise (`atrous_pixel` copies the others).
    let filtered = |x: usize, y: usize| {
        let tile = (y / DENOISE_TILE) * tiles_x + x / DENOISE_TILE;
        filter[tile * channels..(tile + 1) * channels].iter().any(|&f| f)
    };
    scratch.sigma.par_chunks_mut(row).enumerate().for_each(|(y, sigma)| {
        let mut behind = samples.clone();
        for x in 0..width {
            if !filtered(x, y) {
                continue;
            }
            if let Some(lengths) = lengths {
                let frames = lengths[y * width + x] + 1;
                for (b, s) in behind.iter_mut().zip(&samples) {
                    *b = s * frames;
                }
            }
            let v = &mut sigma[x * channels..(x + 1) * channels];
            noise_sigma(raw, surfaces, (width, height), (x, y), &behind, v);
        }
    });
    let (filter, sigma) = (&scratch.filter, &scratch.sigma);
    scratch.values.clear();
    scratch.values.resize(out.len(), 0.0);
    {
        let (mut src, mut dst) = (&mut *out, &mut scratch.values);
        for pass in 0..DENOISE_PASSES {
            let step = 1usize << pass;
            let input = &**src;
            dst.par_chunks_mut(row).enumerate().for_each(|(y, values)| {
                for x in 0..width {
                    let i = y * width + x;
                    let tile = (y / DENOISE_TILE) * tiles_x + x / DENOISE_TILE;
                    let footprint = pixel_footprint(Vec3::from(surfaces[i].position), eye, angle);
                    let v = &mut values[x * channels..(x + 1) * channels];
                    let f = &filter[tile * channels..(tile + 1) * channels];
                    let s = &sigma[i * channels..(i + 1) * channels];
                    atrous_pixel(input, surfaces, (width, height), (x, y), step, footprint, (f, s), v);
                }
            });
            std::mem::swap(&mut src, &mut dst);
        }
        // After an odd number of passes the result is in the scratch buffer.
        if DENOISE_PASSES % 2 == 1 {
            std::mem::swap(src, dst);
        }
    }
    let raw = match lengths {
        Some(_) => &scratch.current,
        None => &scratch.raw,
    };
    out.par_chunks_mut(row).enumerate().for_each(|(y, values)| {
        for x in 0..width {
            let tile = (y / DENOISE_TILE) * tiles_x + x / DENOISE_TILE;
            let v = &mut values[x * channels..(x + 1) * channels];
            let f = &filter[tile * channels..(tile + 1) * channels];
            clamp_pixel(raw, surfaces, (width, height), (x, y), f, v);
        }
    });
}
