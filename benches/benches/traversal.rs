//! Criterion benchmarks of batch ray traversal (`hyrt_cpu::traversal`): scalar reference
//! vs SIMD packets vs single rays through the wide tree, 1 and 2 threads, in rays per
//! second (`Throughput::Elements`).
//!
//! * `shadow`: the shadow-ray list of a real 1280x720 CPU frame (any hit).
//! * `primary`: one primary ray per pixel from `camera::primary_rays` (closest hit).
//! * `secondary`: the reflection and refraction rays of every depth of the same frame at
//!   the default max depth (closest hit), when the scene has mirrors or glass.
//!
//! Scenes: the default scene, and when `../shared/assets` is present Sponza and the bunny
//! (the glTF files with `ensure_camera_and_lights`), the teaser and the dragon manifests.
//! `cargo bench -p hyrt-benches --bench traversal [-- <filter>]`.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use hyrt::Scene;
use hyrt_benches::shared_assets;
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, FrameOptions, PreparedScene};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::camera::primary_rays;
use hyrt_cpu::backend::CpuBackend;
use hyrt_cpu::traversal::{closest_hit_batch_into, occluded_batch_into, with_threads, Traversal};

const W: u32 = 1280;
const H: u32 = 720;
const THREADS: [usize; 2] = [1, 2];

/// The scenes of this bench: (name, scene with camera and lights).
fn scenes() -> Vec<(&'static str, Scene)> {
    let mut out = vec![("default", Scene::default_scene())];
    let Some(assets) = shared_assets() else {
        eprintln!("traversal bench: ../shared/assets not found; default scene only");
        return out;
    };
    let manifests = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes");
    let files = [
        ("sponza", assets.join("sponza.glb")),
        ("bunny", assets.join("bunny.glb")),
        ("teaser", manifests.join("teaser.toml")),
        ("dragon", manifests.join("dragon.toml")),
    ];
    for (name, path) in files {
        match Scene::load(&path) {
            Ok(mut s) => {
                s.ensure_camera_and_lights();
                out.push((name, s));
            }
            Err(e) => eprintln!("traversal bench: skipping {name}: {e}"),
        }
    }
    out
}

fn traversal(c: &mut Criterion) {
    let level = hyrt_cpu::traversal::SimdLevel::detect();
    let kinds = [Traversal::Scalar, Traversal::Packet(level), Traversal::Single(level)];
    for (name, scene) in scenes() {
        let cam = CameraRecord::new(&scene.camera.unwrap(), W, H);
        let geometry = WorldGeometry::build(&scene);
        let bvh = Bvh::build(&geometry, BvhPreset::default());
        let prepared = PreparedScene::new(geometry, bvh, 0.0);
        let frame =
            CpuBackend::new(Some(1)).render(&prepared, &cam, &FrameOptions::with_stage_outputs()).expect("frame");
        let (g, bvh) = (&prepared.geometry, &prepared.bvh);
        let secondary: Vec<_> = frame.bounces.iter().flat_map(|b| b.rays.iter().copied()).collect();
        let shadow = frame.rays;
        let primary = primary_rays(&cam);

        let mut group = c.benchmark_group(format!("traversal/{name}/shadow"));
        group.sample_size(10).throughput(Throughput::Elements(shadow.len() as u64));
        for threads in THREADS {
            for kind in kinds {
                let mut out = Vec::new();
                group.bench_function(format!("{}/{threads}t", kind.name()), |b| {
                    with_threads(threads, || {
                        b.iter(|| occluded_batch_into(bvh, g.traversal_table(), &shadow, kind, &mut out))
                    })
                });
            }
        }
        group.finish();

        for (kind_of_rays, rays) in [("primary", &primary), ("secondary", &secondary)] {
            if rays.is_empty() {
                continue;
            }
            let mut group = c.benchmark_group(format!("traversal/{name}/{kind_of_rays}"));
            group.sample_size(10).throughput(Throughput::Elements(rays.len() as u64));
            for threads in THREADS {
                for kind in kinds {
                    let mut out = Vec::new();
                    group.bench_function(format!("{}/{threads}t", kind.name()), |b| {
                        with_threads(threads, || {
                            b.iter(|| closest_hit_batch_into(bvh, g.traversal_table(), rays, kind, &mut out))
                        })
                    });
                }
            }
            group.finish();
        }
    }
}

criterion_group!(benches, traversal);
criterion_main!(benches);
