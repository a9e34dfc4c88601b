//! Texture filtering, speed against error.
//!
//! A procedural scene whose texture aliases wherever it is minified: a floor tiled with a
//! one-texel checker (the highest frequency a texture holds), seen from near the ground so
//! that it recedes to grazing angles, and an alpha-masked fence standing on it (a checker
//! of holes) that casts its shadow on the floor. It is rendered on the CPU backend with
//! each of the floor's samplers (the fence keeps its own), and scored against a
//! supersampled reference: the same frame at [`SUPERSAMPLE`]² times the pixels, floor
//! sampled bilinearly at level 0, box-filtered down to the frame's size. That is the
//! pixel's average of the texture over its footprint, which mip maps approximate and
//! level-0 sampling aliases away from.
//!
//! A last pair of rows gives what the alpha test costs: the same frame with the fence
//! masked and with the fence opaque (its alpha mode `OPAQUE`: no holes, the scalar
//! traversal and raster paths not taken). Their errors are not comparable (another
//! scene) and are not reported.

use std::fmt::Write as _;
use std::sync::Arc;
use std::time::Instant;

use glam::{Mat4, Vec3};
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, Frame, FrameOptions, PreparedScene};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::scene::{
    AlphaMode, Camera, Filter, Light, Material, Mesh, RenderMode, Sampler, Scene, TextureBinding, TextureImage,
    UvTransform, Wrap,
};
use hyrt_cpu::backend::CpuBackend;

use crate::metrics;

/// The reference's supersampling per axis: 4 x 4 samples per pixel.
pub const SUPERSAMPLE: u32 = 4;

/// Texels per side of the floor's checker (one-texel squares).
const FLOOR_TEXELS: u32 = 64;

/// Times the floor's texture repeats across it.
const FLOOR_REPEATS: f32 = 16.0;

/// One configuration's figures.
#[derive(Clone, Debug)]
pub struct TextureRow {
    pub configuration: String,
    /// Median frame time (ms), every stage.
    pub frame_ms: f64,
    /// Against the supersampled reference (`None` for the alpha-cost rows).
    pub rmse: Option<f64>,
    pub flip: Option<f64>,
    pub wrong_pixels: Option<u64>,
}

/// [`Mesh::uv_quad`] with its texture coordinates scaled by `uv_scale`.
fn quad(name: &str, uv_scale: f32) -> Mesh {
    let mut mesh = Mesh::uv_quad(name);
    for uv in mesh.attributes.tex_coords[0].iter_mut().flatten() {
        *uv *= uv_scale;
    }
    mesh
}

/// The scene with the floor's sampler `floor` and the fence masked or opaque.
pub fn texture_scene(floor: Sampler, masked: bool) -> Scene {
    let mut scene = Scene::default();
    let n = FLOOR_TEXELS;
    let checker: Vec<[u8; 4]> = (0..n * n)
        .map(|k| if (k % n + k / n).is_multiple_of(2) { [235, 225, 200, 255] } else { [40, 60, 90, 255] })
        .collect();
    scene.textures.push(Arc::new(TextureImage::new("floor checker".into(), n, n, checker).expect("sized")));
    let holes: Vec<[u8; 4]> =
        (0..64).map(|k| if (k % 8 + k / 8) % 2 == 0 { [200, 80, 40, 255] } else { [200, 80, 40, 0] }).collect();
    scene.textures.push(Arc::new(TextureImage::new("fence holes".into(), 8, 8, holes).expect("sized")));
    let binding = |image, sampler| TextureBinding { image, sampler, tex_coord: 0, transform: UvTransform::default() };
    let floor_material = Material {
        name: "floor".into(),
        base_color: Vec3::ONE,
        base_color_texture: Some(binding(0, floor)),
        ..Material::grey()
    };
    // The floor: 40 x 40 units in the plane y = 0, texture repeated FLOOR_REPEATS times.
    let floor_at = Mat4::from_scale(Vec3::splat(20.0)) * Mat4::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    scene.add_object(quad("floor", FLOOR_REPEATS), floor_material, floor_at, RenderMode::Raster);
    let nearest = Sampler { mag: Filter::Nearest, min: Filter::Nearest, mip: None, ..Sampler::default() };
    let fence = Material {
        name: "fence".into(),
        base_color: Vec3::ONE,
        base_color_texture: Some(binding(1, Sampler { wrap_s: Wrap::Repeat, ..nearest })),
        alpha_mode: if masked { AlphaMode::Mask { cutoff: 0.5 } } else { AlphaMode::Opaque },
        ..Material::grey()
    };
    let fence_at = Mat4::from_translation(Vec3::new(0.0, 1.0, 2.0)) * Mat4::from_scale(Vec3::new(2.0, 1.0, 1.0));
    scene.add_object(quad("fence", 2.0), fence, fence_at, RenderMode::Raster);
    scene.lights.push(Light::Directional { direction: Vec3::new(0.3, -1.0, -0.6), color: Vec3::ONE, intensity: 2.0 });
    scene.camera = Some(Camera::look_at(Vec3::new(0.0, 1.2, 9.0), Vec3::new(0.0, 0.2, -10.0), Vec3::Y));
    scene
}

/// The samplers compared, by name: level 0 nearest and bilinear (no mip maps), the nearest
/// mip level and trilinear (the glTF default, what hyrt uses when a file leaves filters
/// out), each with the ray-cone level of detail.
pub fn samplers() -> Vec<(&'static str, Sampler)> {
    let s = Sampler::default();
    vec![
        ("nearest, level 0", Sampler { mag: Filter::Nearest, min: Filter::Nearest, mip: None, ..s }),
        ("bilinear, level 0", Sampler { mip: None, ..s }),
        ("bilinear, nearest mip (ray cones)", Sampler { mip: Some(Filter::Nearest), ..s }),
        ("trilinear (ray cones)", s),
    ]
}

fn prepare(cpu: &CpuBackend, scene: &Scene) -> PreparedScene {
    cpu.prepare(WorldGeometry::build(scene), BvhPreset::default())
}

/// The frame's final image and the median of `runs` frame times (ms; NaN for none), after one untimed
/// warm-up frame, every frame into the same reused [`Frame`] (as `hyrt bench` times frames:
/// the first frame of a scene allocates its buffers and builds nothing else worth timing).
fn frames(cpu: &mut CpuBackend, scene: &Scene, width: u32, height: u32, runs: usize) -> (Vec<[f32; 4]>, f64) {
    let prepared = prepare(cpu, scene);
    let camera = CameraRecord::new(&scene.camera.expect("the scene has a camera"), width, height);
    let options = FrameOptions::default();
    let mut frame = Frame::default();
    cpu.render_into(&prepared, &camera, &options, &mut frame).expect("a frame of the texture scene");
    let mut times = Vec::with_capacity(runs);
    for _ in 0..runs {
        let t = Instant::now();
        cpu.render_into(&prepared, &camera, &options, &mut frame).expect("a frame of the texture scene");
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    (frame.final_image, times.get(times.len() / 2).copied().unwrap_or(f64::NAN))
}

/// Box-filter a `width * s` x `height * s` image down by `s` per axis.
pub fn downsample(image: &[[f32; 4]], width: u32, height: u32, s: u32) -> Vec<[f32; 4]> {
    let big_w = (width * s) as usize;
    let scale = 1.0 / (s * s) as f64;
    (0..width as usize * height as usize)
        .map(|p| {
            let (x, y) = (p % width as usize, p / width as usize);
            let mut sum = [0.0f64; 4];
            for dy in 0..s as usize {
                for dx in 0..s as usize {
                    let t = image[(y * s as usize + dy) * big_w + x * s as usize + dx];
                    for c in 0..4 {
                        sum[c] += t[c] as f64;
                    }
                }
            }
            sum.map(|v| (v * scale) as f32)
        })
        .collect()
}

/// Every configuration's row on a `width` x `height` frame with `threads` workers,
/// `runs` frames each (the median time), and the Markdown table.
pub fn texture_speed_vs_error(width: u32, height: u32, threads: usize, runs: usize) -> (Vec<TextureRow>, String) {
    let mut cpu = CpuBackend::new(Some(threads.max(1)));
    let level0 = Sampler { mip: None, ..Sampler::default() };
    // The reference is not timed: its warm-up frame alone.
    let (big, _) = frames(&mut cpu, &texture_scene(level0, true), width * SUPERSAMPLE, height * SUPERSAMPLE, 0);
    let reference = downsample(&big, width, height, SUPERSAMPLE);
    let mut rows = Vec::new();
    for (name, sampler) in samplers() {
        let (image, ms) = frames(&mut cpu, &texture_scene(sampler, true), width, height, runs);
        rows.push(TextureRow {
            configuration: name.to_string(),
            frame_ms: ms,
            rmse: Some(metrics::rmse(&reference, &image)),
            flip: Some(metrics::flip_mean(&reference, &image, width, height)),
            wrong_pixels: Some(metrics::wrong_pixels(&reference, &image)),
        });
    }
    for (name, masked) in [("trilinear, fence alpha-tested", true), ("trilinear, fence opaque (no alpha test)", false)]
    {
        let (_, ms) = frames(&mut cpu, &texture_scene(Sampler::default(), masked), width, height, runs);
        rows.push(TextureRow { configuration: name.into(), frame_ms: ms, rmse: None, flip: None, wrong_pixels: None });
    }
    let mut md = format!(
        "Texture filtering on a procedural scene ({width}x{height}, CPU backend, {threads} threads, median of {runs} \
         frames): a floor tiled with a one-texel checker ({FLOOR_TEXELS}x{FLOOR_TEXELS} texels, repeated \
         {FLOOR_REPEATS} times) receding to grazing angles, and an alpha-masked fence casting its shadow on it. \
         Errors against a {SUPERSAMPLE}x{SUPERSAMPLE} supersampled frame (floor bilinear at level 0, \
         box-filtered). The last two rows give the cost of the alpha test (the fence masked or opaque).\n\n\
         | configuration | frame ms | RMSE | mean FLIP | wrong pixels |\n| --- | ---: | ---: | ---: | ---: |\n"
    );
    let opt = |v: Option<String>| v.unwrap_or_else(|| "-".into());
    for r in &rows {
        let _ = writeln!(
            md,
            "| {} | {:.2} | {} | {} | {} |",
            r.configuration,
            r.frame_ms,
            opt(r.rmse.map(|v| format!("{v:.4}"))),
            opt(r.flip.map(|v| format!("{v:.4}"))),
            opt(r.wrong_pixels.map(|v| v.to_string()))
        );
    }
    (rows, md)
}
