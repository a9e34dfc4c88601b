//! The GPU backend end to end, against the CPU reference, on whatever Vulkan
//! adapter is present (lavapipe in CI). Stage-by-stage tolerances live in the
//! gpu-backend crate's tests; here: whole frames (the command line's GPU tests are in
//! `cli/tests/gpu.rs`).

use hyrt::glam::Vec3;
use hyrt::{AdapterPolicy, BackendKind, FrameOptions, Renderer, Scene};

mod common;

use common::gpu_renderer;

#[test]
fn gpu_frame_matches_cpu_frame_on_the_default_scene_and_sponza() {
    let Some(mut gpu) = gpu_renderer() else { return };
    eprintln!("{}", gpu.choice());
    let mut cpu = Renderer::cpu(Some(2));
    let mut cases = vec![(Scene::default_scene(), 96, 54, 1.0), (Scene::default_scene(), 67, 41, 0.5)];
    let sponza = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets/sponza.glb");
    if sponza.is_file() {
        let mut s = Scene::load(&sponza).unwrap();
        s.ensure_camera_and_lights();
        cases.push((s, 96, 54, 1.0));
    }
    for (scene, w, h, weight) in cases {
        let cam = scene.camera.unwrap();
        let prepared = cpu.prepare(&scene);
        let opts = FrameOptions { weight, ..FrameOptions::with_stage_outputs() };
        let c = cpu.render(&prepared, &cam, w, h, &opts).unwrap();
        let g = gpu.render(&prepared, &cam, w, h, &opts).unwrap();
        assert_eq!((g.width, g.height), (w, h));
        let pixels = (w * h) as usize;
        // Primary visibility, hit points' ids, the ray list's integers and every shadow
        // ray's outcome are identical (the per-stage float budgets and the hard cases are
        // in hyrt-conformance).
        assert!(c.gbuffer.iter().zip(&g.gbuffer).all(|(a, b)| bytemuck::bytes_of(a) == bytemuck::bytes_of(b)));
        let keys = |f: &hyrt::Frame| f.rays.iter().map(|r| (r.pixel, r.light, r.kind)).collect::<Vec<_>>();
        assert_eq!(keys(&c), keys(&g), "{w}x{h}: ray lists differ");
        assert_eq!(c.occluded, g.occluded, "{w}x{h}: shadow rays differ");
        assert_eq!(c.shadow, g.shadow);
        // Every stage's floats too: the surfaces, the ray list and the three images, bit
        // for bit (the corpus-wide check is in hyrt-conformance).
        for (what, a, b) in
            [("rt", &c.rt, &g.rt), ("raster", &c.raster, &g.raster), ("final", &c.final_image, &g.final_image)]
        {
            assert_eq!(bytemuck_bits(a), bytemuck_bits(b), "{w}x{h}: {what} image differs");
        }
        assert!(c.surfaces.iter().zip(&g.surfaces).all(|(a, b)| bytemuck::bytes_of(a) == bytemuck::bytes_of(b)));
        assert!(c.rays.iter().zip(&g.rays).all(|(a, b)| bytemuck::bytes_of(a) == bytemuck::bytes_of(b)));
        let pixels = pixels as u64;
        // Every step of the plan (bvh_build is per scene), the same plan as the CPU's.
        assert_eq!(g.stats.stage_ms.len(), g.plan.steps().len(), "{:?}", g.stats.stage_ms);
        assert_eq!(g.plan, c.plan);
        eprintln!("{w}x{h} weight {weight}: {pixels} pixels and {} rays identical", c.rays.len());
    }
}

#[test]
fn gpu_renders_again_with_reused_buffers_and_a_new_scene() {
    let Some(mut gpu) = gpu_renderer() else { return };
    let scene = Scene::default_scene();
    let cam = scene.camera.unwrap();
    let p1 = gpu.prepare(&scene);
    let a = gpu.render(&p1, &cam, 40, 30, &FrameOptions::with_stage_outputs()).unwrap();
    let mut small = Scene::default_scene();
    small.objects.truncate(3);
    let p2 = gpu.prepare(&small);
    let b = gpu.render(&p2, &cam, 40, 30, &FrameOptions::with_stage_outputs()).unwrap();
    assert_ne!(a.stats.covered_pixels, 0);
    assert!(b.gbuffer.iter().all(|t| !t.is_hit() || t.object < 3), "stale scene buffers");
    let c = gpu.render(&p1, &cam, 40, 30, &FrameOptions::with_stage_outputs()).unwrap();
    assert_eq!(bytemuck_bits(&a.final_image), bytemuck_bits(&c.final_image), "same frame twice differs");
}

fn bytemuck_bits(img: &[[f32; 4]]) -> Vec<u32> {
    img.iter().flat_map(|p| p.map(f32::to_bits)).collect()
}

#[test]
fn gpu_final_image_only_readback_gives_the_same_image_and_counts() {
    let Some(mut gpu) = gpu_renderer() else { return };
    let scene = Scene::default_scene();
    let cam = scene.camera.unwrap();
    let p = gpu.prepare(&scene);
    let all = gpu.render(&p, &cam, 48, 32, &FrameOptions::with_stage_outputs()).unwrap();
    let lean = gpu.render(&p, &cam, 48, 32, &FrameOptions::default()).unwrap();
    assert_eq!(bytemuck_bits(&all.final_image), bytemuck_bits(&lean.final_image));
    assert_eq!(all.stats.covered_pixels, lean.stats.covered_pixels);
    assert_eq!(all.stats.rays_per_kind, lean.stats.rays_per_kind);
    assert_eq!(all.stats.occluded_shadow_rays, lean.stats.occluded_shadow_rays);
    assert_eq!(all.rays.len() as u64, all.stats.rays_per_kind[0]);
    assert!(lean.rays.is_empty() && lean.surfaces.is_empty() && lean.rt.is_empty());
}

/// Reflection and refraction on the GPU backend through the facade: a close-up of the
/// default scene's glass ball, where nearly every pixel spawns two rays, more than the
/// room a first frame gives each bounce's list (a ray per four pixels), so the frame
/// runs again with room for them; the image is the CPU's, bit for bit, and a frame
/// without stage outputs gives the same image and bounce statistics. Depth 0 plans no
/// bounce.
#[test]
fn gpu_traces_bounces_and_makes_room_for_its_lists() {
    let Some(mut gpu) = gpu_renderer() else { return };
    let mut cpu = Renderer::new(BackendKind::Cpu, Some(2), AdapterPolicy::AllowSoftware).unwrap();
    let scene = Scene::default_scene();
    let mut cam = scene.camera.unwrap();
    cam.target = Vec3::new(-0.3, 0.65, 2.0);
    cam.eye = cam.target + Vec3::new(0.0, 0.3, 1.6);
    let (g, c) = (gpu.prepare(&scene), cpu.prepare(&scene));
    let opts = FrameOptions::with_stage_outputs();
    assert_eq!(opts.max_depth, hyrt::DEFAULT_MAX_DEPTH, "frames trace bounces by default");
    let (w, h) = (40, 30);
    let expected = cpu.render(&c, &cam, w, h, &opts).unwrap();
    let first =
        expected.stats.bounces[0].rays_per_kind.iter().sum::<u64>() - expected.stats.bounces[0].rays_per_kind[0];
    assert!(first > (w * h / 4) as u64, "{first} first-bounce rays must overflow the first room");
    let all = gpu.render(&g, &cam, w, h, &opts).unwrap();
    assert_eq!(bytemuck_bits(&all.final_image), bytemuck_bits(&expected.final_image));
    assert_eq!(all.stats.bounces, expected.stats.bounces);
    let lean = gpu.render(&g, &cam, w, h, &FrameOptions::default()).unwrap();
    assert_eq!(bytemuck_bits(&lean.final_image), bytemuck_bits(&expected.final_image));
    assert_eq!(lean.stats.bounces, expected.stats.bounces);
    assert!(lean.bounces.iter().all(|b| b.rays.is_empty()), "no stage outputs: no bounce buffer comes back");
    let flat = gpu.render(&g, &cam, w, h, &FrameOptions { max_depth: 0, ..FrameOptions::default() }).unwrap();
    assert!(flat.stats.bounces.is_empty());
}

/// The raster's primary barycentrics through the facade (the option beside the default
/// re-intersected ones): the GPU frame is the CPU's bit for bit, and its hit points are not
/// the default frame's.
#[test]
fn gpu_raster_barycentrics_match_the_cpu() {
    let Some(mut gpu) = gpu_renderer() else { return };
    let mut cpu = Renderer::cpu(Some(2));
    let scene = Scene::default_scene();
    let cam = scene.camera.unwrap();
    let (pg, pc) = (gpu.prepare(&scene), cpu.prepare(&scene));
    let options =
        FrameOptions { barycentrics: hyrt::PrimaryBarycentrics::Raster, ..FrameOptions::with_stage_outputs() };
    let g = gpu.render(&pg, &cam, 64, 36, &options).unwrap();
    let c = cpu.render(&pc, &cam, 64, 36, &options).unwrap();
    assert_eq!(bytemuck::cast_slice::<_, u8>(&g.surfaces), bytemuck::cast_slice::<_, u8>(&c.surfaces));
    assert_eq!(bytemuck_bits(&g.final_image), bytemuck_bits(&c.final_image));
    let exact = cpu.render(&pc, &cam, 64, 36, &FrameOptions::with_stage_outputs()).unwrap();
    assert!(exact.surfaces.iter().zip(&c.surfaces).any(|(a, b)| a.position != b.position));
}

/// A scene prepared with moving objects (two levels: the moved objects in their own space,
/// one of them mirrored and scaled, the rest baked into world space), moved between
/// frames: the GPU frame is the CPU's bit for bit, shadow rays, bounce hits and images,
/// before and after the moves and a deformation; the device takes the scene once, then
/// only what changed.
#[test]
fn gpu_two_level_frames_match_the_cpu_as_objects_move() {
    use hyrt::glam::{Mat4, Quat};
    let Some(mut gpu) = gpu_renderer() else { return };
    let mut cpu = Renderer::cpu(Some(2));
    let mut scene = Scene::default_scene();
    let moving: Vec<u32> = (0..scene.objects.len() as u32).filter(|&o| o % 2 == 1).collect();
    let first = moving[0] as usize;
    scene.objects[first].transform = Mat4::from_scale(Vec3::new(-1.2, 0.8, 1.0)) * scene.objects[first].transform;
    let mut prepared = cpu.prepare_moving(&scene, &moving);
    assert!(prepared.levels.is_some());
    let cam = scene.camera.unwrap();
    let opts = FrameOptions::with_stage_outputs();
    let (w, h) = (64, 40);
    let mut previous = None;
    for step in 0..4 {
        if step == 3 {
            // The last step deforms the golden sphere's mesh (a moving object): its level is
            // refitted.
            let sphere = scene.objects.iter().position(|o| o.name.contains("sphere")).unwrap();
            assert!(moving.contains(&(sphere as u32)));
            let mesh = scene.objects[sphere].mesh;
            for p in &mut scene.meshes[mesh].positions {
                *p *= 1.0 + 0.25 * (3.0 * p.y).sin();
            }
            prepared.deform_mesh(&scene, mesh).unwrap();
        } else if step > 0 {
            for &o in &moving {
                let turn = Mat4::from_rotation_translation(Quat::from_rotation_y(0.4), Vec3::new(0.2, 0.0, -0.1));
                scene.objects[o as usize].transform = turn * scene.objects[o as usize].transform;
            }
            prepared.move_objects(&scene, &moving).unwrap();
        }
        let c = cpu.render(&prepared, &cam, w, h, &opts).unwrap();
        let g = gpu.render(&prepared, &cam, w, h, &opts).unwrap();
        assert_eq!(c.occluded, g.occluded, "step {step}: shadow rays differ");
        assert_eq!(c.shadow, g.shadow, "step {step}");
        assert!(!c.bounces.is_empty() && c.bounces.len() == g.bounces.len());
        for (d, (a, b)) in c.bounces.iter().zip(&g.bounces).enumerate() {
            let bits =
                |h: &[hyrt::formats::HitRecord]| h.iter().map(|h| bytemuck::bytes_of(h).to_vec()).collect::<Vec<_>>();
            assert_eq!(bits(&a.hits), bits(&b.hits), "step {step}: bounce depth {} hits differ", d + 1);
            assert_eq!(a.occluded, b.occluded, "step {step}: bounce depth {} shadow rays differ", d + 1);
        }
        assert_eq!(bytemuck_bits(&c.final_image), bytemuck_bits(&g.final_image), "step {step}: final image differs");
        assert_ne!(Some(bytemuck_bits(&c.final_image)), previous, "step {step} changed nothing on screen");
        previous = Some(bytemuck_bits(&c.final_image));
        eprintln!("step {step}: {} shadow rays, {} bounce depths identical", c.occluded.len(), c.bounces.len());
        // The scene went to the device once; each move wrote only what changed.
        assert_eq!(gpu.gpu_backend().unwrap().scene_writes(), (1, step), "step {step}");
    }
}
