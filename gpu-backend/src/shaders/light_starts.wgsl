// Stage `compaction`, banded frames only (gpu-backend/src/band.rs): where each light's
// rays start in a light-major shadow-ray list, so that the bands' lists can be merged
// into the frame's order. One thread per light, a binary search over the list's `light`
// fields (the list is sorted by light). Rays past the buffer's room are not written:
// the search stops at the room (the frame then runs again with more).
//
// Prepended: the generated records (hyrt_core::formats::wgsl).

@group(0) @binding(0) var<storage, read> rays: array<RayRecord>;
@group(0) @binding(1) var<storage, read> count: array<u32, 4>;
@group(0) @binding(2) var<storage, read_write> light_starts: array<u32>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let light = gid.x;
    if light >= arrayLength(&light_starts) {
        return;
    }
    var lo = 0u;
    var hi = min(count[0], arrayLength(&rays));
    while lo < hi {
        let mid = lo + (hi - lo) / 2u;
        if rays[mid].light < light {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    light_starts[light] = lo;
}
