//! Where generated files go: a root folder plus the sorted list of what was written.
//!
//! Every writer goes through [`Sink`], so paths are always relative to the campaign folder,
//! parents are created on demand, and the summary lists exactly the files of this run.

use std::path::{Path, PathBuf};

use crate::CorpusError;

/// The output folder of one generation run.
#[derive(Debug)]
pub struct Sink {
    root: PathBuf,
    written: Vec<String>,
}

impl Sink {
    /// A sink writing below `root` (created if missing).
    pub fn new(root: &Path) -> Result<Sink, CorpusError> {
        std::fs::create_dir_all(root).map_err(CorpusError::io("output folder", root))?;
        Ok(Sink {
            root: root.to_path_buf(),
            written: Vec::new(),
        })
    }

    /// The absolute path of `rel`, with its parent folder created; records `rel` as written.
    pub fn path(&mut self, rel: &str) -> Result<PathBuf, CorpusError> {
        let p = self.root.join(rel);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent).map_err(CorpusError::io("folder", parent))?;
        }
        self.written.push(rel.to_string());
        Ok(p)
    }

    /// Writes `bytes` to `rel`.
    pub fn write(&mut self, rel: &str, bytes: &[u8]) -> Result<(), CorpusError> {
        let p = self.path(rel)?;
        std::fs::write(&p, bytes).map_err(CorpusError::io("file", &p))
    }

    /// Serialises `value` as pretty JSON (struct fields in declaration order, maps sorted).
    pub fn write_json<T: serde::Serialize>(
        &mut self,
        rel: &str,
        value: &T,
    ) -> Result<(), CorpusError> {
        let p = self.root.join(rel);
        let mut text =
            serde_json::to_string_pretty(value).map_err(CorpusError::encode("JSON", &p))?;
        text.push('\n');
        self.write(rel, text.as_bytes())
    }

    /// The files written so far, sorted and deduplicated.
    pub fn files(&self) -> Vec<String> {
        let mut v = self.written.clone();
        v.sort();
        v.dedup();
        v
    }
}

/// Appends `v` with exactly `decimals` decimals (no exponent), as instruments print numbers.
pub fn push_fixed(out: &mut String, v: f64, decimals: usize) {
    use std::fmt::Write;
    let scale = 10f64.powi(decimals as i32);
    let v = if (v * scale).round() == 0.0 { 0.0 } else { v }; // no "-0.0000"
    let _ = write!(out, "{v:.decimals$}");
}

/// `v` in C's `%.{precision}e` form: signed exponent of at least two digits (`1.5e+02`).
pub fn sci(v: f64, precision: usize) -> String {
    if v.is_nan() {
        return "NaN".into();
    }
    let s = format!("{v:.precision$e}");
    match s.split_once('e') {
        Some((mant, exp)) => {
            let (sign, digits) = exp.strip_prefix('-').map_or(("+", exp), |d| ("-", d));
            format!("{mant}e{sign}{digits:0>2}")
        }
        None => s,
    }
}
