//! Stage-by-stage comparison of two frames (a reference and a candidate: CPU and GPU,
//! two runs, two thread counts).
//!
//! Every buffer a stage writes is described word by word ([`Word`]): integer words
//! (ids, flags, counts, pixel indices) must be identical; float words are compared in
//! ulp ([`crate::ulp_distance`]) and summarized in a histogram with the worst case.
//! Downstream stages are compared where their inputs agree: the ray lists are
//! matched by `(light, pixel)` (a ray missing on one side is an integer mismatch of
//! `compaction`, not a cascade of shifted records), so one differing pixel is reported
//! once, in the stage that made it.

use hyrt_core::formats::{GBufferTexel, RayRecord, SurfaceRecord};
use hyrt_core::frame::Frame;
use hyrt_core::plan::{BounceBuffer, FrameBuffer};
use hyrt_core::stage::Stage;

use crate::ulp_distance;

/// How a 32-bit word of a record is compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Word {
    /// Must be identical.
    Int(&'static str),
    /// Compared in ulp (both NaN with the same bits count as equal; see [`ulp_distance`]).
    Float(&'static str),
}

/// The words of a G-buffer texel, in memory order.
pub const GBUFFER_WORDS: [Word; 6] = [
    Word::Float("bary_u"),
    Word::Float("bary_v"),
    Word::Float("depth"),
    Word::Int("triangle"),
    Word::Int("object"),
    Word::Int("flags"),
];
/// The words of a surface record, in memory order.
pub const SURFACE_WORDS: [Word; 12] = [
    Word::Float("position.x"),
    Word::Float("position.y"),
    Word::Float("position.z"),
    Word::Float("position_error"),
    Word::Float("normal.x"),
    Word::Float("normal.y"),
    Word::Float("normal.z"),
    Word::Int("object"),
    Word::Float("geometric_normal.x"),
    Word::Float("geometric_normal.y"),
    Word::Float("geometric_normal.z"),
    Word::Int("triangle"),
];
/// The words of a ray record, in memory order.
pub const RAY_WORDS: [Word; 16] = [
    Word::Float("origin.x"),
    Word::Float("origin.y"),
    Word::Float("origin.z"),
    Word::Float("t_min"),
    Word::Float("direction.x"),
    Word::Float("direction.y"),
    Word::Float("direction.z"),
    Word::Float("t_max"),
    Word::Int("pixel"),
    Word::Int("kind"),
    Word::Int("depth"),
    Word::Int("light"),
    Word::Float("throughput.r"),
    Word::Float("throughput.g"),
    Word::Float("throughput.b"),
    Word::Float("cone"),
];
/// The words of an RGBA image texel.
pub const RGBA_WORDS: [Word; 4] = [Word::Float("r"), Word::Float("g"), Word::Float("b"), Word::Float("a")];
/// The words of a closest-hit record, in memory order.
pub const HIT_WORDS: [Word; 6] =
    [Word::Float("t"), Word::Float("u"), Word::Float("v"), Word::Int("triangle"), Word::Int("flags"), Word::Int("pad")];
/// The words of a parent's links to its secondary rays.
pub const LINK_WORDS: [Word; 2] = [Word::Int("reflection"), Word::Int("refraction")];
/// One integer word (occlusion results, shadow codes).
pub const WORD: [Word; 1] = [Word::Int("value")];

/// Buckets of the ulp histogram: bucket 0 counts exact words, bucket `k` (1..=32)
/// counts distances in `[2^(k-1), 2^k)`, the last bucket counts NaN-against-number
/// and larger distances.
pub const ULP_BUCKETS: usize = 34;

/// The bucket of an ulp distance.
pub fn ulp_bucket(ulp: u64) -> usize {
    if ulp == 0 {
        0
    } else {
        ((64 - ulp.leading_zeros()) as usize).min(ULP_BUCKETS - 1)
    }
}

/// Label of a histogram bucket ("0", "1", "2-3", "4-7", ...).
pub fn ulp_bucket_label(bucket: usize) -> String {
    match bucket {
        0 => "0".into(),
        1 => "1".into(),
        b if b == ULP_BUCKETS - 1 => format!(">=2^{}", b - 1),
        b => format!("{}-{}", 1u64 << (b - 1), (1u64 << b) - 1),
    }
}

/// Where in the image a compared element lies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Location {
    /// Element index in its buffer.
    pub index: usize,
    /// Pixel `(x, y)`, when the element belongs to one.
    pub pixel: Option<(u32, u32)>,
    /// Light index, for per-light elements.
    pub light: Option<u32>,
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "#{}", self.index)?;
        if let Some((x, y)) = self.pixel {
            write!(f, " pixel ({x}, {y})")?;
        }
        if let Some(l) = self.light {
            write!(f, " light {l}")?;
        }
        Ok(())
    }
}

/// One differing word, with both values.
#[derive(Clone, Debug, PartialEq)]
pub struct Difference {
    pub at: Location,
    pub word: &'static str,
    pub expected: String,
    pub actual: String,
    /// Ulp distance for float words, `None` for integer words.
    pub ulp: Option<u64>,
}

impl std::fmt::Display for Difference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {}: expected {}, got {}", self.at, self.word, self.expected, self.actual)?;
        if let Some(u) = self.ulp {
            write!(f, " ({u} ulp)")?;
        }
        Ok(())
    }
}

/// The comparison of one buffer of one stage.
#[derive(Clone, Debug, PartialEq)]
pub struct BufferComparison {
    pub stage: Stage,
    /// Buffer name: [`FrameBuffer::label`] ("gbuffer", "surfaces", "rays", "occluded",
    /// "shadow", "rt", "raster", "final", "bounce{d}_rays", ...).
    pub buffer: String,
    /// Elements compared (records, pixels).
    pub elements: usize,
    /// Elements with at least one differing integer word (or present on one side only).
    pub int_mismatches: usize,
    /// The first integer mismatch.
    pub first_int: Option<Difference>,
    /// Float words compared.
    pub float_words: u64,
    /// Histogram of float-word ulp distances ([`ULP_BUCKETS`] buckets).
    pub ulp_histogram: [u64; ULP_BUCKETS],
    /// The float word with the largest ulp distance (first one on ties).
    pub worst: Option<Difference>,
    /// Per-pixel largest ulp distance (for difference images), when the buffer is an
    /// image-shaped buffer (one element per pixel) and some word differs.
    pub pixel_ulps: Option<Vec<u64>>,
}

impl BufferComparison {
    fn new(stage: Stage, buffer: impl Into<String>) -> Self {
        BufferComparison {
            stage,
            buffer: buffer.into(),
            elements: 0,
            int_mismatches: 0,
            first_int: None,
            float_words: 0,
            ulp_histogram: [0; ULP_BUCKETS],
            worst: None,
            pixel_ulps: None,
        }
    }

    /// Largest float ulp distance (0 when none differ).
    pub fn max_ulp(&self) -> u64 {
        self.worst.as_ref().and_then(|w| w.ulp).unwrap_or(0)
    }

    /// Float words that differ.
    pub fn float_mismatches(&self) -> u64 {
        self.ulp_histogram[1..].iter().sum()
    }

    /// True if every word is identical.
    pub fn is_exact(&self) -> bool {
        self.int_mismatches == 0 && self.float_mismatches() == 0
    }

    fn note_int(&mut self, d: impl FnOnce() -> Difference) {
        self.int_mismatches += 1;
        if self.first_int.is_none() {
            self.first_int = Some(d());
        }
    }

    /// Compare two records word by word; returns the record's largest float ulp.
    fn compare_words(&mut self, words: &[Word], at: Location, e: &[u32], a: &[u32]) -> u64 {
        debug_assert_eq!(words.len(), e.len());
        let mut int_differs = None;
        let mut rec_max = 0;
        for ((w, &eb), &ab) in words.iter().zip(e).zip(a) {
            match *w {
                Word::Int(name) => {
                    if eb != ab && int_differs.is_none() {
                        int_differs = Some(Difference {
                            at,
                            word: name,
                            expected: format!("{eb}"),
                            actual: format!("{ab}"),
                            ulp: None,
                        });
                    }
                }
                Word::Float(name) => {
                    let (ef, af) = (f32::from_bits(eb), f32::from_bits(ab));
                    // Bits decide: +0 against -0 is 0 ulp apart but not the same word (1 here).
                    let ulp = if eb == ab { 0 } else { ulp_distance(ef, af).max(1) };
                    self.float_words += 1;
                    self.ulp_histogram[ulp_bucket(ulp)] += 1;
                    rec_max = rec_max.max(ulp);
                    if ulp > self.max_ulp() || (ulp > 0 && self.worst.is_none()) {
                        self.worst = Some(Difference {
                            at,
                            word: name,
                            expected: format!("{ef:e} ({eb:#010x})"),
                            actual: format!("{af:e} ({ab:#010x})"),
                            ulp: Some(ulp),
                        });
                    }
                }
            }
        }
        if let Some(d) = int_differs {
            self.note_int(|| d);
        }
        rec_max
    }
}

fn words_of<T: bytemuck::Pod>(x: &T) -> &[u32] {
    bytemuck::cast_slice(bytemuck::bytes_of(x))
}

fn pixel_of(width: u32, index: usize) -> Option<(u32, u32)> {
    (width > 0).then(|| ((index % width as usize) as u32, (index / width as usize) as u32))
}

/// Compare a per-pixel buffer. `skip` masks pixels whose inputs already differ
/// (reported upstream).
fn compare_per_pixel<T: bytemuck::Pod>(
    stage: Stage,
    buffer: &str,
    words: &[Word],
    width: u32,
    expected: &[T],
    actual: &[T],
    skip: &[bool],
) -> BufferComparison {
    let mut c = BufferComparison::new(stage, buffer);
    if expected.len() != actual.len() {
        c.elements = expected.len().max(actual.len());
        c.note_int(|| Difference {
            at: Location { index: expected.len().min(actual.len()), pixel: None, light: None },
            word: "length",
            expected: expected.len().to_string(),
            actual: actual.len().to_string(),
            ulp: None,
        });
        return c;
    }
    c.elements = expected.len();
    let mut pixel_ulps = vec![0u64; expected.len()];
    for (i, (e, a)) in expected.iter().zip(actual).enumerate() {
        if skip.get(i).copied().unwrap_or(false) {
            continue;
        }
        let at = Location { index: i, pixel: pixel_of(width, i), light: None };
        pixel_ulps[i] = c.compare_words(words, at, words_of(e), words_of(a));
    }
    if pixel_ulps.iter().any(|&u| u > 0) {
        c.pixel_ulps = Some(pixel_ulps);
    }
    c
}

/// Compare two frames of the same scene, camera and options, buffer by buffer.
/// Returns one [`BufferComparison`] per frame buffer either frame holds
/// ([`Frame::buffers`], in stage order: `gbuffer`, `surfaces`, `rays`, `occluded`,
/// `shadow`, `rt`, `raster`, `final`), so a stage the plan skipped is not compared;
/// a buffer only one frame holds is one `presence` difference.
pub fn compare_stages(expected: &Frame, actual: &Frame) -> Vec<BufferComparison> {
    let width = expected.width;
    let pixels = (expected.width * expected.height) as usize;
    if (expected.width, expected.height) != (actual.width, actual.height) {
        let mut c = BufferComparison::new(Stage::VisibilityRaster, "gbuffer");
        c.note_int(|| Difference {
            at: Location { index: 0, pixel: None, light: None },
            word: "size",
            expected: format!("{}x{}", expected.width, expected.height),
            actual: format!("{}x{}", actual.width, actual.height),
            ulp: None,
        });
        return vec![c];
    }
    // Pixels whose primary visibility differs: everything downstream of them differs
    // for that reason alone and is reported once, in the G-buffer.
    let id_differs: Vec<bool> = (0..pixels)
        .map(|i| match (expected.gbuffer.get(i), actual.gbuffer.get(i)) {
            (Some(e), Some(a)) => (e.triangle, e.object, e.flags) != (a.triangle, a.object, a.flags),
            _ => true,
        })
        .collect();
    let (mut rays, mut occluded) = compare_rays(expected, actual, width, &id_differs);

    let mut out = Vec::new();
    for buffer in FrameBuffer::ALL {
        let (stage, name) = (buffer.writer(), buffer.name());
        match (expected.holds(buffer), actual.holds(buffer)) {
            (false, false) => continue,
            (e, a) if e != a => {
                out.push(presence_differs(stage, name, e));
                continue;
            }
            _ => {}
        }
        out.push(match buffer {
            FrameBuffer::GBuffer => compare_per_pixel::<GBufferTexel>(
                stage,
                name,
                &GBUFFER_WORDS,
                width,
                &expected.gbuffer,
                &actual.gbuffer,
                &[],
            ),
            FrameBuffer::Surfaces => compare_per_pixel::<SurfaceRecord>(
                stage,
                name,
                &SURFACE_WORDS,
                width,
                &expected.surfaces,
                &actual.surfaces,
                &id_differs,
            ),
            FrameBuffer::Rays => std::mem::replace(&mut rays, BufferComparison::new(stage, name)),
            FrameBuffer::Occluded => std::mem::replace(&mut occluded, BufferComparison::new(stage, name)),
            FrameBuffer::Shadow => compare_shadow(expected, actual, width, &id_differs),
            // Channels per pixel (`visibility_channels`): compared value by value, located
            // by index (width 0: no pixel coordinates).
            FrameBuffer::Visibility => compare_per_pixel::<f32>(
                stage,
                name,
                &[Word::Float("value")],
                0,
                &expected.visibility,
                &actual.visibility,
                &[],
            ),
            FrameBuffer::Rt => {
                compare_per_pixel(stage, name, &RGBA_WORDS, width, &expected.rt, &actual.rt, &id_differs)
            }
            FrameBuffer::Raster => {
                compare_per_pixel(stage, name, &RGBA_WORDS, width, &expected.raster, &actual.raster, &id_differs)
            }
            FrameBuffer::Final => compare_per_pixel(
                stage,
                name,
                &RGBA_WORDS,
                width,
                &expected.final_image,
                &actual.final_image,
                &id_differs,
            ),
            FrameBuffer::Bounce { .. } => unreachable!("FrameBuffer::ALL holds the primary buffers only"),
        });
    }
    compare_bounces(expected, actual, &mut out);
    out
}

/// A buffer one frame holds and the other does not (`expected_holds` says which).
fn presence_differs(stage: Stage, name: &str, expected_holds: bool) -> BufferComparison {
    let mut c = BufferComparison::new(stage, name);
    let side = |held: bool| if held { "held" } else { "absent" }.to_string();
    c.note_int(|| Difference {
        at: Location { index: 0, pixel: None, light: None },
        word: "presence",
        expected: side(expected_holds),
        actual: side(!expected_holds),
        ulp: None,
    });
    c
}

/// The bounce buffers of every depth either frame planned, each in list order (the
/// lists are deterministic: the same parents spawn the same rays in the same order on
/// every backend). A buffer one frame holds and the other does not is one difference.
fn compare_bounces(expected: &Frame, actual: &Frame, out: &mut Vec<BufferComparison>) {
    let depth = expected.plan.bounce_depth().max(actual.plan.bounce_depth());
    for d in 1..=depth {
        for b in BounceBuffer::ALL {
            let buffer = b.at(d);
            let (stage, name) = (buffer.writer(), buffer.label());
            let (e, a) = (expected.holds(buffer), actual.holds(buffer));
            if !e && !a {
                continue;
            }
            if e != a {
                out.push(presence_differs(stage, &name, e));
                continue;
            }
            let (eb, ab) = (&expected.bounces[d as usize - 1], &actual.bounces[d as usize - 1]);
            let codes = |v: &[u8]| v.iter().map(|&c| c as u32).collect::<Vec<u32>>();
            out.push(match b {
                BounceBuffer::Rays => in_list_order(stage, &name, &RAY_WORDS, &eb.rays, &ab.rays),
                BounceBuffer::Links => in_list_order(stage, &name, &LINK_WORDS, &eb.links, &ab.links),
                BounceBuffer::Hits => in_list_order(stage, &name, &HIT_WORDS, &eb.hits, &ab.hits),
                BounceBuffer::Surfaces => in_list_order(stage, &name, &SURFACE_WORDS, &eb.surfaces, &ab.surfaces),
                BounceBuffer::ShadowRays => in_list_order(stage, &name, &RAY_WORDS, &eb.shadow_rays, &ab.shadow_rays),
                BounceBuffer::Occluded => in_list_order(stage, &name, &WORD, &eb.occluded, &ab.occluded),
                BounceBuffer::Shadow => in_list_order(stage, &name, &WORD, &codes(&eb.shadow), &codes(&ab.shadow)),
                BounceBuffer::Radiance => in_list_order(stage, &name, &RGBA_WORDS, &eb.radiance, &ab.radiance),
            });
        }
    }
}

/// A buffer of a ray list, compared record by record in list order (no pixel location).
fn in_list_order<T: bytemuck::Pod>(
    stage: Stage,
    name: &str,
    words: &[Word],
    expected: &[T],
    actual: &[T],
) -> BufferComparison {
    compare_per_pixel(stage, name, words, 0, expected, actual, &[])
}

/// `compaction`'s rays and `shadow_rays`' occlusion results. Rays are matched by
/// (light, pixel) (the list is light-major, pixel order), so one missing ray leaves
/// the rest aligned; without ray lists (a frame without stage outputs) the occlusion
/// results are compared in list order.
fn compare_rays(
    expected: &Frame,
    actual: &Frame,
    width: u32,
    id_differs: &[bool],
) -> (BufferComparison, BufferComparison) {
    let mut rays = BufferComparison::new(Stage::Compaction, FrameBuffer::Rays.name());
    let mut occ = BufferComparison::new(Stage::ShadowRays, FrameBuffer::Occluded.name());
    let with_rays = expected.holds(FrameBuffer::Rays) && actual.holds(FrameBuffer::Rays);
    let (eo_all, ao_all) = (&expected.occluded, &actual.occluded);
    if !with_rays {
        for (k, (eo, ao)) in eo_all.iter().zip(ao_all).enumerate() {
            occ.elements += 1;
            if eo != ao {
                occ.note_int(|| Difference {
                    at: Location { index: k, pixel: None, light: None },
                    word: "occluded",
                    expected: eo.to_string(),
                    actual: ao.to_string(),
                    ulp: None,
                });
            }
        }
    }
    let key = |r: &RayRecord| (r.light, r.pixel);
    let (mut i, mut j) = (0usize, 0usize);
    let (er, ar): (&[RayRecord], &[RayRecord]) = if with_rays { (&expected.rays, &actual.rays) } else { (&[], &[]) };
    while i < er.len() || j < ar.len() {
        let (ke, ka) = (er.get(i).map(key), ar.get(j).map(key));
        let one_sided = |r: &RayRecord, index: usize, expected_side: bool| {
            let at = Location { index, pixel: pixel_of(width, r.pixel as usize), light: Some(r.light) };
            let (e, a) = if expected_side { ("a ray", "none") } else { ("none", "a ray") };
            Difference { at, word: "presence", expected: e.into(), actual: a.into(), ulp: None }
        };
        match (ke, ka) {
            (Some(a), Some(b)) if a == b => {
                rays.elements += 1;
                let px = er[i].pixel as usize;
                if !id_differs.get(px).copied().unwrap_or(true) {
                    let at = Location { index: i, pixel: pixel_of(width, px), light: Some(er[i].light) };
                    rays.compare_words(&RAY_WORDS, at, words_of(&er[i]), words_of(&ar[j]));
                    occ.elements += 1;
                    let (eo, ao) = (eo_all.get(i), ao_all.get(j));
                    if eo != ao {
                        occ.note_int(|| Difference {
                            at,
                            word: "occluded",
                            expected: format!("{eo:?}"),
                            actual: format!("{ao:?}"),
                            ulp: None,
                        });
                    }
                }
                i += 1;
                j += 1;
            }
            (Some(a), b) if b.is_none() || a < b.unwrap() => {
                rays.elements += 1;
                let px = er[i].pixel as usize;
                if !id_differs.get(px).copied().unwrap_or(true) {
                    rays.note_int(|| one_sided(&er[i], i, true));
                }
                i += 1;
            }
            _ => {
                rays.elements += 1;
                let px = ar[j].pixel as usize;
                if !id_differs.get(px).copied().unwrap_or(true) {
                    rays.note_int(|| one_sided(&ar[j], j, false));
                }
                j += 1;
            }
        }
    }
    let lengths_agree =
        if with_rays { eo_all.len() == er.len() && ao_all.len() == ar.len() } else { eo_all.len() == ao_all.len() };
    if !lengths_agree {
        occ.note_int(|| Difference {
            at: Location { index: 0, pixel: None, light: None },
            word: "length",
            expected: format!("{} (rays {})", eo_all.len(), er.len()),
            actual: format!("{} (rays {})", ao_all.len(), ar.len()),
            ulp: None,
        });
    }
    (rays, occ)
}

/// `shadow_rays`' per (pixel, light) visibility codes.
fn compare_shadow(expected: &Frame, actual: &Frame, width: u32, id_differs: &[bool]) -> BufferComparison {
    let pixels = (expected.width * expected.height) as usize;
    let mut shadow = BufferComparison::new(Stage::ShadowRays, FrameBuffer::Shadow.name());
    let lights = expected.shadow.len().checked_div(pixels).unwrap_or(0);
    if expected.shadow.len() != actual.shadow.len() {
        shadow.note_int(|| Difference {
            at: Location { index: 0, pixel: None, light: None },
            word: "length",
            expected: expected.shadow.len().to_string(),
            actual: actual.shadow.len().to_string(),
            ulp: None,
        });
        return shadow;
    }
    for (k, (e, a)) in expected.shadow.iter().zip(&actual.shadow).enumerate() {
        let px = k / lights.max(1);
        if id_differs.get(px).copied().unwrap_or(true) {
            continue;
        }
        shadow.elements += 1;
        if e != a {
            let at = Location { index: k, pixel: pixel_of(width, px), light: Some((k % lights.max(1)) as u32) };
            shadow.note_int(|| Difference {
                at,
                word: "visibility",
                expected: e.to_string(),
                actual: a.to_string(),
                ulp: None,
            });
        }
    }
    shadow
}

#[cfg(test)]
mod tests {
    use super::*;
    use hyrt_core::formats::{GBUF_HIT, INVALID_ID, RAY_KIND_SHADOW};
    use hyrt_core::plan::{FramePlan, SceneNeeds};

    fn frame(w: u32, h: u32) -> Frame {
        let n = (w * h) as usize;
        Frame {
            width: w,
            height: h,
            gbuffer: vec![GBufferTexel::MISS; n],
            surfaces: vec![SurfaceRecord::MISS; n],
            raster: vec![[0.0; 4]; n],
            rt: vec![[0.0; 4]; n],
            final_image: vec![[0.0; 4]; n],
            shadow: vec![0; n],
            plan: FramePlan::from_counts(SceneNeeds::every_primary_stage(1)),
            stage_outputs: true,
            ..Frame::default()
        }
    }

    fn shadow_ray(pixel: u32) -> RayRecord {
        RayRecord {
            origin: [0.0; 3],
            t_min: 0.0,
            direction: [0.0, 1.0, 0.0],
            t_max: 1.0,
            pixel,
            kind: RAY_KIND_SHADOW,
            depth: 0,
            light: 0,
            throughput: [1.0; 3],
            cone: 0.0,
        }
    }

    #[test]
    fn ulp_buckets_are_powers_of_two() {
        assert_eq!(ulp_bucket(0), 0);
        assert_eq!(ulp_bucket(1), 1);
        assert_eq!((ulp_bucket(2), ulp_bucket(3), ulp_bucket(4)), (2, 2, 3));
        assert_eq!(ulp_bucket(u64::MAX), ULP_BUCKETS - 1);
        assert_eq!(ulp_bucket_label(3), "4-7");
    }

    #[test]
    fn the_sign_of_zero_is_a_difference() {
        let e = frame(2, 1);
        let mut a = e.clone();
        a.final_image[1][0] = -0.0;
        let c = compare_stages(&e, &a);
        let fin = c.iter().find(|c| c.buffer == "final").unwrap();
        assert!(!fin.is_exact() && fin.max_ulp() == 1, "{fin:?}");
    }

    #[test]
    fn identical_frames_compare_exact() {
        let f = frame(5, 3);
        assert!(compare_stages(&f, &f.clone()).iter().all(|c| c.is_exact()));
    }

    #[test]
    fn float_difference_is_counted_in_ulp_with_its_pixel() {
        let e = frame(5, 3);
        let mut a = e.clone();
        a.final_image[7][1] = f32::from_bits(a.final_image[7][1].to_bits() + 5);
        let c = compare_stages(&e, &a);
        let fin = c.iter().find(|c| c.buffer == "final").unwrap();
        assert_eq!(fin.int_mismatches, 0);
        assert_eq!(fin.float_mismatches(), 1);
        assert_eq!(fin.ulp_histogram[ulp_bucket(5)], 1);
        let w = fin.worst.as_ref().unwrap();
        assert_eq!((w.at.pixel, w.word, w.ulp), (Some((2, 1)), "g", Some(5)));
        assert_eq!(fin.pixel_ulps.as_ref().unwrap()[7], 5);
    }

    #[test]
    fn id_mismatch_is_reported_once_upstream() {
        let mut e = frame(4, 2);
        e.gbuffer[3] = GBufferTexel { triangle: 1, object: 0, flags: GBUF_HIT, ..GBufferTexel::MISS };
        e.rays = vec![shadow_ray(3)];
        e.occluded = vec![1];
        e.final_image[3] = [0.5; 4];
        let mut a = frame(4, 2);
        a.gbuffer[3] = GBufferTexel { triangle: 2, ..e.gbuffer[3] };
        a.rays = vec![shadow_ray(3)];
        a.occluded = vec![0];
        let c = compare_stages(&e, &a);
        assert_eq!(c[0].int_mismatches, 1);
        assert_eq!(c[0].first_int.as_ref().unwrap().word, "triangle");
        assert!(c[1..].iter().all(|c| c.is_exact()), "downstream of a differing pixel is not counted again");
    }

    #[test]
    fn missing_ray_is_a_compaction_mismatch_and_the_rest_still_align() {
        let mut e = frame(4, 2);
        e.rays = vec![shadow_ray(1), shadow_ray(2), shadow_ray(5)];
        e.occluded = vec![0, 1, 0];
        let mut a = frame(4, 2);
        a.rays = vec![shadow_ray(1), shadow_ray(5)];
        a.occluded = vec![0, 1];
        let c = compare_stages(&e, &a);
        let rays = c.iter().find(|c| c.buffer == "rays").unwrap();
        assert_eq!(rays.int_mismatches, 1);
        assert_eq!(rays.first_int.as_ref().unwrap().at.pixel, Some((2, 0)));
        let occ = c.iter().find(|c| c.buffer == "occluded").unwrap();
        assert_eq!(occ.int_mismatches, 1, "ray of pixel 5 aligned with its twin: 0 vs 1");
        assert_eq!(occ.first_int.as_ref().unwrap().at.pixel, Some((1, 1)));
        let _ = INVALID_ID;
    }
}
