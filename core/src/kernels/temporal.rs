//! Kernels of the denoiser's temporal pass (issue 38 item 4): where frames follow each
//! other ([`crate::options::FrameOptions::temporal`]: `hyrt render --frames`, `hyrt view`),
//! each pixel's raw visibility channels ([`crate::kernels::denoise::raw_channels`]) are
//! accumulated with what the same surface point had over the previous frames, before the
//! spatial filter, so that the frames' independent samples
//! ([`crate::options::FrameOptions::frame_index`]) add up (SVGF's order: the filter then
//! sees more samples behind each pixel, and narrows its value weights to match):
//!
//! * the pixel's surface point `p` on object `o` is moved to where it was one frame ago by
//!   the object's motion ([`MotionRecord`], from its previous and current transforms:
//!   [`motion_record`], [`apply_motion`]; objects baked into world space do not move);
//! * projected with the previous camera ([`previous_window`]), it lands between four
//!   previous pixel centres ([`bilinear_taps`]), whose histories are blended bilinearly
//!   (so that a moving camera does not resample the history at the nearest pixel every
//!   frame, which smears a penumbra);
//! * a previous pixel counts only if it saw the same surface ([`accepts`]): the same
//!   object, normals within [`TEMPORAL_NORMAL_COS`], and its point within
//!   [`TEMPORAL_PLANE_FOOTPRINTS`] pixel footprints of the moved point's tangent plane.
//!   Where none does (disoccluded), the pixel starts afresh;
//! * and only if this frame's samples could have come from it ([`plausible`]): the mean of
//!   this frame's raw values in the pixel's 5 x 5 neighbourhood within three binomial
//!   deviations of the history. Where a shadow moved (the samples around are all lit
//!   now, or all occluded, and the history says otherwise) the history is dropped at once,
//!   so a new umbra is exactly 0 and newly lit floor exactly 1; a penumbra's noise does
//!   not drop it;
//! * the accepted history is clamped to the range of this frame's raw values around the
//!   pixel ([`crate::kernels::denoise::raw_range`], as the spatial filter's clamp: where
//!   every sample around is lit, or occluded, the pixel is exactly 1, or 0) and blended
//!   as a running mean over the frames behind it, at most [`TEMPORAL_MAX_LENGTH`] of them
//!   ([`temporal_blend`]): `h + (c - h) / (n + 1)`.
//!
//! Every operation is a correctly rounded `+ - * /` or `sqrt` in a stated order; the
//! motion records are made on the host, once per object and frame, so a GPU twin reads
//! the same bits.

use glam::{DMat3, DVec3, Vec3};

use crate::formats::{CameraRecord, MotionRecord, ObjectMap, SurfaceRecord, MOTION_NONE};
pub use crate::kernels::denoise::neighbourhood_mean;
use crate::kernels::denoise::{raw_range, MAX_CHANNELS};
use crate::kernels::raster::{clip_position_from_eye, clip_to_window};

/// Most frames a pixel's history stands for: the blend weight of a new frame never drops
/// below `1 / (TEMPORAL_MAX_LENGTH + 1)` = 1/8, an exponential window of about eight
/// frames (SVGF blends at 0.2, FidelityFX's shadow denoiser at about 0.05 to 0.1): a
/// moving penumbra inside a still-noisy neighbourhood (which the clamp cannot tell from
/// noise) trails by a few frames at most.
pub const TEMPORAL_MAX_LENGTH: u32 = 7;

/// Least cosine between a pixel's normal (moved with its object) and its previous pixel's
/// for the history to count: about 25 degrees, wide enough for the normals of a pixel's
/// neighbours on a curved surface after a sub-pixel move, narrow enough to drop the
/// history of a crease's other side.
pub const TEMPORAL_NORMAL_COS: f32 = 0.9;

/// How far from the moved point's tangent plane the previous pixel's point may lie, in
/// the current pixel's footprints ([`crate::kernels::denoise::pixel_footprint`]): the
/// previous pixel's centre is up to half a pixel across from the moved point, which on a
/// surface curving or sloping within a pixel puts it up to about a footprint off the
/// plane; twice that keeps such pixels and drops any other surface behind or in front.
pub const TEMPORAL_PLANE_FOOTPRINTS: f32 = 2.0;

/// The motion of an object from its previous world-to-object map `previous` to its current
/// one `current` ([`ObjectMap`], `L (w - t)`): `p_prev = L_prev^-1 L_cur (p - t_cur) + t_prev`,
/// the linear part composed in f64 and rounded to f32 once. [`MotionRecord::NONE`] where the
/// maps are equal (the object did not move, or is baked into world space) or where the
/// previous linear part cannot be inverted (not from a map the two-level BVH made).
pub fn motion_record(previous: &ObjectMap, current: &ObjectMap) -> MotionRecord {
    if previous == current {
        return MotionRecord::NONE;
    }
    let linear = |m: &ObjectMap| {
        DMat3::from_cols(
            DVec3::new(m[0][0] as f64, m[1][0] as f64, m[2][0] as f64),
            DVec3::new(m[0][1] as f64, m[1][1] as f64, m[2][1] as f64),
            DVec3::new(m[0][2] as f64, m[1][2] as f64, m[2][2] as f64),
        )
    };
    let m = linear(previous).inverse() * linear(current);
    if !m.is_finite() {
        return MotionRecord::NONE;
    }
    let row = |i: usize| [m.col(0)[i] as f32, m.col(1)[i] as f32, m.col(2)[i] as f32, previous[i][3]];
    MotionRecord {
        map_x: row(0),
        map_y: row(1),
        map_z: row(2),
        translation: [current[0][3], current[1][3], current[2][3]],
        flags: 0,
    }
}

/// The motion of every object between two frames from their maps then and now
/// ([`crate::prepared::PreparedScene::object_maps`]); objects without a previous map (the
/// scene gained them) do not move.
pub fn motion_records(previous: &[ObjectMap], current: &[ObjectMap]) -> Vec<MotionRecord> {
    current
        .iter()
        .enumerate()
        .map(|(o, now)| previous.get(o).map_or(MotionRecord::NONE, |then| motion_record(then, now)))
        .collect()
}

/// Where the point `p` of an object that moved by `m` was one frame ago: `q = p - translation` per
/// coordinate, then per row `((m_0 q.x + m_1 q.y) + m_2 q.z) + m_3` (unfused). `p` itself
/// for [`MOTION_NONE`].
#[inline]
pub fn apply_motion(m: &MotionRecord, p: Vec3) -> Vec3 {
    if m.flags & MOTION_NONE != 0 {
        return p;
    }
    let q = Vec3::new(p.x - m.translation[0], p.y - m.translation[1], p.z - m.translation[2]);
    let row = |r: &[f32; 4]| ((r[0] * q.x + r[1] * q.y) + r[2] * q.z) + r[3];
    Vec3::new(row(&m.map_x), row(&m.map_y), row(&m.map_z))
}

/// The unit normal `n` of an object that moved by `m`, turned as it was one frame ago:
/// `M n` normalized (`M`'s linear part; exact for the rigid motions animations make, an
/// approximation under changing non-uniform scale, which only the history test reads).
/// `n` itself for [`MOTION_NONE`] or where `M n` vanishes.
#[inline]
pub fn move_normal(m: &MotionRecord, n: Vec3) -> Vec3 {
    if m.flags & MOTION_NONE != 0 {
        return n;
    }
    let row = |r: &[f32; 4]| (r[0] * n.x + r[1] * n.y) + r[2] * n.z;
    let v = Vec3::new(row(&m.map_x), row(&m.map_y), row(&m.map_z));
    let len2 = v.dot(v);
    match len2 > 0.0 {
        true => v / len2.sqrt(),
        false => n,
    }
}

/// Where the world point `p` lies in `camera`'s image, in window coordinates (pixel `(x, y)`
/// spans `[x, x + 1) x [y, y + 1)`, its centre at `+ 0.5`): [`clip_position_from_eye`], then
/// [`clip_to_window`]. `None` behind the eye or outside the image.
#[inline]
pub fn previous_window(p: Vec3, camera: &CameraRecord) -> Option<[f32; 2]> {
    let clip = clip_position_from_eye(&camera.view_proj, camera.eye, p.into());
    // Behind the eye, or NaN.
    if clip[3].partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let (w, h) = (camera.width as f32, camera.height as f32);
    let [x, y, _] = clip_to_window(clip, w, h);
    (x >= 0.0 && x < w && y >= 0.0 && y < h).then_some([x, y])
}

/// The pixel (index `y * width + x` of `camera`'s image) whose square holds the world point
/// `p` ([`previous_window`] truncated).
#[inline]
pub fn previous_pixel(p: Vec3, camera: &CameraRecord) -> Option<usize> {
    previous_window(p, camera).map(|w| nearest(w, camera))
}

/// The pixel whose square holds window point `w` (inside the image).
#[inline]
fn nearest([x, y]: [f32; 2], camera: &CameraRecord) -> usize {
    let (x, y) = ((x as u32).min(camera.width - 1), (y as u32).min(camera.height - 1));
    y as usize * camera.width as usize + x as usize
}

/// The four pixels whose centres surround window point `w` in a `width` x `height` image, and
/// their bilinear weights, in the order `(x0, y0)`, `(x0 + 1, y0)`, `(x0, y0 + 1)`,
/// `(x0 + 1, y0 + 1)` with `x0 = floor(w.x - 0.5)`, `fx = w.x - 0.5 - x0` (and so for y): weights
/// `(1 - fx)(1 - fy)`, `fx (1 - fy)`, `(1 - fx) fy`, `fx fy`. A pixel off the image is `None`
/// (its weight is dropped by the caller).
#[inline]
pub fn bilinear_taps([x, y]: [f32; 2], (width, height): (usize, usize)) -> [(Option<usize>, f32); 4] {
    let (gx, gy) = (x - 0.5, y - 0.5);
    let (x0, y0) = (gx.floor(), gy.floor());
    let (fx, fy) = (gx - x0, gy - y0);
    let at = |dx: f32, dy: f32| {
        let (xx, yy) = (x0 + dx, y0 + dy);
        let inside = xx >= 0.0 && yy >= 0.0 && xx < width as f32 && yy < height as f32;
        inside.then(|| yy as usize * width + xx as usize)
    };
    [
        (at(0.0, 0.0), (1.0 - fx) * (1.0 - fy)),
        (at(1.0, 0.0), fx * (1.0 - fy)),
        (at(0.0, 1.0), (1.0 - fx) * fy),
        (at(1.0, 1.0), fx * fy),
    ]
}

/// Whether the previous frame's surface `previous` (at a pixel [`bilinear_taps`] found)
/// saw the surface `current` has now, moved to `p` with normal `n` ([`apply_motion`],
/// [`move_normal`]): a hit on the same object, normals within [`TEMPORAL_NORMAL_COS`], its
/// point within `tolerance` of the plane through `p` normal to `previous`'s normal.
#[inline]
pub fn accepts(current: &SurfaceRecord, p: Vec3, n: Vec3, previous: &SurfaceRecord, tolerance: f32) -> bool {
    if !previous.is_hit() || previous.object != current.object {
        return false;
    }
    let np = Vec3::from(previous.normal);
    np.dot(n) >= TEMPORAL_NORMAL_COS && (Vec3::from(previous.position) - p).dot(np).abs() <= tolerance
}

/// How many binomial deviations this frame's neighbourhood mean may lie from a pixel's
/// history for the history to stand ([`plausible`]): three, the usual band (the spatial
/// filter's [`crate::kernels::denoise::VALUE_TOLERANCE`]).
pub const TEMPORAL_TOLERANCE: f32 = 3.0;

/// Whether this frame's samples around a pixel could have come from its history `history`
/// (the history's mean around the previous pixel, a visible share in [0, 1]): their mean `mean` over `n` samples (the neighbourhood's
/// pixels with an estimate times the samples per pixel) lies within
/// `TEMPORAL_TOLERANCE * sqrt(h (1 - h) / n) + 1 / n` of it: the binomial deviation of such a
/// mean, and one sample's worth more (so that a history of exactly 0 or 1 stands against a
/// mean of 0 or 1 and falls at the first sample that disagrees).
#[inline]
pub fn plausible(history: f32, mean: f32, n: u32) -> bool {
    let n = n as f32;
    let band = TEMPORAL_TOLERANCE * ((history * (1.0 - history)).max(0.0) / n).sqrt() + 1.0 / n;
    (mean - history).abs() <= band
}

/// One channel's blend: this frame's raw value `current` and the accepted history
/// `history` clamped to `[lo, hi]` (this frame's raw range around the pixel,
/// [`crate::kernels::denoise::raw_range`]; not where `lo > hi`: no raw estimate around), as
/// `h + (current - h) / (length + 1)` for a history of `length` frames. Where either has no
/// estimate (negative, [`crate::kernels::soft_shadow::NO_ESTIMATE`]), the other.
#[inline]
pub fn temporal_blend(current: f32, history: f32, (lo, hi): (f32, f32), length: u32) -> f32 {
    if history < 0.0 {
        return current;
    }
    let h = match lo <= hi {
        true => history.max(lo).min(hi),
        false => history,
    };
    if current < 0.0 {
        return h;
    }
    h + (current - h) / (length + 1) as f32
}

/// What the temporal pass reads of the previous frame.
#[derive(Clone, Copy, Debug)]
pub struct History<'a> {
    /// The previous frame's camera (its image may have another size).
    pub camera: &'a CameraRecord,
    /// Its surfaces, one per pixel.
    pub surfaces: &'a [SurfaceRecord],
    /// Its raw channels accumulated by this pass, the same channels per pixel as this
    /// frame's.
    pub visibility: &'a [f32],
    /// Per pixel, the frames its visibility stands for (0: none before it).
    pub length: &'a [u32],
}

/// The temporal pass at pixel `(x, y)` of a `width` x `height` frame: its raw channels
/// (`raw`, the whole frame's, `out.len()` per pixel, `samples` per pixel and frame for each
/// channel) blended with the previous frame's accumulated ones `history` into `out`;
/// `footprint` is the pixel's [`crate::kernels::denoise::pixel_footprint`], `motion` one
/// record per object. Returns the frames the result stands for besides this one: 0 where
/// no history counts (a miss, disoccluded, off the previous image, or a channel whose
/// history this frame's samples contradict: [`plausible`]), else the previous pixel's plus
/// one, at most [`TEMPORAL_MAX_LENGTH`].
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn temporal_pixel(
    raw: &[f32],
    surfaces: &[SurfaceRecord],
    (width, height): (usize, usize),
    (x, y): (usize, usize),
    (footprint, samples): (f32, &[u32]),
    motion: &[MotionRecord],
    history: &History,
    out: &mut [f32],
) -> u32 {
    let channels = out.len();
    let i = y * width + x;
    out.copy_from_slice(&raw[i * channels..(i + 1) * channels]);
    let s = &surfaces[i];
    if !s.is_hit() {
        return 0;
    }
    let m = motion.get(s.object as usize).unwrap_or(&MotionRecord::NONE);
    let p = apply_motion(m, Vec3::from(s.position));
    let Some(window) = previous_window(p, history.camera) else {
        return 0;
    };
    let n = move_normal(m, Vec3::from(s.normal));
    let tolerance = footprint * TEMPORAL_PLANE_FOOTPRINTS;
    let (pw, ph) = (history.camera.width as usize, history.camera.height as usize);
    // The previous pixels around the moved point that saw the same surface, bilinearly
    // weighted; the history of each channel their weighted mean over those with an
    // estimate; its length the least of theirs; the plausibility measured around the
    // heaviest.
    let mut taps = bilinear_taps(window, (pw, ph));
    for (k, w) in taps.iter_mut() {
        if !k.is_some_and(|k| accepts(s, p, n, &history.surfaces[k], tolerance)) {
            (*k, *w) = (None, 0.0);
        }
    }
    let Some((centre, _)) = taps.iter().filter_map(|&(k, w)| k.map(|k| (k, w))).fold(None, |best, (k, w)| match best {
        Some((_, bw)) if bw >= w => best,
        _ => Some((k, w)),
    }) else {
        return 0;
    };
    let mut old = [0.0f32; MAX_CHANNELS];
    for (c, o) in old.iter_mut().enumerate().take(channels) {
        let (mut sum, mut weight) = (0.0f32, 0.0f32);
        for &(k, w) in &taps {
            if let Some(k) = k {
                let v = history.visibility[k * channels + c];
                if v >= 0.0 && w > 0.0 {
                    sum += w * v;
                    weight += w;
                }
            }
        }
        *o = match weight > 0.0 {
            true => sum / weight,
            false => crate::kernels::soft_shadow::NO_ESTIMATE,
        };
    }
    let behind = taps.iter().filter_map(|&(k, _)| k.map(|k| history.length[k])).min().unwrap_or(0);
    // This frame's mean around the pixel and the history's around the previous pixel, per
    // channel: two estimates of the same neighbourhood's light where nothing moved.
    let now = neighbourhood_mean(raw, surfaces, (width, height), (x, y), channels);
    let then = neighbourhood_mean(history.visibility, history.surfaces, (pw, ph), (centre % pw, centre / pw), channels);
    for c in 0..channels {
        let ((mean, count), (old_mean, old_count)) = (now[c], then[c]);
        if old[c] >= 0.0 && count > 0 && old_count > 0 && !plausible(old_mean, mean, count * samples[c]) {
            return 0;
        }
    }
    let length = (behind + 1).min(TEMPORAL_MAX_LENGTH);
    let (lo, hi) = raw_range(raw, surfaces, (width, height), (x, y), channels);
    for c in 0..channels {
        out[c] = temporal_blend(raw[i * channels + c], old[c], (lo[c], hi[c]), length);
    }
    length
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::instance::world_to_object;
    use crate::scene::Camera;
    use glam::{Mat4, Quat};
    use proptest::prelude::*;

    fn surface(p: Vec3, n: Vec3, object: u32) -> SurfaceRecord {
        SurfaceRecord {
            position: p.into(),
            normal: n.into(),
            geometric_normal: n.into(),
            object,
            triangle: 0,
            position_error: 0.0,
        }
    }

    proptest! {
        /// A point of a moving object, carried back by its motion record, is where the
        /// previous transform put the same object-space point (to the f32 roundings of two
        /// maps: a few ulps of the object's size and offset).
        #[test]
        fn motion_carries_points_back_to_their_previous_place(
            (ax, ay, az) in (-3.0f32..3.0, -3.0f32..3.0, -3.0f32..3.0),
            (bx, by, bz) in (-3.0f32..3.0, -3.0f32..3.0, -3.0f32..3.0),
            turn in -3.0f32..3.0, scale in 0.5f32..2.0,
            (ox, oy, oz) in (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0),
        ) {
            let before = Mat4::from_scale_rotation_translation(Vec3::splat(scale), Quat::from_rotation_y(0.3), Vec3::new(ax, ay, az));
            let after = Mat4::from_scale_rotation_translation(Vec3::splat(scale), Quat::from_rotation_y(turn), Vec3::new(bx, by, bz));
            let m = motion_record(&world_to_object(before).unwrap(), &world_to_object(after).unwrap());
            m.validate().unwrap();
            let object_point = Vec3::new(ox, oy, oz);
            let got = apply_motion(&m, after.transform_point3(object_point));
            let want = before.transform_point3(object_point);
            // f32 transforms of points within 5 units, composed twice: under 1e-5 absolute.
            prop_assert!((got - want).length() <= 1e-5, "{got} against {want}");
            let n = move_normal(&m, after.transform_vector3(Vec3::X).normalize());
            let want_n = before.transform_vector3(Vec3::X).normalize();
            prop_assert!(n.dot(want_n) > 1.0 - 1e-5, "{n} against {want_n}");
        }
    }

    #[test]
    fn objects_that_did_not_move_have_no_motion() {
        let map = world_to_object(Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0))).unwrap();
        assert_eq!(motion_record(&map, &map), MotionRecord::NONE);
        let p = Vec3::new(0.1, 0.2, 0.3);
        assert_eq!(apply_motion(&MotionRecord::NONE, p), p);
    }

    #[test]
    fn a_surface_point_reprojects_into_its_own_pixel() {
        let camera = Camera::look_at(Vec3::new(0.3, 2.0, 5.0), Vec3::ZERO, Vec3::Y);
        let record = CameraRecord::new(&camera, 64, 48);
        for y in 0..48 {
            for x in 0..64 {
                // The point 3 units along the pixel's primary ray.
                let ray = crate::kernels::camera::primary_ray(&record, x, y);
                let d = Vec3::from(ray.direction).normalize();
                let p = Vec3::from(ray.origin) + d * 3.0;
                assert_eq!(previous_pixel(p, &record), Some((y * 64 + x) as usize), "pixel ({x}, {y})");
            }
        }
        assert_eq!(previous_pixel(Vec3::new(0.3, 2.0, 7.0), &record), None, "behind the eye");
        assert_eq!(previous_pixel(Vec3::new(100.0, 0.0, 0.0), &record), None, "off the image");
    }

    #[test]
    fn history_of_another_surface_is_refused() {
        let c = surface(Vec3::ZERO, Vec3::Y, 3);
        let same = surface(Vec3::new(0.004, 0.0, 0.0), Vec3::Y, 3);
        assert!(accepts(&c, Vec3::ZERO, Vec3::Y, &same, 0.01));
        assert!(!accepts(&c, Vec3::ZERO, Vec3::Y, &surface(Vec3::ZERO, Vec3::Y, 4), 0.01), "other object");
        assert!(!accepts(&c, Vec3::ZERO, Vec3::Y, &surface(Vec3::new(0.0, 0.05, 0.0), Vec3::Y, 3), 0.01), "in front");
        assert!(!accepts(&c, Vec3::ZERO, Vec3::Y, &surface(Vec3::ZERO, Vec3::X, 3), 0.01), "turned");
        assert!(!accepts(&c, Vec3::ZERO, Vec3::Y, &SurfaceRecord::MISS, 0.01), "a miss");
    }

    #[test]
    fn the_blend_is_a_running_mean() {
        // The same value comes out bit for bit, whatever the history's length.
        for v in [0.0f32, 1.0, 0.3, 1.0 / 3.0] {
            for n in 1..=TEMPORAL_MAX_LENGTH {
                assert_eq!(temporal_blend(v, v, (0.0, 1.0), n).to_bits(), v.to_bits());
            }
        }
        assert_eq!(temporal_blend(0.5, 0.25, (0.0, 1.0), 1), 0.375, "two frames: their mean");
        assert_eq!(temporal_blend(1.0, 0.0, (0.0, 1.0), 3), 0.25, "four frames");
        assert_eq!(temporal_blend(1.0, 0.9, (1.0, 1.0), 7), 1.0, "every sample around lit: full light");
        assert_eq!(temporal_blend(0.0, 0.05, (0.0, 0.0), 7), 0.0, "every sample around occluded: umbra");
        assert_eq!(temporal_blend(0.4, -1.0, (0.0, 1.0), 7), 0.4, "no history value");
        assert_eq!(temporal_blend(-1.0, 0.6, (0.0, 0.5), 7), 0.5, "no estimate now: the clamped history");
    }

    #[test]
    fn a_history_stands_against_noise_and_falls_when_the_shadow_moved() {
        // 25 pixels of 4 samples: a penumbra's history of 0.95 stands against a frame whose
        // 100 samples around all came out lit, or 90 of them.
        assert!(plausible(0.95, 1.0, 100) && plausible(0.95, 0.9, 100));
        // A history of full light or umbra stands where every sample agrees, and falls
        // where the shadow moved in or out.
        assert!(plausible(1.0, 1.0, 100) && plausible(0.0, 0.0, 100));
        assert!(!plausible(1.0, 0.0, 100) && !plausible(0.0, 1.0, 100));
        assert!(!plausible(0.0, 0.5, 100), "half the samples lit where the history had umbra");
        assert!(!plausible(0.5, 0.05, 100), "a penumbra that left");
    }

    /// A still frame whose values equal its history (at a thousand samples a pixel, so
    /// that the history stands against its neighbours): each pixel finds itself and comes
    /// out bit for bit.
    #[test]
    fn a_static_frame_rendered_again_comes_out_unchanged() {
        let camera = Camera::look_at(Vec3::new(0.0, 3.0, 3.0), Vec3::ZERO, Vec3::Y);
        let (w, h) = (32usize, 24usize);
        let record = CameraRecord::new(&camera, w as u32, h as u32);
        // A floor at y = 0 seen from the camera: each pixel's ray meets it.
        let surfaces: Vec<SurfaceRecord> = (0..w * h)
            .map(|i| {
                let ray = crate::kernels::camera::primary_ray(&record, (i % w) as u32, (i / w) as u32);
                let (o, d) = (Vec3::from(ray.origin), Vec3::from(ray.direction));
                let t = -o.y / d.y;
                surface(o + d * t, Vec3::Y, 0)
            })
            .collect();
        let values = vec![0.37f32; w * h];
        let length = vec![3u32; w * h];
        let history = History { camera: &record, surfaces: &surfaces, visibility: &values, length: &length };
        for y in 0..h {
            for x in 0..w {
                let mut out = [0.0f32];
                let n = temporal_pixel(&values, &surfaces, (w, h), (x, y), (0.01, &[1000]), &[], &history, &mut out);
                assert_eq!(n, 4, "pixel ({x}, {y}) found itself");
                assert_eq!(out[0].to_bits(), values[y * w + x].to_bits());
            }
        }
    }
}
