//! The CPU backend's two executors over the corpus: the fused, tiled frame
//! (`hyrt_cpu::fused`) gives the staged frame's G-buffer, final image and statistics bit
//! for bit, on every case, at every SIMD level this CPU has, on 1, 2 and 3 threads, with
//! the raster's and with re-intersected barycentrics; and a frame that does not ask for its
//! G-buffer (`FrameOptions::keep_gbuffer`, which the fused frame then keeps in its raster
//! tiles' scratch alone) has none and the same final image and statistics. Frames that
//! trace bounces run fused too (the tiles defer their bouncing pixels), at the case's depth
//! and at depths 1 and 2, with every bounce depth's counts equal. Frames with stochastic
//! shadow rays (the corpus' `stochastic_*` cases: area lights, ambient occlusion) run
//! staged whatever the executor, so they are compared elsewhere (`tests/corpus.rs`).
//!
//! Tests that force the SIMD level run one at a time (it is process-wide).

use glam::Vec3;
use hyrt_conformance::corpus::{corpus, Case};
use hyrt_core::formats::{CameraRecord, RAY_KIND_REFLECTION, RAY_KIND_REFRACTION};
use hyrt_core::frame::{Backend, BounceStats, Executor, Frame, FrameOptions, PreparedScene, PrimaryBarycentrics};
use hyrt_core::plan::FramePlan;
use hyrt_cpu::backend::CpuBackend;
use hyrt_cpu::traversal::{force_simd_level, SimdLevel, Traversal};

fn render(cpu: &mut CpuBackend, p: &PreparedScene, case: &Case, opts: &FrameOptions) -> Frame {
    let camera = CameraRecord::new(&case.camera, case.width, case.height);
    cpu.render(p, &camera, opts).unwrap_or_else(|e| panic!("{}: {e}", case.name))
}

/// The G-buffer's bytes, the final image's bits, the primary counts, the rays per kind and
/// the bounce statistics.
type Returned = (Vec<u8>, Vec<u32>, [u64; 4], Vec<u64>, Vec<BounceStats>);

/// Everything a display frame returns, as bits: the G-buffer, the final image, and the
/// statistics both executors count (not the times, not the executor): the primary hits'
/// and every bounce depth's.
fn returned(f: &Frame) -> Returned {
    let s = &f.stats;
    let counts = [s.covered_pixels, s.ray_traced_pixels, s.raster_pixels, s.occluded_shadow_rays];
    (
        bytemuck::cast_slice(&f.gbuffer).to_vec(),
        f.final_image.iter().flatten().map(|x| x.to_bits()).collect(),
        counts,
        s.rays_per_kind.to_vec(),
        s.bounces.clone(),
    )
}

/// The SIMD level is process-wide: one test forces it at a time.
static SIMD_LEVEL: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// A staged backend of 2 threads (the reference) and fused ones of 1, 2 and 3 threads.
fn backends() -> (CpuBackend, Vec<CpuBackend>) {
    let mut staged = CpuBackend::new(Some(2));
    staged.set_executor(Executor::Staged);
    (staged, [1, 2, 3].map(|n| CpuBackend::new(Some(n))).into())
}

#[test]
fn fused_frames_are_the_staged_frames_over_the_corpus() {
    let _simd = SIMD_LEVEL.lock().unwrap_or_else(|e| e.into_inner());
    let (mut staged, mut fused) = backends();
    let levels = SimdLevel::available();
    let (mut compared, mut bouncing) = (0, 0);
    // Stochastic frames run staged (`CpuBackend::executor_for`): no fused frame to compare.
    for case in corpus().into_iter().filter(|c| !c.stochastic()) {
        let p = case.prepare(&staged);
        // The case's own depth and none; a case whose plan traces bounces also at depths
        // 1 and 2 (the deepest bounce shades without children).
        let depth = FramePlan::new(&p, &FrameOptions { max_depth: case.max_depth, ..FrameOptions::default() })
            .expect("a plan")
            .bounce_depth();
        let depths = match depth {
            0 => vec![case.max_depth],
            _ => vec![case.max_depth, 1, 2, 0],
        };
        for barycentrics in [PrimaryBarycentrics::Raster, PrimaryBarycentrics::Reintersected] {
            for &max_depth in &depths {
                let opts = FrameOptions {
                    weight: case.weight,
                    max_depth,
                    barycentrics,
                    keep_gbuffer: true,
                    ..FrameOptions::default()
                };
                force_simd_level(None).unwrap();
                let want = render(&mut staged, &p, &case, &opts);
                assert_eq!(want.stats.executor, Executor::Staged);
                let want = returned(&want);
                for &level in &levels {
                    force_simd_level(Some(level)).unwrap();
                    for cpu in &mut fused {
                        // The traversal's level is the backend's setting; the raster's is
                        // detected per frame.
                        cpu.set_shadow_traversal(Traversal::simd());
                        for keep_gbuffer in [true, false] {
                            let opts = FrameOptions { keep_gbuffer, ..opts };
                            let f = render(cpu, &p, &case, &opts);
                            assert_eq!(cpu.executor_for(&f.plan, &opts), Executor::Fused, "{}", case.name);
                            assert_eq!(f.stats.executor, Executor::Fused, "{}: a display frame runs fused", case.name);
                            let got = returned(&f);
                            let what = format!(
                                "{}: {} barycentrics, max depth {max_depth}, {level:?}, {} threads, {}, G-buffer kept: {keep_gbuffer}",
                                case.name,
                                barycentrics.name(),
                                cpu.threads(),
                                f.stats.executor.name()
                            );
                            match keep_gbuffer {
                                true => assert!(got.0 == want.0, "{what}: G-buffer differs"),
                                false => assert!(got.0.is_empty(), "{what}: a G-buffer not asked for"),
                            }
                            assert!(got.1 == want.1, "{what}: final image differs");
                            assert_eq!(got.2, want.2, "{what}: covered, ray-traced, raster pixels, occluded rays");
                            assert_eq!(got.3, want.3, "{what}: rays per kind");
                            assert_eq!(got.4, want.4, "{what}: per bounce depth: rays, hits, occluded rays");
                            compared += 1;
                            bouncing += (f.plan.bounce_depth() > 0) as usize;
                        }
                    }
                }
            }
        }
    }
    force_simd_level(None).unwrap();
    assert!(bouncing > 0, "no corpus frame traced bounces");
    eprintln!(
        "{compared} fused frames ({bouncing} with bounces) equal to their staged frames ({} SIMD levels)",
        levels.len()
    );
}

/// Bouncing pixels across many raster tiles and fused tiles (the corpus's images are one
/// raster tile wide): bounce cases at 200 x 150 (tiles of 64 and 32 pixels, cut at the
/// image's right and bottom edges), and turned away from every mirror and glass object (a
/// plan with bounces where no pixel bounces): the fused frame is the staged frame, at 1, 2
/// and 3 threads, at every SIMD level.
#[test]
fn fused_bounces_across_tiles_and_without_bouncing_pixels() {
    let _simd = SIMD_LEVEL.lock().unwrap_or_else(|e| e.into_inner());
    let (mut staged, mut fused) = backends();
    let named = |name: &str| corpus().into_iter().find(|c| c.name == name).unwrap_or_else(|| panic!("no case {name}"));
    let mut cases = Vec::new();
    for name in ["bounce_parallel_mirrors", "bounce_glass_inside_glass"] {
        cases.push(Case { width: 200, height: 150, ..named(name) });
    }
    // The parallel mirrors seen from above, looking straight down at the floor between
    // them: the mirrors stand outside the view.
    let mut away = Case { width: 200, height: 150, ..named("bounce_parallel_mirrors") };
    away.camera.eye = Vec3::new(0.0, 2.0, 3.0);
    away.camera.target = Vec3::new(0.0, 0.0, 3.001);
    away.camera.up = Vec3::Z;
    cases.push(away);
    let mut spawned = Vec::new();
    for case in &cases {
        let p = case.prepare(&staged);
        let opts = FrameOptions { weight: case.weight, max_depth: case.max_depth, ..FrameOptions::default() };
        force_simd_level(None).unwrap();
        let want = render(&mut staged, &p, case, &opts);
        assert!(want.plan.bounce_depth() > 0, "{}: a plan with bounces", case.name);
        // The rays of depth 1: none where no pixel bounces (the tiles defer none).
        let first = &want.stats.bounces[0].rays_per_kind;
        spawned.push(first[RAY_KIND_REFLECTION as usize] + first[RAY_KIND_REFRACTION as usize]);
        let want = returned(&want);
        for level in SimdLevel::available() {
            force_simd_level(Some(level)).unwrap();
            for cpu in &mut fused {
                let f = render(cpu, &p, case, &opts);
                assert_eq!(f.stats.executor, Executor::Fused);
                let what =
                    format!("{} at {}x{}, {level:?}, {} threads", case.name, case.width, case.height, cpu.threads());
                let got = returned(&f);
                assert!(got.1 == want.1, "{what}: final image differs");
                assert_eq!(got.2, want.2, "{what}: covered, ray-traced, raster pixels, occluded rays");
                assert_eq!(got.3, want.3, "{what}: rays per kind");
                assert_eq!(got.4, want.4, "{what}: per bounce depth");
            }
        }
    }
    force_simd_level(None).unwrap();
    assert!(spawned[0] > 0 && spawned[1] > 0, "the bounce cases bounce: {spawned:?}");
    assert_eq!(spawned[2], 0, "turned away, no pixel bounces: {spawned:?}");
}
