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
//! Each parent is examined once, its rays listed chunk by chunk and the lists joined in
//! order (the GPU flags, scans and writes instead, as `compaction` does; the lists are
//! the same). The kernel is [`hyrt_core::kernels::bounce::spawn`].

use std::collections::TryReserveError;

use glam::Vec3;
use hyrt_core::formats::{GBufferTexel, HitRecord, ObjectRecord, RayRecord, SurfaceRecord, INVALID_ID};
use hyrt_core::geometry::WorldTriangles;
use hyrt_core::kernels::bounce::{bounces, primary_parent, primary_parent_shaded, secondary_parent, spawn, Parent};
use hyrt_core::kernels::texture::Materials;
use rayon::prelude::*;

/// The parents of one bounce: what [`secondary_rays_into`] spawns from.
#[derive(Clone, Copy)]
pub enum Parents<'a> {
    /// The primary hits: one parent per pixel, seen from `eye`.
    Primary { gbuffer: &'a [GBufferTexel], surfaces: &'a [SurfaceRecord], eye: Vec3 },
    /// The hits of the previous bounce: one parent per ray.
    Secondary { rays: &'a [RayRecord], hits: &'a [HitRecord], surfaces: &'a [SurfaceRecord] },
    /// Some pixels' primary hits, seen from `eye`: parent `i` is pixel `pixels[i]`, with
    /// texel `texels[i]`, surface `surfaces[i]` and the record its object is shaded with
    /// there, `records[i]` (the fused frame's bouncing pixels, `crate::fused`: in pixel
    /// order, they spawn the rays [`Parents::Primary`] spawns).
    Pixels {
        pixels: &'a [u32],
        texels: &'a [GBufferTexel],
        surfaces: &'a [SurfaceRecord],
        records: &'a [ObjectRecord],
        eye: Vec3,
    },
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
            Parents::Pixels { pixels, texels, surfaces, records, eye } => {
                primary_parent_shaded(&texels[i], &surfaces[i], eye, pixels[i], materials, records[i])
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

/// Parents a worker spawns from at once: their rays go into a list of the chunk's own,
/// and the lists are joined in chunk order after. Large enough that the join's per-chunk
/// work is negligible, small enough that a frame's few bouncing regions spread over the
/// workers.
const SPAWN_CHUNK: usize = 1024;

/// The stage into caller-owned buffers (allocations reused): the rays of bounce `depth`
/// into `rays`, each parent's child indices into `links`. An error where the allocator
/// cannot hold the list or the links (the frame then fails with
/// `RenderError::OutOfMemory` instead of aborting).
///
/// Each parent is examined once: a chunk of parents spawns into a list of its own, its
/// links numbered in that list; the lists are then joined in chunk order and the links
/// moved by their chunk's start. The result is the compaction of every parent's
/// `[reflection, refraction]` flags in order, as the GPU's scan builds it.
pub fn secondary_rays_into(
    parents: Parents,
    materials: &Materials,
    triangles: &WorldTriangles,
    depth: u32,
    rays: &mut Vec<RayRecord>,
    links: &mut Vec<[u32; 2]>,
) -> Result<(), TryReserveError> {
    let n = parents.len();
    crate::memory::reserve(links, n)?;
    // Every link is written below: resizing alone leaves a reused buffer untouched.
    links.resize(n, [INVALID_ID; 2]);
    let chunks: Vec<Vec<RayRecord>> = links
        .par_chunks_mut(SPAWN_CHUNK)
        .enumerate()
        .map(|(c, links)| {
            let (mut list, len) = (Vec::new(), links.len());
            for (j, link) in links.iter_mut().enumerate() {
                *link = [INVALID_ID; 2];
                let i = c * SPAWN_CHUNK + j;
                if !parents.may_bounce(i, materials.objects) {
                    continue;
                }
                for (lobe, ray) in spawn(&parents.get(i, materials), triangles, depth).into_iter().enumerate() {
                    if let Some(ray) = ray {
                        if list.len() == list.capacity() {
                            // At most two rays a parent: room for the rest of the chunk.
                            list.try_reserve(2 * (len - j))?;
                        }
                        link[lobe] = list.len() as u32;
                        list.push(ray);
                    }
                }
            }
            Ok(list)
        })
        .collect::<Result<_, TryReserveError>>()?;
    let starts: Vec<u32> = chunks
        .iter()
        .scan(0u32, |at, list| {
            let start = *at;
            *at += list.len() as u32;
            Some(start)
        })
        .collect();
    let total = chunks.iter().map(Vec::len).sum();
    crate::memory::reserve(rays, total)?;
    rays.clear();
    chunks.iter().for_each(|list| rays.extend_from_slice(list));
    links.par_chunks_mut(SPAWN_CHUNK).zip(starts).for_each(|(links, start)| {
        for l in links.iter_mut().flatten().filter(|l| **l != INVALID_ID) {
            *l += start;
        }
    });
    if cfg!(debug_assertions) {
        if let Some(e) = rays.iter().find_map(|r| r.validate().err()) {
            panic!("secondary_rays: {e}");
        }
    }
    Ok(())
}
