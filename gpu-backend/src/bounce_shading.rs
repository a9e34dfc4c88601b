//! Stage `bounce_shading` on the GPU: the radiance each ray of bounce `d` brings back to
//! its parent, deepest bounce first, each ray adding its children's in a fixed order:
//! bit for bit `hyrt_cpu::bounce_shading` (per ray
//! [`hyrt_core::kernels::bounce::shade_secondary_hit`]: the environment on a miss, the
//! bouncing shader on mirrors and glass, the ray-traced shader on other ray-traced
//! objects, the raster shader on rasterized ones).
//!
//! Reads the depth's rays, count (indirect dispatch), hits, surfaces and shadow codes;
//! unless it is the plan's deepest bounce, the next depth's links and radiance; objects,
//! triangles, lights, the scene's environment. Writes one linear RGBA value per ray.
//! Also home of the WGSL the radiance-gathering stages share (this one and `rt_shading`
//! with bounces).

use hyrt_core::kernels::bounce::{SKY_GROUND, SKY_HORIZON, SKY_ZENITH};
use hyrt_core::kernels::environment::{ATAN_SERIES, INV_TWO_PI, TAN_PI_8};

use crate::buffers::{FrameBuffers, SceneBuffers};
use crate::rt_shading::{
    bind_buffers, compute_pipeline, f32_literal, storage_entry, surface_shading_source, uniform_entry,
};
use crate::secondary_rays::bounce_wgsl;
use crate::shadow_rays::ray_wgsl;
use crate::GpuContext;

/// The WGSL of a stage that gathers what bouncing surfaces' lobes see: the shading
/// stages' sources ([`surface_shading_source`]), `ray.wgsl`, `bounce.wgsl`,
/// `bounce_radiance.wgsl`, then `stage`.
pub(crate) fn radiance_source(stage: &str) -> String {
    surface_shading_source(&format!(
        "{}\n{}\n{}\n{stage}",
        ray_wgsl(),
        bounce_wgsl(),
        include_str!("shaders/bounce_radiance.wgsl")
    ))
}

/// The constants of `shaders/environment.wgsl` from their Rust values, then the file.
fn environment_wgsl() -> String {
    let vec3 = |name: &str, v: [f32; 3]| {
        format!(
            "const {name}: vec3<f32> = vec3<f32>({}, {}, {});\n",
            f32_literal(v[0]),
            f32_literal(v[1]),
            f32_literal(v[2])
        )
    };
    let series: Vec<String> = ATAN_SERIES.iter().map(|&c| f32_literal(c)).collect();
    let mut s = String::from(
        "// Generated from hyrt_core::kernels::{bounce, environment} (gpu-backend/src/bounce_shading.rs).\n",
    );
    s += &format!("const ATAN_SERIES = array<f32, {}>({});\n", ATAN_SERIES.len(), series.join(", "));
    s += &format!("const TAN_PI_8: f32 = {};\n", f32_literal(TAN_PI_8));
    s += &format!("const INV_TWO_PI: f32 = {};\n", f32_literal(INV_TWO_PI));
    s += &vec3("SKY_ZENITH", SKY_ZENITH);
    s += &vec3("SKY_HORIZON", SKY_HORIZON);
    s += &vec3("SKY_GROUND", SKY_GROUND);
    s + include_str!("shaders/environment.wgsl")
}

/// The `bounce_shading` stage: one pipeline.
pub struct BounceShadingStage {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl BounceShadingStage {
    pub fn new(ctx: &GpuContext) -> Self {
        let source =
            radiance_source(&format!("{}\n{}", environment_wgsl(), include_str!("shaders/bounce_shading.wgsl")));
        let mut entries = vec![uniform_entry(0), uniform_entry(1)];
        entries.extend((2..=9).map(|i| storage_entry(i, true)));
        entries.push(uniform_entry(10));
        entries.extend((11..=13).map(|i| storage_entry(i, true)));
        entries.push(storage_entry(14, false));
        let (pipeline, layout) = compute_pipeline(ctx, "bounce_shading", &source, &entries);
        BounceShadingStage { pipeline, layout }
    }

    /// Shade the rays of `frame.bounces[depth - 1]`, gathering from depth `depth + 1`
    /// unless `last`.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneBuffers,
        frame: &FrameBuffers,
        depth: u32,
        last: bool,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) {
        let b = &frame.bounces[depth as usize - 1];
        let (links, child_radiance) = match last {
            true => (&frame.empty, &frame.empty),
            false => {
                let c = &frame.bounces[depth as usize];
                (&c.links, &c.radiance)
            }
        };
        let bind_group = bind_buffers(
            ctx,
            "bounce_shading",
            &self.layout,
            &[
                &frame.params,
                &b.list,
                &b.rays,
                &b.ray_count,
                &b.hits,
                &b.surfaces,
                &b.shadow,
                &scene.objects,
                &scene.triangles,
                &scene.lights,
                &scene.environment,
                &scene.environment_texels,
                links,
                child_radiance,
                &b.radiance,
            ],
        );
        crate::rt_shading::encode_list_pass(
            encoder,
            "bounce_shading",
            &self.pipeline,
            &bind_group,
            &b.ray_count,
            timing,
        );
    }
}
