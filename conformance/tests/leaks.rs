//! The leak corpus ([`hyrt_conformance::leak`]) on both backends: no light sealed inside a
//! closed shell reaches anything outside it, over at least 10^6 shadow rays per scene, and
//! the GPU backend (lavapipe in CI) renders every leak scene bit-identical to the CPU, but
//! for the one documented deviation of its ray/triangle test: a shadow ray that meets an
//! exactly-zero f32 edge function, where the CPU decides in f64 and misses a silhouette
//! edge by less than a rounding and the GPU's tie rule hits
//! ([`hyrt_core::kernels::ray::meets_zero_edge_tie`]). Far from the origin coordinates
//! are coarse and such rays occur (a handful in 10^8); every differing ray must be one,
//! and every other difference must be a pixel of such a ray.
//! The light-outside scenes (expected lit and shadowed regions against an f64 reference)
//! are checked in `accuracy/tests/leaks.rs`, where the reference renderer lives.

use hyrt_conformance::compare::compare_stages;
use hyrt_conformance::leak::{count_leaks, leak_corpus, LeakCase, LightSide, MIN_SHADOW_RAYS};
use hyrt_conformance::report::{gpu_for_tests, render_case};
use hyrt_core::bvh::BvhPreset;
use hyrt_core::frame::{Backend, Frame, PreparedScene};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::ray::meets_zero_edge_tie;
use hyrt_core::stage::Stage;
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

/// Check that every difference between the CPU's and the GPU's frame is explained by the
/// GPU's documented tie rule; returns how many rays it changed, or the first difference
/// that it does not explain.
fn tie_rule_differences(prepared: &PreparedScene, cpu: &Frame, gpu: &Frame) -> Result<usize, String> {
    for cmp in compare_stages(cpu, gpu) {
        let downstream =
            matches!(cmp.stage, Stage::ShadowRays | Stage::RtShading | Stage::RasterShading | Stage::Composition);
        if !cmp.is_exact() && !downstream {
            return Err(format!("{} / {}: {cmp:?}", cmp.stage, cmp.buffer));
        }
    }
    let lights = prepared.geometry.lights.len();
    let mut pixels = std::collections::BTreeSet::new();
    let mut pairs = std::collections::BTreeSet::new();
    for (i, (&c, &g)) in cpu.occluded.iter().zip(&gpu.occluded).enumerate() {
        if c == g {
            continue;
        }
        let r = &cpu.rays[i];
        let (o, d) = (r.origin.into(), r.direction.into());
        let tie = prepared.geometry.triangles.iter().any(|t| {
            let [v0, v1, v2] = t.vertices();
            meets_zero_edge_tie(o, d, v0, v1, v2)
        });
        if !(c == 0 && g == 1 && tie) {
            return Err(format!("ray {i} ({r:?}): cpu {c}, gpu {g}, meets a zero edge: {tie}"));
        }
        pixels.insert(r.pixel as usize);
        pairs.insert(r.pixel as usize * lights + r.light as usize);
    }
    let differ = |a: &[[f32; 4]], b: &[[f32; 4]]| {
        a.iter()
            .zip(b)
            .enumerate()
            .filter(|(_, (x, y))| bytemuck::bytes_of(*x) != bytemuck::bytes_of(*y))
            .map(|(i, _)| i)
            .collect::<Vec<_>>()
    };
    for (name, a, b) in
        [("raster", &cpu.raster, &gpu.raster), ("rt", &cpu.rt, &gpu.rt), ("final", &cpu.final_image, &gpu.final_image)]
    {
        if let Some(p) = differ(a, b).into_iter().find(|p| !pixels.contains(p)) {
            return Err(format!("{name}: pixel {p} differs without a differing ray"));
        }
    }
    if let Some(k) = (0..cpu.shadow.len()).find(|&k| cpu.shadow[k] != gpu.shadow[k] && !pairs.contains(&k)) {
        return Err(format!("shadow: pair {k} differs without a differing ray"));
    }
    Ok(pairs.len())
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
    let (mut tie_rays, mut rays) = (0, 0);
    for side in [LightSide::Inside, LightSide::Outside] {
        for lc in leak_corpus(side) {
            let prepared = prepare(&cpu, &lc);
            let expected = render(&mut cpu, &prepared, &lc);
            let actual = render(&mut gpu, &prepared, &lc);
            rays += expected.rays.len();
            match tie_rule_differences(&prepared, &expected, &actual) {
                Ok(n) => tie_rays += n,
                Err(e) => differences.push(format!("{}: {e}", lc.case.name)),
            }
            if side == LightSide::Inside {
                failures.extend(leaks_of("gpu", &lc, &actual));
            }
        }
    }
    eprintln!("{tie_rays} of {rays} shadow rays differ, each by the GPU's documented tie rule");
    assert!(differences.is_empty(), "GPU differs from the CPU:\n{}", differences.join("\n"));
    // A handful in 10^8 (measured: 4 at 1e6 and in the far scene).
    assert!(tie_rays * 1_000_000 < rays, "{tie_rays} tie-rule rays of {rays}");
    assert!(failures.is_empty(), "light leaks out of closed shells:\n{}", failures.join("\n"));
}
