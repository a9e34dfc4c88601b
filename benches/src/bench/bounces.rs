//! Reflection and refraction in the report: the frame of each Table 2 scene that has
//! ray-traced mirrors or glass, at the default max depth, per step (`secondary_rays{1}`,
//! `bounce_trace{1}`, ...), on the CPU backend and, when available, the GPU backend: the
//! cost of each bounce next to the paper's stages, in the same run.

use std::fmt::Write as _;

use hyrt_core::formats::{RAY_KIND_REFLECTION, RAY_KIND_REFRACTION, RAY_KIND_SHADOW};
use hyrt_core::frame::{FrameOptions, FrameStats};
use hyrt_core::plan::FramePlan;
use indicatif::ProgressBar;

use super::report::{count, num, Section, Table};
use super::stats::median;
use super::table2::Table2;
use super::{measure_frames_with, BenchError, BenchOptions, FrameBackend};

/// One scene's bounce frames: per step label, the median milliseconds on each backend.
pub struct BounceRow {
    pub name: String,
    /// Step labels in plan order, with the CPU's and the GPU's medians.
    pub steps: Vec<(String, f64, Option<f64>)>,
    pub cpu_frame_ms: f64,
    pub gpu_frame_ms: Option<f64>,
    /// The CPU's last frame (the counts per depth).
    pub stats: FrameStats,
}

/// The section's measurements.
pub struct Bounces {
    pub rows: Vec<BounceRow>,
    pub max_depth: u32,
    pub gpu: Option<String>,
    pub notes: Vec<String>,
}

/// Median milliseconds of each step label over `frames` (in the last frame's order).
pub(super) fn step_medians(frames: &[FrameStats]) -> Vec<(String, f64)> {
    let Some(last) = frames.last() else { return Vec::new() };
    last.stage_ms
        .iter()
        .map(|t| {
            let label = t.label();
            let v: Vec<f64> =
                frames.iter().filter_map(|f| f.stage_ms.iter().find(|s| s.label() == label).map(|s| s.ms)).collect();
            (label, median(&v).unwrap_or(f64::NAN))
        })
        .collect()
}

/// Measure the bounce frames of the scenes of `table2` that plan bounces.
pub fn run(
    options: &BenchOptions,
    table2: &Table2,
    cpu: &mut FrameBackend,
    mut gpu: Option<&mut FrameBackend>,
    progress: &ProgressBar,
) -> Result<Bounces, BenchError> {
    let opts = FrameOptions::default();
    let mut rows = Vec::new();
    let mut notes = Vec::new();
    for r in &table2.rows {
        let plan = FramePlan::new(&r.prepared, &opts)
            .map_err(|source| BenchError::Render { scene: r.name.clone(), source })?;
        if plan.bounce_depth() == 0 {
            continue;
        }
        progress.set_message(format!("bounces: {} (CPU frames)", r.name));
        let (cpu_summary, cpu_frames) =
            measure_frames_with(cpu.backend.as_mut(), &r.prepared, &r.camera, options.frames, &opts)
                .map_err(|source| BenchError::Render { scene: r.name.clone(), source })?;
        let gpu_m = match gpu.as_deref_mut() {
            Some(g) => {
                progress.set_message(format!("bounces: {} ({} frames)", r.name, g.short));
                match measure_frames_with(g.backend.as_mut(), &r.prepared, &r.camera, options.frames, &opts) {
                    Ok(m) => Some(m),
                    Err(e) => {
                        notes.push(format!("{}: GPU frame with bounces failed: {e}", r.name));
                        None
                    }
                }
            }
            None => None,
        };
        let cpu_steps = step_medians(&cpu_frames);
        let gpu_steps = gpu_m.as_ref().map(|(_, f)| step_medians(f));
        let steps = cpu_steps
            .into_iter()
            .map(|(label, ms)| {
                let g = gpu_steps.as_ref().and_then(|s| s.iter().find(|(l, _)| *l == label).map(|(_, ms)| *ms));
                (label, ms, g)
            })
            .collect();
        rows.push(BounceRow {
            name: r.name.clone(),
            steps,
            cpu_frame_ms: cpu_summary.frame_ms,
            gpu_frame_ms: gpu_m.as_ref().map(|(s, _)| s.frame_ms),
            stats: cpu_frames.last().cloned().unwrap_or_default(),
        });
    }
    Ok(Bounces { rows, max_depth: opts.max_depth, gpu: cpu_gpu_label(table2), notes })
}

fn cpu_gpu_label(table2: &Table2) -> Option<String> {
    table2.gpu.as_ref().map(|(label, _)| label.clone())
}

impl Bounces {
    /// The report section.
    pub fn section(&self, table2: &Table2) -> Section {
        let mut md = String::new();
        let (w, h) = table2.size;
        let _ = writeln!(
            md,
            "The frames of the scenes above that have ray-traced mirrors or glass, at the default max depth {} \
             ({w}x{h}, medians; each step as the frame table names it, `stage{{d}}` at bounce depth d). CPU: {}{}.\n",
            self.max_depth,
            table2.cpu_label,
            self.gpu.as_ref().map_or(String::new(), |g| format!("; GPU: {g}")),
        );
        if self.rows.is_empty() {
            md += "No scene of this run has a ray-traced mirror or glass object.\n";
        }
        for r in &self.rows {
            let _ =
                writeln!(md, "**{}**: secondary rays per depth (reflection + refraction, their shadow rays):", r.name);
            let per_depth: Vec<String> = r
                .stats
                .bounces
                .iter()
                .enumerate()
                .map(|(d, b)| {
                    let k = &b.rays_per_kind;
                    format!(
                        "{}: {} + {}, {}",
                        d + 1,
                        count(k[RAY_KIND_REFLECTION as usize]),
                        count(k[RAY_KIND_REFRACTION as usize]),
                        count(k[RAY_KIND_SHADOW as usize])
                    )
                })
                .collect();
            let _ = writeln!(md, "{}.\n", per_depth.join("; "));
            let mut t = Table::new(["step", "CPU ms", "GPU ms"]);
            for (label, c, g) in &r.steps {
                t.row([format!("`{label}`"), num(*c, 2), g.map_or("-".into(), |g| num(g, 2))]);
            }
            t.row(["frame".to_string(), num(r.cpu_frame_ms, 2), r.gpu_frame_ms.map_or("-".into(), |g| num(g, 2))]);
            md += &t.to_markdown();
            md += "\n";
        }
        for n in &self.notes {
            let _ = writeln!(md, "- {n}");
        }
        Section::new("Reflection and refraction: the frame at the default max depth", md)
    }
}
