//! The `hyrt` program: rendering, `--dump`, and clear errors for bad input.

use std::path::Path;
use std::process::Command;

mod common;

fn hyrt() -> Command {
    Command::new(env!("CARGO_BIN_EXE_hyrt"))
}

fn read_npy_shape(path: &Path) -> (Vec<u64>, String) {
    let bytes = std::fs::read(path).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    (npy.shape().to_vec(), npy.dtype().descr().to_string())
}

#[test]
fn cli_render_default_scene_with_dump() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("frame.png");
    let dump = dir.path().join("dump");
    let o = hyrt()
        .args(["render", "--size", "67x41", "--threads", "2", "--out"])
        .arg(&out)
        .arg("--dump")
        .arg(&dump)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("valid rays"), "{stdout}");
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (67, 41));

    for (file, shape, dtype) in [
        ("ids.npy", vec![41, 67, 2], "<u4"),
        ("bary.npy", vec![41, 67, 2], "<f4"),
        ("depth.npy", vec![41, 67], "<f4"),
        ("position.npy", vec![41, 67, 3], "<f4"),
        ("shadow.npy", vec![41, 67, 2], "|u1"),
        ("material.npy", vec![41, 67, 4], "<f4"),
    ] {
        let (s, d) = read_npy_shape(&dump.join(file));
        assert_eq!(s, shape, "{file}");
        assert!(d.contains(dtype), "{file}: dtype {d}");
    }
    let (rays_shape, rays_dtype) = read_npy_shape(&dump.join("rays.npy"));
    assert_eq!(rays_shape.len(), 1);
    for field in ["origin", "direction", "t_max", "pixel", "light", "occluded"] {
        assert!(rays_dtype.contains(field), "rays.npy lacks {field}: {rays_dtype}");
    }
    for png in ["raster.png", "rt.png", "final.png"] {
        let i = image::open(dump.join(png)).unwrap();
        assert_eq!((i.width(), i.height()), (67, 41), "{png}");
    }
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dump.join("frame.json")).unwrap()).unwrap();
    assert_eq!(json["width"], 67);
    assert_eq!(json["height"], 41);
    assert_eq!(json["objects"].as_array().unwrap().len(), 7);
    assert_eq!(json["objects"][0]["render_mode"], "ray_traced");
    assert_eq!(json["environment"], "default sky");
    // The default scene is shaded with the glTF BRDF (`--shading paper` for the paper's model).
    assert_eq!(json["shading"], "gltf");
    assert!((json["ambient"].as_f64().unwrap() - 0.06).abs() < 1e-7, "the default ambient");
    assert!(json["camera"]["view"].is_array() && json["camera"]["projection"].is_array());
    assert!(json["camera"]["conventions"].as_str().unwrap().contains("centre"));
    assert!(json["counts"]["valid_rays"].as_u64().unwrap() > 0);
    assert!(json["stage_ms"]["shadow_rays"].as_f64().is_some());
    // The CPU's default max depth 4: the golden sphere and the glass ball bounce; each
    // depth's buffers are dumped under its own name and counted in frame.json.
    let bounces = json["counts"]["bounces"].as_array().unwrap();
    assert_eq!(bounces.len(), 4, "{bounces:?}");
    assert!(bounces[0]["reflection_rays"].as_u64().unwrap() > 0 && bounces[0]["refraction_rays"].as_u64().unwrap() > 0);
    assert!(json["stage_ms"]["bounce_trace{4}"].as_f64().is_some(), "{}", json["stage_ms"]);
    let (shape, dtype) = read_npy_shape(&dump.join("bounce1_rays.npy"));
    assert_eq!(
        shape,
        vec![bounces[0]["reflection_rays"].as_u64().unwrap() + bounces[0]["refraction_rays"].as_u64().unwrap()]
    );
    assert!(dtype.contains("throughput"), "{dtype}");
    let (shape, _) = read_npy_shape(&dump.join("bounce1_links.npy"));
    assert_eq!(shape, vec![41 * 67, 2], "depth 1's parents are the pixels");
    // ids.npy holds (triangle, object) and 0xFFFFFFFF on miss, consistent with frame.json.
    let bytes = std::fs::read(dump.join("ids.npy")).unwrap();
    let ids: Vec<u32> = npyz::NpyFile::new(&bytes[..]).unwrap().into_vec().unwrap();
    let objects = json["objects"].as_array().unwrap();
    for px in ids.chunks(2) {
        if px[1] == u32::MAX {
            assert_eq!(px[0], u32::MAX);
        } else {
            assert!(px[0] < objects[px[1] as usize]["triangle_count"].as_u64().unwrap() as u32);
        }
    }
}

#[test]
fn cli_png_tone_map_follows_the_shading_model_unless_named() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, extra: &[&str]| {
        let out = dir.path().join(format!("{name}.png"));
        let o = hyrt()
            .args(["render", "--size", "32x24", "--max-depth", "1", "--out"])
            .arg(&out)
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        image::open(&out).unwrap().to_rgba8().into_raw()
    };
    // The glTF BRDF (the default scene's model) is displayed through Khronos PBR Neutral...
    let gltf = run("gltf", &[]);
    assert_eq!(gltf, run("gltf_neutral", &["--tone-map", "khronos-pbr-neutral"]));
    assert_ne!(gltf, run("gltf_none", &["--tone-map", "none"]));
    // ...the paper's model without an operator, as the paper's images are.
    let paper = run("paper", &["--shading", "paper"]);
    assert_eq!(paper, run("paper_none", &["--shading", "paper", "--tone-map", "none"]));
    assert_ne!(paper, run("paper_neutral", &["--shading", "paper", "--tone-map", "khronos-pbr-neutral"]));
}

#[test]
fn cli_camera_overrides_change_the_view() {
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &[&str]| {
        let out = dir.path().join(format!("f{}.png", extra.len()));
        let o = hyrt().args(["render", "--size", "32x24", "--out"]).arg(&out).args(extra).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        image::open(&out).unwrap().to_rgba8().into_raw()
    };
    let a = run(&[]);
    let b = run(&["--eye", "-6,3,6", "--target", "0,1,0", "--fov", "30", "--weight", "0.5"]);
    assert_ne!(a, b);
}

#[test]
fn cli_render_with_an_environment_map_to_openexr() {
    let dir = tempfile::tempdir().unwrap();
    // A 4 x 2 map: a bright upper half, a dark lower one.
    let map = dir.path().join("sky.exr");
    let texels: Vec<f32> = (0..8).flat_map(|k| if k < 4 { [4.0, 3.0, 2.0] } else { [0.01, 0.02, 0.03] }).collect();
    image::Rgb32FImage::from_raw(4, 2, texels).unwrap().save(&map).unwrap();
    let (png, exr) = (dir.path().join("frame.png"), dir.path().join("frame.EXR"));
    let render = |out: &Path, env: Option<&Path>| {
        let mut c = hyrt();
        c.args(["render", "--size", "48x27", "--threads", "2", "--max-depth", "2", "--out"]).arg(out);
        if let Some(env) = env {
            c.arg("--environment").arg(env);
        }
        let o = c.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let stdout = render(&exr, Some(&map));
    assert!(stdout.contains("environment: 4x2 map from") && stdout.contains("sky.exr"), "{stdout}");
    // The OpenEXR file holds the linear frame, 32-bit float (values above 1 stay).
    let img = image::open(&exr).unwrap();
    assert_eq!((img.width(), img.height(), img.color()), (48, 27, image::ColorType::Rgba32F));
    let with_map: Vec<f32> = img.into_rgba32f().into_raw();
    render(&png, None);
    assert_eq!(image::open(&png).unwrap().color(), image::ColorType::Rgba8, "other names are PNG");
    let sky_exr = dir.path().join("sky_frame.exr");
    assert!(render(&sky_exr, None).contains("environment: default sky"));
    let with_sky: Vec<f32> = image::open(&sky_exr).unwrap().into_rgba32f().into_raw();
    // The default scene's golden sphere reflects the map where its reflections leave.
    assert_ne!(with_map, with_sky);

    let bad = dir.path().join("sky.hdr");
    std::fs::write(&bad, "not an image").unwrap();
    let o = hyrt().args(["render", "--size", "8x8", "--environment"]).arg(&bad).output().unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("sky.hdr") && err.contains("environment map") && !err.contains("panicked"), "{err}");
}

#[test]
fn cli_errors_name_the_file_and_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.glb");
    let o = hyrt().arg("render").arg(&missing).output().unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("nope.glb"), "{err}");
    assert!(!err.contains("panicked"), "{err}");

    let garbage = dir.path().join("garbage.glb");
    std::fs::write(&garbage, b"this is not a glb file").unwrap();
    let o = hyrt().arg("render").arg(&garbage).arg("--out").arg(dir.path().join("x.png")).output().unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("garbage.glb") && !err.contains("panicked"), "{err}");

    let unknown = dir.path().join("scene.obj");
    std::fs::write(&unknown, b"v 0 0 0").unwrap();
    let o = hyrt().arg("render").arg(&unknown).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("scene.obj"));

    for bad in [["--size", "0x10"], ["--size", "12"], ["--weight", "2"], ["--eye", "1,2"], ["--fov", "0"]] {
        let o = hyrt().arg("render").args(bad).output().unwrap();
        assert!(!o.status.success(), "{bad:?} accepted");
        assert!(!String::from_utf8_lossy(&o.stderr).contains("panicked"));
    }

    let o =
        hyrt().args(["render", "--size", "8x8", "--out"]).arg(dir.path().join("no/such/dir/x.png")).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("x.png"));
}

#[test]
fn cli_renders_shared_sponza_and_says_what_it_added() {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets");
    if !assets.is_dir() {
        eprintln!("skipping: {} not found", assets.display());
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sponza.png");
    let o = hyrt()
        .arg("render")
        .arg(assets.join("sponza.glb"))
        .args(["--size", "96x54", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no camera") && err.contains("no lights"), "notes missing: {err}");
    // An interior: seen from inside (core/tests/framing.rs checks what the view shows).
    assert!(err.contains("camera placed inside") && err.contains("lights inside"), "{err}");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("66454 triangles"), "{stdout}");
    assert_eq!(image::open(&out).unwrap().width(), 96);
}

#[test]
fn cli_frames_reports_the_median_of_several_frames() {
    let dir = tempfile::tempdir().unwrap();
    let o = hyrt()
        .args(["render", "--size", "24x16", "--frames", "3", "--out"])
        .arg(dir.path().join("f.png"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("median of 3 frames") && stdout.contains("shadow_rays"), "{stdout}");
    // The cold cost apart from the warm one.
    let line = |prefix: &str| stdout.lines().find(|l| l.starts_with(prefix)).map(str::to_string);
    let cold = line("cold: ").unwrap_or_else(|| panic!("no cold line: {stdout}"));
    assert!(cold.contains("backend start") && cold.contains("first frame") && cold.contains("wall clock"), "{cold}");
    let warm = line("warm: ").unwrap_or_else(|| panic!("no warm line: {stdout}"));
    assert!(warm.contains("median of 2 frames after the first"), "{warm}");
    let o = hyrt().args(["render", "--size", "24x16", "--out"]).arg(dir.path().join("g.png")).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("warm: not measured (one frame"), "{stdout}");
    let o = hyrt().args(["render", "--frames", "0"]).output().unwrap();
    assert!(!o.status.success());
}

#[test]
fn cli_conformance_writes_a_report_and_fails_on_an_unknown_filter() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("conf");
    // The CPU on one thread against the two-thread reference must be exact.
    let o = hyrt().args(["conformance", "--against", "cpu1", "--filter", "size_", "--out"]).arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("### size_1x1") && report.contains("| visibility_raster | gbuffer |"), "{report}");
    assert!(report.contains("Beyond the recorded deviations: 0"), "{report}");
    let o = hyrt()
        .args(["conformance", "--against", "cpu1", "--filter", "no_such_case", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("no corpus case matches 'no_such_case'"));
}

/// A frame too large for the memory it may use is refused with a clear message naming the
/// size, the bytes needed and those available, and a non-zero exit: no abort. The cap
/// (`HYRT_MEMORY_LIMIT`, 2 GB) makes the refusal the same on every machine; the
/// 16384x16384 default-scene frame needs at least 37 GB on the CPU backend.
#[test]
fn cli_refuses_a_frame_too_large_for_memory() {
    let dir = tempfile::tempdir().unwrap();
    let o = hyrt()
        .env(hyrt_cpu::memory::MEMORY_LIMIT_ENV, "2000000000")
        .args(["render", "--size", "16384x16384", "--threads", "2", "--out"])
        .arg(dir.path().join("huge.png"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("16384x16384 frame does not fit in memory on the cpu backend"), "{stderr}");
    assert!(stderr.contains("bytes needed") && stderr.contains("2000000000 bytes available"), "{stderr}");
    assert!(!stderr.contains("memory allocation of"), "{stderr}");
    assert!(!dir.path().join("huge.png").exists());
}

/// `--barycentrics reintersected` renders an image of the asked size, as the raster's
/// barycentrics do; an unknown source is refused by the argument parser.
#[test]
fn cli_renders_with_reintersected_barycentrics() {
    let dir = tempfile::tempdir().unwrap();
    let mut images = Vec::new();
    for source in ["raster", "reintersected"] {
        let out = dir.path().join(format!("{source}.png"));
        let o = hyrt()
            .args(["render", "--size", "48x32", "--threads", "2", "--barycentrics", source, "--out"])
            .arg(&out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{source}: {}", String::from_utf8_lossy(&o.stderr));
        images.push(image::open(&out).unwrap().to_rgba8());
    }
    assert_eq!(images[0].dimensions(), (48, 32));
    assert_eq!(images[0].dimensions(), images[1].dimensions());
    let o = hyrt().args(["render", "--barycentrics", "guessed"]).output().unwrap();
    assert!(!o.status.success());
}

/// Issue 34 on the CPU backend: a one-model manifest renders its file's PNG (the GPU's in
/// `cli/tests/gpu.rs`, the features one by one in `hyrt/tests/manifest_paths.rs`).
#[test]
fn cli_one_model_manifest_writes_the_files_png() {
    common::assert_one_model_manifests_render_their_files(&["--backend", "cpu"]);
}
