//! `regolith release DB R --publish`: the release gate. A release is published (ref
//! `published/<name>@<version>`) only when every terrain entry (heightfield and mesh, see
//! `CERTIFIED_KINDS`) has a certificate for *this* release id whose entry hash matches and which
//! passed. `--allow-uncertified` publishes anyway, through a child release whose manifest records
//! `allow_uncertified: true` (version `<version>+uncertified`), so the exception is visible to
//! every reader.

use anyhow::bail;
use regolith_reader::{Database, Location, Writer};
use regolith_validator::validate::CERTIFIED_KINDS;

use super::print_json;
use crate::Outcome;

pub fn run(
    db: &Location,
    release: &str,
    publish: bool,
    allow_uncertified: bool,
    json: bool,
) -> anyhow::Result<Outcome> {
    if !publish {
        bail!("nothing to do: give --publish");
    }
    let database = Database::open(db)?;
    let view = database.release(release)?;
    let mut problems = Vec::new();
    for e in view
        .entries()
        .iter()
        .filter(|e| CERTIFIED_KINDS.contains(&e.kind.as_str()))
    {
        // An unreadable certificate refuses the release (fail closed) and is listed with the
        // others rather than hiding them.
        match database.certificate(&view.id, &e.name) {
            Err(err) => problems.push(format!("{}: cannot read its certificate: {err}", e.name)),
            Ok(None) => problems.push(format!(
                "{}: no certificate for this release (run `regolith validate`)",
                e.name
            )),
            Ok(Some(c)) => {
                if c["entry_hash"].as_str() != Some(e.hash()?.to_hex().as_str()) {
                    problems.push(format!(
                        "{}: the certificate is for another version of the entry",
                        e.name
                    ));
                } else if c["passed"] != serde_json::Value::Bool(true) {
                    let failures: Vec<&str> = c["failures"]
                        .as_array()
                        .into_iter()
                        .flatten()
                        .filter_map(|f| f.as_str())
                        .collect();
                    problems.push(format!(
                        "{}: certificate failed: {}",
                        e.name,
                        failures.join("; ")
                    ));
                }
            }
        }
    }
    let writer = Writer::create_or_open(db)?;
    let (label, id, uncertified) = if problems.is_empty() {
        (view.label(), view.id, false)
    } else if allow_uncertified {
        let mut m = view.manifest.clone();
        m.parent = Some(view.id);
        m.version = format!("{}+uncertified", m.version);
        m.allow_uncertified = Some(true);
        let label = m.label();
        (label, writer.commit(m, false)?, true)
    } else {
        if json {
            print_json(
                &serde_json::json!({"release": view.label(), "published": false, "problems": problems}),
            )?;
        } else {
            say!("refusing to publish {}:", view.label());
            for p in &problems {
                say!("  {p}");
            }
            say!("(validate the entries, or pass --allow-uncertified to publish with the exception recorded)");
        }
        return Ok(Outcome::CheckFailed);
    };
    writer.set_ref(&format!("published/{label}"), &id)?;
    if json {
        print_json(
            &serde_json::json!({"release": label, "id": id.to_hex(), "published": true, "allow_uncertified": uncertified, "problems": problems}),
        )?;
    } else {
        say!(
            "published {label} ({}){}",
            id.short(),
            if uncertified {
                " WITHOUT passing certificates (recorded in its manifest)"
            } else {
                ""
            }
        );
    }
    Ok(Outcome::Ok)
}
