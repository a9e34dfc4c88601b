//! The stages of a hybrid frame. Each has exactly one name, used for the module
//! in each backend, the timing label in [`crate::formats`]' frame statistics,
//! the `--dump` file names and the test names.

/// One stage of the pipeline, in execution order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Stage {
    /// Build the BVH over the whole scene (once per scene, not per frame).
    BvhBuild,
    /// Rasterize every object into the G-buffer: barycentrics, depth, ids, flags (paper 3.2).
    VisibilityRaster,
    /// Rebuild world-space hit points and normals from barycentrics (paper eq. 1).
    Reconstruction,
    /// Compact active (pixel, light) pairs into the shadow-ray list (paper 3.3).
    Compaction,
    /// Trace the shadow-ray list through the BVH, any hit with early exit.
    ShadowRays,
    /// Filter the stochastic visibility of area lights and ambient occlusion over the
    /// visibility buffer's surfaces (issue 38: an edge-aware à-trous wavelet filter,
    /// [`crate::kernels::denoise`]); frames without area lights or occlusion skip it.
    ShadowDenoise,
    /// Spawn the reflection and refraction rays of the surfaces that bounce into the
    /// next depth's ray list (compaction again, over the surfaces' two lobes).
    SecondaryRays,
    /// Trace a secondary ray list through the BVH, closest hit, and rebuild the surfaces
    /// hit from their barycentrics (paper eq. 1 again).
    BounceTrace,
    /// Shade a bounce's hits (misses see the environment: the default sky or the scene's
    /// map) and gather their children's radiance, deepest bounce first.
    BounceShading,
    /// Shade the pixels of ray-traced objects (paper 3.3).
    RtShading,
    /// Shade the pixels of rasterized objects with an ordinary shader (paper 3.4).
    RasterShading,
    /// Weighted mean of the raster and ray-traced images (paper 3.5).
    Composition,
}

impl Stage {
    /// Every stage, in execution order.
    pub const ALL: [Stage; 12] = [
        Stage::BvhBuild,
        Stage::VisibilityRaster,
        Stage::Reconstruction,
        Stage::Compaction,
        Stage::ShadowRays,
        Stage::ShadowDenoise,
        Stage::SecondaryRays,
        Stage::BounceTrace,
        Stage::BounceShading,
        Stage::RtShading,
        Stage::RasterShading,
        Stage::Composition,
    ];

    /// The name of the stage's step at bounce `depth`: its [`Stage::name`] for the primary
    /// hits (depth 0), with `{depth}` after it for a bounce (`compaction{2}`): frame tables,
    /// `frame.json`, errors.
    pub fn label_at(self, depth: u32) -> String {
        match depth {
            0 => self.name().to_string(),
            d => format!("{}{{{d}}}", self.name()),
        }
    }

    /// The stage's one name (snake case), as used by modules, timings and tests.
    pub const fn name(self) -> &'static str {
        match self {
            Stage::BvhBuild => "bvh_build",
            Stage::VisibilityRaster => "visibility_raster",
            Stage::Reconstruction => "reconstruction",
            Stage::Compaction => "compaction",
            Stage::ShadowRays => "shadow_rays",
            Stage::ShadowDenoise => "shadow_denoise",
            Stage::SecondaryRays => "secondary_rays",
            Stage::BounceTrace => "bounce_trace",
            Stage::BounceShading => "bounce_shading",
            Stage::RtShading => "rt_shading",
            Stage::RasterShading => "raster_shading",
            Stage::Composition => "composition",
        }
    }
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
