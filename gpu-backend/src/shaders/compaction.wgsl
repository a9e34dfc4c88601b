// Stage `compaction` (per pair the kernels of hyrt_core::kernels::shadow, the scan
// equal to hyrt_core::kernels::scan::compact_sequential): flag every (light, pixel)
// pair whose light can contribute at the pixel's surface (k = light * pixels +
// pixel), then a deterministic reduce-then-scan over the flags and a scatter of
// one shadow ray per active pair, light-major then pixel order.
//
// Prepended at pipeline creation: the generated records and format constants
// (hyrt_core::formats::wgsl), the stage's constants (WG, ITEMS, TILE, SHADOW_WG, ...),
// ray.wgsl and shading_helpers.wgsl (`light_incidence`, `light_can_contribute`, the
// exact arithmetic that reads `params.zero`).
//
// Passes (one compute pass, one dispatch each, in order):
//   flags_reduce  level 0: flags[k] = needs_shadow_ray, per-tile counts -> level 1
//   reduce        level i -> level i + 1 (per-tile sums), while level i + 1 > TILE
//   scan_top      one workgroup: exclusive scan of the top level in place; writes
//                 ray_count = [count, dispatch_x, dispatch_y, 1]
//   downsweep     level i, top-1 .. 1: exclusive scan of each tile in place plus
//                 the tile's offset from level i + 1
//   scatter_rays  level 0: local scan of the flags plus the tile offset; writes rays
// Each tile is TILE = WG * ITEMS elements; thread `lid` owns ITEMS consecutive
// elements. Integer sums only: the result is exact and independent of scheduling.

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
@group(0) @binding(3) var<storage, read_write> ray_count: array<u32, 4>;

@group(1) @binding(0) var<uniform> params: FrameParams;
@group(1) @binding(1) var<storage, read> surfaces: array<SurfaceRecord>;
@group(1) @binding(2) var<storage, read> lights: array<LightRecord>;
@group(1) @binding(3) var<storage, read_write> rays: array<RayRecord>;
// Test entry point `scatter_indices` only: the compacted indices.
@group(1) @binding(4) var<storage, read_write> out_indices: array<u32>;

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

// mirrors hyrt_core::kernels::shadow::needs_shadow_ray
fn needs_shadow_ray(s: SurfaceRecord, light: LightRecord) -> bool {
    if s.object == INVALID_ID {
        return false;
    }
    let inc = light_incidence(light, s.position);
    return light_can_contribute(s.geometric_normal, s.normal, inc.l, inc.e);
}

// mirrors hyrt_core::kernels::shadow::shadow_ray. +inf (directional lights) comes from
// its bits at run time: no WGSL constant may hold it.
fn shadow_ray(s: SurfaceRecord, light: LightRecord, light_index: u32, pixel: u32) -> RayRecord {
    let origin = offset_ray_origin(s.position, s.position_error, s.geometric_normal, params.zero);
    var direction: vec3<f32>;
    var t_max: f32;
    if light.kind == LIGHT_DIRECTIONAL {
        direction = -light.position_or_direction;
        t_max = bitcast<f32>(F32_EXP_MASK | params.zero); // +inf
    } else {
        direction = light.position_or_direction - origin;
        t_max = bitcast<f32>(SHADOW_T_MAX_POINT_BITS);
    }
    return RayRecord(origin, 0.0, direction, t_max, pixel, RAY_KIND_SHADOW, 0u, light_index,
        vec3<f32>(1.0, 1.0, 1.0), 0u);
}

fn pair_flag(k: u32, pixels: u32) -> u32 {
    let l = k / pixels;
    let p = k - l * pixels;
    return select(0u, 1u, needs_shadow_ray(surfaces[p], lights[l]));
}

// Level 0 of the stage: compute and store the flags, count them per tile.
@compute @workgroup_size(WG)
fn flags_reduce(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>,
                @builtin(num_workgroups) nwg: vec3<u32>) {
    let t = tile_index(wid, nwg);
    let pixels = params.width * params.height;
    let base = t * TILE + lid * ITEMS;
    var sum = 0u;
    for (var j = 0u; j < ITEMS; j = j + 1u) {
        let k = base + j;
        if k < level.n {
            let f = pair_flag(k, pixels);
            flags[k] = f;
            sum = sum + f;
        }
    }
    let s = workgroup_scan(lid, sum);
    if lid == 0u && t < tiles_of(level.n) {
        levels[level.dst_off + t] = s.y;
    }
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
// ray count and the indirect dispatch arguments of `shadow_rays`.
@compute @workgroup_size(WG)
fn scan_top(@builtin(local_invocation_index) lid: u32) {
    let total = scan_tile_in_place(lid, 0u, 0u);
    if lid == 0u {
        let groups = (total + SHADOW_WG - 1u) / SHADOW_WG;
        let x = min(groups, MAX_DISPATCH);
        let y = select(1u, (groups + x - 1u) / max(x, 1u), groups > 0u);
        ray_count[0] = total;
        ray_count[1] = x;
        ray_count[2] = y;
        ray_count[3] = 1u;
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

@compute @workgroup_size(WG)
fn scatter_rays(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>,
                @builtin(num_workgroups) nwg: vec3<u32>) {
    let t = tile_index(wid, nwg);
    var dst = scatter_base(lid, t);
    let pixels = params.width * params.height;
    let base = t * TILE + lid * ITEMS;
    for (var j = 0u; j < ITEMS; j = j + 1u) {
        let k = base + j;
        if k < level.n && flags[k] != 0u {
            let l = k / pixels;
            let p = k - l * pixels;
            // Rays past the buffer's room are not written: the backend sees the
            // count, makes room and runs the frame again.
            if dst < arrayLength(&rays) {
                rays[dst] = shadow_ray(surfaces[p], lights[l], l, p);
            }
            dst = dst + 1u;
        }
    }
}

// Scan-only test entry point: the indices of the non-zero flags, in order.
@compute @workgroup_size(WG)
fn scatter_indices(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>,
                   @builtin(num_workgroups) nwg: vec3<u32>) {
    let t = tile_index(wid, nwg);
    var dst = scatter_base(lid, t);
    let base = t * TILE + lid * ITEMS;
    for (var j = 0u; j < ITEMS; j = j + 1u) {
        let k = base + j;
        if k < level.n && flags[k] != 0u {
            out_indices[dst] = k;
            dst = dst + 1u;
        }
    }
}
