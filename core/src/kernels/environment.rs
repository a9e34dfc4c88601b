//! The radiance a ray that leaves the scene brings back: the default sky, or a bilinear
//! lookup in the scene's equirectangular map ([`crate::scene::Environment`], whose module
//! docs give the layout).
//!
//! # The lookup
//!
//! For a direction `d = (x, y, z)` (any length, finite and non-zero):
//!
//! ```text
//! u = atan2(x, -z) / 2 pi, plus 1 where negative    (in [0, 1]; -Z is 0, +X 0.25, +Z 0.5, -X 0.75)
//! v = atan2(sqrt(x^2 + z^2), y) / pi                (in [0, 1]; +Y is 0, the horizon 0.5, -Y 1)
//! ```
//!
//! with [`atan2_turns`] for `atan2 / 2 pi` (the latitude through `atan2` rather than
//! `acos(y / |d|)`, whose error grows to about `sqrt(2^-24)` radians near the poles), then
//! a bilinear blend of the four texels around `(u W - 1/2, v H - 1/2)` (texel centres at
//! half-integers): columns wrap around (the seam at -Z blends the last and the first
//! column), rows clamp (above the centre of row 0 and below the centre of the last row,
//! that row alone). With `tij` the texel at column `i0 + i` and row `j0 + j` and
//! `lerp(a, b, f) = a + (b - a) f`, the blend is
//!
//! ```text
//! top = lerp(t00, t10, fx),  bottom = lerp(t01, t11, fx),  result = lerp(top, bottom, fy)
//! ```
//!
//! per channel, each product rounded (no fused multiply-add). Equal texels blend to
//! themselves exactly, so a region of one colour (a whole one-colour map) reads that
//! colour bit for bit.
//!
//! Every step is a correctly rounded operation (`+ - * /`, `sqrt`, comparisons, `floor`,
//! conversions of small integers) in a stated order, so the GPU's twin gives the same
//! bits; `atan2` and `acos` of the platforms (and WGSL's) do not.
//!
//! WGSL mirrors (to come with the GPU bounce stages): `atan2_turns`, `direction_to_uv`,
//! `sample_bilinear`, `environment_radiance`, by the same names.

use glam::Vec3;

use crate::scene::{Environment, EnvironmentMap};

/// `tan(pi / 8) = sqrt 2 - 1`: [`atan2_turns`] maps ratios above it through
/// `atan t = pi / 4 + atan((t - 1) / (t + 1))`, so the series only sees `|s| <= tan(pi/8)`.
pub const TAN_PI_8: f32 = 0.414_213_57;

/// `1 / 2 pi`: radians to turns.
pub const INV_TWO_PI: f32 = 1.0 / std::f32::consts::TAU;

/// Coefficients `(-1)^k / (2k + 1)`, k = 8..0, of the series
/// `atan(s) / s = sum (-1)^k s^(2k) / (2k + 1)` in [`atan2_turns`] (Horner order in
/// `s^2`). With `|s| <= tan(pi / 8) < 0.4143` the series alternates with decreasing terms,
/// so the truncation error is below the first omitted term, `s^18 / 19 < 6.8e-9 < 2^-27`
/// relative: under the f32 rounding.
pub const ATAN_SERIES: [f32; 9] =
    [1.0 / 17.0, -1.0 / 15.0, 1.0 / 13.0, -1.0 / 11.0, 1.0 / 9.0, -1.0 / 7.0, 1.0 / 5.0, -1.0 / 3.0, 1.0];

/// Largest error of [`atan2_turns`] against the exact `atan2(y, x) / 2 pi`, in turns:
/// 2^-24 (`2.4e-7` radians), a few roundings of the reduced ratio and the series (each
/// at most 2^-25 of a result below 1/8 turn) plus the final sums with the exact octant
/// constants (half an ulp of a result up to 1/2: 2^-25). The largest error measured, over
/// a dense sweep of the circle and 5 million random points, is 3.3e-8 (2^-24.9); the tests
/// hold every run to this bound. At 8192 texels around the equator it moves a lookup by
/// 5e-4 of a texel.
pub const ATAN2_TURNS_MAX_ERROR: f32 = 1.0 / (1u32 << 24) as f32;

/// `atan2(y, x) / 2 pi`, in turns, in `[-1/2, 1/2]`, from correctly rounded operations only
/// (the platforms' `atan2` differ in the last bits, and WGSL's is not specified to the
/// bit). The ratio of the smaller to the larger magnitude, `t` in `[0, 1]`, is reduced to
/// `|s| <= tan(pi / 8)` ([`TAN_PI_8`]), its arctangent is the series of [`ATAN_SERIES`],
/// and the octant is restored with exact constants (1/8, 1/4, 1/2 turn), so the axes give
/// exact results: `atan2_turns(0, 1) = 0`, `(1, 0) = 1/4`, `(0, -1) = 1/2`,
/// `(-1, 0) = -1/4`. Error at most [`ATAN2_TURNS_MAX_ERROR`].
///
/// Signs of zero are ignored (`atan2_turns(-0, -1) = 1/2`, where `atan2` gives `-pi`);
/// `atan2_turns(0, 0) = 0`; NaN input gives 0 or NaN.
/// WGSL: `atan2_turns`.
#[inline]
pub fn atan2_turns(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let swapped = ay > ax;
    let (num, den) = if swapped { (ax, ay) } else { (ay, ax) };
    // Both zero (or NaN): the direction has no angle; 0 keeps the lookup defined.
    if den == 0.0 || den.is_nan() {
        return 0.0;
    }
    let t = num / den;
    let (s, base) = if t > TAN_PI_8 { ((t - 1.0) / (t + 1.0), 0.125) } else { (t, 0.0) };
    let s2 = s * s;
    let mut p = ATAN_SERIES[0];
    for c in &ATAN_SERIES[1..] {
        p = p * s2 + c;
    }
    // atan(t) in turns, in [0, 1/8].
    let mut a = base + (s * p) * INV_TWO_PI;
    if swapped {
        a = 0.25 - a;
    }
    if x < 0.0 {
        a = 0.5 - a;
    }
    if y < 0.0 {
        -a
    } else {
        a
    }
}

/// The texture coordinates `(u, v)` of the direction `d` (module docs): `u` in `[0, 1]`
/// from -Z through +X, +Z, -X, `v` in `[0, 1]` from +Y down to -Y. Straight up or down
/// (`x = z = 0`) gives `u = 0`. WGSL: `direction_to_uv`.
#[inline]
pub fn direction_to_uv(d: Vec3) -> (f32, f32) {
    let mut u = atan2_turns(d.x, -d.z);
    if u < 0.0 {
        u += 1.0;
    }
    let r = (d.x * d.x + d.z * d.z).sqrt();
    // In [0, 1/2] turns (r >= 0), so v is in [0, 1]; the doubling is exact.
    let v = 2.0 * atan2_turns(r, d.y);
    (u, v)
}

/// The bilinear blend of `map` at texture coordinates `(u, v)` in `[0, 1]` (module docs:
/// texel centres at `((i + 1/2) / W, (j + 1/2) / H)`, columns wrap, rows clamp).
/// Coordinates outside `[0, 1]` (or NaN) are the caller's error; they read a texel of the
/// map or give NaN, never out of bounds. WGSL: `sample_bilinear`.
#[inline]
pub fn sample_bilinear(map: &EnvironmentMap, u: f32, v: f32) -> Vec3 {
    sample_bilinear_grid(map.width(), map.height(), |i, j| Vec3::from_slice(&map.texel(i, j)[..3]), u, v)
}

/// [`sample_bilinear`] on any `w` x `h` lat-long grid laid out as the maps are, its texel
/// `(i, j)` read by `texel`: the one filter of the environment's map and of the
/// image-based light's prefiltered levels ([`crate::kernels::ibl`]). `w` and `h` are at
/// least 1. WGSL: `sample_bilinear` and `sample_prefiltered_level`, the same operations.
#[inline]
pub fn sample_bilinear_grid(w: u32, h: u32, texel: impl Fn(u32, u32) -> Vec3, u: f32, v: f32) -> Vec3 {
    let (w, h) = (w as i32, h as i32);
    let x = u * w as f32 - 0.5;
    let y = v * h as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    // x in [-1/2, W - 1/2] for u in [0, 1]: the floor is in [-1, W - 1]. The clamp only
    // guards the caller's errors (the float-to-int conversion saturates, NaN gives 0).
    let i0 = (x0 as i32).clamp(-1, w - 1);
    let i0 = if i0 < 0 { w - 1 } else { i0 };
    let i1 = if i0 + 1 >= w { 0 } else { i0 + 1 };
    let j = y0 as i32;
    let j0 = j.clamp(0, h - 1);
    let j1 = (j + 1).clamp(0, h - 1);
    let t = |i: i32, j: i32| texel(i as u32, j as u32);
    let lerp = |a: Vec3, b: Vec3, f: f32| a + (b - a) * f;
    let top = lerp(t(i0, j0), t(i1, j0), fx);
    let bottom = lerp(t(i0, j1), t(i1, j1), fx);
    lerp(top, bottom, fy)
}

/// The radiance of `map` seen along `d`: [`sample_bilinear`] at [`direction_to_uv`].
#[inline]
pub fn map_radiance(map: &EnvironmentMap, d: Vec3) -> Vec3 {
    let (u, v) = direction_to_uv(d);
    sample_bilinear(map, u, v)
}

/// What a ray leaving the scene along `d` sees: [`sky`] bit for bit without a map,
/// [`map_radiance`] with one. WGSL: `environment_radiance`.
#[inline]
pub fn environment_radiance(env: &Environment, d: Vec3) -> Vec3 {
    match env {
        Environment::Sky => sky(d),
        Environment::Map(map) => map_radiance(map, d),
    }
}

/// Zenith colour of the default sky (linear RGB).
pub const SKY_ZENITH: [f32; 3] = [0.18, 0.26, 0.45];
/// Horizon colour of the default sky (linear RGB).
pub const SKY_HORIZON: [f32; 3] = [0.55, 0.58, 0.62];
/// Colour below the horizon (the ground) of the default sky (linear RGB).
pub const SKY_GROUND: [f32; 3] = [0.12, 0.11, 0.10];

/// The default sky a secondary ray sees when it leaves a scene without an environment
/// map ([`crate::scene::Environment::Sky`]): above the horizon
/// (+y up) a blend from [`SKY_HORIZON`] to [`SKY_ZENITH`] by the height `y = d.y / |d|`
/// of the direction, `horizon + (zenith - horizon) y`; below it, [`SKY_GROUND`]. Primary
/// misses keep the frame's [`crate::kernels::shading::BACKGROUND`].
#[inline]
pub fn sky(d: Vec3) -> Vec3 {
    let len = d.dot(d).sqrt();
    let y = d.y / len;
    if y.is_nan() || y < 0.0 {
        return Vec3::from(SKY_GROUND);
    }
    let horizon = Vec3::from(SKY_HORIZON);
    horizon + (Vec3::from(SKY_ZENITH) - horizon) * y
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::TAU;
    use std::sync::Arc;

    /// `atan2(y, x) / 2 pi` in f64, the reference.
    fn turns_f64(y: f32, x: f32) -> f64 {
        (y as f64).atan2(x as f64) / TAU
    }

    /// The distance of two angles in turns, across the +-1/2 cut.
    fn turn_distance(a: f64, b: f64) -> f64 {
        let d = (a - b).rem_euclid(1.0);
        d.min(1.0 - d)
    }

    #[test]
    fn atan2_turns_is_exact_on_the_axes_and_octant_diagonals() {
        assert_eq!(atan2_turns(0.0, 1.0), 0.0);
        assert_eq!(atan2_turns(1.0, 0.0), 0.25);
        assert_eq!(atan2_turns(0.0, -1.0), 0.5);
        assert_eq!(atan2_turns(-1.0, 0.0), -0.25);
        assert_eq!(atan2_turns(-0.0, -1.0), 0.5, "signs of zero are ignored");
        assert_eq!(atan2_turns(0.0, 0.0), 0.0);
        assert_eq!(atan2_turns(3.0, 3.0), 0.125);
        assert_eq!(atan2_turns(-2.0, -2.0), -0.375);
    }

    /// A dense sweep around the circle and near every octant boundary, where the
    /// reduction switches branches.
    #[test]
    fn atan2_turns_error_is_within_its_bound_around_the_circle() {
        let mut worst = 0.0f64;
        let n = 200_000;
        for k in 0..n {
            let a = k as f64 / n as f64 * TAU;
            let (y, x) = (a.sin() as f32, a.cos() as f32);
            worst = worst.max(turn_distance(atan2_turns(y, x) as f64, turns_f64(y, x)));
        }
        for t in [TAN_PI_8, 1.0] {
            for ulps in -64i32..=64 {
                let r = f32::from_bits((t.to_bits() as i32 + ulps) as u32);
                for (y, x) in [(r, 1.0), (1.0, r), (-r, 1.0), (r, -1.0), (-1.0, -r)] {
                    worst = worst.max(turn_distance(atan2_turns(y, x) as f64, turns_f64(y, x)));
                }
            }
        }
        assert!(worst <= ATAN2_TURNS_MAX_ERROR as f64, "worst error {worst:e} turns");
    }

    #[test]
    fn the_sky_is_continuous_at_the_horizon_from_above() {
        assert_eq!(sky(Vec3::X), Vec3::from(SKY_HORIZON));
        assert_eq!(sky(Vec3::Y * 3.0), Vec3::from(SKY_ZENITH));
        assert_eq!(sky(-Vec3::Y), Vec3::from(SKY_GROUND));
    }

    proptest! {
        /// Over directions of the whole sphere, any scale.
        #[test]
        fn atan2_turns_matches_f64(y in -1.0e3f32..1.0e3, x in -1.0e3f32..1.0e3) {
            let e = turn_distance(atan2_turns(y, x) as f64, turns_f64(y, x));
            prop_assert!(e <= ATAN2_TURNS_MAX_ERROR as f64, "atan2_turns({y}, {x}): error {e:e}");
        }

        /// The latitude and longitude of random unit directions against f64.
        #[test]
        fn direction_to_uv_matches_f64(x in -1.0f32..1.0, y in -1.0f32..1.0, z in -1.0f32..1.0) {
            let d = Vec3::new(x, y, z);
            prop_assume!(d.length() > 1e-3);
            let (u, v) = direction_to_uv(d);
            let dd = d.as_dvec3();
            let u_ref = (dd.x.atan2(-dd.z) / TAU).rem_euclid(1.0);
            let v_ref = dd.x.hypot(dd.z).atan2(dd.y) / std::f64::consts::PI;
            prop_assert!((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v));
            prop_assert!(turn_distance(u as f64, u_ref) <= ATAN2_TURNS_MAX_ERROR as f64 * 2.0, "u {u} vs {u_ref}");
            // v doubles an atan2 in turns, of a rounded sqrt (half an ulp, relative).
            prop_assert!((v as f64 - v_ref).abs() <= ATAN2_TURNS_MAX_ERROR as f64 * 4.0, "v {v} vs {v_ref}");
        }
    }

    /// A map whose texels are all different, and not linear in the indices (so the mean
    /// of two columns, or two rows, names them): texel (i, j) is
    /// `(i^2 / W, j^2 / H, (7 i + 3 j) mod 11)`, dyadic values a blend of halves keeps exact.
    fn numbered(w: u32, h: u32) -> EnvironmentMap {
        let texels = (0..h)
            .flat_map(|j| {
                (0..w).map(move |i| {
                    [(i * i) as f32 / w as f32, (j * j) as f32 / h as f32, ((7 * i + 3 * j) % 11) as f32, 1.0]
                })
            })
            .collect();
        EnvironmentMap::new(w, h, texels).unwrap()
    }

    fn mean(map: &EnvironmentMap, texels: &[(u32, u32)]) -> Vec3 {
        texels.iter().map(|&(i, j)| Vec3::from_slice(&map.texel(i, j)[..3])).sum::<Vec3>() / texels.len() as f32
    }

    /// Tolerance of lookups against a blend of texels computed by hand: the weights are
    /// off by at most the error of `u W` and `v H` (the atan error, a few 1e-8 turns,
    /// times 16 texels: 1e-6) and neighbouring texels differ by at most 15 here.
    const LOOKUP_TOL: f32 = 1e-4;

    #[test]
    fn the_axes_read_the_texels_the_docs_name() {
        // 8 x 4: u = 0, 1/4, 1/2, 3/4 lie on column boundaries 8u - 1/2 = -1/2, 3/2, 7/2,
        // 11/2; v = 1/2 (the horizon) between rows 1 and 2; v = 0 and 1 beyond the centres
        // of the first and last rows (clamped).
        let m = Environment::Map(Arc::new(numbered(8, 4)));
        let map = m.map().unwrap();
        let close = |d: Vec3, want: Vec3| {
            let got = environment_radiance(&m, d);
            assert!((got - want).abs().max_element() < LOOKUP_TOL, "{d}: {got} vs {want}");
        };
        // -Z: the seam, the last and the first column.
        close(Vec3::NEG_Z, mean(map, &[(7, 1), (0, 1), (7, 2), (0, 2)]));
        close(Vec3::X, mean(map, &[(1, 1), (2, 1), (1, 2), (2, 2)]));
        close(Vec3::Z, mean(map, &[(3, 1), (4, 1), (3, 2), (4, 2)]));
        close(Vec3::NEG_X, mean(map, &[(5, 1), (6, 1), (5, 2), (6, 2)]));
        // Straight up and down: the first and the last row, at u = 0.
        close(Vec3::Y, mean(map, &[(7, 0), (0, 0)]));
        close(Vec3::NEG_Y, mean(map, &[(7, 3), (0, 3)]));
        // Exactly, where the arithmetic is exact (weights of 1/2).
        assert_eq!(environment_radiance(&m, Vec3::Z * 5.0), mean(map, &[(3, 1), (4, 1), (3, 2), (4, 2)]));
    }

    #[test]
    fn a_texel_centre_reads_that_texel() {
        let map = numbered(16, 8);
        let (w, h) = (16.0f64, 8.0f64);
        for j in 0..8 {
            for i in 0..16 {
                let (u, v) = ((i as f64 + 0.5) / w, (j as f64 + 0.5) / h);
                let (phi, theta) = (TAU * u, std::f64::consts::PI * v);
                let d = glam::DVec3::new(theta.sin() * phi.sin(), theta.cos(), -theta.sin() * phi.cos());
                let got = map_radiance(&map, d.as_vec3());
                let want = Vec3::from_slice(&map.texel(i, j)[..3]);
                assert!((got - want).abs().max_element() < LOOKUP_TOL, "({i}, {j}): {got} vs {want}");
            }
        }
    }

    #[test]
    fn without_a_map_the_environment_is_the_sky_bit_for_bit() {
        for d in [Vec3::X, Vec3::new(0.3, 0.8, -0.2), Vec3::new(0.1, -0.9, 0.3), Vec3::NEG_Z * 3.0] {
            assert_eq!(environment_radiance(&Environment::Sky, d).to_array(), sky(d).to_array());
        }
    }

    #[test]
    fn a_one_texel_map_is_uniform() {
        let map = EnvironmentMap::new(1, 1, vec![[0.25, 0.5, 2.0, 1.0]]).unwrap();
        for d in [Vec3::X, Vec3::NEG_Y, Vec3::new(-0.3, 0.2, 0.9), Vec3::NEG_Z] {
            assert_eq!(map_radiance(&map, d), Vec3::new(0.25, 0.5, 2.0), "{d}");
        }
    }
}
