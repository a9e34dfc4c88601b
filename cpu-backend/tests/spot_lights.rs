//! Spot lights and `range` (glTF's `KHR_lights_punctual`) end to end: a floor lit by one
//! spot light from above, its left half rasterized and its right half ray traced, with the
//! glTF BRDF, `ambient = 0` and a black environment, so that every pixel is direct light
//! alone. Each pixel of the final image must be the extension's formulas evaluated in f64
//! at the pixel's dumped position and normal: Appendix B's BRDF x colour x intensity x
//! the cone factor x the range window / d² x N.L. The cone and the window are written here
//! from the light's angles and range as the extension states them, not from the record
//! the renderer builds, so a mistake in either shows. Outside the cone the image is black
//! and no shadow ray is traced.

use glam::{DVec3, Mat4, Vec3};
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::{CameraRecord, SHADOW_LIT, SHADOW_NO_RAY};
use hyrt_core::frame::{Backend, FrameOptions};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::shading::{gltf_brdf_f64, punctual_falloff_f64};
use hyrt_core::scene::{
    Ambient, Camera, Environment, EnvironmentMap, Light, Material, MaterialKind, Mesh, RenderMode, Scene, ShadingModel,
};
use hyrt_cpu::backend::CpuBackend;

/// Relative tolerance of a channel: issue 37's 0.1%, as for the directional light
/// (`gltf_brdf.rs`).
const REL_TOL: f64 = 1e-3;
/// Absolute floor near the cone's outer edge, where the factor `a²` tends to 0: `a` moves
/// by the cone scale (here 1 / (cos 15° - cos 35°), about 6.8) times the rounding of the
/// f32 cosine (about 1e-7), so `a²` by about 1e-6 there, times the light's largest
/// `BRDF x I / d²` on this floor (below 4), with room.
const ABS_TOL: f64 = 2e-5;

const LIGHT_AT: Vec3 = Vec3::new(0.2, 4.0, -0.3);
const INTENSITY: f32 = 40.0;
const COLOR: Vec3 = Vec3::new(1.0, 0.9, 0.8);
const INNER_DEG: f32 = 15.0;
const OUTER_DEG: f32 = 35.0;
/// Shorter than the cone's slant to the floor (4 / cos 35° = 4.9), so the window acts
/// everywhere in the lit disc.
const RANGE: f32 = 5.5;
const BASE: [f32; 3] = [0.8, 0.8, 0.75];
const METALLIC: f32 = 0.2;
const ROUGHNESS: f32 = 0.6;

/// `KHR_lights_punctual`'s cone factor and range window in f64 (core's specification,
/// [`punctual_falloff_f64`]), from this light's angles and range.
fn punctual_falloff(d: f64, cos_axis: f64) -> f64 {
    let cone = (f64::from(INNER_DEG).to_radians(), f64::from(OUTER_DEG).to_radians());
    punctual_falloff_f64(d, cos_axis, Some(f64::from(RANGE)), Some(cone))
}

fn scene() -> Scene {
    let mut scene = Scene { shading: ShadingModel::Gltf, ambient: Ambient(0.0), ..Scene::default() };
    let black = EnvironmentMap::new(1, 1, vec![[0.0, 0.0, 0.0, 1.0]]).expect("a black map");
    scene.environment = Environment::Map(std::sync::Arc::new(black));
    let material = Material {
        name: "floor".into(),
        base_color: Vec3::from(BASE),
        metallic: METALLIC,
        roughness: ROUGHNESS,
        kind: MaterialKind::Diffuse,
        ..Material::grey()
    };
    // Two 5 x 10 halves of a floor at y = 0, meeting at x = 0.
    for (x, mode) in [(-2.5, RenderMode::Raster), (2.5, RenderMode::RayTraced)] {
        let place = Mat4::from_translation(Vec3::new(x, 0.0, 0.0)) * Mat4::from_scale(Vec3::new(5.0, 1.0, 10.0));
        scene.add_object(Mesh::grid("floor", 8), material.clone(), place, mode);
    }
    scene.lights = vec![Light::Spot {
        position: LIGHT_AT,
        direction: Vec3::new(0.1, -1.0, 0.05).normalize(),
        color: COLOR,
        intensity: INTENSITY,
        inner_cone_angle: INNER_DEG.to_radians(),
        outer_cone_angle: OUTER_DEG.to_radians(),
        range: Some(RANGE),
    }];
    scene.camera = Some(Camera::look_at(Vec3::new(0.0, 6.0, 6.0), Vec3::ZERO, Vec3::Y));
    scene
}

#[test]
fn spot_light_frames_match_the_extension_at_the_dumped_surfaces() {
    let scene = scene();
    let Light::Spot { direction: axis, .. } = scene.lights[0] else { unreachable!() };
    let mut cpu = CpuBackend::new(Some(1));
    let prepared = cpu.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    let camera = CameraRecord::new(&scene.camera.expect("camera"), 320, 240);
    let options = FrameOptions { max_depth: 0, ..FrameOptions::with_stage_outputs() };
    let frame = cpu.render(&prepared, &camera, &options).expect("frame");
    let eye = Vec3::from(camera.eye).as_dvec3();
    let (light, axis) = (LIGHT_AT.as_dvec3(), axis.as_dvec3());
    // Pixels fully inside the inner cone, on the ramp, and beyond the cone or the range,
    // for each render mode.
    let mut counts = [[0usize; 3]; 2];
    let mut worst = 0.0f64;
    for (i, s) in frame.surfaces.iter().enumerate() {
        if !s.is_hit() {
            continue;
        }
        let (p, n) = (Vec3::from(s.position).as_dvec3(), Vec3::from(s.normal).as_dvec3().normalize());
        let to_light = light - p;
        let (d, l) = (to_light.length(), to_light.normalize());
        let factor = punctual_falloff(d, -axis.dot(l));
        let nl = n.dot(l);
        let f = gltf_brdf_f64(
            BASE.map(f64::from),
            f64::from(METALLIC),
            f64::from(ROUGHNESS),
            n.to_array(),
            (eye - p).normalize().to_array(),
            l.to_array(),
        );
        let irradiance = (COLOR * INTENSITY).as_dvec3() * factor / (d * d) * nl.max(0.0);
        let want = DVec3::from(f) * irradiance;
        let got = Vec3::from_slice(&frame.final_image[i][..3]).as_dvec3();
        for c in 0..3 {
            let err = (got[c] - want[c]).abs();
            assert!(
                err <= REL_TOL * want[c] + ABS_TOL,
                "pixel {i} at {p:?}, channel {c}: {} against {}",
                got[c],
                want[c]
            );
            if want[c] > 1e-2 {
                worst = worst.max(err / want[c]);
            }
        }
        let mode = prepared.geometry.objects[s.object as usize].flags & hyrt_core::formats::OBJ_RAY_TRACED != 0;
        let band = match factor {
            x if x <= 0.0 => 2,
            _ if -axis.dot(l) >= f64::from(INNER_DEG).to_radians().cos() => 0,
            _ => 1,
        };
        counts[mode as usize][band] += 1;
        // Beyond the cone (or the range) nothing is traced and nothing is added.
        if factor == 0.0 {
            assert_eq!(frame.shadow[i], SHADOW_NO_RAY, "pixel {i} at {p:?}: a shadow ray outside the cone");
            assert_eq!(got, DVec3::ZERO, "pixel {i} at {p:?}");
        } else if nl > 1e-3 && factor > 1e-6 {
            assert_eq!(
                frame.shadow[i], SHADOW_LIT,
                "pixel {i} at {p:?}: nothing stands between the floor and the light"
            );
        }
    }
    // Both paths saw the inner cone, the ramp and the dark beyond, enough to mean something.
    assert!(counts.iter().flatten().all(|&k| k > 300), "pixels (inner, ramp, dark) per mode: {counts:?}");
    eprintln!("pixels (inner, ramp, dark), rasterized then ray traced: {counts:?}; worst relative error {worst:.2e}");
}
