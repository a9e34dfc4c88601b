//! The built-in default scene, in the spirit of the paper's Figure 8: three
//! coloured diffuse ray-traced planes (red, green, blue) forming a corner, a
//! golden specular ray-traced object that reflects them, two purple rasterized
//! objects, and two point lights that make the objects cast shadows onto the planes;
//! and, beyond the figure, a ray-traced glass ball (IOR 1.5) that refracts them.
//! Shaded with the glTF BRDF ([`ShadingModel::Gltf`]) like every scene loaded from a file;
//! the paper's figures and its Table 2 use the paper's model (`scene.shading =
//! ShadingModel::Paper`, `hyrt render --shading paper`).
//!
//! Also the procedural meshes it is made of, which tests use too.

use std::f32::consts::{PI, TAU};

use glam::{Mat4, Quat, Vec2, Vec3};

use super::{Camera, Light, Material, MaterialKind, Mesh, RenderMode, Scene, ShadingModel, VertexAttributes};

impl Mesh {
    /// A unit square in the XZ plane centred at the origin, facing +Y, split into
    /// `n` x `n` quads (two triangles each, shared edges and vertices).
    pub fn grid(name: &str, n: u32) -> Mesh {
        let n = n.max(1);
        let mut positions = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                positions.push(Vec3::new(i as f32 / n as f32 - 0.5, 0.0, j as f32 / n as f32 - 0.5));
            }
        }
        let mut indices = Vec::new();
        let row = n + 1;
        for j in 0..n {
            for i in 0..n {
                let a = j * row + i;
                let (b, c, d) = (a + 1, a + row, a + row + 1);
                indices.push([a, c, b]);
                indices.push([b, c, d]);
            }
        }
        let normals = Some(vec![Vec3::Y; positions.len()]);
        Mesh { name: name.into(), positions, normals, indices, ..Default::default() }
    }

    /// A UV sphere of radius 1 with `segments` around and `rings` from pole to pole.
    pub fn uv_sphere(name: &str, segments: u32, rings: u32) -> Mesh {
        let (segments, rings) = (segments.max(3), rings.max(2));
        let mut positions = Vec::new();
        // Seam (s = segments) and pole (r = 0, rings) vertices take exact values, so
        // they are bit-identical to their twins: sin(2 pi) and sin(pi) are not 0 in f32,
        // and a seam off by 1e-7 would not be watertight.
        for r in 0..=rings {
            let theta = PI * r as f32 / rings as f32;
            let (st, ct) = match r {
                0 => (0.0, 1.0),
                _ if r == rings => (0.0, -1.0),
                _ => (theta.sin(), theta.cos()),
            };
            for s in 0..=segments {
                let phi = TAU * s as f32 / segments as f32;
                let (sp, cp) = if s == segments { (0.0, 1.0) } else { (phi.sin(), phi.cos()) };
                positions.push(Vec3::new(st * cp, ct, st * sp));
            }
        }
        let row = segments + 1;
        let mut indices = Vec::new();
        for r in 0..rings {
            for s in 0..segments {
                let a = r * row + s;
                let (b, c, d) = (a + 1, a + row, a + row + 1);
                if r != 0 {
                    indices.push([a, b, c]);
                }
                if r != rings - 1 {
                    indices.push([b, d, c]);
                }
            }
        }
        let normals = Some(positions.clone());
        Mesh { name: name.into(), positions, normals, indices, ..Default::default() }
    }

    /// A torus in the XZ plane: ring radius `major`, tube radius `minor`.
    pub fn torus(name: &str, major: f32, minor: f32, segments: u32, sides: u32) -> Mesh {
        let (segments, sides) = (segments.max(3), sides.max(3));
        let mut positions = Vec::new();
        let mut normals = Vec::new();
        for i in 0..segments {
            let u = TAU * i as f32 / segments as f32;
            let centre = Vec3::new(u.cos(), 0.0, u.sin()) * major;
            for j in 0..sides {
                let v = TAU * j as f32 / sides as f32;
                let n = Vec3::new(u.cos() * v.cos(), v.sin(), u.sin() * v.cos());
                positions.push(centre + n * minor);
                normals.push(n);
            }
        }
        let mut indices = Vec::new();
        for i in 0..segments {
            for j in 0..sides {
                let a = i * sides + j;
                let b = i * sides + (j + 1) % sides;
                let c = ((i + 1) % segments) * sides + j;
                let d = ((i + 1) % segments) * sides + (j + 1) % sides;
                indices.push([a, b, c]);
                indices.push([b, d, c]);
            }
        }
        Mesh { name: name.into(), positions, normals: Some(normals), indices, ..Default::default() }
    }

    /// An axis-aligned cube from -1 to 1 with flat faces (24 vertices, 12 triangles).
    pub fn cube(name: &str) -> Mesh {
        let mut positions = Vec::new();
        let mut normals = Vec::new();
        let mut indices = Vec::new();
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let mut n = Vec3::ZERO;
                n[axis] = sign;
                let (mut u, mut v) = (Vec3::ZERO, Vec3::ZERO);
                u[(axis + 1) % 3] = 1.0;
                v[(axis + 2) % 3] = 1.0;
                if sign < 0.0 {
                    std::mem::swap(&mut u, &mut v);
                }
                let base = positions.len() as u32;
                for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    positions.push(n + u * a + v * b);
                    normals.push(n);
                }
                indices.push([base, base + 1, base + 2]);
                indices.push([base, base + 2, base + 3]);
            }
        }
        Mesh { name: name.into(), positions, normals: Some(normals), indices, ..Default::default() }
    }

    /// The square [-1, 1]^2 in the plane z = 0 facing +z (two triangles sharing the diagonal
    /// from (-1, -1) to (1, 1)), with glTF texture coordinates `TEXCOORD_0`:
    /// `u = (x + 1) / 2`, `v = (1 - y) / 2` (v down the image, so the image stands upright).
    pub fn uv_quad(name: &str) -> Mesh {
        let positions = vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ];
        let uv = vec![Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 0.0)];
        Mesh {
            name: name.into(),
            positions,
            normals: Some(vec![Vec3::Z; 4]),
            indices: vec![[0, 1, 2], [0, 2, 3]],
            attributes: VertexAttributes { tex_coords: [Some(uv), None], ..VertexAttributes::default() },
        }
    }
}

impl Scene {
    /// The built-in default scene (paper Figure 8); see the module docs.
    pub fn default_scene() -> Scene {
        let mut scene = Scene { shading: ShadingModel::Gltf, ..Scene::default() };
        let diffuse = |name: &str, rgb: Vec3| Material {
            name: name.into(),
            base_color: rgb,
            metallic: 0.0,
            roughness: 0.8,
            transmission: 0.0,
            kind: MaterialKind::Diffuse,
            ..Material::grey()
        };
        let rt = RenderMode::RayTraced;
        // Three planes forming a corner: floor (blue), back wall (red), left wall (green).
        let size = 8.0;
        scene.add_object(
            Mesh::grid("blue_floor", 8),
            diffuse("blue", Vec3::new(0.15, 0.25, 0.8)),
            Mat4::from_scale(Vec3::splat(size)),
            rt,
        );
        scene.add_object(
            Mesh::grid("red_wall", 8),
            diffuse("red", Vec3::new(0.8, 0.15, 0.12)),
            Mat4::from_translation(Vec3::new(0.0, size * 0.5, -size * 0.5))
                * Mat4::from_quat(Quat::from_rotation_x(PI * 0.5))
                * Mat4::from_scale(Vec3::splat(size)),
            rt,
        );
        scene.add_object(
            Mesh::grid("green_wall", 8),
            diffuse("green", Vec3::new(0.15, 0.7, 0.2)),
            Mat4::from_translation(Vec3::new(-size * 0.5, size * 0.5, 0.0))
                * Mat4::from_quat(Quat::from_rotation_z(-PI * 0.5))
                * Mat4::from_scale(Vec3::splat(size)),
            rt,
        );
        // The golden specular object (the paper's golden bunny).
        scene.add_object(
            Mesh::uv_sphere("golden_sphere", 48, 24),
            Material {
                name: "gold".into(),
                base_color: Vec3::new(1.0, 0.76, 0.33),
                metallic: 1.0,
                roughness: 0.2,
                transmission: 0.0,
                kind: MaterialKind::Specular,
                ..Material::grey()
            },
            Mat4::from_translation(Vec3::new(-0.6, 1.2, -0.8)) * Mat4::from_scale(Vec3::splat(1.2)),
            rt,
        );
        // A glass ball on the floor in front of the corner (not in the paper's figure:
        // refraction is its future work).
        scene.add_object(
            Mesh::uv_sphere("glass_ball", 48, 24),
            Material {
                name: "glass".into(),
                base_color: Vec3::new(0.95, 0.97, 1.0),
                metallic: 0.0,
                roughness: 0.0,
                transmission: 1.0,
                kind: MaterialKind::Glass { ior: 1.5 },
                ..Material::grey()
            },
            Mat4::from_translation(Vec3::new(-0.3, 0.65, 2.0)) * Mat4::from_scale(Vec3::splat(0.65)),
            rt,
        );
        // Two purple rasterized objects (the paper's teapots).
        let purple = Vec3::new(0.55, 0.2, 0.7);
        scene.add_object(
            Mesh::torus("purple_torus", 1.0, 0.35, 48, 24),
            diffuse("purple", purple),
            Mat4::from_translation(Vec3::new(2.0, 0.9, 1.2))
                * Mat4::from_quat(Quat::from_rotation_x(-1.0) * Quat::from_rotation_z(0.3))
                * Mat4::from_scale(Vec3::splat(0.8)),
            RenderMode::Raster,
        );
        scene.add_object(
            Mesh::cube("purple_cube"),
            diffuse("purple", purple),
            Mat4::from_translation(Vec3::new(1.6, 0.6, -1.8))
                * Mat4::from_quat(Quat::from_rotation_y(0.6))
                * Mat4::from_scale(Vec3::splat(0.6)),
            RenderMode::Raster,
        );
        scene.lights = vec![
            Light::point(Vec3::new(3.0, 6.5, 4.0), Vec3::new(1.0, 0.95, 0.9), 60.0),
            Light::point(Vec3::new(-1.5, 5.0, 5.0), Vec3::new(0.8, 0.85, 1.0), 30.0),
        ];
        scene.camera = Some(Camera {
            eye: Vec3::new(4.5, 4.2, 8.5),
            target: Vec3::new(0.0, 1.2, 0.0),
            up: Vec3::Y,
            fov_y_deg: 45.0,
            near: 0.1,
            far: 100.0,
        });
        scene
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_scene_matches_figure_8() {
        let s = Scene::default_scene();
        let rt = s.objects.iter().filter(|o| o.render_mode == RenderMode::RayTraced).count();
        let raster = s.objects.iter().filter(|o| o.render_mode == RenderMode::Raster).count();
        assert_eq!((rt, raster), (5, 2));
        assert_eq!(s.lights.len(), 2);
        assert!(s.lights.iter().all(|l| matches!(l, Light::Point { .. })));
        let specular = s.objects.iter().filter(|o| s.materials[o.material].kind == MaterialKind::Specular).count();
        assert_eq!(specular, 1);
        let glass = s.objects.iter().filter(|o| matches!(s.materials[o.material].kind, MaterialKind::Glass { .. }));
        assert_eq!(glass.count(), 1);
    }

    #[test]
    fn procedural_meshes_are_valid_and_closed_where_expected() {
        for m in [Mesh::grid("g", 3), Mesh::uv_sphere("s", 8, 5), Mesh::torus("t", 1.0, 0.3, 8, 6), Mesh::cube("c")] {
            let n = m.positions.len() as u32;
            assert!(m.indices.iter().flatten().all(|&i| i < n), "{}", m.name);
            for t in &m.indices {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                assert!((b - a).cross(c - a).length() > 0.0, "{}: degenerate triangle", m.name);
            }
        }
        // The torus is closed: every edge is used by exactly two triangles.
        let t = Mesh::torus("t", 1.0, 0.3, 8, 6);
        let mut edges = std::collections::HashMap::new();
        for tri in &t.indices {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        assert!(edges.values().all(|&c| c == 2));
    }
}
