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
//! [`secondary_rays_into`]: each parent spawns once, into room sized by
//! [`spawn_bound`]); the GPU flags, scans and writes instead, as `compaction` does, and
//! the lists are the same. The kernel is [`hyrt_core::kernels::bounce::spawn`].

use std::collections::TryReserveError;

use glam::Vec3;
use hyrt_core::formats::{GBufferTexel, HitRecord, ObjectRecord, RayRecord, SurfaceRecord, INVALID_ID};
use hyrt_core::geometry::WorldTriangles;
use hyrt_core::kernels::bounce::{
    bounces, primary_parent, primary_parent_shaded, secondary_parent, spawn, spawn_bound, Parent,
};
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
/// are numbered from the chunk's start. Large enough that the per-chunk work (a bound, a
/// count, a move) is negligible, small enough that a frame's few bouncing regions spread
/// over the workers.
const SPAWN_CHUNK: usize = 1024;

/// The stage into caller-owned buffers (allocations reused): the rays of bounce `depth`
/// into `rays`, each parent's child indices into `links`. An error where the allocator
/// cannot hold the list or the links (the frame then fails with
/// `RenderError::OutOfMemory` instead of aborting).
///
/// Parents go in chunks of `SPAWN_CHUNK`. Each parent spawns once, straight into the list:
/// the list is first sized by the most rays each chunk's parents can spawn
/// ([`spawn_bound`]: one for a mirror, two for glass, read from the object records without
/// spawning), each chunk writes its rays from its bound's start, numbering its links from
/// its first ray, and the chunks are then moved down over the room their parents left
/// unused (nothing moves where every parent spawned its bound, as on the teaser's golden
/// bunny), in order, and the links moved by each chunk's start. The result is the
/// compaction of every parent's `[reflection, refraction]` flags in order, as the GPU's
/// scan builds it, and the list is never held twice. Measured against spawning every
/// chunk twice, once to count and once to write (AMD EPYC, one thread, `hyrt render
/// assets/scenes/teaser.toml --frames 9 --threads 1 --shading paper`, the two binaries
/// alternated four times, medians): the teaser's `secondary_rays{1}` 16.2 to 8.3 ms in
/// the fused frame (66,769 parents), 24.0 to 16.7 ms in the staged one (921,600), the
/// default scene's 10.2 to 5.7 ms; the images byte-identical.
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
    let objects = materials.objects;
    // The most rays each chunk's parents spawn, and where the chunks' room starts.
    let bounds: Vec<usize> = (0..n.div_ceil(SPAWN_CHUNK))
        .into_par_iter()
        .map(|c| {
            (c * SPAWN_CHUNK..n.min((c + 1) * SPAWN_CHUNK))
                .map(|i| spawn_bound(parents.surface(i), objects) as usize)
                .sum()
        })
        .collect();
    let starts = |counts: &[usize]| -> Vec<usize> {
        counts.iter().scan(0, |at, &k| Some(std::mem::replace(at, *at + k))).collect()
    };
    let room = starts(&bounds);
    let most: usize = bounds.iter().sum();
    crate::memory::reserve(rays, most)?;
    // Every ray kept is written below, as the links are; the rest is cut off.
    rays.resize(most, bytemuck::Zeroable::zeroed());
    let mut places = Vec::with_capacity(bounds.len());
    let mut rest = &mut rays[..];
    for &k in &bounds {
        let (place, tail) = rest.split_at_mut(k);
        places.push(place);
        rest = tail;
    }
    // Chunk `c`'s parents spawn in order, its `k`-th ray to `place[k]`; its links are
    // numbered from the chunk's first ray. Its ray count.
    let counts: Vec<usize> = links
        .par_chunks_mut(SPAWN_CHUNK)
        .zip(places)
        .enumerate()
        .map(|(c, (links, place))| {
            let mut k = 0;
            for (j, link) in links.iter_mut().enumerate() {
                *link = [INVALID_ID; 2];
                let i = c * SPAWN_CHUNK + j;
                if !parents.may_bounce(i, objects) {
                    continue;
                }
                for (lobe, ray) in spawn(&parents.get(i, materials), triangles, depth).into_iter().enumerate() {
                    if let Some(ray) = ray {
                        link[lobe] = k as u32;
                        place[k] = ray;
                        k += 1;
                    }
                }
            }
            k
        })
        .collect();
    // The chunks moved down over the room left unused, in order (each moves to or below
    // its room's start, above the chunks before it).
    let at = starts(&counts);
    for ((&from, &to), &k) in room.iter().zip(&at).zip(&counts) {
        if from != to {
            rays.copy_within(from..from + k, to);
        }
    }
    rays.truncate(counts.iter().sum());
    links.par_chunks_mut(SPAWN_CHUNK).zip(at).for_each(|(links, start)| {
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
