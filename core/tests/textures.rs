//! Textured glTF: texture coordinates, vertex colours, base-colour textures with their
//! samplers and transforms, alpha modes; images from a GLB buffer view, a data URI and a
//! file beside a `.gltf`; bad images are errors naming the file. And the real asset,
//! `shared/assets/DamagedHelmet.glb`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use hyrt_core::glam::{Vec2, Vec3};
use hyrt_core::scene::{AlphaMode, Filter, Scene, Wrap};

// The fuzz harness's file builders (base64, PNG checksums); its allocator is not installed.
#[path = "../fuzz/harness.rs"]
mod harness;
use harness::{base64, crc32};

/// A PNG of `w x h` RGBA8 texels.
fn png(w: u32, h: u32, texels: &[[u8; 4]]) -> Vec<u8> {
    let mut out = Vec::new();
    let image = image::RgbaImage::from_raw(w, h, texels.concat()).unwrap();
    image.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png).unwrap();
    out
}

/// One quad (two triangles) with positions, TEXCOORD_0, TEXCOORD_1 and COLOR_0 (unorm8
/// VEC4), in a buffer given as a data URI, and `material` / `images` / `textures` /
/// `samplers` JSON spliced in.
fn quad_gltf(material: &str, images: &str, textures: &str, samplers: &str) -> String {
    let mut bin = Vec::new();
    for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]] {
        p.iter().for_each(|c| bin.extend(c.to_le_bytes()));
    }
    for uv in [[0.0f32, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]] {
        uv.iter().for_each(|c| bin.extend(c.to_le_bytes()));
    }
    for uv in [[0.5f32, 0.5]; 4] {
        uv.iter().for_each(|c| bin.extend(c.to_le_bytes()));
    }
    for c in [[255u8, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255], [255, 255, 255, 0]] {
        bin.extend(c);
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend(i.to_le_bytes());
    }
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1,"TEXCOORD_1":2,"COLOR_0":3}},"indices":4,"material":0}}]}}],
        "materials":[{material}],"images":[{images}],"textures":[{textures}],"samplers":[{samplers}],
        "accessors":[
          {{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
          {{"bufferView":1,"componentType":5126,"count":4,"type":"VEC2"}},
          {{"bufferView":2,"componentType":5126,"count":4,"type":"VEC2"}},
          {{"bufferView":3,"componentType":5121,"normalized":true,"count":4,"type":"VEC4"}},
          {{"bufferView":4,"componentType":5123,"count":6,"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":32}},
          {{"buffer":0,"byteOffset":80,"byteLength":32}},{{"buffer":0,"byteOffset":112,"byteLength":16}},
          {{"buffer":0,"byteOffset":128,"byteLength":12}}],
        "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}]}}"#,
        bin.len(),
        base64(&bin)
    )
}

fn load(files: &[(&str, Vec<u8>)]) -> Result<Scene, String> {
    let files: HashMap<PathBuf, Vec<u8>> = files.iter().map(|(n, b)| (Path::new("/mem").join(n), b.clone())).collect();
    Scene::load_from(Path::new("/mem/scene.gltf"), &files).map_err(|e| e.to_string())
}

#[test]
fn vertex_attributes_textures_samplers_and_transforms_load() {
    let checker = png(2, 2, &[[255, 0, 0, 255], [0, 255, 0, 128], [0, 0, 255, 0], [255, 255, 255, 255]]);
    let material = r#"{"name":"leaves","alphaMode":"MASK","alphaCutoff":0.25,
        "pbrMetallicRoughness":{"baseColorFactor":[1,0.5,0.25,0.75],"metallicFactor":0,
          "baseColorTexture":{"index":0,"texCoord":0,
            "extensions":{"KHR_texture_transform":{"offset":[0.5,0],"rotation":0.5,"scale":[2,3],"texCoord":1}}}}}"#;
    let gltf = quad_gltf(
        material,
        r#"{"uri":"checker%20board.png"}"#,
        r#"{"source":0,"sampler":0}"#,
        r#"{"magFilter":9728,"minFilter":9985,"wrapS":33071,"wrapT":33648}"#,
    );
    let scene = load(&[("scene.gltf", gltf.into_bytes()), ("checker board.png", checker)]).unwrap();
    let mesh = &scene.meshes[0];
    assert_eq!(mesh.attributes.tex_coords[0].as_deref(), Some(&[Vec2::Y, Vec2::ONE, Vec2::X, Vec2::ZERO][..]));
    assert_eq!(mesh.attributes.tex_coords[1].as_deref(), Some(&[Vec2::splat(0.5); 4][..]));
    let colors = mesh.attributes.colors.as_ref().unwrap();
    assert_eq!((colors[0], colors[3]), ([1.0, 0.0, 0.0, 1.0], [1.0, 1.0, 1.0, 0.0]), "unorm8 VEC4 divided by 255");
    let m = &scene.materials[0];
    assert_eq!((m.base_color, m.base_alpha), (Vec3::new(1.0, 0.5, 0.25), 0.75));
    assert_eq!(m.alpha_mode, AlphaMode::Mask { cutoff: 0.25 });
    let t = m.base_color_texture.unwrap();
    assert_eq!(t.tex_coord, 1, "KHR_texture_transform's texCoord overrides the texture's");
    assert_eq!(
        (t.transform.offset, t.transform.rotation, t.transform.scale),
        (Vec2::new(0.5, 0.0), 0.5, Vec2::new(2.0, 3.0))
    );
    assert_eq!((t.sampler.mag, t.sampler.min, t.sampler.mip), (Filter::Nearest, Filter::Linear, Some(Filter::Nearest)));
    assert_eq!((t.sampler.wrap_s, t.sampler.wrap_t), (Wrap::ClampToEdge, Wrap::MirroredRepeat));
    let image = &scene.textures[t.image];
    assert_eq!(
        (image.width, image.height, image.texel(1, 0), image.texel(0, 1)),
        (2, 2, [0, 255, 0, 128], [0, 0, 255, 0])
    );
    assert_eq!(
        image.source.as_deref(),
        Some(Path::new("/mem/checker board.png")),
        "percent-decoded URI beside the .gltf"
    );
}

#[test]
fn images_in_data_uris_are_decoded_once_and_blend_is_a_mask_with_a_note() {
    let texels = [[10, 20, 30, 40]];
    let uri = format!("data:image/png;base64,{}", base64(&png(1, 1, &texels)));
    let material = r#"{"alphaMode":"BLEND","pbrMetallicRoughness":{"baseColorTexture":{"index":0}},
        "normalTexture":{"index":1}}"#;
    let gltf = quad_gltf(material, &format!(r#"{{"uri":"{uri}"}}"#), r#"{"source":0},{"source":0}"#, "{}");
    let scene = load(&[("scene.gltf", gltf.into_bytes())]).unwrap();
    assert_eq!(scene.textures.len(), 1);
    assert_eq!(scene.textures[0].texels, texels);
    let m = &scene.materials[0];
    assert_eq!(m.alpha_mode, AlphaMode::Blend);
    assert_eq!(m.alpha_mode.cutoff(), Some(0.5));
    let sampler = m.base_color_texture.unwrap().sampler;
    assert_eq!(
        (sampler.mag, sampler.mip, sampler.wrap_s),
        (Filter::Linear, Some(Filter::Linear), Wrap::Repeat),
        "defaults"
    );
    let notes = scene.notes.join("\n");
    assert!(notes.contains("BLEND is rendered as MASK at alpha 0.5"), "{notes}");
    // Texture 1 is the same image: decoded once, bound as the normal map.
    assert_eq!(scene.textures.len(), 1, "one image, decoded once");
    assert_eq!(m.maps.normal.map(|t| (t.image, m.maps.normal_scale)), Some((0, 1.0)));
}

#[test]
fn bad_images_are_errors_naming_the_file_and_the_image() {
    let material = r#"{"pbrMetallicRoughness":{"baseColorTexture":{"index":0}}}"#;
    type Case = (&'static str, Vec<(&'static str, Vec<u8>)>, &'static str);
    let cases: Vec<Case> = vec![
        ("not an image", vec![("t.png", b"hello".to_vec())], "neither a PNG nor a JPEG"),
        ("missing file", vec![], "t.png"),
        ("truncated PNG", vec![("t.png", png(64, 64, &[[1, 2, 3, 4]; 4096])[..60].to_vec())], "Png"),
    ];
    for (what, extra, expected) in cases {
        let gltf = quad_gltf(material, r#"{"name":"wall","uri":"t.png"}"#, r#"{"source":0}"#, "{}");
        let mut files = vec![("scene.gltf", gltf.into_bytes())];
        files.extend(extra);
        let message = load(&files).unwrap_err();
        assert!(message.contains("/mem/"), "{what}: the error names no file: {message}");
        assert!(message.contains(expected), "{what}: {message}");
    }
    // A PNG header claiming 16384 x 16384 texels (1 GiB) in a few hundred bytes: refused
    // by the budget before anything is decoded.
    let mut huge = png(1, 1, &[[0; 4]]);
    huge[16..20].copy_from_slice(&16384u32.to_be_bytes());
    huge[20..24].copy_from_slice(&16384u32.to_be_bytes());
    let crc = crc32(&huge[12..29]);
    huge[29..33].copy_from_slice(&crc.to_be_bytes());
    let gltf = quad_gltf(material, r#"{"uri":"t.png"}"#, r#"{"source":0}"#, "{}");
    let message = load(&[("scene.gltf", gltf.into_bytes()), ("t.png", huge)]).unwrap_err();
    assert!(message.contains("budget") && message.contains("image 0"), "{message}");
    // TEXCOORD_2 is not read: a material asking for it is an error, not a wrong mapping.
    let material = r#"{"pbrMetallicRoughness":{"baseColorTexture":{"index":0,"texCoord":2}}}"#;
    let gltf = quad_gltf(material, r#"{"uri":"t.png"}"#, r#"{"source":0}"#, "{}");
    let message = load(&[("scene.gltf", gltf.into_bytes()), ("t.png", png(1, 1, &[[0; 4]]))]).unwrap_err();
    assert!(message.contains("TEXCOORD_2"), "{message}");
}

#[test]
fn the_damaged_helmet_loads_all_five_of_its_textures() {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets");
    if !assets.is_dir() {
        eprintln!("{} not found: skipping the Damaged Helmet test", assets.display());
        return;
    }
    let path = assets.join("DamagedHelmet.glb");
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.textures.len(), 5, "base colour, metallic-roughness, emissive, occlusion, normal");
    assert!(scene.textures.iter().all(|i| (i.width, i.height) == (2048, 2048)));
    let image = &scene.textures[0];
    let m = &scene.materials[scene.objects[0].material];
    assert_eq!(m.base_color_texture.map(|t| (t.image, t.tex_coord)), Some((0, 0)));
    let maps = [m.maps.metallic_roughness, m.maps.emissive, m.maps.occlusion, m.maps.normal];
    assert!(maps.iter().all(|t| t.is_some_and(|t| t.tex_coord == 0)), "{:?}", m.maps);
    assert_eq!(m.emissive, Vec3::ONE, "emissiveFactor [1, 1, 1]");
    let mesh = &scene.meshes[scene.objects[0].mesh];
    assert_eq!(mesh.attributes.tex_coords[0].as_ref().map(Vec::len), Some(mesh.positions.len()));
    // Not a flat colour: the texture varies.
    let distinct: std::collections::HashSet<[u8; 4]> = image.texels.iter().step_by(997).copied().collect();
    assert!(distinct.len() > 100, "{} distinct texels", distinct.len());
    assert!(scene.notes.iter().all(|n| !n.contains("Texture")), "no texture left unused: {:?}", scene.notes);
}

/// A manifest carries its models' textures: each model's materials sample its own file's
/// images (indices moved past the files before it), a file placed by two models is decoded
/// once, and a material override keeps the texture (its factor multiplies it).
#[test]
fn a_manifest_carries_every_models_textures() {
    let textured = |texel: [u8; 4]| {
        let uri = format!("data:image/png;base64,{}", base64(&png(1, 1, &[texel])));
        let material = r#"{"pbrMetallicRoughness":{"baseColorTexture":{"index":0},"metallicFactor":0}}"#;
        quad_gltf(material, &format!(r#"{{"uri":"{uri}"}}"#), r#"{"source":0,"sampler":0}"#, r#"{"magFilter":9728}"#)
    };
    let (red, blue) = ([255, 0, 0, 255], [0, 0, 255, 255]);
    let manifest = "[[model]]\nfile = \"red.gltf\"\n[[model]]\nfile = \"blue.gltf\"\ntranslate = [2.0, 0.0, 0.0]\n\
                    [[model]]\nfile = \"red.gltf\"\nname = \"gold\"\nmaterial = { base_color = [1.0, 0.8, 0.2] }\n";
    let files: HashMap<PathBuf, Vec<u8>> = [
        ("red.gltf", textured(red).into_bytes()),
        ("blue.gltf", textured(blue).into_bytes()),
        ("scene.toml", manifest.as_bytes().to_vec()),
    ]
    .into_iter()
    .map(|(n, b)| (Path::new("/mem").join(n), b))
    .collect();
    let scene = Scene::load_from(Path::new("/mem/scene.toml"), &files).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.textures.len(), 2, "red.gltf's image once, blue.gltf's once");
    let texel_of = |object: &str| {
        let o = scene.objects.iter().find(|o| o.name.starts_with(object)).unwrap();
        let m = &scene.materials[o.material];
        (scene.textures[m.base_color_texture.unwrap().image].texels[0], m.base_color)
    };
    assert_eq!(texel_of("red/"), (red, Vec3::ONE));
    assert_eq!(texel_of("blue/"), (blue, Vec3::ONE));
    assert_eq!(texel_of("gold/"), (red, Vec3::new(1.0, 0.8, 0.2)), "the override's factor, the file's texture");
    // The one-model manifest and the file alone: the same textures and materials.
    let alone = Scene::load_from(Path::new("/mem/red.gltf"), &files).unwrap();
    let one: HashMap<PathBuf, Vec<u8>> =
        [(PathBuf::from("/mem/one.toml"), b"[[model]]\nfile = \"red.gltf\"\n".to_vec())]
            .into_iter()
            .chain(files)
            .collect();
    let manifest = Scene::load_from(Path::new("/mem/one.toml"), &one).unwrap();
    assert_eq!(manifest.materials, alone.materials);
    assert_eq!(manifest.textures, alone.textures);
}
