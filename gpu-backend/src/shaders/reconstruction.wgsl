// reconstruction (paper eq. 1): rebuild the surface at every G-buffer texel.
// Rust side: gpu-backend/src/reconstruction.rs; the kernel:
// hyrt_core::kernels::reconstruction::reconstruct_texel. Every product and sum is written in
// the Rust kernels' order, and every product that feeds a sum goes through `mul`, which
// ORs the always-zero `camera.pad` into its bits so the compiler cannot fuse it into a
// multiply-add: the results are the CPU's bits.
//
// The records and format constants (GBUF_HIT, GBUF_BACK_FACE, INVALID_ID) are
// prepended by the Rust side (hyrt_core::formats::wgsl::declarations), then ray.wgsl with
// its constants (GAMMA_2, GAMMA_3, ... with the exact f32 values of
// hyrt_core::kernels::ray::gamma), then ONE_PLUS_GAMMA_3 and surface.wgsl (the kernels).
//
// Two entry points: `main` (the raster's barycentrics) and `main_reintersected` (each
// pixel's camera ray re-intersected with its triangle, PrimaryBarycentrics::Reintersected).

@group(0) @binding(0) var<storage, read> triangles: array<TriangleRecord>;
@group(0) @binding(1) var<storage, read> normals: array<f32>;
@group(0) @binding(2) var<storage, read> objects: array<ObjectRecord>;
@group(0) @binding(3) var<uniform> camera: CameraRecord;
@group(0) @binding(4) var<storage, read> gbuffer: array<GBufferTexel>;
@group(0) @binding(5) var<storage, read_write> surfaces: array<SurfaceRecord>;
// The band being reconstructed (gpu-backend/src/band.rs).
@group(0) @binding(6) var<uniform> params: FrameParams;

fn rounded(x: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(x) | camera.pad);
}

fn mul(a: f32, b: f32) -> f32 {
    return rounded(a * b);
}

const MISS_SURFACE = SurfaceRecord(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), INVALID_ID, vec3<f32>(0.0), INVALID_ID);

// mirrors hyrt_core::kernels::reconstruction::texel_surface: the surface of a hit texel
// at barycentrics `uv` of its triangle `gi`, seen from the eye.
fn texel_surface(t: GBufferTexel, gi: u32, tri: TriangleRecord, uv: vec2<f32>) -> SurfaceRecord {
    let p = reconstruct_position(uv.x, uv.y, tri.v0, tri.v1, tri.v2);
    return surface_at(gi, uv.x, uv.y, (t.flags & GBUF_BACK_FACE) != 0u, p, camera.eye - p);
}

// mirrors hyrt_core::kernels::reconstruction::reconstruct_texel
fn reconstruct_texel(t: GBufferTexel) -> SurfaceRecord {
    if (t.flags & GBUF_HIT) == 0u {
        return MISS_SURFACE;
    }
    let gi = objects[t.object].first_triangle + t.triangle;
    return texel_surface(t, gi, world_triangle(gi), vec2<f32>(t.bary_u, t.bary_v));
}

fn mul4(a: vec4<f32>, s: f32) -> vec4<f32> {
    return vec4<f32>(mul(a.x, s), mul(a.y, s), mul(a.z, s), mul(a.w, s));
}

fn rounded4(a: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(rounded(a.x), rounded(a.y), rounded(a.z), rounded(a.w));
}

// mirrors hyrt_core::kernels::camera::pixel_centre_ndc
fn pixel_centre_ndc(width: u32, height: u32, x: u32, y: u32) -> vec2<f32> {
    let nx = mul(div_rn(f32(x) + 0.5, f32(width)), 2.0) - 1.0;
    let ny = 1.0 - mul(div_rn(f32(y) + 0.5, f32(height)), 2.0);
    return vec2<f32>(nx, ny);
}

// mirrors the direction of hyrt_core::kernels::camera::primary_ray: glam's Mat4 * Vec4
// (column by column, each product rounded, the sums left to right), then the division by w.
fn primary_ray_direction(x: u32, y: u32) -> vec3<f32> {
    let ndc = pixel_centre_ndc(camera.width, camera.height, x, y);
    let m = camera.inv_view_proj;
    var far = mul4(m[0], ndc.x);
    far = rounded4(far + mul4(m[1], ndc.y));
    far = rounded4(far + mul4(m[2], 1.0));
    far = rounded4(far + mul4(m[3], 1.0));
    return div_rn3(far.xyz, far.w);
}

// mirrors hyrt_core::kernels::reconstruction::reintersected_barycentrics: the watertight
// test over 0 < t < inf, the raster's barycentrics where the ray misses the triangle (or
// is not a ray: WatertightRay::new's None).
fn reintersected_barycentrics(t: GBufferTexel, tri: TriangleRecord, dir: vec3<f32>) -> vec2<f32> {
    let raster = vec2<f32>(t.bary_u, t.bary_v);
    let zero_dir = dir.x == 0.0 && dir.y == 0.0 && dir.z == 0.0;
    if !(is_finite_vec3(camera.eye) && is_finite_vec3(dir)) || zero_dir {
        return raster;
    }
    let inf = bitcast<f32>(F32_EXP_MASK | camera.pad);
    let h = watertight_intersect(watertight_ray_new(camera.eye, dir), 0.0, inf, tri.v0, tri.v1, tri.v2, camera.pad);
    if h.hit {
        return vec2<f32>(h.u, h.v);
    }
    return raster;
}

// mirrors hyrt_core::kernels::reconstruction::reconstruct_texel_reintersected
fn reconstruct_texel_reintersected(t: GBufferTexel, x: u32, y: u32) -> SurfaceRecord {
    if (t.flags & GBUF_HIT) == 0u {
        return MISS_SURFACE;
    }
    let gi = objects[t.object].first_triangle + t.triangle;
    let tri = world_triangle(gi);
    return texel_surface(t, gi, tri, reintersected_barycentrics(t, tri, primary_ray_direction(x, y)));
}

// One thread per pixel of the band (gpu-backend/src/band.rs): `params.width` x
// `params.height` from image row `params.first_row`; the camera's rays are the image's.
@compute @workgroup_size(8, 8, 1)
fn main_reintersected(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let pixel = gid.y * params.width + gid.x;
    surfaces[pixel] = reconstruct_texel_reintersected(gbuffer[pixel], gid.x, gid.y + params.first_row);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let pixel = gid.y * params.width + gid.x;
    surfaces[pixel] = reconstruct_texel(gbuffer[pixel]);
}
