//! Offline HTML reports with PNG figures: `regolith validate --report DIR`.
//!
//! A certificate holds figures (repeatability per ε, ceilings, ratios with confidence
//! intervals, photometric errors, spectrum ratios) and the verdict, but a number such as "SIFT
//! ratio 0.10" does not say *why* a terrain failed: whether the render is misaligned, too
//! smooth, lit differently, or the detector fires on noise. The report puts the evidence next
//! to the figures — real frame, render and their difference, where each detector fired on
//! each, which keypoints repeated, the repeatability-vs-ε curves, the keypoint counts (the
//! thesis's Fig. 6.9) and the radial spectra — so a person can judge a certificate without
//! re-running anything.
//!
//! Why this shape:
//!
//! * **One folder, relative links, no script or network**: `index.html` plus PNGs opens from
//!   disk, survives being zipped or attached to a ticket, and a headless browser can check it
//!   (`tools/report/check_report.sh`).
//! * **Nothing is measured twice**: the images and keypoints come from the validation run
//!   itself through [`crate::validate::Validator::entry`]; the curves and tables are
//!   drawn from the [`crate::validate::Certificate`] it returns. The report cannot disagree
//!   with the certificate.
//! * **Generic figures** ([`plot`]: line plots, grouped bar charts, grey/diverging/magnitude
//!   rasters, strips, keypoint overlays; [`html`]: the page builder) take plain series and
//!   images, so the gap workflow's report (residual maps before/after, radial profiles,
//!   spectra) reuses them.
//! * **Deterministic and font-independent**: PNGs are encoded at pinned settings and text is
//!   drawn with a font compiled into the binary, so the same input gives the same bytes on any
//!   machine, including one without system fonts.

mod gap;
pub mod html;
pub mod plot;
mod validation;

use std::path::PathBuf;

use regolith_reader::ReaderError;

pub use gap::write_gap_report;
pub use validation::{overlay_scale, ValidationReport};

/// Maps an I/O error on `path` to [`ReportError::Io`].
pub(crate) fn io_err(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> ReportError + '_ {
    move |source| ReportError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// A report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// Reading or validating the release failed.
    #[error(transparent)]
    Reader(#[from] ReaderError),
    /// A figure could not be drawn or written.
    #[error(transparent)]
    Plot(#[from] plot::PlotError),
    /// A file or folder could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
}

/// A file-name-safe form of a name: ASCII letters, digits, `.` and `-` kept, anything else `_`.
pub fn slug(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() || s.starts_with('.') {
        format!("_{s}")
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::slug;

    #[test]
    fn slugs_are_file_names() {
        assert_eq!(slug("laser/0.01"), "laser_0.01");
        assert_eq!(slug("../x y"), "_.._x_y");
        assert_eq!(slug(""), "_");
    }
}
