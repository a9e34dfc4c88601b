//! Move an object between frames without preparing the scene again: the scene is
//! prepared once with the object moving (a two-level BVH, the object in its own space),
//! then each frame changes its transform in the scene, calls `move_objects` (its world
//! triangles and its instance rewritten, the top level rebuilt, no bottom level touched)
//! and renders. Halfway it also switches the object between ray traced and rasterized.
//!
//! ```sh
//! cargo run --release -p hyrt --example moving                      # the built-in scene's sphere
//! cargo run --release -p hyrt --example moving -- assets/scenes/teaser.toml bunny
//! ```
//!
//! Renders on the CPU backend (`BackendKind::Cpu`; the GPU backend renders the same frames).
//! Frames go to
//! `hyrt-moving/` in the system's temporary folder; each line says what the move cost
//! against preparing the whole scene again.

use std::f32::consts::TAU;
use std::time::Instant;

use hyrt::glam::{Mat4, Quat, Vec3};
use hyrt::{AdapterPolicy, BackendKind, Frame, FrameOptions, RenderMode, Renderer, Scene};

const FRAMES: u32 = 12;
const WIDTH: u32 = 640;
const HEIGHT: u32 = 360;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mut scene = match args.next() {
        Some(path) => Scene::load(path.as_ref())?,
        None => Scene::default_scene(),
    };
    scene.ensure_camera_and_lights();
    let name = args.next().unwrap_or_else(|| "sphere".into());
    let object = scene
        .objects
        .iter()
        .position(|o| o.name.to_lowercase().contains(&name.to_lowercase()))
        .ok_or_else(|| format!("no object named like '{name}' in the scene"))? as u32;
    let out = std::env::temp_dir().join("hyrt-moving");
    std::fs::create_dir_all(&out)?;

    let mut renderer = Renderer::new(BackendKind::Cpu, None, AdapterPolicy::HardwareOnly)?;
    let camera = scene.camera.ok_or("the scene has no camera")?;
    let mut frame = Frame::default();
    let t = Instant::now();
    let baked = renderer.prepare(&scene);
    let prepare_ms = t.elapsed().as_secs_f64() * 1e3;
    renderer.render_into(&baked, &camera, WIDTH, HEIGHT, &FrameOptions::default(), &mut frame)?;
    let mut prepared = renderer.prepare_moving(&scene, &[object]);
    println!(
        "moving '{}' ({} triangles of {}); preparing the whole scene takes {prepare_ms:.1} ms, \
         a frame of it baked into one tree {:.1} ms",
        scene.objects[object as usize].name,
        scene.meshes[scene.objects[object as usize].mesh].indices.len(),
        prepared.geometry.triangles.len(),
        frame.stats.frame_ms(),
    );
    let rest = scene.objects[object as usize].transform;
    let (lo, hi) = scene.world_bounds().ok_or("the scene has no finite vertex")?;
    let radius = (hi - lo).length() * 0.02;
    for i in 0..FRAMES {
        let angle = i as f32 / FRAMES as f32 * TAU;
        // Around a small circle, turning as it goes.
        let step = Mat4::from_rotation_translation(
            Quat::from_rotation_y(angle),
            Vec3::new(angle.cos(), 0.0, angle.sin()) * radius,
        );
        let o = &mut scene.objects[object as usize];
        o.transform = Mat4::from_translation(rest.w_axis.truncate())
            * step
            * Mat4::from_translation(-rest.w_axis.truncate())
            * rest;
        if i == FRAMES / 2 {
            o.render_mode = match o.render_mode {
                RenderMode::RayTraced => RenderMode::Raster,
                RenderMode::Raster => RenderMode::RayTraced,
            };
        }
        let t = Instant::now();
        prepared.move_objects(&scene, &[object])?;
        let move_ms = t.elapsed().as_secs_f64() * 1e3;
        renderer.render_into(&prepared, &camera, WIDTH, HEIGHT, &FrameOptions::default(), &mut frame)?;
        let path = out.join(format!("frame_{i:02}.png"));
        hyrt::save_png(&frame, &path)?;
        println!("frame {i:2}: move {move_ms:6.2} ms, frame {:6.1} ms -> {}", frame.stats.frame_ms(), path.display());
    }
    Ok(())
}
