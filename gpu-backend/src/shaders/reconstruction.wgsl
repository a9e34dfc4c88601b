// reconstruction (paper eq. 1): rebuild the surface at every G-buffer texel.
// Rust side: gpu-backend/src/reconstruction.rs; the kernel:
// hyrt_core::kernels::reconstruction::reconstruct_texel. Every product and sum is written in
// the Rust kernels' order, and every product that feeds a sum goes through `mul`, which
// ORs the always-zero `camera.pad` into its bits so the compiler cannot fuse it into a
// multiply-add: the results are the CPU's bits.
//
// The records and format constants (GBUF_HIT, GBUF_BACK_FACE, INVALID_ID) are
// prepended by the Rust side (hyrt_core::formats::wgsl::declarations), then GAMMA_2,
// GAMMA_3 and ONE_PLUS_GAMMA_3 with the exact f32 values of
// hyrt_core::kernels::barycentric::gamma, then surface.wgsl (the kernels).

@group(0) @binding(0) var<storage, read> triangles: array<TriangleRecord>;
@group(0) @binding(1) var<storage, read> normals: array<f32>;
@group(0) @binding(2) var<storage, read> objects: array<ObjectRecord>;
@group(0) @binding(3) var<uniform> camera: CameraRecord;
@group(0) @binding(4) var<storage, read> gbuffer: array<GBufferTexel>;
@group(0) @binding(5) var<storage, read_write> surfaces: array<SurfaceRecord>;

fn rounded(x: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(x) | camera.pad);
}

fn mul(a: f32, b: f32) -> f32 {
    return rounded(a * b);
}

// mirrors hyrt_core::kernels::reconstruction::reconstruct_texel
fn reconstruct_texel(t: GBufferTexel) -> SurfaceRecord {
    if (t.flags & GBUF_HIT) == 0u {
        return SurfaceRecord(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), INVALID_ID, vec3<f32>(0.0), INVALID_ID);
    }
    let gi = objects[t.object].first_triangle + t.triangle;
    let tri = triangles[gi];
    let p = reconstruct_position(t.bary_u, t.bary_v, tri.v0, tri.v1, tri.v2);
    return surface_at(gi, t.bary_u, t.bary_v, (t.flags & GBUF_BACK_FACE) != 0u, p, camera.eye - p);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= camera.width || gid.y >= camera.height {
        return;
    }
    let pixel = gid.y * camera.width + gid.x;
    surfaces[pixel] = reconstruct_texel(gbuffer[pixel]);
}
