//! A view for a scene that has no camera ([`super::Scene::ensure_camera_and_lights`]).
//!
//! An object, or a set of objects, is framed from outside: the bounding sphere fits the
//! field of view. A closed interior (a building such as Sponza, a room) seen that way shows
//! its outer walls and nothing of what a user loaded it for, so [`interior_view`] looks for
//! a place inside first, with rays through a BVH of the scene:
//!
//! 1. Candidate eyes on a [`GRID`]³ lattice inside the scene's bounds. Each casts
//!    [`DIRECTIONS`] rays spread evenly over the sphere (a Fibonacci lattice).
//! 2. A candidate whose rays see the interior side of a surface more than
//!    [`MAX_INTERIOR_SIDE`] of the time is inside a solid (a column, a wall, a closed
//!    mesh); see [`crate::kernels::raster::shows_interior`]. The others are free space.
//! 3. Free space is *enclosed* when at least [`MIN_ENCLOSURE`] of its rays meet geometry.
//!    From outside an object, or above a ground plane, at most about half the sphere is
//!    covered; inside a room nearly all of it is, and in a courtyard open to the sky
//!    (Sponza) all but the opening.
//! 4. The scene counts as an interior if at least [`MIN_ENCLOSED_SHARE`] of the candidates
//!    are enclosed: its bounds are mostly space it encloses (Sponza: 85% of them), not an
//!    object with a cavity (the DamagedHelmet's, seen from inside, is 2.5% of its
//!    candidates). The eye goes to the enclosed candidate with the most room around it (the largest median distance to
//!    what its rays hit), lowered to [`EYE_HEIGHT`] of the way from the floor below it to
//!    what is above it, and looks along the longest open horizontal direction
//!    ([`HEADINGS`] tried, level with the eye).
//!
//! The BVH is the scene's own (the same build and watertight ray/triangle test the
//! renderer's reference uses), built with [`BvhPreset::Fastest`] and dropped afterwards.
//! Scenes over [`MAX_TRIANGLES`] world triangles skip the search (its BVH would cost more
//! than the load itself) and are framed from outside.

use glam::Vec3;

use super::{Camera, Scene};
use crate::bvh::{Bvh, BvhPreset};
use crate::formats::{RayRecord, TRI_INWARD};
use crate::geometry::WorldGeometry;
use crate::kernels::raster::shows_interior;

/// Candidate eyes per axis: 9³ = 729 points, 5% to 95% of the bounds on each axis. Fine
/// enough to land in Sponza's courtyard (about a quarter of the building's width) and in
/// its arcades; with [`DIRECTIONS`] rays each, about 47,000 rays, tens of milliseconds.
pub const GRID: usize = 9;

/// Rays per candidate eye, spread over the sphere: 64 rays resolve coverage to about 1.6%,
/// far finer than the gap between [`MIN_ENCLOSURE`] and what an object covers.
pub const DIRECTIONS: usize = 64;

/// The fraction of a candidate's rays that must meet geometry for it to be enclosed.
/// An object seen from outside covers less than half the sphere (a plane under the eye
/// exactly half); Sponza's courtyard, open to the sky, covers about 85% from its floor.
pub const MIN_ENCLOSURE: f32 = 0.75;

/// The share of the candidates that must be enclosed for the scene to be an interior.
/// Measured on the shared models (9³ candidates): Sponza 85%; objects 0 to 2.5% (the
/// bunny, the dragon, the teapot, the horse, the DamagedHelmet, whose head cavity is
/// enclosed free space); the hard cycloidal surface 15%, its folds.
pub const MIN_ENCLOSED_SHARE: f32 = 0.4;

/// The fraction of a candidate's rays that may see the interior side of a surface (a
/// back face of a closed mesh wound outward, a front face of one wound inward) before
/// the candidate counts as inside a solid. Not zero: open sheets modelled single-sided
/// (foliage, curtains) show their back faces from both sides.
pub const MAX_INTERIOR_SIDE: f32 = 0.2;

/// Horizontal directions tried for the view from the chosen eye.
pub const HEADINGS: usize = 32;

/// Where the eye sits between the floor below it and what is above (or the top of the
/// bounds): a quarter of the way up, a standing person's view in a room or courtyard.
pub const EYE_HEIGHT: f32 = 0.25;

/// Scenes with more world triangles than this are framed from outside without the
/// search. Its cost is the BVH: measured on this project's 2-core Xeon, release build,
/// the dragon's 871,414 triangles took 190 ms of world records, 460 ms of
/// [`BvhPreset::Fastest`] build and 60 ms of rays, ten times its file's load (70 ms);
/// below 300,000 triangles (Crytek's Sponza has 262,267; the shared Sponza 66,454) the
/// search stays under about a quarter of a second. Sharing the renderer's own BVH, built
/// at `prepare` anyway, would lift the limit.
pub const MAX_TRIANGLES: usize = 300_000;

/// The vertical field of view of the camera placed inside, in degrees (wider than the
/// outside framing's 45: a room is seen from within it).
pub const INTERIOR_FOV_DEG: f32 = 60.0;

/// A view from inside a scene: [`interior_view`].
#[derive(Clone, Debug, PartialEq)]
pub struct InteriorView {
    pub camera: Camera,
    /// Where lights go if the scene has none: inside too (lights outside a closed room
    /// would light nothing of it): above the eye, and above the point looked at, each
    /// [`LIGHT_HEIGHT`] of the way up to what is above it.
    pub lights: [Vec3; 2],
    /// Why and where the camera was placed, for [`Scene::notes`].
    pub note: String,
}

/// Where default lights sit between the eye (or the point looked at) and what is above
/// it: near the ceiling, clear of it.
pub const LIGHT_HEIGHT: f32 = 0.8;

/// A camera inside `scene` (bounds `lo`..`hi`), if the scene encloses free space (see the
/// module docs); `None` for scenes to be framed from outside.
pub fn interior_view(scene: &Scene, lo: Vec3, hi: Vec3) -> Option<InteriorView> {
    if !(1..=MAX_TRIANGLES).contains(&scene.triangle_count()) {
        return None;
    }
    let extent = hi - lo;
    let diagonal = extent.length();
    if !(diagonal.is_finite() && diagonal > 0.0) {
        return None;
    }
    let geometry = WorldGeometry::build(scene);
    let bvh = Bvh::build(&geometry, BvhPreset::Fastest);
    let triangles = geometry.stored_table();
    let cast = |origin: Vec3, direction: Vec3| -> Option<(f32, bool)> {
        let ray = RayRecord::query(origin.into(), direction.into(), 0.0, diagonal * 2.0);
        let hit = bvh.closest_hit(triangles, &ray)?;
        let inward = triangles[hit.triangle as usize].flags & TRI_INWARD != 0;
        Some((hit.t, shows_interior(hit.back_face, inward)))
    };
    let sphere = fibonacci_sphere(DIRECTIONS);

    let mut best: Option<(f32, Vec3, f32)> = None; // (median distance, eye, enclosure)
    let mut enclosed = 0;
    for k in 0..GRID {
        for j in 0..GRID {
            for i in 0..GRID {
                let f = |n: usize| 0.05 + 0.9 * n as f32 / (GRID - 1) as f32;
                let p = lo + extent * Vec3::new(f(i), f(j), f(k));
                let mut distances = Vec::with_capacity(DIRECTIONS);
                let mut interior = 0;
                for &d in &sphere {
                    if let Some((t, inside)) = cast(p, d) {
                        distances.push(t);
                        interior += inside as usize;
                    }
                }
                let enclosure = distances.len() as f32 / DIRECTIONS as f32;
                if enclosure < MIN_ENCLOSURE || interior as f32 > MAX_INTERIOR_SIDE * DIRECTIONS as f32 {
                    continue;
                }
                enclosed += 1;
                distances.sort_by(f32::total_cmp);
                let median = distances[distances.len() / 2];
                if best.is_none_or(|(m, _, _)| median > m) {
                    best = Some((median, p, enclosure));
                }
            }
        }
    }
    if (enclosed as f32) < MIN_ENCLOSED_SHARE * (GRID * GRID * GRID) as f32 {
        return None;
    }
    let (_, mut eye, enclosure) = best?;

    // Lower the eye towards the floor: EYE_HEIGHT of the way from what is below to what is
    // above (or the top of the bounds, under an open sky).
    let up = Vec3::Y;
    if let Some((below, _)) = cast(eye, -up) {
        let above = cast(eye, up).map_or(hi.y - eye.y, |(t, _)| t).max(0.0);
        eye -= up * (below - EYE_HEIGHT * (below + above)).max(0.0);
    }
    // Look along the longest open horizontal direction; a heading that meets nothing goes
    // as far as the bounds allow.
    let (mut heading, mut reach) = (Vec3::X, -1.0f32);
    for h in 0..HEADINGS {
        let a = std::f32::consts::TAU * h as f32 / HEADINGS as f32;
        let d = Vec3::new(a.cos(), 0.0, a.sin());
        let t = cast(eye, d).map_or(diagonal, |(t, _)| t);
        if t > reach {
            (heading, reach) = (d, t);
        }
    }
    let target = eye + heading * (reach * 0.5).max(diagonal * 1e-3);
    let lift = |p: Vec3| p + up * LIGHT_HEIGHT * cast(p, up).map_or(hi.y - p.y, |(t, _)| t).max(0.0);
    let lights = [lift(eye), lift(target)];
    let camera = Camera { eye, target, up, fov_y_deg: INTERIOR_FOV_DEG, near: diagonal * 1e-4, far: diagonal * 2.0 };
    let note = format!(
        "no camera in the scene, which encloses its space ({:.0}% of the directions from the chosen point meet a surface): camera placed inside (eye {:.3?}, target {:.3?}, fov {INTERIOR_FOV_DEG} deg)",
        enclosure * 100.0,
        camera.eye,
        camera.target
    );
    Some(InteriorView { camera, lights, note })
}

/// `n` unit vectors spread evenly over the sphere (the Fibonacci lattice: equal-area bands
/// in z, the golden angle between consecutive points around it).
pub fn fibonacci_sphere(n: usize) -> Vec<Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5.0f32.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2 * i + 1) as f32 / n as f32;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let a = golden * i as f32;
            Vec3::new(r * a.cos(), z, r * a.sin())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fibonacci_directions_are_unit_and_balanced() {
        let s = fibonacci_sphere(DIRECTIONS);
        assert_eq!(s.len(), DIRECTIONS);
        for d in &s {
            // f32 rounding of r, cos and sin: a few ulps of 1.
            assert!((d.length() - 1.0).abs() < 1e-6, "{d:?}");
        }
        // Evenly spread: the mean is near the centre and each half holds half the points.
        let mean = s.iter().copied().sum::<Vec3>() / DIRECTIONS as f32;
        assert!(mean.length() < 0.05, "{mean:?}");
        assert_eq!(s.iter().filter(|d| d.y > 0.0).count(), DIRECTIONS / 2);
    }
}
