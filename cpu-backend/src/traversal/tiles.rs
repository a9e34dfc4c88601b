//! Packets of pixel tiles: a frame's shadow rays, made from their (light, pixel) pairs in
//! compaction's order (light-major, then pixel order, rows of the image one after the
//! other), traced in an order where each run of [`LANES`] consecutive rays comes from a
//! [`TILE_WIDTH`] x [`TILE_HEIGHT`] block of pixels instead of a strip of one row. The rays
//! of a square-ish block leave nearby points and their packets split less: counted with
//! callgrind (AVX2 lanes, the list sorted into tiles beforehand), 2x4 tiles against the
//! list's 8x1 strips take 9.5% fewer instructions and 12% fewer mispredicted branches on
//! the teaser's shadow rays, 11% and 15% fewer instructions on the far bunny's and the far
//! horse's (4x2: 8%; 4x4: 9% and 12%; 8x2: 2% and 4%).
//!
//! The order is computed per window of whole tile rows (all the rays of one light whose
//! pixels lie in the same [`TILE_HEIGHT`] image rows), by merging the window's rows tile
//! column by tile column: linear in the window, no sort. Only the order of tracing
//! changes; every ray's answer is its own (the traversals are exact), so the results are
//! the list order's bit for bit.
//!
//! Used where the rays are made as they are traced (`occluded_pairs_tiled_into`: the
//! frame's `shadow_rays` without stage outputs), where making them in tile order costs
//! nothing more. A list given as records is traced in its own order: copying its 64-byte
//! records into tile order, per window or per packet, cost more than the tiles saved on the
//! teaser and Sponza (`ray_contest`, one thread: 5 to 15% slower there, 7 to 15% faster on
//! the bunnies and horses).

use hyrt_core::formats::RayRecord;
use rayon::slice::ParallelSliceMut;

use super::LANES;

/// Pixels per tile along a row.
pub const TILE_WIDTH: u32 = 2;
/// Rows per tile.
pub const TILE_HEIGHT: u32 = 4;
const _: () = assert!((TILE_WIDTH * TILE_HEIGHT) as usize == LANES);

/// Where the ray of `light` at `pixel` (of an image `width` pixels wide, `pixel = y * width
/// + x`) comes in tile order: by light, tile row, tile column, then row and column within
/// the tile. The order [`tile_order`] gives each window, and so the whole list's.
#[inline]
pub fn tile_key(light: u32, pixel: u32, width: u32) -> (u32, u32, u32, u32, u32) {
    let width = width.max(1);
    let (x, y) = (pixel % width, pixel / width);
    (light, y / TILE_HEIGHT, x / TILE_WIDTH, y % TILE_HEIGHT, x % TILE_WIDTH)
}

/// Sort a frame's shadow rays (each with its `light` and `pixel`, an image `width` pixels
/// wide) into the order a frame that makes them as it traces them traces them
/// ([`super::occluded_pairs_tiled_into`], the fused executor's `shadow_rays`): stable, by
/// [`tile_key`]. For a list in compaction's order the result is exactly that order (tested
/// below); every ray's answer is its own, so tracing the sorted list gives the same answers,
/// permuted.
///
/// For lists given as records that are traced more than once, or by another tracer as well
/// (`hyrt bench`'s peers trace the frame's shadow rays so, hyrt's packets and Embree's
/// alike). A list traced once gains less than the sort costs (see the module docs).
pub fn sort_into_tiles(rays: &mut [RayRecord], width: u32) {
    rays.par_sort_by_key(|r| tile_key(r.light, r.pixel, width));
}

/// The tile row (light, band of [`TILE_HEIGHT`] image rows) of pair `k = light * pixels +
/// pixel` in an image `width` pixels wide.
#[inline(always)]
fn band(k: u32, pixels: u32, width: u32) -> (u32, u32) {
    (k / pixels, k % pixels / width / TILE_HEIGHT)
}

/// The ends of windows of whole tile rows over `pairs` (`k = light * pixels + pixel`,
/// increasing), each at least `min_len` pairs long where the list allows (the last may be
/// shorter): every window starts where a tile row starts.
pub(crate) fn windows(pairs: &[u32], pixels: u32, width: u32, min_len: usize) -> Vec<usize> {
    let mut ends = Vec::new();
    let mut start = 0;
    while start < pairs.len() {
        let mut end = (start + min_len.max(1)).min(pairs.len());
        if end < pairs.len() {
            // Extend to the end of the tile row of pair `end - 1` (pairs are sorted, so
            // tile rows are contiguous).
            let row = band(pairs[end - 1], pixels, width);
            end += pairs[end..].partition_point(|&k| band(k, pixels, width) == row);
        }
        ends.push(end);
        start = end;
    }
    ends
}

/// The `[light, x, y]` of each pair of a window (`pairs`: `k = light * pixels + pixel`,
/// increasing), into `coords`: divisions only where the light or the image row changes.
pub(crate) fn coords(pairs: &[u32], pixels: u32, width: u32, coords: &mut Vec<[u32; 3]>) {
    coords.clear();
    coords.reserve(pairs.len());
    // The light and image row of the last pair and where they start (`u32::MAX`: not
    // known yet, a division at the next pair).
    let (mut light, mut light_start) = (0u32, u32::MAX);
    let (mut y, mut row_start) = (0u32, u32::MAX);
    for &k in pairs {
        if k < light_start || k - light_start >= pixels {
            light = k / pixels;
            light_start = light * pixels;
            row_start = u32::MAX;
        }
        let p = k - light_start;
        if p < row_start || p - row_start >= width {
            y = p / width;
            row_start = y * width;
        }
        coords.push([light, p - row_start, y]);
    }
}

/// The positions of a window's rays (`coords`, in `(light, pixel)` order: [`coords`]) in
/// tile order, into `order`: by light, tile row, tile column, then row and column within
/// the tile. Linear: the rows of each tile row are merged tile column by tile column.
pub(crate) fn tile_order(coords: &[[u32; 3]], order: &mut Vec<u32>) {
    order.clear();
    let len = coords.len();
    let row_of = |c: &[u32; 3]| (c[0], c[2] / TILE_HEIGHT);
    let mut i = 0;
    while i < len {
        let row = row_of(&coords[i]);
        // The runs of each image row of this tile row: `[start, end)` per row in the tile.
        let mut runs = [(0usize, 0usize); TILE_HEIGHT as usize];
        let mut j = i;
        while j < len && row_of(&coords[j]) == row {
            let r = &mut runs[(coords[j][2] % TILE_HEIGHT) as usize];
            if r.0 == r.1 {
                *r = (j, j);
            }
            r.1 = j + 1;
            j += 1;
        }
        // Merge: the least tile column left among the rows, then each row's pixels in it.
        loop {
            let mut least = u32::MAX;
            for r in &runs {
                if r.0 < r.1 {
                    least = least.min(coords[r.0][1]);
                }
            }
            if least == u32::MAX {
                break;
            }
            // The end of the least tile column left: the runs are sorted by x, so every
            // pixel before it in a run lies in that column.
            let column_end = (least / TILE_WIDTH + 1) * TILE_WIDTH;
            for r in &mut runs {
                while r.0 < r.1 && coords[r.0][1] < column_end {
                    order.push(r.0 as u32);
                    r.0 += 1;
                }
            }
        }
        i = j;
    }
    debug_assert_eq!(order.len(), len);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rays of `lights` lights over the pixels `keep` selects of a `width` x `height` image.
    fn pairs(width: u32, height: u32, lights: u32, keep: impl Fn(u32, u32, u32) -> bool) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for l in 0..lights {
            for p in 0..width * height {
                if keep(l, p % width, p / width) {
                    out.push((l, p));
                }
            }
        }
        out
    }

    /// The order is a permutation, sorted by (light, tile row, tile column, row, column),
    /// on full images, odd sizes (partial tiles at the right and bottom edges) and sparse
    /// masks, and windows cover the list in whole tile rows.
    #[test]
    fn tile_order_sorts_each_window_by_tile_and_windows_hold_whole_tile_rows() {
        let masks: [&dyn Fn(u32, u32, u32) -> bool; 3] =
            [&|_, _, _| true, &|l, x, y| (x * 7 + y * 3 + l) % 5 < 2, &|l, x, y| {
                (x as i32 - 20).pow(2) + (y as i32 - 9).pow(2) < 60 + 30 * l as i32
            }];
        for (width, height) in [(16, 8), (37, 19), (1, 9), (40, 1), (1280, 9)] {
            for (m, keep) in masks.iter().enumerate() {
                let list = pairs(width, height, 3, keep);
                let ks: Vec<u32> = list.iter().map(|&(l, p)| l * width * height + p).collect();
                for min_len in [1, 8, 50, 10_000] {
                    let ends = windows(&ks, width * height, width, min_len);
                    let mut start = 0;
                    let mut order = Vec::new();
                    for &end in &ends {
                        assert!(end > start && end <= list.len());
                        if end < list.len() {
                            assert!(end - start >= min_len, "{width}x{height} mask {m}: short window");
                            let (a, b) = (ks[end - 1], ks[end]);
                            let band = |k| band(k, width * height, width);
                            assert_ne!(band(a), band(b), "window splits a tile row");
                        }
                        let mut c = Vec::new();
                        coords(&ks[start..end], width * height, width, &mut c);
                        let want: Vec<[u32; 3]> =
                            list[start..end].iter().map(|&(l, p)| [l, p % width, p / width]).collect();
                        assert_eq!(c, want);
                        tile_order(&c, &mut order);
                        let mut seen = vec![false; end - start];
                        for &o in &order {
                            assert!(!std::mem::replace(&mut seen[o as usize], true), "position twice");
                        }
                        assert!(seen.iter().all(|&s| s));
                        let keys: Vec<_> = order
                            .iter()
                            .map(|&o| {
                                let (l, p) = list[start + o as usize];
                                tile_key(l, p, width)
                            })
                            .collect();
                        assert!(keys.windows(2).all(|w| w[0] < w[1]), "{width}x{height} mask {m}: not in tile order");
                        start = end;
                    }
                    assert_eq!(start, list.len());
                }
            }
        }
    }

    /// A list of rays in compaction's order sorted by [`sort_into_tiles`] is the order the
    /// windows' [`tile_order`] traces, ray for ray (full images, odd sizes, sparse masks).
    #[test]
    fn sort_into_tiles_is_the_tiled_tracing_order() {
        let masks: [&dyn Fn(u32, u32, u32) -> bool; 2] = [&|_, _, _| true, &|l, x, y| (x * 7 + y * 3 + l) % 5 < 2];
        for (width, height) in [(16, 8), (37, 19), (1, 9), (40, 1)] {
            for keep in masks {
                let list = pairs(width, height, 3, keep);
                let pixels = width * height;
                let ks: Vec<u32> = list.iter().map(|&(l, p)| l * pixels + p).collect();
                let mut traced = Vec::new();
                let mut start = 0;
                for end in windows(&ks, pixels, width, 8) {
                    let (mut c, mut order) = (Vec::new(), Vec::new());
                    coords(&ks[start..end], pixels, width, &mut c);
                    tile_order(&c, &mut order);
                    traced.extend(order.iter().map(|&o| list[start + o as usize]));
                    start = end;
                }
                let mut rays: Vec<RayRecord> = list
                    .iter()
                    .map(|&(light, pixel)| RayRecord { light, pixel, ..bytemuck::Zeroable::zeroed() })
                    .collect();
                sort_into_tiles(&mut rays, width);
                let sorted: Vec<(u32, u32)> = rays.iter().map(|r| (r.light, r.pixel)).collect();
                assert_eq!(sorted, traced, "{width}x{height}");
            }
        }
    }
}
