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

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    // Barycentric weights of (v0, v1, v2), perspective-correct.
    @location(0) bary: vec3<f32>,
    // Global triangle index (used only without primitive_index).
    @location(1) @interpolate(flat) triangle: u32,
}


// mirrors hyrt_core::kernels::raster::clip_position_from_eye (the driver may fuse), then
// maps the band's rows (gpu-backend/src/band.rs) onto the render targets: clip y scaled
// by image height / band rows and shifted (for a frame of one band, by 1 and 0: the
// image's clip position).
fn clip_position(v: vec3<f32>) -> vec4<f32> {
    let c = camera.view_proj * vec4<f32>(v - camera.eye, 1.0);
    let rows = f32(params.height);
    let scale = div_rn(f32(camera.height), rows);
    let shift = 1.0 - div_rn(f32(camera.height) - 2.0 * f32(params.first_row), rows);
    return vec4<f32>(c.x, c.y * scale + c.w * shift, c.z, c.w);
}

@vertex
fn vs_main(@builtin(vertex_index) vertex_index: u32) -> VertexOut {
    let tri_index = vertex_index / 3u;
    let corner = vertex_index % 3u;
    let t = world_triangle(tri_index);
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
