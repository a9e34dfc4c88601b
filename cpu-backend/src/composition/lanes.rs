//! The kernel of `composition` ([`composition_pixel`], with core's [`compose`]) over
//! eight pixels at once, each lane doing the scalar kernel's operations in its order,
//! every one a correctly rounded IEEE 754 f32 operation or a bit operation ([`Lanes`]), so
//! that every lane's texel is the scalar kernel's bits (`tests` pins them).
//!
//! [`composition_pixel`]: crate::composition::composition_pixel
//! [`compose`]: hyrt_core::kernels::shading::compose

use hyrt_core::kernels::shading::BACKGROUND_RGBA;
use hyrt_core::plan::Composition;

use crate::lanes::Lanes;

// No closures around lane operations (`map`, `from_fn`): a closure does not inherit its
// caller's target features, so its lane operations would not inline into the AVX2 entry
// points.

/// [`composition_pixel`](crate::composition::composition_pixel) per lane, on RGBA lanes:
/// the raster texel `r` and the ray-traced texel `t` composed as `mode` says (the image
/// `mode` does not read may be anything).
#[inline(always)]
pub(crate) fn composition_lanes<L: Lanes>(mode: Composition, r: [L::F; 4], t: [L::F; 4], weight: f32) -> [L::F; 4] {
    // `t[3] > 0.0`: the ray-traced image covers the pixel.
    let covered = L::lt(L::splat(0.0), t[3]);
    match mode {
        Composition::CopyRaster => r,
        Composition::RtOverBackground => {
            let mut out = t;
            for (c, &b) in out.iter_mut().zip(&BACKGROUND_RGBA) {
                *c = L::select(covered, *c, L::splat(b));
            }
            out
        }
        Composition::WeightedMean => {
            // compose: `raster * (1 - weight) + rt * weight`, alpha 1.
            let (keep, w) = (L::splat(1.0 - weight), L::splat(weight));
            let mut out = r;
            for (c, &t) in out.iter_mut().take(3).zip(&t) {
                *c = L::select(covered, L::add(L::mul(*c, keep), L::mul(t, w)), *c);
            }
            out[3] = L::select(covered, L::splat(1.0), r[3]);
            out
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::composition::composition_pixel;
    use crate::lanes::tests::{at_every_level, LevelCheck};
    use crate::lanes::LANES;
    use crate::raster_shading::lanes::tests::{lane, same_texel};
    use proptest::prelude::*;

    /// Eight raster and ray-traced texels, a mode and a weight.
    struct CompositionCheck<'a>(Composition, &'a [[f32; 4]; LANES], &'a [[f32; 4]; LANES], f32);

    /// Texels as RGBA lanes (a transpose).
    fn rgba_lanes<L: Lanes>(px: &[[f32; 4]; LANES]) -> [L::F; 4] {
        let mut c = [[0.0f32; LANES]; 4];
        for (k, p) in px.iter().enumerate() {
            for a in 0..4 {
                c[a][k] = p[a];
            }
        }
        [L::load(&c[0]), L::load(&c[1]), L::load(&c[2]), L::load(&c[3])]
    }

    impl LevelCheck for CompositionCheck<'_> {
        fn check<L: Lanes>(&self) -> Result<(), TestCaseError> {
            let CompositionCheck(mode, r, t, weight) = *self;
            let got = composition_lanes::<L>(mode, rgba_lanes::<L>(r), rgba_lanes::<L>(t), weight);
            for k in 0..LANES {
                same_texel(k, lane::<L>(got, k), composition_pixel(mode, &r[k], &t[k], weight))?;
            }
            Ok(())
        }
    }

    /// A colour channel: ordinary, zero of either sign, tiny or huge (no NaN).
    fn channel() -> impl Strategy<Value = f32> {
        prop_oneof![
            4 => 0.0f32..2.0,
            1 => Just(0.0f32),
            1 => Just(-0.0f32),
            1 => 0.0f32..1e-38,
            1 => 0.0f32..f32::MAX,
        ]
    }

    /// A texel as the shading stages write them: alpha 1 (shaded), 0 (not covered) or in
    /// between, and any channel.
    fn texel() -> impl Strategy<Value = [f32; 4]> {
        let alpha = prop_oneof![Just(1.0f32), Just(0.0f32), Just(-0.0f32), 0.0f32..=1.0];
        (channel(), channel(), channel(), alpha).prop_map(|(r, g, b, a)| [r, g, b, a])
    }

    fn mode() -> impl Strategy<Value = Composition> {
        prop_oneof![Just(Composition::WeightedMean), Just(Composition::CopyRaster), Just(Composition::RtOverBackground)]
    }

    fn weight() -> impl Strategy<Value = f32> {
        prop_oneof![Just(0.0f32), Just(0.5f32), Just(1.0f32), 0.0f32..=1.0]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2048))]

        #[test]
        fn composition_lanes_are_the_scalar_kernel(
            mode in mode(),
            r in prop::collection::vec(texel(), LANES),
            t in prop::collection::vec(texel(), LANES),
            weight in weight(),
        ) {
            let (r, t): ([[f32; 4]; LANES], [[f32; 4]; LANES]) = (r.try_into().unwrap(), t.try_into().unwrap());
            at_every_level(&CompositionCheck(mode, &r, &t, weight))?;
        }
    }
}
