//! Criterion benchmarks: every CPU stage, and whole frames, at 1280x720 on the
//! default scene and (when `../shared/assets` is present) the paper's teaser.
//! `cargo bench -p hyrt-benches`; each stage reads the previous stage's real output.

use criterion::{criterion_group, criterion_main, Criterion};
use hyrt::{formats::CameraRecord, FrameOptions, Renderer};
use hyrt_benches::bench_scenes;
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::geometry::WorldGeometry;
use hyrt_cpu::{compaction, composition, raster_shading, reconstruction, rt_shading, shadow_rays, visibility_raster};

const W: u32 = 1280;
const H: u32 = 720;

fn stages(c: &mut Criterion) {
    for b in bench_scenes() {
        let cam = b.scene.camera.unwrap();
        let rec = CameraRecord::new(&cam, W, H);
        let g = WorldGeometry::build(&b.scene);
        let eye = cam.eye;
        let mut group = c.benchmark_group(b.name);
        group.sample_size(10);
        group.bench_function("bvh_build", |bn| bn.iter(|| Bvh::build(&g, BvhPreset::default())));
        let bvh = Bvh::build(&g, BvhPreset::default());
        group.bench_function("visibility_raster", |bn| bn.iter(|| visibility_raster::visibility_raster(&g, &rec)));
        let vis = visibility_raster::visibility_raster(&g, &rec);
        group.bench_function("reconstruction", |bn| bn.iter(|| reconstruction::reconstruction(&vis.gbuffer, &g, eye)));
        let surfaces = reconstruction::reconstruction(&vis.gbuffer, &g, eye);
        group.bench_function("compaction", |bn| bn.iter(|| compaction::compaction(&surfaces, &g.lights)));
        let rays = compaction::compaction(&surfaces, &g.lights);
        group.bench_function("shadow_rays", |bn| bn.iter(|| shadow_rays::shadow_rays(&bvh, &g, &rays)));
        let occluded = shadow_rays::shadow_rays(&bvh, &g, &rays);
        let mask = compaction::shadow_mask(&rays, &occluded, surfaces.len(), g.lights.len());
        group.bench_function("rt_shading", |bn| {
            bn.iter(|| rt_shading::rt_shading(&surfaces, &mask, &g.objects, &g.lights, eye))
        });
        let rt = rt_shading::rt_shading(&surfaces, &mask, &g.objects, &g.lights, eye);
        group.bench_function("raster_shading", |bn| {
            bn.iter(|| raster_shading::raster_shading(&surfaces, &mask, &g.objects, &g.lights, 1.0))
        });
        let raster = raster_shading::raster_shading(&surfaces, &mask, &g.objects, &g.lights, 1.0);
        group.bench_function("composition", |bn| bn.iter(|| composition::composition(&raster, &rt, 1.0)));
        let r = Renderer::cpu(None);
        let prepared = r.prepare(&b.scene);
        group.bench_function("frame", |bn| {
            bn.iter(|| r.render(&prepared, &cam, W, H, &FrameOptions::default()).unwrap())
        });
        group.finish();
    }
}

criterion_group!(benches, stages);
criterion_main!(benches);
