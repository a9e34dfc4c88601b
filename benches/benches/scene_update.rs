//! Criterion benchmarks of moving an object between frames (issue 17): what preparing the
//! whole scene again costs (world tables and the single-level BVH, today's only way),
//! preparing it once with two levels, and moving one object in place
//! (`WorldGeometry::update_object` then `TwoLevelBvh::update_objects`: the object's world
//! triangles rewritten, its instance's map, every instance box and the top level rebuilt,
//! no bottom level touched).
//!
//! Scenes: the default scene (its sphere moving), and with `../shared/assets` the teaser
//! (the bunny moving in Sponza). `cargo bench -p hyrt-benches --bench scene_update`.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use hyrt::Scene;
use hyrt_benches::shared_assets;
use hyrt_core::bvh::two_level::TwoLevelBvh;
use hyrt_core::bvh::{Bvh, BvhPreset};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::glam::{Mat4, Quat, Vec3};

/// (name, scene, the object that moves)
fn scenes() -> Vec<(&'static str, Scene, u32)> {
    let mut out = Vec::new();
    let default = Scene::default_scene();
    let sphere = default.objects.iter().position(|o| o.name.contains("sphere")).unwrap_or(0) as u32;
    out.push(("default", default, sphere));
    match shared_assets() {
        None => eprintln!("scene_update bench: ../shared/assets not found; default scene only"),
        Some(_) => {
            let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/teaser.toml");
            match Scene::load(&path) {
                Ok(s) => {
                    let bunny = s.objects.iter().position(|o| o.name.to_lowercase().contains("bunny")).unwrap_or(0);
                    out.push(("teaser", s, bunny as u32));
                }
                Err(e) => eprintln!("scene_update bench: skipping the teaser: {e}"),
            }
        }
    }
    out
}

fn scene_update(c: &mut Criterion) {
    let preset = BvhPreset::default();
    for (name, mut scene, moving_object) in scenes() {
        let mut group = c.benchmark_group(format!("scene_update/{name}"));
        group.sample_size(10);
        group.bench_function("prepare_again", |b| {
            b.iter(|| {
                let g = WorldGeometry::build(&scene);
                Bvh::build(&g, preset)
            })
        });
        let moving: Vec<bool> = (0..scene.objects.len()).map(|o| o == moving_object as usize).collect();
        group.bench_function("prepare_two_level", |b| {
            b.iter(|| {
                let g = WorldGeometry::build(&scene);
                TwoLevelBvh::build(&scene, &g, preset, &moving)
            })
        });
        let mut geometry = WorldGeometry::build(&scene);
        let mut levels = TwoLevelBvh::build(&scene, &geometry, preset, &moving);
        let rest = scene.objects[moving_object as usize].transform;
        let mut frame = 0u32;
        group.bench_function("move_one_object", |b| {
            b.iter(|| {
                frame += 1;
                let turn = Mat4::from_rotation_translation(
                    Quat::from_rotation_y(0.1 * frame as f32),
                    Vec3::X * 0.01 * frame as f32,
                );
                scene.objects[moving_object as usize].transform = turn * rest;
                geometry.update_object(&scene, moving_object);
                levels.update_objects(&scene, &geometry, &[moving_object]).expect("the object is an instance");
            })
        });
        group.finish();
    }
}

criterion_group!(benches, scene_update);
criterion_main!(benches);
