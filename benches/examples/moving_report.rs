//! The "Moving scenes" section of `hyrt bench` alone, printed as Markdown: the teaser's
//! bunny and a grid of bunnies moving in Sponza (the default scene's sphere without the
//! shared models), hyrt's two-level update and rebuild against Embree's, and the frame.
//!
//! ```text
//! cargo run --release -p hyrt-benches --features embree --example moving_report -- \
//!     [--full] [--no-gpu] [--frames N] [--size WxH] [--threads N]
//! ```
//!
//! Settings are `hyrt bench --quick`'s (`--full`: the full run's); the section is the one
//! the report gets.

use hyrt_benches::bench::scenes::{default_scene, load_manifest};
use hyrt_benches::bench::{frame_backends, moving, BenchOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let out = std::env::temp_dir().join("hyrt-moving-report");
    let mut options = BenchOptions::quick(out);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or_else(|| format!("{a} needs a value"));
        match a.as_str() {
            "--full" => options = BenchOptions { gpu: options.gpu, ..BenchOptions::full(options.out_dir.clone()) },
            "--no-gpu" => options.gpu = false,
            "--frames" => options.frames = value()?.parse()?,
            "--threads" => options.frame_threads = Some(value()?.parse()?),
            "--size" => {
                let v = value()?;
                let (w, h) = v.split_once('x').ok_or("--size takes WxH")?;
                options.table_size = (w.parse()?, h.parse()?);
            }
            other => return Err(format!("unknown argument {other}").into()),
        }
    }
    let mut scenes = vec![default_scene()];
    match load_manifest("teaser") {
        Ok(t) => scenes.push(t),
        Err(e) => eprintln!("moving_report: no teaser ({e}); the default scene's sphere only"),
    }
    let mut notes = Vec::new();
    let (mut cpu, mut gpu) = frame_backends(&options, &mut notes);
    for n in &notes {
        eprintln!("note: {n}");
    }
    let t = std::time::Instant::now();
    let m = moving::run(&options, &scenes, &mut cpu, gpu.as_mut(), &indicatif::ProgressBar::hidden())?;
    let section = m.section();
    println!("## {}\n\n{}", section.title, section.markdown);
    eprintln!("moving_report: {:.1} s", t.elapsed().as_secs_f64());
    Ok(())
}
