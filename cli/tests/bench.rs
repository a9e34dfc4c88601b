//! `hyrt bench` end to end on the built-in default scene at tiny sizes (seconds, not
//! minutes): the report's sections, its counts against a direct render, the plots.
//! No timing is asserted.

use std::path::Path;
use std::process::{Command, Output};

use hyrt::{FrameOptions, Renderer, Scene};

/// Tiny settings: one frame, one repetition, two small sizes.
const TINY: [&str; 14] = [
    "bench",
    "--scenes",
    "default",
    "--frames",
    "1",
    "--repeats",
    "1",
    "--table-size",
    "48x32",
    "--sizes",
    "48x32,64x40",
    "--peer-threads",
    "1,2",
    "--quick",
];

fn bench(dir: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hyrt")).args(TINY).args(extra).arg("--out").arg(dir).output().unwrap()
}

/// Plots need DejaVu Sans (Debian fonts-dejavu-core); without it `hyrt bench` must fail
/// and say so. Returns true when the font is there.
fn font_or_clear_error(o: &Output) -> bool {
    if Path::new(hyrt_benches::bench::plots::FONT_PATH).is_file() {
        return true;
    }
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("fonts-dejavu-core"), "{err}");
    eprintln!("{} missing: checked the error message only", hyrt_benches::bench::plots::FONT_PATH);
    false
}

fn valid_rays_at(w: u32, h: u32) -> u64 {
    let mut scene = Scene::default_scene();
    scene.ensure_camera_and_lights();
    let mut r = Renderer::cpu(Some(1));
    let p = r.prepare(&scene);
    r.render(&p, &scene.camera.unwrap(), w, h, &FrameOptions::default()).unwrap().stats.ray_traced_pixels
}

#[test]
fn bench_cli_writes_the_report_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let o = bench(dir.path(), &["--no-gpu"]);
    if !font_or_clear_error(&o) {
        return;
    }
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    // Header, then the sections in order.
    assert!(md.starts_with("# hyrt benchmark report\n\nCommand: `"), "{md}");
    let order = [
        "## Table 2 reproduction (48x32)",
        "## Reflection and refraction: the frame at the default max depth",
        "## Peers in the same run",
        "## Scaling",
        "## Moving scenes",
        "### default: the sphere",
        "## Speed against error",
        "### Speed against error: default",
        "## Goals",
        "## Notes",
    ];
    let pos: Vec<usize> = order.iter().map(|s| md.find(s).unwrap_or_else(|| panic!("no {s} in\n{md}"))).collect();
    assert!(pos.windows(2).all(|w| w[0] < w[1]), "{pos:?}");
    // The paper's table is quoted; the default scene's row carries the same counts as a
    // direct render at that size.
    assert!(md.contains("| Bunny Scene 1 (Fig. 5) | 68,203 | 5 |"), "{md}");
    let rays = valid_rays_at(48, 32);
    assert!(rays > 0);
    assert!(
        md.contains(&format!("| default | - | 7,116 | - | {} |", hyrt_benches::bench::report::count(rays))),
        "{md}"
    );
    // Peers at both thread counts; the GPU was switched off and the report says so.
    assert!(md.contains("| hyrt `Bvh::occluded` per ray (scalar reference) | 1 |"), "{md}");
    assert!(md.contains("| hyrt `Bvh::closest_hit` per ray (scalar reference) | 2 |"), "{md}");
    // The frame per stage with each shadow traversal (the default scene: no teaser here).
    assert!(md.contains("### default: the CPU frame per stage, shadow rays scalar (before)"), "{md}");
    assert!(md.contains("| scalar (ms) |") && md.contains("| scalar / packets |"), "{md}");
    // The packets the stage uses, against the scalar reference: no ray differs.
    let packets = format!("| hyrt packets of 8 (`{}`) | 2 |", hyrt_cpu::traversal::Traversal::simd().name());
    let row = md.lines().find(|l| l.starts_with(&packets)).unwrap_or_else(|| panic!("no {packets} in\n{md}"));
    assert!(row.ends_with("| 0 |") || row.ends_with("| 0 | 0 |"), "{row}");
    assert!(md.contains("GPU backend not measured"), "{md}");
    if cfg!(feature = "embree") {
        assert!(md.contains("| Embree `rtcOccluded8` (packets of 8) | 2 |"), "{md}");
        assert!(md.contains("| Embree `rtcOccluded8` (packets of 8, coherent context) | 2 |"), "{md}");
        assert!(md.contains("| Embree `rtcIntersect8` (packets of 8) | 1 |"), "{md}");
    } else {
        assert!(md.contains("Embree: not built"), "{md}");
    }
    assert!(dir.path().join("accuracy-default.png").is_file(), "the speed-against-error plot");
    for plot in ["scaling_pixels.png", "scaling_triangles.png"] {
        assert!(md.contains(&format!("]({plot})")), "{plot} not linked");
        let img = image::open(dir.path().join(plot)).unwrap();
        assert_eq!((img.width(), img.height()), hyrt_benches::bench::plots::PLOT_SIZE);
    }
    // The default scene's frame with bounces, per step: each depth's stages named.
    for step in ["| `secondary_rays{1}` |", "| `bounce_trace{4}` |", "| `bounce_shading{1}` |", "| `rt_shading` |"] {
        assert!(md.contains(step), "no {step} in\n{md}");
    }
    // Two sizes in the pixel scaling, on the CPU.
    assert!(md.contains("| 48x32 | 1,536 |") && md.contains("| 64x40 | 2,560 |"), "{md}");
}

#[test]
fn bench_cli_with_a_software_gpu_labels_it() {
    let dir = tempfile::tempdir().unwrap();
    let o = bench(dir.path(), &["--allow-software-gpu", "--peer-threads", "1"]);
    if !font_or_clear_error(&o) {
        return;
    }
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    if md.contains("GPU backend not measured") {
        eprintln!("no Vulkan adapter: the report says so");
        return;
    }
    // A GPU column beside the CPU one, and the raster peer table.
    let short = if md.contains("SOFTWARE rasterizer") { "lavapipe" } else { "GPU" };
    assert!(md.contains(&format!("| {short} ms | {short} FPS |")), "{md}");
    assert!(md.contains(&format!("| default | {short} |")), "{md}");
    // The raster peer: the device's own raster and hyrt's exact kernels, both measured.
    assert!(md.contains(&format!("| {short} own / CPU | {short} ms, hyrt's exact kernels |")), "{md}");
    let row = md.lines().find(|l| l.starts_with("| default | ") && l.matches('|').count() == 7).unwrap();
    assert!(!row.contains(" - "), "both GPU modes measured: {row}");
    // The bounces on the GPU too: every step of the frame has a GPU time.
    let step = md.lines().find(|l| l.starts_with("| `bounce_trace{1}` |")).unwrap_or_else(|| panic!("{md}"));
    assert!(!step.ends_with("| - |"), "the GPU traced the bounces: {step}");
}

#[test]
fn bench_cli_rejects_bad_settings() {
    let dir = tempfile::tempdir().unwrap();
    for bad in [["--frames", "0"], ["--sizes", "0x4"], ["--peer-threads", "0"]] {
        let o = Command::new(env!("CARGO_BIN_EXE_hyrt"))
            .args(["bench", "--out"])
            .arg(dir.path())
            .args(bad)
            .output()
            .unwrap();
        assert!(!o.status.success(), "{bad:?} accepted");
        assert!(!String::from_utf8_lossy(&o.stderr).is_empty());
    }
    assert!(!dir.path().join("report.md").exists());
}

/// `--simd` forces the traversals' SIMD level and the report says which ran (SSE2 exists on
/// every x86-64 CPU, the portable level everywhere); the peers' method names carry it.
#[test]
fn bench_cli_forces_a_simd_level_and_says_so() {
    let level = if cfg!(target_arch = "x86_64") { "sse2" } else { "portable" };
    let dir = tempfile::tempdir().unwrap();
    let o = bench(dir.path(), &["--no-gpu", "--no-accuracy", "--simd", level]);
    if !font_or_clear_error(&o) {
        return;
    }
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    let row = md.lines().find(|l| l.starts_with("| SIMD level of hyrt's traversals |")).expect("a SIMD row");
    let best = hyrt::SimdLevel::best();
    if best.name() == level {
        assert!(row.contains(&format!("{level} (this CPU's best)")), "{row}");
    } else {
        assert!(row.contains(&format!("{level} (forced")), "{row}");
    }
    assert!(md.contains(&format!("`packet-{level}`")), "the peers ran another level");
}
