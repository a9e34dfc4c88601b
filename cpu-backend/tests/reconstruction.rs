//! Stage `reconstruction` with re-intersected barycentrics
//! (`PrimaryBarycentrics::Reintersected`): the raster still decides visibility, and the
//! hit points move onto the pixels' camera rays.

use glam::{DVec3, Vec3};
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, FrameOptions, PrimaryBarycentrics};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::camera::primary_ray;
use hyrt_core::scene::Scene;
use hyrt_cpu::backend::CpuBackend;

/// Distance from `p` to the line of the ray `o + t d`, in f64.
fn distance_to_ray(p: Vec3, o: Vec3, d: Vec3) -> f64 {
    let (p, o, d) = (p.as_dvec3(), o.as_dvec3(), d.as_dvec3().normalize());
    let q: DVec3 = p - o;
    (q - d * q.dot(d)).length()
}

#[test]
fn reintersected_hits_keep_the_raster_visibility_and_lie_on_the_camera_rays() {
    let scene = Scene::default_scene();
    let mut cpu = CpuBackend::new(Some(2));
    let prepared = cpu.prepare(WorldGeometry::build(&scene), BvhPreset::default());
    let cam = CameraRecord::new(&scene.camera.unwrap(), 160, 90);
    let options = |barycentrics| FrameOptions { barycentrics, max_depth: 0, ..FrameOptions::with_stage_outputs() };
    let raster = cpu.render(&prepared, &cam, &options(PrimaryBarycentrics::Raster)).unwrap();
    let exact = cpu.render(&prepared, &cam, &options(PrimaryBarycentrics::Reintersected)).unwrap();
    assert_eq!(raster.gbuffer, exact.gbuffer, "visibility is the raster's either way");
    let (mut sum_raster, mut sum_exact, mut hits) = (0.0, 0.0, 0usize);
    for (i, t) in raster.gbuffer.iter().enumerate() {
        if !t.is_hit() {
            assert_eq!(raster.surfaces[i], exact.surfaces[i]);
            continue;
        }
        let ray = primary_ray(&cam, i as u32 % cam.width, i as u32 / cam.width);
        let (o, d) = (Vec3::from(ray.origin), Vec3::from(ray.direction));
        let dr = distance_to_ray(Vec3::from(raster.surfaces[i].position), o, d);
        let de = distance_to_ray(Vec3::from(exact.surfaces[i].position), o, d);
        sum_raster += dr;
        sum_exact += de;
        hits += 1;
        // On the ray up to f32 rounding of the point (a few ulps of a coordinate of about
        // 10) unless the ray missed the triangle and the raster's barycentrics were kept.
        const ON_RAY: f64 = 1e-4;
        assert!(de <= ON_RAY || de == dr, "pixel {i}: {de} from its ray (raster {dr})");
    }
    assert!(hits > 5_000, "{hits}");
    assert!(sum_exact < sum_raster / 10.0, "mean distance to the rays: exact {sum_exact}, raster {sum_raster}");
}
