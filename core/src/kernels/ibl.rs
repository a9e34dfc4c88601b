//! Image-based light from the scene's environment (issue 37 item 4): what the glTF BRDF's
//! ambient terms will read instead of constants. Two tables, each computed once per
//! environment (or once for all) on the CPU in f64 and rounded to f32, so that both
//! backends read the same bits, and evaluated by small kernels in a stated order:
//!
//! * [`IrradianceSh9`]: the environment's irradiance `E(n) = ∫ L(ω) max(0, n·ω) dω` as nine
//!   real spherical-harmonic coefficients (Ramamoorthi and Hanrahan 2001, "An Efficient
//!   Representation for Irradiance Environment Maps"): the radiance projected on the
//!   harmonics of order 0 to 2 and convolved with the clamped cosine (`Â0 = π`,
//!   `Â1 = 2π/3`, `Â2 = π/4`). The diffuse lobe then reflects `base (1 - metallic) E(n) / π`.
//! * [`SplitSumTable`]: Karis's split-sum factors (Real Shading in Unreal Engine 4, 2013)
//!   for the glTF BRDF's specular lobe: the directional albedo of the GGX lobe with
//!   height-correlated Smith visibility ([`super::shading::smith_visibility`], the BRDF's
//!   own) as `F0 A + B` over `(n·v, roughness)`.
//!
//! * [`PrefilteredEnvironment`]: the environment's radiance convolved with the GGX lobe at
//!   [`PREFILTER_LEVELS`] roughnesses (Karis's first sum, with `n = v = r`), each level a
//!   lat-long grid half the size of the one before.
//!
//! [`ImageBasedLight`] holds the three for one environment and evaluates them
//! ([`ImageBasedLight::radiance`], [`ImageBasedLight::specular_radiance`]); an
//! [`AmbientLight`] is a frame's whole ambient light: the scene's constant level and, for
//! scenes shaded with the glTF model, the image-based light. The shading kernels read it
//! through [`crate::kernels::shading::ambient`].
//!
//! On the GPU the tables travel as [`AmbientLight::texels`] (one buffer of `vec4<f32>`:
//! the irradiance coefficients, the split-sum cells, then the prefiltered levels, at the
//! offsets of [`AMBIENT_TEXELS_SPLIT_SUM`] and [`prefiltered_offset`]) beside an
//! [`crate::formats::AmbientLightRecord`]. WGSL mirrors (`ambient_light.wgsl`):
//! `irradiance_sh9`, `split_sum_lookup`, `sample_prefiltered_level`,
//! `specular_radiance`, `image_based_light`, by these functions' names.

use std::sync::{Arc, OnceLock};

use glam::Vec3;

use crate::formats::{AmbientLightRecord, OBJ_GLTF_BRDF};
use crate::kernels::environment::{direction_to_uv, environment_radiance, sample_bilinear_grid};
use crate::kernels::shading::{ShadingModel, DIELECTRIC_F0};
use crate::kernels::soft_shadow::AmbientOcclusion;
use crate::scene::Environment;

/// The ambient light of a frame: the scene's constant ambient level
/// ([`crate::scene::Scene::ambient`]) and, for a scene shaded with the glTF model, the
/// light of its environment.
///
/// * `scale`: the constant terms' scale, the level over [`crate::kernels::shading::AMBIENT`]
///   ([`crate::kernels::shading::Ambient::scale`]): 1 by default, 0 for none.
/// * `image`: the environment's [`ImageBasedLight`], present when the scene is shaded with
///   [`crate::kernels::shading::ShadingModel::Gltf`]. Objects of that model then take their
///   ambient light from it (diffuse irradiance and prefiltered specular) besides the
///   constant diffuse term; the paper's model keeps its constants
///   ([`crate::kernels::shading::ENVIRONMENT_SPECULAR`]). Tables built by hand without it
///   shade glTF objects with the constants too.
#[derive(Clone, Debug, PartialEq)]
pub struct AmbientLight {
    pub scale: f32,
    pub image: Option<Arc<ImageBasedLight>>,
    /// The frame's ambient-occlusion rays (none by default): their fraction that meets
    /// nothing scales the ambient and image-based terms
    /// ([`crate::kernels::soft_shadow::occluded_object`]).
    pub occlusion: AmbientOcclusion,
}

impl Default for AmbientLight {
    /// The default level without image-based light.
    fn default() -> Self {
        AmbientLight { scale: 1.0, image: None, occlusion: AmbientOcclusion::default() }
    }
}

impl AmbientLight {
    /// The ambient light of `scene`: its level, and its environment's image-based light
    /// when it is shaded with the glTF model.
    pub fn of_scene(scene: &crate::scene::Scene) -> AmbientLight {
        let image = (scene.shading == ShadingModel::Gltf).then(|| ImageBasedLight::shared(&scene.environment));
        AmbientLight { scale: scene.ambient.scale(), image, occlusion: AmbientOcclusion::default() }
    }

    /// The image-based light an object is shaded with: the frame's, for an object of the
    /// glTF model ([`OBJ_GLTF_BRDF`]); `None` for the paper's model.
    #[inline]
    pub fn image_for(&self, flags: u32) -> Option<&ImageBasedLight> {
        if flags & OBJ_GLTF_BRDF != 0 {
            self.image.as_deref()
        } else {
            None
        }
    }

    /// The record the GPU reads ([`AmbientLightRecord`]).
    pub fn record(&self) -> AmbientLightRecord {
        let ao = &self.occlusion;
        AmbientLightRecord {
            scale: self.scale,
            image: self.image.is_some() as u32,
            ao_samples: ao.samples,
            ao_seed: ao.seed,
            ao_radius: ao.radius,
            pad0: 0,
            pad: [0; 2],
        }
    }

    /// The tables as the GPU reads them: [`SH9_TERMS`] irradiance coefficients (RGB, 0),
    /// the [`SPLIT_SUM_SIZE`]² split-sum cells (`A, B, 0, 0`, row-major by roughness) from
    /// [`AMBIENT_TEXELS_SPLIT_SUM`], then every prefiltered level (RGB, 0; row-major, row 0
    /// at +Y) from [`prefiltered_offset`]`(k)`. One zero texel without image-based light.
    pub fn texels(&self) -> Vec<[f32; 4]> {
        let Some(ibl) = &self.image else { return vec![[0.0; 4]] };
        let mut t = Vec::with_capacity(prefiltered_offset(PREFILTER_LEVELS));
        t.extend(ibl.irradiance.coeffs.iter().map(|&[r, g, b]| [r, g, b, 0.0]));
        t.extend(ibl.split_sum.cells.iter().map(|&[a, b]| [a, b, 0.0, 0.0]));
        for level in &ibl.prefiltered.levels {
            t.extend(level.texels.iter().map(|&[r, g, b]| [r, g, b, 0.0]));
        }
        debug_assert_eq!(t.len(), prefiltered_offset(PREFILTER_LEVELS));
        t
    }
}

/// Terms of the irradiance's spherical-harmonic expansion ([`IrradianceSh9`]).
pub const SH9_TERMS: usize = 9;

/// Where the split-sum cells start in [`AmbientLight::texels`].
pub const AMBIENT_TEXELS_SPLIT_SUM: usize = SH9_TERMS;

/// Where prefiltered level `k` starts in [`AmbientLight::texels`] (`k = PREFILTER_LEVELS`:
/// the number of texels).
pub const fn prefiltered_offset(k: usize) -> usize {
    let mut offset = AMBIENT_TEXELS_SPLIT_SUM + SPLIT_SUM_SIZE * SPLIT_SUM_SIZE;
    let mut i = 0;
    while i < k {
        offset += ((PREFILTER_BASE.0 >> i) * (PREFILTER_BASE.1 >> i)) as usize;
        i += 1;
    }
    offset
}

/// The image-based light of one environment: its irradiance ([`IrradianceSh9`]), the
/// split-sum factors ([`SplitSumTable`], the same for every environment, computed once per
/// process) and its prefiltered radiance ([`PrefilteredEnvironment`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ImageBasedLight {
    pub irradiance: IrradianceSh9,
    pub split_sum: Arc<SplitSumTable>,
    pub prefiltered: PrefilteredEnvironment,
}

impl ImageBasedLight {
    /// The tables of `env`.
    pub fn of(env: &Environment) -> ImageBasedLight {
        static SPLIT_SUM: OnceLock<Arc<SplitSumTable>> = OnceLock::new();
        ImageBasedLight {
            irradiance: IrradianceSh9::of(env),
            split_sum: SPLIT_SUM.get_or_init(|| Arc::new(SplitSumTable::compute())).clone(),
            prefiltered: PrefilteredEnvironment::of(env),
        }
    }

    /// [`ImageBasedLight::of`] shared: the default sky's tables are computed once per
    /// process (every scene without a map has them), a map's for each call.
    pub fn shared(env: &Environment) -> Arc<ImageBasedLight> {
        static SKY: OnceLock<Arc<ImageBasedLight>> = OnceLock::new();
        match env {
            Environment::Sky => SKY.get_or_init(|| Arc::new(ImageBasedLight::of(env))).clone(),
            Environment::Map(_) => Arc::new(ImageBasedLight::of(env)),
        }
    }

    /// The environment's radiance through the GGX lobe of `roughness` around the
    /// direction `r` (any length, non-zero): the prefiltered levels at `r`'s lat-long
    /// coordinates ([`direction_to_uv`]), each bilinear ([`sample_bilinear_grid`]), blended
    /// linearly between the two levels around `roughness (LEVELS - 1)` (roughness clamped
    /// to [0, 1]). WGSL: `specular_radiance`.
    #[inline]
    pub fn specular_radiance(&self, r: Vec3, roughness: f32) -> Vec3 {
        let (u, v) = direction_to_uv(r);
        let x = roughness.clamp(0.0, 1.0) * (PREFILTER_LEVELS - 1) as f32;
        // x >= 0 (or NaN, which converts to 0 either way): the conversion's truncation is
        // its floor, without a libm call on baseline x86-64 (WGSL: floor).
        let k = (x as usize).min(PREFILTER_LEVELS - 2);
        let f = x - k as f32;
        let sample = |level: &PrefilteredLevel| {
            let texel = |i: u32, j: u32| Vec3::from(level.texels[(j * level.width + i) as usize]);
            sample_bilinear_grid(level.width, level.height, texel, u, v)
        };
        let (a, b) = (sample(&self.prefiltered.levels[k]), sample(&self.prefiltered.levels[k + 1]));
        a + (b - a) * f
    }

    /// The light a surface of the glTF model reflects from the environment towards `v`
    /// (unit, towards the viewer) at the unit shading normal `n`, before ambient occlusion:
    /// the split-sum form of glTF 2.0 Appendix B's BRDF under the environment,
    ///
    /// ```text
    /// n.v = max(n.v, 0),  r = 2 (n.v) n - v          (the mirror direction; n where it is zero)
    /// (A, B) = split sum (n.v, roughness),  F0 = mix(0.04, base, metallic)
    /// specular = prefiltered(r, roughness) (F0 A + B)
    /// diffuse  = base (1 - metallic) (1 - (0.04 A + B)) E(n) / pi
    /// ```
    ///
    /// `E(n)` the irradiance ([`IrradianceSh9::irradiance`]). As in Appendix B's
    /// `fresnel_mix`, the dielectric's diffuse lobe keeps what its specular lobe does not
    /// reflect (`1 - (0.04 A + B)`, the lobe's directional albedo); the metal has none.
    /// WGSL: `image_based_light`.
    #[inline]
    pub fn radiance(&self, base: Vec3, metallic: f32, roughness: f32, n: Vec3, v: Vec3) -> Vec3 {
        let n_dot_v = n.dot(v).max(0.0);
        let r = n * (2.0 * n_dot_v) - v;
        let r = if r == Vec3::ZERO { n } else { r };
        let [a, b] = self.split_sum.lookup(n_dot_v, roughness);
        let f0 = Vec3::splat(DIELECTRIC_F0).lerp(base, metallic);
        let specular = self.specular_radiance(r, roughness) * (f0 * a + Vec3::splat(b));
        let kd = (1.0 - metallic) * (1.0 - (DIELECTRIC_F0 * a + b));
        let diffuse = base * kd * (self.irradiance.irradiance(n) * std::f32::consts::FRAC_1_PI);
        diffuse + specular
    }

    /// The diffuse part of [`ImageBasedLight::radiance`] alone, scaled by `diffuse_scale`:
    /// what a surface whose specular lobe is traced (a bouncing surface,
    /// [`crate::kernels::bounce::shade_bouncing`]) adds. WGSL: `image_based_diffuse`.
    #[inline]
    pub fn diffuse(&self, base: Vec3, metallic: f32, n: Vec3, diffuse_scale: f32) -> Vec3 {
        base * ((1.0 - metallic) * diffuse_scale) * (self.irradiance.irradiance(n) * std::f32::consts::FRAC_1_PI)
    }
}

/// The clamped cosine's harmonic coefficients per order, `Â_l` (Ramamoorthi and Hanrahan,
/// equation 8): `π`, `2π/3`, `π/4`.
pub const COSINE_LOBE: [f64; 3] = [std::f64::consts::PI, 2.0 * std::f64::consts::PI / 3.0, std::f64::consts::PI / 4.0];

/// The nine real harmonics' normalisations, in [`sh9_basis`]'s order (`1/2 sqrt(1/π)`,
/// `sqrt(3/4π)`, `1/2 sqrt(15/π)`, `1/4 sqrt(5/π)`, `1/4 sqrt(15/π)`).
pub const SH9_NORMS: [f64; 9] = [
    0.282_094_791_773_878_14,
    0.488_602_511_902_919_9,
    0.488_602_511_902_919_9,
    0.488_602_511_902_919_9,
    1.092_548_430_592_079_2,
    1.092_548_430_592_079_2,
    1.092_548_430_592_079_2,
    0.315_391_565_252_520_05,
    0.546_274_215_296_039_6,
];

/// The order `l` of each of the nine harmonics.
const SH9_ORDER: [usize; 9] = [0, 1, 1, 1, 2, 2, 2, 2, 2];

/// Rows and columns of the lat-long grid the default sky is integrated over (it has no
/// texels): 256 x 128 cells, each at most 1.4 degrees across; the sky's one discontinuity,
/// the horizon, falls between two rows.
pub const SKY_QUADRATURE: (u32, u32) = (256, 128);

/// The direction through the centre of cell `(i, j)` of a `w` x `h` lat-long grid laid out
/// as the environment's maps are ([`crate::kernels::environment`]: `u = φ / 2π`,
/// `v = θ / π` from +Y, `d = (sin θ sin φ, cos θ, -sin θ cos φ)`), and the cell's solid
/// angle, exact in latitude: `(2π / w) (cos θ0 - cos θ1)`.
pub fn latlong_cell(i: u32, j: u32, w: u32, h: u32) -> ([f64; 3], f64) {
    let (t0, t1) = (std::f64::consts::PI * j as f64 / h as f64, std::f64::consts::PI * (j + 1) as f64 / h as f64);
    let theta = 0.5 * (t0 + t1);
    let dphi = std::f64::consts::TAU / w as f64;
    let phi = dphi * (i as f64 + 0.5);
    let d = [theta.sin() * phi.sin(), theta.cos(), -theta.sin() * phi.cos()];
    (d, dphi * (t0.cos() - t1.cos()))
}

/// Point `s` of the `n`-point Hammersley set: `(s / n, the base-2 radical inverse of s)`.
fn hammersley(s: u32, n: u32) -> (f64, f64) {
    (s as f64 / n as f64, s.reverse_bits() as f64 / 4_294_967_296.0)
}

/// The half vector, around +z, that the point `(u1, u2)` of the unit square maps to when
/// half vectors are drawn with density `D(h) (n·h)` for GGX of `alpha² = a2`.
fn ggx_half_vector((u1, u2): (f64, f64), a2: f64) -> [f64; 3] {
    let cos_t = ((1.0 - u2) / (1.0 + (a2 - 1.0) * u2)).sqrt();
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = std::f64::consts::TAU * u1;
    [sin_t * phi.cos(), sin_t * phi.sin(), cos_t]
}

/// The exact integrals of [`sh9_basis`]'s nine harmonics over cell `(i, j)` of a `w` x `h`
/// lat-long grid ([`latlong_cell`]'s layout: `θ` in `[π j / h, π (j + 1) / h]` from +Y,
/// `φ` in `[2π i / w, 2π (i + 1) / w]`, `d = (sin θ sin φ, cos θ, -sin θ cos φ)`,
/// `dω = sin θ dθ dφ`): each harmonic is a product of powers of `sin` and `cos` of `θ` and
/// of `φ`, integrated in closed form, in f64. A midpoint rule would be off by about the
/// cell's angular size squared on the quadratic harmonics (a tenth on a 4 x 2 map).
pub fn sh9_cell_integrals(i: u32, j: u32, w: u32, h: u32) -> [f64; 9] {
    use std::f64::consts::{PI, TAU};
    let (t0, t1) = (PI * j as f64 / h as f64, PI * (j + 1) as f64 / h as f64);
    let (p0, p1) = (TAU * i as f64 / w as f64, TAU * (i + 1) as f64 / w as f64);
    let over_t = |f: fn(f64) -> f64| f(t1) - f(t0);
    let over_p = |f: fn(f64) -> f64| f(p1) - f(p0);
    // θ integrals with the solid angle's sin θ.
    let t_s = over_t(|t| -t.cos()); // ∫ sin
    let t_ss = over_t(|t| t / 2.0 - (2.0 * t).sin() / 4.0); // ∫ sin²
    let t_sc = over_t(|t| t.sin() * t.sin() / 2.0); // ∫ cos sin
    let t_ssc = over_t(|t| t.sin().powi(3) / 3.0); // ∫ cos sin²
    let t_sss = over_t(|t| -t.cos() + t.cos().powi(3) / 3.0); // ∫ sin³
    let t_scc = over_t(|t| -t.cos().powi(3) / 3.0); // ∫ cos² sin
                                                    // φ integrals.
    let p_1 = p1 - p0;
    let p_s = over_p(|p| -p.cos()); // ∫ sin
    let p_c = over_p(|p| p.sin()); // ∫ cos
    let p_ss = over_p(|p| p / 2.0 - (2.0 * p).sin() / 4.0); // ∫ sin²
    let p_cc = over_p(|p| p / 2.0 + (2.0 * p).sin() / 4.0); // ∫ cos²
    let p_sc = over_p(|p| p.sin() * p.sin() / 2.0); // ∫ sin cos
    [
        t_s * p_1,                      // 1
        t_ss * p_s,                     // x = sin θ sin φ
        t_sc * p_1,                     // y = cos θ
        -t_ss * p_c,                    // z = -sin θ cos φ
        t_ssc * p_s,                    // xy
        -t_ssc * p_c,                   // yz
        -t_sss * p_sc,                  // xz
        3.0 * t_sss * p_cc - t_s * p_1, // 3z² - 1
        t_sss * p_ss - t_scc * p_1,     // x² - y²
    ]
}

/// The nine real harmonics at `(x, y, z)` (a unit vector), without their normalisations:
/// `1, x, y, z, xy, yz, xz, 3z² - 1, x² - y²`.
pub fn sh9_basis(d: [f64; 3]) -> [f64; 9] {
    let [x, y, z] = d;
    [1.0, x, y, z, x * y, y * z, x * z, 3.0 * z * z - 1.0, x * x - y * y]
}

/// Irradiance as nine spherical-harmonic coefficients per colour channel, already convolved
/// with the clamped cosine and multiplied by the harmonics' normalisations, so that
/// [`IrradianceSh9::irradiance`] is a polynomial in the normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IrradianceSh9 {
    /// Coefficient `k` of [`sh9_basis`]'s order, RGB.
    pub coeffs: [[f32; 3]; 9],
}

impl IrradianceSh9 {
    /// The irradiance coefficients of `env`, over a lat-long grid of at least
    /// [`SKY_QUADRATURE`]'s cells (a larger map's own texels): each cell's radiance taken
    /// at its centre (a map's texel on its own grid, else the lookup rays make,
    /// [`environment_radiance`]: the default sky, or a small map's bilinear blend) times the
    /// harmonics' exact integrals over the cell ([`sh9_cell_integrals`]), so that a uniform
    /// environment projects exactly onto the constant harmonic; sums in f64, rounded to f32
    /// once.
    pub fn of(env: &Environment) -> IrradianceSh9 {
        let (w, h) = match env {
            Environment::Map(m) => (m.width().max(SKY_QUADRATURE.0), m.height().max(SKY_QUADRATURE.1)),
            Environment::Sky => SKY_QUADRATURE,
        };
        let own_texels = env.map().filter(|m| (m.width(), m.height()) == (w, h));
        let mut sum = [[0.0f64; 3]; 9];
        for j in 0..h {
            for i in 0..w {
                let radiance = match own_texels {
                    Some(m) => {
                        let t = m.texel(i, j);
                        [t[0] as f64, t[1] as f64, t[2] as f64]
                    }
                    None => {
                        let (d, _) = latlong_cell(i, j, w, h);
                        let r = environment_radiance(env, Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32));
                        [r.x as f64, r.y as f64, r.z as f64]
                    }
                };
                for (k, y) in sh9_cell_integrals(i, j, w, h).into_iter().enumerate() {
                    for c in 0..3 {
                        sum[k][c] += radiance[c] * y;
                    }
                }
            }
        }
        // Projection coefficient L_k = N_k ∫ L Y'_k; the irradiance's is Â_l L_k, and its
        // evaluation multiplies by N_k again: fold both into the stored coefficient.
        let coeffs = std::array::from_fn(|k| {
            let scale = SH9_NORMS[k] * SH9_NORMS[k] * COSINE_LOBE[SH9_ORDER[k]];
            std::array::from_fn(|c| (sum[k][c] * scale) as f32)
        });
        IrradianceSh9 { coeffs }
    }

    /// The irradiance at a surface facing `n` (unit): `Σ c_k b_k(n)` over [`sh9_basis`]'s
    /// nine terms, in f32, each product rounded, summed in the basis order.
    pub fn irradiance(&self, n: Vec3) -> Vec3 {
        let (x, y, z) = (n.x, n.y, n.z);
        let basis = [1.0, x, y, z, x * y, y * z, x * z, 3.0 * (z * z) - 1.0, x * x - y * y];
        let mut e = Vec3::ZERO;
        for (c, b) in self.coeffs.iter().zip(basis) {
            e += Vec3::from(*c) * b;
        }
        e
    }
}

/// Cells per side of the [`SplitSumTable`]: `n·v` and roughness each in 32 steps.
pub const SPLIT_SUM_SIZE: usize = 32;

/// GGX samples per cell of the [`SplitSumTable`] (a Hammersley set): the factors converge
/// to about 1e-3 at the roughest cells, below what an 8-bit image shows.
pub const SPLIT_SUM_SAMPLES: u32 = 1024;

/// Karis's split-sum factors `(A, B)` of the glTF BRDF's specular lobe: its directional
/// albedo for a reflectance at normal incidence `F0` is `F0 A + B` (Schlick's Fresnel
/// `F0 + (1 - F0)(1 - v·h)^5`). Cell `(i, j)` holds `n·v = (i + 1/2) / SIZE` and
/// `roughness = (j + 1/2) / SIZE` (alpha = roughness², as the BRDF).
#[derive(Clone, Debug, PartialEq)]
pub struct SplitSumTable {
    /// Row-major by roughness: `cells[j * SPLIT_SUM_SIZE + i]`.
    pub cells: Vec<[f32; 2]>,
}

impl SplitSumTable {
    /// The table, by GGX importance sampling in f64 ([`SPLIT_SUM_SAMPLES`] Hammersley
    /// points a cell): for a half vector `h` drawn with density `D(h) (n·h)`, the light
    /// direction `l = reflect(-v, h)` has density `D (n·h) / (4 v·h)`, so each sample
    /// weighs `V 4 (n·l)(v·h) / (n·h)` with `V` the height-correlated Smith visibility.
    pub fn compute() -> SplitSumTable {
        let n = SPLIT_SUM_SIZE;
        let mut cells = Vec::with_capacity(n * n);
        let samples: Vec<(f64, f64)> = (0..SPLIT_SUM_SAMPLES).map(|s| hammersley(s, SPLIT_SUM_SAMPLES)).collect();
        for j in 0..n {
            let roughness = (j as f64 + 0.5) / n as f64;
            let alpha = roughness * roughness;
            for i in 0..n {
                let n_dot_v = (i as f64 + 0.5) / n as f64;
                cells.push(split_sum_f64(n_dot_v, alpha, &samples).map(|x| x as f32));
            }
        }
        SplitSumTable { cells }
    }

    /// `(A, B)` at `(n·v, roughness)`, bilinear between cell centres, clamped at the edges.
    pub fn lookup(&self, n_dot_v: f32, roughness: f32) -> [f32; 2] {
        let n = SPLIT_SUM_SIZE;
        let at = |x: f32| {
            let p = (x.clamp(0.0, 1.0) * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
            // p >= 0 (or NaN): truncation is the floor (WGSL: floor), without a libm call.
            let i0 = (p as usize).min(n - 2);
            (i0, p - i0 as f32)
        };
        let ((i, fx), (j, fy)) = (at(n_dot_v), at(roughness));
        let cell = |i: usize, j: usize| self.cells[j * n + i];
        let lerp = |a: [f32; 2], b: [f32; 2], f: f32| [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f];
        lerp(lerp(cell(i, j), cell(i + 1, j), fx), lerp(cell(i, j + 1), cell(i + 1, j + 1), fx), fy)
    }
}

/// The split-sum factors at one `(n·v, alpha)` over the Hammersley `samples`, in f64 (see
/// [`SplitSumTable::compute`]).
fn split_sum_f64(n_dot_v: f64, alpha: f64, samples: &[(f64, f64)]) -> [f64; 2] {
    let v = [(1.0 - n_dot_v * n_dot_v).max(0.0).sqrt(), 0.0, n_dot_v];
    let a2 = alpha * alpha;
    let (mut a, mut b) = (0.0, 0.0);
    for &u in samples {
        let h = ggx_half_vector(u, a2);
        let v_dot_h = v[0] * h[0] + v[2] * h[2];
        let l = [2.0 * v_dot_h * h[0] - v[0], 2.0 * v_dot_h * h[1], 2.0 * v_dot_h * h[2] - v[2]];
        let (n_dot_l, n_dot_h) = (l[2], h[2]);
        if n_dot_l <= 0.0 || v_dot_h <= 0.0 {
            continue;
        }
        // Height-correlated Smith (glTF 2.0 Appendix B).
        let gv = n_dot_l * (n_dot_v * n_dot_v * (1.0 - a2) + a2).sqrt();
        let gl = n_dot_v * (n_dot_l * n_dot_l * (1.0 - a2) + a2).sqrt();
        let vis = 0.5 / (gv + gl);
        let weight = vis * 4.0 * n_dot_l * v_dot_h / n_dot_h;
        let fc = (1.0 - v_dot_h).powi(5);
        a += (1.0 - fc) * weight;
        b += fc * weight;
    }
    [a / samples.len() as f64, b / samples.len() as f64]
}

/// Roughness levels of the [`PrefilteredEnvironment`]: roughness `k / (LEVELS - 1)`, from a
/// mirror (the environment itself, at [`PREFILTER_BASE`]'s resolution) to 1.
pub const PREFILTER_LEVELS: usize = 6;

/// Columns and rows of the sharpest level; each level after it halves both (a rougher lobe
/// needs fewer texels: at roughness 0.2 the GGX lobe is already about 10 degrees wide).
pub const PREFILTER_BASE: (u32, u32) = (128, 64);

/// GGX samples per texel of the blurred levels (a Hammersley set, as the split sum's).
pub const PREFILTER_SAMPLES: u32 = 256;

/// One level of a [`PrefilteredEnvironment`]: linear RGB radiance on a lat-long grid laid out
/// as the environment's maps are (`crate::scene::environment`), texel centres at
/// half-integers.
#[derive(Clone, Debug, PartialEq)]
pub struct PrefilteredLevel {
    pub width: u32,
    pub height: u32,
    /// Row-major, row 0 at +Y.
    pub texels: Vec<[f32; 3]>,
}

/// The environment's radiance seen through the GGX lobe of each roughness level: for a
/// surface whose mirror direction is `r`, `∫ L(l) D(h) (n·l) dl / ∫ D(h) (n·l) dl` with
/// `n = v = r` (Karis's approximation), by importance sampling the lobe.
#[derive(Clone, Debug, PartialEq)]
pub struct PrefilteredEnvironment {
    /// [`PREFILTER_LEVELS`] levels, smoothest last.
    pub levels: Vec<PrefilteredLevel>,
}

impl PrefilteredEnvironment {
    /// The levels of `env`. Level 0 is the environment's radiance at each texel's centre
    /// direction; level `k` averages [`PREFILTER_SAMPLES`] lobe samples per texel (weights
    /// `n·l`, the radiance by [`environment_radiance`], sums in f64).
    pub fn of(env: &Environment) -> PrefilteredEnvironment {
        let samples: Vec<(f64, f64)> = (0..PREFILTER_SAMPLES).map(|s| hammersley(s, PREFILTER_SAMPLES)).collect();
        let levels = (0..PREFILTER_LEVELS)
            .map(|k| {
                let (width, height) = (PREFILTER_BASE.0 >> k, PREFILTER_BASE.1 >> k);
                let roughness = k as f64 / (PREFILTER_LEVELS - 1) as f64;
                let alpha = roughness * roughness;
                let texels = (0..height)
                    .flat_map(|j| (0..width).map(move |i| (i, j)))
                    .map(|(i, j)| {
                        let (r, _) = latlong_cell(i, j, width, height);
                        if k == 0 {
                            let l = environment_radiance(env, Vec3::new(r[0] as f32, r[1] as f32, r[2] as f32));
                            return l.to_array();
                        }
                        prefiltered_f64(env, r, alpha, &samples).map(|x| x as f32)
                    })
                    .collect();
                PrefilteredLevel { width, height, texels }
            })
            .collect();
        PrefilteredEnvironment { levels }
    }
}

/// One prefiltered texel: GGX lobe samples around `r` (as `n = v = r`), weighted by `n·l`.
fn prefiltered_f64(env: &Environment, r: [f64; 3], alpha: f64, samples: &[(f64, f64)]) -> [f64; 3] {
    // An orthonormal frame around r.
    let up = if r[1].abs() < 0.999 { [0.0, 1.0, 0.0] } else { [1.0, 0.0, 0.0] };
    let cross =
        |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let norm = |a: [f64; 3]| {
        let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        [a[0] / l, a[1] / l, a[2] / l]
    };
    let tx = norm(cross(up, r));
    let ty = cross(r, tx);
    let a2 = alpha * alpha;
    let (mut sum, mut weight) = ([0.0f64; 3], 0.0f64);
    for &u in samples {
        let [hx, hy, hz] = ggx_half_vector(u, a2);
        let h: [f64; 3] = std::array::from_fn(|c| tx[c] * hx + ty[c] * hy + r[c] * hz);
        // l = reflect(-v, h) with v = r: 2 (r.h) h - r; n.l = 2 (r.h)^2 - 1.
        let r_dot_h = hz;
        let n_dot_l = 2.0 * r_dot_h * r_dot_h - 1.0;
        if n_dot_l <= 0.0 {
            continue;
        }
        let l: [f64; 3] = std::array::from_fn(|c| 2.0 * r_dot_h * h[c] - r[c]);
        let radiance = environment_radiance(env, Vec3::new(l[0] as f32, l[1] as f32, l[2] as f32));
        for (s, x) in sum.iter_mut().zip(radiance.to_array()) {
            *s += x as f64 * n_dot_l;
        }
        weight += n_dot_l;
    }
    sum.map(|s| s / weight)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::EnvironmentMap;
    use std::sync::Arc;

    fn map(w: u32, h: u32, texel: impl Fn(u32, u32) -> [f32; 3]) -> Environment {
        let texels =
            (0..h).flat_map(|j| (0..w).map(move |i| (i, j))).map(|(i, j)| texel(i, j)).map(|[r, g, b]| [r, g, b, 1.0]);
        Environment::Map(Arc::new(EnvironmentMap::new(w, h, texels.collect()).unwrap()))
    }

    fn unit(a: f32, b: f32) -> Vec3 {
        Vec3::new(a.cos() * b.sin(), b.cos(), a.sin() * b.sin())
    }

    /// The closed-form cell integrals: over the whole sphere the non-constant harmonics
    /// integrate to zero and the constant one to 4π, on grids down to 1 x 1 cell; one cell
    /// against a fine midpoint rule.
    #[test]
    fn sh9_cell_integrals_are_exact() {
        for (w, h) in [(1, 1), (4, 2), (7, 3), (256, 128)] {
            let mut total = [0.0f64; 9];
            for j in 0..h {
                for i in 0..w {
                    for (t, x) in total.iter_mut().zip(sh9_cell_integrals(i, j, w, h)) {
                        *t += x;
                    }
                }
            }
            assert!((total[0] - 4.0 * std::f64::consts::PI).abs() < 1e-12, "{w}x{h}: {total:?}");
            assert!(total[1..].iter().all(|x| x.abs() < 1e-12), "{w}x{h}: {total:?}");
        }
        // Cell (1, 0) of a 4 x 2 grid (θ in [0, π/2], φ in [π/2, π]), by a 400 x 400
        // midpoint rule (error about 1e-5 of the cell's values, far above f64's).
        let (n, mut fine) = (400u32, [0.0f64; 9]);
        for jj in 0..n {
            for ii in 0..n {
                let (d, solid_angle) = latlong_cell(4 * n / 4 + ii, jj, 4 * n, 2 * n);
                for (f, y) in fine.iter_mut().zip(sh9_basis(d)) {
                    *f += y * solid_angle;
                }
            }
        }
        let exact = sh9_cell_integrals(1, 0, 4, 2);
        for k in 0..9 {
            assert!((exact[k] - fine[k]).abs() < 1e-4, "harmonic {k}: {} vs {}", exact[k], fine[k]);
        }
    }

    #[test]
    fn a_uniform_environment_gives_pi_times_its_radiance_everywhere() {
        let sh = IrradianceSh9::of(&map(64, 32, |_, _| [0.5, 1.0, 2.0]));
        for k in 0..200 {
            let n = unit(k as f32 * 2.39996, (k as f32 + 0.5) / 200.0 * std::f32::consts::PI);
            let e = sh.irradiance(n);
            for (got, l) in e.to_array().into_iter().zip([0.5, 1.0, 2.0]) {
                // The lat-long quadrature: exact band areas, but the harmonics taken at each
                // row's middle latitude; the order-2 terms of a constant then integrate to
                // O((π/H)²) instead of 0: 5.0e-4 of π L measured at the poles with H = 32.
                let want = std::f32::consts::PI * l;
                assert!((got - want).abs() <= 1e-3 * want, "{n:?}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn a_bright_upper_hemisphere_gives_the_exact_cosine_ramp() {
        // L above the horizon, 0 below: E(n) = π L (1 + n.y) / 2 exactly, and that function
        // lies in the span of orders 0 and 1, which the projection keeps whole (the step's
        // order-2 part is zero); only the quadrature errs.
        let sh = IrradianceSh9::of(&map(128, 64, |_, j| if j < 32 { [1.0; 3] } else { [0.0; 3] }));
        for k in 0..200 {
            let n = unit(k as f32 * 2.39996, (k as f32 + 0.5) / 200.0 * std::f32::consts::PI);
            let want = std::f32::consts::PI * (1.0 + n.y) * 0.5;
            let got = sh.irradiance(n).x;
            // The quadrature's middle latitudes (see the uniform case): 6.7e-4 at worst
            // measured over these normals, with H = 64.
            assert!((got - want).abs() < 2e-3, "{n:?}: {got} vs {want}");
        }
    }

    #[test]
    fn the_default_sky_matches_a_brute_force_cosine_integral() {
        let sh = IrradianceSh9::of(&Environment::Sky);
        for n in
            [Vec3::Y, -Vec3::Y, Vec3::X, Vec3::new(0.3, 0.8, -0.52).normalize(), Vec3::new(0.1, -0.6, 0.79).normalize()]
        {
            // E(n) by the same lat-long grid, twice as fine, with the clamped cosine itself.
            let (w, h) = (512u32, 256u32);
            let mut e = [0.0f64; 3];
            for j in 0..h {
                for i in 0..w {
                    let ([x, y, z], solid_angle) = latlong_cell(i, j, w, h);
                    let d = Vec3::new(x as f32, y as f32, z as f32);
                    let c = n.dot(d).max(0.0) as f64 * solid_angle;
                    let r = environment_radiance(&Environment::Sky, d);
                    for (e, r) in e.iter_mut().zip(r.to_array()) {
                        *e += r as f64 * c;
                    }
                }
            }
            let got = sh.irradiance(n);
            for (got, want) in got.to_array().into_iter().zip(e) {
                // Nine harmonics of a sky with a step at the horizon: the truncation of the
                // clamped cosine after order 2 (Ramamoorthi and Hanrahan: about 3% of the
                // irradiance's scale on average). Measured: 6.1e-3 at worst, at the nadir,
                // of irradiances 0.3 to 1.6.
                assert!((got as f64 - want).abs() < 0.015, "{n:?}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn prefiltering_keeps_a_uniform_environment_and_blurs_a_horizon() {
        let uniform = PrefilteredEnvironment::of(&map(32, 16, |_, _| [0.5, 1.0, 2.0]));
        assert_eq!(uniform.levels.len(), PREFILTER_LEVELS);
        for (k, level) in uniform.levels.iter().enumerate() {
            assert_eq!((level.width, level.height), (PREFILTER_BASE.0 >> k, PREFILTER_BASE.1 >> k));
            for t in &level.texels {
                // A weighted mean of one value: that value, but for the f64 sum's rounding.
                for (got, want) in t.iter().zip([0.5f32, 1.0, 2.0]) {
                    assert!((got - want).abs() <= 1e-6 * want, "level {k}: {t:?}");
                }
            }
        }
        // A bright upper hemisphere: level 0 is the map at its texels' directions (the rows
        // next to the horizon bilinear between the map's lit and dark rows); the rough
        // levels mix both halves there (the map alone would read 1 and 0 at those rows'
        // centres, which lie inside its lit and dark halves), symmetrically.
        let step = PrefilteredEnvironment::of(&map(64, 32, |_, j| if j < 16 { [1.0; 3] } else { [0.0; 3] }));
        let horizon = |k: usize| {
            let l = &step.levels[k];
            (
                l.texels[(l.height / 2 - 1) as usize * l.width as usize][0],
                l.texels[(l.height / 2) as usize * l.width as usize][0],
            )
        };
        assert_eq!(horizon(0), (0.75, 0.25));
        for k in 1..PREFILTER_LEVELS {
            let (a, b) = horizon(k);
            // Symmetric but for the sample set, which is not symmetric about the horizon
            // (1.0e-3 off measured with 256 samples).
            assert!(a > 0.5 && a < 0.99 && (a + b - 1.0).abs() < 5e-3, "level {k}: {a}, {b}");
        }
        // The roughest lobe is wide: at 45 degrees above the horizon (its 4 x 2 grid's top
        // row) it still sees a good part of the dark half.
        assert!(horizon(PREFILTER_LEVELS - 1).0 < 0.9, "{:?}", horizon(PREFILTER_LEVELS - 1));
        // The top row stays brighter than the bottom row, mirror images of each other
        // about the horizon but for the sample set (as above).
        for l in &step.levels {
            let (top, bottom) = (l.texels[0][0], l.texels[l.texels.len() - 1][0]);
            assert!(top > 0.5 && (top + bottom - 1.0).abs() < 5e-3, "{}x{}: {top}, {bottom}", l.width, l.height);
        }
    }

    #[test]
    fn split_sum_factors_are_an_albedo() {
        let t = SplitSumTable::compute();
        for j in 0..SPLIT_SUM_SIZE {
            for i in 0..SPLIT_SUM_SIZE {
                let [a, b] = t.cells[j * SPLIT_SUM_SIZE + i];
                // A single-scattering albedo with F = 1: at most 1, plus the estimator's
                // noise (1024 stratified samples).
                assert!(a >= 0.0 && b >= 0.0 && a + b <= 1.0 + 2e-3, "cell ({i}, {j}): {a} + {b}");
            }
        }
        // A smooth mirror reflects everything: at the smoothest row A + B is nearly 1 (the
        // row's roughness is 1/64, alpha 2.4e-4), and rough surfaces lose energy to the
        // single-scattering model's missing bounces, most at grazing angles.
        let [a, b] = t.lookup(1.0, 0.0);
        assert!((a + b - 1.0).abs() < 2e-3, "{a} + {b}");
        let rough = t.lookup(0.5, 1.0);
        assert!(rough[0] + rough[1] < 0.9, "{rough:?}");
        // Fresnel's grazing weight: B grows towards grazing angles.
        assert!(t.lookup(0.05, 0.3)[1] > t.lookup(0.95, 0.3)[1]);
        // The lookup returns cell centres exactly and clamps outside.
        let c = t.cells[5 * SPLIT_SUM_SIZE + 7];
        assert_eq!(t.lookup((7.0 + 0.5) / 32.0, (5.0 + 0.5) / 32.0), c);
        assert_eq!(t.lookup(-1.0, 2.0), t.lookup(0.0, 1.0));
    }
}
