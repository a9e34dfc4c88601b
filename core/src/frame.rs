//! What a backend takes and gives: [`FrameOptions`] in, [`Frame`] out (every
//! stage's output, for `--dump` and conformance), with [`FrameStats`]; and the
//! [`Backend`] trait both backends implement.

use crate::bvh::Bvh;
use crate::formats::{CameraRecord, GBufferTexel, RayRecord, SurfaceRecord, RAY_KIND_COUNT};
use crate::geometry::WorldGeometry;
use crate::stage::Stage;

/// [`Frame::shadow`]: no shadow ray was traced for this (pixel, light): the pixel
/// has no primary hit, or the light is behind the surface (it cannot contribute).
pub const SHADOW_NO_RAY: u8 = 0;
/// [`Frame::shadow`]: a shadow ray was traced and reached the light.
pub const SHADOW_LIT: u8 = 1;
/// [`Frame::shadow`]: a shadow ray was traced and something blocked it.
pub const SHADOW_OCCLUDED: u8 = 2;

/// A scene ready to render: world-space tables and the BVH over all of them,
/// built once and shared by every frame and by both backends.
#[derive(Clone, Debug)]
pub struct PreparedScene {
    pub geometry: WorldGeometry,
    pub bvh: Bvh,
    /// Time the `bvh_build` stage took, in milliseconds.
    pub bvh_build_ms: f64,
    /// Unique per prepared scene (clones share it: same content): backends that keep the scene's
    /// tables on a device key their caches by it. Fields are public for reading;
    /// build with [`PreparedScene::new`] so the id stays unique.
    id: u64,
}

impl PreparedScene {
    /// A prepared scene with a fresh id.
    pub fn new(geometry: WorldGeometry, bvh: Bvh, bvh_build_ms: f64) -> Self {
        static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        let id = NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        PreparedScene { geometry, bvh, bvh_build_ms, id }
    }

    /// The id device caches are keyed by. Mutating the public fields after a
    /// backend has seen the scene is not supported: prepare a new scene instead.
    pub fn id(&self) -> u64 {
        self.id
    }
}

/// Per-frame settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameOptions {
    /// Composition weight of the ray-traced image in [0, 1] (paper 3.5):
    /// final = (1 - weight) * raster + weight * rt on ray-traced pixels.
    pub weight: f32,
    /// Return every stage's output in the [`Frame`] (for `--dump`, conformance).
    /// When false, a backend may return only the final image, the G-buffer and the
    /// counts: the GPU backend then reads back one combined buffer per frame.
    pub stage_outputs: bool,
}

impl Default for FrameOptions {
    fn default() -> Self {
        FrameOptions { weight: 1.0, stage_outputs: true }
    }
}

/// Why a frame could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("invalid frame options: {0}")]
    InvalidOptions(String),
    #[error("invalid camera: {0}")]
    InvalidCamera(String),
    /// The backend's device failed (GPU: no adapter, device lost, out of memory, ...).
    #[error(transparent)]
    Backend(Box<dyn std::error::Error + Send + Sync>),
}

/// Milliseconds one stage took.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageTime {
    pub stage: Stage,
    pub ms: f64,
}

/// Counts and times of one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameStats {
    pub width: u32,
    pub height: u32,
    /// Pixels with a primary hit (any object).
    pub covered_pixels: u64,
    /// Pixels whose primary hit is a ray-traced object: the paper's "valid rays" (Table 2).
    pub ray_traced_pixels: u64,
    /// Pixels whose primary hit is a rasterized object.
    pub raster_pixels: u64,
    /// Rays in the ray list, per `RAY_KIND_*`.
    pub rays_per_kind: [u64; RAY_KIND_COUNT],
    /// Shadow rays that found an occluder.
    pub occluded_shadow_rays: u64,
    /// Worker threads the backend used.
    pub threads: usize,
    /// Milliseconds per stage, in execution order (`bvh_build` is per scene and
    /// reported from [`PreparedScene::bvh_build_ms`]).
    pub stage_ms: Vec<StageTime>,
}

impl FrameStats {
    /// Time of one stage, if it ran.
    pub fn ms(&self, stage: Stage) -> Option<f64> {
        self.stage_ms.iter().find(|s| s.stage == stage).map(|s| s.ms)
    }
    /// Sum of the per-frame stages (everything but `bvh_build`).
    pub fn frame_ms(&self) -> f64 {
        self.stage_ms.iter().filter(|s| s.stage != Stage::BvhBuild).map(|s| s.ms).sum()
    }
}

/// Every stage's output for one frame. Images are linear RGBA, row-major, row 0 on top.
#[derive(Clone, Debug, Default)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// `visibility_raster`: one texel per pixel.
    pub gbuffer: Vec<GBufferTexel>,
    /// `reconstruction`: one record per pixel.
    pub surfaces: Vec<SurfaceRecord>,
    /// `compaction`: the shadow-ray list, light-major then pixel order.
    pub rays: Vec<RayRecord>,
    /// `shadow_rays`: one per ray, 1 = occluded, 0 = reached the light.
    pub occluded: Vec<u32>,
    /// Per pixel and light (`(y * width + x) * lights + light`): `SHADOW_*`.
    pub shadow: Vec<u8>,
    /// `raster_shading`: rasterized objects (and ray-traced ones when weight < 1).
    pub raster: Vec<[f32; 4]>,
    /// `rt_shading`: ray-traced objects only; alpha 1 where shaded, 0 elsewhere.
    pub rt: Vec<[f32; 4]>,
    /// `composition`: the final image.
    pub final_image: Vec<[f32; 4]>,
    pub stats: FrameStats,
}

/// A renderer of hybrid frames. Both backends implement it over the same
/// [`PreparedScene`] and formats, so their outputs compare stage by stage.
pub trait Backend {
    /// Short name for reports ("cpu", "gpu").
    fn name(&self) -> &str;
    /// Render one frame of `scene` seen by `camera` into `frame`, reusing its
    /// buffers: a frame of the same size renders without allocating. Every field of
    /// `frame` is overwritten.
    fn render_into(
        &mut self,
        scene: &PreparedScene,
        camera: &CameraRecord,
        options: &FrameOptions,
        frame: &mut Frame,
    ) -> Result<(), RenderError>;

    /// Render one frame into new buffers.
    fn render(
        &mut self,
        scene: &PreparedScene,
        camera: &CameraRecord,
        options: &FrameOptions,
    ) -> Result<Frame, RenderError> {
        let mut frame = Frame::default();
        self.render_into(scene, camera, options, &mut frame)?;
        Ok(frame)
    }
}
