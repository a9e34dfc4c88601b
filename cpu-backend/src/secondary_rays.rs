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
//! Parents are taken in chunks, each numbering its rays from its own start (see
//! [`secondary_rays_into`]: textured parents spawn once, others twice, to count and to
//! write); the GPU flags, scans and writes instead, as `compaction` does, and the lists are
//! the same. The kernel is [`hyrt_core::kernels::bounce::spawn`].

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
    /// there, `records[i]` (where materials vary over surfaces; empty elsewhere) (the fused
    /// frame's bouncing pixels, `crate::fused`: in pixel order, they spawn the rays
    /// [`Parents::Primary`] spawns).
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
            Parents::Pixels { pixels, texels, surfaces, records, eye } => match records.get(i) {
                Some(&record) => primary_parent_shaded(&texels[i], &surfaces[i], eye, pixels[i], materials, record),
                None => primary_parent(&texels[i], &surfaces[i], eye, pixels[i], materials),
            },
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

/// Parents a worker spawns from at once: the unit of the stage's parallel work, whose rays
/// are numbered from the chunk's start. Large enough that the per-chunk work (a count, a
/// list) is negligible, small enough that a frame's few bouncing regions spread over the
/// workers.
const SPAWN_CHUNK: usize = 1024;

/// The stage into caller-owned buffers (allocations reused): the rays of bounce `depth`
/// into `rays`, each parent's child indices into `links`. An error where the allocator
/// cannot hold the list or the links (the frame then fails with
/// `RenderError::OutOfMemory` instead of aborting).
///
/// Parents go in chunks of `SPAWN_CHUNK`, each chunk's links numbered from its first ray,
/// then moved by the chunk's start in the list. Where materials do not vary over surfaces a
/// parent's rays are cheap to make, and each chunk spawns twice: once to count its rays,
/// once to write them into its place in `rays` (no buffer but the list). Where they vary
/// (textures: [`Materials::at`] is up to four trilinear samples) each parent spawns once,
/// into its worker's buffer, and each chunk keeps its rays in a list of its own at its exact
/// size, joined after (the rays are held twice at the peak). Either way the result is the
/// compaction of every parent's `[reflection, refraction]` flags in order, as the GPU's
/// scan builds it.
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
    // Chunk `c`'s parents spawn in order, ray `k` of the chunk going to `emit(k, ray)`; its
    // links are numbered from the chunk's first ray. Its ray count.
    let spawn_chunk = |c: usize, links: &mut [[u32; 2]], emit: &mut dyn FnMut(usize, RayRecord)| {
        let mut k = 0;
        for (j, link) in links.iter_mut().enumerate() {
            *link = [INVALID_ID; 2];
            let i = c * SPAWN_CHUNK + j;
            if !parents.may_bounce(i, materials.objects) {
                continue;
            }
            for (lobe, ray) in spawn(&parents.get(i, materials), triangles, depth).into_iter().enumerate() {
                if let Some(ray) = ray {
                    link[lobe] = k as u32;
                    emit(k, ray);
                    k += 1;
                }
            }
        }
        k
    };
    let starts = |counts: &[usize]| -> Vec<usize> {
        counts.iter().scan(0, |at, &k| Some(std::mem::replace(at, *at + k))).collect()
    };
    let starts = if materials.varying() {
        let chunks: Vec<Vec<RayRecord>> = links
            .par_chunks_mut(SPAWN_CHUNK)
            .enumerate()
            .map_init(
                || Vec::with_capacity(2 * SPAWN_CHUNK),
                |spawned: &mut Vec<RayRecord>, (c, links)| {
                    spawned.clear();
                    spawn_chunk(c, links, &mut |_, ray| spawned.push(ray));
                    // The chunk's list at its exact size (the worker's buffer is reused).
                    let mut list = Vec::new();
                    list.try_reserve_exact(spawned.len())?;
                    list.extend_from_slice(spawned);
                    Ok(list)
                },
            )
            .collect::<Result<_, TryReserveError>>()?;
        let counts: Vec<usize> = chunks.iter().map(Vec::len).collect();
        crate::memory::reserve(rays, counts.iter().sum())?;
        rays.clear();
        chunks.iter().for_each(|list| rays.extend_from_slice(list));
        starts(&counts)
    } else {
        let counts: Vec<usize> = links
            .par_chunks_mut(SPAWN_CHUNK)
            .enumerate()
            .map(|(c, links)| spawn_chunk(c, links, &mut |_, _| {}))
            .collect();
        let total = counts.iter().sum();
        crate::memory::reserve(rays, total)?;
        // Every ray is written below, as the links are.
        rays.resize(total, bytemuck::Zeroable::zeroed());
        let mut places = Vec::with_capacity(counts.len());
        let mut rest = &mut rays[..];
        for &k in &counts {
            let (place, tail) = rest.split_at_mut(k);
            places.push(place);
            rest = tail;
        }
        links.par_chunks_mut(SPAWN_CHUNK).zip(places).enumerate().for_each(|(c, (links, place))| {
            spawn_chunk(c, links, &mut |k, ray| place[k] = ray);
        });
        starts(&counts)
    };
    links.par_chunks_mut(SPAWN_CHUNK).zip(starts).for_each(|(links, start)| {
        for l in links.iter_mut().flatten().filter(|l| **l != INVALID_ID) {
            *l += start as u32;
        }
    });
    if cfg!(debug_assertions) {
        if let Some(e) = rays.iter().find_map(|r| r.validate().err()) {
            panic!("secondary_rays: {e}");
        }
    }
    Ok(())
}
