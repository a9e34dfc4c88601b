//! Bounce stages of a CPU frame with one step changed: secondary-ray origins offset by
//! another [`OffsetMethod`] than the pipeline's, or another throughput cut-off than
//! `kernels::bounce::MIN_THROUGHPUT`. Everything else is the `hyrt_cpu` stage functions
//! as `CpuBackend` runs them ([`bounce_rt_image`]), so with [`BounceVariant::PIPELINE`]
//! the frame is the backend's bit for bit (tested).

use std::time::Instant;

use glam::Vec3;
use hyrt_core::bvh::Bvh;
use hyrt_core::formats::{GBufferTexel, HitRecord, RayRecord, SurfaceRecord, INVALID_ID, RAY_KIND_REFRACTION};
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::kernels::bounce::{bounces, spawn, Parent};
use hyrt_core::kernels::texture::Materials;
use hyrt_cpu::bounce_shading::{bounce_shading_into, Children};
use hyrt_cpu::bounce_trace::bounce_trace_into;
use hyrt_cpu::compaction::{compaction_into, shadow_mask_into, CompactionScratch};
use hyrt_cpu::raster_shading::Primary;
use hyrt_cpu::rt_shading::{rt_shading_bouncing_into, rt_shading_into, FirstBounce};
use hyrt_cpu::secondary_rays::{secondary_rays_into, Parents};
use hyrt_cpu::shadow_rays::shadow_rays_with;
use hyrt_cpu::traversal::Traversal;
use rayon::prelude::*;

use crate::variants::OffsetMethod;

/// `log2` of the pipeline's throughput cut-off `kernels::bounce::MIN_THROUGHPUT` (1/256;
/// a test checks they agree).
pub const PIPELINE_CUTOFF_LOG2: i32 = -8;

/// `log2` of the cut-off the report calls "none": what a lobe of path weight below 2^-64
/// brings is below half an ulp of its pixel (2^-25 of the pixel's value) unless it sees
/// radiance 2^39 times the pixel's, so nothing it cuts can show. (0 itself cannot be
/// expressed by [`spawn_with_cutoff`]'s exact scaling.)
pub const NO_CUTOFF_LOG2: i32 = -64;

// The scale of the "none" cut-off (2^56) keeps path weights up to 2^71 below f32's
// largest power of two, 2^127: far above any weight (each lobe weighs at most 1 for
// glTF colours in [0, 1]).
const _: () = assert!(PIPELINE_CUTOFF_LOG2 - NO_CUTOFF_LOG2 <= 127 - 71);

/// The throughput cut-offs the report compares (`log2`): none, 1/1024, the pipeline's
/// 1/256, 1/64, 1/16.
pub const CUTOFFS_LOG2: [i32; 5] = [NO_CUTOFF_LOG2, -10, PIPELINE_CUTOFF_LOG2, -6, -4];

/// `2^e` exactly, for `e` in f32's normal range (-126..=127).
pub fn pow2(e: i32) -> f32 {
    assert!((-126..=127).contains(&e), "2^{e} is not a normal f32");
    f32::from_bits(((127 + e) as u32) << 23)
}

/// The name of the cut-off `2^log2` in the report: `none (2^-64)`, `1/256`.
pub fn cutoff_name(log2: i32) -> String {
    if log2 == NO_CUTOFF_LOG2 {
        format!("none (2^{log2})")
    } else if log2 <= 0 {
        format!("1/{}", 1u64 << (-log2))
    } else {
        format!("{}", 1u64 << log2)
    }
}

/// How a frame spawns its secondary rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BounceVariant {
    /// How the origins leave the surface ([`reoffset_secondary_rays`] unless it is
    /// [`OffsetMethod::PIPELINE`]).
    pub offset: OffsetMethod,
    /// `log2` of the throughput cut-off, spawned by [`spawn_with_cutoff`]; `None`: the
    /// pipeline's `secondary_rays` stage itself.
    pub cutoff_log2: Option<i32>,
}

impl BounceVariant {
    /// The pipeline's frame.
    pub const PIPELINE: BounceVariant = BounceVariant { offset: OffsetMethod::PIPELINE, cutoff_log2: None };
}

/// The `secondary_rays` stage with the throughput cut-off `2^cutoff_log2` instead of
/// `MIN_THROUGHPUT`: the rays of bounce `depth` into `rays` (parents' order, reflection
/// before refraction), each parent's `[reflection, refraction]` child indices into `links`.
///
/// The pipeline's own kernel (`kernels::bounce::spawn`) spawns them, with each parent's
/// path weight scaled by `MIN_THROUGHPUT / 2^cutoff_log2` (a power of two) and each
/// ray's weight scaled back: its test `weight >= MIN_THROUGHPUT` becomes
/// `weight >= 2^cutoff_log2`, and scaling by a power of two is exact while the weights
/// stay in f32's normal range (above 2^-126, far below every cut-off compared here but
/// "none"), so directions, origins and weights are the pipeline's bit for bit. At
/// `PIPELINE_CUTOFF_LOG2` it gives the stage's output (tested).
pub fn spawn_with_cutoff(
    parents: Parents,
    materials: &Materials,
    triangles: &hyrt_core::geometry::WorldTriangles,
    depth: u32,
    cutoff_log2: i32,
    rays: &mut Vec<RayRecord>,
    links: &mut Vec<[u32; 2]>,
) {
    let scale = pow2(PIPELINE_CUTOFF_LOG2 - cutoff_log2);
    let unscale = pow2(cutoff_log2 - PIPELINE_CUTOFF_LOG2);
    let n = parents.len();
    let bouncing: Vec<u32> = (0..n as u32)
        .into_par_iter()
        .with_min_len(4096)
        .filter(|&i| parents.may_bounce(i as usize, materials.objects))
        .collect();
    let spawned: Vec<[Option<RayRecord>; 2]> = bouncing
        .par_iter()
        .with_min_len(256)
        .map(|&i| {
            let p = parents.get(i as usize, materials);
            let scaled = Parent { throughput: p.throughput * scale, ..p };
            spawn(&scaled, triangles, depth)
                .map(|r| r.map(|r| RayRecord { throughput: (Vec3::from(r.throughput) * unscale).into(), ..r }))
        })
        .collect();
    links.clear();
    links.resize(n, [INVALID_ID; 2]);
    rays.clear();
    for (&i, pair) in bouncing.iter().zip(&spawned) {
        for (lobe, r) in pair.iter().enumerate() {
            if let Some(r) = r {
                links[i as usize][lobe] = rays.len() as u32;
                rays.push(*r);
            }
        }
    }
}

/// Re-aim the origins of the secondary rays of `parents` (as spawned, with their
/// `links`) by `method`, as [`crate::variants::reoffset_rays`] does for shadow rays:
/// reflection rays leave to the seen side of the parent's geometric normal, refraction
/// rays to the other side; directions, `t_min` and `t_max` are kept.
pub fn reoffset_secondary_rays(
    rays: &mut [RayRecord],
    links: &[[u32; 2]],
    parents: &Parents,
    method: OffsetMethod,
    scene_extent: f32,
) {
    let mut parent_of = vec![INVALID_ID; rays.len()];
    for (i, l) in links.iter().enumerate() {
        for &child in l.iter().filter(|&&c| c != INVALID_ID) {
            parent_of[child as usize] = i as u32;
        }
    }
    rays.par_iter_mut().zip(parent_of.par_iter()).with_min_len(1024).for_each(|(r, &i)| {
        let s = parents.surface(i as usize);
        let ng = Vec3::from(s.geometric_normal);
        let side = if r.kind == RAY_KIND_REFRACTION { -ng } else { ng };
        r.origin = method.origin(Vec3::from(s.position), s.position_error, side, scene_extent).into();
    });
}

/// The buffers of one bounce.
#[derive(Default)]
struct Level {
    rays: Vec<RayRecord>,
    links: Vec<[u32; 2]>,
    hits: Vec<HitRecord>,
    surfaces: Vec<SurfaceRecord>,
    shadow_rays: Vec<RayRecord>,
    occluded: Vec<u32>,
    shadow: Vec<u8>,
    radiance: Vec<[f32; 4]>,
}

/// The ray-traced image of a frame with bounces ([`bounce_rt_image`]).
pub struct BounceRt {
    /// `rt_shading`'s output.
    pub rt: Vec<[f32; 4]>,
    /// Secondary rays traced, all bounces.
    pub rays: u64,
    /// Time of the bounce stages (`secondary_rays` to `bounce_shading`, every depth), ms.
    pub bounce_ms: f64,
}

/// What a frame's bounce stages need from its first stages.
#[derive(Clone, Copy)]
pub struct PrimaryBuffers<'a> {
    pub gbuffer: &'a [GBufferTexel],
    pub surfaces: &'a [SurfaceRecord],
    /// `shadow_rays`' mask (`pixel * lights + light`).
    pub shadow: &'a [u8],
    pub eye: Vec3,
}

/// The frame's stages from `secondary_rays` to `rt_shading` with bounces down to
/// `max_depth`, as `CpuBackend` runs them (packet traversal), with `variant`'s change.
/// Plans no bounce, as `FramePlan` does, where `max_depth` is 0 or no object bounces.
pub fn bounce_rt_image(
    g: &WorldGeometry,
    bvh: &Bvh,
    primary: PrimaryBuffers,
    max_depth: u32,
    variant: BounceVariant,
) -> BounceRt {
    let PrimaryBuffers { gbuffer, surfaces, shadow, eye } = primary;
    let depth = if g.objects.iter().any(bounces) { max_depth as usize } else { 0 };
    // The CPU frame's traversals: packets for shadow rays, single rays for bounces.
    let (traversal, bounce_traversal) = (Traversal::simd(), Traversal::for_bounces());
    // The lab's scenes are untextured: every point is its object's record.
    let materials = Materials::plain(&g.objects);
    let extent = g.scene_extent();
    let mut scratch = CompactionScratch::default();
    let mut closest = Vec::new();
    let t = Instant::now();
    let mut levels: Vec<Level> = Vec::with_capacity(depth);
    for d in 1..=depth as u32 {
        let mut b = Level::default();
        let parents = match levels.last() {
            None => Parents::Primary { gbuffer, surfaces, eye },
            Some(prev) => Parents::Secondary { rays: &prev.rays, hits: &prev.hits, surfaces: &prev.surfaces },
        };
        match variant.cutoff_log2 {
            None => secondary_rays_into(parents, &materials, &g.triangles, d, &mut b.rays, &mut b.links)
                .unwrap_or_else(|e| panic!("secondary_rays: {e}")),
            Some(e) => spawn_with_cutoff(parents, &materials, &g.triangles, d, e, &mut b.rays, &mut b.links),
        }
        if variant.offset != OffsetMethod::PIPELINE {
            reoffset_secondary_rays(&mut b.rays, &b.links, &parents, variant.offset, extent);
        }
        bounce_trace_into(
            bvh,
            None,
            g,
            &materials,
            &b.rays,
            bounce_traversal,
            &mut closest,
            &mut b.hits,
            &mut b.surfaces,
        );
        if !g.lights.is_empty() {
            compaction_into(&b.surfaces, &g.lights, &mut scratch, &mut b.shadow_rays)
                .unwrap_or_else(|e| panic!("compaction: {e}"));
            shadow_rays_with(bvh, g, &b.shadow_rays, traversal, &mut b.occluded);
            shadow_mask_into(&b.shadow_rays, &b.occluded, b.surfaces.len(), g.lights.len(), &mut b.shadow);
        }
        levels.push(b);
    }
    for d in (0..depth).rev() {
        let (this, deeper) = levels.split_at_mut(d + 1);
        let b = &mut this[d];
        let children = deeper.first().map(|n| Children { links: &n.links, radiance: &n.radiance });
        bounce_shading_into(
            &b.rays,
            &b.hits,
            &b.surfaces,
            &b.shadow,
            &materials,
            &g.triangles,
            &g.lights,
            &g.environment,
            &g.ambient,
            children,
            &mut b.radiance,
        );
    }
    let bounce_ms = t.elapsed().as_secs_f64() * 1e3;
    let mut rt = Vec::new();
    match levels.first() {
        None => {
            let primary =
                Primary { gbuffer, materials: &materials, ambient: &g.ambient, eye, visibility: Default::default() };
            rt_shading_into(surfaces, shadow, &primary, &g.lights, &mut rt)
        }
        Some(first) => {
            let bounce = FirstBounce { gbuffer, links: &first.links, radiance: &first.radiance };
            let lights = &g.lights;
            rt_shading_bouncing_into(
                surfaces,
                shadow,
                &materials,
                &g.triangles,
                lights,
                &g.ambient,
                eye,
                bounce,
                Default::default(),
                &mut rt,
            )
        }
    }
    BounceRt { rt, rays: levels.iter().map(|b| b.rays.len() as u64).sum(), bounce_ms }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hyrt_core::kernels::bounce::MIN_THROUGHPUT;

    #[test]
    fn the_pipeline_cutoff_is_min_throughput_and_powers_of_two_are_exact() {
        assert_eq!(pow2(PIPELINE_CUTOFF_LOG2), MIN_THROUGHPUT);
        assert_eq!(pow2(0), 1.0);
        assert_eq!(pow2(-126), f32::MIN_POSITIVE);
        assert_eq!(pow2(127), 2f32.powi(127));
        assert_eq!(cutoff_name(-8), "1/256");
        assert_eq!(cutoff_name(NO_CUTOFF_LOG2), "none (2^-64)");
    }
}
