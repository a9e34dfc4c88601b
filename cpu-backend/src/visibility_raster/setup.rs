//! The raster's setup eight triangles at a time: each lane transforms its triangle's
//! vertices to clip space with [`clip_position_from_eye`]'s operations, and the lanes
//! then find the triangles that certainly draw nothing, which no scalar code touches
//! again:
//!
//! * a vertex with a non-finite clip coordinate;
//! * all three vertices beyond one clip plane or one side of the viewport (the outcodes of
//!   [`setup_from_clip`]);
//! * a triangle within every clip plane (drawn unclipped) with a vertex whose window
//!   position ([`clip_to_window`]) is not finite, whose `w` is not positive or whose
//!   snapped coordinate ([`snap_to_fixed`]) lies beyond [`MAX_FIXED_COORD`], or whose
//!   pixel box ([`pixel_span`] of its snapped coordinates, within the image) holds no
//!   pixel centre. On a dense mesh many triangles are of this kind: 403,470 of the 871,926
//!   in `assets/scenes/dragon.toml`'s frame fall between pixel centres.
//!
//! A triangle within every clip plane that passes those checks goes to the scalar
//! `finish_triangle` (area, winding, the triangle's record) with the window positions
//! and snapped coordinates the lanes computed; one that needs clipping to the scalar
//! [`setup_from_clip`] with the lanes' clip positions. So the set-up triangles are the
//! scalar setup's ([`setup_triangle`]), in the same order, bit for bit: the lanes repeat
//! the scalar kernels' IEEE operations in their order (no fused multiply-add), and a lane
//! drops a triangle only where one of the scalar checks above drops it too. The tests
//! compare the two setups triangle by triangle on random triangles (special values
//! included) and on the hard cases of the clipper.
//!
//! Measured on the dragon's frame (`hyrt render assets/scenes/dragon.toml --frames 9
//! --threads 1 --shading paper`, AMD EPYC, AVX2, the binaries alternated twice): the
//! setup (the fused frame's `visibility_raster` line) from 60.8 to 61.1 ms down to 29.5 ms,
//! the frame from 210 to 182 ms; the near bunny's setup from 5.3 to 3.5 ms, the teaser's
//! from 7.9 to 5.4, the far horse's from 2.05 to 1.07; images unchanged. A first version
//! that dropped the empty triangles in lanes and set up every other one with the scalar
//! code from its clip positions measured no faster (63.5 ms), with its lanes' results
//! stored through `array::map` calls compiled without AVX2 (4% of the frame's samples):
//! stores here are spelt out.
//!
//! [`clip_position_from_eye`]: hyrt_core::kernels::raster::clip_position_from_eye
//! [`clip_to_window`]: hyrt_core::kernels::raster::clip_to_window
//! [`snap_to_fixed`]: hyrt_core::kernels::raster::snap_to_fixed
//! [`pixel_span`]: hyrt_core::kernels::raster::pixel_span
//! [`setup_triangle`]: super::setup_triangle

use hyrt_core::formats::{CameraRecord, TriangleRecord, TRI_INWARD};
use hyrt_core::kernels::raster::{
    culls_interior, shows_interior, ClipPlane, ClipVertex, CLIP_PLANES, F32_INTEGER_THRESHOLD, FIXED_ONE_F32,
    MAX_FIXED_COORD, PIXEL_CENTER_OFFSET,
};

use super::{finish_triangle, raster_flags, setup_from_clip, Frame, RasterTriangle};
use crate::lanes::{avx2_entry_points, dispatch, Lanes, LANES};
use crate::traversal::SimdLevel;

/// Set up `tris` (one setup chunk) into `out`, in order, with the lanes of `level` (one
/// this CPU has): what [`super::setup_triangle`] pushes for each triangle.
pub(super) fn setup_chunk(
    tris: &[TriangleRecord],
    camera: &CameraRecord,
    frame: &Frame,
    level: SimdLevel,
    out: &mut Vec<RasterTriangle>,
) {
    dispatch!(level, setup_lanes, setup_lanes_avx512, setup_lanes_avx2, (tris, camera, frame, out))
}

avx2_entry_points!(
    setup_lanes,
    setup_lanes_avx2,
    setup_lanes_avx512,
    (tris: &[TriangleRecord], camera: &CameraRecord, frame: &Frame, out: &mut Vec<RasterTriangle>)
);

/// [`setup_chunk`] at the lanes `L`.
#[inline(always)]
fn setup_lanes<L: Lanes>(tris: &[TriangleRecord], camera: &CameraRecord, frame: &Frame, out: &mut Vec<RasterTriangle>) {
    let view = View::<L>::new(camera, frame);
    for group in tris.chunks(LANES) {
        // Lanes past the group's end repeat its last triangle; they are not set up.
        let v = L::triangle_lanes(std::array::from_fn(|k| &group[k.min(group.len() - 1)]));
        let lanes = view.classify(&v);
        let mut live = !lanes.nothing & ((1u32 << group.len()) - 1);
        if live == 0 {
            continue;
        }
        live &= !lanes.dropped_by_finish(live & lanes.unclipped, group, frame);
        if live == 0 {
            continue;
        }
        // Spelt out: `array::map` over vectors can stay a call compiled without the
        // target features (one per store).
        let (mut clip, mut win, mut fixed) =
            ([[[0.0f32; LANES]; 4]; 3], [[[0.0f32; LANES]; 3]; 3], [[[0.0f32; LANES]; 2]; 3]);
        for i in 0..3 {
            for (out, x) in clip[i].iter_mut().zip(lanes.clip[i]) {
                *out = L::store(x);
            }
            for (out, x) in win[i].iter_mut().zip(lanes.win[i]) {
                *out = L::store(x);
            }
            for (out, x) in fixed[i].iter_mut().zip(lanes.fixed[i]) {
                *out = L::store(x);
            }
        }
        while live != 0 {
            let k = live.trailing_zeros() as usize;
            live &= live - 1;
            let tri = &group[k];
            let c = |i: usize| [clip[i][0][k], clip[i][1][k], clip[i][2][k], clip[i][3][k]];
            let c = [c(0), c(1), c(2)];
            if lanes.unclipped >> k & 1 != 0 {
                // What `setup_from_clip` hands `emit_triangle` for a triangle within every
                // clip plane, and what `emit_triangle` computes before `finish_triangle`:
                // the lanes computed them with the same operations. The snapped
                // coordinates are integers within `MAX_FIXED_COORD`: exact as i64.
                let corners = ClipVertex::triangle(c);
                let w = |i: usize| [win[i][0][k], win[i][1][k], win[i][2][k]];
                let f = |i: usize| [fixed[i][0][k] as i64, fixed[i][1][k] as i64];
                let v = [&corners[0], &corners[1], &corners[2]];
                finish_triangle(tri, raster_flags(tri), true, v, [w(0), w(1), w(2)], [f(0), f(1), f(2)], frame, out);
            } else {
                setup_from_clip(tri, c, frame, out);
            }
        }
    }
}

/// What the lanes found for eight triangles.
struct Classified<L: Lanes> {
    /// The clip positions of the vertices, `clip[vertex][axis]`.
    clip: [[L::F; 4]; 3],
    /// Their window positions (`clip_to_window`), where `unclipped`.
    win: [[L::F; 3]; 3],
    /// Their snapped window x and y (`snap_to_fixed`, as f32), where `unclipped`.
    fixed: [[L::F; 2]; 3],
    /// The lanes whose triangle certainly draws nothing (see the module docs).
    nothing: u32,
    /// The lanes whose triangle lies within every clip plane, with every vertex's window
    /// position finite, `w > 0` and snapped coordinates within `MAX_FIXED_COORD`:
    /// `emit_triangle` would reach `finish_triangle` with `win` and `fixed`.
    unclipped: u32,
}

/// The greatest magnitude of a snapped coordinate (2^23, 32,768 pixels) for which the
/// lanes decide a triangle's area sign ([`Classified::dropped_by_finish`]): the differences
/// of such coordinates (at most 2^24) are exact in f32, and their products (at most 2^48)
/// exact in f64 ([`Lanes::cross_sign_bits`]).
const EXACT_AREA_COORD: f32 = 8_388_608.0;

impl<L: Lanes> Classified<L> {
    /// Of the lanes `unclipped` (a subset of [`Classified::unclipped`], triangles `group`),
    /// those `finish_triangle` would drop before anything else: a zero doubled area
    /// (`triangle_area2` of the snapped coordinates), or the interior of an object whose
    /// interior is hidden (`shows_interior` of the winding and `TRI_INWARD`, and
    /// `culls_interior`). Decided exactly, for lanes whose snapped coordinates are at most
    /// 2^23 in magnitude (32,768 pixels: every triangle near the image): their differences
    /// are exact in f32 and the area's sign is exact ([`Lanes::cross_sign_bits`]); other
    /// lanes are left to `finish_triangle`. On a closed mesh about half of the triangles
    /// with a pixel centre in their box show its interior; they no longer go through the
    /// scalar code.
    #[inline(always)]
    fn dropped_by_finish(&self, unclipped: u32, group: &[TriangleRecord], frame: &Frame) -> u32 {
        let f = &self.fixed;
        let limit = L::splat(EXACT_AREA_COORD);
        let mut small = L::eq(limit, limit);
        for vertex in f {
            for &x in vertex {
                small = L::and(small, L::le(L::abs(x), limit));
            }
        }
        let lanes = unclipped & L::bits(small);
        if lanes == 0 {
            return 0;
        }
        // `triangle_area2(v0, v1, v2)` = `(y1 - y0) * (x2 - x0) - (x1 - x0) * (y2 - y0)`.
        let (dx1, dy1) = (L::sub(f[1][0], f[0][0]), L::sub(f[1][1], f[0][1]));
        let (dx2, dy2) = (L::sub(f[2][0], f[0][0]), L::sub(f[2][1], f[0][1]));
        let (back, degenerate) = L::cross_sign_bits(dy1, dx2, dx1, dy2);
        let mut drop = degenerate;
        if !frame.interior_culls.is_empty() {
            for (k, tri) in group.iter().enumerate().filter(|(k, _)| lanes >> k & 1 != 0) {
                let interior = shows_interior(back >> k & 1 != 0, tri.flags & TRI_INWARD != 0);
                drop |= ((interior && culls_interior(&frame.interior_culls, tri.object)) as u32) << k;
            }
        }
        drop & lanes
    }
}

/// The camera and frame constants of the setup, in lanes.
struct View<L: Lanes> {
    /// `camera.view_proj`, column-major, each entry in every lane.
    m: [L::F; 16],
    eye: [L::F; 3],
    /// The guard band in NDC (`Frame::guard`).
    guard: [L::F; 2],
    /// The viewport transform's image size (`Frame::width_f`, `Frame::height_f`).
    size: [L::F; 2],
    /// The last pixel column and row rasterized (`Frame::width - 1`, `Frame::height - 1`).
    last: [L::F; 2],
}

impl<L: Lanes> View<L> {
    #[inline(always)]
    fn new(camera: &CameraRecord, frame: &Frame) -> Self {
        let mut m = [L::splat(0.0); 16];
        for (lane, x) in m.iter_mut().zip(camera.view_proj) {
            *lane = L::splat(x);
        }
        let [ex, ey, ez] = camera.eye;
        let [gx, gy] = frame.guard;
        View {
            m,
            eye: [L::splat(ex), L::splat(ey), L::splat(ez)],
            guard: [L::splat(gx), L::splat(gy)],
            size: [L::splat(frame.width_f), L::splat(frame.height_f)],
            // Image sides are at most `MAX_IMAGE_DIM` (2^20): exact in f32.
            last: [L::splat((frame.width - 1) as f32), L::splat((frame.height - 1) as f32)],
        }
    }

    /// `clip_position_from_eye(m, eye, v)` per lane: `v - eye`, then
    /// `((c0 * x + c1 * y) + c2 * z) + c3` for each row, no fused multiply-add.
    #[inline(always)]
    fn clip(&self, v: &[L::F; 3]) -> [L::F; 4] {
        let d = [L::sub(v[0], self.eye[0]), L::sub(v[1], self.eye[1]), L::sub(v[2], self.eye[2])];
        let m = &self.m;
        [clip_row::<L>(m, 0, &d), clip_row::<L>(m, 1, &d), clip_row::<L>(m, 2, &d), clip_row::<L>(m, 3, &d)]
    }

    /// The clip positions of the triangles with vertices `v` (`[vertex][axis]`, world
    /// space), and which of them certainly draw nothing or go straight to
    /// `finish_triangle` ([`Classified`]).
    #[inline(always)]
    fn classify(&self, v: &[[L::F; 3]; 3]) -> Classified<L> {
        let clip = [self.clip(&v[0]), self.clip(&v[1]), self.clip(&v[2])];
        let zero = L::splat(0.0);
        let ones = L::eq(zero, zero);
        let mut not_finite = zero;
        // Per outcode bit, whether every vertex has it (`all`), and whether some vertex
        // lies beyond a clip plane (`clipped`).
        let mut all = [ones; CLIP_PLANES.len() + 4];
        let mut clipped = zero;
        for c in &clip {
            for x in c {
                not_finite = L::or(not_finite, L::andnot(finite::<L>(*x), ones));
            }
            for (p, plane) in CLIP_PLANES.iter().enumerate() {
                let beyond = L::lt(plane_distance::<L>(*plane, c, &self.guard), zero);
                all[p] = L::and(all[p], beyond);
                clipped = L::or(clipped, beyond);
            }
            let (x, y, w) = (c[0], c[1], c[3]);
            let neg_w = L::xor(w, L::splat(-0.0));
            let sides = [L::lt(w, x), L::lt(x, neg_w), L::lt(w, y), L::lt(y, neg_w)];
            for (s, side) in sides.into_iter().enumerate() {
                all[CLIP_PLANES.len() + s] = L::and(all[CLIP_PLANES.len() + s], side);
            }
        }
        let mut beyond_one = zero;
        for bit in all {
            beyond_one = L::or(beyond_one, bit);
        }
        // The window positions, snapped (meaningful for the unclipped triangles).
        let mut bad = zero;
        let (mut lo, mut hi) = ([L::splat(f32::INFINITY); 2], [L::splat(f32::NEG_INFINITY); 2]);
        let mut win = [[zero; 3]; 3];
        let mut fixed = [[zero; 2]; 3];
        for (i, c) in clip.iter().enumerate() {
            let p = clip_to_window::<L>(c, self.size);
            let ok = L::and(L::and(finite::<L>(p[0]), finite::<L>(p[1])), L::and(finite::<L>(p[2]), L::lt(zero, c[3])));
            bad = L::or(bad, L::andnot(ok, ones));
            for a in 0..2 {
                let f = snap_to_fixed::<L>(p[a]);
                bad = L::or(bad, L::lt(L::splat(MAX_FIXED_COORD as f32), L::abs(f)));
                lo[a] = L::min(lo[a], f);
                hi[a] = L::max(hi[a], f);
                fixed[i][a] = f;
            }
            win[i] = p;
        }
        // `pixel_span` within the image, in f32: `[ceil(min / 256), floor((max - 1) / 256)]`
        // clamped to `[0, last]`. The snapped coordinates are integers of at most 2^29 (or
        // `bad`): divided by 256 exactly, and `floor` and `ceil` are exact below 2^22. Only
        // `max - 1` can round, from 2^24 on, and then to `max` or to `max - 2`: the
        // first only raises the last pixel, the second changes nothing (`max` is even
        // there, so `max - 1` is no multiple of 256). So the span is never narrower than
        // the scalar one, and a box found empty here is empty there.
        let mut empty = zero;
        for a in 0..2 {
            let first = L::max(ceil::<L>(L::div(lo[a], L::splat(FIXED_ONE_F32))), zero);
            let last = L::min(floor::<L>(L::div(L::sub(hi[a], L::splat(1.0)), L::splat(FIXED_ONE_F32))), self.last[a]);
            empty = L::or(empty, L::lt(last, first));
        }
        let skipped = L::or(not_finite, beyond_one);
        let unclipped_nothing = L::andnot(clipped, L::or(bad, empty));
        let nothing = L::or(skipped, unclipped_nothing);
        let unclipped = L::andnot(L::or(L::or(skipped, clipped), bad), ones);
        Classified { clip, win, fixed, nothing: L::bits(nothing), unclipped: L::bits(unclipped) }
    }
}

/// Row `r` of `clip_position`: `((m[r] * d.x + m[4 + r] * d.y) + m[8 + r] * d.z) + m[12 + r]`.
/// (Functions, not closures, around lane operations: a closure does not inherit its
/// entry point's target features.)
#[inline(always)]
fn clip_row<L: Lanes>(m: &[L::F; 16], r: usize, d: &[L::F; 3]) -> L::F {
    L::add(L::add(L::add(L::mul(m[r], d[0]), L::mul(m[4 + r], d[1])), L::mul(m[8 + r], d[2])), m[12 + r])
}

/// All ones where `x` is finite (not infinite, not NaN).
#[inline(always)]
fn finite<L: Lanes>(x: L::F) -> L::F {
    L::lt(L::abs(x), L::splat(f32::INFINITY))
}

/// `clip_plane_distance(plane, c, guard)` per lane, the same operations.
#[inline(always)]
fn plane_distance<L: Lanes>(plane: ClipPlane, c: &[L::F; 4], guard: &[L::F; 2]) -> L::F {
    match plane {
        ClipPlane::Near => c[2],
        ClipPlane::Far => L::sub(c[3], c[2]),
        ClipPlane::GuardLeft => L::add(c[0], L::mul(guard[0], c[3])),
        ClipPlane::GuardRight => L::sub(L::mul(guard[0], c[3]), c[0]),
        ClipPlane::GuardTop => L::sub(L::mul(guard[1], c[3]), c[1]),
        ClipPlane::GuardBottom => L::add(c[1], L::mul(guard[1], c[3])),
    }
}

/// `clip_to_window(c, width, height)` per lane: `[(x/w * 0.5 + 0.5) * width,
/// (0.5 - y/w * 0.5) * height, z/w]`.
#[inline(always)]
fn clip_to_window<L: Lanes>(c: &[L::F; 4], size: [L::F; 2]) -> [L::F; 3] {
    let half = L::splat(0.5);
    let (x, y, z) = (L::div(c[0], c[3]), L::div(c[1], c[3]), L::div(c[2], c[3]));
    [L::mul(L::add(L::mul(x, half), half), size[0]), L::mul(L::sub(half, L::mul(y, half)), size[1]), z]
}

/// `snap_to_fixed(v)` per lane, as an f32 (an integer, or the unchanged value from 2^23
/// on): `round_ties_even_f32((v - 0.5) * 256)`.
#[inline(always)]
fn snap_to_fixed<L: Lanes>(v: L::F) -> L::F {
    round_ties_even::<L>(L::mul(L::sub(v, L::splat(PIXEL_CENTER_OFFSET)), L::splat(FIXED_ONE_F32)))
}

/// `round_ties_even_f32(x)` per lane: `(|x| + 2^23) - 2^23` with the sign of `x` below
/// 2^23, `x` itself from there on (NaN included).
#[inline(always)]
fn round_ties_even<L: Lanes>(x: L::F) -> L::F {
    let threshold = L::splat(F32_INTEGER_THRESHOLD);
    let a = L::abs(x);
    let r = L::sub(L::add(a, threshold), threshold);
    L::select(L::lt(a, threshold), L::or(r, L::and(x, L::splat(-0.0))), x)
}

/// The greatest integer at most `y`, for `|y| < 2^22` (exact: `round_ties_even` lies
/// within one half of `y`).
#[inline(always)]
fn floor<L: Lanes>(y: L::F) -> L::F {
    let r = round_ties_even::<L>(y);
    L::select(L::lt(y, r), L::sub(r, L::splat(1.0)), r)
}

/// The least integer at least `y`, for `|y| < 2^22` (exact): `-floor(-y)`.
#[inline(always)]
fn ceil<L: Lanes>(y: L::F) -> L::F {
    let minus = L::splat(-0.0);
    L::xor(floor::<L>(L::xor(y, minus)), minus)
}
