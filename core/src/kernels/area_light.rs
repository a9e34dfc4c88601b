//! Area-light sampling kernels (issue 38 item 1): one sample of a quad light, a sphere light
//! or a sun of finite angular size seen from a surface point, from a point of the
//! sample sequence ([`crate::kernels::sampling::sample_2d`]). Each sample gives the unit
//! direction towards the light, how far a shadow ray must go to reach it, and the weight
//! that makes `weight * brdf * n.l` an unbiased estimate of the light's contribution:
//!
//! ```text
//! direct light = (1 / N) sum over samples of  visible_s * brdf(l_s) * weight_s * max(n.l_s, 0)
//! ```
//!
//! * quad (`corner`, `edge_u`, `edge_v`, emitting radiance `L` to the side of
//!   `edge_u x edge_v`): points uniform in area, `weight = L cos_light A / d^2` (the area
//!   density `1 / A` turned into solid angle);
//! * sphere (`centre`, `radius`, radiance `L`): directions uniform in the cone the sphere
//!   subtends, `weight = L Omega` with `Omega = 2 pi (1 - cos theta_max)`;
//! * sun (travelling along `direction`, angular diameter `delta`, illuminance `E` at normal
//!   incidence): directions uniform in its cone, `weight = E` (its radiance `E / Omega`
//!   times `Omega`).
//!
//! Every step is a correctly rounded operation in a stated order (the warps of
//! [`crate::kernels::sampling`]), so the GPU's twins will give the same bits. Not used by a
//! stage yet: the stochastic shadow rays that read these samples are the issue's next
//! step.

use glam::Vec3;

use crate::kernels::sampling::{quad_point, to_frame, uniform_cone};

/// One sample of an area light seen from a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the point towards the sampled point of the light.
    pub l: Vec3,
    /// Distance to the sampled point along `l` (infinite for a sun): the shadow ray's
    /// extent before its end offset.
    pub distance: f32,
    /// The estimator's weight (module docs): radiance over the sample's solid-angle density.
    pub weight: Vec3,
}

/// Least squared distance a quad sample is evaluated at, as
/// [`crate::kernels::shading::MIN_LIGHT_DISTANCE_SQ`] for point lights: a point on the
/// light itself does not make an infinite weight.
pub const MIN_AREA_LIGHT_DISTANCE_SQ: f32 = crate::kernels::shading::MIN_LIGHT_DISTANCE_SQ;

/// A sample of the quad light `corner + [0, 1] edge_u + [0, 1] edge_v` of radiance
/// `radiance`, emitting to the side of `edge_u x edge_v`, seen from `p`, at sequence point
/// `u`; `None` where the sampled point faces away from `p` (or `p` lies in its plane).
#[inline]
pub fn sample_quad_light(
    corner: Vec3,
    edge_u: Vec3,
    edge_v: Vec3,
    radiance: Vec3,
    p: Vec3,
    u: [f32; 2],
) -> Option<LightSample> {
    let q = quad_point(corner, edge_u, edge_v, u);
    let d = q - p;
    let d2 = d.dot(d).max(MIN_AREA_LIGHT_DISTANCE_SQ);
    let distance = d2.sqrt();
    let l = d / distance;
    let normal = edge_u.cross(edge_v);
    // cos_light * area = (-l) . (edge_u x edge_v): the normal's length is the area.
    let cos_area = -l.dot(normal);
    if cos_area <= 0.0 {
        return None;
    }
    Some(LightSample { l, distance, weight: radiance * (cos_area / d2) })
}

/// `1 - cos(theta_max)` of the cone a sphere of squared radius `r2` subtends from squared
/// distance `d2 > r2`, as `s / (1 + sqrt(1 - s))` with `s = r2 / d2` (the sine squared):
/// accurate for far and small spheres, where `1 - sqrt(1 - s)` would cancel.
#[inline]
pub fn sphere_cone_one_minus_cos(r2: f32, d2: f32) -> f32 {
    let s = r2 / d2;
    s / (1.0 + (1.0 - s).max(0.0).sqrt())
}

/// A sample of the sphere light of `centre`, `radius` and radiance `radiance` seen from
/// `p`, at sequence point `u`: a direction uniform in the cone it subtends, the distance to
/// the near side of the sphere along it. `None` from inside the sphere.
#[inline]
pub fn sample_sphere_light(centre: Vec3, radius: f32, radiance: Vec3, p: Vec3, u: [f32; 2]) -> Option<LightSample> {
    let dc = centre - p;
    let d2 = dc.dot(dc);
    let r2 = radius * radius;
    if d2 <= r2 {
        return None;
    }
    let k = sphere_cone_one_minus_cos(r2, d2);
    let axis = dc / d2.sqrt();
    let l = to_frame(uniform_cone(u, k), axis);
    // The ray p + t l meets the sphere at t = b - sqrt(b^2 - c), b = l.dc, c = d2 - r2
    // (within the cone b^2 >= c up to roundings: clamped).
    let b = l.dot(dc);
    let c = d2 - r2;
    let distance = b - (b * b - c).max(0.0).sqrt();
    let solid_angle = std::f32::consts::TAU * k;
    Some(LightSample { l, distance, weight: radiance * solid_angle })
}

/// `1 - cos` of half a sun's angular diameter `delta` (radians), `2 sin^2(delta / 4)`,
/// computed once per light (on the CPU, in f64) and stored with it.
pub fn sun_one_minus_cos(delta: f64) -> f32 {
    let s = (delta / 4.0).sin();
    (2.0 * s * s) as f32
}

/// A sample of a sun travelling along the unit `direction` whose disk's half angle has
/// `1 - cos = one_minus_cos` ([`sun_one_minus_cos`]) and whose illuminance at normal
/// incidence is `illuminance`, at sequence point `u`: a direction towards the sun uniform
/// in its cone, at infinite distance.
#[inline]
pub fn sample_sun(direction: Vec3, one_minus_cos: f32, illuminance: Vec3, u: [f32; 2]) -> LightSample {
    let l = to_frame(uniform_cone(u, one_minus_cos), -direction);
    LightSample { l, distance: f32::INFINITY, weight: illuminance }
}

/// The irradiance an unoccluded Lambertian emitter of radiance `radiance` over the convex
/// polygon `corners` (emitting towards `p`) gives the point `p` of unit normal `n`,
/// clipped to nothing: Lambert's closed form `E = L / 2 sum_i theta_i (n . g_i)` over the
/// polygon's edges, `theta_i` the angle the edge subtends at `p` and `g_i` the unit normal of
/// the plane through `p` and the edge (Arvo, "Applications of Irradiance Tensors", 1995),
/// in f64. Correct when the whole polygon lies above the plane of `n`. The specification
/// the quad estimator is tested against; not for rendering.
pub fn polygon_irradiance_f64(corners: &[[f64; 3]], p: [f64; 3], n: [f64; 3], radiance: f64) -> f64 {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross =
        |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let unit = |a: [f64; 3]| {
        let l = dot(a, a).sqrt();
        [a[0] / l, a[1] / l, a[2] / l]
    };
    let mut sum = 0.0;
    for i in 0..corners.len() {
        let a = unit(sub(corners[i], p));
        let b = unit(sub(corners[(i + 1) % corners.len()], p));
        let theta = dot(a, b).clamp(-1.0, 1.0).acos();
        let g = unit(cross(a, b));
        sum += theta * dot(n, g);
    }
    (radiance / 2.0 * sum).abs()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::sampling::{sample_2d, sample_seed};
    use proptest::prelude::*;

    /// The estimator `(1 / N) sum weight max(n.l, 0)` of a light's irradiance at `p`.
    fn estimate(n: Vec3, samples: u32, seed: u32, mut sample: impl FnMut([f32; 2]) -> Option<LightSample>) -> f64 {
        let sum: f64 = (0..samples)
            .filter_map(|s| sample(sample_2d(s, seed)))
            .map(|ls| ls.weight.x as f64 * ls.l.dot(n).max(0.0) as f64)
            .sum();
        sum / samples as f64
    }

    proptest! {
        /// An unoccluded quad's irradiance: the estimator at 1,024 samples against
        /// Lambert's closed form, anywhere in front of it and under it.
        #[test]
        fn quad_estimator_converges_to_lamberts_formula(
            px in -2.0f32..2.0, pz in -2.0f32..2.0, height in 0.3f32..3.0,
            tilt in -0.6f32..0.6, pixel in any::<u32>(),
        ) {
            // A 1 x 1.5 quad at y = height facing down; the point on the floor, its normal
            // tilted about z.
            let (corner, edge_u, edge_v) = (Vec3::new(-0.5, height, -0.75), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.5));
            prop_assert!(edge_u.cross(edge_v).y < 0.0, "emits downwards");
            let p = Vec3::new(px, 0.0, pz);
            let n = Vec3::new(tilt.sin(), tilt.cos(), 0.0);
            let corners = [corner, corner + edge_u, corner + edge_u + edge_v, corner + edge_v]
                .map(|c| c.as_dvec3().to_array());
            // Only where the whole quad is above the surface's plane (no clipping).
            prop_assume!(corners.iter().all(|c| (glam::DVec3::from(*c) - p.as_dvec3()).dot(n.as_dvec3()) > 1e-3));
            let want = polygon_irradiance_f64(&corners, p.as_dvec3().to_array(), n.as_dvec3().to_array(), 2.0);
            let got = estimate(n, 1024, sample_seed(pixel, 0, 0), |u| {
                sample_quad_light(corner, edge_u, edge_v, Vec3::splat(2.0), p, u)
            });
            // Quasi-Monte Carlo over a smooth integrand: well under 1% at 1,024 samples.
            prop_assert!((got - want).abs() <= 0.01 * want + 1e-4, "{got} against {want}");
        }

        /// A sphere light: the estimator against the closed form of a sphere seen whole
        /// above the horizon, `E = L pi sin^2(theta_max) cos(alpha)` (the sphere's centre at
        /// angle alpha from the normal).
        #[test]
        fn sphere_estimator_converges_to_the_closed_form(
            distance in 1.5f32..20.0, alpha in 0.0f32..0.9, radius in 0.1f32..1.0, pixel in any::<u32>(),
        ) {
            let centre = Vec3::new(alpha.sin(), alpha.cos(), 0.0) * distance;
            prop_assume!((distance * (std::f32::consts::FRAC_PI_2 - alpha).sin()) > radius * 1.01);
            let n = Vec3::Y;
            let got = estimate(n, 1024, sample_seed(pixel, 1, 0), |u| {
                sample_sphere_light(centre, radius, Vec3::splat(3.0), Vec3::ZERO, u)
            });
            let sin2 = (radius as f64 / distance as f64).powi(2);
            let want = 3.0 * std::f64::consts::PI * sin2 * (alpha as f64).cos();
            prop_assert!((got - want).abs() <= 0.01 * want + 1e-6, "{got} against {want}");
        }
    }

    /// Sphere samples start on the near side of the sphere: the point at `distance` along
    /// `l` lies on it.
    #[test]
    fn sphere_samples_end_on_the_sphere() {
        let (centre, radius) = (Vec3::new(1.0, 5.0, -2.0), 0.8f32);
        for s in 0..256 {
            let ls = sample_sphere_light(centre, radius, Vec3::ONE, Vec3::ZERO, sample_2d(s, 99)).unwrap();
            let q = ls.l * ls.distance;
            // Roundings of a distance of about 5.
            assert!(((q - centre).length() - radius).abs() < 1e-4, "sample {s}: {}", (q - centre).length());
        }
        assert_eq!(sample_sphere_light(centre, radius, Vec3::ONE, centre, [0.5, 0.5]), None, "inside");
    }

    /// A sun of the real sun's size (0.53 degrees): every direction within its disk, its
    /// illuminance the weight; a point sun (diameter 0) is the directional light.
    #[test]
    fn sun_samples_stay_in_its_disk() {
        let direction = Vec3::new(0.3, -0.9, 0.2).normalize();
        let k = sun_one_minus_cos(0.53f64.to_radians());
        let half = 0.53f64.to_radians() / 2.0;
        for s in 0..256 {
            let ls = sample_sun(direction, k, Vec3::splat(7.0), sample_2d(s, 5));
            let angle = (ls.l.as_dvec3().dot(-direction.as_dvec3())).clamp(-1.0, 1.0).acos();
            // The f32 direction's roundings: about 1e-7 radians.
            assert!(angle <= half + 1e-6, "sample {s}: {angle} beyond {half}");
            assert_eq!(ls.weight, Vec3::splat(7.0));
        }
        let point = sample_sun(direction, 0.0, Vec3::ONE, [0.3, 0.7]);
        assert!((point.l + direction).length() < 1e-6);
    }

    #[test]
    fn a_quad_facing_away_gives_no_sample() {
        let (corner, edge_u, edge_v) = (Vec3::new(-0.5, 2.0, -0.5), Vec3::X, Vec3::Z);
        // X x Z = -Y: it emits downwards, so a point above it gets nothing.
        assert!(sample_quad_light(corner, edge_u, edge_v, Vec3::ONE, Vec3::new(0.0, 4.0, 0.0), [0.5, 0.5]).is_none());
        assert!(sample_quad_light(corner, edge_u, edge_v, Vec3::ONE, Vec3::ZERO, [0.5, 0.5]).is_some());
    }
}
