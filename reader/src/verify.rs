//! Whole-database verification: rehash every object reachable from every ref.
//!
//! Used by `regolith verify`. Each object is hashed once even when several releases share it;
//! every problem is collected (not just the first), naming the release, entry and role.

use std::collections::BTreeMap;
use std::io::Read;

use regolith_format::ObjectId;
use serde::Serialize;

use crate::database::Database;
use crate::error::{ReaderError, Result};
use crate::object::{unwrap_verify_error, Site, VerifyingReader};

/// The outcome of a verification.
#[derive(Debug, Clone, Default, Serialize)]
pub struct VerifyReport {
    /// Releases checked (label → id).
    pub releases: BTreeMap<String, String>,
    /// Distinct objects hashed.
    pub objects_checked: u64,
    /// Bytes hashed.
    pub bytes_checked: u64,
    /// Problems found; empty when the database is intact.
    pub problems: Vec<Problem>,
}

/// One problem.
#[derive(Debug, Clone, Serialize)]
pub struct Problem {
    /// The ref or release through which the object was reached.
    pub release: String,
    /// The object id (hex).
    pub object: String,
    /// Entry name, or `<manifest>`.
    pub entry: String,
    /// Role path.
    pub role: String,
    /// What is wrong.
    pub message: String,
}

impl VerifyReport {
    /// True when no problem was found.
    pub fn ok(&self) -> bool {
        self.problems.is_empty()
    }
}

/// Verifies every release reachable from the refs (and their parents).
pub fn verify(db: &Database) -> Result<VerifyReport> {
    let mut report = VerifyReport::default();
    let mut checked: BTreeMap<ObjectId, bool> = BTreeMap::new();
    let mut queue = Vec::new();
    for (name, id) in db.refs()? {
        if crate::database::is_object_ref(&name) {
            report.objects_checked += 1;
            if let Err(e) = crate::object::read_verified(
                &**db.store(),
                &id,
                None,
                &Site::new(&name, "certificate"),
            ) {
                report.problems.push(Problem {
                    release: name.clone(),
                    object: id.to_hex(),
                    entry: name.clone(),
                    role: "certificate".into(),
                    message: short_message(&e),
                });
            }
        } else {
            queue.push((name, id));
        }
    }
    let mut seen_releases = std::collections::BTreeSet::new();
    while let Some((via, id)) = queue.pop() {
        if !seen_releases.insert(id) {
            continue;
        }
        let view = match db.release_by_id(&id) {
            Ok(v) => v,
            Err(e) => {
                report.problems.push(Problem {
                    release: via,
                    object: id.to_hex(),
                    entry: "<manifest>".into(),
                    role: "manifest".into(),
                    message: e.to_string(),
                });
                continue;
            }
        };
        checked.insert(id, true);
        report.objects_checked += 1;
        let label = view.label();
        report.releases.insert(label.clone(), id.to_hex());
        for (entry, role, f) in view.manifest.file_refs() {
            if checked.contains_key(&f.object) {
                continue;
            }
            let site = Site::new(entry, &role);
            let result = VerifyingReader::open(&**db.store(), &f.object, Some(f.size), site)
                .and_then(|mut r| {
                    let mut buf = vec![0u8; 1 << 20];
                    let mut n_total = 0u64;
                    loop {
                        let n = r
                            .read(&mut buf)
                            .map_err(|e| unwrap_verify_error(e, &**db.store(), &f.object))?;
                        if n == 0 {
                            break Ok(n_total);
                        }
                        n_total += n as u64;
                    }
                });
            report.objects_checked += 1;
            match result {
                Ok(n) => {
                    report.bytes_checked += n;
                    checked.insert(f.object, true);
                }
                Err(e) => {
                    checked.insert(f.object, false);
                    report.problems.push(Problem {
                        release: label.clone(),
                        object: f.object.to_hex(),
                        entry: entry.to_string(),
                        role,
                        message: short_message(&e),
                    });
                }
            }
        }
        if let Some(parent) = view.manifest.parent {
            queue.push((format!("parent of {label}"), parent));
        }
    }
    Ok(report)
}

fn short_message(e: &ReaderError) -> String {
    match e {
        ReaderError::MissingObject { .. } => "missing".to_string(),
        ReaderError::CorruptObject { detail, .. } => format!("corrupt: {detail}"),
        other => other.to_string(),
    }
}
