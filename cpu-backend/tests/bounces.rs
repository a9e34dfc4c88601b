//! The bounce stages (`secondary_rays`, `bounce_trace`, `bounce_shading`, and
//! `rt_shading` gathering them) on scenes whose right answer is known: a mirror shows
//! the sky in the mirror direction (and an environment map's texels when the scene has
//! one), two parallel mirrors reach the depth limit or the
//! throughput cut-off, a glass slab passes rays out parallel to how they came in, a
//! glass cube reflects totally inside, no reflected or refracted ray meets the surface it
//! left (also 1e5 from the origin), and the frame is the same for every thread count
//! and traversal.

use std::f32::consts::FRAC_PI_2;
use std::sync::Arc;

use glam::{DVec3, Mat4, Quat, Vec3};
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::{CameraRecord, INVALID_ID, RAY_KIND_REFLECTION, RAY_KIND_REFRACTION};
use hyrt_core::frame::{Backend, Frame, FrameOptions};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::bounce::{sky, MIN_THROUGHPUT, SKY_HORIZON, SKY_ZENITH};
use hyrt_core::kernels::shading::ENVIRONMENT_SPECULAR;
use hyrt_core::plan::SkipReason;
use hyrt_core::scene::{Camera, Environment, EnvironmentMap, Material, MaterialKind, Mesh, RenderMode, Scene};
use hyrt_core::stage::Stage;
use hyrt_cpu::backend::CpuBackend;
use hyrt_cpu::traversal::Traversal;

fn mirror(base: f32) -> Material {
    Material {
        name: "mirror".into(),
        base_color: Vec3::splat(base),
        metallic: 1.0,
        roughness: 0.0,
        transmission: 0.0,
        kind: MaterialKind::Specular,
        ..Material::grey()
    }
}

fn glass(ior: f32) -> Material {
    Material {
        name: "glass".into(),
        base_color: Vec3::ONE,
        metallic: 0.0,
        roughness: 0.0,
        transmission: 1.0,
        kind: MaterialKind::Glass { ior },
        ..Material::grey()
    }
}

fn camera(eye: Vec3, target: Vec3, fov_y_deg: f32) -> Camera {
    Camera { fov_y_deg, ..Camera::look_at(eye, target, Vec3::Y) }
}

/// Render `scene` (no lights unless it has some) on the CPU with every stage output.
fn render(scene: &Scene, cam: &Camera, size: (u32, u32), max_depth: u32, threads: usize, t: Traversal) -> Frame {
    let mut cpu = CpuBackend::new(Some(threads));
    cpu.set_shadow_traversal(t);
    cpu.set_bounce_traversal(t);
    let prepared = cpu.prepare(WorldGeometry::build(scene), BvhPreset::default());
    let options = FrameOptions { max_depth, ..FrameOptions::with_stage_outputs() };
    cpu.render(&prepared, &CameraRecord::new(cam, size.0, size.1), &options).expect("frame")
}

fn render_default(scene: &Scene, cam: &Camera, size: (u32, u32), max_depth: u32) -> Frame {
    render(scene, cam, size, max_depth, 2, Traversal::simd())
}

/// A square mirror of side `side` in the plane z = `z`, facing `+z` or `-z`.
fn add_mirror(scene: &mut Scene, material: Material, side: f32, z: f32, facing_plus_z: bool, offset: Vec3) {
    let rot = Quat::from_rotation_x(if facing_plus_z { FRAC_PI_2 } else { -FRAC_PI_2 });
    let transform = Mat4::from_translation(offset + Vec3::new(0.0, 0.0, z))
        * Mat4::from_quat(rot)
        * Mat4::from_scale(Vec3::splat(side));
    scene.add_object(Mesh::grid("mirror", 8), material, transform, RenderMode::RayTraced);
}

/// The sky in f64, from its constants: the test's independent reading of the docs of
/// `kernels::bounce::sky`.
fn sky_f64(d: DVec3) -> DVec3 {
    let y = d.y / d.length();
    let h = Vec3::from(SKY_HORIZON).as_dvec3();
    if y >= 0.0 {
        h + (Vec3::from(SKY_ZENITH).as_dvec3() - h) * y
    } else {
        Vec3::from(hyrt_core::kernels::bounce::SKY_GROUND).as_dvec3()
    }
}

/// Tolerance of the f32 pipeline against the f64 expectation of a mirror: the view
/// direction is rounded in f32 (a few ulps of values below 1) and normalized twice, and
/// the sky is linear in the direction's height with slope below 1, so a few 1e-7.
const MIRROR_F32_TOL: f64 = 4e-6;

#[test]
fn secondary_rays_a_mirror_shows_the_sky_in_the_mirror_direction() {
    let mut scene = Scene::default();
    add_mirror(&mut scene, mirror(1.0), 20.0, 0.0, true, Vec3::ZERO);
    let eye = Vec3::new(1.5, 2.5, 6.0);
    let cam = camera(eye, Vec3::new(0.2, 0.1, 0.0), 50.0);
    let f = render_default(&scene, &cam, (64, 48), 3);
    let b1 = &f.bounces[0];
    let mut checked = 0;
    for (i, t) in f.gbuffer.iter().enumerate() {
        if !t.is_hit() {
            continue;
        }
        // The reflection ray left and met nothing: the pixel is the sky it points to,
        // weighted by Schlick's Fresnel with F0 = 1 (exactly 1).
        let [refl, refr] = b1.links[i];
        assert_eq!(refr, INVALID_ID, "a mirror does not refract");
        assert_ne!(refl, INVALID_ID, "pixel {i}: a mirror reflects");
        assert!(!b1.hits[refl as usize].is_hit(), "pixel {i}: the reflection met the mirror itself");
        let p = Vec3::from(f.surfaces[i].position).as_dvec3();
        let d = (p - eye.as_dvec3()).normalize();
        let r = d - DVec3::Z * (2.0 * d.dot(DVec3::Z));
        let want = sky_f64(r);
        let got = Vec3::from_slice(&f.rt[i][..3]).as_dvec3();
        assert!((got - want).abs().max_element() < MIRROR_F32_TOL, "pixel {i}: {got} vs sky {want}");
        checked += 1;
    }
    assert!(checked > 64 * 48 / 2, "the mirror fills most of the frame ({checked} pixels)");
    assert_eq!(f.stats.bounces.len(), 3);
    assert_eq!(f.stats.bounces[0].rays_per_kind[RAY_KIND_REFLECTION as usize], checked as u64);
    assert_eq!(f.stats.bounces[0].hits, 0);
    assert_eq!(f.stats.bounces[1].rays_per_kind, [0; 4], "nothing is hit, so nothing bounces again");
    assert_eq!(sky(Vec3::Y), Vec3::from(SKY_ZENITH));
}

/// The documented lookup of `kernels::environment` in f64, from its module docs: `u =
/// atan2(x, -z) / 2 pi` wrapped into [0, 1), `v = atan2(sqrt(x^2 + z^2), y) / pi`, the
/// bilinear blend around `(u W - 1/2, v H - 1/2)`, columns wrapping, rows clamped.
fn map_f64(map: &EnvironmentMap, d: DVec3) -> DVec3 {
    use std::f64::consts::{PI, TAU};
    let (w, h) = (map.width() as i64, map.height() as i64);
    let u = (d.x.atan2(-d.z) / TAU).rem_euclid(1.0);
    let v = d.x.hypot(d.z).atan2(d.y) / PI;
    let (x, y) = (u * w as f64 - 0.5, v * h as f64 - 0.5);
    let (fx, fy) = (x - x.floor(), y - y.floor());
    let (i0, j) = ((x.floor() as i64).rem_euclid(w), y.floor() as i64);
    let i1 = (i0 + 1) % w;
    let (j0, j1) = (j.clamp(0, h - 1), (j + 1).clamp(0, h - 1));
    let t = |i: i64, j: i64| Vec3::from_slice(&map.texel(i as u32, j as u32)[..3]).as_dvec3();
    let top = t(i0, j0) * (1.0 - fx) + t(i1, j0) * fx;
    let bottom = t(i0, j1) * (1.0 - fx) + t(i1, j1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// Tolerance of a mirror's pixels against [`map_f64`]: the f32 reflection direction is off
/// by a few 1e-7 radians (see [`MIRROR_F32_TOL`]) and `atan2_turns` by at most 2^-24 turn,
/// together under 1e-5 of a texel at 32 texels per turn; the test map's channels change by
/// at most 1 from a texel to the next, so the blend is off by under 1e-5, plus its own
/// roundings (a few 1e-8).
const MAP_MIRROR_TOL: f64 = 1e-4;

#[test]
fn bounce_shading_a_mirror_shows_the_environment_map_in_the_mirror_direction() {
    let (w, h) = (32u32, 16u32);
    let texels = (0..h)
        .flat_map(|j| {
            (0..w).map(move |i| {
                [(i as f32 + 0.5) / w as f32, (j as f32 + 0.5) / h as f32, ((7 * i + 3 * j) % 11) as f32 / 10.0, 1.0]
            })
        })
        .collect();
    let map = Arc::new(EnvironmentMap::new(w, h, texels).unwrap());
    let mut scene = Scene::default();
    add_mirror(&mut scene, mirror(1.0), 20.0, 0.0, true, Vec3::ZERO);
    scene.environment = Environment::Map(map.clone());
    let eye = Vec3::new(1.5, 2.5, 6.0);
    let cam = camera(eye, Vec3::new(0.2, 0.1, 0.0), 50.0);
    let f = render_default(&scene, &cam, (64, 48), 3);
    let b1 = &f.bounces[0];
    let mut checked = 0;
    for (i, t) in f.gbuffer.iter().enumerate() {
        if !t.is_hit() {
            continue;
        }
        let refl = b1.links[i][0];
        assert!(refl != INVALID_ID && !b1.hits[refl as usize].is_hit(), "pixel {i}: the reflection leaves the scene");
        let p = Vec3::from(f.surfaces[i].position).as_dvec3();
        let d = (p - eye.as_dvec3()).normalize();
        let r = d - DVec3::Z * (2.0 * d.dot(DVec3::Z));
        let want = map_f64(&map, r);
        let got = Vec3::from_slice(&f.rt[i][..3]).as_dvec3();
        assert!((got - want).abs().max_element() < MAP_MIRROR_TOL, "pixel {i}: {got} vs map {want}");
        assert!((got - sky_f64(r)).abs().max_element() > 1e-3, "pixel {i}: the map, not the sky");
        checked += 1;
    }
    assert!(checked > 64 * 48 / 2, "the mirror fills most of the frame ({checked} pixels)");

    // A map of one colour: every mirror pixel is that colour, bit for bit (equal texels
    // blend to themselves), and the pixels that see no mirror keep the background.
    let colour = [0.75, 1.5, 3.25];
    scene.environment = Environment::Map(Arc::new(EnvironmentMap::new(3, 2, vec![[0.75, 1.5, 3.25, 1.0]; 6]).unwrap()));
    let g = render_default(&scene, &cam, (64, 48), 3);
    for (i, t) in g.gbuffer.iter().enumerate() {
        if t.is_hit() {
            assert_eq!(g.rt[i][..3], colour, "pixel {i}");
        }
        assert_eq!(g.final_image[i].map(f32::to_bits) == f.final_image[i].map(f32::to_bits), !t.is_hit(), "pixel {i}");
    }
}

/// Two mirrors facing each other 2 apart, the camera between them looking at one.
fn parallel_mirrors(base: f32) -> (Scene, Camera) {
    let mut scene = Scene::default();
    add_mirror(&mut scene, mirror(base), 400.0, -1.0, true, Vec3::ZERO);
    add_mirror(&mut scene, mirror(base), 400.0, 1.0, false, Vec3::ZERO);
    (scene, camera(Vec3::new(0.0, 0.0, 0.5), Vec3::new(0.05, 0.02, -1.0), 20.0))
}

#[test]
fn bounce_shading_two_parallel_mirrors_reach_the_depth_limit() {
    let (scene, cam) = parallel_mirrors(1.0);
    let pixels = 32 * 24;
    for max_depth in [1, 2, 5] {
        let f = render_default(&scene, &cam, (32, 24), max_depth);
        assert_eq!(f.stats.bounces.len(), max_depth as usize);
        for (d, b) in f.stats.bounces.iter().enumerate() {
            assert_eq!(b.rays_per_kind[RAY_KIND_REFLECTION as usize], pixels, "depth {}: every ray bounces on", d + 1);
            assert_eq!(b.hits, pixels, "depth {}: every ray meets the other mirror", d + 1);
        }
        // Perfect mirrors (F = 1) and no light: each pixel is the uniform environment the
        // deepest bounce's untraced lobe sees, exactly.
        for px in &f.rt {
            assert_eq!(px, &[ENVIRONMENT_SPECULAR, ENVIRONMENT_SPECULAR, ENVIRONMENT_SPECULAR, 1.0]);
        }
        let steps: Vec<String> = f.stats.stage_ms.iter().map(|t| t.label()).collect();
        assert_eq!(steps.iter().filter(|s| s.starts_with("bounce_trace{")).count(), max_depth as usize, "{steps:?}");
    }
}

#[test]
fn secondary_rays_stop_below_the_throughput_cut_off() {
    // Mirrors of reflectance 0.3 seen nearly head-on (Schlick's grazing term is below
    // 1e-8 within the 20-degree view): path weights 0.3^d, of which 0.3^5 = 0.00243 is
    // below MIN_THROUGHPUT = 1/256 and 0.3^4 = 0.0081 is not.
    assert!(0.3f32.powi(5) < MIN_THROUGHPUT && 0.3f32.powi(4) >= MIN_THROUGHPUT);
    let (scene, cam) = parallel_mirrors(0.3);
    let f = render_default(&scene, &cam, (32, 24), 8);
    let rays: Vec<u64> = f.stats.bounces.iter().map(|b| b.rays_per_kind[RAY_KIND_REFLECTION as usize]).collect();
    assert_eq!(rays, [768, 768, 768, 768, 0, 0, 0, 0]);
    for (d, b) in f.bounces.iter().take(4).enumerate() {
        for r in &b.rays {
            let w = Vec3::from(r.throughput);
            let want = 0.3f32.powi(d as i32 + 1);
            assert!((w - Vec3::splat(want)).abs().max_element() < want * 1e-4, "depth {}: {w}", d + 1);
        }
    }
}

#[test]
fn bounce_trace_refraction_through_a_glass_slab_leaves_parallel_to_the_view() {
    let mut scene = Scene::default();
    // A slab 0.5 thick, 40 wide: faces at z = +-0.25.
    scene.add_object(
        Mesh::cube("slab"),
        glass(1.5),
        Mat4::from_scale(Vec3::new(20.0, 20.0, 0.25)),
        RenderMode::RayTraced,
    );
    let eye = Vec3::new(1.0, 1.5, 6.0);
    let cam = camera(eye, Vec3::ZERO, 40.0);
    let f = render_default(&scene, &cam, (48, 32), 2);
    let (b1, b2) = (&f.bounces[0], &f.bounces[1]);
    let mut through = 0;
    for (i, s) in f.surfaces.iter().enumerate() {
        if !s.is_hit() {
            continue;
        }
        let d = (Vec3::from(s.position) - eye).normalize();
        let [refl, refr] = b1.links[i];
        assert!(refl != INVALID_ID && refr != INVALID_ID, "pixel {i}: glass reflects and refracts");
        let (r1, t1) = (&b1.rays[refl as usize], &b1.rays[refr as usize]);
        assert_eq!((r1.kind, t1.kind), (RAY_KIND_REFLECTION, RAY_KIND_REFRACTION));
        // Fresnel splits the path: R + T = 1 for a white, fully transmissive dielectric.
        let sum = Vec3::from(r1.throughput) + Vec3::from(t1.throughput);
        assert!((sum - Vec3::ONE).abs().max_element() < 1e-6, "pixel {i}: R + T = {sum}");
        // Snell at the front face: sin_t = sin_i / 1.5.
        let (sin_i, sin_t) = (d.cross(Vec3::Z).length(), Vec3::from(t1.direction).cross(Vec3::Z).length());
        assert!((sin_t - sin_i / 1.5).abs() < 1e-5, "pixel {i}: sin_t {sin_t} vs {}", sin_i / 1.5);
        // Inside, it meets the back face from behind, and leaves parallel to the view.
        let h = &b1.hits[refr as usize];
        assert!(h.is_hit() && h.is_back_face(), "pixel {i}: the refracted ray meets the slab's far face from inside");
        let out = b2.links[refr as usize][1];
        assert_ne!(out, INVALID_ID, "pixel {i}: the ray leaves the slab (no total reflection in a slab)");
        let dir = Vec3::from(b2.rays[out as usize].direction);
        assert!((dir - d).length() < 1e-5, "pixel {i}: leaves along {dir}, came along {d}");
        through += 1;
    }
    assert!(through > 48 * 32 / 2, "{through} pixels see the slab");
}

#[test]
fn secondary_rays_reflect_totally_inside_a_glass_cube() {
    // Seen from above at a slant, rays enter the top face; inside they travel at most
    // asin(1/1.5) = 41.8 degrees from the vertical, so where they meet a side face they
    // are at least 48.2 degrees from its normal, past the critical angle: total
    // internal reflection (no refraction ray, all of the weight reflected).
    let mut scene = Scene::default();
    scene.add_object(Mesh::cube("cube"), glass(1.5), Mat4::IDENTITY, RenderMode::RayTraced);
    let eye = Vec3::new(3.0, 4.0, 2.0);
    let f = render_default(&scene, &camera(eye, Vec3::new(0.0, 0.6, 0.0), 30.0), (64, 64), 3);
    let (b1, b2) = (&f.bounces[0], &f.bounces[1]);
    let (mut total, mut leaving) = (0, 0);
    for (j, (r, s)) in b1.rays.iter().zip(&b1.surfaces).enumerate() {
        let entered_through_top = f.surfaces[r.pixel as usize].geometric_normal[1] > 0.5;
        if r.kind != RAY_KIND_REFRACTION || !entered_through_top || !s.is_hit() {
            continue;
        }
        let n = Vec3::from(s.geometric_normal);
        let [refl, refr] = b2.links[j];
        if n.y.abs() < 0.5 {
            assert_eq!(refr, INVALID_ID, "ray {j}: a side face is met past the critical angle");
            let w = Vec3::from(b2.rays[refl as usize].throughput);
            assert_eq!(w, Vec3::from(r.throughput), "ray {j}: total reflection keeps the whole weight");
            total += 1;
        } else {
            assert_ne!(refr, INVALID_ID, "ray {j}: the bottom face is met within the critical angle");
            leaving += 1;
        }
    }
    assert!(total > 50 && leaving > 0, "total internal reflections {total}, rays leaving through the bottom {leaving}");
}

#[test]
fn bounce_trace_no_reflected_or_refracted_ray_meets_the_surface_it_left_far_from_the_origin() {
    for offset in [Vec3::ZERO, Vec3::new(1e5, 3e4, -2e5)] {
        // A flat mirror, and at the origin a convex mirror ball: a reflected ray can
        // meet neither again. (Far out, the ball's vertices snap to 1/128 steps and it is
        // no longer convex; the plane z = -2e5 stays exactly flat.)
        let mut scene = Scene::default();
        add_mirror(&mut scene, mirror(1.0), 4.0, 0.0, true, offset);
        let with_ball = offset == Vec3::ZERO;
        if with_ball {
            scene.add_object(
                Mesh::uv_sphere("ball", 64, 32),
                mirror(1.0),
                Mat4::from_translation(Vec3::new(0.0, 0.0, 1.2)),
                RenderMode::RayTraced,
            );
        }
        let cam = camera(offset + Vec3::new(0.3, 5.0, 6.0), offset + Vec3::new(0.0, 0.0, 0.6), 45.0);
        let f = render_default(&scene, &cam, (96, 64), 1);
        let b1 = &f.bounces[0];
        assert!(b1.rays.len() > 1000, "offset {offset}: {} reflection rays", b1.rays.len());
        let mut ball_to_plane = 0;
        for (j, (r, h)) in b1.rays.iter().zip(&b1.hits).enumerate() {
            let from = f.surfaces[r.pixel as usize].object;
            if h.is_hit() {
                let to = b1.surfaces[j].object;
                assert_ne!(from, to, "offset {offset}: ray {j} from object {from} meets it again");
                ball_to_plane += (from == 1) as u32;
            }
        }
        assert!(!with_ball || ball_to_plane > 0, "the ball reflects the plane");

        // A glass ball: every refraction ray starts inside and meets the ball from inside.
        let mut scene = Scene::default();
        scene.add_object(
            Mesh::uv_sphere("glass", 64, 32),
            glass(1.5),
            Mat4::from_translation(offset),
            RenderMode::RayTraced,
        );
        let cam = camera(offset + Vec3::new(0.5, 1.0, 4.0), offset, 40.0);
        let f = render_default(&scene, &cam, (64, 64), 1);
        let b1 = &f.bounces[0];
        let refracted: Vec<usize> = (0..b1.rays.len()).filter(|&j| b1.rays[j].kind == RAY_KIND_REFRACTION).collect();
        assert!(refracted.len() > 1000, "offset {offset}: {} refraction rays", refracted.len());
        for j in refracted {
            let h = &b1.hits[j];
            assert!(
                h.is_hit() && h.is_back_face(),
                "offset {offset}: refraction ray {j} does not meet the ball from inside: {h:?}"
            );
        }
        // And no reflection ray off a convex ball meets it again.
        assert!(b1.rays.iter().zip(&b1.hits).all(|(r, h)| r.kind != RAY_KIND_REFLECTION || !h.is_hit()));
    }
}

/// The default scene: its golden sphere is a ray-traced mirror, its glass ball refracts.
fn default_with_glass() -> (Scene, Camera) {
    let scene = Scene::default_scene();
    let cam = scene.camera.unwrap();
    (scene, cam)
}

fn bits(f: &Frame) -> Vec<Vec<u8>> {
    let mut out: Vec<Vec<u8>> = f.buffers().map(|b| format!("{b}").into_bytes()).collect();
    for b in &f.bounces {
        out.push(bytemuck::cast_slice(&b.rays).to_vec());
        out.push(bytemuck::cast_slice(&b.links).to_vec());
        out.push(bytemuck::cast_slice(&b.hits).to_vec());
        out.push(bytemuck::cast_slice(&b.surfaces).to_vec());
        out.push(bytemuck::cast_slice(&b.shadow_rays).to_vec());
        out.push(bytemuck::cast_slice(&b.occluded).to_vec());
        out.push(b.shadow.clone());
        out.push(bytemuck::cast_slice(&b.radiance).to_vec());
    }
    out.push(bytemuck::cast_slice(&f.rt).to_vec());
    out.push(bytemuck::cast_slice(&f.final_image).to_vec());
    out
}

#[test]
fn bounce_shading_same_bits_for_every_thread_count_and_traversal() {
    let (scene, cam) = default_with_glass();
    let reference = bits(&render(&scene, &cam, (160, 90), 4, 2, Traversal::simd()));
    for (threads, t) in
        [(1, Traversal::simd()), (2, Traversal::Scalar), (3, Traversal::simd()), (2, Traversal::for_bounces())]
    {
        assert!(reference == bits(&render(&scene, &cam, (160, 90), 4, threads, t)), "{threads} threads, {}", t.name());
    }
}

#[test]
fn rt_shading_pixels_that_do_not_bounce_keep_their_bits() {
    let (scene, cam) = default_with_glass();
    let flat = render_default(&scene, &cam, (160, 90), 0);
    let deep = render_default(&scene, &cam, (160, 90), 4);
    assert!(flat.stats.skipped.iter().any(|s| s.stage == Stage::SecondaryRays && s.reason == SkipReason::MaxDepthZero));
    assert!(flat.bounces.iter().all(|b| b.rays.is_empty()), "depth 0 allocates no bounce");
    // Pixels of a ray-traced mirror or glass object.
    let bouncing = |i: usize| {
        let s = &flat.surfaces[i];
        s.is_hit() && {
            let o = &scene.objects[s.object as usize];
            o.render_mode == RenderMode::RayTraced && scene.materials[o.material].kind != MaterialKind::Diffuse
        }
    };
    let (mut same, mut changed) = (0, 0);
    for i in 0..flat.rt.len() {
        if bouncing(i) {
            changed += (flat.rt[i] != deep.rt[i]) as u32;
        } else {
            assert_eq!(flat.rt[i].map(f32::to_bits), deep.rt[i].map(f32::to_bits), "pixel {i}");
            same += 1;
        }
    }
    assert_eq!(flat.raster, deep.raster, "the raster image does not see bounces");
    assert!(same > 0 && changed > 100, "unchanged {same}, changed by bounces {changed}");

    // A scene without mirrors or glass plans no bounce whatever the depth.
    let mut plain = Scene::default_scene();
    plain.materials.iter_mut().for_each(|m| m.kind = MaterialKind::Diffuse);
    let f = render_default(&plain, &cam, (32, 18), 4);
    assert!(f.stats.skipped.iter().any(|s| s.reason == SkipReason::NoMirrorsOrGlass));
    assert!(f.stats.bounces.is_empty());
}

/// `secondary_rays` writes each parent's rays into room sized by `spawn_bound` and moves
/// the chunks of 1024 parents down over the room their parents left unused: its lists and
/// links are those of a plain loop of `spawn` over the parents in order, at depth 1 (one
/// parent per pixel) and deeper (one per ray of the bounce before), for every thread count.
/// The glass cube seen from above reflects totally inside (parents of glass that spawn one
/// ray of their two) and a half-silvered mirror's weights fall below the cut-off deeper
/// down, in more than one chunk.
#[test]
fn secondary_rays_equal_a_plain_loop_of_spawn() {
    use hyrt_core::kernels::bounce::{primary_parent, secondary_parent, spawn, spawn_bound};
    use hyrt_core::kernels::texture::Materials;
    use hyrt_cpu::secondary_rays::{secondary_rays_into, Parents};

    let mut scene = Scene::default();
    scene.add_object(Mesh::cube("cube"), glass(1.5), Mat4::IDENTITY, RenderMode::RayTraced);
    add_mirror(&mut scene, mirror(0.1), 4.0, -1.5, true, Vec3::ZERO);
    let cam = camera(Vec3::new(3.0, 4.0, 2.0), Vec3::new(0.0, 0.6, 0.0), 40.0);
    let f = render_default(&scene, &cam, (96, 80), 3);
    let g = WorldGeometry::build(&scene);
    let materials = Materials::plain(&g.objects);
    let eye = Vec3::from(CameraRecord::new(&cam, 96, 80).eye);
    let mut short = 0;
    for depth in 1..=3u32 {
        let parents = match depth {
            1 => Parents::Primary { gbuffer: &f.gbuffer, surfaces: &f.surfaces, eye },
            _ => {
                let b = &f.bounces[depth as usize - 2];
                Parents::Secondary { rays: &b.rays, hits: &b.hits, surfaces: &b.surfaces }
            }
        };
        // The plain loop, and how many parents spawn fewer rays than their bound.
        let (mut want, mut want_links) = (Vec::new(), Vec::new());
        for i in 0..parents.len() {
            let p = match parents {
                Parents::Primary { gbuffer, surfaces, eye } => {
                    primary_parent(&gbuffer[i], &surfaces[i], eye, i as u32, &materials)
                }
                Parents::Secondary { rays, hits, surfaces } => {
                    secondary_parent(&rays[i], &hits[i], &surfaces[i], &materials)
                }
                Parents::Pixels { .. } => unreachable!(),
            };
            let mut link = [INVALID_ID; 2];
            let spawned = spawn(&p, &g.triangles, depth);
            for (lobe, ray) in spawned.into_iter().enumerate() {
                if let Some(ray) = ray {
                    link[lobe] = want.len() as u32;
                    want.push(ray);
                }
            }
            let s = p.surface;
            let bound = spawn_bound(s, &g.objects);
            let n = spawned.iter().flatten().count() as u32;
            assert!(n <= bound, "depth {depth}, parent {i}: {n} rays, bound {bound}");
            short += (n < bound) as usize;
            want_links.push(link);
        }
        assert!(parents.len() > 1024 || depth > 1, "depth 1 spans more than one chunk");
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            // Reused buffers, as a frame reuses them, first holding more than the list.
            let (mut rays, mut links) = (want.repeat(2), vec![[7, 7]; parents.len() + 5]);
            pool.install(|| secondary_rays_into(parents, &materials, &g.triangles, depth, &mut rays, &mut links))
                .unwrap();
            assert!(
                bytemuck::cast_slice::<_, u8>(&rays) == bytemuck::cast_slice::<_, u8>(&want),
                "depth {depth}, {threads} threads"
            );
            assert_eq!(links, want_links, "depth {depth}, {threads} threads");
        }
        assert!(!want.is_empty(), "depth {depth} spawns rays");
    }
    assert!(short > 100, "{short} parents spawn fewer rays than their bound");
}
