//! The comparison metrics of `regolith validate`, one reference implementation with fixed test
//! vectors so the numbers never drift between versions:
//!
//! * [`repeatability`]: the Mikolajczyk & Schmid protocol (keypoints of one image mapped into
//!   the other through the known geometry, repeated within ε pixels in the region both see,
//!   divided by the smaller count), its curve over ε, and the thesis's one-directional ratio;
//! * [`photometric`]: RMS and SSIM inside a common mask;
//! * [`spectrum`]: radial power spectra and their log-ratio per frequency band (the thesis's
//!   FFT finding that renders lack high frequencies);
//! * [`stats`]: means with Student-t confidence intervals over captures.

pub mod photometric;
pub mod repeatability;
pub mod spectrum;
pub mod stats;
