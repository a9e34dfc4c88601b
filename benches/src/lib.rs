//! # hyrt-benches
//!
//! The scenes benchmarks run on, shared by the criterion benches
//! (`cargo bench -p hyrt-benches`) and, later, the `hyrt bench` report.
//! Scenes from `../shared/assets` are skipped with a message when absent.

use std::path::PathBuf;

use hyrt::Scene;

/// A named scene ready for benchmarking.
pub struct BenchScene {
    pub name: &'static str,
    pub scene: Scene,
}

/// The folder of shared models, if present (`<repo>/../shared/assets`).
pub fn shared_assets() -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets");
    p.is_dir().then_some(p)
}

/// The default scene plus, when present, the paper's teaser manifest
/// (`assets/scenes/teaser.toml`: Sponza rasterized, the bunny ray traced).
pub fn bench_scenes() -> Vec<BenchScene> {
    let mut out = vec![BenchScene { name: "default", scene: Scene::default_scene() }];
    let teaser = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/teaser.toml");
    if shared_assets().is_none() {
        eprintln!("hyrt-benches: ../shared/assets not found; benchmarking the default scene only");
        return out;
    }
    match Scene::load(&teaser) {
        Ok(mut scene) => {
            scene.ensure_camera_and_lights();
            out.push(BenchScene { name: "teaser", scene });
        }
        Err(e) => eprintln!("hyrt-benches: skipping the teaser: {e}"),
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn bench_scenes_always_include_the_default_scene() {
        let s = super::bench_scenes();
        assert_eq!(s[0].name, "default");
        assert!(s.iter().all(|b| b.scene.camera.is_some() && !b.scene.lights.is_empty()));
    }
}
