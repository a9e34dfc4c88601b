// Ray kernels shared by the GPU ray stages (concatenated in front of
// compaction.wgsl and shadow_rays.wgsl at pipeline creation).
//
// Every function mirrors a kernel of hyrt_core::kernels::ray with the same
// operation order. WGSL has no f64, no inf literal and no isinf/isnan: non-finite
// tests read the exponent bits; infinities are built from bits at run time only.

// The constants of hyrt_core (SLAB_FAR_SCALE, GAMMA_2/3/5 = gamma(n), OFFSET_ERROR_SCALE,
// MIN_LIGHT_DISTANCE_SQ, ...) come from a prelude the Rust side
// generates from the core constants as exact bit patterns (see `ray_prelude`). The
// f32 field masks (F32_SIGN_MASK, F32_EXP_MASK, F32_FRACTION_MASK) and `f32_is_finite`
// come with the preamble every stage begins with (`exact.wgsl`).

fn is_finite_vec3(v: vec3<f32>) -> bool {
    return f32_is_finite(v.x) && f32_is_finite(v.y) && f32_is_finite(v.z);
}

// mirrors hyrt_core::kernels::ray::next_float_up (bits: exact on any device)
fn next_float_up(x: f32) -> f32 {
    let bits = bitcast<u32>(x);
    if (bits & F32_EXP_MASK) == F32_EXP_MASK && (bits == F32_EXP_MASK || (bits & F32_FRACTION_MASK) != 0u) {
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
    if (bits & F32_EXP_MASK) == F32_EXP_MASK && (bits == (F32_EXP_MASK | F32_SIGN_MASK) || (bits & F32_FRACTION_MASK) != 0u) {
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
    let d = opaque(opaque(abs(n.x) + abs(n.y), zero) + abs(n.z), zero) * (p_error * OFFSET_ERROR_SCALE);
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
    return div_rn(1.0, d);
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
    return WatertightRay(origin, kz, vec3<f32>(div_rn(d.x, d.z), div_rn(d.y, d.z), div_rn(1.0, d.z)));
}

// Exact arithmetic of the ray/triangle test. `zero` is an always-zero uniform word
// (`FrameParams::zero`): ORed into a result's bits, it hides the value from the compiler,
// which can then neither fuse a product into a multiply-add nor simplify an expression
// algebraically (`c - (c - a)` to `a`); every operation rounds once, as on the CPU.
fn opaque(x: f32, zero: u32) -> f32 {
    return bitcast<f32>(bitcast<u32>(x) | zero);
}

fn mul_exact(a: f32, b: f32, zero: u32) -> f32 {
    return opaque(a * b, zero);
}

// mirrors hyrt_core::kernels::ray::WatertightRay::transform
fn watertight_transform(r: WatertightRay, p: vec3<f32>, zero: u32) -> vec3<f32> {
    let q = permute_axes(p - r.origin, r.kz);
    return vec3<f32>(q.x - mul_exact(r.shear.x, q.z, zero), q.y - mul_exact(r.shear.y, q.z, zero), q.z);
}

// mirrors hyrt_core::kernels::ray::edge_function: a.x * b.y - a.y * b.x, both products
// rounded (unfused), so edge_function(b, a) == -edge_function(a, b) exactly.
fn edge_function(a: vec3<f32>, b: vec3<f32>, zero: u32) -> f32 {
    return mul_exact(a.x, b.y, zero) - mul_exact(a.y, b.x, zero);
}

// mirrors hyrt_core::kernels::ray::veltkamp_split: (hi, lo)
fn veltkamp_split(a: f32, zero: u32) -> vec2<f32> {
    let c = mul_exact(VELTKAMP_SPLIT, a, zero);
    let hi = opaque(c - opaque(c - a, zero), zero);
    return vec2<f32>(hi, opaque(a - hi, zero));
}

// mirrors hyrt_core::kernels::ray::product_error (Dekker's TwoProduct)
fn product_error(a: f32, b: f32, p: f32, zero: u32) -> f32 {
    let sa = veltkamp_split(a, zero);
    let sb = veltkamp_split(b, zero);
    let x = opaque(mul_exact(sa.x, sb.x, zero) - p, zero);
    let y = opaque(x + mul_exact(sa.x, sb.y, zero), zero);
    let z = opaque(y + mul_exact(sa.y, sb.x, zero), zero);
    return opaque(z + mul_exact(sa.y, sb.y, zero), zero);
}

// mirrors hyrt_core::kernels::ray::edge_sign_exact
fn edge_sign_exact(a: vec3<f32>, b: vec3<f32>, zero: u32) -> f32 {
    let p = mul_exact(a.x, b.y, zero);
    return product_error(a.x, b.y, p, zero) - product_error(a.y, b.x, p, zero);
}

// mirrors hyrt_core::kernels::ray::exact_signs
fn exact_signs(e: vec3<f32>, p0: vec3<f32>, p1: vec3<f32>, p2: vec3<f32>, zero: u32) -> vec3<f32> {
    if e.x != 0.0 && e.y != 0.0 && e.z != 0.0 {
        return e;
    }
    var s = e;
    if e.x == 0.0 {
        s.x = edge_sign_exact(p1, p2, zero);
    }
    if e.y == 0.0 {
        s.y = edge_sign_exact(p2, p0, zero);
    }
    if e.z == 0.0 {
        s.z = edge_sign_exact(p0, p1, zero);
    }
    return s;
}

// mirrors hyrt_core::kernels::ray::WatertightRay::back_face
fn watertight_back_face(r: WatertightRay, det: f32) -> bool {
    return (det > 0.0) == (r.shear.z > 0.0);
}

// mirrors hyrt_core::kernels::ray::TriangleHit (`hit` false: no hit, the rest zero)
struct TriangleHit {
    hit: bool,
    t: f32,
    u: f32,
    v: f32,
    back_face: bool,
}

// mirrors hyrt_core::kernels::ray::WatertightRay::intersect, operation for operation:
// the same hits, t and barycentrics as the CPU, bit for bit, on a device that rounds
// `+`, `-` and `*` as IEEE 754 (the division is `div_rn`'s, exact everywhere).
fn watertight_intersect(r: WatertightRay, t_min: f32, t_max: f32, v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>,
                        zero: u32) -> TriangleHit {
    let none = TriangleHit(false, 0.0, 0.0, 0.0, false);
    let p0 = watertight_transform(r, v0, zero);
    let p1 = watertight_transform(r, v1, zero);
    let p2 = watertight_transform(r, v2, zero);

    let e0 = edge_function(p1, p2, zero);
    let e1 = edge_function(p2, p0, zero);
    let e2 = edge_function(p0, p1, zero);

    let s = exact_signs(vec3<f32>(e0, e1, e2), p0, p1, p2, zero);
    if (s.x < 0.0 || s.y < 0.0 || s.z < 0.0) && (s.x > 0.0 || s.y > 0.0 || s.z > 0.0) {
        return none;
    }
    let det = opaque(e0 + e1, zero) + e2;
    if det == 0.0 || !f32_is_finite(det) {
        return none;
    }

    let z0 = mul_exact(r.shear.z, p0.z, zero);
    let z1 = mul_exact(r.shear.z, p1.z, zero);
    let z2 = mul_exact(r.shear.z, p2.z, zero);
    let t_scaled = opaque(mul_exact(e0, z0, zero) + mul_exact(e1, z1, zero), zero) + mul_exact(e2, z2, zero);
    if det < 0.0 && t_scaled >= 0.0 {
        return none;
    }
    if det > 0.0 && t_scaled <= 0.0 {
        return none;
    }

    let inv_det = div_rn(1.0, det);
    let t = mul_exact(t_scaled, inv_det, zero);
    if !(t > t_min && t < t_max) {
        return none;
    }

    // The conservative t > 0 bound (see the core kernel), in its operation order.
    let max_zt = max(max(abs(z0), abs(z1)), abs(z2));
    let delta_z = mul_exact(GAMMA_3, max_zt, zero);
    let max_xt = max(max(abs(p0.x), abs(p1.x)), abs(p2.x));
    let max_yt = max(max(abs(p0.y), abs(p1.y)), abs(p2.y));
    let max_zw = max(max(abs(p0.z), abs(p1.z)), abs(p2.z));
    let delta_x = mul_exact(GAMMA_5, opaque(max_xt + mul_exact(abs(r.shear.x), max_zw, zero), zero), zero);
    let delta_y = mul_exact(GAMMA_5, opaque(max_yt + mul_exact(abs(r.shear.y), max_zw, zero), zero), zero);
    let de0 = mul_exact(mul_exact(GAMMA_2, max_xt, zero), max_yt, zero);
    let de1 = opaque(de0 + mul_exact(delta_y, max_xt, zero), zero);
    let delta_e = mul_exact(2.0, opaque(de1 + mul_exact(delta_x, max_yt, zero), zero), zero);
    let max_e = max(max(abs(e0), abs(e1)), abs(e2));
    let dt0 = mul_exact(mul_exact(GAMMA_3, max_e, zero), max_zt, zero);
    let dt1 = opaque(dt0 + mul_exact(delta_e, max_zt, zero), zero);
    let dt2 = opaque(dt1 + mul_exact(delta_z, max_e, zero), zero);
    let delta_t = mul_exact(mul_exact(3.0, dt2, zero), abs(inv_det), zero);
    if !(t > delta_t) {
        return none;
    }
    return TriangleHit(true, t, mul_exact(e1, inv_det, zero), mul_exact(e2, inv_det, zero),
        watertight_back_face(r, det));
}

// mirrors hyrt_core::bvh::TraversalRay
struct TraversalRay {
    wt: WatertightRay,
    inv_dir: vec3<f32>,
    t_min: f32,
    t_max: f32,
    box_t_min: f32,
}

// mirrors hyrt_core::bvh::TraversalRay::enter: (hit, t_enter) for [t_min, t_far],
// both ends widened by BVH_CULL_SLACK.
fn enter(r: TraversalRay, node: BvhNode, t_far: f32) -> vec2<f32> {
    let far = t_far * (1.0 + BVH_CULL_SLACK);
    return ray_aabb_conservative(r.wt.origin, r.inv_dir, r.box_t_min, far, node.aabb_min, node.aabb_max);
}

// The validity test of hyrt_core::bvh::TraversalRay::new: finite origin and direction,
// non-zero direction, t_min < t_max (a NaN bound fails).
fn traversal_ray_valid(ray: RayRecord) -> bool {
    return is_finite_vec3(ray.origin) && is_finite_vec3(ray.direction) && !all(ray.direction == vec3<f32>(0.0))
        && ray.t_min < ray.t_max;
}

// mirrors hyrt_core::bvh::TraversalRay::new for a ray that passed `traversal_ray_valid`.
fn traversal_ray_new(ray: RayRecord) -> TraversalRay {
    return TraversalRay(watertight_ray_new(ray.origin, ray.direction), safe_inverse_dir(ray.direction),
        ray.t_min, ray.t_max, ray.t_min * (1.0 - BVH_CULL_SLACK));
}
