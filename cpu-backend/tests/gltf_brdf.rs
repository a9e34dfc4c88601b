//! `rt_shading` and `raster_shading` with the glTF BRDF (a scene shaded with
//! [`ShadingModel::Gltf`]) against the specification: spheres of different metallic,
//! roughness and base colours, half of them rasterized and half ray traced, lit by one
//! directional light, no bounces, `ambient = 0` and a black environment (issue 37's
//! check). Every pixel of the final image is glTF 2.0 Appendix B evaluated in f64
//! ([`gltf_brdf_f64`]) at the pixel's dumped position and normal, seen from the eye, to
//! within 0.1%, rasterized and ray-traced objects alike, and nothing else. The same
//! spheres with their metallic, roughness, occlusion and emission taken from textures
//! match the same formulas with the texels' values, decoded in f64.

use glam::{Mat4, Vec3};
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::{CameraRecord, ObjectRecord, SHADOW_LIT, SHADOW_NO_RAY};
use hyrt_core::frame::{Backend, Frame, FrameOptions};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::shading::{ambient, gltf_brdf_f64, AmbientLight, AMBIENT};
use hyrt_core::scene::{
    Ambient, Camera, Environment, EnvironmentMap, Light, Material, MaterialKind, MaterialMaps, Mesh, RenderMode,
    Sampler, Scene, ShadingModel, TextureBinding, TextureImage, UvTransform,
};
use hyrt_cpu::backend::CpuBackend;

/// Relative tolerance of a channel: issue 37's 0.1%. The renderer's own error is far
/// below it (the kernel is within 1e-4 of the f64 formula for roughness >= 0.1, see core's
/// property test); the margin covers the dumped normal and position being the f32 values
/// the shader read.
const REL_TOL: f64 = 1e-3;
/// Absolute floor for channels near the terminator, where `n.l` tends to 0 and its f32
/// rounding (about 1e-7 absolute) is a large part of a small value: 1e-7 times the light's
/// irradiance (3) and the largest BRDF value of these materials (below 10), with room.
const ABS_TOL: f64 = 1e-5;

/// (base colour, metallic, roughness, render mode) of each sphere.
const SPHERES: [([f32; 3], f32, f32, RenderMode); 6] = [
    ([0.9, 0.2, 0.1], 0.0, 0.15, RenderMode::Raster),
    ([0.9, 0.2, 0.1], 0.0, 0.15, RenderMode::RayTraced),
    ([1.0, 0.77, 0.34], 1.0, 0.35, RenderMode::Raster),
    ([1.0, 0.77, 0.34], 1.0, 0.35, RenderMode::RayTraced),
    ([0.2, 0.5, 0.9], 0.5, 0.8, RenderMode::Raster),
    ([0.2, 0.5, 0.9], 0.5, 0.8, RenderMode::RayTraced),
];

fn scene() -> (Scene, Vec3, Vec3) {
    let mut scene = Scene { shading: ShadingModel::Gltf, ..Scene::default() };
    for (i, &(base, metallic, roughness, mode)) in SPHERES.iter().enumerate() {
        let material = Material {
            name: format!("sphere {i}"),
            base_color: Vec3::from(base),
            metallic,
            roughness,
            // Diffuse kind: no reflection lobe traced or stood in for, so the pixel is the
            // ambient term and direct light alone.
            kind: MaterialKind::Diffuse,
            ..Material::grey()
        };
        let at = Vec3::new(i as f32 * 2.5 - 6.25, 0.0, 0.0);
        scene.add_object(Mesh::uv_sphere("sphere", 64, 32), material, Mat4::from_translation(at), mode);
    }
    let direction = Vec3::new(-0.3, -0.8, -0.5).normalize();
    let (color, intensity) = (Vec3::new(1.0, 0.95, 0.9), 3.0);
    scene.lights = vec![Light::Directional { direction, color, intensity }];
    scene.camera = Some(Camera::look_at(Vec3::new(0.0, 2.0, 9.0), Vec3::ZERO, Vec3::Y));
    (scene, direction, color * intensity)
}

/// `scene` rendered on the CPU at 320 x 120, one thread, no bounces, with the stages'
/// outputs kept: the frame, its camera, the object records and the ambient light.
fn render(scene: &Scene) -> (Frame, CameraRecord, Vec<ObjectRecord>, AmbientLight) {
    let mut cpu = CpuBackend::new(Some(1));
    let prepared = cpu.prepare(WorldGeometry::build(scene), BvhPreset::default());
    let camera = CameraRecord::new(&scene.camera.expect("camera"), 320, 120);
    let options = FrameOptions { max_depth: 0, ..FrameOptions::with_stage_outputs() };
    let frame = cpu.render(&prepared, &camera, &options).expect("frame");
    (frame, camera, prepared.geometry.objects.clone(), prepared.geometry.ambient.clone())
}

#[test]
fn gltf_brdf_frames_match_appendix_b_at_the_dumped_surfaces() {
    let (mut scene, direction, irradiance) = scene();
    scene.ambient = Ambient(0.0);
    scene.environment = black_environment();
    let (frame, camera, objects, ambient_light) = render(&scene);
    let (eye, l) = (Vec3::from(camera.eye).as_dvec3(), (-direction).as_dvec3());
    let (mut checked, mut by_mode) = (0usize, [0usize; 2]);
    let mut worst = 0.0f64;
    for (i, s) in frame.surfaces.iter().enumerate() {
        if !s.is_hit() {
            continue;
        }
        let code = frame.shadow[i];
        assert!(code == SHADOW_LIT || code == SHADOW_NO_RAY, "pixel {i}: spheres apart cast no shadow");
        let obj = &objects[s.object as usize];
        let (base, metallic, roughness, mode) = SPHERES[s.object as usize];
        let (p, n) = (Vec3::from(s.position).as_dvec3(), Vec3::from(s.normal).as_dvec3());
        let lit = code == SHADOW_LIT;
        let (v, nl) = ((eye - p).normalize(), n.normalize().dot(l));
        let f = gltf_brdf_f64(
            base.map(f64::from),
            metallic as f64,
            roughness as f64,
            n.to_array(),
            v.to_array(),
            l.to_array(),
        );
        let (n32, v32) = (Vec3::from(s.normal), v.as_vec3());
        assert_eq!(
            ambient(obj, n32, v32, &ambient_light),
            Vec3::ZERO,
            "ambient = 0 and a black environment remove every ambient term"
        );
        let got = frame.final_image[i];
        for c in 0..3 {
            let direct = if lit && nl > 0.0 { f[c] * irradiance.as_dvec3()[c] * nl } else { 0.0 };
            let want = direct;
            let err = (got[c] as f64 - want).abs();
            assert!(
                err <= REL_TOL * want + ABS_TOL,
                "pixel {i} ({mode:?}, metallic {metallic}, roughness {roughness}) channel {c}: {} against {want}",
                got[c]
            );
            if want > 1e-2 {
                worst = worst.max(err / want);
            }
        }
        checked += 1;
        by_mode[(mode == RenderMode::RayTraced) as usize] += lit as usize;
    }
    // Both paths shaded lit pixels, and enough of them to mean something.
    assert!(checked > 5000 && by_mode.iter().all(|&k| k > 1000), "{checked} pixels, lit {by_mode:?}");
    eprintln!("{checked} pixels, lit {by_mode:?}, worst relative error {worst:.2e}");
}

/// One texture texel per sphere: the metallic-roughness texel's (green, blue), the
/// occlusion texel's red with the strength, and the emissive texel (sRGB) with the factor.
struct Textured {
    green: u8,
    blue: u8,
    red: u8,
    strength: f32,
    emissive_texel: [u8; 3],
    emissive_factor: [f32; 3],
}

const TEXTURED: [Textured; 3] = [
    Textured { green: 40, blue: 0, red: 255, strength: 1.0, emissive_texel: [0; 3], emissive_factor: [0.0; 3] },
    Textured {
        green: 90,
        blue: 255,
        red: 100,
        strength: 0.7,
        emissive_texel: [255, 128, 30],
        emissive_factor: [0.5; 3],
    },
    Textured {
        green: 200,
        blue: 128,
        red: 0,
        strength: 1.0,
        emissive_texel: [60, 200, 250],
        emissive_factor: [1.0, 2.0, 0.5],
    },
];

/// An environment that sends no light.
fn black_environment() -> Environment {
    uniform_environment(0.0)
}

/// An environment of radiance `l` in every direction.
fn uniform_environment(l: f32) -> Environment {
    let map = EnvironmentMap::new(4, 2, vec![[l, l, l, 1.0]; 8]).expect("a uniform map");
    Environment::Map(std::sync::Arc::new(map))
}

/// The sRGB decoding of an 8-bit code in f64 (IEC 61966-2-1).
fn srgb(code: u8) -> f64 {
    let c = code as f64 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[test]
fn textured_metallic_roughness_occlusion_and_emission_match_the_formulas() {
    let (mut scene, direction, irradiance) = scene();
    // A black environment: the ambient light is the constant diffuse term alone, which
    // reads the textured metallic and occlusion.
    scene.environment = black_environment();
    let one = |scene: &mut Scene, name: &str, texel: [u8; 4]| {
        scene.textures.push(std::sync::Arc::new(TextureImage::new(name.into(), 1, 1, vec![texel]).unwrap()));
        let sampler = Sampler { mip: None, ..Sampler::default() };
        TextureBinding { image: scene.textures.len() - 1, sampler, tex_coord: 0, transform: UvTransform::default() }
    };
    for (k, obj) in scene.objects.clone().iter().enumerate() {
        let t = &TEXTURED[k / 2];
        let mr = one(&mut scene, "mr", [0, t.green, t.blue, 255]);
        let occlusion = one(&mut scene, "occlusion", [t.red, 0, 0, 255]);
        let emissive =
            one(&mut scene, "emissive", [t.emissive_texel[0], t.emissive_texel[1], t.emissive_texel[2], 255]);
        let m = &mut scene.materials[obj.material];
        (m.metallic, m.roughness, m.emissive) = (1.0, 1.0, Vec3::from(t.emissive_factor));
        m.maps = MaterialMaps {
            metallic_roughness: Some(mr),
            occlusion: Some(occlusion),
            occlusion_strength: t.strength,
            emissive: Some(emissive),
            ..MaterialMaps::default()
        };
        let mesh = &mut scene.meshes[obj.mesh];
        mesh.attributes.tex_coords[0] = Some(vec![glam::Vec2::ZERO; mesh.positions.len()]);
    }
    let (frame, camera, ..) = render(&scene);
    let (eye, l) = (Vec3::from(camera.eye).as_dvec3(), (-direction).as_dvec3());
    let mut checked = [0usize; 2];
    for (i, s) in frame.surfaces.iter().enumerate() {
        if !s.is_hit() {
            continue;
        }
        let (base, _, _, mode) = SPHERES[s.object as usize];
        let t = &TEXTURED[s.object as usize / 2];
        let (metallic, roughness) = (t.blue as f64 / 255.0, t.green as f64 / 255.0);
        let occlusion = 1.0 + t.strength as f64 * (t.red as f64 / 255.0 - 1.0);
        let (p, n) = (Vec3::from(s.position).as_dvec3(), Vec3::from(s.normal).as_dvec3());
        let lit = frame.shadow[i] == SHADOW_LIT;
        let (v, nl) = ((eye - p).normalize(), n.normalize().dot(l));
        let f = gltf_brdf_f64(base.map(f64::from), metallic, roughness, n.to_array(), v.to_array(), l.to_array());
        let got = frame.final_image[i];
        for c in 0..3 {
            let b = base[c] as f64;
            let ambient = b * (1.0 - metallic) * AMBIENT as f64 * occlusion;
            let emission = t.emissive_factor[c] as f64 * srgb(t.emissive_texel[c]);
            let direct = if lit && nl > 0.0 { f[c] * irradiance.as_dvec3()[c] * nl } else { 0.0 };
            let want = ambient + emission + direct;
            assert!(
                (got[c] as f64 - want).abs() <= REL_TOL * want + ABS_TOL,
                "pixel {i} ({mode:?}, sphere {}) channel {c}: {} against {want}",
                s.object,
                got[c]
            );
        }
        checked[(mode == RenderMode::RayTraced) as usize] += 1;
    }
    assert!(checked.iter().all(|&k| k > 2000), "{checked:?} pixels per path");
}

/// The image-based light in a furnace: under an environment of uniform radiance `L`, no
/// lights and `ambient = 0`, a white dielectric reflects `L` whatever its roughness (its
/// diffuse lobe keeps what its specular lobe does not reflect, `1 - (0.04 A + B)`, and the
/// irradiance of a uniform environment is `pi L`), and a white metal reflects `L (A + B)`,
/// its GGX lobe's directional albedo: below `L`, and near it on a smooth lobe seen head on.
/// Rasterized and ray-traced spheres alike.
#[test]
fn image_based_light_in_a_uniform_environment_keeps_a_white_dielectric_at_its_radiance() {
    const L: f32 = 0.5;
    /// The irradiance coefficients (a sum over 8 texels in f64, rounded once), the split-sum
    /// cells' f32 rounding and a dozen f32 operations of values below 1.
    const FURNACE_TOL: f64 = 1e-5;
    let (mut scene, ..) = scene();
    scene.lights.clear();
    scene.ambient = Ambient(0.0);
    scene.environment = uniform_environment(L);
    scene.materials.iter_mut().for_each(|m| m.base_color = Vec3::ONE);
    let (frame, ..) = render(&scene);
    let (mut dielectric, mut metal) = ([0usize; 2], [0usize; 2]);
    let mut darkest_metal = f64::MAX;
    for (i, s) in frame.surfaces.iter().enumerate() {
        if !s.is_hit() {
            continue;
        }
        let (_, metallic, _, mode) = SPHERES[s.object as usize];
        let got = frame.final_image[i];
        let path = (mode == RenderMode::RayTraced) as usize;
        for (c, &g) in got[..3].iter().enumerate() {
            let g = g as f64;
            if metallic == 0.0 {
                assert!((g - L as f64).abs() <= FURNACE_TOL, "pixel {i} ({mode:?}) channel {c}: {g} against {L}");
            } else {
                assert!(
                    g <= L as f64 * (1.0 + FURNACE_TOL),
                    "pixel {i} ({mode:?}, metallic {metallic}): {g} above {L}"
                );
            }
        }
        if metallic == 0.0 {
            dielectric[path] += 1;
        } else if metallic == 1.0 {
            metal[path] += 1;
            darkest_metal = darkest_metal.min(got[0] as f64);
        }
    }
    assert!(dielectric.iter().chain(&metal).all(|&k| k > 500), "dielectric {dielectric:?}, metal {metal:?} pixels");
    // Roughness 0.35: the lobe's albedo stays above 0.8 even at the silhouette.
    assert!(darkest_metal > 0.8 * L as f64, "darkest metal pixel {darkest_metal}");
}
