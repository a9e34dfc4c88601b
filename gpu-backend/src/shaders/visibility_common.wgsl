// visibility_raster, shared by both modes (gpu-backend/src/visibility_raster.rs puts it
// in front of visibility_raster.wgsl or visibility_raster_interpolated.wgsl, after the
// generated records and format constants of hyrt_core::formats::wgsl): the bindings of
// the scene and the camera, and the compute resolve of the render targets into
// `array<GBufferTexel>`.

// A clip position outside the view volume (x > w): a triangle with a non-finite
// vertex gets it at all three corners and is clipped away entirely.
const OUTSIDE_CLIP: vec4<f32> = vec4<f32>(2.0, 2.0, 0.5, 1.0);

// ---------------------------------------------------------------- raster pass

@group(0) @binding(0) var<storage, read> triangles: array<TriangleRecord>;
@group(0) @binding(1) var<uniform> camera: CameraRecord;
// The band being rendered (gpu-backend/src/band.rs): `width` x `height` pixels from
// image row `first_row`, the render targets' rows and the G-buffer's.
@group(0) @binding(10) var<uniform> params: FrameParams;

fn is_finite4(p: vec4<f32>) -> bool {
    let e = bitcast<vec4<u32>>(p) & vec4<u32>(F32_EXP_MASK);
    return all(e != vec4<u32>(F32_EXP_MASK));
}

// ---------------------------------------------------------------- resolve pass

// Bindings 0 and 10 (`triangles`, `params`) are shared with the raster pass.
@group(0) @binding(2) var id_target: texture_2d<u32>;
@group(0) @binding(3) var surface_target: texture_2d<f32>;
@group(0) @binding(4) var<storage, read_write> gbuffer: array<GBufferTexel>;

@compute @workgroup_size(8, 8, 1)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>) {
    let width = params.width;
    let height = params.height;
    if gid.x >= width || gid.y >= height {
        return;
    }
    let pixel = gid.y * width + gid.x;
    let id = textureLoad(id_target, vec2<u32>(gid.xy), 0).r;
    if id == 0u {
        gbuffer[pixel] = GBufferTexel(0.0, 0.0, 1.0, INVALID_ID, INVALID_ID, 0u);
        return;
    }
    let t = world_triangle(id - 1u);
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
