//! Stage `shadow_denoise` (as `hyrt_cpu::shadow_denoise::shadow_denoise_into`): the
//! stochastic visibility of area lights and ambient occlusion, filtered over the band's
//! surfaces with the WGSL mirrors of [`hyrt_core::kernels::denoise`]
//! (`shaders/shadow_denoise.wgsl`), in the CPU stage's order: each pixel's raw channels,
//! the 8 x 8 tiles that need filtering per channel, each pixel's noise deviation, then
//! [`DENOISE_PASSES`] à-trous passes (ping-pong), the last one clamped to the raw
//! neighbourhood (`shaders/shadow_denoise_stage.wgsl`, one entry point per pass, all in
//! one compute pass).
//!
//! Reads `frame.surfaces`, `frame.shadow`, `scene.lights` (with an emitter light, the
//! emitter table after the records, whose samples the raw channels regenerate:
//! [`crate::buffers::SceneBuffers::lights`]), `scene.ambient_light` (the frame's
//! occlusion), `frame.camera` (the eye), `frame.params`, `frame.slot_params` (`channels`:
//! [`hyrt_core::kernels::denoise::channel_count`]; `emitters`, the table's length) and the pixel's angle, a
//! uniform computed on the host by the CPU stage's own
//! [`hyrt_core::kernels::denoise::pixel_angle`]. Writes `frame.visibility` (`channels` f32
//! per pixel), with the scratch of [`DenoiseBuffers`].
//!
//! The filter reaches [`DENOISE_HALO`] rows past a pixel: a band of a banded frame is
//! rendered over its rows and that many more on each side ([`crate::band`]).

use hyrt_core::formats::{CameraRecord, MotionRecord, ObjectMap, SurfaceRecord};
use hyrt_core::kernels::denoise::{
    ATROUS_KERNEL, CLAMP_RADIUS, DENOISE_PASSES, DENOISE_TILE, MAX_CHANNELS, NORMAL_SQUARINGS, VALUE_TOLERANCE,
};
use hyrt_core::kernels::soft_shadow::NO_ESTIMATE;
use hyrt_core::kernels::temporal::{
    motion_records, TEMPORAL_MAX_LENGTH, TEMPORAL_NORMAL_COS, TEMPORAL_PLANE_FOOTPRINTS, TEMPORAL_TOLERANCE,
};

use crate::buffers::{FrameBuffers, SceneBuffers};
use crate::gpu_buffer::{storage, upload};
use crate::paging::{paged_source, Table, TablePages};
use crate::shader::{preamble, shader_module, shading_helpers, soft_shadow_wgsl, storage_entry, uniform_entry};
use crate::wgsl::f32_literal;
use crate::{GpuContext, GpuError};

/// Rows past a pixel whose values its filtered value depends on, rounded up: the
/// à-trous taps reach `2 (1 + 2 + 4) = 14` rows, the raw neighbourhood of the noise
/// deviation and the clamp 2 more, and the tiles whose flags the taps read up to
/// `DENOISE_TILE - 1` beyond (19 in all); 24 keeps a margin. A band of a denoised frame
/// is rendered with this many more rows on each side, its first row aligned down to a
/// multiple of [`DENOISE_TILE`] (so that its tiles are the frame's).
pub const DENOISE_HALO: u32 = 24;

// The halo covers the filter's reach (taps, the neighbourhood, a tile).
const _: () = assert!(
    2 * ((1 << DENOISE_PASSES) - 1) + CLAMP_RADIUS as u32 + DENOISE_TILE as u32 - 1 <= DENOISE_HALO,
    "DENOISE_HALO is shorter than the filter's reach"
);

/// The uniform of one pass of the stage (`shaders/shadow_denoise_stage.wgsl`).
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `pixel_angle` | f32 | [`hyrt_core::kernels::denoise::pixel_angle`] of the frame's camera |
/// | 4 | `step` | u32 | the à-trous pass's step (1, 2, 4, ...) |
/// | 8 | `last` | u32 | 1 on the last pass (clamped), else 0 |
/// | 12 | `temporal` | u32 | 1 in a frame of the temporal pass (the noise from the samples of the frames behind each pixel), else 0 |
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DenoiseParams {
    pub pixel_angle: f32,
    pub step: u32,
    pub last: u32,
    pub temporal: u32,
}

impl hyrt_core::formats::wgsl::WgslStruct for DenoiseParams {
    const NAME: &'static str = "DenoiseParams";

    fn fields() -> Vec<hyrt_core::formats::wgsl::Field> {
        use hyrt_core::formats::wgsl::{field_type, Field};
        vec![
            Field {
                name: "pixel_angle",
                ty: field_type::<Self, _>(|r| &r.pixel_angle),
                offset: std::mem::offset_of!(Self, pixel_angle),
            },
            Field { name: "step", ty: field_type::<Self, _>(|r| &r.step), offset: std::mem::offset_of!(Self, step) },
            Field { name: "last", ty: field_type::<Self, _>(|r| &r.last), offset: std::mem::offset_of!(Self, last) },
            Field {
                name: "temporal",
                ty: field_type::<Self, _>(|r| &r.temporal),
                offset: std::mem::offset_of!(Self, temporal),
            },
        ]
    }
}

/// The constants of `shaders/shadow_denoise.wgsl` from their Rust values, then the file:
/// after the shading helpers and [`soft_shadow_wgsl`], in a stage that binds what the
/// file's header names.
pub fn denoise_wgsl() -> String {
    let mut s = String::from("// Generated from hyrt_core::kernels::denoise (gpu-backend/src/shadow_denoise.rs).\n");
    let kernel: Vec<String> = ATROUS_KERNEL.iter().map(|&k| f32_literal(k)).collect();
    s += &format!("const ATROUS_KERNEL = array<f32, {}>({});\n", ATROUS_KERNEL.len(), kernel.join(", "));
    s += &format!("const NORMAL_SQUARINGS: u32 = {NORMAL_SQUARINGS}u;\n");
    s += &format!("const VALUE_TOLERANCE: f32 = {};\n", f32_literal(VALUE_TOLERANCE));
    s += &format!("const CLAMP_RADIUS: i32 = {CLAMP_RADIUS}i;\n");
    s += &format!("const DENOISE_TILE: u32 = {DENOISE_TILE}u;\n");
    s += &format!("const MAX_CHANNELS: u32 = {MAX_CHANNELS}u;\n");
    s += &format!("const NO_ESTIMATE: f32 = {};\n", f32_literal(NO_ESTIMATE));
    s + include_str!("shaders/shadow_denoise.wgsl")
}

/// The uniform of the temporal pass (`shaders/temporal.wgsl`, `temporal`).
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `usable` | u32 | 1 where the history is this scene's with these channels (else the pass copies the raw channels, lengths 0) |
/// | 4 | `motion_count` | u32 | motion records in `motion` |
/// | 8 | `pad` | 2 x u32 | zero |
/// | 16 | `samples` | `4 x vec4<u32>` | per channel, its samples per frame ([`hyrt_core::kernels::denoise::channel_samples`]), channel `c` at `[c / 4][c % 4]` |
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct TemporalParams {
    pub usable: u32,
    pub motion_count: u32,
    pub pad: [u32; 2],
    pub samples: [[u32; 4]; MAX_CHANNELS / 4],
}

const _: () = assert!(MAX_CHANNELS.is_multiple_of(4) && std::mem::size_of::<TemporalParams>() == 16 + 4 * MAX_CHANNELS);

impl TemporalParams {
    /// The parameters of a frame with `samples` per channel and frame, `motion_count`
    /// motion records, its history `usable` or not.
    pub fn new(usable: bool, motion_count: u32, samples: &[u32]) -> TemporalParams {
        let mut p = TemporalParams { usable: usable as u32, motion_count, ..Default::default() };
        for (c, &n) in samples.iter().enumerate().take(MAX_CHANNELS) {
            p.samples[c / 4][c % 4] = n;
        }
        p
    }
}

/// The constants of `shaders/temporal.wgsl` from their Rust values, the [`TemporalParams`]
/// declaration, then the file: after [`denoise_wgsl`], in a stage that binds what the
/// file's header names.
pub fn temporal_wgsl() -> String {
    let mut s = String::from("// Generated from hyrt_core::kernels::temporal (gpu-backend/src/shadow_denoise.rs).\n");
    s += &format!("const TEMPORAL_MAX_LENGTH: u32 = {TEMPORAL_MAX_LENGTH}u;\n");
    s += &format!("const TEMPORAL_NORMAL_COS: f32 = {};\n", f32_literal(TEMPORAL_NORMAL_COS));
    s += &format!("const TEMPORAL_PLANE_FOOTPRINTS: f32 = {};\n", f32_literal(TEMPORAL_PLANE_FOOTPRINTS));
    s += &format!("const TEMPORAL_TOLERANCE: f32 = {};\n", f32_literal(TEMPORAL_TOLERANCE));
    s += &format!(
        "// hyrt_gpu::shadow_denoise::TemporalParams\nstruct TemporalParams {{\n    usable: u32,\n    motion_count: u32,\n    \
         pad0: u32,\n    pad1: u32,\n    samples: array<vec4<u32>, {}>,\n}}\n",
        MAX_CHANNELS / 4
    );
    s + include_str!("shaders/temporal.wgsl")
}

/// The stage's WGSL: the generated records, the shading helpers, the soft-shadow kernels,
/// the [`DenoiseParams`] declaration, [`denoise_wgsl`], [`temporal_wgsl`], then the passes.
pub fn shadow_denoise_wgsl() -> String {
    use hyrt_core::formats::wgsl::WgslStruct;
    format!(
        "{}\n{}\n{}\n{}\n{}\n{}\n{}",
        preamble(),
        shading_helpers(),
        soft_shadow_wgsl(),
        DenoiseParams::declaration()
            .replace("// hyrt_core: DenoiseParams", "// hyrt_gpu::shadow_denoise::DenoiseParams"),
        denoise_wgsl(),
        temporal_wgsl(),
        include_str!("shaders/shadow_denoise_stage.wgsl")
    )
}

/// The scratch of the stage in a frame's buffers ([`FrameBuffers::denoise`]), for bands of
/// `pixels` pixels with `channels` channels each.
pub struct DenoiseBuffers {
    /// `array<f32>`, `channels` per pixel: the raw channels.
    pub raw: wgpu::Buffer,
    /// `array<f32>`, `channels` per pixel: the noise deviations.
    pub sigma: wgpu::Buffer,
    /// `array<f32>`, `channels` per pixel: the other half of the ping-pong.
    pub values: wgpu::Buffer,
    /// `array<u32>`, `channels` per tile: 1 where the tile's channel is filtered.
    pub tiles: wgpu::Buffer,
    /// One uniform [`DenoiseParams`] per à-trous pass.
    pub passes: Vec<wgpu::Buffer>,
}

impl DenoiseBuffers {
    /// The scratch for bands of `width` x `rows` pixels of `channels` channels.
    pub fn new(ctx: &GpuContext, width: u32, rows: u32, channels: u32) -> Result<DenoiseBuffers, GpuError> {
        let values = width as usize * rows as usize * channels as usize;
        let tiles = (width as usize).div_ceil(DENOISE_TILE) * (rows as usize).div_ceil(DENOISE_TILE);
        Ok(DenoiseBuffers {
            raw: storage::<f32>(ctx, "shadow_denoise raw", values)?,
            sigma: storage::<f32>(ctx, "shadow_denoise sigma", values)?,
            values: storage::<f32>(ctx, "shadow_denoise values", values)?,
            tiles: storage::<u32>(ctx, "shadow_denoise tiles", tiles * channels as usize)?,
            passes: (0..DENOISE_PASSES)
                .map(|_| {
                    ctx.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("shadow_denoise pass"),
                        size: std::mem::size_of::<DenoiseParams>() as u64,
                        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                        mapped_at_creation: false,
                    })
                })
                .collect(),
        })
    }

    /// Write the passes' parameters for a frame whose pixel spans `pixel_angle`, `temporal`
    /// if it runs the temporal pass.
    pub fn write_params(&self, ctx: &GpuContext, pixel_angle: f32, temporal: bool) {
        for (pass, buffer) in self.passes.iter().enumerate() {
            let p = DenoiseParams {
                pixel_angle,
                step: 1 << pass,
                last: (pass as u32 + 1 == DENOISE_PASSES) as u32,
                temporal: temporal as u32,
            };
            ctx.queue.write_buffer(buffer, 0, bytemuck::bytes_of(&p));
        }
    }
}

/// One frame's history on the device: its surfaces, its channels after the temporal pass
/// and per pixel the frames behind them.
pub struct HistorySet {
    /// `array<SurfaceRecord>`, one per pixel.
    pub surfaces: wgpu::Buffer,
    /// `array<f32>`, `channels` per pixel.
    pub values: wgpu::Buffer,
    /// `array<u32>`, one per pixel.
    pub lengths: wgpu::Buffer,
    /// Pixels and values the buffers have room for.
    room: (usize, usize),
}

impl HistorySet {
    fn new(ctx: &GpuContext, pixels: usize, values: usize) -> Result<HistorySet, GpuError> {
        Ok(HistorySet {
            surfaces: storage::<SurfaceRecord>(ctx, "shadow_denoise history surfaces", pixels)?,
            values: storage::<f32>(ctx, "shadow_denoise history values", values)?,
            lengths: storage::<u32>(ctx, "shadow_denoise history lengths", pixels)?,
            room: (pixels, values),
        })
    }
}

/// What the backend keeps of the last frame of the temporal pass (as the CPU backend's
/// `hyrt_cpu::shadow_denoise::TemporalHistory`), on the device: two [`HistorySet`]s, the
/// previous frame's, which a frame reads, and the other, which it writes (a band that runs
/// again reads the same history); [`GpuHistory::commit`] swaps them once the frame is done.
/// On the host: the scene, camera, object maps and channel count of the frame the history
/// holds. A frame of another scene or channel count, or the first, starts afresh.
pub struct GpuHistory {
    /// The scene of the history's frame; `None` before any.
    scene: Option<u64>,
    camera: CameraRecord,
    maps: Vec<ObjectMap>,
    channels: u32,
    /// The two sets; `sets[previous]` holds the history.
    sets: [HistorySet; 2],
    previous: usize,
    /// What the frame being rendered becomes at its commit.
    pending: Option<(u64, CameraRecord, Vec<ObjectMap>, u32)>,
    /// Uniform `CameraRecord`: the history's camera.
    pub prev_camera: wgpu::Buffer,
    /// Uniform [`TemporalParams`].
    pub params: wgpu::Buffer,
    /// `array<MotionRecord>`, one per object: their motion since the history's frame.
    pub motion: wgpu::Buffer,
}

impl GpuHistory {
    /// No history yet.
    pub fn new(ctx: &GpuContext) -> Result<GpuHistory, GpuError> {
        let uniform = |label: &str, size: usize| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        Ok(GpuHistory {
            scene: None,
            camera: bytemuck::Zeroable::zeroed(),
            maps: Vec::new(),
            channels: 0,
            sets: [HistorySet::new(ctx, 1, 1)?, HistorySet::new(ctx, 1, 1)?],
            previous: 0,
            pending: None,
            prev_camera: uniform("shadow_denoise history camera", std::mem::size_of::<CameraRecord>()),
            params: uniform("shadow_denoise temporal", std::mem::size_of::<TemporalParams>()),
            motion: upload(ctx, "shadow_denoise motion", &[MotionRecord::NONE]),
        })
    }

    /// Get ready for a frame of scene `scene` with the objects' maps `maps` now, seen from
    /// `camera`, with `samples` per channel and frame: whether the history counts (the
    /// CPU's rule: the same scene and channel count, a frame before), the objects' motion
    /// since it ([`motion_records`]), room for this frame in the set it writes.
    pub fn prepare(
        &mut self,
        ctx: &GpuContext,
        scene: u64,
        maps: Vec<ObjectMap>,
        camera: &CameraRecord,
        samples: &[u32],
    ) -> Result<(), GpuError> {
        let channels = samples.len() as u32;
        let usable = self.scene == Some(scene) && self.channels == channels;
        let motion = match usable {
            true => motion_records(&self.maps, &maps),
            false => Vec::new(),
        };
        self.motion = upload(ctx, "shadow_denoise motion", &motion);
        let params = TemporalParams::new(usable, motion.len() as u32, samples);
        ctx.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        ctx.queue.write_buffer(&self.prev_camera, 0, bytemuck::bytes_of(&self.camera));
        let pixels = camera.width as usize * camera.height as usize;
        let values = pixels * channels as usize;
        let next = &mut self.sets[1 - self.previous];
        if next.room.0 < pixels || next.room.1 < values {
            *next = HistorySet::new(ctx, pixels, values)?;
        }
        self.pending = Some((scene, *camera, maps, channels));
        Ok(())
    }

    /// The set the frame reads (the previous frame's) and the one it writes.
    pub fn sets(&self) -> (&HistorySet, &HistorySet) {
        (&self.sets[self.previous], &self.sets[1 - self.previous])
    }

    /// The frame [`GpuHistory::prepare`]d is done: it becomes the history.
    pub fn commit(&mut self) {
        if let Some((scene, camera, maps, channels)) = self.pending.take() {
            (self.scene, self.camera, self.maps, self.channels) = (Some(scene), camera, maps, channels);
            self.previous = 1 - self.previous;
        }
    }
}

/// The stage's bindings (`shaders/shadow_denoise_stage.wgsl`).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Binding {
    Params = 0,
    Camera = 1,
    SlotParams = 2,
    AmbientLight = 3,
    Denoise = 4,
    Surfaces = 5,
    Shadow = 6,
    Lights = 7,
    RawOut = 8,
    Raw = 9,
    SigmaOut = 10,
    Sigma = 11,
    TilesOut = 12,
    Tiles = 13,
    ValuesIn = 14,
    ValuesOut = 15,
    PrevCamera = 16,
    Temporal = 17,
    Motion = 18,
    PrevSurfaces = 19,
    PrevValues = 20,
    PrevLengths = 21,
    AccumulatedOut = 22,
    LengthsOut = 23,
    Lengths = 24,
}

impl Binding {
    fn entry(self) -> wgpu::BindGroupLayoutEntry {
        use Binding::*;
        let b = self as u32;
        match self {
            Params | Camera | SlotParams | AmbientLight | Denoise | PrevCamera | Temporal => uniform_entry(b),
            RawOut | SigmaOut | TilesOut | ValuesOut | AccumulatedOut | LengthsOut => storage_entry(b, false),
            _ => storage_entry(b, true),
        }
    }
}

/// One pass: its entry point's pipeline over the bindings it uses.
struct Pass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    bindings: &'static [Binding],
}

/// The `shadow_denoise` stage: one pipeline per pass.
pub struct ShadowDenoiseStage {
    /// The lights' pages it was compiled for ([`TablePages::lights_only`]).
    pub pages: TablePages,
    raw: Pass,
    temporal: Pass,
    tiles: Pass,
    sigma: Pass,
    atrous: Pass,
}

impl ShadowDenoiseStage {
    /// Compile the stage's pipelines.
    pub fn new(ctx: &GpuContext) -> Self {
        Self::paged(ctx, TablePages::default())
    }

    /// Compile the stage's pipelines for lights in the pages `pages` gives them
    /// ([`TablePages::lights_only`]; none by default).
    pub fn paged(ctx: &GpuContext, pages: TablePages) -> Self {
        use Binding::*;
        let module = shader_module(ctx, "shadow_denoise", &paged_source(&shadow_denoise_wgsl(), pages));
        let light_pages = pages.layout_entries(&[Table::Lights]);
        let pass = |entry: &str, bindings: &'static [Binding]| {
            let label = format!("shadow_denoise {entry}");
            let mut entries: Vec<_> = bindings.iter().map(|b| b.entry()).collect();
            if bindings.contains(&Lights) {
                entries.extend_from_slice(&light_pages);
            }
            let layout = ctx
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(&label), entries: &entries });
            let pipeline =
                module.compute_pipeline(&label, entry, &module.pipeline_layout(&label, &[(&layout, &entries)]), &[]);
            Pass { pipeline, layout, bindings }
        };
        ShadowDenoiseStage {
            pages,
            raw: pass("raw_pass", &[Params, SlotParams, AmbientLight, Surfaces, Shadow, Lights, RawOut]),
            temporal: pass(
                "temporal_pass",
                &[
                    Params,
                    Camera,
                    SlotParams,
                    Denoise,
                    PrevCamera,
                    Temporal,
                    Surfaces,
                    Raw,
                    Motion,
                    PrevSurfaces,
                    PrevValues,
                    PrevLengths,
                    AccumulatedOut,
                    LengthsOut,
                ],
            ),
            tiles: pass("tiles_pass", &[Params, SlotParams, Surfaces, Raw, TilesOut]),
            sigma: pass(
                "sigma_pass",
                &[Params, SlotParams, AmbientLight, Denoise, Surfaces, Lights, Raw, Lengths, SigmaOut],
            ),
            atrous: pass(
                "atrous_pass",
                &[Params, Camera, SlotParams, Denoise, Surfaces, Raw, Sigma, Tiles, ValuesIn, ValuesOut],
            ),
        }
    }

    /// Record the stage over the frame's band: `frame.visibility` from `frame.surfaces`
    /// and `frame.shadow` (the passes' parameters written by
    /// [`DenoiseBuffers::write_params`]); with `history` ([`GpuHistory::prepare`]d for
    /// this frame, which must be one band), the temporal pass between the raw channels and
    /// the filter: the filter's tiles and noise from the accumulated channels (written to
    /// the history's next set with their lengths, the frame's surfaces copied beside
    /// them), its clamp from this frame's raw ones.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        history: Option<&GpuHistory>,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let d = frame.denoise.as_ref().expect("a denoised frame's buffers have the stage's scratch");
        let sets = history.map(|h| h.sets());
        // What a pass reads as `raw`, and as `lengths` (a stand-in without the temporal pass).
        let (filter_raw, lengths) = match sets {
            Some((_, next)) => (&next.values, &next.lengths),
            None => (&d.raw, &d.tiles),
        };
        let group =
            |pass: &Pass, uniform: &wgpu::Buffer, raw: &wgpu::Buffer, input: &wgpu::Buffer, output: &wgpu::Buffer| {
                use Binding::*;
                let mut entries: Vec<wgpu::BindGroupEntry> = pass
                    .bindings
                    .iter()
                    .map(|&b| {
                        let h = || history.expect("the temporal pass has a history");
                        let hs = || sets.expect("the temporal pass has a history");
                        let buffer = match b {
                            Params => &frame.params,
                            Camera => &frame.camera,
                            SlotParams => &frame.slot_params,
                            AmbientLight => &scene.ambient_light,
                            Denoise => uniform,
                            Surfaces => &frame.surfaces,
                            Shadow => &frame.shadow,
                            Lights => scene.lights.first(),
                            RawOut => &d.raw,
                            Raw => raw,
                            SigmaOut | Sigma => &d.sigma,
                            TilesOut | Tiles => &d.tiles,
                            ValuesIn => input,
                            ValuesOut => output,
                            PrevCamera => &h().prev_camera,
                            Temporal => &h().params,
                            Motion => &h().motion,
                            PrevSurfaces => &hs().0.surfaces,
                            PrevValues => &hs().0.values,
                            PrevLengths => &hs().0.lengths,
                            AccumulatedOut => &hs().1.values,
                            LengthsOut => &hs().1.lengths,
                            Lengths => lengths,
                        };
                        wgpu::BindGroupEntry { binding: b as u32, resource: buffer.as_entire_binding() }
                    })
                    .collect();
                if pass.bindings.contains(&Lights) {
                    entries.extend(scene.further_pages(&[Table::Lights]));
                }
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("shadow_denoise"),
                    layout: &pass.layout,
                    entries: &entries,
                })
            };
        let first = &d.passes[0];
        let (width, rows) = (frame.width, frame.band.rows);
        let tile = DENOISE_TILE as u32;
        let grid = |w: u32, h: u32| (w.div_ceil(crate::shader::TILE), h.div_ceil(crate::shader::TILE));
        // Ping-pong from the raw (or accumulated) channels, ending in the frame's visibility.
        let mut groups = vec![(&self.raw, group(&self.raw, first, &d.raw, &d.raw, &d.raw), grid(width, rows))];
        if let Some((_, next)) = sets {
            // The history keeps this frame's surfaces.
            let bytes = (width as usize * rows as usize * std::mem::size_of::<SurfaceRecord>()) as u64;
            encoder.copy_buffer_to_buffer(&frame.surfaces, 0, &next.surfaces, 0, bytes);
            groups.push((&self.temporal, group(&self.temporal, first, &d.raw, &d.raw, &d.raw), grid(width, rows)));
        }
        groups.extend([
            (
                &self.tiles,
                group(&self.tiles, first, filter_raw, &d.raw, &d.raw),
                grid(width.div_ceil(tile), rows.div_ceil(tile)),
            ),
            (&self.sigma, group(&self.sigma, first, filter_raw, &d.raw, &d.raw), grid(width, rows)),
        ]);
        let targets = [&frame.visibility, &d.values];
        let mut input = filter_raw;
        for pass in 0..DENOISE_PASSES as usize {
            // The last pass writes the visibility: start there when the count is odd.
            let output = targets[(DENOISE_PASSES as usize - 1 - pass) % 2];
            // The clamp reads this frame's raw channels.
            groups.push((&self.atrous, group(&self.atrous, &d.passes[pass], &d.raw, input, output), grid(width, rows)));
            input = output;
        }
        let mut cpass = crate::timing::begin_timed_pass(encoder, "shadow_denoise", timing);
        for (pass, group, (x, y)) in &groups {
            cpass.set_pipeline(&pass.pipeline);
            cpass.set_bind_group(0, group, &[]);
            cpass.dispatch_workgroups(*x, *y, 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stage's WGSL parses, validates and uses only exact operations (the stage's
    /// `shader_module` checks this in debug builds alone).
    #[test]
    fn shadow_denoise_uses_only_exact_operations() {
        assert_eq!(crate::shader::inexact_operations(&shadow_denoise_wgsl()), Ok(Vec::new()));
    }
}
