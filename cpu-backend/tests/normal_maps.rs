//! Normal maps against the specification: quads in the XZ plane (normal +Y, texture
//! coordinates u along +x and v along +z) with a one-texel normal texture, seen from above.
//! Every hit pixel's dumped shading normal (`normal.npy`'s record, after normal mapping)
//! is glTF's `normalize(T x s + B y s + N z)` with `(x, y, z) = 2 texel - 1`, `s` the
//! normal texture's scale, `B = cross(N, T) w`, for given tangents of both signs, for
//! generated ones (MikkTSpace; glTF's convention, the bitangent up the image, which is -z
//! here) and for a scaled map, rasterized and ray traced alike.

use glam::{DVec3, Mat4, Vec2, Vec3};
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, FrameOptions};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::scene::{
    Camera, Light, Material, MaterialMaps, Mesh, RenderMode, Sampler, Scene, ShadingModel, TextureBinding,
    TextureImage, UvTransform,
};
use hyrt_cpu::backend::CpuBackend;

/// The normal texel: tangent-space (0.48, 0.36, 0.8) rounded to 8-bit codes.
const TEXEL: [u8; 4] = [189, 173, 230, 255];

/// Per quad: the tangent given as `TANGENT` (`None`: generated), the normal scale, and
/// the world tangent and bitangent the specification then implies.
struct Quad {
    tangent: Option<[f32; 4]>,
    scale: f32,
    t: DVec3,
    b: DVec3,
}

/// Error of a dumped normal: the f32 rounding of the interpolated tangent, its
/// orthogonalization and normalization, the cross product and the final normalization,
/// some twenty roundings of unit-sized values (2^-24 each), with room.
const NORMAL_TOL: f64 = 1e-5;

#[test]
fn mapped_normals_follow_the_tangent_frame_gltf_defines() {
    let quads = [
        Quad { tangent: Some([1.0, 0.0, 0.0, 1.0]), scale: 1.0, t: DVec3::X, b: DVec3::NEG_Z },
        Quad { tangent: Some([1.0, 0.0, 0.0, -1.0]), scale: 1.0, t: DVec3::X, b: DVec3::Z },
        Quad { tangent: None, scale: 1.0, t: DVec3::X, b: DVec3::NEG_Z },
        Quad { tangent: Some([0.0, 0.0, 1.0, 1.0]), scale: 0.5, t: DVec3::Z, b: DVec3::X },
    ];
    let mut scene = Scene { shading: ShadingModel::Gltf, ..Scene::default() };
    scene.textures.push(std::sync::Arc::new(TextureImage::new("n".into(), 1, 1, vec![TEXEL]).unwrap()));
    let sampler = Sampler { mip: None, ..Sampler::default() };
    let binding = TextureBinding { image: 0, sampler, tex_coord: 0, transform: UvTransform::default() };
    for (k, q) in quads.iter().enumerate() {
        let mut mesh = Mesh::grid("quad", 2);
        mesh.attributes.tex_coords[0] = Some(mesh.positions.iter().map(|p| Vec2::new(p.x + 0.5, p.z + 0.5)).collect());
        mesh.attributes.tangents = q.tangent.map(|t| vec![t; mesh.positions.len()]);
        let material = Material {
            maps: MaterialMaps { normal: Some(binding), normal_scale: q.scale, ..MaterialMaps::default() },
            ..Material::grey()
        };
        let mode = if k % 2 == 0 { RenderMode::Raster } else { RenderMode::RayTraced };
        scene.add_object(mesh, material, Mat4::from_translation(Vec3::new(k as f32 * 1.2 - 1.8, 0.0, 0.0)), mode);
    }
    scene.lights = vec![Light::Directional { direction: Vec3::NEG_Y, color: Vec3::ONE, intensity: 1.0 }];
    let camera = Camera::look_at(Vec3::new(0.0, 4.0, 0.001), Vec3::ZERO, Vec3::NEG_Z);
    let mut cpu = CpuBackend::new(Some(1));
    let prepared = cpu.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    let record = CameraRecord::new(&camera, 240, 80);
    let options = FrameOptions { max_depth: 0, ..FrameOptions::with_stage_outputs() };
    let frame = cpu.render(&prepared, &record, &options).expect("frame");
    let decode = |c: u8| 2.0 * (c as f64 / 255.0) - 1.0;
    let mut seen = [0usize; 4];
    for s in frame.surfaces.iter().filter(|s| s.is_hit()) {
        let q = &quads[s.object as usize];
        let (x, y, z) = (decode(TEXEL[0]) * q.scale as f64, decode(TEXEL[1]) * q.scale as f64, decode(TEXEL[2]));
        let want = (q.t * x + q.b * y + DVec3::Y * z).normalize();
        let got = Vec3::from(s.normal).as_dvec3();
        assert!((got - want).length() <= NORMAL_TOL, "quad {}: normal {got} against {want}", s.object);
        seen[s.object as usize] += 1;
    }
    assert!(seen.iter().all(|&n| n > 500), "pixels per quad: {seen:?}");
}
