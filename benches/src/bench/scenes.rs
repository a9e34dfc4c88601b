//! The scenes the benchmark runs on: the built-in default scene, and the paper's Table 2
//! scenes and the scaling scenes from the manifests in `assets/scenes/` when the shared
//! models (`../shared/assets`) are present.

use std::path::PathBuf;

use hyrt_core::scene::{Scene, ShadingModel};

/// The shading model of every scene the report renders: the paper's, whatever the scene's
/// own (the default scene and glTF scenes default to the glTF BRDF), so that Table 2 and the
/// speed-against-error sections compare with the paper and with earlier reports. The
/// report's header says so.
pub const REPORT_SHADING: ShadingModel = ShadingModel::Paper;

/// One row of the paper's Table 2 (Sabino et al. 2011, measured on an NVIDIA 9800 GTX+
/// with CUDA; the paper writes 66.252 for 66,252 and gives no image size).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaperRow {
    /// The scene as the paper names it.
    pub scene: &'static str,
    /// "Valid rays": pixels whose primary hit is a ray-traced object.
    pub valid_rays: u64,
    pub fps: f64,
}

/// The paper's Table 2, quoted.
pub const PAPER_TABLE2: [PaperRow; 5] = [
    PaperRow { scene: "Teaser Scene (Fig. 1(d))", valid_rays: 66_252, fps: 10.0 },
    PaperRow { scene: "Toad Scene 1 (Fig. 7)", valid_rays: 67_734, fps: 5.0 },
    PaperRow { scene: "Toad Scene 2", valid_rays: 5_876, fps: 10.0 },
    PaperRow { scene: "Bunny Scene 1 (Fig. 5)", valid_rays: 68_203, fps: 5.0 },
    PaperRow { scene: "Bunny Scene 2", valid_rays: 26_442, fps: 7.0 },
];

/// A named scene ready to render (camera and lights ensured, shaded with [`REPORT_SHADING`]).
pub struct BenchScene {
    /// Short name: the manifest's file stem, or "default".
    pub name: String,
    pub scene: Scene,
    /// The paper's Table 2 row this scene reproduces, if any.
    pub paper: Option<PaperRow>,
}

/// Which scenes to benchmark.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneSet {
    /// The built-in default scene only (no files needed; for tests and quick checks).
    DefaultOnly,
    /// The default scene plus every manifest whose models are present.
    All,
}

/// `assets/scenes/` of this source tree, or `$HYRT_SCENES_DIR` for a binary that runs
/// away from its checkout (`.ci/gpu-check`).
pub fn scenes_dir() -> PathBuf {
    match std::env::var_os("HYRT_SCENES_DIR") {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes"),
    }
}

/// The shared models folder (`$HYRT_SHARED_ASSETS`, else `<repo>/../shared/assets`), if
/// present.
pub fn shared_assets() -> Option<PathBuf> {
    let p = match std::env::var_os("HYRT_SHARED_ASSETS") {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets"),
    };
    p.is_dir().then_some(p)
}

/// The built-in default scene, ready to render.
pub fn default_scene() -> BenchScene {
    let mut scene = Scene { shading: REPORT_SHADING, ..Scene::default_scene() };
    scene.ensure_camera_and_lights();
    BenchScene { name: "default".into(), scene, paper: None }
}

/// Load `assets/scenes/<name>.toml`. `Err` is a message naming the file and the problem.
pub fn load_manifest(name: &str) -> Result<BenchScene, String> {
    let path = scenes_dir().join(format!("{name}.toml"));
    let mut scene = Scene::load(&path).map_err(|e| e.to_string())?;
    scene.shading = REPORT_SHADING;
    scene.ensure_camera_and_lights();
    Ok(BenchScene { name: name.to_string(), scene, paper: None })
}

/// Manifests of the Table 2 reproduction, with the paper row each stands for (the horse
/// stands in for the paper's toad: same triangle count, 25,820).
pub const TABLE2_MANIFESTS: [(&str, usize); 5] =
    [("teaser", 0), ("horse_near", 1), ("horse_far", 2), ("bunny_near", 3), ("bunny_far", 4)];

/// Manifests of the triangle-count scaling, fewest triangles first (horse 25,820;
/// bunny 69,451; the teaser, Sponza + bunny, 135,905; the dragon 871,414 + a floor).
pub const SCALING_MANIFESTS: [&str; 5] = ["horse_near", "bunny_near", "sponza", "teaser", "dragon"];

/// Load the named manifests, skipping (with a note in `notes`) those that fail or
/// when the shared models are absent.
pub fn load_manifests<'a>(
    names: impl IntoIterator<Item = &'a str>,
    set: SceneSet,
    notes: &mut Vec<String>,
) -> Vec<BenchScene> {
    if set == SceneSet::DefaultOnly {
        return Vec::new();
    }
    if shared_assets().is_none() {
        let msg = "../shared/assets not found: only the built-in default scene is benchmarked".to_string();
        if !notes.contains(&msg) {
            notes.push(msg);
        }
        return Vec::new();
    }
    names
        .into_iter()
        .filter_map(|n| match load_manifest(n) {
            Ok(s) => Some(s),
            Err(e) => {
                notes.push(format!("skipped scene {n}: {e}"));
                None
            }
        })
        .collect()
}

/// The Table 2 scenes: the default scene, then the paper's five when present.
pub fn table2_scenes(set: SceneSet, notes: &mut Vec<String>) -> Vec<BenchScene> {
    let mut out = vec![default_scene()];
    let mut loaded = load_manifests(TABLE2_MANIFESTS.map(|(n, _)| n), set, notes);
    for s in &mut loaded {
        s.paper = TABLE2_MANIFESTS.iter().find(|(n, _)| *n == s.name).map(|&(_, row)| PAPER_TABLE2[row]);
    }
    out.extend(loaded);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_manifest_names_an_existing_file() {
        for (n, _) in TABLE2_MANIFESTS {
            assert!(scenes_dir().join(format!("{n}.toml")).is_file(), "{n}");
        }
        for n in SCALING_MANIFESTS {
            assert!(scenes_dir().join(format!("{n}.toml")).is_file(), "{n}");
        }
    }

    #[test]
    fn manifests_load_when_the_shared_models_are_present() {
        if shared_assets().is_none() {
            eprintln!("../shared/assets not found; skipping");
            return;
        }
        let mut notes = Vec::new();
        let t = table2_scenes(SceneSet::All, &mut notes);
        assert!(notes.is_empty(), "{notes:?}");
        assert_eq!(t.len(), 6);
        assert!(t[1..].iter().all(|s| s.paper.is_some() && s.scene.camera.is_some()));
        assert_eq!(t[1].paper.unwrap().valid_rays, 66_252);
    }
}
