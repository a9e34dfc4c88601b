// visibility_raster with the hardware's own interpolation (VisibilityMode::HardwareInterpolated):
// NOT conformant with the CPU reference, kept only so benchmarks can measure lavapipe as a
// production rasterizer drawing the same visibility pass its own way (the `hyrt bench` peer).
// The hardware raster pass with perspective-interpolated barycentrics and the hardware depth,
// and the compute resolve into `array<GBufferTexel>`. Rust side: gpu-backend/src/visibility_raster.rs.
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
    // Barycentric weights of (v0, v1, v2), perspective-correct.
    @location(0) bary: vec3<f32>,
    // Global triangle index (used only without primitive_index).
    @location(1) @interpolate(flat) triangle: u32,
}

fn is_finite4(p: vec4<f32>) -> bool {
    let e = bitcast<vec4<u32>>(p) & vec4<u32>(F32_EXPONENT_MASK);
    return all(e != vec4<u32>(F32_EXPONENT_MASK));
}

// mirrors hyrt_core::kernels::raster::clip_position (the driver may fuse).
fn clip_position(v: vec3<f32>) -> vec4<f32> {
    return camera.view_proj * vec4<f32>(v, 1.0);
}

@vertex
fn vs_main(@builtin(vertex_index) vertex_index: u32) -> VertexOut {
    let tri_index = vertex_index / 3u;
    let corner = vertex_index % 3u;
    let t = triangles[tri_index];
    // All three corners, so every vertex of a triangle makes the same decision.
    let c0 = clip_position(t.v0);
    let c1 = clip_position(t.v1);
    let c2 = clip_position(t.v2);
    var out: VertexOut;
    out.triangle = tri_index;
    if !(is_finite4(c0) && is_finite4(c1) && is_finite4(c2)) {
        out.clip = OUTSIDE_CLIP;
        out.bary = vec3<f32>(0.0);
        return out;
    }
    if corner == 0u {
        out.clip = c0;
        out.bary = vec3<f32>(1.0, 0.0, 0.0);
    } else if corner == 1u {
        out.clip = c1;
        out.bary = vec3<f32>(0.0, 1.0, 0.0);
    } else {
        out.clip = c2;
        out.bary = vec3<f32>(0.0, 0.0, 1.0);
    }
    return out;
}

struct FragmentOut {
    // Global triangle index + 1 (0 = no triangle: the clear value).
    @location(0) id: u32,
    // (u, v, window depth, 1 if front facing else 0).
    @location(1) surface: vec4<f32>,
}

@fragment
fn fs_main(
    in: VertexOut,
    @builtin(front_facing) front: bool,
    TRIANGLE_ID_PARAMETER
) -> FragmentOut {
    var out: FragmentOut;
    out.id = TRIANGLE_ID_EXPRESSION + 1u;
    out.surface = vec4<f32>(in.bary.y, in.bary.z, in.clip.z, select(0.0, 1.0, front));
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
