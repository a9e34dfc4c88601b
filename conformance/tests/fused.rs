//! The CPU backend's two executors over the corpus: the fused, tiled frame
//! (`hyrt_cpu::fused`) gives the staged frame's G-buffer, final image and statistics bit
//! for bit, on every case, at every SIMD level this CPU has, on 1, 2 and 3 threads, with
//! the raster's and with re-intersected barycentrics; and a frame that does not ask for its
//! G-buffer (`FrameOptions::keep_gbuffer`, which the fused frame then keeps in its raster
//! tiles' scratch alone) has none and the same final image and statistics.
//!
//! One test in its own binary: forcing the SIMD level is process-wide.

use hyrt_conformance::corpus::{corpus, Case};
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, Executor, Frame, FrameOptions, PreparedScene, PrimaryBarycentrics};
use hyrt_cpu::backend::CpuBackend;
use hyrt_cpu::traversal::{force_simd_level, SimdLevel, Traversal};

fn render(cpu: &mut CpuBackend, p: &PreparedScene, case: &Case, opts: &FrameOptions) -> Frame {
    let camera = CameraRecord::new(&case.camera, case.width, case.height);
    cpu.render(p, &camera, opts).unwrap_or_else(|e| panic!("{}: {e}", case.name))
}

/// Everything a display frame returns, as bits: the G-buffer, the final image, and the
/// statistics both executors count (not the times, not the executor).
fn returned(f: &Frame) -> (Vec<u8>, Vec<u32>, [u64; 4], Vec<u64>) {
    let s = &f.stats;
    let counts = [s.covered_pixels, s.ray_traced_pixels, s.raster_pixels, s.occluded_shadow_rays];
    (
        bytemuck::cast_slice(&f.gbuffer).to_vec(),
        f.final_image.iter().flatten().map(|x| x.to_bits()).collect(),
        counts,
        s.rays_per_kind.to_vec(),
    )
}

#[test]
fn fused_frames_are_the_staged_frames_over_the_corpus() {
    let mut staged = CpuBackend::new(Some(2));
    staged.set_executor(Executor::Staged);
    let mut fused: Vec<CpuBackend> = [1, 2, 3].map(|n| CpuBackend::new(Some(n))).into();
    let levels = SimdLevel::available();
    let mut compared = 0;
    for case in corpus() {
        let p = case.prepare(&staged);
        for barycentrics in [PrimaryBarycentrics::Raster, PrimaryBarycentrics::Reintersected] {
            // The case's own depth and none: a bounce case runs staged with its bounces,
            // fused without them.
            for max_depth in [case.max_depth, 0] {
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
                            let runs_fused = cpu.executor_for(&f.plan, &opts) == Executor::Fused;
                            assert_eq!(f.stats.executor, if runs_fused { Executor::Fused } else { Executor::Staged });
                            assert_eq!(
                                runs_fused,
                                f.plan.bounce_depth() == 0,
                                "{}: only bounces run staged",
                                case.name
                            );
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
                            compared += runs_fused as usize;
                        }
                    }
                }
            }
        }
    }
    force_simd_level(None).unwrap();
    assert!(compared > 0);
    eprintln!("{compared} fused frames equal to their staged frames ({} SIMD levels)", levels.len());
}
