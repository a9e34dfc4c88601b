//! Environment maps from files: Radiance HDR and OpenEXR maps written here load back as
//! written (within the format's precision), through `Environment::load` and a manifest's
//! `environment` key; files that cannot make a map are `SceneError`s naming the file.

use std::path::{Path, PathBuf};

use hyrt_core::scene::{Environment, EnvironmentMapError, Scene};
use hyrt_core::SceneError;

/// A fresh, empty folder for one test under Cargo's per-target temporary folder.
fn temp_dir(test: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("environment").join(test);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A 7 x 3 image of HDR values over several powers of two, every texel different.
fn texels() -> (u32, u32, Vec<[f32; 3]>) {
    let (w, h) = (7u32, 3u32);
    let t = (0..w * h)
        .map(|k| {
            let k = k as f32;
            [0.013 * k + 0.001, (k * 0.37).sin().abs() * 9.0, 250.0 / (k + 1.0)]
        })
        .collect();
    (w, h, t)
}

fn write_hdr(path: &Path, w: u32, h: u32, t: &[[f32; 3]]) {
    let flat: Vec<f32> = t.iter().flatten().copied().collect();
    image::Rgb32FImage::from_raw(w, h, flat).unwrap().save_with_format(path, image::ImageFormat::Hdr).unwrap();
}

fn write_exr(path: &Path, w: u32, h: u32, t: &[[f32; 3]]) {
    let flat: Vec<f32> = t.iter().flatten().copied().collect();
    image::Rgb32FImage::from_raw(w, h, flat).unwrap().save_with_format(path, image::ImageFormat::OpenExr).unwrap();
}

/// Radiance HDR keeps per texel an 8-bit exponent `e` shared by the channels, with
/// `2^(e-1) <= max channel < 2^e`, and an 8-bit mantissa per channel, truncated: each
/// channel loses less than `2^e / 256`, that is less than `max channel / 128`.
const RGBE_RELATIVE_TO_MAX: f32 = 1.0 / 128.0;

#[test]
fn a_radiance_hdr_map_loads_back_within_rgbe_precision() {
    let dir = temp_dir("hdr");
    let (w, h, t) = texels();
    let path = dir.join("sky.HDR");
    write_hdr(&path, w, h, &t);
    let env = Environment::load(&path).unwrap();
    let map = env.map().expect("a map");
    assert_eq!((map.width(), map.height(), map.source()), (w, h, Some(path.as_path())));
    for (k, (got, want)) in map.texels().iter().zip(&t).enumerate() {
        let max = want.iter().copied().fold(0.0, f32::max);
        for c in 0..3 {
            let err = want[c] - got[c];
            // Truncation: never above the written value, and less than max / 128 below.
            assert!(
                (0.0..max * RGBE_RELATIVE_TO_MAX).contains(&err),
                "texel {k} channel {c}: {} vs {}",
                got[c],
                want[c]
            );
        }
        assert_eq!(got[3], 1.0, "alpha");
    }
}

#[test]
fn an_openexr_map_loads_back_bit_for_bit() {
    let dir = temp_dir("exr");
    let (w, h, t) = texels();
    let path = dir.join("sky.exr");
    write_exr(&path, w, h, &t);
    let env = Environment::load(&path).unwrap();
    let map = env.map().expect("a map");
    assert_eq!((map.width(), map.height()), (w, h));
    let want: Vec<[f32; 4]> = t.iter().map(|c| [c[0], c[1], c[2], 1.0]).collect();
    assert_eq!(map.texels(), &want[..], "32-bit float channels are stored exactly");
    // Row 0 of the file is row 0 of the map (the top).
    assert_eq!(map.texel(3, 0), want[3]);
    assert_eq!(map.texel(0, 2), want[14]);
}

#[test]
fn a_manifest_names_its_environment_relative_to_itself() {
    let dir = temp_dir("manifest");
    std::fs::create_dir_all(dir.join("maps")).unwrap();
    let (w, h, t) = texels();
    write_exr(&dir.join("maps/sky.exr"), w, h, &t);
    let manifest = dir.join("scene.toml");
    std::fs::write(&manifest, "environment = \"maps/sky.exr\"\n[[model]]\nbuiltin = \"cube\"\n").unwrap();
    let scene = Scene::load(&manifest).unwrap();
    let map = scene.environment.map().expect("the manifest's map");
    assert_eq!(map.texel(1, 1)[..3], t[8][..]);
    // Without the key: the default sky.
    std::fs::write(&manifest, "[[model]]\nbuiltin = \"cube\"\n").unwrap();
    assert_eq!(Scene::load(&manifest).unwrap().environment, Environment::Sky);
    // A missing map is the manifest's error, naming the manifest, the key and the map.
    std::fs::write(&manifest, "environment = \"maps/none.hdr\"\n[[model]]\nbuiltin = \"cube\"\n").unwrap();
    let e = Scene::load(&manifest).unwrap_err();
    let SceneError::ManifestEntry { entry, error, .. } = &e else { panic!("{e:?}") };
    assert_eq!(entry, "environment");
    assert!(matches!(**error, SceneError::Io { .. }), "{error:?}");
    let text = e.to_string();
    assert!(text.contains("scene.toml") && text.contains("none.hdr"), "{text}");
}

/// The file named in the error's text, and the problem.
fn assert_names(e: &SceneError, path: &Path, problem: &str) {
    let text = e.to_string();
    assert!(text.contains(&path.display().to_string()), "{text}");
    assert!(text.contains(problem), "'{text}' does not say '{problem}'");
}

#[test]
fn files_that_cannot_make_a_map_are_errors_naming_the_file() {
    let dir = temp_dir("bad");

    let missing = dir.join("missing.hdr");
    let e = Environment::load(&missing).unwrap_err();
    assert!(matches!(e, SceneError::Io { .. }), "{e:?}");
    assert_names(&e, &missing, "cannot read file");

    for name in ["text.hdr", "text.exr"] {
        let not_image = dir.join(name);
        std::fs::write(&not_image, "this is not an image\n").unwrap();
        let e = Environment::load(&not_image).unwrap_err();
        assert!(
            matches!(e, SceneError::Environment { problem: EnvironmentMapError::Decode { .. }, .. }),
            "{name}: {e:?}"
        );
        assert_names(&e, &not_image, "not a readable");
    }

    // A valid image in a format that is not one of the two.
    let png = dir.join("sky.png");
    image::RgbImage::new(2, 2).save(&png).unwrap();
    let e = Environment::load(&png).unwrap_err();
    assert!(matches!(e, SceneError::Environment { problem: EnvironmentMapError::UnknownFormat, .. }), "{e:?}");
    assert_names(&e, &png, ".hdr");

    // A truncated file: the header promises texels that are not there.
    let (w, h, t) = texels();
    let cut = dir.join("cut.exr");
    write_exr(&cut, w, h, &t);
    let bytes = std::fs::read(&cut).unwrap();
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = Environment::load(&cut).unwrap_err();
    assert!(matches!(e, SceneError::Environment { problem: EnvironmentMapError::Decode { .. }, .. }), "{e:?}");

    // Texels that are not radiance: negative, infinite, NaN (OpenEXR stores them all).
    for (k, bad) in [-0.5f32, f32::INFINITY, f32::NAN].into_iter().enumerate() {
        let mut t = t.clone();
        t[9][1] = bad;
        let path = dir.join(format!("bad{k}.exr"));
        write_exr(&path, w, h, &t);
        let e = Environment::load(&path).unwrap_err();
        let SceneError::Environment { problem: EnvironmentMapError::BadTexel { x, y, .. }, .. } = &e else {
            panic!("{bad}: {e:?}")
        };
        assert_eq!((*x, *y), (2, 1), "texel 9 of a 7-wide map");
        assert_names(&e, &path, "must be finite and >= 0");
    }
}
