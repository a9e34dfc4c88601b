//! The exact helpers on the device, and the float probe.
//!
//! Every stage divides and takes square roots through `div_rn` and `sqrt_rn`
//! (`shaders/exact.wgsl`, mirrors of [`hyrt_core::kernels::exact`]), built from integer
//! operations so that they give IEEE 754's bits on any device. [`ExactKernel`] runs them
//! (and, for comparison, the device's own `/`, `sqrt` and a few plain operations) over
//! lists of operands or over ranges of bit patterns: the helpers' exhaustive tests
//! (`gpu-backend/tests/exact.rs`) and [`FloatProbe`] use it.
//!
//! [`FloatProbe`] is the start-up check of what the GPU backend relies on: the helpers'
//! results on hard cases, rounding to nearest even, subnormals kept, products kept
//! apart from the sums they feed where a shader says so (`rounded`, `mul`), and no
//! contraction anywhere (the shaders reach the driver as SPIR-V with every float
//! operation `NoContraction`, [`crate::spirv`], and a plain `a * b + c` comes back unfused). It also says
//! what the device's own `/` and `sqrt` do on the same hard cases, which is why the
//! helpers exist. [`GpuContext::float_probe`](crate::GpuContext::float_probe) runs it
//! once per context.
//!
//! # Cost
//! Measured when the helpers replaced the device's `/` and `sqrt` (default scene, 1280x720,
//! four bounces, medians of 4 frames, the two builds interleaved twice on a 2-core Xeon;
//! `hyrt render --backend gpu --allow-software-gpu --size 1280x720 --frames 4`), lavapipe
//! stage times in ms, before and after:
//!
//! | stage | before | after |
//! |---|---:|---:|
//! | visibility_raster | 273 | 334 |
//! | reconstruction | 34 | 62 |
//! | compaction | 88 | 110 |
//! | shadow_rays | 233 | 258 |
//! | secondary_rays{1} | 146 | 275 |
//! | rt_shading | 60 | 163 |
//! | raster_shading | 17 | 42 |
//! | bounce_shading{1} | 5.5 | 15.5 |
//! | frame (sum of stages) | 1222 | 1778 |
//!
//! On an NVIDIA H200 the default scene at 1920x1080 went from 7.76 to 8.29 ms (sum of the
//! stages' timestamp times, one run each). lavapipe runs both sides of every select in
//! its lanes, so the straight-line helpers cost it most; a GPU hides them behind memory.

use hyrt_core::kernels::exact::EXACT_ESTIMATE_UNITS;
use wgpu::util::DeviceExt;

use crate::gpu_buffer::{read_back, storage, upload};
use crate::shader::{bind_buffers, main_pipeline, preamble, storage_entry, uniform_entry, StageModule};
use crate::spirv::ShaderDelivery;
use crate::{GpuContext, GpuError};

/// What [`ExactKernel`] computes per element, from operands `a`, `b`, `c` (f32 bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum ExactOp {
    /// `div_rn(a, b)`.
    Div = 0,
    /// `sqrt_rn(a)`.
    Sqrt = 1,
    /// The device's own `a / b` (WGSL `/`).
    DeviceDiv = 2,
    /// The device's own `sqrt(a)`.
    DeviceSqrt = 3,
    /// `a * b + c` as written: the device may fuse it.
    PlainMulAdd = 4,
    /// `rounded(a * b) + c`: the product behind the shaders' barrier (an always-zero
    /// uniform ORed into its bits), which must not be fused.
    GuardedMulAdd = 5,
    /// `a + b`.
    Add = 6,
    /// `a * b`.
    Mul = 7,
    /// `sqrt_rn` of the bit pattern `first + i` (a sweep; no operands).
    SweepSqrt = 8,
    /// `div_rn(fixed, first + i)`.
    SweepDivFixedBy = 9,
    /// `div_rn(first + i, fixed)`.
    SweepDivByFixed = 10,
}

impl ExactOp {
    /// Every operation with its WGSL name (`OP_<name>`, generated into the kernel).
    const ALL: [(&'static str, ExactOp); 11] = [
        ("DIV", ExactOp::Div),
        ("SQRT", ExactOp::Sqrt),
        ("DEVICE_DIV", ExactOp::DeviceDiv),
        ("DEVICE_SQRT", ExactOp::DeviceSqrt),
        ("PLAIN_MUL_ADD", ExactOp::PlainMulAdd),
        ("GUARDED_MUL_ADD", ExactOp::GuardedMulAdd),
        ("ADD", ExactOp::Add),
        ("MUL", ExactOp::Mul),
        ("SWEEP_SQRT", ExactOp::SweepSqrt),
        ("SWEEP_DIV_FIXED_BY", ExactOp::SweepDivFixedBy),
        ("SWEEP_DIV_BY_FIXED", ExactOp::SweepDivByFixed),
    ];
}

/// Declares the job's uniform in Rust and, from the same field list, in WGSL
/// (`JOB_WGSL`): scalars only, spelled alike in both, so the layouts agree.
macro_rules! job_record {
    ($(#[$doc:meta])* struct $name:ident { $($field:ident: $ty:ident,)+ }) => {
        $(#[$doc])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
        struct $name {
            $($field: $ty,)+
        }

        /// The WGSL declaration of the job's uniform.
        const JOB_WGSL: &str =
            concat!("struct ", stringify!($name), " {\n", $("    ", stringify!($field), ": ", stringify!($ty), ",\n",)+ "}\n");
    };
}

job_record! {
    /// The job's uniform: which operation, the sweep's range and fixed operand, the
    /// estimate's skew (`div_rn_skewed`), the element count, and an always-zero word for
    /// the guarded product (32 bytes).
    struct ExactJob {
        op: u32,
        first: u32,
        fixed: u32,
        skew: i32,
        count: u32,
        zero: u32,
        pad0: u32,
        pad1: u32,
    }
}
const _: () = assert!(std::mem::size_of::<ExactJob>() == 32);

/// Workgroups per row of a dispatch: rows of 2^16 elements at 64 threads a group.
const GROUPS_PER_ROW: u32 = 1024;

const ENTRY: &str = r#"
@group(0) @binding(0) var<uniform> job: ExactJob;
@group(0) @binding(1) var<storage, read> operands: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read_write> results: array<u32>;

fn guarded(x: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(x) | job.zero);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * (GROUPS_PER_ROW * 64u);
    if i >= job.count {
        return;
    }
    var r = 0u;
    if job.op >= OP_SWEEP_SQRT {
        let x = bitcast<f32>(job.first + i);
        let fixed = bitcast<f32>(job.fixed);
        switch job.op {
            case OP_SWEEP_SQRT: { r = bitcast<u32>(sqrt_rn_skewed(x, job.skew)); }
            case OP_SWEEP_DIV_FIXED_BY: { r = bitcast<u32>(div_rn_skewed(fixed, x, job.skew)); }
            default: { r = bitcast<u32>(div_rn_skewed(x, fixed, job.skew)); }
        }
    } else {
        let o = operands[i];
        let a = bitcast<f32>(o.x);
        let b = bitcast<f32>(o.y);
        let c = bitcast<f32>(o.z);
        switch job.op {
            case OP_DIV: { r = bitcast<u32>(div_rn_skewed(a, b, job.skew)); }
            case OP_SQRT: { r = bitcast<u32>(sqrt_rn_skewed(a, job.skew)); }
            case OP_DEVICE_DIV: { r = bitcast<u32>(a / b); }
            case OP_DEVICE_SQRT: { r = bitcast<u32>(sqrt(a)); }
            case OP_PLAIN_MUL_ADD: { r = bitcast<u32>(a * b + c); }
            case OP_GUARDED_MUL_ADD: { r = bitcast<u32>(guarded(a * b) + c); }
            case OP_ADD: { r = bitcast<u32>(a + b); }
            default: { r = bitcast<u32>(a * b); }
        }
    }
    results[i] = r;
}
"#;

/// The compute pipeline that evaluates [`ExactOp`]s.
pub struct ExactKernel {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl ExactKernel {
    /// Compile the kernel: the preamble every stage starts with, then the entry point.
    pub fn new(ctx: &GpuContext) -> Result<ExactKernel, GpuError> {
        let ops: String =
            ExactOp::ALL.iter().map(|(name, op)| format!("const OP_{name}: u32 = {}u;\n", *op as u32)).collect();
        let source = format!("{}\nconst GROUPS_PER_ROW: u32 = {GROUPS_PER_ROW}u;\n{ops}{JOB_WGSL}{ENTRY}", preamble());
        let entries = [uniform_entry(0), storage_entry(1, true), storage_entry(2, false)];
        // The one module that uses the device's own `/` and `sqrt` on purpose (to report
        // them), so it is not made through `shader_module`, which refuses them. It reaches
        // the driver as every stage's does (`GpuContext::shader_delivery`), so the probe
        // measures what the stages get.
        ctx.checked(|| {
            let module = StageModule::new(ctx, "exact helpers", &source);
            let layout = ctx.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("exact helpers"),
                entries: &entries,
            });
            let pipeline = main_pipeline("exact helpers", &module, &layout, &entries, &[]);
            ExactKernel { pipeline, layout }
        })
    }

    /// `op` over `operands` (`[a, b, c]` as f32 bits), the estimates moved by `skew` ulp
    /// (0 for the helpers as the stages run them): one result word per operand triple.
    pub fn evaluate(
        &self,
        ctx: &GpuContext,
        op: ExactOp,
        operands: &[[u32; 3]],
        skew: i32,
    ) -> Result<Vec<u32>, GpuError> {
        let padded: Vec<[u32; 4]> = operands.iter().map(|&[a, b, c]| [a, b, c, 0]).collect();
        self.run(ctx, op, &padded, 0, 0, operands.len() as u32, skew)
    }

    /// A sweep ([`ExactOp::SweepSqrt`], [`ExactOp::SweepDivFixedBy`],
    /// [`ExactOp::SweepDivByFixed`]) over the bit patterns `first .. first + count`.
    pub fn sweep(
        &self,
        ctx: &GpuContext,
        op: ExactOp,
        first: u32,
        count: u32,
        fixed: u32,
        skew: i32,
    ) -> Result<Vec<u32>, GpuError> {
        assert!(op as u32 >= ExactOp::SweepSqrt as u32, "{op:?} is not a sweep");
        self.run(ctx, op, &[[0; 4]], first, fixed, count, skew)
    }

    #[allow(clippy::too_many_arguments)]
    fn run(
        &self,
        ctx: &GpuContext,
        op: ExactOp,
        operands: &[[u32; 4]],
        first: u32,
        fixed: u32,
        count: u32,
        skew: i32,
    ) -> Result<Vec<u32>, GpuError> {
        if count == 0 {
            return Ok(Vec::new());
        }
        let job = ExactJob { op: op as u32, first, fixed, skew, count, zero: 0, pad0: 0, pad1: 0 };
        let job_buffer = ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("exact job"),
            contents: bytemuck::bytes_of(&job),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let operand_buffer = upload(ctx, "exact operands", operands);
        let results = storage::<u32>(ctx, "exact results", count as usize)?;
        let group = bind_buffers(ctx, "exact helpers", &self.layout, &[&job_buffer, &operand_buffer, &results]);
        let rows = count.div_ceil(GROUPS_PER_ROW * 64);
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(GROUPS_PER_ROW.min(count.div_ceil(64)), rows, 1);
        }
        ctx.queue.submit([encoder.finish()]);
        read_back(ctx, &results, count as usize)
    }
}

/// Bit equality, NaN equal to NaN whatever its bits (the helpers' NaNs are x86's; a
/// device may give other NaN bits, and the stages never produce NaN on purpose).
pub fn same_bits(a: u32, b: u32) -> bool {
    let nan = |x: u32| x & 0x7fff_ffff > 0x7f80_0000;
    a == b || (nan(a) && nan(b))
}

/// How far the device's own `/` or `sqrt` is from correct rounding on the probe's hard
/// cases.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rounding {
    /// Cases whose result differs from IEEE 754's.
    pub off: usize,
    /// Cases tried.
    pub cases: usize,
    /// Largest difference in ulp (as the bit patterns' distance).
    pub worst_ulp: u32,
}

impl std::fmt::Display for Rounding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.off == 0 {
            write!(f, "correctly rounded on {} hard cases", self.cases)
        } else {
            write!(f, "off on {} of {} hard cases (up to {} ulp)", self.off, self.cases, self.worst_ulp)
        }
    }
}

/// The result of the start-up float check ([`FloatProbe::run`]). The first four fields and
/// the shaders' delivery with no contraction observed are what bit-identity with the CPU
/// needs ([`FloatProbe::guarantees_met`]); the other fields describe the device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FloatProbe {
    /// `div_rn` and `sqrt_rn` cases that differ from IEEE 754 (0 on a conforming device).
    pub helpers_off: usize,
    /// Cases the helpers were checked on.
    pub helper_cases: usize,
    /// Sums and products round to nearest, ties to even (not toward zero).
    pub nearest_even: bool,
    /// Subnormal operands and results of `+` and `*` are kept, not flushed to zero.
    pub subnormals_kept: bool,
    /// A product behind the shaders' barrier (`rounded(a * b) + c`) stays rounded apart
    /// from the sum (false: the device fused it, and shaded bits will differ).
    pub guarded_products_apart: bool,
    /// A plain `a * b + c` came back fused (allowed by WGSL; SPIR-V's `NoContraction`,
    /// which [`ShaderDelivery::Spirv`] puts on every float operation, forbids it; shaders
    /// guard every product that feeds a sum all the same).
    pub plain_mul_add_fused: bool,
    /// How the shaders, the probe's included, reached the driver (described by
    /// [`GpuContext::describe`](crate::GpuContext::describe), not by this probe's `Display`,
    /// which the backend's description prints after the context's).
    pub delivery: ShaderDelivery,
    /// The device's own `/` on the hard cases.
    pub device_div: Rounding,
    /// The device's own `sqrt` on the hard cases.
    pub device_sqrt: Rounding,
}

/// Operands where rounding shows: ones and their neighbours, all-ones significands,
/// subnormals, the extremes, thirds and tenths, and a seeded spread over all exponents.
fn hard_operands() -> Vec<u32> {
    let mut v = vec![
        0x3f80_0000u32,
        0x3f7f_ffff,
        0x3f80_0001,
        0x3fff_ffff,
        0x4040_0000,
        0x3f55_5555,
        0x3eaa_aaab,
        0x3dcc_cccd,
        0x4b7f_ffff,
        0x0000_0001,
        0x0000_0003,
        0x007f_ffff,
        0x0080_0000,
        0x0080_0001,
        0x7f7f_ffff,
        0x7f7f_fffe,
        0x3fb5_04f3,
        0x4049_0fdb,
        0x1000_0000,
        0x6000_0000,
    ];
    let mut s = 0x2545_f491_4f6c_dd1du64;
    for _ in 0..44 {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        // Finite, positive: any exponent field but 255.
        v.push(((s as u32) & 0x7fff_ffff) % 0x7f80_0000);
    }
    v
}

impl FloatProbe {
    /// Run the probe: a few thousand evaluations in one small kernel.
    pub fn run(ctx: &GpuContext) -> Result<FloatProbe, GpuError> {
        let kernel = ExactKernel::new(ctx)?;
        let xs = hard_operands();
        let mut pairs: Vec<[u32; 3]> = Vec::with_capacity(xs.len() * xs.len());
        for &a in &xs {
            for &b in &xs {
                pairs.push([a, b, 0]);
                pairs.push([a ^ 0x8000_0000, b, 0]);
            }
        }
        let singles: Vec<[u32; 3]> = xs.iter().map(|&x| [x, 0, 0]).collect();
        let f = f32::from_bits;
        let ulp = |a: u32, b: u32| (a as i64 - b as i64).unsigned_abs().min(u32::MAX as u64) as u32;

        let mut helpers_off = 0;
        let mut helper_cases = 0;
        let div_expected: Vec<u32> = pairs.iter().map(|p| (f(p[0]) / f(p[1])).to_bits()).collect();
        let sqrt_expected: Vec<u32> = singles.iter().map(|p| f(p[0]).sqrt().to_bits()).collect();
        for skew in [0, -3, 3] {
            let got = kernel.evaluate(ctx, ExactOp::Div, &pairs, skew)?;
            helpers_off += got.iter().zip(&div_expected).filter(|(g, e)| !same_bits(**g, **e)).count();
            let got = kernel.evaluate(ctx, ExactOp::Sqrt, &singles, skew)?;
            helpers_off += got.iter().zip(&sqrt_expected).filter(|(g, e)| !same_bits(**g, **e)).count();
            helper_cases += pairs.len() + singles.len();
        }
        let compare = |got: &[u32], expected: &[u32]| {
            let mut r = Rounding { off: 0, cases: got.len(), worst_ulp: 0 };
            for (&g, &e) in got.iter().zip(expected) {
                if !same_bits(g, e) {
                    r.off += 1;
                    r.worst_ulp = r.worst_ulp.max(ulp(g, e));
                }
            }
            r
        };
        let device_div = compare(&kernel.evaluate(ctx, ExactOp::DeviceDiv, &pairs, 0)?, &div_expected);
        let device_sqrt = compare(&kernel.evaluate(ctx, ExactOp::DeviceSqrt, &singles, 0)?, &sqrt_expected);

        // (1 + 2^-12)^2 = 1 + 2^-11 + 2^-24: rounded apart, minus (1 + 2^-11) gives 0;
        // fused, 2^-24.
        let a = 1.0f32 + f32::EPSILON * 2048.0;
        let fma_case = [[a.to_bits(), a.to_bits(), (-(1.0f32 + f32::EPSILON * 4096.0)).to_bits()]];
        let plain = kernel.evaluate(ctx, ExactOp::PlainMulAdd, &fma_case, 0)?[0];
        let guarded = kernel.evaluate(ctx, ExactOp::GuardedMulAdd, &fma_case, 0)?[0];
        // Ties: 1 + 2^-24 -> 1; (1 + 2^-23) + 2^-24 -> 1 + 2^-22 (even); toward zero
        // would give 1 + 2^-23 for the second.
        let half_ulp = f32::EPSILON / 2.0;
        let tie =
            [[1.0f32.to_bits(), half_ulp.to_bits(), 0], [(1.0f32 + f32::EPSILON).to_bits(), half_ulp.to_bits(), 0]];
        let tie_expected: Vec<u32> = tie.iter().map(|p| (f(p[0]) + f(p[1])).to_bits()).collect();
        let nearest_even = kernel.evaluate(ctx, ExactOp::Add, &tie, 0)? == tie_expected;
        // Subnormals: 2^-149 + 2^-149, 2^-100 * 2^-30, and the smallest normal halved.
        let sub = [
            [1u32, 1, 0],
            [(2.0f32).powi(-100).to_bits(), (2.0f32).powi(-30).to_bits(), 0],
            [f32::MIN_POSITIVE.to_bits(), 0.5f32.to_bits(), 0],
        ];
        let sums = kernel.evaluate(ctx, ExactOp::Add, &sub[..1], 0)?;
        let products = kernel.evaluate(ctx, ExactOp::Mul, &sub[1..], 0)?;
        let subnormals_kept = sums[0] == 2
            && products[0] == (f(sub[1][0]) * f(sub[1][1])).to_bits()
            && products[1] == (f(sub[2][0]) * f(sub[2][1])).to_bits();
        Ok(FloatProbe {
            helpers_off,
            helper_cases,
            nearest_even,
            subnormals_kept,
            guarded_products_apart: guarded == 0,
            plain_mul_add_fused: plain != 0,
            delivery: ctx.shader_delivery,
            device_div,
            device_sqrt,
        })
    }

    /// Everything bit-identity with the CPU reference relies on holds.
    pub fn guarantees_met(&self) -> bool {
        self.missing().is_empty()
    }

    /// Float operations reach the driver decorated `NoContraction`, and the plain
    /// `a * b + c` came back unfused: the device honours it.
    pub fn no_contraction(&self) -> bool {
        self.delivery.no_contraction() && !self.plain_mul_add_fused
    }

    /// The guarantees that fail, by the names conformance reports use.
    pub fn missing(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        if self.helpers_off != 0 {
            v.push("exact helpers");
        }
        if !self.nearest_even {
            v.push("round to nearest even");
        }
        if !self.subnormals_kept {
            v.push("subnormals kept");
        }
        if !self.guarded_products_apart {
            v.push("guarded products apart");
        }
        if !self.no_contraction() {
            v.push("no contraction");
        }
        v
    }
}

impl std::fmt::Display for FloatProbe {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let missing = self.missing();
        if missing.is_empty() {
            write!(f, "float probe: guarantees met (exact div_rn and sqrt_rn on {} cases, ", self.helper_cases)?;
        } else {
            write!(
                f,
                "float probe: MISSING {} (helpers off on {} of {} cases, ",
                missing.join(", "),
                self.helpers_off,
                self.helper_cases
            )?;
        }
        write!(
            f,
            "{}, subnormals {}, guarded products {}); device's own `/` {}, `sqrt` {}; plain a*b+c {}; helpers correct estimates up to {EXACT_ESTIMATE_UNITS} units off",
            if self.nearest_even { "round to nearest even" } else { "NOT round to nearest even" },
            if self.subnormals_kept { "kept" } else { "FLUSHED" },
            if self.guarded_products_apart { "apart" } else { "FUSED" },
            self.device_div,
            self.device_sqrt,
            if self.plain_mul_add_fused { "fused" } else { "rounded twice" },
        )
    }
}
