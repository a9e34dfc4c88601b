//! Soft shadows from area lights and ambient occlusion in the shadow stages (issue 38):
//! how `compaction` makes the stochastic shadow rays, how `shadow_rays` records them, and
//! how the shading stages read them back.
//!
//! # Slots
//!
//! Per surface (a pixel's primary hit, or a secondary hit of a bounce list) the shadow
//! mask holds one `SHADOW_*` code per *slot*: one slot for each point, spot or directional
//! light, [`LightRecord::samples`] for each area light (quad, sphere, sun, emitters), in light order,
//! then [`AmbientOcclusion::samples`] for the ambient occlusion ([`surface_slots`]). A scene
//! of point lights without occlusion has one slot per light: the paper's mask, bit for bit.
//! `compaction` makes the ray of slot `k` of surface `i` ([`needs_slot_ray`],
//! [`slot_ray`]; the ray's `light` field holds the slot), `shadow_rays` writes its code,
//! and the shaders regenerate each sample from the same inputs ([`area_light_sample`],
//! [`ambient_occlusion`]) instead of storing it.
//!
//! # Sample streams
//!
//! Sample `s` of an area light at surface point `p` is point `s` of the stream
//! `stream_seed(surface_key(p), light.seed)` of [`crate::kernels::sampling::sample_2d`]:
//! keyed by the surface point's bits ([`surface_key`]: every pixel sees its own point, so
//! pixels get independent streams, and a secondary hit is keyed like a primary one), by the
//! light and by the frame ([`light_seed`], set on the frame's light records by
//! [`frame_lights`]). The same bits on every backend and thread count: everything is
//! integer arithmetic and the correctly rounded warps of [`crate::kernels::area_light`].
//!
//! # The estimator
//!
//! An area light of `N` samples adds `(1 / N) sum_s shade(l_s, weight_s)` over its samples
//! whose ray reached it ([`crate::kernels::shading::sum_visible_lights`]); samples facing
//! away from the surface trace no ray and add nothing. The ambient occlusion is the
//! fraction of its `N` rays that met nothing within [`AmbientOcclusion::radius`]
//! ([`crate::kernels::occlusion::ao_fraction`]); it multiplies the surface's occlusion
//! ([`ObjectRecord::occlusion`], which scales the ambient and image-based terms).
//!
//! # Emissive meshes
//!
//! With `emissive_lights = true` (manifest), every triangle of an emissive object becomes
//! part of one area light, [`LIGHT_EMITTERS`], whose triangles are the frame's emitter
//! table ([`EmitterRecord`], [`crate::geometry::emitter_table`]): each sample picks a
//! triangle in proportion to its power and a point on it
//! ([`crate::kernels::area_light::sample_emitters`]). The kernels that make or read its
//! samples take the light records with that table, [`Lights`]. Its shadow rays end short
//! of the sampled point as every area light's do ([`SHADOW_T_MAX_POINT`] of the way), so
//! the emitting triangle does not shadow its own light.

use glam::Vec3;

use crate::formats::{
    EmitterRecord, LightRecord, ObjectRecord, RayRecord, SurfaceRecord, LIGHT_EMITTERS, LIGHT_QUAD, LIGHT_SPHERE,
    LIGHT_SUN, SHADOW_LIT,
};
use crate::kernels::area_light::{sample_emitters, sample_quad_light, sample_sphere_light, sample_sun, LightSample};
use crate::kernels::occlusion::{ao_direction, ao_fraction, AO_STREAM};
use crate::kernels::ray::offset_ray_origin;
use crate::kernels::sampling::{hash_combine, hash_u32, sample_2d};
use crate::kernels::shading::light_can_contribute;
use crate::kernels::shadow::{shadow_ray, shadow_ray_record, SHADOW_T_MAX_POINT};

/// Most samples per area light or for the ambient occlusion (`--shadow-samples`,
/// `--ao-samples`): the sequence's points are distinct 24-bit fractions up to 2^24; the
/// limit keeps a mask of one byte per sample within reach at common sizes (a 320 x 180
/// frame at 4,096 samples is 236 MB per light).
pub const MAX_SAMPLES: u32 = 4096;

/// The ambient occlusion a frame traces: `samples` rays per surface (0: none) of length
/// `radius`, from the stream of `seed` ([`light_seed`] of
/// [`crate::kernels::occlusion::AO_STREAM`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AmbientOcclusion {
    pub samples: u32,
    pub radius: f32,
    pub seed: u32,
}

/// A frame's lights as the kernels that sample them read them: the light records and the
/// emitter table a [`LIGHT_EMITTERS`] record samples (empty without one). Dereferences to
/// the records, so code that only counts slots reads it as a slice; made from a slice of
/// records alone for frames without emitters.
#[derive(Clone, Copy, Debug, Default)]
pub struct Lights<'a> {
    pub records: &'a [LightRecord],
    pub emitters: &'a [EmitterRecord],
}

impl<'a> Lights<'a> {
    /// The records `records` with the emitter table `emitters`.
    #[inline]
    pub fn new(records: &'a [LightRecord], emitters: &'a [EmitterRecord]) -> Lights<'a> {
        Lights { records, emitters }
    }
}

impl std::ops::Deref for Lights<'_> {
    type Target = [LightRecord];
    #[inline]
    fn deref(&self) -> &[LightRecord] {
        self.records
    }
}

impl<'a> From<&'a [LightRecord]> for Lights<'a> {
    /// The records without emitters.
    #[inline]
    fn from(records: &'a [LightRecord]) -> Self {
        Lights { records, emitters: &[] }
    }
}

impl<'a, const N: usize> From<&'a [LightRecord; N]> for Lights<'a> {
    /// The records without emitters.
    #[inline]
    fn from(records: &'a [LightRecord; N]) -> Self {
        Lights { records, emitters: &[] }
    }
}

impl<'a> From<&'a Vec<LightRecord>> for Lights<'a> {
    /// The records without emitters.
    #[inline]
    fn from(records: &'a Vec<LightRecord>) -> Self {
        Lights { records, emitters: &[] }
    }
}

impl<'a> From<&'a std::borrow::Cow<'_, [LightRecord]>> for Lights<'a> {
    /// The records without emitters.
    #[inline]
    fn from(records: &'a std::borrow::Cow<'_, [LightRecord]>) -> Self {
        Lights { records, emitters: &[] }
    }
}

impl<'a> From<&Lights<'a>> for Lights<'a> {
    #[inline]
    fn from(lights: &Lights<'a>) -> Self {
        *lights
    }
}

/// The seed of stream `stream` (a light's index, or [`AO_STREAM`]) in frame `frame`.
#[inline]
pub fn light_seed(stream: u32, frame: u32) -> u32 {
    hash_combine(hash_u32(stream), frame)
}

/// The key of a surface point's sample streams: its coordinates' bits, hashed.
#[inline]
pub fn surface_key(p: Vec3) -> u32 {
    hash_combine(hash_combine(hash_u32(p.x.to_bits()), p.y.to_bits()), p.z.to_bits())
}

/// The seed of the stream of `key` ([`surface_key`]) for the stream seed `seed`
/// ([`LightRecord::seed`], [`AmbientOcclusion::seed`]).
#[inline]
pub fn stream_seed(key: u32, seed: u32) -> u32 {
    hash_combine(hash_u32(key), seed)
}

/// The frame's light records: `lights` with every area light given `samples` shadow rays
/// per surface and the seed of its index in frame `frame`; other lights as they are.
pub fn frame_lights(lights: &[LightRecord], samples: u32, frame: u32) -> Vec<LightRecord> {
    lights
        .iter()
        .enumerate()
        .map(|(i, l)| match l.is_area() {
            true => LightRecord { samples: samples.max(1), seed: light_seed(i as u32, frame), ..*l },
            false => *l,
        })
        .collect()
}

/// The frame's ambient occlusion: `samples` rays of length `radius` in frame `frame`.
pub fn frame_occlusion(samples: u32, radius: f32, frame: u32) -> AmbientOcclusion {
    AmbientOcclusion { samples, radius, seed: light_seed(AO_STREAM, frame) }
}

/// The visibility of an area light at a surface none of whose samples traced a ray
/// ([`light_visibility`]): no estimate. The denoiser gives such values no weight and fills
/// them from their neighbours where it can.
pub const NO_ESTIMATE: f32 = -1.0;

/// The slots a light takes in a surface's mask: its samples for an area light, else 1.
#[inline]
pub fn light_slots(light: &LightRecord) -> usize {
    if light.is_area() {
        light.samples as usize
    } else {
        1
    }
}

/// The slots of `lights` in a surface's mask (the ambient occlusion's come after them).
#[inline]
pub fn lights_slots(lights: &[LightRecord]) -> usize {
    lights.iter().map(light_slots).sum()
}

/// The slots of a surface's mask: the lights', then the ambient occlusion's.
#[inline]
pub fn surface_slots(lights: &[LightRecord], ao: &AmbientOcclusion) -> usize {
    lights_slots(lights) + ao.samples as usize
}

/// Whether a frame with `lights` and `ao` traces stochastic rays (an area light, or
/// ambient occlusion).
pub fn is_stochastic(lights: &[LightRecord], ao: &AmbientOcclusion) -> bool {
    ao.samples > 0 || lights.iter().any(LightRecord::is_area)
}

/// What a mask slot stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slot {
    /// Sample `sample` of light `light` (0 for a light that is not an area light).
    Light { light: u32, sample: u32 },
    /// Ambient-occlusion ray `sample`.
    Occlusion { sample: u32 },
}

/// Every slot of a surface's mask, in order ([`surface_slots`] of them).
pub fn slot_table(lights: &[LightRecord], ao: &AmbientOcclusion) -> Vec<Slot> {
    let mut slots = Vec::with_capacity(surface_slots(lights, ao));
    for (l, light) in lights.iter().enumerate() {
        slots.extend((0..light_slots(light) as u32).map(|sample| Slot::Light { light: l as u32, sample }));
    }
    slots.extend((0..ao.samples).map(|sample| Slot::Occlusion { sample }));
    slots
}

/// Sample `sample` of area light `light` seen from the surface point `p` (the module docs'
/// stream); `None` where the sampled point does not face `p` (or `p` is inside a sphere).
/// `emitters` is the frame's emitter table, which a [`LIGHT_EMITTERS`] light samples
/// ([`Lights::emitters`]). Call only on area lights.
#[inline]
pub fn area_light_sample(light: &LightRecord, emitters: &[EmitterRecord], p: Vec3, sample: u32) -> Option<LightSample> {
    let u = sample_2d(sample, stream_seed(surface_key(p), light.seed));
    let radiance = Vec3::from(light.radiance);
    let at = Vec3::from(light.position_or_direction);
    match light.kind {
        LIGHT_QUAD => sample_quad_light(at, Vec3::from(light.edge_u), Vec3::from(light.edge_v), radiance, p, u),
        LIGHT_SPHERE => sample_sphere_light(at, light.size, radiance, p, u),
        LIGHT_SUN => Some(sample_sun(at, light.size, radiance, u)),
        LIGHT_EMITTERS => sample_emitters(emitters, p, u),
        _ => None,
    }
}

/// The direction of ambient-occlusion ray `sample` at surface `s` (`None`: it would leave
/// below the geometric surface and counts as occluded).
#[inline]
pub fn occlusion_direction(s: &SurfaceRecord, ao: &AmbientOcclusion, sample: u32) -> Option<Vec3> {
    let p = Vec3::from(s.position);
    let u = sample_2d(sample, stream_seed(surface_key(p), ao.seed));
    ao_direction(Vec3::from(s.normal), Vec3::from(s.geometric_normal), u)
}

/// Whether slot `slot` of surface `s` traces a ray: a primary hit, and for a light sample
/// one that can contribute (as [`crate::kernels::shadow::needs_shadow_ray`] for the other
/// lights), for an occlusion ray one above the geometric surface.
#[inline]
pub fn needs_slot_ray<'l>(s: &SurfaceRecord, lights: impl Into<Lights<'l>>, ao: &AmbientOcclusion, slot: Slot) -> bool {
    if !s.is_hit() {
        return false;
    }
    let lights = lights.into();
    match slot {
        Slot::Light { light, sample } => {
            let light = &lights[light as usize];
            if !light.is_area() {
                return crate::kernels::shadow::needs_shadow_ray(s, light);
            }
            match area_light_sample(light, lights.emitters, Vec3::from(s.position), sample) {
                Some(ls) => light_can_contribute(Vec3::from(s.geometric_normal), Vec3::from(s.normal), ls.l, ls.weight),
                None => false,
            }
        }
        Slot::Occlusion { sample } => occlusion_direction(s, ao, sample).is_some(),
    }
}

/// The ray of slot `slot_index` (standing for `slot`) of surface `s`, the surface `index`
/// of its list (the ray's `pixel`); its `light` field is the slot. Call only where
/// [`needs_slot_ray`] holds. A point, spot or directional light's is
/// [`crate::kernels::shadow::shadow_ray`]'s; an area light's leaves from the same offset
/// origin towards the sampled point (ending as a point light's ray, at
/// [`SHADOW_T_MAX_POINT`] of the way) or along the sun's sampled direction; an occlusion
/// ray's goes [`AmbientOcclusion::radius`] along its direction.
#[inline]
pub fn slot_ray<'l>(
    s: &SurfaceRecord,
    lights: impl Into<Lights<'l>>,
    ao: &AmbientOcclusion,
    slot: Slot,
    slot_index: u32,
    index: u32,
) -> RayRecord {
    let lights = lights.into();
    let p = Vec3::from(s.position);
    let origin = || offset_ray_origin(p, s.position_error, Vec3::from(s.geometric_normal));
    match slot {
        Slot::Light { light, sample } => {
            let light = &lights[light as usize];
            if !light.is_area() {
                return shadow_ray(s, light, slot_index, index);
            }
            // Callers checked `needs_slot_ray`: the sample exists.
            let Some(ls) = area_light_sample(light, lights.emitters, p, sample) else {
                return shadow_ray_record(origin().into(), [0.0; 3], 0.0, slot_index, index);
            };
            let origin = origin();
            let (direction, t_max) = match light.kind {
                LIGHT_SUN => (ls.l, f32::INFINITY),
                _ => ((p + ls.l * ls.distance) - origin, SHADOW_T_MAX_POINT),
            };
            shadow_ray_record(origin.into(), direction.into(), t_max, slot_index, index)
        }
        Slot::Occlusion { sample } => {
            let direction = occlusion_direction(s, ao, sample).unwrap_or(Vec3::ZERO);
            shadow_ray_record(origin().into(), direction.into(), ao.radius, slot_index, index)
        }
    }
}

/// The ambient occlusion of a surface from its mask `codes` (all its slots): the
/// fraction of its occlusion rays that met nothing; `None` without occlusion rays.
#[inline]
pub fn ambient_occlusion(codes: &[u8], lights: &[LightRecord], ao: &AmbientOcclusion) -> Option<f32> {
    if ao.samples == 0 {
        return None;
    }
    let first = lights_slots(lights);
    let codes = &codes[first..first + ao.samples as usize];
    let lit = codes.iter().filter(|&&c| c == SHADOW_LIT).count() as u32;
    Some(ao_fraction(lit, ao.samples))
}

/// What the shaders know of a surface's shadow rays: its mask `codes` (every slot) and,
/// in a frame that denoised them (`shadow_denoise`), its `filtered` channels
/// ([`crate::kernels::denoise::channel_count`]: each area light's visibility, then the
/// ambient occlusion); an empty `filtered` shades from the codes alone.
#[derive(Clone, Copy, Debug, Default)]
pub struct SurfaceShadow<'a> {
    pub codes: &'a [u8],
    pub filtered: &'a [f32],
}

impl<'a> From<&'a [u8]> for SurfaceShadow<'a> {
    /// The codes alone (no denoised channels).
    #[inline]
    fn from(codes: &'a [u8]) -> Self {
        SurfaceShadow { codes, filtered: &[] }
    }
}

impl<'a, const N: usize> From<&'a [u8; N]> for SurfaceShadow<'a> {
    /// The codes alone (no denoised channels).
    #[inline]
    fn from(codes: &'a [u8; N]) -> Self {
        SurfaceShadow { codes, filtered: &[] }
    }
}

impl<'a> From<&'a Vec<u8>> for SurfaceShadow<'a> {
    /// The codes alone (no denoised channels).
    #[inline]
    fn from(codes: &'a Vec<u8>) -> Self {
        SurfaceShadow { codes, filtered: &[] }
    }
}

/// A frame's denoised channels (`shadow_denoise`'s output), `channels` per pixel; empty
/// where the frame did not denoise.
#[derive(Clone, Copy, Debug, Default)]
pub struct FilteredVisibility<'a> {
    pub values: &'a [f32],
    pub channels: usize,
}

impl<'a> FilteredVisibility<'a> {
    /// Pixel `i`'s channels (empty without denoising).
    #[inline]
    pub fn at(&self, i: usize) -> &'a [f32] {
        match self.values.is_empty() {
            true => &[],
            false => &self.values[i * self.channels..(i + 1) * self.channels],
        }
    }

    /// Pixel `i`'s [`SurfaceShadow`] with its mask `codes`.
    #[inline]
    pub fn surface(&self, i: usize, codes: &'a [u8]) -> SurfaceShadow<'a> {
        SurfaceShadow { codes, filtered: self.at(i) }
    }
}

/// The ambient occlusion the shaders apply: the denoised channel where the frame has one,
/// else [`ambient_occlusion`] of the codes; `None` without occlusion rays.
#[inline]
pub fn surface_ambient_occlusion(shadow: SurfaceShadow, lights: &[LightRecord], ao: &AmbientOcclusion) -> Option<f32> {
    match (ao.samples, shadow.filtered.last()) {
        (0, _) => None,
        (_, Some(&f)) => Some(f),
        (_, None) => ambient_occlusion(shadow.codes, lights, ao),
    }
}

/// `obj` with its occlusion times the surface's ambient occlusion
/// ([`surface_ambient_occlusion`]); `None` without occlusion rays (the shaders keep `obj`
/// and its bits).
#[inline]
pub fn occluded_object(
    obj: &ObjectRecord,
    shadow: SurfaceShadow,
    lights: &[LightRecord],
    ao: &AmbientOcclusion,
) -> Option<ObjectRecord> {
    surface_ambient_occlusion(shadow, lights, ao).map(|f| ObjectRecord { occlusion: obj.occlusion * f, ..*obj })
}

/// A frame's mask slots: its lights (with their emitter table), its ambient occlusion and
/// every slot's meaning ([`slot_table`]), what `compaction` flags and makes rays of.
#[derive(Clone, Debug)]
pub struct Slots<'a> {
    pub lights: Lights<'a>,
    pub ao: AmbientOcclusion,
    pub table: Vec<Slot>,
}

impl<'a> Slots<'a> {
    /// The slots of `lights` and `ao`.
    pub fn new(lights: impl Into<Lights<'a>>, ao: &AmbientOcclusion) -> Slots<'a> {
        let lights = lights.into();
        Slots { lights, ao: *ao, table: slot_table(&lights, ao) }
    }

    /// Slots per surface.
    #[inline]
    pub fn len(&self) -> usize {
        self.table.len()
    }

    /// Whether there is none (no light, no occlusion).
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.table.is_empty()
    }

    /// [`needs_slot_ray`] of slot `slot` at surface `s`.
    #[inline]
    pub fn needs_ray(&self, s: &SurfaceRecord, slot: usize) -> bool {
        needs_slot_ray(s, self.lights, &self.ao, self.table[slot])
    }

    /// [`slot_ray`] of slot `slot` at surface `s`, the surface `index` of its list.
    #[inline]
    pub fn ray(&self, s: &SurfaceRecord, slot: usize, index: u32) -> RayRecord {
        slot_ray(s, self.lights, &self.ao, self.table[slot], slot as u32, index)
    }
}

/// The fraction of each light a surface sees, from its mask `codes` (all its slots), into
/// `out` (one per light): for a point, spot or directional light 1 where its ray reached
/// it, else 0; for an area light the visible share of its unoccluded irradiance,
/// `sum_lit c_s / sum c_s` over the samples that traced a ray, `c_s = max(weight_s) max(n .
/// l_s, 0)` (the sample's irradiance up to the light's colour), [`NO_ESTIMATE`] where no
/// sample traced one (every sampled point lies behind the surface: the samples say nothing
/// of the light's visible part); in f32, summed in sample order. What `visibility_raw.npy` holds and the
/// denoiser filters ([`crate::kernels::denoise`]). An emitter light's samples need the
/// emitter table ([`Lights`]; records alone give it [`NO_ESTIMATE`]).
pub fn light_visibility<'l>(codes: &[u8], lights: impl Into<Lights<'l>>, s: &SurfaceRecord, out: &mut [f32]) {
    let lights = lights.into();
    let (p, n) = (Vec3::from(s.position), Vec3::from(s.normal));
    let mut slot = 0;
    for (light, v) in lights.iter().zip(out.iter_mut()) {
        let k = light_slots(light);
        *v = if light.is_area() {
            let (mut lit, mut all) = (0.0f32, 0.0f32);
            for (sample, &code) in codes[slot..slot + k].iter().enumerate() {
                if code == crate::formats::SHADOW_NO_RAY {
                    continue;
                }
                if let Some(ls) = area_light_sample(light, lights.emitters, p, sample as u32) {
                    let c = ls.weight.max_element() * n.dot(ls.l).max(0.0);
                    all += c;
                    if code == SHADOW_LIT {
                        lit += c;
                    }
                }
            }
            if all > 0.0 {
                lit / all
            } else {
                NO_ESTIMATE
            }
        } else {
            (codes[slot] == SHADOW_LIT) as u8 as f32
        };
        slot += k;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::{SHADOW_NO_RAY, SHADOW_OCCLUDED};
    use crate::kernels::shading::{light_incidence, sum_visible_lights};
    use crate::scene::Light;

    fn quad() -> LightRecord {
        LightRecord::from_light(&Light::Quad {
            corner: Vec3::new(-0.5, 2.0, -0.5),
            edge_u: Vec3::X,
            edge_v: Vec3::Z,
            color: Vec3::ONE,
            intensity: 3.0,
        })
    }

    fn point() -> LightRecord {
        LightRecord::point([0.0, 4.0, 1.0], [5.0; 3])
    }

    fn floor(p: Vec3) -> SurfaceRecord {
        SurfaceRecord {
            position: p.into(),
            normal: [0.0, 1.0, 0.0],
            geometric_normal: [0.0, 1.0, 0.0],
            position_error: 1e-6,
            object: 0,
            ..bytemuck::Zeroable::zeroed()
        }
    }

    #[test]
    fn slots_are_one_per_point_light_and_the_samples_of_area_lights_then_occlusion() {
        let lights = frame_lights(&[point(), quad(), point()], 3, 7);
        assert_eq!((lights[0], lights[2]), (point(), point()), "point lights keep their records");
        assert_eq!((lights[1].samples, lights[1].seed), (3, light_seed(1, 7)));
        let ao = frame_occlusion(2, 0.5, 7);
        let table = slot_table(&lights, &ao);
        use Slot::*;
        assert_eq!(
            table,
            [
                Light { light: 0, sample: 0 },
                Light { light: 1, sample: 0 },
                Light { light: 1, sample: 1 },
                Light { light: 1, sample: 2 },
                Light { light: 2, sample: 0 },
                Occlusion { sample: 0 },
                Occlusion { sample: 1 },
            ]
        );
        assert_eq!(surface_slots(&lights, &ao), table.len());
        assert!(is_stochastic(&lights, &ao));
        assert!(!is_stochastic(&[point()], &AmbientOcclusion::default()));
        for l in &lights {
            l.validate().unwrap();
        }
    }

    #[test]
    fn point_light_slots_are_the_paper_mask() {
        let lights = [point(), point()];
        let s = floor(Vec3::new(0.3, 0.0, -0.2));
        let slots = Slots::new(&lights, &AmbientOcclusion::default());
        for (k, light) in lights.iter().enumerate() {
            assert_eq!(slots.ray(&s, k, 9), crate::kernels::shadow::shadow_ray(&s, light, k as u32, 9));
            assert!(slots.needs_ray(&s, k));
        }
        // The shading sum reads one code per light, as before area lights.
        let shade = |l: Vec3, e: Vec3| e * l.y;
        let want = shade(
            light_incidence(&lights[1], Vec3::from(s.position)).0,
            light_incidence(&lights[1], Vec3::from(s.position)).1,
        );
        let got = sum_visible_lights(&[SHADOW_OCCLUDED, SHADOW_LIT], &lights, Vec3::from(s.position), shade);
        assert_eq!(got, want);
    }

    #[test]
    fn an_area_light_adds_the_mean_of_its_lit_samples() {
        let lights = frame_lights(&[quad()], 4, 0);
        let s = floor(Vec3::new(0.1, 0.0, 0.2));
        let p = Vec3::from(s.position);
        let samples: Vec<LightSample> = (0..4).map(|k| area_light_sample(&lights[0], &[], p, k).unwrap()).collect();
        let shade = |l: Vec3, e: Vec3| e * l.y;
        let codes = [SHADOW_LIT, SHADOW_OCCLUDED, SHADOW_LIT, SHADOW_NO_RAY];
        let got = sum_visible_lights(&codes, &lights, p, shade);
        let want = (shade(samples[0].l, samples[0].weight) + shade(samples[2].l, samples[2].weight)) / 4.0;
        assert_eq!(got, want);
        // Every sample's ray ends just before its point on the quad, from the offset origin.
        let slots = Slots::new(&lights, &AmbientOcclusion::default());
        for (k, ls) in samples.iter().enumerate() {
            assert!(slots.needs_ray(&s, k));
            let r = slots.ray(&s, k, 0);
            let end = Vec3::from(r.origin) + Vec3::from(r.direction) * r.t_max;
            assert!((end - (p + ls.l * ls.distance)).length() < 1e-4, "sample {k} ends at {end}");
            assert_eq!(r.light, k as u32, "the ray's light field is its slot");
        }
        // The visibility weighs the lit samples by their irradiance.
        let mut v = [0.0];
        light_visibility(&codes, &lights, &s, &mut v);
        let c = |ls: &LightSample| ls.weight.max_element() as f64 * ls.l.y as f64;
        let want = (c(&samples[0]) + c(&samples[2])) / (c(&samples[0]) + c(&samples[1]) + c(&samples[2]));
        assert!((v[0] as f64 - want).abs() < 1e-6, "{} against {want}", v[0]);
    }

    #[test]
    fn occlusion_rays_scale_the_surface_occlusion_and_nothing_without_them() {
        let lights = [point()];
        let ao = frame_occlusion(4, 0.25, 0);
        let codes = [SHADOW_LIT, SHADOW_LIT, SHADOW_OCCLUDED, SHADOW_NO_RAY, SHADOW_LIT];
        assert_eq!(ambient_occlusion(&codes, &lights, &ao), Some(0.5), "2 of 4 met nothing (no ray counts as blocked)");
        let obj = ObjectRecord { occlusion: 0.5, ..bytemuck::Zeroable::zeroed() };
        assert_eq!(occluded_object(&obj, codes[..].into(), &lights, &ao).map(|o| o.occlusion), Some(0.25));
        assert_eq!(occluded_object(&obj, codes[..1].into(), &lights, &AmbientOcclusion::default()), None);
        let filtered = SurfaceShadow { codes: &codes, filtered: &[0.75] };
        assert_eq!(
            occluded_object(&obj, filtered, &lights, &ao).map(|o| o.occlusion),
            Some(0.375),
            "the denoised channel wins"
        );
        let s = floor(Vec3::ZERO);
        let slots = Slots::new(&lights, &ao);
        for k in 1..5 {
            let r = slots.ray(&s, k, 0);
            assert_eq!(r.t_max, 0.25);
            assert!(r.direction[1] > 0.0, "occlusion rays leave above the floor");
            assert!((Vec3::from(r.direction).length() - 1.0).abs() < 1e-6);
        }
    }
}
