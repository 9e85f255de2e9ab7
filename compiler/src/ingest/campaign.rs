//! campaign: reader being written.
