//! Path arguments, resolved once for every command.
//!
//! A user types a path in many forms: a bare name (`campaign.toml`), `./x`, `../x`, an
//! absolute path, a symlink, a name in any script. Every command hands its path arguments
//! through [`absolute`] before it uses them, so no command depends on the form: a bare name has
//! no parent (`Path::new("campaign.toml").parent()` is `""`, which names no folder), and code
//! that joins a file's folder with a relative name inside it would otherwise break on it.
//!
//! Paths are made absolute against the working directory without resolving symlinks
//! (`std::path::absolute`), so messages still show the folder the user named and a symlinked
//! database or campaign folder stays what the user pointed at. Names are kept as `OsStr`
//! throughout: nothing here requires UTF-8.

use std::path::{Path, PathBuf};

use anyhow::Context;
use regolith_reader::Location;

/// `path` made absolute against the working directory (`.` and `..` components kept as typed,
/// symlinks not resolved). An empty path is the working directory.
pub fn absolute(path: &Path) -> anyhow::Result<PathBuf> {
    let path = if path.as_os_str().is_empty() {
        Path::new(".")
    } else {
        path
    };
    std::path::absolute(path).with_context(|| {
        format!(
            "resolving the path {:?} against the working directory (is the working directory still there?)",
            path
        )
    })
}

/// A database argument: an object-store URL (`s3://bucket/prefix`, `gs://…`, `az://…`) as
/// typed, or a path (including `file://PATH`) made [`absolute`]. Parsed once here, so every
/// command that takes DB accepts both (docs/object-storage.md).
pub fn db_location(arg: &Path) -> anyhow::Result<Location> {
    match arg.to_str().map(Location::parse) {
        Some(Location::Url(url)) => Ok(Location::Url(url)),
        Some(Location::Local(path)) => Ok(Location::Local(absolute(&path)?)),
        None => Ok(Location::Local(absolute(arg)?)),
    }
}

/// Like [`absolute`], for an optional argument.
pub fn absolute_opt(path: Option<&Path>) -> anyhow::Result<Option<PathBuf>> {
    path.map(absolute).transpose()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    #[test]
    fn bare_names_get_the_working_directory_as_parent() {
        let cwd = std::env::current_dir().unwrap();
        let p = absolute(Path::new("campaign.toml")).unwrap();
        assert_eq!(p, cwd.join("campaign.toml"));
        assert_eq!(p.parent().unwrap(), cwd);
        assert_eq!(absolute(Path::new("")).unwrap(), cwd);
    }

    #[test]
    fn database_arguments_are_urls_or_paths() {
        let cwd = std::env::current_dir().unwrap();
        assert_eq!(
            db_location(Path::new("s3://bucket/terrain/")).unwrap(),
            Location::Url("s3://bucket/terrain".into())
        );
        assert_eq!(
            db_location(Path::new("db")).unwrap(),
            Location::Local(cwd.join("db"))
        );
        assert_eq!(
            db_location(Path::new("file:///srv/db")).unwrap(),
            Location::Local(PathBuf::from("/srv/db"))
        );
        assert_eq!(
            db_location(Path::new("C:/db")).unwrap(),
            Location::Local(cwd.join("C:/db"))
        );
    }

    #[test]
    fn absolute_paths_and_non_utf8_names_pass_through() {
        assert_eq!(
            absolute(Path::new("/a/b/../c")).unwrap(),
            PathBuf::from("/a/b/../c")
        );
        #[cfg(unix)]
        {
            use std::os::unix::ffi::OsStrExt;
            let raw = std::ffi::OsStr::from_bytes(b"ter\xffrain");
            let p = absolute(Path::new(raw)).unwrap();
            assert_eq!(p.file_name().unwrap(), raw);
        }
    }
}
