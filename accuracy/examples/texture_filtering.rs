//! The texture-filtering study of the report on its own (`hyrt_accuracy::textures`):
//!
//! ```text
//! cargo run --release -p hyrt-accuracy --example texture_filtering -- [WIDTH HEIGHT THREADS RUNS]
//! ```

fn main() {
    let args: Vec<u32> = std::env::args().skip(1).map(|a| a.parse().expect("a number")).collect();
    let get = |k: usize, default: u32| args.get(k).copied().unwrap_or(default);
    let (_, md) = hyrt_accuracy::textures::texture_speed_vs_error(
        get(0, 640),
        get(1, 360),
        get(2, 2) as usize,
        get(3, 5) as usize,
    );
    println!("{md}");
}
