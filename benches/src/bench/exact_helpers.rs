//! What the GPU backend's exact arithmetic costs (issue 39, items 3 and 5): the frame with
//! bounces of one Table 2 scene on the GPU backend, step by step, built the default way
//! (every float division and square root through `div_rn` and `sqrt_rn`,
//! [`FloatOps::Exact`]; the shaders as hyrt's SPIR-V with every float operation
//! `NoContraction`, [`ShaderDelivery::Spirv`], where the device offers passthrough), with
//! the device's own `/` and `sqrt` in the helpers' place ([`FloatOps::Device`]), and with
//! the shaders given to wgpu as WGSL ([`ShaderDelivery::Wgsl`]); the builds' frames
//! interleaved frame by frame in one run; and whether their final images are the same bits
//! (they are where the device rounds `/` and `sqrt` correctly, as lavapipe does).

use std::fmt::Write as _;

use hyrt_core::frame::{Backend, Frame, FrameOptions, FrameStats};
use hyrt_core::plan::FramePlan;
use hyrt_gpu::backend::GpuBackend;
use hyrt_gpu::shader::FloatOps;
use hyrt_gpu::spirv::ShaderDelivery;
use hyrt_gpu::GpuContext;
use indicatif::ProgressBar;

use super::bounces::step_medians;
use super::report::{num, Section, Table};
use super::stats::FrameSummary;
use super::table2::Table2;
use super::{BenchError, BenchOptions, FrameBackend};

/// The scene measured when Table 2 has it: mirrors and glass, so every stage runs.
pub const SCENE: &str = "teaser";

/// The measurement: per step label, the median milliseconds of the default build, of the
/// build with the device's own operations, and of the build given WGSL (where the default
/// is SPIR-V).
pub struct ExactCost {
    pub scene: String,
    pub gpu_label: String,
    /// How the default build's shaders reach the driver.
    pub delivery: ShaderDelivery,
    pub frames: usize,
    pub steps: Vec<(String, f64, f64, Option<f64>)>,
    pub frame_ms: (f64, f64, Option<f64>),
    /// The last frames' final images of the default and the device-operation builds are
    /// equal bit for bit.
    pub same_image: bool,
    /// The same for the default and the WGSL builds, where there is one.
    pub wgsl_same_image: Option<bool>,
}

/// The section's content: the measurement, or why there is none.
pub enum ExactHelpers {
    Measured(ExactCost),
    NotMeasured(String),
}

/// Measure the frame of [`SCENE`] (or the first Table 2 scene with bounces) on `gpu` as it
/// is (the exact helpers, the device's delivery) against a second GPU backend built with
/// [`FloatOps::Device`] and, where `gpu` gets SPIR-V, a third given WGSL.
pub fn run(
    options: &BenchOptions,
    table2: &Table2,
    gpu: Option<&mut FrameBackend>,
    progress: &ProgressBar,
) -> Result<ExactHelpers, BenchError> {
    let Some(gpu) = gpu else {
        return Ok(ExactHelpers::NotMeasured("no GPU backend in this run".into()));
    };
    let opts = FrameOptions::default();
    let has_bounces = |r: &&super::table2::Table2Row| {
        FramePlan::new(&r.prepared, &opts).map(|p| p.bounce_depth() > 0).unwrap_or(false)
    };
    let Some(row) =
        table2.rows.iter().find(|r| r.name == SCENE).or_else(|| table2.rows.iter().find(|r| has_bounces(r)))
    else {
        return Ok(ExactHelpers::NotMeasured("no Table 2 scene in this run".into()));
    };
    progress.set_message(format!("exact helpers' cost: {} (building the device-operation pipelines)", row.name));
    let build = |setup: &dyn Fn(&mut GpuContext)| {
        GpuContext::new(options.policy).and_then(|mut ctx| {
            setup(&mut ctx);
            GpuBackend::with_context(ctx)
        })
    };
    let mut device = match build(&|ctx| ctx.float_ops = FloatOps::Device) {
        Ok(d) => d,
        Err(e) => return Ok(ExactHelpers::NotMeasured(format!("no second GPU backend: {e}"))),
    };
    let delivery = device.context().shader_delivery;
    let mut wgsl = match delivery {
        ShaderDelivery::Wgsl => None,
        ShaderDelivery::Spirv { .. } => match build(&|ctx| ctx.shader_delivery = ShaderDelivery::Wgsl) {
            Ok(w) => Some(w),
            Err(e) => return Ok(ExactHelpers::NotMeasured(format!("no WGSL GPU backend: {e}"))),
        },
    };
    let render = |source| BenchError::Render { scene: row.name.clone(), source };
    let (mut exact_frame, mut device_frame, mut wgsl_frame) = (Frame::default(), Frame::default(), Frame::default());
    // One warm-up frame each, then the builds in turn, so that a noisy neighbour slows all.
    gpu.backend.render_into(&row.prepared, &row.camera, &opts, &mut exact_frame).map_err(render)?;
    device.render_into(&row.prepared, &row.camera, &opts, &mut device_frame).map_err(render)?;
    if let Some(w) = wgsl.as_mut() {
        w.render_into(&row.prepared, &row.camera, &opts, &mut wgsl_frame).map_err(render)?;
    }
    let (mut exact_stats, mut device_stats, mut wgsl_stats): (Vec<FrameStats>, Vec<FrameStats>, Vec<FrameStats>) =
        (Vec::new(), Vec::new(), Vec::new());
    for i in 0..options.frames {
        progress.set_message(format!("exact arithmetic's cost: {} (frame {} of {})", row.name, i + 1, options.frames));
        gpu.backend.render_into(&row.prepared, &row.camera, &opts, &mut exact_frame).map_err(render)?;
        exact_stats.push(exact_frame.stats.clone());
        device.render_into(&row.prepared, &row.camera, &opts, &mut device_frame).map_err(render)?;
        device_stats.push(device_frame.stats.clone());
        if let Some(w) = wgsl.as_mut() {
            w.render_into(&row.prepared, &row.camera, &opts, &mut wgsl_frame).map_err(render)?;
            wgsl_stats.push(wgsl_frame.stats.clone());
        }
    }
    let device_steps = step_medians(&device_stats);
    let wgsl_steps = step_medians(&wgsl_stats);
    let find = |steps: &[(String, f64)], label: &str| steps.iter().find(|(l, _)| l == label).map(|(_, ms)| *ms);
    let steps = step_medians(&exact_stats)
        .into_iter()
        .map(|(label, ms)| {
            let d = find(&device_steps, &label).unwrap_or(f64::NAN);
            let w = wgsl.as_ref().map(|_| find(&wgsl_steps, &label).unwrap_or(f64::NAN));
            (label, ms, d, w)
        })
        .collect();
    let frame_ms = |s: &[FrameStats]| FrameSummary::from_frames(s).map_or(f64::NAN, |s| s.frame_ms);
    let bits = |f: &Frame| f.final_image.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    Ok(ExactHelpers::Measured(ExactCost {
        scene: row.name.clone(),
        gpu_label: gpu.label.clone(),
        delivery,
        frames: options.frames,
        steps,
        frame_ms: (frame_ms(&exact_stats), frame_ms(&device_stats), wgsl.as_ref().map(|_| frame_ms(&wgsl_stats))),
        same_image: bits(&exact_frame) == bits(&device_frame),
        wgsl_same_image: wgsl.as_ref().map(|_| bits(&exact_frame) == bits(&wgsl_frame)),
    }))
}

impl ExactHelpers {
    /// The report section.
    pub fn section(&self, table2: &Table2) -> Section {
        let title = "The GPU's exact arithmetic: what it costs";
        let c = match self {
            ExactHelpers::NotMeasured(why) => return Section::new(title, format!("Not measured: {why}.\n")),
            ExactHelpers::Measured(c) => c,
        };
        let (w, h) = table2.size;
        let mut md = String::new();
        let _ = write!(
            md,
            "Every float division and square root of the GPU backend's shaders goes through `div_rn` and `sqrt_rn`, \
             correctly rounded from integer arithmetic, so that real GPUs (whose `/` is `a * rcp(b)`) compute the \
             CPU's bits; and where the device offers wgpu's passthrough the shaders reach it as hyrt's own SPIR-V, \
             every float operation `NoContraction` and the device's float-controls modes declared, instead of WGSL. \
             What that costs: the {} frame with its bounces ({w}x{h}, default max depth, medians of {} frames, the \
             builds' frames in turn) as built by default ({}), with the device's own `/` and `sqrt` in the helpers' \
             place (`FloatOps::Device`), and {}. GPU: {}. The final images with the device's own operations are {}",
            c.scene,
            c.frames,
            c.delivery.describe(),
            if c.wgsl_same_image.is_some() {
                "with the shaders given to wgpu as WGSL (`ShaderDelivery::Wgsl`)"
            } else {
                "(the device takes WGSL only) no third build"
            },
            c.gpu_label,
            if c.same_image {
                "the same bits (this device rounds its own `/` and `sqrt` correctly)"
            } else {
                "NOT the same bits (this device's own `/` or `sqrt` rounds differently)"
            },
        );
        md += &match c.wgsl_same_image {
            Some(true) => "; with WGSL, the same bits.\n\n".to_string(),
            Some(false) => "; with WGSL, NOT the same bits (the driver contracted an unguarded operation).\n\n".into(),
            None => ".\n\n".into(),
        };
        let mut t = Table::new([
            "step",
            "exact helpers ms",
            "device's own ms",
            "helpers / own",
            "as WGSL ms",
            "default / WGSL",
        ]);
        let ratio = |a: f64, b: f64| if b > 0.0 { num(a / b, 2) } else { "-".into() };
        let wgsl = |e: f64, w: Option<f64>| w.map_or(["-".to_string(), "-".to_string()], |w| [num(w, 2), ratio(e, w)]);
        for (label, e, d, w) in &c.steps {
            let [wm, wr] = wgsl(*e, *w);
            t.row([format!("`{label}`"), num(*e, 2), num(*d, 2), ratio(*e, *d), wm, wr]);
        }
        let (e, d, w) = c.frame_ms;
        let [wm, wr] = wgsl(e, w);
        t.row(["frame".to_string(), num(e, 2), num(d, 2), ratio(e, d), wm, wr]);
        md += &t.to_markdown();
        Section::new(title, md)
    }
}
