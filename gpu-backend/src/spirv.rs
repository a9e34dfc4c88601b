//! How the stages' shaders reach the driver (issue 39, item 3).
//!
//! WGSL lets an implementation contract and reassociate float operations and has no way
//! to say otherwise; SPIR-V has: the `NoContraction` decoration on an arithmetic
//! instruction forbids fusing it with another (Vulkan's "Precision and Operation of
//! SPIR-V Instructions"), and the float-controls execution modes (`RoundingModeRTE`,
//! `DenormPreserve`, `SignedZeroInfNanPreserve`, SPIR-V 1.4 / `VK_KHR_shader_float_controls`)
//! make round to nearest even, kept subnormals and IEEE zeros, infinities and NaNs the
//! shader's contract instead of the driver's choice.
//!
//! So where the adapter offers wgpu's `PASSTHROUGH_SHADERS` on Vulkan
//! ([`ShaderDelivery::for_adapter`]), hyrt writes each entry point's SPIR-V itself
//! ([`write_entry`]): naga's SPIR-V writer with the options wgpu's Vulkan backend uses,
//! pipeline-overridable constants resolved first (a passthrough module has none left for
//! the pipeline to set), then [`patch`]ed: every float arithmetic instruction decorated
//! `NoContraction`, and the execution modes the device reports for 32-bit floats declared
//! on the entry point. Elsewhere the WGSL goes to wgpu as it is
//! ([`ShaderDelivery::Wgsl`]), and [`crate::exact::FloatProbe::missing`] names "no
//! contraction" as a guarantee the shaders do not have.
//!
//! A passthrough module carries no reflection, so a pipeline over it cannot derive its
//! layout: [`derived_layout_entries`] derives the bind group layouts from naga's IR as
//! wgpu does for `layout: None`, and the stages use them on both deliveries.

use std::collections::BTreeMap;

/// The float-controls execution modes a device supports for 32-bit floats
/// (`VkPhysicalDeviceFloatControlsProperties`), usable as declared alone (the device's
/// independence properties allow a 32-bit mode without the same mode for 16- and 64-bit
/// floats).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FloatControls {
    /// `RoundingModeRTE`: round to nearest even, by contract.
    pub rounding_mode_rte: bool,
    /// `DenormPreserve`: subnormal operands and results kept, not flushed to zero.
    pub denorm_preserve: bool,
    /// `SignedZeroInfNanPreserve`: no optimization that assumes no signed zero, infinity
    /// or NaN.
    pub signed_zero_inf_nan_preserve: bool,
}

impl FloatControls {
    /// Every mode: what a device that offers them all is given, and what the debug build's
    /// check of the SPIR-V path writes ([`crate::shader::StageModule::entry`]).
    pub const ALL: FloatControls =
        FloatControls { rounding_mode_rte: true, denorm_preserve: true, signed_zero_inf_nan_preserve: true };

    /// The declared modes by their SPIR-V names, in declaration order.
    pub fn names(&self) -> Vec<String> {
        self.modes().iter().map(|(mode, _)| format!("{mode:?}")).collect()
    }

    /// The execution modes and the capabilities that declare them.
    fn modes(&self) -> Vec<(spirv::ExecutionMode, spirv::Capability)> {
        use spirv::{Capability as C, ExecutionMode as M};
        let mut v = Vec::new();
        if self.rounding_mode_rte {
            v.push((M::RoundingModeRTE, C::RoundingModeRTE));
        }
        if self.denorm_preserve {
            v.push((M::DenormPreserve, C::DenormPreserve));
        }
        if self.signed_zero_inf_nan_preserve {
            v.push((M::SignedZeroInfNanPreserve, C::SignedZeroInfNanPreserve));
        }
        v
    }
}

/// What the device's robustness features guarantee of out-of-bounds accesses and of
/// workgroup memory, as wgpu's Vulkan backend finds and enables them: where they hold,
/// the shaders need no bounds checks or zeroing of their own (wgpu writes none).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Robustness {
    /// `robustBufferAccess2` (`VK_EXT_robustness2`): buffer accesses out of bounds read
    /// zero and write nothing.
    pub buffers: bool,
    /// `robustImageAccess2`, or else `robustImageAccess` (Vulkan 1.3,
    /// `VK_EXT_image_robustness`): image loads out of bounds are defined.
    pub images: bool,
    /// `shaderZeroInitializeWorkgroupMemory` (Vulkan 1.3,
    /// `VK_KHR_zero_initialize_workgroup_memory`): the driver zeroes workgroup memory, so
    /// the shaders declare it zeroed instead of writing the zeros themselves.
    pub zeroed_workgroup_memory: bool,
}

/// How a context's shaders reach the driver ([`crate::GpuContext::shader_delivery`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShaderDelivery {
    /// WGSL given to wgpu, which translates it with naga: the driver may contract
    /// products into sums (the shaders guard the products whose rounding matters, and
    /// the float probe checks that guard).
    Wgsl,
    /// SPIR-V written by hyrt ([`write_entry`]) and given to the driver through wgpu's
    /// passthrough: every float operation `NoContraction`, and `float_controls` declared.
    Spirv {
        /// The SPIR-V version written: the highest the device's Vulkan version accepts
        /// (as wgpu chooses it).
        lang_version: (u8, u8),
        /// The execution modes declared on every entry point.
        float_controls: FloatControls,
        /// Which bounds checks the shaders leave to the device.
        robustness: Robustness,
    },
}

/// The Vulkan versions' encodings (`VK_MAKE_API_VERSION(0, 1, minor, 0)`).
const fn vulkan_1(minor: u32) -> u32 {
    (1 << 22) | (minor << 12)
}

impl ShaderDelivery {
    /// What a device created with `features` on `adapter` gets: [`ShaderDelivery::Spirv`]
    /// where it is a Vulkan device with `PASSTHROUGH_SHADERS`, with the float controls
    /// its Vulkan 1.2 properties report; else [`ShaderDelivery::Wgsl`].
    pub fn for_adapter(adapter: &wgpu::Adapter, features: wgpu::Features) -> ShaderDelivery {
        if !features.contains(wgpu::Features::PASSTHROUGH_SHADERS)
            || adapter.get_info().backend != wgpu::Backend::Vulkan
        {
            return ShaderDelivery::Wgsl;
        }
        // SAFETY: the adapter is only read: its Vulkan physical device's properties,
        // through the instance wgpu created it on, which outlives the guard.
        let Some(hal) = (unsafe { adapter.as_hal::<wgpu::hal::api::Vulkan>() }) else {
            return ShaderDelivery::Wgsl;
        };
        let api = hal.physical_device_capabilities().properties().api_version;
        // As wgpu's Vulkan backend chooses it (Vulkan's "SPIR-V Environment" appendix).
        let lang_version = match api {
            v if v >= vulkan_1(3) => (1, 6),
            v if v >= vulkan_1(2) => (1, 5),
            v if v >= vulkan_1(1) => (1, 3),
            _ => (1, 0),
        };
        let shared = hal.shared_instance();
        let float_controls = if api >= vulkan_1(2) && shared.instance_api_version() >= vulkan_1(1) {
            let mut fc = ash::vk::PhysicalDeviceFloatControlsProperties::default();
            let mut properties = ash::vk::PhysicalDeviceProperties2::default().push_next(&mut fc);
            // SAFETY: a query into structures this function owns, on the physical device
            // of the instance it came from (Vulkan 1.1 entry point, instance >= 1.1).
            unsafe {
                shared.raw_instance().get_physical_device_properties2(hal.raw_physical_device(), &mut properties)
            };
            float_controls_of(&fc)
        } else {
            FloatControls::default()
        };
        let robustness = robustness_of(&hal, api);
        ShaderDelivery::Spirv { lang_version, float_controls, robustness }
    }

    /// Whether every float operation reaches the driver decorated `NoContraction`.
    pub fn no_contraction(&self) -> bool {
        matches!(self, ShaderDelivery::Spirv { .. })
    }

    /// One phrase for [`crate::GpuContext::describe`] and the report's header.
    pub fn describe(&self) -> String {
        match self {
            ShaderDelivery::Wgsl => "shaders as WGSL through wgpu (no passthrough: the driver may contract)".into(),
            ShaderDelivery::Spirv { lang_version: (major, minor), float_controls, robustness } => {
                let modes = float_controls.names();
                let modes = if modes.is_empty() {
                    ", no float-controls mode offered".into()
                } else {
                    format!(", {}", modes.join(", "))
                };
                let checked: Vec<&str> = [(!robustness.buffers, "buffers"), (!robustness.images, "image loads")]
                    .into_iter()
                    .filter_map(|(checked, what)| checked.then_some(what))
                    .collect();
                let checks = if checked.is_empty() {
                    "bounds left to the device's robustness".to_string()
                } else {
                    format!("bounds checked in the shader on {}", checked.join(" and "))
                };
                format!("shaders as SPIR-V {major}.{minor} through passthrough, every float operation NoContraction{modes}, {checks}")
            }
        }
    }
}

/// The robustness wgpu's Vulkan backend enables on a device of this adapter (it turns on
/// `VK_EXT_robustness2` and image robustness wherever the adapter has them).
fn robustness_of(hal: &wgpu::hal::vulkan::Adapter, api: u32) -> Robustness {
    let capabilities = hal.physical_device_capabilities();
    let shared = hal.shared_instance();
    if shared.instance_api_version() < vulkan_1(1) {
        return Robustness::default();
    }
    let robustness2 = capabilities.supports_extension(ash::ext::robustness2::NAME);
    let image_robustness = api >= vulkan_1(3) || capabilities.supports_extension(ash::ext::image_robustness::NAME);
    let zero_init =
        api >= vulkan_1(3) || capabilities.supports_extension(ash::khr::zero_initialize_workgroup_memory::NAME);
    let mut r2 = ash::vk::PhysicalDeviceRobustness2FeaturesEXT::default();
    let mut images = ash::vk::PhysicalDeviceImageRobustnessFeatures::default();
    let mut zeroed = ash::vk::PhysicalDeviceZeroInitializeWorkgroupMemoryFeatures::default();
    let mut features = ash::vk::PhysicalDeviceFeatures2::default();
    if robustness2 {
        features = features.push_next(&mut r2);
    }
    if image_robustness {
        features = features.push_next(&mut images);
    }
    if zero_init {
        features = features.push_next(&mut zeroed);
    }
    // SAFETY: a query into structures this function owns, each chained only where the
    // device has its extension, on the physical device of the instance it came from.
    unsafe { shared.raw_instance().get_physical_device_features2(hal.raw_physical_device(), &mut features) };
    Robustness {
        buffers: robustness2 && r2.robust_buffer_access2 != 0,
        images: if robustness2 {
            r2.robust_image_access2 != 0
        } else {
            image_robustness && images.robust_image_access != 0
        },
        zeroed_workgroup_memory: zero_init && zeroed.shader_zero_initialize_workgroup_memory != 0,
    }
}

/// The 32-bit modes of `fc` that may be declared alone: a mode whose independence
/// property is `NONE` would have to be declared for every width (VUIDs
/// `RuntimeSpirv-denormBehaviorIndependence-06289/06290` and
/// `RuntimeSpirv-roundingModeIndependence-06291/06292`), so it is left out there.
fn float_controls_of(fc: &ash::vk::PhysicalDeviceFloatControlsProperties) -> FloatControls {
    use ash::vk::ShaderFloatControlsIndependence as I;
    let alone = |independence: I| independence == I::ALL || independence == I::TYPE_32_ONLY;
    FloatControls {
        rounding_mode_rte: fc.shader_rounding_mode_rte_float32 != 0 && alone(fc.rounding_mode_independence),
        denorm_preserve: fc.shader_denorm_preserve_float32 != 0 && alone(fc.denorm_behavior_independence),
        // Not governed by the independence properties.
        signed_zero_inf_nan_preserve: fc.shader_signed_zero_inf_nan_preserve_float32 != 0,
    }
}

/// What an entry point's SPIR-V is written for: the SPIR-V version, the execution modes
/// to declare, and the pipeline layout's binding numbers per group (increasing), whose
/// ranks are the Vulkan bindings wgpu gives them.
pub struct EntryTarget<'a> {
    pub lang_version: (u8, u8),
    pub float_controls: FloatControls,
    pub robustness: Robustness,
    pub bindings: &'a [Vec<u32>],
}

/// The SPIR-V of entry point `entry` (`stage`) of a validated module, with the
/// pipeline-overridable `constants` resolved, written with the options wgpu's Vulkan
/// backend writes with (bounds checks by clamping, and workgroup memory zeroed by the
/// shader, where the device's [`Robustness`] does not make them needless; loops bounded;
/// each WGSL binding at the Vulkan binding of its rank in its group) and [`patch`]ed for the target's float controls. An error names a binding the entry
/// point uses that the layout lacks.
pub fn write_entry(
    module: &naga::Module,
    info: &naga::valid::ModuleInfo,
    entry: &str,
    stage: naga::ShaderStage,
    constants: &[(&str, f64)],
    target: &EntryTarget,
) -> Result<Vec<u32>, String> {
    use naga::back::spv;
    let constants: naga::back::PipelineConstants = constants.iter().map(|(k, v)| (k.to_string(), *v)).collect();
    let (module, info) =
        naga::back::pipeline_constants::process_overrides(module, info, Some((stage, entry)), &constants)
            .map_err(|e| format!("pipeline constants of {entry}: {e}"))?;
    let mut binding_map = BTreeMap::new();
    for (group, bindings) in target.bindings.iter().enumerate() {
        for (rank, &binding) in bindings.iter().enumerate() {
            binding_map.insert(
                naga::ResourceBinding { group: group as u32, binding },
                spv::BindingInfo { descriptor_set: group as u32, binding: rank as u32, binding_array_size: None },
            );
        }
    }
    use naga::proc::BoundsCheckPolicy::{Restrict, Unchecked};
    let checks = |left_to_device: bool| if left_to_device { Unchecked } else { Restrict };
    let options = spv::Options {
        lang_version: target.lang_version,
        // wgpu's flags on Vulkan (no Y flip or depth clamp in the shader: the viewport
        // and the pipeline do those).
        flags: spv::WriterFlags::LABEL_VARYINGS | spv::WriterFlags::FORCE_POINT_SIZE,
        fake_missing_bindings: false,
        binding_map,
        capabilities: None,
        bounds_check_policies: naga::proc::BoundsCheckPolicies {
            index: Restrict,
            buffer: checks(target.robustness.buffers),
            image_load: checks(target.robustness.images),
            binding_array: Unchecked,
        },
        zero_initialize_workgroup_memory: if target.robustness.zeroed_workgroup_memory {
            spv::ZeroInitializeWorkgroupMemoryMode::Native
        } else {
            spv::ZeroInitializeWorkgroupMemoryMode::Polyfill
        },
        force_loop_bounding: true,
        ray_query_initialization_tracking: true,
        trace_ray_argument_validation: true,
        use_storage_input_output_16: false,
        debug_info: None,
        task_dispatch_limits: None,
        mesh_shader_primitive_indices_clamp: true,
        emit_int_div_checks: true,
    };
    let pipeline = spv::PipelineOptions { shader_stage: stage, entry_point: entry.to_string() };
    let words =
        spv::write_vec(&module, &info, &options, Some(&pipeline)).map_err(|e| format!("SPIR-V of {entry}: {e}"))?;
    patch(&words, target.float_controls)
}

/// The float arithmetic instructions `NoContraction` is put on: everything that rounds a
/// sum or a product (negation and conversions are exact or alone; extended instructions
/// such as `Fma` are not used by the shaders, whose IR check refuses `fma`).
pub const FLOAT_ARITHMETIC: [spirv::Op; 13] = [
    spirv::Op::FAdd,
    spirv::Op::FSub,
    spirv::Op::FMul,
    spirv::Op::FDiv,
    spirv::Op::FRem,
    spirv::Op::FMod,
    spirv::Op::VectorTimesScalar,
    spirv::Op::MatrixTimesScalar,
    spirv::Op::VectorTimesMatrix,
    spirv::Op::MatrixTimesVector,
    spirv::Op::MatrixTimesMatrix,
    spirv::Op::OuterProduct,
    spirv::Op::Dot,
];

/// Words of a SPIR-V module's header (magic, version, generator, bound, schema).
const HEADER_WORDS: usize = 5;

/// One instruction's first word: its length in words and its opcode.
fn first_word(words: u32, op: spirv::Op) -> u32 {
    (words << 16) | op as u32
}

/// `words` (one SPIR-V module) with every result of a [`FLOAT_ARITHMETIC`] instruction
/// decorated `NoContraction`, and, on every entry point, the execution modes of
/// `float_controls` for 32-bit floats with their capabilities. The module must be
/// SPIR-V 1.4 or later where `float_controls` declares a mode (the modes are core
/// there). An error when the words are not a well-formed module.
pub fn patch(words: &[u32], float_controls: FloatControls) -> Result<Vec<u32>, String> {
    use spirv::Op;
    if words.len() < HEADER_WORDS || words[0] != spirv::MAGIC_NUMBER {
        return Err("not a SPIR-V module (no magic number)".into());
    }
    let modes = float_controls.modes();
    let version = (words[1] >> 16 & 0xff, words[1] >> 8 & 0xff);
    if !modes.is_empty() && version < (1, 4) {
        return Err(format!("float-controls modes need SPIR-V 1.4, the module is {}.{}", version.0, version.1));
    }
    let in_preamble = |op: Op| {
        matches!(
            op,
            Op::Capability
                | Op::Extension
                | Op::ExtInstImport
                | Op::MemoryModel
                | Op::EntryPoint
                | Op::ExecutionMode
                | Op::ExecutionModeId
        )
    };
    let in_debug_or_annotations = |op: Op| {
        matches!(
            op,
            Op::SourceContinued
                | Op::Source
                | Op::SourceExtension
                | Op::Name
                | Op::MemberName
                | Op::String
                | Op::ModuleProcessed
                | Op::Decorate
                | Op::MemberDecorate
                | Op::DecorationGroup
                | Op::GroupDecorate
                | Op::GroupMemberDecorate
                | Op::DecorateId
                | Op::DecorateString
                | Op::MemberDecorateString
        )
    };
    let mut float_results = Vec::new();
    let mut entry_points = Vec::new();
    // Where the execution modes end, and where the annotations end (the first type).
    let mut modes_end = None;
    let mut annotations_end = None;
    let mut i = HEADER_WORDS;
    while i < words.len() {
        let count = (words[i] >> 16) as usize;
        if count == 0 || i + count > words.len() {
            return Err(format!("malformed instruction at word {i}"));
        }
        let op = Op::from_u32(words[i] & 0xffff)
            .ok_or_else(|| format!("unknown opcode {} at word {i}", words[i] & 0xffff))?;
        if FLOAT_ARITHMETIC.contains(&op) {
            // Result type, then result id.
            float_results.push(words[i + 2]);
        }
        if op == Op::EntryPoint {
            entry_points.push(words[i + 2]);
        }
        if modes_end.is_none() && !in_preamble(op) {
            modes_end = Some(i);
        }
        if annotations_end.is_none() && !in_preamble(op) && !in_debug_or_annotations(op) {
            annotations_end = Some(i);
        }
        i += count;
    }
    let modes_end = modes_end.unwrap_or(words.len());
    let annotations_end = annotations_end.unwrap_or(words.len());

    let mut out = Vec::with_capacity(
        words.len() + 2 * modes.len() + 4 * modes.len() * entry_points.len() + 3 * float_results.len(),
    );
    out.extend_from_slice(&words[..HEADER_WORDS]);
    // Capabilities come first; the module's own follow.
    for (_, capability) in &modes {
        out.extend([first_word(2, Op::Capability), *capability as u32]);
    }
    out.extend_from_slice(&words[HEADER_WORDS..modes_end]);
    for &entry in &entry_points {
        for (mode, _) in &modes {
            out.extend([first_word(4, Op::ExecutionMode), entry, *mode as u32, 32]);
        }
    }
    out.extend_from_slice(&words[modes_end..annotations_end]);
    for &id in &float_results {
        out.extend([first_word(3, Op::Decorate), id, spirv::Decoration::NoContraction as u32]);
    }
    out.extend_from_slice(&words[annotations_end..]);
    Ok(out)
}

/// The bind group layouts' entries of a pipeline over `entries` (entry point name and
/// the stages that run it) of `module`, as wgpu derives them for `layout: None`: one
/// entry per global with a binding that one of the entry points uses, visible to the
/// stages that use it. Storage buffers are read-only where no entry point may write
/// them; float textures are filterable only where an entry point samples them with a
/// sampler. Groups come in order, from 0 to the highest used (a group no entry point
/// uses is empty).
pub fn derived_layout_entries(
    module: &naga::Module,
    info: &naga::valid::ModuleInfo,
    entries: &[(&str, wgpu::ShaderStages)],
) -> Result<Vec<Vec<wgpu::BindGroupLayoutEntry>>, String> {
    let mut groups: BTreeMap<u32, BTreeMap<u32, wgpu::BindGroupLayoutEntry>> = BTreeMap::new();
    for &(name, stages) in entries {
        let index =
            module.entry_points.iter().position(|e| e.name == name).ok_or_else(|| format!("no entry point {name}"))?;
        let function = info.get_entry_point(index);
        for (handle, global) in module.global_variables.iter() {
            let Some(binding) = &global.binding else { continue };
            if function[handle].is_empty() {
                continue;
            }
            let sampled = function.sampling_set.iter().any(|k| k.image == handle);
            let ty = binding_type(module, global, sampled).ok_or_else(|| {
                format!("{name}: the binding at group {} {} has no binding type", binding.group, binding.binding)
            })?;
            let entry =
                groups.entry(binding.group).or_default().entry(binding.binding).or_insert(wgpu::BindGroupLayoutEntry {
                    binding: binding.binding,
                    visibility: wgpu::ShaderStages::empty(),
                    ty,
                    count: None,
                });
            if entry.ty != ty {
                return Err(format!(
                    "group {} binding {} is declared twice, differently",
                    binding.group, binding.binding
                ));
            }
            entry.visibility |= stages;
        }
    }
    let last = groups.keys().next_back().map_or(0, |g| g + 1);
    Ok((0..last).map(|g| groups.get(&g).map(|b| b.values().copied().collect()).unwrap_or_default()).collect())
}

/// The binding type of a global, as wgpu derives it (`wgpu_core::validation`), but with
/// no minimum binding size (wgpu checks the bound sizes against the shader's where it
/// has the shader's reflection).
fn binding_type(module: &naga::Module, global: &naga::GlobalVariable, sampled: bool) -> Option<wgpu::BindingType> {
    use naga::{AddressSpace, ImageClass, ImageDimension, TypeInner};
    Some(match global.space {
        AddressSpace::Uniform => wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        AddressSpace::Storage { access } => wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: access == naga::StorageAccess::LOAD },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        AddressSpace::Handle => match module.types[global.ty].inner {
            TypeInner::Sampler { comparison } => wgpu::BindingType::Sampler(if comparison {
                wgpu::SamplerBindingType::Comparison
            } else {
                wgpu::SamplerBindingType::Filtering
            }),
            TypeInner::Image { dim, arrayed, class } => {
                let view_dimension = match (dim, arrayed) {
                    (ImageDimension::D1, _) => wgpu::TextureViewDimension::D1,
                    (ImageDimension::D2, true) => wgpu::TextureViewDimension::D2Array,
                    (ImageDimension::D2, false) => wgpu::TextureViewDimension::D2,
                    (ImageDimension::D3, _) => wgpu::TextureViewDimension::D3,
                    (ImageDimension::Cube, true) => wgpu::TextureViewDimension::CubeArray,
                    (ImageDimension::Cube, false) => wgpu::TextureViewDimension::Cube,
                };
                match class {
                    ImageClass::Sampled { kind, multi } => wgpu::BindingType::Texture {
                        sample_type: match kind {
                            naga::ScalarKind::Float => wgpu::TextureSampleType::Float { filterable: sampled },
                            naga::ScalarKind::Sint => wgpu::TextureSampleType::Sint,
                            naga::ScalarKind::Uint => wgpu::TextureSampleType::Uint,
                            _ => return None,
                        },
                        view_dimension,
                        multisampled: multi,
                    },
                    ImageClass::Depth { multi } => wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension,
                        multisampled: multi,
                    },
                    // Storage textures keep their declared format and access; hyrt's
                    // shaders declare none, so none is derived.
                    _ => return None,
                }
            }
            _ => return None,
        },
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const SOURCE: &str = r#"
override SCALE: f32 = 1.0;
@group(0) @binding(0) var<storage, read> input: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> output: array<f32>;
@group(1) @binding(0) var<uniform> unused_by_b: vec4<f32>;

@compute @workgroup_size(64)
fn a(@builtin(global_invocation_id) gid: vec3<u32>) {
    let v = input[gid.x];
    output[gid.x] = dot(v, v) + v.x * v.y * SCALE - v.z / v.w + (v * 2.0).x + unused_by_b.x;
}

@compute @workgroup_size(64)
fn b(@builtin(global_invocation_id) gid: vec3<u32>) {
    output[gid.x] = 1.0;
}
"#;

    fn parsed() -> (naga::Module, naga::valid::ModuleInfo) {
        let module = naga::front::wgsl::parse_str(SOURCE).unwrap();
        let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
            .validate(&module)
            .unwrap();
        (module, info)
    }

    /// The instructions of a module: (opcode, operands).
    fn instructions(words: &[u32]) -> Vec<(spirv::Op, Vec<u32>)> {
        let mut v = Vec::new();
        let mut i = HEADER_WORDS;
        while i < words.len() {
            let count = (words[i] >> 16) as usize;
            v.push((spirv::Op::from_u32(words[i] & 0xffff).unwrap(), words[i + 1..i + count].to_vec()));
            i += count;
        }
        v
    }

    /// The layout of `SOURCE`: group 0 with bindings 0 and 1, group 1 with binding 0.
    fn write(
        entry: &str,
        constants: &[(&str, f64)],
        lang_version: (u8, u8),
        float_controls: FloatControls,
    ) -> Result<Vec<u32>, String> {
        let (module, info) = parsed();
        let bindings = [vec![0, 1], vec![0]];
        let target =
            EntryTarget { lang_version, float_controls, robustness: Robustness::default(), bindings: &bindings };
        write_entry(&module, &info, entry, naga::ShaderStage::Compute, constants, &target)
    }

    #[test]
    fn every_float_operation_is_decorated_no_contraction_and_nothing_else() {
        let words = write("a", &[("SCALE", 3.0)], (1, 6), FloatControls::ALL).unwrap();
        let ins = instructions(&words);
        let float_results: Vec<u32> =
            ins.iter().filter(|(op, _)| FLOAT_ARITHMETIC.contains(op)).map(|(_, operands)| operands[1]).collect();
        let decorated: Vec<u32> = ins
            .iter()
            .filter(|(op, o)| *op == spirv::Op::Decorate && o[1] == spirv::Decoration::NoContraction as u32)
            .map(|(_, o)| o[0])
            .collect();
        // dot, two products, a quotient, a vector times scalar, and the sums.
        assert!(float_results.len() >= 7, "{float_results:?}");
        assert_eq!(decorated, float_results);
        // The override is resolved: no specialization constant is left.
        assert!(!ins.iter().any(|(op, _)| matches!(op, spirv::Op::SpecConstant | spirv::Op::SpecConstantTrue)));
        // Every instruction sits in its section: capabilities, then entry points, then
        // execution modes, then debug names and annotations, then the rest.
        let section = |op: spirv::Op| match op {
            spirv::Op::Capability => 0,
            spirv::Op::Extension | spirv::Op::ExtInstImport | spirv::Op::MemoryModel => 1,
            spirv::Op::EntryPoint => 2,
            spirv::Op::ExecutionMode | spirv::Op::ExecutionModeId => 3,
            spirv::Op::Source | spirv::Op::Name | spirv::Op::MemberName | spirv::Op::String => 4,
            spirv::Op::Decorate | spirv::Op::MemberDecorate => 5,
            _ => 6,
        };
        let sections: Vec<u32> = ins.iter().map(|(op, _)| section(*op)).collect();
        assert!(sections.windows(2).all(|w| w[0] <= w[1]), "{sections:?}");
    }

    #[test]
    fn the_device_modes_are_declared_on_the_entry_point_with_their_capabilities() {
        let words = write("b", &[], (1, 5), FloatControls::ALL).unwrap();
        let ins = instructions(&words);
        let entry = ins.iter().find(|(op, _)| *op == spirv::Op::EntryPoint).unwrap().1[1];
        assert_eq!(FloatControls::ALL.names(), ["RoundingModeRTE", "DenormPreserve", "SignedZeroInfNanPreserve"]);
        for (mode, capability) in FloatControls::ALL.modes() {
            assert!(ins.contains(&(spirv::Op::Capability, vec![capability as u32])), "{capability:?}");
            assert!(ins.contains(&(spirv::Op::ExecutionMode, vec![entry, mode as u32, 32])), "{mode:?}");
        }
        let none = write("b", &[], (1, 5), FloatControls::default()).unwrap();
        assert!(!instructions(&none).iter().any(|(op, o)| *op == spirv::Op::ExecutionMode && o.get(2) == Some(&32)));
        // Before SPIR-V 1.4 the modes are an extension's, which the patch does not add.
        assert!(write("b", &[], (1, 3), FloatControls::ALL).is_err());
        assert!(write("b", &[], (1, 3), FloatControls::default()).is_ok());
    }

    #[test]
    fn malformed_words_are_refused() {
        assert!(patch(&[1, 2, 3], FloatControls::default()).is_err());
        let mut words = write("b", &[], (1, 5), FloatControls::default()).unwrap();
        // An instruction that runs past the end.
        let mut cut = words.clone();
        cut.push(first_word(4, spirv::Op::Decorate));
        assert!(patch(&cut, FloatControls::default()).is_err());
        // An instruction of no words.
        words[HEADER_WORDS] &= 0xffff;
        assert!(patch(&words, FloatControls::default()).is_err());
    }

    #[test]
    fn bindings_are_numbered_by_rank_in_their_group_as_wgpu_numbers_them() {
        let source = "@group(0) @binding(3) var<storage, read> a: array<f32>;\n\
            @group(0) @binding(10) var<storage, read_write> b: array<f32>;\n\
            @compute @workgroup_size(1) fn main() { b[0] = a[0]; }";
        let module = naga::front::wgsl::parse_str(source).unwrap();
        let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
            .validate(&module)
            .unwrap();
        let write = |bindings: &[Vec<u32>]| {
            let target = EntryTarget {
                lang_version: (1, 5),
                float_controls: FloatControls::default(),
                robustness: Robustness::default(),
                bindings,
            };
            write_entry(&module, &info, "main", naga::ShaderStage::Compute, &[], &target)
        };
        let binding_decorations = |words: &[u32]| -> Vec<u32> {
            instructions(words)
                .iter()
                .filter(|(op, o)| *op == spirv::Op::Decorate && o[1] == spirv::Decoration::Binding as u32)
                .map(|(_, o)| o[2])
                .collect()
        };
        // A layout of bindings 0, 3, 7 and 10: 3 is the second, 10 the fourth.
        assert_eq!(binding_decorations(&write(&[vec![0, 3, 7, 10]]).unwrap()), [1, 3]);
        assert_eq!(binding_decorations(&write(&[vec![3, 10]]).unwrap()), [0, 1]);
        // A binding the layout lacks is an error, not a guess.
        assert!(write(&[vec![3]]).is_err());
    }

    #[test]
    fn layouts_are_derived_per_entry_point_as_wgpu_derives_them() {
        let (module, info) = parsed();
        let compute = wgpu::ShaderStages::COMPUTE;
        let a = derived_layout_entries(&module, &info, &[("a", compute)]).unwrap();
        assert_eq!(a.len(), 2);
        assert_eq!(a[0].len(), 2);
        assert_eq!(
            a[0][0].ty,
            wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: false,
                min_binding_size: None
            }
        );
        assert!(matches!(
            a[0][1].ty,
            wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only: false }, .. }
        ));
        assert!(matches!(a[1][0].ty, wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, .. }));
        // `b` writes the output alone: group 0 has binding 1 only, and no group 1.
        let b = derived_layout_entries(&module, &info, &[("b", compute)]).unwrap();
        assert_eq!(b.len(), 1);
        assert_eq!(b[0].iter().map(|e| e.binding).collect::<Vec<_>>(), [1]);
        assert!(derived_layout_entries(&module, &info, &[("c", compute)]).is_err());
    }
}
