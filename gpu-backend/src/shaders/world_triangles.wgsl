// World triangles of a scene with objects by reference: the accessors of
// hyrt_core::geometry::WorldTriangles (`get`, `flags`) over the stored table and, per
// object, its PlacementRecord (crate::world_triangles, which puts this file in a stage
// only for such scenes). A stored object's records are read from `triangles` (by record
// index); an object by reference's are made from its mesh's words under its transform, by
// the operations of hyrt_core::geometry::world_record, so both give the CPU's bits.
//
// Needs from the stage: `triangles: array<TriangleRecord>` (the stored records),
// `placements: array<PlacementRecord>` (one per object, in object order),
// `mesh_words: array<u32>` (hyrt_core::geometry::WorldTriangles::mesh_words), and
// `rounded(x: f32) -> f32`, `mul(a: f32, b: f32) -> f32` over an always-zero uniform word.

// mirrors hyrt_core::geometry::WorldTriangles::object_of: the last object whose first id
// is at most `gi` (slice::partition_point over the objects' first ids).
fn object_of_triangle(gi: u32) -> u32 {
    var lo = 0u;
    var hi = arrayLength(&placements);
    while lo < hi {
        let mid = lo + (hi - lo) / 2u;
        if placements[mid].first_triangle <= gi {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo - 1u;
}

fn placed_scaled(a: vec3<f32>, s: f32) -> vec3<f32> {
    return vec3<f32>(mul(a.x, s), mul(a.y, s), mul(a.z, s));
}

fn placed_rounded(a: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(rounded(a.x), rounded(a.y), rounded(a.z));
}

// mirrors glam::Mat4::transform_point3 (glam 0.34, SSE2 and scalar alike):
// ((x_axis * v.x + y_axis * v.y) + z_axis * v.z) + w_axis, every product rounded on its
// own (no multiply-add), the sums left to right.
fn transform_point3(p: PlacementRecord, v: vec3<f32>) -> vec3<f32> {
    var r = placed_scaled(p.to_world_x, v.x);
    r = placed_rounded(placed_scaled(p.to_world_y, v.y) + r);
    r = placed_rounded(placed_scaled(p.to_world_z, v.z) + r);
    return placed_rounded(p.to_world_w + r);
}

// Vector `i` of the mesh words from word `first` on (three f32 bit patterns).
fn mesh_vec3(first: u32, i: u32) -> vec3<f32> {
    let b = first + 3u * i;
    return vec3<f32>(bitcast<f32>(mesh_words[b]), bitcast<f32>(mesh_words[b + 1u]), bitcast<f32>(mesh_words[b + 2u]));
}

// Triangle `local` of an object by reference's mesh: its three vertex indices.
fn mesh_triangle(p: PlacementRecord, local: u32) -> vec3<u32> {
    let b = p.mesh_indices + 3u * local;
    return vec3<u32>(mesh_words[b], mesh_words[b + 1u], mesh_words[b + 2u]);
}

// mirrors hyrt_core::geometry::WorldTriangles::reference_vertices: the world vertices of
// triangle `local` of an object by reference.
fn reference_vertices(p: PlacementRecord, idx: vec3<u32>) -> array<vec3<f32>, 3> {
    return array<vec3<f32>, 3>(
        transform_point3(p, mesh_vec3(p.mesh_positions, idx.x)),
        transform_point3(p, mesh_vec3(p.mesh_positions, idx.y)),
        transform_point3(p, mesh_vec3(p.mesh_positions, idx.z)),
    );
}

// mirrors hyrt_core::geometry::world_record
fn world_record(world: array<vec3<f32>, 3>, object: u32, index: u32, flags: u32) -> TriangleRecord {
    return TriangleRecord(world[0], object, world[1], index, world[2], flags);
}

// mirrors hyrt_core::geometry::WorldTriangles::get for triangle `local` of object `object`.
fn object_triangle(object: u32, local: u32) -> TriangleRecord {
    let p = placements[object];
    if p.first_record != INVALID_ID {
        return triangles[p.first_record + local];
    }
    return world_record(reference_vertices(p, mesh_triangle(p, local)), object, local, p.flags);
}

// mirrors hyrt_core::geometry::WorldTriangles::get: global triangle `gi`'s world record.
fn world_triangle(gi: u32) -> TriangleRecord {
    let o = object_of_triangle(gi);
    return object_triangle(o, gi - placements[o].first_triangle);
}

// mirrors hyrt_core::geometry::WorldTriangles::flags: global triangle `gi`'s TRI_* flags,
// its object's.
fn world_triangle_flags(gi: u32) -> u32 {
    return placements[object_of_triangle(gi)].flags;
}
