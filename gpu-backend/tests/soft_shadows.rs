//! Area lights and ambient occlusion (issue 38) on the GPU backend: their stochastic shadow
//! rays (`compaction` over mask slots, `shadow_rays`, the shading stages' slot loops, and
//! the same slots at every bounce depth) render bit for bit the CPU reference's frame,
//! denoised (`shadow_denoise`, the default: the filtered visibility and the shading from
//! it) or not (`FrameOptions::denoise` false, `--no-denoise`), whole or in bands of rows
//! (a denoised band is rendered with a halo of rows, `hyrt_gpu::band`); and so do emissive
//! meshes as lights (`emissive_lights`: the emitter table packed into the lights' binding,
//! `hyrt_gpu::buffers::packed_lights`), moving or not. (The conformance corpus'
//! `stochastic_*` cases compare such frames stage by stage too, and
//! `conformance/tests/emissive_lights.rs` the `DamagedHelmet` as emitters.)

mod common;

use common::test_context;
use glam::{Mat4, Vec3};
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::formats::{CameraRecord, RAY_KIND_SHADOW};
use hyrt_core::frame::{Backend, Frame, FrameOptions, PreparedScene};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::scene::{Camera, Light, Material, MaterialKind, Mesh, RenderMode, Scene, ShadingModel};
use hyrt_core::stage::Stage;
use hyrt_cpu::backend::CpuBackend;
use hyrt_gpu::backend::GpuBackend;

/// A floor with a box on it, the box ray traced, under `lights`; with `mirror`, a
/// ray-traced mirror stands behind the box (bounces shade with slots).
fn scene(lights: Vec<Light>, shading: ShadingModel, mirror: bool) -> Scene {
    let mut scene = Scene { shading, ..Scene::default() };
    scene.add_object(Mesh::grid("floor", 4), Material::grey(), Mat4::from_scale(Vec3::splat(4.0)), RenderMode::Raster);
    scene.add_object(
        Mesh::cube("box"),
        Material { base_color: Vec3::new(0.8, 0.4, 0.2), ..Material::grey() },
        Mat4::from_translation(Vec3::new(0.2, 0.35, 0.0)) * Mat4::from_scale(Vec3::splat(0.35)),
        RenderMode::RayTraced,
    );
    if mirror {
        let mirror = Material {
            name: "mirror".into(),
            base_color: Vec3::splat(0.9),
            metallic: 1.0,
            roughness: 0.05,
            kind: MaterialKind::Specular,
            ..Material::grey()
        };
        scene.add_object(
            Mesh::grid("mirror", 2),
            mirror,
            Mat4::from_translation(Vec3::new(0.0, 0.8, -1.2))
                * Mat4::from_quat(glam::Quat::from_rotation_x(std::f32::consts::FRAC_PI_2))
                * Mat4::from_scale(Vec3::new(2.5, 1.0, 1.6)),
            RenderMode::RayTraced,
        );
    }
    scene.lights = lights;
    scene.camera = Some(Camera::look_at(Vec3::new(0.4, 2.2, 2.6), Vec3::new(0.0, 0.3, 0.0), Vec3::Y));
    scene
}

fn quad() -> Light {
    Light::Quad {
        corner: Vec3::new(-0.6, 1.8, -0.4),
        edge_u: Vec3::new(0.8, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, 0.6),
        color: Vec3::ONE,
        intensity: 6.0,
    }
}

fn sphere() -> Light {
    Light::Sphere { position: Vec3::new(-0.8, 1.4, 0.6), radius: 0.25, color: Vec3::new(1.0, 0.9, 0.7), intensity: 9.0 }
}

fn sun() -> Light {
    Light::Sun {
        direction: Vec3::new(0.4, -1.0, -0.3),
        angular_diameter: 0.15,
        color: Vec3::new(1.0, 0.95, 0.9),
        intensity: 2.0,
    }
}

fn point() -> Light {
    Light::point(Vec3::new(1.0, 2.0, 1.0), Vec3::ONE, 3.0)
}

fn prepare(scene: &Scene) -> PreparedScene {
    let geometry = WorldGeometry::build(scene);
    let bvh = Bvh::build(&geometry, BvhPreset::default());
    PreparedScene::new(geometry, bvh, 0.0)
}

fn camera(scene: &Scene) -> CameraRecord {
    CameraRecord::new(&scene.camera.unwrap(), 48, 32)
}

/// Every buffer two frames hold, by their bytes: the first that differs, if any.
fn first_difference(a: &Frame, b: &Frame) -> Option<String> {
    fn bytes<T: bytemuck::Pod>(v: &[T]) -> &[u8] {
        bytemuck::cast_slice(v)
    }
    let mut buffers: Vec<(String, &[u8], &[u8])> = vec![
        ("gbuffer".into(), bytes(&a.gbuffer), bytes(&b.gbuffer)),
        ("surfaces".into(), bytes(&a.surfaces), bytes(&b.surfaces)),
        ("rays".into(), bytes(&a.rays), bytes(&b.rays)),
        ("occluded".into(), bytes(&a.occluded), bytes(&b.occluded)),
        ("shadow".into(), &a.shadow, &b.shadow),
        ("rt".into(), bytes(&a.rt), bytes(&b.rt)),
        ("raster".into(), bytes(&a.raster), bytes(&b.raster)),
        ("final".into(), bytes(&a.final_image), bytes(&b.final_image)),
        ("visibility".into(), bytes(&a.visibility), bytes(&b.visibility)),
    ];
    if a.bounces.len() != b.bounces.len() {
        return Some(format!("{} against {} bounce depths", a.bounces.len(), b.bounces.len()));
    }
    for (d, (x, y)) in a.bounces.iter().zip(&b.bounces).enumerate() {
        let at = |name: &str| format!("bounce {} {name}", d + 1);
        buffers.extend([
            (at("rays"), bytes(&x.rays), bytes(&y.rays)),
            (at("links"), bytes(&x.links), bytes(&y.links)),
            (at("hits"), bytes(&x.hits), bytes(&y.hits)),
            (at("surfaces"), bytes(&x.surfaces), bytes(&y.surfaces)),
            (at("shadow_rays"), bytes(&x.shadow_rays), bytes(&y.shadow_rays)),
            (at("occluded"), bytes(&x.occluded), bytes(&y.occluded)),
            (at("shadow"), &x.shadow[..], &y.shadow[..]),
            (at("radiance"), bytes(&x.radiance), bytes(&y.radiance)),
        ]);
    }
    buffers.into_iter().find(|(_, x, y)| x != y).map(|(name, x, y)| {
        let at = x.iter().zip(y).position(|(p, q)| p != q).unwrap_or(x.len().min(y.len()));
        format!("{name} differs ({} against {} bytes, first at byte {at})", x.len(), y.len())
    })
}

/// The frame `options` on both backends: the CPU's, checked to trace shadow rays (some
/// occluded) and to be the GPU's, every buffer byte for byte and the statistics; with a
/// `mirror`, its first bounce traces shadow rays. `what` names the frame in a failure;
/// the GPU's final image is returned with the CPU's frame.
fn stochastic_frame(
    (cpu, gpu): (&mut CpuBackend, &mut GpuBackend),
    prepared: &PreparedScene,
    camera: &CameraRecord,
    options: &FrameOptions,
    (what, mirror): (&str, bool),
) -> (Frame, Vec<[f32; 4]>) {
    let want = cpu.render(prepared, camera, options).expect("cpu frame");
    assert_eq!(want.plan.bounce_depth() > 0, mirror, "{what}");
    let got = gpu.render(prepared, camera, options).unwrap_or_else(|e| panic!("{what}: {e}"));
    assert!(want.rays.len() > 100 && want.occluded.iter().any(|&o| o != 0), "{what}: rays, some occluded");
    if let Some(d) = first_difference(&want, &got) {
        panic!("{what}: {d}");
    }
    assert_eq!(want.stats.rays_per_kind, got.stats.rays_per_kind, "{what}");
    assert_eq!(want.stats.bounces, got.stats.bounces, "{what}");
    if mirror {
        let shadow_rays = want.stats.bounces[0].rays_per_kind[RAY_KIND_SHADOW as usize];
        assert!(shadow_rays > 0, "{what}: the first bounce traces shadow rays");
    }
    (want, got.final_image)
}

/// Undenoised frames with area lights (quad, sphere, sun, and a point light beside them),
/// ambient occlusion alone and with both, paper and glTF models, with and without a mirror
/// (bounce depths trace and shade the same slots): the GPU's frame is the CPU's, every
/// stage buffer, byte for byte; and the frame changes with its index (the streams' seeds
/// reach the GPU).
#[test]
fn undenoised_stochastic_frames_are_the_cpu_frames_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let mut gpu = GpuBackend::with_context(ctx).expect("backend");
    let mut cpu = CpuBackend::new(Some(2));
    let cases: [(&str, Vec<Light>, u32, ShadingModel, bool); 7] = [
        ("quad light, paper", vec![quad()], 0, ShadingModel::Paper, false),
        ("quad light, glTF", vec![quad()], 0, ShadingModel::Gltf, false),
        ("sphere light and a point light", vec![point(), sphere()], 0, ShadingModel::Paper, false),
        ("sun", vec![sun()], 0, ShadingModel::Gltf, false),
        ("ambient occlusion alone", vec![point()], 2, ShadingModel::Paper, false),
        ("quad light, occlusion and a mirror", vec![quad(), point()], 2, ShadingModel::Paper, true),
        ("every kind, glTF, a mirror", vec![sun(), quad(), sphere()], 2, ShadingModel::Gltf, true),
    ];
    for (name, lights, ao_samples, shading, mirror) in cases {
        let scene = scene(lights, shading, mirror);
        let prepared = prepare(&scene);
        let camera = camera(&scene);
        let mut images = Vec::new();
        for frame_index in [0, 1] {
            let options = FrameOptions {
                stage_outputs: true,
                shadow_samples: 3,
                ao_samples,
                denoise: false,
                frame_index,
                max_depth: 2,
                ..FrameOptions::default()
            };
            let what = format!("{name}, frame {frame_index}");
            let (want, image) = stochastic_frame((&mut cpu, &mut gpu), &prepared, &camera, &options, (&what, mirror));
            assert!(want.plan.stochastic() && !want.plan.runs(Stage::ShadowDenoise), "{name}");
            images.push(image);
        }
        assert!(images[0] != images[1], "{name}: frames 0 and 1 sample alike");
    }
    // Point lights with occlusion, then without: the second frame shades with the scene's
    // own ambient record and one slot per light again (the paper's pipelines).
    let scene = scene(vec![point()], ShadingModel::Paper, false);
    let prepared = prepare(&scene);
    let options = FrameOptions { stage_outputs: true, denoise: false, max_depth: 0, ..FrameOptions::default() };
    for ao_samples in [3, 0, 1] {
        let opts = FrameOptions { ao_samples, ..options };
        let want = cpu.render(&prepared, &camera(&scene), &opts).unwrap();
        let got = gpu.render(&prepared, &camera(&scene), &opts).unwrap();
        assert_eq!(want.plan.stochastic(), ao_samples > 0);
        assert_eq!(first_difference(&want, &got), None, "{ao_samples} occlusion rays");
    }
}

/// The cases of the denoised tests: area lights of every kind, ambient occlusion, both
/// models, mirrors (the bounces' shading of primary surfaces reads the filtered channels,
/// their hits the codes).
fn denoised_cases() -> [(&'static str, Vec<Light>, u32, ShadingModel, bool); 6] {
    [
        ("quad light, paper", vec![quad()], 0, ShadingModel::Paper, false),
        ("quad light, glTF", vec![quad()], 0, ShadingModel::Gltf, false),
        ("sphere light and a point light", vec![point(), sphere()], 0, ShadingModel::Paper, false),
        ("sun", vec![sun()], 0, ShadingModel::Gltf, false),
        ("ambient occlusion alone", vec![point()], 2, ShadingModel::Paper, false),
        ("every kind, occlusion, glTF, a mirror", vec![sun(), quad(), sphere()], 2, ShadingModel::Gltf, true),
    ]
}

/// Denoised frames (`shadow_denoise`, the default) with area lights and ambient occlusion:
/// the GPU's frame is the CPU's, every stage buffer and the filtered visibility, byte for
/// byte; and the filter changed the raw values (it ran).
#[test]
fn denoised_stochastic_frames_are_the_cpu_frames_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let mut gpu = GpuBackend::with_context(ctx).expect("backend");
    let mut cpu = CpuBackend::new(Some(2));
    for (name, lights, ao_samples, shading, mirror) in denoised_cases() {
        let scene = scene(lights, shading, mirror);
        let prepared = prepare(&scene);
        let camera = camera(&scene);
        let options = FrameOptions {
            stage_outputs: true,
            shadow_samples: 2,
            ao_samples,
            max_depth: 2,
            ..FrameOptions::default()
        };
        assert!(options.denoise, "frames denoise by default");
        let want = cpu.render(&prepared, &camera, &options).expect("cpu frame");
        assert!(want.plan.runs(Stage::ShadowDenoise), "{name}");
        let got = gpu.render(&prepared, &camera, &options).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(want.visibility.len(), (48 * 32) * want.plan.visibility_channels() as usize, "{name}");
        if let Some(d) = first_difference(&want, &got) {
            panic!("{name}: {d}");
        }
        assert_eq!(want.stats.rays_per_kind, got.stats.rays_per_kind, "{name}");
        assert_eq!(want.stats.bounces, got.stats.bounces, "{name}");
        let undenoised = cpu.render(&prepared, &camera, &FrameOptions { denoise: false, ..options }).unwrap();
        assert!(undenoised.final_image != got.final_image, "{name}: the denoiser changed nothing");
    }
}

/// Denoised frames in bands of a few rows (`GpuBackend::set_max_band_bytes`): each band is
/// rendered with a halo of rows for the filter's neighbours across its edges, and the
/// merged frame is the CPU's, every buffer, bit for bit; band edges fall inside the
/// penumbrae (checked: a row at a band edge has partly lit pixels).
#[test]
fn denoised_frames_in_bands_are_the_cpu_frames_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let mut gpu = GpuBackend::with_context(ctx).expect("backend");
    let mut cpu = CpuBackend::new(Some(2));
    let (width, height) = (64, 90);
    let own_rows = 7;
    let mut edges_in_penumbrae = 0;
    for (name, lights, ao_samples, shading, mirror) in [
        ("quad light, paper", vec![quad()], 0, ShadingModel::Paper, false),
        ("quad light, occlusion and a mirror", vec![quad(), point()], 2, ShadingModel::Paper, true),
        ("every kind, occlusion, glTF, a mirror", vec![sun(), quad(), sphere()], 2, ShadingModel::Gltf, true),
    ] {
        let scene = scene(lights, shading, mirror);
        let prepared = prepare(&scene);
        let camera = CameraRecord::new(&scene.camera.unwrap(), width, height);
        let options = FrameOptions {
            stage_outputs: true,
            shadow_samples: 2,
            ao_samples,
            max_depth: 2,
            ..FrameOptions::default()
        };
        let want = cpu.render(&prepared, &camera, &options).expect("cpu frame");
        let plan = &want.plan;
        let rows = hyrt_gpu::band::buffer_rows(own_rows, u32::MAX, hyrt_gpu::shadow_denoise::DENOISE_HALO);
        let bytes = hyrt_gpu::band::band_binding_bytes((width * rows) as u64, plan.lights(), plan);
        gpu.set_max_band_bytes(Some(bytes));
        let got = gpu.render(&prepared, &camera, &options).unwrap_or_else(|e| panic!("{name}: {e}"));
        let bands = gpu.last_frame_bands();
        assert!(bands >= height.div_ceil(own_rows), "{name}: {bands} bands");
        if let Some(d) = first_difference(&want, &got) {
            panic!("{name}, {bands} bands: {d}");
        }
        assert_eq!(want.stats.rays_per_kind, got.stats.rays_per_kind, "{name}");
        assert_eq!(want.stats.bounces, got.stats.bounces, "{name}");
        // Rows at band edges with pixels in a penumbra (a first channel strictly between
        // 0 and 1).
        let channels = plan.visibility_channels() as usize;
        edges_in_penumbrae += (1..height.div_ceil(own_rows))
            .filter(|b| {
                let y = (b * own_rows) as usize;
                (0..width as usize).any(|x| {
                    let v = want.visibility[(y * width as usize + x) * channels];
                    v > 0.0 && v < 1.0
                })
            })
            .count();
        gpu.set_max_band_bytes(None);
    }
    assert!(edges_in_penumbrae > 3, "{edges_in_penumbrae} band edges in penumbrae");
}

/// The denoiser's temporal pass (`FrameOptions::temporal`): one GPU backend renders a
/// sequence of frames, each with its own samples (`frame_index`), the camera panning, the
/// box moving (`PreparedScene::move_objects`: a motion record), a frame of another size,
/// one without the temporal pass (which leaves the history alone) and one with another
/// channel count (which starts afresh), then another scene (afresh); each frame is the
/// frame the CPU backend renders as the same frame of its own sequence, every buffer and
/// the accumulated, filtered visibility, bit for bit. The history counted (frames differ
/// from the same frames denoised alone).
#[test]
fn temporal_frames_are_the_cpu_frames_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let mut gpu = GpuBackend::with_context(ctx).expect("backend");
    let mut cpu = CpuBackend::new(Some(2));
    for (name, lights, ao_samples, shading, mirror) in [
        ("quad light, paper", vec![quad()], 0, ShadingModel::Paper, false),
        ("every kind, occlusion, glTF, a mirror", vec![sun(), quad(), sphere()], 2, ShadingModel::Gltf, true),
    ] {
        let scene = scene(lights, shading, mirror);
        let box_object = 1u32;
        let mut prepared = hyrt_cpu::bvh_build::prepare_moving(&scene, BvhPreset::default(), &[box_object]);
        let base = scene.camera.unwrap();
        let mut blended = 0;
        for i in 0..8u32 {
            if i >= 2 {
                // The box slides along x, 3 cm a frame.
                let mut moved = scene.clone();
                moved.objects[box_object as usize].transform =
                    Mat4::from_translation(Vec3::new(0.2 + 0.03 * i as f32, 0.35, 0.0))
                        * Mat4::from_scale(Vec3::splat(0.35));
                prepared.move_objects(&moved, &[box_object]).expect("the box moves");
            }
            // A pan of 2 cm a frame; frame 4 is larger.
            let shift = Vec3::new(0.02 * i as f32, 0.0, 0.0);
            let view = Camera { eye: base.eye + shift, target: base.target + shift, ..base };
            let (width, height) = if i == 4 { (56, 36) } else { (48, 32) };
            let camera = CameraRecord::new(&view, width, height);
            let options = FrameOptions {
                stage_outputs: true,
                shadow_samples: 2,
                // Frame 6 has one more channel (or one less): the history starts afresh.
                ao_samples: if i == 6 { 2 - ao_samples } else { ao_samples },
                max_depth: 2,
                frame_index: i,
                // Frame 3 is denoised alone.
                temporal: i != 3,
                ..FrameOptions::default()
            };
            let want = cpu.render(&prepared, &camera, &options).expect("cpu frame");
            assert!(want.plan.runs(Stage::ShadowDenoise), "{name}");
            let got = gpu.render(&prepared, &camera, &options).unwrap_or_else(|e| panic!("{name}, frame {i}: {e}"));
            if let Some(d) = first_difference(&want, &got) {
                panic!("{name}, frame {i}: {d}");
            }
            assert_eq!(gpu.last_frame_bands(), 1);
            let alone = CpuBackend::new(Some(2))
                .render(&prepared, &camera, &FrameOptions { temporal: false, ..options })
                .expect("cpu frame");
            let differs = alone.visibility != want.visibility;
            assert!(!(i == 0 || i == 3 || i >= 6) || !differs, "{name}, frame {i}: no history to blend");
            blended += differs as u32;
        }
        assert!(blended >= 3, "{name}: {blended} frames blended their history");
    }
}

/// A frame of the temporal pass too large for one band of storage bindings
/// (`GpuBackend::set_max_band_bytes`) is refused (the history is read at reprojected rows
/// of the whole previous frame); the same frame without the pass renders in bands, and the
/// temporal frame in one band renders as the CPU's.
#[test]
fn temporal_frames_in_bands_are_refused() {
    let Some(ctx) = test_context() else { return };
    let mut gpu = GpuBackend::with_context(ctx).expect("backend");
    let scene = scene(vec![quad()], ShadingModel::Paper, false);
    let prepared = prepare(&scene);
    let (width, height) = (64, 90);
    let camera = CameraRecord::new(&scene.camera.unwrap(), width, height);
    let options = FrameOptions {
        stage_outputs: true,
        shadow_samples: 2,
        temporal: true,
        max_depth: 0,
        ..FrameOptions::default()
    };
    let want = CpuBackend::new(Some(2)).render(&prepared, &camera, &options).expect("cpu frame");
    let plan = &want.plan;
    let rows = hyrt_gpu::band::buffer_rows(7, u32::MAX, hyrt_gpu::shadow_denoise::DENOISE_HALO);
    gpu.set_max_band_bytes(Some(hyrt_gpu::band::band_binding_bytes((width * rows) as u64, plan.lights(), plan)));
    let err = gpu.render(&prepared, &camera, &options).expect_err("a banded temporal frame");
    assert!(err.to_string().contains("temporal pass"), "{err}");
    gpu.render(&prepared, &camera, &FrameOptions { temporal: false, ..options }).expect("a banded frame");
    assert!(gpu.last_frame_bands() > 1);
    gpu.set_max_band_bytes(None);
    let got = gpu.render(&prepared, &camera, &options).expect("a temporal frame");
    assert_eq!(first_difference(&want, &got), None);
}

/// `scene` (the floor, the ray-traced box, with `mirror` the mirror) lit by emissive meshes
/// as lights (`Scene::emissive_lights`: one `LIGHT_EMITTERS` area light over their
/// triangles) beside `lights`: a panel over the box (a one-cell grid turned to face down:
/// two single-sided triangles, glowing warm white; object 2, or 3 with the mirror) and a
/// small double-sided glowing ball beside it (48 triangles of another colour and power:
/// picking by power over two meshes).
fn emissive_scene(lights: Vec<Light>, shading: ShadingModel, mirror: bool) -> Scene {
    let mut scene = scene(lights, shading, mirror);
    scene.emissive_lights = true;
    let glow = |emissive: Vec3, double_sided: bool| Material {
        base_color: Vec3::ZERO,
        emissive,
        double_sided,
        kind: MaterialKind::Diffuse,
        ..Material::grey()
    };
    let panel = Mat4::from_translation(Vec3::new(0.0, 1.8, 0.1))
        * Mat4::from_rotation_x(std::f32::consts::PI)
        * Mat4::from_scale(Vec3::new(0.9, 1.0, 0.7));
    scene.add_object(Mesh::grid("panel", 1), glow(Vec3::new(6.0, 5.6, 5.0), false), panel, RenderMode::Raster);
    let ball = Mat4::from_translation(Vec3::new(-0.9, 0.5, 0.7)) * Mat4::from_scale(Vec3::splat(0.15));
    scene.add_object(Mesh::uv_sphere("glow", 8, 4), glow(Vec3::new(1.0, 2.5, 5.0), true), ball, RenderMode::Raster);
    scene
}

/// The emissive cases: the emitters alone (paper, glTF), beside a point and a quad light
/// (the emitter light last among three), and in front of a mirror (bounce depths sample
/// the emitters at their hits).
fn emissive_cases() -> [(&'static str, Vec<Light>, ShadingModel, bool); 4] {
    [
        ("emitters, paper", vec![], ShadingModel::Paper, false),
        ("emitters, glTF", vec![], ShadingModel::Gltf, false),
        ("emitters beside a point and a quad light", vec![point(), quad()], ShadingModel::Paper, false),
        ("emitters, glTF, a mirror", vec![], ShadingModel::Gltf, true),
    ]
}

/// Emissive meshes as lights (`emissive_lights`, an emitter table sampled by `compaction`,
/// the shading stages and `shadow_denoise`): raw (`denoise` false, two frame indices) and
/// denoised frames of every emissive case are the CPU's, every stage buffer byte for byte
/// (the bounce depths' too); the box casts a shadow (occluded samples), the frames change
/// with their index, and the denoiser ran.
#[test]
fn emissive_light_frames_are_the_cpu_frames_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let mut gpu = GpuBackend::with_context(ctx).expect("backend");
    let mut cpu = CpuBackend::new(Some(2));
    for (name, lights, shading, mirror) in emissive_cases() {
        let scene = emissive_scene(lights, shading, mirror);
        let prepared = prepare(&scene);
        assert_eq!(prepared.geometry.emitters.len(), 2 + 48, "{name}: the panel's and the ball's triangles");
        let camera = camera(&scene);
        let mut images = Vec::new();
        for (frame_index, denoise) in [(0, false), (1, false), (0, true)] {
            let options = FrameOptions {
                stage_outputs: true,
                shadow_samples: 3,
                denoise,
                frame_index,
                max_depth: 2,
                ..FrameOptions::default()
            };
            let what = format!("{name}, frame {frame_index}, denoise {denoise}");
            let (want, image) = stochastic_frame((&mut cpu, &mut gpu), &prepared, &camera, &options, (&what, mirror));
            assert!(want.plan.stochastic() && want.plan.runs(Stage::ShadowDenoise) == denoise, "{name}");
            images.push(image);
        }
        assert!(images[0] != images[1], "{name}: frames 0 and 1 sample alike");
        assert!(images[0] != images[2], "{name}: the denoiser changed nothing");
    }
}

/// Denoised emissive frames in bands of a few rows (as
/// `denoised_frames_in_bands_are_the_cpu_frames_bit_for_bit`): the merged frame is the
/// CPU's, every buffer, bit for bit.
#[test]
fn emissive_light_frames_in_bands_are_the_cpu_frames_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let mut gpu = GpuBackend::with_context(ctx).expect("backend");
    let mut cpu = CpuBackend::new(Some(2));
    let (width, height, own_rows) = (64, 90, 7);
    for (name, lights, shading, mirror) in [emissive_cases()[0].clone(), emissive_cases()[3].clone()] {
        let scene = emissive_scene(lights, shading, mirror);
        let prepared = prepare(&scene);
        let camera = CameraRecord::new(&scene.camera.unwrap(), width, height);
        let options = FrameOptions { stage_outputs: true, shadow_samples: 2, max_depth: 2, ..FrameOptions::default() };
        let want = cpu.render(&prepared, &camera, &options).expect("cpu frame");
        let plan = &want.plan;
        let rows = hyrt_gpu::band::buffer_rows(own_rows, u32::MAX, hyrt_gpu::shadow_denoise::DENOISE_HALO);
        gpu.set_max_band_bytes(Some(hyrt_gpu::band::band_binding_bytes((width * rows) as u64, plan.lights(), plan)));
        let got = gpu.render(&prepared, &camera, &options).unwrap_or_else(|e| panic!("{name}: {e}"));
        let bands = gpu.last_frame_bands();
        assert!(bands >= height.div_ceil(own_rows), "{name}: {bands} bands");
        if let Some(d) = first_difference(&want, &got) {
            panic!("{name}, {bands} bands: {d}");
        }
        gpu.set_max_band_bytes(None);
    }
}

/// A moving emitter (`PreparedScene::move_objects` of the panel): the emitter table moves
/// with it, the GPU writes it again with the object (`SceneBuffers::apply`), and each frame
/// is the CPU's bit for bit; the panel's move changed the frame.
#[test]
fn a_moving_emitter_lights_the_gpu_frame_as_the_cpu_frame() {
    let Some(ctx) = test_context() else { return };
    let mut gpu = GpuBackend::with_context(ctx).expect("backend");
    let mut cpu = CpuBackend::new(Some(2));
    let scene = emissive_scene(vec![], ShadingModel::Paper, false);
    let panel = 2u32;
    assert_eq!(scene.objects[panel as usize].name, "panel");
    let mut prepared = hyrt_cpu::bvh_build::prepare_moving(&scene, BvhPreset::default(), &[panel]);
    let camera = camera(&scene);
    let options = FrameOptions { stage_outputs: true, shadow_samples: 2, ..FrameOptions::default() };
    let mut images = Vec::new();
    for step in 0..3 {
        if step > 0 {
            let mut moved = scene.clone();
            moved.objects[panel as usize].transform = Mat4::from_translation(Vec3::new(0.3 * step as f32, 0.0, 0.0))
                * scene.objects[panel as usize].transform;
            prepared.move_objects(&moved, &[panel]).expect("the panel moves");
        }
        let want = cpu.render(&prepared, &camera, &options).expect("cpu frame");
        let got = gpu.render(&prepared, &camera, &options).unwrap_or_else(|e| panic!("step {step}: {e}"));
        if let Some(d) = first_difference(&want, &got) {
            panic!("step {step}: {d}");
        }
        images.push(got.final_image);
    }
    assert!(images[0] != images[1] && images[1] != images[2], "the panel's light moved");
}
