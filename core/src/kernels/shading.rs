//! Shading kernels: the paper's ray-traced shader (Lambert + Blinn-Phong specular with
//! ray-traced shadows, paper 3.3) and ordinary raster shader (Lambert with ambient, paper
//! 3.4), the glTF 2.0 metallic-roughness BRDF that replaces both on the objects of a scene
//! shaded with [`ShadingModel::Gltf`] ([`gltf_brdf`], [`shade_gltf`]), light evaluation and
//! colour encoding.
//!
//! WGSL mirrors: `orient_to_seen_side` in `reconstruction.wgsl`; `light_incidence` and
//! `light_can_contribute` in `shading_helpers.wgsl` (shared by the shading stages and
//! `compaction`); `shade_ray_traced`, `shade_raster`, `ambient`, `compose`, the portable
//! `pow`, `schlick_weight`, `ggx_distribution`, `smith_visibility`, `gltf_brdf` and
//! `shade_gltf_with` in `shading.wgsl`; `shade_rt_surface`, `shade_rt_pixel`,
//! `shade_raster_surface` and `shade_raster_pixel` in `surface_shading.wgsl`.

use glam::Vec3;

use crate::formats::{
    LightRecord, ObjectRecord, SurfaceRecord, LIGHT_DIRECTIONAL, LIGHT_SPOT, OBJ_GLTF_BRDF, SHADOW_LIT, SHADOW_NO_RAY,
};
pub use crate::kernels::ibl::{AmbientLight, ImageBasedLight};
use crate::kernels::soft_shadow::{area_light_sample, occluded_object, Lights, SurfaceShadow};

/// Constant ambient term, as a fraction of the base colour, so that fully
/// shadowed surfaces stay readable (a stand-in for indirect light).
pub const AMBIENT: f32 = 0.06;

/// Radiance of the uniform environment that specular surfaces reflect until
/// reflection rays are traced: the specular counterpart of [`AMBIENT`]. A metal
/// then shows its colour (F0 x this) instead of black between highlights.
pub const ENVIRONMENT_SPECULAR: f32 = 0.35;

/// Background colour (linear RGB) of pixels no primary ray hits.
pub const BACKGROUND: [f32; 3] = [0.02, 0.025, 0.035];
/// [`BACKGROUND`] as the raster and final images hold it where nothing is shaded (alpha 1).
pub const BACKGROUND_RGBA: [f32; 4] = [BACKGROUND[0], BACKGROUND[1], BACKGROUND[2], 1.0];

/// How direct light is shaded, for every object of a scene (the scene's `shading`, manifest
/// key `shading`, `hyrt render --shading`); each object record carries it
/// ([`OBJ_GLTF_BRDF`]), so every shader reads it where it reads the material.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ShadingModel {
    /// The paper's 2011 model: Lambert on rasterized objects ([`shade_raster`]), Lambert
    /// plus a normalized Blinn-Phong lobe on ray-traced ones ([`shade_ray_traced`]).
    #[default]
    Paper,
    /// The glTF 2.0 metallic-roughness BRDF ([`gltf_brdf`]) on both, so an object looks
    /// the same rasterized and ray traced but for what rays add.
    Gltf,
}

impl ShadingModel {
    /// Every model.
    pub const ALL: [ShadingModel; 2] = [ShadingModel::Paper, ShadingModel::Gltf];

    /// Lower-case name (CLI, manifests, reports).
    pub fn name(self) -> &'static str {
        match self {
            ShadingModel::Paper => "paper",
            ShadingModel::Gltf => "gltf",
        }
    }

    /// The model of a [`ShadingModel::name`].
    pub fn from_name(name: &str) -> Option<ShadingModel> {
        ShadingModel::ALL.into_iter().find(|m| m.name() == name)
    }

    /// The [`ObjectRecord::flags`] bits of the model.
    pub fn object_flags(self) -> u32 {
        match self {
            ShadingModel::Paper => 0,
            ShadingModel::Gltf => OBJ_GLTF_BRDF,
        }
    }
}

/// Fresnel reflectance at normal incidence of dielectrics (4%, the usual
/// glTF metallic-roughness convention).
pub const DIELECTRIC_F0: f32 = 0.04;

/// Smallest distance² a point light is evaluated at, so a light sitting on a
/// surface does not produce an infinite irradiance (1e-8 = (1e-4 units)²).
pub const MIN_LIGHT_DISTANCE_SQ: f32 = 1e-8;

/// Direction from a surface point towards a light and the irradiance scale:
/// `(L, E)` with `L` a unit vector and `E` the light's radiance over d² for
/// point and spot lights (times [`light_falloff`]), or its radiance for directional lights.
#[inline]
pub fn light_incidence(light: &LightRecord, p: Vec3) -> (Vec3, Vec3) {
    let radiance = Vec3::from(light.radiance);
    let pd = Vec3::from(light.position_or_direction);
    if light.kind == LIGHT_DIRECTIONAL {
        (-pd, radiance)
    } else {
        let d = pd - p;
        let d2 = d.length_squared().max(MIN_LIGHT_DISTANCE_SQ);
        let l = d / d2.sqrt();
        (l, radiance / d2 * light_falloff(light, l, d2))
    }
}

/// The factor `KHR_lights_punctual` puts on a point or spot light's `radiance / d²` at a
/// surface seen along `l` (unit, towards the light) at squared distance `d2`: 1 for a
/// point light without a range, so its irradiance keeps its bits.
///
/// * Range (`inv_range_sq > 0`): the extension's recommended window
///   `clamp(1 - (d / range)^4, 0, 1)`, computed as `1 - x * x` with `x = d2 * inv_range_sq`.
/// * Spot lights: the extension's cone factor: `cd = dot(spot_direction, -l)` (the cosine
///   of the angle from the cone's axis), `a = clamp(cd * spot_scale + spot_offset, 0, 1)`,
///   the factor `a * a`: 1 inside the inner cone, 0 beyond the outer one, smooth between.
///
/// NaN cannot reach the clamps (`d2` is at least [`MIN_LIGHT_DISTANCE_SQ`] and the
/// record's values are finite), so WGSL's `clamp` (`min(max(..))`) and the lanes' max and
/// min give the same bits; where they could differ, on the sign of a zero, `a * a` is +0
/// either way and `1 - x * x` is never -0. Outside the cone or the range the factor is
/// 0, so [`light_can_contribute`] traces no shadow ray there.
#[inline]
pub fn light_falloff(light: &LightRecord, l: Vec3, d2: f32) -> f32 {
    let mut f = 1.0;
    if light.inv_range_sq > 0.0 {
        let x = d2 * light.inv_range_sq;
        f = (1.0 - x * x).clamp(0.0, 1.0);
    }
    if light.kind == LIGHT_SPOT {
        let cd = -Vec3::from(light.spot_direction).dot(l);
        let a = (cd * light.spot_scale + light.spot_offset).clamp(0.0, 1.0);
        f *= a * a;
    }
    f
}

/// Orient the geometric and shading normals towards the side of the surface that was
/// seen: both are flipped when it was the back of the triangle (double-sided surfaces).
///
/// `back_face` is decided exactly, never by a dot product with the view direction: for a
/// primary hit it is the visibility raster's `GBUF_BACK_FACE` (the sign of the snapped
/// triangle's area, from the integer edge functions), and secondary-ray hits will pass the
/// sign of the ray/triangle determinant the same way. A floating-point test such as
/// `n . (eye - p) < 0` disagrees with the raster on surfaces seen nearly edge-on: there
/// the normal ended up pointing into a closed mesh and shadow rays started inside it
/// (light leaking out of the shell; the leak corpus of `hyrt-conformance`).
#[inline]
pub fn orient_to_seen_side(geometric: Vec3, shading: Vec3, back_face: bool) -> (Vec3, Vec3) {
    if back_face {
        (-geometric, -shading)
    } else {
        (geometric, shading)
    }
}

/// Whether a light can contribute at a point, so a shadow ray is worth tracing:
/// the light is on the front side of both the (viewer-facing) geometric and
/// shading normals and carries energy.
#[inline]
pub fn light_can_contribute(n_geo: Vec3, n_shade: Vec3, l: Vec3, e: Vec3) -> bool {
    n_geo.dot(l) > 0.0 && n_shade.dot(l) > 0.0 && e.max_element() > 0.0
}

/// Least alpha (roughness²) of [`blinn_phong_exponent`]: a mirror-smooth surface keeps a
/// finite lobe.
pub const BLINN_PHONG_MIN_ALPHA: f32 = 1e-3;
/// The range [`blinn_phong_exponent`] clamps its exponent to.
pub const BLINN_PHONG_EXPONENT_RANGE: [f32; 2] = [1.0, 1e4];

/// Blinn-Phong exponent from a glTF roughness (the common 2/alpha^2 - 2 mapping
/// with alpha = roughness^2), clamped to a finite range.
#[inline]
pub fn blinn_phong_exponent(roughness: f32) -> f32 {
    let a = (roughness * roughness).max(BLINN_PHONG_MIN_ALPHA);
    let [least, most] = BLINN_PHONG_EXPONENT_RANGE;
    (2.0 / (a * a) - 2.0).clamp(least, most)
}

/// `2 / ln 2`, the factor of the log2 series in [`log2_portable`].
pub const TWO_OVER_LN_2: f32 = 2.0 / std::f32::consts::LN_2;
/// Coefficients `1 / (2k + 1)`, k = 4..0, of the series `atanh(t) / t = sum t^(2k) / (2k + 1)`
/// in [`log2_portable`] (Horner order). With `|t| <= (sqrt 2 - 1) / (sqrt 2 + 1) < 0.172`
/// the first omitted term, `t^10 / 11`, is below 2^-29 relative: under the f32 rounding.
pub const LOG2_SERIES: [f32; 5] = [1.0 / 9.0, 1.0 / 7.0, 1.0 / 5.0, 1.0 / 3.0, 1.0];
/// Coefficients `1 / k!`, k = 7..0, of `e^g` in [`exp2_portable`] (Horner order). With
/// `|g| <= ln 2 / 2 < 0.347` the first omitted term, `g^8 / 8!`, is below 2^-27 relative.
pub const EXP_SERIES: [f32; 8] = [1.0 / 5040.0, 1.0 / 720.0, 1.0 / 120.0, 1.0 / 24.0, 1.0 / 6.0, 0.5, 1.0, 1.0];
/// [`pow_portable`] returns 0 below `2^POW_FLUSH_EXPONENT`: far above the subnormal
/// range (GPU drivers such as lavapipe flush subnormals to zero), and far below any
/// visible specular term.
pub const POW_FLUSH_EXPONENT: f32 = -100.0;

/// `log2(x)` for finite `x >= f32::MIN_POSITIVE` (smaller or non-finite input is the
/// caller's error: [`pow_portable`] never passes it), from the exponent bits and the
/// series of [`LOG2_SERIES`] on the mantissa reduced to `[sqrt(1/2), sqrt 2)`. Built
/// only from correctly rounded operations in a stated order, so the GPU's twin gives
/// the same bits (unlike `powf` and WGSL `pow`, whose approximations differ). Absolute
/// error about 2^-22 (a few f32 roundings of values below 1) plus the rounding of the
/// final sum with the exponent (half an ulp of the result).
/// WGSL: `log2_portable`.
#[inline]
pub fn log2_portable(x: f32) -> f32 {
    let bits = x.to_bits();
    let mut e = ((bits >> 23) & 0xff) as i32 - 127;
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    if m > std::f32::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    // m - 1 is exact (Sterbenz: m lies within [1/2, 2] of 1).
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let mut p = LOG2_SERIES[0];
    for c in &LOG2_SERIES[1..] {
        p = p * t2 + c;
    }
    e as f32 + (t * p) * TWO_OVER_LN_2
}

/// `2^z` for `z <= 0` (the only use: [`pow_portable`] of a base in `[0, 1]`): `2^n * e^g`
/// with `n = round_ties_even(z)`, `g = (z - n) * ln 2` (`z - n` is exact), the series of
/// [`EXP_SERIES`], and an exact power-of-two scale; 0 below [`POW_FLUSH_EXPONENT`].
/// Relative error about 2^-22. WGSL: `exp2_portable`.
#[inline]
pub fn exp2_portable(z: f32) -> f32 {
    // NaN compares false: flushed too.
    if z.is_nan() || z < POW_FLUSH_EXPONENT {
        return 0.0;
    }
    let n = crate::kernels::raster::round_ties_even_f32(z);
    let g = (z - n) * std::f32::consts::LN_2;
    let mut q = EXP_SERIES[0];
    for c in &EXP_SERIES[1..] {
        q = q * g + c;
    }
    q * f32::from_bits(((n as i32 + 127) as u32) << 23)
}

/// `x^y` for `x` in `[0, 1]` and `y >= 1` (the Blinn-Phong lobe): 0 for `x = 0`, else
/// `exp2_portable(y * log2_portable(x))`; NaN `x` gives 0. Relative error about
/// `2^-22 * (1 + y * |log2 x|)`, invisible in shading, and the same bits on the CPU and
/// the GPU. WGSL: `pow_portable`.
#[inline]
pub fn pow_portable(x: f32, y: f32) -> f32 {
    if x.is_nan() || x < f32::MIN_POSITIVE {
        return 0.0;
    }
    exp2_portable(y * log2_portable(x.min(1.0)))
}

/// Ray-traced shader, one light: Lambert diffuse plus a normalized Blinn-Phong
/// specular lobe, times the light's irradiance scale `e` and `n.l`. The caller
/// multiplies by the shadow visibility and sums over lights.
#[inline]
pub fn shade_ray_traced(obj: &ObjectRecord, n: Vec3, v: Vec3, l: Vec3, e: Vec3) -> Vec3 {
    shade_ray_traced_with(obj, n, v, l, e, 1.0)
}

/// [`shade_ray_traced`] with the diffuse lobe scaled by `diffuse_scale` (`1 -
/// transmission` on glass that refracts, [`crate::kernels::bounce::Lobes`]). A scale of 1
/// gives [`shade_ray_traced`] bit for bit (`x * 1 = x`). An object of the glTF model
/// ([`OBJ_GLTF_BRDF`]) is shaded by [`shade_gltf_with`] instead.
#[inline]
pub fn shade_ray_traced_with(obj: &ObjectRecord, n: Vec3, v: Vec3, l: Vec3, e: Vec3, diffuse_scale: f32) -> Vec3 {
    if obj.flags & OBJ_GLTF_BRDF != 0 {
        return shade_gltf_with(obj, n, v, l, e, diffuse_scale);
    }
    let ndl = n.dot(l);
    if ndl <= 0.0 {
        return Vec3::ZERO;
    }
    let base = Vec3::from(obj.base_color);
    let diffuse = base * (((1.0 - obj.metallic) * std::f32::consts::FRAC_1_PI) * diffuse_scale);
    let f0 = Vec3::splat(DIELECTRIC_F0).lerp(base, obj.metallic);
    let h = (l + v).normalize_or_zero();
    let s = blinn_phong_exponent(obj.roughness);
    let spec = f0 * ((s + 8.0) / (8.0 * std::f32::consts::PI) * pow_portable(n.dot(h).max(0.0), s));
    (diffuse + spec) * e * ndl
}

/// Least GGX alpha (roughness², glTF's "alphaRoughness") of [`gltf_brdf`]: a
/// mirror-smooth surface (roughness 0) keeps a finite highlight under a point light, whose
/// peak `D = 1 / (pi alpha^2)` is then about 3e5 (alpha 0 gives `0 / 0` there). The paper
/// model's floor, [`BLINN_PHONG_MIN_ALPHA`], so both models sharpen alike.
pub const GGX_MIN_ALPHA: f32 = BLINN_PHONG_MIN_ALPHA;

/// Schlick's Fresnel weight `(1 - |v.h|)^5` (glTF 2.0, Appendix B: `fresnel_mix` and
/// `conductor_fresnel`), as two squarings and a product: exact operations in a stated
/// order, the same bits in WGSL (`schlick_weight`), unlike `powf`.
#[inline]
pub fn schlick_weight(v_dot_h: f32) -> f32 {
    let x = 1.0 - v_dot_h.abs();
    let x2 = x * x;
    x2 * x2 * x
}

/// The Trowbridge-Reitz (GGX) distribution `D = alpha^2 chi+(n.h) / (pi ((n.h)^2 (alpha^2 -
/// 1) + 1)^2)` of glTF 2.0 Appendix B, with the bracket written as `sin^2 + cos^2 alpha^2`
/// (`sin_sq = |n x h|^2`, `n_dot_h = cos`): equal for unit `n` and `h`, and free of the
/// cancellation of `1 - (n.h)^2` where the highlight peaks (`n.h` near 1, where `1 - (n.h)^2`
/// in f32 keeps no correct digit once it falls below the dot product's rounding, while the
/// cross product's length keeps its relative accuracy). WGSL: `ggx_distribution`.
#[inline]
pub fn ggx_distribution(alpha: f32, n_dot_h: f32, sin_sq: f32) -> f32 {
    if n_dot_h <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let k = sin_sq + (n_dot_h * n_dot_h) * a2;
    a2 / (std::f32::consts::PI * (k * k))
}

/// The visibility term `V = G / (4 |n.l| |n.v|)` of glTF 2.0 Appendix B with its separable
/// Smith masking-shadowing `G`: `chi+(h.l) / (|n.l| + sqrt(alpha^2 + (1 - alpha^2) (n.l)^2))`
/// times the same in `v`. Each denominator is at least `alpha` (at least
/// [`GGX_MIN_ALPHA`]), so `V` is finite at grazing angles. WGSL: `smith_visibility`.
#[inline]
pub fn smith_visibility(alpha: f32, n_dot_l: f32, n_dot_v: f32, h_dot_l: f32, h_dot_v: f32) -> f32 {
    if h_dot_l <= 0.0 || h_dot_v <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let one_minus_a2 = 1.0 - a2;
    let gl = n_dot_l.abs() + (a2 + one_minus_a2 * (n_dot_l * n_dot_l)).sqrt();
    let gv = n_dot_v.abs() + (a2 + one_minus_a2 * (n_dot_v * n_dot_v)).sqrt();
    1.0 / (gl * gv)
}

/// The glTF 2.0 metallic-roughness BRDF (the specification's Appendix B, as written there)
/// for unit normal `n`, view direction `v` and light direction `l` (both away from the
/// surface):
///
/// ```text
/// specular   = D * V                                  (alpha = roughness^2)
/// dielectric = mix(base / pi, specular, F0 + (1 - F0) (1 - |v.h|)^5)   (F0 = 0.04: ior 1.5)
/// metal      = specular * (base + (1 - base) (1 - |v.h|)^5)
/// brdf       = (1 - metallic) dielectric + metallic metal
/// ```
///
/// `h = normalize(l + v)` (zero where `l = -v`: then `D` and `V` are zero). Alpha is at
/// least [`GGX_MIN_ALPHA`]. `diffuse_scale` scales the diffuse lobe (`1 - transmission` on
/// glass that refracts, as in [`shade_ray_traced_with`]; 1 leaves it as it is, bit for
/// bit). The caller multiplies by the light's irradiance scale and `n.l`
/// ([`shade_gltf_with`]). WGSL: `gltf_brdf`.
#[inline]
pub fn gltf_brdf(base: Vec3, metallic: f32, roughness: f32, diffuse_scale: f32, n: Vec3, v: Vec3, l: Vec3) -> Vec3 {
    let h = (l + v).normalize_or_zero();
    let alpha = (roughness * roughness).max(GGX_MIN_ALPHA);
    let d = ggx_distribution(alpha, n.dot(h), n.cross(h).length_squared());
    let specular = d * smith_visibility(alpha, n.dot(l), n.dot(v), h.dot(l), h.dot(v));
    let w = schlick_weight(v.dot(h));
    let f_dielectric = DIELECTRIC_F0 + (1.0 - DIELECTRIC_F0) * w;
    let diffuse = base * (std::f32::consts::FRAC_1_PI * diffuse_scale);
    let dielectric = diffuse * (1.0 - f_dielectric) + Vec3::splat(specular * f_dielectric);
    let metal = (base + (Vec3::ONE - base) * w) * specular;
    dielectric * (1.0 - metallic) + metal * metallic
}

/// The specification of [`light_falloff`]: `KHR_lights_punctual`'s recommended range
/// window and spot cone factor in f64 at distance `d` from the light and at `cos_axis`, the
/// cosine of the angle from the cone's axis, written from the light's parameters as the
/// extension states them (`range`; the cone's inner and outer angles in radians) rather
/// than from the record. What the kernel is tested against, here and end to end over
/// rendered frames (`cpu-backend/tests/spot_lights.rs`); not for rendering.
pub fn punctual_falloff_f64(d: f64, cos_axis: f64, range: Option<f64>, cone: Option<(f64, f64)>) -> f64 {
    let window = range.map_or(1.0, |r| (1.0 - (d / r).powi(4)).clamp(0.0, 1.0));
    let angular = cone.map_or(1.0, |(inner, outer)| {
        let scale = 1.0 / (inner.cos() - outer.cos()).max(0.001);
        let a = (cos_axis * scale - outer.cos() * scale).clamp(0.0, 1.0);
        a * a
    });
    window * angular
}

/// The specification of [`gltf_brdf`]: glTF 2.0 Appendix B in f64, term by term as the
/// specification writes it (the bracket of `D` as `(n.h)^2 (alpha^2 - 1) + 1`, `V` as
/// `G / (4 |n.l| |n.v|)`, alpha at least [`GGX_MIN_ALPHA`]), on the directions normalized in
/// f64; diffuse scale 1. What the kernel is tested against, here and end to end over
/// rendered frames (`cpu-backend/tests/gltf_brdf.rs`); not for rendering.
pub fn gltf_brdf_f64(base: [f64; 3], metallic: f64, roughness: f64, n: [f64; 3], v: [f64; 3], l: [f64; 3]) -> [f64; 3] {
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let unit = |a: [f64; 3]| {
        let r = dot(a, a).sqrt();
        [a[0] / r, a[1] / r, a[2] / r]
    };
    let (n, v, l) = (unit(n), unit(v), unit(l));
    let h = unit([l[0] + v[0], l[1] + v[1], l[2] + v[2]]);
    let alpha = (roughness * roughness).max(GGX_MIN_ALPHA as f64);
    let a2 = alpha * alpha;
    let chi = |x: f64| if x > 0.0 { 1.0 } else { 0.0 };
    let (nh, nl, nv, hl, hv) = (dot(n, h), dot(n, l), dot(n, v), dot(h, l), dot(h, v));
    let d = a2 * chi(nh) / (std::f64::consts::PI * (nh * nh * (a2 - 1.0) + 1.0).powi(2));
    let g1 = |x: f64, c: f64| 2.0 * x.abs() * chi(c) / (x.abs() + (a2 + (1.0 - a2) * x * x).sqrt());
    let vis = g1(nl, hl) * g1(nv, hv) / (4.0 * nl.abs() * nv.abs());
    let specular = d * vis;
    let w = (1.0 - hv.abs()).powi(5);
    let f_d = 0.04 + (1.0 - 0.04) * w;
    base.map(|c| {
        let dielectric = (1.0 - f_d) * c / std::f64::consts::PI + f_d * specular;
        let metal = specular * (c + (1.0 - c) * w);
        (1.0 - metallic) * dielectric + metallic * metal
    })
}

/// The glTF shader, one light: [`gltf_brdf`] of the object's material times the light's
/// irradiance scale `e` and `n.l`, zero where the light is behind the shading normal. The
/// same direct light for rasterized and ray-traced objects. The caller multiplies by the
/// shadow visibility and sums over lights.
#[inline]
pub fn shade_gltf(obj: &ObjectRecord, n: Vec3, v: Vec3, l: Vec3, e: Vec3) -> Vec3 {
    shade_gltf_with(obj, n, v, l, e, 1.0)
}

/// [`shade_gltf`] with the diffuse lobe scaled by `diffuse_scale` (see [`gltf_brdf`]).
/// WGSL: `shade_gltf_with`.
#[inline]
pub fn shade_gltf_with(obj: &ObjectRecord, n: Vec3, v: Vec3, l: Vec3, e: Vec3, diffuse_scale: f32) -> Vec3 {
    let ndl = n.dot(l);
    if ndl <= 0.0 {
        return Vec3::ZERO;
    }
    let base = Vec3::from(obj.base_color);
    gltf_brdf(base, obj.metallic, obj.roughness, diffuse_scale, n, v, l) * e * ndl
}

/// Ordinary raster shader, one light: Lambert diffuse times `n.l` and the
/// irradiance scale (the paper's grey Sponza shader). The caller multiplies by
/// the ray-traced shadow visibility, so raster objects receive RT shadows. An object of
/// the glTF model ([`OBJ_GLTF_BRDF`]) is shaded by [`shade_gltf`] seen along `-v` (the
/// paper's shader does not read `v`).
#[inline]
pub fn shade_raster(obj: &ObjectRecord, n: Vec3, v: Vec3, l: Vec3, e: Vec3) -> Vec3 {
    if obj.flags & OBJ_GLTF_BRDF != 0 {
        return shade_gltf(obj, n, v, l, e);
    }
    let ndl = n.dot(l);
    if ndl <= 0.0 {
        return Vec3::ZERO;
    }
    Vec3::from(obj.base_color) * std::f32::consts::FRAC_1_PI * e * ndl
}

/// Sum `shade(l, e)` over the lights whose shadow ray reached them, in light order:
/// `shadow` holds the surface's mask slots ([`crate::kernels::soft_shadow`]: one per
/// point, spot or directional light, `samples` per area light). A light of one slot counts
/// where its code is `SHADOW_LIT`, with `(l, e)` from [`light_incidence`] at `p`. An area
/// light adds `(1 / N) sum shade(l_s, weight_s)` over its `N` samples whose ray reached it
/// ([`area_light_sample`]); where the frame denoised its visibility (`shadow.filtered`),
/// it adds the sum over the samples that traced a ray, lit or not, times the filtered
/// visibility `V`: `V (1 / N) sum shade(l_s, weight_s)` (the unshadowed estimate times the
/// visible share, which equals the first where nothing is filtered and the BRDF does not
/// vary over the light). Every shader uses it, so they agree on which lights count.
#[inline]
pub fn sum_visible_lights<'s, 'l>(
    shadow: impl Into<SurfaceShadow<'s>>,
    lights: impl Into<Lights<'l>>,
    p: Vec3,
    mut shade: impl FnMut(Vec3, Vec3) -> Vec3,
) -> Vec3 {
    let SurfaceShadow { codes: shadow, filtered } = shadow.into();
    let lights = lights.into();
    let mut c = Vec3::ZERO;
    let mut slot = 0;
    let mut area = 0;
    for light in lights.iter() {
        if light.is_area() {
            let n = light.samples as usize;
            let visibility = filtered.get(area).copied();
            let mut sum = Vec3::ZERO;
            let mut seen = false;
            for (sample, &code) in shadow[slot..slot + n].iter().enumerate() {
                let counts = match visibility {
                    None => code == SHADOW_LIT,
                    Some(_) => code != SHADOW_NO_RAY,
                };
                if counts {
                    if let Some(ls) = area_light_sample(light, lights.emitters, p, sample as u32) {
                        sum += shade(ls.l, ls.weight);
                        seen = true;
                    }
                }
            }
            if seen {
                c += match visibility {
                    None => sum / n as f32,
                    Some(v) => (sum / n as f32) * v,
                };
            }
            slot += n;
            area += 1;
        } else {
            if shadow[slot] == SHADOW_LIT {
                let (l, e) = light_incidence(light, p);
                c += shade(l, e);
            }
            slot += 1;
        }
    }
    c
}

/// The ray-traced shader at one pixel: [`unlit`] plus [`shade_ray_traced`] from every
/// light its shadow ray reached (`shadow`: the pixel's `SHADOW_*` codes, one per light),
/// seen from `eye`.
#[inline]
pub fn shade_rt_pixel<'s, 'l>(
    s: &SurfaceRecord,
    obj: &ObjectRecord,
    shadow: impl Into<SurfaceShadow<'s>>,
    lights: impl Into<Lights<'l>>,
    ambient: &AmbientLight,
    eye: Vec3,
) -> Vec3 {
    let v = (eye - Vec3::from(s.position)).normalize_or_zero();
    shade_rt_surface(s, obj, shadow, lights, ambient, v)
}

/// The ray-traced shader at a surface seen along `-v` (`v`: unit, towards the viewer):
/// [`unlit`] plus [`shade_ray_traced`] from every light its shadow ray reached. Primary
/// hits ([`shade_rt_pixel`]) and secondary hits on surfaces that do not bounce use it.
#[inline]
pub fn shade_rt_surface<'s, 'l>(
    s: &SurfaceRecord,
    obj: &ObjectRecord,
    shadow: impl Into<SurfaceShadow<'s>>,
    lights: impl Into<Lights<'l>>,
    ambient: &AmbientLight,
    v: Vec3,
) -> Vec3 {
    shade_surface_with(s, obj, shadow.into(), lights.into(), ambient, v, shade_ray_traced)
}

/// [`unlit`] plus `brdf(obj, n, v, l, e)` summed over the lights [`sum_visible_lights`]
/// counts, with the object's occlusion applied ([`occluded_object`]): the body of
/// [`shade_rt_surface`] and [`shade_raster_surface`], which differ in `brdf` alone.
#[inline]
fn shade_surface_with(
    s: &SurfaceRecord,
    obj: &ObjectRecord,
    shadow: SurfaceShadow,
    lights: Lights,
    ambient: &AmbientLight,
    v: Vec3,
    brdf: impl Fn(&ObjectRecord, Vec3, Vec3, Vec3, Vec3) -> Vec3,
) -> Vec3 {
    let p = Vec3::from(s.position);
    let n = Vec3::from(s.normal);
    let occluded = occluded_object(obj, shadow, &lights, &ambient.occlusion);
    let obj = occluded.as_ref().unwrap_or(obj);
    unlit(obj, n, v, ambient) + sum_visible_lights(shadow, lights, p, |l, e| brdf(obj, n, v, l, e))
}

/// The raster shader at a surface seen along `-v` (`v`: unit, towards the viewer):
/// [`unlit`] plus [`shade_raster`] from every light its shadow ray reached (`shadow`: the
/// pixel's `SHADOW_*` codes, one per light).
#[inline]
pub fn shade_raster_surface<'s, 'l>(
    s: &SurfaceRecord,
    obj: &ObjectRecord,
    shadow: impl Into<SurfaceShadow<'s>>,
    lights: impl Into<Lights<'l>>,
    ambient: &AmbientLight,
    v: Vec3,
) -> Vec3 {
    shade_surface_with(s, obj, shadow.into(), lights.into(), ambient, v, shade_raster)
}

/// The raster shader at one pixel seen from `eye`: [`shade_raster_surface`] with `v`
/// towards the eye, as [`shade_rt_pixel`] makes it.
#[inline]
pub fn shade_raster_pixel<'s, 'l>(
    s: &SurfaceRecord,
    obj: &ObjectRecord,
    shadow: impl Into<SurfaceShadow<'s>>,
    lights: impl Into<Lights<'l>>,
    ambient: &AmbientLight,
    eye: Vec3,
) -> Vec3 {
    let v = (eye - Vec3::from(s.position)).normalize_or_zero();
    shade_raster_surface(s, obj, shadow, lights, ambient, v)
}

/// The ambient light a surface reflects towards `v` (unit, towards the viewer) at the unit
/// shading normal `n`, under the frame's `light` ([`AmbientLight`]), all of it times the
/// point's ambient occlusion ([`ObjectRecord::occlusion`]: glTF's occlusion texture
/// "applies to indirect lighting" only):
///
/// * the constant diffuse term: diffuse albedo `base (1 - metallic)` times [`AMBIENT`]
///   times the scene's level (`light.scale`: 1, an exact no-op, by default; 0 with
///   `ambient = 0`);
/// * the paper's model (and glTF objects of tables without image-based light): plus the
///   specular reflectance F0 times [`ENVIRONMENT_SPECULAR`] (a uniform environment reflected
///   by the specular lobe, which integrates to F0), at the same level:
///   `(base (1 - metallic) AMBIENT + F0 ENVIRONMENT_SPECULAR) (scale occlusion)`;
/// * the glTF model with the environment's image-based light: plus
///   [`ImageBasedLight::radiance`] (diffuse irradiance and prefiltered specular), which the
///   level does not scale: `base ((1 - metallic) AMBIENT) (scale occlusion) + IBL
///   occlusion`.
///
/// `n` and `v` are read only by the image-based light. WGSL: `ambient`.
#[inline]
pub fn ambient(obj: &ObjectRecord, n: Vec3, v: Vec3, light: &AmbientLight) -> Vec3 {
    let base = Vec3::from(obj.base_color);
    let constant = light.scale * obj.occlusion;
    match light.image_for(obj.flags) {
        None => {
            let f0 = Vec3::splat(DIELECTRIC_F0).lerp(base, obj.metallic);
            (base * ((1.0 - obj.metallic) * AMBIENT) + f0 * ENVIRONMENT_SPECULAR) * constant
        }
        Some(ibl) => {
            base * ((1.0 - obj.metallic) * AMBIENT) * constant
                + ibl.radiance(base, obj.metallic, obj.roughness, n, v) * obj.occlusion
        }
    }
}

/// What a surface sends out whatever the lights: [`ambient`] plus its emission
/// ([`ObjectRecord::emissive`]; adding the zero of a surface without one keeps the
/// ambient's bits). Every shader of a surface starts from it. WGSL: `unlit`.
#[inline]
pub fn unlit(obj: &ObjectRecord, n: Vec3, v: Vec3, light: &AmbientLight) -> Vec3 {
    ambient(obj, n, v, light) + Vec3::from(obj.emissive)
}

/// A scene's constant ambient light (manifest key `ambient`, `hyrt render --ambient`):
/// the diffuse ambient level, [`AMBIENT`] by default (the paper's look). It scales both
/// constant terms, the diffuse [`AMBIENT`] and the specular [`ENVIRONMENT_SPECULAR`]
/// (including what an untraced lobe sees), by `level / AMBIENT` ([`AmbientLight::scale`]);
/// 0 removes them, so that with a black environment (no image-based light either) a frame
/// holds direct light and emission alone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ambient(pub f32);

impl Default for Ambient {
    fn default() -> Self {
        Ambient(AMBIENT)
    }
}

impl Ambient {
    /// The level, or why it cannot be one (it must be finite and non-negative).
    pub fn new(level: f32) -> Result<Ambient, String> {
        if level.is_finite() && level >= 0.0 {
            Ok(Ambient(level))
        } else {
            Err(format!("ambient {level} must be a finite number >= 0"))
        }
    }

    /// The scale of the constant terms: `level / AMBIENT`, exactly 1 at the default.
    pub fn scale(self) -> f32 {
        self.0 / AMBIENT
    }
}

/// Composition (paper 3.5): the weighted mean `(1 - weight) * raster + weight * rt`.
#[inline]
pub fn compose(raster: Vec3, rt: Vec3, weight: f32) -> Vec3 {
    raster * (1.0 - weight) + rt * weight
}

/// Linear value to an 8-bit sRGB code (clamped to [0, 1]; IEC 61966-2-1 curve).
#[inline]
pub fn linear_to_srgb8(x: f32) -> u8 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    let s = if x <= 0.003_130_8 { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// A linear RGBA texel to 8-bit sRGB RGBA for display: the colour through
/// [`linear_to_srgb8`], alpha (coverage, linear) clamped to [0, 1] and rounded.
#[inline]
pub fn rgba_to_srgb8(p: [f32; 4]) -> [u8; 4] {
    let a = if p[3].is_nan() { 0.0 } else { p[3].clamp(0.0, 1.0) };
    [linear_to_srgb8(p[0]), linear_to_srgb8(p[1]), linear_to_srgb8(p[2]), (a * 255.0 + 0.5) as u8]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Accuracy of the portable kernels against f64 (see their docs): log2 within
    /// 2^-20 absolute plus the final sum's rounding (2^-23 of the result), exp2 within
    /// 2^-20 relative.
    const PORTABLE_LOG2_ABS_TOL: f64 = 1.0 / (1u64 << 20) as f64;
    const PORTABLE_EXP2_REL_TOL: f64 = 1.0 / (1u64 << 20) as f64;

    proptest! {
        #[test]
        fn log2_portable_matches_f64(x in f32::MIN_POSITIVE..f32::MAX) {
            let r = log2_portable(x) as f64;
            let t = (x as f64).log2();
            prop_assert!((r - t).abs() <= PORTABLE_LOG2_ABS_TOL + t.abs() * f32::EPSILON as f64, "log2({x}) = {r}");
        }

        #[test]
        fn exp2_portable_matches_f64(z in -99.0f32..0.0) {
            let r = exp2_portable(z) as f64;
            let t = (z as f64).exp2();
            prop_assert!((r - t).abs() <= PORTABLE_EXP2_REL_TOL * t, "exp2({z}) = {r}, not {t}");
        }

        #[test]
        fn pow_portable_matches_f64_within_its_bound(x in 0.0f32..=1.0, y in 1.0f32..1e4) {
            let r = pow_portable(x, y) as f64;
            let t = (x as f64).powf(y as f64);
            let bound = PORTABLE_EXP2_REL_TOL * (1.0 + y as f64 * (x as f64).log2().abs());
            if t >= (POW_FLUSH_EXPONENT as f64).exp2() * 2.0 {
                prop_assert!((r - t).abs() <= bound * t, "{x}^{y} = {r}, not {t}");
            } else {
                prop_assert!(r <= (POW_FLUSH_EXPONENT as f64).exp2() * 4.0, "{x}^{y} = {r}, flushed {t}");
            }
        }
    }

    #[test]
    fn pow_portable_pins_exact_cases() {
        assert_eq!(pow_portable(1.0, 5000.0), 1.0);
        assert_eq!(pow_portable(0.0, 2.0), 0.0);
        assert_eq!(pow_portable(f32::NAN, 2.0), 0.0);
        assert_eq!(pow_portable(0.5, 2.0), 0.25);
        assert_eq!(exp2_portable(-3.0), 0.125);
        assert_eq!(log2_portable(8.0), 3.0);
    }

    fn grey() -> ObjectRecord {
        ObjectRecord {
            first_triangle: 0,
            triangle_count: 1,
            flags: 0,
            material_kind: 0,
            base_color: [0.5; 3],
            metallic: 0.0,
            roughness: 1.0,
            transmission: 0.0,
            ior: 1.5,
            offset_error: 0.0,
            emissive: [0.0; 3],
            occlusion: 1.0,
        }
    }

    #[test]
    fn point_light_falls_off_with_distance_squared() {
        let l = LightRecord::point([0.0, 2.0, 0.0], [8.0; 3]);
        let (dir, e) = light_incidence(&l, Vec3::ZERO);
        assert_eq!(dir, Vec3::Y);
        assert_eq!(e, Vec3::splat(2.0));
    }

    /// Tolerance of the f32 factor against the f64 one. Inputs rounded to f32 (the record's
    /// cosines and scale, `l`, `d2`) move `a = cd * scale + offset` by a few ulps of its
    /// terms, which `scale` (up to 1000, [`SPOT_MIN_COS_SPAN`]) magnifies: about
    /// `8 eps * (1 + scale)` on `a`, doubled by the square, plus the window's few ulps.
    fn falloff_tolerance(scale: f32) -> f64 {
        16.0 * f64::from(f32::EPSILON) * (1.0 + f64::from(scale)) + 1e-6
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4096))]

        /// The kernel's factor equals the extension's formulas in f64 over random spots,
        /// ranges and surface points, within the rounding of its f32 inputs.
        #[test]
        fn light_falloff_follows_khr_lights_punctual(
            axis in [-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0],
            p in [-10.0f32..10.0, -10.0f32..10.0, -10.0f32..10.0],
            outer in 0.01f32..std::f32::consts::FRAC_PI_2,
            inner_fraction in 0.0f32..1.0,
            range in prop::option::of(0.5f32..20.0),
        ) {
            let axis = Vec3::from(axis).normalize_or(Vec3::NEG_Y);
            let position = Vec3::new(0.5, 3.0, -1.0);
            let inner = outer * inner_fraction;
            let spot = crate::scene::Light::Spot {
                position, direction: axis, color: Vec3::ONE, intensity: 1.0,
                inner_cone_angle: inner, outer_cone_angle: outer, range,
            };
            let record = LightRecord::from_light(&spot);
            let p = Vec3::from(p);
            let (l, e) = light_incidence(&record, p);
            let d = (position - p).as_dvec3();
            let cos_axis = -axis.as_dvec3().dot(d.normalize());
            let want = punctual_falloff_f64(
                d.length(), cos_axis, range.map(f64::from), Some((f64::from(inner), f64::from(outer))),
            );
            let d2 = (position - p).length_squared().max(MIN_LIGHT_DISTANCE_SQ);
            let got = f64::from(light_falloff(&record, l, d2));
            prop_assert!((got - want).abs() <= falloff_tolerance(record.spot_scale), "{got} vs {want}");
            // The irradiance is radiance / d² times that factor.
            prop_assert_eq!(e.x, 1.0 / d2 * light_falloff(&record, l, d2));
            // A point light with the same range: the window alone.
            let point = LightRecord::from_light(&crate::scene::Light::Point {
                position, color: Vec3::ONE, intensity: 1.0, range,
            });
            let want = punctual_falloff_f64(d.length(), cos_axis, range.map(f64::from), None);
            let got = f64::from(light_falloff(&point, l, d2));
            prop_assert!((got - want).abs() <= falloff_tolerance(0.0), "{got} vs {want}");
        }
    }

    /// Exact values of the factor: 1 inside the inner cone and for point lights without a
    /// range (the irradiance keeps its bits), 0 beyond the outer cone and the range (no
    /// shadow ray is traced there), the quarter of full light halfway up the ramp.
    #[test]
    fn light_falloff_pins_the_cone_and_range_edges() {
        let spot = |inner_deg: f32, outer_deg: f32, range| {
            LightRecord::from_light(&crate::scene::Light::Spot {
                position: Vec3::new(0.0, 4.0, 0.0),
                direction: Vec3::NEG_Y,
                color: Vec3::ONE,
                intensity: 16.0,
                inner_cone_angle: inner_deg.to_radians(),
                outer_cone_angle: outer_deg.to_radians(),
                range,
            })
        };
        let s = spot(20.0, 40.0, None);
        let below = |x: f32| light_incidence(&s, Vec3::new(x, 0.0, 0.0));
        // Straight below: full light, 16 / 4².
        assert_eq!(below(0.0), (Vec3::Y, Vec3::splat(1.0)));
        // 45 degrees off the axis, beyond the 40 degree cone: nothing, and no shadow ray.
        let (l, e) = below(4.0);
        assert_eq!(e, Vec3::ZERO);
        assert!(!light_can_contribute(Vec3::Y, Vec3::Y, l, e));
        // Halfway up the ramp in cosine: a = 0.5, a² = 0.25 (within the f32 cosines).
        let cos_mid = 0.5 * (20f32.to_radians().cos() + 40f32.to_radians().cos());
        let x = 4.0 * (1.0 - cos_mid * cos_mid).sqrt() / cos_mid;
        let (l, e) = below(x);
        let d2 = 16.0 + x * x;
        assert!((light_falloff(&s, l, d2) - 0.25).abs() < 1e-5, "{}", light_falloff(&s, l, d2));
        assert!((e.x * d2 / 16.0 - 0.25).abs() < 1e-5);
        // The range: full at the light, 1 - (d/r)^4 between, zero from the range on.
        let r = spot(20.0, 40.0, Some(8.0));
        let at = |y: f32| light_falloff(&r, Vec3::Y, (4.0 - y) * (4.0 - y));
        assert_eq!(at(4.0 - 1e-4), 1.0);
        assert_eq!(at(0.0), 1.0 - 0.0625);
        assert_eq!(at(-4.0), 0.0);
        assert_eq!(at(-40.0), 0.0);
        // A point light without a range: exactly 1, the irradiance of before spot lights.
        let p = LightRecord::point([0.0, 3.0, 0.0], [7.0; 3]);
        for q in [Vec3::ZERO, Vec3::new(1e-3, 2.999, -5.0), Vec3::splat(1e6)] {
            let (l, e) = light_incidence(&p, q);
            let d = Vec3::from(p.position_or_direction) - q;
            let d2 = d.length_squared().max(MIN_LIGHT_DISTANCE_SQ);
            assert_eq!(light_falloff(&p, l, d2), 1.0);
            assert_eq!(e, Vec3::splat(7.0) / d2);
        }
    }

    #[test]
    fn lambert_matches_closed_form() {
        let l = Vec3::new(0.0, 1.0, 1.0).normalize();
        let c = shade_raster(&grey(), Vec3::Y, Vec3::Y, l, Vec3::ONE);
        assert!((c.x - 0.5 * std::f32::consts::FRAC_1_PI * l.y).abs() < 1e-7);
        assert_eq!(shade_raster(&grey(), Vec3::Y, Vec3::Y, -Vec3::Y, Vec3::ONE), Vec3::ZERO);
    }

    /// Relative error the f32 kernel may have against [`gltf_brdf_f64`], for a half vector
    /// `l + v` of length `len` and GGX alpha `alpha`: `h`'s direction is off by a few f32
    /// roundings of `l + v` over its length (`4 eps / len` rad, bound by
    /// [`gltf_brdf_angle_error`]), which moves `D` by up to `4 dtheta / alpha` relative on
    /// the flank of its peak; plus some twenty roundings of the products (`3e-6`).
    fn gltf_brdf_rel_tol(len: f64, alpha: f64) -> f64 {
        3e-6 + 4.0 * gltf_brdf_angle_error(len) / alpha
    }

    /// The error of `normalize(l + v)`'s direction in f32, in radians: the rounding of the
    /// sum (half an ulp of components up to 2, relative to the length) and of the
    /// normalization, with a factor of two to spare.
    fn gltf_brdf_angle_error(len: f64) -> f64 {
        4.0 * f32::EPSILON as f64 / len
    }

    fn direction() -> impl Strategy<Value = [f32; 3]> {
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0)
            .prop_filter("not too short to normalize", |(x, y, z)| x * x + y * y + z * z > 1e-2)
            .prop_map(|(x, y, z)| Vec3::new(x, y, z).normalize().to_array())
    }

    proptest! {
        #[test]
        fn gltf_brdf_matches_appendix_b_in_f64(
            base in prop::array::uniform3(0.0f32..=1.0),
            metallic in 0.0f32..=1.0,
            roughness in 0.1f32..=1.0,
            n in direction(),
            v in direction(),
            l in direction(),
        ) {
            // Light and view on the normal's side (the caller's `n.l > 0`; a view behind
            // a shading normal is the hard-case test's).
            let nv = Vec3::from(n);
            let upper = |d: [f32; 3]| if nv.dot(Vec3::from(d)) < 0.0 { d.map(|c| -c) } else { d };
            let (l, v) = (upper(l), upper(v));
            let (lv, vv) = (Vec3::from(l), Vec3::from(v));
            prop_assume!(nv.dot(lv) > 1e-3 && nv.dot(vv) > 1e-3);
            let got = gltf_brdf(Vec3::from(base), metallic, roughness, 1.0, nv, vv, lv);
            let f = |d: [f32; 3]| d.map(f64::from);
            let want = gltf_brdf_f64(f(base), metallic as f64, roughness as f64, f(n), f(v), f(l));
            let alpha = ((roughness * roughness) as f64).max(GGX_MIN_ALPHA as f64);
            let tol = gltf_brdf_rel_tol((lv + vv).length() as f64, alpha);
            for c in 0..3 {
                let (g, w) = (got[c] as f64, want[c]);
                prop_assert!((g - w).abs() <= tol * w.abs() + 1e-30, "channel {c}: {g} against {w} (tolerance {tol})");
            }
        }
    }

    #[test]
    fn gltf_brdf_is_finite_on_hard_cases() {
        // A mirror (roughness 0) at its peak, light opposite the view (h = 0), grazing
        // view, view behind the shading normal.
        let n = Vec3::Y;
        let cases = [
            (0.0, n, n),
            (0.5, Vec3::new(0.0, 0.6, 0.8), Vec3::new(0.0, 0.6, -0.8)),
            (0.0, Vec3::new(1.0, 0.0, 0.0), n),
            (0.3, Vec3::new(0.0, -0.6, 0.8), n),
            (1.0, Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, -1.0)),
        ];
        for (roughness, v, l) in cases {
            let f = gltf_brdf(Vec3::splat(0.8), 0.5, roughness, 1.0, n, v, l);
            assert!(f.is_finite() && f.min_element() >= 0.0, "roughness {roughness}, v {v}, l {l}: {f}");
        }
        // The mirror's peak at n = v = l: D = 1 / (pi alpha^2) and V = 1 / 4 with alpha =
        // GGX_MIN_ALPHA, a white metal's F = 1: 1 / (4 pi 1e-6), bounded (f32 rounding).
        let peak = gltf_brdf(Vec3::ONE, 1.0, 0.0, 1.0, n, n, n);
        let want = 1.0 / (4.0 * std::f64::consts::PI * 1e-6);
        assert!((peak.x as f64 - want).abs() < 1e-5 * want, "{peak} against {want}");
    }

    /// A rough dielectric viewed and lit along the normal is `(1 - F) base / pi + F D V`
    /// with `F = 0.04` exactly (`h = n`, `1 - |v.h| = 0`), D and V at their closed forms.
    #[test]
    fn gltf_brdf_at_normal_incidence_is_its_closed_form() {
        let n = Vec3::Y;
        let f = gltf_brdf(Vec3::splat(0.5), 0.0, 1.0, 1.0, n, n, n);
        // alpha = 1: D = 1 / pi, V = 1 / (1 + 1)^2 = 1 / 4.
        let want = 0.96 * 0.5 / std::f64::consts::PI + 0.04 / (4.0 * std::f64::consts::PI);
        assert!((f.x as f64 - want).abs() < 1e-7, "{f} against {want}");
    }

    #[test]
    fn srgb_endpoints() {
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        assert_eq!(linear_to_srgb8(0.5), 188);
    }

    #[test]
    fn composition_is_a_weighted_mean() {
        assert_eq!(compose(Vec3::ONE, Vec3::ZERO, 0.25), Vec3::splat(0.75));
    }
}
