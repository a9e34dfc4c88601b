//! Issue 34: a glTF file loaded alone and the same file as the only `[[model]]` of a TOML
//! manifest are one scene, and a manifest of several files keeps each file's textures and
//! animations.
//!
//! For every glTF feature hyrt reads (base-colour textures with each sampler and
//! `KHR_texture_transform`, vertex colours, alpha mask and blend, animation, cameras and
//! punctual lights, instanced meshes) a small file written by `common/gltf.rs`, the
//! committed animated sample and `shared/assets/DamagedHelmet.glb` are each loaded alone and
//! through a manifest beside them that names only the file, posed, framed and lit as the
//! `hyrt` program does, and rendered on the CPU reference and on the GPU: the final images
//! must be the same bit for bit, between the two paths on each backend and between the
//! backends. Each case also checks that its feature shows (every object covers pixels, the
//! frame has many colours, and taking the feature away changes it), so a black or
//! featureless frame cannot pass.
//!
//! A manifest of two textured and two animated files, placed apart, must give each model
//! its own file's materials and images, and pose each model as its own file does:
//! animation 0, "all", plays every animated model's first animation (or the one its
//! `animation` key names), then come every model's animations as "<model>/<animation>";
//! with one animated model, the scene's animations are that file's. Expected transforms are
//! the model matrix times the file alone's, posed by the file alone.

mod common;

use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use common::{gltf, gpu_renderer, shared_assets, temp_dir};
use hyrt::glam::{Mat4, Quat, Vec3};
use hyrt::{FrameOptions, Renderer, Scene};
use hyrt_core::scene::{AlphaMode, Sampler, UvTransform};

/// Frame size: small, for lavapipe on the CI's two cores.
const W: u32 = 96;
const H: u32 = 54;

/// Taking a feature away must change at least this many of the frame's 5184 pixels (a quad
/// of the six-quad layout covers about 100).
const MIN_CHANGED: usize = 50;

/// A merged model's posed transforms against its model matrix times the file alone's posed
/// ones: the merge may multiply in another order (the model matrix above the file's root
/// nodes, `(M P) L` instead of `M (P L)`); with entries up to about 4 that is a few f32 ulp
/// of 4 (4.8e-7 each) per product.
const REASSOCIATION_TOLERANCE: f32 = 1e-5;

/// The animated sample committed with the repository (`core/tests/animation.rs` builds it).
fn animated_box() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/animated_box.gltf")
}

/// `f` of the GPU renderer the tests share (making one builds its pipelines, seconds on
/// lavapipe), one test at a time; `None` without an adapter (skipped visibly; CI fails).
fn with_gpu<R>(f: impl FnOnce(&mut Renderer) -> R) -> Option<R> {
    static GPU: OnceLock<Mutex<Option<Renderer>>> = OnceLock::new();
    // A test that panicked holding it has failed on its own; the others go on with the renderer.
    let mut gpu = GPU.get_or_init(|| Mutex::new(gpu_renderer())).lock().unwrap_or_else(|e| e.into_inner());
    gpu.as_mut().map(f)
}

/// A frame's final image as bits.
fn bits(image: &[[f32; 4]]) -> Vec<[u32; 4]> {
    image.iter().map(|p| p.map(f32::to_bits)).collect()
}

/// How many pixels of two images differ.
fn differing(a: &[[u32; 4]], b: &[[u32; 4]]) -> usize {
    a.iter().zip(b).filter(|(x, y)| x != y).count()
}

/// `path` loaded, posed at `t` s of animation 0 when `pose` is `Some(t)`, and given the
/// default camera and lights where it has none: what `hyrt render [--time t]` renders.
fn load(path: &Path, pose: Option<f32>) -> Scene {
    let mut scene = Scene::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    if let Some(t) = pose {
        scene.set_time(0, t).unwrap_or_else(|e| panic!("{}: set_time(0, {t}): {e}", path.display()));
    }
    scene.ensure_camera_and_lights();
    scene
}

/// `scene`'s final image with the default frame options, prepared as `hyrt render` prepares
/// it: the objects animation 0 moves as moving when posed (`Motion` in `cli/src/main.rs`).
fn render(r: &mut Renderer, scene: &Scene, pose: Option<f32>) -> Vec<[u32; 4]> {
    let moving = match (pose, &scene.animation) {
        (Some(_), Some(a)) => a.moved_objects(0),
        _ => Vec::new(),
    };
    let prepared = if moving.is_empty() { r.prepare(scene) } else { r.prepare_moving(scene, &moving) };
    bits(&r.render(&prepared, &scene.camera.unwrap(), W, H, &FrameOptions::default()).unwrap().final_image)
}

/// What differs between two scenes that a frame depends on, to say why frames differ.
fn scene_differences(alone: &Scene, merged: &Scene) -> Vec<String> {
    let mut out = Vec::new();
    let counts = |s: &Scene| (s.objects.len(), s.meshes.len(), s.materials.len(), s.textures.len(), s.lights.len());
    if counts(alone) != counts(merged) {
        out.push(format!(
            "(objects, meshes, materials, textures, lights) {:?} alone, {:?} merged",
            counts(alone),
            counts(merged)
        ));
    }
    if alone.camera != merged.camera {
        out.push(format!("camera {:?} alone, {:?} merged", alone.camera, merged.camera));
    }
    if alone.lights != merged.lights {
        out.push(format!("lights {:?} alone, {:?} merged", alone.lights, merged.lights));
    }
    if alone.materials != merged.materials || alone.textures != merged.textures {
        out.push("materials or their images differ".into());
    }
    for (a, m) in alone.objects.iter().zip(&merged.objects) {
        if a.transform != m.transform || a.render_mode != m.render_mode {
            out.push(format!("object '{}' placed or shaded otherwise as '{}'", a.name, m.name));
        }
    }
    out
}

/// `file` alone and as a one-model manifest written beside it, posed at `pose`: the same
/// frames on the CPU and the GPU, bit for bit. Returns both scenes (the file alone's first).
fn assert_paths_agree(file: &Path, pose: Option<f32>) -> (Scene, Scene) {
    let name = file.file_name().unwrap().to_string_lossy().into_owned();
    let alone = load(file, pose);
    let merged = load(&gltf::one_model_manifest(file), pose);
    if pose.is_some() {
        let names = |s: &Scene| {
            s.animation.as_ref().map(|a| a.animations().iter().map(|a| a.name().to_owned()).collect::<Vec<_>>())
        };
        assert_eq!(names(&merged), names(&alone), "{name}: the only model's animations are the scene's");
        let moved = |s: &Scene| s.animation.as_ref().map(|a| a.moved_objects(0));
        assert_eq!(moved(&merged), moved(&alone), "{name}: objects animation 0 moves");
    }
    let why = || scene_differences(&alone, &merged).join("\n");
    let mut cpu = Renderer::cpu(Some(2));
    let (a, m) = (render(&mut cpu, &alone, pose), render(&mut cpu, &merged, pose));
    assert!(a == m, "{name}: CPU: the manifest's frame differs at {} pixels\n{}", differing(&a, &m), why());
    if let Some((ga, gm)) = with_gpu(|gpu| (render(gpu, &alone, pose), render(gpu, &merged, pose))) {
        assert!(ga == gm, "{name}: GPU: the manifest's frame differs at {} pixels\n{}", differing(&ga, &gm), why());
        assert!(ga == a, "{name}: the GPU frame differs from the CPU's at {} pixels", differing(&ga, &a));
    }
    eprintln!("{name}: {} objects, the same {W}x{H} frame from both paths", alone.objects.len());
    (alone, merged)
}

/// The feature shows in `scene`'s frame (the CPU's): every object covers a pixel, the frame
/// has many colours, and `take_away` (the scene without the feature) changes it.
fn assert_feature_shows(scene: &Scene, feature: &str, take_away: impl FnOnce(&mut Scene)) {
    let mut cpu = Renderer::cpu(Some(2));
    let prepared = cpu.prepare(scene);
    let frame = cpu.render(&prepared, &scene.camera.unwrap(), W, H, &FrameOptions::with_stage_outputs()).unwrap();
    let mut seen = vec![0; scene.objects.len()];
    for texel in frame.gbuffer.iter().filter(|t| t.is_hit()) {
        seen[texel.object as usize] += 1;
    }
    let unseen: Vec<&str> =
        scene.objects.iter().zip(&seen).filter(|(_, &n)| n == 0).map(|(o, _)| o.name.as_str()).collect();
    assert!(unseen.is_empty(), "{feature}: not in the picture: {unseen:?}");
    let image = bits(&frame.final_image);
    let mut colours = image.clone();
    colours.sort_unstable();
    colours.dedup();
    assert!(colours.len() >= 16, "{feature}: a frame of {} colours", colours.len());
    let mut without = scene.clone();
    take_away(&mut without);
    let changed = differing(&image, &render(&mut cpu, &without, None));
    assert!(changed >= MIN_CHANGED, "{feature}: taking it away changes {changed} pixels");
}

fn no_textures(scene: &mut Scene) {
    scene.materials.iter_mut().for_each(|m| m.base_color_texture = None);
}

#[test]
fn base_colour_textures_with_each_sampler() {
    let (scene, _) = assert_paths_agree(&gltf::samplers(&temp_dir("manifest_paths", "samplers")), None);
    assert_feature_shows(&scene, "base-colour textures", no_textures);
    assert_feature_shows(&scene, "samplers", |s| {
        s.materials
            .iter_mut()
            .filter_map(|m| m.base_color_texture.as_mut())
            .for_each(|t| t.sampler = Sampler::default())
    });
}

#[test]
fn khr_texture_transform_and_a_second_texture_coordinate_set() {
    let (scene, _) = assert_paths_agree(&gltf::texture_transform(&temp_dir("manifest_paths", "transform")), None);
    assert_feature_shows(&scene, "KHR_texture_transform", |s| {
        for t in s.materials.iter_mut().filter_map(|m| m.base_color_texture.as_mut()) {
            (t.transform, t.tex_coord) = (UvTransform::default(), 0);
        }
    });
}

#[test]
fn vertex_colours() {
    let (scene, _) = assert_paths_agree(&gltf::vertex_colours(&temp_dir("manifest_paths", "colours")), None);
    assert_feature_shows(&scene, "vertex colours", |s| s.meshes.iter_mut().for_each(|m| m.attributes.colors = None));
}

#[test]
fn alpha_mask_and_blend_over_a_backdrop() {
    let (scene, _) = assert_paths_agree(&gltf::alpha(&temp_dir("manifest_paths", "alpha")), None);
    assert_feature_shows(&scene, "alpha modes", |s| {
        s.materials.iter_mut().for_each(|m| m.alpha_mode = AlphaMode::Opaque)
    });
}

#[test]
fn animation_at_half_a_second() {
    let dir = temp_dir("manifest_paths", "animation");
    let sample = dir.join("animated_box.gltf");
    std::fs::copy(animated_box(), &sample).unwrap();
    let files =
        [gltf::animated(&dir, "arm.gltf", &[[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255], [255; 4]]), sample];
    for file in files {
        let (scene, _) = assert_paths_agree(&file, Some(0.5));
        assert_feature_shows(&scene, "animation", |s| s.set_time(0, 0.0).unwrap());
    }
}

#[test]
fn the_files_camera_and_punctual_lights() {
    let dir = temp_dir("manifest_paths", "camera");
    for infinite in [false, true] {
        let file = gltf::camera_and_lights(&dir, infinite);
        let (scene, _) = assert_paths_agree(&file, None);
        assert_eq!(scene.lights.len(), 2, "the file's lights, not the default ones");
        assert_feature_shows(&scene, "the file's camera", |s| {
            s.camera = None;
            s.ensure_camera_and_lights();
        });
        assert_feature_shows(&scene, "the file's lights", |s| {
            s.lights.clear();
            s.ensure_camera_and_lights();
        });
    }
}

#[test]
fn one_mesh_placed_by_several_nodes() {
    let (alone, merged) = assert_paths_agree(&gltf::instanced(&temp_dir("manifest_paths", "instanced")), None);
    for (path, scene) in [("alone", &alone), ("manifest", &merged)] {
        // Two primitives, each one mesh shared by the four nodes' objects.
        assert_eq!((scene.meshes.len(), scene.objects.len()), (2, 8), "{path}");
        for mesh in 0..2 {
            assert_eq!(scene.objects.iter().filter(|o| o.mesh == mesh).count(), 4, "{path}: mesh {mesh}");
        }
    }
    assert_feature_shows(&alone, "instances", |s| s.objects.truncate(2));
}

#[test]
fn the_damaged_helmet() {
    let Some(assets) = shared_assets() else { return };
    let dir = temp_dir("manifest_paths", "helmet");
    let helmet = dir.join("DamagedHelmet.glb");
    std::fs::copy(assets.join("DamagedHelmet.glb"), &helmet).unwrap();
    let (scene, _) = assert_paths_agree(&helmet, None);
    assert_feature_shows(&scene, "the helmet's textures", no_textures);
}

/// One `[[model]]` of a test manifest: a file under the manifest's folder, placed.
struct Model {
    file: PathBuf,
    /// `name`; without it the file stem names the model.
    name: Option<&'static str>,
    translate: [f32; 3],
    turn_deg: f32,
    scale: f32,
    /// More TOML keys.
    extra: &'static str,
}

impl Model {
    fn name(&self) -> String {
        self.name.map_or_else(|| self.file.file_stem().unwrap().to_string_lossy().into_owned(), str::to_owned)
    }

    /// The model matrix the manifest's schema gives: translate * rotate * scale.
    fn matrix(&self) -> Mat4 {
        let turn = Quat::from_rotation_y(self.turn_deg.to_radians());
        Mat4::from_scale_rotation_translation(Vec3::splat(self.scale), turn, Vec3::from(self.translate))
    }

    fn toml(&self, dir: &Path) -> String {
        let file = self.file.strip_prefix(dir).unwrap().to_str().unwrap();
        let name = self.name.map(|n| format!("name = \"{n}\"\n")).unwrap_or_default();
        format!(
            "[[model]]\nfile = \"{file}\"\n{name}translate = {:?}\nrotate_deg = [0.0, {:?}, 0.0]\nscale = {:?}\n{}\n",
            self.translate, self.turn_deg, self.scale, self.extra
        )
    }
}

/// A camera and a light framing every test layout, so that the files' own do not matter.
const VIEW: &str = r#"
[camera]
eye = [0.3, 0.5, 7.5]
target = [0.3, 0.0, 0.0]
fov_deg = 50.0

[[light]]
type = "directional"
direction = [-0.2, -0.4, -1.0]
intensity = 2.0
"#;

/// Write `dir/<name>.toml`: [`VIEW`] and `models`.
fn write_manifest(dir: &Path, name: &str, models: &[Model]) -> PathBuf {
    let text = models.iter().fold(VIEW.to_owned(), |text, m| text + "\n" + &m.toml(dir));
    let manifest = dir.join(format!("{name}.toml"));
    std::fs::write(&manifest, text).unwrap();
    manifest
}

/// [`write_manifest`], loaded, and each model's file loaded alone.
fn load_models(dir: &Path, name: &str, models: &[Model]) -> (Scene, Vec<Scene>) {
    let manifest = write_manifest(dir, name, models);
    let merged = Scene::load(&manifest).unwrap_or_else(|e| panic!("{name}.toml: {e}"));
    (merged, models.iter().map(|m| Scene::load(&m.file).unwrap()).collect())
}

/// Where each model's objects start among the merged scene's: in manifest order.
fn firsts(alone: &[Scene]) -> Vec<usize> {
    alone.iter().scan(0, |n, s| Some(std::mem::replace(n, *n + s.objects.len()))).collect()
}

fn assert_near(actual: Mat4, expected: Mat4, what: &str) {
    let diff = (actual - expected).to_cols_array().iter().fold(0.0f32, |m, d| m.max(d.abs()));
    assert!(diff <= REASSOCIATION_TOLERANCE, "{what}: expected\n{expected}\ngot\n{actual}\n(off by {diff})");
}

/// Material `m` of the merged scene is material `a` of the file alone: the same factors,
/// alpha mode and texture binding, and its image the file's own texels.
fn assert_same_material(merged: &Scene, m: usize, alone: &Scene, a: usize, what: &str) {
    let (mm, am) = (&merged.materials[m], &alone.materials[a]);
    let factors = |x: &hyrt::Material| (x.base_color, x.base_alpha, x.metallic, x.roughness, x.kind, x.alpha_mode);
    assert_eq!(factors(mm), factors(am), "{what}: material");
    match (mm.base_color_texture, am.base_color_texture) {
        (None, None) => {}
        (Some(mt), Some(at)) => {
            assert_eq!((mt.sampler, mt.tex_coord, mt.transform), (at.sampler, at.tex_coord, at.transform), "{what}");
            let count = merged.textures.len();
            let image =
                merged.textures.get(mt.image).unwrap_or_else(|| panic!("{what}: image {} of {count}", mt.image));
            let own = &alone.textures[at.image];
            assert!(
                (image.width, image.height, &image.texels) == (own.width, own.height, &own.texels),
                "{what}: its texture is not its file's image but '{}'",
                image.name
            );
        }
        (m, a) => panic!("{what}: texture {m:?} in the manifest, {a:?} alone"),
    }
}

/// Each model's objects of `merged`, in its loaded pose, are the file alone's: the same
/// meshes and materials, placed by the model matrix.
fn assert_models_placed(merged: &Scene, alone: &[Scene], models: &[Model]) {
    let total: usize = alone.iter().map(|s| s.objects.len()).sum();
    assert_eq!(merged.objects.len(), total, "every model's objects, once");
    for ((model, file), first) in models.iter().zip(alone).zip(firsts(alone)) {
        for (j, a) in file.objects.iter().enumerate() {
            let o = &merged.objects[first + j];
            let what = format!("model '{}' object {j} '{}'", model.name(), a.name);
            assert!(o.name.starts_with(&format!("{}/", model.name())), "{what}: named '{}'", o.name);
            assert_near(o.transform, model.matrix() * a.transform, &what);
            let (mm, am) = (&merged.meshes[o.mesh], &file.meshes[a.mesh]);
            assert!(mm.positions == am.positions && mm.indices == am.indices, "{what}: mesh");
            assert_eq!(mm.attributes, am.attributes, "{what}: texture coordinates and colours");
            assert_same_material(merged, o.material, file, a.material, &what);
        }
    }
}

/// `merged` posed by animation `name` at `t`: each model `k` that `plays[k]` names an
/// animation of is where that animation of its file alone puts it, placed by the model
/// matrix; the other models keep their loaded transforms bit for bit, and the manifest's
/// camera stays.
fn assert_posed(merged: &Scene, alone: &[Scene], models: &[Model], name: &str, plays: &[Option<usize>], t: f32) {
    let animation = merged.animation.as_ref().expect("the manifest scene is animated");
    let index = animation.find(name).unwrap_or_else(|| panic!("no animation '{name}'"));
    let mut posed = merged.clone();
    posed.set_time(index, t).unwrap();
    assert_eq!(posed.camera, merged.camera, "'{name}' at {t} s moved the manifest's camera");
    for (k, first) in firsts(alone).into_iter().enumerate() {
        let mut file = alone[k].clone();
        if let Some(a) = plays[k] {
            file.set_time(a, t).unwrap();
        }
        for (j, a) in file.objects.iter().enumerate() {
            let (o, rest) = (&posed.objects[first + j], &merged.objects[first + j]);
            let what = format!("'{name}' at {t} s: model '{}' object '{}'", models[k].name(), a.name);
            if plays[k].is_some() {
                assert_near(o.transform, models[k].matrix() * a.transform, &what);
            } else {
                let bits = |m: Mat4| m.to_cols_array().map(f32::to_bits);
                assert_eq!(bits(o.transform), bits(rest.transform), "{what}: not animated, it stays");
            }
        }
    }
}

/// Textures of the several-model manifest: each 2 x 2 and missing one channel (blue, red,
/// green), so a pixel shaded with a model's own texture has that channel at its minimum.
const RED_GREEN: [[u8; 4]; 4] = [[255, 0, 0, 255], [0, 255, 0, 255], [0, 255, 0, 255], [255, 0, 0, 255]];
const BLUE_CYAN: [[u8; 4]; 4] = [[0, 0, 255, 255], [0, 200, 255, 255], [0, 200, 255, 255], [0, 0, 255, 255]];
const RED_MAGENTA: [[u8; 4]; 4] = [[255, 0, 0, 255], [255, 0, 255, 255], [255, 0, 255, 255], [255, 0, 0, 255]];

/// The files of the several-model tests in `dir/models`: a textured quad (`.gltf`, its
/// image beside it), another (`.glb`), the animated arm (`.gltf`) and the animated sample.
fn model_files(dir: &Path) -> [PathBuf; 4] {
    let models = dir.join("models");
    std::fs::create_dir_all(&models).unwrap();
    let sample = models.join("animated_box.gltf");
    std::fs::copy(animated_box(), &sample).unwrap();
    [
        gltf::textured_quad(&models, "red_green.gltf", &RED_GREEN),
        gltf::textured_quad(&models, "blue_cyan.glb", &BLUE_CYAN),
        gltf::animated(&models, "arm.gltf", &RED_MAGENTA),
        sample,
    ]
}

fn model(file: &Path, name: Option<&'static str>, translate: [f32; 3], turn_deg: f32, scale: f32) -> Model {
    Model { file: file.to_path_buf(), name, translate, turn_deg, scale, extra: "" }
}

#[test]
fn several_textured_and_animated_models_keep_their_own_textures_and_animations() {
    let dir = temp_dir("manifest_paths", "several");
    let [red_green, blue_cyan, arm, sample] = model_files(&dir);
    let models = [
        model(&red_green, None, [-3.2, 1.0, 0.0], 0.0, 1.2),
        model(&blue_cyan, None, [-1.6, 1.0, 0.0], 25.0, 1.2),
        model(&arm, Some("waving"), [0.5, -0.6, 0.0], -10.0, 1.2),
        model(&sample, Some("boxes"), [3.5, 0.0, -1.0], -20.0, 0.6),
    ];
    let (merged, alone) = load_models(&dir, "several", &models);
    assert_models_placed(&merged, &alone, &models);

    let animation = merged.animation.as_ref().expect("animated models: an animated scene");
    let names: Vec<&str> = animation.animations().iter().map(|a| a.name()).collect();
    assert_eq!(names, ["all", "waving/wave", "waving/sway", "boxes/move", "boxes/dolly"]);
    for t in [0.25, 0.5, 1.5] {
        assert_posed(&merged, &alone, &models, "all", &[None, None, Some(0), Some(0)], t);
        assert_posed(&merged, &alone, &models, "waving/sway", &[None, None, Some(1), None], t);
        assert_posed(&merged, &alone, &models, "boxes/move", &[None, None, None, Some(0)], t);
    }

    // Rendered at 0.5 s of "all": each textured model's pixels have its own texture's
    // missing channel at their minimum (raster shading is the base colour times light plus
    // a grey ambient specular term, so a texture's zero channel is the smallest), and the
    // GPU's frame is the CPU's.
    let mut scene = merged.clone();
    scene.set_time(0, 0.5).unwrap();
    let mut cpu = Renderer::cpu(Some(2));
    let prepared = cpu.prepare(&scene);
    let frame = cpu.render(&prepared, &scene.camera.unwrap(), W, H, &FrameOptions::with_stage_outputs()).unwrap();
    let firsts = firsts(&alone);
    for (k, missing) in [(0, 2), (1, 0), (2, 1)] {
        let range = firsts[k]..firsts[k] + alone[k].objects.len();
        let textured = |o: u32| {
            range.contains(&(o as usize))
                && scene.materials[scene.objects[o as usize].material].base_color_texture.is_some()
        };
        let pixels: Vec<[f32; 4]> = frame
            .gbuffer
            .iter()
            .zip(&frame.final_image)
            .filter(|(g, _)| g.is_hit() && textured(g.object))
            .map(|(_, p)| *p)
            .collect();
        let name = models[k].name();
        assert!(pixels.len() >= 20, "model '{name}': {} textured pixels in view", pixels.len());
        for p in &pixels {
            assert!((0..3).all(|c| p[missing] <= p[c]), "model '{name}': pixel {p:?} is not its texture's colour");
        }
        assert!(pixels.iter().any(|p| (0..3).any(|c| p[c] > p[missing] + 0.05)), "model '{name}': untextured");
    }
    if let Some(g) = with_gpu(|gpu| render(gpu, &scene, None)) {
        assert!(
            g == bits(&frame.final_image),
            "GPU frame differs at {} pixels",
            differing(&g, &bits(&frame.final_image))
        );
    }
}

#[test]
fn one_animated_model_keeps_its_animations_and_the_animation_key_picks_what_all_plays() {
    let dir = temp_dir("manifest_paths", "animation_key");
    let [red_green, _, arm, sample] = model_files(&dir);

    // One animated model among still ones: the scene's animations are its file's.
    let models = [model(&red_green, None, [-2.0, 0.0, 0.0], 0.0, 1.0), model(&arm, None, [1.0, 0.0, 0.0], 30.0, 0.9)];
    let (merged, alone) = load_models(&dir, "one_animated", &models);
    let animation = merged.animation.as_ref().expect("an animated model: an animated scene");
    let names: Vec<&str> = animation.animations().iter().map(|a| a.name()).collect();
    assert_eq!(names, ["wave", "sway"]);
    assert_posed(&merged, &alone, &models, "sway", &[None, Some(1)], 0.5);
    assert_posed(&merged, &alone, &models, "wave", &[None, Some(0)], 1.5);

    // `animation = "sway"`: "all" plays the arm's second animation with the boxes' first.
    let mut models = [model(&arm, None, [-1.0, 0.0, 0.0], 0.0, 1.0), model(&sample, None, [2.0, 0.0, 0.0], 0.0, 0.5)];
    models[0].extra = "animation = \"sway\"";
    let (merged, alone) = load_models(&dir, "key", &models);
    for t in [0.25, 0.75] {
        assert_posed(&merged, &alone, &models, "all", &[Some(1), Some(0)], t);
    }

    // A name the file does not have is an error naming it.
    models[0].extra = "animation = \"jump\"";
    let e = Scene::load(&write_manifest(&dir, "missing", &models))
        .expect_err("an animation the file lacks is an error")
        .to_string();
    assert!(e.contains("jump"), "{e}");
}
