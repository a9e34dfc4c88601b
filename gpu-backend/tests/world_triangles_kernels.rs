//! The world-triangle accessors of scenes with objects by reference
//! (`shaders/world_triangles.wgsl`, `shaders/world_normals.wgsl`) against the core's
//! `WorldTriangles::get`, `normals` and `flags`, bit for bit, on every global triangle of a
//! seeded table: stored objects and objects by reference under random affine transforms
//! (rotations, non-uniform and mirroring scales, shears, translations far from the
//! origin), meshes with and without vertex normals (some of them zero, some degenerate
//! triangles), and objects without triangles between the others. The stage tests compare
//! whole frames; this one names the accessor and the word that differ.

mod common;

use std::sync::Arc;

use common::test_context;
use hyrt_core::formats::{FrameParams, PlacementRecord, TriangleRecord, TRI_ALPHA_TEST, TRI_INWARD, TRI_RAY_TRACED};
use hyrt_core::geometry::{world_normals, world_record, ByReference, MeshSource, ObjectTransform, WorldTriangles};
use hyrt_core::glam::{Mat4, Vec3, Vec4};
use hyrt_gpu::exact::same_bits;
use hyrt_gpu::gpu_buffer::{read_back, storage, upload};
use hyrt_gpu::shader::{bind_buffers, compute_pipeline, storage_entry, uniform_entry};
use hyrt_gpu::world_triangles::by_reference_kernels_wgsl;
use wgpu::util::DeviceExt;

/// Result words per triangle: the record (12), the corner normals (9), the flags (1).
const OUT: usize = 22;

const ENTRY: &str = r#"
@group(0) @binding(5) var<storage, read_write> results: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let gi = gid.x;
    if gi >= arrayLength(&results) / OUT {
        return;
    }
    let o = gi * OUT;
    let t = world_triangle(gi);
    let words = array<u32, 12>(
        bitcast<u32>(t.v0.x), bitcast<u32>(t.v0.y), bitcast<u32>(t.v0.z), t.object,
        bitcast<u32>(t.v1.x), bitcast<u32>(t.v1.y), bitcast<u32>(t.v1.z), t.triangle,
        bitcast<u32>(t.v2.x), bitcast<u32>(t.v2.y), bitcast<u32>(t.v2.z), t.flags,
    );
    for (var k = 0u; k < 12u; k++) {
        results[o + k] = words[k];
    }
    let n = world_triangle_normals(gi, t);
    for (var c = 0u; c < 3u; c++) {
        results[o + 12u + 3u * c] = bitcast<u32>(n[c].x);
        results[o + 13u + 3u * c] = bitcast<u32>(n[c].y);
        results[o + 14u + 3u * c] = bitcast<u32>(n[c].z);
    }
    results[o + 21u] = world_triangle_flags(gi);
}
"#;

/// The name of result word `w`.
fn word_name(w: usize) -> String {
    const RECORD: [&str; 12] =
        ["v0.x", "v0.y", "v0.z", "object", "v1.x", "v1.y", "v1.z", "triangle", "v2.x", "v2.y", "v2.z", "flags"];
    match w {
        0..=11 => format!("world_triangle.{}", RECORD[w]),
        12..=20 => format!("world_triangle_normals[{}].{}", (w - 12) / 3, ["x", "y", "z"][(w - 12) % 3]),
        _ => "world_triangle_flags".to_string(),
    }
}

/// A xorshift stream of floats in [0, 1).
struct Stream(u64);

impl Stream {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }

    fn signed(&mut self) -> f32 {
        self.next() * 2.0 - 1.0
    }

    fn vec3(&mut self, scale: f32) -> Vec3 {
        Vec3::new(self.signed(), self.signed(), self.signed()) * scale
    }

    fn below(&mut self, n: u32) -> u32 {
        ((self.next() * n as f32) as u32).min(n - 1)
    }
}

/// A mesh of `vertices` random positions and `triangles` random triangles (every tenth
/// repeating a corner: degenerate), with vertex normals when `normals` (every seventh zero).
fn mesh(s: &mut Stream, vertices: u32, triangles: u32, normals: bool) -> MeshSource {
    let positions: Vec<Vec3> = (0..vertices).map(|_| s.vec3(3.0)).collect();
    let indices: Vec<[u32; 3]> = (0..triangles)
        .map(|t| {
            let a = s.below(vertices);
            let b = if t % 10 == 9 { a } else { s.below(vertices) };
            [a, b, s.below(vertices)]
        })
        .collect();
    let normals = normals.then(|| {
        (0..vertices).map(|v| if v % 7 == 3 { Vec3::ZERO } else { s.vec3(1.0).normalize_or_zero() }).collect()
    });
    MeshSource { positions, normals, indices, every_vertex_used: false }
}

/// A random affine object-to-world transform: a linear part of random columns (shears,
/// non-uniform scales; mirroring for odd `k`), a translation up to 10^4 from the origin.
fn transform(s: &mut Stream, k: usize) -> Mat4 {
    let mut x = s.vec3(2.0) + Vec3::X;
    if k % 2 == 1 {
        x = -x;
    }
    let (y, z) = (s.vec3(2.0) + Vec3::Y, s.vec3(2.0) + Vec3::Z * 0.5);
    let t = s.vec3(1.0e4);
    Mat4::from_cols(x.extend(0.0), y.extend(0.0), z.extend(0.0), Vec4::new(t.x, t.y, t.z, 1.0))
}

/// The seeded table: `(triangles, the objects' first ids and counts)`.
fn table() -> (WorldTriangles, Vec<(u32, u32)>) {
    let mut s = Stream(0x2545_f491_4f6c_dd1d);
    let meshes = vec![
        Arc::new(mesh(&mut s, 97, 211, true)),
        Arc::new(mesh(&mut s, 60, 150, false)),
        Arc::new(mesh(&mut s, 12, 0, true)),
    ];
    let flag_sets = [TRI_RAY_TRACED, TRI_INWARD, TRI_RAY_TRACED | TRI_ALPHA_TEST, 0];
    // (mesh, by reference): stored objects between objects by reference, and empty ones.
    let objects =
        [(0, true), (1, false), (0, true), (2, true), (1, true), (0, false), (2, false), (1, true), (0, true)];
    let counts: Vec<u32> = objects.iter().map(|&(m, _)| meshes[m].indices.len() as u32).collect();
    let transforms: Vec<Mat4> = (0..objects.len()).map(|k| transform(&mut s, k)).collect();
    let placements = objects
        .iter()
        .enumerate()
        .map(|(k, &(m, by_reference))| {
            by_reference.then(|| ByReference {
                mesh: m as u32,
                transform: ObjectTransform::new(transforms[k]),
                flags: flag_sets[k % flag_sets.len()],
            })
        })
        .collect();
    let mut triangles = WorldTriangles::with_placements(&counts, placements, meshes.clone());
    // The stored objects' records, written as `WorldGeometry::write_object` writes them.
    let mut first = 0u32;
    let mut spans = Vec::new();
    let mut first_record = 0u32;
    for (k, &(m, by_reference)) in objects.iter().enumerate() {
        spans.push((first, counts[k]));
        first += counts[k];
        if by_reference {
            continue;
        }
        let mesh = &meshes[m];
        let t = ObjectTransform::new(transforms[k]);
        let (records, normals) = triangles.object_mut(first_record, counts[k]);
        for (ti, idx) in mesh.indices.iter().enumerate() {
            let world = idx.map(|i| t.to_world.transform_point3(mesh.positions[i as usize]));
            records[ti] = world_record(world, k as u32, ti as u32, flag_sets[k % flag_sets.len()]);
            normals[ti] = world_normals(world, *idx, mesh.normals.as_deref(), &t.normal_matrix);
        }
        first_record += counts[k];
    }
    (triangles, spans)
}

#[test]
fn world_triangles_by_reference_match_cpu_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let (table, spans) = table();
    assert!(table.has_references());
    let count = table.len();
    let (words, meshes) = table.mesh_words().expect("a small table");
    let placements: Vec<PlacementRecord> =
        spans.iter().enumerate().map(|(o, &(first, n))| table.placement_record(o as u32, first, n, &meshes)).collect();
    for p in &placements {
        p.validate().expect("valid placement");
    }
    let normals: Vec<f32> = table.stored_normals().iter().flat_map(|n| n.iter().flat_map(|v| v.to_array())).collect();

    let source = format!("{}\nconst OUT: u32 = {OUT}u;\n{ENTRY}", by_reference_kernels_wgsl(0));
    let entries = [
        uniform_entry(0),
        storage_entry(1, true),
        storage_entry(2, true),
        storage_entry(3, true),
        storage_entry(4, true),
        storage_entry(5, false),
    ];
    let (pipeline, layout) = compute_pipeline(&ctx, "world triangles kernels test", &source, &entries);
    let params = ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("params"),
        contents: bytemuck::bytes_of(&FrameParams::new(1, 1, 0, 0.5)),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let buffers = [
        &params,
        &upload::<TriangleRecord>(&ctx, "stored triangles", table.stored_records()),
        &upload::<f32>(&ctx, "stored normals", &normals),
        &upload::<PlacementRecord>(&ctx, "placements", &placements),
        &upload::<u32>(&ctx, "mesh words", &words),
        &storage::<u32>(&ctx, "results", count * OUT).expect("results buffer"),
    ];
    let group = bind_buffers(&ctx, "world triangles kernels test", &layout, &buffers);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups((count as u32).div_ceil(64), 1, 1);
    }
    ctx.queue.submit([encoder.finish()]);
    let gpu = read_back::<u32>(&ctx, buffers[5], count * OUT).expect("read back");

    let mut per_word = std::collections::BTreeMap::<String, usize>::new();
    let mut first = None;
    let (mut by_reference, mut stored) = (0, 0);
    for gi in 0..count {
        let r = table.get(gi);
        let mut want: Vec<u32> = bytemuck::cast_slice::<TriangleRecord, u32>(&[r]).to_vec();
        want.extend(table.normals(gi).iter().flat_map(|n| n.to_array().map(f32::to_bits)));
        want.push(table.flags(gi));
        match table.record_of(gi) {
            Some(_) => stored += 1,
            None => by_reference += 1,
        }
        for (w, (&g, &c)) in gpu[gi * OUT..(gi + 1) * OUT].iter().zip(&want).enumerate() {
            if !same_bits(g, c) {
                *per_word.entry(word_name(w)).or_default() += 1;
                first.get_or_insert_with(|| format!("triangle {gi} {}: gpu {g:#010x} cpu {c:#010x}", word_name(w)));
            }
        }
    }
    // Both kinds of object were read, and the table is not trivially small.
    assert!(stored > 100 && by_reference > 500, "{stored} stored, {by_reference} by reference");
    assert!(per_word.is_empty(), "{}: differing words {per_word:?}; first: {first:?}", ctx.info.name);
}
