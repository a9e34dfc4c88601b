// The surface at a hit (paper eq. 1): WGSL mirrors of hyrt_core::kernels::barycentric
// and the `surface_at` of hyrt_core::kernels::reconstruction, shared by `reconstruction`
// (G-buffer texels) and `bounce_trace` (closest hits of secondary rays). Every product
// and sum is written in the Rust kernels' order, and every product that feeds a sum
// goes through `mul`, which the including stage defines to OR an always-zero uniform
// into its bits (`rounded`) so the compiler cannot fuse it into a multiply-add: the
// results are the CPU's bits.
//
// Prepended after the generated records and the constants GAMMA_2, GAMMA_3 and
// ONE_PLUS_GAMMA_3; the stage defines `rounded(x: f32) -> f32` and
// `mul(a: f32, b: f32) -> f32` and binds `triangles: array<TriangleRecord>` and
// `normals: array<f32>`.

fn mul3(a: vec3<f32>, s: f32) -> vec3<f32> {
    return vec3<f32>(mul(a.x, s), mul(a.y, s), mul(a.z, s));
}

// glam's Vec3::dot: (x * x') + (y * y') + (z * z'), left to right.
fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return rounded(mul(a.x, b.x) + mul(a.y, b.y)) + mul(a.z, b.z);
}

// glam's Vec3::cross.
fn cross3(a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(mul(a.y, b.z) - mul(b.y, a.z), mul(a.z, b.x) - mul(b.z, a.x), mul(a.x, b.y) - mul(b.x, a.y));
}

// glam's Vec3::normalize_or: self * (1 / length) if that reciprocal is finite and > 0.
fn normalize_or(a: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let len = sqrt_rn(dot3(a, a));
    // 1 / len is finite and positive exactly when len is positive, finite and not
    // so small that the reciprocal overflows; the explicit test keeps a division by
    // zero (or NaN) out of the shader.
    if !(len > 0.0) || !f32_is_finite(len) {
        return fallback;
    }
    let rcp = div_rn(1.0, len);
    if f32_is_finite(rcp) && rcp > 0.0 {
        // Each product behind the barrier: a caller's sum would otherwise fuse with it.
        return mul3(a, rcp);
    }
    return fallback;
}

// mirrors hyrt_core::kernels::barycentric::bary_w
fn bary_w(u: f32, v: f32) -> f32 {
    return (1.0 - u) - v;
}

// mirrors hyrt_core::kernels::barycentric::reconstruct_position
fn reconstruct_position(u: f32, v: f32, v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>) -> vec3<f32> {
    let w = bary_w(u, v);
    return vec3<f32>(
        rounded(mul(w, v0.x) + mul(u, v1.x)) + mul(v, v2.x),
        rounded(mul(w, v0.y) + mul(u, v1.y)) + mul(v, v2.y),
        rounded(mul(w, v0.z) + mul(u, v1.z)) + mul(v, v2.z),
    );
}

// mirrors hyrt_core::kernels::barycentric::position_error_bound
fn position_error_bound(u: f32, v: f32, v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>) -> vec3<f32> {
    let w = bary_w(u, v);
    let sum = (abs(mul3(v0, w)) + abs(mul3(v1, u))) + abs(mul3(v2, v));
    let w_err = mul(GAMMA_2, rounded(1.0 + abs(u)) + abs(v));
    return mul3(mul3(sum, GAMMA_3) + mul3(abs(v0), mul(w_err, ONE_PLUS_GAMMA_3)), ONE_PLUS_GAMMA_3);
}

// mirrors hyrt_core::kernels::barycentric::interpolate_normal
fn interpolate_normal(u: f32, v: f32, n0: vec3<f32>, n1: vec3<f32>, n2: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let w = bary_w(u, v);
    let s = vec3<f32>(
        rounded(mul(w, n0.x) + mul(u, n1.x)) + mul(v, n2.x),
        rounded(mul(w, n0.y) + mul(u, n1.y)) + mul(v, n2.y),
        rounded(mul(w, n0.z) + mul(u, n1.z)) + mul(v, n2.z),
    );
    // sqrt + division, as the CPU (not inverseSqrt, which is not exact).
    let len = sqrt_rn(dot3(s, s));
    if len > 0.0 && f32_is_finite(len) {
        return div_rn3(s, len);
    }
    return fallback;
}

// mirrors hyrt_core::kernels::barycentric::geometric_normal
fn geometric_normal(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>) -> vec3<f32> {
    return normalize_or(cross3(v1 - v0, v2 - v0), vec3<f32>(0.0));
}

// mirrors hyrt_core::kernels::shading::orient_to_seen_side; returns (geometric, shading).
fn orient_to_seen_side(geometric: vec3<f32>, shading: vec3<f32>, back_face: bool) -> array<vec3<f32>, 2> {
    if back_face {
        return array<vec3<f32>, 2>(-geometric, -shading);
    }
    return array<vec3<f32>, 2>(geometric, shading);
}

fn max_element(a: vec3<f32>) -> f32 {
    return max(max(a.x, a.y), a.z);
}

fn corner_normal(gi: u32, k: u32) -> vec3<f32> {
    let b = gi * 9u + k * 3u;
    return vec3<f32>(normals[b], normals[b + 1u], normals[b + 2u]);
}

fn any_nonzero(a: vec3<f32>) -> bool {
    return a.x != 0.0 || a.y != 0.0 || a.z != 0.0;
}

// mirrors hyrt_core::kernels::reconstruction::surface_at: the surface record at
// barycentrics (u, v) of global triangle `gi`, whose point `p` the caller rebuilt, seen
// from its back when `back_face`; a degenerate triangle without vertex normals gets the
// normal `toward` normalized (the direction towards the viewer).
fn surface_at(gi: u32, u: f32, v: f32, back_face: bool, p: vec3<f32>, toward: vec3<f32>) -> SurfaceRecord {
    let tri = world_triangle(gi);
    let v0 = tri.v0;
    let v1 = tri.v1;
    let v2 = tri.v2;
    // Its object's offset error (0 unless its rays are traced in its own space).
    let err = max_element(position_error_bound(u, v, v0, v1, v2)) + objects[tri.object].offset_error;
    var ng = geometric_normal(v0, v1, v2);
    let corners = world_triangle_normals(gi, tri);
    var ns = interpolate_normal(u, v, corners[0], corners[1], corners[2], ng);
    // The side the ray saw, exactly.
    let oriented = orient_to_seen_side(ng, ns, back_face);
    ng = oriented[0];
    ns = oriented[1];
    if !any_nonzero(ns) {
        ns = normalize_or(toward, vec3<f32>(0.0, 1.0, 0.0));
    }
    // Keep the shading normal in the viewer's hemisphere of the geometric normal.
    if any_nonzero(ng) && dot3(ns, ng) < 0.0 {
        ns = ng;
    }
    return SurfaceRecord(p, err, ns, tri.object, ng, gi);
}
