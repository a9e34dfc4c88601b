//! Local variants of pipeline steps, applied to the stages' outputs without changing
//! the pipeline: barycentrics quantized to 16-bit unorm before reconstruction, and
//! shadow-ray origins offset by other methods than the pipeline's error-bound one.

use glam::Vec3;
use hyrt_core::formats::{GBufferTexel, LightRecord, RayRecord, SurfaceRecord, LIGHT_DIRECTIONAL};
use hyrt_core::kernels::ray::{offset_ray_origin, offset_ray_origin_integer_ulps};
use hyrt_cpu::compaction::SHADOW_T_MAX_POINT;
use rayon::prelude::*;

/// Largest code of a 16-bit unorm.
pub const UNORM16_MAX: f32 = 65535.0;

/// Bound on `|quantize_unorm16(x) - x|` for `x` in [0, 1]: half a quantization step
/// (round to nearest) plus the f32 rounding of `x * 65535` and of `q / 65535` (one
/// unit roundoff of a value below 1 each, 2^-24; 2^-23 covers both).
pub const UNORM16_MAX_ERROR: f32 = 0.5 / UNORM16_MAX + f32::EPSILON;

/// Round `x` (clamped to [0, 1]; NaN gives 0) to the nearest 16-bit unorm code and back,
/// as a G-buffer storing barycentrics in `unorm16x2` does (Falcor's 64-bit `HitInfo`).
#[inline]
pub fn quantize_unorm16(x: f32) -> f32 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    (x * UNORM16_MAX).round() / UNORM16_MAX
}

/// The G-buffer with both barycentrics of every hit quantized to unorm16.
pub fn quantize_gbuffer(gbuffer: &[GBufferTexel]) -> Vec<GBufferTexel> {
    gbuffer
        .par_iter()
        .with_min_len(4096)
        .map(|t| {
            if t.is_hit() {
                GBufferTexel { bary_u: quantize_unorm16(t.bary_u), bary_v: quantize_unorm16(t.bary_v), ..*t }
            } else {
                *t
            }
        })
        .collect()
}

/// Distance, as a fraction of the scene extent, that [`OffsetMethod::Epsilon`] moves a
/// shadow-ray origin along the geometric normal: 1e-4 (a common fixed "shadow epsilon";
/// 1 mm in a 10 m scene).
pub const CONSTANT_EPSILON_REL: f32 = 1e-4;

/// How a shadow ray's origin leaves the surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OffsetMethod {
    /// The reconstructed point itself, `t_min = 0`.
    None,
    /// The point plus [`CONSTANT_EPSILON_REL`] x scene extent along the geometric normal.
    Epsilon,
    /// `hyrt_core::kernels::ray::offset_ray_origin_integer_ulps` (Wächter and Binder: 256
    /// ulps of each coordinate), the pipeline's before the error-bound offset.
    IntegerUlps,
    /// `hyrt_core::kernels::ray::offset_ray_origin` (pbrt-v4: the point's own error bound,
    /// rounded away from the surface), the pipeline's.
    ErrorBound,
}

impl OffsetMethod {
    pub const ALL: [OffsetMethod; 4] =
        [OffsetMethod::None, OffsetMethod::Epsilon, OffsetMethod::IntegerUlps, OffsetMethod::ErrorBound];

    /// The method `compaction` uses: its rays need no re-offset.
    pub const PIPELINE: OffsetMethod = OffsetMethod::ErrorBound;

    pub const fn name(self) -> &'static str {
        match self {
            OffsetMethod::None => "none",
            OffsetMethod::Epsilon => "epsilon 1e-4 x extent",
            OffsetMethod::IntegerUlps => "256 ulps (Wachter-Binder)",
            OffsetMethod::ErrorBound => "error bound (pbrt-v4)",
        }
    }

    /// The origin of a shadow ray leaving `p` (whose coordinates are within `p_error` of
    /// the exact surface point), whose viewer-facing unit geometric normal is `n`.
    #[inline]
    pub fn origin(self, p: Vec3, p_error: f32, n: Vec3, scene_extent: f32) -> Vec3 {
        match self {
            OffsetMethod::None => p,
            OffsetMethod::Epsilon => p + n * (CONSTANT_EPSILON_REL * scene_extent),
            OffsetMethod::IntegerUlps => offset_ray_origin_integer_ulps(p, n),
            OffsetMethod::ErrorBound => offset_ray_origin(p, p_error, n),
        }
    }
}

/// Re-aim the compacted shadow rays (as `hyrt_cpu::compaction` built them, error-bound
/// origins) from origins chosen by `method`: the direction and `t_max` follow
/// `hyrt_cpu::compaction::shadow_ray` (towards a point light with
/// `t_max = SHADOW_T_MAX_POINT`, along a directional light to infinity).
pub fn reoffset_rays(
    rays: &mut [RayRecord],
    surfaces: &[SurfaceRecord],
    lights: &[LightRecord],
    method: OffsetMethod,
    scene_extent: f32,
) {
    rays.par_iter_mut().with_min_len(4096).for_each(|r| {
        let s = &surfaces[r.pixel as usize];
        let light = &lights[r.light as usize];
        let origin =
            method.origin(Vec3::from(s.position), s.position_error, Vec3::from(s.geometric_normal), scene_extent);
        let (direction, t_max) = if light.kind == LIGHT_DIRECTIONAL {
            (-Vec3::from(light.position_or_direction), f32::INFINITY)
        } else {
            (Vec3::from(light.position_or_direction) - origin, SHADOW_T_MAX_POINT)
        };
        r.origin = origin.into();
        r.direction = direction.into();
        r.t_min = 0.0;
        r.t_max = t_max;
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn unorm16_quantization_is_within_its_bound(x in 0.0f32..=1.0) {
            let q = quantize_unorm16(x);
            prop_assert!((q - x).abs() <= UNORM16_MAX_ERROR, "x {x} q {q}");
            prop_assert!((0.0..=1.0).contains(&q));
            // Idempotent: a code maps to itself.
            prop_assert_eq!(quantize_unorm16(q), q);
        }
    }

    #[test]
    fn unorm16_endpoints_and_out_of_range() {
        assert_eq!(quantize_unorm16(0.0), 0.0);
        assert_eq!(quantize_unorm16(1.0), 1.0);
        assert_eq!(quantize_unorm16(-0.25), 0.0);
        assert_eq!(quantize_unorm16(1.5), 1.0);
        assert_eq!(quantize_unorm16(f32::NAN), 0.0);
        // Half a step rounds away from zero (f32::round).
        assert_eq!(quantize_unorm16(0.5 / UNORM16_MAX), 1.0 / UNORM16_MAX);
    }
}
