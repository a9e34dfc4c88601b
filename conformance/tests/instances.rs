//! Instances read by reference on the GPU (issue 40): a grid of copies of one mesh whose
//! world records the GPU makes on read from the mesh, uploaded once, and the copies'
//! placements, as the CPU backend does. Every stage buffer (the G-buffer's triangle and
//! object ids included) is the CPU reference's bit for bit, before and after an instance
//! moves; the device holds the mesh once, and a move writes its placement, not the mesh.

use hyrt_conformance::compare::compare_stages;
use hyrt_conformance::report::{gpu_for_tests, gpu_for_tests_with};
use hyrt_core::bvh::BvhPreset;
use hyrt_core::formats::CameraRecord;
use hyrt_core::frame::{Backend, FrameOptions, PreparedScene};
use hyrt_core::glam::{Mat4, Quat, Vec3};
use hyrt_core::scene::{Camera, Light, Material, MaterialKind, Mesh, Object, RenderMode, Scene, TextureImage};
use hyrt_cpu::backend::CpuBackend;
use hyrt_gpu::backend::world_table_bytes;
use hyrt_gpu::paging::{Table, TablePages};
use hyrt_gpu::visibility_raster::batch_triangles;
use std::sync::Arc;

/// Copies of the torus in the grid: 6 x 5.
const COLUMNS: usize = 6;
const ROWS: usize = 5;

/// A floor baked in world space (8 x 8 quads) lit by two point lights, and `first`, the
/// mesh its copies share, as object 1 with `material`: where the scenes of copies start.
fn lit_floor_and(first: Mesh, material: Material) -> Scene {
    let mut s = Scene {
        lights: vec![
            Light::point(Vec3::new(-3.0, 6.0, 4.0), Vec3::ONE, 60.0),
            Light::point(Vec3::new(4.0, 5.0, -1.0), Vec3::new(1.0, 0.9, 0.8), 40.0),
        ],
        ..Scene::default()
    };
    let grey = Material { name: "floor".into(), base_color: Vec3::splat(0.7), ..Material::grey() };
    s.add_object(Mesh::grid("floor", 8), grey, Mat4::from_scale(Vec3::splat(8.0)), RenderMode::RayTraced);
    s.add_object(first, material, Mat4::IDENTITY, RenderMode::RayTraced);
    s
}

/// The copies' mirror.
fn mirror() -> Material {
    Material {
        name: "mirror".into(),
        base_color: Vec3::splat(0.95),
        metallic: 1.0,
        roughness: 0.0,
        kind: MaterialKind::Specular,
        ..Material::grey()
    }
}

/// Where copy `k` stands: at `at`, turned about y by `0.37 k` after `x_turn` about x,
/// scaled by `scale`, mirrored in x when `k % 7 == 3`.
fn copy_transform(k: usize, at: Vec3, mut scale: Vec3, x_turn: f32) -> Mat4 {
    if k % 7 == 3 {
        scale.x = -scale.x;
    }
    let turn = Quat::from_rotation_y(0.37 * k as f32) * Quat::from_rotation_x(x_turn);
    Mat4::from_scale_rotation_translation(scale, turn, at)
}

/// Another object drawing object 1's mesh (shared: kept by reference) with material
/// `material`.
fn push_copy(s: &mut Scene, name: String, transform: Mat4, material: usize, render_mode: RenderMode) {
    let (id, mesh) = (s.objects.len() as u32, s.objects[1].mesh);
    s.objects.push(Object { id, name, mesh, transform, material, render_mode, source: Default::default() });
}

/// A camera at `eye` looking at `target`.
fn camera(eye: Vec3, target: Vec3, fov_y_deg: f32) -> Camera {
    Camera { eye, target, up: Vec3::Y, fov_y_deg, near: 0.05, far: 60.0 }
}

/// A floor baked in world space and a 6 x 5 grid of one torus mesh (2,304 triangles; every
/// copy turned, scaled unevenly, every seventh mirrored; mirrors, rasterized and ray-traced
/// diffuse copies), lit by two point lights: 69,120 triangles by reference.
fn grid_scene() -> Scene {
    let torus = Material { name: "torus 0".into(), base_color: Vec3::new(0.8, 0.3, 0.2), ..Material::grey() };
    let mut s = lit_floor_and(Mesh::torus("torus", 0.35, 0.14, 48, 24), torus);
    for k in 0..COLUMNS * ROWS {
        let (c, r) = ((k % COLUMNS) as f32, (k / COLUMNS) as f32);
        let at = Vec3::new(-2.5 + c, 0.35 + 0.05 * r, -3.0 + r);
        let scale = Vec3::new(1.0 + 0.05 * c, 1.0 - 0.04 * r, 0.9 + 0.03 * (c + r));
        let transform = copy_transform(k, at, scale, 0.9 + 0.11 * r);
        let (material, mode) = match k % 4 {
            0 => (mirror(), RenderMode::RayTraced),
            1 => (Material { base_color: Vec3::new(0.2, 0.5, 0.9), ..Material::grey() }, RenderMode::Raster),
            _ => (
                Material { base_color: Vec3::new(0.3 + 0.02 * c, 0.7, 0.3), ..Material::grey() },
                RenderMode::RayTraced,
            ),
        };
        if k == 0 {
            s.objects[1].transform = transform;
            s.materials[1] = material;
            s.objects[1].render_mode = mode;
            continue;
        }
        s.materials.push(material);
        let material = s.materials.len() - 1;
        push_copy(&mut s, format!("torus {k}"), transform, material, mode);
    }
    s.camera = Some(camera(Vec3::new(0.0, 3.6, 4.2), Vec3::new(0.0, 0.2, -1.2), 50.0));
    s
}

/// Render `prepared` on both backends with every stage output and require every buffer to
/// be the CPU's bit for bit, in a frame that sees many copies and bounces off mirrors.
fn same_frames(
    cpu: &mut CpuBackend,
    gpu: &mut dyn Backend,
    prepared: &PreparedScene,
    camera: &CameraRecord,
    what: &str,
) {
    let options = FrameOptions { stage_outputs: true, max_depth: 2, ..FrameOptions::default() };
    let reference = cpu.render(prepared, camera, &options).expect("cpu frame");
    let frame = gpu.render(prepared, camera, &options).expect("gpu frame");
    let compared = compare_stages(&reference, &frame);
    assert!(compared.iter().any(|c| c.buffer == "gbuffer"), "{what}: the G-buffer was compared");
    for cmp in compared {
        assert!(cmp.is_exact(), "{what}: cpu vs gpu: {} / {} differs: {cmp:?}", cmp.stage, cmp.buffer);
    }
    // The frame saw many copies: distinct objects in the G-buffer, and bounces off mirrors.
    let mut objects: Vec<u32> = reference.gbuffer.iter().filter(|t| t.is_hit()).map(|t| t.object).collect();
    objects.sort_unstable();
    objects.dedup();
    assert!(objects.len() > 20, "{what}: {} objects seen", objects.len());
    assert!(!reference.bounces.is_empty(), "{what}: no bounce traced");
}

#[test]
fn gpu_reads_instances_by_reference_as_the_cpu_and_moves_them() {
    let Some(mut gpu) = gpu_for_tests() else { return };
    let mut scene = grid_scene();
    let mut cpu = CpuBackend::new(Some(2));
    // One copy moves; every copy shares the mesh, so all are kept by reference.
    let moving = [7u32];
    let mut prepared = hyrt_cpu::bvh_build::prepare_moving(&scene, BvhPreset::default(), &moving);
    let triangles = &prepared.geometry.triangles;
    assert!(triangles.has_references());
    assert_eq!(triangles.len(), 2 * 8 * 8 + COLUMNS * ROWS * 48 * 24 * 2);
    // What the device holds: the floor's records, the torus once, a placement per object;
    // a flat table would hold every copy's records.
    let uploaded: u64 = world_table_bytes(&prepared).iter().map(|(_, b)| b).sum();
    let flat = (triangles.len() * std::mem::size_of::<hyrt_core::formats::TriangleRecord>()) as u64;
    eprintln!("world tables on the device: {uploaded} bytes (a flat table: {flat})");
    assert!(uploaded * 10 < flat, "{uploaded} bytes uploaded for a {flat}-byte flat table");
    assert_eq!(triangles.stored_records().len(), 2 * 8 * 8, "only the floor is stored");

    let camera = CameraRecord::new(&scene.camera.unwrap(), 96, 64);
    same_frames(&mut cpu, &mut gpu, &prepared, &camera, "as prepared");
    // Move the copy: its placement and the top level change on the device, not the mesh.
    let o = moving[0] as usize;
    scene.objects[o].transform = Mat4::from_rotation_translation(Quat::from_rotation_z(0.6), Vec3::new(0.3, 0.4, 0.2))
        * scene.objects[o].transform;
    prepared.move_objects(&scene, &moving).unwrap();
    same_frames(&mut cpu, &mut gpu, &prepared, &camera, "after a move");
    assert_eq!(gpu.scene_writes(), (1, 1), "the scene went to the device once, then the move");
}

/// Scenes past one storage binding: on devices whose storage bindings hold 1 MiB and
/// 4 MiB (the device enforces it), the grid's 69,248 world triangles are set up and drawn
/// in six and two batches ([`batch_triangles`]), and stored, their tables (3.3 MB of
/// records, as much again in BVH leaf order) are read in pages of one binding each
/// ([`TablePages`]: five and two pages of records); by reference and stored, every buffer
/// is still the CPU's bit for bit: the batches keep the scene's order, so the depth test's
/// ties (the earlier triangle wins) fall as in one draw, and a page holds the records the
/// whole table holds at the same index.
#[test]
fn gpu_renders_past_one_binding_in_batches_and_pages_as_the_cpu() {
    let scene = grid_scene();
    let mut cpu = CpuBackend::new(Some(2));
    let camera = CameraRecord::new(&scene.camera.unwrap(), 96, 64);
    for (binding, batches, pages) in [(1u64 << 20, 6, 5), (4 << 20, 2, 2)] {
        let Some(mut gpu) = gpu_for_tests_with(Some(binding)) else { return };
        let limits = gpu.context().limits.clone();
        assert_eq!(limits.max_storage_buffer_binding_size, binding);
        let batch = batch_triangles(&limits) as usize;
        assert_eq!(batch, binding as usize / 80);
        for (what, prepared) in [
            ("by reference", hyrt_cpu::bvh_build::prepare_moving(&scene, BvhPreset::default(), &[7])),
            ("stored", hyrt_cpu::bvh_build::prepare_scene(&scene, BvhPreset::default())),
        ] {
            let triangles = &prepared.geometry.triangles;
            assert_eq!(triangles.has_references(), what == "by reference");
            assert_eq!(triangles.len().div_ceil(batch), batches, "{what}: {batches} batches");
            let paged = TablePages::of_scene(&prepared, &limits).unwrap();
            if what == "stored" {
                assert_eq!(paged.pages(Table::Triangles), pages, "{what}: pages of records");
                assert_eq!(paged.pages(Table::LeafTriangles), pages, "{what}: pages of leaf slots");
            }
            same_frames(&mut cpu, &mut gpu, &prepared, &camera, &format!("{what}, {binding}-byte bindings"));
        }
    }
}

/// Copies of the cube in [`forest_scene`]: 100 x 50, past two pages of 2,048 placements.
const FOREST: (usize, usize) = (100, 50);

/// A floor baked in world space and a forest of [`FOREST`] small copies of one cube (12
/// triangles each; turned, scaled unevenly, every seventh mirrored; mirrors, rasterized and
/// ray-traced copies), row by row from the back: object `o` stands further forward the
/// higher `o`, so that the camera sees copies of every page of the per-object tables.
fn forest_scene() -> Scene {
    let mut s = lit_floor_and(Mesh::cube("cube"), mirror());
    let green = Material { name: "green".into(), base_color: Vec3::new(0.3, 0.7, 0.3), ..Material::grey() };
    let blue = Material { name: "blue".into(), base_color: Vec3::new(0.2, 0.5, 0.9), ..Material::grey() };
    let (mirror, materials) = (s.objects[1].material, s.materials.len());
    s.materials.extend([green, blue]);
    let (columns, rows) = FOREST;
    for k in 0..columns * rows {
        let (c, r) = ((k % columns) as f32, (k / columns) as f32);
        let at = Vec3::new(-4.0 + 0.08 * c, 0.04, -6.0 + 0.13 * r);
        let scale = Vec3::new(0.025 + 0.0002 * c, 0.03 - 0.0002 * r, 0.02 + 0.0001 * (c + r));
        let transform = copy_transform(k, at, scale, 0.2 + 0.01 * r);
        match k % 4 {
            _ if k == 0 => s.objects[1].transform = transform,
            0 => push_copy(&mut s, format!("cube {k}"), transform, mirror, RenderMode::RayTraced),
            1 => push_copy(&mut s, format!("cube {k}"), transform, materials + 1, RenderMode::Raster),
            _ => push_copy(&mut s, format!("cube {k}"), transform, materials, RenderMode::RayTraced),
        }
    }
    s.camera = Some(camera(Vec3::new(0.0, 2.2, 2.4), Vec3::new(0.0, 0.0, -2.6), 60.0));
    s
}

/// Objects past one storage binding: a forest of 5,000 copies of one cube by reference
/// on a device whose storage bindings hold 384 KiB (the raster's 4,096 clipped-setup slots
/// need as much): their placements (112 bytes each),
/// object records and instances in three pages of 2,048 ([`Table::Placements`],
/// [`Table::Objects`], [`Table::Instances`]; the top level's nodes in pages too); every
/// buffer is the CPU's bit for bit, the bounces' too, before and after a copy of the last
/// page moves. The G-buffer sees objects of every page.
#[test]
fn gpu_reads_objects_in_pages_as_the_cpu() {
    const BINDING: u64 = 384 << 10;
    let Some(mut gpu) = gpu_for_tests_with(Some(BINDING)) else { return };
    let mut scene = forest_scene();
    let mut cpu = CpuBackend::new(Some(2));
    let moving = [(scene.objects.len() - 40) as u32];
    let mut prepared = hyrt_cpu::bvh_build::prepare_moving(&scene, BvhPreset::default(), &moving);
    assert!(prepared.geometry.triangles.has_references());
    let limits = gpu.context().limits.clone();
    let pages = TablePages::of_scene(&prepared, &limits).unwrap();
    let per_page = pages.page_records(Table::Placements).expect("placements in pages");
    assert_eq!(per_page, 2048, "{pages:?}");
    for table in [Table::Placements, Table::Objects, Table::Instances] {
        assert_eq!(pages.pages(table), 3, "{table:?}: {pages:?}");
    }
    assert!(u64::from(moving[0]) >= 2 * per_page, "the moving copy is in the last page");
    let camera = CameraRecord::new(&scene.camera.unwrap(), 96, 64);
    let options = FrameOptions { stage_outputs: true, max_depth: 2, ..FrameOptions::default() };
    for what in ["as prepared", "after a move"] {
        if what == "after a move" {
            let o = moving[0] as usize;
            scene.objects[o].transform = Mat4::from_translation(Vec3::new(0.1, 0.05, 0.1)) * scene.objects[o].transform;
            prepared.move_objects(&scene, &moving).unwrap();
        }
        let started = std::time::Instant::now();
        let reference = cpu.render(&prepared, &camera, &options).expect("cpu frame");
        let frame = gpu.render(&prepared, &camera, &options).expect("gpu frame");
        let compared = compare_stages(&reference, &frame);
        assert!(compared.iter().any(|c| c.buffer == "gbuffer"), "{what}: the G-buffer was compared");
        for cmp in compared {
            assert!(cmp.is_exact(), "{what}: cpu vs gpu: {} / {} differs: {cmp:?}", cmp.stage, cmp.buffer);
        }
        assert!(!reference.bounces.is_empty(), "{what}: no bounce traced");
        let seen: std::collections::BTreeSet<u64> =
            reference.gbuffer.iter().filter(|t| t.is_hit()).map(|t| u64::from(t.object) / per_page).collect();
        assert_eq!(seen.len(), 3, "{what}: pages of the objects seen {seen:?}");
        eprintln!("{what}: {pages:?}, {:.1} s", started.elapsed().as_secs_f64());
    }
    assert_eq!(gpu.scene_writes(), (1, 1), "the scene went to the device once, then the move");
}

/// `image` scaled up `k` times on each side, each texel a `k` x `k` block.
fn enlarged(image: &TextureImage, k: u32) -> TextureImage {
    let (w, h) = (image.width * k, image.height * k);
    let texels = (0..h).flat_map(|y| (0..w).map(move |x| image.texels[((y / k) * image.width + x / k) as usize]));
    TextureImage::new(format!("{} x{k}", image.name), w, h, texels.collect()).expect("a valid image")
}

/// A shared mesh past one storage binding: seven copies of a torus of 90,000 triangles
/// (its positions, normals and triangles 2.2 MB of words) read by reference on a device whose
/// bindings hold 1 MiB: the mesh words in three pages ([`TablePages`]), the raster in
/// batches; every buffer is the CPU's bit for bit, before and after a copy moves.
#[test]
fn gpu_reads_a_shared_mesh_in_pages_as_the_cpu() {
    const BINDING: u64 = 1 << 20;
    let Some(mut gpu) = gpu_for_tests_with(Some(BINDING)) else { return };
    let mut scene = grid_scene();
    let mesh = scene.objects[1].mesh;
    scene.meshes[mesh] = Mesh::torus("torus", 0.35, 0.14, 300, 150);
    scene.objects.truncate(8);
    let mut cpu = CpuBackend::new(Some(2));
    let mut prepared = hyrt_cpu::bvh_build::prepare_moving(&scene, BvhPreset::default(), &[3]);
    assert!(prepared.geometry.triangles.has_references());
    let pages = TablePages::of_scene(&prepared, &gpu.context().limits).unwrap();
    assert_eq!(pages.pages(Table::MeshWords), 3, "{pages:?}");
    let camera = CameraRecord::new(&scene.camera.unwrap(), 96, 64);
    let options = FrameOptions { stage_outputs: true, max_depth: 2, ..FrameOptions::default() };
    for what in ["as prepared", "after a move"] {
        if what == "after a move" {
            scene.objects[3].transform = Mat4::from_translation(Vec3::new(0.2, 0.1, 0.3)) * scene.objects[3].transform;
            prepared.move_objects(&scene, &[3]).unwrap();
        }
        let reference = cpu.render(&prepared, &camera, &options).expect("cpu frame");
        let frame = gpu.render(&prepared, &camera, &options).expect("gpu frame");
        for cmp in compare_stages(&reference, &frame) {
            assert!(cmp.is_exact(), "{what}: cpu vs gpu: {} / {} differs: {cmp:?}", cmp.stage, cmp.buffer);
        }
        let objects: std::collections::BTreeSet<u32> =
            reference.gbuffer.iter().filter(|t| t.is_hit()).map(|t| t.object).collect();
        assert!(objects.len() >= 6, "{what}: objects seen {objects:?}");
    }
}

/// Surface tables past one storage binding: every `texture_` case of the corpus (textures
/// sampled on rasterized and ray-traced objects, vertex colours, alpha tests in the raster,
/// in shadow rays and in a mirror, normal maps, metallic-roughness and emission maps, every
/// wrap mode), its images enlarged to 4 MiB of texels or more, on a device whose storage
/// bindings hold a power of two between a quarter and half of its surface tables, so that
/// their words take three or four pages ([`Table::Surface`]); every buffer is the CPU's bit
/// for bit, the bounces' too: a page holds the words the whole table holds at the same
/// index.
#[test]
fn gpu_reads_surface_tables_in_pages_as_the_cpu() {
    let mut cpu = CpuBackend::new(Some(2));
    let (mut cases, mut bounced) = (0, 0);
    let mut device: Option<(u64, hyrt_gpu::backend::GpuBackend)> = None;
    for mut case in hyrt_conformance::corpus::corpus().into_iter().filter(|c| c.name.starts_with("texture_")) {
        let started = std::time::Instant::now();
        let texels: usize = case.scene.textures.iter().map(|t| t.texels.len()).sum();
        let k = ((1usize << 20) as f64 / texels as f64).sqrt().ceil() as u32;
        case.scene.textures = case.scene.textures.iter().map(|t| Arc::new(enlarged(t, k))).collect();
        let prepared = case.prepare(&cpu);
        let bytes = prepared.geometry.surface.layout().expect("a small table").bytes();
        let binding = (bytes / 4).next_power_of_two();
        // One device per binding size (the cases share one: a new device compiles every
        // pipeline again, about 6 s each on CI's lavapipe).
        if device.as_ref().is_none_or(|(b, _)| *b != binding) {
            let Some(gpu) = gpu_for_tests_with(Some(binding)) else { return };
            device = Some((binding, gpu));
        }
        let gpu = &mut device.as_mut().expect("made above").1;
        let limits = gpu.context().limits.clone();
        assert_eq!(limits.max_storage_buffer_binding_size, binding);
        let pages = TablePages::of_scene(&prepared, &limits).expect("within MAX_PAGES");
        let surface = pages.pages(Table::Surface);
        assert!((3..=4).contains(&surface), "{}: {bytes} bytes of surface tables in {surface} pages", case.name);
        let frame = hyrt_conformance::report::render_case(gpu, &prepared, &case).expect("gpu frame");
        let reference = hyrt_conformance::report::render_case(&mut cpu, &prepared, &case).expect("cpu frame");
        let compared = compare_stages(&reference, &frame);
        assert!(compared.iter().any(|c| c.buffer == "gbuffer"), "{}: the G-buffer was compared", case.name);
        bounced += usize::from(!reference.bounces.is_empty());
        for cmp in compared {
            assert!(cmp.is_exact(), "{}: cpu vs gpu: {} / {} differs: {cmp:?}", case.name, cmp.stage, cmp.buffer);
        }
        eprintln!(
            "{}: textures x{k}, {bytes} bytes of surface tables in {surface} pages of {binding} bytes, {:.1} s",
            case.name,
            started.elapsed().as_secs_f64()
        );
        cases += 1;
    }
    assert!(cases >= 9, "{cases} texture cases");
    assert!(bounced >= 2, "{bounced} cases bounced");
}

/// Dragons on the GPU as the CPU renders them: a manifest grid of `columns` x `rows`
/// copies of the Stanford dragon (871,414 triangles), prepared as the facade prepares it
/// (`prepare_scene`: instances of one mesh past `AUTO_INSTANCING_BYTES`, else every copy
/// stored), rendered by both backends at 160 x 90 (the first seen as
/// `assets/scenes/dragon.toml` sees it) and compared buffer by buffer twice; prints the
/// device's world tables, its pages and both backends' times. `None` without the shared
/// assets or an adapter.
fn dragons_as_the_cpu(columns: u32, rows: u32) -> Option<PreparedScene> {
    let Some(assets) = hyrt_conformance::corpus::shared_assets() else {
        eprintln!("SKIPPED: ../shared/assets not found (dragon.glb)");
        return None;
    };
    let mut gpu = gpu_for_tests()?;
    let manifest = format!(
        "[camera]\neye = [0.089, 0.236, 0.313]\ntarget = [-0.0059, 0.125, -0.0046]\nfov_deg = 45.0\nnear = 0.01\nfar = 30.0\n\n\
         [[light]]\ntype = \"point\"\nposition = [1.0, 2.0, 2.0]\nintensity = 6.0\n\n\
         [[model]]\nfile = {:?}\nname = \"dragon\"\nrender_mode = \"ray_traced\"\n\
         repeat = {{ count = [{columns}, 1, {rows}], step = [0.25, 0.0, -0.3] }}\n",
        assets.join("dragon.glb").display().to_string()
    );
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("instances");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("dragons_{columns}x{rows}.toml"));
    std::fs::write(&path, manifest).unwrap();
    let scene = Scene::load(&path).unwrap();
    let mut cpu = CpuBackend::new(Some(2));
    let prepared = hyrt_cpu::bvh_build::prepare_scene(&scene, BvhPreset::default());
    let tables: Vec<String> = world_table_bytes(&prepared).iter().map(|(t, b)| format!("{t}: {b} bytes")).collect();
    let pages = TablePages::of_scene(&prepared, &gpu.context().limits).unwrap();
    let n = prepared.geometry.triangles.len();
    let camera = CameraRecord::new(&scene.camera.unwrap(), 160, 90);
    let options = FrameOptions { stage_outputs: true, ..FrameOptions::default() };
    let t = std::time::Instant::now();
    let reference = cpu.render(&prepared, &camera, &options).expect("cpu frame");
    let cpu_s = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let frame = gpu.render(&prepared, &camera, &options).expect("gpu frame");
    let first_s = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let again = gpu.render(&prepared, &camera, &options).expect("gpu frame");
    let gpu_s = t.elapsed().as_secs_f64();
    eprintln!(
        "{columns} x {rows} dragons, {n} triangles ({}): world tables on the device {tables:?}, pages {pages:?}; \
         cpu {cpu_s:.2} s, gpu {first_s:.2} s (first frame, pipelines and upload), {gpu_s:.2} s (again) on {}",
        if prepared.geometry.triangles.has_references() { "by reference" } else { "stored" },
        gpu.describe()
    );
    for f in [&frame, &again] {
        for cmp in compare_stages(&reference, f) {
            assert!(cmp.is_exact(), "cpu vs gpu: {} / {} differs: {cmp:?}", cmp.stage, cmp.buffer);
        }
    }
    let hits = reference.gbuffer.iter().filter(|t| t.is_hit()).count();
    assert!(hits > 1000, "{hits} pixels see a dragon");
    Some(prepared)
}

/// 30 dragons (26 million triangles) read by reference: the device holds the mesh once
/// (21 MB of world tables against 1.25 GB flat) and rasterizes them in batches. Ignored:
/// about a minute on lavapipe. Run with `--ignored` where `../shared/assets` is.
#[test]
#[ignore]
fn gpu_renders_dragons_by_reference_as_the_cpu() {
    if let Some(prepared) = dragons_as_the_cpu(6, 5) {
        assert!(prepared.geometry.triangles.has_references());
    }
}

/// Four dragons stored (3.5 million world records: 167 MB, past lavapipe's 128 MiB
/// binding): the records, normals and BVH tables in pages. Ignored: about a minute on
/// lavapipe.
#[test]
#[ignore]
fn gpu_renders_dragons_stored_in_pages_as_the_cpu() {
    if let Some(prepared) = dragons_as_the_cpu(2, 2) {
        assert!(!prepared.geometry.triangles.has_references());
        let records = prepared.geometry.triangles.stored_records().len() * 48;
        assert!(records > 128 << 20, "{records} bytes of records");
    }
}
