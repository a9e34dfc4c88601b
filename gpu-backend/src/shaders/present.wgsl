// `present` (not a stage: an output of the frame): the final image, linear RGBA,
// copied into a storage texture the application owns, so a frame can stay on the
// GPU and feed the application's own passes. One invocation per pixel.
// `TARGET_FORMAT` is substituted by gpu-backend/src/present.rs.

struct Size {
    width: u32,
    height: u32,
}

@group(0) @binding(0) var<storage, read> final_image: array<vec4<f32>>;
@group(0) @binding(1) var<uniform> size: Size;
@group(0) @binding(2) var target_texture: texture_storage_2d<TARGET_FORMAT, write>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= size.width || id.y >= size.height) {
        return;
    }
    textureStore(target_texture, vec2<i32>(id.xy), final_image[id.y * size.width + id.x]);
}
