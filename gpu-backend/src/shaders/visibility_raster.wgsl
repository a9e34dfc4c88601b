// visibility_raster (paper 3.2): the hardware raster pass and the compute resolve
// into `array<GBufferTexel>`. Rust side: gpu-backend/src/visibility_raster.rs.
//
// The constants of hyrt_core::kernels::raster (MAX_IMAGE_DIM, GUARD_BAND_PIXELS,
// MAX_CLIP_VERTICES, PIXEL_CENTER_OFFSET, FIXED_ONE, FIXED_ONE_F32,
// MAX_FIXED_COORD_F32) are prepended by `shader_source` from the Rust values, and the
// texture kernels (`hyrt_gpu::texture::texture_wgsl`, over this file's `rounded` and
// `mul`) are appended, for the alpha test.
//
// `TRIANGLE_ID_SOURCE` is replaced at pipeline creation (see `shader_source`):
// with `@builtin(primitive_index)` the file is prefixed with `enable primitive_index;`
// and the fragment shader reads the id from the builtin; otherwise the vertex shader
// passes its triangle as a flat-interpolated output (every vertex belongs to exactly one
// triangle: the draw is non-indexed over unshared vertices). Either way the id is the
// triangle's within its batch's draw (`RasterBatch`), to which the batch's first
// triangle is added.

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    // Triangle index within the batch's draw (used only without primitive_index).
    @location(0) @interpolate(flat) triangle: u32,
}


// ---------------------------------------------------------------- setup records
//
// The setup pass (`setup`, one thread per triangle) runs the reference's setup of each
// triangle once per frame and records what the vertex and fragment shaders need.

// `RasterSetup::x.w` flags.
const SETUP_MODE_MASK: u32 = 3u;
// Nothing to draw (non-finite, beyond one plane, zero area, no pixel centre).
const SETUP_NONE: u32 = 0u;
// Drawn unclipped by the reference: x, y, z, w hold its normalized setup.
const SETUP_UNCLIPPED: u32 = 1u;
// Clipped by the reference: `x.x` is the first of `x.y` sub-triangle setups in
// `clipped`, in fan order.
const SETUP_CLIPPED: u32 = 2u;
// Clipped, but `clipped` was full: the fragment shader runs the whole setup itself
// (the same operations, so the same result, only slower).
const SETUP_CLIPPED_IN_FRAGMENT: u32 = 3u;
// The normalized triangle was a back face (v1 and v2 swapped).
const SETUP_BACK: u32 = 4u;
// Corners handed to the hardware pre-snapped (else a cover triangle over `box_`).
const SETUP_PRESNAP: u32 = 8u;
// Vertex and pixel-box spans below SMALL_SPAN_FIXED: edge functions fit in i32.
const SETUP_SMALL: u32 = 16u;
// Largest span (fixed units) for i32 edge functions: products of two differences below
// 2^15 stay below 2^30 and their difference below 2^31.
const SMALL_SPAN_FIXED: i32 = 32768;

struct RasterSetup {
    // Unclipped: snapped x of the normalized vertices (v0, va, vb); w: flags.
    x: vec4<i32>,
    // Unclipped: snapped y of the normalized vertices; w: 0.
    y: vec4<i32>,
    // Unclipped: window z/w of the normalized vertices; w: the doubled area as f32.
    z: vec4<f32>,
    // Unclipped: clip w of the normalized vertices; w: 0.
    w: vec4<f32>,
    // The pixels whose centres the reference can cover, [x0, x1) x [y0, y1), in the image.
    box_: vec4<i32>,
}

// One sub-triangle of a clipped triangle's fan (a TriSetup).
struct ClippedSetup {
    // Snapped x of the normalized vertices; w: 1 if valid (set up), else 0.
    x: vec4<i32>,
    y: vec4<i32>,
    // z/w of the normalized vertices; w: the doubled area as f32.
    z: vec4<f32>,
    // Clip w of the normalized vertices; w: 1 if a back face, else 0.
    w: vec4<f32>,
    // Barycentrics in the original triangle of the normalized vertices 0 and 1 ...
    b01: vec4<f32>,
    // ... and 2.
    b2: vec4<f32>,
}

// The batch of triangles being set up and drawn (gpu-backend/src/visibility_raster.rs
// `RasterBatch`): global triangles [first, first + count). `setups`, `setups_out` and
// the clipped setups hold that batch's records, indexed from 0 (the batch's first
// triangle); a scene whose setup records fit one binding is one batch.
struct RasterBatch {
    first: u32,
    count: u32,
    pad0: u32,
    pad1: u32,
}
@group(0) @binding(15) var<uniform> batch: RasterBatch;

@group(0) @binding(5) var<storage, read> setups: array<RasterSetup>;
@group(0) @binding(6) var<storage, read_write> setups_out: array<RasterSetup>;
@group(0) @binding(7) var<storage, read> clipped: array<ClippedSetup>;
@group(0) @binding(8) var<storage, read_write> clipped_out: array<ClippedSetup>;
// Sub-triangle slots of `clipped_out` handed out so far this frame (cleared before the pass).
@group(0) @binding(9) var<storage, read_write> clipped_count: atomic<u32>;
// The surface tables (texture.wgsl's accessors): the fragment shader alpha-tests the
// fragments of triangles flagged TRI_ALPHA_TEST.
@group(0) @binding(11) var<storage, read> surface: array<u32>;
@group(0) @binding(12) var<uniform> surface_layout: SurfaceLayout;
// The objects whose triangles that show their interior the setup drops this frame, one
// bit each (hyrt_core::geometry::WorldGeometry::interior_culls; setup pass only).
@group(0) @binding(16) var<storage, read> interior_culls: array<u32>;

// mirrors hyrt_core::kernels::raster::culls_interior
fn culls_interior(object: u32) -> bool {
    let word = object / 32u;
    return word < arrayLength(&interior_culls) && ((interior_culls[word] >> (object % 32u)) & 1u) != 0u;
}

// Largest window coordinate (pixels) for which a vertex is handed to the hardware
// pre-snapped: its NDC position is rebuilt from the reference's fixed-point position,
// and the hardware's viewport transform (about 3 roundings of a value below 2^11, each
// at most 2^-13 px) lands within 1/512 px of it, so the hardware's own snapping gives
// back the same fixed-point value even where the float value sat on a rounding tie.
const PRESNAP_LIMIT_PX: i32 = 2048;

// How far a cover triangle's edges lie outside the reference triangle's (pixels): more
// than the hardware's own rounding when it clips a triangle to the viewport (a few ulps
// of coordinates up to the guard band, 2^20 px: below 2^-3 px), so the hardware covers
// every pixel centre the reference does; the fragment shader discards the rest.
const COVER_MARGIN_PX: f32 = 1.0;

// How far below the reference's depth the hardware's interpolated depth is kept, so that
// the depth the fragment shader writes is never less than it (the promise of
// `@early_depth_test(greater_equal)`, which lets the device reject hidden fragments
// before shading them): both interpolate the same vertex depths in [0, 1], the
// reference within 8 * 2^-24 (DEPTH_INTERPOLATION_REL_ERROR), the hardware within a few
// ulps of 1; 2^-16 covers both many times over. Cover triangles use depth 0.
const CONSERVATIVE_DEPTH_MARGIN: f32 = 1.0 / 65536.0;

// The NDC position (w = 1) whose window position in the band's render targets is `win`
// (pixels; the band's first row is row 0 of the targets: see band_window).
fn window_to_ndc(win: vec2<f32>, depth: f32) -> vec4<f32> {
    return vec4<f32>(div_rn(win.x, f32(params.width)) * 2.0 - 1.0, 1.0 - div_rn(win.y, f32(params.height)) * 2.0, depth,
        1.0);
}

// The band's window position of image window position `win` (pixels). Exact for a frame
// of one band (first_row 0); in a banded frame only cover triangles take this path,
// whose margin is far above the rounding of a subtraction (2^-3 px at 2^20 px).
fn band_window(win: vec2<f32>) -> vec2<f32> {
    return win - vec2<f32>(0.0, f32(params.first_row));
}

// True if every corner of the unclipped triangle lies within the band's rows and the
// pre-snap limit (rows [first_row, first_row + min(rows, PRESNAP_LIMIT_PX)) in the
// pixel-centre frame); the setup checked the columns (SETUP_PRESNAP). For a frame of
// one band, the setup's test of the whole image.
fn presnap_in_band(s: RasterSetup) -> bool {
    let lo = min(min(s.y.x, s.y.y), s.y.z);
    let hi = max(max(s.y.x, s.y.y), s.y.z);
    let top = i32(params.first_row) * FIXED_ONE;
    let rows = min(i32(params.height), PRESNAP_LIMIT_PX) * FIXED_ONE;
    return lo >= top - FIXED_ONE / 2 && hi <= top + rows - FIXED_ONE / 2;
}

// pixel_span of fixed-point bounds [lo, hi] per axis, within the image, as pixel edges
// [x0, y0, x1, y1) (mirrors hyrt_core::kernels::raster::pixel_span).
fn pixel_box(lo: vec2<i32>, hi: vec2<i32>) -> vec4<i32> {
    let first = max((lo + vec2<i32>(FIXED_ONE - 1)) >> vec2<u32>(8u), vec2<i32>(0));
    let last = min((hi - vec2<i32>(1)) >> vec2<u32>(8u), vec2<i32>(i32(camera.width) - 1, i32(camera.height) - 1));
    return vec4<i32>(first, last + vec2<i32>(1));
}

@compute @workgroup_size(64, 1, 1)
fn setup(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let index = gid.x + gid.y * groups.x * 64u;
    if index >= batch.count {
        return;
    }
    var out: RasterSetup;
    out.x = vec4<i32>(0, 0, 0, i32(SETUP_NONE));
    let t = world_triangle(batch.first + index);
    let c = array<vec4<f32>, 3>(clip_position_exact(t.v0), clip_position_exact(t.v1), clip_position_exact(t.v2));
    let outcodes = reference_outcodes(c);
    if !(is_finite4(c[0]) && is_finite4(c[1]) && is_finite4(c[2])) || outcodes.x != 0u {
        setups_out[index] = out;
        return;
    }
    let outside = outcodes.y & CLIP_OUTCODES;
    if outside == 0u {
        let ts = setup_triangle(ClipVertex(c[0], vec2<f32>(0.0, 0.0)), ClipVertex(c[1], vec2<f32>(1.0, 0.0)),
            ClipVertex(c[2], vec2<f32>(0.0, 1.0)));
        if !ts.valid {
            setups_out[index] = out;
            return;
        }
        let lo = vec2<i32>(min(min(ts.xs.x, ts.xs.y), ts.xs.z), min(min(ts.ys.x, ts.ys.y), ts.ys.z));
        let hi = vec2<i32>(max(max(ts.xs.x, ts.xs.y), ts.xs.z), max(max(ts.ys.x, ts.ys.y), ts.ys.z));
        out.box_ = pixel_box(lo, hi);
        // The inside of a closed object no pixel can see (cpu-backend visibility_raster
        // `finish_triangle`; clipped triangles are kept, there as here).
        let interior = shows_interior(ts.back, (t.flags & TRI_INWARD) != 0u);
        if any(out.box_.zw <= out.box_.xy) || (interior && culls_interior(t.object)) {
            setups_out[index] = out;
            return;
        }
        var flags = SETUP_UNCLIPPED | select(0u, SETUP_BACK, ts.back);
        // Every corner inside the viewport's columns (window [0, size], here in the
        // pixel-centre frame) and within the pre-snap limit; the rows are the band's
        // (presnap_in_band, in the vertex shader).
        let size = min(i32(camera.width), PRESNAP_LIMIT_PX) * FIXED_ONE;
        let half = FIXED_ONE / 2;
        if lo.x >= -half && hi.x <= size - half {
            flags |= SETUP_PRESNAP;
        }
        if all(hi - lo < vec2<i32>(SMALL_SPAN_FIXED)) {
            flags |= SETUP_SMALL;
        }
        out.x = vec4<i32>(ts.xs, i32(flags));
        out.y = vec4<i32>(ts.ys, 0);
        out.z = vec4<f32>(ts.z, edge_value_to_f32(ts.area2));
        out.w = vec4<f32>(ts.w, 0.0);
        setups_out[index] = out;
        return;
    }
    // Clipped: the fixed-point box of the clipped polygon (a superset of every
    // sub-triangle's pixels) for the cover triangle.
    let n = clip_reference_polygon(c, outside);
    var lo = vec2<i32>(i32(MAX_FIXED_COORD_F32));
    var hi = vec2<i32>(-i32(MAX_FIXED_COORD_F32));
    for (var i = 0u; i < n; i++) {
        let q = clip_to_window(poly[i].pos);
        if is_finite4(vec4<f32>(q, 1.0)) && poly[i].pos.w > 0.0 {
            let f = vec2<f32>(snap_to_fixed(q.x), snap_to_fixed(q.y));
            if all(abs(f) <= vec2<f32>(MAX_FIXED_COORD_F32)) {
                lo = min(lo, vec2<i32>(f));
                hi = max(hi, vec2<i32>(f));
            }
        }
    }
    out.box_ = pixel_box(lo, hi);
    if n < 3u || any(out.box_.zw <= out.box_.xy) {
        setups_out[index] = out;
        return;
    }
    // The fan's sub-triangles, set up once here (cpu-backend visibility_raster
    // `setup_triangle`: a fan from the first vertex).
    let count = n - 2u;
    let first = atomicAdd(&clipped_count, count);
    if first + count > arrayLength(&clipped_out) {
        out.x.w = i32(SETUP_CLIPPED_IN_FRAGMENT);
        setups_out[index] = out;
        return;
    }
    for (var i = 0u; i < count; i++) {
        let ts = setup_triangle(poly[0], poly[i + 1u], poly[i + 2u]);
        var cs: ClippedSetup;
        if ts.valid {
            cs.x = vec4<i32>(ts.xs, 1);
            cs.y = vec4<i32>(ts.ys, 0);
            cs.z = vec4<f32>(ts.z, edge_value_to_f32(ts.area2));
            cs.w = vec4<f32>(ts.w, select(0.0, 1.0, ts.back));
            cs.b01 = vec4<f32>(ts.b0, ts.b1);
            cs.b2 = vec4<f32>(ts.b2, 0.0, 0.0);
        }
        clipped_out[first + i] = cs;
    }
    out.x = vec4<i32>(i32(first), i32(count), 0, i32(SETUP_CLIPPED));
    setups_out[index] = out;
}

// HARDWARE_TRIANGLES_PER_TRIANGLE (prepended): a clipped triangle's fan is drawn as up to this
// many grown sub-triangles (near-plane clipping makes a quad: two), in the scene's
// order, so the depth test sees fragments in the reference's order. Larger fans, and
// slivers, get one cover triangle over their pixel box.

// The distance between two points of the cover geometry (a conservative outline that
// the fragment shader's exact coverage test trims, so its rounding is free).
fn distance_rn(a: vec2<f32>, b: vec2<f32>) -> f32 {
    let d = a - b;
    return sqrt_rn(d.x * d.x + d.y * d.y);
}

// Corner `k` of the triangle (xs, ys) (snapped, normalized) grown by COVER_MARGIN_PX
// about its incentre, which moves every edge out by exactly the margin; w = 0 when the
// triangle is a sliver (inradius below the margin) and must be covered otherwise.
fn grown_corner(xs: vec3<i32>, ys: vec3<i32>, area2: f32, k: u32) -> vec4<f32> {
    let v = array<vec2<f32>, 3>(vec2<f32>(f32(xs.x), f32(ys.x)), vec2<f32>(f32(xs.y), f32(ys.y)),
        vec2<f32>(f32(xs.z), f32(ys.z)));
    // FIXED_ONE_F32 is a power of two: multiplying by its inverse is dividing by it.
    let side = vec3<f32>(distance_rn(v[1], v[2]), distance_rn(v[2], v[0]), distance_rn(v[0], v[1])) * INV_FIXED_ONE_F32;
    let perimeter = side.x + side.y + side.z;
    let inradius = div_rn(area2 * (INV_FIXED_ONE_F32 * INV_FIXED_ONE_F32), perimeter);
    if !(inradius >= COVER_MARGIN_PX) {
        return vec4<f32>(0.0);
    }
    let weighted = side.x * v[0] + side.y * v[1] + side.z * v[2];
    let centre = vec2<f32>(div_rn(weighted.x, perimeter), div_rn(weighted.y, perimeter)) * INV_FIXED_ONE_F32;
    let grown = centre + (v[k] * INV_FIXED_ONE_F32 - centre) * div_rn(inradius + COVER_MARGIN_PX, inradius);
    return window_to_ndc(band_window(grown + vec2<f32>(PIXEL_CENTER_OFFSET)), 0.0);
}

// Corner `k` of a cover triangle over the pixel box: a right triangle whose legs are
// twice the box plus a pixel of margin, so its hypotenuse passes outside the box's far
// corner.
fn box_corner(box_: vec4<i32>, k: u32) -> vec4<f32> {
    let a = vec2<f32>(box_.xy) - 1.0;
    let b = vec2<f32>(box_.zw) + 1.0;
    let cover = array<vec2<f32>, 3>(a, vec2<f32>(a.x + 2.0 * (b.x - a.x), a.y), vec2<f32>(a.x, a.y + 2.0 * (b.y - a.y)));
    return window_to_ndc(band_window(cover[k]), 0.0);
}

// The clip position of corner `k` of hardware triangle `sub` of scene triangle `s`.
fn hardware_corner(s: RasterSetup, sub: u32, k: u32) -> vec4<f32> {
    let mode = u32(s.x.w) & SETUP_MODE_MASK;
    if mode == SETUP_NONE {
        return OUTSIDE_CLIP;
    }
    // Not a pixel in the band's rows: nothing to draw in this band.
    if s.box_.w <= i32(params.first_row) || s.box_.y >= i32(params.first_row + params.height) {
        return OUTSIDE_CLIP;
    }
    if mode == SETUP_UNCLIPPED {
        if sub != 0u {
            return OUTSIDE_CLIP;
        }
        if (u32(s.x.w) & SETUP_PRESNAP) != 0u && presnap_in_band(s) {
            // Back to the band's window coordinates: exact (integers below 2^20, then a
            // power of two).
            let fixed = vec2<f32>(f32(s.x[k]), f32(s.y[k] - i32(params.first_row) * FIXED_ONE));
            return window_to_ndc((fixed + vec2<f32>(PIXEL_CENTER_OFFSET * FIXED_ONE_F32)) * INV_FIXED_ONE_F32,
                max(s.z[k] - CONSERVATIVE_DEPTH_MARGIN, 0.0));
        }
        let g = grown_corner(s.x.xyz, s.y.xyz, s.z.w, k);
        return select(g, box_corner(s.box_, k), g.w == 0.0);
    }
    if mode == SETUP_CLIPPED && u32(s.x.y) <= HARDWARE_TRIANGLES_PER_TRIANGLE {
        if sub >= u32(s.x.y) {
            return OUTSIDE_CLIP;
        }
        let cs = clipped[u32(s.x.x) + sub];
        if cs.x.w == 0 {
            return OUTSIDE_CLIP;
        }
        let g = grown_corner(cs.x.xyz, cs.y.xyz, cs.z.w, k);
        return select(g, box_corner(s.box_, k), g.w == 0.0);
    }
    // A large fan, or set up per fragment: one cover triangle.
    return select(OUTSIDE_CLIP, box_corner(s.box_, k), sub == 0u);
}

@vertex
fn vs_main(@builtin(vertex_index) vertex_index: u32) -> VertexOut {
    let per_triangle = 3u * HARDWARE_TRIANGLES_PER_TRIANGLE;
    // The draw is the batch's: its triangles from 0.
    let tri_index = vertex_index / per_triangle;
    let sub = (vertex_index % per_triangle) / 3u;
    var out: VertexOut;
    out.triangle = tri_index;
    out.clip = hardware_corner(setups[tri_index], sub, vertex_index % 3u);
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

// mirrors hyrt_core::kernels::raster::clip_position_from_eye: `v - eye`, then the
// eye-relative matrix in glam's order, no fused multiply-add
fn clip_position_exact(world: vec3<f32>) -> vec4<f32> {
    let m = camera.view_proj;
    let v = world - camera.eye;
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
    return vec2<f32>(div_rn(2.0 * GUARD_BAND_PIXELS, w), div_rn(2.0 * GUARD_BAND_PIXELS, h));
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
    let t = div_rn(d_out, d_out - d_in);
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
    let ndc_x = div_rn(p.x, p.w);
    let ndc_y = div_rn(p.y, p.w);
    let ndc_z = div_rn(p.z, p.w);
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
fn perspective_barycentrics(e: vec3<f32>, w: vec3<f32>) -> vec3<f32> {
    let q0 = div_rn(e.x, w.x);
    let q1 = div_rn(e.y, w.y);
    let q2 = div_rn(e.z, w.z);
    let s = rounded(q0 + q1) + q2;
    return vec3<f32>(div_rn(q0, s), div_rn(q1, s), div_rn(q2, s));
}

// mirrors hyrt_core::kernels::raster::shows_interior
fn shows_interior(back_face: bool, inward: bool) -> bool {
    return back_face != inward;
}

// mirrors hyrt_core::kernels::raster::depth_test_value (bits: exact on any device)
fn depth_test_value(depth: f32, interior: bool) -> f32 {
    if interior && depth >= 0.0 {
        return min(bitcast<f32>(bitcast<u32>(abs(depth)) + INTERIOR_DEPTH_BIAS_ULPS), 1.0);
    }
    return depth;
}

// mirrors hyrt_core::kernels::raster::interpolate_depth
fn interpolate_depth(e: vec3<f32>, area2: f32, z: vec3<f32>) -> f32 {
    let num = rounded(rounded(mul(e.x, z.x) + mul(e.y, z.y)) + mul(e.z, z.z));
    return div_rn(num, area2);
}

// mirrors hyrt_core::kernels::raster::barycentrics_in_original
fn barycentrics_in_original(b: vec3<f32>, a0: vec2<f32>, a1: vec2<f32>, a2: vec2<f32>) -> vec2<f32> {
    var out: vec2<f32>;
    for (var k = 0u; k < 2u; k++) {
        out[k] = rounded(rounded(mul(b.x, a0[k]) + mul(b.y, a1[k])) + mul(b.z, a2[k]));
    }
    return out;
}

// One (sub-)triangle set up by the reference's rules (cpu-backend visibility_raster
// `emit_triangle`, without the pixel box): snapped, normalized counter-clockwise.
struct TriSetup {
    valid: bool,
    back: bool,
    xs: vec3<i32>,
    ys: vec3<i32>,
    z: vec3<f32>,
    w: vec3<f32>,
    // Barycentrics in the original triangle of the normalized vertices.
    b0: vec2<f32>,
    b1: vec2<f32>,
    b2: vec2<f32>,
    // The doubled area (> 0).
    area2: vec2<u32>,
}

// mirrors cpu-backend visibility_raster::emit_triangle (project, snap, cull, normalize)
fn setup_triangle(v0: ClipVertex, v1: ClipVertex, v2: ClipVertex) -> TriSetup {
    var out: TriSetup;
    out.valid = false;
    let vs = array<ClipVertex, 3>(v0, v1, v2);
    var win: array<vec3<f32>, 3>;
    var fixed: array<vec2<i32>, 3>;
    for (var k = 0u; k < 3u; k++) {
        let q = clip_to_window(vs[k].pos);
        if !(is_finite4(vec4<f32>(q, 1.0)) && vs[k].pos.w > 0.0) {
            return out;
        }
        let fx = snap_to_fixed(q.x);
        let fy = snap_to_fixed(q.y);
        if abs(fx) > MAX_FIXED_COORD_F32 || abs(fy) > MAX_FIXED_COORD_F32 {
            return out;
        }
        fixed[k] = vec2<i32>(i32(fx), i32(fy));
        win[k] = q;
    }
    let area = edge_function(fixed[0], fixed[1], fixed[2]);
    if area.x == 0u && area.y == 0u {
        return out;
    }
    out.valid = true;
    out.back = is_negative64(area);
    let a = select(1u, 2u, out.back);
    let b = select(2u, 1u, out.back);
    out.xs = vec3<i32>(fixed[0].x, fixed[a].x, fixed[b].x);
    out.ys = vec3<i32>(fixed[0].y, fixed[a].y, fixed[b].y);
    out.z = vec3<f32>(win[0].z, win[a].z, win[b].z);
    out.w = vec3<f32>(vs[0].pos.w, vs[a].pos.w, vs[b].pos.w);
    out.b0 = vs[0].bary;
    out.b1 = vs[a].bary;
    out.b2 = vs[b].bary;
    out.area2 = select(area, neg64(area), out.back);
    return out;
}

// The edge values at a pixel centre, and whether the fill rule covers it. (Written out
// per edge, without arrays: lavapipe runs 8 fragments in SIMD lanes, and a private array
// indexed per lane becomes memory traffic.)
struct Edges {
    covered: bool,
    e: vec3<f32>,
}

// One exact edge value with its fill-rule bias applied: (value, biased).
fn edge_and_biased(a: vec2<i32>, b: vec2<i32>, p: vec2<i32>) -> array<vec2<u32>, 2> {
    let e = edge_function(a, b, p);
    return array<vec2<u32>, 2>(e, add64(e, edge_bias(a, b)));
}

// Edge `i` runs from vertex i + 1 to vertex i + 2 (opposite vertex i), as the CPU's
// EdgeStepper; exact 64-bit values.
fn edges_at(xs: vec3<i32>, ys: vec3<i32>, p: vec2<i32>) -> Edges {
    let v0 = vec2<i32>(xs.x, ys.x);
    let v1 = vec2<i32>(xs.y, ys.y);
    let v2 = vec2<i32>(xs.z, ys.z);
    let e0 = edge_and_biased(v1, v2, p);
    let e1 = edge_and_biased(v2, v0, p);
    let e2 = edge_and_biased(v0, v1, p);
    var out: Edges;
    out.covered = !(is_negative64(e0[1]) || is_negative64(e1[1]) || is_negative64(e2[1]));
    if out.covered {
        out.e = vec3<f32>(edge_value_to_f32(e0[0]), edge_value_to_f32(e1[0]), edge_value_to_f32(e2[0]));
    }
    return out;
}

// mirrors hyrt_core::kernels::raster::edge_function in i32: exact when every coordinate
// difference is below SMALL_SPAN_FIXED.
fn edge_function_small(a: vec2<i32>, b: vec2<i32>, p: vec2<i32>) -> i32 {
    return (b.y - a.y) * (p.x - a.x) - (b.x - a.x) * (p.y - a.y);
}

// mirrors hyrt_core::kernels::raster::edge_bias in i32
fn edge_bias_small(a: vec2<i32>, b: vec2<i32>) -> i32 {
    let dcdx = a.y - b.y;
    let dcdy = a.x - b.x;
    return select(-1, 0, dcdx < 0 || (dcdx == 0 && dcdy > 0));
}

// `edges_at` in i32, valid when every coordinate difference is below SMALL_SPAN_FIXED
// (SETUP_SMALL, pixel centre inside the pixel box): the same exact values.
fn edges_at_small(xs: vec3<i32>, ys: vec3<i32>, p: vec2<i32>) -> Edges {
    let v0 = vec2<i32>(xs.x, ys.x);
    let v1 = vec2<i32>(xs.y, ys.y);
    let v2 = vec2<i32>(xs.z, ys.z);
    let e = vec3<i32>(edge_function_small(v1, v2, p), edge_function_small(v2, v0, p), edge_function_small(v0, v1, p));
    let bias = vec3<i32>(edge_bias_small(v1, v2), edge_bias_small(v2, v0), edge_bias_small(v0, v1));
    var out: Edges;
    out.covered = all(e + bias >= vec3<i32>(0));
    out.e = vec3<f32>(e);
    return out;
}

// What the reference gives a covered pixel centre.
struct Sample {
    covered: bool,
    bary: vec2<f32>,
    depth: f32,
    back_face: bool,
}

// The per-pixel values of the reference (cpu-backend visibility_raster: the depth test's
// `interpolate_depth`, the tile resolve's barycentrics) from covered edge values.
fn sample_from(edges: Edges, back: bool, unclipped: bool, z: vec3<f32>, w: vec3<f32>, area2: f32,
    b0: vec2<f32>, b1: vec2<f32>, b2: vec2<f32>) -> Sample {
    var out: Sample;
    out.covered = true;
    out.back_face = back;
    out.depth = interpolate_depth(edges.e, area2, z);
    let bw = perspective_barycentrics(edges.e, w);
    if unclipped {
        // perspective_barycentrics_of_corners: the weights of the original v1 and v2
        // among the normalized vertices (v0, va, vb).
        out.bary = select(vec2<f32>(bw.y, bw.z), vec2<f32>(bw.z, bw.y), back);
    } else {
        out.bary = barycentrics_in_original(bw, b0, b1, b2);
    }
    return out;
}

// The reference's outcodes of a triangle's clip positions: x = the codes all three
// share (non-zero: nothing to draw), y = the codes any has (cpu-backend visibility_raster
// `setup_triangle`).
fn reference_outcodes(c: array<vec4<f32>, 3>) -> vec2<u32> {
    let guard = guard_band_ndc();
    var all_codes = 0xffffffffu;
    var any_codes = 0u;
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
        all_codes &= code;
        any_codes |= code;
    }
    return vec2<u32>(all_codes, any_codes);
}

// Clip the triangle against the planes in `outside` into `poly`; returns the vertex
// count (cpu-backend visibility_raster `setup_triangle`).
fn clip_reference_polygon(c: array<vec4<f32>, 3>, outside: u32) -> u32 {
    let guard = guard_band_ndc();
    poly[0] = ClipVertex(c[0], vec2<f32>(0.0, 0.0));
    poly[1] = ClipVertex(c[1], vec2<f32>(1.0, 0.0));
    poly[2] = ClipVertex(c[2], vec2<f32>(0.0, 1.0));
    var n = 3u;
    for (var plane = 0u; plane < CLIP_PLANE_COUNT; plane++) {
        if (outside & (1u << plane)) != 0u {
            n = clip_polygon_against_plane(plane, guard, n);
            poly = next_poly;
            if n < 3u {
                return n;
            }
        }
    }
    return n;
}

// The reference at pixel centre `p` for a triangle it clips: the fan of the clipped
// polygon; at most one sub-triangle covers a pixel centre (they share snapped edges and
// the fill rule).
fn sample_clipped(t: TriangleRecord, p: vec2<i32>) -> Sample {
    var miss: Sample;
    miss.covered = false;
    let c = array<vec4<f32>, 3>(clip_position_exact(t.v0), clip_position_exact(t.v1), clip_position_exact(t.v2));
    let n = clip_reference_polygon(c, reference_outcodes(c).y & CLIP_OUTCODES);
    for (var i = 1u; i + 1u < n; i++) {
        let ts = setup_triangle(poly[0], poly[i], poly[i + 1u]);
        if ts.valid {
            let edges = edges_at(ts.xs, ts.ys, p);
            if edges.covered {
                return sample_from(edges, ts.back, false, ts.z, ts.w, edge_value_to_f32(ts.area2), ts.b0, ts.b1, ts.b2);
            }
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

@fragment EARLY_DEPTH_TEST_ATTRIBUTE
fn fs_main(
    in: VertexOut,
    TRIANGLE_ID_PARAMETER
) -> FragmentOut {
    // The triangle within the batch's draw, and its global index.
    let local = TRIANGLE_ID_EXPRESSION;
    let id = batch.first + local;
    // The image pixel: the band's window position plus its first row.
    let pixel = vec2<i32>(in.clip.xy) + vec2<i32>(0, i32(params.first_row));
    let s = setups[local];
    let flags = u32(s.x.w);
    if any(pixel < s.box_.xy) || any(pixel >= s.box_.zw) {
        discard;
    }
    let p = pixel * FIXED_ONE;
    var sample: Sample;
    if (flags & SETUP_MODE_MASK) == SETUP_UNCLIPPED {
        var edges: Edges;
        if (flags & SETUP_SMALL) != 0u {
            edges = edges_at_small(s.x.xyz, s.y.xyz, p);
        } else {
            edges = edges_at(s.x.xyz, s.y.xyz, p);
        }
        if !edges.covered {
            discard;
        }
        let zero = vec2<f32>(0.0);
        sample = sample_from(edges, (flags & SETUP_BACK) != 0u, true, s.z.xyz, s.w.xyz, s.z.w, zero, zero, zero);
    } else if (flags & SETUP_MODE_MASK) == SETUP_CLIPPED {
        sample.covered = false;
        for (var i = 0; i < s.x.y; i++) {
            let cs = clipped[s.x.x + i];
            if cs.x.w != 0 {
                let edges = edges_at(cs.x.xyz, cs.y.xyz, p);
                if edges.covered {
                    sample = sample_from(edges, cs.w.w != 0.0, false, cs.z.xyz, cs.w.xyz, cs.z.w, cs.b01.xy, cs.b01.zw,
                        cs.b2.xy);
                    break;
                }
            }
        }
        if !sample.covered {
            discard;
        }
    } else {
        sample = sample_clipped(world_triangle(id), p);
        if !sample.covered {
            discard;
        }
    }
    let t = world_triangle(id);
    // A masked fragment (hyrt_cpu visibility_raster's `AlphaTested` sink): where the
    // alpha test fails at the barycentrics this fragment's texel would get, there is no
    // surface, and the fragment is dropped before the depth test. ALPHA_TESTED is a
    // pipeline constant: no alpha test is compiled for scenes without one.
    if ALPHA_TESTED && (t.flags & TRI_ALPHA_TEST) != 0u && !alpha_accepts(t, id, sample.bary.x, sample.bary.y) {
        discard;
    }
    var out: FragmentOut;
    out.id = id + 1u;
    out.surface = vec4<f32>(sample.bary, sample.depth, select(1.0, 0.0, sample.back_face));
    // The depth test compares depth_test_value: interior sides lose near-ties (the
    // G-buffer keeps the unbiased depth, from `surface`). Never below the reference's
    // depth, so the early depth test's promise (greater_equal) holds.
    let inward = (t.flags & TRI_INWARD) != 0u;
    out.depth = depth_test_value(sample.depth, shows_interior(sample.back_face, inward));
    return out;
}
