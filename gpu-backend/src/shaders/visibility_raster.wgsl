// visibility_raster (paper 3.2): the hardware raster pass and the compute resolve
// into `array<GBufferTexel>`. Rust side: gpu-backend/src/visibility_raster.rs.
//
// The constants of hyrt_core::kernels::raster (MAX_IMAGE_DIM, GUARD_BAND_PIXELS,
// MAX_CLIP_VERTICES, PIXEL_CENTER_OFFSET, FIXED_ONE, FIXED_ONE_F32,
// MAX_FIXED_COORD_F32) are prepended by `shader_source` from the Rust values.
//
// `TRIANGLE_ID_SOURCE` is replaced at pipeline creation (see `shader_source`):
// with `@builtin(primitive_index)` the file is prefixed with `enable primitive_index;`
// and the fragment shader reads the id from the builtin; otherwise the vertex shader
// passes `vertex_index / 3` as a flat-interpolated output (every vertex belongs to
// exactly one triangle: the draw is non-indexed over unshared vertices).

struct TriangleRecord {
    v0: vec3<f32>,
    object: u32,
    v1: vec3<f32>,
    triangle: u32,
    v2: vec3<f32>,
    flags: u32,
}

struct CameraRecord {
    view_proj: mat4x4<f32>,
    inv_view_proj: mat4x4<f32>,
    eye: vec3<f32>,
    width: u32,
    height: u32,
    near: f32,
    far: f32,
    pad: u32,
}

struct GBufferTexel {
    bary_u: f32,
    bary_v: f32,
    depth: f32,
    triangle: u32,
    object: u32,
    flags: u32,
}

// hyrt_core::formats constants.
const GBUF_HIT: u32 = 1u;
const GBUF_RAY_TRACED: u32 = 2u;
const GBUF_BACK_FACE: u32 = 4u;
const TRI_RAY_TRACED: u32 = 1u;
const INVALID_ID: u32 = 0xffffffffu;
const F32_EXPONENT_MASK: u32 = 0x7f800000u;
// A clip position outside the view volume (x > w): a triangle with a non-finite
// vertex gets it at all three corners and is clipped away entirely.
const OUTSIDE_CLIP: vec4<f32> = vec4<f32>(2.0, 2.0, 0.5, 1.0);

// ---------------------------------------------------------------- raster pass

@group(0) @binding(0) var<storage, read> triangles: array<TriangleRecord>;
@group(0) @binding(1) var<uniform> camera: CameraRecord;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    // Global triangle index (used only without primitive_index).
    @location(0) @interpolate(flat) triangle: u32,
}

fn is_finite4(p: vec4<f32>) -> bool {
    let e = bitcast<vec4<u32>>(p) & vec4<u32>(F32_EXPONENT_MASK);
    return all(e != vec4<u32>(F32_EXPONENT_MASK));
}

// Largest |window coordinate| (pixels) for which a vertex is handed to the hardware
// pre-snapped: its NDC position is rebuilt from the reference's fixed-point position,
// and the hardware's viewport transform (about 3 roundings of a value below 2^11, each
// at most 2^-13 px) lands within 1/512 px of it, so the hardware's own snapping gives
// back the same fixed-point value even where the float value sat on a rounding tie.
const PRESNAP_LIMIT_PX: f32 = 2048.0;

// The NDC position (w = 1) whose window position is `win` (pixels).
fn window_to_ndc(win: vec2<f32>, depth: f32) -> vec4<f32> {
    return vec4<f32>(win.x / f32(camera.width) * 2.0 - 1.0, 1.0 - win.y / f32(camera.height) * 2.0, depth, 1.0);
}

// The clip position handed to the hardware for corner `k` of triangle `c` (clip space).
//
// - The reference draws the triangle unclipped and all of it lies inside the viewport
//   (and within PRESNAP_LIMIT_PX): the corner pre-snapped (w = 1), so the hardware
//   covers exactly the reference's pixel centres.
// - Otherwise (the reference clips it against the near or far plane or the guard band,
//   or it crosses the viewport's border, where lavapipe clips it to the viewport with
//   its own rounding and can move an edge by an ulp): a cover triangle over the reference's pixel bounding
//   box (every sub-triangle after clipping, as `pixel_span`, within the image) plus a
//   pixel of margin. The fragment shader then keeps exactly the reference's pixels.
fn hardware_position(c: array<vec4<f32>, 3>, k: u32) -> vec4<f32> {
    let guard = guard_band_ndc();
    var outside = 0u;
    var presnap = true;
    var corners: array<vec4<f32>, 3>;
    for (var i = 0u; i < 3u; i++) {
        for (var plane = 0u; plane < CLIP_PLANE_COUNT; plane++) {
            if clip_plane_distance(plane, c[i], guard) < 0.0 {
                outside |= 1u << plane;
            }
        }
        let q = clip_to_window(c[i]);
        let size = vec2<f32>(f32(camera.width), f32(camera.height));
        presnap = presnap && all(q.xy >= vec2<f32>(0.0)) && all(q.xy <= min(size, vec2<f32>(PRESNAP_LIMIT_PX)));
        // Back to window coordinates (exact: integers below 2^20, then a power of two).
        let fixed = vec2<f32>(snap_to_fixed(q.x), snap_to_fixed(q.y));
        corners[i] = window_to_ndc((fixed + vec2<f32>(PIXEL_CENTER_OFFSET * FIXED_ONE_F32)) / FIXED_ONE_F32, q.z);
    }
    if outside == 0u && presnap {
        return corners[k];
    }
    // The reference's polygon (clipped as in sample_reference), its fixed-point box.
    poly[0] = ClipVertex(c[0], vec2<f32>(0.0));
    poly[1] = ClipVertex(c[1], vec2<f32>(0.0));
    poly[2] = ClipVertex(c[2], vec2<f32>(0.0));
    var n = 3u;
    for (var plane = 0u; plane < CLIP_PLANE_COUNT; plane++) {
        if (outside & (1u << plane)) != 0u {
            n = clip_polygon_against_plane(plane, guard, n);
            poly = next_poly;
        }
    }
    var lo = vec2<f32>(MAX_FIXED_COORD_F32);
    var hi = vec2<f32>(-MAX_FIXED_COORD_F32);
    for (var i = 0u; i < n; i++) {
        let q = clip_to_window(poly[i].pos);
        if is_finite4(vec4<f32>(q, 1.0)) && poly[i].pos.w > 0.0 {
            let f = vec2<f32>(snap_to_fixed(q.x), snap_to_fixed(q.y));
            lo = min(lo, f);
            hi = max(hi, f);
        }
    }
    // pixel_span, within the image, as pixel-edge coordinates [x0, x1) x [y0, y1).
    let size = vec2<f32>(f32(camera.width), f32(camera.height));
    let x0 = max(ceil(lo / FIXED_ONE_F32), vec2<f32>(0.0));
    let x1 = min(floor((hi - 1.0) / FIXED_ONE_F32) + 1.0, size);
    if n < 3u || any(x1 <= x0) {
        return OUTSIDE_CLIP;
    }
    // A right triangle whose legs are twice the box (plus a pixel of margin): its
    // hypotenuse passes outside the box's far corner.
    let a = x0 - 1.0;
    let b = x1 + 1.0;
    let cover = array<vec2<f32>, 3>(a, vec2<f32>(a.x + 2.0 * (b.x - a.x), a.y), vec2<f32>(a.x, a.y + 2.0 * (b.y - a.y)));
    return window_to_ndc(cover[k], 0.5);
}

@vertex
fn vs_main(@builtin(vertex_index) vertex_index: u32) -> VertexOut {
    let tri_index = vertex_index / 3u;
    let t = triangles[tri_index];
    // All three corners, so every vertex of a triangle makes the same decision; the
    // reference's clip positions (see the exact kernels below), so the hardware
    // rasterizes the very triangle the fragment shader checks against.
    let c = array<vec4<f32>, 3>(clip_position_exact(t.v0), clip_position_exact(t.v1), clip_position_exact(t.v2));
    var out: VertexOut;
    out.triangle = tri_index;
    if !(is_finite4(c[0]) && is_finite4(c[1]) && is_finite4(c[2])) {
        out.clip = OUTSIDE_CLIP;
        return out;
    }
    out.clip = hardware_position(c, vertex_index % 3u);
    return out;
}

// ---------------------------------------------------------------- exact kernels
//
// The fragment shader does not use the hardware's interpolated attributes: it
// recomputes the CPU reference's setup of its triangle (clip, project, snap, normalize)
// and evaluates the exact edge functions at its pixel centre, so barycentrics and depth
// are bit-identical to hyrt_core::kernels::raster, and writes that depth as
// `frag_depth`, so the depth test compares the reference's values. The hardware decides
// which fragments run at all; a fragment the reference does not cover is discarded.
//
// Bit-exactness rules: every product goes through `mul` (or `rounded`), which ORs the
// always-zero `camera.pad` into its bits: the compiler cannot see through it, so it
// cannot fuse the product into a multiply-add (lavapipe fuses plain vector
// expressions: measured) or reassociate it. Division, conversions and `round` (ties to
// even) are single IEEE operations. 64-bit integers are pairs of u32 (lo, hi).

fn rounded(x: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(x) | camera.pad);
}

fn mul(a: f32, b: f32) -> f32 {
    return rounded(a * b);
}

// mirrors hyrt_core::kernels::raster::clip_position (glam's order, no fused multiply-add)
fn clip_position_exact(v: vec3<f32>) -> vec4<f32> {
    let m = camera.view_proj;
    var o: vec4<f32>;
    for (var r = 0u; r < 4u; r++) {
        o[r] = rounded(rounded(mul(m[0][r], v.x) + mul(m[1][r], v.y)) + mul(m[2][r], v.z)) + m[3][r];
    }
    return o;
}

// mirrors hyrt_core::kernels::raster::guard_band_ndc
fn guard_band_ndc() -> vec2<f32> {
    let w = f32(clamp(camera.width, 1u, MAX_IMAGE_DIM));
    let h = f32(clamp(camera.height, 1u, MAX_IMAGE_DIM));
    return vec2<f32>((2.0 * GUARD_BAND_PIXELS) / w, (2.0 * GUARD_BAND_PIXELS) / h);
}

// Clip planes in hyrt_core::kernels::raster::CLIP_PLANES order.
const PLANE_NEAR: u32 = 0u;
const PLANE_FAR: u32 = 1u;
const PLANE_GUARD_LEFT: u32 = 2u;
const PLANE_GUARD_RIGHT: u32 = 3u;
const PLANE_GUARD_TOP: u32 = 4u;
const PLANE_GUARD_BOTTOM: u32 = 5u;
const CLIP_PLANE_COUNT: u32 = 6u;
const CLIP_OUTCODES: u32 = 63u;

// mirrors hyrt_core::kernels::raster::clip_plane_distance
fn clip_plane_distance(plane: u32, p: vec4<f32>, guard: vec2<f32>) -> f32 {
    switch plane {
        case 0u: { return p.z; }
        case 1u: { return p.w - p.z; }
        case 2u: { return p.x + mul(guard.x, p.w); }
        case 3u: { return mul(guard.x, p.w) - p.x; }
        case 4u: { return mul(guard.y, p.w) - p.y; }
        default: { return p.y + mul(guard.y, p.w); }
    }
}

// hyrt_core::kernels::raster::ClipVertex
struct ClipVertex {
    pos: vec4<f32>,
    bary: vec2<f32>,
}

// mirrors hyrt_core::kernels::raster::clip_edge_intersection
fn clip_edge_intersection(plane: u32, outside: ClipVertex, inside: ClipVertex, d_out: f32, d_in: f32) -> ClipVertex {
    let t = d_out / (d_out - d_in);
    var pos: vec4<f32>;
    for (var k = 0u; k < 4u; k++) {
        pos[k] = outside.pos[k] + mul(t, inside.pos[k] - outside.pos[k]);
    }
    var bary: vec2<f32>;
    for (var k = 0u; k < 2u; k++) {
        bary[k] = outside.bary[k] + mul(t, inside.bary[k] - outside.bary[k]);
    }
    if plane == PLANE_NEAR {
        pos.z = 0.0;
    } else if plane == PLANE_FAR {
        pos.z = pos.w;
    }
    return ClipVertex(pos, bary);
}

var<private> poly: array<ClipVertex, MAX_CLIP_VERTICES>;
var<private> next_poly: array<ClipVertex, MAX_CLIP_VERTICES>;

// mirrors hyrt_core::kernels::raster::clip_polygon_against_plane (poly -> next_poly)
fn clip_polygon_against_plane(plane: u32, guard: vec2<f32>, n: u32) -> u32 {
    if n == 0u {
        return 0u;
    }
    var count = 0u;
    var prev = poly[n - 1u];
    var d_prev = clip_plane_distance(plane, prev.pos, guard);
    for (var i = 0u; i < n; i++) {
        let cur = poly[i];
        let d_cur = clip_plane_distance(plane, cur.pos, guard);
        let prev_in = d_prev >= 0.0;
        let cur_in = d_cur >= 0.0;
        if prev_in != cur_in && count < MAX_CLIP_VERTICES {
            if cur_in {
                next_poly[count] = clip_edge_intersection(plane, prev, cur, d_prev, d_cur);
            } else {
                next_poly[count] = clip_edge_intersection(plane, cur, prev, d_cur, d_prev);
            }
            count += 1u;
        }
        if cur_in && count < MAX_CLIP_VERTICES {
            next_poly[count] = cur;
            count += 1u;
        }
        prev = cur;
        d_prev = d_cur;
    }
    return count;
}

// mirrors hyrt_core::kernels::raster::clip_to_window
fn clip_to_window(p: vec4<f32>) -> vec3<f32> {
    let ndc_x = p.x / p.w;
    let ndc_y = p.y / p.w;
    let ndc_z = p.z / p.w;
    let wx = mul(rounded(mul(ndc_x, 0.5) + 0.5), f32(camera.width));
    let wy = mul(rounded(0.5 - mul(ndc_y, 0.5)), f32(camera.height));
    return vec3<f32>(wx, wy, ndc_z);
}

// mirrors hyrt_core::kernels::raster::snap_to_fixed, as f32 (an integer value; the
// caller checks its range before converting)
fn snap_to_fixed(v: f32) -> f32 {
    return round(mul(rounded(v - PIXEL_CENTER_OFFSET), FIXED_ONE_F32));
}

// ---- 64-bit integers as vec2<u32>(lo, hi), two's complement

fn mul_u32_wide(a: u32, b: u32) -> vec2<u32> {
    let a0 = a & 0xffffu;
    let a1 = a >> 16u;
    let b0 = b & 0xffffu;
    let b1 = b >> 16u;
    let p00 = a0 * b0;
    let p01 = a0 * b1;
    let p10 = a1 * b0;
    let p11 = a1 * b1;
    let mid = (p00 >> 16u) + (p01 & 0xffffu) + (p10 & 0xffffu);
    return vec2<u32>((p00 & 0xffffu) | (mid << 16u), p11 + (p01 >> 16u) + (p10 >> 16u) + (mid >> 16u));
}

fn neg64(x: vec2<u32>) -> vec2<u32> {
    let lo = ~x.x + 1u;
    return vec2<u32>(lo, ~x.y + select(0u, 1u, lo == 0u));
}

fn add64(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    let lo = a.x + b.x;
    return vec2<u32>(lo, a.y + b.y + select(0u, 1u, lo < a.x));
}

fn is_negative64(a: vec2<u32>) -> bool {
    return (a.y >> 31u) != 0u;
}

// |a|, |b| < 2^31 (fixed-point differences are below 2^30).
fn mul_i32_wide(a: i32, b: i32) -> vec2<u32> {
    let p = mul_u32_wide(u32(abs(a)), u32(abs(b)));
    return select(p, neg64(p), (a < 0) != (b < 0));
}

// mirrors hyrt_core::kernels::raster::edge_function
fn edge_function(a: vec2<i32>, b: vec2<i32>, p: vec2<i32>) -> vec2<u32> {
    return add64(mul_i32_wide(b.y - a.y, p.x - a.x), neg64(mul_i32_wide(b.x - a.x, p.y - a.y)));
}

// mirrors hyrt_core::kernels::raster::edge_value_to_f32 (round to nearest, ties to
// even): the top 32 bits of the normalized magnitude, with a sticky bit for the rest,
// convert exactly as the 64-bit value would; the power-of-two scale is exact.
fn edge_value_to_f32(x: vec2<u32>) -> f32 {
    let negative = is_negative64(x);
    let m = select(x, neg64(x), negative);
    var r: f32;
    if m.y == 0u {
        r = f32(m.x);
    } else {
        let s = countLeadingZeros(m.y);
        var top = m.y;
        var rest = m.x;
        if s > 0u {
            top = (m.y << s) | (m.x >> (32u - s));
            rest = m.x << s;
        }
        top |= select(0u, 1u, rest != 0u);
        r = f32(top) * bitcast<f32>((127u + 32u - s) << 23u);
    }
    return select(r, -r, negative);
}

// mirrors hyrt_core::kernels::raster::is_top_left_edge / edge_bias (as a 64-bit value)
fn edge_bias(a: vec2<i32>, b: vec2<i32>) -> vec2<u32> {
    let dcdx = a.y - b.y;
    let dcdy = a.x - b.x;
    if dcdx < 0 || (dcdx == 0 && dcdy > 0) {
        return vec2<u32>(0u, 0u);
    }
    return vec2<u32>(0xffffffffu, 0xffffffffu);
}

// mirrors hyrt_core::kernels::raster::perspective_barycentrics
fn perspective_barycentrics(e: array<f32, 3>, w: vec3<f32>) -> vec3<f32> {
    let q0 = e[0] / w.x;
    let q1 = e[1] / w.y;
    let q2 = e[2] / w.z;
    let s = rounded(q0 + q1) + q2;
    return vec3<f32>(q0 / s, q1 / s, q2 / s);
}

// mirrors hyrt_core::kernels::raster::interpolate_depth
fn interpolate_depth(e: array<f32, 3>, area2: f32, z: vec3<f32>) -> f32 {
    let num = rounded(rounded(mul(e[0], z.x) + mul(e[1], z.y)) + mul(e[2], z.z));
    return num / area2;
}

// mirrors hyrt_core::kernels::raster::barycentrics_in_original
fn barycentrics_in_original(b: vec3<f32>, a0: vec2<f32>, a1: vec2<f32>, a2: vec2<f32>) -> vec2<f32> {
    var out: vec2<f32>;
    for (var k = 0u; k < 2u; k++) {
        out[k] = rounded(rounded(mul(b.x, a0[k]) + mul(b.y, a1[k])) + mul(b.z, a2[k]));
    }
    return out;
}

// What the reference gives a covered pixel centre.
struct Sample {
    covered: bool,
    bary: vec2<f32>,
    depth: f32,
    back_face: bool,
}

// mirrors cpu-backend visibility_raster::emit_triangle and the per-pixel evaluation of
// rasterize_triangle and the tile resolve, for one (sub-)triangle at pixel centre `p`.
fn sample_triangle(v0: ClipVertex, v1: ClipVertex, v2: ClipVertex, unclipped: bool, p: vec2<i32>) -> Sample {
    var miss: Sample;
    miss.covered = false;
    let vs = array<ClipVertex, 3>(v0, v1, v2);
    var win: array<vec3<f32>, 3>;
    var fixed: array<vec2<i32>, 3>;
    for (var k = 0u; k < 3u; k++) {
        let q = clip_to_window(vs[k].pos);
        let finite = is_finite4(vec4<f32>(q, 1.0));
        if !(finite && vs[k].pos.w > 0.0) {
            return miss;
        }
        let fx = snap_to_fixed(q.x);
        let fy = snap_to_fixed(q.y);
        if abs(fx) > MAX_FIXED_COORD_F32 || abs(fy) > MAX_FIXED_COORD_F32 {
            return miss;
        }
        fixed[k] = vec2<i32>(i32(fx), i32(fy));
        win[k] = q;
    }
    let area = edge_function(fixed[0], fixed[1], fixed[2]);
    if area.x == 0u && area.y == 0u {
        return miss;
    }
    let back = is_negative64(area);
    let a = select(1u, 2u, back);
    let b = select(2u, 1u, back);
    let x = array<vec2<i32>, 3>(fixed[0], fixed[a], fixed[b]);
    var e: array<vec2<u32>, 3>;
    for (var i = 0u; i < 3u; i++) {
        let ea = x[(i + 1u) % 3u];
        let eb = x[(i + 2u) % 3u];
        e[i] = edge_function(ea, eb, p);
        if is_negative64(add64(e[i], edge_bias(ea, eb))) {
            return miss;
        }
    }
    let area2 = edge_value_to_f32(select(area, neg64(area), back));
    let ef = array<f32, 3>(edge_value_to_f32(e[0]), edge_value_to_f32(e[1]), edge_value_to_f32(e[2]));
    let w = vec3<f32>(vs[0].pos.w, vs[a].pos.w, vs[b].pos.w);
    let bw = perspective_barycentrics(ef, w);
    var out: Sample;
    out.covered = true;
    out.back_face = back;
    out.depth = interpolate_depth(ef, area2, vec3<f32>(win[0].z, win[a].z, win[b].z));
    if unclipped {
        // perspective_barycentrics_of_corners: the weights of the original v1 and v2.
        let bws = array<f32, 3>(bw.x, bw.y, bw.z);
        let iu = select(1u, 2u, back);
        let iv = select(2u, 1u, back);
        out.bary = vec2<f32>(bws[iu], bws[iv]);
    } else {
        out.bary = barycentrics_in_original(bw, vs[0].bary, vs[a].bary, vs[b].bary);
    }
    return out;
}

// The reference's result for triangle `t` at pixel `pixel`: the setup of
// cpu-backend visibility_raster::setup_triangle (outcodes, clipping, fan).
fn sample_reference(t: TriangleRecord, pixel: vec2<u32>) -> Sample {
    var miss: Sample;
    miss.covered = false;
    let c = array<vec4<f32>, 3>(clip_position_exact(t.v0), clip_position_exact(t.v1), clip_position_exact(t.v2));
    if !(is_finite4(c[0]) && is_finite4(c[1]) && is_finite4(c[2])) {
        return miss;
    }
    let guard = guard_band_ndc();
    var all = 0xffffffffu;
    var any = 0u;
    for (var k = 0u; k < 3u; k++) {
        var code = 0u;
        for (var plane = 0u; plane < CLIP_PLANE_COUNT; plane++) {
            if clip_plane_distance(plane, c[k], guard) < 0.0 {
                code |= 1u << plane;
            }
        }
        let x = c[k].x;
        let y = c[k].y;
        let w = c[k].w;
        code |= select(0u, 64u, x > w) | select(0u, 128u, x < -w) | select(0u, 256u, y > w) | select(0u, 512u, y < -w);
        all &= code;
        any |= code;
    }
    if all != 0u {
        return miss;
    }
    let corners = array<ClipVertex, 3>(
        ClipVertex(c[0], vec2<f32>(0.0, 0.0)),
        ClipVertex(c[1], vec2<f32>(1.0, 0.0)),
        ClipVertex(c[2], vec2<f32>(0.0, 1.0)),
    );
    let p = vec2<i32>(i32(pixel.x) * FIXED_ONE, i32(pixel.y) * FIXED_ONE);
    let outside = any & CLIP_OUTCODES;
    if outside == 0u {
        return sample_triangle(corners[0], corners[1], corners[2], true, p);
    }
    poly[0] = corners[0];
    poly[1] = corners[1];
    poly[2] = corners[2];
    var n = 3u;
    for (var plane = 0u; plane < CLIP_PLANE_COUNT; plane++) {
        if (outside & (1u << plane)) != 0u {
            n = clip_polygon_against_plane(plane, guard, n);
            poly = next_poly;
            if n < 3u {
                return miss;
            }
        }
    }
    // Fan from the first vertex; at most one sub-triangle covers a pixel centre (they
    // share snapped edges and the fill rule).
    for (var i = 1u; i + 1u < n; i++) {
        let s = sample_triangle(poly[0], poly[i], poly[i + 1u], false, p);
        if s.covered {
            return s;
        }
    }
    return miss;
}

struct FragmentOut {
    // Global triangle index + 1 (0 = no triangle: the clear value).
    @location(0) id: u32,
    // (u, v, window depth, 1 if front facing else 0).
    @location(1) surface: vec4<f32>,
    // The reference's depth: the depth test compares the reference's values.
    @builtin(frag_depth) depth: f32,
}

@fragment
fn fs_main(
    in: VertexOut,
    TRIANGLE_ID_PARAMETER
) -> FragmentOut {
    let id = TRIANGLE_ID_EXPRESSION;
    let s = sample_reference(triangles[id], vec2<u32>(in.clip.xy));
    if !s.covered {
        discard;
    }
    var out: FragmentOut;
    out.id = id + 1u;
    out.surface = vec4<f32>(s.bary, s.depth, select(1.0, 0.0, s.back_face));
    out.depth = s.depth;
    return out;
}

// ---------------------------------------------------------------- resolve pass

// Bindings 0 and 1 (`triangles`, `camera`) are shared with the raster pass.
@group(0) @binding(2) var id_target: texture_2d<u32>;
@group(0) @binding(3) var surface_target: texture_2d<f32>;
@group(0) @binding(4) var<storage, read_write> gbuffer: array<GBufferTexel>;

@compute @workgroup_size(8, 8, 1)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>) {
    let width = camera.width;
    let height = camera.height;
    if gid.x >= width || gid.y >= height {
        return;
    }
    let pixel = gid.y * width + gid.x;
    let id = textureLoad(id_target, vec2<u32>(gid.xy), 0).r;
    if id == 0u {
        gbuffer[pixel] = GBufferTexel(0.0, 0.0, 1.0, INVALID_ID, INVALID_ID, 0u);
        return;
    }
    let t = triangles[id - 1u];
    let s = textureLoad(surface_target, vec2<u32>(gid.xy), 0);
    var flags = GBUF_HIT;
    if (t.flags & TRI_RAY_TRACED) != 0u {
        flags |= GBUF_RAY_TRACED;
    }
    if s.w == 0.0 {
        flags |= GBUF_BACK_FACE;
    }
    gbuffer[pixel] = GBufferTexel(s.x, s.y, s.z, t.triangle, t.object, flags);
}
