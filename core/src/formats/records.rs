use bytemuck::{Pod, Zeroable};

use super::wgsl::wgsl_struct;
use super::INVALID_ID;

// ---------------------------------------------------------------------------------------------
// G-buffer
// ---------------------------------------------------------------------------------------------

/// [`GBufferTexel::flags`]: a triangle covers this pixel's centre (a primary hit).
pub const GBUF_HIT: u32 = 1 << 0;
/// [`GBufferTexel::flags`]: the covering object is shaded by the ray tracer.
pub const GBUF_RAY_TRACED: u32 = 1 << 1;
/// [`GBufferTexel::flags`]: the visible face is a back face (seen from behind).
pub const GBUF_BACK_FACE: u32 = 1 << 2;

/// One pixel of the visibility G-buffer written by `visibility_raster` (paper 3.2).
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `bary_u` | f32 | barycentric weight of v1 (perspective-correct, at the pixel centre) |
/// | 4 | `bary_v` | f32 | barycentric weight of v2; the weight of v0 is `w = 1 - u - v` |
/// | 8 | `depth` | f32 | window-space depth in [0, 1] (z/w, linear in screen space) |
/// | 12 | `triangle` | u32 | triangle index within its object's mesh, [`INVALID_ID`] on miss |
/// | 16 | `object` | u32 | object id, [`INVALID_ID`] on miss |
/// | 20 | `flags` | u32 | [`GBUF_HIT`], [`GBUF_RAY_TRACED`], [`GBUF_BACK_FACE`] |
///
/// 24 bytes. A miss texel is [`GBufferTexel::MISS`]: zero barycentrics, depth 1.0,
/// invalid ids, no flags.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct GBufferTexel {
    pub bary_u: f32,
    pub bary_v: f32,
    pub depth: f32,
    pub triangle: u32,
    pub object: u32,
    pub flags: u32,
}
const _: () = assert!(std::mem::size_of::<GBufferTexel>() == 24);
wgsl_struct!(GBufferTexel { bary_u, bary_v, depth, triangle, object, flags });

impl GBufferTexel {
    /// The texel of a pixel no triangle covers.
    pub const MISS: GBufferTexel =
        GBufferTexel { bary_u: 0.0, bary_v: 0.0, depth: 1.0, triangle: INVALID_ID, object: INVALID_ID, flags: 0 };

    /// True if a triangle covers the pixel centre.
    #[inline]
    pub fn is_hit(&self) -> bool {
        self.flags & GBUF_HIT != 0
    }

    /// True if the covering object is ray traced.
    #[inline]
    pub fn is_ray_traced(&self) -> bool {
        self.flags & GBUF_RAY_TRACED != 0
    }

    /// Check the invariants: a miss is exactly [`Self::MISS`]; a hit has valid ids,
    /// finite barycentrics and a depth in [0, 1].
    pub fn validate(&self) -> Result<(), String> {
        if !self.is_hit() {
            if self.to_bits() != Self::MISS.to_bits() {
                return Err(format!("miss texel is not GBufferTexel::MISS: {self:?}"));
            }
            return Ok(());
        }
        if self.triangle == INVALID_ID || self.object == INVALID_ID {
            return Err(format!("hit texel with invalid id: {self:?}"));
        }
        if !(self.bary_u.is_finite() && self.bary_v.is_finite()) {
            return Err(format!("hit texel with non-finite barycentrics: {self:?}"));
        }
        if !(0.0..=1.0).contains(&self.depth) {
            return Err(format!("hit texel depth outside [0, 1]: {self:?}"));
        }
        if self.flags & !(GBUF_HIT | GBUF_RAY_TRACED | GBUF_BACK_FACE) != 0 {
            return Err(format!("hit texel with unknown flags: {self:?}"));
        }
        Ok(())
    }

    /// The raw bits, for exact comparisons (floats compared by bit pattern).
    pub fn to_bits(&self) -> [u32; 6] {
        bytemuck::cast(*self)
    }
}

// ---------------------------------------------------------------------------------------------
// Ray list
// ---------------------------------------------------------------------------------------------

/// [`RayRecord::kind`]: a shadow ray (any hit, early exit).
pub const RAY_KIND_SHADOW: u32 = 0;
/// [`RayRecord::kind`]: a primary ray (closest hit).
pub const RAY_KIND_PRIMARY: u32 = 1;
/// [`RayRecord::kind`]: a reflection ray (closest hit; not traced yet).
pub const RAY_KIND_REFLECTION: u32 = 2;
/// [`RayRecord::kind`]: a refraction ray (closest hit; not traced yet).
pub const RAY_KIND_REFRACTION: u32 = 3;
/// Number of ray kinds (for per-kind counters).
pub const RAY_KIND_COUNT: usize = 4;

/// One ray of the compacted ray list (paper 3.3: one thread per active ray).
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `origin` | [f32; 3] | world-space origin, already offset off the surface |
/// | 12 | `t_min` | f32 | the ray hits only for `t_min < t < t_max` (Vulkan RT rule) |
/// | 16 | `direction` | [f32; 3] | world-space direction, *not* normalized (shadow rays to a point light reach it at t = 1) |
/// | 28 | `t_max` | f32 | see `t_min`; `+inf` for directional lights |
/// | 32 | `pixel` | u32 | linear pixel index `y * width + x` this ray contributes to |
/// | 36 | `kind` | u32 | `RAY_KIND_*` |
/// | 40 | `depth` | u32 | bounce depth of reflection and refraction rays: 1 for the rays from primary hits, `d + 1` for those from the hits of depth `d`; 0 for shadow rays |
/// | 44 | `light` | u32 | light index for shadow rays, [`INVALID_ID`] otherwise |
/// | 48 | `throughput` | [f32; 3] | path weight carried by reflection/refraction rays; 1 for shadow rays |
/// | 60 | `cone` | f32 | width of the pixel's footprint cone at the origin, for texture filtering ([`crate::kernels::texture`]): the cone spread times the path's length so far; 0 for shadow rays and in frames without textures |
///
/// 64 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct RayRecord {
    pub origin: [f32; 3],
    pub t_min: f32,
    pub direction: [f32; 3],
    pub t_max: f32,
    pub pixel: u32,
    pub kind: u32,
    pub depth: u32,
    pub light: u32,
    pub throughput: [f32; 3],
    pub cone: f32,
}
const _: () = assert!(std::mem::size_of::<RayRecord>() == 64);
wgsl_struct!(RayRecord { origin, t_min, direction, t_max, pixel, kind, depth, light, throughput, cone });

impl RayRecord {
    /// A closest-hit query from `origin` along `direction` for `t_min < t < t_max`, of kind
    /// [`RAY_KIND_PRIMARY`], outside any frame: pixel 0, no light, unit throughput, no
    /// cone. What rays cast for a scene's own sake (a camera's placement,
    /// [`crate::scene::framing`]) and tests' single rays are.
    pub fn query(origin: [f32; 3], direction: [f32; 3], t_min: f32, t_max: f32) -> RayRecord {
        RayRecord {
            origin,
            t_min,
            direction,
            t_max,
            pixel: 0,
            kind: RAY_KIND_PRIMARY,
            depth: 0,
            light: INVALID_ID,
            throughput: [1.0; 3],
            cone: 0.0,
        }
    }

    /// Check: finite origin and direction, non-zero direction, `0 <= t_min < t_max`,
    /// known kind, a light index exactly on shadow rays.
    pub fn validate(&self) -> Result<(), String> {
        let o = self.origin;
        let d = self.direction;
        if !o.iter().chain(d.iter()).all(|c| c.is_finite()) {
            return Err(format!("ray with non-finite origin or direction: {self:?}"));
        }
        if d == [0.0; 3] {
            return Err(format!("ray with zero direction: {self:?}"));
        }
        if !(self.t_min >= 0.0 && self.t_min < self.t_max) {
            return Err(format!("ray with empty or negative t range: {self:?}"));
        }
        if self.kind as usize >= RAY_KIND_COUNT {
            return Err(format!("ray with unknown kind: {self:?}"));
        }
        if (self.kind == RAY_KIND_SHADOW) != (self.light != INVALID_ID) {
            return Err(format!("light index must be set exactly on shadow rays: {self:?}"));
        }
        if !(self.cone >= 0.0 && self.cone.is_finite()) {
            return Err(format!("ray with a negative or non-finite cone: {self:?}"));
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Closest hits
// ---------------------------------------------------------------------------------------------

/// [`HitRecord::flags`]: the ray found a triangle.
pub const HIT_FOUND: u32 = 1 << 0;
/// [`HitRecord::flags`]: the ray hit the triangle's back face
/// ([`crate::kernels::ray::TriangleHit::back_face`]).
pub const HIT_BACK_FACE: u32 = 1 << 1;

/// The closest hit of one ray ([`crate::bvh::Bvh::closest_hit`]): what a secondary
/// ray's trace hands to the reconstruction of the surface it hit.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `t` | f32 | ray parameter of the hit, `t_min < t < t_max`; 0 on a miss |
/// | 4 | `u` | f32 | barycentric weight of the triangle's `v1`; 0 on a miss |
/// | 8 | `v` | f32 | barycentric weight of `v2`; 0 on a miss |
/// | 12 | `triangle` | u32 | global triangle index, [`INVALID_ID`] on a miss |
/// | 16 | `flags` | u32 | [`HIT_FOUND`], [`HIT_BACK_FACE`] |
/// | 20 | `pad` | u32 | zero |
///
/// 24 bytes. A miss is [`HitRecord::MISS`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct HitRecord {
    pub t: f32,
    pub u: f32,
    pub v: f32,
    pub triangle: u32,
    pub flags: u32,
    pub pad: u32,
}
const _: () = assert!(std::mem::size_of::<HitRecord>() == 24);
wgsl_struct!(HitRecord { t, u, v, triangle, flags, pad });

impl HitRecord {
    /// The record of a ray that hit nothing.
    pub const MISS: HitRecord = HitRecord { t: 0.0, u: 0.0, v: 0.0, triangle: INVALID_ID, flags: 0, pad: 0 };

    /// The record of a closest hit, or [`Self::MISS`].
    pub fn from_hit(hit: Option<crate::bvh::ClosestHit>) -> HitRecord {
        match hit {
            None => HitRecord::MISS,
            Some(h) => HitRecord {
                t: h.t,
                u: h.u,
                v: h.v,
                triangle: h.triangle,
                flags: HIT_FOUND | if h.back_face { HIT_BACK_FACE } else { 0 },
                pad: 0,
            },
        }
    }

    /// True if the ray found a triangle.
    #[inline]
    pub fn is_hit(&self) -> bool {
        self.flags & HIT_FOUND != 0
    }

    /// True if the ray hit the triangle's back face.
    #[inline]
    pub fn is_back_face(&self) -> bool {
        self.flags & HIT_BACK_FACE != 0
    }

    /// Check: a miss is [`Self::MISS`]; a hit has a triangle, a positive finite `t`,
    /// finite barycentrics and no unknown flags.
    pub fn validate(&self) -> Result<(), String> {
        if !self.is_hit() {
            return if bytemuck::bytes_of(self) == bytemuck::bytes_of(&Self::MISS) {
                Ok(())
            } else {
                Err(format!("miss is not HitRecord::MISS: {self:?}"))
            };
        }
        if self.triangle == INVALID_ID || !(self.t > 0.0 && self.t.is_finite()) {
            return Err(format!("hit without a triangle or a positive t: {self:?}"));
        }
        if !(self.u.is_finite() && self.v.is_finite()) || self.flags & !(HIT_FOUND | HIT_BACK_FACE) != 0 {
            return Err(format!("hit with non-finite barycentrics or unknown flags: {self:?}"));
        }
        if self.pad != 0 {
            return Err(format!("hit padding not zero: {self:?}"));
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Shadow mask
// ---------------------------------------------------------------------------------------------

/// Shadow mask code (`Frame::shadow`, one per pixel and light): no shadow ray was traced
/// for this (pixel, light): the pixel has no primary hit, or the light is behind the
/// surface (it cannot contribute).
pub const SHADOW_NO_RAY: u8 = 0;
/// Shadow mask code: a shadow ray was traced and reached the light.
pub const SHADOW_LIT: u8 = 1;
/// Shadow mask code: a shadow ray was traced and something blocked it.
pub const SHADOW_OCCLUDED: u8 = 2;

// ---------------------------------------------------------------------------------------------
// Scene tables
// ---------------------------------------------------------------------------------------------

/// [`TriangleRecord::flags`]: the triangle's object is ray traced.
pub const TRI_RAY_TRACED: u32 = 1 << 0;
/// [`TriangleRecord::flags`]: the triangle's object is a closed mesh wound inward (its
/// triangles' right-handed normals point into the volume it encloses, the opposite of
/// glTF's counter-clockwise front faces): its exterior is the side its back faces show.
/// The visibility raster's depth test prefers the exterior side on near-ties
/// ([`crate::kernels::raster::depth_test_value`]); see [`crate::geometry::MeshWinding`].
pub const TRI_INWARD: u32 = 1 << 1;
/// [`TriangleRecord::flags`]: the triangle's material is alpha-tested
/// ([`crate::formats::MAT_ALPHA_TEST`]): the raster and every traversal test the texel's
/// alpha before taking a hit on it ([`crate::kernels::texture::alpha_at`]).
pub const TRI_ALPHA_TEST: u32 = 1 << 2;

/// One world-space triangle of the scene table that the raster, the BVH and
/// reconstruction all read. Triangles of one object are contiguous, in mesh order.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `v0` | [f32; 3] | world-space vertex 0 |
/// | 12 | `object` | u32 | object id |
/// | 16 | `v1` | [f32; 3] | world-space vertex 1 |
/// | 28 | `triangle` | u32 | triangle index within the object's mesh |
/// | 32 | `v2` | [f32; 3] | world-space vertex 2 |
/// | 44 | `flags` | u32 | [`TRI_RAY_TRACED`], [`TRI_INWARD`], [`TRI_ALPHA_TEST`] |
///
/// 48 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct TriangleRecord {
    pub v0: [f32; 3],
    pub object: u32,
    pub v1: [f32; 3],
    pub triangle: u32,
    pub v2: [f32; 3],
    pub flags: u32,
}
const _: () = assert!(std::mem::size_of::<TriangleRecord>() == 48);
wgsl_struct!(TriangleRecord { v0, object, v1, triangle, v2, flags });

impl TriangleRecord {
    /// Vertices as glam vectors.
    #[inline]
    pub fn vertices(&self) -> [glam::Vec3; 3] {
        [self.v0.into(), self.v1.into(), self.v2.into()]
    }
    /// Check: valid object id and known flags. Non-finite vertices are allowed here
    /// (the stages must survive them) and reported by [`crate::geometry::WorldGeometry`].
    pub fn validate(&self) -> Result<(), String> {
        if self.object == INVALID_ID || self.triangle == INVALID_ID {
            return Err(format!("triangle with invalid id: {self:?}"));
        }
        if self.flags & !(TRI_RAY_TRACED | TRI_INWARD | TRI_ALPHA_TEST) != 0 {
            return Err(format!("triangle with unknown flags: {self:?}"));
        }
        Ok(())
    }
}

/// [`ObjectRecord::flags`]: the object is ray traced.
pub const OBJ_RAY_TRACED: u32 = 1 << 0;
/// [`ObjectRecord::flags`]: direct light on the object is the glTF metallic-roughness BRDF
/// (`hyrt_core::kernels::shading::shade_gltf`) on both paths, rather than the paper's
/// Lambert (rasterized) and Blinn-Phong (ray traced) shaders: the scene's
/// [`crate::kernels::shading::ShadingModel`].
pub const OBJ_GLTF_BRDF: u32 = 1 << 1;

/// [`ObjectRecord::material_kind`]: a diffuse material ([`crate::scene::MaterialKind::Diffuse`]).
pub const MATERIAL_DIFFUSE: u32 = 0;
/// [`ObjectRecord::material_kind`]: a specular material, a mirror when ray traced.
pub const MATERIAL_SPECULAR: u32 = 1;
/// [`ObjectRecord::material_kind`]: glass, reflecting and refracting when ray traced.
pub const MATERIAL_GLASS: u32 = 2;

/// Per-object data: where its triangles are and how it is shaded.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `first_triangle` | u32 | index of its first triangle in the triangle table |
/// | 4 | `triangle_count` | u32 | number of triangles |
/// | 8 | `flags` | u32 | [`OBJ_RAY_TRACED`], [`OBJ_GLTF_BRDF`] |
/// | 12 | `material_kind` | u32 | [`crate::scene::MaterialKind::code`] |
/// | 16 | `base_color` | [f32; 3] | linear RGB |
/// | 28 | `metallic` | f32 | [0, 1] |
/// | 32 | `roughness` | f32 | [0, 1] |
/// | 36 | `transmission` | f32 | [0, 1] |
/// | 40 | `ior` | f32 | index of refraction (1.5 unless glass says otherwise) |
/// | 44 | `offset_error` | f32 | extra error bound of points on it whose rays are traced in its own space ([`crate::kernels::instance::instance_position_error`]); 0 when baked into world space |
/// | 48 | `emissive` | [f32; 3] | emitted linear radiance (glTF `emissiveFactor` x `KHR_materials_emissive_strength`), added to every shade of the surface; 0 for none |
/// | 60 | `occlusion` | f32 | the ambient occlusion at a point, in [0, 1]: 1 on an object's own record, the occlusion texture's where one gives it ([`crate::kernels::texture::Materials::at`]); it scales the ambient light alone ([`crate::kernels::shading::ambient`]) |
///
/// 64 bytes. [`crate::kernels::texture::Materials::at`] makes the record a point is shaded
/// with from its object's: textures scale the base colour, metallic, roughness, occlusion
/// and emission there.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct ObjectRecord {
    pub first_triangle: u32,
    pub triangle_count: u32,
    pub flags: u32,
    pub material_kind: u32,
    pub base_color: [f32; 3],
    pub metallic: f32,
    pub roughness: f32,
    pub transmission: f32,
    pub ior: f32,
    pub offset_error: f32,
    pub emissive: [f32; 3],
    pub occlusion: f32,
}
const _: () = assert!(std::mem::size_of::<ObjectRecord>() == 64);
wgsl_struct!(ObjectRecord {
    first_triangle,
    triangle_count,
    flags,
    material_kind,
    base_color,
    metallic,
    roughness,
    transmission,
    ior,
    offset_error,
    emissive,
    occlusion
});

impl ObjectRecord {
    /// Check: known flags and kind, finite non-negative colour and emission, factors in
    /// in [0, 1], a finite non-negative occlusion, ior >= 1, a finite non-negative offset
    /// error.
    pub fn validate(&self) -> Result<(), String> {
        let offset_ok = self.offset_error.is_finite() && self.offset_error >= 0.0;
        if self.flags & !(OBJ_RAY_TRACED | OBJ_GLTF_BRDF) != 0 || self.material_kind > MATERIAL_GLASS || !offset_ok {
            return Err(format!("object record with unknown flags or kind: {self:?}"));
        }
        let colour = |c: &[f32; 3]| c.iter().all(|c| c.is_finite() && *c >= 0.0);
        if !colour(&self.base_color) || !colour(&self.emissive) {
            return Err(format!("object record with invalid colour or emission: {self:?}"));
        }
        let unit = 0.0..=1.0;
        if !(unit.contains(&self.metallic)
            && unit.contains(&self.roughness)
            && unit.contains(&self.transmission)
            && self.occlusion.is_finite()
            && self.occlusion >= 0.0)
        {
            return Err(format!("object record with factor outside [0, 1]: {self:?}"));
        }
        if !(self.ior >= 1.0 && self.ior.is_finite()) {
            return Err(format!("object record with ior < 1: {self:?}"));
        }
        Ok(())
    }
}

/// [`LightRecord::kind`]: point light at `position_or_direction`.
pub const LIGHT_POINT: u32 = 0;
/// [`LightRecord::kind`]: directional light travelling along `position_or_direction` (unit).
pub const LIGHT_DIRECTIONAL: u32 = 1;
/// [`LightRecord::kind`]: spot light at `position_or_direction`, pointing along
/// `spot_direction`: a point light times the cone factor of `spot_scale` and `spot_offset`.
pub const LIGHT_SPOT: u32 = 2;
/// [`LightRecord::kind`]: quad area light, the parallelogram `position_or_direction +
/// [0, 1] edge_u + [0, 1] edge_v`, emitting `radiance` to the side of `edge_u x edge_v`;
/// sampled by area ([`crate::kernels::area_light::sample_quad_light`]).
pub const LIGHT_QUAD: u32 = 3;
/// [`LightRecord::kind`]: sphere area light of centre `position_or_direction` and radius
/// `size`, emitting `radiance`; sampled in the cone it subtends
/// ([`crate::kernels::area_light::sample_sphere_light`]).
pub const LIGHT_SPHERE: u32 = 4;
/// [`LightRecord::kind`]: a sun, a directional light of finite angular size travelling along
/// `position_or_direction` (unit), its disk's half angle having `1 - cos = size`; `radiance`
/// is its illuminance at normal incidence ([`crate::kernels::area_light::sample_sun`]).
pub const LIGHT_SUN: u32 = 5;
/// [`LightRecord::kind`]: the scene's emissive triangles (manifest `emissive_lights =
/// true`), one area light over the frame's whole emitter table ([`EmitterRecord`]): a
/// triangle picked in proportion to its power, a point uniform on it
/// ([`crate::kernels::area_light::sample_emitters`]). Its other fields are zero but
/// `samples` and `seed`.
pub const LIGHT_EMITTERS: u32 = 6;

/// Least `cos(inner) - cos(outer)` of a spot light's cone, from `KHR_lights_punctual`'s
/// recommended implementation (`1 / max(0.001, cos inner - cos outer)`): keeps
/// [`LightRecord::spot_scale`] finite for cones whose inner and outer angles nearly meet.
pub const SPOT_MIN_COS_SPAN: f32 = 0.001;

/// One light of the light list.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `position_or_direction` | [f32; 3] | point and spot: world position; directional and sun: unit travel direction; quad: a corner; sphere: the centre |
/// | 12 | `kind` | u32 | [`LIGHT_POINT`], [`LIGHT_DIRECTIONAL`], [`LIGHT_SPOT`], [`LIGHT_QUAD`], [`LIGHT_SPHERE`], [`LIGHT_SUN`] or [`LIGHT_EMITTERS`] |
/// | 16 | `radiance` | [f32; 3] | colour x intensity (linear RGB; candela for point and spot lights, which divide by d², lux for directional lights and suns, nits (emitted radiance) for quads and spheres); zero for emitters (each [`EmitterRecord`] has its own) |
/// | 28 | `inv_range_sq` | f32 | 1 / range² (point and spot lights with a range), else 0: no cutoff |
/// | 32 | `spot_direction` | [f32; 3] | spot: unit direction the cone points along (from the light); else zero |
/// | 44 | `spot_scale` | f32 | spot: `1 / max(SPOT_MIN_COS_SPAN, cos inner - cos outer)`; else 0 |
/// | 48 | `spot_offset` | f32 | spot: `-cos(outer) * spot_scale`; else 0 |
/// | 52 | `size` | f32 | sphere: radius; sun: `1 - cos` of its disk's half angle; else 0 |
/// | 56 | `samples` | u32 | area lights (quad, sphere, sun, emitters): shadow rays per surface this frame, at least 1; else 0 |
/// | 60 | `seed` | u32 | area lights: the seed of this light's sample streams this frame ([`crate::kernels::soft_shadow`]); else 0 |
/// | 64 | `edge_u` | [f32; 3] | quad: the first edge from the corner; else zero |
/// | 76 | `pad0` | u32 | zero |
/// | 80 | `edge_v` | [f32; 3] | quad: the second edge from the corner; else zero |
/// | 92 | `pad1` | u32 | zero |
///
/// 96 bytes. The distance window and the cone factor are
/// [`light_falloff`](crate::kernels::shading::light_falloff)'s; area lights are sampled by
/// [`crate::kernels::soft_shadow`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct LightRecord {
    pub position_or_direction: [f32; 3],
    pub kind: u32,
    pub radiance: [f32; 3],
    pub inv_range_sq: f32,
    pub spot_direction: [f32; 3],
    pub spot_scale: f32,
    pub spot_offset: f32,
    pub size: f32,
    pub samples: u32,
    pub seed: u32,
    pub edge_u: [f32; 3],
    pub pad0: u32,
    pub edge_v: [f32; 3],
    pub pad1: u32,
}
const _: () = assert!(std::mem::size_of::<LightRecord>() == 96);
wgsl_struct!(LightRecord {
    position_or_direction,
    kind,
    radiance,
    inv_range_sq,
    spot_direction,
    spot_scale,
    spot_offset,
    size,
    samples,
    seed,
    edge_u,
    pad0,
    edge_v,
    pad1
});

impl LightRecord {
    /// A point light at `position` of radiance `radiance` (colour x intensity), no range.
    pub fn point(position: [f32; 3], radiance: [f32; 3]) -> Self {
        LightRecord { position_or_direction: position, kind: LIGHT_POINT, radiance, ..Zeroable::zeroed() }
    }

    /// A directional light travelling along `direction` (unit), of radiance `radiance`.
    pub fn directional(direction: [f32; 3], radiance: [f32; 3]) -> Self {
        LightRecord { position_or_direction: direction, kind: LIGHT_DIRECTIONAL, radiance, ..Zeroable::zeroed() }
    }

    /// Build the record of a scene light (directions are normalized here).
    pub fn from_light(light: &crate::scene::Light) -> Self {
        use crate::scene::Light;
        let inv_range_sq = |range: Option<f32>| range.map_or(0.0, |r| 1.0 / (r * r));
        match *light {
            Light::Point { position, color, intensity, range } => LightRecord {
                inv_range_sq: inv_range_sq(range),
                ..LightRecord::point(position.into(), (color * intensity).into())
            },
            Light::Directional { direction, color, intensity } => {
                LightRecord::directional(direction.normalize_or_zero().into(), (color * intensity).into())
            }
            Light::Spot { position, direction, color, intensity, inner_cone_angle, outer_cone_angle, range } => {
                let cos_outer = outer_cone_angle.cos();
                let spot_scale = 1.0 / (inner_cone_angle.cos() - cos_outer).max(SPOT_MIN_COS_SPAN);
                LightRecord {
                    kind: LIGHT_SPOT,
                    inv_range_sq: inv_range_sq(range),
                    spot_direction: direction.normalize_or_zero().into(),
                    spot_scale,
                    spot_offset: -cos_outer * spot_scale,
                    ..LightRecord::point(position.into(), (color * intensity).into())
                }
            }
            Light::Quad { corner, edge_u, edge_v, color, intensity } => LightRecord {
                position_or_direction: corner.into(),
                kind: LIGHT_QUAD,
                radiance: (color * intensity).into(),
                samples: 1,
                edge_u: edge_u.into(),
                edge_v: edge_v.into(),
                ..Zeroable::zeroed()
            },
            Light::Sphere { position, radius, color, intensity } => LightRecord {
                position_or_direction: position.into(),
                kind: LIGHT_SPHERE,
                radiance: (color * intensity).into(),
                size: radius,
                samples: 1,
                ..Zeroable::zeroed()
            },
            Light::Sun { direction, angular_diameter, color, intensity } => LightRecord {
                position_or_direction: direction.normalize_or_zero().into(),
                kind: LIGHT_SUN,
                radiance: (color * intensity).into(),
                size: crate::kernels::area_light::sun_one_minus_cos(angular_diameter as f64),
                samples: 1,
                ..Zeroable::zeroed()
            },
        }
    }

    /// The light of a scene's emitter table ([`LIGHT_EMITTERS`]), one sample per surface
    /// until a frame sets its own ([`crate::kernels::soft_shadow::frame_lights`]).
    pub fn emitters() -> Self {
        LightRecord { kind: LIGHT_EMITTERS, samples: 1, ..Zeroable::zeroed() }
    }

    /// Whether the light is an area light (quad, sphere, sun or the emitters), sampled by
    /// [`LightRecord::samples`] shadow rays per surface instead of one.
    #[inline]
    pub fn is_area(&self) -> bool {
        matches!(self.kind, LIGHT_QUAD | LIGHT_SPHERE | LIGHT_SUN | LIGHT_EMITTERS)
    }

    /// Check: known kind, finite values, unit directions, a non-negative `inv_range_sq`,
    /// the spot fields zero except on spot lights, the padding zero.
    pub fn validate(&self) -> Result<(), String> {
        if self.kind > LIGHT_EMITTERS || self.pad0 != 0 || self.pad1 != 0 {
            return Err(format!("light with unknown kind: {self:?}"));
        }
        let (edge_u, edge_v) = (glam::Vec3::from(self.edge_u), glam::Vec3::from(self.edge_v));
        if !(edge_u.is_finite() && edge_v.is_finite() && self.size.is_finite()) {
            return Err(format!("light with non-finite values: {self:?}"));
        }
        if self.is_area() != (self.samples > 0) || (!self.is_area() && self.seed != 0) {
            return Err(format!("samples and seed must be set on area lights (samples >= 1) only: {self:?}"));
        }
        let quad = self.kind == LIGHT_QUAD;
        if quad != (edge_u.cross(edge_v) != glam::Vec3::ZERO)
            || (!quad && (edge_u, edge_v) != (glam::Vec3::ZERO, glam::Vec3::ZERO))
        {
            return Err(format!("a quad light needs two non-parallel edges, other lights none: {self:?}"));
        }
        let sized = matches!(self.kind, LIGHT_SPHERE | LIGHT_SUN);
        if sized != (self.size > 0.0) || self.size < 0.0 || (self.kind == LIGHT_SUN && self.size > 1.0) {
            return Err(format!(
                "a sphere needs a radius > 0, a sun a cone with 0 < 1 - cos <= 1, others size 0: {self:?}"
            ));
        }
        let p = glam::Vec3::from(self.position_or_direction);
        let spot = glam::Vec3::from(self.spot_direction);
        let finite = p.is_finite()
            && glam::Vec3::from(self.radiance).is_finite()
            && spot.is_finite()
            && self.inv_range_sq.is_finite()
            && self.spot_scale.is_finite()
            && self.spot_offset.is_finite();
        if !finite {
            return Err(format!("light with non-finite values: {self:?}"));
        }
        let unit = |v: glam::Vec3| (v.length() - 1.0).abs() <= 1e-5;
        if matches!(self.kind, LIGHT_DIRECTIONAL | LIGHT_SUN) && !unit(p) {
            return Err(format!("directional light without a unit direction: {self:?}"));
        }
        // (Finite, checked above: no NaN.)
        if self.inv_range_sq < 0.0 || (!matches!(self.kind, LIGHT_POINT | LIGHT_SPOT) && self.inv_range_sq != 0.0) {
            return Err(format!("light with a negative or misplaced inv_range_sq: {self:?}"));
        }
        if self.kind == LIGHT_EMITTERS && (p != glam::Vec3::ZERO || glam::Vec3::from(self.radiance) != glam::Vec3::ZERO)
        {
            return Err(format!("the emitters' light has no position or radiance of its own: {self:?}"));
        }
        match self.kind {
            LIGHT_SPOT if !unit(spot) || self.spot_scale <= 0.0 => {
                Err(format!("spot light without a unit direction or a positive cone scale: {self:?}"))
            }
            LIGHT_SPOT => Ok(()),
            _ if spot != glam::Vec3::ZERO || self.spot_scale != 0.0 || self.spot_offset != 0.0 => {
                Err(format!("spot fields set on a light that is not a spot: {self:?}"))
            }
            _ => Ok(()),
        }
    }
}

/// [`EmitterRecord::flags`]: the triangle emits on both sides (its material is glTF
/// `doubleSided`); else only to the side of `e1 x e2`, glTF's counter-clockwise front.
pub const EMITTER_DOUBLE_SIDED: u32 = 1 << 0;

/// One emissive triangle of the emitter table ([`LIGHT_EMITTERS`], manifest
/// `emissive_lights = true`), built when the scene is prepared
/// ([`crate::geometry::emitter_table`]): the table's triangles in the order of the scene's
/// triangles, those emitting nothing left out.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `v0` | [f32; 3] | world-space vertex 0 |
/// | 12 | `cdf` | f32 | inclusive cumulative probability of picking this triangle or one before it, in proportion to `area x luminance(radiance)`; the last is exactly 1.0 |
/// | 16 | `e1` | [f32; 3] | `v1 - v0` (world space) |
/// | 28 | `flags` | u32 | [`EMITTER_DOUBLE_SIDED`] |
/// | 32 | `e2` | [f32; 3] | `v2 - v0` (world space) |
/// | 44 | `object` | u32 | the object the triangle belongs to |
/// | 48 | `radiance` | [f32; 3] | emitted linear radiance: the material's `emissive` (factor x strength) times, with an emissive texture, the texture's mean over the triangle ([`crate::geometry::EMITTER_TEXTURE_POINTS`] points): a textured emitter lights the scene with each triangle's mean emission |
/// | 60 | `triangle` | u32 | the triangle's index within its object's mesh |
///
/// 64 bytes. The picking probability of triangle `i` is `cdf_i - cdf_{i-1}` (`cdf_{-1} =
/// 0`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct EmitterRecord {
    pub v0: [f32; 3],
    pub cdf: f32,
    pub e1: [f32; 3],
    pub flags: u32,
    pub e2: [f32; 3],
    pub object: u32,
    pub radiance: [f32; 3],
    pub triangle: u32,
}
const _: () = assert!(std::mem::size_of::<EmitterRecord>() == 64);
wgsl_struct!(EmitterRecord { v0, cdf, e1, flags, e2, object, radiance, triangle });

impl EmitterRecord {
    /// Check: finite vertices and edges, a finite non-negative radiance, known flags, valid
    /// ids and a cdf in (0, 1].
    pub fn validate(&self) -> Result<(), String> {
        let finite = [self.v0, self.e1, self.e2].iter().all(|v| glam::Vec3::from(*v).is_finite());
        let radiance = self.radiance.iter().all(|c| c.is_finite() && *c >= 0.0);
        if !(finite && radiance && self.cdf > 0.0 && self.cdf <= 1.0) {
            return Err(format!("emitter with non-finite values, negative radiance or a cdf outside (0, 1]: {self:?}"));
        }
        if self.flags & !EMITTER_DOUBLE_SIDED != 0 || self.object == INVALID_ID || self.triangle == INVALID_ID {
            return Err(format!("emitter with unknown flags or an invalid id: {self:?}"));
        }
        Ok(())
    }
}

/// The camera as the stages see it (for the GPU, one uniform buffer).
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `view_proj` | [f32; 16] | eye-relative world-to-clip, column-major (glam / WGSL `mat4x4<f32>`): `clip = view_proj * (p - eye, 1)` |
/// | 64 | `inv_view_proj` | [f32; 16] | its inverse: clip to `p - eye` |
/// | 128 | `eye` | [f32; 3] | world-space eye position |
/// | 140 | `width` | u32 | image width in pixels |
/// | 144 | `height` | u32 | image height in pixels |
/// | 148 | `near` | f32 | near clip distance |
/// | 152 | `far` | f32 | far clip distance |
/// | 156 | `pad` | u32 | zero |
///
/// 160 bytes. Pixel (x, y) has its centre at window coordinates (x + 0.5, y + 0.5);
/// row 0 is the top row; NDC y = +1 is the top edge.
///
/// The matrices are relative to the eye (camera-relative rendering): the stages project
/// `p - eye` ([`crate::kernels::raster::clip_position_from_eye`]), which keeps full
/// precision far from the origin, where a world-to-clip matrix loses the low bits of
/// every position to the eye's translation (about 0.01 units at 1e5: enough to fold a
/// closed mesh's silhouettes the wrong way, so that back faces showed and light leaked).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct CameraRecord {
    pub view_proj: [f32; 16],
    pub inv_view_proj: [f32; 16],
    pub eye: [f32; 3],
    pub width: u32,
    pub height: u32,
    pub near: f32,
    pub far: f32,
    pub pad: u32,
}
const _: () = assert!(std::mem::size_of::<CameraRecord>() == 160);
wgsl_struct!(CameraRecord { view_proj, inv_view_proj, eye, width, height, near, far, pad });

impl CameraRecord {
    /// Build the record for a camera and an image size.
    pub fn new(camera: &crate::scene::Camera, width: u32, height: u32) -> Self {
        let vp = camera.view_projection_from_eye(width, height);
        CameraRecord {
            view_proj: vp.to_cols_array(),
            inv_view_proj: vp.inverse().to_cols_array(),
            eye: camera.eye.into(),
            width,
            height,
            near: camera.near,
            far: camera.far,
            pad: 0,
        }
    }
    /// Check: non-empty image, finite matrices, 0 < near < far.
    pub fn validate(&self) -> Result<(), String> {
        if self.width == 0 || self.height == 0 {
            return Err(format!("camera with empty image {}x{}", self.width, self.height));
        }
        if !self.view_proj.iter().chain(self.inv_view_proj.iter()).all(|v| v.is_finite()) {
            return Err("camera with non-finite matrices".into());
        }
        if !(self.near > 0.0 && self.near < self.far) {
            return Err(format!("camera needs 0 < near < far, got {} and {}", self.near, self.far));
        }
        Ok(())
    }
}

/// [`MotionRecord::flags`]: the object did not move since the previous frame; its points
/// are where they were (the record's map is not applied).
pub const MOTION_NONE: u32 = 1;

/// How an object moved between the previous frame and this one, for the denoiser's
/// temporal pass ([`crate::kernels::temporal`]): the map from a point of the object where
/// it is now to where the same point was,
/// `p_prev = M (p - translation) + t_prev` per row `(m_x, m_y, m_z)` = `(M_i0, M_i1, M_i2, t_prev_i)`.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `map_x`, `map_y`, `map_z` | 3 x [f32; 4] | rows of `M` = the previous object-to-world linear part times the current world-to-object one, then the previous frame's object-to-world translation `t_prev` |
/// | 48 | `translation` | [f32; 3] | the current object-to-world translation, subtracted first (as an [`crate::formats::ObjectMap`]'s `t`: the map rounds relative to the object's size, not its distance from the origin) |
/// | 60 | `flags` | u32 | [`MOTION_NONE`] or 0 |
///
/// 64 bytes, one per object, made on the host ([`crate::kernels::temporal::motion_record`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct MotionRecord {
    pub map_x: [f32; 4],
    pub map_y: [f32; 4],
    pub map_z: [f32; 4],
    pub translation: [f32; 3],
    pub flags: u32,
}
const _: () = assert!(std::mem::size_of::<MotionRecord>() == 64);
wgsl_struct!(MotionRecord { map_x, map_y, map_z, translation, flags });

impl MotionRecord {
    /// An object that did not move.
    pub const NONE: MotionRecord = MotionRecord {
        map_x: [1.0, 0.0, 0.0, 0.0],
        map_y: [0.0, 1.0, 0.0, 0.0],
        map_z: [0.0, 0.0, 1.0, 0.0],
        translation: [0.0; 3],
        flags: MOTION_NONE,
    };

    /// Check: finite entries, known flags.
    pub fn validate(&self) -> Result<(), String> {
        let finite =
            self.map_x.iter().chain(&self.map_y).chain(&self.map_z).chain(&self.translation).all(|v| v.is_finite());
        if !finite {
            return Err("motion record with non-finite entries".into());
        }
        if self.flags & !MOTION_NONE != 0 {
            return Err(format!("motion record with unknown flags {:#x}", self.flags));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn miss_texel_validates() {
        GBufferTexel::MISS.validate().unwrap();
    }

    #[test]
    fn hit_texel_without_id_is_rejected() {
        let t = GBufferTexel { flags: GBUF_HIT, ..GBufferTexel::MISS };
        assert!(t.validate().is_err());
    }

    #[test]
    fn shadow_ray_needs_light() {
        let r = RayRecord {
            origin: [0.0; 3],
            t_min: 0.0,
            direction: [0.0, 1.0, 0.0],
            t_max: 1.0,
            pixel: 0,
            kind: RAY_KIND_SHADOW,
            depth: 0,
            light: INVALID_ID,
            throughput: [1.0; 3],
            cone: 0.0,
        };
        assert!(r.validate().is_err());
        assert!(RayRecord { light: 0, ..r }.validate().is_ok());
        assert!(RayRecord { t_max: 0.0, ..r }.validate().is_err());
    }
}

// ---------------------------------------------------------------------------------------------
// Reconstructed surface
// ---------------------------------------------------------------------------------------------

/// One pixel of the surface buffer written by `reconstruction` (paper eq. 1).
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `position` | [f32; 3] | world-space hit point `w*v0 + u*v1 + v*v2` |
/// | 12 | `position_error` | f32 | max component of its absolute error bound ([`crate::kernels::barycentric::position_error_bound`]) |
/// | 16 | `normal` | [f32; 3] | unit shading normal, on the side the raster saw (`GBUF_BACK_FACE`) |
/// | 28 | `object` | u32 | object id ([`INVALID_ID`] on miss) |
/// | 32 | `geometric_normal` | [f32; 3] | unit geometric normal, on the side the raster saw (zero for a degenerate triangle); shadow rays leave along it |
/// | 44 | `triangle` | u32 | global triangle index into the triangle table ([`INVALID_ID`] on miss) |
///
/// 48 bytes. A miss is [`SurfaceRecord::MISS`] (all zero, invalid ids).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct SurfaceRecord {
    pub position: [f32; 3],
    pub position_error: f32,
    pub normal: [f32; 3],
    pub object: u32,
    pub geometric_normal: [f32; 3],
    pub triangle: u32,
}
const _: () = assert!(std::mem::size_of::<SurfaceRecord>() == 48);
wgsl_struct!(SurfaceRecord { position, position_error, normal, object, geometric_normal, triangle });

impl SurfaceRecord {
    /// The record of a pixel without a primary hit.
    pub const MISS: SurfaceRecord = SurfaceRecord {
        position: [0.0; 3],
        position_error: 0.0,
        normal: [0.0; 3],
        object: INVALID_ID,
        geometric_normal: [0.0; 3],
        triangle: INVALID_ID,
    };

    /// True if this pixel has a primary hit.
    #[inline]
    pub fn is_hit(&self) -> bool {
        self.object != INVALID_ID
    }

    /// Check: a miss is [`Self::MISS`]; a hit has both ids, a finite position,
    /// a non-negative error bound and unit (or, for the geometric normal of a
    /// degenerate triangle, zero) normals.
    pub fn validate(&self) -> Result<(), String> {
        if !self.is_hit() {
            return if bytemuck::bytes_of(self) == bytemuck::bytes_of(&Self::MISS) {
                Ok(())
            } else {
                Err(format!("miss surface is not SurfaceRecord::MISS: {self:?}"))
            };
        }
        if self.triangle == INVALID_ID {
            return Err(format!("surface hit without a triangle: {self:?}"));
        }
        if !glam::Vec3::from(self.position).is_finite() || self.position_error.is_nan() || self.position_error < 0.0 {
            return Err(format!("surface hit with non-finite position or error: {self:?}"));
        }
        // Unit length within a few ulp of normalize's rounding.
        const UNIT_TOLERANCE: f32 = 1e-5;
        let n = glam::Vec3::from(self.normal).length();
        let g = glam::Vec3::from(self.geometric_normal).length();
        if (n - 1.0).abs() > UNIT_TOLERANCE || !((g - 1.0).abs() <= UNIT_TOLERANCE || g == 0.0) {
            return Err(format!("surface hit with non-unit normals: {self:?}"));
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Frame parameters
// ---------------------------------------------------------------------------------------------

/// How `composition` makes the final image: what a frame's plan decides
/// ([`crate::plan::FramePlan::composition`]) and the GPU reads as its [`Composition::code`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Composition {
    /// Both images exist: the weighted mean where the ray-traced image has coverage,
    /// the raster texel elsewhere (paper 3.5).
    WeightedMean,
    /// Only the raster image exists (no ray-traced object, or weight 0): a copy of it.
    CopyRaster,
    /// Only the ray-traced image exists (every object ray traced, weight 1): it where
    /// it has coverage, the background elsewhere.
    RtOverBackground,
}

impl Composition {
    /// The code the GPU's `composition` reads (`FrameParams::composition`).
    pub const fn code(self) -> u32 {
        match self {
            Composition::WeightedMean => 0,
            Composition::CopyRaster => 1,
            Composition::RtOverBackground => 2,
        }
    }
}

/// Per-frame parameters of the GPU stages, one uniform buffer.
///
/// A frame too large for the device's bindings is rendered in *bands* of whole rows
/// (`hyrt_gpu`'s `Band`): the per-pixel buffers then hold one band, indexed
/// `(y - first_row) * width + x`, and `height` is the band's rows. A frame of one band
/// has `first_row` 0 and `height` the image's.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `width` | u32 | image width |
/// | 4 | `height` | u32 | rows of the band being rendered (the image height for a frame of one band) |
/// | 8 | `light_count` | u32 | lights in the light list |
/// | 12 | `weight` | f32 | composition weight in [0, 1] |
/// | 16 | `zero` | u32 | always 0: shaders OR it into the bits of products, which the compiler cannot see through, so it cannot fuse them into multiply-adds (the CPU kernels round every product) |
/// | 20 | `composition` | u32 | how `composition` composes: [`Composition::code`] of the frame's plan |
/// | 24 | `first_row` | u32 | image row of the band's first row (0 for a frame of one band) |
/// | 28 | `pixel_spread` | f32 | the angle one pixel subtends, the spread of the frame's ray cones ([`crate::kernels::texture::camera_pixel_spread`] of the camera) when some object's colour varies over its surface (textures, vertex colours: the rule of [`crate::geometry::WorldGeometry::materials`]), else 0, so an untextured frame's rays carry zero cones; finite, >= 0 |
///
/// 32 bytes. Build with [`FrameParams::new`] (spread 0) and [`FrameParams::with_pixel_spread`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct FrameParams {
    pub width: u32,
    pub height: u32,
    pub light_count: u32,
    pub weight: f32,
    pub zero: u32,
    pub composition: u32,
    pub first_row: u32,
    pub pixel_spread: f32,
}
const _: () = assert!(std::mem::size_of::<FrameParams>() == 32);
wgsl_struct!(FrameParams { width, height, light_count, weight, zero, composition, first_row, pixel_spread });

impl FrameParams {
    /// The parameters of a `width` x `height` frame with `light_count` lights,
    /// composed by the weighted mean.
    pub fn new(width: u32, height: u32, light_count: u32, weight: f32) -> Self {
        let composition = Composition::WeightedMean.code();
        FrameParams { width, height, light_count, weight, zero: 0, composition, first_row: 0, pixel_spread: 0.0 }
    }

    /// The same parameters with the frame's cone spread (the [`FrameParams`] table).
    pub fn with_pixel_spread(self, pixel_spread: f32) -> Self {
        FrameParams { pixel_spread, ..self }
    }

    /// The same parameters for the band of `rows` rows from image row `first_row`.
    pub fn for_band(self, first_row: u32, rows: u32) -> Self {
        FrameParams { first_row, height: rows, ..self }
    }

    /// The same parameters, composed as `composition` says.
    pub fn with_composition(self, composition: Composition) -> Self {
        FrameParams { composition: composition.code(), ..self }
    }

    /// Check: a non-empty image, a weight in [0, 1], a known composition code, `zero`
    /// zero, a finite non-negative cone spread.
    pub fn validate(&self) -> Result<(), String> {
        if self.composition > Composition::RtOverBackground.code() {
            return Err(format!("unknown composition code {}", self.composition));
        }
        if self.zero != 0 {
            return Err(format!("frame parameters with non-zero zero: {self:?}"));
        }
        if !(self.pixel_spread >= 0.0 && self.pixel_spread.is_finite()) {
            return Err(format!("frame parameters with a negative or non-finite cone spread: {self:?}"));
        }
        if self.width == 0 || self.height == 0 {
            return Err(format!("empty image {}x{}", self.width, self.height));
        }
        if !(0.0..=1.0).contains(&self.weight) {
            return Err(format!("weight {} outside [0, 1]", self.weight));
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Environment
// ---------------------------------------------------------------------------------------------

/// [`EnvironmentRecord::kind`]: the default sky ([`crate::kernels::bounce::sky`]).
pub const ENV_SKY: u32 = 0;
/// [`EnvironmentRecord::kind`]: an equirectangular map
/// ([`crate::kernels::environment::map_radiance`]).
pub const ENV_MAP: u32 = 1;

/// What secondary rays that leave the scene see ([`crate::scene::Environment`]), as the
/// GPU reads it: this header, and the map's texels in a buffer of their own
/// (`width * height` linear RGBA `[f32; 4]`, row 0 on top, as
/// [`crate::scene::EnvironmentMap::texels`]; one zero texel for the sky).
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `kind` | u32 | [`ENV_SKY`] or [`ENV_MAP`] |
/// | 4 | `width` | u32 | map width in texels (1 for the sky) |
/// | 8 | `height` | u32 | map height in texels (1 for the sky) |
/// | 12 | `pad` | u32 | zero |
///
/// 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct EnvironmentRecord {
    pub kind: u32,
    pub width: u32,
    pub height: u32,
    pub pad: u32,
}
const _: () = assert!(std::mem::size_of::<EnvironmentRecord>() == 16);
wgsl_struct!(EnvironmentRecord { kind, width, height, pad });

/// A frame's ambient light ([`crate::kernels::ibl::AmbientLight`]) as the GPU reads it:
/// this header, and the image-based light's tables in a buffer of their own
/// ([`crate::kernels::ibl::AmbientLight::texels`]: `vec4<f32>` texels, one zero texel
/// without image-based light).
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `scale` | f32 | the constant ambient terms' scale, >= 0 ([`crate::kernels::shading::Ambient::scale`]) |
/// | 4 | `image` | u32 | 1 when the texels hold an image-based light, else 0 |
/// | 8 | `ao_samples` | u32 | ambient-occlusion rays per surface this frame; 0: none ([`crate::kernels::soft_shadow::AmbientOcclusion`]) |
/// | 12 | `ao_seed` | u32 | the seed of their sample streams this frame |
/// | 16 | `ao_radius` | f32 | how far they look (scene units); 0 without them |
/// | 20 | `pad0` | u32 | zero |
/// | 24 | `pad` | [u32; 2] | zero |
///
/// 32 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct AmbientLightRecord {
    pub scale: f32,
    pub image: u32,
    pub ao_samples: u32,
    pub ao_seed: u32,
    pub ao_radius: f32,
    pub pad0: u32,
    pub pad: [u32; 2],
}
const _: () = assert!(std::mem::size_of::<AmbientLightRecord>() == 32);
wgsl_struct!(AmbientLightRecord { scale, image, ao_samples, ao_seed, ao_radius, pad0, pad });

impl AmbientLightRecord {
    /// Check: a finite non-negative scale, `image` 0 or 1, a finite positive radius where
    /// occlusion rays are traced (0 and no seed without them), zero padding, and `texels`
    /// entries as [`crate::kernels::ibl::AmbientLight::texels`] makes them (1 without an
    /// image).
    pub fn validate(&self, texels: usize) -> Result<(), String> {
        let scale_ok = self.scale.is_finite() && self.scale >= 0.0;
        let ao_ok = match self.ao_samples {
            0 => self.ao_radius == 0.0 && self.ao_seed == 0,
            _ => self.ao_radius > 0.0 && self.ao_radius.is_finite(),
        };
        if !scale_ok || !ao_ok || self.image > 1 || self.pad0 != 0 || self.pad != [0; 2] {
            return Err(format!("bad ambient light record {self:?}"));
        }
        let want = if self.image == 1 {
            crate::kernels::ibl::prefiltered_offset(crate::kernels::ibl::PREFILTER_LEVELS)
        } else {
            1
        };
        if texels != want {
            return Err(format!("{texels} ambient light texels, {want} expected"));
        }
        Ok(())
    }
}

impl EnvironmentRecord {
    /// The header of `env`, and its texels (one zero texel for the sky).
    pub fn of(env: &crate::scene::Environment) -> (EnvironmentRecord, &[[f32; 4]]) {
        const NO_TEXEL: [[f32; 4]; 1] = [[0.0; 4]];
        match env.map() {
            None => (EnvironmentRecord { kind: ENV_SKY, width: 1, height: 1, pad: 0 }, &NO_TEXEL),
            Some(m) => (EnvironmentRecord { kind: ENV_MAP, width: m.width(), height: m.height(), pad: 0 }, m.texels()),
        }
    }

    /// Check: a known kind, a non-empty size (1 x 1 for the sky), zero padding, and
    /// `texels` of `width * height` entries.
    pub fn validate(&self, texels: usize) -> Result<(), String> {
        let sized = self.width > 0 && self.height > 0 && (self.kind == ENV_MAP || (self.width, self.height) == (1, 1));
        if self.kind > ENV_MAP || !sized || self.pad != 0 {
            return Err(format!("bad environment record {self:?}"));
        }
        if texels != self.width as usize * self.height as usize {
            return Err(format!("{texels} texels for a {}x{} environment", self.width, self.height));
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Ray lists on the GPU
// ---------------------------------------------------------------------------------------------

/// Parameters of one ray list of a GPU frame: the primary hits' shadow rays (depth 0) or
/// the rays of bounce `depth`, one uniform buffer per list. The list stages
/// (`compaction`, `secondary_rays`, `bounce_trace`, `shadow_rays`, `bounce_shading`) size
/// their work by it and read the live counts from the lists' count buffers, so no count
/// comes back to the CPU mid-frame.
///
/// | offset | field | type | meaning |
/// |---:|---|---|---|
/// | 0 | `slots` | u32 | surfaces the list's surface buffer has room for: the pixels (depth 0) or the ray room of bounce `depth`; `compaction` pairs are `light * slots + surface` |
/// | 4 | `parents` | u32 | the parents' slots of `secondary_rays`: the pixels for depth 1, the ray room of depth `depth - 1` beyond |
/// | 8 | `depth` | u32 | the bounce depth, 0 for the primary hits |
/// | 12 | `last` | u32 | 1 at the plan's deepest bounce (its rays have no children), else 0 |
///
/// 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct ListParams {
    pub slots: u32,
    pub parents: u32,
    pub depth: u32,
    pub last: u32,
}
const _: () = assert!(std::mem::size_of::<ListParams>() == 16);
wgsl_struct!(ListParams { slots, parents, depth, last });

impl ListParams {
    /// Check: room for a surface, parents from depth 1 on, `last` 0 or 1 and 0 at depth 0.
    pub fn validate(&self) -> Result<(), String> {
        let ok = self.slots > 0
            && (self.depth == 0 || self.parents > 0)
            && self.last <= 1
            && (self.depth > 0 || self.last == 0);
        if ok {
            Ok(())
        } else {
            Err(format!("bad list parameters {self:?}"))
        }
    }
}
