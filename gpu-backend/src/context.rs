//! Adapter and device selection.

use crate::exact::FloatProbe;
use crate::shader::FloatOps;
use crate::spirv::ShaderDelivery;
use crate::GpuError;

/// Environment variable that allows a software adapter (Mesa lavapipe) when set to `1`.
pub const ALLOW_SOFTWARE_ENV: &str = "HYRT_GPU_ALLOW_SOFTWARE";

/// Which adapters [`GpuContext::new`] accepts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AdapterPolicy {
    /// A hardware GPU only (integrated, discrete or virtual).
    HardwareOnly,
    /// Hardware preferred; a software (CPU) adapter such as lavapipe is accepted.
    AllowSoftware,
}

impl AdapterPolicy {
    /// `AllowSoftware` when [`ALLOW_SOFTWARE_ENV`] is `1`, else `HardwareOnly`.
    pub fn from_env() -> Self {
        match std::env::var(ALLOW_SOFTWARE_ENV).as_deref() {
            Ok("1") => AdapterPolicy::AllowSoftware,
            _ => AdapterPolicy::HardwareOnly,
        }
    }
}

/// A device and queue plus what the adapter offers.
pub struct GpuContext {
    /// The adapter the device was created on (for a window surface's capabilities).
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    /// `@builtin(primitive_index)` is available (wgpu `PRIMITIVE_INDEX`); without it
    /// the raster pass uses flat-interpolated ids on unshared vertices.
    pub primitive_index: bool,
    /// GPU timestamp queries are available for per-stage timings.
    pub timestamps: bool,
    /// Fragment shaders may declare conservative depth (wgpu `SHADER_EARLY_DEPTH_TEST`):
    /// `visibility_raster` then keeps early depth tests while writing `frag_depth`.
    pub early_depth_test: bool,
    /// How the shaders of pipelines built on this context divide and take square roots:
    /// through the exact helpers (the default), or with the device's own operations to
    /// measure what the helpers cost ([`FloatOps::Device`]). Set it before building a
    /// backend on the context.
    pub float_ops: FloatOps,
    /// How the shaders reach the driver: hyrt's own SPIR-V with every float operation
    /// `NoContraction` and the device's float-controls modes, through wgpu's passthrough,
    /// where the device offers it; else WGSL through wgpu ([`ShaderDelivery`]). Set it
    /// (to [`ShaderDelivery::Wgsl`]) before building a backend on the context to compare.
    pub shader_delivery: ShaderDelivery,
    /// The start-up float check, run on the first [`GpuContext::float_probe`] call.
    probe: std::sync::OnceLock<Result<FloatProbe, GpuError>>,
}

impl std::fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuContext")
            .field("adapter", &self.info.name)
            .field("device_type", &self.info.device_type)
            .field("driver", &self.info.driver)
            .field("primitive_index", &self.primitive_index)
            .field("timestamps", &self.timestamps)
            .field("early_depth_test", &self.early_depth_test)
            .field("float_ops", &self.float_ops)
            .field("shader_delivery", &self.shader_delivery)
            .finish()
    }
}

/// True for adapters that run on the CPU (lavapipe, llvmpipe, SwiftShader).
pub fn is_software(info: &wgpu::AdapterInfo) -> bool {
    info.device_type == wgpu::DeviceType::Cpu
}

impl GpuContext {
    /// Pick a Vulkan adapter under `policy` and create a device with the features
    /// hyrt uses where the adapter has them (primitive index, timestamp queries).
    pub fn new(policy: AdapterPolicy) -> Result<GpuContext, GpuError> {
        Self::with_instance(&Self::vulkan_instance(None), None, policy)
    }

    /// The wgpu instance [`GpuContext::new`] picks its adapter from: Vulkan only, asked
    /// for explicitly (with default backends a missing Vulkan driver silently falls back
    /// to GL). An application that presents hyrt's frames to a window passes the
    /// window system's display, creates its surface on this instance and calls
    /// [`GpuContext::with_instance`] with it.
    pub fn vulkan_instance(display: Option<Box<dyn wgpu::wgt::WgpuHasDisplayHandle>>) -> wgpu::Instance {
        let mut descriptor = wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        };
        descriptor.display = display;
        wgpu::Instance::new(descriptor)
    }

    /// As [`GpuContext::new`], on the Vulkan adapters of `instance`
    /// ([`GpuContext::vulkan_instance`]); with `compatible_surface`, only adapters that
    /// can present to it (a window's surface: hyrt's frames then reach the screen
    /// without leaving the device, through [`crate::backend::GpuBackend::render_to_texture`]).
    pub fn with_instance(
        instance: &wgpu::Instance,
        compatible_surface: Option<&wgpu::Surface<'_>>,
        policy: AdapterPolicy,
    ) -> Result<GpuContext, GpuError> {
        Self::create(instance, compatible_surface, policy, None)
    }

    /// As [`GpuContext::new`], with storage bindings of at most `bytes` (or the adapter's
    /// own limit where that is lower), enforced by the device: a large device behaves as a
    /// small one. Tests use it to make lavapipe split what does not fit one binding (the
    /// raster's batches, frames in bands) on scenes small enough to run in CI.
    pub fn with_binding_limit(policy: AdapterPolicy, bytes: u64) -> Result<GpuContext, GpuError> {
        Self::create(&Self::vulkan_instance(None), None, policy, Some(bytes))
    }

    fn create(
        instance: &wgpu::Instance,
        compatible_surface: Option<&wgpu::Surface<'_>>,
        policy: AdapterPolicy,
        binding_limit: Option<u64>,
    ) -> Result<GpuContext, GpuError> {
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN));
        // Hardware first (discrete, integrated, virtual), software last.
        let rank = |a: &wgpu::Adapter| match a.get_info().device_type {
            wgpu::DeviceType::DiscreteGpu => 0,
            wgpu::DeviceType::IntegratedGpu => 1,
            wgpu::DeviceType::VirtualGpu => 2,
            wgpu::DeviceType::Other => 3,
            wgpu::DeviceType::Cpu => 4,
        };
        let adapter = adapters
            .into_iter()
            .filter(|a| compatible_surface.is_none_or(|s| a.is_surface_supported(s)))
            .min_by_key(rank)
            .ok_or(GpuError::NoAdapter)?;
        let info = adapter.get_info();
        if is_software(&info) && policy == AdapterPolicy::HardwareOnly {
            return Err(GpuError::SoftwareOnly { name: format!("{} ({})", info.name, info.driver) });
        }
        let offered = adapter.features();
        // Passthrough: the shaders reach the driver as hyrt's own SPIR-V (`crate::spirv`).
        let wanted = wgpu::Features::PRIMITIVE_INDEX
            | wgpu::Features::TIMESTAMP_QUERY
            | wgpu::Features::SHADER_EARLY_DEPTH_TEST
            | wgpu::Features::PASSTHROUGH_SHADERS;
        let features = offered & wanted;
        // The adapter's real limits where hyrt's frames grow with the image: the render
        // targets' side (lavapipe: 16384, WebGPU's default 8192) and buffer sizes. Frames
        // larger than a binding are rendered in bands (`crate::band`).
        let limits = wgpu::Limits {
            max_texture_dimension_2d: adapter.limits().max_texture_dimension_2d,
            max_storage_buffer_binding_size: adapter
                .limits()
                .max_storage_buffer_binding_size
                .min(binding_limit.unwrap_or(u64::MAX)),
            max_buffer_size: adapter.limits().max_buffer_size,
            // All the adapter has: a scene whose tables are paged (`crate::paging`) binds one
            // more for each further page (lavapipe offers 32).
            max_storage_buffers_per_shader_stage: adapter.limits().max_storage_buffers_per_shader_stage,
            max_buffers_and_acceleration_structures_per_shader_stage: adapter
                .limits()
                .max_buffers_and_acceleration_structures_per_shader_stage,
            max_compute_workgroup_storage_size: adapter.limits().max_compute_workgroup_storage_size,
            ..wgpu::Limits::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("hyrt"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::RequestDevice { adapter: info.name.clone(), message: e.to_string() })?;
        Ok(GpuContext {
            device,
            queue,
            info,
            limits,
            primitive_index: features.contains(wgpu::Features::PRIMITIVE_INDEX),
            timestamps: features.contains(wgpu::Features::TIMESTAMP_QUERY),
            early_depth_test: features.contains(wgpu::Features::SHADER_EARLY_DEPTH_TEST),
            float_ops: FloatOps::Exact,
            shader_delivery: ShaderDelivery::for_adapter(&adapter, features),
            adapter,
            probe: std::sync::OnceLock::new(),
        })
    }

    /// A context on a device the application already has (its own wgpu instance,
    /// adapter, device and queue), so hyrt's passes run beside the application's and
    /// its frames can stay on the GPU ([`crate::backend::GpuBackend::render_to_texture`]).
    /// hyrt uses the features the device was created with: `PRIMITIVE_INDEX`,
    /// `TIMESTAMP_QUERY`, `SHADER_EARLY_DEPTH_TEST` and `PASSTHROUGH_SHADERS` (for
    /// [`ShaderDelivery::Spirv`]) where present (all optional),
    /// and its limits as they are. Stages whose buffers exceed those limits fail with
    /// [`GpuError::Limits`].
    pub fn from_device(adapter: &wgpu::Adapter, device: wgpu::Device, queue: wgpu::Queue) -> GpuContext {
        let features = device.features();
        GpuContext {
            adapter: adapter.clone(),
            info: adapter.get_info(),
            limits: device.limits(),
            primitive_index: features.contains(wgpu::Features::PRIMITIVE_INDEX),
            timestamps: features.contains(wgpu::Features::TIMESTAMP_QUERY),
            early_depth_test: features.contains(wgpu::Features::SHADER_EARLY_DEPTH_TEST),
            device,
            queue,
            float_ops: FloatOps::Exact,
            shader_delivery: ShaderDelivery::for_adapter(adapter, features),
            probe: std::sync::OnceLock::new(),
        }
    }

    /// A one-line description: adapter, type, driver, the features in use, and how the
    /// shaders reach the driver.
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {} {}); triangle ids via {}; timestamp queries {}; conservative depth {}; {}",
            self.info.name,
            self.info.device_type,
            self.info.driver,
            self.info.driver_info,
            if self.primitive_index { "@builtin(primitive_index)" } else { "flat-interpolated vertex ids" },
            if self.timestamps { "available" } else { "unavailable" },
            if self.early_depth_test { "available" } else { "unavailable" },
            self.shader_delivery.describe(),
        ) + match self.float_ops {
            FloatOps::Exact => "",
            FloatOps::Device => "; division and square roots by the device's own `/` and `sqrt`, not the exact helpers",
        }
    }

    /// What the device's float arithmetic guarantees, as far as bit-identity with the CPU
    /// reference needs ([`FloatProbe`]): measured by a small compute check the first time
    /// it is asked for (a few milliseconds), then kept. The GPU backend renders on a device
    /// that misses a guarantee all the same; conformance then names what is missing.
    pub fn float_probe(&self) -> Result<&FloatProbe, GpuError> {
        self.probe.get_or_init(|| FloatProbe::run(self)).as_ref().map_err(Clone::clone)
    }

    /// Run `f` and turn any wgpu validation or out-of-memory error it raised into a
    /// [`GpuError`] instead of wgpu's default panic.
    pub fn checked<T>(&self, f: impl FnOnce() -> T) -> Result<T, GpuError> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let r = f();
        if let Some(e) = pollster::block_on(validation.pop()) {
            let _ = pollster::block_on(oom.pop());
            return Err(GpuError::Validation(e.to_string()));
        }
        if let Some(e) = pollster::block_on(oom.pop()) {
            return Err(GpuError::OutOfMemory(e.to_string()));
        }
        Ok(r)
    }
}
