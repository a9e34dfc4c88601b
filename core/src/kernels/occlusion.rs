//! Ambient-occlusion kernels (issue 38 item 3): the directions of a surface's occlusion
//! rays and the estimate they give. A surface sends `N` rays of length `radius` from its
//! offset origin, cosine-weighted about its shading normal (sample `s` of the stream
//! [`AO_STREAM`] of its pixel, [`crate::kernels::sampling::sample_seed`]); its ambient
//! occlusion is the fraction that meet nothing ([`ao_fraction`]), the estimator of
//! `(1 / pi) integral V(w) cos(theta) dw` over the hemisphere, `V` the visibility within
//! the radius. It will scale the ambient and image-based terms
//! ([`crate::kernels::shading::ambient`]) as the occlusion texture does.
//!
//! Not used by a stage yet: the occlusion rays are the next step.

use glam::Vec3;

use crate::kernels::sampling::{cosine_hemisphere, to_frame};

/// The sample stream of ambient occlusion in [`crate::kernels::sampling::sample_seed`]:
/// lights use their index, so this lies above any light count.
pub const AO_STREAM: u32 = 0xffff_fff0;

/// The direction of the occlusion ray of sequence point `u` at a surface of unit shading
/// normal `n_shade` and geometric normal `n_geo` (both towards the seen side):
/// cosine-weighted about the shading normal; `None` where it would leave below the
/// geometric surface (a shading normal tilted by interpolation or a normal map), which
/// the estimate counts as occluded, as the surface itself hides it.
#[inline]
pub fn ao_direction(n_shade: Vec3, n_geo: Vec3, u: [f32; 2]) -> Option<Vec3> {
    let d = to_frame(cosine_hemisphere(u), n_shade);
    (d.dot(n_geo) > 0.0).then_some(d)
}

/// The ambient occlusion of `unoccluded` rays out of `samples` that met nothing: their
/// fraction, 1 without samples (no occlusion computed: nothing darkens).
#[inline]
pub fn ao_fraction(unoccluded: u32, samples: u32) -> f32 {
    if samples == 0 {
        1.0
    } else {
        unoccluded as f32 / samples as f32
    }
}

/// The specification for a point at distance `d` from an infinite plane perpendicular to
/// its surface (a floor next to a wall): the cosine-weighted fraction of its hemisphere
/// whose rays meet the plane within `radius`. Malley's method maps cosine-weighted
/// directions to uniform points `(x, y)` of the unit disk, `x = sin(theta) cos(phi)` the
/// component towards the wall; a ray meets it within `radius` where `x >= d / radius`,
/// a segment of the disk: `(acos a - a sqrt(1 - a^2)) / pi` with `a = d / radius`
/// (0 beyond the radius, 1/2 at the wall's foot). In f64; not for rendering.
pub fn ao_blocked_by_wall_f64(d: f64, radius: f64) -> f64 {
    let a = (d / radius).clamp(0.0, 1.0);
    (a.acos() - a * (1.0 - a * a).sqrt()) / std::f64::consts::PI
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::sampling::{sample_2d, sample_seed};
    use proptest::prelude::*;

    proptest! {
        /// A point on a floor (+Y) at distance `d` from a wall (the plane x = d): the
        /// fraction of its occlusion rays that meet the wall within the radius, over 1,024
        /// samples of a stream, against the closed form.
        #[test]
        fn occlusion_rays_near_a_wall_match_the_disk_segment(
            d in 0.0f32..2.0, radius in 0.1f32..3.0, pixel in any::<u32>(),
        ) {
            let seed = sample_seed(pixel, AO_STREAM, 0);
            let n = 1024u32;
            let blocked = (0..n)
                .filter_map(|s| ao_direction(Vec3::Y, Vec3::Y, sample_2d(s, seed)))
                .filter(|dir| dir.x > 0.0 && d / dir.x <= radius)
                .count();
            let got = blocked as f64 / n as f64;
            let want = ao_blocked_by_wall_f64(d as f64, radius as f64);
            // A stratified estimate of a disk segment's area: its boundary crosses about
            // 2 sqrt(n) strata, each off by at most one point.
            prop_assert!((got - want).abs() <= 2.0 / (n as f64).sqrt(), "{got} against {want}");
        }

        /// Directions stay above the geometric surface, and follow the shading normal.
        #[test]
        fn occlusion_rays_leave_above_the_geometric_surface(
            tilt in 0.0f32..1.2, u in 0.0f32..1.0, v in 0.0f32..1.0,
        ) {
            let n_shade = Vec3::new(tilt.sin(), tilt.cos(), 0.0);
            if let Some(dir) = ao_direction(n_shade, Vec3::Y, [u, v]) {
                prop_assert!(dir.y > 0.0);
                prop_assert!(dir.dot(n_shade) >= -1e-6);
            }
        }
    }

    #[test]
    fn the_estimate_is_the_unoccluded_fraction() {
        assert_eq!(ao_fraction(0, 0), 1.0);
        assert_eq!(ao_fraction(3, 4), 0.75);
        assert_eq!(ao_fraction(0, 16), 0.0);
        assert_eq!(ao_blocked_by_wall_f64(0.0, 1.0), 0.5);
        assert_eq!(ao_blocked_by_wall_f64(2.0, 1.0), 0.0);
    }
}
