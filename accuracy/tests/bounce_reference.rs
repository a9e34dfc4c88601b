//! The f64 reference's bounce paths against scenes with known answers: a mirror
//! reflecting a wall and the sky by Schlick's Fresnel weight, a white glass ball that
//! vanishes in a constant environment, and the reference without bounces at depth 0.

mod common;

use std::f32::consts::FRAC_PI_2;
use std::sync::Arc;

use common::{default_scene, reference_of};
use glam::{DVec3, Mat4, Quat, Vec3};
use hyrt_accuracy::bounce_reference::{render_reference_bounces, REFERENCE_MAX_DEPTH};
use hyrt_core::kernels::bounce::{bounces, sky};
use hyrt_core::kernels::shading::{ambient, ENVIRONMENT_SPECULAR};
use hyrt_core::scene::{Camera, Environment, EnvironmentMap, Material, MaterialKind, Mesh, RenderMode, Scene};

/// Relative error of a reference pixel against a closed form evaluated in f64: the final
/// rounding of the pixel to f32 (2^-24) and of the f32 radiance it reflects, plus f64
/// reorderings (1e-15); 1e-6 leaves a factor of 8 over the two f32 roundings.
const PIXEL_REL_TOL: f64 = 1e-6;

/// The gold of the default scene: Schlick's F0 of the mirror.
const GOLD: Vec3 = Vec3::new(1.0, 0.76, 0.33);

fn mirror_material() -> Material {
    Material {
        name: "mirror".into(),
        base_color: GOLD,
        metallic: 1.0,
        roughness: 0.0,
        transmission: 0.0,
        kind: MaterialKind::Specular,
        ..Material::grey()
    }
}

fn diffuse(rgb: Vec3) -> Material {
    Material {
        name: "diffuse".into(),
        base_color: rgb,
        metallic: 0.0,
        roughness: 1.0,
        transmission: 0.0,
        kind: MaterialKind::Diffuse,
        ..Material::grey()
    }
}

/// A gold mirror floor (8 x 8 at y = 0, ray traced) seen from above and in front, with no
/// light; with `wall`, a rasterized wall of 200 x 200 at z = -4 facing the camera, which
/// every reflection off the floor hits (the camera is at z = 6, in front of the whole
/// floor, so every reflected ray travels towards -z and upwards).
fn mirror_scene(wall: Option<Vec3>) -> Scene {
    let mut scene = Scene::default();
    scene.add_object(
        Mesh::grid("mirror", 4),
        mirror_material(),
        Mat4::from_scale(Vec3::splat(8.0)),
        RenderMode::RayTraced,
    );
    if let Some(rgb) = wall {
        let t = Mat4::from_translation(Vec3::new(0.0, 0.0, -4.0))
            * Mat4::from_quat(Quat::from_rotation_x(FRAC_PI_2))
            * Mat4::from_scale(Vec3::splat(200.0));
        scene.add_object(Mesh::grid("wall", 2), diffuse(rgb), t, RenderMode::Raster);
    }
    scene.camera = Some(Camera {
        eye: Vec3::new(0.3, 3.0, 6.0),
        target: Vec3::new(0.0, 0.0, 0.0),
        up: Vec3::Y,
        fov_y_deg: 50.0,
        near: 0.1,
        far: 500.0,
    });
    scene
}

/// Schlick's `F0 + (1 - F0) (1 - cos)^5`, written out here in f64.
fn schlick(f0: Vec3, cos: f64) -> DVec3 {
    let f0 = f0.as_dvec3();
    f0 + (DVec3::ONE - f0) * (1.0 - cos).powi(5)
}

fn assert_close(got: [f32; 4], want: DVec3, what: &str) {
    let got = Vec3::from_slice(&got[..3]).as_dvec3();
    let err = (got - want).abs().max_element();
    assert!(err <= PIXEL_REL_TOL * want.max_element(), "{what}: got {got}, want {want}");
}

#[test]
fn a_mirror_floor_reflects_a_wall_times_schlicks_fresnel_weight() {
    let wall = Vec3::new(0.2, 0.5, 0.9);
    let scene = mirror_scene(Some(wall));
    let (g, bvh, r) = reference_of(&scene, 64, 48);
    let b = render_reference_bounces(&g, &bvh, &scene.camera.unwrap(), &r, REFERENCE_MAX_DEPTH);
    // No light: the wall sends its ambient term (the raster shader's, as a raster pass
    // shades it), the gold mirror (metallic, so no diffuse ambient) nothing of its own.
    // (The paper's model: the constant terms, which read no normal or view direction.)
    let constant = |o: usize| ambient(&g.objects[o], Vec3::Y, Vec3::Y, &g.ambient);
    let wall_radiance = constant(1).as_dvec3();
    assert_eq!(constant(0), GOLD * ENVIRONMENT_SPECULAR, "the mirror's own ambient is F0 x environment");
    let eye = scene.camera.unwrap().eye.as_dvec3();
    let mut mirror_pixels = 0;
    for (i, h) in r.hits.iter().enumerate() {
        let h = h.expect("the floor and the wall fill the view");
        if h.object == 1 {
            assert_close(b.image[i], wall_radiance, &format!("wall pixel {i}"));
            continue;
        }
        mirror_pixels += 1;
        let d = (h.position - eye).normalize();
        assert_close(b.image[i], schlick(GOLD, -d.y) * wall_radiance, &format!("mirror pixel {i} at {}", h.position));
    }
    assert!(mirror_pixels > 1000, "{mirror_pixels}");
    // One ray per mirror pixel, each ending on the (rasterized, non-bouncing) wall.
    assert_eq!((b.paths.rays, b.paths.deepest, b.paths.truncated), (mirror_pixels, 1, 0));
}

#[test]
fn a_mirror_floor_alone_reflects_the_sky_times_schlicks_fresnel_weight() {
    let scene = mirror_scene(None);
    let (g, bvh, r) = reference_of(&scene, 48, 36);
    let b = render_reference_bounces(&g, &bvh, &scene.camera.unwrap(), &r, REFERENCE_MAX_DEPTH);
    let eye = scene.camera.unwrap().eye.as_dvec3();
    let mut mirror_pixels = 0;
    for (i, h) in r.hits.iter().enumerate() {
        let Some(h) = h else {
            // Primary misses keep the frame's background, as without bounces.
            assert_eq!(b.image[i], r.image[i]);
            continue;
        };
        mirror_pixels += 1;
        let d = (h.position - eye).normalize();
        let reflected = DVec3::new(d.x, -d.y, d.z);
        let want = schlick(GOLD, -d.y) * sky(reflected.as_vec3()).as_dvec3();
        assert_close(b.image[i], want, &format!("mirror pixel {i}"));
    }
    assert!(mirror_pixels > 500, "{mirror_pixels}");
}

/// A glass ball (white, fully transmissive: no absorption, no diffuse term) in a
/// constant environment of the radiance every untraced lobe sees, with no light.
fn furnace_scene() -> Scene {
    let mut scene = Scene::default();
    let glass = Material {
        name: "glass".into(),
        base_color: Vec3::ONE,
        metallic: 0.0,
        roughness: 0.0,
        transmission: 1.0,
        kind: MaterialKind::Glass { ior: 1.5 },
        ..Material::grey()
    };
    scene.add_object(Mesh::uv_sphere("ball", 32, 16), glass, Mat4::IDENTITY, RenderMode::RayTraced);
    let texels = vec![[ENVIRONMENT_SPECULAR, ENVIRONMENT_SPECULAR, ENVIRONMENT_SPECULAR, 1.0]; 2];
    scene.environment = Environment::Map(Arc::new(EnvironmentMap::new(2, 1, texels).unwrap()));
    scene.camera = Some(Camera {
        eye: Vec3::new(0.4, 0.9, 3.5),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 40.0,
        near: 0.1,
        far: 50.0,
    });
    scene
}

/// The white furnace: Fresnel reflection and refraction weights sum to one at every
/// interface (total internal reflection included), so every path of the glass ball ends in
/// the same radiance and the ball vanishes into the environment, however deep the paths.
#[test]
fn a_white_glass_ball_in_a_constant_environment_vanishes() {
    let scene = furnace_scene();
    let (g, bvh, r) = reference_of(&scene, 64, 64);
    for depth in [1, 3, REFERENCE_MAX_DEPTH] {
        let b = render_reference_bounces(&g, &bvh, &scene.camera.unwrap(), &r, depth);
        let (mut ball, mut off) = (0, 0);
        for (i, h) in r.hits.iter().enumerate() {
            if h.is_none() {
                continue;
            }
            ball += 1;
            let got = Vec3::from_slice(&b.image[i][..3]);
            // Silhouette pixels can lose a lobe whose direction leaves on the wrong side of
            // the geometric normal (`lobes`' fallbacks): counted, not failed.
            if (got - Vec3::splat(ENVIRONMENT_SPECULAR)).abs().max_element()
                > ENVIRONMENT_SPECULAR * PIXEL_REL_TOL as f32
            {
                off += 1;
            }
        }
        assert!(ball > 800, "{ball}");
        assert!(off * 100 <= ball, "depth {depth}: {off} of {ball} ball pixels are not the environment");
        assert!(b.paths.deepest == depth && b.paths.rays > ball, "{:?}", b.paths);
    }
}

#[test]
fn the_reference_at_max_depth_zero_is_the_reference_without_bounces_bit_for_bit() {
    let scene = default_scene();
    let (g, bvh, r) = reference_of(&scene, 64, 36);
    let camera = scene.camera.unwrap();
    let flat = render_reference_bounces(&g, &bvh, &camera, &r, 0);
    assert_eq!(flat.image, r.image);
    assert_eq!(flat.paths.rays, 0);
    // With bounces only the pixels of mirrors and glass change.
    let deep = render_reference_bounces(&g, &bvh, &camera, &r, REFERENCE_MAX_DEPTH);
    let mut changed = 0;
    for (i, h) in r.hits.iter().enumerate() {
        let bouncing = h.is_some_and(|h| bounces(&g.objects[h.object as usize]));
        if bouncing {
            changed += (deep.image[i] != r.image[i]) as u32;
        } else {
            assert_eq!(deep.image[i], r.image[i], "pixel {i} does not bounce");
        }
    }
    assert!(changed > 100, "{changed}");
    assert!(deep.paths.deepest >= 4, "the glass ball needs paths in and out: {:?}", deep.paths);
}
