//! Sampling kernels for stochastic rays (issue 38: soft shadows from area lights, ambient
//! occlusion): a deterministic low-discrepancy sequence decorrelated per pixel, and the
//! warps that turn its points into directions and points on lights.
//!
//! # The sequence
//!
//! Sample `s` of stream `seed` is point `s` of a 2D Sobol' sequence (van der Corput in the
//! first dimension, Sobol's second dimension) after Owen scrambling, in the hash-based form
//! of Burley, "Practical Hash-based Owen Scrambling" (JCGT 9(4), 2020), with Vegdahl's
//! improved Laine-Karras permutation ([`laine_karras_permutation`]):
//!
//! * the index is scrambled first ([`nested_uniform_scramble`] of `s`), so that different
//!   streams visit the net's points in different orders (Burley's shuffling);
//! * each dimension is scrambled with a seed of its own.
//!
//! Owen scrambling keeps the Sobol' points' stratification: every prefix of `2^m` samples
//! of a stream has exactly one point in each of the `2^m` elementary intervals of any
//! shape (a (0, m, 2)-net: its tests check it), while different streams are independent
//! random scramblings (decorrelated between pixels, lights and frames:
//! [`sample_seed`]). Everything is integer arithmetic modulo 2^32 and one exact conversion
//! to f32 ([`unit_f32`]), so the GPU's twin gives the same bits.
//!
//! # The warps
//!
//! [`concentric_disk`] (Shirley and Chiu's map, with the angle kept within
//! `[-pi/4, pi/4]` so that [`sin_cos_quarter`]'s polynomials serve), [`cosine_hemisphere`]
//! (Malley's method over it), [`uniform_cone`] (the disk's radius squared as `1 - cos`, no
//! trigonometry), [`orthonormal_basis`] (Duff et al. 2017) and [`quad_point`]. Every step is
//! a correctly rounded operation (`+ - * /`, `sqrt`, comparisons) in a stated order; no
//! platform `sin`, `cos` or `powf`.
//!
//! WGSL mirrors will come with the stages that trace these rays, by the same names.

use glam::Vec3;

/// Chris Wellons's `lowbias32` integer hash (two multiply-xorshift rounds; bias 0.17 in
/// his measure): the seeds of [`sample_seed`] and of each scrambled dimension.
#[inline]
pub fn hash_u32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// Boost's `hash_combine` over [`hash_u32`]: a new seed from `seed` and `value`.
#[inline]
pub fn hash_combine(seed: u32, value: u32) -> u32 {
    seed ^ hash_u32(value).wrapping_add(0x9e37_79b9).wrapping_add(seed << 6).wrapping_add(seed >> 2)
}

/// The seed of the sample stream of `pixel`, `stream` (a light, or the ambient occlusion)
/// and `frame`: independent streams for every pixel, light and frame, the same on every
/// backend and thread count.
#[inline]
pub fn sample_seed(pixel: u32, stream: u32, frame: u32) -> u32 {
    hash_combine(hash_combine(hash_u32(pixel), stream), frame)
}

/// The Laine-Karras permutation with Nathan Vegdahl's constants (Burley 2020, section 4,
/// as revised by Vegdahl, "Building a better LK hash", 2021): a bijection of `u32` whose
/// output bit `k` depends only on input bits `0..=k` (additions and products carry
/// upwards only). Applied to a bit-reversed fraction ([`nested_uniform_scramble`]) it
/// permutes each binary digit by a function of the digits before it: Owen's nested
/// scrambling.
#[inline]
pub fn laine_karras_permutation(mut x: u32, seed: u32) -> u32 {
    x ^= x.wrapping_mul(0x3d20_adea);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 16) | 1);
    x ^= x.wrapping_mul(0x0552_6c56);
    x ^= x.wrapping_mul(0x53a2_2864);
    x
}

/// Owen's nested uniform scrambling of the 32-bit fraction `x` (its bit 31 the first
/// binary digit) with `seed`: [`laine_karras_permutation`] of the reversed bits.
#[inline]
pub fn nested_uniform_scramble(x: u32, seed: u32) -> u32 {
    laine_karras_permutation(x.reverse_bits(), seed).reverse_bits()
}

/// Direction number `k` (0-based) of Sobol's second dimension: `v_0 = 1/2`,
/// `v_(k+1) = v_k xor (v_k / 2)` (`0.1, 0.11, 0.101, 0.1111, 0.10001, ...` in binary),
/// as a 32-bit fraction.
pub const fn sobol_direction(k: u32) -> u32 {
    let mut v = 1u32 << 31;
    let mut i = 0;
    while i < k {
        v ^= v >> 1;
        i += 1;
    }
    v
}

/// Sobol's second dimension a byte at a time: `SOBOL_BYTES[b][x]` is the xor of the
/// direction numbers `8 b + j` over the set bits `j` of `x`. The dimension is linear over
/// xor in the index's bits, so [`sobol_2d`] is the xor of four lookups, the same bits as
/// the loop over the index's bits that defines it (and that the WGSL twin runs; the tests
/// check every direction number).
const SOBOL_BYTES: [[u32; 256]; 4] = {
    let mut t = [[0u32; 256]; 4];
    let mut b = 0;
    while b < 4 {
        let mut x = 0;
        while x < 256 {
            let mut y = 0u32;
            let mut j = 0;
            while j < 8 {
                if x & (1 << j) != 0 {
                    y ^= sobol_direction(8 * b as u32 + j);
                }
                j += 1;
            }
            t[b][x] = y;
            x += 1;
        }
        b += 1;
    }
    t
};

/// Point `index` of the first two dimensions of the Sobol' sequence, as 32-bit fractions:
/// the van der Corput sequence (the reversed bits) and Sobol's second dimension, the xor
/// of the direction numbers ([`sobol_direction`]) of the index's set bits (by bytes,
/// `SOBOL_BYTES`).
#[inline]
pub fn sobol_2d(index: u32) -> [u32; 2] {
    let [b0, b1, b2, b3] = index.to_le_bytes();
    let y = SOBOL_BYTES[0][b0 as usize]
        ^ SOBOL_BYTES[1][b1 as usize]
        ^ SOBOL_BYTES[2][b2 as usize]
        ^ SOBOL_BYTES[3][b3 as usize];
    [index.reverse_bits(), y]
}

/// A 32-bit fraction as an f32 in `[0, 1)`: its top 24 bits times `2^-24`, exact.
#[inline]
pub fn unit_f32(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Sample `index` of the stream `seed` ([`sample_seed`]) in `[0, 1)^2`: the shuffled,
/// Owen-scrambled Sobol' point of the module docs.
#[inline]
pub fn sample_2d(index: u32, seed: u32) -> [f32; 2] {
    let shuffled = nested_uniform_scramble(index, hash_combine(seed, 0));
    let [x, y] = sobol_2d(shuffled);
    [
        unit_f32(nested_uniform_scramble(x, hash_combine(seed, 1))),
        unit_f32(nested_uniform_scramble(y, hash_combine(seed, 2))),
    ]
}

/// Coefficients `(-1)^k / (2k + 1)!`, k = 5..0, of `sin(x) / x` in [`sin_cos_quarter`]
/// (Horner order in `x^2`). For `|x| <= pi/4` the first omitted term, `x^12 / 13!`, is below
/// `1e-11`: far under the f32 rounding.
pub const SIN_SERIES: [f32; 6] = [-1.0 / 39_916_800.0, 1.0 / 362_880.0, -1.0 / 5040.0, 1.0 / 120.0, -1.0 / 6.0, 1.0];
/// Coefficients `(-1)^k / (2k)!`, k = 5..0, of `cos(x)` in [`sin_cos_quarter`]; the first
/// omitted term, `x^12 / 12!`, is below `1e-10` for `|x| <= pi/4`.
pub const COS_SERIES: [f32; 6] = [-1.0 / 3_628_800.0, 1.0 / 40_320.0, -1.0 / 720.0, 1.0 / 24.0, -0.5, 1.0];

/// Largest error of [`sin_cos_quarter`] against the exact sine and cosine, for
/// `|x| <= pi/4`: a few f32 roundings of values below 1 (each at most 2^-25) through the
/// Horner steps, 2^-22 with room; the tests hold every run to it.
pub const SIN_COS_MAX_ERROR: f32 = 1.0 / (1u32 << 22) as f32;

/// `(sin x, cos x)` for `|x| <= pi/4` by their Taylor series ([`SIN_SERIES`],
/// [`COS_SERIES`]) in Horner form: correctly rounded operations in a stated order, the same
/// bits on every backend (platform and WGSL `sin` and `cos` differ in the last bits). Larger
/// `|x|` is the caller's error (the error grows). Error at most [`SIN_COS_MAX_ERROR`].
#[inline]
pub fn sin_cos_quarter(x: f32) -> (f32, f32) {
    let x2 = x * x;
    let mut s = SIN_SERIES[0];
    for c in &SIN_SERIES[1..] {
        s = s * x2 + c;
    }
    let mut c = COS_SERIES[0];
    for k in &COS_SERIES[1..] {
        c = c * x2 + k;
    }
    (x * s, c)
}

/// Shirley and Chiu's concentric map of `[0, 1)^2` onto the unit disk (area-preserving,
/// continuous, low distortion): `(a, b) = 2u - 1`; where `|a| > |b|` the radius is `a` and
/// the angle `(pi/4)(b/a)`, else the radius is `b` and the angle `pi/2 - (pi/4)(a/b)`, whose
/// cosine and sine are the sine and cosine of `(pi/4)(a/b)`. The centre maps to 0.
#[inline]
pub fn concentric_disk([u, v]: [f32; 2]) -> [f32; 2] {
    let a = 2.0 * u - 1.0;
    let b = 2.0 * v - 1.0;
    if a == 0.0 && b == 0.0 {
        return [0.0, 0.0];
    }
    if a.abs() > b.abs() {
        let (s, c) = sin_cos_quarter(std::f32::consts::FRAC_PI_4 * (b / a));
        [a * c, a * s]
    } else {
        let (s, c) = sin_cos_quarter(std::f32::consts::FRAC_PI_4 * (a / b));
        [b * s, b * c]
    }
}

/// A direction around +Z with density `cos(theta) / pi` (Malley's method: the
/// [`concentric_disk`] point lifted to the hemisphere), `z >= 0`; unit up to roundings.
#[inline]
pub fn cosine_hemisphere(u: [f32; 2]) -> Vec3 {
    let [x, y] = concentric_disk(u);
    let z = (1.0 - x * x - y * y).max(0.0).sqrt();
    Vec3::new(x, y, z)
}

/// A direction around +Z, uniform in solid angle within the cone of `1 - cos(half angle)
/// = one_minus_cos_max` (in `[0, 2]`; small for a sun or a far sphere, exact where a
/// cosine near 1 would round): the [`concentric_disk`] point of radius `r` and direction
/// `(dx, dy) / r` gives `1 - cos(theta) = r^2 one_minus_cos_max` (uniform in `r^2`, so in
/// solid angle) and `sin(theta) = sqrt(k (2 - k))` with `k = 1 - cos(theta)`, without
/// trigonometry. The centre is +Z.
#[inline]
pub fn uniform_cone(u: [f32; 2], one_minus_cos_max: f32) -> Vec3 {
    let [x, y] = concentric_disk(u);
    let r2 = x * x + y * y;
    if r2 == 0.0 {
        return Vec3::Z;
    }
    let k = r2 * one_minus_cos_max;
    let sin_theta = (k * (2.0 - k)).max(0.0).sqrt();
    let scale = sin_theta / r2.sqrt();
    Vec3::new(x * scale, y * scale, 1.0 - k)
}

/// Two unit vectors `(t, b)` completing the unit `n` to a right-handed orthonormal basis
/// `(t, b, n)`, continuous except across `n.z = 0` (Duff, Burgess, Christensen, Hery,
/// Kensler, Liani and Villemin, "Building an Orthonormal Basis, Revisited", JCGT 6(1),
/// 2017), the sign of `n.z` taken with `>= 0` (so `-0` counts as positive, as in WGSL).
#[inline]
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t = Vec3::new(1.0 + sign * (n.x * n.x) * a, sign * b, -sign * n.x);
    let bt = Vec3::new(b, sign + (n.y * n.y) * a, -n.y);
    (t, bt)
}

/// `local` (around +Z) in the frame of [`orthonormal_basis`] around `n`:
/// `t local.x + b local.y + n local.z`.
#[inline]
pub fn to_frame(local: Vec3, n: Vec3) -> Vec3 {
    let (t, b) = orthonormal_basis(n);
    t * local.x + b * local.y + n * local.z
}

/// The point `corner + u edge_u + v edge_v` of a quad light, uniform in its area
/// (density `1 / |edge_u x edge_v|`).
#[inline]
pub fn quad_point(corner: Vec3, edge_u: Vec3, edge_v: Vec3, [u, v]: [f32; 2]) -> Vec3 {
    corner + edge_u * u + edge_v * v
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Every prefix of `2^m` samples of a stream is a (0, m, 2)-net: each of the `2^m`
    /// elementary intervals `[a / 2^j, (a + 1) / 2^j) x [b / 2^(m-j), (b + 1) / 2^(m-j))`
    /// holds exactly one point, for every shape `j`. On the 24-bit fractions the samples
    /// keep (so up to `m = 12` here, 4,096 samples, each cell side at least 2^-12).
    fn is_net(points: &[[f32; 2]], m: u32) -> Result<(), String> {
        let n = 1usize << m;
        for j in 0..=m {
            let mut seen = vec![false; n];
            for p in &points[..n] {
                let a = (p[0] * (1u32 << j) as f32) as usize;
                let b = (p[1] * (1u32 << (m - j)) as f32) as usize;
                let cell = a * (1usize << (m - j)) + b;
                if std::mem::replace(&mut seen[cell], true) {
                    return Err(format!("m = {m}, shape {j}: two points in cell ({a}, {b})"));
                }
            }
        }
        Ok(())
    }

    /// Sobol's second dimension as defined: the xor of the direction numbers over the
    /// index's set bits, bit by bit (the WGSL twin's loop).
    fn sobol_y_by_bits(index: u32) -> u32 {
        let mut y = 0u32;
        let mut v = 1u32 << 31;
        let mut i = index;
        while i != 0 {
            if i & 1 != 0 {
                y ^= v;
            }
            i >>= 1;
            v ^= v >> 1;
        }
        y
    }

    /// Both forms are xor-linear in the index's bits, so agreeing on the 32 single bits
    /// (and on 0) they agree on every index; the random indices check the tables' layout
    /// once more.
    #[test]
    fn sobol_tables_are_the_bit_loop() {
        assert_eq!(sobol_2d(0)[1], 0);
        for k in 0..32 {
            assert_eq!(sobol_2d(1 << k)[1], sobol_y_by_bits(1 << k), "direction number {k}");
            assert_eq!(sobol_direction(k), sobol_y_by_bits(1 << k));
        }
        let mut x = 0x9e37_79b9u32;
        for _ in 0..100_000 {
            x = hash_u32(x);
            assert_eq!(sobol_2d(x)[1], sobol_y_by_bits(x), "index {x:#x}");
        }
    }

    #[test]
    fn sobol_second_dimension_has_its_direction_numbers() {
        let want = [0x8000_0000u32, 0xc000_0000, 0xa000_0000, 0xf000_0000, 0x8800_0000];
        for (k, w) in want.iter().enumerate() {
            assert_eq!(sobol_2d(1 << k)[1], *w, "direction number {}", k + 1);
        }
        assert_eq!(sobol_2d(3), [0xc000_0000, 0x4000_0000]);
    }

    #[test]
    fn unscrambled_sobol_points_are_nets() {
        let points: Vec<[f32; 2]> = (0..4096).map(|i| sobol_2d(i).map(unit_f32)).collect();
        for m in 0..=12 {
            is_net(&points, m).unwrap();
        }
    }

    /// The scrambled value depends on higher input digits only through lower ones: the
    /// scramble permutes each dyadic interval's halves, so it maps intervals to intervals.
    #[test]
    fn nested_uniform_scrambling_maps_dyadic_intervals_to_dyadic_intervals() {
        for seed in [0u32, 1, 0xdead_beef, 12345] {
            for k in 1..=16 {
                let shift = 32 - k;
                for prefix in 0..(1u32 << k.min(8)) {
                    let lo = (prefix << shift) | 0x0001_2345 & ((1u32 << shift) - 1);
                    let hi = (prefix << shift) | ((1u32 << shift) - 1);
                    let (a, b) = (nested_uniform_scramble(lo, seed), nested_uniform_scramble(hi, seed));
                    assert_eq!(a >> shift, b >> shift, "seed {seed}, {k} digits: {lo:#x} and {hi:#x} part");
                }
            }
        }
    }

    /// Decorrelation: neighbouring pixels' first samples spread over the square like
    /// independent uniform points (the mean of each coordinate and of their product over
    /// 65,536 pixels within 4 standard errors of the uniform's).
    #[test]
    fn streams_of_neighbouring_pixels_are_decorrelated() {
        let n = 65_536u32;
        let (mut sx, mut sy, mut sxy, mut sxx) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let mut prev = sample_2d(0, sample_seed(0, 0, 0));
        for pixel in 1..=n {
            let p = sample_2d(0, sample_seed(pixel, 0, 0));
            sx += p[0] as f64;
            sy += p[1] as f64;
            sxy += (p[0] as f64 - 0.5) * (p[1] as f64 - 0.5);
            // The correlation of one pixel's first sample with its neighbour's.
            sxx += (p[0] as f64 - 0.5) * (prev[0] as f64 - 0.5);
            prev = p;
        }
        let nf = n as f64;
        // Standard error of a mean of uniforms: sqrt(1/12 / n); of the products: 1/12 / sqrt(n).
        let se_mean = (1.0 / 12.0 / nf).sqrt();
        let se_prod = 1.0 / 12.0 / nf.sqrt();
        assert!((sx / nf - 0.5).abs() < 4.0 * se_mean, "mean x {}", sx / nf);
        assert!((sy / nf - 0.5).abs() < 4.0 * se_mean, "mean y {}", sy / nf);
        assert!((sxy / nf).abs() < 4.0 * se_prod, "x y correlation {}", sxy / nf);
        assert!((sxx / nf).abs() < 4.0 * se_prod, "neighbour correlation {}", sxx / nf);
    }

    #[test]
    fn sin_cos_quarter_is_within_its_bound() {
        let n = 100_000;
        let mut worst = 0.0f64;
        for k in -n..=n {
            let x = std::f32::consts::FRAC_PI_4 * k as f32 / n as f32;
            let (s, c) = sin_cos_quarter(x);
            let xd = x as f64;
            worst = worst.max((s as f64 - xd.sin()).abs()).max((c as f64 - xd.cos()).abs());
        }
        assert!(worst <= SIN_COS_MAX_ERROR as f64, "worst error {worst:e}");
        assert_eq!(sin_cos_quarter(0.0), (0.0, 1.0));
    }

    /// The concentric map's points lie in the unit disk, and its quadrants and radii are
    /// uniform in area: the fraction of 4,096 stratified points within radius 1/2 is 1/4.
    #[test]
    fn concentric_disk_is_area_uniform() {
        let seed = sample_seed(7, 1, 0);
        let points: Vec<[f32; 2]> = (0..4096).map(|s| concentric_disk(sample_2d(s, seed))).collect();
        assert!(points.iter().all(|p| p[0] * p[0] + p[1] * p[1] <= 1.0 + 1e-6));
        let inner = points.iter().filter(|p| p[0] * p[0] + p[1] * p[1] < 0.25).count();
        // A (0, 12, 2)-net warped: the count is within a few points of 1,024.
        assert!((inner as i64 - 1024).abs() <= 16, "{inner} of 4096 within radius 1/2");
        for quadrant in 0..4 {
            let (sx, sy) = (quadrant & 1 == 0, quadrant & 2 == 0);
            let k = points.iter().filter(|p| (p[0] >= 0.0) == sx && (p[1] >= 0.0) == sy).count();
            assert!((k as i64 - 1024).abs() <= 16, "quadrant {quadrant}: {k}");
        }
    }

    /// Cosine-weighted directions: E[z] = 2/3 and E[z^2] = 1/2 for the density cos / pi,
    /// by 4,096 stratified samples (quasi-Monte Carlo error about 1e-3).
    #[test]
    fn cosine_hemisphere_has_the_cosine_moments() {
        let seed = sample_seed(3, 2, 1);
        let dirs: Vec<Vec3> = (0..4096).map(|s| cosine_hemisphere(sample_2d(s, seed))).collect();
        let n = dirs.len() as f64;
        let ez = dirs.iter().map(|d| d.z as f64).sum::<f64>() / n;
        let ez2 = dirs.iter().map(|d| (d.z * d.z) as f64).sum::<f64>() / n;
        assert!((ez - 2.0 / 3.0).abs() < 2e-3, "E[z] {ez}");
        assert!((ez2 - 0.5).abs() < 2e-3, "E[z^2] {ez2}");
        assert!(dirs.iter().all(|d| d.z >= 0.0 && (d.length() - 1.0).abs() < 1e-6));
    }

    /// Uniform cone directions: within the cone, unit, and uniform in solid angle
    /// (E[1 - cos] = (1 - cos max) / 2), for a wide cone and a sun-sized one.
    #[test]
    fn uniform_cone_is_uniform_in_solid_angle() {
        for half_angle in [1.2f64, 0.5f64.to_radians() / 2.0] {
            let k_max = (1.0 - half_angle.cos()) as f32;
            let seed = sample_seed(11, 0, 0);
            let dirs: Vec<Vec3> = (0..4096).map(|s| uniform_cone(sample_2d(s, seed), k_max)).collect();
            // 1 - cos from the sine, in f64 (1 - z rounds away a sun's cone).
            let k_of = |d: &Vec3| {
                let s2 = (d.x as f64).powi(2) + (d.y as f64).powi(2);
                s2 / (1.0 + (1.0 - s2).max(0.0).sqrt())
            };
            let mean_k = dirs.iter().map(k_of).sum::<f64>() / dirs.len() as f64;
            assert!((mean_k / k_max as f64 - 0.5).abs() < 2e-3, "half angle {half_angle}: E[1 - cos] {mean_k}");
            for d in &dirs {
                assert!((d.length() - 1.0).abs() < 1e-6, "{d}");
                // A few roundings of the sine, relative.
                assert!(k_of(d) <= k_max as f64 * (1.0 + 1e-5), "{d} outside the cone");
            }
        }
    }

    proptest! {
        /// Every stream is a net at every power of two up to 4,096 samples.
        #[test]
        fn scrambled_streams_are_nets(pixel in any::<u32>(), stream in 0u32..8, frame in 0u32..4) {
            let seed = sample_seed(pixel, stream, frame);
            let points: Vec<[f32; 2]> = (0..4096).map(|s| sample_2d(s, seed)).collect();
            for m in 0..=12 {
                prop_assert!(is_net(&points, m).is_ok(), "{:?}", is_net(&points, m));
            }
        }

        /// The basis is orthonormal and right-handed around any unit normal.
        #[test]
        fn orthonormal_basis_is_orthonormal(x in -1.0f32..1.0, y in -1.0f32..1.0, z in -1.0f32..1.0) {
            let n = Vec3::new(x, y, z);
            prop_assume!(n.length() > 1e-3);
            let n = n.normalize();
            let (t, b) = orthonormal_basis(n);
            // Roundings of values of order 1 through a dozen operations.
            const BASIS_TOL: f32 = 1e-5;
            prop_assert!((t.length() - 1.0).abs() < BASIS_TOL && (b.length() - 1.0).abs() < BASIS_TOL);
            prop_assert!(t.dot(b).abs() < BASIS_TOL && t.dot(n).abs() < BASIS_TOL && b.dot(n).abs() < BASIS_TOL);
            prop_assert!((t.cross(b) - n).length() < 2.0 * BASIS_TOL);
        }
    }
}
