// Ray kernels shared by the GPU ray stages (concatenated in front of
// compaction.wgsl and shadow_rays.wgsl at pipeline creation).
//
// Every function mirrors a kernel of hyrt_core::kernels::ray with the same
// operation order. WGSL has no f64, no inf literal and no isinf/isnan: non-finite
// tests read the exponent bits; infinities are built from bits at run time only.

// The constants of hyrt_core (SLAB_FAR_SCALE, GAMMA_2/3/5 = gamma(n), OFFSET_ERROR_SCALE,
// MIN_LIGHT_DISTANCE_SQ, ...) come from a prelude the Rust side
// generates from the core constants as exact bit patterns (see `ray_prelude`).

const F32_EXP_MASK: u32 = 0x7f800000u;
const F32_SIGN_MASK: u32 = 0x80000000u;

// True for a finite f32 (not inf, not NaN), from its bits.
fn is_finite_f32(x: f32) -> bool {
    return (bitcast<u32>(x) & F32_EXP_MASK) != F32_EXP_MASK;
}

fn is_finite_vec3(v: vec3<f32>) -> bool {
    return is_finite_f32(v.x) && is_finite_f32(v.y) && is_finite_f32(v.z);
}

// mirrors hyrt_core::kernels::ray::next_float_up (bits: exact on any device)
fn next_float_up(x: f32) -> f32 {
    let bits = bitcast<u32>(x);
    if (bits & F32_EXP_MASK) == F32_EXP_MASK && (bits == F32_EXP_MASK || (bits & 0x007fffffu) != 0u) {
        return x; // +inf or NaN
    }
    if (bits & 0x7fffffffu) == 0u {
        return bitcast<f32>(1u); // +0 or -0: the smallest subnormal
    }
    if (bits & F32_SIGN_MASK) == 0u {
        return bitcast<f32>(bits + 1u);
    }
    return bitcast<f32>(bits - 1u);
}

// mirrors hyrt_core::kernels::ray::next_float_down
fn next_float_down(x: f32) -> f32 {
    let bits = bitcast<u32>(x);
    if (bits & F32_EXP_MASK) == F32_EXP_MASK && (bits == (F32_EXP_MASK | F32_SIGN_MASK) || (bits & 0x007fffffu) != 0u) {
        return x; // -inf or NaN
    }
    if (bits & 0x7fffffffu) == 0u {
        return bitcast<f32>(F32_SIGN_MASK | 1u); // +0 or -0: the smallest negative subnormal
    }
    if (bits & F32_SIGN_MASK) == 0u {
        return bitcast<f32>(bits - 1u);
    }
    return bitcast<f32>(bits + 1u);
}

// One coordinate of offset_ray_origin. `zero` is an always-zero uniform ORed into the
// product's bits so that the compiler cannot fuse `p + n * d` into a multiply-add (which
// rounds once where the CPU rounds twice).
fn offset_coordinate(p: f32, n: f32, d: f32, zero: u32) -> f32 {
    let offset = bitcast<f32>(bitcast<u32>(n * d) | zero);
    let o = p + offset;
    if offset > 0.0 {
        return next_float_up(o);
    }
    if offset < 0.0 {
        return next_float_down(o);
    }
    return o;
}

// mirrors hyrt_core::kernels::ray::offset_ray_origin (pbrt-v4's OffsetRayOrigin with the
// point's own error bound): d = ((|n.x| + |n.y|) + |n.z|) * (p_error * OFFSET_ERROR_SCALE),
// then each coordinate p + n * d, stepped once more away from the surface.
fn offset_ray_origin(p: vec3<f32>, p_error: f32, n: vec3<f32>, zero: u32) -> vec3<f32> {
    let d = ((abs(n.x) + abs(n.y)) + abs(n.z)) * (p_error * OFFSET_ERROR_SCALE);
    return vec3<f32>(offset_coordinate(p.x, n.x, d, zero), offset_coordinate(p.y, n.y, d, zero),
        offset_coordinate(p.z, n.z, d, zero));
}

// mirrors hyrt_core::kernels::ray::max_component_index (ties to the later axis)
fn max_component_index(v: vec3<f32>) -> u32 {
    if v.x > v.y {
        if v.x > v.z {
            return 0u;
        }
        return 2u;
    }
    if v.y > v.z {
        return 1u;
    }
    return 2u;
}

// mirrors hyrt_core::kernels::ray::permute_axes
fn permute_axes(v: vec3<f32>, kz: u32) -> vec3<f32> {
    switch kz {
        case 0u: {
            return vec3<f32>(v.y, v.z, v.x);
        }
        case 1u: {
            return vec3<f32>(v.z, v.x, v.y);
        }
        default: {
            return v;
        }
    }
}

// mirrors hyrt_core::kernels::ray::safe_inverse_dir: 1 / +-0 is +-inf by the sign
// bit (WGSL promises neither signed zeros nor infinities from a division by zero).
fn safe_inverse_coordinate(d: f32) -> f32 {
    if d == 0.0 {
        return bitcast<f32>(F32_EXP_MASK | (bitcast<u32>(d) & F32_SIGN_MASK));
    }
    return 1.0 / d;
}

fn safe_inverse_dir(d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(safe_inverse_coordinate(d.x), safe_inverse_coordinate(d.y), safe_inverse_coordinate(d.z));
}

// The sign bit of the inverse direction (inv_dir.is_sign_negative() on the CPU).
fn sign_negative(x: f32) -> bool {
    return (bitcast<u32>(x) & F32_SIGN_MASK) != 0u;
}

// mirrors hyrt_core::kernels::ray::ray_aabb_conservative. Returns (hit, t_enter).
// Running max/min written as `if candidate > acc { acc = candidate }` so a NaN
// candidate (0 * inf) is dropped, as on the CPU (WGSL's min/max leave NaN unspecified).
fn ray_aabb_conservative(
    origin: vec3<f32>,
    inv_dir: vec3<f32>,
    t_min: f32,
    t_max: f32,
    bmin: vec3<f32>,
    bmax: vec3<f32>,
) -> vec2<f32> {
    let neg_x = sign_negative(inv_dir.x);
    let neg_y = sign_negative(inv_dir.y);
    let neg_z = sign_negative(inv_dir.z);
    let near_x = select(bmin.x, bmax.x, neg_x);
    let far_x = select(bmax.x, bmin.x, neg_x);
    let near_y = select(bmin.y, bmax.y, neg_y);
    let far_y = select(bmax.y, bmin.y, neg_y);
    let near_z = select(bmin.z, bmax.z, neg_z);
    let far_z = select(bmax.z, bmin.z, neg_z);
    let tn_x = (near_x - origin.x) * inv_dir.x;
    let tn_y = (near_y - origin.y) * inv_dir.y;
    let tn_z = (near_z - origin.z) * inv_dir.z;
    let tf_x = (far_x - origin.x) * inv_dir.x * SLAB_FAR_SCALE;
    let tf_y = (far_y - origin.y) * inv_dir.y * SLAB_FAR_SCALE;
    let tf_z = (far_z - origin.z) * inv_dir.z * SLAB_FAR_SCALE;

    var t_enter = t_min;
    if tn_x > t_enter {
        t_enter = tn_x;
    }
    if tn_y > t_enter {
        t_enter = tn_y;
    }
    if tn_z > t_enter {
        t_enter = tn_z;
    }
    var t_exit = t_max;
    if tf_x < t_exit {
        t_exit = tf_x;
    }
    if tf_y < t_exit {
        t_exit = tf_y;
    }
    if tf_z < t_exit {
        t_exit = tf_z;
    }
    return vec2<f32>(select(0.0, 1.0, t_enter <= t_exit), t_enter);
}

// mirrors hyrt_core::kernels::ray::WatertightRay
struct WatertightRay {
    origin: vec3<f32>,
    kz: u32,
    shear: vec3<f32>,
}

// mirrors hyrt_core::kernels::ray::WatertightRay::new (validity checked by the caller)
fn watertight_ray_new(origin: vec3<f32>, dir: vec3<f32>) -> WatertightRay {
    let kz = max_component_index(abs(dir));
    let d = permute_axes(dir, kz);
    return WatertightRay(origin, kz, vec3<f32>(d.x / d.z, d.y / d.z, 1.0 / d.z));
}

// mirrors hyrt_core::kernels::ray::WatertightRay::transform
fn watertight_transform(r: WatertightRay, p: vec3<f32>) -> vec3<f32> {
    let q = permute_axes(p - r.origin, r.kz);
    return vec3<f32>(q.x - r.shear.x * q.z, q.y - r.shear.y * q.z, q.z);
}

// Lexicographic order of two sheared vertices (x, then y).
fn vertex_before(a: vec3<f32>, b: vec3<f32>) -> bool {
    return a.x < b.x || (a.x == b.x && a.y < b.y);
}

// mirrors hyrt_core::kernels::ray::edge_function: a.x * b.y - a.y * b.x.
// WGSL may fuse either product into an FMA, which would break the exact
// antisymmetry edge(b, a) == -edge(a, b) the watertight test relies on. So the
// edge is always evaluated with its two vertices in one canonical
// (lexicographic) order and negated when swapped: both triangles sharing an edge
// then compute the very same value, fused or not. Without fusion this equals the
// CPU's plain difference bit for bit (IEEE subtraction is exactly antisymmetric).
fn edge_function(a: vec3<f32>, b: vec3<f32>) -> f32 {
    if vertex_before(b, a) {
        return -(b.x * a.y - b.y * a.x);
    }
    return a.x * b.y - a.y * b.x;
}

// mirrors hyrt_core::kernels::ray::WatertightRay::intersect, any-hit form: true
// for a hit with t_min < t < t_max that is conservatively positive.
//
// Tie rule (no f64 in WGSL): where an f32 edge function is exactly zero the CPU
// recomputes all three in f64 and takes the exact signs. The GPU keeps the f32
// values: a zero edge function counts as on the edge, i.e. inside (as the CPU
// does for an exactly-zero f64 value). Both triangles sharing that edge see the
// same zero (canonical edge order), so a ray through a shared edge or vertex of a
// closed mesh still hits. A non-zero f32 edge function always has the exact
// sign (rounding is monotone), so the GPU can differ from the CPU only when the
// two products of an edge function round to the same f32 while their exact
// difference has the sign that rejects: the ray passes within about one rounding
// of an open (silhouette) edge, the CPU misses and the GPU hits (pinned in
// tests/shadow_rays.rs). Apart from t at the interval ends (f32 vs f64-rounded
// edge values give t a few ulps apart), GPU hits are a superset of CPU hits.
fn watertight_hit(r: WatertightRay, t_min: f32, t_max: f32, v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>) -> bool {
    let p0 = watertight_transform(r, v0);
    let p1 = watertight_transform(r, v1);
    let p2 = watertight_transform(r, v2);

    let e0 = edge_function(p1, p2);
    let e1 = edge_function(p2, p0);
    let e2 = edge_function(p0, p1);

    if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
        return false;
    }
    let det = e0 + e1 + e2;
    if det == 0.0 || !is_finite_f32(det) {
        return false;
    }

    let z0 = r.shear.z * p0.z;
    let z1 = r.shear.z * p1.z;
    let z2 = r.shear.z * p2.z;
    let t_scaled = e0 * z0 + e1 * z1 + e2 * z2;
    if det < 0.0 && t_scaled >= 0.0 {
        return false;
    }
    if det > 0.0 && t_scaled <= 0.0 {
        return false;
    }

    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    if !(t > t_min && t < t_max) {
        return false;
    }

    let max_zt = max(max(abs(z0), abs(z1)), abs(z2));
    let delta_z = GAMMA_3 * max_zt;
    let max_xt = max(max(abs(p0.x), abs(p1.x)), abs(p2.x));
    let max_yt = max(max(abs(p0.y), abs(p1.y)), abs(p2.y));
    // World-space z of the translated vertices (see the core kernel for why not max_zt).
    let max_zw = max(max(abs(p0.z), abs(p1.z)), abs(p2.z));
    let delta_x = GAMMA_5 * (max_xt + abs(r.shear.x) * max_zw);
    let delta_y = GAMMA_5 * (max_yt + abs(r.shear.y) * max_zw);
    let delta_e = 2.0 * (GAMMA_2 * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = max(max(abs(e0), abs(e1)), abs(e2));
    let delta_t = 3.0 * (GAMMA_3 * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * abs(inv_det);
    return t > delta_t;
}
