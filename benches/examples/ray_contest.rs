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
//!     [--threads N] [--rounds N] [--passes N] [--cold MB] [--simd avx2|avx512|sse2|portable] [--kind shadow|primary|both|bounce|from-lights]
//!     [--packets-only | --singles-only | --embree-only] [--with-avx2] [--with-auto] [--list-order] SCENE...
//! ```
//!
//! The contenders run in a pool whose workers are pinned one per CPU
//! (`hyrt_benches::bench::peers::contest_pool`, as in the report).
//! `RAY_CONTEST_ROUNDS=1` in the environment also prints every contender's time round by
//! round (a whole phase of rounds at one thread's speed is the scheduler, not the tracer).
//!
//! `--with-avx2`: at the AVX-512 level, also each traversal compiled for AVX2 alone,
//! interleaved with the rest, so that one run says which level is faster per ray kind
//! (issue 36's per-kind SIMD level). `--with-auto`: also the traversals the stages run where
//! they measure their level (`packet-auto`, `single-auto`). `--passes N`: each contender's
//! turn traces the list N times in a row (times per pass), as the report's contest does for
//! short lists.
//!
//! `--cold MB`: before every timed turn each worker of the pool reads a buffer of `MB`
//! megabytes (untimed), so that every contender starts with caches holding none of its
//! data, instead of what the contender before it left there. Without it a contender that
//! follows one sharing its structure starts warm: in the report's contest Embree's
//! `rtcIntersect8` always follows its `rtcIntersect1` on the same tree, while hyrt's single
//! rays follow its packets, which walk the binary tree and not the wide view (as in a
//! frame, where the bounce stage follows the shadow stage). Give at least twice the
//! last-level cache (`--cold 96` on this project's EPYC with 32 MB of L3).
//!
//! The shadow rays are traced in the order the report's contest traces them: 2x4 pixel tiles
//! per light (`hyrt_cpu::traversal::sort_into_tiles`, the order of a CPU frame without
//! stage outputs). `--list-order` keeps the frame's list as compaction wrote it (light,
//! then pixel row after pixel row), the order of a frame that keeps its stage outputs.
//!
//! `--kind bounce` traces the frame's reflection and refraction rays (closest hit; scenes
//! with mirrors or glass only) instead. `--kind from-lights` traces the frame's shadow rays
//! to point and spot lights backwards, from each light to the ray's origin, as closest-hit
//! rays (origin `o + d`, direction `-d`, `t` from `1 - t_max` to 1; directional lights'
//! rays left out): every ray of a packet leaves one point (up to the rounding of `o + d`),
//! and the directions part where the list of active pixels jumps from one pixel row to the
//! next, the frustum packets' hard case (`traversal::frustum`'s `MAX_IDLE_LEAF_BOXES`).
//! Only hyrt's own answers are compared (with its scalar reference); the backward rays
//! answer differently from the forward ones near the origins' surfaces.
//!
//! `--packets-only` times hyrt's packets alone (no Embree, no single rays), `--singles-only`
//! its single rays alone, `--embree-only` Embree's packets alone: for profiling (e.g.
//! `valgrind --tool=callgrind --toggle-collect=rtcIntersect8`).
//! SCENE is a manifest name of `assets/scenes` (teaser, sponza, horse_near, horse_far,
//! bunny_near, bunny_far, dragon); `all` is all of them.

use hyrt_benches::bench::embree::EmbreeScene;
use hyrt_benches::bench::peers::{frame_rays, frame_shadow_rays, PeerScene};
use hyrt_benches::bench::scenes::load_manifest;
use hyrt_benches::bench::stats::{interleaved_turns_ms, median, round_ratios};
use hyrt_core::formats::{CameraRecord, RayRecord};
use hyrt_core::kernels::camera::primary_rays;
use hyrt_cpu::traversal::{
    closest_hit_batch_into, force_simd_level, occluded_batch_into, sort_into_tiles, SimdLevel, Traversal,
    TRAVERSAL_CHUNK,
};
use rayon::prelude::*;

const ALL: [&str; 7] = ["teaser", "sponza", "horse_near", "horse_far", "bunny_near", "bunny_far", "dragon"];
const SIZE: (u32, u32) = (1280, 720);

struct Args {
    threads: usize,
    rounds: usize,
    /// Passes of the list in each contender's turn (the time per pass is reported).
    passes: usize,
    /// Megabytes read by every worker before each timed turn (0: none).
    cold_mb: usize,
    shadow: bool,
    primary: bool,
    /// The frame's reflection and refraction rays (closest hit), with `--kind bounce`.
    bounce: bool,
    /// The frame's shadow rays traced from their lights (closest hit), with `--kind
    /// from-lights`.
    from_lights: bool,
    scenes: Vec<String>,
    /// Only hyrt's packets (for profiling them alone).
    packets_only: bool,
    /// Only hyrt's single rays (for profiling them alone).
    singles_only: bool,
    /// Only Embree's runs (for profiling the peer alone).
    embree_only: bool,
    /// At the AVX-512 level, also each traversal at AVX2.
    with_avx2: bool,
    /// Also the stages' measured traversals (`packet-auto`, `single-auto`).
    with_auto: bool,
    /// The shadow rays in compaction's order, not sorted into tiles.
    list_order: bool,
}

fn parse() -> Result<Args, String> {
    let mut a = Args {
        threads: 2,
        rounds: 5,
        passes: 1,
        cold_mb: 0,
        shadow: true,
        primary: true,
        bounce: false,
        from_lights: false,
        scenes: Vec::new(),
        packets_only: false,
        singles_only: false,
        embree_only: false,
        with_avx2: false,
        with_auto: false,
        list_order: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut value = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        match arg.as_str() {
            "--threads" => a.threads = value("--threads")?.parse().map_err(|e| format!("--threads: {e}"))?,
            "--rounds" => a.rounds = value("--rounds")?.parse().map_err(|e| format!("--rounds: {e}"))?,
            "--passes" => a.passes = value("--passes")?.parse().map_err(|e| format!("--passes: {e}"))?,
            "--cold" => a.cold_mb = value("--cold")?.parse().map_err(|e| format!("--cold: {e}"))?,
            "--simd" => {
                let v = value("--simd")?;
                let level = SimdLevel::from_name(&v).ok_or(format!("--simd: unknown level {v}"))?;
                force_simd_level(Some(level))?;
            }
            "--kind" => match value("--kind")?.as_str() {
                "shadow" => a.primary = false,
                "primary" => a.shadow = false,
                "both" => {}
                "bounce" => (a.shadow, a.primary, a.bounce) = (false, false, true),
                "from-lights" => (a.shadow, a.primary, a.from_lights) = (false, false, true),
                k => return Err(format!("--kind: unknown kind {k}")),
            },
            "--packets-only" => a.packets_only = true,
            "--singles-only" => a.singles_only = true,
            "--embree-only" => a.embree_only = true,
            "--with-avx2" => a.with_avx2 = true,
            "--with-auto" => a.with_auto = true,
            "--list-order" => a.list_order = true,
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
        if std::env::var_os("RAY_CONTEST_ROUNDS").is_some() {
            println!("    rounds: {:?}", m.iter().map(|x| (x * 100.0).round() / 100.0).collect::<Vec<_>>());
        }
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

/// Embree's packet tracer of one ray kind, with its name in the table.
type EmbreeRun<E> = (&'static str, fn(&EmbreeScene, &[RayRecord], &mut [E]));

/// What every ray list of one scene is traced with.
struct Contest<'a> {
    args: &'a Args,
    pool: &'a rayon::ThreadPool,
    hyrt: &'a [Traversal],
    embree: &'a EmbreeScene,
    scene: &'a str,
}

impl Contest<'_> {
    /// Trace `rays` with hyrt's traversals (`trace`, answers `H`) and, unless
    /// `--packets-only`, Embree's two packet runs (answers `E`, buffers filled with
    /// `e_blank`), interleaved; check every hyrt traversal against the scalar reference
    /// ray by ray, and print the medians and ratios.
    fn run<H, E>(
        &self,
        kind: &str,
        rays: &[RayRecord],
        trace: impl Fn(&[RayRecord], Traversal, &mut Vec<H>) + Sync,
        peers: [EmbreeRun<E>; 2],
        e_blank: E,
    ) where
        H: PartialEq + Send,
        E: Clone + Send,
    {
        let pool = self.pool;
        let reference = pool.install(|| {
            let mut o = Vec::new();
            trace(rays, Traversal::Scalar, &mut o);
            o
        });
        let mut outs: Vec<Vec<H>> = self.hyrt.iter().map(|_| Vec::new()).collect();
        let mut e_outs = vec![vec![e_blank; rays.len()]; peers.len()];
        let ms = {
            let trace = &trace;
            let mut runs: Vec<Box<dyn FnMut() + '_>> = Vec::new();
            let passes = self.args.passes.max(1);
            for (&t, o) in self.hyrt.iter().zip(outs.iter_mut()) {
                runs.push(Box::new(move || (0..passes).for_each(|_| pool.install(|| trace(rays, t, o)))));
            }
            if !self.args.packets_only && !self.args.singles_only {
                for (&(_, f), o) in peers.iter().zip(e_outs.iter_mut()) {
                    let e = self.embree;
                    runs.push(Box::new(move || {
                        (0..passes).for_each(|_| pool.install(|| embree_chunks(rays, o, |r, o| f(e, r, o))))
                    }));
                }
            }
            let mut refs: Vec<&mut dyn FnMut()> = runs.iter_mut().map(|r| &mut **r as &mut dyn FnMut()).collect();
            // Read with a stride of one cache line; the sum keeps the reads.
            let sweep: Vec<u64> = (0..(self.args.cold_mb << 17) as u64).collect();
            let mut evict = || {
                if !sweep.is_empty() {
                    pool.broadcast(|_| {
                        std::hint::black_box(sweep.iter().step_by(8).fold(0u64, |a, &x| a.wrapping_add(x)))
                    });
                }
            };
            let ms = interleaved_turns_ms(self.args.rounds, &mut |_| {}, &mut evict, &mut refs);
            ms.into_iter().map(|m| m.into_iter().map(|x| x / passes as f64).collect()).collect::<Vec<Vec<f64>>>()
        };
        for (t, o) in self.hyrt.iter().zip(&outs) {
            let differ = o.iter().zip(&reference).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{}: {differ} {kind} differ from the scalar reference", t.name());
        }
        let names: Vec<String> =
            self.hyrt.iter().map(|t| t.name()).chain(peers.iter().map(|(n, _)| n.to_string())).collect();
        print(kind, self.scene, rays.len(), &names, &ms, self.hyrt.len());
    }
}

/// The rays of `shadow` to point and spot lights (finite `t_max`; their direction ends at
/// the light), backwards: from `o + d` along `-d` for `t` from `1 - t_max` to 1.
fn from_lights(shadow: &[RayRecord]) -> Vec<RayRecord> {
    shadow
        .iter()
        .filter(|r| r.t_max.is_finite())
        .map(|r| {
            let (o, d) = (r.origin, r.direction);
            RayRecord {
                origin: [o[0] + d[0], o[1] + d[1], o[2] + d[2]],
                direction: [-d[0], -d[1], -d[2]],
                t_min: 1.0 - r.t_max,
                t_max: 1.0,
                ..*r
            }
        })
        .collect()
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
    println!("Embree: {}", hyrt_benches::bench::peers::embree_peer());
    let pool = hyrt_benches::bench::peers::contest_pool(args.threads);
    let mut hyrt = if args.embree_only {
        Vec::new()
    } else if args.packets_only {
        vec![Traversal::Packet(level)]
    } else if args.singles_only {
        vec![Traversal::Single(level)]
    } else {
        vec![Traversal::Packet(level), Traversal::Single(level)]
    };
    if args.with_avx2 && level == SimdLevel::Avx512 {
        let avx2 = |t: &Traversal| match *t {
            Traversal::Packet(_) => Traversal::Packet(SimdLevel::Avx2),
            _ => Traversal::Single(SimdLevel::Avx2),
        };
        let twins: Vec<Traversal> = hyrt.iter().map(avx2).collect();
        hyrt.extend(twins);
    }
    if args.with_auto && hyrt_cpu::traversal::tuning::applies() {
        let auto: Vec<Traversal> = hyrt
            .iter()
            .filter_map(|t| match t {
                Traversal::Packet(l) if *l == level => Some(Traversal::PacketAuto),
                Traversal::Single(l) if *l == level => Some(Traversal::SingleAuto),
                _ => None,
            })
            .collect();
        hyrt.extend(auto);
    }
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
        let contest = Contest { args: &args, pool: &pool, hyrt: &hyrt, embree: &embree, scene: name };
        if args.shadow {
            let mut rays = frame_shadow_rays(&row).expect("frame");
            if !args.list_order {
                sort_into_tiles(&mut rays, row.camera.width);
            }
            contest.run(
                "shadow rays",
                &rays,
                |rays, t, o| occluded_batch_into(bvh, g.traversal_table(), rays, t, o),
                [
                    ("Embree rtcOccluded8", EmbreeScene::occluded8),
                    ("Embree rtcOccluded8 coherent", EmbreeScene::occluded8_coherent),
                ],
                false,
            );
        }
        // Closest hits against Embree's two packet runs.
        let closest = |kind: &str, rays: &[RayRecord]| {
            contest.run(
                kind,
                rays,
                |rays, t, o| closest_hit_batch_into(bvh, g.traversal_table(), rays, t, o),
                [
                    ("Embree rtcIntersect8", EmbreeScene::intersect8),
                    ("Embree rtcIntersect8 coherent", EmbreeScene::intersect8_coherent),
                ],
                None,
            )
        };
        if args.bounce {
            let rays = frame_rays(&row).expect("frame").1;
            if rays.is_empty() {
                println!("{name}: no reflection or refraction rays");
            } else {
                closest("reflection and refraction rays", &rays);
            }
        }
        if args.primary {
            closest("primary rays", &primary_rays(&camera));
        }
        if args.from_lights {
            let rays = from_lights(&frame_shadow_rays(&row).expect("frame"));
            if rays.is_empty() {
                println!("{name}: no shadow rays to point or spot lights");
            } else {
                closest("shadow rays from the lights", &rays);
            }
        }
    }
}
