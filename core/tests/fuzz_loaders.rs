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

#[test]
fn loaders_survive_mutated_files() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut seeds = harness::built_seeds();
    seeds.extend(harness::real_seeds(&root));
    for seed in &seeds {
        if let Err(e) = harness::load(seed) {
            panic!("seed {} does not load: {e}", seed.main.display());
        }
    }
    let report = harness::run(&seeds, SHORT_RUN_SEED, 0..SHORT_RUN_EXECUTIONS, |_| {});
    assert!(report.failures.is_empty(), "{:#?}", report.failures);
    assert_eq!(report.executions, SHORT_RUN_EXECUTIONS);
    // The mutations must not only produce garbage: some inputs still load.
    assert!(report.loaded > SHORT_RUN_EXECUTIONS / 20, "{report:?}");
}
