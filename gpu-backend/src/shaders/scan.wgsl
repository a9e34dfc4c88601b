// The deterministic list compaction every list stage shares (`compaction`,
// `secondary_rays`): a reduce-then-scan over u32 flags (no atomics, no decoupled
// look-back: WebGPU has no forward-progress guarantee), equal to
// hyrt_core::kernels::scan::compact_sequential. Integer sums only: the result is exact
// and independent of scheduling.
//
// The including stage defines, before this file:
//   fn element_flag(k: u32) -> u32     whether element k (< level.n) is kept (0 or 1)
//   fn emit(k: u32, kept: bool, dst: u32)
//                                      called once for every element k < level.n in the
//                                      last pass, kept ones with their index in the list
// and the constants WG, ITEMS, TILE, SHADOW_WG (the workgroup of the list's consumers)
// and MAX_DISPATCH.
//
// Passes (one compute pass, one dispatch each, in order):
//   flags_reduce  level 0: flags[k] = element_flag(k), per-tile counts -> level 1
//   reduce        level i -> level i + 1 (per-tile sums), while level i + 1 > TILE
//   scan_top      one workgroup: exclusive scan of the top level in place; writes
//                 list_count = [count, dispatch_x, dispatch_y, 1]
//   downsweep     level i, top-1 .. 1: exclusive scan of each tile in place plus
//                 the tile's offset from level i + 1
//   scatter       level 0: local scan of the flags plus the tile offset; emit()
// Each tile is TILE = WG * ITEMS elements; thread `lid` owns ITEMS consecutive
// elements.

struct Level {
    // Elements at this level.
    n: u32,
    // Offset of this level in `levels` (unused at level 0, which is `flags`).
    src_off: u32,
    // Offset of the level above (one value per tile of this level) in `levels`.
    dst_off: u32,
    // 1: this level is the flags (values count as 0 or 1); 0: counts.
    src_is_flags: u32,
}

@group(0) @binding(0) var<uniform> level: Level;
@group(0) @binding(1) var<storage, read_write> flags: array<u32>;
@group(0) @binding(2) var<storage, read_write> levels: array<u32>;
@group(0) @binding(3) var<storage, read_write> list_count: array<u32, 4>;

var<workgroup> scan_buf: array<u32, 2 * WG>;

// Exclusive workgroup scan of one value per thread (Hillis-Steele, ping-pong
// buffers: log2(WG) barriers). Returns (exclusive prefix, workgroup total).
fn workgroup_scan(lid: u32, v: u32) -> vec2<u32> {
    var src = 0u;
    scan_buf[lid] = v;
    workgroupBarrier();
    for (var off = 1u; off < WG; off = off * 2u) {
        let dst = 1u - src;
        var x = scan_buf[src * WG + lid];
        if lid >= off {
            x = x + scan_buf[src * WG + lid - off];
        }
        scan_buf[dst * WG + lid] = x;
        src = dst;
        workgroupBarrier();
    }
    let inclusive = scan_buf[src * WG + lid];
    let total = scan_buf[src * WG + WG - 1u];
    // The next call overwrites scan_buf.
    workgroupBarrier();
    return vec2<u32>(inclusive - v, total);
}

// Tile index of a 2D dispatch (x-major), the same rule the host uses.
fn tile_index(wid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return wid.y * nwg.x + wid.x;
}

fn tiles_of(n: u32) -> u32 {
    return (n + TILE - 1u) / TILE;
}

fn level_value(i: u32) -> u32 {
    if level.src_is_flags != 0u {
        return select(0u, 1u, flags[i] != 0u);
    }
    return levels[level.src_off + i];
}

// Per-tile sums of one level into the level above.
@compute @workgroup_size(WG)
fn reduce(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>,
          @builtin(num_workgroups) nwg: vec3<u32>) {
    let t = tile_index(wid, nwg);
    let base = t * TILE + lid * ITEMS;
    var sum = 0u;
    for (var j = 0u; j < ITEMS; j = j + 1u) {
        let i = base + j;
        if i < level.n {
            sum = sum + level_value(i);
        }
    }
    let s = workgroup_scan(lid, sum);
    if lid == 0u && t < tiles_of(level.n) {
        levels[level.dst_off + t] = s.y;
    }
}

// Exclusive scan of one tile of `levels` in place, each value plus `offset`.
fn scan_tile_in_place(lid: u32, t: u32, offset: u32) -> u32 {
    let base = t * TILE + lid * ITEMS;
    var sum = 0u;
    for (var j = 0u; j < ITEMS; j = j + 1u) {
        let i = base + j;
        if i < level.n {
            sum = sum + levels[level.src_off + i];
        }
    }
    let s = workgroup_scan(lid, sum);
    var run = offset + s.x;
    for (var j = 0u; j < ITEMS; j = j + 1u) {
        let i = base + j;
        if i < level.n {
            let v = levels[level.src_off + i];
            levels[level.src_off + i] = run;
            run = run + v;
        }
    }
    return s.y;
}

// The top level (at most TILE values), one workgroup: scan in place, write the
// list's count and the indirect dispatch arguments of its consumers (one thread per
// entry, SHADOW_WG per workgroup).
@compute @workgroup_size(WG)
fn scan_top(@builtin(local_invocation_index) lid: u32) {
    let total = scan_tile_in_place(lid, 0u, 0u);
    if lid == 0u {
        let groups = (total + SHADOW_WG - 1u) / SHADOW_WG;
        let x = min(groups, MAX_DISPATCH);
        let y = select(1u, (groups + x - 1u) / max(x, 1u), groups > 0u);
        list_count[0] = total;
        list_count[1] = x;
        list_count[2] = y;
        list_count[3] = 1u;
    }
}

// Levels below the top: scan each tile in place, offset by the (already scanned)
// level above.
@compute @workgroup_size(WG)
fn downsweep(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>,
             @builtin(num_workgroups) nwg: vec3<u32>) {
    let t = tile_index(wid, nwg);
    // Out-of-range tiles of a 2D dispatch read a harmless offset and write nothing.
    let offset = levels[level.dst_off + min(t, tiles_of(level.n) - 1u)];
    scan_tile_in_place(lid, t, offset);
}

// Level 0: the destination index of each active element of this thread. Returns
// the thread's first destination; the caller walks its ITEMS flags.
fn scatter_base(lid: u32, t: u32) -> u32 {
    let base = t * TILE + lid * ITEMS;
    var sum = 0u;
    for (var j = 0u; j < ITEMS; j = j + 1u) {
        let i = base + j;
        if i < level.n {
            sum = sum + level_value(i);
        }
    }
    let s = workgroup_scan(lid, sum);
    let tile_offset = levels[level.dst_off + min(t, tiles_of(level.n) - 1u)];
    return tile_offset + s.x;
}

// Level 0: compute and store the flags, count them per tile.
@compute @workgroup_size(WG)
fn flags_reduce(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>,
                @builtin(num_workgroups) nwg: vec3<u32>) {
    let t = tile_index(wid, nwg);
    let base = t * TILE + lid * ITEMS;
    var sum = 0u;
    for (var j = 0u; j < ITEMS; j = j + 1u) {
        let k = base + j;
        if k < level.n {
            let f = element_flag(k);
            flags[k] = f;
            sum = sum + f;
        }
    }
    let s = workgroup_scan(lid, sum);
    if lid == 0u && t < tiles_of(level.n) {
        levels[level.dst_off + t] = s.y;
    }
}

// Level 0, last: every element once, the kept ones with their list index.
@compute @workgroup_size(WG)
fn scatter(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>,
           @builtin(num_workgroups) nwg: vec3<u32>) {
    let t = tile_index(wid, nwg);
    var dst = scatter_base(lid, t);
    let base = t * TILE + lid * ITEMS;
    for (var j = 0u; j < ITEMS; j = j + 1u) {
        let k = base + j;
        if k < level.n {
            let kept = flags[k] != 0u;
            emit(k, kept, dst);
            if kept {
                dst = dst + 1u;
            }
        }
    }
}
