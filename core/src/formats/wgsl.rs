//! The WGSL twins of the formats, generated from the Rust records so that no record is
//! typed twice: every GPU shader starts with [`declarations`].
//!
//! Each record lists its fields once, next to its Rust definition, with
//! `wgsl_struct!`: the macro takes the WGSL type of a
//! field from its Rust type ([`WgslField`]), its offset from [`std::mem::offset_of!`],
//! and fails to compile when a Rust field is missing from the list. [`WgslStruct::declaration`]
//! lays the fields out by WGSL's rules and checks the offsets and the size against Rust's
//! (a record whose layouts differ cannot be declared). The format constants are generated
//! the same way, by name, from their Rust values ([`constants`]).

use crate::formats::{
    AmbientLightRecord, BvhNode, CameraRecord, EmitterRecord, EnvironmentRecord, FrameParams, GBufferTexel, HitRecord,
    InstanceRecord, LightRecord, ListParams, MaterialRecord, MotionRecord, ObjectRecord, PlacementRecord, RayRecord,
    SurfaceLayout, SurfaceRecord, TextureRecord, TriangleRecord, TriangleUvRecord,
};

/// The WGSL type of a record field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WgslType {
    /// `f32`.
    F32,
    /// `u32`.
    U32,
    /// `vec2<u32>`.
    Vec2U32,
    /// `vec2<f32>`.
    Vec2F32,
    /// `vec3<f32>`.
    Vec3F32,
    /// `mat4x4<f32>` (column-major).
    Vec4F32,
    Mat4x4F32,
}

impl WgslType {
    /// The type as WGSL spells it.
    pub fn name(self) -> &'static str {
        match self {
            WgslType::F32 => "f32",
            WgslType::U32 => "u32",
            WgslType::Vec2U32 => "vec2<u32>",
            WgslType::Vec2F32 => "vec2<f32>",
            WgslType::Vec3F32 => "vec3<f32>",
            WgslType::Vec4F32 => "vec4<f32>",
            WgslType::Mat4x4F32 => "mat4x4<f32>",
        }
    }

    /// `AlignOf` in WGSL's memory layout rules.
    pub fn align(self) -> usize {
        match self {
            WgslType::F32 | WgslType::U32 => 4,
            WgslType::Vec2U32 | WgslType::Vec2F32 => 8,
            WgslType::Vec3F32 | WgslType::Vec4F32 | WgslType::Mat4x4F32 => 16,
        }
    }

    /// `SizeOf` in WGSL's memory layout rules.
    pub fn size(self) -> usize {
        match self {
            WgslType::F32 | WgslType::U32 => 4,
            WgslType::Vec2U32 | WgslType::Vec2F32 => 8,
            WgslType::Vec3F32 => 12,
            WgslType::Vec4F32 => 16,
            WgslType::Mat4x4F32 => 64,
        }
    }
}

/// A Rust field type with a WGSL twin of the same size.
pub trait WgslField {
    /// Its WGSL type.
    const WGSL: WgslType;
}

impl WgslField for f32 {
    const WGSL: WgslType = WgslType::F32;
}
impl WgslField for u32 {
    const WGSL: WgslType = WgslType::U32;
}
impl WgslField for [u32; 2] {
    const WGSL: WgslType = WgslType::Vec2U32;
}
impl WgslField for [f32; 2] {
    const WGSL: WgslType = WgslType::Vec2F32;
}
impl WgslField for [f32; 3] {
    const WGSL: WgslType = WgslType::Vec3F32;
}
impl WgslField for [f32; 4] {
    const WGSL: WgslType = WgslType::Vec4F32;
}
impl WgslField for [f32; 16] {
    const WGSL: WgslType = WgslType::Mat4x4F32;
}

/// The WGSL type of the field a projection selects (lets `wgsl_struct!` read a field's
/// type from its Rust declaration).
pub fn field_type<S, T: WgslField>(_field: fn(&S) -> &T) -> WgslType {
    T::WGSL
}

/// One field of a record: its name, WGSL type and Rust byte offset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Field {
    pub name: &'static str,
    pub ty: WgslType,
    /// `std::mem::offset_of!` of the Rust field.
    pub offset: usize,
}

/// A `#[repr(C)]` record that crosses to the GPU, declared in WGSL from its field list.
pub trait WgslStruct: Sized {
    /// The struct's name, the same in Rust and WGSL.
    const NAME: &'static str;

    /// The fields, in declaration order.
    fn fields() -> Vec<Field>;

    /// The WGSL offsets of the fields and the WGSL size of the struct (WGSL's layout
    /// rules: each field at the next multiple of its alignment, the size rounded up to
    /// the largest alignment).
    fn wgsl_layout() -> (Vec<usize>, usize) {
        let mut end = 0usize;
        let mut align = 1usize;
        let offsets = Self::fields()
            .iter()
            .map(|f| {
                let offset = end.next_multiple_of(f.ty.align());
                end = offset + f.ty.size();
                align = align.max(f.ty.align());
                offset
            })
            .collect();
        (offsets, end.next_multiple_of(align))
    }

    /// Check that WGSL lays the record out as Rust does: every field at its Rust offset
    /// and the same size.
    fn check_layout() -> Result<(), String> {
        let (offsets, size) = Self::wgsl_layout();
        for (f, offset) in Self::fields().iter().zip(offsets) {
            if f.offset != offset {
                return Err(format!("{}.{}: Rust offset {}, WGSL offset {offset}", Self::NAME, f.name, f.offset));
            }
        }
        if size != std::mem::size_of::<Self>() {
            return Err(format!("{}: Rust size {}, WGSL size {size}", Self::NAME, std::mem::size_of::<Self>()));
        }
        Ok(())
    }

    /// The WGSL `struct` declaration. Panics if the layouts differ ([`Self::check_layout`]).
    fn declaration() -> String {
        if let Err(e) = Self::check_layout() {
            panic!("WGSL layout differs from Rust: {e}");
        }
        let mut s = format!(
            "// hyrt_core: {} ({} bytes).\nstruct {} {{\n",
            Self::NAME,
            std::mem::size_of::<Self>(),
            Self::NAME
        );
        for f in Self::fields() {
            s += &format!("    {}: {},\n", f.name, f.ty.name());
        }
        s + "}\n"
    }
}

/// Implement [`WgslStruct`] for a record from the list of its fields:
/// `wgsl_struct!(LightRecord { position_or_direction, kind, radiance, pad });`.
/// Every field of the Rust struct must be listed, in declaration order (a missing one
/// does not compile; a wrong order fails [`WgslStruct::check_layout`]).
macro_rules! wgsl_struct {
    ($record:ident { $($field:ident),+ $(,)? }) => {
        impl $crate::formats::wgsl::WgslStruct for $record {
            const NAME: &'static str = stringify!($record);
            fn fields() -> Vec<$crate::formats::wgsl::Field> {
                // Exhaustive: does not compile if a field of the record is not listed.
                let _every_field_listed = |r: &$record| {
                    let $record { $($field: _),+ } = r;
                };
                vec![$($crate::formats::wgsl::Field {
                    name: stringify!($field),
                    ty: $crate::formats::wgsl::field_type::<$record, _>(|r| &r.$field),
                    offset: std::mem::offset_of!($record, $field),
                }),+]
            }
        }
    };
}
pub(crate) use wgsl_struct;

/// `(name, value as u32)` for each named constant: the name spelled once, as in Rust.
macro_rules! u32_constants {
    ($($name:ident),+ $(,)?) => {
        [$((stringify!($name), $name as u32)),+]
    };
}

/// The format constants as `(name, value)`, the WGSL names equal to the Rust ones:
/// ids, flags, kinds and codes of [`crate::formats`], and the
/// [`Composition::code`](super::Composition::code)s as `COMPOSITION_*`.
pub fn constant_values() -> Vec<(&'static str, u32)> {
    use crate::formats::*;
    let mut c = u32_constants!(
        INVALID_ID,
        GBUF_HIT,
        GBUF_RAY_TRACED,
        GBUF_BACK_FACE,
        RAY_KIND_SHADOW,
        RAY_KIND_PRIMARY,
        RAY_KIND_REFLECTION,
        RAY_KIND_REFRACTION,
        HIT_FOUND,
        HIT_BACK_FACE,
        SHADOW_NO_RAY,
        SHADOW_LIT,
        SHADOW_OCCLUDED,
        TRI_RAY_TRACED,
        TRI_INWARD,
        TRI_ALPHA_TEST,
        OBJ_RAY_TRACED,
        OBJ_GLTF_BRDF,
        MATERIAL_DIFFUSE,
        MATERIAL_SPECULAR,
        MATERIAL_GLASS,
        LIGHT_POINT,
        LIGHT_DIRECTIONAL,
        LIGHT_SPOT,
        ENV_SKY,
        ENV_MAP,
        WRAP_REPEAT,
        WRAP_CLAMP,
        WRAP_MIRROR,
        FILTER_NEAREST,
        FILTER_LINEAR,
        FILTER_NO_MIP,
        MAT_TEXTURED,
        MAT_VERTEX_COLORS,
        MAT_ALPHA_TEST,
        MAT_METALLIC_ROUGHNESS,
        MAT_OCCLUSION,
        MAT_EMISSIVE,
        MAT_NORMAL,
        MAT_ANY_TEXTURE,
        TEXEL_SRGB,
        TEXEL_LINEAR,
    )
    .to_vec();
    c.extend(u32_constants!(
        INSTANCE_IDENTITY,
        INSTANCE_MIRRORED,
        INSTANCE_ALPHA_TEST,
        MOTION_NONE,
        EMITTER_DOUBLE_SIDED
    ));
    c.extend([
        ("COMPOSITION_WEIGHTED_MEAN", Composition::WeightedMean.code()),
        ("COMPOSITION_COPY_RASTER", Composition::CopyRaster.code()),
        ("COMPOSITION_RT_OVER_BACKGROUND", Composition::RtOverBackground.code()),
    ]);
    c
}

/// The format constants as WGSL `const` declarations ([`constant_values`]).
pub fn constants() -> String {
    constant_values().into_iter().map(|(name, value)| format!("const {name}: u32 = {value}u;\n")).collect()
}

/// The WGSL struct declarations of every record that crosses to the GPU, in one place.
pub fn struct_declarations() -> String {
    [
        GBufferTexel::declaration(),
        RayRecord::declaration(),
        TriangleRecord::declaration(),
        ObjectRecord::declaration(),
        LightRecord::declaration(),
        CameraRecord::declaration(),
        SurfaceRecord::declaration(),
        HitRecord::declaration(),
        FrameParams::declaration(),
        BvhNode::declaration(),
        EnvironmentRecord::declaration(),
        AmbientLightRecord::declaration(),
        ListParams::declaration(),
        TextureRecord::declaration(),
        MaterialRecord::declaration(),
        TriangleUvRecord::declaration(),
        SurfaceLayout::declaration(),
        InstanceRecord::declaration(),
        MotionRecord::declaration(),
        EmitterRecord::declaration(),
        PlacementRecord::declaration(),
    ]
    .join("\n")
}

/// What every GPU shader starts with: the record structs ([`struct_declarations`]) and
/// the format constants ([`constants`]), generated from the Rust definitions.
pub fn declarations() -> String {
    format!(
        "// Generated by hyrt_core::formats::wgsl::declarations from the Rust records and constants.\n{}\n{}\n",
        struct_declarations(),
        constants()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every record's WGSL layout is its Rust layout: offsets (`offset_of!`) and size.
    #[test]
    fn wgsl_layouts_match_rust() {
        GBufferTexel::check_layout().unwrap();
        RayRecord::check_layout().unwrap();
        TriangleRecord::check_layout().unwrap();
        ObjectRecord::check_layout().unwrap();
        LightRecord::check_layout().unwrap();
        CameraRecord::check_layout().unwrap();
        SurfaceRecord::check_layout().unwrap();
        HitRecord::check_layout().unwrap();
        FrameParams::check_layout().unwrap();
        BvhNode::check_layout().unwrap();
        EnvironmentRecord::check_layout().unwrap();
        AmbientLightRecord::check_layout().unwrap();
        ListParams::check_layout().unwrap();
        TextureRecord::check_layout().unwrap();
        MaterialRecord::check_layout().unwrap();
        TriangleUvRecord::check_layout().unwrap();
        SurfaceLayout::check_layout().unwrap();
        InstanceRecord::check_layout().unwrap();
        MotionRecord::check_layout().unwrap();
        EmitterRecord::check_layout().unwrap();
        PlacementRecord::check_layout().unwrap();
    }

    #[test]
    fn declarations_spell_fields_and_constants() {
        let d = declarations();
        assert!(d.contains("struct CameraRecord {\n    view_proj: mat4x4<f32>,\n"));
        assert!(d.contains("    eye: vec3<f32>,\n    width: u32,\n"));
        assert!(d.contains("struct FrameParams {"));
        assert!(d.contains("    first_row: u32,\n    pixel_spread: f32,\n}"));
        assert!(d.contains("const INVALID_ID: u32 = 4294967295u;\n"));
        assert!(d.contains("const SHADOW_OCCLUDED: u32 = 2u;\n"));
        assert!(d.contains("const COMPOSITION_RT_OVER_BACKGROUND: u32 = 2u;\n"));
    }

    /// A record laid out differently in WGSL (a `vec3` after one scalar is aligned to 16
    /// in WGSL, to 4 in Rust) is caught.
    #[test]
    fn a_layout_mismatch_is_reported() {
        #[repr(C)]
        struct Misaligned {
            a: u32,
            b: [f32; 3],
        }
        wgsl_struct!(Misaligned { a, b });
        let m = Misaligned { a: 0, b: [0.0; 3] };
        assert_eq!((m.a, m.b), (0, [0.0; 3]));
        assert!(Misaligned::check_layout().unwrap_err().contains("Misaligned.b"));
    }
}
