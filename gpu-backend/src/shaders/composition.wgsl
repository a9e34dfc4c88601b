// Stage `composition` (per pixel hyrt_core::kernels::shading::compose): where the ray-traced image
// has coverage (alpha > 0) the weighted mean `compose(raster, rt, weight)` with
// alpha 1, elsewhere the raster texel unchanged. One invocation per pixel.
// A plan that made one image only copies it (`params.composition`, the codes of
// hyrt_core::plan::Composition): 1 the raster image; 2 the ray-traced image where it
// has coverage, the background elsewhere. The image not made is not read.
// Appended to the generated records,
// shading_helpers.wgsl and shading.wgsl.

@group(0) @binding(0) var<storage, read> raster: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read> rt: array<vec4<f32>>;
@group(0) @binding(2) var<uniform> params: FrameParams;
@group(0) @binding(3) var<storage, read_write> final_image: array<vec4<f32>>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (!pixel_in_image(id, params.width, params.height)) {
        return;
    }
    let pixel = id.y * params.width + id.x;
    if (params.composition == COMPOSITION_COPY_RASTER) {
        final_image[pixel] = raster[pixel];
        return;
    }
    if (params.composition == COMPOSITION_RT_OVER_BACKGROUND) {
        let t = rt[pixel];
        final_image[pixel] = select(vec4<f32>(BACKGROUND, 1.0), t, t.w > 0.0);
        return;
    }
    let r = raster[pixel];
    let t = rt[pixel];
    if (t.w > 0.0) {
        final_image[pixel] = vec4<f32>(compose(r.xyz, t.xyz, params.weight), 1.0);
    } else {
        final_image[pixel] = r;
    }
}
