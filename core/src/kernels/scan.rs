//! Exclusive prefix sum over u32 flags: the specification of compaction.
//!
//! An exclusive scan over integers is exact, so compaction built on it is stable
//! (input order kept) and bit-reproducible on any backend and thread count,
//! unlike atomic-append compaction (numerics-notes, "Compaction").
//!
//! WGSL mirror: the GPU backend's reduce-then-scan computes the same values.

/// Exclusive prefix sum of `flags` (each counted as 0 or 1): `out[i]` is the
/// number of non-zero flags before `i`. Returns the offsets and the total.
pub fn exclusive_scan(flags: &[u32]) -> (Vec<u32>, u32) {
    let mut out = Vec::with_capacity(flags.len());
    let mut sum = 0u32;
    for &f in flags {
        out.push(sum);
        sum += (f != 0) as u32;
    }
    (out, sum)
}

/// The sequential compaction every parallel one must equal: the indices of the
/// non-zero flags, in increasing order.
pub fn compact_sequential(flags: &[u32]) -> Vec<u32> {
    flags.iter().enumerate().filter(|(_, f)| **f != 0).map(|(i, _)| i as u32).collect()
}

/// Exclusive prefix sum of counts (not flags): `out[i] = counts[0] + .. + counts[i-1]`.
/// Used over per-block counts by the parallel compaction.
pub fn exclusive_scan_sums(counts: &[u32]) -> (Vec<u32>, u32) {
    let mut out = Vec::with_capacity(counts.len());
    let mut sum = 0u32;
    for &c in counts {
        out.push(sum);
        sum += c;
    }
    (out, sum)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scan_counts_before_each_index() {
        let (o, n) = exclusive_scan(&[1, 0, 7, 1, 0]);
        assert_eq!(o, vec![0, 1, 1, 2, 3]);
        assert_eq!(n, 3);
        assert_eq!(compact_sequential(&[1, 0, 7, 1, 0]), vec![0, 2, 3]);
        assert_eq!(exclusive_scan(&[]), (vec![], 0));
    }
}
