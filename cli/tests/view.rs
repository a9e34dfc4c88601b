//! `hyrt view` under X11: on the display of the session, or on an Xvfb each test starts
//! (on a display number Xvfb picks, killed at the end). In CI a missing Xvfb fails the test;
//! elsewhere it skips with the reason.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};

mod common;

use common::gpu_adapter;

/// An X display for the viewer: the session's, or an Xvfb this test owns.
struct Display {
    name: String,
    xvfb: Option<Child>,
}

impl Drop for Display {
    fn drop(&mut self) {
        if let Some(child) = &mut self.xvfb {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

fn display() -> Option<Display> {
    if let Some(d) = std::env::var_os("DISPLAY").filter(|d| !d.is_empty()) {
        return Some(Display { name: d.to_string_lossy().into_owned(), xvfb: None });
    }
    // Xvfb picks a free display number itself and writes it to `-displayfd` once it
    // accepts connections: no race with other tests or other Xvfbs on the machine.
    let child = Command::new("Xvfb")
        .args(["-displayfd", "1", "-screen", "0", "1280x1024x24", "-nolisten", "tcp"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn();
    let mut child = match child {
        Ok(c) => c,
        Err(e) => {
            assert!(std::env::var_os("CI").is_none(), "CI needs Xvfb for the viewer's test (Debian: xvfb): {e}");
            eprintln!("SKIPPED: no DISPLAY and no Xvfb ({e})");
            return None;
        }
    };
    let mut line = String::new();
    let read = BufReader::new(child.stdout.take().expect("piped")).read_line(&mut line);
    let display = Display { name: format!(":{}", line.trim()), xvfb: Some(child) };
    assert!(read.is_ok() && line.trim().parse::<u32>().is_ok(), "Xvfb did not start: {read:?} '{line}'");
    Some(display)
}

/// Run `hyrt` in `cwd` (where the viewer's P and O keys write) on `display`.
fn hyrt(display: Option<&Display>, cwd: &Path, args: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_hyrt"));
    cmd.args(args).current_dir(cwd).env("HYRT_GPU_ALLOW_SOFTWARE", "1");
    match display {
        Some(d) => cmd.env("DISPLAY", &d.name),
        None => cmd.env_remove("DISPLAY"),
    };
    let o = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("panicked"), "hyrt {args:?} panicked: {err}");
    o
}

fn ok(o: Output, what: &str) -> String {
    assert!(o.status.success(), "{what}: {}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn pixels(path: &Path) -> image::RgbaImage {
    image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgba8()
}

#[test]
fn viewer_screenshots_equal_render_and_clicks_pick_objects() {
    let Some(display) = display() else { return };
    let dir = tempfile::tempdir().unwrap();
    let camera = ["--size", "96x54", "--eye", "3.5,2.5,6", "--target", "0,0.5,0", "--fov", "50"];
    let mut backends = vec!["cpu"];
    if gpu_adapter() {
        backends.push("gpu");
    }
    for backend in backends {
        let shot = dir.path().join(format!("view-{backend}.png"));
        let rendered = dir.path().join(format!("render-{backend}.png"));
        let mut args = vec!["view", "--backend", backend, "--frames", "3", "--screenshot", shot.to_str().unwrap()];
        args.extend(camera);
        let out = ok(hyrt(Some(&display), dir.path(), &args), "hyrt view");
        assert!(out.contains("wrote"), "{out}");
        let mut args = vec!["render", "--backend", backend, "--out", rendered.to_str().unwrap()];
        args.extend(camera);
        ok(hyrt(None, dir.path(), &args), "hyrt render");
        let (a, b) = (pixels(&shot), pixels(&rendered));
        assert_eq!(a.dimensions(), (96, 54), "{backend}");
        assert!(a == b, "{backend}: the viewer's screenshot differs from hyrt render of the same camera");
        // The display's exposure and tone mapping, from the flags and from a script, as
        // hyrt render writes them.
        let tone = ["--exposure", "1.5", "--tone-map", "khronos-pbr-neutral"];
        let toned = dir.path().join(format!("toned-{backend}.png"));
        let mut args = vec!["render", "--backend", backend, "--out", toned.to_str().unwrap()];
        args.extend(camera);
        args.extend(tone);
        ok(hyrt(None, dir.path(), &args), "hyrt render --exposure");
        let shot = dir.path().join(format!("toned-view-{backend}.png"));
        let mut args = vec!["view", "--backend", backend, "--frames", "3", "--screenshot", shot.to_str().unwrap()];
        args.extend(camera);
        args.extend(tone);
        ok(hyrt(Some(&display), dir.path(), &args), "hyrt view --exposure");
        assert!(pixels(&shot) == pixels(&toned) && pixels(&toned) != b, "{backend}: exposure and tone map");

        // A script clicks the middle pixel (an object of the default scene), flips through
        // every view and writes one of them. With the paper's model: under the glTF BRDF a
        // diffuse object looks the same rasterized and ray traced (what that model is for),
        // so the change of mode would not show in the final image.
        let paper = dir.path().join(format!("paper-{backend}.png"));
        let mut args = vec!["render", "--backend", backend, "--shading", "paper", "--out", paper.to_str().unwrap()];
        args.extend(camera);
        ok(hyrt(None, dir.path(), &args), "hyrt render --shading paper");
        let script = dir.path().join("script.txt");
        let views: String = ["2", "3", "4", "5", "6", "7", "8", "9", "0", "-", "="]
            .iter()
            .enumerate()
            .map(|(i, k)| format!("{} view {k}\n", i + 1))
            .collect();
        std::fs::write(&script, format!("0 click 48 30\n{views}12 screenshot\n13 view 1\n")).unwrap();
        let shot = dir.path().join(format!("script-{backend}.png"));
        let mut args = vec!["view", "--backend", backend, "--frames", "14", "--screenshot", shot.to_str().unwrap()];
        args.extend(["--script", script.to_str().unwrap(), "--shading", "paper"]);
        args.extend(camera);
        let out = ok(hyrt(Some(&display), dir.path(), &args), "hyrt view --script");
        assert!(out.contains("pick (48, 30): object") && out.contains("is now"), "{out}");
        assert!(dir.path().join("hyrt-view-0000.png").exists(), "{out}");
        std::fs::remove_file(dir.path().join("hyrt-view-0000.png")).unwrap();
        // The picked object changed mode: the final image differs from the unpicked one.
        assert!(pixels(&shot) != pixels(&paper), "{backend}: picking changed nothing");
    }
}

#[test]
fn viewer_plays_animations_the_same_way_each_unattended_run() {
    let Some(display) = display() else { return };
    let dir = tempfile::tempdir().unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/animated_box.gltf");
    let script = dir.path().join("play.txt");
    std::fs::write(&script, "0 play\n").unwrap();
    let run = |name: &str, script: Option<&Path>| {
        let shot = dir.path().join(name);
        let mut args = vec!["view", scene.to_str().unwrap(), "--size", "64x36", "--frames", "6"];
        args.extend(["--screenshot", shot.to_str().unwrap()]);
        if let Some(s) = script {
            args.extend(["--script", s.to_str().unwrap()]);
        }
        ok(hyrt(Some(&display), dir.path(), &args), "hyrt view animated");
        pixels(&shot)
    };
    let (a, b, still) = (run("a.png", Some(&script)), run("b.png", Some(&script)), run("still.png", None));
    assert!(a == b, "two runs of the same script differ");
    assert!(a != still, "playing the animation moved nothing");
}

#[test]
fn viewer_closed_before_its_last_frame_says_the_screenshot_is_missing() {
    let Some(display) = display() else { return };
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("quit.txt");
    std::fs::write(&script, "1 quit\n").unwrap();
    let shot = dir.path().join("never.png");
    let args = ["view", "--size", "32x18", "--frames", "5", "--script", script.to_str().unwrap()];
    let o = hyrt(Some(&display), dir.path(), &[&args[..], &["--screenshot", shot.to_str().unwrap()]].concat());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("closed after 1 of 5 frames"), "{err}");
    assert!(!shot.exists());
}

#[test]
fn viewer_without_a_display_says_so() {
    let o = hyrt(None, &std::env::temp_dir(), &["view", "--frames", "1"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no window system") && err.contains("DISPLAY"), "{err}");
}
