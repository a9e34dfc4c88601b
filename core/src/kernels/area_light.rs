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
//!   times `Omega`);
//! * emitters (the table of emissive triangles, [`crate::formats::EmitterRecord`]): a
//!   triangle `i` picked with probability `p_i` (its share of the table's power) by the
//!   sample's first coordinate, that coordinate reused within the triangle's bin, a point
//!   uniform in its area, `weight = L_i cos_light A_i / (d^2 p_i)`.
//!
//! Every step is a correctly rounded operation in a stated order (the warps of
//! [`crate::kernels::sampling`]), so the GPU's twins give the same bits
//! (`gpu-backend/src/shaders/area_light.wgsl`, the emitters' over the table the GPU packs
//! into its lights' binding). The stages read them through [`crate::kernels::soft_shadow`].

use glam::Vec3;

use crate::formats::{EmitterRecord, EMITTER_DOUBLE_SIDED};
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

/// The largest f32 below 1 (`1 - 2^-24`): a sequence coordinate remapped within an emitter's
/// bin ([`pick_emitter`]) is clamped to it, staying in `[0, 1)` as the sequence's are
/// although its division may round up to 1.
pub const ONE_BELOW_ONE: f32 = 1.0 - 1.0 / 16_777_216.0;

/// The emitter the sequence coordinate `x` in `[0, 1)` picks from `emitters` (non-empty,
/// cdf non-decreasing, the last 1.0): the first whose `cdf` exceeds `x` (binary search;
/// the last where rounding leaves none), with its probability `p_i = cdf_i - cdf_{i-1}`
/// and `x` remapped into its bin, `min((x - cdf_{i-1}) / p_i, ONE_BELOW_ONE)`. A bin of
/// zero width (a triangle whose power rounds away in the cumulative sum) is never picked.
#[inline]
pub fn pick_emitter(emitters: &[EmitterRecord], x: f32) -> (usize, f32, f32) {
    let (mut lo, mut hi) = (0usize, emitters.len() - 1);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if x < emitters[mid].cdf {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    let below = if lo == 0 { 0.0 } else { emitters[lo - 1].cdf };
    let p = emitters[lo].cdf - below;
    (lo, p, ((x - below) / p).min(ONE_BELOW_ONE))
}

/// The point `v0 + (s (1 - v)) e1 + (s v) e2`, `s = sqrt(u)`, uniform in the area of the
/// triangle `v0, v0 + e1, v0 + e2` (density `2 / |e1 x e2|`; the square-root warp).
#[inline]
pub fn triangle_point(v0: Vec3, e1: Vec3, e2: Vec3, [u, v]: [f32; 2]) -> Vec3 {
    let s = u.sqrt();
    v0 + e1 * (s * (1.0 - v)) + e2 * (s * v)
}

/// A sample of the emitter table `emitters` (module docs) seen from `p` at sequence point
/// `u`: the triangle [`pick_emitter`] picks with `u[0]`, the point [`triangle_point`] of
/// the remapped `u[0]` and `u[1]`, `weight = radiance * (((-l . (e1 x e2)) * 0.5 / d2) /
/// p_i)` (`-l . (e1 x e2) / 2` is `cos_light` times the area), `d2` at least
/// [`MIN_AREA_LIGHT_DISTANCE_SQ`] as for quads. `None` for an empty table, where the point
/// faces away from `p` (the back of a single-sided triangle) or `p` lies in its plane.
#[inline]
pub fn sample_emitters(emitters: &[EmitterRecord], p: Vec3, u: [f32; 2]) -> Option<LightSample> {
    if emitters.is_empty() {
        return None;
    }
    let (i, pick, x) = pick_emitter(emitters, u[0]);
    let e = &emitters[i];
    let (e1, e2) = (Vec3::from(e.e1), Vec3::from(e.e2));
    let q = triangle_point(Vec3::from(e.v0), e1, e2, [x, u[1]]);
    let d = q - p;
    let d2 = d.dot(d).max(MIN_AREA_LIGHT_DISTANCE_SQ);
    let distance = d2.sqrt();
    let l = d / distance;
    let cos_twice_area = -l.dot(e1.cross(e2));
    let cos_twice_area = if e.flags & EMITTER_DOUBLE_SIDED != 0 { cos_twice_area.abs() } else { cos_twice_area };
    if cos_twice_area <= 0.0 {
        return None;
    }
    Some(LightSample { l, distance, weight: Vec3::from(e.radiance) * (((cos_twice_area * 0.5) / d2) / pick) })
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

    /// The emitter table of `triangles` (`[v0, v1, v2]`, radiance, double-sided), through
    /// the renderer's own cdf ([`crate::geometry::with_emitter_cdf`]).
    fn table(triangles: &[([Vec3; 3], Vec3, bool)]) -> Vec<EmitterRecord> {
        let records = triangles
            .iter()
            .enumerate()
            .map(|(k, &([v0, v1, v2], radiance, double_sided))| EmitterRecord {
                v0: v0.into(),
                cdf: 0.0,
                e1: (v1 - v0).into(),
                flags: if double_sided { EMITTER_DOUBLE_SIDED } else { 0 },
                e2: (v2 - v0).into(),
                object: 0,
                radiance: radiance.into(),
                triangle: k as u32,
            })
            .collect();
        crate::geometry::with_emitter_cdf(records)
    }

    /// The quad `corner + [0, 1] edge_u + [0, 1] edge_v` as two triangles wound as the quad
    /// (`e1 x e2` along `edge_u x edge_v`), of radiance `radiance`.
    fn quad_triangles(corner: Vec3, edge_u: Vec3, edge_v: Vec3, radiance: Vec3) -> Vec<([Vec3; 3], Vec3, bool)> {
        let (a, b, c, d) = (corner, corner + edge_u, corner + edge_u + edge_v, corner + edge_v);
        vec![([a, b, c], radiance, false), ([a, c, d], radiance, false)]
    }

    proptest! {
        /// An unoccluded emissive quad mesh (two triangles): the emitter estimator at 1,024
        /// samples against Lambert's closed form, as the quad light's.
        #[test]
        fn emitter_estimator_converges_to_lamberts_formula(
            px in -2.0f32..2.0, pz in -2.0f32..2.0, height in 0.3f32..3.0,
            tilt in -0.6f32..0.6, pixel in any::<u32>(),
        ) {
            let (corner, edge_u, edge_v) = (Vec3::new(-0.5, height, -0.75), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.5));
            let emitters = table(&quad_triangles(corner, edge_u, edge_v, Vec3::splat(2.0)));
            prop_assert_eq!(emitters.len(), 2);
            let p = Vec3::new(px, 0.0, pz);
            let n = Vec3::new(tilt.sin(), tilt.cos(), 0.0);
            let corners = [corner, corner + edge_u, corner + edge_u + edge_v, corner + edge_v]
                .map(|c| c.as_dvec3().to_array());
            prop_assume!(corners.iter().all(|c| (glam::DVec3::from(*c) - p.as_dvec3()).dot(n.as_dvec3()) > 1e-3));
            let want = polygon_irradiance_f64(&corners, p.as_dvec3().to_array(), n.as_dvec3().to_array(), 2.0);
            let got = estimate(n, 1024, sample_seed(pixel, 0, 0), |u| sample_emitters(&emitters, p, u));
            // Quasi-Monte Carlo over a smooth integrand (the bin's remapped coordinate keeps
            // the sequence stratified within each triangle): well under 1% at 1,024 samples.
            prop_assert!((got - want).abs() <= 0.01 * want + 1e-4, "{got} against {want}");
        }

        /// Picking: every sequence coordinate picks the first bin whose cdf exceeds it, the
        /// remapped coordinate stays in [0, 1), and the bins' widths are the triangles'
        /// shares of the power (area x luminance), the last cdf exactly 1.
        #[test]
        fn emitters_are_picked_in_proportion_to_their_power(
            sizes in proptest::collection::vec((0.01f32..4.0, 0.0f32..3.0), 1..12), x in 0.0f32..1.0,
        ) {
            let triangles: Vec<_> = sizes
                .iter()
                .map(|&(size, glow)| {
                    // At the origin (overlapping: picking does not care), so the edges are exact.
                    ([Vec3::ZERO, Vec3::X * size, Vec3::Z * size], Vec3::new(glow, glow * 0.5, 0.0), false)
                })
                .collect();
            let emitters = table(&triangles);
            // Zero power (no glow) is left out; the rest keep their order.
            let kept: Vec<usize> = (0..sizes.len()).filter(|&k| sizes[k].1 > 0.0).collect();
            prop_assert_eq!(emitters.iter().map(|e| e.triangle as usize).collect::<Vec<_>>(), kept.clone());
            prop_assume!(!emitters.is_empty());
            prop_assert_eq!(emitters.last().unwrap().cdf, 1.0);
            let power: Vec<f64> = kept
                .iter()
                .map(|&k| 0.5 * (sizes[k].0 as f64).powi(2) * (0.2126 * sizes[k].1 as f64 + 0.7152 * 0.5 * sizes[k].1 as f64))
                .collect();
            let total: f64 = power.iter().sum();
            let mut below = 0.0f32;
            for (e, p) in emitters.iter().zip(&power) {
                // The f32 rounding of the cumulative shares: a few ulp of 1.
                prop_assert!(((e.cdf - below) as f64 - p / total).abs() < 1e-6, "{} against {}", e.cdf - below, p / total);
                below = e.cdf;
            }
            let (i, pick, remapped) = pick_emitter(&emitters, x);
            let lo = if i == 0 { 0.0 } else { emitters[i - 1].cdf };
            prop_assert!(lo <= x && x < emitters[i].cdf, "{x} in bin {i} [{lo}, {})", emitters[i].cdf);
            prop_assert_eq!(pick, emitters[i].cdf - lo);
            prop_assert!((0.0..1.0).contains(&remapped));
        }
    }

    /// The last bin takes the coordinates just below 1; a single-sided emitter gives no
    /// sample behind it, a double-sided one does (with the same weight as in front).
    #[test]
    fn the_last_bin_and_the_sides_of_emitters() {
        let one = table(&[([Vec3::ZERO, Vec3::X, Vec3::Z], Vec3::ONE, false)]);
        assert_eq!(pick_emitter(&one, ONE_BELOW_ONE).0, 0);
        let two = table(&[
            ([Vec3::ZERO, Vec3::X, Vec3::Z], Vec3::ONE, false),
            ([Vec3::ZERO, Vec3::X * 2.0, Vec3::Z * 2.0], Vec3::ONE, false),
        ]);
        assert_eq!(two[0].cdf, 0.2, "areas 1/2 and 2: a fifth of the power");
        assert_eq!(pick_emitter(&two, ONE_BELOW_ONE).0, 1);
        assert_eq!(pick_emitter(&two, 0.2).0, 1, "the bin boundary belongs to the next bin");
        assert_eq!(pick_emitter(&two, 0.0).0, 0);
        // X x Z = -Y: emits downwards.
        let below = Vec3::new(0.2, -1.0, 0.2);
        let above = Vec3::new(0.2, 1.0, 0.2);
        assert!(sample_emitters(&one, below, [0.3, 0.6]).is_some());
        assert!(sample_emitters(&one, above, [0.3, 0.6]).is_none());
        let both = table(&[([Vec3::ZERO, Vec3::X, Vec3::Z], Vec3::ONE, true)]);
        let (front, back) =
            (sample_emitters(&both, below, [0.3, 0.6]).unwrap(), sample_emitters(&both, above, [0.3, 0.6]).unwrap());
        assert_eq!(front.weight, back.weight, "mirror images of each other");
        assert!(sample_emitters(&[], below, [0.3, 0.6]).is_none());
        // Sample points lie on the triangle: barycentrics in [0, 1].
        for s in 0..256 {
            let ls = sample_emitters(&one, below, sample_2d(s, 7)).unwrap();
            let q = below + ls.l * ls.distance;
            // Roundings of coordinates of order 1.
            assert!(q.y.abs() < 1e-5 && q.x >= -1e-6 && q.z >= -1e-6 && q.x + q.z <= 1.0 + 1e-5, "{q}");
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
