//! From linear radiance to display values: an exposure in stops, then a named tone-mapping
//! operator ([`ToneMap`]), before the sRGB encoding of 8-bit output
//! ([`crate::kernels::shading::rgba_to_srgb8`]). PNG output goes through it
//! (`hyrt render --exposure STOPS --tone-map NAME`); OpenEXR output stays linear radiance,
//! before exposure and tone mapping.
//!
//! The CPU applies it when writing a file; no GPU stage runs it yet, so it has no WGSL
//! mirror.

use glam::Vec3;

/// A tone-mapping operator: linear radiance (after the exposure) to linear display values
/// in [0, 1], which [`crate::kernels::shading::linear_to_srgb8`] then encodes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ToneMap {
    /// None: values are clamped to [0, 1] by the encoding (the paper's images, and every
    /// figure of the report's accuracy sections, are of this kind). What the paper's
    /// shading model is displayed with ([`ToneMap::for_shading`]); `Default` for that
    /// reason, and because it leaves every value below 1 as it is.
    #[default]
    None,
    /// The Khronos PBR Neutral tone mapper (Khronos Group, 2024): base colours under
    /// direct light reproduced as they are below [`NEUTRAL_START_COMPRESSION`], highlights
    /// compressed towards white above it; meant for glTF materials.
    KhronosPbrNeutral,
    /// Stephen Hill's fit of the ACES reference rendering and output transforms (sRGB
    /// primaries to ACES AP1 and back, [`ACES_INPUT`], [`ACES_OUTPUT`]): the filmic curve
    /// of the glTF Sample Viewer's "ACES Hill".
    Aces,
}

impl ToneMap {
    /// Every operator.
    pub const ALL: [ToneMap; 3] = [ToneMap::None, ToneMap::KhronosPbrNeutral, ToneMap::Aces];

    /// Lower-case name (CLI).
    pub fn name(self) -> &'static str {
        match self {
            ToneMap::None => "none",
            ToneMap::KhronosPbrNeutral => "khronos-pbr-neutral",
            ToneMap::Aces => "aces",
        }
    }

    /// The operator a frame shaded with `shading` is displayed with unless one is named:
    /// [`ToneMap::KhronosPbrNeutral`] for the glTF BRDF, whose physically based materials
    /// and light units (candela, lux) easily exceed 1 in highlights and which Khronos made
    /// the operator for (base colours under direct light come out as authored); no operator
    /// for the paper's model, whose lights and albedos were chosen for clamped output (the
    /// paper's images, and the report's accuracy figures).
    pub fn for_shading(shading: crate::kernels::shading::ShadingModel) -> ToneMap {
        match shading {
            crate::kernels::shading::ShadingModel::Gltf => ToneMap::KhronosPbrNeutral,
            crate::kernels::shading::ShadingModel::Paper => ToneMap::None,
        }
    }

    /// The operator of a [`ToneMap::name`].
    pub fn from_name(name: &str) -> Option<ToneMap> {
        ToneMap::ALL.into_iter().find(|t| t.name() == name)
    }
}

/// Where the Khronos PBR Neutral operator starts compressing: `0.8 - 0.04` (its
/// specification's `startCompression`; 0.04 is the offset it takes off every channel).
pub const NEUTRAL_START_COMPRESSION: f32 = 0.8 - 0.04;
/// The Khronos PBR Neutral operator's `desaturation` of compressed highlights.
pub const NEUTRAL_DESATURATION: f32 = 0.15;

/// sRGB (Rec. 709) primaries to ACES AP1 with the RRT's saturation, rows (Hill's fit).
pub const ACES_INPUT: [[f32; 3]; 3] =
    [[0.59719, 0.35458, 0.04823], [0.07600, 0.90834, 0.01566], [0.02840, 0.13383, 0.83777]];
/// The ODT's saturation and AP1 back to sRGB primaries, rows (Hill's fit).
pub const ACES_OUTPUT: [[f32; 3]; 3] =
    [[1.60475, -0.53108, -0.07367], [-0.10208, 1.10813, -0.00605], [-0.00327, -0.07276, 1.07602]];

/// The scale of an exposure of `stops` (`2^stops`; exact for whole stops).
#[inline]
pub fn exposure_scale(stops: f32) -> f32 {
    stops.exp2()
}

/// The Khronos PBR Neutral operator on one linear colour, as its specification writes it.
#[inline]
pub fn khronos_pbr_neutral(c: Vec3) -> Vec3 {
    let x = c.min_element();
    let offset = if x < 0.08 { x - 6.25 * x * x } else { 0.04 };
    let c = c - Vec3::splat(offset);
    let peak = c.max_element();
    if peak < NEUTRAL_START_COMPRESSION {
        return c;
    }
    let d = 1.0 - NEUTRAL_START_COMPRESSION;
    let new_peak = 1.0 - d * d / (peak + d - NEUTRAL_START_COMPRESSION);
    let c = c * (new_peak / peak);
    let g = 1.0 - 1.0 / (NEUTRAL_DESATURATION * (peak - new_peak) + 1.0);
    c.lerp(Vec3::splat(new_peak), g)
}

/// Hill's ACES fit on one linear colour: the input matrix, the rational fit of the RRT and
/// ODT, the output matrix, clamped to [0, 1].
#[inline]
pub fn aces(c: Vec3) -> Vec3 {
    let rows = |m: &[[f32; 3]; 3], v: Vec3| {
        Vec3::new(Vec3::from(m[0]).dot(v), Vec3::from(m[1]).dot(v), Vec3::from(m[2]).dot(v))
    };
    let v = rows(&ACES_INPUT, c);
    let a = v * (v + Vec3::splat(0.0245786)) - Vec3::splat(0.000090537);
    let b = v * (v * 0.983729 + Vec3::splat(0.432951)) + Vec3::splat(0.238081);
    rows(&ACES_OUTPUT, a / b).clamp(Vec3::ZERO, Vec3::ONE)
}

/// A linear RGBA texel for display: its colour times `exposure` ([`exposure_scale`]) through
/// `op`; alpha unchanged. [`ToneMap::None`] at scale 1 returns the texel bit for bit.
#[inline]
pub fn display(p: [f32; 4], exposure: f32, op: ToneMap) -> [f32; 4] {
    if op == ToneMap::None && exposure == 1.0 {
        return p;
    }
    let c = Vec3::new(p[0], p[1], p[2]) * exposure;
    // NaN and negative radiance (never produced by the shaders) display as black.
    let c = Vec3::new(c.x.max(0.0), c.y.max(0.0), c.z.max(0.0));
    let c = match op {
        ToneMap::None => c,
        ToneMap::KhronosPbrNeutral => khronos_pbr_neutral(c),
        ToneMap::Aces => aces(c),
    };
    [c.x, c.y, c.z, p[3]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for t in ToneMap::ALL {
            assert_eq!(ToneMap::from_name(t.name()), Some(t));
        }
        assert_eq!(ToneMap::from_name("reinhard"), None);
    }

    #[test]
    fn none_at_zero_stops_is_the_identity() {
        let p = [0.3, 7.0, f32::NAN, 0.5];
        let q = display(p, exposure_scale(0.0), ToneMap::None);
        assert!(p.iter().zip(&q).all(|(a, b)| a.to_bits() == b.to_bits()));
        assert_eq!(exposure_scale(2.0), 4.0);
        assert_eq!(exposure_scale(-1.0), 0.5);
        assert_eq!(display([1.0, 2.0, 3.0, 1.0], 0.5, ToneMap::None), [0.5, 1.0, 1.5, 1.0]);
    }

    /// Below the start of compression the neutral operator only takes its offset off:
    /// 0.04 for colours whose darkest channel is at least 0.08, `x - 6.25 x^2` below.
    #[test]
    fn neutral_keeps_base_colours_and_compresses_highlights() {
        let c = khronos_pbr_neutral(Vec3::new(0.5, 0.3, 0.1));
        assert!((c - Vec3::new(0.46, 0.26, 0.06)).abs().max_element() < 1e-6, "{c}");
        let x = 0.05f32;
        let c = khronos_pbr_neutral(Vec3::new(0.4, x, 0.3));
        assert!((c.y - (x - (x - 6.25 * x * x))).abs() < 1e-7, "{c}");
        // Highlights: monotone, below 1, towards white.
        let mut last = 0.0;
        for k in 1..200 {
            let c = khronos_pbr_neutral(Vec3::new(0.2, 0.5, 1.0) * k as f32 * 0.1);
            assert!(c.max_element() <= 1.0 && c.max_element() >= last - 1e-6, "{k}: {c}");
            last = c.max_element();
        }
        let bright = khronos_pbr_neutral(Vec3::new(100.0, 10.0, 1.0));
        assert!(bright.min_element() > 0.5 && bright.max_element() < 1.0, "desaturated towards white: {bright}");
    }

    /// Hill's fit: black stays (nearly) black, mid grey lands near 0.18's filmic value,
    /// bright values saturate at 1, the curve is monotone on grey.
    #[test]
    fn aces_is_a_filmic_curve() {
        assert!(aces(Vec3::ZERO).max_element() < 1e-3);
        assert_eq!(aces(Vec3::splat(1e4)), Vec3::ONE);
        let mut last = -1.0;
        for k in 0..400 {
            let g = aces(Vec3::splat(k as f32 * 0.05)).x;
            assert!(g >= last && (0.0..=1.0).contains(&g), "{k}: {g}");
            last = g;
        }
        let grey = aces(Vec3::splat(0.18));
        assert!((grey.x - grey.z).abs() < 1e-3 && grey.x > 0.1 && grey.x < 0.2, "{grey}");
    }

    #[test]
    fn display_keeps_alpha_and_blackens_nan() {
        let p = display([f32::NAN, -1.0, 0.5, 0.25], 1.0, ToneMap::Aces);
        assert_eq!(p[3], 0.25);
        assert!(p[0] < 1e-3 && p[1] < 1e-3 && p[2] > 0.0);
    }
}
