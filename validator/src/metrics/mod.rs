//! The comparison metrics of `regolith validate`, one reference implementation with fixed test
//! vectors so the numbers never drift between versions:
//!
//! * [`repeatability`]: the Mikolajczyk & Schmid protocol (keypoints of one image mapped into
//!   the other through the known geometry, repeated within ε pixels in the region both see,
//!   divided by the smaller count), its curve over ε, and the thesis's one-directional ratio;
//! * [`region_overlap`]: ellipse overlap error and region repeatability for region detectors
//!   (MSER), pairs with overlap error < 40 % (Mikolajczyk et al. 2005);
//! * [`matching`]: descriptor matching (ratio test, cross check), the matching score, and the
//!   SIFT + RANSAC figures of thesis Table 6.1, with the estimators in [`ransac`];
//! * [`photometric`]: RMS and SSIM inside a common mask;
//! * [`spectrum`]: radial power spectra and their log-ratio per frequency band (the thesis's
//!   FFT finding that renders lack high frequencies);
//! * [`stats`]: means with Student-t confidence intervals over captures;
//! * [`compare`]: one detector on one view (real vs render and real vs real), every metric above
//!   from one detection per image.

pub mod compare;
pub mod matching;
pub mod photometric;
pub mod ransac;
pub mod region_overlap;
pub mod repeatability;
pub mod spectrum;
pub mod stats;
