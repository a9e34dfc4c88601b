//! Scaling: frame time against pixel count (one scene, several sizes) and against triangle
//! count (several scenes, one size), as tables and PNG plots.

use std::fmt::Write as _;
use std::path::PathBuf;

use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::FrameStats;
use hyrt_core::stage::Stage;
use indicatif::ProgressBar;

use super::plots::{self, Plot, Series};
use super::report::{count, num, Section, Table};
use super::scenes::{self, SceneSet};
use super::table2::Table2;
use super::{link, measure_frames, prepare, BenchError, BenchOptions, FrameBackend};

/// File names of the plots in the output folder.
pub const PIXELS_PLOT: &str = "scaling_pixels.png";
pub const TRIANGLES_PLOT: &str = "scaling_triangles.png";

/// The scaling section and the plot files it references.
pub struct Scaling {
    pub section: Section,
    pub files: Vec<PathBuf>,
}

/// One point of the triangle scaling.
struct TrianglePoint {
    scene: String,
    triangles: usize,
    valid_rays: u64,
    bvh_build_ms: f64,
    frame_ms: f64,
    shadow_ms: f64,
    shadow_rays: u64,
}

/// Measure both scalings and draw the plots.
pub fn run(
    options: &BenchOptions,
    table2: &Table2,
    cpu: &mut FrameBackend,
    mut gpu: Option<&mut FrameBackend>,
    notes: &mut Vec<String>,
    progress: &ProgressBar,
) -> Result<Scaling, BenchError> {
    let dir = &options.out_dir;
    let mut md = String::new();
    let mut files = Vec::new();

    // Pixel count: the teaser (or the default scene) at every size.
    let row = table2.rows.iter().find(|r| r.name == "teaser").unwrap_or(&table2.rows[0]);
    progress.inc_length(options.pixel_sizes.len() as u64 * (1 + gpu.is_some() as u64));
    let mut t = Table::new(["size", "pixels", "valid rays", "backend", "frame ms", "FPS", "ms per megapixel"]);
    let mut cpu_series = Series { label: cpu.label.clone(), points: Vec::new() };
    let mut gpu_series = gpu.as_ref().map(|g| Series { label: g.short.clone(), points: Vec::new() });
    for &(w, h) in &options.pixel_sizes {
        let camera = CameraRecord::new(&row.scene_camera, w, h);
        let mp = (w as f64 * h as f64) / 1e6;
        for (b, series) in
            std::iter::once((&mut *cpu, &mut cpu_series)).chain(gpu.as_deref_mut().zip(gpu_series.as_mut()))
        {
            progress.set_message(format!("scaling: {} at {w}x{h} ({})", row.name, b.short));
            let m = measure_frames(b.backend.as_mut(), &row.prepared, &camera, options.frames);
            progress.inc(1);
            match m {
                Ok((s, last)) => {
                    series.points.push((mp, s.frame_ms));
                    t.row([
                        format!("{w}x{h}"),
                        count((w as u64) * (h as u64)),
                        count(last.ray_traced_pixels),
                        b.short.clone(),
                        num(s.frame_ms, 1),
                        num(s.fps(), 1),
                        num(s.frame_ms / mp, 1),
                    ]);
                }
                Err(e) => notes.push(format!("scaling {} at {w}x{h} on {}: {e}", row.name, b.short)),
            }
        }
    }
    let mut series = vec![cpu_series];
    series.extend(gpu_series);
    let path = dir.join(PIXELS_PLOT);
    plots::draw(
        &Plot {
            title: format!("Frame time against pixel count ({})", row.name),
            x_label: "megapixels".into(),
            y_label: "frame time (ms, median)".into(),
            log_x: false,
            log_y: false,
            x_format: plots::plain,
            series,
        },
        &path,
    )?;
    let _ = writeln!(
        md,
        "### Pixel count\n\nScene {}, every stage but `bvh_build`.\n\n![frame time against pixel count]({})\n\n{}",
        row.name,
        link(dir, &path),
        t.to_markdown()
    );
    files.push(path);

    // Triangle count: scenes from the Table 2 run where present, the others loaded here.
    let (w, h) = options.table_size;
    let mut points: Vec<TrianglePoint> = Vec::new();
    let point_of =
        |name: &str, p: &hyrt_core::frame::PreparedScene, s: &super::FrameSummary, last: &FrameStats| TrianglePoint {
            scene: name.to_string(),
            triangles: p.geometry.triangle_count(),
            valid_rays: last.ray_traced_pixels,
            shadow_rays: last.rays_per_kind.iter().sum(),
            bvh_build_ms: p.bvh_build_ms,
            frame_ms: s.frame_ms,
            shadow_ms: s.ms(Stage::ShadowRays).unwrap_or(f64::NAN),
        };
    let wanted: Vec<&str> = if options.triangle_scaling && options.scenes == SceneSet::All {
        scenes::SCALING_MANIFESTS.to_vec()
    } else {
        vec![]
    };
    if wanted.is_empty() || scenes::shared_assets().is_none() {
        let r = &table2.rows[0];
        points.push(point_of(&r.name, &r.prepared, &r.cpu.0, &r.cpu.1));
    }
    progress.inc_length(wanted.len() as u64);
    for name in wanted {
        progress.set_message(format!("scaling: {name} (triangle count)"));
        if let Some(r) = table2.rows.iter().find(|r| r.name == name) {
            points.push(point_of(name, &r.prepared, &r.cpu.0, &r.cpu.1));
        } else {
            let loaded = scenes::load_manifests([name], SceneSet::All, notes);
            if let Some(s) = loaded.first() {
                let p = prepare(&s.scene, options.frame_threads);
                let camera = CameraRecord::new(&s.scene.camera.expect("bench scenes have a camera"), w, h);
                let (m, last) = measure_frames(cpu.backend.as_mut(), &p, &camera, options.frames)
                    .map_err(|source| BenchError::Render { scene: name.to_string(), source })?;
                points.push(point_of(name, &p, &m, &last));
            }
        }
        progress.inc(1);
    }
    points.sort_by_key(|p| p.triangles);
    let mut t = Table::new([
        "scene",
        "triangles",
        "valid rays",
        "shadow rays",
        "bvh_build ms",
        "shadow_rays ms",
        "shadow Mrays/s",
        "frame ms",
    ]);
    for p in &points {
        t.row([
            p.scene.clone(),
            count(p.triangles as u64),
            count(p.valid_rays),
            count(p.shadow_rays),
            num(p.bvh_build_ms, 1),
            num(p.shadow_ms, 2),
            num(super::stats::mrays_per_s(p.shadow_rays as usize, p.shadow_ms), 2),
            num(p.frame_ms, 1),
        ]);
    }
    let path = dir.join(TRIANGLES_PLOT);
    let pts = |f: fn(&TrianglePoint) -> f64| points.iter().map(|p| (p.triangles as f64, f(p))).collect::<Vec<_>>();
    plots::draw(
        &Plot {
            title: format!("Time against triangle count ({w}x{h}, CPU)"),
            x_label: "triangles (log scale)".into(),
            y_label: "ms (median, log scale)".into(),
            log_x: true,
            log_y: true,
            x_format: plots::si,
            series: vec![
                Series { label: "frame".into(), points: pts(|p| p.frame_ms) },
                Series { label: "shadow_rays stage".into(), points: pts(|p| p.shadow_ms) },
                Series { label: "bvh_build (once per scene)".into(), points: pts(|p| p.bvh_build_ms) },
            ],
        },
        &path,
    )?;
    let _ = writeln!(
        md,
        "\n### Triangle count\n\nEach scene with its own camera at {w}x{h} on the CPU backend ({}); the valid rays \
         and shadow rays differ from scene to scene, so frame time mixes triangle count with screen coverage; \
         the shadow-ray rate (Mrays/s) does not.\n\n\
         ![time against triangle count]({})\n\n{}",
        cpu.label,
        link(dir, &path),
        t.to_markdown()
    );
    files.push(path);
    Ok(Scaling { section: Section::new("Scaling", md), files })
}
