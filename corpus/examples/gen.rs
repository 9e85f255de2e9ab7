//! Generates a campaign and prints the stage timings: `cargo run -p regolith-corpus --example gen -- mini 1 /tmp/out [--full]`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use regolith_corpus::{generate, GenerateOptions, Preset};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let preset = args
        .get(1)
        .and_then(|s| Preset::parse(s))
        .ok_or("preset: estec|mini")?;
    let seed: u64 = args.get(2).ok_or("seed")?.parse()?;
    let out = args.get(3).ok_or("out dir")?;
    let full = args.iter().any(|a| a == "--full");
    let hidden = match args.iter().position(|a| a == "--hidden") {
        Some(i) => regolith_corpus::effects::parse_list(args.get(i + 1).ok_or("effects")?)?,
        None => Vec::new(),
    };
    let t = std::time::Instant::now();
    let s = generate(
        &GenerateOptions {
            preset,
            seed,
            full,
            captures: None,
            hidden,
        },
        std::path::Path::new(out),
        &|_, _| {},
    )?;
    println!(
        "total {:.2} s, {} files, captures {}",
        t.elapsed().as_secs_f64(),
        s.files.len(),
        s.captures
    );
    for (stage, secs) in &s.stage_seconds {
        println!("  {stage:<20} {secs:.2} s");
    }
    for (scan, n) in &s.scan_points {
        println!("  {scan}: {n} points");
    }
    Ok(())
}
