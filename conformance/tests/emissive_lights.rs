//! Emissive meshes as lights (`emissive_lights = true`) through manifests on both backends:
//! the GPU's frame is the CPU reference's on every stage buffer, bit for bit, raw and
//! denoised: the example manifest (`assets/scenes/emissive_lights.toml`: a panel and a
//! sphere glowing over a box and a ray-traced ball) and the real `DamagedHelmet.glb`,
//! whose emissive texture makes its emitter table, where the shared assets hold it.

use hyrt_conformance::compare::compare_stages;
use hyrt_conformance::corpus::shared_assets;
use hyrt_conformance::report::gpu_for_tests;
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, FrameOptions};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::scene::Scene;
use hyrt_cpu::backend::CpuBackend;

/// `scene` at `width` x `height`, 2 samples per area light, raw and denoised, on both
/// backends: every stage buffer and the ray counts alike. Returns the emitter count.
fn compare_both_ways(scene: &Scene, (width, height): (u32, u32), what: &str) -> usize {
    let Some(mut gpu) = gpu_for_tests() else { return 0 };
    let mut cpu = CpuBackend::new(Some(2));
    let g = WorldGeometry::build(scene);
    let emitters = g.emitters.len();
    assert!(emitters > 0, "{what}: no emitter");
    let prepared = cpu.prepare(g, BvhPreset::default());
    let camera = CameraRecord::new(&scene.camera.expect("a camera"), width, height);
    for denoise in [false, true] {
        let options = FrameOptions { stage_outputs: true, shadow_samples: 2, denoise, ..FrameOptions::default() };
        let reference = cpu.render(&prepared, &camera, &options).unwrap();
        let frame = gpu.render(&prepared, &camera, &options).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert!(reference.rays.len() > 100, "{what}: {} shadow rays", reference.rays.len());
        assert_eq!(reference.plan.runs(hyrt_core::stage::Stage::ShadowDenoise), denoise, "{what}");
        for cmp in compare_stages(&reference, &frame) {
            assert!(cmp.is_exact(), "{what}, denoise {denoise}: {} / {} differs: {cmp:?}", cmp.stage, cmp.buffer);
        }
        assert_eq!(reference.stats.rays_per_kind, frame.stats.rays_per_kind, "{what}");
        // Again, its pipelines built (the first frame of a specialization builds them): the
        // same image, and the frame's time on lavapipe.
        let start = std::time::Instant::now();
        let again = gpu.render(&prepared, &camera, &options).unwrap_or_else(|e| panic!("{what}: {e}"));
        let elapsed = start.elapsed();
        assert!(again.final_image == frame.final_image, "{what}: the same frame twice");
        let stages: Vec<String> =
            again.stats.stage_ms.iter().map(|t| format!("{} {:.2} ms", t.stage.name(), t.ms)).collect();
        eprintln!(
            "{what}, denoise {denoise}: {emitters} emitters, {} shadow rays, gpu frame {elapsed:.2?} ({})",
            reference.rays.len(),
            stages.join(", ")
        );
    }
    emitters
}

#[test]
fn the_example_manifest_renders_on_the_gpu_as_on_the_cpu() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/emissive_lights.toml");
    let mut scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    scene.ensure_camera_and_lights();
    assert!(scene.emissive_lights && scene.lights.is_empty(), "lit by its emissive meshes alone");
    compare_both_ways(&scene, (96, 54), "emissive_lights.toml");
}

#[test]
fn the_damaged_helmet_as_emitters_renders_on_the_gpu_as_on_the_cpu() {
    let Some(assets) = shared_assets() else {
        eprintln!("SKIPPED: ../shared/assets not found (DamagedHelmet.glb)");
        return;
    };
    let helmet = assets.join("DamagedHelmet.glb");
    let dir = std::env::temp_dir().join(format!("hyrt-conformance-emissive-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let manifest = dir.join("helmet.toml");
    // The helmet turned towards a camera on its left, over a grey floor, glTF shading.
    let text = format!(
        "shading = 'gltf'\nemissive_lights = true\nambient = 0.01\n\
         [camera]\neye = [-1.6, 0.6, 2.4]\ntarget = [0.0, -0.2, 0.0]\n\
         [[model]]\nfile = {:?}\nrotate_deg = [0.0, -30.0, 0.0]\n\
         [[model]]\nbuiltin = 'grid'\nname = 'floor'\nscale = 8.0\ntranslate = [0.0, -1.0, 0.0]\n",
        helmet.display().to_string()
    );
    std::fs::write(&manifest, text).unwrap();
    let scene = Scene::load(&manifest).unwrap_or_else(|e| panic!("{e}"));
    std::fs::remove_dir_all(&dir).ok();
    let emitters = compare_both_ways(&scene, (80, 60), "DamagedHelmet");
    assert!(emitters == 0 || emitters > 100, "{emitters} emitters: the helmet's glowing triangles");
}

/// Lights past one storage binding: `stochastic_gltf_emitters_mirror_bounces`, raw and
/// denoised, its panel a 132 x 132 grid (34,848 emissive triangles), on a device whose
/// storage bindings hold 2 MiB (the denoised frame in one band): the lights' table (96 bytes
/// a record: the point light, then the emitter table) in three pages of 16,384
/// ([`Table::Lights`], read by `compaction`, the
/// shading stages, `bounce_shading` and `shadow_denoise`); every stage buffer is the CPU's
/// bit for bit, the bounces' too.
#[test]
fn gpu_reads_lights_in_pages_as_the_cpu() {
    use hyrt_gpu::paging::{Table, TablePages};
    let Some(mut gpu) = hyrt_conformance::report::gpu_for_tests_with(Some(2 << 20)) else { return };
    let mut cpu = CpuBackend::new(Some(2));
    let named = |c: &hyrt_conformance::corpus::Case| c.name.ends_with("_gltf_emitters_mirror_bounces");
    let mut cases = 0;
    for mut case in hyrt_conformance::corpus::corpus().into_iter().filter(named) {
        let started = std::time::Instant::now();
        let panel = case.scene.meshes.iter().position(|m| m.name == "panel").expect("the panel");
        case.scene.meshes[panel] = hyrt_core::scene::Mesh::grid("panel", 132);
        let prepared = case.prepare(&cpu);
        let pages = TablePages::of_scene(&prepared, &gpu.context().limits).expect("within MAX_PAGES");
        assert_eq!(pages.pages(Table::Lights), 3, "{}: {pages:?}", case.name);
        let reference = hyrt_conformance::report::render_case(&mut cpu, &prepared, &case).expect("cpu frame");
        let frame = hyrt_conformance::report::render_case(&mut gpu, &prepared, &case).expect("gpu frame");
        assert!(!reference.bounces.is_empty(), "{}: no bounce traced", case.name);
        for cmp in compare_stages(&reference, &frame) {
            assert!(cmp.is_exact(), "{}: cpu vs gpu: {} / {} differs: {cmp:?}", case.name, cmp.stage, cmp.buffer);
        }
        let emitters = prepared.geometry.emitters.len();
        eprintln!("{}: {emitters} emitters, {pages:?}, {:.1} s", case.name, started.elapsed().as_secs_f64());
        cases += 1;
    }
    assert_eq!(cases, 2, "the case raw and denoised");
}
