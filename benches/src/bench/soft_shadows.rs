//! Soft shadows in the report (issue 38): the quad light of `assets/scenes/area_light.toml`
//! at 1, 2, 4 and 16 shadow rays per pixel, shaded from the raw samples and through
//! `shadow_denoise`, against a 1,024-sample reference:
//!
//! * visibility RMSE: the frame's visibility of the light (raw: `light_visibility` of the
//!   mask; denoised: `shadow_denoise`'s channel) against the visible share of 1,024
//!   samples of an independent stream (frame index [`REFERENCE_FRAME`]) traced per pixel
//!   with the scalar reference traversal, over the pixels where the reference has an
//!   estimate; pixels without a frame estimate count as 0;
//! * image FLIP: the final image against the mean of four 256-sample frames without the
//!   denoiser (1,024 samples per pixel and light), at NVIDIA's default viewing condition;
//! * time: the frame's median and its `shadow_rays` and `shadow_denoise` steps (the CPU
//!   backend; stochastic frames run staged);
//! * the frame's shadow-ray list traced by hyrt's packets and by Embree's `rtcOccluded8`,
//!   interleaved round by round (the trace alone, the same rays).

use std::fmt::Write as _;
use std::path::PathBuf;

use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, Frame, FrameOptions, PreparedScene};
use hyrt_core::kernels::soft_shadow::{frame_lights, light_visibility, lights_slots, slot_ray, AmbientOcclusion, Slot};
use hyrt_core::stage::Stage;
use hyrt_cpu::backend::CpuBackend;
use hyrt_cpu::traversal::{occluded_batch_into, Traversal};
use indicatif::ProgressBar;
use rayon::prelude::*;

use super::plots::{self, Plot, Series};
use super::report::{count, num, Section, Table};
use super::stats::{interleaved_ms, median};
use super::{link, measure_frames_with, BenchError, BenchOptions};

/// The scene: one quad light over a floor, a box between them, a ray-traced sphere.
pub const SCENE: &str = "area_light";
/// Shadow rays per pixel the section measures.
pub const SAMPLES: [u32; 4] = [1, 2, 4, 16];
/// Samples per pixel of the reference.
pub const REFERENCE_SAMPLES: u32 = 1024;
/// The frame index whose sample streams the reference draws (independent of frame 0's).
pub const REFERENCE_FRAME: u32 = 1 << 20;
/// The plot's file name.
pub const PLOT: &str = "soft_shadows.png";

/// One row: a sample count, raw or denoised.
pub struct SoftShadowRow {
    pub samples: u32,
    pub denoise: bool,
    pub frame_ms: f64,
    pub shadow_rays_ms: f64,
    pub denoise_ms: Option<f64>,
    pub rmse: f64,
    pub flip: f64,
    pub rays: usize,
    /// hyrt's packets and Embree's `rtcOccluded8` on the frame's shadow-ray list: median
    /// ms of interleaved rounds (`None`: Embree not built).
    pub trace_ms: (f64, Option<f64>),
}

/// The section's measurements.
pub struct SoftShadows {
    pub rows: Vec<SoftShadowRow>,
    pub size: (u32, u32),
    pub threads: usize,
    pub pixels: usize,
    pub plot: Option<PathBuf>,
    pub notes: Vec<String>,
}

/// The 1,024-sample visibility per pixel (`None` on a miss or where no sample traced a
/// ray), traced with the scalar reference any-hit query.
fn reference_visibility(prepared: &PreparedScene, frame: &Frame, light: usize) -> Vec<Option<f32>> {
    let g = &prepared.geometry;
    let lights = frame_lights(&g.lights, REFERENCE_SAMPLES, REFERENCE_FRAME);
    let ao = AmbientOcclusion::default();
    frame
        .surfaces
        .par_iter()
        .map(|s| {
            if !s.is_hit() {
                return None;
            }
            // Every light's slots (`light_visibility` walks them all); the others trace none.
            let mut all = vec![0u8; lights_slots(&lights)];
            let first = lights_slots(&lights[..light]);
            for (sample, code) in all[first..first + REFERENCE_SAMPLES as usize].iter_mut().enumerate() {
                let slot = Slot::Light { light: light as u32, sample: sample as u32 };
                if !hyrt_core::kernels::soft_shadow::needs_slot_ray(s, &lights, &ao, slot) {
                    continue;
                }
                let ray = slot_ray(s, &lights, &ao, slot, sample as u32, 0);
                *code = hyrt_core::kernels::shadow::shadow_code(prepared.bvh.occluded(g.traversal_table(), &ray));
            }
            let mut v = vec![0.0f32; lights.len()];
            light_visibility(&all, &lights, s, &mut v);
            (v[light] >= 0.0).then_some(v[light])
        })
        .collect()
}

/// Run the section on the CPU backend with `threads` workers (all when `None`).
pub fn run(options: &BenchOptions, progress: &ProgressBar) -> Result<SoftShadows, BenchError> {
    let bench = super::scenes::load_manifest(SCENE).map_err(BenchError::Options)?;
    let scene = bench.scene;
    let (w, h) = (options.table_size.0 / 2, options.table_size.1 / 2);
    let camera = CameraRecord::new(&scene.camera.expect("the manifest has a camera"), w, h);
    let mut cpu = CpuBackend::new(options.frame_threads);
    let threads = cpu.threads();
    let prepared = cpu.prepare(hyrt_core::geometry::WorldGeometry::build(&scene), Default::default());
    let render = |source| BenchError::Render { scene: SCENE.to_string(), source };
    let light = prepared.geometry.lights.iter().position(|l| l.is_area()).expect("the scene has an area light");
    let mut notes = Vec::new();

    // The reference: visibility from 1,024 samples, the image from four 256-sample frames.
    progress.set_message("soft shadows: the 1,024-sample reference");
    let outputs = FrameOptions { shadow_samples: 1, denoise: false, ..FrameOptions::with_stage_outputs() };
    let surfaces = cpu.render(&prepared, &camera, &outputs).map_err(render)?;
    let reference = reference_visibility(&prepared, &surfaces, light);
    let parts = REFERENCE_SAMPLES / 256;
    let mut image = vec![[0.0f32; 4]; (w * h) as usize];
    for k in 0..parts {
        let opts = FrameOptions {
            shadow_samples: 256,
            denoise: false,
            frame_index: REFERENCE_FRAME + 1 + k,
            ..Default::default()
        };
        let f = cpu.render(&prepared, &camera, &opts).map_err(render)?;
        for (a, b) in image.iter_mut().zip(&f.final_image) {
            for c in 0..4 {
                a[c] += b[c] / parts as f32;
            }
        }
    }

    let mut rows = Vec::new();
    for &samples in &SAMPLES {
        for denoise in [false, true] {
            progress.set_message(format!("soft shadows: {samples} samples{}", if denoise { ", denoised" } else { "" }));
            let opts = FrameOptions { shadow_samples: samples, denoise, ..Default::default() };
            let (summary, frames) =
                measure_frames_with(&mut cpu, &prepared, &camera, options.frames, &opts).map_err(render)?;
            let step = |stage: Stage| {
                let v: Vec<f64> = frames.iter().filter_map(|f| f.ms(stage)).collect();
                median(&v)
            };
            let f = cpu.render(&prepared, &camera, &FrameOptions { stage_outputs: true, ..opts }).map_err(render)?;
            let lighting = prepared.frame_lighting(&opts);
            let slots = lighting.slots();
            let (mut sum, mut n) = (0.0f64, 0usize);
            let mut v = vec![0.0f32; lighting.lights.len()];
            for (i, s) in f.surfaces.iter().enumerate() {
                let Some(want) = reference[i] else { continue };
                let got = if denoise {
                    f.visibility[i * f.plan.visibility_channels() as usize]
                } else {
                    light_visibility(&f.shadow[i * slots..(i + 1) * slots], lighting.lights(), s, &mut v);
                    v[light]
                };
                let e = got.max(0.0) as f64 - want as f64;
                sum += e * e;
                n += 1;
            }
            let rmse = (sum / n.max(1) as f64).sqrt();
            let flip = hyrt_accuracy::metrics::flip_mean(&image, &f.final_image, w, h);
            let trace_ms = trace_contest(&prepared, &f, threads, options.repeats);
            rows.push(SoftShadowRow {
                samples,
                denoise,
                frame_ms: summary.frame_ms,
                shadow_rays_ms: step(Stage::ShadowRays).unwrap_or(f64::NAN),
                denoise_ms: step(Stage::ShadowDenoise),
                rmse,
                flip,
                rays: f.rays.len(),
                trace_ms,
            });
        }
    }
    if rows.iter().any(|r| r.trace_ms.1.is_none()) {
        notes.push(format!("Embree: {}", super::peers::embree_peer()));
    }
    let path = options.out_dir.join(PLOT);
    let series = [false, true]
        .into_iter()
        .map(|d| Series {
            label: if d { "denoised (shadow_denoise)".into() } else { "raw samples".into() },
            points: rows.iter().filter(|r| r.denoise == d).map(|r| (r.frame_ms, r.rmse)).collect(),
        })
        .collect();
    let plot = Plot {
        title: format!("Soft shadows: visibility error against frame time ({SCENE}, 1, 2, 4, 16 samples)"),
        x_label: "frame time (ms, median)".into(),
        y_label: "visibility RMSE against 1,024 samples".into(),
        log_x: true,
        log_y: true,
        x_format: plots::plain,
        series,
    };
    let plot = match plots::draw(&plot, &path) {
        Ok(()) => Some(path),
        Err(e) => {
            notes.push(format!("plot not drawn: {e}"));
            None
        }
    };
    let pixels = reference.iter().filter(|r| r.is_some()).count();
    Ok(SoftShadows { rows, size: (w, h), threads, pixels, plot, notes })
}

/// The frame's shadow-ray list traced by hyrt's packets (the stages' traversal) and by
/// Embree's `rtcOccluded8`, interleaved: their median milliseconds.
fn trace_contest(prepared: &PreparedScene, frame: &Frame, threads: usize, rounds: usize) -> (f64, Option<f64>) {
    let rays = &frame.rays;
    let g = &prepared.geometry;
    let pool = super::peers::contest_pool(threads);
    let mut out = Vec::new();
    let mut hyrt =
        || pool.install(|| occluded_batch_into(&prepared.bvh, g.traversal_table(), rays, Traversal::simd(), &mut out));
    #[cfg(feature = "embree")]
    {
        let config = format!("threads={threads}");
        if let Ok(e) = super::embree::EmbreeScene::new(g, &config) {
            let mut o = vec![false; rays.len()];
            let mut embree = || {
                pool.install(|| {
                    o.par_chunks_mut(hyrt_cpu::traversal::TRAVERSAL_CHUNK)
                        .zip(rays.par_chunks(hyrt_cpu::traversal::TRAVERSAL_CHUNK))
                        .for_each(|(o, r)| e.occluded8(r, o))
                })
            };
            let ms = interleaved_ms(rounds, &mut [&mut hyrt, &mut embree]);
            return (median(&ms[0]).unwrap_or(f64::NAN), median(&ms[1]));
        }
    }
    let ms = interleaved_ms(rounds, &mut [&mut hyrt]);
    (median(&ms[0]).unwrap_or(f64::NAN), None)
}

impl SoftShadows {
    /// The report section.
    pub fn section(&self, dir: &std::path::Path) -> Section {
        let mut md = String::new();
        let (w, h) = self.size;
        let _ = writeln!(
            md,
            "`assets/scenes/{SCENE}.toml` at {w}x{h}, {} threads (the CPU backend; frames with area lights run \
             staged): the quad light's visibility from {} shadow rays per pixel, shaded from the raw samples and \
             through `shadow_denoise`, against {REFERENCE_SAMPLES} samples of an independent stream traced per pixel \
             ({} pixels with an estimate). Visibility RMSE over those pixels; FLIP of the final image against the \
             mean of four 256-sample frames; medians of frames; the frame's shadow-ray list traced alone by hyrt's \
             packets and by Embree's `rtcOccluded8`, interleaved.\n",
            self.threads,
            SAMPLES.map(|s| s.to_string()).join(", "),
            count(self.pixels as u64),
        );
        let mut t = Table::new([
            "samples",
            "denoiser",
            "visibility RMSE",
            "FLIP",
            "frame (ms)",
            "`shadow_rays` (ms)",
            "`shadow_denoise` (ms)",
            "rays",
            "trace: hyrt (ms)",
            "trace: Embree (ms)",
            "Embree / hyrt",
        ]);
        for r in &self.rows {
            t.row([
                r.samples.to_string(),
                if r.denoise { "yes" } else { "no" }.to_string(),
                num(r.rmse, 4),
                num(r.flip, 4),
                num(r.frame_ms, 1),
                num(r.shadow_rays_ms, 1),
                r.denoise_ms.map_or("-".into(), |m| num(m, 1)),
                count(r.rays as u64),
                num(r.trace_ms.0, 1),
                r.trace_ms.1.map_or("-".into(), |m| num(m, 1)),
                r.trace_ms.1.map_or("-".into(), |m| num(m / r.trace_ms.0, 2)),
            ]);
        }
        md += &t.to_markdown();
        if let Some(p) = &self.plot {
            let _ = writeln!(md, "\n![visibility error against frame time]({})", link(dir, p));
        }
        for n in &self.notes {
            let _ = writeln!(md, "- {n}");
        }
        Section::new("Soft shadows: samples, the denoiser and the error", md)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The section at a small size: every row measured, the error falling with the
    /// samples, the denoiser below the raw samples at one sample per pixel, and the table.
    #[test]
    fn the_section_measures_every_row_and_the_denoiser_helps() {
        let dir = std::env::temp_dir().join(format!("hyrt-soft-shadows-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let options = BenchOptions { frames: 1, repeats: 1, table_size: (160, 90), ..BenchOptions::quick(dir.clone()) };
        let s = run(&options, &ProgressBar::hidden()).unwrap();
        assert_eq!(s.rows.len(), SAMPLES.len() * 2);
        let rmse = |samples: u32, denoise: bool| {
            s.rows.iter().find(|r| r.samples == samples && r.denoise == denoise).map(|r| r.rmse).unwrap()
        };
        for r in &s.rows {
            eprintln!(
                "{} samples, denoise {}: rmse {:.4}, flip {:.4}, {} rays",
                r.samples, r.denoise, r.rmse, r.flip, r.rays
            );
            assert!(r.rmse.is_finite() && r.flip.is_finite() && r.rays > 0);
        }
        assert!(rmse(16, false) < rmse(1, false), "more samples, less error");
        assert!(rmse(1, true) < rmse(1, false), "the denoiser lowers the error at one sample");
        let md = s.section(&dir).markdown;
        assert!(md.contains("| 16 | yes |"), "{md}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
