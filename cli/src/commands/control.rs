//! `regolith control DB --entry E --texture-blur-m S`: a negative control for the release gate
//! (`regolith_validator::control`): the entry with its texture blurred, in a child release.

use regolith_reader::{Database, Location, Writer};
use regolith_validator::control::blurred_texture;

use super::print_json;
use crate::Outcome;

pub fn run(
    db: &Location,
    release: &str,
    entry: &str,
    sigma_m: f64,
    json: bool,
) -> anyhow::Result<Outcome> {
    let database = Database::open(db)?;
    let view = database.release(release)?;
    view.entry(entry)?;
    let writer = Writer::create_or_open(db)?;
    let c = blurred_texture(&writer, &view, entry, sigma_m)?;
    if json {
        print_json(&serde_json::json!({
            "release": c.release,
            "id": c.id.to_hex(),
            "parent": view.label(),
            "entry": c.entry,
            "texture_blur_m": sigma_m,
            "texture_blur_px": c.sigma_px,
        }))?;
    } else {
        say!(
            "{}: {} = {entry} with its texture blurred by σ {sigma_m} m ({:.2} texture pixels); \
             validate it with: regolith validate {} --release {} --entry {}",
            c.release,
            c.entry,
            c.sigma_px,
            db.display(),
            c.release,
            c.entry
        );
    }
    Ok(Outcome::Ok)
}
