//! The `reconstruction` kernel over eight texels at once: core's `texel_surface` and
//! `surface_at` (in [`hyrt_core::kernels::reconstruction`]) with
//! [`reconstruct_position`], [`position_error_bound`], [`interpolate_normal`] and
//! [`orient_to_seen_side`], each lane doing the scalar kernels' operations in their order,
//! every one a correctly rounded IEEE 754 f32 operation or a bit operation ([`Lanes`]).
//! So each lane's record is the scalar kernel's, bit for bit (`tests` pins them).
//!
//! One case stays scalar: a lane whose interpolated and geometric normals are both zero (a
//! degenerate triangle without vertex normals) is shaded facing the viewer, which
//! [`SurfaceLanes8::viewer_facing`] reports for the caller to rebuild with the scalar
//! kernel.
//!
//! [`reconstruct_position`]: hyrt_core::kernels::barycentric::reconstruct_position
//! [`position_error_bound`]: hyrt_core::kernels::barycentric::position_error_bound
//! [`interpolate_normal`]: hyrt_core::kernels::barycentric::interpolate_normal
//! [`orient_to_seen_side`]: hyrt_core::kernels::shading::orient_to_seen_side

use hyrt_core::formats::{SurfaceRecord, INVALID_ID};
use hyrt_core::kernels::barycentric::gamma;
use hyrt_core::kernels::reconstruction::TriangleSetup;

use crate::lanes::{dot3, mask_lanes, Lanes, LANES};

// No closures around lane operations (`map`, `from_fn`): a closure does not inherit its
// caller's target features, so its lane operations would not inline into the AVX2 entry
// points.

/// Eight reconstructed surfaces as lanes.
#[derive(Clone, Copy)]
pub(crate) struct SurfaceLanes8<L: Lanes> {
    /// All ones where the texel is a hit.
    pub hit: L::F,
    pub position: [L::F; 3],
    pub position_error: L::F,
    pub normal: [L::F; 3],
    pub geometric_normal: [L::F; 3],
    /// Bit `k`: lane `k` is a hit whose shading normal is zero, to be rebuilt by the scalar
    /// kernel (it faces the viewer).
    pub viewer_facing: u32,
}

/// What the lanes read of a triangle's [`TriangleSetup`]: `[vertex][axis]`,
/// `[corner][axis]`, the geometric normal and the object's offset error.
struct SetupLanes<L: Lanes> {
    v: [[L::F; 3]; 3],
    n: [[L::F; 3]; 3],
    geometric: [L::F; 3],
    offset_error: L::F,
}

impl<L: Lanes> SetupLanes<L> {
    /// The lanes of eight setups: one splat where all lanes share a triangle (the usual
    /// block inside one triangle), else a transpose.
    #[inline(always)]
    fn of(setups: [&TriangleSetup; LANES]) -> SetupLanes<L> {
        let words = |s: &TriangleSetup| {
            let (t, n, g) = (s.record(), s.normals(), s.geometric());
            [
                t.v0[0],
                t.v0[1],
                t.v0[2],
                t.v1[0],
                t.v1[1],
                t.v1[2],
                t.v2[0],
                t.v2[1],
                t.v2[2],
                n[0].x,
                n[0].y,
                n[0].z,
                n[1].x,
                n[1].y,
                n[1].z,
                n[2].x,
                n[2].y,
                n[2].z,
                g.x,
                g.y,
                g.z,
                s.offset_error(),
            ]
        };
        let first = setups[0].index();
        let mut lanes = [L::splat(0.0); 22];
        if setups.iter().all(|s| s.index() == first) {
            for (lanes, x) in lanes.iter_mut().zip(words(setups[0])) {
                *lanes = L::splat(x);
            }
        } else {
            let mut w = [[0.0f32; LANES]; 22];
            for (k, s) in setups.iter().enumerate() {
                for (w, x) in w.iter_mut().zip(words(s)) {
                    w[k] = x;
                }
            }
            for (lanes, w) in lanes.iter_mut().zip(&w) {
                *lanes = L::load(w);
            }
        }
        SetupLanes::from_words(&lanes)
    }

    /// The setup lanes from their 22 words' lanes (in the order of `of`).
    #[inline(always)]
    fn from_words(word: &[L::F; 22]) -> SetupLanes<L> {
        let word = |i: usize| word[i];
        SetupLanes {
            v: [[word(0), word(1), word(2)], [word(3), word(4), word(5)], [word(6), word(7), word(8)]],
            n: [[word(9), word(10), word(11)], [word(12), word(13), word(14)], [word(15), word(16), word(17)]],
            geometric: [word(18), word(19), word(20)],
            offset_error: word(21),
        }
    }
}

/// `(w * a + u * b) + v * c`: one coordinate of core's `reconstruct_position` and
/// `interpolate_normal`.
#[inline(always)]
fn weighted<L: Lanes>(w: L::F, u: L::F, v: L::F, a: L::F, b: L::F, c: L::F) -> L::F {
    L::add(L::add(L::mul(w, a), L::mul(u, b)), L::mul(v, c))
}

/// One coordinate of core's `position_error_bound` for vertex coordinates `c`:
/// `(sum * gamma(3) + |c0| * (w_err * (1 + gamma(3)))) * (1 + gamma(3))` with
/// `sum = (|w c0| + |u c1|) + |v c2|`; `v0_factor` is `w_err * (1 + gamma(3))`.
#[inline(always)]
fn error_bound<L: Lanes>(w: L::F, u: L::F, v: L::F, c: [L::F; 3], g3: L::F, v0_factor: L::F, one_g3: L::F) -> L::F {
    let sum = L::add(L::add(L::abs(L::mul(w, c[0])), L::abs(L::mul(u, c[1]))), L::abs(L::mul(v, c[2])));
    L::mul(L::add(L::mul(sum, g3), L::mul(L::abs(c[0]), v0_factor)), one_g3)
}

/// Eight texels' surfaces: lane `k` is a hit where bit `k` of `hit` is set, on the
/// triangle of `setups[k]` (any setup for a miss) at barycentrics `(u[k], v[k])`, seen
/// from its back where bit `k` of `back` is set (the G-buffer's `GBUF_BACK_FACE`).
#[inline(always)]
pub(crate) fn surfaces_lanes<L: Lanes>(
    setups: [&TriangleSetup; LANES],
    hit: u32,
    back: u32,
    u: &[f32; LANES],
    v: &[f32; LANES],
) -> SurfaceLanes8<L> {
    let t = SetupLanes::<L>::of(setups);
    let (u, v) = (L::load(u), L::load(v));
    let zero = L::splat(0.0);
    // bary_w
    let w = L::sub(L::sub(L::splat(1.0), u), v);
    // reconstruct_position
    let p = [
        weighted::<L>(w, u, v, t.v[0][0], t.v[1][0], t.v[2][0]),
        weighted::<L>(w, u, v, t.v[0][1], t.v[1][1], t.v[2][1]),
        weighted::<L>(w, u, v, t.v[0][2], t.v[1][2], t.v[2][2]),
    ];
    // position_error_bound(..).max_element() + offset_error
    let (g2, g3) = (L::splat(gamma(2)), L::splat(gamma(3)));
    let one_g3 = L::splat(1.0 + gamma(3));
    let w_err = L::mul(g2, L::add(L::add(L::splat(1.0), L::abs(u)), L::abs(v)));
    let v0_factor = L::mul(w_err, one_g3);
    let ex = error_bound::<L>(w, u, v, [t.v[0][0], t.v[1][0], t.v[2][0]], g3, v0_factor, one_g3);
    let ey = error_bound::<L>(w, u, v, [t.v[0][1], t.v[1][1], t.v[2][1]], g3, v0_factor, one_g3);
    let ez = error_bound::<L>(w, u, v, [t.v[0][2], t.v[1][2], t.v[2][2]], g3, v0_factor, one_g3);
    let err = L::add(L::max(ex, L::max(ey, ez)), t.offset_error);
    // interpolate_normal(u, v, normals, geometric)
    let s = [
        weighted::<L>(w, u, v, t.n[0][0], t.n[1][0], t.n[2][0]),
        weighted::<L>(w, u, v, t.n[0][1], t.n[1][1], t.n[2][1]),
        weighted::<L>(w, u, v, t.n[0][2], t.n[1][2], t.n[2][2]),
    ];
    let len = L::sqrt(dot3::<L>(s, s));
    let unit = L::and(L::lt(zero, len), L::lt(len, L::splat(f32::INFINITY)));
    let ns = [
        L::select(unit, L::div(s[0], len), t.geometric[0]),
        L::select(unit, L::div(s[1], len), t.geometric[1]),
        L::select(unit, L::div(s[2], len), t.geometric[2]),
    ];
    // orient_to_seen_side: a sign flip of both where the back was seen.
    let flip = L::and(mask_lanes::<L>(back), L::splat(-0.0));
    let ng = [L::xor(t.geometric[0], flip), L::xor(t.geometric[1], flip), L::xor(t.geometric[2], flip)];
    let ns = [L::xor(ns[0], flip), L::xor(ns[1], flip), L::xor(ns[2], flip)];
    // A zero shading normal faces the viewer: left to the scalar kernel.
    let hit_mask = mask_lanes::<L>(hit);
    let ns_zero = L::and(L::and(L::eq(ns[0], zero), L::eq(ns[1], zero)), L::eq(ns[2], zero));
    let viewer_facing = L::bits(L::and(hit_mask, ns_zero));
    // Keep the shading normal in the geometric normal's hemisphere.
    let ng_zero = L::and(L::and(L::eq(ng[0], zero), L::eq(ng[1], zero)), L::eq(ng[2], zero));
    let use_ng = L::andnot(ng_zero, L::lt(dot3::<L>(ns, ng), zero));
    let ns = [L::select(use_ng, ng[0], ns[0]), L::select(use_ng, ng[1], ns[1]), L::select(use_ng, ng[2], ns[2])];
    SurfaceLanes8 { hit: hit_mask, position: p, position_error: err, normal: ns, geometric_normal: ng, viewer_facing }
}

impl<L: Lanes> SurfaceLanes8<L> {
    /// Lane `k`'s record ([`SurfaceRecord::MISS`] for a miss), its triangle from
    /// `setups[k]`. Meaningless for a lane of [`Self::viewer_facing`].
    ///
    /// The records are written by two transposes in registers ([`Lanes::transpose8`]):
    /// words 0 to 7 (position, error bound, normal, object) and 8 to 11 (geometric normal,
    /// triangle), each lane's floats masked to its hit (a miss's are `+0`, as in
    /// [`SurfaceRecord::MISS`]). It replaced a record built field by field from the lanes
    /// stored to arrays.
    #[inline(always)]
    pub fn records(&self, setups: [&TriangleSetup; LANES]) -> [SurfaceRecord; LANES] {
        let (h, hit) = (self.hit, L::bits(self.hit));
        let mut ids = [[f32::from_bits(INVALID_ID); LANES]; 2];
        for k in 0..LANES {
            if hit >> k & 1 != 0 {
                ids[0][k] = f32::from_bits(setups[k].record().object);
                ids[1][k] = f32::from_bits(setups[k].index() as u32);
            }
        }
        let (p, n, g, zero) = (&self.position, &self.normal, &self.geometric_normal, L::splat(0.0));
        let first = L::transpose8([
            L::and(h, p[0]),
            L::and(h, p[1]),
            L::and(h, p[2]),
            L::and(h, self.position_error),
            L::and(h, n[0]),
            L::and(h, n[1]),
            L::and(h, n[2]),
            L::load(&ids[0]),
        ]);
        let last = L::transpose8([
            L::and(h, g[0]),
            L::and(h, g[1]),
            L::and(h, g[2]),
            L::load(&ids[1]),
            zero,
            zero,
            zero,
            zero,
        ]);
        let mut out = [SurfaceRecord::MISS; LANES];
        for (k, record) in out.iter_mut().enumerate() {
            let words: &mut [f32; 12] = bytemuck::cast_mut(record);
            let (a, b) = (L::store(first[k]), L::store(last[k]));
            words[..8].copy_from_slice(&a);
            words[8..].copy_from_slice(&b[..4]);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lanes::Portable;
    use glam::Mat4;
    use glam::Vec3;
    use hyrt_core::formats::CameraRecord;
    use hyrt_core::formats::{GBufferTexel, GBUF_BACK_FACE, GBUF_HIT};
    use hyrt_core::geometry::WorldGeometry;
    use hyrt_core::kernels::reconstruction::reconstruct_texel;
    use hyrt_core::scene::{Camera, Material, Mesh, RenderMode, Scene};

    use crate::reconstruction::{BlockSetups, Reconstruct};
    use proptest::prelude::*;

    fn check<L: Lanes>(g: &WorldGeometry, texels: &[GBufferTexel; LANES], eye: Vec3) -> Result<(), TestCaseError> {
        let setups: Vec<TriangleSetup> = texels
            .iter()
            .map(|t| TriangleSetup::new(g, if t.is_hit() { g.global_triangle(t.object, t.triangle) } else { 0 }))
            .collect();
        let setups: [&TriangleSetup; LANES] = std::array::from_fn(|k| &setups[k]);
        let mut hit = 0;
        let mut back = 0;
        for (k, t) in texels.iter().enumerate() {
            hit |= (t.is_hit() as u32) << k;
            back |= ((t.flags & GBUF_BACK_FACE != 0) as u32) << k;
        }
        let u = texels.map(|t| t.bary_u);
        let v = texels.map(|t| t.bary_v);
        let lanes = surfaces_lanes::<L>(setups, hit, back, &u, &v);
        let got = lanes.records(setups);
        for (k, t) in texels.iter().enumerate() {
            let want = reconstruct_texel(t, g, eye);
            if lanes.viewer_facing >> k & 1 == 1 {
                prop_assert!(want.is_hit());
                continue;
            }
            same_record(k, &got[k], &want)?;
        }
        Ok(())
    }

    /// Lane `k`'s record is the scalar kernel's, bit for bit.
    fn same_record(k: usize, got: &SurfaceRecord, want: &SurfaceRecord) -> Result<(), TestCaseError> {
        prop_assert_eq!(bytemuck::bytes_of(got), bytemuck::bytes_of(want), "lane {}: {:?} vs {:?}", k, got, want);
        Ok(())
    }

    fn check_levels(g: &WorldGeometry, texels: &[GBufferTexel; LANES], eye: Vec3) -> Result<(), TestCaseError> {
        check::<Portable>(g, texels, eye)?;
        #[cfg(target_arch = "x86_64")]
        {
            check::<crate::lanes::Sse2>(g, texels, eye)?;
            if is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 detected just above.
                unsafe { check_avx2(g, texels, eye)? };
            }
        }
        Ok(())
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn check_avx2(g: &WorldGeometry, texels: &[GBufferTexel; LANES], eye: Vec3) -> Result<(), TestCaseError> {
        check::<crate::lanes::Avx2>(g, texels, eye)
    }

    /// Coordinates of every kind: ordinary, zero of either sign, tiny, far from the origin.
    fn coord() -> impl Strategy<Value = f32> {
        prop_oneof![
            6 => -10.0f32..10.0,
            1 => Just(0.0f32),
            1 => Just(-0.0f32),
            1 => -1e-6f32..1e-6,
            1 => -1e6f32..1e6,
        ]
    }

    fn vec3() -> impl Strategy<Value = Vec3> {
        (coord(), coord(), coord()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    /// Six vertices with four triangles (one of them degenerate: a repeated vertex), with
    /// no normals, random ones, or normals that cancel (opposite at two corners), placed
    /// by a random transform, stored in world space or by reference (its offset error).
    fn scene() -> impl Strategy<Value = (WorldGeometry, usize)> {
        let normals = prop_oneof![
            1 => Just(None),
            2 => prop::collection::vec(vec3(), 6).prop_map(Some),
            1 => vec3().prop_map(|n| Some(vec![n, -n, n, -n, Vec3::ZERO, n])),
        ];
        (prop::collection::vec(vec3(), 6), normals, vec3(), -3.0f32..3.0, any::<bool>()).prop_map(
            |(positions, normals, shift, scale, by_reference)| {
                let indices = vec![[0, 1, 2], [3, 4, 5], [0, 2, 4], [1, 1, 3]];
                let mesh = Mesh { name: "m".into(), positions, normals, indices, ..Default::default() };
                let mut scene = Scene::default();
                let place = Mat4::from_scale_rotation_translation(
                    Vec3::splat(scale),
                    glam::Quat::from_rotation_y(scale),
                    shift,
                );
                scene.add_object(mesh, Material::grey(), place, RenderMode::RayTraced);
                (WorldGeometry::build_placed(&scene, &[by_reference]), 4)
            },
        )
    }

    /// A texel: a miss, or a hit on one of `triangles` at barycentrics in and around
    /// the triangle (the raster's are within a few ulps of it), either facing.
    fn texel(triangles: usize) -> impl Strategy<Value = GBufferTexel> {
        let bary = prop_oneof![4 => 0.0f32..=1.0, 1 => Just(0.0f32), 1 => Just(1.0f32), 1 => -1e-6f32..1e-6];
        (any::<bool>(), 0..triangles as u32, bary.clone(), bary, any::<bool>()).prop_map(|(hit, tri, u, v, back)| {
            if !hit {
                return GBufferTexel::MISS;
            }
            let flags = GBUF_HIT | if back { GBUF_BACK_FACE } else { 0 };
            GBufferTexel { bary_u: u, bary_v: v, depth: 0.5, triangle: tri, object: 0, flags }
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(1024))]

        #[test]
        fn reconstruction_lanes_are_the_scalar_kernel(
            (g, n) in scene(),
            texels in prop::collection::vec(texel(4), LANES),
            same in any::<bool>(),
            eye in vec3(),
        ) {
            // (A vector, not `uniform8`: eight nested value trees overflow a test thread's stack.)
            let mut texels: [GBufferTexel; LANES] = texels.try_into().expect("LANES texels");
            prop_assume!(n == 4);
            if same {
                // The usual block: every lane on one triangle (the splat path).
                let triangle = texels[0].triangle.min(n as u32 - 1);
                for t in texels.iter_mut().filter(|t| t.is_hit()) {
                    t.triangle = triangle;
                }
            }
            check_levels(&g, &texels, eye)?;
        }
    }

    /// [`Reconstruct::block`] with re-intersection: each lane's camera ray against its
    /// triangle in lanes ([`crate::traversal::intersect_each`]), against the scalar kernel.
    fn check_reintersected<L: Lanes>(
        g: &WorldGeometry,
        camera: &CameraRecord,
        texels: &[GBufferTexel; LANES],
        xy: [(u32, u32); LANES],
    ) -> Result<(), TestCaseError> {
        let r = Reconstruct::Reintersected(camera);
        let got = r.block::<L>(std::array::from_fn(|k| &texels[k]), xy, g, &mut BlockSetups::default());
        for (k, t) in texels.iter().enumerate() {
            let want = r.pixel(t, g, xy[k].0, xy[k].1, &mut None);
            same_record(k, &got[k], &want)?;
        }
        Ok(())
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn check_reintersected_avx2(
        g: &WorldGeometry,
        camera: &CameraRecord,
        texels: &[GBufferTexel; LANES],
        xy: [(u32, u32); LANES],
    ) -> Result<(), TestCaseError> {
        check_reintersected::<crate::lanes::Avx2>(g, camera, texels, xy)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(1024))]

        #[test]
        fn reintersected_block_is_the_scalar_kernel(
            (g, n) in scene(),
            texels in prop::collection::vec(texel(4), LANES),
            (toward, distance) in (vec3(), 0.5f32..50.0),
            pixels in prop::collection::vec((5u32..11, 5u32..11), LANES),
            target_triangle in 0usize..4,
        ) {
            prop_assume!(n == 4);
            let texels: [GBufferTexel; LANES] = texels.try_into().expect("LANES texels");
            // A 16x16 camera looking at a triangle's centroid: the middle pixels' rays
            // meet it (and its neighbours) often.
            let [a, b, c] = g.triangle(target_triangle).vertices();
            let target = (a + b + c) / 3.0;
            let eye = target + toward.normalize_or(Vec3::X) * distance;
            prop_assume!(eye.is_finite() && (target - eye).length() > 0.25 && (eye - target).normalize().dot(Vec3::Y).abs() < 0.99);
            let near = distance * 1e-3;
            let camera = Camera { eye, target, up: Vec3::Y, fov_y_deg: 20.0, near, far: distance * 1e3 };
            let camera = CameraRecord::new(&camera, 16, 16);
            let xy: [(u32, u32); LANES] = std::array::from_fn(|k| pixels[k]);
            check_reintersected::<Portable>(&g, &camera, &texels, xy)?;
            #[cfg(target_arch = "x86_64")]
            {
                check_reintersected::<crate::lanes::Sse2>(&g, &camera, &texels, xy)?;
                if is_x86_feature_detected!("avx2") {
                    // SAFETY: AVX2 detected just above.
                    unsafe { check_reintersected_avx2(&g, &camera, &texels, xy)? };
                }
            }
        }
    }
}
