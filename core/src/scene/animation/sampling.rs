//! Keyframe sampling: the glTF 2.0 interpolation rules as pure functions (the specification,
//! section 3.11 "Animations", and Appendix C "Interpolation").
//!
//! * [`locate`] finds where a time falls among strictly increasing key times: clamped to the
//!   first key before it (and for NaN), to the last key after it, on a key exactly, or between
//!   two keys at a fraction `s` in (0, 1].
//! * [`step`], [`lerp`], [`slerp`] and [`cubic_hermite`] interpolate one interval.
//! * [`sample_vec3`] and [`sample_rotation`] put them together for a sampler's keyframes.
//!
//! On a key (and clamped) every function returns the key's stored value bit for bit; only
//! values between keys are computed (and, for rotations, normalized). These run on the CPU
//! when a scene is posed, before a frame is prepared, so both backends see the same
//! transforms: unlike the frame kernels they may call the platform's `acos` and `sin`.

use glam::{Quat, Vec3, Vec4};

/// How a keyframe sampler interpolates between its keys (glTF `sampler.interpolation`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// The value of the last key at or before the time (`STEP`).
    Step,
    /// Linear interpolation; spherical linear for rotations (`LINEAR`, the glTF default).
    Linear,
    /// Cubic Hermite spline through the keys with an in-tangent and an out-tangent per key
    /// (`CUBICSPLINE`): the output holds `[in-tangent, value, out-tangent]` per key.
    CubicSpline,
}

impl Interpolation {
    /// The name glTF uses.
    pub const fn name(self) -> &'static str {
        match self {
            Interpolation::Step => "STEP",
            Interpolation::Linear => "LINEAR",
            Interpolation::CubicSpline => "CUBICSPLINE",
        }
    }

    /// Output elements per key: 3 for `CUBICSPLINE` (in-tangent, value, out-tangent), else 1.
    pub const fn outputs_per_key(self) -> usize {
        match self {
            Interpolation::CubicSpline => 3,
            Interpolation::Step | Interpolation::Linear => 1,
        }
    }
}

/// Where a time falls among a sampler's key times.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum KeyPosition {
    /// On key `k`: exactly at its time, or clamped to it (before the first key, after the
    /// last, or a NaN time, which takes the first).
    Key(usize),
    /// Between key `key` and key `key + 1`: `s` in (0, 1] is the fraction of the interval
    /// elapsed, `interval` its length in seconds (> 0).
    Between { key: usize, s: f32, interval: f32 },
}

/// Where `t` falls among `times` (finite, strictly increasing, at least one; the loader
/// checks this). Times outside the keys clamp to the nearest end, as glTF requires.
///
/// ```
/// use hyrt_core::scene::animation::{locate, KeyPosition};
/// let times = [0.0, 1.0, 3.0];
/// assert_eq!(locate(&times, -1.0), KeyPosition::Key(0));
/// assert_eq!(locate(&times, 1.0), KeyPosition::Key(1));
/// assert_eq!(locate(&times, 2.0), KeyPosition::Between { key: 1, s: 0.5, interval: 2.0 });
/// assert_eq!(locate(&times, 9.0), KeyPosition::Key(2));
/// ```
pub fn locate(times: &[f32], t: f32) -> KeyPosition {
    // Keys at or before `t`; NaN compares false, so a NaN time counts none and takes key 0.
    let at_or_before = times.partition_point(|&k| k <= t);
    if at_or_before == 0 {
        return KeyPosition::Key(0);
    }
    let key = at_or_before - 1;
    if key + 1 == times.len() {
        return KeyPosition::Key(key);
    }
    let interval = times[key + 1] - times[key];
    let s = (t - times[key]) / interval;
    // `t` past a key by less than the interval's resolution rounds to the key itself.
    if s == 0.0 {
        KeyPosition::Key(key)
    } else {
        KeyPosition::Between { key, s, interval }
    }
}

/// `STEP`: the value of the key at or before the time, whatever `s` is.
pub fn step<T: Copy>(a: T, _b: T, _s: f32) -> T {
    a
}

/// `LINEAR` for vectors: `(1 - s) a + s b`, as the specification writes it.
pub fn lerp(a: Vec3, b: Vec3, s: f32) -> Vec3 {
    a * (1.0 - s) + b * s
}

/// Quaternions closer than this (the cosine of half the angle between the rotations, after
/// taking the shorter arc) are interpolated linearly and normalized instead of by angle: at
/// 0.9995 the half-angle is at most 0.032 rad, where the f32 rounding of the dot product
/// (about 6e-8) already moves `acos` by 2e-6 rad, about as much as the normalized linear
/// interpolation deviates from the great arc there (under the half-angle cubed over 16).
pub const SLERP_LINEAR_COSINE: f32 = 0.9995;

/// `LINEAR` for rotations: spherical linear interpolation of unit quaternions along the
/// shorter arc (`b` negated when `a . b < 0`, since `q` and `-q` are the same rotation),
/// normalized.
///
/// ```
/// use hyrt_core::glam::Quat;
/// use hyrt_core::scene::animation::slerp;
/// let a = Quat::IDENTITY;
/// let b = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
/// let half = slerp(a, b, 0.5);
/// assert!(half.angle_between(Quat::from_rotation_y(std::f32::consts::FRAC_PI_4)) < 1e-3);
/// // -b is the same rotation: the same half-way rotation.
/// assert!(slerp(a, -b, 0.5).angle_between(half) < 1e-3);
/// ```
pub fn slerp(a: Quat, b: Quat, s: f32) -> Quat {
    let (a, mut b) = (Vec4::from(a), Vec4::from(b));
    let mut cos = a.dot(b);
    if cos < 0.0 {
        b = -b;
        cos = -cos;
    }
    let mixed = if cos > SLERP_LINEAR_COSINE {
        a * (1.0 - s) + b * s
    } else {
        let angle = cos.min(1.0).acos();
        let sin = angle.sin();
        a * (((1.0 - s) * angle).sin() / sin) + b * ((s * angle).sin() / sin)
    };
    Quat::from_vec4(mixed.normalize())
}

/// `CUBICSPLINE` on one interval (Appendix C): the Hermite curve from value `v0` with
/// out-tangent `b0` to value `v1` with in-tangent `a1`, at fraction `s` of an interval of
/// `interval` seconds. The tangents are per second, hence scaled by the interval:
///
/// `p(s) = (2s^3 - 3s^2 + 1) v0 + interval (s^3 - 2s^2 + s) b0 + (-2s^3 + 3s^2) v1 + interval (s^3 - s^2) a1`.
pub fn cubic_hermite(v0: Vec4, b0: Vec4, v1: Vec4, a1: Vec4, s: f32, interval: f32) -> Vec4 {
    let s2 = s * s;
    let s3 = s2 * s;
    v0 * (2.0 * s3 - 3.0 * s2 + 1.0)
        + b0 * (interval * (s3 - 2.0 * s2 + s))
        + v1 * (-2.0 * s3 + 3.0 * s2)
        + a1 * (interval * (s3 - s2))
}

/// A sampler's value at `t`: `values` holds one value per key, or for `CUBICSPLINE` three,
/// `[in-tangent, value, out-tangent]`, which `cubic` gets as `[v0, b0, v1, a1]` (value and
/// out-tangent of the key before, value and in-tangent of the key after) with `s` and the
/// interval's length.
fn sample<T: Copy>(
    interpolation: Interpolation,
    times: &[f32],
    values: &[T],
    t: f32,
    linear: impl Fn(T, T, f32) -> T,
    cubic: impl Fn([T; 4], f32, f32) -> T,
) -> T {
    let per_key = interpolation.outputs_per_key();
    let value = |k: usize| values[k * per_key + per_key / 2];
    match locate(times, t) {
        KeyPosition::Key(k) => value(k),
        KeyPosition::Between { key, s, interval } => match interpolation {
            Interpolation::Step => step(value(key), value(key + 1), s),
            Interpolation::Linear => linear(value(key), value(key + 1), s),
            Interpolation::CubicSpline => {
                cubic([values[key * 3 + 1], values[key * 3 + 2], values[key * 3 + 4], values[key * 3 + 3]], s, interval)
            }
        },
    }
}

/// A translation or scale sampler's value at `t`: `values` holds one vector per key (three,
/// `[in-tangent, value, out-tangent]`, for `CUBICSPLINE`).
pub fn sample_vec3(interpolation: Interpolation, times: &[f32], values: &[Vec3], t: f32) -> Vec3 {
    sample(interpolation, times, values, t, lerp, |[v0, b0, v1, a1], s, interval| {
        cubic_hermite(v0.extend(0.0), b0.extend(0.0), v1.extend(0.0), a1.extend(0.0), s, interval).truncate()
    })
}

/// A rotation sampler's value at `t`, a unit quaternion (the keys are stored unit, as the
/// loader normalizes them): `values` as for [`sample_vec3`]. Between keys `LINEAR` is
/// [`slerp`] and `CUBICSPLINE` the Hermite curve of the quaternions' components, normalized.
pub fn sample_rotation(interpolation: Interpolation, times: &[f32], values: &[Quat], t: f32) -> Quat {
    sample(interpolation, times, values, t, slerp, |[v0, b0, v1, a1], s, interval| {
        let mixed = cubic_hermite(v0.into(), b0.into(), v1.into(), a1.into(), s, interval);
        Quat::from_vec4(mixed.normalize())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

    /// Interpolated rotations go through `acos`, `sin` and a normalization in f32: a few ulp
    /// of 1 in each component.
    const ROTATION_TOLERANCE: f32 = 1e-6;
    /// Hermite polynomials of `s` in f32 against the cubic evaluated directly, values of
    /// size up to 52: a few ulp of 52.
    const HERMITE_TOLERANCE: f32 = 2e-5;

    fn near(a: Quat, b: Quat) -> bool {
        // q and -q are the same rotation.
        Vec4::from(a).abs_diff_eq(Vec4::from(b), ROTATION_TOLERANCE)
            || Vec4::from(a).abs_diff_eq(-Vec4::from(b), ROTATION_TOLERANCE)
    }

    #[test]
    fn locate_clamps_lands_on_keys_and_splits_intervals() {
        let times = [0.5, 1.0, 2.0];
        assert_eq!(locate(&times, 0.0), KeyPosition::Key(0), "before the first key");
        assert_eq!(locate(&times, 0.5), KeyPosition::Key(0));
        assert_eq!(locate(&times, 0.75), KeyPosition::Between { key: 0, s: 0.5, interval: 0.5 });
        assert_eq!(locate(&times, 1.0), KeyPosition::Key(1));
        assert_eq!(locate(&times, 1.25), KeyPosition::Between { key: 1, s: 0.25, interval: 1.0 });
        assert_eq!(locate(&times, 2.0), KeyPosition::Key(2));
        assert_eq!(locate(&times, 1e9), KeyPosition::Key(2), "after the last key");
        assert_eq!(locate(&times, f32::INFINITY), KeyPosition::Key(2));
        assert_eq!(locate(&times, f32::NEG_INFINITY), KeyPosition::Key(0));
        assert_eq!(locate(&times, f32::NAN), KeyPosition::Key(0), "NaN takes the first key");
        assert_eq!(locate(&[3.0], 7.0), KeyPosition::Key(0), "a single key");
    }

    #[test]
    fn step_holds_the_earlier_key_until_the_next() {
        let times = [0.0, 1.0, 2.0];
        let values = [Vec3::ZERO, Vec3::X, Vec3::Y];
        for (t, expected) in [
            (-1.0, Vec3::ZERO),
            (0.0, Vec3::ZERO),
            (0.999, Vec3::ZERO),
            (1.0, Vec3::X),
            (1.5, Vec3::X),
            (2.0, Vec3::Y),
            (5.0, Vec3::Y),
        ] {
            assert_eq!(sample_vec3(Interpolation::Step, &times, &values, t), expected, "t = {t}");
        }
    }

    #[test]
    fn linear_interpolates_vectors_and_clamps() {
        let times = [1.0, 3.0];
        let values = [Vec3::new(0.0, 2.0, -4.0), Vec3::new(4.0, 2.0, 0.0)];
        // s = 0.25 and 0.75 are exact in binary: the results are exact.
        assert_eq!(sample_vec3(Interpolation::Linear, &times, &values, 1.5), Vec3::new(1.0, 2.0, -3.0));
        assert_eq!(sample_vec3(Interpolation::Linear, &times, &values, 2.5), Vec3::new(3.0, 2.0, -1.0));
        assert_eq!(sample_vec3(Interpolation::Linear, &times, &values, 0.0), values[0]);
        assert_eq!(sample_vec3(Interpolation::Linear, &times, &values, 4.0), values[1]);
    }

    #[test]
    fn slerp_follows_the_arc_at_constant_speed() {
        let a = Quat::from_rotation_z(0.0);
        let b = Quat::from_rotation_z(FRAC_PI_2);
        for s in [0.1f32, 0.25, 0.5, 0.9] {
            assert!(near(slerp(a, b, s), Quat::from_rotation_z(FRAC_PI_2 * s)), "s = {s}");
        }
        // Half-way between 0 and 270 degrees about Z the short way is -45 degrees (via 0 -> -90).
        let far = Quat::from_rotation_z(3.0 * FRAC_PI_2);
        assert!(a.dot(far) < 0.0, "270 degrees is the long way round");
        assert!(near(slerp(a, far, 0.5), Quat::from_rotation_z(-FRAC_PI_4)));
    }

    #[test]
    fn slerp_takes_the_shorter_arc_for_q_and_minus_q() {
        let a = Quat::from_rotation_x(0.3);
        let b = Quat::from_rotation_y(1.1);
        for s in [0.2f32, 0.5, 0.8] {
            assert!(near(slerp(a, b, s), slerp(a, -b, s)), "s = {s}");
            assert!(near(slerp(-a, b, s), slerp(a, b, s)), "s = {s}");
        }
        // Rotations 180 degrees apart as quaternions q and -q: no motion at all.
        assert!(near(slerp(a, -a, 0.5), a));
    }

    #[test]
    fn slerp_of_nearly_equal_rotations_is_linear_and_unit() {
        let a = Quat::from_rotation_y(1.0);
        let b = Quat::from_rotation_y(1.0 + 1e-3);
        let m = slerp(a, b, 0.5);
        assert!((m.length() - 1.0).abs() <= ROTATION_TOLERANCE);
        assert!(near(m, Quat::from_rotation_y(1.0 + 0.5e-3)));
    }

    #[test]
    fn step_and_linear_rotation_keys() {
        let times = [0.0, 2.0];
        let values = [Quat::IDENTITY, Quat::from_rotation_x(PI / 3.0)];
        assert_eq!(sample_rotation(Interpolation::Step, &times, &values, 1.9), values[0]);
        assert_eq!(sample_rotation(Interpolation::Step, &times, &values, 2.0), values[1]);
        assert!(near(sample_rotation(Interpolation::Linear, &times, &values, 1.0), Quat::from_rotation_x(PI / 6.0)));
        assert_eq!(sample_rotation(Interpolation::Linear, &times, &values, -3.0), values[0]);
        assert_eq!(sample_rotation(Interpolation::Linear, &times, &values, 30.0), values[1]);
    }

    #[test]
    fn cubic_spline_reproduces_a_cubic_with_known_tangents() {
        // f(t) = t^3 - t + 2 on keys 0, 1, 3: f' = 3t^2 - 1. A cubic Hermite segment with the
        // exact end values and derivatives (per second) is the cubic itself.
        let f = |t: f32| t * t * t - t + 2.0;
        let df = |t: f32| 3.0 * t * t - 1.0;
        let times = [0.0f32, 1.0, 3.0];
        let values: Vec<Vec3> = times
            .iter()
            .flat_map(|&t| {
                let along = |v: f32| Vec3::new(v, 2.0 * v, -v);
                [along(df(t)), along(f(t)), along(df(t))]
            })
            .collect();
        // In-tangent and out-tangent are separate: the first key's in-tangent and the last
        // key's out-tangent are unused.
        for t in [0.0f32, 0.25, 0.5, 1.0, 1.5, 2.0, 2.75, 3.0] {
            let v = sample_vec3(Interpolation::CubicSpline, &times, &values, t);
            let e = Vec3::new(f(t), 2.0 * f(t), -f(t));
            assert!(v.abs_diff_eq(e, HERMITE_TOLERANCE), "t = {t}: {v} against {e}");
        }
        // Hand-computed: at t = 2 (s = 1/2 of the 2-second interval from 1 to 3),
        // p = 0.5 * 2 + 2 * 0.125 * 2 + 0.5 * 26 + 2 * (-0.125) * 26 = 1 + 0.5 + 13 - 6.5 = 8 = f(2).
        assert_eq!(sample_vec3(Interpolation::CubicSpline, &times, &values, 2.0).x, 8.0);
        assert_eq!(
            sample_vec3(Interpolation::CubicSpline, &times, &values, -1.0),
            values[1],
            "clamped to key 0's value"
        );
        assert_eq!(
            sample_vec3(Interpolation::CubicSpline, &times, &values, 4.0),
            values[7],
            "clamped to the last value"
        );
    }

    #[test]
    fn cubic_spline_rotation_is_normalized() {
        // Zero tangents: an ease-in-out between two rotations, normalized at every time.
        let zero = Quat::from_xyzw(0.0, 0.0, 0.0, 0.0);
        let values = [zero, Quat::IDENTITY, zero, zero, Quat::from_rotation_z(FRAC_PI_2), zero];
        let times = [0.0, 1.0];
        for t in [0.1f32, 0.5, 0.9] {
            let q = sample_rotation(Interpolation::CubicSpline, &times, &values, t);
            assert!((q.length() - 1.0).abs() <= ROTATION_TOLERANCE, "t = {t}");
        }
        // Symmetric weights at s = 1/2: the half-way rotation.
        let mid = sample_rotation(Interpolation::CubicSpline, &times, &values, 0.5);
        assert!(near(mid, Quat::from_rotation_z(FRAC_PI_4)));
    }

    fn unit_quat() -> impl Strategy<Value = Quat> {
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0)
            .prop_filter("not near zero", |(x, y, z, w)| x * x + y * y + z * z + w * w > 1e-2)
            .prop_map(|(x, y, z, w)| Quat::from_xyzw(x, y, z, w).normalize())
    }

    /// Strictly increasing key times from positive gaps.
    fn key_times(n: usize) -> impl Strategy<Value = Vec<f32>> {
        prop::collection::vec(1e-3f32..10.0, n).prop_map(|gaps| {
            gaps.iter()
                .scan(0.0f32, |t, g| {
                    let key = *t;
                    *t += g;
                    Some(key)
                })
                .collect()
        })
    }

    proptest! {
        #[test]
        fn slerp_is_unit_length(a in unit_quat(), b in unit_quat(), s in 0.0f32..=1.0) {
            let q = slerp(a, b, s);
            prop_assert!((q.length() - 1.0).abs() <= ROTATION_TOLERANCE, "{q} has length {}", q.length());
        }

        #[test]
        fn linear_and_step_return_the_keys_exactly_at_key_times(
            times in key_times(5),
            vectors in prop::collection::vec(prop::array::uniform3(-1e3f32..1e3), 5),
            rotations in prop::collection::vec(unit_quat(), 5),
        ) {
            let vectors: Vec<Vec3> = vectors.into_iter().map(Vec3::from).collect();
            for mode in [Interpolation::Step, Interpolation::Linear] {
                for (k, &t) in times.iter().enumerate() {
                    prop_assert_eq!(sample_vec3(mode, &times, &vectors, t), vectors[k]);
                    prop_assert_eq!(sample_rotation(mode, &times, &rotations, t), rotations[k]);
                }
            }
        }
    }
}
