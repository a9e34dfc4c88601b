// Stage `compaction`, banded frames only (gpu-backend/src/band.rs): where each light's
// rays start in a light-major shadow-ray list, so that the bands' lists can be merged
// into the frame's order. One thread per light, a binary search over the list's `light`
// fields (the list is sorted by light). Rays past the buffer's room are not written:
// the search stops at the room (the frame then runs again with more).
//
// Three words per slot (`slots` = arrayLength(&light_starts) / 3): where the slot's rays
// start (`light_starts[slot]`), then where its rays from surfaces at `bounds[1]` or past
// start (`light_starts[slots + slot]`), then where those at `bounds[2]` or past start
// (`light_starts[2 * slots + slot]`): a slot's rays are in surface order (their `pixel`),
// so the band's own rays of a band rendered with a halo of rows are the middle range
// (band.rs). The bounce lists' bounds keep every ray: `[0, 0, u32::MAX, 0]`.
//
// Prepended: the generated records (hyrt_core::formats::wgsl).

@group(0) @binding(0) var<storage, read> rays: array<RayRecord>;
@group(0) @binding(1) var<storage, read> count: array<u32, 4>;
@group(0) @binding(2) var<storage, read_write> light_starts: array<u32>;
@group(0) @binding(3) var<storage, read> bounds: array<u32, 4>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let slots = arrayLength(&light_starts) / 3u;
    if gid.x >= 3u * slots {
        return;
    }
    let light = gid.x % slots;
    let part = gid.x / slots;
    let bound = select(0u, bounds[part], part > 0u);
    var lo = 0u;
    var hi = min(count[0], arrayLength(&rays));
    while lo < hi {
        let mid = lo + (hi - lo) / 2u;
        let r = rays[mid];
        if r.light < light || (r.light == light && r.pixel < bound) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    light_starts[gid.x] = lo;
}
