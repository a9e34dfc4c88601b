//! The shadow-ray kernels of `compaction` over eight surfaces at once: core's
//! [`needs_shadow_ray`] (with [`light_incidence`] and [`light_can_contribute`]) and
//! [`shadow_ray`] (with [`offset_ray_origin`], [`next_float_up`] and [`next_float_down`]),
//! each lane doing the scalar kernel's operations in its order, every one a correctly
//! rounded IEEE 754 f32 operation or a bit operation ([`Lanes`]), so that every lane's
//! answer and ray are the scalar kernel's bits. `tests` pins them to the scalar kernels.
//!
//! The origin of a surface's shadow rays does not depend on the light, so
//! [`SurfaceLanes::load`] offsets it once and [`shadow_rays_lanes`] gives each light the
//! directions alone.
//!
//! [`needs_shadow_ray`]: hyrt_core::kernels::shadow::needs_shadow_ray
//! [`shadow_ray`]: hyrt_core::kernels::shadow::shadow_ray
//! [`light_incidence`]: hyrt_core::kernels::shading::light_incidence
//! [`light_can_contribute`]: hyrt_core::kernels::shading::light_can_contribute
//! [`offset_ray_origin`]: hyrt_core::kernels::ray::offset_ray_origin
//! [`next_float_up`]: hyrt_core::kernels::ray::next_float_up
//! [`next_float_down`]: hyrt_core::kernels::ray::next_float_down

use hyrt_core::formats::{LightRecord, RayRecord, SurfaceRecord, INVALID_ID, LIGHT_DIRECTIONAL, LIGHT_SPOT};
use hyrt_core::kernels::ray::OFFSET_ERROR_SCALE;
use hyrt_core::kernels::shading::MIN_LIGHT_DISTANCE_SQ;
use hyrt_core::kernels::shadow::{shadow_ray_record, SHADOW_T_MAX_POINT};

use crate::lanes::{dot3, splat3, sub3, words12, Lanes, LANES};

// No closures below (`map`, `from_fn`): a closure does not inherit its caller's target
// features, so lane operations inside one would not inline into the AVX2 entry points.

/// Eight surfaces as lanes: what the shadow-ray kernels read of a [`SurfaceRecord`], and
/// the origin of its shadow rays.
#[derive(Clone, Copy)]
pub(crate) struct SurfaceLanes<L: Lanes> {
    /// All ones where the surface is a hit ([`SurfaceRecord::is_hit`]).
    pub hit: L::F,
    pub position: [L::F; 3],
    pub normal: [L::F; 3],
    pub geometric_normal: [L::F; 3],
    /// `offset_ray_origin(position, position_error, geometric_normal)`.
    pub origin: [L::F; 3],
}

/// The words of eight surface records as lanes, by quads (a transpose in registers,
/// [`Lanes::quad_lanes`]): `[position, position_error]`, `[normal, object]`,
/// `[geometric_normal, triangle]`; and the lanes that are hits
/// ([`SurfaceRecord::is_hit`]: the object word is not `INVALID_ID`, compared as a word).
///
/// It replaced eleven arrays filled word by word and loaded back as vectors, each load
/// waiting on eight scalar stores it cannot be forwarded from.
#[inline(always)]
pub(crate) fn surface_quads<L: Lanes>(s: [&SurfaceRecord; LANES]) -> ([[L::F; 4]; 3], L::F) {
    let quads = L::quad_lanes(words12(s));
    let zero = L::splat(0.0);
    let miss = L::eq_bits(quads[1][3], L::splat(f32::from_bits(INVALID_ID)));
    (quads, L::andnot(miss, L::eq(zero, zero)))
}

impl<L: Lanes> SurfaceLanes<L> {
    /// The lanes of eight surfaces ([`surface_quads`]) and their shadow rays' origins.
    #[inline(always)]
    pub fn load(s: [&SurfaceRecord; LANES]) -> SurfaceLanes<L> {
        let ([p, n, g], hit) = surface_quads::<L>(s);
        let position = [p[0], p[1], p[2]];
        let geometric_normal = [g[0], g[1], g[2]];
        SurfaceLanes {
            hit,
            position,
            normal: [n[0], n[1], n[2]],
            geometric_normal,
            origin: offset_ray_origin_lanes::<L>(position, p[3], geometric_normal),
        }
    }
}

/// Core's `next_float_up` per lane: NaN and `+inf` stay, zeros become the least positive
/// float, others step one ulp up through their bits.
#[inline(always)]
fn next_float_up_lanes<L: Lanes>(x: L::F) -> L::F {
    let zero = L::splat(0.0);
    let x0 = L::select(L::eq(x, zero), zero, x);
    let step = L::select(L::le(zero, x0), L::splat(f32::from_bits(1)), L::splat(f32::from_bits(u32::MAX)));
    let stepped = L::bits_add(x0, step);
    // Not NaN (`x == x`) and not +inf.
    L::select(L::andnot(L::eq(x, L::splat(f32::INFINITY)), L::eq(x, x)), stepped, x)
}

/// Core's `next_float_down` per lane, the mirror of [`next_float_up_lanes`].
#[inline(always)]
fn next_float_down_lanes<L: Lanes>(x: L::F) -> L::F {
    let zero = L::splat(0.0);
    let x0 = L::select(L::eq(x, zero), L::splat(-0.0), x);
    let step = L::select(L::le(x0, zero), L::splat(f32::from_bits(1)), L::splat(f32::from_bits(u32::MAX)));
    let stepped = L::bits_add(x0, step);
    L::select(L::andnot(L::eq(x, L::splat(f32::NEG_INFINITY)), L::eq(x, x)), stepped, x)
}

/// Core's `offset_ray_origin(p, p_error, n)` per lane.
#[inline(always)]
fn offset_ray_origin_lanes<L: Lanes>(p: [L::F; 3], p_error: L::F, n: [L::F; 3]) -> [L::F; 3] {
    let d =
        L::mul(L::add(L::add(L::abs(n[0]), L::abs(n[1])), L::abs(n[2])), L::mul(p_error, L::splat(OFFSET_ERROR_SCALE)));
    [
        offset_coordinate_lanes::<L>(p[0], n[0], d),
        offset_coordinate_lanes::<L>(p[1], n[1], d),
        offset_coordinate_lanes::<L>(p[2], n[2], d),
    ]
}

/// One coordinate of [`offset_ray_origin_lanes`], moved by `n * d`.
#[inline(always)]
fn offset_coordinate_lanes<L: Lanes>(p: L::F, n: L::F, d: L::F) -> L::F {
    let zero = L::splat(0.0);
    let offset = L::mul(n, d);
    let o = L::add(p, offset);
    let down = L::select(L::lt(offset, zero), next_float_down_lanes::<L>(o), o);
    L::select(L::lt(zero, offset), next_float_up_lanes::<L>(o), down)
}

/// Core's `light_incidence(light, p)` per lane: the unit direction towards the light and
/// its irradiance scale.
#[inline(always)]
pub(crate) fn light_incidence_lanes<L: Lanes>(light: &LightRecord, p: [L::F; 3]) -> ([L::F; 3], [L::F; 3]) {
    let pd = splat3::<L>(light.position_or_direction);
    let radiance = splat3::<L>(light.radiance);
    if light.kind == LIGHT_DIRECTIONAL {
        // `-pd` is a sign flip (`0 - x` would give `+0` for `+0`).
        let minus = L::splat(-0.0);
        ([L::xor(pd[0], minus), L::xor(pd[1], minus), L::xor(pd[2], minus)], radiance)
    } else {
        let d = sub3::<L>(pd, p);
        let d2 = L::max(dot3::<L>(d, d), L::splat(MIN_LIGHT_DISTANCE_SQ));
        let len = L::sqrt(d2);
        let l = [L::div(d[0], len), L::div(d[1], len), L::div(d[2], len)];
        let e = [L::div(radiance[0], d2), L::div(radiance[1], d2), L::div(radiance[2], d2)];
        match light_falloff_lanes::<L>(light, l, d2) {
            Some(f) => (l, [L::mul(e[0], f), L::mul(e[1], f), L::mul(e[2], f)]),
            // Core multiplies by exactly 1, which changes no bits.
            None => (l, e),
        }
    }
}

/// Core's `light_falloff(light, l, d2)` per lane, `None` where it is 1 for every lane (a
/// point light without a range).
#[inline(always)]
fn light_falloff_lanes<L: Lanes>(light: &LightRecord, l: [L::F; 3], d2: L::F) -> Option<L::F> {
    let ranged = light.inv_range_sq > 0.0;
    let spot = light.kind == LIGHT_SPOT;
    if !ranged && !spot {
        return None;
    }
    let (zero, one) = (L::splat(0.0), L::splat(1.0));
    let mut f = one;
    if ranged {
        let x = L::mul(d2, L::splat(light.inv_range_sq));
        f = L::min(L::max(L::sub(one, L::mul(x, x)), zero), one);
    }
    if spot {
        // `-dot` is a sign flip, as core's unary minus.
        let cd = L::xor(dot3::<L>(splat3::<L>(light.spot_direction), l), L::splat(-0.0));
        let ramp = L::add(L::mul(cd, L::splat(light.spot_scale)), L::splat(light.spot_offset));
        let a = L::min(L::max(ramp, zero), one);
        f = L::mul(f, L::mul(a, a));
    }
    Some(f)
}

/// Eight surfaces' shadow rays towards one light: which lanes need one (core's
/// `needs_shadow_ray`, bit `k` for lane `k`) and the rays' directions and `t_max` (core's
/// `shadow_ray`, whose origin is [`SurfaceLanes::origin`]).
#[inline(always)]
pub(crate) fn shadow_rays_lanes<L: Lanes>(s: &SurfaceLanes<L>, light: &LightRecord) -> (u32, [L::F; 3], f32) {
    let zero = L::splat(0.0);
    let (l, e) = light_incidence_lanes::<L>(light, s.position);
    let (direction, t_max) = if light.kind == LIGHT_DIRECTIONAL {
        (l, f32::INFINITY)
    } else {
        (sub3::<L>(splat3::<L>(light.position_or_direction), s.origin), SHADOW_T_MAX_POINT)
    };
    // light_can_contribute: glam's max_element is `max(x, max(y, z))` with `a > b ? a : b`.
    let energy = L::lt(zero, L::max(e[0], L::max(e[1], e[2])));
    let facing = L::and(L::lt(zero, dot3::<L>(s.geometric_normal, l)), L::lt(zero, dot3::<L>(s.normal, l)));
    (L::bits(L::and(s.hit, L::and(facing, energy))), direction, t_max)
}

/// The shadow ray of lane `k`: core's `shadow_ray` record from the lanes' origin and
/// direction.
#[inline(always)]
pub(crate) fn shadow_ray_of_lane(
    origin: &[[f32; LANES]; 3],
    direction: &[[f32; LANES]; 3],
    t_max: f32,
    k: usize,
    light_index: u32,
    pixel: u32,
) -> RayRecord {
    let lane = |v: &[[f32; LANES]; 3]| [v[0][k], v[1][k], v[2][k]];
    shadow_ray_record(lane(origin), lane(direction), t_max, light_index, pixel)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::lanes::{store3, Portable};
    use hyrt_core::kernels::shadow::{needs_shadow_ray, shadow_ray};
    use proptest::prelude::*;

    /// The lanes' answers and rays against the scalar kernels, bit for bit.
    fn check<L: Lanes>(surfaces: &[SurfaceRecord; LANES], light: &LightRecord) -> Result<(), TestCaseError> {
        let s = SurfaceLanes::<L>::load(std::array::from_fn(|k| &surfaces[k]));
        let (active, direction, t_max) = shadow_rays_lanes::<L>(&s, light);
        let (origin, direction) = (store3::<L>(s.origin), store3::<L>(direction));
        for (k, surface) in surfaces.iter().enumerate() {
            let want = needs_shadow_ray(surface, light);
            prop_assert_eq!(active >> k & 1 == 1, want, "lane {}: needs_shadow_ray of {:?}", k, surface);
            if surface.is_hit() {
                let want = shadow_ray(surface, light, 3, 77);
                let got = shadow_ray_of_lane(&origin, &direction, t_max, k, 3, 77);
                prop_assert_eq!(
                    bytemuck::bytes_of(&got),
                    bytemuck::bytes_of(&want),
                    "lane {}: {:?} vs {:?}",
                    k,
                    got,
                    want
                );
            }
        }
        Ok(())
    }

    fn check_levels(surfaces: &[SurfaceRecord; LANES], light: &LightRecord) -> Result<(), TestCaseError> {
        check::<Portable>(surfaces, light)?;
        #[cfg(target_arch = "x86_64")]
        {
            check::<crate::lanes::Sse2>(surfaces, light)?;
            if is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 detected just above.
                unsafe { check_avx2(surfaces, light)? };
            }
        }
        Ok(())
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn check_avx2(surfaces: &[SurfaceRecord; LANES], light: &LightRecord) -> Result<(), TestCaseError> {
        check::<crate::lanes::Avx2>(surfaces, light)
    }

    /// Floats of every kind the kernels meet: signed zeros, tiny and huge magnitudes,
    /// values near the light, and ordinary ones.
    pub(crate) fn coord() -> impl Strategy<Value = f32> {
        prop_oneof![
            4 => -20.0f32..20.0,
            1 => Just(0.0f32),
            1 => Just(-0.0f32),
            1 => -1e-6f32..1e-6,
            1 => -1e30f32..1e30,
            1 => any::<f32>().prop_filter("finite", |x| x.is_finite()),
        ]
    }

    pub(crate) fn vec3() -> impl Strategy<Value = [f32; 3]> {
        [coord(), coord(), coord()]
    }

    /// A unit-ish normal, a zero one (a degenerate triangle), or any vector.
    fn normal() -> impl Strategy<Value = [f32; 3]> {
        prop_oneof![
            4 => vec3().prop_map(|v| {
                let n = glam::Vec3::from(v).normalize_or_zero();
                n.into()
            }),
            1 => Just([0.0f32; 3]),
            1 => vec3(),
        ]
    }

    fn surface() -> impl Strategy<Value = SurfaceRecord> {
        (any::<bool>(), vec3(), 0.0f32..1e-2, normal(), normal()).prop_map(|(hit, position, err, normal, geometric)| {
            if !hit {
                return SurfaceRecord::MISS;
            }
            SurfaceRecord { position, position_error: err, normal, object: 1, geometric_normal: geometric, triangle: 2 }
        })
    }

    fn light() -> impl Strategy<Value = LightRecord> {
        light_with(0.0f32..100.0)
    }

    /// Point, directional and spot lights (with and without a range, cones from narrow to
    /// a half space) of radiance components drawn from `radiance`, as
    /// `LightRecord::from_light` makes them.
    pub(crate) fn light_with(radiance: impl Strategy<Value = f32> + Clone) -> impl Strategy<Value = LightRecord> {
        use glam::Vec3;
        use hyrt_core::scene::Light;
        let range = prop::option::of(prop_oneof![1e-3f32..1.0, 1.0f32..100.0]);
        let cone = (1e-3f32..std::f32::consts::FRAC_PI_2, 0.0f32..1.0);
        (0..3u32, vec3(), [radiance.clone(), radiance.clone(), radiance], range, vec3(), cone).prop_map(
            |(kind, p, radiance, range, axis, (outer, inner))| {
                let (position, color) = (Vec3::from(p), Vec3::from(radiance));
                let light = match kind {
                    0 => Light::Point { position, color, intensity: 1.0, range },
                    1 => Light::Directional { direction: position.normalize_or(Vec3::Y), color, intensity: 1.0 },
                    _ => Light::Spot {
                        position,
                        direction: Vec3::from(axis).normalize_or(Vec3::NEG_Y),
                        color,
                        intensity: 1.0,
                        inner_cone_angle: outer * inner,
                        outer_cone_angle: outer,
                        range,
                    },
                };
                LightRecord::from_light(&light)
            },
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2048))]

        #[test]
        fn shadow_ray_lanes_are_the_scalar_kernels(surfaces in prop::collection::vec(surface(), LANES), light in light()) {
            // (A vector, not `uniform8`: eight nested value trees overflow a test thread's stack.)
            let surfaces: [SurfaceRecord; LANES] = surfaces.try_into().expect("LANES surfaces");
            check_levels(&surfaces, &light)?;
        }
    }

    /// Surfaces on and around the light, with the offsets' edge cases: a zero error, a
    /// zero normal, coordinates at zero and at the largest floats.
    #[test]
    fn shadow_ray_lanes_on_hard_cases() {
        let light = LightRecord::point([1.0, 2.0, 3.0], [1.0, 0.0, 0.0]);
        let s = |position: [f32; 3], err: f32, n: [f32; 3]| SurfaceRecord {
            position,
            position_error: err,
            normal: n,
            object: 0,
            geometric_normal: n,
            triangle: 0,
        };
        let surfaces = [
            s([1.0, 2.0, 3.0], 0.0, [0.0, 1.0, 0.0]),
            s([1.0, 1.0, 3.0], 1e-3, [0.0, 1.0, 0.0]),
            s([0.0, -0.0, 0.0], 1e-7, [0.6, 0.8, 0.0]),
            s([-0.0, 0.0, 3.0], 0.0, [0.0, 0.0, 0.0]),
            s([f32::MAX, -f32::MAX, 1.0], 1e-3, [-1.0, 0.0, 0.0]),
            s([1.0, 2.0 - f32::EPSILON, 3.0], 1e-9, [0.0, 1.0, 0.0]),
            SurfaceRecord::MISS,
            s([1e-40, -1e-40, 2.0], 1e-38, [0.0, 0.0, 1.0]),
        ];
        check_levels(&surfaces, &light).unwrap();
        let directional = LightRecord::directional([0.0, -1.0, 0.0], light.radiance);
        check_levels(&surfaces, &directional).unwrap();
        // A spot at the same place with a range: the window and cone factors on the same
        // hard cases.
        let spot = hyrt_core::scene::Light::Spot {
            position: glam::Vec3::new(1.0, 2.0, 3.0),
            direction: glam::Vec3::NEG_Y,
            color: glam::Vec3::X,
            intensity: 1.0,
            inner_cone_angle: 0.2,
            outer_cone_angle: 1.2,
            range: Some(4.0),
        };
        check_levels(&surfaces, &LightRecord::from_light(&spot)).unwrap();
    }
}
