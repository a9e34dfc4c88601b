//! Peers in the same run, on the same rays, with the same threads:
//!
//! * shadow rays from a real frame's ray list (`Frame::rays`), in the order a CPU frame
//!   without stage outputs traces them (2x4 pixel tiles per light, [`sort_into_tiles`]:
//!   both executors trace packets of those tiles; only a frame that keeps its stage outputs
//!   traces the list in compaction's row order), traced by hyrt's
//!   CPU stage ([`hyrt_cpu::shadow_rays::shadow_rays`]) and by Intel Embree 3
//!   (`rtcOccluded1`, and `rtcOccluded8` on packets of 8 consecutive rays, with the default
//!   incoherent context and with the context flagged coherent);
//! * primary rays (one per pixel, [`primary_rays`]) traced by [`Bvh::closest_hit`] and by
//!   Embree (`rtcIntersect1`, `rtcIntersect8` in both contexts);
//! * the reflection and refraction rays of a real frame (every bounce's ray list of a
//!   frame at [`DEFAULT_MAX_DEPTH`], one after the other), traced closest-hit by the
//!   `bounce_trace` stage's traversal and by Embree, as the primary rays;
//! * the visibility raster of the CPU backend against the GPU backend's (lavapipe here),
//!   from the Table 2 frames.
//!
//! Every tracer runs in a rayon pool of the given size, one call per ray (or packet) over
//! chunks of [`SHADOW_RAY_CHUNK`] rays, and the hit/miss answers are compared ray by ray.
//! Embree is behind the `embree` cargo feature; without it the tables say so.

use std::fmt::Write as _;

use hyrt_core::bvh::{Bvh, ClosestHit};
use hyrt_core::formats::{CameraRecord, RayRecord};
use hyrt_core::frame::{Executor, Frame, FrameOptions, PreparedScene};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::bounce::DEFAULT_MAX_DEPTH;
use hyrt_core::kernels::camera::primary_rays;
use hyrt_core::stage::Stage;
use hyrt_cpu::shadow_rays::SHADOW_OCCLUDED;
use hyrt_cpu::traversal::{
    closest_hit_batch_into, occluded_batch_into, sort_into_tiles, Traversal, TRAVERSAL_CHUNK as SHADOW_RAY_CHUNK,
};
use indicatif::ProgressBar;
use rayon::prelude::*;

use super::hit_points::{self, HitPoints};
use super::report::{count, num, Section, Table};
use super::stats::{interleaved_ms, median, round_ratios};
use super::stats::{mrays_per_s, FrameSummary};
use super::table2::{Table2, Table2Row};
use super::{BenchError, BenchOptions};

/// The shadow-ray goal when Embree is not built: Embree 3's `rtcOccluded8` on the teaser's
/// shadow rays with 2 threads, as measured on this project's 2-core machine and quoted in
/// its issue (Mrays/s).
pub const EMBREE_SHADOW_PACKET_GOAL_MRAYS: f64 = 52.2;

/// One tracer on one ray set with one thread count.
#[derive(Clone, Debug, PartialEq)]
pub struct RayRun {
    pub method: String,
    pub threads: usize,
    pub rays: usize,
    /// Median milliseconds over the rounds.
    pub ms: f64,
    /// Milliseconds of each round, the contenders of a ray list interleaved round by round
    /// ([`interleaved_ms`]): ratios between contenders are taken round by round.
    pub rounds: Vec<f64>,
    /// Rays whose hit/miss differs from hyrt's (`None` for hyrt itself).
    pub disagreements: Option<usize>,
    /// Primary rays only: rays both hit, on different triangles.
    pub other_triangle: Option<usize>,
}

impl RayRun {
    /// A run not (yet) compared with hyrt.
    pub fn new(method: &str, threads: usize, rays: usize, ms: f64) -> RayRun {
        RayRun {
            method: method.to_string(),
            threads,
            rays,
            ms,
            rounds: vec![ms],
            disagreements: None,
            other_triangle: None,
        }
    }

    /// A run timed in interleaved rounds: its median and its rounds.
    pub fn of_rounds(method: &str, threads: usize, rays: usize, rounds: Vec<f64>) -> RayRun {
        RayRun { rounds, ..RayRun::new(method, threads, rays, 0.0) }.with_median()
    }

    fn with_median(mut self) -> RayRun {
        self.ms = median(&self.rounds).unwrap_or(f64::NAN);
        self
    }

    pub fn mrays(&self) -> f64 {
        mrays_per_s(self.rays, self.ms)
    }
}

/// Peer measurements on one scene.
#[derive(Clone, Debug)]
pub struct ScenePeers {
    pub scene: String,
    pub shadow: Vec<RayRun>,
    pub primary: Vec<RayRun>,
    /// hyrt's `bvh_build` and Embree's `rtcCommitScene`, in milliseconds.
    pub hyrt_build_ms: f64,
    pub embree_build_ms: Option<f64>,
    /// Shadow rays hyrt found blocked.
    pub occluded: usize,
    /// Primary rays that hit something (hyrt).
    pub primary_hits: usize,
    /// The frame's reflection and refraction rays (empty without a ray-traced mirror or
    /// glass in view).
    pub secondary: Vec<RayRun>,
    /// Reflection and refraction rays that hit something (hyrt).
    pub secondary_hits: usize,
    /// hyrt's whole CPU frame against Embree tracing that frame's primary and shadow rays,
    /// per peer thread count, interleaved round by round ([`FrameRace`]; empty without
    /// Embree).
    pub frames: Vec<FrameRace>,
    /// The executor that ran [`ScenePeers::frames`].
    pub frame_executor: Executor,
    /// The same frame with the staged executor at the most threads, its
    /// `visibility_raster` and `reconstruction` against hyrt tracing its primary rays
    /// ([`StagedRace`]).
    pub staged_frame: Option<StagedRace>,
    /// The frame's primary hit points against Embree's, per barycentrics mode (empty
    /// without Embree).
    pub hit_points: Vec<HitPoints>,
}

/// hyrt's whole CPU frame (the paper's frame, max depth 0: every per-frame stage, shading
/// and composition included, as a default `CpuBackend` runs it) against Embree tracing the
/// same frame's primary rays and then its shadow rays, each with the method that was
/// fastest in this run's contest of that list: the two contenders in interleaved rounds on
/// one stopwatch (a round of hyrt is one `render_into`, a round of Embree both lists), so
/// that the ratio is taken round by round as the ray rows' are.
///
/// Before, the frame was timed alone (its median over the frames) and set against the
/// medians of the ray contests run after it: on a busy host the row moved by a factor of
/// up to 1.7 between two runs of the same code (the teaser at one thread 0.94 and 1.58),
/// where the interleaved ray rows moved by a few percent.
#[derive(Clone, Debug)]
pub struct FrameRace {
    pub threads: usize,
    /// hyrt's frames, `rays` = pixels.
    pub hyrt: RayRun,
    /// Embree's turns (`method` names both tracers), `rays` = primary plus shadow rays.
    pub embree: RayRun,
}

/// The paper's premise, hyrt against itself: the staged frame (each stage timed) against
/// the packets the stages run ([`Traversal::simd`]) tracing the same frame's primary rays,
/// in interleaved rounds (one frame, one pass of the rays), so that the ratio of its
/// `visibility_raster` + `reconstruction` to the rays is taken round by round.
#[derive(Clone, Debug)]
pub struct StagedRace {
    pub threads: usize,
    /// The per-stage medians of the race's frames.
    pub summary: FrameSummary,
    /// `visibility_raster` + `reconstruction` of each round's frame (ms).
    pub raster_reconstruction: Vec<f64>,
    /// The primary rays, each round.
    pub primary: RayRun,
}

/// Visibility raster of the CPU backend against the GPU backend on one scene.
pub struct RasterRow {
    pub scene: String,
    pub cpu_ms: f64,
    /// The GPU backend's stage as it renders: the reference's kernels in the fragment
    /// shader (bit-identical to the CPU).
    pub gpu_ms: f64,
    /// The device's own raster of the same pass (hardware attribute interpolation and
    /// depth, `VisibilityMode::HardwareInterpolated`): the device as a plain rasterizer.
    pub gpu_interpolated_ms: Option<f64>,
}

/// The CPU frame of one scene with the `shadow_rays` stage tracing one ray at a time (the
/// scalar reference, as before the SIMD traversal) and in packets (as it renders).
pub struct FrameTraversals {
    pub scene: String,
    /// (traversal name, per-stage medians), scalar first.
    pub runs: Vec<(String, FrameSummary)>,
}

/// All peer measurements.
pub struct Peers {
    pub scenes: Vec<ScenePeers>,
    /// The teaser's (or the first scene's) CPU frame per stage, scalar against packets.
    pub frames: Option<FrameTraversals>,
    pub raster: Vec<RasterRow>,
    /// Short name of the GPU backend ("lavapipe" or "GPU"), when measured.
    pub gpu_short: Option<String>,
    pub cpu_threads: usize,
    /// Why Embree is missing, when it is.
    pub embree_missing: Option<String>,
    /// The Embree peer as the header names it ([`embree_peer`]: version, ISA, BVH), when it ran.
    pub embree: Option<String>,
}

/// The Embree the peer is: its version, the ISA its run-time dispatch selected on this
/// machine and the BVH it builds for triangle scenes (`embree::EmbreeBuild`;
/// "not found" and why, when Embree's output did not say), or why there is none.
pub fn embree_peer() -> String {
    #[cfg(feature = "embree")]
    {
        // Asked once a process (the header and the Peers section both name the peer): the
        // probe creates a device, commits a scene and captures Embree's standard output,
        // and its answer does not change within a run.
        static PEER: std::sync::OnceLock<String> = std::sync::OnceLock::new();
        PEER.get_or_init(|| match super::embree::EmbreeScene::version() {
            Ok(v) => format!(
                "Embree {v} (hand-written FFI to the system's libembree3; default build quality and scene flags): {}",
                match super::embree::EmbreeBuild::detect() {
                    Ok(b) => b.to_string(),
                    Err(e) => format!("ISA and BVH not found ({e})"),
                }
            ),
            Err(e) => e.to_string(),
        })
        .clone()
    }
    #[cfg(not(feature = "embree"))]
    {
        "not built (enable the `embree` cargo feature of the hyrt crate; needs Debian's libembree-dev)".to_string()
    }
}

/// The thread pool of a contest of ray tracers: `threads` workers, each pinned to a CPU of
/// its own (the `i`-th of the process's affinity mask) where the mask has that many; every
/// contender of a contest runs on it, Embree's runs as hyrt's.
///
/// Unpinned, the scheduler sometimes left both workers of a fresh two-thread pool on one
/// core for a whole short contest (bursts of a few milliseconds, the workers asleep in
/// between, so the load balancer never moved one): on this project's 2-core AMD EPYC the
/// far bunny's 39,781 shadow rays took 4.8 ms a round at "2 threads", one thread's time,
/// for the first 8 of 15 rounds and 2.6 ms after, for every contender alike; pinned, 2.6
/// ms from the first round (`RAY_CONTEST_ROUNDS=1 ray_contest --packets-only --kind shadow
/// bunny_far`). Whole frames (the CPU backend's own pool, busy through the frame) measured
/// the same pinned and unpinned (`hyrt render --frames 30 --threads 2`, five scenes).
pub fn contest_pool(threads: usize) -> rayon::ThreadPool {
    let cpus = allowed_cpus();
    let pin = threads <= cpus.len();
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .start_handler(move |i| {
            if pin {
                pin_current_thread(cpus[i]);
            }
        })
        .build()
        .expect("rayon pool")
}

/// The CPUs this process may run on, in increasing order (empty where unknown).
#[cfg(target_os = "linux")]
fn allowed_cpus() -> Vec<usize> {
    // SAFETY: `sched_getaffinity` writes at most `size_of::<cpu_set_t>()` bytes into `set`,
    // a zeroed plain-old-data bit set; `CPU_ISSET` reads within it.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return Vec::new();
        }
        (0..libc::CPU_SETSIZE as usize).filter(|&c| libc::CPU_ISSET(c, &set)).collect()
    }
}

#[cfg(not(target_os = "linux"))]
fn allowed_cpus() -> Vec<usize> {
    Vec::new()
}

/// Pin the calling thread to `cpu` (best effort: a failure leaves it unpinned).
#[cfg(target_os = "linux")]
fn pin_current_thread(cpu: usize) {
    // SAFETY: `set` is a zeroed bit set with `cpu` (below `CPU_SETSIZE`, from
    // `allowed_cpus`) set; `sched_setaffinity(0, ..)` applies to the calling thread only.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set);
    }
}

#[cfg(not(target_os = "linux"))]
fn pin_current_thread(_cpu: usize) {}

/// Trace `rays` with `trace` (one call per chunk) in `pool`; `out` gets one answer per ray.
#[cfg_attr(not(feature = "embree"), allow(dead_code))]
fn in_chunks<T: Send>(
    pool: &rayon::ThreadPool,
    rays: &[RayRecord],
    out: &mut [T],
    trace: impl Fn(&[RayRecord], &mut [T]) + Sync,
) {
    pool.install(|| {
        out.par_chunks_mut(SHADOW_RAY_CHUNK).zip(rays.par_chunks(SHADOW_RAY_CHUNK)).for_each(|(o, r)| trace(r, o))
    });
}

/// The name of a hyrt traversal in the tables: the scalar reference, the packets the
/// stages run ([`Traversal::simd`]: "hyrt packets", what the goals take), single rays, or
/// packets at one fixed level named as a comparison where the stages run another (or
/// measure theirs, [`Traversal::PacketAuto`]).
fn hyrt_method(reference: &str, traversal: Traversal) -> String {
    let stages = Traversal::simd();
    match traversal {
        Traversal::Scalar => format!("hyrt `{reference}` per ray (scalar reference)"),
        // Not "hyrt packets ...": the goals take the traversal the stages run.
        Traversal::Packet(_) if traversal != stages => {
            format!(
                "hyrt `{}`: the packets at one level, for comparison (the stages run `{}`)",
                traversal.name(),
                stages.name()
            )
        }
        // `packet-auto`: AVX-512 or AVX2, whichever the kind of walk measured faster (the
        // report's header says which).
        Traversal::Packet(_) | Traversal::PacketAuto => format!("hyrt packets of 8 (`{}`)", traversal.name()),
        Traversal::Single(_) | Traversal::SingleAuto => {
            format!("hyrt single rays, 16-wide nodes (`{}`)", traversal.name())
        }
    }
}

/// The SIMD traversals the peers table measures besides the scalar reference: the packets
/// the `shadow_rays` stage runs ([`Traversal::simd`]) and single rays through the wide
/// tree ([`Traversal::for_bounces`]); where the stages measure their level per kind of
/// walk (a CPU with AVX-512, `hyrt_cpu::traversal::tuning`), also the packets at AVX-512
/// and at AVX2 alone, interleaved with the others, so that one run shows both levels
/// beside the one the stages chose.
fn hyrt_simd() -> Vec<Traversal> {
    use hyrt_cpu::traversal::SimdLevel;
    let mut out = vec![Traversal::simd(), Traversal::for_bounces()];
    if Traversal::simd() == Traversal::PacketAuto {
        out.extend([Traversal::Packet(SimdLevel::Avx512), Traversal::Packet(SimdLevel::Avx2)]);
    }
    out
}

/// One run of a contender over its ray list.
type Run<'a> = Box<dyn FnMut() + 'a>;
/// A contender of a ray list's contest: its name in the tables and its run.
type Contender<'a> = (String, Run<'a>);

/// Least time the rounds of a contest should add up to for its fastest contender. Each
/// turn traces the list once, as a frame does; a list its fastest contender traces in less
/// than this over the asked rounds (the far horse's 6,085 shadow rays take half a
/// millisecond on two threads) is contested over more rounds, at most [`MAX_ROUNDS`].
///
/// Not several passes a turn, as earlier reports did: a list traced again and again in a
/// row lets each tracer's caches and branch predictors learn it, which no frame does, and
/// that favours tracers unequally. The far horse's shadow rays at 40 passes a turn against
/// one (`ray_contest --passes 40`, 2 threads, pinned, 15 rounds, twice): Embree's
/// `rtcOccluded8` 0.50 to 0.30 ms a pass, hyrt's packets 0.53 to 0.45, so the ratio went
/// from 0.96-0.97 to 0.67-0.68. The wake-up jitter those passes were meant to average out
/// came from a pool's workers sharing a core, which [`contest_pool`] removes.
///
/// 300 ms, not 60 as before: the Goals table's ray rows are the medians of these rounds'
/// ratios, and at 60 ms the lists the fastest tracer runs through in 10 to 30 ms at two
/// threads (the teaser's reflections, the dragon's shadow rays, most scenes' primary rays)
/// had three to six rounds, so one or two slow rounds moved a row's verdict (the teaser's
/// reflections: 0.97 and 0.88 in the reports of two consecutive sessions with the same
/// traversal code, single rounds' ratios from 0.73 to 1.16). At 300 ms those rows get 10
/// to 50 rounds, for about two minutes more of `hyrt bench --quick` on a 2-core machine.
pub const MIN_CONTEST_MS: f64 = 300.0;

/// Most rounds of one contest (a list of a few rays would otherwise ask for thousands).
pub const MAX_ROUNDS: usize = 64;

/// Run the contenders of one ray list in interleaved rounds ([`interleaved_ms`]), each
/// turn one pass of the list: at least `rounds` rounds, more for a short list
/// ([`contest_rounds`], from one timed pass of each contender).
fn contest(rounds: usize, threads: usize, rays: usize, contenders: Vec<Contender<'_>>) -> Vec<RayRun> {
    let (names, mut runs): (Vec<String>, Vec<Run<'_>>) = contenders.into_iter().unzip();
    let fastest = runs
        .iter_mut()
        .map(|run| {
            let t = std::time::Instant::now();
            run();
            t.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::INFINITY, f64::min);
    let mut refs: Vec<&mut dyn FnMut()> = runs.iter_mut().map(|r| &mut **r as &mut dyn FnMut()).collect();
    let ms = interleaved_ms(contest_rounds(rounds, fastest), &mut refs);
    names.iter().zip(ms).map(|(name, ms)| RayRun::of_rounds(name, threads, rays, ms)).collect()
}

/// Rounds of a contest asked for `rounds` whose fastest pass took `fastest_ms`: enough for
/// [`MIN_CONTEST_MS`], at least `rounds`, at most [`MAX_ROUNDS`] (or `rounds` if more).
fn contest_rounds(rounds: usize, fastest_ms: f64) -> usize {
    let most = MAX_ROUNDS.max(rounds);
    if fastest_ms.is_finite() && fastest_ms > 0.0 {
        ((MIN_CONTEST_MS / fastest_ms).ceil() as usize).clamp(rounds, most)
    } else {
        rounds
    }
}

/// The shadow rays of a real frame of the scene (the CPU backend, every stage's output kept).
pub fn frame_shadow_rays(row: &PeerScene<'_>) -> Result<Vec<RayRecord>, BenchError> {
    Ok(frame_rays(row)?.0)
}

/// A real frame's ray lists: its shadow rays (from the primary hits), and its reflection
/// and refraction rays of every bounce, depth 1 first (a frame at [`DEFAULT_MAX_DEPTH`] on
/// the CPU backend, every stage's output kept).
pub fn frame_rays(row: &PeerScene<'_>) -> Result<(Vec<RayRecord>, Vec<RayRecord>), BenchError> {
    let mut backend = hyrt_cpu::backend::CpuBackend::new(None);
    // Stage outputs (the ray lists) need the staged executor; say so rather than rely on it.
    backend.set_executor(Executor::Staged);
    let mut frame = Frame::default();
    hyrt_core::frame::Backend::render_into(
        &mut backend,
        row.prepared,
        &row.camera,
        &FrameOptions { max_depth: DEFAULT_MAX_DEPTH, ..FrameOptions::with_stage_outputs() },
        &mut frame,
    )
    .map_err(|source| BenchError::Render { scene: row.name.to_string(), source })?;
    let secondary = frame.bounces.iter().take(frame.plan.bounce_depth() as usize).flat_map(|b| b.rays.iter().copied());
    let secondary = secondary.collect();
    Ok((frame.rays, secondary))
}

/// A scene the peers trace: prepared, with the camera of the image they trace (borrowed
/// from a Table 2 row, or from the extra scenes a full run loads).
pub struct PeerScene<'a> {
    pub name: &'a str,
    pub prepared: &'a PreparedScene,
    pub camera: CameraRecord,
}

impl<'a> PeerScene<'a> {
    fn of_row(row: &'a Table2Row) -> PeerScene<'a> {
        PeerScene { name: &row.name, prepared: &row.prepared, camera: row.camera }
    }
}

fn measure_scene(
    options: &BenchOptions,
    row: &PeerScene<'_>,
    progress: &ProgressBar,
) -> Result<(ScenePeers, Option<String>), BenchError> {
    let g: &WorldGeometry = &row.prepared.geometry;
    let bvh: &Bvh = &row.prepared.bvh;
    let (mut shadow, secondary) = frame_rays(row)?;
    sort_into_tiles(&mut shadow, row.camera.width);
    let primary = primary_rays(&row.camera);
    let max_threads = options.peer_threads.iter().copied().max().unwrap_or(1);
    #[cfg(feature = "embree")]
    let (embree, embree_missing) = match super::embree::EmbreeScene::new(g, &format!("threads={max_threads}")) {
        Ok(e) => (Some(e), None),
        Err(e) => (None, Some(e.to_string())),
    };
    #[cfg(not(feature = "embree"))]
    let embree_missing = Some(embree_peer());
    let mut out = ScenePeers {
        scene: row.name.to_string(),
        shadow: Vec::new(),
        frames: Vec::new(),
        frame_executor: Executor::Fused,
        staged_frame: None,
        primary: Vec::new(),
        hyrt_build_ms: row.prepared.bvh_build_ms,
        embree_build_ms: None,
        occluded: 0,
        primary_hits: 0,
        secondary: Vec::new(),
        secondary_hits: 0,
        hit_points: Vec::new(),
    };
    #[cfg(feature = "embree")]
    {
        out.embree_build_ms = embree.as_ref().map(|e| e.build_ms);
        if let Some(e) = &embree {
            progress.set_message(format!("peers: {} primary hit points against Embree's", row.name));
            let render = |source| BenchError::Render { scene: row.name.to_string(), source };
            out.hit_points = super::hit_points::measure(row.prepared, &row.camera, e).map_err(render)?;
        }
    }
    #[cfg(feature = "embree")]
    let embree_ref = embree.as_ref();
    #[cfg(not(feature = "embree"))]
    let embree_ref = None;
    for &threads in &options.peer_threads {
        progress.set_message(format!("peers: {} shadow and primary rays, {threads} threads", row.name));
        let pool = contest_pool(threads);
        // hyrt: the scalar reference traversal (one ray at a time), the packets of 8 the
        // `shadow_rays` stage uses and single rays, then Embree's, each in a pool of
        // `threads`, interleaved round by round. Outputs go to a buffer reused across
        // rounds, as in the `shadow_rays` stage.
        let traversals: Vec<Traversal> = std::iter::once(Traversal::Scalar).chain(hyrt_simd()).collect();
        let mut outs = vec![Vec::new(); traversals.len()];
        #[cfg(feature = "embree")]
        let occ = embree_occluders();
        #[cfg(feature = "embree")]
        let mut embree_outs = vec![vec![false; shadow.len()]; occ.len()];
        let runs = {
            let mut contenders: Vec<Contender<'_>> = Vec::new();
            for (&traversal, o) in traversals.iter().zip(outs.iter_mut()) {
                let (pool, shadow) = (&pool, &shadow);
                let run = move || pool.install(|| occluded_batch_into(bvh, g.traversal_table(), shadow, traversal, o));
                contenders.push((hyrt_method("Bvh::occluded", traversal), Box::new(run)));
            }
            #[cfg(feature = "embree")]
            if let Some(e) = &embree {
                for (&(name, f), o) in occ.iter().zip(embree_outs.iter_mut()) {
                    let (pool, shadow) = (&pool, &shadow);
                    contenders
                        .push((name.to_string(), Box::new(move || in_chunks(pool, shadow, o, |r, o| f(e, r, o)))));
                }
            }
            contest(options.repeats, threads, shadow.len(), contenders)
        };
        let occluded = &outs[0];
        let hyrt_occ: Vec<bool> = occluded.iter().map(|&o| o == SHADOW_OCCLUDED).collect();
        for (i, mut run) in runs.into_iter().enumerate() {
            // Every run against the scalar reference: hyrt's must be 0 (tests hold them to it).
            run.disagreements = match outs.get(i) {
                Some(_) if i == 0 => None,
                Some(o) => Some(occluded.iter().zip(o).filter(|(a, b)| a != b).count()),
                #[cfg(feature = "embree")]
                None => Some(hyrt_occ.iter().zip(&embree_outs[i - outs.len()]).filter(|(a, b)| a != b).count()),
                #[cfg(not(feature = "embree"))]
                None => None,
            };
            out.shadow.push(run);
        }
        out.occluded = hyrt_occ.iter().filter(|&&o| o).count();
        let (runs, hits) = closest_hit_runs(options.repeats, &pool, bvh, g, &primary, embree_ref);
        out.primary.extend(runs);
        out.primary_hits = hits;
        if threads == max_threads {
            progress.set_message(format!("peers: {} staged frame against its primary rays", row.name));
            out.staged_frame = Some(staged_race(options, row, &pool, &primary)?);
        }
        if !secondary.is_empty() {
            let (runs, hits) = closest_hit_runs(options.repeats, &pool, bvh, g, &secondary, embree_ref);
            out.secondary.extend(runs);
            out.secondary_hits = hits;
        }
        #[cfg(feature = "embree")]
        if let Some(e) = &embree {
            progress.set_message(format!("peers: {} hyrt's frame against Embree's rays, {threads} threads", row.name));
            let (race, executor) = frame_race(options, row, threads, &pool, e, (&primary, &shadow), &out)?;
            out.frames.extend(race);
            out.frame_executor = executor;
        }
        progress.inc(1);
    }
    Ok((out, embree_missing))
}

/// hyrt's frame with `threads` against Embree tracing its `primary` and `shadow` rays with
/// the methods fastest in `peers`' contests at that thread count ([`FrameRace`]); none
/// where those contests have no Embree run. Also the executor that ran hyrt's frame.
#[cfg(feature = "embree")]
fn frame_race(
    options: &BenchOptions,
    row: &PeerScene<'_>,
    threads: usize,
    pool: &rayon::ThreadPool,
    embree: &super::embree::EmbreeScene,
    (primary, shadow): (&[RayRecord], &[RayRecord]),
    peers: &ScenePeers,
) -> Result<(Option<FrameRace>, Executor), BenchError> {
    // The name of the Embree method with the least median time in `runs` at `threads`.
    let fastest = |runs: &[RayRun]| -> Option<String> {
        let embree = runs.iter().filter(|r| r.threads == threads && r.method.starts_with("Embree"));
        embree.min_by(|a, b| a.ms.total_cmp(&b.ms)).map(|r| r.method.clone())
    };
    let hit = fastest(&peers.primary).and_then(|m| embree_intersectors().into_iter().find(|(n, _)| *n == m));
    let occ = fastest(&peers.shadow).and_then(|m| embree_occluders().into_iter().find(|(n, _)| *n == m));
    let (Some((hit_name, hit)), Some((occ_name, occ))) = (hit, occ) else {
        return Ok((None, Executor::default()));
    };
    let mut cpu = hyrt_cpu::backend::CpuBackend::new(Some(threads));
    let mut frame = Frame::default();
    let mut failed = None;
    let (mut hits, mut blocked) = (vec![None; primary.len()], vec![false; shadow.len()]);
    let frame_run = || {
        let options = super::paper_frame();
        if let Err(e) =
            hyrt_core::frame::Backend::render_into(&mut cpu, row.prepared, &row.camera, &options, &mut frame)
        {
            failed = Some(e);
        }
    };
    let embree_run = || {
        in_chunks(pool, primary, &mut hits, |r, o| hit(embree, r, o));
        in_chunks(pool, shadow, &mut blocked, |r, o| occ(embree, r, o));
    };
    let contenders: Vec<Contender<'_>> =
        vec![("hyrt".to_string(), Box::new(frame_run)), (format!("{hit_name} + {occ_name}"), Box::new(embree_run))];
    let pixels = (row.camera.width * row.camera.height) as usize;
    let mut runs = contest(race_rounds(options), threads, pixels, contenders).into_iter();
    if let Some(source) = failed {
        return Err(BenchError::Render { scene: row.name.to_string(), source });
    }
    let (Some(hyrt), Some(mut embree)) = (runs.next(), runs.next()) else { unreachable!("two contenders") };
    embree.rays = primary.len() + shadow.len();
    Ok((Some(FrameRace { threads, hyrt, embree }), frame.stats.executor))
}

/// Least rounds of a race of whole frames ([`FrameRace`], [`StagedRace`]): `--frames`
/// (5 with `--quick`) gave five or six rounds of these 50 to 150 ms turns, and a busy host
/// then moved a row's median by a third between two runs (the near bunny at one thread:
/// 1.21 (1.00–1.41) and 0.76 (0.74–1.19), consecutive `--quick` reports); 15 rounds cost
/// about half a minute more over the peers' scenes.
const MIN_RACE_ROUNDS: usize = 15;

/// Rounds of a race of whole frames: `--frames`, at least [`MIN_RACE_ROUNDS`].
fn race_rounds(options: &BenchOptions) -> usize {
    options.frames.max(MIN_RACE_ROUNDS)
}

/// [`StagedRace`] in `pool`.
fn staged_race(
    options: &BenchOptions,
    row: &PeerScene<'_>,
    pool: &rayon::ThreadPool,
    primary: &[RayRecord],
) -> Result<StagedRace, BenchError> {
    let threads = pool.current_num_threads();
    let mut cpu = hyrt_cpu::backend::CpuBackend::new(Some(threads));
    cpu.set_executor(Executor::Staged);
    let mut frame = Frame::default();
    let mut stats = Vec::new();
    let mut failed = None;
    let frame_run = || {
        let options = super::paper_frame();
        match hyrt_core::frame::Backend::render_into(&mut cpu, row.prepared, &row.camera, &options, &mut frame) {
            Ok(()) => stats.push(frame.stats.clone()),
            Err(e) => failed = Some(e),
        }
    };
    let (bvh, g, traversal) = (&row.prepared.bvh, &row.prepared.geometry, Traversal::simd());
    let mut hits = Vec::new();
    let rays_run = || pool.install(|| closest_hit_batch_into(bvh, g.traversal_table(), primary, traversal, &mut hits));
    let contenders: Vec<Contender<'_>> = vec![
        ("hyrt staged frame".to_string(), Box::new(frame_run)),
        (hyrt_method("Bvh::closest_hit", traversal), Box::new(rays_run)),
    ];
    let pixels = (row.camera.width * row.camera.height) as usize;
    let runs = contest(race_rounds(options), threads, pixels, contenders);
    let render = |source| BenchError::Render { scene: row.name.to_string(), source };
    if let Some(source) = failed {
        return Err(render(source));
    }
    // The warm-up frame is not a round.
    let rounds = &stats[stats.len() - runs[1].rounds.len()..];
    let summary = FrameSummary::from_frames(rounds)
        .ok_or_else(|| render(hyrt_core::frame::RenderError::InvalidOptions("no frame was measured".into())))?;
    let stage = |f: &hyrt_core::frame::FrameStats, s| f.ms(s).unwrap_or(f64::NAN);
    let raster_reconstruction =
        rounds.iter().map(|f| stage(f, Stage::VisibilityRaster) + stage(f, Stage::Reconstruction)).collect();
    let mut primary_run = runs[1].clone();
    primary_run.rays = primary.len();
    Ok(StagedRace { threads, summary, raster_reconstruction, primary: primary_run })
}

/// Embree's closest-hit tracers: single rays, and packets in both contexts (as
/// [`embree_occluders`]).
#[cfg(feature = "embree")]
#[allow(clippy::type_complexity)]
fn embree_intersectors() -> [(&'static str, fn(&super::embree::EmbreeScene, &[RayRecord], &mut [Option<u32>])); 3] {
    use super::embree::EmbreeScene;
    [
        ("Embree `rtcIntersect1`", EmbreeScene::intersect1),
        ("Embree `rtcIntersect8` (packets of 8)", EmbreeScene::intersect8),
        ("Embree `rtcIntersect8` (packets of 8, coherent context)", EmbreeScene::intersect8_coherent),
    ]
}

/// Embree's any-hit tracers: single rays, and packets both with Embree's default
/// (incoherent) context and flagged coherent, which lets Embree trace a packet with its
/// frustum-based coherent traversal: faster on these ray lists, so the goals take the
/// faster of the two.
#[cfg(feature = "embree")]
#[allow(clippy::type_complexity)]
fn embree_occluders() -> [(&'static str, fn(&super::embree::EmbreeScene, &[RayRecord], &mut [bool])); 3] {
    use super::embree::EmbreeScene;
    [
        ("Embree `rtcOccluded1`", EmbreeScene::occluded1),
        ("Embree `rtcOccluded8` (packets of 8)", EmbreeScene::occluded8),
        ("Embree `rtcOccluded8` (packets of 8, coherent context)", EmbreeScene::occluded8_coherent),
    ]
}

#[cfg(feature = "embree")]
type EmbreeRef<'a> = Option<&'a super::embree::EmbreeScene>;
#[cfg(not(feature = "embree"))]
type EmbreeRef<'a> = Option<&'a std::convert::Infallible>;

/// Closest hits of `rays` in `pool`: hyrt's scalar reference and the packets the
/// `bounce_trace` stage uses, then Embree's `rtcIntersect1` and `rtcIntersect8` (both
/// contexts) when built; each run compared ray by ray with hyrt's reference. Also the
/// number of rays that hit something (hyrt).
fn closest_hit_runs(
    repeats: usize,
    pool: &rayon::ThreadPool,
    bvh: &Bvh,
    g: &WorldGeometry,
    rays: &[RayRecord],
    embree: EmbreeRef<'_>,
) -> (Vec<RayRun>, usize) {
    let threads = pool.current_num_threads();
    let traversals: Vec<Traversal> = std::iter::once(Traversal::Scalar).chain(hyrt_simd()).collect();
    let mut outs = vec![Vec::new(); traversals.len()];
    #[cfg(feature = "embree")]
    let hit = embree_intersectors();
    #[cfg(feature = "embree")]
    let mut embree_outs = vec![vec![None; rays.len()]; hit.len()];
    let runs = {
        let mut contenders: Vec<Contender<'_>> = Vec::new();
        for (&traversal, o) in traversals.iter().zip(outs.iter_mut()) {
            let run = move || pool.install(|| closest_hit_batch_into(bvh, g.traversal_table(), rays, traversal, o));
            contenders.push((hyrt_method("Bvh::closest_hit", traversal), Box::new(run)));
        }
        #[cfg(feature = "embree")]
        if let Some(e) = embree {
            for (&(name, f), o) in hit.iter().zip(embree_outs.iter_mut()) {
                contenders.push((name.to_string(), Box::new(move || in_chunks(pool, rays, o, |r, o| f(e, r, o)))));
            }
        }
        #[cfg(not(feature = "embree"))]
        let _ = embree;
        contest(repeats, threads, rays.len(), contenders)
    };
    let triangles = |o: &[Option<ClosestHit>]| o.iter().map(|h| h.map(|h| h.triangle)).collect::<Vec<_>>();
    let hits: Vec<Option<u32>> = triangles(&outs[0]);
    let answers: Vec<Vec<Option<u32>>> = outs.iter().map(|o| triangles(o)).collect();
    #[cfg(feature = "embree")]
    let answers: Vec<Vec<Option<u32>>> = answers.into_iter().chain(embree_outs).collect();
    let runs = runs
        .into_iter()
        .zip(&answers)
        .enumerate()
        .map(|(i, (mut run, h))| {
            // Every run against hyrt's scalar reference (run 0).
            if i > 0 {
                run.disagreements = Some(hits.iter().zip(h).filter(|(a, b)| a.is_some() != b.is_some()).count());
                run.other_triangle =
                    Some(hits.iter().zip(h).filter(|(a, b)| a.is_some() && b.is_some() && a != b).count());
            }
            run
        })
        .collect();
    let hit_count = hits.iter().filter(|h| h.is_some()).count();
    (runs, hit_count)
}

/// Scenes beyond Table 2's that the peers trace.
const PEER_EXTRA_MANIFESTS: [&str; 2] = ["sponza", "dragon"];

/// Which Table 2 rows the ray peers run on: every scene but the default one (quick runs
/// too: the traversal issue's verdict is scene by scene); the default scene when nothing
/// else is loaded.
fn peer_rows(table2: &Table2) -> Vec<&Table2Row> {
    let named: Vec<&Table2Row> = table2.rows.iter().filter(|r| r.name != "default").collect();
    if named.is_empty() {
        return table2.rows.iter().take(1).collect();
    }
    named
}

/// Measure every peer.
pub fn run(options: &BenchOptions, table2: &Table2, progress: &ProgressBar) -> Result<Peers, BenchError> {
    let table_rows = peer_rows(table2);
    // Sponza alone and the dragon are traced too: the traversal issue's scenes, at the
    // Table 2 image size.
    let mut extra = Vec::new();
    let extra_names = &PEER_EXTRA_MANIFESTS[..];
    if table_rows.iter().any(|r| r.name != "default") {
        for s in super::scenes::load_manifests(extra_names.iter().copied(), options.scenes, &mut Vec::new()) {
            let Some(camera) = s.scene.camera else { continue };
            let (w, h) = table2.size;
            extra.push((s.name, super::prepare(&s.scene, options.frame_threads), CameraRecord::new(&camera, w, h)));
        }
    }
    let rows: Vec<PeerScene<'_>> = table_rows
        .into_iter()
        .map(PeerScene::of_row)
        .chain(extra.iter().map(|(name, prepared, camera)| PeerScene { name, prepared, camera: *camera }))
        .collect();
    progress.inc_length((rows.len() * options.peer_threads.len()) as u64);
    let mut scenes = Vec::new();
    let mut embree_missing = None;
    for r in &rows {
        let (p, missing) = measure_scene(options, r, progress)?;
        scenes.push(p);
        embree_missing = embree_missing.or(missing);
    }
    // The frame with each shadow traversal, on the scene of the goals.
    let mut frames = None;
    if let Some(r) = rows.iter().find(|r| r.name == "teaser").or(rows.first()) {
        progress.set_message(format!("peers: {} CPU frames, scalar and packet shadow rays", r.name));
        let mut runs = Vec::new();
        for traversal in [Traversal::Scalar, Traversal::simd()] {
            let mut cpu = hyrt_cpu::backend::CpuBackend::new(options.frame_threads);
            // Per stage: the staged executor (the fused one times only its tiles).
            cpu.set_executor(Executor::Staged);
            cpu.set_shadow_traversal(traversal);
            let (m, _) = super::measure_frames(&mut cpu, r.prepared, &r.camera, options.frames)
                .map_err(|source| BenchError::Render { scene: r.name.to_string(), source })?;
            runs.push((traversal.name(), m));
        }
        frames = Some(FrameTraversals { scene: r.name.to_string(), runs });
    }
    // The device as a plain rasterizer of the same pass: a second GPU backend in the
    // hardware-interpolated mode, on the Table 2 frames.
    let mut plain = None;
    if table2.rows.iter().any(|r| r.gpu.is_some()) {
        if let Ok(mut g) = hyrt_gpu::backend::GpuBackend::new(options.policy) {
            if g.set_visibility_mode(hyrt_gpu::visibility_raster::VisibilityMode::HardwareInterpolated).is_ok() {
                plain = Some(g);
            }
        }
    }
    let mut raster = Vec::new();
    for r in &table2.rows {
        let (Some(g), Some(cpu_ms)) = (r.gpu.as_ref(), r.cpu.0.ms(Stage::VisibilityRaster)) else { continue };
        let Some(gpu_ms) = g.0.ms(Stage::VisibilityRaster) else { continue };
        progress.set_message(format!("peers: {} visibility raster, hardware interpolation", r.name));
        let gpu_interpolated_ms = plain
            .as_mut()
            .and_then(|p| super::measure_frames(p, &r.prepared, &r.camera, options.frames).ok())
            .and_then(|(m, _)| m.ms(Stage::VisibilityRaster));
        raster.push(RasterRow { scene: r.name.clone(), cpu_ms, gpu_ms, gpu_interpolated_ms });
    }
    let cpu_threads = table2.rows.first().map_or(0, |r| r.cpu.1.threads);
    Ok(Peers {
        scenes,
        frames,
        raster,
        gpu_short: table2.gpu.as_ref().map(|g| g.1.clone()),
        cpu_threads,
        embree: embree_missing.is_none().then(embree_peer),
        embree_missing,
    })
}

/// The per-stage table of [`FrameTraversals`], with its heading and the ratio of the
/// scalar to the packet times (how much faster each stage got).
fn frame_traversal_table(f: &FrameTraversals, threads: usize, (w, h): (u32, u32)) -> String {
    // The per-frame stages (`bvh_build` runs once per scene), then the frame.
    // The per-frame stages that ran (`bvh_build` runs once per scene), then the frame.
    let stages: Vec<Stage> = Stage::ALL
        .into_iter()
        .filter(|s| *s != Stage::BvhBuild && f.runs.iter().any(|(_, m)| m.ms(*s).is_some()))
        .collect();
    let mut cols = vec!["shadow traversal".to_string()];
    cols.extend(stages.iter().map(|s| s.name().to_string()));
    cols.push("frame".into());
    let mut t = Table::new(cols);
    let cells = |m: &FrameSummary| {
        let mut c: Vec<f64> = stages.iter().map(|s| m.ms(*s).unwrap_or(f64::NAN)).collect();
        c.push(m.frame_ms);
        c
    };
    for (name, m) in &f.runs {
        let mut row = vec![format!("{name} (ms)")];
        row.extend(cells(m).into_iter().map(|v| num(v, 2)));
        t.row(row);
    }
    if let [(_, before), (_, after)] = &f.runs[..] {
        let mut row = vec!["scalar / packets".to_string()];
        row.extend(cells(before).into_iter().zip(cells(after)).map(|(b, a)| num(b / a, 2)));
        t.row(row);
    }
    format!(
        "### {}: the CPU frame per stage, shadow rays scalar (before) and in packets (after)\n\n\
         {w}x{h}, {threads} threads, the staged executor (each stage timed), medians of frames; only \
         `shadow_rays` changes between the rows (both give the same bits).\n\n{}",
        f.scene,
        t.to_markdown()
    )
}

fn ray_table(runs: &[RayRun], primary: bool) -> Table {
    let mut cols = vec!["method", "threads", "rays", "ms", "Mrays/s", "speed / hyrt", "hit/miss differs from hyrt"];
    if primary {
        cols.push("both hit, other triangle");
    }
    let mut t = Table::new(cols);
    for r in runs {
        let base =
            runs.iter().find(|b| b.threads == r.threads && b.disagreements.is_none()).map_or(f64::NAN, RayRun::mrays);
        let mut row = vec![
            r.method.clone(),
            r.threads.to_string(),
            count(r.rays as u64),
            num(r.ms, 2),
            num(r.mrays(), 2),
            num(r.mrays() / base, 2),
            r.disagreements.map_or("(reference)".into(), |d| count(d as u64)),
        ];
        if primary {
            row.push(r.other_triangle.map_or("-".into(), |d| count(d as u64)));
        }
        t.row(row);
    }
    t
}

impl Peers {
    /// The report section.
    pub fn section(&self, table2: &Table2) -> Section {
        let (w, h) = table2.size;
        let mut md = String::new();
        let _ = writeln!(
            md,
            "Same rays, same threads: each tracer runs in a rayon pool of the stated size, one call per ray \
             (or per packet of 8 consecutive rays) over chunks of {SHADOW_RAY_CHUNK} rays, each writing into an \
             output buffer reused across runs; times are medians of repeated runs. Embree's packets run with its \
             default (incoherent) intersect context and with the context flagged coherent, which lets Embree use \
             its frustum-based coherent packet traversal (faster on these lists); the goals take the faster. \
             hyrt's closest-hit packets do the same where their rays travel together (one frustum test per node \
             of the 8-wide tree; primary rays) and walk the binary tree lane by lane otherwise; its any-hit \
             packets always walk the binary tree. Shadow rays are a real {w}x{h} frame's ray list \
             (`Frame::rays`) in the order a CPU frame without stage outputs traces them (the default fused \
             executor and the staged one): 2x4 pixel tiles per light (`hyrt_cpu::traversal::sort_into_tiles`), \
             so every tracer's packets of 8 consecutive rays are 2x4 tiles; primary rays one per pixel through its centre. Embree's triangle test is not watertight, hyrt's is: rays through shared \
             edges or vertices may differ, and the count of such rays is reported as measured."
        );
        match (&self.embree_missing, &self.embree) {
            (Some(m), _) => {
                let _ = writeln!(md, "\nEmbree: {m}.");
            }
            (None, Some(e)) => {
                let _ = writeln!(md, "\nThe peer: {e}.");
            }
            (None, None) => {}
        }
        for s in &self.scenes {
            let _ = writeln!(
                md,
                "\n### {}: shadow rays\n\n{} rays, {} of them occluded (hyrt). BVH build: hyrt {} ms{}.\n\n{}",
                s.scene,
                count(s.shadow.first().map_or(0, |r| r.rays) as u64),
                count(s.occluded as u64),
                num(s.hyrt_build_ms, 1),
                s.embree_build_ms.map(|e| format!(", Embree `rtcCommitScene` {} ms", num(e, 1))).unwrap_or_default(),
                ray_table(&s.shadow, false).to_markdown()
            );
            let _ = writeln!(
                md,
                "\n### {}: primary rays\n\n{} rays, {} of them hit (hyrt).\n\n{}",
                s.scene,
                count(s.primary.first().map_or(0, |r| r.rays) as u64),
                count(s.primary_hits as u64),
                ray_table(&s.primary, true).to_markdown()
            );
            if s.secondary.is_empty() {
                let _ = writeln!(
                    md,
                    "\n### {}: reflection and refraction rays\n\nNone: no ray-traced mirror or glass in view.",
                    s.scene
                );
            } else {
                let _ = writeln!(
                    md,
                    "\n### {}: reflection and refraction rays\n\nThe frame's own secondary rays (every bounce of a frame at max depth {DEFAULT_MAX_DEPTH}, one list), {} rays, {} of them hit (hyrt).\n\n{}",
                    s.scene,
                    count(s.secondary.first().map_or(0, |r| r.rays) as u64),
                    count(s.secondary_hits as u64),
                    ray_table(&s.secondary, true).to_markdown()
                );
            }
        }
        if let Some(f) = &self.frames {
            let _ = writeln!(md, "\n{}", frame_traversal_table(f, self.cpu_threads, (w, h)));
        }
        let _ = writeln!(md, "\n### Visibility raster: CPU against the GPU backend\n");
        match &self.gpu_short {
            Some(g) if !self.raster.is_empty() => {
                let mut t = Table::new([
                    "scene".to_string(),
                    format!("CPU ms ({} threads)", self.cpu_threads),
                    format!("{g} ms, its own raster"),
                    format!("{g} own / CPU"),
                    format!("{g} ms, hyrt's exact kernels"),
                    format!("{g} exact / CPU"),
                ]);
                for r in &self.raster {
                    let own = r.gpu_interpolated_ms;
                    t.row([
                        r.scene.clone(),
                        num(r.cpu_ms, 2),
                        own.map_or("-".into(), |m| num(m, 2)),
                        own.map_or("-".into(), |m| num(m / r.cpu_ms, 2)),
                        num(r.gpu_ms, 2),
                        num(r.gpu_ms / r.cpu_ms, 2),
                    ]);
                }
                let _ = writeln!(
                    md,
                    "The `visibility_raster` stage of the Table 2 frames ({w}x{h}, medians). \"Its own raster\": the \
                     device draws the pass with its own attribute interpolation and depth \
                     (`VisibilityMode::HardwareInterpolated`, not bit-identical to the CPU): the device as a plain \
                     rasterizer, the peer. \"hyrt's exact kernels\": the GPU backend as it renders, its fragment \
                     shader evaluating the CPU reference's kernels and writing the reference depth, bit-identical to \
                     the CPU (on a hardware GPU that arithmetic is cheap; on lavapipe it runs on these CPU cores). {}\n\n{}",
                    if g == "lavapipe" {
                        "lavapipe is Mesa's software rasterizer, on the same CPU cores."
                    } else {
                        "Hardware GPU."
                    },
                    t.to_markdown()
                );
            }
            _ => {
                let _ = writeln!(md, "Not measured: no GPU backend in this run (see Notes).");
            }
        }
        Section::new("Peers in the same run", md)
    }

    /// Goal rows: (goal, target, hyrt, hyrt / target). Shadow rays: hyrt's packets against
    /// Embree's faster 8-wide packet run (default or coherent context) on every scene the
    /// peers traced; the hybrid frame (every per-frame stage, the fused executor's frame)
    /// against Embree's fastest primary-ray plus fastest shadow-ray runs of the same frame,
    /// every scene and thread count; the staged frame's `visibility_raster` +
    /// `reconstruction` against hyrt's packets tracing its primary rays, every scene at the
    /// most threads (goal: a ratio of 2); on the teaser (or the first scene) also shadow
    /// rays against `rtcOccluded1`; primary rays against Embree's faster `rtcIntersect8` run
    /// on every scene (the teaser first); secondary rays (the `bounce_trace` traversal)
    /// against Embree's faster run. At the most threads unless said.
    pub fn goals(&self) -> Vec<[String; 4]> {
        let mut out = Vec::new();
        // The scene of the single-figure goals: the teaser if measured.
        let Some(main) = self.scenes.iter().find(|s| s.scene == "teaser").or(self.scenes.first()) else {
            return out;
        };
        let threads = main.shadow.iter().map(|r| r.threads).max().unwrap_or(1);
        // The fastest run with `t` threads whose method starts with `prefix`.
        let fastest = |runs: &'_ [RayRun], t: usize, prefix: &str| {
            runs.iter()
                .filter(|r| r.threads == t && r.method.starts_with(prefix))
                .max_by(|a, b| a.mrays().total_cmp(&b.mrays()))
                .cloned()
        };
        // At the most threads: the fastest run, and the peers' least time in each round.
        let best = |runs: &'_ [RayRun], prefix: &str| {
            let run = fastest(runs, threads, prefix)?;
            Some((run, per_round_least(runs, threads, prefix)))
        };
        // hyrt against a peer: rates (medians over the rounds) and the ratio round by round.
        let row = |what: &str, scene: &str, (peer, peer_rounds): (RayRun, Vec<f64>), hyrt: Option<&RayRun>| {
            let hyrt_rate = hyrt.map_or(f64::NAN, RayRun::mrays);
            [
                format!("{what} rays, {scene}, {threads} threads: {} (this run)", peer.method),
                format!("{} Mrays/s", num(peer.mrays(), 1)),
                format!("{} Mrays/s", num(hyrt_rate, 1)),
                hyrt.map_or_else(|| num(f64::NAN, 2), |h| ratio_cell(&peer_rounds, &h.rounds)),
            ]
        };
        for s in self.scenes.iter() {
            // hyrt's figure: the packets the `shadow_rays` stage uses.
            let hyrt_run = fastest(&s.shadow, threads, "hyrt packets");
            let hyrt_shadow = hyrt_run.as_ref().map_or(f64::NAN, RayRun::mrays);
            match best(&s.shadow, "Embree `rtcOccluded8`") {
                Some(peer) => out.push(row("shadow", &s.scene, peer, hyrt_run.as_ref())),
                None if s.scene == "teaser" => out.push([
                    format!(
                        "shadow rays, {}, {threads} threads: Embree `rtcOccluded8` (Embree not built: the issue's figure for 2 threads on the teaser, not this run)",
                        s.scene
                    ),
                    format!("{} Mrays/s", num(EMBREE_SHADOW_PACKET_GOAL_MRAYS, 1)),
                    format!("{} Mrays/s", num(hyrt_shadow, 1)),
                    num(hyrt_shadow / EMBREE_SHADOW_PACKET_GOAL_MRAYS, 2),
                ]),
                None => {}
            }
        }
        // The hybrid frame against Embree only tracing it: hyrt's whole frame against
        // Embree's fastest primary-ray method plus its fastest shadow-ray method, in
        // interleaved rounds, each thread count.
        for s in self.scenes.iter() {
            for race in &s.frames {
                let (e, t) = (&race.embree, race.threads);
                out.push([
                    format!(
                        "hybrid frame vs Embree tracing the same frame, {}, {t} threads: hyrt's {} frame against {} (this run, interleaved; 1.5 would be a {} ms frame)",
                        s.scene,
                        s.frame_executor.name(),
                        e.method,
                        num(e.ms / 1.5, 1)
                    ),
                    format!("{} ms", num(e.ms, 1)),
                    format!("{} ms", num(race.hyrt.ms, 1)),
                    ratio_cell(&e.rounds, &race.hyrt.rounds),
                ]);
            }
        }
        // The paper's premise: rasterizing the primary visibility and reconstructing the
        // surfaces costs at most half of tracing the primary rays (hyrt's own packets).
        for s in self.scenes.iter() {
            let Some(race) = &s.staged_frame else { continue };
            let (t, staged, p) = (&race.threads, &race.summary, &race.primary);
            let (Some(raster), Some(rec)) = (staged.ms(Stage::VisibilityRaster), staged.ms(Stage::Reconstruction))
            else {
                continue;
            };
            let rr = median(&race.raster_reconstruction).unwrap_or(f64::NAN);
            out.push([
                format!(
                    "raster + reconstruction vs hyrt's own primary rays, {}, {t} threads: the staged frame's \
                     `visibility_raster` + `reconstruction` ({} + {} ms) against {} tracing its primary rays \
                     (this run, interleaved; 2.0 would be a {} ms raster + reconstruction)",
                    s.scene,
                    num(raster, 2),
                    num(rec, 2),
                    p.method,
                    num(p.ms / 2.0, 2)
                ),
                format!("{} ms", num(p.ms, 2)),
                format!("{} ms", num(rr, 2)),
                ratio_cell(&p.rounds, &race.raster_reconstruction),
            ]);
        }
        // Primary hit points against Embree's hits of the same camera rays.
        out.extend(self.scenes.iter().filter_map(|s| hit_points::goal_row(&s.scene, &s.hit_points)));
        let hyrt_shadow = fastest(&main.shadow, threads, "hyrt packets");
        let hyrt_primary = fastest(&main.primary, threads, "hyrt packets");
        if let Some(peer) = best(&main.shadow, "Embree `rtcOccluded1`") {
            out.push(row("shadow", &main.scene, peer, hyrt_shadow.as_ref()));
        }
        if let Some(peer) = best(&main.primary, "Embree `rtcIntersect8`") {
            out.push(row("primary", &main.scene, peer, hyrt_primary.as_ref()));
        }
        for s in self.scenes.iter().filter(|s| s.scene != main.scene) {
            let hyrt_primary = fastest(&s.primary, threads, "hyrt packets");
            if let Some(peer) = best(&s.primary, "Embree `rtcIntersect8`") {
                out.push(row("primary", &s.scene, peer, hyrt_primary.as_ref()));
            }
        }
        // Secondary rays on every scene that has them: the `bounce_trace` stage's traversal
        // against Embree's faster single-ray or packet run.
        let bounce_method = hyrt_method("Bvh::closest_hit", Traversal::for_bounces());
        for s in self.scenes.iter().filter(|s| !s.secondary.is_empty()) {
            let hyrt_secondary = fastest(&s.secondary, threads, &bounce_method);
            if let Some(peer) = best(&s.secondary, "Embree `rtcIntersect") {
                out.push(row("reflection and refraction", &s.scene, peer, hyrt_secondary.as_ref()));
            }
        }
        if let Some(g) = &self.gpu_short {
            for r in self.raster.iter().filter(|r| r.scene == main.scene) {
                // The peer is the device's own raster when measured.
                let (peer, what) = match r.gpu_interpolated_ms {
                    Some(m) => (m, "its own raster"),
                    None => (r.gpu_ms, "hyrt's exact kernels"),
                };
                out.push([
                    format!("visibility raster, {}: at least as fast as {g} ({what})", r.scene),
                    format!("{} ms", num(peer, 2)),
                    format!("{} ms", num(r.cpu_ms, 2)),
                    num(peer / r.cpu_ms, 2),
                ]);
            }
        }
        out
    }
}

/// The least time in each round among the runs with `threads` threads whose method starts
/// with `prefix` (the fastest of several peers, round by round).
fn per_round_least(runs: &[RayRun], threads: usize, prefix: &str) -> Vec<f64> {
    let matching: Vec<&RayRun> = runs.iter().filter(|r| r.threads == threads && r.method.starts_with(prefix)).collect();
    let rounds = matching.iter().map(|r| r.rounds.len()).min().unwrap_or(0);
    (0..rounds).map(|i| matching.iter().map(|r| r.rounds[i]).fold(f64::INFINITY, f64::min)).collect()
}

/// The speed ratio hyrt / peer, `peer / hyrt` time, taken round by round: its median,
/// and with more than one round the least and greatest ratio of a round.
fn ratio_cell(peer: &[f64], hyrt: &[f64]) -> String {
    match round_ratios(peer, hyrt) {
        Some((m, lo, hi)) if peer.len() > 1 => format!("{} ({}–{})", num(m, 2), num(lo, 2), num(hi, 2)),
        Some((m, _, _)) => num(m, 2),
        None => num(f64::NAN, 2),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_lists_get_more_rounds() {
        assert_eq!(contest_rounds(3, 20.0), 15);
        assert_eq!(contest_rounds(3, 7.0), 43);
        assert_eq!(contest_rounds(3, 5.0), 60);
        assert_eq!(contest_rounds(3, 1.0), MAX_ROUNDS);
        assert_eq!(contest_rounds(3, MIN_CONTEST_MS), 3);
        assert_eq!(contest_rounds(3, 500.0), 3);
        assert_eq!(contest_rounds(3, 1e-6), MAX_ROUNDS);
        assert_eq!(contest_rounds(100, 1e-6), 100);
        assert_eq!(contest_rounds(3, 0.0), 3);
        assert_eq!(contest_rounds(3, f64::NAN), 3);
    }

    /// Every turn is one pass of each contender: one timed pass, the warm-up turn and the
    /// rounds (the most, for instant passes), as many for both.
    #[test]
    fn contest_turns_are_one_pass() {
        use std::cell::Cell;
        let (a, b) = (Cell::new(0usize), Cell::new(0usize));
        let contenders: Vec<Contender<'_>> =
            vec![("a".into(), Box::new(|| a.set(a.get() + 1))), ("b".into(), Box::new(|| b.set(b.get() + 1)))];
        let runs = contest(3, 1, 10, contenders);
        assert_eq!((a.get(), b.get()), (2 + MAX_ROUNDS, 2 + MAX_ROUNDS));
        assert_eq!(runs.len(), 2);
    }

    fn run(method: &str, threads: usize, ms: f64) -> RayRun {
        let mut r = RayRun::new(method, threads, 1_000_000, ms);
        if !method.contains("scalar reference") {
            r.disagreements = Some(0);
        }
        r
    }

    fn peers(scene: &str, embree: bool) -> Peers {
        let scalar = hyrt_method("Bvh::occluded", Traversal::Scalar);
        // The packets the stages run (another level is named as a comparison).
        let packets = hyrt_method("Bvh::occluded", Traversal::simd());
        let mut shadow =
            vec![run(&scalar, 1, 800.0), run(&packets, 1, 400.0), run(&scalar, 2, 400.0), run(&packets, 2, 200.0)];
        let mut primary = vec![
            run(&hyrt_method("Bvh::closest_hit", Traversal::Scalar), 2, 1000.0),
            run(&hyrt_method("Bvh::closest_hit", Traversal::simd()), 2, 500.0),
        ];
        if embree {
            shadow.push(run("Embree `rtcOccluded8` (packets of 8)", 2, 50.0));
            shadow.push(run("Embree `rtcOccluded8` (packets of 8, coherent context)", 2, 40.0));
            shadow.push(run("Embree `rtcOccluded1`", 2, 100.0));
            primary.push(run("Embree `rtcIntersect8` (packets of 8)", 2, 250.0));
        }
        Peers {
            scenes: vec![ScenePeers {
                scene: scene.into(),
                shadow,
                primary,
                hyrt_build_ms: 1.0,
                embree_build_ms: None,
                occluded: 0,
                primary_hits: 0,
                secondary: Vec::new(),
                secondary_hits: 0,
                frames: Vec::new(),
                frame_executor: Executor::Fused,
                staged_frame: None,
                hit_points: Vec::new(),
            }],
            frames: None,
            raster: vec![RasterRow {
                scene: scene.into(),
                cpu_ms: 10.0,
                gpu_ms: 90.0,
                gpu_interpolated_ms: Some(30.0),
            }],
            gpu_short: Some("lavapipe".into()),
            cpu_threads: 2,
            embree_missing: (!embree).then(|| "not built".into()),
            embree: embree
                .then(|| "Embree 3.13.5 (...): ISA avx2 selected at run time, BVH8<triangle4> (8-wide)".into()),
        }
    }

    fn table2_without_rows() -> Table2 {
        Table2 {
            rows: vec![],
            size: (64, 32),
            cpu_label: String::new(),
            gpu: None,
            gpu_errors: vec![],
            frames: 3,
            copy_gb_s: 10.0,
        }
    }

    #[test]
    fn the_section_names_the_embree_peer_or_why_it_is_missing() {
        let md = peers("teaser", true).section(&table2_without_rows()).markdown;
        assert!(md.contains("\nThe peer: Embree 3.13.5 (...): ISA avx2 selected at run time, BVH8<triangle4>"), "{md}");
        let md = peers("teaser", false).section(&table2_without_rows()).markdown;
        assert!(md.contains("\nEmbree: not built.") && !md.contains("The peer:"), "{md}");
    }

    #[test]
    fn primary_hit_points_against_embrees_get_a_goal_row_per_scene_that_has_them() {
        let mut p = peers("teaser", true);
        let has_row =
            |p: &Peers| p.goals().iter().any(|g| g[0].starts_with("primary hit points vs Embree's hits, teaser"));
        assert!(!has_row(&p), "no measurement, no row");
        let h = |barycentrics, median_rel| HitPoints {
            barycentrics,
            pixels: 10_000,
            hit_or_miss_differs: 1,
            within: 9_999,
            median_rel,
        };
        p.scenes[0].hit_points = vec![
            h(hyrt_core::frame::PrimaryBarycentrics::Reintersected, 2e-8),
            h(hyrt_core::frame::PrimaryBarycentrics::Raster, 3e-6),
        ];
        let goals = p.goals();
        let row = goals.iter().find(|g| g[0].starts_with("primary hit points vs Embree's hits, teaser")).unwrap();
        assert_eq!(row[3], "1.00", "{row:?}");
        assert!(row[0].contains("raster barycentrics: median 3.0e-6"), "{row:?}");
    }

    #[test]
    fn goals_use_this_runs_embree_figures_at_the_most_threads() {
        let g = peers("teaser", true).goals();
        // 1M rays: hyrt 200 ms = 5 Mrays/s; Embree packets 50 ms = 20 Mrays/s, with the
        // coherent context 40 ms = 25 Mrays/s: the faster is the target.
        assert_eq!(g[0][1..], ["25.0 Mrays/s".to_string(), "5.0 Mrays/s".into(), "0.20".into()]);
        assert!(g[0][0].contains("2 threads") && g[0][0].contains("this run"), "{:?}", g[0]);
        assert!(g[0][0].contains("coherent context"), "{:?}", g[0]);
        assert_eq!(g[1][3], "0.50"); // against rtcOccluded1 (10 Mrays/s)
        assert_eq!(g[2][3], "0.50"); // primary: 2 Mrays/s against 4 Mrays/s
        assert_eq!(g[3][1..], ["30.00 ms".to_string(), "10.00 ms".into(), "3.00".into()]);
        assert_eq!(g.len(), 4);
    }

    /// A ray goal's ratio is taken round by round against the fastest peer of each round:
    /// rounds the machine slowed for both contenders do not move it.
    #[test]
    fn goal_ratios_are_the_median_of_the_rounds_against_each_rounds_fastest_peer() {
        let mut p = peers("teaser", true);
        let shadow = &mut p.scenes[0].shadow;
        let rounds = |method: &str, ms: &[f64]| RayRun::of_rounds(method, 2, 1_000_000, ms.to_vec());
        // hyrt's packets: 200, 400 (a slow round), 100 ms.
        shadow[3] = rounds(&shadow[3].method.clone(), &[200.0, 400.0, 100.0]);
        // Two Embree packet runs: the faster of each round is 40, 80, 25 ms.
        shadow[4] = rounds(&shadow[4].method.clone(), &[50.0, 80.0, 25.0]);
        shadow[5] = rounds(&shadow[5].method.clone(), &[40.0, 90.0, 30.0]);
        let g = p.goals();
        // Rounds: 40/200, 80/400, 25/100 = 0.20, 0.20, 0.25; median 0.20.
        assert_eq!(g[0][3], "0.20 (0.20–0.25)", "{:?}", g[0]);
        assert_eq!(RayRun::of_rounds("x", 1, 10, vec![3.0, 1.0, 2.0]).ms, 2.0);
    }

    /// The hybrid frame against Embree tracing the same frame's rays, one row per race
    /// (thread count), its ratio the median of the rounds' ratios with their range.
    #[test]
    fn the_hybrid_frame_is_set_against_embree_tracing_the_same_frame_round_by_round() {
        let mut p = peers("teaser", true);
        assert!(p.goals().iter().all(|r| !r[0].starts_with("hybrid frame")), "no race, no row");
        let embree = "Embree `rtcIntersect8` (packets of 8) + Embree `rtcOccluded8` (packets of 8, coherent context)";
        // Rounds of 290, 580 (a slow round for both), 300 ms against 145, 290, 100 ms.
        p.scenes[0].frames = vec![FrameRace {
            threads: 2,
            hyrt: RayRun::of_rounds("hyrt", 2, 1_000, vec![145.0, 290.0, 100.0]),
            embree: RayRun::of_rounds(embree, 2, 2_000, vec![290.0, 580.0, 300.0]),
        }];
        let g = p.goals();
        let rows: Vec<_> = g.iter().filter(|r| r[0].starts_with("hybrid frame vs Embree")).collect();
        assert_eq!(rows.len(), 1, "{g:?}");
        // Medians 300 and 145 ms; ratios 2, 2, 3 round by round.
        assert_eq!(rows[0][1..], ["300.0 ms".to_string(), "145.0 ms".into(), "2.00 (2.00–3.00)".into()]);
        assert!(rows[0][0].contains("teaser, 2 threads") && rows[0][0].contains("coherent context"), "{:?}", rows[0]);
        assert!(rows[0][0].contains("hyrt's fused frame against Embree `rtcIntersect8`"), "{:?}", rows[0]);
        assert!(rows[0][0].contains("1.5 would be a 200.0 ms frame"), "{:?}", rows[0]);
    }

    /// The paper's premise: the staged frame's raster + reconstruction against hyrt's own
    /// packets tracing the primary rays, with or without Embree.
    #[test]
    fn raster_and_reconstruction_are_set_against_hyrts_own_primary_rays_round_by_round() {
        for embree in [true, false] {
            let mut p = peers("teaser", embree);
            let staged = FrameSummary {
                frames: 3,
                stage_ms: vec![
                    (Stage::VisibilityRaster, 150.0),
                    (Stage::Reconstruction, 50.0),
                    (Stage::ShadowRays, 9.0),
                ],
                frame_ms: 300.0,
            };
            // Rounds of raster + reconstruction 200, 400 (a slow round for both), 190 ms
            // against the primary rays' 500, 1000, 380 ms.
            let primary = hyrt_method("Bvh::closest_hit", Traversal::simd());
            p.scenes[0].staged_frame = Some(StagedRace {
                threads: 2,
                summary: staged,
                raster_reconstruction: vec![200.0, 400.0, 190.0],
                primary: RayRun::of_rounds(&primary, 2, 1_000_000, vec![500.0, 1000.0, 380.0]),
            });
            let g = p.goals();
            let rows: Vec<_> = g.iter().filter(|r| r[0].starts_with("raster + reconstruction vs hyrt's own")).collect();
            assert_eq!(rows.len(), 1, "{g:?}");
            // Medians 500 and 200 ms; ratios 2.5, 2.5, 2 round by round.
            assert_eq!(rows[0][1..], ["500.00 ms".to_string(), "200.00 ms".into(), "2.50 (2.00–2.50)".into()]);
            assert!(rows[0][0].contains("teaser, 2 threads"), "{:?}", rows[0]);
            assert!(rows[0][0].contains("(150.00 + 50.00 ms) against hyrt packets of 8"), "{:?}", rows[0]);
            assert!(rows[0][0].contains("2.0 would be a 250.00 ms raster + reconstruction"), "{:?}", rows[0]);
        }
        // Without the staged frame, no row.
        assert!(peers("teaser", true).goals().iter().all(|r| !r[0].starts_with("raster + reconstruction")));
    }

    #[test]
    fn secondary_rays_get_a_table_and_a_goal_against_embrees_faster_intersect() {
        let mut p = peers("teaser", true);
        let packets = hyrt_method("Bvh::closest_hit", Traversal::Packet(hyrt_cpu::traversal::SimdLevel::Portable));
        let single = hyrt_method("Bvh::closest_hit", Traversal::for_bounces());
        p.scenes[0].secondary = vec![
            run(&hyrt_method("Bvh::closest_hit", Traversal::Scalar), 2, 400.0),
            // The goal takes the `bounce_trace` stage's traversal, not the faster packets.
            run(&packets, 2, 200.0),
            run(&single, 2, 250.0),
            run("Embree `rtcIntersect1`", 2, 125.0),
            run("Embree `rtcIntersect8` (packets of 8)", 2, 200.0),
        ];
        p.scenes[0].secondary_hits = 7;
        let g = p.goals();
        // 1M rays: hyrt's single rays 4 Mrays/s; Embree's faster is rtcIntersect1 at 8.
        let row = g.iter().find(|r| r[0].starts_with("reflection and refraction rays, teaser")).expect("a goal row");
        assert!(row[0].contains("rtcIntersect1"), "{row:?}");
        assert_eq!(row[1..], ["8.0 Mrays/s".to_string(), "4.0 Mrays/s".into(), "0.50".into()]);
        let table2 = table2_without_rows();
        let md = p.section(&table2).markdown;
        assert!(md.contains("### teaser: reflection and refraction rays"), "{md}");
        assert!(md.contains("1,000,000 rays, 7 of them hit (hyrt)"), "{md}");
        // A scene without them says so instead of a table.
        let md = peers("teaser", true).section(&table2).markdown;
        assert!(md.contains("None: no ray-traced mirror or glass in view."), "{md}");
    }

    #[test]
    fn every_traced_scene_gets_a_shadow_and_a_primary_packet_goal() {
        let mut p = peers("teaser", true);
        let mut sponza = p.scenes[0].clone();
        sponza.scene = "sponza".into();
        sponza.shadow.retain(|r| !r.method.contains("coherent"));
        p.scenes.push(sponza);
        let g = p.goals();
        assert_eq!(g.len(), 6, "{g:?}");
        // Primary rays: the teaser's, then Sponza's.
        let primary: Vec<&str> = g.iter().filter(|r| r[0].starts_with("primary rays")).map(|r| r[0].as_str()).collect();
        assert_eq!(primary.len(), 2, "{g:?}");
        assert!(primary[0].starts_with("primary rays, teaser") && primary[1].starts_with("primary rays, sponza"));
        assert!(
            g[1][0].starts_with("shadow rays, sponza, 2 threads: Embree `rtcOccluded8` (packets of 8)"),
            "{:?}",
            g[1]
        );
        assert_eq!(g[1][3], "0.25");
        // The single-figure goals stay on the teaser.
        assert!(g[2][0].contains("teaser") && g[2][0].contains("rtcOccluded1"), "{:?}", g[2]);
    }

    #[test]
    fn frame_table_has_every_frame_stage_and_the_ratio_row() {
        let summary = |shadow: f64| FrameSummary {
            frames: 3,
            // The paper's frame: no bounce stage and no denoiser ran, so the table has no
            // column for them.
            stage_ms: Stage::ALL
                .iter()
                .filter(|s| {
                    ![Stage::SecondaryRays, Stage::BounceTrace, Stage::BounceShading, Stage::ShadowDenoise].contains(s)
                })
                .map(|&s| (s, if s == Stage::ShadowRays { shadow } else { 1.0 }))
                .collect(),
            frame_ms: 6.0 + shadow,
        };
        let f = FrameTraversals {
            scene: "teaser".into(),
            runs: vec![("scalar".into(), summary(40.0)), ("packet-avx2".into(), summary(10.0))],
        };
        let md = frame_traversal_table(&f, 2, (1280, 720));
        assert!(md.starts_with("### teaser: the CPU frame per stage"), "{md}");
        assert!(!md.contains("bvh_build"), "{md}");
        assert!(md.contains("| scalar (ms) | 1.00 | 1.00 | 1.00 | 40.00 | 1.00 | 1.00 | 1.00 | 46.00 |"), "{md}");
        assert!(md.contains("| scalar / packets | 1.00 | 1.00 | 1.00 | 4.00 | 1.00 | 1.00 | 1.00 | 2.88 |"), "{md}");
    }

    #[test]
    fn without_embree_the_issues_figure_is_the_goal_on_the_teaser_only() {
        let g = peers("teaser", false).goals();
        assert!(g[0][0].contains("Embree not built"), "{:?}", g[0]);
        assert_eq!(g[0][1], format!("{EMBREE_SHADOW_PACKET_GOAL_MRAYS:.1} Mrays/s"));
        assert_eq!(g.len(), 2); // and the raster goal
        let g = peers("default", false).goals();
        assert!(g.iter().all(|r| !r[0].contains("Embree")), "{g:?}");
    }

    #[test]
    fn ray_table_compares_each_run_with_hyrt_scalar_at_the_same_thread_count() {
        let p = peers("teaser", true);
        let md = ray_table(&p.scenes[0].shadow, false).to_markdown();
        assert!(
            md.contains("| Embree `rtcOccluded8` (packets of 8) | 2 | 1,000,000 | 50.00 | 20.00 | 8.00 | 0 |"),
            "{md}"
        );
        assert!(
            md.contains("| hyrt `Bvh::occluded` per ray (scalar reference) | 1 | 1,000,000 | 800.00 | 1.25 | 1.00 | (reference) |"),
            "{md}"
        );
        let row = format!(
            "| {} | 1 | 1,000,000 | 400.00 | 2.50 | 2.00 | 0 |",
            hyrt_method("Bvh::occluded", Traversal::simd())
        );
        assert!(md.contains(&row), "{md}");
    }

    /// Packets at a level other than the stages' traversal are named as a comparison, so
    /// that the goals (which take "hyrt packets") keep to the stages' traversal (measured
    /// per kind of walk where the CPU has AVX-512: every fixed level is then a comparison).
    #[test]
    fn packets_at_another_level_are_not_the_stages_packets() {
        use hyrt_cpu::traversal::SimdLevel;
        assert!(hyrt_method("Bvh::occluded", Traversal::simd()).starts_with("hyrt packets"));
        for level in SimdLevel::available() {
            let name = hyrt_method("Bvh::occluded", Traversal::Packet(level));
            if Traversal::Packet(level) != Traversal::simd() {
                assert!(!name.starts_with("hyrt packets") && name.contains("for comparison"), "{name}");
            }
        }
        assert_eq!(hyrt_simd()[..2], [Traversal::simd(), Traversal::for_bounces()]);
    }
}
