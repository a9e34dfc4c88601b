//! Ray kernels: the watertight ray/triangle test, the conservative ray/box slab
//! test and the robust secondary-ray origin offset.
//!
//! These are the specification of every ray query in hyrt: the CPU BVH traversal
//! ([`crate::bvh`]) calls them and the WGSL traversal mirrors each function by
//! name. All arithmetic is plain f32 with the operation order written out (no
//! `mul_add`, no reassociation), so a GPU that rounds every operation as IEEE 754 and
//! does not fuse products into additions computes the same bits: even the tie rule of
//! [`intersect_triangle_watertight`] (an exactly-zero edge function) is decided exactly
//! in f32, by Dekker's error-free product ([`product_error`]), not in f64, which WGSL
//! lacks.
//!
//! Conventions:
//! * A ray is `origin + t * dir`, `dir` not necessarily normalized.
//! * A triangle is hit only for `t_min < t < t_max` (the Vulkan ray-tracing rule).
//! * Barycentrics follow the G-buffer: `u` is the weight of `v1`, `v` the weight
//!   of `v2`, `w = 1 - u - v` the weight of `v0`.
//! * Non-finite inputs never hit and never panic.
//!
//! ```
//! use hyrt_core::glam::Vec3;
//! use hyrt_core::kernels::ray::intersect_triangle_watertight;
//! let hit = intersect_triangle_watertight(
//!     Vec3::new(0.25, 0.25, 1.0), Vec3::NEG_Z, 0.0, f32::INFINITY,
//!     Vec3::ZERO, Vec3::X, Vec3::Y,
//! ).unwrap();
//! assert_eq!((hit.t, hit.u, hit.v), (1.0, 0.25, 0.25));
//! ```

use glam::Vec3;

// ---------------------------------------------------------------------------------------------
// Floating-point error bounds
// ---------------------------------------------------------------------------------------------

/// Unit roundoff of f32, 2^-24: the largest relative error of one correctly rounded
/// operation (pbrt-v4 `MachineEpsilon`, `util/float.h`; Higham's *u*).
pub const MACHINE_EPSILON: f32 = f32::EPSILON * 0.5;

/// pbrt-v4 `gamma(n) = n u / (1 - n u)`: a bound on the relative error accumulated by
/// `n` successive rounded operations (Higham, *Accuracy and Stability of Numerical
/// Algorithms*, lemma 3.1; pbrt-v4 `util/float.h`).
#[inline]
pub const fn gamma(n: i32) -> f32 {
    let nu = n as f32 * MACHINE_EPSILON;
    nu / (1.0 - nu)
}

/// Scale applied to every far slab distance in [`ray_aabb_conservative`]:
/// `1 + 2 gamma(3)` (pbrt-v4 `Bounds3::IntersectP`, after Ize 2013, "Robust BVH Ray
/// Traversal"). Each slab distance carries at most gamma(3) relative error (the
/// subtraction, the rounded reciprocal and the product), so widening the far bound by
/// twice that keeps the interval conservative.
pub const SLAB_FAR_SCALE: f32 = 1.0 + 2.0 * gamma(3);

// ---------------------------------------------------------------------------------------------
// Watertight ray/triangle intersection
// ---------------------------------------------------------------------------------------------

/// A ray/triangle hit: distance and barycentrics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter of the hit: `t_min < t < t_max`.
    pub t: f32,
    /// Barycentric weight of `v1`.
    pub u: f32,
    /// Barycentric weight of `v2` (the weight of `v0` is `1 - u - v`).
    pub v: f32,
    /// The ray hit the triangle's back: it travels along the right-handed normal
    /// `(v1 - v0) x (v2 - v0)`. Decided exactly, from the sign of the determinant the
    /// test itself computed ([`WatertightRay::back_face`]), never from a dot product.
    pub back_face: bool,
}

/// The per-ray constants of the watertight test (Woop, Benthin, Wald 2013, "Watertight
/// Ray/Triangle Intersection", JCGT 2(1), section 3: computed once per ray).
///
/// The ray's space is: translate by `-origin`, permute the axes so that the largest
/// `|dir|` component becomes z, then shear so that the ray becomes the +z axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WatertightRay {
    /// The ray origin (the translation).
    pub origin: Vec3,
    /// Index of the largest `|dir|` component; the permutation is
    /// `(kx, ky, kz) = ((kz + 1) % 3, (kz + 2) % 3, kz)` (see [`permute_axes`]).
    pub kz: u32,
    /// Shear constants `(dir[kx] / dir[kz], dir[ky] / dir[kz], 1 / dir[kz])`.
    pub shear: Vec3,
}

/// Index of the largest of three values, ties going to the later axis (pbrt-v4
/// `MaxComponentIndex`): `x > y ? (x > z ? 0 : 2) : (y > z ? 1 : 2)`.
#[inline]
pub fn max_component_index(v: Vec3) -> u32 {
    if v.x > v.y {
        if v.x > v.z {
            0
        } else {
            2
        }
    } else if v.y > v.z {
        1
    } else {
        2
    }
}

/// The axes in [`permute_axes`]'s order, as indices: `permute_axes(v, kz)[i]` is
/// `v[permuted_axis_order(kz)[i]]` (for code that reads the axes from memory, such as the
/// CPU's single-ray leaf test, which picks its vertex rows once per ray).
#[inline]
pub const fn permuted_axis_order(kz: u32) -> [usize; 3] {
    match kz {
        0 => [1, 2, 0],
        1 => [2, 0, 1],
        _ => [0, 1, 2],
    }
}

/// Permute the axes of `v` so that axis `kz` comes last:
/// `kz = 0: (y, z, x)`, `kz = 1: (z, x, y)`, `kz = 2: (x, y, z)`.
#[inline]
pub fn permute_axes(v: Vec3, kz: u32) -> Vec3 {
    match kz {
        0 => Vec3::new(v.y, v.z, v.x),
        1 => Vec3::new(v.z, v.x, v.y),
        _ => v,
    }
}

/// The 2D edge function `a.x * b.y - a.y * b.x` of sheared vertices, in f32.
///
/// Written as a plain difference of two rounded products (as in Woop et al.; pbrt-v4 uses
/// Kahan's `DifferenceOfProducts` instead) so that it is exactly antisymmetric:
/// `edge_function(b, a) == -edge_function(a, b)` bit for bit. Two triangles sharing an
/// edge therefore see the same edge value with opposite signs, which is what makes the
/// test watertight. A GPU mirror must not let the compiler fuse either product into an
/// FMA.
#[inline]
fn edge_function(a: Vec3, b: Vec3) -> f32 {
    a.x * b.y - a.y * b.x
}

/// Veltkamp's splitting constant for f32, `2^12 + 1`: `split` cuts a 24-bit significand
/// into two halves of at most 12 bits, whose products are exact in f32 (Dekker 1971,
/// "A floating-point technique for extending the available precision"; Ogita, Rump,
/// Oishi 2005, `Split` with `s = 12`).
pub const VELTKAMP_SPLIT: f32 = 4097.0;

/// `a = hi + lo` exactly, each with at most 12 significant bits (Veltkamp). Exact unless
/// `VELTKAMP_SPLIT * a` overflows (`|a|` above about 8e34).
#[inline]
pub fn veltkamp_split(a: f32) -> (f32, f32) {
    let c = VELTKAMP_SPLIT * a;
    let hi = c - (c - a);
    (hi, a - hi)
}

/// The rounding error of the f32 product `p = a * b`: `a * b - p`, exactly (Dekker's
/// `TwoProduct` without a fused multiply-add, which WGSL does not promise). Every
/// operation below is exact or its error cancels by construction, as long as nothing
/// overflows and the error is not subnormal: products of magnitude above about 1e-30
/// (coordinates relative to the ray origin above about 1e-15), far below any scene the
/// renderer accepts.
#[inline]
pub fn product_error(a: f32, b: f32, p: f32) -> f32 {
    let (ah, al) = veltkamp_split(a);
    let (bh, bl) = veltkamp_split(b);
    ((ah * bh - p) + ah * bl + al * bh) + al * bl
}

/// A value with the exact sign of the edge function `a.x * b.y - a.y * b.x` whose f32
/// value (`edge_function`) is exactly zero: both products then round to the same `p`,
/// so the exact difference is `(a.x b.y - p) - (a.y b.x - p)`, the difference of the two
/// exact rounding errors ([`product_error`]), which one rounded subtraction returns with
/// its exact sign (zero only when it is exactly zero). Antisymmetric like the edge
/// function: swapping `a` and `b` negates it exactly.
#[inline]
pub fn edge_sign_exact(a: Vec3, b: Vec3) -> f32 {
    let p = a.x * b.y;
    product_error(a.x, b.y, p) - product_error(a.y, b.x, p)
}

/// The edge functions' signs for the inside test: the f32 values where none is zero (a
/// non-zero f32 edge function has the exact sign: rounding is monotone), else every
/// exactly-zero one replaced by [`edge_sign_exact`].
#[inline]
fn exact_signs(e: [f32; 3], p0: Vec3, p1: Vec3, p2: Vec3) -> [f32; 3] {
    if e[0] != 0.0 && e[1] != 0.0 && e[2] != 0.0 {
        return e;
    }
    let fix = |e: f32, a: Vec3, b: Vec3| if e == 0.0 { edge_sign_exact(a, b) } else { e };
    [fix(e[0], p1, p2), fix(e[1], p2, p0), fix(e[2], p0, p1)]
}

impl WatertightRay {
    /// Precompute the ray space. `None` (the ray hits nothing) for a non-finite origin
    /// or direction, or a zero direction.
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3) -> Option<WatertightRay> {
        if !(origin.is_finite() && dir.is_finite()) || dir == Vec3::ZERO {
            return None;
        }
        let kz = max_component_index(dir.abs());
        let d = permute_axes(dir, kz);
        let shear = Vec3::new(d.x / d.z, d.y / d.z, 1.0 / d.z);
        Some(WatertightRay { origin, kz, shear })
    }

    /// Translate, permute and shear a vertex (x and y only; z is left unscaled).
    #[inline]
    fn transform(&self, p: Vec3) -> Vec3 {
        let q = permute_axes(p - self.origin, self.kz);
        Vec3::new(q.x - self.shear.x * q.z, q.y - self.shear.y * q.z, q.z)
    }

    /// Whether a hit with determinant `det` (the sum of the three edge functions,
    /// [`Self::intersect`]) is on the triangle's back face.
    ///
    /// In the ray space the normal's z component is `(n . d) / d_z` (the shear keeps x
    /// and y of the normal and maps `n_z` to `n . d / d_z`; the axis permutation is
    /// cyclic, so it keeps handedness), and `det` is twice the triangle's projected
    /// signed area, which has the sign of that z component. So `n . d > 0` (the ray
    /// travels along the normal: a back face) exactly when `det` and `1 / d_z`
    /// (`shear.z`) have the same sign. Inside a triangle the three edge functions share
    /// one sign, so `det` has it with no cancellation: the facing is as exact as the
    /// hit itself. WGSL: `watertight_back_face`.
    #[inline(always)]
    pub fn back_face(&self, det: f32) -> bool {
        (det > 0.0) == (self.shear.z > 0.0)
    }

    /// The facing of a triangle this ray hits: [`Self::back_face`] of the determinant
    /// that [`Self::intersect`] computes (the sum of the f32 edge functions), with no
    /// range test. For traversals that find the hit without keeping the determinant
    /// (the SIMD packets).
    pub fn facing(&self, v0: Vec3, v1: Vec3, v2: Vec3) -> bool {
        let (p0, p1, p2) = (self.transform(v0), self.transform(v1), self.transform(v2));
        self.back_face(edge_function(p1, p2) + edge_function(p2, p0) + edge_function(p0, p1))
    }

    /// The watertight test against one triangle, for this precomputed ray; see
    /// [`intersect_triangle_watertight`], which is exactly this after [`Self::new`].
    /// (`inline(always)`: it is the body of the traversal's leaf loop, which LLVM otherwise
    /// keeps out of line; inlining it measured about a third more shadow rays per second.)
    #[inline(always)]
    pub fn intersect(&self, t_min: f32, t_max: f32, v0: Vec3, v1: Vec3, v2: Vec3) -> Option<TriangleHit> {
        // Vertices in ray space (x, y sheared; z still unscaled).
        let p0 = self.transform(v0);
        let p1 = self.transform(v1);
        let p2 = self.transform(v2);

        // Edge functions: e_i is twice the signed area of the sub-triangle opposite v_i,
        // seen from the ray (the ray is the point (0, 0) of the sheared xy plane).
        let e0 = edge_function(p1, p2);
        let e1 = edge_function(p2, p0);
        let e2 = edge_function(p0, p1);

        // Inside test: all edge functions of the same sign (zeros accepted: edges are
        // shared, both neighbours report the hit and the caller breaks the tie). Where the
        // ray passes (to f32 precision) exactly through an edge or vertex, an f32 edge
        // function is zero and its exact sign decides ([`exact_signs`]; Woop et al.
        // section 3 recompute in f64, which the GPU cannot mirror): a ray through a
        // shared edge enters exactly one side, and a ray a hair outside a silhouette edge
        // misses. The values below stay the f32 ones.
        let [s0, s1, s2] = exact_signs([e0, e1, e2], p0, p1, p2);
        if (s0 < 0.0 || s1 < 0.0 || s2 < 0.0) && (s0 > 0.0 || s1 > 0.0 || s2 > 0.0) {
            return None;
        }
        // Degenerate in ray space (det == 0; always the case for a triangle with two equal
        // vertices), or non-finite (a NaN or infinite vertex makes det non-finite).
        let det = e0 + e1 + e2;
        if det == 0.0 || !det.is_finite() {
            return None;
        }

        // Scaled hit distance: t * det, signs compared before dividing.
        let z0 = self.shear.z * p0.z;
        let z1 = self.shear.z * p1.z;
        let z2 = self.shear.z * p2.z;
        let t_scaled = e0 * z0 + e1 * z1 + e2 * z2;
        if det < 0.0 && t_scaled >= 0.0 {
            return None;
        }
        if det > 0.0 && t_scaled <= 0.0 {
            return None;
        }

        let inv_det = 1.0 / det;
        let t = t_scaled * inv_det;
        // Written so that a NaN anywhere rejects.
        if !(t > t_min && t < t_max) {
            return None;
        }

        // Conservative t > 0: reject hits closer to the origin than the error bound of t
        // (pbrt-v4 `IntersectTriangle`, "Ensure that computed triangle t is
        // conservatively greater than zero"; PBR 4th ed. section 6.8.7), with one change:
        // the error of the sheared x (`x - s z`, `s = d.x / d.z`, and likewise y) is
        // bounded by `gamma(5) (|x| + |s| |z|)` with the world-space z of the translated
        // vertices: the book's derivation before it bounds `|s|` by 1. pbrt-v4's code adds
        // the z already scaled by 1 / d.z (units of t) instead, which made the bound depend
        // on the direction's length: with directions 1e-6 times the scene's distances it
        // exceeded t and rejected real hits (226 t at 100 scene units); with directions
        // longer than the distances (shadow rays to a light several units away) it fell
        // below the error. Now the bound is invariant under scaling the direction
        // (`conservative_t_bound_holds_for_any_direction_length`).
        let max_zt = z0.abs().max(z1.abs()).max(z2.abs());
        let delta_z = gamma(3) * max_zt;
        let max_xt = p0.x.abs().max(p1.x.abs()).max(p2.x.abs());
        let max_yt = p0.y.abs().max(p1.y.abs()).max(p2.y.abs());
        let max_zw = p0.z.abs().max(p1.z.abs()).max(p2.z.abs());
        let delta_x = gamma(5) * (max_xt + self.shear.x.abs() * max_zw);
        let delta_y = gamma(5) * (max_yt + self.shear.y.abs() * max_zw);
        let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
        let max_e = e0.abs().max(e1.abs()).max(e2.abs());
        let delta_t = 3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
        // Positive form, so that a NaN bound rejects.
        if t > delta_t {
            Some(TriangleHit { t, u: e1 * inv_det, v: e2 * inv_det, back_face: self.back_face(det) })
        } else {
            None
        }
    }
}

/// Whether the watertight test of the ray `origin + t dir` against the triangle meets an
/// exactly-zero f32 edge function while the other two are not of opposite signs: where
/// [`WatertightRay::intersect`] lets the exact sign of that edge function decide
/// ([`edge_sign_exact`]). Both backends decide these rays by the same f32 arithmetic;
/// tests use it to show that a corpus exercises the rule.
pub fn meets_zero_edge_tie(origin: Vec3, dir: Vec3, v0: Vec3, v1: Vec3, v2: Vec3) -> bool {
    let Some(r) = WatertightRay::new(origin, dir) else { return false };
    let (p0, p1, p2) = (r.transform(v0), r.transform(v1), r.transform(v2));
    let e = [edge_function(p1, p2), edge_function(p2, p0), edge_function(p0, p1)];
    e.contains(&0.0) && !(e.iter().any(|&x| x < 0.0) && e.iter().any(|&x| x > 0.0))
}

/// Watertight ray/triangle intersection (Woop, Benthin, Wald 2013; pbrt-v4
/// `IntersectTriangle`): translate the vertices to the ray origin, permute the axes so the
/// largest `|dir|` component is z, shear so the ray is the +z axis, then evaluate the three
/// 2D edge functions at the origin. Edge functions are exactly antisymmetric (see
/// `edge_function`), and the signs of exactly-zero ones are decided exactly
/// ([`edge_sign_exact`]), so a ray through a shared edge or vertex of a closed mesh always
/// hits at least one of its triangles.
///
/// Returns a hit only for `t_min < t < t_max` and only if `t` is conservatively positive
/// (larger than its rounding-error bound, pbrt-v4). Never hits a triangle with `det == 0`
/// in ray space (in particular any triangle with two equal vertices), nor for NaN or
/// infinite inputs, a zero direction, or NaN bounds.
///
/// Both faces are hit (no culling). `u` and `v` are the weights of `v1` and `v2`.
///
/// Range: the edge functions are products of two vertex coordinates relative to the ray
/// origin, so triangles extending more than about 1e19 from the origin overflow f32 and
/// are never hit (a non-finite `det` rejects).
#[inline]
pub fn intersect_triangle_watertight(
    origin: Vec3,
    dir: Vec3,
    t_min: f32,
    t_max: f32,
    v0: Vec3,
    v1: Vec3,
    v2: Vec3,
) -> Option<TriangleHit> {
    WatertightRay::new(origin, dir)?.intersect(t_min, t_max, v0, v1, v2)
}

// ---------------------------------------------------------------------------------------------
// Conservative slab test
// ---------------------------------------------------------------------------------------------

/// Component-wise `1 / dir`, keeping the sign of zero: `1 / +0 = +inf`, `1 / -0 = -inf`
/// (IEEE 754 division does exactly this; the function exists so that the GPU mirror,
/// where WGSL does not promise signed zeros or infinities, has one place to fix it).
#[inline]
pub fn safe_inverse_dir(dir: Vec3) -> Vec3 {
    Vec3::new(1.0 / dir.x, 1.0 / dir.y, 1.0 / dir.z)
}

/// Conservative ray/box slab test (Kay-Kajiya slabs; robustness after Ize 2013 and
/// pbrt-v4 `Bounds3::IntersectP`). Returns the entry distance `max(t_min, near planes)`
/// if the ray's interval `[t_min, t_max]` overlaps the closed box, else `None`.
///
/// * The near and far plane of each axis are chosen by the sign bit of `inv_dir`, so a
///   `-0` direction component (inverse `-inf`) is handled like any negative one.
/// * Far distances are scaled by [`SLAB_FAR_SCALE`] so that rounding never loses a box
///   the exact test would hit.
/// * An origin exactly on a slab plane with an infinite inverse gives `0 * inf = NaN`;
///   the running max/min are written as `if candidate > acc { acc = candidate }` so a NaN
///   candidate is dropped: that axis then does not constrain the interval (the ray lies
///   in the plane, inside the closed slab). NaN `t_min` or `t_max` give `None`.
///
/// The origin must be finite (the BVH traversal checks rays once up front).
#[inline]
pub fn ray_aabb_conservative(
    origin: Vec3,
    inv_dir: Vec3,
    t_min: f32,
    t_max: f32,
    bmin: Vec3,
    bmax: Vec3,
) -> Option<f32> {
    let (near_x, far_x) = if inv_dir.x.is_sign_negative() { (bmax.x, bmin.x) } else { (bmin.x, bmax.x) };
    let (near_y, far_y) = if inv_dir.y.is_sign_negative() { (bmax.y, bmin.y) } else { (bmin.y, bmax.y) };
    let (near_z, far_z) = if inv_dir.z.is_sign_negative() { (bmax.z, bmin.z) } else { (bmin.z, bmax.z) };
    let tn_x = (near_x - origin.x) * inv_dir.x;
    let tn_y = (near_y - origin.y) * inv_dir.y;
    let tn_z = (near_z - origin.z) * inv_dir.z;
    let tf_x = (far_x - origin.x) * inv_dir.x * SLAB_FAR_SCALE;
    let tf_y = (far_y - origin.y) * inv_dir.y * SLAB_FAR_SCALE;
    let tf_z = (far_z - origin.z) * inv_dir.z * SLAB_FAR_SCALE;

    let mut t_enter = t_min;
    if tn_x > t_enter {
        t_enter = tn_x;
    }
    if tn_y > t_enter {
        t_enter = tn_y;
    }
    if tn_z > t_enter {
        t_enter = tn_z;
    }
    let mut t_exit = t_max;
    if tf_x < t_exit {
        t_exit = tf_x;
    }
    if tf_y < t_exit {
        t_exit = tf_y;
    }
    if tf_z < t_exit {
        t_exit = tf_z;
    }
    if t_enter <= t_exit {
        Some(t_enter)
    } else {
        None
    }
}

// ---------------------------------------------------------------------------------------------
// Secondary-ray origins
// ---------------------------------------------------------------------------------------------

/// Scale of the error bound in [`offset_ray_origin`]: `1 + 2^-8`.
///
/// Where it comes from: the offset must move the computed point `p` past the triangle's
/// exact plane, whose distance from `p` along the exact unit normal `n*` is at most
/// `e |n*|_1` (`e` bounds each coordinate's error). The offset is taken along the f32
/// normal `n`, whose direction is off by an angle `a`, and its length is evaluated in f32
/// (about 4 roundings, `4 u` relative). It moves `p` by `S e |n|_1 (1 - 4u) cos a` along
/// `n*`, which exceeds `e |n*|_1 <= e (|n|_1 + sqrt(3) a)` for every `a <= 1e-3` rad when
/// `S = 1 + 2^-8` (`|n|_1 >= 1`). An f32 cross product of two edges is that accurate
/// unless the triangle is a sliver with an aspect ratio beyond about 1e4 (angle error
/// about `u` times the aspect ratio). pbrt-v4 uses `S = 1` and assumes the normal exact.
pub const OFFSET_ERROR_SCALE: f32 = 1.0 + 1.0 / 256.0;

/// The next f32 above `x` (pbrt-v4 `NextFloatUp`): `-0` and `+0` step to the smallest
/// subnormal, `+inf` and NaN stay. Integer arithmetic on the bits: exact on any device.
#[inline]
pub fn next_float_up(x: f32) -> f32 {
    if x.is_nan() || x == f32::INFINITY {
        return x;
    }
    let x = if x == 0.0 { 0.0 } else { x };
    let bits = x.to_bits();
    f32::from_bits(if x >= 0.0 { bits + 1 } else { bits - 1 })
}

/// The next f32 below `x` (pbrt-v4 `NextFloatDown`), the mirror of [`next_float_up`].
#[inline]
pub fn next_float_down(x: f32) -> f32 {
    if x.is_nan() || x == f32::NEG_INFINITY {
        return x;
    }
    let x = if x == 0.0 { -0.0 } else { x };
    let bits = x.to_bits();
    f32::from_bits(if x <= 0.0 { bits + 1 } else { bits - 1 })
}

/// Move a reconstructed surface point off its surface by its own error bound, to the side
/// `n` points to (pbrt-v4 `OffsetRayOrigin`, PBR 4th ed. section 6.8.6).
///
/// * `p` is the computed point and `p_error` a bound on the absolute error of each of its
///   coordinates against the exact point on the triangle's plane
///   ([`crate::kernels::barycentric::position_error_bound`], the record's
///   `position_error`).
/// * `n` is the unit *geometric* normal oriented towards the side the new ray leaves from
///   (for a primary hit, the side the raster saw: `GBUF_BACK_FACE`; flip it for
///   transmission). A zero normal (degenerate triangle) leaves `p` where it is.
///
/// The point moves by `d = OFFSET_ERROR_SCALE * p_error * |n|_1` along `n`, which carries
/// it past the exact plane (see [`OFFSET_ERROR_SCALE`]); each moved coordinate is then
/// rounded one more f32 step away from the surface, so the rounding of `p + d n` cannot
/// bring it back. Rays from the result into that side start with `t_min = 0`; the
/// watertight test's conservative `t` rejects what is left of the triangle itself.
///
/// Unlike Wächter and Binder's fixed 256 ulps ([`offset_ray_origin_integer_ulps`]), the
/// offset follows the error: a few ulps of the coordinates (about 6 at 1e5 from the
/// origin, where 256 ulps are 2 units and jump into nearby geometry), and less near the
/// vertices of small triangles.
///
/// Operation order (the WGSL mirror `offset_ray_origin` keeps it, unfused):
/// `d = ((|n.x| + |n.y|) + |n.z|) * (p_error * OFFSET_ERROR_SCALE)`, then per coordinate
/// `o = p + n * d` and the step away.
#[inline]
pub fn offset_ray_origin(p: Vec3, p_error: f32, n: Vec3) -> Vec3 {
    let d = ((n.x.abs() + n.y.abs()) + n.z.abs()) * (p_error * OFFSET_ERROR_SCALE);
    let coordinate = |p: f32, n: f32| {
        let offset = n * d;
        let o = p + offset;
        if offset > 0.0 {
            next_float_up(o)
        } else if offset < 0.0 {
            next_float_down(o)
        } else {
            o
        }
    };
    Vec3::new(coordinate(p.x, n.x), coordinate(p.y, n.y), coordinate(p.z, n.z))
}

/// Below this magnitude a coordinate is offset by a fixed amount instead of in ulps
/// (Wächter and Binder 2019, "A Fast and Robust Method for Avoiding Self-Intersection",
/// Ray Tracing Gems ch. 6, listing 6-1: `origin()`), because ulps shrink towards zero.
pub const OFFSET_ORIGIN: f32 = 1.0 / 32.0;
/// Fixed offset per unit of normal near zero (Wächter and Binder, `float_scale()`).
pub const OFFSET_FLOAT_SCALE: f32 = 1.0 / 65536.0;
/// Offset in ulps per unit of normal away from zero (Wächter and Binder, `int_scale()`).
pub const OFFSET_INT_SCALE: f32 = 256.0;

/// One coordinate of [`offset_ray_origin_integer_ulps`].
#[inline]
fn offset_coordinate_integer_ulps(p: f32, n: f32) -> f32 {
    if p.abs() < OFFSET_ORIGIN {
        p + OFFSET_FLOAT_SCALE * n
    } else {
        // `as i32` truncates towards zero like the C original (and saturates; NaN -> 0).
        let of_i = (OFFSET_INT_SCALE * n) as i32;
        let step = if p < 0.0 { of_i.wrapping_neg() } else { of_i };
        f32::from_bits((p.to_bits() as i32).wrapping_add(step) as u32)
    }
}

/// Wächter and Binder's offset (Ray Tracing Gems ch. 6), the pipeline's until the
/// error-bound offset [`offset_ray_origin`] replaced it; kept as the comparison of the
/// speed-against-error report. Each coordinate moves by `OFFSET_INT_SCALE * n_i` ulps
/// (truncated to an integer), or by `OFFSET_FLOAT_SCALE * n_i` when `|p_i| <
/// OFFSET_ORIGIN`, whatever the point's actual error: 256 ulps grow with the coordinates
/// (2 units at 1e5), so near other geometry the origin can land behind it (light leaks
/// out of closed shells, the leak corpus of `hyrt-conformance`).
#[inline]
pub fn offset_ray_origin_integer_ulps(p: Vec3, n: Vec3) -> Vec3 {
    Vec3::new(
        offset_coordinate_integer_ulps(p.x, n.x),
        offset_coordinate_integer_ulps(p.y, n.y),
        offset_coordinate_integer_ulps(p.z, n.z),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gamma_matches_pbrt() {
        assert_eq!(MACHINE_EPSILON, 2f32.powi(-24));
        let g3 = gamma(3);
        assert!(g3 > 3.0 * MACHINE_EPSILON && g3 < 3.0001 * MACHINE_EPSILON);
        let far_scale = SLAB_FAR_SCALE;
        assert!(far_scale > 1.0 && far_scale < 1.0 + 4.0 * f32::EPSILON);
    }

    #[test]
    fn permutation_puts_largest_axis_last() {
        let v = Vec3::new(1.0, 2.0, 3.0);
        assert_eq!(permute_axes(v, 0), Vec3::new(2.0, 3.0, 1.0));
        assert_eq!(permute_axes(v, 1), Vec3::new(3.0, 1.0, 2.0));
        assert_eq!(permute_axes(v, 2), v);
        for kz in 0..3 {
            assert_eq!(permute_axes(v, kz).to_array(), permuted_axis_order(kz).map(|a| v[a]));
        }
        assert_eq!(max_component_index(Vec3::new(1.0, 1.0, 1.0)), 2);
        assert_eq!(max_component_index(Vec3::new(2.0, 2.0, 1.0)), 1);
        assert_eq!(max_component_index(Vec3::new(3.0, 2.0, 1.0)), 0);
    }

    #[test]
    fn edge_function_is_antisymmetric() {
        let a = Vec3::new(0.1, 0.7, 0.0);
        let b = Vec3::new(-0.3, 1.0 / 3.0, 0.0);
        assert_eq!(edge_function(a, b).to_bits(), (-edge_function(b, a)).to_bits());
    }

    #[test]
    fn integer_ulp_offset_moves_whole_ulps() {
        let p = Vec3::new(1.0, -2.0, 0.01);
        let o = offset_ray_origin_integer_ulps(p, Vec3::new(1.0, 0.0, 1.0));
        assert_eq!(o.x.to_bits(), 1.0f32.to_bits() + 256);
        assert_eq!(o.y, -2.0);
        assert_eq!(o.z, 0.01 + OFFSET_FLOAT_SCALE);
        let o = offset_ray_origin_integer_ulps(p, Vec3::new(0.0, 1.0, -1.0));
        // Towards +y from a negative coordinate: the magnitude shrinks by 256 ulps.
        assert_eq!(o.y.to_bits(), (-2.0f32).to_bits() - 256);
        assert_eq!(o.z, 0.01 - OFFSET_FLOAT_SCALE);
    }
}
