//! What a frame is asked for: the per-frame options ([`FrameOptions`]), which the plan
//! reads ([`crate::plan::FramePlan::new`]) and every backend takes with the prepared scene.
//! Re-exported by [`crate::frame`]. What a frame under them returns is the plan's to say
//! (`FrameOptions::returns`, in [`crate::plan`], which stands above these options).

use crate::error::RenderError;
use crate::kernels::bounce::MAX_DEPTH_LIMIT;
use crate::kernels::soft_shadow::MAX_SAMPLES;

/// Per-frame settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameOptions {
    /// Composition weight of the ray-traced image in [0, 1] (paper 3.5):
    /// final = (1 - weight) * raster + weight * rt on ray-traced pixels.
    pub weight: f32,
    /// Return every stage's output in the [`Frame`](crate::frame::Frame) (for `--dump`, conformance).
    /// When false (the default: what a display loop needs), the frame holds only the
    /// final image (what the plan's `FrameBuffer::always_returned` names),
    /// and the G-buffer if [`FrameOptions::keep_gbuffer`] asks for it: the GPU backend then
    /// reads back one combined buffer per frame.
    pub stage_outputs: bool,
    /// Return the G-buffer in a frame without [`FrameOptions::stage_outputs`] (which
    /// returns it anyway): for picking (`hyrt view`) and the G-buffer's views. False by
    /// default: a frame for display (`hyrt render`) needs the final image alone, and the
    /// CPU backend's fused executor then writes the G-buffer only into each raster tile's
    /// scratch, never whole-image (`hyrt_cpu::memory`). The frame's counts do not depend
    /// on it. The GPU backend reads the G-buffer back either way (its statistics count it)
    /// and empties it at the end of a frame that did not ask for it.
    pub keep_gbuffer: bool,
    /// The deepest bounce of reflection and refraction rays traced from ray-traced
    /// mirrors and glass ([`crate::kernels::bounce`]), at most [`MAX_DEPTH_LIMIT`];
    /// 0 traces none (the paper's frame: shadow rays only).
    pub max_depth: u32,
    /// Where `reconstruction` takes the primary hits' barycentrics from.
    pub barycentrics: PrimaryBarycentrics,
    /// Shadow rays per surface for each area light (quad, sphere, sun), in `1..=`
    /// [`MAX_SAMPLES`]; point, spot and directional lights keep one
    /// ([`crate::kernels::soft_shadow`]). Default [`DEFAULT_SHADOW_SAMPLES`].
    pub shadow_samples: u32,
    /// Ambient-occlusion rays per surface, at most [`MAX_SAMPLES`]; 0 (the default) traces
    /// none.
    pub ao_samples: u32,
    /// How far an ambient-occlusion ray looks (scene units, > 0); `None`: the scene's
    /// extent times [`DEFAULT_AO_RADIUS_FRACTION`].
    pub ao_radius: Option<f32>,
    /// The frame's number in a sequence: it seeds the sample streams of area lights and
    /// occlusion, so that following frames see independent samples. Default 0.
    pub frame_index: u32,
    /// Filter the stochastic visibility of area lights and ambient occlusion
    /// (`shadow_denoise`, [`crate::kernels::denoise`]) before shading; true by default.
    /// Without it the shaders average the raw samples.
    pub denoise: bool,
    /// Frames follow each other (an animation, a viewer, `--frames`): the denoiser also
    /// blends each pixel with what the previous frame the backend rendered saw of the
    /// same surface point, reprojected through the previous camera and the objects'
    /// previous transforms ([`crate::kernels::temporal`]). Each frame then needs its own
    /// [`FrameOptions::frame_index`] for its samples to add anything. Only where the frame
    /// denoises; false by default (a frame on its own depends on nothing before it).
    pub temporal: bool,
}

/// Default [`FrameOptions::shadow_samples`]: four rays per surface and area light.
pub const DEFAULT_SHADOW_SAMPLES: u32 = 4;

/// Default ambient-occlusion radius as a fraction of the scene's extent (the diagonal of
/// its bounds): a twentieth, about 2 m in Sponza's atrium.
pub const DEFAULT_AO_RADIUS_FRACTION: f32 = 0.05;

/// The barycentrics `reconstruction` rebuilds primary hit points from (paper eq. 1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum PrimaryBarycentrics {
    /// The raster's: interpolated at the pixel centre in the snapped triangle (vertices on
    /// a 1/256-pixel grid), so hit points carry the snapping error (about 7e-6 of the
    /// scene's diagonal on the teaser). Cheaper by a few percent of the frame.
    Raster,
    /// The pixel's camera ray intersected with the triangle the raster found, by the
    /// watertight kernel ([`crate::kernels::reconstruction::reintersected_barycentrics`]):
    /// hit points as exact as a ray tracer's, visibility still the raster's. Where the ray
    /// misses that triangle (a pixel centre the snapped triangle covers and the exact one
    /// does not, at its edges) the raster's barycentrics are kept. Both backends,
    /// bit-identical (the GPU's `reconstruction` mirrors the camera ray and the test).
    /// The default: exact primary hits cost under a tenth of the CPU's fused frame.
    #[default]
    Reintersected,
}

impl PrimaryBarycentrics {
    /// Lower-case name (CLI, reports).
    pub fn name(self) -> &'static str {
        match self {
            PrimaryBarycentrics::Raster => "raster",
            PrimaryBarycentrics::Reintersected => "reintersected",
        }
    }
}

impl Default for FrameOptions {
    /// Weight 1 (ray-traced objects shaded by the tracer alone), no stage outputs (the
    /// final image alone), exact primary hits ([`PrimaryBarycentrics::Reintersected`]),
    /// reflection and refraction to [`crate::kernels::bounce::DEFAULT_MAX_DEPTH`]
    /// bounces (a scene without ray-traced mirrors or glass plans none; `max_depth: 0`
    /// gives the paper's frame, shadow rays only).
    fn default() -> Self {
        FrameOptions {
            weight: 1.0,
            stage_outputs: false,
            keep_gbuffer: false,
            max_depth: crate::kernels::bounce::DEFAULT_MAX_DEPTH,
            barycentrics: PrimaryBarycentrics::Reintersected,
            shadow_samples: DEFAULT_SHADOW_SAMPLES,
            ao_samples: 0,
            ao_radius: None,
            frame_index: 0,
            denoise: true,
            temporal: false,
        }
    }
}

impl FrameOptions {
    /// The default options with every stage's output returned (`--dump`, tests).
    pub fn with_stage_outputs() -> Self {
        FrameOptions { stage_outputs: true, ..FrameOptions::default() }
    }

    /// Check the options: the weight is a number in [0, 1]. [`FramePlan::new`](crate::plan::FramePlan::new) calls
    /// this, so every backend validates options in one place.
    pub fn validate(&self) -> Result<(), RenderError> {
        if !(0.0..=1.0).contains(&self.weight) {
            return Err(RenderError::InvalidOptions(format!(
                "composition weight must be in [0, 1], got {}",
                self.weight
            )));
        }
        if self.max_depth > MAX_DEPTH_LIMIT {
            return Err(RenderError::InvalidOptions(format!(
                "max depth must be at most {MAX_DEPTH_LIMIT}, got {}",
                self.max_depth
            )));
        }
        if !(1..=MAX_SAMPLES).contains(&self.shadow_samples) {
            return Err(RenderError::InvalidOptions(format!(
                "shadow samples must be in 1..={MAX_SAMPLES}, got {}",
                self.shadow_samples
            )));
        }
        if self.ao_samples > MAX_SAMPLES {
            return Err(RenderError::InvalidOptions(format!(
                "ambient-occlusion samples must be at most {MAX_SAMPLES}, got {}",
                self.ao_samples
            )));
        }
        if let Some(r) = self.ao_radius {
            if !(r > 0.0 && r.is_finite()) {
                return Err(RenderError::InvalidOptions(format!(
                    "ambient-occlusion radius must be finite and > 0, got {r}"
                )));
            }
        }
        Ok(())
    }
}
