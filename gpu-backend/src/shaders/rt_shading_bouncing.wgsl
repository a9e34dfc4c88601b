// Stage `rt_shading` in a frame that traces bounces
// (hyrt_core::kernels::bounce::shade_rt_pixel_bouncing per pixel, as
// hyrt_cpu::rt_shading::rt_shading_bouncing_into): the pixels of ray-traced mirrors and
// glass add what their first-bounce rays (`links[pixel]` into `child_radiance`) brought
// back; every other ray-traced pixel is shaded as rt_shading.wgsl shades it, bit for
// bit. (0, 0, 0, 0) where no ray-traced object was hit.
//
// Prepended: the generated records and constants, the shading helpers, shading.wgsl,
// the texture kernels, materials.wgsl, lat_long.wgsl, ambient_light.wgsl,
// surface_shading.wgsl, ray.wgsl, bounce.wgsl, bounce_radiance.wgsl, rt_shading.wgsl (the
// bindings 0 to 12 and the pixel loop, which calls this file's `rt_pixel`).

// Binding 13: the triangle flags (hyrt_gpu::world_triangles::triangle_flags_wgsl).
@group(0) @binding(14) var<storage, read> links: array<vec2<u32>>;
@group(0) @binding(15) var<storage, read> child_radiance: array<vec4<f32>>;

// mirrors the pixel closure of hyrt_cpu::rt_shading::rt_shading_bouncing_into
fn rt_pixel(pixel: u32, s: SurfaceRecord) -> vec3<f32> {
    let p = primary_parent(gbuffer[pixel], s, camera.eye, pixel);
    return shade_rt_pixel_bouncing(pixel, p, camera.eye, links[pixel]);
}
