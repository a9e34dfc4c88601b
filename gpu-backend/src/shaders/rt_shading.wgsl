// Stage `rt_shading` (hyrt_core::kernels::shading::shade_rt_pixel per pixel): the pixels of ray-traced
// objects, Lambert + Blinn-Phong from every visible light plus ambient; alpha 1
// there, (0, 0, 0, 0) on every other pixel. One invocation per pixel.
// Appended to the generated records,
// shading_helpers.wgsl and shading.wgsl.

@group(0) @binding(0) var<storage, read> surfaces: array<SurfaceRecord>;
@group(0) @binding(1) var<storage, read> shadow: array<u32>;
@group(0) @binding(2) var<storage, read> objects: array<ObjectRecord>;
@group(0) @binding(3) var<storage, read> lights: array<LightRecord>;
@group(0) @binding(4) var<uniform> camera: CameraRecord;
@group(0) @binding(5) var<uniform> params: FrameParams;
@group(0) @binding(6) var<storage, read_write> rt: array<vec4<f32>>;

// mirrors hyrt_core::kernels::shading::sum_visible_lights with the
// shade_ray_traced closure of hyrt_core::kernels::shading::shade_rt_pixel.
fn sum_visible_lights_rt(pixel: u32, p: vec3<f32>, obj: ObjectRecord, n: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    var c = vec3<f32>(0.0);
    let nl = params.light_count;
    for (var i = 0u; i < nl; i++) {
        if (light_is_visible(shadow[pixel * nl + i])) {
            let inc = light_incidence(lights[i], p);
            c += shade_ray_traced(obj, n, v, inc.l, inc.e);
        }
    }
    return c;
}

// mirrors hyrt_core::kernels::shading::shade_rt_pixel
fn shade_rt_pixel(pixel: u32, s: SurfaceRecord, obj: ObjectRecord, eye: vec3<f32>) -> vec3<f32> {
    let p = s.position;
    let n = s.normal;
    let v = normalize_or_zero(eye - p);
    return ambient(obj) + sum_visible_lights_rt(pixel, p, obj, n, v);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (!pixel_in_image(id, params.width, params.height)) {
        return;
    }
    let pixel = id.y * params.width + id.x;
    let s = surfaces[pixel];
    if (s.object == INVALID_ID) {
        rt[pixel] = vec4<f32>(0.0);
        return;
    }
    let obj = objects[s.object];
    if ((obj.flags & OBJ_RAY_TRACED) == 0u) {
        rt[pixel] = vec4<f32>(0.0);
        return;
    }
    rt[pixel] = vec4<f32>(shade_rt_pixel(pixel, s, obj, camera.eye), 1.0);
}
