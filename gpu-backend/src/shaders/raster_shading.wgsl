// Stage `raster_shading` (hyrt_core::kernels::shading::shade_raster_pixel per pixel): Lambert from every
// visible light (the visible samples of area lights) plus ambient (times the ambient
// occlusion of the pixel's occlusion rays) on the pixels of rasterized objects, and on those of
// ray-traced objects only when the composition weight is below 1 (else
// (0, 0, 0, 0) there); BACKGROUND with alpha 1 where nothing was hit. One
// invocation per pixel, the object shaded as the pixel sees it (primary_object.wgsl:
// textured and vertex-coloured at the G-buffer's barycentrics where materials vary).
// Appended to the generated records, shading_helpers.wgsl, shading.wgsl, the texture
// kernels, materials.wgsl, lat_long.wgsl, ambient_light.wgsl, surface_shading.wgsl and
// primary_object.wgsl.

@group(0) @binding(0) var<storage, read> surfaces: array<SurfaceRecord>;
@group(0) @binding(1) var<storage, read> shadow: array<u32>;
@group(0) @binding(2) var<storage, read> objects: array<ObjectRecord>;
@group(0) @binding(3) var<storage, read> lights: array<LightRecord>;
@group(0) @binding(4) var<uniform> params: FrameParams;
@group(0) @binding(5) var<storage, read_write> raster: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> gbuffer: array<GBufferTexel>;
@group(0) @binding(7) var<uniform> camera: CameraRecord;
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
        raster[pixel] = vec4<f32>(BACKGROUND, 1.0);
        return;
    }
    let obj = objects[s.object];
    let shade_rt_objects = params.weight < 1.0;
    if ((obj.flags & OBJ_RAY_TRACED) != 0u && !shade_rt_objects) {
        raster[pixel] = vec4<f32>(0.0);
        return;
    }
    raster[pixel] = vec4<f32>(shade_raster_pixel(pixel, s, primary_object(pixel, s), camera.eye), 1.0);
}
