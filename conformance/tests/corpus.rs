//! The corpus on the GPU backend against the CPU reference, stage by stage
//! (lavapipe in CI), and determinism of each backend over the whole corpus.
//!
//! The report is written to `target/tmp/conformance/report.md` (with difference
//! images); a failing test prints every violation with its case, stage and pixel.

use hyrt_conformance::compare::compare_stages;
use hyrt_conformance::corpus::corpus;
use hyrt_conformance::report::{
    gpu_for_tests, known_deviations_path, missing_guarantees, render_case, render_pair, run_case, KnownDeviations,
    Report,
};
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, Executor, FrameOptions, PrimaryBarycentrics};
use hyrt_core::plan::FramePlan;
use hyrt_cpu::backend::CpuBackend;
use hyrt_gpu::band::band_binding_bytes;

#[test]
fn conformance_gpu_matches_cpu_on_every_stage_of_the_corpus() {
    let Some(mut gpu) = gpu_for_tests() else { return };
    let mut cpu = CpuBackend::new(Some(2));
    let candidate = format!("gpu: {}", gpu.describe());
    let missing_guarantees = missing_guarantees(gpu.context());
    let results = corpus().iter().map(|case| run_case(&mut cpu, &mut gpu, case)).collect();
    let report = Report { reference: "cpu, 2 threads".into(), candidate, missing_guarantees, results };
    let path = known_deviations_path();
    if std::env::var_os("HYRT_CONFORMANCE_BLESS").is_some() {
        std::fs::write(&path, KnownDeviations::from_report(&report).to_toml()).expect("write known deviations");
        eprintln!("wrote {}", path.display());
    }
    let known = KnownDeviations::load(&path).unwrap();
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("conformance");
    report.write(&dir, &known).expect("write the conformance report");
    eprintln!("{}\nreport: {}", report.summary_markdown(), dir.join("report.md").display());
    let (violations, improvements) = report.check(&known);
    for i in &improvements {
        eprintln!("better than recorded (tighten known_deviations.toml): {i}");
    }
    assert!(violations.is_empty(), "{} beyond the recorded deviations:\n{}", violations.len(), violations.join("\n"));
}

#[test]
fn determinism_cpu_same_bits_twice_and_on_1_or_2_threads_over_the_corpus() {
    let mut one = CpuBackend::new(Some(1));
    let mut two = CpuBackend::new(Some(2));
    for case in corpus() {
        let p1 = case.prepare(&one);
        let p2 = case.prepare(&two);
        assert_eq!(
            bytemuck::cast_slice::<_, u8>(&p1.bvh.nodes),
            bytemuck::cast_slice::<_, u8>(&p2.bvh.nodes),
            "{}: BVH build differs across thread counts",
            case.name
        );
        let (a, b) = render_pair(&mut one, &mut two, &p1, &case);
        let (a, b) = (a.unwrap(), b.unwrap());
        let c = render_case(&mut two, &p1, &case).unwrap();
        for (x, y, what) in [(&a, &b, "1 vs 2 threads"), (&b, &c, "run twice")] {
            for cmp in compare_stages(x, y) {
                assert!(cmp.is_exact(), "{}: {what}: {} / {} differs: {cmp:?}", case.name, cmp.stage, cmp.buffer);
            }
        }
    }
}

#[test]
fn determinism_gpu_same_bits_twice_over_the_corpus() {
    let Some(mut gpu) = gpu_for_tests() else { return };
    let cpu = CpuBackend::new(Some(2));
    for case in corpus() {
        let p = case.prepare(&cpu);
        let a = render_case(&mut gpu, &p, &case).unwrap();
        let b = render_case(&mut gpu, &p, &case).unwrap();
        for cmp in compare_stages(&a, &b) {
            assert!(cmp.is_exact(), "{}: gpu run twice: {} / {} differs: {cmp:?}", case.name, cmp.stage, cmp.buffer);
        }
    }
}

/// The raster's primary barycentrics (`PrimaryBarycentrics::Raster`, the option beside the
/// default re-intersected ones that the corpus runs above): every stage of every case,
/// bounces included, is the CPU's bit for bit here too.
#[test]
fn conformance_gpu_matches_cpu_with_raster_barycentrics_over_the_corpus() {
    let Some(mut gpu) = gpu_for_tests() else { return };
    let mut cpu = CpuBackend::new(Some(2));
    let mut moved = 0usize;
    for case in corpus() {
        let p = case.prepare(&cpu);
        let camera = CameraRecord::new(&case.camera, case.width, case.height);
        let opts = |barycentrics| FrameOptions { stage_outputs: true, barycentrics, ..case.options() };
        let a = cpu.render(&p, &camera, &opts(PrimaryBarycentrics::Raster)).unwrap();
        let b = gpu.render(&p, &camera, &opts(PrimaryBarycentrics::Raster)).unwrap();
        for cmp in compare_stages(&a, &b) {
            assert!(cmp.is_exact(), "{}: cpu vs gpu: {} / {} differs: {cmp:?}", case.name, cmp.stage, cmp.buffer);
        }
        let exact = cpu.render(&p, &camera, &opts(PrimaryBarycentrics::Reintersected)).unwrap();
        moved += a.surfaces.iter().zip(&exact.surfaces).filter(|(x, y)| x.position != y.position).count();
    }
    // Not the default frame under another name: hit points moved.
    assert!(moved > 10_000, "{moved} hit points moved");
}

/// Frames larger than the device's bindings render in bands of rows (`hyrt_gpu::band`):
/// here every case is forced into bands of about a quarter of its rows (bounce lists
/// that outgrow them split the band again), and every stage's buffers, merged from the
/// bands, are the whole frame's bit for bit, and so the CPU's. A denoised case's bands are
/// rendered with a halo of rows on each side (the denoiser's neighbours): bindings that
/// hold 8 rows and the halo's, so that band edges cross its penumbrae every 8 rows.
/// Own rows of the bands of the banded test's denoised cases.
const DENOISED_BAND_ROWS: u32 = 8;

#[test]
fn conformance_gpu_in_bands_is_the_whole_frame_over_the_corpus() {
    let Some(mut gpu) = gpu_for_tests() else { return };
    let cpu = CpuBackend::new(Some(2));
    let (mut banded, mut split) = (0, 0);
    for case in corpus() {
        let p = case.prepare(&cpu);
        gpu.set_max_band_bytes(None);
        let whole = render_case(&mut gpu, &p, &case).unwrap();
        assert_eq!(gpu.last_frame_bands(), 1, "{}: a corpus frame fits whole", case.name);
        let camera = CameraRecord::new(&case.camera, case.width, case.height);
        let plan = FramePlan::new(&p, &case.options()).unwrap();
        let rows = if case.denoise { DENOISED_BAND_ROWS } else { case.height.div_ceil(4) };
        let held = match case.denoise {
            true => hyrt_gpu::band::buffer_rows(rows, u32::MAX, hyrt_gpu::shadow_denoise::DENOISE_HALO),
            false => rows,
        };
        // Shadow-mask slots per surface: the lights, or more with area lights and occlusion.
        let lights = plan.lights();
        gpu.set_max_band_bytes(Some(band_binding_bytes((camera.width * held) as u64, lights, &plan)));
        let bands = render_case(&mut gpu, &p, &case).unwrap();
        let n = gpu.last_frame_bands();
        assert!(n >= case.height.div_ceil(rows), "{}: {n} bands of {rows} rows", case.name);
        banded += (n > 1) as u32;
        split += (n > case.height.div_ceil(rows)) as u32;
        for cmp in compare_stages(&whole, &bands) {
            assert!(
                cmp.is_exact(),
                "{}: whole vs {n} bands: {} / {} differs: {cmp:?}",
                case.name,
                cmp.stage,
                cmp.buffer
            );
        }
        assert_eq!(whole.stats.rays_per_kind, bands.stats.rays_per_kind, "{}", case.name);
        assert_eq!(whole.stats.bounces, bands.stats.bounces, "{}", case.name);
        assert_eq!(whole.stats.covered_pixels, bands.stats.covered_pixels, "{}", case.name);
    }
    eprintln!("{banded} cases in bands, {split} of them split for their bounce lists");
    assert!(banded > 20 && split > 0, "{banded} banded, {split} split");
}

/// A staged CPU frame that does not return its shadow-ray lists (the primary hits' and each
/// bounce depth's) does not write them (`compaction` keeps the active pairs, `shadow_rays`
/// makes each ray as it traces it): its image and statistics (rays per kind and occluded
/// rays of every depth) are the frame's that writes the lists, on every case of the corpus.
/// (The fused frame against the staged one: `tests/fused.rs`.)
#[test]
fn cpu_frames_without_the_ray_list_are_the_frames_with_it_over_the_corpus() {
    let mut cpu = CpuBackend::new(Some(2));
    cpu.set_executor(Executor::Staged);
    for case in corpus() {
        let p = case.prepare(&cpu);
        let camera = CameraRecord::new(&case.camera, case.width, case.height);
        let opts = |stage_outputs| FrameOptions { stage_outputs, ..case.options() };
        let (with, without) =
            (cpu.render(&p, &camera, &opts(true)).unwrap(), cpu.render(&p, &camera, &opts(false)).unwrap());
        // A display frame holds the final image alone.
        assert!(without.rays.is_empty() && without.occluded.is_empty() && without.shadow.is_empty(), "{}", case.name);
        assert!(without.gbuffer.is_empty(), "{}: no G-buffer unless asked", case.name);
        let bits = |v: &[[f32; 4]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&with.final_image), bits(&without.final_image), "{}: final image", case.name);
        assert_eq!(with.stats.rays_per_kind, without.stats.rays_per_kind, "{}", case.name);
        assert_eq!(with.stats.occluded_shadow_rays, without.stats.occluded_shadow_rays, "{}", case.name);
        assert_eq!(with.stats.bounces, without.stats.bounces, "{}", case.name);
    }
}
