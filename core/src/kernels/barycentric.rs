//! Barycentric reconstruction of the hit point (paper eq. 1) and its error bound.
//!
//! WGSL mirror: `reconstruct_position` in the GPU backend's `reconstruction.wgsl`
//! must use the same operation order: `w = (1 - u) - v`, then per component
//! `(w * v0 + u * v1) + v * v2` with every product and sum rounded separately
//! (no fused multiply-add; where the driver fuses, the bound below still holds
//! because a fused operation rounds once instead of twice).

use glam::Vec3;

/// Unit roundoff of f32 (round to nearest): 2^-24.
pub const F32_UNIT_ROUNDOFF: f32 = f32::EPSILON * 0.5;

/// pbrt-v4's gamma(n) = n*u / (1 - n*u): the relative error bound of n rounded
/// f32 operations (Higham, "Accuracy and Stability of Numerical Algorithms", 3.1).
#[inline]
pub fn gamma(n: u32) -> f32 {
    let nu = n as f32 * F32_UNIT_ROUNDOFF;
    nu / (1.0 - nu)
}

/// The weight of v0 from the G-buffer's (u, v): `w = (1 - u) - v`, in this order.
#[inline]
pub fn bary_w(u: f32, v: f32) -> f32 {
    (1.0 - u) - v
}

/// Paper eq. 1: x = w*v0 + u*v1 + v*v2 with w = (1 - u) - v, evaluated as
/// `(w*v0 + u*v1) + v*v2` per component, each operation rounded.
#[inline]
pub fn reconstruct_position(u: f32, v: f32, v0: Vec3, v1: Vec3, v2: Vec3) -> Vec3 {
    let w = bary_w(u, v);
    Vec3::new((w * v0.x + u * v1.x) + v * v2.x, (w * v0.y + u * v1.y) + v * v2.y, (w * v0.z + u * v1.z) + v * v2.z)
}

/// Absolute error bound, per component, of [`reconstruct_position`] against the
/// exact point `(1 - u - v)*v0 + u*v1 + v*v2` computed from the same f32 `u`, `v`
/// and vertices in exact arithmetic.
///
/// Derivation (standard model, each operation `op` returns `op * (1 + d)`, |d| <= u):
/// * `w` takes two roundings: |w~ - w| <= gamma(2) * (1 + |u| + |v|).
/// * The dot product of three terms takes 3 multiplies and 2 adds, so a term
///   carries at most 3 roundings: pbrt-v4 bounds it by gamma(3) * sum|b_i p_i|
///   (pbrt uses gamma(7) to also cover its own `1 - u - v`; we bound that part
///   separately and exactly as above).
/// * Total: gamma(3) * (|w~ v0| + |u v1| + |v v2|) + (1 + gamma(3)) * |w~ - w| * |v0|.
///
/// At |p| ~ 1e6 this is ~0.2 units: keep coordinates near the origin where it matters.
#[inline]
pub fn position_error_bound(u: f32, v: f32, v0: Vec3, v1: Vec3, v2: Vec3) -> Vec3 {
    let w = bary_w(u, v);
    let sum = (w * v0).abs() + (u * v1).abs() + (v * v2).abs();
    let w_err = gamma(2) * (1.0 + u.abs() + v.abs());
    // The bound itself is evaluated in f32; inflate by one more gamma(3) so its own
    // rounding cannot make it smaller than the true bound.
    (sum * gamma(3) + v0.abs() * (w_err * (1.0 + gamma(3)))) * (1.0 + gamma(3))
}

/// Interpolate the three corner normals with the same weights and normalize;
/// falls back to `fallback` (the geometric normal) when the result is zero.
#[inline]
pub fn interpolate_normal(u: f32, v: f32, n: [Vec3; 3], fallback: Vec3) -> Vec3 {
    let w = bary_w(u, v);
    let s = Vec3::new(
        (w * n[0].x + u * n[1].x) + v * n[2].x,
        (w * n[0].y + u * n[1].y) + v * n[2].y,
        (w * n[0].z + u * n[1].z) + v * n[2].z,
    );
    let len = s.length();
    if len > 0.0 && len.is_finite() {
        s / len
    } else {
        fallback
    }
}

/// Unit geometric normal `(v1 - v0) x (v2 - v0)`; zero for a degenerate triangle.
#[inline]
pub fn geometric_normal(v0: Vec3, v1: Vec3, v2: Vec3) -> Vec3 {
    (v1 - v0).cross(v2 - v0).normalize_or_zero()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Exact reference in f64 (products of two f32 are exact in f64; the sums of
    /// three such terms round at most twice in f64, ~2^-53, far below the f32 bound).
    fn exact(u: f32, v: f32, p: [Vec3; 3]) -> [f64; 3] {
        let (u, v) = (u as f64, v as f64);
        let w = 1.0 - u - v;
        let c = |i: usize| w * p[0][i] as f64 + u * p[1][i] as f64 + v * p[2][i] as f64;
        [c(0), c(1), c(2)]
    }

    fn coord() -> impl Strategy<Value = f32> {
        // Magnitudes from 1e-3 to 1e6 with both signs (numerics-notes: 10^U(-8, 8) in pbrt).
        (-3.0f64..6.0, any::<bool>(), 1.0f64..10.0)
            .prop_map(|(e, s, m)| ((if s { -1.0 } else { 1.0 }) * m * 10f64.powf(e)) as f32)
    }

    fn vertex() -> impl Strategy<Value = Vec3> {
        (coord(), coord(), coord()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    fn bary() -> impl Strategy<Value = (f32, f32)> {
        (0.0f32..=1.0, 0.0f32..=1.0).prop_map(|(a, b)| if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4096))]

        #[test]
        fn reconstruction_within_stated_bound((u, v) in bary(), v0 in vertex(), v1 in vertex(), v2 in vertex()) {
            let x = reconstruct_position(u, v, v0, v1, v2);
            let b = position_error_bound(u, v, v0, v1, v2);
            let e = exact(u, v, [v0, v1, v2]);
            for i in 0..3 {
                let err = (x[i] as f64 - e[i]).abs();
                prop_assert!(err <= b[i] as f64, "axis {i}: error {err} > bound {} (x {} exact {})", b[i], x[i], e[i]);
            }
        }

        #[test]
        fn reconstruction_weights_sum_to_one_within_bound((u, v) in bary()) {
            let w = bary_w(u, v);
            let sum = w as f64 + u as f64 + v as f64;
            prop_assert!((sum - 1.0).abs() <= (gamma(2) * (1.0 + u + v)) as f64, "sum {sum}");
        }

        #[test]
        fn reconstruction_point_lies_on_triangle((u, v) in bary(), v0 in vertex(), v1 in vertex(), v2 in vertex()) {
            // Distance to the triangle's plane is at most the length of the error bound.
            let n = [v0, v1, v2].map(|p| p.as_dvec3());
            let normal = (n[1] - n[0]).cross(n[2] - n[0]);
            prop_assume!(normal.length() > 0.0);
            let x = reconstruct_position(u, v, v0, v1, v2).as_dvec3();
            let dist = (x - n[0]).dot(normal / normal.length()).abs();
            let b = position_error_bound(u, v, v0, v1, v2).as_dvec3().length();
            // The exact barycentric point is on the plane; the f64 evaluation of the
            // distance adds a relative error of a few 2^-53 of the coordinates.
            let f64_slack = 8.0 * f64::EPSILON * (n[0].abs().max_element() + x.abs().max_element()) * 4.0;
            prop_assert!(dist <= b + f64_slack, "distance {dist} > bound {b}");
        }
    }

    #[test]
    fn reconstruction_hits_vertices_exactly() {
        let p = [Vec3::new(1e6, -3.0, 0.25), Vec3::new(2.0, 5.5, -7.0), Vec3::new(-1e-3, 8.0, 9.0)];
        assert_eq!(reconstruct_position(0.0, 0.0, p[0], p[1], p[2]), p[0]);
        assert_eq!(reconstruct_position(1.0, 0.0, p[0], p[1], p[2]), p[1]);
        assert_eq!(reconstruct_position(0.0, 1.0, p[0], p[1], p[2]), p[2]);
    }

    #[test]
    fn bound_at_one_million_is_a_fraction_of_a_unit() {
        let v = Vec3::splat(1e6);
        let b = position_error_bound(1.0 / 3.0, 1.0 / 3.0, v, v, v);
        assert!(b.max_element() < 0.5 && b.max_element() > 0.01, "{b}");
    }
}
