//! The ray-traced shader of `rt_shading` over eight pixels at once: core's
//! [`shade_rt_pixel`] (with [`shade_rt_surface`], [`unlit`], [`sum_visible_lights`],
//! [`light_incidence`], [`shade_ray_traced`], [`blinn_phong_exponent`] and
//! [`pow_portable`] with [`log2_portable`], [`exp2_portable`] and [`round_ties_even_f32`])
//! and the stage's [`rt_shading_pixel`] around it, each lane doing the scalar kernels'
//! operations in their order, every one a correctly rounded IEEE 754 f32 operation or a
//! bit operation ([`Lanes`]), so that every lane's texel is the scalar kernel's bits
//! (`tests` pins them). Plain materials only, as in [`crate::raster_shading::lanes`].
//!
//! The parts of [`shade_ray_traced`] that do not depend on the light (the diffuse
//! albedo, F0, the exponent and the lobe's normalization) are computed once for all
//! lights: the same operations on the same operands, so the same bits. Its diffuse scale
//! is 1 there, and `x * 1 = x`: the lanes leave that multiplication out.
//!
//! [`shade_rt_pixel`]: hyrt_core::kernels::shading::shade_rt_pixel
//! [`shade_rt_surface`]: hyrt_core::kernels::shading::shade_rt_surface
//! [`unlit`]: hyrt_core::kernels::shading::unlit
//! [`sum_visible_lights`]: hyrt_core::kernels::shading::sum_visible_lights
//! [`light_incidence`]: hyrt_core::kernels::shading::light_incidence
//! [`shade_ray_traced`]: hyrt_core::kernels::shading::shade_ray_traced
//! [`blinn_phong_exponent`]: hyrt_core::kernels::shading::blinn_phong_exponent
//! [`pow_portable`]: hyrt_core::kernels::shading::pow_portable
//! [`log2_portable`]: hyrt_core::kernels::shading::log2_portable
//! [`exp2_portable`]: hyrt_core::kernels::shading::exp2_portable
//! [`round_ties_even_f32`]: hyrt_core::kernels::raster::round_ties_even_f32
//! [`rt_shading_pixel`]: crate::rt_shading::rt_shading_pixel

use hyrt_core::formats::LightRecord;
use hyrt_core::kernels::raster::F32_INTEGER_THRESHOLD;
use hyrt_core::kernels::shading::{
    AmbientLight, BLINN_PHONG_EXPONENT_RANGE, BLINN_PHONG_MIN_ALPHA, EXP_SERIES, LOG2_SERIES, POW_FLUSH_EXPONENT,
    TWO_OVER_LN_2,
};

use crate::lanes::{dot3, normalize_or_zero_lanes, select3, splat3, sub3, zero3, Lanes};
use crate::raster_shading::lanes::{
    f0_lanes, sum_visible_lights_gltf_lanes, sum_visible_lights_lanes, unlit_lanes, LightShader, LitLanes, PrimaryLanes,
};

// No closures around lane operations (`map`, `from_fn`): a closure does not inherit its
// caller's target features, so its lane operations would not inline into the AVX2 entry
// points.

/// Core's `round_ties_even_f32` per lane: `(|x| + 2^23) - 2^23` with `x`'s sign below
/// 2^23, `x` itself from there on (NaN included).
#[inline(always)]
fn round_ties_even_lanes<L: Lanes>(x: L::F) -> L::F {
    let t = L::splat(F32_INTEGER_THRESHOLD);
    let a = L::abs(x);
    // `copysign` of a non-negative value: its sign bit set to `x`'s.
    let r = L::or(L::sub(L::add(a, t), t), L::and(x, L::splat(-0.0)));
    L::select(L::lt(a, t), r, x)
}

/// The bit pattern `b` in every lane.
#[inline(always)]
fn splat_bits<L: Lanes>(b: u32) -> L::F {
    L::splat(f32::from_bits(b))
}

/// Core's `log2_portable` per lane: the exponent bits and the series on the mantissa.
#[inline(always)]
fn log2_portable_lanes<L: Lanes>(x: L::F) -> L::F {
    let e = L::bits_add(L::and(L::shr_bits::<23>(x), splat_bits::<L>(0xff)), splat_bits::<L>(-127i32 as u32));
    let m = L::or(L::and(x, splat_bits::<L>(0x007f_ffff)), splat_bits::<L>(0x3f80_0000));
    let big = L::lt(L::splat(std::f32::consts::SQRT_2), m);
    let m = L::select(big, L::mul(m, L::splat(0.5)), m);
    let e = L::select(big, L::bits_add(e, splat_bits::<L>(1)), e);
    let one = L::splat(1.0);
    let t = L::div(L::sub(m, one), L::add(m, one));
    let t2 = L::mul(t, t);
    let mut p = L::splat(LOG2_SERIES[0]);
    for &c in &LOG2_SERIES[1..] {
        p = L::add(L::mul(p, t2), L::splat(c));
    }
    L::add(L::int_to_float(e), L::mul(L::mul(t, p), L::splat(TWO_OVER_LN_2)))
}

/// Core's `exp2_portable` per lane: `2^n * e^g`, zero below `POW_FLUSH_EXPONENT` and for
/// NaN.
#[inline(always)]
fn exp2_portable_lanes<L: Lanes>(z: L::F) -> L::F {
    // `!(z.is_nan() || z < POW_FLUSH_EXPONENT)`: NaN fails the comparison.
    let keep = L::le(L::splat(POW_FLUSH_EXPONENT), z);
    let n = round_ties_even_lanes::<L>(z);
    let g = L::mul(L::sub(z, n), L::splat(std::f32::consts::LN_2));
    let mut q = L::splat(EXP_SERIES[0]);
    for &c in &EXP_SERIES[1..] {
        q = L::add(L::mul(q, g), L::splat(c));
    }
    // `f32::from_bits(((n as i32 + 127) as u32) << 23)`; a flushed lane's garbage is dropped.
    let scale = L::shl_bits::<23>(L::bits_add(L::float_to_int(n), splat_bits::<L>(127)));
    L::select(keep, L::mul(q, scale), L::splat(0.0))
}

/// Core's `pow_portable(x, y)` per lane: zero for `x` below `f32::MIN_POSITIVE` and NaN,
/// else `exp2_portable(y * log2_portable(min(x, 1)))`.
#[inline(always)]
fn pow_portable_lanes<L: Lanes>(x: L::F, y: L::F) -> L::F {
    let keep = L::le(L::splat(f32::MIN_POSITIVE), x);
    let z = L::mul(y, log2_portable_lanes::<L>(L::min(x, L::splat(1.0))));
    L::select(keep, exp2_portable_lanes::<L>(z), L::splat(0.0))
}

/// Core's `blinn_phong_exponent(roughness)` per lane. `f32::max(a, c)` and `f32::clamp`
/// against constants are `MAXPS`/`MINPS` with the constant second (`max`) or first (the
/// clamp's `x < least` and `x > most`).
#[inline(always)]
fn blinn_phong_exponent_lanes<L: Lanes>(roughness: L::F) -> L::F {
    let a = L::max(L::mul(roughness, roughness), L::splat(BLINN_PHONG_MIN_ALPHA));
    let s = L::sub(L::div(L::splat(2.0), L::mul(a, a)), L::splat(2.0));
    let [least, most] = BLINN_PHONG_EXPONENT_RANGE;
    L::min(L::splat(most), L::max(L::splat(least), s))
}

/// Core's `shade_ray_traced(obj, n, v, l, e)` per lane, with what does not depend on the
/// light computed once ([`RtShader::of`]).
struct RtShader<L: Lanes> {
    n: [L::F; 3],
    v: [L::F; 3],
    /// `base * ((1 - metallic) * FRAC_1_PI)`.
    diffuse: [L::F; 3],
    f0: [L::F; 3],
    /// The Blinn-Phong exponent `s`.
    s: L::F,
    /// `(s + 8) / (8 pi)`.
    norm: L::F,
}

impl<L: Lanes> RtShader<L> {
    #[inline(always)]
    fn of(p: &PrimaryLanes<L>, v: [L::F; 3]) -> RtShader<L> {
        let (base, metallic) = (p.base_color, p.metallic);
        let k = L::mul(L::sub(L::splat(1.0), metallic), L::splat(std::f32::consts::FRAC_1_PI));
        let s = blinn_phong_exponent_lanes::<L>(p.roughness);
        RtShader {
            n: p.normal,
            v,
            diffuse: [L::mul(base[0], k), L::mul(base[1], k), L::mul(base[2], k)],
            f0: f0_lanes::<L>(base, metallic),
            s,
            norm: L::div(L::add(s, L::splat(8.0)), L::splat(8.0 * std::f32::consts::PI)),
        }
    }
}

impl<L: Lanes> LightShader<L> for RtShader<L> {
    #[inline(always)]
    fn shade(&self, l: [L::F; 3], e: [L::F; 3]) -> [L::F; 3] {
        let ndl = dot3::<L>(self.n, l);
        let v = self.v;
        let h = normalize_or_zero_lanes::<L>([L::add(l[0], v[0]), L::add(l[1], v[1]), L::add(l[2], v[2])]);
        // `n.dot(h).max(0.0)`: a NaN or negative-zero dot gives +0, which `pow_portable`
        // takes to 0 as it takes the scalar kernel's.
        let ndh = L::max(dot3::<L>(self.n, h), L::splat(0.0));
        let k = L::mul(self.norm, pow_portable_lanes::<L>(ndh, self.s));
        let (d, f0) = (self.diffuse, self.f0);
        let c = [
            L::mul(L::mul(L::add(d[0], L::mul(f0[0], k)), e[0]), ndl),
            L::mul(L::mul(L::add(d[1], L::mul(f0[1], k)), e[1]), ndl),
            L::mul(L::mul(L::add(d[2], L::mul(f0[2], k)), e[2]), ndl),
        ];
        // `ndl <= 0` returns zero; a NaN `ndl` goes on, as in the scalar kernel.
        select3::<L>(L::le(ndl, L::splat(0.0)), zero3::<L>(), c)
    }
}

/// The stage's kernel ([`rt_shading_pixel`](crate::rt_shading::rt_shading_pixel)) per lane,
/// as RGBA lanes: core's `shade_rt_pixel` seen from `eye` with alpha 1 on ray-traced
/// objects, transparent black elsewhere. The shader runs only where some lane needs it.
#[inline(always)]
pub(crate) fn rt_shading_lanes<L: Lanes>(
    p: &PrimaryLanes<L>,
    lit: &LitLanes,
    lights: &[LightRecord],
    ambient: &AmbientLight,
    eye: [f32; 3],
) -> [L::F; 4] {
    let zero = L::splat(0.0);
    if L::bits(p.ray_traced) == 0 {
        return [zero; 4];
    }
    // shade_rt_pixel
    let v = normalize_or_zero_lanes::<L>(sub3::<L>(splat3::<L>(eye), p.position));
    // shade_rt_surface
    let a = unlit_lanes::<L>(p, ambient, eye, p.ray_traced);
    let c = match L::bits(p.gltf) {
        0 => sum_visible_lights_lanes::<L, _>(lit, lights, p.position, &RtShader::of(p, v)),
        _ => sum_visible_lights_gltf_lanes::<L, _>(p, lit, lights, v, &RtShader::of(p, v)),
    };
    let c = select3::<L>(p.ray_traced, [L::add(a[0], c[0]), L::add(a[1], c[1]), L::add(a[2], c[2])], zero3::<L>());
    [c[0], c[1], c[2], L::select(p.ray_traced, L::splat(1.0), zero)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lanes::tests::{at_every_level, same_bits, LevelCheck};
    use crate::lanes::LANES;
    use crate::raster_shading::lanes::tests::{block, gltf, hard_block, lane, same_texel, with_sky, Block};
    use crate::raster_shading::Primary;
    use crate::rt_shading::rt_shading_pixel;
    use hyrt_core::kernels::shading::pow_portable;
    use hyrt_core::kernels::texture::Materials;
    use proptest::prelude::*;

    struct RtCheck<'a>(&'a Block);

    impl LevelCheck for RtCheck<'_> {
        fn check<L: Lanes>(&self) -> Result<(), TestCaseError> {
            let b = self.0;
            let got = rt_shading_lanes::<L>(&b.primary::<L>(), &b.lit(), &b.lights, &b.ambient, b.eye);
            let materials = Materials::plain(&b.objects);
            let primary = Primary {
                gbuffer: &[],
                materials: &materials,
                ambient: &b.ambient,
                eye: b.eye.into(),
                visibility: Default::default(),
            };
            for (k, s) in b.surfaces.iter().enumerate() {
                let want = rt_shading_pixel(&primary, &b.lights, k, s, b.codes(k));
                same_texel(k, lane::<L>(got, k), want)?;
            }
            Ok(())
        }
    }

    /// `pow_portable` of eight (base, exponent) pairs.
    struct PowCheck([f32; LANES], [f32; LANES]);

    impl LevelCheck for PowCheck {
        fn check<L: Lanes>(&self) -> Result<(), TestCaseError> {
            let got = L::store(pow_portable_lanes::<L>(L::load(&self.0), L::load(&self.1)));
            for (k, &got) in got.iter().enumerate() {
                let want = pow_portable(self.0[k], self.1[k]);
                prop_assert!(same_bits(got, want), "lane {}: {}^{} = {} vs {}", k, self.0[k], self.1[k], got, want);
            }
            Ok(())
        }
    }

    /// Bases of the Blinn-Phong lobe: `[0, 1]` with its ends, subnormals, `f32::MIN_POSITIVE`
    /// and its neighbours, values near `sqrt 1/2` (the mantissa's fold), above 1, negative.
    fn base() -> impl Strategy<Value = f32> {
        prop_oneof![
            4 => 0.0f32..=1.0,
            1 => Just(0.0f32),
            1 => Just(-0.0f32),
            1 => Just(1.0f32),
            1 => Just(f32::MIN_POSITIVE),
            1 => (0u32..4).prop_map(|d| f32::from_bits(f32::MIN_POSITIVE.to_bits() + d - 2)),
            1 => (0u32..64).prop_map(|d| f32::from_bits(std::f32::consts::FRAC_1_SQRT_2.to_bits() + d - 32)),
            1 => 0.0f32..1e-30,
            1 => 1.0f32..4.0,
            1 => -1.0f32..0.0,
        ]
    }

    /// Exponents of the lobe: its range's ends and anything between.
    fn exponent() -> impl Strategy<Value = f32> {
        prop_oneof![4 => 1.0f32..1e4, 1 => Just(1.0f32), 1 => Just(1e4f32), 1 => 1.0f32..8.0]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2048))]

        #[test]
        fn rt_shading_lanes_are_the_scalar_kernel(b in block()) {
            at_every_level(&RtCheck(&b))?;
        }

        #[test]
        fn pow_portable_lanes_are_the_scalar_kernel(
            x in prop::collection::vec(base(), LANES),
            y in prop::collection::vec(exponent(), LANES),
        ) {
            let (x, y): ([f32; LANES], [f32; LANES]) = (x.try_into().unwrap(), y.try_into().unwrap());
            at_every_level(&PowCheck(x, y))?;
        }
    }

    /// Lights behind, grazing and on the surface; metallic and roughness 0 and 1; a miss;
    /// every shadow code.
    #[test]
    fn rt_shading_lanes_on_hard_cases() {
        at_every_level(&RtCheck(&hard_block())).unwrap();
        at_every_level(&RtCheck(&gltf(hard_block()))).unwrap();
        at_every_level(&RtCheck(&with_sky(gltf(hard_block())))).unwrap();
        at_every_level(&RtCheck(&with_sky(hard_block()))).unwrap();
    }

    /// Exact powers, the flush threshold and its neighbourhood, and the exponent's
    /// rounding ties.
    #[test]
    fn pow_portable_lanes_on_hard_cases() {
        use std::f32::consts::FRAC_1_SQRT_2;
        let pairs = [
            (
                [1.0, 0.5, 0.25, 0.0, f32::MIN_POSITIVE, 0.5, 0.75, 2f32.powi(-50)],
                [1e4, 2.0, 3.0, 2.0, 1.0, 100.0, 1.0, 2.0],
            ),
            (
                [0.5, 0.5, 0.5, 0.5, 0.9999999, 1e-38, FRAC_1_SQRT_2, f32::from_bits(FRAC_1_SQRT_2.to_bits() + 1)],
                [99.5, 100.5, 0.5 + 1.0, 2.5, 1e4, 1.0, 1e4, 1.5],
            ),
        ];
        for (x, y) in pairs {
            at_every_level(&PowCheck(x, y)).unwrap();
        }
    }
}
