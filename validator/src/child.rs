//! Child releases: what `gap --apply` and `regolith control` write. Releases are immutable, so a
//! model or a control goes into a new release whose `parent` is the examined one, versioned
//! `<version>+<tag>.<n>` with the first free `n`; a child of the same release that already holds
//! the same thing is reused instead, so running the command twice writes nothing new.

use regolith_format::manifest::Entry;
use regolith_format::{ObjectId, Release};
use regolith_reader::{ReaderError, ReleaseView, Writer};

/// Commits `m` (the child's manifest, `parent` set here) as a child of `view` tagged `tag`, or
/// returns an existing child of `view` with an entry for which `same` holds. `follow_latest`:
/// move `latest` to the child when it pointed at the parent. Returns the label and id.
pub(crate) fn commit_child(
    writer: &Writer,
    view: &ReleaseView,
    mut m: Release,
    tag: &str,
    follow_latest: bool,
    same: impl Fn(&Entry) -> bool,
) -> Result<(String, ObjectId), ReaderError> {
    let db = writer.database();
    let existing = db.releases()?;
    for (label, id) in &existing {
        let child = db.release_by_id(id)?;
        if child.manifest.parent == Some(view.id) && child.manifest.entries.iter().any(&same) {
            return Ok((label.clone(), *id));
        }
    }
    m.parent = Some(view.id);
    let base = view.manifest.version.clone();
    m.version = (1..)
        .map(|n| format!("{base}+{tag}.{n}"))
        .find(|v| {
            let label = format!("{}@{v}", m.name);
            !existing.iter().any(|(l, _)| *l == label)
        })
        .unwrap_or(base);
    let move_latest = follow_latest && db.read_ref("latest")?.is_some_and(|id| id == view.id);
    let label = m.label();
    let id = writer.commit(m, move_latest)?;
    Ok((label, id))
}
