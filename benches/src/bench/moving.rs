//! Moving scenes (issue 17): what moving objects costs per frame, measured in one run.
//!
//! On the teaser (the bunny moving in Sponza; the default scene's sphere when the shared
//! models are absent) and on a scene of many instances of one mesh (the teaser's bunny
//! copied [`GRID`] times on a grid in Sponza's aisle, all moving, one bottom level), each
//! frame moves and turns the moving objects a little, then, interleaved round by round
//! ([`interleaved_rounds_ms`]; the move itself is set up untimed before each round):
//!
//! * **hyrt update**: [`PreparedScene::move_objects`] (the objects' references, records and
//!   instances rewritten, the top level rebuilt, no bottom level touched);
//! * **hyrt rebuild**: the moved scene prepared again flat ([`WorldGeometry::build`] and
//!   the single-level BVH, `Renderer::prepare`: what a move cost before the two levels);
//! * **Embree two-level update** (feature `embree`): the objects as instances of
//!   object-space scenes, the static rest one triangle geometry of the top scene;
//!   `rtcSetGeometryTransform` + `rtcCommitGeometry` per instance, `rtcCommitScene` of the
//!   top scene;
//! * **Embree rebuild**: a new flat scene of the moved world triangles (`rtcCommitScene`).
//!
//! Then the frame: the CPU backend's (and the GPU backend's, when measured) frame of the
//! two-level scene against the same moved scene prepared flat, interleaved frame by frame. After the last round the
//! primary rays of a small image are traced through every scene and compared hit by hit,
//! so that the section says whether the contenders trace the same moved scene.

use std::cell::RefCell;
use std::fmt::Write as _;

use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::{CameraRecord, RayRecord};
use hyrt_core::frame::{Backend, Frame, FrameStats, PreparedScene, RenderError};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::glam::{Mat4, Quat, Vec3};
use hyrt_core::kernels::camera::primary_rays;
use hyrt_core::scene::Scene;
use hyrt_cpu::backend::CpuBackend;
use indicatif::ProgressBar;

use super::report::{count, num, Section, Table};
use super::stats::{interleaved_rounds_ms, median, range, round_ratios, FrameSummary};
use super::{paper_frame, BenchError, BenchOptions, BenchScene, FrameBackend};

/// Instances of the many-instances scene (a grid of `GRID_X` by `GRID / GRID_X`) in full
/// runs; [`GRID_QUICK`] in quick runs.
pub const GRID: usize = 64;
pub const GRID_QUICK: usize = 16;
/// Frames (rounds) of the many-instances scene at the most: its rebuilds take seconds.
const MANY_FRAMES: usize = 7;
/// Frames per scene of the GPU backend at the most (a lavapipe frame takes seconds); none in
/// quick runs.
const GPU_FRAMES: usize = 3;
const GRID_X: usize = 16;

/// One contender's per-frame times.
#[derive(Clone, Debug, PartialEq)]
pub struct Timing {
    pub what: String,
    /// Milliseconds of each round (frame).
    pub rounds: Vec<f64>,
}

impl Timing {
    fn median(&self) -> f64 {
        median(&self.rounds).unwrap_or(f64::NAN)
    }
}

/// Hit-by-hit comparison of the contenders' scenes after the last frame, on primary rays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Check {
    pub size: (u32, u32),
    pub rays: usize,
    /// Rays hyrt's two-level scene hits on a moving object.
    pub moving_hits: usize,
    /// Rays hyrt's two-level scene hits at all.
    pub hits: usize,
    /// Rays whose triangle differs between hyrt's two-level scene and the rebuilt one.
    pub hyrt_rebuilt_differ: usize,
    /// Embree's two-level and flat scenes against hyrt's two-level one: rays whose hit or
    /// miss differs, and rays both hit on different objects.
    pub embree_two_level: Option<(usize, usize)>,
    pub embree_flat: Option<(usize, usize)>,
}

/// Frame times of the two-level scene against the flat one on one backend.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameCost {
    pub backend: String,
    pub flat: FrameSummary,
    pub two_level: FrameSummary,
}

/// One moving scene's measurements.
#[derive(Clone, Debug, PartialEq)]
pub struct MovingScene {
    pub name: String,
    /// What moves, in words.
    pub moving: String,
    pub triangles: usize,
    pub moving_triangles: usize,
    /// hyrt update, hyrt rebuild, then Embree's update and rebuild when built.
    pub timings: Vec<Timing>,
    pub frames: Vec<FrameCost>,
    /// Frame failures (a backend that could not render a scene).
    pub frame_errors: Vec<String>,
    pub check: Check,
}

/// The section's measurements.
pub struct Moving {
    pub scenes: Vec<MovingScene>,
    pub size: (u32, u32),
    pub threads: usize,
    /// Why Embree is missing, when it is.
    pub embree_missing: Option<String>,
    /// Why the GPU backend's frames are not measured although it is there, when they are not.
    pub gpu_skipped: Option<String>,
}

/// The object-to-world transform of an object at `rest` in frame `frame`: turned about
/// its own origin by 3 degrees a frame about y and carried `step` further along x.
pub fn frame_transform(rest: Mat4, frame: usize, step: f32) -> Mat4 {
    let f = frame as f32;
    let centre = rest.w_axis.truncate();
    Mat4::from_translation(centre + Vec3::X * step * f)
        * Mat4::from_quat(Quat::from_rotation_y(f * 3f32.to_radians()))
        * Mat4::from_translation(-centre)
        * rest
}

/// The teaser with its bunny copied `n` times (sharing its mesh and material) on a grid
/// in Sponza's aisle in front of the camera, each a quarter of the teaser bunny's size;
/// the teaser's own bunny removed. `None` without an object named like "bunny".
pub fn many_bunnies(teaser: &Scene, n: usize) -> Option<(Scene, Vec<u32>)> {
    let bunny = teaser.objects.iter().position(|o| o.name.to_lowercase().contains("bunny"))?;
    let mut scene = teaser.clone();
    let template = scene.objects.remove(bunny);
    for (i, o) in scene.objects.iter_mut().enumerate() {
        o.id = i as u32;
    }
    // The teaser bunny is 25x its file's size with its base on the floor at x = z = 0;
    // a quarter of it (about 0.95 m tall) on a grid of 1.1 m in x and 1.2 m in z.
    let quarter = Mat4::from_translation(Vec3::new(0.0, 0.0933, 0.0))
        * Mat4::from_scale(Vec3::splat(0.25))
        * Mat4::from_translation(Vec3::new(0.0, -0.0933, 0.0))
        * template.transform;
    let rows = n.div_ceil(GRID_X);
    let mut moving = Vec::with_capacity(n);
    for i in 0..n {
        let (x, z) = ((i % GRID_X) as f32, (i / GRID_X) as f32);
        let at = Vec3::new(-5.5 + 1.1 * x, 0.0, 1.2 * (z - 0.5 * (rows as f32 - 1.0)));
        let id = scene.objects.len() as u32;
        let mut o = template.clone();
        o.id = id;
        o.name = format!("{}#{i}", template.name);
        o.transform = Mat4::from_translation(at) * quarter;
        scene.objects.push(o);
        moving.push(id);
    }
    Some((scene, moving))
}

/// A scene the section moves: its name, the scene, the moving objects, what moves in
/// words, and the frames (rounds) to measure at the most.
pub type MovingSetup = (String, Scene, Vec<u32>, String, usize);

/// The scenes the section moves, from the benchmark's scenes: the teaser (bunny) and the
/// scene of `bunnies` bunnies when the teaser is among them, else the default scene's
/// sphere.
pub fn moving_scenes(scenes: &[BenchScene], bunnies: usize) -> Vec<MovingSetup> {
    let named = |s: &BenchScene, part: &str| {
        let o = s.scene.objects.iter().position(|o| o.name.to_lowercase().contains(part))?;
        let what = format!("the {part} ({})", s.scene.objects[o].name);
        Some((s.name.clone(), s.scene.clone(), vec![o as u32], what, usize::MAX))
    };
    if let Some(teaser) = scenes.iter().find(|s| s.name == "teaser") {
        let mut out: Vec<_> = named(teaser, "bunny").into_iter().collect();
        if let Some((scene, moving)) = many_bunnies(&teaser.scene, bunnies) {
            let what = format!("{bunnies} bunnies sharing one mesh");
            out.push((format!("teaser, {bunnies} bunnies"), scene, moving, what, MANY_FRAMES));
        }
        return out;
    }
    scenes.iter().find(|s| s.name == "default").and_then(|s| named(s, "sphere")).into_iter().collect()
}

/// Measure every moving scene of `scenes` ([`moving_scenes`]).
pub fn run(
    options: &BenchOptions,
    scenes: &[BenchScene],
    cpu: &mut FrameBackend,
    mut gpu: Option<&mut FrameBackend>,
    progress: &ProgressBar,
) -> Result<Moving, BenchError> {
    let threads = options.frame_threads.unwrap_or_else(rayon::current_num_threads);
    let mut out = Moving {
        scenes: Vec::new(),
        size: options.table_size,
        threads,
        embree_missing: (!cfg!(feature = "embree")).then(super::peers::embree_peer),
        gpu_skipped: None,
    };
    if options.quick && gpu.is_some() {
        gpu = None;
        out.gpu_skipped = Some(format!(
            "the GPU backend's frames are measured in full runs only ({GPU_FRAMES} frames a scene: a lavapipe frame takes \
             seconds)"
        ));
    }
    let bunnies = if options.quick { GRID_QUICK } else { GRID };
    for (name, scene, moving, what, frames) in moving_scenes(scenes, bunnies) {
        progress.set_message(format!("moving scenes: {name}"));
        let options = BenchOptions { frames: options.frames.min(frames), ..options.clone() };
        let m = measure(&options, &name, scene, &moving, what, cpu, gpu.as_deref_mut(), &mut out.embree_missing)?;
        out.scenes.push(m);
    }
    Ok(out)
}

/// The paper's frame ([`paper_frame`]) of each of `scenes` on one backend, interleaved: a
/// warm-up frame of each, then `frames` rounds of one frame of each, the order rotated
/// each round ([`interleaved_rounds_ms`]); per scene, the summary of its measured frames.
fn interleaved_frames(
    backend: &mut dyn Backend,
    scenes: [&PreparedScene; 2],
    camera: &CameraRecord,
    frames: usize,
) -> Result<[FrameSummary; 2], RenderError> {
    let options = paper_frame();
    let backend = RefCell::new(backend);
    let error = RefCell::new(None);
    let stats: [RefCell<Vec<FrameStats>>; 2] = Default::default();
    let mut runs = [0, 1].map(|i| {
        let (backend, error, stats, mut frame) = (&backend, &error, &stats[i], Frame::default());
        move || match backend.borrow_mut().render_into(scenes[i], camera, &options, &mut frame) {
            Ok(()) => stats.borrow_mut().push(frame.stats.clone()),
            Err(e) => *error.borrow_mut() = Some(e),
        }
    });
    let [a, b] = &mut runs;
    interleaved_rounds_ms(frames, &mut |_| {}, &mut [a, b]);
    if let Some(e) = error.into_inner() {
        return Err(e);
    }
    // The first frame of each was the warm-up.
    let summary = |s: RefCell<Vec<FrameStats>>| {
        FrameSummary::from_frames(&s.into_inner()[1..])
            .ok_or_else(|| RenderError::InvalidOptions("no frame was measured".into()))
    };
    let [s0, s1] = stats;
    Ok([summary(s0)?, summary(s1)?])
}

/// Where hyrt's closest hit lands for each ray (global triangle index).
fn hyrt_hits(prepared: &PreparedScene, rays: &[RayRecord]) -> Vec<Option<u32>> {
    let t = prepared.geometry.traversal_table();
    rays.iter()
        .map(|r| match &prepared.levels {
            Some(l) => l.closest_hit(r),
            None => prepared.bvh.closest_hit(t, r),
        })
        .map(|h| h.map(|h| h.triangle))
        .collect()
}

/// Rays whose hit or miss differs, and rays both hit on different objects.
#[cfg_attr(not(feature = "embree"), allow(dead_code))]
fn compare(g: &WorldGeometry, a: &[Option<u32>], b: &[Option<u32>]) -> (usize, usize) {
    let object = |t: u32| g.triangle(t as usize).object;
    let miss = a.iter().zip(b).filter(|(a, b)| a.is_some() != b.is_some()).count();
    let other =
        a.iter().zip(b).filter(|(a, b)| matches!((a, b), (Some(x), Some(y)) if object(*x) != object(*y))).count();
    (miss, other)
}

#[allow(clippy::too_many_arguments)]
fn measure(
    options: &BenchOptions,
    name: &str,
    scene: Scene,
    moving: &[u32],
    what: String,
    cpu: &mut FrameBackend,
    gpu: Option<&mut FrameBackend>,
    embree_missing: &mut Option<String>,
) -> Result<MovingScene, BenchError> {
    let preset = BvhPreset::default();
    let builder = CpuBackend::new(options.frame_threads);
    let rests: Vec<Mat4> = moving.iter().map(|&o| scene.objects[o as usize].transform).collect();
    let step = scene.world_bounds().map_or(0.01, |(lo, hi)| (hi - lo).length() * 1e-3);
    let world = WorldGeometry::build(&scene);
    let prepared = hyrt_cpu::bvh_build::prepare_moving(&scene, preset, moving);
    #[cfg(feature = "embree")]
    let embree = {
        use super::embree::{EmbreeInstances, EmbreeScene};
        let config = format!("threads={}", options.frame_threads.unwrap_or_else(rayon::current_num_threads));
        match (EmbreeInstances::new(&scene, &world, moving, &config), EmbreeScene::new(&world, &config)) {
            (Ok(i), Ok(f)) => Some((RefCell::new(i), RefCell::new(f))),
            (Err(e), _) | (_, Err(e)) => {
                *embree_missing = Some(e.to_string());
                None
            }
        }
    };
    #[cfg(not(feature = "embree"))]
    let _ = &embree_missing;
    let scene = RefCell::new(scene);
    let world = RefCell::new(world);
    let prepared = RefCell::new(prepared);
    let rebuilt: RefCell<Option<PreparedScene>> = RefCell::new(None);
    let failed: RefCell<Option<String>> = RefCell::new(None);
    let mut setup = |frame: usize| {
        let mut s = scene.borrow_mut();
        for (&o, rest) in moving.iter().zip(&rests) {
            s.objects[o as usize].transform = frame_transform(*rest, frame, step);
        }
        // The moved world triangles Embree's rebuild takes (hyrt's own are its contenders' work).
        let mut w = world.borrow_mut();
        for &o in moving {
            w.update_object(&s, o);
        }
    };
    let mut update = || {
        if let Err(e) = prepared.borrow_mut().move_objects(&scene.borrow(), moving) {
            *failed.borrow_mut() = Some(e.to_string());
        }
    };
    let mut rebuild = || {
        *rebuilt.borrow_mut() = Some(builder.prepare(WorldGeometry::build(&scene.borrow()), preset));
    };
    #[cfg_attr(not(feature = "embree"), allow(unused_mut))]
    let mut contenders: Vec<(String, &mut dyn FnMut())> = vec![
        ("hyrt update: `move_objects`".into(), &mut update),
        ("hyrt rebuild: `WorldGeometry::build` + `Bvh::build` (`Renderer::prepare`)".into(), &mut rebuild),
    ];
    #[cfg(feature = "embree")]
    let (mut embree_update, mut embree_rebuild);
    #[cfg(feature = "embree")]
    if let Some((inst, flat)) = &embree {
        embree_update = || {
            let mut inst = inst.borrow_mut();
            let s = scene.borrow();
            let objects: Vec<u32> = inst.objects().collect();
            for (i, o) in objects.into_iter().enumerate() {
                inst.set_transform(i, &s.objects[o as usize].transform);
            }
            if let Err(e) = inst.commit() {
                *failed.borrow_mut() = Some(e.to_string());
            }
        };
        embree_rebuild = || {
            if let Err(e) = flat.borrow_mut().rebuild(&world.borrow()) {
                *failed.borrow_mut() = Some(e.to_string());
            }
        };
        contenders.push((
            "Embree two-level update: `rtcSetGeometryTransform` + `rtcCommitGeometry` per instance, `rtcCommitScene` of the top scene"
                .into(),
            &mut embree_update,
        ));
        contenders.push((
            "Embree rebuild: a new flat scene of the moved triangles, `rtcCommitScene`".into(),
            &mut embree_rebuild,
        ));
    }
    let (names, mut runs): (Vec<String>, Vec<&mut dyn FnMut()>) = contenders.into_iter().unzip();
    let ms = interleaved_rounds_ms(options.frames, &mut setup, &mut runs);
    drop(runs);
    if let Some(e) = failed.into_inner() {
        return Err(BenchError::Options(format!("{name}: moving the objects failed: {e}")));
    }
    let timings = names.into_iter().zip(ms).map(|(what, rounds)| Timing { what, rounds }).collect();
    let scene = scene.into_inner();
    let prepared = prepared.into_inner();
    let rebuilt = rebuilt.into_inner().expect("the rebuild ran");

    // The contenders' scenes after the last frame, hit by hit.
    let camera = scene.camera.expect("bench scenes have a camera");
    let check_size = ((options.table_size.0 / 4).max(1), (options.table_size.1 / 4).max(1));
    let rays = primary_rays(&CameraRecord::new(&camera, check_size.0, check_size.1));
    let hyrt = hyrt_hits(&prepared, &rays);
    let g = &prepared.geometry;
    #[cfg_attr(not(feature = "embree"), allow(unused_mut))]
    let mut check = Check {
        size: check_size,
        rays: rays.len(),
        moving_hits: hyrt.iter().flatten().filter(|&&t| moving.contains(&g.triangle(t as usize).object)).count(),
        hits: hyrt.iter().flatten().count(),
        hyrt_rebuilt_differ: hyrt.iter().zip(hyrt_hits(&rebuilt, &rays)).filter(|(a, b)| **a != *b).count(),
        ..Check::default()
    };
    #[cfg(feature = "embree")]
    if let Some((inst, flat)) = &embree {
        let mut e = vec![None; rays.len()];
        inst.borrow().intersect1(&rays, &mut e);
        check.embree_two_level = Some(compare(g, &hyrt, &e));
        flat.borrow().intersect1(&rays, &mut e);
        check.embree_flat = Some(compare(g, &hyrt, &e));
    }

    // The frame of the two-level scene against the flat one, same camera and size.
    let record = CameraRecord::new(&camera, options.table_size.0, options.table_size.1);
    let mut frames = Vec::new();
    let mut frame_errors = Vec::new();
    for (b, n) in [(cpu, options.frames)].into_iter().chain(gpu.map(|g| (g, options.frames.min(GPU_FRAMES)))) {
        match interleaved_frames(b.backend.as_mut(), [&rebuilt, &prepared], &record, n) {
            Ok([flat, two_level]) => frames.push(FrameCost { backend: b.short.clone(), flat, two_level }),
            Err(e) => {
                // One list item: the error's lines joined.
                let e = e.to_string().split_whitespace().collect::<Vec<_>>().join(" ");
                frame_errors.push(format!("{name}: {} frame failed: {e}", b.short))
            }
        }
    }
    let moving_triangles = moving.iter().map(|&o| scene.meshes[scene.objects[o as usize].mesh].indices.len()).sum();
    Ok(MovingScene {
        name: name.to_string(),
        moving: what,
        triangles: g.triangles.len(),
        moving_triangles,
        timings,
        frames,
        frame_errors,
        check,
    })
}

impl Moving {
    /// The report section.
    pub fn section(&self) -> Section {
        let mut md = String::new();
        let _ = writeln!(
            md,
            "Objects that move between frames, prepared once with two levels (each moving object an instance of its \
             mesh's object-space bottom level, the static rest baked into one world-space bottom level) and moved \
             each frame, against preparing the moved scene again, with Embree doing the same in this run. Each frame \
             moves every moving object a little along x and turns it 3 degrees about its own y axis; the move is \
             set untimed, then the contenders take it in turn, interleaved, the order rotated each frame. Medians \
             over the frames with the least and greatest in brackets; ratios hyrt / Embree are taken frame by frame \
             (above 1: Embree is faster). Embree's rebuild is given the moved world triangles (made untimed) and copies \
             them into a new scene; hyrt's rebuild makes them too. hyrt's update runs on one thread (the calling \
             one); hyrt's rebuild and Embree run on {} threads.\n",
            self.threads
        );
        if let Some(why) = &self.embree_missing {
            let _ = writeln!(md, "Embree not measured: {why}.\n");
        }
        if let Some(why) = &self.gpu_skipped {
            let _ = writeln!(md, "Not measured here: {why}.\n");
        }
        for s in &self.scenes {
            md += &s.markdown(self.size);
        }
        if self.scenes.is_empty() {
            md += "No scene measured: neither the teaser nor the default scene is among this run's scenes.\n";
        }
        Section::new("Moving scenes", md)
    }
}

impl MovingScene {
    fn markdown(&self, (w, h): (u32, u32)) -> String {
        let mut md = String::new();
        let _ = writeln!(
            md,
            "### {}: {} moving ({} of {} triangles)\n",
            self.name,
            self.moving,
            count(self.moving_triangles as u64),
            count(self.triangles as u64)
        );
        let mut t = Table::new(["per frame", "median (ms)", "range (ms)", "hyrt / Embree"]);
        // hyrt's update against Embree's update, hyrt's rebuild against Embree's rebuild.
        let peer = |i: usize| self.timings.get(i + 2).map(|p| &p.rounds);
        for (i, timing) in self.timings.iter().enumerate() {
            let (lo, hi) = range(&timing.rounds).unwrap_or((f64::NAN, f64::NAN));
            let ratio = match (i < 2).then(|| peer(i)).flatten() {
                Some(p) => round_ratios(&timing.rounds, p)
                    .map_or(String::new(), |(m, lo, hi)| format!("{} ({}–{})", ratio(m), ratio(lo), ratio(hi))),
                None => String::new(),
            };
            t.row([timing.what.clone(), num(timing.median(), 3), format!("{}–{}", num(lo, 3), num(hi, 3)), ratio]);
        }
        md += &t.to_markdown();
        let frames = self.timings.first().map_or(0, |t| t.rounds.len());
        let _ = write!(md, "\n{frames} frames.");
        if let [update, rebuild, ..] = &self.timings[..] {
            let _ =
                write!(md, " hyrt's update is {}x faster than its rebuild", num(rebuild.median() / update.median(), 1));
            if let [_, _, e_update, e_rebuild] = &self.timings[..] {
                let _ = write!(
                    md,
                    "; Embree's two-level update is {}x faster than its rebuild. Frame by frame, hyrt's update \
                     took {}x the time of Embree's and hyrt's rebuild {}x that of Embree's (medians of the \
                     per-frame ratios)",
                    num(e_rebuild.median() / e_update.median(), 1),
                    ratio(round_ratios(&update.rounds, &e_update.rounds).map_or(f64::NAN, |r| r.0)),
                    ratio(round_ratios(&rebuild.rounds, &e_rebuild.rounds).map_or(f64::NAN, |r| r.0)),
                );
            }
            md += ".";
        }
        md += " hyrt's moving objects are kept by reference in its world tables (their mesh and transform; \
               the raster and shading stages make their world records when they read them), so its update \
               sets their transforms and records, recomputes their bounds (one pass over their vertices) and \
               every instance box, and rebuilds the top level; Embree's update sets the instance transforms \
               and commits its top scene.\n\n";
        let c = &self.check;
        let _ = write!(
            md,
            "Check after the last frame, {} primary rays at {}x{}: hyrt's two-level scene hits {} ({} on the moving \
             objects); hyrt's rebuilt scene hits another triangle on {}",
            count(c.rays as u64),
            c.size.0,
            c.size.1,
            count(c.hits as u64),
            count(c.moving_hits as u64),
            count(c.hyrt_rebuilt_differ as u64)
        );
        for (what, e) in [("Embree's two-level scene", c.embree_two_level), ("Embree's rebuilt scene", c.embree_flat)] {
            if let Some((miss, other)) = e {
                let _ = write!(
                    md,
                    "; {what} differs in hit or miss on {} and hits another object on {}",
                    count(miss as u64),
                    count(other as u64)
                );
            }
        }
        md += " (Embree's triangle test is not watertight: a few rays on shared edges may differ).";
        if c.moving_hits == 0 {
            md += " **No ray hit a moving object: the moves were not seen by these rays.**";
        }
        md += "\n\n";
        if !self.frames.is_empty() {
            let _ = writeln!(
                md,
                "The frame at {w}x{h} (the paper's frame, shadow rays only; on the CPU backend with the staged executor, as \
                 Table 2's per-stage table; medians over the frames, the two interleaved) of the \
                 scene after the last move, prepared with two levels and prepared flat:\n"
            );
            let mut t = Table::new(["backend", "frames", "flat (ms)", "two levels (ms)", "two levels / flat"]);
            for f in &self.frames {
                t.row([
                    f.backend.clone(),
                    f.flat.frames.to_string(),
                    num(f.flat.frame_ms, 2),
                    num(f.two_level.frame_ms, 2),
                    num(f.two_level.frame_ms / f.flat.frame_ms, 2),
                ]);
            }
            md += &t.to_markdown();
            md += "\n";
        }
        for e in &self.frame_errors {
            let _ = writeln!(md, "- {e}");
        }
        md
    }
}

fn ratio(x: f64) -> String {
    num(x, if x < 10.0 { 2 } else { 1 })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bunny_scene() -> Scene {
        let mut scene = Scene::default_scene();
        scene.ensure_camera_and_lights();
        scene.objects[0].name = "bunny/bunny#0".into();
        scene
    }

    #[test]
    fn the_first_frame_is_the_rest_and_later_frames_move_and_turn() {
        let rest = Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0)) * Mat4::from_scale(Vec3::splat(2.0));
        assert!(frame_transform(rest, 0, 0.5).abs_diff_eq(rest, 1e-6));
        let m = frame_transform(rest, 2, 0.5);
        // The origin goes 2 steps along x; the axes turn 6 degrees about y, scale kept.
        assert!(m.w_axis.truncate().abs_diff_eq(Vec3::new(2.0, 2.0, 3.0), 1e-5), "{m}");
        assert!((m.x_axis.truncate().length() - 2.0).abs() < 1e-5);
        assert!((m.x_axis.z + 2.0 * 6f32.to_radians().sin()).abs() < 1e-5, "{m}");
    }

    #[test]
    fn many_bunnies_share_the_bunnys_mesh_and_get_one_bottom_level() {
        let scene = bunny_scene();
        let (many, moving) = many_bunnies(&scene, 5).unwrap();
        assert_eq!(many.objects.len(), scene.objects.len() - 1 + 5);
        assert_eq!(moving.len(), 5);
        assert!(many.objects.iter().enumerate().all(|(i, o)| o.id == i as u32));
        let mesh = scene.objects[0].mesh;
        assert!(moving.iter().all(|&o| many.objects[o as usize].mesh == mesh));
        let prepared = hyrt_cpu::bvh_build::prepare_moving(&many, BvhPreset::default(), &moving);
        let levels = prepared.levels.as_ref().unwrap();
        // The world-space level and one bottom level for the five.
        assert_eq!(levels.bottoms.len(), 2);
        assert!(many_bunnies(&Scene::default_scene(), 5).is_none());
    }

    #[test]
    fn the_teaser_gives_two_scenes_and_the_default_scene_its_sphere() {
        let teaser = BenchScene { name: "teaser".into(), scene: bunny_scene(), paper: None };
        let s = moving_scenes(&[teaser], 3);
        assert_eq!(
            s.iter().map(|s| (s.0.as_str(), s.2.len())).collect::<Vec<_>>(),
            [("teaser", 1), ("teaser, 3 bunnies", 3)]
        );
        let default = super::super::scenes::default_scene();
        let s = moving_scenes(&[default], 3);
        assert_eq!(s.len(), 1);
        assert!(s[0].3.contains("sphere"), "{}", s[0].3);
    }

    #[test]
    fn the_section_sets_hyrt_against_embree_frame_by_frame() {
        let timing = |what: &str, rounds: &[f64]| Timing { what: what.into(), rounds: rounds.to_vec() };
        let summary = |ms: f64| FrameSummary { frames: 3, stage_ms: vec![], frame_ms: ms };
        let m = Moving {
            scenes: vec![MovingScene {
                name: "teaser".into(),
                moving: "the bunny".into(),
                triangles: 1000,
                moving_triangles: 100,
                timings: vec![
                    timing("hyrt update", &[2.0, 4.0, 3.0]),
                    timing("hyrt rebuild", &[100.0, 90.0, 80.0]),
                    timing("Embree update", &[1.0, 1.0, 1.0]),
                    timing("Embree rebuild", &[50.0, 30.0, 40.0]),
                ],
                frames: vec![FrameCost { backend: "CPU".into(), flat: summary(100.0), two_level: summary(150.0) }],
                frame_errors: vec![],
                check: Check { rays: 10, hits: 8, moving_hits: 3, ..Check::default() },
            }],
            size: (64, 32),
            threads: 2,
            embree_missing: None,
            gpu_skipped: None,
        };
        let md = m.section().markdown;
        assert!(md.contains("| hyrt update | 3.000 | 2.000–4.000 | 3.00 (2.00–4.00) |"), "{md}");
        assert!(md.contains("| hyrt rebuild | 90.000 | 80.000–100.000 | 2.00 (2.00–3.00) |"), "{md}");
        assert!(md.contains("| Embree update | 1.000 | 1.000–1.000 |  |"), "{md}");
        assert!(md.contains("| CPU | 3 | 100.00 | 150.00 | 1.50 |"), "{md}");
        assert!(md.contains("3 frames. hyrt's update is 30.0x faster than its rebuild"), "{md}");
        assert!(md.contains("hyrt's update took 3.00x the time of Embree's and hyrt's rebuild 2.00x"), "{md}");
        assert!(!md.contains("No ray hit a moving object"), "{md}");
    }
}
