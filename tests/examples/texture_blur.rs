//! The texture's effective blur ([`regolith_validator::gap::texture`]) of compiled campaigns
//! under their stored models, without the other gap stages: how the own blur of faithful
//! textures is measured, and how a hidden `texture-lowpass` reads.
//!
//! `cargo run --release -p regolith-tests --example texture_blur -- ENTRY DB...` (each `DB` a
//! compiled database whose latest release holds `ENTRY`; a `truth/hidden.json` in `DB/../camp`
//! is shown next to it).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;

use regolith_reader::Database;
use regolith_validator::gap;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((entry, dbs)) = args.split_first() else {
        eprintln!("usage: texture_blur ENTRY DB...");
        std::process::exit(2);
    };
    for db in dbs {
        let path = Path::new(db);
        let database = Database::open(path).unwrap();
        let view = database.release("latest").unwrap();
        let hidden = std::fs::read_to_string(path.join("../camp/truth/hidden.json"))
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .map_or("?".to_string(), |v| v["effects"].to_string());
        let t0 = std::time::Instant::now();
        match gap::texture_figures(&view, entry, &[]).unwrap() {
            Some(f) => println!(
                "{db}: effective {:.1} mm (own {:.1}, excess {:.1}, corr {:.2}, cell {} m) hidden {hidden} [{:.0} s]",
                f.effective_blur_m * 1e3,
                f.own_blur_m * 1e3,
                f.excess_m * 1e3,
                f.correlation,
                f.cell_m,
                t0.elapsed().as_secs_f64()
            ),
            None => println!("{db}: no measure"),
        }
    }
}
