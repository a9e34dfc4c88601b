//! The conformance corpus: scenes built by code, each named for what it stresses.
//!
//! Families (the prefix of every case name):
//! - `paper_*`: the default scene and the paper-like scenes of `../shared/assets`
//!   (Sponza with a ray-traced bunny, the bunny near and far, the horse) and its hard
//!   models, when that folder is present;
//! - `raster_*`: shared edges and vertices, vertices on pixel centres and on subpixel
//!   ties, top-left rule, sub-pixel and sliver triangles, the near and far planes,
//!   coplanar overlap, back faces, huge coordinates and tiny scales;
//! - `ray_*`: shadow rays through shared edges and vertices, grazing rays,
//!   axis-parallel directions with +0 and -0 components, large coordinates, lights on
//!   surfaces;
//! - `degenerate_*`: zero-area, NaN and Inf triangles, an empty scene, a scene without
//!   lights, all-miss and all-hit frames;
//! - `size_*`: 1x1, odd sizes (not multiples of tile or workgroup sizes), rows wider
//!   than 256 bytes, a tall single column;
//! - `bounce_*`: reflection and refraction: two parallel mirrors (the depth limit
//!   reached), a glass sphere with total internal reflection, grazing refraction, glass
//!   inside glass, refracted rays through the shared edges and vertices of low-poly
//!   glass, a mirror 1e5 from the origin;
//! - `instance_*`: two-level scenes (objects prepared as moving, traced in their own
//!   space): one mesh shared by instances scaled unevenly, rotated and mirrored, glass
//!   and mirrors among them; every object an instance far from the origin;
//! - `texture_*`: textures (procedural images built here), vertex colours and alpha
//!   tests: bilinear, trilinear and nearest sampling under a `KHR_texture_transform` on
//!   rasterized and ray-traced objects, vertex colours alone and times a texture, a
//!   checker fence whose holes let light through onto a wall, alpha-mask edges across
//!   the edges two triangles share, mip selection on a floor seen nearly edge-on, masked
//!   and textured geometry seen in a mirror, every wrap mode.
//! - `shading_*`: cases of the families above again with the glTF BRDF on every object
//!   (`shading_gltf_<case>`): the default scene's cases, every bounce case, and up to
//!   three textured and three two-level ones; spheres from smooth to rough; and the
//!   image-based light of a procedural environment map (every other glTF case has the
//!   default sky's) on the spheres and on the default scene, at its depth and at depth 1.
//! - `stochastic_*`: stochastic shadow rays (issue 38): a quad light over a floor with a
//!   box (the paper's model and the glTF one), a sphere light beside a point light, a sun
//!   of finite angular size, ambient occlusion alone in a corner, and a quad light with
//!   occlusion rays in front of a mirror (every bounce depth traces and shades the same
//!   slots), emissive meshes as lights (`emissive_lights`: a glowing panel and ball over
//!   the box, the paper's model; the glTF model beside a point light, in front of the
//!   mirror); few samples, small images. Each without the denoiser ([`Case::denoise`]
//!   false: the raw samples), and again denoised (`stochastic_denoised_*`: `shadow_denoise`
//!   and its filtered visibility, which the shading of primary surfaces reads).
//!
//! Images are small (lavapipe runs the GPU side on the CI's two cores).

use std::path::{Path, PathBuf};

use std::sync::Arc;

use glam::{DMat4, DVec4, Mat4, Quat, Vec2, Vec3};
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{FrameOptions, DEFAULT_SHADOW_SAMPLES};
use hyrt_core::kernels::bounce::DEFAULT_MAX_DEPTH;
use hyrt_core::scene::{
    AlphaMode, Ambient, Camera, Environment, EnvironmentMap, Filter, Light, Material, MaterialKind, MaterialMaps, Mesh,
    RenderMode, Sampler, Scene, ShadingModel, TextureBinding, TextureImage, UvTransform, Wrap,
};

/// One scene of the corpus with the image it is rendered at.
#[derive(Clone, Debug)]
pub struct Case {
    /// Unique name; the prefix says the family (module docs).
    pub name: String,
    /// What the case stresses, in a sentence.
    pub stresses: &'static str,
    pub scene: Scene,
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
    /// Composition weight (paper 3.5).
    pub weight: f32,
    /// Deepest reflection and refraction bounce (`FrameOptions::max_depth`): the
    /// library's default ([`DEFAULT_MAX_DEPTH`]) unless the case says otherwise.
    pub max_depth: u32,
    /// Objects prepared as moving (a two-level BVH, `instance_*` cases); empty: the scene
    /// is prepared as one world-space tree.
    pub moving: Vec<u32>,
    /// Shadow rays per surface and area light (`FrameOptions::shadow_samples`): the
    /// library's default unless the case says otherwise (`stochastic_*` cases).
    pub shadow_samples: u32,
    /// Ambient-occlusion rays per surface (`FrameOptions::ao_samples`): none unless the
    /// case says otherwise (`stochastic_*` cases).
    pub ao_samples: u32,
    /// Whether the frame denoises its stochastic shadows (`FrameOptions::denoise`): false
    /// unless the case says otherwise (`stochastic_denoised_*` cases).
    pub denoise: bool,
}

impl Case {
    /// The options the case renders with (every stage output is the caller's choice):
    /// its weight, depth and samples, and whether it denoises ([`Case::denoise`]; a frame
    /// without stochastic rays does not denoise anyway).
    pub fn options(&self) -> FrameOptions {
        FrameOptions {
            weight: self.weight,
            max_depth: self.max_depth,
            shadow_samples: self.shadow_samples,
            ao_samples: self.ao_samples,
            denoise: self.denoise,
            ..FrameOptions::default()
        }
    }

    /// Whether the case traces stochastic shadow rays: an area light (quad, sphere, sun, or
    /// emissive meshes as lights: the corpus sets `emissive_lights` only on scenes that
    /// glow), or ambient occlusion. Such frames run staged on the CPU backend.
    pub fn stochastic(&self) -> bool {
        self.ao_samples > 0
            || self.scene.emissive_lights
            || self.scene.lights.iter().any(|l| hyrt_core::formats::LightRecord::from_light(l).is_area())
    }

    /// The case's scene prepared on `cpu` (`bvh_build` on its pool): with its moving
    /// objects in a two-level BVH when it has some, else as one world-space tree.
    pub fn prepare(&self, cpu: &hyrt_cpu::backend::CpuBackend) -> hyrt_core::frame::PreparedScene {
        let preset = hyrt_core::bvh::BvhPreset::default();
        match self.moving.is_empty() {
            true => cpu.prepare(hyrt_core::geometry::WorldGeometry::build(&self.scene), preset),
            false => hyrt_cpu::bvh_build::prepare_moving(&self.scene, preset, &self.moving),
        }
    }
}

/// Environment variable naming the shared models folder, for a binary that runs away
/// from its checkout (`.ci/gpu-check` on a machine with a GPU).
pub const ASSETS_ENV: &str = "HYRT_SHARED_ASSETS";

/// The shared models folder (`$HYRT_SHARED_ASSETS`, else `<repo>/../shared/assets`), if
/// present.
pub fn shared_assets() -> Option<PathBuf> {
    let p = match std::env::var_os(ASSETS_ENV) {
        Some(dir) => PathBuf::from(dir),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets"),
    };
    p.is_dir().then_some(p)
}

fn diffuse(name: &str, rgb: Vec3) -> Material {
    Material {
        name: name.into(),
        base_color: rgb,
        metallic: 0.0,
        roughness: 0.8,
        transmission: 0.0,
        kind: MaterialKind::Diffuse,
        ..Material::grey()
    }
}

fn gold() -> Material {
    Material {
        name: "gold".into(),
        base_color: Vec3::new(1.0, 0.76, 0.33),
        metallic: 1.0,
        roughness: 0.2,
        transmission: 0.0,
        kind: MaterialKind::Specular,
        ..Material::grey()
    }
}

const RT: RenderMode = RenderMode::RayTraced;
const RASTER: RenderMode = RenderMode::Raster;

fn point(position: Vec3, intensity: f32) -> Light {
    Light::point(position, Vec3::ONE, intensity)
}

fn mesh(name: &str, positions: Vec<Vec3>, indices: Vec<[u32; 3]>) -> Mesh {
    Mesh { name: name.into(), positions, normals: None, indices, ..Default::default() }
}

fn camera(eye: Vec3, target: Vec3, near: f32, far: f32) -> Camera {
    Camera { eye, target, up: Vec3::Y, fov_y_deg: 45.0, near, far }
}

/// The world point seen at window position `(wx, wy)` (pixel units, row 0 on top) at
/// NDC depth `depth`, unprojected in f64 and rounded once to f32. Projecting it back in
/// f32 lands within rounding error of `(wx, wy)`, which is what these cases want: vertices
/// *at* rounding boundaries, where two implementations disagree if any.
fn unproject(cam: &Camera, width: u32, height: u32, wx: f64, wy: f64, depth: f64) -> Vec3 {
    let rec = CameraRecord::new(cam, width, height);
    // The record's matrix is eye-relative: unproject to `p - eye`, then add the eye.
    let inv = DMat4::from_cols_array(&rec.view_proj.map(|x| x as f64)).inverse();
    let ndc = DVec4::new(wx / width as f64 * 2.0 - 1.0, 1.0 - wy / height as f64 * 2.0, depth, 1.0);
    let p = inv * ndc;
    (p.truncate() / p.w + Vec3::from(rec.eye).as_dvec3()).as_vec3()
}

/// Two triangles over the window rectangle `[x0, x1] x [y0, y1]` at NDC depth `depth`.
fn window_quad(cam: &Camera, w: u32, h: u32, name: &str, r: [f64; 4], depth: f64) -> Mesh {
    let [x0, y0, x1, y1] = r;
    let p = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)].map(|(x, y)| unproject(cam, w, h, x, y, depth));
    // Counter-clockwise on screen (y down): front faces.
    mesh(name, p.to_vec(), vec![[0, 3, 2], [0, 2, 1]])
}

struct Builder {
    cases: Vec<Case>,
}

impl Builder {
    fn add(&mut self, name: &str, stresses: &'static str, scene: Scene, camera: Camera, w: u32, h: u32) {
        self.cases.push(Case {
            name: name.into(),
            stresses,
            scene,
            camera,
            width: w,
            height: h,
            weight: 1.0,
            max_depth: DEFAULT_MAX_DEPTH,
            moving: Vec::new(),
            shadow_samples: DEFAULT_SHADOW_SAMPLES,
            ao_samples: 0,
            denoise: false,
        });
    }
}

/// A floor (ray traced) and a back wall (rasterized) for cases to put things on.
fn stage_set(scene: &mut Scene, size: f32) {
    scene.add_object(
        Mesh::grid("floor", 8),
        diffuse("blue", Vec3::new(0.2, 0.3, 0.8)),
        Mat4::from_scale(Vec3::splat(size)),
        RT,
    );
    scene.add_object(
        Mesh::grid("wall", 8),
        diffuse("red", Vec3::new(0.8, 0.2, 0.15)),
        Mat4::from_translation(Vec3::new(0.0, size * 0.5, -size * 0.5))
            * Mat4::from_quat(Quat::from_rotation_x(std::f32::consts::FRAC_PI_2))
            * Mat4::from_scale(Vec3::splat(size)),
        RASTER,
    );
}

/// The default scene with the paper's model: the families below are the paper's, and
/// [`shading_cases`] repeats the default scene's cases with the glTF BRDF (the model
/// `Scene::default_scene` itself has).
fn paper_default_scene() -> Scene {
    Scene { shading: ShadingModel::Paper, ..Scene::default_scene() }
}

/// The default scene moved by `offset` and scaled by `scale` (camera, lights and clip
/// planes with it).
fn transformed_default(offset: Vec3, scale: f32) -> (Scene, Camera) {
    let mut s = paper_default_scene();
    let m = Mat4::from_translation(offset) * Mat4::from_scale(Vec3::splat(scale));
    for o in &mut s.objects {
        o.transform = m * o.transform;
    }
    for l in &mut s.lights {
        if let Light::Point { position, intensity, .. } = l {
            *position = m.transform_point3(*position);
            *intensity *= scale * scale;
        }
    }
    let c = s.camera.unwrap();
    let cam = Camera {
        eye: m.transform_point3(c.eye),
        target: m.transform_point3(c.target),
        near: c.near * scale,
        far: c.far * scale,
        ..c
    };
    s.camera = Some(cam);
    (s, cam)
}

fn default_case(b: &mut Builder) {
    let s = paper_default_scene();
    let cam = s.camera.unwrap();
    b.add("paper_default_scene", "the built-in Figure-8 scene: every stage on mixed objects", s.clone(), cam, 96, 54);
    b.cases.push(Case {
        name: "paper_default_scene_weight_half".into(),
        stresses: "composition with weight 0.5 (both images on ray-traced pixels)",
        scene: s,
        camera: cam,
        width: 67,
        height: 41,
        weight: 0.5,
        max_depth: DEFAULT_MAX_DEPTH,
        moving: Vec::new(),
        shadow_samples: DEFAULT_SHADOW_SAMPLES,
        ao_samples: 0,
        denoise: false,
    });
    // KHR_lights_punctual's spot lights and ranges: the default scene's key light as a spot
    // whose cone edge crosses the objects and the floor, a narrow spot with a range that
    // ends inside the scene, and the fill light with a range; mirrors and glass bounce
    // into their cones.
    let mut s = paper_default_scene();
    let &Light::Point { position: key, color, intensity, .. } = &s.lights[0] else { unreachable!("a point key") };
    let target = Vec3::new(0.0, 0.5, 0.0);
    s.lights[0] = Light::Spot {
        position: key,
        direction: (target - key).normalize(),
        color,
        intensity,
        inner_cone_angle: 8f32.to_radians(),
        outer_cone_angle: 22f32.to_radians(),
        range: None,
    };
    if let Light::Point { range, .. } = &mut s.lights[1] {
        *range = Some(9.0);
    }
    s.lights.push(Light::Spot {
        position: Vec3::new(-2.0, 3.0, 2.0),
        direction: Vec3::new(0.6, -1.0, -0.4).normalize(),
        color: Vec3::new(0.4, 0.6, 1.0),
        intensity: 12.0,
        inner_cone_angle: 0.0,
        outer_cone_angle: 30f32.to_radians(),
        range: Some(3.8),
    });
    b.add("paper_default_scene_spot_lights", "spot lights' cones and lights' ranges on every stage", s, cam, 96, 54);
}

fn paper_cases(b: &mut Builder, shared: &Path) {
    let scenes_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes");
    for (name, file, stresses, w, h) in [
        ("paper_teaser", "teaser.toml", "Sponza rasterized + the bunny ray traced (paper teaser)", 128, 72),
        ("paper_bunny_near", "bunny_near.toml", "the bunny filling the frame (paper Bunny 1)", 96, 54),
        ("paper_bunny_far", "bunny_far.toml", "the bunny small and far: sub-pixel triangles (paper Bunny 2)", 96, 54),
        ("paper_horse_near", "horse_near.toml", "the horse scan (stand-in for the paper's toad)", 96, 54),
    ] {
        match Scene::load(&scenes_dir.join(file)) {
            Ok(mut s) => {
                s.ensure_camera_and_lights();
                let cam = s.camera.unwrap();
                b.add(name, stresses, s, cam, w, h);
            }
            Err(e) => eprintln!("conformance corpus: skipping {name}: {e}"),
        }
    }
    for (name, file, stresses) in [
        ("paper_hard_teapot", "teapot.glb", "108 zero-area triangles and 1,113 slivers in a real model"),
        ("paper_hard_cycloidal", "hard_cycloidal.glb", "CAD tessellation: non-manifold edges and slivers"),
        ("paper_hard_dragon_res3", "hard_dragon_res3.glb", "a non-manifold decimated scan"),
        ("paper_hard_bunny_far", "hard_bunny_far.glb", "the bunny 100 m from the origin in millimetres"),
    ] {
        match Scene::load(&shared.join(file)) {
            Ok(mut s) => {
                // Every object ray traced: the hard geometry is traced as well as rasterized.
                for o in &mut s.objects {
                    o.render_mode = RT;
                }
                s.ensure_camera_and_lights();
                let cam = s.camera.unwrap();
                b.add(name, stresses, s, cam, 80, 60);
            }
            Err(e) => eprintln!("conformance corpus: skipping {name}: {e}"),
        }
    }
}

fn raster_cases(b: &mut Builder) {
    let (w, h) = (64u32, 48u32);
    let cam = camera(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 0.1, 100.0);
    let lights = vec![point(Vec3::new(1.0, 3.0, 4.0), 20.0), point(Vec3::new(-2.0, 1.0, 3.0), 8.0)];

    // A fan of 24 triangles around one shared vertex, seen face on, and a dense grid.
    let mut s = Scene { lights: lights.clone(), ..Scene::default() };
    let n = 24;
    let mut pos = vec![Vec3::ZERO];
    for i in 0..n {
        let a = std::f32::consts::TAU * i as f32 / n as f32;
        pos.push(Vec3::new(a.cos(), a.sin(), 0.0) * 1.3);
    }
    let idx = (0..n).map(|i| [0, 1 + i, 1 + (i + 1) % n]).collect();
    s.add_object(mesh("fan", pos, idx), diffuse("fan", Vec3::new(0.8, 0.6, 0.2)), Mat4::IDENTITY, RT);
    s.add_object(
        Mesh::grid("grid", 24),
        diffuse("grid", Vec3::splat(0.7)),
        Mat4::from_translation(Vec3::new(0.0, -1.0, -1.0)) * Mat4::from_scale(Vec3::splat(6.0)),
        RASTER,
    );
    b.add("raster_shared_edges_fan_and_grid", "a 24-triangle fan and a 24x24 grid: every pixel once", s, cam, w, h);

    // Closed meshes: sphere, torus, cube, half of them ray traced.
    let mut s = Scene { lights: lights.clone(), ..Scene::default() };
    s.add_object(
        Mesh::uv_sphere("sphere", 32, 16),
        gold(),
        Mat4::from_translation(Vec3::new(-1.2, 0.0, 0.0)) * Mat4::from_scale(Vec3::splat(0.8)),
        RT,
    );
    s.add_object(
        Mesh::torus("torus", 0.7, 0.25, 32, 16),
        diffuse("torus", Vec3::new(0.5, 0.2, 0.7)),
        Mat4::from_translation(Vec3::new(1.1, 0.2, 0.0)) * Mat4::from_quat(Quat::from_rotation_x(1.0)),
        RASTER,
    );
    s.add_object(
        Mesh::cube("cube"),
        diffuse("cube", Vec3::splat(0.6)),
        Mat4::from_translation(Vec3::new(0.0, -1.0, -1.5)) * Mat4::from_scale(Vec3::splat(0.5)),
        RT,
    );
    b.add("raster_closed_meshes", "closed meshes (sphere, torus, cube): shared edges, silhouettes", s, cam, w, h);

    // One closed mesh wound outward as a whole: a cube with an inside-out cube in front of
    // it. The faces of the small cube that face the camera show its interior, which the
    // raster drops for a closed object wholly in front of the near plane; its far faces,
    // which face the camera, show instead.
    let mut s = Scene { lights: lights.clone(), ..Scene::default() };
    let (big, small) = (Mesh::cube("big"), Mesh::cube("small"));
    let (mut pos, mut idx) = (big.positions.clone(), big.indices.clone());
    let to_small = Mat4::from_translation(Vec3::new(0.2, 0.1, 1.8)) * Mat4::from_scale(Vec3::splat(0.35));
    let base = pos.len() as u32;
    pos.extend(small.positions.iter().map(|p| to_small.transform_point3(*p)));
    idx.extend(small.indices.iter().map(|t| [t[0] + base, t[2] + base, t[1] + base]));
    let rotation = Mat4::from_quat(Quat::from_rotation_y(0.4) * Quat::from_rotation_x(0.3));
    s.add_object(mesh("inside_out", pos, idx), diffuse("inside_out", Vec3::new(0.3, 0.6, 0.8)), rotation, RASTER);
    b.add(
        "raster_closed_mesh_interior_dropped",
        "a closed mesh with an inside-out part in front: the faces that show its interior dropped",
        s,
        cam,
        w,
        h,
    );

    // Vertices on pixel centres, on 1/256 and on 1/512 ties (exactly between two subpixel
    // positions: the rounding rule decides).
    for (name, frac, stresses) in [
        ("raster_vertices_on_pixel_centres", 0.5, "vertices exactly on pixel centres"),
        ("raster_vertices_on_subpixel_256", 0.5 + 1.0 / 256.0, "vertices on 1/256-pixel subpixel positions"),
        ("raster_vertices_on_subpixel_ties_512", 0.5 + 1.0 / 512.0, "vertices on 1/512 ties between subpixels"),
    ] {
        let mut s = Scene { lights: lights.clone(), ..Scene::default() };
        let mut k = 0u32;
        for j in 0..4u32 {
            for i in 0..6u32 {
                let (x0, y0) = (2.0 + 10.0 * i as f64 + frac, 2.0 + 11.0 * j as f64 + frac);
                let depth = 0.9 + 0.01 * (i + j) as f64;
                let p = [
                    unproject(&cam, w, h, x0, y0, depth),
                    unproject(&cam, w, h, x0 + 7.0, y0 + 2.0, depth),
                    unproject(&cam, w, h, x0 + 3.0, y0 + 8.0, depth),
                    unproject(&cam, w, h, x0 + 8.0, y0 + 9.0, depth),
                ];
                let rt = if k.is_multiple_of(2) { RT } else { RASTER };
                s.add_object(
                    mesh("tris", p.to_vec(), vec![[0, 2, 1], [1, 2, 3]]),
                    diffuse("t", Vec3::splat(0.7)),
                    Mat4::IDENTITY,
                    rt,
                );
                k += 1;
            }
        }
        b.add(name, stresses, s, cam, w, h);
    }

    // Top-left rule: axis-aligned quads whose edges run exactly through pixel centres,
    // sharing edges with their neighbours.
    let mut s = Scene { lights: lights.clone(), ..Scene::default() };
    for j in 0..3u32 {
        for i in 0..4u32 {
            let r = [4.5 + 14.0 * i as f64, 3.5 + 14.0 * j as f64, 18.5 + 14.0 * i as f64, 17.5 + 14.0 * j as f64];
            let rt = if (i + j) % 2 == 0 { RT } else { RASTER };
            s.add_object(
                window_quad(&cam, w, h, "cell", r, 0.95),
                diffuse("cell", Vec3::splat(0.3 + 0.1 * i as f32)),
                Mat4::IDENTITY,
                rt,
            );
        }
    }
    b.add("raster_top_left_rule", "edges exactly through pixel centres, shared by neighbouring quads", s, cam, w, h);

    // Sub-pixel triangles and slivers.
    let mut s = Scene { lights: lights.clone(), ..Scene::default() };
    let mut pos = Vec::new();
    let mut idx = Vec::new();
    for k in 0..200u32 {
        let x = 1.0 + (k % 20) as f64 * 3.1 + 0.37 * (k / 20) as f64;
        let y = 1.0 + (k / 20) as f64 * 4.6;
        let size = 0.15 + 0.05 * (k % 7) as f64;
        let base = pos.len() as u32;
        pos.push(unproject(&cam, w, h, x, y, 0.9));
        pos.push(unproject(&cam, w, h, x + size, y + 0.3 * size, 0.9));
        pos.push(unproject(&cam, w, h, x + 0.2 * size, y + size, 0.9));
        idx.push([base, base + 2, base + 1]);
    }
    s.add_object(mesh("subpixel", pos, idx), diffuse("s", Vec3::splat(0.8)), Mat4::IDENTITY, RT);
    let mut pos = Vec::new();
    let mut idx = Vec::new();
    for k in 0..12u32 {
        let y = 2.0 + 3.7 * k as f64;
        let t = 0.01 + 0.03 * k as f64;
        let base = pos.len() as u32;
        pos.push(unproject(&cam, w, h, -3.0, y, 0.92));
        pos.push(unproject(&cam, w, h, 70.0, y + 1.3, 0.92));
        pos.push(unproject(&cam, w, h, 70.0, y + 1.3 + t, 0.92));
        idx.push([base, base + 2, base + 1]);
    }
    s.add_object(mesh("slivers", pos, idx), diffuse("s", Vec3::splat(0.5)), Mat4::IDENTITY, RASTER);
    b.add(
        "raster_subpixel_and_sliver_triangles",
        "triangles smaller than a pixel and slivers 0.01-0.34 px thick",
        s,
        cam,
        w,
        h,
    );

    // Near and far planes: a floor running through the camera and past the far plane.
    let mut s = Scene { lights: vec![point(Vec3::new(0.0, 3.0, 0.0), 10.0)], ..Scene::default() };
    s.add_object(Mesh::grid("floor", 6), diffuse("floor", Vec3::splat(0.7)), Mat4::from_scale(Vec3::splat(40.0)), RT);
    s.add_object(
        Mesh::cube("box"),
        diffuse("box", Vec3::new(0.8, 0.4, 0.2)),
        Mat4::from_translation(Vec3::new(0.3, 0.5, -3.0)) * Mat4::from_scale(Vec3::splat(0.5)),
        RASTER,
    );
    // A wall the near plane cuts through diagonally.
    s.add_object(
        Mesh::grid("wall", 4),
        diffuse("wall", Vec3::new(0.3, 0.7, 0.3)),
        Mat4::from_translation(Vec3::new(-0.8, 0.6, 1.0))
            * Mat4::from_quat(Quat::from_rotation_z(1.2) * Quat::from_rotation_x(0.9))
            * Mat4::from_scale(Vec3::splat(3.0)),
        RASTER,
    );
    let c = camera(Vec3::new(0.0, 0.6, 1.5), Vec3::new(0.0, 0.3, -5.0), 0.5, 15.0);
    b.add("raster_near_and_far_plane_crossing", "triangles crossing the near plane and the far plane", s, c, w, h);

    // Coplanar overlap: two quads in one plane, triangulated differently, and a duplicated triangle.
    let mut s = Scene { lights: lights.clone(), ..Scene::default() };
    // The same rectangle corners, split along the other diagonal in q2.
    let rect = |name: &str, x0: f32, y0: f32, x1: f32, y1: f32, tris: Vec<[u32; 3]>| {
        let corners =
            vec![Vec3::new(x0, y0, 0.0), Vec3::new(x1, y0, 0.0), Vec3::new(x1, y1, 0.0), Vec3::new(x0, y1, 0.0)];
        mesh(name, corners, tris)
    };
    let q1 = rect("q1", -1.5, -1.0, 0.5, 1.0, vec![[0, 1, 2], [0, 2, 3]]);
    let q2 = rect("q2", -0.5, -1.2, 1.5, 0.8, vec![[0, 1, 3], [1, 2, 3]]);
    let tri = mesh(
        "dup",
        vec![Vec3::new(-1.0, 0.2, 0.3), Vec3::new(1.0, 0.4, 0.3), Vec3::new(0.0, 1.3, 0.3)],
        vec![[0, 1, 2], [0, 1, 2]],
    );
    let tilt = Mat4::from_quat(Quat::from_rotation_y(0.4) * Quat::from_rotation_x(-0.3));
    s.add_object(q1, diffuse("a", Vec3::new(0.8, 0.2, 0.2)), tilt, RT);
    s.add_object(q2, diffuse("b", Vec3::new(0.2, 0.8, 0.2)), tilt, RASTER);
    s.add_object(tri, diffuse("c", Vec3::new(0.2, 0.2, 0.8)), tilt, RT);
    b.add(
        "raster_coplanar_overlap",
        "coplanar overlapping triangles and a duplicated triangle: depth ties",
        s,
        cam,
        w,
        h,
    );

    // Back faces: inside a cube, and single triangles wound clockwise.
    let mut s = Scene { lights: vec![point(Vec3::new(0.3, 0.5, 0.2), 2.0)], ..Scene::default() };
    s.add_object(Mesh::cube("room"), diffuse("room", Vec3::splat(0.7)), Mat4::from_scale(Vec3::splat(2.0)), RT);
    s.add_object(
        mesh(
            "cw",
            vec![Vec3::new(-0.5, -0.5, -1.0), Vec3::new(0.0, 0.6, -1.0), Vec3::new(0.5, -0.5, -1.0)],
            vec![[0, 1, 2]],
        ),
        diffuse("cw", Vec3::new(0.9, 0.5, 0.1)),
        Mat4::IDENTITY,
        RASTER,
    );
    let c = camera(Vec3::new(0.1, 0.2, 1.2), Vec3::new(0.0, 0.0, -1.0), 0.05, 10.0);
    b.add("raster_back_faces", "back faces: the inside of a cube and clockwise triangles", s, c, w, h);

    // Huge coordinates and tiny scales.
    for (name, offset, scale, stresses) in [
        ("raster_huge_coordinates_1e5", Vec3::new(1e5, 0.0, -1e5), 1.0, "the default scene 1e5 from the origin"),
        ("raster_huge_coordinates_1e6", Vec3::new(-1e6, 1e6, 0.0), 1.0, "the default scene 1e6 from the origin"),
        ("raster_tiny_scale_1e-3", Vec3::ZERO, 1e-3, "the default scene scaled by 1e-3"),
    ] {
        let (s, c) = transformed_default(offset, scale);
        b.add(name, stresses, s, c, w, h);
    }
}

fn ray_cases(b: &mut Builder) {
    let (w, h) = (64u32, 48u32);
    let cam = camera(Vec3::new(0.0, 3.0, 4.5), Vec3::new(0.0, 0.0, 0.0), 0.1, 100.0);

    // Shadow rays through the shared edges and vertices of an occluder grid: the light
    // sits straight above a grid vertex, the receiver's pixels look through the grid.
    let mut s = Scene {
        lights: vec![point(Vec3::new(0.0, 4.0, 0.0), 30.0), point(Vec3::new(0.25, 4.0, 0.25), 10.0)],
        ..Scene::default()
    };
    s.add_object(Mesh::grid("floor", 16), diffuse("floor", Vec3::splat(0.8)), Mat4::from_scale(Vec3::splat(8.0)), RT);
    s.add_object(
        Mesh::grid("occluder", 4),
        diffuse("occ", Vec3::new(0.6, 0.6, 0.2)),
        Mat4::from_translation(Vec3::new(0.0, 2.0, 0.0)) * Mat4::from_scale(Vec3::splat(2.0)),
        RASTER,
    );
    s.add_object(
        Mesh::uv_sphere("ball", 16, 8),
        gold(),
        Mat4::from_translation(Vec3::new(1.5, 0.5, 1.0)) * Mat4::from_scale(Vec3::splat(0.5)),
        RT,
    );
    b.add(
        "ray_shadow_through_shared_edges_and_vertices",
        "shadow rays through an occluder grid's edges and vertices, light above a vertex",
        s,
        cam,
        w,
        h,
    );

    // Grazing: a light barely above a long floor, and a light in the plane of a wall.
    let mut s = Scene {
        lights: vec![point(Vec3::new(-6.0, 0.02, 0.0), 40.0), point(Vec3::new(0.0, 1.0, -1.0), 10.0)],
        ..Scene::default()
    };
    stage_set(&mut s, 8.0);
    s.add_object(
        Mesh::cube("block"),
        diffuse("block", Vec3::new(0.7, 0.5, 0.3)),
        Mat4::from_translation(Vec3::new(0.5, 0.3, 0.5)) * Mat4::from_scale(Vec3::splat(0.3)),
        RT,
    );
    b.add("ray_grazing_light", "shadow rays grazing a floor and a light in the plane of a wall", s, cam, w, h);

    // Axis-parallel shadow rays with +0 and -0 direction components (directional lights
    // straight down and along x, with signed zeros) over axis-aligned boxes.
    let lights = vec![
        Light::Directional { direction: Vec3::new(0.0, -1.0, -0.0), color: Vec3::ONE, intensity: 2.0 },
        Light::Directional { direction: Vec3::new(-0.0, -1.0, 0.0), color: Vec3::new(0.5, 0.5, 1.0), intensity: 1.0 },
        Light::Directional { direction: Vec3::new(-1.0, -0.0, 0.0), color: Vec3::new(1.0, 0.5, 0.5), intensity: 1.0 },
    ];
    let mut s = Scene { lights, ..Scene::default() };
    s.add_object(Mesh::grid("floor", 8), diffuse("floor", Vec3::splat(0.8)), Mat4::from_scale(Vec3::splat(8.0)), RT);
    s.add_object(
        Mesh::cube("box_a"),
        diffuse("a", Vec3::new(0.8, 0.3, 0.3)),
        Mat4::from_translation(Vec3::new(-1.0, 1.0, 0.0)) * Mat4::from_scale(Vec3::splat(0.5)),
        RASTER,
    );
    s.add_object(
        Mesh::cube("box_b"),
        diffuse("b", Vec3::new(0.3, 0.8, 0.3)),
        Mat4::from_translation(Vec3::new(1.0, 0.5, 0.0)) * Mat4::from_scale(Vec3::splat(0.5)),
        RT,
    );
    s.add_object(
        Mesh::grid("wall_x", 4),
        diffuse("w", Vec3::splat(0.6)),
        Mat4::from_translation(Vec3::new(3.0, 1.0, 0.0))
            * Mat4::from_quat(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2))
            * Mat4::from_scale(Vec3::splat(2.0)),
        RT,
    );
    b.add(
        "ray_axis_parallel_signed_zero",
        "axis-parallel shadow rays with +0 and -0 components over axis-aligned boxes",
        s,
        cam,
        w,
        h,
    );

    // Large coordinates: the shadow part of the huge-coordinate scenes, with a nearby light.
    let (mut s, c) = transformed_default(Vec3::new(3e5, -2e5, 7e5), 1.0);
    s.lights.push(point(Vec3::new(3e5 + 1.0, -2e5 + 2.5, 7e5 + 1.0), 20.0));
    b.add("ray_shadows_at_large_coordinates", "shadow rays from surfaces 7e5 from the origin", s, c, w, h);

    // Lights exactly on surfaces: on the floor plane and on a box's top face.
    let mut s = Scene {
        lights: vec![point(Vec3::new(0.5, 0.0, 0.5), 10.0), point(Vec3::new(-1.0, 1.0, 0.0), 10.0)],
        ..Scene::default()
    };
    s.add_object(Mesh::grid("floor", 8), diffuse("floor", Vec3::splat(0.8)), Mat4::from_scale(Vec3::splat(8.0)), RT);
    s.add_object(
        Mesh::cube("box"),
        diffuse("box", Vec3::new(0.4, 0.4, 0.8)),
        Mat4::from_translation(Vec3::new(-1.0, 0.5, 0.0)) * Mat4::from_scale(Vec3::splat(0.5)),
        RT,
    );
    b.add("ray_light_on_surface", "point lights exactly on the floor plane and on a box face", s, cam, w, h);
}

/// A rasterized floor under the degenerate cases' objects.
fn add_floor(s: &mut Scene) {
    let floor = Mat4::from_translation(Vec3::new(0.0, -1.0, 0.0)) * Mat4::from_scale(Vec3::splat(6.0));
    s.add_object(Mesh::grid("floor", 4), diffuse("f", Vec3::splat(0.6)), floor, RASTER);
}

fn degenerate_cases(b: &mut Builder) {
    let (w, h) = (48u32, 32u32);
    let cam = camera(Vec3::new(0.0, 0.5, 4.0), Vec3::ZERO, 0.1, 100.0);
    let lights = vec![point(Vec3::new(1.0, 3.0, 3.0), 20.0)];

    // Zero-area triangles (repeated vertex, collinear, all equal) among normal ones.
    let mut s = Scene { lights: lights.clone(), ..Scene::default() };
    let p = vec![
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.5, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
    ];
    let idx = vec![[0, 0, 1], [3, 4, 5], [2, 2, 2], [0, 1, 2], [1, 1, 2], [5, 4, 3]];
    s.add_object(mesh("zero_area", p, idx), diffuse("z", Vec3::splat(0.8)), Mat4::IDENTITY, RT);
    add_floor(&mut s);
    b.add(
        "degenerate_zero_area_triangles",
        "zero-area triangles (repeated and collinear vertices) among normal ones",
        s,
        cam,
        w,
        h,
    );

    // NaN and Inf vertices.
    let mut s = Scene { lights: lights.clone(), ..Scene::default() };
    let p = vec![
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(f32::NAN, 0.0, 0.0),
        Vec3::new(0.0, f32::INFINITY, 0.0),
        Vec3::new(f32::NEG_INFINITY, f32::NAN, 1.0),
    ];
    let idx = vec![[0, 1, 3], [0, 1, 2], [1, 4, 2], [3, 4, 5], [5, 0, 2]];
    s.add_object(mesh("non_finite", p, idx), diffuse("n", Vec3::splat(0.8)), Mat4::IDENTITY, RT);
    add_floor(&mut s);
    b.add(
        "degenerate_nan_and_inf_vertices",
        "triangles with NaN and Inf vertices are neither covered nor hit",
        s,
        cam,
        w,
        h,
    );

    b.add(
        "degenerate_empty_scene",
        "no objects: every stage runs on nothing",
        Scene { lights: lights.clone(), ..Scene::default() },
        cam,
        w,
        h,
    );

    let mut s = Scene::default();
    stage_set(&mut s, 6.0);
    // A mirror and a glass ball: their bounces run without shadow rays at any depth.
    s.add_object(
        Mesh::uv_sphere("gold_ball", 16, 8),
        gold(),
        Mat4::from_translation(Vec3::new(-0.8, 0.6, 0.0)) * Mat4::from_scale(Vec3::splat(0.5)),
        RT,
    );
    s.add_object(
        Mesh::uv_sphere("glass_ball", 16, 8),
        glass(1.5),
        Mat4::from_translation(Vec3::new(0.8, 0.6, 0.0)) * Mat4::from_scale(Vec3::splat(0.5)),
        RT,
    );
    b.add("degenerate_no_lights", "no lights: no shadow rays at all, bounces without them", s, cam, w, h);

    let (s, mut c) = transformed_default(Vec3::ZERO, 1.0);
    c.target = c.eye + (c.eye - c.target);
    b.add("degenerate_all_miss", "the camera looks away: no pixel covered", s, c, w, h);

    let mut s = Scene { lights: vec![point(Vec3::new(0.0, 0.0, 1.0), 5.0)], ..Scene::default() };
    s.add_object(
        Mesh::grid("wall", 4),
        diffuse("w", Vec3::splat(0.8)),
        Mat4::from_quat(Quat::from_rotation_x(std::f32::consts::FRAC_PI_2)) * Mat4::from_scale(Vec3::splat(20.0)),
        RT,
    );
    s.add_object(
        Mesh::uv_sphere("ball", 16, 8),
        diffuse("b", Vec3::new(0.9, 0.5, 0.2)),
        Mat4::from_translation(Vec3::new(0.3, 0.0, 0.5)) * Mat4::from_scale(Vec3::splat(0.3)),
        RASTER,
    );
    let c = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 0.1, 100.0);
    b.add("degenerate_all_hit", "a wall fills the frame: every pixel covered", s, c, w, h);
}

fn size_cases(b: &mut Builder) {
    let s = paper_default_scene();
    let cam = s.camera.unwrap();
    for (name, w, h, stresses) in [
        ("size_1x1", 1, 1, "a single pixel"),
        ("size_odd_67x41", 67, 41, "odd size: no multiple of any tile or workgroup size"),
        ("size_wide_rows_257x3", 257, 3, "rows of 1,028 bytes of u32 and 6,168 bytes of texels: not multiples of 256"),
        ("size_tall_1x97", 1, 97, "a single column"),
    ] {
        b.add(name, stresses, s.clone(), cam, w, h);
    }
}

/// The whole corpus. Paper scenes are included when `../shared/assets` is present
/// (`shared`), with a message otherwise.
pub fn corpus() -> Vec<Case> {
    let mut b = Builder { cases: Vec::new() };
    default_case(&mut b);
    match shared_assets() {
        Some(dir) => paper_cases(&mut b, &dir),
        None => eprintln!("conformance corpus: ../shared/assets not found: paper scenes skipped"),
    }
    raster_cases(&mut b);
    ray_cases(&mut b);
    degenerate_cases(&mut b);
    size_cases(&mut b);
    bounce_cases(&mut b);
    texture_cases(&mut b);
    instance_cases(&mut b);
    shading_cases(&mut b);
    stochastic_cases(&mut b);
    b.cases
}

/// Shadow rays per area light of the `stochastic_*` cases: few, so that CI stays fast.
const STOCHASTIC_SHADOW_SAMPLES: u32 = 3;
/// Ambient-occlusion rays of the `stochastic_*` cases that trace them.
const STOCHASTIC_AO_SAMPLES: u32 = 2;

/// A floor (rasterized) with a box on it (ray traced) and a ball (rasterized) for the
/// stochastic cases' lights to shadow: penumbrae across both kinds of pixels.
fn box_on_floor(lights: Vec<Light>, shading: ShadingModel) -> Scene {
    let mut s = Scene { lights, shading, ..Scene::default() };
    s.add_object(
        Mesh::grid("floor", 4),
        diffuse("floor", Vec3::splat(0.7)),
        Mat4::from_scale(Vec3::splat(6.0)),
        RASTER,
    );
    s.add_object(
        Mesh::cube("box"),
        diffuse("box", Vec3::new(0.8, 0.45, 0.2)),
        Mat4::from_translation(Vec3::new(-0.3, 0.4, 0.0))
            * Mat4::from_quat(Quat::from_rotation_y(0.5))
            * Mat4::from_scale(Vec3::splat(0.4)),
        RT,
    );
    s.add_object(
        Mesh::uv_sphere("ball", 16, 8),
        diffuse("ball", Vec3::new(0.3, 0.5, 0.8)),
        Mat4::from_translation(Vec3::new(0.8, 0.3, 0.4)) * Mat4::from_scale(Vec3::splat(0.3)),
        RASTER,
    );
    s
}

/// `s` with a ray-traced mirror standing behind the box: the hits of its reflection rays
/// trace and shade the same slots as the primary hits.
fn before_mirror(mut s: Scene) -> Scene {
    s.add_object(
        Mesh::grid("mirror", 2),
        mirror(),
        Mat4::from_translation(Vec3::new(0.0, 0.9, -1.0))
            * Mat4::from_quat(Quat::from_rotation_x(std::f32::consts::FRAC_PI_2))
            * Mat4::from_scale(Vec3::new(3.0, 1.0, 1.8)),
        RT,
    );
    s
}

/// `s` with emissive meshes as lights (`emissive_lights`): a panel over the box (a one-cell
/// grid turned to face down, two single-sided triangles) and a small double-sided glowing
/// ball (of another colour and power).
fn with_emitters(mut s: Scene) -> Scene {
    s.emissive_lights = true;
    let glow = |name: &str, emissive: Vec3, double_sided: bool| Material {
        base_color: Vec3::ZERO,
        emissive,
        double_sided,
        ..diffuse(name, Vec3::ZERO)
    };
    s.add_object(
        Mesh::grid("panel", 1),
        glow("panel", Vec3::new(7.0, 6.5, 5.8), false),
        Mat4::from_translation(Vec3::new(-0.2, 1.9, 0.0))
            * Mat4::from_quat(Quat::from_rotation_x(std::f32::consts::PI))
            * Mat4::from_scale(Vec3::new(1.0, 1.0, 0.8)),
        RASTER,
    );
    s.add_object(
        Mesh::uv_sphere("glow", 8, 4),
        glow("glow", Vec3::new(1.0, 2.5, 5.0), true),
        Mat4::from_translation(Vec3::new(-1.1, 0.4, 0.9)) * Mat4::from_scale(Vec3::splat(0.15)),
        RASTER,
    );
    s
}

/// The `stochastic_*` cases (module docs): area lights' samples and ambient-occlusion
/// rays on every stage, without the denoiser, then the same scenes denoised
/// (`stochastic_denoised_*`).
fn stochastic_cases(b: &mut Builder) {
    let (w, h) = (96u32, 64u32);
    let cam = camera(Vec3::new(0.6, 2.0, 3.2), Vec3::new(0.0, 0.3, 0.0), 0.05, 50.0);
    let quad = || Light::Quad {
        corner: Vec3::new(-0.7, 2.0, -0.5),
        edge_u: Vec3::new(1.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, 0.8),
        color: Vec3::new(1.0, 0.95, 0.85),
        intensity: 8.0,
    };
    let samples = |b: &mut Builder, shadow: u32, ao: u32| {
        let case = b.cases.last_mut().expect("a case");
        (case.shadow_samples, case.ao_samples) = (shadow, ao);
    };
    for (name, shading, stresses) in [
        (
            "stochastic_quad_light_box",
            ShadingModel::Paper,
            "a quad light's samples over a box and a ball on a floor: penumbrae on rasterized and ray-traced pixels",
        ),
        (
            "stochastic_gltf_quad_light_box",
            ShadingModel::Gltf,
            "the quad light's samples through the glTF BRDF and the image-based light",
        ),
    ] {
        b.add(name, stresses, box_on_floor(vec![quad()], shading), cam, w, h);
        samples(b, STOCHASTIC_SHADOW_SAMPLES, 0);
    }
    let sphere = Light::Sphere {
        position: Vec3::new(-1.0, 1.3, 0.8),
        radius: 0.3,
        color: Vec3::new(1.0, 0.85, 0.6),
        intensity: 12.0,
    };
    b.add(
        "stochastic_sphere_light",
        "a sphere light's cone samples beside a point light's one slot",
        box_on_floor(vec![point(Vec3::new(1.5, 2.5, 1.5), 6.0), sphere], ShadingModel::Paper),
        cam,
        w,
        h,
    );
    samples(b, STOCHASTIC_SHADOW_SAMPLES, 0);
    let sun = Light::Sun {
        direction: Vec3::new(0.5, -1.0, -0.4).normalize(),
        angular_diameter: 0.2,
        color: Vec3::new(1.0, 0.95, 0.9),
        intensity: 2.5,
    };
    b.add(
        "stochastic_sun",
        "a sun of finite angular size: directions in its cone, rays to infinity",
        box_on_floor(vec![sun], ShadingModel::Gltf),
        cam,
        w,
        h,
    );
    samples(b, STOCHASTIC_SHADOW_SAMPLES, 0);
    // Ambient occlusion alone: a box in the corner of a floor and a wall, a point light.
    let mut s = box_on_floor(vec![point(Vec3::new(1.0, 2.5, 2.0), 10.0)], ShadingModel::Paper);
    s.add_object(
        Mesh::grid("wall", 4),
        diffuse("wall", Vec3::new(0.8, 0.3, 0.25)),
        Mat4::from_translation(Vec3::new(0.0, 1.0, -0.5))
            * Mat4::from_quat(Quat::from_rotation_x(std::f32::consts::FRAC_PI_2))
            * Mat4::from_scale(Vec3::splat(6.0)),
        RT,
    );
    b.add(
        "stochastic_ambient_occlusion",
        "ambient-occlusion rays alone (a point light's one slot, then theirs) in the corners of a box, a floor and a wall",
        s,
        cam,
        w,
        h,
    );
    samples(b, DEFAULT_SHADOW_SAMPLES, STOCHASTIC_AO_SAMPLES);
    // A quad light and occlusion rays in front of a ray-traced mirror: the bounces' hits
    // trace and shade the same slots.
    let s = before_mirror(box_on_floor(vec![quad(), point(Vec3::new(1.5, 2.0, 2.0), 4.0)], ShadingModel::Paper));
    b.add(
        "stochastic_mirror_bounces",
        "a quad light's samples and occlusion rays at the hits of a mirror's reflection rays (every bounce depth)",
        s,
        cam,
        w,
        h,
    );
    samples(b, STOCHASTIC_SHADOW_SAMPLES, STOCHASTIC_AO_SAMPLES);
    b.cases.last_mut().expect("a case").max_depth = 2;
    // Emissive meshes as lights: the panel and ball of `with_emitters` over the box, then
    // beside a point light in front of the mirror (the bounces' hits sample the emitters).
    b.add(
        "stochastic_emitters_box",
        "emissive meshes as lights: a triangle picked by power, a point on it, the box's soft shadow",
        with_emitters(box_on_floor(vec![], ShadingModel::Paper)),
        cam,
        w,
        h,
    );
    samples(b, STOCHASTIC_SHADOW_SAMPLES, 0);
    let s = before_mirror(with_emitters(box_on_floor(vec![point(Vec3::new(1.5, 2.0, 2.0), 4.0)], ShadingModel::Gltf)));
    b.add(
        "stochastic_gltf_emitters_mirror_bounces",
        "the emitter light (last, after a point light) through the glTF BRDF at the primary hits and at every bounce depth's",
        s,
        cam,
        w,
        h,
    );
    samples(b, STOCHASTIC_SHADOW_SAMPLES, 0);
    b.cases.last_mut().expect("a case").max_depth = 2;
    // Every case again, denoised.
    let raw: Vec<Case> = b.cases.iter().filter(|c| c.name.starts_with("stochastic_")).cloned().collect();
    for case in raw {
        let name = format!("stochastic_denoised_{}", &case.name["stochastic_".len()..]);
        b.cases.push(Case { name, denoise: true, ..case });
    }
}

/// Cases of the other families again with the glTF BRDF on every object
/// ([`ShadingModel::Gltf`]): the paper's default scene, every bounce case (mirrors and
/// glass, their direct light through `shade_ray_traced_with`), and up to three textured
/// and three two-level ones (materials varying per pixel, records in object space).
fn shading_cases(b: &mut Builder) {
    let family = |prefix: &'static str, most: usize| {
        b.cases.iter().filter(move |c| c.name.starts_with(prefix)).take(most).cloned()
    };
    let picked: Vec<Case> = family("paper_default", usize::MAX)
        .chain(family("bounce_", usize::MAX))
        .chain(family("texture_", 3))
        .chain(family("instance_", 3))
        .collect();
    for case in picked {
        let scene = Scene { shading: ShadingModel::Gltf, ..case.scene };
        b.cases.push(Case { name: format!("shading_gltf_{}", case.name), scene, ..case });
    }
    // Issue 37's check scene: smooth to rough, dielectric to metal, rasterized and ray
    // traced, one directional light (its analytic twin: cpu-backend/tests/gltf_brdf.rs).
    let mut scene = Scene { shading: ShadingModel::Gltf, ..Scene::default() };
    for (i, (metallic, roughness)) in
        [(0.0, 0.05), (0.0, 0.5), (1.0, 0.2), (1.0, 0.7), (0.5, 0.35), (0.5, 1.0)].into_iter().enumerate()
    {
        let base = Vec3::new(0.9, 0.3 + 0.1 * i as f32, 0.2);
        let material = Material { metallic, roughness, ..diffuse(&format!("sphere {i}"), base) };
        let at = Mat4::from_translation(Vec3::new(i as f32 * 2.5 - 6.25, 0.0, 0.0));
        let mode = if i % 2 == 0 { RenderMode::Raster } else { RenderMode::RayTraced };
        scene.add_object(Mesh::uv_sphere("sphere", 32, 16), material, at, mode);
    }
    let direction = Vec3::new(-0.3, -0.8, -0.5).normalize();
    scene.lights = vec![Light::Directional { direction, color: Vec3::ONE, intensity: 3.0 }];
    let cam = camera(Vec3::new(0.0, 2.0, 9.0), Vec3::ZERO, 0.1, 30.0);
    let dark = Scene { ambient: Ambient(0.0), ..scene.clone() };
    let mapped = Scene { environment: procedural_environment(), ..scene.clone() };
    b.add("shading_gltf_spheres", "the glTF BRDF from smooth to rough, dielectric to metal", scene, cam, 96, 40);
    b.add(
        "shading_gltf_spheres_environment_map",
        "the spheres under an environment map's image-based light: every prefiltered level",
        mapped,
        cam,
        96,
        40,
    );
    b.add(
        "shading_gltf_spheres_without_ambient",
        "the same spheres with ambient = 0: direct light alone",
        dark,
        cam,
        96,
        40,
    );
    // A metal mirror and glass with ambient = 0: no constant term anywhere, untraced lobes
    // and the mirror's own ambient included.
    let (s, cam) = transformed_default(Vec3::ZERO, 1.0);
    let s = Scene { ambient: Ambient(0.0), ..s };
    b.add("paper_default_scene_without_ambient", "mirrors and glass with ambient = 0", s, cam, 64, 48);
    // The image-based light of an environment map (every other glTF case has the default
    // sky's): the default scene's rasterized and ray-traced objects, its golden mirror and
    // glass at the library's depth, and at depth 1, where the lobes of the first bounce's
    // mirror and glass hits are not traced and see the prefiltered map instead.
    let s = Scene { shading: ShadingModel::Gltf, environment: procedural_environment(), ..Scene::default_scene() };
    let cam = s.camera.unwrap();
    b.add(
        "shading_gltf_environment_map",
        "the default scene under an environment map's image-based light, mirrors and glass",
        s.clone(),
        cam,
        64,
        48,
    );
    b.add(
        "shading_gltf_environment_map_depth_1",
        "an environment map's prefiltered light in the untraced lobes of depth 1",
        s,
        cam,
        64,
        48,
    );
    b.cases.last_mut().expect("a case").max_depth = 1;
}

/// A small procedural environment map (32 x 16, linear RGB): a blue gradient sky with a
/// bright sun, a warm band along the horizon and a dark checkered ground, so that the
/// prefiltered levels and the irradiance vary with the direction.
fn procedural_environment() -> Environment {
    let (w, h) = (32u32, 16u32);
    let texels = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| {
            let t = j as f32 / (h / 2) as f32;
            let rgb = if (i, j) == (9, 3) {
                [60.0, 55.0, 45.0]
            } else if j + 1 == h / 2 {
                [1.2, 0.7, 0.35]
            } else if j < h / 2 {
                [0.2 + 0.5 * t, 0.35 + 0.45 * t, 0.9 - 0.2 * t]
            } else if (i / 4 + j / 2) % 2 == 0 {
                [0.12, 0.1, 0.08]
            } else {
                [0.3, 0.25, 0.18]
            };
            [rgb[0], rgb[1], rgb[2], 1.0]
        })
        .collect();
    Environment::Map(Arc::new(EnvironmentMap::new(w, h, texels).expect("a valid environment map")))
}

/// Scenes traced through two levels: objects prepared as moving, in their own space,
/// scaled, rotated, mirrored, sharing a mesh, far from the origin.
fn instance_cases(b: &mut Builder) {
    let (w, h) = (64u32, 48u32);
    let moving_all = |b: &mut Builder| {
        let case = b.cases.last_mut().expect("a case");
        case.moving = (0..case.scene.objects.len() as u32).collect();
    };
    // One closed ball mesh drawn five times: scaled unevenly, rotated, mirrored, glass and
    // mirror and diffuse, rasterized and ray traced, on a floor and a wall baked in world
    // space. Rays leave and enter instances; shadows fall across them.
    let mut s = Scene { lights: vec![point(Vec3::new(1.0, 4.0, 3.0), 40.0)], ..Scene::default() };
    stage_set(&mut s, 8.0);
    let ball = Mesh::uv_sphere("ball", 24, 12);
    s.add_object(
        ball,
        glass(1.5),
        Mat4::from_translation(Vec3::new(-1.6, 0.6, 0.0)) * Mat4::from_scale(Vec3::splat(0.6)),
        RT,
    );
    let shared = s.objects.last().expect("the ball").mesh;
    let placements = [
        (Vec3::new(-0.3, 0.5, -0.4), Vec3::new(0.8, 0.5, 0.6), 0.7, mirror(), RT),
        (Vec3::new(0.9, 0.7, 0.2), Vec3::new(-0.5, 0.7, 0.5), -1.1, diffuse("orange", Vec3::new(0.9, 0.5, 0.1)), RT),
        (Vec3::new(1.9, 0.4, -0.6), Vec3::new(0.4, 0.4, -0.9), 2.0, glass(1.33), RT),
        (Vec3::new(0.3, 1.6, -1.2), Vec3::new(0.6, 0.3, 0.6), 0.3, diffuse("green", Vec3::new(0.2, 0.8, 0.3)), RASTER),
    ];
    for (i, (at, scale, angle, material, mode)) in placements.into_iter().enumerate() {
        s.materials.push(material);
        let id = s.objects.len() as u32;
        s.objects.push(hyrt_core::scene::Object {
            id,
            name: format!("ball {i}"),
            mesh: shared,
            transform: Mat4::from_scale_rotation_translation(scale, Quat::from_rotation_y(angle), at),
            material: s.materials.len() - 1,
            render_mode: mode,
            source: Default::default(),
        });
    }
    let cam = camera(Vec3::new(0.2, 1.6, 4.2), Vec3::new(0.2, 0.7, 0.0), 0.05, 50.0);
    b.add(
        "instance_shared_mirrored_scaled",
        "one ball mesh in five instances (uneven scales, rotations, mirrors; glass, mirror, diffuse) over baked geometry",
        s,
        cam,
        w,
        h,
    );
    b.cases.last_mut().expect("a case").moving = vec![2];

    // Every object an instance, the whole group 1e4 from the origin: the maps subtract the
    // translation before they rotate, so rays stay as precise as at the origin.
    let mut s = Scene { lights: vec![point(Vec3::new(1e4 + 1.0, 4.0, 3.0), 40.0)], ..Scene::default() };
    let far = Mat4::from_translation(Vec3::new(1e4, 0.0, 0.0));
    s.add_object(
        Mesh::grid("floor", 4),
        diffuse("floor", Vec3::splat(0.7)),
        far * Mat4::from_scale(Vec3::splat(6.0)),
        RT,
    );
    s.add_object(
        Mesh::uv_sphere("far_ball", 24, 12),
        glass(1.5),
        far * Mat4::from_scale_rotation_translation(
            Vec3::new(0.7, 0.5, 0.9),
            Quat::from_rotation_z(0.5),
            Vec3::Y * 0.6,
        ),
        RT,
    );
    s.add_object(
        Mesh::cube("far_box"),
        mirror(),
        far * Mat4::from_scale_rotation_translation(
            Vec3::new(-0.4, 0.6, 0.3),
            Quat::from_rotation_y(0.8),
            Vec3::new(1.2, 0.6, -0.5),
        ),
        RT,
    );
    let cam = camera(Vec3::new(1e4 + 0.3, 1.5, 3.5), Vec3::new(1e4 + 0.3, 0.5, 0.0), 0.05, 50.0);
    b.add(
        "instance_far_from_origin",
        "every object an instance, 1e4 from the origin, mirrored and rotated",
        s,
        cam,
        w,
        h,
    );
    moving_all(b);
}

/// A perfect mirror: metallic, roughness 0, a faint tint.
fn mirror() -> Material {
    Material {
        name: "mirror".into(),
        base_color: Vec3::new(0.95, 0.95, 0.92),
        metallic: 1.0,
        roughness: 0.0,
        transmission: 0.0,
        kind: MaterialKind::Specular,
        ..Material::grey()
    }
}

/// Clear glass of index `ior`.
fn glass(ior: f32) -> Material {
    Material {
        name: format!("glass {ior}"),
        base_color: Vec3::new(0.97, 0.98, 1.0),
        metallic: 0.0,
        roughness: 0.0,
        transmission: 1.0,
        kind: MaterialKind::Glass { ior },
        ..Material::grey()
    }
}

fn bounce_cases(b: &mut Builder) {
    let (w, h) = (64u32, 48u32);
    let with_depth = |b: &mut Builder, depth: u32| b.cases.last_mut().expect("a case").max_depth = depth;

    // Two parallel mirrors facing each other with a ball between them, seen at an
    // angle: rays bounce between the mirrors until the depth limit.
    let mut s = Scene { lights: vec![point(Vec3::new(0.0, 3.0, 1.0), 30.0)], ..Scene::default() };
    s.add_object(Mesh::grid("floor", 4), diffuse("floor", Vec3::splat(0.7)), Mat4::from_scale(Vec3::splat(8.0)), RT);
    for (name, x, angle) in [("mirror_left", -1.5f32, -1.0f32), ("mirror_right", 1.5, 1.0)] {
        s.add_object(
            Mesh::grid(name, 2),
            mirror(),
            Mat4::from_translation(Vec3::new(x, 1.0, 0.0))
                * Mat4::from_quat(Quat::from_rotation_z(angle * std::f32::consts::FRAC_PI_2))
                * Mat4::from_scale(Vec3::new(2.0, 1.0, 12.0)),
            RT,
        );
    }
    s.add_object(
        Mesh::uv_sphere("ball", 16, 8),
        diffuse("ball", Vec3::new(0.9, 0.4, 0.1)),
        Mat4::from_translation(Vec3::new(0.3, 0.5, 0.0)) * Mat4::from_scale(Vec3::splat(0.4)),
        RASTER,
    );
    let cam = camera(Vec3::new(-1.2, 1.1, 2.0), Vec3::new(1.5, 0.9, 1.4), 0.05, 50.0);
    b.add("bounce_parallel_mirrors", "rays between two parallel mirrors until the depth limit", s, cam, w, h);
    with_depth(b, 8);

    // A glass sphere of high index seen whole: its rim reflects totally inside.
    let mut s = Scene { lights: vec![point(Vec3::new(2.0, 4.0, 3.0), 40.0)], ..Scene::default() };
    stage_set(&mut s, 8.0);
    s.add_object(
        Mesh::uv_sphere("diamond_ball", 32, 16),
        glass(2.4),
        Mat4::from_translation(Vec3::new(0.0, 1.0, 0.0)),
        RT,
    );
    let cam = camera(Vec3::new(0.0, 1.4, 3.5), Vec3::new(0.0, 1.0, 0.0), 0.05, 50.0);
    b.add(
        "bounce_glass_total_internal_reflection",
        "a glass sphere of index 2.4: total internal reflection",
        s,
        cam,
        w,
        h,
    );
    with_depth(b, 6);

    // A glass slab seen edge-on from just above its top face: refraction at grazing
    // incidence, Fresnel near 1.
    let mut s = Scene { lights: vec![point(Vec3::new(0.0, 3.0, -2.0), 30.0)], ..Scene::default() };
    stage_set(&mut s, 8.0);
    s.add_object(
        Mesh::cube("slab"),
        glass(1.5),
        Mat4::from_translation(Vec3::new(0.0, 0.5, 0.0)) * Mat4::from_scale(Vec3::new(2.0, 0.25, 1.5)),
        RT,
    );
    let cam = camera(Vec3::new(0.0, 0.78, 4.0), Vec3::new(0.0, 0.74, 0.0), 0.05, 50.0);
    b.add("bounce_grazing_refraction", "refraction into a slab's top face at grazing incidence", s, cam, w, h);

    // Glass inside glass: media are not nested (each surface separates its object's
    // index from air), documented in hyrt_core::kernels::bounce; both backends agree.
    let mut s = Scene { lights: vec![point(Vec3::new(1.0, 4.0, 2.0), 40.0)], ..Scene::default() };
    stage_set(&mut s, 8.0);
    s.add_object(Mesh::uv_sphere("outer", 32, 16), glass(1.5), Mat4::from_translation(Vec3::new(0.0, 1.0, 0.0)), RT);
    s.add_object(
        Mesh::uv_sphere("inner", 24, 12),
        glass(1.33),
        Mat4::from_translation(Vec3::new(0.1, 1.0, 0.1)) * Mat4::from_scale(Vec3::splat(0.5)),
        RT,
    );
    let cam = camera(Vec3::new(0.0, 1.3, 3.2), Vec3::new(0.0, 1.0, 0.0), 0.05, 50.0);
    b.add("bounce_glass_inside_glass", "a glass ball inside another (media not nested)", s, cam, w, h);
    with_depth(b, 8);

    // Low-poly glass seen along its axes: an axis-aligned cube straight on (the centre
    // ray enters through a face's diagonal edge and leaves through the opposite one) and
    // an octahedron-like sphere: refracted rays leave through shared edges and vertices.
    let mut s = Scene { lights: vec![point(Vec3::new(0.5, 4.0, 0.5), 40.0)], ..Scene::default() };
    s.add_object(Mesh::grid("floor", 8), diffuse("floor", Vec3::splat(0.8)), Mat4::from_scale(Vec3::splat(8.0)), RT);
    s.add_object(Mesh::cube("glass_cube"), glass(1.5), Mat4::from_translation(Vec3::new(0.0, 0.0, 0.0)), RT);
    s.add_object(Mesh::uv_sphere("octahedron", 4, 2), glass(1.5), Mat4::from_translation(Vec3::new(2.5, 0.0, 0.0)), RT);
    let cam = camera(Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO, 0.05, 50.0);
    b.add(
        "bounce_through_shared_edges_and_vertices",
        "refracted rays through the shared edges and vertices of low-poly glass, on axis",
        s,
        cam,
        63,
        47,
    );

    // The default scene (a golden mirror sphere and a glass ball) 1e5 from the origin:
    // coordinates of ulp 2^-7, where origin offsets decide self-intersection.
    let (s, cam) = transformed_default(Vec3::new(1.0e5, 0.0, 1.0e5), 1.0);
    b.add("bounce_mirror_far_from_origin", "mirror and glass 1e5 from the origin", s, cam, w, h);
}

/// A `w` x `h` image whose texel `(x, y)` is `texel(x, y)`.
fn image(name: &str, w: u32, h: u32, texel: impl Fn(u32, u32) -> [u8; 4]) -> TextureImage {
    let texels = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| texel(x, y)).collect();
    TextureImage::new(name.into(), w, h, texels).expect("a valid image")
}

/// A colourful 32 x 32 image with detail at every scale: red along x, green along y, blue
/// in 4-texel checks, and a one-texel grid every 8 texels (so every mip level differs).
fn pattern_image() -> TextureImage {
    image("pattern", 32, 32, |x, y| {
        let check = if (x / 4 + y / 4) % 2 == 0 { 230 } else { 40 };
        let line = x % 8 == 0 || y % 8 == 0;
        if line {
            [250, 250, 250, 255]
        } else {
            [(x * 255 / 31) as u8, (y * 255 / 31) as u8, check, 255]
        }
    })
}

/// Add `image` to the scene and bind it with `sampler` and `transform` (coordinate set 0).
fn bind(scene: &mut Scene, image: TextureImage, sampler: Sampler, transform: UvTransform) -> TextureBinding {
    scene.textures.push(Arc::new(image));
    TextureBinding { image: scene.textures.len() - 1, sampler, tex_coord: 0, transform }
}

/// `mesh` with texture coordinates `uv(vertex index, position)`.
fn with_uvs(mut mesh: Mesh, uv: impl Fn(usize, Vec3) -> Vec2) -> Mesh {
    let coords = mesh.positions.iter().enumerate().map(|(i, &p)| uv(i, p)).collect();
    mesh.attributes.tex_coords[0] = Some(coords);
    mesh
}

/// A grid (`Mesh::grid`: the XZ square [-0.5, 0.5]^2, normal +Y) whose texture coordinates
/// run over `[0, repeat]^2`, u along x and v along z.
fn uv_grid(name: &str, n: u32, repeat: f32) -> Mesh {
    with_uvs(Mesh::grid(name, n), |_, p| Vec2::new(p.x + 0.5, p.z + 0.5) * repeat)
}

/// A UV sphere (`Mesh::uv_sphere`) with its own coordinates: u around (seam vertices at
/// 1), v from pole to pole.
fn uv_sphere(name: &str, segments: u32, rings: u32) -> Mesh {
    let row = segments as usize + 1;
    with_uvs(Mesh::uv_sphere(name, segments, rings), |i, _| {
        Vec2::new((i % row) as f32 / segments as f32, (i / row) as f32 / rings as f32)
    })
}

/// A diffuse material of colour `rgb` whose base colour is multiplied by `texture`.
fn textured(name: &str, rgb: Vec3, texture: TextureBinding) -> Material {
    Material { base_color_texture: Some(texture), ..diffuse(name, rgb) }
}

/// Nearest filtering everywhere, level 0 only, clamped: every texel a hard square.
const NEAREST: Sampler = Sampler {
    wrap_s: Wrap::ClampToEdge,
    wrap_t: Wrap::ClampToEdge,
    mag: Filter::Nearest,
    min: Filter::Nearest,
    mip: None,
};

/// A fence texture: `cells` x `cells` texels, opaque (alpha 255) where `x + y` is even and
/// a hole (alpha 0) elsewhere; the opaque texels alternate two colours by column.
fn fence_image(cells: u32) -> TextureImage {
    image("fence", cells, cells, |x, y| {
        let a = if (x + y) % 2 == 0 { 255 } else { 0 };
        if x % 2 == 0 {
            [220, 180, 60, a]
        } else {
            [60, 140, 220, a]
        }
    })
}

fn texture_cases(b: &mut Builder) {
    let (w, h) = (64u32, 48u32);
    let with_depth = |b: &mut Builder, depth: u32| b.cases.last_mut().expect("a case").max_depth = depth;

    // A textured ray-traced floor (trilinear, repeat, under a rotating and scaling
    // KHR_texture_transform), a rasterized sphere (bilinear, no mip maps) and a ray-traced
    // one (nearest mip level, nearest within it), all with the one pattern image.
    let mut s = Scene { lights: vec![point(Vec3::new(1.5, 4.0, 3.0), 40.0)], ..Scene::default() };
    let transform = UvTransform { offset: Vec2::new(0.1, -0.3), rotation: 0.4, scale: Vec2::new(1.5, 0.75) };
    let floor = bind(&mut s, pattern_image(), Sampler::default(), transform);
    s.add_object(uv_grid("floor", 4, 3.0), textured("floor", Vec3::ONE, floor), Mat4::from_scale(Vec3::splat(8.0)), RT);
    let bilinear = bind(&mut s, pattern_image(), Sampler { mip: None, ..Sampler::default() }, UvTransform::default());
    s.add_object(
        uv_sphere("raster_ball", 24, 12),
        textured("raster_ball", Vec3::new(1.0, 0.9, 0.8), bilinear),
        Mat4::from_translation(Vec3::new(-1.1, 0.8, 0.0)) * Mat4::from_scale(Vec3::splat(0.8)),
        RASTER,
    );
    let nearest_mip = Sampler { min: Filter::Nearest, mip: Some(Filter::Nearest), ..Sampler::default() };
    let scaled = UvTransform { scale: Vec2::new(4.0, 2.0), ..UvTransform::default() };
    let nearest = bind(&mut s, pattern_image(), nearest_mip, scaled);
    s.add_object(
        uv_sphere("rt_ball", 24, 12),
        textured("rt_ball", Vec3::ONE, nearest),
        Mat4::from_translation(Vec3::new(1.1, 0.8, 0.0)) * Mat4::from_scale(Vec3::splat(0.8)),
        RT,
    );
    let cam = camera(Vec3::new(0.0, 2.2, 4.5), Vec3::new(0.0, 0.5, 0.0), 0.1, 100.0);
    b.add(
        "texture_raster_and_ray_traced_filtering",
        "bilinear, trilinear and nearest-mip textures under a KHR transform, rasterized and ray traced",
        s,
        cam,
        w,
        h,
    );

    // Vertex colours: a rasterized grid coloured per vertex, a ray-traced sphere whose
    // vertex colours multiply a texture, and a plain object among them.
    let mut s = Scene { lights: vec![point(Vec3::new(-1.0, 3.0, 3.0), 30.0)], ..Scene::default() };
    let mut grid = Mesh::grid("coloured_grid", 6);
    grid.attributes.colors =
        Some(grid.positions.iter().map(|p| [p.x + 0.5, 1.0 - (p.z + 0.5), 0.5 + p.x * p.z, 1.0]).collect());
    s.add_object(
        grid,
        diffuse("coloured_grid", Vec3::ONE),
        Mat4::from_translation(Vec3::new(0.0, -0.5, 0.0)) * Mat4::from_scale(Vec3::splat(5.0)),
        RASTER,
    );
    let mut ball = uv_sphere("coloured_ball", 16, 8);
    ball.attributes.colors =
        Some(ball.positions.iter().map(|p| [0.6 + 0.4 * p.y, 0.5 + 0.5 * p.x, 1.0, 1.0]).collect());
    let texture = bind(&mut s, pattern_image(), Sampler::default(), UvTransform::default());
    s.add_object(
        ball,
        textured("coloured_ball", Vec3::ONE, texture),
        Mat4::from_translation(Vec3::new(0.6, 0.3, 0.0)) * Mat4::from_scale(Vec3::splat(0.7)),
        RT,
    );
    s.add_object(
        Mesh::cube("plain_box"),
        diffuse("plain_box", Vec3::new(0.3, 0.7, 0.4)),
        Mat4::from_translation(Vec3::new(-1.2, 0.0, 0.3)) * Mat4::from_scale(Vec3::splat(0.4)),
        RT,
    );
    let cam = camera(Vec3::new(0.0, 1.5, 4.0), Vec3::new(0.0, 0.0, 0.0), 0.1, 100.0);
    b.add("texture_vertex_colours", "vertex colours alone and times a texture, beside a plain object", s, cam, w, h);

    // A fence of 8 x 8 checker texels, every other one a hole (nearest, alpha-tested), in
    // front of a wall, lit through the holes: its shadow on the wall is a checker too. One
    // fence rasterized, one ray traced.
    let mut s = Scene { lights: vec![point(Vec3::new(0.5, 1.0, 4.0), 30.0)], ..Scene::default() };
    s.add_object(
        Mesh::grid("wall", 4),
        diffuse("wall", Vec3::splat(0.8)),
        Mat4::from_translation(Vec3::new(0.0, 0.0, -1.0))
            * Mat4::from_quat(Quat::from_rotation_x(std::f32::consts::FRAC_PI_2))
            * Mat4::from_scale(Vec3::splat(8.0)),
        RT,
    );
    for (name, x, mode) in [("fence_raster", -1.05f32, RASTER), ("fence_rt", 1.05, RT)] {
        let texture = bind(&mut s, fence_image(8), NEAREST, UvTransform::default());
        let fence = Material { alpha_mode: AlphaMode::Mask { cutoff: 0.5 }, ..textured(name, Vec3::ONE, texture) };
        s.add_object(
            Mesh::uv_quad(name),
            fence,
            Mat4::from_translation(Vec3::new(x, 0.0, 0.0)) * Mat4::from_scale(Vec3::splat(0.95)),
            mode,
        );
    }
    let cam = camera(Vec3::new(0.3, 0.4, 4.5), Vec3::new(0.0, 0.0, -0.5), 0.1, 100.0);
    b.add(
        "texture_alpha_fence_shadow",
        "an alpha-tested checker fence: holes in the raster, the rays and its shadow on a wall",
        s,
        cam,
        w,
        h,
    );

    // Alpha-mask edges across the diagonal two triangles share: an alpha ramp along u
    // (bilinear, clamped, cutoff 0.5) over a quad seen at an angle, and a grid whose
    // vertex-colour alpha (BLEND: tested at 0.5) falls along a diagonal of its own, its
    // contour crossing many shared edges; both cast shadows onto the floor.
    let mut s = Scene { lights: vec![point(Vec3::new(-1.0, 3.0, 2.0), 30.0)], ..Scene::default() };
    s.add_object(
        Mesh::grid("floor", 4),
        diffuse("floor", Vec3::splat(0.7)),
        Mat4::from_translation(Vec3::new(0.0, -1.0, 0.0)) * Mat4::from_scale(Vec3::splat(8.0)),
        RASTER,
    );
    let ramp = image("ramp", 4, 1, |x, _| [200, 80 + 40 * x as u8, 90, (x * 85) as u8]);
    let clamped = Sampler { wrap_s: Wrap::ClampToEdge, wrap_t: Wrap::ClampToEdge, mip: None, ..Sampler::default() };
    let texture = bind(&mut s, ramp, clamped, UvTransform::default());
    let ramped = Material { alpha_mode: AlphaMode::Mask { cutoff: 0.5 }, ..textured("ramp", Vec3::ONE, texture) };
    s.add_object(
        Mesh::uv_quad("ramp_quad"),
        ramped,
        Mat4::from_translation(Vec3::new(-0.9, 0.0, 0.0)) * Mat4::from_quat(Quat::from_rotation_y(0.5)),
        RASTER,
    );
    let mut grid = Mesh::grid("faded_grid", 5);
    grid.attributes.colors = Some(grid.positions.iter().map(|p| [0.9, 0.4, 0.7, 0.5 + (p.x - p.z) * 0.8]).collect());
    s.add_object(
        grid,
        Material { alpha_mode: AlphaMode::Blend, ..diffuse("faded_grid", Vec3::ONE) },
        Mat4::from_translation(Vec3::new(0.9, 0.0, 0.0))
            * Mat4::from_quat(Quat::from_rotation_x(1.2))
            * Mat4::from_scale(Vec3::splat(1.8)),
        RT,
    );
    let cam = camera(Vec3::new(0.0, 0.5, 4.0), Vec3::new(0.0, -0.2, 0.0), 0.1, 100.0);
    b.add(
        "texture_mask_edge_across_shared_edges",
        "alpha-mask contours (texture ramp, vertex-colour alpha) crossing triangles' shared edges",
        s,
        cam,
        w,
        h,
    );

    // A fine checker floor seen nearly edge-on: the footprint grows along the view, and
    // the level of detail climbs through the whole chain (trilinear on the rasterized
    // half, nearest level and nearest texel on the ray-traced half). The checker's hue
    // changes across the image and its contrast vanishes level by level, so every level
    // has colours of its own.
    let mut s = Scene { lights: vec![point(Vec3::new(0.0, 2.0, -2.0), 30.0)], ..Scene::default() };
    let checker = || {
        image("fine_checker", 64, 64, |x, y| {
            let (r, b) = ((x * 4) as u8, (y * 4) as u8);
            if (x + y) % 2 == 0 {
                [r, 240, b, 255]
            } else {
                [r / 2, 30, b / 2, 255]
            }
        })
    };
    for (name, x, sampler, mode) in [
        ("floor_trilinear", -2.0f32, Sampler::default(), RASTER),
        (
            "floor_nearest_mip",
            2.0,
            Sampler { mag: Filter::Nearest, min: Filter::Nearest, mip: Some(Filter::Nearest), ..Sampler::default() },
            RT,
        ),
    ] {
        let texture = bind(&mut s, checker(), sampler, UvTransform::default());
        s.add_object(
            uv_grid(name, 8, 16.0),
            textured(name, Vec3::ONE, texture),
            Mat4::from_translation(Vec3::new(x, 0.0, -10.0)) * Mat4::from_scale(Vec3::new(4.0, 1.0, 24.0)),
            mode,
        );
    }
    let cam = camera(Vec3::new(0.0, 0.12, 2.0), Vec3::new(0.0, 0.05, -10.0), 0.05, 100.0);
    b.add(
        "texture_grazing_floor_mip_selection",
        "a fine checker floor seen nearly edge-on: mip levels chosen by ray cones at grazing angles",
        s,
        cam,
        w,
        h,
    );

    // A mirror that shows a fence (alpha-tested, rasterized) and a textured wall behind
    // it, lit from between the mirror and the fence: secondary rays pass the fence's holes
    // (closest hit with the alpha test), so do the shadow rays of depth 1 from the wall
    // (the fence's shadow on it is a checker), and the wall is sampled with the cone the
    // reflection carries on.
    let mut s = Scene { lights: vec![point(Vec3::new(0.3, 1.2, -0.6), 20.0)], ..Scene::default() };
    s.add_object(
        Mesh::grid("mirror", 2),
        mirror(),
        Mat4::from_translation(Vec3::new(0.0, 0.0, -1.5))
            * Mat4::from_quat(Quat::from_rotation_x(std::f32::consts::FRAC_PI_2))
            * Mat4::from_scale(Vec3::new(4.0, 1.0, 3.0)),
        RT,
    );
    let texture = bind(&mut s, fence_image(6), NEAREST, UvTransform::default());
    let fence = Material { alpha_mode: AlphaMode::Mask { cutoff: 0.5 }, ..textured("fence", Vec3::ONE, texture) };
    s.add_object(
        Mesh::uv_quad("fence"),
        fence,
        Mat4::from_translation(Vec3::new(0.0, 0.2, 1.0)) * Mat4::from_quat(Quat::from_rotation_y(std::f32::consts::PI)),
        RASTER,
    );
    let texture = bind(&mut s, pattern_image(), Sampler::default(), UvTransform::default());
    s.add_object(
        Mesh::uv_quad("back_wall"),
        textured("back_wall", Vec3::ONE, texture),
        Mat4::from_translation(Vec3::new(0.0, 0.5, 3.0))
            * Mat4::from_quat(Quat::from_rotation_y(std::f32::consts::PI))
            * Mat4::from_scale(Vec3::splat(3.0)),
        RT,
    );
    let cam = camera(Vec3::new(0.4, 0.3, 0.2), Vec3::new(0.0, 0.2, -1.5), 0.05, 100.0);
    b.add(
        "texture_masked_geometry_in_a_mirror",
        "an alpha-tested fence and a textured wall seen in a mirror: alpha tests and cones of secondary rays",
        s,
        cam,
        w,
        h,
    );
    with_depth(b, 2);

    // Every wrap mode (and pairs of them) on quads whose coordinates run over
    // [-1.25, 2.25]: three periods, nearest and bilinear alternating.
    let mut s = Scene { lights: vec![point(Vec3::new(0.0, 1.0, 4.0), 20.0)], ..Scene::default() };
    let pairs = [
        (Wrap::Repeat, Wrap::Repeat),
        (Wrap::ClampToEdge, Wrap::ClampToEdge),
        (Wrap::MirroredRepeat, Wrap::MirroredRepeat),
        (Wrap::Repeat, Wrap::MirroredRepeat),
        (Wrap::MirroredRepeat, Wrap::ClampToEdge),
        (Wrap::ClampToEdge, Wrap::Repeat),
    ];
    let stretch = UvTransform { offset: Vec2::splat(-1.25), rotation: 0.0, scale: Vec2::splat(3.5) };
    for (k, (wrap_s, wrap_t)) in pairs.into_iter().enumerate() {
        let filter = if k % 2 == 0 { Filter::Nearest } else { Filter::Linear };
        let sampler = Sampler { wrap_s, wrap_t, mag: filter, min: filter, mip: None };
        let small =
            image("wrap", 5, 3, |x, y| [(x * 60) as u8, (y * 120) as u8, if (x + y) % 2 == 0 { 255 } else { 30 }, 255]);
        let texture = bind(&mut s, small, sampler, stretch);
        let (col, row) = ((k % 3) as f32, (k / 3) as f32);
        s.add_object(
            Mesh::uv_quad("wrapped"),
            textured("wrapped", Vec3::ONE, texture),
            Mat4::from_translation(Vec3::new(-2.2 + 2.2 * col, 1.1 - 2.2 * row, 0.0)),
            if k % 2 == 0 { RT } else { RASTER },
        );
    }
    let cam = camera(Vec3::new(0.0, 0.0, 6.5), Vec3::ZERO, 0.1, 100.0);
    b.add("texture_wrap_modes", "repeat, clamp-to-edge and mirrored repeat on each axis, three periods", s, cam, w, h);

    // The glTF material textures: a rasterized floor whose one ORM image (occlusion red,
    // roughness green, metallic blue, linear) is both its metallic-roughness and its
    // occlusion texture at half its base colour's resolution (the levels of detail
    // shift); a ray-traced mirror ball whose metallic-roughness texture alone makes bands
    // of metal and dielectric (its bounces shade the textured record); a glowing ball with
    // an emissive texture and factor, ray traced, and a rasterized one with emission alone.
    let mut s =
        Scene { lights: vec![point(Vec3::new(1.5, 4.0, 3.0), 40.0)], shading: ShadingModel::Gltf, ..Scene::default() };
    let orm = image("orm", 16, 16, |x, y| {
        let occlusion = if (x / 2 + y / 2) % 2 == 0 { 255 } else { 90 };
        [occlusion, (x * 17) as u8, (y * 17) as u8, 255]
    });
    let base = bind(&mut s, pattern_image(), Sampler::default(), UvTransform::default());
    let orm = bind(&mut s, orm, Sampler::default(), UvTransform::default());
    let floor = Material {
        metallic: 1.0,
        roughness: 1.0,
        maps: MaterialMaps {
            metallic_roughness: Some(orm),
            occlusion: Some(orm),
            occlusion_strength: 0.8,
            ..MaterialMaps::default()
        },
        ..textured("orm_floor", Vec3::ONE, base)
    };
    s.add_object(uv_grid("orm_floor", 4, 2.0), floor, Mat4::from_scale(Vec3::splat(8.0)), RASTER);
    let bands = image("bands", 8, 8, |_, y| [255, 60, if y % 4 < 2 { 255 } else { 0 }, 255]);
    let bands = bind(&mut s, bands, NEAREST, UvTransform::default());
    let ball = Material { maps: MaterialMaps { metallic_roughness: Some(bands), ..MaterialMaps::default() }, ..gold() };
    s.add_object(
        uv_sphere("banded_mirror", 24, 12),
        ball,
        Mat4::from_translation(Vec3::new(-1.1, 0.8, 0.0)) * Mat4::from_scale(Vec3::splat(0.8)),
        RT,
    );
    let glow = image("glow", 8, 4, |x, y| [(x * 36) as u8, 255, (y * 80) as u8, 255]);
    let glow = bind(&mut s, glow, Sampler::default(), UvTransform::default());
    let lamp = Material {
        emissive: Vec3::new(2.0, 1.5, 0.5),
        maps: MaterialMaps { emissive: Some(glow), ..MaterialMaps::default() },
        ..diffuse("lamp", Vec3::splat(0.2))
    };
    s.add_object(
        uv_sphere("lamp", 16, 8),
        lamp,
        Mat4::from_translation(Vec3::new(1.1, 0.8, 0.0)) * Mat4::from_scale(Vec3::splat(0.6)),
        RT,
    );
    s.add_object(
        Mesh::cube("ember"),
        Material { emissive: Vec3::new(0.8, 0.2, 0.05), ..diffuse("ember", Vec3::splat(0.1)) },
        Mat4::from_translation(Vec3::new(0.0, 0.3, 1.2)) * Mat4::from_scale(Vec3::splat(0.3)),
        RASTER,
    );
    let cam = camera(Vec3::new(0.0, 2.2, 4.5), Vec3::new(0.0, 0.5, 0.0), 0.1, 100.0);
    b.add(
        "texture_metallic_roughness_occlusion_emission",
        "glTF metallic-roughness, occlusion and emissive textures and emission, rasterized, ray traced and reflected",
        s,
        cam,
        w,
        h,
    );

    // Normal maps: a rasterized floor of bumps whose tangents are generated (MikkTSpace),
    // a ray-traced ball with given tangents of both signs, a mirrored copy of it (negative
    // scale: the sign flips), and a mirror ball, also normal-mapped, that reflects the
    // floor (bounce hits normal-mapped too).
    let mut s =
        Scene { lights: vec![point(Vec3::new(-1.5, 4.0, 3.0), 40.0)], shading: ShadingModel::Gltf, ..Scene::default() };
    let bumps = image("bumps", 16, 16, |x, y| {
        let (dx, dy) = ((x % 4) as f32 - 1.5, (y % 4) as f32 - 1.5);
        let n = Vec3::new(dx * 0.25, dy * 0.25, 1.0).normalize();
        let code = |c: f32| ((c * 0.5 + 0.5) * 255.0).round() as u8;
        [code(n.x), code(n.y), code(n.z), 255]
    });
    let bumps_map = bind(&mut s, bumps, Sampler::default(), UvTransform::default());
    let bumpy = |name: &str, base: Material, scale: f32| Material {
        name: name.into(),
        maps: MaterialMaps { normal: Some(bumps_map), normal_scale: scale, ..MaterialMaps::default() },
        ..base
    };
    s.add_object(
        uv_grid("bumpy_floor", 4, 3.0),
        bumpy("bumpy_floor", diffuse("bumpy_floor", Vec3::splat(0.7)), 1.0),
        Mat4::from_scale(Vec3::splat(8.0)),
        RASTER,
    );
    let mut ball = uv_sphere("bumpy_ball", 24, 12);
    // Given tangents: around the sphere (along u), the sign alternating by hemisphere.
    ball.attributes.tangents = Some(
        ball.positions
            .iter()
            .map(|p| {
                let t = Vec3::new(-p.z, 0.0, p.x).normalize_or(Vec3::X);
                [t.x, t.y, t.z, if p.y >= 0.0 { 1.0 } else { -1.0 }]
            })
            .collect(),
    );
    let ball_material = bumpy("bumpy_ball", diffuse("bumpy_ball", Vec3::new(0.8, 0.4, 0.3)), 0.7);
    s.add_object(
        ball.clone(),
        ball_material.clone(),
        Mat4::from_translation(Vec3::new(1.2, 0.7, 0.0)) * Mat4::from_scale(Vec3::splat(0.6)),
        RT,
    );
    s.add_object(
        ball,
        ball_material,
        Mat4::from_translation(Vec3::new(0.0, 0.7, 1.0)) * Mat4::from_scale(Vec3::new(-0.5, 0.5, 0.5)),
        RASTER,
    );
    s.add_object(
        uv_sphere("bumpy_mirror", 24, 12),
        bumpy("bumpy_mirror", gold(), 0.5),
        Mat4::from_translation(Vec3::new(-1.2, 0.8, 0.0)) * Mat4::from_scale(Vec3::splat(0.8)),
        RT,
    );
    let cam = camera(Vec3::new(0.0, 2.2, 4.5), Vec3::new(0.0, 0.5, 0.0), 0.1, 100.0);
    b.add(
        "texture_normal_maps",
        "normal maps with generated and given tangents of both signs, mirrored, rasterized, ray traced and reflected",
        s,
        cam,
        w,
        h,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corpus_names_are_unique_and_carry_their_family() {
        let c = corpus();
        let mut names: Vec<&str> = c.iter().map(|c| c.name.as_str()).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), c.len());
        for case in &c {
            assert!(
                [
                    "paper_",
                    "raster_",
                    "ray_",
                    "degenerate_",
                    "size_",
                    "bounce_",
                    "texture_",
                    "instance_",
                    "shading_",
                    "stochastic_"
                ]
                .iter()
                .any(|p| case.name.starts_with(p)),
                "{}",
                case.name
            );
            // Stochastic rays exactly in their family, denoised exactly in its cases so named.
            assert_eq!(case.stochastic(), case.name.starts_with("stochastic_"), "{}", case.name);
            assert_eq!(case.options().denoise, case.name.starts_with("stochastic_denoised_"), "{}", case.name);
        }
        let stochastic: Vec<&Case> = c.iter().filter(|c| c.stochastic()).collect();
        let lit_by = |kind: fn(&Light) -> bool| stochastic.iter().filter(|c| c.scene.lights.iter().any(kind)).count();
        let quads = lit_by(|l| matches!(l, Light::Quad { .. }));
        let spheres = lit_by(|l| matches!(l, Light::Sphere { .. }));
        let suns = lit_by(|l| matches!(l, Light::Sun { .. }));
        assert!(quads >= 2 && spheres >= 1 && suns >= 1, "area lights of every kind: {quads}, {spheres}, {suns}");
        let emitters = stochastic.iter().filter(|c| c.scene.emissive_lights);
        assert!(
            emitters.clone().count() >= 4 && emitters.clone().any(|c| c.max_depth > 0),
            "emissive meshes as lights"
        );
        for case in emitters {
            let g = hyrt_core::geometry::WorldGeometry::build(&case.scene);
            assert!(g.emitters.len() > 2, "{}: {} emitters", case.name, g.emitters.len());
        }
        assert!(stochastic.iter().any(|c| c.ao_samples > 0 && c.max_depth > 0 && c.name.contains("mirror")));
        assert!(stochastic.iter().any(|c| c.scene.shading == ShadingModel::Gltf));
        let denoised = stochastic.iter().filter(|c| c.denoise).count();
        assert_eq!(2 * denoised, stochastic.len(), "every stochastic case denoised and not");
        assert!(c.len() >= 30, "{} cases", c.len());
        let gltf = |family: &str| c.iter().filter(|c| c.name.starts_with(&format!("shading_gltf_{family}"))).count();
        let counts = (gltf("paper_default"), gltf("bounce_"), gltf("texture_"), gltf("instance_"));
        assert!(counts.0 >= 1 && counts.1 >= 3 && counts.2 == 3 && counts.3 >= 1, "glTF shading cases {counts:?}");
        assert!(c.iter().filter(|c| c.name.starts_with("shading_")).all(|c| c.scene.shading == ShadingModel::Gltf));
    }

    #[test]
    fn unprojected_vertices_land_on_their_window_position() {
        let cam = camera(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 0.1, 100.0);
        let p = unproject(&cam, 64, 48, 10.5, 20.5, 0.9);
        let rec = CameraRecord::new(&cam, 64, 48);
        let c = Mat4::from_cols_array(&rec.view_proj) * (p - Vec3::from(rec.eye)).extend(1.0);
        let (x, y) = ((c.x / c.w * 0.5 + 0.5) * 64.0, (0.5 - c.y / c.w * 0.5) * 48.0);
        // f32 rounding of the world position and of the projection: well under 1/256 px.
        const PROJECTION_ROUNDING_PX: f32 = 1e-4;
        assert!((x - 10.5).abs() < PROJECTION_ROUNDING_PX && (y - 20.5).abs() < PROJECTION_ROUNDING_PX, "({x}, {y})");
    }
}
