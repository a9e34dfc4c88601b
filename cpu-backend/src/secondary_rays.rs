//! Stage `secondary_rays`: the surfaces of depth `d - 1` that bounce (ray-traced mirrors
//! and glass, [`hyrt_core::kernels::bounce`]) spawn the reflection and refraction rays
//! of depth `d`, compacted into one ray list (the paper's compaction again: one entry
//! per ray that is traced, none for the parents that spawn nothing).
//!
//! Inputs: for `d = 1` the G-buffer and the primary surfaces (one parent per pixel),
//! else the rays, hits and surfaces of depth `d - 1` (one parent per ray); the materials and
//! triangles. Outputs: the rays of depth `d`, in their parents' order, reflection before
//! refraction; and per parent its `[reflection, refraction]` child indices
//! (`INVALID_ID` where that lobe spawned no ray), which `bounce_shading` and
//! `rt_shading` gather through.
//!
//! Each parent is examined twice, as `compaction` does: once to flag the rays that
//! exist, once to build the survivors after the scan. The kernel is
//! [`hyrt_core::kernels::bounce::spawn`].

use std::collections::TryReserveError;

use glam::Vec3;
use hyrt_core::formats::{GBufferTexel, HitRecord, ObjectRecord, RayRecord, SurfaceRecord, INVALID_ID};
use hyrt_core::geometry::WorldTriangles;
use hyrt_core::kernels::bounce::{bounces, primary_parent, secondary_parent, spawn, Parent};
use hyrt_core::kernels::texture::Materials;
use rayon::prelude::*;

use crate::compaction::{compact_into, CompactionScratch};

/// The parents of one bounce: what [`secondary_rays_into`] spawns from.
#[derive(Clone, Copy)]
pub enum Parents<'a> {
    /// The primary hits: one parent per pixel, seen from `eye`.
    Primary { gbuffer: &'a [GBufferTexel], surfaces: &'a [SurfaceRecord], eye: Vec3 },
    /// The hits of the previous bounce: one parent per ray.
    Secondary { rays: &'a [RayRecord], hits: &'a [HitRecord], surfaces: &'a [SurfaceRecord] },
    /// Some pixels' primary hits, seen from `eye`: parent `i` is pixel `pixels[i]`, with
    /// texel `texels[i]` and surface `surfaces[i]` (the fused frame's bouncing pixels,
    /// `crate::fused`: in pixel order, they spawn the rays [`Parents::Primary`] spawns).
    Pixels { pixels: &'a [u32], texels: &'a [GBufferTexel], surfaces: &'a [SurfaceRecord], eye: Vec3 },
}

impl<'a> Parents<'a> {
    /// How many parents there are.
    pub fn len(&self) -> usize {
        match self {
            Parents::Primary { surfaces, .. }
            | Parents::Secondary { surfaces, .. }
            | Parents::Pixels { surfaces, .. } => surfaces.len(),
        }
    }

    /// True when there is none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether parent `i` can spawn anything: it hit an object that bounces. The cheap
    /// test before [`Parents::get`] (which normalizes the view direction): most pixels of
    /// a frame do not bounce.
    #[inline]
    pub fn may_bounce(&self, i: usize, objects: &[ObjectRecord]) -> bool {
        may_bounce(self.surface(i), objects)
    }

    /// The surface of parent `i`.
    #[inline]
    pub fn surface(&self, i: usize) -> &'a SurfaceRecord {
        match *self {
            Parents::Primary { surfaces, .. }
            | Parents::Secondary { surfaces, .. }
            | Parents::Pixels { surfaces, .. } => &surfaces[i],
        }
    }

    /// Parent `i`, its object shaded as `materials` see it there.
    #[inline]
    pub fn get(&self, i: usize, materials: &Materials) -> Parent<'a> {
        match *self {
            Parents::Primary { gbuffer, surfaces, eye } => {
                primary_parent(&gbuffer[i], &surfaces[i], eye, i as u32, materials)
            }
            Parents::Secondary { rays, hits, surfaces } => {
                secondary_parent(&rays[i], &hits[i], &surfaces[i], materials)
            }
            Parents::Pixels { pixels, texels, surfaces, eye } => {
                primary_parent(&texels[i], &surfaces[i], eye, pixels[i], materials)
            }
        }
    }
}

/// Whether surface `s` can spawn secondary rays: it hit an object that bounces
/// ([`bounces`]). [`Parents::may_bounce`]'s test; the fused frame defers the pixels it
/// holds for (`crate::fused`).
#[inline]
pub fn may_bounce(s: &SurfaceRecord, objects: &[ObjectRecord]) -> bool {
    s.is_hit() && bounces(&objects[s.object as usize])
}

/// The stage into caller-owned buffers (allocations reused): the rays of bounce `depth`
/// into `rays`, each parent's child indices into `links`. An error where the allocator
/// cannot hold the flags, the list or the links (the frame then fails with
/// `RenderError::OutOfMemory` instead of aborting).
pub fn secondary_rays_into(
    parents: Parents,
    materials: &Materials,
    triangles: &WorldTriangles,
    depth: u32,
    scratch: &mut CompactionScratch,
    rays: &mut Vec<RayRecord>,
    links: &mut Vec<[u32; 2]>,
) -> Result<(), TryReserveError> {
    let n = parents.len();
    // Every flag is written below: resizing alone leaves a reused buffer untouched.
    crate::memory::reserve(&mut scratch.flags, 2 * n)?;
    scratch.flags.resize(2 * n, 0);
    scratch.flags.par_chunks_mut(2).enumerate().with_min_len(1024).for_each(|(i, f)| {
        if !parents.may_bounce(i, materials.objects) {
            f[0] = 0;
            f[1] = 0;
            return;
        }
        let r = spawn(&parents.get(i, materials), triangles, depth);
        f[0] = r[0].is_some() as u32;
        f[1] = r[1].is_some() as u32;
    });
    compact_into(&scratch.flags, &mut scratch.active)?;
    crate::memory::reserve(rays, scratch.active.len())?;
    crate::memory::reserve(links, n)?;
    scratch
        .active
        .par_iter()
        .with_min_len(1024)
        .map(|&k| {
            let (i, lobe) = (k as usize / 2, k as usize % 2);
            spawn(&parents.get(i, materials), triangles, depth)[lobe].expect("flagged in the first pass")
        })
        .collect_into_vec(rays);
    links.resize(n, [INVALID_ID; 2]);
    links.par_iter_mut().with_min_len(4096).for_each(|l| *l = [INVALID_ID; 2]);
    // `active` is sorted: the child index of flag `k` is its rank in the list.
    for (j, &k) in scratch.active.iter().enumerate() {
        links[k as usize / 2][k as usize % 2] = j as u32;
    }
    if cfg!(debug_assertions) {
        if let Some(e) = rays.iter().find_map(|r| r.validate().err()) {
            panic!("secondary_rays: {e}");
        }
    }
    Ok(())
}
