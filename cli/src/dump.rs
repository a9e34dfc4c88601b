//! `--dump DIR`: every stage's output, in formats outside tools read
//! (NumPy `.npy`, PNG, JSON). File by file:
//!
//! | file | dtype, shape | content |
//! |---|---|---|
//! | `ids.npy` | u32, H x W x 2 | triangle index within its object, object id; `0xFFFFFFFF` on miss |
//! | `bary.npy` | f32, H x W x 2 | barycentrics (u, v) of v1, v2; w = 1 - u - v |
//! | `depth.npy` | f32, H x W | window depth in [0, 1]; 1 on miss |
//! | `position.npy` | f32, H x W x 3 | world-space hit point (0 on miss) |
//! | `normal.npy` | f32, H x W x 3 | viewer-facing unit shading normal, after normal mapping (0 on miss) |
//! | `material.npy` | f32, H x W x 4 | the material each pixel's surface is shaded with: metallic, roughness, ambient occlusion (1 without an occlusion texture), emissive luminance (Rec. 709 weights of the linear emission); 0 on miss |
//! | `rays.npy` | structured, N | the ray list: `origin` (3,)f4, `t_min` f4, `direction` (3,)f4, `t_max` f4, `pixel` u4, `kind` u4, `depth` u4, `light` u4, `throughput` (3,)f4, `occluded` u4 |
//! | `shadow.npy` | u8, H x W x S | per mask slot (one per point, spot or directional light, `--shadow-samples` per area light, in light order, then `--ao-samples` for ambient occlusion; `hyrt_core::kernels::soft_shadow`): 0 no ray (miss, light behind the surface, occlusion ray below it), 1 lit, 2 occluded |
//! | `visibility_raw.npy` | f32, H x W x L | per light, the fraction of it the pixel's surface sees: 1 or 0 for point, spot and directional lights; for area lights the visible share of the unoccluded irradiance of its samples (`soft_shadow::light_visibility`), before denoising; 0 on miss |
//! | `visibility.npy` | f32, H x W x L | as `visibility_raw.npy`, with the area lights' values after `shadow_denoise` (the same where the frame did not denoise: `--no-denoise`, or no area light) |
//! | `ao_raw.npy`, `ao.npy` | f32, H x W | with `--ao-samples`: the ambient occlusion, the fraction of occlusion rays that met nothing within the radius, before and after `shadow_denoise`; 1 on miss |
//! | `raster.png`, `rt.png`, `final.png` | sRGB RGBA8 | the three images (`rt.png` alpha = ray-traced coverage) |
//! | `bounce{d}_rays.npy` | structured, N_d | the reflection and refraction rays of bounce `d` (as `rays.npy`; `occluded` is `0xFFFFFFFF`) |
//! | `bounce{d}_links.npy` | u32, P x 2 | per parent (pixel for `d = 1`, else ray of `d - 1`): its reflection and refraction child in `bounce{d}_rays.npy`, `0xFFFFFFFF` for none |
//! | `bounce{d}_hits.npy` | structured, N_d | closest hit: `t`, `u`, `v` f4, `triangle` u4 (global index), `flags` u4 (1 hit, 2 back face) |
//! | `bounce{d}_position.npy`, `bounce{d}_normal.npy` | f32, N_d x 3 | the surface each ray hit (0 on miss) |
//! | `bounce{d}_shadow_rays.npy` | structured | shadow rays from those surfaces (as `rays.npy`; `pixel` = the secondary ray) |
//! | `bounce{d}_shadow.npy` | u8, N_d x L | as `shadow.npy`, per secondary ray |
//! | `bounce{d}_radiance.npy` | f32, N_d x 4 | the linear radiance each ray brings back |
//! | `frame.json` | | image size, camera (matrices and conventions), lights, environment, shading model (`paper`, `gltf`), ambient level, object table, counts, times, skipped stages |
//!
//! The files of a buffer whose stage the frame's plan skipped are not written
//! (`frame.json` lists the skipped stages and why).

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{BufferView, Frame, FrameLighting, FrameOptions, PreparedScene};
use hyrt_core::kernels::soft_shadow::{ambient_occlusion, light_visibility};
use hyrt_core::plan::{BounceBuffer, FrameBuffer};
use hyrt_core::scene::{Camera, Scene};
use npyz::WriterBuilder;
use serde_json::{json, Value};

use hyrt::image_io::write_png;
use hyrt::Error;

/// One row of `rays.npy` (a NumPy structured dtype).
#[derive(npyz::Serialize, npyz::AutoSerialize, Clone, Copy)]
struct RayRow {
    origin: [f32; 3],
    t_min: f32,
    direction: [f32; 3],
    t_max: f32,
    pixel: u32,
    kind: u32,
    depth: u32,
    light: u32,
    throughput: [f32; 3],
    occluded: u32,
}

fn write_npy<T: npyz::AutoSerialize + Copy>(
    path: &Path,
    shape: &[u64],
    data: impl IntoIterator<Item = T>,
) -> Result<(), Error> {
    let io = |source| Error::Write { path: path.to_path_buf(), source };
    let file = File::create(path).map_err(io)?;
    let mut w =
        npyz::WriteOptions::new().default_dtype().shape(shape).writer(BufWriter::new(file)).begin_nd().map_err(io)?;
    w.extend(data).map_err(io)?;
    w.finish().map_err(io)
}

/// `rays.npy` or a bounce's `bounce{d}_shadow_rays.npy`: the rays with their occlusion
/// results (`occluded` may be empty: secondary rays, whose results are their hits).
fn write_rays(path: &Path, rays: &[hyrt_core::formats::RayRecord], occluded: &[u32]) -> Result<(), Error> {
    let rows = rays.iter().enumerate().map(|(i, r)| RayRow {
        origin: r.origin,
        t_min: r.t_min,
        direction: r.direction,
        t_max: r.t_max,
        pixel: r.pixel,
        kind: r.kind,
        depth: r.depth,
        light: r.light,
        throughput: r.throughput,
        occluded: occluded.get(i).copied().unwrap_or(NOT_A_SHADOW_RAY),
    });
    write_npy(path, &[rays.len() as u64], rows)
}

/// The `occluded` column of reflection and refraction rays, which have no occlusion
/// result (their closest hits are `bounce{d}_hits.npy`).
const NOT_A_SHADOW_RAY: u32 = u32::MAX;

/// One row of `bounce{d}_hits.npy`.
#[derive(npyz::Serialize, npyz::AutoSerialize, Clone, Copy)]
struct HitRow {
    t: f32,
    u: f32,
    v: f32,
    triangle: u32,
    flags: u32,
}

/// The files of one bounce buffer, named `bounce{d}_<buffer>`, one row per ray of the
/// depth (per parent for `links`).
fn write_bounce_buffer(
    out: &mut impl FnMut(&str) -> PathBuf,
    frame: &Frame,
    buffer: FrameBuffer,
    lights: u64,
) -> Result<(), Error> {
    let FrameBuffer::Bounce { buffer: kind, depth } = buffer else { unreachable!("a bounce buffer") };
    let b = &frame.bounces[depth as usize - 1];
    let name = |file: &str| format!("bounce{depth}_{file}");
    match kind {
        BounceBuffer::Rays => write_rays(&out(&name("rays.npy")), &b.rays, &[]),
        BounceBuffer::Links => {
            write_npy(&out(&name("links.npy")), &[b.links.len() as u64, 2], b.links.iter().flatten().copied())
        }
        BounceBuffer::Hits => {
            let rows = b.hits.iter().map(|h| HitRow { t: h.t, u: h.u, v: h.v, triangle: h.triangle, flags: h.flags });
            write_npy(&out(&name("hits.npy")), &[b.hits.len() as u64], rows)
        }
        BounceBuffer::Surfaces => {
            let n = b.surfaces.len() as u64;
            write_npy(&out(&name("position.npy")), &[n, 3], b.surfaces.iter().flat_map(|s| s.position))?;
            write_npy(&out(&name("normal.npy")), &[n, 3], b.surfaces.iter().flat_map(|s| s.normal))
        }
        BounceBuffer::ShadowRays => write_rays(&out(&name("shadow_rays.npy")), &b.shadow_rays, &b.occluded),
        // The `occluded` column of bounce{d}_shadow_rays.npy.
        BounceBuffer::Occluded => Ok(()),
        BounceBuffer::Shadow => {
            let n = b.surfaces.len() as u64;
            write_npy(&out(&name("shadow.npy")), &[n, lights], b.shadow.iter().copied())
        }
        BounceBuffer::Radiance => {
            write_npy(&out(&name("radiance.npy")), &[b.radiance.len() as u64, 4], b.radiance.iter().flatten().copied())
        }
    }
}

/// Write every dump file of `frame` into `dir` (created if needed).
pub fn write_dump(
    dir: &Path,
    scene: &Scene,
    prepared: &PreparedScene,
    (camera, options): (&Camera, &FrameOptions),
    frame: &Frame,
    backend: &str,
) -> Result<Vec<PathBuf>, Error> {
    std::fs::create_dir_all(dir).map_err(|source| Error::Write { path: dir.to_path_buf(), source })?;
    let (w, h) = (frame.width as u64, frame.height as u64);
    let lighting = prepared.frame_lighting(options);
    let lights = lighting.slots() as u64;
    let mut written = Vec::new();
    let mut out = |name: &str| {
        let p = dir.join(name);
        written.push(p.clone());
        p
    };
    // One file set per buffer the frame holds: a stage the plan skipped writes none.
    for buffer in frame.buffers() {
        let depth = buffer.depth();
        if depth > 0 {
            write_bounce_buffer(&mut out, frame, buffer, lights)?;
            continue;
        }
        match frame.buffer(buffer).expect("held") {
            BufferView::GBuffer(g) => {
                write_npy(&out("ids.npy"), &[h, w, 2], g.iter().flat_map(|t| [t.triangle, t.object]))?;
                write_npy(&out("bary.npy"), &[h, w, 2], g.iter().flat_map(|t| [t.bary_u, t.bary_v]))?;
                write_npy(&out("depth.npy"), &[h, w], g.iter().map(|t| t.depth))?;
            }
            BufferView::Surfaces(s) => {
                write_npy(&out("position.npy"), &[h, w, 3], s.iter().flat_map(|s| s.position))?;
                write_npy(&out("normal.npy"), &[h, w, 3], s.iter().flat_map(|s| s.normal))?;
            }
            BufferView::Rays(rays) => write_rays(&out("rays.npy"), rays, &frame.occluded)?,
            // The occlusion results are the `occluded` column of rays.npy.
            BufferView::Words(_) => {}
            BufferView::Codes(codes) => write_npy(&out("shadow.npy"), &[h, w, lights], codes.iter().copied())?,
            // Written with the raw visibility, below.
            BufferView::Values(_) => {}
            BufferView::Image(img) => {
                write_png(&out(&format!("{}.png", buffer.name())), frame.width, frame.height, img)?
            }
            BufferView::Hits(_) | BufferView::Links(_) => unreachable!("bounce buffers are written above"),
        }
    }
    if frame.holds(FrameBuffer::Shadow) && frame.holds(FrameBuffer::Surfaces) {
        write_visibility(&mut out, frame, &lighting, (w, h))?;
    }
    if !frame.gbuffer.is_empty() && !frame.surfaces.is_empty() {
        let values = material_values(prepared, camera, frame);
        write_npy(&out("material.npy"), &[h, w, 4], values.into_iter().flatten())?;
    }
    let json_path = out("frame.json");
    let doc = frame_json(scene, prepared, camera, frame, backend);
    let text = serde_json::to_string_pretty(&doc).expect("frame.json serializes");
    std::fs::write(&json_path, text).map_err(|source| Error::Write { path: json_path.clone(), source })?;
    Ok(written)
}

/// `visibility_raw.npy` and `ao_raw.npy` from the shadow mask, and `visibility.npy` and
/// `ao.npy` as the shaders applied them: `shadow_denoise`'s channels where it ran, else the
/// raw values (the module docs' table).
fn write_visibility(
    out: &mut impl FnMut(&str) -> PathBuf,
    frame: &Frame,
    lighting: &FrameLighting,
    (w, h): (u64, u64),
) -> Result<(), Error> {
    let (ls, ao) = (&lighting.lights[..], &lighting.ambient.occlusion);
    let (nl, slots) = (ls.len(), lighting.slots());
    let pixels = frame.surfaces.len();
    let mut visibility = vec![0.0f32; pixels * nl];
    let mut occlusion = vec![1.0f32; pixels];
    for (i, s) in frame.surfaces.iter().enumerate().filter(|(_, s)| s.is_hit()) {
        let codes = &frame.shadow[i * slots..(i + 1) * slots];
        light_visibility(codes, lighting.lights(), s, &mut visibility[i * nl..(i + 1) * nl]);
        occlusion[i] = ambient_occlusion(codes, ls, ao).unwrap_or(1.0);
    }
    write_npy(&out("visibility_raw.npy"), &[h, w, nl as u64], visibility.iter().copied())?;
    if ao.samples > 0 {
        write_npy(&out("ao_raw.npy"), &[h, w], occlusion.iter().copied())?;
    }
    if frame.holds(FrameBuffer::Visibility) {
        let channels = frame.plan.visibility_channels() as usize;
        for i in (0..pixels).filter(|&i| frame.surfaces[i].is_hit()) {
            let filtered = &frame.visibility[i * channels..(i + 1) * channels];
            let area = ls.iter().enumerate().filter(|(_, l)| l.is_area()).map(|(l, _)| l);
            for (k, l) in area.enumerate() {
                visibility[i * nl + l] = filtered[k];
            }
            if ao.samples > 0 {
                occlusion[i] = filtered[channels - 1];
            }
        }
    }
    write_npy(&out("visibility.npy"), &[h, w, nl as u64], visibility)?;
    if ao.samples > 0 {
        write_npy(&out("ao.npy"), &[h, w], occlusion)?;
    }
    Ok(())
}

/// Per pixel, the material its primary hit is shaded with, as core's `primary_parent`
/// makes it (textures and all): metallic, roughness, the ambient occlusion
/// ([`hyrt_core::formats::ObjectRecord::occlusion`]) and the emission's luminance; zeros on
/// a miss.
fn material_values(prepared: &PreparedScene, camera: &Camera, frame: &Frame) -> Vec<[f32; 4]> {
    use hyrt_core::kernels::bounce::primary_parent;
    let rec = CameraRecord::new(camera, frame.width, frame.height);
    let geometry = &prepared.geometry;
    let materials = geometry.materials(&rec);
    let eye = hyrt_core::glam::Vec3::from(rec.eye);
    frame
        .gbuffer
        .iter()
        .zip(&frame.surfaces)
        .enumerate()
        .map(|(i, (t, s))| {
            if !s.is_hit() {
                return [0.0; 4];
            }
            let o = primary_parent(t, s, eye, i as u32, &materials).object;
            let e = o.emissive;
            [o.metallic, o.roughness, o.occlusion, 0.2126 * e[0] + 0.7152 * e[1] + 0.0722 * e[2]]
        })
        .collect()
}

/// The `frame.json` document.
pub fn frame_json(scene: &Scene, prepared: &PreparedScene, camera: &Camera, frame: &Frame, backend: &str) -> Value {
    let rec = CameraRecord::new(camera, frame.width, frame.height);
    let view = camera.view();
    let proj = camera.projection(frame.width as f32 / frame.height as f32);
    let objects: Vec<Value> = scene
        .objects
        .iter()
        .map(|o| {
            json!({
                "id": o.id,
                "name": o.name,
                "source_file": o.source.file.as_ref().map(|f| f.display().to_string()),
                "node": o.source.node,
                "mesh": o.source.mesh,
                "primitive": o.source.primitive,
                "triangle_count": scene.meshes[o.mesh].triangle_count(),
                "first_triangle": prepared.geometry.objects[o.id as usize].first_triangle,
                "render_mode": o.render_mode.name(),
                "material": scene.materials[o.material].name,
                "material_kind": scene.materials[o.material].kind.name(),
            })
        })
        .collect();
    let s = &frame.stats;
    let times: serde_json::Map<String, Value> = s.stage_ms.iter().map(|t| (t.label(), json!(t.ms))).collect();
    json!({
        "backend": backend,
        "threads": s.threads,
        "width": frame.width,
        "height": frame.height,
        "camera": {
            "eye": camera.eye.to_array(),
            "target": camera.target.to_array(),
            "up": camera.up.to_array(),
            "fov_y_deg": camera.fov_y_deg,
            "near": camera.near,
            "far": camera.far,
            "view": view.to_cols_array_2d(),
            "projection": proj.to_cols_array_2d(),
            "view_projection": (proj * view).to_cols_array(),
            "view_projection_from_eye": rec.view_proj,
            "matrix_layout": "column-major: view[c][r] is column c, row r (glam / WGSL)",
            "conventions": "right-handed world; clip = projection * view * world = view_projection_from_eye * (world - eye) \
    (the stages project eye-relative positions); NDC y up, depth z/w in [0, 1]; \
    window x = (ndc_x * 0.5 + 0.5) * width, y = (0.5 - ndc_y * 0.5) * height; row 0 is the top row; \
    pixel (x, y) is sampled at its centre (x + 0.5, y + 0.5)",
        },
        "lights": prepared.geometry.lights.iter().map(|l| {
            use hyrt_core::formats::{LIGHT_DIRECTIONAL, LIGHT_SPOT};
            let kind = match l.kind {
                LIGHT_DIRECTIONAL => "directional",
                LIGHT_SPOT => "spot",
                _ => "point",
            };
            let mut light = json!({
                "kind": kind,
                "position_or_direction": l.position_or_direction,
                "radiance": l.radiance,
            });
            if l.inv_range_sq > 0.0 {
                light["range"] = json!(1.0 / l.inv_range_sq.sqrt());
            }
            if l.kind == LIGHT_SPOT {
                // The record's cone: cos(outer) = -offset / scale, cos(inner) = cos(outer) + 1 / scale.
                let cos_outer = -l.spot_offset / l.spot_scale;
                light["spot_direction"] = json!(l.spot_direction);
                light["outer_cone_deg"] = json!(cos_outer.acos().to_degrees());
                light["inner_cone_deg"] = json!((cos_outer + 1.0 / l.spot_scale).min(1.0).acos().to_degrees());
            }
            light
        }).collect::<Vec<_>>(),
        "environment": prepared.geometry.environment.describe(),
        "shading": scene.shading.name(),
        "ambient": scene.ambient.0,
        "objects": objects,
        "triangles": prepared.geometry.triangle_count(),
        "bvh": { "nodes": prepared.bvh.nodes.len(), "preset": format!("{:?}", prepared.bvh.build_preset) },
        "counts": {
            "covered_pixels": s.covered_pixels,
            "ray_traced_pixels": s.ray_traced_pixels,
            "valid_rays": s.ray_traced_pixels,
            "raster_pixels": s.raster_pixels,
            "shadow_rays": s.rays_per_kind[hyrt_core::formats::RAY_KIND_SHADOW as usize],
            "occluded_shadow_rays": s.occluded_shadow_rays,
            "rays_per_kind": {
                "shadow": s.rays_per_kind[0], "primary": s.rays_per_kind[1],
                "reflection": s.rays_per_kind[2], "refraction": s.rays_per_kind[3],
            },
            "bounces": s.bounces.iter().enumerate().map(|(i, b)| json!({
                "depth": i + 1,
                "reflection_rays": b.rays_per_kind[hyrt_core::formats::RAY_KIND_REFLECTION as usize],
                "refraction_rays": b.rays_per_kind[hyrt_core::formats::RAY_KIND_REFRACTION as usize],
                "hits": b.hits,
                "shadow_rays": b.rays_per_kind[hyrt_core::formats::RAY_KIND_SHADOW as usize],
                "occluded_shadow_rays": b.occluded_shadow_rays,
            })).collect::<Vec<_>>(),
        },
        "stage_ms": times,
        "stage_work": s.stage_ms.iter().map(|t| json!({
            "stage": t.label(),
            "pixels": t.work.pixels,
            "rays_per_kind": t.work.rays,
        })).collect::<Vec<_>>(),
        "skipped_stages": s.skipped.iter().map(|k| json!({
            "stage": k.stage.name(),
            "reason": k.reason.describe(),
        })).collect::<Vec<_>>(),
        "frame_ms": s.frame_ms(),
        "notes": scene.notes,
    })
}
