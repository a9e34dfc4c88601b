//! Animated glTF scenes from the command line and through the library: `--time`,
//! `--animation`, `--frames N --fps F`, and the CPU backend's object ids following the
//! animated box (`assets/scenes/animated_box.gltf`, built by `core/tests/animation.rs`).

use std::path::{Path, PathBuf};
use std::process::Command;

use hyrt::{BackendKind, FrameOptions, Renderer, Scene};

fn hyrt() -> Command {
    Command::new(env!("CARGO_BIN_EXE_hyrt"))
}

fn sample() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/animated_box.gltf")
}

/// The box's object id in the sample scene (node 1, after the ground).
const BOX: u32 = 1;

/// The mean pixel column of the box's pixels and how many there are, in a frame of the
/// sample scene posed at `t` seconds of animation `move`, rendered by the CPU backend.
fn box_pixels(t: f32) -> (f32, usize) {
    let mut scene = Scene::load(&sample()).unwrap();
    scene.set_time(0, t).unwrap();
    let mut renderer = Renderer::new(BackendKind::Cpu, Some(2), hyrt::AdapterPolicy::from_env()).unwrap();
    let prepared = renderer.prepare(&scene);
    let (w, h) = (96, 54);
    let options = FrameOptions { stage_outputs: true, ..FrameOptions::default() };
    let mut frame = hyrt::Frame::default();
    renderer.render_into(&prepared, &scene.camera.unwrap(), w, h, &options, &mut frame).unwrap();
    let columns: Vec<usize> =
        frame.gbuffer.iter().enumerate().filter(|(_, g)| g.object == BOX).map(|(i, _)| i % w as usize).collect();
    (columns.iter().sum::<usize>() as f32 / columns.len().max(1) as f32, columns.len())
}

#[test]
fn the_cpu_backend_sees_the_box_move_from_left_to_right() {
    // The box goes from x = -1 at 0 s to x = +1 at 1 s, in front of a camera at x = 0.
    let (left, seen_left) = box_pixels(0.0);
    let (right, seen_right) = box_pixels(1.0);
    assert!(seen_left > 20 && seen_right > 20, "the box is in view: {seen_left} and {seen_right} pixels");
    assert!(left < 48.0 && right > 48.0, "the box crosses the middle column 48: {left} then {right}");
}

#[test]
fn cli_renders_numbered_frames_of_an_animation() {
    let dir = tempfile::tempdir().unwrap();
    let o = hyrt()
        .arg("render")
        .arg(sample())
        .args(["--size", "48x27", "--threads", "2", "--frames", "3", "--fps", "2", "--time", "0.5", "--out"])
        .arg(dir.path().join("anim.png"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    for (i, t) in [(0, "0.5000"), (1, "1.0000"), (2, "1.5000")] {
        assert!(stdout.contains(&format!("anim_000{i}.png (t = {t} s)")), "{stdout}");
    }
    assert!(!dir.path().join("anim.png").exists(), "frames are numbered, no unnumbered image");
    let frames: Vec<Vec<u8>> = (0..3)
        .map(|i| image::open(dir.path().join(format!("anim_000{i}.png"))).unwrap().to_rgb8().into_raw())
        .collect();
    assert!(frames[0] != frames[1] && frames[1] != frames[2], "the scene moves between frames");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("2 animation(s): 'move' (2.000 s), 'dolly' (2.000 s)"), "{stderr}");
}

#[test]
fn cli_time_picks_the_pose_and_the_animation_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let render = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let o = hyrt()
            .arg("render")
            .arg(sample())
            .args(["--size", "48x27", "--out"])
            .arg(&out)
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        image::open(out).unwrap().to_rgb8().into_raw()
    };
    let rest = render("rest.png", &[]);
    assert_eq!(
        render("zero.png", &["--time", "0"]),
        render("again.png", &["--time", "-3"]),
        "clamped to the first key"
    );
    assert_eq!(render("end.png", &["--time", "2"]), render("late.png", &["--time", "50"]), "clamped to the last key");
    assert_ne!(render("dolly.png", &["--time", "1", "--animation", "dolly"]), rest, "the camera moved");
}

#[test]
fn cli_animation_options_on_a_scene_without_animations_or_a_missing_name_are_errors() {
    let o = hyrt().args(["render", "--size", "8x8", "--time", "1"]).output().unwrap();
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("the default scene has no animations"), "{stderr}");
    let o = hyrt().arg("render").arg(sample()).args(["--size", "8x8", "--animation", "walk"]).output().unwrap();
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("has no animation 'walk' (it has 'move', 'dolly')"), "{stderr}");
    for bad in [["--fps", "0"], ["--time", "inf"]] {
        let o = hyrt().arg("render").arg(sample()).args(bad).output().unwrap();
        assert!(!o.status.success(), "{bad:?}");
    }
}
