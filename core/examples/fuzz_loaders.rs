//! Long runs of the loader fuzzer (`fuzz/harness.rs`):
//!
//! ```text
//! cargo run --release -p hyrt-core --example fuzz_loaders -- --iterations 1000000 [--seed S] [--start N]
//! cargo run --release -p hyrt-core --example fuzz_loaders -- --seed S --only N [--write DIR]
//! ```
//!
//! `--only N` runs execution N alone and, with `--write`, writes its files under DIR (its
//! input's, and those of the manifests a glTF or GLB input is loaded through).
//! Exits non-zero when an execution fails (a panic, an error not naming its file); a hang
//! or an allocation past the limit aborts, naming the execution.

#[path = "../fuzz/harness.rs"]
mod harness;

#[global_allocator]
static ALLOC: harness::Counting = harness::Counting;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |name: &str| args.iter().position(|a| a == name).and_then(|k| args.get(k + 1)).cloned();
    let number = |name: &str, default: u64| value(name).map(|v| v.parse().expect("a number")).unwrap_or(default);
    let seed = number("--seed", 1);
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut seeds = harness::built_seeds();
    seeds.extend(harness::real_seeds(&root));
    if let Some(n) = value("--only").map(|v| v.parse::<u64>().expect("a number")) {
        // The input, then the manifests built around it (they share its files).
        let loads = harness::loads(&seeds, seed, n);
        if let Some(dir) = value("--write") {
            for load in &loads {
                harness::write_input(load, dir.as_ref()).expect("writing the input");
                println!("execution {n}: main file {} written under {dir}", load.main.display());
            }
        }
        let report = harness::run(&seeds, seed, n..n + 1, |_| {});
        for load in &loads {
            println!("{}: {:?}", load.main.display(), harness::load(load));
        }
        println!("{report:?}");
        std::process::exit(if report.failures.is_empty() { 0 } else { 1 });
    }
    let start = number("--start", 0);
    let iterations = number("--iterations", 100_000);
    println!("{} seeds; seed {seed}; executions {start}..{}", seeds.len(), start + iterations);
    let began = std::time::Instant::now();
    let report = harness::run(&seeds, seed, start..start + iterations, |r| eprintln!("{}", summary(r, began)));
    println!("done: {}", summary(&report, began));
    for (n, what) in report.failures.iter().take(50) {
        println!("execution {n}: {what}");
    }
    std::process::exit(if report.failures.is_empty() { 0 } else { 1 });
}

/// Executions, time, rate and outcomes so far.
fn summary(r: &harness::Report, began: std::time::Instant) -> String {
    let s = began.elapsed().as_secs_f64();
    format!(
        "{} executions in {s:.1} s ({:.0}/s): {} loaded, {} refused; through manifests {} loaded, {} refused; {} failures",
        r.executions,
        r.executions as f64 / s,
        r.loaded,
        r.refused,
        r.manifest_loaded,
        r.manifest_refused,
        r.failures.len()
    )
}
