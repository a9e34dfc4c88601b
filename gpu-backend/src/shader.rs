//! What every GPU stage is built from: the WGSL sources (the generated preludes of core
//! constants and the shared `shaders/*.wgsl` files, assembled per stage), and the
//! pipeline, binding and dispatch plumbing. Stages import this module; it imports no
//! stage, so the stage modules stand side by side above it.

use hyrt_core::bvh::{BVH_CULL_SLACK, BVH_STACK_SIZE};
use hyrt_core::kernels::area_light::MIN_AREA_LIGHT_DISTANCE_SQ;
use hyrt_core::kernels::bounce::{IOR_OUTSIDE, MIN_THROUGHPUT, SKY_GROUND, SKY_HORIZON, SKY_ZENITH};
use hyrt_core::kernels::environment::{ATAN_SERIES, INV_TWO_PI, TAN_PI_8};
use hyrt_core::kernels::exact::DEFAULT_NAN;
use hyrt_core::kernels::ibl::{
    prefiltered_offset, AMBIENT_TEXELS_SPLIT_SUM, PREFILTER_BASE, PREFILTER_LEVELS, SH9_TERMS, SPLIT_SUM_SIZE,
};
use hyrt_core::kernels::occlusion::AO_STREAM;
use hyrt_core::kernels::ray::{gamma, OFFSET_ERROR_SCALE, SLAB_FAR_SCALE, VELTKAMP_SPLIT};
use hyrt_core::kernels::sampling::{COS_SERIES, SIN_SERIES};
use hyrt_core::kernels::shading::{
    AMBIENT, BACKGROUND, DIELECTRIC_F0, ENVIRONMENT_SPECULAR, EXP_SERIES, GGX_MIN_ALPHA, LOG2_SERIES,
    MIN_LIGHT_DISTANCE_SQ, POW_FLUSH_EXPONENT, TWO_OVER_LN_2,
};
use hyrt_core::kernels::shadow::SHADOW_T_MAX_POINT;

use crate::buffers::SlotParams;
use hyrt_core::formats::{LIGHT_QUAD, LIGHT_SPHERE, LIGHT_SUN};

use crate::wgsl::f32_literal;
use crate::GpuContext;

// ---------------------------------------------------------------------------------------------
// Dispatch sizes
// ---------------------------------------------------------------------------------------------

/// Threads per workgroup of the `shadow_rays` kernel (one ray each). 64 is a
/// multiple of every common SIMD width (32 NVIDIA, 64 AMD, 8-16 lavapipe lanes).
pub const SHADOW_RAYS_WORKGROUP_SIZE: u32 = 64;

/// Largest workgroup count per dispatch dimension (WebGPU's default limit).
pub const MAX_WORKGROUPS_PER_DIMENSION: u32 = 65_535;

/// Side of the square workgroup of the shading stages (`@workgroup_size(8, 8, 1)`).
pub(crate) const TILE: u32 = 8;

// ---------------------------------------------------------------------------------------------
// WGSL sources
// ---------------------------------------------------------------------------------------------

/// The generated records and format constants of every stage
/// ([`hyrt_core::formats::wgsl::declarations`]), with the fields whose names WGSL reserves
/// renamed: [`hyrt_core::formats::MotionRecord`]'s `from` is `from_point` here (`from` is
/// a reserved word: naga refuses the module). The layout is the record's.
pub fn declarations() -> String {
    let core = hyrt_core::formats::wgsl::declarations();
    let start = core.find("struct MotionRecord {").unwrap_or(core.len());
    let end = core[start..].find('}').map_or(core.len(), |e| start + e);
    format!("{}{}{}", &core[..start], core[start..end].replace("\n    from: ", "\n    from_point: "), &core[end..])
}

/// What every stage's WGSL begins with: the generated records and format constants
/// ([`declarations`]), then the f32 field masks and the exact division and square root
/// (`shaders/exact.wgsl`, mirrors of [`hyrt_core::kernels::exact`]) after their constant,
/// generated from the Rust value. No shader divides floats or takes a square root any
/// other way.
pub fn preamble() -> String {
    format!(
        "{}\n// Generated from hyrt_core::kernels::exact (gpu-backend/src/shader.rs).\nconst EXACT_DEFAULT_NAN: u32 = {:#010x}u;\n{}",
        declarations(),
        DEFAULT_NAN,
        include_str!("shaders/exact.wgsl")
    )
}

/// The WGSL both ray stages share after the generated records ([`declarations`]): the
/// ray constants, generated from their Rust values so they cannot drift, followed by
/// `ray.wgsl`.
pub(crate) fn ray_wgsl() -> String {
    let consts = [
        ("SLAB_FAR_SCALE", f32_literal(SLAB_FAR_SCALE)),
        ("GAMMA_2", f32_literal(gamma(2))),
        ("GAMMA_3", f32_literal(gamma(3))),
        ("GAMMA_5", f32_literal(gamma(5))),
        ("OFFSET_ERROR_SCALE", f32_literal(OFFSET_ERROR_SCALE)),
        ("BVH_CULL_SLACK", f32_literal(BVH_CULL_SLACK)),
        ("VELTKAMP_SPLIT", f32_literal(VELTKAMP_SPLIT)),
        ("SHADOW_T_MAX_POINT_BITS", format!("{}u", SHADOW_T_MAX_POINT.to_bits())),
        ("BVH_STACK_SIZE", format!("{}u", BVH_STACK_SIZE)),
        ("SHADOW_WG", format!("{SHADOW_RAYS_WORKGROUP_SIZE}u")),
        ("MAX_DISPATCH", format!("{MAX_WORKGROUPS_PER_DIMENSION}u")),
    ];
    let mut s = String::from("// Generated from the hyrt_core constants (gpu-backend/src/shadow_rays.rs).\n");
    for (name, value) in consts {
        s += &format!("const {name} = {value};\n");
    }
    s + include_str!("shaders/ray.wgsl")
}

/// The shading constants of `shading_helpers.wgsl` and `shading.wgsl`, generated from
/// the Rust values so that both sides use the same bits (the format constants come with
/// the records, [`declarations`]).
fn prelude() -> String {
    let f = |name: &str, x: f32| format!("const {name}: f32 = {};\n", f32_literal(x));
    let [br, bg, bb] = BACKGROUND;
    let mut s = String::from("// Generated by hyrt_gpu::rt_shading::prelude from the hyrt_core constants.\n");
    s += &f("AMBIENT", AMBIENT);
    s += &f("ENVIRONMENT_SPECULAR", ENVIRONMENT_SPECULAR);
    s += &format!(
        "const BACKGROUND: vec3<f32> = vec3<f32>({}, {}, {});\n",
        f32_literal(br),
        f32_literal(bg),
        f32_literal(bb)
    );
    s += &f("DIELECTRIC_F0", DIELECTRIC_F0);
    s += &f("GGX_MIN_ALPHA", GGX_MIN_ALPHA);
    s += &f("MIN_LIGHT_DISTANCE_SQ", MIN_LIGHT_DISTANCE_SQ);
    s += &f("FRAC_1_PI", std::f32::consts::FRAC_1_PI);
    s += &f("PI", std::f32::consts::PI);
    s += &f("F32_MAX", f32::MAX);
    s += &f("F32_MIN_POSITIVE", f32::MIN_POSITIVE);
    s += &f("SQRT_2", std::f32::consts::SQRT_2);
    s += &f("LN_2", std::f32::consts::LN_2);
    s += &f("TWO_OVER_LN_2", TWO_OVER_LN_2);
    s += &f("POW_FLUSH_EXPONENT", POW_FLUSH_EXPONENT);
    let array = |name: &str, xs: &[f32]| {
        let items: Vec<String> = xs.iter().map(|&x| f32_literal(x)).collect();
        format!("const {name} = array<f32, {}>({});\n", xs.len(), items.join(", "))
    };
    s += &array("LOG2_SERIES", &LOG2_SERIES);
    s += &array("EXP_SERIES", &EXP_SERIES);
    s
}

/// The shading constants and `shaders/shading_helpers.wgsl` (exact arithmetic, light
/// evaluation), for every stage that evaluates lights: the shading stages and
/// `compaction`. Goes after [`declarations`]; the stage binds `params: FrameParams`.
pub(crate) fn shading_helpers() -> String {
    format!("{}\n{}", prelude(), include_str!("shaders/shading_helpers.wgsl"))
}

/// The WGSL of a shading stage: the generated records and format constants, the
/// shading helpers, `shaders/shading.wgsl` (the mirrored kernels), then the stage's
/// own source.
pub fn shading_source(stage: &str) -> String {
    format!("{}\n{}\n{}\n{}", preamble(), shading_helpers(), include_str!("shaders/shading.wgsl"), stage)
}

/// [`shading_source`] with the texture kernels and the shaded object records
/// ([`crate::texture::texture_wgsl`], [`crate::texture::materials_wgsl`]), the ambient
/// light ([`lat_long_wgsl`], [`ambient_light_wgsl`]), the soft-shadow kernels
/// ([`soft_shadow_wgsl`]: area-light samples) and the per-surface shaders over a
/// `shadow` binding (`shaders/surface_shading.wgsl`: `ambient`, `unlit` and the shaders
/// that start from them, reading the mask's slots) before the stage's source: for the
/// stages that bind `shadow`, `slot_params`, `lights`, `objects`, the surface tables and
/// the ambient light (`rt_shading`, `raster_shading`, `bounce_shading`). Shades from the
/// mask's codes alone ([`filtered_visibility_wgsl`] of `None`).
pub fn surface_shading_source(stage: &str) -> String {
    surface_shading_source_for(stage, None)
}

/// [`surface_shading_source`] for a stage that shades a denoised frame's primary
/// surfaces from `shadow_denoise`'s channels, bound at `visibility` (`None`: the codes
/// alone; [`filtered_visibility_wgsl`]).
pub fn surface_shading_source_for(stage: &str, visibility: Option<u32>) -> String {
    shading_source(&format!(
        "{}\n{}\n{}\n{}\n{}\n{}\n{}\n{stage}",
        crate::texture::texture_wgsl(),
        crate::texture::materials_wgsl(),
        lat_long_wgsl(),
        ambient_light_wgsl(),
        soft_shadow_wgsl(),
        filtered_visibility_wgsl(visibility),
        include_str!("shaders/surface_shading.wgsl")
    ))
}

/// What `shaders/surface_shading.wgsl` reads of a frame's denoised visibility: with a
/// binding, `DENOISED` true and `filtered_channel(index, c)`, channel `c` of surface
/// `index` of `visibility: array<f32>` (`slot_params.channels` per surface) bound there;
/// without, `DENOISED` false (the stage shades from the codes, and binds no visibility).
pub fn filtered_visibility_wgsl(binding: Option<u32>) -> String {
    match binding {
        Some(b) => format!(
            "// The frame's denoised visibility (hyrt_gpu::shader::filtered_visibility_wgsl).\n\
             @group(0) @binding({b}) var<storage, read> visibility: array<f32>;\n\
             const DENOISED: bool = true;\n\
             fn filtered_channel(index: u32, c: u32) -> f32 {{\n    return visibility[index * slot_params.channels + c];\n}}\n"
        ),
        None => "// No denoised visibility (hyrt_gpu::shader::filtered_visibility_wgsl).\nconst DENOISED: bool = false;\nfn filtered_channel(index: u32, c: u32) -> f32 {\n    return 0.0;\n}\n".to_string(),
    }
}

/// `rounded` and `mul` (the shading helpers' names, for `surface.wgsl` and the texture
/// kernels) over the ray kernels' `opaque` and `mul_exact` and the frame's always-zero
/// word, for the ray stages that do not include the shading helpers (`shadow_rays`,
/// `bounce_trace`); after [`ray_wgsl`], in a stage that binds `params: FrameParams`.
pub(crate) const EXACT_PRODUCTS: &str = "fn rounded(x: f32) -> f32 {\n    return opaque(x, params.zero);\n}\n\nfn mul(a: f32, b: f32) -> f32 {\n    return mul_exact(a, b, params.zero);\n}\n";

/// The constants of `shaders/bounce.wgsl` from their Rust values, then the file: after
/// the generated records, `ray.wgsl` and the shading helpers.
pub(crate) fn bounce_wgsl() -> String {
    format!(
        "// Generated from hyrt_core::kernels::bounce (gpu-backend/src/secondary_rays.rs).\nconst IOR_OUTSIDE: f32 = {};\nconst MIN_THROUGHPUT: f32 = {};\n{}",
        f32_literal(IOR_OUTSIDE),
        f32_literal(MIN_THROUGHPUT),
        include_str!("shaders/bounce.wgsl")
    )
}

/// The WGSL of a stage that gathers what bouncing surfaces' lobes see: the shading
/// stages' sources ([`surface_shading_source`]), `ray.wgsl`, `bounce.wgsl`,
/// `bounce_radiance.wgsl`, then `stage`.
pub(crate) fn radiance_source(stage: &str) -> String {
    radiance_source_for(stage, None)
}

/// [`radiance_source`] with the denoised visibility bound at `visibility`
/// ([`surface_shading_source_for`]).
pub(crate) fn radiance_source_for(stage: &str, visibility: Option<u32>) -> String {
    surface_shading_source_for(
        &format!("{}\n{}\n{}\n{stage}", ray_wgsl(), bounce_wgsl(), include_str!("shaders/bounce_radiance.wgsl")),
        visibility,
    )
}

/// The constants of `shaders/lat_long.wgsl` (the portable atan2 in turns and the
/// lat-long lookup of [`hyrt_core::kernels::environment`], without a binding) from their
/// Rust values, then the file: in every stage that reads the environment or the ambient
/// light ([`surface_shading_source`]), once.
pub fn lat_long_wgsl() -> String {
    let series: Vec<String> = ATAN_SERIES.iter().map(|&c| f32_literal(c)).collect();
    let mut s = String::from("// Generated from hyrt_core::kernels::environment (gpu-backend/src/shader.rs).\n");
    s += &format!("const ATAN_SERIES = array<f32, {}>({});\n", ATAN_SERIES.len(), series.join(", "));
    s += &format!("const TAN_PI_8: f32 = {};\n", f32_literal(TAN_PI_8));
    s += &format!("const INV_TWO_PI: f32 = {};\n", f32_literal(INV_TWO_PI));
    s + include_str!("shaders/lat_long.wgsl")
}

/// The constants of `shaders/environment.wgsl` from their Rust values, then the file:
/// after [`lat_long_wgsl`] (which [`surface_shading_source`] includes).
pub(crate) fn environment_wgsl() -> String {
    let vec3 = |name: &str, v: [f32; 3]| {
        format!(
            "const {name}: vec3<f32> = vec3<f32>({}, {}, {});\n",
            f32_literal(v[0]),
            f32_literal(v[1]),
            f32_literal(v[2])
        )
    };
    let mut s = String::from("// Generated from hyrt_core::kernels::bounce (gpu-backend/src/shader.rs).\n");
    s += &vec3("SKY_ZENITH", SKY_ZENITH);
    s += &vec3("SKY_HORIZON", SKY_HORIZON);
    s += &vec3("SKY_GROUND", SKY_GROUND);
    s + include_str!("shaders/environment.wgsl")
}

// `ambient_light.wgsl` writes out the irradiance's nine terms (`sh9_basis`).
const _: () = assert!(SH9_TERMS == 9);

/// The constants of `shaders/ambient_light.wgsl` (the layout of
/// [`hyrt_core::kernels::ibl::AmbientLight::texels`]) from their Rust values, then the file:
/// after [`lat_long_wgsl`].
pub fn ambient_light_wgsl() -> String {
    let u = |name: &str, x: usize| format!("const {name}: u32 = {x}u;\n");
    let mut s = String::from("// Generated from hyrt_core::kernels::ibl (gpu-backend/src/shader.rs).\n");
    s += &u("SH9_TERMS", SH9_TERMS);
    s += &u("AMBIENT_TEXELS_SPLIT_SUM", AMBIENT_TEXELS_SPLIT_SUM);
    s += &u("SPLIT_SUM_SIZE", SPLIT_SUM_SIZE);
    s += &u("PREFILTER_LEVELS", PREFILTER_LEVELS);
    s += &u("PREFILTER_BASE_WIDTH", PREFILTER_BASE.0 as usize);
    s += &u("PREFILTER_BASE_HEIGHT", PREFILTER_BASE.1 as usize);
    let offsets: Vec<String> = (0..=PREFILTER_LEVELS).map(|k| format!("{}u", prefiltered_offset(k))).collect();
    s += &format!("const PREFILTERED_OFFSET = array<u32, {}>({});\n", offsets.len(), offsets.join(", "));
    s + include_str!("shaders/ambient_light.wgsl")
}

// `sampling.wgsl`'s `sin_cos_quarter` runs six Horner terms of each series.
const _: () = assert!(SIN_SERIES.len() == 6 && COS_SERIES.len() == 6);

/// The constants of `shaders/sampling.wgsl` (the mirrors of
/// [`hyrt_core::kernels::sampling`]: the sample sequence and its warps) from their Rust
/// values, then the file: in a stage that begins with [`preamble`] and defines
/// `rounded` and `mul` (the shading helpers, or the ray stages' `EXACT_PRODUCTS`), before
/// [`area_light_wgsl`] and [`occlusion_wgsl`].
pub fn sampling_wgsl() -> String {
    let array = |name: &str, xs: &[f32]| {
        let items: Vec<String> = xs.iter().map(|&x| f32_literal(x)).collect();
        format!("const {name} = array<f32, {}>({});\n", xs.len(), items.join(", "))
    };
    let mut s = String::from("// Generated from hyrt_core::kernels::sampling (gpu-backend/src/shader.rs).\n");
    s += &array("SIN_SERIES", &SIN_SERIES);
    s += &array("COS_SERIES", &COS_SERIES);
    s += &format!("const FRAC_PI_4: f32 = {};\n", f32_literal(std::f32::consts::FRAC_PI_4));
    s + include_str!("shaders/sampling.wgsl")
}

/// The constants of `shaders/area_light.wgsl` (the mirrors of
/// [`hyrt_core::kernels::area_light`]'s samplers) from their Rust values, then the file:
/// after [`sampling_wgsl`], in a stage that binds `params: FrameParams`.
pub fn area_light_wgsl() -> String {
    let mut s = String::from("// Generated from hyrt_core::kernels::area_light (gpu-backend/src/shader.rs).\n");
    s += &format!("const MIN_AREA_LIGHT_DISTANCE_SQ: f32 = {};\n", f32_literal(MIN_AREA_LIGHT_DISTANCE_SQ));
    s += &format!("const TAU: f32 = {};\n", f32_literal(std::f32::consts::TAU));
    s + include_str!("shaders/area_light.wgsl")
}

/// The constant of `shaders/occlusion.wgsl` (the mirrors of
/// [`hyrt_core::kernels::occlusion`]) from its Rust value, then the file: after
/// [`sampling_wgsl`].
pub fn occlusion_wgsl() -> String {
    format!(
        "// Generated from hyrt_core::kernels::occlusion (gpu-backend/src/shader.rs).\nconst AO_STREAM: u32 = {AO_STREAM:#010x}u;\n{}",
        include_str!("shaders/occlusion.wgsl")
    )
}

/// The soft-shadow kernels (`shaders/soft_shadow.wgsl`, mirrors of
/// [`hyrt_core::kernels::soft_shadow`]: the sample streams and the samples a mask slot
/// stands for) after what they build on: [`sampling_wgsl`], [`area_light_wgsl`],
/// [`occlusion_wgsl`], the area lights' kinds (from their Rust values: the generated
/// declarations name the other lights' only) and the [`SlotParams`] declaration. For the
/// stages that make or read stochastic rays (`compaction`, the shading stages), once;
/// after [`preamble`] and the shading helpers, in a stage that binds `params`, `lights`
/// and `ambient_light` (and `slot_params` where it reads the mask).
pub fn soft_shadow_wgsl() -> String {
    let mut s = format!("{}\n{}\n{}\n", sampling_wgsl(), area_light_wgsl(), occlusion_wgsl());
    s += "// Generated from hyrt_core::formats (gpu-backend/src/shader.rs).\n";
    for (name, kind) in [("LIGHT_QUAD", LIGHT_QUAD), ("LIGHT_SPHERE", LIGHT_SPHERE), ("LIGHT_SUN", LIGHT_SUN)] {
        s += &format!("const {name}: u32 = {kind}u;\n");
    }
    s + &slot_params_wgsl() + include_str!("shaders/soft_shadow.wgsl")
}

/// The WGSL declaration of [`SlotParams`], the uniform of a frame's mask slots: for a stage
/// that reads the mask without [`soft_shadow_wgsl`] (`shadow_rays`).
pub fn slot_params_wgsl() -> String {
    use hyrt_core::formats::wgsl::WgslStruct;
    SlotParams::declaration().replace("// hyrt_core: SlotParams", "// hyrt_gpu::buffers::SlotParams")
}

/// The surface kernels (`shaders/surface.wgsl`) after `ONE_PLUS_GAMMA_3`; they also
/// read `GAMMA_2` and `GAMMA_3`, which the including stage defines (exact f32 values).
pub(crate) fn surface_wgsl() -> String {
    format!("const ONE_PLUS_GAMMA_3: f32 = {:?};\n{}", 1.0f32 + gamma(3), include_str!("shaders/surface.wgsl"))
}

// ---------------------------------------------------------------------------------------------
// Only exact operations
// ---------------------------------------------------------------------------------------------

/// The functions that may use the device's own `/` and `sqrt`: the exact helpers' float
/// estimates, which their integer correction makes exact (`shaders/exact.wgsl`).
pub const EXACT_ESTIMATE_FUNCTIONS: [&str; 2] = ["div_rn_skewed", "sqrt_rn_skewed"];

/// The WGSL builtins a shader may not call: their precision is the device's (Vulkan's
/// precision appendix and WGSL's "Floating Point Accuracy" allow ulps of error, or a
/// fused multiply-add, for each), so they would not give the CPU reference's bits.
/// Square roots and what is built on them go through `sqrt_rn`, divisions through
/// `div_rn`, dot products through `dot3` (each product rounded apart).
const INEXACT_BUILTINS: [naga::MathFunction; 27] = {
    use naga::MathFunction as M;
    [
        M::Sqrt,
        M::InverseSqrt,
        M::Normalize,
        M::Length,
        M::Distance,
        M::Pow,
        M::Exp,
        M::Exp2,
        M::Log,
        M::Log2,
        M::Fma,
        M::Dot,
        M::Cross,
        M::Mix,
        M::SmoothStep,
        M::FaceForward,
        M::Reflect,
        M::Refract,
        M::Sin,
        M::Cos,
        M::Tan,
        M::Asin,
        M::Acos,
        M::Atan,
        M::Atan2,
        M::Determinant,
        M::Inverse,
    ]
};

/// Every use of an operation whose rounding is the device's in a WGSL module: a float
/// division or remainder, or a builtin of `INEXACT_BUILTINS`, outside
/// [`EXACT_ESTIMATE_FUNCTIONS`]. One line per use, naming the function; empty when the
/// module computes only with correctly rounded operations (`+`, `-`, `*`, conversions,
/// comparisons, integer and bit operations) and the helpers. An error when the source
/// does not parse or validate.
pub fn inexact_operations(source: &str) -> Result<Vec<String>, String> {
    use naga::{BinaryOperator, Expression, ScalarKind};
    let module = naga::front::wgsl::parse_str(source).map_err(|e| e.emit_to_string(source))?;
    let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
        .validate(&module)
        .map_err(|e| e.emit_to_string(source))?;
    let mut found = Vec::new();
    let mut check = |name: &str, function: &naga::Function, finfo: &naga::valid::FunctionInfo| {
        if EXACT_ESTIMATE_FUNCTIONS.contains(&name) {
            return;
        }
        for (_, expression) in function.expressions.iter() {
            match expression {
                Expression::Binary { op: op @ (BinaryOperator::Divide | BinaryOperator::Modulo), left, .. } => {
                    let ty = finfo[*left].ty.inner_with(&module.types);
                    if ty.scalar_kind() == Some(ScalarKind::Float) {
                        found.push(format!("{name}: float {op:?} (use div_rn)"));
                    }
                }
                Expression::Math { fun, .. } if INEXACT_BUILTINS.contains(fun) => {
                    found.push(format!("{name}: {fun:?} (use sqrt_rn, div_rn or the written-out kernels)"));
                }
                _ => {}
            }
        }
    };
    for (handle, function) in module.functions.iter() {
        check(function.name.as_deref().unwrap_or("?"), function, &info[handle]);
    }
    for (i, entry) in module.entry_points.iter().enumerate() {
        check(&entry.name, &entry.function, info.get_entry_point(i));
    }
    Ok(found)
}

/// The shader module of a stage's WGSL. In debug builds (every test run) each distinct
/// source is first checked by [`inexact_operations`] and refused with a panic that names
/// the offending functions: a stage that divides or takes a root with the device's own
/// operations would differ from the CPU reference on real GPUs, though not on lavapipe.
pub fn shader_module(ctx: &GpuContext, label: &str, source: &str) -> wgpu::ShaderModule {
    if cfg!(debug_assertions) {
        use std::collections::HashSet;
        use std::sync::Mutex;
        static CHECKED: Mutex<Option<HashSet<u64>>> = Mutex::new(None);
        let key = {
            use std::hash::{Hash, Hasher};
            let mut h = std::collections::hash_map::DefaultHasher::new();
            source.hash(&mut h);
            h.finish()
        };
        let fresh = CHECKED.lock().unwrap_or_else(|e| e.into_inner()).get_or_insert_with(HashSet::new).insert(key);
        if fresh {
            match inexact_operations(source) {
                Ok(found) if found.is_empty() => {}
                Ok(found) => {
                    panic!("shader {label} uses operations the device rounds its own way:\n{}", found.join("\n"))
                }
                Err(e) => panic!("shader {label} does not parse: {e}"),
            }
        }
    }
    ctx.device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

// ---------------------------------------------------------------------------------------------
// Pipelines, bindings, dispatches
// ---------------------------------------------------------------------------------------------

/// A compute-visible storage buffer binding.
pub fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A compute-visible uniform buffer binding.
pub fn uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

pub(crate) fn dynamic_uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: true,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A bind group layout and the compute pipeline (`main`) of `source` over it.
pub fn compute_pipeline(
    ctx: &GpuContext,
    label: &str,
    source: &str,
    entries: &[wgpu::BindGroupLayoutEntry],
) -> (wgpu::ComputePipeline, wgpu::BindGroupLayout) {
    specialized_pipeline(ctx, label, source, entries, &[])
}

/// [`compute_pipeline`] with values for pipeline-overridable `constants` of `source`
/// (`crate::texture::Specialization::constants`).
pub fn specialized_pipeline(
    ctx: &GpuContext,
    label: &str,
    source: &str,
    entries: &[wgpu::BindGroupLayoutEntry],
    constants: &[(&str, f64)],
) -> (wgpu::ComputePipeline, wgpu::BindGroupLayout) {
    let device = &ctx.device;
    let module = shader_module(ctx, label, source);
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries });
    (main_pipeline(ctx, label, &module, &layout, constants), layout)
}

/// The compute pipeline of entry point `main` of `module` over one bind group layout, with
/// values for its pipeline-overridable `constants`.
pub(crate) fn main_pipeline(
    ctx: &GpuContext,
    label: &str,
    module: &wgpu::ShaderModule,
    layout: &wgpu::BindGroupLayout,
    constants: &[(&str, f64)],
) -> wgpu::ComputePipeline {
    let pipeline_layout = ctx.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    ctx.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        module,
        entry_point: Some("main"),
        compilation_options: wgpu::PipelineCompilationOptions { constants, ..Default::default() },
        cache: None,
    })
}

/// A bind group of whole buffers at bindings 0, 1, 2, ...
pub fn bind_buffers(
    ctx: &GpuContext,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
        .collect();
    ctx.device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(label), layout, entries: &entries })
}

/// One compute pass that runs `pipeline` once per pixel of a `width` x `height`
/// image (8 x 8 workgroups; the shader skips the invocations past the edges), with
/// the stage's timestamps when `timing` is `Some((set, i))`: index `i` at the
/// start of the pass, `i + 1` at its end.
///
/// The grid is `ceil(width / 8)` x `ceil(height / 8)` workgroups, within the
/// 65,535-per-dimension limit up to 524,280 pixels per side.
pub(crate) fn encode_pixel_pass(
    encoder: &mut wgpu::CommandEncoder,
    label: &str,
    pipeline: &wgpu::ComputePipeline,
    bind_group: &wgpu::BindGroup,
    width: u32,
    height: u32,
    timing: Option<(&wgpu::QuerySet, u32)>,
) {
    let mut pass = crate::timing::begin_timed_pass(encoder, label, timing);
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, bind_group, &[]);
    pass.dispatch_workgroups(width.div_ceil(TILE), height.div_ceil(TILE), 1);
}

/// One compute pass that runs `pipeline` once per entry of a list, in workgroups of
/// [`SHADOW_RAYS_WORKGROUP_SIZE`](crate::shadow_rays::SHADOW_RAYS_WORKGROUP_SIZE), from
/// the indirect-dispatch arguments in `count` (`[count, x, y, 1]`, written by the scan
/// that built the list), with the stage's timestamps as [`encode_pixel_pass`].
pub(crate) fn encode_list_pass(
    encoder: &mut wgpu::CommandEncoder,
    label: &str,
    pipeline: &wgpu::ComputePipeline,
    bind_group: &wgpu::BindGroup,
    count: &wgpu::Buffer,
    timing: Option<(&wgpu::QuerySet, u32)>,
) {
    let mut pass = crate::timing::begin_timed_pass(encoder, label, timing);
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, bind_group, &[]);
    pass.dispatch_workgroups_indirect(count, 4);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sample sequence, area-light and occlusion mirrors parse, validate and use only
    /// exact operations in both kinds of stage they are written for: after the shading
    /// helpers (the shading stages) and after the ray stages' `EXACT_PRODUCTS`.
    #[test]
    fn sampling_modules_fit_shading_and_ray_stages() {
        let modules = format!("{}\n{}\n{}", sampling_wgsl(), area_light_wgsl(), occlusion_wgsl());
        let params = "@group(0) @binding(0) var<uniform> params: FrameParams;\n";
        let shading = shading_source(&format!("{params}{modules}"));
        let ray = format!("{}{}{params}{EXACT_PRODUCTS}\n{modules}", preamble(), ray_wgsl());
        for (kind, source) in [("shading", shading), ("ray", ray)] {
            assert_eq!(inexact_operations(&source), Ok(Vec::new()), "in a {kind} stage");
        }
    }

    /// The stages that make or read stochastic rays parse, validate and use only exact
    /// operations with the soft-shadow kernels in (`shader_module` checks this in debug
    /// builds alone; this runs in every build).
    #[test]
    fn soft_shadow_stages_use_only_exact_operations() {
        let surface_stage = |bindings: &str| {
            surface_shading_source(&format!("{bindings}\n{}", include_str!("shaders/primary_object.wgsl")))
        };
        let sources = [
            ("compaction", crate::compaction::compaction_wgsl()),
            ("raster_shading", surface_stage(include_str!("shaders/raster_shading.wgsl"))),
            (
                "rt_shading",
                surface_stage(&format!(
                    "{}\nfn rt_pixel(pixel: u32, s: SurfaceRecord) -> vec3<f32> {{ return shade_rt_pixel(pixel, s, primary_object(pixel, s), camera.eye); }}",
                    include_str!("shaders/rt_shading.wgsl")
                )),
            ),
            (
                "bounce_shading",
                radiance_source(&format!("{}\n{}", environment_wgsl(), include_str!("shaders/bounce_shading.wgsl"))),
            ),
        ];
        for (stage, source) in sources {
            assert_eq!(inexact_operations(&source), Ok(Vec::new()), "{stage}");
        }
    }
}
