//! # hyrt-benches
//!
//! - [`bench`](mod@bench): the benchmark report of `hyrt bench` (the paper's Table 2 on both
//!   backends, peers with the Embree binding behind the `embree` feature, scaling, plots,
//!   and the speed-against-error section from `hyrt-accuracy`).
//! - The scenes benchmarks run on, shared by the criterion benches
//!   (`cargo bench -p hyrt-benches`); they load scenes the way `hyrt bench` does
//!   ([`bench::scenes`]). Scenes from `../shared/assets` are skipped with a message when
//!   absent.

pub mod bench;

use std::path::PathBuf;

use hyrt::Scene;

/// A named scene ready for benchmarking.
pub struct BenchScene {
    pub name: &'static str,
    pub scene: Scene,
}

/// The folder of shared models, if present (`<repo>/../shared/assets`).
pub fn shared_assets() -> Option<PathBuf> {
    crate::bench::scenes::shared_assets()
}

/// The default scene plus, when present, the paper's teaser manifest
/// (`assets/scenes/teaser.toml`: Sponza rasterized, the bunny ray traced), loaded as
/// `hyrt bench` loads them.
pub fn bench_scenes() -> Vec<BenchScene> {
    let mut out = vec![BenchScene { name: "default", scene: crate::bench::scenes::default_scene().scene }];
    let mut notes = Vec::new();
    let teaser = crate::bench::scenes::load_manifests(["teaser"], crate::bench::SceneSet::All, &mut notes);
    for n in notes {
        eprintln!("hyrt-benches: {n}");
    }
    out.extend(teaser.into_iter().map(|s| BenchScene { name: "teaser", scene: s.scene }));
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
