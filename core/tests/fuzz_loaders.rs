//! A short run of the loader fuzzer (`fuzz/harness.rs`): a fixed seed, a few thousand
//! executions over every loader. Long runs: `cargo run --release -p hyrt-core --example
//! fuzz_loaders -- --iterations 1000000`.

#[path = "../fuzz/harness.rs"]
mod harness;

#[global_allocator]
static ALLOC: harness::Counting = harness::Counting;

/// Executions of the short run: a few seconds in the test profile.
const SHORT_RUN_EXECUTIONS: u64 = 3000;

/// The short run's seed (any fixed value: the run is deterministic).
const SHORT_RUN_SEED: u64 = 16;

/// Failures a failing run shows (they are often one bug many times).
const SHOWN_FAILURES: usize = 40;

#[test]
fn loaders_survive_mutated_files() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut seeds = harness::built_seeds();
    seeds.extend(harness::real_seeds(&root));
    // Every seed loads, alone and (a glTF or GLB file) through the manifests built around it.
    let mut unloaded = Vec::new();
    for (k, seed) in seeds.iter().enumerate() {
        let through = harness::through_manifests(seed, &mut harness::Rng::new(k as u64));
        for load in std::iter::once(seed).chain(&through) {
            if let Err(e) = harness::load(load) {
                unloaded.push(format!("seed {} does not load: {e}", seed.main.display()));
            }
        }
    }
    let report = harness::run(&seeds, SHORT_RUN_SEED, 0..SHORT_RUN_EXECUTIONS, |_| {});
    assert!(
        unloaded.is_empty() && report.failures.is_empty(),
        "{unloaded:#?}\n{} failures, the first {SHOWN_FAILURES}: {:#?}",
        report.failures.len(),
        &report.failures[..report.failures.len().min(SHOWN_FAILURES)]
    );
    assert_eq!(report.executions, SHORT_RUN_EXECUTIONS);
    // The mutations must not only produce garbage: some inputs still load, alone and through
    // manifests (which would refuse every input if they named it wrongly).
    let brief = (report.loaded, report.refused, report.manifest_loaded, report.manifest_refused);
    assert!(report.loaded > SHORT_RUN_EXECUTIONS / 20, "loaded, refused, through manifests: {brief:?}");
    assert!(report.manifest_loaded > SHORT_RUN_EXECUTIONS / 20, "loaded, refused, through manifests: {brief:?}");
}
