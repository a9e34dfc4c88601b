//! The raster shader of `raster_shading` over eight pixels at once: core's
//! [`shade_raster_pixel`] (with [`unlit`], [`sum_visible_lights`], [`light_incidence`]
//! and [`shade_raster`]) and the stage's [`raster_shading_pixel`] around it, each lane
//! doing the scalar kernels' operations in their order, every one a correctly rounded IEEE
//! 754 f32 operation or a bit operation ([`Lanes`]), so that every lane's texel is the
//! scalar kernel's bits (`tests` pins them).
//!
//! The eight pixels may lie on different objects: [`PrimaryLanes::load`] gathers each
//! lane's record. Where materials vary over surfaces ([`Materials::varying`]: textures,
//! vertex colours) the caller gives each lane the record it is shaded with, as the scalar
//! stage makes it per pixel (`Primary::object`: the texture lookups stay scalar, the
//! shading is in lanes; [`PrimaryLanes::load_shaded`]).
//!
//! Light-independent parts of a kernel (the base colour over pi, the unlit term) are
//! computed once for all lights: the same operations on the same operands, so the same bits.
//!
//! Objects shaded with the glTF BRDF ([`OBJ_GLTF_BRDF`]) take core's `shade_gltf` in lanes
//! ([`GltfShader`], through [`sum_visible_lights_gltf_lanes`], which `rt_shading`'s lanes
//! share) instead of the paper's shaders; a block mixing both models runs both and selects
//! per lane.
//!
//! [`shade_raster_pixel`]: hyrt_core::kernels::shading::shade_raster_pixel
//! [`unlit`]: hyrt_core::kernels::shading::unlit
//! [`sum_visible_lights`]: hyrt_core::kernels::shading::sum_visible_lights
//! [`light_incidence`]: hyrt_core::kernels::shading::light_incidence
//! [`shade_raster`]: hyrt_core::kernels::shading::shade_raster
//! [`raster_shading_pixel`]: crate::raster_shading::raster_shading_pixel
//! [`Materials::varying`]: hyrt_core::kernels::texture::Materials::varying

use glam::Vec3;
use hyrt_core::formats::{LightRecord, ObjectRecord, SurfaceRecord, OBJ_GLTF_BRDF, OBJ_RAY_TRACED};
use hyrt_core::kernels::shading::{
    AmbientLight, AMBIENT, BACKGROUND_RGBA, DIELECTRIC_F0, ENVIRONMENT_SPECULAR, GGX_MIN_ALPHA,
};

use crate::compaction::lanes::{light_incidence_lanes, surface_quads};
use crate::lanes::{dot3, mask_lanes, normalize_or_zero_lanes, select3, splat3, sub3, zero3, Lanes, LANES};

// No closures around lane operations (`map`, `from_fn`): a closure does not inherit its
// caller's target features, so its lane operations would not inline into the AVX2 entry
// points.

/// Eight primary hits as lanes: what the shaders read of their surfaces and their objects'
/// records (zeros in a miss's lanes).
#[derive(Clone, Copy)]
pub(crate) struct PrimaryLanes<L: Lanes> {
    /// All ones where the surface is a hit ([`SurfaceRecord::is_hit`]).
    pub hit: L::F,
    /// All ones where it is a hit on a ray-traced object ([`OBJ_RAY_TRACED`]).
    pub ray_traced: L::F,
    /// All ones where it is a hit on an object shaded with the glTF BRDF
    /// ([`OBJ_GLTF_BRDF`]).
    pub gltf: L::F,
    pub position: [L::F; 3],
    pub normal: [L::F; 3],
    pub base_color: [L::F; 3],
    pub metallic: L::F,
    pub roughness: L::F,
    pub emissive: [L::F; 3],
    pub occlusion: L::F,
}

impl<L: Lanes> PrimaryLanes<L> {
    /// The lanes of eight surfaces and of their objects' records (a transpose).
    #[inline(always)]
    pub fn load(s: [&SurfaceRecord; LANES], objects: &[ObjectRecord]) -> PrimaryLanes<L> {
        let mut shaded = [&objects[0]; LANES];
        for (shaded, r) in shaded.iter_mut().zip(s) {
            if r.is_hit() {
                *shaded = &objects[r.object as usize];
            }
        }
        Self::load_shaded(s, objects, shaded)
    }

    /// [`Self::load`] with lane `k` shaded with the record `shaded[k]` (read where it is a
    /// hit): the material at its pixel where materials vary. Whether it is ray traced is its
    /// object's (`objects`), as in the scalar stages.
    ///
    /// The surfaces come in by a transpose in registers ([`surface_quads`]). Where every
    /// hit lane is on one object shaded with one record (most blocks of most frames) its
    /// fields are splatted and masked to the hits; otherwise they are gathered lane by
    /// lane. Either way a miss's lanes hold zeros.
    #[inline(always)]
    pub fn load_shaded(
        s: [&SurfaceRecord; LANES],
        objects: &[ObjectRecord],
        shaded: [&ObjectRecord; LANES],
    ) -> PrimaryLanes<L> {
        let ([p, n, _], hit) = surface_quads::<L>(s);
        let position = [p[0], p[1], p[2]];
        let normal = [n[0], n[1], n[2]];
        // The first hit lane's object and record, if every hit lane shares them.
        let mut one: Option<(u32, &ObjectRecord)> = None;
        let mut uniform = true;
        for (r, obj) in s.iter().zip(shaded) {
            if !r.is_hit() {
                continue;
            }
            match one {
                None => one = Some((r.object, obj)),
                Some((o, first)) => uniform &= o == r.object && std::ptr::eq(first, obj),
            }
        }
        let zero = L::splat(0.0);
        let Some((o, obj)) = one else {
            return PrimaryLanes {
                hit,
                ray_traced: zero,
                gltf: zero,
                position,
                normal,
                base_color: [zero; 3],
                metallic: zero,
                roughness: zero,
                emissive: [zero; 3],
                occlusion: zero,
            };
        };
        if uniform {
            let flags = objects[o as usize].flags;
            let flag = |bit: u32| if flags & bit != 0 { hit } else { zero };
            return PrimaryLanes {
                hit,
                ray_traced: flag(OBJ_RAY_TRACED),
                gltf: flag(OBJ_GLTF_BRDF),
                position,
                normal,
                base_color: [
                    L::and(hit, L::splat(obj.base_color[0])),
                    L::and(hit, L::splat(obj.base_color[1])),
                    L::and(hit, L::splat(obj.base_color[2])),
                ],
                metallic: L::and(hit, L::splat(obj.metallic)),
                roughness: L::and(hit, L::splat(obj.roughness)),
                emissive: [
                    L::and(hit, L::splat(obj.emissive[0])),
                    L::and(hit, L::splat(obj.emissive[1])),
                    L::and(hit, L::splat(obj.emissive[2])),
                ],
                occlusion: L::and(hit, L::splat(obj.occlusion)),
            };
        }
        let mut w = [[0.0f32; LANES]; 11];
        for (k, (r, obj)) in s.iter().zip(shaded).enumerate() {
            if !r.is_hit() {
                continue;
            }
            let flags = objects[r.object as usize].flags;
            w[0][k] = f32::from_bits(if flags & OBJ_RAY_TRACED != 0 { u32::MAX } else { 0 });
            w[1][k] = f32::from_bits(if flags & OBJ_GLTF_BRDF != 0 { u32::MAX } else { 0 });
            for a in 0..3 {
                w[2 + a][k] = obj.base_color[a];
                w[7 + a][k] = obj.emissive[a];
            }
            w[5][k] = obj.metallic;
            w[6][k] = obj.roughness;
            w[10][k] = obj.occlusion;
        }
        PrimaryLanes {
            hit,
            ray_traced: L::load(&w[0]),
            gltf: L::load(&w[1]),
            position,
            normal,
            base_color: [L::load(&w[2]), L::load(&w[3]), L::load(&w[4])],
            metallic: L::load(&w[5]),
            roughness: L::load(&w[6]),
            emissive: [L::load(&w[7]), L::load(&w[8]), L::load(&w[9])],
            occlusion: L::load(&w[10]),
        }
    }
}

/// Per light, the lanes whose shadow ray reached it (`SHADOW_LIT`), bit `k` for lane `k`:
/// what [`sum_visible_lights_lanes`] reads of the shadow mask.
pub(crate) type LitLanes = [u32];

/// A one-light shader over lanes: the closure core's kernels pass to
/// [`sum_visible_lights`](hyrt_core::kernels::shading::sum_visible_lights).
pub(crate) trait LightShader<L: Lanes> {
    /// The shader's colour from a light in direction `l` with irradiance scale `e`.
    fn shade(&self, l: [L::F; 3], e: [L::F; 3]) -> [L::F; 3];
}

/// Core's `sum_visible_lights` per lane: `shade` summed, in light order from zero, over the
/// lights whose bit is set in the lane's `lit` word; a light no lane sees is skipped (it
/// would add nothing anywhere).
#[inline(always)]
pub(crate) fn sum_visible_lights_lanes<L: Lanes, S: LightShader<L>>(
    lit: &LitLanes,
    lights: &[LightRecord],
    p: [L::F; 3],
    shade: &S,
) -> [L::F; 3] {
    let mut c = zero3::<L>();
    for (light, &lit) in lights.iter().zip(lit) {
        if lit == 0 {
            continue;
        }
        let (l, e) = light_incidence_lanes::<L>(light, p);
        let s = shade.shade(l, e);
        let lit = mask_lanes::<L>(lit);
        c = select3::<L>(lit, [L::add(c[0], s[0]), L::add(c[1], s[1]), L::add(c[2], s[2])], c);
    }
    c
}

/// `Vec3::splat(DIELECTRIC_F0).lerp(base, metallic)` per lane (glam's `lerp`:
/// `self * (1 - s) + rhs * s`): the specular reflectance at normal incidence.
#[inline(always)]
pub(crate) fn f0_lanes<L: Lanes>(base: [L::F; 3], metallic: L::F) -> [L::F; 3] {
    let dielectric = L::mul(L::splat(DIELECTRIC_F0), L::sub(L::splat(1.0), metallic));
    [
        L::add(dielectric, L::mul(base[0], metallic)),
        L::add(dielectric, L::mul(base[1], metallic)),
        L::add(dielectric, L::mul(base[2], metallic)),
    ]
}

/// Core's `unlit(obj, n, v, ambient)` per lane, seen from `eye` (`v` is the unit vector
/// from the surface to the eye, as `shade_rt_pixel` and `shade_raster_pixel` make it):
/// `ambient(..) + emissive`, with `ambient(..)` =
/// `(base * ((1 - metallic) * AMBIENT) + f0 * ENVIRONMENT_SPECULAR) * (scale * occlusion)`
/// for the paper's model, and on the glTF lanes of a frame with image-based light
/// `base * ((1 - metallic) * AMBIENT) * (scale * occlusion) + IBL * occlusion`, the
/// image-based term by core's scalar kernel lane by lane (its table lookups do not
/// vectorize; the same operations on the same operands, so the same bits), only on the
/// `wanted` lanes (the ones the caller keeps: the others get the paper's terms).
#[inline(always)]
pub(crate) fn unlit_lanes<L: Lanes>(
    p: &PrimaryLanes<L>,
    ambient: &AmbientLight,
    eye: [f32; 3],
    wanted: L::F,
) -> [L::F; 3] {
    let (base, metallic) = (p.base_color, p.metallic);
    let f0 = f0_lanes::<L>(base, metallic);
    let k = L::mul(L::sub(L::splat(1.0), metallic), L::splat(AMBIENT));
    let env = L::splat(ENVIRONMENT_SPECULAR);
    let (o, e) = (L::mul(L::splat(ambient.scale), p.occlusion), p.emissive);
    let paper = [
        L::add(L::mul(L::add(L::mul(base[0], k), L::mul(f0[0], env)), o), e[0]),
        L::add(L::mul(L::add(L::mul(base[1], k), L::mul(f0[1], env)), o), e[1]),
        L::add(L::mul(L::add(L::mul(base[2], k), L::mul(f0[2], env)), o), e[2]),
    ];
    let image_lanes = L::bits(L::and(L::and(p.gltf, p.hit), wanted));
    let Some(ibl) = ambient.image.as_deref() else { return paper };
    if image_lanes == 0 {
        return paper;
    }
    // The image-based term, lane by lane, times the occlusion.
    let [bx, by, bz] = [L::store(base[0]), L::store(base[1]), L::store(base[2])];
    let [nx, ny, nz] = [L::store(p.normal[0]), L::store(p.normal[1]), L::store(p.normal[2])];
    let [px, py, pz] = [L::store(p.position[0]), L::store(p.position[1]), L::store(p.position[2])];
    let (m, r, occ) = (L::store(metallic), L::store(p.roughness), L::store(p.occlusion));
    let mut image = [[0.0f32; LANES]; 3];
    for lane in 0..LANES {
        if image_lanes & (1 << lane) == 0 {
            continue;
        }
        let v = (Vec3::from(eye) - Vec3::new(px[lane], py[lane], pz[lane])).normalize_or_zero();
        let (b, n) = (Vec3::new(bx[lane], by[lane], bz[lane]), Vec3::new(nx[lane], ny[lane], nz[lane]));
        let c = ibl.radiance(b, m[lane], r[lane], n, v) * occ[lane];
        for (image, c) in image.iter_mut().zip(c.to_array()) {
            image[lane] = c;
        }
    }
    let image = [L::load(&image[0]), L::load(&image[1]), L::load(&image[2])];
    let gltf = [
        L::add(L::add(L::mul(L::mul(base[0], k), o), image[0]), e[0]),
        L::add(L::add(L::mul(L::mul(base[1], k), o), image[1]), e[1]),
        L::add(L::add(L::mul(L::mul(base[2], k), o), image[2]), e[2]),
    ];
    select3::<L>(p.gltf, gltf, paper)
}

/// Core's `shade_raster(obj, n, l, e)` per lane: `((base * FRAC_1_PI) * e) * n.l`, zero
/// where `n.l <= 0`; `base * FRAC_1_PI` ([`RasterShader::base_over_pi`]) once for all
/// lights.
struct RasterShader<L: Lanes> {
    n: [L::F; 3],
    base_over_pi: [L::F; 3],
}

impl<L: Lanes> LightShader<L> for RasterShader<L> {
    #[inline(always)]
    fn shade(&self, l: [L::F; 3], e: [L::F; 3]) -> [L::F; 3] {
        let ndl = dot3::<L>(self.n, l);
        let b = self.base_over_pi;
        // `ndl <= 0` returns zero; a NaN `ndl` goes on, as in the scalar kernel.
        let back = L::le(ndl, L::splat(0.0));
        let c = [L::mul(L::mul(b[0], e[0]), ndl), L::mul(L::mul(b[1], e[1]), ndl), L::mul(L::mul(b[2], e[2]), ndl)];
        select3::<L>(back, zero3::<L>(), c)
    }
}

/// Core's `shade_gltf(obj, n, v, l, e)` per lane (`gltf_brdf` with diffuse scale 1, times
/// `e` and `n.l`), with what does not depend on the light computed once
/// ([`GltfShader::of`]): the same operations in the same order as the scalar kernel.
struct GltfShader<L: Lanes> {
    n: [L::F; 3],
    v: [L::F; 3],
    base: [L::F; 3],
    metallic: L::F,
    /// `max(roughness^2, GGX_MIN_ALPHA)` squared.
    a2: L::F,
    /// `1 - a2`.
    one_minus_a2: L::F,
    /// `smith_visibility`'s denominator in `v`, `|n.v| + sqrt(a2 + (1 - a2) (n.v)^2)`,
    /// which no light changes.
    gv: L::F,
}

impl<L: Lanes> GltfShader<L> {
    /// The shader of the lanes' materials, seen along `-v`.
    #[inline(always)]
    fn of(p: &PrimaryLanes<L>, v: [L::F; 3]) -> GltfShader<L> {
        // `f32::max(a, c)` against a constant: `MAXPS` with the constant second.
        let alpha = L::max(L::mul(p.roughness, p.roughness), L::splat(GGX_MIN_ALPHA));
        let a2 = L::mul(alpha, alpha);
        let one_minus_a2 = L::sub(L::splat(1.0), a2);
        let ndv = dot3::<L>(p.normal, v);
        let gv = L::add(L::abs(ndv), L::sqrt(L::add(a2, L::mul(one_minus_a2, L::mul(ndv, ndv)))));
        GltfShader { n: p.normal, v, base: p.base_color, metallic: p.metallic, a2, one_minus_a2, gv }
    }
}

impl<L: Lanes> LightShader<L> for GltfShader<L> {
    #[inline(always)]
    fn shade(&self, l: [L::F; 3], e: [L::F; 3]) -> [L::F; 3] {
        let (n, v, a2, zero, one) = (self.n, self.v, self.a2, L::splat(0.0), L::splat(1.0));
        let ndl = dot3::<L>(n, l);
        let h = normalize_or_zero_lanes::<L>([L::add(l[0], v[0]), L::add(l[1], v[1]), L::add(l[2], v[2])]);
        // ggx_distribution(alpha, n.h, |n x h|^2)
        let nxh = [
            L::sub(L::mul(n[1], h[2]), L::mul(h[1], n[2])),
            L::sub(L::mul(n[2], h[0]), L::mul(h[2], n[0])),
            L::sub(L::mul(n[0], h[1]), L::mul(h[0], n[1])),
        ];
        let ndh = dot3::<L>(n, h);
        let k = L::add(dot3::<L>(nxh, nxh), L::mul(L::mul(ndh, ndh), a2));
        let d = L::div(a2, L::mul(L::splat(std::f32::consts::PI), L::mul(k, k)));
        let d = L::select(L::le(ndh, zero), zero, d);
        // smith_visibility(alpha, n.l, n.v, h.l, h.v)
        let (hdl, hdv) = (dot3::<L>(h, l), dot3::<L>(h, v));
        let gl = L::add(L::abs(ndl), L::sqrt(L::add(a2, L::mul(self.one_minus_a2, L::mul(ndl, ndl)))));
        let vis = L::div(one, L::mul(gl, self.gv));
        let vis = L::select(L::or(L::le(hdl, zero), L::le(hdv, zero)), zero, vis);
        let specular = L::mul(d, vis);
        // schlick_weight(v.h): `v.h` is `h.v` bit for bit (the same products, summed in
        // the same order).
        let x = L::sub(one, L::abs(hdv));
        let x2 = L::mul(x, x);
        let w = L::mul(L::mul(x2, x2), x);
        let f_d = L::add(L::splat(DIELECTRIC_F0), L::mul(L::splat(1.0 - DIELECTRIC_F0), w));
        let (spec_f, one_minus_f, one_minus_m) = (L::mul(specular, f_d), L::sub(one, f_d), L::sub(one, self.metallic));
        // `base * (FRAC_1_PI * 1.0)`: the diffuse scale of `shade_gltf`.
        let pi = L::splat(std::f32::consts::FRAC_1_PI);
        let mut c = [zero; 3];
        for (ch, c) in c.iter_mut().enumerate() {
            let b = self.base[ch];
            let dielectric = L::add(L::mul(L::mul(b, pi), one_minus_f), spec_f);
            let metal = L::mul(L::add(b, L::mul(L::sub(one, b), w)), specular);
            let brdf = L::add(L::mul(dielectric, one_minus_m), L::mul(metal, self.metallic));
            *c = L::mul(L::mul(brdf, e[ch]), ndl);
        }
        // `ndl <= 0` returns zero; a NaN `ndl` goes on, as in the scalar kernel.
        select3::<L>(L::le(ndl, zero), zero3::<L>(), c)
    }
}

/// [`sum_visible_lights_lanes`] of a block with glTF-shaded lanes ([`PrimaryLanes::gltf`]
/// not empty), seen along `-v`: the [`GltfShader`] on those lanes and the paper model's
/// `paper` shader on the others, which runs only where the block mixes both models.
#[inline(always)]
pub(crate) fn sum_visible_lights_gltf_lanes<L: Lanes, S: LightShader<L>>(
    p: &PrimaryLanes<L>,
    lit: &LitLanes,
    lights: &[LightRecord],
    v: [L::F; 3],
    paper: &S,
) -> [L::F; 3] {
    let g = sum_visible_lights_lanes::<L, _>(lit, lights, p.position, &GltfShader::of(p, v));
    match L::bits(L::andnot(p.gltf, p.hit)) {
        0 => g,
        _ => select3::<L>(p.gltf, g, sum_visible_lights_lanes::<L, _>(lit, lights, p.position, paper)),
    }
}

/// Core's `shade_raster_pixel` per lane, seen from `eye`: `unlit +
/// sum_visible_lights(shade_raster)`, the glTF shader on the lanes of objects shaded with it.
#[inline(always)]
fn shade_raster_pixel_lanes<L: Lanes>(
    p: &PrimaryLanes<L>,
    lit: &LitLanes,
    lights: &[LightRecord],
    ambient: &AmbientLight,
    eye: [f32; 3],
    shaded: L::F,
) -> [L::F; 3] {
    let pi = L::splat(std::f32::consts::FRAC_1_PI);
    let b = p.base_color;
    let shader =
        RasterShader::<L> { n: p.normal, base_over_pi: [L::mul(b[0], pi), L::mul(b[1], pi), L::mul(b[2], pi)] };
    let a = unlit_lanes::<L>(p, ambient, eye, shaded);
    let c = if L::bits(p.gltf) == 0 {
        sum_visible_lights_lanes::<L, _>(lit, lights, p.position, &shader)
    } else {
        let v = normalize_or_zero_lanes::<L>(sub3::<L>(splat3::<L>(eye), p.position));
        sum_visible_lights_gltf_lanes::<L, _>(p, lit, lights, v, &shader)
    };
    [L::add(a[0], c[0]), L::add(a[1], c[1]), L::add(a[2], c[2])]
}

/// The stage's kernel ([`raster_shading_pixel`](crate::raster_shading::raster_shading_pixel))
/// per lane, as RGBA lanes: the background on a miss, transparent black on a ray-traced
/// object unless `shade_ray_traced`, else the raster shader with alpha 1. The shader runs
/// only where some lane needs it.
#[inline(always)]
pub(crate) fn raster_shading_lanes<L: Lanes>(
    p: &PrimaryLanes<L>,
    lit: &LitLanes,
    lights: &[LightRecord],
    ambient: &AmbientLight,
    eye: [f32; 3],
    shade_ray_traced: bool,
) -> [L::F; 4] {
    let shaded = if shade_ray_traced { p.hit } else { L::andnot(p.ray_traced, p.hit) };
    let c = if L::bits(shaded) != 0 {
        shade_raster_pixel_lanes::<L>(p, lit, lights, ambient, eye, shaded)
    } else {
        zero3::<L>()
    };
    let [r, g, b, a] = BACKGROUND_RGBA;
    let none = select3::<L>(p.hit, zero3::<L>(), splat3::<L>([r, g, b]));
    let c = select3::<L>(shaded, c, none);
    let alpha = L::select(shaded, L::splat(1.0), L::select(p.hit, L::splat(0.0), L::splat(a)));
    [c[0], c[1], c[2], alpha]
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::compaction::lanes::tests::{light_with, vec3};
    use crate::lanes::tests::{at_every_level, same_bits, LevelCheck};
    use crate::raster_shading::{raster_shading_pixel, Primary};
    use glam::Vec3;
    use hyrt_core::formats::{LIGHT_DIRECTIONAL, SHADOW_LIT, SHADOW_NO_RAY, SHADOW_OCCLUDED};
    use hyrt_core::kernels::shading::ImageBasedLight;
    use hyrt_core::kernels::texture::Materials;
    use proptest::prelude::*;

    /// A block of eight pixels to shade: surfaces, the objects they name, lights, each
    /// pixel's shadow codes (`pixel * lights + light`) and the eye.
    #[derive(Clone, Debug)]
    pub(crate) struct Block {
        pub surfaces: [SurfaceRecord; LANES],
        pub objects: Vec<ObjectRecord>,
        pub lights: Vec<LightRecord>,
        pub shadow: Vec<u8>,
        pub eye: [f32; 3],
        pub ambient: AmbientLight,
    }

    /// The default sky's image-based light (computed once per process).
    pub(crate) fn sky_light() -> std::sync::Arc<ImageBasedLight> {
        ImageBasedLight::shared(&hyrt_core::scene::Environment::Sky)
    }

    /// An ambient light: the default, a constant level, or a level with the sky's
    /// image-based light.
    fn ambient_light() -> impl Strategy<Value = AmbientLight> {
        let scale = prop_oneof![2 => Just(1.0f32), 1 => Just(0.0f32), 1 => 0.0f32..4.0];
        (scale, any::<bool>()).prop_map(|(scale, image)| AmbientLight {
            scale,
            image: image.then(sky_light),
            ..AmbientLight::default()
        })
    }

    impl Block {
        /// Pixel `k`'s shadow codes.
        pub fn codes(&self, k: usize) -> &[u8] {
            let nl = self.lights.len();
            &self.shadow[k * nl..(k + 1) * nl]
        }

        /// Per light, the lanes whose code is `SHADOW_LIT` (as the fused tile gathers them).
        pub fn lit(&self) -> Vec<u32> {
            let nl = self.lights.len();
            let mut lit = vec![0u32; nl];
            for k in 0..LANES {
                for (l, lit) in lit.iter_mut().enumerate() {
                    *lit |= ((self.shadow[k * nl + l] == SHADOW_LIT) as u32) << k;
                }
            }
            lit
        }

        pub fn primary<L: Lanes>(&self) -> PrimaryLanes<L> {
            PrimaryLanes::load(std::array::from_fn(|k| &self.surfaces[k]), &self.objects)
        }
    }

    /// Lane `k` of RGBA lanes.
    pub(crate) fn lane<L: Lanes>(c: [L::F; 4], k: usize) -> [f32; 4] {
        [L::store(c[0])[k], L::store(c[1])[k], L::store(c[2])[k], L::store(c[3])[k]]
    }

    /// Lane `k`'s texel is `want`, bit for bit.
    pub(crate) fn same_texel(k: usize, got: [f32; 4], want: [f32; 4]) -> Result<(), TestCaseError> {
        let same = got.iter().zip(&want).all(|(&g, &w)| same_bits(g, w));
        prop_assert!(same, "lane {}: {:?} vs {:?}", k, got, want);
        Ok(())
    }

    /// A unit normal (the usual), a zero one, or any vector.
    fn normal() -> impl Strategy<Value = [f32; 3]> {
        prop_oneof![
            6 => vec3().prop_map(|v| Vec3::from(v).normalize_or(Vec3::Y).into()),
            1 => Just([0.0f32; 3]),
            1 => vec3(),
        ]
    }

    /// A factor in [0, 1] with its ends and the smallest values.
    fn unit() -> impl Strategy<Value = f32> {
        prop_oneof![3 => 0.0f32..=1.0, 1 => Just(0.0f32), 1 => Just(1.0f32), 1 => 0.0f32..1e-3, 1 => Just(1e-30f32)]
    }

    fn colour() -> impl Strategy<Value = f32> {
        prop_oneof![4 => 0.0f32..=1.0, 1 => Just(0.0f32), 1 => 0.0f32..1e6, 1 => Just(f32::MAX)]
    }

    /// Emission: none (most objects), or any colour.
    fn emission() -> impl Strategy<Value = [f32; 3]> {
        prop_oneof![3 => Just([0.0f32; 3]), 1 => [colour(), colour(), colour()]]
    }

    fn object() -> impl Strategy<Value = ObjectRecord> {
        let occlusion = prop_oneof![2 => Just(1.0f32), 1 => unit(), 1 => 0.0f32..4.0];
        let base = (any::<bool>(), any::<bool>(), [colour(), colour(), colour()], unit(), unit());
        (base, emission(), occlusion).prop_map(
            |((ray_traced, gltf, base_color, metallic, roughness), emissive, occlusion)| ObjectRecord {
                first_triangle: 0,
                triangle_count: 1,
                flags: if ray_traced { OBJ_RAY_TRACED } else { 0 } | if gltf { OBJ_GLTF_BRDF } else { 0 },
                material_kind: 0,
                base_color,
                metallic,
                roughness,
                transmission: 0.0,
                ior: 1.5,
                offset_error: 0.0,
                emissive,
                occlusion,
            },
        )
    }

    fn light() -> impl Strategy<Value = LightRecord> {
        light_with(prop_oneof![4 => 0.0f32..100.0, 1 => Just(0.0f32), 1 => 0.0f32..1e30])
    }

    /// A block: up to three objects, one to three lights, hits and misses (the usual:
    /// every lane on one object), each (pixel, light) with any shadow code; half the time
    /// the lights are placed on the surfaces' sides the scalar kernel shades (`n.l > 0`).
    pub(crate) fn block() -> impl Strategy<Value = Block> {
        let code = prop_oneof![Just(SHADOW_NO_RAY), Just(SHADOW_LIT), Just(SHADOW_LIT), Just(SHADOW_OCCLUDED)];
        let surface = (prop_oneof![1 => Just(false), 6 => Just(true)], vec3(), normal(), 0u32..3);
        (
            prop::collection::vec(object(), 3),
            prop::collection::vec(light(), 1..4),
            prop::collection::vec(surface, LANES),
            prop::collection::vec(code, 3 * LANES),
            (any::<bool>(), any::<bool>(), vec3(), ambient_light()),
        )
            .prop_map(|(objects, mut lights, surfaces, codes, (one_object, above, eye, ambient))| {
                let surfaces: [SurfaceRecord; LANES] = std::array::from_fn(|k| {
                    let (hit, position, normal, object) = surfaces[k];
                    if !hit {
                        return SurfaceRecord::MISS;
                    }
                    let object = if one_object { surfaces[0].3 } else { object };
                    let geometric_normal = normal;
                    SurfaceRecord { position, position_error: 1e-5, normal, object, geometric_normal, triangle: 0 }
                });
                if above {
                    // Lights over the first hit, along its normal: most lanes lit from the front.
                    if let Some(s) = surfaces.iter().find(|s| s.is_hit()) {
                        let (p, n) = (Vec3::from(s.position), Vec3::from(s.normal));
                        for (i, light) in lights.iter_mut().enumerate() {
                            light.position_or_direction = match light.kind {
                                LIGHT_DIRECTIONAL => (-n).normalize_or(Vec3::Y).into(),
                                _ => (p + n * (1.0 + i as f32)).into(),
                            };
                        }
                    }
                }
                let shadow = codes[..LANES * lights.len()].to_vec();
                Block { surfaces, objects, lights, shadow, eye, ambient }
            })
    }

    struct RasterCheck<'a>(&'a Block, bool);

    impl LevelCheck for RasterCheck<'_> {
        fn check<L: Lanes>(&self) -> Result<(), TestCaseError> {
            let RasterCheck(b, shade_ray_traced) = *self;
            let got =
                raster_shading_lanes::<L>(&b.primary::<L>(), &b.lit(), &b.lights, &b.ambient, b.eye, shade_ray_traced);
            let materials = Materials::plain(&b.objects);
            let primary = Primary {
                gbuffer: &[],
                materials: &materials,
                ambient: &b.ambient,
                eye: b.eye.into(),
                visibility: Default::default(),
            };
            for (k, s) in b.surfaces.iter().enumerate() {
                let want = raster_shading_pixel(&primary, &b.lights, shade_ray_traced, k, s, b.codes(k));
                same_texel(k, lane::<L>(got, k), want)?;
            }
            Ok(())
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2048))]

        #[test]
        fn raster_shading_lanes_are_the_scalar_kernel(b in block(), shade_ray_traced in any::<bool>()) {
            at_every_level(&RasterCheck(&b, shade_ray_traced))?;
        }
    }

    /// A light exactly behind, one at grazing incidence and one on the surface, with every
    /// shadow code, over a block of hits and misses.
    #[test]
    fn raster_shading_lanes_on_hard_cases() {
        for b in [hard_block(), gltf(hard_block()), with_sky(gltf(hard_block())), with_sky(hard_block())] {
            for shade_ray_traced in [false, true] {
                at_every_level(&RasterCheck(&b, shade_ray_traced)).unwrap();
            }
        }
    }

    /// `b` under the default sky's image-based light, at half the default constant level.
    pub(crate) fn with_sky(b: Block) -> Block {
        Block { ambient: AmbientLight { scale: 0.5, image: Some(sky_light()), ..AmbientLight::default() }, ..b }
    }

    /// `b` with every object shaded with the glTF BRDF.
    pub(crate) fn gltf(mut b: Block) -> Block {
        b.objects.iter_mut().for_each(|o| o.flags |= OBJ_GLTF_BRDF);
        b
    }

    /// Lights behind, grazing and on the surface; metallic and roughness 0 and 1; a miss;
    /// every shadow code.
    pub(crate) fn hard_block() -> Block {
        let object = |flags: u32, metallic: f32, roughness: f32| ObjectRecord {
            first_triangle: 0,
            triangle_count: 1,
            flags,
            material_kind: 0,
            base_color: [1.0, 0.766, 0.336],
            metallic,
            roughness,
            transmission: 0.0,
            ior: 1.5,
            offset_error: 0.0,
            emissive: [0.0; 3],
            occlusion: 1.0,
        };
        let objects = vec![
            object(0, 0.0, 1.0),
            object(OBJ_RAY_TRACED, 1.0, 0.0),
            // Emissive and occluded.
            ObjectRecord { emissive: [2.0, 0.5, 0.0], occlusion: 0.25, ..object(OBJ_RAY_TRACED, 0.0, 1.0) },
        ];
        let s = |position: [f32; 3], normal: [f32; 3], object: u32| SurfaceRecord {
            position,
            position_error: 0.0,
            normal,
            object,
            geometric_normal: normal,
            triangle: 0,
        };
        let surfaces = [
            s([0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 0),
            s([0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 1),
            s([1.0, 2.0, 3.0], [0.0, 1.0, 0.0], 2),
            SurfaceRecord::MISS,
            s([0.0, -0.0, 1.0], [1.0, 0.0, 0.0], 1),
            s([-1.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1),
            s([1e30, -1e30, 0.0], [0.0, -1.0, 0.0], 0),
            s([0.0, 5.0, 0.0], [0.6, 0.8, 0.0], 1),
        ];
        let point = |p: [f32; 3]| LightRecord::point(p, [8.0; 3]);
        let lights = vec![
            point([0.0, -1.0, 0.0]),
            point([5.0, 0.0, 0.0]),
            point([1.0, 2.0, 3.0]),
            LightRecord::directional([0.0, -1.0, 0.0], [1.0; 3]),
        ];
        let codes = [SHADOW_LIT, SHADOW_LIT, SHADOW_OCCLUDED, SHADOW_NO_RAY];
        let shadow = (0..LANES * lights.len()).map(|i| codes[(i + i / 4) % 4]).collect();
        Block { surfaces, objects, lights, shadow, eye: [0.0, 1.0, 2.0], ambient: AmbientLight::default() }
    }
}
