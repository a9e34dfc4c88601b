//! Running the corpus on two backends and writing the report.
//!
//! [`run_case`] renders one [`Case`] on a reference and a candidate backend and
//! compares every stage ([`crate::compare::compare_stages`]); [`check`] holds the
//! result against the recorded [`KnownDeviations`] (whose causes are [`CAUSES`]); [`Report`] writes `report.md` (a summary
//! per stage, then per case and stage: mismatching elements, the ulp histogram, the
//! worst case with its pixel and values) and difference images for every per-pixel
//! buffer that differs.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, Frame, FrameOptions, PreparedScene};
use hyrt_core::stage::Stage;
use hyrt_cpu::backend::CpuBackend;

use crate::compare::{compare_stages, ulp_bucket, ulp_bucket_label, BufferComparison, ULP_BUCKETS};
use crate::corpus::Case;

/// Why a buffer of the GPU backend on lavapipe differs from the CPU reference today.
/// The target is exact agreement; each entry names a cause the crate docs explain.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cause {
    pub stage: Stage,
    pub buffer: &'static str,
    /// Why integer words differ (empty: they must not).
    pub integers: &'static str,
    /// Why float words differ (empty: they must not).
    pub floats: &'static str,
}

/// The cause of each buffer's differences (see [`Cause`]). Today every stage of the GPU
/// backend on lavapipe is bit-identical to the reference on the whole corpus, so no
/// cause is recorded: a deviation that appears (another driver, a change) must name its
/// cause here and in `known_deviations.toml`.
pub const CAUSES: [Cause; 8] = [
    Cause { stage: Stage::VisibilityRaster, buffer: "gbuffer", integers: "", floats: "" },
    Cause { stage: Stage::Reconstruction, buffer: "surfaces", integers: "", floats: "" },
    Cause { stage: Stage::Compaction, buffer: "rays", integers: "", floats: "" },
    Cause { stage: Stage::ShadowRays, buffer: "occluded", integers: "", floats: "" },
    Cause { stage: Stage::ShadowRays, buffer: "shadow", integers: "", floats: "" },
    Cause { stage: Stage::RtShading, buffer: "rt", integers: "", floats: "" },
    Cause { stage: Stage::RasterShading, buffer: "raster", integers: "", floats: "" },
    Cause { stage: Stage::Composition, buffer: "final", integers: "", floats: "" },
];

/// The cause of a buffer's differences.
pub fn cause(buffer: &str) -> Option<&'static Cause> {
    CAUSES.iter().find(|c| c.buffer == buffer)
}

/// The recorded deviations of today's GPU backend on lavapipe from the reference, per
/// case and buffer (`known_deviations.toml` in this crate): a ratchet. A run may show
/// fewer differences than recorded (the report lists the improvements, to tighten the
/// file) but never more; a case or buffer that is not listed must be exact.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KnownDeviations {
    #[serde(default, rename = "deviation")]
    pub deviations: Vec<Deviation>,
}

/// One recorded deviation (see [`KnownDeviations`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Deviation {
    pub case: String,
    pub buffer: String,
    /// Most elements with differing integer words.
    pub int_mismatches: usize,
    /// Largest float ulp distance.
    pub max_ulp: u64,
}

/// Where the recorded deviations live.
pub fn known_deviations_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("known_deviations.toml")
}

impl KnownDeviations {
    /// Read the recorded deviations.
    pub fn load(path: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        toml::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// The deviations a report shows.
    pub fn from_report(report: &Report) -> Self {
        let mut deviations = Vec::new();
        for r in &report.results {
            let Ok(cs) = &r.outcome else { continue };
            for c in cs.iter().filter(|c| !c.is_exact()) {
                deviations.push(Deviation {
                    case: r.name.clone(),
                    buffer: c.buffer.clone(),
                    int_mismatches: c.int_mismatches,
                    max_ulp: c.max_ulp(),
                });
            }
        }
        KnownDeviations { deviations }
    }

    /// The file's text: a header, then one table per deviation.
    pub fn to_toml(&self) -> String {
        let mut s = String::from(
            "# Recorded deviations of the GPU backend on Mesa lavapipe from the CPU reference, per corpus case\n\
             # and stage buffer: a ratchet (hyrt_conformance::report::KnownDeviations). Causes: the crate docs\n\
             # and hyrt_conformance::report::CAUSES. Regenerate after an improvement with\n\
             #   HYRT_CONFORMANCE_BLESS=1 cargo test -p hyrt-conformance --test corpus\n\n",
        );
        s += &toml::to_string(self).expect("deviations serialize");
        s
    }

    fn get(&self, case: &str, buffer: &str) -> Option<&Deviation> {
        self.deviations.iter().find(|d| d.case == case && d.buffer == buffer)
    }
}

/// One case run on both backends.
#[derive(Clone, Debug)]
pub struct CaseResult {
    pub name: String,
    pub stresses: &'static str,
    pub width: u32,
    pub height: u32,
    pub triangles: usize,
    /// Shadow rays of the reference frame.
    pub rays: usize,
    /// Every stage's comparison, or why the case could not run.
    pub outcome: Result<Vec<BufferComparison>, String>,
}

/// How a case compares with the recorded deviations: one line per violation (more
/// differences than recorded, naming the case, stage, buffer and the first or worst
/// element), and one per improvement (fewer than recorded).
pub fn check(r: &CaseResult, known: &KnownDeviations) -> (Vec<String>, Vec<String>) {
    let comps = match &r.outcome {
        Ok(c) => c,
        Err(e) => return (vec![format!("{}: did not run: {e}", r.name)], Vec::new()),
    };
    let (mut violations, mut improvements) = (Vec::new(), Vec::new());
    for c in comps {
        let rec = known.get(&r.name, &c.buffer);
        let (max_int, max_ulp) = rec.map_or((0, 0), |d| (d.int_mismatches, d.max_ulp));
        if c.int_mismatches > max_int {
            violations.push(format!(
                "{} / {} / {}: {} of {} elements differ in integer words (recorded: {max_int}); first: {}",
                r.name,
                c.stage,
                c.buffer,
                c.int_mismatches,
                c.elements,
                c.first_int.as_ref().map(|d| d.to_string()).unwrap_or_default()
            ));
        }
        if c.max_ulp() > max_ulp {
            violations.push(format!(
                "{} / {} / {}: {} float words differ, worst {} ulp (recorded: {max_ulp}): {}",
                r.name,
                c.stage,
                c.buffer,
                c.float_mismatches(),
                c.max_ulp(),
                c.worst.as_ref().map(|d| d.to_string()).unwrap_or_default()
            ));
        }
        if rec.is_some() && (c.int_mismatches < max_int || c.max_ulp() < max_ulp) {
            improvements.push(format!(
                "{} / {}: {} integer mismatches (recorded {max_int}), worst {} ulp (recorded {max_ulp})",
                r.name,
                c.buffer,
                c.int_mismatches,
                c.max_ulp()
            ));
        }
    }
    (violations, improvements)
}

/// Render `case` on both backends (same prepared scene, camera and options) and compare.
/// The reference also prepares the scene (`bvh_build` runs once, on the CPU), with the
/// case's moving objects in a two-level BVH when it has some.
pub fn run_case(reference: &mut CpuBackend, candidate: &mut dyn Backend, case: &Case) -> CaseResult {
    let prepared = case.prepare(reference);
    let (a, b) = render_pair(reference, candidate, &prepared, case);
    let outcome = match (a, b) {
        (Ok(a), Ok(b)) => Ok((compare_stages(&a, &b), a.rays.len())),
        (Err(e), _) => Err(format!("reference: {e}")),
        (_, Err(e)) => Err(format!("{}: {e}", candidate.name())),
    };
    let rays = outcome.as_ref().map_or(0, |(_, n)| *n);
    CaseResult {
        name: case.name.clone(),
        stresses: case.stresses,
        width: case.width,
        height: case.height,
        triangles: prepared.geometry.triangle_count(),
        rays,
        outcome: outcome.map(|(c, _)| c),
    }
}

/// Render a case on one backend with every stage output ([`Case::options`]: denoised
/// where the case says so).
pub fn render_case(backend: &mut dyn Backend, prepared: &PreparedScene, case: &Case) -> Result<Frame, String> {
    let camera = CameraRecord::new(&case.camera, case.width, case.height);
    let opts = FrameOptions { stage_outputs: true, ..case.options() };
    backend.render(prepared, &camera, &opts).map_err(|e| e.to_string())
}

/// What [`Report::missing_guarantees`] holds for a GPU candidate on `ctx`: the guarantees
/// its float probe found missing, or the probe's failure.
pub fn missing_guarantees(ctx: &hyrt_gpu::GpuContext) -> Vec<String> {
    match ctx.float_probe() {
        Ok(probe) => probe.missing().into_iter().map(String::from).collect(),
        Err(e) => vec![format!("float probe failed: {e}")],
    }
}

/// The GPU backend for the conformance tests (software adapters allowed: lavapipe in CI).
/// Without an adapter it panics when `CI` is set (CI installs lavapipe: a GPU test must
/// fail there rather than skip) and otherwise says SKIPPED and returns `None`. Any other
/// failure to start (a shader that does not compile, a validation error) is a bug and
/// panics everywhere: it must not pass for a missing adapter.
pub fn gpu_for_tests() -> Option<hyrt_gpu::backend::GpuBackend> {
    gpu_for_tests_with(None)
}

/// As [`gpu_for_tests`], on a device whose storage bindings hold at most `binding_limit`
/// bytes where given ([`hyrt_gpu::GpuContext::with_binding_limit`]).
pub fn gpu_for_tests_with(binding_limit: Option<u64>) -> Option<hyrt_gpu::backend::GpuBackend> {
    use hyrt_core::GpuError;
    let policy = hyrt_gpu::AdapterPolicy::AllowSoftware;
    let backend = match binding_limit {
        None => hyrt_gpu::backend::GpuBackend::new(policy),
        Some(bytes) => hyrt_gpu::GpuContext::with_binding_limit(policy, bytes)
            .and_then(hyrt_gpu::backend::GpuBackend::with_context),
    };
    match backend {
        Ok(g) => Some(g),
        Err(e) if std::env::var_os("CI").is_some() => panic!("CI needs a GPU adapter (lavapipe): {e}"),
        Err(e @ (GpuError::NoAdapter | GpuError::SoftwareOnly { .. } | GpuError::RequestDevice { .. })) => {
            eprintln!("SKIPPED: no GPU adapter: {e}");
            None
        }
        Err(e) => panic!("the GPU backend does not start: {e}"),
    }
}

/// Render a case on two backends with every stage output.
pub fn render_pair(
    a: &mut dyn Backend,
    b: &mut dyn Backend,
    prepared: &PreparedScene,
    case: &Case,
) -> (Result<Frame, String>, Result<Frame, String>) {
    (render_case(a, prepared, case), render_case(b, prepared, case))
}

/// The results of a corpus run, with the names of what was compared.
#[derive(Clone, Debug)]
pub struct Report {
    /// The reference backend ("cpu, 2 threads").
    pub reference: String,
    /// The candidate backend (the GPU adapter, or "cpu, 1 thread" for determinism runs).
    pub candidate: String,
    /// The guarantees the candidate's float probe found missing
    /// (`hyrt_gpu::exact::FloatProbe::missing`, or the probe's failure); empty when they
    /// are met or the candidate is no GPU. Every difference is recorded against them: a
    /// device without them still renders, and its report says under which missing
    /// guarantees each stage differs ([`Report::summary_markdown`], [`Report::check`]).
    pub missing_guarantees: Vec<String>,
    pub results: Vec<CaseResult>,
}

/// Buffer names in stage order.
const BUFFERS: [&str; 8] = ["gbuffer", "surfaces", "rays", "occluded", "shadow", "rt", "raster", "final"];

impl Report {
    /// Every violation of the recorded deviations, and every improvement on them.
    ///
    /// On a candidate with missing guarantees each violation names them.
    pub fn check(&self, known: &KnownDeviations) -> (Vec<String>, Vec<String>) {
        let (mut v, mut i) = (Vec::new(), Vec::new());
        let attribution = self.attribution();
        for r in &self.results {
            let (a, b) = check(r, known);
            v.extend(a.into_iter().map(|a| match &attribution {
                Some(m) => format!("{a} [{m}]"),
                None => a,
            }));
            i.extend(b);
        }
        (v, i)
    }

    /// "the float probe found missing: ..." where the candidate lacks guarantees.
    pub fn attribution(&self) -> Option<String> {
        (!self.missing_guarantees.is_empty())
            .then(|| format!("the float probe found missing: {}", self.missing_guarantees.join(", ")))
    }

    fn comparisons<'a>(&'a self, buffer: &'a str) -> impl Iterator<Item = (&'a CaseResult, &'a BufferComparison)> + 'a {
        self.results
            .iter()
            .filter_map(|r| r.outcome.as_ref().ok().map(|c| (r, c)))
            .flat_map(move |(r, cs)| cs.iter().filter(move |c| c.buffer == buffer).map(move |c| (r, c)))
    }

    /// The summary table: per stage buffer, cases, elements, integer mismatches, float
    /// words that differ, the worst ulp (and where).
    pub fn summary_markdown(&self) -> String {
        let mut s = String::new();
        let ran = self.results.iter().filter(|r| r.outcome.is_ok()).count();
        let _ = writeln!(
            s,
            "Reference: {}. Candidate: {}. Cases: {} ({} ran).\n",
            self.reference,
            self.candidate,
            self.results.len(),
            ran
        );
        if let Some(m) = self.attribution() {
            let _ = writeln!(
                s,
                "The candidate lacks guarantees bit-identity relies on ({m}): the differences of every stage are \
                 recorded against them in the last column.\n"
            );
        }
        let _ = writeln!(
            s,
            "| stage | buffer | elements | integer mismatches | cases with integer mismatches | float words differing | worst ulp | worst case | missing guarantees (float probe) |"
        );
        let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|---|---|");
        for buffer in BUFFERS {
            let (mut elements, mut ints, mut floats, mut worst) = (0usize, 0usize, 0u64, (0u64, String::new()));
            let mut int_cases = 0;
            let mut stage = None;
            for (r, c) in self.comparisons(buffer) {
                stage = Some(c.stage);
                elements += c.elements;
                ints += c.int_mismatches;
                int_cases += usize::from(c.int_mismatches > 0);
                floats += c.float_mismatches();
                if c.max_ulp() > worst.0 {
                    worst = (c.max_ulp(), format!("{}: {}", r.name, c.worst.as_ref().unwrap()));
                }
            }
            let Some(stage) = stage else { continue };
            let missing = if ints == 0 && floats == 0 {
                "-".to_string()
            } else if self.missing_guarantees.is_empty() {
                "none".to_string()
            } else {
                self.missing_guarantees.join(", ")
            };
            let _ = writeln!(
                s,
                "| {stage} | {buffer} | {elements} | {ints} | {int_cases} | {floats} | {} | {} | {missing} |",
                worst.0,
                if worst.1.is_empty() { "-".into() } else { worst.1.replace('|', "/") }
            );
        }
        s
    }

    /// The ulp histogram per buffer, over all cases (buckets with counts only).
    pub fn histogram_markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "| buffer | float words | ulp histogram (bucket: count) |");
        let _ = writeln!(s, "|---|---:|---|");
        for buffer in BUFFERS {
            let mut hist = [0u64; ULP_BUCKETS];
            let mut words = 0;
            for (_, c) in self.comparisons(buffer) {
                words += c.float_words;
                for (h, x) in hist.iter_mut().zip(c.ulp_histogram) {
                    *h += x;
                }
            }
            if words == 0 {
                continue;
            }
            let cells: Vec<String> = hist
                .iter()
                .enumerate()
                .filter(|(_, &n)| n > 0)
                .map(|(b, n)| format!("{}: {n}", ulp_bucket_label(b)))
                .collect();
            let _ = writeln!(s, "| {buffer} | {words} | {} |", cells.join(", "));
        }
        s
    }

    /// The whole report as Markdown, checked against `known`.
    pub fn markdown(&self, known: &KnownDeviations) -> String {
        let mut s = String::from("# hyrt conformance report\n\n## Summary\n\n");
        s += &self.summary_markdown();
        s += "\n## Ulp histograms (all cases)\n\n";
        s += &self.histogram_markdown();
        s += "\n## Causes of the differences\n\n| stage | buffer | integer words | float words |\n|---|---|---|---|\n";
        for c in CAUSES {
            let or_none = |t: &str| if t.is_empty() { "must be identical".to_string() } else { t.to_string() };
            let _ = writeln!(s, "| {} | {} | {} | {} |", c.stage, c.buffer, or_none(c.integers), or_none(c.floats));
        }
        let (violations, improvements) = self.check(known);
        s += &format!("\n## Beyond the recorded deviations: {}\n\n", violations.len());
        for v in &violations {
            let _ = writeln!(s, "- {v}");
        }
        s += &format!("\n## Better than recorded: {}\n\n", improvements.len());
        for v in &improvements {
            let _ = writeln!(s, "- {v}");
        }
        s += "\n## Cases\n";
        for r in &self.results {
            let _ = writeln!(
                s,
                "\n### {}\n\n{} ({}x{}, {} triangles, {} shadow rays)\n",
                r.name, r.stresses, r.width, r.height, r.triangles, r.rays
            );
            match &r.outcome {
                Err(e) => {
                    let _ = writeln!(s, "Did not run: {e}");
                }
                Ok(cs) => {
                    let _ = writeln!(
                        s,
                        "| stage | buffer | elements | int mismatches | first | float differing | worst ulp | worst |"
                    );
                    let _ = writeln!(s, "|---|---|---:|---:|---|---:|---:|---|");
                    for c in cs {
                        let first = c.first_int.as_ref().map_or("-".into(), |d| d.to_string().replace('|', "/"));
                        let worst = c.worst.as_ref().map_or("-".into(), |d| d.to_string().replace('|', "/"));
                        let _ = writeln!(
                            s,
                            "| {} | {} | {} | {} | {first} | {} | {} | {worst} |",
                            c.stage,
                            c.buffer,
                            c.elements,
                            c.int_mismatches,
                            c.float_mismatches(),
                            c.max_ulp()
                        );
                    }
                }
            }
        }
        s
    }

    /// Write `report.md` and `<case>/<buffer>_diff.png` for every per-pixel buffer with
    /// differing words into `dir`. Returns the files written.
    pub fn write(&self, dir: &Path, known: &KnownDeviations) -> std::io::Result<Vec<PathBuf>> {
        std::fs::create_dir_all(dir)?;
        let mut files = vec![dir.join("report.md")];
        std::fs::write(&files[0], self.markdown(known))?;
        for r in &self.results {
            let Ok(cs) = &r.outcome else { continue };
            for c in cs {
                let Some(ulps) = &c.pixel_ulps else { continue };
                let case_dir = dir.join(&r.name);
                std::fs::create_dir_all(&case_dir)?;
                let path = case_dir.join(format!("{}_diff.png", c.buffer));
                difference_image(r.width, r.height, ulps).save(&path).map_err(std::io::Error::other)?;
                files.push(path);
            }
        }
        Ok(files)
    }
}

/// A difference image: black where identical, otherwise a ramp from blue (1 ulp) over
/// green to red (2^20 ulp and more, or NaN), by the bucket of the pixel's largest ulp.
pub fn difference_image(width: u32, height: u32, pixel_ulps: &[u64]) -> image::RgbImage {
    image::RgbImage::from_fn(width, height, |x, y| {
        let u = pixel_ulps.get((y * width + x) as usize).copied().unwrap_or(0);
        if u == 0 {
            return image::Rgb([0, 0, 0]);
        }
        let t = (ulp_bucket(u) as f32 / 21.0).min(1.0);
        let ramp = |c: f32| (c.clamp(0.0, 1.0) * 255.0).round() as u8;
        image::Rgb([ramp(2.0 * t - 1.0), ramp(1.0 - (2.0 * t - 1.0).abs()), ramp(1.0 - 2.0 * t)])
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn difference_image_is_black_where_identical() {
        let img = difference_image(3, 1, &[0, 1, u64::MAX]);
        assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0]);
        let [r, g, b] = img.get_pixel(1, 0).0;
        assert!(b > g && g > r, "1 ulp is mostly blue: {:?}", [r, g, b]);
        assert_eq!(img.get_pixel(2, 0).0, [255, 0, 0], "NaN against a number is red");
    }

    #[test]
    fn every_buffer_has_a_cause_entry() {
        for b in BUFFERS {
            assert!(cause(b).is_some(), "{b}");
        }
    }

    /// A buffer of 9 elements, `int_mismatches` of them differing in integer words.
    fn comparison(stage: Stage, buffer: &str, int_mismatches: usize) -> BufferComparison {
        BufferComparison {
            stage,
            buffer: buffer.into(),
            elements: 9,
            int_mismatches,
            first_int: None,
            float_words: 0,
            ulp_histogram: [0; ULP_BUCKETS],
            worst: None,
            pixel_ulps: None,
        }
    }

    /// Case "c" (3x3) with these comparisons.
    fn case_result(comparisons: Vec<BufferComparison>) -> CaseResult {
        CaseResult {
            name: "c".into(),
            stresses: "",
            width: 3,
            height: 3,
            triangles: 1,
            rays: 0,
            outcome: Ok(comparisons),
        }
    }

    #[test]
    fn known_deviations_round_trip_and_ratchet() {
        let known = KnownDeviations {
            deviations: vec![Deviation { case: "c".into(), buffer: "gbuffer".into(), int_mismatches: 2, max_ulp: 10 }],
        };
        assert_eq!(toml::from_str::<KnownDeviations>(&known.to_toml()).unwrap(), known);
        let mut g = comparison(Stage::VisibilityRaster, "gbuffer", 3);
        let result = |g: &BufferComparison| case_result(vec![g.clone()]);
        let (v, _) = check(&result(&g), &known);
        assert_eq!(v.len(), 1, "3 > 2 recorded: {v:?}");
        g.int_mismatches = 1;
        let (v, i) = check(&result(&g), &known);
        assert!(v.is_empty() && i.len() == 1, "fewer than recorded is an improvement");
        let other = CaseResult { name: "d".into(), ..result(&g) };
        assert_eq!(check(&other, &known).0.len(), 1, "an unlisted case must be exact");
    }

    /// A candidate whose float probe found guarantees missing: every stage that differs,
    /// and every violation, names them; stages that agree name nothing.
    #[test]
    fn differences_are_recorded_against_the_missing_guarantees() {
        let case =
            case_result(vec![comparison(Stage::VisibilityRaster, "gbuffer", 0), comparison(Stage::RtShading, "rt", 2)]);
        let mut report = Report {
            reference: "cpu".into(),
            candidate: "gpu".into(),
            missing_guarantees: vec!["subnormals kept".into(), "guarded products apart".into()],
            results: vec![case],
        };
        let summary = report.summary_markdown();
        let row = |buffer: &str| summary.lines().find(|l| l.contains(&format!("| {buffer} |"))).unwrap().to_string();
        assert!(row("rt").ends_with("| subnormals kept, guarded products apart |"), "{summary}");
        assert!(row("gbuffer").ends_with("| - |"), "{summary}");
        assert!(summary.contains("the float probe found missing: subnormals kept, guarded products apart"));
        let (violations, _) = report.check(&KnownDeviations::default());
        assert_eq!(violations.len(), 1);
        assert!(violations[0].ends_with("[the float probe found missing: subnormals kept, guarded products apart]"));
        // A candidate that meets the guarantees: differences say so, violations stay plain.
        report.missing_guarantees.clear();
        assert!(report.summary_markdown().lines().any(|l| l.contains("| rt |") && l.ends_with("| none |")));
        assert!(!report.check(&KnownDeviations::default()).0[0].contains("float probe"));
    }
}
