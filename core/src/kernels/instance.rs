//! Instances: the kernels of the two-level BVH ([`crate::bvh::two_level`]), whose bottom
//! levels hold each mesh's triangles in its own (object) space and whose top level holds
//! the instances' world boxes.
//!
//! A ray reaching an instance in the top level is moved into the instance's object space
//! ([`to_object_space`]) and traced through the mesh's bottom level there. An affine map
//! keeps the ray parameter: the world point `o + t d` maps to `M o + t (L d)` (L the
//! linear part of M), so `t` found in object space is the world `t` up to the rounding of
//! the map, and hits in different instances compare by `t` directly. Inside one instance
//! every triangle is tested against the same object-space ray with the watertight test,
//! so a closed mesh stays closed however it is scaled, rotated or mirrored.
//!
//! Rounding is paid in two places, both bounded here:
//!
//! * The top level must not cull an instance a ray hits in object space: the instance's
//!   world box is the image of its bottom-level box widened by [`instance_box_margin`].
//! * A ray leaving an instance's surface must not hit that surface again: the world point
//!   it leaves from was rebuilt from the world triangle (the object's vertices mapped to
//!   world space and rounded), and its origin is mapped back by the rounded inverse. The
//!   extra distance this puts between the origin and the object-space triangle is bounded
//!   by [`instance_position_error`], added to the point's own error bound before the
//!   origin is offset ([`crate::kernels::ray::offset_ray_origin`]). Objects baked into
//!   world space (no transform at trace time) add nothing.

use glam::{DVec3, Mat4, Vec3};

use crate::kernels::ray::gamma;

/// The map type and the identity, defined with [`crate::formats::InstanceRecord`], whose
/// rows they are; re-exported here beside the kernels that make and apply maps.
pub use crate::formats::{ObjectMap, MAP_IDENTITY};

/// The largest condition number `||A||_inf * ||A^-1||_inf` of an object's linear part `A`
/// the two-level BVH maps: 2^16. The inverse is computed in f64 and rounded to f32, so its
/// entries carry one f32 rounding (the f64 error, about `2^-52` times the condition
/// number, stays under `2^-36` of them); and the bounds below scale with the condition
/// number, so a nearly singular transform would make every offset huge. Objects past it
/// (and singular ones) are baked into world space instead.
pub const MAX_INSTANCE_CONDITION: f64 = 65536.0;

/// The world-to-object map of an object whose object-to-world transform is
/// `object_to_world` ([`ObjectMap`]). `None` when the transform is not finite, not affine
/// (its fourth row is not `0 0 0 1`), singular, or worse conditioned than
/// [`MAX_INSTANCE_CONDITION`].
pub fn world_to_object(object_to_world: Mat4) -> Option<ObjectMap> {
    let m = object_to_world.as_dmat4();
    if !object_to_world.is_finite() || m.row(3) != glam::DVec4::W {
        return None;
    }
    let a = glam::DMat3::from_mat4(m);
    let inv = a.inverse();
    let (na, ni) = (mat3_norm(&a), mat3_norm(&inv));
    if !(inv.is_finite() && na > 0.0 && ni > 0.0 && na * ni <= MAX_INSTANCE_CONDITION) {
        return None;
    }
    let l = inv.as_mat3();
    let t = object_to_world.w_axis;
    let row = |i: usize| [l.col(0)[i], l.col(1)[i], l.col(2)[i], t[i]];
    Some([row(0), row(1), row(2)])
}

/// `||A||_inf` (largest row sum of absolute values) of a 3x3 matrix.
fn mat3_norm(a: &glam::DMat3) -> f64 {
    (0..3).map(|i| a.row(i).abs().element_sum()).fold(0.0, f64::max)
}

/// A ray moved into an instance's object space by its map `m` ([`ObjectMap`]):
/// `(L (origin - t), L dir)`, in f32.
///
/// Operation order (the WGSL mirror `to_object_space` keeps it, unfused):
/// `q = origin - t` per coordinate, then per row `i`
/// `origin'_i = (l_i0 * q.x + l_i1 * q.y) + l_i2 * q.z` and
/// `dir'_i = (l_i0 * d.x + l_i1 * d.y) + l_i2 * d.z`. The direction is not normalized,
/// so the ray parameter `t` means the same point in both spaces.
#[inline]
pub fn to_object_space(m: &ObjectMap, origin: Vec3, dir: Vec3) -> (Vec3, Vec3) {
    let q = Vec3::new(origin.x - m[0][3], origin.y - m[1][3], origin.z - m[2][3]);
    let apply = |r: &[f32; 4], v: Vec3| (r[0] * v.x + r[1] * v.y) + r[2] * v.z;
    (
        Vec3::new(apply(&m[0], q), apply(&m[1], q), apply(&m[2], q)),
        Vec3::new(apply(&m[0], dir), apply(&m[1], dir), apply(&m[2], dir)),
    )
}

/// `|| |A| |L| ||_inf`: the infinity norm of the product of the absolute values of the
/// object-to-world linear part `A` and the map's `L`, in f64. It carries an object-space
/// error bound (per coordinate) back to world space, and is 1 for any map without a
/// rotation (scales and mirrors), at most the condition number otherwise.
fn map_round_trip(object_to_world: Mat4, map: &ObjectMap) -> f64 {
    let a = glam::DMat3::from_mat4(object_to_world.as_dmat4());
    let l = glam::DMat3::from_cols_array_2d(&[
        [map[0][0] as f64, map[1][0] as f64, map[2][0] as f64],
        [map[0][1] as f64, map[1][1] as f64, map[2][1] as f64],
        [map[0][2] as f64, map[1][2] as f64, map[2][2] as f64],
    ]);
    let abs = |m: glam::DMat3| glam::DMat3::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs());
    mat3_norm(&(abs(a) * abs(l)))
}

/// The absolute margin by which an instance's world box (the exact image of its bottom
/// level's box) is widened so that the top level never culls an instance a ray hits in
/// object space.
///
/// The object-space ray's point at `t` differs from the exact image of the world ray's
/// point by the rounding of [`to_object_space`] and of `L`'s entries: per coordinate at
/// most `gamma(5) |L| |origin - t|` from the origin (a subtraction, then a product and
/// two sums, one more rounding for the entries) and `gamma(4) |L| t |dir|` from the
/// direction. Rays start inside the scene (on surfaces; `|origin| <= scene_magnitude`,
/// the largest absolute world coordinate of the scene) and a hit lies in the scene too,
/// so both together are at most `gamma(5) |L| (3 scene_magnitude + |t|)`; mapped back to
/// world space by `|A|` (`map_round_trip`). Evaluated in f64 with `gamma(8)` for the
/// evaluation's own rounding, and rounded up to f32.
pub fn instance_box_margin(map: &ObjectMap, object_to_world: Mat4, scene_magnitude: f32) -> f32 {
    let t = object_to_world.w_axis.truncate().abs().max_element() as f64;
    round_up(map_round_trip(object_to_world, map) * gamma(8) as f64 * (3.0 * scene_magnitude as f64 + t))
}

/// The world box of an instance: the bottom level's object box `(lo, hi)` mapped by
/// `object_to_world` (all eight corners, in f64), widened by `margin`
/// ([`instance_box_margin`]) and rounded outward to f32.
pub fn instance_world_box(object_to_world: Mat4, lo: Vec3, hi: Vec3, margin: f32) -> (Vec3, Vec3) {
    let m = object_to_world.as_dmat4();
    let (mut wlo, mut whi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for c in box_corners(lo, hi) {
        let w = m.transform_point3(c);
        wlo = wlo.min(w);
        whi = whi.max(w);
    }
    let margin = margin as f64;
    (
        Vec3::new(round_down(wlo.x - margin), round_down(wlo.y - margin), round_down(wlo.z - margin)),
        Vec3::new(round_up(whi.x + margin), round_up(whi.y + margin), round_up(whi.z + margin)),
    )
}

/// The eight corners of a box, in f64.
fn box_corners(lo: Vec3, hi: Vec3) -> impl Iterator<Item = DVec3> {
    (0..8).map(move |k| {
        DVec3::new(
            if k & 1 == 0 { lo.x } else { hi.x } as f64,
            if k & 2 == 0 { lo.y } else { hi.y } as f64,
            if k & 4 == 0 { lo.z } else { hi.z } as f64,
        )
    })
}

/// Extra absolute error, per world coordinate, of a point rebuilt on an instance's world
/// triangles when the ray leaving it is traced in the instance's object space: added to
/// the point's own bound ([`crate::kernels::barycentric::position_error_bound`]) before
/// the origin is offset ([`crate::kernels::ray::offset_ray_origin`]), it keeps the origin
/// on the right side of the object-space triangle it left. `(lo, hi)` is the object-space
/// box of the instance's mesh.
///
/// The offset moves the origin out of a box of the bound's half-width around the point,
/// along the world normal, so any world-space displacement within that box leaves it on
/// the right side; and the object-to-world map is linear, so the origin is on the right
/// side of the object-space triangle exactly when its exact world image is on the right
/// side of the exact image of that triangle. Two errors separate them beyond the point's
/// own, both bounded per world coordinate:
///
/// * The world triangle's vertices are within `e_v = gamma(4) (||A|| V + |t|)` of the
///   exact images of the object's (`A` the object-to-world linear part, `t` its
///   translation, `V` the largest object coordinate; a product and three sums).
/// * The map's rounding puts the object-space origin within `gamma(5) |L| |origin - t|`
///   per coordinate of the exact one ([`instance_box_margin`]), which is the image of a
///   world displacement within `gamma(5) |A| |L| |origin - t|`. The origin lies on the
///   object plus its offset: `|origin - t| <= R + 3 (e_p + E)` with `R` the largest
///   `|A c|` over the object box's corners, `e_p <= gamma(32) W` the point's own bound
///   (about 15 roundings of barycentric weights near 1; `W` the largest world coordinate)
///   and `E` this bound.
///
/// So `E = e_v + gamma(5) k (R + 3 gamma(32) W + 3 E)` with `k = map_round_trip`, solved
/// for `E` (the factor `1 - 3 gamma(5) k` is above 0.9 for any map under
/// [`MAX_INSTANCE_CONDITION`]). Evaluated in f64 with `gamma(6)` for `gamma(5)` and rounded
/// up. Zero-cost where it matters: a scaled or mirrored object without rotation has
/// `k = 1`, so the bound is a few ulps of its own size and of its translation.
pub fn instance_position_error(object_to_world: Mat4, map: &ObjectMap, lo: Vec3, hi: Vec3) -> f32 {
    let m = object_to_world.as_dmat4();
    let linear = glam::DMat3::from_mat4(m);
    let a = mat3_norm(&linear);
    let t = m.w_axis.truncate().abs().max_element();
    let v = lo.abs().max(hi.abs()).max_element() as f64;
    let r = box_corners(lo, hi).map(|c| (linear * c).abs().max_element()).fold(0.0, f64::max);
    let w = r + t;
    let g = |n: i32| gamma(n) as f64;
    let k = map_round_trip(object_to_world, map);
    let e_v = g(4) * (a * v + t);
    let e = (e_v + g(6) * k * (r + 3.0 * g(32) * w)) / (1.0 - 3.0 * g(6) * k);
    round_up(e)
}

/// `x` rounded to an f32 no smaller than it (`+inf` past the f32 range).
fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        f.next_up()
    } else {
        f
    }
}

/// `x` rounded to an f32 no larger than it.
fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) > x {
        f.next_down()
    } else {
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    #[test]
    fn world_to_object_inverts_and_refuses_singular_maps() {
        let o2w = Mat4::from_scale_rotation_translation(
            Vec3::new(2.0, 0.5, 3.0),
            Quat::from_rotation_y(0.7),
            Vec3::new(1.0, -2.0, 5.0),
        );
        let m = world_to_object(o2w).unwrap();
        let p = Vec3::new(0.3, -1.2, 4.0);
        let (back, _) = to_object_space(&m, o2w.transform_point3(p), Vec3::X);
        assert!((back - p).abs().max_element() < 1e-5, "{back} vs {p}");
        assert!(world_to_object(Mat4::from_scale(Vec3::new(1.0, 0.0, 1.0))).is_none());
        assert!(world_to_object(Mat4::from_scale(Vec3::new(1.0, 1e-6, 1.0))).is_none(), "ill-conditioned");
        let mut projective = Mat4::IDENTITY;
        projective.x_axis.w = 0.5;
        assert!(world_to_object(projective).is_none());
        assert_eq!(world_to_object(Mat4::IDENTITY), Some(MAP_IDENTITY));
    }

    #[test]
    fn to_object_space_keeps_the_ray_parameter() {
        let o2w = Mat4::from_scale_rotation_translation(Vec3::splat(4.0), Quat::from_rotation_z(1.1), Vec3::ONE);
        let m = world_to_object(o2w).unwrap();
        let (o, d) = (Vec3::new(1.0, 2.0, 3.0), Vec3::new(-0.5, 0.25, 1.0));
        let (oo, od) = to_object_space(&m, o, d);
        let t = 3.5;
        let world = o2w.transform_point3(oo + t * od);
        assert!((world - (o + t * d)).abs().max_element() < 1e-5);
    }

    #[test]
    fn rounding_helpers_round_outward() {
        let x = 0.1f64;
        assert!(round_up(x) as f64 >= x && round_down(x) as f64 <= x);
        assert_eq!(round_up(1.0), 1.0);
        assert_eq!(round_up(1e300), f32::INFINITY);
    }
}
