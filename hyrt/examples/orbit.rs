//! Orbit the camera around a scene, move an object, switch it to ray traced, and
//! write each frame as a PNG: what a program using hyrt does, in one page.
//!
//! ```sh
//! cargo run --release -p hyrt --example orbit                      # the built-in scene
//! cargo run --release -p hyrt --example orbit -- ../shared/assets/DamagedHelmet.glb
//! ```
//!
//! The backend is a hardware GPU when there is one and the CPU reference otherwise
//! (`HYRT_GPU_ALLOW_SOFTWARE=1` accepts a software GPU such as lavapipe). Frames go to
//! `hyrt-orbit/` in the system's temporary folder (or the folder given second).

use std::f32::consts::TAU;
use std::path::PathBuf;

use hyrt::glam::{Mat4, Vec3};
use hyrt::{AdapterPolicy, BackendKind, Camera, Frame, FrameOptions, RenderMode, Renderer, Scene};

/// Frames around the orbit.
const FRAMES: u32 = 8;
/// Image size.
const WIDTH: u32 = 640;
const HEIGHT: u32 = 360;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mut scene = match args.next() {
        Some(path) => Scene::load(path.as_ref())?,
        None => Scene::default_scene(),
    };
    // A scene without lights gets two; one without a camera is framed (we orbit anyway).
    scene.ensure_camera_and_lights();
    let out = args.next().map(PathBuf::from).unwrap_or_else(|| std::env::temp_dir().join("hyrt-orbit"));
    std::fs::create_dir_all(&out)?;

    // Backend selection with fallback: a GPU when there is one, else the CPU.
    let mut renderer = Renderer::new(BackendKind::Auto, None, AdapterPolicy::from_env())?;
    println!("backend: {} ({})", renderer.choice(), renderer.choice_details());

    let (lo, hi) = scene.world_bounds().ok_or("the scene has no finite vertex")?;
    let (center, radius) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
    // Scenes are prepared once (world tables and BVH) and re-prepared after an edit.
    let mut prepared = renderer.prepare(&scene);
    // The frame's buffers are reused from frame to frame: no allocation per frame.
    let mut frame = Frame::default();
    for i in 0..FRAMES {
        if i == FRAMES / 3 && !scene.objects.is_empty() {
            // Move the first object up by a tenth of the scene's size.
            let lift = Mat4::from_translation(Vec3::Y * radius * 0.1);
            scene.objects[0].transform = lift * scene.objects[0].transform;
            prepared = renderer.prepare(&scene);
            println!("moved object '{}'", scene.objects[0].name);
        }
        if i == 2 * FRAMES / 3 && !scene.objects.is_empty() {
            // Switch it to ray traced: the plan now runs rt_shading for it.
            scene.objects[0].render_mode = RenderMode::RayTraced;
            prepared = renderer.prepare(&scene);
            println!("object '{}' is ray traced now", scene.objects[0].name);
        }
        let angle = i as f32 / FRAMES as f32 * TAU;
        let eye = center + Vec3::new(angle.sin(), 0.45, angle.cos()) * radius * 2.2;
        let camera = Camera::look_at(eye, center, Vec3::Y);
        renderer.render_into(&prepared, &camera, WIDTH, HEIGHT, &FrameOptions::default(), &mut frame)?;

        let path = out.join(format!("orbit_{i}.png"));
        hyrt::save_png(&frame, &path)?;
        let s = &frame.stats;
        let skipped: Vec<String> = s.skipped.iter().map(|k| format!("{} ({})", k.stage, k.reason)).collect();
        println!(
            "frame {i}: {:.1} ms, {} ray-traced pixels, {} shadow rays; skipped: {}; wrote {}",
            s.frame_ms(),
            s.ray_traced_pixels,
            s.rays_per_kind.iter().sum::<u64>(),
            if skipped.is_empty() { "nothing".into() } else { skipped.join(", ") },
            path.display()
        );
    }
    Ok(())
}
