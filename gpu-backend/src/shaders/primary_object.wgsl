// mirrors hyrt_cpu::raster_shading::Primary::object: the record pixel `pixel`'s object is
// shaded with, as the primary hit's parent sees it (`primary_parent`, at the G-buffer's
// barycentrics and the eye's footprint) where materials vary, the object's own record
// elsewhere. For the primary shading stages (`raster_shading`, `rt_shading`), which bind
// `gbuffer: array<GBufferTexel>` and `camera: CameraRecord` besides what materials.wgsl
// reads.
fn primary_object(pixel: u32, s: SurfaceRecord) -> ObjectRecord {
    if materials_vary() {
        return primary_parent(gbuffer[pixel], s, camera.eye, pixel).object;
    }
    return objects[s.object];
}
