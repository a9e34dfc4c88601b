//! Kernels of the `shadow_denoise` stage (issue 38 item 4): an edge-aware à-trous wavelet
//! filter (Dammertz, Sewtz, Hanika and Lensch, "Edge-Avoiding À-Trous Wavelet Transform
//! for fast Global Illumination Filtering", HPG 2010) over each pixel's stochastic
//! visibility channels ([`raw_channels`]: the visible share of each area light, then the
//! ambient occlusion), guided by the visibility buffer's surfaces:
//!
//! * pass `k` (steps 1, 2, 4, ... : [`DENOISE_PASSES`]) takes the 5 x 5 B3-spline taps
//!   ([`ATROUS_KERNEL`]) `2^k` pixels apart;
//! * a tap counts only on the same object ([`SurfaceRecord::object`]: shadows do not bleed
//!   across object edges), weighted by the normals' agreement `max(n . n', 0)^32` and by
//!   its distance from the centre's tangent plane, `max(1 - |(p' - p) . n| / f, 0)`, `f` the
//!   pixel's footprint at its distance times the step ([`tap_weight`]);
//! * each channel is the centre's value plus `sum w (v - centre) / sum w` over the taps in
//!   row-major order (the weighted mean, written so that a constant input comes out bit
//!   for bit: every difference is 0), the centre's own weight `ATROUS_KERNEL[0]^2`; taps without an estimate
//!   ([`crate::kernels::soft_shadow::NO_ESTIMATE`]: none of the pixel's samples traced a
//!   ray) weigh nothing, so the filter fills such pixels from their neighbours;
//! * and by the values' agreement within the noise the pixel's samples carry
//!   ([`value_weight`], [`noise_sigma`]: wide at one sample per pixel, narrow at many, so
//!   that more samples keep more of the penumbra's gradient);
//! * the result is clamped to the range of the raw values in the pixel's 5 x 5
//!   neighbourhood ([`clamp_pixel`]): the wide taps do not carry a penumbra's light into
//!   an umbra whose samples are all occluded;
//! * 8 x 8 tiles whose hit pixels' raw values of a channel all agree on 0 or on 1 (fully
//!   lit, or umbra) keep them and are not filtered ([`tile_agrees`]): a frame models only
//!   what needs it, and an umbra stays exactly dark.
//!
//! Every operation is a correctly rounded `+ - * /` or `sqrt` in a stated order, so a GPU
//! twin can give the same bits.

use glam::Vec3;

use crate::formats::{LightRecord, SurfaceRecord};
use crate::kernels::soft_shadow::{ambient_occlusion, light_visibility, AmbientOcclusion, Lights};

/// The B3-spline taps at offsets 0, 1 and 2 (`1/16 [1 4 6 4 1]`).
pub const ATROUS_KERNEL: [f32; 3] = [3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// Filter passes: steps 1, 2 and 4 pixels, a footprint of 29 x 29 pixels. Enough at 4
/// samples per pixel to bring the penumbra's noise under the bar (the
/// `soft_shadows` tests measure it); more would widen the blur of contact shadows.
pub const DENOISE_PASSES: u32 = 3;

/// Side of the tiles the filter classifies ([`tile_agrees`]).
pub const DENOISE_TILE: usize = 8;

/// How many times the normals' cosine is squared in [`tap_weight`]: `cos^32`, which
/// keeps taps within about 12 degrees of the centre's normal at half weight or more
/// (the exponent SVGF uses for its normal weight is 128; shadows vary more slowly across
/// curved surfaces than indirect light).
pub const NORMAL_SQUARINGS: u32 = 5;

/// The channels the filter works on per pixel: one per area light, then one for the
/// ambient occlusion where the frame traces it.
pub fn channel_count(lights: &[LightRecord], ao: &AmbientOcclusion) -> usize {
    lights.iter().filter(|l| l.is_area()).count() + (ao.samples > 0) as usize
}

/// The samples per pixel behind each channel ([`channel_count`] of them): each area
/// light's, then the ambient occlusion's.
pub fn channel_samples(lights: &[LightRecord], ao: &AmbientOcclusion) -> Vec<u32> {
    let mut out: Vec<u32> = lights.iter().filter(|l| l.is_area()).map(|l| l.samples).collect();
    if ao.samples > 0 {
        out.push(ao.samples);
    }
    out
}

/// How many noise deviations apart two values may lie and still average
/// ([`value_weight`]): 3, the usual three-sigma band.
pub const VALUE_TOLERANCE: f32 = 3.0;

/// The noise a pixel's raw value carries, per channel, into `out`: the deviation of the
/// mean of `n` coin flips of probability `m`, `sqrt(m (1 - m) / n)`, with `m` the mean of
/// the raw values with an estimate in its 5 x 5 neighbourhood on the same object ([`CLAMP_RADIUS`])
/// and `n` the channel's samples per pixel (`samples`). Few samples give a wide
/// deviation, so the filter averages freely; many give a narrow one, so it keeps the
/// penumbra's gradient. 0 where the neighbourhood is all lit or all dark (or a miss).
pub fn noise_sigma(
    raw: &[f32],
    surfaces: &[SurfaceRecord],
    (width, height): (usize, usize),
    (x, y): (usize, usize),
    samples: &[u32],
    out: &mut [f32],
) {
    let channels = out.len();
    out.fill(0.0);
    let centre = &surfaces[y * width + x];
    if !centre.is_hit() {
        return;
    }
    let means = neighbourhood_mean(raw, surfaces, (width, height), (x, y), channels);
    for c in 0..channels {
        if let (m, 1..) = means[c] {
            out[c] = ((m * (1.0 - m)).max(0.0) / samples[c] as f32).sqrt();
        }
    }
}

/// Per channel, the mean of the values `values` (`channels` per pixel) with an estimate in
/// the 5 x 5 neighbourhood of hit pixel `(x, y)` on its object
/// ([`neighbourhood`]); [`noise_sigma`]'s mean, and the temporal pass's
/// ([`crate::kernels::temporal`]), in row-major order, and how many there
/// are (mean 0 where none).
pub fn neighbourhood_mean(
    values: &[f32],
    surfaces: &[SurfaceRecord],
    (width, height): (usize, usize),
    (x, y): (usize, usize),
    channels: usize,
) -> [(f32, u32); MAX_CHANNELS] {
    let mut sums = [0.0f32; MAX_CHANNELS];
    let mut counts = [0u32; MAX_CHANNELS];
    for k in neighbourhood(surfaces, (width, height), (x, y)) {
        for c in 0..channels {
            let v = values[k * channels + c];
            if v >= 0.0 {
                sums[c] += v;
                counts[c] += 1;
            }
        }
    }
    std::array::from_fn(|c| match counts[c] {
        0 => (0.0, 0),
        n => (sums[c] / n as f32, n),
    })
}

/// The weight of a tap of value `other` for a centre of value `centre` whose noise
/// deviation is `sigma` ([`noise_sigma`]): `max(1 - |other - centre| / (3 sigma), 0)`; 1
/// where the centre has no estimate; where `sigma` is 0, 1 for an equal value, else 0.
#[inline]
pub fn value_weight(centre: f32, other: f32, sigma: f32) -> f32 {
    if centre < 0.0 {
        return 1.0;
    }
    let d = (other - centre).abs();
    if sigma > 0.0 {
        (1.0 - d / (VALUE_TOLERANCE * sigma)).max(0.0)
    } else if d == 0.0 {
        1.0
    } else {
        0.0
    }
}

/// A pixel's raw channels ([`channel_count`] of them) from its mask `codes`: each area
/// light's visible share ([`light_visibility`]; emissive meshes' through the emitter table
/// `lights` carries), then the ambient occlusion; 0 (and 1 for the occlusion) on a miss.
/// `scratch` holds one value per light.
pub fn raw_channels<'l>(
    codes: &[u8],
    lights: impl Into<Lights<'l>>,
    ao: &AmbientOcclusion,
    s: &SurfaceRecord,
    scratch: &mut [f32],
    out: &mut [f32],
) {
    let lights = lights.into();
    let mut k = 0;
    if s.is_hit() {
        light_visibility(codes, lights, s, scratch);
    } else {
        scratch.fill(0.0);
    }
    for (light, &v) in lights.iter().zip(scratch.iter()) {
        if light.is_area() {
            out[k] = v;
            k += 1;
        }
    }
    if ao.samples > 0 {
        out[k] = if s.is_hit() { ambient_occlusion(codes, lights.records, ao).unwrap_or(1.0) } else { 1.0 };
    }
}

/// The angle one pixel spans at the image's centre: the chord between the unit directions
/// of the primary rays through the two centre pixels of a column (a pixel is far below a
/// degree, where the chord is the angle to 1e-5 relative). Computed on the host once a
/// frame; the GPU stage takes it as a uniform.
pub fn pixel_angle(camera: &crate::formats::CameraRecord) -> f32 {
    use crate::kernels::camera::primary_ray;
    let (x, y) = (camera.width / 2, camera.height / 2);
    let d0 = Vec3::from(primary_ray(camera, x, y).direction).normalize();
    let d1 = Vec3::from(primary_ray(camera, x, y.saturating_sub(1)).direction).normalize();
    (d1 - d0).length()
}

/// The footprint of a pixel at `p` seen from `eye`: its distance times the angle one pixel
/// spans (`pixel_angle`, `2 tan(fov / 2) / height`).
#[inline]
pub fn pixel_footprint(p: Vec3, eye: Vec3, pixel_angle: f32) -> f32 {
    let d = p - eye;
    d.dot(d).sqrt() * pixel_angle
}

/// The edge-stopping weight of tap `other` for the centre `centre` at plane tolerance
/// `footprint` (the centre's [`pixel_footprint`] times the pass's step): 0 off the centre's
/// object or off its hit; else `max(n . n', 0)^32 * max(1 - |(p' - p) . n| / footprint, 0)`.
#[inline]
pub fn tap_weight(centre: &SurfaceRecord, other: &SurfaceRecord, footprint: f32) -> f32 {
    if !other.is_hit() || other.object != centre.object {
        return 0.0;
    }
    let n = Vec3::from(centre.normal);
    let mut c = n.dot(Vec3::from(other.normal)).max(0.0);
    for _ in 0..NORMAL_SQUARINGS {
        c = c * c;
    }
    let plane = (Vec3::from(other.position) - Vec3::from(centre.position)).dot(n).abs();
    c * (1.0 - plane / footprint).max(0.0)
}

/// Whether the hit pixels of a tile agree on a channel: all 0 or all 1 (`values`: the
/// channel's raw value at each of the tile's hit pixels; a tile without hits agrees).
#[inline]
pub fn tile_agrees(mut values: impl Iterator<Item = f32>) -> bool {
    match values.next() {
        None => true,
        Some(first) if first == 0.0 || first == 1.0 => values.all(|v| v == first),
        Some(_) => false,
    }
}

/// One à-trous pass at pixel `(x, y)` of a `width` x `height` image: its `channels` values
/// from `input` (`channels` per pixel) filtered with taps `step` pixels apart, into `out`;
/// `filter[c]` says whether channel `c` is filtered there (else it is copied), `footprint`
/// is the centre's [`pixel_footprint`]. A miss is copied.
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn atrous_pixel(
    input: &[f32],
    surfaces: &[SurfaceRecord],
    (width, height): (usize, usize),
    (x, y): (usize, usize),
    step: usize,
    footprint: f32,
    (filter, sigma): (&[bool], &[f32]),
    out: &mut [f32],
) {
    let channels = out.len();
    let i = y * width + x;
    let centre = &surfaces[i];
    out.copy_from_slice(&input[i * channels..(i + 1) * channels]);
    if !centre.is_hit() || !filter.iter().any(|&f| f) {
        return;
    }
    let tolerance = footprint * step as f32;
    let mut sums = [0.0f32; MAX_CHANNELS];
    let mut weights = [0.0f32; MAX_CHANNELS];
    for dy in -2i32..=2 {
        let yy = y as i64 + dy as i64 * step as i64;
        if yy < 0 || yy >= height as i64 {
            continue;
        }
        for dx in -2i32..=2 {
            let xx = x as i64 + dx as i64 * step as i64;
            if xx < 0 || xx >= width as i64 {
                continue;
            }
            let j = yy as usize * width + xx as usize;
            let h = ATROUS_KERNEL[dx.unsigned_abs() as usize] * ATROUS_KERNEL[dy.unsigned_abs() as usize];
            let w = if j == i { h } else { h * tap_weight(centre, &surfaces[j], tolerance) };
            if w == 0.0 {
                continue;
            }
            for c in 0..channels {
                let v = input[j * channels + c];
                // Values without an estimate (`NO_ESTIMATE`, negative) weigh nothing.
                if v >= 0.0 {
                    let centre_value = input[i * channels + c];
                    let wc = if j == i { w } else { w * value_weight(centre_value, v, sigma[c]) };
                    weights[c] += wc;
                    sums[c] += wc * (v - centre_value.max(0.0));
                }
            }
        }
    }
    for c in 0..channels {
        if filter[c] && weights[c] > 0.0 {
            out[c] = input[i * channels + c].max(0.0) + sums[c] / weights[c];
        }
    }
}

/// Radius of the neighbourhood whose raw values bound a filtered value ([`clamp_pixel`])
/// and set its noise ([`noise_sigma`]): 5 x 5 pixels, 100 samples at 4 per pixel.
pub const CLAMP_RADIUS: i64 = 2;

/// The pixels of the [`CLAMP_RADIUS`] neighbourhood of `(x, y)` (itself included) that are
/// hits on its object, in row-major order.
pub fn neighbourhood(
    surfaces: &[SurfaceRecord],
    (width, height): (usize, usize),
    (x, y): (usize, usize),
) -> impl Iterator<Item = usize> + '_ {
    let object = surfaces[y * width + x].object;
    let rows = (y as i64 - CLAMP_RADIUS).max(0)..=(y as i64 + CLAMP_RADIUS).min(height as i64 - 1);
    let columns = (x as i64 - CLAMP_RADIUS).max(0)..=(x as i64 + CLAMP_RADIUS).min(width as i64 - 1);
    rows.flat_map(move |yy| columns.clone().map(move |xx| yy as usize * width + xx as usize))
        .filter(move |&j| surfaces[j].is_hit() && surfaces[j].object == object)
}

/// The last step at pixel `(x, y)`: each filtered channel `out[c]` (where `filter[c]`)
/// clamped to the range of the raw values `raw` with an estimate in its 5 x 5
/// neighbourhood on the same object ([`CLAMP_RADIUS`]). Where every sample around is
/// occluded the light stays out (an umbra next to a penumbra does not take the
/// penumbra's light from the wide taps), and where every sample around is lit no shadow
/// comes in; elsewhere the clamp does nothing. A miss, and a pixel none of whose channels
/// is filtered, is left as it is.
pub fn clamp_pixel(
    raw: &[f32],
    surfaces: &[SurfaceRecord],
    (width, height): (usize, usize),
    (x, y): (usize, usize),
    filter: &[bool],
    out: &mut [f32],
) {
    let channels = out.len();
    let centre = &surfaces[y * width + x];
    if !centre.is_hit() || !filter.iter().any(|&f| f) {
        return;
    }
    let (lo, hi) = raw_range(raw, surfaces, (width, height), (x, y), channels);
    for c in 0..channels {
        if filter[c] && out[c] >= 0.0 && lo[c] <= hi[c] {
            out[c] = out[c].max(lo[c]).min(hi[c]);
        }
    }
}

/// Per channel, the least and the greatest of the raw values `raw` (`channels` per pixel)
/// with an estimate in the 5 x 5 neighbourhood of hit pixel `(x, y)` on its object
/// ([`CLAMP_RADIUS`]); `lo > hi` (infinities) for a channel without any. What
/// [`clamp_pixel`] bounds a filtered value by, and the temporal pass a pixel's history
/// ([`crate::kernels::temporal`]).
pub fn raw_range(
    raw: &[f32],
    surfaces: &[SurfaceRecord],
    (width, height): (usize, usize),
    (x, y): (usize, usize),
    channels: usize,
) -> ([f32; MAX_CHANNELS], [f32; MAX_CHANNELS]) {
    let mut lo = [f32::INFINITY; MAX_CHANNELS];
    let mut hi = [f32::NEG_INFINITY; MAX_CHANNELS];
    for j in neighbourhood(surfaces, (width, height), (x, y)) {
        for c in 0..channels {
            let v = raw[j * channels + c];
            if v >= 0.0 {
                lo[c] = lo[c].min(v);
                hi[c] = hi[c].max(v);
            }
        }
    }
    (lo, hi)
}

/// Most channels a frame filters: area lights plus the ambient occlusion.
pub const MAX_CHANNELS: usize = 16;

#[cfg(test)]
mod tests {
    use super::*;

    fn surface(p: Vec3, n: Vec3, object: u32) -> SurfaceRecord {
        SurfaceRecord {
            position: p.into(),
            normal: n.into(),
            geometric_normal: n.into(),
            object,
            triangle: 0,
            position_error: 0.0,
        }
    }

    /// A 12 x 10 floor (object 0) with a box top (object 1, 0.5 above it) over its right
    /// third.
    fn floor_and_box() -> Vec<SurfaceRecord> {
        let (w, h) = (12, 10);
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32 * 0.01, (i / w) as f32 * 0.01);
                match i % w >= 8 {
                    true => surface(Vec3::new(x, 0.5, y), Vec3::Y, 1),
                    false => surface(Vec3::new(x, 0.0, y), Vec3::Y, 0),
                }
            })
            .collect()
    }

    #[test]
    fn constant_input_comes_out_bit_for_bit() {
        let s = floor_and_box();
        for value in [0.0f32, 1.0, 0.37, 1.0 / 3.0] {
            let input = vec![value; s.len() * 2];
            for i in 0..s.len() {
                let mut out = [0.0; 2];
                atrous_pixel(&input, &s, (12, 10), (i % 12, i / 12), 2, 0.01, (&[true, true], &[1.0, 1.0]), &mut out);
                assert_eq!(out.map(f32::to_bits), [value.to_bits(); 2], "pixel {i}");
            }
        }
    }

    #[test]
    fn pixels_without_an_estimate_are_filled_from_their_neighbours() {
        let s = floor_and_box();
        let none = crate::kernels::soft_shadow::NO_ESTIMATE;
        let input: Vec<f32> = (0..s.len()).map(|i| if i % 2 == 0 { none } else { 0.5 }).collect();
        let mut out = [0.0];
        atrous_pixel(&input, &s, (12, 10), (2, 2), 1, 0.01, (&[true], &[1.0]), &mut out);
        assert_eq!(out[0], 0.5, "a pixel without an estimate takes its neighbours'");
        let alone = vec![none; s.len()];
        atrous_pixel(&alone, &s, (12, 10), (2, 2), 1, 0.01, (&[true], &[1.0]), &mut out);
        assert_eq!(out[0], none, "without any estimate around, none");
    }

    #[test]
    fn values_do_not_cross_object_edges() {
        let s = floor_and_box();
        // Noise on the floor, 1 on the box top.
        let input: Vec<f32> = (0..s.len()).map(|i| if i % 12 >= 8 { 1.0 } else { (i % 3) as f32 / 2.0 }).collect();
        for y in 0..10 {
            for x in 8..12 {
                let mut out = [0.0];
                atrous_pixel(&input, &s, (12, 10), (x, y), 1, 0.01, (&[true], &[1.0]), &mut out);
                assert_eq!(out[0], 1.0, "box pixel ({x}, {y}) took the floor's values");
            }
            let mut out = [0.0];
            atrous_pixel(&input, &s, (12, 10), (7, y), 1, 0.01, (&[true], &[1.0]), &mut out);
            assert!(out[0] < 1.0, "floor pixel next to the box");
        }
    }

    #[test]
    fn taps_off_the_tangent_plane_or_turned_away_weigh_nothing() {
        let c = surface(Vec3::ZERO, Vec3::Y, 0);
        assert_eq!(tap_weight(&c, &surface(Vec3::new(0.1, 0.0, 0.0), Vec3::Y, 0), 0.01), 1.0);
        assert_eq!(tap_weight(&c, &surface(Vec3::new(0.0, 0.02, 0.0), Vec3::Y, 0), 0.01), 0.0);
        assert_eq!(tap_weight(&c, &surface(Vec3::ZERO, Vec3::X, 0), 0.01), 0.0);
        assert_eq!(tap_weight(&c, &surface(Vec3::ZERO, Vec3::Y, 1), 0.01), 0.0);
        assert_eq!(tap_weight(&c, &SurfaceRecord::MISS, 0.01), 0.0);
        let tilted = tap_weight(&c, &surface(Vec3::ZERO, Vec3::new(0.0, 1.0, 0.2).normalize(), 0), 0.01);
        assert!(tilted > 0.4 && tilted < 0.6, "{tilted}: 11 degrees off is about half");
    }

    #[test]
    fn tiles_agree_only_on_all_zero_or_all_one() {
        assert!(tile_agrees([0.0, 0.0].into_iter()));
        assert!(tile_agrees([1.0, 1.0].into_iter()));
        assert!(tile_agrees(std::iter::empty()));
        assert!(!tile_agrees([1.0, 0.0].into_iter()));
        assert!(!tile_agrees([0.5, 0.5].into_iter()));
    }
}
