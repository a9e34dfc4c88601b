//! The leak corpus ([`hyrt_conformance::leak`]) on both backends: no light sealed inside a
//! closed shell reaches anything outside it, over at least 10^6 shadow rays per scene, and
//! the GPU backend (lavapipe in CI) renders every leak scene bit-identical to the CPU,
//! also the shadow rays that meet an exactly-zero f32 edge function, which both backends
//! decide by the same exact sign ([`hyrt_core::kernels::ray::edge_sign_exact`]). Far from
//! the origin coordinates are coarse and such rays occur (a handful in 10^8, which the
//! GPU decided differently before the exact sign).
//! The light-outside scenes (expected lit and shadowed regions against an f64 reference)
//! are checked in `accuracy/tests/leaks.rs`, where the reference renderer lives.

use hyrt_conformance::compare::compare_stages;
use hyrt_conformance::leak::{count_leaks, leak_corpus, LeakCase, LightSide, MIN_SHADOW_RAYS};
use hyrt_conformance::report::{gpu_for_tests, render_case};
use hyrt_core::bvh::BvhPreset;
use hyrt_core::frame::{Backend, Frame, PreparedScene};
use hyrt_core::geometry::WorldGeometry;
use hyrt_cpu::backend::CpuBackend;

fn prepare(cpu: &CpuBackend, lc: &LeakCase) -> PreparedScene {
    cpu.prepare(WorldGeometry::build(&lc.case.scene), BvhPreset::default())
}

fn render(backend: &mut dyn Backend, prepared: &PreparedScene, lc: &LeakCase) -> Frame {
    render_case(backend, prepared, &lc.case).unwrap_or_else(|e| panic!("{}: {e}", lc.case.name))
}

/// The leaks of one light-inside frame, as a failure line.
fn leaks_of(backend_name: &str, lc: &LeakCase, frame: &Frame) -> Option<String> {
    let c = count_leaks(frame);
    eprintln!("{backend_name}: {}: {c:?}", lc.case.name);
    assert!(c.shadow_rays >= MIN_SHADOW_RAYS, "{}: only {} shadow rays", lc.case.name, c.shadow_rays);
    assert_eq!(c.occluded + c.lit_pairs, c.shadow_rays, "{}: every ray has a result", lc.case.name);
    (c.lit_pairs != 0).then(|| {
        format!(
            "{backend_name}: {}: {} lit (pixel, light) pairs outside the shell ({} floor pixels, {} on the shell)",
            lc.case.name, c.lit_pairs, c.lit_floor_pixels, c.lit_shell_pixels
        )
    })
}

/// The first buffer in which the GPU's frame differs from the CPU's, if any.
fn first_difference(cpu: &Frame, gpu: &Frame) -> Option<String> {
    compare_stages(cpu, gpu).into_iter().find(|c| !c.is_exact()).map(|c| format!("{} / {}: {c:?}", c.stage, c.buffer))
}

#[test]
fn leak_corpus_cpu_no_light_escapes_a_closed_shell() {
    let mut cpu = CpuBackend::new(Some(2));
    let cases = leak_corpus(LightSide::Inside);
    assert!(cases.len() >= 42, "{} cases", cases.len());
    let mut failures = Vec::new();
    for lc in &cases {
        let prepared = prepare(&cpu, lc);
        let frame = render(&mut cpu, &prepared, lc);
        failures.extend(leaks_of("cpu", lc, &frame));
    }
    assert!(failures.is_empty(), "light leaks out of closed shells:\n{}", failures.join("\n"));
}

#[test]
fn leak_corpus_gpu_matches_cpu_and_no_light_escapes_a_closed_shell() {
    let Some(mut gpu) = gpu_for_tests() else { return };
    let mut cpu = CpuBackend::new(Some(2));
    let mut differences = Vec::new();
    let mut failures = Vec::new();
    let mut rays = 0;
    for side in [LightSide::Inside, LightSide::Outside] {
        for lc in leak_corpus(side) {
            let prepared = prepare(&cpu, &lc);
            let expected = render(&mut cpu, &prepared, &lc);
            let actual = render(&mut gpu, &prepared, &lc);
            rays += expected.rays.len();
            if let Some(e) = first_difference(&expected, &actual) {
                differences.push(format!("{}: {e}", lc.case.name));
            }
            if side == LightSide::Inside {
                failures.extend(leaks_of("gpu", &lc, &actual));
            }
        }
    }
    eprintln!("{rays} shadow rays, every one bit-identical");
    assert!(differences.is_empty(), "GPU differs from the CPU:\n{}", differences.join("\n"));
    assert!(failures.is_empty(), "light leaks out of closed shells:\n{}", failures.join("\n"));
}
