//! What the GPU backend's exact helpers cost (issue 39, item 5): the frame with bounces of
//! one Table 2 scene on the GPU backend, step by step, built the default way (every float
//! division and square root through `div_rn` and `sqrt_rn`, [`FloatOps::Exact`]) and with
//! the device's own `/` and `sqrt` in their place ([`FloatOps::Device`]), the two frames
//! interleaved frame by frame in one run; and whether the two final images are the same
//! bits (they are where the device rounds `/` and `sqrt` correctly, as lavapipe does).

use std::fmt::Write as _;

use hyrt_core::frame::{Backend, Frame, FrameOptions, FrameStats};
use hyrt_core::plan::FramePlan;
use hyrt_gpu::backend::GpuBackend;
use hyrt_gpu::shader::FloatOps;
use hyrt_gpu::GpuContext;
use indicatif::ProgressBar;

use super::bounces::step_medians;
use super::report::{num, Section, Table};
use super::stats::FrameSummary;
use super::table2::Table2;
use super::{BenchError, BenchOptions, FrameBackend};

/// The scene measured when Table 2 has it: mirrors and glass, so every stage runs.
pub const SCENE: &str = "teaser";

/// The measurement: per step label, the median milliseconds with the exact helpers and
/// with the device's own operations.
pub struct ExactCost {
    pub scene: String,
    pub gpu_label: String,
    pub frames: usize,
    pub steps: Vec<(String, f64, f64)>,
    pub frame_ms: (f64, f64),
    /// The last frames' final images are equal bit for bit.
    pub same_image: bool,
}

/// The section's content: the measurement, or why there is none.
pub enum ExactHelpers {
    Measured(ExactCost),
    NotMeasured(String),
}

/// Measure the frame of [`SCENE`] (or the first Table 2 scene with bounces) on `gpu` as it
/// is (the exact helpers) against a second GPU backend built with [`FloatOps::Device`].
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
    let device = GpuContext::new(options.policy).and_then(|mut ctx| {
        ctx.float_ops = FloatOps::Device;
        GpuBackend::with_context(ctx)
    });
    let mut device = match device {
        Ok(d) => d,
        Err(e) => return Ok(ExactHelpers::NotMeasured(format!("no second GPU backend: {e}"))),
    };
    let render = |source| BenchError::Render { scene: row.name.clone(), source };
    let (mut exact_frame, mut device_frame) = (Frame::default(), Frame::default());
    // One warm-up frame each, then the two in turn, so that a noisy neighbour slows both.
    gpu.backend.render_into(&row.prepared, &row.camera, &opts, &mut exact_frame).map_err(render)?;
    device.render_into(&row.prepared, &row.camera, &opts, &mut device_frame).map_err(render)?;
    let (mut exact_stats, mut device_stats): (Vec<FrameStats>, Vec<FrameStats>) = (Vec::new(), Vec::new());
    for i in 0..options.frames {
        progress.set_message(format!("exact helpers' cost: {} (frame {} of {})", row.name, i + 1, options.frames));
        gpu.backend.render_into(&row.prepared, &row.camera, &opts, &mut exact_frame).map_err(render)?;
        exact_stats.push(exact_frame.stats.clone());
        device.render_into(&row.prepared, &row.camera, &opts, &mut device_frame).map_err(render)?;
        device_stats.push(device_frame.stats.clone());
    }
    let device_steps = step_medians(&device_stats);
    let steps = step_medians(&exact_stats)
        .into_iter()
        .map(|(label, ms)| {
            let d = device_steps.iter().find(|(l, _)| *l == label).map_or(f64::NAN, |(_, ms)| *ms);
            (label, ms, d)
        })
        .collect();
    let frame_ms = |s: &[FrameStats]| FrameSummary::from_frames(s).map_or(f64::NAN, |s| s.frame_ms);
    let bits = |f: &Frame| f.final_image.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    Ok(ExactHelpers::Measured(ExactCost {
        scene: row.name.clone(),
        gpu_label: gpu.label.clone(),
        frames: options.frames,
        steps,
        frame_ms: (frame_ms(&exact_stats), frame_ms(&device_stats)),
        same_image: bits(&exact_frame) == bits(&device_frame),
    }))
}

impl ExactHelpers {
    /// The report section.
    pub fn section(&self, table2: &Table2) -> Section {
        let title = "The GPU's exact division and square root: what they cost";
        let c = match self {
            ExactHelpers::NotMeasured(why) => return Section::new(title, format!("Not measured: {why}.\n")),
            ExactHelpers::Measured(c) => c,
        };
        let (w, h) = table2.size;
        let mut md = String::new();
        let _ = writeln!(
            md,
            "Every float division and square root of the GPU backend's shaders goes through `div_rn` and `sqrt_rn`, \
             correctly rounded from integer arithmetic, so that real GPUs (whose `/` is `a * rcp(b)`) compute the \
             CPU's bits. What that costs: the {} frame with its bounces ({w}x{h}, default max depth, medians of {} \
             frames, the two builds' frames in turn) with the helpers and with the device's own `/` and `sqrt` in their \
             place (`FloatOps::Device`). GPU: {}. The two final images are {}.\n",
            c.scene,
            c.frames,
            c.gpu_label,
            if c.same_image {
                "the same bits (this device rounds its own `/` and `sqrt` correctly)"
            } else {
                "NOT the same bits (this device's own `/` or `sqrt` rounds differently)"
            },
        );
        let mut t = Table::new(["step", "exact helpers ms", "device's own ms", "helpers / own"]);
        let ratio = |a: f64, b: f64| if b > 0.0 { num(a / b, 2) } else { "-".into() };
        for (label, e, d) in &c.steps {
            t.row([format!("`{label}`"), num(*e, 2), num(*d, 2), ratio(*e, *d)]);
        }
        t.row(["frame".to_string(), num(c.frame_ms.0, 2), num(c.frame_ms.1, 2), ratio(c.frame_ms.0, c.frame_ms.1)]);
        md += &t.to_markdown();
        Section::new(title, md)
    }
}
