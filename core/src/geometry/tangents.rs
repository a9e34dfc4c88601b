//! Tangent frames for normal maps: each triangle corner's tangent (`xyz`, along increasing
//! u of the normal texture's coordinates) and the sign of its bitangent (`w`:
//! `bitangent = cross(normal, tangent) * w`, glTF's definition), in object space from the
//! mesh ([`mesh_tangents`]) and then in world space ([`world_tangents`]), stored per
//! triangle corner in [`super::SurfaceTables::tangents`].
//!
//! A mesh with a `TANGENT` attribute keeps its tangents. Without one, they are generated as
//! glTF asks ("client implementations SHOULD calculate tangents using default MikkTSpace
//! algorithms with the specified vertex positions, normals, and texture coordinates
//! associated with the normal texture"), with `bevy_mikktspace` (a safe port of Mikkelsen's
//! reference code, the same output on x86). glTF's texture coordinates have v growing
//! down the image, while normal maps (and the tools that bake them and export glTF
//! tangents, such as Blender) take +Y, green, up the image: MikkTSpace is given `(u, -v)`,
//! so that the bitangent points up the image, as an exported `TANGENT` does (three.js
//! negates the generated sign for glTF for the same reason).

use glam::{Mat3, Mat4, Vec3};

use crate::scene::Mesh;

/// The object-space tangents of `mesh`'s triangle corners for texture-coordinate set
/// `tex_coord`: its `TANGENT` attribute, else MikkTSpace's ([module docs](self)). Zeros
/// where none can be had (the set is missing, a corner has no tangent space, generation
/// fails): the normal map then leaves those corners' normals as they are
/// ([`crate::kernels::texture::Materials::normal_mapped`]).
pub fn mesh_tangents(mesh: &Mesh, tex_coord: u32) -> Vec<[[f32; 4]; 3]> {
    if let Some(t) = &mesh.attributes.tangents {
        return mesh.indices.iter().map(|idx| idx.map(|i| t[i as usize])).collect();
    }
    let zeros = vec![[[0.0; 4]; 3]; mesh.indices.len()];
    let Some(Some(uv)) = mesh.attributes.tex_coords.get(tex_coord as usize) else {
        return zeros;
    };
    let mut g = MikkMesh { mesh, uv, out: zeros };
    match bevy_mikktspace::generate_tangents(&mut g) {
        Ok(()) => g.out,
        Err(_) => vec![[[0.0; 4]; 3]; mesh.indices.len()],
    }
}

/// `corners` (object space) under `transform` into `out`: each tangent through the
/// transform's linear part and normalized (tangents are surface directions, transformed
/// as positions are, not as normals), its sign flipped where the transform mirrors
/// (a negative determinant turns the cross product of transformed normal and tangent
/// around). A zero tangent stays zero.
pub fn world_tangents(out: &mut [[[f32; 4]; 3]], corners: &[[[f32; 4]; 3]], transform: &Mat4) {
    let m = Mat3::from_mat4(*transform);
    let mirrored = m.determinant() < 0.0;
    for (o, c) in out.iter_mut().zip(corners) {
        *o = c.map(|t| {
            let d = (m * Vec3::new(t[0], t[1], t[2])).normalize_or_zero();
            let w = if (t[3] < 0.0) != mirrored { -1.0 } else { 1.0 };
            [d.x, d.y, d.z, w]
        });
    }
}

/// A mesh as MikkTSpace reads it: its triangles, its vertex normals (the face's where it
/// has none) and one coordinate set, with v negated ([module docs](self)); the tangents
/// are written per triangle corner.
struct MikkMesh<'a> {
    mesh: &'a Mesh,
    uv: &'a [glam::Vec2],
    out: Vec<[[f32; 4]; 3]>,
}

impl bevy_mikktspace::Geometry for MikkMesh<'_> {
    fn num_faces(&self) -> usize {
        self.mesh.indices.len()
    }

    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }

    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.mesh.positions[self.mesh.indices[face][vert] as usize].into()
    }

    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        match &self.mesh.normals {
            Some(n) => n[self.mesh.indices[face][vert] as usize].into(),
            None => {
                let [a, b, c] = self.mesh.indices[face].map(|i| self.mesh.positions[i as usize]);
                (b - a).cross(c - a).normalize_or_zero().into()
            }
        }
    }

    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        let t = self.uv[self.mesh.indices[face][vert] as usize];
        [t.x, -t.y]
    }

    fn set_tangent(&mut self, tangent_space: Option<bevy_mikktspace::TangentSpace>, face: usize, vert: usize) {
        if let Some(t) = tangent_space {
            self.out[face][vert] = t.tangent_encoded();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    /// The unit grid in the XZ plane (normal +Y) with u along +x and v along +z.
    fn grid() -> Mesh {
        let mut mesh = Mesh::grid("g", 3);
        let uv = mesh.positions.iter().map(|p| Vec2::new(p.x + 0.5, p.z + 0.5)).collect();
        mesh.attributes.tex_coords[0] = Some(uv);
        mesh
    }

    #[test]
    fn generated_tangents_run_along_u_with_the_bitangent_up_the_image() {
        // Tangent +x (increasing u); v grows along +z, down the image, so the bitangent
        // cross(+Y, +x) w = -z w must point up the image, -z: w = +1.
        for t in mesh_tangents(&grid(), 0).iter().flatten() {
            assert!((Vec3::new(t[0], t[1], t[2]) - Vec3::X).length() < 1e-6, "{t:?}");
            assert_eq!(t[3], 1.0);
        }
        // Mirrored coordinates (u decreasing along x) flip the tangent and the sign.
        let mut mirrored = grid();
        for c in mirrored.attributes.tex_coords[0].as_mut().unwrap() {
            c.x = 1.0 - c.x;
        }
        for t in mesh_tangents(&mirrored, 0).iter().flatten() {
            assert!((Vec3::new(t[0], t[1], t[2]) + Vec3::X).length() < 1e-6, "{t:?}");
            assert_eq!(t[3], -1.0);
        }
        assert!(mesh_tangents(&grid(), 1).iter().flatten().all(|t| *t == [0.0; 4]), "no such set: zeros");
    }

    #[test]
    fn given_tangents_are_kept_and_mirroring_transforms_flip_the_sign() {
        let mut mesh = grid();
        mesh.attributes.tangents = Some(vec![[0.0, 0.0, 1.0, -1.0]; mesh.positions.len()]);
        let corners = mesh_tangents(&mesh, 0);
        assert!(corners.iter().flatten().all(|t| *t == [0.0, 0.0, 1.0, -1.0]));
        let mut out = vec![[[0.0; 4]; 3]; corners.len()];
        world_tangents(&mut out, &corners, &Mat4::from_scale(Vec3::new(1.0, 1.0, -2.0)));
        assert!(out.iter().flatten().all(|t| *t == [0.0, 0.0, -1.0, 1.0]), "{:?}", out[0]);
        world_tangents(&mut out, &corners, &Mat4::from_rotation_y(std::f32::consts::FRAC_PI_2));
        assert!(out.iter().flatten().all(|t| (Vec3::new(t[0], t[1], t[2]) - Vec3::X).length() < 1e-6 && t[3] == -1.0));
    }
}
