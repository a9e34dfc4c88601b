// `present` (not a stage: an output of the frame): the final image, linear RGBA,
// copied into a storage texture the application owns, so a frame can stay on the
// GPU and feed the application's own passes. One invocation per pixel.
// `TARGET_FORMAT` is substituted by gpu-backend/src/present.rs, which prepends the
// generated records (hyrt_core::formats::wgsl).

@group(0) @binding(0) var<storage, read> final_image: array<vec4<f32>>;
// The band (gpu-backend/src/band.rs): its final image goes to its rows of the target.
@group(0) @binding(1) var<uniform> params: FrameParams;
@group(0) @binding(2) var target_texture: texture_storage_2d<TARGET_FORMAT, write>;
// `[pixels, own_lo, own_hi, 0]`: the band's own pixels (all but the halo rows of a band
// of a denoised frame, which the neighbouring bands own).
@group(0) @binding(3) var<storage, read> live: array<u32, 4>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    let pixel = id.y * params.width + id.x;
    if (pixel < live[1] || pixel >= live[2]) {
        return;
    }
    textureStore(target_texture, vec2<i32>(vec2<u32>(id.x, id.y + params.first_row)),
        final_image[id.y * params.width + id.x]);
}
