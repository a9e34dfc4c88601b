// Stage `bounce_shading` (hyrt_core::kernels::bounce::shade_secondary_hit per ray, as
// hyrt_cpu::bounce_shading): the radiance each ray of bounce `list.depth` brings back to
// its parent. Runs deepest bounce first, so each ray adds what its children (the rays of
// the next depth it spawned, `links[2 i]` and `links[2 i + 1]`) brought back; the plan's
// deepest bounce (`list.last`) has none. One thread per ray, indirect dispatch from
// `ray_count`.
//
// Prepended: the generated records and constants, the shading helpers, shading.wgsl,
// the texture kernels and materials.wgsl, lat_long.wgsl, ambient_light.wgsl,
// surface_shading.wgsl, ray.wgsl, bounce.wgsl, bounce_radiance.wgsl, environment.wgsl.

@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<uniform> list: ListParams;
@group(0) @binding(2) var<storage, read> rays: array<RayRecord>;
@group(0) @binding(3) var<storage, read> ray_count: array<u32, 4>;
@group(0) @binding(4) var<storage, read> hits: array<HitRecord>;
@group(0) @binding(5) var<storage, read> surfaces: array<SurfaceRecord>;
@group(0) @binding(6) var<storage, read> shadow: array<u32>;
@group(0) @binding(7) var<storage, read> objects: array<ObjectRecord>;
// Binding 8: the triangle flags (hyrt_gpu::world_triangles::triangle_flags_wgsl).
@group(0) @binding(9) var<storage, read> lights: array<LightRecord>;
@group(0) @binding(10) var<uniform> environment: EnvironmentRecord;
@group(0) @binding(11) var<storage, read> environment_texels: array<vec4<f32>>;
@group(0) @binding(12) var<storage, read> links: array<vec2<u32>>;
@group(0) @binding(13) var<storage, read> child_radiance: array<vec4<f32>>;
@group(0) @binding(14) var<storage, read_write> radiance: array<vec4<f32>>;
@group(0) @binding(15) var<storage, read> surface: array<u32>;
@group(0) @binding(16) var<uniform> surface_layout: SurfaceLayout;
@group(0) @binding(17) var<uniform> ambient_light: AmbientLightRecord;
@group(0) @binding(18) var<storage, read> ambient_texels: array<vec4<f32>>;
// The frame's shadow-mask slots (the depth's `shadow` rows; read with area lights or
// ambient occlusion).
@group(0) @binding(19) var<uniform> slot_params: SlotParams;

// mirrors hyrt_core::kernels::bounce::shade_secondary_hit; `index` is the ray's row of
// `shadow`.
fn shade_secondary_hit(index: u32, p: Parent, children: vec2<u32>) -> vec3<f32> {
    let s = p.surface;
    if s.object == INVALID_ID {
        return environment_radiance(p.d);
    }
    let pl = parent_lobes(p);
    if pl.ok {
        return shade_bouncing(index, s, pl.obj, pl.lobes, p.d, children);
    }
    let obj = p.object;
    if (obj.flags & OBJ_RAY_TRACED) != 0u {
        return shade_rt_surface(index, s, obj, -p.d);
    }
    return shade_raster_surface(index, s, obj, -p.d);
}

@compute @workgroup_size(SHADOW_WG)
fn main(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>,
        @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = (wid.y * nwg.x + wid.x) * SHADOW_WG + lid;
    if i >= min(ray_count[0], arrayLength(&rays)) {
        return;
    }
    let p = secondary_parent(rays[i], hits[i], surfaces[i]);
    var children = vec2<u32>(INVALID_ID, INVALID_ID);
    if list.last == 0u {
        children = links[i];
    }
    radiance[i] = vec4<f32>(shade_secondary_hit(i, p, children), 1.0);
}
