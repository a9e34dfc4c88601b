// Corner normals of a scene with objects by reference: hyrt_core::geometry::WorldTriangles::normals
// over the stored normals and the objects' PlacementRecords (crate::world_triangles puts
// this file after world_triangles.wgsl and surface.wgsl, only for such scenes).
//
// Needs from the stage: world_triangles.wgsl's bindings, `normals: array<f32>` (nine per
// stored record), and surface.wgsl (`corner_normal`, `geometric_normal`, `normalize_or`,
// `any_nonzero`).

// mirrors glam::Mat3 * Vec3 (glam 0.34): (x_axis * v.x + y_axis * v.y) + z_axis * v.z,
// every product rounded on its own, the sums left to right.
fn normal_matrix_mul(p: PlacementRecord, v: vec3<f32>) -> vec3<f32> {
    var r = placed_scaled(p.normal_x, v.x);
    r = placed_rounded(r + placed_scaled(p.normal_y, v.y));
    return placed_rounded(r + placed_scaled(p.normal_z, v.z));
}

// mirrors hyrt_core::geometry::world_normals: the mesh's vertex normals under the normal
// matrix (the geometric normal where one vanishes), else the geometric normal.
fn world_normals(world: array<vec3<f32>, 3>, idx: vec3<u32>, p: PlacementRecord) -> array<vec3<f32>, 3> {
    let face = geometric_normal(world[0], world[1], world[2]);
    if p.mesh_normals == INVALID_ID {
        return array<vec3<f32>, 3>(face, face, face);
    }
    var out = array<vec3<f32>, 3>(face, face, face);
    for (var k = 0u; k < 3u; k++) {
        let n = normalize_or(normal_matrix_mul(p, mesh_vec3(p.mesh_normals, idx[k])), vec3<f32>(0.0));
        if any_nonzero(n) {
            out[k] = n;
        }
    }
    return out;
}

// mirrors hyrt_core::geometry::WorldTriangles::normals: the world-space unit normals at the
// corners of `tri`, the record `world_triangle` gave (its object and mesh index name it).
fn world_triangle_normals(gi: u32, tri: TriangleRecord) -> array<vec3<f32>, 3> {
    let p = placements[tri.object];
    if p.first_record != INVALID_ID {
        let r = p.first_record + tri.triangle;
        return array<vec3<f32>, 3>(corner_normal(r, 0u), corner_normal(r, 1u), corner_normal(r, 2u));
    }
    let world = array<vec3<f32>, 3>(tri.v0, tri.v1, tri.v2);
    return world_normals(world, mesh_triangle(p, tri.triangle), p);
}
