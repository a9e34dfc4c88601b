//! The ray contest of `hyrt bench`'s peers section on chosen scenes only, for working on
//! a traversal: each scene's frame shadow rays (any hit) and one primary ray per pixel
//! (closest hit) at 1280x720, traced by hyrt's SIMD traversals and Embree's fastest
//! packets, interleaved round by round in a pool of the given threads. Prints each
//! contender's median time and, for each hyrt traversal, the median (least-greatest) of
//! the per-round ratios Embree's best / hyrt (above 1: hyrt is faster), and checks every
//! hyrt traversal against the scalar reference ray by ray.
//!
//! ```text
//! cargo run --release -p hyrt-benches --features embree --example ray_contest -- \
//!     [--threads N] [--rounds N] [--simd avx2|avx512|sse2|portable] [--kind shadow|primary|both]
//!     [--packets-only] SCENE...
//! ```
//!
//! `--packets-only` times hyrt's packets alone (no Embree, no single rays): for profiling.
//! SCENE is a manifest name of `assets/scenes` (teaser, sponza, horse_near, horse_far,
//! bunny_near, bunny_far, dragon); `all` is all of them.

use hyrt_benches::bench::embree::EmbreeScene;
use hyrt_benches::bench::peers::{frame_shadow_rays, PeerScene};
use hyrt_benches::bench::scenes::load_manifest;
use hyrt_benches::bench::stats::{interleaved_ms, median, round_ratios};
use hyrt_core::bvh::ClosestHit;
use hyrt_core::formats::{CameraRecord, RayRecord};
use hyrt_core::kernels::camera::primary_rays;
use hyrt_cpu::traversal::{
    closest_hit_batch_into, force_simd_level, occluded_batch_into, SimdLevel, Traversal, TRAVERSAL_CHUNK,
};
use rayon::prelude::*;

const ALL: [&str; 7] = ["teaser", "sponza", "horse_near", "horse_far", "bunny_near", "bunny_far", "dragon"];
const SIZE: (u32, u32) = (1280, 720);

struct Args {
    threads: usize,
    rounds: usize,
    shadow: bool,
    primary: bool,
    scenes: Vec<String>,
    /// Only hyrt's packets (for profiling them alone).
    packets_only: bool,
}

fn parse() -> Result<Args, String> {
    let mut a = Args { threads: 2, rounds: 5, shadow: true, primary: true, scenes: Vec::new(), packets_only: false };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut value = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        match arg.as_str() {
            "--threads" => a.threads = value("--threads")?.parse().map_err(|e| format!("--threads: {e}"))?,
            "--rounds" => a.rounds = value("--rounds")?.parse().map_err(|e| format!("--rounds: {e}"))?,
            "--simd" => {
                let v = value("--simd")?;
                let level = SimdLevel::from_name(&v).ok_or(format!("--simd: unknown level {v}"))?;
                force_simd_level(Some(level))?;
            }
            "--kind" => match value("--kind")?.as_str() {
                "shadow" => a.primary = false,
                "primary" => a.shadow = false,
                "both" => {}
                k => return Err(format!("--kind: unknown kind {k}")),
            },
            "--packets-only" => a.packets_only = true,
            "all" => a.scenes.extend(ALL.iter().map(|s| s.to_string())),
            s if s.starts_with("--") => return Err(format!("unknown option {s}")),
            s => a.scenes.push(s.to_string()),
        }
    }
    if a.scenes.is_empty() {
        return Err("name at least one scene (or all)".into());
    }
    Ok(a)
}

/// Embree's answers in chunks of the traversal's size, on the current pool.
fn embree_chunks<T: Send>(rays: &[RayRecord], out: &mut [T], f: impl Fn(&[RayRecord], &mut [T]) + Sync) {
    out.par_chunks_mut(TRAVERSAL_CHUNK).zip(rays.par_chunks(TRAVERSAL_CHUNK)).for_each(|(o, r)| f(r, o));
}

/// Print the contest's medians and each hyrt traversal's per-round ratio against the
/// fastest Embree run of the same round. `ms[i]` per contender; the first `hyrt` are hyrt's.
fn print(kind: &str, scene: &str, rays: usize, names: &[String], ms: &[Vec<f64>], hyrt: usize) {
    println!("{scene} {kind}: {rays} rays");
    for (n, m) in names.iter().zip(ms) {
        let med = median(m).unwrap_or(f64::NAN);
        println!("  {n:<44} {med:>8.2} ms {:>7.2} Mrays/s", rays as f64 / med / 1e3);
    }
    if ms.len() == hyrt {
        return;
    }
    let rounds = ms[0].len();
    let best_peer: Vec<f64> =
        (0..rounds).map(|r| ms[hyrt..].iter().map(|m| m[r]).fold(f64::INFINITY, f64::min)).collect();
    for (n, m) in names.iter().zip(ms).take(hyrt) {
        if let Some((med, lo, hi)) = round_ratios(&best_peer, m) {
            println!("  {n}: Embree's best / hyrt = {med:.2} ({lo:.2}-{hi:.2})");
        }
    }
}

fn main() {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("ray_contest: {e}");
            std::process::exit(2);
        }
    };
    let level = SimdLevel::detect();
    println!("SIMD level {}, {} threads, {} rounds", level.name(), args.threads, args.rounds);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(args.threads).build().expect("rayon pool");
    let hyrt = if args.packets_only {
        vec![Traversal::Packet(level)]
    } else {
        vec![Traversal::Packet(level), Traversal::Single(level)]
    };
    for name in &args.scenes {
        let scene = match load_manifest(name) {
            Ok(s) => s.scene,
            Err(e) => {
                eprintln!("ray_contest: {name}: {e}");
                continue;
            }
        };
        let prepared = hyrt_benches::bench::prepare(&scene, Some(args.threads));
        let camera = CameraRecord::new(&scene.camera.expect("manifests have cameras"), SIZE.0, SIZE.1);
        let row = PeerScene { name, prepared: &prepared, camera };
        let g = &prepared.geometry;
        let bvh = &prepared.bvh;
        let embree = EmbreeScene::new(g, &format!("threads={}", args.threads)).expect("Embree scene");
        let mut names: Vec<String> = hyrt.iter().map(|t| t.name()).collect();
        if args.shadow {
            let rays = frame_shadow_rays(&row).expect("frame");
            let reference = pool.install(|| {
                let mut o = Vec::new();
                occluded_batch_into(bvh, &g.triangles, &rays, Traversal::Scalar, &mut o);
                o
            });
            let mut outs = vec![Vec::new(); hyrt.len()];
            let mut e_outs = vec![vec![false; rays.len()]; 2];
            let ms = {
                let mut runs: Vec<Box<dyn FnMut() + '_>> = Vec::new();
                for (&t, o) in hyrt.iter().zip(outs.iter_mut()) {
                    let (pool, rays) = (&pool, &rays);
                    runs.push(Box::new(move || pool.install(|| occluded_batch_into(bvh, &g.triangles, rays, t, o))));
                }
                if !args.packets_only {
                    let [o8, o8c] = &mut e_outs[..] else { unreachable!() };
                    let (p, r, e) = (&pool, &rays, &embree);
                    runs.push(Box::new(move || p.install(|| embree_chunks(r, o8, |r, o| e.occluded8(r, o)))));
                    runs.push(Box::new(move || p.install(|| embree_chunks(r, o8c, |r, o| e.occluded8_coherent(r, o)))));
                }
                let mut refs: Vec<&mut dyn FnMut()> = runs.iter_mut().map(|r| &mut **r as &mut dyn FnMut()).collect();
                interleaved_ms(args.rounds, &mut refs)
            };
            for (t, o) in hyrt.iter().zip(&outs) {
                let differ = o.iter().zip(&reference).filter(|(a, b)| a != b).count();
                assert_eq!(differ, 0, "{}: {differ} shadow rays differ from the scalar reference", t.name());
            }
            names.truncate(hyrt.len());
            names.extend(["Embree rtcOccluded8".to_string(), "Embree rtcOccluded8 coherent".to_string()]);
            print("shadow rays", name, rays.len(), &names, &ms, hyrt.len());
        }
        if args.primary {
            let rays = primary_rays(&camera);
            let reference: Vec<Option<ClosestHit>> = pool.install(|| {
                let mut o = Vec::new();
                closest_hit_batch_into(bvh, &g.triangles, &rays, Traversal::Scalar, &mut o);
                o
            });
            let mut outs = vec![Vec::new(); hyrt.len()];
            let mut e_outs = vec![vec![None; rays.len()]; 2];
            let ms = {
                let mut runs: Vec<Box<dyn FnMut() + '_>> = Vec::new();
                for (&t, o) in hyrt.iter().zip(outs.iter_mut()) {
                    let (pool, rays) = (&pool, &rays);
                    runs.push(Box::new(move || pool.install(|| closest_hit_batch_into(bvh, &g.triangles, rays, t, o))));
                }
                if !args.packets_only {
                    let [o8, o8c] = &mut e_outs[..] else { unreachable!() };
                    let (p, r, e) = (&pool, &rays, &embree);
                    runs.push(Box::new(move || p.install(|| embree_chunks(r, o8, |r, o| e.intersect8(r, o)))));
                    runs.push(Box::new(move || {
                        p.install(|| embree_chunks(r, o8c, |r, o| e.intersect8_coherent(r, o)))
                    }));
                }
                let mut refs: Vec<&mut dyn FnMut()> = runs.iter_mut().map(|r| &mut **r as &mut dyn FnMut()).collect();
                interleaved_ms(args.rounds, &mut refs)
            };
            for (t, o) in hyrt.iter().zip(&outs) {
                let differ = o.iter().zip(&reference).filter(|(a, b)| a != b).count();
                assert_eq!(differ, 0, "{}: {differ} primary rays differ from the scalar reference", t.name());
            }
            names.truncate(hyrt.len());
            names.extend(["Embree rtcIntersect8".to_string(), "Embree rtcIntersect8 coherent".to_string()]);
            print("primary rays", name, rays.len(), &names, &ms, hyrt.len());
        }
    }
}
