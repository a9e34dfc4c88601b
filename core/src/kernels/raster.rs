//! Rasterization kernels of `visibility_raster` (paper 3.2): the per-vertex,
//! per-triangle and per-pixel maths, following the rules of Mesa's
//! llvmpipe/lavapipe (`lp_setup_tri.c`, `lp_rast_tri_tmp.h`, `draw_pipe_clip.c`)
//! on x86-64, which is the rasterizer the GPU backend is checked against.
//!
//! Pipeline of one triangle, each step one function here:
//!
//! 1. [`clip_position_from_eye`]: world to clip space, `view_proj * (v - eye, 1)` in
//!    f32 with the camera's eye-relative matrix ([`clip_position`] is glam's
//!    `Mat4 * Vec4`, bit for bit).
//! 2. [`clip_plane_distance`] / [`clip_polygon_against_plane`]: Sutherland-Hodgman
//!    clipping in homogeneous space against the near (`z >= 0`) and far (`z <= w`)
//!    planes, and against the guard band (`|x|, |y| <= g * w`) only when a vertex
//!    lies beyond it. Every new vertex carries its barycentric coordinates in the
//!    *original* triangle ([`ClipVertex::bary`]).
//! 3. [`clip_to_window`]: perspective divide and viewport transform
//!    (`x_w = (ndc_x * 0.5 + 0.5) * width`, `y_w = (0.5 - ndc_y * 0.5) * height`).
//! 4. [`snap_to_fixed`]: window x, y to [`SUBPIXEL_BITS`] fractional bits, round to
//!    nearest, ties to even, in the *pixel-centre frame* (fixed coordinate 0 is the
//!    centre of pixel 0, as llvmpipe does with `half_pixel_center`).
//! 5. [`edge_function`], [`triangle_area2`], [`edge_bias`] and [`is_top_left_edge`]:
//!    exact 64-bit edge functions and the top-left fill rule; [`pixel_covered`].
//! 6. [`perspective_barycentrics`], [`barycentrics_in_original`] and
//!    [`interpolate_depth`]: the G-buffer values of a covered pixel centre;
//!    [`depth_test_value`]: what the depth test compares (a surface's interior side loses
//!    near-ties to its exterior, [`shows_interior`]).
//!
//! ## Orientation
//!
//! Window space is y-down. [`edge_function`]`(a, b, p)` is positive when `p` is on
//! the left of `a -> b` as seen on screen, so a triangle whose vertices run
//! counter-clockwise *on screen* has `triangle_area2 > 0` (llvmpipe's "ccw", its
//! `area > 0`). Setup normalizes every triangle to that orientation (by swapping
//! v1 and v2, as llvmpipe does with `flatshade_first`, lavapipe's default) before
//! the fill rule is applied. A world-space triangle seen from the front (its
//! right-handed normal `(v1 - v0) x (v2 - v0)` pointing at the eye) is
//! counter-clockwise in y-up NDC, and the viewport's y flip keeps the picture (only
//! the sign convention of the y axis changes), so it is counter-clockwise on screen
//! too: `triangle_area2 > 0` before normalization means *front face*, `< 0` means
//! *back face* (seen from behind).
//!
//! ## Ranges (why nothing overflows)
//!
//! After guard-band clipping every window coordinate lies within
//! `GUARD_BAND_PIXELS + MAX_IMAGE_DIM / 2 < 2^21` pixels of the origin, so a
//! snapped coordinate fits in [`MAX_FIXED_COORD`] `= 2^29`; setup rejects anything
//! larger. Differences of coordinates are then below `2^30`, each product in an
//! edge function below `2^60` and every edge value and doubled area below `2^61`:
//! far inside `i64`. Pixel centres inside the image are below
//! `MAX_IMAGE_DIM * FIXED_ONE = 2^28`.
//!
//! ## Agreement with lavapipe and the GPU backend
//!
//! The integer part (snapping of given window coordinates, edge functions, fill rule,
//! zero-area culling) is llvmpipe's exactly. The float part is this module's own: the
//! GPU backend does not rely on the hardware's vertex maths or attribute interpolation
//! but evaluates these very functions in its fragment shader (WGSL twins of the same
//! names, products kept from fusing) and hands the hardware pre-snapped vertices, so both
//! backends produce the same bits. Every per-pixel float step is therefore f32 (WGSL has
//! no f64), one correctly rounded operation at a time, in a stated order. Clipping:
//! near and far planes in homogeneous space with new vertices exactly on the plane, and
//! a guard band only when a vertex lies beyond it (lavapipe's own clipper is bypassed
//! for such triangles by the GPU backend's cover triangles).
//!
//! WGSL mirrors: each function names its WGSL twin (same name); 64-bit integers are
//! pairs of u32 there.

/// Fractional bits of snapped window coordinates: llvmpipe `FIXED_ORDER` (`lp_rast.h`),
/// lavapipe's `subPixelPrecisionBits`.
pub const SUBPIXEL_BITS: u32 = 8;
/// One pixel in fixed-point units (llvmpipe `FIXED_ONE`).
pub const FIXED_ONE: i64 = 1 << SUBPIXEL_BITS;
/// [`FIXED_ONE`] as f32, the scale applied before rounding.
pub const FIXED_ONE_F32: f32 = FIXED_ONE as f32;
/// Offset subtracted from window coordinates before snapping: the pixel centre
/// (llvmpipe `pixel_offset`, 0.5 because lavapipe sets `half_pixel_center`).
/// Fixed coordinates are therefore relative to the centre of pixel (0, 0), and the
/// centre of pixel (x, y) is exactly `(x * FIXED_ONE, y * FIXED_ONE)`.
pub const PIXEL_CENTER_OFFSET: f32 = 0.5;
/// Half-width of the guard band in pixels, around the viewport centre: x/y are not
/// clipped to the viewport, only to this band, and only when a vertex lies beyond
/// it. Chosen so every snapped coordinate fits [`MAX_FIXED_COORD`] with a margin of
/// 2^19 pixels for f32 rounding in the clipper (see the module docs).
pub const GUARD_BAND_PIXELS: f32 = (1u32 << 20) as f32;
/// Largest image side the rasterizer covers; pixels beyond it stay misses. Equal to
/// the guard band so the viewport always lies inside it.
pub const MAX_IMAGE_DIM: u32 = 1 << 20;
/// Largest |snapped coordinate| (fixed units) setup accepts: 2^21 pixels. Keeps
/// every edge-function product below 2^60 (module docs); a triangle with a vertex
/// beyond it (only possible through f32 overflow) is skipped.
pub const MAX_FIXED_COORD: i64 = 1 << 29;
/// Most vertices a triangle can have after clipping: 3 plus one per plane.
pub const MAX_CLIP_VERTICES: usize = 3 + CLIP_PLANES.len();

/// A clip plane of the homogeneous clipper. Inside is `distance >= 0`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ClipPlane {
    /// `z >= 0` (D3D/Vulkan/WebGPU depth range, lavapipe `clip_halfz`).
    Near,
    /// `z <= w`.
    Far,
    /// `x >= -g_x * w`: window x >= width / 2 - [`GUARD_BAND_PIXELS`].
    GuardLeft,
    /// `x <= g_x * w`.
    GuardRight,
    /// `y <= g_y * w` (NDC y up, so this bounds the top of the window).
    GuardTop,
    /// `y >= -g_y * w`.
    GuardBottom,
}

/// The planes in the order the clipper applies them.
pub const CLIP_PLANES: [ClipPlane; 6] = [
    ClipPlane::Near,
    ClipPlane::Far,
    ClipPlane::GuardLeft,
    ClipPlane::GuardRight,
    ClipPlane::GuardTop,
    ClipPlane::GuardBottom,
];

/// A vertex of a (clipped) triangle in clip space, with its barycentric
/// coordinates `(u, v)` (weights of v1 and v2) in the original, unclipped triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClipVertex {
    pub pos: [f32; 4],
    pub bary: [f32; 2],
}

impl ClipVertex {
    /// The three corners of an unclipped triangle: barycentrics (0,0), (1,0), (0,1).
    #[inline]
    pub fn triangle(p: [[f32; 4]; 3]) -> [ClipVertex; 3] {
        [
            ClipVertex { pos: p[0], bary: [0.0, 0.0] },
            ClipVertex { pos: p[1], bary: [1.0, 0.0] },
            ClipVertex { pos: p[2], bary: [0.0, 1.0] },
        ]
    }
}

/// `m * (v, 1)` in f32, column-major `m`, with glam's operation order
/// (`((c0 * x + c1 * y) + c2 * z) + c3`, no fused multiply-add), so the result is
/// bit-identical to `Mat4::from_cols_array(m) * v.extend(1.0)`.
/// WGSL: `clip_position`.
#[inline]
pub fn clip_position(m: &[f32; 16], v: [f32; 3]) -> [f32; 4] {
    let mut out = [0.0f32; 4];
    for (r, o) in out.iter_mut().enumerate() {
        *o = m[r] * v[0] + m[4 + r] * v[1] + m[8 + r] * v[2] + m[12 + r];
    }
    out
}

/// The clip position of world point `v` seen from `eye`: [`clip_position`] of `v - eye`
/// (three f32 subtractions, then the matrix) with the camera's eye-relative `view_proj`
/// ([`crate::formats::CameraRecord`]). The subtraction is exact when `v` is within a factor
/// of two of `eye` per coordinate (Sterbenz) and otherwise rounds once relative to the
/// difference, so positions keep their precision relative to the camera at any distance
/// from the origin. WGSL: `clip_position_exact`.
#[inline]
pub fn clip_position_from_eye(m: &[f32; 16], eye: [f32; 3], v: [f32; 3]) -> [f32; 4] {
    clip_position(m, [v[0] - eye[0], v[1] - eye[1], v[2] - eye[2]])
}

/// Guard-band half-extent in NDC units, `[g_x, g_y] = 2 * GUARD_BAND_PIXELS / [width, height]`.
/// WGSL: `guard_band_ndc`.
#[inline]
pub fn guard_band_ndc(width: u32, height: u32) -> [f32; 2] {
    let w = width.clamp(1, MAX_IMAGE_DIM) as f32;
    let h = height.clamp(1, MAX_IMAGE_DIM) as f32;
    [2.0 * GUARD_BAND_PIXELS / w, 2.0 * GUARD_BAND_PIXELS / h]
}

/// Signed distance-like value of clip position `p` to `plane` (not normalized):
/// `>= 0` inside. `guard` is [`guard_band_ndc`]. WGSL: `clip_plane_distance`.
#[inline]
pub fn clip_plane_distance(plane: ClipPlane, p: [f32; 4], guard: [f32; 2]) -> f32 {
    match plane {
        ClipPlane::Near => p[2],
        ClipPlane::Far => p[3] - p[2],
        ClipPlane::GuardLeft => p[0] + guard[0] * p[3],
        ClipPlane::GuardRight => guard[0] * p[3] - p[0],
        ClipPlane::GuardTop => guard[1] * p[3] - p[1],
        ClipPlane::GuardBottom => p[1] + guard[1] * p[3],
    }
}

/// The point where edge `outside -> inside` crosses `plane`, given the two
/// endpoints' distances (`d_out < 0 <= d_in`). Always interpolated *from the outside
/// vertex*, as llvmpipe's clipper does (`interp(.., t, out, in)`), so the two
/// triangles sharing an edge compute the very same bits and stay watertight:
/// `t = d_out / (d_out - d_in)`, `p = out + t * (in - out)` per component (f32), and
/// the same for the barycentrics. On the near and far planes the new vertex is then
/// put exactly on the plane (`z = 0`, resp. `z = w`) so its depth `z / w` is exactly
/// 0, resp. 1, never a rounding error outside `[0, 1]`. WGSL: `clip_edge_intersection`.
#[inline]
pub fn clip_edge_intersection(
    plane: ClipPlane,
    outside: &ClipVertex,
    inside: &ClipVertex,
    d_out: f32,
    d_in: f32,
) -> ClipVertex {
    let t = d_out / (d_out - d_in);
    let mut pos = [0.0f32; 4];
    for (k, p) in pos.iter_mut().enumerate() {
        *p = outside.pos[k] + t * (inside.pos[k] - outside.pos[k]);
    }
    let mut bary = [0.0f32; 2];
    for (k, b) in bary.iter_mut().enumerate() {
        *b = outside.bary[k] + t * (inside.bary[k] - outside.bary[k]);
    }
    match plane {
        ClipPlane::Near => pos[2] = 0.0,
        ClipPlane::Far => pos[2] = pos[3],
        _ => {}
    }
    ClipVertex { pos, bary }
}

/// One Sutherland-Hodgman step: clip the convex polygon `input` against `plane`,
/// writing the result to `output` and returning its vertex count (0 when nothing is
/// left). A vertex with distance exactly 0 is inside. Vertex order (and with it the
/// winding) is preserved; for each input edge `prev -> cur` it emits the crossing
/// (if any) and then `cur` (if inside). `input.len() < MAX_CLIP_VERTICES` is
/// required (one plane adds at most one vertex). WGSL: `clip_polygon_against_plane`.
#[inline]
pub fn clip_polygon_against_plane(
    plane: ClipPlane,
    guard: [f32; 2],
    input: &[ClipVertex],
    output: &mut [ClipVertex; MAX_CLIP_VERTICES],
) -> usize {
    let n = input.len();
    if n == 0 {
        return 0;
    }
    let mut count = 0;
    let mut prev = &input[n - 1];
    let mut d_prev = clip_plane_distance(plane, prev.pos, guard);
    for cur in input {
        let d_cur = clip_plane_distance(plane, cur.pos, guard);
        let prev_in = d_prev >= 0.0;
        let cur_in = d_cur >= 0.0;
        if prev_in != cur_in && count < MAX_CLIP_VERTICES {
            output[count] = if cur_in {
                clip_edge_intersection(plane, prev, cur, d_prev, d_cur)
            } else {
                clip_edge_intersection(plane, cur, prev, d_cur, d_prev)
            };
            count += 1;
        }
        if cur_in && count < MAX_CLIP_VERTICES {
            output[count] = *cur;
            count += 1;
        }
        prev = cur;
        d_prev = d_cur;
    }
    count
}

/// Perspective divide and viewport transform, all in f32 with this exact operation
/// order: `[(x/w * 0.5 + 0.5) * width, (0.5 - y/w * 0.5) * height, z/w]`
/// (row 0 at the top, `z/w` is the window depth). WGSL: `clip_to_window`.
#[inline]
pub fn clip_to_window(p: [f32; 4], width: f32, height: f32) -> [f32; 3] {
    let ndc_x = p[0] / p[3];
    let ndc_y = p[1] / p[3];
    let ndc_z = p[2] / p[3];
    [(ndc_x * 0.5 + 0.5) * width, (0.5 - ndc_y * 0.5) * height, ndc_z]
}

/// Snap a window coordinate to fixed point in the pixel-centre frame:
/// `round_ties_even((v - 0.5) * 256)`, each step in f32, exactly as llvmpipe's SSE
/// setup (`calc_fixed_position`: `_mm_sub_ps`, `_mm_mul_ps`, `_mm_cvtps_epi32` under
/// the default MXCSR rounding, which is nearest-even; that is the path lavapipe takes
/// on x86-64; its scalar fallback `util_iround` rounds ties away from zero instead).
///
/// The centre of pixel `x` is fixed coordinate `x * FIXED_ONE`. For
/// `0.25 <= v < 2^23` the subtraction is exact and this equals
/// `round_ties_even(v * 256) - 128`; below 0.25 the f32 subtraction can round onto a
/// 1/512 tie (e.g. `v = 1/512 + 2^-30` snaps to -128, not -127): we keep llvmpipe's result.
/// Non-finite input gives a meaningless value: callers check finiteness first.
/// WGSL: `snap_to_fixed`.
#[inline]
pub fn snap_to_fixed(v: f32) -> i64 {
    round_ties_even_f32((v - PIXEL_CENTER_OFFSET) * FIXED_ONE_F32) as i64
}

/// 2^23: from here on every f32 is an integer.
pub const F32_INTEGER_THRESHOLD: f32 = 8_388_608.0;

/// Round to the nearest integer, ties to even: `f32::round_ties_even`, written as
/// `(|x| + 2^23) - 2^23` with the sign restored, which lets the addition's own
/// round-to-nearest-even do the work (the sum lies in [2^23, 2^24), where the f32
/// spacing is exactly 1, and 2^23 is even). Without SSE4.1 `round_ties_even` is a
/// libm call; this is two additions. NaN stays NaN. WGSL: the built-in `round`,
/// which rounds ties to even (the addition trick is not safe there: WGSL may
/// reassociate it away).
#[inline]
pub fn round_ties_even_f32(x: f32) -> f32 {
    let a = x.abs();
    if a < F32_INTEGER_THRESHOLD {
        ((a + F32_INTEGER_THRESHOLD) - F32_INTEGER_THRESHOLD).copysign(x)
    } else {
        x
    }
}

/// Fixed-point position of the centre of pixel `(x, y)`. WGSL: `pixel_center_fixed`.
#[inline]
pub fn pixel_center_fixed(x: i64, y: i64) -> [i64; 2] {
    [x * FIXED_ONE, y * FIXED_ONE]
}

/// Exact edge function of the directed edge `a -> b` at `p` (fixed point):
/// `(b.y - a.y) * (p.x - a.x) - (b.x - a.x) * (p.y - a.y)`. Positive when `p` lies on
/// the left of `a -> b` on screen (y down), i.e. inside a counter-clockwise
/// (on screen) triangle; equal to llvmpipe's plane value `c + dcdy * y - dcdx * x`.
/// Inputs must be within [`MAX_FIXED_COORD`]. WGSL: `edge_function`.
#[inline]
pub fn edge_function(a: [i64; 2], b: [i64; 2], p: [i64; 2]) -> i64 {
    (b[1] - a[1]) * (p[0] - a[0]) - (b[0] - a[0]) * (p[1] - a[1])
}

/// Twice the signed area of `(v0, v1, v2)` on screen: [`edge_function`]`(v0, v1, v2)`.
/// Positive: counter-clockwise on screen (a front face); negative: clockwise (a back
/// face); zero: degenerate, culled. Equals llvmpipe's `calc_fixed_position` area.
/// WGSL: `triangle_area2`.
#[inline]
pub fn triangle_area2(v0: [i64; 2], v1: [i64; 2], v2: [i64; 2]) -> i64 {
    edge_function(v0, v1, v2)
}

/// Whether `a -> b`, an edge of a counter-clockwise (on screen, `triangle_area2 > 0`)
/// triangle, is a top or a left edge (D3D11 functional spec 3.4.2.1, y down): a left
/// edge goes down the screen (`b.y > a.y`); a top edge is horizontal and runs right
/// to left (`b.x < a.x`), which puts the triangle below it. This is llvmpipe's
/// `dcdx < 0 || (dcdx == 0 && dcdy > 0)` with `dcdx = a.y - b.y`, `dcdy = a.x - b.x`.
/// WGSL: `is_top_left_edge`.
#[inline]
pub fn is_top_left_edge(a: [i64; 2], b: [i64; 2]) -> bool {
    let dcdx = a[1] - b[1];
    let dcdy = a[0] - b[0];
    dcdx < 0 || (dcdx == 0 && dcdy > 0)
}

/// Fill-rule bias of an edge of a counter-clockwise triangle: 0 for top/left edges,
/// -1 otherwise, so that a sample is covered iff `edge_function + bias >= 0` for all
/// three edges (llvmpipe adds 1 to `c` of top/left edges and tests `c - 1 >= 0`,
/// which is the same). A sample exactly on an edge shared by two triangles is
/// therefore covered by exactly one of them. WGSL: `edge_bias`.
#[inline]
pub fn edge_bias(a: [i64; 2], b: [i64; 2]) -> i64 {
    if is_top_left_edge(a, b) {
        0
    } else {
        -1
    }
}

/// Coverage test from the three biased edge values: all non-negative.
/// WGSL: `pixel_covered`.
#[inline]
pub fn pixel_covered(biased: [i64; 3]) -> bool {
    (biased[0] | biased[1] | biased[2]) >= 0
}

/// An exact edge value as f32, rounded to nearest, ties to even (Rust's `as`; WGSL
/// `edge_value_to_f32` does the same from two 32-bit words). Every float step of the
/// per-pixel kernels below starts from these, so both backends compute the same bits.
#[inline]
pub fn edge_value_to_f32(e: i64) -> f32 {
    e as f32
}

/// Perspective-correct barycentric weights of the three (clipped-triangle) vertices
/// at a covered sample, from the exact unbiased edge values `e` (`e[i]` of the edge
/// opposite vertex i, all `>= 0` inside, sum = the doubled area) and the vertices'
/// clip `w` (all > 0 after clipping): `q_i = f32(e_i) / w_i`, `s = (q_0 + q_1) + q_2`,
/// `b_i = q_i / s`, each step one correctly rounded f32 operation, in this order.
///
/// All in f32 (not f64) so the GPU can mirror it bit for bit: WGSL has no f64, and
/// every step here is one IEEE operation that lavapipe performs exactly (its division is
/// correctly rounded; products are kept from fusing, see the WGSL). Error: each `q_i`
/// carries 2 roundings, `s` 2 more, `b_i` 1: a few ulps of 1, far below the G-buffer's
/// use (the hit point's own error bound, `kernels::barycentric`). WGSL:
/// `perspective_barycentrics`.
#[inline]
pub fn perspective_barycentrics(e: [i64; 3], w: [f32; 3]) -> [f32; 3] {
    let q0 = edge_value_to_f32(e[0]) / w[0];
    let q1 = edge_value_to_f32(e[1]) / w[1];
    let q2 = edge_value_to_f32(e[2]) / w[2];
    let s = q0 + q1 + q2;
    [q0 / s, q1 / s, q2 / s]
}

/// Map barycentric weights `b` over a clipped triangle's vertices to barycentrics
/// `(u, v)` of the original triangle through the vertices' [`ClipVertex::bary`]:
/// `u = (b0 * u0 + b1 * u1) + b2 * u2` (likewise `v`), in f32, products rounded
/// separately (no fused multiply-add). WGSL: `barycentrics_in_original`.
#[inline]
pub fn barycentrics_in_original(b: [f32; 3], attrs: [[f32; 2]; 3]) -> [f32; 2] {
    let mut out = [0.0f32; 2];
    for (k, o) in out.iter_mut().enumerate() {
        *o = b[0] * attrs[0][k] + b[1] * attrs[1][k] + b[2] * attrs[2][k];
    }
    out
}

/// [`perspective_barycentrics`] for a triangle whose vertices are the original corners
/// in some order: `iu` and `iv` are the indices of the original v1 and v2, whose
/// weights are the G-buffer's `(u, v)`. WGSL: `perspective_barycentrics_of_corners`.
#[inline]
pub fn perspective_barycentrics_of_corners(e: [i64; 3], w: [f32; 3], iu: usize, iv: usize) -> [f32; 2] {
    let b = perspective_barycentrics(e, w);
    [b[iu], b[iv]]
}

/// Window depth at a covered sample: the vertices' `z/w` interpolated linearly in
/// screen space, `((f32(e0) * z0 + f32(e1) * z1) + f32(e2) * z2) / f32(area2)`, each
/// step one correctly rounded f32 operation (no fused multiply-add). `area2` is the
/// triangle's doubled area, which equals `e0 + e1 + e2` at every sample. Every term is
/// non-negative on covered samples (`e_i >= 0`, `z_i` in `[0, 1]`), so there is no
/// cancellation: the relative error is at most about 7 * 2^-24 (3 conversions, 3
/// products, 2 sums, 1 division, 1 conversion of the area). WGSL: `interpolate_depth`.
#[inline]
pub fn interpolate_depth(e: [i64; 3], area2: i64, z: [f32; 3]) -> f32 {
    let num = edge_value_to_f32(e[0]) * z[0] + edge_value_to_f32(e[1]) * z[1] + edge_value_to_f32(e[2]) * z[2];
    num / edge_value_to_f32(area2)
}

/// Relative error bound of [`interpolate_depth`] against the exact value (see its
/// docs): 8 roundings of at most 2^-24 each, rounded up.
pub const DEPTH_INTERPOLATION_REL_ERROR: f64 = 8.0 / (1u64 << 24) as f64;

/// How many f32 steps the depth of a fragment that shows a surface's interior side is
/// pushed back in the depth test ([`depth_test_value`]), so that it never wins against the
/// exterior side it lies behind: 32.
///
/// Where it comes from: at a silhouette of a closed mesh the face seen from outside and the
/// face behind it, seen from inside, share an edge, and at pixel centres next to that edge
/// their exact depths differ by less than the rounding of [`interpolate_depth`]. Each
/// computed depth is within `8 * 2^-24` relative of its exact value
/// ([`DEPTH_INTERPOLATION_REL_ERROR`]), which is less than 8 ulps of it (for `d` in
/// `[2^k, 2^(k+1))`, `8 * 2^-24 * d < 2^(k-20) = 8 ulp(d)`), so two depths that are in
/// order exactly are out of order by less than 16 ulps once computed; 32 also covers a pair
/// that straddles a power of two. Without it the inside won a few such pixels on every
/// silhouette, and their shadow rays started inside the mesh: light leaked out of closed
/// shells (the leak corpus of `hyrt-conformance`). In view space 32 ulps of depth are
/// about `32 * 2^-24 * z^2 / near`: an interior side must be nearer than that to hide an
/// exterior side.
pub const INTERIOR_DEPTH_BIAS_ULPS: u32 = 32;

/// Whether a fragment shows the interior side of its surface: a back face
/// (`GBUF_BACK_FACE`), unless the triangle belongs to a closed mesh wound inward
/// (`TRI_INWARD`), whose exterior is the side its back faces show. Open meshes follow
/// glTF: front faces are the exterior. WGSL: `shows_interior`.
#[inline]
pub fn shows_interior(back_face: bool, inward: bool) -> bool {
    back_face != inward
}

/// The value the depth test (LESS against a clear value of 1.0) compares for a fragment of
/// window depth `depth`: the depth itself where the fragment shows the exterior side; where
/// it shows the interior side ([`shows_interior`]) the depth [`INTERIOR_DEPTH_BIAS_ULPS`]
/// f32 steps further, at most 1.0 (which never passes LESS, as a device clamps the written
/// depth to the viewport's [0, 1]). Integer arithmetic on the bits, monotone: fragments of
/// one side keep their order. A NaN or negative depth is returned as it is (the test
/// rejects it). The G-buffer keeps the unbiased depth. WGSL: `depth_test_value`.
#[inline]
pub fn depth_test_value(depth: f32, interior: bool) -> f32 {
    if interior && depth >= 0.0 {
        // `abs` turns a -0 depth into +0 before stepping.
        f32::from_bits(depth.abs().to_bits() + INTERIOR_DEPTH_BIAS_ULPS).min(1.0)
    } else {
        depth
    }
}

/// Inclusive pixel range `[lo, hi]` along one axis whose centres can be covered by a
/// triangle spanning fixed coordinates `[min, max]`: `lo = ceil(min / 256)`,
/// `hi = floor((max - 1) / 256)` (a centre at exactly `max` lies on a right or bottom
/// edge, never covered; llvmpipe's bounding box is the same but rounds `lo` down).
/// Empty when `hi < lo`. WGSL: `pixel_span`.
#[inline]
pub fn pixel_span(min: i64, max: i64) -> [i64; 2] {
    [(min + (FIXED_ONE - 1)) >> SUBPIXEL_BITS, (max - 1) >> SUBPIXEL_BITS]
}

/// How far in front of the near plane every corner of a closed object's bounds must lie
/// before the raster drops the triangles that show the object's interior
/// ([`interior_hidden`]), relative to the sum of the magnitudes of the clip coordinate's
/// terms: 2^-18.
///
/// Where it comes from: the raster computes a vertex's clip `z` and `w` in f32
/// ([`clip_position_from_eye`]: one subtraction per coordinate, then three products and
/// three sums), each operation rounding by at most 2^-24 relative, so the computed value
/// lies within `6 * 2^-24` (plus second-order terms) of the exact one times the sum of the
/// magnitudes of its terms (`|m_i (v_i - eye_i)|` and the constant). [`interior_hidden`]
/// evaluates the exact values at the corners of the bounds in f64 (rounding near 2^-53 of
/// the same sum); 2^-18, ten times `6 * 2^-24`, leaves every vertex within the bounds a
/// strictly positive computed clip `z` and `w`.
pub const INTERIOR_CULL_NEAR_MARGIN: f64 = 1.0 / 262_144.0;

/// Whether no pixel can see the interior of a closed surface whose world vertices all lie
/// within `lo..=hi`: every point of those bounds lies in front of the camera's near plane
/// (clip `z > 0` and `w > 0`, by [`INTERIOR_CULL_NEAR_MARGIN`]). Then the eye is outside
/// the bounds, and the raster clips no triangle of the surface at the near plane (which
/// would open it). Along every pixel's ray the first crossing of a closed surface seen from
/// outside enters it, through a triangle that shows the exterior; the raster's other clip
/// planes (the far plane, the guard band) only cut away what lies beyond that crossing or
/// outside every pixel's ray. After snapping, too, a pixel centre that a triangle showing
/// the interior covers is covered by one showing the exterior (on a closed surface the
/// triangles over a point, counted with the sign of their area, sum to zero, and the
/// top-left rule counts a shared edge once, the same way for the two triangles that fold
/// over it). So dropping those triangles ([`culls_interior`]) leaves no pixel uncovered;
/// a pixel it changes is one where a triangle showing the interior was nearer than the
/// exterior in front of it after rounding (see [`INTERIOR_DEPTH_BIAS_ULPS`]).
///
/// False for empty bounds (`lo > hi` on an axis) and for non-finite ones.
pub fn interior_hidden(camera: &crate::formats::CameraRecord, lo: [f32; 3], hi: [f32; 3]) -> bool {
    let finite = lo.iter().chain(&hi).all(|c| c.is_finite());
    if !finite || (0..3).any(|i| lo[i] > hi[i]) {
        return false;
    }
    let m = &camera.view_proj;
    // Rows 2 (z: the near plane is z >= 0) and 3 (w) of the column-major matrix, as
    // `clip_position_from_eye` applies it to `v - eye`. Affine in `v`: least at a corner.
    [2usize, 3].into_iter().all(|r| {
        let constant = f64::from(m[12 + r]);
        let (mut least, mut size) = (constant, constant.abs());
        for i in 0..3 {
            let a = f64::from(m[4 * i + r]);
            let eye = f64::from(camera.eye[i]);
            let (near, far) = (a * (f64::from(lo[i]) - eye), a * (f64::from(hi[i]) - eye));
            least += near.min(far);
            size += near.abs().max(far.abs());
        }
        least > INTERIOR_CULL_NEAR_MARGIN * size
    })
}

/// The words of the interior-cull bits of `objects` objects (one bit each, 32 a word, at
/// least one word, as WebGPU binds no empty buffer): the length of
/// `hyrt_core::geometry::WorldGeometry::interior_culls`.
#[inline]
pub fn interior_cull_words(objects: usize) -> usize {
    objects.div_ceil(32).max(1)
}

/// Whether the raster drops an unclipped triangle of `object` that shows its interior
/// side ([`shows_interior`]): `object`'s bit in `bits`, one bit per object, object `o` at
/// bit `o % 32` of word `o / 32` (set where [`interior_hidden`] holds for a closed object:
/// `hyrt_core::geometry::WorldGeometry::interior_culls`); objects past the words are not
/// culled. WGSL: `culls_interior`.
#[inline]
pub fn culls_interior(bits: &[u32], object: u32) -> bool {
    bits.get((object / 32) as usize).is_some_and(|w| (w >> (object % 32)) & 1 != 0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn snap_rounds_ties_to_even_in_the_pixel_centre_frame() {
        // (v - 0.5) * 256 exactly on .5: ties go to the even integer.
        assert_eq!(snap_to_fixed(0.5), 0);
        assert_eq!(snap_to_fixed(0.5 + 1.0 / 512.0), 0); // 0.5 -> 0
        assert_eq!(snap_to_fixed(0.5 + 3.0 / 512.0), 2); // 1.5 -> 2
        assert_eq!(snap_to_fixed(0.5 + 5.0 / 512.0), 2); // 2.5 -> 2
        assert_eq!(snap_to_fixed(0.5 - 1.0 / 512.0), 0); // -0.5 -> 0
        assert_eq!(snap_to_fixed(0.5 - 3.0 / 512.0), -2); // -1.5 -> -2
        assert_eq!(snap_to_fixed(100.5 + 255.0 / 512.0), 25600 + 128); // 127.5 -> 128
        assert_eq!(snap_to_fixed(100.5 + 257.0 / 512.0), 25600 + 128); // 128.5 -> 128
                                                                       // Not ties: ordinary rounding.
        assert_eq!(snap_to_fixed(0.5 + 1.0 / 256.0), 1);
        assert_eq!(snap_to_fixed(7.25), 6 * 256 + 192);
    }

    #[test]
    fn snap_keeps_llvmpipe_rounding_of_the_centre_offset_near_zero() {
        // Pinned: the f32 subtraction v - 0.5 rounds onto a 1/512 tie, which then
        // goes to even. The naive round_ties_even(v * 256) - 128 would give 1.
        let v = 1.0f32 / 512.0 + (2.0f32).powi(-30);
        assert_eq!(v - 0.5, -255.0 / 512.0);
        assert_eq!(snap_to_fixed(v), -128);
        assert_eq!((v * 256.0).round_ties_even() as i64 - 128, -127);
        let v = -1.0f32 / 512.0 - (2.0f32).powi(-30);
        assert_eq!(snap_to_fixed(v), -128);
        assert_eq!((v * 256.0).round_ties_even() as i64 - 128, -129);
    }

    #[test]
    fn edge_function_and_area_orientation() {
        // Counter-clockwise on screen (y down): top-left, bottom-left, top-right.
        let (a, b, c) = ([0, 0], [0, 2560], [2560, 0]);
        assert_eq!(triangle_area2(a, b, c), 2560 * 2560);
        assert_eq!(triangle_area2(a, c, b), -2560 * 2560);
        let p = [256, 256];
        assert!(edge_function(a, b, p) > 0 && edge_function(b, c, p) > 0 && edge_function(c, a, p) > 0);
        // The three edge values sum to the doubled area anywhere.
        for p in [[0, 0], [-999, 12345], [700, 900]] {
            let s = edge_function(b, c, p) + edge_function(c, a, p) + edge_function(a, b, p);
            assert_eq!(s, triangle_area2(a, b, c));
        }
    }

    #[test]
    fn top_left_classification() {
        // Triangle (0,0) (0,10) (10,0), counter-clockwise on screen.
        let (a, b, c) = ([0, 0], [0, 10], [10, 0]);
        assert!(is_top_left_edge(a, b), "vertical edge going down the left side is a left edge");
        assert!(!is_top_left_edge(b, c), "the hypotenuse on the bottom right is neither");
        assert!(is_top_left_edge(c, a), "horizontal edge on top, right to left, is a top edge");
        // Triangle (0,10) (10,10) (5,0): bottom horizontal edge (left to right) is not top.
        let (a, b, c) = ([0, 10], [10, 10], [5, 0]);
        assert!(triangle_area2(a, b, c) > 0);
        assert!(!is_top_left_edge(a, b));
        assert!(!is_top_left_edge(b, c), "right edge going up");
        assert!(is_top_left_edge(c, a), "left edge going down");
        assert_eq!(edge_bias(c, a), 0);
        assert_eq!(edge_bias(a, b), -1);
    }

    #[test]
    fn shared_edge_sample_is_covered_once() {
        // Two triangles sharing the diagonal (0,0)-(512,512) of a square; the
        // pixel centre (256,256) lies on it.
        let q = [[0, 0], [512, 0], [512, 512], [0, 512]];
        let tris = [[q[0], q[3], q[2]], [q[0], q[2], q[1]]];
        let mut n = 0;
        for t in tris {
            let [v0, v1, v2] = if triangle_area2(t[0], t[1], t[2]) > 0 { t } else { [t[0], t[2], t[1]] };
            let p = [256, 256];
            let biased = [
                edge_function(v1, v2, p) + edge_bias(v1, v2),
                edge_function(v2, v0, p) + edge_bias(v2, v0),
                edge_function(v0, v1, p) + edge_bias(v0, v1),
            ];
            n += pixel_covered(biased) as u32;
        }
        assert_eq!(n, 1);
    }

    #[test]
    fn pixel_span_bounds() {
        assert_eq!(pixel_span(0, 256), [0, 0]);
        assert_eq!(pixel_span(1, 256), [1, 0]); // empty
        assert_eq!(pixel_span(-1, 257), [0, 1]);
        assert_eq!(pixel_span(-300, -10), [-1, -1]);
    }

    #[test]
    fn interior_sides_lose_depth_ties_by_a_fixed_number_of_steps() {
        assert!(shows_interior(true, false) && shows_interior(false, true));
        assert!(!shows_interior(false, false) && !shows_interior(true, true));
        assert_eq!(depth_test_value(0.5, false), 0.5);
        assert_eq!(depth_test_value(0.5, true).to_bits(), 0.5f32.to_bits() + INTERIOR_DEPTH_BIAS_ULPS);
        assert_eq!(depth_test_value(-0.0, true).to_bits(), INTERIOR_DEPTH_BIAS_ULPS);
        assert_eq!(depth_test_value(1.0 - f32::EPSILON, true), 1.0);
        assert!(depth_test_value(f32::NAN, true).is_nan());
        assert_eq!(depth_test_value(-0.25, true), -0.25);
        // Monotone, and larger than every depth within 16 steps below it.
        let d = 0.987_654_3f32;
        assert!(depth_test_value(d, true) < depth_test_value(f32::from_bits(d.to_bits() + 1), true));
        assert!(depth_test_value(d, true) > f32::from_bits(d.to_bits() + 16));
        // 16 ulps of any depth exceed the stated error bound of two depths.
        for d in [1e-6f32, 0.25, 0.4999999, 0.5, 0.75, 0.9999] {
            let ulp = (f32::from_bits(d.to_bits() + 1) - d) as f64;
            assert!(2.0 * DEPTH_INTERPOLATION_REL_ERROR * d as f64 <= 16.0 * ulp, "{d}");
        }
    }

    #[test]
    fn barycentrics_and_depth_at_vertices() {
        let area = 1000;
        let w = [1.0, 2.0, 4.0];
        assert_eq!(perspective_barycentrics([area, 0, 0], w), [1.0, 0.0, 0.0]);
        assert_eq!(perspective_barycentrics([0, 0, area], w), [0.0, 0.0, 1.0]);
        let z = [0.25, 0.5, 0.75];
        assert_eq!(interpolate_depth([0, area, 0], area, z), 0.5);
        // Equal w: perspective weights are the affine ones.
        let b = perspective_barycentrics([250, 250, 500], [3.0; 3]);
        assert_eq!(b, [0.25, 0.25, 0.5]);
        // Perspective: halfway on screen between w=1 and w=3 is 1/4 of the way in 3D.
        let b = perspective_barycentrics([500, 500, 0], [1.0, 3.0, 1.0]);
        assert_eq!(b, [0.75, 0.25, 0.0], "exact here: 500, 500/3 and their sum round to 0.75 and 0.25");
        let ident = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        let b = [0.2f32, 0.3, 0.5];
        assert_eq!(barycentrics_in_original(b, ident), [0.3f32, 0.5f32]);
    }

    #[test]
    fn clip_triangle_crossing_near_plane() {
        let guard = guard_band_ndc(64, 64);
        let tri = ClipVertex::triangle([[0.0, 0.0, -1.0, 1.0], [1.0, 0.0, 1.0, 2.0], [0.0, 1.0, 1.0, 2.0]]);
        let mut out = [tri[0]; MAX_CLIP_VERTICES];
        let n = clip_polygon_against_plane(ClipPlane::Near, guard, &tri, &mut out);
        assert_eq!(n, 4);
        for v in &out[..n] {
            assert!(v.pos[2] >= 0.0);
            // Barycentrics reproduce the position from the original corners.
            let (u, w) = (v.bary[0], v.bary[1]);
            for k in 0..4 {
                let p = (1.0 - u - w) * tri[0].pos[k] + u * tri[1].pos[k] + w * tri[2].pos[k];
                if k != 2 {
                    assert!((p - v.pos[k]).abs() < 1e-6, "{v:?}");
                }
            }
        }
        // Entirely outside: nothing left.
        let behind = ClipVertex::triangle([[0.0, 0.0, -1.0, 1.0], [1.0, 0.0, -1.0, 1.0], [0.0, 1.0, -0.5, 1.0]]);
        assert_eq!(clip_polygon_against_plane(ClipPlane::Near, guard, &behind, &mut out), 0);
    }

    proptest! {
        #[test]
        fn clip_position_matches_glam(m in prop::array::uniform16(-100.0f32..100.0), v in prop::array::uniform3(-1e4f32..1e4)) {
            let g = glam::Mat4::from_cols_array(&m) * glam::Vec3::from(v).extend(1.0);
            let ours = clip_position(&m, v);
            prop_assert_eq!(ours.map(f32::to_bits), g.to_array().map(f32::to_bits));
        }

        #[test]
        fn shared_edge_crossing_is_identical_from_both_sides(
            a in prop::array::uniform4(-10.0f32..10.0),
            b in prop::array::uniform4(-10.0f32..10.0),
        ) {
            // Whichever triangle clips the edge, and in whichever direction its
            // polygon walks it, the new vertex has the same position bits.
            let plane = ClipPlane::Near;
            let guard = guard_band_ndc(100, 50);
            let va = ClipVertex { pos: a, bary: [0.0, 0.0] };
            let vb = ClipVertex { pos: b, bary: [1.0, 0.0] };
            let (da, db) = (clip_plane_distance(plane, a, guard), clip_plane_distance(plane, b, guard));
            prop_assume!((da >= 0.0) != (db >= 0.0));
            let c = ClipVertex { pos: [a[0], a[1], a[2] + 1.0, a[3]], bary: [0.0, 1.0] };
            let mut o1 = [va; MAX_CLIP_VERTICES];
            let mut o2 = [va; MAX_CLIP_VERTICES];
            let n1 = clip_polygon_against_plane(plane, guard, &[va, vb, c], &mut o1);
            let n2 = clip_polygon_against_plane(plane, guard, &[vb, va, c], &mut o2);
            let cross = |o: &[ClipVertex]| -> Vec<[u32; 4]> {
                o.iter().filter(|v| v.pos != a && v.pos != b && v.pos != c.pos).map(|v| v.pos.map(f32::to_bits)).collect()
            };
            let x1 = cross(&o1[..n1]);
            let x2 = cross(&o2[..n2]);
            prop_assert!(x1.iter().any(|p| x2.contains(p)), "{:?} vs {:?}", x1, x2);
        }

        #[test]
        fn corner_barycentrics_match_the_general_path(
            e in prop::array::uniform3(0i64..(1i64 << 40)),
            w in prop::array::uniform3(1e-3f32..1e4),
            perm in 0usize..6,
        ) {
            prop_assume!(e.iter().sum::<i64>() > 0);
            let orders = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
            let o = orders[perm];
            // Vertex i is original corner o[i].
            let corner = [[0.0f32, 0.0], [1.0, 0.0], [0.0, 1.0]];
            let attrs = [corner[o[0]], corner[o[1]], corner[o[2]]];
            let iu = o.iter().position(|&c| c == 1).unwrap();
            let iv = o.iter().position(|&c| c == 2).unwrap();
            let general = barycentrics_in_original(perspective_barycentrics(e, w), attrs);
            let fast = perspective_barycentrics_of_corners(e, w, iu, iv);
            prop_assert_eq!(general.map(f32::to_bits), fast.map(f32::to_bits));
        }

        #[test]
        fn round_ties_even_matches_std(bits in any::<u32>()) {
            let x = f32::from_bits(bits);
            let (ours, std) = (round_ties_even_f32(x), x.round_ties_even());
            prop_assert!(ours.to_bits() == std.to_bits() || (ours.is_nan() && std.is_nan()), "{} -> {} vs {}", x, ours, std);
        }

        #[test]
        fn round_ties_even_matches_std_near_ties(k in -(1i64 << 26)..(1i64 << 26)) {
            let x = k as f32 * 0.5;
            prop_assert_eq!(round_ties_even_f32(x).to_bits(), x.round_ties_even().to_bits());
            let y = f32::from_bits(x.to_bits().wrapping_add(1));
            prop_assert_eq!(round_ties_even_f32(y).to_bits(), y.round_ties_even().to_bits());
        }

        #[test]
        fn snap_matches_exact_reference(k in -(1i64 << 22)..(1i64 << 22)) {
            // v = k / 1024 is exact in f32 for |k| < 2^24; the reference rounds
            // (v - 0.5) * 256 = (k - 512) / 4 to nearest even with integers.
            let v = k as f32 / 1024.0;
            let n = k - 512;
            let (q, r) = (n.div_euclid(4), n.rem_euclid(4));
            let expect = match r { 0 | 1 => q, 3 => q + 1, _ => if q % 2 == 0 { q } else { q + 1 } };
            prop_assert_eq!(snap_to_fixed(v), expect);
        }
    }

    /// The camera of `eye` looking at the origin (near 0.1), 64x64 pixels.
    fn camera_at(eye: [f32; 3]) -> crate::formats::CameraRecord {
        let mut c = crate::scene::Camera::look_at(glam::Vec3::from(eye), glam::Vec3::ZERO, glam::Vec3::Y);
        c.near = 0.1;
        crate::formats::CameraRecord::new(&c, 64, 64)
    }

    #[test]
    fn interior_hidden_holds_for_bounds_wholly_in_front_of_the_near_plane_only() {
        let cam = camera_at([0.0, 0.0, 5.0]);
        // In front, in view and beside it (off screen, but in front of the plane).
        assert!(interior_hidden(&cam, [-1.0; 3], [1.0; 3]));
        assert!(interior_hidden(&cam, [40.0, -1.0, -1.0], [41.0, 1.0, 1.0]));
        // The eye inside; the bounds across the near plane (4.9 from the eye along -z is
        // z = 0.1 .. the plane at z = 4.9); behind the eye; touching the eye.
        assert!(!interior_hidden(&cam, [-1.0, -1.0, -1.0], [1.0, 1.0, 6.0]));
        assert!(!interior_hidden(&cam, [-1.0, -1.0, 4.85], [1.0, 1.0, 4.95]));
        assert!(!interior_hidden(&cam, [-1.0, -1.0, 6.0], [1.0, 1.0, 7.0]));
        assert!(!interior_hidden(&cam, [-1.0, -1.0, 0.0], [1.0, 1.0, 5.0]));
        // Just in front of the near plane (z = 4.9) and just across it.
        assert!(interior_hidden(&cam, [-1.0, -1.0, 0.0], [1.0, 1.0, 4.899]));
        assert!(!interior_hidden(&cam, [-1.0, -1.0, 0.0], [1.0, 1.0, 4.901]));
        // Empty and non-finite bounds.
        assert!(!interior_hidden(&cam, [1.0; 3], [-1.0; 3]));
        assert!(!interior_hidden(&cam, [f32::NAN, 0.0, 0.0], [1.0; 3]));
        assert!(!interior_hidden(&cam, [-1.0; 3], [f32::INFINITY, 1.0, 1.0]));
    }

    #[test]
    fn culls_interior_reads_one_bit_per_object() {
        let bits = [0b101u32, 1 << 31];
        let culled: Vec<u32> = (0..80).filter(|&o| culls_interior(&bits, o)).collect();
        assert_eq!(culled, vec![0, 2, 63]);
        assert!(!culls_interior(&[], 0));
    }

    proptest! {
        /// Every vertex of bounds `interior_hidden` accepts computes, as the raster
        /// computes it, a clip position strictly in front of the near plane with `w > 0`:
        /// no triangle within them is clipped at the near plane.
        #[test]
        fn interior_hidden_bounds_give_positive_clip_z_and_w(
            eye in prop::array::uniform3(-50.0f32..50.0),
            lo in prop::array::uniform3(-50.0f32..50.0),
            size in prop::array::uniform3(0.0f32..20.0),
            t in prop::array::uniform3(0.0f32..=1.0),
        ) {
            prop_assume!(eye.iter().map(|c| c * c).sum::<f32>() > 1e-2);
            let cam = camera_at(eye);
            let hi = [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]];
            prop_assume!(interior_hidden(&cam, lo, hi));
            let v: [f32; 3] = std::array::from_fn(|i| (lo[i] + t[i] * (hi[i] - lo[i])).clamp(lo[i], hi[i]));
            let c = clip_position_from_eye(&cam.view_proj, cam.eye, v);
            prop_assert!(c[2] > 0.0 && c[3] > 0.0, "{v:?}: clip {c:?}");
        }
    }
}
