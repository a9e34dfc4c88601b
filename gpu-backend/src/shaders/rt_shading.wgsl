// Stage `rt_shading` (hyrt_core::kernels::shading::shade_rt_pixel per pixel): the pixels of ray-traced
// objects, Lambert + Blinn-Phong from every visible light (the visible samples of area
// lights) plus ambient (times the ambient occlusion of the pixel's occlusion rays); alpha 1
// there, (0, 0, 0, 0) on every other pixel. One invocation per pixel.
// Appended to the generated records, shading_helpers.wgsl, shading.wgsl, the texture
// kernels, materials.wgsl, lat_long.wgsl, ambient_light.wgsl and surface_shading.wgsl, and followed by the frame's
// `rt_pixel(pixel, surface)`: `shade_rt_pixel` of the pixel's shaded object
// (primary_object.wgsl) in the paper's frame, `shade_rt_pixel_bouncing` in one that
// traces bounces (rt_shading_bouncing.wgsl). The G-buffer (barycentrics) and the surface
// tables are read only where materials vary (textures, vertex colours), the ambient
// light's texels only under an image-based light.

@group(0) @binding(0) var<storage, read> surfaces: array<SurfaceRecord>;
@group(0) @binding(1) var<storage, read> shadow: array<u32>;
@group(0) @binding(2) var<storage, read> objects: array<ObjectRecord>;
@group(0) @binding(3) var<storage, read> lights: array<LightRecord>;
@group(0) @binding(4) var<uniform> camera: CameraRecord;
@group(0) @binding(5) var<uniform> params: FrameParams;
@group(0) @binding(6) var<storage, read_write> rt: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> gbuffer: array<GBufferTexel>;
@group(0) @binding(8) var<storage, read> surface: array<u32>;
@group(0) @binding(9) var<uniform> surface_layout: SurfaceLayout;
@group(0) @binding(10) var<uniform> ambient_light: AmbientLightRecord;
@group(0) @binding(11) var<storage, read> ambient_texels: array<vec4<f32>>;
// The frame's shadow-mask slots (read with area lights or ambient occlusion).
@group(0) @binding(12) var<uniform> slot_params: SlotParams;

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
    rt[pixel] = vec4<f32>(rt_pixel(pixel, s), 1.0);
}
